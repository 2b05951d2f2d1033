//! Chart preparation, pure data work with no drawing: clipping, staircases, min/max reduction per pixel column, ranges.

use plotters::prelude::*;
use std::collections::HashSet;

use super::*;

pub(super) type Pt = (f64, f64);

/// Axis-aligned clip box in drawing coordinates.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bounds {
    pub(super) x0: f64,
    pub(super) x1: f64,
    pub(super) y0: f64,
    pub(super) y1: f64,
}

impl Bounds {
    pub(super) fn contains(&self, p: Pt) -> bool {
        p.0 >= self.x0 && p.0 <= self.x1 && p.1 >= self.y0 && p.1 <= self.y1
    }
}

/// Liang–Barsky clipping of segment `p`-`q`. Unclipped ends are returned
/// bit-identical so polylines can be re-joined.
pub(super) fn clip_segment(p: Pt, q: Pt, b: &Bounds) -> Option<(Pt, Pt)> {
    let dx = q.0 - p.0;
    let dy = q.1 - p.1;
    let mut t0 = 0.0f64;
    let mut t1 = 1.0f64;
    for (pp, qq) in [
        (-dx, p.0 - b.x0),
        (dx, b.x1 - p.0),
        (-dy, p.1 - b.y0),
        (dy, b.y1 - p.1),
    ] {
        if pp == 0.0 {
            if qq < 0.0 {
                return None;
            }
        } else {
            let r = qq / pp;
            if pp < 0.0 {
                if r > t1 {
                    return None;
                }
                t0 = t0.max(r);
            } else {
                if r < t0 {
                    return None;
                }
                t1 = t1.min(r);
            }
        }
    }
    let a = if t0 == 0.0 {
        p
    } else {
        (p.0 + t0 * dx, p.1 + t0 * dy)
    };
    let c = if t1 == 1.0 {
        q
    } else {
        (p.0 + t1 * dx, p.1 + t1 * dy)
    };
    let ok = a.0.is_finite() && a.1.is_finite() && c.0.is_finite() && c.1.is_finite();
    ok.then_some((a, c))
}

/// Clips a polyline to `b`, splitting it where it leaves the box.
pub(super) fn clip_polyline(pts: &[Pt], b: &Bounds) -> Vec<Vec<Pt>> {
    let mut out = Vec::new();
    let mut cur: Vec<Pt> = Vec::new();
    let flush = |cur: &mut Vec<Pt>, out: &mut Vec<Vec<Pt>>| {
        if cur.len() >= 2 {
            out.push(std::mem::take(cur));
        } else {
            cur.clear();
        }
    };
    for w in pts.windows(2) {
        match clip_segment(w[0], w[1], b) {
            None => flush(&mut cur, &mut out),
            Some((a, c)) => {
                if cur.last() != Some(&a) {
                    flush(&mut cur, &mut out);
                    cur.push(a);
                }
                cur.push(c);
                if c != w[1] {
                    flush(&mut cur, &mut out);
                }
            }
        }
    }
    flush(&mut cur, &mut out);
    out
}

/// Zero-order-hold staircase through the samples.
pub(super) fn staircase(x: &[f64], y: &[f64]) -> Vec<Pt> {
    let n = x.len().min(y.len());
    let mut out = Vec::with_capacity(2 * n);
    for i in 0..n {
        out.push((x[i], y[i]));
        if i + 1 < n {
            out.push((x[i + 1], y[i]));
        }
    }
    out
}

/// Splits a series into runs of consecutive drawable samples (drawing
/// coordinates; non-finite or out-of-domain samples break runs).
pub(super) fn drawable_runs(s: &Series, log_x: bool, log_y: bool) -> Vec<(Vec<f64>, Vec<f64>)> {
    let n = s.x.len().min(s.y.len());
    let mut runs = Vec::new();
    let mut cx = Vec::new();
    let mut cy = Vec::new();
    for i in 0..n {
        let x = if log_x {
            if s.x[i] > 0.0 {
                s.x[i].log10()
            } else {
                f64::NAN
            }
        } else {
            s.x[i]
        };
        let y = if log_y {
            if s.y[i] > 0.0 {
                s.y[i].log10()
            } else {
                f64::NAN
            }
        } else {
            s.y[i]
        };
        if x.is_finite() && y.is_finite() {
            cx.push(x);
            cy.push(y);
        } else if !cx.is_empty() {
            runs.push((std::mem::take(&mut cx), std::mem::take(&mut cy)));
        }
    }
    if !cx.is_empty() {
        runs.push((cx, cy));
    }
    runs
}

/// Keeps the parts of a run that can be visible in the x range `[lo, hi]`:
/// samples inside it and samples whose segment to a neighbour crosses it.
pub(super) fn trim_to_x(rx: &[f64], ry: &[f64], lo: f64, hi: f64) -> Vec<(Vec<f64>, Vec<f64>)> {
    let n = rx.len().min(ry.len());
    let seg_visible = |a: usize, b: usize| rx[a].min(rx[b]) <= hi && rx[a].max(rx[b]) >= lo;
    let mut out = Vec::new();
    let (mut cx, mut cy) = (Vec::new(), Vec::new());
    for i in 0..n {
        let keep = (rx[i] >= lo && rx[i] <= hi)
            || (i > 0 && seg_visible(i - 1, i))
            || (i + 1 < n && seg_visible(i, i + 1));
        if keep {
            cx.push(rx[i]);
            cy.push(ry[i]);
        } else if !cx.is_empty() {
            out.push((std::mem::take(&mut cx), std::mem::take(&mut cy)));
        }
    }
    if !cx.is_empty() {
        out.push((cx, cy));
    }
    out
}

/// Drops markers that would land on the same pixel (visually lossless).
pub(super) fn dedupe_markers(pts: Vec<Pt>, b: &Bounds) -> Vec<Pt> {
    if pts.len() <= 4000 {
        return pts;
    }
    let (w, h) = (b.x1 - b.x0, b.y1 - b.y0);
    let mut seen = HashSet::with_capacity(pts.len().min(1 << 16));
    pts.into_iter()
        .filter(|p| {
            let kx = ((p.0 - b.x0) / w * 2400.0) as i64;
            let ky = ((p.1 - b.y0) / h * 1400.0) as i64;
            seen.insert((kx, ky))
        })
        .collect()
}

/// A series ready for drawing (drawing coordinates, clipped).
#[derive(Debug)]
pub(super) struct PreparedSeries {
    pub(super) label: String,
    pub(super) color: RGBColor,
    pub(super) style: SeriesStyle,
    pub(super) lines: Vec<Vec<Pt>>,
    pub(super) dots: Vec<Pt>,
    /// Has at least one drawable sample anywhere (decides the legend entry).
    pub(super) has_data: bool,
    /// Shown for context only: a plain line, its legend sample without a marker.
    pub(super) context: bool,
    /// Dash pattern and marker shape (index into [`LINE_PATTERNS`]), so curves of one
    /// colour family or curves drawn over each other stay apart.
    pub(super) pattern: usize,
    /// Where the series' identifying markers sit (a few per curve, staggered per series).
    pub(super) markers: Vec<Pt>,
    /// x of samples above the y axis (one per pixel column group), marked at the top edge.
    pub(super) off_above: Vec<f64>,
    /// x of samples below the y axis, marked at the bottom edge.
    pub(super) off_below: Vec<f64>,
}

/// Dash patterns (on, off, ... lengths in pixels; empty = solid) by pattern index.
pub(super) const LINE_PATTERNS: [&[f64]; 4] =
    [&[], &[12.0, 6.0], &[3.0, 4.0], &[12.0, 4.0, 3.0, 4.0]];

/// Identifying markers per curve.
const MARKERS_PER_SERIES: usize = 8;

/// An x interval shaded as not judged (drawing coordinates, within the x axis).
#[derive(Debug)]
pub(super) struct PreparedShade {
    pub(super) lo: f64,
    pub(super) hi: f64,
    pub(super) label: String,
}

/// A band ready for drawing (clamped to the y axis).
#[derive(Debug)]
pub(super) struct PreparedBand {
    pub(super) lo: f64,
    pub(super) hi: f64,
    pub(super) label: String,
    pub(super) color: RGBColor,
}

/// A chart ready for drawing.
#[derive(Debug)]
pub(super) struct PreparedChart {
    pub(super) title: String,
    pub(super) x_label: String,
    pub(super) y_label: String,
    pub(super) x: Axis,
    pub(super) y: Axis,
    pub(super) series: Vec<PreparedSeries>,
    pub(super) bands: Vec<PreparedBand>,
    pub(super) shades: Vec<PreparedShade>,
    /// Notes under the legend: the chart's own, coinciding curves, data off scale.
    pub(super) notes: Vec<String>,
    pub(super) has_data: bool,
}

impl PreparedChart {
    pub(super) fn has_legend(&self) -> bool {
        self.series
            .iter()
            .any(|s| s.has_data && !s.label.is_empty())
            || self.bands.iter().any(|b| !b.label.is_empty())
            || self.shades.iter().any(|b| !b.label.is_empty())
            || !self.notes.is_empty()
    }
}

/// A value in drawing coordinates (log10 on a log axis; NaN where a log axis has none).
fn to_drawing(v: f64, log: bool) -> f64 {
    if !log {
        v
    } else if v > 0.0 {
        v.log10()
    } else {
        f64::NAN
    }
}

/// Whether two series draw the same curve: identical x samples and y within `tol`
/// (drawing coordinates) wherever both are in the x range `[x0, x1]` and finite.
fn coincide(a: &Series, b: &Series, log: (bool, bool), x_view: (f64, f64), tol: f64) -> bool {
    let n = a.x.len().min(a.y.len());
    if n == 0 || n != b.x.len().min(b.y.len()) || a.x[..n] != b.x[..n] {
        return false;
    }
    let mut compared = 0usize;
    for i in 0..n {
        let x = to_drawing(a.x[i], log.0);
        if !(x >= x_view.0 && x <= x_view.1) {
            continue;
        }
        let (ya, yb) = (to_drawing(a.y[i], log.1), to_drawing(b.y[i], log.1));
        match (ya.is_finite(), yb.is_finite()) {
            (true, true) => {
                if (ya - yb).abs() > tol {
                    return false;
                }
                compared += 1;
            }
            (false, false) => {}
            _ => return false,
        }
    }
    compared > 0
}

/// A few points of the drawn curve at staggered x positions (by `pattern`), so the
/// markers of different curves do not sit on each other.
fn marker_points(lines: &[Vec<Pt>], x0: f64, x1: f64, pattern: usize) -> Vec<Pt> {
    let pts: Vec<Pt> = lines.iter().flatten().copied().collect();
    if pts.is_empty() {
        return Vec::new();
    }
    let offset = (pattern % LINE_PATTERNS.len()) as f64 + 0.5;
    let slot = (x1 - x0) / MARKERS_PER_SERIES as f64;
    let mut out = Vec::new();
    let mut k = 0usize;
    for j in 0..MARKERS_PER_SERIES {
        let target = x0 + slot * (j as f64 + offset / LINE_PATTERNS.len() as f64);
        while k < pts.len() && pts[k].0 < target {
            k += 1;
        }
        match pts.get(k) {
            Some(p) if (p.0 - target).abs() <= slot * 0.5 => out.push(*p),
            _ => {}
        }
    }
    out
}

/// x of the samples beyond the y range, one per x bucket (about a marker's width),
/// `(above, below)`.
fn off_scale(runs: &[(Vec<f64>, Vec<f64>)], b: &Bounds) -> (Vec<f64>, Vec<f64>) {
    const BUCKETS: f64 = 120.0;
    let w = b.x1 - b.x0;
    let mut above: HashSet<i64> = HashSet::new();
    let mut below: HashSet<i64> = HashSet::new();
    for (rx, ry) in runs {
        for (&x, &y) in rx.iter().zip(ry) {
            if !(x >= b.x0 && x <= b.x1) {
                continue;
            }
            let k = ((x - b.x0) / w * BUCKETS).floor() as i64;
            if y > b.y1 {
                above.insert(k);
            } else if y < b.y0 {
                below.insert(k);
            }
        }
    }
    let centres = |set: HashSet<i64>| {
        let mut v: Vec<f64> = set
            .into_iter()
            .map(|k| b.x0 + (k as f64 + 0.5) / BUCKETS * w)
            .collect();
        v.sort_by(f64::total_cmp);
        v
    };
    (centres(above), centres(below))
}

/// Decimation buckets for a figure of the given width (≈ plot pixels).
pub(super) fn plot_buckets(fig_width: u32) -> usize {
    (fig_width as usize).saturating_sub(150).max(100)
}

pub(super) fn prepare_chart(chart: &Chart, buckets: usize) -> Result<PreparedChart, PlotError> {
    let log_x = chart.log_x;
    let log_y = chart.log_y;
    let runs: Vec<Vec<(Vec<f64>, Vec<f64>)>> = chart
        .series
        .iter()
        .map(|s| drawable_runs(s, log_x, log_y))
        .collect();

    // Data extents in drawing coordinates.
    let (mut xmin, mut xmax) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut ymin, mut ymax) = (f64::INFINITY, f64::NEG_INFINITY);
    let fit = chart.y_fit_x.map(|(a, b)| {
        let (a, b) = (to_drawing(a, log_x), to_drawing(b, log_x));
        (a.min(b), a.max(b))
    });
    let (mut fit_min, mut fit_max) = (f64::INFINITY, f64::NEG_INFINITY);
    // Context series set the y range only when nothing else has data to set it.
    let judged = |i: usize| !chart.series[i].context;
    let any_judged = runs
        .iter()
        .enumerate()
        .any(|(i, r)| judged(i) && !r.is_empty());
    for (i, series_runs) in runs.iter().enumerate() {
        let scales = judged(i) || !any_judged;
        for (rx, ry) in series_runs {
            for &v in rx {
                xmin = xmin.min(v);
                xmax = xmax.max(v);
            }
            for (&x, &v) in rx.iter().zip(ry).filter(|_| scales) {
                ymin = ymin.min(v);
                ymax = ymax.max(v);
                if fit.is_some_and(|(a, b)| x >= a && x <= b) {
                    fit_min = fit_min.min(v);
                    fit_max = fit_max.max(v);
                }
            }
        }
    }
    let has_data = xmin <= xmax;
    if fit_min <= fit_max {
        // The window holds data: it alone sets the scale (what lies outside is marked
        // off scale where it leaves the axis).
        (ymin, ymax) = (fit_min, fit_max);
    }
    for b in chart.bands.iter().filter(|_| !log_y) {
        for v in [b.lo, b.hi] {
            if v.is_finite() && !(b.lo.is_nan() || b.hi.is_nan()) {
                ymin = ymin.min(v);
                ymax = ymax.max(v);
            }
        }
    }

    let (x0, x1) = match chart.x_range {
        Some(r) => explicit_range(r, log_x, "x")?,
        None => auto_range(xmin, xmax, log_x),
    };
    let (y0, y1) = match chart.y_range {
        Some(r) => explicit_range(r, log_y, "y")?,
        None => auto_range(ymin, ymax, log_y),
    };
    let x_axis = if log_x {
        Axis::log10(x0, x1)
    } else {
        Axis::linear(x0, x1, 8)
    }
    .named(&chart.x_names);
    let y_axis = if log_y {
        Axis::log10(y0, y1)
    } else {
        Axis::linear(y0, y1, 6)
    }
    .named(&chart.y_names);
    let bounds = Bounds { x0, x1, y0, y1 };

    let mut series = Vec::with_capacity(chart.series.len());
    for (idx, (s, runs)) in chart.series.iter().zip(&runs).enumerate() {
        let mut lines = Vec::new();
        let mut dots = Vec::new();
        match s.style {
            SeriesStyle::Points => {
                for (rx, ry) in runs {
                    dots.extend(
                        rx.iter()
                            .zip(ry)
                            .map(|(&x, &y)| (x, y))
                            .filter(|&p| bounds.contains(p)),
                    );
                }
                dots = dedupe_markers(dots, &bounds);
            }
            SeriesStyle::Line | SeriesStyle::Step => {
                // Only what can be seen gets the pixel budget, so a zoomed
                // x range keeps full resolution.
                let visible: Vec<(Vec<f64>, Vec<f64>)> = runs
                    .iter()
                    .flat_map(|(rx, ry)| trim_to_x(rx, ry, x0, x1))
                    .collect();
                let total: usize = visible.iter().map(|(rx, _)| rx.len()).sum();
                for (rx, ry) in &visible {
                    let share = (buckets as f64 * rx.len() as f64 / total.max(1) as f64).ceil();
                    let (dx, dy) = decimate_minmax(rx, ry, (share as usize).max(1));
                    if dx.len() == 1 {
                        if bounds.contains((dx[0], dy[0])) {
                            dots.push((dx[0], dy[0]));
                        }
                        continue;
                    }
                    let pts: Vec<Pt> = if s.style == SeriesStyle::Step {
                        staircase(&dx, &dy)
                    } else {
                        dx.into_iter().zip(dy).collect()
                    };
                    lines.extend(clip_polyline(&pts, &bounds));
                }
            }
        }
        // Patterns and markers tell the curves of the legend apart; a curve outside it
        // (a bound, a guide) stays a plain line.
        let pattern = if s.label.is_empty() || s.context {
            0
        } else {
            s.rgb.map_or(s.palette_slot.unwrap_or(idx), |_| idx) % LINE_PATTERNS.len()
        };
        let (off_above, off_below) = off_scale(runs, &bounds);
        series.push(PreparedSeries {
            label: s.label.clone(),
            color: match s.rgb {
                Some([r, g, b]) => RGBColor(r, g, b),
                None => PALETTE[s.palette_slot.unwrap_or(idx) % PALETTE.len()],
            },
            style: s.style,
            markers: if s.label.is_empty() || s.context {
                Vec::new()
            } else {
                marker_points(&lines, x0, x1, pattern)
            },
            lines,
            dots,
            has_data: !runs.is_empty(),
            context: s.context,
            pattern,
            off_above,
            off_below,
        });
    }

    let mut notes = chart.notes.clone();
    let tol = COINCIDE_FRACTION * (y1 - y0);
    for j in 1..chart.series.len() {
        for i in 0..j {
            let (a, b) = (&chart.series[i], &chart.series[j]);
            if a.label.is_empty()
                || b.label.is_empty()
                || a.label == b.label
                || a.context
                || b.context
            {
                continue;
            }
            if coincide(a, b, (log_x, log_y), (x0, x1), tol) {
                notes.push(format!(
                    "{} coincides with {} (within {} % of the axis)",
                    b.label,
                    a.label,
                    COINCIDE_FRACTION * 100.0
                ));
            }
        }
    }
    if series
        .iter()
        .any(|s| !s.off_above.is_empty() || !s.off_below.is_empty())
    {
        notes.push("triangles at the axis edge: data off scale there".into());
    }

    let mut shades = Vec::new();
    for sh in &chart.x_shades {
        let lo = if sh.lo == f64::NEG_INFINITY {
            x0
        } else {
            to_drawing(sh.lo, log_x)
        };
        let hi = if sh.hi == f64::INFINITY {
            x1
        } else {
            to_drawing(sh.hi, log_x)
        };
        let (lo, hi) = (lo.min(hi).max(x0), hi.max(lo).min(x1));
        if lo < hi {
            shades.push(PreparedShade {
                lo,
                hi,
                label: sh.label.clone(),
            });
        }
    }

    let mut bands = Vec::new();
    for b in chart.bands.iter().filter(|_| !log_y) {
        if b.lo.is_nan() || b.hi.is_nan() {
            continue;
        }
        let (lo, hi) = if b.lo <= b.hi {
            (b.lo, b.hi)
        } else {
            (b.hi, b.lo)
        };
        let (lo, hi) = (lo.max(y0), hi.min(y1));
        if lo >= hi {
            continue;
        }
        bands.push(PreparedBand {
            lo,
            hi,
            label: b.label.clone(),
            color: BAND_COLORS[bands.len() % BAND_COLORS.len()],
        });
    }

    Ok(PreparedChart {
        title: chart.title.clone(),
        x_label: chart.x_label.clone(),
        y_label: chart.y_label.clone(),
        x: x_axis,
        y: y_axis,
        series,
        bands,
        shades,
        notes,
        has_data,
    })
}
