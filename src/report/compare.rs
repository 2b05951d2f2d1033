//! Files of a design comparison: `compare.csv` (one row per design), `summary.json`, each
//! design's own run files under `designs/<name>/`, and overlay figures with one fixed
//! colour per design (its position on the command line).

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::analysis::verdict::Verdict;
use crate::closed_loop::{CompensationMode, Completion, ModeResult};
use crate::plot::{save_panels, Chart, HBand, PlotError, Series};
use crate::report::ReportError;
use crate::scenario::Scenario;

/// One design's outcome.
#[derive(Clone, Debug)]
pub struct DesignOutcome {
    /// Name (scenario name, or the name given with its overrides).
    pub name: String,
    /// What it is: the scenario file or the overrides applied.
    pub description: String,
    /// The resolved scenario.
    pub scenario: Scenario,
    /// The mode compared.
    pub mode: CompensationMode,
    /// Its result.
    pub result: ModeResult,
    /// The design's verdict (margins over the operating range, pointing of `mode`).
    pub verdict: Verdict,
    /// Pointing target, mrad.
    pub target_mrad: f64,
}

impl DesignOutcome {
    /// Meets every requirement: its verdict.
    pub fn passes(&self) -> bool {
        self.verdict.passes
    }
}

#[derive(Serialize)]
struct DesignSummary<'a> {
    name: &'a str,
    description: &'a str,
    mode: &'static str,
    passes: bool,
    rms_mrad: Option<f64>,
    peak_mrad: Option<f64>,
    los: Option<&'a crate::metrics::los::LosMetrics>,
    verdict: &'a Verdict,
    completion: &'a Completion,
    scenario: &'a Scenario,
}

fn finished(d: &DesignOutcome) -> bool {
    d.result.completion == Completion::Complete && d.result.metrics.samples > 0
}

/// Write `compare.csv`, `summary.json` and each design's run files.
pub fn write_compare(dir: &Path, designs: &[DesignOutcome]) -> Result<Vec<PathBuf>, ReportError> {
    let mut written = Vec::new();
    let path = dir.join("compare.csv");
    let csv_err = |e| ReportError::csv(&path, e);
    let mut w = crate::report::csv_writer(&path)?;
    w.write_record([
        "design",
        "mode",
        "status",
        "passes",
        "rms_mrad",
        "peak_mrad",
        "jitter_max_mrad",
        "jitter_p95_mrad",
        "exposure_s",
        "phase_margin_deg",
        "gain_margin_up_db",
        "gain_margin_down_db",
        "ms",
        "failing",
        "description",
    ])
    .map_err(csv_err)?;
    let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.6e}"));
    for d in designs {
        let ok = finished(d);
        let los = d.result.los.as_ref().filter(|_| ok);
        w.write_record([
            d.name.clone(),
            d.mode.name().to_string(),
            d.result.completion.status().to_string(),
            d.passes().to_string(),
            opt(ok.then_some(d.result.metrics.rms_mrad)),
            opt(ok.then_some(d.result.metrics.peak_mrad)),
            opt(los.and_then(|l| l.jitter_rms_max_mrad)),
            opt(los.and_then(|l| l.jitter_rms_p95_mrad)),
            opt(los.map(|l| l.exposure_s)),
            opt(d.verdict.worst_value("phase_margin")),
            opt(d.verdict.worst_value("gain_margin_up")),
            opt(d.verdict.worst_value("gain_margin_down")),
            opt(d.verdict.worst_value("sensitivity_peak")),
            d.verdict.reasons().join("; "),
            d.description.clone(),
        ])
        .map_err(csv_err)?;
    }
    w.flush().map_err(|e| ReportError::io(&path, e))?;
    written.push(path);
    let summaries: Vec<DesignSummary> = designs
        .iter()
        .map(|d| DesignSummary {
            name: &d.name,
            description: &d.description,
            mode: d.mode.name(),
            passes: d.passes(),
            rms_mrad: finished(d).then_some(d.result.metrics.rms_mrad),
            peak_mrad: finished(d).then_some(d.result.metrics.peak_mrad),
            los: d.result.los.as_ref().filter(|_| finished(d)),
            verdict: &d.verdict,
            completion: &d.result.completion,
            scenario: &d.scenario,
        })
        .collect();
    let path = dir.join("summary.json");
    let value = serde_json::json!({
        "program_version": env!("CARGO_PKG_VERSION"),
        "complete": designs.iter().all(|d| d.result.completion == Completion::Complete),
        "all_pass": designs.iter().all(DesignOutcome::passes),
        "designs": summaries,
    });
    crate::report::write_json(&path, &value)?;
    written.push(path);
    for d in designs {
        written.extend(crate::report::closed_loop::write_closed_loop_outputs(
            &design_dir(dir, d),
            &d.scenario,
            &design_result(d),
            Some(&d.verdict),
        )?);
    }
    Ok(written)
}

/// Where a design's own run files go: `designs/<name>/`.
fn design_dir(dir: &Path, d: &DesignOutcome) -> PathBuf {
    dir.join("designs").join(&d.name)
}

/// A design's outcome as the result of a run of its one mode.
fn design_result(d: &DesignOutcome) -> crate::closed_loop::ClosedLoopResult {
    crate::closed_loop::ClosedLoopResult {
        modes: vec![d.result.clone()],
        duration_s: d
            .scenario
            .closed_loop
            .as_ref()
            .map_or(0.0, |c| c.duration_s),
        complete: d.result.completion == Completion::Complete,
    }
}

/// Each design's own figures under `designs/<name>/`, the same as `run` draws for it.
pub fn plot_designs(dir: &Path, designs: &[DesignOutcome]) -> Result<Vec<PathBuf>, PlotError> {
    let mut files = Vec::new();
    for d in designs {
        files.extend(crate::report::closed_loop::plot_closed_loop(
            &design_dir(dir, d),
            &design_result(d),
            d.target_mrad,
            crate::report::closed_loop::command_unit(&d.scenario),
        )?);
    }
    Ok(files)
}

/// The comparison table for the terminal.
pub fn format_compare(designs: &[DesignOutcome]) -> String {
    let f = |v: Option<f64>, p: usize| v.map_or("-".to_string(), |v| format!("{v:.p$}"));
    let width = designs
        .iter()
        .map(|d| d.name.len())
        .max()
        .unwrap_or(6)
        .max(6);
    let mut out = format!(
        "{:<width$} {:<10} {:>9} {:>9} {:>11} {:>7} {:>8} {:>10} {:>5} {:>7}  {}\n",
        "design",
        "mode",
        "rms_mrad",
        "peak_mrad",
        "jitter_mrad",
        "PM_deg",
        "GM_up_dB",
        "GM_down_dB",
        "Ms",
        "verdict",
        "status"
    );
    for d in designs {
        let ok = finished(d);
        // The whole stop message is printed as a warning; the row names it.
        let mut status = match &d.result.completion {
            Completion::Complete => "complete".to_string(),
            Completion::Incomplete { kind, time_s, .. } => {
                format!(
                    "STOPPED: {} at t = {} s",
                    kind.name(),
                    crate::readable(*time_s)
                )
            }
        };
        if d.result.completion == Completion::Complete {
            if let crate::metrics::limit_cycle::LimitCycle::Detected {
                amplitude_mrad,
                frequency_hz,
                ..
            } = d.result.limit_cycle
            {
                status.push_str(&format!(
                    "; LIMIT CYCLE {amplitude_mrad:.3} mrad at {frequency_hz:.1} Hz"
                ));
            }
        }
        out.push_str(&format!(
            "{:<width$} {:<10} {:>9} {:>9} {:>11} {:>7} {:>8} {:>10} {:>5} {:>7}  {}\n",
            d.name,
            d.mode.name(),
            f(ok.then_some(d.result.metrics.rms_mrad), 4),
            f(ok.then_some(d.result.metrics.peak_mrad), 4),
            f(
                d.result
                    .los
                    .as_ref()
                    .filter(|_| ok)
                    .and_then(|l| l.jitter_rms_max_mrad),
                4
            ),
            f(d.verdict.worst_value("phase_margin"), 1),
            f(d.verdict.worst_value("gain_margin_up"), 1),
            f(d.verdict.worst_value("gain_margin_down"), 1),
            f(d.verdict.worst_value("sensitivity_peak"), 2),
            if d.passes() { "PASS" } else { "FAIL" },
            status
        ));
    }
    out.push_str(
        "(margins: the worst over the operating range; a dash: none, as for an unstable loop)\n",
    );
    for d in designs {
        out.push_str(&format!("\ndesign {}:\n{}", d.name, d.verdict.table()));
    }
    out
}

/// Overlay figures: line-of-sight error against time (whole run, and the metrics window
/// on an axis fitted to the designs), and the error's PSD over its cumulative RMS; then
/// each design's own figures ([`plot_designs`]). Design `i` takes palette slot `i` in
/// every overlay figure.
pub fn plot_compare(dir: &Path, designs: &[DesignOutcome]) -> Result<Vec<PathBuf>, PlotError> {
    let mut files = plot_overlays(dir, designs)?;
    files.extend(plot_designs(dir, designs)?);
    Ok(files)
}

/// The overlay figures of [`plot_compare`].
fn plot_overlays(dir: &Path, designs: &[DesignOutcome]) -> Result<Vec<PathBuf>, PlotError> {
    let target = designs.first().map_or(0.1, |d| d.target_mrad);
    let band = || {
        vec![HBand {
            lo: -target,
            hi: target,
            label: format!("target +-{target} mrad"),
        }]
    };
    let error: Vec<Series> = designs
        .iter()
        .enumerate()
        .filter_map(|(i, d)| {
            let s = d.result.series.as_ref()?;
            Some(Series::line(&d.name, s.t_s.clone(), s.pointing_error_mrad.clone()).in_slot(i))
        })
        .collect();
    let mut files = Vec::new();
    if !error.is_empty() {
        let window = designs
            .iter()
            .find(|d| d.result.metrics.samples > 0)
            .map(|d| (d.result.metrics.window_s[0], d.result.metrics.window_s[1]));
        let span = error
            .iter()
            .flat_map(|s| s.x.iter().copied().filter(|t| t.is_finite()))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| {
                (a.min(t), b.max(t))
            });
        // The second panel is scaled to the designs that pass, so they can be told apart
        // (to every design when none passes).
        let any_pass = designs.iter().any(DesignOutcome::passes);
        let largest = designs
            .iter()
            .filter(|d| !any_pass || d.passes())
            .filter_map(|d| {
                let s = d.result.series.as_ref()?;
                let (a, b) = window?;
                Some(
                    s.t_s
                        .iter()
                        .zip(&s.pointing_error_mrad)
                        .filter(|(t, e)| **t >= a && **t <= b && e.is_finite())
                        .fold(0.0_f64, |m, (_, e)| m.max(e.abs())),
                )
            })
            .fold(0.0_f64, f64::max);
        // Only the designs that pass there, each in its own colour still.
        let passing: Vec<Series> = designs
            .iter()
            .enumerate()
            .filter(|(_, d)| !any_pass || d.passes())
            .filter_map(|(i, d)| {
                let s = d.result.series.as_ref()?;
                Some(Series::line(&d.name, s.t_s.clone(), s.pointing_error_mrad.clone()).in_slot(i))
            })
            .collect();
        let mut fitted = Chart {
            title: if any_pass {
                "metrics window, the designs that pass".into()
            } else {
                "metrics window".into()
            },
            x_label: "time [s]".into(),
            y_label: "line-of-sight error [mrad]".into(),
            series: passing,
            bands: band(),
            ..Chart::default()
        };
        if let Some((a, b)) = window.filter(|(a, b)| b > a) {
            let y = (1.1 * largest).max(1.2 * target);
            fitted.x_range = Some((a, b));
            fitted.y_range = Some((-y, y));
        }
        files.extend(save_panels(
            "Line-of-sight error by design",
            &[
                Chart {
                    title: "whole run (scale set by the metrics window)".into(),
                    x_label: "time [s]".into(),
                    y_label: "line-of-sight error [mrad]".into(),
                    x_shades: crate::report::closed_loop::window_shades(window, span),
                    y_fit_x: window,
                    series: error,
                    bands: band(),
                    ..Chart::default()
                },
                fitted,
            ],
            &dir.join("compare_error"),
        )?);
    }
    let spectra: Vec<(String, usize, &crate::metrics::los::ErrorSpectrum)> = designs
        .iter()
        .enumerate()
        // A design that stopped has no spectrum of its own to show.
        .filter(|(_, d)| d.result.completion == Completion::Complete)
        .filter_map(|(i, d)| d.result.spectrum.as_ref().map(|s| (d.name.clone(), i, s)))
        .collect();
    if !spectra.is_empty() {
        files.extend(save_panels(
            "Line-of-sight error spectrum by design (metrics window)",
            &crate::report::closed_loop::spectrum_charts(&spectra, target),
            &dir.join("compare_psd"),
        )?);
    }
    Ok(files)
}
