//! Faults injected into a clean log mid-record, stretches that are not the drive: an input
//! jerk the output follows, a reading stuck while the other moves, an input that leaves its
//! motion, an output reading that jumps away and back, an input that jumps and stays, an
//! output spike. Shared by `tests/segments.rs` and `benches/identify_rates.rs`.

#![allow(dead_code)]

use cable_servo::identify::segments::Channel;
use cable_servo::identify::{BenchLog, EffectName};
use cable_servo::scenario::Scenario;
use rand::{Rng, SeedableRng};
use std::f64::consts::TAU;

use super::rates::{scenario, truth};

/// The truth's encoder steps (65536 and 2^20 counts per revolution), rad.
pub const Q_IN: f64 = TAU / 65536.0;
pub const Q_OUT: f64 = TAU / 1_048_576.0;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fault {
    /// The input jerked by about 1 rad and back within 0.2 s, the output following through
    /// a 20 ms lag.
    Jerk,
    /// The output reading jumps to a wrong value (or holds its last one) for 0.5 to 2 s.
    OutputStuck,
    /// The input reading holds its last value for 0.5 to 2 s.
    InputStuck,
    /// The input reading leaves its sine by 0.05 to 0.2 rad over 0.5 to 1.5 s (the output
    /// does not follow).
    Departure,
    /// The output reading jumps by 0.02 to 0.1 rad for 0.1 to 0.5 s and back (a glitch of
    /// its encoder), the input not moving with it.
    OutputJump,
    /// The input jumps by 1 to 2 rad within 0.05 to 0.15 s (faster than 1.5 times the scan's
    /// peak speed) and stays there, the output following through a 20 ms lag: every later
    /// sample is off the motion fitted before.
    JumpThatStays,
    /// One to four output samples 1 to 10 mrad off (170 to 1700 encoder steps).
    OutputSpike,
}

pub const FAULTS: [Fault; 7] = [
    Fault::Jerk,
    Fault::OutputStuck,
    Fault::InputStuck,
    Fault::Departure,
    Fault::OutputJump,
    Fault::JumpThatStays,
    Fault::OutputSpike,
];

pub fn quant(v: f64, q: f64) -> f64 {
    (v / q).round() * q
}

/// Inject `fault` starting at `t0` (s); returns its channel and its span (s).
pub fn inject(
    log: &mut BenchLog,
    fault: Fault,
    t0: f64,
    ic: f64,
    rng: &mut impl Rng,
) -> (Channel, f64, f64) {
    let n = log.t_s.len();
    let a = row_at(log, t0);
    let dt = log.t_s[1] - log.t_s[0];
    let bump = |t: f64, width: f64| 0.5 * (1.0 - (TAU * (t - t0) / width).cos());
    match fault {
        Fault::Jerk => {
            let width = 0.2;
            let amp = rng.gen_range(0.8..1.2) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
            let alpha = 1.0 - (-dt / 0.02f64).exp();
            let mut lagged = 0.0;
            for i in a..n {
                let t = log.t_s[i];
                let u = if t <= t0 + width {
                    amp * bump(t, width)
                } else {
                    0.0
                };
                log.theta_in_rad[i] += quant(u, Q_IN);
                lagged += alpha * (u - lagged);
                log.theta_out_rad[i] += quant(lagged / ic, Q_OUT);
            }
            (Channel::Input, t0, t0 + width)
        }
        Fault::OutputStuck => {
            let dur = rng.gen_range(0.5..2.0);
            let wrong = if rng.gen_bool(0.5) {
                0.0
            } else {
                rng.gen_range(0.02..0.1) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 }
            };
            let held = quant(log.theta_out_rad[a] + wrong, Q_OUT);
            let b = a + (dur / dt).round() as usize;
            for v in &mut log.theta_out_rad[a..b] {
                *v = held;
            }
            (Channel::Output, t0, log.t_s[b - 1])
        }
        Fault::InputStuck => {
            let dur = rng.gen_range(0.5..2.0);
            let end = hold_input(log, t0, dur);
            (Channel::Input, t0, end)
        }
        Fault::Departure => {
            let width = rng.gen_range(0.5..1.5);
            let amp = rng.gen_range(0.05..0.2) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
            for i in a..n {
                let t = log.t_s[i];
                if t <= t0 + width {
                    log.theta_in_rad[i] += quant(amp * bump(t, width), Q_IN);
                }
            }
            (Channel::Input, t0, t0 + width)
        }
        Fault::JumpThatStays => {
            let width = rng.gen_range(0.05..0.15);
            let amp = rng.gen_range(1.0..2.0) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
            // Whole input steps, so that the readings after it are those of a drive shifted
            // by exactly that much.
            let amp = quant(amp, Q_IN);
            let alpha = 1.0 - (-dt / 0.02f64).exp();
            let mut lagged = 0.0;
            for i in a..n {
                let t = log.t_s[i];
                let u = if t <= t0 + width {
                    amp * 0.5 * (1.0 - (std::f64::consts::PI * (t - t0) / width).cos())
                } else {
                    amp
                };
                let before = log.theta_in_rad[i];
                log.theta_in_rad[i] = quant(before + u, Q_IN);
                lagged += alpha * (u - lagged);
                let out = log.theta_out_rad[i];
                log.theta_out_rad[i] = quant(out + lagged / ic, Q_OUT);
            }
            (Channel::Input, t0, t0 + width)
        }
        Fault::OutputSpike => {
            let len = rng.gen_range(1..=4usize);
            let wrong = rng.gen_range(1e-3..1e-2) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
            let end = offset_output(log, a, a + len, wrong);
            (Channel::Output, t0, end)
        }
        Fault::OutputJump => {
            let dur = rng.gen_range(0.1..0.5);
            let wrong = rng.gen_range(0.02..0.1) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
            let end = offset_output(log, a, a + (dur / dt).round() as usize, wrong);
            (Channel::Output, t0, end)
        }
    }
}

/// The output readings of rows `a..b` of `log` moved by `size` (rad) and kept on the
/// output's encoder grid; returns the time of the last row moved, s.
pub fn offset_output(log: &mut BenchLog, a: usize, b: usize, size: f64) -> f64 {
    for v in &mut log.theta_out_rad[a..b] {
        *v = quant(*v + size, Q_OUT);
    }
    log.t_s[b - 1]
}

/// The input reading held at its value at `t0` (s, inside the log) for `dur` s; returns the
/// time of the last sample held, s.
pub fn hold_input(log: &mut BenchLog, t0: f64, dur: f64) -> f64 {
    let a = row_at(log, t0);
    let dt = log.t_s[1] - log.t_s[0];
    let b = (a + (dur / dt).round() as usize).min(log.t_s.len());
    let held = log.theta_in_rad[a];
    for v in &mut log.theta_in_rad[a..b] {
        *v = held;
    }
    log.t_s[b - 1]
}

/// A log of the independent truth with `effects` (scenario from the seed's parity) and
/// `fault` injected at a time drawn from the seed (8 to 20 s into the record); returns the
/// scenario, the log and the fault's channel and span, s.
pub fn faulted_log(
    effects: &[(EffectName, f64)],
    fault: Fault,
    seed: u64,
) -> (Scenario, BenchLog, (Channel, f64, f64)) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let sc = scenario(seed % 2 == 1);
    let mut log = truth(&sc, effects, seed);
    let t0 = rng.gen_range(8.0..20.0);
    let span = inject(&mut log, fault, t0, sc.drive.ratio(), &mut rng);
    (sc, log, span)
}

/// The first row of `log` at or after `t0` (s); `t0` must lie inside the log.
pub fn row_at(log: &BenchLog, t0: f64) -> usize {
    log.t_s
        .iter()
        .position(|t| *t >= t0)
        .expect("the time lies inside the log")
}
