//! Files of a closed-loop run: `timeseries.csv`, `summary.json`, a text table, and the
//! chart descriptions for the plot module.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::closed_loop::{
    ClosedLoopResult, CompensationMode, Completion, ModeResult, SolverStats, TimeSeries,
};
use crate::metrics::los::ErrorSpectrum;
use crate::metrics::Metrics;
use crate::plot::{save_chart, save_panels, Chart, HBand, PlotError, Series, XShade};
use crate::report::ReportError;
use crate::scenario::Scenario;

/// Header of `timeseries.csv` (units in the names); the command and feedforward columns
/// are `motor_command_a`, `feedforward_a` with a current amplifier and `motor_command_v`,
/// `feedforward_v` with a voltage one.
pub const TIMESERIES_HEADER: [&str; 16] = [
    "mode",
    "t_s",
    "reference_rad",
    "motor_angle_rad",
    "output_angle_rad",
    "pointing_error_mrad",
    "transmission_error_mrad",
    "tension_upper_n",
    "tension_lower_n",
    "motor_command_a",
    "motor_current_a",
    "load_torque_nm",
    "feedforward_a",
    "motor_reference_rad",
    "base_angle_rad",
    "gyro_rad_s",
];

/// A mode's figures; a mode that stopped has none (null), with the reason.
#[derive(Serialize)]
struct ModeSummary<'a> {
    name: &'static str,
    rms_mrad: Option<f64>,
    peak_mrad: Option<f64>,
    p95_mrad: Option<f64>,
    within_target_fraction: Option<f64>,
    passes_target: bool,
    /// Why the figures are null (a stop, an empty metrics window).
    #[serde(skip_serializing_if = "Option::is_none")]
    no_metrics_reason: Option<String>,
    metrics: Option<&'a Metrics>,
    solver: &'a SolverStats,
    completion: &'a Completion,
    simulated_s: f64,
    limit_cycle: &'a crate::metrics::limit_cycle::LimitCycle,
    /// Line-of-sight statistics (RMS, peak, jitter per exposure).
    los: Option<&'a crate::metrics::los::LosMetrics>,
    /// Whether the feedforward also predicted the `[effects]` error (the extended model).
    effects_compensated: bool,
    /// Time the command spent at the amplifier's limit.
    command_saturation: crate::closed_loop::CommandSaturation,
}

#[derive(Serialize)]
struct CompensatorGiven {
    reference: bool,
    known_load_terms: Vec<crate::physics::LoadTerm>,
    unknown_load_terms: Vec<crate::physics::LoadTerm>,
    note: &'static str,
}

#[derive(Serialize)]
struct Summary<'a> {
    program_version: &'static str,
    scenario_name: &'a str,
    simulated_s: f64,
    duration_s: f64,
    complete: bool,
    command_unit: &'static str,
    modes: Vec<ModeSummary<'a>>,
    /// The design's verdict: every requirement with its measured value and margin.
    #[serde(skip_serializing_if = "Option::is_none")]
    verdict: Option<&'a crate::analysis::verdict::Verdict>,
    /// What the memory and memoryless feedforward were given in advance.
    compensator_given: CompensatorGiven,
    solver: SolverStats,
    scenario: &'a Scenario,
}

fn mode_summary(m: &ModeResult) -> ModeSummary<'_> {
    // What a stopped mode ran is not the design's answer: no figures, the reason instead.
    let reason = m.no_figures_reason();
    let ok = reason.is_none();
    let figure = |v: f64| ok.then_some(v);
    ModeSummary {
        name: m.mode.name(),
        rms_mrad: figure(m.metrics.rms_mrad),
        peak_mrad: figure(m.metrics.peak_mrad),
        p95_mrad: figure(m.metrics.p95_mrad),
        within_target_fraction: figure(m.metrics.within_target_fraction),
        passes_target: ok && m.metrics.passes_target,
        no_metrics_reason: reason,
        metrics: ok.then_some(&m.metrics),
        solver: &m.stats,
        completion: &m.completion,
        simulated_s: m.simulated_s,
        limit_cycle: &m.limit_cycle,
        los: m.los.as_ref().filter(|_| ok),
        effects_compensated: m.effects_compensated,
        command_saturation: m.saturation,
    }
}

/// One mode's `timeseries.csv` rows (no header). Numbers are written in their shortest
/// form that reads back to the same `f64` (ryu): exact, and several times faster than a
/// fixed number of digits. Neither a mode name nor a number ever needs CSV quoting, so
/// the rows are joined directly.
/// `None` for a mode that kept no series.
pub fn timeseries_rows(m: &crate::closed_loop::ModeResult) -> Option<Vec<u8>> {
    let s = m.series.as_ref()?;
    let mode = m.mode.name();
    let mut out = Vec::with_capacity(s.len() * 16 * 20);
    let mut number = ryu::Buffer::new();
    for i in 0..s.len() {
        let cols = [
            s.t_s[i],
            s.reference_rad[i],
            s.motor_angle_rad[i],
            s.output_angle_rad[i],
            s.pointing_error_mrad[i],
            s.transmission_error_mrad[i],
            s.tension_upper_n[i],
            s.tension_lower_n[i],
            s.motor_command[i],
            s.motor_current_a[i],
            s.load_torque_nm[i],
            s.feedforward[i],
            s.motor_reference_rad[i],
            s.base_angle_rad[i],
            s.gyro_rad_s[i],
        ];
        out.extend_from_slice(mode.as_bytes());
        for v in cols {
            out.push(b',');
            out.extend_from_slice(number.format(v).as_bytes());
        }
        out.push(b'\n');
    }
    Some(out)
}

/// Write `timeseries.csv` (all modes, with a `mode` column; only modes that were
/// recorded) and `summary.json` into `dir` (created if missing). Returns the paths.
pub fn write_closed_loop_outputs(
    dir: &Path,
    scenario: &Scenario,
    result: &ClosedLoopResult,
    verdict: Option<&crate::analysis::verdict::Verdict>,
) -> Result<Vec<PathBuf>, ReportError> {
    use rayon::prelude::*;
    // Formatting is most of the cost of writing: each mode's rows on its own core.
    let rows: Vec<Option<Vec<u8>>> = result.modes.par_iter().map(timeseries_rows).collect();
    write_closed_loop_outputs_with_rows(dir, scenario, result, rows, verdict)
}

/// [`write_closed_loop_outputs`] with each mode's `timeseries.csv` rows already formatted
/// by [`timeseries_rows`] (in mode order), as a run formats them on each mode's thread
/// the moment the mode ends.
pub fn write_closed_loop_outputs_with_rows(
    dir: &Path,
    scenario: &Scenario,
    result: &ClosedLoopResult,
    rows: Vec<Option<Vec<u8>>>,
    verdict: Option<&crate::analysis::verdict::Verdict>,
) -> Result<Vec<PathBuf>, ReportError> {
    std::fs::create_dir_all(dir).map_err(|e| ReportError::io(dir, e))?;
    let mut written = Vec::new();
    let command_unit = command_unit(scenario);
    if result.modes.iter().any(|m| m.series.is_some()) {
        let path = dir.join("timeseries.csv");
        let csv_err = |e| ReportError::csv(&path, e);
        let mut header = TIMESERIES_HEADER;
        if command_unit == "V" {
            header[9] = "motor_command_v";
            header[12] = "feedforward_v";
        }
        let mut w = csv::Writer::from_path(&path).map_err(csv_err)?;
        w.write_record(header).map_err(csv_err)?;
        w.flush().map_err(|e| ReportError::io(&path, e))?;
        let mut file = w
            .into_inner()
            .map_err(|e| ReportError::io(&path, e.into_error()))?;
        for block in rows.iter().flatten() {
            std::io::Write::write_all(&mut file, block).map_err(|e| ReportError::io(&path, e))?;
        }
        std::io::Write::flush(&mut file).map_err(|e| ReportError::io(&path, e))?;
        written.push(path);
    }
    let total = result
        .modes
        .iter()
        .fold(SolverStats::default(), |a, m| SolverStats {
            periods: a.periods + m.stats.periods,
            steps: a.steps + m.stats.steps,
            rhs_evaluations: a.rhs_evaluations + m.stats.rhs_evaluations,
            tension_solves: a.tension_solves + m.stats.tension_solves,
            rejected_steps: a.rejected_steps + m.stats.rejected_steps,
            compensator_faults: a.compensator_faults + m.stats.compensator_faults,
            wall_s: a.wall_s + m.stats.wall_s,
        });
    let summary = Summary {
        program_version: env!("CARGO_PKG_VERSION"),
        scenario_name: scenario.name(),
        simulated_s: result
            .modes
            .iter()
            .map(|m| m.simulated_s)
            .fold(f64::INFINITY, f64::min)
            .min(result.duration_s),
        duration_s: result.duration_s,
        complete: result.complete,
        command_unit,
        modes: result.modes.iter().map(mode_summary).collect(),
        verdict,
        compensator_given: CompensatorGiven {
            reference: true,
            known_load_terms: scenario.load.known_terms(),
            unknown_load_terms: scenario.load.unknown_terms(),
            note: "the feedforward uses the reference and the known load terms only; \
                   unknown terms act on the plant and reach the controller through its sensors",
        },
        solver: total,
        scenario,
    };
    if result
        .modes
        .iter()
        .any(|m| m.spectrum.is_some() && m.completion == Completion::Complete)
    {
        let path = dir.join("error_psd.csv");
        let csv_err = |e| ReportError::csv(&path, e);
        let mut w = csv::Writer::from_path(&path).map_err(csv_err)?;
        w.write_record([
            "mode",
            "frequency_hz",
            "psd_mrad2_per_hz",
            "cumulative_rms_mrad",
        ])
        .map_err(csv_err)?;
        for m in result
            .modes
            .iter()
            .filter(|m| m.completion == Completion::Complete)
        {
            let Some(sp) = &m.spectrum else { continue };
            for i in 0..sp.frequency_hz.len() {
                w.write_record([
                    m.mode.name().to_string(),
                    format!("{:.6e}", sp.frequency_hz[i]),
                    format!("{:.6e}", sp.psd_mrad2_per_hz[i]),
                    format!("{:.6e}", sp.cumulative_rms_mrad[i]),
                ])
                .map_err(csv_err)?;
            }
        }
        w.flush().map_err(|e| ReportError::io(&path, e))?;
        written.push(path);
    }
    let path = dir.join("summary.json");
    let value = serde_json::to_value(&summary).map_err(|e| ReportError::Encode {
        path: path.clone(),
        message: e.to_string(),
    })?;
    crate::report::write_json(&path, &value)?;
    written.push(path);
    Ok(written)
}

/// Fixed-width table: mode, RMS, peak, p95 (mrad), whether it passes, and completion; for
/// a reference with steps, a second table of the step figures that decide the pass.
pub fn format_table(result: &ClosedLoopResult) -> String {
    let exposure_ms = result
        .modes
        .iter()
        .find_map(|m| m.los.as_ref().map(|l| l.exposure_s * 1e3));
    let jitter_head = exposure_ms.map_or("jitter_mrad".to_string(), |e| {
        format!("jitter{e:.0}ms_mrad")
    });
    let mut out = format!(
        "{:<12} {:>10} {:>10} {:>10} {:>16} {:>8}  {}\n",
        "mode", "rms_mrad", "peak_mrad", "p95_mrad", jitter_head, "passes", "status"
    );
    for m in &result.modes {
        let status = match &m.completion {
            Completion::Complete => "complete".to_string(),
            Completion::Incomplete { fault, .. } => format!("INCOMPLETE: {fault}"),
        };
        // A stopped mode has no figures: what it ran is not the design's answer.
        let figure = |v: f64| match (&m.completion, m.metrics.samples) {
            (Completion::Complete, n) if n > 0 => format!("{v:.5}"),
            _ => "-".to_string(),
        };
        let jitter = m
            .los
            .as_ref()
            .and_then(|l| l.jitter_rms_max_mrad)
            .map_or("-".to_string(), figure);
        out.push_str(&format!(
            "{:<12} {:>10} {:>10} {:>10} {:>16} {:>8}  {}\n",
            m.mode.name(),
            figure(m.metrics.rms_mrad),
            figure(m.metrics.peak_mrad),
            figure(m.metrics.p95_mrad),
            jitter,
            if m.metrics.passes_target && matches!(m.completion, Completion::Complete) {
                "yes"
            } else {
                "no"
            },
            status
        ));
    }
    for m in &result.modes {
        let sat = m.saturation;
        // A sample or two at the limit is a transient; a tenth of a percent is worth a
        // line (a whole second at it stops the run).
        if sat.fraction >= 1e-3 && m.completion == Completion::Complete {
            out.push_str(&format!(
                "{}: command at the amplifier limit for {:.1} % of the run (longest {:.3} s without a break)\n",
                m.mode.name(),
                100.0 * sat.fraction,
                sat.longest_s
            ));
        }
    }
    if result.modes.iter().any(|m| m.effects_compensated) {
        out.push_str(
            "the compensated modes also predict the [effects] error (closed_loop.compensate_effects = true: the extended model)\n",
        );
    }
    for m in &result.modes {
        if let crate::metrics::limit_cycle::LimitCycle::Detected {
            amplitude_mrad,
            frequency_hz,
            start_s,
            cycles,
        } = m.limit_cycle
        {
            out.push_str(&format!(
                "{}: LIMIT CYCLE at rest: {amplitude_mrad:.4} mrad at {frequency_hz:.2} Hz from t = {start_s:.3} s ({cycles} cycles judged)\n",
                m.mode.name()
            ));
        }
        // A periodic error at a driven frequency is the loop's forced response: named, so
        // nobody hunts a limit cycle that is not there.
        if let crate::metrics::limit_cycle::LimitCycle::Forced {
            amplitude_mrad,
            frequency_hz,
            source,
        } = &m.limit_cycle
        {
            out.push_str(&format!(
                "{}: periodic error at rest: {amplitude_mrad:.4} mrad at {frequency_hz:.2} Hz, also present in the {source}: forced, not a limit cycle\n",
                m.mode.name()
            ));
        }
    }
    if result
        .modes
        .iter()
        .any(|m| m.metrics.step_summary.is_some())
    {
        out.push_str(&format_step_table(result));
    }
    out
}

/// Step figures per mode (the worst over the steps): settled steps, overshoot (%), 10-90 %
/// rise time (ms), settling time (ms), peak and RMS error after settling over the settled
/// steps and the error left at the end of a step (mrad), pass.
fn format_step_table(result: &ClosedLoopResult) -> String {
    let opt = |v: Option<f64>, scale: f64, none: &str| match v {
        Some(v) => format!("{:.3}", v * scale),
        None => none.to_string(),
    };
    let mut out = format!(
        "steps (worst over the steps; stares = stare windows that pass: the step settled and its error after settling stayed within {0} mrad; passes = every stare passes)\n",
        result
            .modes
            .first()
            .map_or(0.0, |m| m.metrics.target_mrad)
    );
    out.push_str(&format!(
        "{:<12} {:>8} {:>8} {:>12} {:>10} {:>16} {:>15} {:>14} {:>11} {:>8}\n",
        "mode",
        "stares",
        "settled",
        "overshoot_%",
        "rise_ms",
        "settling_ms",
        "after_peak_mrad",
        "after_rms_mrad",
        "final_mrad",
        "passes"
    ));
    for m in &result.modes {
        let Some(s) = &m.metrics.step_summary else {
            continue;
        };
        let stares = m.metrics.steps.iter().filter(|st| st.passes_target).count();
        out.push_str(&format!(
            "{:<12} {:>8} {:>8} {:>12.1} {:>10} {:>16} {:>15} {:>14} {:>11.3} {:>8}\n",
            m.mode.name(),
            format!("{stares}/{}", s.judged),
            format!("{}/{}", s.settled, s.judged),
            s.max_overshoot_percent,
            opt(s.max_rise_time_s, 1e3, "not reached"),
            opt(s.worst_settling_time_s, 1e3, "did not settle"),
            opt(s.error_after_settling_peak_mrad, 1.0, "-"),
            opt(s.error_after_settling_rms_mrad, 1.0, "-"),
            s.max_final_error_mrad,
            if m.metrics.passes_target { "yes" } else { "no" },
        ));
    }
    out
}

/// Unit of the motor command and feedforward: `"A"` behind a current amplifier, `"V"`
/// behind a voltage one (a scenario without a closed loop: `"A"`).
pub fn command_unit(scenario: &Scenario) -> &'static str {
    match scenario.closed_loop.as_ref().map(|p| p.motor.amplifier) {
        Some(crate::closed_loop::Amplifier::Voltage) => "V",
        _ => "A",
    }
}

/// Legend label of the shade over the samples outside the metrics window.
pub const OUTSIDE_WINDOW: &str = "outside the metrics window (not judged)";

/// The metrics window `[from, to]` (s) the modes were judged over: that of the first mode
/// with judged samples; `None` when no mode has any.
pub fn metrics_window(result: &ClosedLoopResult) -> Option<(f64, f64)> {
    result
        .modes
        .iter()
        .find(|m| m.metrics.samples > 0)
        .map(|m| (m.metrics.window_s[0], m.metrics.window_s[1]))
        .filter(|(a, b)| a.is_finite() && b.is_finite() && b >= a)
}

/// Grey shades over the recorded time `span` (s) before and after the metrics window
/// (none on a side the window reaches).
pub fn window_shades(window: Option<(f64, f64)>, span: (f64, f64)) -> Vec<XShade> {
    let Some((from, to)) = window else {
        return Vec::new();
    };
    let shade = |lo, hi| XShade {
        lo,
        hi,
        label: OUTSIDE_WINDOW.into(),
    };
    let mut out = Vec::new();
    if span.0 < from {
        out.push(shade(f64::NEG_INFINITY, from));
    }
    if span.1 > to {
        out.push(shade(to, f64::INFINITY));
    }
    out
}

/// A mode's samples `y` at times `t` split at the metrics window `[from, to]`:
/// `(judged, not judged)`, each as long as `y` with NaN where the other holds the sample,
/// so each draws as a line of its own, broken where the other takes over. Without a
/// window every sample is judged.
fn split_at_window(t: &[f64], y: &[f64], window: Option<(f64, f64)>) -> (Vec<f64>, Vec<f64>) {
    let inside = |t: f64| window.is_none_or(|(from, to)| t >= from && t <= to);
    t.iter()
        .zip(y)
        .map(|(&t, &v)| {
            if inside(t) {
                (v, f64::NAN)
            } else {
                (f64::NAN, v)
            }
        })
        .unzip()
}

/// Legend label of the samples recorded before the metrics window.
const BEFORE_WINDOW: &str = "before metrics start (not judged)";

/// Legend label of the samples a run recorded outside the metrics window `[from, to]`
/// over its recorded time `span` (s): before the window alone when it runs to the end.
fn not_judged_label((_, to): (f64, f64), span: (f64, f64)) -> &'static str {
    if span.1 > to {
        OUTSIDE_WINDOW
    } else {
        BEFORE_WINDOW
    }
}

/// A figure of a run: one chart, or charts stacked under one title.
// A handful of figures per run, built and drawn once: boxing the chart buys nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Figure {
    /// One chart.
    Chart(Chart),
    /// Panels sharing a title.
    Panels {
        /// Figure title.
        title: String,
        /// Panels, top to bottom.
        charts: Vec<Chart>,
    },
}

/// The palette slot of a mode, the same in every figure: none blue, memoryless orange,
/// memory green.
pub fn mode_slot(mode: CompensationMode) -> usize {
    match mode {
        CompensationMode::None => 0,
        CompensationMode::Memoryless => 1,
        CompensationMode::Memory => 2,
    }
}

/// The closed-loop figures as `(file stem, figure)`: pointing error against time (every
/// mode with the +-target band; below, the compensated modes on an axis fitted to them),
/// pointing error against output angle (the samples before the metrics window in grey),
/// span tensions (upper and lower panels) and motor command in `command_unit` (`"A"` or
/// `"V"`, see [`command_unit`]); one colour per mode throughout. Time outside the metrics
/// window is shaded, and the error panels' scale is set by the window alone (a start-up
/// transient beyond it is marked off scale). Built from recorded series only (empty when
/// nothing was recorded, and then no figure is written).
pub fn closed_loop_charts(
    result: &ClosedLoopResult,
    target_mrad: f64,
    command_unit: &str,
) -> Vec<(String, Figure)> {
    let recorded: Vec<(CompensationMode, &TimeSeries, String)> = result
        .modes
        .iter()
        .filter_map(|m| m.series.as_ref().map(|s| (m.mode, s, m.label())))
        .collect();
    if recorded.is_empty() {
        return Vec::new();
    }
    let band = || {
        vec![HBand {
            lo: -target_mrad,
            hi: target_mrad,
            label: format!("target +-{target_mrad} mrad"),
        }]
    };
    let curves = |f: &Columns, only_compensated: bool| -> Vec<Series> {
        recorded
            .iter()
            .filter(|(mode, _, _)| !only_compensated || *mode != CompensationMode::None)
            .map(|(mode, s, label)| {
                let (x, y) = f(s);
                Series::line(label.as_str(), x, y).in_slot(mode_slot(*mode))
            })
            .collect()
    };
    let chart = |title: &str, x_label: &str, y_label: &str, series, bands| Chart {
        title: title.into(),
        x_label: x_label.into(),
        y_label: y_label.into(),
        series,
        bands,
        ..Chart::default()
    };
    let window = metrics_window(result);
    let span = recorded
        .iter()
        .flat_map(|(_, s, _)| s.t_s.iter().copied().filter(|t| t.is_finite()))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| {
            (a.min(t), b.max(t))
        });
    let timed = |c: Chart| Chart {
        x_shades: window_shades(window, span),
        ..c
    };
    let error = |s: &TimeSeries| (s.t_s.clone(), s.pointing_error_mrad.clone());
    let all_modes = Chart {
        y_fit_x: window,
        ..timed(chart(
            "every mode (scale set by the metrics window)",
            "time [s]",
            "pointing error [mrad]",
            curves(&error, false),
            band(),
        ))
    };
    let compensated = recorded
        .iter()
        .any(|(m, _, _)| *m != CompensationMode::None);
    let has_none = recorded
        .iter()
        .any(|(m, _, _)| *m == CompensationMode::None);
    let pointing = if compensated && has_none {
        // The uncompensated error sets the first panel's scale; the second is fitted to
        // the compensated modes (and the band) so they can be told apart.
        // Over the metrics window, where the modes are judged (the start-up transient
        // would set the scale otherwise).
        let (from, to) = result
            .modes
            .iter()
            .find(|m| m.mode != CompensationMode::None && m.metrics.samples > 0)
            .map_or((f64::NEG_INFINITY, f64::INFINITY), |m| {
                (m.metrics.window_s[0], m.metrics.window_s[1])
            });
        let largest = recorded
            .iter()
            .filter(|(m, _, _)| *m != CompensationMode::None)
            .flat_map(|(_, s, _)| {
                s.t_s
                    .iter()
                    .zip(&s.pointing_error_mrad)
                    .filter(move |(t, _)| **t >= from && **t <= to)
                    .map(|(_, e)| e.abs())
            })
            .filter(|e| e.is_finite())
            .fold(0.0_f64, f64::max);
        let y = (1.1 * largest).max(1.2 * target_mrad);
        // A run that stopped before the window has no window to name.
        let title = if from.is_finite() {
            format!(
                "compensated modes over the metrics window, axis fitted to them (from {from:.1} s)"
            )
        } else {
            "compensated modes (no metrics window: every compensated mode stopped before it)"
                .to_string()
        };
        let mut fitted = chart(
            &title,
            "time [s]",
            "pointing error [mrad]",
            curves(&error, true),
            band(),
        );
        if from.is_finite() && to > from {
            fitted.x_range = Some((from, to));
            fitted.y_range = Some((-y, y));
        }
        Figure::Panels {
            title: "Pointing error".into(),
            charts: vec![all_modes, fitted],
        }
    } else {
        Figure::Chart(Chart {
            title: "Pointing error".into(),
            ..all_modes
        })
    };
    let tension_panel = |title: &str, f: &Columns| {
        timed(chart(
            title,
            "time [s]",
            "tension [N]",
            curves(f, false),
            Vec::new(),
        ))
    };
    // Commands are held between samples: drawn as staircases.
    let commands = recorded
        .iter()
        .map(|(mode, s, label)| {
            Series::step(label.as_str(), s.t_s.clone(), s.motor_command.clone())
                .in_slot(mode_slot(*mode))
        })
        .collect();
    let mut figures = vec![
        ("pointing_error".into(), pointing),
        (
            "error_vs_angle".into(),
            error_vs_angle(&recorded, window, span, band),
        ),
        (
            "tensions".into(),
            Figure::Panels {
                title: "Span tensions".into(),
                charts: vec![
                    tension_panel("upper span", &|s| {
                        (s.t_s.clone(), s.tension_upper_n.clone())
                    }),
                    tension_panel("lower span", &|s| {
                        (s.t_s.clone(), s.tension_lower_n.clone())
                    }),
                ],
            },
        ),
        (
            "motor_command".into(),
            Figure::Chart(timed(chart(
                "Motor command",
                "time [s]",
                &format!("motor command [{command_unit}]"),
                commands,
                Vec::new(),
            ))),
        ),
    ];
    if let Some(f) = spectrum_figure(result, target_mrad) {
        figures.push(("error_psd".into(), f));
    }
    figures
}

/// Pointing error against output angle: each mode's samples in the metrics window in its
/// colour, on an axis fitted to them (and the target), and the samples before the window
/// (the start-up transient, not judged) in light grey under them, marked off scale where
/// they leave the axis. With the uncompensated mode beside compensated ones, a second
/// panel shows the compensated modes' judged samples alone, on an axis fitted to them.
fn error_vs_angle(
    recorded: &[(CompensationMode, &TimeSeries, String)],
    window: Option<(f64, f64)>,
    span: (f64, f64),
    band: impl Fn() -> Vec<HBand>,
) -> Figure {
    let angle =
        |s: &TimeSeries| -> Vec<f64> { s.output_angle_rad.iter().map(|v| v * 1e3).collect() };
    let mut context = Vec::new();
    let mut judged = Vec::new();
    for (mode, s, label) in recorded {
        let (inside, outside) = split_at_window(&s.t_s, &s.pointing_error_mrad, window);
        let x = angle(s);
        if outside.iter().any(|v| v.is_finite()) {
            // One legend entry for the grey of every mode.
            let label = match (context.is_empty(), window) {
                (true, Some(w)) => not_judged_label(w, span).to_string(),
                _ => String::new(),
            };
            context.push(Series::line(label, x.clone(), outside).as_context());
        }
        let curve = Series::line(label.as_str(), x, inside).in_slot(mode_slot(*mode));
        judged.push((*mode, curve));
    }
    let title = match window {
        Some((from, _)) if !context.is_empty() => format!(
            "Pointing error against output angle, judged from {} s",
            crate::compact(from)
        ),
        _ => "Pointing error against output angle".to_string(),
    };
    let set_apart = !context.is_empty();
    let chart = |title: &str, series: Vec<Series>| Chart {
        title: title.into(),
        x_label: "output angle [mrad]".into(),
        y_label: "pointing error [mrad]".into(),
        series,
        bands: band(),
        ..Chart::default()
    };
    let compensated: Vec<Series> = judged
        .iter()
        .filter(|(m, _)| *m != CompensationMode::None)
        .map(|(_, s)| s.clone())
        .collect();
    let has_none = judged.iter().any(|(m, _)| *m == CompensationMode::None);
    // The grey first, so the judged curves are drawn over it.
    let every: Vec<Series> = context
        .into_iter()
        .chain(judged.into_iter().map(|(_, s)| s))
        .collect();
    if has_none && !compensated.is_empty() {
        // The uncompensated error sets the first panel's scale; the compensated modes,
        // judged against the target, need one of their own to be told apart.
        let first = if set_apart {
            "every mode, axis fitted to the judged samples"
        } else {
            "every mode"
        };
        let second = if set_apart {
            "compensated modes, judged samples only, axis fitted to them"
        } else {
            "compensated modes, axis fitted to them"
        };
        Figure::Panels {
            title,
            charts: vec![chart(first, every), chart(second, compensated)],
        }
    } else {
        let mut one = chart(&title, every);
        if set_apart {
            one.notes
                .push("axis fitted to the judged samples (the metrics window)".into());
        }
        Figure::Chart(one)
    }
}

/// The target as a grey line across the spectra's frequency span (a log axis
/// cannot shade a band down to zero).
pub fn target_line(spectra: &[&ErrorSpectrum], target_mrad: f64) -> Series {
    let top = spectra
        .iter()
        .filter_map(|s| s.frequency_hz.last().copied())
        .fold(0.0, f64::max);
    let bottom = spectra
        .iter()
        .filter_map(|s| s.frequency_hz.get(1).copied())
        .fold(f64::INFINITY, f64::min);
    Series::line(
        format!("target {target_mrad} mrad"),
        vec![bottom, top],
        vec![target_mrad, target_mrad],
    )
    .in_slot(7)
}

/// Welch PSD of the line-of-sight error (log-log) over cumulative RMS against frequency:
/// which frequencies the error lives at, and how much of the target each band uses.
fn spectrum_figure(result: &ClosedLoopResult, target_mrad: f64) -> Option<Figure> {
    let spectra: Vec<(String, usize, &ErrorSpectrum)> = result
        .modes
        .iter()
        // A mode that stopped has no spectrum of its own to show.
        .filter(|m| m.completion == Completion::Complete)
        .filter_map(|m| {
            m.spectrum
                .as_ref()
                .map(|s| (m.label(), mode_slot(m.mode), s))
        })
        .collect();
    (!spectra.is_empty()).then(|| Figure::Panels {
        title: "Line-of-sight error spectrum (metrics window)".into(),
        charts: spectrum_charts(&spectra, target_mrad),
    })
}

/// The two panels of a spectrum figure for curves `(label, palette slot, spectrum)`: the
/// PSD on log-log axes, and the cumulative RMS with the target as a line.
pub fn spectrum_charts(
    spectra: &[(String, usize, &ErrorSpectrum)],
    target_mrad: f64,
) -> Vec<Chart> {
    let series = |f: &dyn Fn(&ErrorSpectrum) -> Vec<f64>| -> Vec<Series> {
        spectra
            .iter()
            .map(|(label, slot, s)| {
                Series::line(label, s.frequency_hz.clone(), f(s)).in_slot(*slot)
            })
            .collect()
    };
    let mut cumulative = series(&|s| s.cumulative_rms_mrad.clone());
    cumulative.push(target_line(
        &spectra.iter().map(|x| x.2).collect::<Vec<_>>(),
        target_mrad,
    ));
    vec![
        Chart {
            title: "power spectral density (Welch, Hann, 50 % overlap)".into(),
            x_label: "frequency [Hz]".into(),
            y_label: "PSD [mrad^2/Hz]".into(),
            series: series(&|s| s.psd_mrad2_per_hz.clone()),
            log_x: true,
            log_y: true,
            ..Chart::default()
        },
        Chart {
            title: "cumulative RMS from 0 Hz".into(),
            x_label: "frequency [Hz]".into(),
            y_label: "RMS up to f [mrad]".into(),
            series: cumulative,
            log_x: true,
            log_y: true,
            ..Chart::default()
        },
    ]
}

/// Picks the `(x, y)` columns of a chart from a series.
type Columns = dyn Fn(&TimeSeries) -> (Vec<f64>, Vec<f64>);

/// Draw the closed-loop charts into `dir` (PNG and SVG each); returns the files.
pub fn plot_closed_loop(
    dir: &Path,
    result: &ClosedLoopResult,
    target_mrad: f64,
    command_unit: &str,
) -> Result<Vec<PathBuf>, PlotError> {
    use rayon::prelude::*;
    // Figures are independent files: drawn side by side on the cores.
    let drawn: Vec<Result<Vec<PathBuf>, PlotError>> =
        closed_loop_charts(result, target_mrad, command_unit)
            .into_par_iter()
            .map(|(stem, figure)| match figure {
                Figure::Chart(chart) => save_chart(&chart, &dir.join(stem)),
                Figure::Panels { title, charts } => save_panels(&title, &charts, &dir.join(stem)),
            })
            .collect();
    let mut files = Vec::new();
    for d in drawn {
        files.extend(d?);
    }
    Ok(files)
}

/// Write `error_budget.csv`: one row per mode and effect (the last row of a mode is the
/// rest with every listed effect off), with the total and the RSS repeated on each row so
/// a spreadsheet can group by mode.
pub fn write_budget(
    dir: &Path,
    budget: &crate::analysis::budget::ErrorBudget,
) -> Result<PathBuf, ReportError> {
    let path = dir.join("error_budget.csv");
    let csv_err = |e| ReportError::csv(&path, e);
    let mut w = csv::Writer::from_path(&path).map_err(csv_err)?;
    w.write_record([
        "mode",
        "effect",
        "rms_without_mrad",
        "contribution_mrad",
        "share_of_total_percent",
        "total_mrad",
        "rss_mrad",
        "status",
    ])
    .map_err(csv_err)?;
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
    for m in &budget.modes {
        for l in &m.lines {
            let share = m
                .total_mrad
                .zip(l.contribution_mrad)
                .filter(|(t, _)| *t > 0.0)
                .map(|(t, c)| 100.0 * c * c / (t * t));
            w.write_record([
                m.mode.name().to_string(),
                l.effect.map_or("rest", |e| e.name()).to_string(),
                opt(l.rms_without_mrad),
                opt(l.contribution_mrad),
                share.map_or(String::new(), |s| format!("{s:.2}")),
                opt(m.total_mrad),
                opt(m.rss_mrad),
                l.status.clone(),
            ])
            .map_err(csv_err)?;
        }
    }
    w.flush().map_err(|e| ReportError::io(&path, e))?;
    Ok(path)
}

/// The budget as a console table: per mode, each effect's contribution and share of the
/// mean square, the rest, the RSS against the total.
pub fn format_budget(budget: &crate::analysis::budget::ErrorBudget) -> String {
    let f = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.5}"));
    let mut out = String::from(
        "error budget (RMS line-of-sight error; contribution = sqrt(total^2 - without^2))\n",
    );
    for m in &budget.modes {
        out.push_str(&format!(
            "{:<12} {:<16} {:>16} {:>18} {:>8}\n",
            m.mode.name(),
            "effect off",
            "rms_without_mrad",
            "contribution_mrad",
            "share_%"
        ));
        for l in &m.lines {
            let share = m
                .total_mrad
                .zip(l.contribution_mrad)
                .filter(|(t, _)| *t > 0.0)
                .map_or("-".to_string(), |(t, c)| {
                    format!("{:.1}", 100.0 * c * c / (t * t))
                });
            out.push_str(&format!(
                "{:<12} {:<16} {:>16} {:>18} {:>8}{}\n",
                "",
                l.effect.map_or("rest (all off)", |e| e.name()),
                f(l.rms_without_mrad),
                f(l.contribution_mrad),
                share,
                if l.status == "ok" {
                    String::new()
                } else {
                    format!("  {}", l.status)
                }
            ));
        }
        out.push_str(&format!(
            "{:<12} {:<16} total {} mrad, RSS of the lines {} mrad\n",
            "",
            "",
            f(m.total_mrad),
            f(m.rss_mrad)
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each sample goes to exactly one side of the metrics window's edges, which belong to
    /// the window.
    #[test]
    fn samples_are_split_at_the_metrics_window() {
        let t = [0.0, 1.0, 2.0, 3.0, 4.0];
        let y = [5.0, 4.0, 3.0, 2.0, 1.0];
        let (judged, outside) = split_at_window(&t, &y, Some((2.0, 3.0)));
        let nan = f64::NAN;
        let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(p, q)| p.to_bits() == q.to_bits());
        assert!(same(&judged, &[nan, nan, 3.0, 2.0, nan]), "{judged:?}");
        assert!(same(&outside, &[5.0, 4.0, nan, nan, 1.0]), "{outside:?}");
        let (all, none) = split_at_window(&t, &y, None);
        assert_eq!(all, y.to_vec());
        assert!(none.iter().all(|v| v.is_nan()));
    }

    #[test]
    fn the_samples_not_judged_are_named_by_where_they_lie() {
        assert_eq!(not_judged_label((2.0, 20.0), (0.0, 20.0)), BEFORE_WINDOW);
        assert_eq!(not_judged_label((2.0, 10.0), (0.0, 20.0)), OUTSIDE_WINDOW);
    }
}
