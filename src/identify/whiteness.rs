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

    /// Exact upper tail of the chi-square distribution with an even number `k` of degrees
    /// of freedom: `P(X > x) = exp(-x/2) sum_{j < k/2} (x/2)^j / j!`.
    fn exact_tail_even(x: f64, k: usize) -> f64 {
        assert!(k.is_multiple_of(2));
        let mut term = 1.0;
        let mut sum = 1.0;
        for j in 1..k / 2 {
            term *= x / 2.0 / j as f64;
            sum += term;
        }
        (-x / 2.0).exp() * sum
    }

    #[test]
    fn chi_square_tail_matches_tables() {
        // Table values: chi-square 95th and 99.9th percentiles for 20 degrees of freedom;
        // their exact tails (closed form above) are 0.0500052 and 0.000999921. The
        // approximation gives 0.049900 (0.2 % off) and 0.0010392 (3.9 % off).
        assert!((exact_tail_even(31.410, 20) - 0.05).abs() < 1e-5);
        assert!((exact_tail_even(45.315, 20) - 0.001).abs() < 1e-7);
        assert!((chi_square_tail(31.410, 20.0) / 0.05 - 1.0).abs() < 0.005);
        assert!((chi_square_tail(45.315, 20.0) / 0.001 - 1.0).abs() < 0.05);
    }

    /// Wilson-Hilferty against the exact tail for every even k from 10 to 60 and every
    /// x on a 0.05 grid while the tail is at least 0.001. Measured worst relative errors
    /// (all at k = 10): 0.56 % for tails >= 0.05, 1.02 % for >= 0.01, 6.5 % for >= 0.001;
    /// worst absolute error 0.0013. The bounds are those with a little room.
    #[test]
    fn chi_square_tail_is_good_to_a_few_percent_for_ten_or_more_degrees() {
        let mut worst = [0.0f64; 3];
        let mut worst_abs = 0.0f64;
        for k in (10..=60).step_by(2) {
            let mut x = 0.05;
            loop {
                let exact = exact_tail_even(x, k);
                if exact < 0.001 {
                    break;
                }
                let approx = chi_square_tail(x, k as f64);
                let rel = (approx / exact - 1.0).abs();
                for (w, floor) in worst.iter_mut().zip([0.05, 0.01, 0.001]) {
                    if exact >= floor {
                        *w = w.max(rel);
                    }
                }
                worst_abs = worst_abs.max((approx - exact).abs());
                x += 0.05;
            }
        }
        assert!(worst[0] < 0.007, "{worst:?}");
        assert!(worst[1] < 0.012, "{worst:?}");
        assert!(worst[2] < 0.07, "{worst:?}");
        assert!(worst_abs < 0.0015, "{worst_abs}");
    }

    /// On white noise the test rejects at its level: over 4000 independent residuals of
    /// 1000 samples, 20 lags, the share with p < 0.05 is 0.05 within 3.5 binomial standard
    /// deviations (sqrt(0.05 * 0.95 / 4000) = 0.0034, so 0.038 to 0.062; Ljung-Box itself
    /// runs about 0.003 over its level at this length, which the window holds), and the mean
    /// Q is its 20 degrees of freedom within 3 % (the standard error of the mean is
    /// sqrt(2 * 20 / 4000) = 0.1, 0.5 %).
    #[test]
    fn white_noise_is_rejected_at_the_test_level() {
        const RUNS: usize = 4000;
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let mut rejected = 0;
        let mut q_sum = 0.0;
        for _ in 0..RUNS {
            let noise: Vec<f64> = (0..1000).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let w = ljung_box(&noise, 20, 1000).unwrap();
            assert_eq!((w.samples, w.lags), (1000, 20));
            rejected += usize::from(w.p_value < 0.05);
            q_sum += w.q;
        }
        let rate = rejected as f64 / RUNS as f64;
        let mean_q = q_sum / RUNS as f64;
        println!("rejection rate {rate}, mean Q {mean_q}");
        assert!((rate - 0.05).abs() < 0.012, "rejection rate {rate}");
        assert!((mean_q / 20.0 - 1.0).abs() < 0.03, "mean Q {mean_q}");
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
