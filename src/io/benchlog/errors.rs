//! What can be wrong with a bench log, and messages that name the file, line and column.

use std::io;

use super::{MAX_SHOWN_CHARS, MAX_SHOWN_COLUMNS, OPTIONAL_COLUMNS, REQUIRED_COLUMNS};

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
    /// A finite number beyond what the column can physically hold
    /// ([`super::MAX_MAGNITUDE`]: a load of 1e308 N m is a broken logger, and the replay
    /// would carry it to infinity).
    BeyondColumn,
    /// A time beyond [`super::MAX_TIME_S`] in magnitude.
    BeyondTime,
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
    /// Control bytes (NUL and the like) in the header: the file is not text at all.
    #[error(
        "{path}: line {line}: the header holds control bytes (such as NUL): this is not a text CSV file (a binary file?); a bench log is UTF-8 text whose header names the columns {}",
        REQUIRED_COLUMNS.join(",")
    )]
    NotText {
        /// File path or stream name.
        path: String,
        /// Line of the header row.
        line: u64,
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
    /// [`super::write_bench_log`] was given a log that could not be read back (no samples,
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
            | LogError::Encoding { line, .. }
            | LogError::NotText { line, .. } => Some(*line),
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
            | LogError::NotText { path, .. }
            | LogError::Csv { path, .. }
            | LogError::Invalid { path, .. } => path,
        }
    }
}

/// Quote user-provided text for a message: truncated to [`MAX_SHOWN_CHARS`] characters,
/// with control characters and quotes escaped.
pub(crate) fn show(text: &str) -> String {
    format!("{:?}", truncate(text))
}

/// Truncate to [`MAX_SHOWN_CHARS`] characters, marking the cut with `...`.
pub(super) fn truncate(text: &str) -> String {
    match text.char_indices().nth(MAX_SHOWN_CHARS) {
        Some((cut, _)) => format!("{}...", text.get(..cut).unwrap_or_default()),
        None => text.to_string(),
    }
}

pub(super) fn show_list(names: &[String]) -> String {
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

pub(super) fn header_hint(found: &[String]) -> &'static str {
    let known = found
        .iter()
        .any(|f| REQUIRED_COLUMNS.contains(&f.as_str()) || OPTIONAL_COLUMNS.contains(&f.as_str()));
    if known {
        ""
    } else {
        "; note: the first line that is not a `#` comment or blank is taken as the header row"
    }
}

pub(super) fn empty_note(lines: u64) -> String {
    if lines == 0 {
        " (the file has no content)".to_string()
    } else {
        format!(" (only {lines} comment or blank line(s))")
    }
}

pub(super) fn describe_value(reason: ValueProblem, text: &str) -> String {
    match reason {
        ValueProblem::Empty => "empty field".to_string(),
        ValueProblem::NotANumber => format!("non-numeric value {}", show(text)),
        ValueProblem::NaN => format!("NaN value {} is not allowed", show(text)),
        ValueProblem::Infinite => format!("infinite value {} is not allowed", show(text)),
        ValueProblem::OutOfRange => format!(
            "value {} is out of range for a 64-bit float (overflows to infinity)",
            show(text)
        ),
        ValueProblem::BeyondColumn => format!(
            "value {} is out of range: angles (rad) and loads (N m) are allowed up to {} in magnitude",
            show(text),
            crate::number(super::MAX_MAGNITUDE)
        ),
        ValueProblem::BeyondTime => format!(
            "time {} is out of range: times are allowed up to {} s in magnitude",
            show(text),
            crate::number(super::MAX_TIME_S)
        ),
    }
}
