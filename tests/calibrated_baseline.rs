//! The calibrated instrument as given, replayed on the shipped logs through the physics
//! (`identify::baseline`: capstan replay, ratio shape, contact memory with its load law,
//! compliance), against the identification that calibrated it from its own design matrix:
//! `scenarios/davinci_tool4.toml` is the joint calibration on all eleven logs, so on each
//! log its replay is an in-sample fit and may not be worse than the guide's held-out
//! error of the fold that left that log out, nor than the base model or the play
//! operator there. A replay that dropped or mis-signed an effect, or read a key wrong,
//! lands far above those figures.

use cable_servo::identify::{baseline, model, startup};
use cable_servo::io::benchlog::read_bench_log;

#[path = "support/davinci.rs"]
mod davinci;
use davinci::{guide_rows, repo, shipped_scenario};

#[test]
fn the_calibrated_scenario_replays_within_its_held_out_errors() {
    let dir = repo().join("../shared/real-data/davinci");
    if !dir.join("tool4_00.csv").exists() {
        eprintln!("skipped: {} is not beside the repository", dir.display());
        return;
    }
    let sc = shipped_scenario();
    let ident = sc.identify.clone().unwrap_or_default();
    let fx = sc.effects.clone().expect("calibrated effects");
    let rows = guide_rows();
    assert_eq!(rows.len(), 11, "docs/diagnose.md rows: {rows:?}");
    for row in rows {
        let (log, base, held_out, play) = (row.log, row.base, row.extended, row.play);
        let raw = read_bench_log(&dir.join(format!("{log}.csv"))).expect("log");
        let (cut, _) = startup::cut_start(&raw, startup::StartMode::Detect);
        let p = model::prepare(&cut, ident.max_rate_hz).expect("prepared");
        let keep = vec![true; p.t.len()];
        let s =
            baseline::score(&sc.drive, &fx, std::slice::from_ref(&p), &keep, &[]).expect("replay");
        eprintln!("{log}: replay {:.3} mrad, held out {held_out}", s.rmse_mrad);
        assert!(
            s.rmse_mrad <= held_out + 0.006 && s.rmse_mrad < play && s.rmse_mrad < base,
            "{log}: replayed {:.4} mrad; the guide: held out {held_out}, play {play}, base {base}",
            s.rmse_mrad
        );
        // An in-sample fit this far below its held-out figure would mean the replay is
        // not the model that was scored.
        assert!(
            s.rmse_mrad > 0.5 * held_out,
            "{log}: replayed {:.4} mrad against held out {held_out}",
            s.rmse_mrad
        );
    }
}
