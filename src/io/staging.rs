//! What `--force` may replace, staging directories in flight, and stale ones left by
//! processes that died.
//!
//! A results directory this program wrote carries [`MARKER_FILE`] (older results are known
//! by their `summary.json` or `diagnosis.json`). `--force` replaces such a directory and
//! nothing else: a user's file or a directory of other content is refused with a
//! description of what is there. Single-file outputs follow the same rule with a content
//! check of their own (see [`check_file_target`]).

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// File written into every results directory so `--force` knows it may replace it.
pub const MARKER_FILE: &str = ".cable-servo-results";

/// Files that mark a results directory written before the marker existed.
const LEGACY_MARKS: [&str; 2] = ["summary.json", "diagnosis.json"];

/// Text of [`MARKER_FILE`].
pub const MARKER_TEXT: &str =
    "Results directory written by cable-servo; `--force` may replace it.\n";

/// `None` when `path` is absent or a results directory this program wrote; otherwise what
/// is there, in words (for the refusal message).
pub fn foreign_content(path: &Path) -> Option<String> {
    let meta = fs::symlink_metadata(path).ok()?;
    if meta.file_type().is_symlink() {
        return Some(format!(
            "a symbolic link (to {})",
            fs::read_link(path)
                .map(|t| t.display().to_string())
                .unwrap_or_else(|_| "an unreadable target".into())
        ));
    }
    if meta.is_file() {
        return Some(format!("a regular file of {} bytes", meta.len()));
    }
    if !meta.is_dir() {
        return Some("a special file (not a directory)".into());
    }
    if path.join(MARKER_FILE).is_file() || LEGACY_MARKS.iter().any(|m| path.join(m).is_file()) {
        return None;
    }
    let entries: Vec<String> = match fs::read_dir(path) {
        Ok(rd) => rd
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect(),
        Err(e) => return Some(format!("a directory that cannot be listed ({e})")),
    };
    if entries.is_empty() {
        // An empty directory holds nothing to lose.
        return None;
    }
    let mut shown: Vec<&str> = entries.iter().map(String::as_str).take(5).collect();
    shown.sort_unstable();
    Some(format!(
        "a directory of {} ({}{}) with no {MARKER_FILE} or summary.json, so not results written by cable-servo",
        match entries.len() {
            1 => "1 entry".to_string(),
            n => format!("{n} entries"),
        },
        shown.join(", "),
        if entries.len() > shown.len() { ", ..." } else { "" }
    ))
}

/// What a single-file output may replace under `--force`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// A scenario written by `diagnose --save-model` (first line `# Calibrated from`).
    SavedModel,
    /// A diagnosis JSON report (holds `"cause"`).
    DiagnosisJson,
    /// A merged sweep table (header starts `case,`).
    SweepTable,
    /// A synthetic bench log (first line a `#` comment naming `synth`).
    BenchLog,
}

impl FileKind {
    fn looks_ours(self, head: &str) -> bool {
        match self {
            FileKind::SavedModel => head.starts_with("# Calibrated from"),
            FileKind::DiagnosisJson => {
                head.trim_start().starts_with('{') && head.contains("\"cause\"")
            }
            FileKind::SweepTable => head.starts_with("case,"),
            FileKind::BenchLog => head.starts_with('#') || head.starts_with("t_s,"),
        }
    }

    fn describe(self) -> &'static str {
        match self {
            FileKind::SavedModel => "a model saved by diagnose --save-model",
            FileKind::DiagnosisJson => "a diagnosis JSON report",
            FileKind::SweepTable => "a sweep table",
            FileKind::BenchLog => "a bench log",
        }
    }
}

/// Why a single-file output may not be written at its path.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FileTargetError {
    /// A file is there and `--force` was not given.
    #[error("refusing to overwrite existing file {}; pass --force to replace it or choose another path", path.display())]
    Exists {
        /// The path.
        path: PathBuf,
    },
    /// Something is there that this program did not write.
    #[error("refusing to replace {} even with --force: it is {what}, not {expected}; move it away or choose another path", path.display())]
    Foreign {
        /// The path.
        path: PathBuf,
        /// What is there.
        what: String,
        /// What would be replaceable.
        expected: &'static str,
    },
}

/// Check that a single-file output may be written at `path`: nothing there, or (with
/// `force`) a regular file whose first 4 kB look like what this program writes there.
pub fn check_file_target(path: &Path, force: bool, kind: FileKind) -> Result<(), FileTargetError> {
    let Ok(meta) = fs::symlink_metadata(path) else {
        return Ok(());
    };
    let foreign = |what: String| FileTargetError::Foreign {
        path: path.to_path_buf(),
        what,
        expected: kind.describe(),
    };
    if meta.is_dir() {
        return Err(foreign("a directory".into()));
    }
    if !meta.is_file() {
        return Err(foreign(
            foreign_content(path).unwrap_or_else(|| "not a regular file".into()),
        ));
    }
    if !force {
        return Err(FileTargetError::Exists {
            path: path.to_path_buf(),
        });
    }
    let head = read_head(path, 4096);
    if meta.len() == 0 || kind.looks_ours(&head) {
        Ok(())
    } else {
        Err(foreign(format!(
            "a regular file of {} bytes that does not look like one this program writes",
            meta.len()
        )))
    }
}

fn read_head(path: &Path, n: usize) -> String {
    use std::io::Read;
    let mut buf = vec![0u8; n];
    let got = fs::File::open(path)
        .and_then(|mut f| f.read(&mut buf))
        .unwrap_or(0);
    String::from_utf8_lossy(&buf[..got]).into_owned()
}

/// Staging directories of this process not yet committed; removed if a signal ends the
/// process before they are.
static ACTIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Record a staging directory in flight.
pub fn register(path: &Path) {
    if let Ok(mut v) = ACTIVE.lock() {
        v.push(path.to_path_buf());
    }
}

/// Forget a staging directory (committed or removed).
pub fn unregister(path: &Path) {
    if let Ok(mut v) = ACTIVE.lock() {
        v.retain(|p| p != path);
    }
}

/// Remove every staging directory in flight; returns what was removed.
pub fn remove_active() -> Vec<PathBuf> {
    let paths = match ACTIVE.lock() {
        Ok(mut v) => std::mem::take(&mut *v),
        Err(_) => Vec::new(),
    };
    paths
        .into_iter()
        .filter(|p| fs::remove_dir_all(p).is_ok())
        .collect()
}

/// Process id embedded in a staging or set-aside name `.<name>.<tag>-<pid>-<n>`.
fn staging_pid(file_name: &str) -> Option<u32> {
    if !file_name.starts_with('.') {
        return None;
    }
    let (_, tail) = file_name
        .rsplit_once(".partial-")
        .or_else(|| file_name.rsplit_once(".old-"))?;
    let (pid, n) = tail.split_once('-')?;
    n.parse::<u64>().ok()?;
    pid.parse().ok()
}

/// Whether process `pid` is alive; unknown (non-Linux) counts as alive, so nothing of a
/// running process is ever removed.
fn alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    let proc_root = Path::new("/proc");
    if !proc_root.join("self").exists() {
        return true;
    }
    proc_root.join(pid.to_string()).exists()
}

/// Remove staging and set-aside directories in `dir` left by processes that no longer
/// run (killed before they could clean up); returns what was removed.
pub fn remove_stale(dir: &Path) -> Vec<PathBuf> {
    let Ok(rd) = fs::read_dir(dir) else {
        return Vec::new();
    };
    rd.filter_map(|e| e.ok())
        .filter(|e| e.file_type().is_ok_and(|t| t.is_dir()))
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            let pid = staging_pid(&name)?;
            (!alive(pid)).then(|| e.path())
        })
        .filter(|p| fs::remove_dir_all(p).is_ok())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn staging_names_carry_their_pid() {
        assert_eq!(staging_pid(".run.partial-1234-0"), Some(1234));
        assert_eq!(staging_pid(".my.run.old-77-3"), Some(77));
        assert_eq!(staging_pid("run.partial-1234-0"), None);
        assert_eq!(staging_pid(".run.partial-x-0"), None);
    }

    #[test]
    fn foreign_content_describes_what_is_there() {
        let root = tempfile::tempdir().unwrap();
        let file = root.path().join("f");
        fs::write(&file, b"hello").unwrap();
        assert!(foreign_content(&file)
            .unwrap()
            .contains("regular file of 5 bytes"));
        let dir = root.path().join("d");
        fs::create_dir(&dir).unwrap();
        assert_eq!(foreign_content(&dir), None, "empty directory");
        fs::write(dir.join("thesis.tex"), b"x").unwrap();
        let what = foreign_content(&dir).unwrap();
        assert!(what.contains("thesis.tex"), "{what}");
        fs::write(dir.join(MARKER_FILE), MARKER_TEXT).unwrap();
        assert_eq!(foreign_content(&dir), None);
        assert_eq!(foreign_content(&root.path().join("absent")), None);
    }

    #[test]
    fn single_files_are_replaced_only_when_ours() {
        let root = tempfile::tempdir().unwrap();
        let model = root.path().join("m.toml");
        check_file_target(&model, false, FileKind::SavedModel).unwrap();
        fs::write(&model, "# Calibrated from a.csv\n[drive]\n").unwrap();
        assert!(matches!(
            check_file_target(&model, false, FileKind::SavedModel),
            Err(FileTargetError::Exists { .. })
        ));
        check_file_target(&model, true, FileKind::SavedModel).unwrap();
        fs::write(&model, "my notes\n").unwrap();
        let e = check_file_target(&model, true, FileKind::SavedModel).unwrap_err();
        assert!(e.to_string().contains("does not look like"), "{e}");
        let e = check_file_target(root.path(), true, FileKind::DiagnosisJson).unwrap_err();
        assert!(e.to_string().contains("a directory"), "{e}");
    }
}
