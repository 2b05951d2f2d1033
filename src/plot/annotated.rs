//! Annotated figures for loop analysis: panels with dashed curves, markers with text,
//! arrowheads along a curve, an equal-aspect plane (Nyquist, z-plane), and the legend and
//! notes in a column beside the data, never over it.

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::FontStyle;

use super::*;

/// Line pattern of a [`Trace`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dash {
    /// Unbroken.
    Solid,
    /// 10 px dashes.
    Dashed,
    /// 2 px dots.
    Dotted,
    /// 18 px dashes with short gaps.
    LongDash,
}

impl Dash {
    /// The pattern of member `i` of a family (operating points): solid, dashed, dotted,
    /// long dashes, then again.
    pub fn nth(i: usize) -> Dash {
        [Dash::Solid, Dash::Dashed, Dash::Dotted, Dash::LongDash][i % 4]
    }

    fn pattern(self) -> Option<(u32, u32)> {
        match self {
            Dash::Solid => None,
            Dash::Dashed => Some((10, 6)),
            Dash::Dotted => Some((3, 5)),
            Dash::LongDash => Some((18, 5)),
        }
    }
}

/// Marker shape of a [`Mark`] or of a [`Trace`]'s samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shape {
    /// Filled circle.
    Circle,
    /// Open circle.
    Ring,
    /// Diagonal cross.
    Cross,
    /// Filled square.
    Square,
    /// Filled diamond.
    Diamond,
    /// Filled triangle pointing up.
    Triangle,
}

/// A curve of a [`Panel`].
#[derive(Clone, Debug)]
pub struct Trace {
    /// Legend label; empty keeps it out of the legend.
    pub label: String,
    /// x samples (frequencies in Hz on a log axis: the raw values, not their logarithm).
    pub x: Vec<f64>,
    /// y samples; a non-finite one breaks the line.
    pub y: Vec<f64>,
    /// Colour (red, green, blue).
    pub rgb: [u8; 3],
    /// Line pattern.
    pub dash: Dash,
    /// Line width, px (0: markers only).
    pub width: u32,
    /// A marker at every sample, for sparse data that must not look like a smooth curve.
    pub marker: Option<Shape>,
}

impl Trace {
    /// A line of width 2.
    pub fn line(
        label: impl Into<String>,
        x: Vec<f64>,
        y: Vec<f64>,
        rgb: [u8; 3],
        dash: Dash,
    ) -> Self {
        Trace {
            label: label.into(),
            x,
            y,
            rgb,
            dash,
            width: 2,
            marker: None,
        }
    }
}

/// A marked point, with an optional text beside it.
#[derive(Clone, Debug)]
pub struct Mark {
    /// Position, data coordinates.
    pub x: f64,
    /// Position, data coordinates.
    pub y: f64,
    /// Shape.
    pub shape: Shape,
    /// Colour.
    pub rgb: [u8; 3],
    /// Size, px (radius).
    pub size: u32,
    /// Legend label; empty keeps it out of the legend.
    pub label: String,
    /// Text drawn beside the marker; empty for none.
    pub text: String,
    /// Offset of the text's left end from the marker, px (right, down).
    pub text_offset: (i32, i32),
}

/// An arrowhead on a curve, pointing along it.
#[derive(Clone, Copy, Debug)]
pub struct Arrowhead {
    /// Tip, data coordinates.
    pub at: (f64, f64),
    /// A point behind the tip on the curve (sets the direction), data coordinates.
    pub from: (f64, f64),
    /// Colour.
    pub rgb: [u8; 3],
}

/// One chart of an [`AnnotatedFigure`].
#[derive(Clone, Debug, Default)]
pub struct Panel {
    /// Title over the chart (empty: none).
    pub title: String,
    /// x axis description with its unit.
    pub x_label: String,
    /// y axis description with its unit.
    pub y_label: String,
    /// x range, data units (raw values on a log axis, positive).
    pub x_range: (f64, f64),
    /// y range.
    pub y_range: (f64, f64),
    /// log10 x axis.
    pub log_x: bool,
    /// Equal scale on both axes (a complex plane): the shorter range is widened about
    /// its middle to fit the chart's shape.
    pub equal_aspect: bool,
    /// Curves, drawn in order.
    pub traces: Vec<Trace>,
    /// Marked points, drawn over the curves.
    pub marks: Vec<Mark>,
    /// Arrowheads.
    pub arrows: Vec<Arrowhead>,
}

/// Panels stacked vertically, with the legend and notes in a column to the right.
#[derive(Clone, Debug, Default)]
pub struct AnnotatedFigure {
    /// Figure title.
    pub title: String,
    /// The charts, top to bottom (1 to 4).
    pub panels: Vec<Panel>,
    /// Lines of text under the legend (what the marks mean, the numbers).
    pub notes: Vec<String>,
    /// Height of one panel, px (about 420 for a stacked Bode plot, 800 for a plane).
    pub panel_height: u32,
}

/// Width of the legend column, px.
const SIDE_PX: u32 = 400;
/// Width of the whole figure, px.
const ANNOTATED_WIDTH: u32 = 1500;
/// Legend and note text size.
const SIDE_TEXT_PX: u32 = 15;

/// Writes `<stem>.png` and `<stem>.svg` of `fig`; returns both paths.
pub fn save_annotated(fig: &AnnotatedFigure, stem: &Path) -> Result<Vec<PathBuf>, PlotError> {
    if fig.panels.is_empty() || fig.panels.len() > 4 {
        return Err(PlotError::InvalidInput(format!(
            "an annotated figure needs 1 to 4 panels, got {}",
            fig.panels.len()
        )));
    }
    for p in &fig.panels {
        let (x0, x1) = p.x_range;
        let (y0, y1) = p.y_range;
        let ok = x0.is_finite() && x1.is_finite() && y0.is_finite() && y1.is_finite();
        if !ok || x1 <= x0 || y1 <= y0 || (p.log_x && x0 <= 0.0) {
            return Err(PlotError::InvalidInput(format!(
                "panel {:?}: ranges x {x0}..{x1}, y {y0}..{y1} are not increasing finite ranges",
                p.title
            )));
        }
    }
    save_figure(&Annotated(fig), stem)
}

struct Annotated<'a>(&'a AnnotatedFigure);

fn rgb(c: [u8; 3]) -> RGBColor {
    RGBColor(c[0], c[1], c[2])
}

impl Figure for Annotated<'_> {
    fn size(&self) -> (u32, u32) {
        let h = self.0.panel_height.clamp(200, 1200);
        (ANNOTATED_WIDTH, 60 + h * self.0.panels.len() as u32)
    }

    fn render<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let fig = self.0;
        let body = root
            .margin(8, 0, 0, 0)
            .titled(&fig.title, title_font(TITLE_PX))
            .map_err(err)?;
        let (plots, side) = body.split_horizontally(ANNOTATED_WIDTH - SIDE_PX);
        let areas = plots.split_evenly((fig.panels.len(), 1));
        let y_area = 100;
        for (area, panel) in areas.iter().zip(&fig.panels) {
            draw_panel(area, panel, y_area)?;
        }
        draw_side(&side, fig)
    }
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    p: &Panel,
    y_area: u32,
) -> Result<(), String> {
    let tx = |x: f64| if p.log_x { x.log10() } else { x };
    let (mut x0, mut x1) = (tx(p.x_range.0), tx(p.x_range.1));
    let (mut y0, mut y1) = p.y_range;
    let caption = if p.title.is_empty() { 0 } else { 34 };
    if p.equal_aspect {
        let (w, h) = area.dim_in_pixel();
        let pw = f64::from(w.saturating_sub(y_area + 2 * MARGIN_PX + 14).max(50));
        let ph = f64::from(
            h.saturating_sub(X_AREA_PX + 2 * MARGIN_PX + caption)
                .max(50),
        );
        let (sx, sy) = ((x1 - x0) / pw, (y1 - y0) / ph);
        if sx > sy {
            let mid = 0.5 * (y0 + y1);
            let half = 0.5 * sx * ph;
            (y0, y1) = (mid - half, mid + half);
        } else {
            let mid = 0.5 * (x0 + x1);
            let half = 0.5 * sy * pw;
            (x0, x1) = (mid - half, mid + half);
        }
    }
    let xa = if p.log_x {
        Axis::log10(x0, x1)
    } else {
        Axis::linear(x0, x1, 8)
    };
    let ya = Axis::linear(y0, y1, 7);
    let mut builder = ChartBuilder::on(area);
    builder
        .margin(MARGIN_PX)
        .margin_right(MARGIN_PX + 14)
        .x_label_area_size(X_AREA_PX)
        .y_label_area_size(y_area);
    if !p.title.is_empty() {
        builder.caption(&p.title, title_font(PANEL_TITLE_PX));
    }
    let mut cc = builder
        .build_cartesian_2d(xa.spec(), ya.spec())
        .map_err(err)?;
    let xfmt = |v: &f64| xa.label(*v);
    let yfmt = |v: &f64| ya.label(*v);
    cc.configure_mesh()
        .x_label_formatter(&xfmt)
        .y_label_formatter(&yfmt)
        .label_style(tick_font())
        .axis_desc_style(desc_font())
        .bold_line_style(BLACK.mix(0.13))
        .light_line_style(BLACK.mix(0.045))
        .axis_style(RGBColor(60, 60, 60))
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .draw()
        .map_err(err)?;
    let bounds = Bounds { x0, x1, y0, y1 };
    // What the texts beside the marks should keep off: the curves' pixels and the
    // markers of sampled traces.
    let mut inked: Vec<(i32, i32)> = Vec::new();
    let mut dots: Vec<PixelRect> = Vec::new();
    for t in &p.traces {
        let color = rgb(t.rgb);
        let pts: Vec<Pt> =
            t.x.iter()
                .zip(&t.y)
                .map(|(&x, &y)| {
                    (
                        if p.log_x && x > 0.0 {
                            x.log10()
                        } else if p.log_x {
                            f64::NAN
                        } else {
                            x
                        },
                        y,
                    )
                })
                .collect();
        if t.width > 0 {
            let style = color.stroke_width(t.width);
            // Runs of finite samples, each clipped to the chart.
            let mut run: Vec<Pt> = Vec::new();
            let mut runs: Vec<Vec<Pt>> = Vec::new();
            for &q in &pts {
                if q.0.is_finite() && q.1.is_finite() {
                    run.push(q);
                } else if !run.is_empty() {
                    runs.push(std::mem::take(&mut run));
                }
            }
            runs.push(run);
            for piece in runs.iter().flat_map(|r| clip_polyline(r, &bounds)) {
                inked.extend(along(&piece, |q| cc.backend_coord(&q)));
                match t.dash.pattern() {
                    None => {
                        cc.draw_series(
                            piece
                                .windows(2)
                                .map(|w| PathElement::new(vec![w[0], w[1]], style)),
                        )
                        .map_err(err)?;
                    }
                    Some((on, off)) => {
                        cc.draw_series(std::iter::once(DashedPathElement::new(
                            piece.clone(),
                            on,
                            off,
                            style,
                        )))
                        .map_err(err)?;
                    }
                }
            }
        }
        if let Some(shape) = t.marker {
            for &q in pts.iter().filter(|q| bounds.contains(**q)) {
                marker(&mut cc, q, shape, 4, color)?;
                let (x, y) = cc.backend_coord(&q);
                dots.push(((x - 5, y - 5), (x + 5, y + 5)));
            }
        }
    }
    for a in &p.arrows {
        let tip = (tx(a.at.0), a.at.1);
        let back = (tx(a.from.0), a.from.1);
        if !bounds.contains(tip) {
            continue;
        }
        let (px, py) = cc.backend_coord(&tip);
        let (qx, qy) = cc.backend_coord(&back);
        let (dx, dy) = (f64::from(px - qx), f64::from(py - qy));
        let n = dx.hypot(dy);
        if n == 0.0 {
            continue;
        }
        let (ux, uy) = (dx / n, dy / n);
        let pt = |along: f64, across: f64| {
            (
                (along * ux - across * uy).round() as i32,
                (along * uy + across * ux).round() as i32,
            )
        };
        let head = EmptyElement::at(tip)
            + Polygon::new(
                vec![pt(0.0, 0.0), pt(-14.0, 6.0), pt(-14.0, -6.0)],
                rgb(a.rgb).filled(),
            );
        cc.draw_series(std::iter::once(head)).map_err(err)?;
    }
    let shown: Vec<(&Mark, Pt)> = p
        .marks
        .iter()
        .map(|m| (m, (tx(m.x), m.y)))
        .filter(|(_, q)| bounds.contains(*q))
        .collect();
    for &(m, q) in &shown {
        marker(&mut cc, q, m.shape, m.size, rgb(m.rgb))?;
    }
    // The texts after every marker, each placed clear of the markers and of the texts
    // placed before it.
    let plain = TextStyle::from((FONT, MARK_TEXT_PX).into_font());
    let obstacles: Vec<PixelRect> = shown
        .iter()
        .map(|&(m, q)| {
            let (x, y) = cc.backend_coord(&q);
            let r = m.size as i32 + 2;
            ((x - r, y - r), (x + r, y + r))
        })
        .chain(dots)
        .collect();
    let texts: Vec<(&Mark, Pt, LabelBox)> = shown
        .iter()
        .filter(|(m, _)| !m.text.is_empty())
        .map(|&(m, q)| {
            let (w, h) = area
                .estimate_text_size(&m.text, &plain)
                .map_or((8 * m.text.len() as i32, MARK_TEXT_PX as i32), |(w, h)| {
                    (w as i32, h as i32)
                });
            let label = LabelBox {
                anchor: cc.backend_coord(&q),
                offset: m.text_offset,
                size: (w + 2, h + 2),
            };
            (m, q, label)
        })
        .collect();
    let (px_x, px_y) = cc.plotting_area().get_pixel_range();
    // A few pixels in from the axes, so no text touches them.
    let plot = (
        (px_x.start + 3, px_y.start + 3),
        (px_x.end - 3, px_y.end - 3),
    );
    let labels: Vec<LabelBox> = texts.iter().map(|t| t.2).collect();
    let placed = place_labels(&labels, &obstacles, &inked, plot);
    for ((m, q, label), &(ox, oy)) in texts.iter().zip(&placed) {
        let colour = rgb(m.rgb);
        // A text moved off its spot points back at its marker.
        if (oy - label.offset.1).abs() > label.size.1 || ox != label.offset.0 {
            let (top, bottom) = (oy - label.size.1 / 2, oy + label.size.1 / 2);
            let near_y = 0.clamp(top, bottom);
            let near_x = if ox < 0 { ox + label.size.0 } else { ox };
            let r = m.size as i32 + 1;
            let len = f64::from(near_x).hypot(f64::from(near_y));
            if len > f64::from(r) + 2.0 {
                let start = (
                    (f64::from(near_x) * f64::from(r) / len).round() as i32,
                    (f64::from(near_y) * f64::from(r) / len).round() as i32,
                );
                cc.draw_series(std::iter::once(
                    EmptyElement::at(*q)
                        + PathElement::new(vec![start, (near_x, near_y)], colour.mix(0.7)),
                ))
                .map_err(err)?;
            }
        }
        // A white halo keeps the text readable over grid and curves.
        let white = WHITE.mix(0.9);
        let halo = TextStyle::from((FONT, MARK_TEXT_PX, FontStyle::Bold).into_font())
            .color(&white)
            .pos(Pos::new(HPos::Left, VPos::Center));
        let font = TextStyle::from((FONT, MARK_TEXT_PX).into_font())
            .color(&colour)
            .pos(Pos::new(HPos::Left, VPos::Center));
        for (dx, dy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
            cc.draw_series(std::iter::once(
                EmptyElement::at(*q) + Text::new(m.text.clone(), (ox + dx, oy + dy), halo.clone()),
            ))
            .map_err(err)?;
        }
        cc.draw_series(std::iter::once(
            EmptyElement::at(*q) + Text::new(m.text.clone(), (ox, oy), font),
        ))
        .map_err(err)?;
    }
    Ok(())
}

/// Size of the text beside a mark, px.
const MARK_TEXT_PX: u32 = 15;

/// A mark's text to be placed: the marker's pixel, the offset asked for (of the text's
/// left end, its middle in height) and the text's size, px.
#[derive(Clone, Copy, Debug)]
pub(super) struct LabelBox {
    pub(super) anchor: (i32, i32),
    pub(super) offset: (i32, i32),
    pub(super) size: (i32, i32),
}

impl LabelBox {
    /// The text's box at offset `o`.
    fn at(&self, o: (i32, i32)) -> PixelRect {
        let (x, y) = (self.anchor.0 + o.0, self.anchor.1 + o.1);
        (
            (x, y - self.size.1 / 2),
            (x + self.size.0, y + self.size.1 - self.size.1 / 2),
        )
    }
}

/// Area two boxes share, px².
fn shared(a: PixelRect, b: PixelRect) -> i64 {
    let w = a.1 .0.min(b.1 .0) - a.0 .0.max(b.0 .0);
    let h = a.1 .1.min(b.1 .1) - a.0 .1.max(b.0 .1);
    if w > 0 && h > 0 {
        i64::from(w) * i64::from(h)
    } else {
        0
    }
}

/// Area of `a` outside `area`, px².
fn outside(a: PixelRect, area: PixelRect) -> i64 {
    let whole = i64::from(a.1 .0 - a.0 .0) * i64::from(a.1 .1 - a.0 .1);
    whole - shared(a, area)
}

/// Pixels along a polyline in data coordinates, one every 2 px of its length however
/// densely it is sampled (`px` maps a point to its pixel).
fn along(piece: &[Pt], px: impl Fn(Pt) -> (i32, i32)) -> Vec<(i32, i32)> {
    const STEP: f64 = 2.0;
    let pts = super::chart::pixels_of(piece, px);
    let mut out: Vec<(i32, i32)> = pts
        .first()
        .map(|p| (p.0 as i32, p.1 as i32))
        .into_iter()
        .collect();
    // Length walked since the last pixel taken.
    let mut walked = 0.0;
    for w in pts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = (b.0 - a.0).hypot(b.1 - a.1);
        let mut at = STEP - walked;
        while at <= len {
            let t = at / len;
            out.push((
                (a.0 + t * (b.0 - a.0)).round() as i32,
                (a.1 + t * (b.1 - a.1)).round() as i32,
            ));
            at += STEP;
        }
        walked = len - (at - STEP);
    }
    out
}

/// Offsets for texts beside marks, in order. A text never covers the texts placed before
/// it or the `obstacles` (the markers) and stays inside `area` when any spot tried allows:
/// where it asked to be, stacked a line at a time above or below (the way it asked first)
/// and moved out from the marker by up to two thirds of its width, and the same on the
/// marker's other side, taken only when its own side has no such spot (a side is asked
/// for a reason: away from the critical point). Among those, the one that weighs least:
/// the `inked` pixels it covers (the curves, one every 2 px) plus a price for each move;
/// failing all, the spot that overlaps least.
pub(super) fn place_labels(
    labels: &[LabelBox],
    obstacles: &[PixelRect],
    inked: &[(i32, i32)],
    area: PixelRect,
) -> Vec<(i32, i32)> {
    const STEPS: i32 = 6;
    // A move is worth about 24 px of curve under the text (the halo keeps a text over a
    // curve readable; one far from its marker is hard to pair with it).
    const MOVE_COST: i64 = 12;
    let mut placed: Vec<PixelRect> = Vec::new();
    let mut out = Vec::with_capacity(labels.len());
    for l in labels {
        let (ox, oy) = l.offset;
        let line = l.size.1;
        let first = if oy < 0 { -1 } else { 1 };
        // (offset, moves, other side): a move is a line up or down, or a third of the
        // text's width further out from the marker.
        let mut tries = Vec::new();
        for (base, flipped) in [(ox, 0), (-ox - l.size.0, 1)] {
            let outward = if 2 * base + l.size.0 >= 0 { 1 } else { -1 };
            for j in 0..=2 {
                let x = base + outward * j * l.size.0 / 3;
                tries.push(((x, oy), j, flipped));
                for k in 1..=STEPS {
                    tries.push(((x, oy + first * k * line), j + k, flipped));
                    tries.push(((x, oy - first * k * line), j + k, flipped));
                }
            }
        }
        // Only the curve near this mark can matter.
        let reach = (
            (
                l.anchor.0 - ox.abs() - 2 * l.size.0,
                l.anchor.1 - (STEPS + 1) * line - oy.abs(),
            ),
            (
                l.anchor.0 + ox.abs() + 2 * l.size.0,
                l.anchor.1 + (STEPS + 1) * line + oy.abs(),
            ),
        );
        let near: Vec<(i32, i32)> = inked
            .iter()
            .copied()
            .filter(|&(x, y)| {
                x >= reach.0 .0 && x <= reach.1 .0 && y >= reach.0 .1 && y <= reach.1 .1
            })
            .collect();
        let hard = |o: (i32, i32)| {
            let b = l.at(o);
            let hit: i64 = placed.iter().chain(obstacles).map(|&q| shared(b, q)).sum();
            hit + outside(b, area)
        };
        let soft = |o: (i32, i32), moved: i32| {
            let ((x0, y0), (x1, y1)) = l.at(o);
            let covered = near
                .iter()
                .filter(|&&(x, y)| x >= x0 && x < x1 && y >= y0 && y < y1)
                .count() as i64;
            covered + MOVE_COST * i64::from(moved)
        };
        let best = tries
            .iter()
            .filter(|t| hard(t.0) == 0)
            .min_by_key(|t| (t.2, soft(t.0, t.1)))
            .or_else(|| tries.iter().min_by_key(|t| hard(t.0)))
            .map_or(l.offset, |t| t.0);
        placed.push(l.at(best));
        out.push(best);
    }
    out
}

type Cc<'a, DB> = ChartContext<'a, DB, Cartesian2d<TickRange, TickRange>>;

fn marker<DB: DrawingBackend>(
    cc: &mut Cc<'_, DB>,
    q: Pt,
    shape: Shape,
    size: u32,
    color: RGBColor,
) -> Result<(), String> {
    let r = size as i32;
    let filled = color.filled();
    let stroke = color.stroke_width(2);
    match shape {
        Shape::Circle => {
            cc.draw_series(std::iter::once(
                EmptyElement::at(q) + Circle::new((0, 0), size, filled),
            ))
            .map_err(err)?;
        }
        Shape::Ring => {
            cc.draw_series(std::iter::once(
                EmptyElement::at(q) + Circle::new((0, 0), size, stroke),
            ))
            .map_err(err)?;
        }
        Shape::Cross => {
            cc.draw_series(std::iter::once(
                EmptyElement::at(q)
                    + PathElement::new(vec![(-r, -r), (r, r)], stroke)
                    + PathElement::new(vec![(-r, r), (r, -r)], stroke),
            ))
            .map_err(err)?;
        }
        Shape::Square => {
            cc.draw_series(std::iter::once(
                EmptyElement::at(q) + Rectangle::new([(-r, -r), (r, r)], filled),
            ))
            .map_err(err)?;
        }
        Shape::Diamond => {
            cc.draw_series(std::iter::once(
                EmptyElement::at(q)
                    + Polygon::new(
                        vec![(0, -r - 1), (r + 1, 0), (0, r + 1), (-r - 1, 0)],
                        filled,
                    ),
            ))
            .map_err(err)?;
        }
        Shape::Triangle => {
            cc.draw_series(std::iter::once(
                EmptyElement::at(q)
                    + Polygon::new(vec![(0, -r - 1), (r + 1, r), (-r - 1, r)], filled),
            ))
            .map_err(err)?;
        }
    }
    Ok(())
}

/// Legend entries (traces and marks with a label, each label once) and the notes.
fn draw_side<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    fig: &AnnotatedFigure,
) -> Result<(), String> {
    let font = TextStyle::from((FONT, SIDE_TEXT_PX).into_font())
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    let mut y = 50;
    let mut seen: Vec<&str> = Vec::new();
    let line_h = SIDE_TEXT_PX as i32 + 9;
    let x = 12;
    for p in &fig.panels {
        for t in p.traces.iter().filter(|t| !t.label.is_empty()) {
            if seen.contains(&t.label.as_str()) {
                continue;
            }
            seen.push(&t.label);
            let color = rgb(t.rgb);
            if t.width > 0 {
                let style = color.stroke_width(t.width);
                match t.dash.pattern() {
                    None => area
                        .draw(&PathElement::new(vec![(x, y), (x + 40, y)], style))
                        .map_err(err)?,
                    Some((on, off)) => area
                        .draw(&DashedPathElement::new(
                            vec![(x, y), (x + 40, y)],
                            on,
                            off,
                            style,
                        ))
                        .map_err(err)?,
                }
            }
            if let Some(s) = t.marker {
                side_marker(area, (x + 20, y), s, 4, color)?;
            }
            y = side_text(area, &t.label, x + 50, y, &font, line_h)?;
        }
        for m in p.marks.iter().filter(|m| !m.label.is_empty()) {
            if seen.contains(&m.label.as_str()) {
                continue;
            }
            seen.push(&m.label);
            side_marker(area, (x + 20, y), m.shape, m.size, rgb(m.rgb))?;
            y = side_text(area, &m.label, x + 50, y, &font, line_h)?;
        }
    }
    y += line_h / 2;
    for n in &fig.notes {
        y = side_text(area, n, x, y, &font, line_h - 4)?;
    }
    Ok(())
}

/// Draws `text` wrapped to the column from `(x, y)`; returns the next line's y.
fn side_text<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    text: &str,
    x: i32,
    mut y: i32,
    font: &TextStyle,
    line_h: i32,
) -> Result<i32, String> {
    let width = SIDE_PX as i32 - x - 8;
    let mut line = String::new();
    let fits = |s: &str| {
        area.estimate_text_size(s, font)
            .map(|(w, _)| w as i32 <= width)
            .unwrap_or(s.len() as i32 * 8 <= width)
    };
    let indent = if text.starts_with("  ") { "    " } else { "  " };
    // Words as the legend wraps them: a number stays with its unit.
    for word in super::chart::unbroken_words(text) {
        let word = word.as_str();
        let candidate = if line.is_empty() {
            word.to_string()
        } else {
            format!("{line} {word}")
        };
        if fits(&candidate) || line.trim().is_empty() {
            line = candidate;
        } else {
            area.draw(&Text::new(line.clone(), (x, y), font.clone()))
                .map_err(err)?;
            y += line_h;
            line = format!("{indent}{word}");
        }
    }
    if !line.is_empty() {
        area.draw(&Text::new(line, (x, y), font.clone()))
            .map_err(err)?;
        y += line_h;
    }
    Ok(y)
}

fn side_marker<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    at: (i32, i32),
    shape: Shape,
    size: u32,
    color: RGBColor,
) -> Result<(), String> {
    let r = size as i32;
    let (x, y) = at;
    let filled = color.filled();
    let stroke = color.stroke_width(2);
    match shape {
        Shape::Circle => area.draw(&Circle::new(at, size, filled)),
        Shape::Ring => area.draw(&Circle::new(at, size, stroke)),
        Shape::Cross => area
            .draw(&PathElement::new(
                vec![(x - r, y - r), (x + r, y + r)],
                stroke,
            ))
            .and_then(|_| {
                area.draw(&PathElement::new(
                    vec![(x - r, y + r), (x + r, y - r)],
                    stroke,
                ))
            }),
        Shape::Square => area.draw(&Rectangle::new([(x - r, y - r), (x + r, y + r)], filled)),
        Shape::Diamond => area.draw(&Polygon::new(
            vec![
                (x, y - r - 1),
                (x + r + 1, y),
                (x, y + r + 1),
                (x - r - 1, y),
            ],
            filled,
        )),
        Shape::Triangle => area.draw(&Polygon::new(
            vec![(x, y - r - 1), (x + r + 1, y + r), (x - r - 1, y + r)],
            filled,
        )),
    }
    .map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn panel() -> Panel {
        Panel {
            x_label: "frequency [Hz]".into(),
            y_label: "|L| [dB]".into(),
            x_range: (0.1, 1000.0),
            y_range: (-40.0, 40.0),
            log_x: true,
            traces: vec![
                Trace::line(
                    "with a gap",
                    vec![0.1, 1.0, f64::NAN, 100.0, 1000.0],
                    vec![30.0, 20.0, 0.0, f64::INFINITY, -60.0],
                    [0, 0, 255],
                    Dash::Dashed,
                ),
                Trace {
                    width: 0,
                    marker: Some(Shape::Circle),
                    ..Trace::line(
                        "measured",
                        vec![1.0, 10.0],
                        vec![5.0, 50.0],
                        [255, 0, 0],
                        Dash::Solid,
                    )
                },
            ],
            marks: vec![Mark {
                x: 10.0,
                y: 0.0,
                shape: Shape::Diamond,
                rgb: [0, 0, 0],
                size: 5,
                label: "crossing".into(),
                text: "PM 40°".into(),
                text_offset: (8, -12),
            }],
            arrows: vec![Arrowhead {
                at: (10.0, 0.0),
                from: (1.0, 20.0),
                rgb: [0, 0, 0],
            }],
            ..Panel::default()
        }
    }

    /// Non-finite samples and points beyond the ranges are left out, never drawn wild;
    /// both files appear.
    #[test]
    fn a_figure_with_gaps_and_off_scale_points_is_written() {
        let tmp = tempfile::tempdir().unwrap();
        let fig = AnnotatedFigure {
            title: "test".into(),
            panels: vec![panel(), Panel { equal_aspect: true, log_x: false, x_range: (-2.0, 1.0), ..panel() }],
            notes: vec!["a note long enough to be wrapped onto a second line in the side column of the figure".into()],
            panel_height: 400,
        };
        let files = save_annotated(&fig, &tmp.path().join("f")).unwrap();
        assert_eq!(files.len(), 2);
        assert!(files.iter().all(|f| f.is_file()));
    }

    /// Texts that would print over each other are stacked apart, each kept inside the
    /// plot and off the markers; a text with room stays where it asked to be.
    #[test]
    fn texts_beside_marks_are_placed_apart() {
        let area = ((0, 0), (400, 300));
        let label = |anchor, offset| LabelBox {
            anchor,
            offset,
            size: (110, 17),
        };
        // Two marks close together, both asking for the text above-right.
        let labels = [label((100, 100), (8, -14)), label((104, 104), (8, -14))];
        let markers = [((94, 94), (106, 106)), ((98, 98), (110, 110))];
        let placed = place_labels(&labels, &markers, &[], area);
        assert_eq!(placed[0], (8, -14), "the first keeps its spot");
        let boxes: Vec<PixelRect> = labels.iter().zip(&placed).map(|(l, &o)| l.at(o)).collect();
        assert_eq!(shared(boxes[0], boxes[1]), 0, "{boxes:?}");
        for b in &boxes {
            assert_eq!(outside(*b, area), 0, "{b:?}");
            for m in &markers {
                assert_eq!(shared(*b, *m), 0, "{b:?} over {m:?}");
            }
        }
        // A curve through the spot asked for: the text moves off it, by as little as does.
        let curve: Vec<(i32, i32)> = (0..400).map(|x| (x, 86)).collect();
        let off = place_labels(&[label((100, 100), (8, -14))], &[], &curve, area);
        let b = label((100, 100), off[0]).at(off[0]);
        assert!(
            !curve
                .iter()
                .any(|&(x, y)| x >= b.0 .0 && x < b.1 .0 && y >= b.0 .1 && y < b.1 .1),
            "{b:?}"
        );
        assert!((off[0].1 + 14).abs() <= 17, "{off:?}");
        // However densely a curve is sampled, it is counted by its length.
        let dense: Vec<Pt> = (0..=200).map(|i| (f64::from(i) * 0.1, 0.0)).collect();
        let sparse = [(0.0, 0.0), (20.0, 0.0)];
        let px = |q: Pt| ((q.0 * 10.0) as i32, 5);
        assert_eq!(along(&dense, px).len(), along(&sparse, px).len());
        assert_eq!(along(&sparse, px).len(), 101);
        // At the right edge, the text goes to the marker's left.
        let edge = place_labels(&[label((390, 150), (8, -14))], &[], &[], area);
        assert!(edge[0].0 < 0, "{edge:?}");
    }

    #[test]
    fn bad_ranges_and_panel_counts_are_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let stem = tmp.path().join("f");
        let mut p = panel();
        p.x_range = (0.0, 10.0); // log axis from zero
        let fig = AnnotatedFigure {
            panels: vec![p],
            ..AnnotatedFigure::default()
        };
        assert!(matches!(
            save_annotated(&fig, &stem),
            Err(PlotError::InvalidInput(_))
        ));
        let none = AnnotatedFigure::default();
        assert!(matches!(
            save_annotated(&none, &stem),
            Err(PlotError::InvalidInput(_))
        ));
    }
}
