//! The sweep table (`sweep.csv`, streamed one row per case) and its plots.

use std::io::Write;
use std::path::{Path, PathBuf};

use super::ReportError;
use crate::plot::{save_chart, save_heatmap, Chart, Heatmap, Series};
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
    let numeric_figures: Vec<usize> = (0..figure_columns.len())
        .filter(|&j| {
            rows.iter()
                .any(|r| matches!(r.1.get(j), Some(Cell::Num(Some(_)))))
        })
        .take(max_figures)
        .collect();
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
                vec![Series::line(fig.clone(), x, y)]
            } else {
                distinct(gi)
                    .into_iter()
                    .map(|g| {
                        let mut pts: Vec<(f64, f64)> = rows
                            .iter()
                            .filter(|r| param(r, gi) == Some(g))
                            .filter_map(|r| Some((param(r, xi)?, value(r, j)?)))
                            .collect();
                        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                        let (x, y) = pts.into_iter().unzip();
                        Series::line(format!("{} = {g}", parameter_columns[gi]), x, y)
                    })
                    .collect()
            };
            let chart = Chart {
                title: format!("{fig} against {}", parameter_columns[xi]),
                x_label: parameter_columns[xi].clone(),
                y_label: fig.clone(),
                series,
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
                        "{fig} over {} and {}",
                        parameter_columns[0], parameter_columns[1]
                    ),
                    x_label: parameter_columns[0].clone(),
                    y_label: parameter_columns[1].clone(),
                    z_label: fig.clone(),
                    x: xs,
                    y: ys,
                    z,
                    contour: if fig.ends_with("_mrad") {
                        contour_mrad
                    } else {
                        None
                    },
                };
                files.extend(save_heatmap(&map, &dir.join(format!("{fig}_map")))?);
            }
        }
    }
    Ok(files)
}
