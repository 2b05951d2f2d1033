//! Corpus of bench-log inputs in `tests/corpus/logs/`.
//!
//! * `good_*.csv` must parse; the sibling `good_*.expected` (optional) holds `rows N`.
//! * every other `*.csv` must be rejected, and its sibling `<stem>.expected` holds one or
//!   more lines that must all appear in the error message.
//!
//! Each case is read three ways (file path, in-memory reader, streaming visitor) and the
//! outcomes must agree.

use std::fs;
use std::path::{Path, PathBuf};

use cable_servo::io::benchlog::{read_bench_log, read_bench_log_from, visit_bench_log};

fn corpus_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/logs")
}

fn cases() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = fs::read_dir(corpus_dir())
        .expect("corpus directory tests/corpus/logs exists")
        .map(|e| e.expect("readable directory entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv"))
        .collect();
    v.sort();
    v
}

fn expected_lines(case: &Path) -> Option<Vec<String>> {
    let text = fs::read_to_string(case.with_extension("expected")).ok()?;
    Some(
        text.lines()
            .map(str::trim_end)
            .filter(|l| !l.is_empty())
            .map(String::from)
            .collect(),
    )
}

fn is_good(case: &Path) -> bool {
    case.file_name()
        .and_then(|n| n.to_str())
        .is_some_and(|n| n.starts_with("good_"))
}

#[test]
fn bad_cases_are_rejected_with_clear_messages() {
    let mut checked = 0;
    let mut failures = Vec::new();
    for case in cases().into_iter().filter(|c| !is_good(c)) {
        let name = case.display().to_string();
        let Some(expected) = expected_lines(&case) else {
            failures.push(format!("{name}: missing sibling .expected file"));
            continue;
        };
        assert!(!expected.is_empty(), "{name}: .expected is empty");
        let message = match read_bench_log(&case) {
            Ok(log) => {
                failures.push(format!(
                    "{name}: parsed ({} samples) but must fail",
                    log.len()
                ));
                continue;
            }
            Err(e) => e.to_string(),
        };
        if !message.contains(&name) {
            failures.push(format!("{name}: message does not name the file: {message}"));
        }
        for want in &expected {
            if !message.contains(want.as_str()) {
                failures.push(format!(
                    "{name}: message lacks {want:?}\n    message: {message}"
                ));
            }
        }
        if message.contains('\n') {
            failures.push(format!("{name}: message spans several lines: {message}"));
        }
        // Same outcome from an in-memory reader and from the streaming visitor.
        let bytes = fs::read(&case).unwrap();
        let from = read_bench_log_from(&bytes[..], &name)
            .map(|_| ())
            .unwrap_err();
        assert_eq!(from.to_string(), message, "{name}: reader vs file");
        let mut rows = 0;
        let visit = visit_bench_log(&bytes[..], &name, |_| rows += 1).unwrap_err();
        assert_eq!(visit.to_string(), message, "{name}: visitor vs file");
        checked += 1;
    }
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
    assert!(checked >= 14, "only {checked} bad cases found");
}

#[test]
fn good_cases_parse() {
    let mut checked = 0;
    for case in cases().into_iter().filter(|c| is_good(c)) {
        let name = case.display().to_string();
        let log = read_bench_log(&case).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(!log.is_empty(), "{name}");
        let n = log.len();
        for col in [&log.theta_in_rad, &log.theta_out_rad, &log.load_nm] {
            assert_eq!(col.len(), n, "{name}");
        }
        for col in [
            &log.tension_upper_n,
            &log.tension_lower_n,
            &log.motor_current_a,
        ]
        .into_iter()
        .flatten()
        {
            assert_eq!(col.len(), n, "{name}");
        }
        assert!(log.t_s.windows(2).all(|w| w[1] > w[0]), "{name}");
        assert_eq!(log.source, name);
        if let Some(lines) = expected_lines(&case) {
            for line in lines {
                if let Some(rows) = line.strip_prefix("rows ") {
                    assert_eq!(n, rows.trim().parse::<usize>().unwrap(), "{name}: rows");
                }
            }
        }
        let mut rows = 0;
        let info = visit_bench_log(fs::File::open(&case).unwrap(), &name, |_| rows += 1)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(rows, n, "{name}");
        assert_eq!(info.rows as usize, n, "{name}");
        checked += 1;
    }
    assert!(checked >= 3, "only {checked} good cases found");
}

#[test]
fn good_case_details() {
    let dir = corpus_dir();
    let log = read_bench_log(&dir.join("good_bom_crlf_comments.csv")).unwrap();
    assert_eq!(log.comments, vec!["rig: bench 2", "operator: test"]);
    assert_eq!(log.load_nm, vec![0.3, 0.31, 0.32]);

    let log = read_bench_log(&dir.join("good_reordered_extra.csv")).unwrap();
    assert_eq!(log.extra_columns, vec!["rig_temp_c", "note"]);
    assert_eq!(log.t_s, vec![0.0, 0.5, 0.75]);
    assert_eq!(log.theta_in_rad, vec![0.1, 0.11, 0.12]);
    assert_eq!(log.load_nm, vec![-0.7, -0.7, -0.6]);
    assert!(log.tension_upper_n.is_none() && log.motor_current_a.is_none());

    let log = read_bench_log(&dir.join("good_optional_tensions.csv")).unwrap();
    assert_eq!(log.tension_upper_n, Some(vec![40.0, 45.2, 45.3]));
    assert_eq!(log.tension_lower_n, Some(vec![40.0, 34.8, 34.7]));
    assert_eq!(log.motor_current_a, Some(vec![0.0, 0.12, 0.125]));
    assert!(log.extra_columns.is_empty());

    let log = read_bench_log(&dir.join("good_whitespace_quotes_cr.csv")).unwrap();
    assert_eq!(log.t_s, vec![0.0, 0.5]);
    assert_eq!(log.theta_in_rad, vec![0.1, 0.1]);
    assert_eq!(log.theta_out_rad, vec![0.2, 2.0]);
    assert_eq!(log.load_nm[1], 1e-3);
    assert!(log.load_nm[0] == 0.0 && log.load_nm[0].is_sign_negative());

    let log = read_bench_log(&dir.join("good_davinci_excerpt.csv")).unwrap();
    assert_eq!(log.extra_columns, vec!["input_torque_nm"]);
    assert_eq!(log.comments.len(), 4);
    assert!(log.comments[0].starts_with("da Vinci"));
    assert!(log.motor_current_a.is_some() && log.tension_upper_n.is_none());
}

#[test]
fn bad_case_line_numbers_match_expected() {
    // `LogError::line()` agrees with the `line N` in the expected text.
    for case in cases().into_iter().filter(|c| !is_good(c)) {
        let Some(expected) = expected_lines(&case) else {
            continue;
        };
        let err = read_bench_log(&case).unwrap_err();
        let first = &expected[0];
        if let Some(rest) = first.strip_prefix("line ") {
            let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
            let want: u64 = digits.parse().unwrap();
            assert_eq!(err.line(), Some(want), "{}: {err}", case.display());
        }
    }
}

#[test]
fn unreadable_paths_are_io_errors_naming_the_path() {
    let missing = corpus_dir().join("does_not_exist.csv");
    let e = read_bench_log(&missing).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("does_not_exist.csv") && msg.contains("cannot read"),
        "{msg}"
    );
    assert_eq!(e.line(), None);
    // A directory is not a log either.
    let e = read_bench_log(&corpus_dir()).unwrap_err();
    assert!(e.to_string().contains("cannot read"), "{e}");
}
