//! Stretches of a bench log that are not the drive, kept out of fitting and scoring.
//!
//! Real benches record events the quasi-static drive model has no business explaining: the
//! input spindle jerked by its motor (a rad in a fifth of a second, the output following
//! dynamically), an encoder reading that drops to a wrong value and holds it while the
//! other channel moves on, an input that leaves its commanded motion for a moment, a few
//! output samples far off their neighbours. Fitted as
//! physics, such a stretch of a few hundred milliseconds can outweigh every effect the
//! diagnosis looks for. Each detector judges the log by its own statistics (median and MAD
//! of the quantity it watches) so that encoder quantisation and sensor noise, which set
//! those statistics, never trigger on a clean log; everything is linear in the log length.

use serde::Serialize;

use crate::measurement::BenchLog;

/// Padding added on each side of a flagged stretch, s: covers the detectors' own windows
/// (10 ms differences) and the 25 ms derivative windows of the prepared velocities, so no
/// kept row is computed from a flagged sample.
pub const PAD_S: f64 = 0.05;

/// A departure or a speed beyond this many robust standard deviations (1.4826 MAD) of the
/// log's own input-minus-motion residual is flagged: for Gaussian noise it is never
/// reached, and a smooth structure the motion model misses (harmonics of the spindle's
/// controller) peaks near 1.4 standard deviations.
pub const ROBUST_K: f64 = 10.0;

/// A reading is stuck when it stays exactly constant for at least this long, s, while the
/// other channel moves more than [`STUCK_FACTOR`] times the log's own largest travels
/// through play at its reversals.
pub const STUCK_MIN_S: f64 = 0.1;

/// How many times its own typical deadband travel the other channel must move during a
/// constant reading for the reading to count as stuck.
pub const STUCK_FACTOR: f64 = 4.0;

/// A held reading that still reads noise stays within this many of its noise's robust
/// standard deviations of its first value (two noisy samples differ by 3.5 of their
/// difference's deviations: one sample in about 2000 leaves the band).
pub const STUCK_NOISE_BANDS: f64 = 5.0;

/// An input stretch moving faster than this many times its motion's own peak speed is named
/// a jerk (a held reading, which lags the motion, never reaches 1).
pub const JERK_SPEED: f64 = 1.5;

/// A speed of the input itself (not of its residual from the motion) beyond this many times
/// its own 95th percentile is a jerk, whatever the motion fitted: an input that jumps and
/// stays shifted moves every later sample off the motion family, which then fits neither
/// side and reads the jump as its own scatter. The percentile is that of the motion for any
/// jerk shorter than a twentieth of the log (a sine's is 0.997 of its peak speed).
pub const JERK_SPEED_QUANTILE: f64 = 0.95;

/// Up to [`SPIKE_MAX_SAMPLES`] output samples off the straight path their neighbours agree
/// on, in the output's deviation from the drive's play (the reading less its play operator
/// of the input), all the same way by more than this many encoder steps and by [`ROBUST_K`]
/// robust standard deviations of a sample's deviation from the mean of its two
/// neighbours, are a spike however short: the truth's sensor outliers reach 10 steps, a wrong reading of
/// a millirad on a 2^20-count encoder is 167. A single such sample sets the log's RMS
/// error (3.5 mrad over 3000 samples is 0.064 mrad, ten noise floors).
pub const SPIKE_STEPS: f64 = 30.0;

/// Where the input moves faster than this many times its usual speed (its
/// [`JERK_SPEED_QUANTILE`]), a lasting shift is looked for: lower than [`JERK_SPEED`], since
/// a shift slower than a jerk still bends the motion fitted through both sides (0.7 rad in
/// 0.2 s on a 6.3 rad/s scan had a third of the log flagged as departing). Where there is
/// no shift (a sum of two sines runs up to 1.14 times its usual speed), the stretches
/// between are moved back onto the motion fitted through all of them.
pub const JUMP_SEARCH_SPEED: f64 = 1.2;

/// How much closer the motion must fit the input between its jumps once their lasting
/// shifts are taken out (the robust spread's ratio) for the shifts to be kept.
pub const JUMP_FIT_GAIN: f64 = 0.5;

/// Stretches far off the motion whose peak distance reaches this share of the farthest
/// one's are left out of its fit together; the nearer wait for the refit without them.
pub const TRIM_WORST: f64 = 0.5;

/// Most refits of the motion per share of its amplitude it is trimmed at (the last leaves
/// out every stretch still far off).
pub const TRIM_STAGES: usize = 4;

/// Most refits of the motion through an input whose lasting jumps were taken out.
pub const JUMP_REFITS: usize = 4;

/// Fast runs of the input closer than this, s, are one jump when its lasting shift is
/// read: a jerk and its return cancel.
pub const JUMP_MERGE_S: f64 = 0.3;

/// Length of input on either side of a jump from which its lasting shift is read, s.
pub const JUMP_SIDE_S: f64 = 0.2;

/// Longest spike, samples: longer wrong readings are judged as departures and jumps.
pub const SPIKE_MAX_SAMPLES: usize = 5;

/// How straight the path around a spike must be: the slopes just before and just after it
/// differ from the slope across it by less than this share of the spike's size (over the
/// spike's length), where a kink of the drive differs by about its whole size.
pub const SPIKE_STRAIGHT: f64 = 0.25;

/// A spike on a turn of the input, straight on one account of the drive only, must stand
/// off that account's path by this many times what the log's turns usually show
/// ([`spikes_on_turns`]): the turns of one drive show alike (on 16 truth logs of the
/// gimbal's brake without a spike, a stretch off both accounts and straight on one came
/// to 1.47 times the usual on one turn and was found on no other), spikes of 1.5 to
/// 3 mrad on a turn of the same logs to 3.2 to 8.7 times.
pub const SPIKE_TURN_FACTOR: f64 = 3.0;

/// Samples either side of a turn of the motion within which a spike is judged as on it.
pub const SPIKE_TURN_REACH: usize = 2 * SPIKE_MAX_SAMPLES;

/// How long after a flagged input stretch the output may still be catching up with it, s:
/// output stretches within this (and the padding) of one are not judged.
pub const FOLLOW_S: f64 = 0.1;

/// Shortest run of flagged samples that counts, s (an isolated outlier sample does not).
pub const MIN_RUN_S: f64 = 0.01;

/// Which reading a stretch concerns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Channel {
    /// `theta_in_rad`.
    Input,
    /// `theta_out_rad`.
    Output,
}

impl std::fmt::Display for Channel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Channel::Input => "input",
            Channel::Output => "output",
        })
    }
}

/// Why a stretch is not the drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Reason {
    /// The input moves far faster than its own motion elsewhere in the log (a jerk).
    Jerk,
    /// The input leaves the motion it follows everywhere else.
    Departure,
    /// The reading holds one value while the other channel moves.
    Stuck,
    /// A few samples of the reading far off their neighbours (a glitch of the encoder).
    Spike,
}

impl Reason {
    /// Words for the console, the JSON and the plots' legend.
    pub fn words(self, channel: Channel) -> String {
        match (self, channel) {
            (Reason::Jerk, c) => format!("{c} jerk or jump (faster than its motion ever moves)"),
            (Reason::Departure, Channel::Input) => "input departs from its motion".into(),
            (Reason::Departure, Channel::Output) => {
                "output departs from the input it follows".into()
            }
            (Reason::Stuck, Channel::Input) => "input stuck while output moves".into(),
            (Reason::Stuck, Channel::Output) => "output stuck while input moves".into(),
            (Reason::Spike, c) => format!("{c} spike (samples far off their neighbours)"),
        }
    }
}

/// One stretch of a log that is not the drive.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Segment {
    /// Log source.
    pub log: String,
    /// Reading concerned.
    pub channel: Channel,
    /// Start, in the log's own time (`t_s` column), padding included, s.
    pub start_s: f64,
    /// End, in the log's own time, padding included, s.
    pub end_s: f64,
    /// Why, in words (several reasons joined by `"; "` when stretches merged).
    pub reason: String,
    /// `"excluded"` (rows neither fitted nor scored) or `"kept"` (`--keep-segments`).
    pub action: String,
    /// End of the rows kept out, s (log time): `end_s` for an output reading; for a
    /// stretch of the input, the input's next reversal (or the log's end). A wrong input
    /// reading fed the model's friction memory and cable transport travel the drive did not
    /// see; through a jerk (a radian in a fifth of a second) the drive moved, but by its
    /// dynamics, which the quasi-static replay does not follow. Either way the memory the
    /// replay carries out of the stretch is not the drive's, and only a reversal restarts
    /// it.
    pub excluded_to_s: f64,
}

/// Median of a copy, `O(n)`; 0 for an empty slice.
fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut w = v.to_vec();
    let k = w.len() / 2;
    let (_, m, _) = w.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    *m
}

/// Robust standard deviation (1.4826 MAD) and median.
fn robust(v: &[f64]) -> (f64, f64) {
    let m = median(v);
    let dev: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    (1.4826 * median(&dev), m)
}

/// Shapes of periodic input motion fitted to a log.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Shape {
    Sine,
    Triangle,
    /// A log with under two midline crossings: `c0 + c1 u + c2 u^2` in `u = (t - phase) w`
    /// (the record's middle and inverse half length), the smooth stroke a stretch of any
    /// motion family is over such a short record.
    Stroke,
}

/// The input's own periodic motion: `offset + a sin(w t) + b cos(w t)` for a sine, or
/// `offset + amp tri(w t + phase, turn)` for a triangle.
#[derive(Clone, Copy, Debug)]
struct Motion {
    shape: Shape,
    w: f64,
    c: [f64; 3],
    phase: f64,
    turn: f64,
}

/// Triangle scan of unit amplitude in phase `p` (period 2 pi, rising through 0 at `p = 0`
/// like a sine) whose turnarounds are parabolic over `turn` of each half period: the scan
/// the scenarios' `triangle` motion makes.
fn tri(p: f64, turn: f64) -> f64 {
    let half = std::f64::consts::PI;
    let tau = (p + 0.5 * half).rem_euclid(2.0 * half);
    let (local, sign) = if tau < half {
        (tau, 1.0)
    } else {
        (tau - half, -1.0)
    };
    let ta = 0.5 * turn.max(1e-3) * half;
    let v = 2.0 / (half - ta);
    let a = v / ta;
    let y = if local < ta {
        0.5 * a * local * local
    } else if local <= half - ta {
        0.5 * a * ta * ta + v * (local - ta)
    } else {
        let s = half - local;
        2.0 - 0.5 * a * s * s
    };
    sign * (y - 1.0)
}

impl Motion {
    fn at(&self, t: f64) -> f64 {
        match self.shape {
            Shape::Sine => {
                self.c[0] + self.c[1] * (self.w * t).sin() + self.c[2] * (self.w * t).cos()
            }
            Shape::Triangle => self.c[0] + self.c[1] * tri(self.w * t + self.phase, self.turn),
            Shape::Stroke => {
                let u = (t - self.phase) * self.w;
                self.c[0] + u * (self.c[1] + u * self.c[2])
            }
        }
    }

    /// Amplitude, rad.
    fn amplitude(&self) -> f64 {
        match self.shape {
            Shape::Sine => self.c[1].hypot(self.c[2]),
            Shape::Triangle => self.c[1].abs(),
            // Half the travel over the record (u from -1 to 1).
            Shape::Stroke => self.c[1].abs(),
        }
    }

    /// Largest speed of the motion between consecutive instants of `t`, rad/s.
    fn peak_speed(&self, t: &[f64]) -> f64 {
        t.windows(2)
            .map(|w| ((self.at(w[1]) - self.at(w[0])) / (w[1] - w[0]).max(1e-300)).abs())
            .fold(0.0f64, f64::max)
    }

    /// Phase of the motion's extremes (where the input reverses) after time `t`, s.
    fn next_reversal(&self, t: f64) -> f64 {
        // Extremes of sin(w t + p) are at w t + p = pi/2 + k pi.
        let p = match self.shape {
            Shape::Sine => self.c[2].atan2(self.c[1]),
            Shape::Triangle => self.phase,
            Shape::Stroke => {
                // The parabola's vertex, when it lies ahead; else none in the record.
                let u = -self.c[1] / (2.0 * self.c[2]);
                let at = self.phase + u / self.w;
                return if at.is_finite() && at > t {
                    at
                } else {
                    f64::INFINITY
                };
            }
        };
        let half = std::f64::consts::PI;
        let k = ((self.w * t + p - std::f64::consts::FRAC_PI_2) / half).floor() + 1.0;
        (k * half + std::f64::consts::FRAC_PI_2 - p) / self.w
    }
}

/// Least squares of `y` on the columns `cols` over rows `use_row`, with the SSE.
fn lsq<const N: usize>(
    y: &[f64],
    cols: impl Fn(usize) -> [f64; N],
    rows: &[usize],
) -> Option<([f64; N], f64)> {
    let mut a = [[0.0; N]; N];
    let mut b = [0.0; N];
    for &i in rows {
        let c = cols(i);
        for j in 0..N {
            b[j] += c[j] * y[i];
            for k in 0..N {
                a[j][k] += c[j] * c[k];
            }
        }
    }
    let x = nalgebra::DMatrix::from_fn(N, N, |j, k| a[j][k])
        .lu()
        .solve(&nalgebra::DVector::from_column_slice(&b))?;
    let sse: f64 = rows
        .iter()
        .map(|&i| {
            let c = cols(i);
            let p: f64 = (0..N).map(|k| c[k] * x[k]).sum();
            (y[i] - p).powi(2)
        })
        .sum();
    let mut out = [0.0; N];
    out.copy_from_slice(x.as_slice());
    sse.is_finite().then_some((out, sse))
}

/// The smooth stroke ([`Shape::Stroke`]) of the input on rows `rows`, for a record too
/// short to show a periodic motion.
fn fit_stroke(t: &[f64], x: &[f64], rows: &[usize]) -> Option<Motion> {
    let (t0, t1) = (t[*rows.first()?], t[*rows.last()?]);
    if t1 <= t0 {
        return None;
    }
    let (phase, w) = (0.5 * (t0 + t1), 2.0 / (t1 - t0));
    let (c, _) = lsq(
        x,
        |i| {
            let u = (t[i] - phase) * w;
            [1.0, u, u * u]
        },
        rows,
    )?;
    Some(Motion {
        shape: Shape::Stroke,
        w,
        c,
        phase,
        turn: 0.0,
    })
}

/// Fit the input's periodic motion (sine or triangle, whichever fits better) on rows
/// `rows`; for a record with under two midline crossings its smooth stroke instead when
/// that fits closer; `None` when it does not move.
fn fit_motion(t: &[f64], x: &[f64], rows: &[usize]) -> Option<Motion> {
    if rows.len() < 20 {
        return None;
    }
    let vals: Vec<f64> = rows.iter().map(|&i| x[i]).collect();
    let mid = median(&vals);
    let mut sorted = vals.clone();
    sorted.sort_by(|a, b| a.total_cmp(b));
    let amp = 0.5 * (sorted[sorted.len() * 95 / 100] - sorted[sorted.len() * 5 / 100]);
    if amp <= 0.0 {
        return None;
    }
    // Crossings of the midline with hysteresis of a quarter amplitude give the frequency.
    let band = 0.25 * amp;
    let mut side = 0.0f64;
    let mut crossings = 0usize;
    for v in &vals {
        let s = if *v > mid + band {
            1.0
        } else if *v < mid - band {
            -1.0
        } else {
            0.0
        };
        if s != 0.0 {
            if side != 0.0 && s != side {
                crossings += 1;
            }
            side = s;
        }
    }
    let span = t[*rows.last()?] - t[rows[0]];
    if span <= 0.0 {
        return None;
    }
    // A record with fewer than two crossings may still hold a reversal (one end near the
    // midline): both its smooth stroke and the periodic families are fitted, and the
    // closer one is kept.
    let stroke = if crossings < 2 {
        Some(fit_stroke(t, x, rows)?)
    } else {
        None
    };
    let f0 = crossings.max(1) as f64 / (2.0 * span);
    // A few crossings pin the frequency only loosely: a record of one reversal between
    // two ends at the same height counts two crossings over what may be a fifth of a
    // period. The grid then spans a factor 8 geometrically; with many crossings +-20 %.
    let few = crossings < 6;
    let ratio = 8f64.powf(1.0 / 120.0);
    let grid: Vec<f64> = if few {
        (0..=120).map(|g| 0.25 * f0 * ratio.powi(g)).collect()
    } else {
        (0..=40)
            .map(|g| f0 * (0.8 + 0.4 * f64::from(g) / 40.0))
            .collect()
    };
    // Half the spacing of the grid around a frequency `f`, Hz.
    let grid_step = |f: f64| if few { f * (ratio - 1.0) } else { 0.01 * f0 };
    // The search runs on at most 1000 rows, the residual on all of them.
    let stride = (rows.len() / 1000).max(1);
    let sub: Vec<usize> = rows.iter().step_by(stride).copied().collect();
    let sine = |w: f64| {
        lsq(x, |i| [1.0, (w * t[i]).sin(), (w * t[i]).cos()], &sub).map(|(c, sse)| {
            (
                Motion {
                    shape: Shape::Sine,
                    w,
                    c,
                    phase: 0.0,
                    turn: 0.0,
                },
                sse,
            )
        })
    };
    // Sine: a grid around the crossing estimate, then golden-section refinement.
    let tau = std::f64::consts::TAU;
    let mut grid_best = (f64::INFINITY, f0);
    for &f in &grid {
        if let Some((_, sse)) = sine(tau * f) {
            if sse < grid_best.0 {
                grid_best = (sse, f);
            }
        }
    }
    let step = grid_step(grid_best.1);
    let (mut lo, mut hi) = (grid_best.1 - step, grid_best.1 + step);
    for _ in 0..25 {
        let a = lo + (hi - lo) / 3.0;
        let b = hi - (hi - lo) / 3.0;
        let fa = sine(tau * a).map_or(f64::INFINITY, |r| r.1);
        let fb = sine(tau * b).map_or(f64::INFINITY, |r| r.1);
        if fa < fb {
            hi = b;
        } else {
            lo = a;
        }
    }
    let (s, s_sse) = sine(tau * 0.5 * (lo + hi))?;
    // Triangle: a triangle's fundamental has about its frequency and phase, so it starts
    // from the sine's; turnaround fraction, phase and frequency are then refined in turn.
    let triangle = |w: f64, phase: f64, turn: f64| {
        lsq(x, |i| [1.0, tri(w * t[i] + phase, turn)], &sub).map(|(c2, sse)| {
            (
                Motion {
                    shape: Shape::Triangle,
                    w,
                    c: [c2[0], c2[1], 0.0],
                    phase,
                    turn,
                },
                sse,
            )
        })
    };
    let cost =
        |w: f64, phase: f64, turn: f64| triangle(w, phase, turn).map_or(f64::INFINITY, |r| r.1);
    let sine_phase = |m: &Motion| m.c[2].atan2(m.c[1]);
    let (mut w, mut phase): (f64, f64) = (s.w, sine_phase(&s));
    if few {
        // Over a fraction of a period the sine's frequency is not the triangle's (the
        // sine bends where the triangle runs straight), and a higher frequency with
        // rounder turnarounds can place the next turnaround at the record's ends: the
        // triangle takes its own frequency and turnaround fraction from a grid of both.
        // Its phase at each frequency is the sine's there or, better pinned, the one that
        // puts its extreme at the record's own turning point.
        let apex = interior_extreme(t, x, &sub);
        let mut best = (f64::INFINITY, w, phase);
        for &f in &grid {
            let wg = tau * f;
            let from_sine = sine(wg).map(|(m, _)| sine_phase(&m));
            let from_apex = apex.map(|(ta, top)| {
                let quarter = std::f64::consts::FRAC_PI_2;
                (if top { quarter } else { -quarter }) - wg * ta
            });
            for pg in [from_sine, from_apex].into_iter().flatten() {
                for k in 0..10 {
                    let c = cost(wg, pg, 0.05 + 0.1 * k as f64);
                    if c < best.0 {
                        best = (c, wg, pg);
                    }
                }
            }
        }
        (w, phase) = (best.1, best.2);
    }
    // The turnaround fraction from a coarse grid first: the cost has side minima in it.
    let mut turn = (1..20)
        .map(|k| k as f64 * 0.05)
        .map(|v| (cost(w, phase, v), v))
        .fold((f64::INFINITY, 0.5), |a, b| if b.0 < a.0 { b } else { a })
        .1;
    let mut dw = if few {
        tau * grid_step(w / tau)
    } else {
        0.01 * s.w
    };
    let (mut dp, mut dturn): (f64, f64) = (0.1, 0.05);
    // Over part of a period the frequency trades against the amplitude and turnaround
    // fraction, a valley the turns of this descent cross slowly: more turns, shrinking
    // less.
    let (turns, shrink) = if few { (16, 0.6) } else { (4, 0.3) };
    for _ in 0..turns {
        turn = golden(
            |v| cost(w, phase, v),
            (turn - dturn).max(0.001),
            (turn + dturn).min(0.999),
        );
        phase = golden(|v| cost(w, v, turn), phase - dp, phase + dp);
        // The phase is referred to t = 0: a frequency change turns it about the middle of
        // the record.
        let tm = 0.5 * (t[rows[0]] + t[*rows.last()?]);
        let (w0, p0) = (w, phase);
        w = golden(|v| cost(v, p0 - (v - w0) * tm, turn), w - dw, w + dw);
        phase = p0 - (w - w0) * tm;
        dw *= shrink;
        dp *= shrink;
        dturn *= shrink;
    }
    let (periodic, periodic_sse) = match triangle(w, phase, turn) {
        Some((m, sse)) if sse < s_sse => (m, sse),
        _ => (s, s_sse),
    };
    // Compared on the search's rows, where the periodic fit's error was summed.
    let stroke_sse = |m: &Motion| {
        sub.iter()
            .map(|&i| (x[i] - m.at(t[i])).powi(2))
            .sum::<f64>()
    };
    match stroke {
        Some(st) if stroke_sse(&st) <= periodic_sse => Some(st),
        _ => Some(periodic),
    }
}

/// Time (s) of the input's extreme over rows `rows` when it lies inside the record (at
/// least a tenth of its span from either end), and whether it is the top: where a record
/// of one reversal turns.
fn interior_extreme(t: &[f64], x: &[f64], rows: &[usize]) -> Option<(f64, bool)> {
    let (first, last) = (*rows.first()?, *rows.last()?);
    let margin = 0.1 * (t[last] - t[first]);
    let inside = |i: usize| t[i] - t[first] > margin && t[last] - t[i] > margin;
    let by = |a: &&usize, b: &&usize| x[**a].total_cmp(&x[**b]);
    let top = rows.iter().max_by(by).copied().filter(|i| inside(*i));
    let bottom = rows.iter().min_by(by).copied().filter(|i| inside(*i));
    match (top, bottom) {
        (Some(i), None) => Some((t[i], true)),
        (None, Some(i)) => Some((t[i], false)),
        // Both inside (more than one reversal) or neither (none inside): no single
        // turning point to pin the phase.
        _ => None,
    }
}

/// Minimum of a unimodal `f` on `[lo, hi]` by golden-section search (30 steps).
fn golden(f: impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    let r = 0.5 * (5f64.sqrt() - 1.0);
    let mut a = hi - r * (hi - lo);
    let mut b = lo + r * (hi - lo);
    let (mut fa, mut fb) = (f(a), f(b));
    for _ in 0..30 {
        if fa < fb {
            hi = b;
            b = a;
            fb = fa;
            a = hi - r * (hi - lo);
            fa = f(a);
        } else {
            lo = a;
            a = b;
            fa = fb;
            b = lo + r * (hi - lo);
            fb = f(b);
        }
    }
    0.5 * (lo + hi)
}

/// Runs of `flag` at least `min_len` long, as index ranges (inclusive start, exclusive end).
fn runs(flag: &[bool], min_len: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < flag.len() {
        if flag[i] {
            let a = i;
            while i < flag.len() && flag[i] {
                i += 1;
            }
            if i - a >= min_len {
                out.push((a, i));
            }
        } else {
            i += 1;
        }
    }
    out
}

/// A flagged stretch before padding and merging: (channel, reason, first index, end index).
type Raw = (Channel, Reason, usize, usize);

/// Input stretches that leave the input's own periodic motion: far off it (departure) or
/// far faster (jerk). Returns them with the fitted motion.
fn input_departures(t: &[f64], x: &[f64], q_in: f64, dt: f64) -> (Vec<Raw>, Option<Motion>) {
    let speeds = RawSpeeds::of(t, x, dt);
    let (mut shifted, jumps) = without_lasting_jumps(t, x, &speeds, q_in, dt);
    if !jumps.is_empty() {
        // Read off a short stretch on either side, a shift is off by the motion's
        // curvature there (0.04 rad of a 1.7 rad shift on a 10 rad scan, which the motion
        // fitted after it left as a departure of one side); each stretch between jumps is
        // then moved onto the motion fitted through all of them, a few times over, as the
        // motion fitted through a shifted stretch is bent by it.
        let all: Vec<usize> = (0..t.len()).collect();
        let mut bounds = vec![0];
        for (a, b) in &jumps {
            bounds.extend([*a, *b]);
        }
        bounds.push(t.len());
        let pieces: Vec<(usize, usize)> = bounds.chunks(2).map(|c| (c[0], c[1])).collect();
        for _ in 0..JUMP_REFITS {
            let Some(m) = fit_motion(t, &shifted, &all) else {
                break;
            };
            let r: Vec<f64> = (0..t.len()).map(|i| shifted[i] - m.at(t[i])).collect();
            let first = median(&r[pieces[0].0..pieces[0].1]);
            let mut moved = 0.0f64;
            for &(a, b) in pieces.iter().skip(1) {
                if b > a {
                    let off = median(&r[a..b]) - first;
                    shifted[a..b].iter_mut().for_each(|v| *v -= off);
                    moved = moved.max(off.abs());
                }
            }
            if moved <= q_in {
                break;
            }
        }
        // Kept only where the motion then fits the stretches between the jumps at least
        // twice as close: an input held and then catching up with its motion jumps fast
        // without shifting what follows (a held input's log read 0.135 rad of spread with
        // the catch-up taken out as a shift, 0.141 without, and the rest of the log then
        // departed from the motion).
        let between: Vec<usize> = pieces.iter().flat_map(|&(a, b)| a..b).collect();
        let spread = |y: &[f64]| {
            fit_motion(t, y, &all).map_or(f64::INFINITY, |m| {
                let r: Vec<f64> = between.iter().map(|&i| y[i] - m.at(t[i])).collect();
                robust(&r).0
            })
        };
        if spread(&shifted) >= JUMP_FIT_GAIN * spread(x) {
            shifted = x.to_vec();
        }
    }
    departures_from(t, &speeds, &shifted, q_in, dt)
}

/// The input's own speed as read, rad/s: over the 10 ms window (`2 h` samples) around each
/// sample (the ends one-sided), and its usual value, the [`JERK_SPEED_QUANTILE`].
struct RawSpeeds {
    h: usize,
    speed: Vec<f64>,
    usual: f64,
}

impl RawSpeeds {
    fn of(t: &[f64], x: &[f64], dt: f64) -> Self {
        let n = t.len();
        let h = ((0.01 / dt).round() as usize).max(1);
        let speed: Vec<f64> = (0..n)
            .map(|i| {
                let a = i.saturating_sub(h);
                let b = (i + h).min(n - 1);
                ((x[b] - x[a]) / (t[b] - t[a]).max(1e-300)).abs()
            })
            .collect();
        let mut sorted = speed.clone();
        let k = ((n as f64 * JERK_SPEED_QUANTILE) as usize).min(n.saturating_sub(1));
        let usual = if sorted.is_empty() {
            0.0
        } else {
            *sorted.select_nth_unstable_by(k, |a, b| a.total_cmp(b)).1
        };
        RawSpeeds { h, speed, usual }
    }

    /// Where the speed exceeds `factor` times `usual` (rad/s) plus ten encoder steps
    /// (`q` rad) per window.
    fn above(&self, factor: f64, usual: f64, q: f64, dt: f64) -> Vec<bool> {
        let limit = factor * usual + 10.0 * q / (2.0 * self.h as f64 * dt);
        self.speed.iter().map(|s| *s > limit).collect()
    }
}

/// The input with each lasting jump taken out, and the jumps taken out (index ranges,
/// in time order): where it moves faster than [`JUMP_SEARCH_SPEED`] times its usual speed
/// (runs within [`JUMP_MERGE_S`] joined, so a jerk and its return are one), the shift from
/// before to after, read off one quadratic in time with a step fitted to [`JUMP_SIDE_S`] on
/// either side, is subtracted from every later sample when it exceeds twenty encoder steps
/// and 0.2 % of the input's range. A jump that stays would
/// otherwise put every later sample off the motion fitted before it: the fit then bends
/// through both sides or keeps one, and the other side reads as a departure (a jump near
/// the middle of a 30 s log had the whole first third flagged, and its next reversal read
/// as the log's end).
fn without_lasting_jumps(
    t: &[f64],
    x: &[f64],
    speeds: &RawSpeeds,
    q_in: f64,
    dt: f64,
) -> (Vec<f64>, Vec<(usize, usize)>) {
    let n = t.len();
    let h = speeds.h;
    let fast = speeds.above(JUMP_SEARCH_SPEED, speeds.usual, q_in, dt);
    let merge = ((JUMP_MERGE_S / dt).round() as usize).max(1);
    let mut spans: Vec<(usize, usize)> = Vec::new();
    for (a, b) in runs(&fast, 1) {
        match spans.last_mut() {
            Some(last) if a <= last.1 + merge => last.1 = b,
            _ => spans.push((a, b)),
        }
    }
    let mut out = x.to_vec();
    let mut taken = Vec::new();
    if spans.is_empty() {
        return (out, taken);
    }
    let (lo, hi) = x
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    let least = (20.0 * q_in).max(0.002 * (hi - lo));
    let side = ((JUMP_SIDE_S / dt).round() as usize).max(3);
    for (a, b) in spans {
        // Clear of the jump's slower flanks by as much again as its fast part.
        let margin = (b - a).max(h);
        let (l1, r0) = (a.saturating_sub(margin), (b + margin).min(n));
        let (l0, r1) = (l1.saturating_sub(side), (r0 + side).min(n));
        if l1 - l0 < 3 || r1 - r0 < 3 {
            continue;
        }
        let mid = 0.5 * (t[a] + t[b - 1]);
        let rows: Vec<usize> = (l0..l1).chain(r0..r1).collect();
        let Some((c, _)) = lsq(
            x,
            |i| {
                let tau = t[i] - mid;
                [1.0, tau, tau * tau, if t[i] > mid { 1.0 } else { 0.0 }]
            },
            &rows,
        ) else {
            continue;
        };
        let step = c[3];
        if step.abs() <= least {
            continue;
        }
        for (i, v) in out.iter_mut().enumerate().skip(a) {
            // Through the jump itself a share of the step (those rows are flagged anyway).
            let share = if i >= b {
                1.0
            } else {
                (i + 1 - a) as f64 / (b - a + 1) as f64
            };
            *v -= share * step;
        }
        taken.push((a, b));
    }
    (out, taken)
}

/// [`input_departures`] on `x`, the input with its lasting jumps taken out; `speeds` are
/// those of the input as read, which name jumps.
fn departures_from(
    t: &[f64],
    speeds: &RawSpeeds,
    x: &[f64],
    q_in: f64,
    dt: f64,
) -> (Vec<Raw>, Option<Motion>) {
    let n = t.len();
    let h = ((0.01 / dt).round() as usize).max(1);
    let min_len = ((MIN_RUN_S / dt).round() as usize).max(3);
    let pad = ((PAD_S / dt).round() as usize).max(1);
    let all: Vec<usize> = (0..n).collect();
    let Some(mut m) = fit_motion(t, x, &all) else {
        return (Vec::new(), None);
    };
    let resid = |m: &Motion| -> Vec<f64> { (0..n).map(|i| x[i] - m.at(t[i])).collect() };
    let mut use_row = vec![true; n];
    // Rows far off the motion (beyond a share of its amplitude, 1 % then 0.3 % then
    // 0.1 %, and the robust threshold) are left out of the fit, with their padding, and the
    // motion refitted: a fault then does not bend the motion it is judged against, while
    // the motion's own shape (its turnarounds, which a bent fit also misses, by less) stays
    // in the fit. A refit is kept only when it fits its rows better. The stretches go out
    // worst first ([`TRIM_WORST`], up to [`TRIM_STAGES`] refits a share): a fault bends
    // the fit at every like part of the motion, and left out with it those parts would
    // take the shape they pin out of the refit (an input held across one reversal of a
    // triangle scan, 0.9 to 2 rad off, rounded the fitted turnarounds so that each of the
    // other reversals lay 0.16 to 0.45 rad off; with all of them out the turnaround
    // fraction was left to the ramps, and every reversal read as a departure; taken out
    // alone, the refit found the scan's own 0.2).
    'shares: for share in [0.01, 0.003, 0.001] {
        let mut out = vec![false; n];
        for stage in 0..TRIM_STAGES {
            let r = resid(&m);
            let (sr, mr) = robust(&r);
            let gross = (ROBUST_K * sr).max(share * m.amplitude()).max(10.0 * q_in);
            let far_flag: Vec<bool> = (0..n)
                .map(|i| !out[i] && (r[i] - mr).abs() > gross)
                .collect();
            let far: Vec<(usize, usize, f64)> = runs(&far_flag, 1)
                .into_iter()
                .map(|(a, b)| {
                    let peak = r[a..b].iter().fold(0.0f64, |p, v| p.max((v - mr).abs()));
                    (a, b, peak)
                })
                .collect();
            let Some(worst) = far.iter().map(|f| f.2).reduce(f64::max) else {
                break;
            };
            // The last stage takes whatever is still far.
            let least = if stage + 1 == TRIM_STAGES {
                0.0
            } else {
                TRIM_WORST * worst
            };
            let mut next = out.clone();
            for &(a, b, _) in far.iter().filter(|f| f.2 >= least) {
                for u in &mut next[a.saturating_sub(pad)..(b + pad).min(n)] {
                    *u = true;
                }
            }
            let rows: Vec<usize> = (0..n).filter(|i| !next[*i]).collect();
            let cost = |mm: &Motion| {
                rows.iter()
                    .map(|&i| (x[i] - mm.at(t[i])).powi(2))
                    .sum::<f64>()
            };
            match fit_motion(t, x, &rows) {
                Some(m2) if cost(&m2) <= cost(&m) => {
                    m = m2;
                    use_row = next.iter().map(|o| !o).collect();
                    out = next;
                }
                _ => break 'shares,
            }
        }
    }
    let r = resid(&m);
    let v: Vec<f64> = (0..n)
        .map(|i| {
            let a = i.saturating_sub(h);
            let b = (i + h).min(n - 1);
            (r[b] - r[a]) / (t[b] - t[a]).max(1e-300)
        })
        .collect();
    let kept = |s: &[f64]| -> Vec<f64> {
        s.iter()
            .zip(&use_row)
            .filter(|(_, u)| **u)
            .map(|(v, _)| *v)
            .collect()
    };
    let (sr, mr) = robust(&kept(&r));
    let (sv, mv) = robust(&kept(&v));
    // Floors: ten encoder steps, and the speed one step over the difference window reads,
    // ten times; both far above what quantisation alone can produce. The speed also never
    // judges finer than the position's own scatter read over the window: on a short
    // record whose encoder step cannot be read off its levels, with the motion fitted
    // closely, the speeds' spread reads a smooth fitting error, not the sensor.
    let tr = (ROBUST_K * sr).max(10.0 * q_in).max(1e-12);
    let tv = (ROBUST_K * sv)
        .max(10.0 * q_in / (2.0 * h as f64 * dt))
        .max(ROBUST_K * std::f64::consts::SQRT_2 * sr / (2.0 * h as f64 * dt))
        .max(1e-12);
    // Flagged where the input is far off its motion or far faster than it; named a jerk
    // when it moves faster than the motion itself ever does ([`JERK_SPEED`] times its
    // peak speed), a departure otherwise.
    let flag: Vec<bool> = (0..n)
        .map(|i| (r[i] - mr).abs() > tr || (v[i] - mv).abs() > tv)
        .collect();
    let peak_speed = m.peak_speed(t);
    // The input's own speed against its usual speed: a jump that leaves the input shifted
    // bends the motion fitted through both sides (and so the thresholds above) but not
    // this.
    let jumps = speeds.above(JERK_SPEED, speeds.usual.max(peak_speed), q_in, dt);
    let flag: Vec<bool> = flag.iter().zip(&jumps).map(|(f, j)| *f || *j).collect();
    let found = runs(&flag, min_len)
        .into_iter()
        .map(|(a, b)| {
            let fastest = v[a..b].iter().fold(0.0f64, |p, e| p.max((e - mv).abs()));
            let reason = if fastest > JERK_SPEED * peak_speed || jumps[a..b].contains(&true) {
                Reason::Jerk
            } else {
                Reason::Departure
            };
            (Channel::Input, reason, a, b)
        })
        .collect();
    (found, Some(m))
}

/// Output stretches that are not the drive's response to its input: the output off each
/// of three accounts of the drive, the straight line through output against input
/// (`gain`, rad per rad), a play ([`play_residual`]) and two branches switched at the turn
/// ([`branch_residual`]), by far more than the log's own transmission error spreads about
/// it (a departure); moving faster than [`JERK_SPEED`] times what the input's travel, or
/// the peak speed of its motion `m`, can drive (a jerk or jump); or a few samples off the
/// path of their neighbours on both the play and the branches (a spike, [`spikes_in`]; on
/// a turn of `m`, straight on one of them, [`spikes_on_turns`]). An input jerk the output
/// follows is the drive and is not flagged here.
fn output_departures(
    t: &[f64],
    xi: &[f64],
    xo: &[f64],
    gain: f64,
    q_out: f64,
    dt: f64,
    m: &Motion,
) -> Vec<Raw> {
    let n = t.len();
    let peak_in_speed = m.peak_speed(t);
    let h = ((0.01 / dt).round() as usize).max(1);
    let min_len = ((MIN_RUN_S / dt).round() as usize).max(3);
    let e: Vec<f64> = (0..n).map(|i| xo[i] - gain * xi[i]).collect();
    let (se, me) = robust(&e);
    let te = (ROBUST_K * se).max(10.0 * q_out).max(1e-12);
    // A record of few reversals has most of its samples on one branch of the drive's
    // hysteresis, so the straight line's spread is narrow and the free travel after a
    // reversal reads as a departure; off the drive is off both the line and the play.
    let e_play = play_residual(xi, xo);
    let (sp, mp) = robust(&e_play);
    let tp = (ROBUST_K * sp).max(10.0 * q_out).max(1e-12);
    // Nor is an output that changes branch the moment the input turns: where the load
    // flips with the direction (a brake) the lag flips with it, before the input has
    // moved back through any play.
    let e_branch = branch_residual(xi, xo);
    let (sb, mb) = robust(&e_branch);
    let tb = (ROBUST_K * sb).max(10.0 * q_out).max(1e-12);
    let speed = |x: &[f64], i: usize| {
        let (a, b) = (i.saturating_sub(h), (i + h).min(n - 1));
        (x[b] - x[a]) / (t[b] - t[a]).max(1e-300)
    };
    let floor = 10.0 * q_out / (2.0 * h as f64 * dt);
    // The step into each sample as well: a reading that jumps back and forth every sample
    // (a wrong column, a unit off by a large factor) cancels in the difference over
    // `2 h` samples whenever the jumps pair up across it.
    let step = |i: usize| {
        let j = (i + 1).min(n - 1);
        ((xo[j] - xo[i]) / (t[j] - t[i]).max(1e-300)).abs()
    };
    let step_floor = 10.0 * q_out / dt;
    let fast: Vec<bool> = (0..n)
        .map(|i| {
            let driven = gain * peak_in_speed.max(speed(xi, i).abs());
            speed(xo, i).abs() > JERK_SPEED * driven + floor
                || step(i) > JERK_SPEED * driven + step_floor
        })
        .collect();
    let flag: Vec<bool> = (0..n)
        .map(|i| {
            ((e[i] - me).abs() > te && (e_play[i] - mp).abs() > tp && (e_branch[i] - mb).abs() > tb)
                || fast[i]
        })
        .collect();
    let mut found: Vec<Raw> = runs(&flag, min_len)
        .into_iter()
        .map(|(a, b)| {
            let reason = if fast[a..b].iter().any(|f| *f) {
                Reason::Jerk
            } else {
                Reason::Departure
            };
            (Channel::Output, reason, a, b)
        })
        .collect();
    // Spikes count however short: up to [`SPIKE_MAX_SAMPLES`] samples off the straight
    // path their neighbours on both sides agree on. The drive's own kinks (a brake breaking
    // away at a reversal turns the output within a sample) bend that path, so they are not
    // spikes, however sharp. A spike is off that path on both accounts of the drive (a
    // play, and branches switched at the turn), so a reversal either follows is not one.
    // On a turn the path is straight on the account that follows the drive there and
    // bent on the other, so a spike on it is off that account's kink, not off a straight
    // path: judged there against how the log's other turns show (spikes of 1.5 to 3 mrad
    // on a reversal of sine and triangle scans went unflagged on 13 of 16 truth logs when
    // both accounts had to be straight about them).
    let (on_play, least_play) = spikes_in(&e_play, q_out);
    let (on_branch, least_branch) = spikes_in(&e_branch, q_out);
    let on_turns = spikes_on_turns(
        [
            (e_play.as_slice(), least_play),
            (e_branch.as_slice(), least_branch),
        ],
        &turns_of(m, t, dt),
    );
    let spikes: Vec<bool> = on_play
        .iter()
        .zip(&on_branch)
        .zip(&on_turns)
        .map(|((a, b), c)| (*a && *b) || *c)
        .collect();
    found.extend(
        runs(&spikes, 1)
            .into_iter()
            .map(|(a, b)| (Channel::Output, Reason::Spike, a, b)),
    );
    found
}

/// Samples of residual `e` (rad) that are spikes: up to [`SPIKE_MAX_SAMPLES`] in a row,
/// all off the straight path their neighbours agree on, the same way, by more than
/// [`ROBUST_K`] robust deviations of that offset and [`SPIKE_STEPS`] encoder steps
/// (`q_out`, rad), with the path around them straight ([`SPIKE_STRAIGHT`]). At the log's
/// ends the path is the line through the samples on the one side there is. Also returns
/// that least offset, rad.
fn spikes_in(e: &[f64], q_out: f64) -> (Vec<bool>, f64) {
    let n = e.len();
    let off_neighbours: Vec<f64> = (0..n)
        .map(|i| {
            if i == 0 || i + 1 >= n {
                0.0
            } else {
                e[i] - 0.5 * (e[i - 1] + e[i + 1])
            }
        })
        .collect();
    let (sd, _) = robust(&off_neighbours);
    let ts = (ROBUST_K * sd).max(SPIKE_STEPS * q_out).max(1e-12);
    let mut spikes = vec![false; n];
    for a in 0..n {
        for len in 1..=SPIKE_MAX_SAMPLES {
            let b = a + len;
            if b > n {
                break;
            }
            if off_path(e, a, b)
                .is_some_and(|(smallest, bend)| smallest > ts && straight(smallest, bend))
            {
                spikes[a..b].iter_mut().for_each(|s| *s = true);
            }
        }
    }
    (spikes, ts)
}

/// Whether the path about a stretch off it by `smallest` (rad) bends by little enough
/// (`bend`, rad over the stretch, [`off_path`]) for the stretch to be a spike.
fn straight(smallest: f64, bend: f64) -> bool {
    smallest > 0.0 && bend < SPIKE_STRAIGHT * smallest
}

/// Spikes on a turn of the input (`turns`, the samples nearest the motion's turns, in
/// time order) that the path of their neighbours is straight about on one account of the
/// drive only (`accounts`: the play's and the branches' residuals, rad, each with the
/// least offset of a spike on it, [`spikes_in`]): off both by more than their least
/// offset, and off the straight one by more than [`SPIKE_TURN_FACTOR`] times what the
/// turns usually show. A turn's own showing is the largest offset off either account's
/// path of any stretch within [`SPIKE_TURN_REACH`] samples of it; the usual is the larger
/// of the medians over the tops and over the bottoms (an unbalance loads them unlike),
/// each of at least three turns, so one spiked turn does not set it.
fn spikes_on_turns(accounts: [(&[f64], f64); 2], turns: &[usize]) -> Vec<bool> {
    let n = accounts[0].0.len().min(accounts[1].0.len());
    let mut spikes = vec![false; n];
    // Turns alternate between the two ways: three of each.
    if turns.len() < 6 {
        return spikes;
    }
    let stretches = |k: usize| {
        let (from, to) = (
            k.saturating_sub(SPIKE_TURN_REACH),
            (k + SPIKE_TURN_REACH + 1).min(n),
        );
        (from..to).flat_map(move |a| (a + 1..=(a + SPIKE_MAX_SAMPLES).min(n)).map(move |b| (a, b)))
    };
    let paths = |(a, b): (usize, usize)| accounts.map(|(e, _)| off_path(e, a, b));
    let shown: Vec<f64> = turns
        .iter()
        .map(|&k| {
            stretches(k)
                .flat_map(paths)
                .flatten()
                .fold(0.0f64, |m, (off, _)| m.max(off))
        })
        .collect();
    let one: Vec<f64> = shown.iter().step_by(2).copied().collect();
    let other: Vec<f64> = shown.iter().skip(1).step_by(2).copied().collect();
    let usual = median(&one).max(median(&other));
    for &k in turns {
        for (a, b) in stretches(k) {
            let p = paths((a, b));
            let off_both = p
                .iter()
                .zip(&accounts)
                .all(|(p, (_, least))| p.is_some_and(|(off, _)| off > *least));
            let straight_off = p
                .iter()
                .flatten()
                .filter(|(off, bend)| straight(*off, *bend))
                .fold(0.0f64, |m, (off, _)| m.max(*off));
            if off_both && straight_off > SPIKE_TURN_FACTOR * usual {
                spikes[a..b].iter_mut().for_each(|s| *s = true);
            }
        }
    }
    spikes
}

/// For samples `a..b` of residual `e` (rad): the least offset off the straight path their
/// neighbours agree on when every sample lies off it the same way (else zero), and how far
/// that path bends over the stretch. Within the log the path is the chord between the
/// samples either side, and its bend the larger change of slope at either end there is a
/// sample to see it; at the log's first or last sample it is the line through the two
/// samples on the other side, and its bend the change of slope at the third. `None`
/// where the neighbours are too few to agree on a path.
fn off_path(e: &[f64], a: usize, b: usize) -> Option<(f64, f64)> {
    let n = e.len();
    let span = (b - a + 1) as f64;
    // The path's value at sample k is `at + slope * (k - from)`.
    let (at, from, slope, bend) = if a >= 1 && b < n {
        let slope = (e[b] - e[a - 1]) / span;
        let left = (a >= 2).then(|| ((e[a - 1] - e[a - 2]) - slope).abs());
        let right = (b + 1 < n).then(|| ((e[b + 1] - e[b]) - slope).abs());
        let bend = match (left, right) {
            (Some(l), Some(r)) => l.max(r),
            (Some(s), None) | (None, Some(s)) => s,
            (None, None) => return None,
        };
        (e[a - 1], a - 1, slope, bend)
    } else if a == 0 && b + 2 < n {
        let slope = e[b + 1] - e[b];
        (e[b], b, slope, ((e[b + 2] - e[b + 1]) - slope).abs())
    } else if b == n && a >= 3 {
        let slope = e[a - 1] - e[a - 2];
        (
            e[a - 1],
            a - 1,
            slope,
            ((e[a - 2] - e[a - 3]) - slope).abs(),
        )
    } else {
        return None;
    };
    let (lo, hi) = (a..b)
        .map(|k| e[k] - (at + slope * (k as f64 - from as f64)))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), d| {
            (l.min(d), h.max(d))
        });
    let smallest = if lo > 0.0 {
        lo
    } else if hi < 0.0 {
        -hi
    } else {
        0.0
    };
    Some((smallest, bend * span))
}

/// Widest play half-width tried for [`play_residual`], as a share of the input's range:
/// the shipped da Vinci logs' play, 0.040 to 0.0625 rad, is 2 to 3 % of their spindle's
/// range of about 2.1 rad.
const PLAY_MAX_SHARE: f64 = 0.1;

/// Play half-widths tried besides zero, evenly in their logarithm from
/// [`PLAY_NARROWEST`] times the widest to the widest: 40, a factor 1.19 apart. A stroke of
/// 3 rad on a drive whose play is a few mrad needs widths far below the tenth of the
/// range an even grid of 20 steps started at (30 mrad): the play went unfitted and the
/// whole return branch of clean logs read as a departure.
const PLAY_WIDTHS: usize = 40;

/// Narrowest play half-width tried, as a share of the widest (1e-3: 0.6 mrad on a 6 rad
/// range).
const PLAY_NARROWEST: f64 = 1e-3;

/// Widths tried around the best of the grid, between its two neighbours (8).
const PLAY_REFINE: usize = 8;

/// The output less the drive's response as a play operator: `xo - a - g P_r(xi)`, with the
/// half-width `r`, the play's state at the first sample (centred or against either side)
/// and the line `a + g p` chosen for the least robust spread, so that a stretch that
/// departs from the drive (a minority of the samples) does not pull the fit. The
/// straight line (`r = 0`) is among the candidates.
fn play_residual(xi: &[f64], xo: &[f64]) -> Vec<f64> {
    let n = xi.len().min(xo.len());
    if n == 0 {
        return Vec::new();
    }
    let (xi, xo) = (&xi[..n], &xo[..n]);
    let (lo, hi) = xi
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    let range = (hi - lo).max(0.0);
    let mo = xo.iter().sum::<f64>() / n as f64;
    let mut p = vec![0.0; n];
    let mut e = vec![0.0; n];
    // The residual of a play `(r, first output)` fitted by least squares, into `e`;
    // returns its robust spread.
    let fit = |r: f64, y0: f64, p: &mut [f64], e: &mut [f64]| {
        super::play::play_into(xi, r, y0, p);
        let mp = p.iter().sum::<f64>() / n as f64;
        let sxy: f64 = p.iter().zip(xo).map(|(a, b)| (a - mp) * (b - mo)).sum();
        let sxx: f64 = p.iter().map(|a| (a - mp).powi(2)).sum();
        let g = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        for ((ei, pi), oi) in e.iter_mut().zip(p.iter()).zip(xo) {
            *ei = oi - mo - g * (pi - mp);
        }
        robust(e).0
    };
    let mut best = (f64::INFINITY, 0.0, xi[0]);
    let mut try_width = |r: f64, best: &mut (f64, f64, f64)| {
        let starts: &[f64] = if r == 0.0 { &[0.0] } else { &[-1.0, 0.0, 1.0] };
        for side in starts {
            let y0 = xi[0] + side * r;
            let spread = fit(r, y0, &mut p, &mut e);
            if spread < best.0 {
                *best = (spread, r, y0);
            }
        }
    };
    // Widths evenly spaced in their logarithm, so that a play of a few mrad on a stroke of
    // a few rad is tried as closely as one of a tenth of the stroke; then refined between
    // the neighbours of the best.
    let widest = PLAY_MAX_SHARE * range;
    let narrowest = widest * PLAY_NARROWEST;
    let ratio = (widest / narrowest).powf(1.0 / PLAY_WIDTHS as f64);
    try_width(0.0, &mut best);
    for k in (0..=PLAY_WIDTHS).filter(|_| widest > 0.0) {
        try_width(narrowest * ratio.powi(k as i32), &mut best);
    }
    if best.1 > 0.0 {
        let centre = best.1;
        for k in 1..PLAY_REFINE {
            let step = ratio.powf(2.0 * k as f64 / PLAY_REFINE as f64 - 1.0);
            if (step - 1.0).abs() > 1e-12 {
                try_width(centre * step, &mut best);
            }
        }
    }
    fit(best.1, best.2, &mut p, &mut e);
    e
}

/// The output less the straight line through output against input with a step that
/// follows the input's direction of travel: `xo - (a + g xi + b dir)`, least squares,
/// `dir` +-1 from the input's own neighbours. Two parallel branches, switched the moment
/// the input turns.
fn branch_residual(xi: &[f64], xo: &[f64]) -> Vec<f64> {
    let n = xi.len().min(xo.len());
    if n < 3 {
        return vec![0.0; n];
    }
    let mut dir = vec![0.0; n];
    let mut held = vec![false; n];
    let mut last = 0.0;
    for (i, d) in dir.iter_mut().enumerate() {
        let step = xi[(i + 1).min(n - 1)] - xi[i.saturating_sub(1)];
        if step != 0.0 {
            last = step.signum();
        } else {
            held[i] = true;
        }
        *d = last;
    }
    // Before the input first moves, the direction it first takes.
    if let Some(first) = dir.iter().copied().find(|d| *d != 0.0) {
        for d in dir.iter_mut().take_while(|d| **d == 0.0) {
            *d = first;
        }
    }
    // Least squares in centred columns, solved by Cramer's rule on the 2 x 2 system.
    let mean = |v: &[f64]| v.iter().sum::<f64>() / n as f64;
    let (mx, md, mo) = (mean(&xi[..n]), mean(&dir), mean(&xo[..n]));
    let (mut sxx, mut sxd, mut sdd, mut sxo, mut sdo) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for i in 0..n {
        let (x, d, o) = (xi[i] - mx, dir[i] - md, xo[i] - mo);
        sxx += x * x;
        sxd += x * d;
        sdd += d * d;
        sxo += x * o;
        sdo += d * o;
    }
    let det = sxx * sdd - sxd * sxd;
    let (g, b) = if det > 1e-12 * sxx * sdd && det > 0.0 {
        ((sxo * sdd - sdo * sxd) / det, (sdo * sxx - sxo * sxd) / det)
    } else if sxx > 0.0 {
        (sxo / sxx, 0.0)
    } else {
        (0.0, 0.0)
    };
    // Where the input's neighbours agree (the very sample it turns at, or a dwell) the
    // drive may be on either branch: the nearer counts.
    (0..n)
        .map(|i| {
            let r = xo[i] - mo - g * (xi[i] - mx) - b * (dir[i] - md);
            let other = r + 2.0 * b * dir[i];
            if held[i] && other.abs() < r.abs() {
                other
            } else {
                r
            }
        })
        .collect()
}

/// Band (rad) within which a reading that holds still stays, from its own sample-to-sample
/// noise: [`STUCK_NOISE_BANDS`] robust standard deviations of its white part (from second
/// differences, which a smooth motion leaves near zero). 0 for a reading whose noise is
/// below its encoder step (the common case): only an exactly repeated value is held.
fn hold_band(x: &[f64]) -> f64 {
    if x.len() < 3 {
        return 0.0;
    }
    let d2: Vec<f64> = x.windows(3).map(|w| w[2] - 2.0 * w[1] + w[0]).collect();
    // Second differences of white noise of deviation s have deviation s sqrt(6).
    let (sigma, _) = robust(&d2);
    STUCK_NOISE_BANDS * sigma / 6f64.sqrt()
}

/// Runs of `x` held within `band` of their first value (exactly constant for a quiet
/// encoder) at least [`STUCK_MIN_S`] long during which `other` moves
/// more than [`STUCK_FACTOR`] times the log's typical travel through play; `gain` converts
/// the other channel's travel into this one's (rad per rad), `reversals` is about how many
/// times the motion reverses in the log.
fn stuck(
    x: &[f64],
    other: &[f64],
    gain: f64,
    q: f64,
    dt: f64,
    reversals: usize,
    channel: Channel,
) -> Vec<Raw> {
    let n = x.len();
    let min_len = ((STUCK_MIN_S / dt).round() as usize).max(3);
    let band = hold_band(x);
    // The other channel's travel read through a running median as wide as two spikes
    // and a sample, so that a spike of the other reading while this one holds (an
    // output spike in a dwell of the input) is not travel.
    let other = running_median(other, SPIKE_MAX_SAMPLES);
    let other = &other[..];
    let mut all: Vec<(usize, usize, f64)> = Vec::new();
    let mut a = 0;
    while a < n {
        let mut b = a + 1;
        let tol = (1e-12 * x[a].abs().max(1.0)).max(band);
        while b < n && (x[b] - x[a]).abs() <= tol {
            b += 1;
        }
        if b - a >= 2 {
            let (lo, hi) = other[a..b]
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                    (l.min(*v), h.max(*v))
                });
            all.push((a, b, (hi - lo) * gain));
        }
        a = b;
    }
    if all.is_empty() {
        return Vec::new();
    }
    // Through play at each reversal a reading holds while the other moves: the largest
    // travels of the log, about one per reversal; their median is the log's own deadband,
    // and one stuck stretch among them does not move it. A reversal without a held
    // reading (play under one count, or noise dithering it) counts as no travel.
    let mut travels: Vec<f64> = all.iter().map(|r| r.2).collect();
    travels.sort_by(|p, q| q.total_cmp(p));
    travels.resize(travels.len().max(reversals + 1), 0.0);
    let typical = median(&travels[..reversals + 1]);
    let threshold = (STUCK_FACTOR * typical).max(20.0 * q).max(1e-9);
    all.into_iter()
        .filter(|(a, b, travel)| b - a >= min_len && *travel > threshold)
        .map(|(a, b, _)| (channel, Reason::Stuck, a, b))
        .collect()
}

/// Median of `v` over each sample and `half` samples either side; within `half` samples
/// of an end, over the first or last `2 half + 1` samples.
fn running_median(v: &[f64], half: usize) -> Vec<f64> {
    let n = v.len();
    let width = (2 * half + 1).min(n);
    let mut w: Vec<f64> = Vec::with_capacity(width);
    (0..n)
        .map(|i| {
            // A window cut short at an end would be half a spike's samples and half the
            // drive's: a spike of `half` samples on a log's first samples would be its
            // median there, and read as travel.
            let a = i.saturating_sub(half).min(n - width);
            w.clear();
            w.extend_from_slice(&v[a..a + width]);
            let k = w.len() / 2;
            *w.select_nth_unstable_by(k, f64::total_cmp).1
        })
        .collect()
}

/// Samples nearest the turns of motion `m` over times `t` (sampled every `dt` s), in time
/// order.
fn turns_of(m: &Motion, t: &[f64], dt: f64) -> Vec<usize> {
    let Some((&first, &last)) = t.first().zip(t.last()) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    let mut from = first;
    // Bounded by the samples, whatever the motion's period.
    while out.len() < t.len() {
        let at = m.next_reversal(from);
        if !(at.is_finite() && at > from && at <= last) {
            break;
        }
        let k = t.partition_point(|v| *v < at).min(t.len() - 1);
        out.push(if k > 0 && at - t[k - 1] < t[k] - at {
            k - 1
        } else {
            k
        });
        from = at + dt;
    }
    out
}

/// Stretches of `log` that are not the drive, padded by [`PAD_S`] and merged per channel,
/// in time order. `action` goes into each segment (`"excluded"` or `"kept"`). Typical cost:
/// a few milliseconds for 20 000 samples.
pub fn detect(log: &BenchLog, action: &str) -> Vec<Segment> {
    let n = log
        .t_s
        .len()
        .min(log.theta_in_rad.len())
        .min(log.theta_out_rad.len());
    if n < 40 {
        return Vec::new();
    }
    let t = &log.t_s[..n];
    let xi = &log.theta_in_rad[..n];
    let xo = &log.theta_out_rad[..n];
    if t.iter().chain(xi).chain(xo).any(|v| !v.is_finite()) {
        return Vec::new();
    }
    let span = t[n - 1] - t[0];
    if span <= 0.0 {
        return Vec::new();
    }
    let dt = span / (n - 1) as f64;
    let q_in = super::resolution::encoder_step(xi);
    let q_out = super::resolution::encoder_step(xo);
    let (mut raw, motion) = input_departures(t, xi, q_in, dt);
    // Output per input radian (least squares), for converting travels between channels.
    let mi = xi.iter().sum::<f64>() / n as f64;
    let mo = xo.iter().sum::<f64>() / n as f64;
    let sxy: f64 = xi.iter().zip(xo).map(|(a, b)| (a - mi) * (b - mo)).sum();
    let sxx: f64 = xi.iter().map(|a| (a - mi).powi(2)).sum();
    let syy: f64 = xo.iter().map(|b| (b - mo).powi(2)).sum();
    let reversals = motion
        .map(|m| (m.w * span / std::f64::consts::PI).round() as usize)
        .unwrap_or(4)
        .max(2);
    if sxx > 0.0 && syy > 0.0 {
        let g_out = (sxy / sxx).abs();
        let g_in = (sxy / syy).abs();
        raw.extend(stuck(xo, xi, g_out, q_out, dt, reversals, Channel::Output));
        raw.extend(stuck(xi, xo, g_in, q_in, dt, reversals, Channel::Input));
        if let Some(m) = motion {
            // The output is judged against the input: where the input is flagged (a jerk the
            // output follows through whatever lags between them, a wrong input reading)
            // that says nothing of the output, so only output stretches clear of the
            // input's count.
            let follow = ((PAD_S + FOLLOW_S) / dt).round() as usize;
            let jerks: Vec<(usize, usize)> = raw
                .iter()
                .filter(|r| r.0 == Channel::Input)
                .map(|r| (r.2.saturating_sub(follow), r.3 + follow))
                .collect();
            raw.extend(
                output_departures(t, xi, xo, sxy / sxx, q_out, dt, &m)
                    .into_iter()
                    .filter(|o| !jerks.iter().any(|j| o.2 < j.1 && j.0 < o.3)),
            );
        }
    }
    // Pad, then merge overlapping stretches of one channel.
    let mut spans: Vec<(Channel, f64, f64, Vec<Reason>)> = raw
        .iter()
        .map(|(c, r, a, b)| {
            (
                *c,
                (t[*a] - PAD_S).max(t[0]),
                (t[b - 1] + PAD_S).min(t[n - 1]),
                vec![*r],
            )
        })
        .collect();
    spans.sort_by(|p, q| (p.0 as u8).cmp(&(q.0 as u8)).then(p.1.total_cmp(&q.1)));
    let mut merged: Vec<(Channel, f64, f64, Vec<Reason>)> = Vec::new();
    for s in spans {
        match merged.last_mut() {
            Some(m) if m.0 == s.0 && s.1 <= m.2 => {
                m.2 = m.2.max(s.2);
                for r in s.3 {
                    if !m.3.contains(&r) {
                        m.3.push(r);
                    }
                }
            }
            _ => merged.push(s),
        }
    }
    let mut out: Vec<Segment> = merged
        .into_iter()
        .map(|(channel, start_s, end_s, reasons)| {
            // A wrong input reading fed the replay travel the drive did not see; through a
            // jerk the drive's own dynamics, not the quasi-static replay, set the memory it
            // leaves with. On synthetic logs, keeping only a jerk's own rows out left the
            // extended residual at 3 to 5 times the noise floor and two compliances
            // unexplained; up to the next reversal, 1.0 to 1.5 times, every effect named.
            let input = channel == Channel::Input;
            let excluded_to_s = match motion {
                Some(m) if input => m.next_reversal(end_s).min(t[n - 1]).max(end_s),
                _ => end_s,
            };
            Segment {
                log: log.source.clone(),
                channel,
                start_s,
                end_s,
                reason: reasons
                    .iter()
                    .map(|r| r.words(channel))
                    .collect::<Vec<_>>()
                    .join("; "),
                action: action.to_string(),
                excluded_to_s,
            }
        })
        .collect();
    out.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
    out
}

/// Rows of a prepared log (times `t_rel` from the log's first sample `t0`, rows averaged
/// over `block_s`) to fit and score: false where a row's samples reach into an excluded
/// stretch (`start_s` to `excluded_to_s`) of `segments`.
pub fn keep_rows(t_rel: &[f64], t0: f64, block_s: f64, segments: &[Segment]) -> Vec<bool> {
    let half = 0.5 * block_s.max(0.0);
    t_rel
        .iter()
        .map(|tr| {
            let t = tr + t0;
            !segments
                .iter()
                .filter(|s| s.action == "excluded")
                .any(|s| t + half >= s.start_s && t - half <= s.excluded_to_s)
        })
        .collect()
}

/// One line for the console: log, channel, times, reason and what was done with the rows.
pub fn describe(s: &Segment) -> String {
    let what = if s.action != "excluded" {
        "kept (--keep-segments): fitted and scored".to_string()
    } else if s.excluded_to_s > s.end_s {
        format!(
            "excluded from fitting and scoring, with the rows up to {:.3} s, the input's next reversal or the log's end when none comes (the model's memory there is not the drive's: fed a reading the drive did not follow, or motion too fast for the quasi-static replay)",
            s.excluded_to_s
        )
    } else {
        "excluded from fitting and scoring".to_string()
    };
    format!(
        "Not the drive: {}: {} {:.3} to {:.3} s: {}; {what}",
        s.log, s.channel, s.start_s, s.end_s, s.reason
    )
}

/// Fewest rows of a log left to fit and score once its stretches that are not the drive
/// are left out: the least a log may hold at all ([`super::model::prepare`]).
pub const MIN_ROWS_LEFT: usize = 40;

/// Refuse a log whose rows to fit and score (`keep_per_log`, after the exclusions of
/// `segments_per_log`) fall under [`MIN_ROWS_LEFT`]: with nothing left, every error
/// reads zero and the answer would be that nothing is wrong, when the log is the fault
/// (a reading off its scale, a wrong column, a delay of seconds).
fn enough_rows_left(
    prepared: &[super::model::Prepared],
    keep_per_log: &[Vec<bool>],
    segments_per_log: &[Vec<Segment>],
) -> Result<(), super::IdentifyError> {
    for ((p, keep), segs) in prepared.iter().zip(keep_per_log).zip(segments_per_log) {
        let left = keep.iter().filter(|k| **k).count();
        if left >= MIN_ROWS_LEFT {
            continue;
        }
        let first = segs
            .iter()
            .find(|s| s.action == "excluded")
            .map(|s| {
                let more = segs.len().saturating_sub(1);
                let more = if more > 0 {
                    format!(" and {more} more")
                } else {
                    String::new()
                };
                format!(
                    " (the {} reading from {:.3} to {:.3} s: {}{more})",
                    s.channel, s.start_s, s.excluded_to_s, s.reason
                )
            })
            .unwrap_or_default();
        return Err(super::IdentifyError::BadLog {
            log: p.source.clone(),
            message: format!(
                "{left} of its {} rows are left once the stretches that are not the drive are left out{first}; at least {MIN_ROWS_LEFT} are needed. Check the log's columns and units, or pass --keep-segments to fit and score it as it is",
                p.t.len()
            ),
        });
    }
    Ok(())
}

/// Each log's segments, and one flag per row of each prepared log: fit and score it.
pub type SegmentsAndRows = (Vec<Vec<Segment>>, Vec<Vec<bool>>);

/// Segments of every log and the rows of each prepared log to fit and score, settled
/// ([`super::model::settle_rows`]: the direction from the rows kept, the rows across a
/// load step out); a log left with too few rows is refused ([`MIN_ROWS_LEFT`]). `keep`
/// as in [`detect_all`].
pub fn rows_to_fit(
    cut: &[BenchLog],
    prepared: &mut [super::model::Prepared],
    keep: bool,
) -> Result<SegmentsAndRows, super::IdentifyError> {
    let (segments, mut keep_per_log) = detect_all(cut, prepared, keep);
    super::model::settle_rows(prepared, &mut keep_per_log);
    enough_rows_left(prepared, &keep_per_log, &segments)?;
    Ok((segments, keep_per_log))
}

/// Segments of every log and the rows of each prepared log to fit and score (all of them
/// when `keep` is set: the segments are then reported as `"kept"`).
pub fn detect_all(
    cut: &[BenchLog],
    prepared: &[super::model::Prepared],
    keep: bool,
) -> (Vec<Vec<Segment>>, Vec<Vec<bool>>) {
    let action = if keep { "kept" } else { "excluded" };
    cut.iter()
        .zip(prepared)
        .map(|(log, p)| {
            let segs = detect(log, action);
            let t0 = log.t_s.first().copied().unwrap_or(0.0);
            let block = if p.t.len() > 1 {
                (p.t[p.t.len() - 1] - p.t[0]) / (p.t.len() - 1) as f64
            } else {
                0.0
            };
            let rows = keep_rows(&p.t, t0, block, &segs);
            (segs, rows)
        })
        .unzip()
}

/// Shaded time intervals of a log's plots, in the prepared log's time (from its first
/// sample `t0`, s): the rows kept out, labelled `excluded: <reason>` (or `detected, kept:
/// <reason>` under `--keep-segments`).
pub fn shades(segments: &[Segment], t0: f64) -> Vec<(f64, f64, String)> {
    segments
        .iter()
        .map(|s| {
            let label = if s.action == "excluded" {
                format!("excluded: {}", s.reason)
            } else {
                format!("detected, kept: {}", s.reason)
            };
            (s.start_s - t0, s.excluded_to_s - t0, label)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log(t: Vec<f64>, xi: Vec<f64>, xo: Vec<f64>) -> BenchLog {
        let n = t.len();
        BenchLog {
            t_s: t,
            theta_in_rad: xi,
            theta_out_rad: xo,
            load_nm: vec![0.0; n],
            source: "test".into(),
            ..BenchLog::default()
        }
    }

    fn q(v: f64, step: f64) -> f64 {
        (v / step).round() * step
    }

    /// A drive with the free travel of the first da Vinci log (0.025 rad of spindle at a
    /// reversal), recorded for 6 s of a 0.1 Hz scan that reverses once near the end: the
    /// output standing still through the play after the reversal is the drive, not a
    /// departure, wherever the record starts. A reading that drops by 0.1 rad for 0.5 s on
    /// such a record is still caught at its jumps; on so short a record the held stretch
    /// between them is not named a departure.
    #[test]
    fn the_free_travel_after_a_reversal_is_not_a_departure() {
        use rand::{Rng, SeedableRng};
        let step_in = std::f64::consts::TAU / 8192.0;
        let step_out = std::f64::consts::TAU / 4000.0;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for start in [0.0, 0.7, 1.9, 3.3] {
            let t: Vec<f64> = (0..6000).map(|i| start + i as f64 * 1e-3).collect();
            let scan: Vec<f64> = t
                .iter()
                .map(|t| 1.0 * (0.2 * std::f64::consts::PI * (t + 2.5)).sin())
                .collect();
            let free = crate::identify::play::play(&scan, 0.0125);
            let xi: Vec<f64> = scan
                .iter()
                .map(|x| q(x + 2e-4 * rng.gen_range(-1.0..1.0), step_in))
                .collect();
            let clean: Vec<f64> = free
                .iter()
                .map(|x| q(0.9 * x - 1.2 + 3e-4 * rng.gen_range(-1.0..1.0), step_out))
                .collect();
            let s = detect(&log(t.clone(), xi.clone(), clean.clone()), "excluded");
            assert!(s.is_empty(), "start {start}: {s:?}");
            let dropped: Vec<f64> = clean
                .iter()
                .zip(&t)
                .map(|(x, ti)| {
                    if (start + 2.0..start + 2.5).contains(ti) {
                        x - 0.1
                    } else {
                        *x
                    }
                })
                .collect();
            let s = detect(&log(t, xi, dropped), "excluded");
            for edge in [start + 2.0, start + 2.5] {
                assert!(
                    s.iter().any(|s| s.channel == Channel::Output
                        && s.start_s <= edge
                        && s.end_s >= edge),
                    "start {start}, edge {edge}: {s:?}"
                );
            }
        }
    }

    /// A scan of half sines of 5 s between dwells of 2 s at each turn, rad (5 rad at the
    /// input).
    fn dwell_scan(t: f64) -> f64 {
        let cycle = t % 14.0;
        let (u, top) = if cycle < 7.0 {
            (cycle, 1.0)
        } else {
            (cycle - 7.0, -1.0)
        };
        let half = if u < 5.0 {
            -(std::f64::consts::PI * u / 5.0).cos()
        } else {
            1.0
        };
        5.0 * top * half
    }

    /// A scan with a 2 s dwell at each turn (a table the bench steps through): an output
    /// spike of three samples inside a dwell is the output's, and the input that holds
    /// there, as the motion says, is not stuck. Before, the spike counted as the output's
    /// travel and the whole dwell was flagged as "input stuck while output moves", the
    /// spike itself not at all.
    #[test]
    fn an_output_spike_in_a_dwell_of_the_input_is_the_outputs() {
        use rand::{Rng, SeedableRng};
        let step_in = std::f64::consts::TAU / 65536.0;
        let step_out = std::f64::consts::TAU / 1_048_576.0;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let t: Vec<f64> = (0..3000).map(|i| i as f64 * 0.01).collect();
        let xi: Vec<f64> = t.iter().map(|t| q(dwell_scan(*t), step_in)).collect();
        let mut xo: Vec<f64> = t
            .iter()
            .map(|t| {
                q(
                    0.195 * dwell_scan(*t) + 3e-6 * rng.gen_range(-1.0..1.0),
                    step_out,
                )
            })
            .collect();
        // Inside the dwell from 5 to 7 s.
        for x in &mut xo[600..603] {
            *x += 5e-3;
        }
        let s = detect(&log(t, xi, xo), "excluded");
        assert!(
            s.iter().all(|s| s.channel == Channel::Output),
            "the input flagged: {s:?}"
        );
        assert!(
            s.iter().any(|s| s.start_s <= 6.0 && s.end_s >= 6.02),
            "the spike not flagged: {s:?}"
        );
    }

    /// The same scan recorded from inside one dwell to inside another: an output spike of
    /// one to five samples on the record's first or last samples is the output's. Before,
    /// the other channel's running median was cut short at the ends, so three or more
    /// spiked samples were its median there and the input's dwell was flagged as "input
    /// stuck while output moves", the spike not at all (an outside check: five of ten
    /// such spikes at the start of the first da Vinci log, which starts at rest).
    #[test]
    fn an_output_spike_on_a_records_first_or_last_samples_is_the_outputs() {
        use rand::{Rng, SeedableRng};
        let step_in = std::f64::consts::TAU / 65536.0;
        let step_out = std::f64::consts::TAU / 1_048_576.0;
        // From 5.5 s, inside the dwell from 5 to 7 s, to 34.49 s, inside the one from 33
        // to 35 s.
        let t: Vec<f64> = (0..2900).map(|i| 5.5 + i as f64 * 0.01).collect();
        let n = t.len();
        let xi: Vec<f64> = t.iter().map(|t| q(dwell_scan(*t), step_in)).collect();
        for seed in 0..4u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let clean: Vec<f64> = t
                .iter()
                .map(|t| {
                    q(
                        0.195 * dwell_scan(*t) + 3e-6 * rng.gen_range(-1.0..1.0),
                        step_out,
                    )
                })
                .collect();
            let s = detect(&log(t.clone(), xi.clone(), clean.clone()), "excluded");
            assert!(s.is_empty(), "seed {seed}, clean: {s:?}");
            for k in 1..=SPIKE_MAX_SAMPLES {
                for at_end in [false, true] {
                    let size =
                        rng.gen_range(2e-3..2e-2) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
                    let mut xo = clean.clone();
                    let spiked = if at_end { n - k..n } else { 0..k };
                    for x in &mut xo[spiked.clone()] {
                        *x += size;
                    }
                    let s = detect(&log(t.clone(), xi.clone(), xo), "excluded");
                    let what = format!("seed {seed}, {k} samples, end {at_end}: {s:?}");
                    assert!(
                        s.iter().all(|s| s.channel == Channel::Output),
                        "the input flagged: {what}"
                    );
                    let (a, b) = (t[spiked.start], t[spiked.end - 1]);
                    assert!(
                        s.iter().any(|s| s.start_s <= a && s.end_s >= b),
                        "the spike not flagged: {what}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_quantised_sine_is_clean_and_a_jerk_is_found() {
        let n = 20_000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        let step_in = std::f64::consts::TAU / 8192.0;
        let step_out = std::f64::consts::TAU / 4000.0;
        let xi: Vec<f64> = t
            .iter()
            .map(|t| {
                q(
                    0.52 + 0.52 * (0.2 * std::f64::consts::PI * t).sin(),
                    step_in,
                )
            })
            .collect();
        let xo: Vec<f64> = xi.iter().map(|x| q(0.87 * x, step_out)).collect();
        assert!(detect(&log(t.clone(), xi.clone(), xo.clone()), "excluded").is_empty());
        let bump = |t: f64| {
            if (10.0..10.2).contains(&t) {
                0.5 * (1.0 - (std::f64::consts::TAU * (t - 10.0) / 0.2).cos())
            } else {
                0.0
            }
        };
        let xj: Vec<f64> = xi
            .iter()
            .zip(&t)
            .map(|(x, t)| q(x + bump(*t), step_in))
            .collect();
        let xoj: Vec<f64> = xj.iter().map(|x| q(0.87 * x, step_out)).collect();
        let s = detect(&log(t, xj, xoj), "excluded");
        assert_eq!(s.len(), 1, "{s:?}");
        assert_eq!(s[0].channel, Channel::Input);
        assert!(
            (s[0].start_s - 9.95).abs() < 0.03 && (s[0].end_s - 10.25).abs() < 0.03,
            "{s:?}"
        );
    }

    #[test]
    fn the_scenarios_triangle_scan_is_its_own_motion() {
        let sig = crate::signal::Signal::Triangle {
            amplitude_rad: 10.0,
            frequency_hz: 0.1,
            turn_fraction: 0.2,
        };
        let t: Vec<f64> = (0..3001).map(|i| i as f64 * 0.01).collect();
        let x: Vec<f64> = t.iter().map(|t| sig.at(*t).value).collect();
        for (k, v) in x.iter().enumerate().step_by(250) {
            assert!((v - 10.0 * tri(std::f64::consts::TAU * 0.1 * t[k], 0.2)).abs() < 1e-9);
        }
        let rows: Vec<usize> = (0..t.len()).collect();
        let m = fit_motion(&t, &x, &rows).expect("motion");
        let worst = t
            .iter()
            .zip(&x)
            .fold(0.0f64, |a, (t, x)| a.max((x - m.at(*t)).abs()));
        assert!(worst < 1e-3, "{m:?}: {worst}");
    }

    #[test]
    fn excluded_rows_cover_the_stretch_and_its_tail() {
        let seg = Segment {
            log: "x".into(),
            channel: Channel::Input,
            start_s: 1.0,
            end_s: 1.5,
            reason: String::new(),
            action: "excluded".into(),
            excluded_to_s: 2.0,
        };
        let t: Vec<f64> = (0..40).map(|i| i as f64 * 0.1).collect();
        let keep = keep_rows(&t, 0.0, 0.1, std::slice::from_ref(&seg));
        assert!(keep[9] && !keep[10] && !keep[20] && keep[21]);
        let kept = Segment {
            action: "kept".into(),
            ..seg
        };
        assert!(keep_rows(&t, 0.0, 0.1, &[kept]).iter().all(|k| *k));
    }
}
