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

/// Longest batch, as a share of the longest stretch of fitted rows: a residual correlated
/// over most of a log leaves too few batches to estimate anything, and its `+-` is then a
/// lower bound.
pub const RUNS_MAX_BATCH_SHARE: f64 = 0.25;

/// Stretches shorter than this many rows are left out of the correlation time (their
/// autocovariance at any useful lag is mostly edge); their scores still count.
pub const RUNS_MIN_STRETCH: usize = 32;

/// Longest lag, samples, the correlation time is summed to: beyond it a residual that
/// wanders like a random walk keeps raising the sum without end, and the covariance is
/// said to understate ([`Runs::batch_capped`]).
pub const RUNS_MAX_LAG: usize = 4096;

/// Rows the autocovariance is estimated on at most (each stretch's first share), so that
/// hours of logs cost seconds, not hours: 200 000 rows give the correlation time to a
/// fraction of a per cent.
pub const RUNS_MAX_ROWS: usize = 200_000;

/// How a fit's residual comes in runs, and the covariance that holds for it.
#[derive(Clone, Debug)]
pub struct Runs {
    /// Covariance robust to a residual correlated in time (the sandwich `(J^T J)^-1 S
    /// (J^T J)^-1`, `S` the long-run covariance of the scores `J_t r_t` by overlapping batch
    /// means within each stretch of fitted rows), in the parameters' own units.
    pub cov: DMatrix<f64>,
    /// Integrated correlation time of the residual, samples (1 for a white residual; Sokal's
    /// self-consistent window, pooled over the stretches).
    pub correlation_samples: f64,
    /// Batch length used, samples.
    pub batch_samples: usize,
    /// Whether the residual is correlated over more than the batch or the lag window can
    /// hold (a batch cut to [`RUNS_MAX_BATCH_SHARE`] of the longest stretch below five
    /// correlation times, or a window that reached [`RUNS_MAX_LAG`] or a quarter of the
    /// longest stretch before closing), so the covariance still understates what the runs
    /// do.
    pub batch_capped: bool,
    /// Covariance from the scatter of the logs' summed scores ([`between_logs`]), in the
    /// parameters' own units, when at least [`BETWEEN_LOGS_MIN`] logs have fitted rows.
    pub between_logs: Option<DMatrix<f64>>,
    /// Logs with fitted rows that [`Runs::between_logs`] was formed over (0 when it was
    /// not).
    pub logs: usize,
}

/// Integrated correlation time `1 + 2 sum rho_l` of `runs` (each a stretch of residual in
/// time order; those under [`RUNS_MIN_STRETCH`] rows left out), its autocovariance pooled
/// over them, summed to the first lag `M` with `M >= 5 tau(M)` (Sokal's window). Returns
/// the time, samples, and whether the window had to stop before closing, at [`RUNS_MAX_LAG`]
/// or a quarter of the longest stretch.
pub fn correlation_time(runs: &[&[f64]]) -> (f64, bool) {
    let usable: Vec<&[f64]> = runs
        .iter()
        .copied()
        .filter(|r| r.len() >= RUNS_MIN_STRETCH)
        .collect();
    let total: usize = usable.iter().map(|r| r.len()).sum();
    if total == 0 {
        return (1.0, false);
    }
    // Beyond RUNS_MAX_ROWS, each stretch's first share.
    let share = (RUNS_MAX_ROWS as f64 / total as f64).min(1.0);
    let centred: Vec<Vec<f64>> = usable
        .iter()
        .map(|r| {
            let n = ((r.len() as f64 * share).ceil() as usize).clamp(2, r.len());
            let r = &r[..n];
            let m = r.iter().sum::<f64>() / n as f64;
            r.iter().map(|v| v - m).collect()
        })
        .collect();
    let used: usize = centred.iter().map(|r| r.len()).sum();
    let longest = centred.iter().map(|r| r.len()).max().unwrap_or(0);
    let gamma = |l: usize| -> f64 {
        centred
            .iter()
            .filter(|r| r.len() > l)
            .map(|r| r.iter().zip(&r[l..]).map(|(a, b)| a * b).sum::<f64>())
            .sum::<f64>()
            / used as f64
    };
    let g0 = gamma(0);
    if !(g0 > 0.0 && g0.is_finite()) {
        return (1.0, false);
    }
    let max_lag = (longest / 4).min(RUNS_MAX_LAG);
    let mut tau = 1.0;
    for l in 1..=max_lag {
        tau += 2.0 * gamma(l) / g0;
        if l as f64 >= 5.0 * tau {
            return (tau.max(1.0), false);
        }
    }
    (tau.max(1.0), max_lag >= 1)
}

/// The covariance of a fit whose residual `resid` comes in runs: `j`'s rows and `resid`
/// in time order, `stretches` the row ranges of each stretch of consecutive fitted rows
/// (no batch spans two: a log's end, a cut or an excluded segment separates them). A
/// stretch shorter than the batch counts as one batch of its own length. `None` when there
/// are no rows.
pub fn long_run(
    j: &DMatrix<f64>,
    resid: &[f64],
    stretches: &[std::ops::Range<usize>],
    dof_scale: f64,
) -> Option<Runs> {
    let np = j.ncols();
    let pieces: Vec<&[f64]> = stretches.iter().map(|r| &resid[r.clone()]).collect();
    let (tau, window_cut) = correlation_time(&pieces);
    let longest = stretches.iter().map(|r| r.len()).max().filter(|n| *n > 0)?;
    let cap = ((RUNS_MAX_BATCH_SHARE * longest as f64).floor() as usize).max(1);
    let want = (RUNS_BATCH_TAUS * tau).ceil().max(1.0) as usize;
    let b = want.min(cap);
    // A white residual needs batches of one row: the batch is cut short of what the runs
    // need only when it is under five correlation times beyond the first row.
    let needed = (RUNS_BATCH_TAUS * (tau - 1.0)).ceil().max(0.0) as usize + 1;
    let scaled = Scaled::new(j);
    let (inv, _) = scaled.pseudo_inverse();
    let score = |row: usize, k: usize| scaled.js[(row, k)] * resid[row];
    // Overlapping batch means: S = sum over windows of (sum of b scores)(...)^T / b,
    // scaled by n / (windows b) for the windows a stretch's ends and the stride leave out.
    // Windows start every eighth of a batch: nearly all of full overlap's precision at an
    // eighth of its cost.
    let stride = (b / 8).max(1);
    let mut s = DMatrix::<f64>::zeros(np, np);
    let mut d = vec![0.0; np];
    let mut add = |d: &[f64], w: f64| {
        for r in 0..np {
            if d[r] == 0.0 {
                continue;
            }
            for c in 0..np {
                s[(r, c)] += w * d[r] * d[c];
            }
        }
    };
    for range in stretches {
        let n = range.len();
        if n == 0 {
            continue;
        }
        let len = b.min(n);
        for (k, dk) in d.iter_mut().enumerate() {
            *dk = range.clone().take(len).map(|row| score(row, k)).sum();
        }
        let starts = (n - len) / stride + 1;
        let w = n as f64 / (starts as f64 * len as f64);
        for i in 0..starts {
            add(&d, w);
            if i + 1 < starts {
                // Slide the window by `stride` rows: the rows that enter, less those that
                // leave.
                let t = range.start + i * stride;
                for (k, dk) in d.iter_mut().enumerate() {
                    for row in t..t + stride {
                        *dk += score(row + len, k) - score(row, k);
                    }
                }
            }
        }
    }
    let cov = &inv * (s * dof_scale) * &inv;
    Some(Runs {
        cov: scaled.unscale(cov),
        correlation_samples: tau,
        batch_samples: b,
        batch_capped: window_cut || cap < needed,
        between_logs: None,
        logs: 0,
    })
}

/// Fewest logs with fitted rows the scatter between them is taken from: the logs' summed
/// scores sum to zero along every freely fitted direction, so `g` logs give `g - 1`
/// degrees of freedom, and below four of them the spread of a spread is more than a third
/// of itself.
pub const BETWEEN_LOGS_MIN: usize = 5;

/// The covariance that holds when the model's error differs from log to log (a law that
/// misses how the load moves a term, a log's own drift), not only from sample to sample:
/// the sandwich `(J^T J)^-1 S (J^T J)^-1` with `S = g / (g - 1) sum_k s_k s_k^T`, `s_k`
/// the summed scores `J_t r_t` of log `k` over its fitted rows (`logs`, row ranges of `j`
/// and `resid`), `g` the logs with any (Liang and Zeger's covariance clustered by log, with
/// the usual small-sample factor). It is the jackknife that leaves out one log at a time
/// taken to first order, so a parameter that only the differences between logs pin (how a
/// width follows the load, with one load per log) gets a `+-` from how far the logs
/// disagree on it, where the batches of [`long_run`] count every run of every log as a
/// fresh look. To first order it still understates where one log alone reaches what the
/// others do not (its leverage; the refitted jackknife of the leave-one-out shows that),
/// and its rank is at most `g - 1`: beside the others it can only widen. A first-order
/// form that leaves each log out exactly, `(J^T J - J_k^T J_k)^+ J_k^T r_k`, was tried
/// and not kept: where one log alone sees a parameter (the slack, seen only by the
/// lightest load), leaving it out makes the rest nearly singular, and the `+-` ran to
/// hundreds of times a value on its bound. `None` when fewer than [`BETWEEN_LOGS_MIN`]
/// logs have rows.
pub fn between_logs(
    j: &DMatrix<f64>,
    resid: &[f64],
    logs: &[std::ops::Range<usize>],
    dof_scale: f64,
) -> Option<DMatrix<f64>> {
    let groups: Vec<&std::ops::Range<usize>> = logs.iter().filter(|r| !r.is_empty()).collect();
    let g = groups.len();
    if g < BETWEEN_LOGS_MIN {
        return None;
    }
    let scaled = Scaled::new(j);
    let (inv, _) = scaled.pseudo_inverse();
    let np = j.ncols();
    let mut s = DMatrix::<f64>::zeros(np, np);
    for range in groups {
        let rows = scaled.js.rows(range.start, range.len());
        let r = nalgebra::DVector::from_column_slice(&resid[range.start..range.end]);
        let score = rows.transpose() * r;
        s += &score * score.transpose();
    }
    let scale = g as f64 / (g - 1) as f64 * dof_scale;
    let cov = &inv * (s * scale) * &inv;
    Some(scaled.unscale(cov))
}

/// Whether a parameter's value may well be zero without saying anything of how well it is
/// pinned: an encoder zero, a runout's phase, a log's own part of a calibrated term. Its
/// uncertainty against its value is no test (an encoder zero of 8e-8 rad pinned to 1e-7
/// is pinned); the correlation and unseen-direction rules still judge it.
pub fn zero_is_natural(name: &str) -> bool {
    name.starts_with("encoder_zero[") || name.ends_with("_phase") || name.contains("_per_log[")
}

/// Why `p` is not identifiable on its `std` alone, in words: that uncertainty is not finite
/// or exceeds its value (`None` when it is within it, and for a value whose natural size is
/// zero, [`zero_is_natural`], unless it is not finite).
pub fn uncertainty_exceeds_value(p: &ParamEstimate) -> Option<String> {
    (!p.std.is_finite() || (p.std > p.value.abs() && !zero_is_natural(&p.name))).then(|| {
        format!(
            "its uncertainty ({}) exceeds its value",
            crate::compact(p.std)
        )
    })
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
        } else if let Some(why) = uncertainty_exceeds_value(p) {
            why
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
            let (tau, cut) = correlation_time(&[&e]);
            assert!(!cut);
            let exact = (1.0 + rho) / (1.0 - rho);
            assert!(
                (tau / exact - 1.0).abs() < 0.06,
                "rho {rho}: tau {tau}, closed form {exact}"
            );
        }
        // Split into logs, the same series gives the same time: no lag spans two logs.
        let e = ar1(200_000, 0.8, 5);
        let parts: Vec<&[f64]> = e.chunks(20_000).collect();
        let (tau, _) = correlation_time(&parts);
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

    /// A stretch of a few rows (what an excluded segment leaves between two others) takes
    /// no part in the correlation time and counts as one batch: it does not switch the
    /// runs off for the long stretches beside it.
    #[test]
    fn a_short_stretch_does_not_switch_the_runs_off() {
        let n = 6000;
        let e = ar1(n, 0.9, 7);
        let j = DMatrix::from_element(n, 1, 1.0);
        let long = [0..2997, 2997..3003, 3003..n];
        let alone = [0..2997, 3003..n];
        let a = long_run(&j, &e, &long, 1.0).expect("runs");
        let b = long_run(&j, &e, &alone, 1.0).expect("runs");
        assert!((a.correlation_samples / 19.0 - 1.0).abs() < 0.25, "{a:?}");
        assert_eq!(a.correlation_samples, b.correlation_samples);
        assert!(!a.batch_capped, "{a:?}");
        let rel = (a.cov[(0, 0)] / b.cov[(0, 0)]).sqrt();
        assert!((rel - 1.0).abs() < 0.02, "{rel}");
    }

    /// A residual that wanders like a random walk has no correlation time: the window
    /// stops at its limit and the covariance says it understates.
    #[test]
    fn a_wandering_residual_is_said_to_understate() {
        let n = 20_000;
        let mut x = 0.0;
        let steps = ar1(n, 0.0, 8);
        let walk: Vec<f64> = steps
            .iter()
            .map(|w| {
                x += w;
                x
            })
            .collect();
        let j = DMatrix::from_element(n, 1, 1.0);
        let r = long_run(&j, &walk, std::slice::from_ref(&(0..n)), 1.0).expect("runs");
        assert!(r.batch_capped, "{r:?}");
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

    /// Eleven logs, each with its own encoder zero, share a slope on a regressor that is
    /// white in time and scaled by the log's load; each log's true slope is the shared one
    /// plus its own deviation. Within a log the residual is white, so neither the white nor
    /// the runs `+-` can see the deviations; the scatter between the logs does, and gives
    /// the refits' actual scatter.
    fn logs_that_disagree(deviation: f64, draws: u64) -> ([f64; 3], f64) {
        let (g, n) = (11usize, 2000usize);
        let loads: Vec<f64> = (0..g).map(|k| 0.5 + k as f64 / (g - 1) as f64).collect();
        let logs: Vec<std::ops::Range<usize>> = (0..g).map(|k| k * n..(k + 1) * n).collect();
        let (mut fits, mut var) = (Vec::new(), [0.0; 3]);
        for seed in 0..draws {
            let noise = ar1(g * n, 0.0, 3000 + seed);
            let regressor = ar1(g * n, 0.0, 7000 + seed);
            let own = ar1(g, 0.0, 11_000 + seed);
            let j = DMatrix::from_fn(g * n, g + 1, |r, c| {
                if c < g {
                    f64::from(u8::from(r / n == c))
                } else {
                    loads[r / n] * regressor[r]
                }
            });
            let y: Vec<f64> = (0..g * n)
                .map(|r| {
                    0.1 * (r / n) as f64 + (2.0 + deviation * own[r / n]) * j[(r, g)] + noise[r]
                })
                .collect();
            let x = ols(&j, &y);
            let resid: Vec<f64> = (0..g * n)
                .map(|r| y[r] - x[r / n] - x[g] * j[(r, g)])
                .collect();
            let dof = (g * n - g - 1) as f64;
            let s2 = resid.iter().map(|v| v * v).sum::<f64>() / dof;
            let scale = (g * n) as f64 / dof;
            let white = analyse(&j, s2);
            let runs = long_run(&j, &resid, &logs, scale).expect("runs");
            let between = between_logs(&j, &resid, &logs, scale).expect("eleven logs");
            for (v, c) in var.iter_mut().zip([&white.cov, &runs.cov, &between]) {
                *v += c[(g, g)] / draws as f64;
            }
            fits.push(x[g]);
        }
        let m = fits.iter().sum::<f64>() / draws as f64;
        let scatter = fits.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (draws - 1) as f64;
        (var, scatter)
    }

    #[test]
    fn the_scatter_between_logs_gives_the_refits_scatter_when_the_logs_disagree() {
        let ([white, runs, between], scatter) = logs_that_disagree(0.05, 300);
        let r = |v: f64| (v / scatter).sqrt();
        assert!(
            (0.8..1.2).contains(&r(between)),
            "between +- {} of the scatter",
            r(between)
        );
        assert!(r(runs) < 0.5, "runs +- {}", r(runs));
        assert!(r(white) < 0.5, "white +- {}", r(white));
    }

    #[test]
    fn logs_that_agree_keep_their_white_uncertainty() {
        let ([white, _, between], scatter) = logs_that_disagree(0.0, 200);
        let r = (between / white).sqrt();
        assert!((0.85..1.15).contains(&r), "between +- {r} of the white one");
        let w = (white / scatter).sqrt();
        assert!((0.85..1.15).contains(&w), "white +- {w} of the scatter");
    }

    #[test]
    fn too_few_logs_give_no_scatter_between_them() {
        let j = DMatrix::from_element(40, 1, 1.0);
        let e = ar1(40, 0.0, 5);
        let four: Vec<std::ops::Range<usize>> = (0..4).map(|k| k * 10..(k + 1) * 10).collect();
        assert!(between_logs(&j, &e, &four, 1.0).is_none());
        let five: Vec<std::ops::Range<usize>> = (0..5).map(|k| k * 8..(k + 1) * 8).collect();
        assert!(between_logs(&j, &e, &five, 1.0).is_some());
        // An empty log is no log.
        let mut padded = four.clone();
        padded.push(40..40);
        assert!(between_logs(&j, &e, &padded, 1.0).is_none());
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
