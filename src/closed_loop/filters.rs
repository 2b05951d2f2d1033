//! Discrete loop filters from physical parameters: low-pass, notch, lead-lag and general
//! biquads, each discretised by the Tustin (bilinear) transform prewarped at its
//! characteristic frequency, so the discrete filter has exactly the continuous response
//! there (a notch stays centred on the resonance it is meant to cancel).
//!
//! Tustin maps `s = K (z - 1)/(z + 1)` with `K = w0 / tan(w0 T / 2)` (plain Tustin:
//! `K = 2/T`); the discrete response at `f` is the continuous one at the warped frequency
//! `K tan(pi f T)`.

use nalgebra::Complex;
use serde::{Deserialize, Serialize};

/// One continuous-time filter, from physical parameters (`kind = "..."` in a scenario).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum FilterSpec {
    /// First-order low-pass `w/(s + w)` (a gyro's anti-noise filter at 500 Hz).
    LowPass1 {
        /// Corner frequency, Hz.
        /// Allowed: > 0 and below the Nyquist frequency.
        corner_hz: f64,
    },
    /// Second-order low-pass `w^2/(s^2 + 2 zeta w s + w^2)`.
    LowPass2 {
        /// Corner (natural) frequency, Hz.
        /// Allowed: > 0 and below the Nyquist frequency.
        corner_hz: f64,
        /// Damping ratio (0.707: Butterworth).
        /// Allowed: > 0 and at most 10.
        /// Unit: 1.
        #[serde(default = "default_damping")]
        damping: f64,
    },
    /// Notch `(s^2 + 2 zd w s + w^2)/(s^2 + 2 zp w s + w^2)` with `zp = width/(2 centre)`
    /// and `zd = zp 10^(-depth/20)`: attenuation `depth_db` at the centre, and the width
    /// between the frequencies where a deep notch is 3 dB down (for a cable-drive
    /// resonance at 40 Hz: centre 40, depth 20, width 20).
    Notch {
        /// Centre frequency, Hz.
        /// Allowed: > 0 and below the Nyquist frequency.
        center_hz: f64,
        /// Attenuation at the centre, dB (> 0; 20 to 40).
        /// Allowed: above 0 and at most 120.
        depth_db: f64,
        /// Width between the -3 dB frequencies of the deep notch, Hz (about half the
        /// centre frequency; below twice the centre).
        /// Allowed: above 0 and below twice `center_hz`.
        width_hz: f64,
    },
    /// Lead-lag `(s/wz + 1)/(s/wp + 1)`, unity gain at DC: phase lead between a zero below
    /// a pole (20 and 80 Hz give about 37 deg at 40 Hz), lag the other way round.
    LeadLag {
        /// Zero, Hz.
        /// Allowed: > 0 and below the Nyquist frequency.
        zero_hz: f64,
        /// Pole, Hz.
        /// Allowed: > 0 and below the Nyquist frequency.
        pole_hz: f64,
    },
    /// General continuous biquad `(b2 s^2 + b1 s + b0)/(a2 s^2 + a1 s + a0)`: `b = [b0,
    /// b1, b2]`, `a = [a0, a1, a2]` (ascending powers of `s`).
    Biquad {
        /// Numerator coefficients, ascending powers of `s`.
        /// Unit: 1 (ascending powers of `s`, with `s` in rad/s).
        /// Allowed: finite; degree in `s` at most that of `a`.
        b: [f64; 3],
        /// Denominator coefficients, ascending powers of `s`.
        /// Unit: 1 (ascending powers of `s`, with `s` in rad/s).
        /// Allowed: finite, not all zero, one sign (a stable filter).
        a: [f64; 3],
        /// Frequency where the discrete response equals the continuous one, Hz; none:
        /// plain Tustin (`K = 2/T`).
        /// Allowed: > 0 and below the Nyquist frequency.
        #[serde(default)]
        prewarp_hz: Option<f64>,
    },
}

fn default_damping() -> f64 {
    std::f64::consts::FRAC_1_SQRT_2
}

impl FilterSpec {
    /// Continuous coefficients `(b, a)` in ascending powers of `s` (rad/s units) and the
    /// prewarp frequency in Hz.
    fn continuous(&self) -> ([f64; 3], [f64; 3], Option<f64>) {
        use std::f64::consts::TAU;
        match *self {
            FilterSpec::LowPass1 { corner_hz } => {
                let w = TAU * corner_hz;
                ([w, 0.0, 0.0], [w, 1.0, 0.0], Some(corner_hz))
            }
            FilterSpec::LowPass2 { corner_hz, damping } => {
                let w = TAU * corner_hz;
                (
                    [w * w, 0.0, 0.0],
                    [w * w, 2.0 * damping * w, 1.0],
                    Some(corner_hz),
                )
            }
            FilterSpec::Notch {
                center_hz,
                depth_db,
                width_hz,
            } => {
                let w = TAU * center_hz;
                let zp = width_hz / (2.0 * center_hz);
                let zd = zp * 10f64.powf(-depth_db / 20.0);
                (
                    [w * w, 2.0 * zd * w, 1.0],
                    [w * w, 2.0 * zp * w, 1.0],
                    Some(center_hz),
                )
            }
            FilterSpec::LeadLag { zero_hz, pole_hz } => {
                let (wz, wp) = (TAU * zero_hz, TAU * pole_hz);
                (
                    [1.0, 1.0 / wz, 0.0],
                    [1.0, 1.0 / wp, 0.0],
                    Some((zero_hz * pole_hz).sqrt()),
                )
            }
            FilterSpec::Biquad { b, a, prewarp_hz } => (b, a, prewarp_hz),
        }
    }

    /// The continuous response at `f_hz` (`s = j 2 pi f`).
    pub fn continuous_response(&self, f_hz: f64) -> Complex<f64> {
        let (b, a, _) = self.continuous();
        let s = Complex::new(0.0, std::f64::consts::TAU * f_hz);
        let poly = |c: [f64; 3]| Complex::from(c[0]) + s * c[1] + s * s * c[2];
        poly(b) / poly(a)
    }

    /// Check the parameters at control rate `fs_hz`; the message names the bad value and
    /// what is allowed.
    pub fn validate(&self, fs_hz: f64) -> Result<(), String> {
        let nyquist = 0.5 * fs_hz;
        let freq = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 && v < nyquist {
                Ok(())
            } else {
                Err(format!(
                    "{name} = {} must be a frequency above 0 and below the Nyquist frequency {} Hz",
                    crate::number(v),
                    crate::number(nyquist)
                ))
            }
        };
        match *self {
            FilterSpec::LowPass1 { corner_hz } => freq("corner_hz", corner_hz)?,
            FilterSpec::LowPass2 { corner_hz, damping } => {
                freq("corner_hz", corner_hz)?;
                if !(damping.is_finite() && damping > 0.0 && damping <= 10.0) {
                    return Err(format!(
                        "damping = {} must be in (0, 10] (0.707 for Butterworth)",
                        crate::number(damping)
                    ));
                }
            }
            FilterSpec::Notch {
                center_hz,
                depth_db,
                width_hz,
            } => {
                freq("center_hz", center_hz)?;
                if !(depth_db.is_finite() && depth_db > 0.0 && depth_db <= 120.0) {
                    return Err(format!(
                        "depth_db = {} must be in (0, 120] dB (20 to 40 typical)",
                        crate::number(depth_db)
                    ));
                }
                if !(width_hz.is_finite() && width_hz > 0.0 && width_hz < 2.0 * center_hz) {
                    return Err(format!(
                        "width_hz = {} must be above 0 and below twice center_hz ({} Hz)",
                        crate::number(width_hz),
                        crate::number(2.0 * center_hz)
                    ));
                }
            }
            FilterSpec::LeadLag { zero_hz, pole_hz } => {
                freq("zero_hz", zero_hz)?;
                freq("pole_hz", pole_hz)?;
            }
            FilterSpec::Biquad { b, a, prewarp_hz } => {
                if let Some(f) = prewarp_hz {
                    freq("prewarp_hz", f)?;
                }
                if b.iter().chain(&a).any(|v| !v.is_finite()) {
                    return Err("b and a must hold finite numbers".into());
                }
                let degree = |c: &[f64; 3]| c.iter().rposition(|v| *v != 0.0);
                match (degree(&b), degree(&a)) {
                    (_, None) => return Err("a = [0, 0, 0] is not a denominator".into()),
                    (Some(nb), Some(na)) if nb > na => {
                        return Err(format!(
                            "b has degree {nb} in s above a's {na}: the filter is improper (give a2 or a1 a value)"
                        ))
                    }
                    _ => {}
                }
                let d = Biquad::design(self, fs_hz);
                if !d.poles_inside_unit_circle() {
                    return Err(format!(
                        "a = {a:?} gives an unstable filter (a pole outside the unit circle once discretised): the denominator's coefficients must share one sign"
                    ));
                }
            }
        }
        Ok(())
    }
}

/// A discrete biquad `(b0 + b1 z^-1 + b2 z^-2)/(1 + a1 z^-1 + a2 z^-2)` in transposed
/// direct form II (two states, good rounding behaviour at high sample rates).
#[derive(Clone, Debug, PartialEq)]
pub struct Biquad {
    b0: f64,
    b1: f64,
    b2: f64,
    a1: f64,
    a2: f64,
    s1: f64,
    s2: f64,
}

impl Biquad {
    /// Tustin image of `spec` at sample rate `fs_hz`, prewarped at its characteristic
    /// frequency.
    pub fn design(spec: &FilterSpec, fs_hz: f64) -> Self {
        let (b, a, prewarp) = spec.continuous();
        let t = 1.0 / fs_hz;
        let k = match prewarp {
            Some(f) => {
                let w0 = std::f64::consts::TAU * f;
                w0 / (0.5 * w0 * t).tan()
            }
            None => 2.0 / t,
        };
        // c0 + c1 s + c2 s^2 with s = K (1 - q)/(1 + q), q = z^-1, times (1 + q)^2; a
        // first-order filter only times (1 + q), or the common factor would leave a
        // cancelled pole at z = -1 in the states.
        let first_order = b[2] == 0.0 && a[2] == 0.0;
        let map = |c: [f64; 3]| {
            let k2 = k * k;
            if first_order {
                [c[0] + c[1] * k, c[0] - c[1] * k, 0.0]
            } else {
                [
                    c[0] + c[1] * k + c[2] * k2,
                    2.0 * c[0] - 2.0 * c[2] * k2,
                    c[0] - c[1] * k + c[2] * k2,
                ]
            }
        };
        let (nb, na) = (map(b), map(a));
        let n = na[0];
        Biquad {
            b0: nb[0] / n,
            b1: nb[1] / n,
            b2: nb[2] / n,
            a1: na[1] / n,
            a2: na[2] / n,
            s1: 0.0,
            s2: 0.0,
        }
    }

    /// Coefficients `[b0, b1, b2, a1, a2]`.
    pub fn coefficients(&self) -> [f64; 5] {
        [self.b0, self.b1, self.b2, self.a1, self.a2]
    }

    /// One sample.
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        let y = self.b0 * x + self.s1;
        self.s1 = self.b1 * x - self.a1 * y + self.s2;
        self.s2 = self.b2 * x - self.a2 * y;
        y
    }

    /// Clear the states.
    pub fn reset(&mut self) {
        self.s1 = 0.0;
        self.s2 = 0.0;
    }

    /// Discrete response `H(e^{j 2 pi f / fs})`.
    pub fn response(&self, f_hz: f64, fs_hz: f64) -> Complex<f64> {
        let q = Complex::from_polar(1.0, -std::f64::consts::TAU * f_hz / fs_hz);
        (Complex::from(self.b0) + q * self.b1 + q * q * self.b2)
            / (Complex::from(1.0) + q * self.a1 + q * q * self.a2)
    }

    /// Whether both poles lie strictly inside the unit circle (the Jury conditions for
    /// `z^2 + a1 z + a2`).
    pub fn poles_inside_unit_circle(&self) -> bool {
        self.a2.abs() < 1.0 && self.a1.abs() < 1.0 + self.a2
    }
}

/// Filters in series; an empty chain passes its input through unchanged.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FilterChain {
    stages: Vec<Biquad>,
}

impl FilterChain {
    /// The chain of `specs` at sample rate `fs_hz`.
    pub fn new(specs: &[FilterSpec], fs_hz: f64) -> Self {
        FilterChain {
            stages: specs.iter().map(|s| Biquad::design(s, fs_hz)).collect(),
        }
    }

    /// One sample through every stage.
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        self.stages.iter_mut().fold(x, |v, b| b.step(v))
    }

    /// Product of the stages' responses at `f_hz`.
    pub fn response(&self, f_hz: f64, fs_hz: f64) -> Complex<f64> {
        self.stages
            .iter()
            .fold(Complex::from(1.0), |acc, b| acc * b.response(f_hz, fs_hz))
    }

    /// Whether the chain has no stage.
    pub fn is_empty(&self) -> bool {
        self.stages.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn specs() -> Vec<FilterSpec> {
        vec![
            FilterSpec::LowPass1 { corner_hz: 500.0 },
            FilterSpec::LowPass2 {
                corner_hz: 300.0,
                damping: 0.5,
            },
            FilterSpec::Notch {
                center_hz: 40.0,
                depth_db: 20.0,
                width_hz: 20.0,
            },
            FilterSpec::LeadLag {
                zero_hz: 20.0,
                pole_hz: 80.0,
            },
            FilterSpec::Biquad {
                b: [1.0, 0.01, 1e-5],
                a: [1.0, 0.002, 3e-6],
                prewarp_hz: Some(90.0),
            },
            FilterSpec::Biquad {
                b: [4e4, 0.0, 0.0],
                a: [4e4, 120.0, 1.0],
                prewarp_hz: None,
            },
        ]
    }

    fn db(c: Complex<f64>) -> f64 {
        20.0 * c.norm().log10()
    }

    fn prewarp_k(spec: &FilterSpec, fs: f64) -> f64 {
        match spec.continuous().2 {
            Some(f) => {
                let w0 = std::f64::consts::TAU * f;
                w0 / (0.5 * w0 / fs).tan()
            }
            None => 2.0 * fs,
        }
    }

    /// The discrete response is the continuous one at the warped frequency
    /// `K tan(pi f T) / (2 pi)` (the defining identity of the bilinear map).
    #[test]
    fn discrete_responses_are_the_tustin_images() {
        for fs in [20_000.0, 2_000.0] {
            for spec in specs() {
                if spec.validate(fs).is_err() {
                    continue;
                }
                let d = Biquad::design(&spec, fs);
                let k = prewarp_k(&spec, fs);
                for i in 0..50 {
                    let f = 0.1 * (0.45 * fs / 0.1_f64).powf(i as f64 / 49.0);
                    let warped = k * (std::f64::consts::PI * f / fs).tan() / std::f64::consts::TAU;
                    let want = spec.continuous_response(warped);
                    let got = d.response(f, fs);
                    assert!(
                        (db(got) - db(want)).abs() < 0.01,
                        "{spec:?} at {f} Hz, fs {fs}"
                    );
                    let dphi = (got / want).arg().to_degrees();
                    assert!(dphi.abs() < 0.05, "{spec:?} at {f} Hz: {dphi} deg");
                }
            }
        }
    }

    /// A first-order filter keeps one pole: no cancelled pair at z = -1 in its states.
    #[test]
    fn first_order_filters_have_one_pole() {
        for spec in [
            FilterSpec::LowPass1 { corner_hz: 400.0 },
            FilterSpec::LeadLag {
                zero_hz: 30.0,
                pole_hz: 60.0,
            },
        ] {
            let [_, _, b2, _, a2] = Biquad::design(&spec, 20_000.0).coefficients();
            assert_eq!((b2, a2), (0.0, 0.0), "{spec:?}");
        }
    }

    #[test]
    fn prewarped_frequency_is_exact() {
        let fs = 2000.0;
        for spec in specs() {
            let Some(f0) = spec.continuous().2 else {
                continue;
            };
            let d = Biquad::design(&spec, fs);
            let (got, want) = (d.response(f0, fs), spec.continuous_response(f0));
            assert!((got - want).norm() < 1e-9 * want.norm(), "{spec:?}");
        }
    }

    #[test]
    fn notch_depth_and_width_are_as_specified() {
        let fs = 20_000.0;
        let spec = FilterSpec::Notch {
            center_hz: 40.0,
            depth_db: 30.0,
            width_hz: 10.0,
        };
        let d = Biquad::design(&spec, fs);
        assert!((db(d.response(40.0, fs)) + 30.0).abs() < 0.01);
        // -3 dB edges of the continuous notch: |H|^2 = 1/2 where (w0^2 - w^2)^2 =
        // (2 zp w0 w)^2 (1 - 2 r^2) / ... for a deep notch the edges sit at
        // w = w0 (sqrt(1 + zp^2) +- zp): their distance is the width.
        let zp: f64 = 10.0 / 80.0;
        let lo = 40.0 * ((1.0 + zp * zp).sqrt() - zp);
        let hi = 40.0 * ((1.0 + zp * zp).sqrt() + zp);
        assert!((hi - lo - 10.0).abs() < 1e-9);
        for f in [lo, hi] {
            // A 30 dB notch leaves 10^-1.5 of the numerator's damping: within 0.01 dB of -3.
            assert!(
                (db(spec.continuous_response(f)) + 3.0103).abs() < 0.01,
                "{f}"
            );
            assert!((db(d.response(f, fs)) + 3.0103).abs() < 0.02, "{f}");
        }
    }

    /// Stepping a sine through the filter gives `|H|` and its phase in steady state.
    #[test]
    fn time_steps_agree_with_the_response() {
        let fs = 2000.0;
        for spec in specs() {
            for f in [3.0, 40.0, 150.0] {
                let mut d = Biquad::design(&spec, fs);
                let h = d.response(f, fs);
                let n_settle = 40_000;
                // Ten seconds: a whole number of periods at each frequency.
                let n = 20_000;
                let w = std::f64::consts::TAU * f / fs;
                let (mut c, mut s) = (0.0, 0.0);
                for k in 0..(n_settle + n) {
                    let y = d.step((w * k as f64).sin());
                    if k >= n_settle {
                        c += y * (w * k as f64).cos();
                        s += y * (w * k as f64).sin();
                    }
                }
                let amp = 2.0 * (c * c + s * s).sqrt() / n as f64;
                assert!(
                    (amp / h.norm() - 1.0).abs() < 1e-3,
                    "{spec:?} {f}: {amp} vs {}",
                    h.norm()
                );
            }
        }
    }

    #[test]
    fn unity_dc_gains_and_identity_chain() {
        let fs = 20_000.0;
        for spec in [
            FilterSpec::LowPass1 { corner_hz: 100.0 },
            FilterSpec::LowPass2 {
                corner_hz: 100.0,
                damping: 0.7,
            },
            FilterSpec::LeadLag {
                zero_hz: 20.0,
                pole_hz: 80.0,
            },
            FilterSpec::Notch {
                center_hz: 40.0,
                depth_db: 20.0,
                width_hz: 20.0,
            },
        ] {
            let d = Biquad::design(&spec, fs);
            let [b0, b1, b2, a1, a2] = d.coefficients();
            assert!(
                ((b0 + b1 + b2) / (1.0 + a1 + a2) - 1.0).abs() < 1e-9,
                "{spec:?}"
            );
        }
        let mut empty = FilterChain::new(&[], fs);
        assert!(empty.is_empty());
        for x in [0.1, -3.7, 1e-300, 12345.678] {
            assert_eq!(empty.step(x), x);
        }
        assert_eq!(empty.response(12.0, fs), Complex::from(1.0));
    }

    #[test]
    fn bad_filters_are_refused_with_the_value_named() {
        let fs = 20_000.0;
        let err = |s: FilterSpec| s.validate(fs).unwrap_err();
        assert!(err(FilterSpec::LowPass1 {
            corner_hz: 12_000.0
        })
        .contains("Nyquist frequency 10000"));
        assert!(err(FilterSpec::Notch {
            center_hz: 40.0,
            depth_db: -3.0,
            width_hz: 10.0
        })
        .contains("depth_db = -3"));
        assert!(err(FilterSpec::Notch {
            center_hz: 40.0,
            depth_db: 20.0,
            width_hz: 0.0
        })
        .contains("width_hz = 0"));
        assert!(err(FilterSpec::LowPass1 {
            corner_hz: f64::NAN
        })
        .contains("corner_hz"));
        assert!(err(FilterSpec::Biquad {
            b: [1.0, 0.0, 0.0],
            a: [1.0, -0.01, 1e-5],
            prewarp_hz: None
        })
        .contains("unstable"));
        assert!(err(FilterSpec::Biquad {
            b: [0.0, 0.0, 1.0],
            a: [1.0, 0.0, 0.0],
            prewarp_hz: None
        })
        .contains("improper"));
        assert!(err(FilterSpec::Biquad {
            b: [1.0, 0.0, 0.0],
            a: [0.0, 0.0, 0.0],
            prewarp_hz: None
        })
        .contains("denominator"));
    }

    #[test]
    fn filters_read_from_toml() {
        let n: FilterSpec =
            toml::from_str("kind = \"notch\"\ncenter_hz = 40.0\ndepth_db = 20.0\nwidth_hz = 20.0")
                .unwrap();
        assert_eq!(
            n,
            FilterSpec::Notch {
                center_hz: 40.0,
                depth_db: 20.0,
                width_hz: 20.0
            }
        );
        let l: FilterSpec = toml::from_str("kind = \"low_pass2\"\ncorner_hz = 300.0").unwrap();
        assert!(
            matches!(l, FilterSpec::LowPass2 { damping, .. } if (damping - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12)
        );
        assert!(toml::from_str::<FilterSpec>(
            "kind = \"notch\"\ncenter_hz = 40.0\ndepth = 20.0\nwidth_hz = 5.0"
        )
        .is_err());
    }
}
