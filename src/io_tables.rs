//! Loading of CSV tables named in a scenario: reference trajectories
//! (`Signal::Table`) and load torque series (`load.disturbance_csv`).
//!
//! A table is a CSV file with a header; the time column is `t_s`, the value column is the
//! one the scenario names (`value` by default, `torque_nm` for disturbances). Rows must be
//! in increasing time.

use std::path::{Path, PathBuf};

use crate::scenario::Scenario;

/// A table that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// File cannot be opened or parsed as CSV.
    #[error("cannot read table {path}: {message}")]
    Read {
        /// File path.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A needed column is missing.
    #[error("table {path} has no column {column:?} (columns: {found})")]
    MissingColumn {
        /// File path.
        path: PathBuf,
        /// Wanted column.
        column: String,
        /// Columns present.
        found: String,
    },
    /// A bad row.
    #[error("table {path}, line {line}: {message}")]
    BadRow {
        /// File path.
        path: PathBuf,
        /// 1-based line (header is line 1).
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// Read `(t_s, column)` pairs from a CSV file.
pub fn read_table(path: &Path, column: &str) -> Result<Vec<(f64, f64)>, TableError> {
    let read_err = |message: String| TableError::Read {
        path: path.to_path_buf(),
        message,
    };
    let mut r = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| read_err(e.to_string()))?;
    let headers = r.headers().map_err(|e| read_err(e.to_string()))?.clone();
    let find = |name: &str| {
        headers
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| TableError::MissingColumn {
                path: path.to_path_buf(),
                column: name.to_string(),
                found: headers.iter().collect::<Vec<_>>().join(", "),
            })
    };
    let (it, iv) = (find("t_s")?, find(column)?);
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (i, rec) in r.records().enumerate() {
        let line = i + 2;
        let bad = |message: String| TableError::BadRow {
            path: path.to_path_buf(),
            line,
            message,
        };
        let rec = rec.map_err(|e| bad(e.to_string()))?;
        let num = |k: usize, name: &str| -> Result<f64, TableError> {
            let s = rec.get(k).unwrap_or("");
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(format!("{name} = {s:?} is not a finite number")))
        };
        let (t, v) = (num(it, "t_s")?, num(iv, column)?);
        if let Some(&(tp, _)) = out.last() {
            if t <= tp {
                return Err(bad(format!("t_s = {t} does not increase (previous {tp})")));
            }
        }
        out.push((t, v));
    }
    if out.is_empty() {
        return Err(read_err("no data rows".into()));
    }
    Ok(out)
}

/// Fill every table of a scenario from files; relative paths are taken from `base_dir`
/// (the scenario file's folder).
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
    if let Some(cl) = scenario.closed_loop.as_mut() {
        cl.reference.for_each_table(&mut |path, column, samples| {
            if result.is_ok() {
                match read_table(&resolve(path), column) {
                    Ok(s) => *samples = s,
                    Err(e) => result = Err(e),
                }
            }
        });
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_and_rejects() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.csv");
        std::fs::write(&p, "t_s, value\n0, 0\n1, 0.5\n").unwrap();
        assert_eq!(
            read_table(&p, "value").unwrap(),
            vec![(0.0, 0.0), (1.0, 0.5)]
        );
        assert!(matches!(
            read_table(&p, "torque_nm"),
            Err(TableError::MissingColumn { .. })
        ));
        std::fs::write(&p, "t_s,value\n0,0\n0,1\n").unwrap();
        let e = read_table(&p, "value").unwrap_err().to_string();
        assert!(e.contains("line 3"), "{e}");
        std::fs::write(&p, "t_s,value\n0,nan\n").unwrap();
        assert!(read_table(&p, "value").is_err());
    }
}
