//! Chart drawing: one chart or a column of panels, legends, bands.

use plotters::coord::{CoordTranslate, Shift};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::FontStyle;

use super::*;

pub(super) fn tick_font() -> TextStyle<'static> {
    TextStyle::from((FONT, TICK_PX).into_font()).color(&RGBColor(40, 40, 40))
}

pub(super) fn desc_font() -> TextStyle<'static> {
    TextStyle::from((FONT, DESC_PX).into_font()).color(&BLACK)
}

pub(super) fn title_font(px: u32) -> TextStyle<'static> {
    TextStyle::from((FONT, px, FontStyle::Bold).into_font()).color(&BLACK)
}

/// Width of the y label area needed for the tick labels and the description.
pub(super) fn y_area_width<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    axis: &Axis,
    desc: &str,
) -> u32 {
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

/// Where a chart was drawn, in absolute pixels `((left, top), (right, bottom))`: its
/// plotting area and, if it has one, its legend box (always outside the plotting area).
#[derive(Clone, Copy, Debug)]
pub(super) struct ChartLayout {
    pub(super) plot: PixelRect,
    pub(super) legend: Option<PixelRect>,
}

/// A rectangle in absolute pixels, `((left, top), (right, bottom))`.
pub(super) type PixelRect = ((i32, i32), (i32, i32));

impl ChartLayout {
    /// Whether the legend (if any) keeps clear of the plotting area.
    pub(super) fn legend_clear(&self) -> bool {
        let ((pl, pt), (pr, pb)) = self.plot;
        self.legend
            .is_none_or(|((ll, lt), (lr, lb))| !(ll < pr && pl < lr && lt < pb && pt < lb))
    }
}

/// Width of the legend column a chart needs (0 without a legend).
pub(super) fn legend_width(p: &PreparedChart) -> u32 {
    if p.has_legend() {
        LEGEND_WIDTH_PX
    } else {
        0
    }
}

/// Pieces of a pixel polyline that are "on" in a dash `pattern` (on, off, ... lengths in
/// pixels), walked by arc length so the pattern runs on across the polyline's corners.
pub(super) fn dash_pieces(pts: &[(f64, f64)], pattern: &[f64]) -> Vec<Vec<(f64, f64)>> {
    if pattern.is_empty() || pattern.iter().any(|l| l.is_nan() || *l <= 0.0) {
        return vec![pts.to_vec()];
    }
    let mut out = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    let (mut k, mut left) = (0usize, pattern[0]);
    for w in pts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
        if !len.is_finite() {
            continue;
        }
        let mut done = 0.0;
        while len - done > left {
            done += left;
            let t = done / len;
            let p = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
            if k % 2 == 0 {
                if cur.is_empty() {
                    cur.push(a);
                }
                cur.push(p);
                out.push(std::mem::take(&mut cur));
            } else {
                cur.push(p);
            }
            k = (k + 1) % pattern.len();
            left = pattern[k];
        }
        left -= len - done;
        if k % 2 == 0 {
            if cur.is_empty() {
                cur.push(a);
            }
            cur.push(b);
        } else {
            cur.clear();
        }
    }
    if k % 2 == 0 && cur.len() >= 2 {
        out.push(cur);
    }
    out
}

/// Draws marker `shape` (a pattern index) centred at pixel `c` of `area`.
fn draw_marker<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    shape: usize,
    c: (i32, i32),
    size: i32,
    color: RGBColor,
) -> Result<(), String> {
    let fill = color.filled();
    match shape % LINE_PATTERNS.len() {
        0 => area.draw(&Circle::new(c, size, fill)).map_err(err),
        1 => area
            .draw(&Polygon::new(
                vec![
                    (c.0, c.1 - size - 1),
                    (c.0 - size - 1, c.1 + size),
                    (c.0 + size + 1, c.1 + size),
                ],
                fill,
            ))
            .map_err(err),
        2 => area
            .draw(&Rectangle::new(
                [(c.0 - size, c.1 - size), (c.0 + size, c.1 + size)],
                fill,
            ))
            .map_err(err),
        _ => area
            .draw(&Polygon::new(
                vec![
                    (c.0, c.1 - size - 2),
                    (c.0 + size + 2, c.1),
                    (c.0, c.1 + size + 2),
                    (c.0 - size - 2, c.1),
                ],
                fill,
            ))
            .map_err(err),
    }
}

/// The points of `line` in the backend's pixels (`px`), as floats for walking along it.
pub(super) fn pixels_of(line: &[Pt], px: impl Fn(Pt) -> (i32, i32)) -> Vec<(f64, f64)> {
    line.iter()
        .map(|&q| {
            let (x, y) = px(q);
            (f64::from(x), f64::from(y))
        })
        .collect()
}

/// The words of `text` for wrapping, a number kept with the unit after it (`20000 Hz)`,
/// `0.1 mrad`): a line must not end in a number whose unit starts the next.
pub(super) fn unbroken_words(text: &str) -> Vec<String> {
    let mut words: Vec<String> = Vec::new();
    let mut after_number = false;
    for word in text.split_whitespace() {
        let unit = word.len() <= 5 && word.starts_with(|c: char| c.is_alphabetic() || c == '%');
        match words.last_mut() {
            Some(last) if after_number && unit => {
                last.push(' ');
                last.push_str(word);
                after_number = false;
            }
            _ => {
                words.push(word.to_string());
                after_number = word.ends_with(|c: char| c.is_ascii_digit());
            }
        }
    }
    words
}

/// Splits `text` into lines no wider than `width` pixels (at word boundaries; a single
/// longer word keeps its own line).
fn wrap<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    text: &str,
    font: &TextStyle,
    width: u32,
) -> Vec<String> {
    let fits = |s: &str| {
        area.estimate_text_size(s, font)
            .map_or(s.len() as u32 * LEGEND_PX / 2, |(w, _)| w)
            <= width
    };
    let mut lines = Vec::new();
    let mut cur = String::new();
    for word in unbroken_words(text) {
        let word = word.as_str();
        let candidate = if cur.is_empty() {
            word.to_string()
        } else {
            format!("{cur} {word}")
        };
        if fits(&candidate) || cur.is_empty() {
            cur = candidate;
        } else {
            lines.push(std::mem::replace(&mut cur, word.to_string()));
        }
    }
    if !cur.is_empty() {
        lines.push(cur);
    }
    lines
}

/// Draws a prepared chart into `area`, with a y label area of `y_area` px and a legend
/// column of `legend_w` px on the right (outside the plotting area).
pub(super) fn draw_chart<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    p: &PreparedChart,
    title_px: u32,
    y_area: u32,
    legend_w: u32,
) -> Result<ChartLayout, String> {
    // The title over the whole width (plot and legend), centred on the figure.
    let body = if p.title.is_empty() {
        area.clone()
    } else {
        area.margin(MARGIN_PX, 0, 0, 0)
            .titled(&p.title, title_font(title_px))
            .map_err(err)?
    };
    let (w, _) = body.dim_in_pixel();
    let (plot_area, legend_area) = if legend_w > 0 && legend_w < w / 2 {
        let (l, r) = body.split_horizontally(w - legend_w);
        (l, Some(r))
    } else {
        (body.clone(), None)
    };
    let mut builder = ChartBuilder::on(&plot_area);
    builder
        .margin(MARGIN_PX)
        .margin_top(if p.title.is_empty() { MARGIN_PX } else { 6 })
        .margin_right(MARGIN_PX + 14)
        .x_label_area_size(if p.x_label.is_empty() {
            X_AREA_PX - DESC_PX - 8
        } else {
            X_AREA_PX
        })
        .y_label_area_size(y_area);
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
    let (yl, yh) = (p.y.lo, p.y.hi);
    cc.draw_series(
        p.shades
            .iter()
            .map(|s| Rectangle::new([(s.lo, yl), (s.hi, yh)], SHADE_COLOR.mix(0.16).filled())),
    )
    .map_err(err)?;
    for b in &p.bands {
        let fill = b.color.mix(0.16).filled();
        let edge = b.color.mix(0.55).stroke_width(1);
        cc.draw_series(std::iter::once(Rectangle::new(
            [(xl, b.lo), (xh, b.hi)],
            fill,
        )))
        .map_err(err)?;
        cc.draw_series(
            [b.lo, b.hi]
                .into_iter()
                .filter(|&v| v > p.y.lo && v < p.y.hi)
                .map(|v| PathElement::new(vec![(xl, v), (xh, v)], edge)),
        )
        .map_err(err)?;
    }

    // Pixel positions relative to `area`, for what is drawn in pixels (dashes, markers).
    let base = area.get_base_pixel();
    let mapper = cc.as_coord_spec().clone();
    let px = |q: Pt| {
        let (x, y) = mapper.translate(&q);
        (x - base.0, y - base.1)
    };
    for s in &p.series {
        let color = s.color;
        let line = color.stroke_width(2);
        let pattern = LINE_PATTERNS[s.pattern % LINE_PATTERNS.len()];
        if pattern.is_empty() {
            // Segment by segment: the bitmap backend joins a thick polyline with mitres,
            // which shoot far past the data where a min/max-reduced trace turns sharply
            // (spikes the data lacks); separate segments have no joins.
            cc.draw_series(s.lines.iter().flat_map(|l| {
                l.windows(2)
                    .map(move |w| PathElement::new(vec![w[0], w[1]], line))
                    .chain((l.len() == 1).then(|| PathElement::new(l.clone(), line)))
            }))
            .map_err(err)?;
        } else {
            for l in &s.lines {
                let pixels = pixels_of(l, px);
                for piece in dash_pieces(&pixels, pattern) {
                    for w in piece.windows(2) {
                        let seg = vec![
                            (w[0].0.round() as i32, w[0].1.round() as i32),
                            (w[1].0.round() as i32, w[1].1.round() as i32),
                        ];
                        area.draw(&PathElement::new(seg, line)).map_err(err)?;
                    }
                }
            }
        }
        let dot = if s.style == SeriesStyle::Points { 4 } else { 2 };
        if s.style == SeriesStyle::Points {
            for &d in &s.dots {
                draw_marker(area, s.pattern, px(d), dot, color)?;
            }
        } else {
            cc.draw_series(s.dots.iter().map(|&d| Circle::new(d, dot, color.filled())))
                .map_err(err)?;
        }
        for &m in &s.markers {
            draw_marker(area, s.pattern, px(m), 4, color)?;
        }
        // Data beyond the axis: a triangle at the edge pointing the way the data went.
        for (xs, up) in [(&s.off_above, true), (&s.off_below, false)] {
            for &x in xs.iter() {
                let (cx, edge) = px((x, if up { yh } else { yl }));
                let (tip, foot) = if up {
                    (edge + 1, edge + 9)
                } else {
                    (edge - 1, edge - 9)
                };
                area.draw(&Polygon::new(
                    vec![(cx, tip), (cx - 5, foot), (cx + 5, foot)],
                    color.filled(),
                ))
                .map_err(err)?;
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

    let (px_x, px_y) = cc.plotting_area().get_pixel_range();
    let plot = ((px_x.start, px_y.start), (px_x.end, px_y.end));
    let legend = match legend_area {
        Some(la) if p.has_legend() => Some(draw_legend(&la, p, px_y.start)?),
        _ => None,
    };
    Ok(ChartLayout { plot, legend })
}

/// Draws the legend of `p` into the column `la`, its box's top at absolute pixel row
/// `top`; returns the box in absolute pixels.
fn draw_legend<DB: DrawingBackend>(
    la: &DrawingArea<DB, Shift>,
    p: &PreparedChart,
    top: i32,
) -> Result<PixelRect, String> {
    const ROW: i32 = 22;
    const SAMPLE: i32 = 34;
    const STEP_RISE: i32 = 8;
    let base = la.get_base_pixel();
    let (w, _) = la.dim_in_pixel();
    let font = TextStyle::from((FONT, LEGEND_PX).into_font()).color(&BLACK);
    let note_font = TextStyle::from((FONT, LEGEND_PX - 2).into_font()).color(&RGBColor(70, 70, 70));
    let text_w = (w as i32 - SAMPLE - 40).max(40) as u32;

    enum Key<'a> {
        Series(&'a PreparedSeries),
        Fill(RGBColor),
    }
    let mut entries: Vec<(Key, Vec<String>)> = Vec::new();
    for s in p
        .series
        .iter()
        .filter(|s| s.has_data && !s.label.is_empty())
    {
        entries.push((Key::Series(s), wrap(la, &s.label, &font, text_w)));
    }
    for b in p.bands.iter().filter(|b| !b.label.is_empty()) {
        entries.push((Key::Fill(b.color), wrap(la, &b.label, &font, text_w)));
    }
    let mut shade_labels: Vec<&str> = Vec::new();
    for sh in p.shades.iter().filter(|s| !s.label.is_empty()) {
        if !shade_labels.contains(&sh.label.as_str()) {
            shade_labels.push(&sh.label);
            entries.push((Key::Fill(SHADE_COLOR), wrap(la, &sh.label, &font, text_w)));
        }
    }
    let notes: Vec<Vec<String>> = p
        .notes
        .iter()
        .map(|n| wrap(la, n, &note_font, w.saturating_sub(30)))
        .collect();
    let rows: usize = entries.iter().map(|e| e.1.len()).sum::<usize>()
        + notes.iter().map(Vec::len).sum::<usize>();
    let left = 4;
    let right = w as i32 - 6;
    let top = top - base.1;
    let bottom = top + 10 + ROW * rows as i32 + 4;
    la.draw(&Rectangle::new(
        [(left, top), (right, bottom)],
        WHITE.filled(),
    ))
    .map_err(err)?;
    la.draw(&Rectangle::new(
        [(left, top), (right, bottom)],
        BLACK.mix(0.35),
    ))
    .map_err(err)?;
    let anchor = Pos::new(HPos::Left, VPos::Center);
    let mut y = top + 5 + ROW / 2;
    for (key, lines) in &entries {
        let x = left + 8;
        match key {
            Key::Series(s) => {
                let line = s.color.stroke_width(2);
                let pattern = LINE_PATTERNS[s.pattern % LINE_PATTERNS.len()];
                if s.style != SeriesStyle::Points {
                    let sample: Vec<(f64, f64)> = if s.style == SeriesStyle::Step {
                        // The treads clear of the marker on the riser (it reaches 6 px
                        // from its centre), or they cut into it.
                        vec![
                            (f64::from(x), f64::from(y + STEP_RISE)),
                            (f64::from(x + SAMPLE / 2), f64::from(y + STEP_RISE)),
                            (f64::from(x + SAMPLE / 2), f64::from(y - STEP_RISE)),
                            (f64::from(x + SAMPLE), f64::from(y - STEP_RISE)),
                        ]
                    } else {
                        vec![
                            (f64::from(x), f64::from(y)),
                            (f64::from(x + SAMPLE), f64::from(y)),
                        ]
                    };
                    for piece in dash_pieces(&sample, pattern) {
                        let pts = piece
                            .iter()
                            .map(|q| (q.0.round() as i32, q.1.round() as i32))
                            .collect::<Vec<_>>();
                        la.draw(&PathElement::new(pts, line)).map_err(err)?;
                    }
                }
                let size = if s.style == SeriesStyle::Points { 3 } else { 4 };
                if !s.context || s.style == SeriesStyle::Points {
                    draw_marker(la, s.pattern, (x + SAMPLE / 2, y), size, s.color)?;
                }
            }
            Key::Fill(c) => {
                la.draw(&Rectangle::new(
                    [(x, y - 7), (x + SAMPLE, y + 7)],
                    c.mix(0.25).filled(),
                ))
                .map_err(err)?;
            }
        }
        for l in lines {
            la.draw(&Text::new(
                l.as_str(),
                (x + SAMPLE + 8, y),
                font.clone().pos(anchor),
            ))
            .map_err(err)?;
            y += ROW;
        }
    }
    for lines in &notes {
        for l in lines {
            la.draw(&Text::new(
                l.as_str(),
                (left + 8, y),
                note_font.clone().pos(anchor),
            ))
            .map_err(err)?;
            y += ROW;
        }
    }
    Ok((
        (base.0 + left, base.1 + top),
        (base.0 + right, base.1 + bottom),
    ))
}

/// Figure with one chart.
pub(super) struct SingleFigure(pub(super) PreparedChart);

impl Figure for SingleFigure {
    fn size(&self) -> (u32, u32) {
        CHART_SIZE
    }

    fn render<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
        let y_area = y_area_width(root, &self.0.y, &self.0.y_label);
        let layout = draw_chart(root, &self.0, TITLE_PX, y_area, legend_width(&self.0))?;
        debug_assert!(layout.legend_clear(), "legend over the data: {layout:?}");
        Ok(())
    }
}

/// Figure with vertically stacked charts under a shared title.
pub(super) struct PanelFigure {
    pub(super) title: String,
    pub(super) panels: Vec<PreparedChart>,
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
        // And the same legend column, so the right edges line up too.
        let legend_w = self.panels.iter().map(legend_width).max().unwrap_or(0);
        let areas = body.split_evenly((self.panels.len(), 1));
        for (area, panel) in areas.iter().zip(&self.panels) {
            let layout = draw_chart(area, panel, PANEL_TITLE_PX, y_area, legend_w)?;
            debug_assert!(layout.legend_clear(), "legend over the data: {layout:?}");
        }
        Ok(())
    }
}
