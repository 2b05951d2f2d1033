//! Pointing metrics over a window, for simulated and measured records alike.
//! Bottom layer: imports nothing of this crate.
//!
//! One streaming routine ([`MetricsAccumulator`], or [`compute_metrics`] over an iterator)
//! so a simulation that keeps no time series and a bench log read from disk are judged
//! the same way. Samples are assumed uniformly spaced in time (fractions are sample
//! fractions).

pub mod limit_cycle;
pub mod los;

use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

/// One sample of a record.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t_s: f64,
    /// Desired output angle, rad.
    pub reference_rad: f64,
    /// Output angle (simulated, or output encoder), rad.
    pub output_rad: f64,
    /// Transmission error `theta_out - theta_in/ic`, rad, when both angles are known.
    pub transmission_error_rad: Option<f64>,
    /// Motor command (A or V), when known.
    pub command: Option<f64>,
    /// Motor current, A, when known.
    pub current_a: Option<f64>,
}

/// A step of the reference, judged for rise, overshoot and settling.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepEvent {
    /// Instant of the step, s.
    pub time_s: f64,
    /// Level before, rad.
    pub from_rad: f64,
    /// Level after, rad.
    pub to_rad: f64,
}

/// What to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct MetricsConfig {
    /// Samples before this time are ignored (start-up), s.
    pub window_start_s: f64,
    /// Samples after this time are ignored, s (`f64::INFINITY` for all).
    pub window_end_s: f64,
    /// Pointing requirement, mrad (0.1).
    pub target_mrad: f64,
    /// Settling band around the new level, mrad (usually the target).
    pub settle_band_mrad: f64,
    /// Reference steps to judge (those starting inside the window are used); each is
    /// judged until the next one.
    pub steps: Vec<StepEvent>,
}

/// Step response figures.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepMetrics {
    /// The step.
    pub step: StepEvent,
    /// Time from 10 % to 90 % of the step, s; `None` if 90 % was never reached.
    pub rise_time_s: Option<f64>,
    /// Largest excursion beyond the new level, percent of the step (0 if none).
    pub overshoot_percent: f64,
    /// Time from the step until the output enters the band for the last time (last exit
    /// from the band); `None` = did not settle before the next step or the end.
    pub settling_time_s: Option<f64>,
    /// Largest absolute error from the new level, from settling until the next step or
    /// the end, mrad; `None` if the step did not settle.
    #[serde(default)]
    pub error_after_settling_peak_mrad: Option<f64>,
    /// RMS pointing error over the same stretch, mrad; `None` if the step did not settle.
    #[serde(default)]
    pub error_after_settling_rms_mrad: Option<f64>,
    /// Absolute error from the new level at the step's last sample (before the next step
    /// or at the end), mrad: how far off a step that did not settle was left standing.
    #[serde(default)]
    pub final_error_mrad: f64,
    /// The stare after this step passes: the step settled and its error after settling
    /// stayed within the target until the next step (or the end).
    #[serde(default)]
    pub passes_target: bool,
}

/// How a record is judged against the target.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Criterion {
    /// Peak pointing error over the whole window (a moving reference).
    #[default]
    Tracking,
    /// Error after settling of every step (a reference that jumps and stares): the jumps
    /// themselves are not errors, a step that does not settle fails.
    Steps,
}

/// The steps of a record taken together (the worst of each figure).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepSummary {
    /// Steps judged (those starting inside the window).
    pub judged: u64,
    /// Steps that settled into the band before the next step or the end.
    pub settled: u64,
    /// Largest overshoot, percent of the step.
    pub max_overshoot_percent: f64,
    /// Longest 10-90 % rise time, s; `None` if some step never reached 90 %.
    pub max_rise_time_s: Option<f64>,
    /// Longest settling time, s; `None` if some step did not settle.
    pub worst_settling_time_s: Option<f64>,
    /// Largest absolute pointing error after settling over the steps that settled, mrad;
    /// `None` if none did.
    pub error_after_settling_peak_mrad: Option<f64>,
    /// Largest per-step RMS pointing error after settling over the steps that settled,
    /// mrad; `None` if none did.
    pub error_after_settling_rms_mrad: Option<f64>,
    /// Largest absolute error at the end of a step, mrad.
    pub max_final_error_mrad: f64,
    /// Every step settled and its error after settling stays within the target.
    pub passes_target: bool,
}

/// Metrics of one record.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Samples inside the window.
    pub samples: u64,
    /// First and last sample time inside the window, s (0 when empty).
    pub window_s: [f64; 2],
    /// RMS of the pointing error `theta_out - r_out`, mrad.
    pub rms_mrad: f64,
    /// Largest absolute pointing error, mrad.
    pub peak_mrad: f64,
    /// 95th percentile of the absolute pointing error (nearest rank, resolved to 0.12 %),
    /// mrad.
    pub p95_mrad: f64,
    /// Fraction of samples with `|error| <= target_mrad`.
    pub within_target_fraction: f64,
    /// Requirement used, mrad.
    pub target_mrad: f64,
    /// Whether the record meets the target (and the window is not empty): under
    /// [`Criterion::Tracking`] the peak error stays within it, under [`Criterion::Steps`]
    /// every step settles and its error after settling stays within it.
    pub passes_target: bool,
    /// Which of the two judgements `passes_target` is: steps when the window holds a
    /// reference step, tracking otherwise.
    #[serde(default)]
    pub criterion: Criterion,
    /// Largest absolute transmission error, mrad (`None` if not recorded).
    pub peak_transmission_error_mrad: Option<f64>,
    /// RMS motor command, A or V (`None` if not recorded).
    pub rms_command: Option<f64>,
    /// RMS motor current, A (`None` if not recorded).
    pub rms_current_a: Option<f64>,
    /// Step responses judged.
    pub steps: Vec<StepMetrics>,
    /// Longest settling time over the steps, s; `None` if any step did not settle or
    /// there were none (see `all_steps_settled`).
    pub worst_settling_time_s: Option<f64>,
    /// Whether every judged step settled.
    pub all_steps_settled: bool,
    /// The steps taken together; `None` when no step was judged.
    #[serde(default)]
    pub step_summary: Option<StepSummary>,
}

const DECADES_LO: f64 = -9.0;
const DECADES: usize = 15;
const BINS_PER_DECADE: usize = 2000;

#[derive(Clone, Debug)]
struct StepTrack {
    ev: StepEvent,
    end_s: f64,
    t10: Option<f64>,
    t90: Option<f64>,
    overshoot: f64,
    settle_at: Option<f64>,
    /// Since `settle_at`: peak |pointing error| (mrad), sum of squares, samples.
    after_peak: f64,
    after_sq: f64,
    after_n: u64,
    last_error_mrad: f64,
    seen: bool,
}

/// Streaming metrics: push samples in time order, then [`MetricsAccumulator::finish`].
#[derive(Clone, Debug)]
pub struct MetricsAccumulator {
    cfg: MetricsConfig,
    n: u64,
    first_t: f64,
    last_t: f64,
    sum_sq: f64,
    peak: f64,
    within: u64,
    hist: Vec<u32>,
    zeros: u64,
    last_bin: BinRange,
    te_peak: Option<f64>,
    cmd_sq: Option<f64>,
    cur_sq: Option<f64>,
    cmd_n: u64,
    cur_n: u64,
    steps: Vec<StepTrack>,
}

#[inline]
fn bin_of(v_mrad: f64) -> Option<usize> {
    if v_mrad < 10f64.powf(DECADES_LO) {
        return None;
    }
    // The saturating cast floors non-negative values and sends negative ones to 0, as
    // `floor` then `max(0)` would; without SSE4.1 `floor` is a library call.
    let b = (v_mrad.log10() - DECADES_LO) * BINS_PER_DECADE as f64;
    Some((b as usize).min(DECADES * BINS_PER_DECADE - 1))
}

fn bin_upper(b: usize) -> f64 {
    10f64.powf(DECADES_LO + (b + 1) as f64 / BINS_PER_DECADE as f64)
}

/// Relative distance from a bin's edges inside which [`bin_of`] is certain without its
/// logarithm: 1e-9 is about 1e-6 of a bin, some 1e5 times the last-place error of any
/// usable `log10` (and of the edges below), and costs a negligible share of the hits.
const EDGE_MARGIN: f64 = 1e-9;

/// Lower edge of bin `b` (mrad) to a few ulp, from one table of a decade's edges and one
/// of the decades' powers of ten (a closed-loop run looks edges up whenever the error moves
/// to another bin, up to once per sample).
fn bin_lower(b: usize) -> f64 {
    struct Edges {
        mantissa: Vec<f64>,
        decade: Vec<f64>,
    }
    static EDGES: OnceLock<Edges> = OnceLock::new();
    let e = EDGES.get_or_init(|| Edges {
        mantissa: (0..BINS_PER_DECADE)
            .map(|j| 10f64.powf(j as f64 / BINS_PER_DECADE as f64))
            .collect(),
        decade: (0..=DECADES)
            .map(|d| 10f64.powi(d as i32 + DECADES_LO as i32))
            .collect(),
    });
    e.mantissa[b % BINS_PER_DECADE] * e.decade[(b / BINS_PER_DECADE).min(DECADES)]
}

/// A histogram bin and the values (mrad) that surely fall into it.
#[derive(Clone, Copy, Debug)]
struct BinRange {
    bin: usize,
    lo: f64,
    hi: f64,
}

impl BinRange {
    const EMPTY: BinRange = BinRange {
        bin: 0,
        lo: f64::INFINITY,
        hi: f64::NEG_INFINITY,
    };

    fn around(bin: usize) -> Self {
        let last = DECADES * BINS_PER_DECADE - 1;
        BinRange {
            bin,
            // Below the first edge values count as zeros before a range is consulted,
            // above the last they are clamped into the last bin.
            lo: if bin == 0 {
                0.0
            } else {
                bin_lower(bin) * (1.0 + EDGE_MARGIN)
            },
            hi: if bin == last {
                f64::INFINITY
            } else {
                bin_lower(bin + 1) * (1.0 - EDGE_MARGIN)
            },
        }
    }

    #[inline]
    fn holds(&self, v_mrad: f64) -> bool {
        v_mrad >= self.lo && v_mrad < self.hi
    }
}

impl MetricsAccumulator {
    /// Empty accumulator.
    pub fn new(cfg: MetricsConfig) -> Self {
        let mut evs: Vec<StepEvent> = cfg
            .steps
            .iter()
            .copied()
            .filter(|e| e.time_s >= cfg.window_start_s && e.to_rad != e.from_rad)
            .collect();
        evs.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        let steps = evs
            .iter()
            .enumerate()
            .map(|(i, ev)| StepTrack {
                ev: *ev,
                end_s: evs.get(i + 1).map_or(f64::INFINITY, |n| n.time_s),
                t10: None,
                t90: None,
                overshoot: 0.0,
                settle_at: None,
                after_peak: 0.0,
                after_sq: 0.0,
                after_n: 0,
                last_error_mrad: 0.0,
                seen: false,
            })
            .collect();
        MetricsAccumulator {
            cfg,
            n: 0,
            first_t: 0.0,
            last_t: 0.0,
            sum_sq: 0.0,
            peak: 0.0,
            within: 0,
            hist: vec![0; DECADES * BINS_PER_DECADE],
            zeros: 0,
            last_bin: BinRange::EMPTY,
            te_peak: None,
            cmd_sq: None,
            cur_sq: None,
            cmd_n: 0,
            cur_n: 0,
            steps,
        }
    }

    /// Add one sample (in time order). Non-finite values are skipped.
    #[inline]
    pub fn push(&mut self, s: &Sample) {
        if !(s.t_s >= self.cfg.window_start_s && s.t_s <= self.cfg.window_end_s) {
            return;
        }
        let err = (s.output_rad - s.reference_rad) * 1e3;
        if !err.is_finite() {
            return;
        }
        if self.n == 0 {
            self.first_t = s.t_s;
        }
        self.n += 1;
        self.last_t = s.t_s;
        let a = err.abs();
        self.sum_sq += err * err;
        self.peak = self.peak.max(a);
        if a <= self.cfg.target_mrad {
            self.within += 1;
        }
        if a < 10f64.powf(DECADES_LO) {
            self.zeros += 1;
        } else {
            let b = if self.last_bin.holds(a) {
                self.last_bin.bin
            } else {
                self.rebin(a)
            };
            self.hist[b] += 1;
        }
        if let Some(te) = s.transmission_error_rad.filter(|v| v.is_finite()) {
            self.te_peak = Some(self.te_peak.unwrap_or(0.0).max(te.abs() * 1e3));
        }
        if let Some(c) = s.command.filter(|v| v.is_finite()) {
            *self.cmd_sq.get_or_insert(0.0) += c * c;
            self.cmd_n += 1;
        }
        if let Some(c) = s.current_a.filter(|v| v.is_finite()) {
            *self.cur_sq.get_or_insert(0.0) += c * c;
            self.cur_n += 1;
        }
        if !self.steps.is_empty() {
            self.push_steps(s);
        }
    }

    /// Bin of `a` (mrad, at least the lowest edge) when it left the last one. Successive
    /// errors mostly stay in a bin or move to a neighbour, which needs no logarithm.
    #[inline(never)]
    fn rebin(&mut self, a: f64) -> usize {
        let b = self.last_bin.bin;
        let last = DECADES * BINS_PER_DECADE - 1;
        let near = [
            (b < last && a >= self.last_bin.hi).then(|| b + 1),
            (b > 0 && a < self.last_bin.lo).then(|| b - 1),
        ];
        for r in near.into_iter().flatten().map(BinRange::around) {
            if r.holds(a) {
                self.last_bin = r;
                return r.bin;
            }
        }
        // Near an edge `a` may lie outside its bin's sure range: counted by the
        // logarithm all the same.
        let exact = bin_of(a).unwrap_or(0);
        self.last_bin = BinRange::around(exact);
        exact
    }

    // Kept out of line so the common case (no steps) inlines into the caller's loop.
    #[inline(never)]
    fn push_steps(&mut self, s: &Sample) {
        let band = self.cfg.settle_band_mrad * 1e-3;
        for st in self
            .steps
            .iter_mut()
            .filter(|st| s.t_s >= st.ev.time_s && s.t_s < st.end_s)
        {
            st.seen = true;
            let span = st.ev.to_rad - st.ev.from_rad;
            let progress = (s.output_rad - st.ev.from_rad) / span;
            if st.t10.is_none() && progress >= 0.1 {
                st.t10 = Some(s.t_s);
            }
            if st.t90.is_none() && progress >= 0.9 {
                st.t90 = Some(s.t_s);
            }
            st.overshoot = st.overshoot.max((progress - 1.0) * 100.0);
            st.last_error_mrad = (s.output_rad - st.ev.to_rad).abs() * 1e3;
            if (s.output_rad - st.ev.to_rad).abs() <= band {
                st.settle_at.get_or_insert(s.t_s);
                // From the step's own level: a sample on the next step's instant may
                // already carry the next reference but still belongs to this step.
                let e = (s.output_rad - st.ev.to_rad) * 1e3;
                st.after_peak = st.after_peak.max(e.abs());
                st.after_sq += e * e;
                st.after_n += 1;
            } else {
                // An exit restarts both the settling time and the error after settling.
                st.settle_at = None;
                st.after_peak = 0.0;
                st.after_sq = 0.0;
                st.after_n = 0;
            }
        }
    }

    /// The metrics. An empty window gives zeros and `passes_target = false`.
    pub fn finish(self) -> Metrics {
        let n = self.n;
        let p95 = if n == 0 {
            0.0
        } else {
            let rank = ((0.95 * n as f64).ceil() as u64).max(1);
            if rank <= self.zeros {
                0.0
            } else {
                let mut cum = self.zeros;
                let mut v = self.peak;
                for (b, &c) in self.hist.iter().enumerate() {
                    cum += u64::from(c);
                    if cum >= rank {
                        v = bin_upper(b).min(self.peak);
                        break;
                    }
                }
                v
            }
        };
        let steps: Vec<StepMetrics> = self
            .steps
            .iter()
            .filter(|st| st.seen)
            .map(|st| StepMetrics {
                step: st.ev,
                rise_time_s: match (st.t10, st.t90) {
                    (Some(a), Some(b)) => Some(b - a),
                    _ => None,
                },
                overshoot_percent: st.overshoot.max(0.0),
                settling_time_s: st.settle_at.map(|t| t - st.ev.time_s),
                error_after_settling_peak_mrad: st.settle_at.map(|_| st.after_peak),
                error_after_settling_rms_mrad: st
                    .settle_at
                    .map(|_| (st.after_sq / st.after_n.max(1) as f64).sqrt()),
                final_error_mrad: st.last_error_mrad,
                passes_target: st.settle_at.is_some() && st.after_peak <= self.cfg.target_mrad,
            })
            .collect();
        let step_summary = summarize_steps(&steps, self.cfg.target_mrad);
        let all_settled = steps.iter().all(|s| s.settling_time_s.is_some());
        let worst = if all_settled {
            steps
                .iter()
                .filter_map(|s| s.settling_time_s)
                .reduce(f64::max)
        } else {
            None
        };
        let rms =
            |sq: Option<f64>, k: u64| sq.map(|s| if k > 0 { (s / k as f64).sqrt() } else { 0.0 });
        Metrics {
            samples: n,
            window_s: [self.first_t, self.last_t],
            rms_mrad: if n > 0 {
                (self.sum_sq / n as f64).sqrt()
            } else {
                0.0
            },
            peak_mrad: self.peak,
            p95_mrad: p95,
            within_target_fraction: if n > 0 {
                self.within as f64 / n as f64
            } else {
                0.0
            },
            target_mrad: self.cfg.target_mrad,
            passes_target: n > 0
                && match &step_summary {
                    Some(sum) => sum.passes_target,
                    None => self.peak <= self.cfg.target_mrad,
                },
            criterion: if step_summary.is_some() {
                Criterion::Steps
            } else {
                Criterion::Tracking
            },
            peak_transmission_error_mrad: self.te_peak,
            rms_command: rms(self.cmd_sq, self.cmd_n),
            rms_current_a: rms(self.cur_sq, self.cur_n),
            steps,
            worst_settling_time_s: worst,
            all_steps_settled: all_settled,
            step_summary,
        }
    }
}

/// The worst of each step figure; `None` without steps.
fn summarize_steps(steps: &[StepMetrics], target_mrad: f64) -> Option<StepSummary> {
    if steps.is_empty() {
        return None;
    }
    // `None` as soon as one step lacks the figure: a missing rise or settling is the
    // worst case, not one to skip.
    let worst = |f: &dyn Fn(&StepMetrics) -> Option<f64>| {
        steps
            .iter()
            .map(f)
            .try_fold(0.0f64, |acc, v| v.map(|v| acc.max(v)))
    };
    let settled = steps.iter().filter(|s| s.settling_time_s.is_some()).count() as u64;
    let settled_worst =
        |f: &dyn Fn(&StepMetrics) -> Option<f64>| steps.iter().filter_map(f).reduce(f64::max);
    let peak_after = settled_worst(&|s| s.error_after_settling_peak_mrad);
    Some(StepSummary {
        judged: steps.len() as u64,
        settled,
        max_overshoot_percent: steps
            .iter()
            .map(|s| s.overshoot_percent)
            .fold(0.0, f64::max),
        max_rise_time_s: worst(&|s| s.rise_time_s),
        worst_settling_time_s: worst(&|s| s.settling_time_s),
        error_after_settling_peak_mrad: peak_after,
        error_after_settling_rms_mrad: settled_worst(&|s| s.error_after_settling_rms_mrad),
        max_final_error_mrad: steps.iter().map(|s| s.final_error_mrad).fold(0.0, f64::max),
        passes_target: settled == steps.len() as u64
            && peak_after.is_some_and(|p| p <= target_mrad),
    })
}

/// Metrics of a whole record.
pub fn compute_metrics<'a>(
    samples: impl IntoIterator<Item = &'a Sample>,
    cfg: &MetricsConfig,
) -> Metrics {
    let mut acc = MetricsAccumulator::new(cfg.clone());
    for s in samples {
        acc.push(s);
    }
    acc.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(start: f64) -> MetricsConfig {
        MetricsConfig {
            window_start_s: start,
            window_end_s: f64::INFINITY,
            target_mrad: 0.1,
            settle_band_mrad: 0.1,
            steps: vec![],
        }
    }

    fn rec(errors_mrad: &[f64]) -> Vec<Sample> {
        errors_mrad
            .iter()
            .enumerate()
            .map(|(i, e)| Sample {
                t_s: i as f64,
                reference_rad: 1.0,
                output_rad: 1.0 + e * 1e-3,
                transmission_error_rad: Some(-e * 2e-3),
                command: Some(if i % 2 == 0 { 3.0 } else { -3.0 }),
                current_a: None,
            })
            .collect()
    }

    #[test]
    fn rms_peak_fraction_by_hand() {
        // Window from t = 1 drops the 5 mrad start-up sample.
        let r = rec(&[5.0, 0.03, -0.04, 0.12, 0.0]);
        let m = compute_metrics(&r, &cfg(1.0));
        assert_eq!(m.samples, 4);
        let rms = ((0.03f64.powi(2) + 0.04f64.powi(2) + 0.12f64.powi(2)) / 4.0).sqrt();
        assert!((m.rms_mrad - rms).abs() < 1e-12, "{}", m.rms_mrad);
        assert!((m.peak_mrad - 0.12).abs() < 1e-12);
        assert!((m.within_target_fraction - 0.75).abs() < 1e-15);
        assert!(!m.passes_target);
        assert!((m.peak_transmission_error_mrad.unwrap() - 0.24).abs() < 1e-12);
        assert!((m.rms_command.unwrap() - 3.0).abs() < 1e-12);
        assert_eq!(m.rms_current_a, None);
        assert_eq!(m.window_s, [1.0, 4.0]);
    }

    #[test]
    fn histogram_bins_match_the_logarithm() {
        // Slow walks, neighbour moves, jumps across decades and values on and next to
        // the edges, each binned through the cached ranges and directly.
        let mut v = vec![0.0, 1e-12, 1e-9, 1e-9 * (1.0 - 1e-16), 1e6, 1e300];
        for b in (0..DECADES * BINS_PER_DECADE).step_by(7) {
            let e = bin_upper(b);
            v.extend([
                e,
                e.next_up(),
                e.next_down(),
                e * (1.0 + 1e-9),
                e * (1.0 - 1e-9),
            ]);
        }
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut a = 0.2;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let u = (x >> 11) as f64 / (1u64 << 53) as f64;
            a = match x % 50 {
                0 => 10f64.powf(14.0 * u - 10.0),
                1..=5 => a * (1.0 + 0.01 * (u - 0.5)),
                _ => a * (1.0 + 1e-4 * (u - 0.5)),
            };
            v.push(a);
        }
        let samples: Vec<Sample> = v
            .iter()
            .enumerate()
            .map(|(i, &e)| Sample {
                t_s: i as f64,
                reference_rad: 0.0,
                output_rad: e * 1e-3,
                ..Sample::default()
            })
            .collect();
        let mut acc = MetricsAccumulator::new(cfg(0.0));
        let mut hist = vec![0u32; DECADES * BINS_PER_DECADE];
        let mut zeros = 0;
        for s in &samples {
            acc.push(s);
            match bin_of(s.output_rad * 1e3) {
                Some(b) => hist[b] += 1,
                None => zeros += 1,
            }
        }
        assert_eq!(acc.zeros, zeros);
        assert!(acc.hist == hist);
    }

    #[test]
    fn p95_nearest_rank() {
        // 100 samples 0.01, 0.02, ..., 1.00 mrad: nearest rank 95 is 0.95.
        let e: Vec<f64> = (1..=100).map(|i| i as f64 * 0.01).collect();
        let m = compute_metrics(&rec(&e), &cfg(0.0));
        assert!((m.p95_mrad / 0.95 - 1.0).abs() < 1.2e-3, "{}", m.p95_mrad);
        assert!((m.peak_mrad - 1.0).abs() < 1e-12);
        // Mostly zeros: p95 is exactly zero.
        let mut z = vec![0.0; 99];
        z.push(0.5);
        assert_eq!(compute_metrics(&rec(&z), &cfg(0.0)).p95_mrad, 0.0);
    }

    #[test]
    fn empty_window_is_not_nan() {
        let m = compute_metrics(&rec(&[0.1, 0.2]), &cfg(10.0));
        assert_eq!(m.samples, 0);
        assert!(!m.passes_target);
        assert_eq!(m.rms_mrad, 0.0);
        assert_eq!(m.p95_mrad, 0.0);
    }

    fn step_record(y: &[f64]) -> Vec<Sample> {
        y.iter()
            .enumerate()
            .map(|(i, v)| Sample {
                t_s: i as f64 * 0.1,
                reference_rad: if i >= 1 { 1e-3 } else { 0.0 },
                output_rad: v * 1e-3,
                ..Sample::default()
            })
            .collect()
    }

    fn step_cfg() -> MetricsConfig {
        MetricsConfig {
            steps: vec![StepEvent {
                time_s: 0.1,
                from_rad: 0.0,
                to_rad: 1e-3,
            }],
            ..cfg(0.0)
        }
    }

    #[test]
    fn step_rise_overshoot_settling_by_hand() {
        // Step of 1 mrad at t = 0.1; band 0.1 mrad.
        // t:   0.0  0.1  0.2  0.3  0.4  0.5  0.6  0.7  0.8
        let y = [0.0, 0.0, 0.05, 0.5, 0.95, 1.2, 0.95, 1.05, 1.0];
        let m = compute_metrics(&step_record(&y), &step_cfg());
        let s = m.steps[0];
        // 10 % first reached at t = 0.3 (0.5), 90 % at 0.4.
        assert!((s.rise_time_s.unwrap() - 0.1).abs() < 1e-12);
        assert!((s.overshoot_percent - 20.0).abs() < 1e-9);
        // Last exit from the band: outside at 0.5 (1.2), inside from 0.6 on.
        assert!((s.settling_time_s.unwrap() - 0.5).abs() < 1e-12);
        assert!(m.all_steps_settled);
        assert!((m.worst_settling_time_s.unwrap() - 0.5).abs() < 1e-12);
        // After settling (t = 0.6 on): errors -0.05, 0.05, 0 mrad; the visit to the band
        // at t = 0.4 before the exit does not count.
        assert!((s.error_after_settling_peak_mrad.unwrap() - 0.05).abs() < 1e-12);
        let rms = (2.0 * 0.05f64.powi(2) / 3.0).sqrt();
        assert!((s.error_after_settling_rms_mrad.unwrap() - rms).abs() < 1e-12);
        // A step record is judged on the error after settling, not on the jump itself.
        assert_eq!(m.criterion, Criterion::Steps);
        assert!(m.peak_mrad > 0.9);
        assert!(m.passes_target);
        let sum = m.step_summary.unwrap();
        assert_eq!((sum.judged, sum.settled), (1, 1));
        assert!((sum.max_overshoot_percent - 20.0).abs() < 1e-9);
    }

    /// First-order response `1 - exp(-t/tau)` to a 1 mrad step, sampled finely: rise time
    /// 10-90 % is `tau ln 9`, settling into +-0.1 mrad (10 %) takes `tau ln 10`, and after
    /// that the error is the decaying exponential itself.
    #[test]
    fn first_order_step_by_hand() {
        let (tau, dt, t0) = (0.01, 1e-5, 0.1);
        let samples: Vec<Sample> = (0..20_001)
            .map(|i| {
                let t = i as f64 * dt;
                let on = t >= t0;
                Sample {
                    t_s: t,
                    reference_rad: if on { 1e-3 } else { 0.0 },
                    output_rad: if on {
                        1e-3 * (1.0 - (-(t - t0) / tau).exp())
                    } else {
                        0.0
                    },
                    ..Sample::default()
                }
            })
            .collect();
        let cfg = MetricsConfig {
            steps: vec![StepEvent {
                time_s: t0,
                from_rad: 0.0,
                to_rad: 1e-3,
            }],
            ..cfg(0.0)
        };
        let m = compute_metrics(&samples, &cfg);
        let s = m.steps[0];
        // Crossings are taken at the first sample past the level: one sample of slack.
        assert!(
            (s.rise_time_s.unwrap() - tau * 9f64.ln()).abs() <= dt,
            "{s:?}"
        );
        assert_eq!(s.overshoot_percent, 0.0);
        let ts = s.settling_time_s.unwrap();
        assert!((ts - tau * 10f64.ln()).abs() <= dt, "{s:?}");
        // Error after settling: exp(-t/tau) mrad from the settling sample to the end.
        let after: Vec<f64> = samples
            .iter()
            .filter(|x| x.t_s >= t0 + ts - 0.5 * dt)
            .map(|x| (x.output_rad - x.reference_rad) * 1e3)
            .collect();
        let rms = (after.iter().map(|e| e * e).sum::<f64>() / after.len() as f64).sqrt();
        let peak = (-ts / tau).exp();
        assert!(peak <= 0.1 && peak > 0.1 * (1.0 - 2.0 * dt / tau));
        assert!((s.error_after_settling_peak_mrad.unwrap() - peak).abs() < 1e-12);
        assert!((s.error_after_settling_rms_mrad.unwrap() / rms - 1.0).abs() < 1e-9);
        assert!(m.passes_target);
        // A tighter requirement than the error after settling fails the same record.
        let strict = compute_metrics(
            &samples,
            &MetricsConfig {
                target_mrad: 0.05,
                settle_band_mrad: 0.1,
                ..cfg.clone()
            },
        );
        assert!(!strict.passes_target);
    }

    #[test]
    fn step_that_ends_outside_did_not_settle() {
        let y = [0.0, 0.0, 0.5, 1.0, 1.0, 0.8];
        let m = compute_metrics(&step_record(&y), &step_cfg());
        assert_eq!(m.steps[0].settling_time_s, None);
        assert_eq!(m.steps[0].error_after_settling_peak_mrad, None);
        assert_eq!(m.steps[0].error_after_settling_rms_mrad, None);
        assert!(!m.all_steps_settled);
        assert_eq!(m.worst_settling_time_s, None);
        // Did not settle: a failure, whatever the errors.
        assert_eq!(m.criterion, Criterion::Steps);
        assert!(!m.passes_target);
        assert!((m.steps[0].final_error_mrad - 0.2).abs() < 1e-12);
        let sum = m.step_summary.unwrap();
        assert_eq!((sum.judged, sum.settled), (1, 0));
        assert!((sum.max_final_error_mrad - 0.2).abs() < 1e-12);
        assert_eq!(sum.worst_settling_time_s, None);
        assert_eq!(sum.error_after_settling_peak_mrad, None);
        // Without steps the record is judged on tracking.
        let m = compute_metrics(&rec(&[0.05, -0.02]), &cfg(0.0));
        assert_eq!((m.criterion, m.step_summary), (Criterion::Tracking, None));
        assert!(m.passes_target);
        // Never reached 90 %: no rise time.
        let m = compute_metrics(&step_record(&[0.0, 0.0, 0.3, 0.5]), &step_cfg());
        assert_eq!(m.steps[0].rise_time_s, None);
    }
}
