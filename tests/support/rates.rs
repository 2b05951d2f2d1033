//! The identification statistics on the independent truth, shared by `tests/identify.rs`
//! (a few seeds per effect, in the suite) and `benches/identify_rates.rs` (50 seeds).

#![allow(dead_code)]

use cable_servo::identify::{diagnose, effect_value, DiagnoseOptions, EffectName};
use cable_servo::measurement::BenchLog;
use cable_servo::scenario::Scenario;
use rand::{Rng, SeedableRng};

use super::truth::{truth_log, TruthOptions};

/// A slewing gimbal axis on the paper bench's drive: large sine scan, brake and unbalance
/// (the built-in `gimbal_ident` scenario).
const GIMBAL: &str = include_str!("../../scenarios/gimbal_ident.toml");

pub fn scenario(triangle: bool) -> Scenario {
    let mut text = GIMBAL.to_string();
    if triangle {
        text = text.replace("kind = \"sine\"", "kind = \"triangle\"");
    }
    Scenario::from_toml(&text, "gimbal", "gimbal", &[]).expect("test scenario")
}

/// The shipped gimbal scan with one line of its scenario changed (`from`, which must be
/// there, to `to`): another stroke, speed or load, as a bench engineer would run it.
pub fn gimbal_changed(from: &str, to: &str) -> Scenario {
    assert!(GIMBAL.contains(from), "gimbal_ident.toml has no {from:?}");
    let name = format!("gimbal, {to}");
    Scenario::from_toml(&GIMBAL.replace(from, to), &name, &name, &[]).expect("changed scenario")
}

pub fn truth(sc: &Scenario, effects: &[(EffectName, f64)], seed: u64) -> BenchLog {
    truth_log(sc, effects, seed, &TruthOptions::default())
        .unwrap_or_else(|e| panic!("truth: {e}"))
        .log
}
/// Realistic size range of each effect for this axis (signature well above the noise).
pub fn size_range(e: EffectName) -> (f64, f64) {
    match e {
        EffectName::InputPulleyRunout => (3e-4, 2e-3),
        EffectName::OutputDrumRunout => (5e-5, 3e-4),
        EffectName::EncoderDelay => (2e-4, 2e-3),
        EffectName::EncoderScaleError => (3e-5, 3e-4),
        EffectName::PreloadRelaxation => (0.005, 0.015),
        EffectName::BearingFriction => (0.1, 0.3),
        EffectName::CableTransport => (0.05, 0.5),
        EffectName::ThermalDrift => (1e-6, 5e-6),
        EffectName::AngleDependentRatio => (5e-5, 5e-4),
        // Below 1e-4 rad/(N m) most of it hides in the calibrated cable modulus and what is
        // left is at the noise floor on this axis.
        EffectName::LoadCompliance => (1e-4, 1e-3),
        EffectName::DistributedFrictionMemory => (5e-5, 5e-4),
    }
}

/// How close a size must be. Preload relaxation is sized within 20 %: the fit replays the
/// cable at constant preloads and interpolates in time, while the truth's preload creeps
/// inside the memory it holds, and the instrument's preload is itself up to 2 % off the
/// scenario's; on the truth it reads low, 18.4 % at worst in 50 draws.
///
/// Thermal drift is sized within 25 %: the truth's output encoder also wanders as a random
/// walk (2 µrad RMS at the end of the record) and with 1/f noise (1 µrad RMS), which no
/// model can tell from a drift over one record. The slope fitted to a random walk of end RMS
/// `s` over `T` scatters by `1.1 s / T` (0.073 µrad/s here), the 1/f noise's slowest terms
/// add about 0.03 µrad/s: 0.08 µrad/s together, 8 % of the smallest drift drawn (1 µrad/s);
/// 25 % is three of those.
pub fn size_tolerance(e: EffectName) -> f64 {
    match e {
        EffectName::PreloadRelaxation => 0.20,
        EffectName::ThermalDrift => 0.25,
        _ => 0.10,
    }
}

/// The share of draws named right and sized within [`size_tolerance`] that
/// `docs/diagnose.md` states for each effect, as measured over 50 draws by `benches/identify_rates.rs`:
/// 95 % for all but compliance, whose smallest sizes partly hide in the calibrated modulus
/// (named 49/50, sized 46/50 there).
pub fn claimed_rates(e: EffectName) -> (f64, f64) {
    match e {
        EffectName::LoadCompliance => (0.98, 0.92),
        _ => (0.95, 0.95),
    }
}

/// The default search (every effect, unless the scenario lists candidates), without the
/// play operator's comparison.
pub fn opts() -> DiagnoseOptions {
    DiagnoseOptions {
        skip_play_operator: true,
        ..DiagnoseOptions::default()
    }
}

/// Options searching the library alone (the default before the multi-wrap effects
/// joined it).
pub fn opts_library() -> DiagnoseOptions {
    DiagnoseOptions {
        candidates: Some(EffectName::ALL.to_vec()),
        ..opts()
    }
}

/// Options searching the library and the multi-wrap effects together.
pub fn opts_every() -> DiagnoseOptions {
    DiagnoseOptions {
        candidates: Some(EffectName::EVERY.to_vec()),
        ..opts()
    }
}

/// Size of seed `seed`: even seeds within a factor 2 of the smallest size, odd seeds spread
/// over the whole range (log-uniform).
pub fn size_of(e: EffectName, seed: u64) -> f64 {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed * 7919 + e as u64);
    let (lo, hi) = size_range(e);
    let top = if seed.is_multiple_of(2) { 2.0 * lo } else { hi };
    lo * (top / lo).powf(rng.gen::<f64>())
}

pub struct Rates {
    pub named: usize,
    pub sized: usize,
    pub worst: f64,
    /// Draws whose answer came with candidates it could not tell apart.
    pub tied: usize,
}

pub fn run_effect(e: EffectName, seeds: u64) -> Rates {
    let mut r = Rates {
        named: 0,
        sized: 0,
        worst: 0.0,
        tied: 0,
    };
    for seed in 0..seeds {
        let v = size_of(e, seed);
        let sc = scenario(seed % 4 >= 2);
        let log = truth(&sc, &[(e, v)], seed);
        let d = diagnose(&sc, &[log], &opts()).expect("diagnosis");
        if d.cause == e.as_str() {
            r.named += 1;
        }
        r.tied += usize::from(!d.indistinguishable.is_empty());
        if let Some(est) = effect_value(&d, e) {
            // A runout's sign is its phase shifted by pi; every other effect is sized with
            // its sign.
            let signed = match e {
                EffectName::InputPulleyRunout | EffectName::OutputDrumRunout => est.abs(),
                _ => est,
            };
            let rel = (signed - v).abs() / v;
            r.worst = r.worst.max(rel);
            if rel <= size_tolerance(e) {
                r.sized += 1;
            }
        }
        eprintln!(
            "{e} seed {seed}: true {v:.4e} -> cause {} est {:?} base {:.4} ext {:.4} floor {:.4}; not told apart {:?}",
            d.cause,
            effect_value(&d, e),
            d.rmse_base_mrad,
            d.rmse_extended_mrad,
            d.noise_floor_mrad,
            d.indistinguishable
        );
    }
    eprintln!(
        "RATE {e}: named {}/{seeds}, sized within {:.0} % {}/{seeds}, worst size error {:.1} %, not told apart from another {}/{seeds}",
        r.named,
        size_tolerance(e) * 100.0,
        r.sized,
        r.worst * 100.0,
        r.tied
    );
    r
}

/// Clean logs (no effect hidden) called `none`, of `seeds`.
pub fn clean_rate(seeds: u64, o: &DiagnoseOptions, what: &str) -> usize {
    let mut none = 0;
    for seed in 0..seeds {
        let sc = scenario(seed % 2 == 1);
        let log = truth(&sc, &[], 1000 + seed);
        let d = diagnose(&sc, &[log], o).expect("diagnosis");
        if d.cause == "none" {
            none += 1;
        } else {
            eprintln!("clean ({what}) seed {seed}: {} {:?}", d.cause, d.candidates);
        }
    }
    eprintln!("RATE clean, {what}: none {none}/{seeds}");
    none
}
