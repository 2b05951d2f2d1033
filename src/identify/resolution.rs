//! Encoder resolution read from the levels a quantised angle takes.
//!
//! Sample-to-sample differences measure the encoder step only while the axis creeps; on a
//! scan at constant speed every difference is the travel per sample (tens of steps), and a
//! low percentile of them returns that travel. The set of distinct values the signal
//! visits does not depend on speed: over a record the sampling phase drifts, so the sorted
//! levels sit one step apart, whatever the motion.

/// Encoder step of a quantised angle record, rad; 0 when the record is not on a grid
/// (unquantised or noisy data, or fewer than 10 distinct levels). Typical: 1.57e-3 rad for
/// a 4000-count encoder, 9.6e-5 rad for 2^16 counts. A record of which at least half of
/// the readings lie on a grid is on it, so that a stretch off it (a fault, or readings a
/// logger filled in) does not hide the step of the rest. (Readings off any grid land
/// within the test's rounding of a whole step about one time in ten.)
pub fn encoder_step(v: &[f64]) -> f64 {
    let mut values: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if values.len() < 10 {
        return 0.0;
    }
    values.sort_by(|a, b| a.total_cmp(b));
    let range = values[values.len() - 1] - values[0];
    if range <= 0.0 {
        return 0.0;
    }
    // Values converted from counts carry rounding of the last bits; merge those.
    let tol = 1e-9
        * range
            .max(values[0].abs())
            .max(values[values.len() - 1].abs());
    // The distinct levels, each with how many readings it holds.
    let levels = counted(&values, tol);
    let all: Vec<f64> = levels.iter().map(|l| l.0).collect();
    let q = level_grid(&all, tol);
    if q > 0.0 {
        return q;
    }
    // Each reading off the grid adds a level of its own and breaks the spacings of the
    // grid's; the levels read more than once are the grid's, and most readings must lie on
    // the grid they give. Continuous data seldom repeats a value and has too few of them.
    // A slow stretch off the grid, written to a file's last decimal, repeats a few values
    // of its own by chance (ten in 4000 readings of a creeping sine at six decimals), and
    // their spacings break the grid's: the levels read three or four times then give it.
    // Readings off the grid are written to the file's last decimal, so they repeat on that
    // unit and its small multiples: a step read where they are many must be well above it.
    let unit = decimal_unit(v);
    for least in 2..=4 {
        let repeated: Vec<f64> = levels
            .iter()
            .filter(|l| l.1 >= least)
            .map(|l| l.0)
            .collect();
        let q = level_grid(&repeated, tol);
        if q <= 20.0 * unit {
            continue;
        }
        // A reading is on the grid when it lies a whole number of steps from the nearest
        // repeated level: near, so that the step's own rounding does not add up. (A grid
        // was found on them, so there are at least ten.)
        let on_grid = |q: f64| {
            values
                .iter()
                .filter(|&&x| {
                    let i = repeated
                        .partition_point(|r| *r < x)
                        .clamp(1, repeated.len() - 1);
                    let (lo, hi) = (repeated[i - 1], repeated[i]);
                    let near = if x - lo > hi - x { hi } else { lo };
                    let k = (x - near) / q;
                    (k - k.round()).abs() < 0.05
                })
                .count() as f64
                / values.len() as f64
        };
        // Half, not nine in ten: with the step lost, every threshold counted in encoder
        // steps fell to the noise, and a da Vinci log with a fifth of its readings off the
        // grid had untouched stretches flagged as jerks.
        if on_grid(q) >= 0.5 {
            return finest_that_fits(q, unit, on_grid);
        }
    }
    step_of_differences(v, tol, unit)
}

/// How many different whole numbers of a step the successive differences must take for
/// [`step_of_differences`] to read the step off them.
const LEAST_MULTIPLES: usize = 5;

/// The step read off the differences between successive readings of `v` (in time order),
/// where the levels do not give it: a scan that sweeps its encoder reads each level about
/// once, so that with a stretch off the grid too few levels repeat. The difference of two
/// successive readings on the grid is a whole number of steps, and a scan repeats those
/// differences many times, where readings off the grid give each its own. Each of the
/// most repeated differences and of the smallest spacings between repeated differences,
/// and its half, third and quarter, is a candidate; the step
/// is the coarsest of which at least half of the differences that are not zero are a
/// whole number (a held reading fits any grid), at least five different ones, and over
/// twenty times the decimal `unit` the readings are written in. 0 when none is.
fn step_of_differences(v: &[f64], tol: f64, unit: f64) -> f64 {
    let mut d: Vec<f64> = v
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|x| x.is_finite() && *x > tol)
        .collect();
    if d.len() < 10 {
        return 0.0;
    }
    d.sort_by(|a, b| a.total_cmp(b));
    let mut distinct = counted(&d, tol);
    distinct.retain(|l| l.1 >= 2);
    // A fast scan's differences are tens of steps; the step is then the spacing of the
    // repeated differences (the smallest few of the spacings are candidates too).
    let mut spacings: Vec<f64> = distinct.windows(2).map(|w| w[1].0 - w[0].0).collect();
    spacings.sort_by(|a, b| a.total_cmp(b));
    distinct.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.total_cmp(&b.0)));
    let mut candidates: Vec<f64> = distinct
        .iter()
        .take(20)
        .map(|l| l.0)
        .chain(spacings.iter().copied().filter(|g| *g > tol).take(20))
        .flat_map(|g| (1..=4).map(move |k| g / k as f64))
        .filter(|q| *q > tol)
        .collect();
    // The differences of readings written to the file's last decimal `unit` repeat on
    // that unit and its small multiples, about half of them on twice the unit.
    candidates.retain(|q| *q > 20.0 * unit);
    candidates.sort_by(|a, b| b.total_cmp(a));
    // Differences of readings on a grid are whole numbers of its step to the file's
    // rounding: within a twentieth of a candidate picks those that may be, the step
    // refined on them by least squares, and within the rounding of two readings of it
    // decides. (With a twentieth alone, a sine's speed dwelling near its peak and a few
    // steps of noise let 1448 steps of a 6 µrad grid pass on a sweep that moves about
    // that much a sample, and then 206 of them, with the multiples one to seven.)
    let exact = 3.0 * unit + 10.0 * tol;
    let whole = |q: f64, near: f64| {
        d.iter()
            .filter_map(|&x| {
                // A difference under half a step is no whole number of it (else every
                // candidate coarser than the travel would pass).
                let k = (x / q).round();
                (k >= 1.0 && (x - k * q).abs() <= near).then_some((k, x))
            })
            .collect::<Vec<(f64, f64)>>()
    };
    candidates
        .into_iter()
        .find_map(|q| {
            let loose = whole(q, 0.05 * q);
            if 2 * loose.len() < d.len() {
                return None;
            }
            // Narrowed in steps, so that the differences off the grid the first window
            // holds do not pull the step (by 1.6e-6 of it, on a scan's input two fifths off
            // the grid).
            let mut q = least_squares_step(&loose);
            for share in [0.01, 0.002] {
                q = least_squares_step(&whole(q, share * q));
            }
            // The whole numbers must be many, or a ramp at one speed would give the step of
            // its travel per sample.
            let share = |q: f64| {
                let tight = whole(q, exact);
                let mut multiples: Vec<i64> = tight.iter().map(|(k, _)| *k as i64).collect();
                multiples.sort_unstable();
                multiples.dedup();
                if multiples.len() >= LEAST_MULTIPLES {
                    tight.len() as f64 / d.len() as f64
                } else {
                    0.0
                }
            };
            let q = least_squares_step(&whole(q, exact));
            (share(q) >= 0.5).then(|| {
                let q = finest_that_fits(q, unit, share);
                least_squares_step(&whole(q, exact))
            })
        })
        .unwrap_or(0.0)
}

/// The distinct values of the sorted `v`, each with how many of them lie within `tol` of
/// its first.
fn counted(v: &[f64], tol: f64) -> Vec<(f64, usize)> {
    let mut out: Vec<(f64, usize)> = Vec::new();
    for x in v {
        match out.last_mut() {
            Some((kept, count)) if (*x - *kept).abs() <= tol => *count += 1,
            _ => out.push((*x, 1)),
        }
    }
    out
}

/// The step (rad) that best fits differences `(k, x)` as `k` steps each, by least squares;
/// 0 when there are none (no difference then fits it).
fn least_squares_step(fits: &[(f64, f64)]) -> f64 {
    let (kx, kk) = fits
        .iter()
        .fold((0.0, 0.0), |(kx, kk), (k, x)| (kx + k * x, kk + k * k));
    if kk > 0.0 {
        kx / kk
    } else {
        0.0
    }
}

/// The step `q` (rad) found to fit at least half of the readings, or its half, third or
/// quarter where that fits clearly more of them (`share`: the fraction that fits a step):
/// the coarsest within 0.05 of the best, and over twenty times the decimal `unit`. Readings
/// off the grid fit a step and its fractions equally often, a twentieth either way, while
/// readings on it fit twice the step half the time only: a triangle scan of an 8192-count
/// encoder whose levels read twice or more were every other count gave two steps.
fn finest_that_fits(q: f64, unit: f64, share: impl Fn(f64) -> f64) -> f64 {
    let fits: Vec<(f64, f64)> = (1..=4)
        .map(|k| q / k as f64)
        .filter(|f| *f > 20.0 * unit)
        .map(|f| (f, share(f)))
        .collect();
    let best = fits.iter().fold(0.0f64, |b, (_, s)| b.max(*s));
    fits.iter()
        .find(|(_, s)| *s >= best - 0.05)
        .map_or(q, |(f, _)| *f)
}

/// The coarsest decimal unit (1, 0.1, ... 1e-12) that 99 % of the readings `v` are
/// written in, as a file with a fixed number of decimals holds them; 0 when they carry
/// more digits than that.
fn decimal_unit(v: &[f64]) -> f64 {
    (0..=12)
        .map(|k| 10f64.powi(-k))
        .find(|&u| {
            let on = v
                .iter()
                .filter(|&&x| {
                    let k = x / u;
                    (k - k.round()).abs() < 1e-3
                })
                .count();
            on as f64 >= 0.99 * v.len() as f64
        })
        .unwrap_or(0.0)
}

/// The step of the grid sorted distinct `levels` (rad) lie on: every spacing a whole
/// number of it; 0 when they do not (or are fewer than 10). `tol` (rad) is the rounding
/// below which two levels are one.
fn level_grid(levels: &[f64], tol: f64) -> f64 {
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

    /// Levels read twice or more that are all even counts, the odd ones read once, and a
    /// few readings off the grid that break the spacings of all the levels: twice the
    /// step fits the even readings (three quarters of them), the step itself nearly all.
    #[test]
    fn twice_the_step_is_not_taken_for_it() {
        let q = std::f64::consts::TAU / 8192.0;
        let mut v: Vec<f64> = (0..200)
            .flat_map(|k| [2 * k, 2 * k])
            .map(|k| k as f64 * q)
            .collect();
        v.extend((0..100).map(|k| (2 * k + 1) as f64 * q));
        v.extend((0..20).map(|k| (7.0 * k as f64 + 0.37) * q));
        let est = encoder_step(&v);
        assert!((est / q - 1.0).abs() < 1e-6, "step {est} vs {q}");
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

    /// A creeping sine on a 4000-count grid, written with six decimals as the shipped logs
    /// are, with a smooth stretch of 2 % of its readings off the grid (a raised-cosine jerk
    /// written unquantised): those readings add 396 levels to the grid's 639, yet the step
    /// is the grid's, to the file's last decimal. So it is with the stretch on 20 % or 40 %
    /// of the record; on 70 % the record is not a grid.
    #[test]
    fn a_stretch_off_the_grid_keeps_the_step_of_the_rest() {
        let q = 2.0 * std::f64::consts::PI / 4000.0;
        let record = |share: f64| -> Vec<f64> {
            let n = 20000;
            let (a, b) = (8000, 8000 + (share * n as f64) as usize);
            (0..n)
                .map(|i| {
                    let x = 0.5 * (i as f64 * 1e-3 * 0.6).sin() - 0.3;
                    let x = if (a..b).contains(&i) {
                        let p = (i - a) as f64 / (b - a) as f64;
                        x + 0.5 * (1.0 - (std::f64::consts::TAU * p).cos())
                    } else {
                        quantise(x, q)
                    };
                    (x * 1e6).round() / 1e6
                })
                .collect()
        };
        let v = record(0.02);
        let mut levels = v.clone();
        levels.sort_by(|a, b| a.total_cmp(b));
        levels.dedup();
        let on_grid = levels
            .iter()
            .filter(|x| ((*x / q) - (*x / q).round()).abs() < 1e-3)
            .count();
        assert!(
            levels.len() - on_grid > levels.len() / 10,
            "the stretch's levels are over a tenth of all"
        );
        // Read off the spacings of every level, as a record wholly on a grid is, it is none.
        assert_eq!(super::level_grid(&levels, 1e-12), 0.0);
        let est = encoder_step(&v);
        assert!((est - q).abs() <= 1e-6, "step {est} vs {q}");
        for share in [0.2, 0.4] {
            let est = encoder_step(&record(share));
            assert!((est - q).abs() <= 1e-6, "{share}: step {est} vs {q}");
        }
        assert_eq!(encoder_step(&record(0.7)), 0.0);
    }

    /// A sine sweeping 26 000 steps of an 8192-count encoder in 3000 readings (the gimbal
    /// scan's input), each level read about once, with two fifths of its readings off the
    /// grid by a tenth of a step of noise: too few levels repeat to give the step, and the
    /// successive differences give it. Off the grid throughout, it is none.
    #[test]
    fn a_sweep_with_a_stretch_off_the_grid_keeps_its_step() {
        use rand::{Rng, SeedableRng};
        let q = std::f64::consts::TAU / 8192.0;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let noise = rand_distr::Normal::new(0.0, 0.1 * q).expect("normal");
        let sweep = |off: std::ops::Range<usize>, rng: &mut rand_chacha::ChaCha8Rng| {
            (0..3000)
                .map(|i| {
                    let x = 10.0 * (std::f64::consts::TAU * 0.1 * i as f64 * 0.01).sin();
                    if off.contains(&i) {
                        quantise(x, q) + rng.sample(noise)
                    } else {
                        quantise(x, q)
                    }
                })
                .collect::<Vec<f64>>()
        };
        let v = sweep(1000..2200, &mut rng);
        let est = encoder_step(&v);
        assert!((est / q - 1.0).abs() < 1e-6, "step {est} vs {q}");
        assert_eq!(encoder_step(&sweep(0..3000, &mut rng)), 0.0);
    }

    #[test]
    fn too_few_levels_is_no_estimate() {
        assert_eq!(encoder_step(&[0.0; 50]), 0.0);
        assert_eq!(encoder_step(&[1.0, 2.0]), 0.0);
    }
}
