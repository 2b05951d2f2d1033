//! How well a calibration pins each parameter: the covariance `s^2 (J^T J)^-1` computed on
//! a column-scaled Jacobian, so a parameter whose column is tiny in absolute terms (a
//! load-scaled weight multiplying `|M|^8`) keeps its own uncertainty instead of being
//! dropped as numerically null, and the directions the data truly cannot see are named
//! rather than reported with a `+-` of 1e-10.

use nalgebra::DMatrix;
use serde::Serialize;

use super::ParamEstimate;

/// Eigenvalue of the column-scaled `J^T J` (unit diagonal) below which a direction counts
/// as unseen by the data, relative to the largest: a condition number of `J` above about
/// 1e6, far past what measurement noise lets a fit resolve.
const NULL_EIGENVALUE: f64 = 1e-12;

/// Correlation above which two parameters trade off so closely that neither is pinned on
/// its own.
pub const MAX_CORRELATION: f64 = 0.99;

/// Covariance of a fit and the parameters the data cannot pin.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// Covariance, in the parameters' own units; zero along unseen directions.
    pub cov: DMatrix<f64>,
    /// Per parameter: whether it takes part in a direction the data does not see (a
    /// column of zeros, or a combination of columns that cancels).
    pub unseen: Vec<bool>,
}

impl Analysis {
    /// Correlation of parameters `i` and `j` (0 when either has no variance).
    pub fn correlation(&self, i: usize, j: usize) -> f64 {
        let d = (self.cov[(i, i)] * self.cov[(j, j)]).sqrt();
        if d > 0.0 && d.is_finite() {
            self.cov[(i, j)] / d
        } else {
            0.0
        }
    }
}

/// Covariance `s2 (J^T J)^-1` from the Jacobian `j` (rows: residuals; columns:
/// parameters) with the columns scaled to unit norm before the inversion.
pub fn analyse(j: &DMatrix<f64>, s2: f64) -> Analysis {
    let np = j.ncols();
    let norms: Vec<f64> = (0..np).map(|k| j.column(k).norm()).collect();
    let mut js = j.clone();
    for (k, n) in norms.iter().enumerate() {
        if *n > 0.0 && n.is_finite() {
            js.column_mut(k).scale_mut(1.0 / n);
        }
    }
    let a = js.transpose() * &js;
    let eig = a.symmetric_eigen();
    let top = eig.eigenvalues.iter().fold(0.0f64, |m, v| m.max(*v));
    let mut inv = DMatrix::<f64>::zeros(np, np);
    let mut unseen: Vec<bool> = norms.iter().map(|n| !(*n > 0.0 && n.is_finite())).collect();
    for (e, lambda) in eig.eigenvalues.iter().enumerate() {
        let v = eig.eigenvectors.column(e);
        if *lambda > NULL_EIGENVALUE * top && top > 0.0 {
            inv += (v * v.transpose()) / *lambda;
        } else {
            for (k, u) in unseen.iter_mut().enumerate() {
                if v[k].abs() > 0.1 {
                    *u = true;
                }
            }
        }
    }
    let mut cov = inv * s2;
    for r in 0..np {
        for c in 0..np {
            let d = norms[r] * norms[c];
            cov[(r, c)] = if d > 0.0 && d.is_finite() {
                cov[(r, c)] / d
            } else {
                0.0
            };
        }
    }
    Analysis { cov, unseen }
}

/// Whether a parameter's value may well be zero without saying anything of how well it is
/// pinned: an encoder zero, a runout's phase, a log's own part of a calibrated term. Its
/// uncertainty against its value is no test (an encoder zero of 8e-8 rad pinned to 1e-7
/// is pinned); the correlation and unseen-direction rules still judge it.
pub fn zero_is_natural(name: &str) -> bool {
    name.starts_with("encoder_zero[") || name.ends_with("_phase") || name.contains("_per_log[")
}

/// A reported parameter the data does not pin, and why.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct NotIdentifiable {
    /// Parameter name, as in the parameter table.
    pub name: String,
    /// Why, in words: its uncertainty exceeds its value, or it trades off with another.
    pub reason: String,
}

/// The parameters of `params` the data cannot pin. `raw` maps a parameter's name to its
/// column in `analysis` where it is one fitted coefficient itself (derived quantities have
/// none and are judged on their uncertainty alone). A value held on a bound at exactly
/// zero is the fit saying the term is not needed, not a parameter it failed to pin.
pub fn not_identifiable(
    params: &[ParamEstimate],
    analysis: &Analysis,
    raw: &[(String, usize)],
) -> Vec<NotIdentifiable> {
    let column = |name: &str| raw.iter().find(|(n, _)| n == name).map(|(_, c)| *c);
    let mut out = Vec::new();
    for p in params {
        if p.value == 0.0 {
            continue;
        }
        let reason = if let Some(c) = column(&p.name).filter(|c| analysis.unseen[*c]) {
            let partners: Vec<&str> = raw
                .iter()
                .filter(|(n, k)| *k != c && analysis.unseen[*k] && *n != p.name)
                .map(|(n, _)| n.as_str())
                .take(3)
                .collect();
            if partners.is_empty() {
                "the logs do not move the residual along it".to_string()
            } else {
                format!(
                    "the logs see it only in a combination with {}",
                    partners.join(", ")
                )
            }
        } else if !p.std.is_finite() || (p.std > p.value.abs() && !zero_is_natural(&p.name)) {
            format!(
                "its uncertainty ({}) exceeds its value",
                crate::compact(p.std)
            )
        } else if let Some((other, r)) = column(&p.name).and_then(|c| {
            raw.iter()
                .filter(|(n, k)| *k != c && *n != p.name)
                .map(|(n, k)| (n, analysis.correlation(c, *k)))
                .filter(|(_, r)| r.abs() > MAX_CORRELATION)
                .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        }) {
            format!("correlation {r:.3} with {other}: the logs pin only their combination")
        } else {
            continue;
        };
        out.push(NotIdentifiable {
            name: p.name.clone(),
            reason,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(name: &str, value: f64, std: f64) -> ParamEstimate {
        ParamEstimate {
            name: name.into(),
            value,
            std,
            unit: "1".into(),
        }
    }

    #[test]
    fn a_tiny_column_keeps_its_own_uncertainty() {
        // Two independent parameters, one column 1e-9 the size of the other: the
        // unscaled inverse drops it; the scaled one gives each its exact variance.
        let n = 50;
        let j = DMatrix::from_fn(n, 2, |r, c| {
            let x = (r as f64 * 0.37).sin();
            if c == 0 {
                x
            } else {
                1e-9 * (r as f64 * 1.91).cos()
            }
        });
        let a = analyse(&j, 1.0);
        let exact = (j.transpose() * &j).try_inverse().unwrap();
        for k in 0..2 {
            let rel = a.cov[(k, k)] / exact[(k, k)] - 1.0;
            assert!(rel.abs() < 1e-6, "parameter {k}: {rel}");
        }
        assert_eq!(a.unseen, vec![false, false]);
    }

    #[test]
    fn a_cancelling_pair_is_unseen_and_named() {
        let n = 40;
        let j = DMatrix::from_fn(n, 3, |r, c| {
            let x = (r as f64 * 0.5).sin();
            match c {
                0 | 1 => x,
                _ => (r as f64 * 0.21).cos(),
            }
        });
        let a = analyse(&j, 1.0);
        assert_eq!(a.unseen, vec![true, true, false]);
        let params = [
            estimate("a", 2.0, 1e-10),
            estimate("b", 3.0, 1e-10),
            estimate("c", 1.0, 0.1),
        ];
        let raw = [("a".into(), 0), ("b".into(), 1), ("c".into(), 2)];
        let said = not_identifiable(&params, &a, &raw);
        assert_eq!(said.len(), 2, "{said:?}");
        assert!(said[0].reason.contains("combination with b"), "{said:?}");
    }

    #[test]
    fn strongly_correlated_or_uncertain_parameters_are_flagged() {
        let n = 60;
        let j = DMatrix::from_fn(n, 3, |r, c| {
            let x = (r as f64 * 0.3).sin();
            let y = (r as f64 * 0.77).cos();
            match c {
                0 => x,
                1 => x + 0.01 * y,
                _ => (r as f64 * 1.9 + 0.4).sin(),
            }
        });
        let a = analyse(&j, 1e-6);
        assert!(a.correlation(0, 1).abs() > MAX_CORRELATION);
        let params = [
            estimate("a", 1.0, a.cov[(0, 0)].sqrt()),
            estimate("b", 1.0, a.cov[(1, 1)].sqrt()),
            estimate("c", 1.0, a.cov[(2, 2)].sqrt()),
            estimate("derived", 1e-3, 2e-3),
            estimate("zero_on_bound", 0.0, 0.2),
            estimate("encoder_zero[0]", 8e-8, 1.1e-7),
        ];
        let raw = [("a".into(), 0), ("b".into(), 1), ("c".into(), 2)];
        let said = not_identifiable(&params, &a, &raw);
        let names: Vec<&str> = said.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["a", "b", "derived"], "{said:?}");
        assert!(said[0].reason.contains("correlation"), "{said:?}");
        assert!(said[2].reason.contains("exceeds its value"), "{said:?}");
    }
}
