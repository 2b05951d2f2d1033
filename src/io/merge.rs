//! Joining shard tables into the table a single run writes.
//!
//! Every shard's `summary.json` records its index, the shard count, the case count and a
//! checksum of the sweep's case list ([`ShardManifest`]). A merge refuses a set with a
//! shard missing, given twice, cut short or taken from another sweep, naming it; a partial
//! merge (asked for explicitly) writes what is there and says so in its record
//! `<out>.merge.json` and on the terminal.
//!
//! Every cell is checked against what its column may hold ([`Layout`]) before anything is
//! written: a hand-edited or damaged shard is refused naming its file, line, column, the
//! value and what is allowed, and leaves no merged table behind.

use std::path::{Path, PathBuf};

use crate::io::manifest::ShardManifest;
use crate::io::staging::{check_file_target, FileKind};
use crate::io::sweep_columns::{Content, Layout};

/// Merging failed.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    /// A shard file cannot be read.
    #[error("cannot read shard {path}: {source}")]
    Read {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// Shards do not belong together or are damaged.
    #[error("{path}:{line}: {message}")]
    Content {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A cell holds what its column may not.
    #[error("{path}:{line}: column {column} ({name}) holds {value}; {expected}")]
    Cell {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// Column name.
        name: String,
        /// The cell as found, quoted, or "a blank cell".
        value: String,
        /// What the cell should hold (`allowed: ...`, or the rule it breaks).
        expected: String,
    },
    /// The set of shards is not the whole sweep.
    #[error("{0}")]
    Incomplete(String),
    /// The output exists.
    #[error(transparent)]
    Exists(#[from] crate::io::staging::FileTargetError),
    /// The output cannot be written.
    #[error("cannot write {path}: {message}")]
    Write {
        /// File.
        path: PathBuf,
        /// Cause.
        message: String,
    },
}

impl MergeError {
    /// Process exit code (3 bad input, 5 output problem).
    pub fn exit_code(&self) -> u8 {
        match self {
            MergeError::Read { .. }
            | MergeError::Content { .. }
            | MergeError::Cell { .. }
            | MergeError::Incomplete(_) => 3,
            MergeError::Exists(_) | MergeError::Write { .. } => 5,
        }
    }
}

/// What a merge produced.
#[derive(Clone, Debug, PartialEq)]
pub struct MergeReport {
    /// Rows written.
    pub rows: usize,
    /// Cases in the whole sweep (when the shards record it).
    pub cases_total: Option<usize>,
    /// What is missing when the merge is partial (empty when complete).
    pub gaps: Vec<String>,
}

impl MergeReport {
    /// True when every case of the sweep is in the merged table.
    pub fn complete(&self) -> bool {
        self.gaps.is_empty()
    }
}

/// One row of a shard: its case, its text as written (kept byte for byte), its line and
/// its cells.
struct ShardRow {
    index: usize,
    text: String,
    line: usize,
    cells: Vec<String>,
}

/// One shard as read from disk.
struct ShardFile {
    table: PathBuf,
    manifest: Option<ShardManifest>,
    summary_complete: bool,
    /// Per parameter column, whether the sweep varies a number there, as its
    /// `summary.json` records the sweep; `None` without a readable record.
    numeric_parameters: Option<Vec<bool>>,
    header: Vec<String>,
    rows: Vec<ShardRow>,
}

fn describe(path: &Path, m: &Option<ShardManifest>) -> String {
    match m {
        Some(m) => format!("shard {}/{} ({})", m.index, m.count, path.display()),
        None => path.display().to_string(),
    }
}

/// Which swept parameters are numbers, from a sweep's `summary.json`: a drawn parameter
/// always is, a listed one when every listed value is.
fn numeric_parameters(summary: &serde_json::Value) -> Option<Vec<bool>> {
    let parameters = summary.get("scenario")?.get("sweep")?.get("parameters")?;
    parameters
        .as_array()?
        .iter()
        .map(|p| {
            if p.get("dist").is_some_and(|d| !d.is_null()) {
                return Some(true);
            }
            let values = p.get("values")?.as_array()?;
            Some(!values.is_empty() && values.iter().all(serde_json::Value::is_number))
        })
        .collect()
}

/// A cell for a message, quoted and cut as a bench log's cells are.
fn shown_cell(cell: &str) -> String {
    if cell.is_empty() {
        return "a blank cell".into();
    }
    super::benchlog::show(cell)
}

fn read_shard(shard: &Path) -> Result<ShardFile, MergeError> {
    let table = if shard.is_dir() {
        shard.join("sweep.csv")
    } else {
        shard.to_path_buf()
    };
    let text = std::fs::read_to_string(&table).map_err(|source| MergeError::Read {
        path: table.clone(),
        source,
    })?;
    let dir = table.parent().unwrap_or(Path::new("."));
    let summary = std::fs::read_to_string(dir.join("summary.json")).ok();
    let manifest = summary.as_deref().and_then(ShardManifest::from_summary);
    let summary_json = summary
        .as_deref()
        .and_then(|s| serde_json::from_str::<serde_json::Value>(s).ok());
    let summary_complete = summary_json
        .as_ref()
        .and_then(|v| v.get("complete").and_then(|c| c.as_bool()))
        .unwrap_or(false)
        && !dir.join(crate::io::output::INCOMPLETE_FILE).exists();
    let numeric_parameters = summary_json.as_ref().and_then(numeric_parameters);
    let content = |line: usize, message: String| MergeError::Content {
        path: table.clone(),
        line,
        message,
    };
    // Reasons may hold commas and are quoted then: cells are read as CSV, while each row
    // keeps its text as written.
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(text.as_bytes());
    let mut records = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| {
            content(
                e.position().map_or(0, |p| p.line() as usize),
                format!("not readable as CSV: {e}"),
            )
        })?;
        let start = record.position().map_or(0, |p| p.byte() as usize);
        let line = record.position().map_or(0, |p| p.line() as usize);
        records.push((start, line, record));
    }
    let Some((_, _, head)) = records.first() else {
        return Err(content(1, "empty file: not a sweep table".into()));
    };
    if head.get(0) != Some("case") {
        return Err(content(
            1,
            "header does not start with `case,`: not a sweep table".into(),
        ));
    }
    let header: Vec<String> = head.iter().map(str::to_string).collect();
    let fields = header.len();
    let ends: Vec<usize> = records
        .iter()
        .skip(1)
        .map(|r| r.0)
        .chain(std::iter::once(text.len()))
        .collect();
    let last = records.len() - 1;
    let mut rows = Vec::new();
    for (k, ((start, line, record), end)) in records.iter().zip(&ends).enumerate().skip(1) {
        let row_text = text
            .get(*start..*end)
            .unwrap_or_default()
            .trim_end_matches(['\r', '\n']);
        let first = record.get(0).unwrap_or_default();
        let index = first.parse::<usize>().map_err(|_| MergeError::Cell {
            path: table.clone(),
            line: *line,
            column: 1,
            name: "case".into(),
            value: shown_cell(first),
            expected: format!("allowed: {}", Content::Case.allowed()),
        })?;
        // A row cut short (disk full, process killed mid-write) has fewer fields or no
        // line end.
        let unended = k == last && !text.ends_with('\n');
        if record.len() != fields || unended {
            return Err(content(
                *line,
                format!(
                    "row of case {index} is cut short ({} of {fields} fields{}): the shard is truncated; rerun it",
                    record.len(),
                    if unended { ", no line end" } else { "" }
                ),
            ));
        }
        rows.push(ShardRow {
            index,
            text: row_text.to_string(),
            line: *line,
            cells: record.iter().map(str::to_string).collect(),
        });
    }
    Ok(ShardFile {
        table,
        manifest,
        summary_complete,
        numeric_parameters,
        header,
        rows,
    })
}

/// Check every cell of every shard against its column. Which parameter columns hold
/// numbers comes from a shard's record of its sweep; without one, from the cells
/// themselves: a parameter's values are all numbers or all names, so a column mostly of
/// numbers is a numeric one.
fn check_cells(files: &[ShardFile]) -> Result<(), MergeError> {
    let Some(first) = files.first() else {
        return Ok(());
    };
    let mut layout = Layout::of_header(&first.header).map_err(|message| MergeError::Content {
        path: first.table.clone(),
        line: 1,
        message,
    })?;
    let recorded = files
        .iter()
        .filter_map(|f| f.numeric_parameters.clone())
        .find(|kinds| kinds.len() == layout.parameters);
    let numeric = recorded.unwrap_or_else(|| {
        (1..=layout.parameters)
            .map(|j| {
                let (numbers, names) =
                    files
                        .iter()
                        .flat_map(|f| &f.rows)
                        .fold((0usize, 0usize), |(n, t), r| {
                            let number = r.cells[j].parse::<f64>().is_ok();
                            (n + usize::from(number), t + usize::from(!number))
                        });
                numbers >= names
            })
            .collect()
    });
    layout.set_parameter_kinds(&numeric);
    for f in files {
        for row in &f.rows {
            let cells: Vec<&str> = row.cells.iter().map(String::as_str).collect();
            if let Some((j, expected)) = layout.check_row(&cells) {
                return Err(MergeError::Cell {
                    path: f.table.clone(),
                    line: row.line,
                    column: j + 1,
                    name: layout.names[j].clone(),
                    value: shown_cell(&row.cells[j]),
                    expected,
                });
            }
        }
    }
    Ok(())
}

/// Merge shard tables (files or directories holding `sweep.csv` and the shard's
/// `summary.json`) into `out`. Rows are kept byte for byte and ordered by case index.
///
/// Refused, naming the shard: a shard without its record (unless `partial`), shards of
/// different sweeps (header, shard count or case-list checksum differ), a shard given
/// twice, a case in two shards, a shard whose rows are not the cases it owns, a cell its
/// column may not hold (with file, line, column, value and what is allowed), and, unless
/// `partial`, a missing or truncated shard. With `partial`, the table holds what the
/// shards have and `<out>.merge.json` says what is missing.
pub fn merge_files(
    shards: &[PathBuf],
    out: &Path,
    force: bool,
    partial: bool,
) -> Result<MergeReport, MergeError> {
    check_file_target(out, force, FileKind::SweepTable)?;
    let mut header: Option<(String, PathBuf)> = None;
    let mut files: Vec<ShardFile> = Vec::new();
    for shard in shards {
        let file = read_shard(shard)?;
        let head = file.header.join(",");
        match &header {
            None => header = Some((head, file.table.clone())),
            Some((h, first)) if *h != head => {
                return Err(MergeError::Content {
                    path: file.table.clone(),
                    line: 1,
                    message: format!(
                        "header differs from {}'s: a shard of a different sweep",
                        first.display()
                    ),
                })
            }
            Some(_) => {}
        }
        files.push(file);
    }
    let Some((head, _)) = header else {
        return Err(MergeError::Incomplete("no shard given".into()));
    };
    check_cells(&files)?;
    let mut gaps = Vec::new();
    // The sweep the shards claim to belong to: the first shard with a record.
    let reference = files
        .iter()
        .find_map(|f| f.manifest.clone().map(|m| (m, f)));
    if let Some((r, first)) = &reference {
        let mut seen: Vec<Option<&Path>> = vec![None; r.count];
        for f in &files {
            let Some(m) = &f.manifest else {
                let msg = format!(
                    "{} has no shard record (summary.json with shard index, count and case-list checksum beside it), so it cannot be checked against shard {}/{} ({})",
                    f.table.display(),
                    r.index,
                    r.count,
                    first.table.display()
                );
                if partial {
                    gaps.push(format!("unchecked: {msg}"));
                    continue;
                }
                return Err(MergeError::Incomplete(format!(
                    "{msg}; pass --partial to merge it unchecked"
                )));
            };
            if m.count != r.count
                || m.cases_total != r.cases_total
                || m.case_list_checksum != r.case_list_checksum
            {
                return Err(MergeError::Incomplete(format!(
                    "{} belongs to another sweep than {}: {} shards of {} cases, case-list checksum {}, against {} shards of {} cases, checksum {}",
                    describe(&f.table, &f.manifest),
                    describe(&first.table, &Some(r.clone())),
                    m.count,
                    m.cases_total,
                    m.case_list_checksum,
                    r.count,
                    r.cases_total,
                    r.case_list_checksum
                )));
            }
            if m.index == 0 || m.index > r.count {
                return Err(MergeError::Incomplete(format!(
                    "{}: shard index {} outside 1..={}",
                    f.table.display(),
                    m.index,
                    r.count
                )));
            }
            if let Some(other) = seen[m.index - 1] {
                return Err(MergeError::Incomplete(format!(
                    "shard {}/{} given twice: {} and {}",
                    m.index,
                    m.count,
                    other.display(),
                    f.table.display()
                )));
            }
            seen[m.index - 1] = Some(&f.table);
            if let Some(row) = f.rows.iter().find(|row| row.index >= m.cases_total) {
                return Err(MergeError::Content {
                    path: f.table.clone(),
                    line: row.line,
                    message: format!(
                        "case {} is beyond the sweep's {} cases (0 to {}): the table does not match its summary.json",
                        row.index,
                        m.cases_total,
                        m.cases_total.saturating_sub(1)
                    ),
                });
            }
            if let Some(row) = f.rows.iter().find(|row| !m.owns(row.index)) {
                return Err(MergeError::Content {
                    path: f.table.clone(),
                    line: row.line,
                    message: format!(
                        "case {} is not one of shard {}/{}'s cases: the table does not match its summary.json",
                        row.index, m.index, m.count
                    ),
                });
            }
            if f.rows.len() != m.cases_in_shard || !f.summary_complete {
                let msg = format!(
                    "{} is truncated: {} of its {} cases{}",
                    describe(&f.table, &f.manifest),
                    f.rows.len(),
                    m.cases_in_shard,
                    if f.summary_complete {
                        ""
                    } else {
                        " (its summary.json or INCOMPLETE.txt marks it incomplete)"
                    }
                );
                if !partial {
                    return Err(MergeError::Incomplete(format!(
                        "{msg}; rerun the shard, or pass --partial to merge what is there"
                    )));
                }
                gaps.push(msg);
            }
        }
        let missing: Vec<String> = seen
            .iter()
            .enumerate()
            .filter(|(_, s)| s.is_none())
            .map(|(i, _)| format!("{}/{}", i + 1, r.count))
            .collect();
        if !missing.is_empty() {
            let cases: usize = (0..r.cases_total)
                .filter(|c| seen[c % r.count].is_none())
                .count();
            let msg = format!(
                "shard{} {} missing ({cases} of {} cases)",
                if missing.len() > 1 { "s" } else { "" },
                missing.join(", "),
                r.cases_total
            );
            if !partial {
                return Err(MergeError::Incomplete(format!(
                    "{msg}; give every shard's results, or pass --partial to merge what is there"
                )));
            }
            gaps.push(msg);
        }
    } else if !partial {
        return Err(MergeError::Incomplete(format!(
            "no shard has its record (summary.json with shard index, count and case-list checksum beside its sweep.csv, e.g. {}): completeness cannot be checked; pass --partial to merge anyway",
            files[0].table.display()
        )));
    } else {
        gaps.push("unchecked: no shard has its record; completeness unknown".into());
    }
    let mut rows: Vec<(usize, &str, &Path, usize)> = files
        .iter()
        .flat_map(|f| {
            f.rows
                .iter()
                .map(move |r| (r.index, r.text.as_str(), f.table.as_path(), r.line))
        })
        .collect();
    rows.sort_by_key(|r| r.0);
    for w in rows.windows(2) {
        if w[0].0 == w[1].0 {
            return Err(MergeError::Content {
                path: w[1].2.to_path_buf(),
                line: w[1].3,
                message: format!(
                    "case {} also appears in {} line {}: a shard given twice?",
                    w[1].0,
                    w[0].2.display(),
                    w[0].3
                ),
            });
        }
    }
    let mut text = head;
    text.push('\n');
    for r in &rows {
        text.push_str(r.1);
        text.push('\n');
    }
    let write_err = |e: String| MergeError::Write {
        path: out.to_path_buf(),
        message: e,
    };
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| write_err(e.to_string()))?;
    }
    let report = MergeReport {
        rows: rows.len(),
        cases_total: reference.as_ref().map(|r| r.0.cases_total),
        gaps,
    };
    let record = serde_json::json!({
        "program_version": env!("CARGO_PKG_VERSION"),
        "complete": report.complete(),
        "partial": !report.complete(),
        "rows": report.rows,
        "cases_total": report.cases_total,
        "case_list_checksum": reference.as_ref().map(|r| r.0.case_list_checksum.clone()),
        "shards": files.iter().map(|f| f.table.display().to_string()).collect::<Vec<_>>(),
        "missing": report.gaps,
    });
    let mut record_path = out.as_os_str().to_owned();
    record_path.push(".merge.json");
    let record_text = serde_json::to_string_pretty(&record).unwrap_or_default() + "\n";
    crate::io::output::write_atomic(Path::new(&record_path), record_text.as_bytes())
        .map_err(|e| write_err(e.to_string()))?;
    crate::io::output::write_atomic(out, text.as_bytes()).map_err(|e| write_err(e.to_string()))?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::sweep_columns::BACKLASH;

    /// A shard table without its record, as a hand-made or copied file would be.
    fn bare_shard(dir: &Path, name: &str, parameters: &str, rows: &[&str]) -> PathBuf {
        let path = dir.join(name);
        let mut text = format!("case,{parameters},{}\n", BACKLASH.join(","));
        for row in rows {
            text.push_str(row);
            text.push('\n');
        }
        std::fs::write(&path, text).unwrap();
        path
    }

    const SLIPPED: &str = "0,10,memory,,,,gross_slip,false,,gross_slip,\"gross slip of the upper half, on the pulley\"";
    const HELD: &str = "1,100,memoryless,0.2,0.4,0.4,ok,false,103.5,ok,";

    #[test]
    fn rows_without_a_record_merge_as_written_with_quoted_reasons() {
        let tmp = tempfile::tempdir().unwrap();
        let a = bare_shard(tmp.path(), "a.csv", "preload_n,model", &[SLIPPED]);
        let b = bare_shard(tmp.path(), "b.csv", "preload_n,model", &[HELD]);
        let out = tmp.path().join("m.csv");
        let report = merge_files(&[b, a], &out, false, true).unwrap();
        assert_eq!(report.rows, 2);
        let merged = std::fs::read_to_string(&out).unwrap();
        let lines: Vec<&str> = merged.lines().collect();
        assert_eq!(lines[1..], [SLIPPED, HELD]);
    }

    /// Without a record, a parameter column of numbers is told from one of names by its
    /// cells: the odd one out is refused, wherever it stands.
    #[test]
    fn a_name_among_swept_numbers_is_refused_without_a_record() {
        let tmp = tempfile::tempdir().unwrap();
        let a = bare_shard(
            tmp.path(),
            "a.csv",
            "preload_n,model",
            &[&SLIPPED.replacen(",10,", ",ten,", 1)],
        );
        let b = bare_shard(
            tmp.path(),
            "b.csv",
            "preload_n,model",
            &[HELD, &HELD.replacen("1,", "2,", 1)],
        );
        let out = tmp.path().join("m.csv");
        let e = merge_files(&[b, a.clone()], &out, false, true).unwrap_err();
        assert_eq!(e.exit_code(), 3);
        let text = e.to_string();
        assert_eq!(
            text,
            format!(
                "{}:2: column 2 (preload_n) holds \"ten\"; allowed: a finite number (the case's value of the swept parameter)",
                a.display()
            )
        );
        assert!(!out.exists());
        assert!(!tmp.path().join("m.csv.merge.json").exists());
    }

    #[test]
    fn a_header_of_no_known_sweep_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("a.csv");
        std::fs::write(&path, "case,preload_n,initial_mrad\n0,10,1.5\n").unwrap();
        let e = merge_files(&[path], &tmp.path().join("m.csv"), false, true).unwrap_err();
        assert_eq!(e.exit_code(), 3);
        let text = e.to_string();
        assert!(
            text.contains(":1: the columns after the parameters"),
            "{text}"
        );
    }

    #[test]
    fn a_long_or_unprintable_cell_is_shown_cut_and_escaped() {
        assert_eq!(shown_cell(""), "a blank cell");
        // Control characters escaped, never written raw into a message.
        assert_eq!(shown_cell("a\tb"), "\"a\\tb\"");
        let long = "x".repeat(200);
        assert_eq!(shown_cell(&long), format!("\"{}...\"", "x".repeat(40)));
    }
}
