//! Small time tables referenced by scenarios: CSV trajectories and disturbance torques.

use std::path::{Path, PathBuf};

use crate::scenario::Scenario;

/// A table file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// The file cannot be read.
    #[error("cannot read {path}: {message}")]
    Read {
        /// File.
        path: PathBuf,
        /// Cause.
        message: String,
    },
    /// Bad content.
    #[error("file {path}, row {row} (line {line}), column \"{column}\": {message}")]
    Content {
        /// File.
        path: PathBuf,
        /// 1-based data row (the header and comment lines not counted).
        row: u64,
        /// 1-based line of the file.
        line: u64,
        /// Column name.
        column: String,
        /// What is wrong.
        message: String,
    },
}

/// Largest time a table may hold, s (about 30 years): beyond any run, and it keeps the
/// times users read short.
pub const MAX_TABLE_TIME_S: f64 = 1e9;

/// Largest disturbance torque a table may hold, N m: far beyond any cable drive (a gimbal
/// drum carries a few N m), like the scenario's own torque keys.
pub const MAX_TABLE_TORQUE_NM: f64 = 1e4;

/// What a table's value column holds, and so the range each of its rows must keep to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValueRange {
    /// Largest magnitude allowed, in `unit`.
    pub max_abs: f64,
    /// Unit shown in messages (`rad`, `N m`).
    pub unit: &'static str,
}

impl ValueRange {
    /// A closed-loop reference or base motion, rad: the bound of the closed-loop
    /// references' own keys.
    pub const POINTING: ValueRange = ValueRange {
        max_abs: crate::closed_loop::params::MAX_POINTING_RAD,
        unit: "rad",
    };
    /// A quasi-static input motion, rad: the bound of a signal's amplitude keys.
    pub const MOTION: ValueRange = ValueRange {
        max_abs: crate::signal::MAX_ANGLE_RAD,
        unit: "rad",
    };
    /// A disturbance torque, N m.
    pub const TORQUE: ValueRange = ValueRange {
        max_abs: MAX_TABLE_TORQUE_NM,
        unit: "N m",
    };
}

/// Read `(t_s, value)` pairs from a CSV file with a `t_s` column and `column`; `#` comment
/// lines are skipped; time must be finite, within [`MAX_TABLE_TIME_S`] and increase
/// strictly; every value must lie within `range` (checked row by row, like the scenario's
/// keys, so a mistyped row is named instead of running or printing huge numbers).
pub fn read_table(
    path: &Path,
    column: &str,
    range: ValueRange,
) -> Result<Vec<(f64, f64)>, TableError> {
    let read_err = |message: String| TableError::Read {
        path: path.to_path_buf(),
        message,
    };
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| read_err(e.to_string()))?;
    let headers = reader
        .headers()
        .map_err(|e| read_err(e.to_string()))?
        .clone();
    let find = |name: &str| {
        headers
            .iter()
            .position(|h| h.trim_start_matches('\u{feff}') == name)
            .ok_or_else(|| {
                read_err(format!(
                    "no column `{name}` (found: {})",
                    headers.iter().collect::<Vec<_>>().join(", ")
                ))
            })
    };
    let it = find("t_s")?;
    let iv = find(column)?;
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (index, record) in reader.records().enumerate() {
        let record = record.map_err(|e| read_err(e.to_string()))?;
        let line = record.position().map_or(0, |p| p.line());
        let content = |name: &str, message: String| TableError::Content {
            path: path.to_path_buf(),
            row: index as u64 + 1,
            line,
            column: name.to_string(),
            message,
        };
        let cell = |i: usize, name: &str, max_abs: f64, unit: &str| -> Result<f64, TableError> {
            let text = record.get(i).unwrap_or("");
            let Ok(v) = text.parse::<f64>() else {
                // The cell as typed, cut short: a pasted blob must not flood the message.
                let shown: String = text.chars().take(40).collect();
                return Err(content(name, format!("\"{shown}\" is not a number")));
            };
            if v.is_finite() && v.abs() <= max_abs {
                Ok(v)
            } else {
                Err(content(
                    name,
                    format!(
                        "{} is out of range (allowed {} to {} {unit})",
                        crate::readable(v),
                        crate::readable(-max_abs),
                        crate::readable(max_abs)
                    ),
                ))
            }
        };
        let t = cell(it, "t_s", MAX_TABLE_TIME_S, "s")?;
        let v = cell(iv, column, range.max_abs, range.unit)?;
        if let Some(&(prev, _)) = out.last() {
            if t <= prev {
                return Err(content(
                    "t_s",
                    format!(
                        "time {} s does not increase (previous row {} s)",
                        crate::readable(t),
                        crate::readable(prev)
                    ),
                ));
            }
        }
        out.push((t, v));
    }
    if out.is_empty() {
        return Err(read_err("holds no samples".into()));
    }
    Ok(out)
}

/// Fill every table a scenario references, paths relative to `base_dir` (the scenario
/// file's folder).
pub fn load_tables(scenario: &mut Scenario, base_dir: &Path) -> Result<(), TableError> {
    let resolve = |p: &str| {
        let p = Path::new(p);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            base_dir.join(p)
        }
    };
    if let Some(path) = scenario.load.disturbance_csv.clone() {
        scenario.load.disturbance = read_table(&resolve(&path), "torque_nm", ValueRange::TORQUE)?;
    }
    let mut result = Ok(());
    let visitor = |range: ValueRange| {
        move |path: &str, column: &str, samples: &mut Vec<(f64, f64)>| {
            if samples.is_empty() {
                *samples = read_table(&resolve(path), column, range)?;
            }
            Ok::<(), TableError>(())
        }
    };
    if let Some(qs) = scenario.quasi_static.as_mut() {
        let read = visitor(ValueRange::MOTION);
        qs.motion.for_each_table(&mut |p, c, s| {
            if result.is_ok() {
                result = read(p, c, s);
            }
        });
    }
    for signal in scenario.signals_mut() {
        let read = visitor(ValueRange::POINTING);
        signal.for_each_table(&mut |p, c, s| {
            if result.is_ok() {
                result = read(p, c, s);
            }
        });
    }
    result
}
