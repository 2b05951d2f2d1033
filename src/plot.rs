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

use std::collections::HashSet;
use std::ffi::OsString;
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};

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

/// Colour of missing / failed heat-map cells.
const MISSING_COLOR: RGBColor = RGBColor(190, 190, 190);
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
}

impl Series {
    /// A series drawn as a connected line.
    pub fn line(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            x,
            y,
            style: SeriesStyle::Line,
        }
    }

    /// A series drawn as individual markers.
    pub fn points(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            x,
            y,
            style: SeriesStyle::Points,
        }
    }

    /// A series drawn as a zero-order-hold staircase.
    pub fn step(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            x,
            y,
            style: SeriesStyle::Step,
        }
    }
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
}

/// Heat map over two parameters, `z[iy][ix]`.
///
/// `x` and `y` are the (strictly monotonic, finite) parameter values at the
/// cell centres; cell edges lie half-way between neighbours. NaN/infinite
/// cells are drawn in a neutral grey "missing/failed" colour. If `contour`
/// is set, a thick line is drawn along the cell edges where `z` crosses that
/// level (e.g. the 0.1 mrad pointing target). A colour bar labelled with
/// `z_label` is drawn to the right.
#[derive(Clone, Debug)]
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

// ---------------------------------------------------------------------------
// Fonts and file handling
// ---------------------------------------------------------------------------

/// Registers the embedded DejaVu Sans fonts under [`FONT`] exactly once.
fn ensure_fonts() -> Result<(), String> {
    static FONTS: OnceLock<Result<(), String>> = OnceLock::new();
    FONTS
        .get_or_init(|| {
            register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
                .map_err(|_| "cannot load embedded DejaVu Sans font".to_string())?;
            register_font(FONT, FontStyle::Bold, dejavu::sans::bold())
                .map_err(|_| "cannot load embedded DejaVu Sans Bold font".to_string())?;
            Ok(())
        })
        .clone()
}

/// A figure that can be rendered on any plotters backend.
trait Figure {
    /// Figure size in pixels.
    fn size(&self) -> (u32, u32);
    /// Draws the figure on a white root area.
    fn render<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String>;
}

/// `path` with `suffix` appended to its final component.
fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut s: OsString = path.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

/// Converts any displayable backend error into a message.
fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> PlotError + '_ {
    move |source| PlotError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Removes a leftover temporary file or directory of an earlier crashed run.
fn remove_stale(tmp: &Path) {
    if let Ok(meta) = fs::symlink_metadata(tmp) {
        let _ = if meta.is_dir() {
            fs::remove_dir_all(tmp)
        } else {
            fs::remove_file(tmp)
        };
    }
}

fn save_figure<F: Figure>(fig: &F, stem: &Path) -> Result<Vec<PathBuf>, PlotError> {
    if stem.file_name().is_none() {
        return Err(PlotError::InvalidInput(format!(
            "output stem {} has no file name",
            stem.display()
        )));
    }
    ensure_fonts().map_err(|message| PlotError::Backend {
        path: stem.to_path_buf(),
        message,
    })?;
    if let Some(parent) = stem.parent() {
        if !parent.as_os_str().is_empty() {
            fs::create_dir_all(parent).map_err(io_err(parent))?;
        }
    }
    let png = with_suffix(stem, ".png");
    let svg = with_suffix(stem, ".svg");
    write_png(fig, &png)?;
    write_svg(fig, &svg)?;
    Ok(vec![png, svg])
}

/// Renders the PNG atomically.
///
/// The bitmap encoder picks the image format from the file extension, so
/// the image is drawn to `<stem>.png.tmp/<name>.png` (a temporary directory
/// next to the target) and then renamed to `<stem>.png`.
fn write_png<F: Figure>(fig: &F, target: &Path) -> Result<(), PlotError> {
    let tmp_dir = with_suffix(target, ".tmp");
    remove_stale(&tmp_dir);
    fs::create_dir(&tmp_dir).map_err(io_err(&tmp_dir))?;
    let name = target.file_name().unwrap_or_else(|| "figure.png".as_ref());
    let tmp_file = tmp_dir.join(name);
    // The backend is dropped inside `draw`, before the clean-up.
    let result = draw(fig, BitMapBackend::new(&tmp_file, fig.size()), target)
        .and_then(|_| fs::rename(&tmp_file, target).map_err(io_err(target)));
    let _ = fs::remove_dir_all(&tmp_dir);
    result
}

/// Draws `fig` on a white background with `backend`; errors name `target`.
fn draw<F: Figure, DB: DrawingBackend>(
    fig: &F,
    backend: DB,
    target: &Path,
) -> Result<(), PlotError> {
    let root = backend.into_drawing_area();
    root.fill(&WHITE)
        .map_err(err)
        .and_then(|_| fig.render(&root))
        .and_then(|_| root.present().map_err(err))
        .map_err(|message| PlotError::Backend {
            path: target.to_path_buf(),
            message,
        })
}

/// Renders the SVG atomically via `<stem>.svg.tmp`.
fn write_svg<F: Figure>(fig: &F, target: &Path) -> Result<(), PlotError> {
    let tmp = with_suffix(target, ".tmp");
    remove_stale(&tmp);
    let result = draw(fig, SVGBackend::new(&tmp, fig.size()), target)
        .and_then(|_| fs::rename(&tmp, target).map_err(io_err(target)));
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

// ---------------------------------------------------------------------------
// Axes: ranges, ticks and labels
// ---------------------------------------------------------------------------

/// One axis in drawing coordinates (log10 of the value for a log axis).
#[derive(Clone, Debug)]
struct Axis {
    lo: f64,
    hi: f64,
    major: Vec<f64>,
    minor: Vec<f64>,
    log: bool,
    /// Linear tick step (0 when not applicable).
    step: f64,
    /// Scientific notation for linear labels.
    sci: bool,
}

/// "Nice" step (1, 2 or 5 times a power of ten) at least `raw`.
fn nice_step(raw: f64) -> Option<(f64, u32)> {
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
fn multiples(lo: f64, hi: f64, step: f64) -> Vec<f64> {
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
    fn linear(lo: f64, hi: f64, target: usize) -> Self {
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
    fn log10(lo: f64, hi: f64) -> Self {
        let mut axis = Axis {
            lo,
            hi,
            major: Vec::new(),
            minor: Vec::new(),
            log: true,
            step: 0.0,
            sci: false,
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

    /// Coordinate spec for plotters with our own tick positions.
    fn spec(&self) -> TickRange {
        TickRange {
            lo: self.lo,
            hi: self.hi,
            major: self.major.clone(),
            minor: self.minor.clone(),
        }
    }

    /// Tick label for drawing coordinate `v`.
    fn label(&self, v: f64) -> String {
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
struct TickRange {
    lo: f64,
    hi: f64,
    major: Vec<f64>,
    minor: Vec<f64>,
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
fn fmt_log_tick(v: f64) -> String {
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
fn fmt_general(v: f64) -> String {
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
fn degenerate_pad(mid: f64) -> f64 {
    if mid == 0.0 || !mid.is_finite() {
        1.0
    } else {
        mid.abs() * 0.1
    }
}

/// Non-degenerate range from data extremes (in drawing coordinates).
fn auto_range(min: f64, max: f64, log: bool) -> (f64, f64) {
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
fn explicit_range(r: (f64, f64), log: bool, what: &str) -> Result<(f64, f64), PlotError> {
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

// ---------------------------------------------------------------------------
// Chart preparation (pure data work, no drawing)
// ---------------------------------------------------------------------------

type Pt = (f64, f64);

/// Axis-aligned clip box in drawing coordinates.
#[derive(Clone, Copy, Debug)]
struct Bounds {
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
}

impl Bounds {
    fn contains(&self, p: Pt) -> bool {
        p.0 >= self.x0 && p.0 <= self.x1 && p.1 >= self.y0 && p.1 <= self.y1
    }
}

/// Liang–Barsky clipping of segment `p`-`q`. Unclipped ends are returned
/// bit-identical so polylines can be re-joined.
fn clip_segment(p: Pt, q: Pt, b: &Bounds) -> Option<(Pt, Pt)> {
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
fn clip_polyline(pts: &[Pt], b: &Bounds) -> Vec<Vec<Pt>> {
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
fn staircase(x: &[f64], y: &[f64]) -> Vec<Pt> {
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
fn drawable_runs(s: &Series, log_x: bool) -> Vec<(Vec<f64>, Vec<f64>)> {
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
        let y = s.y[i];
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
fn trim_to_x(rx: &[f64], ry: &[f64], lo: f64, hi: f64) -> Vec<(Vec<f64>, Vec<f64>)> {
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
fn dedupe_markers(pts: Vec<Pt>, b: &Bounds) -> Vec<Pt> {
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
struct PreparedSeries {
    label: String,
    color: RGBColor,
    style: SeriesStyle,
    lines: Vec<Vec<Pt>>,
    dots: Vec<Pt>,
    /// Has at least one drawable sample anywhere (decides the legend entry).
    has_data: bool,
}

/// A band ready for drawing (clamped to the y axis).
#[derive(Debug)]
struct PreparedBand {
    lo: f64,
    hi: f64,
    label: String,
    color: RGBColor,
}

/// A chart ready for drawing.
#[derive(Debug)]
struct PreparedChart {
    title: String,
    x_label: String,
    y_label: String,
    x: Axis,
    y: Axis,
    series: Vec<PreparedSeries>,
    bands: Vec<PreparedBand>,
    has_data: bool,
}

impl PreparedChart {
    fn has_legend(&self) -> bool {
        self.series
            .iter()
            .any(|s| s.has_data && !s.label.is_empty())
            || self.bands.iter().any(|b| !b.label.is_empty())
    }
}

/// Decimation buckets for a figure of the given width (≈ plot pixels).
fn plot_buckets(fig_width: u32) -> usize {
    (fig_width as usize).saturating_sub(150).max(100)
}

fn prepare_chart(chart: &Chart, buckets: usize) -> Result<PreparedChart, PlotError> {
    let log_x = chart.log_x;
    let runs: Vec<Vec<(Vec<f64>, Vec<f64>)>> = chart
        .series
        .iter()
        .map(|s| drawable_runs(s, log_x))
        .collect();

    // Data extents in drawing coordinates.
    let (mut xmin, mut xmax) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut ymin, mut ymax) = (f64::INFINITY, f64::NEG_INFINITY);
    for (rx, ry) in runs.iter().flatten() {
        for &v in rx {
            xmin = xmin.min(v);
            xmax = xmax.max(v);
        }
        for &v in ry {
            ymin = ymin.min(v);
            ymax = ymax.max(v);
        }
    }
    let has_data = xmin <= xmax;
    for b in &chart.bands {
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
        Some(r) => explicit_range(r, false, "y")?,
        None => auto_range(ymin, ymax, false),
    };
    let x_axis = if log_x {
        Axis::log10(x0, x1)
    } else {
        Axis::linear(x0, x1, 8)
    };
    let y_axis = Axis::linear(y0, y1, 6);
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
        series.push(PreparedSeries {
            label: s.label.clone(),
            color: PALETTE[idx % PALETTE.len()],
            style: s.style,
            lines,
            dots,
            has_data: !runs.is_empty(),
        });
    }

    let mut bands = Vec::new();
    for b in &chart.bands {
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
        has_data,
    })
}

// ---------------------------------------------------------------------------
// Chart drawing
// ---------------------------------------------------------------------------

fn tick_font() -> TextStyle<'static> {
    TextStyle::from((FONT, TICK_PX).into_font()).color(&RGBColor(40, 40, 40))
}

fn desc_font() -> TextStyle<'static> {
    TextStyle::from((FONT, DESC_PX).into_font()).color(&BLACK)
}

fn title_font(px: u32) -> TextStyle<'static> {
    TextStyle::from((FONT, px, FontStyle::Bold).into_font()).color(&BLACK)
}

/// Width of the y label area needed for the tick labels and the description.
fn y_area_width<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, axis: &Axis, desc: &str) -> u32 {
    let font = tick_font();
    let widest = axis
        .major
        .iter()
        .map(|&v| {
            let s = axis.label(v);
            area.estimate_text_size(&s, &font)
                .map(|(w, _)| w)
                .unwrap_or(TICK_PX * s.len() as u32 * 2 / 3)
        })
        .max()
        .unwrap_or(0);
    let desc_w = if desc.is_empty() { 0 } else { DESC_PX + 14 };
    widest + 18 + desc_w
}

/// Draws a prepared chart into `area`, with a y label area of `y_area` px.
fn draw_chart<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    p: &PreparedChart,
    title_px: u32,
    y_area: u32,
) -> Result<(), String> {
    let mut builder = ChartBuilder::on(area);
    builder
        .margin(MARGIN_PX)
        .margin_right(MARGIN_PX + 14)
        .x_label_area_size(if p.x_label.is_empty() {
            X_AREA_PX - DESC_PX - 8
        } else {
            X_AREA_PX
        })
        .y_label_area_size(y_area);
    if !p.title.is_empty() {
        builder.caption(&p.title, title_font(title_px));
    }
    let mut cc = builder
        .build_cartesian_2d(p.x.spec(), p.y.spec())
        .map_err(err)?;

    let xfmt = |v: &f64| p.x.label(*v);
    let yfmt = |v: &f64| p.y.label(*v);
    {
        let mut mesh = cc.configure_mesh();
        mesh.x_label_formatter(&xfmt)
            .y_label_formatter(&yfmt)
            .label_style(tick_font())
            .axis_desc_style(desc_font())
            .bold_line_style(BLACK.mix(0.13))
            .light_line_style(BLACK.mix(0.045))
            .axis_style(RGBColor(60, 60, 60));
        if !p.x_label.is_empty() {
            mesh.x_desc(p.x_label.as_str());
        }
        if !p.y_label.is_empty() {
            mesh.y_desc(p.y_label.as_str());
        }
        mesh.draw().map_err(err)?;
    }

    let (xl, xh) = (p.x.lo, p.x.hi);
    for b in &p.bands {
        let fill = b.color.mix(0.16).filled();
        let edge = b.color.mix(0.55).stroke_width(1);
        let anno = cc
            .draw_series(std::iter::once(Rectangle::new(
                [(xl, b.lo), (xh, b.hi)],
                fill,
            )))
            .map_err(err)?;
        if !b.label.is_empty() {
            anno.label(b.label.as_str())
                .legend(move |(x, y)| Rectangle::new([(x, y - 7), (x + 24, y + 7)], fill));
        }
        cc.draw_series(
            [b.lo, b.hi]
                .into_iter()
                .filter(|&v| v > p.y.lo && v < p.y.hi)
                .map(|v| PathElement::new(vec![(xl, v), (xh, v)], edge)),
        )
        .map_err(err)?;
    }

    for s in &p.series {
        let color = s.color;
        let line = color.stroke_width(2);
        let (marker, dot) = match s.style {
            SeriesStyle::Points => (4, 3),
            _ => (3, 2),
        };
        cc.draw_series(s.lines.iter().map(|l| PathElement::new(l.clone(), line)))
            .map_err(err)?;
        cc.draw_series(s.dots.iter().map(|&d| Circle::new(d, dot, color.filled())))
            .map_err(err)?;
        if s.has_data && !s.label.is_empty() {
            let anno = cc
                .draw_series(std::iter::empty::<PathElement<Pt>>())
                .map_err(err)?
                .label(s.label.as_str());
            match s.style {
                SeriesStyle::Line => {
                    anno.legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], line));
                }
                SeriesStyle::Step => {
                    anno.legend(move |(x, y)| {
                        PathElement::new(
                            vec![
                                (x, y + 5),
                                (x + 12, y + 5),
                                (x + 12, y - 5),
                                (x + 24, y - 5),
                            ],
                            line,
                        )
                    });
                }
                SeriesStyle::Points => {
                    anno.legend(move |(x, y)| Circle::new((x + 12, y), marker, color.filled()));
                }
            }
        }
    }

    if !p.has_data {
        let style = TextStyle::from((FONT, DESC_PX).into_font())
            .color(&RGBColor(120, 120, 120))
            .pos(Pos::new(HPos::Center, VPos::Center));
        cc.plotting_area()
            .draw(&Text::new(
                "no finite data",
                (0.5 * (xl + xh), 0.5 * (p.y.lo + p.y.hi)),
                style,
            ))
            .map_err(err)?;
    }

    if p.has_legend() {
        cc.configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .margin(12)
            .legend_area_size(32)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.35))
            .label_font(TextStyle::from((FONT, LEGEND_PX).into_font()).color(&BLACK))
            .draw()
            .map_err(err)?;
    }
    Ok(())
}

/// Figure with one chart.
struct SingleFigure(PreparedChart);

impl Figure for SingleFigure {
    fn size(&self) -> (u32, u32) {
        CHART_SIZE
    }

    fn render<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let y_area = y_area_width(root, &self.0.y, &self.0.y_label);
        draw_chart(root, &self.0, TITLE_PX, y_area)
    }
}

/// Figure with vertically stacked charts under a shared title.
struct PanelFigure {
    title: String,
    panels: Vec<PreparedChart>,
}

impl Figure for PanelFigure {
    fn size(&self) -> (u32, u32) {
        let n = self.panels.len().min(MAX_PANELS) as u32;
        let title = if self.title.is_empty() { 0 } else { 50 };
        (PANEL_WIDTH, title + PANEL_HEIGHT * n.max(1))
    }

    fn render<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let body = if self.title.is_empty() {
            root.clone()
        } else {
            let top = root.margin(8, 0, 0, 0);
            top.titled(&self.title, title_font(TITLE_PX)).map_err(err)?
        };
        // Same y label area everywhere so the plot areas line up.
        let y_area = self
            .panels
            .iter()
            .map(|p| y_area_width(root, &p.y, &p.y_label))
            .max()
            .unwrap_or(60);
        let areas = body.split_evenly((self.panels.len(), 1));
        for (area, panel) in areas.iter().zip(&self.panels) {
            draw_chart(area, panel, PANEL_TITLE_PX, y_area)?;
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------
// Heat map
// ---------------------------------------------------------------------------

/// Cell edges from strictly monotonic, finite cell-centre coordinates.
fn cell_edges(c: &[f64], what: &str) -> Result<Vec<f64>, PlotError> {
    if c.is_empty() {
        return Err(PlotError::InvalidInput(format!("heat map {what} is empty")));
    }
    if c.iter().any(|v| !v.is_finite()) {
        return Err(PlotError::InvalidInput(format!(
            "heat map {what} contains non-finite values"
        )));
    }
    if c.len() == 1 {
        let pad = degenerate_pad(c[0]);
        return Ok(vec![c[0] - pad, c[0] + pad]);
    }
    let increasing = c.windows(2).all(|w| w[1] > w[0]);
    let decreasing = c.windows(2).all(|w| w[1] < w[0]);
    if !(increasing || decreasing) {
        return Err(PlotError::InvalidInput(format!(
            "heat map {what} must be strictly monotonic"
        )));
    }
    let n = c.len();
    let mut e = Vec::with_capacity(n + 1);
    e.push(c[0] - 0.5 * (c[1] - c[0]));
    for w in c.windows(2) {
        e.push(0.5 * (w[0] + w[1]));
    }
    e.push(c[n - 1] + 0.5 * (c[n - 1] - c[n - 2]));
    if e.iter().any(|v| !v.is_finite()) {
        return Err(PlotError::InvalidInput(format!(
            "heat map {what} spacing overflows"
        )));
    }
    Ok(e)
}

/// Viridis colour at `t` in [0, 1].
fn viridis(t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let pos = t * (VIRIDIS.len() - 1) as f64;
    let i = (pos.floor() as usize).min(VIRIDIS.len() - 2);
    let f = pos - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |u: u8, v: u8| (f64::from(u) + (f64::from(v) - f64::from(u)) * f).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Joins contour edge segments that share end points into polylines, so
/// thick lines get proper joins instead of notched corners.
fn chain_segments(segs: &[(Pt, Pt)]) -> Vec<Vec<Pt>> {
    use std::collections::{HashMap, VecDeque};
    let key = |p: Pt| (p.0.to_bits(), p.1.to_bits());
    let mut at: HashMap<(u64, u64), Vec<usize>> = HashMap::new();
    for (i, &(a, b)) in segs.iter().enumerate() {
        at.entry(key(a)).or_default().push(i);
        at.entry(key(b)).or_default().push(i);
    }
    let mut used = vec![false; segs.len()];
    // Unused segment touching `p`, and its other end point.
    let next = |p: Pt, used: &mut [bool]| -> Option<Pt> {
        let j = *at.get(&key(p))?.iter().find(|&&j| !used[j])?;
        used[j] = true;
        let (a, b) = segs[j];
        Some(if key(a) == key(p) { b } else { a })
    };
    let mut out = Vec::new();
    for i in 0..segs.len() {
        if used[i] {
            continue;
        }
        used[i] = true;
        let mut line: VecDeque<Pt> = VecDeque::from([segs[i].0, segs[i].1]);
        while let Some(p) = line.back().copied().and_then(|e| next(e, &mut used)) {
            line.push_back(p);
        }
        while let Some(p) = line.front().copied().and_then(|e| next(e, &mut used)) {
            line.push_front(p);
        }
        // Drop collinear interior points (edges are axis-aligned); the
        // bitmap backend renders thick collinear joints with gaps.
        let mut simplified: Vec<Pt> = Vec::with_capacity(line.len());
        for p in line {
            if simplified.len() >= 2 {
                let a = simplified[simplified.len() - 2];
                let b = simplified[simplified.len() - 1];
                if (a.0 == b.0 && b.0 == p.0) || (a.1 == b.1 && b.1 == p.1) {
                    simplified.pop();
                }
            }
            simplified.push(p);
        }
        out.push(simplified);
    }
    out
}

/// A heat map ready for drawing.
#[derive(Debug)]
struct PreparedHeatmap {
    title: String,
    x_label: String,
    y_label: String,
    z_label: String,
    x: Axis,
    y: Axis,
    z: Axis,
    cells: Vec<(Pt, Pt, RGBColor)>,
    /// Level and contour polylines along cell edges.
    contour: Option<(f64, Vec<Vec<Pt>>)>,
    has_missing: bool,
}

fn prepare_heatmap(map: &Heatmap) -> Result<PreparedHeatmap, PlotError> {
    let xe = cell_edges(&map.x, "x")?;
    let ye = cell_edges(&map.y, "y")?;
    let (nx, ny) = (map.x.len(), map.y.len());
    if map.z.len() != ny {
        return Err(PlotError::InvalidInput(format!(
            "heat map z has {} rows but y has {} values",
            map.z.len(),
            ny
        )));
    }
    if let Some((iy, row)) = map.z.iter().enumerate().find(|(_, r)| r.len() != nx) {
        return Err(PlotError::InvalidInput(format!(
            "heat map z row {iy} has {} values but x has {nx}",
            row.len()
        )));
    }
    if let Some(level) = map.contour {
        if !level.is_finite() {
            return Err(PlotError::InvalidInput(format!(
                "contour level {level} is not finite"
            )));
        }
    }

    let (mut zmin, mut zmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for &v in map.z.iter().flatten().filter(|v| v.is_finite()) {
        zmin = zmin.min(v);
        zmax = zmax.max(v);
    }
    let (z0, z1) = if zmin > zmax {
        (0.0, 1.0)
    } else if zmax - zmin <= zmin.abs().max(zmax.abs()) * 1e-12 {
        let pad = degenerate_pad(zmin);
        (zmin - pad, zmin + pad)
    } else {
        (zmin, zmax)
    };

    let mut cells = Vec::with_capacity(nx * ny);
    let mut has_missing = false;
    for (iy, row) in map.z.iter().enumerate() {
        for (ix, &v) in row.iter().enumerate() {
            let color = if v.is_finite() {
                viridis((v - z0) / (z1 - z0))
            } else {
                has_missing = true;
                MISSING_COLOR
            };
            cells.push(((xe[ix], ye[iy]), (xe[ix + 1], ye[iy + 1]), color));
        }
    }

    let contour = map.contour.map(|level| {
        let crosses =
            |a: f64, b: f64| a.is_finite() && b.is_finite() && ((a < level) != (b < level));
        let mut segs = Vec::new();
        for (iy, row) in map.z.iter().enumerate() {
            for ix in 0..nx.saturating_sub(1) {
                if crosses(row[ix], row[ix + 1]) {
                    segs.push(((xe[ix + 1], ye[iy]), (xe[ix + 1], ye[iy + 1])));
                }
            }
        }
        for iy in 0..ny.saturating_sub(1) {
            for ix in 0..nx {
                if crosses(map.z[iy][ix], map.z[iy + 1][ix]) {
                    segs.push(((xe[ix], ye[iy + 1]), (xe[ix + 1], ye[iy + 1])));
                }
            }
        }
        (level, chain_segments(&segs))
    });

    let span = |e: &[f64]| {
        let lo = e.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = e.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (lo, hi)
    };
    let (xl, xh) = span(&xe);
    let (yl, yh) = span(&ye);
    Ok(PreparedHeatmap {
        title: map.title.clone(),
        x_label: map.x_label.clone(),
        y_label: map.y_label.clone(),
        z_label: map.z_label.clone(),
        x: Axis::linear(xl, xh, 8),
        y: Axis::linear(yl, yh, 8),
        z: Axis::linear(z0, z1, 8),
        cells,
        contour,
        has_missing,
    })
}

/// Heat-map figure: map on the left, colour bar on the right.
struct HeatFigure(PreparedHeatmap);

impl Figure for HeatFigure {
    fn size(&self) -> (u32, u32) {
        HEATMAP_SIZE
    }

    fn render<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let h = &self.0;
        let body = if h.title.is_empty() {
            root.clone()
        } else {
            root.margin(8, 0, 0, 0)
                .titled(&h.title, title_font(TITLE_PX))
                .map_err(err)?
        };
        let bar_labels = y_area_width(root, &h.z, &h.z_label);
        let strip = (MARGIN_PX + 8 + 34 + bar_labels).max(190);
        let (w, _) = body.dim_in_pixel();
        let (left, right) = body.split_horizontally(w.saturating_sub(strip).max(w / 2));

        // The map.
        let y_area = y_area_width(root, &h.y, &h.y_label);
        let mut cc = ChartBuilder::on(&left)
            .margin(MARGIN_PX)
            .x_label_area_size(X_AREA_PX)
            .y_label_area_size(y_area)
            .build_cartesian_2d(h.x.spec(), h.y.spec())
            .map_err(err)?;
        cc.draw_series(
            h.cells
                .iter()
                .map(|&(a, b, c)| Rectangle::new([a, b], c.filled())),
        )
        .map_err(err)?;
        if let Some((_, lines)) = &h.contour {
            let halo = WHITE.stroke_width(6);
            let line = CONTOUR_COLOR.stroke_width(3);
            cc.draw_series(lines.iter().map(|l| PathElement::new(l.clone(), halo)))
                .map_err(err)?;
            cc.draw_series(lines.iter().map(|l| PathElement::new(l.clone(), line)))
                .map_err(err)?;
        }
        let xfmt = |v: &f64| h.x.label(*v);
        let yfmt = |v: &f64| h.y.label(*v);
        {
            let mut mesh = cc.configure_mesh();
            mesh.disable_mesh()
                .x_label_formatter(&xfmt)
                .y_label_formatter(&yfmt)
                .label_style(tick_font())
                .axis_desc_style(desc_font())
                .axis_style(RGBColor(60, 60, 60));
            if !h.x_label.is_empty() {
                mesh.x_desc(h.x_label.as_str());
            }
            if !h.y_label.is_empty() {
                mesh.y_desc(h.y_label.as_str());
            }
            mesh.draw().map_err(err)?;
        }

        // The colour bar.
        let mut cb = ChartBuilder::on(&right)
            .margin(MARGIN_PX)
            .margin_left(8)
            .x_label_area_size(X_AREA_PX)
            .y_label_area_size(0)
            .right_y_label_area_size(bar_labels)
            .build_cartesian_2d(
                TickRange {
                    lo: 0.0,
                    hi: 1.0,
                    major: Vec::new(),
                    minor: Vec::new(),
                },
                h.z.spec(),
            )
            .map_err(err)?;
        let steps = 160;
        let (z0, z1) = (h.z.lo, h.z.hi);
        cb.draw_series((0..steps).map(|i| {
            let a = z0 + (z1 - z0) * i as f64 / steps as f64;
            let b = z0 + (z1 - z0) * (i + 1) as f64 / steps as f64;
            let t = (i as f64 + 0.5) / steps as f64;
            Rectangle::new([(0.0, a), (1.0, b)], viridis(t).filled())
        }))
        .map_err(err)?;
        if let Some((level, _)) = h.contour {
            if level >= z0 && level <= z1 {
                let pts = vec![(0.0, level), (1.0, level)];
                cb.draw_series(std::iter::once(PathElement::new(
                    pts.clone(),
                    WHITE.stroke_width(6),
                )))
                .map_err(err)?;
                cb.draw_series(std::iter::once(PathElement::new(
                    pts,
                    CONTOUR_COLOR.stroke_width(3),
                )))
                .map_err(err)?;
            }
        }
        let zfmt = |v: &f64| h.z.label(*v);
        {
            let mut mesh = cb.configure_mesh();
            mesh.disable_mesh()
                .disable_x_axis()
                .y_label_formatter(&zfmt)
                .label_style(tick_font())
                .axis_desc_style(desc_font())
                .axis_style(RGBColor(60, 60, 60));
            if !h.z_label.is_empty() {
                mesh.y_desc(h.z_label.as_str());
            }
            mesh.draw().map_err(err)?;
        }
        cb.plotting_area()
            .draw(&Rectangle::new(
                [(0.0, z0), (1.0, z1)],
                RGBColor(60, 60, 60),
            ))
            .map_err(err)?;

        // Key for the missing colour and the contour, below the colour bar.
        let (bx, by) = cb.backend_coord(&(0.0, z0));
        let key_font = TextStyle::from((FONT, 15).into_font())
            .color(&BLACK)
            .pos(Pos::new(HPos::Left, VPos::Center));
        let mut row_y = by + 20;
        if h.has_missing {
            root.draw(&Rectangle::new(
                [(bx, row_y - 7), (bx + 22, row_y + 7)],
                MISSING_COLOR.filled(),
            ))
            .map_err(err)?;
            root.draw(&Text::new(
                "missing/failed",
                (bx + 30, row_y),
                key_font.clone(),
            ))
            .map_err(err)?;
            row_y += 24;
        }
        if let Some((level, _)) = h.contour {
            root.draw(&PathElement::new(
                vec![(bx, row_y), (bx + 22, row_y)],
                CONTOUR_COLOR.stroke_width(3),
            ))
            .map_err(err)?;
            root.draw(&Text::new(
                format!("contour {}", fmt_general(level)),
                (bx + 30, row_y),
                key_font,
            ))
            .map_err(err)?;
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------
// Tests
// ---------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::*;

    /// Fresh output directory for one test.
    fn out_dir(name: &str) -> PathBuf {
        let dir = std::env::temp_dir()
            .join("cable-servo-plot-tests")
            .join(name);
        let _ = fs::remove_dir_all(&dir);
        dir
    }

    /// Files exist, are non-empty, PNG is a PNG of the expected size, SVG is
    /// an SVG, and no temporary file is left behind.
    fn check_outputs(paths: &[PathBuf], size: (u32, u32)) {
        assert_eq!(paths.len(), 2);
        let png = fs::read(&paths[0]).expect("png readable");
        assert!(paths[0].extension().is_some_and(|e| e == "png"));
        assert!(png.len() > 1000, "png too small: {}", png.len());
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
        let w = u32::from_be_bytes([png[16], png[17], png[18], png[19]]);
        let h = u32::from_be_bytes([png[20], png[21], png[22], png[23]]);
        assert_eq!((w, h), size);
        let svg = fs::read_to_string(&paths[1]).expect("svg readable");
        assert!(paths[1].extension().is_some_and(|e| e == "svg"));
        assert!(svg.contains("<svg"));
        assert!(svg.trim_end().ends_with("</svg>"));
        let dir = paths[0].parent().expect("parent");
        for entry in fs::read_dir(dir).expect("dir") {
            let name = entry.expect("entry").file_name();
            assert!(
                !name.to_string_lossy().ends_with(".tmp"),
                "temporary file left: {name:?}"
            );
        }
    }

    fn is_sorted(v: &[f64]) -> bool {
        v.windows(2).all(|w| w[0] <= w[1])
    }

    #[test]
    fn decimate_keeps_extremes_and_bounds() {
        let n = 100_000;
        let x: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        let mut y: Vec<f64> = x.iter().map(|t| (t * 7.0).sin()).collect();
        y[12_345] = 5.0; // single-sample spike
        y[77_777] = -4.0;
        for buckets in [1, 7, 100, 1000] {
            let (dx, dy) = decimate_minmax(&x, &y, buckets);
            assert!(dx.len() <= 2 * buckets, "{} > 2*{buckets}", dx.len());
            assert_eq!(dx.len(), dy.len());
            assert!(dy.contains(&5.0) && dy.contains(&-4.0));
            assert!(is_sorted(&dx));
            // Every output point is an input point.
            for (xx, yy) in dx.iter().zip(&dy) {
                let i = (xx * 1e3).round() as usize;
                assert_eq!(y[i], *yy);
            }
        }
        // buckets == 0 behaves like 1.
        let (dx, _) = decimate_minmax(&x, &y, 0);
        assert!(dx.len() <= 2);
    }

    #[test]
    fn decimate_short_and_edge_cases() {
        assert_eq!(decimate_minmax(&[], &[], 10), (vec![], vec![]));
        assert_eq!(decimate_minmax(&[1.0], &[2.0], 10), (vec![1.0], vec![2.0]));
        assert_eq!(decimate_minmax(&[1.0], &[2.0], 0), (vec![1.0], vec![2.0]));
        // Short series (even with NaN) are returned unchanged.
        let (dx, dy) = decimate_minmax(&[0.0, 1.0, 2.0], &[1.0, f64::NAN, 3.0], 2);
        assert_eq!(dx, vec![0.0, 1.0, 2.0]);
        assert!(dy[1].is_nan());
        // Mismatched lengths use the common prefix.
        let (dx, dy) = decimate_minmax(&[0.0, 1.0, 2.0], &[5.0, 6.0], 10);
        assert_eq!((dx.len(), dy.len()), (2, 2));
    }

    #[test]
    fn decimate_handles_nan() {
        let n = 50_000;
        let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let mut y: Vec<f64> = x.iter().map(|t| (t * 0.01).cos()).collect();
        for i in (0..n).step_by(97) {
            y[i] = f64::NAN;
        }
        y[5] = f64::INFINITY;
        y[40_000] = 9.0;
        y[40_001] = -9.0;
        let mut x2 = x.clone();
        x2[100] = f64::NAN;
        let (dx, dy) = decimate_minmax(&x2, &y, 50);
        assert!(dx.len() <= 100);
        assert!(dx.iter().chain(&dy).all(|v| v.is_finite()));
        assert!(dy.contains(&9.0) && dy.contains(&-9.0));
        assert!(is_sorted(&dx));
        // Only non-finite data reduces to nothing, without panicking.
        let nan = vec![f64::NAN; 1000];
        assert_eq!(decimate_minmax(&nan, &nan, 10), (vec![], vec![]));
        // Constant x (zero width: falls back to equal-count buckets).
        let cx = vec![1.0; 1000];
        let (dx, dy) = decimate_minmax(&cx, &y[..1000], 10);
        assert!(dx.len() <= 20 && !dy.is_empty());
    }

    #[test]
    fn decimate_non_monotonic_x() {
        // A hysteresis-like loop: x goes up and down.
        let n = 20_000;
        let t: Vec<f64> = (0..n)
            .map(|i| i as f64 / n as f64 * std::f64::consts::TAU)
            .collect();
        let x: Vec<f64> = t.iter().map(|t| t.sin()).collect();
        let y: Vec<f64> = t.iter().map(|t| (t + 0.5).sin()).collect();
        let (dx, dy) = decimate_minmax(&x, &y, 100);
        assert!(dx.len() <= 200 && dx.len() == dy.len());
        let ymax = y.iter().copied().fold(f64::MIN, f64::max);
        let ymin = y.iter().copied().fold(f64::MAX, f64::min);
        assert!(dy.contains(&ymax) && dy.contains(&ymin));
    }

    #[test]
    fn ticks_and_labels_are_clean() {
        let a = Axis::linear(0.0, 0.7, 8);
        let labels: Vec<String> = a.major.iter().map(|&v| a.label(v)).collect();
        assert_eq!(
            labels,
            ["0.0", "0.1", "0.2", "0.3", "0.4", "0.5", "0.6", "0.7"]
        );
        let a = Axis::linear(-3.3, 12.0, 8);
        let labels: Vec<String> = a.major.iter().map(|&v| a.label(v)).collect();
        assert_eq!(labels, ["-2", "0", "2", "4", "6", "8", "10", "12"]);
        let a = Axis::linear(-2e-6, 3e-6, 6);
        assert!(a.major.len() >= 3);
        assert!(a.major.iter().all(|&v| !a.label(v).is_empty()));
        let lg = Axis::log10(-1.0, 3.0);
        let labels: Vec<String> = lg.major.iter().map(|&v| lg.label(v)).collect();
        for want in ["0.1", "1", "10", "100", "1000"] {
            assert!(labels.contains(&want.to_string()), "{labels:?}");
        }
        let lg = Axis::log10(2.0, 8.0);
        let labels: Vec<String> = lg.major.iter().map(|&v| lg.label(v)).collect();
        assert!(labels.contains(&"1e6".to_string()), "{labels:?}");
        // Narrow log range still gets at least two ticks.
        assert!(Axis::log10(0.0, 0.05).major.len() >= 2);
        let a = Axis::linear(0.9e6, 1.7e6, 4);
        let labels: Vec<String> = a.major.iter().map(|&v| a.label(v)).collect();
        assert_eq!(labels, ["1.0e6", "1.2e6", "1.4e6", "1.6e6"]);
        let a = Axis::linear(-f64::MAX, f64::MAX, 8);
        let labels: Vec<String> = a.major.iter().map(|&v| a.label(v)).collect();
        assert!(labels.contains(&"1.5e308".to_string()), "{labels:?}");
        assert_eq!(fmt_log_tick(-240.0), "1e-240");
        assert_eq!(fmt_log_tick(60.0 + 2f64.log10()), "2e60");
        assert_eq!(fmt_log_tick(-2.0 + 5f64.log10()), "0.05");
        assert_eq!(fmt_log_tick(6.0 - 1e-12), "1e6");
        assert_eq!(fmt_general(0.002), "0.002");
        assert_eq!(fmt_general(2e-5), "2e-5");
    }

    #[test]
    fn ranges_are_never_degenerate() {
        let (a, b) = auto_range(3.0, 3.0, false);
        assert!(b > a && a < 3.0 && b > 3.0);
        let (a, b) = auto_range(0.0, 0.0, false);
        assert!(b > a);
        let (a, b) = auto_range(f64::INFINITY, f64::NEG_INFINITY, false);
        assert!(b > a);
        let (a, b) = explicit_range((2.0, 2.0), false, "y").expect("padded");
        assert!(b > a);
        let (a, b) = explicit_range((5.0, 1.0), false, "y").expect("swapped");
        assert_eq!((a, b), (1.0, 5.0));
        assert!(explicit_range((f64::NAN, 1.0), false, "y").is_err());
        assert!(explicit_range((0.0, 10.0), true, "x").is_err());
    }

    #[test]
    fn zoomed_long_trace_keeps_resolution() {
        // 200k samples over 0..100 s, viewing only 1..2 s: the visible second
        // still gets about one bucket per pixel, and two series don't share it.
        let n = 200_000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 5e-4).collect();
        let y: Vec<f64> = t.iter().map(|t| (t * 50.0).sin()).collect();
        let chart = Chart {
            series: vec![
                Series::line("a", t.clone(), y.clone()),
                Series::step("b", t.clone(), y.clone()),
            ],
            x_range: Some((1.0, 2.0)),
            ..Default::default()
        };
        let buckets = plot_buckets(CHART_SIZE.0);
        let p = prepare_chart(&chart, buckets).expect("prepare");
        let a: usize = p.series[0].lines.iter().map(Vec::len).sum();
        assert!(a >= buckets, "only {a} points for {buckets} buckets");
        assert!(a <= 2 * buckets + 4, "{a}");
        for l in p.series.iter().flat_map(|s| &s.lines) {
            assert!(l.iter().all(|q| (1.0..=2.0).contains(&q.0)));
        }
        // A segment crossing the whole view with both ends outside is kept.
        let kept = trim_to_x(&[0.0, 10.0], &[1.0, 2.0], 4.0, 5.0);
        assert_eq!(kept.len(), 1);
        assert_eq!(kept[0].0, vec![0.0, 10.0]);
        assert!(trim_to_x(&[0.0, 1.0], &[1.0, 2.0], 4.0, 5.0).is_empty());
    }

    #[test]
    fn clipping_splits_and_rejoins() {
        let b = Bounds {
            x0: 0.0,
            x1: 10.0,
            y0: 0.0,
            y1: 1.0,
        };
        let pts = vec![(0.0, 0.5), (2.0, 0.5), (3.0, 2.0), (4.0, 0.5), (6.0, 0.5)];
        let lines = clip_polyline(&pts, &b);
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert_eq!(lines[0][0], (0.0, 0.5));
        assert_eq!(lines[1].last(), Some(&(6.0, 0.5)));
        for l in &lines {
            for p in l {
                assert!(b.contains(*p), "{p:?} outside");
            }
        }
        assert!(clip_segment((-1.0, 5.0), (11.0, 5.0), &b).is_none());
    }

    #[test]
    fn contour_segments_are_chained() {
        // An L-shaped edge path plus a separate segment.
        let segs = vec![
            ((1.0, 0.0), (1.0, 1.0)),
            ((2.0, 5.0), (3.0, 5.0)),
            ((1.0, 1.0), (2.0, 1.0)),
            ((0.0, 0.0), (1.0, 0.0)),
            ((2.0, 1.0), (3.0, 1.0)), // collinear continuation
        ];
        let mut lines = chain_segments(&segs);
        lines.sort_by_key(|l| l.len());
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[0].len(), 2);
        assert_eq!(lines[1].len(), 4, "{lines:?}");
        let ends = [lines[1][0], lines[1][3]];
        assert!(ends.contains(&(0.0, 0.0)) && ends.contains(&(3.0, 1.0)));
    }

    #[test]
    fn save_chart_messy_data() {
        let dir = out_dir("messy");
        let t: Vec<f64> = (0..500).map(|i| i as f64 * 0.01).collect();
        let mut err: Vec<f64> = t
            .iter()
            .map(|t| 0.15 * (-t).exp() * (t * 9.0).sin())
            .collect();
        err[100] = f64::NAN;
        err[200] = f64::INFINITY;
        err[201] = f64::NEG_INFINITY;
        let mut t2 = t.clone();
        t2[300] = f64::NAN;
        let chart = Chart {
            title: "Pointing error (messy data)".into(),
            x_label: "time [s]".into(),
            y_label: "error [mrad]".into(),
            series: vec![
                Series::line("az error", t2.clone(), err.clone()),
                Series::line("empty", vec![], vec![]),
                Series::line("constant", t.clone(), vec![0.05; t.len()]),
                Series::step(
                    "command (ZOH)",
                    t.iter().step_by(50).copied().collect(),
                    err.iter().step_by(50).map(|v| v * 0.5).collect(),
                ),
                Series::points(
                    "samples",
                    t.iter().step_by(25).copied().collect(),
                    vec![-0.1; 20],
                ),
                Series::line("all nan", vec![f64::NAN; 3], vec![1.0; 3]),
                Series::line("", vec![1.0, 2.0], vec![f64::NAN, 0.0]),
            ],
            bands: vec![
                HBand {
                    lo: -0.1,
                    hi: 0.1,
                    label: "target ±0.1 mrad".into(),
                },
                HBand {
                    lo: f64::NAN,
                    hi: 1.0,
                    label: "invisible".into(),
                },
            ],
            ..Default::default()
        };
        let paths = save_chart(&chart, &dir.join("messy")).expect("save");
        check_outputs(&paths, CHART_SIZE);
        let svg = fs::read_to_string(&paths[1]).expect("svg");
        assert!(svg.contains("target ±0.1 mrad"));
        assert!(svg.contains("az error"));
        assert!(
            !svg.contains("all nan"),
            "all-NaN series must not be in legend"
        );
        assert!(!svg.contains("invisible"));
        assert!(!svg.contains("NaN"));
    }

    #[test]
    fn save_chart_degenerate_and_empty() {
        let dir = out_dir("degenerate");
        // Only a constant series (single point, even).
        let chart = Chart {
            series: vec![Series::line("c", vec![1.0], vec![2.0])],
            ..Default::default()
        };
        check_outputs(
            &save_chart(&chart, &dir.join("single")).expect("single"),
            CHART_SIZE,
        );
        // No finite data at all.
        let chart = Chart {
            title: "nothing".into(),
            series: vec![
                Series::line("nan", vec![f64::NAN; 4], vec![f64::NAN; 4]),
                Series::points("empty", vec![], vec![]),
            ],
            ..Default::default()
        };
        let paths = save_chart(&chart, &dir.join("empty")).expect("empty");
        check_outputs(&paths, CHART_SIZE);
        assert!(fs::read_to_string(&paths[1])
            .expect("svg")
            .contains("no finite data"));
        // Completely default chart.
        check_outputs(
            &save_chart(&Chart::default(), &dir.join("default")).expect("default"),
            CHART_SIZE,
        );
        // Explicit ranges clip the data; dotted stem keeps its dot.
        let chart = Chart {
            series: vec![Series::line(
                "clipped",
                (0..100).map(f64::from).collect(),
                (0..100).map(|i| f64::from(i) * 10.0).collect(),
            )],
            x_range: Some((90.0, 10.0)),
            y_range: Some((100.0, 100.0)),
            ..Default::default()
        };
        let paths = save_chart(&chart, &dir.join("run_0.1")).expect("ranges");
        assert_eq!(paths[0].file_name().expect("name"), "run_0.1.png");
        check_outputs(&paths, CHART_SIZE);
    }

    #[test]
    fn failed_write_leaves_no_temporary_files() {
        let dir = out_dir("blocked");
        // A directory where the PNG should go makes the final rename fail.
        fs::create_dir_all(dir.join("fig.png").join("occupied")).expect("mkdir");
        let chart = Chart {
            series: vec![Series::line("a", vec![0.0, 1.0], vec![0.0, 1.0])],
            ..Default::default()
        };
        let res = save_chart(&chart, &dir.join("fig"));
        assert!(matches!(res, Err(PlotError::Io { .. })), "{res:?}");
        assert!(!dir.join("fig.png.tmp").exists());
        assert!(!dir.join("fig.svg.tmp").exists());
        // A stale temporary from a crashed run does not block a new save.
        fs::create_dir_all(dir.join("ok.png.tmp").join("junk")).expect("mkdir");
        fs::write(dir.join("ok.svg.tmp"), b"half-written").expect("write");
        let paths = save_chart(&chart, &dir.join("ok")).expect("save over stale tmp");
        assert!(!dir.join("ok.png.tmp").exists() && !dir.join("ok.svg.tmp").exists());
        assert!(paths.iter().all(|p| p.exists()));
    }

    #[test]
    fn save_chart_extreme_values() {
        let dir = out_dir("extreme");
        let big = f64::MAX;
        let chart = Chart {
            series: vec![
                Series::line("huge", vec![-big, 0.0, big], vec![big, -big, 1e-320]),
                Series::points("tiny", vec![1e-310, 2e-310], vec![5e-324, 0.0]),
            ],
            bands: vec![HBand {
                lo: f64::NEG_INFINITY,
                hi: f64::INFINITY,
                label: "everything".into(),
            }],
            ..Default::default()
        };
        check_outputs(
            &save_chart(&chart, &dir.join("huge")).expect("huge"),
            CHART_SIZE,
        );
        let chart = Chart {
            series: vec![Series::step(
                "tiny",
                vec![0.0, 1e-300, 2e-300],
                vec![1.0, 1.0 + 1e-15, 1.0],
            )],
            log_x: true,
            x_range: Some((1e-300, 1e300)),
            ..Default::default()
        };
        check_outputs(
            &save_chart(&chart, &dir.join("wide_log")).expect("wide"),
            CHART_SIZE,
        );
        let map = Heatmap {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            z_label: String::new(),
            x: vec![0.0, 1.0],
            y: vec![0.0, 1.0],
            z: vec![vec![big, -big], vec![f64::INFINITY, 0.0]],
            contour: Some(0.5),
        };
        check_outputs(
            &save_heatmap(&map, &dir.join("heat")).expect("heat"),
            HEATMAP_SIZE,
        );
    }

    #[test]
    fn save_chart_log_x() {
        let dir = out_dir("log");
        let f: Vec<f64> = (-20..=60)
            .map(|i| 10f64.powf(f64::from(i) / 20.0))
            .collect();
        let mag: Vec<f64> = f
            .iter()
            .map(|f| -20.0 * (1.0 + (f / 30.0).powi(2)).sqrt().log10())
            .collect();
        let mut fx = f.clone();
        fx[0] = 0.0;
        fx[1] = -5.0;
        let chart = Chart {
            title: "Closed-loop response".into(),
            x_label: "frequency [Hz]".into(),
            y_label: "magnitude [dB]".into(),
            series: vec![
                Series::line("|T(jω)|", fx.clone(), mag.clone()),
                Series::points(
                    "measured",
                    fx.iter().step_by(7).copied().collect(),
                    mag.iter().step_by(7).map(|m| m + 0.5).collect(),
                ),
                Series::line("non-positive only", vec![0.0, -1.0], vec![1.0, 2.0]),
            ],
            bands: vec![HBand {
                lo: -3.0,
                hi: f64::INFINITY,
                label: "-3 dB".into(),
            }],
            log_x: true,
            ..Default::default()
        };
        check_outputs(
            &save_chart(&chart, &dir.join("bode")).expect("log"),
            CHART_SIZE,
        );
        // Invalid explicit log range is an error and leaves no files.
        let bad = Chart {
            log_x: true,
            x_range: Some((0.0, 10.0)),
            ..chart.clone()
        };
        assert!(matches!(
            save_chart(&bad, &dir.join("bad")),
            Err(PlotError::InvalidInput(_))
        ));
        assert!(!dir.join("bad.png").exists() && !dir.join("bad.svg").exists());
        // Log axis with only non-positive x: empty figure, no panic.
        let none = Chart {
            series: vec![Series::line("neg", vec![-1.0, 0.0], vec![1.0, 2.0])],
            log_x: true,
            ..Default::default()
        };
        check_outputs(
            &save_chart(&none, &dir.join("none")).expect("none"),
            CHART_SIZE,
        );
    }

    #[test]
    fn save_heatmap_nan_and_contour() {
        let dir = out_dir("heat");
        let x: Vec<f64> = (0..30).map(|i| 0.5 + f64::from(i) * 0.1).collect();
        let y: Vec<f64> = (0..20).map(|i| 100.0 + f64::from(i) * 25.0).collect();
        let z: Vec<Vec<f64>> = y
            .iter()
            .enumerate()
            .map(|(iy, yv)| {
                x.iter()
                    .enumerate()
                    .map(|(ix, xv)| {
                        if (ix + iy) % 17 == 0 || (iy > 15 && ix > 25) {
                            f64::NAN
                        } else {
                            0.02 + 0.3 * (xv - 1.5).powi(2) + yv / 5000.0
                        }
                    })
                    .collect()
            })
            .collect();
        let map = Heatmap {
            title: "Pointing error over preload and stiffness".into(),
            x_label: "preload [N]".into(),
            y_label: "stiffness [N/mm]".into(),
            z_label: "RMS error [mrad]".into(),
            x,
            y,
            z,
            contour: Some(0.1),
        };
        let prepared = prepare_heatmap(&map).expect("prepare");
        assert!(prepared.has_missing);
        assert!(!prepared.contour.as_ref().expect("contour").1.is_empty());
        let paths = save_heatmap(&map, &dir.join("sweep")).expect("heatmap");
        check_outputs(&paths, HEATMAP_SIZE);
        let svg = fs::read_to_string(&paths[1]).expect("svg");
        assert!(svg.contains("missing/failed") && svg.contains("contour 0.1"));

        // All-NaN and single-cell maps still render.
        let single = Heatmap {
            x: vec![1.0],
            y: vec![2.0],
            z: vec![vec![f64::NAN]],
            contour: None,
            ..map.clone()
        };
        check_outputs(
            &save_heatmap(&single, &dir.join("single")).expect("single"),
            HEATMAP_SIZE,
        );
        // Bad dimensions are errors.
        let bad = Heatmap {
            z: vec![vec![1.0; 3]],
            ..map.clone()
        };
        assert!(matches!(
            save_heatmap(&bad, &dir.join("bad")),
            Err(PlotError::InvalidInput(_))
        ));
        let bad = Heatmap { x: vec![], ..map };
        assert!(save_heatmap(&bad, &dir.join("bad")).is_err());
    }

    #[test]
    fn save_panels_three_charts() {
        let dir = out_dir("panels");
        let t: Vec<f64> = (0..2000).map(|i| f64::from(i) * 1e-3).collect();
        let angle = |f: f64| t.iter().map(|t| (t * f).sin()).collect::<Vec<_>>();
        let charts = vec![
            Chart {
                title: "Gimbal angles".into(),
                y_label: "angle [deg]".into(),
                series: vec![
                    Series::line("azimuth", t.clone(), angle(3.0)),
                    Series::line("elevation", t.clone(), angle(5.0)),
                ],
                ..Default::default()
            },
            Chart {
                title: "Pointing error".into(),
                y_label: "error [mrad]".into(),
                series: vec![Series::line(
                    "error",
                    t.clone(),
                    t.iter()
                        .map(|t| 0.3 * (-3.0 * t).exp() * (t * 40.0).sin())
                        .collect(),
                )],
                bands: vec![HBand {
                    lo: -0.1,
                    hi: 0.1,
                    label: "target".into(),
                }],
                ..Default::default()
            },
            Chart {
                title: "Cable tensions".into(),
                x_label: "time [s]".into(),
                y_label: "tension [N]".into(),
                series: vec![
                    Series::step(
                        "T1",
                        t.clone(),
                        t.iter().map(|t| 120.0 + 30.0 * (t * 3.0).sin()).collect(),
                    ),
                    Series::step(
                        "T2",
                        t.clone(),
                        t.iter().map(|t| 120.0 - 30.0 * (t * 3.0).sin()).collect(),
                    ),
                ],
                ..Default::default()
            },
        ];
        let paths = save_panels(
            "Step response, 10 deg",
            &charts,
            &dir.join("nested/dir/step"),
        )
        .expect("panels");
        check_outputs(&paths, (PANEL_WIDTH, 50 + 3 * PANEL_HEIGHT));
        assert!(matches!(
            save_panels("x", &[], &dir.join("none")),
            Err(PlotError::InvalidInput(_))
        ));
        let many = vec![Chart::default(); MAX_PANELS + 1];
        assert!(matches!(
            save_panels("x", &many, &dir.join("many")),
            Err(PlotError::InvalidInput(_))
        ));
    }

    #[test]
    fn save_chart_200k_points() {
        let dir = out_dir("big");
        let n = 200_000;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-4).collect();
        let y: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(i, t)| (t * 2.0).sin() + if i == 123_456 { 3.0 } else { 0.0 })
            .collect();
        let chart = Chart {
            title: "200k samples".into(),
            x_label: "time [s]".into(),
            y_label: "signal".into(),
            series: vec![
                Series::line("trace", t.clone(), y.clone()),
                Series::step("held", t.clone(), y.iter().map(|v| v * 0.5).collect()),
            ],
            ..Default::default()
        };
        let prepared = prepare_chart(&chart, plot_buckets(CHART_SIZE.0)).expect("prepare");
        let drawn: usize = prepared.series[0].lines.iter().map(Vec::len).sum();
        assert!(drawn <= 2 * plot_buckets(CHART_SIZE.0) + 2, "{drawn}");
        let peak = prepared.series[0].lines.iter().flatten().any(|p| p.1 > 2.5);
        assert!(peak, "spike lost by decimation");
        let start = std::time::Instant::now();
        let paths = save_chart(&chart, &dir.join("big")).expect("save");
        eprintln!("200k-point chart saved in {:?}", start.elapsed());
        check_outputs(&paths, CHART_SIZE);
    }
}
