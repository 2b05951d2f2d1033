//! Line-of-sight error statistics as pointing engineers judge them: RMS and peak, jitter
//! within a camera exposure, and the error's spectrum with its cumulative RMS.
//! Bottom layer: imports nothing of this crate.
//!
//! Input is a uniformly sampled error series (mrad) over the metrics window. Jitter is the
//! RMS about the window's own mean inside every exposure-long window (sliding one sample
//! at a time): the part of the error that blurs one image, while the window mean moves
//! the whole image. Non-finite samples are dropped first, so no figure is ever NaN.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Line-of-sight statistics (`[closed_loop.los]`): the exposure that jitter is judged over
/// and the segment of the error's spectrum.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LosParams {
    /// Camera exposure, s (0.01: jitter is judged within each 10 ms exposure).
    /// Allowed: > 0 and at most 1e4.
    #[serde(default = "default_exposure")]
    pub exposure_s: f64,
    /// Welch segment length, s (1.0: 1 Hz resolution); rounded down to a power of two
    /// samples and capped to the record.
    /// Allowed: > 0 and at most 1e4.
    #[serde(default = "default_segment")]
    pub psd_segment_s: f64,
}

fn default_exposure() -> f64 {
    0.01
}
fn default_segment() -> f64 {
    1.0
}

impl Default for LosParams {
    fn default() -> Self {
        LosParams {
            exposure_s: default_exposure(),
            psd_segment_s: default_segment(),
        }
    }
}

impl LosParams {
    /// Check the settings; returns `(key, message)`.
    pub fn validate(&self) -> Result<(), (String, String)> {
        for (k, v, what) in [
            ("exposure_s", self.exposure_s, "0.01 for a 10 ms exposure"),
            (
                "psd_segment_s",
                self.psd_segment_s,
                "1.0 for 1 Hz resolution",
            ),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 1e4) {
                return Err((
                    k.to_string(),
                    format!("{v} must be a time above 0 and at most 1e4 s ({what})"),
                ));
            }
        }
        Ok(())
    }
}

/// Line-of-sight figures of one record.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LosMetrics {
    /// RMS about zero (the pointing error), mrad.
    pub rms_mrad: f64,
    /// Largest absolute error, mrad.
    pub peak_mrad: f64,
    /// Mean error, mrad.
    pub mean_mrad: f64,
    /// Exposure the jitter is judged over, s.
    pub exposure_s: f64,
    /// Largest jitter (RMS about the exposure's mean) over every exposure window, mrad;
    /// `None` when the record is shorter than one exposure.
    pub jitter_rms_max_mrad: Option<f64>,
    /// 95th percentile of that jitter over the windows, mrad.
    pub jitter_rms_p95_mrad: Option<f64>,
    /// Largest absolute exposure mean (how far one image is displaced), mrad.
    pub exposure_mean_max_mrad: Option<f64>,
    /// Samples judged.
    pub samples: usize,
}

/// One-sided power spectral density of the error and its cumulative RMS.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ErrorSpectrum {
    /// Bin frequencies, Hz, from 0 to Nyquist.
    pub frequency_hz: Vec<f64>,
    /// PSD, mrad^2/Hz.
    pub psd_mrad2_per_hz: Vec<f64>,
    /// RMS carried by the frequencies up to each bin, mrad (the last one is the total).
    pub cumulative_rms_mrad: Vec<f64>,
}

/// Samples per exposure window at `fs_hz` (at least 2).
fn window_len(fs_hz: f64, exposure_s: f64) -> usize {
    ((exposure_s * fs_hz).round() as usize).max(2)
}

/// Jitter of every exposure window `(rms about the window mean, window mean)`, sliding one
/// sample at a time; see [`for_each_exposure`].
pub fn exposure_windows(e: &[f64], w: usize) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(e.len().saturating_sub(w) + 1);
    for_each_exposure(e, w, |rms, mean| out.push((rms, mean)));
    out
}

/// Calls `f(rms about the window mean, window mean)` for every exposure window of `w`
/// samples, sliding one sample at a time; O(n) by running sums, anchored afresh every
/// window length so rounding cannot accumulate. Nothing is called when `e` is shorter
/// than one window.
fn for_each_exposure(e: &[f64], w: usize, mut f: impl FnMut(f64, f64)) {
    if w == 0 || e.len() < w {
        return;
    }
    // Sums of the values about the record's mean: the variance is then a difference of
    // small numbers, not of two large ones.
    let centre = e.iter().sum::<f64>() / e.len() as f64;
    let (mut s1, mut s2) = (0.0, 0.0);
    for &v in &e[..w] {
        let v = v - centre;
        s1 += v;
        s2 += v * v;
    }
    let inv = 1.0 / w as f64;
    for start in 0..=(e.len() - w) {
        if start > 0 {
            if start % w == 0 {
                (s1, s2) = e[start..start + w].iter().fold((0.0, 0.0), |(a, b), v| {
                    let v = v - centre;
                    (a + v, b + v * v)
                });
            } else {
                let (old, new) = (e[start - 1] - centre, e[start + w - 1] - centre);
                s1 += new - old;
                s2 += new * new - old * old;
            }
        }
        let mean = s1 * inv;
        f((s2 * inv - mean * mean).max(0.0).sqrt(), mean + centre);
    }
}

/// The finite samples of `e`, copied only when some are not.
fn finite(e: &[f64]) -> std::borrow::Cow<'_, [f64]> {
    if e.iter().all(|v| v.is_finite()) {
        std::borrow::Cow::Borrowed(e)
    } else {
        std::borrow::Cow::Owned(e.iter().copied().filter(|v| v.is_finite()).collect())
    }
}

/// The line-of-sight figures of error series `e_mrad` sampled at `fs_hz`.
pub fn los_metrics(e_mrad: &[f64], fs_hz: f64, p: &LosParams) -> LosMetrics {
    let e = finite(e_mrad);
    let e: &[f64] = &e;
    let n = e.len();
    let (mut sum, mut sq, mut peak) = (0.0, 0.0, 0.0_f64);
    for &v in e {
        sum += v;
        sq += v * v;
        peak = peak.max(v.abs());
    }
    let nf = n.max(1) as f64;
    let mut jit = Vec::with_capacity(n);
    let mut mean_max = 0.0_f64;
    for_each_exposure(e, window_len(fs_hz, p.exposure_s), |rms, mean| {
        jit.push(rms);
        mean_max = mean_max.max(mean.abs());
    });
    let (max, p95, mean_max) = if jit.is_empty() {
        (None, None, None)
    } else {
        let max = jit.iter().copied().fold(0.0, f64::max);
        let k = ((0.95 * jit.len() as f64).ceil() as usize).clamp(1, jit.len()) - 1;
        let (_, p95, _) = jit.select_nth_unstable_by(k, f64::total_cmp);
        (Some(max), Some(*p95), Some(mean_max))
    };
    LosMetrics {
        rms_mrad: (sq / nf).sqrt(),
        peak_mrad: peak,
        mean_mrad: sum / nf,
        exposure_s: p.exposure_s,
        jitter_rms_max_mrad: max,
        jitter_rms_p95_mrad: p95,
        exposure_mean_max_mrad: mean_max,
        samples: n,
    }
}

/// In-place radix-2 FFT of `(re, im)` (length a power of two) with the twiddle factors
/// `(cos, sin)` of `-2 pi k / n`, `k < n/2`, computed once per segment length.
fn fft(re: &mut [f64], im: &mut [f64], twiddle: &[(f64, f64)]) {
    let n = re.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let stride = n / len;
        for start in (0..n).step_by(len) {
            for k in 0..len / 2 {
                let (c, s) = twiddle[k * stride];
                let (a, b) = (start + k, start + k + len / 2);
                let tr = re[b] * c - im[b] * s;
                let ti = re[b] * s + im[b] * c;
                re[b] = re[a] - tr;
                im[b] = im[a] - ti;
                re[a] += tr;
                im[a] += ti;
            }
        }
        len <<= 1;
    }
}

/// Segment pairs transformed at once by [`error_spectrum`]: enough to keep two cores busy,
/// few enough that their spectra stay small (32 pairs of 16384 bins: 4 MB).
const SPECTRUM_BATCH_PAIRS: usize = 32;

/// Welch estimate of the one-sided PSD of `e_mrad` (Hann window, 50 % overlap, segments
/// of `segment_s` rounded down to a power of two samples, at most the record), scaled so
/// that the PSD summed over its bins times the bin width is the record's mean square; the
/// mean is kept, so the cumulative RMS at the top bin is the total RMS. `None` for fewer
/// than 16 finite samples.
pub fn error_spectrum(e_mrad: &[f64], fs_hz: f64, segment_s: f64) -> Option<ErrorSpectrum> {
    let e = finite(e_mrad);
    let e: &[f64] = &e;
    if e.len() < 16 || !(fs_hz.is_finite() && fs_hz > 0.0) {
        return None;
    }
    let want = ((segment_s * fs_hz) as usize).clamp(16, e.len());
    let m = 1usize << (usize::BITS - 1 - want.leading_zeros());
    let hop = m / 2;
    let w: Vec<f64> = (0..m)
        .map(|i| {
            let s = (std::f64::consts::PI * i as f64 / m as f64).sin();
            s * s
        })
        .collect();
    let w2: f64 = w.iter().map(|v| v * v).sum();
    let bins = m / 2 + 1;
    let mut acc = vec![0.0; bins];
    let mut segments = 0usize;
    let twiddle: Vec<(f64, f64)> = (0..m / 2)
        .map(|k| {
            let (s, c) = (-std::f64::consts::TAU * k as f64 / m as f64).sin_cos();
            (c, s)
        })
        .collect();
    // Two real segments per complex transform, one as the real part and one as the
    // imaginary part: for z = a + i b, |A_k|^2 + |B_k|^2 = (|Z_k|^2 + |Z_(m-k)|^2) / 2,
    // the cross terms cancel. A lone last segment (b = 0) obeys the same formula.
    let starts: Vec<usize> = (0..)
        .map(|j| j * hop)
        .take_while(|s| s + m <= e.len())
        .collect();
    // The transforms run in parallel, a batch of pairs at a time (bounded memory); their
    // power is added in segment order, so the sum is the same to the last bit on any
    // number of threads.
    let buffers = || (vec![0.0; m], vec![0.0; m]);
    let power = |(re, im): &mut (Vec<f64>, Vec<f64>), pair: &[usize]| -> Vec<f64> {
        for i in 0..m {
            re[i] = e[pair[0] + i] * w[i];
            im[i] = pair.get(1).map_or(0.0, |&b| e[b + i] * w[i]);
        }
        fft(re, im, &twiddle);
        (0..bins)
            .map(|k| {
                let j = (m - k) % m;
                0.5 * (re[k] * re[k] + im[k] * im[k] + re[j] * re[j] + im[j] * im[j])
            })
            .collect()
    };
    for batch in starts.chunks(2 * SPECTRUM_BATCH_PAIRS) {
        // One pair of transform buffers per worker, reused across its pairs.
        let powers: Vec<Vec<f64>> = batch.par_chunks(2).map_init(buffers, power).collect();
        for p in &powers {
            for (a, v) in acc.iter_mut().zip(p) {
                *a += v;
            }
        }
        segments += batch.len();
    }
    let df = fs_hz / m as f64;
    let scale = 1.0 / (fs_hz * w2 * segments as f64);
    let psd: Vec<f64> = acc
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let one_sided = if k == 0 || k == m / 2 { 1.0 } else { 2.0 };
            a * scale * one_sided
        })
        .collect();
    let mut total = 0.0;
    let cumulative = psd
        .iter()
        .map(|p| {
            total += p * df;
            total.sqrt()
        })
        .collect();
    Some(ErrorSpectrum {
        frequency_hz: (0..bins).map(|k| k as f64 * df).collect(),
        psd_mrad2_per_hz: psd,
        cumulative_rms_mrad: cumulative,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn sine_with_offset_rms_peak_and_spectrum() {
        let fs = 1000.0;
        let (a, m, f0) = (0.3, 0.05, 25.0);
        let e: Vec<f64> = (0..100_000)
            .map(|k| m + a * (std::f64::consts::TAU * f0 * k as f64 / fs).sin())
            .collect();
        let l = los_metrics(&e, fs, &LosParams::default());
        let rms = (m * m + a * a / 2.0).sqrt();
        assert!((l.rms_mrad / rms - 1.0).abs() < 1e-9, "{}", l.rms_mrad);
        assert!((l.peak_mrad - (m + a)).abs() < 1e-6);
        let s = error_spectrum(&e, fs, 1.0).unwrap();
        let top = s
            .psd_mrad2_per_hz
            .iter()
            .enumerate()
            .skip(2)
            .max_by(|x, y| x.1.total_cmp(y.1))
            .unwrap()
            .0;
        assert!(
            (s.frequency_hz[top] - f0).abs() <= 1.0,
            "{}",
            s.frequency_hz[top]
        );
        let total = *s.cumulative_rms_mrad.last().unwrap();
        assert!((total / rms - 1.0).abs() < 0.01, "{total} vs {rms}");
        // Below the sine only the mean; above it everything.
        let below = s.frequency_hz.iter().position(|f| *f >= f0 - 5.0).unwrap();
        assert!((s.cumulative_rms_mrad[below] / m - 1.0).abs() < 0.05);
        let above = s.frequency_hz.iter().position(|f| *f >= f0 + 5.0).unwrap();
        assert!((s.cumulative_rms_mrad[above] / rms - 1.0).abs() < 0.01);
    }

    /// The paired transform against one transform per segment, written out plainly, for
    /// even and odd numbers of segments.
    #[test]
    fn paired_segments_equal_one_transform_each() {
        use rand::Rng;
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        for len in [64usize, 96, 128, 160, 1000] {
            let e: Vec<f64> = (0..len).map(|_| rng.gen_range(-1.0..1.0) + 0.3).collect();
            let s = error_spectrum(&e, 100.0, 0.32).unwrap();
            let m = 32;
            let w: Vec<f64> = (0..m)
                .map(|i| (std::f64::consts::PI * i as f64 / m as f64).sin().powi(2))
                .collect();
            let twiddle: Vec<(f64, f64)> = (0..m / 2)
                .map(|k| {
                    let (s, c) = (-std::f64::consts::TAU * k as f64 / m as f64).sin_cos();
                    (c, s)
                })
                .collect();
            let mut acc = vec![0.0; m / 2 + 1];
            let mut start = 0;
            let mut segments = 0;
            while start + m <= len {
                let mut re: Vec<f64> = (0..m).map(|i| e[start + i] * w[i]).collect();
                let mut im = vec![0.0; m];
                fft(&mut re, &mut im, &twiddle);
                for (k, a) in acc.iter_mut().enumerate() {
                    *a += re[k] * re[k] + im[k] * im[k];
                }
                segments += 1;
                start += m / 2;
            }
            let w2: f64 = w.iter().map(|v| v * v).sum();
            for (k, a) in acc.iter().enumerate() {
                let one_sided = if k == 0 || k == m / 2 { 1.0 } else { 2.0 };
                let want = a * one_sided / (100.0 * w2 * segments as f64);
                let got = s.psd_mrad2_per_hz[k];
                assert!(
                    (got - want).abs() <= 1e-12 * want.abs().max(1e-6),
                    "{len} samples, bin {k}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn white_noise_level() {
        let fs = 2000.0;
        let sigma = 0.02;
        for seed in 1..=3 {
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
            let n = Normal::new(0.0, sigma).unwrap();
            let e: Vec<f64> = (0..400_000).map(|_| n.sample(&mut rng)).collect();
            let s = error_spectrum(&e, fs, 0.5).unwrap();
            let inner = &s.psd_mrad2_per_hz[5..s.psd_mrad2_per_hz.len() - 5];
            let level = inner.iter().sum::<f64>() / inner.len() as f64;
            let want = sigma * sigma / (fs / 2.0);
            assert!(
                (level / want - 1.0).abs() < 0.05,
                "seed {seed}: {level} vs {want}"
            );
            let l = los_metrics(&e, fs, &LosParams::default());
            let p95 = l.jitter_rms_p95_mrad.unwrap();
            // 20-sample windows: the RMS about the window mean is sigma sqrt(19/20) on
            // average, its 95th percentile somewhat above.
            assert!(p95 > sigma * 0.95 && p95 < sigma * 1.3, "{p95}");
        }
    }

    #[test]
    fn jitter_of_slow_and_fast_sines() {
        let fs = 10_000.0;
        let p = LosParams {
            exposure_s: 0.01,
            ..LosParams::default()
        };
        // Slow: over 10 ms a 0.2 Hz sine is a ramp of slope A w at most; RMS of a ramp
        // about its mean over tau is slope tau / sqrt(12).
        let (a, f) = (1.0, 0.2);
        let w = std::f64::consts::TAU * f;
        let e: Vec<f64> = (0..100_000)
            .map(|k| a * (w * k as f64 / fs).sin())
            .collect();
        let l = los_metrics(&e, fs, &p);
        let want = a * w * 0.01 / 12f64.sqrt();
        let got = l.jitter_rms_max_mrad.unwrap();
        assert!((got / want - 1.0).abs() < 0.02, "{got} vs {want}");
        // Fast: many periods inside each exposure: jitter is A / sqrt(2).
        let e: Vec<f64> = (0..50_000)
            .map(|k| a * (std::f64::consts::TAU * 1000.0 * k as f64 / fs).sin())
            .collect();
        let l = los_metrics(&e, fs, &p);
        let got = l.jitter_rms_p95_mrad.unwrap();
        assert!((got / (a / 2f64.sqrt()) - 1.0).abs() < 0.02, "{got}");
    }

    #[test]
    fn sliding_windows_match_brute_force() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let n = Normal::new(0.3, 1.0).unwrap();
        let e: Vec<f64> = (0..2000).map(|_| n.sample(&mut rng)).collect();
        let w = 37;
        let fast = exposure_windows(&e, w);
        assert_eq!(fast.len(), e.len() - w + 1);
        for (i, (j, m)) in fast.iter().enumerate() {
            let win = &e[i..i + w];
            let mean = win.iter().sum::<f64>() / w as f64;
            let rms = (win.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / w as f64).sqrt();
            assert!(
                (j - rms).abs() < 1e-9 && (m - mean).abs() < 1e-12,
                "window {i}"
            );
        }
    }

    #[test]
    fn edge_cases_never_give_nan() {
        let p = LosParams::default();
        let empty = los_metrics(&[], 1000.0, &p);
        assert_eq!(
            (empty.rms_mrad, empty.peak_mrad, empty.samples),
            (0.0, 0.0, 0)
        );
        assert!(empty.jitter_rms_max_mrad.is_none());
        let short = los_metrics(&[0.1; 5], 1000.0, &p);
        assert!(short.jitter_rms_max_mrad.is_none() && short.rms_mrad > 0.0);
        let flat = los_metrics(&[0.2; 500], 1000.0, &p);
        assert_eq!(flat.jitter_rms_max_mrad, Some(0.0));
        let with_nan = los_metrics(&[0.1, f64::NAN, 0.1], 1000.0, &p);
        assert!(with_nan.rms_mrad.is_finite() && with_nan.samples == 2);
        assert!(error_spectrum(&[1.0; 10], 1000.0, 1.0).is_none());
        assert!(LosParams {
            exposure_s: 0.0,
            ..p.clone()
        }
        .validate()
        .is_err());
        assert!(LosParams {
            psd_segment_s: f64::NAN,
            ..p
        }
        .validate()
        .is_err());
    }
}
