//! The sweep table (`sweep.csv`, streamed one row per case) and its plots.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::columns::{column_label, column_value, column_words};
use super::ReportError;
use crate::plot::{family_colour, save_chart, save_heatmap, Chart, Heatmap, Series};
use crate::sweep::engine::{render_value, Case, Cell};

/// Streams `sweep.csv`: header `case,<parameter columns>,<figure columns>`, then one row per
/// case in case order. Numbers are written in shortest round-trip form, so merged shard
/// files equal a single run's file byte for byte.
pub struct SweepTable {
    path: PathBuf,
    out: std::io::BufWriter<std::fs::File>,
    /// Rows kept for the plots: small (one line per case), never time series.
    pub rows: Vec<(Case, Vec<Cell>)>,
}

/// Header line of a sweep table.
pub fn header(parameter_columns: &[String], figure_columns: &[String]) -> String {
    let mut cols = vec!["case".to_string()];
    cols.extend(parameter_columns.iter().cloned());
    cols.extend(figure_columns.iter().cloned());
    cols.join(",")
}

/// One CSV cell, quoted when needed.
fn field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// One row of a sweep table.
pub fn row_line(case: &Case, cells: &[Cell]) -> String {
    let mut parts = vec![case.index.to_string()];
    parts.extend(case.assignments.iter().map(|a| field(&render_value(&a.2))));
    parts.extend(cells.iter().map(|c| field(&c.render())));
    parts.join(",")
}

impl SweepTable {
    /// Create the file and write the header.
    pub fn create(
        path: &Path,
        parameter_columns: &[String],
        figure_columns: &[String],
    ) -> Result<SweepTable, ReportError> {
        let file = std::fs::File::create(path).map_err(|e| ReportError::io(path, e))?;
        let mut out = std::io::BufWriter::new(file);
        writeln!(out, "{}", header(parameter_columns, figure_columns))
            .map_err(|e| ReportError::io(path, e))?;
        Ok(SweepTable {
            path: path.to_path_buf(),
            out,
            rows: Vec::new(),
        })
    }

    /// Append one case's row.
    pub fn push(&mut self, case: &Case, cells: Vec<Cell>) -> std::io::Result<()> {
        writeln!(self.out, "{}", row_line(case, &cells))?;
        self.rows.push((case.clone(), cells));
        Ok(())
    }

    /// Flush to disk.
    pub fn finish(&mut self) -> Result<(), ReportError> {
        self.out.flush().map_err(|e| ReportError::io(&self.path, e))
    }
}

/// Numeric value of a TOML parameter value, when it has one.
pub fn numeric(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Float(f) => Some(*f),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// Plots of a sweep: each numeric figure against the first parameter (a curve per value of
/// the second), against the second (a curve per value of the first), and a heat map over
/// both; `contour` marks a level on the heat maps of figures in mrad (the pointing target).
pub fn plot(
    dir: &Path,
    parameter_columns: &[String],
    figure_columns: &[String],
    rows: &[(Case, Vec<Cell>)],
    contour_mrad: Option<f64>,
    max_figures: usize,
) -> Result<Vec<PathBuf>, ReportError> {
    let mut files = Vec::new();
    if rows.is_empty() || parameter_columns.is_empty() {
        return Ok(files);
    }
    let param =
        |r: &(Case, Vec<Cell>), i: usize| r.0.assignments.get(i).and_then(|a| numeric(&a.2));
    if parameter_columns.len() < 2 {
        // One parameter: one chart per metric, every mode a curve in its own colour.
        return by_metric(
            dir,
            parameter_columns,
            figure_columns,
            rows,
            max_figures,
            true,
            contour_mrad,
        );
    }
    let numeric_figures = drawn_figures(figure_columns, rows, max_figures);
    let value = |r: &(Case, Vec<Cell>), j: usize| match r.1.get(j) {
        Some(Cell::Num(Some(v))) if v.is_finite() => Some(*v),
        _ => None,
    };
    let distinct = |i: usize| {
        let mut v: Vec<f64> = rows.iter().filter_map(|r| param(r, i)).collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v
    };
    for &j in &numeric_figures {
        let fig = &figure_columns[j];
        let pairs: Vec<(usize, usize)> = if parameter_columns.len() >= 2 {
            vec![(0, 1), (1, 0)]
        } else {
            vec![(0, usize::MAX)]
        };
        for (xi, gi) in pairs {
            let series: Vec<Series> = if gi == usize::MAX {
                let (x, y): (Vec<f64>, Vec<f64>) = rows
                    .iter()
                    .filter_map(|r| Some((param(r, xi)?, value(r, j)?)))
                    .unzip();
                vec![Series::line(figure_words(fig), x, y)]
            } else {
                let members = distinct(gi);
                let n = members.len();
                members
                    .into_iter()
                    .enumerate()
                    .map(|(k, g)| {
                        let mut pts: Vec<(f64, f64)> = rows
                            .iter()
                            .filter(|r| param(r, gi) == Some(g))
                            .filter_map(|r| Some((param(r, xi)?, value(r, j)?)))
                            .collect();
                        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                        let (x, y) = pts.into_iter().unzip();
                        member(
                            Series::line(column_value(&parameter_columns[gi], g), x, y),
                            k,
                            n,
                        )
                    })
                    .collect()
            };
            let series = match mode_and_metric(fig).0 {
                Some((_, slot)) if gi == usize::MAX => {
                    series.into_iter().map(|s| s.in_slot(slot)).collect()
                }
                _ => series,
            };
            let mut series = series;
            let xs: Vec<f64> = series.iter().flat_map(|s| s.x.iter().copied()).collect();
            series.extend(target_series(fig, contour_mrad, &xs));
            let chart = Chart {
                title: format!(
                    "{} against {}",
                    figure_words(fig),
                    column_words(&parameter_columns[xi]).0
                ),
                x_label: column_label(&parameter_columns[xi]),
                y_label: figure_label(fig),
                series,
                log_x: log_spaced(&distinct(xi)),
                ..Chart::default()
            };
            files.extend(save_chart(
                &chart,
                &dir.join(format!("{fig}_vs_{}", parameter_columns[xi])),
            )?);
        }
        if parameter_columns.len() >= 2 {
            let xs = distinct(0);
            let ys = distinct(1);
            if xs.len() >= 2 && ys.len() >= 2 {
                let mut z = vec![vec![f64::NAN; xs.len()]; ys.len()];
                for r in rows {
                    if let (Some(x), Some(y)) = (param(r, 0), param(r, 1)) {
                        let ix = xs.iter().position(|v| *v == x);
                        let iy = ys.iter().position(|v| *v == y);
                        if let (Some(ix), Some(iy)) = (ix, iy) {
                            z[iy][ix] = value(r, j).unwrap_or(f64::NAN);
                        }
                    }
                }
                let map = Heatmap {
                    title: format!(
                        "{} over {} and {}",
                        figure_words(fig),
                        column_words(&parameter_columns[0]).0,
                        column_words(&parameter_columns[1]).0
                    ),
                    x_label: column_label(&parameter_columns[0]),
                    y_label: column_label(&parameter_columns[1]),
                    z_label: figure_label(fig),
                    log_x: log_spaced(&xs),
                    log_y: log_spaced(&ys),
                    x: xs,
                    y: ys,
                    z,
                    contour: if fig.ends_with("_mrad") {
                        contour_mrad
                    } else {
                        None
                    },
                    // Errors over a sweep spread over decades: a linear scale would
                    // paint all but the worst cells one colour.
                    log_z: true,
                };
                files.extend(save_heatmap(&map, &dir.join(format!("{fig}_map")))?);
            }
        }
    }
    Ok(files)
}

/// Member `k` of `n` curves of a family ordered by a swept value: a palette colour of its
/// own, never the grey the target line is drawn in; beyond the palette, a colour ramp in
/// the family's order (the palette would repeat colour and pattern together).
fn member(s: Series, k: usize, n: usize) -> Series {
    const SLOTS: [usize; 9] = [0, 1, 2, 3, 4, 5, 6, 8, 9];
    if n <= SLOTS.len() {
        s.in_slot(SLOTS[k % SLOTS.len()])
    } else {
        s.in_rgb(family_colour(k, n))
    }
}

/// A figure column in words, with its mode when it has one (`memory_rms_mrad`: RMS
/// pointing error, memory).
fn figure_words(column: &str) -> String {
    match mode_and_metric(column) {
        (Some((mode, _)), metric) => format!("{}, {mode}", column_words(metric).0),
        (None, _) => column_words(column).0,
    }
}

/// A figure column as an axis description: its words and its unit in brackets.
fn figure_label(column: &str) -> String {
    let unit = column_words(mode_and_metric(column).1).1;
    match unit {
        Some(u) => format!("{} [{u}]", figure_words(column)),
        None => figure_words(column),
    }
}

/// The target as a grey line across the swept values, for a figure in mrad (an error
/// judged against the pointing target); nothing for other figures.
fn target_series(figure: &str, target_mrad: Option<f64>, xs: &[f64]) -> Option<Series> {
    let target = target_mrad.filter(|t| t.is_finite() && figure.ends_with("_mrad"))?;
    let (lo, hi) = xs
        .iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| {
            (l.min(*x), h.max(*x))
        });
    (lo <= hi).then(|| {
        Series::line(
            format!("target {target} mrad"),
            vec![lo, hi],
            vec![target, target],
        )
        .in_slot(7)
    })
}

/// Mode and metric of a closed-loop figure column (`memory_rms_mrad` -> memory,
/// rms_mrad), with the mode's fixed palette slot; other columns have no mode.
fn mode_and_metric(column: &str) -> (Option<(&'static str, usize)>, &str) {
    use crate::closed_loop::CompensationMode;
    for mode in [
        CompensationMode::None,
        CompensationMode::Memoryless,
        CompensationMode::Memory,
    ] {
        if let Some(metric) = column
            .strip_prefix(mode.name())
            .and_then(|rest| rest.strip_prefix('_'))
        {
            return (
                Some((mode.name(), super::closed_loop::mode_slot(mode))),
                metric,
            );
        }
    }
    (None, column)
}

/// The numeric figure columns to draw: every column (every mode) of the first
/// `max_metrics` metrics that hold a number in some row.
fn drawn_figures(
    figure_columns: &[String],
    rows: &[(Case, Vec<Cell>)],
    max_metrics: usize,
) -> Vec<usize> {
    let numeric: Vec<usize> = (0..figure_columns.len())
        .filter(|&j| {
            rows.iter()
                .any(|r| matches!(r.1.get(j), Some(Cell::Num(Some(_)))))
        })
        .collect();
    let mut metrics: Vec<&str> = Vec::new();
    for &j in &numeric {
        let m = mode_and_metric(&figure_columns[j]).1;
        if !metrics.contains(&m) {
            metrics.push(m);
        }
    }
    metrics.truncate(max_metrics);
    numeric
        .into_iter()
        .filter(|&j| metrics.contains(&mode_and_metric(&figure_columns[j]).1))
        .collect()
}

/// Whether swept values are spread over decades evenly in their logarithm (a log axis
/// shows them evenly): all positive, over more than a decade, and their log-spacing more
/// uniform than their linear spacing.
fn log_spaced(values: &[f64]) -> bool {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    if v.len() < 3 || v[0] <= 0.0 || v[v.len() - 1] / v[0] < 10.0 {
        return false;
    }
    let spread = |d: Vec<f64>| {
        let m = d.iter().sum::<f64>() / d.len() as f64;
        (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / d.len() as f64).sqrt() / m.abs()
    };
    let lin = spread(v.windows(2).map(|w| w[1] - w[0]).collect());
    let log = spread(v.windows(2).map(|w| (w[1] / w[0]).ln()).collect());
    log < lin
}

/// Spread of each numeric figure over the cases of a sampled (tolerance) sweep: mean,
/// standard deviation, extremes and the 5, 50 and 95 % points (empirical, nearest rank),
/// in the figure's own unit. Returns JSON and a printable table.
pub fn statistics(
    figure_columns: &[String],
    rows: &[(Case, Vec<Cell>)],
) -> (serde_json::Value, String) {
    let mut json = serde_json::Map::new();
    // As wide as the longest name (`memory_within_target_fraction`), so no row shifts.
    let width = figure_columns
        .iter()
        .map(|n| n.chars().count())
        .max()
        .unwrap_or(0)
        .max(26);
    let mut text = format!(
        "{:<width$} {:>7} {:>12} {:>12} {:>12} {:>12} {:>12} {:>12} {:>12}\n",
        "figure", "cases", "mean", "std", "min", "p5", "p50", "p95", "max"
    );
    for (j, name) in figure_columns.iter().enumerate() {
        let mut v: Vec<f64> = rows
            .iter()
            .filter_map(|r| match r.1.get(j) {
                Some(Cell::Num(Some(x))) if x.is_finite() => Some(*x),
                _ => None,
            })
            .collect();
        if v.is_empty() {
            continue;
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let mean = v.iter().sum::<f64>() / n as f64;
        let std = if n > 1 {
            (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        let pct = |p: f64| v[((p * n as f64).ceil() as usize).clamp(1, n) - 1];
        let (p5, p50, p95) = (pct(0.05), pct(0.5), pct(0.95));
        text.push_str(&format!(
            "{name:<width$} {n:>7} {mean:>12.6} {std:>12.6} {:>12.6} {p5:>12.6} {p50:>12.6} {p95:>12.6} {:>12.6}\n",
            v[0],
            v[n - 1]
        ));
        json.insert(
            name.clone(),
            serde_json::json!({
                "cases": n, "mean": mean, "std": std, "min": v[0], "p5": p5,
                "p50": p50, "p95": p95, "max": v[n - 1],
            }),
        );
    }
    (serde_json::Value::Object(json), text)
}

/// Plots of a sampled sweep: each numeric figure against each parameter, one point per
/// case (curves and heat maps need a grid); `target_mrad` drawn as a line on the figures
/// in mrad.
pub fn plot_samples(
    dir: &Path,
    parameter_columns: &[String],
    figure_columns: &[String],
    rows: &[(Case, Vec<Cell>)],
    target_mrad: Option<f64>,
    max_figures: usize,
) -> Result<Vec<PathBuf>, ReportError> {
    by_metric(
        dir,
        parameter_columns,
        figure_columns,
        rows,
        max_figures,
        false,
        target_mrad,
    )
}

/// One chart per metric and parameter with every mode in it in its own colour: points for
/// sampled sweeps, curves in parameter order for a one-parameter grid.
fn by_metric(
    dir: &Path,
    parameter_columns: &[String],
    figure_columns: &[String],
    rows: &[(Case, Vec<Cell>)],
    max_figures: usize,
    lines: bool,
    target_mrad: Option<f64>,
) -> Result<Vec<PathBuf>, ReportError> {
    let mut files = Vec::new();
    let mut charts = Vec::new();
    let figures = drawn_figures(figure_columns, rows, max_figures);
    // One chart per metric and parameter, every mode in it in its own colour.
    let mut metrics: Vec<&str> = Vec::new();
    for &j in &figures {
        let m = mode_and_metric(&figure_columns[j]).1;
        if !metrics.contains(&m) {
            metrics.push(m);
        }
    }
    for metric in metrics {
        for (i, param) in parameter_columns.iter().enumerate().take(4) {
            let mut series = Vec::new();
            let mut xs_all = Vec::new();
            let mut cases = 0;
            for &j in figures
                .iter()
                .filter(|&&j| mode_and_metric(&figure_columns[j]).1 == metric)
            {
                let mut pts: Vec<(f64, f64)> = rows
                    .iter()
                    .filter_map(|r| {
                        let x = r.0.assignments.get(i).and_then(|a| numeric(&a.2))?;
                        match r.1.get(j) {
                            Some(Cell::Num(Some(v))) if v.is_finite() => Some((x, *v)),
                            _ => None,
                        }
                    })
                    .collect();
                if lines {
                    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                }
                let (x, y): (Vec<f64>, Vec<f64>) = pts.into_iter().unzip();
                if x.is_empty() {
                    continue;
                }
                cases = cases.max(x.len());
                xs_all.extend(x.iter().copied());
                let fig = &figure_columns[j];
                let (label, slot) = match mode_and_metric(fig).0 {
                    Some((mode, slot)) => (mode.to_string(), Some(slot)),
                    None => (column_words(fig).0, None),
                };
                let s = if lines {
                    Series::line(label, x, y)
                } else {
                    Series::points(label, x, y)
                };
                let s = match slot {
                    Some(k) => s.in_slot(k),
                    None => s,
                };
                series.push(s);
            }
            if series.is_empty() {
                continue;
            }
            series.extend(target_series(metric, target_mrad, &xs_all));
            let chart = Chart {
                title: format!(
                    "{} against {} ({cases} finished cases)",
                    column_words(metric).0,
                    column_words(param).0
                ),
                x_label: column_label(param),
                y_label: column_label(metric),
                series,
                log_x: log_spaced(&xs_all),
                ..Chart::default()
            };
            charts.push((chart, dir.join(format!("{metric}_vs_{param}"))));
        }
    }
    // Drawing is the whole cost here, and the charts are independent: one per core,
    // written in order.
    use rayon::prelude::*;
    let saved: Vec<_> = charts
        .par_iter()
        .map(|(chart, stem)| save_chart(chart, stem))
        .collect();
    for s in saved {
        files.extend(s?);
    }
    Ok(files)
}

/// How the cases of a sweep ended, per status column (`status`, or `<mode>_status`):
/// finished (`ok`), stopped by the physics (slack, gross slip, unstable, ...) or not run
/// at all (`error`, invalid parameters), the pass rate with every stopped or failed case
/// counted as not meeting the target, and the first stopped cases with their values and
/// reason. Returns JSON and a printable text.
pub fn outcomes(
    parameter_columns: &[String],
    figure_columns: &[String],
    rows: &[(Case, Vec<Cell>)],
) -> (serde_json::Value, String) {
    const SHOWN: usize = 5;
    let mut json = serde_json::Map::new();
    let mut text = String::new();
    let text_of = |cells: &[Cell], j: Option<usize>| match j.and_then(|j| cells.get(j)) {
        Some(Cell::Text(t)) => t.clone(),
        _ => String::new(),
    };
    for (j, name) in figure_columns.iter().enumerate() {
        let Some(prefix) = name.strip_suffix("status") else {
            continue;
        };
        let passes = figure_columns
            .iter()
            .position(|c| *c == format!("{prefix}passes_target"));
        let stop = figure_columns
            .iter()
            .position(|c| *c == format!("{prefix}stop"));
        let (mut ok, mut stopped, mut errors, mut passed) = (0usize, 0usize, 0usize, 0usize);
        let mut first = Vec::new();
        for (case, cells) in rows {
            let status = text_of(cells, Some(j));
            match status.as_str() {
                "ok" => ok += 1,
                "error" => errors += 1,
                _ => stopped += 1,
            }
            if text_of(cells, passes) == "true" && status == "ok" {
                passed += 1;
            }
            if status != "ok" && first.len() < SHOWN {
                let values: serde_json::Map<String, serde_json::Value> = parameter_columns
                    .iter()
                    .zip(&case.assignments)
                    .map(|(c, a)| (c.clone(), serde_json::json!(render_value(&a.2))))
                    .collect();
                first.push(serde_json::json!({
                    "case": case.index,
                    "values": values,
                    "status": status,
                    "reason": text_of(cells, stop),
                }));
            }
        }
        let label = prefix.trim_end_matches('_');
        let label = if label.is_empty() { "cases" } else { label };
        let n = rows.len();
        text.push_str(&format!(
            "{label}: {ok} of {n} cases finished, {stopped} stopped by the physics, {errors} could not run{}\n",
            passes.map_or(String::new(), |_| format!(
                "; {passed} meet the target ({:.1} %, stopped and failed cases counted as not meeting it)",
                if n > 0 { 100.0 * passed as f64 / n as f64 } else { 0.0 }
            ))
        ));
        for f in &first {
            text.push_str(&format!(
                "  case {} ({}): {} {}\n",
                f["case"],
                f["values"]
                    .as_object()
                    .map(|m| m
                        .iter()
                        .map(|(k, v)| format!("{k} = {}", v.as_str().unwrap_or_default()))
                        .collect::<Vec<_>>()
                        .join(", "))
                    .unwrap_or_default(),
                f["status"].as_str().unwrap_or_default(),
                f["reason"].as_str().unwrap_or_default()
            ));
        }
        json.insert(
            label.to_string(),
            serde_json::json!({
                "cases": n,
                "finished": ok,
                "stopped": stopped,
                "errors": errors,
                "meet_target": passes.map(|_| passed),
                "pass_rate": passes.map(|_| if n > 0 { passed as f64 / n as f64 } else { 0.0 }),
                "first_not_finished": first,
            }),
        );
    }
    (serde_json::Value::Object(json), text)
}

#[cfg(test)]
mod plot_choice_tests {
    use super::*;

    #[test]
    fn log_spaced_values_are_told_from_linear_ones() {
        assert!(log_spaced(&[5.0, 15.8, 50.0, 158.0, 500.0]));
        assert!(!log_spaced(&[10.0, 20.0, 30.0, 40.0, 50.0]));
        assert!(!log_spaced(&[1.0, 2.0, 3.0]));
        assert!(!log_spaced(&[-1.0, 10.0, 100.0]));
    }

    /// However many curves a family has, none takes the grey of the target line, and up
    /// to nine each has a colour of its own.
    #[test]
    fn a_family_never_takes_the_target_grey() {
        let curve = || Series::line("", Vec::new(), Vec::new());
        for n in 1..=9 {
            let slots: Vec<Option<usize>> =
                (0..n).map(|k| member(curve(), k, n).palette_slot).collect();
            assert!(!slots.contains(&Some(7)), "{slots:?}");
            let mut distinct = slots.clone();
            distinct.sort_unstable();
            distinct.dedup();
            assert_eq!(distinct.len(), n, "{slots:?}");
        }
        let ramp: Vec<Option<[u8; 3]>> = (0..12).map(|k| member(curve(), k, 12).rgb).collect();
        assert!(ramp
            .iter()
            .all(|c| c.is_some() && *c != Some([127, 127, 127])));
    }

    #[test]
    fn a_figure_column_is_described_with_its_mode_and_unit() {
        assert_eq!(
            figure_label("memory_rms_mrad"),
            "RMS pointing error, memory [mrad]"
        );
        assert_eq!(figure_label("reversal_mrad"), "reversal backlash [mrad]");
        assert_eq!(figure_label("tension_upper_n"), "tension upper [N]");
        assert_eq!(
            figure_words("none_p95_mrad"),
            "95th percentile pointing error, none"
        );
    }

    #[test]
    fn a_figure_column_names_its_mode_and_metric() {
        assert_eq!(
            mode_and_metric("memoryless_rms_mrad"),
            (Some(("memoryless", 1)), "rms_mrad")
        );
        assert_eq!(
            mode_and_metric("memory_peak_mrad"),
            (Some(("memory", 2)), "peak_mrad")
        );
        assert_eq!(mode_and_metric("reversal_mrad"), (None, "reversal_mrad"));
    }
}
