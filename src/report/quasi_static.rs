//! Files and plots of the quasi-static and backlash studies.

use std::path::Path;

use serde_json::json;

use super::{csv_writer, ReportError};
use crate::physics::drive::DriveParams;
use crate::plot::{save_chart, save_panels, Chart, Series};
use crate::scenario::Scenario;
use crate::study::quasi_static::{model_name, BacklashResult, QsTrace};

/// Write `timeseries.csv` (long format, one row per model and sample, a `model` column) and
/// `profiles.csv` (exact breakpoints of the tension profiles).
pub fn write_tables(dir: &Path, traces: &[QsTrace]) -> Result<(), ReportError> {
    let path = dir.join("timeseries.csv");
    let mut w = csv_writer(&path)?;
    let header = [
        "model",
        "t_s",
        "theta_in_rad",
        "theta_out_rad",
        "load_nm",
        "torque_nm",
        "tension_upper_n",
        "tension_lower_n",
        "transmission_error_mrad",
        "slip_upper_drum_rad",
        "slip_upper_pulley_rad",
        "slip_lower_drum_rad",
        "slip_lower_pulley_rad",
    ];
    w.write_record(header)
        .map_err(|e| ReportError::csv(&path, e))?;
    for trace in traces {
        let name = model_name(trace.model);
        for s in &trace.samples {
            let row = [
                name.to_string(),
                format!("{}", s.t_s),
                format!("{}", s.theta_in_rad),
                format!("{}", s.theta_out_rad),
                format!("{}", s.load_nm),
                format!("{}", s.torque_nm),
                format!("{}", s.tension_upper_n),
                format!("{}", s.tension_lower_n),
                format!("{}", s.transmission_error_rad * 1e3),
                format!("{}", s.slip_angles_rad[0]),
                format!("{}", s.slip_angles_rad[1]),
                format!("{}", s.slip_angles_rad[2]),
                format!("{}", s.slip_angles_rad[3]),
            ];
            w.write_record(&row)
                .map_err(|e| ReportError::csv(&path, e))?;
        }
    }
    w.flush().map_err(|e| ReportError::io(&path, e))?;

    let path = dir.join("profiles.csv");
    let mut w = csv_writer(&path)?;
    w.write_record([
        "model",
        "t_s",
        "region",
        "elongation_um",
        "s_rad",
        "tension_n",
    ])
    .map_err(|e| ReportError::csv(&path, e))?;
    for trace in traces {
        for p in &trace.profiles {
            for (s, t) in &p.breakpoints {
                w.write_record([
                    model_name(trace.model).to_string(),
                    format!("{}", p.t_s),
                    p.region.to_string(),
                    format!("{}", p.elongation_m * 1e6),
                    format!("{s}"),
                    format!("{t}"),
                ])
                .map_err(|e| ReportError::csv(&path, e))?;
            }
        }
    }
    w.flush().map_err(|e| ReportError::io(&path, e))?;
    Ok(())
}

/// Write `summary.json`.
pub fn write_summary(
    dir: &Path,
    scenario: &Scenario,
    traces: &[QsTrace],
    warnings: &[String],
) -> Result<(), ReportError> {
    let models: Vec<_> = traces
        .iter()
        .map(|t| {
            let mut v = serde_json::to_value(t.figures()).unwrap_or_default();
            if let (Some(stop), Some(obj)) = (&t.stop, v.as_object_mut()) {
                obj.insert(
                    "stop".into(),
                    json!({ "t_s": stop.t_s, "fault": stop.fault.to_string() }),
                );
            }
            v
        })
        .collect();
    let complete = traces.iter().all(|t| t.stop.is_none());
    let simulated_s = traces
        .iter()
        .filter_map(|t| t.samples.last().map(|s| s.t_s))
        .fold(0.0, f64::max);
    super::write_summary(
        &dir.join("summary.json"),
        scenario,
        complete,
        &json!({
            "simulated_s": simulated_s,
            "models": models,
            "warnings": warnings,
        }),
    )
}

/// Plot the quasi-static study. Returns the files written.
pub fn plot(
    dir: &Path,
    drive: &DriveParams,
    traces: &[QsTrace],
) -> Result<Vec<std::path::PathBuf>, ReportError> {
    let mut files = Vec::new();
    let ic = drive.ratio();
    let col = |trace: &QsTrace, f: &dyn Fn(&crate::study::quasi_static::QsSample) -> f64| {
        trace.samples.iter().map(f).collect::<Vec<f64>>()
    };
    let Some(first) = traces.first() else {
        return Ok(files);
    };
    let t = col(first, &|s| s.t_s);

    // Angles and error over time.
    let angles = Chart {
        title: "Input and output angles".into(),
        x_label: "time [s]".into(),
        y_label: "angle [mrad]".into(),
        series: vec![
            Series::line(
                "theta_in / ic",
                t.clone(),
                col(first, &|s| s.theta_in_rad / ic * 1e3),
            ),
            Series::line(
                format!("theta_out ({})", model_name(first.model)),
                t.clone(),
                col(first, &|s| s.theta_out_rad * 1e3),
            ),
        ],
        ..Chart::default()
    };
    let error = Chart {
        title: "Transmission error".into(),
        x_label: "time [s]".into(),
        y_label: "error [mrad]".into(),
        series: traces
            .iter()
            .map(|tr| {
                Series::line(
                    model_name(tr.model),
                    col(tr, &|s| s.t_s),
                    col(tr, &|s| s.transmission_error_rad * 1e3),
                )
            })
            .collect(),
        ..Chart::default()
    };
    let load = Chart {
        title: "Transmitted torque".into(),
        x_label: "time [s]".into(),
        y_label: "torque M [N m]".into(),
        series: vec![Series::line(
            "M = -Ml",
            t.clone(),
            col(first, &|s| s.torque_nm),
        )],
        ..Chart::default()
    };
    files.extend(save_panels(
        "Quasi-static drive: angles, transmission error and load",
        &[angles, error, load],
        &dir.join("angles_error"),
    )?);

    // Error against output angle and against load: the hysteresis loops.
    for (stem, title, x_label, xf) in [
        (
            "error_vs_output",
            "Transmission error against output angle",
            "output angle [mrad]",
            (&|s: &crate::study::quasi_static::QsSample| s.theta_out_rad * 1e3)
                as &dyn Fn(&crate::study::quasi_static::QsSample) -> f64,
        ),
        (
            "error_vs_load",
            "Transmission error against transmitted torque",
            "torque M [N m]",
            &|s: &crate::study::quasi_static::QsSample| s.torque_nm,
        ),
    ] {
        let chart = Chart {
            title: title.into(),
            x_label: x_label.into(),
            y_label: "transmission error [mrad]".into(),
            series: traces
                .iter()
                .map(|tr| {
                    Series::line(
                        model_name(tr.model),
                        col(tr, xf),
                        col(tr, &|s| s.transmission_error_rad * 1e3),
                    )
                })
                .collect(),
            ..Chart::default()
        };
        files.extend(save_chart(&chart, &dir.join(stem))?);
    }

    // Span tensions.
    let mut series = Vec::new();
    for tr in traces {
        let name = model_name(tr.model);
        series.push(Series::line(
            format!("upper ({name})"),
            col(tr, &|s| s.t_s),
            col(tr, &|s| s.tension_upper_n),
        ));
        series.push(Series::line(
            format!("lower ({name})"),
            col(tr, &|s| s.t_s),
            col(tr, &|s| s.tension_lower_n),
        ));
    }
    files.extend(save_chart(
        &Chart {
            title: "Free-span tensions".into(),
            x_label: "time [s]".into(),
            y_label: "tension [N]".into(),
            series,
            ..Chart::default()
        },
        &dir.join("tensions"),
    )?);

    // Tension profiles of the memory model at the requested instants.
    if let Some(tr) = traces.iter().find(|t| !t.profiles.is_empty()) {
        let regions = ["upper_drum", "upper_pulley", "lower_drum", "lower_pulley"];
        let charts: Vec<Chart> = regions
            .iter()
            .map(|region| {
                let snaps: Vec<_> = tr.profiles.iter().filter(|p| p.region == *region).collect();
                // Show the part of the wrap where anything happened, not the idle plateau.
                let active = snaps
                    .iter()
                    .flat_map(|p| p.breakpoints.iter().rev().skip(1).map(|b| b.0))
                    .fold(0.0f64, f64::max);
                let wrap = snaps
                    .iter()
                    .filter_map(|p| p.breakpoints.last().map(|b| b.0))
                    .fold(0.0f64, f64::max);
                let x_max = (1.3 * active).clamp(1e-3, wrap.max(1e-3));
                Chart {
                    title: format!(
                        "{} wrap ({})",
                        region.replace('_', " "),
                        model_name(tr.model)
                    ),
                    x_label: "wrap angle from contact point [rad]".into(),
                    y_label: "tension [N]".into(),
                    series: snaps
                        .iter()
                        .map(|p| {
                            let (s, tn) = densify(&p.breakpoints, x_max);
                            Series::line(format!("t = {:.2} s", p.t_s), s, tn)
                        })
                        .collect(),
                    x_range: Some((0.0, x_max)),
                    ..Chart::default()
                }
            })
            .collect();
        files.extend(save_panels(
            "Tension profiles along the wraps",
            &charts,
            &dir.join("profiles"),
        )?);
    }
    Ok(files)
}

/// Sample an exact log-linear profile finely enough to draw its exponential segments.
fn densify(breakpoints: &[(f64, f64)], x_max: f64) -> (Vec<f64>, Vec<f64>) {
    let mut s = Vec::new();
    let mut t = Vec::new();
    for w in breakpoints.windows(2) {
        let ((s0, t0), (s1, t1)) = (w[0], w[1]);
        if s0 > x_max {
            break;
        }
        let s1c = s1.min(x_max);
        let n = 24;
        for i in 0..n {
            let x = s0 + (s1c - s0) * i as f64 / n as f64;
            let frac = if s1 > s0 { (x - s0) / (s1 - s0) } else { 0.0 };
            s.push(x);
            t.push(t0 * (t1 / t0).powf(frac));
        }
        if s1 >= x_max {
            let frac = if s1 > s0 { (s1c - s0) / (s1 - s0) } else { 0.0 };
            s.push(s1c);
            t.push(t0 * (t1 / t0).powf(frac));
        }
    }
    if let (Some(&last), true) = (breakpoints.last(), s.is_empty()) {
        s.push(0.0);
        t.push(last.1);
    }
    (s, t)
}

/// Write the single-case backlash result.
pub fn write_backlash(
    dir: &Path,
    scenario: &Scenario,
    result: &BacklashResult,
    warnings: &[String],
) -> Result<(), ReportError> {
    super::write_summary(
        &dir.join("summary.json"),
        scenario,
        true,
        &json!({
            "result": result,
            "free_span_backlash_mrad": scenario.backlash.as_ref().map(|b| free_span_backlash_mrad(&scenario.drive, b.load_nm)),
            "warnings": warnings,
        }),
    )
}

/// Reversal backlash of the free spans alone, `Lf*M/(ro^2*G)`, mrad: the limit of the
/// backlash at infinite preload, where the slip zones shrink to nothing.
pub fn free_span_backlash_mrad(drive: &DriveParams, load_nm: f64) -> f64 {
    drive.free_span_m() * load_nm / (drive.drum_radius_m.powi(2) * drive.cable_modulus_n) * 1e3
}
