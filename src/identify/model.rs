//! Replay of the quasi-static memory model against measured logs, the extended models built
//! from the effect library, and their fits (nonlinear parameters by Levenberg-Marquardt,
//! linear ones projected out by least squares).

use std::collections::HashMap;
use std::sync::Arc;

use nalgebra::DMatrix;

use super::effects::{EffectName, IdentifyParams};
use super::lm::levenberg_marquardt;
use super::IdentifyError;
use crate::measurement::BenchLog;
use crate::physics::effects::{ContactMemory, EffectsParams};
use crate::physics::{CableDrive, DriveParams, HysteresisModel};

/// A log made ready for fitting: decimated, with velocities and motion direction.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// Where it came from.
    pub source: String,
    /// Time from the log start, s.
    pub t: Vec<f64>,
    /// Input angle, rad.
    pub th_in: Vec<f64>,
    /// Output angle, rad.
    pub th_out: Vec<f64>,
    /// Transmitted torque `M = -load_nm`, N m.
    pub torque: Vec<f64>,
    /// Input velocity, rad/s (smoothed central difference).
    pub vel_in: Vec<f64>,
    /// Output velocity, rad/s.
    pub vel_out: Vec<f64>,
    /// Direction of motion (+1/-1, held through stops).
    pub dir: Vec<f64>,
    /// Input travel since the previous sample, rad.
    pub travel: Vec<f64>,
    /// Record length, s.
    pub duration: f64,
    /// Quantisation step of the input angle, rad (0 when not visible).
    pub q_in: f64,
    /// Quantisation step of the output angle, rad.
    pub q_out: f64,
    /// Rows whose averaged samples straddle a step of the load ([`straddles_a_step`]):
    /// neither fitted nor scored.
    pub straddles_step: Vec<bool>,
}

/// Decimate by block averaging to at most `max_rate_hz` and derive velocities.
pub fn prepare(log: &BenchLog, max_rate_hz: f64) -> Result<Prepared, IdentifyError> {
    let bad = |message: String| IdentifyError::BadLog {
        log: log.source.clone(),
        message,
    };
    let n = log.len();
    if n < 40 {
        return Err(bad(format!(
            "{n} samples is too few; at least 40 are needed (a few periods of motion)"
        )));
    }
    for (name, col) in [
        ("theta_in_rad", &log.theta_in_rad),
        ("theta_out_rad", &log.theta_out_rad),
        ("load_nm", &log.load_nm),
    ] {
        if col.len() != n {
            return Err(bad(format!(
                "column {name} has {} rows, t_s has {n}",
                col.len()
            )));
        }
        if let Some(i) = col.iter().position(|v| !v.is_finite()) {
            return Err(bad(format!("column {name} is not finite at row {}", i + 1)));
        }
    }
    if let Some(i) = log
        .t_s
        .windows(2)
        .position(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
    {
        return Err(bad(format!("t_s does not increase at row {}", i + 2)));
    }
    let span = log.t_s[n - 1] - log.t_s[0];
    let rate = (n - 1) as f64 / span;
    // Keep at least 40 samples after averaging, whatever the rates.
    let m = ((rate / max_rate_hz).floor() as usize).clamp(1, (n / 40).max(1));
    let q_in = super::resolution::encoder_step(&log.theta_in_rad);
    let q_out = super::resolution::encoder_step(&log.theta_out_rad);
    let avg = |v: &[f64]| -> Vec<f64> {
        v.chunks(m)
            .filter(|c| c.len() == m)
            .map(|c| c.iter().sum::<f64>() / m as f64)
            .collect()
    };
    let t0 = log.t_s[0];
    let t: Vec<f64> = avg(&log.t_s).into_iter().map(|t| t - t0).collect();
    let th_in = avg(&log.theta_in_rad);
    let th_out = avg(&log.theta_out_rad);
    let torque: Vec<f64> = avg(&log.load_nm).into_iter().map(|l| -l).collect();
    let straddles_step = straddles_a_step(&log.load_nm, m);
    let k = t.len();
    let dt = span / (n - 1) as f64 * m as f64;
    let w = window_rows(dt);
    let deriv = |v: &[f64]| -> Vec<f64> {
        (0..k)
            .map(|i| {
                let a = i.saturating_sub(w);
                let b = (i + w).min(k - 1);
                (v[b] - v[a]) / (t[b] - t[a])
            })
            .collect()
    };
    let vel_in = deriv(&th_in);
    let vel_out = deriv(&th_out);
    let dir = direction(&vel_in, None, dir_floor(q_in, w, dt), Some(&torque));
    let mut travel = vec![0.0; k];
    for i in 1..k {
        travel[i] = (th_in[i] - th_in[i - 1]).abs();
    }
    Ok(Prepared {
        source: log.source.clone(),
        duration: t[k - 1].max(dt),
        t,
        th_in,
        th_out,
        torque,
        vel_in,
        vel_out,
        dir,
        travel,
        q_in,
        q_out,
        straddles_step,
    })
}

/// A load's range, N m: its 1st to 99th percentile, so that a few outliers do not set it.
/// 0 for an empty load.
fn load_range(load_nm: &[f64]) -> f64 {
    if load_nm.is_empty() {
        return 0.0;
    }
    let mut sorted: Vec<f64> = load_nm.to_vec();
    sorted.sort_by(f64::total_cmp);
    let at = |q: f64| sorted[((sorted.len() - 1) as f64 * q).round() as usize];
    at(0.99) - at(0.01)
}

/// Per row of `m` samples averaged (the rows [`prepare`] makes): whether the load steps
/// inside it by more than half its range over the log (1st to 99th percentile). A brake
/// or a bearing flips its torque within a sample where the drum reverses, and the drum's
/// lag jumps with it; a row averaged across that instant holds the mean of two states the
/// drive never passes through slowly, which no replay of the averaged torque gives (on a
/// 500 Hz log at 250 Hz rows one such row per reversal left 12 times the noise, enough
/// for a drum runout to be named in a bearing friction's place). Never set when rows are
/// single samples. On the shipped da Vinci logs (rows of five samples) no row's load
/// moves by half the range.
pub fn straddles_a_step(load_nm: &[f64], m: usize) -> Vec<bool> {
    let rows = load_nm.len() / m.max(1);
    if m < 2 || rows == 0 {
        return vec![false; rows];
    }
    let range = load_range(load_nm);
    load_nm
        .chunks_exact(m)
        .map(|c| {
            let (lo, hi) = c
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(*v), b.max(*v))
                });
            range > 0.0 && hi - lo > 0.5 * range
        })
        .collect()
}

/// Rows each side of a velocity's central difference for rows `dt` (s) apart: 25 ms,
/// at least one.
fn window_rows(dt: f64) -> usize {
    ((0.025 / dt).round() as usize).max(1)
}

/// Speed (rad/s) below which the direction of motion never flips: four input encoder
/// steps `q_in` (rad) over the velocity's difference window of `2 w` rows of `dt` (s).
fn dir_floor(q_in: f64, w: usize, dt: f64) -> f64 {
    4.0 * q_in / (2.0 * w as f64 * dt)
}

/// Direction of motion (+1/-1, held through stops) from the input velocity `vel_in`
/// (rad/s). A reversal is confirmed where the speed passes 0.2 % of the peak speed of the
/// rows in `keep` (all rows without it), or `floor` (rad/s) when that is higher, and the
/// flip is placed where the velocity last took the new sign before it: the reversal
/// itself, not the row where the speed has grown past the threshold; or, given the
/// transmitted `torque` (N m per row), at a turning row where it steps ([`turned_at`]).
fn direction(
    vel_in: &[f64],
    keep: Option<&[bool]>,
    floor: f64,
    torque: Option<&[f64]>,
) -> Vec<f64> {
    let vmax = vel_in
        .iter()
        .enumerate()
        .filter(|(i, _)| keep.is_none_or(|k| k.get(*i).copied().unwrap_or(true)))
        .fold(0.0f64, |a, (_, v)| a.max(v.abs()));
    // The threshold only confirms a reversal, so that quantisation steps never flip the
    // direction. The brake and any bearing friction flip where the motion reverses: a
    // row between the reversal and the confirmation would carry the friction the wrong
    // way, and one such row at a reversal between samples (the speed under the threshold
    // for 3 ms on the gimbal's sine) left 17 times the noise there, enough for a drum
    // runout to be named in a bearing friction's place.
    let thr = (0.002 * vmax).max(floor);
    // A load step worth reading a turn off: a quarter of the load's range (1st to 99th
    // percentile), and twenty times its typical change between rows, so that a load
    // without a brake, whose range is its noise, never places a turn.
    let least_step = torque.map_or(f64::INFINITY, |m| {
        if m.len() < 2 {
            return f64::INFINITY;
        }
        let mut steps: Vec<f64> = m.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
        steps.sort_by(f64::total_cmp);
        (0.25 * load_range(m)).max(20.0 * steps[steps.len() / 2])
    });
    let first = vel_in
        .iter()
        .find(|v| v.abs() > thr)
        .map_or(1.0, |v| v.signum());
    let mut out = vec![first; vel_in.len()];
    let mut cur = first;
    let mut last_flip = 0;
    for (i, v) in vel_in.iter().enumerate() {
        if v.abs() > thr && v.signum() != cur {
            cur = v.signum();
            // Back to the first row of the run that already moves the new way (a row at
            // rest, or the previous flip, ends it).
            let mut j = i;
            while j > last_flip && vel_in[j - 1] * cur > 0.0 {
                j -= 1;
            }
            if let Some(r) =
                torque.and_then(|m| turned_at(m, least_step, vel_in, thr, last_flip, j))
            {
                j = r;
            }
            for d in &mut out[j..i] {
                *d = cur;
            }
            last_flip = j;
        }
        out[i] = cur;
    }
    out
}

/// The row at which a load that follows the motion (a brake) stepped, among the rows
/// before `j` (the first that moves the new way, after `last_flip`) whose speed is under
/// `thr`: where the input turns on a sample its speed there reads zero, and which way the
/// drive already went is read off the load. `None` when no such row holds a step larger
/// than `least_step` (N m) that is also the largest step from there to `j`. (A bearing
/// friction that flips at the turning sample itself, carried the old way, left 0.1 to
/// 0.17 mrad on that one row per reversal, and a drum runout was named in its place.)
fn turned_at(
    m: &[f64],
    least_step: f64,
    vel_in: &[f64],
    thr: f64,
    last_flip: usize,
    j: usize,
) -> Option<usize> {
    let mut k = j;
    while k > last_flip + 1 && vel_in[k - 1].abs() <= thr {
        k -= 1;
    }
    if k == j || j >= m.len() {
        return None;
    }
    let step = |r: usize| (m[r] - m[r - 1]).abs();
    let (r, big) =
        (k.max(1)..=j).map(|r| (r, step(r))).fold(
            (j, 0.0),
            |(br, bs), (r, s)| if s > bs { (r, s) } else { (br, bs) },
        );
    (r < j && big > least_step).then_some(r)
}

/// Once the bad stretches of each log are known (`keep_per_log`, one flag per row of each
/// prepared log): each log's direction of motion from the rows kept
/// ([`Prepared::direction_over`]), and its rows averaged across a load step
/// ([`Prepared::straddles_step`]) taken out of the rows to fit and score.
pub fn settle_rows(prepared: &mut [Prepared], keep_per_log: &mut [Vec<bool>]) {
    for (p, keep) in prepared.iter_mut().zip(keep_per_log.iter_mut()) {
        p.direction_over(keep);
        for (k, s) in keep.iter_mut().zip(&p.straddles_step) {
            *k &= !*s;
        }
    }
}

impl Prepared {
    /// Direction of motion again, its threshold from the peak speed of the rows kept
    /// (`keep`, one per row) only. A stretch that is not the drive (an input jerk, or a
    /// held reading that jumps back) moves far faster than the motion, and a threshold
    /// scaled on it confirms reversals late, or never where it passes the motion's own
    /// peak speed, and the brake and any bearing friction flip at every reversal.
    /// Nothing changes when every row is kept.
    pub fn direction_over(&mut self, keep: &[bool]) {
        if keep.iter().all(|k| *k) || self.t.len() < 2 {
            return;
        }
        let k = self.t.len();
        let dt = (self.t[k - 1] - self.t[0]) / (k - 1) as f64;
        let floor = dir_floor(self.q_in, window_rows(dt), dt);
        self.dir = direction(&self.vel_in, Some(keep), floor, Some(&self.torque));
    }
}

/// The torque the cable carries in log `l` when a bearing hides a Coulomb torque `mb`
/// (N m) from the load sensor: the measured torque plus `mb` along the motion.
pub fn with_bearing_friction(l: &Prepared, mb: f64) -> Vec<f64> {
    l.torque
        .iter()
        .zip(&l.dir)
        .map(|(m, d)| m + mb * d)
        .collect()
}

/// Transmission error of the memory model along a torque history, rad.
pub fn replay(drive: &DriveParams, torque: &[f64]) -> Result<Vec<f64>, (usize, String)> {
    let mut d = CableDrive::new(drive.clone(), HysteresisModel::Memory);
    let mut out = Vec::with_capacity(torque.len());
    for (i, m) in torque.iter().enumerate() {
        match d.apply_torque(*m) {
            Ok(s) => out.push(s.transmission_error_rad),
            Err(f) => return Err((i, f.to_string())),
        }
    }
    Ok(out)
}

/// Knots of a relaxing preload: the error is replayed at the preload of each knot and
/// interpolated in time between them. Backlash is convex in the preload, so a single chord
/// from the first to the last preload overstates the error in between and biases the fitted
/// rate low; the chord's error falls with the square of the knot spacing.
pub const RELAXATION_KNOTS: usize = 4;

/// [`replay`] with the preload changing linearly from `drive.preload_n` at rate
/// `rate_per_s` (1/s of the initial preload, `preload_relaxation`): falling when positive,
/// rising when negative, over sample times `t_s` of a record `duration_s` long.
pub fn relaxing_replay(
    drive: &DriveParams,
    torque: &[f64],
    t_s: &[f64],
    duration_s: f64,
    rate_per_s: f64,
) -> Result<Vec<f64>, (usize, String)> {
    let mut e = replay(drive, torque)?;
    let changes = rate_per_s != 0.0 && rate_per_s.is_finite();
    if !changes || duration_s.is_nan() || duration_s <= 0.0 {
        return Ok(e);
    }
    let k = RELAXATION_KNOTS;
    let knots = (1..=k)
        .map(|j| {
            let mut d = drive.clone();
            d.preload_n *= (1.0 - rate_per_s * duration_s * j as f64 / k as f64).max(0.05);
            replay(&d, torque)
        })
        .collect::<Result<Vec<_>, _>>()?;
    for (i, v) in e.iter_mut().enumerate() {
        let x = (t_s[i] / duration_s).clamp(0.0, 1.0) * k as f64;
        let j = (x.floor() as usize).min(k - 1);
        let lo = if j == 0 { *v } else { knots[j - 1][i] };
        *v = lo + (x - j as f64) * (knots[j][i] - lo);
    }
    Ok(e)
}

/// Low-pass in input-travel domain: what stuck cable carried over the wraps does to a jump.
pub fn transport_filter(e: &[f64], travel: &[f64], theta_c: f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(e.len());
    let mut y = e.first().copied().unwrap_or(0.0);
    for (i, v) in e.iter().enumerate() {
        let a = if theta_c > 0.0 {
            1.0 - (-travel[i] / theta_c).exp()
        } else {
            1.0
        };
        y += a * (v - y);
        out.push(y);
    }
    out
}

/// The capstan replay along log `l` with bearing friction `bearing_nm` (N m, against the
/// motion) and preload relaxation `relaxation_per_s` (1/s), rad; a failure names the log
/// and the time.
fn log_replay(
    drive: &DriveParams,
    l: &Prepared,
    bearing_nm: f64,
    relaxation_per_s: f64,
) -> Result<Vec<f64>, IdentifyError> {
    let torque = with_bearing_friction(l, bearing_nm);
    relaxing_replay(drive, &torque, &l.t, l.duration, relaxation_per_s).map_err(|(i, message)| {
        IdentifyError::Replay {
            log: l.source.clone(),
            t_s: l.t.get(i).copied().unwrap_or(0.0),
            message,
        }
    })
}

/// A calibrated instrument's prediction of the transmission error along log `l` (rad, at
/// `drive`'s ratio): the capstan replay with the effects' bearing friction, relaxation and
/// transport, plus their kinematic error, compliance, contact memory and encoder terms.
/// `bearing_nm`, `relaxation_per_s` and `transport_rad` add to the effects' own (the
/// terms a fit on top may add). Fails where the drive cannot carry the log's load.
pub fn calibrated_prediction(
    drive: &DriveParams,
    effects: &EffectsParams,
    l: &Prepared,
    extra: [f64; 3],
) -> Result<Vec<f64>, IdentifyError> {
    let [bearing_nm, relaxation_per_s, transport_rad] = extra;
    let ic = drive.ratio();
    let mut e = log_replay(
        drive,
        l,
        effects.bearing_friction() + bearing_nm,
        effects.preload_relaxation_per_s.unwrap_or(0.0) + relaxation_per_s,
    )?;
    let tc = effects.cable_transport_rad.unwrap_or(0.0) + transport_rad;
    if tc > 0.0 {
        e = transport_filter(&e, &l.travel, tc);
    }
    let c = effects.load_compliance();
    let tau = effects.encoder_delay_s.unwrap_or(0.0);
    let s = effects.encoder_scale_error.unwrap_or(0.0);
    let mut contacts = ContactMemory::new(effects, l.th_in.first().copied().unwrap_or(0.0));
    Ok((0..l.t.len())
        .map(|i| {
            let (th_in, th_out, m) = (l.th_in[i], l.th_out[i], l.torque[i]);
            let lag = contacts.as_mut().map_or(0.0, |k| k.commit(th_in, m));
            e[i] + effects.kinematic_error_rad(th_in, th_out, l.t[i], ic) + c * m + lag
                - tau * l.vel_out[i]
                + s * th_out
        })
        .collect())
}

/// A nonlinear parameter of a model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NlParam {
    /// Friction coefficient.
    Mu,
    /// Preload, N.
    Preload,
    /// The effect's own nonlinear parameter.
    Effect(EffectName),
    /// A parameter of the friction memory's load law.
    Memory(MemoryLaw),
}

/// Nonlinear parameters of how the distributed friction memory follows the transmitted
/// torque's magnitude `|M|`: contact thresholds that grow with it, and a slack (free
/// travel) that it takes up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemoryLaw {
    /// Threshold growth `beta`: thresholds `r_j (1 + beta |M|)`, 1/(N m).
    Growth,
    /// The slack's width at no load, rad of input.
    Slack,
    /// The torque that takes the slack up, N m.
    TakenUp,
}

/// Points of the coarse scan of each memory-law parameter, and rounds of the scan (the
/// threshold growth and the slack trade against each other: the second round scans each
/// with the others at their first-round values).
const LAW_SCAN: (usize, usize) = (13, 2);

/// Intervals of the coarse grid of the slack's width and take-up torque tried after the
/// scan (`LAW_GRID` widths above zero times `LAW_GRID + 1` torques).
const LAW_GRID: usize = 4;

/// How far apart the logs' lightest and heaviest mean torque magnitudes must lie, as a
/// fraction of the heaviest, for them to be at more than one load level (the da Vinci logs
/// run from 0.013 to 0.119 N m; logs of one bench setting agree within a few percent).
const LOAD_LEVELS_APART: f64 = 0.2;

impl NlParam {
    /// Name in reports and saved models: the drive key, the effect's name, or for the
    /// friction memory its load exponent.
    pub fn name(self) -> &'static str {
        match self {
            NlParam::Mu => "friction_coefficient",
            NlParam::Preload => "preload_n",
            NlParam::Effect(EffectName::DistributedFrictionMemory) => {
                "friction_memory_load_exponent"
            }
            NlParam::Effect(e) => e.as_str(),
            NlParam::Memory(MemoryLaw::Growth) => "friction_memory_threshold_growth_per_nm",
            NlParam::Memory(MemoryLaw::Slack) => "friction_memory_slack_rad",
            NlParam::Memory(MemoryLaw::TakenUp) => "friction_memory_slack_taken_up_nm",
        }
    }
}

/// A coefficient fitted linearly.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinParam {
    /// Encoder zero of log `k`, rad.
    Offset(usize),
    /// `G_ref / G`.
    ModulusScale,
    /// `1/ic - 1/ic_ref`.
    InverseRatio,
    /// Coefficient `k` of an effect's column.
    Effect(EffectName, usize),
    /// Log `k`'s own value of an effect a calibrated scenario marks as per log
    /// (`identify.per_log`), added to the calibrated one.
    PerLog(EffectName, usize),
}

/// The one column of an effect whose size multiplies a measured signal, at row `i` of log
/// `l` (rad per unit of the effect's size); 0 for any other effect.
pub fn single_column(e: EffectName, l: &Prepared, i: usize) -> f64 {
    match e {
        EffectName::EncoderDelay => -l.vel_out[i],
        EffectName::EncoderScaleError => l.th_out[i],
        EffectName::ThermalDrift => l.t[i],
        EffectName::LoadCompliance => l.torque[i],
        _ => 0.0,
    }
}

/// Effects whose signature is linear in their size given the measured signals.
pub fn is_linear(e: EffectName) -> bool {
    !matches!(
        e,
        EffectName::PreloadRelaxation | EffectName::BearingFriction | EffectName::CableTransport
    )
}

/// The bound that means none of effect `e` (a cable transport over the least travel
/// allowed, 1e-4 rad; a bearing friction of zero) when the fit `x` (layout `nl`) sits on
/// it, within a millionth of the parameter's range: the logs pushed it to less than the
/// model can hold, so the effect is not found. `None` for an effect sized by a linear
/// column, or fitted with either sign (a preload relaxation, whose none lies inside its
/// range and whose lower bound is a rising preload), or off the bound.
pub fn at_none_bound(nl: &[(NlParam, f64, f64, f64)], x: &[f64], e: EffectName) -> Option<f64> {
    if is_linear(e) {
        return None;
    }
    nl.iter()
        .zip(x)
        .find(|(n, _)| n.0 == NlParam::Effect(e))
        .filter(|(n, _)| n.1 >= 0.0)
        .filter(|(n, v)| (**v - n.1).abs() <= 1e-6 * (n.2 - n.1))
        .map(|(n, _)| n.1)
}

/// The friction memory's load exponent in a fit's nonlinear parameters `x` (layout `nl`),
/// 1 when the memory is not in the model.
pub fn memory_load_exponent(nl: &[(NlParam, f64, f64, f64)], x: &[f64]) -> f64 {
    nl.iter()
        .position(|n| n.0 == NlParam::Effect(EffectName::DistributedFrictionMemory))
        .and_then(|i| x.get(i).copied())
        .unwrap_or(1.0)
}

/// The nonlinear parameters of a fit that ended on a bound (layout `nl`, values `x`), each
/// as a sentence: the logs push them past what the model allows, so the value is a limit,
/// not an estimate.
pub fn on_bounds(nl: &[(NlParam, f64, f64, f64)], x: &[f64]) -> Vec<String> {
    nl.iter()
        .zip(x)
        .filter_map(|(n, v)| {
            let near = |b: f64| (v - b).abs() <= 1e-9 * b.abs().max(1e-12);
            let side = if near(n.1) {
                "lower"
            } else if near(n.2) {
                "upper"
            } else {
                return None;
            };
            Some(format!(
                "{} = {} is on its {side} bound (allowed {} to {}): the logs push it further, so read it as a limit, not an estimate",
                n.0.name(),
                crate::compact(*v),
                crate::compact(n.1),
                crate::compact(n.2)
            ))
        })
        .collect()
}

/// Step of the preload raise (the friction coefficient's, when the preload is known) that
/// looks for a drive carrying every log ([`Evaluator::carrying_start`]): 5 %.
pub const CARRY_STEP: f64 = 1.05;
/// Largest raise tried, times the drive's own value (33 steps of 5 %).
pub const CARRY_MAX: f64 = 5.0;

/// A model: the base drive (reference values), what is calibrated and which effects.
#[derive(Clone, Debug)]
pub struct Spec {
    /// Drive with reference values (start of calibration; `G_ref`, `ic_ref`).
    pub drive: DriveParams,
    /// Calibrate friction.
    pub fit_mu: bool,
    /// Calibrate preload.
    pub fit_pre: bool,
    /// Calibrate cable modulus.
    pub fit_g: bool,
    /// Calibrate the ratio.
    pub fit_ratio: bool,
    /// Effects included.
    pub effects: Vec<EffectName>,
    /// Bounds and settings.
    pub ident: IdentifyParams,
    /// A calibrated instrument's effects (a scenario's `[effects]`), held at their values
    /// in every prediction: the effects above are then fitted on top of the calibrated
    /// model (`None`: the capstan model alone).
    pub calibrated: Option<EffectsParams>,
}

/// Parameters of a fitted model.
#[derive(Clone, Debug)]
pub struct Fitted {
    /// Nonlinear parameters (layout of `Spec::nonlinear`).
    pub x: Vec<f64>,
    /// Linear coefficients.
    pub coef: Vec<f64>,
    /// Names of the linear coefficients.
    pub lin: Vec<LinParam>,
    /// Residual sum of squares on the fitted rows.
    pub cost: f64,
    /// Rows fitted.
    pub n_fit: usize,
    /// Iterations of the nonlinear fit (0 when there is nothing nonlinear to fit).
    pub iterations: usize,
    /// Whether the nonlinear fit converged; `false` when it stopped on its iteration
    /// limit still improving.
    pub converged: bool,
}

impl Fitted {
    /// The fitted linear coefficient `k` of effect `e` (its unit is the effect's), or
    /// `None` when the fit does not carry it.
    pub fn effect_coef(&self, e: EffectName, k: usize) -> Option<f64> {
        self.lin
            .iter()
            .position(|p| *p == LinParam::Effect(e, k))
            .map(|i| self.coef[i])
    }
}

type ReplayKey = [u64; 5];

/// Evaluates a model on a set of logs, caching base replays.
pub struct Evaluator<'a> {
    /// The model.
    pub spec: Spec,
    /// The logs.
    pub logs: &'a [Prepared],
    /// Measured error relative to the reference ratio, stacked over the logs, rad.
    y: Vec<f64>,
    /// Largest transmitted torque magnitude over the logs, N m.
    max_torque: f64,
    /// Whether the logs were recorded at more than one load level (their mean torque
    /// magnitudes differ): the memory's load law is calibrated across such logs only. On
    /// logs at one level its threshold growth is close to a uniform scale of the threshold
    /// grid and its slack a wider first contact, which the logs cannot tell from the
    /// weights.
    several_loads: bool,
    cache: HashMap<ReplayKey, Arc<Vec<Vec<f64>>>>,
}

/// One model evaluation: fixed part and linear columns, stacked over logs.
pub struct Design {
    /// Target minus fixed part.
    pub target: Vec<f64>,
    /// Fixed part of the prediction.
    pub fixed: Vec<f64>,
    /// Linear columns, each over its rows `support` only (zero on every other row).
    pub cols: Vec<Vec<f64>>,
    /// The rows each column covers (an encoder zero's: its own log's), in stacked row
    /// indices.
    pub support: Vec<std::ops::Range<usize>>,
    /// Their names.
    pub names: Vec<LinParam>,
    /// Largest `|M|^p` over the logs (p the friction memory's load exponent; 1 without
    /// the memory), (N m)^p: where the load-scaled memory weights are bounded.
    pub max_load_factor: f64,
}

impl<'a> Evaluator<'a> {
    /// Set up; the measured error uses the reference ratio of `spec.drive`.
    pub fn new(spec: Spec, logs: &'a [Prepared]) -> Self {
        let ic = spec.drive.ratio();
        let y = logs
            .iter()
            .flat_map(|l| l.th_out.iter().zip(&l.th_in).map(|(o, i)| o - i / ic))
            .collect();
        let max_torque = logs
            .iter()
            .flat_map(|l| l.torque.iter())
            .fold(0.0_f64, |m, t| m.max(t.abs()));
        // Each log's mean torque magnitude: the load level it was recorded at.
        let levels: Vec<f64> = logs
            .iter()
            .map(|l| l.torque.iter().map(|t| t.abs()).sum::<f64>() / l.torque.len().max(1) as f64)
            .collect();
        let (lo, hi) = levels
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(*v), b.max(*v)));
        let several_loads = levels.len() >= 2 && hi - lo > LOAD_LEVELS_APART * hi;
        Evaluator {
            spec,
            logs,
            y,
            max_torque,
            several_loads,
            cache: HashMap::new(),
        }
    }

    /// Total rows.
    pub fn rows(&self) -> usize {
        self.logs.iter().map(|l| l.t.len()).sum()
    }

    /// Nonlinear parameters with bounds and start values.
    pub fn nonlinear(&self) -> Vec<(NlParam, f64, f64, f64)> {
        let s = &self.spec;
        let id = &s.ident;
        let mut v = Vec::new();
        if s.fit_mu {
            let mu = s.drive.friction_coefficient;
            v.push((
                NlParam::Mu,
                id.friction_bounds[0],
                id.friction_bounds[1],
                mu,
            ));
        }
        if s.fit_pre {
            let p = s.drive.preload_n;
            v.push((
                NlParam::Preload,
                p * id.preload_factor_bounds[0],
                p * id.preload_factor_bounds[1],
                p,
            ));
        }
        let tmax = self.logs.iter().fold(1e-3f64, |a, l| a.max(l.duration));
        let cap = 2.0 * s.drive.preload_n * s.drive.drum_radius_m;
        for e in &s.effects {
            match e {
                // Either sign: a preload that rises through the record (a tensioner
                // still taking up, a frame that warms and stretches the cable) follows the
                // same law as one that relaxes, and a bound at zero never finds it.
                EffectName::PreloadRelaxation => {
                    v.push((NlParam::Effect(*e), -0.6 / tmax, 0.6 / tmax, 0.05 / tmax))
                }
                EffectName::BearingFriction => {
                    v.push((NlParam::Effect(*e), 0.0, 0.4 * cap, 0.02 * cap))
                }
                EffectName::CableTransport => v.push((NlParam::Effect(*e), 1e-4, 3.0, 0.05)),
                EffectName::DistributedFrictionMemory => {
                    use super::extra_effects as x;
                    // The weights grow as |M|^p beside the threshold law: a contact's
                    // friction, and so its share of the lag, grows with the tension
                    // pressing on it. On the eleven da Vinci logs the two together beat
                    // either alone held out on the lightest log (4.8 against 5.8 mrad
                    // with the law alone), and a drive whose lag grows with the load at
                    // fixed widths needs them.
                    let (lo, hi, start) = x::MEMORY_LOAD_EXPONENT;
                    v.push((NlParam::Effect(*e), lo, hi, start));
                    if self.several_loads {
                        // Scaled by the logs' own torques and stroke: a drive without load
                        // has no law to find (its bounds collapse to zero growth).
                        let m = self.max_torque.max(1e-9);
                        let (stroke, _) = self.stroke_and_thresholds();
                        let sl = x::SLACK_STROKE * (stroke.1 - stroke.0);
                        v.push((
                            NlParam::Memory(MemoryLaw::Growth),
                            0.0,
                            x::GROWTH_AT_MAX / m,
                            0.0,
                        ));
                        v.push((NlParam::Memory(MemoryLaw::Slack), 0.0, sl, 0.0));
                        v.push((
                            NlParam::Memory(MemoryLaw::TakenUp),
                            x::TAKEN_UP.0 * m,
                            x::TAKEN_UP.1 * m,
                            0.3 * m,
                        ));
                    }
                }
                _ => {}
            }
        }
        v
    }

    /// The value of `p` in `x`, laid out as `nl` (from [`Self::nonlinear`]).
    fn value(nl: &[(NlParam, f64, f64, f64)], x: &[f64], p: NlParam) -> Option<f64> {
        nl.iter()
            .position(|n| n.0 == p)
            .and_then(|i| x.get(i).copied())
    }

    /// Base error (with nonlinear effects) per log for nonlinear parameters `x`.
    fn base(&mut self, x: &[f64]) -> Result<Arc<Vec<Vec<f64>>>, IdentifyError> {
        let nl = self.nonlinear();
        let mut drive = self.spec.drive.clone();
        if let Some(mu) = Self::value(&nl, x, NlParam::Mu) {
            drive.friction_coefficient = mu;
        }
        if let Some(p) = Self::value(&nl, x, NlParam::Preload) {
            drive.preload_n = p;
        }
        let mb = Self::value(&nl, x, NlParam::Effect(EffectName::BearingFriction)).unwrap_or(0.0);
        let rel =
            Self::value(&nl, x, NlParam::Effect(EffectName::PreloadRelaxation)).unwrap_or(0.0);
        let tc = Self::value(&nl, x, NlParam::Effect(EffectName::CableTransport));
        let calibrated = self.spec.calibrated.as_ref();
        let key = [
            drive.friction_coefficient.to_bits(),
            drive.preload_n.to_bits(),
            mb.to_bits(),
            rel.to_bits(),
            // The transport filter comes before a calibrated instrument's effects, so its
            // prediction is cached per constant; the capstan replay is filtered after.
            calibrated.map_or(0, |_| tc.unwrap_or(0.0).to_bits()),
        ];
        if !self.cache.contains_key(&key) {
            let all = self
                .logs
                .iter()
                .map(|l| match calibrated {
                    Some(fx) => calibrated_prediction(&drive, fx, l, [mb, rel, tc.unwrap_or(0.0)]),
                    None => log_replay(&drive, l, mb, rel),
                })
                .collect::<Result<Vec<_>, _>>()?;
            if self.cache.len() > 64 {
                self.cache.clear();
            }
            self.cache.insert(key, Arc::new(all));
        }
        let cached = Arc::clone(&self.cache[&key]);
        Ok(match (tc, calibrated) {
            (Some(tc), None) => Arc::new(
                cached
                    .iter()
                    .zip(self.logs)
                    .map(|(e, l)| transport_filter(e, &l.travel, tc))
                    .collect(),
            ),
            _ => cached,
        })
    }

    /// Design for nonlinear parameters `x`.
    #[allow(clippy::needless_range_loop)]
    pub fn design(&mut self, x: &[f64]) -> Result<Design, IdentifyError> {
        let base = self.base(x)?;
        let n = self.rows();
        let nlogs = self.logs.len();
        let mut names: Vec<LinParam> = (0..nlogs).map(LinParam::Offset).collect();
        if self.spec.fit_g {
            names.push(LinParam::ModulusScale);
        }
        if self.spec.fit_ratio {
            names.push(LinParam::InverseRatio);
        }
        for e in &self.spec.effects {
            let k = match e {
                EffectName::InputPulleyRunout | EffectName::OutputDrumRunout => 2,
                EffectName::EncoderDelay
                | EffectName::EncoderScaleError
                | EffectName::ThermalDrift
                | EffectName::LoadCompliance => 1,
                EffectName::AngleDependentRatio => super::extra_effects::SHAPE_TERMS,
                EffectName::DistributedFrictionMemory => {
                    2 * super::extra_effects::MEMORY_THRESHOLDS + 1
                }
                _ => 0,
            };
            for j in 0..k {
                names.push(LinParam::Effect(*e, j));
            }
        }
        if self.spec.calibrated.is_some() {
            for e in &self.spec.ident.per_log {
                names.extend((0..nlogs).map(|k| LinParam::PerLog(*e, k)));
            }
        }
        let mut starts = vec![0];
        for l in self.logs {
            starts.push(starts[starts.len() - 1] + l.t.len());
        }
        let support: Vec<std::ops::Range<usize>> = names
            .iter()
            .map(|name| match name {
                LinParam::Offset(k) | LinParam::PerLog(_, k) => starts[*k]..starts[*k + 1],
                _ => 0..n,
            })
            .collect();
        let mut cols: Vec<Vec<f64>> = support
            .iter()
            .map(|s| Vec::with_capacity(s.len()))
            .collect();
        let mut fixed = Vec::with_capacity(n);
        let mut target = Vec::with_capacity(n);
        let (stroke, thresholds) = self.stroke_and_thresholds();
        let nl = self.nonlinear();
        let load_exponent = Self::value(
            &nl,
            x,
            NlParam::Effect(EffectName::DistributedFrictionMemory),
        )
        .unwrap_or(1.0);
        let law =
            |k: MemoryLaw, default: f64| Self::value(&nl, x, NlParam::Memory(k)).unwrap_or(default);
        let (growth, slack, taken_up) = (
            law(MemoryLaw::Growth, 0.0),
            law(MemoryLaw::Slack, 0.0),
            law(MemoryLaw::TakenUp, 1.0),
        );
        for (li, l) in self.logs.iter().enumerate() {
            // Columns of the extended effects, which need a whole log (memory) or the stroke.
            let shape = self
                .spec
                .effects
                .contains(&EffectName::AngleDependentRatio)
                .then(|| super::extra_effects::shape_columns(&l.th_in, stroke));
            let memory = self
                .spec
                .effects
                .contains(&EffectName::DistributedFrictionMemory)
                .then(|| {
                    use super::extra_effects as xe;
                    let mut c = xe::memory_law_columns(&l.th_in, &l.torque, &thresholds, growth);
                    // `|M|^p` once per row: the scaled columns share it.
                    let factor: Vec<f64> = l
                        .torque
                        .iter()
                        .map(|m| m.abs().powf(load_exponent))
                        .collect();
                    let scaled: Vec<Vec<f64>> = c
                        .iter()
                        .map(|col| col.iter().zip(&factor).map(|(v, f)| v * f).collect())
                        .collect();
                    c.extend(scaled);
                    c.push(xe::slack_column(&l.th_in, &l.torque, slack, taken_up));
                    c
                });
            let nl = l.t.len();
            for (b, y) in base[li][..nl]
                .iter()
                .zip(&self.y[starts[li]..starts[li + 1]])
            {
                let f = if self.spec.fit_g { 0.0 } else { *b };
                fixed.push(f);
                target.push(y - f);
            }
            // Column by column: each is a copy, a constant or one expression over the log.
            let zeros = |c: &mut Vec<f64>| c.resize(c.len() + nl, 0.0);
            for (c, name) in cols.iter_mut().zip(&names) {
                match name {
                    LinParam::Offset(k) => {
                        if *k == li {
                            c.resize(nl, 1.0);
                        }
                    }
                    LinParam::ModulusScale => c.extend_from_slice(&base[li][..nl]),
                    LinParam::InverseRatio => c.extend_from_slice(&l.th_in[..nl]),
                    LinParam::PerLog(e, k) => {
                        if *k == li {
                            c.extend((0..nl).map(|i| single_column(*e, l, i)));
                        }
                    }
                    LinParam::Effect(e, j) => match (e, j) {
                        (EffectName::InputPulleyRunout, 0) => {
                            c.extend(l.th_in[..nl].iter().map(|v| v.sin()))
                        }
                        (EffectName::InputPulleyRunout, _) => {
                            c.extend(l.th_in[..nl].iter().map(|v| v.cos()))
                        }
                        (EffectName::OutputDrumRunout, 0) => {
                            c.extend(l.th_out[..nl].iter().map(|v| v.sin()))
                        }
                        (EffectName::OutputDrumRunout, _) => {
                            c.extend(l.th_out[..nl].iter().map(|v| v.cos()))
                        }
                        (
                            EffectName::EncoderDelay
                            | EffectName::EncoderScaleError
                            | EffectName::ThermalDrift
                            | EffectName::LoadCompliance,
                            _,
                        ) => c.extend((0..nl).map(|i| single_column(*e, l, i))),
                        (EffectName::AngleDependentRatio, j) => match &shape {
                            Some(s) => c.extend_from_slice(&s[*j][..nl]),
                            None => zeros(c),
                        },
                        (EffectName::DistributedFrictionMemory, j) => match &memory {
                            Some(m) => c.extend_from_slice(&m[*j][..nl]),
                            None => zeros(c),
                        },
                        _ => zeros(c),
                    },
                }
            }
        }
        let max_load_factor = self
            .logs
            .iter()
            .flat_map(|l| l.torque.iter())
            .fold(0.0_f64, |m, t| m.max(t.abs()))
            .powf(load_exponent);
        Ok(Design {
            target,
            fixed,
            cols,
            support,
            names,
            max_load_factor,
        })
    }

    /// Input stroke over all logs (rad) and the friction-memory thresholds (rad of input)
    /// defined on it; shared by every log so the shape and weights are one instrument's.
    pub fn stroke_and_thresholds(
        &self,
    ) -> ((f64, f64), [f64; super::extra_effects::MEMORY_THRESHOLDS]) {
        let stroke = super::extra_effects::stroke(self.logs.iter().map(|l| l.th_in.as_slice()));
        let r = super::extra_effects::memory_thresholds_rad(stroke.1 - stroke.0);
        (stroke, r)
    }

    /// Bounds of the linear coefficients that have physical limits.
    fn lin_bounds(&self, name: LinParam, d: &Design) -> Option<(f64, f64)> {
        let id = &self.spec.ident;
        match name {
            // Compliance of either sign: a link that gives way with the load adds to the
            // spans' stretch (negative), a drive stiffer than the cable model takes from it.
            LinParam::Effect(EffectName::LoadCompliance, _) => Some((-100.0, 100.0)),
            // A contact's weight at most 10 rad/rad; a load-scaled one at the logs' largest
            // torque.
            LinParam::Effect(EffectName::DistributedFrictionMemory, j)
                if (super::extra_effects::MEMORY_THRESHOLDS
                    ..2 * super::extra_effects::MEMORY_THRESHOLDS)
                    .contains(&j) =>
            {
                Some((0.0, 10.0 / d.max_load_factor.max(1e-12)))
            }
            LinParam::Effect(EffectName::DistributedFrictionMemory, _) => Some((0.0, 10.0)),
            LinParam::ModulusScale => Some((
                1.0 / id.modulus_factor_bounds[1],
                1.0 / id.modulus_factor_bounds[0],
            )),
            LinParam::InverseRatio => {
                let ic = self.spec.drive.ratio();
                Some((
                    1.0 / (ic * id.ratio_factor_bounds[1]) - 1.0 / ic,
                    1.0 / (ic * id.ratio_factor_bounds[0]) - 1.0 / ic,
                ))
            }
            _ => None,
        }
    }

    /// Linear coefficients on rows `mask` (bounded ones clamped and the rest refitted).
    /// The normal equations are formed once; each pass that pins a coefficient on its
    /// bound solves the free ones' block with the pinned ones moved to the right-hand
    /// side, which is what refitting the columns would give, at a fraction of the work.
    pub fn solve_linear(&self, d: &Design, mask: &[bool]) -> Option<Vec<f64>> {
        let p = d.names.len();
        let (ata, aty) = normal_equations(d, mask)?;
        let mut pinned: Vec<Option<f64>> = vec![None; p];
        // Each pass pins at least one more coefficient on its bound, so this ends.
        for _ in 0..3 + p {
            let free: Vec<usize> = (0..p).filter(|j| pinned[*j].is_none()).collect();
            let mut coef = vec![0.0; p];
            for (j, v) in pinned.iter().enumerate() {
                if let Some(v) = v {
                    coef[j] = *v;
                }
            }
            if !free.is_empty() {
                let nf = free.len();
                let mut g = DMatrix::<f64>::zeros(nf, nf);
                let mut h = nalgebra::DVector::<f64>::zeros(nf);
                for (a, ja) in free.iter().enumerate() {
                    h[a] = aty[*ja]
                        - pinned
                            .iter()
                            .enumerate()
                            .filter_map(|(k, v)| v.map(|v| ata[(*ja, k)] * v))
                            .sum::<f64>();
                    for (b, jb) in free.iter().enumerate() {
                        g[(a, b)] = ata[(*ja, *jb)];
                    }
                }
                // Equilibrated pseudo-inverse, as `linear_lsq`: collinear columns get the
                // minimum-norm answer.
                let sc: Vec<f64> = (0..nf)
                    .map(|a| {
                        let v = g[(a, a)];
                        if v > 0.0 {
                            1.0 / v.sqrt()
                        } else {
                            0.0
                        }
                    })
                    .collect();
                for a in 0..nf {
                    for b in 0..nf {
                        g[(a, b)] *= sc[a] * sc[b];
                    }
                    h[a] *= sc[a];
                }
                let svd = g.svd(true, true);
                let smax = svd.singular_values.max();
                if !smax.is_finite() {
                    return None;
                }
                let sol = svd.pseudo_inverse(smax * 1e-10).ok()? * h;
                for (a, j) in free.iter().enumerate() {
                    coef[*j] = sol[a] * sc[a];
                }
            }
            if coef.iter().any(|c| !c.is_finite()) {
                return None;
            }
            let mut again = false;
            for j in free {
                if let Some((lo, hi)) = self.lin_bounds(d.names[j], d) {
                    if coef[j] < lo || coef[j] > hi {
                        pinned[j] = Some(coef[j].clamp(lo, hi));
                        again = true;
                    }
                }
            }
            if !again {
                return Some(coef);
            }
        }
        None
    }

    /// Prediction of the measured error (relative to the reference ratio), stacked.
    pub fn predict(d: &Design, coef: &[f64]) -> Vec<f64> {
        let rows: Vec<usize> = (0..d.fixed.len()).collect();
        Self::predict_rows(d, coef, &rows)
    }

    /// The prediction on `rows` (ascending), each row summed over the columns in order,
    /// a column adding its product with zero off its support as a whole column would (so a
    /// prediction of -0 becomes +0 the same way).
    fn predict_rows(d: &Design, coef: &[f64], rows: &[usize]) -> Vec<f64> {
        let mut p: Vec<f64> = rows.iter().map(|i| d.fixed[*i]).collect();
        for ((c, s), v) in d.cols.iter().zip(&d.support).zip(coef) {
            let z = v * 0.0;
            let (lo, hi) = support_positions(rows, s);
            for pk in &mut p[..lo] {
                *pk += z;
            }
            for (pk, i) in p[lo..hi].iter_mut().zip(&rows[lo..hi]) {
                *pk += v * c[*i - s.start];
            }
            for pk in &mut p[hi..] {
                *pk += z;
            }
        }
        p
    }

    /// Stacked measured error relative to the reference ratio.
    pub fn measured(&self) -> Vec<f64> {
        self.y.clone()
    }

    /// Measured minus predicted on the rows of `mask`, in row order; each row's prediction
    /// summed as [`Self::predict`] sums it.
    fn masked_residual(d: &Design, coef: &[f64], y: &[f64], mask: &[bool]) -> Vec<f64> {
        let rows: Vec<usize> = (0..d.fixed.len()).filter(|i| mask[*i]).collect();
        let p = Self::predict_rows(d, coef, &rows);
        rows.iter().zip(&p).map(|(i, pk)| y[*i] - pk).collect()
    }

    /// The least raise of the spec's drive, its preload (the friction coefficient's, when
    /// the preload is not fitted) in steps of [`CARRY_STEP`] up to [`CARRY_MAX`] times its
    /// value and within its bounds, at which the replay carries every log, as a start in
    /// the nonlinear layout; `None` when none does or neither is fitted.
    pub fn carrying_start(&mut self) -> Option<Vec<f64>> {
        let nl = self.nonlinear();
        let raised = [NlParam::Preload, NlParam::Mu]
            .into_iter()
            .find(|p| nl.iter().any(|n| n.0 == *p))?;
        let mut f = CARRY_STEP;
        while f <= CARRY_MAX {
            let x: Vec<f64> = nl
                .iter()
                .map(|n| {
                    if n.0 == raised {
                        (n.3 * f).min(n.2)
                    } else {
                        n.3
                    }
                })
                .collect();
            if self.design(&x).is_ok() {
                return Some(x);
            }
            f *= CARRY_STEP;
        }
        None
    }

    /// Fit on rows `mask`, starting from `x0` (nonlinear layout), at most `iters` LM steps.
    /// Without `x0` the fit starts from the spec's drive, or, when that drive cannot carry
    /// the logs (a calibration that left its friction and preload where its own heaviest
    /// log only just holds), from [`Self::carrying_start`].
    pub fn fit(
        &mut self,
        mask: &[bool],
        x0: Option<&[f64]>,
        iters: usize,
    ) -> Result<Fitted, IdentifyError> {
        let nl = self.nonlinear();
        let lo: Vec<f64> = nl.iter().map(|n| n.1).collect();
        let hi: Vec<f64> = nl.iter().map(|n| n.2).collect();
        let mut start: Vec<f64> = match x0 {
            Some(x) if x.len() == nl.len() => x.to_vec(),
            _ => {
                let own: Vec<f64> = nl.iter().map(|n| n.3).collect();
                match self.design(&own) {
                    Ok(_) => own,
                    Err(e) => self.carrying_start().ok_or(e)?,
                }
            }
        };
        let n_fit = mask.iter().filter(|m| **m).count();
        let resid = |x: &[f64], me: &mut Self| -> Option<Vec<f64>> {
            let d = me.design(x).ok()?;
            let coef = me.solve_linear(&d, mask)?;
            Some(Self::masked_residual(&d, &coef, &me.y, mask))
        };
        // Coarse scan of a single effect parameter first: their costs are often multimodal
        // (transport length, friction torque hidden behind a stiffer cable).
        let (law_points, passes) = LAW_SCAN;
        let scan: Vec<(usize, usize)> = (0..passes)
            .flat_map(|pass| {
                nl.iter()
                    .enumerate()
                    .filter(move |(_, n)| match n.0 {
                        NlParam::Effect(_) => pass == 0,
                        NlParam::Memory(_) => true,
                        _ => false,
                    })
                    .map(move |(k, _)| (pass, k))
            })
            .collect();
        let cost_at = |x: &[f64], me: &mut Self| -> Option<f64> {
            resid(x, me).map(|r| r.iter().map(|e| e * e).sum())
        };
        // One parameter over its range with the others held; returns the cost at the best
        // point (infinite when no point could be evaluated).
        let scan_one = |k: usize, start: &mut Vec<f64>, me: &mut Self| -> f64 {
            let n = &nl[k];
            let mut best = (f64::INFINITY, start[k]);
            let ns = if let NlParam::Memory(_) = n.0 {
                law_points
            } else {
                7
            };
            // A parameter of either sign is scanned out to each bound from zero alike, so
            // the scan does not decide its sign before the fit does.
            let sides = if n.1 < 0.0 { 2 } else { 1 };
            for g in 0..sides * ns {
                let (side, g) = (g / ns, g % ns);
                if side == 1 && g == 0 {
                    continue;
                }
                let f = g as f64 / (ns - 1) as f64;
                let v = if n.1 > 0.0 {
                    n.1 * (n.2 / n.1).powf(f)
                } else if side == 1 {
                    n.1 * f * f
                } else {
                    n.2 * f * f
                };
                let mut xs = start.clone();
                xs[k] = v;
                if let Some(c) = cost_at(&xs, me).filter(|c| *c < best.0) {
                    best = (c, v);
                }
            }
            start[k] = best.1;
            best.0
        };
        if x0.is_none() {
            let mut cost = f64::INFINITY;
            for (_, k) in scan {
                cost = scan_one(k, &mut start, self);
            }
            // The slack does nothing while the torque that takes it up lies below every
            // log's load, and that torque nothing while the slack is zero: scanned one at
            // a time from such a corner they stay in it, where the cost is flat. A coarse
            // grid of the pair is kept only when it beats the scan, then refined one
            // parameter at a time again.
            let at = |p: MemoryLaw| nl.iter().position(|n| n.0 == NlParam::Memory(p));
            if let (Some(ks), Some(ku)) = (at(MemoryLaw::Slack), at(MemoryLaw::TakenUp)) {
                let mut best = (cost, start[ks], start[ku]);
                for i in 1..=LAW_GRID {
                    for j in 0..=LAW_GRID {
                        let mut xs = start.clone();
                        xs[ks] = nl[ks].2 * (i as f64 / LAW_GRID as f64).powi(2);
                        xs[ku] = nl[ku].1 * (nl[ku].2 / nl[ku].1).powf(j as f64 / LAW_GRID as f64);
                        if let Some(c) = cost_at(&xs, self).filter(|c| *c < best.0) {
                            best = (c, xs[ks], xs[ku]);
                        }
                    }
                }
                if best.0 < cost {
                    (start[ks], start[ku]) = (best.1, best.2);
                    for (k, n) in nl.iter().enumerate() {
                        if let NlParam::Memory(_) = n.0 {
                            scan_one(k, &mut start, self);
                        }
                    }
                }
            }
        }
        // Surface why the start fails (slack, gross slip) instead of a bare fit error.
        self.design(&start)?;
        let (x, iterations, converged) = if nl.is_empty() {
            (Vec::new(), 0, true)
        } else {
            let lm = levenberg_marquardt(|x| resid(x, self), &start, &lo, &hi, iters)
                .map_err(|e| IdentifyError::Fit(e.to_string()))?;
            (lm.x, lm.iterations, lm.converged)
        };
        let d = self.design(&x)?;
        let coef = self
            .solve_linear(&d, mask)
            .ok_or_else(|| IdentifyError::Fit("linear least squares is singular".into()))?;
        let p = Self::predict(&d, &coef);
        let y = self.measured();
        let cost: f64 = (0..y.len())
            .filter(|i| mask[*i])
            .map(|i| (y[i] - p[i]).powi(2))
            .sum();
        if !cost.is_finite() || x.iter().any(|v| !v.is_finite()) {
            return Err(IdentifyError::Fit(
                "the fit diverged (non-finite cost); check units of the logs".into(),
            ));
        }
        Ok(Fitted {
            x,
            coef,
            lin: d.names,
            cost,
            n_fit,
            iterations,
            converged,
        })
    }

    /// Residual (measured minus predicted) on all rows for a fit; logs without any fitted
    /// row get their encoder zero from their own data (it is a nuisance, not a prediction).
    pub fn residual(
        &mut self,
        f: &Fitted,
        mask: &[bool],
    ) -> Result<(Vec<f64>, Vec<f64>), IdentifyError> {
        let d = self.design(&f.x)?;
        let mut p = Self::predict(&d, &f.coef);
        let y = self.measured();
        let mut start = 0;
        for l in self.logs {
            let r = start..start + l.t.len();
            if !mask[r.clone()].iter().any(|m| *m) {
                let off = r.clone().map(|i| y[i] - p[i]).sum::<f64>() / l.t.len() as f64;
                for i in r.clone() {
                    p[i] += off;
                }
            }
            start = r.end;
        }
        let res = y.iter().zip(&p).map(|(a, b)| a - b).collect();
        Ok((res, p))
    }

    /// Covariance of (nonlinear, linear) parameters at a fit: `s^2 (J^T J)^-1` with the
    /// nonlinear columns by finite differences at fixed linear coefficients.
    pub fn covariance(&mut self, f: &Fitted, mask: &[bool]) -> Result<DMatrix<f64>, IdentifyError> {
        Ok(self.identifiability(f, mask)?.cov)
    }

    /// [`Evaluator::covariance`] with the parameters the data cannot pin.
    pub fn identifiability(
        &mut self,
        f: &Fitted,
        mask: &[bool],
    ) -> Result<super::identifiability::Analysis, IdentifyError> {
        let (j, _, _, s2) = self.jacobian(f, mask)?;
        Ok(super::identifiability::analyse(&j, s2))
    }

    /// [`Evaluator::identifiability`] and, beside it, the covariance that holds when the
    /// residual comes in runs ([`super::identifiability::long_run`]), each stretch of a log's
    /// consecutive fitted rows its own series.
    pub fn identifiability_with_runs(
        &mut self,
        f: &Fitted,
        mask: &[bool],
    ) -> Result<
        (
            super::identifiability::Analysis,
            Option<super::identifiability::Runs>,
        ),
        IdentifyError,
    > {
        let (j, rows, p0, s2) = self.jacobian(f, mask)?;
        let y = self.measured();
        let resid: Vec<f64> = rows.iter().map(|i| y[*i] - p0[*i]).collect();
        let log_ends: Vec<usize> = self
            .logs
            .iter()
            .scan(0, |end, l| {
                *end += l.t.len();
                Some(*end)
            })
            .collect();
        let nr = j.nrows() as f64;
        let dof_scale = nr / (nr - j.ncols() as f64).max(1.0);
        let runs =
            super::identifiability::long_run(&j, &resid, &stretches(&rows, &log_ends), dof_scale)
                .map(|mut r| {
                    let mut start = 0;
                    let per_log: Vec<std::ops::Range<usize>> = log_ends
                        .iter()
                        .map(|end| {
                            let stop = rows.partition_point(|i| i < end);
                            let range = start..stop;
                            start = stop;
                            range
                        })
                        .collect();
                    r.between_logs =
                        super::identifiability::between_logs(&j, &resid, &per_log, dof_scale);
                    if r.between_logs.is_some() {
                        r.logs = per_log.iter().filter(|g| !g.is_empty()).count();
                    }
                    r
                });
        Ok((super::identifiability::analyse(&j, s2), runs))
    }

    /// The Jacobian of the fit's prediction on the rows of `mask` (nonlinear columns by
    /// finite differences at fixed linear coefficients, then the linear ones), those rows'
    /// indices, the prediction on every row, and the residual's variance per degree of
    /// freedom.
    fn jacobian(&mut self, f: &Fitted, mask: &[bool]) -> Result<Jacobian, IdentifyError> {
        let nl = self.nonlinear();
        let d0 = self.design(&f.x)?;
        let p0 = Self::predict(&d0, &f.coef);
        let rows: Vec<usize> = (0..p0.len()).filter(|i| mask[*i]).collect();
        let np = nl.len() + f.coef.len();
        let mut j = DMatrix::<f64>::zeros(rows.len(), np);
        for (k, n) in nl.iter().enumerate() {
            let mut h = 1e-4 * (n.2 - n.1);
            if f.x[k] + h > n.2 {
                h = -h;
            }
            let mut x = f.x.clone();
            x[k] += h;
            let d = match self.design(&x) {
                Ok(d) => d,
                Err(_) => {
                    h = -h;
                    x[k] = f.x[k] + h;
                    self.design(&x)?
                }
            };
            let p = Self::predict(&d, &f.coef);
            for (r, i) in rows.iter().enumerate() {
                j[(r, k)] = (p[*i] - p0[*i]) / h;
            }
        }
        for (c, (col, s)) in d0.cols.iter().zip(&d0.support).enumerate() {
            let (lo, hi) = support_positions(&rows, s);
            for (r, i) in rows.iter().enumerate().take(hi).skip(lo) {
                j[(r, nl.len() + c)] = col[*i - s.start];
            }
        }
        let dof = (rows.len() as f64 - np as f64).max(1.0);
        let s2 = f.cost / dof;
        Ok((j, rows, p0, s2))
    }
}

/// The positions in `rows` (ascending row indices) of the rows inside `s`, as a range
/// `lo..hi`.
fn support_positions(rows: &[usize], s: &std::ops::Range<usize>) -> (usize, usize) {
    (
        rows.partition_point(|i| *i < s.start),
        rows.partition_point(|i| *i < s.end),
    )
}

/// Rows per block of [`normal_equations`]: a block's rows, gathered row by row, stay in
/// the first-level cache beside the block's accumulators.
const NORMAL_BLOCK: usize = 256;

/// `A'A` (upper triangle mirrored) and `A'y` of the design's columns and target on the
/// rows of `mask`; `None` when a fitted row holds a value that is not finite or the sums
/// overflow.
///
/// Each entry is the sum of its products in row order, as a plain loop over the rows
/// forms it; a block of rows only gathers the columns that cover it and are not all zero
/// on it (an encoder zero's column covers its own log), since a zero product leaves a
/// running sum that started at +0 unchanged.
fn normal_equations(d: &Design, mask: &[bool]) -> Option<(DMatrix<f64>, Vec<f64>)> {
    let p = d.names.len();
    let n = d.target.len();
    let mut ata = DMatrix::<f64>::zeros(p, p);
    let mut aty = vec![0.0; p];
    let mut active = Vec::with_capacity(p);
    let mut rows = Vec::with_capacity(NORMAL_BLOCK);
    let mut buf = vec![0.0; NORMAL_BLOCK * p];
    let mut acc = vec![0.0; p * p];
    let mut acc_y = vec![0.0; p];
    let mut ys = Vec::with_capacity(NORMAL_BLOCK);
    // Blocks end where a column's rows begin or end, so each column covers a block whole
    // or not at all.
    let mut edges: Vec<usize> = d.support.iter().flat_map(|s| [s.start, s.end]).collect();
    edges.push(n);
    edges.sort_unstable();
    edges.dedup();
    let mut start = 0;
    while start < n {
        let edge = edges[edges.partition_point(|e| *e <= start)];
        let end = (start + NORMAL_BLOCK).min(edge);
        rows.clear();
        rows.extend((start..end).filter(|i| mask[*i]));
        if !rows.iter().all(|i| d.target[*i].is_finite()) {
            return None;
        }
        active.clear();
        active.extend((0..p).filter(|j| {
            let s = &d.support[*j];
            s.start <= start && end <= s.end && rows.iter().any(|i| d.cols[*j][*i - s.start] != 0.0)
        }));
        let m = active.len();
        // A block without fitted rows has no active column.
        if m > 0 {
            for (k, j) in active.iter().enumerate() {
                let (c, s0) = (&d.cols[*j], d.support[*j].start);
                for (t, i) in rows.iter().enumerate() {
                    buf[t * m + k] = c[*i - s0];
                }
            }
            for (a, ja) in active.iter().enumerate() {
                acc_y[a] = aty[*ja];
                for (b, jb) in active.iter().enumerate().skip(a) {
                    acc[a * m + b] = ata[(*ja, *jb)];
                }
            }
            ys.clear();
            ys.extend(rows.iter().map(|i| d.target[*i]));
            accumulate(&buf[..rows.len() * m], &ys, m, &mut acc, &mut acc_y);
            for (a, ja) in active.iter().enumerate() {
                aty[*ja] = acc_y[a];
                for (b, jb) in active.iter().enumerate().skip(a) {
                    ata[(*ja, *jb)] = acc[a * m + b];
                }
            }
        }
        start = end;
    }
    // A value that is not finite (or sums that overflow) leaves its own square's sum, on
    // the diagonal, not finite.
    if !(0..p).all(|a| ata[(a, a)].is_finite() && aty[a].is_finite()) {
        return None;
    }
    for a in 0..p {
        for b in 0..a {
            ata[(a, b)] = ata[(b, a)];
        }
    }
    Some((ata, aty))
}

/// Adds the rows of `buf` (row-major, `m` wide, one per entry of `ys`) to the upper
/// triangle `acc` (row-major, `m` by `m`) and their products with `ys` to `acc_y`, each
/// sum in row order. Two rows at a time: each entry gets the first row's product and then
/// the second's, as two passes would add them, with one load and store of the entry.
fn accumulate(buf: &[f64], ys: &[f64], m: usize, acc: &mut [f64], acc_y: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the processor has AVX (checked just above), all the function assumes.
        unsafe { accumulate_avx(buf, ys, m, acc, acc_y) };
        return;
    }
    accumulate_rows(buf, ys, m, acc, acc_y);
}

/// [`accumulate_rows`] compiled for AVX: four lanes where the baseline has two, each lane
/// the same multiply and add (no fused multiply-add), so the sums are the same bits.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn accumulate_avx(buf: &[f64], ys: &[f64], m: usize, acc: &mut [f64], acc_y: &mut [f64]) {
    accumulate_rows(buf, ys, m, acc, acc_y);
}

#[inline(always)]
fn accumulate_rows(buf: &[f64], ys: &[f64], m: usize, acc: &mut [f64], acc_y: &mut [f64]) {
    let mut pairs = buf.chunks_exact(2 * m).zip(ys.chunks_exact(2));
    for (r, y) in &mut pairs {
        let (r1, r2) = r.split_at(m);
        for a in 0..m {
            let (p, q) = (r1[a], r2[a]);
            acc_y[a] = acc_y[a] + p * y[0] + q * y[1];
            let row = &mut acc[a * m + a..(a + 1) * m];
            for ((s, v1), v2) in row.iter_mut().zip(&r1[a..]).zip(&r2[a..]) {
                *s = *s + p * v1 + q * v2;
            }
        }
    }
    if ys.len() % 2 == 1 {
        let t = ys.len() - 1;
        let (r, y) = (&buf[t * m..(t + 1) * m], ys[t]);
        for a in 0..m {
            let p = r[a];
            acc_y[a] += p * y;
            for (s, v) in acc[a * m + a..(a + 1) * m].iter_mut().zip(&r[a..]) {
                *s += p * v;
            }
        }
    }
}

/// [`Evaluator`]'s Jacobian on the fitted rows, those rows' indices, the prediction on
/// every row, and the residual's variance per degree of freedom.
type Jacobian = (DMatrix<f64>, Vec<usize>, Vec<f64>, f64);

/// Stretches of consecutive fitted rows, as ranges of positions in `rows` (the fitted
/// rows' indices over the stacked logs, ascending): a gap in the indices (a start cut or
/// an excluded segment) or the end of a log (`log_ends`, each log's end index) closes one,
/// so no batch of the runs covariance joins data not recorded together.
fn stretches(rows: &[usize], log_ends: &[usize]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for k in 1..=rows.len() {
        let closes = k == rows.len() || rows[k] != rows[k - 1] + 1 || log_ends.contains(&rows[k]);
        if closes {
            out.push(start..k);
            start = k;
        }
    }
    out
}

#[cfg(test)]
mod stretch_tests {
    #[test]
    fn a_gap_or_a_logs_end_closes_a_stretch() {
        // Two logs of 6 rows; rows 2 and 3 of the first excluded, the second whole.
        let rows = [0, 1, 4, 5, 6, 7, 8, 9, 10, 11];
        assert_eq!(super::stretches(&rows, &[6, 12]), vec![0..2, 2..4, 4..10]);
        assert!(super::stretches(&[], &[6]).is_empty());
    }
}

#[cfg(test)]
mod bound_tests {
    use super::*;

    #[test]
    fn parameters_on_a_bound_are_named_and_interior_ones_are_not() {
        let nl = [
            (NlParam::Mu, 0.02, 0.5, 0.1),
            (NlParam::Preload, 10.0, 1000.0, 100.0),
            (
                NlParam::Effect(EffectName::DistributedFrictionMemory),
                0.5,
                8.0,
                1.0,
            ),
        ];
        let said = on_bounds(&nl, &[0.02, 123.0, 8.0]);
        assert_eq!(said.len(), 2, "{said:?}");
        assert!(said[0].starts_with("friction_coefficient = 0.02 is on its lower bound"));
        assert!(said[1].starts_with("friction_memory_load_exponent = 8 is on its upper bound"));
        assert!(on_bounds(&nl, &[0.1, 123.0, 2.5]).is_empty());
    }

    /// A transport on its least travel and a bearing friction of zero are none of either;
    /// a millionth of the range above the bound, or the upper bound, is a size; a linear
    /// effect is never held at a bound.
    #[test]
    fn an_effect_on_the_bound_that_means_none_is_told() {
        let transport = NlParam::Effect(EffectName::CableTransport);
        let friction = NlParam::Effect(EffectName::BearingFriction);
        let nl = [
            (NlParam::Preload, 10.0, 1000.0, 100.0),
            (transport, 1e-4, 3.0, 0.05),
            (friction, 0.0, 8.0, 0.4),
        ];
        let e = EffectName::CableTransport;
        assert_eq!(at_none_bound(&nl, &[10.0, 1e-4, 1.0], e), Some(1e-4));
        assert_eq!(at_none_bound(&nl, &[10.0, 1e-4 + 2e-6, 1.0], e), Some(1e-4));
        assert_eq!(at_none_bound(&nl, &[10.0, 1e-4 + 4e-6, 1.0], e), None);
        assert_eq!(at_none_bound(&nl, &[10.0, 3.0, 1.0], e), None);
        let f = EffectName::BearingFriction;
        assert_eq!(at_none_bound(&nl, &[10.0, 0.5, 0.0], f), Some(0.0));
        assert_eq!(at_none_bound(&nl, &[10.0, 0.5, 1e-3], f), None);
        // Not in the fit, or sized by a linear column: nothing to tell.
        assert_eq!(
            at_none_bound(&nl, &[10.0, 0.5, 0.0], EffectName::PreloadRelaxation),
            None
        );
        // Fitted with either sign: its lower bound is the fastest rise, not none.
        let relax = NlParam::Effect(EffectName::PreloadRelaxation);
        let signed = [
            (NlParam::Preload, 10.0, 1000.0, 100.0),
            (relax, -0.02, 0.02, 0.0),
        ];
        for v in [-0.02, 0.0, 0.02] {
            assert_eq!(
                at_none_bound(&signed, &[10.0, v], EffectName::PreloadRelaxation),
                None,
                "{v}"
            );
        }
        assert_eq!(
            at_none_bound(&nl, &[10.0, 0.5, 0.0], EffectName::LoadCompliance),
            None
        );
    }
}

#[cfg(test)]
mod row_tests {
    use super::*;

    /// A brake's load flipping between samples 12 and 13: with rows of four samples only
    /// the row holding both sides straddles the step; a ramp through the same range over
    /// the log does not, nor does anything on single-sample rows.
    #[test]
    fn only_the_row_across_a_load_step_straddles_it() {
        let step: Vec<f64> = (0..40)
            .map(|i| if i <= 12 { 0.7 } else { -0.7 } + 0.01 * (i as f64 * 0.7).sin())
            .collect();
        let rows = straddles_a_step(&step, 4);
        assert_eq!(rows.len(), 10);
        let marked: Vec<usize> = (0..10).filter(|i| rows[*i]).collect();
        assert_eq!(marked, vec![3]);
        assert!(straddles_a_step(&step, 1).iter().all(|s| !s));
        let ramp: Vec<f64> = (0..40).map(|i| 0.7 - 1.4 * i as f64 / 39.0).collect();
        assert!(straddles_a_step(&ramp, 4).iter().all(|s| !s));
        assert!(straddles_a_step(&[0.3; 40], 4).iter().all(|s| !s));
    }

    /// A sine's speed at 100 rows/s, reversing 1.5 ms before a row: the direction flips
    /// on that row, the first of each new sign, though the speed there is still under the
    /// threshold (0.2 % of its peak) and passes it a row later. With a
    /// jump of the reading (a held input catching up) at rows 1000 to 1005, the threshold
    /// from the rows kept flips there too; one scaled on a jump faster than the motion's
    /// peak speed never flips at all.
    #[test]
    fn flips_land_on_the_reversals_and_a_jump_left_out_does_not_hide_them() {
        let v: Vec<f64> = (0..3000)
            .map(|i| {
                let t = i as f64 * 0.01;
                0.2 * (std::f64::consts::TAU * 0.1 * (t + 0.0015)).cos()
            })
            .collect();
        let crossings: Vec<usize> = (1..3000)
            .filter(|&i| v[i].signum() != v[i - 1].signum())
            .collect();
        assert_eq!(crossings.len(), 6);
        let floor = 1e-6;
        let flips = |d: &[f64]| -> Vec<usize> {
            (1..d.len())
                .filter(|&i| d[i] != d[i - 1] && !(995..1010).contains(&i))
                .collect()
        };
        let clean = direction(&v, None, floor, None);
        assert_eq!(flips(&clean), crossings);
        // Confirmed a row after each crossing, where the threshold alone would flip.
        let thr = 0.002 * 0.2;
        assert!(crossings
            .iter()
            .all(|&i| v[i].abs() <= thr && v[i + 1].abs() > thr));

        let keep: Vec<bool> = (0..3000).map(|i| !(995..1010).contains(&i)).collect();
        for (jump, flips_unkept) in [(-40.0, 6), (-200.0, 0)] {
            let mut jumped = v.clone();
            for x in &mut jumped[1000..1006] {
                *x = jump;
            }
            let kept = direction(&jumped, Some(&keep), floor, None);
            assert_eq!(flips(&kept), crossings, "jump {jump}");
            let unkept = direction(&jumped, None, floor, None);
            assert_eq!(flips(&unkept).len(), flips_unkept, "jump {jump}");
        }
        assert_eq!(direction(&v, Some(&[true; 3000]), floor, None), clean);
    }
}

#[cfg(test)]
mod normal_equation_tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A design of `logs` logs: per-log zero columns over their own rows, dense columns with
    /// runs of exact zeros (a memory column below its thresholds), values over six decades.
    fn design(rng: &mut rand_chacha::ChaCha8Rng, logs: &[usize], dense: usize) -> Design {
        let n: usize = logs.iter().sum();
        let mut names = Vec::new();
        let mut support = Vec::new();
        let mut cols = Vec::new();
        let mut start = 0;
        for (k, len) in logs.iter().enumerate() {
            names.push(LinParam::Offset(k));
            support.push(start..start + len);
            cols.push(vec![1.0; *len]);
            start += len;
        }
        for j in 0..dense {
            names.push(LinParam::Effect(EffectName::DistributedFrictionMemory, j));
            support.push(0..n);
            let scale = 10f64.powi(rng.gen_range(-4..3));
            cols.push(
                (0..n)
                    .map(|i| {
                        if (i / 37 + j) % 5 == 0 {
                            0.0
                        } else {
                            scale * rng.gen_range(-1.0..1.0)
                        }
                    })
                    .collect(),
            );
        }
        let fixed: Vec<f64> = (0..n).map(|_| rng.gen_range(-1e-3..1e-3)).collect();
        let target = (0..n).map(|_| rng.gen_range(-1e-2..1e-2)).collect();
        Design {
            target,
            fixed,
            cols,
            support,
            names,
            max_load_factor: 1.0,
        }
    }

    /// Column `j` over every row, zeros off its support.
    fn full(d: &Design, j: usize) -> Vec<f64> {
        let s = &d.support[j];
        (0..d.target.len())
            .map(|i| {
                if s.contains(&i) {
                    d.cols[j][i - s.start]
                } else {
                    0.0
                }
            })
            .collect()
    }

    #[test]
    fn the_blocked_sums_are_the_plain_loops_bit_for_bit() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for case in 0..40 {
            let logs: Vec<usize> = (0..rng.gen_range(1..5))
                .map(|_| rng.gen_range(1..700))
                .collect();
            let dense = rng.gen_range(0..9);
            let d = design(&mut rng, &logs, dense);
            let n = d.target.len();
            let p = d.names.len();
            let mask: Vec<bool> = (0..n)
                .map(|i| case % 3 == 0 || rng.gen_bool(0.8) || i == 0)
                .collect();
            let cols: Vec<Vec<f64>> = (0..p).map(|j| full(&d, j)).collect();
            // The plain loop over the rows, every column whole.
            let mut ata = DMatrix::<f64>::zeros(p, p);
            let mut aty = vec![0.0; p];
            for i in (0..n).filter(|i| mask[*i]) {
                for a in 0..p {
                    aty[a] += cols[a][i] * d.target[i];
                    for b in a..p {
                        ata[(a, b)] += cols[a][i] * cols[b][i];
                    }
                }
            }
            for a in 0..p {
                for b in 0..a {
                    ata[(a, b)] = ata[(b, a)];
                }
            }
            let (got, got_y) = normal_equations(&d, &mask).expect("finite design");
            for a in 0..p {
                assert_eq!(
                    got_y[a].to_bits(),
                    aty[a].to_bits(),
                    "case {case}: A'y[{a}]"
                );
                for b in 0..p {
                    assert_eq!(
                        got[(a, b)].to_bits(),
                        ata[(a, b)].to_bits(),
                        "case {case}: A'A[{a},{b}]"
                    );
                }
            }
            // The prediction with every column whole.
            let coef: Vec<f64> = (0..p).map(|_| rng.gen_range(-2.0..2.0)).collect();
            let mut want = d.fixed.clone();
            for (c, v) in cols.iter().zip(&coef) {
                for (w, ci) in want.iter_mut().zip(c) {
                    *w += v * ci;
                }
            }
            let got = Evaluator::predict(&d, &coef);
            assert!(
                got.iter()
                    .zip(&want)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "case {case}: prediction"
            );
            // The fit's residual on the fitted rows, from that prediction.
            let y: Vec<f64> = (0..n).map(|_| rng.gen_range(-1e-2..1e-2)).collect();
            let want: Vec<f64> = (0..n)
                .filter(|i| mask[*i])
                .map(|i| y[i] - want[i])
                .collect();
            let got = Evaluator::masked_residual(&d, &coef, &y, &mask);
            assert!(
                got.iter()
                    .zip(&want)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "case {case}: residual"
            );
            assert_eq!(got.len(), want.len());
        }
    }

    #[test]
    fn a_value_that_is_not_finite_gives_no_normal_equations() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut d = design(&mut rng, &[300, 200], 4);
            let mask = vec![true; 500];
            assert!(normal_equations(&d, &mask).is_some());
            d.cols[3][123] = bad;
            assert!(normal_equations(&d, &mask).is_none(), "{bad} in a column");
            // Off the fitted rows it does not count.
            let mut off = mask.clone();
            off[123] = false;
            assert!(
                normal_equations(&d, &off).is_some(),
                "{bad} on a row not fitted"
            );
            d.cols[3][123] = 0.5;
            d.target[7] = bad;
            assert!(normal_equations(&d, &mask).is_none(), "{bad} in the target");
        }
    }
}
