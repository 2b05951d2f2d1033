//! Margins of the exact linear reference over every crossing.
//!
//! A loop around a cable drive can cross `|L| = 1` several times (the integrator's low
//! crossover, the cable resonance near a kilohertz) and the negative real axis both with
//! `|L| < 1` and `|L| > 1` (a PID around a double integrator is conditionally stable). Each
//! crossing is listed with its frequency and margin; the worst of each kind is what a
//! design is judged by, and the list says which crossing that was. Stability comes from the
//! closed loop's poles: an unstable loop gets no margins at all, only its pole.

use nalgebra::Complex;
use serde::Serialize;

use super::linear::{Instability, LinearLoop};

/// A frequency where `|L|` crosses 1.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GainCrossover {
    /// Crossover frequency, Hz.
    pub frequency_hz: f64,
    /// Phase margin there, deg: `180 - |arg L|` (35 to 60 for a sound design).
    pub phase_margin_deg: f64,
    /// Which way `|L|` passes 1 as the frequency rises: `down` at the usual crossover,
    /// `up` where a resonance lifts it back above 1.
    pub direction: MagnitudeSlope,
}

/// Which way `|L|` passes 1 at a gain crossover, frequency rising.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MagnitudeSlope {
    /// From above 1 to below.
    Down,
    /// From below 1 to above.
    Up,
}

/// Which way the loop gain may move before the crossing reaches -1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GainDirection {
    /// `|L| < 1` at the crossing: how far the gain may rise (the classical margin).
    Up,
    /// `|L| > 1` at the crossing: how far the gain may fall (conditionally stable loops).
    Down,
}

impl GainDirection {
    /// `up` or `down`.
    pub fn name(self) -> &'static str {
        match self {
            GainDirection::Up => "up",
            GainDirection::Down => "down",
        }
    }
}

/// A frequency where `L` crosses the negative real axis.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PhaseCrossover {
    /// Crossover frequency, Hz.
    pub frequency_hz: f64,
    /// Gain margin there, dB, in `direction` (6 or more for a sound design).
    pub gain_margin_db: f64,
    /// Whether the gain may rise or fall by that much.
    pub direction: GainDirection,
}

/// Margins, peaks and bandwidth of a stable loop; only the pole of an unstable one.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Margins {
    /// Whether every pole of the sampled closed loop lies inside the unit circle.
    pub stable: bool,
    /// Largest closed-loop pole magnitude (below 1 when stable).
    pub spectral_radius: f64,
    /// The fastest-growing mode of an unstable loop.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub instability: Option<InstabilityRecord>,
    /// Every gain crossover, by frequency (empty for an unstable loop).
    pub gain_crossovers: Vec<GainCrossover>,
    /// Every phase crossover, by frequency (empty for an unstable loop).
    pub phase_crossovers: Vec<PhaseCrossover>,
    /// Worst phase margin over the gain crossovers, deg.
    pub phase_margin_deg: Option<f64>,
    /// Its crossover frequency, Hz.
    pub crossover_hz: Option<f64>,
    /// Worst upward gain margin, dB.
    pub gain_margin_db: Option<f64>,
    /// Its phase crossover frequency, Hz.
    pub phase_crossover_hz: Option<f64>,
    /// Worst downward gain margin, dB.
    pub lower_gain_margin_db: Option<f64>,
    /// Its phase crossover frequency, Hz.
    pub lower_phase_crossover_hz: Option<f64>,
    /// Sensitivity peak `max |S|` (1.3 to 2 for a sound design); `None` when unstable.
    pub ms: Option<f64>,
    /// Frequency of that peak, Hz.
    pub ms_hz: Option<f64>,
    /// Complementary sensitivity peak `max |T|`; `None` when unstable.
    pub mt: Option<f64>,
    /// Closed-loop bandwidth: first frequency where `|T|` falls below -3 dB, Hz.
    pub bandwidth_hz: Option<f64>,
}

/// An unstable loop's fastest mode, as written to results.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct InstabilityRecord {
    /// Largest pole magnitude `|z|` (above 1).
    pub pole_magnitude: f64,
    /// Growth rate, 1/s.
    pub growth_per_s: f64,
    /// Frequency of the mode, Hz (0 for a real pole).
    pub frequency_hz: f64,
}

impl From<Instability> for InstabilityRecord {
    fn from(i: Instability) -> Self {
        InstabilityRecord {
            pole_magnitude: i.pole_magnitude,
            growth_per_s: i.growth_per_s,
            frequency_hz: i.frequency_hz,
        }
    }
}

impl Margins {
    /// The worst gain crossover, with how many there are.
    pub fn worst_gain_crossover(&self) -> Option<&GainCrossover> {
        self.gain_crossovers
            .iter()
            .min_by(|a, b| a.phase_margin_deg.total_cmp(&b.phase_margin_deg))
    }

    /// The worst phase crossover in `direction`.
    pub fn worst_phase_crossover(&self, direction: GainDirection) -> Option<&PhaseCrossover> {
        self.phase_crossovers
            .iter()
            .filter(|c| c.direction == direction)
            .min_by(|a, b| a.gain_margin_db.total_cmp(&b.gain_margin_db))
    }

    /// Every crossing as console lines: `gain crossover 30.1 Hz  PM 62.3 deg`, the worst
    /// of each kind marked.
    pub fn crossing_lines(&self) -> Vec<String> {
        if !self.stable {
            return vec![match self.instability {
                Some(i) => format!(
                    "UNSTABLE: closed-loop pole |z| = {} (a mode growing at {} 1/s at {} Hz): no margins",
                    crate::significant(i.pole_magnitude, 6),
                    crate::significant(i.growth_per_s, 4),
                    crate::significant(i.frequency_hz, 4)
                ),
                None => "UNSTABLE: no margins".into(),
            }];
        }
        let mut out = Vec::new();
        let worst_pm = self.worst_gain_crossover().map(|c| c.frequency_hz);
        for c in &self.gain_crossovers {
            out.push(format!(
                "gain crossover  {:>9} Hz  phase margin {:>6} deg{}",
                crate::significant(c.frequency_hz, 4),
                format!("{:.1}", c.phase_margin_deg),
                if Some(c.frequency_hz) == worst_pm && self.gain_crossovers.len() > 1 {
                    "  (worst)"
                } else {
                    ""
                }
            ));
        }
        if self.gain_crossovers.is_empty() {
            out.push("gain crossover  none: |L| never crosses 1 below Nyquist".into());
        }
        let worst_up = self
            .worst_phase_crossover(GainDirection::Up)
            .map(|c| c.frequency_hz);
        let worst_down = self
            .worst_phase_crossover(GainDirection::Down)
            .map(|c| c.frequency_hz);
        for c in &self.phase_crossovers {
            let worst = match c.direction {
                GainDirection::Up => worst_up,
                GainDirection::Down => worst_down,
            };
            let several = self
                .phase_crossovers
                .iter()
                .filter(|d| d.direction == c.direction)
                .count()
                > 1;
            out.push(format!(
                "phase crossover {:>9} Hz  gain margin {:>6} dB {}{}",
                crate::significant(c.frequency_hz, 4),
                format!("{:.2}", c.gain_margin_db),
                c.direction.name(),
                if several && worst == Some(c.frequency_hz) {
                    "  (worst)"
                } else {
                    ""
                }
            ));
        }
        if self.phase_crossovers.is_empty() {
            out.push("phase crossover none: the phase never reaches -180 deg below Nyquist".into());
        }
        if let (Some(ms), Some(f)) = (self.ms, self.ms_hz) {
            out.push(format!(
                "sensitivity peak Ms {} at {} Hz",
                crate::significant(ms, 4),
                crate::significant(f, 4)
            ));
        }
        out
    }
}

impl LinearLoop {
    /// Margins over every crossing: see [`margins`].
    pub fn margins(&self, points: usize) -> Margins {
        margins(self, points)
    }
}

/// The frequencies the margins are read on, Hz: `points` (at least 10) log-spaced from
/// 0.1 Hz to just below Nyquist.
pub fn margin_grid(lin: &LinearLoop, points: usize) -> Vec<f64> {
    let (lo, hi) = (0.1_f64, lin.nyquist_hz() * 0.9999);
    let points = points.max(10);
    (0..points)
        .map(|i| lo * (hi / lo).powf(i as f64 / (points - 1) as f64))
        .collect()
}

/// `|c|` as the square root of its squared parts: the loop's values lie many decades from
/// where those overflow or underflow, so `hypot`'s guards only cost time, at every one of
/// the grid's points.
#[inline]
fn modulus(c: Complex<f64>) -> f64 {
    (c.re * c.re + c.im * c.im).sqrt()
}

/// Margins of `lin` on `points` log-spaced frequencies from 0.1 Hz to just below Nyquist
/// (2000 is plenty), each crossing refined by bisection.
pub fn margins(lin: &LinearLoop, points: usize) -> Margins {
    let rho = lin.spectral_radius();
    let mut m = Margins {
        stable: rho < 1.0,
        spectral_radius: rho,
        instability: None,
        gain_crossovers: Vec::new(),
        phase_crossovers: Vec::new(),
        phase_margin_deg: None,
        crossover_hz: None,
        gain_margin_db: None,
        phase_crossover_hz: None,
        lower_gain_margin_db: None,
        lower_phase_crossover_hz: None,
        ms: None,
        ms_hz: None,
        mt: None,
        bandwidth_hz: None,
    };
    if !m.stable {
        m.instability = lin.instability().map(InstabilityRecord::from);
        return m;
    }
    let freqs = margin_grid(lin, points);
    let points = freqs.len();
    let l: Vec<Complex<f64>> = freqs.iter().map(|&f| lin.loop_gain(f)).collect();
    let refine = |f0: f64, f1: f64, g: &dyn Fn(f64) -> f64| {
        let (mut a, mut b) = (f0, f1);
        let ga = g(a);
        for _ in 0..60 {
            let m = (a * b).sqrt();
            if (g(m) > 0.0) == (ga > 0.0) {
                a = m;
            } else {
                b = m;
            }
        }
        (a * b).sqrt()
    };
    let mut gain_crossovers = Vec::new();
    let mut phase_crossovers = Vec::new();
    // Each magnitude once: the tests below read each point's twice or more.
    let mag: Vec<f64> = l.iter().map(|&l| modulus(l)).collect();
    for i in 1..points {
        let (l0, l1) = (l[i - 1], l[i]);
        let (m0, m1) = (mag[i - 1], mag[i]);
        if (m0 - 1.0) * (m1 - 1.0) <= 0.0 && m0 != m1 {
            let f = refine(freqs[i - 1], freqs[i], &|f| modulus(lin.loop_gain(f)) - 1.0);
            gain_crossovers.push(GainCrossover {
                frequency_hz: f,
                phase_margin_deg: 180.0 - lin.loop_gain(f).arg().to_degrees().abs(),
                direction: if m1 < m0 {
                    MagnitudeSlope::Down
                } else {
                    MagnitudeSlope::Up
                },
            });
        }
        // Crossing of the negative real axis: the imaginary part changes sign there.
        if l0.im * l1.im <= 0.0 && (l0.re < 0.0 || l1.re < 0.0) && l0.im != l1.im {
            let f = refine(freqs[i - 1], freqs[i], &|f| lin.loop_gain(f).im);
            let lf = lin.loop_gain(f);
            if lf.re < 0.0 {
                let db = 20.0 * lf.norm().log10();
                phase_crossovers.push(PhaseCrossover {
                    frequency_hz: f,
                    gain_margin_db: db.abs(),
                    direction: if db < 0.0 {
                        GainDirection::Up
                    } else {
                        GainDirection::Down
                    },
                });
            }
        }
    }
    // |S| = 1/|1 + L| and |T| = |L|/|1 + L|: one square root and one division a point.
    let (s, t): (Vec<f64>, Vec<f64>) = l
        .iter()
        .zip(&mag)
        .map(|(&l, &m)| {
            let inv = 1.0 / modulus(Complex::from(1.0) + l);
            (inv, m * inv)
        })
        .unzip();
    let half_power = std::f64::consts::FRAC_1_SQRT_2;
    let bandwidth = (1..points)
        .find(|&i| t[i - 1] >= half_power && t[i] < half_power)
        .map(|i| {
            refine(freqs[i - 1], freqs[i], &|f| {
                lin.complementary(f).norm() - half_power
            })
        });
    let (ms_i, ms) =
        s.iter().copied().enumerate().fold(
            (0, 0.0),
            |best, (i, v)| if v > best.1 { (i, v) } else { best },
        );
    m.gain_crossovers = gain_crossovers;
    m.phase_crossovers = phase_crossovers;
    m.ms = Some(ms);
    m.ms_hz = Some(freqs[ms_i]);
    m.mt = Some(t.iter().copied().fold(0.0, f64::max));
    m.bandwidth_hz = bandwidth;
    if let Some(c) = m.worst_gain_crossover().copied() {
        m.phase_margin_deg = Some(c.phase_margin_deg);
        m.crossover_hz = Some(c.frequency_hz);
    }
    if let Some(c) = m.worst_phase_crossover(GainDirection::Up).copied() {
        m.gain_margin_db = Some(c.gain_margin_db);
        m.phase_crossover_hz = Some(c.frequency_hz);
    }
    if let Some(c) = m.worst_phase_crossover(GainDirection::Down).copied() {
        m.lower_gain_margin_db = Some(c.gain_margin_db);
        m.lower_phase_crossover_hz = Some(c.frequency_hz);
    }
    m
}
