//! The shipped da Vinci logs (`../shared/real-data/davinci`, beside the repository) against
//! the figures `docs/diagnose.md` reports for them: the leave-one-log-out table over the
//! eleven logs is recomputed and every number of that table is checked, so the guide
//! cannot drift from the code.

use std::path::{Path, PathBuf};

use cable_servo::identify::loo::leave_one_out;
use cable_servo::identify::startup::StartMode;
use cable_servo::scenario::Scenario;

#[path = "support/davinci.rs"]
mod davinci;
use davinci::{eleven_logs, EXTENSION};

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn data_dir() -> PathBuf {
    let dir = repo().join("../shared/real-data/davinci");
    assert!(
        dir.join("tool4_00.csv").exists(),
        "the shipped da Vinci logs are not at {} (the repository expects `shared/` beside it)",
        dir.display()
    );
    dir
}

/// One row of the guide's eleven-log table (`docs/diagnose.md`): log, base, extended, play operator, pull (%).
#[derive(Debug)]
struct GuideRow {
    log: String,
    base: f64,
    extended: f64,
    play: f64,
    floor: f64,
    pull: f64,
    /// What the extended residual still follows: the signal and its binned RMS, mrad.
    follows: (String, f64),
}

fn number(cell: &str) -> f64 {
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
fn guide_rows() -> Vec<GuideRow> {
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
        });
    }
    rows
}

#[test]
fn leave_one_out_on_the_shipped_logs_gives_the_table_of_the_guide() {
    let dir = data_dir();
    let scenario = Scenario::load(
        repo()
            .join("scenarios/davinci_tool4.toml")
            .to_str()
            .unwrap_or(""),
        &[],
    )
    .expect("scenario");
    let ident = scenario.identify.clone().unwrap_or_default();
    let logs = eleven_logs(&dir);
    let t = leave_one_out(
        &scenario.drive,
        &ident,
        &logs,
        &EXTENSION,
        StartMode::Detect,
    )
    .expect("leave-one-out");
    let readme = guide_rows();
    assert_eq!(readme.len(), 11, "docs/diagnose.md table rows: {readme:?}");
    assert_eq!(t.rows.len(), 11, "leave-one-out rows");
    // The guide prints two decimals (one for the pull): a figure that moves by more than
    // its last printed digit must be re-measured there.
    for (row, want) in t.rows.iter().zip(&readme) {
        assert!(
            row.log.contains(&want.log),
            "row order: {} against docs/diagnose.md {}",
            row.log,
            want.log
        );
        let play = row.play_mrad.unwrap_or(f64::INFINITY);
        for (what, got, readme, tol) in [
            ("base", row.base_mrad, want.base, 0.006),
            ("extended", row.extended_mrad, want.extended, 0.006),
            ("play operator", play, want.play, 0.006),
            ("noise floor", row.floor_mrad, want.floor, 0.006),
            ("pull", row.pull_percent, want.pull, 0.06),
        ] {
            assert!(
                (got - readme).abs() <= tol,
                "{}: {what} {got:.4} against docs/diagnose.md's {readme}",
                want.log
            );
        }
        // The code says "unexplained: follows the input velocity (7.93 mrad RMS of binned
        // means)"; the guide prints the signal and one decimal.
        let (signal, size) = &want.follows;
        let said = row
            .residual
            .split_once(signal.as_str())
            .map(|(_, rest)| number(rest.split_whitespace().next().unwrap_or("")));
        assert!(
            said.is_some_and(|v| (v - size).abs() <= 0.051),
            "{}: the residual follows `{}`, docs/diagnose.md says {signal} ({size})",
            want.log,
            row.residual
        );
    }
    // The guide's claims in words: 11/11 over the base model and over the play operator,
    // and no log named as disagreeing with the others.
    assert_eq!(t.wins_over_base, 11);
    assert_eq!(t.wins_over_play, 11);
    assert!(t.disagreeing.is_empty(), "{:?}", t.disagreeing);
}
