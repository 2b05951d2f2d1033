//! The streaming reader: a line filter (BOM, line endings, comments, blank lines) in front
//! of the CSV parser, and the record parser that checks every value as it arrives.

use std::collections::{HashMap, VecDeque};
use std::io::{self, BufRead, BufReader, Read};

use super::errors::truncate;
use super::{LogError, ValueProblem};
use super::{LogInfo, Sample, REQUIRED_COLUMNS, UTF8_BOM};

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
pub(super) struct Parser<R: Read> {
    name: String,
    rdr: csv::Reader<LineFilter<R>>,
    record: csv::ByteRecord,
    /// Known column for each header field (None = extra column).
    slots: Vec<Option<Col>>,
    /// Time and line of the previous sample.
    prev: Option<(f64, u64)>,
    pub(super) info: LogInfo,
    /// Refuse angles and loads beyond [`super::MAX_MAGNITUDE`] (a log a drive is judged
    /// on); the plain reader takes any finite number.
    pub(super) bounded: bool,
}

impl<R: Read> Parser<R> {
    /// Read comments and the header row and resolve the columns.
    pub(super) fn open(reader: R, name: &str) -> Result<Self, LogError> {
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
            bounded: false,
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
            if text.chars().any(|c| c.is_control() && c != '\t') {
                return Err(LogError::NotText {
                    path: parser.name.clone(),
                    line,
                });
            }
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
    pub(super) fn next_sample(&mut self) -> Result<Option<Sample>, LogError> {
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
            let bounded = self.bounded && matches!(col, Col::ThetaIn | Col::ThetaOut | Col::Load);
            let v = parse_value(text)
                .and_then(|v| {
                    if bounded && v.abs() > super::MAX_MAGNITUDE {
                        Err(ValueProblem::BeyondColumn)
                    } else if matches!(col, Col::T) && v.abs() > super::MAX_TIME_S {
                        Err(ValueProblem::BeyondTime)
                    } else {
                        Ok(v)
                    }
                })
                .map_err(|reason| LogError::BadValue {
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
    pub(super) fn finish(self) -> Result<LogInfo, LogError> {
        if self.info.rows == 0 {
            return Err(LogError::HeaderOnly {
                path: self.name,
                line: self.info.header_line,
            });
        }
        Ok(self.info)
    }
}
