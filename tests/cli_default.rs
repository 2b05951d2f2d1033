//! The command a new user types first: `cable-servo` with no arguments.

use std::process::{Command, Output};

fn cable_servo(args: &[&str], cwd: &std::path::Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cable-servo"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("the binary runs")
}

#[test]
fn no_arguments_runs_the_default_study_and_a_second_run_keeps_the_first() {
    let tmp = tempfile::tempdir().unwrap();
    let first = cable_servo(&[], tmp.path());
    let out = String::from_utf8_lossy(&first.stdout);
    assert_eq!(
        first.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    assert!(out.contains("memory"), "{out}");
    assert!(out.contains("results: results/eots_tracking\n"), "{out}");
    let dir = tmp.path().join("results/eots_tracking");
    assert!(dir.join("summary.json").is_file());

    let second = cable_servo(&[], tmp.path());
    let out = String::from_utf8_lossy(&second.stdout);
    assert_eq!(second.status.code(), Some(0), "{out}");
    assert!(out.contains("results: results/eots_tracking-2\n"), "{out}");
    assert!(tmp
        .path()
        .join("results/eots_tracking-2/summary.json")
        .is_file());
    assert!(dir.join("summary.json").is_file());
}

#[test]
fn help_still_lists_the_commands() {
    let tmp = tempfile::tempdir().unwrap();
    let help = cable_servo(&["--help"], tmp.path());
    assert_eq!(help.status.code(), Some(0));
    let text = String::from_utf8_lossy(&help.stdout);
    for cmd in [
        "run", "sweep", "merge", "design", "diagnose", "synth", "show", "freqresp", "margins",
    ] {
        assert!(
            text.contains(&format!("  {cmd} ")),
            "{cmd} missing:\n{text}"
        );
    }
}

/// `run X` then `sweep X` with no `--out`: each has its own default folder, both succeed.
#[test]
fn run_then_sweep_of_one_scenario_do_not_collide() {
    let tmp = tempfile::tempdir().unwrap();
    let run = cable_servo(&["run", "paper_fig11"], tmp.path());
    assert_eq!(
        run.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let sweep = cable_servo(&["sweep", "paper_fig11"], tmp.path());
    let out = String::from_utf8_lossy(&sweep.stdout);
    assert_eq!(
        sweep.status.code(),
        Some(0),
        "{out}{}",
        String::from_utf8_lossy(&sweep.stderr)
    );
    assert!(
        out.contains("results: results/paper_fig11-sweep\n"),
        "{out}"
    );
    assert!(tmp
        .path()
        .join("results/paper_fig11/summary.json")
        .is_file());
    assert!(tmp
        .path()
        .join("results/paper_fig11-sweep/sweep.csv")
        .is_file());
}
