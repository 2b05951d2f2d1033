//! Diagnosis of bench logs: replay the quasi-static memory model against measurements,
//! calibrate its parameters, search the effect library for what it misses, and score every
//! model on data its fit did not see.
//! Computation layer: takes an [`IdentifySetup`] and logs in memory; imports physics,
//! measurement and study, never files, plots or scenarios.

pub mod baseline;
pub mod effects;
pub mod estimates;
pub mod extra_effects;
pub mod identifiability;
pub mod instrument;
pub mod lm;
pub mod loo;
pub mod model;
pub mod play;
pub mod records;
pub mod resolution;
pub mod segments;
pub mod startup;
pub mod synth;
pub mod whiteness;

pub use crate::measurement::{BenchLog, Sample};
pub use effects::{EffectName, EffectsParams, IdentifyParams};
pub use estimates::effect_value;
pub use records::*;
pub use synth::{parse_effect_arg, synthesize, MemoryLoad, Ringing, SynthOptions};

use crate::physics::DriveParams;
use crate::physics::LoadParams;
use crate::study::quasi_static::QuasiStaticParams;
use model::{Evaluator, Fitted, LinParam, NlParam, Prepared, Spec};

/// Training masks and held-out masks of the cross-validation, and the mask of the final fit.
struct Split {
    /// Folds that select effects (time blocks of the calibration data).
    folds: Vec<(Vec<bool>, Vec<bool>)>,
    /// Held-out logs: (calibration rows, held-out rows), scored once after selection so
    /// the reported gain is free of selection bias.
    outer: Option<(Vec<bool>, Vec<bool>)>,
    full: Vec<bool>,
    text: String,
}

/// `keep` marks the rows outside excluded segments: every mask is restricted to them.
fn make_split(
    logs: &[Prepared],
    ident: &IdentifyParams,
    opts: &DiagnoseOptions,
    keep: &[bool],
) -> Result<Split, IdentifyError> {
    let n: usize = logs.iter().map(|l| l.t.len()).sum();
    if !opts.holdout_logs.is_empty() {
        if let Some(bad) = opts.holdout_logs.iter().find(|i| **i >= logs.len()) {
            return Err(IdentifyError::Config {
                key: "--holdout".into(),
                message: format!("log index {bad} does not exist ({} logs given)", logs.len()),
            });
        }
        if opts.holdout_logs.len() >= logs.len() {
            return Err(IdentifyError::Config {
                key: "--holdout".into(),
                message: "every log is held out; keep at least one for calibration".into(),
            });
        }
        let mut train = Vec::with_capacity(n);
        for (k, l) in logs.iter().enumerate() {
            let held = opts.holdout_logs.contains(&k);
            train.extend(std::iter::repeat_n(!held, l.t.len()));
        }
        let test: Vec<bool> = train.iter().zip(keep).map(|(t, k)| !t && *k).collect();
        for (t, k) in train.iter_mut().zip(keep) {
            *t &= *k;
        }
        let names: Vec<&str> = opts
            .holdout_logs
            .iter()
            .map(|k| logs[*k].source.as_str())
            .collect();
        let folds = block_folds(logs, ident.holdout_blocks, &train);
        return Ok(Split {
            folds,
            outer: Some((train.clone(), test)),
            full: train,
            text: format!(
                "held-out logs: {} (effects selected on {} time blocks of the other logs)",
                names.join(", "),
                ident.holdout_blocks
            ),
        });
    }
    let all = keep.to_vec();
    debug_assert_eq!(all.len(), n);
    Ok(Split {
        folds: block_folds(logs, ident.holdout_blocks, &all),
        outer: None,
        full: all,
        text: format!(
            "{} contiguous time blocks per log, each held out in turn",
            ident.holdout_blocks
        ),
    })
}

/// `k` contiguous blocks per log, restricted to rows in `within`.
pub(crate) fn block_folds(
    logs: &[Prepared],
    k: usize,
    within: &[bool],
) -> Vec<(Vec<bool>, Vec<bool>)> {
    let n = within.len();
    (0..k)
        .map(|f| {
            let mut test = Vec::with_capacity(n);
            for l in logs {
                let m = l.t.len();
                test.extend((0..m).map(|i| i * k / m == f));
            }
            for (t, w) in test.iter_mut().zip(within) {
                *t &= *w;
            }
            let train = test.iter().zip(within).map(|(t, w)| !t && *w).collect();
            (train, test)
        })
        .collect()
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

/// Noise floor of the residual: robust high-frequency spread, or quantisation when larger.
/// Only differences between neighbouring rows both in `keep` count.
pub(crate) fn noise_floor(logs: &[Prepared], resid: &[f64], keep: &[bool], ic: f64) -> f64 {
    let mut d: Vec<f64> = Vec::new();
    let mut start = 0;
    for l in logs {
        let r = start..start + l.t.len();
        d.extend(
            resid[r.clone()]
                .windows(2)
                .zip(keep[r.clone()].windows(2))
                .filter(|(_, k)| k[0] && k[1])
                .map(|(w, _)| (w[1] - w[0]).abs()),
        );
        start = r.end;
    }
    if d.is_empty() {
        d.push(0.0);
    }
    d.sort_by(|a, b| a.total_cmp(b));
    // RMS of first differences (exact for white noise of any distribution, including
    // quantisation at speed), with the largest 1 % dropped so jumps at reversals do not
    // count as noise.
    let keep = &d[..(d.len() * 99 / 100).max(1).min(d.len())];
    let s_diff = rms(keep.iter().copied()) / std::f64::consts::SQRT_2;
    let q2 = logs
        .iter()
        .map(|l| (l.q_out.powi(2) + (l.q_in / ic).powi(2)) / 12.0)
        .sum::<f64>()
        / logs.len().max(1) as f64;
    s_diff.max(q2.sqrt())
}

/// The noise floor `floor` (rad) estimated again on the residual of the fit `fit` of
/// `spec` over the rows `full` (`keep` as in [`noise_floor`]), when that gives less: a
/// residual's differences carry the structure a model leaves beside the noise, so the
/// better model gives the tighter estimate. Unchanged when the residual cannot be
/// computed; never below the quantisation.
fn tighter_floor(
    floor: f64,
    logs: &[Prepared],
    spec: Spec,
    fit: &Fitted,
    full: &[bool],
    keep: &[bool],
    ic: f64,
) -> f64 {
    let mut ev = Evaluator::new(spec, logs);
    match ev.residual(fit, full) {
        Ok((mut r, _)) => {
            recenter_unfitted(logs, &mut r, full, keep);
            floor.min(noise_floor(logs, &r, keep, ic).max(1e-12))
        }
        Err(_) => floor,
    }
}

fn spec_for(
    drive: &DriveParams,
    ident: &IdentifyParams,
    effects: &[EffectName],
    nonlinear_base: bool,
    calibrated: Option<&EffectsParams>,
) -> Spec {
    Spec {
        drive: drive.clone(),
        fit_mu: nonlinear_base && ident.is_unknown("friction_coefficient"),
        fit_pre: nonlinear_base && ident.is_unknown("preload_n"),
        fit_g: ident.is_unknown("cable_modulus_n"),
        fit_ratio: ident.is_unknown("ratio"),
        effects: effects.to_vec(),
        ident: ident.clone(),
        calibrated: calibrated.cloned(),
    }
}

fn with_base(drive: &DriveParams, spec_nl: &[(NlParam, f64, f64, f64)], x: &[f64]) -> DriveParams {
    let mut d = drive.clone();
    for (n, v) in spec_nl.iter().zip(x) {
        match n.0 {
            NlParam::Mu => d.friction_coefficient = *v,
            NlParam::Preload => d.preload_n = *v,
            NlParam::Effect(_) | NlParam::Memory(_) => {}
        }
    }
    d
}

/// For logs without a fitted row in `fit`, the encoder zero [`Evaluator::residual`] takes
/// from the whole log, taken again from its rows in `keep` only: an excluded stretch (a
/// reading stuck at a wrong value) must not set the zero the kept rows are scored about.
pub(crate) fn recenter_unfitted(logs: &[Prepared], resid: &mut [f64], fit: &[bool], keep: &[bool]) {
    let mut start = 0;
    for l in logs {
        let r = start..start + l.t.len();
        start = r.end;
        if fit[r.clone()].iter().any(|m| *m) {
            continue;
        }
        let (sum, count) = r
            .clone()
            .filter(|i| keep[*i])
            .fold((0.0, 0usize), |(s, c), i| (s + resid[i], c + 1));
        if count > 0 && count < l.t.len() {
            let mean = sum / count as f64;
            for v in &mut resid[r] {
                *v -= mean;
            }
        }
    }
}

/// Held-out RMSE, held-out count and the fit on the final mask.
type CvResult = Result<(f64, usize, Fitted), IdentifyError>;
/// A candidate's held-out score with why its size is not found, when it is not
/// ([`size_not_found`]).
type SizedResult = Result<(Option<String>, (f64, usize, Fitted)), IdentifyError>;

/// How many of the candidates that improve on the current model, best first, are paired
/// with each other when none passes the gate alone (up to fifteen pairs); the most helpful
/// one is also paired with every other that helps, as a forward selection would add its
/// second (with the eleven effects searched by default, an input pulley runout beside an
/// encoder delay ranked seventh alone and its pair was not judged).
const PAIR_POOL: usize = 6;

/// How much more of the structure above the noise floor another candidate that passes the
/// gate may leave unexplained, held out, than the accepted one, for the logs to be said
/// not to tell them apart: `rmse_alt^2 - floor^2 <= (1 + TIE_FRACTION) (rmse^2 - floor^2)`
/// (0.1). Judged on the excess over the floor, not on the RMSE itself, because near the
/// floor every candidate's RMSE is mostly noise: a bearing friction found alone usually
/// leaves a drum runout 0.7 % to 4 % behind in RMSE but 12 % or more behind in what it
/// explains, while a compliance beside a ratio shape left an encoder scale error, a drum
/// runout and a bearing friction within 1 % to 6 %.
pub const TIE_FRACTION: f64 = 0.1;

/// Held-out RMSEs this close, as a fraction, tie whatever the floor says (0.005): where the
/// floor estimate lies above what the best candidate reaches, the excess cannot judge. The
/// smallest compliances (about 1e-4 rad/(N m)) and a drum runout came 0.06 % to 0.5 %
/// apart on several draws, on one of which the runout was named; a bearing friction's
/// nearest rival sits 0.66 % or more behind on all but one of 50 draws.
pub const TIE_RMSE_FRACTION: f64 = 0.005;

/// The rows of `scores` from `from` on that pass the gate and tie with the accepted row
/// `idx` ([`ties_with`], `floor_mrad` the noise floor); `None` when none does. These are
/// judged again on the whole model found once the search ends.
fn near_ties(
    scores: &[CandidateScore],
    from: usize,
    idx: usize,
    floor_mrad: f64,
) -> Option<Indistinguishable> {
    let best = scores[idx].rmse_heldout_mrad;
    let alternatives: Vec<Alternative> = scores
        .iter()
        .enumerate()
        .skip(from)
        .filter(|(i, c)| {
            *i != idx
                && c.verdict == "qualifies"
                && ties_with(c.rmse_heldout_mrad, best, floor_mrad)
        })
        .map(|(_, c)| Alternative {
            name: c.name.clone(),
            rmse_heldout_mrad: c.rmse_heldout_mrad,
        })
        .collect();
    (!alternatives.is_empty()).then(|| Indistinguishable {
        accepted: scores[idx].name.clone(),
        rmse_heldout_mrad: best,
        alternatives,
    })
}

/// Whether held-out RMSE `rmse` leaves at most [`TIE_FRACTION`] more above the noise
/// floor than `best`, or lies within [`TIE_RMSE_FRACTION`] of it (same unit as `floor`).
fn ties_with(rmse: f64, best: f64, floor: f64) -> bool {
    rmse <= best * (1.0 + TIE_RMSE_FRACTION)
        || rmse * rmse - floor * floor <= (1.0 + TIE_FRACTION) * (best * best - floor * floor)
}

/// How a candidate's verdict starts when it is refused only for its size: `size: ` and why.
pub const SIZE_VERDICT: &str = "size: ";

/// Candidates refused only for a size the logs cannot tell from zero ([`SIZE_VERDICT`])
/// that still bring the held-out error within [`SEARCH_ENDS_WITHIN`] of the noise floor
/// (`floor_mrad`), where the effects found (`found_mrad`) do not: an effect the data need
/// but cannot size, not one they lack. Best first, each effect once (a later round tries
/// it again). On a balanced gimbal axis a compliance of 5e-4 rad/(N m) reached the noise
/// this way, traded against the cable modulus, while an encoder delay of -0.17 ms left
/// 12 floors.
pub fn unpinned(
    candidates: &[CandidateScore],
    found_mrad: f64,
    floor_mrad: f64,
) -> Vec<&CandidateScore> {
    let within = SEARCH_ENDS_WITHIN * floor_mrad;
    if found_mrad <= within {
        return Vec::new();
    }
    let mut v: Vec<&CandidateScore> = candidates
        .iter()
        .filter(|c| c.verdict.starts_with(SIZE_VERDICT) && c.rmse_heldout_mrad <= within)
        .collect();
    v.sort_by(|a, b| a.rmse_heldout_mrad.total_cmp(&b.rmse_heldout_mrad));
    let mut seen: Vec<&str> = Vec::new();
    v.retain(|c| {
        let new = !seen.contains(&c.name.as_str());
        seen.push(&c.name);
        new
    });
    v
}

/// The search for effects ends when the model's held-out error is within this factor of
/// the noise floor (1.05): what is left above it is too little for any effect to show.
pub const SEARCH_ENDS_WITHIN: f64 = 1.05;

/// How the candidate table names a carried effect tried at another size.
pub const RESIZED_SUFFIX: &str = " (resized)";

/// The candidate-table name of effect `name` (e.g. `encoder_delay`) tried at another size
/// than calibrated: `encoder_delay (resized)`.
pub fn resized_label(name: &str) -> String {
    format!("{name}{RESIZED_SUFFIX}")
}

/// The effect's own name in a candidate-table name.
fn unlabelled(name: &str) -> &str {
    name.strip_suffix(RESIZED_SUFFIX).unwrap_or(name)
}

/// Tie `t`, seen in the round that accepted its effect, judged on the whole model the
/// search ended with (`chosen`, held-out RMSE `found`, rad; `floor` in rad): each
/// alternative takes the accepted effect's place beside the other effects found and is
/// scored by `score` (held-out RMSE, rad; `None` when its fit fails or is implausible).
/// An alternative the model already holds is no alternative. `None` when no tie stands.
fn confirm_tie<F>(
    t: Indistinguishable,
    chosen: &[EffectName],
    found: f64,
    floor: f64,
    score: &F,
) -> Option<Indistinguishable>
where
    F: Fn(&[EffectName]) -> Option<f64> + Sync,
{
    use rayon::prelude::*;
    let gone: Vec<&str> = t.accepted.split(" + ").map(unlabelled).collect();
    let kept: Vec<EffectName> = chosen
        .iter()
        .copied()
        .filter(|c| !gone.contains(&c.as_str()))
        .collect();
    let mut alternatives: Vec<Alternative> = t
        .alternatives
        .par_iter()
        .filter_map(|a| {
            let parts: Vec<EffectName> = a
                .name
                .split(" + ")
                .map(|p| unlabelled(p).parse())
                .collect::<Result<_, _>>()
                .ok()?;
            if parts.iter().any(|p| kept.contains(p)) {
                return None;
            }
            let effs: Vec<EffectName> = kept.iter().chain(&parts).copied().collect();
            let rmse = score(&effs)?;
            ties_with(rmse, found, floor).then(|| Alternative {
                name: a.name.clone(),
                rmse_heldout_mrad: rmse * 1e3,
            })
        })
        .collect();
    alternatives.sort_by(|a, b| a.rmse_heldout_mrad.total_cmp(&b.rmse_heldout_mrad));
    (!alternatives.is_empty()).then_some(Indistinguishable {
        accepted: t.accepted,
        rmse_heldout_mrad: found * 1e3,
        alternatives,
    })
}

/// The score of a candidate whose fit failed: no numbers, the reason in the verdict.
fn failed_score(name: String, round: usize, err: &IdentifyError) -> CandidateScore {
    CandidateScore {
        name,
        rmse_heldout_mrad: f64::NAN,
        gain_percent: f64::NAN,
        explained_fraction: f64::NAN,
        score: f64::NAN,
        accepted: false,
        round,
        verdict: format!("fit failed: {err}"),
    }
}

/// Cross-validated held-out residuals of a model with `effects` on top of per-fold base
/// drives (and of a calibrated instrument's effects, when given); returns (held-out RMSE,
/// held-out count, fit on the final mask).
#[allow(clippy::too_many_arguments)]
fn cross_validate(
    logs: &[Prepared],
    ident: &IdentifyParams,
    full_drive: &DriveParams,
    fold_drives: &[DriveParams],
    folds: &[(Vec<bool>, Vec<bool>)],
    full_mask: &[bool],
    keep: &[bool],
    effects: &[EffectName],
    calibrated: Option<&EffectsParams>,
) -> CvResult {
    let mut ev = Evaluator::new(
        spec_for(full_drive, ident, effects, false, calibrated),
        logs,
    );
    let full = ev.fit(full_mask, None, 25)?;
    let mut held = Vec::new();
    for ((train, test), drive) in folds.iter().zip(fold_drives) {
        let mut evf = Evaluator::new(spec_for(drive, ident, effects, false, calibrated), logs);
        let f = evf.fit(train, Some(&full.x), 10)?;
        let (mut r, _) = evf.residual(&f, train)?;
        recenter_unfitted(logs, &mut r, train, keep);
        held.extend(r.iter().zip(test).filter(|(_, t)| **t).map(|(r, _)| *r));
    }
    Ok((rms(held.iter().copied()), held.len(), full))
}

/// What identification reads of a study description: the drive to calibrate, its loads,
/// the identification settings and, for synthetic logs, the prescribed motion.
#[derive(Clone, Copy, Debug)]
pub struct IdentifySetup<'a> {
    /// Name used in messages and log comments.
    pub name: &'a str,
    /// Nominal drive (the calibration's starting point).
    pub drive: &'a DriveParams,
    /// Loads on the drum (synthetic logs).
    pub load: &'a LoadParams,
    /// How logs calibrate the drive; `None` = defaults.
    pub identify: Option<&'a IdentifyParams>,
    /// Prescribed input motion, duration and rate (synthetic logs).
    pub quasi_static: Option<&'a QuasiStaticParams>,
    /// Calibrated effects of the instrument (`[effects]`): when present, a log is first
    /// judged against the whole calibrated model as given.
    pub effects: Option<&'a EffectsParams>,
}

/// Anything an identification setup can be read from: a setup itself, or a scenario
/// (which implements this at the edge).
pub trait IdentifySource {
    /// The setup.
    fn identify_setup(&self) -> IdentifySetup<'_>;
}

impl IdentifySource for IdentifySetup<'_> {
    fn identify_setup(&self) -> IdentifySetup<'_> {
        *self
    }
}

/// Diagnose bench logs against the setup's drive: calibrate the base model, search the
/// effect library, score on held-out data. Typical run: a few seconds for a minute of data.
pub fn diagnose(
    source: &(impl IdentifySource + ?Sized),
    logs: &[BenchLog],
    options: &DiagnoseOptions,
) -> Result<Diagnosis, IdentifyError> {
    diagnose_with_progress(source, logs, options, &crate::progress::Silent)
}

/// [`diagnose`], reporting each candidate effect judged to `progress` (units: candidate
/// fits, each cross-validated over the held-out folds). The total is counted up front as
/// if every round of the search ran (8 then 7 candidates by default: 15); when the search
/// stops early the total is lowered at the end to the candidates actually judged. The
/// base calibration before the first candidate is not counted (the bar shows `0/total`
/// meanwhile). Results are those of [`diagnose`].
pub fn diagnose_with_progress(
    source: &(impl IdentifySource + ?Sized),
    logs: &[BenchLog],
    options: &DiagnoseOptions,
    progress: &dyn crate::progress::Progress,
) -> Result<Diagnosis, IdentifyError> {
    if logs.is_empty() {
        return Err(IdentifyError::NoLogs);
    }
    let scenario = source.identify_setup();
    let ident = scenario.identify.cloned().unwrap_or_default();
    ident.validate().map_err(|(k, m)| IdentifyError::Config {
        key: format!("identify.{k}"),
        message: m,
    })?;
    let (cut_logs, start_cuts): (Vec<BenchLog>, Vec<startup::StartCut>) = logs
        .iter()
        .map(|l| startup::cut_start(l, options.start))
        .unzip();
    let mut prepared: Vec<Prepared> = logs
        .iter()
        .zip(&cut_logs)
        .zip(&start_cuts)
        .map(|((l, c), cut)| startup::prepare_after_cut(l, c, cut, ident.max_rate_hz))
        .collect::<Result<_, _>>()?;
    for p in &prepared {
        still_input(p)?;
    }
    let (segments_per_log, keep_per_log) =
        segments::rows_to_fit(&cut_logs, &mut prepared, options.keep_segments)?;
    let keep: Vec<bool> = keep_per_log.iter().flatten().copied().collect();
    let split = make_split(&prepared, &ident, options, &keep)?;
    let drive0 = scenario.drive.clone();

    // Base model: full calibration, then per fold from there.
    let base_spec = spec_for(&drive0, &ident, &[], true, None);
    let mut ev = Evaluator::new(base_spec.clone(), &prepared);
    let base_fit = ev.fit(&split.full, None, 40)?;
    let nl = ev.nonlinear();
    let base_drive = with_base(&drive0, &nl, &base_fit.x);
    let mut full_drive = base_drive.clone();
    let mut fold_drives = Vec::new();
    let mut held = Vec::new();
    for (train, test) in &split.folds {
        let f = ev.fit(train, Some(&base_fit.x), 10)?;
        fold_drives.push(with_base(&drive0, &nl, &f.x));
        let (r, _) = ev.residual(&f, train)?;
        held.extend(r.iter().zip(test).filter(|(_, t)| **t).map(|(r, _)| *r));
    }
    let rmse_base = rms(held.iter().copied());
    let n_held = held.len().max(1) as f64;
    let (mut base_resid, base_pred) = ev.residual(&base_fit, &split.full)?;
    recenter_unfitted(&prepared, &mut base_resid, &split.full, &keep);
    let ic_fit = fitted_ratio(&drive0, &base_fit);
    // Estimated on the base model's residual, whose differences still carry what the base
    // model leaves; the calibrated instrument, each model the search accepts and the
    // final model read it again ([`tighter_floor`]).
    let mut floor = noise_floor(&prepared, &base_resid, &keep, ic_fit).max(1e-12);
    // A fit the search may build on: sizes physically possible and a drift resolvable
    // over the noise floor `floor` (rad) as it stands.
    let admissible = |fit: &Fitted, floor: f64| {
        plausible(fit, drive0.ratio()) && resolvable(fit, least_resolvable_drift(&prepared, floor))
    };

    // On a calibrated instrument (a scenario's `[effects]`) the search asks what is still
    // missing on top of it: its drive and effects held as calibrated, only each log's zero
    // and the candidates fitted. The capstan calibration above stays the base the result
    // is compared with.
    let top = scenario
        .effects
        .filter(|fx| **fx != EffectsParams::default());
    let search_ident = if top.is_some() {
        IdentifyParams {
            unknown: Vec::new(),
            ..ident.clone()
        }
    } else {
        ident.clone()
    };
    let mut current = rmse_base;
    let mut cannot_carry: Option<CarryRaise> = None;
    // On a calibrated instrument: what the search on top starts from, held out.
    let mut calibrated_held_out = rmse_base;
    if let Some(fx) = top {
        full_drive = drive0.clone();
        fold_drives = vec![drive0.clone(); split.folds.len()];
        if let Some(fault) = first_replay_fault(&drive0, fx, &prepared) {
            let raised = raise_to_carry(&prepared, &ident, &drive0, fx).ok_or(fault.0)?;
            cannot_carry = Some(CarryRaise {
                fault: fault.1,
                friction_coefficient: [drive0.friction_coefficient, raised.friction_coefficient],
                preload_n: [drive0.preload_n, raised.preload_n],
            });
            fold_drives = vec![raised.clone(); split.folds.len()];
            full_drive = raised;
        }
        let (rmse, _, fit) = cross_validate(
            &prepared,
            &search_ident,
            &full_drive,
            &fold_drives,
            &split.folds,
            &split.full,
            &keep,
            &[],
            top,
        )?;
        current = rmse;
        calibrated_held_out = rmse;
        // The search builds on the calibrated model, so its residual, not the capstan
        // model's, says what is noise.
        let spec = spec_for(&full_drive, &search_ident, &[], false, top);
        floor = tighter_floor(floor, &prepared, spec, &fit, &split.full, &keep, ic_fit);
    }

    // Candidates.
    // On a calibrated instrument the search holds the ratio, whatever the base fit frees.
    let ratio_free = search_ident.is_unknown("ratio");
    // A carried one-column effect the scenario holds at one size for every log: the
    // search may find the logs judged at another ([`Diagnosis::resized`]).
    let resizable = |e: EffectName| {
        top.is_some_and(|fx| e.carried_by(fx))
            && effects::PER_LOG_EFFECTS.contains(&e)
            && !ident.per_log.contains(&e)
    };
    // A candidate's name in the table: a carried effect tried at another size says so.
    let label = |e: EffectName| {
        if resizable(e) {
            resized_label(e.as_str())
        } else {
            e.to_string()
        }
    };
    let mut pool: Vec<EffectName> = options
        .candidates
        .clone()
        .unwrap_or_else(|| ident.searched())
        .into_iter()
        // A free ratio and an output scale error are the same column.
        .filter(|e| !(ratio_free && *e == EffectName::EncoderScaleError))
        // What the calibrated instrument already carries is not searched again as a new
        // effect, nor what it refits on each log; a one-column effect it carries is tried
        // at another size, as a change on top of the calibrated one.
        .filter(|e| {
            top.is_none_or(|fx| (!e.carried_by(fx) || resizable(*e)) && !ident.per_log.contains(e))
        })
        .collect();
    let searchable: Vec<String> = pool.iter().map(|e| label(*e)).collect();
    // Each round judges every candidate left and takes one out of the pool (two, when
    // only a pair passes the gate).
    let rounds = ident.max_effects.min(pool.len());
    let most_judged: usize = (0..rounds).map(|r| pool.len() - r).sum();
    let judged = crate::progress::Counter::new(most_judged, progress);
    let mut chosen: Vec<EffectName> = Vec::new();
    let mut scores: Vec<CandidateScore> = Vec::new();
    let mut chosen_fit: Option<Fitted> = None;
    let mut indistinguishable: Vec<Indistinguishable> = Vec::new();
    // Held-out score of a set of effects on a calibration (the search's moves on).
    let held_out = |full: &DriveParams, folds: &[DriveParams], effs: &[EffectName]| {
        cross_validate(
            &prepared,
            &search_ident,
            full,
            folds,
            &split.folds,
            &split.full,
            &keep,
            effs,
            top,
        )
    };
    for round in 1..=ident.max_effects {
        if pool.is_empty() || current <= SEARCH_ENDS_WITHIN * floor {
            break;
        }
        use rayon::prelude::*;
        // Held-out score of the chosen effects and more, on this round's calibration.
        let score_with = |effs: &[EffectName]| held_out(&full_drive, &fold_drives, effs);
        // Whether the sizes of `new` among `effs` stand off zero on the full fit.
        let size_of = |effs: &[EffectName], fit: &Fitted, new: &[EffectName], judged: usize| {
            let spec = spec_for(&full_drive, &search_ident, effs, false, top);
            size_not_found(&prepared, spec, fit, &split.full, new, size_sigmas(judged))
        };
        let results: Vec<(EffectName, SizedResult)> = pool
            .par_iter()
            .map(|e| {
                let mut effs = chosen.clone();
                effs.push(*e);
                let r = score_with(&effs);
                judged.tick();
                (*e, r.map(|r| (size_of(&effs, &r.2, &[*e], pool.len()), r)))
            })
            .collect();
        // Whether a candidate qualifies, and its row in the candidate table.
        // `resized`: every effect judged is a carried one at another size, which names
        // no new cause and is not held to the share of the structure explained.
        let judge = |name: String,
                     rmse: f64,
                     fit: &Fitted,
                     not_sized: Option<String>,
                     resized: bool|
         -> (bool, CandidateScore) {
            let gain = 100.0 * (1.0 - rmse / current);
            let excess = (current * current - floor * floor).max(1e-30);
            let explained = (current * current - rmse * rmse) / excess;
            let k = fit.coef.len() + fit.x.len();
            let score = n_held * (rmse * rmse).max(1e-300).ln() + k as f64 * n_held.ln();
            let physical = plausible(fit, drive0.ratio());
            let gain_mrad = (current - rmse) * 1e3;
            let verdict = if !physical {
                "size outside physical bounds (stands in for something else)".to_string()
            } else if !resolvable(fit, least_resolvable_drift(&prepared, floor)) {
                "drift below the noise over the record (not told from the sensor's wander)"
                    .to_string()
            } else if gain < ident.min_gain_percent {
                "gain below threshold".to_string()
            } else if gain_mrad < ident.min_gain_mrad {
                "gain below identify.min_gain_mrad".to_string()
            } else if explained < ident.min_explained_fraction && !resized {
                "explains too little of the structure".to_string()
            } else if let Some(why) = not_sized {
                format!("{SIZE_VERDICT}{why}")
            } else {
                "qualifies".to_string()
            };
            let row = CandidateScore {
                name,
                rmse_heldout_mrad: rmse * 1e3,
                gain_percent: gain,
                explained_fraction: explained,
                score,
                accepted: false,
                round,
                verdict: verdict.clone(),
            };
            (verdict == "qualifies", row)
        };
        let round_from = scores.len();
        let mut best: Option<(usize, f64)> = None;
        // Candidates that improve on the current model, for the joint search of pairs.
        let mut helpful: Vec<(EffectName, f64)> = Vec::new();
        for (e, r) in results {
            let (rmse, fit, not_sized) = match r {
                Ok((not_sized, (rmse, _, fit))) => (rmse, fit, not_sized),
                Err(err) => {
                    scores.push(failed_score(label(e), round, &err));
                    continue;
                }
            };
            let significant = not_sized.is_none();
            let (ok, row) = judge(label(e), rmse, &fit, not_sized, resizable(e));
            if rmse < current && admissible(&fit, floor) && significant {
                helpful.push((e, rmse));
            }
            scores.push(row);
            let idx = scores.len() - 1;
            if ok && best.is_none_or(|(_, b)| rmse < b) {
                best = Some((idx, rmse));
            }
            if let Some((b, _)) = best {
                if b == idx {
                    chosen_fit = Some(fit);
                }
            }
        }
        let accepted: Vec<EffectName> = if let Some((idx, rmse)) = best {
            scores[idx].accepted = true;
            scores[idx].verdict = "accepted (best qualifying)".into();
            indistinguishable.extend(near_ties(&scores, round_from, idx, floor * 1e3));
            current = rmse;
            pool.iter()
                .copied()
                .filter(|p| label(*p) == scores[idx].name)
                .collect()
        } else if chosen.len() + 2 <= ident.max_effects && helpful.len() >= 2 {
            // No effect passes the gate alone: two that each carry part of the structure
            // are judged together, held out, among the most helpful few.
            helpful.sort_by(|a, b| a.1.total_cmp(&b.1));
            let top = helpful.len().min(PAIR_POOL);
            let pairs: Vec<(EffectName, EffectName)> = (0..top)
                .flat_map(|i| (i + 1..top).map(move |j| (i, j)))
                .chain((top..helpful.len()).map(|j| (0, j)))
                .map(|(i, j)| (helpful[i].0, helpful[j].0))
                .collect();
            let results: Vec<((EffectName, EffectName), SizedResult)> = pairs
                .par_iter()
                .map(|(a, b)| {
                    let mut effs = chosen.clone();
                    effs.extend([*a, *b]);
                    let r = score_with(&effs);
                    (
                        (*a, *b),
                        // Each pair tests two sizes.
                        r.map(|r| (size_of(&effs, &r.2, &[*a, *b], 2 * pairs.len()), r)),
                    )
                })
                .collect();
            let pairs_from = scores.len();
            let mut best_pair: Option<(usize, f64, (EffectName, EffectName), Fitted)> = None;
            for ((a, b), r) in results {
                let name = format!("{} + {}", label(a), label(b));
                let (rmse, fit, not_sized) = match r {
                    Ok((not_sized, (rmse, _, fit))) => (rmse, fit, not_sized),
                    Err(err) => {
                        scores.push(failed_score(name, round, &err));
                        continue;
                    }
                };
                let (mut ok, mut row) =
                    judge(name, rmse, &fit, not_sized, resizable(a) && resizable(b));
                // Each of the two must earn its place beside the other: the pair gains the
                // threshold over either alone. (Two angle-periodic shapes that each gained
                // under 3 % on a clean 0.4 Hz scan passed together at 3.5 %.)
                let alone =
                    |e: EffectName| helpful.iter().find(|h| h.0 == e).map_or(current, |h| h.1);
                let adds =
                    |e: EffectName| 100.0 * (1.0 - rmse / alone(e)) >= ident.min_gain_percent;
                if ok && !(adds(a) && adds(b)) {
                    ok = false;
                    row.verdict =
                        "one of the two gains under the threshold beside the other".to_string();
                }
                scores.push(row);
                if ok && best_pair.as_ref().is_none_or(|p| rmse < p.1) {
                    best_pair = Some((scores.len() - 1, rmse, (a, b), fit));
                }
            }
            match best_pair {
                Some((idx, rmse, (a, b), fit)) => {
                    scores[idx].accepted = true;
                    scores[idx].verdict =
                        "accepted as a pair (neither passes alone; judged together, held out)"
                            .into();
                    indistinguishable.extend(near_ties(&scores, pairs_from, idx, floor * 1e3));
                    current = rmse;
                    chosen_fit = Some(fit);
                    vec![a, b]
                }
                None => Vec::new(),
            }
        } else {
            Vec::new()
        };
        if accepted.is_empty() {
            break;
        }
        for e in accepted {
            chosen.push(e);
            pool.retain(|p| *p != e);
        }
        // The base model's residual carries the structure just found, and a large smooth
        // error adds its own differences to the floor's estimate: a 0.003 input pulley
        // runout put it at 0.014 mrad over a true 0.0057, enough to end the search before
        // a 0.09 N m bearing friction beside it. What the model found leaves is the
        // tighter estimate; the floor never rises, and never falls below quantisation.
        if let Some(fit) = &chosen_fit {
            let spec = spec_for(&full_drive, &search_ident, &chosen, false, top);
            floor = tighter_floor(floor, &prepared, spec, fit, &split.full, &keep, ic_fit);
        }
        // The base calibration absorbed part of the accepted effect; free it again with
        // the effect in place so the next round does not pick up the leftover bias.
        if top.is_none()
            && nl
                .iter()
                .any(|n| matches!(n.0, NlParam::Mu | NlParam::Preload))
        {
            if let Some(fit) = &chosen_fit {
                if let Ok(r) = recalibrate(
                    &prepared,
                    &ident,
                    &drive0,
                    &full_drive,
                    &split,
                    &chosen,
                    fit,
                ) {
                    full_drive = r.0;
                    fold_drives = r.1;
                    current = current.min(r.2);
                }
            }
        }
    }

    // A tie seen in the round that chose an effect is judged again on the whole model
    // found ([`confirm_tie`]), held out on the same calibration.
    if !indistinguishable.is_empty() {
        let score = |effs: &[EffectName]| {
            held_out(&full_drive, &fold_drives, effs)
                .ok()
                .filter(|(_, _, fit)| admissible(fit, floor))
                .map(|(rmse, _, _)| rmse)
        };
        indistinguishable = match score(&chosen) {
            None => Vec::new(),
            Some(found) => indistinguishable
                .into_iter()
                .filter_map(|t| confirm_tie(t, &chosen, found, floor, &score))
                .collect(),
        };
    }

    // The search stopped before its last possible round: the candidates judged (one
    // score each) are all the work there was.
    let singles_judged = scores.iter().filter(|c| !c.name.contains(" + ")).count();
    if singles_judged < most_judged {
        progress.update(singles_judged, singles_judged);
    }

    // Final extended model: base parameters free again together with the effects (on a
    // calibrated instrument none is free: its drive stays as calibrated, or as raised to
    // carry the logs).
    let drive_ext = if top.is_some() { &full_drive } else { &drive0 };
    let ext_spec = spec_for(drive_ext, &search_ident, &chosen, true, top);
    let mut ev_ext = Evaluator::new(ext_spec, &prepared);
    let nl_ext = ev_ext.nonlinear();
    let mut x0: Vec<f64> = Vec::new();
    for n in &nl_ext {
        x0.push(match n.0 {
            NlParam::Mu => full_drive.friction_coefficient,
            NlParam::Preload => full_drive.preload_n,
            NlParam::Effect(_) | NlParam::Memory(_) => chosen_fit
                .as_ref()
                .and_then(|f| {
                    let evc = Evaluator::new(
                        spec_for(&full_drive, &search_ident, &chosen, false, top),
                        &prepared,
                    );
                    evc.nonlinear()
                        .iter()
                        .position(|m| m.0 == n.0)
                        .and_then(|i| f.x.get(i).copied())
                })
                .unwrap_or(n.3),
        });
    }
    let joint = if chosen.is_empty() && top.is_none() {
        Ok(base_fit.clone())
    } else {
        ev_ext.fit(&split.full, Some(&x0), 30)
    };
    // When freeing the base parameters again leaves the drive's capacity (slack, gross
    // slip), keep them at the base calibration and report the effects fitted on top.
    let (mut ev_final, ext_fit, drive_for) = match joint {
        Ok(f) => (ev_ext, f, drive_ext.clone()),
        Err(_) => {
            let mut evc = Evaluator::new(
                spec_for(&full_drive, &search_ident, &chosen, false, top),
                &prepared,
            );
            let xs = chosen_fit.as_ref().map(|f| f.x.clone());
            let f = evc.fit(&split.full, xs.as_deref(), 30)?;
            (evc, f, full_drive.clone())
        }
    };
    let nl_final = ev_final.nonlinear();
    let (mut ext_resid, ext_pred) = ev_final.residual(&ext_fit, &split.full)?;
    recenter_unfitted(&prepared, &mut ext_resid, &split.full, &keep);
    // What the final model leaves judges the answer and is what the report calls noise.
    let floor = floor.min(noise_floor(&prepared, &ext_resid, &keep, ic_fit).max(1e-12));
    let kept_resid: Vec<f64> = ext_resid
        .iter()
        .zip(&keep)
        .filter(|(_, k)| **k)
        .map(|(r, _)| *r)
        .collect();
    let residual_whiteness = whiteness::ljung_box(&kept_resid, 10, 150);
    let np = nl_final.len() + ext_fit.coef.len();
    let (analysis, runs) = ev_final
        .identifiability_with_runs(&ext_fit, &split.full)
        .unwrap_or_else(|_| {
            let analysis = identifiability::Analysis {
                cov: nalgebra::DMatrix::from_element(np, np, f64::NAN),
                unseen: vec![false; np],
            };
            (analysis, None)
        });
    let cov = analysis.cov.clone();
    let ext_drive = with_base(&drive_for, &nl_final, &ext_fit.x);
    let (mut params, drive_out, mut effects_out) = reported_parameters(
        (&drive0, &ext_drive),
        &nl_final,
        &ext_fit,
        &cov,
        ev_final.stroke_and_thresholds(),
        prepared.iter().map(|l| l.torque.as_slice()),
    );
    let residual_runs = runs.map(|r| {
        let basis = ev_final.stroke_and_thresholds();
        let table = |cov: &nalgebra::DMatrix<f64>| {
            reported_parameters(
                (&drive0, &ext_drive),
                &nl_final,
                &ext_fit,
                cov,
                basis,
                prepared.iter().map(|l| l.torque.as_slice()),
            )
            .0
        };
        ResidualRuns::widen(&r, &mut params, table, mean_sample_interval(&prepared))
    });
    // A carried effect found at another size was fitted as a change on top of the
    // calibrated size: the size reported and saved is the two together.
    let mut resized = Vec::new();
    for e in chosen.iter().filter(|e| resizable(**e)) {
        let calibrated = top.and_then(|fx| e.one_column_size(fx));
        let p = params.iter_mut().find(|p| p.name == e.as_str());
        if let (Some(calibrated), Some(p)) = (calibrated, p) {
            p.value += calibrated;
            e.set_one_column_size(&mut effects_out, p.value);
            resized.push(ResizedEffect {
                effect: e.to_string(),
                calibrated,
                found: p.value,
                std: p.std,
                unit: p.unit.clone(),
                per_log: Vec::new(),
            });
        }
    }
    // The extended model on a calibrated instrument is the instrument with what was found
    // on top: a saved model must carry both.
    if let Some(fx) = top {
        effects_out = overlay(fx, &effects_out);
    }
    // One size shared by logs that differ fits none of them: each log's own says so.
    if prepared.len() > 1 {
        for r in &mut resized {
            let Ok(e) = r.effect.parse::<EffectName>() else {
                continue;
            };
            if let Ok(c) = baseline::score(&drive_for, &effects_out, &prepared, &keep, &[e]) {
                r.per_log = c
                    .per_log_terms
                    .iter()
                    .filter_map(|t| Some((t.log.clone(), r.found + t.values.first()?.value)))
                    .collect();
            }
        }
    }
    // A held-out log's encoder zero is fitted on that log only when it is scored.
    let params: Vec<ParamEstimate> = params
        .into_iter()
        .filter(|p| {
            !options
                .holdout_logs
                .iter()
                .any(|k| p.name == format!("encoder_zero[{k}]"))
        })
        .collect();

    let directions: Vec<EffectDirection> = chosen
        .iter()
        .filter_map(|e| {
            let v = params.iter().find(|p| p.name == e.as_str())?.value;
            Some(EffectDirection {
                effect: e.to_string(),
                value: v,
                meaning: e.direction(v)?.to_string(),
            })
        })
        .collect();
    let not_identifiable = identifiability::not_identifiable(
        &params,
        &analysis,
        &raw_columns(&nl_final, &ext_fit.lin),
    );

    let (rmse_base, rmse_ext) = match &split.outer {
        None => (rmse_base, current),
        Some(outer) => {
            let folds = std::slice::from_ref(outer);
            let bd = std::slice::from_ref(&base_drive);
            let b = cross_validate(
                &prepared,
                &ident,
                &base_drive,
                bd,
                folds,
                &split.full,
                &keep,
                &[],
                None,
            )?;
            let drives = std::slice::from_ref(&full_drive);
            let e = if chosen.is_empty() && top.is_none() {
                b.0
            } else {
                cross_validate(
                    &prepared,
                    &search_ident,
                    &full_drive,
                    drives,
                    folds,
                    &split.full,
                    &keep,
                    &chosen,
                    top,
                )?
                .0
            };
            (b.0, e)
        }
    };
    let structure_ratio = rmse_ext / floor;
    let unexplained_structure = structure_ratio > ident.none_within_floor;
    // Without an effect found, what is left decides: the base model's error, or the
    // calibrated instrument's when the search ran on top of it.
    let left = if top.is_some() { rmse_ext } else { rmse_base };
    let mut cause = if let Some(c) = chosen.first() {
        c.to_string()
    } else if left / floor > ident.none_within_floor {
        "unexplained".to_string()
    } else {
        "none".to_string()
    };

    let play_folds = split
        .outer
        .as_ref()
        .map(|o| vec![o.clone()])
        .unwrap_or_else(|| split.folds.clone());
    let play_operator = if options.skip_play_operator {
        None
    } else {
        Some(play::cross_validate(
            &prepared,
            &drive0,
            &ident,
            &play_folds,
        )?)
    };

    // An extension that a deadband fitted to the same logs beats, held out, has not shown
    // that it names what the drive does: the effects it found are kept in `causes`, but
    // no cause is claimed.
    let beats_play_operator = play_operator
        .as_ref()
        .map(|p| rmse_ext * 1e3 < p.rmse_heldout_mrad);
    if beats_play_operator == Some(false) && !chosen.is_empty() {
        cause = "unexplained".to_string();
    }
    // Nor has one that leaves structure which another candidate, refused only for a size
    // these logs cannot pin, takes down to the noise.
    if !chosen.is_empty() && !unpinned(&scores, rmse_ext * 1e3, floor * 1e3).is_empty() {
        cause = "unexplained".to_string();
    }

    // Traces for plots, with the fitted ratio and each log's encoder zero removed.
    let ic_ext = drive_out.ratio();
    let ic_ref = drive0.ratio();
    let mut traces = Vec::new();
    let mut start = 0;
    for (k, l) in prepared.iter().enumerate() {
        let r = start..start + l.t.len();
        let off = ext_fit
            .lin
            .iter()
            .position(|p| *p == LinParam::Offset(k))
            .map_or(0.0, |i| ext_fit.coef[i]);
        // Predictions are of the error at the reference ratio; shift them to the fitted one.
        let corr = |th_in: f64| th_in * (1.0 / ic_ref - 1.0 / ic_ext);
        let measured: Vec<f64> = (0..l.t.len())
            .map(|j| l.th_out[j] - l.th_in[j] / ic_ext - off)
            .collect();
        let base_rad: Vec<f64> = r
            .clone()
            .enumerate()
            .map(|(j, i)| base_pred[i] - off + corr(l.th_in[j]))
            .collect();
        let extended_rad: Vec<f64> = r
            .clone()
            .enumerate()
            .map(|(j, i)| ext_pred[i] - off + corr(l.th_in[j]))
            .collect();
        traces.push(Trace {
            log: l.source.clone(),
            t_s: l.t.clone(),
            theta_in_rad: l.th_in.clone(),
            theta_out_rad: l.th_out.clone(),
            velocity_rad_s: l.vel_in.clone(),
            load_nm: l.torque.clone(),
            measured_rad: measured,
            base_rad,
            extended_rad,
            held_out: options.holdout_logs.contains(&k),
            excluded: segments::shades(
                &segments_per_log[k],
                cut_logs[k].t_s.first().copied().unwrap_or(0.0),
            ),
        });
        start = r.end;
    }

    let residual_signatures = loo::residual_signatures(&prepared, &ext_resid, &keep, floor);
    // The instrument as calibrated, judged on these logs before anything is refitted.
    let calibrated_model = match top {
        Some(fx) => {
            let refitted_per_log = std::iter::once("encoder zero".to_string())
                .chain(ident.per_log.iter().map(|e| e.to_string()))
                .collect();
            let held_not_refitted: Vec<String> = effects::PER_LOG_EFFECTS
                .iter()
                .filter(|e| resizable(**e))
                .map(|e| e.to_string())
                .collect();
            Some(match &cannot_carry {
                None => {
                    let c = baseline::score(&drive0, fx, &prepared, &keep, &ident.per_log)?;
                    CalibratedModelScore {
                        rmse_mrad: Some(c.rmse_mrad),
                        held_out_mrad: calibrated_held_out * 1e3,
                        per_log_mrad: c.per_log_mrad.into_iter().map(Some).collect(),
                        cannot_carry: None,
                        refitted_per_log,
                        per_log_terms: c.per_log_terms,
                        held_not_refitted,
                        residual_signatures: loo::residual_signatures(
                            &prepared,
                            &c.residual,
                            &keep,
                            floor,
                        ),
                    }
                }
                Some(raise) => CalibratedModelScore {
                    rmse_mrad: None,
                    held_out_mrad: calibrated_held_out * 1e3,
                    per_log_mrad: per_log_calibrated(&drive0, fx, &prepared, &keep, &ident.per_log),
                    cannot_carry: Some(raise.clone()),
                    refitted_per_log,
                    per_log_terms: Vec::new(),
                    held_not_refitted,
                    residual_signatures: Vec::new(),
                },
            })
        }
        _ => None,
    };
    Ok(Diagnosis {
        residual_signatures,
        indistinguishable,
        calibrated_model,
        cause,
        causes: chosen.iter().map(|c| c.to_string()).collect(),
        rmse_base_mrad: rmse_base * 1e3,
        rmse_extended_mrad: rmse_ext * 1e3,
        gain_percent: 100.0 * (1.0 - rmse_ext / rmse_base.max(1e-300)),
        noise_floor_mrad: floor * 1e3,
        structure_ratio,
        unexplained_structure,
        residual_whiteness,
        residual_runs,
        params,
        candidates: scores,
        play_operator,
        beats_play_operator,
        directions,
        resized,
        searchable,
        holdout: split.text,
        logs: prepared.iter().map(|l| l.source.clone()).collect(),
        ignored_columns: logs
            .iter()
            .filter(|l| !l.extra_columns.is_empty())
            .map(|l| (l.source.clone(), l.extra_columns.clone()))
            .collect(),
        start_cuts,
        excluded_segments: segments_per_log.into_iter().flatten().collect(),
        drive: drive_out,
        effects: effects_out,
        traces,
        params_on_bound: model::on_bounds(&nl_final, &ext_fit.x),
        not_identifiable,
        fits_on_limit: [
            ("base calibration", &base_fit),
            ("extended calibration", &ext_fit),
        ]
        .iter()
        .filter(|(_, f)| !f.converged)
        .map(|(what, f)| {
            format!(
                "{what}: stopped on its limit of {} iterations while still improving",
                f.iterations
            )
        })
        .collect(),
    })
}

/// `base` with every key that `top` sets taken from `top` (the effects found on top of a
/// calibrated instrument added to its own).
fn overlay(base: &EffectsParams, top: &EffectsParams) -> EffectsParams {
    let (Ok(serde_json::Value::Object(mut b)), Ok(serde_json::Value::Object(t))) =
        (serde_json::to_value(base), serde_json::to_value(top))
    else {
        return base.clone();
    };
    for (k, v) in t {
        if !v.is_null() {
            b.insert(k, v);
        }
    }
    serde_json::from_value(serde_json::Value::Object(b)).unwrap_or_else(|_| base.clone())
}

/// The parameter-table names of the fitted coefficients that are reported as they are
/// (not derived from several), with their columns in the covariance: nonlinear first,
/// then linear in the fit's order.
fn raw_columns(nl: &[(NlParam, f64, f64, f64)], lin: &[LinParam]) -> Vec<(String, usize)> {
    let mut out: Vec<(String, usize)> = nl
        .iter()
        .enumerate()
        .map(|(k, n)| (n.0.name().to_string(), k))
        .collect();
    for (i, p) in lin.iter().enumerate() {
        let name = match p {
            LinParam::Offset(k) => format!("encoder_zero[{k}]"),
            LinParam::ModulusScale => "cable_modulus_n".into(),
            LinParam::InverseRatio => "ratio".into(),
            LinParam::Effect(
                e @ (EffectName::EncoderDelay
                | EffectName::EncoderScaleError
                | EffectName::ThermalDrift
                | EffectName::LoadCompliance),
                0,
            ) => e.to_string(),
            LinParam::PerLog(e, k) => format!("{e}_per_log[{k}]"),
            LinParam::Effect(..) => continue,
        };
        out.push((name, nl.len() + i));
    }
    out
}

/// The first log the calibrated drive cannot carry with `fx`'s effects (gross slip or
/// slack in the replay): the error, and the fault in words for the report.
fn first_replay_fault(
    drive: &DriveParams,
    fx: &EffectsParams,
    logs: &[Prepared],
) -> Option<(IdentifyError, String)> {
    logs.iter().find_map(|l| {
        model::calibrated_prediction(drive, fx, l, [0.0; 3])
            .err()
            .map(|e| {
                let words = match &e {
                    // The fault without the physics' design advice, which is not this
                    // report's (the remedy here is a calibration that sees this log).
                    IdentifyError::Replay { log, t_s, message } => format!(
                        "{log}: at t = {t_s:.3} s, {}",
                        message.split("; ").next().unwrap_or(message)
                    ),
                    other => other.to_string(),
                };
                (e, words)
            })
    })
}

/// The calibrated drive raised so that it carries the logs: its preload (its friction
/// coefficient, when `identify.unknown` leaves the preload known) raised in steps of
/// [`model::CARRY_STEP`] to the first value at which the calibrated model's replay carries every
/// log, every effect held; `None` when neither is free or no raise within the bounds
/// carries the logs. Nothing is fitted: a fit of the two along their valley wandered far
/// (friction to its bound of 1) and did worse held out than the least raise (on the
/// heaviest da Vinci log against a calibration without it, 3.44 against 3.37 mrad).
fn raise_to_carry(
    logs: &[Prepared],
    ident: &IdentifyParams,
    drive0: &DriveParams,
    fx: &EffectsParams,
) -> Option<DriveParams> {
    let carry_ident = IdentifyParams {
        unknown: ident
            .unknown
            .iter()
            .filter(|u| *u == "friction_coefficient" || *u == "preload_n")
            .cloned()
            .collect(),
        ..ident.clone()
    };
    let mut ev = Evaluator::new(spec_for(drive0, &carry_ident, &[], true, Some(fx)), logs);
    let nl = ev.nonlinear();
    let x = ev.carrying_start()?;
    Some(with_base(drive0, &nl, &x))
}

/// Each log's error under the calibrated model as given (`None` where its drive cannot
/// carry the log), mrad.
fn per_log_calibrated(
    drive: &DriveParams,
    fx: &EffectsParams,
    logs: &[Prepared],
    keep: &[bool],
    per_log: &[EffectName],
) -> Vec<Option<f64>> {
    let mut row = 0;
    logs.iter()
        .map(|l| {
            let rows = row..row + l.t.len();
            row = rows.end;
            baseline::score(drive, fx, std::slice::from_ref(l), &keep[rows], per_log)
                .ok()
                .map(|c| c.rmse_mrad)
        })
        .collect()
}

/// Base calibration with effects in place: returns the drive calibrated on the final mask,
/// per-fold drives and the cross-validated RMSE.
fn recalibrate(
    logs: &[Prepared],
    ident: &IdentifyParams,
    drive0: &DriveParams,
    full_drive: &DriveParams,
    split: &Split,
    effects: &[EffectName],
    fixed_fit: &Fitted,
) -> Result<(DriveParams, Vec<DriveParams>, f64), IdentifyError> {
    let fixed = Evaluator::new(spec_for(full_drive, ident, effects, false, None), logs).nonlinear();
    let mut ev = Evaluator::new(spec_for(drive0, ident, effects, true, None), logs);
    let nl = ev.nonlinear();
    let x0: Vec<f64> = nl
        .iter()
        .map(|n| match n.0 {
            NlParam::Mu => full_drive.friction_coefficient,
            NlParam::Preload => full_drive.preload_n,
            NlParam::Effect(_) | NlParam::Memory(_) => fixed
                .iter()
                .position(|m| m.0 == n.0)
                .and_then(|i| fixed_fit.x.get(i).copied())
                .unwrap_or(n.3),
        })
        .collect();
    let full = ev.fit(&split.full, Some(&x0), 20)?;
    let mut drives = Vec::new();
    let mut held = Vec::new();
    for (train, test) in &split.folds {
        let f = ev.fit(train, Some(&full.x), 8)?;
        drives.push(with_base(drive0, &nl, &f.x));
        let (r, _) = ev.residual(&f, train)?;
        held.extend(r.iter().zip(test).filter(|(_, t)| **t).map(|(r, _)| *r));
    }
    Ok((
        with_base(drive0, &nl, &full.x),
        drives,
        rms(held.iter().copied()),
    ))
}

/// Whether every effect size in a fit is physically possible; a runout of half the radius
/// or a delay of seconds is a sign that the effect is standing in for something else.
fn plausible(f: &Fitted, ic: f64) -> bool {
    let coef = |e: EffectName, k: usize| f.effect_coef(e, k);
    let limit = |e: EffectName| match e {
        EffectName::InputPulleyRunout | EffectName::OutputDrumRunout => 0.05,
        EffectName::EncoderDelay => 0.05,
        EffectName::EncoderScaleError => 0.02,
        EffectName::ThermalDrift => 1e-4,
        // A ratio shape of 0.2 rad over a stroke is a linkage, not a cable drive.
        EffectName::AngleDependentRatio => 0.2,
        _ => f64::INFINITY,
    };
    EffectName::EVERY.iter().all(|e| {
        let v = match (coef(*e, 0), coef(*e, 1)) {
            (Some(a), Some(b)) => {
                let h = a.hypot(b);
                if *e == EffectName::InputPulleyRunout {
                    h * ic
                } else {
                    h
                }
            }
            (Some(a), None) => a.abs(),
            _ => 0.0,
        };
        v <= limit(*e)
    })
}

/// The smallest thermal drift the logs can tell from their sensors' own slow wander,
/// rad/s: one that moves the reading by the noise floor (`floor`, rad RMS) over the longest
/// record. A random walk's slope over a record of length `T` scatters by about its end RMS
/// over `T`, so a smaller drift is no more than the encoder's wander: on a clean 30 s log
/// with an input jerk kept out, a drift of 0.13 µrad/s (4 µrad over the log, under the
/// floor of 5.7 µrad) passed the gain gate at 5 %. The realistic drifts of a bench, 1 to 5
/// µrad/s, move a 30 s record by 5 to 25 times that floor.
fn least_resolvable_drift(logs: &[Prepared], floor: f64) -> f64 {
    let longest = logs
        .iter()
        .filter_map(|l| Some(l.t.last()? - l.t.first()?))
        .fold(0.0, f64::max);
    if longest > 0.0 {
        floor / longest
    } else {
        0.0
    }
}

/// Whether a fit's thermal drift, if it has one, is at least `min_drift_rad_s` in size
/// (see [`least_resolvable_drift`]).
fn resolvable(f: &Fitted, min_drift_rad_s: f64) -> bool {
    f.effect_coef(EffectName::ThermalDrift, 0)
        .is_none_or(|v| v.abs() >= min_drift_rad_s)
}

/// Ratio implied by a fit's inverse-ratio coefficient.
fn fitted_ratio(drive: &DriveParams, f: &Fitted) -> f64 {
    let ic = drive.ratio();
    f.lin
        .iter()
        .position(|p| *p == LinParam::InverseRatio)
        .map_or(ic, |i| 1.0 / (1.0 / ic + f.coef[i]))
}

/// Refuses a log whose input does not move: with nothing driven, every model replays the
/// same still output, its residual is the encoder zero alone, and a noise floor of zero
/// judged the fits (a verdict with a floor of 0.0000 mrad, exit 0).
fn still_input(p: &Prepared) -> Result<(), IdentifyError> {
    let (lo, hi) = p
        .th_in
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let span = if hi >= lo { hi - lo } else { 0.0 };
    // A drive held still reads at most a step or two of encoder jitter.
    if span > 2.0 * p.q_in.max(1e-9) {
        return Ok(());
    }
    Err(IdentifyError::BadLog {
        log: p.source.clone(),
        message: format!(
            "the input angle (theta_in_rad) does not move in this log (it spans {} rad{}): a diagnosis needs the drive turned through its stroke, with at least one reversal to see the friction memory",
            crate::compact(span),
            if p.q_in > 0.0 {
                format!(", {} encoder steps", crate::compact(span / p.q_in))
            } else {
                String::new()
            }
        ),
    })
}

/// The parameter table of a fit as the report prints it, with the drive and effects it
/// stands for: the calibrated terms (`base` as given, `fitted` the drive of the fit) and the
/// effects' own parameters on `basis`, the logs' stroke and memory thresholds, with the
/// memory's size at the mean of `torques`, the loads of the logs fitted.
pub(super) fn reported_parameters<'a>(
    (base, fitted): (&DriveParams, &DriveParams),
    nl: &[(NlParam, f64, f64, f64)],
    fit: &Fitted,
    cov: &nalgebra::DMatrix<f64>,
    basis: ((f64, f64), [f64; extra_effects::MEMORY_THRESHOLDS]),
    torques: impl Iterator<Item = &'a [f64]>,
) -> (Vec<ParamEstimate>, DriveParams, EffectsParams) {
    let (mut params, drive, mut eff) = estimates::parameters(base, fitted, nl, fit, cov);
    let (stroke, thresholds) = basis;
    extra_effects::parameters(
        fit,
        nl.len(),
        cov,
        &extra_effects::Basis {
            stroke,
            thresholds: &thresholds,
            mean_load_factor: extra_effects::mean_load_factor(
                torques,
                model::memory_load_exponent(nl, &fit.x),
            ),
        },
        &mut params,
        &mut eff,
    );
    (params, drive, eff)
}

/// Mean time between samples over the logs, s (0 for logs of one sample).
pub(crate) fn mean_sample_interval(logs: &[Prepared]) -> f64 {
    let (span, steps) =
        logs.iter()
            .fold((0.0, 0usize), |(s, n), l| match (l.t.first(), l.t.last()) {
                (Some(a), Some(b)) if l.t.len() > 1 => (s + (b - a), n + l.t.len() - 1),
                _ => (s, n),
            });
    if steps == 0 {
        0.0
    } else {
        span / steps as f64
    }
}

/// Standard deviations by which an effect's fitted size must stand off zero to be found:
/// under two, its size is not told from zero (a clean 2 s gimbal log fitted a drum runout
/// of 8.1e-5 +- 6.4e-5, and a 5 % held-out gain named it).
pub const MIN_SIZE_SIGMAS: f64 = 2.0;

/// Chance, over all the candidates of one round together, that a size the logs do not
/// hold passes [`size_sigmas`] (0.05, two-sided).
pub const SIZE_FAMILY_LEVEL: f64 = 0.05;

/// Standard deviations by which a size must stand off zero when `judged` sizes (one per
/// candidate, two per pair) are judged side by side in one round: at least
/// [`MIN_SIZE_SIGMAS`], and the two-sided [`SIZE_FAMILY_LEVEL`] shared among them
/// (Bonferroni: 2.73 for 8 candidates, 2.84 for 11, 3.14 for the 30 sizes of 15 pairs,
/// 3.21 for the 38 of 19).
/// With one threshold of two for every candidate, the chance that one of eleven passes by
/// noise alone is about 40 %: beside a 2e-4 rad friction memory on `synth` logs an encoder
/// scale error of 1.35e-6 +- 5.5e-7 (2.4 sigma) was named second on two of four seeds.
pub fn size_sigmas(judged: usize) -> f64 {
    let m = judged.max(1) as f64;
    MIN_SIZE_SIGMAS.max(crate::stats::normal_quantile(
        1.0 - 0.5 * SIZE_FAMILY_LEVEL / m,
    ))
}

/// Why the effects `new` of a fit are not found, when one is not: a size within `sigmas`
/// standard deviations of zero ([`size_sigmas`]) or along a direction the logs do not
/// see, or a size fitted onto the bound that means none of the effect (a cable transport
/// over the least travel allowed, a bearing friction of zero), where
/// the logs push it to less than the model can hold. `None`: every new effect stands off
/// zero. The sizes are read as the report reads them ([`estimates::parameters`]), on the
/// fit `fit` of the model `spec` over the rows `mask`.
fn size_not_found(
    logs: &[Prepared],
    spec: Spec,
    fit: &Fitted,
    mask: &[bool],
    new: &[EffectName],
    sigmas: f64,
) -> Option<String> {
    let drive = spec.drive.clone();
    let carried = |e: EffectName| spec.calibrated.as_ref().is_some_and(|fx| e.carried_by(fx));
    let change: Vec<bool> = new.iter().map(|e| carried(*e)).collect();
    let mut ev = Evaluator::new(spec, logs);
    let nl = ev.nonlinear();
    for e in new {
        if let Some(lo) = model::at_none_bound(&nl, &fit.x, *e) {
            return Some(format!(
                "{e} fitted onto its lower bound {} (none of it): not found",
                crate::compact(lo)
            ));
        }
    }
    let analysis = ev.identifiability(fit, mask).ok()?;
    let (params, _, _) = reported_parameters(
        (&drive, &drive),
        &nl,
        fit,
        &analysis.cov,
        ev.stroke_and_thresholds(),
        logs.iter().map(|l| l.torque.as_slice()),
    );
    new.iter().zip(&change).find_map(|(e, change)| {
        let p = params.iter().find(|p| p.name == e.as_str())?;
        let seen = p.std > 0.0 && p.std.is_finite();
        (!seen || p.value.abs() < sigmas * p.std).then(|| {
            let what = if *change {
                format!("a change of {e} from its calibrated size")
            } else {
                e.to_string()
            };
            format!(
                "{what} of {} +- {} not told from zero (under {} sigma of a white residual)",
                crate::compact(p.value),
                crate::compact(p.std),
                crate::compact((sigmas * 100.0).round() / 100.0)
            )
        })
    })
}
