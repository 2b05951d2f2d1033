//! Calibration across logs and validation by whole logs.
//!
//! One instrument, several bench runs: geometry, ratio shape, compliance, friction and the
//! extension's weights are the instrument's and shared by every log; only what the bench
//! changes between runs (the encoder zero; the load, which is measured) is per log. Each log
//! is left out in turn, the shared model calibrated on the others and scored on it, beside
//! a play operator fitted to that log itself (held-out time blocks inside it).

use serde::Serialize;

use super::effects::{EffectName, IdentifyParams};
use super::model::{Evaluator, Fitted, NlParam, Prepared, Spec};
use super::startup::{self, StartCut, StartMode};
use super::{extra_effects, play, BenchLog, IdentifyError, ParamEstimate, ResidualRuns};
use crate::physics::DriveParams;

/// Shared parameters whose standard deviation exceeds this fraction of their value are
/// flagged as not pinned down by the logs.
pub const NOT_PINNED_REL_STD: f64 = 0.5;

/// A shared parameter of the joint calibration over every log, with what the folds (each
/// calibrated without one log) say of it.
#[derive(Clone, Debug, Serialize)]
pub struct SharedParam {
    /// The estimate; its `std` is the reported 1-sigma, in the parameter's unit: the larger
    /// of [`SharedParam::std_fit`] and [`SharedParam::jackknife_std`] (a value held on its
    /// bound keeps the fit's).
    #[serde(flatten)]
    pub estimate: ParamEstimate,
    /// The joint calibration's own 1-sigma, in the parameter's unit: the largest of the
    /// white-residual one, the runs' and, with five or more logs, the logs' disagreement
    /// as a linear view of the fit sees it.
    pub std_fit: f64,
    /// Jackknife spread of the folds' values, in the parameter's unit, as in
    /// [`LooTable::jackknife`] (`None` with fewer than three logs, or where a fold lacks it).
    pub jackknife_std: Option<f64>,
    /// Why the logs do not identify the parameter, in words (`None` when they do, or when
    /// it is held on its bound): the folds scatter by more than its value (the logs
    /// disagree on it), or its uncertainty exceeds its value.
    pub not_identifiable: Option<String>,
}

impl SharedParam {
    /// `estimate` from the joint calibration judged with the folds' jackknife spread
    /// `jackknife` (its unit).
    pub fn judge(mut estimate: ParamEstimate, jackknife: Option<f64>) -> Self {
        let std_fit = estimate.std;
        let held = on_bound(std_fit, estimate.value);
        let exceeds = super::identifiability::uncertainty_exceeds_value(&estimate);
        // The reported +- is the larger of the fit's and the jackknife's. The fit's comes
        // from a linear view of one optimum; the folds are the calibration itself redone
        // without each log, so where the law is nonlinear in the logs (a threshold growth
        // that leans on the lightest and heaviest log) they show a scatter the linear view
        // does not, and an uncertainty smaller than how far the answer moves when one log
        // is dropped would be claimed precision the logs do not give. The jackknife is not
        // the only figure because it can be too small the other way: folds that start
        // where the optimum is flat need not move off their start at all. Taking the
        // larger errs towards calling a parameter unpinned, the safe side for a user
        // deciding whether to trust a size.
        if !held {
            if let Some(j) = jackknife {
                estimate.widen(j);
            }
        }
        // A value whose natural size is zero (a runout's phase) is not judged against it.
        let natural = super::identifiability::zero_is_natural(&estimate.name);
        let v = estimate.value.abs();
        let apart = jackknife.filter(|j| !natural && *j > v).map(|j| {
            format!(
                "the logs disagree on it (the folds, each calibrated without one log, scatter by {}, more than its value)",
                crate::compact(j)
            )
        });
        let not_identifiable = if held {
            None
        } else if let Some(exceeds) = exceeds {
            Some(match apart {
                Some(a) => format!("{exceeds}, and {a}"),
                None => exceeds,
            })
        } else {
            apart.map(|a| {
                format!(
                    "{a}, where the joint fit alone gives +- {}",
                    crate::compact(std_fit)
                )
            })
        };
        Self {
            estimate,
            std_fit,
            jackknife_std: jackknife,
            not_identifiable,
        }
    }

    /// Whether the joint calibration held it on its bound (no `+-` reported).
    fn held(&self) -> bool {
        on_bound(self.std_fit, self.estimate.value)
    }
}

/// Whether a joint calibration's `value` with 1-sigma `std_fit` is held on its bound:
/// exactly zero is a term its bound holds (a weight kept non-negative), and no spread at
/// all one the fit does not move; neither is an estimate to widen or to judge.
fn on_bound(std_fit: f64, value: f64) -> bool {
    std_fit == 0.0 || value == 0.0
}

/// One log left out.
#[derive(Clone, Debug, Serialize)]
pub struct LooRow {
    /// Log source.
    pub log: String,
    /// Rows scored (after decimation and the start-up cut).
    pub rows: usize,
    /// RMS error of the base capstan model calibrated on the other logs, mrad.
    pub base_mrad: f64,
    /// RMS error of the extended model calibrated on the other logs, mrad.
    pub extended_mrad: f64,
    /// RMS error of a play operator fitted to this log, on its own held-out time blocks,
    /// mrad (`None` when the play fit failed; the message is in `notes`).
    pub play_mrad: Option<f64>,
    /// Noise floor of the log from encoder resolution, mrad.
    pub floor_mrad: f64,
    /// What the extended model's residual on this log still follows, in words: within
    /// twice the floor it is noise; otherwise the signal (input angle, transmitted load,
    /// input velocity) whose binned residual means are largest, when above the floor.
    pub residual: String,
    /// How much this log pulls the shared model from the others: the others' mean
    /// in-sample RMS with it in the joint calibration less without it, over the former,
    /// % (a few % for a log that agrees with the rest).
    pub pull_percent: f64,
    /// The log diagnosed alone against the calibration on the other logs, as
    /// `diagnose --scenario` judges a new log of the instrument once that calibration is
    /// saved as a scenario; `None` when that diagnosis failed (the message is in `notes`).
    pub as_new_log: Option<NewLogScore>,
}

/// A left-out log diagnosed alone against the calibration on the others, as a new log of
/// the instrument would be: the calibrated model with what the search finds on top, its
/// encoder zero fitted on the log's other time blocks, against the base capstan model
/// recalibrated on the log and a play operator fitted to it, all held out on those blocks.
#[derive(Clone, Debug, Serialize)]
pub struct NewLogScore {
    /// Held-out error of the calibrated model with what was found on top, mrad.
    pub extended_mrad: f64,
    /// Held-out error of the base capstan model recalibrated on the log, mrad.
    pub base_mrad: f64,
    /// Held-out error of the play operator fitted to the log, mrad.
    pub play_mrad: Option<f64>,
    /// The diagnosis's cause (`none`, `unexplained` or the effects found).
    pub cause: String,
    /// Whether the calibrated drive could not carry the log and had its preload raised
    /// ([`super::CarryRaise`]).
    pub preload_raised: bool,
}

impl NewLogScore {
    /// Whether the calibrated model beats both baselines on the log.
    pub fn beats_both(&self) -> bool {
        self.extended_mrad < self.base_mrad
            && self.play_mrad.is_some_and(|p| self.extended_mrad < p)
    }
}

/// Bins for the residual structure check (equal counts).
const STRUCTURE_BINS: usize = 20;

/// RMS of the residual's bin means over equal-count bins of `signal`, rad: the part of the
/// residual that is a function of that signal (about floor/sqrt(n/bins) for noise).
pub fn binned_structure(resid: &[f64], signal: &[f64]) -> f64 {
    let n = resid.len().min(signal.len());
    if n < 2 * STRUCTURE_BINS {
        return 0.0;
    }
    let mut idx: Vec<usize> = (0..n).collect();
    idx.sort_by(|a, b| signal[*a].total_cmp(&signal[*b]));
    let mean = resid[..n].iter().sum::<f64>() / n as f64;
    let mut s = 0.0;
    for b in 0..STRUCTURE_BINS {
        let part = &idx[b * n / STRUCTURE_BINS..(b + 1) * n / STRUCTURE_BINS];
        let m = part.iter().map(|i| resid[*i]).sum::<f64>() / part.len().max(1) as f64;
        s += (m - mean).powi(2) * part.len() as f64;
    }
    (s / n as f64).sqrt()
}

/// How strongly `resid` (rad, the logs' samples in order) follows the input angle, the
/// transmitted load and the input velocity of `logs`: the RMS of its bin means along each
/// ([`binned_structure`]), over the noise floor `floor` (rad); strongest first.
/// Only rows in `keep` count.
pub fn residual_signatures(
    logs: &[Prepared],
    resid: &[f64],
    keep: &[bool],
    floor: f64,
) -> Vec<super::ResidualSignature> {
    let along = |pick: fn(&Prepared) -> &[f64]| -> Vec<f64> {
        logs.iter()
            .flat_map(|l| pick(l).iter().copied())
            .zip(keep)
            .filter(|(_, k)| **k)
            .map(|(v, _)| v)
            .collect()
    };
    let resid: Vec<f64> = resid
        .iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(r, _)| *r)
        .collect();
    signatures(
        &resid,
        &[
            ("input angle", along(|l| &l.th_in)),
            ("transmitted load", along(|l| &l.torque)),
            ("input velocity", along(|l| &l.vel_in)),
        ],
        floor,
    )
}

/// [`residual_signatures`] for named signals.
fn signatures(
    resid: &[f64],
    signals: &[(&str, Vec<f64>)],
    floor: f64,
) -> Vec<super::ResidualSignature> {
    let mut out: Vec<super::ResidualSignature> = signals
        .iter()
        .map(|(name, signal)| {
            let v = binned_structure(resid, signal);
            super::ResidualSignature {
                variable: (*name).to_string(),
                binned_rms_mrad: v * 1e3,
                ratio_to_floor: v / floor.max(1e-300),
            }
        })
        .collect();
    out.sort_by(|a, b| b.ratio_to_floor.total_cmp(&a.ratio_to_floor));
    out
}

fn residual_verdict(p: &Prepared, resid: &[f64], keep: &[bool], rmse: f64, floor: f64) -> String {
    if rmse <= 2.0 * floor {
        return "within twice the noise floor".into();
    }
    match residual_signatures(std::slice::from_ref(p), resid, keep, floor)
        .first()
        .filter(|g| g.ratio_to_floor > 1.0)
    {
        Some(g) => format!(
            "unexplained: follows the {} ({:.2} mrad RMS of binned means)",
            g.variable, g.binned_rms_mrad
        ),
        None => "above the floor without structure in angle, load or velocity".into(),
    }
}

/// Joint calibration over every log and the leave-one-log-out table.
#[derive(Clone, Debug, Serialize)]
pub struct LooTable {
    /// Extension used (fixed for every fold).
    pub effects: Vec<String>,
    /// One row per log, in input order.
    pub rows: Vec<LooRow>,
    /// Shared parameters of the joint calibration over all logs, with 1-sigma and whether
    /// the logs identify them.
    pub shared: Vec<SharedParam>,
    /// How the joint calibration's residual comes in runs and how far that widened the
    /// shared parameters' `+-` (`None` when the covariance could not be computed).
    pub residual_runs: Option<ResidualRuns>,
    /// Per shared parameter, how far the folds' calibrations (each without one log) scatter:
    /// the jackknife standard deviation over the logs, a check on the `+-` that needs no
    /// assumption about the residual (empty with fewer than three logs).
    pub jackknife: Vec<JackknifeSpread>,
    /// Shared parameters the logs do not pin down (relative std above
    /// [`NOT_PINNED_REL_STD`], the folds' spread included), with why.
    pub not_pinned: Vec<String>,
    /// Shared nonlinear parameters of the joint calibration that ended on a bound.
    pub on_bound: Vec<String>,
    /// What was cut from each log's start.
    pub start_cuts: Vec<StartCut>,
    /// Stretches of the logs that are not the drive ([`super::segments::detect`]), neither
    /// fitted nor scored unless `action` is `"kept"`; empty when nothing was flagged.
    pub excluded_segments: Vec<super::segments::Segment>,
    /// How far input-pulley runout can be told from a ratio shape over the stroke (0..1).
    pub runout_separability: f64,
    /// Limits and warnings in words.
    pub notes: Vec<String>,
    /// Logs that pull the shared model away from the others (pull above
    /// [`PULL_FLAG_PERCENT`]), each with what its exclusion does.
    pub disagreeing: Vec<String>,
    /// Logs where the extended model beats the base model.
    pub wins_over_base: usize,
    /// Logs where the extended model beats the play operator fitted to the log.
    pub wins_over_play: usize,
    /// Logs where the diagnosis of the log alone, against the calibration on the others,
    /// beats both the base model and the play operator ([`LooRow::as_new_log`]).
    pub new_log_wins: usize,
    /// Drive of the joint calibration on every log.
    pub drive: DriveParams,
    /// Effects of the joint calibration, as stored in a scenario.
    pub effects_params: super::effects::EffectsParams,
}

/// How far one shared parameter moves from fold to fold.
#[derive(Clone, Debug, Serialize)]
pub struct JackknifeSpread {
    /// Parameter name, as in the shared table.
    pub name: String,
    /// Jackknife standard deviation over the logs, `sqrt((n - 1) / n sum (x_i - mean)^2)`
    /// with `x_i` the fold without log `i`, in the parameter's unit: the spread of the
    /// joint calibration that leaving out a log at a time shows.
    pub std: f64,
}

/// The jackknife spread of each of `shared` over the folds' values of it (a parameter
/// missing from a fold, or not a number there, gets none).
fn jackknife_spread(shared: &[ParamEstimate], folds: &[&[ParamEstimate]]) -> Vec<JackknifeSpread> {
    let n = folds.len();
    if n < 3 {
        return Vec::new();
    }
    shared
        .iter()
        .filter_map(|p| {
            let xs: Vec<f64> = folds
                .iter()
                .map(|f| f.iter().find(|q| q.name == p.name).map(|q| q.value))
                .collect::<Option<_>>()?;
            if xs.iter().any(|x| !x.is_finite()) {
                return None;
            }
            let m = xs.iter().sum::<f64>() / n as f64;
            let ss: f64 = xs.iter().map(|x| (x - m).powi(2)).sum();
            Some(JackknifeSpread {
                name: p.name.clone(),
                std: ((n - 1) as f64 / n as f64 * ss).sqrt(),
            })
        })
        .collect()
}

/// The shared parameters the logs do not pin down (relative std above
/// [`NOT_PINNED_REL_STD`]), each in words with why.
fn not_pinned(shared: &[SharedParam]) -> Vec<String> {
    shared
        .iter()
        .filter(|s| {
            let p = &s.estimate;
            // Weights pinned at zero by their bound carry no information either way.
            let at_bound = p.name.starts_with("friction_memory_") && p.value == 0.0;
            let pinned = p.std.is_finite() && p.std <= NOT_PINNED_REL_STD * p.value.abs();
            !at_bound && !pinned
        })
        .map(|s| {
            let p = &s.estimate;
            // Named where the folds' spread is what leaves it unpinned.
            let disagree = match s.jackknife_std {
                Some(j) if !s.held() && s.std_fit <= NOT_PINNED_REL_STD * p.value.abs() => {
                    format!(
                        "; the logs disagree on it: the folds, each calibrated without one log, scatter by {}, {:.1} times the joint fit's +- of {}",
                        crate::compact(j),
                        j / s.std_fit,
                        crate::compact(s.std_fit)
                    )
                }
                _ => String::new(),
            };
            format!(
                "{} = {:.4e} +- {:.2e} {}: not pinned down by these logs{disagree}",
                p.name, p.value, p.std, p.unit
            )
        })
        .collect()
}

/// One model calibrated with a log left out.
struct Fold {
    /// RMS on the log left out, rad.
    held_rms: f64,
    /// Residual on the log left out, rad.
    held: Vec<f64>,
    /// Every log's RMS, rad (in-sample for the others).
    per_log_rms: Vec<f64>,
    /// The fit on the other logs.
    fit: Fitted,
    /// Its nonlinear parameters' layout.
    nl: Vec<(NlParam, f64, f64, f64)>,
    /// Stroke and memory thresholds of the design.
    basis: ((f64, f64), [f64; extra_effects::MEMORY_THRESHOLDS]),
}

/// A log whose exclusion lowers the others' error by more than this (%) is named in the
/// report: it disagrees with the shared model the others agree on.
pub const PULL_FLAG_PERCENT: f64 = 5.0;

fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
    }
}

fn spec(drive: &DriveParams, ident: &IdentifyParams, effects: &[EffectName]) -> Spec {
    Spec {
        drive: drive.clone(),
        fit_mu: ident.is_unknown("friction_coefficient"),
        fit_pre: ident.is_unknown("preload_n"),
        fit_g: ident.is_unknown("cable_modulus_n"),
        fit_ratio: ident.is_unknown("ratio"),
        effects: effects.to_vec(),
        ident: ident.clone(),
        calibrated: None,
    }
}

/// Sample rate of a raw log, Hz.
fn rate(log: &BenchLog) -> f64 {
    let n = log.t_s.len();
    if n < 2 {
        return 0.0;
    }
    (n - 1) as f64 / (log.t_s[n - 1] - log.t_s[0]).max(1e-300)
}

/// Refuse logs that cannot be one instrument on one bench: different sample rates, encoder
/// resolutions or transmission ratios (judged away from the reversals, where the load
/// cannot move it: [`super::instrument::travel_ratio`]); a log without a reversal.
pub fn check_logs(raw: &[BenchLog], prepared: &[Prepared]) -> Result<(), IdentifyError> {
    let Some(first) = raw.first() else {
        return Err(IdentifyError::NoLogs);
    };
    let r0 = rate(first);
    let p0 = &prepared[0];
    // The whole-log slope of output on input moves with the load (free travel narrows as
    // tension takes up slack); the travel ratio far from reversals does not.
    let s0 = super::instrument::travel_ratio(p0);
    for (l, p) in raw.iter().zip(prepared).skip(1) {
        let bad = |message: String| IdentifyError::BadLog {
            log: l.source.clone(),
            message,
        };
        let r = rate(l);
        if (r / r0 - 1.0).abs() > 0.01 {
            return Err(bad(format!(
                "sampled at {r:.1} Hz but {} at {r0:.1} Hz; logs calibrated together must come from one bench setup (same sample rate)",
                first.source
            )));
        }
        for (name, q, q0) in [("input", p.q_in, p0.q_in), ("output", p.q_out, p0.q_out)] {
            if q > 0.0 && q0 > 0.0 && (q / q0 - 1.0).abs() > 0.01 {
                return Err(bad(format!(
                    "{name} encoder step {q:.3e} rad differs from {} ({q0:.3e} rad): a different instrument or encoder; calibrate each instrument on its own",
                    first.source
                )));
            }
        }
        if let (Some(s), Some(s0)) = (super::instrument::travel_ratio(p), s0) {
            if (s / s0 - 1.0).abs() > 0.05 {
                return Err(bad(format!(
                    "away from its reversals the output turns {s:.4} rad per input rad, in {} {s0:.4}: a different instrument (its transmission ratio differs by more than 5 %, which no load changes); calibrate each instrument on its own",
                    first.source
                )));
            }
        }
    }
    for p in prepared {
        if !p.dir.windows(2).any(|w| w[0] != w[1]) {
            return Err(IdentifyError::BadLog {
                log: p.source.clone(),
                message: "the input never reverses in this log (after the start-up cut); friction memory needs at least one reversal".into(),
            });
        }
    }
    Ok(())
}

/// Joint calibration over `logs` and leave-one-log-out validation of the base model and the
/// extension `effects` (fixed for every fold), with a play operator fitted to each left-out
/// log for comparison. Folds run in parallel. Typical: 10 to 60 s for eleven 20 s logs.
pub fn leave_one_out(
    drive: &DriveParams,
    ident: &IdentifyParams,
    logs: &[BenchLog],
    effects: &[EffectName],
    start: StartMode,
) -> Result<LooTable, IdentifyError> {
    leave_one_out_with_progress(drive, ident, logs, effects, start, &crate::progress::Silent)
}

/// [`leave_one_out`], reporting each finished fold to `progress` (units: logs held out,
/// one per log; the joint calibration over every log that follows the folds is not
/// counted and takes about as long as one fold). Results are those of [`leave_one_out`].
pub fn leave_one_out_with_progress(
    drive: &DriveParams,
    ident: &IdentifyParams,
    logs: &[BenchLog],
    effects: &[EffectName],
    start: StartMode,
    progress: &dyn crate::progress::Progress,
) -> Result<LooTable, IdentifyError> {
    leave_one_out_with_segments(drive, ident, logs, effects, start, false, progress)
}

/// [`leave_one_out_with_progress`]; `keep_segments` fits and scores the stretches of the
/// logs flagged as not the drive ([`super::segments::detect`]) instead of excluding them
/// (they are still reported, as `"kept"`).
pub fn leave_one_out_with_segments(
    drive: &DriveParams,
    ident: &IdentifyParams,
    logs: &[BenchLog],
    effects: &[EffectName],
    start: StartMode,
    keep_segments: bool,
    progress: &dyn crate::progress::Progress,
) -> Result<LooTable, IdentifyError> {
    if logs.len() < 2 {
        return Err(IdentifyError::Config {
            key: "leave-one-out".into(),
            message: format!(
                "{} log given; leaving one out needs at least two",
                logs.len()
            ),
        });
    }
    let (cut, start_cuts): (Vec<BenchLog>, Vec<StartCut>) =
        logs.iter().map(|l| startup::cut_start(l, start)).unzip();
    let mut prepared: Vec<Prepared> = logs
        .iter()
        .zip(&cut)
        .zip(&start_cuts)
        .map(|((l, c), s)| startup::prepare_after_cut(l, c, s, ident.max_rate_hz))
        .collect::<Result<_, _>>()?;
    check_logs(&cut, &prepared)?;
    let (segments, keep_per_log) =
        super::segments::rows_to_fit(&cut, &mut prepared, keep_segments)?;
    let keep: Vec<bool> = keep_per_log.iter().flatten().copied().collect();
    let n: usize = prepared.iter().map(|p| p.t.len()).sum();
    let ranges: Vec<std::ops::Range<usize>> = prepared
        .iter()
        .scan(0, |s, p| {
            let r = *s..*s + p.t.len();
            *s = r.end;
            Some(r)
        })
        .collect();

    type FoldOut = (LooRow, (Vec<f64>, Vec<ParamEstimate>), Option<String>);
    let fold = |k: usize| -> Result<FoldOut, IdentifyError> {
        let train: Vec<bool> = (0..n).map(|i| !ranges[k].contains(&i) && keep[i]).collect();
        let kept = |r: &[f64], g: &std::ops::Range<usize>| -> Vec<f64> {
            r[g.clone()]
                .iter()
                .zip(&keep[g.clone()])
                .filter(|(_, k)| **k)
                .map(|(v, _)| *v)
                .collect()
        };
        // The extension starts from the base calibration when it adds no nonlinear
        // parameter (the layouts agree), which saves most of its iterations.
        let score = |effs: &[EffectName], x0: Option<&[f64]>| -> Result<Fold, IdentifyError> {
            let mut ev = Evaluator::new(spec(drive, ident, effs), &prepared);
            let x0 = x0.filter(|x| x.len() == ev.nonlinear().len());
            let f = ev.fit(&train, x0, 30)?;
            let (mut r, _) = ev.residual(&f, &train)?;
            super::recenter_unfitted(&prepared, &mut r, &train, &keep);
            let held: Vec<f64> = r[ranges[k].clone()].to_vec();
            Ok(Fold {
                held_rms: rms(&kept(&r, &ranges[k])),
                held,
                per_log_rms: ranges.iter().map(|g| rms(&kept(&r, g))).collect(),
                nl: ev.nonlinear(),
                basis: ev.stroke_and_thresholds(),
                fit: f,
            })
        };
        let base_fold = score(&[], None)?;
        let (base, xb) = (base_fold.held_rms, base_fold.fit.x);
        let Fold {
            held_rms: ext,
            held: ext_resid,
            per_log_rms: others,
            fit: ext_fit,
            nl: ext_nl,
            basis,
            ..
        } = score(effects, Some(&xb))?;
        let train_torques = prepared
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != k)
            .map(|(_, p)| p.torque.as_slice());
        let no_cov = nalgebra::DMatrix::from_element(
            ext_nl.len() + ext_fit.coef.len(),
            ext_nl.len() + ext_fit.coef.len(),
            f64::NAN,
        );
        let (_, fold_drive, fold_effects) =
            as_scenario(drive, &ext_nl, &ext_fit, &no_cov, basis, train_torques);
        // The jackknife compares the folds with the joint calibration: a size read at the
        // mean torque is read at every log's mean, as the joint one is, so the spread is
        // the fit's and not the shift of a fold's own mean torque.
        let (fold_params, _, _) = as_scenario(
            drive,
            &ext_nl,
            &ext_fit,
            &no_cov,
            basis,
            prepared.iter().map(|p| p.torque.as_slice()),
        );
        let as_new_log = new_log_score(
            &fold_drive,
            &fold_effects,
            ident,
            &logs[k],
            start,
            keep_segments,
        );
        let one = std::slice::from_ref(&prepared[k]);
        let keep_k = &keep_per_log[k];
        let folds = super::block_folds(one, ident.holdout_blocks, keep_k);
        let play = play::cross_validate(one, drive, ident, &folds)
            .ok()
            .map(|b| b.rmse_heldout_mrad);
        let floor = super::noise_floor(one, &ext_resid, keep_k, drive.ratio());
        let q = {
            let p = &prepared[k];
            ((p.q_out.powi(2) + (p.q_in / drive.ratio()).powi(2)) / 12.0).sqrt()
        };
        // The floor from encoder resolution; the residual-difference estimate is reported
        // by the diagnosis, here the encoders decide.
        let floor = if q > 0.0 { q } else { floor };
        Ok((
            LooRow {
                log: prepared[k].source.clone(),
                rows: keep_k.iter().filter(|k| **k).count(),
                base_mrad: base * 1e3,
                extended_mrad: ext * 1e3,
                play_mrad: play,
                floor_mrad: floor * 1e3,
                residual: residual_verdict(&prepared[k], &ext_resid, keep_k, ext, floor),
                pull_percent: 0.0,
                as_new_log: as_new_log.as_ref().ok().cloned(),
            },
            (others, fold_params),
            as_new_log.err().map(|e| {
                format!(
                    "{}: diagnosed alone against the calibration on the others, it failed: {e}",
                    prepared[k].source
                )
            }),
        ))
    };
    use rayon::prelude::*;
    let counter = crate::progress::Counter::new(prepared.len(), progress);
    let folds: Vec<FoldOut> = (0..prepared.len())
        .into_par_iter()
        .map(|k| {
            let r = fold(k);
            counter.tick();
            r
        })
        .collect::<Result<_, _>>()?;

    // Joint calibration on every log: the shared parameters and how well they are pinned.
    let all = keep.clone();
    let mut ev = Evaluator::new(spec(drive, ident, effects), &prepared);
    let f: Fitted = ev.fit(&all, None, 40)?;
    let nl = ev.nonlinear();
    let np = nl.len() + f.coef.len();
    let (cov, runs) = match ev.identifiability_with_runs(&f, &all) {
        Ok((a, runs)) => (a.cov, runs),
        Err(_) => (nalgebra::DMatrix::from_element(np, np, f64::NAN), None),
    };
    let (stroke, thresholds) = ev.stroke_and_thresholds();
    let (mut shared, joint_drive, eff) = as_scenario(
        drive,
        &nl,
        &f,
        &cov,
        (stroke, thresholds),
        prepared.iter().map(|l| l.torque.as_slice()),
    );
    shared.retain(|p| !p.name.starts_with("encoder_zero["));
    let residual_runs = runs.map(|r| {
        let table = |cov: &nalgebra::DMatrix<f64>| {
            as_scenario(
                drive,
                &nl,
                &f,
                cov,
                (stroke, thresholds),
                prepared.iter().map(|l| l.torque.as_slice()),
            )
            .0
        };
        ResidualRuns::widen(
            &r,
            &mut shared,
            table,
            super::mean_sample_interval(&prepared),
        )
    });
    // How much each log pulls the shared model away from the others: their in-sample
    // error with it in the calibration against without it.
    let (joint_resid, _) = ev.residual(&f, &all)?;
    let joint: Vec<f64> = ranges
        .iter()
        .map(|g| {
            let v: Vec<f64> = joint_resid[g.clone()]
                .iter()
                .zip(&keep[g.clone()])
                .filter(|(_, k)| **k)
                .map(|(v, _)| *v)
                .collect();
            rms(&v)
        })
        .collect();
    let fold_params: Vec<&[ParamEstimate]> = folds.iter().map(|f| f.1 .1.as_slice()).collect();
    let jackknife = jackknife_spread(&shared, &fold_params);
    let shared: Vec<SharedParam> = shared
        .into_iter()
        .map(|p| {
            let j = jackknife.iter().find(|j| j.name == p.name).map(|j| j.std);
            SharedParam::judge(p, j)
        })
        .collect();
    let not_pinned = not_pinned(&shared);
    let mut rows = Vec::with_capacity(folds.len());
    let mut pulling = Vec::new();
    let mut new_log_failures = Vec::new();
    for (k, (mut row, (without, _), failed)) in folds.into_iter().enumerate() {
        new_log_failures.extend(failed);
        let others = |v: &[f64]| -> f64 {
            let sum: f64 = v
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != k)
                .map(|(_, x)| x)
                .sum();
            sum / (v.len() - 1).max(1) as f64
        };
        let (with_k, without_k) = (others(&joint), others(&without));
        row.pull_percent = if with_k > 0.0 {
            100.0 * (with_k - without_k) / with_k
        } else {
            0.0
        };
        if row.pull_percent > PULL_FLAG_PERCENT {
            pulling.push(format!(
                "{}: calibrated without it, the other logs' error falls by {:.0} % ({:.2} to {:.2} mrad RMS on average); a shared model cannot serve it and them together, and it weighs on every fold that keeps it",
                row.log,
                row.pull_percent,
                with_k * 1e3,
                without_k * 1e3
            ));
        }
        rows.push(row);
    }
    let on_bound = super::model::on_bounds(&nl, &f.x);
    let all_in: Vec<f64> = prepared.iter().flat_map(|p| p.th_in.clone()).collect();
    let sep = extra_effects::runout_separability(&all_in, stroke);
    let mut notes = Vec::new();
    if effects.contains(&EffectName::AngleDependentRatio) && sep < extra_effects::SEPARABLE_MIN {
        notes.push(format!(
            "input stroke {:.3} rad ({:.0} % of a revolution): a ratio shape and an eccentric input pulley (runout) leave the same error over it ({:.1} % of a runout's signature lies outside the shape's span); the angle-dependent ratio found here may equally be pulley runout, and only a stroke of a revolution or more tells them apart",
            stroke.1 - stroke.0,
            100.0 * (stroke.1 - stroke.0) / std::f64::consts::TAU,
            100.0 * sep
        ));
    }
    notes.extend(new_log_failures);
    for (k, r) in rows.iter().enumerate() {
        if r.play_mrad.is_none() {
            notes.push(format!(
                "{}: the play operator could not be fitted to this log",
                prepared[k].source
            ));
        }
    }
    let wins_over_base = rows
        .iter()
        .filter(|r| r.extended_mrad < r.base_mrad)
        .count();
    let wins_over_play = rows
        .iter()
        .filter(|r| r.play_mrad.is_some_and(|p| r.extended_mrad < p))
        .count();
    let new_log_wins = rows
        .iter()
        .filter(|r| r.as_new_log.as_ref().is_some_and(NewLogScore::beats_both))
        .count();
    Ok(LooTable {
        effects: effects.iter().map(|e| e.to_string()).collect(),
        rows,
        shared,
        residual_runs,
        jackknife,
        not_pinned,
        on_bound,
        start_cuts,
        excluded_segments: segments.into_iter().flatten().collect(),
        runout_separability: sep,
        notes,
        disagreeing: pulling,
        wins_over_base,
        wins_over_play,
        new_log_wins,
        drive: joint_drive,
        effects_params: eff,
    })
}

/// A fit of the shared model as a scenario stores it: the parameter table (with `cov`,
/// NaN where unknown), the drive and the effects. `basis` is the design's stroke and memory
/// thresholds, `torques` the loads of the logs it was fitted on (the memory's size is
/// reported at their mean).
fn as_scenario<'a>(
    drive: &DriveParams,
    nl: &[(NlParam, f64, f64, f64)],
    f: &Fitted,
    cov: &nalgebra::DMatrix<f64>,
    basis: ((f64, f64), [f64; extra_effects::MEMORY_THRESHOLDS]),
    torques: impl Iterator<Item = &'a [f64]>,
) -> (
    Vec<ParamEstimate>,
    DriveParams,
    super::effects::EffectsParams,
) {
    let mut d = drive.clone();
    for (p, v) in nl.iter().zip(&f.x) {
        match p.0 {
            NlParam::Mu => d.friction_coefficient = *v,
            NlParam::Preload => d.preload_n = *v,
            NlParam::Effect(_) | NlParam::Memory(_) => {}
        }
    }
    super::reported_parameters((drive, &d), nl, f, cov, basis, torques)
}

/// `log` diagnosed alone against `drive` and `effects` (a fold's calibration, as a saved
/// scenario carries it), as `diagnose --scenario` judges a new log.
fn new_log_score(
    drive: &DriveParams,
    effects: &super::effects::EffectsParams,
    ident: &IdentifyParams,
    log: &BenchLog,
    start: StartMode,
    keep_segments: bool,
) -> Result<NewLogScore, IdentifyError> {
    let load = crate::physics::LoadParams::default();
    let setup = super::IdentifySetup {
        name: "leave-one-out fold",
        drive,
        load: &load,
        identify: Some(ident),
        quasi_static: None,
        effects: Some(effects),
    };
    let options = super::DiagnoseOptions {
        start,
        keep_segments,
        ..Default::default()
    };
    let d = super::diagnose_with_progress(
        &setup,
        std::slice::from_ref(log),
        &options,
        &crate::progress::Silent,
    )?;
    Ok(NewLogScore {
        extended_mrad: d.rmse_extended_mrad,
        base_mrad: d.rmse_base_mrad,
        play_mrad: d.play_operator.as_ref().map(|p| p.rmse_heldout_mrad),
        preload_raised: d
            .calibrated_model
            .as_ref()
            .is_some_and(|c| c.cannot_carry.is_some()),
        cause: d.cause,
    })
}

/// The table and the shared parameters as text (Markdown table first).
pub fn loo_text(t: &LooTable) -> String {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Leave-one-log-out (shared model calibrated on the other logs; extension: {})\n",
        if t.effects.is_empty() {
            "none".to_string()
        } else {
            t.effects.join(" + ")
        }
    );
    let _ = writeln!(
        s,
        "| log left out | base (mrad) | extended (mrad) | play operator fitted to the log (mrad) | noise floor (mrad) | pull on the others (%) | extended residual | diagnosed alone against the others' calibration (mrad) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    for r in &t.rows {
        let name = std::path::Path::new(&r.log)
            .file_name()
            .map_or(r.log.clone(), |f| f.to_string_lossy().into_owned());
        let play = r
            .play_mrad
            .map_or("fit failed".to_string(), |p| format!("{p:.2}"));
        let alone = r.as_new_log.as_ref().map_or("failed".to_string(), |a| {
            let versus = if a.beats_both() {
                "beats both"
            } else {
                "does not beat both"
            };
            let raised = if a.preload_raised {
                ", preload raised to carry it"
            } else {
                ""
            };
            format!(
                "{:.2} ({versus}: base {:.2}, play {}{raised})",
                a.extended_mrad,
                a.base_mrad,
                a.play_mrad
                    .map_or("failed".to_string(), |p| format!("{p:.2}"))
            )
        });
        let _ = writeln!(
            s,
            "| {name} | {:.2} | {:.2} | {play} | {:.2} | {:.1} | {} | {alone} |",
            r.base_mrad, r.extended_mrad, r.floor_mrad, r.pull_percent, r.residual
        );
    }
    let _ = writeln!(
        s,
        "\nExtended beats base on {}/{} logs, the per-log play operator on {}/{}.",
        t.wins_over_base,
        t.rows.len(),
        t.wins_over_play,
        t.rows.len()
    );
    let alone: Vec<f64> = t
        .rows
        .iter()
        .filter_map(|r| r.as_new_log.as_ref().map(|a| a.extended_mrad))
        .collect();
    if !alone.is_empty() {
        let _ = writeln!(
            s,
            "Each log diagnosed alone against the calibration on the others (as `diagnose --scenario` judges a new log): beats the base model recalibrated on it and its play operator, held out on its time blocks, on {}/{} logs (mean {:.2} mrad over the {} diagnosed).",
            t.new_log_wins,
            t.rows.len(),
            alone.iter().sum::<f64>() / alone.len() as f64,
            alone.len()
        );
    }
    for c in t.start_cuts.iter().filter(|c| c.cut_s > 0.0) {
        let _ = writeln!(s, "Start-up: {}: {}", c.log, c.reason);
    }
    for g in &t.excluded_segments {
        let _ = writeln!(s, "{}", super::segments::describe(g));
    }
    let _ = writeln!(
        s,
        "\nShared parameters, joint calibration on every log (value +- 1 sigma):"
    );
    if let Some(r) = &t.residual_runs {
        let _ = writeln!(
            s,
            "  (The +- allow for a residual that comes in runs: correlated over about {} samples ({} s), each +- {}; widened by a median {:.2}x, at most {:.1}x.)",
            crate::compact((r.correlation_samples * 10.0).round() / 10.0),
            crate::compact(r.correlation_s),
            super::records::uncertainty_sources(
                r,
                if r.batch_capped { ", cut at a quarter of the longest stretch of a log, so these still understate" } else { "" },
            ),
            r.median_widening,
            r.max_widening,
        );
    }
    if !t.jackknife.is_empty() {
        let _ = writeln!(
            s,
            "  (In brackets: the jackknife spread of the folds' calibrations, each without one log; each +- is the larger of the joint fit's and it, and a value it exceeds is not identifiable: the logs disagree on it.)"
        );
    }
    for p in &t.shared {
        let jack = p
            .jackknife_std
            .map(|j| format!(" [jackknife {}]", crate::compact(j)))
            .unwrap_or_default();
        let _ = writeln!(s, "  {}{jack}", shared_row(p));
    }
    for n in &t.not_pinned {
        let _ = writeln!(s, "  NOT PINNED: {n}");
    }
    for n in &t.on_bound {
        let _ = writeln!(s, "  ON A BOUND: {n}");
    }
    for n in &t.disagreeing {
        let _ = writeln!(s, "DISAGREES with the other logs: {n}");
    }
    for n in &t.notes {
        let _ = writeln!(s, "Limit: {n}");
    }
    s
}

/// One row of the shared-parameter table: the value with its 1-sigma where the logs pin
/// it; where they do not ([`SharedParam::not_identifiable`]), or it was held on its bound,
/// that in words instead of a `+-` that would read as an estimate.
fn shared_row(s: &SharedParam) -> String {
    let p = &s.estimate;
    let head = format!("{:<34} {:>13.5e}", p.name, p.value);
    if s.held() {
        format!("{head}    {}; held on its bound, not fitted freely", p.unit)
    } else if let Some(why) = &s.not_identifiable {
        format!("{head}    {}; not identifiable: {why}", p.unit)
    } else {
        format!("{head} +- {:<10.2e} {}", p.std, p.unit)
    }
}

#[cfg(test)]
mod tests {
    use super::{binned_structure, jackknife_spread, shared_row, ParamEstimate, SharedParam};

    /// The jackknife of a mean is the standard error `s / sqrt(n)` exactly (`s` the sample
    /// standard deviation): the folds' values are the means without one sample each.
    #[test]
    fn the_jackknife_of_a_mean_is_its_standard_error() {
        let x = [2.0, 3.5, -1.0, 4.25, 0.5, 7.0, 3.0];
        let n = x.len() as f64;
        let sum: f64 = x.iter().sum();
        let folds: Vec<Vec<ParamEstimate>> = x
            .iter()
            .map(|xi| vec![ParamEstimate::new("m", (sum - xi) / (n - 1.0), 0.0, "1")])
            .collect();
        let refs: Vec<&[ParamEstimate]> = folds.iter().map(|f| f.as_slice()).collect();
        let shared = [
            ParamEstimate::new("m", sum / n, 0.1, "1"),
            ParamEstimate::new("absent", 1.0, 0.1, "1"),
        ];
        let j = jackknife_spread(&shared, &refs);
        let mean = sum / n;
        let s = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        assert_eq!(j.len(), 1, "{j:?}");
        assert!((j[0].std / (s / n.sqrt()) - 1.0).abs() < 1e-12, "{j:?}");
        assert!(jackknife_spread(&shared, &refs[..2]).is_empty());
    }

    #[test]
    fn binned_structure_sees_a_function_of_the_signal_and_not_noise() {
        let n = 4000;
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        // Residual = 1e-3 x^2 exactly: its binned means carry its whole spread.
        let r: Vec<f64> = x.iter().map(|v| 1e-3 * v * v).collect();
        let mean = r.iter().sum::<f64>() / n as f64;
        let sd = (r.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        let s = binned_structure(&r, &x);
        assert!((s / sd - 1.0).abs() < 0.05, "{s} vs {sd}");
        // A residual that depends on another, unrelated sequence shows little structure.
        let other: Vec<f64> = (0..n)
            .map(|i| 1e-3 * ((i * 7919 % 1000) as f64 / 500.0 - 1.0))
            .collect();
        let t = binned_structure(&other, &x);
        assert!(t < 0.2 * 1e-3 / 3f64.sqrt(), "{t}");
    }

    /// The signal a residual follows is named first, above the floor; the others, and
    /// noise alone, stay under it.
    #[test]
    fn the_signal_a_residual_follows_is_named_first() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let n = 20_000;
        let angle: Vec<f64> = (0..n).map(|_| rng.gen_range(0.0..1.0)).collect();
        let load: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
        let noise: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0) * 0.03e-3).collect();
        let floor = 0.02e-3;
        let along: Vec<f64> = angle
            .iter()
            .zip(&noise)
            .map(|(a, e)| 0.1e-3 * (std::f64::consts::TAU * a).sin() + e)
            .collect();
        let signals = [("input angle", angle), ("transmitted load", load)];
        let s = super::signatures(&along, &signals, floor);
        assert_eq!(s[0].variable, "input angle", "{s:?}");
        assert!(
            s[0].ratio_to_floor > 3.0 && s[1].ratio_to_floor < 0.5,
            "{s:?}"
        );
        let s = super::signatures(&noise, &signals, floor);
        assert!(s.iter().all(|g| g.ratio_to_floor < 0.5), "{s:?}");
    }

    #[test]
    fn a_shared_value_its_uncertainty_exceeds_reads_as_not_identifiable() {
        let p = |value: f64, std: f64| {
            SharedParam::judge(
                ParamEstimate::new(
                    "friction_memory_weight[r=0.0042 rad]",
                    value,
                    std,
                    "rad/rad",
                ),
                None,
            )
        };
        let loose = shared_row(&p(3.98754e-2, 4.05e-2));
        assert!(!loose.contains("+-"), "{loose}");
        assert!(loose.contains("not identifiable"), "{loose}");
        for std in [0.0, 4.2e-2] {
            let held = shared_row(&p(0.0, std));
            assert!(
                !held.contains("+-") && held.contains("held on its bound"),
                "{held}"
            );
        }
        assert!(shared_row(&p(3.98754e-2, 4.05e-3)).contains("+-"));
    }

    /// A value the folds scatter by more than itself is not identifiable, the logs
    /// disagreeing on it, even where the joint fit's own `+-` is well under it; its `+-`
    /// is the jackknife's. One the folds agree on keeps the fit's `+-`, and a value held on
    /// its bound or with a natural zero is not judged against its size.
    #[test]
    fn a_value_the_folds_scatter_by_more_than_itself_is_not_identifiable() {
        let growth = |jack: Option<f64>| {
            SharedParam::judge(
                ParamEstimate::new("friction_memory_threshold_growth", 4.16, 0.99, "1/(N m)"),
                jack,
            )
        };
        let apart = growth(Some(7.8));
        assert_eq!(apart.std_fit, 0.99);
        assert_eq!(apart.estimate.std, 7.8);
        let why = apart.not_identifiable.clone().unwrap_or_default();
        assert!(why.starts_with("the logs disagree on it"), "{apart:?}");
        let row = shared_row(&apart);
        assert!(
            !row.contains("+-  ") && row.contains("the logs disagree"),
            "{row}"
        );
        let listed = super::not_pinned(std::slice::from_ref(&apart));
        assert!(
            listed.len() == 1 && listed[0].contains("the logs disagree on it"),
            "{listed:?}"
        );
        for jack in [None, Some(0.5), Some(3.0)] {
            let agreed = growth(jack);
            assert!(agreed.not_identifiable.is_none(), "{agreed:?}");
            assert!(shared_row(&agreed).contains("+-"), "{agreed:?}");
            assert_eq!(agreed.estimate.std, jack.unwrap_or(0.0).max(0.99));
        }
        let both = SharedParam::judge(ParamEstimate::new("preload_n", 28.3, 67.6, "N"), Some(72.7));
        let why = both.not_identifiable.clone().unwrap_or_default();
        assert!(
            why.starts_with("its uncertainty (67.6)") && why.contains("the logs disagree"),
            "{both:?}"
        );
        let held = SharedParam::judge(
            ParamEstimate::new("friction_memory_weight[r=0.0042 rad]", 0.0, 0.0, "rad/rad"),
            Some(0.01),
        );
        assert!(held.not_identifiable.is_none() && held.estimate.std == 0.0);
        let phase = SharedParam::judge(
            ParamEstimate::new("input_pulley_runout_phase", 0.01, 0.001, "rad"),
            Some(0.2),
        );
        assert!(phase.not_identifiable.is_none(), "{phase:?}");
        assert_eq!(phase.estimate.std, 0.2);
    }
}
