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
    #[error("{path}:{line}: column {column}: {message}")]
    Content {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// Column name.
        column: String,
        /// What is wrong.
        message: String,
    },
}

/// Read `(t_s, value)` pairs from a CSV file with a `t_s` column and `column`; `#` comment
/// lines are skipped; time must increase strictly.
pub fn read_table(path: &Path, column: &str) -> Result<Vec<(f64, f64)>, TableError> {
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
    for record in reader.records() {
        let record = record.map_err(|e| read_err(e.to_string()))?;
        let line = record.position().map_or(0, |p| p.line());
        let cell = |i: usize, name: &str| -> Result<f64, TableError> {
            let text = record.get(i).unwrap_or("");
            text.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| TableError::Content {
                    path: path.to_path_buf(),
                    line,
                    column: name.to_string(),
                    message: format!("{text:?} is not a finite number"),
                })
        };
        let t = cell(it, "t_s")?;
        let v = cell(iv, column)?;
        if let Some(&(prev, _)) = out.last() {
            if t <= prev {
                return Err(TableError::Content {
                    path: path.to_path_buf(),
                    line,
                    column: "t_s".into(),
                    message: format!("time {t} s does not increase (previous {prev} s)"),
                });
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
        scenario.load.disturbance = read_table(&resolve(&path), "torque_nm")?;
    }
    let mut result = Ok(());
    let mut visit = |path: &str, column: &str, samples: &mut Vec<(f64, f64)>| {
        if result.is_ok() && samples.is_empty() {
            match read_table(&resolve(path), column) {
                Ok(s) => *samples = s,
                Err(e) => result = Err(e),
            }
        }
    };
    if let Some(qs) = scenario.quasi_static.as_mut() {
        qs.motion.for_each_table(&mut visit);
    }
    for signal in scenario.signals_mut() {
        signal.for_each_table(&mut visit);
    }
    result
}
