//! Closed-loop gimbal axis against independent math and the quasi-static core.

use cable_servo::closed_loop::*;
use cable_servo::identify::EffectsParams;
use cable_servo::physics::{CableDrive, HysteresisModel};
use cable_servo::report::closed_loop::{
    closed_loop_charts, format_table, plot_closed_loop, write_closed_loop_outputs,
};
use cable_servo::scenario::Scenario;
use cable_servo::signal::Signal;
use nalgebra::{SMatrix, SVector};

fn builtin(name: &str) -> Scenario {
    Scenario::load(name, &[]).unwrap()
}

fn params(s: &mut Scenario) -> &mut ClosedLoopParams {
    s.closed_loop.as_mut().unwrap()
}

/// Linear cable, no brake, no limits, no noise, continuous encoders, current amplifier:
/// the sampled loop must equal the exact zero-order-hold discretisation computed here
/// with the matrix exponential, for no computation delay, one sample and half a sample
/// (the command switching inside the period).
#[test]
fn linear_loop_matches_exact_discrete_time_response() {
    for delay in [0.0, 1.0, 0.5] {
        linear_loop_matches_exact_discrete_time_response_with_delay(delay);
    }
}

fn linear_loop_matches_exact_discrete_time_response_with_delay(delay: f64) {
    let mut s = builtin("eots_tracking");
    s.load.brake_nm = 0.0;
    s.load.brake_breakaway_nm = Some(0.0);
    {
        let p = params(&mut s);
        p.cable = CableModel::Linear;
        p.duration_s = 0.2;
        p.metrics_start_s = 0.0;
        p.modes = vec![CompensationMode::None];
        p.rk4_substeps = 20;
        p.reference = Signal::Sine {
            amplitude_rad: 0.005,
            frequency_hz: 2.0,
            phase_rad: 0.3,
            offset_rad: 0.0,
        };
        p.motor.coulomb_nm = 0.0;
        p.motor.current_limit_a = None;
        p.sensors.quantize = false;
        p.sensors.motor_noise_rad = 0.0;
        p.sensors.output_noise_rad = 0.0;
        p.controller.sample_rate_hz = 20000.0;
        p.controller.velocity_feedforward = 2e-3;
        p.controller.acceleration_feedforward = 0.01;
        p.controller.load_feedforward = false;
        p.controller.computation_delay_samples = delay;
    }
    let result = run_closed_loop(&s, &RunOptions::default()).unwrap();
    let series = result.modes[0].series.as_ref().unwrap();

    // Independent model. x = [theta_m, omega_m, theta_o, omega_o], input i (A).
    let p = s.closed_loop.as_ref().unwrap();
    let d = &s.drive;
    let (ri, ro) = (d.pulley_radius_m, d.drum_radius_m);
    let lf = (d.center_distance_m.powi(2) - (ro + ri).powi(2)).sqrt();
    let k = d.cable_modulus_n / lf;
    let c = p.cable_damping_n_s_per_m(d);
    let (jm, bm, kt) = (
        p.motor.inertia_kg_m2,
        p.motor.viscous_nm_s_per_rad,
        p.motor.torque_constant_nm_per_a,
    );
    let (jo, bo) = (p.output.inertia_kg_m2, p.output.viscous_nm_s_per_rad);
    // F = Tu - Tl = 2k (ri th_m - ro th_o) + 2c (ri w_m - ro w_o)
    let f = [2.0 * k * ri, 2.0 * c * ri, -2.0 * k * ro, -2.0 * c * ro];
    let mut m = SMatrix::<f64, 5, 5>::zeros();
    m[(0, 1)] = 1.0;
    for j in 0..4 {
        m[(1, j)] = -ri * f[j] / jm;
        m[(3, j)] = ro * f[j] / jo;
    }
    m[(1, 1)] -= bm / jm;
    m[(1, 4)] = kt / jm;
    m[(2, 3)] = 1.0;
    m[(3, 3)] -= bo / jo;
    let ts = 1.0 / p.controller.sample_rate_hz;
    let e = (m * ts).exp();
    let ad = e.fixed_view::<4, 4>(0, 0).into_owned();
    let bd = e.fixed_view::<4, 1>(0, 4).into_owned();
    // Under a delay of `whole + frac` periods the plant holds u_{k-whole-1} for `frac` of
    // the period, then u_{k-whole}: x+ = Ad x + B1 u_{k-whole-1} + B2 u_{k-whole}.
    let whole = delay.floor() as usize;
    let frac = delay - delay.floor();
    let e_first = (m * (frac * ts)).exp();
    let e_rest = (m * ((1.0 - frac) * ts)).exp();
    let b2 = e_rest.fixed_view::<4, 1>(0, 4).into_owned();
    let b1 = e_rest.fixed_view::<4, 4>(0, 0) * e_first.fixed_view::<4, 1>(0, 4);
    let b2 = if frac > 0.0 { b2 } else { bd };
    let mut past = vec![0.0; whole + 2];

    // The documented difference equations of the controller.
    let ctl = &p.controller;
    let ic = d.ratio();
    let a = (-std::f64::consts::TAU * ctl.derivative_filter_hz * ts).exp();
    let (mut integ, mut deriv, mut last_y) = (0.0, 0.0, 0.0);
    let mut x = SVector::<f64, 4>::zeros();
    let n = (p.duration_s * ctl.sample_rate_hz).round() as usize;
    assert_eq!(series.len(), n + 1);
    let mut worst = 0.0f64;
    let mut scale = 0.0f64;
    let (mut worst_cmd, mut max_cmd) = (0.0f64, 0.0f64);
    for kk in 0..=n {
        let t = kk as f64 * ts;
        let theta_o = x[2];
        worst = worst.max((series.output_angle_rad[kk] - theta_o).abs());
        worst = worst.max((series.motor_angle_rad[kk] - x[0]).abs() / ic);
        scale = scale.max(theta_o.abs());
        let r = p.reference.at(t);
        let y = x[0];
        let err = ic * r.value - y;
        let dy = if kk == 0 { 0.0 } else { y - last_y };
        last_y = y;
        deriv = a * deriv - (1.0 - a) * ctl.kd / ts * dy;
        integ += ctl.ki * ts * err;
        let u = ctl.kp * err
            + integ
            + deriv
            + ctl.velocity_feedforward * ic * r.rate
            + ctl.acceleration_feedforward * ic * r.accel;
        worst_cmd = worst_cmd.max((series.motor_command[kk] - u).abs());
        max_cmd = max_cmd.max(u.abs());
        past.remove(0);
        past.push(u);
        let (first, second) = (past[0], past[1]);
        x = if frac > 0.0 {
            ad * x + b1 * first + b2 * second
        } else {
            ad * x + b2 * second
        };
    }
    assert!(scale > 1e-3, "the output must move: {scale}");
    assert!(
        worst_cmd <= 1e-6 * max_cmd,
        "command {worst_cmd:e} of {max_cmd:e}"
    );
    assert!(
        worst <= 1e-6 * scale,
        "delay {delay}: max deviation {worst:e} rad vs scale {scale:e} rad"
    );
}

/// Slow motion against the brake: the plant's transmission error is the quasi-static
/// core's under the torque the cable transmits, through slip and through every reversal.
#[test]
fn slow_motion_reproduces_quasi_static_core() {
    let mut s = builtin("eots_tracking");
    s.load.brake_breakaway_nm = Some(s.load.brake_nm);
    {
        let p = params(&mut s);
        p.duration_s = 12.0;
        p.modes = vec![CompensationMode::None];
        p.sensors.quantize = false;
        p.cable_damping_ratio = 0.02;
    }
    let result = run_closed_loop(&s, &RunOptions::default()).unwrap();
    assert!(result.complete);
    let ts = result.modes[0].series.as_ref().unwrap();
    let ro = s.drive.drum_radius_m;
    let mut core = CableDrive::new(s.drive.clone(), HysteresisModel::Memory);
    let mut worst = 0.0f64;
    for k in 0..ts.len() {
        let m = ro * (ts.tension_upper_n[k] - ts.tension_lower_n[k]);
        let e_core = core.apply_torque(m).unwrap().transmission_error_rad * 1e3;
        worst = worst.max((ts.transmission_error_mrad[k] - e_core).abs());
    }
    // The brake reverses once per reversal of motion (at 2.5 and 7.5 s), never chatters.
    let flips = ts
        .load_torque_nm
        .windows(2)
        .filter(|w| w[0] * w[1] < 0.0)
        .count();
    assert!(flips <= 3, "load torque changed sign {flips} times");
    // 0.2 % of the 0.433 mrad reversal jump (damping and drum inertia make up the rest).
    assert!(worst < 8.7e-4, "worst deviation {worst} mrad");

    // While the drum slides steadily, the error sits near the core's +-0.7 N m values; the
    // torque peaks of the stick phases (a little above the brake torque) stay in memory,
    // so the match is to 1 % of the jump here, the tight check being the one above.
    let mut fresh = CableDrive::new(s.drive.clone(), HysteresisModel::Memory);
    fresh.apply_torque(0.7).unwrap();
    let minus = fresh.apply_torque(-0.7).unwrap().transmission_error_rad * 1e3;
    let plus = fresh.apply_torque(0.7).unwrap().transmission_error_rad * 1e3;
    let at = |t: f64| {
        let k = ts.t_s.partition_point(|&x| x < t);
        ts.transmission_error_mrad[k]
    };
    // Sine reference: moving down around t = 5 s, up around t = 10 s.
    assert!(
        (at(5.0) - minus).abs() < 0.01 * (plus - minus).abs(),
        "{} {minus}",
        at(5.0)
    );
    assert!(
        (at(10.0) - plus).abs() < 0.01 * (plus - minus).abs(),
        "{} {plus}",
        at(10.0)
    );
}

/// The EOTS case: uncompensated misses 0.1 mrad, memory compensation meets it with margin.
#[test]
fn eots_tracking_memory_compensation_meets_target() {
    let s = builtin("eots_tracking");
    let opts = RunOptions {
        record: false,
        ..RunOptions::default()
    };
    let r = run_closed_loop(&s, &opts).unwrap();
    assert!(r.complete);
    let none = &r.modes[0].metrics;
    let less = &r.modes[1].metrics;
    let mem = &r.modes[2].metrics;
    // The brake's breakaway peak stays in the cable's memory; only the memory model
    // carries it into the prediction.
    assert!(
        mem.rms_mrad < 0.8 * less.rms_mrad,
        "{} vs {}",
        mem.rms_mrad,
        less.rms_mrad
    );
    assert!(r.modes[0].series.is_none());
    assert!(none.peak_mrad > 0.2 && !none.passes_target, "{none:?}");
    assert!(mem.peak_mrad < 0.1, "{mem:?}");
    assert!(mem.rms_mrad < 0.01, "{mem:?}");
    assert!(mem.passes_target);
}

#[test]
fn slack_ends_the_run_with_a_clear_message() {
    let mut s = builtin("eots_tracking");
    // 25 N m exceeds the slack limit 2 * 100 N * 0.1025 m = 20.5 N m.
    s.load.constant_nm = 25.0;
    {
        let p = params(&mut s);
        p.duration_s = 1.0;
        p.metrics_start_s = 0.5;
        p.modes = vec![CompensationMode::None];
        p.motor.current_limit_a = None;
    }
    let r = run_closed_loop(&s, &RunOptions::default()).unwrap();
    assert!(!r.complete);
    match &r.modes[0].completion {
        Completion::Incomplete { fault, time_s, .. } => {
            // Whichever capacity limit comes first, the message says what to change.
            assert!(
                (fault.contains("slack") || fault.contains("gross slip"))
                    && fault.contains("preload")
                    && fault.contains("half"),
                "{fault}"
            );
            assert!(*time_s > 0.0 && *time_s < 1.0);
        }
        c => panic!("expected a fault, got {c:?}"),
    }
    // Metrics of an empty window are zeros, never NaN.
    let m = &r.modes[0].metrics;
    assert!(m.rms_mrad.is_finite() && m.p95_mrad.is_finite());
}

#[test]
fn a_slack_span_early_in_a_run_asks_for_the_preload_the_load_needs() {
    // Preloaded to 1e-7 N, the drive goes slack in the first periods, when it has
    // transmitted almost nothing: the preload asked for must carry the declared load
    // (0.75 N m on a 0.1025 m drum: 3.66 N), and the torque at the fault must show.
    let mut s = builtin("eots_tracking");
    s.drive.preload_n = 1e-7;
    {
        let p = params(&mut s);
        p.duration_s = 0.01;
        p.metrics_start_s = 0.0;
        p.modes = vec![CompensationMode::None];
    }
    let needed = s.load.peak_torque_nm() / (2.0 * s.drive.drum_radius_m);
    assert!((needed - 3.659).abs() < 1e-3, "{needed}");
    let r = run_closed_loop(&s, &RunOptions::default()).unwrap();
    match &r.modes[0].completion {
        Completion::Incomplete { fault, time_s, .. } => {
            assert!(
                fault.contains("raise preload_n above about 3.7 N"),
                "{fault}"
            );
            assert!(!fault.contains("0.0000 N m"), "{fault}");
            assert!(fault.contains(&format!("t = {} s", cable_servo::readable(*time_s))));
            let reason = r.modes[0].no_figures_reason().unwrap_or_default();
            // One time, written the same way, wherever the stop is told.
            assert_eq!(
                reason.matches(&cable_servo::readable(*time_s)).count(),
                2,
                "{reason}"
            );
        }
        c => panic!("expected a fault, got {c:?}"),
    }
}

#[test]
fn validation_names_the_key() {
    let text = cable_servo::scenario::builtin("eots_tracking").unwrap();
    let err = Scenario::from_toml(
        text,
        "x.toml",
        "x",
        &["closed_loop.controller.sample_rate_hz=500".into()],
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("closed_loop.controller.sample_rate_hz") && err.contains("fastest mode"),
        "{err}"
    );
    let err = Scenario::from_toml(
        text,
        "x.toml",
        "x",
        &["closed_loop.motor.inertia_kg=1".into()],
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("did you mean `inertia_kg_m2`"), "{err}");
    let err = Scenario::from_toml(
        text,
        "x.toml",
        "x",
        &["closed_loop.modes=[\"memory\", \"memory\"]".into()],
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("closed_loop.modes"), "{err}");
    // A non-closed-loop scenario is refused with a typed error.
    let qs = builtin("paper_bench");
    assert!(matches!(
        run_closed_loop(&qs, &RunOptions::default()),
        Err(ClosedLoopError::NotClosedLoop { .. })
    ));
}

#[test]
fn outputs_are_written_and_metrics_do_not_depend_on_recording() {
    let mut s = builtin("step_stare");
    {
        let p = params(&mut s);
        p.duration_s = 1.2;
        p.modes = vec![CompensationMode::None, CompensationMode::Memory];
    }
    let rec = run_closed_loop(
        &s,
        &RunOptions {
            decimation: 10,
            ..RunOptions::default()
        },
    )
    .unwrap();
    let bare = run_closed_loop_metrics(&s).unwrap();
    for (a, b) in rec.modes.iter().zip(&bare.modes) {
        assert_eq!(a.metrics, b.metrics);
        assert!(b.series.is_none());
    }
    let steps = &rec.modes[0].metrics.steps;
    assert_eq!(steps.len(), 2, "{steps:?}");
    assert!(steps[0].settling_time_s.is_some(), "{steps:?}");

    let dir = tempfile::tempdir().unwrap();
    let files = write_closed_loop_outputs(dir.path(), &s, &rec, None).unwrap();
    // Time series, error spectrum, summary.
    assert_eq!(files.len(), 3, "{files:?}");
    assert!(dir.path().join("error_psd.csv").is_file());
    let text = std::fs::read_to_string(dir.path().join("timeseries.csv")).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    assert!(header.starts_with(
        "mode,t_s,reference_rad,motor_angle_rad,output_angle_rad,pointing_error_mrad"
    ));
    assert!(
        header.ends_with(
            ",load_torque_nm,feedforward_a,motor_reference_rad,base_angle_rad,gyro_rad_s"
        ),
        "{header}"
    );
    assert_eq!(
        lines.count(),
        2 * rec.modes[0].series.as_ref().unwrap().len()
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("summary.json")).unwrap())
            .unwrap();
    assert_eq!(json["complete"], true);
    assert_eq!(json["program_version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(json["modes"][1]["name"], "memory");
    for key in [
        "rms_mrad",
        "peak_mrad",
        "p95_mrad",
        "within_target_fraction",
        "passes_target",
    ] {
        assert!(!json["modes"][0][key].is_null(), "{key}");
    }
    assert_eq!(json["scenario"]["study"], "closed_loop");
    // A step reference is judged on its steps, and the console says how.
    assert_eq!(json["modes"][0]["metrics"]["criterion"], "steps");
    assert_eq!(json["modes"][0]["metrics"]["step_summary"]["judged"], 2);
    let table = format_table(&rec);
    assert!(table.contains("memory"));
    assert!(table.contains("settling_ms"), "{table}");
    // Pointing error, error against angle, tensions, command, error spectrum.
    let charts = closed_loop_charts(&rec, 0.1, "A");
    assert_eq!(charts.len(), 5);
    let pictures = plot_closed_loop(dir.path(), &rec, 0.1, "A").unwrap();
    assert_eq!(pictures.len(), 10);
    assert!(pictures.iter().all(|p| p.exists()));
}

/// Partial reversals (unbalance plus brake): the memory compensator beats the memoryless
/// (by a few per cent with the loop tuned for margins: what remains is mostly the loop's
/// own response at the turns, which both compensators leave).
#[test]
fn eots_scan_memory_beats_memoryless() {
    let s = builtin("eots_scan");
    let opts = RunOptions {
        modes: Some(vec![CompensationMode::Memoryless, CompensationMode::Memory]),
        ..RunOptions::metrics_only()
    };
    let r = run_closed_loop(&s, &opts).unwrap();
    let (less, mem) = (&r.modes[0].metrics, &r.modes[1].metrics);
    assert!(
        mem.rms_mrad < less.rms_mrad,
        "{} vs {}",
        mem.rms_mrad,
        less.rms_mrad
    );
    assert!(mem.peak_mrad <= less.peak_mrad, "{mem:?} vs {less:?}");
}

fn shortened(name: &str, duration_s: f64) -> Scenario {
    let mut s = builtin(name);
    let p = params(&mut s);
    p.duration_s = duration_s;
    p.metrics_start_s = 1.0;
    s
}

fn metrics_of(s: &Scenario) -> Vec<cable_servo::metrics::Metrics> {
    run_closed_loop(s, &RunOptions::metrics_only())
        .unwrap()
        .modes
        .into_iter()
        .map(|m| {
            assert_eq!(m.completion, Completion::Complete, "{:?}", m.mode);
            m.metrics
        })
        .collect()
}

/// Slow motion on a stiff linear cable without brake: the plant's transmission error is
/// the effects' closed form; what remains is the drive's dither from encoder quantisation
/// (below 1e-3 mrad) once started.
#[test]
fn plant_transmission_error_carries_the_kinematic_effects() {
    let mut s = shortened("eots_tracking", 3.0);
    s.load.brake_nm = 0.0;
    s.load.brake_breakaway_nm = Some(0.0);
    let fx = EffectsParams {
        input_pulley_runout: Some(0.01),
        input_pulley_runout_phase_rad: Some(0.5),
        output_drum_runout: Some(1e-3),
        output_drum_runout_phase_rad: Some(-0.7),
        thermal_drift_rad_per_s: Some(2e-5),
        ..EffectsParams::default()
    };
    s.effects = Some(fx.clone());
    params(&mut s).cable = CableModel::Linear;
    params(&mut s).modes = vec![CompensationMode::None];
    let r = run_closed_loop(&s, &RunOptions::default()).unwrap();
    let ts = r.modes[0].series.as_ref().unwrap();
    let ic = s.drive.ratio();
    let mut largest = 0.0f64;
    // After the start-up transient.
    for i in (0..ts.len()).step_by(50).filter(|&i| ts.t_s[i] >= 1.0) {
        let expect =
            fx.kinematic_error_rad(ts.motor_angle_rad[i], ts.output_angle_rad[i], ts.t_s[i], ic)
                * 1e3;
        largest = largest.max(expect.abs());
        let got = ts.transmission_error_mrad[i];
        assert!(
            (got - expect).abs() < 2e-3,
            "t = {}: {got} vs {expect}",
            ts.t_s[i]
        );
    }
    assert!(largest > 0.05, "{largest}");
}

/// The extended model's feedforward removes most of the runout error the base model
/// leaves.
#[test]
fn compensating_identified_runout_lowers_pointing_error() {
    let mut base = shortened("eots_runout", 6.0);
    params(&mut base).modes = vec![CompensationMode::Memory];
    assert!(!params(&mut base).compensate_effects);
    let mut ext = base.clone();
    params(&mut ext).compensate_effects = true;
    let b = &metrics_of(&base)[0];
    let e = &metrics_of(&ext)[0];
    assert!(
        e.rms_mrad < 0.5 * b.rms_mrad,
        "extended {} vs base {} mrad",
        e.rms_mrad,
        b.rms_mrad
    );
    assert!(e.passes_target && !b.passes_target, "{e:?} {b:?}");
    // An explicit compensator copy equal to the plant's is the default.
    let mut same = ext.clone();
    params(&mut same).compensator_effects = ext.effects.clone();
    assert_eq!(metrics_of(&same)[0], *e);
    // A compensator copy without the runout falls back to the base result.
    let mut none = ext.clone();
    params(&mut none).compensator_effects = Some(EffectsParams {
        bearing_friction_nm: Some(0.0),
        ..EffectsParams::default()
    });
    assert_eq!(metrics_of(&none)[0], *b);
}

/// An `[effects]` section of zeros changes nothing, bit for bit.
#[test]
fn zero_effects_leave_results_unchanged() {
    let plain = shortened("eots_tracking", 4.0);
    let mut zero = plain.clone();
    zero.effects = Some(EffectsParams {
        input_pulley_runout: Some(0.0),
        input_pulley_runout_phase_rad: Some(0.0),
        output_drum_runout: Some(0.0),
        output_drum_runout_phase_rad: Some(0.0),
        bearing_friction_nm: Some(0.0),
        thermal_drift_rad_per_s: Some(0.0),
        ..EffectsParams::default()
    });
    let before = metrics_of(&plain);
    assert_eq!(before, metrics_of(&zero));
    params(&mut zero).compensate_effects = true;
    assert_eq!(before, metrics_of(&zero));
}

#[test]
fn effects_options_are_validated_by_key() {
    let text = cable_servo::scenario::builtin("eots_tracking").unwrap();
    let err = Scenario::from_toml(
        text,
        "x.toml",
        "x",
        &["closed_loop.compensate_effects=true".into()],
    )
    .map(|s| run_closed_loop(&s, &RunOptions::metrics_only()).map(|_| ()))
    .map_or_else(|e| e.to_string(), |r| r.unwrap_err().to_string());
    assert!(
        err.contains("closed_loop.compensate_effects") && err.contains("[effects]"),
        "{err}"
    );
    let mut s = builtin("eots_runout");
    params(&mut s).compensator_effects = Some(EffectsParams {
        input_pulley_runout: Some(-1.0),
        ..EffectsParams::default()
    });
    match run_closed_loop(&s, &RunOptions::metrics_only()) {
        Err(ClosedLoopError::Invalid { key, .. }) => {
            assert_eq!(key, "closed_loop.compensator_effects.input_pulley_runout")
        }
        r => panic!("expected a validation error, got {r:?}"),
    }
}

/// The step-and-stare drive, one 2 mrad step from rest at 0.05 s, 0.35 s in all.
fn step_from_rest() -> Scenario {
    let mut s = builtin("step_stare");
    let p = params(&mut s);
    p.duration_s = 0.35;
    p.metrics_start_s = 0.0;
    p.reference = Signal::Step {
        amplitude_rad: 0.002,
        time_s: 0.05,
    };
    s
}

/// From rest the brake holds whatever the cable transmits once the reference stops, so
/// the compensated modes must not predict a standing brake torque: they may not overshoot
/// more than `none`, nor stand further off the target after settling.
#[test]
fn compensation_does_not_worsen_a_step_from_rest() {
    let r = run_closed_loop(&step_from_rest(), &RunOptions::metrics_only()).unwrap();
    let summary = |m: CompensationMode| {
        let mr = r.modes.iter().find(|x| x.mode == m).unwrap();
        assert_eq!(mr.completion, Completion::Complete, "{m:?}");
        assert_eq!(mr.metrics.steps.len(), 1, "{m:?}");
        mr.metrics.step_summary.unwrap()
    };
    let none = summary(CompensationMode::None);
    let after = |s: &cable_servo::metrics::StepSummary| {
        s.error_after_settling_peak_mrad
            .expect("the step settles in every mode")
    };
    for mode in [CompensationMode::Memoryless, CompensationMode::Memory] {
        let comp = summary(mode);
        assert!(
            comp.max_overshoot_percent <= none.max_overshoot_percent + 1.0,
            "{mode:?}: {comp:?} vs none {none:?}"
        );
        assert!(
            after(&comp) <= after(&none) + 0.005,
            "{mode:?}: {comp:?} vs none {none:?}"
        );
    }
}

/// The feedforward is computed from the reference and the declared loads only: an
/// unknown constant torque and a sine torque on the drum change the output but leave the
/// feedforward and the compensated motor reference bit for bit the same.
#[test]
fn feedforward_does_not_see_unknown_disturbances() {
    let mut quiet = builtin("eots_tracking");
    {
        let p = params(&mut quiet);
        p.duration_s = 0.3;
        p.metrics_start_s = 0.0;
        p.modes = vec![CompensationMode::Memoryless, CompensationMode::Memory];
    }
    let mut disturbed = quiet.clone();
    disturbed.load.constant_nm = 0.2;
    disturbed.load.sine_nm = 0.1;
    disturbed.load.sine_frequency_hz = 7.0;
    let a = run_closed_loop(&quiet, &RunOptions::default()).unwrap();
    let b = run_closed_loop(&disturbed, &RunOptions::default()).unwrap();
    for (ma, mb) in a.modes.iter().zip(&b.modes) {
        assert_eq!(mb.completion, Completion::Complete);
        let (sa, sb) = (ma.series.as_ref().unwrap(), mb.series.as_ref().unwrap());
        assert_eq!(sa.len(), sb.len());
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(&sa.feedforward),
            bits(&sb.feedforward),
            "{:?}",
            ma.mode
        );
        assert_eq!(
            bits(&sa.motor_reference_rad),
            bits(&sb.motor_reference_rad),
            "{:?}",
            ma.mode
        );
        assert!(sa.feedforward.iter().any(|&u| u != 0.0));
        let moved = sa
            .output_angle_rad
            .iter()
            .zip(&sb.output_angle_rad)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(moved > 1e-6, "{:?}: output moved {moved} rad", ma.mode);
    }
}

/// The calibrated da Vinci loop, shortened; `effects` keeps the scenario's `[effects]`.
fn davinci_loop(duration_s: f64, effects: bool) -> Scenario {
    let mut s = builtin("davinci_tool4_loop");
    let p = params(&mut s);
    p.duration_s = duration_s;
    p.metrics_start_s = 2.0;
    if !effects {
        s.effects = None;
    }
    s
}

/// The plant carries the multi-wrap effects: against the same loop without them, the
/// output differs by the ratio shape's Legendre terms at the motor angle, the jaw link's
/// compliance times the transmitted torque and the friction memory of its contacts,
/// computed here from their closed forms and the identification's own play operators
/// along the recorded motor angle.
#[test]
fn plant_carries_the_ratio_shape_and_the_jaw_link() {
    let record = |s: &Scenario| {
        let mut p = s.clone();
        params(&mut p).modes = vec![CompensationMode::None];
        let options = RunOptions {
            record: true,
            decimation: 1,
            modes: None,
            injection: None,
            line_of_sight: true,
        };
        let r = run_closed_loop(&p, &options).unwrap();
        assert_eq!(r.modes[0].completion, Completion::Complete);
        r.modes[0].series.clone().unwrap()
    };
    let with = davinci_loop(6.0, true);
    let fx = with.effects.clone().unwrap();
    let plain = record(&davinci_loop(6.0, false));
    let ext = record(&with);
    let c = fx.angle_dependent_ratio_coefs.clone().unwrap();
    let [lo, hi] = fx.angle_dependent_ratio_stroke_rad.unwrap();
    let thresholds = fx.friction_memory_thresholds_rad.clone().unwrap();
    let weights = fx.friction_memory_weights.clone().unwrap();
    let n = thresholds.len();
    let load_weights = fx
        .friction_memory_load_weights_per_nm
        .clone()
        .unwrap_or_else(|| vec![0.0; n]);
    let p = fx.friction_memory_load_exponent.unwrap_or(1.0);
    use cable_servo::identify::extra_effects::{memory_law_columns, slack_column};
    // The transmitted torque is the constant jaw torque once its ramp is over: the
    // contacts' thresholds and the slack's width are those at that torque.
    let m = -with.load.constant_nm;
    let torque = vec![m; ext.motor_angle_rad.len()];
    let growth = fx.friction_memory_threshold_growth_per_nm.unwrap_or(0.0);
    let lags = memory_law_columns(&ext.motor_angle_rad, &torque, &thresholds, growth);
    let slack = match (
        fx.friction_memory_slack_rad,
        fx.friction_memory_slack_taken_up_nm,
        fx.friction_memory_slack_weight,
    ) {
        (Some(s), Some(mu), Some(w)) => slack_column(&ext.motor_angle_rad, &torque, s, mu)
            .into_iter()
            .map(|v| w * v)
            .collect(),
        _ => vec![0.0; torque.len()],
    };
    let mut checked = 0;
    let mut largest = 0.0f64;
    for i in (0..ext.len()).filter(|&i| ext.t_s[i] >= 1.0) {
        let th = ext.motor_angle_rad[i];
        let u = 2.0 * (th - lo) / (hi - lo) - 1.0;
        if !(-1.0..=1.0).contains(&u) {
            continue;
        }
        let shape = c[0] * 0.5 * (3.0 * u * u - 1.0)
            + c[1] * 0.5 * u * (5.0 * u * u - 3.0)
            + c[2] * (35.0 * u.powi(4) - 30.0 * u * u + 3.0) / 8.0;
        let memory: f64 = (0..thresholds.len())
            .map(|j| (weights[j] + load_weights[j] * m.abs().powf(p)) * lags[j][i])
            .sum::<f64>()
            + slack[i];
        let expect = shape + fx.load_compliance_rad_per_nm.unwrap() * m + memory;
        // The cable's own error is the plain loop's at the same sample: both loops follow
        // the same motor reference, and the cable carries the same constant torque (the
        // two differ by 0.06 mrad at most; the effects reach 300 mrad).
        let got = (ext.transmission_error_mrad[i] - plain.transmission_error_mrad[i]) * 1e-3;
        assert!(
            (got - expect).abs() < 0.2e-3,
            "t = {}: the effects add {got} rad, their closed forms {expect} rad",
            ext.t_s[i]
        );
        largest = largest.max(expect.abs());
        checked += 1;
    }
    assert!(checked > 10_000, "{checked}");
    assert!(largest > 0.1, "{largest}");
}

/// On a plant carrying the calibrated model, the base model's feedforward alone cannot
/// hold the jaw (the calibrated compliance takes back most of the spans' stretch it
/// predicts), and the extended model's feedforward brings the error down by more than two
/// orders of magnitude from the uncompensated loop.
#[test]
fn extended_compensation_wins_on_a_plant_that_carries_the_calibrated_model() {
    let base = davinci_loop(12.0, true);
    let mut ext = base.clone();
    params(&mut ext).compensate_effects = true;
    let b = metrics_of(&base);
    let e = metrics_of(&ext);
    let (none, base_model, extended) = (&b[0], &b[1], &e[1]);
    assert_eq!(
        b[0], e[0],
        "the uncompensated loop does not depend on the option"
    );
    assert!(none.rms_mrad > 20.0, "{none:?}");
    assert!(base_model.rms_mrad > none.rms_mrad, "{base_model:?}");
    assert!(
        extended.rms_mrad < 0.01 * none.rms_mrad && extended.rms_mrad < 0.5,
        "extended {extended:?} against none {none:?}"
    );
}

/// A motor too weak for the load it must hold: with the jaw torque needing 3.3 A of a 3 A
/// amplifier, the loop (stable on its linear reference) sits at the limit while the axis
/// runs away. That is a stop, named, not a tracking figure.
#[test]
fn a_command_stuck_at_the_amplifier_limit_stops_the_run() {
    let mut s = davinci_loop(4.0, false);
    let p = params(&mut s);
    p.motor.torque_constant_nm_per_a = 0.02;
    // The same loop gain with the weaker motor.
    p.controller.kp *= 2.5;
    p.controller.ki *= 2.5;
    p.controller.kd *= 2.5;
    let r = run_closed_loop(&s, &RunOptions::metrics_only()).unwrap();
    for m in &r.modes {
        match &m.completion {
            Completion::Incomplete { fault, kind, .. } => {
                assert_eq!(*kind, StopKind::Saturated, "{fault}");
                assert!(fault.contains("amplifier limit 3"), "{fault}");
            }
            other => panic!("{:?}: {other:?}", m.mode),
        }
        assert!(m.saturation.longest_s >= cable_servo::closed_loop::sim::SATURATION_STOP_S);
    }
    assert!(!r.complete);
    // The motor of the scenario holds it, and its command never sits at the limit.
    let ok = run_closed_loop(&davinci_loop(4.0, false), &RunOptions::metrics_only()).unwrap();
    assert!(ok.complete);
    assert!(ok.modes.iter().all(|m| m.saturation.longest_s < 0.1));
}

/// A sweep's cases read the reference from one table: every figure of a run that reads
/// it is bit for bit the figure of a run that evaluates the signal itself, also when the
/// table was made by an earlier run and when a run with another reference replaces it.
#[test]
fn a_shared_reference_table_changes_no_result() {
    let cache = ReferenceCache::new();
    let strip = |r: ClosedLoopResult| -> Vec<ModeResult> {
        r.modes
            .into_iter()
            .map(|mut m| {
                m.stats.wall_s = 0.0;
                m
            })
            .collect()
    };
    for name in ["eots_tracking", "eots_scan", "step_stare", "eots_tracking"] {
        let mut s = builtin(name);
        {
            let p = params(&mut s);
            p.duration_s = 0.6;
            p.metrics_start_s = 0.1;
        }
        let own = strip(run_closed_loop_metrics(&s).unwrap());
        for _ in 0..2 {
            let shared = strip(run_closed_loop_metrics_shared(&s, &cache).unwrap());
            assert_eq!(shared, own, "{name}");
        }
    }
}

/// A run that keeps no line of sight (a sweep case, a frequency-response run) gives the
/// same metrics and the same verdict as a full run, and neither jitter nor spectrum; a
/// scenario whose requirements judge jitter keeps the jitter, the very one a full run
/// gives, so its verdict cannot change either.
#[test]
fn leaving_out_the_line_of_sight_changes_nothing_else() {
    use cable_servo::analysis::verdict::judge;
    let mut s = shortened("eots_tracking", 2.5);
    params(&mut s).modes = vec![CompensationMode::None, CompensationMode::Memory];
    let run = |s: &Scenario, record: bool, line_of_sight: bool| {
        let options = RunOptions {
            record,
            decimation: 20,
            line_of_sight,
            ..RunOptions::default()
        };
        run_closed_loop(s, &options).unwrap()
    };
    for record in [false, true] {
        let full = run(&s, record, true);
        let lean = run(&s, record, false);
        let setup = s.closed_loop_setup().unwrap();
        for (a, b) in full.modes.iter().zip(&lean.modes) {
            assert_eq!(a.completion, Completion::Complete, "{:?}", a.mode);
            assert_eq!(a.metrics, b.metrics, "{:?}", a.mode);
            assert_eq!(a.limit_cycle, b.limit_cycle, "{:?}", a.mode);
            assert_eq!(a.series, b.series, "{:?}", a.mode);
            assert!(a.los.is_some(), "{:?}", a.mode);
            assert_eq!(a.spectrum.is_some(), record, "{:?}", a.mode);
            assert!(b.los.is_none() && b.spectrum.is_none(), "{:?}", b.mode);
            let (va, vb) = (judge(&setup, a), judge(&setup, b));
            assert_eq!(format!("{va:?}"), format!("{vb:?}"), "{:?}", a.mode);
        }
    }
    // With a jitter limit the verdict reads the jitter: it is kept, and judged the same.
    let mut judged = s.clone();
    params(&mut judged).requirements.max_jitter_mrad = Some(0.05);
    let full = run(&judged, false, true);
    let lean = run(&judged, false, false);
    let setup = judged.closed_loop_setup().unwrap();
    for (a, b) in full.modes.iter().zip(&lean.modes) {
        let jitter = a.los.as_ref().and_then(|l| l.jitter_rms_max_mrad);
        assert!(jitter.is_some(), "{:?}", a.mode);
        assert_eq!(a.los, b.los, "{:?}", a.mode);
        let verdict = judge(&setup, b);
        assert!(
            verdict
                .checks
                .iter()
                .any(|c| c.requirement == "jitter" && c.measured.is_some()),
            "{:?}",
            verdict.checks
        );
        assert_eq!(format!("{:?}", judge(&setup, a)), format!("{verdict:?}"));
    }
}
