//! Encoder resolution read from the levels a quantised angle takes.
//!
//! Sample-to-sample differences measure the encoder step only while the axis creeps; on a
//! scan at constant speed every difference is the travel per sample (tens of steps), and a
//! low percentile of them returns that travel. The set of distinct values the signal
//! visits does not depend on speed: over a record the sampling phase drifts, so the sorted
//! levels sit one step apart, whatever the motion.

/// Encoder step of a quantised angle record, rad; 0 when the record is not on a grid
/// (unquantised or noisy data, or fewer than 10 distinct levels). Typical: 1.57e-3 rad for
/// a 4000-count encoder, 9.6e-5 rad for 2^16 counts.
pub fn encoder_step(v: &[f64]) -> f64 {
    let mut levels: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if levels.len() < 10 {
        return 0.0;
    }
    levels.sort_by(|a, b| a.total_cmp(b));
    let range = levels[levels.len() - 1] - levels[0];
    if range <= 0.0 {
        return 0.0;
    }
    // Values converted from counts carry rounding of the last bits; merge those.
    let tol = 1e-9
        * range
            .max(levels[0].abs())
            .max(levels[levels.len() - 1].abs());
    levels.dedup_by(|a, b| (*a - *b).abs() <= tol);
    if levels.len() < 10 {
        return 0.0;
    }
    let mut gaps: Vec<f64> = levels.windows(2).map(|w| w[1] - w[0]).collect();
    gaps.sort_by(|a, b| a.total_cmp(b));
    // Low percentile, not the minimum, so one pair of nearly equal values left by rounding
    // in a file does not set the grid.
    let q0 = gaps[gaps.len() / 100];
    if q0 <= tol {
        return 0.0;
    }
    // Refine on the gaps of one step (the common case), then require every level spacing to
    // be a multiple of it: continuous data fails this.
    let ones: Vec<f64> = gaps
        .iter()
        .copied()
        .filter(|g| (g / q0).round() == 1.0)
        .collect();
    let q = ones[ones.len() / 2];
    let on_grid = gaps
        .iter()
        .filter(|g| {
            let k = (**g / q).round();
            k >= 1.0 && (**g - k * q).abs() < 0.05 * q
        })
        .count();
    if on_grid as f64 > 0.9 * gaps.len() as f64 {
        q
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::encoder_step;

    fn quantise(x: f64, q: f64) -> f64 {
        (x / q).round() * q
    }

    /// Triangle scan at constant speed, 37.3 steps per sample, turning points between
    /// samples (as on a bench): every sample-to-sample difference is 37 or 38 steps, yet
    /// the levels visited over the passes lie on the one-step grid.
    #[test]
    fn constant_speed_triangle_gives_the_step_not_the_travel() {
        let q = 2.0 * std::f64::consts::PI / 65536.0;
        let per_sample = 37.3 * q;
        let half = 1000.37;
        let v: Vec<f64> = (0..20000)
            .map(|i| {
                let p = (i as f64 / (2.0 * half)).fract() * 2.0 * half;
                let s = if p < half { p } else { 2.0 * half - p };
                quantise(0.1 + s * per_sample, q)
            })
            .collect();
        let est = encoder_step(&v);
        assert!((est / q - 1.0).abs() < 1e-6, "step {est} vs {q}");
        // The 1st percentile of the sample-to-sample differences (the former estimate) is
        // the travel per sample, tens of steps.
        let mut d: Vec<f64> = v
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .filter(|d| *d > 0.0)
            .collect();
        d.sort_by(|a, b| a.total_cmp(b));
        assert!(d[d.len() / 100] > 30.0 * q);
    }

    #[test]
    fn creeping_sine_gives_the_step() {
        let q = 2.0 * std::f64::consts::PI / 4000.0;
        let v: Vec<f64> = (0..20000)
            .map(|i| quantise(0.5 * (i as f64 * 1e-3 * 0.6).sin() - 0.3, q))
            .collect();
        let est = encoder_step(&v);
        assert!((est / q - 1.0).abs() < 1e-6, "step {est} vs {q}");
    }

    #[test]
    fn unquantised_noisy_record_is_not_a_grid() {
        // Deterministic pseudo-noise (no RNG needed): an irrational-frequency chirp.
        let v: Vec<f64> = (0..5000)
            .map(|i| {
                let x = i as f64;
                (x * 0.001).sin() + 1e-5 * (x * x * 0.7548776662466927).sin()
            })
            .collect();
        assert_eq!(encoder_step(&v), 0.0);
    }

    #[test]
    fn too_few_levels_is_no_estimate() {
        assert_eq!(encoder_step(&[0.0; 50]), 0.0);
        assert_eq!(encoder_step(&[1.0, 2.0]), 0.0);
    }
}
