//! Numbers users read stay short: extreme inputs (a load of 1e300 N m, a friction
//! coefficient of 1e-300) must not print hundreds of digits, nor Rust's `Some(`, `None`
//! or `NaN`, in any message or table of the command line.

use std::path::PathBuf;
use std::process::Command;

const EXE: &str = env!("CARGO_BIN_EXE_cable-servo");

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs of digits (a dot inside a number joins its two runs) longer than 12 characters.
fn long_numbers(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut digits = String::new();
    let flush = |digits: &mut String, out: &mut Vec<String>| {
        if digits.chars().filter(char::is_ascii_digit).count() > 12 {
            out.push(digits.clone());
        }
        digits.clear();
    };
    for c in line.chars() {
        if c.is_ascii_digit() || (c == '.' && !digits.is_empty()) {
            digits.push(c);
        } else {
            flush(&mut digits, &mut out);
        }
    }
    flush(&mut digits, &mut out);
    out
}

#[test]
fn the_digit_counter_finds_long_numbers_only() {
    assert!(long_numbers("0.1234567 N at 12345678 Hz, 1e300").is_empty());
    assert_eq!(
        long_numbers("M = 100000000000000000 N"),
        ["100000000000000000"]
    );
    assert_eq!(long_numbers("0.0000000000001"), ["0.0000000000001"]);
}

#[test]
fn extreme_inputs_print_short_numbers_and_no_debug_text() {
    let tmp = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let out = |name: &str| tmp.path().join(name).to_string_lossy().into_owned();
    let fig11 = root().join("scenarios/paper_fig11.toml");
    let fig11 = fig11.to_string_lossy();
    let cases: Vec<Vec<String>> = vec![
        vec!["design", "least-preload", "--load-nm", "1e300"],
        vec!["design", "least-preload", &fig11, "--load-nm", "1e300"],
        vec!["design", "least-preload", "--load-nm", "1e-300"],
        vec![
            "design",
            "largest-load",
            "--min",
            "1e-300",
            "--max",
            "1e-299",
        ],
        vec![
            "design",
            "least-preload",
            "--set",
            "drive.friction_coefficient=1e-300",
        ],
        vec!["margins", "--set", "drive.friction_coefficient=1e-300"],
        vec!["margins", "--load-nm", "1e300"],
    ]
    .into_iter()
    .map(|v| v.into_iter().map(String::from).collect())
    .collect();
    let mut runs = cases;
    for (i, set) in [
        "drive.friction_coefficient=1e-300",
        "drive.preload_n=1e300",
        "load.brake_nm=1e300",
    ]
    .iter()
    .enumerate()
    {
        runs.push(
            [
                "run",
                "paper_bench",
                "--set",
                set,
                "--out",
                &out(&format!("run{i}")),
            ]
            .map(String::from)
            .to_vec(),
        );
    }
    let mut failures = Vec::new();
    for args in &runs {
        let o = Command::new(EXE)
            .args(args)
            .current_dir(tmp.path())
            .output()
            .unwrap_or_else(|e| panic!("{e}"));
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        for line in text.lines() {
            let long = long_numbers(line);
            if !long.is_empty() {
                failures.push(format!("{args:?}: {} long number(s): {line}", long.len()));
            }
            for bad in ["Some(", "None", "NaN", "panicked"] {
                if line.contains(bad) {
                    failures.push(format!("{args:?}: {bad} in: {line}"));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
