//! Invariants of the capstan memory rule over random load histories (physics.md section 3).

use cable_servo::physics::wrap::WrapRegion;
use cable_servo::physics::{CableDrive, DriveParams, HysteresisModel};
use proptest::prelude::*;

const MU: f64 = 0.2;
const TPRE: f64 = 100.0;

fn bench() -> DriveParams {
    DriveParams::default()
}

/// Transmitted torques safely inside the bench drive's capacity (slack near 20 N m).
fn torque_history() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(-6.0f64..6.0, 1..60)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Slope bound, equilibrium, length constraint and tension bounds after every step.
    #[test]
    fn every_state_obeys_friction_and_equilibrium(history in torque_history()) {
        let p = bench();
        let mut drive = CableDrive::new(p.clone(), HysteresisModel::Memory);
        let (mut lo, mut hi) = (TPRE, TPRE);
        for &m in &history {
            let s = drive.apply_torque(m).unwrap();
            // Equilibrium of the drum and the constant-length constraint.
            prop_assert!((p.drum_radius_m * (s.tension_upper_n - s.tension_lower_n) - m).abs() < 1e-9);
            prop_assert!((s.elongation_upper_m + s.elongation_lower_m).abs() < 1e-15);
            lo = lo.min(s.tension_upper_n).min(s.tension_lower_n);
            hi = hi.max(s.tension_upper_n).max(s.tension_lower_n);
            for half in [drive.upper(), drive.lower()] {
                // |d ln T/ds| <= mu on every segment. Breakpoint positions and tensions each
                // carry rounding of about 1e-15, which dominates the slope of the
                // micro-segments a dithering load leaves: hence the absolute floor.
                for w in half.wrap().breakpoints().windows(2) {
                    let ((s0, t0), (s1, t1)) = (w[0], w[1]);
                    let rise = (t1 / t0).ln().abs();
                    prop_assert!(rise <= MU * (s1 - s0) * (1.0 + 1e-9) + 1e-13, "segment {s0}..{s1}: {t0} -> {t1}");
                }
                // Friction cannot create tension beyond what the boundary ever carried.
                let tb = half.wrap().boundary_tension_n();
                for (_, t) in half.drum_breakpoints(tb).into_iter().chain(half.pulley_breakpoints(tb)) {
                    prop_assert!(t >= lo * (1.0 - 1e-12) && t <= hi * (1.0 + 1e-12));
                }
            }
        }
    }

    /// A boundary excursion beyond every earlier one wipes out the whole history of a region.
    #[test]
    fn larger_excursion_wipes_out_history(
        history in prop::collection::vec(70.0f64..140.0, 1..40),
        extra in 1.01f64..3.0,
    ) {
        // Long enough that no zone reaches the inner end.
        let mut region = WrapRegion::new(0.1, 50.0, MU, TPRE, 1.4e4);
        for &t in &history {
            region.commit(t);
        }
        // Dips reach at most ln(Tpre/min)/mu: the new rising zone must reach further.
        let min = history.iter().copied().fold(TPRE, f64::min);
        let max = history.iter().copied().fold(TPRE, f64::max);
        let big = (TPRE * TPRE / min).max(max) * extra;
        region.commit(big);
        let mut virgin = WrapRegion::new(0.1, 50.0, MU, TPRE, 1.4e4);
        virgin.commit(big);
        let a = region.breakpoints();
        let b = virgin.breakpoints();
        prop_assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(&b) {
            prop_assert!((x.0 - y.0).abs() < 1e-9 && (x.1 - y.1).abs() < 1e-9 * y.1);
        }
        prop_assert!((region.elongation_m() - virgin.elongation_m()).abs() < 1e-15);
    }

    /// On a first loading (monotone from the preloaded state) memory and memoryless agree.
    #[test]
    fn memoryless_equals_memory_on_first_loading(
        mut steps in prop::collection::vec(0.0f64..8.0, 1..30),
        sign in prop::bool::ANY,
    ) {
        steps.sort_by(f64::total_cmp);
        let s = if sign { 1.0 } else { -1.0 };
        let mut memory = CableDrive::new(bench(), HysteresisModel::Memory);
        let mut memoryless = CableDrive::new(bench(), HysteresisModel::Memoryless);
        for &m in &steps {
            let a = memory.apply_torque(s * m).unwrap();
            let b = memoryless.apply_torque(s * m).unwrap();
            prop_assert!((a.tension_upper_n - b.tension_upper_n).abs() < 1e-10);
            prop_assert!((a.transmission_error_rad - b.transmission_error_rad).abs() < 1e-12 * b.transmission_error_rad.abs() + 1e-18);
        }
    }

    /// The memoryless model has no load-vs-error hysteresis: the same load gives the same
    /// error whatever came before.
    #[test]
    fn memoryless_forgets(history in torque_history(), m in -6.0f64..6.0) {
        let mut drive = CableDrive::new(bench(), HysteresisModel::Memoryless);
        let fresh = drive.trial_torque(m).unwrap();
        for &h in &history {
            drive.apply_torque(h).unwrap();
        }
        let after = drive.apply_torque(m).unwrap();
        // Each solve stops within 1e-13 of the tension (about 1e-15 rad of transmission
        // error on the bench); two solves from different starting points may differ by a few
        // of those.
        prop_assert!((fresh.transmission_error_rad - after.transmission_error_rad).abs() < 1e-14);
    }
}

/// A partial reversal leaves a tension bump that the memoryless model does not have.
#[test]
fn partial_reversal_differs_from_memoryless() {
    let mut memory = CableDrive::new(bench(), HysteresisModel::Memory);
    let mut memoryless = CableDrive::new(bench(), HysteresisModel::Memoryless);
    for m in [1.3, 0.0] {
        memory.apply_torque(m).unwrap();
        memoryless.apply_torque(m).unwrap();
    }
    // At zero load the memory model keeps a residual error of the opposite... any sign: it
    // must not return to zero, while the memoryless model does.
    let e_mem = memory.state().transmission_error_rad;
    let e_less = memoryless.state().transmission_error_rad;
    assert!(e_less.abs() < 1e-15);
    assert!(e_mem.abs() > 1e-6, "{e_mem}");
}
