//! Axes: ranges, ticks and labels (linear and logarithmic).

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};

use super::*;

/// One axis in drawing coordinates (log10 of the value for a log axis).
#[derive(Clone, Debug)]
pub(super) struct Axis {
    pub(super) lo: f64,
    pub(super) hi: f64,
    pub(super) major: Vec<f64>,
    pub(super) minor: Vec<f64>,
    pub(super) log: bool,
    /// Linear tick step (0 when not applicable).
    pub(super) step: f64,
    /// Scientific notation for linear labels.
    pub(super) sci: bool,
    /// Names shown at these positions instead of numbers (a categorical axis).
    pub(super) names: Vec<(f64, String)>,
}

/// "Nice" step (1, 2 or 5 times a power of ten) at least `raw`.
pub(super) fn nice_step(raw: f64) -> Option<(f64, u32)> {
    if !(raw.is_finite() && raw > 0.0) {
        return None;
    }
    let e = raw.log10().floor();
    let base = 10f64.powf(e);
    let f = raw / base;
    let (m, mult) = if f <= 1.0 + 1e-9 {
        (1, 1.0)
    } else if f <= 2.0 + 1e-9 {
        (2, 2.0)
    } else if f <= 5.0 + 1e-9 {
        (5, 5.0)
    } else {
        (1, 10.0)
    };
    let step = mult * base;
    (step.is_finite() && step > 0.0).then_some((step, m))
}

/// Multiples of `step` inside `[lo, hi]` (empty when unreasonable).
pub(super) fn multiples(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    if !(step > 0.0 && lo.is_finite() && hi.is_finite()) {
        return Vec::new();
    }
    let k0 = (lo / step - 1e-9).ceil();
    let k1 = (hi / step + 1e-9).floor();
    if !(k0.is_finite() && k1.is_finite()) || k1 < k0 || k1 - k0 > 500.0 {
        return Vec::new();
    }
    let (k0, k1) = (k0 as i64, k1 as i64);
    (k0..=k1)
        .map(|k| {
            let v = k as f64 * step;
            if v.abs() < step * 1e-9 {
                0.0
            } else {
                v
            }
        })
        .collect()
}

impl Axis {
    /// Linear axis over `[lo, hi]` with about `target` labelled ticks.
    pub(super) fn linear(lo: f64, hi: f64, target: usize) -> Self {
        // Halved operands: no overflow even for a range of +-f64::MAX.
        let half_span = hi * 0.5 - lo * 0.5;
        let mut axis = Axis {
            lo,
            hi,
            major: Vec::new(),
            minor: Vec::new(),
            log: false,
            step: 0.0,
            sci: false,
            names: Vec::new(),
        };
        if let Some((step, m)) = nice_step(half_span / target.max(2) as f64 * 2.0) {
            axis.major = multiples(lo, hi, step);
            let sub = if m == 2 { 4.0 } else { 5.0 };
            axis.minor = multiples(lo, hi, step / sub);
            axis.step = step;
            let maxabs = lo.abs().max(hi.abs());
            axis.sci = maxabs >= 1e6 || step < 1e-4;
        }
        axis
    }

    /// log10 axis; `lo`/`hi` are exponents.
    pub(super) fn log10(lo: f64, hi: f64) -> Self {
        let mut axis = Axis {
            lo,
            hi,
            major: Vec::new(),
            minor: Vec::new(),
            log: true,
            step: 0.0,
            sci: false,
            names: Vec::new(),
        };
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            return axis;
        }
        let decades = hi - lo;
        let e0 = lo.floor().clamp(-400.0, 400.0) as i32;
        let e1 = hi.ceil().clamp(-400.0, 400.0) as i32;
        let every = (decades / 10.0).ceil().max(1.0) as i32;
        let within = |v: f64| v >= lo - 1e-9 && v <= hi + 1e-9;
        let collect = |mantissas: &[f64], every: i32| -> Vec<f64> {
            let mut out = Vec::new();
            for e in e0..=e1 {
                if e.rem_euclid(every) != 0 {
                    continue;
                }
                for &m in mantissas {
                    let v = f64::from(e) + m.log10();
                    if within(v) {
                        out.push(v);
                    }
                }
            }
            out
        };
        let mut major = if decades > 4.0 {
            collect(&[1.0], every)
        } else {
            collect(&[1.0, 2.0, 5.0], 1)
        };
        if major.len() < 2 {
            major = collect(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0], 1);
        }
        if major.len() < 2 {
            // Less than a factor of ~1.3: linear ticks in value space.
            let (a, b) = (10f64.powf(lo), 10f64.powf(hi));
            if let Some((step, _)) = nice_step((b - a) / 6.0) {
                major = multiples(a, b, step)
                    .into_iter()
                    .filter(|v| *v > 0.0)
                    .map(f64::log10)
                    .collect();
            }
        }
        if decades <= 12.0 {
            axis.minor = collect(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0], 1);
        }
        axis.major = major;
        axis
    }

    /// The same axis with names at the given positions as its only ticks (those in
    /// range); no names keeps the numeric ticks.
    pub(super) fn named(mut self, names: &[(f64, String)]) -> Self {
        let inside: Vec<(f64, String)> = names
            .iter()
            .filter(|(v, _)| v.is_finite() && *v >= self.lo && *v <= self.hi)
            .cloned()
            .collect();
        if !inside.is_empty() {
            self.major = inside.iter().map(|(v, _)| *v).collect();
            self.minor = Vec::new();
            self.names = inside;
        }
        self
    }

    /// Coordinate spec for plotters with our own tick positions.
    pub(super) fn spec(&self) -> TickRange {
        TickRange {
            lo: self.lo,
            hi: self.hi,
            major: self.major.clone(),
            minor: self.minor.clone(),
        }
    }

    /// Tick label for drawing coordinate `v`.
    pub(super) fn label(&self, v: f64) -> String {
        if !self.names.is_empty() {
            let tolerance = (self.hi - self.lo).abs() * 1e-9;
            return self
                .names
                .iter()
                .find(|(p, _)| (p - v).abs() <= tolerance)
                .map_or_else(String::new, |(_, n)| n.clone());
        }
        if self.log {
            return fmt_log_tick(v);
        }
        if self.step <= 0.0 {
            return fmt_general(v);
        }
        let v = if v.abs() < self.step * 1e-6 { 0.0 } else { v };
        if self.sci {
            if v == 0.0 {
                return "0".into();
            }
            // Enough mantissa digits to resolve one step at v's magnitude.
            let digits = (v.abs().log10().floor() - self.step.log10().floor()).clamp(0.0, 15.0);
            format!("{:.*e}", digits as usize, v)
        } else {
            let decimals = (-self.step.log10() - 1e-9).ceil().clamp(0.0, 12.0) as usize;
            format!("{:.*}", decimals, v)
        }
    }
}

/// Linear plotters coordinate with explicitly given major (labelled) and
/// minor (light grid) tick positions.
#[derive(Clone, Debug)]
pub(super) struct TickRange {
    pub(super) lo: f64,
    pub(super) hi: f64,
    pub(super) major: Vec<f64>,
    pub(super) minor: Vec<f64>,
}

impl Ranged for TickRange {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        // Halved operands: no overflow even for a range of +-f64::MAX.
        let t = (*v * 0.5 - self.lo * 0.5) / (self.hi * 0.5 - self.lo * 0.5);
        // Clamp so far-away or non-finite values can never overflow i32.
        let t = if t.is_nan() { 0.0 } else { t.clamp(-4.0, 5.0) };
        let len = f64::from(limit.1) - f64::from(limit.0);
        (f64::from(limit.0) + len * t).round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.minor.clone()
        } else {
            self.major.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

/// Label of the log-axis tick at exponent `v` (`0.01`, `200`, `5e-7`).
pub(super) fn fmt_log_tick(v: f64) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    let mut e = v.floor();
    let mut m = 10f64.powf(v - e);
    if m >= 10.0 - 1e-9 {
        m /= 10.0;
        e += 1.0;
    }
    // Round the mantissa to 6 significant digits to hide powf noise.
    let m = (m * 1e5).round() / 1e5;
    if (-3.0..6.0).contains(&e) {
        fmt_general(m * 10f64.powi(e as i32))
    } else {
        format!("{}e{}", fmt_general(m), e)
    }
}

/// Short, exact-looking representation of a value (`0.002`, `150`, `2e6`).
pub(super) fn fmt_general(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let a = v.abs();
    let close = |s: &str, target: f64| {
        s.parse::<f64>()
            .map(|p| (p - target).abs() <= target.abs() * 1e-9)
            .unwrap_or(false)
    };
    if (1e-3..1e6).contains(&a) {
        for d in 0..=6 {
            let s = format!("{:.*}", d, v);
            if close(&s, v) {
                return s;
            }
        }
        format!("{:.6}", v)
    } else {
        let e = a.log10().floor();
        let m = v / 10f64.powf(e);
        for d in 0..=6 {
            let s = format!("{:.*}", d, m);
            if close(&s, m) {
                return format!("{s}e{e}");
            }
        }
        format!("{v:e}")
    }
}

/// Padding used when a range collapses to a single value.
pub(super) fn degenerate_pad(mid: f64) -> f64 {
    if mid == 0.0 || !mid.is_finite() {
        1.0
    } else {
        mid.abs() * 0.1
    }
}

/// Non-degenerate range from data extremes (in drawing coordinates).
pub(super) fn auto_range(min: f64, max: f64, log: bool) -> (f64, f64) {
    if !(min.is_finite() && max.is_finite()) || min > max {
        return (0.0, 1.0);
    }
    let span = max - min;
    let scale = min.abs().max(max.abs());
    if span <= scale * 1e-12 || span == 0.0 {
        let mid = 0.5 * (min + max);
        let pad = if log { 0.5 } else { degenerate_pad(mid) };
        return (mid - pad, mid + pad);
    }
    let m = span * 0.05;
    let (lo, hi) = (min - m, max + m);
    if lo.is_finite() && hi.is_finite() {
        (lo, hi)
    } else {
        (min, max)
    }
}

/// Validates an explicit range and converts it to drawing coordinates.
pub(super) fn explicit_range(
    r: (f64, f64),
    log: bool,
    what: &str,
) -> Result<(f64, f64), PlotError> {
    let (mut a, mut b) = r;
    if !(a.is_finite() && b.is_finite()) {
        return Err(PlotError::InvalidInput(format!(
            "{what} range ({a}, {b}) is not finite"
        )));
    }
    if log {
        if a <= 0.0 || b <= 0.0 {
            return Err(PlotError::InvalidInput(format!(
                "{what} range ({a}, {b}) must be positive on a log axis"
            )));
        }
        a = a.log10();
        b = b.log10();
    }
    if a > b {
        std::mem::swap(&mut a, &mut b);
    }
    let scale = a.abs().max(b.abs());
    if b - a <= scale * 1e-12 {
        let mid = 0.5 * (a + b);
        let pad = if log { 0.5 } else { degenerate_pad(mid) };
        return Ok((mid - pad, mid + pad));
    }
    Ok((a, b))
}
