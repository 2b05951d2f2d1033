//! Every shipped closed-loop design holds margins an engineer signs, with one sample of
//! computation delay, on the exact linear reference: phase margin >= 35 deg, gain margin
//! >= 6 dB (upward and, for these conditionally stable PID loops, downward).

use cable_servo::analysis::linear::{margins_signable, LinearLoop};
use cable_servo::scenario::{Scenario, Study, BUILTIN};

#[test]
fn shipped_closed_loop_designs_have_signable_margins() {
    let mut checked = 0;
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
        let m = LinearLoop::new(p, &s.drive).margins(2000);
        if let Err(why) = margins_signable(&m) {
            panic!("{name}: {why}: {m:?}");
        }
        checked += 1;
    }
    assert!(checked >= 5, "only {checked} closed-loop scenarios found");
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
    assert!(margins_signable(&m).is_err());
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
/// in; a stable loop's slip keeps its own name.
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
}
