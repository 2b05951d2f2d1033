//! Hunting at rest: a loop closed on the output encoder with integral action against a
//! brake whose breakaway exceeds its sliding torque (stiction) stick-slips around the
//! target for ever; the same loop against a brake without stiction settles. Every
//! closed-loop run reports which.

use cable_servo::analysis::freqresp::{measure, FreqRespParams, LoopPoint, PredictedCycle};
use cable_servo::closed_loop::{
    run_closed_loop, Amplifier, ClosedLoopSource, Feedback, RunOptions,
};
use cable_servo::metrics::limit_cycle::LimitCycle;
use cable_servo::scenario::Scenario;

/// The loop on the output encoder at its shipped integral gain (ki 1000: linearly stable
/// on the exact reference, PM 24 deg, GM 7.8 dB), so whatever cycles is the friction's
/// doing.
fn hunt(breakaway_nm: f64) -> LimitCycle {
    simulated(&hunting_loop(1000.0, breakaway_nm))
}

/// The reference steps by `STEP_RAD` at `STEP_S` and then rests.
const STEP_RAD: f64 = 0.001;
const STEP_S: f64 = 0.2;

/// What the derivation leaves out moves amplitude and frequency by less than this (the
/// budget is on `derived_hunt`).
const MODEL_TOLERANCE: f64 = 0.01;

#[test]
fn stiction_under_integral_action_hunts_and_is_reported() {
    let sets = hunting_loop(1000.0, 1.2);
    let d = derived_hunt(&sets);
    match simulated(&sets) {
        LimitCycle::Detected {
            amplitude_mrad,
            frequency_hz,
            start_s,
            cycles,
        } => {
            println!(
                "{amplitude_mrad} mrad at {frequency_hz} Hz from {start_s} s, {cycles} cycles; derived {d:?}"
            );
            // The drum rests at +-a between slips, so half the peak-to-peak error is a.
            let a_mrad = d.amplitude_rad * 1e3;
            assert!(
                (amplitude_mrad / a_mrad - 1.0).abs() < MODEL_TOLERANCE,
                "simulated {amplitude_mrad} mrad, derived {a_mrad} mrad"
            );
            assert!(
                (frequency_hz / d.frequency_hz - 1.0).abs() < MODEL_TOLERANCE,
                "simulated {frequency_hz} Hz, derived {} Hz",
                d.frequency_hz
            );
            // The cycling starts with the first breakaway, the first slip carrying the
            // output up through the target.
            let (first, last) = d.first_breakaway_s;
            assert!(
                start_s > first && start_s < last + d.slip_s,
                "{start_s} s: the first slip is derived to start in {first}..{last} s"
            );
        }
        other => panic!("no limit cycle found: {other:?}"),
    }
    // Breakaway equal to the sliding torque: no stiction, the slip starts with no excess
    // torque, the amplitude (proportional to the excess) is zero and the loop settles.
    let calm = hunt(0.7);
    assert!(matches!(calm, LimitCycle::None { .. }), "{calm:?}");
}

/// The slip is linear in the breakaway excess and the stick amplitude and homogeneous in
/// them (see `derived_hunt`): twice the excess (breakaway 1.7 against sliding 0.7 N m)
/// gives exactly twice the amplitude and the same slip time, and the shorter sticks follow
/// from the integral ramping over twice the error. What the derivation leaves out is
/// mostly proportional to the swing (delays, the cable's twist) and cancels in the ratio;
/// what is not (encoder counts, the breakaway overshoot of one sample's ramp) is below
/// 0.15 % at the smaller swing, so the ratio must be 2 within 0.5 %. Were the motor's
/// friction missing from the stick (the command breaking away at Fs, not Fs + fm), the
/// excess would be 0.474 and 0.974 N m and the ratio 2.05.
#[test]
fn doubling_the_breakaway_excess_doubles_the_hunt() {
    let size = |breakaway_nm: f64| {
        let sets = hunting_loop(1000.0, breakaway_nm);
        let d = derived_hunt(&sets);
        match simulated(&sets) {
            LimitCycle::Detected {
                amplitude_mrad,
                frequency_hz,
                ..
            } => {
                println!("breakaway {breakaway_nm} N m: {amplitude_mrad} mrad at {frequency_hz} Hz; derived {d:?}");
                assert!(
                    (amplitude_mrad / (d.amplitude_rad * 1e3) - 1.0).abs() < MODEL_TOLERANCE,
                    "{amplitude_mrad} mrad, derived {:?}",
                    d
                );
                assert!(
                    (frequency_hz / d.frequency_hz - 1.0).abs() < MODEL_TOLERANCE,
                    "{frequency_hz} Hz, derived {d:?}"
                );
                amplitude_mrad
            }
            other => panic!("breakaway {breakaway_nm} N m: no limit cycle found: {other:?}"),
        }
    };
    let ratio = size(1.7) / size(1.2);
    assert!((ratio / 2.0 - 1.0).abs() < 0.005, "{ratio}");
}

/// The time series splits each half cycle as derived: the drum is held while the integral
/// ramps the command from its landing value to the breakaway at ki_e a (N m/s), then slips
/// for the loop's half swing, which is the same at either breakaway excess. Each run is
/// counted in control samples (50 us: 0.1 % of a slip), within the model tolerance. The
/// command at landing differs from `Fc + fm` by `J v'(t_slip)`, proportional to the excess
/// `Fs - Fc`, and so does what the derivation leaves out: it must agree within the model
/// tolerance of the excess (the sample after the stop adds one step of ramp, 0.1 % of it).
#[test]
fn the_drum_sticks_for_the_integral_ramp_and_slips_for_the_loop_swing() {
    for breakaway_nm in [1.2, 1.7] {
        let sets = hunting_loop(1000.0, breakaway_nm);
        let d = derived_hunt(&sets);
        let s = Scenario::load("eots_tracking", &sets).unwrap_or_else(|e| panic!("{e}"));
        let options = RunOptions {
            record: true,
            decimation: 1,
            ..RunOptions::default()
        };
        let r = run_closed_loop(&s, &options).unwrap_or_else(|e| panic!("{e}"));
        let series = r.modes[0].series.as_ref().expect("recorded");
        // Runs of held and sliding samples over the second half of the rest, where the
        // cycle has settled; the first and last runs are cut by the window.
        let from = series.t_s.partition_point(|&t| t < 3.0);
        let held = &series.drum_held[from..];
        let mut runs: Vec<(bool, usize)> = Vec::new();
        for &h in held {
            match runs.last_mut() {
                Some((state, n)) if *state == h => *n += 1,
                _ => runs.push((h, 1)),
            }
        }
        let whole = &runs[1..runs.len() - 1];
        assert!(whole.len() >= 8, "{runs:?}");
        let ts = series.t_s[1] - series.t_s[0];
        let p = s.closed_loop.as_ref().expect("closed-loop scenario");
        let ic = s.drive.drum_radius_m / s.drive.pulley_radius_m;
        let torque_per_a = ic * p.motor.torque_constant_nm_per_a;
        let ki_nm_per_rad_s = p.controller.ki * ic * torque_per_a;
        let excess_nm = breakaway_nm - s.load.brake_nm;
        let mut seen: Vec<(&str, f64)> = Vec::new();
        let mut at = from + runs[0].1;
        for &(is_held, n) in whole {
            if is_held {
                // The drum slid through the target to the side it is held on. The derivative
                // term kicks by 33 mN m per encoder count as the drum stops (kd/T times a
                // count), gone within a few samples (its filter keeps 0.15 a sample): the
                // command is read 1 ms into the stick and the integral's ramp over that
                // millisecond is taken back off.
                let slid = series.pointing_error_mrad[at].signum();
                let settled = 20;
                let ramp_nm = ki_nm_per_rad_s * series.pointing_error_mrad[at].abs() * 1e-3 * ts;
                let landing = slid * series.motor_command[at + settled] * torque_per_a
                    + settled as f64 * ramp_nm;
                seen.push(("landing N m", landing));
                assert!(
                    (landing - d.landing_nm).abs() < MODEL_TOLERANCE * excess_nm,
                    "breakaway {breakaway_nm} N m: landing command {landing} N m, derived {} N m",
                    d.landing_nm
                );
            }
            at += n;
            let (what, derived) = if is_held {
                ("stick", d.stick_s)
            } else {
                ("slip", d.slip_s)
            };
            let measured = n as f64 * ts;
            seen.push((what, measured));
            assert!(
                (measured / derived - 1.0).abs() < MODEL_TOLERANCE,
                "breakaway {breakaway_nm} N m: {what} of {measured} s, derived {derived} s ({runs:?})"
            );
        }
        println!(
            "breakaway {breakaway_nm} N m: {:?}; derived {d:?}",
            &seen[..6]
        );
    }
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

fn hunting_loop(ki: f64, breakaway_nm: f64) -> Vec<String> {
    [
        "closed_loop.controller.feedback=\"output\"",
        "closed_loop.controller.kp=40",
        "closed_loop.controller.kd=0.5",
        "closed_loop.duration_s=6",
        "closed_loop.metrics_start_s=0.1",
        "closed_loop.modes=[\"none\"]",
    ]
    .iter()
    .map(|s| s.to_string())
    .chain([
        format!(
            "closed_loop.reference={{kind=\"step\", amplitude_rad={STEP_RAD}, time_s={STEP_S}}}"
        ),
        format!("closed_loop.controller.ki={ki}"),
        format!("load.brake_breakaway_nm={breakaway_nm}"),
    ])
    .collect()
}

fn predicted(sets: &[String]) -> Vec<PredictedCycle> {
    let s = Scenario::load("eots_tracking", sets).unwrap_or_else(|e| panic!("{e}"));
    let spec = FreqRespParams {
        point: LoopPoint::Plant,
        f_min_hz: 2.0,
        f_max_hz: Some(20.0),
        points: 12,
        amplitudes: vec![1.2, 1.3, 1.4, 1.5, 1.6, 1.8, 2.0, 2.5, 3.0, 4.0, 6.0],
        ..FreqRespParams::default()
    };
    let setup = s.closed_loop_setup().unwrap_or_else(|e| panic!("{e}"));
    let r = measure(setup, &spec, 0, &|| {}).unwrap_or_else(|e| panic!("{e}"));
    r.limit_cycles
        .unwrap_or_else(|| panic!("the plant point predicts"))
}

fn simulated(sets: &[String]) -> LimitCycle {
    let s = Scenario::load("eots_tracking", sets).unwrap_or_else(|e| panic!("{e}"));
    let r = run_closed_loop(&s, &RunOptions::metrics_only()).unwrap_or_else(|e| panic!("{e}"));
    r.modes[0].limit_cycle.clone()
}

/// Integral gain high enough that the exact linear reference is unstable (a pole at
/// |z| = 1.0003 near 10 Hz): the brake's friction bounds the oscillation. The plant's
/// describing function, measured open loop at each command amplitude and closed with the
/// exact controller, crosses -1 where the simulated loop settles into its cycle.
///
/// The describing function assumes a sinusoidal command and keeps only its fundamental.
/// The frequency comes from where the loop's phase crosses -180 deg, which the harmonics
/// of the stick phases barely move: it must agree within 10 % (8.56 Hz predicted against
/// 8.06 Hz simulated, 6 %). The amplitude comes from where the gain crosses 1, and the
/// friction's describing function changes slowly with amplitude there, so a small error in
/// gain is a large one in amplitude: it must agree within 35 % (5.77 mrad predicted
/// against 4.45 mrad simulated, 30 %).
#[test]
fn describing_function_predicts_the_cycle_of_a_high_integral_gain() {
    let sets = hunting_loop(3000.0, 1.2);
    let LimitCycle::Detected {
        frequency_hz,
        amplitude_mrad,
        ..
    } = simulated(&sets)
    else {
        panic!("the loop does not cycle in simulation");
    };
    let cycles = predicted(&sets);
    println!("simulated {amplitude_mrad} mrad at {frequency_hz} Hz; predicted {cycles:?}");
    let stable: Vec<&PredictedCycle> = cycles.iter().filter(|c| c.stable).collect();
    assert_eq!(stable.len(), 1, "{cycles:?}");
    let c = stable[0];
    assert!(
        (c.frequency_hz / frequency_hz - 1.0).abs() < 0.1,
        "predicted {} Hz, simulated {frequency_hz} Hz",
        c.frequency_hz
    );
    // The output swing is the right size too, if less closely (the command is far from a
    // sinusoid while the brake holds).
    assert!(
        (c.output_amplitude_mrad / amplitude_mrad - 1.0).abs() < 0.35,
        "predicted {} mrad, simulated {amplitude_mrad} mrad",
        c.output_amplitude_mrad
    );
}

/// The same loop at its shipped integral gain against a brake without stiction settles,
/// and the describing function predicts no cycle either.
#[test]
fn describing_function_predicts_nothing_for_a_loop_that_settles() {
    let sets = hunting_loop(1000.0, 0.7);
    let sim = simulated(&sets);
    assert!(matches!(sim, LimitCycle::None { .. }), "{sim:?}");
    let cycles = predicted(&sets);
    assert!(cycles.is_empty(), "{cycles:?}");
}

/// The stabilised gimbal is linear and stable at rest; under a 5 Hz base sine its 5 Hz
/// error at rest is the base motion's forced response, not a limit cycle (it was reported
/// as "LIMIT CYCLE at rest: 0.0599 mrad at 5.02 Hz"). Under its shipped hull-vibration PSD
/// (1 to 150 Hz) nothing is reported as a limit cycle either.
#[test]
fn a_stable_loop_under_base_motion_reports_a_forced_error_not_a_limit_cycle() {
    let sine = "closed_loop.base_motion={kind=\"sine\", amplitude_rad=1e-3, frequency_hz=5.0}";
    for (sets, forced) in [(vec![sine.to_string()], true), (vec![], false)] {
        let s = Scenario::load("gimbal_stabilized", &sets).unwrap_or_else(|e| panic!("{e}"));
        let r = run_closed_loop(&s, &RunOptions::metrics_only()).unwrap_or_else(|e| panic!("{e}"));
        for m in &r.modes {
            match &m.limit_cycle {
                LimitCycle::Forced {
                    source,
                    frequency_hz,
                    ..
                } => {
                    assert!(source.contains("base motion"), "{source}");
                    if forced {
                        assert!((frequency_hz - 5.0).abs() < 0.1, "{frequency_hz}");
                    }
                }
                other => assert!(
                    !forced && !matches!(other, LimitCycle::Detected { .. }),
                    "{sets:?} {}: {other:?}",
                    m.mode.name()
                ),
            }
        }
    }
}

/// The hunting cycle of a loop from `hunting_loop`, derived from the equations of motion of
/// a rigid drive: independent of the simulation's plant, controller and integrator.
#[derive(Clone, Copy, Debug)]
struct DerivedHunt {
    /// Error at which the drum rests between slips, rad (half the peak-to-peak).
    amplitude_rad: f64,
    /// Duration of each slip, s.
    slip_s: f64,
    /// Duration of each stick, s.
    stick_s: f64,
    /// Command (as drum torque) when the drum lands, in the direction it slid, N m.
    landing_nm: f64,
    /// Frequency of the cycle, Hz.
    frequency_hz: f64,
    /// Earliest and latest time of the first breakaway after the step, s.
    first_breakaway_s: (f64, f64),
}

/// Stick-slip hunting under integral action, derived on the drum side.
///
/// Loop (read from the scenario): PID on the output encoder (error `e = r - theta_o`,
/// read as `ic e` motor rad), current amplifier (the command is the current), `ic = ro/ri`.
/// Referred to the drum, with `ic` from the encoder and `ic Kt` from current to torque:
///
/// ```text
/// k   = kp ic^2 Kt   = 210.1 N m/rad        J = Jo + ic^2 Jm = 0.0526 kg m^2
/// ki_e = ki ic^2 Kt  = 5253 N m/(rad s)     c = kd ic^2 Kt + bo + ic^2 bm = 2.630 N m s/rad
/// fm  = ic Tc_motor  = 0.0256 N m           Fs = 1.2, Fc = 0.7 N m (brake)
/// ```
///
/// Stick at error `a`: the output stands, the derivative term is zero and the command
/// `T = k a + I` ramps at exactly `ki_e a` N m/s. The cable stretches with it, so the motor
/// creeps at `ki_e a / (2 (EA/Lf) ri ro)` rad/s or faster (the free spans are the stiffest
/// the cable gets): 0.0127 rad/s, above the 0.01 rad/s over which its Coulomb friction
/// builds up, so the motor holds back its full `fm` and the drum breaks away when
/// `T = Fs + fm`.
///
/// Slip (taken in the + direction): `J v' = T - (bo + ic^2 bm) v - Fc - fm`, with
/// `T = k e + I - kd_e v`, `e' = -v`, `I' = ki_e e`. Differentiated twice:
///
/// ```text
/// J v''' + c v'' + k v' + ki_e v = 0,   v(0) = 0,  J v'(0) = Fs - Fc,  J v''(0) = ki_e a - c v'(0)
/// ```
///
/// (`fm` cancels: it holds back the breakaway and the slide alike). The slip ends at the
/// first zero of `v`, `t_slip`, after a travel `D = integral of v`. The cycle is symmetric
/// about the target when `D = 2a`, solved here for `a`. Everything is linear and
/// homogeneous in `(Fs - Fc, a)`: `a` is proportional to `Fs - Fc` and `t_slip` does not
/// depend on it. The command at landing is `T_land = Fc + fm + J v'(t_slip)` (below `Fs`:
/// the drum sticks), and the next stick ramps it to `-(Fs + fm)` at `ki_e a`:
///
/// ```text
/// t_stick = (Fs + fm + T_land) / (ki_e a),   f = 1 / (2 (t_slip + t_stick))
/// ```
///
/// Shipped loop: `a` = 1.789 mrad, `t_slip` = 50.6 ms, `T_land` = 0.447 N m,
/// `t_stick` = 178.0 ms, f = 2.187 Hz. The textbook second-order slip (no integral during
/// it: zeta = c / (2 sqrt(k J)) = 0.40, travel `(Fs - Fc)(1 + exp(-pi zeta/sqrt(1 -
/// zeta^2))) / k`) gives 1.50 mrad: over a slip of a fifth of the cycle the integral keeps
/// pushing, and it alone fixes where the cycle centres (without it any offset repeats).
///
/// What this leaves out, bounded:
/// - sampling: one period of computation delay and the hold (75 us) and the derivative
///   filter at 6 kHz (27 us) take `k 75 us` = 0.016 N m s/rad (0.6 %) off `c` and add
///   `c 100 us` = 2.7e-4 kg m^2 (0.5 %) to `J`: 0.3 % on amplitude and frequency;
/// - the cable: with a current amplifier and the output encoder it stands between a torque
///   source and the drum and acts only through the motor inertia behind it (5 % of `J`). At
///   the slip's 9 Hz against its locked mode near 190 Hz that is 0.2 % of 5 %; at release
///   the drum takes the excess first and the cable's torque drops by 5 % of `Fs - Fc`,
///   0.025 N m, a twist of 7 urad (0.4 % of `a`) ringing at about 200 Hz, down to 5 % by
///   the slip's end at the cable's 5 % damping. Its memory changes the transmission
///   error, which the output encoder does not read;
/// - encoder counts (0.75 urad, 0.04 %), the breakaway overshoot of at most one sample's
///   ramp (`ki_e a T` = 0.5 mN m, 0.1 % of `Fs - Fc`), and the cycle's scatter over the
///   judged stretch.
///
/// Together under 1 %: the tolerance `MODEL_TOLERANCE`. Mistakes of the size a plant can
/// make fail it: leaving the motor's inertia out of `J` moves amplitude and frequency by 1.7
/// and 1.4 %, its friction out of the stick by 5 and 3.4 %.
fn derived_hunt(sets: &[String]) -> DerivedHunt {
    let s = Scenario::load("eots_tracking", sets).unwrap_or_else(|e| panic!("{e}"));
    let p = s.closed_loop.as_ref().expect("closed-loop scenario");
    assert_eq!(p.motor.amplifier, Amplifier::Current);
    assert_eq!(p.controller.feedback, Feedback::Output);
    let (ri, ro) = (s.drive.pulley_radius_m, s.drive.drum_radius_m);
    let ic = ro / ri;
    let torque_per_a = ic * p.motor.torque_constant_nm_per_a;
    let k = p.controller.kp * ic * torque_per_a;
    let ki_e = p.controller.ki * ic * torque_per_a;
    let c = p.controller.kd * ic * torque_per_a
        + p.output.viscous_nm_s_per_rad
        + ic * ic * p.motor.viscous_nm_s_per_rad;
    let j = p.output.inertia_kg_m2 + ic * ic * p.motor.inertia_kg_m2;
    let fm = ic * p.motor.coulomb_nm;
    let fc = s.load.brake_nm;
    let fs = s.load.brake_breakaway_nm.unwrap_or(fc).max(fc);
    assert!(fs > fc, "no stiction, no hunting");

    // One slip from rest at error `a` with the command at the breakaway: (duration, travel,
    // landing command). RK4 at 2 us: 1e-4 rad per step at the slip's 57 rad/s.
    let slip = |a: f64| -> (f64, f64, f64) {
        let h = 2e-6;
        let rhs = |[e, v, i]: [f64; 3]| [-v, (k * e + i - c * v - fc - fm) / j, ki_e * e];
        let add = |x: [f64; 3], d: [f64; 3], s: f64| [0, 1, 2].map(|n| x[n] + s * d[n]);
        let mut x = [a, 0.0, fs + fm - k * a];
        let mut t = 0.0;
        loop {
            let k1 = rhs(x);
            let k2 = rhs(add(x, k1, h / 2.0));
            let k3 = rhs(add(x, k2, h / 2.0));
            let k4 = rhs(add(x, k3, h));
            let next =
                [0, 1, 2].map(|n| x[n] + h / 6.0 * (k1[n] + 2.0 * k2[n] + 2.0 * k3[n] + k4[n]));
            if next[1] <= 0.0 {
                // The speed's zero, interpolated within the step.
                let f = x[1] / (x[1] - next[1]);
                let end = [0, 1, 2].map(|n| x[n] + f * (next[n] - x[n]));
                return (t + f * h, a - end[0], k * end[0] + end[2]);
            }
            x = next;
            t += h;
        }
    };
    // D(a) - 2a falls from D(0) > 0; the undamped slip without the integral travels
    // 2 (Fs - Fc)/k, more than any damped one, so at that `a` it is negative.
    let (mut lo, mut hi) = (0.0, 2.0 * (fs - fc) / k);
    assert!(slip(hi).1 < 2.0 * hi);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if slip(mid).1 > 2.0 * mid {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let a = 0.5 * (lo + hi);
    let (slip_s, _, landing_nm) = slip(a);
    assert!(
        landing_nm.abs() < fs,
        "the drum does not stick: {landing_nm} N m"
    );

    // The motor's creep while the drum sticks, at the free spans' stiffness.
    let half_stiffness = {
        let r = ro + ri; // crossed (figure-eight) spans
        let span = (s.drive.center_distance_m.powi(2) - r * r).sqrt();
        s.drive.cable_modulus_n / span
    };
    let creep = ki_e * a / (2.0 * half_stiffness * ri * ro);
    assert!(
        creep > p.motor.coulomb_smoothing_rad_s,
        "the motor creeps at {creep} rad/s: its friction is not at full level in the stick"
    );

    let stick_s = (fs + fm + landing_nm) / (ki_e * a);
    // First breakaway: the step puts k STEP_RAD on the drum and the integral ramps it at
    // ki_e STEP_RAD; the motor's friction then holds back between nothing (the creep is
    // slower at this smaller error) and fm, and the command reaches the motor one sample
    // late.
    let ramp = |target: f64| STEP_S + (target - k * STEP_RAD) / (ki_e * STEP_RAD);
    DerivedHunt {
        amplitude_rad: a,
        slip_s,
        stick_s,
        landing_nm,
        frequency_hz: 1.0 / (2.0 * (slip_s + stick_s)),
        first_breakaway_s: (ramp(fs), ramp(fs + fm) + 1.0 / p.controller.sample_rate_hz),
    }
}
