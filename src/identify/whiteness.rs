//! Whiteness of a residual: the Ljung-Box portmanteau test.

use serde::Serialize;

/// Ljung-Box test of a residual's first `lags` autocorrelations.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Whiteness {
    /// Samples tested (after thinning).
    pub samples: usize,
    /// Autocorrelation lags summed.
    pub lags: usize,
    /// `Q = n (n + 2) sum_k r_k^2 / (n - k)`.
    pub q: f64,
    /// Probability of a `Q` at least this large for white noise (chi-square with `lags`
    /// degrees of freedom, Wilson-Hilferty approximation). Small: structure remains.
    pub p_value: f64,
}

/// Ljung-Box statistic of `residual` thinned to at most `max_samples` points (every
/// `n/max_samples`-th sample, so that a smooth structure shows at short lags while sample-to-
/// sample quantisation correlation is diluted). `None` for fewer than `4 * lags` samples or a
/// constant residual.
pub fn ljung_box(residual: &[f64], lags: usize, max_samples: usize) -> Option<Whiteness> {
    let stride = residual.len().div_ceil(max_samples.max(1)).max(1);
    let x: Vec<f64> = residual.iter().step_by(stride).copied().collect();
    let n = x.len();
    if lags == 0 || n < 4 * lags {
        return None;
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let var: f64 = x.iter().map(|v| (v - mean).powi(2)).sum();
    if !(var > 0.0 && var.is_finite()) {
        return None;
    }
    let nf = n as f64;
    let q = nf
        * (nf + 2.0)
        * (1..=lags)
            .map(|k| {
                let r: f64 = (k..n)
                    .map(|i| (x[i] - mean) * (x[i - k] - mean))
                    .sum::<f64>()
                    / var;
                r * r / (nf - k as f64)
            })
            .sum::<f64>();
    Some(Whiteness {
        samples: n,
        lags,
        q,
        p_value: chi_square_tail(q, lags as f64),
    })
}

/// Upper tail of the chi-square distribution with `k` degrees of freedom at `x`
/// (Wilson-Hilferty cube-root normal approximation, good to a few percent for k >= 10).
fn chi_square_tail(x: f64, k: f64) -> f64 {
    let h = 2.0 / (9.0 * k);
    let z = ((x / k).cbrt() - (1.0 - h)) / h.sqrt();
    0.5 * libm::erfc(z / std::f64::consts::SQRT_2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn chi_square_tail_matches_tables() {
        // Table values: chi-square 95th and 99.9th percentiles for 20 degrees of freedom.
        assert!((chi_square_tail(31.410, 20.0) - 0.05).abs() < 0.003);
        assert!((chi_square_tail(45.315, 20.0) - 0.001).abs() < 0.0005);
    }

    #[test]
    fn white_noise_passes_and_a_sine_fails() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let noise: Vec<f64> = (0..2000).map(|_| rng.gen_range(-1.0..1.0)).collect();
        let w = ljung_box(&noise, 20, 1000).unwrap();
        assert!(w.p_value > 0.01, "{w:?}");
        let sine: Vec<f64> = (0..2000)
            .map(|i| (i as f64 * 0.05).sin() + 0.1 * noise[i])
            .collect();
        let s = ljung_box(&sine, 20, 1000).unwrap();
        assert!(s.p_value < 1e-6, "{s:?}");
        assert!(ljung_box(&[1.0; 500], 20, 1000).is_none());
    }
}
