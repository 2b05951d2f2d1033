//! Time signals: prescribed input motion and closed-loop references.
//! Bottom layer: imports nothing of this crate but the number formatting of messages.
//!
//! A [`Signal`] is evaluated analytically (value, first and second derivative), so feedforward
//! terms are exact; tabulated signals interpolate linearly between samples.

use std::sync::OnceLock;

use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

/// Largest amplitude, offset or slew rate a signal may have (rad, rad/s).
pub const MAX_ANGLE_RAD: f64 = 1e6;

/// A scalar signal of time, in radians for motions and references.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Signal {
    /// `offset + amplitude*sin(2 pi f t + phase)`.
    Sine {
        /// Amplitude, rad (0.1 for the paper bench's input).
        /// Allowed: -1e6 to 1e6.
        amplitude_rad: f64,
        /// Frequency, Hz (0.1 on the bench).
        /// Allowed: >= 0.
        frequency_hz: f64,
        /// Phase at t = 0, rad.
        /// Allowed: any finite number.
        #[serde(default)]
        phase_rad: f64,
        /// Constant offset, rad.
        /// Allowed: -1e6 to 1e6.
        #[serde(default)]
        offset_rad: f64,
    },
    /// Step of `amplitude_rad` at `time_s` (0 before).
    Step {
        /// Step height, rad (e.g. 0.005 for a 5 mrad step-and-stare).
        /// Allowed: -1e6 to 1e6.
        amplitude_rad: f64,
        /// Step time, s.
        /// Allowed: any finite number.
        #[serde(default)]
        time_s: f64,
    },
    /// Repeated step-and-stare: a staircase of `amplitude_rad` steps every `period_s`,
    /// alternating direction after `steps_per_sweep` steps.
    StepStare {
        /// Height of each step, rad.
        /// Allowed: -1e6 to 1e6.
        amplitude_rad: f64,
        /// Dwell between steps, s.
        /// Allowed: > 0.
        period_s: f64,
        /// Steps before the staircase turns back.
        /// Allowed: at least 1.
        /// Unit: steps.
        #[serde(default = "default_steps")]
        steps_per_sweep: u32,
    },
    /// Slew at constant rate from `start_s`, optionally stopping at `stop_s`.
    Ramp {
        /// Rate, rad/s.
        /// Allowed: -1e6 to 1e6.
        rate_rad_s: f64,
        /// Start time, s.
        /// Allowed: any finite number.
        #[serde(default)]
        start_s: f64,
        /// End of the slew, s (holds afterwards).
        /// Allowed: not before `start_s`.
        #[serde(default)]
        stop_s: Option<f64>,
    },
    /// Triangle scan between `-amplitude` and `+amplitude` with rounded turnarounds
    /// (constant acceleration over `turn_fraction` of each half period) so the reference
    /// stays twice differentiable in the mean.
    Triangle {
        /// Amplitude, rad.
        /// Allowed: -1e6 to 1e6.
        amplitude_rad: f64,
        /// Scan frequency, Hz.
        /// Allowed: > 0.
        frequency_hz: f64,
        /// Fraction of each half period spent turning around, [0.001, 1).
        /// Allowed: 0.001 to below 1.
        #[serde(default = "default_turn")]
        turn_fraction: f64,
    },
    /// Sum of several signals.
    Sum {
        /// Components.
        /// Allowed: at least one.
        parts: Vec<Signal>,
    },
    /// Tabulated trajectory (time s, value rad), linear interpolation, held at the ends.
    /// Built from a CSV file by the I/O layer.
    Table {
        /// Path of the CSV file (columns `t_s` and a value column) as given in the scenario.
        /// Allowed: a CSV file, relative to the scenario file's folder.
        path: String,
        /// Name of the value column.
        /// Allowed: a column of that file.
        #[serde(default = "default_table_column")]
        column: String,
        /// Samples, filled by the loader (not part of the file format).
        #[serde(skip)]
        samples: Vec<(f64, f64)>,
    },
    /// Random motion with a given one-sided power spectral density: a sum of sines, one per
    /// logarithmic band between the table's first and last frequency, each at a random
    /// frequency inside its band with a random phase and the amplitude that carries the
    /// band's power (`a = sqrt(2 * integral of S over the band)`), so the motion's variance
    /// equals the integral of the table exactly. A vehicle's angular vibration about one
    /// axis is typically 1e-8 to 1e-6 rad^2/Hz from 1 to 100 Hz.
    Psd {
        /// Rows `[frequency Hz, PSD rad^2/Hz]`, frequencies strictly increasing, PSD > 0;
        /// interpolated linearly in log-log coordinates (straight lines on a PSD plot).
        /// Allowed: at least two rows; frequencies > 0 and strictly increasing; PSD above 0
        /// and at most 1.
        /// Unit: rows of `[Hz, rad^2/Hz]`.
        psd: Vec<[f64; 2]>,
        /// Seed of the random frequencies and phases (the same seed gives the same motion).
        /// Allowed: any whole number from 0.
        #[serde(default = "default_psd_seed")]
        seed: u64,
        /// Number of sines (bands), 10 to 2000 (200 resolves a PSD table to a few percent
        /// per band while costing little per sample).
        /// Allowed: 10 to 2000.
        /// Unit: sines.
        #[serde(default = "default_psd_components")]
        components: u32,
        /// The realised sines, computed on first use from the table and the seed.
        #[serde(skip)]
        realised: OnceLock<Vec<SineComponent>>,
    },
}

/// One sine of a realised random motion: `amplitude * sin(omega t + phase)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SineComponent {
    /// Amplitude, rad.
    pub amplitude_rad: f64,
    /// Angular frequency, rad/s.
    pub omega_rad_s: f64,
    /// Phase at t = 0, rad.
    pub phase_rad: f64,
}

fn default_psd_seed() -> u64 {
    1
}
fn default_psd_components() -> u32 {
    200
}

/// Most sines a PSD realisation may use.
pub const MAX_PSD_COMPONENTS: u32 = 2000;

/// PSD of a table at `f` (Hz), log-log interpolation; 0 outside the table.
pub fn psd_at(table: &[[f64; 2]], f: f64) -> f64 {
    let n = table.len();
    if n == 0 || f < table[0][0] || f > table[n - 1][0] {
        return 0.0;
    }
    let k = table.partition_point(|r| r[0] <= f).clamp(1, n - 1);
    let ([f0, s0], [f1, s1]) = (table[k - 1], table[k]);
    let x = (f / f0).ln() / (f1 / f0).ln();
    (s0.ln() + x * (s1.ln() - s0.ln())).exp()
}

/// Integral of the table's PSD from `fa` to `fb` (Hz), rad^2: exact for the log-log
/// interpolation (a power law on each segment).
pub fn psd_integral(table: &[[f64; 2]], fa: f64, fb: f64) -> f64 {
    let mut total = 0.0;
    for w in table.windows(2) {
        let ([f0, s0], [f1, s1]) = (w[0], w[1]);
        let (a, b) = (fa.max(f0), fb.min(f1));
        if b <= a {
            continue;
        }
        // S = s0 (f/f0)^p on this segment.
        let p = (s1 / s0).ln() / (f1 / f0).ln();
        let q = p + 1.0;
        total += if q.abs() < 1e-12 {
            s0 * f0 * (b / a).ln()
        } else {
            s0 / f0.powf(p) * (b.powf(q) - a.powf(q)) / q
        };
    }
    total
}

/// Sines realising a PSD table: `n` logarithmic bands between its first and last frequency.
pub fn realise_psd(table: &[[f64; 2]], seed: u64, n: u32) -> Vec<SineComponent> {
    let n = n.max(1);
    let Some((first, last)) = table.first().zip(table.last()) else {
        return Vec::new();
    };
    let (lo, hi) = (first[0], last[0]);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|j| {
            let fa = lo * (hi / lo).powf(f64::from(j) / f64::from(n));
            let fb = lo * (hi / lo).powf(f64::from(j + 1) / f64::from(n));
            let f = fa * (fb / fa).powf(rng.gen::<f64>());
            SineComponent {
                amplitude_rad: (2.0 * psd_integral(table, fa, fb)).sqrt(),
                omega_rad_s: std::f64::consts::TAU * f,
                phase_rad: std::f64::consts::TAU * rng.gen::<f64>(),
            }
        })
        .collect()
}

fn default_steps() -> u32 {
    4
}
fn default_turn() -> f64 {
    0.2
}
fn default_table_column() -> String {
    "value".to_string()
}

/// Callback filling a tabulated signal: `(path, column, samples)`.
pub type TableVisitor<'a> = dyn FnMut(&str, &str, &mut Vec<(f64, f64)>) + 'a;

/// Value and derivatives of a signal at one instant.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SignalPoint {
    /// Value, rad.
    pub value: f64,
    /// First time derivative, rad/s.
    pub rate: f64,
    /// Second time derivative, rad/s^2.
    pub accel: f64,
}

impl Signal {
    /// A bound on `|value|` at every time, rad, where one is known without sampling (a
    /// sine: `|offset| + |amplitude|`; a step: `|amplitude|`); `None` for the other kinds.
    /// Every sampled value's magnitude is at most this bound in floating point too, since
    /// `|sin| <= 1` and rounding is monotonic.
    pub fn value_bound(&self) -> Option<f64> {
        let b = match self {
            Signal::Sine {
                amplitude_rad,
                offset_rad,
                ..
            } => offset_rad.abs() + amplitude_rad.abs(),
            Signal::Step { amplitude_rad, .. } => amplitude_rad.abs(),
            _ => return None,
        };
        b.is_finite().then_some(b)
    }

    /// Evaluate at time `t_s`.
    pub fn at(&self, t_s: f64) -> SignalPoint {
        use std::f64::consts::TAU;
        match self {
            Signal::Sine {
                amplitude_rad,
                frequency_hz,
                phase_rad,
                offset_rad,
            } => {
                let w = TAU * frequency_hz;
                let ph = w * t_s + phase_rad;
                SignalPoint {
                    value: offset_rad + amplitude_rad * ph.sin(),
                    rate: amplitude_rad * w * ph.cos(),
                    accel: -amplitude_rad * w * w * ph.sin(),
                }
            }
            Signal::Step {
                amplitude_rad,
                time_s,
            } => SignalPoint {
                value: if t_s >= *time_s { *amplitude_rad } else { 0.0 },
                ..SignalPoint::default()
            },
            Signal::StepStare {
                amplitude_rad,
                period_s,
                steps_per_sweep,
            } => {
                let n = (t_s / period_s).floor().max(0.0) as u64;
                let m = u64::from((*steps_per_sweep).max(1));
                let phase = n % (2 * m);
                let level = if phase <= m { phase } else { 2 * m - phase };
                SignalPoint {
                    value: amplitude_rad * level as f64,
                    ..SignalPoint::default()
                }
            }
            Signal::Ramp {
                rate_rad_s,
                start_s,
                stop_s,
            } => {
                let end = stop_s.unwrap_or(f64::INFINITY);
                let tc = t_s.clamp(*start_s, end.max(*start_s));
                let moving = t_s > *start_s && t_s < end;
                SignalPoint {
                    value: rate_rad_s * (tc - start_s),
                    rate: if moving { *rate_rad_s } else { 0.0 },
                    accel: 0.0,
                }
            }
            Signal::Triangle {
                amplitude_rad,
                frequency_hz,
                turn_fraction,
            } => triangle(*amplitude_rad, *frequency_hz, *turn_fraction, t_s),
            Signal::Sum { parts } => parts.iter().fold(SignalPoint::default(), |acc, p| {
                let q = p.at(t_s);
                SignalPoint {
                    value: acc.value + q.value,
                    rate: acc.rate + q.rate,
                    accel: acc.accel + q.accel,
                }
            }),
            Signal::Table { samples, .. } => table(samples, t_s),
            Signal::Psd { .. } => {
                self.psd_components()
                    .iter()
                    .fold(SignalPoint::default(), |acc, c| {
                        let (s, co) = (c.omega_rad_s * t_s + c.phase_rad).sin_cos();
                        SignalPoint {
                            value: acc.value + c.amplitude_rad * s,
                            rate: acc.rate + c.amplitude_rad * c.omega_rad_s * co,
                            accel: acc.accel - c.amplitude_rad * c.omega_rad_s * c.omega_rad_s * s,
                        }
                    })
            }
        }
    }

    /// The sines of a PSD motion (empty for every other kind), realised on first use.
    pub fn psd_components(&self) -> &[SineComponent] {
        match self {
            Signal::Psd {
                psd,
                seed,
                components,
                realised,
            } => realised.get_or_init(|| realise_psd(psd, *seed, *components)),
            _ => &[],
        }
    }

    /// Check the parameters; returns a description of the first problem.
    pub fn validate(&self) -> Result<(), String> {
        let finite = |name: &str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(format!(
                    "{name} = {}",
                    crate::out_of_range(v, "a finite number")
                ))
            }
        };
        // A period or frequency: finite and above zero.
        let positive = |name: &str, v: f64, what: &str, unit: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!(
                    "{name} = {} must be a finite {what} > 0 {unit}",
                    crate::number(v)
                ))
            }
        };
        // Angles and rates beyond any pointing motion; also keeps derivatives finite.
        let angle = |name: &str, v: f64| {
            finite(name, v)?;
            if v.abs() <= MAX_ANGLE_RAD {
                Ok(())
            } else {
                Err(format!(
                    "{name} = {} is beyond any motion (at most {MAX_ANGLE_RAD:e} in size)",
                    crate::number(v)
                ))
            }
        };
        match self {
            Signal::Sine {
                amplitude_rad,
                frequency_hz,
                phase_rad,
                offset_rad,
            } => {
                angle("amplitude_rad", *amplitude_rad)?;
                finite("phase_rad", *phase_rad)?;
                angle("offset_rad", *offset_rad)?;
                if !(frequency_hz.is_finite() && *frequency_hz >= 0.0) {
                    return Err(format!(
                        "frequency_hz = {} must be a finite frequency >= 0 Hz",
                        crate::number(*frequency_hz)
                    ));
                }
                Ok(())
            }
            Signal::Step {
                amplitude_rad,
                time_s,
            } => {
                angle("amplitude_rad", *amplitude_rad)?;
                finite("time_s", *time_s)
            }
            Signal::StepStare {
                amplitude_rad,
                period_s,
                steps_per_sweep,
            } => {
                angle("amplitude_rad", *amplitude_rad)?;
                positive("period_s", *period_s, "time", "s")?;
                if *steps_per_sweep == 0 {
                    return Err("steps_per_sweep = 0 must be at least 1".into());
                }
                Ok(())
            }
            Signal::Ramp {
                rate_rad_s,
                start_s,
                stop_s,
            } => {
                angle("rate_rad_s", *rate_rad_s)?;
                finite("start_s", *start_s)?;
                if let Some(s) = stop_s {
                    finite("stop_s", *s)?;
                    if s < start_s {
                        return Err(format!(
                            "stop_s = {} must not come before start_s = {}",
                            crate::number(*s),
                            crate::number(*start_s)
                        ));
                    }
                }
                Ok(())
            }
            Signal::Triangle {
                amplitude_rad,
                frequency_hz,
                turn_fraction,
            } => {
                angle("amplitude_rad", *amplitude_rad)?;
                positive("frequency_hz", *frequency_hz, "frequency", "Hz")?;
                if !(*turn_fraction >= 1e-3 && *turn_fraction < 1.0) {
                    return Err(format!(
                        "turn_fraction = {} must be in [0.001, 1)",
                        crate::number(*turn_fraction)
                    ));
                }
                Ok(())
            }
            Signal::Sum { parts } => {
                if parts.is_empty() {
                    return Err("a sum needs at least one part in `parts`".into());
                }
                parts
                    .iter()
                    .enumerate()
                    .try_for_each(|(i, p)| p.validate().map_err(|m| format!("parts[{i}]: {m}")))
            }
            Signal::Table { path, column, .. } => {
                if path.is_empty() || column.is_empty() {
                    Err("a table signal needs a CSV `path` and a value `column`".into())
                } else {
                    Ok(())
                }
            }
            Signal::Psd {
                psd, components, ..
            } => {
                if psd.len() < 2 {
                    return Err(format!(
                        "psd has {} row(s): give at least two rows [frequency_hz, psd_rad2_per_hz]",
                        psd.len()
                    ));
                }
                for (i, [f, v]) in psd.iter().enumerate() {
                    if !(f.is_finite() && *f > 0.0) {
                        return Err(format!(
                            "psd[{i}]: frequency {} Hz must be a finite frequency > 0",
                            crate::number(*f)
                        ));
                    }
                    if !(v.is_finite() && *v > 0.0 && *v <= 1.0) {
                        return Err(format!(
                            "psd[{i}]: {} rad^2/Hz at {} Hz must be positive and at most 1 (a PSD table needs positive values; vehicle vibration is about 1e-8 to 1e-6)",
                            crate::number(*v),
                            crate::number(*f)
                        ));
                    }
                    if i > 0 && *f <= psd[i - 1][0] {
                        return Err(format!(
                            "psd[{i}]: frequency {} Hz must be above the previous row's {} Hz (frequencies strictly increasing)",
                            crate::number(*f),
                            crate::number(psd[i - 1][0])
                        ));
                    }
                }
                if !(10..=MAX_PSD_COMPONENTS).contains(components) {
                    return Err(format!(
                        "components = {components} must be in 10..={MAX_PSD_COMPONENTS}"
                    ));
                }
                Ok(())
            }
        }
    }

    /// Highest frequency the signal repeats at, Hz (sine and triangle frequencies, step-stare
    /// step rate), for checking the sample rate; 0 for signals that do not repeat.
    pub fn fastest_frequency_hz(&self) -> f64 {
        match self {
            Signal::Sine { frequency_hz, .. } | Signal::Triangle { frequency_hz, .. } => {
                *frequency_hz
            }
            Signal::StepStare { period_s, .. } => 1.0 / period_s,
            Signal::Sum { parts } => parts
                .iter()
                .map(Signal::fastest_frequency_hz)
                .fold(0.0, f64::max),
            Signal::Psd { psd, .. } => psd.last().map_or(0.0, |r| r[0]),
            Signal::Step { .. } | Signal::Ramp { .. } | Signal::Table { .. } => 0.0,
        }
    }

    /// Visit every tabulated part as `(path, column, samples)`, so the I/O layer can fill
    /// the samples from files.
    pub fn for_each_table(&mut self, f: &mut TableVisitor<'_>) {
        match self {
            Signal::Table {
                path,
                column,
                samples,
            } => f(path, column, samples),
            Signal::Sum { parts } => parts.iter_mut().for_each(|p| p.for_each_table(f)),
            _ => {}
        }
    }
}

/// Triangle wave with parabolic blends at the turnarounds: each half period the scan runs
/// from one extreme to the other on a trapezoidal speed profile (accelerate over `tb/2`,
/// cruise, decelerate over `tb/2`).
fn triangle(amp: f64, freq: f64, turn: f64, t: f64) -> SignalPoint {
    let half = 0.5 / freq;
    // Shift by a quarter period so the scan starts at 0 moving up, like a sine.
    let tau = (t + 0.5 * half).rem_euclid(2.0 * half);
    let (local, sign) = if tau < half {
        (tau, 1.0)
    } else {
        (tau - half, -1.0)
    };
    let ta = 0.5 * turn * half;
    let v = 2.0 * amp / (half - ta);
    let a = v / ta;
    let (p, r, acc) = if local < ta {
        (0.5 * a * local * local, a * local, a)
    } else if local <= half - ta {
        (0.5 * a * ta * ta + v * (local - ta), v, 0.0)
    } else {
        let s = half - local;
        (2.0 * amp - 0.5 * a * s * s, a * s, -a)
    };
    SignalPoint {
        value: sign * (p - amp),
        rate: sign * r,
        accel: sign * acc,
    }
}

fn table(samples: &[(f64, f64)], t: f64) -> SignalPoint {
    let n = samples.len();
    if n == 0 {
        return SignalPoint::default();
    }
    if t <= samples[0].0 {
        return SignalPoint {
            value: samples[0].1,
            ..SignalPoint::default()
        };
    }
    if t >= samples[n - 1].0 {
        return SignalPoint {
            value: samples[n - 1].1,
            ..SignalPoint::default()
        };
    }
    let k = samples.partition_point(|s| s.0 <= t);
    let (t0, v0) = samples[k - 1];
    let (t1, v1) = samples[k];
    let rate = (v1 - v0) / (t1 - t0);
    SignalPoint {
        value: v0 + rate * (t - t0),
        rate,
        accel: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_derivatives(sig: &Signal, t0: f64, t1: f64) {
        let n = 997;
        for i in 1..n {
            let t = t0 + (t1 - t0) * i as f64 / n as f64;
            let h = 1e-6;
            let p = sig.at(t);
            let num = (sig.at(t + h).value - sig.at(t - h).value) / (2.0 * h);
            assert!(
                (num - p.rate).abs() < 1e-4 * (1.0 + p.rate.abs()),
                "t {t}: {num} vs {}",
                p.rate
            );
        }
    }

    proptest::proptest! {
        /// No sample of a sine or a step exceeds its bound, in floating point, whatever
        /// the signs and sizes: the validation trusts the bound in place of its samples.
        #[test]
        fn no_sample_exceeds_the_bound(
            amplitude in -1e6f64..1e6,
            offset in -1e6f64..1e6,
            frequency in 0.0f64..1e4,
            phase in -10.0f64..10.0,
            t in 0.0f64..1e4,
        ) {
            let sine = Signal::Sine {
                amplitude_rad: amplitude,
                frequency_hz: frequency,
                phase_rad: phase,
                offset_rad: offset,
            };
            let b = sine.value_bound().expect("a sine is bounded");
            proptest::prop_assert!(sine.at(t).value.abs() <= b);
            let step = Signal::Step { amplitude_rad: amplitude, time_s: 1.0 };
            let b = step.value_bound().expect("a step is bounded");
            proptest::prop_assert!(step.at(t).value.abs() <= b);
        }
    }

    /// The bound of a sine that sits exactly on its limit is reached, not exceeded: an
    /// amplitude of 1 at a quarter period.
    #[test]
    fn the_bound_is_reached_at_the_crest() {
        let s = Signal::Sine {
            amplitude_rad: 1.0,
            frequency_hz: 0.25,
            phase_rad: 0.0,
            offset_rad: 99.0,
        };
        assert_eq!(s.value_bound(), Some(100.0));
        assert_eq!(s.at(1.0).value, 100.0);
        assert!(Signal::Ramp {
            rate_rad_s: 1.0,
            start_s: 0.0,
            stop_s: None
        }
        .value_bound()
        .is_none());
    }

    #[test]
    fn sine_derivatives() {
        let s = Signal::Sine {
            amplitude_rad: 0.1,
            frequency_hz: 0.1,
            phase_rad: 0.3,
            offset_rad: 0.0,
        };
        check_derivatives(&s, 0.0, 10.0);
    }

    #[test]
    fn triangle_spans_amplitude_and_is_continuous() {
        let s = Signal::Triangle {
            amplitude_rad: 0.02,
            frequency_hz: 0.5,
            turn_fraction: 0.2,
        };
        check_derivatives(&s, 0.0, 4.0);
        let max = (0..4000)
            .map(|i| s.at(i as f64 * 1e-3).value)
            .fold(f64::MIN, f64::max);
        let min = (0..4000)
            .map(|i| s.at(i as f64 * 1e-3).value)
            .fold(f64::MAX, f64::min);
        assert!(
            (max - 0.02).abs() < 1e-6 && (min + 0.02).abs() < 1e-6,
            "{min} {max}"
        );
        assert!(s.at(0.0).value.abs() < 1e-12);
    }

    fn vehicle_psd() -> Vec<[f64; 2]> {
        vec![[1.0, 1e-7], [10.0, 1e-6], [40.0, 2e-7], [200.0, 1e-9]]
    }

    #[test]
    fn psd_integral_matches_numeric_quadrature() {
        let t = vehicle_psd();
        // Fine trapezoid on a log grid of the interpolated PSD.
        let n = 200_000;
        let (lo, hi) = (2.0_f64, 150.0_f64);
        let mut num = 0.0;
        for i in 0..n {
            let fa = lo * (hi / lo).powf(i as f64 / n as f64);
            let fb = lo * (hi / lo).powf((i + 1) as f64 / n as f64);
            num += 0.5 * (psd_at(&t, fa) + psd_at(&t, fb)) * (fb - fa);
        }
        let exact = psd_integral(&t, lo, hi);
        assert!((num - exact).abs() < 1e-6 * exact, "{num} {exact}");
        // A flat segment integrates to S * width.
        let flat = [[1.0, 2e-6], [5.0, 2e-6]];
        assert!((psd_integral(&flat, 1.0, 5.0) - 8e-6).abs() < 1e-18);
    }

    #[test]
    fn psd_realisation_carries_the_table_variance() {
        let t = vehicle_psd();
        let sig = Signal::Psd {
            psd: t.clone(),
            seed: 7,
            components: 300,
            realised: OnceLock::new(),
        };
        sig.validate().unwrap();
        let var: f64 = sig
            .psd_components()
            .iter()
            .map(|c| 0.5 * c.amplitude_rad * c.amplitude_rad)
            .sum();
        let total = psd_integral(&t, 1.0, 200.0);
        assert!((var - total).abs() < 1e-12 * total, "{var} {total}");
        // Time average of the square over a long record: the same variance within a few
        // percent (the sines are incommensurate, not orthogonal over a finite record).
        let fs = 2000.0;
        let n = 400_000;
        let ms = (0..n)
            .map(|i| sig.at(i as f64 / fs).value.powi(2))
            .sum::<f64>()
            / n as f64;
        assert!((ms / total - 1.0).abs() < 0.05, "{ms} {total}");
        // Derivatives agree with differences.
        check_derivatives(&sig, 0.0, 0.5);
        // Same seed, same motion; another seed, another one.
        let again = sig.clone();
        assert_eq!(again.at(1.234).value, sig.at(1.234).value);
        let other = Signal::Psd {
            psd: t,
            seed: 8,
            components: 300,
            realised: OnceLock::new(),
        };
        assert!(other.at(1.234).value != sig.at(1.234).value);
    }

    #[test]
    fn psd_tables_that_are_not_positive_or_not_increasing_are_refused() {
        let bad = |psd: Vec<[f64; 2]>| {
            Signal::Psd {
                psd,
                seed: 1,
                components: 200,
                realised: OnceLock::new(),
            }
            .validate()
            .unwrap_err()
        };
        assert!(bad(vec![[1.0, 1e-6], [1.0, 1e-6]]).contains("strictly increasing"));
        assert!(bad(vec![[2.0, 1e-6], [1.0, 1e-6]]).contains("psd[1]"));
        assert!(bad(vec![[1.0, 0.0], [2.0, 1e-6]]).contains("positive"));
        assert!(bad(vec![[1.0, -1e-6], [2.0, 1e-6]]).contains("psd[0]"));
        assert!(bad(vec![[1.0, f64::NAN], [2.0, 1e-6]]).contains("psd[0]"));
        assert!(bad(vec![[1.0, 1e-6]]).contains("at least two rows"));
        let toml_psd: Signal = toml::from_str(
            "kind = \"psd\"\npsd = [[1.0, 1e-7], [10.0, 1e-6], [100.0, 1e-8]]\nseed = 3",
        )
        .unwrap();
        toml_psd.validate().unwrap();
    }
}
