//! The atomic bench-log writer: floats that read back bit for bit, never a partial file.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use super::{BenchLog, LogError, REQUIRED_COLUMNS};

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
