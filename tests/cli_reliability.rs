//! Faults and mistakes through the binary: what `--force` may replace, merges of
//! incomplete shard sets, interruption by signals, runs too large to hold, empty metrics.
//! Each test checks the exit code, the message, what is left on disk and that nothing
//! incomplete is claimed complete.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const EXE: &str = env!("CARGO_BIN_EXE_cable-servo");

fn cable_servo(args: &[&str], cwd: &Path) -> Output {
    Command::new(EXE)
        .args(args)
        .current_dir(cwd)
        .env_remove("RUST_BACKTRACE")
        .output()
        .expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

fn no_panic(o: &Output) {
    let err = stderr(o);
    assert!(!err.contains("panicked"), "{err}");
}

/// Runs `args` (with `--out` under a fresh directory) and requires an input refusal: exit
/// 3, no panic, nothing left behind. Returns stderr.
fn refused_as_input(args: &[&str]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let mut all: Vec<&str> = args.to_vec();
    all.extend(["--out", p(&out)]);
    let o = cable_servo(&all, dir.path());
    no_panic(&o);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{args:?}: {err}");
    assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
    err
}

/// A quick quasi-static run.
fn quick_run(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "run",
        "paper_bench",
        "--set",
        "quasi_static.duration_s=2",
        "--set",
        "quasi_static.profile_times_s=[1.0]",
        "--out",
        p(out),
    ];
    args.extend_from_slice(extra);
    cable_servo(&args, out.parent().unwrap())
}

#[test]
fn force_replaces_only_results_this_program_wrote() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    // A user's regular file at the results path.
    fs::write(&out, b"my thesis").unwrap();
    let o = quick_run(&out, &["--force"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(5), "{err}");
    assert!(err.contains("regular file of 9 bytes"), "{err}");
    assert!(err.contains("--out"), "{err}");
    assert_eq!(fs::read(&out).unwrap(), b"my thesis");
    assert_eq!(entries(tmp.path()), vec!["out"]);
    no_panic(&o);
    // A directory the program never wrote.
    fs::remove_file(&out).unwrap();
    fs::create_dir(&out).unwrap();
    fs::write(out.join("notes.txt"), b"mine").unwrap();
    let o = quick_run(&out, &["--force"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(5), "{err}");
    assert!(
        err.contains("notes.txt") && err.contains("not results"),
        "{err}"
    );
    assert_eq!(entries(&out), vec!["notes.txt"]);
    assert_eq!(entries(tmp.path()), vec!["out"]);
    // Its own results are replaced.
    fs::remove_dir_all(&out).unwrap();
    let o = quick_run(&out, &[]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(out.join(".cable-servo-results").is_file());
    let o = quick_run(&out, &["--force"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(entries(tmp.path()), vec!["out"]);
}

#[test]
fn diagnose_single_files_are_not_overwritten_without_force() {
    let tmp = tempfile::tempdir().unwrap();
    let log = tmp.path().join("log.csv");
    fs::write(&log, "t_s,theta_in_rad,theta_out_rad,load_nm\n0,0,0,0\n").unwrap();
    let model = tmp.path().join("model.toml");
    fs::write(&model, b"# my own scenario\n").unwrap();
    let json = tmp.path().join("d.json");
    fs::write(&json, b"{\"mine\": 1}").unwrap();
    let base = [
        "diagnose",
        "--scenario",
        "gimbal_ident",
        "--data",
        p(&log),
        "--out",
        "res",
    ];
    for (flag, file) in [("--save-model", &model), ("--json", &json)] {
        let before = fs::read(file).unwrap();
        let o = cable_servo(&[&base[..], &[flag, p(file)]].concat(), tmp.path());
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(5), "{flag}: {err}");
        assert!(err.contains("refusing to overwrite existing file"), "{err}");
        assert!(err.contains("--force"), "{err}");
        // With --force, a file this program did not write is still refused.
        let o = cable_servo(
            &[&base[..], &[flag, p(file), "--force"]].concat(),
            tmp.path(),
        );
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(5), "{flag}: {err}");
        assert!(err.contains("does not look like"), "{err}");
        assert_eq!(fs::read(file).unwrap(), before);
        no_panic(&o);
    }
    assert_eq!(entries(tmp.path()), vec!["d.json", "log.csv", "model.toml"]);
}

const SHARD_ARGS: [&str; 10] = [
    "sweep",
    "paper_fig11",
    "--vary",
    "drive.preload_n=uniform(40,150)",
    "--vary",
    "backlash.load_nm=uniform(0.1,1)",
    "--samples",
    "12",
    "--threads",
    "1",
];

fn shard(dir: &Path, k: usize, n: usize, seed: &str) -> PathBuf {
    let out = dir.join(format!("s{k}-{seed}"));
    let shard = format!("{k}/{n}");
    let args = [
        &SHARD_ARGS[..],
        &["--seed", seed, "--shard", &shard, "--out", p(&out)],
    ]
    .concat();
    let o = cable_servo(&args, dir);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    out
}

fn merge(dir: &Path, out: &Path, shards: &[&PathBuf], extra: &[&str]) -> Output {
    let mut args = vec!["merge", "--out", p(out)];
    args.extend_from_slice(extra);
    args.extend(shards.iter().map(|s| p(s)));
    cable_servo(&args, dir)
}

#[test]
fn merge_refuses_a_missing_truncated_duplicated_or_foreign_shard() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let s1 = shard(dir, 1, 3, "5");
    let s2 = shard(dir, 2, 3, "5");
    let s3 = shard(dir, 3, 3, "5");
    let out = dir.join("merged.csv");

    // One shard missing.
    let o = merge(dir, &out, &[&s1, &s3], &[]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("shard 2/3 missing (4 of 12 cases)"), "{err}");
    assert!(err.contains("--partial"), "{err}");
    assert!(!out.exists());

    // A shard given twice.
    let o = merge(dir, &out, &[&s1, &s2, &s2, &s3], &[]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("shard 2/3 given twice"), "{err}");
    assert!(!out.exists());

    // A shard of another sweep (other seed: other case list).
    let foreign = shard(dir, 2, 3, "6");
    let o = merge(dir, &out, &[&s1, &foreign, &s3], &[]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("belongs to another sweep"), "{err}");
    assert!(err.contains(p(&foreign)), "{err}");
    assert!(!out.exists());

    // A shard cut short: its last row removed.
    let table = fs::read_to_string(s3.join("sweep.csv")).unwrap();
    let cut: Vec<&str> = table.lines().collect();
    fs::write(s3.join("sweep.csv"), cut[..cut.len() - 1].join("\n") + "\n").unwrap();
    let o = merge(dir, &out, &[&s1, &s2, &s3], &[]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(
        err.contains("shard 3/3") && err.contains("truncated: 3 of its 4 cases"),
        "{err}"
    );
    assert!(!out.exists());
    // A row cut mid-write.
    fs::write(s3.join("sweep.csv"), &table[..table.len() - 4]).unwrap();
    let o = merge(dir, &out, &[&s1, &s2, &s3], &[]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("cut short"), "{err}");
    fs::write(s3.join("sweep.csv"), &table).unwrap();

    // Asked for: a partial merge, marked partial on the terminal and in its record.
    let o = merge(dir, &out, &[&s1, &s3], &["--partial"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("PARTIAL merge: 8 of 12 cases"),
        "{}",
        stdout(&o)
    );
    assert!(stderr(&o).contains("shard 2/3 missing"), "{}", stderr(&o));
    let record = fs::read_to_string(dir.join("merged.csv.merge.json")).unwrap();
    assert!(record.contains("\"partial\": true"), "{record}");
    assert!(record.contains("\"complete\": false"), "{record}");
    assert_eq!(fs::read_to_string(&out).unwrap().lines().count(), 9);

    // The whole set merges, complete.
    let o = merge(dir, &out, &[&s3, &s1, &s2], &["--force"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("12 cases merged"), "{}", stdout(&o));
    let record = fs::read_to_string(dir.join("merged.csv.merge.json")).unwrap();
    assert!(record.contains("\"complete\": true"), "{record}");
}

/// Poll `done` every 10 ms until it gives a value. Harness use only: the deadline is a hang
/// guard, far beyond what any machine needs, never a speed requirement; reaching it panics
/// with "hung" and `what`.
fn wait_for<T>(what: &str, mut done: impl FnMut() -> Option<T>) -> T {
    const HANG_GUARD: std::time::Duration = std::time::Duration::from_secs(300);
    let start = std::time::Instant::now();
    loop {
        if let Some(v) = done() {
            return v;
        }
        assert!(start.elapsed() < HANG_GUARD, "hung: {what}");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

/// The staging directory of process `pid` in `dir` once it is registered for removal on a
/// signal: its results marker is written right after registration.
fn staging_of(dir: &Path, pid: u32) -> Option<PathBuf> {
    let tag = format!(".partial-{pid}-");
    entries(dir)
        .into_iter()
        .find(|e| e.contains(&tag))
        .map(|e| dir.join(e))
        .filter(|d| d.join(".cable-servo-results").exists())
}

/// Complete data rows in a CSV being written (its header line and any partly written last
/// line not counted).
fn complete_rows(csv: &Path) -> usize {
    let newlines = fs::read(csv)
        .map(|b| b.iter().filter(|&&c| c == b'\n').count())
        .unwrap_or(0);
    newlines.saturating_sub(1)
}

fn send(signal: &str, pid: u32) {
    let ok = Command::new("kill")
        .args([signal, &pid.to_string()])
        .status()
        .expect("kill runs")
        .success();
    assert!(ok, "kill {signal} {pid}");
}

#[cfg(unix)]
#[test]
fn sigint_during_a_sweep_keeps_finished_cases_marked_incomplete() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("tol");
    let child = Command::new(EXE)
        .args([
            "sweep",
            "eots_tolerance",
            "--set",
            "sweep.samples=4000",
            "--threads",
            "2",
            "--out",
            p(&out),
        ])
        .current_dir(tmp.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The signal goes once the staged sweep.csv holds a finished case: the sweep is under
    // way and stops gracefully. The table is buffered, so the first rows show after a few
    // dozen cases (about 25 of 330 bytes in 8 KiB), under 1 % of the 4000 drawn (the
    // scenario's 1000 raised so): whatever the machine's speed, the sweep is far from done
    // when the signal arrives.
    let seen = wait_for("no finished case in the staged sweep.csv", || {
        let staging = staging_of(tmp.path(), child.id())?;
        let rows = complete_rows(&staging.join("sweep.csv"));
        (rows >= 1).then_some(rows)
    });
    send("-INT", child.id());
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted by SIGINT"), "{err}");
    no_panic(&o);
    // Only the results directory: no hidden staging left.
    assert_eq!(entries(tmp.path()), vec!["tol"]);
    let marker = fs::read_to_string(out.join("INCOMPLETE.txt")).unwrap();
    assert!(marker.contains("interrupted by SIGINT"), "{marker}");
    assert!(marker.contains("kept: sweep.csv"), "{marker}");
    let summary = fs::read_to_string(out.join("summary.json")).unwrap();
    assert!(summary.contains("\"complete\": false"), "{summary}");
    assert!(
        summary.contains("\"interrupted_by\": \"SIGINT\""),
        "{summary}"
    );
    // Every case seen finished before the signal is kept, and the signal stopped the sweep
    // short of its 4000 cases.
    let kept = complete_rows(&out.join("sweep.csv"));
    println!("{kept} of 4000 cases kept, {seen} seen before the signal");
    assert!(
        (seen..=3999).contains(&kept),
        "{kept} rows kept, {seen} seen before the signal: all 4000 cases ran, or finished rows were lost"
    );
    assert!(
        marker.contains(&format!("with the {kept} finished cases of 4000")),
        "{marker}"
    );
    // Such a shard is refused by merge as truncated.
    let o = cable_servo(
        &["merge", "--out", p(&tmp.path().join("m.csv")), p(&out)],
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stderr(&o).contains("truncated"), "{}", stderr(&o));
}

#[cfg(unix)]
#[test]
fn sigterm_during_a_run_leaves_nothing_and_stale_staging_is_cleared() {
    let tmp = tempfile::tempdir().unwrap();
    // A staging directory left by a process that no longer exists.
    let stale = tmp.path().join(".out.partial-4999999-0");
    fs::create_dir(&stale).unwrap();
    fs::write(stale.join("timeseries.csv"), b"t_s\n").unwrap();
    let out = tmp.path().join("out");
    let child = Command::new(EXE)
        .args([
            "run",
            "eots_tracking",
            "--set",
            "closed_loop.duration_s=100",
            "--out",
            p(&out),
        ])
        .current_dir(tmp.path())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The run's own staging directory, registered for removal: the 100 s simulation has
    // begun (it writes nothing until it ends) and the stale directory was cleared first.
    let staging = wait_for("the run did not stage its results", || {
        staging_of(tmp.path(), child.id())
    });
    assert!(
        !stale.exists(),
        "a new run kept the stale staging directory"
    );
    send("-TERM", child.id());
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(143), "{err}");
    assert!(err.contains("interrupted by SIGTERM"), "{err}");
    assert!(err.contains("partial results removed"), "{err}");
    assert!(err.contains(&staging.display().to_string()), "{err}");
    assert!(!stale.exists(), "stale staging directory kept");
    assert!(entries(tmp.path()).is_empty(), "{:?}", entries(tmp.path()));
}

/// Columns the bench-log format does not define are ignored and named in the report.
#[test]
fn extra_log_columns_are_listed_in_the_diagnosis_report() {
    let tmp = tempfile::tempdir().unwrap();
    let log = tmp.path().join("log.csv");
    let o = cable_servo(
        &[
            "synth",
            "--scenario",
            "gimbal_ident",
            "--seed",
            "4",
            "--out",
            p(&log),
        ],
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // Two columns of the lab's own beside the format's.
    let text = fs::read_to_string(&log).unwrap();
    let widened: String = text
        .lines()
        .map(|l| {
            if l.starts_with('#') {
                format!("{l}\n")
            } else if l.starts_with("t_s") {
                format!("{l},lab_temp_c,operator\n")
            } else {
                format!("{l},21.5,A\n")
            }
        })
        .collect();
    fs::write(&log, widened).unwrap();
    let o = cable_servo(
        &[
            "diagnose",
            "--scenario",
            "gimbal_ident",
            "--data",
            p(&log),
            "--out",
            "d",
        ],
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let report = fs::read_to_string(tmp.path().join("d/report.txt")).unwrap();
    assert!(
        report.contains("(not in the bench-log format): lab_temp_c, operator"),
        "{report}"
    );
}

/// An absurd thread count is lowered with a note instead of exhausting the process.
#[test]
fn absurd_thread_counts_are_lowered_with_a_note() {
    let tmp = tempfile::tempdir().unwrap();
    let o = cable_servo(
        &["sweep", "paper_fig11", "--threads", "100000", "--out", "s"],
        tmp.path(),
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--threads 100000 lowered to"),
        "{}",
        stderr(&o)
    );
    assert!(tmp.path().join("s/sweep.csv").is_file());
}

/// A run too large to hold in memory is refused before it starts, with the estimate and
/// the setting that lowers it, and leaves nothing behind.
#[test]
fn runs_too_large_to_hold_are_refused_with_the_setting_that_lowers_them() {
    let err = refused_as_input(&[
        "run",
        "eots_tracking",
        "--set",
        "closed_loop.duration_s=20000",
    ]);
    assert!(
        err.contains("MB in memory") && err.contains("lower closed_loop.timeseries_rate_hz"),
        "{err}"
    );
}

/// A run that would compute for longer than a run may is refused before it starts: the
/// command first says how long it estimated, then the refusal names the settings that
/// shorten it; nothing is left behind. A sweep whose cases add up past a sweep's limit
/// is refused the same way, pointing to shards.
#[test]
fn runs_too_long_to_compute_are_refused_with_the_settings_that_shorten_them() {
    let err = refused_as_input(&[
        "run",
        "eots_tracking",
        "--set",
        "closed_loop.duration_s=50000",
        "--set",
        "closed_loop.rk4_substeps=100",
        "--set",
        "closed_loop.timeseries_rate_hz=0.01",
    ]);
    assert!(err.contains("this run computes for about"), "{err}");
    assert!(
        err.contains("more than the 12 h a run may take")
            && err.contains("shorten closed_loop.duration_s (at most about"),
        "{err}"
    );
    let err = refused_as_input(&[
        "sweep",
        "eots_tolerance",
        "--set",
        "closed_loop.duration_s=50000",
        "--vary",
        "drive.preload_n=uniform(60,90)",
        "--samples",
        "4000",
    ]);
    assert!(
        err.contains("a sweep (or one shard of it) may take") && err.contains("--shard"),
        "{err}"
    );
}

/// Gains five times too high: the amplifier's limit would hold the loop in a saturated
/// oscillation that once ran "complete" at 4 mrad RMS; it now stops, named as unstable,
/// with the gains to check, and the results are marked incomplete.
#[test]
fn a_saturated_unstable_loop_is_stopped_and_named() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("hot");
    let o = cable_servo(
        &[
            "run",
            "eots_tracking",
            "--set",
            "closed_loop.controller.kp=1500",
            "--set",
            "closed_loop.controller.ki=100000",
            "--set",
            "closed_loop.controller.kd=12.5",
            "--set",
            "closed_loop.duration_s=3",
            "--out",
            p(&out),
        ],
        dir.path(),
    );
    no_panic(&o);
    let (err, table) = (stderr(&o), stdout(&o));
    assert_eq!(o.status.code(), Some(4), "{err}");
    assert!(
        err.contains("the loop is unstable") && err.contains("amplifier limit"),
        "{err}"
    );
    assert!(err.contains("kp = 1500, ki = 100000, kd = 12.5"), "{err}");
    assert!(table.contains(" - "), "{table}");
    assert!(out.join("INCOMPLETE.txt").is_file());
}

/// Numbers far outside any servo axis pass a sign check but not the physical ranges: each
/// is refused naming the key, the value and the range with its reason, and nothing is
/// written.
#[test]
fn loop_values_outside_physical_ranges_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (set, key, range) in [
        (
            "closed_loop.motor.resistance_ohm=1e-300",
            "closed_loop.motor.resistance_ohm",
            "outside 0.001 to 1000",
        ),
        (
            "closed_loop.output.inertia_kg_m2=1e30",
            "closed_loop.output.inertia_kg_m2",
            "a drum with its payload",
        ),
        (
            "closed_loop.controller.kp=1e300",
            "closed_loop.controller.kp",
            "a servo gain",
        ),
        (
            "closed_loop.motor.current_limit_a=1e-9",
            "closed_loop.motor.current_limit_a",
            "an amplifier's current",
        ),
    ] {
        let out = dir.path().join("r");
        let o = cable_servo(
            &["run", "eots_tracking", "--set", set, "--out", p(&out)],
            dir.path(),
        );
        no_panic(&o);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(3), "{set}: {err}");
        assert!(err.contains(key) && err.contains(range), "{set}: {err}");
        assert!(entries(dir.path()).is_empty(), "{set}");
    }
}

/// A bisection asked for a tolerance no double resolves, or over a range of hundreds of
/// decades, ends after a few dozen probes, says the tolerance it worked to, and prints
/// no number of hundreds of digits.
#[test]
fn design_searches_end_and_say_what_tolerance_they_reached() {
    let dir = tempfile::tempdir().unwrap();
    for args in [
        &[
            "design",
            "least-preload",
            "--load-nm",
            "0.5",
            "--tol-n",
            "1e-300",
        ][..],
        &[
            "design",
            "least-preload",
            "--load-nm",
            "0.5",
            "--max-n",
            "1e300",
        ][..],
    ] {
        let o = cable_servo(args, dir.path());
        no_panic(&o);
        let out = stdout(&o);
        assert_eq!(o.status.code(), Some(0), "{args:?}: {out}{}", stderr(&o));
        let probes: usize = out
            .split(" probes)")
            .next()
            .and_then(|s| s.rsplit(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("probes in {out}"));
        assert!(probes <= 64, "{probes} probes: {out}");
        let longest = out
            .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-'))
            .map(str::len)
            .max()
            .unwrap_or(0);
        assert!(longest < 24, "a number of {longest} characters: {out}");
        if args.contains(&"1e-300") {
            assert!(out.contains("tolerance 1e-300 raised to"), "{out}");
        }
    }
}

/// The help names every built-in scenario, so a user can find each by name.
#[test]
fn help_lists_every_built_in_scenario() {
    let dir = tempfile::tempdir().unwrap();
    let o = cable_servo(&["--help"], dir.path());
    let text = stdout(&o).replace('\n', " ");
    for (name, _) in cable_servo::scenario::BUILTIN {
        assert!(text.contains(name), "{name} missing from --help: {text}");
    }
}
