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
//! The reader streams: bytes flow from a [`BufReader`] through a small line filter into a
//! [`csv::Reader`], one record at a time. [`visit_bench_log`] therefore runs in memory
//! bounded by the longest line; [`read_bench_log`] additionally holds the output columns.
//! No input can make the reader panic.
//!
//! [`write_bench_log`] writes the same format atomically, with floats that read back bit
//! for bit; [`write_bench_log_to`] writes it to any [`Write`]r.

use std::collections::{HashMap, VecDeque};
use std::fs::File;
use std::io::{self, BufRead, BufReader, BufWriter, Read, Write};
use std::path::Path;

pub use crate::measurement::{BenchLog, Sample};

/// Required columns, in the order [`write_bench_log`] writes them.
pub const REQUIRED_COLUMNS: [&str; 4] = ["t_s", "theta_in_rad", "theta_out_rad", "load_nm"];

/// Optional columns, in the order [`write_bench_log`] writes them (after the required ones).
pub const OPTIONAL_COLUMNS: [&str; 3] = ["tension_upper_n", "tension_lower_n", "motor_current_a"];

/// Maximum number of characters of offending input quoted in an error message.
const MAX_SHOWN_CHARS: usize = 40;

/// Maximum number of found column names listed in a missing-columns message.
const MAX_SHOWN_COLUMNS: usize = 20;

const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// What is wrong with a field that should hold a number (see [`LogError::BadValue`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValueProblem {
    /// The field is empty (or only whitespace).
    Empty,
    /// The text is not a decimal number.
    NotANumber,
    /// The text spells NaN.
    NaN,
    /// The text spells an infinity (`inf`, `-infinity`, ...).
    Infinite,
    /// The text is a number too large for an `f64` (e.g. `1e999`).
    OutOfRange,
}

/// Errors from reading or writing a bench log.
///
/// `path` is the file path (or the `name` given to the `*_from` / `visit_*` functions);
/// `line` is the 1-based physical line number in the file, counting comment and blank
/// lines. Every message is a single line naming the file, the line and (where relevant)
/// the column, and says what would be accepted.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// The file cannot be opened or read.
    #[error("{path}: cannot read bench log: {source}")]
    Io {
        /// File path or stream name.
        path: String,
        /// Underlying I/O error.
        source: io::Error,
    },
    /// The file (or its temporary sibling) cannot be written, synced or renamed.
    #[error("{path}: cannot write bench log: {source}")]
    Write {
        /// Destination path.
        path: String,
        /// Underlying I/O error.
        source: io::Error,
    },
    /// No header row: the file is empty or holds only comment/blank lines.
    #[error(
        "{path}: empty bench log: no header row found{}; expected a CSV header row naming the columns {} (any order), optionally preceded by `#` comment lines",
        empty_note(*lines),
        REQUIRED_COLUMNS.join(", ")
    )]
    Empty {
        /// File path or stream name.
        path: String,
        /// Number of (comment or blank) lines in the file.
        lines: u64,
    },
    /// A header row but no sample rows.
    #[error(
        "{path}: line {line}: bench log has a header row but no data rows; at least one sample row is required after the header"
    )]
    HeaderOnly {
        /// File path or stream name.
        path: String,
        /// Line of the header row.
        line: u64,
    },
    /// One or more required columns are absent from the header.
    #[error(
        "{path}: line {line} (header): missing required column(s) {}; columns found: {}; required columns are {} in any order (optional: {}){}",
        missing.join(", "),
        show_list(found),
        REQUIRED_COLUMNS.join(", "),
        OPTIONAL_COLUMNS.join(", "),
        header_hint(found)
    )]
    MissingColumns {
        /// File path or stream name.
        path: String,
        /// Line of the header row.
        line: u64,
        /// Required column names not found.
        missing: Vec<String>,
        /// All column names found in the header, in file order.
        found: Vec<String>,
    },
    /// The same column name appears twice in the header.
    #[error(
        "{path}: line {line} (header): column {} appears twice (fields {first_field} and {second_field}); each column name may appear only once",
        show(column)
    )]
    DuplicateColumn {
        /// File path or stream name.
        path: String,
        /// Line of the header row.
        line: u64,
        /// The duplicated column name.
        column: String,
        /// 1-based field index of the first occurrence.
        first_field: usize,
        /// 1-based field index of the second occurrence.
        second_field: usize,
    },
    /// A header field is empty (often a trailing comma).
    #[error(
        "{path}: line {line} (header): field {field} has an empty column name; every header field must name a column (check for a stray or trailing comma)"
    )]
    EmptyColumnName {
        /// File path or stream name.
        path: String,
        /// Line of the header row.
        line: u64,
        /// 1-based field index.
        field: usize,
    },
    /// A field that must hold a finite number does not.
    #[error(
        "{path}: line {line}, column {}: {}; expected a finite decimal number such as 0.25 or -1.5e-3",
        show(column),
        describe_value(*reason, text)
    )]
    BadValue {
        /// File path or stream name.
        path: String,
        /// Line of the row.
        line: u64,
        /// Column name.
        column: String,
        /// The offending text (truncated to about 40 characters).
        text: String,
        /// What is wrong with it.
        reason: ValueProblem,
    },
    /// `t_s` does not strictly increase from one row to the next.
    #[error(
        "{path}: line {line}, column \"t_s\": time {t_s:?} s {} the previous sample's time {prev_s:?} s (line {prev_line}); t_s must be strictly increasing",
        if t_s == prev_s { "equals" } else { "is earlier than" }
    )]
    NonIncreasingTime {
        /// File path or stream name.
        path: String,
        /// Line of the offending row.
        line: u64,
        /// Line of the previous sample.
        prev_line: u64,
        /// Time of the previous sample, s.
        prev_s: f64,
        /// Time of the offending row, s.
        t_s: f64,
    },
    /// A row has a different number of fields than the header.
    #[error(
        "{path}: line {line}: expected {expected} fields (one per header column), found {found}{}",
        if found > expected { " (decimal commas and trailing commas are not allowed)" } else { "" }
    )]
    Ragged {
        /// File path or stream name.
        path: String,
        /// Line of the row.
        line: u64,
        /// Number of header columns.
        expected: usize,
        /// Number of fields in the row.
        found: usize,
    },
    /// A `#` comment line after the header row.
    #[error(
        "{path}: line {line}: `#` comment line after the header row; comments are only allowed before the header"
    )]
    CommentAfterHeader {
        /// File path or stream name.
        path: String,
        /// Line of the comment.
        line: u64,
    },
    /// Bytes that are not valid UTF-8.
    #[error(
        "{path}: line {line}{}: invalid UTF-8 byte sequence; bench logs must be UTF-8 (plain ASCII) text",
        column.as_deref().map(|c| format!(", column {}", show(c))).unwrap_or_default()
    )]
    Encoding {
        /// File path or stream name.
        path: String,
        /// Line containing the bad bytes.
        line: u64,
        /// Column, when the bytes are inside a data field.
        column: Option<String>,
    },
    /// Any other CSV-level problem reported by the `csv` crate.
    #[error("{path}{}: malformed CSV: {message}", line.map(|l| format!(": line {l}")).unwrap_or_default())]
    Csv {
        /// File path or stream name.
        path: String,
        /// Line, when known.
        line: Option<u64>,
        /// The `csv` crate's description.
        message: String,
    },
    /// [`write_bench_log`] was given a log that could not be read back (no samples,
    /// columns of different lengths, non-finite values, non-increasing time).
    #[error("{path}: refusing to write invalid bench log: {reason}")]
    Invalid {
        /// Destination path.
        path: String,
        /// What is wrong with the log.
        reason: String,
    },
}

impl LogError {
    /// The 1-based line number in the file the error refers to, if any.
    pub fn line(&self) -> Option<u64> {
        match self {
            LogError::Io { .. }
            | LogError::Write { .. }
            | LogError::Empty { .. }
            | LogError::Invalid { .. } => None,
            LogError::Csv { line, .. } => *line,
            LogError::HeaderOnly { line, .. }
            | LogError::MissingColumns { line, .. }
            | LogError::DuplicateColumn { line, .. }
            | LogError::EmptyColumnName { line, .. }
            | LogError::BadValue { line, .. }
            | LogError::NonIncreasingTime { line, .. }
            | LogError::Ragged { line, .. }
            | LogError::CommentAfterHeader { line, .. }
            | LogError::Encoding { line, .. } => Some(*line),
        }
    }

    /// The file path (or stream name) the error refers to.
    pub fn path(&self) -> &str {
        match self {
            LogError::Io { path, .. }
            | LogError::Write { path, .. }
            | LogError::Empty { path, .. }
            | LogError::HeaderOnly { path, .. }
            | LogError::MissingColumns { path, .. }
            | LogError::DuplicateColumn { path, .. }
            | LogError::EmptyColumnName { path, .. }
            | LogError::BadValue { path, .. }
            | LogError::NonIncreasingTime { path, .. }
            | LogError::Ragged { path, .. }
            | LogError::CommentAfterHeader { path, .. }
            | LogError::Encoding { path, .. }
            | LogError::Csv { path, .. }
            | LogError::Invalid { path, .. } => path,
        }
    }
}

/// Quote user-provided text for a message: truncated to [`MAX_SHOWN_CHARS`] characters,
/// with control characters and quotes escaped.
fn show(text: &str) -> String {
    format!("{:?}", truncate(text))
}

/// Truncate to [`MAX_SHOWN_CHARS`] characters, marking the cut with `...`.
fn truncate(text: &str) -> String {
    match text.char_indices().nth(MAX_SHOWN_CHARS) {
        Some((cut, _)) => format!("{}...", text.get(..cut).unwrap_or_default()),
        None => text.to_string(),
    }
}

fn show_list(names: &[String]) -> String {
    if names.is_empty() {
        return "(none)".to_string();
    }
    let mut out: Vec<String> = names
        .iter()
        .take(MAX_SHOWN_COLUMNS)
        .map(|n| show(n))
        .collect();
    if names.len() > MAX_SHOWN_COLUMNS {
        out.push(format!("... and {} more", names.len() - MAX_SHOWN_COLUMNS));
    }
    out.join(", ")
}

fn header_hint(found: &[String]) -> &'static str {
    let known = found
        .iter()
        .any(|f| REQUIRED_COLUMNS.contains(&f.as_str()) || OPTIONAL_COLUMNS.contains(&f.as_str()));
    if known {
        ""
    } else {
        "; note: the first line that is not a `#` comment or blank is taken as the header row"
    }
}

fn empty_note(lines: u64) -> String {
    if lines == 0 {
        " (the file has no content)".to_string()
    } else {
        format!(" (only {lines} comment or blank line(s))")
    }
}

fn describe_value(reason: ValueProblem, text: &str) -> String {
    match reason {
        ValueProblem::Empty => "empty field".to_string(),
        ValueProblem::NotANumber => format!("non-numeric value {}", show(text)),
        ValueProblem::NaN => format!("NaN value {} is not allowed", show(text)),
        ValueProblem::Infinite => format!("infinite value {} is not allowed", show(text)),
        ValueProblem::OutOfRange => format!(
            "value {} is out of range for a 64-bit float (overflows to infinity)",
            show(text)
        ),
    }
}

/// Parse one numeric field (already trimmed) into a finite `f64`.
fn parse_value(text: &str) -> Result<f64, ValueProblem> {
    if text.is_empty() {
        return Err(ValueProblem::Empty);
    }
    match text.parse::<f64>() {
        Err(_) => Err(ValueProblem::NotANumber),
        Ok(v) if v.is_nan() => Err(ValueProblem::NaN),
        Ok(v) if v.is_infinite() => {
            let mag = text.trim_start_matches(['+', '-']).to_ascii_lowercase();
            if mag == "inf" || mag == "infinity" {
                Err(ValueProblem::Infinite)
            } else {
                Err(ValueProblem::OutOfRange)
            }
        }
        Ok(v) => Ok(v),
    }
}

fn trim_ascii_ws(text: &str) -> &str {
    text.trim_matches([' ', '\t'])
}

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
    let name = path.display().to_string();
    let file = File::open(path).map_err(|source| LogError::Io {
        path: name.clone(),
        source,
    })?;
    read_bench_log_from(file, &name)
}

/// Read and validate a bench log from any reader (buffering is done internally);
/// `name` stands for the file path in error messages and in [`BenchLog::source`].
pub fn read_bench_log_from<R: Read>(reader: R, name: &str) -> Result<BenchLog, LogError> {
    let mut parser = Parser::open(reader, name)?;
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

/// Write `log` to `path` with the standard header (required columns, then the optional
/// columns that are present), preceded by its comments as `# ` lines. Floats are written
/// with `{}` (shortest representation that round-trips), so reading the file back
/// reproduces every value bit for bit. Extra column names are not written (their values
/// are not kept).
///
/// The write is atomic: a temporary file in the same directory is written, synced and
/// renamed over `path`, so readers never see a partial file. Logs that could not be read
/// back (no samples, columns of unequal length, non-finite values, non-increasing time)
/// are refused with [`LogError::Invalid`].
pub fn write_bench_log(path: &Path, log: &BenchLog) -> Result<(), LogError> {
    let name = path.display().to_string();
    validate_for_write(log).map_err(|reason| LogError::Invalid {
        path: name.clone(),
        reason,
    })?;
    let write_err = |source: io::Error| LogError::Write {
        path: name.clone(),
        source,
    };
    let dir = parent_dir(path);
    let mut prefix = std::ffi::OsString::from(".");
    prefix.push(path.file_name().unwrap_or_else(|| "benchlog".as_ref()));
    prefix.push(".");
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // Like a normal file creation: 0666 filtered by the umask (not tempfile's 0600).
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir).map_err(write_err)?;
    {
        let mut w = BufWriter::new(tmp.as_file_mut());
        write_contents(&mut w, log).map_err(write_err)?;
        w.flush().map_err(write_err)?;
    }
    tmp.as_file().sync_all().map_err(write_err)?;
    tmp.persist(path).map_err(|e| write_err(e.error))?;
    sync_dir(dir);
    Ok(())
}

/// Write `log` in the same format as [`write_bench_log`] to any writer (not atomic; the
/// writer is not buffered here, so pass a [`BufWriter`] for files or sockets). `name`
/// stands for the destination in error messages. The same validation applies.
pub fn write_bench_log_to<W: Write>(writer: W, name: &str, log: &BenchLog) -> Result<(), LogError> {
    validate_for_write(log).map_err(|reason| LogError::Invalid {
        path: name.to_string(),
        reason,
    })?;
    let mut writer = writer;
    write_contents(&mut writer, log)
        .and_then(|()| writer.flush())
        .map_err(|source| LogError::Write {
            path: name.to_string(),
            source,
        })
}

fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Best-effort fsync of a directory so a rename inside it is durable.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

fn validate_for_write(log: &BenchLog) -> Result<(), String> {
    let n = log.len();
    if n == 0 {
        return Err("the log has no samples; a bench log needs at least one sample row".into());
    }
    let mut columns: Vec<(&str, &[f64])> = vec![
        ("t_s", &log.t_s),
        ("theta_in_rad", &log.theta_in_rad),
        ("theta_out_rad", &log.theta_out_rad),
        ("load_nm", &log.load_nm),
    ];
    for (name, col) in [
        ("tension_upper_n", &log.tension_upper_n),
        ("tension_lower_n", &log.tension_lower_n),
        ("motor_current_a", &log.motor_current_a),
    ] {
        if let Some(c) = col {
            columns.push((name, c));
        }
    }
    for (name, col) in &columns {
        if col.len() != n {
            return Err(format!(
                "column {name} has {} values but t_s has {n}; all columns must have the same length",
                col.len()
            ));
        }
        if let Some((i, v)) = col.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(format!(
                "sample {i} (0-based), column {name}: value {v} is not finite; only finite numbers can be written"
            ));
        }
    }
    if let Some((i, w)) = log
        .t_s
        .windows(2)
        .enumerate()
        .find(|(_, w)| !matches!(w, [a, b] if b > a))
    {
        let (a, b) = match w {
            [a, b] => (*a, *b),
            _ => (f64::NAN, f64::NAN),
        };
        return Err(format!(
            "t_s[{}] = {b} s is not greater than t_s[{i}] = {a} s; t_s must be strictly increasing",
            i + 1
        ));
    }
    Ok(())
}

fn write_contents<W: Write>(w: &mut W, log: &BenchLog) -> io::Result<()> {
    for comment in &log.comments {
        for part in comment.replace("\r\n", "\n").split(['\n', '\r']) {
            if part.is_empty() {
                writeln!(w, "#")?;
            } else {
                writeln!(w, "# {part}")?;
            }
        }
    }
    let optional: Vec<(&str, &[f64])> = [
        ("tension_upper_n", &log.tension_upper_n),
        ("tension_lower_n", &log.tension_lower_n),
        ("motor_current_a", &log.motor_current_a),
    ]
    .into_iter()
    .filter_map(|(name, col)| col.as_deref().map(|c| (name, c)))
    .collect();
    write!(w, "{}", REQUIRED_COLUMNS.join(","))?;
    for (name, _) in &optional {
        write!(w, ",{name}")?;
    }
    writeln!(w)?;
    let required = log
        .t_s
        .iter()
        .zip(&log.theta_in_rad)
        .zip(&log.theta_out_rad)
        .zip(&log.load_nm);
    for (i, (((t, a), b), m)) in required.enumerate() {
        write!(w, "{t},{a},{b},{m}")?;
        for (_, col) in &optional {
            match col.get(i) {
                Some(v) => write!(w, ",{v}")?,
                None => write!(w, ",")?,
            }
        }
        writeln!(w)?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Streaming parser
// ---------------------------------------------------------------------------------------

/// Known columns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Col {
    T,
    ThetaIn,
    ThetaOut,
    Load,
    TensionUpper,
    TensionLower,
    Current,
}

impl Col {
    fn from_name(name: &str) -> Option<Col> {
        Some(match name {
            "t_s" => Col::T,
            "theta_in_rad" => Col::ThetaIn,
            "theta_out_rad" => Col::ThetaOut,
            "load_nm" => Col::Load,
            "tension_upper_n" => Col::TensionUpper,
            "tension_lower_n" => Col::TensionLower,
            "motor_current_a" => Col::Current,
            _ => return None,
        })
    }
}

/// Line filter between the byte source and the CSV parser.
///
/// It splits the input into physical lines (`\n`, `\r\n` or `\r`), strips a leading BOM,
/// collects `#` comment lines before the header, drops blank lines, and hands the rest to
/// the CSV parser with `\n` endings. Because the parser then sees no blank lines and one
/// terminator per line, its record line numbers map exactly to physical line numbers via
/// the (run-length) `offsets` table.
struct LineFilter<R: Read> {
    inner: BufReader<R>,
    /// Current line being handed out (with its `\n`).
    line: Vec<u8>,
    pos: usize,
    eof: bool,
    /// Physical lines consumed so far.
    physical: u64,
    /// Lines handed to the CSV parser so far (= its line numbering).
    emitted: u64,
    /// Header seen (comments are only recognised before it).
    in_body: bool,
    comments: Vec<String>,
    /// `(first csv line, physical - csv line)` runs, pruned as records are consumed.
    offsets: VecDeque<(u64, u64)>,
    /// Physical line of an invalid-UTF-8 comment (reported instead of the io error).
    bad_comment_line: Option<u64>,
}

impl<R: Read> LineFilter<R> {
    fn new(reader: R) -> Self {
        LineFilter {
            inner: BufReader::new(reader),
            line: Vec::new(),
            pos: 0,
            eof: false,
            physical: 0,
            emitted: 0,
            in_body: false,
            comments: Vec::new(),
            offsets: VecDeque::new(),
            bad_comment_line: None,
        }
    }

    /// Read one physical line (without terminator) into `self.line`.
    /// Returns `false` at end of input.
    fn read_physical_line(&mut self) -> io::Result<bool> {
        self.line.clear();
        self.pos = 0;
        let mut any = false;
        loop {
            let (used, ended_by_cr, done) = {
                let avail = match self.inner.fill_buf() {
                    Ok(b) => b,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(e) => return Err(e),
                };
                if avail.is_empty() {
                    return Ok(any);
                }
                any = true;
                match avail.iter().position(|&b| b == b'\n' || b == b'\r') {
                    Some(i) => {
                        self.line
                            .extend_from_slice(avail.get(..i).unwrap_or_default());
                        (i + 1, avail.get(i) == Some(&b'\r'), true)
                    }
                    None => {
                        self.line.extend_from_slice(avail);
                        (avail.len(), false, false)
                    }
                }
            };
            self.inner.consume(used);
            if ended_by_cr {
                // Swallow the `\n` of a `\r\n` pair.
                loop {
                    match self.inner.fill_buf() {
                        Ok(b) => {
                            if b.first() == Some(&b'\n') {
                                self.inner.consume(1);
                            }
                            break;
                        }
                        Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                        Err(e) => return Err(e),
                    }
                }
            }
            if done {
                return Ok(true);
            }
        }
    }

    /// Advance to the next line to hand out, or set `eof`.
    fn advance(&mut self) -> io::Result<()> {
        loop {
            if !self.read_physical_line()? {
                self.eof = true;
                return Ok(());
            }
            self.physical += 1;
            if self.physical == 1 && self.line.starts_with(UTF8_BOM) {
                self.line.drain(..UTF8_BOM.len());
            }
            if self.line.iter().all(|&b| b == b' ' || b == b'\t') {
                continue;
            }
            if !self.in_body {
                if let Some(rest) = self.line.strip_prefix(b"#") {
                    match std::str::from_utf8(rest) {
                        Ok(text) => {
                            let text = text.strip_prefix(' ').unwrap_or(text);
                            self.comments.push(text.to_string());
                            continue;
                        }
                        Err(_) => {
                            self.bad_comment_line = Some(self.physical);
                            self.eof = true;
                            return Err(io::Error::new(
                                io::ErrorKind::InvalidData,
                                "invalid UTF-8 in comment line",
                            ));
                        }
                    }
                }
                self.in_body = true;
            }
            self.emitted += 1;
            let offset = self.physical.saturating_sub(self.emitted);
            if self.offsets.back().map(|&(_, o)| o) != Some(offset) {
                self.offsets.push_back((self.emitted, offset));
            }
            self.line.push(b'\n');
            return Ok(());
        }
    }

    /// Physical line number of the CSV parser's line `csv_line`. Queries must be
    /// non-decreasing (older table entries are discarded).
    fn physical_line(&mut self, csv_line: u64) -> u64 {
        while self
            .offsets
            .get(1)
            .is_some_and(|&(start, _)| start <= csv_line)
        {
            self.offsets.pop_front();
        }
        let offset = match self.offsets.front() {
            Some(&(start, off)) if start <= csv_line => off,
            _ => 0,
        };
        csv_line.saturating_add(offset)
    }
}

impl<R: Read> Read for LineFilter<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        if out.is_empty() {
            return Ok(0);
        }
        while self.pos >= self.line.len() {
            if self.eof {
                return Ok(0);
            }
            self.advance()?;
            if self.eof {
                return Ok(0);
            }
        }
        let src = self.line.get(self.pos..).unwrap_or_default();
        let n = src.len().min(out.len());
        if let (Some(dst), Some(src)) = (out.get_mut(..n), src.get(..n)) {
            dst.copy_from_slice(src);
        }
        self.pos += n;
        Ok(n)
    }
}

/// Record-at-a-time validating parser shared by all read functions.
struct Parser<R: Read> {
    name: String,
    rdr: csv::Reader<LineFilter<R>>,
    record: csv::ByteRecord,
    /// Known column for each header field (None = extra column).
    slots: Vec<Option<Col>>,
    /// Time and line of the previous sample.
    prev: Option<(f64, u64)>,
    info: LogInfo,
}

impl<R: Read> Parser<R> {
    /// Read comments and the header row and resolve the columns.
    fn open(reader: R, name: &str) -> Result<Self, LogError> {
        let rdr = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .from_reader(LineFilter::new(reader));
        let mut parser = Parser {
            name: name.to_string(),
            rdr,
            record: csv::ByteRecord::new(),
            slots: Vec::new(),
            prev: None,
            info: LogInfo::default(),
        };
        let Some(line) = parser.read_record()? else {
            return Err(LogError::Empty {
                path: parser.name.clone(),
                lines: parser.rdr.get_ref().physical,
            });
        };
        parser.info.header_line = line;
        parser.info.comments = std::mem::take(&mut parser.rdr.get_mut().comments);

        let mut seen: HashMap<String, usize> = HashMap::new();
        for (i, field) in parser.record.iter().enumerate() {
            let Ok(text) = std::str::from_utf8(field) else {
                return Err(LogError::Encoding {
                    path: parser.name.clone(),
                    line,
                    column: None,
                });
            };
            let column = trim_ascii_ws(text);
            if column.is_empty() {
                return Err(LogError::EmptyColumnName {
                    path: parser.name.clone(),
                    line,
                    field: i + 1,
                });
            }
            if let Some(&first) = seen.get(column) {
                return Err(LogError::DuplicateColumn {
                    path: parser.name.clone(),
                    line,
                    column: column.to_string(),
                    first_field: first + 1,
                    second_field: i + 1,
                });
            }
            seen.insert(column.to_string(), i);
            let slot = Col::from_name(column);
            match slot {
                None => parser.info.extra_columns.push(column.to_string()),
                Some(Col::TensionUpper) => parser.info.has_tension_upper_n = true,
                Some(Col::TensionLower) => parser.info.has_tension_lower_n = true,
                Some(Col::Current) => parser.info.has_motor_current_a = true,
                Some(_) => {}
            }
            parser.slots.push(slot);
            parser.info.columns.push(column.to_string());
        }
        let missing: Vec<String> = REQUIRED_COLUMNS
            .iter()
            .filter(|c| !seen.contains_key(**c))
            .map(|c| c.to_string())
            .collect();
        if !missing.is_empty() {
            return Err(LogError::MissingColumns {
                path: parser.name.clone(),
                line,
                missing,
                found: std::mem::take(&mut parser.info.columns),
            });
        }
        Ok(parser)
    }

    /// Read the next CSV record into `self.record`; returns its physical line.
    fn read_record(&mut self) -> Result<Option<u64>, LogError> {
        match self.rdr.read_byte_record(&mut self.record) {
            Ok(false) => Ok(None),
            Ok(true) => {
                let csv_line = self.record.position().map_or(0, |p| p.line());
                Ok(Some(self.rdr.get_mut().physical_line(csv_line)))
            }
            Err(e) => Err(self.convert_csv_error(e)),
        }
    }

    fn convert_csv_error(&mut self, e: csv::Error) -> LogError {
        let path = self.name.clone();
        if let Some(line) = self.rdr.get_mut().bad_comment_line.take() {
            return LogError::Encoding {
                path,
                line,
                column: None,
            };
        }
        let csv_line = e.position().map(|p| p.line());
        let line = csv_line.map(|l| self.rdr.get_mut().physical_line(l));
        let message = e.to_string();
        match e.into_kind() {
            csv::ErrorKind::Io(source) => LogError::Io { path, source },
            _ => LogError::Csv {
                path,
                line,
                message,
            },
        }
    }

    /// Parse and validate the next data row.
    fn next_sample(&mut self) -> Result<Option<Sample>, LogError> {
        let Some(line) = self.read_record()? else {
            return Ok(None);
        };
        let record = &self.record;
        let first = record.get(0).unwrap_or_default();
        if first
            .iter()
            .find(|&&b| b != b' ' && b != b'\t')
            .is_some_and(|&b| b == b'#')
        {
            return Err(LogError::CommentAfterHeader {
                path: self.name.clone(),
                line,
            });
        }
        if record.len() != self.slots.len() {
            return Err(LogError::Ragged {
                path: self.name.clone(),
                line,
                expected: self.slots.len(),
                found: record.len(),
            });
        }
        let mut s = Sample {
            t_s: f64::NAN,
            theta_in_rad: f64::NAN,
            theta_out_rad: f64::NAN,
            load_nm: f64::NAN,
            tension_upper_n: None,
            tension_lower_n: None,
            motor_current_a: None,
        };
        for (i, (field, slot)) in record.iter().zip(&self.slots).enumerate() {
            let column = || self.info.columns.get(i).cloned().unwrap_or_default();
            let Ok(text) = std::str::from_utf8(field) else {
                return Err(LogError::Encoding {
                    path: self.name.clone(),
                    line,
                    column: Some(column()),
                });
            };
            let Some(col) = *slot else { continue };
            let text = trim_ascii_ws(text);
            let v = parse_value(text).map_err(|reason| LogError::BadValue {
                path: self.name.clone(),
                line,
                column: column(),
                text: truncate(text),
                reason,
            })?;
            match col {
                Col::T => s.t_s = v,
                Col::ThetaIn => s.theta_in_rad = v,
                Col::ThetaOut => s.theta_out_rad = v,
                Col::Load => s.load_nm = v,
                Col::TensionUpper => s.tension_upper_n = Some(v),
                Col::TensionLower => s.tension_lower_n = Some(v),
                Col::Current => s.motor_current_a = Some(v),
            }
        }
        if let Some((prev_s, prev_line)) = self.prev {
            // Values are finite here; `partial_cmp` would also reject a NaN.
            if s.t_s.partial_cmp(&prev_s) != Some(std::cmp::Ordering::Greater) {
                return Err(LogError::NonIncreasingTime {
                    path: self.name.clone(),
                    line,
                    prev_line,
                    prev_s,
                    t_s: s.t_s,
                });
            }
        }
        self.prev = Some((s.t_s, line));
        self.info.rows += 1;
        Ok(Some(s))
    }

    /// Finish after the last record: a log needs at least one sample.
    fn finish(self) -> Result<LogInfo, LogError> {
        if self.info.rows == 0 {
            return Err(LogError::HeaderOnly {
                path: self.name,
                line: self.info.header_line,
            });
        }
        Ok(self.info)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &[u8]) -> Result<BenchLog, LogError> {
        read_bench_log_from(text, "mem.csv")
    }

    fn err(text: &[u8]) -> String {
        match parse(text) {
            Ok(log) => panic!("expected an error, got {} samples", log.len()),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn parses_minimal_log() {
        let log =
            parse(b"t_s,theta_in_rad,theta_out_rad,load_nm\n0,1,2,3\n0.5,1.5,2.5,-3.5\n").unwrap();
        assert_eq!(log.len(), 2);
        assert_eq!(log.t_s, vec![0.0, 0.5]);
        assert_eq!(log.load_nm, vec![3.0, -3.5]);
        assert!(log.tension_upper_n.is_none());
        assert!(log.extra_columns.is_empty());
        assert_eq!(log.source, "mem.csv");
    }

    #[test]
    fn bom_crlf_comments_blank_lines_and_line_numbers() {
        let good: &[u8] = b"\xEF\xBB\xBF# rig: A\r\n#second\r\n\r\n\
            load_nm , t_s,x,theta_out_rad,theta_in_rad\r\n\
            1,0,a,2,3\r\n\r\n  \r\n\
            1,1,b,2,3\r\n";
        let ok = parse(good).unwrap();
        assert_eq!(
            ok.comments,
            vec!["rig: A".to_string(), "second".to_string()]
        );
        assert_eq!(ok.extra_columns, vec!["x".to_string()]);
        assert_eq!(ok.theta_in_rad, vec![3.0, 3.0]);
        assert_eq!(ok.t_s, vec![0.0, 1.0]);
        let bad = [good, b"1,1,c,2,3\r\n\r\n"].concat();
        let e = parse(&bad).unwrap_err();
        assert_eq!(e.line(), Some(9), "{e}");
        assert!(e.to_string().contains("line 9"), "{e}");
        assert!(e.to_string().contains("(line 8)"), "{e}");
    }

    #[test]
    fn cr_only_line_endings() {
        let log = parse(b"#c\rt_s,theta_in_rad,theta_out_rad,load_nm\r0,1,2,3\r1,1,2,3\r").unwrap();
        assert_eq!(log.len(), 2);
        let e = err(b"#c\rt_s,theta_in_rad,theta_out_rad,load_nm\r0,1,2,3\r\r1,1,2,\r");
        assert!(e.contains("line 5") && e.contains("load_nm"), "{e}");
    }

    #[test]
    fn error_messages() {
        let h = "t_s,theta_in_rad,theta_out_rad,load_nm\n";
        let e = err(format!("{h}0,1,2,3\n1,1,,3\n").as_bytes());
        assert!(
            e.contains("mem.csv: line 3, column \"theta_out_rad\": empty field"),
            "{e}"
        );
        let e = err(format!("{h}0,1,2,3\n1,1,abc,3\n").as_bytes());
        assert!(e.contains("non-numeric value \"abc\""), "{e}");
        let e = err(format!("{h}0,nan,2,3\n").as_bytes());
        assert!(e.contains("NaN value") && e.contains("line 2"), "{e}");
        let e = err(format!("{h}0,1,-inf,3\n").as_bytes());
        assert!(e.contains("infinite value \"-inf\""), "{e}");
        let e = err(format!("{h}0,1,1e999,3\n").as_bytes());
        assert!(e.contains("out of range"), "{e}");
        let e = err(format!("{h}0,1,2,3\n0,1,2,3\n").as_bytes());
        assert!(
            e.contains("line 3") && e.contains("equals") && e.contains("(line 2)"),
            "{e}"
        );
        let e = err(format!("{h}1,1,2,3\n0.5,1,2,3\n").as_bytes());
        assert!(e.contains("is earlier than"), "{e}");
        let e = err(format!("{h}0,1,2\n").as_bytes());
        assert!(
            e.contains("expected 4 fields") && e.contains("found 3"),
            "{e}"
        );
        let e = err(b"");
        assert!(
            e.contains("empty bench log") && e.contains("no content"),
            "{e}"
        );
        let e = err(b"# only\n\n");
        assert!(e.contains("only 2 comment or blank"), "{e}");
        let e = err(h.as_bytes());
        assert!(e.contains("line 1") && e.contains("no data rows"), "{e}");
        let e = err(b"t_s,theta_in_rad,load_nm,extra\n0,1,2,3\n");
        assert!(
            e.contains("theta_out_rad") && e.contains("\"extra\""),
            "{e}"
        );
        let e = err(b"t_s,theta_in_rad,theta_out_rad,load_nm,t_s\n0,1,2,3,4\n");
        assert!(
            e.contains("column \"t_s\" appears twice (fields 1 and 5)"),
            "{e}"
        );
        let e = err(b"t_s,theta_in_rad,theta_out_rad,load_nm,\n0,1,2,3,\n");
        assert!(e.contains("field 5 has an empty column name"), "{e}");
        let e = err(format!("{h}0,1,2,3\n# late comment\n").as_bytes());
        assert!(e.contains("line 3") && e.contains("comment"), "{e}");
        let e = err(&[h.as_bytes(), b"0,1,2,\xff\n"].concat());
        assert!(
            e.contains("line 2, column \"load_nm\": invalid UTF-8"),
            "{e}"
        );
        let e = err(b"# \xfe\xff\nt_s\n");
        assert!(e.contains("line 1: invalid UTF-8"), "{e}");
        let long = "x".repeat(500);
        let e = err(format!("{h}0,1,2,{long}\n").as_bytes());
        assert!(e.contains(&format!("\"{}...\"", "x".repeat(40))), "{e}");
        assert!(e.len() < 300, "{e}");
    }

    #[test]
    fn io_errors_name_the_path() {
        let e = read_bench_log(Path::new("/nonexistent/dir/log.csv")).unwrap_err();
        assert!(matches!(e, LogError::Io { .. }));
        assert!(e.to_string().contains("/nonexistent/dir/log.csv"), "{e}");

        struct Failing(usize);
        impl Read for Failing {
            fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
                let data = b"t_s,theta_in_rad,theta_out_rad,load_nm\n0,1,2,3\n";
                if self.0 >= data.len() {
                    return Err(io::Error::other("disk on fire"));
                }
                let n = buf.len().min(data.len() - self.0).min(7);
                buf[..n].copy_from_slice(&data[self.0..self.0 + n]);
                self.0 += n;
                Ok(n)
            }
        }
        let e = read_bench_log_from(Failing(0), "stream").unwrap_err();
        assert!(matches!(e, LogError::Io { .. }), "{e:?}");
        assert!(e.to_string().contains("stream") && e.to_string().contains("disk on fire"));
    }

    #[test]
    fn byte_at_a_time_reader_gives_same_result() {
        struct Trickle<'a>(&'a [u8]);
        impl Read for Trickle<'_> {
            fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
                match (self.0.split_first(), buf.first_mut()) {
                    (Some((b, rest)), Some(dst)) => {
                        *dst = *b;
                        self.0 = rest;
                        Ok(1)
                    }
                    _ => Ok(0),
                }
            }
        }
        let text = b"\xEF\xBB\xBF#a\r\n\r\nt_s,theta_in_rad,theta_out_rad,load_nm,motor_current_a\r\n0,1,2,3,4\r\n\r\n1,1,2,3,x\r\n";
        let a = read_bench_log_from(Trickle(text), "t")
            .unwrap_err()
            .to_string();
        let b = parse(text).unwrap_err().to_string().replace("mem.csv", "t");
        assert_eq!(a, b);
        assert!(a.contains("line 6"), "{a}");
    }

    #[test]
    fn visitor_streams_samples() {
        let text = b"#hello\nt_s,theta_in_rad,theta_out_rad,load_nm,tension_upper_n,junk\n0,1,2,3,4,z\n1,1,2,3,5,z\n";
        let mut sum = 0.0;
        let info = visit_bench_log(&text[..], "v", |s| sum += s.tension_upper_n.unwrap()).unwrap();
        assert_eq!(sum, 9.0);
        assert_eq!(info.rows, 2);
        assert_eq!(info.header_line, 2);
        assert_eq!(info.comments, vec!["hello".to_string()]);
        assert_eq!(info.extra_columns, vec!["junk".to_string()]);
        assert!(info.has_tension_upper_n && !info.has_tension_lower_n);
        assert_eq!(info.columns.len(), 6);
    }

    fn sample_log() -> BenchLog {
        let mut log = BenchLog {
            comments: vec!["first".into(), "".into(), " indented".into()],
            ..BenchLog::default()
        };
        let values = [
            0.1,
            -0.0,
            1e-300,
            5e-324,
            f64::MAX,
            f64::MIN_POSITIVE,
            std::f64::consts::PI,
            -1.0 / 3.0,
            123_456_789.123_456_79,
            f64::EPSILON,
        ];
        let mut t = -5.0;
        for (i, &v) in values.iter().enumerate() {
            t += 0.1 * (i as f64 + 1.0) / 7.0;
            log.push(&Sample {
                t_s: t,
                theta_in_rad: v,
                theta_out_rad: -v,
                load_nm: v * 0.5,
                tension_upper_n: Some(v / 3.0),
                tension_lower_n: None,
                motor_current_a: Some(i as f64),
            });
        }
        log
    }

    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    #[test]
    fn write_read_round_trip_is_bit_exact() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.csv");
        let log = sample_log();
        write_bench_log(&path, &log).unwrap();
        let back = read_bench_log(&path).unwrap();
        assert_eq!(bits(&back.t_s), bits(&log.t_s));
        assert_eq!(bits(&back.theta_in_rad), bits(&log.theta_in_rad));
        assert_eq!(bits(&back.theta_out_rad), bits(&log.theta_out_rad));
        assert_eq!(bits(&back.load_nm), bits(&log.load_nm));
        assert_eq!(
            bits(back.tension_upper_n.as_ref().unwrap()),
            bits(log.tension_upper_n.as_ref().unwrap())
        );
        assert!(back.tension_lower_n.is_none());
        assert_eq!(
            bits(back.motor_current_a.as_ref().unwrap()),
            bits(log.motor_current_a.as_ref().unwrap())
        );
        assert_eq!(back.comments, log.comments);
        // Only the final file is left behind.
        let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(names.len(), 1);
        // Overwrite works and is atomic (same path, new content).
        let short = log.slice(2..4);
        write_bench_log(&path, &short).unwrap();
        assert_eq!(read_bench_log(&path).unwrap().len(), 2);
    }

    #[test]
    fn multi_line_comments_are_split_and_writer_to_memory_works() {
        let mut log = sample_log().slice(0..2);
        log.comments = vec!["a\nb".into(), "c\r\nd".into()];
        let mut out = Vec::new();
        write_bench_log_to(&mut out, "mem", &log).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.starts_with("# a\n# b\n# c\n# d\nt_s,"), "{text}");
        let back = parse(text.as_bytes()).unwrap();
        assert_eq!(back.comments, vec!["a", "b", "c", "d"]);
        let e = write_bench_log_to(Vec::new(), "mem", &BenchLog::default()).unwrap_err();
        assert!(e.to_string().starts_with("mem: refusing to write"), "{e}");
    }

    #[test]
    fn write_refuses_unreadable_logs() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.csv");
        let mut log = sample_log();
        assert!(matches!(
            write_bench_log(&path, &BenchLog::default()),
            Err(LogError::Invalid { .. })
        ));
        log.load_nm[3] = f64::NAN;
        let e = write_bench_log(&path, &log).unwrap_err().to_string();
        assert!(e.contains("load_nm") && e.contains("not finite"), "{e}");
        let mut log = sample_log();
        log.t_s[5] = log.t_s[4];
        let e = write_bench_log(&path, &log).unwrap_err().to_string();
        assert!(e.contains("strictly increasing"), "{e}");
        let mut log = sample_log();
        log.theta_out_rad.pop();
        let e = write_bench_log(&path, &log).unwrap_err().to_string();
        assert!(e.contains("same length"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        let e = write_bench_log(Path::new("/nonexistent/dir/x.csv"), &sample_log()).unwrap_err();
        assert!(matches!(e, LogError::Write { .. }), "{e:?}");
    }

    #[test]
    fn slice_and_push_semantics() {
        let log = sample_log();
        assert_eq!(log.slice(3..100).len(), log.len() - 3);
        assert_eq!(log.slice(50..60).len(), 0);
        #[allow(clippy::reversed_empty_ranges)]
        let reversed = log.slice(5..2);
        assert!(reversed.is_empty());
        assert_eq!(log.slice(1..3).sample(0), log.sample(1));
        assert!(log.slice(1..3).tension_upper_n.is_some());
        assert_eq!(log.sample(log.len()), None);

        let mut log = BenchLog::default();
        let s = Sample {
            t_s: 0.0,
            theta_in_rad: 0.0,
            theta_out_rad: 0.0,
            load_nm: 0.0,
            tension_upper_n: None,
            tension_lower_n: None,
            motor_current_a: None,
        };
        log.push(&s);
        log.push(&Sample {
            t_s: 1.0,
            motor_current_a: Some(2.0),
            ..s
        });
        let current = log.motor_current_a.as_ref().unwrap();
        assert_eq!(current.len(), 2);
        assert!(current[0].is_nan());
        assert_eq!(current[1], 2.0);
    }

    #[test]
    fn reads_real_davinci_logs_if_present() {
        let dir = Path::new("/work/shared/real-data/davinci");
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for entry in entries.flatten() {
            let path = entry.path();
            if path.extension().is_some_and(|e| e == "csv") {
                let log = read_bench_log(&path).unwrap();
                assert!(log.len() > 10_000, "{}", path.display());
                assert_eq!(log.extra_columns, vec!["input_torque_nm".to_string()]);
                assert_eq!(log.comments.len(), 4);
                assert!(log.motor_current_a.is_some());
            }
        }
    }
}
