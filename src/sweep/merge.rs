//! Joining shard tables into the table a single run writes.
//!
//! Every shard's `summary.json` records its index, the shard count, the case count and a
//! checksum of the sweep's case list ([`ShardManifest`]). A merge refuses a set with a
//! shard missing, given twice, cut short or taken from another sweep, naming it; a partial
//! merge (asked for explicitly) writes what is there and says so in its record
//! `<out>.merge.json` and on the terminal.

use std::path::{Path, PathBuf};

use crate::io::manifest::ShardManifest;
use crate::io::staging::{check_file_target, FileKind};

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
            MergeError::Read { .. } | MergeError::Content { .. } | MergeError::Incomplete(_) => 3,
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

/// One shard as read from disk.
struct ShardFile {
    table: PathBuf,
    manifest: Option<ShardManifest>,
    summary_complete: bool,
    rows: Vec<(usize, String, usize)>,
}

fn describe(path: &Path, m: &Option<ShardManifest>) -> String {
    match m {
        Some(m) => format!("shard {}/{} ({})", m.index, m.count, path.display()),
        None => path.display().to_string(),
    }
}

fn read_shard(shard: &Path) -> Result<(ShardFile, String), MergeError> {
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
    let summary_complete = summary
        .as_deref()
        .and_then(|s| serde_json::from_str::<serde_json::Value>(s).ok())
        .and_then(|v| v.get("complete").and_then(|c| c.as_bool()))
        .unwrap_or(false)
        && !dir.join(crate::io::output::INCOMPLETE_FILE).exists();
    let content = |line: usize, message: String| MergeError::Content {
        path: table.clone(),
        line,
        message,
    };
    let mut lines = text.lines();
    let head = lines
        .next()
        .ok_or_else(|| content(1, "empty file: not a sweep table".into()))?;
    if !head.starts_with("case,") {
        return Err(content(
            1,
            "header does not start with `case,`: not a sweep table".into(),
        ));
    }
    let fields = head.split(',').count();
    let mut rows = Vec::new();
    let n_lines = text.lines().count();
    for (i, line) in lines.enumerate() {
        if line.is_empty() {
            continue;
        }
        let index = line
            .split(',')
            .next()
            .and_then(|c| c.parse::<usize>().ok())
            .ok_or_else(|| content(i + 2, "row does not start with a case number".into()))?;
        // A row cut short (disk full, process killed mid-write) has fewer fields or no
        // line end.
        let cut = line.split(',').count() != fields || (i + 2 == n_lines && !text.ends_with('\n'));
        if cut {
            return Err(content(
                i + 2,
                format!(
                    "row of case {index} is cut short ({} of {fields} fields{}): the shard is truncated; rerun it",
                    line.split(',').count(),
                    if text.ends_with('\n') { "" } else { ", no line end" }
                ),
            ));
        }
        rows.push((index, line.to_string(), i + 2));
    }
    Ok((
        ShardFile {
            table,
            manifest,
            summary_complete,
            rows,
        },
        head.to_string(),
    ))
}

/// Merge shard tables (files or directories holding `sweep.csv` and the shard's
/// `summary.json`) into `out`. Rows are kept byte for byte and ordered by case index.
///
/// Refused, naming the shard: a shard without its record (unless `partial`), shards of
/// different sweeps (header, shard count or case-list checksum differ), a shard given
/// twice, a case in two shards, a shard whose rows are not the cases it owns, and, unless
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
        let (file, head) = read_shard(shard)?;
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
            if let Some((index, _, line)) = f.rows.iter().find(|row| !m.owns(row.0)) {
                return Err(MergeError::Content {
                    path: f.table.clone(),
                    line: *line,
                    message: format!(
                        "case {index} is not one of shard {}/{}'s cases: the table does not match its summary.json",
                        m.index, m.count
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
                .map(move |(i, l, n)| (*i, l.as_str(), f.table.as_path(), *n))
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
