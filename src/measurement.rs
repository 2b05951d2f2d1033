//! A bench log in memory: the measured angles, load and optional tensions and current of a
//! drive, column-wise. Bottom layer: imports nothing of this crate; files are read by `io`.

use std::ops::Range;

/// One sample (one data row) of a bench log.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sample {
    /// Sample time, s.
    pub t_s: f64,
    /// Input pulley / motor shaft angle (encoder A), rad.
    pub theta_in_rad: f64,
    /// Output drum angle (encoder B), rad.
    pub theta_out_rad: f64,
    /// Torque applied by the external load to the output shaft, N m (positive in +theta_out).
    pub load_nm: f64,
    /// Upper free-span tension, N (`None` when the column is absent).
    pub tension_upper_n: Option<f64>,
    /// Lower free-span tension, N (`None` when the column is absent).
    pub tension_lower_n: Option<f64>,
    /// Motor current, A (`None` when the column is absent).
    pub motor_current_a: Option<f64>,
}

/// A bench log held in memory, column-wise. All present columns have the same length.
#[derive(Clone, Debug, Default)]
pub struct BenchLog {
    /// Sample times, s (strictly increasing in a log read from a file).
    pub t_s: Vec<f64>,
    /// Input pulley / motor shaft angle, rad.
    pub theta_in_rad: Vec<f64>,
    /// Output drum angle, rad.
    pub theta_out_rad: Vec<f64>,
    /// External load torque on the output shaft, N m.
    pub load_nm: Vec<f64>,
    /// Upper free-span tension, N (`None` when not measured).
    pub tension_upper_n: Option<Vec<f64>>,
    /// Lower free-span tension, N (`None` when not measured).
    pub tension_lower_n: Option<Vec<f64>>,
    /// Motor current, A (`None` when not measured).
    pub motor_current_a: Option<Vec<f64>>,
    /// Names of unknown header columns that were ignored, in file order.
    pub extra_columns: Vec<String>,
    /// Text of the `#` comment lines before the header: the `#` and one following space
    /// are removed, as are line endings.
    pub comments: Vec<String>,
    /// File path (or stream name) the log was read from; empty for logs built in memory.
    pub source: String,
}

impl BenchLog {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when the log holds no samples.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// The sample at index `i`, or `None` when out of range.
    pub fn sample(&self, i: usize) -> Option<Sample> {
        let opt = |c: &Option<Vec<f64>>| c.as_ref().and_then(|v| v.get(i).copied());
        Some(Sample {
            t_s: *self.t_s.get(i)?,
            theta_in_rad: *self.theta_in_rad.get(i)?,
            theta_out_rad: *self.theta_out_rad.get(i)?,
            load_nm: *self.load_nm.get(i)?,
            tension_upper_n: opt(&self.tension_upper_n),
            tension_lower_n: opt(&self.tension_lower_n),
            motor_current_a: opt(&self.motor_current_a),
        })
    }

    /// Copy of the samples in `range` (sample indices), with the same metadata
    /// (`extra_columns`, `comments`, `source`) and the same set of optional columns.
    /// The range is clamped to `0..len()`, so this never panics.
    pub fn slice(&self, range: Range<usize>) -> BenchLog {
        let end = range.end.min(self.len());
        let start = range.start.min(end);
        let cut = |v: &Vec<f64>| v.get(start..end).map(<[f64]>::to_vec).unwrap_or_default();
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

    /// Append one sample.
    ///
    /// Optional columns stay aligned with `t_s`: if the log has an optional column and the
    /// sample lacks the value, NaN ("not measured") is stored; if the sample has a value for
    /// a column the log does not have yet, the column is created and earlier samples get
    /// NaN. (A log containing NaN is refused by the log writer.)
    pub fn push(&mut self, s: &Sample) {
        let n = self.len();
        self.t_s.push(s.t_s);
        self.theta_in_rad.push(s.theta_in_rad);
        self.theta_out_rad.push(s.theta_out_rad);
        self.load_nm.push(s.load_nm);
        push_optional(&mut self.tension_upper_n, s.tension_upper_n, n);
        push_optional(&mut self.tension_lower_n, s.tension_lower_n, n);
        push_optional(&mut self.motor_current_a, s.motor_current_a, n);
    }
}

fn push_optional(column: &mut Option<Vec<f64>>, value: Option<f64>, len_before: usize) {
    match (column.as_mut(), value) {
        (Some(c), v) => c.push(v.unwrap_or(f64::NAN)),
        (None, Some(v)) => {
            let mut c = vec![f64::NAN; len_before];
            c.push(v);
            *column = Some(c);
        }
        (None, None) => {}
    }
}
