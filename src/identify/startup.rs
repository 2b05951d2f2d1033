//! Start-up transients kept out of fitting and scoring.
//!
//! A bench often engages its load motor after recording has started: the load steps from
//! near zero to its working level within the first fraction of a second, and the output
//! jumps and rings while the drive takes it up. A quasi-static model starting from rest at
//! the first sample cannot follow that, and the seconds after it say nothing about the
//! drive, so they are cut.

use crate::measurement::BenchLog;

/// Settling time kept out after the load has reached 90 % of its step, s: the da Vinci
/// bench's jaw motor settles within about 0.1 s; four times that leaves margin.
pub const SETTLE_S: f64 = 0.4;

/// What was cut from the start of one log.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StartCut {
    /// Log source.
    pub log: String,
    /// Time cut from the start, s (0: nothing cut).
    pub cut_s: f64,
    /// Why, in words.
    pub reason: String,
}

/// How the start of each log is handled.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum StartMode {
    /// Detect a load step at the start and cut it with its settling ([`detect_load_step`]).
    #[default]
    Detect,
    /// Cut this many seconds from every log's start (0: keep everything).
    Fixed(f64),
}

/// Time from the first sample to the end of a start-up load step with its settling, s, or
/// `None` when the log does not start with one.
///
/// A step is found when the load of the first sample differs from the median load of the
/// record's second half by more than three times the load's own spread during the run
/// (half the 10-90 % range), so a brake that flips with the motion direction is not taken
/// for a step. The cut ends [`SETTLE_S`] after the load first reaches 90 % of the step;
/// only the first fifth of the record (at most 2 s) is searched.
pub fn detect_load_step(t_s: &[f64], load_nm: &[f64]) -> Option<f64> {
    let n = t_s.len().min(load_nm.len());
    if n < 100 {
        return None;
    }
    let t0 = t_s[0];
    let window_end = (t0 + 2.0).min(t0 + 0.2 * (t_s[n - 1] - t0));
    let w = t_s.iter().take_while(|t| **t <= window_end).count().max(1);
    // The load motor can engage within a millisecond of the first sample: the first
    // sample is the only one sure to precede the step.
    let l0 = load_nm[0];
    if !l0.is_finite() {
        return None;
    }
    let mut second: Vec<f64> = load_nm[n / 2..n].to_vec();
    let lref = median(&mut second)?;
    let mut run: Vec<f64> = load_nm[w..n].to_vec();
    if run.len() < 10 {
        return None;
    }
    run.sort_by(|a, b| a.total_cmp(b));
    let spread = 0.5 * (run[run.len() * 9 / 10] - run[run.len() / 10]);
    let step = lref - l0;
    if !step.is_finite() || step == 0.0 || step.abs() <= 3.0 * spread {
        return None;
    }
    let reach = (0..w).find(|i| (load_nm[*i] - l0) / step >= 0.9)?;
    Some((t_s[reach] - t0 + SETTLE_S).min(window_end - t0))
}

fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() || v.iter().any(|x| !x.is_finite()) {
        return None;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    Some(v[v.len() / 2])
}

/// The log without its first `cut_s` seconds (times keep their values).
pub fn trim_start(log: &BenchLog, cut_s: f64) -> BenchLog {
    let Some(t0) = log.t_s.first().copied() else {
        return log.clone();
    };
    let k = log.t_s.iter().take_while(|t| **t < t0 + cut_s).count();
    let cut = |v: &Vec<f64>| v.get(k..).map(|s| s.to_vec()).unwrap_or_default();
    BenchLog {
        t_s: cut(&log.t_s),
        theta_in_rad: cut(&log.theta_in_rad),
        theta_out_rad: cut(&log.theta_out_rad),
        load_nm: cut(&log.load_nm),
        tension_upper_n: log.tension_upper_n.as_ref().map(cut),
        tension_lower_n: log.tension_lower_n.as_ref().map(cut),
        motor_current_a: log.motor_current_a.as_ref().map(cut),
        extra_columns: log.extra_columns.clone(),
        comments: log.comments.clone(),
        source: log.source.clone(),
    }
}

/// Apply `mode` to a log: the log to fit and what was cut.
pub fn cut_start(log: &BenchLog, mode: StartMode) -> (BenchLog, StartCut) {
    let (cut_s, reason) = match mode {
        StartMode::Fixed(s) if s > 0.0 => (s, format!("first {s:.3} s cut as requested")),
        StartMode::Fixed(_) => (0.0, "nothing cut (as requested)".to_string()),
        StartMode::Detect => match detect_load_step(&log.t_s, &log.load_nm) {
            Some(s) => (
                s,
                format!(
                    "first {s:.3} s cut: load step at the start (load motor engaging) and {SETTLE_S} s of settling"
                ),
            ),
            None => (0.0, "no start-up load step found; nothing cut".to_string()),
        },
    };
    let trimmed = if cut_s > 0.0 {
        trim_start(log, cut_s)
    } else {
        log.clone()
    };
    (
        trimmed,
        StartCut {
            log: log.source.clone(),
            cut_s,
            reason,
        },
    )
}

/// [`super::model::prepare`] of `cut_log`, the part of `log` left after `cut`: a log too
/// short to fit after the cut says so, with the cut and what the whole log held, so the
/// cut is the thing to change, not the log.
pub fn prepare_after_cut(
    log: &BenchLog,
    cut_log: &BenchLog,
    cut: &StartCut,
    max_rate_hz: f64,
) -> Result<super::model::Prepared, super::IdentifyError> {
    super::model::prepare(cut_log, max_rate_hz).map_err(|e| match e {
        super::IdentifyError::BadLog { log: name, message } if cut.cut_s > 0.0 => {
            let span = match (log.t_s.first(), log.t_s.last()) {
                (Some(a), Some(b)) => format!(" from {a:.3} to {b:.3} s"),
                _ => String::new(),
            };
            super::IdentifyError::BadLog {
                log: name,
                message: format!(
                    "{message}; left after the start cut ({}) of a log of {} samples{span}",
                    cut.reason,
                    log.len()
                ),
            }
        }
        e => e,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cut_that_leaves_too_little_is_named_in_the_error() {
        let n = 20000;
        let t = times(n, 1e-3);
        let log = BenchLog {
            theta_in_rad: t.iter().map(|t| (0.5 * t).sin()).collect(),
            theta_out_rad: t.iter().map(|t| (0.5 * t).sin()).collect(),
            load_nm: vec![0.1; n],
            t_s: t,
            source: "tool4_04.csv".into(),
            ..BenchLog::default()
        };
        let (short, cut) = cut_start(&log, StartMode::Fixed(19.99));
        let e = prepare_after_cut(&log, &short, &cut, 1000.0)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            e.contains("tool4_04.csv")
                && e.contains("too few")
                && e.contains("first 19.990 s cut as requested")
                && e.contains("20000 samples from 0.000 to 19.999 s"),
            "{e}"
        );
        let (whole, cut) = cut_start(&log, StartMode::Fixed(0.0));
        assert!(prepare_after_cut(&log, &whole, &cut, 1000.0).is_ok());
    }

    fn times(n: usize, dt: f64) -> Vec<f64> {
        (0..n).map(|i| i as f64 * dt).collect()
    }

    #[test]
    fn load_step_at_start_is_found_and_cut_after_settling() {
        let t = times(20000, 1e-3);
        // Load rises from 0.01 to 0.07 N m between 30 and 60 ms, then varies by +-0.01.
        let load: Vec<f64> = t
            .iter()
            .map(|t| {
                let ramp = ((t - 0.03) / 0.03).clamp(0.0, 1.0);
                0.01 + 0.06 * ramp + 0.01 * ramp * (2.0 * std::f64::consts::PI * 0.1 * t).sin()
            })
            .collect();
        let cut = detect_load_step(&t, &load).expect("step found");
        // 90 % reached at 57 ms.
        assert!((cut - (0.057 + SETTLE_S)).abs() < 2e-3, "cut {cut}");
    }

    #[test]
    fn brake_flipping_with_direction_is_not_a_step() {
        let t = times(4000, 5e-3);
        let load: Vec<f64> = t
            .iter()
            .map(|t| -0.5 * (2.0 * std::f64::consts::PI * 0.25 * t).cos().signum())
            .collect();
        assert_eq!(detect_load_step(&t, &load), None);
    }

    #[test]
    fn steady_load_is_not_a_step() {
        let t = times(4000, 5e-3);
        let load: Vec<f64> = t.iter().map(|t| 0.013 + 0.004 * (0.6 * t).sin()).collect();
        assert_eq!(detect_load_step(&t, &load), None);
    }
}
