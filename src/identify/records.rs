//! What a diagnosis returns and how it fails: options, parameter estimates, candidate
//! scores, traces for plots.

use serde::Serialize;

use super::{identifiability, whiteness};
use super::{startup, EffectName, EffectsParams};
use crate::physics::DriveParams;

/// Why a diagnosis cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    /// No logs.
    #[error("no bench logs given; pass at least one log (--data LOG.csv)")]
    NoLogs,
    /// A log that cannot be used.
    #[error("{log}: {message}")]
    BadLog {
        /// Log source (file).
        log: String,
        /// What is wrong.
        message: String,
    },
    /// Settings that do not fit the data.
    #[error("{key}: {message}")]
    Config {
        /// Scenario key or option.
        key: String,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// The model cannot follow the log (cable slack or gross slip at these parameters).
    #[error("{log}: replay fails at t = {t_s:.3} s: {message}; the scenario's drive cannot carry the logged load (check drive.preload_n, the load sign, and load_nm units)")]
    Replay {
        /// Log source.
        log: String,
        /// Time of the failure, s.
        t_s: f64,
        /// The drive fault.
        message: String,
    },
    /// A fit that failed or diverged.
    #[error("fit failed: {0}")]
    Fit(String),
    /// Output cannot be written.
    #[error("cannot write {path}: {message}")]
    Write {
        /// Path.
        path: String,
        /// Reason.
        message: String,
    },
}

/// Settings of a diagnosis beyond the scenario's `[identify]` section.
#[derive(Clone, Debug, Default)]
pub struct DiagnoseOptions {
    /// Indices of logs held out entirely (calibrate on the others, score on these). Empty:
    /// contiguous time blocks of every log are held out in turn.
    pub holdout_logs: Vec<usize>,
    /// Restrict the candidate effects (None: scenario's list, or every effect).
    pub candidates: Option<Vec<EffectName>>,
    /// Skip the play-operator baseline (saves time in statistical runs).
    pub skip_play_operator: bool,
    /// Start-up handling: detect a load step at each log's start (default) or cut a fixed
    /// time; what is cut is neither fitted nor scored.
    pub start: startup::StartMode,
    /// Fit and score the stretches [`super::segments::detect`] flags as not the drive
    /// (they are still reported, as `"kept"`); default false: they are excluded.
    pub keep_segments: bool,
}

/// One estimated parameter.
#[derive(Clone, Debug, Serialize)]
pub struct ParamEstimate {
    /// Name (scenario key or effect name).
    pub name: String,
    /// Value.
    pub value: f64,
    /// Standard deviation, in the value's unit: the larger of `std_white` and the one that
    /// holds when the residual comes in runs (see [`ResidualRuns`]); a real log's residual
    /// is seldom white, and the white-residual figure then understates how far a size
    /// refitted on other data moves.
    pub std: f64,
    /// Standard deviation from `s^2 (J^T J)^-1`, which assumes a white residual; the size
    /// gate of the search judges a candidate on it (see the guide).
    pub std_white: f64,
    /// Unit.
    pub unit: String,
}

impl ParamEstimate {
    /// A parameter with a white-residual standard deviation `std` (both fields alike until
    /// [`ParamEstimate::widen`] takes the residual's runs into account).
    pub fn new(name: impl Into<String>, value: f64, std: f64, unit: impl Into<String>) -> Self {
        Self {
            name: name.into(),
            value,
            std,
            std_white: std,
            unit: unit.into(),
        }
    }

    /// `std` the larger of itself (at first the white-residual figure) and `runs_std`, the
    /// same parameter's standard deviation from a covariance that holds for a residual in
    /// runs or for logs that disagree. A figure that is not a number leaves `std` as it is.
    pub fn widen(&mut self, runs_std: f64) {
        if runs_std.is_finite() && runs_std > self.std {
            self.std = runs_std;
        }
    }
}

/// The scenario's calibrated model replayed on the logs as given: drive and every effect at
/// their calibrated values, only each log's encoder zero fitted on it (one number per
/// log, so its error is as good as held out).
#[derive(Clone, Debug, Serialize)]
pub struct CalibratedModelScore {
    /// RMS transmission error over the logs, mrad; `None` when the calibrated drive cannot
    /// carry one of them (`cannot_carry` says where): a replay that stopped is no number.
    pub rmse_mrad: Option<f64>,
    /// The same per log, in `logs` order, mrad (`None` for a log the drive cannot carry).
    pub per_log_mrad: Vec<Option<f64>>,
    /// Held-out RMS transmission error of the model the search on top started from (the
    /// calibrated model, on the drive raised to carry the logs where `cannot_carry` says
    /// so), each log's zero fitted on the training blocks, mrad: the error each candidate
    /// added on top is judged against.
    pub held_out_mrad: f64,
    /// Where the calibrated drive as given cannot carry a log's load, and the drive the
    /// search on top then ran on; `None` when it carries every log.
    pub cannot_carry: Option<CarryRaise>,
    /// What was fitted on each log before it was judged: its encoder zero and the terms the
    /// scenario marks as per log (`identify.per_log`).
    pub refitted_per_log: Vec<String>,
    /// Each log's own value of every term marked per log, added to the calibrated one, in
    /// `logs` order (empty when none is marked).
    pub per_log_terms: Vec<PerLogTerms>,
    /// One-column effects the calibration carries that `identify.per_log` does not refit
    /// on each log (an encoder delay, say): the replay holds them at their calibrated
    /// size, and the search on top tries each at one other size shared by the logs
    /// judged ([`Diagnosis::resized`]).
    pub held_not_refitted: Vec<String>,
    /// What its residual still follows, strongest first.
    pub residual_signatures: Vec<ResidualSignature>,
}

/// A calibrated drive that cannot carry a log's load (gross slip or slack in the replay),
/// and the drive raised so that it does (its preload, or its friction coefficient when the
/// preload is known, by the least number of 5 % steps). The friction coefficient and
/// preload of an instrument whose load never reverses are weakly pinned, and a joint
/// calibration tends to leave them where the heaviest calibration log only just holds: a
/// new log a few per cent heavier stops the replay there.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct CarryRaise {
    /// Why the replay stopped: the log, the time and the fault.
    pub fault: String,
    /// Friction coefficient as calibrated and as raised here (typical 0.05 to 0.3).
    pub friction_coefficient: [f64; 2],
    /// Preload as calibrated and as raised here, N.
    pub preload_n: [f64; 2],
}

/// One log's own values of the terms a calibrated scenario refits per log.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PerLogTerms {
    /// The log, as named in `logs`.
    pub log: String,
    /// The log's part of each term, added to the calibrated value.
    pub values: Vec<PerLogValue>,
}

/// A log's own part of one term refitted per log.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PerLogValue {
    /// Effect name, e.g. `load_compliance`.
    pub effect: String,
    /// The log's part, added to the calibrated value, in `unit` (a compliance of typically
    /// 1e-4 to 1e-2 rad/(N m)).
    pub value: f64,
    /// Unit: `rad/(N m)` for `load_compliance`, `s` for `encoder_delay`, `1` for
    /// `encoder_scale_error`, `rad/s` for `thermal_drift`.
    pub unit: String,
}

/// The sign of an effect found, with what it means.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct EffectDirection {
    /// Effect name.
    pub effect: String,
    /// Its fitted size, with sign, in the effect's unit.
    pub value: f64,
    /// What the sign means for the drive.
    pub meaning: String,
}

/// A carried effect found at another size than the calibration's.
#[derive(Clone, Debug, Serialize)]
pub struct ResizedEffect {
    /// Effect name.
    pub effect: String,
    /// Its size in the scenario's `[effects]`, in `unit`.
    pub calibrated: f64,
    /// Its size on the logs judged (calibrated plus the change fitted on top), in `unit`.
    pub found: f64,
    /// Standard deviation of the change, in `unit`.
    pub std: f64,
    /// Unit of the sizes (s for an encoder delay, rad/(N m) for a compliance).
    pub unit: String,
    /// With several logs, each log's own size (the shared one plus what the log alone
    /// adds, its zero refitted with it), `(log, size)` in `logs` order: logs that differ
    /// call for `identify.per_log`. Empty for one log.
    pub per_log: Vec<(String, f64)>,
}

/// Held-out score of one candidate.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateScore {
    /// Effect name.
    pub name: String,
    /// Held-out RMSE with the effect added to the model it was tried on, mrad.
    pub rmse_heldout_mrad: f64,
    /// Relative held-out RMSE gain, percent.
    pub gain_percent: f64,
    /// Fraction of the structured residual variance (above noise floor) it explains.
    pub explained_fraction: f64,
    /// Score used for ranking (held-out BIC-like: `n ln(mse) + k ln(n)`, lower is better).
    pub score: f64,
    /// Whether it was accepted.
    pub accepted: bool,
    /// Selection round (1 = tried on the base model).
    pub round: usize,
    /// Why it was accepted or not.
    pub verdict: String,
}

/// Candidates that explain the logs as well as an accepted one, held out: the logs cannot
/// tell them apart, and the accepted name is one of several that fit. Found in the round
/// that accepted the effect and confirmed on the whole model the search ended with.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Indistinguishable {
    /// The accepted effect, or pair (`a + b`).
    pub accepted: String,
    /// Held-out RMSE of the effects found, on the search's last calibration, mrad.
    pub rmse_heldout_mrad: f64,
    /// Each candidate that, in the accepted one's place with the other effects kept,
    /// leaves at most [`super::TIE_FRACTION`] more above the noise floor or comes within
    /// [`super::TIE_RMSE_FRACTION`] of its held-out RMSE, closest first.
    pub alternatives: Vec<Alternative>,
}

/// One candidate as good as an accepted effect, held out.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Alternative {
    /// Effect name, or pair (`a + b`).
    pub name: String,
    /// Held-out RMSE of the effects found with it in the accepted one's place, mrad.
    pub rmse_heldout_mrad: f64,
}

/// A baseline model's held-out score.
#[derive(Clone, Debug, Serialize)]
pub struct BaselineScore {
    /// Model name.
    pub name: String,
    /// Held-out RMSE, mrad.
    pub rmse_heldout_mrad: f64,
    /// Fitted parameters.
    pub params: Vec<ParamEstimate>,
}

/// Time histories of one log for plots.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    /// Log source.
    pub log: String,
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Input angle, rad.
    pub theta_in_rad: Vec<f64>,
    /// Output angle, rad.
    pub theta_out_rad: Vec<f64>,
    /// Input velocity, rad/s.
    pub velocity_rad_s: Vec<f64>,
    /// Transmitted load (the torque the drive carries), N m.
    pub load_nm: Vec<f64>,
    /// Measured transmission error (fitted ratio, encoder zero removed), rad.
    pub measured_rad: Vec<f64>,
    /// Base model prediction, rad.
    pub base_rad: Vec<f64>,
    /// Extended model prediction, rad.
    pub extended_rad: Vec<f64>,
    /// Whether the sample was held out in the log-level split.
    pub held_out: bool,
    /// Stretches flagged as not the drive, in this trace's time: (from, to, legend label),
    /// s.
    pub excluded: Vec<(f64, f64, String)>,
}

/// How strongly the extended model's residual follows one logged variable: the RMS of the
/// residual's means in bins of equal sample count along the variable (all logs together),
/// so noise averages out and structure along the variable stays.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct ResidualSignature {
    /// The variable (`input angle`, `transmitted load`, `input velocity`).
    pub variable: String,
    /// RMS of the residual's bin means along it, mrad.
    pub binned_rms_mrad: f64,
    /// That over the noise floor: above 1, structure along this variable that noise does
    /// not explain.
    pub ratio_to_floor: f64,
}

/// How the final fit's residual comes in runs, and what that does to the parameters'
/// `+-` ([`super::identifiability::long_run`]).
#[derive(Clone, Debug, Serialize)]
pub struct ResidualRuns {
    /// Integrated correlation time of the residual, samples: 1 for a white residual,
    /// `(1 + rho) / (1 - rho)` for a first-order autoregression.
    pub correlation_samples: f64,
    /// The same at the logs' mean sample interval, s.
    pub correlation_s: f64,
    /// Batch of the long-run covariance, samples (about five correlation times).
    pub batch_samples: usize,
    /// Whether the residual is correlated over more than a quarter of the longest stretch
    /// of fitted rows can hold, or wanders without end: even the widened `+-` understate.
    pub batch_capped: bool,
    /// Median over the reported parameters of `std / std_white` (1: the runs change
    /// nothing).
    pub median_widening: f64,
    /// Largest such ratio, and the parameter it belongs to.
    pub max_widening: f64,
    /// Parameter of [`ResidualRuns::max_widening`].
    pub max_widening_parameter: String,
    /// Logs whose disagreement also bounds each `+-` from below (the scatter of their
    /// summed scores, see the guide); 0 when fewer than five logs have fitted rows and
    /// only the runs within a log count.
    pub between_logs: usize,
}

/// What each `+-` is the larger of, in words, for a report: "the larger of the
/// white-residual one and one from batches of N samples", with `capped` after the batches,
/// and the logs' disagreement as a third when it took part ([`ResidualRuns::between_logs`]).
pub fn uncertainty_sources(r: &ResidualRuns, capped: &str) -> String {
    if r.between_logs == 0 {
        format!(
            "the larger of the white-residual one and one from batches of {} samples{capped}",
            r.batch_samples
        )
    } else {
        format!(
            "the largest of the white-residual one, one from batches of {} samples{capped} and one from how far the {} logs disagree (the scatter of their summed scores, as a jackknife over the logs sees it)",
            r.batch_samples, r.between_logs
        )
    }
}

impl ResidualRuns {
    /// Widen each of `params` by the same parameter's standard deviation in the table
    /// `table` builds on the runs' covariance and on the covariance between logs (when
    /// there is one), and record how much that was.
    pub(crate) fn widen(
        runs: &super::identifiability::Runs,
        params: &mut [ParamEstimate],
        table: impl Fn(&nalgebra::DMatrix<f64>) -> Vec<ParamEstimate>,
        sample_interval_s: f64,
    ) -> Self {
        let in_runs = table(&runs.cov);
        let in_between = runs.between_logs.as_ref().map(&table);
        let mut ratios = Vec::new();
        let (mut max_widening, mut max_widening_parameter) = (1.0, String::new());
        for p in params.iter_mut() {
            for table in std::iter::once(&in_runs).chain(in_between.as_ref()) {
                if let Some(q) = table.iter().find(|q| q.name == p.name) {
                    p.widen(q.std);
                }
            }
            if p.std_white > 0.0 && p.std_white.is_finite() && p.std.is_finite() {
                let r = p.std / p.std_white;
                if r > max_widening {
                    (max_widening, max_widening_parameter) = (r, p.name.clone());
                }
                ratios.push(r);
            }
        }
        ratios.sort_by(f64::total_cmp);
        let median_widening = match ratios.len() {
            0 => 1.0,
            n if n % 2 == 1 => ratios[n / 2],
            n => 0.5 * (ratios[n / 2 - 1] + ratios[n / 2]),
        };
        Self {
            correlation_samples: runs.correlation_samples,
            correlation_s: runs.correlation_samples * sample_interval_s,
            batch_samples: runs.batch_samples,
            batch_capped: runs.batch_capped,
            median_widening,
            max_widening,
            max_widening_parameter,
            between_logs: if in_between.is_some() { runs.logs } else { 0 },
        }
    }
}

/// Result of [`super::diagnose`].
#[derive(Clone, Debug, Serialize)]
pub struct Diagnosis {
    /// Strongest accepted effect, `none` (nothing beats the noise) or `unexplained`
    /// (structure remains that no candidate explains).
    pub cause: String,
    /// Every accepted effect, strongest first.
    pub causes: Vec<String>,
    /// Held-out RMSE of the calibrated base model, mrad.
    pub rmse_base_mrad: f64,
    /// Held-out RMSE of the extended model, mrad.
    pub rmse_extended_mrad: f64,
    /// `100 (1 - extended/base)`.
    pub gain_percent: f64,
    /// Noise floor (sensor noise and quantisation), mrad: the smallest reading of the
    /// residuals of the base model, the calibrated instrument, each model the search
    /// accepted and the final one, never below the encoders' quantisation (0.0057 mrad
    /// for the shipped gimbal's 2^16 and 2^20-count encoders; 0.50 mrad on the da Vinci
    /// logs).
    pub noise_floor_mrad: f64,
    /// Held-out RMSE of the extended model over the noise floor (about 1 when nothing is
    /// left).
    pub structure_ratio: f64,
    /// Whether structure above the noise remains after the extension (the decision rule:
    /// held-out RMSE above `identify.none_within_floor`, 1.25 by default, times the floor).
    pub unexplained_structure: bool,
    /// Ljung-Box whiteness test of the extended model's residual (10 lags, thinned to about
    /// 150 samples so that sample-to-sample quantisation colour is diluted while a
    /// structure of the record's time scale still shows), reported beside the decision as a
    /// second opinion: p << 1e-3 when structure remains. In tests it flags every
    /// unmodelled resonance but also rejects about half of the clean, quantised logs, which
    /// is why it does not decide.
    pub residual_whiteness: Option<whiteness::Whiteness>,
    /// How the final residual comes in runs and how far that widened the parameters' `+-`
    /// (`None` when no log is long enough to hold a batch).
    pub residual_runs: Option<ResidualRuns>,
    /// Calibrated base and effect parameters.
    pub params: Vec<ParamEstimate>,
    /// Every candidate tried.
    pub candidates: Vec<CandidateScore>,
    /// Play-operator (deadband) model for comparison.
    pub play_operator: Option<BaselineScore>,
    /// Whether the extended model's held-out error is below the play operator's (absent
    /// when the play operator was skipped). When it is not, `cause` is `unexplained`
    /// whatever `causes` holds: the effects found improve on the base model but describe
    /// the logs less well than a deadband does.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beats_play_operator: Option<bool>,
    /// Which way each signed effect found went, in words (compliance: a link giving way
    /// with the load, or a drive stiffer than the cable model).
    #[serde(default)]
    pub directions: Vec<EffectDirection>,
    /// Effects the calibrated instrument carries that the logs judged show at another
    /// size (found by the search on top, past the same gate as a new effect): empty
    /// when no scenario `[effects]` were given or every carried size stands.
    #[serde(default)]
    pub resized: Vec<ResizedEffect>,
    /// The candidates the search could try, named as in `candidates`; none is tried when
    /// the model's error is already within [`super::SEARCH_ENDS_WITHIN`] of the noise floor.
    #[serde(default)]
    pub searchable: Vec<String>,
    /// How data was held out.
    pub holdout: String,
    /// Logs used.
    pub logs: Vec<String>,
    /// Columns of each log that the format does not define, ignored: `(log, columns)`,
    /// logs without any left out.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ignored_columns: Vec<(String, Vec<String>)>,
    /// Calibrations that stopped on their iteration limit while still improving, each
    /// with its limit: their parameters are the best reached, not a converged optimum.
    /// Empty when every calibration converged.
    #[serde(default)]
    pub fits_on_limit: Vec<String>,
    /// Parameters of the extended calibration that ended on a bound, each a sentence.
    #[serde(default)]
    pub params_on_bound: Vec<String>,
    /// Parameters the logs do not pin (uncertainty larger than the value, correlation
    /// above 0.99 with another, or a direction the data does not see), each with why:
    /// their values are one of many that fit as well, and their `std` means little.
    #[serde(default)]
    pub not_identifiable: Vec<identifiability::NotIdentifiable>,
    /// Accepted effects that other candidates explain as well, held out (within
    /// [`super::TIE_FRACTION`] above the floor or [`super::TIE_RMSE_FRACTION`] in RMSE):
    /// the logs cannot tell them apart. Empty when every choice
    /// stood clear of the rest.
    #[serde(default)]
    pub indistinguishable: Vec<Indistinguishable>,
    /// The extended model's residual along each logged variable, strongest first: which
    /// variable the structure that remains follows (the residual plot to look at).
    #[serde(default)]
    pub residual_signatures: Vec<ResidualSignature>,
    /// The scenario's calibrated model (`[effects]`) as given, on these logs: absent when
    /// the scenario carries no effects.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibrated_model: Option<CalibratedModelScore>,
    /// What was cut from the start of each log (start-up transient), in `logs` order.
    pub start_cuts: Vec<startup::StartCut>,
    /// Stretches of the logs that are not the drive (a jerk, a stuck reading, a departure
    /// from the input's motion), in `logs` order then time; their rows are neither fitted
    /// nor scored unless `action` is `"kept"`. Empty when nothing was flagged.
    pub excluded_segments: Vec<super::segments::Segment>,
    /// Calibrated drive.
    pub drive: DriveParams,
    /// Identified effects, as stored in a scenario.
    pub effects: EffectsParams,
    /// Plot data.
    #[serde(skip)]
    pub traces: Vec<Trace>,
}
