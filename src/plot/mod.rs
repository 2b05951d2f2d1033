//! Publication-quality plots for cable-servo design reviews, drawn from result records only.
//! Edge layer: imports nothing of this crate.
//!
//! Every figure is written twice, as `<stem>.png` (raster, for slides and
//! quick looks) and `<stem>.svg` (vector, for documents). Text is rendered
//! with the DejaVu Sans font that is compiled into the binary, so no system
//! font libraries are needed.
//!
//! Robustness rules that hold for every public function here:
//!
//! * nothing panics on bad data: NaN/infinite samples are skipped, empty
//!   series are skipped, degenerate ranges are padded, and a chart without a
//!   single finite point still yields a valid (empty) figure;
//! * files are written atomically: drawing happens into a temporary
//!   `<stem>.png.tmp` / `<stem>.svg.tmp` next to the target which is renamed
//!   into place only after the figure was completely written;
//! * long traces are reduced with [`decimate_minmax`] (about one bucket per
//!   pixel of plot width) so a 200k-sample trace draws fast without losing
//!   peaks.

use std::path::{Path, PathBuf};

use plotters::prelude::*;

mod annotated;
mod axis;
mod chart;
mod heatmap;
mod output;
mod prepare;
#[cfg(test)]
mod tests;

pub use annotated::{save_annotated, AnnotatedFigure, Arrowhead, Dash, Mark, Panel, Shape, Trace};
use axis::*;
use chart::*;
use heatmap::*;
use output::*;
use prepare::*;

/// Font family used for every text element (registered from the `dejavu` crate).
const FONT: &str = "sans-serif";
/// Size of a single chart figure in pixels.
const CHART_SIZE: (u32, u32) = (1200, 700);
/// Width of a panel figure in pixels.
const PANEL_WIDTH: u32 = 1200;
/// Height of one panel of a panel figure in pixels.
const PANEL_HEIGHT: u32 = 360;
/// Most panels in one panel figure (keeps the bitmap size sane).
const MAX_PANELS: usize = 16;
/// Size of a heat-map figure in pixels.
const HEATMAP_SIZE: (u32, u32) = (1200, 800);
/// Figure title size.
const TITLE_PX: u32 = 28;
/// Title size of the individual charts inside a panel figure.
const PANEL_TITLE_PX: u32 = 22;
/// Axis description size.
const DESC_PX: u32 = 20;
/// Tick label size.
const TICK_PX: u32 = 16;
/// Legend text size.
const LEGEND_PX: u32 = 16;
/// Height of the x label area (tick labels plus axis description).
const X_AREA_PX: u32 = 64;
/// Margin around every chart.
const MARGIN_PX: u32 = 14;

/// tab10-like palette, distinct and colour-blind friendlier than pure RGB.
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Band colours: the first band is green (target / acceptable zone), the
/// second red (limit / forbidden zone), further bands cycle through the rest.
const BAND_COLORS: [RGBColor; 4] = [
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(31, 119, 180),
    RGBColor(148, 103, 189),
];

/// Colour of missing / failed heat-map cells: a light grey that no colour scale here
/// contains, drawn with a dark cross so it reads as "no value" even in greyscale.
const MISSING_COLOR: RGBColor = RGBColor(190, 190, 190);
/// Shade of the x intervals a chart marks as not judged (outside the metrics window).
const SHADE_COLOR: RGBColor = RGBColor(120, 120, 120);
/// Width of the legend column right of a chart's plotting area, in pixels: wide enough
/// for a mode label and a short note; longer text wraps.
const LEGEND_WIDTH_PX: u32 = 250;
/// Two curves closer than this fraction of the y axis' span everywhere in view are
/// reported as coinciding (0.5 %: about 2 px on a 360 px panel, where one hides the other).
const COINCIDE_FRACTION: f64 = 0.005;
/// Colour of the heat-map contour line (drawn over a white halo).
const CONTOUR_COLOR: RGBColor = RGBColor(220, 20, 60);

/// Viridis colour map anchors (perceptually uniform, colour-blind safe).
const VIRIDIS: [(u8, u8, u8); 11] = [
    (68, 1, 84),
    (72, 35, 116),
    (64, 67, 135),
    (52, 94, 141),
    (41, 120, 142),
    (32, 144, 140),
    (34, 167, 132),
    (68, 190, 112),
    (121, 209, 81),
    (189, 222, 38),
    (253, 231, 37),
];

/// Errors returned by the plotting functions.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The drawing backend (font rendering, PNG encoder, SVG writer) failed
    /// while producing `path`.
    #[error("failed to draw {}: {message}", path.display())]
    Backend {
        /// File that was being produced.
        path: PathBuf,
        /// Backend error message.
        message: String,
    },
    /// Creating a directory, renaming or removing a file failed.
    #[error("i/o error on {}: {source}", path.display())]
    Io {
        /// File or directory the operation was applied to.
        path: PathBuf,
        /// Underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The input cannot be plotted (mismatched dimensions, invalid explicit
    /// range, empty grid, ...). The string describes the problem.
    #[error("invalid plot input: {0}")]
    InvalidInput(String),
}

/// How a [`Series`] is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SeriesStyle {
    /// Straight lines between consecutive samples (broken at NaN/inf samples).
    Line,
    /// One marker per sample, no connecting lines.
    Points,
    /// Zero-order-hold staircase: each sample holds its value until the next
    /// sample's x (the natural look of sampled controller outputs).
    Step,
}

/// One data series of a [`Chart`].
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label; an empty label keeps the series out of the legend.
    pub label: String,
    /// x samples.
    pub x: Vec<f64>,
    /// y samples (pairs beyond the shorter of `x`/`y` are ignored).
    pub y: Vec<f64>,
    /// Drawing style.
    pub style: SeriesStyle,
    /// Palette slot (0 to 9) that fixes the colour, so one quantity (a compensation mode)
    /// keeps its colour in every figure; `None` = the series' position in the chart.
    pub palette_slot: Option<usize>,
    /// A colour of its own (red, green, blue), ahead of the palette: black for a
    /// reference, [`family_colour`] for a family ordered by a parameter.
    pub rgb: Option<[u8; 3]>,
    /// Shown for context, not judged (samples before the metrics window): drawn plain
    /// (no dashes, no markers) and kept out of the automatic y range, which the other
    /// series set, so it cannot squeeze them; beyond that range it is marked off scale.
    pub context: bool,
}

/// Colour of samples shown for context only ([`Series::context`]): a light grey under
/// the judged curves.
pub const CONTEXT_RGB: [u8; 3] = [185, 185, 185];

/// Colour of a reference curve drawn among measured ones.
pub const REFERENCE_RGB: [u8; 3] = [0, 0, 0];

/// Colour of member `i` of `n` in a family ordered by a parameter (an amplitude): from
/// dark blue through teal to yellow-green, so neighbours look alike and the order reads
/// off the figure however many members there are (a viridis-like ramp).
pub fn family_colour(i: usize, n: usize) -> [u8; 3] {
    const RAMP: [[f64; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [200.0, 210.0, 30.0],
    ];
    let t = if n > 1 {
        i as f64 / (n - 1) as f64
    } else {
        0.0
    };
    let x = t.clamp(0.0, 1.0) * (RAMP.len() - 1) as f64;
    let k = (x.floor() as usize).min(RAMP.len() - 2);
    let f = x - k as f64;
    std::array::from_fn(|c| (RAMP[k][c] + f * (RAMP[k + 1][c] - RAMP[k][c])).round() as u8)
}

impl Series {
    /// The same series in its own colour.
    pub fn in_rgb(mut self, rgb: [u8; 3]) -> Self {
        self.rgb = Some(rgb);
        self
    }

    /// The same series in palette slot `slot` (0 to 9, wrapping).
    pub fn in_slot(mut self, slot: usize) -> Self {
        self.palette_slot = Some(slot);
        self
    }

    /// The same series shown for context only, in [`CONTEXT_RGB`] (see [`Series::context`]).
    pub fn as_context(mut self) -> Self {
        self.context = true;
        self.rgb = Some(CONTEXT_RGB);
        self
    }

    /// A series drawn as a connected line.
    pub fn line(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            x,
            y,
            style: SeriesStyle::Line,
            palette_slot: None,
            rgb: None,
            context: false,
        }
    }

    /// A series drawn as individual markers.
    pub fn points(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            x,
            y,
            style: SeriesStyle::Points,
            palette_slot: None,
            rgb: None,
            context: false,
        }
    }

    /// A series drawn as a zero-order-hold staircase.
    pub fn step(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            x,
            y,
            style: SeriesStyle::Step,
            palette_slot: None,
            rgb: None,
            context: false,
        }
    }
}

/// An x interval drawn shaded grey behind the data, e.g. the start-up transient outside
/// the metrics window: the data stay drawn, the shade says they are not judged.
#[derive(Clone, Debug)]
pub struct XShade {
    /// Start of the interval (x units; `-inf` reaches the left edge).
    pub lo: f64,
    /// End of the interval (x units; `inf` reaches the right edge).
    pub hi: f64,
    /// Legend label (empty = not in legend); equal labels share one legend entry.
    pub label: String,
}

/// Horizontal band drawn shaded, e.g. the +-0.1 mrad pointing target.
///
/// The first band of a chart is shaded light green, the second light red,
/// further ones in other light colours. `lo`/`hi` may be given in either
/// order; an infinite limit extends the band to the edge of the plot, a NaN
/// limit makes the band invisible. Finite limits are included in the
/// automatic y range. A non-empty `label` puts the band into the legend.
#[derive(Clone, Debug)]
pub struct HBand {
    /// Lower y limit.
    pub lo: f64,
    /// Upper y limit.
    pub hi: f64,
    /// Legend label (empty = not in legend).
    pub label: String,
}

/// An x/y chart with any number of series and shaded horizontal bands.
#[derive(Clone, Debug, Default)]
pub struct Chart {
    /// Chart title (empty = no title).
    pub title: String,
    /// x axis description, e.g. `"time [s]"`.
    pub x_label: String,
    /// y axis description, e.g. `"pointing error [mrad]"`.
    pub y_label: String,
    /// Data series, coloured in order from a tab10-like palette.
    pub series: Vec<Series>,
    /// Shaded horizontal bands drawn behind the series.
    pub bands: Vec<HBand>,
    /// Explicit x range; `None` = automatic from the finite data (+5% margin).
    /// Must be finite (and positive when `log_x`); reversed limits are swapped.
    pub x_range: Option<(f64, f64)>,
    /// Explicit y range; `None` = automatic from the finite data and finite
    /// band limits (+5% margin). Must be finite; reversed limits are swapped.
    pub y_range: Option<(f64, f64)>,
    /// log10 x axis (for sweeps); samples with non-positive x are skipped.
    pub log_x: bool,
    /// log10 y axis (spectra); samples with non-positive y are skipped, and so are bands.
    pub log_y: bool,
    /// Shaded x intervals (not judged), drawn behind everything.
    pub x_shades: Vec<XShade>,
    /// Automatic y range fitted to the samples with x in this interval only (the metrics
    /// window), so a start-up transient does not set the scale; samples beyond the axis
    /// are marked "off scale" at its edge. `None` = every sample.
    pub y_fit_x: Option<(f64, f64)>,
    /// Names instead of numbers on the x axis: `(position, name)`, e.g. categories at
    /// 1, 2, 3; empty = numeric ticks.
    pub x_names: Vec<(f64, String)>,
    /// Names instead of numbers on the y axis, as `x_names`.
    pub y_names: Vec<(f64, String)>,
    /// Notes printed under the legend (what the figure leaves out or clips).
    pub notes: Vec<String>,
}

/// Heat map over two parameters, `z[iy][ix]`.
///
/// `x` and `y` are the (strictly monotonic, finite) parameter values at the
/// cell centres; cell edges lie half-way between neighbours. NaN/infinite
/// cells are drawn in a neutral grey "missing/failed" colour. If `contour`
/// is set, a thick line is drawn along the cell edges where `z` crosses that
/// level (e.g. the 0.1 mrad pointing target). A colour bar labelled with
/// `z_label` is drawn to the right.
#[derive(Clone, Debug, Default)]
pub struct Heatmap {
    /// Figure title (empty = no title).
    pub title: String,
    /// x axis description.
    pub x_label: String,
    /// y axis description.
    pub y_label: String,
    /// Colour bar description.
    pub z_label: String,
    /// Parameter values of the columns.
    pub x: Vec<f64>,
    /// Parameter values of the rows.
    pub y: Vec<f64>,
    /// Values, `z[iy][ix]`; must have `y.len()` rows of `x.len()` values.
    pub z: Vec<Vec<f64>>,
    /// Optional contour level.
    pub contour: Option<f64>,
    /// log10 x axis (a log-spaced sweep variable): cell edges at the geometric means of
    /// neighbouring centres, so every cell has its centre in the middle on the axis. The
    /// values must then be positive.
    pub log_x: bool,
    /// log10 y axis, as `log_x`.
    pub log_y: bool,
    /// log10 colour scale, for values spread over decades (an RMS error over a sweep),
    /// where a linear scale paints most cells one colour. Ignored (linear) when a finite
    /// value is not positive.
    pub log_z: bool,
}

/// Writes `<stem>.png` (1200x700) and `<stem>.svg`; returns both paths.
///
/// `<stem>` gets the extensions appended (so `run_0.1` becomes
/// `run_0.1.png`); its parent directory is created if missing.
pub fn save_chart(chart: &Chart, stem: &Path) -> Result<Vec<PathBuf>, PlotError> {
    let prepared = prepare_chart(chart, plot_buckets(CHART_SIZE.0))?;
    save_figure(&SingleFigure(prepared), stem)
}

/// Several charts stacked vertically in one figure (shared figure title),
/// e.g. angles / error / tensions. Writes `<stem>.png` and `<stem>.svg`
/// (1200 px wide, 360 px per panel) and returns both paths. The plot areas
/// of all panels are aligned horizontally. 1 to 16 charts are accepted;
/// anything else is a [`PlotError::InvalidInput`].
pub fn save_panels(title: &str, charts: &[Chart], stem: &Path) -> Result<Vec<PathBuf>, PlotError> {
    if charts.is_empty() || charts.len() > MAX_PANELS {
        return Err(PlotError::InvalidInput(format!(
            "save_panels needs 1 to {MAX_PANELS} charts, got {}",
            charts.len()
        )));
    }
    let buckets = plot_buckets(PANEL_WIDTH);
    let panels = charts
        .iter()
        .map(|c| prepare_chart(c, buckets))
        .collect::<Result<Vec<_>, _>>()?;
    save_figure(
        &PanelFigure {
            title: title.to_string(),
            panels,
        },
        stem,
    )
}

/// Heat map over two parameters, `z[iy][ix]`; NaN cells drawn as a neutral
/// grey "missing/failed" colour; an optional contour level drawn as a thick
/// line along cell edges where z crosses the level; colour bar with
/// `z_label`. Writes `<stem>.png` (1200x800) and `<stem>.svg` and returns
/// both paths.
pub fn save_heatmap(map: &Heatmap, stem: &Path) -> Result<Vec<PathBuf>, PlotError> {
    let prepared = prepare_heatmap(map)?;
    save_figure(&HeatFigure(prepared), stem)
}

/// Reduce a long series to at most `2*buckets` points keeping min and max of
/// y per x-bucket (in original order), so a 200k-sample trace draws fast and
/// loses no peaks. Series shorter than that are returned unchanged.
///
/// Details:
/// * only the first `min(x.len(), y.len())` pairs are considered;
/// * `buckets == 0` is treated as 1;
/// * when the series is reduced, pairs with a NaN/infinite coordinate are
///   dropped (a series of only non-finite pairs reduces to nothing);
/// * buckets are equal-width intervals of x when the finite x values are
///   non-decreasing (the usual time trace); otherwise (e.g. a hysteresis
///   loop) they are equal-count runs of consecutive samples, which keeps the
///   trajectory's shape;
/// * within a bucket the minimum and maximum sample are emitted in their
///   original order (once if they are the same sample).
pub fn decimate_minmax(x: &[f64], y: &[f64], buckets: usize) -> (Vec<f64>, Vec<f64>) {
    let n = x.len().min(y.len());
    let buckets = buckets.max(1);
    if n <= buckets.saturating_mul(2) {
        return (x[..n].to_vec(), y[..n].to_vec());
    }
    let finite: Vec<usize> = (0..n)
        .filter(|&i| x[i].is_finite() && y[i].is_finite())
        .collect();
    let m = finite.len();
    if m == 0 {
        return (Vec::new(), Vec::new());
    }
    let mut sorted = true;
    let mut xmin = f64::INFINITY;
    let mut xmax = f64::NEG_INFINITY;
    let mut prev = f64::NEG_INFINITY;
    for &i in &finite {
        let xi = x[i];
        if xi < prev {
            sorted = false;
        }
        prev = xi;
        xmin = xmin.min(xi);
        xmax = xmax.max(xi);
    }
    let width = xmax - xmin;
    let by_value = sorted && width > 0.0 && width.is_finite();
    let bucket_of = |k: usize, i: usize| -> usize {
        if by_value {
            let b = ((x[i] - xmin) / width * buckets as f64).floor();
            // `as` saturates; NaN cannot occur (finite inputs, width > 0).
            (b.max(0.0) as usize).min(buckets - 1)
        } else {
            ((k as u128 * buckets as u128) / m as u128) as usize
        }
    };

    let mut out_x = Vec::with_capacity(2 * buckets);
    let mut out_y = Vec::with_capacity(2 * buckets);
    let mut flush = |lo: usize, hi: usize| {
        let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
        out_x.push(x[a]);
        out_y.push(y[a]);
        if b != a {
            out_x.push(x[b]);
            out_y.push(y[b]);
        }
    };
    let mut current = usize::MAX;
    let (mut imin, mut imax) = (0usize, 0usize);
    for (k, &i) in finite.iter().enumerate() {
        let b = bucket_of(k, i);
        if b != current {
            if current != usize::MAX {
                flush(imin, imax);
            }
            current = b;
            imin = i;
            imax = i;
        } else {
            if y[i] < y[imin] {
                imin = i;
            }
            if y[i] > y[imax] {
                imax = i;
            }
        }
    }
    if current != usize::MAX {
        flush(imin, imax);
    }
    (out_x, out_y)
}
