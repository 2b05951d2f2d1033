//! A calibrated scenario's whole model replayed on a log as given: the drive and every
//! effect of `[effects]` at their calibrated values, with only what belongs to one log
//! (its encoder zero, and the terms the scenario marks as per log) fitted on it. This is
//! how a new log is judged against the instrument before anything is recalibrated on it.

use serde::Serialize;

use super::model::{calibrated_prediction, single_column, Prepared};
use super::records::{PerLogTerms, PerLogValue};
use super::{EffectName, IdentifyError};
use crate::physics::effects::EffectsParams;
use crate::physics::DriveParams;

/// The calibrated model's error on logs it was not fitted to.
#[derive(Clone, Debug, Serialize)]
pub struct CalibratedScore {
    /// RMS of measured minus predicted transmission error over every log, each with its own
    /// encoder zero, mrad.
    pub rmse_mrad: f64,
    /// The same per log, in input order, mrad.
    pub per_log_mrad: Vec<f64>,
    /// Each log's own value of the terms refitted per log (empty when none is marked).
    pub per_log_terms: Vec<PerLogTerms>,
    /// Residual on every row (excluded ones too), stacked over the logs, rad (for the
    /// signatures, which take the same mask).
    #[serde(skip)]
    pub residual: Vec<f64>,
}

/// Replay `drive` with `effects` on `logs` and score it on the rows `keep` (stacked over
/// the logs; rows of stretches that are not the drive are false), fitting on each log only
/// its encoder zero and its own part of the terms in `per_log` (least squares on the kept
/// rows; the scenario's `identify.per_log`). The replay runs through every row in time
/// order. Typical: a few ms per 20 s log.
pub fn score(
    drive: &DriveParams,
    effects: &EffectsParams,
    logs: &[Prepared],
    keep: &[bool],
    per_log: &[EffectName],
) -> Result<CalibratedScore, IdentifyError> {
    let ic = drive.ratio();
    let mut residual = Vec::new();
    let mut per_log_mrad = Vec::with_capacity(logs.len());
    let mut terms = Vec::new();
    let (mut sum, mut count) = (0.0, 0usize);
    let mut row = 0;
    for l in logs {
        let kept: Vec<bool> = (row..row + l.t.len())
            .map(|i| keep.get(i).copied().unwrap_or(true))
            .collect();
        row += l.t.len();
        let pred = calibrated_prediction(drive, effects, l, [0.0; 3])?;
        let r: Vec<f64> = (0..l.t.len())
            .map(|i| l.th_out[i] - l.th_in[i] / ic - pred[i])
            .collect();
        let coef = fit_per_log(l, &r, &kept, per_log);
        let fitted = |i: usize| {
            coef[0]
                + per_log
                    .iter()
                    .zip(&coef[1..])
                    .map(|(e, c)| c * single_column(*e, l, i))
                    .sum::<f64>()
        };
        let r: Vec<f64> = r.iter().enumerate().map(|(i, v)| v - fitted(i)).collect();
        let used = r.iter().zip(&kept).filter(|(_, k)| **k);
        let n = used.clone().count();
        let ss: f64 = used.map(|(v, _)| v * v).sum();
        per_log_mrad.push((ss / n.max(1) as f64).sqrt() * 1e3);
        sum += ss;
        count += n;
        residual.extend(r);
        if !per_log.is_empty() {
            terms.push(PerLogTerms {
                log: l.source.clone(),
                values: per_log
                    .iter()
                    .zip(&coef[1..])
                    .map(|(e, c)| PerLogValue {
                        effect: e.to_string(),
                        value: *c,
                        unit: e.unit().to_string(),
                    })
                    .collect(),
            });
        }
    }
    Ok(CalibratedScore {
        rmse_mrad: (sum / count.max(1) as f64).sqrt() * 1e3,
        per_log_mrad,
        per_log_terms: terms,
        residual,
    })
}

/// Least-squares zero and per-log terms of residual `r` on the kept rows of log `l`:
/// `[zero, per_log...]`. A term the rows cannot pin (a column the zero or another term
/// already spans, as a constant torque does) gets 0 rather than an arbitrary split.
fn fit_per_log(l: &Prepared, r: &[f64], kept: &[bool], per_log: &[EffectName]) -> Vec<f64> {
    let rows: Vec<usize> = (0..r.len()).filter(|i| kept[*i]).collect();
    let m = 1 + per_log.len();
    let mut coef = vec![0.0; m];
    if rows.is_empty() {
        return coef;
    }
    if per_log.is_empty() {
        coef[0] = rows.iter().map(|i| r[*i]).sum::<f64>() / rows.len() as f64;
        return coef;
    }
    let a = nalgebra::DMatrix::from_fn(rows.len(), m, |i, j| match j {
        0 => 1.0,
        _ => single_column(per_log[j - 1], l, rows[i]),
    });
    let b = nalgebra::DVector::from_iterator(rows.len(), rows.iter().map(|i| r[*i]));
    // Columns scaled to unit norm so that the rank tolerance means the same for a torque
    // in N m and a time in s.
    let norms: Vec<f64> = a.column_iter().map(|c| c.norm()).collect();
    let scaled = nalgebra::DMatrix::from_fn(rows.len(), m, |i, j| {
        if norms[j] > 0.0 {
            a[(i, j)] / norms[j]
        } else {
            0.0
        }
    });
    if let Ok(x) = scaled.svd(true, true).solve(&b, 1e-9) {
        for (j, c) in coef.iter_mut().enumerate() {
            let v = if norms[j] > 0.0 { x[j] / norms[j] } else { 0.0 };
            *c = if v.is_finite() { v } else { 0.0 };
        }
    }
    coef
}
