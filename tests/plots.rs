//! What the closed-loop figures show: one colour per mode whichever modes run, the
//! compensated modes on their own fitted panel.

use cable_servo::closed_loop::{run_closed_loop, RunOptions};
use cable_servo::report::closed_loop::{closed_loop_charts, Figure};
use cable_servo::scenario::Scenario;

fn figures(modes: &str) -> Vec<(String, Figure)> {
    let sets = vec![
        format!("closed_loop.modes={modes}"),
        "closed_loop.duration_s=2.5".to_string(),
    ];
    let s = Scenario::load("eots_tracking", &sets).unwrap_or_else(|e| panic!("{e}"));
    let r = run_closed_loop(&s, &RunOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    closed_loop_charts(&r, 0.1, "A")
}

fn slots(f: &Figure) -> Vec<(String, Option<usize>)> {
    let charts = match f {
        Figure::Chart(c) => vec![c.clone()],
        Figure::Panels { charts, .. } => charts.clone(),
    };
    charts
        .iter()
        .flat_map(|c| c.series.iter().map(|s| (s.label.clone(), s.palette_slot)))
        .collect()
}

#[test]
fn a_mode_keeps_its_colour_in_every_figure() {
    let all = figures("[\"none\", \"memoryless\", \"memory\"]");
    let two = figures("[\"memory\", \"memoryless\"]");
    for (stem, f) in all.iter().chain(&two) {
        for (label, slot) in slots(f) {
            let want = match label.as_str() {
                "none" => 0,
                "memoryless" => 1,
                "memory" => 2,
                // The target drawn as a line on a log axis: grey, outside the modes' slots.
                "target 0.1 mrad" => 7,
                other => panic!("{stem}: unexpected series {other}"),
            };
            assert_eq!(slot, Some(want), "{stem}: {label}");
        }
    }
    // With none present the compensated modes get their own panel, fitted to them.
    let Figure::Panels { charts, .. } = &all[0].1 else {
        panic!("pointing error is not a panel figure");
    };
    assert_eq!(charts[1].series.len(), 2);
    let (lo, hi) = charts[1].y_range.unwrap_or((f64::NAN, f64::NAN));
    assert!(lo < -0.1 && hi > 0.1 && hi < 0.2, "{lo} {hi}");
}
