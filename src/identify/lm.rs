//! Least squares: bounded Levenberg-Marquardt with a finite-difference Jacobian and linear
//! least squares with covariance, both on nalgebra.

use nalgebra::{DMatrix, DVector};

/// Linear least-squares solution `y ~ X b`.
#[derive(Clone, Debug)]
pub struct LinearFit {
    /// Coefficients.
    pub coef: Vec<f64>,
    /// Unscaled covariance `(X^T X)^-1` (multiply by the residual variance).
    pub cov_unscaled: DMatrix<f64>,
}

/// Solve `min |y - X b|` on the rows where `mask` is true; columns are given column-wise.
/// Collinear columns get a minimum-norm answer (singular values below 1e-10 relative are
/// dropped) instead of a blow-up.
pub fn linear_lsq(cols: &[&[f64]], y: &[f64], mask: &[bool]) -> Option<LinearFit> {
    let p = cols.len();
    if p == 0 {
        return Some(LinearFit {
            coef: Vec::new(),
            cov_unscaled: DMatrix::zeros(0, 0),
        });
    }
    let mut ata = DMatrix::<f64>::zeros(p, p);
    let mut aty = DVector::<f64>::zeros(p);
    let mut row = vec![0.0; p];
    for i in 0..y.len() {
        if !mask[i] {
            continue;
        }
        for (j, c) in cols.iter().enumerate() {
            row[j] = c[i];
        }
        for a in 0..p {
            let ra = row[a];
            if ra == 0.0 {
                continue;
            }
            aty[a] += ra * y[i];
            for b in a..p {
                ata[(a, b)] += ra * row[b];
            }
        }
    }
    for a in 0..p {
        for b in 0..a {
            ata[(a, b)] = ata[(b, a)];
        }
    }
    // Equilibrate so the singular-value cut is scale free.
    let d: Vec<f64> = (0..p)
        .map(|j| {
            let v = ata[(j, j)];
            if v > 0.0 {
                1.0 / v.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let mut s = ata.clone();
    for a in 0..p {
        for b in 0..p {
            s[(a, b)] *= d[a] * d[b];
        }
    }
    let svd = s.svd(true, true);
    let smax = svd.singular_values.max();
    if !smax.is_finite() {
        return None;
    }
    let tol = smax * 1e-10;
    let pinv = svd.pseudo_inverse(tol).ok()?;
    let mut cov = pinv;
    for a in 0..p {
        for b in 0..p {
            cov[(a, b)] *= d[a] * d[b];
        }
    }
    let coef = &cov * aty;
    if coef.iter().any(|c| !c.is_finite()) {
        return None;
    }
    Some(LinearFit {
        coef: coef.iter().copied().collect(),
        cov_unscaled: cov,
    })
}

/// Result of a bounded Levenberg-Marquardt run.
#[derive(Clone, Debug)]
pub struct LmResult {
    /// Parameters at the optimum.
    pub x: Vec<f64>,
    /// Sum of squared residuals there.
    pub cost: f64,
    /// Jacobian at the optimum (rows = residuals), for covariances.
    pub jacobian: DMatrix<f64>,
    /// Iterations used.
    pub iterations: usize,
    /// Whether the fit stopped because no step improved it any more; `false` when it
    /// stopped on its iteration limit still improving.
    pub converged: bool,
}

/// Why a fit failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LmError {
    /// The model could not be evaluated at the starting point.
    #[error("the model cannot be evaluated at the starting point (parameters {0:?})")]
    BadStart(Vec<f64>),
}

/// Minimise `|r(x)|^2` with `lo <= x <= hi` (bounds by projection of every step).
/// `r` returns `None` where the model is undefined (e.g. slack cable); such steps are
/// rejected like uphill steps.
pub fn levenberg_marquardt<F>(
    mut r: F,
    x0: &[f64],
    lo: &[f64],
    hi: &[f64],
    max_iter: usize,
) -> Result<LmResult, LmError>
where
    F: FnMut(&[f64]) -> Option<Vec<f64>>,
{
    let n = x0.len();
    let clamp = |x: &mut [f64]| {
        for i in 0..n {
            x[i] = x[i].clamp(lo[i], hi[i]);
        }
    };
    let mut x = x0.to_vec();
    clamp(&mut x);
    let ok = |v: &Vec<f64>| v.iter().all(|e| e.is_finite());
    let mut res = r(&x)
        .filter(ok)
        .ok_or_else(|| LmError::BadStart(x.clone()))?;
    let mut cost: f64 = res.iter().map(|e| e * e).sum();
    let jac = |r: &mut F, x: &[f64], res: &[f64]| -> DMatrix<f64> {
        let m = res.len();
        let mut j = DMatrix::<f64>::zeros(m, n);
        for k in 0..n {
            let span = hi[k] - lo[k];
            let mut h = 1e-5 * span.max(x[k].abs() * 1e-3).max(1e-12);
            if x[k] + h > hi[k] {
                h = -h;
            }
            let mut xp = x.to_vec();
            xp[k] += h;
            if let Some(rp) = r(&xp).filter(ok) {
                for i in 0..m {
                    j[(i, k)] = (rp[i] - res[i]) / h;
                }
            }
        }
        j
    };
    let mut lambda = 1e-3;
    let mut j = jac(&mut r, &x, &res);
    let mut iterations = 0;
    let mut converged = false;
    while iterations < max_iter {
        iterations += 1;
        let jt = j.transpose();
        let jtj = &jt * &j;
        let g = &jt * DVector::from_column_slice(&res);
        let mut improved = false;
        for _ in 0..12 {
            let mut a = jtj.clone();
            for k in 0..n {
                a[(k, k)] += lambda * jtj[(k, k)].max(1e-30);
            }
            let Some(step) = a.clone().cholesky().map(|c| c.solve(&(-&g))) else {
                lambda *= 10.0;
                continue;
            };
            let mut xn: Vec<f64> = (0..n).map(|k| x[k] + step[k]).collect();
            clamp(&mut xn);
            if let Some(rn) = r(&xn).filter(ok) {
                let cn: f64 = rn.iter().map(|e| e * e).sum();
                if cn < cost {
                    let rel = (cost - cn) / cost.max(1e-300);
                    let moved = (0..n).any(|k| (xn[k] - x[k]).abs() > 1e-9 * (hi[k] - lo[k]));
                    x = xn;
                    res = rn;
                    cost = cn;
                    lambda = (lambda * 0.3).max(1e-9);
                    improved = rel > 1e-10 && moved;
                    break;
                }
            }
            lambda *= 10.0;
        }
        if !improved {
            converged = true;
            break;
        }
        j = jac(&mut r, &x, &res);
    }
    Ok(LmResult {
        x,
        cost,
        jacobian: j,
        iterations,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `2 exp(-0.7 t)` fitted from `(1, 0.1)` within bounds, at most `max_iter` iterations.
    fn fit_exponential(max_iter: usize) -> LmResult {
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (-0.7 * t).exp()).collect();
        levenberg_marquardt(
            |p| {
                Some(
                    t.iter()
                        .zip(&y)
                        .map(|(t, y)| p[0] * (-p[1] * t).exp() - y)
                        .collect(),
                )
            },
            &[1.0, 0.1],
            &[0.0, 0.0],
            &[10.0, 5.0],
            max_iter,
        )
        .unwrap()
    }

    #[test]
    fn fits_exponential_within_bounds() {
        let fit = fit_exponential(100);
        assert!((fit.x[0] - 2.0).abs() < 1e-6 && (fit.x[1] - 0.7).abs() < 1e-6);
        assert!(fit.converged && fit.iterations < 100, "{}", fit.iterations);
    }

    /// A fit cut short by its iteration limit says so: it is not reported as converged.
    #[test]
    fn a_fit_on_its_iteration_limit_is_not_converged() {
        let fit = fit_exponential(2);
        assert_eq!(fit.iterations, 2);
        assert!(!fit.converged);
    }

    #[test]
    fn linear_handles_collinear_columns() {
        let a: Vec<f64> = (0..10).map(|i| i as f64).collect();
        let y: Vec<f64> = a.iter().map(|a| 3.0 * a).collect();
        let mask = vec![true; 10];
        let fit = linear_lsq(&[&a, &a], &y, &mask).unwrap();
        assert!((fit.coef[0] + fit.coef[1] - 3.0).abs() < 1e-9);
    }
}
