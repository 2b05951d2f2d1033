//! Sustained oscillation at rest (hunting): integral action against stiction, or a loop
//! dithering between encoder counts, keeps the output moving while the reference stands
//! still. Judged on every stretch where the reference rests, for simulated and measured
//! records alike.
//!
//! A stretch is kept from the moment the reference stops. When it ends (the reference
//! moves again, or the record ends) its second half (the first holds the step's transient)
//! is judged: zero crossings of the error about its mean, with a hysteresis of a tenth of
//! its half peak-to-peak so noise does not count. It is a limit cycle when at least
//! `min_cycles` whole cycles are found, their periods agree (coefficient of variation
//! below 0.15) and the swing does not die out (the last quarter's peak-to-peak at least
//! 0.8 of the first quarter's). A decaying ring is a settling transient, not a cycle.
//!
//! A periodic error is not a limit cycle when something outside the loop drives it: a
//! stable linear loop under a 5 Hz base motion shows a 5 Hz error at rest. The detector is
//! told the [`Forcing`] (reference, base motion, load torques); an oscillation at a forcing
//! line or one of its harmonics, within the detector's frequency resolution, or inside a
//! broadband forcing's band, is reported as [`LimitCycle::Forced`].

use serde::{Deserialize, Serialize};

/// What was found.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum LimitCycle {
    /// The reference never rested long enough to judge (sine tracking, scans).
    #[default]
    NotJudged,
    /// Rest stretches judged; no sustained oscillation.
    None {
        /// Time at rest judged, s.
        judged_s: f64,
    },
    /// A periodic error at rest at a frequency the loop is driven at (a forcing line or
    /// its harmonic, or inside a broadband forcing): a forced response, not a limit cycle.
    /// Only reported when no stretch holds a real limit cycle.
    Forced {
        /// Half the peak-to-peak pointing error over the cycles, mrad.
        amplitude_mrad: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// What drives it, as users read it: `base motion`, `load sine torque`, ...
        source: String,
    },
    /// A sustained oscillation at rest (the largest one, if several stretches hunt).
    Detected {
        /// Half the peak-to-peak pointing error over the cycles, mrad.
        amplitude_mrad: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// When the regular cycling starts, s.
        start_s: f64,
        /// Whole cycles seen.
        cycles: u32,
    },
}

/// Most harmonics of a forcing line an error is matched against: a linear loop answers
/// a sine at its frequency; the loop's nonlinearities (play, friction) add low harmonics.
pub const MAX_FORCING_HARMONIC: u32 = 10;

/// What drives the loop from outside, so a periodic error at a driven frequency is not
/// taken for a limit cycle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Forcing {
    /// Periodic forcing lines `(frequency Hz, source)`, e.g. `(5.0, "base motion")`.
    pub lines: Vec<(f64, String)>,
    /// Broadband forcing `(lowest Hz, highest Hz, source)` whose lines are not known (a
    /// random PSD motion, a tabulated motion or torque): any error inside the band may be
    /// forced.
    pub bands: Vec<(f64, f64, String)>,
}

impl Forcing {
    /// Whether nothing drives the loop from outside.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty() && self.bands.is_empty()
    }

    /// The source that explains an oscillation at `frequency_hz` measured to within
    /// `resolution_hz`, if any: a line or one of its first [`MAX_FORCING_HARMONIC`]
    /// harmonics, else a band holding it.
    pub fn explains(&self, frequency_hz: f64, resolution_hz: f64) -> Option<&str> {
        let line = self.lines.iter().find(|(f0, _)| {
            *f0 > 0.0
                && (1..=MAX_FORCING_HARMONIC)
                    .any(|k| (frequency_hz - k as f64 * f0).abs() <= resolution_hz)
        });
        if let Some((_, source)) = line {
            return Some(source);
        }
        self.bands
            .iter()
            .find(|(lo, hi, _)| {
                frequency_hz >= lo - resolution_hz && frequency_hz <= hi + resolution_hz
            })
            .map(|(_, _, source)| source.as_str())
    }
}

/// Streaming detector: push every sample in time order, then [`LimitCycleDetector::finish`].
#[derive(Clone, Debug)]
pub struct LimitCycleDetector {
    min_rest_s: f64,
    min_cycles: u32,
    max_samples: usize,
    last_reference: Option<f64>,
    rest: Vec<(f64, f64)>,
    judged_s: f64,
    found: Option<LimitCycle>,
    forcing: Forcing,
    forced: Option<LimitCycle>,
}

impl Default for LimitCycleDetector {
    fn default() -> Self {
        Self::new(0.2, 4, 400_000)
    }
}

impl LimitCycleDetector {
    /// Rest stretches shorter than `min_rest_s` (s) are not judged; a cycle needs
    /// `min_cycles` periods in the judged half; at most `max_samples` of a stretch are
    /// kept (the latest).
    pub fn new(min_rest_s: f64, min_cycles: u32, max_samples: usize) -> Self {
        LimitCycleDetector {
            min_rest_s,
            min_cycles: min_cycles.max(2),
            max_samples: max_samples.max(16),
            last_reference: None,
            rest: Vec::new(),
            judged_s: 0.0,
            found: None,
            forcing: Forcing::default(),
            forced: None,
        }
    }

    /// The same detector told what drives the loop: oscillations at those frequencies
    /// are reported as [`LimitCycle::Forced`].
    pub fn with_forcing(mut self, forcing: Forcing) -> Self {
        self.forcing = forcing;
        self
    }

    /// One sample: time (s), reference and output (rad).
    pub fn push(&mut self, t_s: f64, reference_rad: f64, output_rad: f64) {
        let error_mrad = (output_rad - reference_rad) * 1e3;
        if !(t_s.is_finite() && error_mrad.is_finite()) {
            return;
        }
        if self.last_reference != Some(reference_rad) {
            self.close();
            self.last_reference = Some(reference_rad);
        }
        if self.rest.len() == self.max_samples {
            // Keep the latest half: the end of a long rest is what tells.
            self.rest.drain(..self.max_samples / 2);
        }
        self.rest.push((t_s, error_mrad));
    }

    fn close(&mut self) {
        // Cleared, not replaced: a moving reference closes a stretch at every sample, and
        // the buffer keeps its capacity for the next rest.
        let judged = match (self.rest.first(), self.rest.last()) {
            (Some(first), Some(last)) if last.0 - first.0 >= self.min_rest_s => {
                Some((last.0 - first.0, judge(&self.rest, self.min_cycles)))
            }
            _ => None,
        };
        self.rest.clear();
        let Some((length_s, found)) = judged else {
            return;
        };
        self.judged_s += length_s;
        // A cycle at a driven frequency is the loop's forced response.
        let found = match found {
            Some(LimitCycle::Detected {
                amplitude_mrad,
                frequency_hz,
                cycles,
                ..
            }) => {
                // The frequency is the mean of `cycles` periods: known to about one cycle
                // over the span they cover, and never finer than 2 % (period scatter).
                let span_s = f64::from(cycles.max(1)) / frequency_hz;
                let resolution_hz = (1.0 / span_s).max(0.02 * frequency_hz);
                match self.forcing.explains(frequency_hz, resolution_hz) {
                    Some(source) => {
                        let bigger = match &self.forced {
                            Some(LimitCycle::Forced {
                                amplitude_mrad: a, ..
                            }) => amplitude_mrad > *a,
                            _ => true,
                        };
                        if bigger {
                            self.forced = Some(LimitCycle::Forced {
                                amplitude_mrad,
                                frequency_hz,
                                source: source.to_string(),
                            });
                        }
                        None
                    }
                    None => found,
                }
            }
            other => other,
        };
        if let Some(found) = found {
            let bigger = match (&self.found, &found) {
                (
                    Some(LimitCycle::Detected {
                        amplitude_mrad: a, ..
                    }),
                    LimitCycle::Detected {
                        amplitude_mrad: b, ..
                    },
                ) => b > a,
                _ => true,
            };
            if bigger {
                self.found = Some(found);
            }
        }
    }

    /// The verdict over every rest stretch.
    pub fn finish(mut self) -> LimitCycle {
        self.close();
        match self.found.or(self.forced) {
            Some(found) => found,
            None if self.judged_s > 0.0 => LimitCycle::None {
                judged_s: self.judged_s,
            },
            None => LimitCycle::NotJudged,
        }
    }
}

/// Upward crossings of `x` through its mean with hysteresis `h` (times interpolated).
fn upward_crossings(x: &[(f64, f64)], mean: f64, h: f64) -> Vec<f64> {
    let mut out = Vec::new();
    let mut below = false;
    for w in x.windows(2) {
        let (a, b) = (w[0].1 - mean, w[1].1 - mean);
        if a < -h {
            below = true;
        }
        // Armed once the swing has fallen below -h, counted at the next rise through the
        // mean: noise about the mean cannot count twice.
        if below && a < 0.0 && b >= 0.0 {
            let t = w[0].0 + (w[1].0 - w[0].0) * (-a) / (b - a);
            out.push(t);
            below = false;
        }
    }
    out
}

fn peak_to_peak(x: &[(f64, f64)]) -> f64 {
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.1), hi.max(p.1))
        });
    if hi >= lo {
        hi - lo
    } else {
        0.0
    }
}

fn judge(stretch: &[(f64, f64)], min_cycles: u32) -> Option<LimitCycle> {
    let half = &stretch[stretch.len() / 2..];
    if half.len() < 16 {
        return None;
    }
    let mean = half.iter().map(|p| p.1).sum::<f64>() / half.len() as f64;
    let p2p = peak_to_peak(half);
    if p2p <= 0.0 {
        return None;
    }
    let crossings = upward_crossings(half, mean, 0.05 * p2p);
    if crossings.len() < min_cycles as usize + 1 {
        return None;
    }
    let periods: Vec<f64> = crossings.windows(2).map(|w| w[1] - w[0]).collect();
    let m = periods.iter().sum::<f64>() / periods.len() as f64;
    let var = periods.iter().map(|p| (p - m).powi(2)).sum::<f64>() / periods.len() as f64;
    if var.sqrt() > 0.15 * m {
        return None;
    }
    let q = half.len() / 4;
    let (first, last) = (
        peak_to_peak(&half[..q]),
        peak_to_peak(&half[half.len() - q..]),
    );
    if last < 0.8 * first {
        return None;
    }
    // Where the regular cycling starts: walk back over the whole stretch while the
    // periods stay within 25 % of the mean and the swing within half the final one.
    let all = upward_crossings(stretch, mean, 0.05 * p2p);
    let mut start = crossings[0];
    for w in all.windows(2).rev() {
        if w[1] > crossings[0] {
            continue;
        }
        let period_ok = ((w[1] - w[0]) / m - 1.0).abs() < 0.25;
        let swing = peak_to_peak(
            &stretch
                .iter()
                .copied()
                .filter(|p| p.0 >= w[0] && p.0 <= w[1])
                .collect::<Vec<_>>(),
        );
        if !(period_ok && swing >= 0.5 * p2p) {
            break;
        }
        start = w[0];
    }
    Some(LimitCycle::Detected {
        amplitude_mrad: 0.5 * p2p,
        frequency_hz: 1.0 / m,
        start_s: start,
        cycles: periods.len() as u32,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(f: impl Fn(f64) -> (f64, f64), rate: f64, end: f64) -> LimitCycle {
        let mut d = LimitCycleDetector::default();
        let n = (end * rate) as usize;
        for k in 0..=n {
            let t = k as f64 / rate;
            let (r, y) = f(t);
            d.push(t, r, y);
        }
        d.finish()
    }

    #[test]
    fn a_sustained_oscillation_at_rest_is_found_with_its_frequency_and_start() {
        // Step at 1 s, then a 0.02 mrad, 7 Hz hunt from 2 s.
        let lc = record(
            |t| {
                let r = if t < 1.0 { 0.0 } else { 1e-3 };
                let hunt = if t >= 2.0 {
                    2e-5 * (std::f64::consts::TAU * 7.0 * (t - 2.0)).sin()
                } else {
                    0.0
                };
                (r, r + hunt)
            },
            5000.0,
            6.0,
        );
        match lc {
            LimitCycle::Detected {
                amplitude_mrad,
                frequency_hz,
                start_s,
                ..
            } => {
                assert!((frequency_hz / 7.0 - 1.0).abs() < 0.01, "{frequency_hz}");
                assert!(
                    (amplitude_mrad / 0.02 - 1.0).abs() < 0.02,
                    "{amplitude_mrad}"
                );
                assert!((start_s - 2.0).abs() < 0.2, "{start_s}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_decaying_ring_and_a_moving_reference_are_not_limit_cycles() {
        let ring = record(
            |t| {
                let r = if t < 0.5 { 0.0 } else { 1e-3 };
                let e = if t >= 0.5 {
                    1e-4 * (-(t - 0.5) / 0.3).exp() * (std::f64::consts::TAU * 9.0 * t).sin()
                } else {
                    0.0
                };
                (r, r + e)
            },
            5000.0,
            4.0,
        );
        assert!(matches!(ring, LimitCycle::None { .. }), "{ring:?}");
        let sine = record(
            |t| {
                let r = 1e-2 * (std::f64::consts::TAU * 0.1 * t).sin();
                (r, r + 1e-6 * (std::f64::consts::TAU * 30.0 * t).sin())
            },
            2000.0,
            5.0,
        );
        assert_eq!(sine, LimitCycle::NotJudged);
    }

    fn rest_with_5hz(forcing: Forcing) -> LimitCycle {
        let mut d = LimitCycleDetector::default().with_forcing(forcing);
        for k in 0..=20_000 {
            let t = k as f64 / 5000.0;
            d.push(t, 0.0, 6e-7 * (std::f64::consts::TAU * 5.0 * t).sin());
        }
        d.finish()
    }

    #[test]
    fn an_error_at_a_forcing_frequency_or_its_harmonic_is_forced_not_a_limit_cycle() {
        assert!(matches!(
            rest_with_5hz(Forcing::default()),
            LimitCycle::Detected { .. }
        ));
        let base = Forcing {
            lines: vec![(5.0, "base motion".into())],
            bands: vec![],
        };
        match rest_with_5hz(base) {
            LimitCycle::Forced {
                frequency_hz,
                source,
                ..
            } => {
                assert!((frequency_hz - 5.0).abs() < 0.05, "{frequency_hz}");
                assert_eq!(source, "base motion");
            }
            other => panic!("{other:?}"),
        }
        let sub = Forcing {
            lines: vec![(2.5, "load sine torque".into())],
            bands: vec![],
        };
        assert!(matches!(rest_with_5hz(sub), LimitCycle::Forced { .. }));
        let broadband = Forcing {
            lines: vec![],
            bands: vec![(1.0, 100.0, "base motion (broadband)".into())],
        };
        assert!(matches!(
            rest_with_5hz(broadband),
            LimitCycle::Forced { .. }
        ));
        let elsewhere = Forcing {
            lines: vec![(3.0, "reference".into())],
            bands: vec![(20.0, 100.0, "base motion (broadband)".into())],
        };
        assert!(matches!(
            rest_with_5hz(elsewhere),
            LimitCycle::Detected { .. }
        ));
    }
}
