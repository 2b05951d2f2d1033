//! Diagnosis against synthetic logs with hidden effects of known size.

use cable_servo::identify::{
    diagnose, read_bench_log, report::effect_value, synthesize, write_bench_log, DiagnoseOptions,
    EffectName, Ringing, SynthOptions,
};
use cable_servo::scenario::Scenario;
use rand::{Rng, SeedableRng};

/// A slewing gimbal axis on the paper bench's drive: large sine scan, brake and unbalance.
const GIMBAL: &str = r#"
name = "gimbal_ident"
study = "quasi_static"

[drive]
pulley_radius_m = 0.020
drum_radius_m = 0.1025
center_distance_m = 0.1450595
cable_modulus_n = 1.4e4
friction_coefficient = 0.2
preload_n = 50.0
drum_wrap_rad = 3.14159265
pulley_wrap_rad = 18.8495559

[load]
brake_nm = 0.7
unbalance_nm = 0.3

[quasi_static]
duration_s = 30.0
sample_rate_hz = 100.0

[quasi_static.motion]
kind = "sine"
amplitude_rad = 10.0
frequency_hz = 0.1

[identify]
unknown = ["cable_modulus_n"]
"#;

fn scenario(triangle: bool) -> Scenario {
    let mut text = GIMBAL.to_string();
    if triangle {
        text = text.replace("kind = \"sine\"", "kind = \"triangle\"");
    }
    Scenario::from_toml(&text, "gimbal", "gimbal", &[]).expect("test scenario")
}

/// Realistic size range of each effect for this axis (signature well above the noise).
fn size_range(e: EffectName) -> (f64, f64) {
    match e {
        EffectName::InputPulleyRunout => (3e-4, 2e-3),
        EffectName::OutputDrumRunout => (5e-5, 3e-4),
        EffectName::EncoderDelay => (2e-4, 2e-3),
        EffectName::EncoderScaleError => (3e-5, 3e-4),
        EffectName::PreloadRelaxation => (0.005, 0.015),
        EffectName::BearingFriction => (0.1, 0.3),
        EffectName::CableTransport => (0.05, 0.5),
        EffectName::ThermalDrift => (1e-6, 5e-6),
    }
}

fn opts() -> DiagnoseOptions {
    DiagnoseOptions {
        skip_play_operator: true,
        ..DiagnoseOptions::default()
    }
}

fn run_effect(e: EffectName, seeds: u64) -> (usize, usize, f64) {
    let mut named = 0;
    let mut sized = 0;
    let mut worst: f64 = 0.0;
    for seed in 0..seeds {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed * 7919 + e as u64);
        let (lo, hi) = size_range(e);
        let v = lo * (hi / lo).powf(rng.gen::<f64>());
        let sc = scenario(seed % 2 == 1);
        let log = synthesize(&sc, &[(e, v)], seed, &SynthOptions::default()).unwrap();
        let d = diagnose(&sc, &[log], &opts()).unwrap();
        if d.cause == e.as_str() {
            named += 1;
        }
        if let Some(est) = effect_value(&d, e) {
            let rel = (est.abs() - v).abs() / v;
            worst = worst.max(rel);
            if rel <= 0.10 {
                sized += 1;
            }
        }
        eprintln!("{e} seed {seed}: true {v:.4e} -> cause {} causes {:?} est {:?} base {:.4} ext {:.4} floor {:.4}", d.cause, d.causes, effect_value(&d, e), d.rmse_base_mrad, d.rmse_extended_mrad, d.noise_floor_mrad);
    }
    (named, sized, worst)
}

#[test]
fn probe() {
    let t = std::time::Instant::now();
    for e in EffectName::ALL {
        let r = run_effect(e, 2);
        eprintln!("{e}: {r:?}");
    }
    eprintln!("elapsed {:?}", t.elapsed());
}
