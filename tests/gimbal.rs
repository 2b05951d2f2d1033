//! The stabilised gimbal: base motion, gyro, rate loop, filters, disturbance observer,
//! line-of-sight metrics, the error budget and `compare`, checked against the exact
//! sampled linear reference (computed, not simulated) and against their definitions.

use cable_servo::analysis::budget::{error_budget, BudgetEffect};
use cable_servo::analysis::freqresp::{measure, FreqRespParams, FreqResponse, LoopPoint};
use cable_servo::analysis::linear::LinearLoop;
use cable_servo::closed_loop::{
    run_closed_loop, ClosedLoopSource, Completion, RunOptions, StopKind,
};
use cable_servo::scenario::Scenario;

fn scenario(name: &str, sets: &[&str]) -> Scenario {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    Scenario::load(name, &sets).unwrap_or_else(|e| panic!("{e}"))
}

/// What the linear reference leaves out, switched off: the cable's hysteresis, friction,
/// quantisation and noise.
const LINEAR: [&str; 6] = [
    "closed_loop.cable=\"linear\"",
    "load.brake_nm=0",
    "load.brake_breakaway_nm=0",
    "closed_loop.motor.coulomb_nm=0",
    "closed_loop.sensors.quantize=false",
    "closed_loop.modes=[\"none\"]",
];

fn stabilised(extra: &[&str]) -> Scenario {
    let mut sets: Vec<&str> = LINEAR.to_vec();
    sets.extend([
        "closed_loop.gyro.noise_density_rad_s_per_sqrt_hz=0",
        "closed_loop.gyro.quantization_rad_s=0",
    ]);
    sets.extend(extra);
    scenario("gimbal_stabilized", &sets)
}

fn run(s: &Scenario, spec: &FreqRespParams) -> FreqResponse {
    let setup = s.closed_loop_setup().unwrap_or_else(|e| panic!("{e}"));
    measure(setup, spec, 0, &|| {}).unwrap_or_else(|e| panic!("{e}"))
}

fn db(c: nalgebra::Complex<f64>) -> f64 {
    20.0 * c.norm().log10()
}

/// Simulated line of sight over base angle against the exact sampled sensitivity from
/// base motion to line of sight, 0.5 to 100 Hz, within 0.5 dB: for a PID on the motor
/// encoder (the drum follows the base), for the stabilised loop, and for the stabilised
/// loop with every part of the law in use.
#[test]
fn base_motion_to_line_of_sight_matches_the_exact_sampled_sensitivity() {
    let designs = [
        ("encoder PID", scenario("eots_tracking", &LINEAR)),
        ("gyro rate loop, notch", stabilised(&[])),
        (
            "every part",
            stabilised(&[
                "closed_loop.controller.rate_measurement_filters=[{kind=\"low_pass2\",corner_hz=1500.0}]",
                "closed_loop.controller.rate_command_filters=[{kind=\"lead_lag\",zero_hz=60.0,pole_hz=30.0}]",
                "closed_loop.controller.measurement_filters=[{kind=\"low_pass1\",corner_hz=400.0}]",
                "closed_loop.controller.disturbance_observer={bandwidth_hz=3.0}",
                "closed_loop.gyro.bandwidth_hz=1000",
            ]),
        ),
    ];
    for (name, s) in &designs {
        let p = s.closed_loop.as_ref().unwrap();
        assert!(
            LinearLoop::new(p, &s.drive).margins(500).stable,
            "{name} must be a stable loop"
        );
        let spec = FreqRespParams {
            point: LoopPoint::BaseMotion,
            f_min_hz: 0.5,
            f_max_hz: Some(100.0),
            points: 9,
            amplitudes: vec![1.0],
            refine_iterations: 0,
            // The outer loop's slowest pole (|z| = 0.9999, 0.5 s) must have died away to
            // well below the -120 dB the stabilised loop leaves at 0.5 Hz.
            settle_min_s: 10.0,
            ..FreqRespParams::default()
        };
        let r = run(s, &spec);
        for pt in &r.amplitudes[0].points {
            let got = pt
                .response
                .unwrap_or_else(|| panic!("{name}: {:?}", pt.failure));
            println!(
                "{name}: {:7.3} Hz  simulated {:8.3} dB  exact {:8.3} dB",
                pt.frequency_hz,
                db(got),
                db(pt.exact)
            );
            assert!(
                (db(got) - db(pt.exact)).abs() < 0.5,
                "{name} at {} Hz: {} dB against {} dB",
                pt.frequency_hz,
                db(got),
                db(pt.exact)
            );
        }
    }
}

/// The law as simulated (law.rs) and as written in the linear reference agree: the loop
/// gain measured at the command equals the exact one, and the exact gain margin is where
/// the reference's closed-loop poles leave the unit circle (two independent routes).
#[test]
fn rate_loop_law_matches_its_linear_reference() {
    let s = stabilised(&[
        "closed_loop.controller.disturbance_observer={bandwidth_hz=3.0}",
        "closed_loop.controller.rate_command_filters=[{kind=\"lead_lag\",zero_hz=60.0,pole_hz=30.0}]",
    ]);
    let p = s.closed_loop.as_ref().unwrap();
    let lin = LinearLoop::new(p, &s.drive);
    let m = lin.margins(3000);
    assert!(m.stable, "{m:?}");
    let gm = m.gain_margin_db.expect("a phase crossover");
    let g = 10f64.powf(gm / 20.0);
    let (below, above) = (
        lin.with_gain(g * 0.99).spectral_radius(),
        lin.with_gain(g * 1.01).spectral_radius(),
    );
    assert!(below < 1.0 && above > 1.0, "{below} {above} at {gm} dB");
    let spec = FreqRespParams {
        point: LoopPoint::PlantInput,
        f_min_hz: 2.0,
        f_max_hz: Some(1000.0),
        points: 8,
        amplitudes: vec![0.2],
        refine_iterations: 0,
        ..FreqRespParams::default()
    };
    let r = run(&s, &spec);
    for pt in &r.amplitudes[0].points {
        let got = pt.response.unwrap_or_else(|| panic!("{:?}", pt.failure));
        let phase = (got / pt.exact).arg().to_degrees();
        assert!(
            (db(got) - db(pt.exact)).abs() < 0.1 && phase.abs() < 1.0,
            "{} Hz: {} dB / {phase} deg off",
            pt.frequency_hz,
            db(got) - db(pt.exact)
        );
    }
}

/// Effects that do not interact (linear plant; base motion, a disturbance torque and
/// encoder noise at different frequencies): their contributions add in mean square, so
/// the RSS of the budget is the total within 10 %.
#[test]
fn error_budget_of_independent_effects_adds_up() {
    let s = scenario(
        "eots_tracking",
        &[
            "closed_loop.cable=\"linear\"",
            "load.brake_nm=0",
            "load.brake_breakaway_nm=0",
            "closed_loop.motor.coulomb_nm=0",
            "closed_loop.modes=[\"none\"]",
            "closed_loop.duration_s=6",
            "closed_loop.metrics_start_s=1",
            "closed_loop.reference={kind=\"step\",amplitude_rad=0.0}",
            "closed_loop.base_motion={kind=\"sine\",amplitude_rad=1e-4,frequency_hz=3.0}",
            "load.sine_nm=0.05",
            "load.sine_frequency_hz=11.0",
            "closed_loop.sensors.quantize=false",
            "closed_loop.sensors.motor_noise_rad=2e-4",
        ],
    );
    let setup = s.closed_loop_setup().unwrap();
    let b = error_budget(&setup).unwrap();
    assert_eq!(
        b.effects,
        vec![
            BudgetEffect::BaseMotion,
            BudgetEffect::Sensors,
            BudgetEffect::Disturbance
        ]
    );
    let m = &b.modes[0];
    let total = m.total_mrad.unwrap();
    let rss = m.rss_mrad.unwrap();
    println!("{m:#?}");
    assert!(
        (rss / total - 1.0).abs() < 0.1,
        "RSS {rss} against total {total}"
    );
    for l in &m.lines[..3] {
        assert!(l.contribution_mrad.unwrap() > 0.01 * total, "{l:?}");
    }
}

/// The stabilised design rejects base motion: with the loop on the encoders the line of
/// sight follows the base; on the gyro it holds it (the metrics see the inertial error).
#[test]
fn gyro_loop_holds_the_line_of_sight_the_encoder_loop_does_not() {
    let base = "closed_loop.base_motion={kind=\"sine\",amplitude_rad=1e-3,frequency_hz=2.0}";
    let encoder = scenario(
        "eots_tracking",
        &[
            base,
            "closed_loop.reference={kind=\"step\",amplitude_rad=0.0}",
            "closed_loop.modes=[\"none\"]",
            "closed_loop.duration_s=4",
            "closed_loop.metrics_start_s=1",
        ],
    );
    let gyro = scenario(
        "gimbal_stabilized",
        &[
            base,
            "closed_loop.modes=[\"none\"]",
            "closed_loop.duration_s=4",
            "closed_loop.metrics_start_s=1",
        ],
    );
    let rms = |s: &Scenario| {
        let r = run_closed_loop(s, &RunOptions::metrics_only()).unwrap();
        assert_eq!(r.modes[0].completion, Completion::Complete);
        let los = r.modes[0].los.clone().unwrap();
        assert!((los.rms_mrad - r.modes[0].metrics.rms_mrad).abs() < 1e-9);
        los.rms_mrad
    };
    let (e, g) = (rms(&encoder), rms(&gyro));
    // A 1 mrad sine has 0.707 mrad RMS.
    assert!(
        (e / std::f64::consts::FRAC_1_SQRT_2 - 1.0).abs() < 0.05,
        "encoder loop: {e}"
    );
    assert!(g < 0.1 * e, "gyro loop {g} against encoder loop {e}");
}

/// Bad input is refused with the key named; an unstable law stops with the time and a
/// hint, and leaves no non-finite number in the series.
#[test]
fn bad_gimbal_input_is_named_and_unstable_laws_stop() {
    let refused = |sets: &[&str], key: &str| {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        let e = Scenario::load("gimbal_stabilized", &sets)
            .map(|s| {
                run_closed_loop(&s, &RunOptions::metrics_only())
                    .err()
                    .map(|e| e.to_string())
                    .unwrap_or_default()
            })
            .unwrap_or_else(|e| e.to_string());
        assert!(e.contains(key), "{e}");
    };
    refused(
        &["closed_loop.base_motion.psd=[[1.0, 1e-7], [0.5, 1e-7]]"],
        "closed_loop.base_motion",
    );
    refused(
        &["closed_loop.base_motion.psd=[[1.0, -1e-7], [5.0, 1e-7]]"],
        "positive",
    );
    refused(
        &["closed_loop.gyro.sample_rate_hz=40000"],
        "closed_loop.gyro.sample_rate_hz",
    );
    refused(
        &["closed_loop.gyro.sample_rate_hz=3000"],
        "divided by a whole number",
    );
    refused(
        &["closed_loop.controller.command_filters=[{kind=\"notch\",center_hz=12000.0,depth_db=20.0,width_hz=10.0}]"],
        "closed_loop.controller.command_filters[0]",
    );
    refused(
        &["closed_loop.controller.disturbance_observer={bandwidth_hz=0.0}"],
        "disturbance_observer.bandwidth_hz",
    );
    let s = scenario(
        "gimbal_stabilized",
        &[
            "closed_loop.controller.rate_loop.kp=200",
            "closed_loop.modes=[\"none\"]",
            "closed_loop.duration_s=2",
            "closed_loop.metrics_start_s=0.5",
        ],
    );
    let r = run_closed_loop(&s, &RunOptions::default()).unwrap();
    let m = &r.modes[0];
    match &m.completion {
        Completion::Incomplete {
            kind,
            fault,
            time_s,
        } => {
            assert_eq!(*kind, StopKind::Unstable, "{fault}");
            assert!(fault.contains("unstable") && *time_s < 2.0, "{fault}");
        }
        c => panic!("an unstable law ran to the end: {c:?}"),
    }
    let series = m.series.as_ref().unwrap();
    assert!(series
        .pointing_error_mrad
        .iter()
        .chain(&series.motor_command)
        .all(|v| v.is_finite()));
}

/// `compare`: a table, one folder per design, overlay figures, and exit code 4 when a
/// design misses the target (the encoder loop under base motion does).
#[test]
fn compare_runs_designs_side_by_side() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cmp");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_cable-servo"))
        .args([
            "compare",
            "gimbal_stabilized",
            "--set",
            "closed_loop.duration_s=3",
            "--set",
            "closed_loop.metrics_start_s=1",
            "--design",
            "stabilised:",
            "--design",
            "encoder:closed_loop.controller.feedback=\"motor\";closed_loop.controller.rate_loop.measurement=\"motor_velocity\"",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(4), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("stabilised") && stdout.contains("encoder"),
        "{stdout}"
    );
    assert!(stderr.contains("1 of 2 designs miss"), "{stderr}");
    for f in [
        "compare.csv",
        "summary.json",
        "compare_error.png",
        "compare_psd.svg",
        "designs/stabilised/timeseries.csv",
        "designs/encoder/error_psd.csv",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let csv = std::fs::read_to_string(out.join("compare.csv")).unwrap();
    assert_eq!(csv.lines().count(), 3, "{csv}");
}
