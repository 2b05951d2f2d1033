//! Closed-loop design answers: the largest load, or the fastest scan, that still meets the
//! pointing target with a given controller and compensation; and the controller itself,
//! tuned ([`tune`]), with the least control rate a tuned design needs. Top layer.
//!
//! Each answer bisects on one scenario value, running the closed loop at every probe, and
//! assumes the loop meets the target below the answer and misses it above.

use serde::Serialize;

pub mod tune;
pub mod tune_files;

use crate::closed_loop::{self, CompensationMode};
use crate::scenario::Scenario;
use crate::signal::Signal;
use crate::study::answers::largest_passing;

/// What a design question varies.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Question {
    /// Brake torque `load.brake_nm` (N m); the breakaway torque keeps its ratio to it.
    LargestLoad,
    /// Reference frequency (Hz) of a sine or triangle scan, amplitude unchanged.
    FastestScan,
}

/// Answer to a design question.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DesignAnswer {
    /// The question.
    pub question: Question,
    /// Compensation mode judged.
    pub mode: CompensationMode,
    /// Largest value that meets the target (N m or Hz); `None` if even the lower end
    /// misses.
    pub value: Option<f64>,
    /// Unit of `value`.
    pub unit: &'static str,
    /// Searched range.
    pub range: (f64, f64),
    /// Bisection tolerance worked to (the one asked for, or the floor when finer).
    pub tolerance: f64,
    /// Closed-loop runs made.
    pub runs: usize,
    /// A raised tolerance or a search stopped on its limit, in words; `None` otherwise.
    pub note: Option<String>,
    /// What the answer means.
    pub definition: String,
}

/// A question that cannot be asked of this scenario.
#[derive(Debug, thiserror::Error)]
pub enum DesignError {
    /// Not a closed-loop scenario, or the mode is not listed, or the reference is not a scan.
    #[error("{0}")]
    Unsuitable(String),
    /// The results directory cannot be prepared or moved into place.
    #[error(transparent)]
    Output(#[from] crate::io::output::OutputError),
    /// A figure cannot be drawn.
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    /// A result file cannot be written (path and cause).
    #[error("cannot write {0}")]
    Write(String),
}

/// Largest end of a search range, N m or Hz: far beyond any gimbal's brake load or scan,
/// and small enough that the bisection's tolerance floor (1e-9 of it) stays a number a
/// design review can read.
pub const MAX_SEARCH_END: f64 = 1e6;

/// Whether a search `range` (N m or Hz) and `tolerance` can be searched: checked before
/// any run, so a range no search can resolve costs nothing.
pub fn check_search(range: (f64, f64), tolerance: f64) -> Result<(), DesignError> {
    if range.0 >= 0.0
        && range.1 > range.0
        && range.1 <= MAX_SEARCH_END
        && tolerance > 0.0
        && tolerance.is_finite()
    {
        return Ok(());
    }
    Err(DesignError::Unsuitable(format!(
        "need a range 0 <= lo < hi <= {} and a finite tolerance > 0, got {} to {} and {}",
        crate::readable(MAX_SEARCH_END),
        crate::readable(range.0),
        crate::readable(range.1),
        crate::readable(tolerance)
    )))
}

fn with_value(base: &Scenario, question: Question, value: f64) -> Scenario {
    let mut s = base.clone();
    match question {
        Question::LargestLoad => {
            let ratio = base
                .load
                .brake_breakaway_nm
                .filter(|_| base.load.brake_nm > 0.0)
                .map(|b| b / base.load.brake_nm);
            s.load.brake_nm = value;
            s.load.brake_breakaway_nm = ratio.map(|r| r * value);
        }
        Question::FastestScan => {
            if let Some(cl) = s.closed_loop.as_mut() {
                if let Signal::Sine { frequency_hz, .. } | Signal::Triangle { frequency_hz, .. } =
                    &mut cl.reference
                {
                    *frequency_hz = value;
                }
            }
        }
    }
    s
}

/// Whether `mode` keeps the line of sight within the target over the whole run.
fn meets(scenario: &Scenario, mode: CompensationMode) -> bool {
    if scenario.validate("design probe").is_err() {
        return false;
    }
    // The probe is judged as every command judges a design: every requirement, in `mode`.
    let mut probe = scenario.clone();
    if let Some(cl) = probe.closed_loop.as_mut() {
        cl.requirements.mode = Some(mode);
    }
    let Ok(setup) = closed_loop::ClosedLoopSource::closed_loop_setup(&probe) else {
        return false;
    };
    crate::analysis::verdict::evaluate(&setup).is_ok_and(|v| v.passes)
}

/// Largest brake load or fastest scan in `range` that meets the pointing target with
/// `mode`, to within `tolerance`.
pub fn largest_meeting_target(
    base: &Scenario,
    question: Question,
    mode: CompensationMode,
    range: (f64, f64),
    tolerance: f64,
) -> Result<DesignAnswer, DesignError> {
    let cl = base.closed_loop.as_ref().ok_or_else(|| {
        DesignError::Unsuitable(format!(
            "scenario {} is not a closed-loop study",
            base.name()
        ))
    })?;
    if !cl.modes.contains(&mode) {
        return Err(DesignError::Unsuitable(format!(
            "mode {} is not listed in closed_loop.modes",
            mode.name()
        )));
    }
    if question == Question::FastestScan
        && !matches!(cl.reference, Signal::Sine { .. } | Signal::Triangle { .. })
    {
        return Err(DesignError::Unsuitable(
            "the fastest scan needs a sine or triangle closed_loop.reference".into(),
        ));
    }
    check_search(range, tolerance)?;
    let search = largest_passing(range.0, range.1, tolerance, |v| {
        meets(&with_value(base, question, v), mode)
    });
    let (unit, what) = match question {
        Question::LargestLoad => (
            "N m",
            "brake torque load.brake_nm (breakaway scaled with it)",
        ),
        Question::FastestScan => ("Hz", "reference scan frequency at the scenario's amplitude"),
    };
    Ok(DesignAnswer {
        question,
        mode,
        value: search.value,
        unit,
        range,
        tolerance: search.tolerance,
        runs: search.probes,
        note: search.note(tolerance),
        definition: format!(
            "largest {what} at which the design meets every requirement with the {} mode judged: pointing error within {} mrad over the metrics window of a complete run, and the margins of closed_loop.requirements over the operating range at that load; bisection, assuming the design passes below the answer and fails above",
            mode.name(),
            crate::compact(cl.target_mrad)
        ),
    })
}
