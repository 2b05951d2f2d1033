//! The calibrated instrument as given, replayed on a log it was not calibrated on, against
//! the leave-one-out of the identification: `scenarios/davinci_tool4.toml` is the joint
//! calibration on the ten logs other than tool4_00, which is exactly the fold that leaves
//! tool4_00 out, so replaying the scenario's drive and `[effects]` through the physics
//! (capstan replay, ratio shape, contact memory, compliance; `identify::baseline`) must
//! reproduce that fold's held-out error, which the identification computes from its own
//! design matrix. Two implementations of one model, checked against each other and against
//! the figure the guide prints.

use std::path::Path;

use cable_servo::identify::{baseline, model, startup};
use cable_servo::io::benchlog::read_bench_log;
use cable_servo::scenario::Scenario;

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The guide's held-out extended error of tool4_00, mrad.
fn guide_tool4_00() -> f64 {
    let text = std::fs::read_to_string(repo().join("docs/diagnose.md")).expect("docs/diagnose.md");
    let row = text
        .lines()
        .skip_while(|l| !l.starts_with("| log left out | base capstan model |"))
        .find(|l| l.starts_with("| tool4_00"))
        .expect("the guide's leave-one-out row of tool4_00");
    let cell = row.split('|').nth(3).expect("extended column");
    let digits: String = cell
        .chars()
        .filter(|c| c.is_ascii_digit() || *c == '.')
        .collect();
    digits.parse().expect("a number")
}

#[test]
fn the_calibrated_scenario_replays_to_the_held_out_error_of_its_fold() {
    let log_path = repo().join("../shared/real-data/davinci/tool4_00.csv");
    if !log_path.exists() {
        eprintln!(
            "skipped: {} is not beside the repository",
            log_path.display()
        );
        return;
    }
    let sc = Scenario::load(
        repo()
            .join("scenarios/davinci_tool4.toml")
            .to_str()
            .unwrap_or(""),
        &[],
    )
    .expect("scenario");
    let ident = sc.identify.clone().unwrap_or_default();
    let fx = sc.effects.clone().expect("calibrated effects");
    let log = read_bench_log(&log_path).expect("log");
    let (cut, _) = startup::cut_start(&log, startup::StartMode::Detect);
    let p = model::prepare(&cut, ident.max_rate_hz).expect("prepared");
    let s = baseline::score(
        &sc.drive,
        &fx,
        std::slice::from_ref(&p),
        &vec![true; p.t.len()],
    )
    .expect("replay");
    let want = guide_tool4_00();
    assert!(
        (s.rmse_mrad - want).abs() <= 0.006,
        "replayed {:.4} mrad, the guide's held-out tool4_00 {want}",
        s.rmse_mrad
    );
    assert_eq!(s.per_log_mrad.len(), 1);
}
