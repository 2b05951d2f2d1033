//! `report.html`: one self-contained page per results directory, made from the records the
//! run already wrote (`summary.json` or the command's own JSON record, `sweep.csv`) and
//! the SVG figures beside them. Nothing is computed again: the page is a view of those
//! records, with numbers formatted as the console prints them.
//!
//! The page carries everything inline (figures as SVG, a small style sheet) and refers to
//! no URL at all, so it opens the same from a mail attachment as from the directory.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::ReportError;

/// File name of the report inside a results directory.
pub const REPORT_FILE: &str = "report.html";

/// Figures inlined at most; a sweep with per-case figures could otherwise make a page of
/// hundreds of megabytes. The rest are named in the warnings.
const MAX_FIGURES: usize = 40;

/// Records a results directory may hold, in the order they are looked for: every run's
/// `summary.json`, then the records of commands that write no summary.
const RECORDS: [&str; 4] = [
    "summary.json",
    "least_rate.json",
    "diagnosis.json",
    "leave_one_out.json",
];

/// Writes `report.html` into the results directory `dir` (atomically) from the records
/// and SVG figures already there, and returns its path.
///
/// Call it after `summary.json` and the figures are written. A missing record gives a
/// page that says so; an unreadable one is an error.
pub fn write_report(dir: &Path) -> Result<PathBuf, ReportError> {
    write_report_with(dir, &[], None)
}

/// [`write_report`] with the run's warnings (those not kept in its record, such as figures
/// that could not be drawn) and, for a run that stopped early, the reason it stopped.
pub fn write_report_with(
    dir: &Path,
    warnings: &[String],
    stopped: Option<&str>,
) -> Result<PathBuf, ReportError> {
    let (record_name, record) = read_record(dir)?;
    let mut page = Page::default();
    page.warnings.extend(warnings.iter().cloned());
    describe(dir, record_name, &record, stopped, &mut page)?;
    let figures = collect_figures(dir, &mut page.warnings);
    let html = render(&page, &record, record_name, &figures);
    let path = dir.join(REPORT_FILE);
    crate::io::output::write_atomic(&path, html.as_bytes())
        .map_err(|e| ReportError::io(&path, std::io::Error::other(e.to_string())))?;
    Ok(path)
}

/// The record of the run: its file name and content (`Value::Null` when there is none).
fn read_record(dir: &Path) -> Result<(&'static str, Value), ReportError> {
    for name in RECORDS {
        let path = dir.join(name);
        match std::fs::read(&path) {
            Ok(bytes) => {
                let value = serde_json::from_slice(&bytes).map_err(|e| ReportError::Encode {
                    path: path.clone(),
                    message: format!("not a readable record: {e}"),
                })?;
                return Ok((name, value));
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(ReportError::io(&path, e)),
        }
    }
    Ok(("", Value::Null))
}

/// The verdict of a results directory.
#[derive(Debug, Default)]
enum Outcome {
    /// Every requirement met.
    Pass(String),
    /// A requirement is not met.
    NotMet(String),
    /// The run stopped before its end.
    Stopped(String),
    /// Nothing is judged for this command or study.
    #[default]
    NotJudged,
}

/// One requirement as the page shows it.
#[derive(Debug, Default)]
struct Row {
    /// Requirement's identifier (`phase_margin`) or a figure's name.
    requirement: String,
    /// Where it was judged.
    condition: String,
    measured: Option<f64>,
    /// Relation and limit (`>=`, 35).
    limit: Option<(String, f64)>,
    margin: Option<f64>,
    unit: String,
    /// `None` where the record gives no pass or fail for the row.
    passes: Option<bool>,
    note: String,
}

/// A table of rows under a heading.
#[derive(Debug, Default)]
struct Table {
    /// Names the table for readers of the page's source (`verdict`, `design:NAME`).
    key: String,
    heading: String,
    rows: Vec<Row>,
}

/// What the page says, in its order.
#[derive(Debug, Default)]
struct Page {
    title: String,
    subtitle: Vec<String>,
    outcome: Outcome,
    /// Failing requirements or other reasons, in words, under the verdict.
    reasons: Vec<String>,
    tables: Vec<Table>,
    /// Plain text records shown as they are (a diagnosis report).
    texts: Vec<(String, String)>,
    warnings: Vec<String>,
    incomplete: bool,
}

fn num(v: &Value) -> Option<f64> {
    v.as_f64().filter(|x| x.is_finite())
}

fn text(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        Value::Null => String::new(),
        other => other.to_string(),
    }
}

/// A number as the console prints it (four significant digits, no trailing zeros).
fn fmt(v: f64) -> String {
    crate::compact(v)
}

fn fmt_opt(v: Option<f64>) -> String {
    v.map_or_else(|| "\u{2014}".to_string(), fmt)
}

/// `phase margin (free span): 24.1 deg, required >= 35 deg; at 31 Hz`, as
/// `analysis::verdict::Check::sentence` words it.
fn sentence(row: &Row) -> String {
    let unit = |v: f64| {
        if row.unit.is_empty() {
            fmt(v)
        } else {
            format!("{} {}", fmt(v), row.unit)
        }
    };
    let mut s = format!(
        "{} ({}): {}",
        row.requirement.replace('_', " "),
        row.condition,
        row.measured.map_or_else(|| "no value".to_string(), unit)
    );
    if let Some((rel, limit)) = &row.limit {
        let _ = write!(s, ", required {rel} {}", unit(*limit));
    }
    if !row.note.is_empty() {
        let _ = write!(s, "; {}", row.note);
    }
    s
}

/// Rows of a `verdict` record (`analysis::verdict::Verdict` serialised).
fn verdict_rows(verdict: &Value) -> Vec<Row> {
    verdict["checks"]
        .as_array()
        .map(|checks| {
            checks
                .iter()
                .map(|c| Row {
                    requirement: text(&c["requirement"]),
                    condition: text(&c["condition"]),
                    measured: num(&c["measured"]),
                    limit: num(&c["limit"]).map(|l| (text(&c["relation"]), l)),
                    margin: num(&c["margin"]),
                    unit: text(&c["unit"]),
                    passes: c["passes"].as_bool(),
                    note: text(&c["note"]),
                })
                .collect()
        })
        .unwrap_or_default()
}

/// Pass or not met from a verdict's rows, with the failing ones in words.
fn verdict_outcome(passes: bool, rows: &[Row], reasons: &mut Vec<String>) -> Outcome {
    let n = rows.len();
    let failing: Vec<&Row> = rows.iter().filter(|r| r.passes == Some(false)).collect();
    reasons.extend(failing.iter().map(|r| sentence(r)));
    if passes {
        Outcome::Pass(format!("meets every requirement ({n} of {n})"))
    } else {
        Outcome::NotMet(format!(
            "misses {} of {n} requirement{}",
            failing.len(),
            if n == 1 { "" } else { "s" }
        ))
    }
}

/// `PID kp 300, ki 2e4, kd 2.5 at 2e4 Hz, feedback motor` from a scenario's controller.
fn controller_words(controller: &Value) -> Option<String> {
    let g = |k: &str| num(&controller[k]).map(fmt);
    Some(format!(
        "PID kp {}, ki {}, kd {} at {} Hz, feedback on the {}",
        g("kp")?,
        g("ki")?,
        g("kd")?,
        g("sample_rate_hz")?,
        text(&controller["feedback"])
    ))
}

/// Why a stopped run stopped: the caller's reason, else `INCOMPLETE.txt`, else the
/// modes' stop messages.
fn stop_reason(dir: &Path, record: &Value, stopped: Option<&str>) -> String {
    if let Some(s) = stopped {
        return s.to_string();
    }
    if let Ok(t) = std::fs::read_to_string(dir.join(crate::io::output::INCOMPLETE_FILE)) {
        let t = t.trim();
        if !t.is_empty() {
            return t.to_string();
        }
    }
    let modes: Vec<String> = record["modes"]
        .as_array()
        .into_iter()
        .flatten()
        .filter(|m| m["completion"]["status"].as_str() != Some("complete"))
        .map(|m| {
            let c = &m["completion"];
            format!(
                "mode {}: {}",
                text(&m["name"]),
                [&c["fault"], &c["message"], &c["kind"], &c["status"]]
                    .into_iter()
                    .map(text)
                    .find(|s| !s.is_empty())
                    .unwrap_or_default()
            )
        })
        .collect();
    if modes.is_empty() {
        "the run stopped before its end".to_string()
    } else {
        modes.join("; ")
    }
}

/// Fill the page from the record, by the shape each command writes.
fn describe(
    dir: &Path,
    record_name: &str,
    record: &Value,
    stopped: Option<&str>,
    page: &mut Page,
) -> Result<(), ReportError> {
    let scenario = &record["scenario"];
    let name = [
        &record["scenario_name"],
        &scenario["name"],
        &record["scenario"],
    ]
    .into_iter()
    .find_map(|v| v.as_str().map(str::to_string))
    .unwrap_or_default();
    let study = [&record["study"], &scenario["study"]]
        .into_iter()
        .map(text)
        .find(|s| !s.is_empty())
        .unwrap_or_default();
    page.incomplete = stopped.is_some() || record["complete"].as_bool() == Some(false);
    if let Some(w) = record["warnings"].as_array() {
        page.warnings.extend(w.iter().map(text));
    }
    let description = text(&scenario["description"]);
    if !description.is_empty() {
        page.subtitle.push(description);
    }
    if let Some(c) = controller_words(&scenario["closed_loop"]["controller"]) {
        page.subtitle.push(c);
    }
    if record["verdict"].is_object() {
        page.title = format!("{} study: {name}", words(&study));
        let rows = verdict_rows(&record["verdict"]);
        let passes = record["verdict"]["passes"].as_bool().unwrap_or(false);
        page.outcome = verdict_outcome(passes, &rows, &mut page.reasons);
        page.tables.push(Table {
            key: "verdict".into(),
            heading: format!(
                "Requirements (judged mode: {})",
                text(&record["verdict"]["judged_mode"])
            ),
            rows,
        });
        if let Some(modes) = record["modes"].as_array() {
            page.tables.push(Table {
                key: "modes".into(),
                heading: format!(
                    "Pointing error [mrad] per compensation mode, over the metrics window{}",
                    window_words(modes)
                ),
                rows: mode_rows(modes),
            });
        }
        if record["freqresp"].is_object() {
            // A frequency response carries the design's verdict beside what it measured:
            // the page's outcome is the verdict, as the command's exit code is.
            page.title = format!("Frequency response: {name}");
            describe_freqresp(record, page, false);
        }
    } else if let Some(designs) = record["designs"].as_array() {
        describe_compare(designs, record, page);
    } else if record["cases_total"].is_number() {
        page.title = format!("Sweep of {name} ({} study)", words(&study));
        describe_sweep(dir, record, page)?;
    } else if record["freqresp"].is_object() {
        page.title = format!("Frequency response: {name}");
        describe_freqresp(record, page, true);
    } else if record["tune"].is_object() {
        describe_tune(dir, record, page);
    } else if record["least_rate"].is_object() {
        describe_least_rate(&record["least_rate"], page);
    } else if record_name.is_empty() {
        page.title = format!(
            "Results in {}",
            dir.file_name().unwrap_or_default().to_string_lossy()
        );
        page.warnings.push(format!(
            "no record ({}) in this directory: the page shows its figures only",
            RECORDS.join(", ")
        ));
    } else {
        // A study without requirements (quasi-static, backlash) or a diagnosis: its key
        // figures as they are recorded.
        // A diagnosis is titled by the logs it read (report.txt's first line, below), not
        // by the study of the scenario it was calibrated for.
        let diagnosis = matches!(record_name, "diagnosis.json" | "leave_one_out.json");
        page.title = if diagnosis {
            String::new()
        } else if study.is_empty() {
            format!("{}: {name}", words(record_name.trim_end_matches(".json")))
        } else {
            format!("{} study: {name}", words(&study))
        };
        let mut rows = Vec::new();
        for key in ["result", "metrics"] {
            scalar_rows(&record[key], "", &mut rows);
        }
        if rows.is_empty() {
            scalar_rows(record, "", &mut rows);
        }
        if !rows.is_empty() {
            page.tables.push(Table {
                key: "figures".into(),
                heading: "Key figures".into(),
                rows,
            });
        }
        if let Ok(t) = std::fs::read_to_string(dir.join("report.txt")) {
            // Its first line names the logs: `Diagnosis of 2 log(s): a.csv, b.csv`.
            if page.title.is_empty() {
                if let Some(first) = t.lines().next().filter(|l| !l.trim().is_empty()) {
                    page.title = first.trim().to_string();
                }
            }
            page.texts.push(("Diagnosis".into(), t));
        }
        // The leave-one-out table and the shared parameters, as the console prints them.
        if let Ok(t) = std::fs::read_to_string(dir.join("leave_one_out.txt")) {
            page.texts.push(("Leave one log out".into(), t));
        }
        if let Some(fault) = record["result"]["fault"].as_str() {
            page.outcome = Outcome::Stopped(fault.to_string());
        }
        if page.title.is_empty() {
            page.title = format!("{}: {name}", words(record_name.trim_end_matches(".json")));
        }
    }
    if page.incomplete && !matches!(page.outcome, Outcome::Stopped(_)) {
        let reason = stop_reason(dir, record, stopped);
        if let Outcome::NotMet(w) | Outcome::Pass(w) = &page.outcome {
            page.reasons.insert(0, format!("verdict of what ran: {w}"));
        }
        page.outcome = Outcome::Stopped(reason);
    }
    Ok(())
}

/// The pointing figures of every mode a closed-loop run simulated, as the console's table
/// gives them: the design is judged in one mode, the others show what compensation buys.
/// A mode that stopped has no figures, only its reason.
fn mode_rows(modes: &[Value]) -> Vec<Row> {
    let mut rows = Vec::new();
    for m in modes {
        let condition = format!("mode {}", text(&m["name"]));
        let stopped = m["completion"]["status"].as_str() != Some("complete");
        if stopped {
            rows.push(Row {
                requirement: "pointing_error".into(),
                condition,
                note: format!(
                    "stopped at {} s: {}",
                    text(&m["completion"]["time_s"]),
                    text(&m["completion"]["fault"])
                ),
                ..Row::default()
            });
            continue;
        }
        for (key, figure) in [
            ("rms_mrad", "rms_error"),
            ("peak_mrad", "peak_error"),
            ("p95_mrad", "p95_error"),
        ] {
            rows.push(Row {
                requirement: figure.into(),
                condition: condition.clone(),
                measured: num(&m[key]),
                unit: "mrad".into(),
                ..Row::default()
            });
        }
    }
    rows
}

/// ` (2 to 20 s)` from the first mode's metrics window, or nothing when none is recorded.
fn window_words(modes: &[Value]) -> String {
    modes
        .iter()
        .find_map(|m| {
            let w = m["metrics"]["window_s"].as_array()?;
            Some(format!(
                " ({} to {} s)",
                fmt(num(w.first()?)?),
                fmt(num(w.get(1)?)?)
            ))
        })
        .unwrap_or_default()
}

/// `closed_loop` to `Closed loop`.
fn words(id: &str) -> String {
    capitalised(&id.replace(['_', '-'], " "))
}

/// `s` with its first letter in capitals.
fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map(|f| f.to_uppercase().collect::<String>() + c.as_str())
        .unwrap_or_default()
}

/// Numeric and short text scalars of a JSON object, as figure rows.
fn scalar_rows(v: &Value, prefix: &str, rows: &mut Vec<Row>) {
    let Some(obj) = v.as_object() else { return };
    for (k, x) in obj {
        // Provenance, shown in its own section.
        if matches!(
            k.as_str(),
            "scenario" | "scenario_name" | "study" | "program" | "program_version" | "complete"
        ) {
            continue;
        }
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        let (measured, note) = match x {
            Value::Number(_) => (num(x), String::new()),
            Value::String(s) if s.len() <= 200 => (None, s.clone()),
            Value::Bool(b) => (None, b.to_string()),
            _ => continue,
        };
        rows.push(Row {
            requirement: key,
            condition: String::new(),
            measured,
            limit: None,
            margin: None,
            unit: String::new(),
            passes: None,
            note,
        });
    }
}

fn describe_compare(designs: &[Value], record: &Value, page: &mut Page) {
    let names: Vec<String> = designs.iter().map(|d| text(&d["name"])).collect();
    page.title = format!("Comparison of designs: {}", names.join(", "));
    let mut failing = 0;
    for d in designs {
        let rows = verdict_rows(&d["verdict"]);
        let passes = d["passes"].as_bool().unwrap_or(false);
        if !passes {
            failing += 1;
            let first = rows
                .iter()
                .find(|r| r.passes == Some(false))
                .map_or_else(|| "no verdict recorded".to_string(), sentence);
            page.reasons
                .push(format!("design {}: {first}", text(&d["name"])));
        }
        if d["completion"]["status"].as_str() != Some("complete") {
            page.warnings.push(format!(
                "design {} stopped: {}",
                text(&d["name"]),
                text(&d["completion"])
            ));
        }
        page.tables.push(Table {
            key: format!("design:{}", text(&d["name"])),
            heading: format!(
                "Design {}: {} ({} mode) \u{2014} {}",
                text(&d["name"]),
                text(&d["description"]),
                text(&d["mode"]),
                if passes {
                    "PASS"
                } else {
                    "requirement not met"
                }
            ),
            rows,
        });
    }
    let n = designs.len();
    page.outcome = if record["all_pass"].as_bool() == Some(true) {
        Outcome::Pass(format!("every design meets every requirement ({n} of {n})"))
    } else {
        Outcome::NotMet(format!(
            "{failing} of {n} designs miss a requirement (a design that stopped counts as missing it)"
        ))
    };
}

/// The `passes` and `failing` columns of `sweep.csv`: (passing, judged, failing reasons).
fn sweep_passes(dir: &Path) -> Result<Option<(usize, usize, Vec<String>)>, ReportError> {
    let path = dir.join("sweep.csv");
    let mut reader = match csv::Reader::from_path(&path) {
        Ok(r) => r,
        Err(e) => {
            return match e.kind() {
                csv::ErrorKind::Io(io) if io.kind() == std::io::ErrorKind::NotFound => Ok(None),
                _ => Err(ReportError::csv(&path, e)),
            }
        }
    };
    let header = reader.headers().map_err(|e| ReportError::csv(&path, e))?;
    let Some(jp) = header.iter().position(|c| c == "passes") else {
        return Ok(None);
    };
    let jf = header.iter().position(|c| c == "failing");
    let (mut passing, mut total, mut failing) = (0, 0, Vec::new());
    for rec in reader.records() {
        let rec = rec.map_err(|e| ReportError::csv(&path, e))?;
        total += 1;
        if rec.get(jp) == Some("true") {
            passing += 1;
        } else if let Some(why) = jf.and_then(|j| rec.get(j)).filter(|s| !s.is_empty()) {
            failing.push(format!("case {}: {why}", total - 1));
        }
    }
    Ok(Some((passing, total, failing)))
}

fn describe_sweep(dir: &Path, record: &Value, page: &mut Page) -> Result<(), ReportError> {
    page.subtitle.push(format!(
        "{} of {} cases written, mode {}",
        text(&record["cases_written"]),
        text(&record["cases_total"]),
        text(&record["mode"])
    ));
    if let Some((passing, total, failing)) = sweep_passes(dir)? {
        const SHOWN: usize = 10;
        page.reasons.extend(failing.iter().take(SHOWN).cloned());
        if failing.len() > SHOWN {
            page.reasons.push(format!(
                "and {} more (sweep.csv, column failing)",
                failing.len() - SHOWN
            ));
        }
        page.outcome = if passing == total {
            Outcome::Pass(format!(
                "every case meets every requirement ({total} of {total})"
            ))
        } else {
            Outcome::NotMet(format!(
                "{} of {total} cases miss a requirement (a stopped case counts as missing)",
                total - passing
            ))
        };
    }
    let mut rows = Vec::new();
    if let Some(outcomes) = record["outcomes"].as_object() {
        for (mode, o) in outcomes {
            for (key, unit) in [
                ("cases", ""),
                ("finished", ""),
                ("stopped", ""),
                ("errors", ""),
                ("meet_target", ""),
                ("pass_rate", ""),
            ] {
                if let Some(v) = num(&o[key]) {
                    rows.push(Row {
                        requirement: key.into(),
                        condition: mode.clone(),
                        measured: Some(v),
                        limit: None,
                        margin: None,
                        unit: unit.into(),
                        passes: None,
                        note: String::new(),
                    });
                }
            }
            for f in o["first_not_finished"].as_array().into_iter().flatten() {
                page.warnings.push(format!(
                    "{mode}, case {}: {}",
                    text(&f["case"]),
                    text(&f["reason"])
                ));
            }
        }
    }
    page.tables.push(Table {
        key: "cases".into(),
        heading: "Cases per mode".into(),
        rows,
    });
    Ok(())
}

/// Rows of estimated or exact margins against the scenario's requirements.
fn margin_rows(margins: &Value, requirements: &Value, condition: &str, rows: &mut Vec<Row>) {
    let items = [
        (
            "phase_margin",
            &margins["phase_margin_deg"],
            ">=",
            &requirements["min_phase_margin_deg"],
            "deg",
        ),
        (
            "gain_margin_up",
            &margins["gain_margin_db"],
            ">=",
            &requirements["min_gain_margin_db"],
            "dB",
        ),
        (
            "gain_margin_down",
            &margins["lower_gain_margin_db"],
            ">=",
            &requirements["min_gain_margin_db"],
            "dB",
        ),
        (
            "sensitivity_peak",
            &margins["ms"],
            "<=",
            &requirements["max_ms"],
            "",
        ),
    ];
    for (req, measured, rel, limit, unit) in items {
        let (measured, limit) = (num(measured), num(limit));
        rows.push(Row {
            requirement: req.into(),
            condition: condition.into(),
            measured,
            limit: limit.map(|l| (rel.to_string(), l)),
            margin: measured
                .zip(limit)
                .map(|(m, l)| if rel == ">=" { m - l } else { l - m }),
            unit: unit.into(),
            passes: None,
            note: String::new(),
        });
    }
}

/// The measured margins per amplitude; with `judged`, the page's outcome from them (a
/// record without the design's verdict).
fn describe_freqresp(record: &Value, page: &mut Page, judged: bool) {
    let f = &record["freqresp"];
    let req = &record["scenario"]["closed_loop"]["requirements"];
    page.subtitle.push(format!(
        "{} at the {}, operating point {}",
        text(&f["transfer"]),
        text(&f["point"]).replace('_', " "),
        text(&f["operating_point"])
    ));
    let mut rows = Vec::new();
    for a in f["amplitudes"].as_array().into_iter().flatten() {
        let cond = format!("amplitude {} {}", text(&a["amplitude"]), text(&a["unit"]));
        margin_rows(&a["margins"], req, &cond, &mut rows);
        // Beside the design's verdict the shortfalls stay in the table, not among the
        // verdict's reasons.
        for s in a["shortfalls"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|_| judged)
        {
            page.reasons.push(format!("{cond}: {}", text(s)));
        }
    }
    margin_rows(
        &f["exact_linear_reference"],
        req,
        "exact linear reference",
        &mut rows,
    );
    if judged {
        page.outcome = match f["passes"].as_bool() {
            Some(true) => Outcome::Pass("every amplitude meets the requirements".into()),
            Some(false) => Outcome::NotMet("an amplitude misses a requirement".into()),
            None => Outcome::NotJudged,
        };
    }
    page.tables.push(Table {
        key: "freqresp".into(),
        heading: "Measured margins per amplitude, and the exact linear reference".into(),
        rows,
    });
}

/// Rows of a tuned candidate (`design::tune::Candidate` serialised).
fn candidate_rows(c: &Value, requirements: &Value, target: Option<f64>, who: &str) -> Vec<Row> {
    let mut rows = Vec::new();
    for m in c["margins"].as_array().into_iter().flatten() {
        let renamed = serde_json::json!({
            "phase_margin_deg": m["phase_margin_deg"],
            "gain_margin_db": m["gain_margin_up_db"],
            "lower_gain_margin_db": m["gain_margin_down_db"],
            "ms": m["ms"],
        });
        margin_rows(
            &renamed,
            requirements,
            &format!("{who}, {}", text(&m["condition"])),
            &mut rows,
        );
    }
    let peak = num(&c["peak_mrad"]);
    rows.push(Row {
        requirement: "pointing".into(),
        condition: who.into(),
        measured: peak,
        limit: target.map(|t| ("<=".to_string(), t)),
        margin: peak.zip(target).map(|(p, t)| t - p),
        unit: "mrad".into(),
        passes: c["passes"].as_bool(),
        note: "peak error".into(),
    });
    rows
}

/// The requirements a tune judged against: those of the tuned scenario it wrote (the
/// tune changes gains only), `Null` when nothing was picked.
fn tuned_requirements(dir: &Path) -> Value {
    std::fs::read_to_string(dir.join("tuned.toml"))
        .ok()
        .and_then(|t| toml::from_str::<toml::Value>(&t).ok())
        .and_then(|t| serde_json::to_value(t).ok())
        .map_or(Value::Null, |v| v["closed_loop"]["requirements"].clone())
}

fn describe_tune(dir: &Path, record: &Value, page: &mut Page) {
    let t = &record["tune"];
    let req = &tuned_requirements(dir);
    let target = num(&t["target_mrad"]);
    page.title = format!("Tuned PID: {}", text(&t["scenario"]));
    page.subtitle.clear();
    page.subtitle.push(format!(
        "{} mode at {} Hz, load feedforward {}",
        text(&t["mode"]),
        fmt_opt(num(&t["rate_hz"])),
        text(&t["feedforward"])
    ));
    let pick = &record["pick"];
    let gains = |c: &Value| {
        format!(
            "kp {}, ki {}, kd {}",
            fmt_opt(num(&c["gains"]["kp"])),
            fmt_opt(num(&c["gains"]["ki"])),
            fmt_opt(num(&c["gains"]["kd"]))
        )
    };
    if pick.is_object() {
        page.reasons
            .extend(pick["failing"].as_array().into_iter().flatten().map(text));
        page.outcome = if pick["passes"].as_bool() == Some(true) {
            Outcome::Pass(format!("the pick meets every requirement: {}", gains(pick)))
        } else {
            Outcome::NotMet(format!("the pick ({}) misses a requirement", gains(pick)))
        };
        page.tables.push(Table {
            key: "pick".into(),
            heading: format!("The pick: {}", gains(pick)),
            rows: candidate_rows(pick, req, target, "pick"),
        });
    } else {
        page.outcome = Outcome::NotMet("no signable candidate was found".into());
    }
    let own = &t["scenario_design"];
    if own.is_object() {
        page.tables.push(Table {
            key: "scenario_design".into(),
            heading: format!("The scenario's own design: {}", gains(own)),
            rows: candidate_rows(own, req, target, "scenario"),
        });
    }
    let active = text(&t["active_constraint"]);
    if !active.is_empty() {
        page.reasons.push(format!("active constraint: {active}"));
    }
}

fn describe_least_rate(r: &Value, page: &mut Page) {
    page.title = format!(
        "Least control rate: {}",
        [&r["scenario"], &r["scenario_name"]]
            .into_iter()
            .map(text)
            .find(|s| !s.is_empty())
            .unwrap_or_default()
    );
    let mut rows = Vec::new();
    scalar_rows(r, "", &mut rows);
    page.outcome = match num(&r["passing_hz"]) {
        Some(hz) => Outcome::Pass(format!(
            "a tuned, signable PID meets the target at {} Hz",
            fmt(hz)
        )),
        None => Outcome::NotMet("no rate in the searched range meets the target".into()),
    };
    page.tables.push(Table {
        key: "least_rate".into(),
        heading: "Search".into(),
        rows,
    });
}

/// One figure ready to inline.
struct Figure {
    /// Path relative to the results directory, `/`-separated.
    name: String,
    svg: String,
    /// The figure's own title, when it has one (see [`figure_title`]).
    title: Option<String>,
}

/// Every `*.svg` under `dir` (sorted, the top directory first), prepared to inline.
fn collect_figures(dir: &Path, warnings: &mut Vec<String>) -> Vec<Figure> {
    let mut paths = Vec::new();
    svg_paths(dir, 0, &mut paths);
    paths.sort_by_key(|p| {
        let rel = p.strip_prefix(dir).unwrap_or(p).to_path_buf();
        (rel.components().count(), rel)
    });
    if paths.len() > MAX_FIGURES {
        warnings.push(format!(
            "{} figures are in the directory; the first {MAX_FIGURES} are shown here",
            paths.len()
        ));
        paths.truncate(MAX_FIGURES);
    }
    use rayon::prelude::*;
    // Figures are read and prepared side by side (the largest are megabytes), then taken
    // in their order.
    let prepared: Vec<Result<Figure, String>> = paths
        .par_iter()
        .enumerate()
        .map(|(i, path)| {
            let name = path
                .strip_prefix(dir)
                .unwrap_or(path)
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect::<Vec<_>>()
                .join("/");
            match std::fs::read_to_string(path) {
                Ok(raw) => match inline_svg(&raw, &format!("fig{i}-")) {
                    Some(svg) => Ok(Figure {
                        name,
                        title: figure_title(&svg),
                        svg,
                    }),
                    None => Err(format!(
                        "figure {name} is left out of this page: it is not a plain SVG drawing (no <svg> element, or it refers to something outside itself)"
                    )),
                },
                Err(e) => Err(format!("figure {name} could not be read: {e}")),
            }
        })
        .collect();
    let mut figures = Vec::new();
    for figure in prepared {
        match figure {
            Ok(f) => figures.push(f),
            Err(w) => warnings.push(w),
        }
    }
    figures
}

fn svg_paths(dir: &Path, depth: usize, out: &mut Vec<PathBuf>) {
    // Results directories are shallow (cases/NNNN/, designs/NAME/); the bound keeps a
    // symlink loop from running away.
    if depth > 4 {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let path = e.path();
        let hidden = e.file_name().to_string_lossy().starts_with('.');
        match e.file_type() {
            Ok(t) if t.is_dir() && !hidden => svg_paths(&path, depth + 1, out),
            Ok(t) if t.is_file() && !hidden && path.extension().is_some_and(|x| x == "svg") => {
                out.push(path)
            }
            _ => {}
        }
    }
}

/// An SVG document as an element to inline: prolog, doctype and comments before the root
/// dropped, every id prefixed with `prefix` (with its references), fixed width and height
/// replaced by a view box so the figure scales with the page. `None` when the text has no
/// `<svg` root or refers to anything outside itself (an external image, script or link).
fn inline_svg(raw: &str, prefix: &str) -> Option<String> {
    let start = raw.find("<svg")?;
    let body = &raw[start..];
    let lower = body.to_ascii_lowercase();
    if lower.contains("<script")
        || lower.contains("<foreignobject")
        || lower.contains("href=\"http")
        || lower.contains("href='http")
        || lower.contains("href=\"//")
        || lower.contains("url(http")
        || lower.contains("url(//")
        || lower.contains("@import")
    {
        return None;
    }
    let end = body.find('>')?;
    let (root, rest) = body.split_at(end);
    let attr = |name: &str| -> Option<String> {
        let key = format!(" {name}=\"");
        let i = root.find(&key)? + key.len();
        let j = root[i..].find('"')?;
        Some(root[i..i + j].to_string())
    };
    let mut new_root = String::from("<svg");
    let width = attr("width");
    let height = attr("height");
    let has_view_box = attr("viewBox").is_some();
    // Keep every root attribute except the fixed size.
    let mut rest_of_root = &root[4..];
    while let Some(eq) = rest_of_root.find("=\"") {
        let name = rest_of_root[..eq].trim();
        let after = &rest_of_root[eq + 2..];
        let close = after.find('"')?;
        let value = &after[..close];
        if name != "width" && name != "height" && name != "style" {
            let _ = write!(new_root, " {name}=\"{value}\"");
        }
        rest_of_root = &after[close + 1..];
    }
    if !has_view_box {
        let w: f64 = width.as_deref()?.trim_end_matches("px").parse().ok()?;
        let h: f64 = height.as_deref()?.trim_end_matches("px").parse().ok()?;
        let _ = write!(new_root, " viewBox=\"0 0 {w} {h}\"");
    }
    new_root.push_str(" preserveAspectRatio=\"xMidYMid meet\" role=\"img\"");
    let mut svg = new_root + rest;
    // Ids are file-local in a document but page-global once inlined.
    let mut ids = Vec::new();
    let mut from = 0;
    while let Some(i) = svg[from..].find(" id=\"") {
        let s = from + i + 5;
        let Some(len) = svg[s..].find('"') else { break };
        ids.push(svg[s..s + len].to_string());
        from = s + len;
    }
    for id in ids {
        for (old, new) in [
            (format!(" id=\"{id}\""), format!(" id=\"{prefix}{id}\"")),
            (format!("url(#{id})"), format!("url(#{prefix}{id})")),
            (format!("href=\"#{id}\""), format!("href=\"#{prefix}{id}\"")),
        ] {
            svg = svg.replace(&old, &new);
        }
    }
    Some(svg.trim_end().to_string())
}

/// HTML-escape text for element content and attribute values.
fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// A figure's caption: its own title, else words from its file name
/// (`designs/a/pointing_error.svg` to `Pointing error (designs/a)`); the folder of a
/// figure below the results directory is named after it.
fn caption(name: &str, title: Option<&str>) -> String {
    let (folder, file) = name.rsplit_once('/').unwrap_or(("", name));
    let stem = match title {
        Some(t) => words_of_title(t),
        None => words(file.trim_end_matches(".svg")),
    };
    if folder.is_empty() {
        stem
    } else {
        format!("{stem} ({folder})")
    }
}

/// A title as a caption: a plain first word gets its capital; a name (`eots_tracking:`,
/// `L`) is left as written.
fn words_of_title(t: &str) -> String {
    let first = t.split_whitespace().next().unwrap_or("");
    if first.chars().all(|c| c.is_ascii_lowercase() || c == '-') {
        capitalised(t)
    } else {
        t.to_string()
    }
}

/// The title a figure of this tool carries: the text of its first bold `<text>` element
/// (the chart's caption; above panels, the figure's own title), unescaped. File names
/// read as captions say less ("P95 mrad vs brake nm" where the figure says "95th
/// percentile pointing error against brake"). `None` for an SVG without one, which keeps
/// the file name's words.
fn figure_title(svg: &str) -> Option<String> {
    let mut rest = svg;
    while let Some(start) = rest.find("<text") {
        let after = &rest[start..];
        let open_end = after.find('>')?;
        let attributes = &after[..open_end];
        let body = &after[open_end + 1..];
        let close = body.find("</text>")?;
        if attributes.contains("font-weight=\"bold\"") {
            let text = body[..close]
                .trim()
                .replace("&lt;", "<")
                .replace("&gt;", ">")
                .replace("&quot;", "\"")
                .replace("&#39;", "'")
                .replace("&apos;", "'")
                .replace("&amp;", "&");
            let text = text.split_whitespace().collect::<Vec<_>>().join(" ");
            return (!text.is_empty()).then_some(text);
        }
        rest = &body[close..];
    }
    None
}

const STYLE: &str = "
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,'Helvetica Neue',Arial,sans-serif;color:#1a1a1a;max-width:1100px;margin:0 auto;padding:1.5rem;line-height:1.4}
h1{font-size:1.6rem;margin:0 0 .3rem}h2{font-size:1.2rem;margin:2rem 0 .6rem;border-bottom:1px solid #ccc;padding-bottom:.2rem}
h3{font-size:1rem;margin:1.2rem 0 .4rem}
.sub{color:#555;margin:.1rem 0}
.verdict{border-radius:6px;padding:.8rem 1rem;margin:1rem 0;border:2px solid}
.verdict .word{font-size:1.4rem;font-weight:700}
.pass{background:#e9f7ec;border-color:#2e7d32}.pass .word{color:#1b5e20}
.fail{background:#fdecea;border-color:#c62828}.fail .word{color:#b71c1c}
.stop{background:#fff4e5;border-color:#e65100}.stop .word{color:#bf360c}
.none{background:#f3f3f3;border-color:#888}
.incomplete{background:#e65100;color:#fff;font-weight:700;font-size:1.2rem;padding:.6rem 1rem;border-radius:6px;margin:1rem 0;letter-spacing:.03em}
ul.reasons{margin:.4rem 0 0 1.2rem;padding:0}
table{border-collapse:collapse;width:100%;font-size:.9rem;margin:.3rem 0 1rem}
th,td{border-bottom:1px solid #ddd;padding:.3rem .5rem;text-align:left;vertical-align:top}
th{background:#f5f5f5}
td.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
td.ok{color:#1b5e20;font-weight:600}td.bad{color:#b71c1c;font-weight:700}
figure{margin:1rem 0 2rem;page-break-inside:avoid;break-inside:avoid}
figure svg{width:100%;height:auto;display:block;border:1px solid #eee}
figcaption{color:#444;font-size:.9rem;margin-top:.3rem}
pre{background:#f7f7f7;padding:.6rem;overflow-x:auto;font-size:.8rem;white-space:pre-wrap}
details summary{cursor:pointer;color:#333}
dl{display:grid;grid-template-columns:max-content 1fr;gap:.2rem 1rem}dt{font-weight:600}dd{margin:0}
@media print{body{max-width:none;padding:0}details{display:block}h2{page-break-after:avoid}}
";

fn render(page: &Page, record: &Value, record_name: &str, figures: &[Figure]) -> String {
    let mut h = String::with_capacity(figures.iter().map(|f| f.svg.len()).sum::<usize>() + 20_000);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<header>\n<h1>{}</h1>\n",
        esc(&page.title),
        esc(&page.title)
    );
    for s in &page.subtitle {
        let _ = writeln!(h, "<p class=\"sub\">{}</p>", esc(s));
    }
    h.push_str("</header>\n");
    if page.incomplete {
        h.push_str("<div class=\"incomplete\" id=\"incomplete\">INCOMPLETE: these results stopped before the end of the run</div>\n");
    }
    let (class, word, detail) = match &page.outcome {
        Outcome::Pass(d) => ("pass", "PASS", d.clone()),
        Outcome::NotMet(d) => ("fail", "REQUIREMENT NOT MET", d.clone()),
        Outcome::Stopped(d) => ("stop", "STOPPED", d.clone()),
        Outcome::NotJudged => (
            "none",
            "NOT JUDGED",
            "this command declares no requirement to judge".to_string(),
        ),
    };
    let _ = write!(
        h,
        "<section class=\"verdict {class}\" id=\"verdict\" data-verdict=\"{class}\">\n<span class=\"word\">{word}</span> <span class=\"detail\">{}</span>\n",
        esc(&detail)
    );
    if !page.reasons.is_empty() {
        h.push_str("<ul class=\"reasons\">\n");
        for r in &page.reasons {
            let _ = writeln!(h, "<li>{}</li>", esc(r));
        }
        h.push_str("</ul>\n");
    }
    h.push_str("</section>\n");
    for t in &page.tables {
        render_table(&mut h, t);
    }
    for (heading, body) in &page.texts {
        let _ = writeln!(h, "<h2>{}</h2>", esc(heading));
        render_text(&mut h, body);
    }
    if !figures.is_empty() {
        h.push_str("<h2>Figures</h2>\n");
    }
    for (i, f) in figures.iter().enumerate() {
        let _ = write!(
            h,
            "<figure id=\"figure-{}\" data-file=\"{}\">\n{}\n<figcaption>Figure {}: {} <code>{}</code></figcaption>\n</figure>\n",
            i + 1,
            esc(&f.name),
            f.svg,
            i + 1,
            esc(&caption(&f.name, f.title.as_deref())),
            esc(&f.name)
        );
    }
    h.push_str("<h2>Warnings</h2>\n");
    if page.warnings.is_empty() {
        h.push_str("<p>None.</p>\n");
    } else {
        h.push_str("<ul id=\"warnings\">\n");
        for w in &page.warnings {
            let _ = writeln!(h, "<li>{}</li>", esc(w));
        }
        h.push_str("</ul>\n");
    }
    render_provenance(&mut h, page, record, record_name);
    h.push_str("</body>\n</html>\n");
    h
}

/// A plain-text record as the console prints it: the Markdown tables in it (a header
/// row, a `|---|` row, then rows, each line starting with `|`) become HTML tables whose
/// number cells align right; everything else stays preformatted, line for line.
fn render_text(h: &mut String, body: &str) {
    let lines: Vec<&str> = body.lines().collect();
    let mut plain: Vec<&str> = Vec::new();
    let flush = |h: &mut String, plain: &mut Vec<&str>| {
        while plain.last().is_some_and(|l| l.trim().is_empty()) {
            plain.pop();
        }
        let start = plain.iter().take_while(|l| l.trim().is_empty()).count();
        if start < plain.len() {
            let _ = writeln!(h, "<pre>{}</pre>", esc(&plain[start..].join("\n")));
        }
        plain.clear();
    };
    let mut i = 0;
    while i < lines.len() {
        let rows = lines[i..]
            .iter()
            .take_while(|l| l.trim_start().starts_with('|'))
            .count();
        let is_table = rows >= 2 && separator_row(lines[i + 1]);
        if !is_table {
            plain.push(lines[i]);
            i += 1;
            continue;
        }
        flush(h, &mut plain);
        h.push_str("<table class=\"text-table\">\n<thead><tr>");
        for c in markdown_cells(lines[i]) {
            let _ = write!(h, "<th>{}</th>", esc(c));
        }
        h.push_str("</tr></thead>\n<tbody>\n");
        for line in &lines[i + 2..i + rows] {
            h.push_str("<tr>");
            for c in markdown_cells(line) {
                let class = if c.parse::<f64>().is_ok() {
                    " class=\"num\""
                } else {
                    ""
                };
                let _ = write!(h, "<td{class}>{}</td>", esc(c));
            }
            h.push_str("</tr>\n");
        }
        h.push_str("</tbody>\n</table>\n");
        i += rows;
    }
    flush(h, &mut plain);
}

/// The cells of a Markdown table row `| a | b |`, trimmed.
fn markdown_cells(line: &str) -> Vec<&str> {
    let inner = line.trim().trim_start_matches('|');
    let inner = inner.strip_suffix('|').unwrap_or(inner);
    inner.split('|').map(str::trim).collect()
}

/// Whether a line is a Markdown table's header separator, `|---|:--:|`.
fn separator_row(line: &str) -> bool {
    let cells = markdown_cells(line);
    !cells.is_empty()
        && cells
            .iter()
            .all(|c| !c.is_empty() && c.chars().all(|ch| ch == '-' || ch == ':'))
}

fn render_table(h: &mut String, t: &Table) {
    let _ = writeln!(h, "<h2>{}</h2>", esc(&t.heading));
    if t.rows.is_empty() {
        h.push_str("<p>No rows recorded.</p>\n");
        return;
    }
    let judged = t.rows.iter().any(|r| r.limit.is_some());
    let _ = write!(
        h,
        "<table class=\"requirements\" data-key=\"{}\">\n<thead><tr><th>{}</th><th>condition</th><th>{}</th>",
        esc(&t.key),
        if judged { "requirement" } else { "figure" },
        if judged { "measured" } else { "value" }
    );
    if judged {
        h.push_str("<th>limit</th><th>margin</th><th>unit</th><th></th>");
    }
    h.push_str("<th>where / why</th></tr></thead>\n<tbody>\n");
    for r in &t.rows {
        let _ = write!(
            h,
            "<tr data-requirement=\"{}\" data-condition=\"{}\"><td>{}</td><td>{}</td>",
            esc(&r.requirement),
            esc(&r.condition),
            esc(&r.requirement.replace('_', " ")),
            esc(&r.condition),
        );
        // A recorded word (a regime, a cause) is the value itself where nothing is judged.
        let word = !judged && r.measured.is_none() && !r.note.is_empty();
        if word {
            let _ = write!(h, "<td class=\"word\">{}</td>", esc(&r.note));
        } else {
            let _ = write!(
                h,
                "<td class=\"num measured\">{}</td>",
                esc(&fmt_opt(r.measured))
            );
        }
        if judged {
            let (rel, limit) = r
                .limit
                .as_ref()
                .map_or(("", None), |(rel, l)| (rel.as_str(), Some(*l)));
            let (class, mark) = match r.passes {
                Some(true) => ("ok", "ok"),
                Some(false) => ("bad", "FAIL"),
                None => ("", ""),
            };
            let _ = write!(
                h,
                "<td class=\"num limit\">{} {}</td><td class=\"num margin\">{}</td><td>{}</td><td class=\"{class}\">{mark}</td>",
                esc(rel),
                esc(&limit.map_or_else(String::new, fmt)),
                esc(&fmt_opt(r.margin)),
                esc(&r.unit)
            );
        }
        let note = if word { "" } else { r.note.as_str() };
        let _ = writeln!(h, "<td>{}</td></tr>", esc(note));
    }
    h.push_str("</tbody>\n</table>\n");
}

fn render_provenance(h: &mut String, page: &Page, record: &Value, record_name: &str) {
    h.push_str("<h2>Provenance</h2>\n<dl>\n");
    let mut item = |k: &str, v: String| {
        if !v.is_empty() {
            let _ = writeln!(h, "<dt>{}</dt><dd>{}</dd>", esc(k), esc(&v));
        }
    };
    let scenario = &record["scenario"];
    let name = [
        &record["scenario_name"],
        &scenario["name"],
        &record["tune"]["scenario"],
    ]
    .into_iter()
    .map(text)
    .find(|s| !s.is_empty())
    .unwrap_or_default();
    item("scenario", name);
    item(
        "study",
        [&record["study"], &scenario["study"]]
            .into_iter()
            .map(text)
            .find(|s| !s.is_empty())
            .unwrap_or_default(),
    );
    item(
        "program",
        format!(
            "cable-servo {}",
            [
                &record["program_version"],
                &record["least_rate"]["program_version"]
            ]
            .into_iter()
            .map(text)
            .find(|s| !s.is_empty())
            .unwrap_or_else(|| env!("CARGO_PKG_VERSION").to_string())
        ),
    );
    item(
        "completeness",
        if page.incomplete {
            "INCOMPLETE".to_string()
        } else {
            "complete".to_string()
        },
    );
    item("record", record_name.to_string());
    h.push_str("</dl>\n");
    let resolved: Vec<(String, &Value)> = if scenario.is_object() {
        vec![(String::new(), scenario)]
    } else if let Some(designs) = record["designs"].as_array() {
        designs
            .iter()
            .map(|d| (format!(" of design {}", text(&d["name"])), &d["scenario"]))
            .collect()
    } else {
        Vec::new()
    };
    for (whose, s) in resolved {
        let body = toml::to_string(s)
            .unwrap_or_else(|_| serde_json::to_string_pretty(s).unwrap_or_default());
        let _ = write!(
            h,
            "<details>\n<summary>The resolved scenario{} (as run)</summary>\n<pre>{}</pre>\n</details>\n",
            esc(&whose),
            esc(&body)
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markdown_tables_in_a_text_become_html_tables_and_the_rest_stays_text() {
        let body = "Heading line\n\n| log | rms (mrad) |\n|---|---:|\n| a<b.csv | 1.25 |\n| c.csv | n/a |\n\nAfter the table.\n| a lone bar line\n";
        let mut h = String::new();
        render_text(&mut h, body);
        assert_eq!(h.matches("<table").count(), 1, "{h}");
        assert!(h.contains("<th>log</th><th>rms (mrad)</th>"), "{h}");
        assert!(
            h.contains("<tr><td>a&lt;b.csv</td><td class=\"num\">1.25</td></tr>"),
            "{h}"
        );
        assert!(h.contains("<tr><td>c.csv</td><td>n/a</td></tr>"), "{h}");
        assert!(h.starts_with("<pre>Heading line</pre>\n<table"), "{h}");
        assert!(
            h.ends_with("</table>\n<pre>After the table.\n| a lone bar line</pre>\n"),
            "{h}"
        );
        let mut plain = String::new();
        render_text(&mut plain, "no table\n| x |\nmore");
        assert_eq!(plain, "<pre>no table\n| x |\nmore</pre>\n");
    }

    #[test]
    fn svg_is_inlined_scalable_with_unique_ids() {
        let raw = "<?xml version=\"1.0\"?>\n<!-- c -->\n<svg width=\"100\" height=\"50\" xmlns=\"http://www.w3.org/2000/svg\"><defs><clipPath id=\"c\"><rect/></clipPath></defs><g clip-path=\"url(#c)\"/><use href=\"#c\"/></svg>\n";
        let svg = inline_svg(raw, "f1-").unwrap();
        assert!(svg.starts_with("<svg xmlns="), "{svg}");
        assert!(svg.contains("viewBox=\"0 0 100 50\""), "{svg}");
        assert!(!svg.contains("width=\"100\""), "{svg}");
        assert!(
            svg.contains("id=\"f1-c\"") && svg.contains("url(#f1-c)"),
            "{svg}"
        );
        assert!(svg.contains("href=\"#f1-c\""), "{svg}");
        assert!(inline_svg("<svg><image href=\"http://x/y.png\"/></svg>", "a").is_none());
        assert!(inline_svg("no drawing", "a").is_none());
    }

    #[test]
    fn a_figure_is_captioned_by_its_own_title() {
        let svg = "<svg><rect/><text x=\"1\" font-size=\"12\">0.1</text><text x=\"600\" font-weight=\"bold\">\npeak pointing error against preload &amp; load (1000 finished cases)\n</text><text font-weight=\"bold\">upper span</text></svg>";
        let title = figure_title(svg);
        assert_eq!(
            title.as_deref(),
            Some("peak pointing error against preload & load (1000 finished cases)")
        );
        assert_eq!(
            caption("peak_mrad_vs_preload_n.svg", title.as_deref()),
            "Peak pointing error against preload & load (1000 finished cases)"
        );
        assert_eq!(
            caption("designs/a/pointing_error.svg", Some("pointing error")),
            "Pointing error (designs/a)"
        );
        assert_eq!(
            caption("psd.svg", Some("line-of-sight error_psd")),
            "Line-of-sight error_psd"
        );
        // A name keeps its spelling.
        assert_eq!(
            caption("bode.svg", Some("eots_tracking: loop gain L")),
            "eots_tracking: loop gain L"
        );
        // Without a bold title the file name speaks.
        assert_eq!(figure_title("<svg><text>axis</text></svg>"), None);
        assert_eq!(
            figure_title("<svg><text font-weight=\"bold\"> </text></svg>"),
            None
        );
        assert_eq!(figure_title("<svg><text font-weight=\"bold\">cut"), None);
        assert_eq!(
            caption("designs/a/pointing_error.svg", None),
            "Pointing error (designs/a)"
        );
    }

    #[test]
    fn text_is_escaped() {
        assert_eq!(
            esc("<a href=\"x\">&'"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&#39;"
        );
    }

    #[test]
    fn a_directory_without_record_still_gets_a_page() {
        let tmp = tempfile::tempdir().unwrap();
        let path = write_report(tmp.path()).unwrap();
        let html = std::fs::read_to_string(path).unwrap();
        assert!(
            html.contains("NOT JUDGED") && html.contains("no record"),
            "{html}"
        );
    }
}
