//! Frequency response of the nonlinear sampled loop by sinusoidal injection (sinestream).
//!
//! Linearising at a backlash or a Coulomb friction gives zero or undefined gain, so the
//! response is measured as a bench would: a sinusoid of one frequency and amplitude is
//! injected at a loop point of the full simulation (hysteretic cable, brake, encoders,
//! computation delay), the loop is left to settle, and whole periods are correlated at the
//! injected frequency. The frequency is snapped so that the window holds a whole number of
//! periods *and* of samples: the correlation of sampled sinusoids is then exact (no
//! leakage), and with a linear cable the estimate equals the exact discrete transfer at
//! `z = exp(j 2 pi f T)`. The loop is measured as feedback alone: the reference is held at
//! zero (or is the injected sinusoid), feedforward and compensation are off.
//!
//! | point | injected | measured | transfer |
//! |---|---|---|---|
//! | `plant_input` | `d` added to the command | `u = u_c + d` | `L = -U_c/U = D/U - 1` |
//! | `output_disturbance` | `d` added to the measurement | `y + d` | `S = (Y + D)/D` |
//! | `input_disturbance` | `d` added to the command | `y` | `PS = Y/D` |
//! | `reference` | the reference is `d` | `y` | `T_r = Y/R` |
//! | `plant` | `d` is the whole command, the loop open | `y` | `P = Y/D`, `L = K P` |
//!
//! The `plant` point measures the plant's describing function: its response to a
//! sinusoidal command of each amplitude, with the controller disconnected. Brake stiction,
//! Coulomb friction and the capstan's hysteresis make it depend on the amplitude. The loop
//! gain at that amplitude is the exact discrete controller `K` times it, and where that
//! family meets the critical point as the amplitude varies the loop can sustain an
//! oscillation: [`predict_limit_cycles`]. The command is a cosine, which drives a free
//! inertia from rest without a mean drift, and an offset and a linear drift are fitted out
//! of the measured window with the fundamental.
//!
//! A brake with breakaway or Coulomb friction holds the axis while the injected motion is
//! small, and the loop then sees the motor on the cable spring, not the design. The
//! `slewing` operating point measures as a gimbal bench does: the reference is a ramp at
//! a constant output rate fast enough that the drum never reverses, with the sinusoid on
//! top, so the friction slides and acts as a constant torque. What the PID sees of the
//! ramp is constant in the steady state: its derivative acts on the measurement (a
//! constant `kd ic rate`), its integral settles to the constant command that drives the
//! sliding friction and the viscous drag, and the error returns to zero; none of it is
//! at the injected frequency. Each measured signal has its offset and linear drift fitted
//! out jointly with the fundamental ([`without_drift`]), which removes the ramp exactly and
//! what is left of the start-up transient in the window. Each measurement classifies the
//! axis ([`AxisMotion`]) from the simulation's own brake state and the sign of the drum's
//! and the motor's velocity.
//!
//! `y` is the measured angle in motor rad (the motor angle, or `ic` times the output
//! angle under output feedback). The PID differentiates the measurement, not the error,
//! so the reference-to-output response `T_r = P (kp + ki T/(1 - z^-1)) / (1 + L)` is not
//! the complementary sensitivity `T = L/(1 + L)`; `T` is derived from `L` or `S`.

use nalgebra::Complex;
use rayon::prelude::*;
use serde::Serialize;

use super::linear::LinearLoop;
use super::margins::Margins;
use crate::closed_loop::params::{ClosedLoopParams, CompensationMode, Feedback};
pub use crate::closed_loop::probe::{FreqRespParams, LoopPoint, OperatingPoint};
use crate::closed_loop::sim::{
    run_closed_loop, ClosedLoopError, ClosedLoopSetup, Completion, Injection, InjectionSite,
    RunOptions, TimeSeries,
};
use crate::signal::Signal;

/// Why a frequency response cannot be measured.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FreqRespError {
    /// A setting out of range.
    #[error("{key}: {message}")]
    Invalid {
        /// Dotted scenario key.
        key: String,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// The loop itself cannot run.
    #[error(transparent)]
    ClosedLoop(#[from] ClosedLoopError),
    /// Worker threads could not start.
    #[error("cannot start worker threads: {0}")]
    Threads(String),
}

fn invalid(key: &str, message: String) -> FreqRespError {
    FreqRespError::Invalid {
        key: format!("closed_loop.freqresp.{key}"),
        message,
    }
}

/// Highest base-motion frequency the simulation takes at `sample_rate_hz`, exclusive:
/// a tenth of the control rate, Hz (the base is interpolated inside each period).
pub fn base_motion_limit_hz(sample_rate_hz: f64) -> f64 {
    0.1 * sample_rate_hz
}

/// Base-motion rejection in dB from line of sight over base angle: `-20 log10 |LOS/base|`
/// (positive when the line of sight moves less than the base).
pub fn rejection_db(los_over_base: Complex<f64>) -> f64 {
    -20.0 * los_over_base.norm().log10()
}

/// The declared base-rejection requirement `(frequency Hz, least rejection dB)`, when
/// `point` measures base motion and both keys are given.
fn base_requirement(
    point: LoopPoint,
    req: &crate::closed_loop::Requirements,
) -> Option<(f64, f64)> {
    match (point, req.base_rejection_hz, req.min_base_rejection_db) {
        (LoopPoint::BaseMotion, Some(f), Some(db)) => Some((f, db)),
        _ => None,
    }
}

/// Fastest slew accepted, output rad/s: beyond it a measurement of seconds turns the
/// output through many revolutions, which says the amplitude is too large for a slew.
pub const MAX_SLEW_RAD_S: f64 = 10.0;

/// Slowest slew chosen automatically, output rad/s: slower than this the breakaway at the
/// start of the ramp leaves a stick-slip transient that outlasts the settling time.
pub const MIN_AUTO_SLEW_RAD_S: f64 = 0.01;

/// How the axis moved during one measurement window, worst last.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum AxisMotion {
    /// No friction that can stick (no brake, no motor or bearing Coulomb friction).
    Frictionless,
    /// The friction slid one way throughout the window: a constant torque.
    Sliding,
    /// The drum stuck, or the drum or the motor reversed, for part of each cycle.
    Slipping,
    /// The brake held the drum for at least half of the window.
    Held,
}

impl AxisMotion {
    /// Name as written in tables and files.
    pub fn name(self) -> &'static str {
        match self {
            AxisMotion::Frictionless => "frictionless",
            AxisMotion::Sliding => "sliding",
            AxisMotion::Slipping => "slipping",
            AxisMotion::Held => "held",
        }
    }

    /// What this motion does to the estimate, in one line.
    pub fn effect(self) -> &'static str {
        match self {
            AxisMotion::Frictionless => "no friction to stick: the estimate is the linear loop, up to the cable's hysteresis",
            AxisMotion::Sliding => "friction acts as a constant torque: the estimate is the linear loop",
            AxisMotion::Slipping => "the friction sticks or reverses each cycle: a describing function, distorted by stick-slip, not the linear loop",
            AxisMotion::Held => "the brake holds the drum: the loop sees the motor on the cable spring, the estimate is not the design's response (measure slewing)",
        }
    }
}

/// Frequencies of one amplitude by how the axis moved.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct AxisCounts {
    /// Frequencies with no friction that can stick.
    pub frictionless: usize,
    /// Frequencies where the friction slid throughout.
    pub sliding: usize,
    /// Frequencies where it stuck or reversed part of each cycle.
    pub slipping: usize,
    /// Frequencies where the brake held the drum most of the window.
    pub held: usize,
}

impl AxisCounts {
    fn of(points: &[FreqPoint]) -> Self {
        let mut c = AxisCounts::default();
        for p in points {
            match p.axis {
                Some(AxisMotion::Frictionless) => c.frictionless += 1,
                Some(AxisMotion::Sliding) => c.sliding += 1,
                Some(AxisMotion::Slipping) => c.slipping += 1,
                Some(AxisMotion::Held) => c.held += 1,
                None => {}
            }
        }
        c
    }
}

/// The operating point a measurement runs at, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OperatingPlan {
    /// Rest or slewing.
    pub operating_point: OperatingPoint,
    /// Why: the key that set it, or the friction that makes a slew necessary.
    pub reason: String,
    /// Slew rate per amplitude, output rad/s, in the order of the amplitudes (`None` at
    /// rest).
    pub slew_rates_rad_s: Vec<Option<f64>>,
    /// Whether the rates were chosen automatically (`slew_rate_rad_s` unset).
    pub slew_rate_automatic: bool,
    /// Longest output travel of one run, rad (0 at rest): the slew over the settling and
    /// measuring time of the lowest frequency.
    pub travel_rad: f64,
}

/// Friction in the plant that can hold the axis, as `key = value`.
fn holding_friction(setup: &ClosedLoopSetup<'_>) -> Vec<String> {
    let mut out = Vec::new();
    let breakaway = setup.load.breakaway_nm();
    if breakaway > 0.0 {
        out.push(format!(
            "load.brake_nm = {} (breakaway {} N m)",
            crate::compact(setup.load.brake_nm),
            crate::compact(breakaway)
        ));
    }
    let coulomb = setup.params.motor.coulomb_nm;
    if coulomb > 0.0 {
        out.push(format!(
            "closed_loop.motor.coulomb_nm = {}",
            crate::compact(coulomb)
        ));
    }
    let bearing = setup.effects.map_or(0.0, |e| e.bearing_friction());
    if bearing > 0.0 {
        out.push(format!(
            "effects.bearing_friction_nm = {}",
            crate::compact(bearing)
        ));
    }
    out
}

/// Terms of the plant that change with the output angle, as scenario keys: a slew moves
/// the operating point along them.
fn angle_dependent_terms(setup: &ClosedLoopSetup<'_>) -> Vec<&'static str> {
    let mut out = Vec::new();
    if setup.load.unbalance_nm != 0.0 {
        out.push("load.unbalance_nm");
    }
    if let Some(e) = setup.effects {
        let nz = |v: Option<f64>| v.is_some_and(|x| x != 0.0);
        if nz(e.input_pulley_runout) {
            out.push("effects.input_pulley_runout");
        }
        if nz(e.output_drum_runout) {
            out.push("effects.output_drum_runout");
        }
        if e.angle_dependent_ratio_coefs
            .as_ref()
            .is_some_and(|c| c.iter().any(|v| *v != 0.0))
        {
            out.push("effects.angle_dependent_ratio_coefs");
        }
    }
    out
}

/// Output angle per unit injection at `f` on the linear reference, rad (A or V at the
/// command, output mrad elsewhere): under motor feedback the output is taken as the
/// motor angle over the ratio, which overstates it above the cable's resonance (a
/// conservative slew).
fn output_per_injection(lin: &LinearLoop, point: LoopPoint, ic: f64, f: f64) -> f64 {
    match point {
        LoopPoint::PlantInput | LoopPoint::InputDisturbance | LoopPoint::Plant => {
            (lin.plant(f) * lin.sensitivity(f)).norm() / ic
        }
        LoopPoint::OutputDisturbance => lin.complementary(f).norm() * 1e-3,
        LoopPoint::Reference => exact_transfer(lin, point, f).norm() * 1e-3,
        LoopPoint::BaseMotion => (lin.base_to_los(f) - Complex::from(1.0)).norm() * 1e-3,
    }
}

/// Chooses the operating point and the slew rates, and refuses a slew the plant cannot
/// take (keys named). `lin` is the exact linear reference the rates are read from.
pub fn operating_plan(
    setup: &ClosedLoopSetup<'_>,
    spec: &FreqRespParams,
    lin: &LinearLoop,
) -> Result<OperatingPlan, FreqRespError> {
    let p = setup.params;
    let friction = holding_friction(setup);
    let moving = angle_dependent_terms(setup);
    let (operating_point, reason) = match spec.operating_point {
        Some(o) => (o, "set by closed_loop.freqresp.operating_point".to_string()),
        None if spec.point == LoopPoint::Plant => (
            OperatingPoint::Rest,
            "the plant point opens the loop: its describing function is measured at rest"
                .to_string(),
        ),
        None if friction.is_empty() => (
            OperatingPoint::Rest,
            "no brake or Coulomb friction can hold the axis".to_string(),
        ),
        // Chosen, not asked for: rest, saying why, rather than refusing.
        None if !moving.is_empty() => (
            OperatingPoint::Rest,
            format!(
                "{} would hold the axis, but the plant changes with the output angle ({}), so a slew would not stay at one operating point; the axis column says whether the friction held",
                friction.join(", "),
                moving.join(", ")
            ),
        ),
        None => (
            OperatingPoint::Slewing,
            format!(
                "{} would hold the axis at small amplitude; slewing keeps it sliding",
                friction.join(", ")
            ),
        ),
    };
    let amps = spec.amplitudes(p.motor.command_limit())?;
    if operating_point == OperatingPoint::Rest {
        return Ok(OperatingPlan {
            operating_point,
            reason,
            slew_rates_rad_s: vec![None; amps.len()],
            slew_rate_automatic: false,
            travel_rad: 0.0,
        });
    }
    let ts = 1.0 / p.controller.sample_rate_hz;
    let freqs = spec.frequencies(p.controller.sample_rate_hz)?;
    let ic = setup.drive.ratio();
    let rates: Vec<f64> = match spec.slew_rate_rad_s {
        Some(r) => vec![r; amps.len()],
        None => amps
            .iter()
            .map(|&a| {
                let peak = freqs
                    .iter()
                    .map(|&f| {
                        std::f64::consts::TAU * f * a * output_per_injection(lin, spec.point, ic, f)
                    })
                    .fold(0.0_f64, f64::max);
                (2.0 * peak).max(MIN_AUTO_SLEW_RAD_S)
            })
            .collect(),
    };
    let longest_s = freqs
        .iter()
        .map(|&f| {
            let w = window(spec, f, ts);
            (w.settle + w.samples) as f64 * ts
        })
        .fold(0.0_f64, f64::max);
    let fastest = rates.iter().copied().fold(0.0_f64, f64::max);
    let travel_rad = fastest * longest_s;
    if fastest > MAX_SLEW_RAD_S {
        return Err(invalid("slew_rate_rad_s", format!("the slew chosen for the largest amplitude, {} rad/s, is above {MAX_SLEW_RAD_S} rad/s: lower the amplitudes, or set closed_loop.freqresp.slew_rate_rad_s (the axis then slips where the injected motion outruns the slew)", crate::significant(fastest, 3))));
    }
    if !moving.is_empty() {
        return Err(invalid("operating_point", format!("slewing turns the output through up to {} rad in one run, and the plant changes with the output angle ({}): the loop would not be measured at one operating point; set closed_loop.freqresp.operating_point = \"rest\", or remove those terms to measure the loop alone", crate::significant(travel_rad, 3), moving.join(", "))));
    }
    Ok(OperatingPlan {
        operating_point,
        reason,
        slew_rates_rad_s: rates.into_iter().map(Some).collect(),
        slew_rate_automatic: spec.slew_rate_rad_s.is_none(),
        travel_rad,
    })
}

impl FreqRespParams {
    /// The frequencies to measure, Hz, checked against Nyquist.
    pub fn frequencies(&self, sample_rate_hz: f64) -> Result<Vec<f64>, FreqRespError> {
        let nyquist = 0.5 * sample_rate_hz;
        let check = |key: &str, f: f64| {
            if !(f.is_finite() && f > 0.0) {
                Err(invalid(
                    key,
                    format!("frequency {f} Hz: must be a finite number > 0"),
                ))
            } else if f >= nyquist {
                Err(invalid(key, format!("frequency {f} Hz is at or above Nyquist ({nyquist} Hz, half of closed_loop.controller.sample_rate_hz); measure below it (0.4 x Nyquist = {} Hz keeps several samples per period)", 0.4 * nyquist)))
            } else {
                Ok(f)
            }
        };
        // The base's motion is interpolated inside each period: below a tenth of the rate
        // (the scenario's own check on `closed_loop.base_motion`, strict).
        let base_limit = base_motion_limit_hz(sample_rate_hz);
        let base_check = |key: &str, f: f64| {
            if self.point == LoopPoint::BaseMotion && f >= base_limit {
                Err(invalid(key, format!("frequency {f} Hz: base motion is measured up to a tenth of the control rate (below {base_limit} Hz), as the base is interpolated inside each period")))
            } else {
                Ok(f)
            }
        };
        if !self.frequencies_hz.is_empty() {
            let mut f = self
                .frequencies_hz
                .iter()
                .map(|&f| check("frequencies_hz", f).and_then(|f| base_check("frequencies_hz", f)))
                .collect::<Result<Vec<f64>, _>>()?;
            f.sort_by(f64::total_cmp);
            f.dedup();
            return Ok(f);
        }
        let lo = check("f_min_hz", self.f_min_hz)?;
        let (hi, hi_key) = match self.f_max_hz {
            Some(f) => (base_check("f_max_hz", check("f_max_hz", f)?)?, "f_max_hz"),
            // The default sits just inside the real limit: a frequency snapped to whole
            // periods moves by at most half a sample in `min_samples`.
            None if self.point == LoopPoint::BaseMotion => (
                base_limit * (1.0 - 1.0 / f64::from(self.min_samples.max(16))),
                "f_min_hz",
            ),
            None => (0.4 * nyquist, "f_min_hz"),
        };
        if hi <= lo {
            return Err(invalid(
                hi_key,
                if self.f_max_hz.is_some() {
                    format!("{hi} Hz must be above f_min_hz = {lo} Hz")
                } else {
                    format!("{lo} Hz must be below the default upper end of the range, {hi} Hz (or give f_max_hz)")
                },
            ));
        }
        if !(2..=500).contains(&self.points) {
            return Err(invalid(
                "points",
                format!("{}: allowed 2 to 500", self.points),
            ));
        }
        Ok((0..self.points)
            .map(|i| lo * (hi / lo).powf(i as f64 / (self.points - 1) as f64))
            .collect())
    }

    /// The amplitudes to measure, in the point's unit.
    pub fn amplitudes(&self, command_limit: f64) -> Result<Vec<f64>, FreqRespError> {
        let list = if !self.amplitudes.is_empty() {
            self.amplitudes.clone()
        } else if matches!(
            self.point,
            LoopPoint::PlantInput | LoopPoint::InputDisturbance | LoopPoint::Plant
        ) {
            let full = if command_limit.is_finite() {
                command_limit
            } else {
                10.0
            };
            if self.point == LoopPoint::Plant {
                // A describing function is read across amplitudes: 12 from 1 % to 60 %.
                (0..12)
                    .map(|i| 0.01 * full * 60f64.powf(f64::from(i) / 11.0))
                    .collect()
            } else {
                vec![0.001 * full, 0.01 * full, 0.1 * full]
            }
        } else {
            vec![0.01, 0.1, 1.0]
        };
        for &a in &list {
            if !(a.is_finite() && a > 0.0) {
                return Err(invalid(
                    "amplitudes",
                    format!("amplitude {a}: must be a finite number > 0"),
                ));
            }
            if matches!(
                self.point,
                LoopPoint::PlantInput | LoopPoint::InputDisturbance | LoopPoint::Plant
            ) && a >= command_limit
            {
                return Err(invalid("amplitudes", format!("amplitude {a} reaches the amplifier limit {command_limit}: the loop would only saturate; use amplitudes below it")));
            }
        }
        Ok(list)
    }

    /// Checks every setting (keys named in the messages).
    pub fn validate(&self, p: &ClosedLoopParams) -> Result<(), FreqRespError> {
        let gyro_angle = p.controller.feedback == Feedback::GyroAngle;
        match self.point {
            LoopPoint::OutputDisturbance | LoopPoint::Reference
                if gyro_angle || !p.controller.is_plain_pid() =>
            {
                return Err(invalid("point", format!("{}: its closed form holds for a single PID on an encoder; with a rate loop, filters, an observer or gyro-angle feedback use plant_input (the loop gain at the command) or base_motion", self.point.name())));
            }
            LoopPoint::Plant if gyro_angle || !p.controller.is_plain_pid() => {
                return Err(invalid("point", "plant: the loop gain is formed with a single PID on an encoder; with a rate loop, filters, an observer or gyro-angle feedback use plant_input".into()));
            }
            LoopPoint::InputDisturbance if gyro_angle => {
                return Err(invalid("point", "input_disturbance: the gyro angle is not recorded; use plant_input or base_motion".into()));
            }
            _ => {}
        }
        self.frequencies(p.controller.sample_rate_hz)?;
        if let Some((f, _)) = base_requirement(self.point, &p.requirements) {
            let limit = base_motion_limit_hz(p.controller.sample_rate_hz);
            if f >= limit {
                return Err(FreqRespError::Invalid {
                    key: "closed_loop.requirements.base_rejection_hz".into(),
                    message: format!("{f} Hz: base motion is measured below a tenth of the control rate ({limit} Hz); judge the rejection at a lower frequency"),
                });
            }
        }
        self.amplitudes(p.motor.command_limit())?;
        let positive = |key: &str, v: f64, hi: f64| {
            if v.is_finite() && v >= 0.0 && v <= hi {
                Ok(())
            } else {
                Err(invalid(key, format!("{v}: allowed 0 to {hi}")))
            }
        };
        positive("settle_periods", self.settle_periods, 1000.0)?;
        positive("settle_min_s", self.settle_min_s, 100.0)?;
        if !(1..=10_000).contains(&self.measure_periods) {
            return Err(invalid(
                "measure_periods",
                format!("{}: allowed 1 to 10000", self.measure_periods),
            ));
        }
        if !(16..=10_000_000).contains(&self.min_samples) {
            return Err(invalid(
                "min_samples",
                format!("{}: allowed 16 to 10000000", self.min_samples),
            ));
        }
        if self.harmonics > 50 {
            return Err(invalid(
                "harmonics",
                format!("{}: allowed 0 to 50", self.harmonics),
            ));
        }
        if let Some(rate) = self.slew_rate_rad_s {
            if !(rate.is_finite() && rate > 0.0 && rate <= MAX_SLEW_RAD_S) {
                return Err(invalid(
                    "slew_rate_rad_s",
                    format!("{rate} rad/s: allowed above 0 up to {MAX_SLEW_RAD_S} rad/s of output"),
                ));
            }
        }
        if self.point == LoopPoint::Plant && self.operating_point == Some(OperatingPoint::Slewing) {
            return Err(invalid("operating_point", "slewing: the plant point opens the loop, so nothing would hold a slew; it measures the describing function at rest (operating_point = \"rest\"); measure the slewing loop at plant_input".into()));
        }
        if self.refine_iterations > 50 {
            return Err(invalid(
                "refine_iterations",
                format!("{}: allowed 0 to 50", self.refine_iterations),
            ));
        }
        Ok(())
    }
}

/// The measurement at one frequency and amplitude.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FreqPoint {
    /// Frequency asked for, Hz.
    pub requested_hz: f64,
    /// Frequency measured (snapped to whole periods in whole samples), Hz.
    pub frequency_hz: f64,
    /// Measured transfer of the point (`None` when the point failed).
    #[serde(serialize_with = "polar_opt")]
    pub response: Option<Complex<f64>>,
    /// Loop gain `L` derived from it (plant input and output disturbance only).
    #[serde(serialize_with = "polar_opt")]
    pub loop_gain: Option<Complex<f64>>,
    /// The exact linear reference of the same transfer at `frequency_hz`.
    #[serde(serialize_with = "polar")]
    pub exact: Complex<f64>,
    /// Harmonic distortion of the measured signal: RMS of the 2nd to the highest
    /// harmonic below Nyquist over the fundamental, percent.
    pub distortion_percent: Option<f64>,
    /// Amplitude of the output angle at the injected frequency, mrad.
    pub output_amplitude_mrad: Option<f64>,
    /// How the axis moved during the window (`None` when the run failed).
    pub axis: Option<AxisMotion>,
    /// Fraction of the window the brake held the drum, 0 to 1.
    pub held_fraction: Option<f64>,
    /// Reversals of the drum's or the motor's velocity in the window, per period of the
    /// injection (about 2 at rest, 0 when sliding).
    pub reversals_per_period: Option<f64>,
    /// Relative uncertainty of the estimate, percent: the noise in the bins next to the
    /// injected frequency over the fundamental (of the denominator too at the plant
    /// input); above `MAX_UNCERTAINTY` the point fails.
    pub uncertainty_percent: Option<f64>,
    /// Whether this frequency was added to refine a margin, peak or bandwidth.
    pub refinement: bool,
    /// Why the point has no result (slack, gross slip, saturation, divergence).
    pub failure: Option<String>,
}

/// A complex response as magnitude (dB), phase (deg) and its parts.
fn polar<S: serde::Serializer>(c: &Complex<f64>, s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let mut m = s.serialize_map(Some(4))?;
    m.serialize_entry("mag_db", &(20.0 * c.norm().log10()))?;
    m.serialize_entry("phase_deg", &c.arg().to_degrees())?;
    m.serialize_entry("re", &c.re)?;
    m.serialize_entry("im", &c.im)?;
    m.end()
}

fn polar_opt<S: serde::Serializer>(c: &Option<Complex<f64>>, s: S) -> Result<S::Ok, S::Error> {
    match c {
        Some(c) => polar(c, s),
        None => s.serialize_none(),
    }
}

/// Margins, peaks and bandwidth read from a measured loop gain.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct EstimatedMargins {
    /// Phase margin, deg (smallest over gain crossovers).
    pub phase_margin_deg: Option<f64>,
    /// Its gain crossover, Hz.
    pub crossover_hz: Option<f64>,
    /// Upward gain margin, dB.
    pub gain_margin_db: Option<f64>,
    /// Its phase crossover, Hz.
    pub phase_crossover_hz: Option<f64>,
    /// Downward gain margin, dB (crossings of -180 deg with `|L| > 1`).
    pub lower_gain_margin_db: Option<f64>,
    /// Sensitivity peak `max |S|`.
    pub ms: Option<f64>,
    /// Where it peaks, Hz.
    pub ms_hz: Option<f64>,
    /// Complementary sensitivity peak `max |T|`.
    pub mt: Option<f64>,
    /// Closed-loop bandwidth: first frequency where `|T|` falls below -3 dB, Hz.
    pub bandwidth_hz: Option<f64>,
}

/// Everything measured at one amplitude.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AmplitudeResponse {
    /// Injection amplitude, in `unit`.
    pub amplitude: f64,
    /// Unit of the amplitude (A, V or mrad).
    pub unit: String,
    /// Every frequency, ascending (refinements included).
    pub points: Vec<FreqPoint>,
    /// Slew rate of the operating point, output rad/s (`None` at rest).
    pub slew_rate_rad_s: Option<f64>,
    /// How the axis moved: the worst over the frequencies measured.
    pub axis: Option<AxisMotion>,
    /// Frequencies by how the axis moved.
    pub axis_frequencies: AxisCounts,
    /// Margins from the measured `L` (plant input, output disturbance).
    pub margins: Option<EstimatedMargins>,
    /// Requirements not met, and frequencies whose run stopped (empty = passes).
    pub shortfalls: Vec<String>,
    /// Frequencies the measurement could not resolve at this amplitude, grouped by
    /// reason ([`FreqPoint::unresolved`]): left out of the estimate and named here, not
    /// failing; a larger amplitude resolves them.
    pub unresolved: Vec<String>,
    /// The base-motion rejection at the required frequency (base motion with
    /// `requirements.min_base_rejection_db` declared; `None` otherwise).
    pub base_rejection: Option<RejectionCheck>,
}

/// The base-motion rejection at the frequency `[closed_loop.requirements]` names.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RejectionCheck {
    /// Frequency judged, Hz (`requirements.base_rejection_hz`).
    pub frequency_hz: f64,
    /// Measured rejection there, dB (`-20 log10 |LOS/base|`, interpolated linearly in dB
    /// on log frequency between the measured neighbours); `None` when not measured.
    pub rejection_db: Option<f64>,
    /// The exact linear reference's rejection there, dB.
    pub reference_rejection_db: f64,
    /// Least rejection required, dB (`requirements.min_base_rejection_db`).
    pub min_rejection_db: f64,
}

impl RejectionCheck {
    /// Whether the measured rejection meets the requirement.
    pub fn passes(&self) -> bool {
        self.rejection_db
            .is_some_and(|r| r >= self.min_rejection_db)
    }

    /// The shortfall, worded for the console (`None` when it passes).
    pub fn shortfall(&self) -> Option<String> {
        match self.rejection_db {
            _ if self.passes() => None,
            Some(r) => Some(format!(
                "base-motion rejection {r:.2} dB at {} Hz < {} dB required",
                self.frequency_hz, self.min_rejection_db
            )),
            None => Some(format!(
                "base-motion rejection at {} Hz not measured (its frequency and neighbours failed)",
                self.frequency_hz
            )),
        }
    }
}

/// Measured rejection at `f_hz`, dB: linear in dB on log frequency between the measured
/// points either side, or the nearest point when it lies within the frequency snap.
fn rejection_at(points: &[FreqPoint], f_hz: f64) -> Option<f64> {
    let ok: Vec<(f64, f64)> = points
        .iter()
        .filter_map(|p| p.response.map(|r| (p.frequency_hz, rejection_db(r))))
        .collect();
    if let Some(w) = ok
        .windows(2)
        .find(|w| w[0].0 <= f_hz && f_hz <= w[1].0 && w[1].0 > w[0].0)
    {
        let s = (f_hz / w[0].0).ln() / (w[1].0 / w[0].0).ln();
        return Some(w[0].1 + s * (w[1].1 - w[0].1));
    }
    // Outside the measured span only the requirement's own point, moved by the snap to
    // whole periods (half a sample in `min_samples`, 16 or more), may stand for it.
    ok.iter()
        .filter(|(f, _)| (f / f_hz).ln().abs() < 0.04)
        .min_by(|a, b| (a.0 / f_hz).ln().abs().total_cmp(&(b.0 / f_hz).ln().abs()))
        .map(|p| p.1)
}

impl AmplitudeResponse {
    /// Whether every requirement is met and every frequency measured.
    pub fn passes(&self) -> bool {
        self.shortfalls.is_empty()
    }
}

/// The cable of the exact linear reference.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReferenceCable {
    /// Transmitted torque of the tangent stiffness, N m; `None` for the free span.
    pub load_nm: Option<f64>,
    /// Stiffness of each half, N/m.
    pub half_stiffness_n_per_m: f64,
    /// The free-span stiffness of each half, N/m, for comparison.
    pub free_span_half_stiffness_n_per_m: f64,
}

/// A frequency-response measurement.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FreqResponse {
    /// Loop point.
    pub point: LoopPoint,
    /// Measured transfer (`L`, `S`, `PS`, `T_r`).
    pub transfer: String,
    /// The operating point measured about, and why.
    pub operating: OperatingPlan,
    /// One entry per amplitude.
    pub amplitudes: Vec<AmplitudeResponse>,
    /// Margins of the exact linear reference (cable as its linear spring).
    pub exact_margins: Margins,
    /// The stiffness the exact reference gave its cable.
    pub reference_cable: ReferenceCable,
    /// Limit cycles the amplitude family predicts (the `plant` point only; `None`
    /// elsewhere, empty when none is predicted over the amplitudes measured).
    pub limit_cycles: Option<Vec<PredictedCycle>>,
    /// Simulation runs made (one per frequency and amplitude, refinements included).
    pub runs: usize,
    /// Simulated time over all runs, s.
    pub simulated_s: f64,
}

impl FreqResponse {
    /// Whether every frequency of every amplitude was measured: no run stopped. Points
    /// the measurement could not resolve at their amplitude are named, not counted here.
    pub fn complete(&self) -> bool {
        self.amplitudes.iter().all(|a| {
            a.points
                .iter()
                .all(|p| p.failure.is_none() || p.unresolved())
        })
    }

    /// The verdict: `None` when there is nothing to judge (base motion without a declared
    /// `requirements.min_base_rejection_db`, every frequency measured), else whether
    /// every amplitude meets its requirements.
    pub fn verdict(&self) -> Option<bool> {
        let passes = self.amplitudes.iter().all(AmplitudeResponse::passes);
        let undeclared = self.point == LoopPoint::BaseMotion
            && self.amplitudes.iter().all(|a| a.base_rejection.is_none());
        if undeclared && passes {
            None
        } else {
            Some(passes)
        }
    }
}

/// An oscillation the describing function predicts: where the loop gain `K P(A)` at a
/// phase crossover passes through `-1` between two measured amplitudes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PredictedCycle {
    /// Frequency of the oscillation, Hz (the phase crossover there).
    pub frequency_hz: f64,
    /// Amplitude of the command's fundamental in the oscillation (A, or V with a voltage
    /// amplifier).
    pub command_amplitude: f64,
    /// Unit of `command_amplitude`.
    pub unit: String,
    /// Amplitude of the output angle's fundamental, mrad.
    pub output_amplitude_mrad: f64,
    /// Whether the oscillation attracts: a little larger and the loop is stable (it
    /// shrinks back), a little smaller and it is not (it grows back). An unstable one is
    /// a threshold: motion above it grows, below it dies out.
    pub stable: bool,
    /// The measured amplitudes either side, in `unit`.
    pub between: [f64; 2],
}

/// Where a measured loop gain crosses the negative real axis between grid frequencies.
#[derive(Clone, Copy, Debug)]
struct PhaseCrossing {
    frequency_hz: f64,
    magnitude: f64,
    output_mrad: f64,
    /// The phase rises through -180 deg with frequency (the lower crossing of a loop with
    /// integral action): there the loop is stable when `|L| > 1`. Where it falls, when
    /// `|L| < 1`.
    rising: bool,
}

impl PhaseCrossing {
    fn stable(&self) -> bool {
        (self.magnitude > 1.0) == self.rising
    }
}

fn phase_crossings(points: &[FreqPoint]) -> Vec<PhaseCrossing> {
    let grid: Vec<(f64, Complex<f64>, f64)> = points
        .iter()
        .filter_map(|p| Some((p.frequency_hz, p.loop_gain?, p.output_amplitude_mrad?)))
        .filter(|(_, l, _)| l.norm() > 0.0)
        .collect();
    grid.windows(2)
        .filter_map(|w| {
            let ((f0, l0, y0), (f1, l1, y1)) = (w[0], w[1]);
            // Phase measured from -180 deg, so the crossing is a sign change near zero.
            let (a0, a1) = ((-l0).arg(), (-l1).arg());
            let half = std::f64::consts::FRAC_PI_2;
            if a0 * a1 > 0.0 || a0 == a1 || a0.abs() > half || a1.abs() > half {
                return None;
            }
            let s = a0 / (a0 - a1);
            let lerp = |u: f64, v: f64| u + s * (v - u);
            Some(PhaseCrossing {
                frequency_hz: lerp(f0.ln(), f1.ln()).exp(),
                magnitude: lerp(l0.norm().ln(), l1.norm().ln()).exp(),
                output_mrad: lerp(y0, y1),
                rising: a1 > a0,
            })
        })
        .collect()
}

/// Limit cycles predicted from a describing-function family (the `plant` point's loop
/// gains at each amplitude): between two neighbouring amplitudes, a phase crossover of the
/// same kind whose `|L|` passes through 1, interpolated on log amplitude. Amplitudes where
/// nothing moved (the brake held) have no crossing and bracket nothing.
///
/// The describing function assumes the command is close to a sinusoid. A stick-slip
/// cycle at a small fraction of the loop's bandwidth (integral action winding against a
/// brake that holds most of the period) is far from one, and its frequency is missed.
pub fn predict_limit_cycles(amplitudes: &[AmplitudeResponse]) -> Vec<PredictedCycle> {
    let mut family: Vec<(f64, &str, Vec<PhaseCrossing>)> = amplitudes
        .iter()
        .map(|a| (a.amplitude, a.unit.as_str(), phase_crossings(&a.points)))
        .collect();
    family.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out = Vec::new();
    for w in family.windows(2) {
        let ((a0, unit, c0), (a1, _, c1)) = (&w[0], &w[1]);
        for x0 in c0 {
            // The same crossover one amplitude up: the same kind, nearest in frequency
            // and within an octave.
            let Some(x1) = c1
                .iter()
                .filter(|x| x.rising == x0.rising)
                .min_by(|p, q| {
                    let d = |x: &&PhaseCrossing| (x.frequency_hz / x0.frequency_hz).ln().abs();
                    d(p).total_cmp(&d(q))
                })
                .filter(|x| (x.frequency_hz / x0.frequency_hz).ln().abs() < 2f64.ln())
            else {
                continue;
            };
            let (g0, g1) = (x0.magnitude.ln(), x1.magnitude.ln());
            if g0 * g1 > 0.0 || g0 == g1 {
                continue;
            }
            let s = g0 / (g0 - g1);
            let lerp = |u: f64, v: f64| u + s * (v - u);
            out.push(PredictedCycle {
                frequency_hz: lerp(x0.frequency_hz.ln(), x1.frequency_hz.ln()).exp(),
                command_amplitude: lerp(a0.ln(), a1.ln()).exp(),
                unit: unit.to_string(),
                output_amplitude_mrad: lerp(x0.output_mrad, x1.output_mrad),
                stable: x1.stable(),
                between: [*a0, *a1],
            });
        }
    }
    out
}

/// Discrete Fourier coefficient of `x[k0..k0+n]` at `cycles` cycles over the window
/// (`2/n` scaling: a sinusoid of amplitude `a` gives `|X| = a`).
fn coefficient(x: &[f64], cycles: f64) -> Complex<f64> {
    let n = x.len() as f64;
    let w = std::f64::consts::TAU * cycles / n;
    let (mut re, mut im) = (0.0, 0.0);
    for (k, v) in x.iter().enumerate() {
        let (s, c) = (w * k as f64).sin_cos();
        re += v * c;
        im -= v * s;
    }
    Complex::new(re, im) * (2.0 / n)
}

impl FreqPoint {
    /// A point asked for at `requested_hz` and run at `frequency_hz` (Hz), before anything
    /// is read from its run: no response, no failure yet.
    pub fn unmeasured(
        requested_hz: f64,
        frequency_hz: f64,
        exact: Complex<f64>,
        refinement: bool,
    ) -> FreqPoint {
        FreqPoint {
            requested_hz,
            frequency_hz,
            response: None,
            loop_gain: None,
            exact,
            distortion_percent: None,
            output_amplitude_mrad: None,
            axis: None,
            held_fraction: None,
            reversals_per_period: None,
            uncertainty_percent: None,
            refinement,
            failure: None,
        }
    }

    /// Whether this point's run stopped (slack, slip, saturation): a failed measurement
    /// that fails its amplitude, unlike one the measurement could not resolve.
    pub fn stopped(&self) -> bool {
        self.failure.is_some() && !self.unresolved()
    }

    /// Whether this point failed only because the measurement could not resolve it (no
    /// response at the injected frequency, or noise above [`MAX_UNCERTAINTY`]): the run
    /// itself went through, a larger amplitude would resolve it. Such a point is left out
    /// of the estimate and named; a point whose run stopped (slack, slip, saturation) is
    /// a failed measurement.
    pub fn unresolved(&self) -> bool {
        self.failure.is_some()
            && (self.response.is_none()
                && self
                    .failure
                    .as_deref()
                    .is_some_and(|f| f.starts_with("no response"))
                || self
                    .uncertainty_percent
                    .is_some_and(|u| u > 100.0 * MAX_UNCERTAINTY))
    }
}

/// Largest relative uncertainty of a measured point (0.1: about 0.8 dB and 6 deg); a
/// point more uncertain fails, as its number would mislead the margins.
pub const MAX_UNCERTAINTY: f64 = 0.1;

/// RMS of the Fourier coefficients (scaled as [`coefficient`]) of the two bins either side
/// of the fundamental's `cycles`, skipping harmonics and bins outside the window's band:
/// the level of what is not the response near the injected frequency.
fn noise_floor(x: &[f64], cycles: u64) -> f64 {
    let half = x.len() as u64 / 2;
    let bins: Vec<u64> = [
        cycles.saturating_sub(2),
        cycles.saturating_sub(1),
        cycles + 1,
        cycles + 2,
    ]
    .into_iter()
    .filter(|&k| k >= 1 && k < half && k % cycles != 0)
    .collect();
    if bins.is_empty() {
        return 0.0;
    }
    let power: f64 = bins
        .iter()
        .map(|&k| coefficient(x, k as f64).norm_sqr())
        .sum();
    (power / bins.len() as f64).sqrt()
}

/// `x` less the offset and linear drift of a joint least-squares fit of offset, drift and
/// the sinusoid of `cycles` cycles over the window. What is left keeps the fitted
/// sinusoid, and the residual is orthogonal to it, so [`coefficient`] of the result is the
/// fitted fundamental exactly (a plain detrend would also remove the part of the
/// sinusoid that correlates with a ramp). A window too short to fit is returned as is.
fn without_drift(x: &[f64], cycles: f64) -> Vec<f64> {
    let n = x.len();
    if n < 8 {
        return x.to_vec();
    }
    let w = std::f64::consts::TAU * cycles / n as f64;
    // The drift on [-1, 1] keeps the normal equations well conditioned.
    let ramp = |k: usize| 2.0 * k as f64 / (n - 1) as f64 - 1.0;
    let basis = |k: usize| {
        let (s, c) = (w * k as f64).sin_cos();
        nalgebra::Vector4::new(1.0, ramp(k), c, s)
    };
    let mut gram = nalgebra::Matrix4::<f64>::zeros();
    let mut rhs = nalgebra::Vector4::<f64>::zeros();
    for (k, v) in x.iter().enumerate() {
        let b = basis(k);
        gram += b * b.transpose();
        rhs += b * *v;
    }
    let Some(fit) = gram.lu().solve(&rhs) else {
        return x.to_vec();
    };
    x.iter()
        .enumerate()
        .map(|(k, v)| v - fit[0] - fit[1] * ramp(k))
        .collect()
}

/// A measurement plan at one frequency: the snapped frequency and the sample counts.
#[derive(Clone, Copy, Debug)]
struct Window {
    frequency_hz: f64,
    settle: u64,
    samples: u64,
    cycles: u64,
}

fn window(spec: &FreqRespParams, f_hz: f64, ts: f64) -> Window {
    let per_period = 1.0 / (f_hz * ts);
    let cycles = u64::from(spec.measure_periods)
        .max((f64::from(spec.min_samples) / per_period).ceil() as u64)
        .max(1);
    let samples = ((cycles as f64 * per_period).round() as u64).max(2);
    let frequency_hz = cycles as f64 / (samples as f64 * ts);
    let settle_s = (spec.settle_periods / frequency_hz).max(spec.settle_min_s);
    Window {
        frequency_hz,
        settle: (settle_s / ts).ceil() as u64,
        samples,
        cycles,
    }
}

/// The exact transfer of `point` on the linear reference at `f` Hz.
pub fn exact_transfer(lin: &LinearLoop, point: LoopPoint, f: f64) -> Complex<f64> {
    match point {
        LoopPoint::PlantInput => lin.loop_gain(f),
        LoopPoint::OutputDisturbance => lin.sensitivity(f),
        LoopPoint::InputDisturbance => lin.plant(f) * lin.sensitivity(f),
        LoopPoint::Plant => lin.plant(f),
        LoopPoint::Reference => lin.plant(f) * lin.error_path(f) * lin.sensitivity(f),
        LoopPoint::BaseMotion => lin.base_to_los(f),
    }
}

/// What one measurement needs besides the frequency and amplitude.
struct Bench<'a> {
    setup: ClosedLoopSetup<'a>,
    spec: &'a FreqRespParams,
    lin: LinearLoop,
    /// Whether the plant has friction that can hold the axis.
    friction: bool,
    /// Whether a reversal of the drum reverses a friction (a brake or bearing friction).
    drum_friction: bool,
    /// Whether a reversal of the motor does (motor Coulomb friction).
    motor_friction: bool,
}

impl Bench<'_> {
    /// Runs the loop at `f_hz` with amplitude `amp`, slewing at `slew` output rad/s when
    /// given, and correlates the window.
    fn measure(
        &self,
        f_hz: f64,
        amp: f64,
        slew: Option<f64>,
        refinement: bool,
    ) -> Result<(FreqPoint, f64), FreqRespError> {
        let base = self.setup.params;
        let point = self.spec.point;
        let ts = 1.0 / base.controller.sample_rate_hz;
        let ic = self.setup.drive.ratio();
        let mut w = window(self.spec, f_hz, ts);
        if point == LoopPoint::BaseMotion {
            // One more sample in the window lowers the snapped frequency: it must stay
            // below the limit the scenario's base motion is checked against.
            let limit = base_motion_limit_hz(base.controller.sample_rate_hz);
            while w.frequency_hz >= limit {
                w.samples += 1;
                w.frequency_hz = w.cycles as f64 / (w.samples as f64 * ts);
            }
        }
        let n = w.settle + w.samples;
        let mut p = base.clone();
        p.duration_s = n as f64 * ts;
        p.metrics_start_s = 0.0;
        p.modes = vec![CompensationMode::None];
        // A measurement run is judged by nothing: the design's judged mode (declared for
        // the design's own runs) must not send it looking for a mode it does not run.
        p.requirements.mode = None;
        p.controller.velocity_feedforward = 0.0;
        p.controller.acceleration_feedforward = 0.0;
        p.controller.load_feedforward = false;
        if point == LoopPoint::Plant {
            // The controller disconnected: the command is the injection alone.
            p.controller.kp = 0.0;
            p.controller.ki = 0.0;
            p.controller.kd = 0.0;
        }
        p.timeseries_rate_hz = base.controller.sample_rate_hz;
        p.base_motion = (point == LoopPoint::BaseMotion).then_some(Signal::Sine {
            amplitude_rad: amp * 1e-3,
            frequency_hz: w.frequency_hz,
            phase_rad: 0.0,
            offset_rad: 0.0,
        });
        let about = match point {
            LoopPoint::Reference => Signal::Sine {
                amplitude_rad: amp * 1e-3,
                frequency_hz: w.frequency_hz,
                phase_rad: 0.0,
                offset_rad: 0.0,
            },
            _ => Signal::Step {
                amplitude_rad: 0.0,
                time_s: 0.0,
            },
        };
        // The slew starts with the run: the breakaway and the integral's wind-up to the
        // sliding torque are part of the settling, before the window.
        p.reference = match slew {
            Some(rate) => Signal::Sum {
                parts: vec![
                    Signal::Ramp {
                        rate_rad_s: rate,
                        start_s: 0.0,
                        stop_s: None,
                    },
                    about,
                ],
            },
            None => about,
        };
        let injection = match point {
            LoopPoint::PlantInput | LoopPoint::InputDisturbance => Some(Injection {
                site: InjectionSite::Command,
                amplitude: amp,
                frequency_hz: w.frequency_hz,
                phase_rad: 0.0,
            }),
            LoopPoint::Plant => Some(Injection {
                site: InjectionSite::Command,
                amplitude: amp,
                frequency_hz: w.frequency_hz,
                phase_rad: std::f64::consts::FRAC_PI_2,
            }),
            LoopPoint::OutputDisturbance => Some(Injection {
                site: InjectionSite::Measurement,
                amplitude: ic * amp * 1e-3,
                frequency_hz: w.frequency_hz,
                phase_rad: 0.0,
            }),
            LoopPoint::Reference | LoopPoint::BaseMotion => None,
        };
        let setup = ClosedLoopSetup {
            params: &p,
            ..self.setup
        };
        let options = RunOptions {
            record: true,
            decimation: 1,
            modes: Some(vec![CompensationMode::None]),
            injection,
            // The response is read from the series; the jitter and spectrum are not.
            line_of_sight: false,
        };
        let result = run_closed_loop(&setup, &options)?;
        let exact = exact_transfer(&self.lin, point, w.frequency_hz);
        let mut out = FreqPoint::unmeasured(f_hz, w.frequency_hz, exact, refinement);
        let simulated = p.duration_s;
        let Some(mode) = result.modes.first() else {
            out.failure = Some("no mode ran".into());
            return Ok((out, simulated));
        };
        if let Completion::Incomplete { fault, .. } = &mode.completion {
            out.failure = Some(fault.clone());
            return Ok((out, mode.simulated_s));
        }
        let Some(series) = mode.series.as_ref().filter(|s| s.len() as u64 > n - 1) else {
            out.failure = Some("the run kept fewer samples than the window".into());
            return Ok((out, simulated));
        };
        let range = w.settle as usize..(w.settle + w.samples) as usize;
        let limit = p.motor.command_limit();
        if series.motor_command[range.clone()]
            .iter()
            .any(|u| u.abs() >= limit)
        {
            out.failure = Some(format!(
                "the amplifier saturates (command at its limit {limit}) inside the measurement window: lower the amplitude"
            ));
            return Ok((out, simulated));
        }
        let cycles = w.cycles as f64;
        let (axis, held, reversals) = classify(
            series,
            range.clone(),
            self.friction,
            (self.drum_friction, self.motor_friction),
        );
        out.axis = Some(axis);
        out.held_fraction = Some(held);
        out.reversals_per_period = Some(reversals as f64 / cycles);
        // Offsets and drifts are not part of a response: the open plant's drift, a
        // slew's ramp, the constant command that drives the sliding friction, and what
        // is left of the start-up transient. Fitted jointly with the fundamental, so
        // the ramp takes none of the sinusoid with it.
        let open = |x: Vec<f64>| without_drift(&x, cycles);
        let measured: Vec<f64> = open(
            range
                .clone()
                .map(|k| match (point, p.controller.feedback) {
                    (LoopPoint::BaseMotion, _) => {
                        series.output_angle_rad[k] + series.base_angle_rad[k]
                    }
                    (_, Feedback::Motor) => series.motor_angle_rad[k],
                    // Gyro-angle feedback is refused for the points that read this.
                    (_, Feedback::Output | Feedback::GyroAngle) => ic * series.output_angle_rad[k],
                })
                .collect(),
        );
        let injected: Vec<f64> = range
            .clone()
            .map(|k| injection.map_or(0.0, |i| i.at(series.t_s[k])))
            .collect();
        let c = |x: &[f64]| coefficient(x, cycles);
        // The response, the signal observed, and the fundamental of a denominator that
        // carries the observed signal's noise (the command at the plant input).
        let (response, observed, noisy_denominator): (Complex<f64>, Vec<f64>, Option<f64>) =
            match point {
                LoopPoint::PlantInput => {
                    let u = open(series.motor_command[range.clone()].to_vec());
                    let u_c: Vec<f64> = u.iter().zip(&injected).map(|(u, d)| u - d).collect();
                    (-c(&u_c) / c(&u), u_c, Some(c(&u).norm()))
                }
                LoopPoint::OutputDisturbance => {
                    let y_d: Vec<f64> =
                        measured.iter().zip(&injected).map(|(y, d)| y + d).collect();
                    (c(&y_d) / c(&injected), y_d, None)
                }
                LoopPoint::InputDisturbance | LoopPoint::Plant => {
                    (c(&measured) / c(&injected), measured, None)
                }
                LoopPoint::Reference => {
                    let r: Vec<f64> = open(
                        series.reference_rad[range.clone()]
                            .iter()
                            .map(|r| ic * r)
                            .collect(),
                    );
                    (c(&measured) / c(&r), measured, None)
                }
                LoopPoint::BaseMotion => {
                    let b = &series.base_angle_rad[range.clone()];
                    (c(&measured) / c(b), measured, None)
                }
            };
        let fundamental = c(&observed).norm();
        // A signal that never moves (motion below one encoder count, an output the brake
        // holds) has no response to read: a failed point, not a gain of zero.
        // Rounding leaves a constant signal a fundamental near 1e-16 of its size.
        let largest = observed.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        if !(response.re.is_finite() && response.im.is_finite())
            || response.norm() == 0.0
            || fundamental <= 1e-9 * largest
        {
            out.failure = Some(format!(
                "no response: the measured signal does not move at the injected frequency ({}); raise the amplitude{}",
                if axis == AxisMotion::Held {
                    "the brake holds the drum"
                } else {
                    "motion below one encoder count"
                },
                if slew.is_none() && self.friction {
                    ", or measure slewing (closed_loop.freqresp.operating_point = \"slewing\")"
                } else {
                    ""
                }
            ));
            return Ok((out, simulated));
        }
        // Noise at the injected frequency, read from the neighbouring bins: what the
        // observed signal carries that the injection does not explain (quantisation,
        // what is left of a transient, stick-slip) lands there as much as on the
        // fundamental. Relative to the fundamentals it bounds the estimate's error.
        let noise = noise_floor(&observed, w.cycles);
        let relative = noise / fundamental + noisy_denominator.map_or(0.0, |u| noise / u);
        out.uncertainty_percent = Some(100.0 * relative);
        if relative > MAX_UNCERTAINTY {
            // The numbers are in `uncertainty_percent`: one text for all such points
            // lets the console group them.
            out.failure = Some(format!(
                "uncertain by more than {:.0} % ({:.1} dB, {:.0} deg): the measured signal carries motion the injection does not explain near this frequency (encoder quantisation, a transient, stick-slip); raise the amplitude",
                100.0 * MAX_UNCERTAINTY,
                20.0 * (1.0 + MAX_UNCERTAINTY).log10(),
                MAX_UNCERTAINTY.asin().to_degrees()
            ));
            return Ok((out, simulated));
        }
        let nyquist_cycles = 0.5 * w.samples as f64;
        let harmonics: f64 = (2..=self.spec.harmonics.max(1))
            .map(|h| f64::from(h) * cycles)
            .filter(|&hc| hc < nyquist_cycles)
            .map(|hc| coefficient(&observed, hc).norm_sqr())
            .sum();
        let theta_o = open(series.output_angle_rad[range].to_vec());
        out.response = Some(response);
        out.loop_gain = match point {
            LoopPoint::PlantInput => Some(response),
            LoopPoint::Plant => Some(self.lin.controller(w.frequency_hz) * response),
            LoopPoint::OutputDisturbance => Some(response.inv() - Complex::from(1.0)),
            _ => None,
        };
        out.distortion_percent = Some(100.0 * harmonics.sqrt() / fundamental);
        out.output_amplitude_mrad = Some(c(&theta_o).norm() * 1e3);
        Ok((out, simulated))
    }
}

/// How the axis moved over `range`: `(motion, fraction of samples the brake held the
/// drum, reversals of the drum's or the motor's velocity)`. The velocities are the
/// simulated states' sample-to-sample differences (exact, not the encoders), and a
/// sample where one does not move is no reversal. `friction` says whether anything
/// can stick at all; `(drum, motor)` whether a reversal there reverses a friction (a
/// reversal where nothing rubs changes nothing).
fn classify(
    s: &TimeSeries,
    range: std::ops::Range<usize>,
    friction: bool,
    (drum, motor): (bool, bool),
) -> (AxisMotion, f64, usize) {
    let n = range.len().max(1);
    let held = s
        .drum_held
        .get(range.clone())
        .map_or(0, |h| h.iter().filter(|x| **x).count());
    let reversals = |x: &[f64]| {
        let mut last = 0.0_f64;
        let mut count = 0;
        for d in x.windows(2).map(|w| w[1] - w[0]) {
            if d != 0.0 {
                if last != 0.0 && d.signum() != last {
                    count += 1;
                }
                last = d.signum();
            }
        }
        count
    };
    let rev = if drum {
        reversals(&s.output_angle_rad[range.clone()])
    } else {
        0
    } + if motor {
        reversals(&s.motor_angle_rad[range])
    } else {
        0
    };
    let held_fraction = held as f64 / n as f64;
    let motion = if !friction {
        AxisMotion::Frictionless
    } else if held_fraction >= 0.5 {
        AxisMotion::Held
    } else if held > 0 || rev > 0 {
        AxisMotion::Slipping
    } else {
        AxisMotion::Sliding
    };
    (motion, held_fraction, rev)
}

/// Root of `g` between two measured points by the Illinois variant of regula falsi on
/// log frequency; every evaluation is a measurement. Returns the last point measured.
fn refine_root(
    a: (f64, f64),
    b: (f64, f64),
    iterations: u32,
    eval: &mut dyn FnMut(f64) -> Option<(f64, f64, FreqPoint)>,
) -> Option<FreqPoint> {
    let (mut xa, mut ga) = (a.0.ln(), a.1);
    let (mut xb, mut gb) = (b.0.ln(), b.1);
    let mut last = None;
    let mut side = 0;
    for _ in 0..iterations {
        if gb == ga {
            break;
        }
        let x = (xa * gb - xb * ga) / (gb - ga);
        let (f, g, p) = eval(x.exp())?;
        let x = f.ln();
        last = Some(p);
        if g == 0.0 {
            break;
        }
        if (g > 0.0) == (gb > 0.0) {
            xb = x;
            gb = g;
            if side == -1 {
                ga /= 2.0;
            }
            side = -1;
        } else {
            xa = x;
            ga = g;
            if side == 1 {
                gb /= 2.0;
            }
            side = 1;
        }
    }
    last
}

/// Maximum of `h` near the best of three measured points by successive parabolic
/// interpolation on log frequency. Returns the points measured.
fn refine_peak(
    three: [(f64, f64); 3],
    iterations: u32,
    eval: &mut dyn FnMut(f64) -> Option<(f64, f64, FreqPoint)>,
) -> Vec<FreqPoint> {
    let mut pts: Vec<(f64, f64)> = three.iter().map(|(f, h)| (f.ln(), *h)).collect();
    let mut measured = Vec::new();
    for _ in 0..iterations {
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let [(x0, h0), (x1, h1), (x2, h2)] = [pts[0], pts[1], pts[2]];
        let den = (x1 - x0) * (h1 - h2) - (x1 - x2) * (h1 - h0);
        if den == 0.0 {
            break;
        }
        let x = x1 - 0.5 * ((x1 - x0).powi(2) * (h1 - h2) - (x1 - x2).powi(2) * (h1 - h0)) / den;
        if !(x > x0 && x < x2) || (x - x1).abs() < 1e-6 {
            break;
        }
        let Some((f, h, p)) = eval(x.exp()) else {
            break;
        };
        measured.push(p);
        pts.push((f.ln(), h));
        // Keep the best point and its nearest neighbour on each side.
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let best = (0..pts.len())
            .max_by(|&i, &j| pts[i].1.total_cmp(&pts[j].1))
            .unwrap_or(0);
        if best == 0 || best == pts.len() - 1 {
            break;
        }
        pts = vec![pts[best - 1], pts[best], pts[best + 1]];
    }
    measured
}

/// Measures `L` at a frequency and scores it: `(frequency measured, score, point)`.
type Probe<'a> = dyn FnMut(f64, &dyn Fn(Complex<f64>) -> f64, &mut Vec<FreqPoint>) -> Option<(f64, f64, FreqPoint)>
    + 'a;

fn s_of(l: Complex<f64>) -> Complex<f64> {
    (Complex::from(1.0) + l).inv()
}

fn t_of(l: Complex<f64>) -> Complex<f64> {
    l / (Complex::from(1.0) + l)
}

/// Margins from measured loop gains, ascending in frequency; `eval` measures `L` at a new
/// frequency (refinement) and returns `(frequency measured, point)`.
fn margins_of(
    points: &mut Vec<FreqPoint>,
    iterations: u32,
    eval: &mut dyn FnMut(f64) -> Option<FreqPoint>,
) -> EstimatedMargins {
    let grid: Vec<(f64, Complex<f64>)> = points
        .iter()
        .filter_map(|p| p.loop_gain.map(|l| (p.frequency_hz, l)))
        .collect();
    let mut m = EstimatedMargins::default();
    let mut extra: Vec<FreqPoint> = Vec::new();
    let mut with_l = |f: f64, g: &dyn Fn(Complex<f64>) -> f64, extra: &mut Vec<FreqPoint>| {
        let p = eval(f)?;
        let l = p.loop_gain?;
        let out = (p.frequency_hz, g(l), p.clone());
        extra.push(p);
        Some(out)
    };
    let mut pm: Option<(f64, f64)> = None;
    let mut gm_up: Option<(f64, f64)> = None;
    let mut gm_down: Option<f64> = None;
    for w in grid.windows(2) {
        let ((f0, l0), (f1, l1)) = (w[0], w[1]);
        let lg = |l: Complex<f64>| l.norm().ln();
        if lg(l0) * lg(l1) <= 0.0 && lg(l0) != lg(l1) {
            let found = refine_root((f0, lg(l0)), (f1, lg(l1)), iterations, &mut |f| {
                with_l(f, &lg, &mut extra)
            });
            let (f, l) = match found.and_then(|p| p.loop_gain.map(|l| (p.frequency_hz, l))) {
                Some(v) => v,
                // Linear interpolation of log |L| on log f, phase likewise, between the
                // closest measurements either side of the crossing.
                None => {
                    let ((f0, l0), (f1, l1)) = closest_bracket((f0, l0), (f1, l1), &extra, lg);
                    let s = lg(l0) / (lg(l0) - lg(l1));
                    let f = (f0.ln() + s * (f1.ln() - f0.ln())).exp();
                    let arg = l0.arg() + s * wrap(l1.arg() - l0.arg());
                    (f, Complex::from_polar(1.0, arg))
                }
            };
            let margin = 180.0 - l.arg().to_degrees().abs();
            if pm.is_none_or(|(m, _)| margin < m) {
                pm = Some((margin, f));
            }
        }
        let sn = |l: Complex<f64>| l.im / l.norm();
        if l0.im * l1.im <= 0.0 && (l0.re < 0.0 || l1.re < 0.0) && l0.im != l1.im {
            let found = refine_root((f0, sn(l0)), (f1, sn(l1)), iterations, &mut |f| {
                with_l(f, &sn, &mut extra)
            });
            let l = match found.and_then(|p| p.loop_gain) {
                Some(l) => Some((l, None)),
                None => {
                    let ((f0, l0), (f1, l1)) = closest_bracket((f0, l0), (f1, l1), &extra, sn);
                    // Without a measurement at the crossing, the chord between the two
                    // closest points says where the phase crosses the real axis: a chord crossing
                    // it right of the origin passes 0 deg (a sign change of the imaginary
                    // part through +-90 deg), which is no phase crossover at all.
                    let s = l0.im / (l0.im - l1.im);
                    let on_axis = l0.re + s * (l1.re - l0.re);
                    (on_axis < 0.0).then(|| {
                        let mag = (l0.norm().ln() + s * (l1.norm().ln() - l0.norm().ln())).exp();
                        let f = (f0.ln() + s * (f1.ln() - f0.ln())).exp();
                        (Complex::new(-mag, 0.0), Some(f))
                    })
                }
            };
            if let Some((l, f_interp)) = l {
                let f = f_interp.unwrap_or_else(|| extra.last().map_or(f0, |p| p.frequency_hz));
                if l.re < 0.0 {
                    let db = -20.0 * l.norm().log10();
                    if l.norm() < 1.0 {
                        if gm_up.is_none_or(|(m, _)| db < m) {
                            gm_up = Some((db, f));
                        }
                    } else if gm_down.is_none_or(|m| -db < m) {
                        gm_down = Some(-db);
                    }
                }
            }
        }
    }
    m.phase_margin_deg = pm.map(|p| p.0);
    m.crossover_hz = pm.map(|p| p.1);
    m.gain_margin_db = gm_up.map(|g| g.0);
    m.phase_crossover_hz = gm_up.map(|g| g.1);
    m.lower_gain_margin_db = gm_down;
    // Peaks of |S| and |T|, refined around the grid's best.
    let peak = |h: &dyn Fn(Complex<f64>) -> f64,
                extra: &mut Vec<FreqPoint>,
                with_l: &mut Probe<'_>|
     -> Option<(f64, f64)> {
        let best = (0..grid.len()).max_by(|&i, &j| h(grid[i].1).total_cmp(&h(grid[j].1)))?;
        let mut top = (grid[best].0, h(grid[best].1));
        if best > 0 && best + 1 < grid.len() {
            let three = [best - 1, best, best + 1].map(|i| (grid[i].0, h(grid[i].1)));
            for p in refine_peak(three, iterations, &mut |f| with_l(f, h, extra)) {
                if let Some(l) = p.loop_gain {
                    if h(l) > top.1 {
                        top = (p.frequency_hz, h(l));
                    }
                }
            }
        }
        Some(top)
    };
    let s_abs = |l: Complex<f64>| s_of(l).norm();
    let t_abs = |l: Complex<f64>| t_of(l).norm();
    if let Some((f, ms)) = peak(&s_abs, &mut extra, &mut with_l) {
        m.ms = Some(ms);
        m.ms_hz = Some(f);
    }
    m.mt = peak(&t_abs, &mut extra, &mut with_l).map(|p| p.1);
    let half = std::f64::consts::FRAC_1_SQRT_2;
    let tb = |l: Complex<f64>| t_of(l).norm().ln() - half.ln();
    m.bandwidth_hz = grid
        .windows(2)
        .find(|w| tb(w[0].1) >= 0.0 && tb(w[1].1) < 0.0)
        .map(|w| {
            let ((f0, l0), (f1, l1)) = (w[0], w[1]);
            refine_root((f0, tb(l0)), (f1, tb(l1)), iterations, &mut |f| {
                with_l(f, &tb, &mut extra)
            })
            .map(|p| p.frequency_hz)
            .unwrap_or_else(|| {
                let s = tb(l0) / (tb(l0) - tb(l1));
                (f0.ln() + s * (f1.ln() - f0.ln())).exp()
            })
        });
    points.extend(extra);
    points.sort_by(|a, b| a.frequency_hz.total_cmp(&b.frequency_hz));
    m
}

/// The closest pair of loop gains `(f, L)` either side of a sign change of `g` between
/// the bracket `a`..`b`, from the bracket and the measurements a refinement made inside
/// it (`extra`; a refinement that failed midway still narrowed the bracket, and the
/// bracket's chord alone can put the crossing on the wrong side of the origin).
fn closest_bracket(
    a: (f64, Complex<f64>),
    b: (f64, Complex<f64>),
    extra: &[FreqPoint],
    g: impl Fn(Complex<f64>) -> f64,
) -> ((f64, Complex<f64>), (f64, Complex<f64>)) {
    let (lo, hi) = if a.0 <= b.0 { (a, b) } else { (b, a) };
    let mut inside: Vec<(f64, Complex<f64>)> = extra
        .iter()
        .filter(|p| p.frequency_hz > lo.0 && p.frequency_hz < hi.0)
        .filter_map(|p| p.loop_gain.map(|l| (p.frequency_hz, l)))
        .collect();
    inside.push(lo);
    inside.push(hi);
    inside.sort_by(|x, y| x.0.total_cmp(&y.0));
    inside
        .windows(2)
        .find(|w| g(w[0].1) * g(w[1].1) <= 0.0 && g(w[0].1) != g(w[1].1))
        .map_or((lo, hi), |w| (w[0], w[1]))
}

fn wrap(a: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    (a + std::f64::consts::PI).rem_euclid(tau) - std::f64::consts::PI
}

/// Measures the frequency response of `setup`'s loop as `spec` says: frequencies and
/// amplitudes in parallel on `threads` workers (0 = all cores), then the margins of each
/// amplitude refined one measurement at a time. `progress` is called after each
/// measurement of the grid.
pub fn measure(
    setup: ClosedLoopSetup<'_>,
    spec: &FreqRespParams,
    threads: usize,
    progress: &(dyn Fn() + Sync),
) -> Result<FreqResponse, FreqRespError> {
    let p = setup.params;
    spec.validate(p)?;
    let mut freqs = spec.frequencies(p.controller.sample_rate_hz)?;
    let required = base_requirement(spec.point, &p.requirements);
    // The required frequency is measured itself, so the verdict reads no interpolation
    // across a wide step of the grid.
    if let Some((f, _)) = required {
        if !freqs.iter().any(|&g| (g / f - 1.0).abs() < 1e-9) {
            freqs.push(f);
            freqs.sort_by(f64::total_cmp);
        }
    }
    let amps = spec.amplitudes(p.motor.command_limit())?;
    let free = ClosedLoopParams::half_stiffness_n_per_m(setup.drive);
    let k = match spec.reference_load_nm {
        None => free,
        Some(m) => super::linear::tangent_half_stiffness(setup.drive, m)
            .map_err(|message| invalid("reference_load_nm", message))?,
    };
    let reference_cable = ReferenceCable {
        load_nm: spec.reference_load_nm,
        half_stiffness_n_per_m: k,
        free_span_half_stiffness_n_per_m: free,
    };
    let lin = LinearLoop::with_half_stiffness(p, setup.drive, k);
    let plan = operating_plan(&setup, spec, &lin)?;
    let friction = !holding_friction(&setup).is_empty();
    let bench = Bench {
        setup,
        spec,
        lin,
        friction,
        drum_friction: setup.load.breakaway_nm() > 0.0
            || setup.effects.is_some_and(|e| e.bearing_friction() > 0.0),
        motor_friction: p.motor.coulomb_nm > 0.0,
    };
    let slews = plan.slew_rates_rad_s.clone();
    let exact = bench.lin.margins(4000);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| FreqRespError::Threads(e.to_string()))?;
    let jobs: Vec<(usize, f64)> = (0..amps.len())
        .flat_map(|a| freqs.iter().map(move |&f| (a, f)))
        .collect();
    let measured: Vec<Result<(usize, FreqPoint, f64), FreqRespError>> = pool.install(|| {
        jobs.par_iter()
            .map(|&(a, f)| {
                let r = bench
                    .measure(f, amps[a], slews[a], false)
                    .map(|(pt, s)| (a, pt, s));
                progress();
                r
            })
            .collect()
    });
    let mut runs = 0;
    let mut simulated_s = 0.0;
    let mut per_amp: Vec<Vec<FreqPoint>> = vec![Vec::new(); amps.len()];
    for r in measured {
        let (a, pt, s) = r?;
        runs += 1;
        simulated_s += s;
        per_amp[a].push(pt);
    }
    let voltage = p.motor.amplifier == crate::closed_loop::params::Amplifier::Voltage;
    let unit = spec.point.amplitude_unit(voltage).to_string();
    let refined: Vec<Result<(AmplitudeResponse, usize, f64), FreqRespError>> = pool.install(|| {
        per_amp
            .into_par_iter()
            .zip(amps.par_iter())
            .zip(slews.par_iter())
            .map(|((mut points, &amp), &slew)| {
                let mut extra_runs = 0;
                let mut extra_s = 0.0;
                let mut error = None;
                let margins = spec.point.gives_loop_gain().then(|| {
                    margins_of(&mut points, spec.refine_iterations, &mut |f| match bench
                        .measure(f, amp, slew, true)
                    {
                        Ok((pt, s)) => {
                            extra_runs += 1;
                            extra_s += s;
                            pt.failure.is_none().then_some(pt)
                        }
                        Err(e) => {
                            error = Some(e);
                            None
                        }
                    })
                });
                if let Some(e) = error {
                    return Err(e);
                }
                let mut shortfalls = shortfalls(&p.requirements, &points, margins.as_ref());
                let base_rejection = required.map(|(f, min_db)| RejectionCheck {
                    frequency_hz: f,
                    rejection_db: rejection_at(&points, f),
                    reference_rejection_db: rejection_db(bench.lin.base_to_los(f)),
                    min_rejection_db: min_db,
                });
                shortfalls.extend(base_rejection.as_ref().and_then(RejectionCheck::shortfall));
                let mut unresolved = failure_groups(
                    &points,
                    FreqPoint::unresolved,
                    "unresolved (left out of the estimate, not failing)",
                );
                // A margin the exact reference has and this amplitude's measurements do not:
                // its crossover lies among frequencies left out, so it was not measured, and
                // the table's dash must not read as "no crossover".
                if let Some(m) = margins.as_ref().filter(|_| points.iter().any(FreqPoint::unresolved)) {
                    for (what, measured, f) in [
                        ("gain margin", m.gain_margin_db, exact.phase_crossover_hz),
                        ("downward gain margin", m.lower_gain_margin_db, exact.lower_phase_crossover_hz),
                    ] {
                        if let (None, Some(f)) = (measured, f) {
                            unresolved.push(format!(
                                "{what} not measured: the exact reference crosses -180 deg at {} Hz, where this amplitude's measurements are left out",
                                crate::significant(f, 4)
                            ));
                        }
                    }
                }
                Ok((
                    AmplitudeResponse {
                        amplitude: amp,
                        unit: unit.clone(),
                        slew_rate_rad_s: slew,
                        axis: points.iter().filter_map(|p| p.axis).max(),
                        axis_frequencies: AxisCounts::of(&points),
                        points,
                        unresolved,
                        margins,
                        shortfalls,
                        base_rejection,
                    },
                    extra_runs,
                    extra_s,
                ))
            })
            .collect()
    });
    let mut amplitudes = Vec::new();
    for r in refined {
        let (a, n, s) = r?;
        runs += n;
        simulated_s += s;
        amplitudes.push(a);
    }
    let limit_cycles = (spec.point == LoopPoint::Plant).then(|| predict_limit_cycles(&amplitudes));
    Ok(FreqResponse {
        point: spec.point,
        transfer: spec.point.transfer().to_string(),
        operating: plan,
        limit_cycles,
        amplitudes,
        exact_margins: exact,
        reference_cable,
        runs,
        simulated_s,
    })
}

/// The points `pick` chooses among those with a failure, grouped by their reason, each
/// group with its frequencies, so the console says which and why without the CSV;
/// `verb` says what happened to them ("failed", "unresolved").
fn failure_groups(
    points: &[FreqPoint],
    pick: impl Fn(&FreqPoint) -> bool,
    verb: &str,
) -> Vec<String> {
    let mut out = Vec::new();
    let mut groups: Vec<(&str, Vec<f64>, Vec<f64>)> = Vec::new();
    for p in points.iter().filter(|p| pick(p)) {
        if let Some(why) = p.failure.as_deref() {
            let u: Vec<f64> = p.uncertainty_percent.into_iter().collect();
            match groups.iter_mut().find(|g| g.0 == why) {
                Some(g) => {
                    g.1.push(p.frequency_hz);
                    g.2.extend(u);
                }
                None => groups.push((why, vec![p.frequency_hz], u)),
            }
        }
    }
    for (why, f, u) in &groups {
        const SHOWN: usize = 8;
        let mut list: Vec<String> = f
            .iter()
            .take(SHOWN)
            .map(|f| crate::significant(*f, 4))
            .collect();
        if f.len() > SHOWN {
            list.push(format!("and {} more", f.len() - SHOWN));
        }
        let spread = if u.is_empty() {
            String::new()
        } else {
            let (lo, hi) = u.iter().fold((f64::INFINITY, 0.0_f64), |(lo, hi), v| {
                (lo.min(*v), hi.max(*v))
            });
            format!(" (uncertainty {lo:.0} to {hi:.0} %)")
        };
        out.push(format!(
            "{} of {} frequencies {verb}, at {} Hz: {why}{spread}",
            f.len(),
            points.len(),
            list.join(", ")
        ));
    }
    out
}

fn shortfalls(
    req: &crate::closed_loop::Requirements,
    points: &[FreqPoint],
    margins: Option<&EstimatedMargins>,
) -> Vec<String> {
    // A point the measurement could not resolve is named apart, not failing.
    let mut out = failure_groups(points, FreqPoint::stopped, "failed");
    let Some(m) = margins else {
        return out;
    };
    match m.phase_margin_deg {
        Some(pm) if pm >= req.min_phase_margin_deg => {}
        Some(pm) => out.push(format!(
            "phase margin {pm:.1} deg < closed_loop.requirements.min_phase_margin_deg = {} deg",
            req.min_phase_margin_deg
        )),
        None => {
            out.push("no gain crossover inside the measured frequencies: no phase margin".into())
        }
    }
    for (name, gm) in [
        ("gain margin", m.gain_margin_db),
        ("downward gain margin", m.lower_gain_margin_db),
    ] {
        if let Some(gm) = gm {
            if gm < req.min_gain_margin_db {
                out.push(format!(
                    "{name} {gm:.2} dB < closed_loop.requirements.min_gain_margin_db = {} dB",
                    req.min_gain_margin_db
                ));
            }
        }
    }
    if let Some(ms) = m.ms {
        if ms > req.max_ms {
            out.push(format!(
                "sensitivity peak Ms {ms:.3} > closed_loop.requirements.max_ms = {}",
                req.max_ms
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coefficient_of_a_sampled_sinusoid_is_exact_over_whole_periods() {
        let (n, cycles) = (37usize, 5.0);
        let x: Vec<f64> = (0..n)
            .map(|k| 0.7 * (std::f64::consts::TAU * cycles * k as f64 / n as f64 + 0.3).sin() + 2.0)
            .collect();
        let c = coefficient(&x, cycles);
        assert!((c.norm() - 0.7).abs() < 1e-12, "{c}");
        // sin(w t + 0.3) = cos(w t + 0.3 - pi/2)
        assert!((c.arg() - (0.3 - std::f64::consts::FRAC_PI_2)).abs() < 1e-12);
    }

    #[test]
    fn noise_floor_sees_what_the_injection_does_not_explain() {
        let n = 4000usize;
        let tau = std::f64::consts::TAU;
        // Fundamental at 8 cycles, harmonics, an offset: no noise near the fundamental.
        let clean: Vec<f64> = (0..n)
            .map(|k| {
                let x = tau * k as f64 / n as f64;
                (8.0 * x).sin() + 0.5 * (16.0 * x).cos() + 3.0
            })
            .collect();
        assert!(noise_floor(&clean, 8) < 1e-12);
        // A tone of 0.1 in the next bin: RMS over the four neighbours is 0.1 / 2.
        let noisy: Vec<f64> = clean
            .iter()
            .enumerate()
            .map(|(k, v)| v + 0.1 * (tau * 9.0 * k as f64 / n as f64).sin())
            .collect();
        assert!((noise_floor(&noisy, 8) - 0.05).abs() < 1e-12);
    }

    #[test]
    fn window_snaps_to_whole_periods_in_whole_samples() {
        let spec = FreqRespParams::default();
        for f in [0.37, 3.1, 97.0, 3700.0] {
            let w = window(&spec, f, 5e-5);
            let periods = w.frequency_hz * w.samples as f64 * 5e-5;
            assert!((periods - w.cycles as f64).abs() < 1e-9, "{f}");
            assert!((w.frequency_hz / f - 1.0).abs() < 1.0 / f64::from(spec.min_samples) + 1e-12);
            assert!(w.samples >= u64::from(spec.min_samples));
        }
    }

    fn measured(f: f64, l: Complex<f64>) -> FreqPoint {
        FreqPoint {
            response: Some(l),
            loop_gain: Some(l),
            ..FreqPoint::unmeasured(f, f, l, false)
        }
    }

    #[test]
    fn a_phase_passing_zero_between_two_points_is_no_phase_crossover() {
        let deg = |d: f64| d.to_radians();
        // -111 deg at -17 dB, then +48 deg at -20.6 dB: the imaginary part changes sign
        // through 0 deg. With no measurement between them (the refinement fails), no
        // gain margin may be made up from the chord.
        let mut points = vec![
            measured(40.58, Complex::from_polar(0.141, deg(-111.0))),
            measured(45.66, Complex::from_polar(0.093, deg(48.0))),
        ];
        let m = margins_of(&mut points, 4, &mut |_| None);
        assert_eq!(m.gain_margin_db, None, "{m:?}");
        assert_eq!(m.phase_crossover_hz, None, "{m:?}");
        // The same sign change through -180 deg is a phase crossover at about -18.7 dB.
        let mut points = vec![
            measured(40.58, Complex::from_polar(0.141, deg(-170.0))),
            measured(45.66, Complex::from_polar(0.093, deg(175.0))),
        ];
        let m = margins_of(&mut points, 4, &mut |_| None);
        let gm = m.gain_margin_db.expect("a crossing through -180 deg");
        assert!((17.0..20.6).contains(&gm), "{gm}");
        let f = m.phase_crossover_hz.unwrap_or(0.0);
        assert!((40.58..45.66).contains(&f), "{f}");
        // A bracket whose chord passes just left of the origin (-126.8 deg at -5.1 dB,
        // +58.6 deg at -10.0 dB), with a refinement that measured -110.9 deg and
        // +47.6 deg inside it and then failed: the closest measurements decide, and the
        // phase passes 0 deg, so there is no crossover (the chord alone made one up at
        // 43.1 Hz, 8.19 dB).
        let mut points = vec![
            measured(32.85, Complex::from_polar(0.554, deg(-126.8))),
            measured(50.85, Complex::from_polar(0.315, deg(58.55))),
        ];
        let mut inside = vec![
            measured(40.58, Complex::from_polar(0.1415, deg(-110.85))),
            measured(45.66, Complex::from_polar(0.0930, deg(47.6))),
        ]
        .into_iter();
        let m = margins_of(&mut points, 4, &mut |_| inside.next());
        assert_eq!(m.gain_margin_db, None, "{m:?}");
    }

    #[test]
    fn an_unresolved_frequency_is_named_apart_and_a_stopped_one_fails() {
        let mut quiet = measured(3.7, Complex::from(0.5));
        quiet.response = None;
        quiet.loop_gain = None;
        quiet.failure = Some("no response at the injected frequency".into());
        let mut noisy = measured(2585.0, Complex::from(0.1));
        noisy.uncertainty_percent = Some(40.0);
        noisy.failure = Some("uncertain by more than 10 %".into());
        let mut slipped = measured(5.0, Complex::from(0.5));
        slipped.response = None;
        slipped.loop_gain = None;
        slipped.failure = Some("gross slip on the pulley".into());
        let ok = measured(26.0, Complex::from_polar(1.0, -2.4));
        let req = crate::closed_loop::Requirements::default();
        let points = vec![quiet.clone(), ok.clone(), noisy.clone()];
        assert!(quiet.unresolved() && noisy.unresolved() && !slipped.unresolved());
        assert!(shortfalls(&req, &points, None).is_empty());
        let named = failure_groups(&points, FreqPoint::unresolved, "unresolved");
        assert_eq!(named.len(), 2, "{named:?}");
        assert!(named[0].starts_with("1 of 3 frequencies unresolved, at 3.700 Hz: no response"));
        let points = vec![quiet, ok, slipped];
        let short = shortfalls(&req, &points, None);
        assert_eq!(short.len(), 1, "{short:?}");
        assert!(
            short[0].contains("failed, at 5.000 Hz: gross slip"),
            "{short:?}"
        );
    }

    #[test]
    fn illinois_finds_a_root_of_a_smooth_function() {
        let g = |f: f64| (f / 26.3).ln() * 3.0 + (f / 26.3 - 1.0).powi(2);
        let mut eval = |f: f64| {
            let p = FreqPoint::unmeasured(f, f, Complex::from(0.0), true);
            Some((f, g(f), p))
        };
        let p = refine_root((10.0, g(10.0)), (50.0, g(50.0)), 12, &mut eval).unwrap();
        assert!(
            (p.frequency_hz / 26.3 - 1.0).abs() < 1e-9,
            "{}",
            p.frequency_hz
        );
    }
}
