//! Diagnosis output: JSON, a one-minute text report, traces, plots, and the extended model
//! as a scenario file.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::identify::{Diagnosis, EffectName, IdentifyError};
use crate::scenario::Scenario;

/// Ljung-Box p-value below which the report says the residual is not white, so that its
/// `+-` (which assume it is) understate the spread: 0.01.
const WHITE_P: f64 = 0.01;

fn wr(path: &Path, text: &str) -> Result<(), IdentifyError> {
    std::fs::write(path, text).map_err(|e| IdentifyError::Write {
        path: path.display().to_string(),
        message: e.to_string(),
    })
}

/// The text an engineer reads first.
pub fn summary_text(d: &Diagnosis) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Diagnosis of {} log(s): {}",
        d.logs.len(),
        d.logs.join(", ")
    );
    let _ = writeln!(s, "Held out: {}", d.holdout);
    if let Some(c) = &d.calibrated_model {
        let play = d
            .play_operator
            .as_ref()
            .map(|p| {
                format!(
                    "; a play operator fitted here: {:.2} mrad held out",
                    p.rmse_heldout_mrad
                )
            })
            .unwrap_or_default();
        let refitted = match c.refitted_per_log.as_slice() {
            [] | [_] => "only each log's encoder zero fitted".to_string(),
            [zero, terms @ ..] => format!(
                "only each log's {zero} and its own {} fitted",
                terms.join(", ")
            ),
        };
        let given = match (c.rmse_mrad, &c.cannot_carry) {
            (Some(r), _) => format!(
                "{} mrad RMS ({} mrad held out, where the search on top starts)",
                crate::significant(r, 3),
                crate::significant(c.held_out_mrad, 3)
            ),
            (None, Some(f)) => format!("cannot carry the load: {}", f.fault),
            (None, None) => "no replay".to_string(),
        };
        let _ = writeln!(
            s,
            "Calibrated model of the scenario, as given ({refitted}): {given}; the base capstan model recalibrated here: {:.2} mrad held out{play}.",
            d.rmse_base_mrad
        );
        if let Some(f) = &c.cannot_carry {
            let [(p0, p1), (m0, m1)] = [
                (f.preload_n[0], f.preload_n[1]),
                (f.friction_coefficient[0], f.friction_coefficient[1]),
            ];
            let raised = if p1 != p0 {
                format!("preload, weakly pinned where the load never reverses, raised here to the least that carries this log (in steps of 5 %), everything else as calibrated: {p0:.2} -> {p1:.2} N")
            } else {
                format!("friction coefficient raised here to the least that carries this log (in steps of 5 %), everything else as calibrated: {m0:.4} -> {m1:.4}")
            };
            let _ = writeln!(
                s,
                "Its {raised}; the search below runs on that drive. Recalibrate the instrument with this log."
            );
        }
        for t in &c.per_log_terms {
            let values: Vec<String> = t
                .values
                .iter()
                .map(|v| {
                    format!(
                        "{} {:+.3e} {} added to the calibrated value",
                        v.effect, v.value, v.unit
                    )
                })
                .collect();
            let _ = writeln!(s, "  {}: {}", t.log, values.join(", "));
        }
        // A replay that stopped beats nothing.
        let rmse = c.rmse_mrad.unwrap_or(f64::INFINITY);
        let beats_play = d
            .play_operator
            .as_ref()
            .is_none_or(|p| rmse < p.rmse_heldout_mrad);
        let (on, shows) = if d.logs.len() > 1 {
            ("on these logs", "these logs show")
        } else {
            ("on this log", "this log shows")
        };
        let verdict = match (rmse < d.rmse_base_mrad, beats_play) {
            (true, true) => format!("The calibrated model beats both {on}"),
            (true, false) => format!("The calibrated model beats the base model but not the play operator {on}"),
            (false, true) => format!("The calibrated model beats the play operator but not the recalibrated base model {on}"),
            (false, false) => format!("The calibrated model beats neither {on}: the instrument has changed, or {shows} what its calibration did not see"),
        };
        let follows = c
            .residual_signatures
            .first()
            .filter(|g| g.ratio_to_floor > 1.0)
            .map(|g| {
                format!(
                    "; what it leaves follows {} most ({:.2} mrad, {:.1}x the noise floor)",
                    g.variable, g.binned_rms_mrad, g.ratio_to_floor
                )
            })
            .unwrap_or_default();
        let _ = writeln!(s, "{verdict}{follows}.");
        let searched: Vec<&str> = d
            .candidates
            .iter()
            .filter(|c| c.round == 1 && !c.name.contains(" + "))
            .map(|c| c.name.as_str())
            .collect();
        let _ = if searched.is_empty() && !d.searchable.is_empty() {
            writeln!(
                s,
                "Nothing was searched on top of it: what it leaves is within {:.0} % of the noise floor (candidates: {}).",
                100.0 * (crate::identify::SEARCH_ENDS_WITHIN - 1.0),
                d.searchable.join(", ")
            )
        } else if searched.is_empty() {
            writeln!(
                s,
                "Nothing was searched on top of it: it already carries every candidate effect ([identify] candidates){}.",
                if c.refitted_per_log.len() > 1 {
                    " or refits it per log"
                } else {
                    ""
                }
            )
        } else {
            writeln!(
                s,
                "What is still missing was searched on top of it ({}): {}, only each log's zero and the candidates fitted.",
                searched.join(", "),
                if c.cannot_carry.is_some() {
                    "its drive as raised above and its effects held as calibrated"
                } else {
                    "its drive and effects held as calibrated"
                }
            )
        };
        if !c.held_not_refitted.is_empty() {
            let quoted: Vec<String> = c
                .held_not_refitted
                .iter()
                .map(|e| format!("\"{e}\""))
                .collect();
            let (tried, not_tried): (Vec<&String>, Vec<&String>) =
                c.held_not_refitted.iter().partition(|e| {
                    d.searchable
                        .iter()
                        .any(|k| *k == crate::identify::resized_label(e))
                });
            let join = |v: &[&String]| v.iter().map(|e| e.as_str()).collect::<Vec<_>>().join(", ");
            if !tried.is_empty() {
                let _ = writeln!(
                    s,
                    "Held at the calibrated size in the replay; the search on top {} each at one other size shared by the logs judged: {}.",
                    if searched.is_empty() { "would try" } else { "tries" },
                    join(&tried)
                );
            }
            if !not_tried.is_empty() {
                let _ = writeln!(
                    s,
                    "Held at the calibrated size and not searched again (not among the candidates searched): {}. A log whose own size differs shows the difference as something else.",
                    join(&not_tried)
                );
            }
            let _ = writeln!(
                s,
                "To refit on each log instead: --set 'identify.per_log=[{}]'.",
                quoted.join(",")
            );
        }
    }
    for (log, columns) in &d.ignored_columns {
        let _ = writeln!(
            s,
            "Columns ignored in {log} (not in the bench-log format): {}",
            columns.join(", ")
        );
    }
    for c in d.start_cuts.iter().filter(|c| c.cut_s > 0.0) {
        let _ = writeln!(s, "Start-up: {}: {}", c.log, c.reason);
    }
    for g in &d.excluded_segments {
        let _ = writeln!(s, "{}", crate::identify::segments::describe(g));
    }
    for f in &d.fits_on_limit {
        let _ = writeln!(
            s,
            "Not converged: {f}; its parameters are the best it reached"
        );
    }
    for b in &d.params_on_bound {
        let _ = writeln!(s, "On a bound: {b}");
    }
    let lost_to_play = d
        .play_operator
        .as_ref()
        .filter(|_| d.beats_play_operator == Some(false) && !d.causes.is_empty());
    let against_base = if d.rmse_extended_mrad < d.rmse_base_mrad {
        "improves on the base model".to_string()
    } else {
        format!(
            "does not improve on the base model recalibrated on the log(s) ({:.2} mrad)",
            d.rmse_base_mrad
        )
    };
    let unpinned =
        crate::identify::unpinned(&d.candidates, d.rmse_extended_mrad, d.noise_floor_mrad);
    let missing = match unpinned.first() {
        Some(c) => format!(
            "{} would bring it to the noise, but these logs cannot pin its size (below)",
            c.name
        ),
        None => "the drive does something the library does not hold".to_string(),
    };
    let verdict = match (d.cause.as_str(), lost_to_play) {
        ("unexplained", Some(p)) => format!(
            "not established: the extended model with {} {against_base} and loses to a play operator (deadband) fitted to the same log(s), held out ({:.2} against {:.2} mrad); {missing}",
            d.causes.join(" and "),
            d.rmse_extended_mrad,
            p.rmse_heldout_mrad
        ),
        ("none", _) if d.calibrated_model.is_some() => {
            "nothing beyond sensor noise: the scenario's calibrated model explains the data"
                .to_string()
        }
        ("none", _) => "nothing beyond sensor noise: the calibrated base model explains the data".to_string(),
        ("unexplained", None) if !unpinned.is_empty() => format!("structure remains; {missing}"),
        ("unexplained", None) => "structure remains that no effect in the library explains (look at the residual plots: resonance, sensor fault, load not logged?)".to_string(),
        (c, _) => {
            let m = c.parse::<EffectName>().map(|e| e.meaning()).unwrap_or("");
            let other = if d.resized.iter().any(|r| r.effect == c) {
                " at another size than calibrated"
            } else {
                ""
            };
            format!("{c}{other} ({m})")
        }
    };
    let _ = writeln!(s, "\nCAUSE: {verdict}");
    // A size with its unit; a ratio's unit "1" is left out.
    let sized = |v: f64, unit: &str| match unit {
        "" | "1" => crate::compact(v),
        u => format!("{} {u}", crate::compact(v)),
    };
    for r in &d.resized {
        // The parameter table's judgement of the size, so the two never disagree.
        let (spread, unpinned) = match d.not_identifiable.iter().find(|n| n.name == r.effect) {
            Some(n) => (
                sized(r.found, &r.unit),
                format!("; not identifiable: {}", n.reason),
            ),
            None => (
                format!("{} +- {}", crate::compact(r.found), sized(r.std, &r.unit)),
                String::new(),
            ),
        };
        let _ = writeln!(
            s,
            "  {}: {} calibrated, {spread} on the logs judged (one size for them all){unpinned}",
            r.effect,
            sized(r.calibrated, &r.unit),
        );
        if r.per_log.len() > 1 {
            let each: Vec<String> = r
                .per_log
                .iter()
                .map(|(log, v)| format!("{log} {}", sized(*v, &r.unit)))
                .collect();
            let _ = writeln!(
                s,
                "  each log alone: {}; where they differ, refit it on each log: --set 'identify.per_log=[\"{}\"]'",
                each.join(", "),
                r.effect
            );
        }
    }
    for d in &d.directions {
        let unit = d
            .effect
            .parse::<EffectName>()
            .map(|e| e.unit())
            .unwrap_or("");
        let _ = writeln!(
            s,
            "  {} = {}: {}",
            d.effect,
            sized(d.value, unit),
            d.meaning
        );
    }
    // A cause is named on held-out error; its size is judged apart, and the table's
    // judgement of it (the residual's runs allowed for) is said here, beside the name.
    for c in d
        .causes
        .iter()
        .filter(|c| !d.resized.iter().any(|r| &r.effect == *c))
    {
        if let Some(n) = d.not_identifiable.iter().find(|n| &n.name == c) {
            let _ = writeln!(
                s,
                "  {c}: the held-out error needs it, but this size is not identifiable: {}",
                n.reason
            );
        }
    }
    if d.causes.len() > 1 && d.cause != "unexplained" {
        let named: Vec<String> = d
            .causes
            .iter()
            .map(|c| {
                if d.resized.iter().any(|r| r.effect == *c) {
                    crate::identify::resized_label(c)
                } else {
                    c.clone()
                }
            })
            .collect();
        let _ = writeln!(
            s,
            "All effects found, strongest first: {}",
            named.join(", ")
        );
    }
    for t in &d.indistinguishable {
        let names: Vec<&str> = t.alternatives.iter().map(|a| a.name.as_str()).collect();
        let rmses: Vec<String> = t
            .alternatives
            .iter()
            .map(|a| format!("{:.4}", a.rmse_heldout_mrad))
            .collect();
        let _ = writeln!(
            s,
            "Not told apart: {}, or in its place {} (the effects found: {:.4} mrad held out; with each in its place {} mrad): each leaves at most {:.0} % more structure above the noise or comes within {:.1} % of its error, so these data cannot tell them apart; logs at other loads, speeds or strokes can",
            t.accepted,
            names.join(" or "),
            t.rmse_heldout_mrad,
            rmses.join(", "),
            100.0 * crate::identify::TIE_FRACTION,
            100.0 * crate::identify::TIE_RMSE_FRACTION
        );
    }
    for c in &unpinned {
        let _ = writeln!(
            s,
            "Not pinned: {} brings the held-out error to {:.4} mrad, within the noise, against {:.4} for the effects found, but its size cannot be told from zero ({}): these logs cannot tell it from the base parameters it trades against; logs at other loads, speeds or strokes can",
            c.name,
            c.rmse_heldout_mrad,
            d.rmse_extended_mrad,
            c.verdict.trim_start_matches(crate::identify::SIZE_VERDICT)
        );
    }
    let extended = if d.calibrated_model.is_some() {
        "extended (the calibrated model and what was found on top)"
    } else {
        "extended"
    };
    let _ = writeln!(
        s,
        "\nHeld-out RMS transmission error: base {:.4} mrad -> {extended} {:.4} mrad ({:+.1} %), noise floor {:.4} mrad",
        d.rmse_base_mrad, d.rmse_extended_mrad, -d.gain_percent, d.noise_floor_mrad
    );
    if let Some(p) = &d.play_operator {
        let _ = writeln!(
            s,
            "Play-operator (deadband) model for comparison: {:.4} mrad held out: the extended model {} it",
            p.rmse_heldout_mrad,
            if d.rmse_extended_mrad < p.rmse_heldout_mrad {
                "beats"
            } else {
                "does not beat"
            }
        );
    }
    if let Some(w) = &d.residual_whiteness {
        let _ = writeln!(
            s,
            "Residual whiteness (Ljung-Box, {} lags, {} samples): Q = {:.1}, p = {:.2e} (second opinion; the noise-floor test decides)",
            w.lags,
            w.samples,
            w.q,
            w.p_value,
        );
    }
    if d.unexplained_structure && d.cause != "unexplained" {
        let _ = writeln!(
            s,
            "Residual is still {:.1}x the noise floor: more is going on than the model holds.",
            d.structure_ratio
        );
    }
    if !d.residual_signatures.is_empty() {
        let _ = writeln!(
            s,
            "Extended-model residual along each variable (RMS of its means in 20 equal-count bins, x noise floor): {}",
            d.residual_signatures
                .iter()
                .map(|g| format!(
                    "{} {:.3} mrad ({:.1}x)",
                    g.variable, g.binned_rms_mrad, g.ratio_to_floor
                ))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    if let Some(g) = d
        .residual_signatures
        .first()
        .filter(|g| g.ratio_to_floor > 1.0 && (d.unexplained_structure || d.cause == "unexplained"))
    {
        let _ = writeln!(
            s,
            "The structure that remains follows {} most: see residual_extended.png, panel \"against {}\".",
            g.variable, g.variable
        );
    }
    let _ = writeln!(s, "\nParameters (value +- 1 sigma):");
    if let Some(line) = runs_note(d) {
        let _ = writeln!(s, "  ({line})");
    }
    for p in &d.params {
        match d.not_identifiable.iter().find(|n| n.name == p.name) {
            Some(n) => {
                let _ = writeln!(
                    s,
                    "  {:<28} {:>14.6e}    {}; not identifiable: {}",
                    p.name, p.value, p.unit, n.reason
                );
            }
            // No spread at all, or exactly zero, is a value the fit held (a weight kept at
            // zero by its bound), not one it pinned exactly.
            None if p.std == 0.0 || p.value == 0.0 => {
                let _ = writeln!(
                    s,
                    "  {:<28} {:>14.6e}    {}; held on its bound, not fitted freely",
                    p.name, p.value, p.unit
                );
            }
            None => {
                let _ = writeln!(
                    s,
                    "  {:<28} {:>14.6e} +- {:<10.2e} {}",
                    p.name, p.value, p.std, p.unit
                );
            }
        }
    }
    let _ = if d.candidates.is_empty() {
        writeln!(s, "\nCandidates: none judged")
    } else {
        writeln!(
            s,
            "\nCandidates (held-out RMSE, gain, share of structure explained):"
        )
    };
    // Single candidates line up; a pair's longer name pushes its own row only.
    let width = d
        .candidates
        .iter()
        .filter(|c| !c.name.contains(" + "))
        .map(|c| c.name.len())
        .fold(22, usize::max);
    for c in &d.candidates {
        let _ = writeln!(
            s,
            "  round {} {:<width$} {:.4} mrad {:+6.1} % {:5.2}  {}",
            c.round, c.name, c.rmse_heldout_mrad, c.gain_percent, c.explained_fraction, c.verdict
        );
    }
    s
}

/// Widening of a `+-` by the residual's runs above which the report says so even when the
/// Ljung-Box test passes: on white residuals the batch estimate alone scatters the largest
/// widening up to about 1.1 (1.02 to 1.07 on the guide's three synthetic logs, 1.09 on the
/// clean log of `a_residual_in_runs_widens_the_uncertainties_and_says_so`).
const RUNS_NOTE_WIDENING: f64 = 1.25;

/// What the residual's runs did to the `+-`, in words, when the residual is not white or
/// the runs widened a `+-` by more than [`RUNS_NOTE_WIDENING`].
fn runs_note(d: &Diagnosis) -> Option<String> {
    let white = d
        .residual_whiteness
        .as_ref()
        .filter(|w| w.p_value < WHITE_P)
        .map(|w| {
            format!(
                "this residual is not white (Ljung-Box p = {:.1e})",
                w.p_value
            )
        });
    let Some(r) = &d.residual_runs else {
        return white.map(|w| {
            format!("The +- assume a white residual and {w}: its errors come in runs, and the spread of a size refitted on other data can be several times its +-.")
        });
    };
    if white.is_none() && r.max_widening <= RUNS_NOTE_WIDENING {
        return None;
    }
    let mut line = format!(
        "The +- allow for a residual that comes in runs: correlated over about {} samples ({} s), so each +- is {}; that widened them by a median {:.2}x, at most {:.1}x ({})",
        crate::compact((r.correlation_samples * 10.0).round() / 10.0),
        crate::compact(r.correlation_s),
        crate::identify::uncertainty_sources(r, ""),
        r.median_widening,
        r.max_widening,
        if r.max_widening_parameter.is_empty() { "none" } else { &r.max_widening_parameter },
    );
    if let Some(w) = white {
        line.push_str(&format!("; {w}"));
    }
    if r.batch_capped {
        line.push_str("; the residual is correlated over more than a quarter of the longest stretch of a log can hold, so even these understate how far a size refitted on other data moves");
    }
    line.push('.');
    Some(line)
}

/// Write `diagnosis.json`, `report.txt`, `traces.csv` and plots into `dir`; returns the
/// files written. `json_path` overrides where the JSON goes.
pub fn write_diagnosis(
    dir: &Path,
    scenario: &Scenario,
    diagnosis: &Diagnosis,
    json_path: Option<&Path>,
) -> Result<Vec<PathBuf>, IdentifyError> {
    std::fs::create_dir_all(dir).map_err(|e| IdentifyError::Write {
        path: dir.display().to_string(),
        message: e.to_string(),
    })?;
    let mut files = Vec::new();
    let encode_err = |e: serde_json::Error| IdentifyError::Write {
        path: "diagnosis.json".into(),
        message: e.to_string(),
    };
    // The diagnosis records what made it, as every result does.
    let record = crate::report::with_provenance(
        scenario,
        true,
        &serde_json::to_value(diagnosis).map_err(encode_err)?,
    );
    let json = serde_json::to_string_pretty(&record).map_err(encode_err)?;
    let jp = json_path
        .map(Path::to_path_buf)
        .unwrap_or_else(|| dir.join("diagnosis.json"));
    wr(&jp, &json)?;
    files.push(jp);
    let rp = dir.join("report.txt");
    wr(&rp, &summary_text(diagnosis))?;
    files.push(rp);
    let mut csv = String::from("log,t_s,theta_in_rad,theta_out_rad,velocity_rad_s,load_nm,measured_rad,base_rad,extended_rad,residual_rad\n");
    for (k, t) in diagnosis.traces.iter().enumerate() {
        for i in 0..t.t_s.len() {
            let _ = writeln!(
                csv,
                "{k},{:.5},{:.7},{:.7},{:.6},{:.6},{:.4e},{:.4e},{:.4e},{:.4e}",
                t.t_s[i],
                t.theta_in_rad[i],
                t.theta_out_rad[i],
                t.velocity_rad_s[i],
                t.load_nm.get(i).copied().unwrap_or(f64::NAN),
                t.measured_rad[i],
                t.base_rad[i],
                t.extended_rad[i],
                t.measured_rad[i] - t.extended_rad[i]
            );
        }
    }
    let cp = dir.join("traces.csv");
    wr(&cp, &csv)?;
    files.push(cp);
    files.extend(plots(dir, diagnosis)?);
    Ok(files)
}

/// Error traces and residual signatures: the shape of the residual against time, input
/// angle, output angle, transmitted load and velocity is what names a cause.
fn plots(dir: &Path, d: &Diagnosis) -> Result<Vec<PathBuf>, IdentifyError> {
    use crate::plot::{save_chart, save_panels, Chart, HBand, Series, XShade};
    // Stretches flagged as not the drive, shaded on a log's time axis.
    let shades = |t: &crate::identify::Trace| -> Vec<XShade> {
        t.excluded
            .iter()
            .map(|(lo, hi, label)| XShade {
                lo: *lo,
                hi: *hi,
                label: label.clone(),
            })
            .collect()
    };
    let perr = |e: crate::plot::PlotError| IdentifyError::Write {
        path: dir.display().to_string(),
        message: e.to_string(),
    };
    let mut files = Vec::new();
    let short = |s: &str| {
        Path::new(s)
            .file_stem()
            .and_then(|x| x.to_str())
            .unwrap_or(s)
            .to_string()
    };
    let mut error_charts = Vec::new();
    for t in &d.traces {
        // A log whose encoders were zeroed a turn apart sits a constant away from the
        // others; each panel shows its curves about the measured mean, and says by how
        // much (traces.csv keeps the values as they are).
        let finite: Vec<f64> = t
            .measured_rad
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .collect();
        let mean = if finite.is_empty() {
            0.0
        } else {
            finite.iter().sum::<f64>() / finite.len() as f64
        };
        let mr = |v: &[f64]| v.iter().map(|x| (x - mean) * 1e3).collect::<Vec<f64>>();
        error_charts.push(Chart {
            title: format!(
                "{}{}: transmission error, measured mean {:.1} mrad removed",
                short(&t.log),
                if t.held_out { " (held out)" } else { "" },
                mean * 1e3
            ),
            x_label: "time [s]".into(),
            y_label: "error [mrad]".into(),
            series: vec![
                Series::points("measured", t.t_s.clone(), mr(&t.measured_rad)),
                Series::line("base model", t.t_s.clone(), mr(&t.base_rad)),
                Series::line("extended model", t.t_s.clone(), mr(&t.extended_rad)),
            ],
            x_shades: shades(t),
            ..Chart::default()
        });
    }
    files.extend(
        save_panels(
            "Measured, base and extended transmission error",
            &error_charts,
            &dir.join("error"),
        )
        .map_err(perr)?,
    );
    let floor = d.noise_floor_mrad;
    let band = || HBand {
        lo: -floor,
        hi: floor,
        label: "noise floor".into(),
    };
    let against =
        |label: &str, f: &dyn Fn(&crate::identify::Trace) -> Vec<f64>, base: bool| -> Chart {
            Chart {
                title: format!(
                    "{} residual against {label}",
                    if base { "base-model" } else { "extended-model" }
                ),
                x_label: label.into(),
                y_label: "residual [mrad]".into(),
                series: d
                    .traces
                    .iter()
                    .map(|t| {
                        let model = if base { &t.base_rad } else { &t.extended_rad };
                        let r: Vec<f64> = t
                            .measured_rad
                            .iter()
                            .zip(model)
                            .map(|(m, p)| (m - p) * 1e3)
                            .collect();
                        Series::points(short(&t.log), f(t), r)
                    })
                    .collect(),
                bands: vec![band()],
                ..Chart::default()
            }
        };
    for base in [true, false] {
        let charts = vec![
            Chart {
                // Every log's flagged stretches on the shared time axis, named by log when
                // there are several.
                x_shades: d
                    .traces
                    .iter()
                    .flat_map(|t| {
                        shades(t).into_iter().map(|mut s| {
                            if d.traces.len() > 1 {
                                s.label = format!("{}: {}", short(&t.log), s.label);
                            }
                            s
                        })
                    })
                    .collect(),
                ..against("time [s]", &|t| t.t_s.clone(), base)
            },
            against("input angle [rad]", &|t| t.theta_in_rad.clone(), base),
            against("output angle [rad]", &|t| t.theta_out_rad.clone(), base),
            against("transmitted load [N m]", &|t| t.load_nm.clone(), base),
            against(
                "input velocity [rad/s]",
                &|t| t.velocity_rad_s.clone(),
                base,
            ),
        ];
        let stem = if base {
            "residual_base"
        } else {
            "residual_extended"
        };
        files.extend(
            save_panels(
                &format!("Residual signatures ({stem})"),
                &charts,
                &dir.join(stem),
            )
            .map_err(perr)?,
        );
    }
    // Candidates by name on the y axis (first at the top), their held-out RMSE along x,
    // accepted ones apart; the model they were added to as a vertical line to beat.
    let round_one: Vec<&crate::identify::CandidateScore> =
        d.candidates.iter().filter(|c| c.round == 1).collect();
    let n = round_one.len();
    let row = |i: usize| (n - i) as f64;
    let names: Vec<(f64, String)> = round_one
        .iter()
        .enumerate()
        .map(|(i, c)| {
            (
                row(i),
                // Three significant digits: an effect that brings a log to its noise
                // floor sits at a few thousandths of a mrad, which two decimals round
                // to 0.01.
                format!(
                    "{} ({} mrad)",
                    c.name,
                    crate::significant(c.rmse_heldout_mrad, 3)
                ),
            )
        })
        .collect();
    let pick = |accepted: bool| -> (Vec<f64>, Vec<f64>) {
        round_one
            .iter()
            .enumerate()
            .filter(|(_, c)| c.accepted == accepted)
            .map(|(i, c)| (c.rmse_heldout_mrad, row(i)))
            .unzip()
    };
    let (rx, ry) = pick(false);
    let (ax, ay) = pick(true);
    // On a calibrated instrument the candidates were added to it, not to the base model.
    let (start, start_mrad) = match &d.calibrated_model {
        Some(c) => ("calibrated model", c.held_out_mrad),
        None => ("base model", d.rmse_base_mrad),
    };
    let series = vec![
        Series::points("not accepted", rx, ry).in_slot(0),
        Series::points("accepted", ax, ay).in_slot(2),
        Series::line(
            format!("{start} ({} mrad)", crate::significant(start_mrad, 3)),
            vec![start_mrad, start_mrad],
            vec![0.5, n as f64 + 0.5],
        )
        .in_slot(7),
    ];
    let cands = Chart {
        title: format!("Held-out RMSE of each candidate effect added to the {start} (round 1)"),
        x_label: "held-out RMSE [mrad]".into(),
        y_label: "candidate effect".into(),
        series,
        y_range: Some((0.5, n.max(1) as f64 + 0.5)),
        y_names: names,
        ..Chart::default()
    };
    files.extend(save_chart(&cands, &dir.join("candidates")).map_err(perr)?);
    Ok(files)
}

/// Write the calibrated drive and the identified effects as a scenario TOML the closed loop
/// can compensate with (`[effects]` section).
pub fn save_model(
    path: &Path,
    scenario: &Scenario,
    diagnosis: &Diagnosis,
) -> Result<(), IdentifyError> {
    let mut s = scenario.clone();
    s.drive = diagnosis.drive.clone();
    s.effects = Some(diagnosis.effects.clone());
    calibrated_identity(
        &mut s,
        &format!(
            "calibrated on {} (held-out RMSE {:.4} mrad; cause: {})",
            diagnosis.logs.join(", "),
            diagnosis.rmse_extended_mrad,
            diagnosis.cause
        ),
    );
    let text = toml::to_string(&s).map_err(|e| IdentifyError::Write {
        path: path.display().to_string(),
        message: e.to_string(),
    })?;
    let header = format!(
        "# Calibrated from {} (held-out RMSE base {:.4} mrad, extended {:.4} mrad; cause: {})\n",
        diagnosis.logs.join(", "),
        diagnosis.rmse_base_mrad,
        diagnosis.rmse_extended_mrad,
        diagnosis.cause
    );
    wr(path, &(header + &text))
}

/// Names a saved model after what it now is: `<name>_calibrated` (an `_uncalibrated` or
/// `_calibrated` suffix replaced) with a description of what it was calibrated on, so a
/// model calibrated from `davinci_tool4_uncalibrated` does not describe itself as "before
/// calibration" above calibrated values.
pub fn calibrated_identity(s: &mut Scenario, calibrated_on: &str) {
    let name = s.name().to_string();
    let stem = name
        .strip_suffix("_uncalibrated")
        .or_else(|| name.strip_suffix("_calibrated"))
        .unwrap_or(&name)
        .to_string();
    s.name = Some(format!("{stem}_calibrated"));
    s.description = Some(format!("{stem} {calibrated_on}"));
}
