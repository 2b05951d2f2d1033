//! Bench-log records as `data-format.md` defines them (minimal reader and writer used by the
//! diagnosis until the shared reader is available).

use std::ops::Range;
use std::path::Path;

/// One row of a bench log.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// Time, s.
    pub t_s: f64,
    /// Input angle, rad.
    pub theta_in_rad: f64,
    /// Output angle, rad.
    pub theta_out_rad: f64,
    /// Load torque on the output shaft, N m.
    pub load_nm: f64,
    /// Upper span tension, N.
    pub tension_upper_n: Option<f64>,
    /// Lower span tension, N.
    pub tension_lower_n: Option<f64>,
    /// Motor current, A.
    pub motor_current_a: Option<f64>,
}

/// A bench log held column-wise.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BenchLog {
    /// Sample times, s (strictly increasing).
    pub t_s: Vec<f64>,
    /// Input angle, rad.
    pub theta_in_rad: Vec<f64>,
    /// Output angle, rad.
    pub theta_out_rad: Vec<f64>,
    /// Load torque on the output shaft, N m (a brake resisting +motion reads negative).
    pub load_nm: Vec<f64>,
    /// Upper span tension, N.
    pub tension_upper_n: Option<Vec<f64>>,
    /// Lower span tension, N.
    pub tension_lower_n: Option<Vec<f64>>,
    /// Motor current, A.
    pub motor_current_a: Option<Vec<f64>>,
    /// Names of columns that were present but not used.
    pub extra_columns: Vec<String>,
    /// `#` comment lines before the header (without the `#`).
    pub comments: Vec<String>,
    /// Where the log came from (file path or "synthetic").
    pub source: String,
}

/// A log that cannot be read, naming file, line and column.
#[derive(Debug, thiserror::Error)]
pub enum LogError {
    /// File cannot be opened or written.
    #[error("{path}: {source}")]
    Io {
        /// File path.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// Bad content.
    #[error("{path}:{line}: column {column}: {message}")]
    Format {
        /// File path.
        path: String,
        /// 1-based line.
        line: usize,
        /// Column name.
        column: String,
        /// What is wrong.
        message: String,
    },
}

impl BenchLog {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// Whether the log has no samples.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// Samples `r` as a new log.
    pub fn slice(&self, r: Range<usize>) -> BenchLog {
        let cut = |v: &Vec<f64>| v[r.clone()].to_vec();
        BenchLog {
            t_s: cut(&self.t_s),
            theta_in_rad: cut(&self.theta_in_rad),
            theta_out_rad: cut(&self.theta_out_rad),
            load_nm: cut(&self.load_nm),
            tension_upper_n: self.tension_upper_n.as_ref().map(cut),
            tension_lower_n: self.tension_lower_n.as_ref().map(cut),
            motor_current_a: self.motor_current_a.as_ref().map(cut),
            extra_columns: self.extra_columns.clone(),
            comments: self.comments.clone(),
            source: self.source.clone(),
        }
    }

    /// Append a sample.
    pub fn push(&mut self, s: &Sample) {
        self.t_s.push(s.t_s);
        self.theta_in_rad.push(s.theta_in_rad);
        self.theta_out_rad.push(s.theta_out_rad);
        self.load_nm.push(s.load_nm);
        let put = |col: &mut Option<Vec<f64>>, v: Option<f64>| {
            if let (Some(c), Some(v)) = (col.as_mut(), v) {
                c.push(v);
            }
        };
        put(&mut self.tension_upper_n, s.tension_upper_n);
        put(&mut self.tension_lower_n, s.tension_lower_n);
        put(&mut self.motor_current_a, s.motor_current_a);
    }
}

/// Read a bench log (CSV with `#` comments before the header).
pub fn read_bench_log(path: &Path) -> Result<BenchLog, LogError> {
    let p = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| LogError::Io {
        path: p.clone(),
        source,
    })?;
    let fmt = |line: usize, column: &str, message: String| LogError::Format {
        path: p.clone(),
        line,
        column: column.to_string(),
        message,
    };
    let mut log = BenchLog {
        source: p.clone(),
        ..BenchLog::default()
    };
    let mut lines = text.lines().enumerate();
    let mut header: Option<(usize, Vec<String>)> = None;
    for (i, line) in lines.by_ref() {
        let l = line.trim();
        if let Some(c) = l.strip_prefix('#') {
            log.comments.push(c.trim().to_string());
        } else if !l.is_empty() {
            header = Some((i + 1, l.split(',').map(|s| s.trim().to_string()).collect()));
            break;
        }
    }
    let (hline, names) = header.ok_or_else(|| fmt(1, "-", "no header row".into()))?;
    let find = |n: &str| names.iter().position(|c| c == n);
    let required = ["t_s", "theta_in_rad", "theta_out_rad", "load_nm"];
    let mut idx = [0usize; 4];
    for (k, n) in required.iter().enumerate() {
        idx[k] = find(n).ok_or_else(|| {
            fmt(
                hline,
                n,
                format!(
                    "required column `{n}` is missing (header: {})",
                    names.join(",")
                ),
            )
        })?;
    }
    let opt = [
        find("tension_upper_n"),
        find("tension_lower_n"),
        find("motor_current_a"),
    ];
    const KNOWN: [&str; 7] = [
        "t_s",
        "theta_in_rad",
        "theta_out_rad",
        "load_nm",
        "tension_upper_n",
        "tension_lower_n",
        "motor_current_a",
    ];
    log.extra_columns = names
        .iter()
        .filter(|n| !KNOWN.contains(&n.as_str()))
        .cloned()
        .collect();
    let mut optcols: [Option<Vec<f64>>; 3] = [
        opt[0].map(|_| Vec::new()),
        opt[1].map(|_| Vec::new()),
        opt[2].map(|_| Vec::new()),
    ];
    for (i, line) in lines {
        let l = line.trim();
        if l.is_empty() {
            continue;
        }
        let fields: Vec<&str> = l.split(',').collect();
        let get = |k: usize, name: &str| -> Result<f64, LogError> {
            let s = fields.get(k).map(|s| s.trim()).unwrap_or("");
            if s.is_empty() {
                return Err(fmt(i + 1, name, "empty field".into()));
            }
            let v: f64 = s
                .parse()
                .map_err(|_| fmt(i + 1, name, format!("`{s}` is not a number")))?;
            if !v.is_finite() {
                return Err(fmt(i + 1, name, format!("`{s}` is not finite")));
            }
            Ok(v)
        };
        let t = get(idx[0], "t_s")?;
        if let Some(&prev) = log.t_s.last() {
            if t <= prev {
                return Err(fmt(
                    i + 1,
                    "t_s",
                    format!("time {t} does not increase (previous {prev})"),
                ));
            }
        }
        log.t_s.push(t);
        log.theta_in_rad.push(get(idx[1], "theta_in_rad")?);
        log.theta_out_rad.push(get(idx[2], "theta_out_rad")?);
        log.load_nm.push(get(idx[3], "load_nm")?);
        for (k, name) in ["tension_upper_n", "tension_lower_n", "motor_current_a"]
            .iter()
            .enumerate()
        {
            if let (Some(c), Some(col)) = (opt[k], optcols[k].as_mut()) {
                col.push(get(c, name)?);
            }
        }
    }
    let [a, b, c] = optcols;
    log.tension_upper_n = a;
    log.tension_lower_n = b;
    log.motor_current_a = c;
    Ok(log)
}

/// Write a bench log in the format [`read_bench_log`] reads.
pub fn write_bench_log(path: &Path, log: &BenchLog) -> Result<(), LogError> {
    use std::fmt::Write as _;
    let mut s = String::new();
    for c in &log.comments {
        let _ = writeln!(s, "# {c}");
    }
    s.push_str("t_s,theta_in_rad,theta_out_rad,load_nm");
    let opts = [
        ("tension_upper_n", &log.tension_upper_n),
        ("tension_lower_n", &log.tension_lower_n),
        ("motor_current_a", &log.motor_current_a),
    ];
    for (n, c) in &opts {
        if c.is_some() {
            let _ = write!(s, ",{n}");
        }
    }
    s.push('\n');
    for i in 0..log.len() {
        let _ = write!(
            s,
            "{:.6},{:.9},{:.9},{:.6}",
            log.t_s[i], log.theta_in_rad[i], log.theta_out_rad[i], log.load_nm[i]
        );
        for (_, c) in &opts {
            if let Some(c) = c {
                let _ = write!(s, ",{:.6}", c.get(i).copied().unwrap_or(0.0));
            }
        }
        s.push('\n');
    }
    std::fs::write(path, s).map_err(|source| LogError::Io {
        path: path.display().to_string(),
        source,
    })
}
