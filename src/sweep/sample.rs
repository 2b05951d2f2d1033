//! Deterministic draws for random and Latin-hypercube sweeps.
//!
//! Every draw is a function of `(master seed, case index, parameter index)` only, so a case
//! gets the same values whichever thread or shard runs it. Latin-hypercube strata are
//! permutations drawn from the master seed alone.

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

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

/// Standard normal cumulative distribution function.
pub fn normal_cdf(z: f64) -> f64 {
    0.5 * libm::erfc(-z / std::f64::consts::SQRT_2)
}

/// Standard normal quantile (inverse CDF) for `p` in (0, 1): Acklam's rational
/// approximation (relative error 1.2e-9) polished by one Halley step to full precision.
pub fn normal_quantile(p: f64) -> f64 {
    if p <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    const P_LOW: f64 = 0.02425;
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    let mut x = if p < P_LOW {
        tail((-2.0 * p.ln()).sqrt())
    } else if p <= 1.0 - P_LOW {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    };
    // Halley step on Phi(x) - p; erfc keeps the tails accurate.
    let e = normal_cdf(x) - p;
    let u = e * (2.0 * std::f64::consts::PI).sqrt() * (0.5 * x * x).exp();
    x -= u / (1.0 + 0.5 * x * u);
    x
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
    fn quantile_inverts_cdf() {
        for &p in &[1e-12, 1e-6, 0.01, 0.02425, 0.3, 0.5, 0.8, 0.99, 1.0 - 1e-9] {
            let x = normal_quantile(p);
            let back = normal_cdf(x);
            assert!(
                ((back - p) / p.min(1.0 - p)).abs() < 1e-9,
                "{p}: {x} {back}"
            );
        }
        assert!((normal_quantile(0.975) - 1.959_963_984_540_054).abs() < 1e-12);
    }

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
