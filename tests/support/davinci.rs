//! The eleven shipped da Vinci logs, the extension the leave-one-out table of
//! `docs/diagnose.md` uses, the shipped scenario and that table as the guide prints it,
//! shared by `tests/real_data.rs`, `tests/calibrated_baseline.rs` and
//! `benches/leave_one_out.rs`.
#![allow(dead_code)]

use std::path::Path;

use cable_servo::identify::{BenchLog, EffectName};
use cable_servo::io::benchlog::read_bench_log;
use cable_servo::scenario::Scenario;

/// Log names `tool4_NN.csv`: 0.1 Hz at seven jaw loads, then 60 % at four more rates.
pub const LOGS: [&str; 11] = [
    "00", "02", "04", "05", "06", "08", "09", "15", "25", "35", "45",
];

/// The multi-wrap extension of the leave-one-out table.
pub const EXTENSION: [EffectName; 3] = [
    EffectName::AngleDependentRatio,
    EffectName::LoadCompliance,
    EffectName::DistributedFrictionMemory,
];

/// The eleven logs from `dir`, in table order.
pub fn eleven_logs(dir: &Path) -> Vec<BenchLog> {
    LOGS.iter()
        .map(|k| {
            let p = dir.join(format!("tool4_{k}.csv"));
            read_bench_log(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
        })
        .collect()
}

/// The repository's root.
pub fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `scenarios/davinci_tool4.toml`, the joint calibration on the eleven logs.
pub fn shipped_scenario() -> Scenario {
    let path = repo().join("scenarios/davinci_tool4.toml");
    Scenario::load(path.to_str().unwrap_or(""), &[]).expect("scenario")
}

/// `scenarios/davinci_tool4_uncalibrated.toml`: the instrument before calibration, where
/// the guide's leave-one-log-out starts every fold.
pub fn uncalibrated_scenario() -> Scenario {
    let path = repo().join("scenarios/davinci_tool4_uncalibrated.toml");
    Scenario::load(path.to_str().unwrap_or(""), &[]).expect("scenario")
}

/// One row of the guide's eleven-log table (`docs/diagnose.md`): log, base, extended, play operator, pull (%).
#[derive(Debug)]
pub struct GuideRow {
    /// Log name, `tool4_NN`.
    pub log: String,
    /// Base capstan model, held out, mrad.
    pub base: f64,
    /// Extended model, held out, mrad.
    pub extended: f64,
    /// Play operator fitted to the log, held out, mrad.
    pub play: f64,
    /// Noise floor, mrad.
    pub floor: f64,
    /// Pull on the other logs, %.
    pub pull: f64,
    /// What the extended residual still follows: the signal and its binned RMS, mrad.
    pub follows: (String, f64),
    /// The log diagnosed alone against the calibration on the others, held out, mrad.
    pub alone: f64,
}

/// A table cell's number (units and markup dropped).
pub fn number(cell: &str) -> f64 {
    let s: String = cell
        .chars()
        .filter(|c| c.is_ascii_digit() || *c == '.' || *c == '-')
        .collect();
    s.parse()
        .unwrap_or_else(|_| panic!("docs/diagnose.md table cell `{cell}` is not a number"))
}

/// "input velocity (7.9 mrad)" or "input angle (1.1)": the signal and the number.
fn follows(cell: &str) -> (String, f64) {
    let (name, rest) = cell
        .split_once('(')
        .unwrap_or_else(|| panic!("docs/diagnose.md cell `{cell}`: expected `signal (N mrad)`"));
    (name.trim().to_string(), number(rest))
}

/// The rows of the `docs/diagnose.md` table headed "| log left out | base capstan model |".
pub fn guide_rows() -> Vec<GuideRow> {
    let text = std::fs::read_to_string(repo().join("docs/diagnose.md")).expect("docs/diagnose.md");
    let mut lines = text
        .lines()
        .skip_while(|l| !l.starts_with("| log left out | base capstan model |"))
        .skip(2);
    let mut rows = Vec::new();
    for l in lines.by_ref() {
        if !l.starts_with("| tool4_") {
            break;
        }
        let c: Vec<&str> = l.split('|').map(str::trim).collect();
        rows.push(GuideRow {
            log: c[1]
                .split_whitespace()
                .next()
                .unwrap_or_default()
                .to_string(),
            base: number(c[2]),
            extended: number(c[3]),
            play: number(c[4]),
            floor: number(c[5]),
            pull: number(c[6]),
            follows: follows(c[7]),
            alone: number(c[8]),
        });
    }
    rows
}
