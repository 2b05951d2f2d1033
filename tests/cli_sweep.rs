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

/// Cases the physics stops are rows with a status, the stop's reason and empty figures;
/// they stay out of the statistics and count as not meeting the target.
#[test]
fn stopped_cases_are_named_and_never_numbers() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("low");
    let o = cable_servo(&[
        "sweep",
        "eots_tracking",
        "--vary",
        "drive.preload_n=1.5,60",
        "--set",
        "closed_loop.modes=[\"memory\"]",
        "--set",
        "closed_loop.duration_s=0.6",
        "--set",
        "closed_loop.metrics_start_s=0.1",
        "--out",
        path(&out),
    ]);
    let console = String::from_utf8_lossy(&o.stdout).to_string();
    // A stopped case misses its requirements: the sweep says how many, and exits 4.
    assert_eq!(
        o.status.code(),
        Some(4),
        "{console}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        console.contains("verdict: 1 of 2 cases miss a requirement"),
        "{console}"
    );
    let table = text(&out.join("sweep.csv"));
    let header: Vec<&str> = table.lines().next().unwrap_or("").split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|c| *c == name)
            .unwrap_or_else(|| panic!("{name} not in {header:?}"))
    };
    let rows: Vec<Vec<String>> = table
        .lines()
        .skip(1)
        .map(|l| {
            let mut r = csv::ReaderBuilder::new()
                .has_headers(false)
                .from_reader(l.as_bytes());
            r.records()
                .next()
                .and_then(Result::ok)
                .map(|rec| rec.iter().map(str::to_string).collect())
                .unwrap_or_default()
        })
        .collect();
    assert_eq!(rows.len(), 2, "{table}");
    let (low, high) = (&rows[0], &rows[1]);
    assert_eq!(low[col("memory_status")], "gross_slip", "{table}");
    assert!(low[col("memory_stop")].contains("gross slip"), "{table}");
    for figure in ["memory_rms_mrad", "memory_peak_mrad", "memory_p95_mrad"] {
        assert_eq!(low[col(figure)], "", "{figure}: {table}");
        assert!(!high[col(figure)].is_empty(), "{figure}: {table}");
    }
    assert_eq!(low[col("memory_passes_target")], "false");
    assert_eq!(high[col("memory_status")], "ok");
    assert!(
        console
            .contains("memory: 1 of 2 cases finished, 1 stopped by the physics, 0 could not run"),
        "{console}"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&text(&out.join("summary.json"))).unwrap();
    let m = &summary["outcomes"]["memory"];
    assert_eq!(m["stopped"], 1, "{m}");
    assert_eq!(m["first_not_finished"][0]["case"], 0, "{m}");
    assert_eq!(m["first_not_finished"][0]["status"], "gross_slip", "{m}");
}
