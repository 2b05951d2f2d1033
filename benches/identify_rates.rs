//! The identification statistics on the independent truth of `tests/support/truth.rs`:
//! every effect hidden at 50 random sizes and phases (half of them within a factor 2 of the
//! smallest size), clean logs with the library and with every effect searched. Prints the
//! table `docs/diagnose.md` cites; `IDENTIFY_RATE_SEEDS` sets another count, and
//! `IDENTIFY_RATE_EFFECTS` (names separated by commas, `clean` for the clean rows,
//! `faults` for the fault table) runs only those rows.
//!
//! The fault table: each fault of `tests/support/faults.rs` injected mid-log on clean logs
//! and on top of each effect, `IDENTIFY_RATE_FAULT_SEEDS` draws a cell (default 20, about
//! 13 minutes on 2 cores); per cell, the draws whose answer is right (`none` on a clean log,
//! the effect otherwise) and those with a stretch flagged on the fault's channel over (part
//! of) its span; per fault, the draws with a stretch also excluded away from it.

#[path = "../tests/support/mod.rs"]
mod support;

use cable_servo::identify::{diagnose, EffectName};
use rayon::prelude::*;
use support::faults::{faulted_log, Fault, FAULTS};
use support::rates::{
    clean_rate, opts, opts_every, opts_library, run_effect, size_of, size_tolerance,
};

/// A count from the environment variable `name`; `default` when unset or not a number.
fn env_count(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

fn main() {
    let seeds = env_count("IDENTIFY_RATE_SEEDS", 50);
    let only: Option<Vec<String>> = std::env::var("IDENTIFY_RATE_EFFECTS")
        .ok()
        .map(|s| s.split(',').map(|n| n.trim().to_string()).collect());
    let wanted = |name: &str| only.as_ref().is_none_or(|o| o.iter().any(|n| n == name));
    let start = std::time::Instant::now();
    let mut table = Vec::new();
    for e in EffectName::EVERY {
        if !wanted(e.as_str()) {
            continue;
        }
        let r = run_effect(e, seeds);
        table.push(format!(
            "| `{e}` | {}/{seeds} | {}/{seeds} within {:.0} % | {:.1} % | {}/{seeds} |",
            r.named,
            r.sized,
            size_tolerance(e) * 100.0,
            r.worst * 100.0,
            r.tied
        ));
    }
    if !table.is_empty() || wanted("clean") {
        println!("| effect | named | sized | worst size error | not told apart |");
        println!("|---|---|---|---|---|");
    }
    for row in table {
        println!("{row}");
    }
    if wanted("clean") {
        let none = clean_rate(seeds, &opts_library(), "library searched");
        let none_every = clean_rate(seeds, &opts_every(), "every effect searched");
        println!("| clean logs, library searched | `none` {none}/{seeds} | | | |");
        println!("| clean logs, every effect searched | `none` {none_every}/{seeds} | | | |");
    }
    if wanted("clean") || EffectName::EVERY.iter().any(|e| wanted(e.as_str())) {
        println!(
            "{seeds} seeds per row in {:.0} s",
            start.elapsed().as_secs_f64()
        );
    }
    if wanted("faults") {
        let fault_seeds = env_count("IDENTIFY_RATE_FAULT_SEEDS", 20);
        let start = std::time::Instant::now();
        fault_table(fault_seeds);
        println!(
            "{fault_seeds} draws per cell in {:.0} s",
            start.elapsed().as_secs_f64()
        );
    }
}

/// A fault's column heading.
fn heading(f: Fault) -> &'static str {
    match f {
        Fault::Jerk => "input jerk",
        Fault::OutputStuck => "output stuck",
        Fault::InputStuck => "input stuck",
        Fault::Departure => "input departs",
        Fault::OutputJump => "output jump",
        Fault::JumpThatStays => "input jump that stays",
        Fault::OutputSpike => "output spike",
    }
}

/// What the draws of one cell came to.
#[derive(Clone, Copy, Default)]
struct FaultCounts {
    /// Answer right: the hidden effect named, `none` on a clean log.
    right: usize,
    /// A stretch excluded on the fault's channel over (part of) its span.
    flagged: usize,
    /// A stretch excluded more than [`AWAY_S`] from the fault's span.
    elsewhere: usize,
}

impl std::ops::Add for FaultCounts {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self {
            right: self.right + o.right,
            flagged: self.flagged + o.flagged,
            elsewhere: self.elsewhere + o.elsewhere,
        }
    }
}

/// How far from a fault's span an excluded stretch counts as elsewhere, s: beyond the
/// padding and what the fault's own edges leave.
const AWAY_S: f64 = 1.0;

/// One draw of a fault on top of `hidden` (clean when `None`).
fn fault_draw(hidden: Option<EffectName>, fault: Fault, seed: u64, s: u64) -> FaultCounts {
    let effects: Vec<(EffectName, f64)> = hidden.iter().map(|e| (*e, size_of(*e, s))).collect();
    let (sc, log, (channel, a, b)) = faulted_log(&effects, fault, seed);
    let d = match diagnose(&sc, std::slice::from_ref(&log), &opts()) {
        Ok(d) => d,
        Err(err) => {
            eprintln!("{hidden:?} under {fault:?}, seed {seed}: failed: {err}");
            return FaultCounts::default();
        }
    };
    let want = hidden.map_or("none", |e| e.as_str());
    let segs = &d.excluded_segments;
    // A fault that grows from nothing (a departure's bump) is seen a few samples in, so a
    // stretch over part of its span counts.
    let seen = segs
        .iter()
        .any(|g| g.channel == channel && g.start_s <= b && g.end_s >= a);
    let elsewhere = segs
        .iter()
        .any(|g| g.end_s < a - AWAY_S || g.start_s > b + AWAY_S);
    if d.cause != want || !seen || elsewhere {
        eprintln!(
            "{want} under {fault:?} at {a:.2}-{b:.2} s, seed {seed}: cause {}, flagged {:?}",
            d.cause,
            segs.iter()
                .map(|g| format!("{:?} {:.2}-{:.2} s", g.channel, g.start_s, g.end_s))
                .collect::<Vec<_>>()
        );
    }
    FaultCounts {
        right: usize::from(d.cause == want),
        flagged: usize::from(seen),
        elsewhere: usize::from(elsewhere),
    }
}

/// Each fault on clean logs and on top of each effect (the default search, every effect),
/// `seeds` draws a cell: "right / flagged" per cell, and per fault the draws with a
/// stretch excluded away from it.
fn fault_table(seeds: u64) {
    let hidden: Vec<Option<EffectName>> = std::iter::once(None)
        .chain(EffectName::EVERY.map(Some))
        .collect();
    let mut rows = Vec::new();
    let mut per_fault = [FaultCounts::default(); FAULTS.len()];
    let mut drawn = [0usize; FAULTS.len()];
    for (k, e) in hidden.iter().enumerate() {
        let mut cells = Vec::new();
        for (f, fault) in FAULTS.iter().enumerate() {
            if *fault == Fault::JumpThatStays && *e == Some(EffectName::InputPulleyRunout) {
                // The injection shifts the readings, not the drive: the runout the output
                // shows after the shift is still that of the input angle before it, which
                // no drive does.
                cells.push("n/a".to_string());
                continue;
            }
            // The draws in parallel: a diagnosis keeps about one and a quarter cores busy.
            let c = (0..seeds)
                .into_par_iter()
                .map(|s| {
                    let seed = 20_000 + 100_000 * k as u64 + 10_000 * *fault as u64 + s;
                    fault_draw(*e, *fault, seed, s)
                })
                .reduce(FaultCounts::default, |x, y| x + y);
            eprintln!(
                "FAULT {fault:?} on {e:?}: right {}/{seeds}, flagged {}/{seeds}, elsewhere {}/{seeds}",
                c.right, c.flagged, c.elsewhere
            );
            per_fault[f] = per_fault[f] + c;
            drawn[f] += seeds as usize;
            cells.push(format!("{} / {}", c.right, c.flagged));
        }
        let name = e.map_or("clean logs (`none`)".to_string(), |e| format!("`{e}`"));
        rows.push(format!("| {name} | {} |", cells.join(" | ")));
    }
    let heads: Vec<&str> = FAULTS.iter().map(|f| heading(*f)).collect();
    println!(
        "| hidden, then a fault mid-log: right / flagged of {seeds} | {} |",
        heads.join(" | ")
    );
    println!("|---|{}", "---|".repeat(heads.len()));
    for r in rows {
        println!("{r}");
    }
    let column = |pick: fn(&FaultCounts) -> usize| -> String {
        per_fault
            .iter()
            .zip(&drawn)
            .map(|(c, n)| format!("{}/{n}", pick(c)))
            .collect::<Vec<_>>()
            .join(" | ")
    };
    println!("| all rows: right | {} |", column(|c| c.right));
    println!("| all rows: flagged | {} |", column(|c| c.flagged));
    println!(
        "| all rows: a stretch also excluded more than {AWAY_S} s away | {} |",
        column(|c| c.elsewhere)
    );
}
