//! Joining shard tables into the table a single run writes.

use std::path::{Path, PathBuf};

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
    /// The output exists.
    #[error("refusing to overwrite {0}; pass --force to replace it")]
    Exists(PathBuf),
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
            MergeError::Read { .. } | MergeError::Content { .. } => 3,
            MergeError::Exists(_) | MergeError::Write { .. } => 5,
        }
    }
}

/// Merge shard tables (files or directories holding `sweep.csv`) into `out`; returns the
/// number of cases. Rows are kept byte for byte and ordered by case index; shards must
/// share the header and must not repeat a case.
pub fn merge_files(shards: &[PathBuf], out: &Path, force: bool) -> Result<usize, MergeError> {
    if out.exists() && !force {
        return Err(MergeError::Exists(out.to_path_buf()));
    }
    let mut header: Option<(String, PathBuf)> = None;
    let mut rows: Vec<(usize, String, PathBuf, usize)> = Vec::new();
    for shard in shards {
        let path = if shard.is_dir() {
            shard.join("sweep.csv")
        } else {
            shard.clone()
        };
        let text = std::fs::read_to_string(&path).map_err(|source| MergeError::Read {
            path: path.clone(),
            source,
        })?;
        let mut lines = text.lines();
        let head = lines.next().ok_or_else(|| MergeError::Content {
            path: path.clone(),
            line: 1,
            message: "empty file: not a sweep table".into(),
        })?;
        if !head.starts_with("case,") {
            return Err(MergeError::Content {
                path: path.clone(),
                line: 1,
                message: "header does not start with `case,`: not a sweep table".into(),
            });
        }
        match &header {
            None => header = Some((head.to_string(), path.clone())),
            Some((h, first)) if h != head => {
                return Err(MergeError::Content {
                    path: path.clone(),
                    line: 1,
                    message: format!(
                        "header differs from {}'s: shards of different sweeps?",
                        first.display()
                    ),
                })
            }
            Some(_) => {}
        }
        for (i, line) in lines.enumerate() {
            if line.is_empty() {
                continue;
            }
            let index = line
                .split(',')
                .next()
                .and_then(|c| c.parse::<usize>().ok())
                .ok_or_else(|| MergeError::Content {
                    path: path.clone(),
                    line: i + 2,
                    message: "row does not start with a case number".into(),
                })?;
            rows.push((index, line.to_string(), path.clone(), i + 2));
        }
    }
    rows.sort_by_key(|r| r.0);
    for w in rows.windows(2) {
        if w[0].0 == w[1].0 {
            return Err(MergeError::Content {
                path: w[1].2.clone(),
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
    let Some((head, _)) = header else {
        return Err(MergeError::Content {
            path: out.to_path_buf(),
            line: 0,
            message: "no shard given".into(),
        });
    };
    let mut text = head;
    text.push('\n');
    for r in &rows {
        text.push_str(&r.1);
        text.push('\n');
    }
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|e| MergeError::Write {
            path: out.to_path_buf(),
            message: e.to_string(),
        })?;
    }
    crate::io::output::write_atomic(out, text.as_bytes()).map_err(|e| MergeError::Write {
        path: out.to_path_buf(),
        message: e.to_string(),
    })?;
    Ok(rows.len())
}
