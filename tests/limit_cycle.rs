//! Hunting at rest: a loop closed on the output encoder with integral action against a
//! brake whose breakaway exceeds its sliding torque (stiction) stick-slips around the
//! target for ever; the same loop against a brake without stiction settles. Every
//! closed-loop run reports which.

use cable_servo::closed_loop::{run_closed_loop, RunOptions};
use cable_servo::metrics::limit_cycle::LimitCycle;
use cable_servo::scenario::Scenario;

fn hunt(breakaway_nm: f64) -> LimitCycle {
    let sets: Vec<String> = [
        "closed_loop.controller.feedback=\"output\"",
        // Linearly stable on the exact reference (PM 24 deg, GM 7.8 dB): whatever cycles
        // is the friction's doing.
        "closed_loop.controller.kp=40",
        "closed_loop.controller.ki=1000",
        "closed_loop.controller.kd=0.5",
        "closed_loop.reference={kind=\"step\", amplitude_rad=0.001, time_s=0.2}",
        "closed_loop.duration_s=6",
        "closed_loop.metrics_start_s=0.1",
        "closed_loop.modes=[\"none\"]",
    ]
    .iter()
    .map(|s| s.to_string())
    .chain([format!("load.brake_breakaway_nm={breakaway_nm}")])
    .collect();
    let s = Scenario::load("eots_tracking", &sets).unwrap_or_else(|e| panic!("{e}"));
    let r = run_closed_loop(&s, &RunOptions::metrics_only()).unwrap_or_else(|e| panic!("{e}"));
    r.modes[0].limit_cycle.clone()
}

#[test]
fn stiction_under_integral_action_hunts_and_is_reported() {
    match hunt(1.2) {
        LimitCycle::Detected {
            amplitude_mrad,
            frequency_hz,
            start_s,
            cycles,
        } => {
            println!(
                "{amplitude_mrad} mrad at {frequency_hz} Hz from {start_s} s, {cycles} cycles"
            );
            assert!(
                amplitude_mrad > 0.5 && amplitude_mrad < 5.0,
                "{amplitude_mrad}"
            );
            assert!(frequency_hz > 1.0 && frequency_hz < 5.0, "{frequency_hz}");
            assert!(start_s > 0.2 && start_s < 2.0, "{start_s}");
        }
        other => panic!("no limit cycle found: {other:?}"),
    }
    // Breakaway equal to the sliding torque: no stiction, the loop settles.
    let calm = hunt(0.7);
    assert!(matches!(calm, LimitCycle::None { .. }), "{calm:?}");
}

#[test]
fn a_tracking_run_is_not_judged() {
    let s = Scenario::load("eots_tracking", &["closed_loop.duration_s=3".to_string()])
        .unwrap_or_else(|e| panic!("{e}"));
    let r = run_closed_loop(&s, &RunOptions::metrics_only()).unwrap_or_else(|e| panic!("{e}"));
    assert!(r
        .modes
        .iter()
        .all(|m| m.limit_cycle == LimitCycle::NotJudged));
}
