//! Quasi-static studies: prescribed input motion and load, no inertia.
//!
//! The drive is stepped through the load history sample by sample; each step solves both
//! span tensions from equilibrium and the length constraint and commits the wrap memory.

use serde::{Deserialize, Serialize};

use crate::physics::{CableDrive, DriveFault, DriveParams, Half, HysteresisModel, LoadParams};
use crate::signal::Signal;

/// Prescribed-motion quasi-static study.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QuasiStaticParams {
    /// Simulated time, s (20 for two periods of the bench's 0.1 Hz sine).
    /// Allowed: > 0 and at most 1e6; `duration_s` x `sample_rate_hz` at most 2e6 samples.
    pub duration_s: f64,
    /// Samples per second, Hz (200 is plenty at 0.1 Hz).
    /// Allowed: > 0; at least 10 samples per period of the motion and of the load's sine;
    /// `duration_s` x `sample_rate_hz` at most 2e6 samples.
    #[serde(default = "default_qs_rate")]
    pub sample_rate_hz: f64,
    /// Input (motor pulley) angle against time.
    pub motion: Signal,
    /// Models to run side by side.
    /// Allowed: at least one of `"memory"`, `"memoryless"`.
    #[serde(default = "default_models")]
    pub models: Vec<HysteresisModel>,
    /// Instants at which tension profiles along the wraps are recorded and plotted, s.
    /// Allowed: each within 0 to `duration_s`.
    #[serde(default)]
    pub profile_times_s: Vec<f64>,
}

fn default_qs_rate() -> f64 {
    200.0
}

fn default_models() -> Vec<HysteresisModel> {
    vec![HysteresisModel::Memory, HysteresisModel::Memoryless]
}

/// Backlash protocol parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BacklashParams {
    /// Magnitude of the transmitted torque `M`, N m (0.72 on the bench).
    /// Allowed: > 0 and at most 1e6.
    pub load_nm: f64,
    /// History model.
    #[serde(default)]
    pub model: HysteresisModel,
}

/// One quasi-static sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct QsSample {
    /// Time, s.
    pub t_s: f64,
    /// Input (motor pulley) angle, rad.
    pub theta_in_rad: f64,
    /// Output (drum) angle, rad.
    pub theta_out_rad: f64,
    /// Torque the load applies to the drum `Ml`, N m.
    pub load_nm: f64,
    /// Torque the cable transmits `M = -Ml`, N m.
    pub torque_nm: f64,
    /// Upper span tension, N.
    pub tension_upper_n: f64,
    /// Lower span tension, N.
    pub tension_lower_n: f64,
    /// Transmission error `theta_out - theta_in/ic`, rad.
    pub transmission_error_rad: f64,
    /// Slip-zone lengths `[upper drum, upper pulley, lower drum, lower pulley]`, rad.
    pub slip_angles_rad: [f64; 4],
}

/// Tension profile of one wrap region at one instant: exact breakpoints `(s rad, T N)`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ProfileSnapshot {
    /// Instant, s.
    pub t_s: f64,
    /// Region: `upper_drum`, `upper_pulley`, `lower_drum`, `lower_pulley`.
    pub region: &'static str,
    /// Breakpoints from the contact point inward.
    pub breakpoints: Vec<(f64, f64)>,
    /// Elongation of this wrap region relative to the preloaded state, m.
    pub elongation_m: f64,
}

/// Where a run stopped early.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stop {
    /// Time of the failed step, s.
    pub t_s: f64,
    /// What happened.
    pub fault: DriveFault,
}

/// Result of one model over the whole motion.
#[derive(Clone, Debug, PartialEq)]
pub struct QsTrace {
    /// History model.
    pub model: HysteresisModel,
    /// Samples up to the end or up to the stop.
    pub samples: Vec<QsSample>,
    /// Tension profiles at the requested instants.
    pub profiles: Vec<ProfileSnapshot>,
    /// Set when the drive left its capacity; the samples end there.
    pub stop: Option<Stop>,
    /// Largest number of breakpoints held by any half's wrap profile (memory depth).
    pub max_breakpoints: usize,
    /// First time a drum slip zone reached its anchor (the profile is cut there; the run
    /// goes on), s, and which half.
    pub anchor_reached: Option<(f64, Half)>,
}

/// Key figures of a trace.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct QsFigures {
    /// Model name.
    pub model: String,
    /// Largest transmission-error magnitude, mrad.
    pub peak_error_mrad: f64,
    /// Peak-to-peak transmission error, mrad.
    pub peak_to_peak_error_mrad: f64,
    /// RMS transmission error, mrad.
    pub rms_error_mrad: f64,
    /// Largest jump of the transmission error between consecutive samples, mrad
    /// (the backlash at load reversals).
    pub largest_jump_mrad: f64,
    /// Tension range seen, N.
    pub tension_min_n: f64,
    /// Tension range seen, N.
    pub tension_max_n: f64,
    /// Deepest memory (breakpoints in one wrap profile).
    pub max_breakpoints: usize,
    /// First time a drum slip zone reached its anchor, s (`null` if never).
    pub anchor_reached_at_s: Option<f64>,
    /// Which half reached its anchor first.
    pub anchor_half: Option<Half>,
    /// Whether the run reached its end.
    pub complete: bool,
}

impl QsTrace {
    /// Key figures (empty traces give zeros and `complete = false`).
    pub fn figures(&self) -> QsFigures {
        let e: Vec<f64> = self
            .samples
            .iter()
            .map(|s| s.transmission_error_rad * 1e3)
            .collect();
        let n = e.len().max(1) as f64;
        let max = e.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = e.iter().copied().fold(f64::INFINITY, f64::min);
        let jump = e
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(0.0, f64::max);
        let (tmin, tmax) = self.samples.iter().fold((f64::INFINITY, 0.0f64), |a, s| {
            (
                a.0.min(s.tension_upper_n).min(s.tension_lower_n),
                a.1.max(s.tension_upper_n).max(s.tension_lower_n),
            )
        });
        let empty = e.is_empty();
        QsFigures {
            model: model_name(self.model).to_string(),
            peak_error_mrad: if empty { 0.0 } else { max.abs().max(min.abs()) },
            peak_to_peak_error_mrad: if empty { 0.0 } else { max - min },
            rms_error_mrad: (e.iter().map(|x| x * x).sum::<f64>() / n).sqrt(),
            largest_jump_mrad: jump,
            tension_min_n: if empty { 0.0 } else { tmin },
            tension_max_n: tmax,
            max_breakpoints: self.max_breakpoints,
            anchor_reached_at_s: self.anchor_reached.map(|a| a.0),
            anchor_half: self.anchor_reached.map(|a| a.1),
            complete: self.stop.is_none() && !empty,
        }
    }
}

/// Name of a model as used in files.
pub fn model_name(model: HysteresisModel) -> &'static str {
    match model {
        HysteresisModel::Memory => "memory",
        HysteresisModel::Memoryless => "memoryless",
    }
}

/// Run the prescribed-motion study for one model.
///
/// The brake acts against the drum's direction of motion, taken as the direction of the
/// input motion (the error is tiny next to the motion); at rest the last direction holds,
/// as a powder brake keeps its last torque until driven the other way.
pub fn run_model(
    drive_params: &DriveParams,
    load: &LoadParams,
    study: &QuasiStaticParams,
    model: HysteresisModel,
) -> QsTrace {
    let mut drive = CableDrive::new(drive_params.clone(), model);
    let ic = drive_params.ratio();
    let n = (study.duration_s * study.sample_rate_hz).round().max(1.0) as usize;
    let dt = study.duration_s / n as f64;
    let mut samples = Vec::with_capacity(n + 1);
    let mut profiles = Vec::new();
    let mut pending: Vec<f64> = study.profile_times_s.clone();
    pending.sort_by(f64::total_cmp);
    let mut next_profile = 0;
    let mut direction = 0.0;
    let mut error = 0.0;
    let mut max_breakpoints = 0;
    let mut stop = None;
    let mut anchor_reached = None;
    for k in 0..=n {
        let t = k as f64 * dt;
        let motion = study.motion.at(t);
        if motion.rate > 0.0 {
            direction = 1.0;
        } else if motion.rate < 0.0 {
            direction = -1.0;
        }
        let theta_in = motion.value;
        // Angle-dependent loads use the output angle of the previous step: quasi-static, the
        // error changes by far less than the angle resolution of any load model.
        let theta_out_guess = theta_in / ic + error;
        let load_nm = load.quasi_static_torque_nm(t, theta_out_guess, direction);
        let torque = -load_nm;
        match drive.apply_torque(torque) {
            Ok(state) => {
                error = state.transmission_error_rad;
                if anchor_reached.is_none() {
                    if state.anchor_reached[0] {
                        anchor_reached = Some((t, Half::Upper));
                    } else if state.anchor_reached[1] {
                        anchor_reached = Some((t, Half::Lower));
                    }
                }
                samples.push(QsSample {
                    t_s: t,
                    theta_in_rad: theta_in,
                    theta_out_rad: theta_in / ic + error,
                    load_nm,
                    torque_nm: torque,
                    tension_upper_n: state.tension_upper_n,
                    tension_lower_n: state.tension_lower_n,
                    transmission_error_rad: error,
                    slip_angles_rad: drive.slip_angles_rad(&state),
                });
                max_breakpoints = max_breakpoints
                    .max(drive.upper().wrap().breakpoint_count())
                    .max(drive.lower().wrap().breakpoint_count());
            }
            Err(fault) => {
                stop = Some(Stop { t_s: t, fault });
                break;
            }
        }
        while next_profile < pending.len() && pending[next_profile] <= t + 0.5 * dt {
            profiles.extend(snapshot(&drive, t));
            next_profile += 1;
        }
    }
    QsTrace {
        model,
        samples,
        profiles,
        stop,
        max_breakpoints,
        anchor_reached,
    }
}

/// Tension profiles and elongations of all four wrap regions.
pub fn snapshot(drive: &CableDrive, t_s: f64) -> Vec<ProfileSnapshot> {
    let state = drive.state();
    let (_, ud, up) = drive.upper().region_elongations_m(state.tension_upper_n);
    let (_, ld, lp) = drive.lower().region_elongations_m(state.tension_lower_n);
    [
        (
            "upper_drum",
            drive.upper().drum_breakpoints(state.tension_upper_n),
            ud,
        ),
        (
            "upper_pulley",
            drive.upper().pulley_breakpoints(state.tension_upper_n),
            up,
        ),
        (
            "lower_drum",
            drive.lower().drum_breakpoints(state.tension_lower_n),
            ld,
        ),
        (
            "lower_pulley",
            drive.lower().pulley_breakpoints(state.tension_lower_n),
            lp,
        ),
    ]
    .into_iter()
    .map(|(region, breakpoints, elongation_m)| ProfileSnapshot {
        t_s,
        region,
        breakpoints,
        elongation_m,
    })
    .collect()
}

/// Operating regime of a backlash case.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Regime {
    /// All states reachable.
    Ok,
    /// A span goes slack.
    Slack,
    /// The cable slides around the pulley.
    GrossSlip,
}

impl Regime {
    /// Every regime, for readers that check a regime column against the names it may hold.
    pub const ALL: [Regime; 3] = [Regime::Ok, Regime::Slack, Regime::GrossSlip];

    /// Name as written in tables.
    pub fn as_str(self) -> &'static str {
        match self {
            Regime::Ok => "ok",
            Regime::Slack => "slack",
            Regime::GrossSlip => "gross_slip",
        }
    }
}

/// Result of the `+M, -M, +M` protocol.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BacklashResult {
    /// Regime; figures are `None` unless `Ok`.
    pub regime: Regime,
    /// Transmission-error magnitude after the first `+M`, mrad.
    pub initial_mrad: Option<f64>,
    /// Change of transmission error from `+M` to `-M` (first reversal), mrad.
    pub first_reversal_mrad: Option<f64>,
    /// Change of transmission error from `-M` back to `+M`, mrad (the Fig. 11 figure).
    pub reversal_mrad: Option<f64>,
    /// Upper span tension after the first `+M`, N.
    pub tension_upper_n: Option<f64>,
    /// Whether a drum slip zone reached its anchor during the protocol.
    pub anchor_reached: bool,
    /// The fault, when not `Ok`.
    pub fault: Option<String>,
}

/// Apply `+M`, `-M`, `+M` to a preloaded drive.
pub fn backlash(drive_params: &DriveParams, params: &BacklashParams) -> BacklashResult {
    let mut drive = CableDrive::new(drive_params.clone(), params.model);
    let m = params.load_nm;
    let run = (|| {
        let first = drive.apply_torque(m)?;
        let back = drive.apply_torque(-m)?;
        let again = drive.apply_torque(m)?;
        Ok::<_, DriveFault>((first, back, again))
    })();
    match run {
        Ok((first, back, again)) => BacklashResult {
            regime: Regime::Ok,
            initial_mrad: Some(first.transmission_error_rad.abs() * 1e3),
            first_reversal_mrad: Some(
                (back.transmission_error_rad - first.transmission_error_rad).abs() * 1e3,
            ),
            reversal_mrad: Some(
                (back.transmission_error_rad - again.transmission_error_rad).abs() * 1e3,
            ),
            tension_upper_n: Some(first.tension_upper_n),
            anchor_reached: [first, back, again]
                .iter()
                .any(|s| s.anchor_reached.iter().any(|&a| a)),
            fault: None,
        },
        Err(fault) => BacklashResult {
            regime: match fault {
                DriveFault::Slack { .. } => Regime::Slack,
                DriveFault::GrossSlip { .. } => Regime::GrossSlip,
            },
            initial_mrad: None,
            first_reversal_mrad: None,
            reversal_mrad: None,
            tension_upper_n: None,
            anchor_reached: false,
            fault: Some(fault.to_string()),
        },
    }
}
