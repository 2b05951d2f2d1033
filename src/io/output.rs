//! Results directories and files that are never half-written.
//!
//! A run writes its results into a hidden staging directory next to the final location
//! ([`StagedDir`]) and moves it into place with a single rename when it is done. If the run
//! fails (bad input, error, panic), dropping the [`StagedDir`] removes the staging
//! directory, so nothing is left behind. Single files are written with [`write_atomic`].

use std::ffi::OsString;
use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Name of the marker file written by [`StagedDir::commit_incomplete`].
pub const INCOMPLETE_FILE: &str = "INCOMPLETE.txt";

/// Errors from creating or committing results.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The final results directory already exists and `force` was not given.
    #[error(
        "refusing to overwrite existing results directory {}; pass --force to replace it or --out to choose another",
        path.display()
    )]
    Exists {
        /// The existing results path.
        path: PathBuf,
    },
    /// The results path is a regular file (or another non-directory): results are a
    /// directory, and a file there is no earlier results to overwrite.
    #[error(
        "refusing to write results to {}: it is a regular file, not a results directory; choose another --out (a directory name)",
        path.display()
    )]
    NotADirectory {
        /// The path.
        path: PathBuf,
    },
    /// `--force` was given but the path holds something this program did not write.
    #[error(
        "refusing to replace {} with --force: it is {what}; move it away or choose another --out",
        path.display()
    )]
    NotOurs {
        /// The path.
        path: PathBuf,
        /// What is there.
        what: String,
    },
    /// A single-file output cannot be written at its path.
    #[error(transparent)]
    FileTarget(#[from] super::staging::FileTargetError),
    /// A filesystem operation failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The path the failing operation was applied to.
        path: PathBuf,
        /// Underlying I/O error.
        source: io::Error,
    },
}

fn io_err(path: &Path) -> impl FnOnce(io::Error) -> OutputError + '_ {
    move |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Distinguishes staging / aside names created by this process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Directory that holds `path`; `.` for a bare file name.
fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// True if something (file, directory, or even a dangling symlink) exists at `path`.
fn exists(path: &Path) -> bool {
    fs::symlink_metadata(path).is_ok()
}

/// `<dir>/.<name>.<tag>-<pid>-<n>`
fn sibling_name(dir: &Path, name: &std::ffi::OsStr, tag: &str) -> PathBuf {
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut s = OsString::from(".");
    s.push(name);
    s.push(format!(".{tag}-{}-{n}", std::process::id()));
    dir.join(s)
}

/// Best-effort fsync of a directory so renames inside it are durable.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(d) = fs::File::open(dir) {
        let _ = d.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

fn remove_any(path: &Path) -> io::Result<()> {
    match fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => fs::remove_dir_all(path),
        Ok(_) => fs::remove_file(path),
        Err(e) => Err(e),
    }
}

/// A results directory under construction.
///
/// Files go into a hidden staging directory `<parent>/.<name>.partial-<pid>-<n>` created
/// next to the final path (same filesystem, so the final move is one atomic rename).
/// Call [`commit`](StagedDir::commit) (or [`commit_incomplete`](StagedDir::commit_incomplete))
/// to move it into place; dropping it without committing deletes the staging directory.
#[derive(Debug)]
pub struct StagedDir {
    staging: PathBuf,
    final_path: PathBuf,
    force: bool,
    committed: bool,
    stale_removed: Vec<PathBuf>,
}

/// Refuse `--force` on anything this program did not write.
fn check_ours(path: &Path) -> Result<(), OutputError> {
    match super::staging::foreign_content(path) {
        None => Ok(()),
        Some(what) => Err(OutputError::NotOurs {
            path: path.to_path_buf(),
            what,
        }),
    }
}

impl StagedDir {
    /// Start a results directory that will end up at `final_path`.
    ///
    /// Refuses with [`OutputError::Exists`] if `final_path` exists and `force` is false
    /// (checked again at commit). Missing parent directories are created.
    pub fn create(final_path: &Path, force: bool) -> Result<StagedDir, OutputError> {
        let Some(name) = final_path.file_name() else {
            return Err(OutputError::Io {
                path: final_path.to_path_buf(),
                source: io::Error::new(
                    io::ErrorKind::InvalidInput,
                    "results path must end in a directory name",
                ),
            });
        };
        if exists(final_path) {
            // With --force, `check_ours` says what the file is.
            if !force && !final_path.is_dir() {
                return Err(OutputError::NotADirectory {
                    path: final_path.to_path_buf(),
                });
            }
            if !force {
                return Err(OutputError::Exists {
                    path: final_path.to_path_buf(),
                });
            }
            check_ours(final_path)?;
        }
        let parent = parent_dir(final_path);
        fs::create_dir_all(parent).map_err(io_err(parent))?;
        let stale_removed = super::staging::remove_stale(parent);
        let mut attempts = 0;
        let staging = loop {
            let candidate = sibling_name(parent, name, "partial");
            match fs::create_dir(&candidate) {
                Ok(()) => break candidate,
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists && attempts < 1000 => {
                    attempts += 1;
                }
                Err(e) => return Err(io_err(&candidate)(e)),
            }
        };
        super::staging::register(&staging);
        let staged = StagedDir {
            staging,
            final_path: final_path.to_path_buf(),
            force,
            committed: false,
            stale_removed,
        };
        let marker = staged.staging.join(super::staging::MARKER_FILE);
        fs::write(&marker, super::staging::MARKER_TEXT).map_err(io_err(&marker))?;
        Ok(staged)
    }

    /// Staging directories of dead processes removed when this one was created.
    pub fn stale_removed(&self) -> &[PathBuf] {
        &self.stale_removed
    }

    /// The staging directory to write result files into.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Where the results will be after a successful commit.
    pub fn final_path(&self) -> &Path {
        &self.final_path
    }

    /// Move the staging directory to the final path and return the final path.
    ///
    /// Without `force`, an existing final path is refused with [`OutputError::Exists`]
    /// (and the staging directory is removed). With `force`, the old results are renamed
    /// aside, the new ones renamed in, then the old ones deleted (best effort); if the
    /// second rename fails the old results are put back.
    pub fn commit(mut self) -> Result<PathBuf, OutputError> {
        let parent = parent_dir(&self.final_path).to_path_buf();
        if exists(&self.final_path) {
            if !self.force {
                return Err(if self.final_path.is_dir() {
                    OutputError::Exists {
                        path: self.final_path.clone(),
                    }
                } else {
                    OutputError::NotADirectory {
                        path: self.final_path.clone(),
                    }
                });
            }
            check_ours(&self.final_path)?;
            let name = self.final_path.file_name().unwrap_or_default().to_owned();
            let aside = sibling_name(&parent, &name, "old");
            fs::rename(&self.final_path, &aside).map_err(io_err(&self.final_path))?;
            if let Err(e) = fs::rename(&self.staging, &self.final_path) {
                let _ = fs::rename(&aside, &self.final_path);
                return Err(io_err(&self.final_path)(e));
            }
            self.committed = true;
            super::staging::unregister(&self.staging);
            let _ = remove_any(&aside);
        } else {
            fs::rename(&self.staging, &self.final_path).map_err(io_err(&self.final_path))?;
            self.committed = true;
            super::staging::unregister(&self.staging);
        }
        sync_dir(&parent);
        Ok(self.final_path.clone())
    }

    /// Write [`INCOMPLETE_FILE`] (`INCOMPLETE.txt`) containing `reason` into the staging
    /// directory, then [`commit`](StagedDir::commit). Use when a run stops early but its
    /// partial results are still worth keeping, clearly marked.
    pub fn commit_incomplete(self, reason: &str) -> Result<PathBuf, OutputError> {
        let mut text = String::from("These results are INCOMPLETE.\nReason: ");
        text.push_str(reason);
        text.push('\n');
        write_atomic(&self.staging.join(INCOMPLETE_FILE), text.as_bytes())?;
        self.commit()
    }
}

impl Drop for StagedDir {
    /// Remove the staging directory unless it was committed.
    fn drop(&mut self) {
        if !self.committed {
            let _ = fs::remove_dir_all(&self.staging);
            super::staging::unregister(&self.staging);
        }
    }
}

/// Write a file atomically: the bytes go to a temporary file in the same directory
/// (`.<name>.<random>.tmp`), which is fsynced and then renamed over `path`. Readers see
/// either the old content or the new, never a mix; on error no temporary file remains.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let dir = parent_dir(path);
    let mut prefix = OsString::from(".");
    prefix.push(path.file_name().unwrap_or_else(|| "output".as_ref()));
    prefix.push(".");
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // Like a normal file creation: 0666 filtered by the umask (not tempfile's 0600).
        builder.permissions(fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir).map_err(io_err(path))?;
    tmp.write_all(bytes).map_err(io_err(path))?;
    tmp.as_file().sync_all().map_err(io_err(path))?;
    tmp.persist(path).map_err(|e| io_err(path)(e.error))?;
    sync_dir(dir);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn commit_moves_results_into_place() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("nested/run1");
        let staged = StagedDir::create(&out, false).unwrap();
        assert!(staged.path().starts_with(root.path().join("nested")));
        let staging_name = staged
            .path()
            .file_name()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        assert!(staging_name.starts_with(".run1.partial-"), "{staging_name}");
        assert_eq!(staged.final_path(), out);
        write_atomic(&staged.path().join("a.txt"), b"hello").unwrap();
        assert!(!out.exists());
        assert_eq!(staged.commit().unwrap(), out);
        assert_eq!(fs::read(out.join("a.txt")).unwrap(), b"hello");
        assert_eq!(entries(&root.path().join("nested")), vec!["run1"]);
    }

    #[test]
    fn a_regular_file_is_not_called_a_results_directory() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("good.csv");
        fs::write(&out, b"t_s,theta_in_rad\n").unwrap();
        let msg = StagedDir::create(&out, false).unwrap_err().to_string();
        assert!(
            msg.contains("regular file") && !msg.contains("existing results directory"),
            "{msg}"
        );
        assert_eq!(fs::read(&out).unwrap(), b"t_s,theta_in_rad\n");
    }

    #[test]
    fn refuses_existing_dir_without_force() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("run");
        fs::create_dir(&out).unwrap();
        fs::write(out.join("old.txt"), b"old").unwrap();
        let e = StagedDir::create(&out, false).unwrap_err();
        assert!(matches!(e, OutputError::Exists { .. }));
        let msg = e.to_string();
        assert!(
            msg.contains("refusing to overwrite existing results directory"),
            "{msg}"
        );
        assert!(
            msg.contains(&out.display().to_string()) && msg.contains("--force"),
            "{msg}"
        );
        assert!(msg.contains("--out"), "{msg}");
        assert_eq!(entries(root.path()), vec!["run"]);
        assert_eq!(fs::read(out.join("old.txt")).unwrap(), b"old");
    }

    #[test]
    fn refuses_at_commit_if_final_appeared_meanwhile() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("run");
        let staged = StagedDir::create(&out, false).unwrap();
        fs::write(staged.path().join("new.txt"), b"new").unwrap();
        fs::create_dir(&out).unwrap();
        fs::write(out.join("other.txt"), b"other").unwrap();
        assert!(matches!(staged.commit(), Err(OutputError::Exists { .. })));
        assert_eq!(entries(root.path()), vec!["run"]);
        assert_eq!(entries(&out), vec!["other.txt"]);
    }

    #[test]
    fn force_replaces_existing_dir() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("run");
        fs::create_dir(&out).unwrap();
        fs::write(out.join("old.txt"), b"old").unwrap();
        fs::write(out.join("summary.json"), b"{}").unwrap();
        let staged = StagedDir::create(&out, true).unwrap();
        fs::write(staged.path().join("new.txt"), b"new").unwrap();
        // Old results are untouched until commit.
        assert_eq!(fs::read(out.join("old.txt")).unwrap(), b"old");
        staged.commit().unwrap();
        assert_eq!(
            entries(&out),
            vec![super::super::staging::MARKER_FILE, "new.txt"]
        );
        assert_eq!(entries(root.path()), vec!["run"]);
    }

    #[test]
    fn force_refuses_a_file_or_a_foreign_directory() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("run");
        fs::write(&out, b"a file in the way").unwrap();
        let e = StagedDir::create(&out, true).unwrap_err();
        assert!(matches!(e, OutputError::NotOurs { .. }), "{e}");
        assert!(e.to_string().contains("regular file of 17 bytes"), "{e}");
        fs::remove_file(&out).unwrap();
        fs::create_dir(&out).unwrap();
        fs::write(out.join("notes.txt"), b"mine").unwrap();
        let e = StagedDir::create(&out, true).unwrap_err();
        assert!(e.to_string().contains("notes.txt"), "{e}");
        assert_eq!(entries(root.path()), vec!["run"]);
        assert_eq!(entries(&out), vec!["notes.txt"]);
    }

    #[test]
    fn stale_staging_of_a_dead_process_is_removed() {
        let root = tempfile::tempdir().unwrap();
        // Pid far above any pid_max: never a live process.
        let stale = root.path().join(".run.partial-4999999-0");
        fs::create_dir(&stale).unwrap();
        let staged = StagedDir::create(&root.path().join("run"), false).unwrap();
        assert_eq!(staged.stale_removed(), std::slice::from_ref(&stale));
        assert!(!stale.exists());
    }

    #[test]
    fn drop_without_commit_leaves_nothing() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("run");
        {
            let staged = StagedDir::create(&out, false).unwrap();
            fs::create_dir(staged.path().join("sub")).unwrap();
            fs::write(staged.path().join("sub/data.csv"), b"1,2\n").unwrap();
            assert!(staged.path().exists());
        }
        assert!(entries(root.path()).is_empty());
        // Also when a panic unwinds through the owner.
        let out2 = out.clone();
        let r = std::panic::catch_unwind(move || {
            let staged = StagedDir::create(&out2, false).unwrap();
            fs::write(staged.path().join("x"), b"x").unwrap();
            panic!("simulated failure");
        });
        assert!(r.is_err());
        assert!(entries(root.path()).is_empty());
    }

    #[test]
    fn commit_incomplete_leaves_marker() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("run");
        let staged = StagedDir::create(&out, false).unwrap();
        fs::write(staged.path().join("partial.csv"), b"t\n").unwrap();
        let path = staged
            .commit_incomplete("solver diverged at t = 3.2 s")
            .unwrap();
        assert_eq!(path, out);
        let text = fs::read_to_string(out.join(INCOMPLETE_FILE)).unwrap();
        assert!(text.contains("solver diverged at t = 3.2 s"), "{text}");
        assert_eq!(
            entries(&out),
            vec![
                super::super::staging::MARKER_FILE,
                INCOMPLETE_FILE,
                "partial.csv"
            ]
        );
        assert_eq!(entries(root.path()), vec!["run"]);
    }

    #[test]
    fn staging_names_are_unique() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("run");
        let a = StagedDir::create(&out, false).unwrap();
        let b = StagedDir::create(&out, false).unwrap();
        assert_ne!(a.path(), b.path());
        a.commit().unwrap();
        assert!(matches!(b.commit(), Err(OutputError::Exists { .. })));
        assert_eq!(entries(root.path()), vec!["run"]);
    }

    #[test]
    fn write_atomic_leaves_no_tmp_files() {
        let root = tempfile::tempdir().unwrap();
        let file = root.path().join("summary.json");
        write_atomic(&file, b"{\"a\":1}").unwrap();
        write_atomic(&file, b"{\"a\":2}").unwrap();
        assert_eq!(fs::read(&file).unwrap(), b"{\"a\":2}");
        assert_eq!(entries(root.path()), vec!["summary.json"]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = fs::metadata(&file).unwrap().permissions().mode();
            assert_ne!(mode & 0o600, 0, "owner can read/write");
        }
        let e = write_atomic(&root.path().join("missing/x.txt"), b"x").unwrap_err();
        assert!(matches!(e, OutputError::Io { .. }));
        assert!(e.to_string().contains("missing/x.txt"), "{e}");
        assert_eq!(entries(root.path()), vec!["summary.json"]);
    }
}
