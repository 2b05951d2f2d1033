//! Every shipped closed-loop design holds margins an engineer signs, with one sample of
//! computation delay, on the exact linear reference: phase margin >= 35 deg, gain margin
//! >= 6 dB (upward and, for these conditionally stable PID loops, downward).

use cable_servo::analysis::linear::LinearLoop;
use cable_servo::analysis::verdict;
use cable_servo::closed_loop::{ClosedLoopSource, Requirements};
use cable_servo::scenario::{Scenario, Study, BUILTIN};

/// Every requirement of a design except its pointing error (which the failing examples
/// miss, and say so): stability and margins at each stiffness of the operating range.
fn margin_failures(s: &Scenario) -> Vec<String> {
    let setup = s.closed_loop_setup().unwrap();
    let v = verdict::evaluate(&setup).unwrap();
    v.checks
        .iter()
        .filter(|c| c.requirement != "pointing" && !c.passes)
        .map(|c| c.sentence())
        .collect()
}

#[test]
fn shipped_closed_loop_designs_have_signable_margins() {
    let mut checked = 0;
    let signable = Requirements::default();
    for (name, _) in BUILTIN {
        let s = Scenario::load(name, &[]).unwrap();
        if s.study != Study::ClosedLoop {
            continue;
        }
        let p = s.closed_loop.as_ref().unwrap();
        assert!(
            p.controller.computation_delay_samples >= 1.0,
            "{name}: computation_delay_samples = {} (at least one sample)",
            p.controller.computation_delay_samples
        );
        // Never loosened: what an engineer signs is the least a shipped design declares.
        let r = &p.requirements;
        assert!(
            r.min_phase_margin_deg >= signable.min_phase_margin_deg,
            "{name}"
        );
        assert!(
            r.min_gain_margin_db >= signable.min_gain_margin_db,
            "{name}"
        );
        assert!(r.max_ms <= signable.max_ms, "{name}");
        let failures = margin_failures(&s);
        assert!(failures.is_empty(), "{name}: {failures:?}");
        checked += 1;
    }
    assert!(checked >= 5, "only {checked} closed-loop scenarios found");
}

/// Every gain and phase crossover is listed: the count equals the sign changes of
/// `|L| - 1` and of `Im L` (with `Re L < 0`) on an independent, finer grid; each listed
/// crossover lies on `|L| = 1` with the phase margin read from `arg L` there, and the worst
/// is the one the summary reports.
#[test]
fn margins_list_every_crossing_and_judge_by_the_worst() {
    let s = Scenario::load("eots_tracking", &[]).unwrap();
    let lin = LinearLoop::new(s.closed_loop.as_ref().unwrap(), &s.drive);
    let m = lin.margins(4000);
    assert!(m.stable);
    let (lo, hi, n) = (0.1_f64, lin.nyquist_hz() * 0.9999, 60_000);
    let f = |i: usize| lo * (hi / lo).powf(i as f64 / (n - 1) as f64);
    let (mut gain, mut phase) = (0, 0);
    let mut prev = lin.loop_gain(f(0));
    for i in 1..n {
        let l = lin.loop_gain(f(i));
        if (prev.norm() - 1.0) * (l.norm() - 1.0) < 0.0 {
            gain += 1;
        }
        if prev.im * l.im < 0.0 && (prev.re + l.re) < 0.0 {
            phase += 1;
        }
        prev = l;
    }
    assert!(gain >= 2, "this loop crosses |L| = 1 several times: {gain}");
    assert_eq!(m.gain_crossovers.len(), gain, "{m:?}");
    assert_eq!(m.phase_crossovers.len(), phase, "{m:?}");
    for c in &m.gain_crossovers {
        let l = lin.loop_gain(c.frequency_hz);
        assert!((l.norm() - 1.0).abs() < 1e-9, "{c:?}: |L| = {}", l.norm());
        let pm = 180.0 - l.arg().to_degrees().abs();
        assert!((pm - c.phase_margin_deg).abs() < 1e-9, "{c:?}");
    }
    let worst = m
        .gain_crossovers
        .iter()
        .map(|c| c.phase_margin_deg)
        .fold(f64::INFINITY, f64::min);
    assert_eq!(m.phase_margin_deg, Some(worst));
    // An unstable loop has no margins at all: only its pole.
    let u = Scenario::load("eots_tracking", &["closed_loop.controller.kd=10".into()]).unwrap();
    let mu = LinearLoop::new(u.closed_loop.as_ref().unwrap(), &u.drive).margins(4000);
    assert!(!mu.stable);
    assert!(mu.gain_crossovers.is_empty() && mu.phase_crossovers.is_empty());
    assert_eq!((mu.phase_margin_deg, mu.ms), (None, None));
    assert!(mu.instability.is_some_and(|i| i.pole_magnitude > 1.0));
}

/// The test above can fail: the gains eots_tracking shipped with before (crossover near
/// 1 kHz, 10 kHz sampling) are unstable once the command comes one sample late.
#[test]
fn the_former_fast_gains_fail_with_one_sample_of_delay() {
    let s = Scenario::load(
        "eots_tracking",
        &[
            "closed_loop.controller.sample_rate_hz=10000".into(),
            "closed_loop.controller.kp=1000".into(),
            "closed_loop.controller.ki=60000".into(),
            "closed_loop.controller.kd=4.5".into(),
            "closed_loop.controller.derivative_filter_hz=1000".into(),
        ],
    )
    .unwrap();
    let p = s.closed_loop.as_ref().unwrap();
    let m = LinearLoop::new(p, &s.drive).margins(2000);
    assert!(!m.stable, "{m:?}");
    assert!(margin_failures(&s).iter().any(|f| f.starts_with("stable")));
    // Without the delay the same loop is stable but its phase margin is thin.
    let s0 = Scenario::load(
        "eots_tracking",
        &[
            "closed_loop.controller.sample_rate_hz=10000".into(),
            "closed_loop.controller.kp=1000".into(),
            "closed_loop.controller.ki=60000".into(),
            "closed_loop.controller.kd=4.5".into(),
            "closed_loop.controller.derivative_filter_hz=1000".into(),
            "closed_loop.controller.computation_delay_samples=0".into(),
        ],
    )
    .unwrap();
    let m0 = LinearLoop::new(s0.closed_loop.as_ref().unwrap(), &s0.drive).margins(2000);
    assert!(m0.stable, "{m0:?}");
    assert!(m0.phase_margin_deg.unwrap() < 35.0, "{m0:?}");
}

/// Gains far too high: the run stops, and the stop is named as the loop's instability
/// (growth rate, frequency, the gains to check) rather than as the slack or slip it ends
/// in; a stable loop's slip keeps its own name, and so does a slip that comes before an
/// unstable mode has grown.
#[test]
fn an_unstable_loop_is_named_before_the_slack_it_causes() {
    use cable_servo::closed_loop::{run_closed_loop, Completion, RunOptions, StopKind};
    let run = |sets: &[&str]| {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        let s = Scenario::load("eots_tracking", &sets).unwrap_or_else(|e| panic!("{e}"));
        let r = run_closed_loop(&s, &RunOptions::metrics_only()).unwrap_or_else(|e| panic!("{e}"));
        r.modes[0].completion.clone()
    };
    // Every gain five times (the gain margin is 10 dB), no current limit and a light
    // preload, so the growing oscillation slips the cable instead of saturating the
    // amplifier.
    let hot = run(&[
        "drive.preload_n=20",
        "closed_loop.controller.kp=1500",
        "closed_loop.controller.ki=100000",
        "closed_loop.controller.kd=12.5",
        "closed_loop.motor.current_limit_a=10000",
        "closed_loop.duration_s=1",
        "closed_loop.metrics_start_s=0.1",
        "closed_loop.modes=[\"none\"]",
    ]);
    match hot {
        Completion::Incomplete { fault, kind, .. } => {
            assert_eq!(kind, StopKind::Unstable, "{fault}");
            assert!(fault.contains("the loop is unstable"), "{fault}");
            assert!(fault.contains("kp = 1500"), "{fault}");
            assert!(fault.contains("1/s at"), "{fault}");
        }
        Completion::Complete => panic!("five times the gains ran to the end"),
    }
    let slips = run(&[
        "drive.preload_n=1.5",
        "closed_loop.duration_s=0.5",
        "closed_loop.metrics_start_s=0.1",
        "closed_loop.modes=[\"none\"]",
    ]);
    assert!(
        matches!(
            slips,
            Completion::Incomplete {
                kind: StopKind::GrossSlip,
                ..
            }
        ),
        "{slips:?}"
    );
    // A slightly unstable loop (its mode grows at about 35 1/s) on a preload too low for
    // the load: the cable slips within 11 ms, long before that mode has grown tenfold, so
    // the slip keeps its name and the instability is told beside it.
    let early = run(&[
        "drive.preload_n=3",
        "closed_loop.controller.ki=200000",
        "closed_loop.duration_s=1",
        "closed_loop.metrics_start_s=0.1",
        "closed_loop.modes=[\"memory\"]",
    ]);
    match early {
        Completion::Incomplete {
            fault,
            kind,
            time_s,
        } => {
            assert_eq!(kind, StopKind::GrossSlip, "{fault}");
            assert!(time_s < 0.05, "{time_s} s: {fault}");
            assert!(fault.contains("also unstable"), "{fault}");
        }
        Completion::Complete => panic!("a 3 N preload carried the load"),
    }
}
