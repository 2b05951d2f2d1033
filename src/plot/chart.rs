//! Chart drawing: one chart or a column of panels, legends, bands.

use plotters::coord::Shift;
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

/// Draws a prepared chart into `area`, with a y label area of `y_area` px.
pub(super) fn draw_chart<DB: DrawingBackend>(
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
        // Segment by segment: the bitmap backend joins a thick polyline with mitres, which
        // shoot far past the data where a min/max-reduced trace turns sharply (spikes the
        // data lacks); separate segments have no joins.
        cc.draw_series(s.lines.iter().flat_map(|l| {
            l.windows(2)
                .map(move |w| PathElement::new(vec![w[0], w[1]], line))
                .chain((l.len() == 1).then(|| PathElement::new(l.clone(), line)))
        }))
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
pub(super) struct SingleFigure(pub(super) PreparedChart);

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
        let areas = body.split_evenly((self.panels.len(), 1));
        for (area, panel) in areas.iter().zip(&self.panels) {
            draw_chart(area, panel, PANEL_TITLE_PX, y_area)?;
        }
        Ok(())
    }
}
