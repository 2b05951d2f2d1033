//! The `sweep`, `merge` and `design` commands end to end.

use std::path::Path;
use std::process::{Command, Output};

fn cable_servo(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cable-servo"))
        .args(args)
        .output()
        .expect("the binary runs")
}

fn text(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn vary_without_a_sweep_section_with_case_time_series() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("tol");
    let o = cable_servo(&[
        "sweep",
        "paper_bench",
        "--vary",
        "drive.preload_n=normal_rel(0.05)",
        "--vary",
        "load.brake_nm=uniform(0.6,0.8)",
        "--set",
        "quasi_static.duration_s=2",
        "--set",
        "quasi_static.profile_times_s=[1.0]",
        "--samples",
        "4",
        "--seed",
        "9",
        "--case-timeseries",
        "--out",
        path(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let table = text(&out.join("sweep.csv"));
    assert_eq!(table.lines().count(), 5, "{table}");
    assert!(table.starts_with("case,preload_n,brake_nm,peak_error_mrad,"));
    let series = text(&out.join("cases/case-000003/timeseries.csv"));
    assert!(series.starts_with("model,t_s,"), "{series}");
    let summary = text(&out.join("summary.json"));
    assert!(summary.contains("\"mode\": \"random\""), "{summary}");
}

#[test]
fn shards_merge_into_the_single_run_file() {
    let tmp = tempfile::tempdir().unwrap();
    let common = [
        "sweep",
        "paper_fig11",
        "--vary",
        "drive.preload_n=tnormal(40,20,5,150)",
        "--vary",
        "backlash.load_nm=uniform(0.1,2)",
        "--mode",
        "latin_hypercube",
        "--samples",
        "30",
    ];
    let run = |extra: &[&str], dir: &Path| {
        let mut args = common.to_vec();
        args.extend_from_slice(extra);
        args.extend_from_slice(&["--out", path(dir)]);
        let o = cable_servo(&args);
        // Low preloads may go slack: a result, not a failure of the run.
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    let single = tmp.path().join("single");
    run(&["--threads", "2"], &single);
    run(
        &["--threads", "1", "--shard", "1/2"],
        &tmp.path().join("s1"),
    );
    run(
        &["--threads", "2", "--shard", "2/2"],
        &tmp.path().join("s2"),
    );
    let merged = tmp.path().join("merged.csv");
    let o = cable_servo(&[
        "merge",
        "--out",
        path(&merged),
        path(&tmp.path().join("s2")),
        path(&tmp.path().join("s1")),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(text(&merged), text(&single.join("sweep.csv")));
}

#[test]
fn bad_vary_names_the_argument_and_the_forms() {
    let o = cable_servo(&[
        "sweep",
        "paper_fig11",
        "--vary",
        "drive.preload_n=gauss(1,2)",
    ]);
    assert_eq!(o.status.code(), Some(3));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--vary drive.preload_n=gauss(1,2)"), "{err}");
    assert!(err.contains("tnormal(mean,std,min,max)"), "{err}");
    let o = cable_servo(&["sweep", "paper_fig11", "--mode", "sobol"]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn least_preload_answer() {
    let o = cable_servo(&[
        "design",
        "least-preload",
        "paper_fig11",
        "--load-nm",
        "0.72",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("least preload at M = 0.72 N m"), "{out}");
    assert!(out.contains("definition:"), "{out}");
}
