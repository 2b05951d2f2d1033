//! Diagnosis against synthetic logs with hidden effects of known size.

use cable_servo::identify::{
    diagnose, effect_value, synthesize, DiagnoseOptions, EffectName, Ringing, SynthOptions,
};
use cable_servo::io::benchlog::{read_bench_log, write_bench_log};
use cable_servo::scenario::Scenario;
use rand::{Rng, SeedableRng};

/// A slewing gimbal axis on the paper bench's drive: large sine scan, brake and unbalance
/// (the built-in `gimbal_ident` scenario).
const GIMBAL: &str = include_str!("../scenarios/gimbal_ident.toml");

fn scenario(triangle: bool) -> Scenario {
    let mut text = GIMBAL.to_string();
    if triangle {
        text = text.replace("kind = \"sine\"", "kind = \"triangle\"");
    }
    // IDENT_UNKNOWN='"cable_modulus_n","preload_n","friction_coefficient"' repeats the
    // statistics with every base parameter calibrated as well.
    if let Ok(u) = std::env::var("IDENT_UNKNOWN") {
        text = text.replace(
            "unknown = [\"cable_modulus_n\"]",
            &format!("unknown = [{u}]"),
        );
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
        EffectName::AngleDependentRatio => (5e-5, 5e-4),
        // Below 1e-4 rad/(N m) most of it hides in the calibrated cable modulus and what is
        // left is at the noise floor on this axis.
        EffectName::LoadCompliance => (1e-4, 1e-3),
        EffectName::DistributedFrictionMemory => (5e-5, 5e-4),
    }
}

fn opts() -> DiagnoseOptions {
    DiagnoseOptions {
        skip_play_operator: true,
        ..DiagnoseOptions::default()
    }
}

/// Options searching the library and the multi-wrap effects together.
fn opts_every() -> DiagnoseOptions {
    DiagnoseOptions {
        candidates: Some(EffectName::EVERY.to_vec()),
        ..opts()
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
        let o = if EffectName::EXTENDED.contains(&e) {
            opts_every()
        } else {
            opts()
        };
        let d = diagnose(&sc, &[log], &o).unwrap();
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

/// Seeds per effect in the default run; the `#[ignore]`d `*_many` tests use 50.
const SEEDS: u64 = 20;

fn check_effect(e: EffectName, seeds: u64) {
    let (named, sized, worst) = run_effect(e, seeds);
    let need = (0.95 * seeds as f64).ceil() as usize;
    eprintln!(
        "RATE {e}: named {named}/{seeds}, size within 10 % {sized}/{seeds}, worst size error {:.2} %",
        worst * 100.0
    );
    assert!(
        named >= need && sized >= need,
        "{e}: named {named}/{seeds}, size within 10 % {sized}/{seeds} (worst {:.1} %)",
        worst * 100.0
    );
}

macro_rules! effect_tests {
    ($($name:ident, $many:ident => $e:expr;)*) => {$(
        #[test]
        fn $name() {
            check_effect($e, SEEDS);
        }
        #[test]
        #[ignore]
        fn $many() {
            check_effect($e, 50);
        }
    )*};
}

effect_tests! {
    finds_input_pulley_runout, finds_input_pulley_runout_many => EffectName::InputPulleyRunout;
    finds_output_drum_runout, finds_output_drum_runout_many => EffectName::OutputDrumRunout;
    finds_encoder_delay, finds_encoder_delay_many => EffectName::EncoderDelay;
    finds_encoder_scale_error, finds_encoder_scale_error_many => EffectName::EncoderScaleError;
    finds_preload_relaxation, finds_preload_relaxation_many => EffectName::PreloadRelaxation;
    finds_bearing_friction, finds_bearing_friction_many => EffectName::BearingFriction;
    finds_cable_transport, finds_cable_transport_many => EffectName::CableTransport;
    finds_thermal_drift, finds_thermal_drift_many => EffectName::ThermalDrift;
}

/// Seeds per multi-wrap effect in the default run (each diagnosis searches all eleven
/// effects); the `#[ignore]`d `*_many` tests use 50.
const SEEDS_EXTENDED: u64 = 8;

macro_rules! extended_tests {
    ($($name:ident, $many:ident => $e:expr;)*) => {$(
        #[test]
        fn $name() {
            check_effect($e, SEEDS_EXTENDED);
        }
        #[test]
        #[ignore]
        fn $many() {
            check_effect($e, 50);
        }
    )*};
}

extended_tests! {
    finds_angle_dependent_ratio, finds_angle_dependent_ratio_many => EffectName::AngleDependentRatio;
    finds_load_compliance, finds_load_compliance_many => EffectName::LoadCompliance;
    finds_distributed_friction_memory, finds_distributed_friction_memory_many => EffectName::DistributedFrictionMemory;
}

fn clean_none_every(seeds: u64) {
    let mut none = 0;
    for seed in 0..seeds {
        let sc = scenario(seed % 2 == 1);
        let log = synthesize(&sc, &[], 2000 + seed, &SynthOptions::default()).unwrap();
        let d = diagnose(&sc, &[log], &opts_every()).unwrap();
        if d.cause == "none" {
            none += 1;
        } else {
            eprintln!(
                "clean (every effect searched) seed {seed}: {} {:?}",
                d.cause, d.causes
            );
        }
    }
    let need = (0.95 * seeds as f64).ceil() as usize;
    eprintln!("RATE clean, every effect searched: none {none}/{seeds}");
    assert!(none >= need, "clean logs called none {none}/{seeds}");
}

#[test]
fn clean_logs_are_none_with_every_effect_searched() {
    clean_none_every(SEEDS_EXTENDED);
}

#[test]
#[ignore]
fn clean_logs_are_none_with_every_effect_searched_many() {
    clean_none_every(50);
}

fn clean_none(seeds: u64) {
    let mut none = 0;
    for seed in 0..seeds {
        let sc = scenario(seed % 2 == 1);
        let log = synthesize(&sc, &[], 1000 + seed, &SynthOptions::default()).unwrap();
        let d = diagnose(&sc, &[log], &opts()).unwrap();
        if d.cause == "none" {
            none += 1;
        } else {
            eprintln!("clean seed {seed}: {} {:?}", d.cause, d.candidates);
        }
    }
    let need = (0.95 * seeds as f64).ceil() as usize;
    eprintln!("RATE clean: none {none}/{seeds}");
    assert!(none >= need, "clean logs called none {none}/{seeds}");
}

#[test]
fn clean_logs_are_none() {
    clean_none(SEEDS);
}

#[test]
#[ignore]
fn clean_logs_are_none_many() {
    clean_none(50);
}

#[test]
fn resonance_is_unexplained() {
    for seed in 0..4u64 {
        let sc = scenario(seed % 2 == 1);
        let synth = SynthOptions {
            ringing: Some(Ringing {
                amplitude_rad: 1e-4 * (1.0 + seed as f64 * 0.5),
                frequency_hz: 3.0 + seed as f64,
                decay_s: 0.5,
            }),
            ..SynthOptions::default()
        };
        let log = synthesize(&sc, &[], 2000 + seed, &synth).unwrap();
        let d = diagnose(&sc, &[log], &opts()).unwrap();
        assert_eq!(d.cause, "unexplained", "seed {seed}: {:?}", d.candidates);
        let w = d
            .residual_whiteness
            .expect("a 30 s log is long enough to test");
        assert!(
            w.p_value < 1e-3,
            "seed {seed}: ringing left a white residual {w:?}"
        );
    }
}

#[test]
fn two_effects_are_both_named() {
    let sc = scenario(false);
    let effects = [
        (EffectName::InputPulleyRunout, 1.0e-3),
        (EffectName::ThermalDrift, 3e-6),
    ];
    let log = synthesize(&sc, &effects, 7, &SynthOptions::default()).unwrap();
    let d = diagnose(&sc, &[log], &opts()).unwrap();
    assert_eq!(
        d.causes,
        vec!["input_pulley_runout", "thermal_drift"],
        "{:?}",
        d.candidates
    );
    for (e, v) in effects {
        let est = effect_value(&d, e).unwrap();
        assert!((est - v).abs() < 0.1 * v, "{e}: {est} vs {v}");
    }
}

#[test]
fn several_logs_and_held_out_log() {
    let sc = scenario(false);
    let logs: Vec<_> = (0..3)
        .map(|s| {
            synthesize(
                &sc,
                &[(EffectName::EncoderDelay, 8e-4)],
                300 + s,
                &SynthOptions::default(),
            )
            .unwrap()
        })
        .collect();
    let d = diagnose(
        &sc,
        &logs,
        &DiagnoseOptions {
            holdout_logs: vec![1],
            ..DiagnoseOptions::default()
        },
    )
    .unwrap();
    assert_eq!(d.cause, "encoder_delay");
    let est = effect_value(&d, EffectName::EncoderDelay).unwrap();
    assert!((est - 8e-4).abs() < 8e-5, "{est}");
    assert!(d.play_operator.is_some());
    assert!(d.rmse_extended_mrad < d.rmse_base_mrad);
}

#[test]
fn calibrates_modulus_preload_and_friction_with_uncertainty() {
    let mut sc = scenario(false);
    let truth = sc.drive.clone();
    // Start calibration away from the truth; three loads make the parameters separable.
    sc.drive.cable_modulus_n = 1.0e4;
    sc.drive.preload_n = 70.0;
    sc.drive.friction_coefficient = 0.3;
    sc.identify.as_mut().unwrap().unknown = vec![
        "cable_modulus_n".into(),
        "preload_n".into(),
        "friction_coefficient".into(),
    ];
    let logs: Vec<_> = [0.3, 0.7, 1.2]
        .iter()
        .enumerate()
        .map(|(k, b)| {
            let mut s = scenario(false);
            s.load.brake_nm = *b;
            synthesize(&s, &[], 400 + k as u64, &SynthOptions::default()).unwrap()
        })
        .collect();
    let d = diagnose(&sc, &logs, &opts()).unwrap();
    let g = d
        .params
        .iter()
        .find(|p| p.name == "cable_modulus_n")
        .unwrap();
    assert!(
        (g.value - truth.cable_modulus_n).abs() < 0.1 * truth.cable_modulus_n,
        "{g:?}"
    );
    assert!(g.std > 0.0 && g.std.is_finite());
    assert_eq!(d.cause, "none", "{:?}", d.candidates);
}

#[test]
fn log_round_trip_and_errors_name_line() {
    let sc = scenario(false);
    let log = synthesize(&sc, &[], 5, &SynthOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("a.csv");
    write_bench_log(&p, &log).unwrap();
    let back = read_bench_log(&p).unwrap();
    assert_eq!(back.len(), log.len());
    let text = std::fs::read_to_string(&p).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let header = lines.iter().position(|l| !l.starts_with('#')).unwrap();
    let bad_line = header + 3;
    let mut v: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
    v[bad_line - 1] = "0.020000,abc,0.0,0.0".to_string();
    std::fs::write(&p, v.join("\n")).unwrap();
    let err = read_bench_log(&p).unwrap_err().to_string();
    assert!(
        err.contains("a.csv") && err.contains("line") && err.contains("abc"),
        "{err} (line {bad_line})"
    );
    let d = diagnose(&sc, &[], &opts());
    assert!(d.is_err());
}

#[test]
fn writes_report_and_model() {
    let sc = scenario(false);
    let log = synthesize(
        &sc,
        &[(EffectName::InputPulleyRunout, 1e-3)],
        9,
        &SynthOptions::default(),
    )
    .unwrap();
    let d = diagnose(&sc, &[log], &DiagnoseOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let files = cable_servo::report::diagnosis::write_diagnosis(dir.path(), &d, None).unwrap();
    assert!(files.iter().all(|f| f.exists()));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("diagnosis.json")).unwrap())
            .unwrap();
    for k in [
        "cause",
        "causes",
        "rmse_base_mrad",
        "rmse_extended_mrad",
        "gain_percent",
        "params",
        "candidates",
    ] {
        assert!(json.get(k).is_some(), "{k}");
    }
    let m = dir.path().join("model.toml");
    cable_servo::report::diagnosis::save_model(&m, &sc, &d).unwrap();
    let back = Scenario::load(m.to_str().unwrap(), &[]).unwrap();
    let eps = back.effects.unwrap().input_pulley_runout.unwrap();
    assert!((eps - 1e-3).abs() < 1e-4);
}

/// Real data: calibrate on tool4_00 + tool4_09, score on tool4_05 (run with --ignored).
#[test]
#[ignore]
fn davinci_real_logs() {
    let dir = std::path::Path::new("/work/shared/real-data/davinci");
    let sc = Scenario::load("scenarios/davinci_tool4.toml", &[]).unwrap();
    let logs: Vec<_> = ["tool4_00.csv", "tool4_05.csv", "tool4_09.csv"]
        .iter()
        .map(|f| read_bench_log(&dir.join(f)).unwrap())
        .collect();
    let t = std::time::Instant::now();
    let d = diagnose(
        &sc,
        &logs,
        &DiagnoseOptions {
            holdout_logs: vec![1],
            ..DiagnoseOptions::default()
        },
    )
    .unwrap();
    eprintln!("{}", cable_servo::report::diagnosis::summary_text(&d));
    eprintln!("elapsed {:?}", t.elapsed());
    let out = std::path::Path::new("target/davinci_diagnosis");
    cable_servo::report::diagnosis::write_diagnosis(out, &d, None).unwrap();
    cable_servo::report::diagnosis::save_model(&out.join("davinci_tool4_model.toml"), &sc, &d)
        .unwrap();
}

#[test]
fn shipped_davinci_scenario_loads_with_effects() {
    let sc = Scenario::load("scenarios/davinci_tool4.toml", &[]).unwrap();
    let fx = sc.effects.unwrap();
    assert!(
        fx.angle_dependent_ratio_coefs.is_some()
            && fx.load_compliance_rad_per_nm.is_some()
            && fx.friction_memory_weights.is_some()
    );
    assert!(fx.validate().is_ok());
    assert!(sc.identify.unwrap().is_unknown("ratio"));
    let err = Scenario::load(
        "scenarios/davinci_tool4.toml",
        &["effects.bearing_frictoin_nm=1".into()],
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("bearing_friction_nm"), "{err}");
}

/// The absolute gain an effect must bring (`identify.min_gain_mrad`, 0.3 mrad on real
/// logs): a runout that is found by default is refused when its gain in mrad falls short,
/// with that reason, and the answer becomes `unexplained` (structure remains); the
/// threshold for `none` (`identify.none_within_floor`) moves the line between the two.
#[test]
fn absolute_gain_and_floor_thresholds_decide_as_set() {
    let sc = scenario(false);
    let log = synthesize(
        &sc,
        &[(EffectName::InputPulleyRunout, 3e-4)],
        11,
        &SynthOptions::default(),
    )
    .unwrap();
    let d = diagnose(&sc, std::slice::from_ref(&log), &opts()).unwrap();
    assert_eq!(d.cause, "input_pulley_runout", "{:?}", d.candidates);
    let gain_mrad = d.rmse_base_mrad - d.rmse_extended_mrad;
    let mut strict = sc.clone();
    if let Some(i) = strict.identify.as_mut() {
        i.min_gain_mrad = 2.0 * gain_mrad;
    }
    let d = diagnose(&strict, std::slice::from_ref(&log), &opts()).unwrap();
    assert_eq!(d.cause, "unexplained", "{:?}", d.candidates);
    assert!(
        d.candidates
            .iter()
            .any(|c| c.name == "input_pulley_runout" && c.verdict.contains("min_gain_mrad")),
        "{:?}",
        d.candidates
    );
    let ratio = d.rmse_base_mrad / d.noise_floor_mrad;
    assert!(
        1.1 * ratio <= 10.0,
        "the test needs a residual within 9 floors: {ratio}"
    );
    if let Some(i) = strict.identify.as_mut() {
        i.none_within_floor = 1.1 * ratio;
    }
    let d = diagnose(&strict, std::slice::from_ref(&log), &opts()).unwrap();
    assert_eq!(d.cause, "none", "ratio {ratio}");
}
