//! The friction memory's load law on synthetic logs: contacts whose slip thresholds grow
//! with the transmitted torque, a slack the torque takes up, or neither. Logs at several
//! jaw loads of one instrument (da Vinci-like geometry and encoders, white angle noise
//! before quantisation, load-cell noise, one log loaded the other way) are calibrated
//! jointly, and the memory's lag after a long travel is compared with the truth's at the
//! lightest and the heaviest load.

use cable_servo::identify::extra_effects::memory_thresholds_rad;
use cable_servo::identify::model::{prepare, Evaluator, LinParam, MemoryLaw, NlParam, Spec};
use cable_servo::identify::{synthesize, BenchLog, EffectName, IdentifyParams, SynthOptions};
use cable_servo::physics::effects::{contact_threshold, slack_width};
use cable_servo::physics::EffectsParams;
use cable_servo::scenario::Scenario;

/// Jaw loads of the logs, N m (one the other way: only magnitudes matter).
const LOADS: [f64; 4] = [0.02, -0.05, 0.08, 0.11];

/// A law's lag after a long travel at torque `m` (N m), rad: each play's weight times its
/// half width.
fn lag(fx: &EffectsParams, m: f64) -> f64 {
    let g = fx.friction_memory_threshold_growth_per_nm.unwrap_or(0.0);
    let contacts: f64 = fx
        .friction_memory_thresholds_rad
        .iter()
        .flatten()
        .zip(fx.friction_memory_weights.iter().flatten())
        .enumerate()
        .map(|(j, (r, w))| {
            // Weights that grow as |M|^p, where the calibration keeps them.
            let grown = fx
                .friction_memory_load_weights_per_nm
                .as_ref()
                .map_or(0.0, |v| {
                    v[j] * m
                        .abs()
                        .powf(fx.friction_memory_load_exponent.unwrap_or(1.0))
                });
            (w + grown) * contact_threshold(*r, g, m)
        })
        .sum();
    let slack = match (
        fx.friction_memory_slack_rad,
        fx.friction_memory_slack_taken_up_nm,
        fx.friction_memory_slack_weight,
    ) {
        (Some(s), Some(mu), Some(w)) => w * slack_width(s, mu, m),
        _ => 0.0,
    };
    contacts + slack
}

fn logs(truth: &EffectsParams, seed: u64) -> (Scenario, Vec<BenchLog>) {
    let base = Scenario::load("davinci_tool4", &[]).expect("shipped scenario");
    let logs = LOADS
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let sc = Scenario::load(
                "davinci_tool4",
                &[
                    format!("load.constant_nm={m}"),
                    "quasi_static.duration_s=20".into(),
                ],
            )
            .expect("shipped scenario");
            let o = SynthOptions {
                input_counts_per_rev: 8192.0,
                output_counts_per_rev: 4000.0,
                angle_noise_rad: 3e-4,
                load_noise_nm: 0.002,
                memory_law: Some(truth.clone()),
                ..SynthOptions::default()
            };
            let mut l = synthesize(&sc, &[], seed * 10 + i as u64, &o).expect("synthesis");
            l.source = format!("law-{seed}-{i}");
            l
        })
        .collect();
    (base, logs)
}

/// Joint calibration of the friction memory (the drive is the truth's) and the calibrated
/// law as `[effects]` keys.
fn calibrate(sc: &Scenario, logs: &[BenchLog]) -> EffectsParams {
    let ident = IdentifyParams::default();
    let prepared: Vec<_> = logs
        .iter()
        .map(|l| prepare(l, ident.max_rate_hz).expect("prepare"))
        .collect();
    let spec = Spec {
        drive: sc.drive.clone(),
        fit_mu: false,
        fit_pre: false,
        fit_g: false,
        fit_ratio: false,
        effects: vec![EffectName::DistributedFrictionMemory],
        ident,
        calibrated: None,
    };
    let mut ev = Evaluator::new(spec, &prepared);
    let all = vec![true; ev.rows()];
    let f = ev.fit(&all, None, 30).expect("fit");
    let nl = ev.nonlinear();
    let x = |k: MemoryLaw| {
        nl.iter()
            .position(|n| n.0 == NlParam::Memory(k))
            .map(|i| f.x[i])
    };
    let (_, thresholds) = ev.stroke_and_thresholds();
    let coef = |j: usize| {
        f.lin
            .iter()
            .position(|p| *p == LinParam::Effect(EffectName::DistributedFrictionMemory, j))
            .map(|i| f.coef[i])
            .unwrap_or(0.0)
    };
    let n = thresholds.len();
    let exponent = nl
        .iter()
        .position(|p| p.0 == NlParam::Effect(EffectName::DistributedFrictionMemory))
        .map(|i| f.x[i]);
    // The slack's weight follows the contacts' weights and, when kept, their load parts.
    let slack_column = if exponent.is_some() { 2 * n } else { n };
    EffectsParams {
        friction_memory_thresholds_rad: Some(thresholds.to_vec()),
        friction_memory_weights: Some((0..n).map(coef).collect()),
        friction_memory_load_weights_per_nm: exponent.map(|_| (n..2 * n).map(coef).collect()),
        friction_memory_load_exponent: exponent,
        friction_memory_threshold_growth_per_nm: x(MemoryLaw::Growth),
        friction_memory_slack_rad: x(MemoryLaw::Slack),
        friction_memory_slack_taken_up_nm: x(MemoryLaw::TakenUp),
        friction_memory_slack_weight: Some(coef(slack_column)),
        ..EffectsParams::default()
    }
}

/// Lag at the lightest and the heaviest load (rad): calibrated, then the truth's.
type Ends = ((f64, f64), (f64, f64));

/// [`Ends`] over three seeds.
fn run(truth: &EffectsParams) -> Vec<Ends> {
    let (lo, hi) = (0.02, 0.11);
    (1..=3)
        .map(|seed| {
            let (sc, l) = logs(truth, seed);
            let fit = calibrate(&sc, &l);
            let got = (lag(&fit, lo), lag(&fit, hi));
            let want = (lag(truth, lo), lag(truth, hi));
            println!(
                "seed {seed}: lag {:.2} -> {:.2} mrad (truth {:.2} -> {:.2}); growth {:?}, slack {:?} rad x {:?} up to {:?} N m",
                got.0 * 1e3,
                got.1 * 1e3,
                want.0 * 1e3,
                want.1 * 1e3,
                fit.friction_memory_threshold_growth_per_nm,
                fit.friction_memory_slack_rad,
                fit.friction_memory_slack_weight,
                fit.friction_memory_slack_taken_up_nm,
            );
            (got, want)
        })
        .collect()
}

/// Contacts off the identification grid (between its thresholds), as a real drive's are.
fn contacts() -> Vec<f64> {
    let r = memory_thresholds_rad(1.04);
    vec![(r[2] * r[3]).sqrt(), (r[4] * r[5]).sqrt()]
}

/// The change of the lag from the lightest to the heaviest load is recovered with its sign
/// and within 25 % of its size, the lag at either end within 15 %.
fn check(rows: &[Ends]) {
    for ((g0, g1), (w0, w1)) in rows {
        let (dg, dw) = (g1 - g0, w1 - w0);
        assert!(
            dg * dw > 0.0 && (dg / dw - 1.0).abs() < 0.25,
            "lag change {dg} rad against the truth's {dw}"
        );
        assert!((g0 / w0 - 1.0).abs() < 0.15, "light-load lag {g0} vs {w0}");
        assert!((g1 / w1 - 1.0).abs() < 0.15, "heavy-load lag {g1} vs {w1}");
    }
}

#[test]
fn thresholds_growing_with_the_load_are_recovered() {
    let truth = EffectsParams {
        friction_memory_thresholds_rad: Some(contacts()),
        friction_memory_weights: Some(vec![0.3, 0.2]),
        friction_memory_threshold_growth_per_nm: Some(10.0),
        ..EffectsParams::default()
    };
    check(&run(&truth));
}

#[test]
fn slack_taken_up_by_the_load_is_recovered() {
    let truth = EffectsParams {
        friction_memory_thresholds_rad: Some(contacts()),
        friction_memory_weights: Some(vec![0.3, 0.2]),
        friction_memory_slack_rad: Some(0.04),
        friction_memory_slack_taken_up_nm: Some(0.08),
        friction_memory_slack_weight: Some(0.9),
        ..EffectsParams::default()
    };
    check(&run(&truth));
}

/// Without load dependence the calibrated lag changes by less than 5 % of itself between
/// the lightest and the heaviest load.
#[test]
fn a_memory_without_load_dependence_gets_none() {
    let truth = EffectsParams {
        friction_memory_thresholds_rad: Some(contacts()),
        friction_memory_weights: Some(vec![0.3, 0.2]),
        ..EffectsParams::default()
    };
    for ((g0, g1), (w0, _)) in run(&truth) {
        assert!(
            (g1 - g0).abs() < 0.05 * w0,
            "lag {g0} -> {g1} rad for a load-free memory of {w0}"
        );
        assert!((g0 / w0 - 1.0).abs() < 0.15, "lag {g0} vs {w0}");
    }
}
