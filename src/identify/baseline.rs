//! A calibrated scenario's whole model replayed on a log as given: the drive and every
//! effect of `[effects]` at their calibrated values, with only what belongs to one log
//! (its encoder zero) fitted on it. This is how a new log is judged against the instrument
//! before anything is recalibrated on it.

use serde::Serialize;

use super::model::{calibrated_prediction, Prepared};
use super::IdentifyError;
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
    /// Residual on every row (excluded ones too), stacked over the logs, rad (for the
    /// signatures, which take the same mask).
    #[serde(skip)]
    pub residual: Vec<f64>,
}

/// Replay `drive` with `effects` on `logs` and score it on the rows `keep` (stacked over
/// the logs; rows of stretches that are not the drive are false), fitting only each log's
/// encoder zero (the mean of its kept residual). The replay runs through every row in time
/// order. Typical: a few ms per 20 s log.
pub fn score(
    drive: &DriveParams,
    effects: &EffectsParams,
    logs: &[Prepared],
    keep: &[bool],
) -> Result<CalibratedScore, IdentifyError> {
    let ic = drive.ratio();
    let mut residual = Vec::new();
    let mut per_log = Vec::with_capacity(logs.len());
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
        let used: Vec<f64> = r
            .iter()
            .zip(&kept)
            .filter(|(_, k)| **k)
            .map(|(v, _)| *v)
            .collect();
        let zero = used.iter().sum::<f64>() / used.len().max(1) as f64;
        let ss: f64 = used.iter().map(|v| (v - zero) * (v - zero)).sum();
        per_log.push((ss / used.len().max(1) as f64).sqrt() * 1e3);
        sum += ss;
        count += used.len();
        residual.extend(r.iter().map(|v| v - zero));
    }
    Ok(CalibratedScore {
        rmse_mrad: (sum / count.max(1) as f64).sqrt() * 1e3,
        per_log_mrad: per_log,
        residual,
    })
}
