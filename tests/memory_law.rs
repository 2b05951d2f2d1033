//! The friction memory's load law on synthetic logs: contacts whose slip thresholds grow
//! with the transmitted torque, a slack the torque takes up, or neither. Logs at several
//! jaw loads of one instrument (da Vinci-like geometry and encoders, white angle noise
//! before quantisation, load-cell noise, one log loaded the other way) are calibrated
//! jointly, and the memory's lag after a long travel is compared with the truth's at the
//! lightest and the heaviest load. A drive whose free travel narrows with the load is
//! calibrated as one drive and checked log by log, left out in turn.

use cable_servo::identify::extra_effects::memory_thresholds_rad;
use cable_servo::identify::loo::leave_one_out;
use cable_servo::identify::model::{prepare, Evaluator, LinParam, MemoryLaw, NlParam, Spec};
use cable_servo::identify::startup::StartMode;
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

/// A log of `davinci_tool4` with `overrides`, its friction memory following `truth`'s law:
/// 8192 and 4000-count encoders, white angle noise before quantisation, load-cell noise.
fn law_log(truth: &EffectsParams, overrides: &[String], seed: u64) -> BenchLog {
    let sc = Scenario::load("davinci_tool4", overrides).expect("shipped scenario");
    let o = SynthOptions {
        input_counts_per_rev: 8192.0,
        output_counts_per_rev: 4000.0,
        angle_noise_rad: 3e-4,
        load_noise_nm: 0.002,
        memory_law: Some(truth.clone()),
        ..SynthOptions::default()
    };
    synthesize(&sc, &[], seed, &o).expect("synthesis")
}

fn logs(truth: &EffectsParams, seed: u64) -> (Scenario, Vec<BenchLog>) {
    let base = Scenario::load("davinci_tool4", &[]).expect("shipped scenario");
    let logs = LOADS
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let overrides = [
                format!("load.constant_nm={m}"),
                "quasi_static.duration_s=20".into(),
            ];
            let mut l = law_log(truth, &overrides, seed * 10 + i as u64);
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

/// Straight-line slope of output on input over a whole log.
fn slope(l: &BenchLog) -> f64 {
    let (x, y) = (&l.theta_in_rad, &l.theta_out_rad);
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    sxy / sxx
}

/// Another drive of the da Vinci kind (ratio 1.13): 0.1 rad of free travel at no load,
/// taken up by 0.045 N m, over two contacts whose thresholds grow with the load. Its logs
/// at five loads from 10 % to 40 % differ in whole-log slope by 8.7 %, so they must be
/// calibrated together as one drive. Left out in turn, each is predicted better than by
/// the base model and by a play operator fitted to the log itself, and none is named as
/// disagreeing. Scanned one parameter at a time, the fold without the 0.034 N m log
/// stopped where the slack is taken up below every load (15.9 mrad held out against the
/// play operator's 4.3, and a pull of -615 %).
#[test]
fn a_drive_whose_free_travel_narrows_with_the_load_is_one_drive() {
    let r = memory_thresholds_rad(1.04);
    let truth = EffectsParams {
        friction_memory_thresholds_rad: Some(vec![(r[2] * r[3]).sqrt(), (r[4] * r[5]).sqrt()]),
        friction_memory_weights: Some(vec![0.3, 0.3]),
        friction_memory_threshold_growth_per_nm: Some(3.0),
        friction_memory_slack_rad: Some(0.1),
        friction_memory_slack_taken_up_nm: Some(0.045),
        friction_memory_slack_weight: Some(0.8),
        ..EffectsParams::default()
    };
    let radius = "drive.pulley_radius_m=0.0046".to_string();
    let logs: Vec<BenchLog> = [0.011, 0.018, 0.026, 0.034, 0.044]
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let overrides = [format!("load.constant_nm={m}"), radius.clone()];
            let mut l = law_log(&truth, &overrides, 100 + i as u64);
            l.source = format!("load-{m}");
            l
        })
        .collect();
    let slopes: Vec<f64> = logs.iter().map(slope).collect();
    let moved = slopes[4] / slopes[0] - 1.0;
    assert!(moved > 0.05, "whole-log slopes {slopes:?}");

    let sc = Scenario::load("davinci_tool4", &[radius]).expect("shipped scenario");
    let ident = sc.identify.clone().unwrap_or_default();
    let t = leave_one_out(
        &sc.drive,
        &ident,
        &logs,
        &[EffectName::DistributedFrictionMemory],
        StartMode::Detect,
    )
    .unwrap_or_else(|e| panic!("one drive at five loads: {e}"));
    for row in &t.rows {
        println!(
            "{}: base {:.2}, extended {:.2}, play {} mrad, pull {:.1} %",
            row.log,
            row.base_mrad,
            row.extended_mrad,
            row.play_mrad.map_or("failed".into(), |p| format!("{p:.2}")),
            row.pull_percent
        );
    }
    assert_eq!(t.wins_over_base, 5, "{:?}", t.rows);
    assert_eq!(t.wins_over_play, 5, "{:?}", t.rows);
    assert!(t.disagreeing.is_empty(), "{:?}", t.disagreeing);
    let shared = |name: &str| {
        t.shared
            .iter()
            .map(|s| &s.estimate)
            .find(|p| p.name == name)
            .map(|p| p.value)
            .unwrap_or_else(|| panic!("{name} not calibrated"))
    };
    let (slack, taken_up) = (
        shared("friction_memory_slack_rad"),
        shared("friction_memory_slack_taken_up_nm"),
    );
    println!("slack {slack:.4} rad, taken up at {taken_up:.4} N m");
    assert!((slack / 0.1 - 1.0).abs() < 0.15, "slack {slack} rad");
    assert!(
        (taken_up / 0.045 - 1.0).abs() < 0.15,
        "taken up at {taken_up} N m"
    );
}
