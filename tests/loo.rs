//! Calibration across logs: bad mixes of logs are refused with a message, a stroke too
//! short to tell a ratio shape from runout is reported as a limit, and a synthetic
//! instrument's extension wins on logs it did not see.

use cable_servo::identify::loo::{leave_one_out, loo_text};
use cable_servo::identify::startup::StartMode;
use cable_servo::identify::{synthesize, BenchLog, EffectName, SynthOptions};
use cable_servo::scenario::Scenario;

fn gimbal(overrides: &[&str]) -> Scenario {
    let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    Scenario::load("gimbal_ident", &o).expect("built-in scenario")
}

fn log(sc: &Scenario, effects: &[(EffectName, f64)], seed: u64, o: SynthOptions) -> BenchLog {
    let mut l = synthesize(sc, effects, seed, &o).expect("synthetic log");
    l.source = format!("synthetic-{seed}");
    l
}

fn err_of(sc: &Scenario, logs: &[BenchLog]) -> String {
    let ident = sc.identify.clone().unwrap_or_default();
    match leave_one_out(&sc.drive, &ident, logs, &[], StartMode::Detect) {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn mixed_sample_rates_are_refused() {
    let sc = gimbal(&["quasi_static.duration_s=10"]);
    let a = log(&sc, &[], 1, SynthOptions::default());
    let b = log(
        &sc,
        &[],
        2,
        SynthOptions {
            sample_rate_hz: Some(200.0),
            ..SynthOptions::default()
        },
    );
    let e = err_of(&sc, &[a, b]);
    assert!(
        e.contains("synthetic-2") && e.contains("sample rate"),
        "{e}"
    );
}

#[test]
fn different_instruments_are_refused() {
    let sc = gimbal(&["quasi_static.duration_s=10"]);
    let other = gimbal(&["quasi_static.duration_s=10", "drive.pulley_radius_m=0.025"]);
    let a = log(&sc, &[], 1, SynthOptions::default());
    let b = log(&other, &[], 2, SynthOptions::default());
    let e = err_of(&sc, &[a, b]);
    assert!(e.contains("different instrument"), "{e}");
}

#[test]
fn log_without_a_reversal_is_refused() {
    let sc = gimbal(&[]);
    let a = log(&sc, &[], 1, SynthOptions::default());
    let short = log(
        &sc,
        &[],
        2,
        SynthOptions {
            duration_s: Some(1.0),
            ..SynthOptions::default()
        },
    );
    let e = err_of(&sc, &[a, short]);
    assert!(e.contains("never reverses"), "{e}");
}

#[test]
fn short_stroke_reports_shape_and_runout_as_indistinguishable() {
    let sc = gimbal(&[
        "quasi_static.duration_s=10",
        "quasi_static.motion.amplitude_rad=0.5",
    ]);
    // One instrument: the same seed draws the same shape; two record lengths make two logs.
    let logs: Vec<BenchLog> = [10.0, 12.0]
        .iter()
        .map(|d| {
            log(
                &sc,
                &[(EffectName::AngleDependentRatio, 2e-4)],
                5,
                SynthOptions {
                    duration_s: Some(*d),
                    ..SynthOptions::default()
                },
            )
        })
        .collect();
    let ident = sc.identify.clone().unwrap_or_default();
    let t = leave_one_out(
        &sc.drive,
        &ident,
        &logs,
        &[EffectName::AngleDependentRatio],
        StartMode::Detect,
    )
    .expect("leave-one-out");
    let text = loo_text(&t);
    assert!(text.contains("may equally be pulley runout"), "{text}");
    // The shape still transfers to the log left out.
    assert_eq!(t.wins_over_base, 2, "{text}");
}

#[test]
fn one_log_is_not_enough() {
    let sc = gimbal(&["quasi_static.duration_s=10"]);
    let a = log(&sc, &[], 1, SynthOptions::default());
    let e = err_of(&sc, &[a]);
    assert!(e.contains("at least two"), "{e}");
}
