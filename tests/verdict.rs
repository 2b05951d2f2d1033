//! One verdict: `run`, `compare`, `margins`, `freqresp` and `design` judge a design by the
//! same requirements and agree on every requirement's pass or fail and on the exit code,
//! for designs that pass, that miss Ms by a little, that lack phase margin (at the free
//! span, or only under load), that are unstable, and that miss the pointing target with
//! good margins. Exploring another load with `margins --load-nm` changes none of it.

use std::collections::BTreeMap;
use std::process::{Command, Output};

fn cable_servo(args: &[String], cwd: &std::path::Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cable-servo"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("the binary runs")
}

/// A verdict table's rows: (requirement, condition) -> passes.
type Rows = BTreeMap<(String, String), bool>;

/// Requirement rows of a verdict table.
fn verdict_rows(stdout: &str) -> Rows {
    const NAMES: [&str; 11] = [
        "stable",
        "phase_margin",
        "gain_margin_up",
        "gain_margin_down",
        "sensitivity_peak",
        "operating_load",
        "pointing",
        "rms",
        "jitter",
        "settling",
        "base_rejection",
    ];
    let mut rows = BTreeMap::new();
    for line in stdout.lines() {
        let Some(name) = NAMES.iter().find(|n| line.starts_with(&format!("{n} "))) else {
            continue;
        };
        // Fixed columns: requirement (18), condition (22), then figures; pass word after.
        let condition = line.get(19..41).unwrap_or("").trim().to_string();
        let passes = if line.contains("  ok  ") {
            true
        } else if line.contains("  FAIL  ") {
            false
        } else {
            panic!("a verdict row without ok or FAIL: {line}")
        };
        rows.insert((name.to_string(), condition), passes);
    }
    rows
}

struct Design {
    name: &'static str,
    sets: &'static [&'static str],
    passes: bool,
    /// A requirement that must fail (with its condition's start), when the design fails.
    failing: Option<(&'static str, &'static str)>,
}

const DESIGNS: &[Design] = &[
    Design {
        name: "signable",
        sets: &[],
        passes: true,
        failing: None,
    },
    Design {
        name: "ms_over_2",
        sets: &[
            "closed_loop.controller.kp=450",
            "closed_loop.controller.ki=30000",
            "closed_loop.controller.kd=3.5",
        ],
        passes: false,
        failing: Some(("sensitivity_peak", "free span")),
    },
    Design {
        name: "pm_under_35",
        sets: &["closed_loop.controller.kp=3000"],
        passes: false,
        failing: Some(("phase_margin", "free span")),
    },
    Design {
        name: "unstable",
        sets: &["closed_loop.controller.kd=10"],
        passes: false,
        failing: Some(("stable", "free span")),
    },
    Design {
        name: "soft_under_load",
        sets: &["drive.preload_n=5"],
        passes: false,
        failing: Some(("phase_margin", "tangent")),
    },
    Design {
        name: "judged_mode_declared",
        sets: &["closed_loop.requirements.mode=\"memory\""],
        passes: true,
        failing: None,
    },
    Design {
        name: "pointing_fails",
        sets: &["closed_loop.target_mrad=0.03"],
        passes: false,
        failing: Some(("pointing", "memory")),
    },
];

/// Shorter runs (every command sees the same scenario, so the verdicts stay comparable).
const COMMON: &[&str] = &["closed_loop.duration_s=6"];

fn sets(d: &Design) -> Vec<String> {
    COMMON
        .iter()
        .chain(d.sets.iter())
        .flat_map(|s| ["--set".to_string(), s.to_string()])
        .collect()
}

#[test]
fn every_command_gives_one_verdict_per_design() {
    let tmp = tempfile::tempdir().unwrap();
    for d in DESIGNS {
        let mut outputs: Vec<(&str, Output)> = Vec::new();
        let mut args = vec!["run".to_string(), "eots_tracking".into()];
        args.extend(sets(d));
        args.extend(["--out".into(), format!("run-{}", d.name)]);
        outputs.push(("run", cable_servo(&args, tmp.path())));

        let mut args = vec!["margins".to_string(), "eots_tracking".into()];
        args.extend(sets(d));
        outputs.push(("margins", cable_servo(&args, tmp.path())));

        // Exploring a light load shows softer-cable margins but never changes the verdict.
        let mut args = vec!["margins".to_string(), "eots_tracking".into()];
        args.extend(sets(d));
        args.extend(["--load-nm".into(), "0.1".into()]);
        outputs.push(("margins --load-nm", cable_servo(&args, tmp.path())));

        let mut args = vec!["compare".to_string(), "eots_tracking".into()];
        args.extend(
            COMMON
                .iter()
                .flat_map(|s| ["--set".to_string(), s.to_string()]),
        );
        args.extend([
            "--design".into(),
            format!("{}:{}", d.name, d.sets.join(";")),
            "--out".into(),
            format!("compare-{}", d.name),
        ]);
        outputs.push(("compare", cable_servo(&args, tmp.path())));

        let mut args = vec!["freqresp".to_string(), "eots_tracking".into()];
        args.extend(sets(d));
        args.extend([
            "--frequencies".into(),
            "20,200".into(),
            "--amplitudes".into(),
            "0.8".into(),
            "--out".into(),
            format!("freqresp-{}", d.name),
        ]);
        outputs.push(("freqresp", cable_servo(&args, tmp.path())));

        let mut args = vec![
            "design".to_string(),
            "largest-load".into(),
            "eots_tracking".into(),
        ];
        args.extend(sets(d));
        args.extend(["--min".into(), "0.5".into(), "--max".into(), "1".into()]);
        args.extend(["--tol".into(), "0.25".into()]);
        outputs.push(("design", cable_servo(&args, tmp.path())));

        let want_code = if d.passes { 0 } else { 4 };
        let mut reference: Option<(&str, Rows)> = None;
        for (command, out) in &outputs {
            let stdout = String::from_utf8_lossy(&out.stdout);
            let stderr = String::from_utf8_lossy(&out.stderr);
            let rows = verdict_rows(&stdout);
            assert!(
                !rows.is_empty(),
                "{} {command}: no verdict table\n{stdout}\n{stderr}",
                d.name
            );
            assert_eq!(
                out.status.code(),
                Some(want_code),
                "{} {command}: exit code\n{stdout}\n{stderr}",
                d.name
            );
            let headline = if d.passes {
                "verdict: PASS"
            } else {
                "verdict: FAIL"
            };
            assert!(stdout.contains(headline), "{} {command}: {stdout}", d.name);
            if let Some((req, cond)) = d.failing {
                assert!(
                    rows.iter()
                        .any(|((r, c), ok)| r == req && c.starts_with(cond) && !ok),
                    "{} {command}: {req} at {cond} should fail\n{stdout}",
                    d.name
                );
            }
            match &reference {
                None => reference = Some((command, rows)),
                Some((first, want)) => assert_eq!(
                    &rows, want,
                    "{}: {command} and {first} disagree\n{stdout}",
                    d.name
                ),
            }
        }
        if !d.passes {
            // An unstable loop gets no margins anywhere: only its pole.
            let (_, rows) = reference.as_ref().unwrap();
            if d.name == "unstable" {
                assert!(!rows.keys().any(|(r, _)| r == "phase_margin"), "{rows:?}");
            }
        }
        // `run` writes the same verdict to summary.json, and a stopped mode has no figures.
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(tmp.path().join(format!("run-{}/summary.json", d.name)))
                .unwrap(),
        )
        .unwrap();
        assert_eq!(summary["verdict"]["passes"], serde_json::json!(d.passes));
        for mode in summary["modes"].as_array().unwrap() {
            if mode["completion"]["status"] != serde_json::json!("complete") {
                assert!(mode["peak_mrad"].is_null(), "{mode}");
                assert!(mode["rms_mrad"].is_null(), "{mode}");
                assert!(mode["metrics"].is_null(), "{mode}");
                assert!(mode["no_metrics_reason"].is_string(), "{mode}");
            }
        }
    }
}

/// No output of the commands above carries debug formatting or runaway digits.
#[test]
fn margins_of_an_unstable_or_poor_loop_read_as_words() {
    let tmp = tempfile::tempdir().unwrap();
    for set in [
        "closed_loop.controller.kd=10",
        "closed_loop.controller.kp=3000",
    ] {
        let out = cable_servo(&["margins".into(), "--set".into(), set.into()], tmp.path());
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        for bad in ["Some(", "None", "NaN", "inf"] {
            assert!(!text.contains(bad), "{set}: {bad} in\n{text}");
        }
        let long = text
            .split(|c: char| !(c.is_ascii_digit() || c == '.'))
            .filter(|w| w.chars().filter(char::is_ascii_digit).count() > 12)
            .count();
        assert_eq!(
            long, 0,
            "{set}: a number with more than 12 digits in\n{text}"
        );
        assert_eq!(out.status.code(), Some(4), "{text}");
    }
}

/// Every shipped closed-loop scenario: `run` and `margins` give the same exit code, and a
/// scenario fails exactly when its description says it is a failing example.
#[test]
fn shipped_scenarios_meet_their_requirements_or_say_they_fail() {
    use cable_servo::scenario::{Scenario, Study, BUILTIN};
    let tmp = tempfile::tempdir().unwrap();
    let mut checked = 0;
    for (name, _) in BUILTIN {
        let s = Scenario::load(name, &[]).unwrap();
        if s.study != Study::ClosedLoop {
            continue;
        }
        let description = s.description.clone().unwrap_or_default();
        let failing_example = description.contains("FAILING EXAMPLE");
        let want = if failing_example { 4 } else { 0 };
        let run = cable_servo(
            &[
                "run".into(),
                name.to_string(),
                "--out".into(),
                format!("run-{name}"),
            ],
            tmp.path(),
        );
        let margins = cable_servo(&["margins".into(), name.to_string()], tmp.path());
        for (command, out) in [("run", &run), ("margins", &margins)] {
            assert_eq!(
                out.status.code(),
                Some(want),
                "{name} {command} (description: {description})\n{}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
        }
        checked += 1;
    }
    assert!(checked >= 7, "{checked}");
}

/// The shipped tracking design's default frequency response: the brake would hold the
/// axis, so it slews; what the encoder cannot resolve is named, and the exit code is the
/// design's verdict, as `run` gives it.
#[test]
fn the_default_frequency_response_agrees_with_the_verdict() {
    let tmp = tempfile::tempdir().unwrap();
    let out = cable_servo(&["freqresp".into()], tmp.path());
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("operating point: slewing"), "{text}");
    assert!(text.contains("verdict: PASS"), "{text}");
}

/// A frequency response whose measurement run stops (an injection that saturates the
/// amplifier) keeps what it measured, marked incomplete everywhere: the exit code, the
/// `INCOMPLETE.txt` marker and `summary.json`, which also carries the design's verdict.
#[test]
fn a_stopped_measurement_is_incomplete_in_every_output() {
    let tmp = tempfile::tempdir().unwrap();
    let args: Vec<String> = [
        "freqresp",
        "eots_tracking",
        "--set",
        "closed_loop.duration_s=4",
        "--frequencies",
        "20",
        "--amplitudes",
        "7",
        "--out",
        "fr",
    ]
    .map(String::from)
    .to_vec();
    let out = cable_servo(&args, tmp.path());
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(out.status.code(), Some(4), "{text}");
    assert!(text.contains("INCOMPLETE"), "{text}");
    assert!(tmp.path().join("fr/INCOMPLETE.txt").exists(), "{text}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("fr/summary.json")).unwrap())
            .unwrap();
    assert_eq!(summary["complete"], serde_json::json!(false), "{summary}");
    assert_eq!(
        summary["verdict"]["passes"],
        serde_json::json!(true),
        "{summary}"
    );
}

/// A design that declares the mode it is judged in is tuned and compared in that mode: a
/// `--mode` that differs is refused rather than judged by another requirement.
#[test]
fn a_declared_judged_mode_is_the_one_tune_and_compare_judge() {
    let tmp = tempfile::tempdir().unwrap();
    let declared = [
        "--set",
        "closed_loop.duration_s=4",
        "--set",
        "closed_loop.requirements.mode=\"memoryless\"",
    ];
    let run = |args: &[&str]| {
        let args: Vec<String> = args.iter().map(|s| s.to_string()).collect();
        let out = cable_servo(&args, tmp.path());
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        (out.status.code(), text)
    };
    let mut tune = vec!["design", "tune", "--quick", "--feedforward", "off"];
    tune.extend(declared);
    let (_, text) = run(&[tune.as_slice(), &["--out", "tuned"]].concat());
    assert!(text.contains("(memoryless mode)"), "{text}");
    let written = std::fs::read_to_string(tmp.path().join("tuned/tuned.toml")).unwrap();
    assert!(written.contains("mode = \"memoryless\""), "{written}");
    let (code, text) = run(&[tune.as_slice(), &["--mode", "memory", "--out", "t2"]].concat());
    assert_eq!(code, Some(2), "{text}");
    assert!(text.contains("closed_loop.requirements.mode"), "{text}");
    assert!(!tmp.path().join("t2").exists());
    let mut compare = vec!["compare", "eots_tracking", "--mode", "none", "--out", "c"];
    compare.extend(declared);
    let (code, text) = run(&compare);
    assert_eq!(code, Some(3), "{text}");
    assert!(text.contains("closed_loop.requirements.mode"), "{text}");
    assert!(!tmp.path().join("c").exists());
}
