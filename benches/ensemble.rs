//! The spread of the closed loop's figures under perturbations a change of arithmetic
//! could cause: every shipped closed-loop scenario run with its preload moved by
//! `k * 1e-12` relative (k = -10..10 without 0, 20 members), each mode's RMS, peak and
//! 95th-percentile pointing error. A compensated loop is sensitive to the last digits of
//! its inputs, so a change that moves results (a different but equally exact order of
//! operations, an approximation inside a period) is judged against this spread, not
//! against one run.
//!
//! `cargo bench --bench ensemble` prints the spread. With `ENSEMBLE_SAVE=FILE` it also
//! writes the ensembles as JSON; with `ENSEMBLE_CHECK=FILE` it holds the unperturbed
//! figures of the code at hand against those in FILE (written by the code before the
//! change) and exits 1 when one moved by more than its ensemble's width (max - min). See
//! benches/README.md.

use std::collections::BTreeMap;
use std::process::ExitCode;
use std::time::Instant;

use cable_servo::closed_loop::{run_closed_loop, Completion, RunOptions};
use cable_servo::scenario::Scenario;
use serde_json::{json, Value};

/// The shipped scenarios with a closed loop.
const SCENARIOS: [&str; 7] = [
    "eots_tracking",
    "eots_scan",
    "eots_runout",
    "eots_mismatch",
    "step_stare",
    "gimbal_stabilized",
    "davinci_tool4_loop",
];

/// Relative preload steps of the members.
const STEP: f64 = 1e-12;
const HALF_WIDTH: i32 = 10;

/// `mode -> figure -> value` of one run; a stopped mode gives its stop as `null` figures.
fn figures(s: &Scenario) -> BTreeMap<String, BTreeMap<&'static str, Option<f64>>> {
    let r = run_closed_loop(s, &RunOptions::metrics_only()).expect("shipped scenario runs");
    r.modes
        .iter()
        .map(|m| {
            let done = matches!(m.completion, Completion::Complete);
            let f = |v: f64| done.then_some(v);
            let mut row = BTreeMap::new();
            row.insert("rms_mrad", f(m.metrics.rms_mrad));
            row.insert("peak_mrad", f(m.metrics.peak_mrad));
            row.insert("p95_mrad", f(m.metrics.p95_mrad));
            (m.mode.name().to_string(), row)
        })
        .collect()
}

/// A figure as the table shows it; a stopped mode has none.
fn shown(v: Option<f64>) -> String {
    v.map_or("stopped".to_string(), |v| format!("{v:.6}"))
}

fn with_preload(name: &str, factor: f64) -> Scenario {
    let mut s = Scenario::load(name, &[]).expect("shipped scenario");
    s.drive.preload_n *= factor;
    s
}

fn main() -> ExitCode {
    let check: Option<Value> = std::env::var("ENSEMBLE_CHECK").ok().map(|p| {
        let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{p}: {e}"));
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{p}: {e}"))
    });
    let start = Instant::now();
    let mut saved = serde_json::Map::new();
    let mut outside = Vec::new();
    println!("| scenario | mode | figure | unperturbed | ensemble min | ensemble max | spread (% of mean) |");
    println!("|---|---|---|---|---|---|---|");
    for name in SCENARIOS {
        let base = figures(&with_preload(name, 1.0));
        let members: Vec<_> = (-HALF_WIDTH..=HALF_WIDTH)
            .filter(|k| *k != 0)
            .map(|k| figures(&with_preload(name, 1.0 + f64::from(k) * STEP)))
            .collect();
        let mut per_scenario = serde_json::Map::new();
        for (mode, row) in &base {
            let mut per_mode = serde_json::Map::new();
            for (figure, value) in row {
                let values: Vec<Option<f64>> = members.iter().map(|m| m[mode][figure]).collect();
                let stopped = values.iter().filter(|v| v.is_none()).count();
                let done: Vec<f64> = values.iter().flatten().copied().collect();
                // The members' range, none when every member stopped.
                let range = (!done.is_empty()).then(|| {
                    done.iter()
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                            (a.min(*v), b.max(*v))
                        })
                });
                let (lo, hi) = (range.map(|r| r.0), range.map(|r| r.1));
                let mean = done.iter().sum::<f64>() / done.len().max(1) as f64;
                let spread = match range {
                    Some((l, h)) if mean != 0.0 => format!("{:.3}", (h - l) / mean.abs() * 100.0),
                    _ => "-".to_string(),
                };
                let members_note = if stopped > 0 {
                    format!(" ({stopped} of {} stopped)", values.len())
                } else {
                    String::new()
                };
                println!(
                    "| {name} | {mode} | {figure} | {} | {} | {} | {spread}{members_note} |",
                    shown(*value),
                    shown(lo),
                    shown(hi),
                );
                per_mode.insert(
                    figure.to_string(),
                    json!({"unperturbed": value, "min": lo, "max": hi, "stopped": stopped}),
                );
                if let Some(reference) = &check {
                    let r = &reference[name][mode.as_str()][*figure];
                    // The change may move a figure from the old code's unperturbed value by
                    // at most the ensemble's width: an unperturbed run need not lie inside
                    // its own members' range (eots_tracking's memoryless p95 does not).
                    let old_value = r["unperturbed"].as_f64();
                    let width = r["max"].as_f64().zip(r["min"].as_f64()).map(|(h, l)| h - l);
                    let inside = match (value, old_value, width) {
                        (Some(v), Some(u), Some(w)) => (v - u).abs() <= w,
                        // A stop is inside only where the reference stopped too.
                        (None, None, _) => true,
                        (None, _, _) => r["stopped"].as_u64().unwrap_or(0) > 0,
                        _ => false,
                    };
                    if !inside {
                        outside.push(format!(
                            "{name} {mode} {figure}: {:?} against {:?} before, a move larger than the reference ensemble's width {:?}",
                            value,
                            old_value,
                            width
                        ));
                    }
                }
            }
            per_scenario.insert(mode.clone(), Value::Object(per_mode));
        }
        saved.insert(name.to_string(), Value::Object(per_scenario));
    }
    eprintln!(
        "{} scenarios x {} runs in {:.0} s",
        SCENARIOS.len(),
        2 * HALF_WIDTH + 1,
        start.elapsed().as_secs_f64()
    );
    if let Ok(path) = std::env::var("ENSEMBLE_SAVE") {
        let text = serde_json::to_string_pretty(&Value::Object(saved)).expect("plain JSON");
        std::fs::write(&path, text).unwrap_or_else(|e| panic!("{path}: {e}"));
        eprintln!("ensembles written to {path}");
    }
    if check.is_some() {
        if outside.is_empty() {
            eprintln!("no figure moved by more than its reference ensemble's width");
        } else {
            for o in &outside {
                eprintln!("OUTSIDE: {o}");
            }
            return ExitCode::FAILURE;
        }
    }
    ExitCode::SUCCESS
}
