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
        "run", "sweep", "merge", "design", "diagnose", "synth", "show",
    ] {
        assert!(
            text.contains(&format!("  {cmd} ")),
            "{cmd} missing:\n{text}"
        );
    }
}
