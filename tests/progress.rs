//! Progress of long work: shown on a terminal only, so output piped to a file or read by
//! CI stays free of rewritten progress lines.

use cable_servo::progress::Progress;
use cable_servo::run::progress::Bar;

/// With stderr not a terminal (this test captures it), a run with an error budget prints
/// no progress line, and its results are unchanged.
#[test]
fn no_progress_when_stderr_is_not_a_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_cable-servo"))
        .args([
            "run",
            "gimbal_stabilized",
            "--set",
            "closed_loop.duration_s=1",
            "--set",
            "closed_loop.metrics_start_s=0.5",
            "--set",
            "closed_loop.error_budget=true",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(out.join("error_budget.csv").is_file(), "{stderr}");
    assert!(!stderr.contains("error budget:"), "{stderr}");
    assert!(!stderr.contains('\r'), "{stderr}");
}

/// A bar takes reports from parallel units in any order and never moves back.
#[test]
fn a_bar_takes_reports_out_of_order() {
    let bar = Bar::new("error budget", "runs");
    for (d, t) in [(0, 5), (2, 5), (1, 5), (5, 5)] {
        bar.update(d, t);
    }
    bar.finish();
}
