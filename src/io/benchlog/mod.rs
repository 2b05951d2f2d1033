//! Strict reader and atomic writer for measured bench logs.
//!
//! A bench log is a CSV file (see `data-format.md`): optional `#` comment lines, then one
//! header row, then one row per sample. Column names are fixed, their order is free and
//! unknown extra columns are ignored (but reported).
//!
//! | column            | unit | required |
//! |-------------------|------|----------|
//! | `t_s`             | s    | yes (strictly increasing) |
//! | `theta_in_rad`    | rad  | yes |
//! | `theta_out_rad`   | rad  | yes |
//! | `load_nm`         | N m  | yes |
//! | `tension_upper_n` | N    | no  |
//! | `tension_lower_n` | N    | no  |
//! | `motor_current_a` | A    | no  |
//!
//! Accepted leniencies: a UTF-8 byte-order mark, `\n`, `\r\n` or `\r` line endings, blank
//! (empty or whitespace-only) lines anywhere, spaces/tabs around fields and column names,
//! and CSV quoting of fields. Everything else that is not a finite number where a number is
//! needed is an input error ([`LogError`]) whose message names the file, the 1-based line
//! number in the file (comment and blank lines included) and, where relevant, the column.
//!
//! The reader streams: bytes flow from a [`std::io::BufReader`] through a small line filter into a
//! [`csv::Reader`], one record at a time. [`visit_bench_log`] therefore runs in memory
//! bounded by the longest line; [`read_bench_log`] additionally holds the output columns.
//! No input can make the reader panic.
//!
//! [`write_bench_log`] writes the same format atomically, with floats that read back bit
//! for bit; [`write_bench_log_to`] writes it to any [`std::io::Write`]r.
//!
//! The parts: `errors` (what can be wrong with a log, and messages that say where),
//! `parse` (the streaming line filter and record parser), `write` (the atomic writer).

mod errors;
mod parse;
#[cfg(test)]
mod tests;
mod write;

use std::fs::File;
use std::io::Read;
use std::path::Path;

pub use crate::measurement::{BenchLog, Sample};
pub(crate) use errors::show;
pub use errors::{LogError, ValueProblem};
pub use write::{write_bench_log, write_bench_log_to};

use parse::Parser;

/// Required columns, in the order [`write_bench_log`] writes them.
pub const REQUIRED_COLUMNS: [&str; 4] = ["t_s", "theta_in_rad", "theta_out_rad", "load_nm"];

/// Optional columns, in the order [`write_bench_log`] writes them (after the required ones).
pub const OPTIONAL_COLUMNS: [&str; 3] = ["tension_upper_n", "tension_lower_n", "motor_current_a"];

/// Largest magnitude an angle (rad) or load (N m) column of a log a drive is judged on
/// may hold ([`read_drive_log`]): 1e6 is far beyond any drive (160 000 turns, a megajoule
/// per radian), and a replay of anything larger overflows.
pub const MAX_MAGNITUDE: f64 = 1e6;

/// Largest magnitude of a log's time column, s: 1e9 s is 32 years, far beyond any bench
/// run, and a time of 1e300 s would reach every trace, axis and table read from it.
pub const MAX_TIME_S: f64 = 1e9;

/// Maximum number of characters of offending input quoted in an error message.
const MAX_SHOWN_CHARS: usize = 40;

/// Maximum number of found column names listed in a missing-columns message.
const MAX_SHOWN_COLUMNS: usize = 20;

const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// Summary of a log streamed by [`visit_bench_log`].
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct LogInfo {
    /// All header column names (trimmed), in file order.
    pub columns: Vec<String>,
    /// Unknown columns that were ignored, in file order.
    pub extra_columns: Vec<String>,
    /// Comment lines before the header (see [`BenchLog::comments`]).
    pub comments: Vec<String>,
    /// 1-based line number of the header row.
    pub header_line: u64,
    /// Number of sample rows.
    pub rows: u64,
    /// Whether the optional `tension_upper_n` column is present.
    pub has_tension_upper_n: bool,
    /// Whether the optional `tension_lower_n` column is present.
    pub has_tension_lower_n: bool,
    /// Whether the optional `motor_current_a` column is present.
    pub has_motor_current_a: bool,
}

/// Read and validate a bench log file.
///
/// The file is streamed; memory use is the returned columns. Errors name `path`.
pub fn read_bench_log(path: &Path) -> Result<BenchLog, LogError> {
    read_file(path, false)
}

/// [`read_bench_log`] for a log a drive is judged on: angles and loads beyond
/// [`MAX_MAGNITUDE`] are refused with file, line and column, as any other bad value (a
/// load of 1e308 N m reached the replay and its messages as `inf`).
pub fn read_drive_log(path: &Path) -> Result<BenchLog, LogError> {
    read_file(path, true)
}

/// The file at `path` read by [`read_log`]; errors name `path`.
fn read_file(path: &Path, bounded: bool) -> Result<BenchLog, LogError> {
    let name = path.display().to_string();
    let file = File::open(path).map_err(|source| LogError::Io {
        path: name.clone(),
        source,
    })?;
    read_log(file, &name, bounded)
}

/// Read and validate a bench log from any reader (buffering is done internally);
/// `name` stands for the file path in error messages and in [`BenchLog::source`].
pub fn read_bench_log_from<R: Read>(reader: R, name: &str) -> Result<BenchLog, LogError> {
    read_log(reader, name, false)
}

/// [`read_bench_log_from`], with angles and loads held to [`MAX_MAGNITUDE`] when `bounded`.
fn read_log<R: Read>(reader: R, name: &str, bounded: bool) -> Result<BenchLog, LogError> {
    let mut parser = Parser::open(reader, name)?;
    parser.bounded = bounded;
    let info = &parser.info;
    let mut log = BenchLog {
        tension_upper_n: info.has_tension_upper_n.then(Vec::new),
        tension_lower_n: info.has_tension_lower_n.then(Vec::new),
        motor_current_a: info.has_motor_current_a.then(Vec::new),
        source: name.to_string(),
        ..BenchLog::default()
    };
    while let Some(s) = parser.next_sample()? {
        log.t_s.push(s.t_s);
        log.theta_in_rad.push(s.theta_in_rad);
        log.theta_out_rad.push(s.theta_out_rad);
        log.load_nm.push(s.load_nm);
        for (col, v) in [
            (&mut log.tension_upper_n, s.tension_upper_n),
            (&mut log.tension_lower_n, s.tension_lower_n),
            (&mut log.motor_current_a, s.motor_current_a),
        ] {
            if let (Some(c), Some(v)) = (col.as_mut(), v) {
                c.push(v);
            }
        }
    }
    let info = parser.finish()?;
    for c in [
        &mut log.t_s,
        &mut log.theta_in_rad,
        &mut log.theta_out_rad,
        &mut log.load_nm,
    ] {
        c.shrink_to_fit();
    }
    for c in [
        &mut log.tension_upper_n,
        &mut log.tension_lower_n,
        &mut log.motor_current_a,
    ]
    .into_iter()
    .flatten()
    {
        c.shrink_to_fit();
    }
    log.extra_columns = info.extra_columns;
    log.comments = info.comments;
    Ok(log)
}

/// Stream a bench log, calling `f` for every valid sample in file order, without storing
/// the samples (memory is bounded by the longest line).
///
/// Validation is the same as [`read_bench_log_from`]. Because validation is streaming,
/// `f` may already have seen the samples before an offending row when an error is
/// returned; callers that must not act on partial data should buffer or discard them.
pub fn visit_bench_log<R: Read>(
    reader: R,
    name: &str,
    mut f: impl FnMut(&Sample),
) -> Result<LogInfo, LogError> {
    let mut parser = Parser::open(reader, name)?;
    while let Some(s) = parser.next_sample()? {
        f(&s);
    }
    parser.finish()
}
