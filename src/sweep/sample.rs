//! Deterministic draws for random and Latin-hypercube sweeps.
//!
//! Every draw is a function of `(master seed, case index, parameter index)` only, so a case
//! gets the same values whichever thread or shard runs it. Latin-hypercube strata are
//! permutations drawn from the master seed alone.

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::stats::{normal_cdf, normal_quantile};

/// SplitMix64 finaliser: spreads nearby inputs (case 0, 1, 2...) over unrelated seeds.
fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Seed of the stream of `(seed, a, b)`.
pub fn mix(seed: u64, a: u64, b: u64) -> u64 {
    splitmix(splitmix(splitmix(seed) ^ a) ^ b.rotate_left(32))
}

/// Tag that keeps the permutation streams apart from the per-case streams.
const PERMUTATION_STREAM: u64 = u64::MAX;

/// Uniform draw in the open interval (0, 1) for one case and parameter.
pub fn case_uniform(seed: u64, case: usize, parameter: usize) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(mix(seed, case as u64, parameter as u64));
    rng.sample(rand::distributions::Open01)
}

/// Stratum of every case for one parameter of a Latin hypercube of `n` cases: a random
/// permutation of `0..n` drawn from the master seed.
pub fn lhs_strata(seed: u64, parameter: usize, n: usize) -> Vec<u32> {
    let mut rng = ChaCha8Rng::seed_from_u64(mix(seed, PERMUTATION_STREAM, parameter as u64));
    let mut perm: Vec<u32> = (0..n as u32).collect();
    perm.shuffle(&mut rng);
    perm
}

/// A distribution ready to draw from, in the unit of its key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Draw {
    /// Uniform on `[lo, hi]`.
    Uniform {
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// Normal.
    Normal {
        /// Mean.
        mean: f64,
        /// Standard deviation (> 0).
        std: f64,
    },
    /// Normal restricted to `[lo, hi]`.
    TruncatedNormal {
        /// Mean of the parent normal.
        mean: f64,
        /// Standard deviation of the parent normal (> 0).
        std: f64,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
}

impl Draw {
    /// Value at cumulative probability `u` in (0, 1). Inverse-CDF sampling serves both
    /// plain random draws and Latin-hypercube strata, and truncation needs no rejection
    /// loop (so the cost of a draw does not depend on how tight the bounds are).
    pub fn quantile(&self, u: f64) -> f64 {
        match *self {
            Draw::Uniform { lo, hi } => lo + (hi - lo) * u,
            Draw::Normal { mean, std } => mean + std * normal_quantile(u),
            Draw::TruncatedNormal { mean, std, lo, hi } => {
                let (a, b) = (normal_cdf((lo - mean) / std), normal_cdf((hi - mean) / std));
                let x = if b > a {
                    mean + std * normal_quantile(a + (b - a) * u)
                } else {
                    // Both bounds far in one tail: the mass is at the bound nearer the mean.
                    if (lo - mean).abs() < (hi - mean).abs() {
                        lo
                    } else {
                        hi
                    }
                };
                x.clamp(lo, hi)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truncated_normal_stays_within_bounds() {
        let d = Draw::TruncatedNormal {
            mean: 100.0,
            std: 5.0,
            lo: 99.0,
            hi: 130.0,
        };
        for k in 0..5000 {
            let v = d.quantile(case_uniform(11, k, 0));
            assert!((99.0..=130.0).contains(&v), "{v}");
        }
        // Bounds deep in one tail still give values inside.
        let far = Draw::TruncatedNormal {
            mean: 0.0,
            std: 1.0,
            lo: 40.0,
            hi: 41.0,
        };
        let v = far.quantile(0.5);
        assert!((40.0..=41.0).contains(&v), "{v}");
    }

    #[test]
    fn normal_draws_have_the_declared_moments() {
        let d = Draw::Normal {
            mean: 100.0,
            std: 5.0,
        };
        let n = 20_000;
        let xs: Vec<f64> = (0..n).map(|k| d.quantile(case_uniform(5, k, 2))).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        // Standard error of the mean is 5/sqrt(20000) = 0.035; of the std about 0.025.
        assert!((mean - 100.0).abs() < 0.15, "{mean}");
        assert!((var.sqrt() - 5.0).abs() < 0.1, "{}", var.sqrt());
    }

    #[test]
    fn streams_are_fixed_by_seed_case_and_parameter() {
        assert_eq!(case_uniform(1, 2, 3), case_uniform(1, 2, 3));
        assert_ne!(case_uniform(1, 2, 3), case_uniform(1, 3, 2));
        assert_ne!(case_uniform(1, 2, 3), case_uniform(2, 2, 3));
        assert_eq!(lhs_strata(4, 0, 50), lhs_strata(4, 0, 50));
        assert_ne!(lhs_strata(4, 0, 50), lhs_strata(4, 1, 50));
    }
}
