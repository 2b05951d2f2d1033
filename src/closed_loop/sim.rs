//! The sample-and-hold loop: plant integrated over each control period with the command
//! held, the integrator restarted at every sample, memory committed at period boundaries.

use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::base::BaseMotion;
use super::controller::{BrakePredictor, CommandDelay, Compensator, Sensors};
use super::law::{ControlLaw, GyroReader, LawInputs};
use super::params::{Amplifier, ClosedLoopParams, CompensationMode, Feedback};
use super::period::{integrate_period, settle_boundary};
use super::plant::{
    load_torque, BaseSegment, BrakeState, PlantCable, PlantCoefficients, State, CURRENT, GYRO,
    OMEGA_M, OMEGA_O, THETA_M, THETA_O,
};
use super::reference::{ReferenceCache, SampledReference};
use crate::metrics::limit_cycle::{Forcing, LimitCycle, LimitCycleDetector};
use crate::metrics::los::{error_spectrum, los_metrics, ErrorSpectrum, LosMetrics};
use crate::metrics::{Metrics, MetricsAccumulator, MetricsConfig, Sample, StepEvent};
use crate::physics::{
    ContactMemory, DriveFault, DriveParams, EffectsParams, Half, LoadParams, LoadTerm,
};
use crate::signal::Signal;

/// What to keep from a run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOptions {
    /// Keep the time series (false for sweeps: metrics only, no per-sample storage).
    pub record: bool,
    /// Keep every n-th sample of the series (1 = all); metrics always use every sample.
    pub decimation: usize,
    /// Run only these modes (those of the scenario that are listed here); `None` = all.
    pub modes: Option<Vec<CompensationMode>>,
    /// A sinusoid added inside the loop (frequency-response measurement); `None` in
    /// every ordinary run.
    pub injection: Option<Injection>,
    /// Keep the line of sight's errors for [`ModeResult::los`] (jitter over exposure
    /// windows) and, when recording, [`ModeResult::spectrum`]. True by default. Callers
    /// that read neither turn it off (a sweep case, whose table holds no jitter; a
    /// frequency-response run): the errors then cost no buffer and no windows, and
    /// `los` and `spectrum` are `None`. A scenario whose requirements judge jitter keeps
    /// `los` whatever this says, so its verdict is the same either way.
    pub line_of_sight: bool,
}

/// Where an injected sinusoid enters the sampled loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InjectionSite {
    /// Added to the controller's command before the computation delay and the hold (A or
    /// V), clipped to the amplifier's limit with it.
    Command,
    /// Added to the measurement the controller reads (motor rad: `ic` times the output
    /// angle under output feedback).
    Measurement,
}

/// `amplitude * sin(2 pi f t_k + phase)` added at `site` at every sample `t_k`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Injection {
    /// Where it enters.
    pub site: InjectionSite,
    /// Amplitude in the site's unit (A or V at the command, motor rad at the measurement).
    pub amplitude: f64,
    /// Frequency, Hz (below Nyquist).
    pub frequency_hz: f64,
    /// Phase at `t = 0`, rad (0: a sine from rest; pi/2: a cosine, which drives a free
    /// inertia from rest without a mean drift).
    pub phase_rad: f64,
}

impl Injection {
    /// The injected value at `t_s`.
    pub fn at(&self, t_s: f64) -> f64 {
        self.amplitude * (std::f64::consts::TAU * self.frequency_hz * t_s + self.phase_rad).sin()
    }
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            record: true,
            decimation: 1,
            modes: None,
            injection: None,
            line_of_sight: true,
        }
    }
}

impl RunOptions {
    /// Metrics only (no time series), every mode, the line of sight kept.
    pub fn metrics_only() -> Self {
        RunOptions {
            record: false,
            ..RunOptions::default()
        }
    }

    /// Whether a run of `p` keeps the line of sight's errors (see [`Self::line_of_sight`]).
    fn keeps_line_of_sight(&self, p: &ClosedLoopParams) -> bool {
        self.line_of_sight || p.requirements.max_jitter_mrad.is_some()
    }
}

/// Why a closed-loop run could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClosedLoopError {
    /// The scenario is not a closed-loop study.
    #[error("scenario study is {study}: a closed-loop run needs study = \"closed_loop\" and a [closed_loop] section")]
    NotClosedLoop {
        /// The scenario's study, as named in its file.
        study: String,
    },
    /// A parameter out of range or inconsistent.
    #[error("{key}: {message}")]
    Invalid {
        /// Dotted scenario key.
        key: String,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// A CSV table named in the scenario has not been loaded.
    #[error("{key}: the table {path} holds no samples; load it with io::tables::load_tables before running")]
    TableNotLoaded {
        /// Dotted scenario key.
        key: String,
        /// File named in the scenario.
        path: String,
    },
    /// The mode filter leaves nothing to run.
    #[error("none of the requested modes {requested} is listed in closed_loop.modes")]
    NoModes {
        /// The filter.
        requested: String,
    },
    /// The run would compute for longer than a run may.
    #[error("the run would compute for about {} ({what}), more than the {} a run may take: {remedy}", crate::duration_words(*.estimate_s), crate::duration_words(*.limit_s))]
    TooLong {
        /// Estimated wall time, s.
        estimate_s: f64,
        /// The limit, s.
        limit_s: f64,
        /// What takes the time.
        what: String,
        /// Which settings shorten it.
        remedy: String,
    },
    /// The run would hold more in memory than a run may.
    #[error("the run would hold about {estimate_mb:.0} MB in memory ({what}), more than the {limit_mb:.0} MB a run may use: {remedy}")]
    TooLarge {
        /// Estimated memory, MB.
        estimate_mb: f64,
        /// The limit, MB.
        limit_mb: f64,
        /// What takes the memory.
        what: String,
        /// Which settings lower it.
        remedy: String,
    },
}

/// Most memory a closed-loop run may plan to hold, MB: the time series and the
/// line-of-sight error kept for jitter and spectra.
pub const MAX_RUN_MEMORY_MB: f64 = 2048.0;

/// Columns of a recorded time series (one f64 each per row).
const SERIES_COLUMNS: usize = 15;

/// Longest a single closed-loop run may plan to compute, s of wall time (12 h): beyond
/// it a run is refused with the settings that shorten it, before anything is written.
pub const MAX_RUN_WALL_S: f64 = 12.0 * 3600.0;

/// Cost of one control period of one mode, ns: `boundary + substeps * step` (one core of
/// the 2-core machine the benchmarks run on; the hysteretic cable with memory: 191 ms for
/// 400 000 periods, the linear cable 83 ms). An estimate, good to a factor of two.
const PERIOD_COST_NS: [(f64, f64); 2] = [(110.0, 370.0), (50.0, 160.0)];

/// Memory and time a run will take, estimated before it starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorkEstimate {
    /// Control periods per mode.
    pub periods: u64,
    /// Modes run.
    pub modes: usize,
    /// Rows of time series kept per mode.
    pub series_rows: u64,
    /// Memory held, MB (time series plus line-of-sight error).
    pub memory_mb: f64,
    /// Computation, s on one core (all modes).
    pub compute_s: f64,
    /// Wall time with the modes side by side on the machine's cores, s.
    pub wall_s: f64,
}

/// The work of `p` with `modes` modes under `options`.
pub fn estimate_work(p: &ClosedLoopParams, modes: usize, options: &RunOptions) -> WorkEstimate {
    let (boundary_ns, step_ns) = PERIOD_COST_NS[match p.cable {
        super::params::CableModel::Hysteretic => 0,
        super::params::CableModel::Linear => 1,
    }];
    let per_period_s = (boundary_ns + step_ns * f64::from(p.rk4_substeps)) * 1e-9;
    let compute_s = p.periods() as f64 * modes as f64 * per_period_s;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let lanes = modes.clamp(1, cores.max(1)) as f64;
    let periods = p.periods();
    let rows = if options.record {
        periods / options.decimation.max(1) as u64 + 1
    } else {
        0
    };
    let window = if options.keeps_line_of_sight(p) {
        ((p.duration_s - p.metrics_start_s).max(0.0) * p.controller.sample_rate_hz)
            .ceil()
            .min(MAX_LOS_SAMPLES as f64)
    } else {
        0.0
    };
    let bytes = modes as f64 * (rows as f64 * SERIES_COLUMNS as f64 + window) * 8.0;
    WorkEstimate {
        periods,
        modes,
        series_rows: rows,
        memory_mb: bytes / 1e6,
        compute_s,
        wall_s: compute_s / lanes,
    }
}

/// How a mode's run ended.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum Completion {
    /// Ran to the end.
    Complete,
    /// Stopped early by a physical fault of the plant.
    Incomplete {
        /// What happened and what to change.
        fault: String,
        /// When, s.
        time_s: f64,
        /// What kind of stop it was.
        #[serde(default)]
        kind: StopKind,
    },
}

/// What stopped a run: the short name a sweep row carries in its status column.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopKind {
    /// A span went slack.
    Slack,
    /// The cable slid around the pulley.
    GrossSlip,
    /// The loop diverged (the plant state stopped being finite).
    Unstable,
    /// The command sat at the amplifier's limit for [`SATURATION_STOP_S`] without a
    /// break: the motor had lost the axis.
    Saturated,
    /// Anything else.
    #[default]
    Stopped,
}

impl StopKind {
    /// Every kind, for readers that check a status column against the names it may hold.
    pub const ALL: [StopKind; 5] = [
        StopKind::Slack,
        StopKind::GrossSlip,
        StopKind::Unstable,
        StopKind::Saturated,
        StopKind::Stopped,
    ];

    /// The status name (`slack`, `gross_slip`, `unstable`, `saturated`, `stopped`).
    pub fn name(self) -> &'static str {
        match self {
            StopKind::Slack => "slack",
            StopKind::GrossSlip => "gross_slip",
            StopKind::Unstable => "unstable",
            StopKind::Saturated => "saturated",
            StopKind::Stopped => "stopped",
        }
    }

    /// The kind of a cable fault.
    pub fn of(fault: &DriveFault) -> Self {
        match fault {
            DriveFault::Slack { .. } => StopKind::Slack,
            DriveFault::GrossSlip { .. } => StopKind::GrossSlip,
        }
    }
}

impl Completion {
    /// `ok`, or the kind of stop.
    pub fn status(&self) -> &'static str {
        match self {
            Completion::Complete => "ok",
            Completion::Incomplete { kind, .. } => kind.name(),
        }
    }
}

/// Integration statistics of one mode.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SolverStats {
    /// Control periods simulated.
    pub periods: u64,
    /// RK4 steps taken.
    pub steps: u64,
    /// Right-hand-side evaluations (each solves both span tensions exactly).
    pub rhs_evaluations: u64,
    /// Tension solves of a cable half, in the right-hand side and at period boundaries
    /// (closed form on the stored segment the slip zone ends on, Newton only across
    /// segments; 0 for the linear cable).
    pub tension_solves: u64,
    /// Rejected steps (always 0 with fixed-step RK4; kept for adaptive solvers).
    pub rejected_steps: u64,
    /// Samples at which the compensator's own model faulted and held its prediction.
    pub compensator_faults: u64,
    /// Wall-clock time of the mode, s.
    pub wall_s: f64,
}

/// Sampled time series of one mode (one row per kept control sample).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TimeSeries {
    /// Sample time, s.
    pub t_s: Vec<f64>,
    /// Desired output angle, rad.
    pub reference_rad: Vec<f64>,
    /// Motor angle, rad.
    pub motor_angle_rad: Vec<f64>,
    /// Output angle, rad.
    pub output_angle_rad: Vec<f64>,
    /// Pointing error `theta_out - r_out`, mrad.
    pub pointing_error_mrad: Vec<f64>,
    /// Transmission error `theta_out - theta_m/ic`, mrad.
    pub transmission_error_mrad: Vec<f64>,
    /// Upper span tension (damping included), N.
    pub tension_upper_n: Vec<f64>,
    /// Lower span tension, N.
    pub tension_lower_n: Vec<f64>,
    /// Held command, A or V.
    pub motor_command: Vec<f64>,
    /// Winding current, A.
    pub motor_current_a: Vec<f64>,
    /// Torque of the loads on the drum (brake reaction included), N m.
    pub load_torque_nm: Vec<f64>,
    /// Feedforward added to the PID output (velocity, acceleration and load terms, the
    /// compensator's reference shift included), A or V like the command. Computed from the
    /// reference and the known load terms only, so unknown disturbances leave it unchanged.
    pub feedforward: Vec<f64>,
    /// Motor angle the compensator asks for, `ic (r - e_pred)`, rad (the PID reference
    /// under motor feedback; `ic r` in mode `none`).
    pub motor_reference_rad: Vec<f64>,
    /// Base angle about the axis, rad (0 without base motion); the line of sight is this
    /// plus the output angle.
    pub base_angle_rad: Vec<f64>,
    /// Gyro reading as the controller gets it, rad/s (0 without a gyro).
    pub gyro_rad_s: Vec<f64>,
    /// Whether the brake held the drum at this sample (false without a brake): the
    /// frequency response reads from it whether the axis slid during its measurement.
    /// Not written to files.
    #[serde(skip)]
    pub drum_held: Vec<bool>,
}

impl TimeSeries {
    fn with_capacity(n: usize) -> Self {
        let v = || Vec::with_capacity(n);
        TimeSeries {
            t_s: v(),
            reference_rad: v(),
            motor_angle_rad: v(),
            output_angle_rad: v(),
            pointing_error_mrad: v(),
            transmission_error_mrad: v(),
            tension_upper_n: v(),
            tension_lower_n: v(),
            motor_command: v(),
            motor_current_a: v(),
            load_torque_nm: v(),
            feedforward: v(),
            motor_reference_rad: v(),
            base_angle_rad: v(),
            gyro_rad_s: v(),
            drum_held: Vec::with_capacity(n),
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// Whether empty.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }
}

/// Result of one compensation mode.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModeResult {
    /// The mode.
    pub mode: CompensationMode,
    /// Metrics over the window.
    pub metrics: Metrics,
    /// Solver statistics.
    pub stats: SolverStats,
    /// Completion status.
    pub completion: Completion,
    /// Simulated time reached, s.
    pub simulated_s: f64,
    /// Time series (`None` when not recorded).
    pub series: Option<TimeSeries>,
    /// Sustained oscillation while the reference rests (hunting), judged over the
    /// metrics window.
    #[serde(default)]
    pub limit_cycle: LimitCycle,
    /// Line-of-sight statistics over the metrics window: RMS, peak, jitter within each
    /// exposure; `None` when the window holds no sample.
    #[serde(default)]
    pub los: Option<LosMetrics>,
    /// Welch PSD and cumulative RMS of the line-of-sight error over the metrics window
    /// (recorded runs only; written as its own CSV, not in the summary).
    #[serde(skip)]
    pub spectrum: Option<ErrorSpectrum>,
    /// Whether the compensator also predicted the `[effects]` error (the extended model,
    /// `closed_loop.compensate_effects`); false for the uncompensated mode.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub effects_compensated: bool,
    /// Time the command spent at the amplifier's limit over the run: a loop whose command
    /// sits there is not controlling the axis.
    #[serde(default)]
    pub saturation: CommandSaturation,
}

impl ModeResult {
    /// Why this mode has no figures to judge (a stop, an empty metrics window); `None`
    /// when its metrics are the design's answer. What a stopped mode ran is not.
    pub fn no_figures_reason(&self) -> Option<String> {
        match &self.completion {
            Completion::Incomplete { fault, time_s, .. } => Some(format!(
                "mode {} stopped at t = {} s: {fault}",
                self.mode.name(),
                crate::readable(*time_s)
            )),
            Completion::Complete if self.metrics.samples == 0 => {
                Some("the metrics window holds no sample".to_string())
            }
            Completion::Complete => None,
        }
    }

    /// The mode's name as figures label it: `memory + effects` when the extended model
    /// compensated.
    pub fn label(&self) -> String {
        if self.effects_compensated {
            format!("{} + effects", self.mode.name())
        } else {
            self.mode.name().to_string()
        }
    }
}

/// Most samples of the line-of-sight error kept for jitter and spectra (2^22: 210 s at
/// 20 kHz, 34 MB); a longer window is judged on its first 2^22 samples, and the result
/// says how long a stretch that was.
pub const MAX_LOS_SAMPLES: usize = 1 << 22;

/// Result of a closed-loop run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClosedLoopResult {
    /// Per mode, in scenario order.
    pub modes: Vec<ModeResult>,
    /// Requested simulated time, s.
    pub duration_s: f64,
    /// Whether every mode ran to the end.
    pub complete: bool,
}

/// An unstable sampled closed loop's fastest-growing mode, as its exact linear reference
/// (`crate::analysis::linear`) finds it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instability {
    /// Largest pole magnitude `|z|` (above 1).
    pub pole_magnitude: f64,
    /// Growth rate of that mode, 1/s (`ln|z|` per period).
    pub growth_per_s: f64,
    /// Its frequency, Hz (0 for a real pole).
    pub frequency_hz: f64,
}

/// Everything a closed-loop run reads: the drive, the loads on its drum, the effects the
/// plant carries and the loop itself.
#[derive(Clone, Copy, Debug)]
pub struct ClosedLoopSetup<'a> {
    /// The cable drive.
    pub drive: &'a DriveParams,
    /// Loads on the output drum.
    pub load: &'a LoadParams,
    /// Effects beyond the base model that the plant carries (runout, drift, bearing friction).
    pub effects: Option<&'a EffectsParams>,
    /// Motor, controller, sensors, compensation, reference and timing.
    pub params: &'a ClosedLoopParams,
    /// The loop's instability on its exact linear reference, when it has one: an unstable
    /// loop ends in slack or slip, and a stop is named by its cause. Filled by whoever
    /// builds the setup (the simulation does not analyse its own loop).
    pub instability: Option<Instability>,
}

/// Anything a closed-loop setup can be read from: a setup itself, or a scenario (which
/// implements this at the edge, so this module never learns what a scenario file is).
pub trait ClosedLoopSource {
    /// The setup, or why this source holds none.
    fn closed_loop_setup(&self) -> Result<ClosedLoopSetup<'_>, ClosedLoopError>;
}

impl ClosedLoopSource for ClosedLoopSetup<'_> {
    fn closed_loop_setup(&self) -> Result<ClosedLoopSetup<'_>, ClosedLoopError> {
        Ok(*self)
    }
}

fn check_tables(signal: &Signal, key: &str) -> Result<(), ClosedLoopError> {
    match signal {
        Signal::Table { path, samples, .. } if samples.is_empty() => {
            Err(ClosedLoopError::TableNotLoaded {
                key: key.into(),
                path: path.clone(),
            })
        }
        Signal::Sum { parts } => parts.iter().try_for_each(|p| check_tables(p, key)),
        _ => Ok(()),
    }
}

/// Reference steps for step metrics (plain steps and step-and-stare staircases).
pub fn step_events(signal: &Signal, duration_s: f64) -> Vec<StepEvent> {
    match signal {
        Signal::Step {
            amplitude_rad,
            time_s,
        } => vec![StepEvent {
            time_s: *time_s,
            from_rad: 0.0,
            to_rad: *amplitude_rad,
        }],
        Signal::StepStare { period_s, .. } => {
            let n = (duration_s / period_s).floor() as u64;
            (1..=n)
                .map(|j| {
                    let t = j as f64 * period_s;
                    StepEvent {
                        time_s: t,
                        from_rad: signal.at(t - 0.5 * period_s).value,
                        to_rad: signal.at(t + 0.5 * period_s).value,
                    }
                })
                .filter(|e| e.time_s < duration_s)
                .collect()
        }
        _ => Vec::new(),
    }
}

/// Run the closed loop of a scenario for every selected compensation mode.
pub fn run_closed_loop(
    source: &(impl ClosedLoopSource + ?Sized),
    options: &RunOptions,
) -> Result<ClosedLoopResult, ClosedLoopError> {
    run_closed_loop_then(source, options, |_| ()).map(|(result, _)| result)
}

/// [`run_closed_loop`], and `then` applied to each mode's result on that mode's thread as
/// soon as the mode ends (its outputs, say), while the other modes still run: the cores
/// stay busy through the end of the slowest mode. The values come back in mode order.
pub fn run_closed_loop_then<T: Send>(
    source: &(impl ClosedLoopSource + ?Sized),
    options: &RunOptions,
    then: impl Fn(&ModeResult) -> T + Sync,
) -> Result<(ClosedLoopResult, Vec<T>), ClosedLoopError> {
    run_closed_loop_shared(source, options, None, then)
}

/// [`run_closed_loop_then`] reading the reference from `reference`, a cache shared by the
/// runs of one study (the cases of a sweep): the results are bit for bit those without it.
pub fn run_closed_loop_shared<T: Send>(
    source: &(impl ClosedLoopSource + ?Sized),
    options: &RunOptions,
    reference: Option<&ReferenceCache>,
    then: impl Fn(&ModeResult) -> T + Sync,
) -> Result<(ClosedLoopResult, Vec<T>), ClosedLoopError> {
    let setup = source.closed_loop_setup()?;
    let scenario = &setup;
    let p = setup.params;
    p.validate(scenario.drive)
        .map_err(|(key, message)| ClosedLoopError::Invalid { key, message })?;
    scenario
        .drive
        .validate()
        .map_err(|e| ClosedLoopError::Invalid {
            key: "drive".into(),
            message: e.to_string(),
        })?;
    scenario
        .load
        .validate()
        .map_err(|(k, message)| ClosedLoopError::Invalid {
            key: format!("load.{k}"),
            message,
        })?;
    if let Some(fx) = scenario.effects {
        fx.validate()
            .map_err(|(k, message)| ClosedLoopError::Invalid {
                key: format!("effects.{k}"),
                message,
            })?;
    }
    p.validate_effects(scenario.effects)
        .map_err(|(key, message)| ClosedLoopError::Invalid { key, message })?;
    check_tables(&p.reference, "closed_loop.reference")?;
    if let Some(b) = &p.base_motion {
        check_tables(b, "closed_loop.base_motion")?;
    }
    if let (Some(path), true) = (
        &scenario.load.disturbance_csv,
        scenario.load.disturbance.is_empty(),
    ) {
        return Err(ClosedLoopError::TableNotLoaded {
            key: "load.disturbance_csv".into(),
            path: path.clone(),
        });
    }
    let modes: Vec<CompensationMode> = p
        .modes
        .iter()
        .copied()
        .filter(|m| options.modes.as_ref().is_none_or(|f| f.contains(m)))
        .collect();
    if modes.is_empty() {
        return Err(ClosedLoopError::NoModes {
            requested: format!("{:?}", options.modes),
        });
    }
    let work = estimate_work(p, modes.len(), options);
    if work.memory_mb > MAX_RUN_MEMORY_MB {
        return Err(ClosedLoopError::TooLarge {
            estimate_mb: work.memory_mb,
            limit_mb: MAX_RUN_MEMORY_MB,
            what: format!(
                "{} mode(s) x {} rows of time series at closed_loop.timeseries_rate_hz = {} Hz over closed_loop.duration_s = {} s",
                work.modes,
                work.series_rows,
                crate::number(p.timeseries_rate_hz),
                crate::number(p.duration_s)
            ),
            remedy: format!(
                "lower closed_loop.timeseries_rate_hz (at most about {} Hz fits), shorten closed_loop.duration_s, or list fewer closed_loop.modes",
                crate::number(
                    (p.timeseries_rate_hz * MAX_RUN_MEMORY_MB / work.memory_mb * 0.9).floor()
                )
            ),
        });
    }
    if work.wall_s > MAX_RUN_WALL_S {
        return Err(ClosedLoopError::TooLong {
            estimate_s: work.wall_s,
            limit_s: MAX_RUN_WALL_S,
            what: format!(
                "{} mode(s) x {} control periods: closed_loop.duration_s = {} s at closed_loop.controller.sample_rate_hz = {} Hz with closed_loop.rk4_substeps = {}",
                work.modes,
                work.periods,
                crate::number(p.duration_s),
                crate::number(p.controller.sample_rate_hz),
                p.rk4_substeps
            ),
            remedy: format!(
                "shorten closed_loop.duration_s (at most about {} s fits), lower closed_loop.rk4_substeps, or list fewer closed_loop.modes",
                crate::number((p.duration_s * MAX_RUN_WALL_S / work.wall_s * 0.9).floor())
            ),
        });
    }
    let instability = setup.instability;
    let sampled =
        reference.and_then(|c| c.get(&p.reference, 1.0 / p.controller.sample_rate_hz, p.periods()));
    let sampled = sampled.as_deref();
    // Modes are independent runs, side by side on the cores (results in mode order).
    // Inside a pool (a sweep's cases) the pool shares the cores out; alone, one thread
    // per mode: three modes on two cores then finish together in 1.5 mode-times, where
    // a two-thread pool needs two.
    let one = |m: CompensationMode| {
        let r = run_mode(&setup, m, options, instability, sampled);
        let t = then(&r);
        (r, t)
    };
    let done: Vec<(ModeResult, T)> = if rayon::current_thread_index().is_some() || modes.len() == 1
    {
        modes.par_iter().map(|&m| one(m)).collect()
    } else {
        std::thread::scope(|s| {
            let one = &one;
            let handles: Vec<_> = modes.iter().map(|&m| s.spawn(move || one(m))).collect();
            handles
                .into_iter()
                .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
                .collect()
        })
    };
    let (results, values): (Vec<ModeResult>, Vec<T>) = done.into_iter().unzip();
    Ok((
        ClosedLoopResult {
            complete: results.iter().all(|r| r.completion == Completion::Complete),
            modes: results,
            duration_s: p.duration_s,
        },
        values,
    ))
}

/// Metrics of every mode without time series: the cheap call for one sweep case. The
/// line of sight's jitter is left out unless the scenario's requirements judge it (see
/// [`RunOptions::line_of_sight`]).
pub fn run_closed_loop_metrics(
    source: &(impl ClosedLoopSource + ?Sized),
) -> Result<ClosedLoopResult, ClosedLoopError> {
    run_closed_loop(source, &sweep_case())
}

/// What a sweep case keeps: metrics and the verdict's inputs, no series, no jitter the
/// verdict does not judge.
fn sweep_case() -> RunOptions {
    RunOptions {
        line_of_sight: false,
        ..RunOptions::metrics_only()
    }
}

/// [`run_closed_loop_metrics`] reading the reference from a cache shared by the cases of
/// a sweep; the same results.
pub fn run_closed_loop_metrics_shared(
    source: &(impl ClosedLoopSource + ?Sized),
    reference: &ReferenceCache,
) -> Result<ClosedLoopResult, ClosedLoopError> {
    run_closed_loop_shared(source, &sweep_case(), Some(reference), |_| ()).map(|(result, _)| result)
}

/// Fault message with time and mode. A slack span found while solving by displacement
/// carries no torque; the transmitted torque at the last sample fills it in. The preload
/// it asks for carries that torque and the load's declared peak (`peak_load_nm`, N m),
/// whichever is larger: a drive that goes slack early in a run has transmitted little
/// yet, and asking for the preload that carries only that would send the user round
/// again.
fn describe(
    fault: &DriveFault,
    t: f64,
    mode: CompensationMode,
    cable_torque_nm: f64,
    peak_load_nm: f64,
    drum_radius_m: f64,
) -> String {
    let mut hint = "";
    let fault = match *fault {
        DriveFault::Slack { half, .. } => {
            // Positive torque tightens the upper span: a slack span on the tight side's
            // opposite is expected, the other way round means the tension swung through
            // a whole preload within one period.
            let swung = (half == Half::Upper) == (cable_torque_nm > 0.0);
            if swung {
                hint = "; the tensions swung within one period, so the loop is likely unstable: lower the controller gains";
            }
            DriveFault::Slack {
                half,
                torque_nm: cable_torque_nm,
                needed_preload_n: cable_torque_nm.abs().max(peak_load_nm) / (2.0 * drum_radius_m),
            }
        }
        other => other,
    };
    format!(
        "plant cable fault at t = {} s (mode {}): {fault}{hint}",
        crate::readable(t),
        mode.name()
    )
}

/// The settings an unstable loop's message asks to check.
fn gains_to_check(c: &super::params::ControllerParams) -> String {
    let mut out = format!(
        "check closed_loop.controller kp = {}, ki = {}, kd = {}, derivative_filter_hz = {} and computation_delay_samples = {}",
        crate::number(c.kp),
        crate::number(c.ki),
        crate::number(c.kd),
        crate::number(c.derivative_filter_hz),
        crate::number(c.computation_delay_samples)
    );
    if let Some(r) = &c.rate_loop {
        out.push_str(&format!(
            ", rate_loop.kp = {}, rate_loop.ki = {}",
            crate::number(r.kp),
            crate::number(r.ki)
        ));
    }
    let filters = c.measurement_filters.len()
        + c.rate_command_filters.len()
        + c.rate_measurement_filters.len()
        + c.command_filters.len();
    if filters > 0 {
        out.push_str(&format!(
            " and the {filters} filter(s) (a notch belongs on the drive's resonance)"
        ));
    }
    out.push_str(" (`cable-servo margins` shows the margins)");
    out
}

/// Growth of an unstable mode since the run began (tenfold, 20 dB) from which a slack
/// span or a slip is taken for its doing rather than the drive's own.
const GROWN_TO_STOP: f64 = 10.0;

/// A stop, named as the loop's instability when the exact linear reference is unstable,
/// unless it is a slack span or a slip before the growing mode has grown
/// [`GROWN_TO_STOP`] times: a preload too low for the load slips in a stable loop too, so
/// such a stop keeps its name, with the instability and its growth so far told beside it.
fn stop(
    fault: String,
    time_s: f64,
    kind: StopKind,
    instability: Option<Instability>,
    controller: &super::params::ControllerParams,
) -> Completion {
    match instability {
        Some(i)
            if matches!(kind, StopKind::GrossSlip | StopKind::Slack)
                && (i.growth_per_s * time_s).exp() < GROWN_TO_STOP =>
        {
            Completion::Incomplete {
                fault: format!(
                    "{fault}; the loop is also unstable (on its exact linear reference the largest closed-loop pole has |z| = {:.5}: a mode growing at {:.1} 1/s at {:.1} Hz, only {} times its start by then); {}",
                    i.pole_magnitude,
                    i.growth_per_s,
                    i.frequency_hz,
                    crate::compact((i.growth_per_s * time_s).exp()),
                    gains_to_check(controller)
                ),
                time_s,
                kind,
            }
        }
        Some(i) => Completion::Incomplete {
            fault: format!(
                "the loop is unstable (on its exact linear reference the largest closed-loop pole has |z| = {:.5}: a mode growing at {:.1} 1/s at {:.1} Hz), so it ended in: {fault}; {}",
                i.pole_magnitude,
                i.growth_per_s,
                i.frequency_hz,
                gains_to_check(controller)
            ),
            time_s,
            kind: StopKind::Unstable,
        },
        None => Completion::Incomplete {
            fault,
            time_s,
            kind,
        },
    }
}

/// The base's motion over the fraction `[from, to]` of the period that starts at `a` and
/// ends at `b` (length `ts`), on the period's Hermite curve.
fn piece_of(
    a: &crate::signal::SignalPoint,
    b: &crate::signal::SignalPoint,
    from: f64,
    to: f64,
    ts: f64,
) -> BaseSegment {
    let whole = BaseSegment {
        rate0: a.rate,
        rate1: b.rate,
        accel0: a.accel,
        accel1: b.accel,
        angle0: a.value,
    };
    if from == 0.0 && to == 1.0 {
        return whole;
    }
    let (angle0, rate0, accel0) = whole.at(from, ts);
    let (_, rate1, accel1) = whole.at(to, ts);
    BaseSegment {
        rate0,
        rate1,
        accel0,
        accel1,
        angle0,
    }
}

/// Motor angle `theta` (rad) that puts the output on its reference when the effects add
/// `f(theta) = (error, slope)` (rad, rad/rad) to what the motor angle `theta0 = ic (r -
/// e_known)` already accounts for: the root of `theta - theta0 + ic f(theta)`. Newton's
/// steps, kept inside the bracket the signs have found: the friction memory makes `f`
/// piecewise linear, with kinks a plain Newton step can circle around.
fn solve_input_angle(theta0: f64, ic: f64, f: impl Fn(f64) -> (f64, f64)) -> f64 {
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    let mut theta = theta0;
    for _ in 0..40 {
        let (value, slope) = f(theta);
        let g = theta - theta0 + ic * value;
        if g == 0.0 {
            break;
        }
        if g > 0.0 {
            hi = hi.min(theta);
        } else {
            lo = lo.max(theta);
        }
        let d = 1.0 + ic * slope;
        let mut next = if d > 0.05 { theta - g / d } else { theta - g };
        // A step that lands on the bracket's end is the root to rounding; one beyond it
        // gives way to bisection.
        if !(next >= lo && next <= hi) {
            next = if lo.is_finite() && hi.is_finite() {
                0.5 * (lo + hi)
            } else {
                theta - g
            };
        }
        if (next - theta).abs() <= 1e-14 * (1.0 + theta.abs()) {
            return next;
        }
        theta = next;
    }
    theta
}

/// What drives the loop from outside (reference, base motion, load torques), so the
/// hunting detector does not take their forced response for a limit cycle.
fn forcing(p: &ClosedLoopParams, load: &LoadParams) -> Forcing {
    let mut f = Forcing::default();
    signal_forcing(&p.reference, "reference", &mut f);
    if let Some(b) = &p.base_motion {
        signal_forcing(b, "base motion", &mut f);
    }
    if load.sine_nm != 0.0 && load.sine_frequency_hz > 0.0 {
        f.lines
            .push((load.sine_frequency_hz, "load sine torque".to_string()));
    }
    if !load.disturbance.is_empty() {
        // A tabulated torque's lines are not estimated: any frequency may be forced.
        f.bands.push((
            0.0,
            f64::INFINITY,
            "load disturbance table (broadband)".to_string(),
        ));
    }
    f
}

/// The lines (sine and triangle frequencies) or bands (PSD, table) a signal drives at.
fn signal_forcing(s: &Signal, source: &str, f: &mut Forcing) {
    match s {
        Signal::Sine {
            amplitude_rad,
            frequency_hz,
            ..
        } if *amplitude_rad != 0.0 && *frequency_hz > 0.0 => {
            f.lines.push((*frequency_hz, source.to_string()));
        }
        Signal::Triangle { frequency_hz, .. } => {
            f.lines.push((*frequency_hz, source.to_string()));
        }
        Signal::Sum { parts } => parts.iter().for_each(|q| signal_forcing(q, source, f)),
        Signal::Psd { psd, .. } => {
            if let (Some(lo), Some(hi)) = (psd.first(), psd.last()) {
                f.bands
                    .push((lo[0], hi[0], format!("{source} (broadband)")));
            }
        }
        Signal::Table { samples, .. } if samples.len() > 1 => {
            // A table's lines are not estimated: broadband over every frequency.
            f.bands
                .push((0.0, f64::INFINITY, format!("{source} (broadband)")));
        }
        _ => {}
    }
}

fn run_mode(
    scenario: &ClosedLoopSetup<'_>,
    mode: CompensationMode,
    options: &RunOptions,
    instability: Option<Instability>,
    sampled: Option<&SampledReference>,
) -> ModeResult {
    let wall = Instant::now();
    let p = scenario.params;
    let drive = scenario.drive;
    let load = scenario.load;
    let ic = drive.ratio();
    let ts = 1.0 / p.controller.sample_rate_hz;
    let n = p.periods();
    let sub = p.rk4_substeps;
    let coeff = PlantCoefficients::new(p, drive, load, scenario.effects);
    let mut cable = PlantCable::new(p.cable, drive);
    let mut sensors = Sensors::new(&p.sensors);
    let command_limit = p.motor.command_limit();
    let mut law = ControlLaw::new(p, ic, command_limit);
    let mut gyro = p
        .gyro
        .as_ref()
        .and_then(|g| GyroReader::new(g, p.controller.sample_rate_hz));
    let mut base = p.base_motion.as_ref().map(|b| BaseMotion::new(b, ts));
    let mut delay = CommandDelay::new(p.controller.computation_delay_samples);
    let mut comp = mode
        .model()
        .map(|m| Compensator::new(p.compensator_params(drive), m));
    // Effects the compensator predicts (only modes with a compensator use them).
    let comp_fx = p
        .compensator_effects(scenario.effects)
        .filter(|_| comp.is_some());
    let comp_kinematic = comp_fx.filter(|fx| fx.has_kinematic());
    let comp_bearing = comp_fx.map_or(0.0, |fx| fx.bearing_friction());
    let comp_compliance = comp_fx.map_or(0.0, EffectsParams::load_compliance);
    let mut comp_contacts = comp_fx.and_then(|fx| ContactMemory::new(fx, 0.0));
    // The jaw link between the drum and the output sensor, massless: it gives way under the
    // load it carries and lags by its contacts' friction memory, without changing the
    // forces on the drum.
    let link_compliance = scenario.effects.map_or(0.0, EffectsParams::load_compliance);
    let mut link_contacts = scenario.effects.and_then(|fx| ContactMemory::new(fx, 0.0));
    let comp_ic = p.compensator_params(drive).ratio();
    // The brake is a declared model; should it ever be treated as unknown, the
    // feedforward must not see it.
    let (brake_known, brake_breakaway_known) = if LoadTerm::Brake.known_to_compensator() {
        (load.brake_nm, load.breakaway_nm())
    } else {
        (0.0, 0.0)
    };
    let mut brake_pred = BrakePredictor::new(
        brake_known + comp_bearing,
        brake_breakaway_known + comp_bearing,
        p.controller.brake_transition_s,
        ts,
    );
    // Whether any declared load besides the brake acts (saves a sine per sample when none).
    let known_smooth_load = load.known_terms().iter().any(|t| *t != LoadTerm::Brake);
    let voltage_mode = p.motor.amplifier == Amplifier::Voltage;
    let c = &p.controller;

    let mut metrics = MetricsAccumulator::new(MetricsConfig {
        window_start_s: p.metrics_start_s,
        window_end_s: f64::INFINITY,
        target_mrad: p.target_mrad,
        settle_band_mrad: p.settle_band_mrad.unwrap_or(p.target_mrad),
        steps: step_events(&p.reference, p.duration_s),
    });
    let mut hunting = LimitCycleDetector::default().with_forcing(forcing(p, load));
    let mut saturation = Saturation::default();
    let window_samples = ((p.duration_s - p.metrics_start_s) * p.controller.sample_rate_hz)
        .max(0.0)
        .ceil() as usize
        + 1;
    // A run that keeps no line of sight pushes nothing, so its buffer needs no room.
    let los_samples = if options.keeps_line_of_sight(p) {
        MAX_LOS_SAMPLES
    } else {
        0
    };
    let mut los_errors: Vec<f64> = Vec::with_capacity(window_samples.min(los_samples));
    let decimation = options.decimation.max(1) as u64;
    let mut series = options
        .record
        .then(|| TimeSeries::with_capacity((n / decimation + 1) as usize));

    let mut x = State::zeros();
    let mut base_now = base.as_mut().map(|b| b.at_sample(0)).unwrap_or_default();
    // The gyro starts settled on the base's rate, and the controller aligns its gyro angle
    // with the line of sight at switch-on.
    x[GYRO] = base_now.rate;
    let mut gyro_angle = base_now.value;
    let mut brake = BrakeState::Stuck;
    if p.start == super::params::StartState::InertiallyStill && base_now.rate != 0.0 {
        // The drum turns against the base, the cable unstretched (D' = 0).
        x[OMEGA_O] = -base_now.rate;
        x[OMEGA_M] = ic * x[OMEGA_O];
        x[GYRO] = 0.0;
        if coeff.breakaway > 0.0 {
            brake = BrakeState::Slipping(x[OMEGA_O].signum());
        }
    }
    let mut prev_ref = p.reference.at(0.0).value;
    let mut prev_e_pred = 0.0;
    let mut stats = SolverStats::default();
    let mut completion = Completion::Complete;
    let mut reached = 0.0;
    let mut last_torque = 0.0;
    let mut boundary_solves = 0u64;

    for k in 0..=n {
        let t = k as f64 * ts;
        boundary_solves += 1;
        let forces = match settle_boundary(
            &coeff,
            &mut cable,
            load,
            &mut brake,
            &mut x,
            t,
            (base_now.value, base_now.accel),
        ) {
            Ok(f) => f,
            Err(f) => {
                completion = stop(
                    describe(&f, t, mode, last_torque, load.peak_torque_nm(), coeff.ro),
                    t,
                    StopKind::of(&f),
                    instability,
                    c,
                );
                break;
            }
        };
        let (tu, tl) = (forces.tension_upper_n, forces.tension_lower_n);
        last_torque = forces.cable_torque_nm;
        let link_torque = -load_torque(&coeff, brake, &forces);
        let output = x[THETA_O]
            + link_compliance * link_torque
            + link_contacts
                .as_mut()
                .map_or(0.0, |m| m.commit(x[THETA_M], link_torque));

        // Controller at t_k.
        let ym = sensors.motor.read(x[THETA_M], &mut sensors.rng);
        let yo = sensors.output.read(output, &mut sensors.rng);
        let r = sampled
            .and_then(|s| s.point(k))
            .unwrap_or_else(|| p.reference.at(t));
        let delta = if r.rate != 0.0 {
            r.rate
        } else {
            r.value - prev_ref
        };
        prev_ref = r.value;
        let m_brake = brake_pred.update(delta);
        // The compensator is given only the declared load models (unbalance, brake, a
        // declared constant), from the reference and the clock: other constant, sine and
        // CSV torques reach it only through the sensors.
        let m_smooth = if known_smooth_load {
            load.known_torque_nm(t, r.value)
        } else {
            0.0
        };
        let m_link = m_brake - m_smooth;
        let m_pred = m_link + coeff.jo * r.accel + coeff.bo * r.rate;
        let e_cable = comp.as_mut().map_or(0.0, |cp| cp.predict(m_pred));
        let e_known = e_cable + comp_compliance * m_link;
        // The contacts have moved with the motor, which the encoder reads: the
        // compensator's copy of their memory follows the measured angle, not the one it
        // asked for.
        if let Some(m) = comp_contacts.as_mut() {
            m.commit(ym, m_link);
        }
        let e_pred = if comp_kinematic.is_some() || comp_contacts.is_some() {
            // The effects' error depends on the motor angle it shifts.
            let theta_in = solve_input_angle(ic * (r.value - e_known), ic, |th| {
                let k = comp_kinematic
                    .map(|fx| fx.kinematic_error(th, r.value, t, comp_ic))
                    .unwrap_or_default();
                let (lag, lag_slope) = comp_contacts
                    .as_ref()
                    .map_or((0.0, 0.0), |m| m.lag_and_slope(th, m_link));
                (k.value_rad + lag, k.d_theta_in + lag_slope)
            });
            r.value - theta_in / ic
        } else {
            e_known
        };
        let r_m = ic * (r.value - e_pred);
        let shift_rate = if k > 0 {
            -ic * (e_pred - prev_e_pred) / ts
        } else {
            0.0
        };
        prev_e_pred = e_pred;
        let mut u_ff = c.velocity_feedforward * (ic * r.rate + shift_rate)
            + c.acceleration_feedforward * ic * r.accel;
        if c.load_feedforward {
            let i_ff = m_pred / (ic * coeff.kt);
            u_ff += if voltage_mode { coeff.r * i_ff } else { i_ff };
        }
        let gyro_reading = gyro.as_mut().map_or(0.0, |g| g.read(x[GYRO]));
        let (rr, mut yy) = match c.feedback {
            Feedback::Motor => (r_m, ym),
            Feedback::Output => (ic * r.value, ic * yo),
            Feedback::GyroAngle => (ic * r.value, ic * gyro_angle),
        };
        gyro_angle += ts * gyro_reading;
        let injected = options.injection.map(|i| (i.site, i.at(t)));
        if let Some((InjectionSite::Measurement, d)) = injected {
            yy += d;
        }
        let mut u = law.update(&LawInputs {
            reference: rr,
            measurement: yy,
            rate_feedforward: r.rate + shift_rate / ic,
            gyro: gyro_reading,
            motor_encoder: ym,
            feedforward: u_ff,
        });
        if let Some((InjectionSite::Command, d)) = injected {
            u = (u + d).clamp(-command_limit, command_limit);
        }
        if let Some(i) = instability.filter(|_| u.abs() >= command_limit) {
            // An unstable linear loop that reaches the amplifier's limit has not found a
            // working point: what follows is a saturated oscillation, not a result.
            completion = Completion::Incomplete {
                fault: format!(
                    "the loop is unstable (on its exact linear reference the largest closed-loop pole has |z| = {:.5}: a mode growing at {:.1} 1/s at {:.1} Hz) and its command reached the amplifier limit {} at t = {} s (mode {}); {}",
                    i.pole_magnitude,
                    i.growth_per_s,
                    i.frequency_hz,
                    crate::number(command_limit),
                    crate::readable(t),
                    mode.name(),
                    gains_to_check(c)
                ),
                time_s: t,
                kind: StopKind::Unstable,
            };
            break;
        }
        if saturation.push(u.abs() >= command_limit, ts) >= SATURATION_STOP_S {
            completion = Completion::Incomplete {
                fault: format!(
                    "the command sat at the amplifier limit {} for {SATURATION_STOP_S} s without a break up to t = {} s (mode {}): the motor cannot deliver what the loop asks (the load it must hold, a torque constant or limit too small)",
                    crate::number(command_limit),
                    crate::readable(t),
                    mode.name()
                ),
                time_s: t,
                kind: StopKind::Saturated,
            };
            break;
        }
        let held = delay.push(u);
        if !voltage_mode {
            x[CURRENT] = if held.split > 0.0 {
                held.first
            } else {
                held.second
            };
        }

        // The line of sight: the output's angle on the moving base.
        let los = output + base_now.value;
        let sample = Sample {
            t_s: t,
            reference_rad: r.value,
            output_rad: los,
            transmission_error_rad: Some(output - x[THETA_M] / ic),
            command: Some(u),
            current_a: Some(x[CURRENT]),
        };
        metrics.push(&sample);
        if t >= p.metrics_start_s {
            hunting.push(t, r.value, los);
            if los_errors.len() < los_samples {
                los_errors.push((los - r.value) * 1e3);
            }
        }
        if let Some(s) = series.as_mut().filter(|_| k % decimation == 0) {
            s.t_s.push(t);
            s.reference_rad.push(r.value);
            s.motor_angle_rad.push(x[THETA_M]);
            s.output_angle_rad.push(output);
            s.pointing_error_mrad.push((los - r.value) * 1e3);
            s.transmission_error_mrad
                .push((output - x[THETA_M] / ic) * 1e3);
            s.tension_upper_n.push(tu);
            s.tension_lower_n.push(tl);
            s.motor_command.push(u);
            s.motor_current_a.push(x[CURRENT]);
            s.load_torque_nm.push(load_torque(&coeff, brake, &forces));
            s.feedforward.push(u_ff);
            s.motor_reference_rad.push(r_m);
            s.base_angle_rad.push(base_now.value);
            s.gyro_rad_s.push(gyro_reading);
            s.drum_held.push(matches!(brake, BrakeState::Stuck));
        }
        reached = t;
        if k == n {
            break;
        }

        // Plant over [t_k, t_k+1) with the delayed commands held, in one piece or two (the
        // command switches inside the period under a fractional delay); the integrator
        // restarts at every piece, and the cable memory is committed only at t_k+1.
        let pieces = if held.split > 0.0 {
            [
                (0.0, held.split, held.first),
                (held.split, 1.0, held.second),
            ]
        } else {
            [(0.0, 1.0, held.second), (1.0, 1.0, held.second)]
        };
        let base_next = base
            .as_mut()
            .map(|b| b.at_sample(k + 1))
            .unwrap_or_default();
        let mut fault = None;
        for (from, to, command) in pieces {
            if to <= from {
                continue;
            }
            if !voltage_mode {
                x[CURRENT] = command;
            }
            let end = integrate_period(
                &coeff,
                &cable,
                load,
                brake,
                command,
                t + from * ts,
                (to - from) * ts,
                sub,
                piece_of(&base_now, &base_next, from, to, ts),
                &mut x,
            );
            stats.steps += u64::from(end.stats.accepted_steps);
            stats.rhs_evaluations += u64::from(end.stats.num_eval);
            stats.rejected_steps += u64::from(end.stats.rejected_steps);
            fault = end.fault;
            if fault.is_some() {
                break;
            }
        }
        stats.periods += 1;
        base_now = base_next;
        if let Some(f) = fault {
            completion = stop(
                describe(
                    &f,
                    t + ts,
                    mode,
                    last_torque,
                    load.peak_torque_nm(),
                    coeff.ro,
                ),
                t + ts,
                StopKind::of(&f),
                instability,
                c,
            );
            reached = t + ts;
            break;
        }
        if !x.iter().all(|v| v.is_finite()) {
            completion = Completion::Incomplete {
                fault: format!(
                    "the loop diverged (plant state not finite) at t = {} s (mode {}); lower closed_loop.controller gains or raise sample_rate_hz",
                    crate::readable(t + ts),
                    mode.name()
                ),
                time_s: t + ts,
                kind: StopKind::Unstable,
            };
            reached = t + ts;
            break;
        }
    }
    // Every right-hand side and every boundary solves both halves.
    if let PlantCable::Hysteretic(_) = cable {
        stats.tension_solves = 2 * (stats.rhs_evaluations + boundary_solves);
    }
    stats.compensator_faults = comp.as_ref().map_or(0, Compensator::faults);
    let fs = p.controller.sample_rate_hz;
    // Independent reads of the same errors: on two cores the jitter windows run beside
    // the spectrum's transforms.
    let (los, spectrum) = rayon::join(
        || (!los_errors.is_empty()).then(|| los_metrics(&los_errors, fs, &p.los)),
        || {
            (options.record && options.line_of_sight)
                .then(|| error_spectrum(&los_errors, fs, p.los.psd_segment_s))
                .flatten()
        },
    );
    stats.wall_s = wall.elapsed().as_secs_f64();
    ModeResult {
        los,
        spectrum,
        mode,
        metrics: metrics.finish(),
        stats,
        completion,
        simulated_s: reached,
        series,
        limit_cycle: hunting.finish(),
        effects_compensated: comp_fx.is_some(),
        saturation: saturation.finish(),
    }
}

/// Longest unbroken stretch at the amplifier's limit after which a run stops, s: a
/// servo's transients saturate for milliseconds; a whole second means the motor lost the
/// axis, and what follows is not the design's answer.
pub const SATURATION_STOP_S: f64 = 1.0;

/// How long the command sat at the amplifier's limit over the run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CommandSaturation {
    /// Fraction of the run's control samples at the limit, 0 to 1.
    pub fraction: f64,
    /// Longest unbroken stretch at the limit, s.
    pub longest_s: f64,
}

/// Counts samples at the limit and the longest run of them.
#[derive(Default)]
struct Saturation {
    samples: u64,
    at_limit: u64,
    run_s: f64,
    longest_s: f64,
}

impl Saturation {
    /// Count one sample; returns the current unbroken stretch at the limit, s.
    fn push(&mut self, at_limit: bool, ts: f64) -> f64 {
        self.samples += 1;
        if at_limit {
            self.at_limit += 1;
            self.run_s += ts;
            self.longest_s = self.longest_s.max(self.run_s);
        } else {
            self.run_s = 0.0;
        }
        self.run_s
    }

    fn finish(&self) -> CommandSaturation {
        CommandSaturation {
            fraction: if self.samples > 0 {
                self.at_limit as f64 / self.samples as f64
            } else {
                0.0
            },
            longest_s: self.longest_s,
        }
    }
}

#[cfg(test)]
mod solve_tests {
    use super::solve_input_angle;

    /// Piecewise-linear effects with slopes down to -0.85 rad/rad (sticking contacts) and a
    /// smooth term: the root found leaves no residual, from either side.
    #[test]
    fn the_motor_angle_puts_the_output_on_its_reference() {
        let ic = 1.09;
        let f = |th: f64| {
            let stick = (th - 0.3).clamp(-0.02, 0.02);
            let kink = if th > 0.5 { -0.6 * (th - 0.5) } else { 0.0 };
            let value = -0.85 * stick + kink + 1e-3 * (3.0 * th).sin();
            let slope = if (th - 0.3).abs() < 0.02 { -0.85 } else { 0.0 }
                + if th > 0.5 { -0.6 } else { 0.0 }
                + 3e-3 * (3.0 * th).cos();
            (value, slope)
        };
        for k in 0..200 {
            let theta0 = -0.2 + k as f64 * 0.005;
            let th = solve_input_angle(theta0, ic, f);
            let g = th - theta0 + ic * f(th).0;
            assert!(g.abs() < 1e-14, "theta0 {theta0}: residual {g} at {th}");
        }
    }
}
