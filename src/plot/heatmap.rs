//! Heat maps with contour lines (a sweep over two parameters).

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::*;

/// Cell edges from strictly monotonic, finite cell-centre coordinates.
pub(super) fn cell_edges(c: &[f64], what: &str) -> Result<Vec<f64>, PlotError> {
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
pub(super) fn viridis(t: f64) -> RGBColor {
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

/// The unit of a colour bar's label written `words [unit]`, for the contour's key; empty
/// for a label without one.
fn unit_of(label: &str) -> &str {
    label
        .strip_suffix(']')
        .and_then(|l| l.rfind('[').map(|i| &l[i + 1..]))
        .unwrap_or("")
}

/// Joins contour edge segments that share end points into polylines, so
/// thick lines get proper joins instead of notched corners.
pub(super) fn chain_segments(segs: &[(Pt, Pt)]) -> Vec<Vec<Pt>> {
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
pub(super) struct PreparedHeatmap {
    pub(super) title: String,
    pub(super) x_label: String,
    pub(super) y_label: String,
    pub(super) z_label: String,
    pub(super) x: Axis,
    pub(super) y: Axis,
    pub(super) z: Axis,
    pub(super) cells: Vec<(Pt, Pt, RGBColor)>,
    /// Colour bar in log10 of the values.
    pub(super) log_z: bool,
    /// Corners of the cells without a value (failed or stopped cases), crossed out.
    pub(super) missing: Vec<(Pt, Pt)>,
    /// Level and contour polylines along cell edges.
    pub(super) contour: Option<(f64, Vec<Vec<Pt>>)>,
    pub(super) has_missing: bool,
}

/// Cell centres in drawing coordinates: log10 of the values on a log axis (which must
/// then be positive).
fn drawing_centres(c: &[f64], log: bool, what: &str) -> Result<Vec<f64>, PlotError> {
    if !log {
        return Ok(c.to_vec());
    }
    if let Some(v) = c.iter().find(|v| v.is_nan() || **v <= 0.0) {
        return Err(PlotError::InvalidInput(format!(
            "heat map {what} value {v} is not positive on a log axis"
        )));
    }
    Ok(c.iter().map(|v| v.log10()).collect())
}

pub(super) fn prepare_heatmap(map: &Heatmap) -> Result<PreparedHeatmap, PlotError> {
    let xe = cell_edges(&drawing_centres(&map.x, map.log_x, "x")?, "x")?;
    let ye = cell_edges(&drawing_centres(&map.y, map.log_y, "y")?, "y")?;
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

    // A log scale only where every value has a logarithm; otherwise linear.
    let log_z = map.log_z && map.z.iter().flatten().all(|v| !v.is_finite() || *v > 0.0);
    let zd = |v: f64| if log_z { v.log10() } else { v };
    let (mut zmin, mut zmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in map
        .z
        .iter()
        .flatten()
        .filter(|v| v.is_finite())
        .map(|v| zd(*v))
    {
        zmin = zmin.min(v);
        zmax = zmax.max(v);
    }
    let (z0, z1) = if zmin > zmax {
        (0.0, 1.0)
    } else if zmax - zmin <= zmin.abs().max(zmax.abs()) * 1e-12 {
        let pad = if log_z { 0.5 } else { degenerate_pad(zmin) };
        (zmin - pad, zmin + pad)
    } else {
        (zmin, zmax)
    };

    let mut cells = Vec::with_capacity(nx * ny);
    let mut missing = Vec::new();
    for (iy, row) in map.z.iter().enumerate() {
        for (ix, &v) in row.iter().enumerate() {
            let color = if v.is_finite() {
                viridis((zd(v) - z0) / (z1 - z0))
            } else {
                missing.push(((xe[ix], ye[iy]), (xe[ix + 1], ye[iy + 1])));
                MISSING_COLOR
            };
            cells.push(((xe[ix], ye[iy]), (xe[ix + 1], ye[iy + 1]), color));
        }
    }
    let has_missing = !missing.is_empty();

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
        x: if map.log_x {
            Axis::log10(xl, xh)
        } else {
            Axis::linear(xl, xh, 8)
        },
        y: if map.log_y {
            Axis::log10(yl, yh)
        } else {
            Axis::linear(yl, yh, 8)
        },
        z: if log_z {
            Axis::log10(z0, z1)
        } else {
            Axis::linear(z0, z1, 8)
        },
        log_z,
        cells,
        missing,
        contour,
        has_missing,
    })
}

/// Heat-map figure: map on the left, colour bar on the right.
pub(super) struct HeatFigure(pub(super) PreparedHeatmap);

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
        // A cross on each cell without a value: no colour of the scale, no doubt.
        let cross = RGBColor(60, 60, 60).stroke_width(2);
        cc.draw_series(h.missing.iter().flat_map(|&(a, b)| {
            [
                PathElement::new(vec![a, b], cross),
                PathElement::new(vec![(a.0, b.1), (b.0, a.1)], cross),
            ]
        }))
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
            let level = if h.log_z { level.log10() } else { level };
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
            root.draw(&PathElement::new(
                vec![(bx, row_y - 7), (bx + 22, row_y + 7)],
                RGBColor(60, 60, 60).stroke_width(2),
            ))
            .map_err(err)?;
            root.draw(&PathElement::new(
                vec![(bx, row_y + 7), (bx + 22, row_y - 7)],
                RGBColor(60, 60, 60).stroke_width(2),
            ))
            .map_err(err)?;
            root.draw(&Text::new(
                "failed or stopped case",
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
                match unit_of(&h.z_label) {
                    "" => format!("target contour {}", fmt_general(level)),
                    // Shorter than the key's width allows for "contour" beside the unit.
                    unit => format!("target {} {unit}", fmt_general(level)),
                },
                (bx + 30, row_y),
                key_font,
            ))
            .map_err(err)?;
        }
        Ok(())
    }
}
