//! How well a calibration pins each parameter: the covariance `s^2 (J^T J)^-1` computed on
//! a column-scaled Jacobian, so a parameter whose column is tiny in absolute terms (a
//! load-scaled weight multiplying `|M|^8`) keeps its own uncertainty instead of being
//! dropped as numerically null, and the directions the data truly cannot see are named
//! rather than reported with a `+-` of 1e-10. Beside it, [`long_run`] gives the covariance
//! that holds when the residual comes in runs, as a real log's does: there the white
//! figure understates the spread of a refit several times over (about 10x on the shipped
//! da Vinci logs).

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
    let scaled = Scaled::new(j);
    let (inv, unseen) = scaled.pseudo_inverse();
    Analysis {
        cov: scaled.unscale(inv * s2),
        unseen,
    }
}

/// A Jacobian with its columns scaled to unit norm, and the norms to undo it.
struct Scaled {
    js: DMatrix<f64>,
    norms: Vec<f64>,
}

impl Scaled {
    fn new(j: &DMatrix<f64>) -> Self {
        let np = j.ncols();
        let norms: Vec<f64> = (0..np).map(|k| j.column(k).norm()).collect();
        let mut js = j.clone();
        for (k, n) in norms.iter().enumerate() {
            if *n > 0.0 && n.is_finite() {
                js.column_mut(k).scale_mut(1.0 / n);
            }
        }
        Self { js, norms }
    }

    /// `(Js^T Js)^+` over the directions the data sees, and which parameters take part in
    /// one it does not.
    fn pseudo_inverse(&self) -> (DMatrix<f64>, Vec<bool>) {
        let (np, norms, js) = (self.norms.len(), &self.norms, &self.js);
        let a = js.transpose() * js;
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
        (inv, unseen)
    }

    /// A covariance in the scaled parameters back in the parameters' own units.
    fn unscale(&self, mut cov: DMatrix<f64>) -> DMatrix<f64> {
        let np = self.norms.len();
        for r in 0..np {
            for c in 0..np {
                let d = self.norms[r] * self.norms[c];
                cov[(r, c)] = if d > 0.0 && d.is_finite() {
                    cov[(r, c)] / d
                } else {
                    0.0
                };
            }
        }
        cov
    }
}

/// Batches, in multiples of the residual's integrated correlation time, over which
/// [`long_run`] sums the fit's scores. Bartlett's kernel, which overlapping batch means
/// approximate, underestimates a long-run variance by about `tau / (2 b)` at a batch of
/// `b` samples (10 % at five correlation times) and scatters by about `sqrt(4 b / 3 n)` of
/// itself; five keeps the bias at a tenth while a 60 s log at 200 Hz with a correlation
/// time of 20 samples still holds 120 batches.
pub const RUNS_BATCH_TAUS: f64 = 5.0;

/// Longest batch, as a share of the shortest log: a residual correlated over most of a log
/// leaves too few batches to estimate anything, and its `+-` is then a lower bound.
pub const RUNS_MAX_BATCH_SHARE: f64 = 0.25;

/// How a fit's residual comes in runs, and the covariance that holds for it.
#[derive(Clone, Debug)]
pub struct Runs {
    /// Covariance robust to a residual correlated in time (the sandwich `(J^T J)^-1 S
    /// (J^T J)^-1`, `S` the long-run covariance of the scores `J_t r_t` by overlapping batch
    /// means within each log), in the parameters' own units.
    pub cov: DMatrix<f64>,
    /// Integrated correlation time of the residual, samples (1 for a white residual; Sokal's
    /// self-consistent window, pooled over the logs).
    pub correlation_samples: f64,
    /// Batch length used, samples.
    pub batch_samples: usize,
    /// Whether the batch was cut to [`RUNS_MAX_BATCH_SHARE`] of the shortest log, so the
    /// covariance still understates what the runs do.
    pub batch_capped: bool,
}

/// Integrated correlation time `1 + 2 sum rho_l` of `runs` (each a log's residual, in
/// time order), its autocovariance pooled over them, summed to the first lag `M` with `M
/// >= 5 tau(M)` (Sokal's window) and never past a quarter of the shortest run.
pub fn correlation_time(runs: &[&[f64]]) -> f64 {
    let shortest = runs.iter().map(|r| r.len()).min().unwrap_or(0);
    let total: usize = runs.iter().map(|r| r.len()).sum();
    if shortest < 8 || total == 0 {
        return 1.0;
    }
    let centred: Vec<Vec<f64>> = runs
        .iter()
        .map(|r| {
            let m = r.iter().sum::<f64>() / r.len() as f64;
            r.iter().map(|v| v - m).collect()
        })
        .collect();
    let gamma = |l: usize| -> f64 {
        centred
            .iter()
            .map(|r| r.iter().zip(&r[l..]).map(|(a, b)| a * b).sum::<f64>())
            .sum::<f64>()
            / total as f64
    };
    let g0 = gamma(0);
    if !(g0 > 0.0 && g0.is_finite()) {
        return 1.0;
    }
    let mut tau = 1.0;
    for l in 1..shortest / 4 {
        tau += 2.0 * gamma(l) / g0;
        if l as f64 >= 5.0 * tau {
            break;
        }
    }
    tau.max(1.0)
}

/// The covariance of a fit whose residual `resid` comes in runs: `j`'s rows and `resid`
/// in time order, `logs` the row ranges of each log (no batch spans two). `None` when no
/// log is long enough to hold a batch.
pub fn long_run(
    j: &DMatrix<f64>,
    resid: &[f64],
    logs: &[std::ops::Range<usize>],
    dof_scale: f64,
) -> Option<Runs> {
    let np = j.ncols();
    let pieces: Vec<&[f64]> = logs.iter().map(|r| &resid[r.clone()]).collect();
    let tau = correlation_time(&pieces);
    let shortest = logs.iter().map(|r| r.len()).min()?;
    let cap = ((RUNS_MAX_BATCH_SHARE * shortest as f64).floor() as usize).max(1);
    let want = (RUNS_BATCH_TAUS * tau).ceil().max(1.0) as usize;
    let b = want.min(cap);
    let scaled = Scaled::new(j);
    let (inv, _) = scaled.pseudo_inverse();
    // Overlapping batch means: S = sum over windows of (sum of b scores)(...)^T / b,
    // scaled by n / (n - b + 1) for the windows a log's ends leave out.
    let mut s = DMatrix::<f64>::zeros(np, np);
    let mut cum = vec![0.0; np];
    let mut hist: Vec<Vec<f64>> = Vec::new();
    for range in logs {
        let n = range.len();
        if n < b {
            continue;
        }
        hist.clear();
        hist.push(vec![0.0; np]);
        cum.iter_mut().for_each(|c| *c = 0.0);
        for row in range.clone() {
            for (k, c) in cum.iter_mut().enumerate() {
                *c += scaled.js[(row, k)] * resid[row];
            }
            hist.push(cum.clone());
        }
        let windows = n - b + 1;
        let w = n as f64 / (windows as f64 * b as f64);
        let mut d = vec![0.0; np];
        for t in 0..windows {
            for (k, dk) in d.iter_mut().enumerate() {
                *dk = hist[t + b][k] - hist[t][k];
            }
            for r in 0..np {
                if d[r] == 0.0 {
                    continue;
                }
                for c in 0..np {
                    s[(r, c)] += w * d[r] * d[c];
                }
            }
        }
    }
    let cov = &inv * (s * dof_scale) * &inv;
    Some(Runs {
        cov: scaled.unscale(cov),
        correlation_samples: tau,
        batch_samples: b,
        batch_capped: want > cap,
    })
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
mod runs_tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    /// A first-order autoregression `e_t = rho e_(t-1) + w_t`, started in its stationary
    /// spread, innovations of unit variance.
    fn ar1(n: usize, rho: f64, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut e: f64 = StandardNormal.sample(&mut rng);
        e /= (1.0 - rho * rho).sqrt();
        (0..n)
            .map(|_| {
                let w: f64 = StandardNormal.sample(&mut rng);
                e = rho * e + w;
                e
            })
            .collect()
    }

    /// Ordinary least squares of `y` on the columns of `j`.
    fn ols(j: &DMatrix<f64>, y: &[f64]) -> Vec<f64> {
        let a = j.transpose() * j;
        let b = j.transpose() * nalgebra::DVector::from_column_slice(y);
        a.lu().solve(&b).expect("regular").iter().copied().collect()
    }

    #[test]
    fn the_correlation_time_of_an_autoregression_is_its_closed_form() {
        for (rho, seed) in [(0.0, 1), (0.5, 2), (0.8, 3), (0.95, 4)] {
            let e = ar1(200_000, rho, seed);
            let tau = correlation_time(&[&e]);
            let exact = (1.0 + rho) / (1.0 - rho);
            assert!(
                (tau / exact - 1.0).abs() < 0.06,
                "rho {rho}: tau {tau}, closed form {exact}"
            );
        }
        // Split into logs, the same series gives the same time: no lag spans two logs.
        let e = ar1(200_000, 0.8, 5);
        let parts: Vec<&[f64]> = e.chunks(20_000).collect();
        let tau = correlation_time(&parts);
        assert!((tau / 9.0 - 1.0).abs() < 0.06, "{tau}");
    }

    /// An offset and a slow sine fitted to a residual in runs: the runs covariance gives
    /// the scatter of the fitted values over many draws, and the white one does not.
    #[test]
    fn the_runs_covariance_is_the_scatter_of_refits() {
        let (n, rho, draws) = (4000, 0.9, 300);
        let j = DMatrix::from_fn(n, 2, |r, c| match c {
            0 => 1.0,
            _ => (std::f64::consts::TAU * r as f64 / 400.0).sin(),
        });
        let truth = [0.3, -1.2];
        let mut fits = Vec::new();
        let (mut var_runs, mut var_white) = ([0.0; 2], [0.0; 2]);
        for seed in 0..draws {
            let e = ar1(n, rho, 100 + seed);
            let y: Vec<f64> = (0..n)
                .map(|r| truth[0] * j[(r, 0)] + truth[1] * j[(r, 1)] + e[r])
                .collect();
            let x = ols(&j, &y);
            let resid: Vec<f64> = (0..n)
                .map(|r| y[r] - x[0] * j[(r, 0)] - x[1] * j[(r, 1)])
                .collect();
            let s2 = resid.iter().map(|v| v * v).sum::<f64>() / (n - 2) as f64;
            let white = analyse(&j, s2);
            let runs = long_run(
                &j,
                &resid,
                std::slice::from_ref(&(0..n)),
                n as f64 / (n - 2) as f64,
            )
            .expect("runs");
            for k in 0..2 {
                var_runs[k] += runs.cov[(k, k)] / draws as f64;
                var_white[k] += white.cov[(k, k)] / draws as f64;
            }
            fits.push(x);
        }
        // The mean's variance in closed form: the process variance 1 / (1 - rho^2) times
        // its correlation time (1 + rho) / (1 - rho), over n.
        let closed = 1.0 / (1.0 - rho * rho) * (1.0 + rho) / (1.0 - rho) / n as f64;
        for k in 0..2 {
            let m = fits.iter().map(|x| x[k]).sum::<f64>() / draws as f64;
            let scatter = fits.iter().map(|x| (x[k] - m).powi(2)).sum::<f64>() / (draws - 1) as f64;
            let runs_ratio = (var_runs[k] / scatter).sqrt();
            let white_ratio = (var_white[k] / scatter).sqrt();
            assert!(
                (0.8..1.15).contains(&runs_ratio),
                "parameter {k}: runs +- {runs_ratio} of the scatter"
            );
            assert!(white_ratio < 0.4, "parameter {k}: white +- {white_ratio}");
            if k == 0 {
                let c = (scatter / closed).sqrt();
                assert!((0.85..1.15).contains(&c), "scatter {c} of the closed form");
            }
        }
    }

    #[test]
    fn a_white_residual_keeps_its_white_uncertainty() {
        let (n, draws) = (3000, 40);
        // Two logs, each with its own offset, and a shared slope.
        let j = DMatrix::from_fn(2 * n, 3, |r, c| match c {
            0 => f64::from(u8::from(r < n)),
            1 => f64::from(u8::from(r >= n)),
            _ => (r % n) as f64 / n as f64 - 0.5,
        });
        let mut ratio = [0.0; 3];
        for seed in 0..draws {
            let resid = ar1(2 * n, 0.0, 900 + seed);
            let s2 = resid.iter().map(|v| v * v).sum::<f64>() / (2 * n - 3) as f64;
            let white = analyse(&j, s2);
            let runs = long_run(&j, &resid, &[0..n, n..2 * n], 1.0).expect("runs");
            assert!(
                runs.correlation_samples < 1.2,
                "{}",
                runs.correlation_samples
            );
            assert!(!runs.batch_capped);
            for (k, r) in ratio.iter_mut().enumerate() {
                *r += (runs.cov[(k, k)] / white.cov[(k, k)]).sqrt() / draws as f64;
            }
        }
        for r in ratio {
            assert!((0.9..1.1).contains(&r), "{ratio:?}");
        }
    }

    #[test]
    fn a_residual_correlated_over_most_of_a_log_caps_its_batch() {
        let n = 400;
        let j = DMatrix::from_element(n, 1, 1.0);
        let resid: Vec<f64> = (0..n)
            .map(|r| (std::f64::consts::TAU * r as f64 / n as f64).sin())
            .collect();
        let runs = long_run(&j, &resid, std::slice::from_ref(&(0..n)), 1.0).expect("runs");
        assert!(runs.batch_capped, "{runs:?}");
        assert_eq!(runs.batch_samples, 100);
        assert!(long_run(&j, &resid, &[], 1.0).is_none());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(name: &str, value: f64, std: f64) -> ParamEstimate {
        ParamEstimate::new(name, value, std, "1")
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
