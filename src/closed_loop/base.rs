//! The base's motion at the control samples: angle, rate and acceleration.
//!
//! Analytic signals are evaluated directly. A PSD motion (hundreds of sines) is advanced
//! by rotating each sine's phasor one period per sample, which costs a few multiplications
//! per sine instead of a sine and a cosine, and is re-anchored to the exact phases every
//! few thousand samples so rounding cannot accumulate. A CSV table is interpolated by
//! cubic Hermite segments (Catmull-Rom slopes) so the base has a continuous rate and an
//! acceleration, which the linear interpolation of a reference would not give.

use crate::signal::{Signal, SignalPoint, SineComponent};

/// Samples between exact re-evaluations of the rotated phasors.
const RESYNC_SAMPLES: u64 = 4096;

/// Base motion evaluated at `t_k = k T`, for increasing `k`.
#[derive(Clone, Debug)]
pub struct BaseMotion<'a> {
    signal: &'a Signal,
    ts: f64,
    bank: Option<PhasorBank>,
}

#[derive(Clone, Debug)]
struct PhasorBank {
    sines: Vec<SineComponent>,
    /// `(cos, sin)` of each sine's phase at sample `k`.
    phasor: Vec<(f64, f64)>,
    /// `(cos, sin)` of each sine's advance per sample.
    step: Vec<(f64, f64)>,
    /// Sample the phasors stand at.
    k: u64,
}

impl PhasorBank {
    fn anchor(&mut self, k: u64, ts: f64) {
        let t = k as f64 * ts;
        for (p, c) in self.phasor.iter_mut().zip(&self.sines) {
            let (s, co) = (c.omega_rad_s * t + c.phase_rad).sin_cos();
            *p = (co, s);
        }
        self.k = k;
    }

    fn at(&mut self, k: u64, ts: f64) -> SignalPoint {
        if k < self.k || k - self.k > 1 || k.is_multiple_of(RESYNC_SAMPLES) {
            self.anchor(k, ts);
        } else if k == self.k + 1 {
            for (p, &(cs, sn)) in self.phasor.iter_mut().zip(&self.step) {
                *p = (p.0 * cs - p.1 * sn, p.1 * cs + p.0 * sn);
            }
            self.k = k;
        }
        let mut out = SignalPoint::default();
        for (&(co, s), c) in self.phasor.iter().zip(&self.sines) {
            let a = c.amplitude_rad;
            let w = c.omega_rad_s;
            out.value += a * s;
            out.rate += a * w * co;
            out.accel -= a * w * w * s;
        }
        out
    }
}

impl<'a> BaseMotion<'a> {
    /// The motion of `signal` sampled every `ts` seconds.
    pub fn new(signal: &'a Signal, ts: f64) -> Self {
        let sines = signal.psd_components();
        let bank = (!sines.is_empty()).then(|| {
            let mut b = PhasorBank {
                sines: sines.to_vec(),
                phasor: vec![(1.0, 0.0); sines.len()],
                step: sines
                    .iter()
                    .map(|c| {
                        let (s, co) = (c.omega_rad_s * ts).sin_cos();
                        (co, s)
                    })
                    .collect(),
                k: 0,
            };
            b.anchor(0, ts);
            b
        });
        BaseMotion { signal, ts, bank }
    }

    /// Angle (rad), rate (rad/s) and acceleration (rad/s^2) at sample `k`.
    pub fn at_sample(&mut self, k: u64) -> SignalPoint {
        match self.bank.as_mut() {
            Some(b) => b.at(k, self.ts),
            None => smooth_at(self.signal, k as f64 * self.ts),
        }
    }
}

/// A signal with tables interpolated smoothly.
pub fn smooth_at(signal: &Signal, t: f64) -> SignalPoint {
    match signal {
        Signal::Table { samples, .. } => hermite(samples, t),
        Signal::Sum { parts } => parts.iter().fold(SignalPoint::default(), |acc, p| {
            let q = smooth_at(p, t);
            SignalPoint {
                value: acc.value + q.value,
                rate: acc.rate + q.rate,
                accel: acc.accel + q.accel,
            }
        }),
        other => other.at(t),
    }
}

/// The cubic Hermite curve from `p0` (slope `m0`) to `p1` (slope `m1`) on `s` in [0, 1]:
/// its value and first and second derivatives with respect to `s`.
#[inline]
pub fn hermite_cubic(p0: f64, m0: f64, p1: f64, m1: f64, s: f64) -> [f64; 3] {
    let (s2, s3) = (s * s, s * s * s);
    [
        (2.0 * s3 - 3.0 * s2 + 1.0) * p0
            + (s3 - 2.0 * s2 + s) * m0
            + (-2.0 * s3 + 3.0 * s2) * p1
            + (s3 - s2) * m1,
        (6.0 * s2 - 6.0 * s) * p0
            + (3.0 * s2 - 4.0 * s + 1.0) * m0
            + (-6.0 * s2 + 6.0 * s) * p1
            + (3.0 * s2 - 2.0 * s) * m1,
        (12.0 * s - 6.0) * p0
            + (6.0 * s - 4.0) * m0
            + (-12.0 * s + 6.0) * p1
            + (6.0 * s - 2.0) * m1,
    ]
}

/// Cubic Hermite interpolation with Catmull-Rom slopes (one-sided at the ends), held at
/// the end values outside the table.
fn hermite(samples: &[(f64, f64)], t: f64) -> SignalPoint {
    let n = samples.len();
    if n == 0 {
        return SignalPoint::default();
    }
    if n == 1 || t <= samples[0].0 || t >= samples[n - 1].0 {
        let v = if t <= samples[0].0 {
            samples[0].1
        } else {
            samples[n - 1].1
        };
        return SignalPoint {
            value: v,
            ..SignalPoint::default()
        };
    }
    let k = samples.partition_point(|s| s.0 <= t).clamp(1, n - 1);
    let slope = |i: usize| -> f64 {
        let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
        (samples[b].1 - samples[a].1) / (samples[b].0 - samples[a].0)
    };
    let (t0, p0) = samples[k - 1];
    let (t1, p1) = samples[k];
    let h = t1 - t0;
    let (m0, m1) = (slope(k - 1) * h, slope(k) * h);
    let [value, d1, d2] = hermite_cubic(p0, m0, p1, m1, (t - t0) / h);
    SignalPoint {
        value,
        rate: d1 / h,
        accel: d2 / (h * h),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotated_phasors_match_direct_evaluation() {
        let sig: Signal = toml::from_str(
            "kind = \"psd\"\npsd = [[1.0, 1e-7], [10.0, 1e-6], [200.0, 1e-9]]\ncomponents = 150",
        )
        .unwrap();
        let ts = 5e-5;
        let mut b = BaseMotion::new(&sig, ts);
        let mut worst: f64 = 0.0;
        for k in 0..20_000u64 {
            let fast = b.at_sample(k);
            if k % 997 == 0 || k == 4095 || k == 4097 {
                let exact = sig.at(k as f64 * ts);
                worst = worst
                    .max((fast.value - exact.value).abs() / 1e-3)
                    .max((fast.accel - exact.accel).abs() / exact.accel.abs().max(1.0));
            }
        }
        assert!(worst < 1e-9, "{worst}");
    }

    #[test]
    fn hermite_table_reproduces_a_cubic_inside() {
        // Catmull-Rom reproduces quadratics exactly away from the ends.
        let f = |t: f64| 0.3 + 0.5 * t - 0.2 * t * t;
        let samples: Vec<(f64, f64)> = (0..=20)
            .map(|i| (i as f64 * 0.1, f(i as f64 * 0.1)))
            .collect();
        for t in [0.33, 0.9, 1.27, 1.71] {
            let p = hermite(&samples, t);
            assert!((p.value - f(t)).abs() < 1e-12, "{t}");
            assert!((p.rate - (0.5 - 0.4 * t)).abs() < 1e-9, "{t}");
            assert!((p.accel + 0.4).abs() < 1e-6, "{t}: {}", p.accel);
        }
        assert_eq!(hermite(&samples, -1.0).value, f(0.0));
        assert_eq!(hermite(&samples, 5.0).rate, 0.0);
    }
}
