//! Regimes outside the drive's capacity are detected and named, never NaN or a panic.

use cable_servo::physics::{
    CableDrive, DriveFault, DriveParams, Half, HysteresisModel, LoadParams,
};
use cable_servo::scenario::QuasiStaticParams;
use cable_servo::signal::Signal;
use cable_servo::study::quasi_static::run_model;

#[path = "support/capstan.rs"]
mod capstan;

#[test]
fn slack_is_named_with_the_half_and_a_remedy() {
    let mut drive = CableDrive::new(
        DriveParams {
            preload_n: 10.0,
            ..DriveParams::default()
        },
        HysteresisModel::Memory,
    );
    // Capacity about 2*Tpre*ro = 2.05 N m.
    match drive.apply_torque(3.0) {
        Err(DriveFault::Slack {
            half,
            needed_preload_n,
            ..
        }) => {
            assert_eq!(half, Half::Lower);
            assert!(needed_preload_n > 10.0);
        }
        other => panic!("expected slack, got {other:?}"),
    }
    match drive.apply_torque(-3.0) {
        Err(DriveFault::Slack { half, .. }) => assert_eq!(half, Half::Upper),
        other => panic!("expected slack, got {other:?}"),
    }
    // Nothing was committed: the drive still carries a feasible load as if virgin.
    let fresh = CableDrive::new(drive.params().clone(), HysteresisModel::Memory)
        .trial_torque(1.0)
        .unwrap();
    let after = drive.apply_torque(1.0).unwrap();
    assert_eq!(fresh.tension_upper_n, after.tension_upper_n);
}

#[test]
fn gross_slip_on_a_short_pulley_wrap() {
    // Half a radian of pulley wrap per half: a slip zone of ln(T/Tpre)/mu reaches the
    // neutral point once the span tension rises by about 5 %.
    let params = DriveParams {
        pulley_wrap_rad: 1.0,
        ..DriveParams::default()
    };
    let mut drive = CableDrive::new(params, HysteresisModel::Memory);
    assert!(drive.apply_torque(0.5).is_ok());
    match drive.apply_torque(2.5) {
        Err(DriveFault::GrossSlip {
            half,
            slip_angle_rad,
            available_rad,
            tension_n,
        }) => {
            assert_eq!(half, Half::Upper);
            assert_eq!(available_rad, 0.5);
            assert!(slip_angle_rad > available_rad);
            // The demanded slip zone follows the capstan law.
            assert!((slip_angle_rad - (tension_n / 100.0).ln() / 0.2).abs() < 1e-9);
        }
        other => panic!("expected gross slip, got {other:?}"),
    }
}

#[test]
fn a_run_that_goes_slack_keeps_its_samples_up_to_the_fault() {
    let load = LoadParams {
        sine_nm: 4.0,
        sine_frequency_hz: 0.1,
        ..LoadParams::default()
    };
    let study = QuasiStaticParams {
        duration_s: 10.0,
        sample_rate_hz: 100.0,
        motion: Signal::Sine {
            amplitude_rad: 0.1,
            frequency_hz: 0.1,
            phase_rad: 0.0,
            offset_rad: 0.0,
        },
        models: vec![HysteresisModel::Memory],
        profile_times_s: vec![],
    };
    let params = DriveParams {
        preload_n: 15.0,
        ..DriveParams::default()
    };
    let trace = run_model(&params, &load, &study, HysteresisModel::Memory);
    let stop = trace.stop.expect("the run must stop");
    // As the loose span's tension falls towards zero its unloading slip zone,
    // ln(Tpre/T)/mu long, runs around the pulley to the neutral point just before the
    // span would go slack: either way the loose (upper, M < 0) half loses its grip.
    match stop.fault {
        DriveFault::Slack { half, .. } | DriveFault::GrossSlip { half, .. } => {
            assert_eq!(half, Half::Upper)
        }
    }
    // The closed form of the drive loaded from rest (tests/support/capstan.rs): the loose
    // span falls to 15 exp(-0.2 * 3 pi) = 2.278 N, where its pulley slip zone reaches the
    // neutral point, while the tight one rises to 36.42 N (the wraps' friction moves the two
    // unequally), so the drum carries 0.1025 (36.42 - 2.28) = 3.500 N m, more than the
    // 2*15*0.1025 = 3.075 N m of equal and opposite moves. 4 sin(2 pi 0.1 t) N m reaches
    // it at t* = asin(3.500/4)/(0.2 pi) = 1.6954 s. The run samples every 10 ms and stops at
    // the first sample whose load it cannot carry: the sample at or just after t*.
    let (capacity_nm, _, _) = capstan::gross_slip_torque_nm(&capstan::PAPER_DRIVE, 15.0);
    let t_star = (capacity_nm / 4.0).asin() / (2.0 * std::f64::consts::PI * 0.1);
    println!(
        "stopped at {} s ({:?}); closed form {capacity_nm} N m at {t_star} s",
        stop.t_s, stop.fault
    );
    assert!(
        stop.t_s >= t_star && stop.t_s < t_star + 0.01 + 1e-9,
        "stopped at {} s, closed form {t_star} s",
        stop.t_s
    );
    assert!(!trace.samples.is_empty());
    assert!(trace
        .samples
        .iter()
        .all(|s| s.transmission_error_rad.is_finite()
            && s.tension_lower_n > 0.0
            && s.tension_upper_n > 0.0));
    assert!(!trace.figures().complete);
}
