//! Every shipped closed-loop design holds margins an engineer signs, with one sample of
//! computation delay, on the exact linear reference: phase margin >= 35 deg, gain margin
//! >= 6 dB (upward and, for these conditionally stable PID loops, downward).

use cable_servo::closed_loop::linear::{margins_signable, LinearLoop};
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
