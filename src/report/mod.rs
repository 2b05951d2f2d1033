//! Result files and plots of each study. Edge layer: imports computation results, plot, io
//! and scenario. CSV and JSON are written first; plots come after and can never break a run
//! (their failures are reported as warnings).

pub mod closed_loop;
pub mod columns;
pub mod compare;
pub mod diagnosis;
pub mod freqresp;
pub mod html;
pub mod margins;
pub mod quasi_static;
pub mod sweep;

use std::path::{Path, PathBuf};

/// Writing results failed.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// File system error.
    #[error("cannot write {path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// CSV or JSON encoding error.
    #[error("cannot write {path}: {message}")]
    Encode {
        /// File.
        path: PathBuf,
        /// Cause.
        message: String,
    },
    /// A plot could not be drawn.
    #[error("plot: {0}")]
    Plot(#[from] crate::plot::PlotError),
}

impl ReportError {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        ReportError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
    pub(crate) fn csv(path: &Path, e: csv::Error) -> Self {
        ReportError::Encode {
            path: path.to_path_buf(),
            message: e.to_string(),
        }
    }
}

/// A CSV writer on a new file.
pub fn csv_writer(path: &Path) -> Result<csv::Writer<std::fs::File>, ReportError> {
    let file = std::fs::File::create(path).map_err(|e| ReportError::io(path, e))?;
    Ok(csv::Writer::from_writer(file))
}

/// Write pretty JSON atomically.
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<(), ReportError> {
    let mut text = serde_json::to_string_pretty(value).map_err(|e| ReportError::Encode {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    text.push('\n');
    crate::io::output::write_atomic(path, text.as_bytes()).map_err(|e| ReportError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    })
}

/// Write `summary.json`: the provenance every result records (program and version,
/// scenario name, study, completeness and the resolved scenario) merged with the study's
/// own `fields` (a JSON object).
pub fn write_summary(
    path: &Path,
    scenario: &crate::scenario::Scenario,
    complete: bool,
    fields: &serde_json::Value,
) -> Result<(), ReportError> {
    write_json(path, &with_provenance(scenario, complete, fields))
}

/// The provenance every result records (program and version, scenario name, study,
/// completeness and the resolved scenario) merged with a record's own `fields` (a JSON
/// object; its keys win): what `summary.json` holds, and the records of the commands that
/// write another file (`diagnosis.json`, `leave_one_out.json`).
pub fn with_provenance(
    scenario: &crate::scenario::Scenario,
    complete: bool,
    fields: &serde_json::Value,
) -> serde_json::Value {
    let mut summary = serde_json::json!({
        "program": "cable-servo",
        "program_version": env!("CARGO_PKG_VERSION"),
        "scenario_name": scenario.name(),
        "study": scenario.study,
        "complete": complete,
        "scenario": scenario,
    });
    if let (Some(all), Some(own)) = (summary.as_object_mut(), fields.as_object()) {
        all.extend(own.clone());
    }
    summary
}
