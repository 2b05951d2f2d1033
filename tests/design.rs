//! Closed-loop design answers are consistent with direct runs on either side of them.

use cable_servo::closed_loop::{run_closed_loop, CompensationMode, RunOptions};
use cable_servo::design::{largest_meeting_target, Question};
use cable_servo::scenario::Scenario;
use cable_servo::signal::Signal;

fn peak_passes(s: &Scenario) -> bool {
    let options = RunOptions {
        modes: Some(vec![CompensationMode::Memory]),
        ..RunOptions::metrics_only()
    };
    let r = run_closed_loop(s, &options).unwrap();
    r.modes[0].metrics.passes_target
}

#[test]
fn fastest_scan_passes_and_a_faster_one_fails() {
    let base = Scenario::load("eots_scan", &[]).unwrap();
    let tol = 0.05;
    let answer = largest_meeting_target(
        &base,
        Question::FastestScan,
        CompensationMode::Memory,
        (0.1, 3.0),
        tol,
    )
    .unwrap();
    let f = answer
        .value
        .expect("the nominal scan passes, so some speed must");
    assert!(f > 0.5, "the built-in scan at 0.5 Hz passes: {f}");
    let at = |hz: f64| {
        let mut s = base.clone();
        if let Some(cl) = s.closed_loop.as_mut() {
            if let Signal::Triangle { frequency_hz, .. } = &mut cl.reference {
                *frequency_hz = hz;
            }
        }
        s
    };
    assert!(peak_passes(&at(f)));
    assert!(!peak_passes(&at(f + 2.0 * tol)));
}

#[test]
fn a_search_range_without_a_readable_end_is_refused_before_any_run() {
    let base = Scenario::load("eots_scan", &[]).unwrap();
    for (range, tol) in [
        ((0.05, f64::INFINITY), 0.02),
        ((0.05, 1e308), 0.02),
        ((-1.0, 3.0), 0.02),
        ((0.05, 3.0), f64::INFINITY),
    ] {
        let e = largest_meeting_target(
            &base,
            Question::LargestLoad,
            CompensationMode::Memory,
            range,
            tol,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("0 <= lo < hi <= 1e6") && !e.contains("inf "),
            "{e}"
        );
    }
}
