//! Play-operator (deadband) model of the drive, the usual description of such drives:
//! `theta_out = P_r(theta_in/ic) + c*M + zero`, fitted on its own for comparison.

use super::effects::IdentifyParams;
use super::lm::{levenberg_marquardt, linear_lsq};
use super::model::Prepared;
use super::{BaselineScore, IdentifyError, ParamEstimate};
use crate::physics::DriveParams;

/// Play operator of half-width `r` applied to `x`, started centred.
pub fn play(x: &[f64], r: f64) -> Vec<f64> {
    let mut out = vec![0.0; x.len()];
    play_into(x, r, x.first().copied().unwrap_or(0.0), &mut out);
    out
}

/// Play operator of half-width `r` applied to `x` into `out` (as long as `x`), its output
/// starting from `y0` (clamped to the first sample's band).
pub fn play_into(x: &[f64], r: f64, y0: f64, out: &mut [f64]) {
    let mut y = y0;
    for (o, v) in out.iter_mut().zip(x) {
        y = y.clamp(v - r, v + r);
        *o = y;
    }
}

struct PlayFit {
    x: Vec<f64>,
    coef: Vec<f64>,
}

#[allow(clippy::needless_range_loop)]
/// Columns: per-log zero, compliance `c` against torque. Target `theta_out - P_r(a theta_in)`.
fn evaluate(logs: &[Prepared], a: f64, r: f64) -> (Vec<f64>, Vec<Vec<f64>>) {
    let n: usize = logs.iter().map(|l| l.t.len()).sum();
    let mut target = Vec::with_capacity(n);
    // Not `vec![..; k]`: a cloned `Vec` does not keep its capacity.
    let mut cols: Vec<Vec<f64>> = (0..=logs.len()).map(|_| Vec::with_capacity(n)).collect();
    for (k, l) in logs.iter().enumerate() {
        let x: Vec<f64> = l.th_in.iter().map(|t| a * t).collect();
        let p = play(&x, r);
        for i in 0..l.t.len() {
            target.push(l.th_out[i] - p[i]);
            for (j, c) in cols.iter_mut().enumerate().take(logs.len()) {
                c.push(if j == k { 1.0 } else { 0.0 });
            }
            cols[logs.len()].push(l.torque[i]);
        }
    }
    (target, cols)
}

fn fit(
    logs: &[Prepared],
    mask: &[bool],
    a0: f64,
    fit_a: bool,
    ident: &IdentifyParams,
    start: Option<&[f64]>,
) -> Result<PlayFit, IdentifyError> {
    let resid = |x: &[f64]| -> Option<Vec<f64>> {
        let a = if fit_a { x[1] } else { a0 };
        let (t, cols) = evaluate(logs, a, x[0]);
        let refs: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
        let f = linear_lsq(&refs, &t, mask)?;
        Some(
            (0..t.len())
                .filter(|i| mask[*i])
                .map(|i| t[i] - refs.iter().zip(&f.coef).map(|(c, b)| c[i] * b).sum::<f64>())
                .collect(),
        )
    };
    let amp = logs
        .iter()
        .flat_map(|l| l.th_out.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1e-3);
    let (mut lo, mut hi) = (vec![0.0], vec![0.2 * amp]);
    let mut x0 = vec![0.0];
    if fit_a {
        lo.push(a0 / ident.ratio_factor_bounds[1]);
        hi.push(a0 / ident.ratio_factor_bounds[0]);
        x0.push(a0);
    }
    if let Some(s) = start {
        x0 = s.to_vec();
    } else {
        // The cost is flat in r where the play never engages; scan first.
        let mut best = (f64::INFINITY, 0.0);
        for g in 0..12 {
            let r = hi[0] * (g as f64 / 11.0).powi(2);
            let mut x = x0.clone();
            x[0] = r;
            if let Some(res) = resid(&x) {
                let c: f64 = res.iter().map(|e| e * e).sum();
                if c < best.0 {
                    best = (c, r);
                }
            }
        }
        x0[0] = best.1;
    }
    let lm = levenberg_marquardt(resid, &x0, &lo, &hi, 30)
        .map_err(|e| IdentifyError::Fit(e.to_string()))?;
    let a = if fit_a { lm.x[1] } else { a0 };
    let (t, cols) = evaluate(logs, a, lm.x[0]);
    let refs: Vec<&[f64]> = cols.iter().map(|c| c.as_slice()).collect();
    let f = linear_lsq(&refs, &t, mask)
        .ok_or_else(|| IdentifyError::Fit("play operator: singular".into()))?;
    Ok(PlayFit {
        x: lm.x,
        coef: f.coef,
    })
}

/// Held-out RMSE of the fitted play-operator model on the same split as the diagnosis.
pub fn cross_validate(
    logs: &[Prepared],
    drive: &DriveParams,
    ident: &IdentifyParams,
    folds: &[(Vec<bool>, Vec<bool>)],
) -> Result<BaselineScore, IdentifyError> {
    let a0 = 1.0 / drive.ratio();
    let fit_a = ident.is_unknown("ratio");
    let first = folds
        .first()
        .ok_or_else(|| IdentifyError::Fit("play operator: no folds".into()))?;
    let full = fit(logs, &first.0, a0, fit_a, ident, None)?;
    let mut held = Vec::new();
    for (train, test) in folds {
        let f = fit(logs, train, a0, fit_a, ident, Some(&full.x))?;
        let a = if fit_a { f.x[1] } else { a0 };
        let (t, cols) = evaluate(logs, a, f.x[0]);
        let mut start = 0;
        for (k, l) in logs.iter().enumerate() {
            let rows = start..start + l.t.len();
            let mut zero = f.coef[k];
            if !rows.clone().any(|i| train[i]) {
                // Encoder zero of a log never seen in training: a nuisance fitted on it.
                zero = rows
                    .clone()
                    .map(|i| t[i] - f.coef[logs.len()] * cols[logs.len()][i])
                    .sum::<f64>()
                    / l.t.len() as f64;
            }
            for i in rows.clone() {
                if test[i] {
                    held.push(t[i] - zero - f.coef[logs.len()] * cols[logs.len()][i]);
                }
            }
            start = rows.end;
        }
    }
    let rmse = (held.iter().map(|e| e * e).sum::<f64>() / held.len().max(1) as f64).sqrt();
    let mut params = vec![
        ParamEstimate::new("play_half_width", full.x[0], f64::NAN, "rad (output)"),
        ParamEstimate::new("compliance", full.coef[logs.len()], f64::NAN, "rad/(N m)"),
    ];
    if fit_a {
        params.push(ParamEstimate::new("ratio", 1.0 / full.x[1], f64::NAN, "1"));
    }
    Ok(BaselineScore {
        name: "play_operator".into(),
        rmse_heldout_mrad: rmse * 1e3,
        params,
    })
}
