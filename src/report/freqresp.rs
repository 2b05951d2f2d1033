//! Files and figures of a frequency-response measurement: one CSV and one JSON per
//! amplitude, all amplitudes in `freqresp.csv`, `summary.json`, Bode and Nyquist plots.

use std::path::{Path, PathBuf};

use nalgebra::Complex;

use super::{csv_writer, write_json, write_summary, ReportError};
use crate::analysis::freqresp::{
    exact_transfer, rejection_db, AmplitudeResponse, FreqPoint, FreqResponse, LoopPoint,
    PredictedCycle,
};
use crate::analysis::linear::LinearLoop;
use crate::plot::{
    family_colour, save_annotated, save_panels, AnnotatedFigure, Arrowhead, Chart, Dash, Mark,
    Series, Shape, Trace, REFERENCE_RGB,
};
use crate::scenario::Scenario;

const COLUMNS: [&str; 24] = [
    "amplitude",
    "amplitude_unit",
    "requested_hz",
    "frequency_hz",
    "refinement",
    "status",
    "mag_db",
    "phase_deg",
    "re",
    "im",
    "exact_mag_db",
    "exact_phase_deg",
    "loop_gain_mag_db",
    "loop_gain_phase_deg",
    "sensitivity_mag_db",
    "complementary_mag_db",
    "distortion_percent",
    "output_amplitude_mrad",
    "rejection_db",
    "reference_rejection_db",
    "axis",
    "held_fraction",
    "uncertainty_percent",
    "failure",
];

fn db(c: Complex<f64>) -> f64 {
    20.0 * c.norm().log10()
}

fn num(v: Option<f64>) -> String {
    v.map_or_else(String::new, |v| format!("{v}"))
}

fn row(point: LoopPoint, a: &AmplitudeResponse, p: &FreqPoint) -> Vec<String> {
    let r = p.response;
    // Rejection is the base-motion point's figure; elsewhere the columns stay empty.
    let base = point == LoopPoint::BaseMotion;
    let l = p.loop_gain;
    let one = Complex::from(1.0);
    vec![
        format!("{}", a.amplitude),
        a.unit.clone(),
        format!("{}", p.requested_hz),
        format!("{}", p.frequency_hz),
        p.refinement.to_string(),
        if p.unresolved() {
            "unresolved"
        } else if p.stopped() {
            "failed"
        } else {
            "ok"
        }
        .to_string(),
        num(r.map(db)),
        num(r.map(|r| r.arg().to_degrees())),
        num(r.map(|r| r.re)),
        num(r.map(|r| r.im)),
        format!("{}", db(p.exact)),
        format!("{}", p.exact.arg().to_degrees()),
        num(l.map(db)),
        num(l.map(|l| l.arg().to_degrees())),
        num(l.map(|l| db((one + l).inv()))),
        num(l.map(|l| db(l / (one + l)))),
        num(p.distortion_percent),
        num(p.output_amplitude_mrad),
        num(r.filter(|_| base).map(rejection_db)),
        num(base.then(|| rejection_db(p.exact))),
        p.axis.map_or_else(String::new, |a| a.name().to_string()),
        num(p.held_fraction),
        num(p.uncertainty_percent),
        p.failure.clone().unwrap_or_default(),
    ]
}

fn write_rows(path: &Path, rows: &[Vec<String>]) -> Result<(), ReportError> {
    let mut w = csv_writer(path)?;
    w.write_record(COLUMNS)
        .map_err(|e| ReportError::csv(path, e))?;
    for r in rows {
        w.write_record(r).map_err(|e| ReportError::csv(path, e))?;
    }
    w.flush().map_err(|e| ReportError::io(path, e))
}

/// Writes `freqresp.csv` (every amplitude), `amplitude_<k>.csv` and `.json` per amplitude
/// (k from 1, in the order given) and `summary.json`.
/// `verdict` is the design's, written beside the measurement as every command writes it.
pub fn write_outputs(
    dir: &Path,
    scenario: &Scenario,
    r: &FreqResponse,
    verdict: &crate::analysis::verdict::Verdict,
) -> Result<(), ReportError> {
    let mut all = Vec::new();
    for (k, a) in r.amplitudes.iter().enumerate() {
        let rows: Vec<Vec<String>> = a.points.iter().map(|p| row(r.point, a, p)).collect();
        write_rows(&dir.join(format!("amplitude_{}.csv", k + 1)), &rows)?;
        let json = serde_json::to_value(a).map_err(|e| ReportError::Encode {
            path: dir.join(format!("amplitude_{}.json", k + 1)),
            message: e.to_string(),
        })?;
        write_json(&dir.join(format!("amplitude_{}.json", k + 1)), &json)?;
        all.extend(rows);
    }
    write_rows(&dir.join("freqresp.csv"), &all)?;
    let amplitudes: Vec<serde_json::Value> = r
        .amplitudes
        .iter()
        .map(|a| {
            serde_json::json!({
                "amplitude": a.amplitude,
                "unit": a.unit,
                "passes": r.verdict().map(|_| a.passes()),
                "shortfalls": a.shortfalls,
                "unresolved": a.unresolved,
                "base_rejection": a.base_rejection,
                "slew_rate_rad_s": a.slew_rate_rad_s,
                "axis": a.axis,
                "axis_effect": a.axis.map(|m| m.effect()),
                "axis_frequencies": a.axis_frequencies,
                "frequencies": a.points.len(),
                "failed_frequencies": a
                    .points
                    .iter()
                    .filter(|p| p.stopped())
                    .count(),
                "unresolved_frequencies": a.points.iter().filter(|p| p.unresolved()).count(),
                "margins": a.margins,
            })
        })
        .collect();
    let summary = dir.join("summary.json");
    let encoded_verdict = serde_json::to_value(verdict).map_err(|e| ReportError::Encode {
        path: summary.clone(),
        message: e.to_string(),
    })?;
    write_summary(
        &summary,
        scenario,
        r.complete(),
        &serde_json::json!({
            "passes": verdict.passes,
            "verdict": encoded_verdict,
            "freqresp": {
                "point": r.point,
                "transfer": r.transfer,
                "operating_point": r.operating.operating_point,
                "operating_point_reason": r.operating.reason,
                "slew_rate_automatic": r.operating.slew_rate_automatic,
                "slew_travel_rad": r.operating.travel_rad,
                "passes": r.amplitudes.iter().all(AmplitudeResponse::passes),
                "amplitudes": amplitudes,
                "exact_linear_reference": r.exact_margins,
                "reference_cable": r.reference_cable,
                "limit_cycles": r.limit_cycles,
                "runs": r.runs,
                "simulated_s": r.simulated_s,
            }
        }),
    )
}

/// Phase in degrees, unwrapped along the series so a curve does not jump by 360 deg.
pub(super) fn unwrapped(phases_deg: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for p in phases_deg {
        // The first point on the branch (-360, 0] (lag is what loops have), the rest
        // continuous from it.
        let v = match out.last() {
            Some(&prev) => p - 360.0 * ((p - prev) / 360.0).round(),
            None if p > 0.0 => p - 360.0,
            None => p,
        };
        out.push(v);
    }
    out
}

/// Bode plot (magnitude and phase of the measured transfer, one curve per amplitude, the
/// exact linear reference as a line) and, when the loop gain is known, a Nyquist plot of
/// it near -1 with the sensitivity requirement's circle `|1 + L| = 1/max_ms`. Measured
/// values are markers only (nothing was measured between them); failed frequencies are
/// left out (they are in the CSV, marked).
pub fn plot(
    dir: &Path,
    r: &FreqResponse,
    lin: &LinearLoop,
    max_ms: f64,
) -> Result<Vec<PathBuf>, ReportError> {
    let ok = |a: &AmplitudeResponse| -> Vec<(f64, Complex<f64>, Option<Complex<f64>>)> {
        a.points
            .iter()
            .filter_map(|p| p.response.map(|c| (p.frequency_hz, c, p.loop_gain)))
            .collect()
    };
    let (lo, hi) = r
        .amplitudes
        .iter()
        .flat_map(|a| a.points.iter().map(|p| p.frequency_hz))
        .fold((f64::INFINITY, 0.0_f64), |(lo, hi), f| {
            (lo.min(f), hi.max(f))
        });
    let mut written = Vec::new();
    if !(lo.is_finite() && hi > lo) {
        return Ok(written);
    }
    let dense: Vec<f64> = (0..300)
        .map(|i| lo * (hi / lo).powf(i as f64 / 299.0))
        .collect();
    let exact: Vec<Complex<f64>> = dense
        .iter()
        .map(|&f| exact_transfer(lin, r.point, f))
        .collect();
    let mut mag = Chart {
        title: format!("|{}| against frequency", r.transfer),
        x_label: "frequency [Hz]".into(),
        y_label: format!("|{}| [dB]", r.transfer),
        log_x: true,
        ..Chart::default()
    };
    let mut phase = Chart {
        title: format!("phase of {}", r.transfer),
        x_label: "frequency [Hz]".into(),
        y_label: "phase [deg]".into(),
        log_x: true,
        ..Chart::default()
    };
    // Amplitudes in ascending order along one colour ramp, so the trend with amplitude
    // reads off the figure; the exact reference in black.
    let mut order: Vec<usize> = (0..r.amplitudes.len()).collect();
    order.sort_by(|&i, &j| {
        r.amplitudes[i]
            .amplitude
            .total_cmp(&r.amplitudes[j].amplitude)
    });
    let colour = |k: usize| {
        let rank = order.iter().position(|&i| i == k).unwrap_or(k);
        family_colour(rank, r.amplitudes.len())
    };
    for (k, a) in r.amplitudes.iter().enumerate() {
        let pts = ok(a);
        let label = format!("{} {}", a.amplitude, a.unit);
        let f: Vec<f64> = pts.iter().map(|p| p.0).collect();
        mag.series.push(
            Series::points(
                label.clone(),
                f.clone(),
                pts.iter().map(|p| db(p.1)).collect(),
            )
            .in_rgb(colour(k)),
        );
        phase.series.push(
            Series::points(
                label,
                f,
                unwrapped(pts.iter().map(|p| p.1.arg().to_degrees())),
            )
            .in_rgb(colour(k)),
        );
    }
    // The reference first, so the measured markers are drawn over it.
    mag.series.insert(
        0,
        Series::line(
            "exact linear reference",
            dense.clone(),
            exact.iter().map(|c| db(*c)).collect(),
        )
        .in_rgb(REFERENCE_RGB),
    );
    phase.series.insert(
        0,
        Series::line(
            "exact linear reference",
            dense.clone(),
            unwrapped(exact.iter().map(|c| c.arg().to_degrees())),
        )
        .in_rgb(REFERENCE_RGB),
    );
    let title = format!(
        "{} at {}, {} amplitude(s) simulated",
        r.transfer,
        r.point.name(),
        r.amplitudes.len()
    );
    written.extend(save_panels(&title, &[mag, phase], &dir.join("bode"))?);
    if r.point.gives_loop_gain() {
        let mut ny = super::margins::nyquist_plane(max_ms);
        let exact_l: Vec<Complex<f64>> = dense.iter().map(|&f| lin.loop_gain(f)).collect();
        ny.traces.push(Trace::line(
            "exact linear reference",
            exact_l.iter().map(|c| c.re).collect(),
            exact_l.iter().map(|c| c.im).collect(),
            REFERENCE_RGB,
            Dash::Solid,
        ));
        for k in (1..dense.len()).step_by(25) {
            ny.arrows.push(Arrowhead {
                at: (exact_l[k].re, exact_l[k].im),
                from: (exact_l[k - 1].re, exact_l[k - 1].im),
                rgb: REFERENCE_RGB,
            });
        }
        // Measured points only: nothing was measured between them.
        for (k, a) in r.amplitudes.iter().enumerate() {
            let pts = ok(a);
            let l: Vec<Complex<f64>> = pts.iter().filter_map(|p| p.2).collect();
            ny.traces.push(Trace {
                width: 0,
                marker: Some(Shape::Circle),
                ..Trace::line(
                    format!("measured, {} {}", a.amplitude, a.unit),
                    l.iter().map(|c| c.re).collect(),
                    l.iter().map(|c| c.im).collect(),
                    colour(k),
                    Dash::Solid,
                )
            });
            // Measured points of the first amplitude named by their frequency, but only
            // where no named point is close by (labels would overprint).
            if k == 0 {
                let mut named: Vec<Complex<f64>> = Vec::new();
                for p in pts.iter() {
                    if let Some(c) = p.2 {
                        if named.iter().any(|n| (n - c).norm() < 0.25) {
                            continue;
                        }
                        named.push(c);
                        ny.marks.push(Mark {
                            x: c.re,
                            y: c.im,
                            shape: Shape::Circle,
                            rgb: colour(k),
                            size: 4,
                            label: String::new(),
                            text: format!("{} Hz", crate::significant(p.0, 3)),
                            text_offset: (8, -10),
                        });
                    }
                }
            }
        }
        ny.marks.push(Mark {
            x: -1.0,
            y: 0.0,
            shape: Shape::Cross,
            rgb: [214, 39, 40],
            size: 7,
            label: "critical point -1".into(),
            text: String::new(),
            text_offset: (0, 0),
        });
        let fig = AnnotatedFigure {
            title: "Nyquist plot of the loop gain L near the critical point".into(),
            panels: vec![ny],
            notes: vec![
                "Dots: the measured loop gain at each injected frequency (some labelled in Hz); nothing is drawn between them. Line: the exact linear reference, arrows towards rising frequency.".into(),
            ],
            panel_height: 820,
        };
        written.extend(save_annotated(&fig, &dir.join("nyquist"))?);
    }
    Ok(written)
}

/// The console table: per amplitude, the estimated margins beside the exact reference's;
/// for base motion, the rejection per frequency beside the exact reference's.
pub fn format_table(r: &FreqResponse) -> String {
    if r.point == LoopPoint::BaseMotion {
        return format_rejection_table(r);
    }
    let opt = |v: Option<f64>, d: usize| v.map_or_else(|| "-".to_string(), |v| format!("{v:.d$}"));
    let e = &r.exact_margins;
    let o = &r.operating;
    let mut t = match o.operating_point {
        crate::analysis::freqresp::OperatingPoint::Rest => {
            format!("operating point: rest ({})\n", o.reason)
        }
        crate::analysis::freqresp::OperatingPoint::Slewing => format!(
            "operating point: slewing at a constant output rate under the injection ({}); rate {} per amplitude, up to {} rad of output travel in one run\n",
            o.reason,
            if o.slew_rate_automatic {
                "chosen as twice the largest output velocity of the injection on the exact linear reference (closed_loop.freqresp.slew_rate_rad_s unset)"
            } else {
                "set by closed_loop.freqresp.slew_rate_rad_s"
            },
            crate::significant(o.travel_rad, 3)
        ),
    };
    t.push_str(&format!(
        "{:<22} {:>9} {:>9} {:>9} {:>9} {:>9} {:>7} {:>9} {:>8} {:>12} {:>6}\n",
        "amplitude",
        "PM_deg",
        "fc_hz",
        "GM_db",
        "f180_hz",
        "GMlow_db",
        "Ms",
        "BW_hz",
        "THDmax%",
        "axis",
        "passes"
    ));
    for a in &r.amplitudes {
        let thd = a
            .points
            .iter()
            .filter_map(|p| p.distortion_percent)
            .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))));
        let unresolved = a.points.iter().filter(|p| p.unresolved()).count();
        let failed = a.points.iter().filter(|p| p.stopped()).count();
        let counts: Vec<String> = [(failed, "failed"), (unresolved, "unresolved")]
            .iter()
            .filter(|(n, _)| *n > 0)
            .map(|(n, what)| {
                let noun = if *n == 1 { "frequency" } else { "frequencies" };
                format!("{n} {noun} {what}")
            })
            .collect();
        let m = a.margins.clone().unwrap_or_default();
        t.push_str(&format!(
            "{:<22} {:>9} {:>9} {:>9} {:>9} {:>9} {:>7} {:>9} {:>8} {:>12} {:>6}{}\n",
            format!("{} {}", a.amplitude, a.unit),
            opt(m.phase_margin_deg, 1),
            opt(m.crossover_hz, 1),
            opt(m.gain_margin_db, 2),
            opt(m.phase_crossover_hz, 1),
            opt(m.lower_gain_margin_db, 2),
            opt(m.ms, 3),
            opt(m.bandwidth_hz, 1),
            opt(thd, 1),
            a.axis.map_or("-", |m| m.name()),
            if a.passes() { "yes" } else { "no" },
            if counts.is_empty() {
                String::new()
            } else {
                format!("  ({})", counts.join(", "))
            }
        ));
    }
    t.push_str(&format!(
        "{:<22} {:>9} {:>9} {:>9} {:>9} {:>9} {:>7} {:>9} {:>8} {:>12} {:>6}\n",
        "exact linear reference",
        opt(e.phase_margin_deg, 1),
        opt(e.crossover_hz, 1),
        opt(e.gain_margin_db, 2),
        opt(e.phase_crossover_hz, 1),
        opt(e.lower_gain_margin_db, 2),
        opt(e.ms, 3),
        opt(e.bandwidth_hz, 1),
        "-",
        "-",
        if e.stable { "stable" } else { "UNSTABLE" }
    ));
    let c = &r.reference_cable;
    t.push_str(&match c.load_nm {
        None => format!(
            "exact linear reference: each cable half a spring of {:.4e} N/m, the free span (the small-amplitude limit)\n",
            c.half_stiffness_n_per_m
        ),
        Some(m) => format!(
            "exact linear reference: each cable half a spring of {:.4e} N/m, the tangent stiffness on first loading to {} N m ({:.1} % of the free span's {:.4e} N/m)\n",
            c.half_stiffness_n_per_m,
            crate::compact(m),
            100.0 * c.half_stiffness_n_per_m / c.free_span_half_stiffness_n_per_m,
            c.free_span_half_stiffness_n_per_m
        ),
    });
    for a in &r.amplitudes {
        t.push_str(&axis_line(a));
    }
    for a in &r.amplitudes {
        if !a.passes() {
            t.push_str(&format!(
                "{} {}: does not pass ({} reason{}):\n",
                a.amplitude,
                a.unit,
                a.shortfalls.len(),
                if a.shortfalls.len() == 1 { "" } else { "s" }
            ));
        }
        for s in &a.shortfalls {
            t.push_str(&format!("  {} {}: {s}\n", a.amplitude, a.unit));
        }
    }
    for a in &r.amplitudes {
        for u in &a.unresolved {
            t.push_str(&format!("{} {}: {u}\n", a.amplitude, a.unit));
        }
    }
    if let Some(cycles) = &r.limit_cycles {
        t.push_str(&limit_cycle_lines(r, cycles));
    }
    t
}

/// The base-motion table: per amplitude and frequency the measured rejection
/// (`-20 log10 |LOS/base|`), the exact reference's, their difference and the phase of the
/// measured response relative to the reference; then the verdict, or why there is none.
fn format_rejection_table(r: &FreqResponse) -> String {
    let mut t = format!(
        "{:<12} {:>12} {:>13} {:>13} {:>13} {:>14} {:>8}\n",
        "amplitude",
        "frequency_hz",
        "rejection_db",
        "reference_db",
        "difference_db",
        "phase_diff_deg",
        "THD%"
    );
    for a in &r.amplitudes {
        for p in &a.points {
            let head = format!(
                "{:<12} {:>12.4} ",
                format!("{} {}", a.amplitude, a.unit),
                p.frequency_hz
            );
            let exact = rejection_db(p.exact);
            t.push_str(&match p.response {
                Some(c) => format!(
                    "{head}{:>13.3} {:>13.3} {:>13.3} {:>14.2} {:>8}\n",
                    rejection_db(c),
                    exact,
                    rejection_db(c) - exact,
                    (c / p.exact).arg().to_degrees(),
                    p.distortion_percent
                        .map_or_else(|| "-".to_string(), |v| format!("{v:.1}"))
                ),
                None => format!(
                    "{head}{:>13} {:>13.3} {:>13} {:>14} {:>8}  failed: {}\n",
                    "-",
                    exact,
                    "-",
                    "-",
                    "-",
                    p.failure.as_deref().unwrap_or("")
                ),
            });
        }
    }
    let mut declared = false;
    for a in &r.amplitudes {
        if let Some(c) = &a.base_rejection {
            declared = true;
            t.push_str(&format!(
                "{} {}: rejection {} dB at {} Hz (exact reference {:.2} dB), required >= {} dB: passes {}\n",
                a.amplitude,
                a.unit,
                c.rejection_db
                    .map_or_else(|| "-".to_string(), |v| format!("{v:.2}")),
                c.frequency_hz,
                c.reference_rejection_db,
                c.min_rejection_db,
                if a.passes() { "yes" } else { "no" }
            ));
        }
        for s in &a.shortfalls {
            t.push_str(&format!("{} {}: {s}\n", a.amplitude, a.unit));
        }
    }
    if !declared {
        t.push_str("no base-rejection requirement declared: no verdict on the rejection (give closed_loop.requirements.min_base_rejection_db and base_rejection_hz to judge one)\n");
    }
    t
}

/// How the axis moved at one amplitude and what that does to the estimate, one line.
fn axis_line(a: &AmplitudeResponse) -> String {
    let Some(worst) = a.axis else {
        return String::new();
    };
    let c = &a.axis_frequencies;
    let measured = c.frictionless + c.sliding + c.slipping + c.held;
    let counts: Vec<String> = [
        ("held", c.held),
        ("slipping", c.slipping),
        ("sliding", c.sliding),
        ("frictionless", c.frictionless),
    ]
    .iter()
    .filter(|(_, n)| *n > 0)
    .map(|(name, n)| format!("{name} {n}"))
    .collect();
    let slew = a.slew_rate_rad_s.map_or_else(
        || "at rest".to_string(),
        |r| format!("slewing {} rad/s", crate::significant(r, 3)),
    );
    format!(
        "{} {}: axis {} ({slew}; of {measured} frequencies {}): {}\n",
        a.amplitude,
        a.unit,
        worst.name(),
        counts.join(", "),
        worst.effect()
    )
}

/// What the describing-function family predicts, one line per crossing of -1.
fn limit_cycle_lines(r: &FreqResponse, cycles: &[PredictedCycle]) -> String {
    let sig = |v: f64| crate::significant(v, 3);
    let span = r
        .amplitudes
        .iter()
        .map(|a| a.amplitude)
        .fold((f64::INFINITY, 0.0_f64), |(lo, hi), a| {
            (lo.min(a), hi.max(a))
        });
    let unit = r.amplitudes.first().map_or("", |a| a.unit.as_str());
    if cycles.is_empty() {
        return format!(
            "describing function: no limit cycle predicted between {} and {} {unit} (a stick-slip cycle far slower than the loop's bandwidth is not sinusoidal enough to be predicted; `run` detects one)\n",
            sig(span.0),
            sig(span.1)
        );
    }
    cycles
        .iter()
        .map(|c| {
            format!(
                "describing function: {} at {} Hz, command {} {} (between {} and {}), output {} mrad{}\n",
                if c.stable {
                    "limit cycle predicted"
                } else {
                    "threshold"
                },
                sig(c.frequency_hz),
                sig(c.command_amplitude),
                c.unit,
                sig(c.between[0]),
                sig(c.between[1]),
                sig(c.output_amplitude_mrad),
                if c.stable {
                    ": the loop is stable just above it and not just below, so motion settles onto it"
                } else {
                    ": motion larger than this grows, smaller shrinks"
                }
            )
        })
        .collect()
}
