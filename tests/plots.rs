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
    // Context (samples not judged) is grey, outside every mode's slot.
    charts
        .iter()
        .flat_map(|c| {
            c.series
                .iter()
                .filter(|s| !s.context)
                .map(|s| (s.label.clone(), s.palette_slot))
        })
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

fn chart_of<'a>(figures: &'a [(String, Figure)], stem: &str) -> Vec<&'a cable_servo::plot::Chart> {
    let (_, f) = figures
        .iter()
        .find(|(s, _)| s == stem)
        .unwrap_or_else(|| panic!("no figure {stem}"));
    match f {
        Figure::Chart(c) => vec![c],
        Figure::Panels { charts, .. } => charts.iter().collect(),
    }
}

/// The motor command's axis names the unit the amplifier takes: amperes behind a current
/// amplifier, volts behind a voltage one.
#[test]
fn motor_command_axis_names_the_run_unit() {
    use cable_servo::report::closed_loop::command_unit;
    let sets = |amp: &str| {
        vec![
            "closed_loop.duration_s=2.5".to_string(),
            "closed_loop.modes=[\"memory\"]".to_string(),
            format!("closed_loop.motor.amplifier=\"{amp}\""),
        ]
    };
    for (amp, unit) in [("current", "A"), ("voltage", "V")] {
        let s = Scenario::load("eots_tracking", &sets(amp)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(command_unit(&s), unit);
        let r = run_closed_loop(&s, &RunOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        let figures = closed_loop_charts(&r, 0.1, command_unit(&s));
        let command = chart_of(&figures, "motor_command");
        assert_eq!(command[0].y_label, format!("motor command [{unit}]"));
    }
}

/// Time outside the metrics window is shaded on every time panel, and the error panel
/// that shows every mode takes its scale from the window alone.
#[test]
fn time_outside_the_metrics_window_is_shaded_and_off_the_error_scale() {
    let all = figures("[\"none\", \"memoryless\", \"memory\"]");
    let error = chart_of(&all, "pointing_error");
    let window = error[0].y_fit_x.expect("the window sets the scale");
    assert!(window.0 > 0.0, "{window:?}");
    for stem in ["pointing_error", "tensions", "motor_command"] {
        for c in chart_of(&all, stem) {
            if c.x_range.is_some() {
                continue; // the panel drawn over the window alone
            }
            assert!(
                c.x_shades.iter().any(|s| s.hi == window.0),
                "{stem}: {} not shaded before {}",
                c.title,
                window.0
            );
        }
    }
    // Every error panel carries the target.
    for c in chart_of(&all, "pointing_error") {
        assert!(c.bands.iter().any(|b| b.label.starts_with("target")));
    }
}

/// The error against angle judges what the verdict judges: each mode's curve holds its
/// samples in the metrics window and nothing else; the start-up before it is kept apart,
/// in grey under one legend entry, and leaves the axis to the judged samples.
#[test]
fn error_against_angle_sets_the_start_up_apart() {
    let sets = vec![
        "closed_loop.modes=[\"none\", \"memory\"]".to_string(),
        "closed_loop.duration_s=2.5".to_string(),
    ];
    let s = Scenario::load("eots_tracking", &sets).unwrap_or_else(|e| panic!("{e}"));
    let r = run_closed_loop(&s, &RunOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let figures = closed_loop_charts(&r, 0.1, "A");
    let panels = chart_of(&figures, "error_vs_angle");
    let c = panels[0];
    // The compensated mode on an axis of its own, judged samples only.
    let labels: Vec<&str> = panels[1].series.iter().map(|s| s.label.as_str()).collect();
    assert_eq!(labels, ["memory"]);
    let (from, to) = (
        r.modes[0].metrics.window_s[0],
        r.modes[0].metrics.window_s[1],
    );
    let context: Vec<_> = c.series.iter().filter(|s| s.context).collect();
    let judged: Vec<_> = c.series.iter().filter(|s| !s.context).collect();
    assert_eq!((context.len(), judged.len()), (2, 2));
    let labels: Vec<&str> = context.iter().map(|s| s.label.as_str()).collect();
    assert_eq!(labels[1], "", "one legend entry for the grey");
    assert!(labels[0].starts_with("before metrics start"), "{labels:?}");
    let Some((_, Figure::Panels { title, .. })) =
        figures.iter().find(|(s, _)| s == "error_vs_angle")
    else {
        panic!("error against angle is not a panel figure");
    };
    assert!(title.contains("judged from"), "{title}");
    for (k, m) in r.modes.iter().enumerate() {
        let t = &m.series.as_ref().expect("recorded").t_s;
        for (i, &ti) in t.iter().enumerate() {
            let inside = ti >= from && ti <= to;
            assert_eq!(
                judged[k].y[i].is_finite(),
                inside,
                "{} at {ti} s",
                m.mode.name()
            );
            assert_eq!(
                context[k].y[i].is_finite(),
                !inside,
                "{} at {ti} s",
                m.mode.name()
            );
        }
    }
}
