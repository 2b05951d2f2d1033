//! The identification statistics on the independent truth of `tests/support/truth.rs`:
//! every effect hidden at 50 random sizes and phases (half of them within a factor 2 of the
//! smallest size), clean logs with the library and with every effect searched. Prints the
//! table `docs/diagnose.md` cites; `IDENTIFY_RATE_SEEDS` sets another count, and
//! `IDENTIFY_RATE_EFFECTS` (names separated by commas, `clean` for the clean rows) runs
//! only those rows.

#[path = "../tests/support/mod.rs"]
mod support;

use cable_servo::identify::EffectName;
use support::rates::{clean_rate, opts_every, opts_library, run_effect, size_tolerance};

fn main() {
    let seeds: u64 = std::env::var("IDENTIFY_RATE_SEEDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(50);
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
    println!("| effect | named | sized | worst size error | not told apart |");
    println!("|---|---|---|---|---|");
    for row in table {
        println!("{row}");
    }
    if wanted("clean") {
        let none = clean_rate(seeds, &opts_library(), "library searched");
        let none_every = clean_rate(seeds, &opts_every(), "every effect searched");
        println!("| clean logs, library searched | `none` {none}/{seeds} | | | |");
        println!("| clean logs, every effect searched | `none` {none_every}/{seeds} | | | |");
    }
    println!(
        "{seeds} seeds per row in {:.0} s",
        start.elapsed().as_secs_f64()
    );
}
