//! The `sweep`, `merge` and `design` commands end to end.

use std::path::Path;
use std::process::{Command, Output};

#[path = "support/capstan.rs"]
mod capstan;

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

/// The console of a run that must exit with `code`; on another, both its streams.
fn exits(o: &Output, code: i32) -> String {
    let console = String::from_utf8_lossy(&o.stdout).to_string();
    assert_eq!(
        o.status.code(),
        Some(code),
        "{console}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    console
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

/// The error stream of a run that must be refused with `code`.
fn refused(o: &Output, code: i32) -> String {
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(o.status.code(), Some(code), "{err}");
    err
}

#[test]
fn bad_vary_names_the_argument_and_the_forms() {
    let o = cable_servo(&[
        "sweep",
        "paper_fig11",
        "--vary",
        "drive.preload_n=gauss(1,2)",
    ]);
    let err = refused(&o, 3);
    assert!(err.contains("--vary drive.preload_n=gauss(1,2)"), "{err}");
    assert!(err.contains("tnormal(mean,std,min,max)"), "{err}");
    let o = cable_servo(&["sweep", "paper_fig11", "--mode", "sobol"]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn a_mistyped_vary_key_is_named_with_where_it_comes_from_and_leaves_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sx");
    let o = cable_servo(&[
        "sweep",
        "paper_bench",
        "--vary",
        "drive.prelaod_n=10,20",
        "--out",
        path(&out),
    ]);
    let err = refused(&o, 3);
    assert!(err.contains("drive.prelaod_n=10"), "{err}");
    assert!(err.contains("--vary"), "{err}");
    assert!(err.contains("did you mean `preload_n`"), "{err}");
    assert!(!out.exists());
    // A key varied twice would drop its first values: refused.
    let o = cable_servo(&[
        "sweep",
        "paper_bench",
        "--vary",
        "drive.preload_n=10:100:10",
        "--vary",
        "drive.preload_n=5,6",
        "--out",
        path(&out),
    ]);
    let err = refused(&o, 3);
    assert!(err.contains("already varied"), "{err}");
    assert!(!out.exists());
}

/// The first number in `line` after `after`.
fn number_after(line: &str, after: &str) -> f64 {
    let rest = &line[line
        .find(after)
        .unwrap_or_else(|| panic!("{after:?} in {line}"))
        + after.len()..];
    let end = rest
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == 'e'))
        .unwrap_or(rest.len());
    rest[..end]
        .parse()
        .unwrap_or_else(|e| panic!("{:?} in {line}: {e}", &rest[..end]))
}

/// The backlash protocol of paper_fig11 at 0.72 N m with `preload_n`, run on its own:
/// `(exit code, regime)`.
fn backlash_at(preload_n: f64) -> (Option<i32>, String) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b");
    let o = cable_servo(&[
        "run",
        "paper_fig11",
        "--set",
        &format!("drive.preload_n={preload_n}"),
        "--set",
        "backlash.load_nm=0.72",
        "--out",
        path(&out),
    ]);
    let console = String::from_utf8_lossy(&o.stdout).to_string();
    let row = console
        .lines()
        .nth(1)
        .unwrap_or_else(|| panic!("no result row: {console}"));
    let regime = row
        .split_whitespace()
        .last()
        .unwrap_or_default()
        .to_string();
    (o.status.code(), regime)
}

/// The least preload is checked against the closed form of the first +M loading (see
/// tests/support/capstan.rs: gross slip of the loose half on the pulley at
/// `M = 0.2333 N m per N of preload` for this drive, so 3.08602 N for 0.72 N m; the later
/// -M and +M do not fail first) and against runs of the protocol on their own (not through
/// the search): the answer passes and the answer less the tolerance fails. The bisection
/// returns the upper end of its last bracket, so the answer lies in
/// `[threshold, threshold + tolerance]`, up to the 5e-6 N of printing it to 6 significant
/// digits. The comparison bound
/// is `M / (2 r_drum) = 0.72 / 0.205 = 3.5122 N`, printed to 3 decimals; the search over
/// [0.01, 700] N (1e5 capped at 5 % strain of 1.4e4 N) to 0.01 N needs
/// `ceil(log2(69999)) + 2 = 19` probes at most.
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
    assert!(out.contains("definition:"), "{out}");
    let answer = out
        .lines()
        .find(|l| l.starts_with("least preload at M = 0.72 N m (memory model): "))
        .unwrap_or_else(|| panic!("{out}"));
    let preload = number_after(answer, "(memory model): ");
    let tolerance = number_after(answer, "(+");
    let probes = number_after(answer, "N, ");
    let bound_line = out
        .lines()
        .find(|l| l.contains("M/(2*drum_radius_m) = "))
        .unwrap_or_else(|| panic!("{out}"));
    let bound = number_after(bound_line, "M/(2*drum_radius_m) = ");
    let exact_bound = 0.72 / (2.0 * 0.1025);
    assert!(
        (bound - exact_bound).abs() <= 0.5e-3,
        "{bound} against {exact_bound}"
    );
    assert_eq!(tolerance, 0.01, "{answer}");
    let most = ((700.0f64 - 0.01) / 0.01).log2().ceil() + 2.0;
    assert!(
        probes >= 2.0 && probes <= most,
        "{probes} probes, at most {most}"
    );
    // Friction on the wraps moves the span tensions unequally: the answer lies below the
    // equal-and-opposite slack bound, which is itself no lower bound.
    assert!(preload > 0.0 && preload < exact_bound, "{answer}");
    let (per_newton, _, _) = capstan::gross_slip_torque_nm(&capstan::PAPER_DRIVE, 1.0);
    let threshold = 0.72 / per_newton;
    println!("answer {preload} N, closed form {threshold} N");
    assert!(
        preload >= threshold - 5e-6 && preload <= threshold + tolerance + 5e-6,
        "{preload} N against the closed form {threshold} N (+{tolerance} N)"
    );
    // The answer is printed to 6 significant digits (within 5e-6 N here): 1e-5 N above it
    // is at least the answer, 1e-5 N below the answer less the tolerance is below it.
    let (code, regime) = backlash_at(preload + 1e-5);
    assert_eq!(
        (code, regime.as_str()),
        (Some(0), "ok"),
        "at the answer {preload} N"
    );
    let below = preload - tolerance - 1e-5;
    let (code, regime) = backlash_at(below);
    assert_eq!(code, Some(4), "at {below} N: {regime}");
    assert!(
        regime == "gross_slip" || regime == "slack",
        "at {below} N: {regime}"
    );
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
    // A stopped case misses its requirements: the sweep says how many, and exits 4.
    let console = exits(&o, 4);
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

/// A backlash case the physics stops carries its reason to the console, `summary.json`
/// and the `stop` column of `sweep.csv`; with no requirement to judge, the sweep itself
/// succeeds.
#[test]
fn a_slack_case_names_its_reason_everywhere() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("slack");
    let o = cable_servo(&[
        "sweep",
        "paper_fig11",
        "--vary",
        "drive.preload_n=10,100",
        "--vary",
        "backlash.load_nm=3",
        "--out",
        path(&out),
    ]);
    let console = exits(&o, 0);
    let line = console
        .lines()
        .find(|l| l.trim_start().starts_with("case 0 "))
        .unwrap_or_else(|| panic!("no line for the stopped case: {console}"));
    let reason = line
        .split_once("): slack ")
        .map(|(_, r)| r.trim())
        .unwrap_or_default();
    assert!(reason.contains("span goes slack"), "{line}");
    assert!(reason.contains("raise preload_n above"), "{line}");

    let summary: serde_json::Value =
        serde_json::from_str(&text(&out.join("summary.json"))).unwrap();
    let first = &summary["outcomes"]["cases"]["first_not_finished"][0];
    assert_eq!(first["status"], "slack", "{first}");
    assert_eq!(first["reason"], reason, "{first}");

    let mut table = csv::Reader::from_path(out.join("sweep.csv")).unwrap();
    let header = table.headers().unwrap().clone();
    let col = |name: &str| {
        header
            .iter()
            .position(|c| c == name)
            .unwrap_or_else(|| panic!("{name} not in {header:?}"))
    };
    let (status, stop) = (col("status"), col("stop"));
    let rows: Vec<csv::StringRecord> = table.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 2);
    assert_eq!(&rows[0][status], "slack");
    assert_eq!(&rows[0][stop], reason);
    assert_eq!(&rows[1][status], "ok");
    assert_eq!(&rows[1][stop], "");
}

/// Shards are checked cell by cell before anything is merged: junk a hand edit or a
/// damaged disk leaves in a shard is refused with its file, line, column and value, and
/// no merged table is left behind; good shards, quoted reasons included, still merge into
/// the single run's file.
#[test]
fn merge_refuses_junk_cells_naming_file_line_and_column() {
    let tmp = tempfile::tempdir().unwrap();
    // 10 N slips on a 3 rad pulley wrap at 0.72 N m (a reason with commas, so quoted) and
    // goes slack at 3 N m; 100 N carries both.
    let common = [
        "sweep",
        "paper_fig11",
        "--vary",
        "drive.preload_n=10,100",
        "--vary",
        "backlash.load_nm=0.72,3",
        "--set",
        "drive.pulley_wrap_rad=3",
        "--threads",
        "1",
    ];
    let run = |extra: &[&str], dir: &Path| {
        let args = [&common[..], extra, &["--out", path(dir)]].concat();
        let o = cable_servo(&args);
        exits(&o, 0);
    };
    let (single, s1, s2) = (
        tmp.path().join("single"),
        tmp.path().join("s1"),
        tmp.path().join("s2"),
    );
    run(&[], &single);
    run(&["--shard", "1/2"], &s1);
    run(&["--shard", "2/2"], &s2);
    let merge = |out: &Path| cable_servo(&["merge", "--out", path(out), path(&s1), path(&s2)]);

    let good = tmp.path().join("good.csv");
    let o = merge(&good);
    exits(&o, 0);
    let merged = text(&good);
    assert_eq!(merged, text(&single.join("sweep.csv")));
    assert!(
        merged.contains(",\"gross slip of the upper half"),
        "{merged}"
    );

    let table = s1.join("sweep.csv");
    let original = text(&table);
    let lines: Vec<&str> = original.lines().collect();
    assert!(
        lines[1].starts_with("0,10,0.72,,,,gross_slip,"),
        "{original}"
    );
    assert!(lines[2].starts_with("2,100,0.72,"), "{original}");
    let ok = lines[2].split(',').collect::<Vec<_>>();
    let edited = |column: usize, value: &str| {
        let mut cells = ok.clone();
        cells[column - 1] = value;
        cells.join(",")
    };
    let slipped_with_figures = lines[1].replacen("0,10,0.72,,", "0,10,0.72,0.5,", 1);
    let slipped_without_reason = "0,10,0.72,,,,gross_slip,false,,gross_slip,".to_string();
    // (line, row, column, name, value as quoted in the message, what the message says)
    let junk = [
        (
            3,
            "2,10,abc,nan,,,ok,false,1,ok,".to_string(),
            3,
            "load_nm",
            "\"abc\"",
            "finite number",
        ),
        (
            3,
            edited(2, "inf"),
            2,
            "preload_n",
            "\"inf\"",
            "finite number",
        ),
        (
            3,
            edited(4, "nan"),
            4,
            "initial_mrad",
            "\"nan\"",
            "finite number",
        ),
        (
            3,
            edited(9, "1e999"),
            9,
            "tension_upper_n",
            "\"1e999\"",
            "finite number",
        ),
        (
            3,
            edited(7, "fine"),
            7,
            "regime",
            "\"fine\"",
            "`gross_slip`",
        ),
        (
            3,
            edited(8, "yes"),
            8,
            "anchor_reached",
            "\"yes\"",
            "`true` or `false`",
        ),
        (
            3,
            edited(10, "done"),
            10,
            "status",
            "\"done\"",
            "`unstable`",
        ),
        (
            2,
            slipped_with_figures,
            4,
            "initial_mrad",
            "\"0.5\"",
            "must be blank",
        ),
        (
            2,
            slipped_without_reason,
            11,
            "stop",
            "a blank cell",
            "must not be blank",
        ),
    ];
    for (k, (line, row, column, name, value, says)) in junk.into_iter().enumerate() {
        let mut rows = lines.clone();
        rows[line - 1] = &row;
        std::fs::write(&table, rows.join("\n") + "\n").unwrap();
        let out = tmp.path().join(format!("junk-{k}.csv"));
        let o = merge(&out);
        let err = String::from_utf8_lossy(&o.stderr).to_string();
        assert_eq!(o.status.code(), Some(3), "{row}: {err}");
        let at = format!(
            "{}:{line}: column {column} ({name}) holds {value}",
            path(&table)
        );
        assert!(err.contains(&at), "{row}\nexpected {at}\n{err}");
        assert!(err.contains(says), "{row}: {err}");
        assert!(!out.exists(), "{row}: a merged table was written");
        assert!(!tmp.path().join(format!("junk-{k}.csv.merge.json")).exists());
    }
    std::fs::write(&table, &original).unwrap();
    let o = merge(&tmp.path().join("again.csv"));
    exits(&o, 0);
}
