//! Files of `margins`: `margins.json` (every crossing, Ms, closed-loop poles, the step's
//! figures per operating point), `linear_model.json` (the plant's matrices, the discrete
//! controller and the loop gain, for python-control or MATLAB; `docs/linear-model.md`),
//! `summary.json` with the verdict, and the figures: Bode, Nyquist, Nichols, z-plane and
//! reference step, one curve and line style per operating point.

use std::path::{Path, PathBuf};

use nalgebra::Complex;

use super::{write_json, write_summary, ReportError};
use crate::analysis::linear_model::{LoopModels, PointModel};
use crate::analysis::margins::GainDirection;
use crate::analysis::verdict::Verdict;
use crate::closed_loop::params::ClosedLoopParams;
use crate::plot::{
    save_annotated, AnnotatedFigure, Arrowhead, Dash, Mark, Panel, Shape, Trace, REFERENCE_RGB,
};
use crate::scenario::Scenario;

/// Version of the `linear_model.json` layout.
pub const LINEAR_MODEL_FORMAT: u32 = 1;

/// Colours of the operating points, in order (blue, orange, green, purple).
const POINT_RGB: [[u8; 3]; 4] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [148, 103, 189],
];
const CRITICAL_RGB: [u8; 3] = [214, 39, 40];
const GUIDE_RGB: [u8; 3] = [120, 120, 120];

fn colour(i: usize) -> [u8; 3] {
    POINT_RGB[i % POINT_RGB.len()]
}

fn encode(path: &Path, v: impl serde::Serialize) -> Result<serde_json::Value, ReportError> {
    serde_json::to_value(v).map_err(|e| ReportError::Encode {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// The `margins.json` record of one operating point.
fn point_json(path: &Path, p: &PointModel) -> Result<serde_json::Value, ReportError> {
    let m = &p.margins;
    let step = p.step.as_ref().map(|s| {
        serde_json::json!({
            "settle_band": s.settle_band,
            "rise_time_s": s.rise_time_s,
            "settling_time_s": s.settling_time_s,
            "settled": s.settled,
            "window_s": s.output.len() as f64 * s.sample_period_s,
            "peak": s.peak,
            "peak_time_s": s.peak_time_s,
            "overshoot_percent": s.overshoot_percent,
        })
    });
    Ok(serde_json::json!({
        "condition": p.condition,
        "load_nm": p.load_nm,
        "half_stiffness_n_per_m": p.half_stiffness_n_per_m,
        "stable": m.stable,
        "spectral_radius": m.spectral_radius,
        "instability": encode(path, m.instability)?,
        "gain_crossovers": encode(path, &m.gain_crossovers)?,
        "phase_crossovers": encode(path, &m.phase_crossovers)?,
        "worst": {
            "phase_margin_deg": m.phase_margin_deg,
            "phase_margin_hz": m.crossover_hz,
            "gain_margin_up_db": m.gain_margin_db,
            "gain_margin_up_hz": m.phase_crossover_hz,
            "gain_margin_down_db": m.lower_gain_margin_db,
            "gain_margin_down_hz": m.lower_phase_crossover_hz,
        },
        "ms": m.ms,
        "ms_hz": m.ms_hz,
        "mt": m.mt,
        "bandwidth_hz": m.bandwidth_hz,
        "closed_loop_poles": encode(path, &p.closed_loop_poles)?,
        "loop_zeros": encode(path, &p.loop_zeros)?,
        "loop_zeros_note": p.loop_zeros_note,
        "step": step,
        "step_note": p.step_note,
    }))
}

/// Writes `margins.json`, `linear_model.json` and `summary.json` (with `verdict`).
pub fn write_outputs(
    dir: &Path,
    scenario: &Scenario,
    p: &ClosedLoopParams,
    models: &LoopModels,
    verdict: &Verdict,
    explored_load_nm: Option<f64>,
) -> Result<(), ReportError> {
    let ctl = &p.controller;
    let req = &p.requirements;
    let path = dir.join("margins.json");
    let points = models
        .points
        .iter()
        .map(|m| point_json(&path, m))
        .collect::<Result<Vec<_>, _>>()?;
    let requirements = serde_json::json!({
        "min_phase_margin_deg": req.min_phase_margin_deg,
        "min_gain_margin_db": req.min_gain_margin_db,
        "max_ms": req.max_ms,
    });
    let margins = serde_json::json!({
        "scenario_name": scenario.name(),
        "sample_rate_hz": ctl.sample_rate_hz,
        "computation_delay_samples": ctl.computation_delay_samples,
        "requirements": requirements,
        "operating_load_problem": models.problem,
        "explored_load_nm": explored_load_nm,
        "operating_points": points,
    });
    write_json(&path, &margins)?;
    let path = dir.join("linear_model.json");
    let model = serde_json::json!({
        "format": "cable-servo linear model",
        "format_version": LINEAR_MODEL_FORMAT,
        "documentation": "docs/linear-model.md",
        "scenario_name": scenario.name(),
        "sample_rate_hz": ctl.sample_rate_hz,
        "requirements": requirements,
        "loop": "L(z) = K(z) P(z): broken at the plant input, negative feedback u = -K y; P(z) = C (zI - A)^-1 B of plant.sampled, K(z) = numerator_z_inv / denominator_z_inv (whole periods of delay included)",
        "operating_points": models
            .points
            .iter()
            .map(|m| {
                Ok(serde_json::json!({
                    "condition": m.condition,
                    "load_nm": m.load_nm,
                    "half_stiffness_n_per_m": m.half_stiffness_n_per_m,
                    "plant": encode(&path, &m.plant)?,
                    "controller": encode(&path, &m.controller)?,
                    "loop_response": encode(&path, &m.loop_response)?,
                    "margins": encode(&path, &m.margins)?,
                }))
            })
            .collect::<Result<Vec<_>, ReportError>>()?,
    });
    write_json(&path, &model)?;
    write_summary(
        &dir.join("summary.json"),
        scenario,
        true,
        &serde_json::json!({
            "margins": margins,
            "passes": verdict.passes,
            "verdict": encode(&dir.join("summary.json"), verdict)?,
        }),
    )
}

fn db(c: Complex<f64>) -> f64 {
    20.0 * c.norm().log10()
}

/// The -180 deg + k 360 deg nearest to `phase`.
fn nearest_critical(phase: f64) -> f64 {
    -180.0 + 360.0 * ((phase + 180.0) / 360.0).round()
}

/// Index of the grid frequency nearest to `f` (log distance).
fn nearest(freqs: &[f64], f: f64) -> usize {
    freqs
        .iter()
        .enumerate()
        .min_by(|a, b| {
            (a.1.ln() - f.ln())
                .abs()
                .total_cmp(&(b.1.ln() - f.ln()).abs())
        })
        .map_or(0, |(i, _)| i)
}

fn hz(f: f64) -> String {
    format!("{} Hz", crate::significant(f, 4))
}

fn range_of(v: impl Iterator<Item = f64>, floor: f64, ceil: f64, pad: f64) -> (f64, f64) {
    let (lo, hi) = v
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if lo > hi {
        return (floor, ceil);
    }
    let (lo, hi) = ((lo - pad).max(floor), (hi + pad).min(ceil));
    if hi > lo {
        (lo, hi)
    } else {
        (lo - 1.0, lo + 1.0)
    }
}

/// Every figure; a failed one is returned as the error after the others were tried.
pub fn plot(
    dir: &Path,
    scenario: &Scenario,
    p: &ClosedLoopParams,
    models: &LoopModels,
) -> Result<Vec<PathBuf>, ReportError> {
    let mut written = Vec::new();
    let mut first_error = None;
    let name = scenario.name();
    let figures = [
        bode(name, models),
        nyquist(name, p, models),
        nichols(name, p, models),
        zplane(name, models),
        step(name, models),
    ];
    for (stem, fig) in ["bode", "nyquist", "nichols", "pole_zero", "step"]
        .iter()
        .zip(figures)
    {
        let Some(fig) = fig else { continue };
        match save_annotated(&fig, &dir.join(stem)) {
            Ok(paths) => written.extend(paths),
            Err(e) => {
                first_error.get_or_insert(ReportError::Plot(e));
            }
        }
    }
    match first_error {
        Some(e) => Err(e),
        None => Ok(written),
    }
}

fn stable_points(models: &LoopModels) -> impl Iterator<Item = (usize, &PointModel)> {
    models
        .points
        .iter()
        .enumerate()
        .filter(|(_, m)| m.margins.stable)
}

fn bode(name: &str, models: &LoopModels) -> Option<AnnotatedFigure> {
    let first = models.points.first()?;
    let f = &first.loop_response.freq_hz;
    let (f0, f1) = (*f.first()?, *f.last()?);
    let mut mag = Panel {
        title: "magnitude".into(),
        x_label: "frequency [Hz]".into(),
        y_label: "|L| [dB]".into(),
        log_x: true,
        ..Panel::default()
    };
    let mut phase = Panel {
        title: "phase".into(),
        x_label: "frequency [Hz]".into(),
        y_label: "arg L [deg]".into(),
        log_x: true,
        ..Panel::default()
    };
    let mut notes = vec!["Marked: every gain crossover (circle) with its phase margin, every phase crossover (diamond) with its gain margin; bars show each margin.".to_string()];
    let mut all_db = Vec::new();
    let mut all_ph = Vec::new();
    let mut pm_from = Vec::new();
    for (i, m) in models.points.iter().enumerate() {
        let r = &m.loop_response;
        let l: Vec<Complex<f64>> = (0..r.len()).map(|k| r.at(k)).collect();
        let dbs: Vec<f64> = l.iter().map(|&c| db(c)).collect();
        let ph = super::freqresp::unwrapped(l.iter().map(|c| c.arg().to_degrees()));
        all_db.extend(dbs.iter().copied());
        all_ph.extend(ph.iter().copied());
        let (c, dash) = (colour(i), Dash::nth(i));
        let label = format!("L, {}", m.condition);
        mag.traces.push(Trace::line(
            label.clone(),
            r.freq_hz.clone(),
            dbs.clone(),
            c,
            dash,
        ));
        phase
            .traces
            .push(Trace::line(label, r.freq_hz.clone(), ph.clone(), c, dash));
        notes.push(format!("{} ({}):", m.condition, dash_words(dash)));
        if !m.margins.stable {
            notes.push("  unstable closed loop: no margins".into());
            continue;
        }
        // Labels of the second point below the marks, of the first above.
        let dy = if i % 2 == 0 { -14 } else { 16 };
        for g in &m.margins.gain_crossovers {
            let k = nearest(&r.freq_hz, g.frequency_hz);
            let crit = nearest_critical(ph[k]);
            pm_from.push(crit);
            let at = crit + g.phase_margin_deg * (ph[k] - crit).signum();
            mag.marks
                .push(point_mark(g.frequency_hz, 0.0, Shape::Circle, c, ""));
            phase.traces.push(bar(g.frequency_hz, crit, at, c));
            let mut mk = point_mark(
                g.frequency_hz,
                at,
                Shape::Circle,
                c,
                &format!("PM {:.1}°", g.phase_margin_deg),
            );
            mk.text_offset = (8, dy);
            phase.marks.push(mk);
            notes.push(format!(
                "  gain crossover {}: PM {:.1} deg",
                hz(g.frequency_hz),
                g.phase_margin_deg
            ));
        }
        for pc in &m.margins.phase_crossovers {
            let k = nearest(&r.freq_hz, pc.frequency_hz);
            let level = match pc.direction {
                GainDirection::Up => -pc.gain_margin_db,
                GainDirection::Down => pc.gain_margin_db,
            };
            let word = match pc.direction {
                GainDirection::Up => "up",
                GainDirection::Down => "down",
            };
            mag.traces.push(bar(pc.frequency_hz, 0.0, level, c));
            let mut mk = point_mark(
                pc.frequency_hz,
                level,
                Shape::Diamond,
                c,
                &format!("GM {word} {:.1} dB", pc.gain_margin_db),
            );
            mk.text_offset = (8, dy);
            mag.marks.push(mk);
            phase.marks.push(point_mark(
                pc.frequency_hz,
                nearest_critical(ph[k]),
                Shape::Diamond,
                c,
                "",
            ));
            notes.push(format!(
                "  phase crossover {}: GM {word} {:.2} dB",
                hz(pc.frequency_hz),
                pc.gain_margin_db
            ));
        }
    }
    mag.x_range = (f0, f1);
    phase.x_range = (f0, f1);
    // The loop's interesting stretch: the low-frequency rise and the roll-off into the
    // zero-order hold's notch at Nyquist leave the view rather than squeeze it.
    mag.y_range = range_of(all_db.into_iter(), -60.0, 80.0, 5.0);
    // Every critical line a phase margin is measured from stays in view.
    phase.y_range = range_of(
        all_ph.into_iter().chain(pm_from.iter().copied()),
        -1080.0,
        360.0,
        15.0,
    );
    // A margin beyond the view keeps its label, at the edge it leaves by.
    for panel in [&mut mag, &mut phase] {
        let (lo, hi) = panel.y_range;
        let pad = 0.03 * (hi - lo);
        for mk in &mut panel.marks {
            if mk.y < lo || mk.y > hi {
                mk.y = mk.y.clamp(lo + pad, hi - pad);
                mk.shape = Shape::Triangle;
                if !mk.text.is_empty() {
                    mk.text.push_str(" (off scale)");
                }
            }
        }
    }
    mag.traces.push(guide("", vec![f0, f1], vec![0.0, 0.0]));
    let (lo, hi) = phase.y_range;
    let mut k = nearest_critical(lo) - 360.0;
    while k <= hi + 360.0 {
        if k > lo && k < hi {
            phase.traces.push(guide("", vec![f0, f1], vec![k, k]));
        }
        k += 360.0;
    }
    Some(AnnotatedFigure {
        title: format!("{name}: loop gain L = K P broken at the plant input, exact sampled loop"),
        panels: vec![mag, phase],
        notes,
        panel_height: 430,
    })
}

fn dash_words(d: Dash) -> &'static str {
    match d {
        Dash::Solid => "solid",
        Dash::Dashed => "dashed",
        Dash::Dotted => "dotted",
        Dash::LongDash => "long dashes",
    }
}

fn point_mark(x: f64, y: f64, shape: Shape, rgb: [u8; 3], text: &str) -> Mark {
    Mark {
        x,
        y,
        shape,
        rgb,
        size: 5,
        label: String::new(),
        text: text.to_string(),
        text_offset: (8, -14),
    }
}

/// A vertical bar from `a` to `b` at `x` (a margin).
fn bar(x: f64, a: f64, b: f64, rgb: [u8; 3]) -> Trace {
    Trace {
        width: 3,
        ..Trace::line("", vec![x, x], vec![a, b], rgb, Dash::Solid)
    }
}

fn guide(label: &str, x: Vec<f64>, y: Vec<f64>) -> Trace {
    Trace {
        width: 1,
        ..Trace::line(label, x, y, [60, 60, 60], Dash::Solid)
    }
}

fn circle(cx: f64, cy: f64, r: f64) -> (Vec<f64>, Vec<f64>) {
    (0..=360)
        .map(|k| {
            let t = (k as f64).to_radians();
            (cx + r * t.cos(), cy + r * t.sin())
        })
        .unzip()
}

fn nyquist(name: &str, p: &ClosedLoopParams, models: &LoopModels) -> Option<AnnotatedFigure> {
    let max_ms = p.requirements.max_ms;
    let mut plane = nyquist_plane(max_ms);
    let mut notes = vec![
        "Positive frequencies, 0.1 Hz to Nyquist; arrows point to rising frequency; dots mark 1, 2 and 5 per decade.".to_string(),
    ];
    let (ux, uy) = circle(0.0, 0.0, 1.0);
    plane.traces.push(Trace {
        width: 1,
        ..Trace::line("|L| = 1", ux, uy, GUIDE_RGB, Dash::Dotted)
    });
    for (i, m) in models.points.iter().enumerate() {
        let r = &m.loop_response;
        let (c, dash) = (colour(i), Dash::nth(i));
        plane.traces.push(Trace::line(
            format!("L, {}", m.condition),
            r.re.clone(),
            r.im.clone(),
            c,
            dash,
        ));
        // Arrows at every third of a decade, where the curve is in view.
        let mut e = -1.0_f64;
        while 10f64.powf(e) < r.freq_hz.last().copied().unwrap_or(0.0) {
            let k = nearest(&r.freq_hz, 10f64.powf(e));
            if k > 0 {
                plane.arrows.push(Arrowhead {
                    at: (r.re[k], r.im[k]),
                    from: (r.re[k - 1], r.im[k - 1]),
                    rgb: c,
                });
            }
            e += 1.0 / 3.0;
        }
        // Frequency marks at 1, 2, 5 per decade; labelled on the first curve only (the
        // others pass the same frequencies close by), dots on every curve.
        for d in 0..6 {
            for mantissa in [1.0, 2.0, 5.0] {
                let f = mantissa * 10f64.powi(d);
                if f < r.freq_hz[0] || f > *r.freq_hz.last().unwrap_or(&0.0) {
                    continue;
                }
                let k = nearest(&r.freq_hz, f);
                let text = if i == 0 {
                    format!("{} Hz", crate::compact(f))
                } else {
                    String::new()
                };
                let mut mk = point_mark(r.re[k], r.im[k], Shape::Circle, c, &text);
                mk.size = 4;
                // The label on the side away from -1, so none sits near the critical point.
                let away = Complex::new(r.re[k] + 1.0, r.im[k]);
                let u = if away.norm() > 0.0 {
                    away / away.norm()
                } else {
                    Complex::from(1.0)
                };
                let width = 8 * text.len() as i32;
                mk.text_offset = (
                    (14.0 * u.re).round() as i32 - if u.re < 0.0 { width } else { 0 },
                    (-14.0 * u.im).round() as i32,
                );
                plane.marks.push(mk);
            }
        }
        if let (Some(ms), Some(f)) = (m.margins.ms, m.margins.ms_hz) {
            let k = nearest(&r.freq_hz, f);
            let mut mk = point_mark(
                r.re[k],
                r.im[k],
                Shape::Square,
                c,
                &format!("Ms {:.2} at {}", ms, hz(f)),
            );
            mk.text_offset = (14, if i % 2 == 0 { -6 } else { 14 });
            plane.marks.push(mk);
            notes.push(format!(
                "{} ({}): Ms {:.3} at {} (square), closest approach to -1: {:.3}",
                m.condition,
                dash_words(dash),
                ms,
                hz(f),
                1.0 / ms
            ));
        } else {
            notes.push(format!("{}: unstable closed loop", m.condition));
        }
    }
    plane.marks.push(Mark {
        x: -1.0,
        y: 0.0,
        shape: Shape::Cross,
        rgb: CRITICAL_RGB,
        size: 7,
        label: "critical point -1".into(),
        text: String::new(),
        text_offset: (0, 0),
    });
    Some(AnnotatedFigure {
        title: format!("{name}: Nyquist plot of L near the critical point"),
        panels: vec![plane],
        notes,
        panel_height: 820,
    })
}

fn nichols(name: &str, p: &ClosedLoopParams, models: &LoopModels) -> Option<AnnotatedFigure> {
    let mut chart = Panel {
        x_label: "arg L [deg]".into(),
        y_label: "|L| [dB]".into(),
        ..Panel::default()
    };
    let mut all_ph = Vec::new();
    for (i, m) in models.points.iter().enumerate() {
        let r = &m.loop_response;
        let l: Vec<Complex<f64>> = (0..r.len()).map(|k| r.at(k)).collect();
        let ph = super::freqresp::unwrapped(l.iter().map(|c| c.arg().to_degrees()));
        let dbs: Vec<f64> = l.iter().map(|&c| db(c)).collect();
        // The view: where |L| is within +-40 dB, the region the contours describe.
        all_ph.extend(
            ph.iter()
                .zip(&dbs)
                .filter(|(_, d)| d.abs() < 40.0)
                .map(|(p, _)| *p),
        );
        chart.traces.push(Trace::line(
            format!("L, {}", m.condition),
            ph,
            dbs,
            colour(i),
            Dash::nth(i),
        ));
    }
    let (x0, x1) = range_of(all_ph.into_iter(), -1080.0, 360.0, 20.0);
    chart.x_range = (x0, x1);
    chart.y_range = (-40.0, 40.0);
    let mut crit = nearest_critical(x0) - 360.0;
    let mut first = true;
    while crit <= x1 + 360.0 {
        if crit > x0 && crit < x1 {
            for (k, m_db) in [0.5, 1.0, 3.0, 6.0].into_iter().enumerate() {
                let mm = 10f64.powf(m_db / 20.0);
                let (x, y) = contour(crit, |t| {
                    let tc = Complex::from_polar(mm, t);
                    tc / (Complex::from(1.0) - tc)
                });
                let label = if first {
                    "closed loop |T| = 0.5, 1, 3, 6 dB".to_string()
                } else {
                    String::new()
                };
                let top = top_point(&x, &y);
                chart.traces.push(Trace {
                    width: 1,
                    ..Trace::line(
                        if k == 0 { label } else { String::new() },
                        x,
                        y,
                        GUIDE_RGB,
                        Dash::Dotted,
                    )
                });
                if let Some((tx, ty)) = top {
                    let mut mk =
                        point_mark(tx, ty, Shape::Circle, GUIDE_RGB, &format!("{m_db} dB"));
                    mk.size = 2;
                    mk.text_offset = (4, -10);
                    chart.marks.push(mk);
                }
            }
            let ms = p.requirements.max_ms;
            if ms.is_finite() && ms > 1.0 {
                let (x, y) = contour(crit, |t| {
                    Complex::from(-1.0) + Complex::from_polar(1.0 / ms, t)
                });
                chart.traces.push(Trace::line(
                    if first {
                        format!("|S| = Ms limit {}", crate::compact(ms))
                    } else {
                        String::new()
                    },
                    x,
                    y,
                    CRITICAL_RGB,
                    Dash::Dashed,
                ));
            }
            chart.marks.push(Mark {
                x: crit,
                y: 0.0,
                shape: Shape::Cross,
                rgb: CRITICAL_RGB,
                size: 7,
                label: "critical point (-180 deg + k 360 deg, 0 dB)".into(),
                text: String::new(),
                text_offset: (0, 0),
            });
            first = false;
        }
        crit += 360.0;
    }
    Some(AnnotatedFigure {
        title: format!("{name}: Nichols chart of L with closed-loop contours"),
        panels: vec![chart],
        notes: vec![
            "Contours of the closed loop T = L/(1+L) (dotted, labelled in dB) and of the sensitivity limit |S| = Ms (red), around each critical point in view.".into(),
        ],
        panel_height: 760,
    })
}

/// A closed contour `L(theta)` on the Nichols plane around the critical point `crit`:
/// phase on the branch around it, dB.
fn contour(crit: f64, l: impl Fn(f64) -> Complex<f64>) -> (Vec<f64>, Vec<f64>) {
    (0..=720)
        .map(|k| {
            let t = -std::f64::consts::PI + std::f64::consts::TAU * k as f64 / 720.0;
            let v = l(t);
            let ph = v.arg().to_degrees();
            // Onto the branch within 180 deg of `crit`.
            let ph = ph + 360.0 * ((crit - ph) / 360.0).round();
            (ph, db(v))
        })
        .unzip()
}

fn top_point(x: &[f64], y: &[f64]) -> Option<(f64, f64)> {
    x.iter()
        .zip(y)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map(|(a, b)| (*a, *b))
}

fn zplane(name: &str, models: &LoopModels) -> Option<AnnotatedFigure> {
    let mut full = Panel {
        title: "whole unit disc".into(),
        x_label: "Re z [1]".into(),
        y_label: "Im z [1]".into(),
        x_range: (-1.15, 1.15),
        y_range: (-1.15, 1.15),
        equal_aspect: true,
        ..Panel::default()
    };
    let (ux, uy) = circle(0.0, 0.0, 1.0);
    full.traces.push(guide("unit circle |z| = 1", ux, uy));
    let mut notes =
        vec!["x: closed-loop poles; o: zeros of L (shared by T = L/(1+L)).".to_string()];
    for (i, m) in models.points.iter().enumerate() {
        let c = colour(i);
        for (k, z) in m.closed_loop_poles.iter().enumerate() {
            full.marks.push(Mark {
                x: z.re,
                y: z.im,
                shape: Shape::Cross,
                rgb: c,
                size: 6,
                label: if k == 0 {
                    format!("closed-loop poles, {}", m.condition)
                } else {
                    String::new()
                },
                text: String::new(),
                text_offset: (0, 0),
            });
        }
        for (k, z) in m.loop_zeros.iter().enumerate() {
            full.marks.push(Mark {
                x: z.re,
                y: z.im,
                shape: Shape::Ring,
                rgb: c,
                size: 6,
                label: if k == 0 {
                    format!("zeros of L, {}", m.condition)
                } else {
                    String::new()
                },
                text: String::new(),
                text_offset: (0, 0),
            });
        }
        if let Some(note) = &m.loop_zeros_note {
            notes.push(format!("{}: {note}", m.condition));
        }
        let largest = m
            .closed_loop_poles
            .iter()
            .max_by(|a, b| a.magnitude.total_cmp(&b.magnitude));
        if let Some(z) = largest {
            notes.push(format!(
                "{}: largest pole |z| = {:.6}{}",
                m.condition,
                z.magnitude,
                z.natural_hz
                    .map(|f| format!(
                        " ({} natural, damping {:.3})",
                        hz(f),
                        z.damping.unwrap_or(0.0)
                    ))
                    .unwrap_or_default()
            ));
        }
        // The poles of the loop's modes in Hz, most lightly damped first.
        let mut modes: Vec<_> = m
            .closed_loop_poles
            .iter()
            .filter(|z| z.im > 0.0)
            .filter_map(|z| Some((z.damping?, z.natural_hz?)))
            .collect();
        modes.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (d, f) in modes.iter().take(4) {
            notes.push(format!("  mode {}: damping {:.3}", hz(*f), d));
        }
    }
    // The neighbourhood of z = 1, where the loop's slow poles sit at a fast control rate.
    let near: Vec<(f64, f64)> = models
        .points
        .iter()
        .flat_map(|m| m.closed_loop_poles.iter().chain(&m.loop_zeros))
        .filter(|z| (Complex::new(z.re, z.im) - 1.0).norm() < 0.3)
        .map(|z| (z.re, z.im))
        .collect();
    let mut panels = vec![full.clone()];
    if !near.is_empty() {
        let span = near
            .iter()
            .map(|(x, y)| (x - 1.0).abs().max(y.abs()))
            .fold(0.0, f64::max)
            .max(1e-4)
            * 1.3;
        let mut zoom = full;
        zoom.title = "near z = 1".into();
        zoom.x_range = (1.0 - span, 1.0 + 0.3 * span);
        zoom.y_range = (-span, span);
        for mk in &mut zoom.marks {
            mk.label.clear();
        }
        zoom.traces[0].label.clear();
        panels.push(zoom);
    }
    Some(AnnotatedFigure {
        title: format!("{name}: closed-loop poles and loop zeros in the z-plane"),
        panels,
        notes,
        panel_height: 640,
    })
}

fn step(name: &str, models: &LoopModels) -> Option<AnnotatedFigure> {
    let mut chart = Panel {
        x_label: "time after the reference step [ms]".into(),
        y_label: "drum angle / step [1]".into(),
        ..Panel::default()
    };
    let mut notes = Vec::new();
    let mut end_ms: f64 = 0.0;
    let mut shown = 0;
    let mut y_hi: f64 = 1.1;
    for (i, m) in stable_points(models) {
        let Some(s) = &m.step else {
            notes.push(format!(
                "{}: {}",
                m.condition,
                m.step_note.as_deref().unwrap_or("no step")
            ));
            continue;
        };
        shown += 1;
        let (c, dash) = (colour(i), Dash::nth(i));
        let ms = 1e3 * s.sample_period_s;
        let t: Vec<f64> = (0..s.output.len()).map(|k| k as f64 * ms).collect();
        let window = t.last().copied().unwrap_or(0.0);
        end_ms = end_ms.max(match s.settling_time_s {
            Some(ts) => (2.5 * ts * 1e3).max(5.0 * s.peak_time_s * 1e3).min(window),
            None => window,
        });
        y_hi = y_hi.max(s.peak + 0.05);
        chart.traces.push(Trace::line(
            format!("output, {}", m.condition),
            t.clone(),
            s.output.clone(),
            c,
            dash,
        ));
        let dy = if i % 2 == 0 { -14 } else { 16 };
        if s.overshoot_percent > 0.0 {
            let mut mk = point_mark(
                s.peak_time_s * 1e3,
                s.peak,
                Shape::Triangle,
                c,
                &format!("overshoot {:.1} %", s.overshoot_percent),
            );
            mk.text_offset = (8, dy);
            chart.marks.push(mk);
        }
        if let Some(ts) = s.settling_time_s {
            let k = ((ts / s.sample_period_s).round() as usize).min(s.output.len() - 1);
            let mut mk = point_mark(
                ts * 1e3,
                s.output[k],
                Shape::Diamond,
                c,
                &format!("settled {:.2} ms", ts * 1e3),
            );
            mk.text_offset = (8, if i % 2 == 0 { -16 } else { 18 });
            chart.marks.push(mk);
        }
        if let Some(tr) = s.rise_time_s {
            // The 90 % crossing.
            if let Some(k) = s.output.iter().position(|&v| v >= 0.9) {
                let mut mk = point_mark(
                    k as f64 * ms,
                    s.output[k],
                    Shape::Circle,
                    c,
                    &format!("rise 10-90 % {:.2} ms", tr * 1e3),
                );
                mk.text_offset = (12, if i % 2 == 0 { 24 } else { 44 });
                chart.marks.push(mk);
            }
        }
        notes.push(format!(
            "{} ({}): rise {}, settling {}, overshoot {:.2} %",
            m.condition,
            dash_words(dash),
            s.rise_time_s
                .map_or("never reaches 90 %".into(), |v| format!(
                    "{:.3} ms",
                    v * 1e3
                )),
            match s.settling_time_s {
                Some(v) => format!("{:.3} ms", v * 1e3),
                None => format!("did not settle within {:.1} ms", window),
            },
            s.overshoot_percent
        ));
    }
    for (_, m) in models
        .points
        .iter()
        .enumerate()
        .filter(|(_, m)| !m.margins.stable)
    {
        notes.push(format!("{}: unstable closed loop, no step", m.condition));
    }
    if shown == 0 {
        return None;
    }
    let band = crate::analysis::linear_model::STEP_SETTLE_FRACTION;
    chart.traces.insert(
        0,
        Trace {
            width: 2,
            ..Trace::line(
                "reference",
                vec![0.0, 0.0, end_ms],
                vec![0.0, 1.0, 1.0],
                REFERENCE_RGB,
                Dash::Solid,
            )
        },
    );
    for (k, v) in [1.0 - band, 1.0 + band].into_iter().enumerate() {
        chart.traces.insert(
            1,
            Trace {
                width: 1,
                ..Trace::line(
                    if k == 0 {
                        format!("settling band +-{} %", crate::compact(100.0 * band))
                    } else {
                        String::new()
                    },
                    vec![0.0, end_ms],
                    vec![v, v],
                    GUIDE_RGB,
                    Dash::Dashed,
                )
            },
        );
    }
    chart.x_range = (0.0, end_ms.max(1e-3));
    chart.y_range = (-0.05, y_hi);
    notes.insert(0, "Exact response of the sampled loop at the samples, drum angle over a unit reference step (the derivative acts on the measurement).".into());
    Some(AnnotatedFigure {
        title: format!("{name}: reference step of the exact sampled loop"),
        panels: vec![chart],
        notes,
        panel_height: 640,
    })
}

/// The Nyquist plane near -1 (equal aspect) with the Ms requirement drawn on it.
pub(super) fn nyquist_plane(max_ms: f64) -> Panel {
    let mut plane = Panel {
        x_label: "Re L [1]".into(),
        y_label: "Im L [1]".into(),
        x_range: (-3.0, 1.5),
        y_range: (-2.0, 2.0),
        equal_aspect: true,
        ..Panel::default()
    };
    plane.traces.extend(ms_requirement(max_ms));
    plane
}

/// The Ms requirement on a Nyquist plane: the circle `|1 + L| = 1 / Ms_max` about -1 that
/// the loop must stay outside (none when no finite limit above 1 is set).
fn ms_requirement(max_ms: f64) -> Option<Trace> {
    (max_ms.is_finite() && max_ms > 1.0).then(|| {
        let (cx, cy) = circle(-1.0, 0.0, 1.0 / max_ms);
        Trace::line(
            format!(
                "requirement Ms <= {}: L stays outside |1 + L| = {}",
                crate::compact(max_ms),
                crate::compact(1.0 / max_ms)
            ),
            cx,
            cy,
            CRITICAL_RGB,
            Dash::Dashed,
        )
    })
}
