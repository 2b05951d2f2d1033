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

/// Every report a computation made, in order.
fn recorder() -> std::sync::Mutex<Vec<(usize, usize)>> {
    std::sync::Mutex::new(Vec::new())
}

/// Small logs of one synthetic instrument with hidden `effects`: `n` records of 10 s,
/// seeds 1.. .
fn small_logs(
    sc: &cable_servo::scenario::Scenario,
    effects: &[(cable_servo::identify::EffectName, f64)],
    n: u64,
) -> Vec<cable_servo::identify::BenchLog> {
    (1..=n)
        .map(|seed| {
            let mut l = cable_servo::identify::synthesize(
                sc,
                effects,
                seed,
                &cable_servo::identify::SynthOptions::default(),
            )
            .expect("synthetic log");
            l.source = format!("synthetic-{seed}");
            l
        })
        .collect()
}

/// Leave-one-out reports the size of the work at once, then exactly one tick per log
/// held out (folds run in parallel, so in any order), ending at total/total; the table
/// is the one computed without progress.
#[test]
fn leave_one_out_ticks_once_per_fold() {
    use cable_servo::identify::loo::{leave_one_out, leave_one_out_with_progress};
    use cable_servo::identify::startup::StartMode;
    let sc = cable_servo::scenario::Scenario::load(
        "gimbal_ident",
        &["quasi_static.duration_s=10".to_string()],
    )
    .expect("built-in scenario");
    let ident = sc.identify.clone().unwrap_or_default();
    let logs = small_logs(&sc, &[], 3);
    let seen = recorder();
    let sink = |d: usize, t: usize| seen.lock().expect("recorder").push((d, t));
    let with = leave_one_out_with_progress(&sc.drive, &ident, &logs, &[], StartMode::Detect, &sink)
        .expect("leave-one-out");
    let seen = seen.into_inner().expect("recorder");
    assert_eq!(seen.first(), Some(&(0, 3)), "{seen:?}");
    assert_eq!(
        seen.len(),
        1 + 3,
        "one report up front, one per fold: {seen:?}"
    );
    assert!(seen.iter().all(|(_, t)| *t == 3), "{seen:?}");
    let mut ticks: Vec<usize> = seen[1..].iter().map(|(d, _)| *d).collect();
    ticks.sort_unstable();
    assert_eq!(ticks, vec![1, 2, 3], "{seen:?}");
    let without =
        leave_one_out(&sc.drive, &ident, &logs, &[], StartMode::Detect).expect("leave-one-out");
    assert_eq!(
        serde_json::to_string(&with).expect("json"),
        serde_json::to_string(&without).expect("json"),
        "progress changed the results"
    );
}

/// A diagnosis counts candidate effects judged: it starts at 0 of an upper bound (every
/// round of the search run), never goes past it, and ends with done equal to total, the
/// candidates actually judged; the diagnosis is the one computed without progress.
#[test]
fn diagnosis_counts_candidates_judged() {
    use cable_servo::identify::{diagnose, diagnose_with_progress, DiagnoseOptions};
    let sc = cable_servo::scenario::Scenario::load(
        "gimbal_ident",
        &["quasi_static.duration_s=10".to_string()],
    )
    .expect("built-in scenario");
    // A hidden ratio shape gives the search something to judge.
    let logs = small_logs(
        &sc,
        &[(cable_servo::identify::EffectName::AngleDependentRatio, 2e-4)],
        1,
    );
    let options = DiagnoseOptions::default();
    let seen = recorder();
    let sink = |d: usize, t: usize| seen.lock().expect("recorder").push((d, t));
    let with = diagnose_with_progress(&sc, &logs, &options, &sink).expect("diagnosis");
    let seen = seen.into_inner().expect("recorder");
    let Some(&(_, bound)) = seen.first() else {
        panic!("no progress reported");
    };
    assert_eq!(seen[0], (0, bound), "{seen:?}");
    assert!(seen.iter().all(|(d, t)| d <= t && *t <= bound), "{seen:?}");
    let judged = with.candidates.len();
    assert!(judged > 0, "nothing judged: {seen:?}");
    assert_eq!(seen.last(), Some(&(judged, judged)), "{seen:?}");
    let without = diagnose(&sc, &logs, &options).expect("diagnosis");
    assert_eq!(
        serde_json::to_string(&with).expect("json"),
        serde_json::to_string(&without).expect("json"),
        "progress changed the results"
    );
}
