//! Reader and writer round trips and the messages of malformed logs.

use std::io::{self, Read};
use std::path::Path;

use super::*;

fn parse(text: &[u8]) -> Result<BenchLog, LogError> {
    read_bench_log_from(text, "mem.csv")
}

fn err(text: &[u8]) -> String {
    match parse(text) {
        Ok(log) => panic!("expected an error, got {} samples", log.len()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn parses_minimal_log() {
    let log =
        parse(b"t_s,theta_in_rad,theta_out_rad,load_nm\n0,1,2,3\n0.5,1.5,2.5,-3.5\n").unwrap();
    assert_eq!(log.len(), 2);
    assert_eq!(log.t_s, vec![0.0, 0.5]);
    assert_eq!(log.load_nm, vec![3.0, -3.5]);
    assert!(log.tension_upper_n.is_none());
    assert!(log.extra_columns.is_empty());
    assert_eq!(log.source, "mem.csv");
}

#[test]
fn bom_crlf_comments_blank_lines_and_line_numbers() {
    let good: &[u8] = b"\xEF\xBB\xBF# rig: A\r\n#second\r\n\r\n\
        load_nm , t_s,x,theta_out_rad,theta_in_rad\r\n\
        1,0,a,2,3\r\n\r\n  \r\n\
        1,1,b,2,3\r\n";
    let ok = parse(good).unwrap();
    assert_eq!(
        ok.comments,
        vec!["rig: A".to_string(), "second".to_string()]
    );
    assert_eq!(ok.extra_columns, vec!["x".to_string()]);
    assert_eq!(ok.theta_in_rad, vec![3.0, 3.0]);
    assert_eq!(ok.t_s, vec![0.0, 1.0]);
    let bad = [good, b"1,1,c,2,3\r\n\r\n"].concat();
    let e = parse(&bad).unwrap_err();
    assert_eq!(e.line(), Some(9), "{e}");
    assert!(e.to_string().contains("line 9"), "{e}");
    assert!(e.to_string().contains("(line 8)"), "{e}");
}

#[test]
fn cr_only_line_endings() {
    let log = parse(b"#c\rt_s,theta_in_rad,theta_out_rad,load_nm\r0,1,2,3\r1,1,2,3\r").unwrap();
    assert_eq!(log.len(), 2);
    let e = err(b"#c\rt_s,theta_in_rad,theta_out_rad,load_nm\r0,1,2,3\r\r1,1,2,\r");
    assert!(e.contains("line 5") && e.contains("load_nm"), "{e}");
}

#[test]
fn error_messages() {
    let h = "t_s,theta_in_rad,theta_out_rad,load_nm\n";
    let e = err(format!("{h}0,1,2,3\n1,1,,3\n").as_bytes());
    assert!(
        e.contains("mem.csv: line 3, column \"theta_out_rad\": empty field"),
        "{e}"
    );
    let e = err(format!("{h}0,1,2,3\n1,1,abc,3\n").as_bytes());
    assert!(e.contains("non-numeric value \"abc\""), "{e}");
    let e = err(format!("{h}0,nan,2,3\n").as_bytes());
    assert!(e.contains("NaN value") && e.contains("line 2"), "{e}");
    let e = err(format!("{h}0,1,-inf,3\n").as_bytes());
    assert!(e.contains("infinite value \"-inf\""), "{e}");
    let e = err(format!("{h}0,1,1e999,3\n").as_bytes());
    assert!(e.contains("out of range"), "{e}");
    let e = err(b"\0\x01\x02garbage\n1,2\n");
    assert!(
        e.contains("not a text CSV") && !e.contains("\\u{") && !e.contains("\\0"),
        "{e}"
    );

    let e = err(format!("{h}0,1,2,3\n0,1,2,3\n").as_bytes());
    assert!(
        e.contains("line 3") && e.contains("equals") && e.contains("(line 2)"),
        "{e}"
    );
    let e = err(format!("{h}1,1,2,3\n0.5,1,2,3\n").as_bytes());
    assert!(e.contains("is earlier than"), "{e}");
    let e = err(format!("{h}0,1,2\n").as_bytes());
    assert!(
        e.contains("expected 4 fields") && e.contains("found 3"),
        "{e}"
    );
    let e = err(b"");
    assert!(
        e.contains("empty bench log") && e.contains("no content"),
        "{e}"
    );
    let e = err(b"# only\n\n");
    assert!(e.contains("only 2 comment or blank"), "{e}");
    let e = err(h.as_bytes());
    assert!(e.contains("line 1") && e.contains("no data rows"), "{e}");
    let e = err(b"t_s,theta_in_rad,load_nm,extra\n0,1,2,3\n");
    assert!(
        e.contains("theta_out_rad") && e.contains("\"extra\""),
        "{e}"
    );
    let e = err(b"t_s,theta_in_rad,theta_out_rad,load_nm,t_s\n0,1,2,3,4\n");
    assert!(
        e.contains("column \"t_s\" appears twice (fields 1 and 5)"),
        "{e}"
    );
    let e = err(b"t_s,theta_in_rad,theta_out_rad,load_nm,\n0,1,2,3,\n");
    assert!(e.contains("field 5 has an empty column name"), "{e}");
    let e = err(format!("{h}0,1,2,3\n# late comment\n").as_bytes());
    assert!(e.contains("line 3") && e.contains("comment"), "{e}");
    let e = err(&[h.as_bytes(), b"0,1,2,\xff\n"].concat());
    assert!(
        e.contains("line 2, column \"load_nm\": invalid UTF-8"),
        "{e}"
    );
    let e = err(b"# \xfe\xff\nt_s\n");
    assert!(e.contains("line 1: invalid UTF-8"), "{e}");
    let long = "x".repeat(500);
    let e = err(format!("{h}0,1,2,{long}\n").as_bytes());
    assert!(e.contains(&format!("\"{}...\"", "x".repeat(40))), "{e}");
    assert!(e.len() < 300, "{e}");
}

#[test]
fn io_errors_name_the_path() {
    let e = read_bench_log(Path::new("/nonexistent/dir/log.csv")).unwrap_err();
    assert!(matches!(e, LogError::Io { .. }));
    assert!(e.to_string().contains("/nonexistent/dir/log.csv"), "{e}");

    struct Failing(usize);
    impl Read for Failing {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let data = b"t_s,theta_in_rad,theta_out_rad,load_nm\n0,1,2,3\n";
            if self.0 >= data.len() {
                return Err(io::Error::other("disk on fire"));
            }
            let n = buf.len().min(data.len() - self.0).min(7);
            buf[..n].copy_from_slice(&data[self.0..self.0 + n]);
            self.0 += n;
            Ok(n)
        }
    }
    let e = read_bench_log_from(Failing(0), "stream").unwrap_err();
    assert!(matches!(e, LogError::Io { .. }), "{e:?}");
    assert!(e.to_string().contains("stream") && e.to_string().contains("disk on fire"));
}

#[test]
fn byte_at_a_time_reader_gives_same_result() {
    struct Trickle<'a>(&'a [u8]);
    impl Read for Trickle<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            match (self.0.split_first(), buf.first_mut()) {
                (Some((b, rest)), Some(dst)) => {
                    *dst = *b;
                    self.0 = rest;
                    Ok(1)
                }
                _ => Ok(0),
            }
        }
    }
    let text = b"\xEF\xBB\xBF#a\r\n\r\nt_s,theta_in_rad,theta_out_rad,load_nm,motor_current_a\r\n0,1,2,3,4\r\n\r\n1,1,2,3,x\r\n";
    let a = read_bench_log_from(Trickle(text), "t")
        .unwrap_err()
        .to_string();
    let b = parse(text).unwrap_err().to_string().replace("mem.csv", "t");
    assert_eq!(a, b);
    assert!(a.contains("line 6"), "{a}");
}

#[test]
fn visitor_streams_samples() {
    let text = b"#hello\nt_s,theta_in_rad,theta_out_rad,load_nm,tension_upper_n,junk\n0,1,2,3,4,z\n1,1,2,3,5,z\n";
    let mut sum = 0.0;
    let info = visit_bench_log(&text[..], "v", |s| sum += s.tension_upper_n.unwrap()).unwrap();
    assert_eq!(sum, 9.0);
    assert_eq!(info.rows, 2);
    assert_eq!(info.header_line, 2);
    assert_eq!(info.comments, vec!["hello".to_string()]);
    assert_eq!(info.extra_columns, vec!["junk".to_string()]);
    assert!(info.has_tension_upper_n && !info.has_tension_lower_n);
    assert_eq!(info.columns.len(), 6);
}

fn sample_log() -> BenchLog {
    let mut log = BenchLog {
        comments: vec!["first".into(), "".into(), " indented".into()],
        ..BenchLog::default()
    };
    let values = [
        0.1,
        -0.0,
        1e-300,
        5e-324,
        f64::MAX,
        f64::MIN_POSITIVE,
        std::f64::consts::PI,
        -1.0 / 3.0,
        123_456_789.123_456_79,
        f64::EPSILON,
    ];
    let mut t = -5.0;
    for (i, &v) in values.iter().enumerate() {
        t += 0.1 * (i as f64 + 1.0) / 7.0;
        log.push(&Sample {
            t_s: t,
            theta_in_rad: v,
            theta_out_rad: -v,
            load_nm: v * 0.5,
            tension_upper_n: Some(v / 3.0),
            tension_lower_n: None,
            motor_current_a: Some(i as f64),
        });
    }
    log
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn write_read_round_trip_is_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("log.csv");
    let log = sample_log();
    write_bench_log(&path, &log).unwrap();
    let back = read_bench_log(&path).unwrap();
    assert_eq!(bits(&back.t_s), bits(&log.t_s));
    assert_eq!(bits(&back.theta_in_rad), bits(&log.theta_in_rad));
    assert_eq!(bits(&back.theta_out_rad), bits(&log.theta_out_rad));
    assert_eq!(bits(&back.load_nm), bits(&log.load_nm));
    assert_eq!(
        bits(back.tension_upper_n.as_ref().unwrap()),
        bits(log.tension_upper_n.as_ref().unwrap())
    );
    assert!(back.tension_lower_n.is_none());
    assert_eq!(
        bits(back.motor_current_a.as_ref().unwrap()),
        bits(log.motor_current_a.as_ref().unwrap())
    );
    assert_eq!(back.comments, log.comments);
    // Only the final file is left behind.
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert_eq!(names.len(), 1);
    // Overwrite works and is atomic (same path, new content).
    let short = log.slice(2..4);
    write_bench_log(&path, &short).unwrap();
    assert_eq!(read_bench_log(&path).unwrap().len(), 2);
}

#[test]
fn multi_line_comments_are_split_and_writer_to_memory_works() {
    let mut log = sample_log().slice(0..2);
    log.comments = vec!["a\nb".into(), "c\r\nd".into()];
    let mut out = Vec::new();
    write_bench_log_to(&mut out, "mem", &log).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(text.starts_with("# a\n# b\n# c\n# d\nt_s,"), "{text}");
    let back = parse(text.as_bytes()).unwrap();
    assert_eq!(back.comments, vec!["a", "b", "c", "d"]);
    let e = write_bench_log_to(Vec::new(), "mem", &BenchLog::default()).unwrap_err();
    assert!(e.to_string().starts_with("mem: refusing to write"), "{e}");
}

#[test]
fn write_refuses_unreadable_logs() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.csv");
    let mut log = sample_log();
    assert!(matches!(
        write_bench_log(&path, &BenchLog::default()),
        Err(LogError::Invalid { .. })
    ));
    log.load_nm[3] = f64::NAN;
    let e = write_bench_log(&path, &log).unwrap_err().to_string();
    assert!(e.contains("load_nm") && e.contains("not finite"), "{e}");
    let mut log = sample_log();
    log.t_s[5] = log.t_s[4];
    let e = write_bench_log(&path, &log).unwrap_err().to_string();
    assert!(e.contains("strictly increasing"), "{e}");
    let mut log = sample_log();
    log.theta_out_rad.pop();
    let e = write_bench_log(&path, &log).unwrap_err().to_string();
    assert!(e.contains("same length"), "{e}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    let e = write_bench_log(Path::new("/nonexistent/dir/x.csv"), &sample_log()).unwrap_err();
    assert!(matches!(e, LogError::Write { .. }), "{e:?}");
}

#[test]
fn slice_and_push_semantics() {
    let log = sample_log();
    assert_eq!(log.slice(3..100).len(), log.len() - 3);
    assert_eq!(log.slice(50..60).len(), 0);
    #[allow(clippy::reversed_empty_ranges)]
    let reversed = log.slice(5..2);
    assert!(reversed.is_empty());
    assert_eq!(log.slice(1..3).sample(0), log.sample(1));
    assert!(log.slice(1..3).tension_upper_n.is_some());
    assert_eq!(log.sample(log.len()), None);

    let mut log = BenchLog::default();
    let s = Sample {
        t_s: 0.0,
        theta_in_rad: 0.0,
        theta_out_rad: 0.0,
        load_nm: 0.0,
        tension_upper_n: None,
        tension_lower_n: None,
        motor_current_a: None,
    };
    log.push(&s);
    log.push(&Sample {
        t_s: 1.0,
        motor_current_a: Some(2.0),
        ..s
    });
    let current = log.motor_current_a.as_ref().unwrap();
    assert_eq!(current.len(), 2);
    assert!(current[0].is_nan());
    assert_eq!(current[1], 2.0);
}

/// The real da Vinci logs beside the repository (`../shared/real-data/davinci`, as CI lays
/// them out), with each log's mean jaw load from that folder's README table (N m, three
/// decimals).
const DAVINCI_LOGS: [(&str, f64); 11] = [
    ("tool4_00.csv", 0.013),
    ("tool4_02.csv", 0.037),
    ("tool4_04.csv", 0.060),
    ("tool4_05.csv", 0.073),
    ("tool4_06.csv", 0.084),
    ("tool4_08.csv", 0.107),
    ("tool4_09.csv", 0.119),
    ("tool4_15.csv", 0.072),
    ("tool4_25.csv", 0.072),
    ("tool4_35.csv", 0.072),
    ("tool4_45.csv", 0.072),
];

#[test]
fn reads_the_real_davinci_logs() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/real-data/davinci");
    let entries = std::fs::read_dir(&dir).unwrap_or_else(|e| {
        panic!(
            "the real da Vinci logs are missing: cannot read {} ({e}); they sit in shared/real-data/davinci beside the repository",
            dir.display()
        )
    });
    let mut found: Vec<String> = entries
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".csv"))
        .collect();
    found.sort();
    let expected: Vec<String> = DAVINCI_LOGS.iter().map(|(n, _)| n.to_string()).collect();
    assert_eq!(found, expected, "logs in {}", dir.display());
    for (name, mean_load_nm) in DAVINCI_LOGS {
        let path = dir.join(name);
        let log = read_bench_log(&path).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            log.extra_columns,
            vec!["input_torque_nm".to_string()],
            "{name}"
        );
        assert_eq!(log.comments.len(), 4, "{name}");
        assert!(
            log.comments[0].contains("da Vinci"),
            "{name}: {:?}",
            log.comments
        );
        let current = log.motor_current_a.as_ref().expect("motor current column");
        assert!(current.iter().all(|i| i.is_finite()), "{name}");
        // 20 s at 1 kHz from t = 0 (one log ends 24 samples early): every step is 1 ms (to
        // the 3 decimals written), and the rows are the span's samples.
        let n = log.len();
        let span_s = log.t_s[n - 1] - log.t_s[0];
        assert_eq!(log.t_s[0], 0.0, "{name}");
        assert!((19.97..=20.0).contains(&span_s), "{name}: {span_s} s");
        assert!(
            log.t_s
                .windows(2)
                .all(|w| (w[1] - w[0] - 1e-3).abs() < 1e-9),
            "{name}: not sampled every 1 ms"
        );
        assert_eq!(n, (span_s * 1e3).round() as usize + 1, "{name}");
        // The README table's mean jaw load, rounded to 1e-3 N m: within half a unit of it.
        let mean = log.load_nm.iter().sum::<f64>() / n as f64;
        assert!(
            (mean - mean_load_nm).abs() <= 0.5e-3 + 1e-9,
            "{name}: mean load {mean} N m, README {mean_load_nm}"
        );
    }
}

#[test]
fn a_drive_log_refuses_loads_and_angles_beyond_any_drive() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.csv");
    std::fs::write(
        &path,
        "t_s,theta_in_rad,theta_out_rad,load_nm\n0,1,2,0.1\n0.01,1,2,1e308\n",
    )
    .unwrap();
    let e = super::read_drive_log(&path).unwrap_err().to_string();
    // The temporary directory's random name may itself hold "inf": read the message
    // without it.
    let e = e.replace(&dir.path().display().to_string(), "");
    assert!(
        e.contains("huge.csv")
            && e.contains("line 3")
            && e.contains("load_nm")
            && e.contains("out of range")
            && !e.contains("inf"),
        "{e}"
    );
    // The plain reader keeps its contract: any finite number round-trips.
    assert!(read_bench_log(&path).is_ok());
}

#[test]
fn a_log_refuses_a_time_beyond_any_bench_run() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("late.csv");
    std::fs::write(
        &path,
        "t_s,theta_in_rad,theta_out_rad,load_nm\n0,0,-0,-0.7\n1e300,-0,-0.0002,-0.70\n",
    )
    .unwrap();
    for e in [
        super::read_drive_log(&path).unwrap_err().to_string(),
        read_bench_log(&path).unwrap_err().to_string(),
    ] {
        assert!(
            e.contains("late.csv")
                && e.contains("line 3")
                && e.contains("t_s")
                && e.contains("1e300")
                && e.contains("up to 1e9 s"),
            "{e}"
        );
    }
    // A long run's times are accepted.
    std::fs::write(
        &path,
        "t_s,theta_in_rad,theta_out_rad,load_nm\n0,0,0,0\n86400,0.1,0.1,0\n",
    )
    .unwrap();
    assert!(read_bench_log(&path).is_ok());
}
