//! Views of a tune's records: the console text, `tuned.toml`, `candidates.csv`,
//! `summary.json` and the figures. Nothing here is computed twice: every number is read
//! from the [`TuneResult`].

use std::path::{Path, PathBuf};

use super::tune::{Candidate, Feedforward, LeastRate, TuneResult};
use super::DesignError;
use crate::analysis::linear::LinearLoop;
use crate::closed_loop::ClosedLoopSource;
use crate::io::output::{write_atomic, StagedDir};
use crate::plot::{self, Chart, HBand, Series};
use crate::scenario::Scenario;

fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "-".to_string(), crate::compact)
}

/// One line per candidate figure set: gains, margins at each stiffness, peak.
fn candidate_line(c: &Candidate) -> String {
    let margins: Vec<String> = c
        .margins
        .iter()
        .map(|m| {
            format!(
                "{}: PM {} deg, GM {}/{} dB, Ms {}",
                m.condition,
                opt(m.phase_margin_deg.map(|v| round(v, 1))),
                opt(m.gain_margin_up_db.map(|v| round(v, 2))),
                opt(m.gain_margin_down_db.map(|v| round(v, 2))),
                opt(m.ms.map(|v| round(v, 3)))
            )
        })
        .collect();
    format!(
        "kp {} ki {} kd {} at {} Hz, load feedforward {}: peak {} mrad, rms {} mrad ({}); {}",
        crate::significant(c.gains.kp, 4),
        crate::significant(c.gains.ki, 4),
        crate::significant(c.gains.kd, 4),
        crate::compact(c.rate_hz),
        if c.load_feedforward { "on" } else { "off" },
        opt(c.peak_mrad.map(|v| round(v, 5))),
        opt(c.rms_mrad.map(|v| round(v, 5))),
        c.status,
        margins.join("; ")
    )
}

fn round(v: f64, digits: i32) -> f64 {
    let f = 10f64.powi(digits);
    (v * f).round() / f
}

/// The console report of a tune.
pub fn tune_text(r: &TuneResult) -> String {
    let mut out = String::new();
    out.push_str(&format!(
        "searched: {}\n{} of {} grid designs signable on the exact linear loop; {} judged on the nonlinear plant ({} mode) in {} s\n",
        r.searched,
        r.linear_feasible,
        r.linear_candidates,
        r.verified.len(),
        r.mode.name(),
        crate::significant(r.elapsed_s, 3)
    ));
    if !r.filter_variants.is_empty() {
        out.push_str("filter settings (linear ranking: least peak drum compliance of a signable grid design):\n");
        for v in &r.filter_variants {
            out.push_str(&format!(
                "  {}: {} signable, {}{}\n",
                v.label,
                v.linear_feasible,
                v.best_linear_compliance_mrad_per_nm
                    .map_or("none signable".into(), |c| format!(
                        "{} mrad/N m",
                        crate::significant(c, 4)
                    )),
                if v.searched {
                    format!(
                        "; searched: best peak {}",
                        v.best_peak_mrad.map_or("none signable".into(), |p| format!(
                            "{} mrad",
                            crate::significant(p, 4)
                        ))
                    )
                } else {
                    String::new()
                }
            ));
        }
    }
    out.push_str(&format!(
        "scenario's design: {}\n",
        candidate_line(&r.scenario_design)
    ));
    for (word, best) in [
        ("best without load feedforward", r.best_without_feedforward),
        ("best with load feedforward", r.best_with_feedforward),
    ] {
        if let Some(i) = best {
            out.push_str(&format!("{word}: {}\n", candidate_line(&r.verified[i])));
        }
    }
    match r.picked() {
        Some(c) => {
            out.push_str(&format!("pick: {}\n", candidate_line(c)));
            out.push_str(&format!(
                "pick {} the pointing target of {} mrad\n",
                if c.passes { "meets" } else { "MISSES" },
                crate::compact(r.target_mrad)
            ));
        }
        None => out.push_str(
            "pick: none; no candidate was signable over the operating range with a complete run\n",
        ),
    }
    if let Some(a) = &r.active_constraint {
        out.push_str(&format!("active constraint: {a}\n"));
    }
    if !r.blocked_moves.is_empty() {
        out.push_str(&format!(
            "moves the requirements forbid: {}\n",
            r.blocked_moves.join("; ")
        ));
    }
    if !r.sensitivity.is_empty() {
        out.push_str("sensitivity of the pick (one gain moved, the others kept):\n");
        out.push_str(&format!(
            "  {:<4} {:>7} {:>11} {:>11} {:>8} {:>8} {:>7}  signable\n",
            "gain", "change", "peak_mrad", "d_peak", "PM_deg", "GM_dB", "Ms"
        ));
        for s in &r.sensitivity {
            out.push_str(&format!(
                "  {:<4} {:>6}% {:>11} {:>11} {:>8} {:>8} {:>7}  {}\n",
                s.gain,
                crate::compact(100.0 * s.change),
                opt(s.peak_mrad.map(|v| round(v, 5))),
                opt(s.peak_change_mrad.map(|v| round(v, 5))),
                opt(s.phase_margin_deg.map(|v| round(v, 2))),
                opt(s.gain_margin_db.map(|v| round(v, 2))),
                opt(s.ms.map(|v| round(v, 3))),
                if s.signable { "yes" } else { "no" }
            ));
        }
    }
    out
}

/// The console report of a least-rate search.
pub fn least_rate_text(r: &LeastRate) -> String {
    let mut out = String::new();
    for p in &r.probes {
        out.push_str(&format!(
            "{:>9} Hz: {} ({} verdicts, {} s){}\n",
            crate::compact(p.rate_hz),
            if p.passes {
                "passes"
            } else {
                "no passing design found"
            },
            p.verdicts,
            crate::significant(p.elapsed_s, 3),
            p.pick
                .as_ref()
                .map_or(String::new(), |c| format!("; best {}", candidate_line(c)))
        ));
    }
    match (r.failing_hz, r.passing_hz) {
        (Some(f), Some(p)) => out.push_str(&format!(
            "least rate: between {} and {} Hz{}\n",
            crate::compact(f),
            crate::compact(p),
            if r.failing_confirmed {
                " (the failing end tuned again with every design found as a seed)"
            } else {
                " (the probe limit stopped the search before the failing end was confirmed)"
            }
        )),
        (None, Some(p)) => out.push_str(&format!(
            "least rate: at or below {} Hz (the lower end of the search passes)\n",
            crate::compact(p)
        )),
        (Some(f), None) => out.push_str(&format!(
            "least rate: none up to {} Hz (even the upper end of the search finds no passing design)\n",
            crate::compact(f)
        )),
        (None, None) => out.push_str("least rate: no probe made\n"),
    }
    out.push_str(&format!("  definition: {}\n", r.definition));
    out
}

/// Columns of `candidates.csv`.
const CSV_HEADER: [&str; 23] = [
    "origin",
    "rate_hz",
    "load_feedforward",
    "kp",
    "ki",
    "kd",
    "pm_free_deg",
    "gm_up_free_db",
    "gm_down_free_db",
    "ms_free",
    "pm_tangent_deg",
    "gm_up_tangent_db",
    "gm_down_tangent_db",
    "ms_tangent",
    "margin_class",
    "linear_compliance_mrad_per_nm",
    "status",
    "peak_mrad",
    "rms_mrad",
    "signable",
    "passes",
    "on_front",
    "pick",
];

fn csv_row(c: &Candidate, pick: bool) -> Vec<String> {
    let cell = |v: Option<f64>| v.map_or_else(String::new, |v| format!("{v}"));
    let mut row = vec![
        c.origin.to_string(),
        format!("{}", c.rate_hz),
        c.load_feedforward.to_string(),
        format!("{}", c.gains.kp),
        format!("{}", c.gains.ki),
        format!("{}", c.gains.kd),
    ];
    for i in 0..2 {
        let m = c.margins.get(i);
        row.push(cell(m.and_then(|m| m.phase_margin_deg)));
        row.push(cell(m.and_then(|m| m.gain_margin_up_db)));
        row.push(cell(m.and_then(|m| m.gain_margin_down_db)));
        row.push(cell(m.and_then(|m| m.ms)));
    }
    row.extend([
        cell(c.margin_class),
        cell(c.linear_compliance_mrad_per_nm),
        c.status.clone(),
        cell(c.peak_mrad),
        cell(c.rms_mrad),
        c.signable.to_string(),
        c.passes.to_string(),
        c.on_front.to_string(),
        pick.to_string(),
    ]);
    row
}

fn write_err(path: &Path, e: impl std::fmt::Display) -> DesignError {
    DesignError::Write(format!("{}: {e}", path.display()))
}

/// Writes a tune's files into `dir` (staged, moved into place at the end): `tuned.toml`
/// (when there is a pick), `candidates.csv`, `summary.json`, `summary.txt` and the
/// figures `front`, `bode` and `step` (PNG and SVG). `base` is the scenario as given.
pub fn write_tune(
    r: &TuneResult,
    base: &Scenario,
    dir: &Path,
    force: bool,
) -> Result<PathBuf, DesignError> {
    let staged = StagedDir::create(dir, force)?;
    let at = |name: &str| staged.path().join(name);
    if let Some(t) = &r.tuned {
        let text = toml::to_string(t).map_err(|e| write_err(&at("tuned.toml"), e))?;
        let header = format!(
            "# Tuned by cable-servo design tune from scenario {}: {}\n# Run it as it is: cable-servo run tuned.toml\n",
            r.scenario,
            r.picked().map_or(String::new(), candidate_line)
        );
        write_atomic(&at("tuned.toml"), (header + &text).as_bytes())?;
    }
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(CSV_HEADER)
        .map_err(|e| write_err(&at("candidates.csv"), e))?;
    w.write_record(csv_row(&r.scenario_design, false))
        .map_err(|e| write_err(&at("candidates.csv"), e))?;
    for (i, c) in r.verified.iter().enumerate() {
        w.write_record(csv_row(c, r.pick == Some(i)))
            .map_err(|e| write_err(&at("candidates.csv"), e))?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| write_err(&at("candidates.csv"), e))?;
    write_atomic(&at("candidates.csv"), &bytes)?;
    let front: Vec<&Candidate> = r.verified.iter().filter(|c| c.on_front).collect();
    let summary = crate::report::with_provenance(
        base,
        true,
        &serde_json::json!({
            "tune": r,
            "pick": r.picked(),
            "front": front,
        }),
    );
    let body =
        serde_json::to_vec_pretty(&summary).map_err(|e| write_err(&at("summary.json"), e))?;
    write_atomic(&at("summary.json"), &body)?;
    write_atomic(&at("summary.txt"), tune_text(r).as_bytes())?;
    figures(r, base, staged.path())?;
    Ok(staged.commit()?)
}

/// Writes a least-rate search's `least_rate.json` and `least_rate.txt` into `dir`.
pub fn write_least_rate(
    r: &LeastRate,
    base: &Scenario,
    dir: &Path,
    force: bool,
) -> Result<PathBuf, DesignError> {
    let staged = StagedDir::create(dir, force)?;
    let path = staged.path().join("least_rate.json");
    let body = serde_json::to_vec_pretty(&crate::report::with_provenance(
        base,
        true,
        &serde_json::json!({ "least_rate": r }),
    ))
    .map_err(|e| write_err(&path, e))?;
    write_atomic(&path, &body)?;
    write_atomic(
        &staged.path().join("least_rate.txt"),
        least_rate_text(r).as_bytes(),
    )?;
    Ok(staged.commit()?)
}

/// A design's name in a figure with what sets it apart from the candidates searched: its
/// control rate always (the scenario's own design keeps its rate whatever rate was tuned
/// at), and its load-feedforward setting when the search did not try that setting.
fn design_label(name: &str, c: &Candidate, searched: Feedforward) -> String {
    let mut words = format!("{} Hz", crate::compact(c.rate_hz));
    if !searched.settings().contains(&c.load_feedforward) {
        words.push_str(if c.load_feedforward {
            ", with load feedforward"
        } else {
            ", without load feedforward"
        });
    }
    format!("{name} ({words})")
}

/// The front (peak against margin class, per load-feedforward setting), the Bode plot of
/// the pick's loop gain against the scenario's design at each stiffness, and their
/// reference steps on the exact linear loop.
fn figures(r: &TuneResult, base: &Scenario, dir: &Path) -> Result<(), DesignError> {
    let mut front = Chart {
        title: format!(
            "{}: signable candidates at {} Hz, {} mode",
            r.scenario,
            crate::compact(r.rate_hz),
            r.mode.name()
        ),
        x_label: "margin class: least relative margin over PM, GM and Ms [%]".into(),
        y_label: "peak pointing error [mrad]".into(),
        bands: vec![HBand {
            lo: 0.0,
            hi: r.target_mrad,
            label: format!("target {} mrad", crate::compact(r.target_mrad)),
        }],
        ..Chart::default()
    };
    for (slot, ff) in [(0, false), (1, true)] {
        let word = if ff { "with" } else { "without" };
        let signable: Vec<&Candidate> = r
            .verified
            .iter()
            .filter(|c| c.signable && c.load_feedforward == ff)
            .collect();
        if signable.is_empty() {
            continue;
        }
        let xy = |v: &[&Candidate]| -> (Vec<f64>, Vec<f64>) {
            v.iter()
                .filter_map(|c| Some((100.0 * c.margin_class?, c.peak_mrad?)))
                .unzip()
        };
        let (x, y) = xy(&signable);
        front
            .series
            .push(Series::points(format!("{word} load feedforward"), x, y).in_slot(slot));
        let mut on: Vec<&Candidate> = signable.into_iter().filter(|c| c.on_front).collect();
        on.sort_by(|a, b| {
            a.margin_class
                .unwrap_or(0.0)
                .total_cmp(&b.margin_class.unwrap_or(0.0))
        });
        let (x, y) = xy(&on);
        front
            .series
            .push(Series::line(format!("front {word}"), x, y).in_slot(slot));
    }
    if let Some(c) = r.picked() {
        if let (Some(m), Some(p)) = (c.margin_class, c.peak_mrad) {
            front
                .series
                .push(Series::points("pick", vec![100.0 * m], vec![p]).in_rgb(plot::REFERENCE_RGB));
        }
    }
    if r.scenario_design.signable {
        if let (Some(m), Some(p)) = (r.scenario_design.margin_class, r.scenario_design.peak_mrad) {
            front.series.push(
                Series::points(
                    design_label("scenario's design", &r.scenario_design, r.feedforward),
                    vec![100.0 * m],
                    vec![p],
                )
                .in_slot(3),
            );
        }
    }
    if !front.series.is_empty() {
        plot::save_chart(&front, &dir.join("front"))?;
    }
    let Some(tuned) = &r.tuned else {
        return Ok(());
    };
    let mut own = base.clone();
    if let Some(cl) = own.closed_loop.as_mut() {
        cl.requirements.mode = Some(r.mode);
    }
    let designs: Vec<(&str, &Scenario, &Candidate, usize)> = match r.picked() {
        Some(c) => vec![
            ("pick", tuned, c, 0),
            ("scenario's design", &own, &r.scenario_design, 3),
        ],
        None => return Ok(()),
    };
    let (mut mag, mut phase, mut step) = (
        Chart {
            x_label: "frequency [Hz]".into(),
            y_label: "|L| [dB]".into(),
            log_x: true,
            ..Chart::default()
        },
        Chart {
            x_label: "frequency [Hz]".into(),
            y_label: "phase of L [deg]".into(),
            log_x: true,
            ..Chart::default()
        },
        Chart {
            title: format!(
                "{}: reference step on the exact linear loop (drum angle over the step)",
                r.scenario
            ),
            x_label: "time [s]".into(),
            y_label: "drum angle / step [1]".into(),
            ..Chart::default()
        },
    );
    for (label, s, c, slot) in designs {
        let setup = s
            .closed_loop_setup()
            .map_err(|e| DesignError::Unsuitable(e.to_string()))?;
        for (k, point) in c.margins.iter().enumerate() {
            let lin = LinearLoop::with_half_stiffness(
                setup.params,
                setup.drive,
                point.half_stiffness_n_per_m,
            );
            let hi = lin.nyquist_hz() * 0.999;
            let freqs: Vec<f64> = (0..600)
                .map(|i| 1.0 * (hi / 1.0).powf(i as f64 / 599.0))
                .collect();
            let l: Vec<_> = freqs.iter().map(|&f| lin.loop_gain(f)).collect();
            let name = format!(
                "{}, {}",
                design_label(label, c, r.feedforward),
                point.condition
            );
            let line = |y: Vec<f64>| {
                let s = Series::line(name.clone(), freqs.clone(), y);
                if k == 0 {
                    s.in_slot(slot)
                } else {
                    s.in_slot(slot + 1)
                }
            };
            mag.series
                .push(line(l.iter().map(|v| 20.0 * v.norm().log10()).collect()));
            phase
                .series
                .push(line(l.iter().map(|v| v.arg().to_degrees()).collect()));
            if let Some(y) = lin.reference_step(0.1) {
                let t: Vec<f64> = (0..y.len())
                    .map(|i| i as f64 / (2.0 * lin.nyquist_hz()))
                    .collect();
                let s = Series::line(name.clone(), t, y);
                step.series.push(if k == 0 {
                    s.in_slot(slot)
                } else {
                    s.in_slot(slot + 1)
                });
            }
        }
    }
    plot::save_panels(
        &format!(
            "{}: loop gain L of the pick and of the scenario's design",
            r.scenario
        ),
        &[mag, phase],
        &dir.join("bode"),
    )?;
    if !step.series.is_empty() {
        plot::save_chart(&step, &dir.join("step"))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::tune::Gains;

    fn design(rate_hz: f64, load_feedforward: bool) -> Candidate {
        Candidate {
            gains: Gains {
                kp: 1.0,
                ki: 0.0,
                kd: 0.0,
            },
            rate_hz,
            load_feedforward,
            origin: "scenario",
            linear_compliance_mrad_per_nm: None,
            margins: Vec::new(),
            signable: true,
            status: "complete".into(),
            peak_mrad: Some(0.05),
            rms_mrad: Some(0.01),
            passes: true,
            margin_class: Some(0.1),
            failing: Vec::new(),
            on_front: false,
        }
    }

    /// A design drawn among candidates of another rate or feedforward setting says so.
    #[test]
    fn a_design_is_named_with_its_own_rate_and_an_unsearched_feedforward() {
        let own = design(20000.0, false);
        assert_eq!(
            design_label("scenario's design", &own, Feedforward::Without),
            "scenario's design (20000 Hz)"
        );
        let with = design(20000.0, true);
        assert_eq!(
            design_label("scenario's design", &with, Feedforward::Without),
            "scenario's design (20000 Hz, with load feedforward)"
        );
        assert_eq!(
            design_label("pick", &design(10000.0, true), Feedforward::Both),
            "pick (10000 Hz)"
        );
    }
}
