//! Property tests / fuzzing of the bench-log reader (>= 100 000 generated cases in total).
//!
//! Every input must produce `Ok` or `Err` without panicking, and:
//! * an `Ok` log is internally consistent (equal column lengths, finite values, strictly
//!   increasing time) and equals the generating model when the input was valid;
//! * an `Err` is a one-line message naming the stream, with a line number inside the input;
//! * the in-memory reader, the streaming visitor and a reader delivering random-size
//!   chunks all agree.
//!
//! Each property counts the cases it ran and checks that count; the last property to
//! finish checks the total (whatever order the tests run in).

use std::cell::Cell;
use std::io::{self, Read};
use std::sync::atomic::{AtomicUsize, Ordering};

use cable_servo::io::benchlog::{
    read_bench_log, read_bench_log_from, visit_bench_log, write_bench_log, write_bench_log_to,
    BenchLog, LogError, Sample,
};
use proptest::prelude::*;
use proptest::sample::Index;

const NAME: &str = "fuzz.csv";

// Case counts (sum >= 100_000).
const CASES_RANDOM_BYTES: u32 = 25_000;
const CASES_TOKEN_SOUP: u32 = 25_000;
const CASES_MUTATED: u32 = 30_000;
const CASES_VALID_MODEL: u32 = 15_000;
const CASES_ROUND_TRIP_MEMORY: u32 = 5_000;
/// Few: every case fsyncs a file and a directory.
const CASES_ROUND_TRIP_FILE: u32 = 100;

/// Properties below that count towards the total.
const PROPERTIES: usize = 6;
/// Cases run by the properties that finished, and how many finished.
static CASES_RAN: AtomicUsize = AtomicUsize::new(0);
static PROPERTIES_FINISHED: AtomicUsize = AtomicUsize::new(0);

/// A property finished having run `ran` cases, planned `planned`: it must have run them
/// all (more when proptest replays saved failures first); the last property to finish
/// checks the total.
fn finish(property: &str, ran: &Cell<u32>, planned: u32) {
    let ran = ran.get();
    assert!(
        ran >= planned,
        "{property}: {ran} cases ran of {planned} planned"
    );
    CASES_RAN.fetch_add(ran as usize, Ordering::SeqCst);
    if PROPERTIES_FINISHED.fetch_add(1, Ordering::SeqCst) + 1 == PROPERTIES {
        let total = CASES_RAN.load(Ordering::SeqCst);
        assert!(
            total >= 100_000,
            "{total} cases ran in all, fewer than 100 000"
        );
        eprintln!("bench-log reader: {total} cases ran in all");
    }
}

/// One more case ran.
fn count(ran: &Cell<u32>) {
    ran.set(ran.get() + 1);
}

/// Physical lines in `bytes` as the reader counts them (`\n`, `\r\n`, lone `\r`).
fn physical_lines(bytes: &[u8]) -> u64 {
    let mut n = 1;
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'\n' => n += 1,
            b'\r' => {
                n += 1;
                if bytes.get(i + 1) == Some(&b'\n') {
                    i += 1;
                }
            }
            _ => {}
        }
        i += 1;
    }
    n
}

/// Reader that hands out data in chunks of the given sizes (cycled).
struct Chunked<'a> {
    data: &'a [u8],
    sizes: Vec<usize>,
    i: usize,
}

impl Read for Chunked<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let size = self.sizes[self.i % self.sizes.len()].max(1);
        self.i += 1;
        let n = size.min(buf.len()).min(self.data.len());
        buf[..n].copy_from_slice(&self.data[..n]);
        self.data = &self.data[n..];
        Ok(n)
    }
}

fn check_log(log: &BenchLog) {
    let n = log.len();
    assert!(n > 0, "Ok log without samples");
    assert_eq!(log.source, NAME);
    let mut cols: Vec<&Vec<f64>> = vec![
        &log.t_s,
        &log.theta_in_rad,
        &log.theta_out_rad,
        &log.load_nm,
    ];
    cols.extend(
        [
            &log.tension_upper_n,
            &log.tension_lower_n,
            &log.motor_current_a,
        ]
        .into_iter()
        .flatten(),
    );
    for c in cols {
        assert_eq!(c.len(), n);
        assert!(c.iter().all(|v| v.is_finite()), "non-finite value accepted");
    }
    assert!(
        log.t_s.windows(2).all(|w| w[1] > w[0]),
        "time not increasing"
    );
}

fn check_err(e: &LogError, bytes: &[u8]) {
    let msg = e.to_string();
    assert!(
        msg.starts_with(NAME),
        "message does not start with the name: {msg}"
    );
    assert!(!msg.contains('\n'), "multi-line message: {msg}");
    assert!(
        msg.len() < 1500,
        "overlong message ({} bytes): {msg}",
        msg.len()
    );
    if let Some(line) = e.line() {
        let total = physical_lines(bytes);
        assert!(
            line >= 1 && line <= total,
            "line {line} outside 1..={total}: {msg}"
        );
    }
    assert!(
        !matches!(e, LogError::Csv { .. }),
        "raw csv error leaked: {msg}"
    );
}

/// Parse `bytes` three ways; check invariants and agreement; return the result.
fn check(bytes: &[u8], chunks: &[usize]) -> Result<BenchLog, LogError> {
    let result = read_bench_log_from(bytes, NAME);
    match &result {
        Ok(log) => check_log(log),
        Err(e) => check_err(e, bytes),
    }
    let mut seen = Vec::new();
    let visited = visit_bench_log(bytes, NAME, |s| seen.push(*s));
    match (&result, &visited) {
        (Ok(log), Ok(info)) => {
            assert_eq!(info.rows as usize, log.len());
            assert_eq!(seen.len(), log.len());
            for (i, s) in seen.iter().enumerate() {
                assert_eq!(
                    log.sample(i).map(|x| x.t_s.to_bits()),
                    Some(s.t_s.to_bits())
                );
            }
            assert_eq!(info.comments, log.comments);
            assert_eq!(info.extra_columns, log.extra_columns);
        }
        (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string()),
        _ => panic!("reader and visitor disagree: {result:?} vs {visited:?}"),
    }
    if !chunks.is_empty() {
        let chunked = read_bench_log_from(
            Chunked {
                data: bytes,
                sizes: chunks.to_vec(),
                i: 0,
            },
            NAME,
        );
        match (&result, &chunked) {
            (Ok(a), Ok(b)) => {
                assert_eq!(bits(&a.t_s), bits(&b.t_s));
                assert_eq!(bits(&a.load_nm), bits(&b.load_nm));
                assert_eq!(a.comments, b.comments);
            }
            (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string()),
            _ => panic!("chunked reading disagrees: {result:?} vs {chunked:?}"),
        }
    }
    result
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

// ---------------------------------------------------------------------------------------
// Generators
// ---------------------------------------------------------------------------------------

const TOKENS: &[&[u8]] = &[
    b"t_s",
    b"theta_in_rad",
    b"theta_out_rad",
    b"load_nm",
    b"tension_upper_n",
    b"tension_lower_n",
    b"motor_current_a",
    b"extra",
    b"t_s,theta_in_rad,theta_out_rad,load_nm\n",
    b",",
    b",",
    b",",
    b"\n",
    b"\n",
    b"\r\n",
    b"\r",
    b"#",
    b"# comment\n",
    b" ",
    b"\t",
    b"\"",
    b"0",
    b"1",
    b"7",
    b"-",
    b"+",
    b".",
    b"e",
    b"E",
    b"0.5",
    b"-1e-3",
    b"1e999",
    b"nan",
    b"NaN",
    b"inf",
    b"-Infinity",
    b"\xEF\xBB\xBF",
    b"\xff",
    b"\xc3",
    b"\xc3\xa9",
    "∞".as_bytes(),
    "é".as_bytes(),
    b"\0",
];

fn token_soup() -> impl Strategy<Value = Vec<u8>> {
    (
        any::<bool>(),
        prop::collection::vec(prop::sample::select(TOKENS), 0..80),
    )
        .prop_map(|(with_header, tokens)| {
            let mut out = Vec::new();
            if with_header {
                out.extend_from_slice(b"t_s,theta_in_rad,theta_out_rad,load_nm\n0,0,0,0\n");
            }
            for t in tokens {
                out.extend_from_slice(t);
            }
            out
        })
}

/// Texts that are not plain finite numbers (or are edge cases of them).
const NASTY_VALUES: &[&str] = &[
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "+inf",
    "infinity",
    "-Infinity",
    "1e999",
    "-1e999",
    "1e-999",
    "-",
    "+",
    "",
    " ",
    "\t",
    ".",
    "e5",
    "1e",
    "1e+",
    "0x10",
    "1_000",
    "1,5",
    "½",
    "١٢",
    "∞",
    "𝟙",
    "\u{0}",
    "1 2",
    "--1",
    "+-1",
    "1..2",
    "\"1\"",
    "\"",
    "#1",
    "# 1",
    "0.0.0",
    "1e308",
    "1.8e308",
    "4.9e-324",
    "-0",
    "+0",
    "00001",
    "1.",
    ".5",
    "\u{feff}1",
    "１",
    "−1",
];

fn nasty_value() -> impl Strategy<Value = String> {
    prop_oneof![
        3 => prop::sample::select(NASTY_VALUES).prop_map(String::from),
        1 => "[-+.eEnaifINF0-9 ]{0,8}",
        1 => "\\PC{0,6}",
        1 => Just("9".repeat(400)),
        1 => any::<f64>().prop_map(|v| format!("{v}")),
    ]
}

/// Finite floats of every kind (normal, subnormal, zero, both signs).
fn finite() -> impl Strategy<Value = f64> {
    use prop::num::f64::{NEGATIVE, NORMAL, POSITIVE, SUBNORMAL, ZERO};
    POSITIVE | NEGATIVE | NORMAL | SUBNORMAL | ZERO
}

/// A valid bench log described structurally.
#[derive(Clone, Debug)]
struct Model {
    /// Column names in file order.
    columns: Vec<String>,
    /// Field texts per row, in file order.
    rows: Vec<Vec<String>>,
    /// Expected values per row for the known columns: t, in, out, load, upper, lower, current.
    values: Vec<[Option<f64>; 7]>,
    extras: Vec<String>,
    comments: Vec<String>,
    eol: &'static str,
    bom: bool,
    blank_after: Vec<bool>,
    trailing_blank: usize,
}

const KNOWN: [&str; 7] = [
    "t_s",
    "theta_in_rad",
    "theta_out_rad",
    "load_nm",
    "tension_upper_n",
    "tension_lower_n",
    "motor_current_a",
];

fn render_float(v: f64, style: u8) -> String {
    match style % 4 {
        0 => format!("{v}"),
        1 => format!("{v:?}"),
        2 => format!("{v:e}"),
        _ => format!("{v:E}"),
    }
}

fn model() -> impl Strategy<Value = Model> {
    let layout = (
        prop::collection::vec(any::<bool>(), 3),
        prop::collection::vec("[a-z][a-z0-9_]{0,6}", 0..3),
        any::<u64>(),
    );
    let rows = (
        -1.0e3f64..1.0e3,
        1.0e-3f64..10.0,
        prop::collection::vec(
            (
                prop::collection::vec(finite(), 6),
                prop::collection::vec(any::<u8>(), 7),
                prop::collection::vec("[a-z0-9 .]{0,6}", 3),
                any::<bool>(),
            ),
            1..8,
        ),
    );
    let framing = (
        prop::collection::vec("[^\r\n]{0,20}", 0..3),
        prop::sample::select(vec!["\n", "\r\n", "\r"]),
        any::<bool>(),
        0usize..3,
    );
    (layout, rows, framing).prop_map(
        |(
            (optional, extra_names, shuffle_seed),
            (t0, dt, raw_rows),
            (comments, eol, bom, trailing_blank),
        )| {
            // Columns: required, chosen optional, uniquely named extras; then shuffled.
            let mut cols: Vec<(String, Option<usize>)> =
                (0..4).map(|k| (KNOWN[k].to_string(), Some(k))).collect();
            for (j, present) in optional.iter().enumerate() {
                if *present {
                    cols.push((KNOWN[4 + j].to_string(), Some(4 + j)));
                }
            }
            let mut extras = Vec::new();
            for (j, name) in extra_names.iter().enumerate() {
                let name = format!("x{j}_{name}");
                extras.push(name.clone());
                cols.push((name, None));
            }
            // Deterministic Fisher-Yates from the seed.
            let mut seed = shuffle_seed | 1;
            for i in (1..cols.len()).rev() {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                cols.swap(i, (seed % (i as u64 + 1)) as usize);
            }
            let order_extras: Vec<String> = cols
                .iter()
                .filter(|(_, k)| k.is_none())
                .map(|(n, _)| n.clone())
                .collect();
            let mut rows = Vec::new();
            let mut values = Vec::new();
            let mut blank_after = Vec::new();
            for (r, (vals, styles, extra_vals, blank)) in raw_rows.iter().enumerate() {
                let t = t0 + r as f64 * dt;
                let mut expect = [None; 7];
                let mut fields = Vec::new();
                let mut extra_i = 0;
                for (c, (_, known)) in cols.iter().enumerate() {
                    let style = styles[c % styles.len()];
                    match known {
                        Some(k) => {
                            let v = if *k == 0 { t } else { vals[k - 1] };
                            expect[*k] = Some(v);
                            let mut text = render_float(v, style);
                            if style & 0x10 != 0 {
                                text = format!("\"{text}\"");
                            } else if style & 0x20 != 0 {
                                text = format!(" {text}\t");
                            }
                            fields.push(text);
                        }
                        None => {
                            fields.push(extra_vals[extra_i % extra_vals.len()].clone());
                            extra_i += 1;
                        }
                    }
                }
                rows.push(fields);
                values.push(expect);
                blank_after.push(*blank);
            }
            Model {
                columns: cols.into_iter().map(|(n, _)| n).collect(),
                rows,
                values,
                extras: order_extras,
                comments,
                eol,
                bom,
                blank_after,
                trailing_blank,
            }
        },
    )
}

impl Model {
    fn render(&self) -> Vec<u8> {
        let mut s = String::new();
        if self.bom {
            s.push('\u{feff}');
        }
        for c in &self.comments {
            s.push('#');
            s.push_str(c);
            s.push_str(self.eol);
        }
        s.push_str(&self.columns.join(","));
        s.push_str(self.eol);
        for (row, blank) in self.rows.iter().zip(&self.blank_after) {
            s.push_str(&row.join(","));
            s.push_str(self.eol);
            if *blank {
                s.push_str(self.eol);
            }
        }
        for _ in 0..self.trailing_blank {
            s.push_str(self.eol);
        }
        s.into_bytes()
    }

    fn expected_comments(&self) -> Vec<String> {
        self.comments
            .iter()
            .map(|c| c.strip_prefix(' ').unwrap_or(c).to_string())
            .collect()
    }
}

#[derive(Clone, Debug)]
enum Mutation {
    DeleteByte(Index),
    DuplicateByte(Index),
    InsertToken(Index, &'static [u8]),
    ReplaceField(Index, Index, String),
    SwapFields(Index, Index, Index),
    SwapRows(Index, Index),
    DuplicateRow(Index),
    SwapHeader(Index, Index),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        2 => any::<Index>().prop_map(Mutation::DeleteByte),
        2 => any::<Index>().prop_map(Mutation::DuplicateByte),
        2 => (any::<Index>(), prop::sample::select(TOKENS)).prop_map(|(i, t)| Mutation::InsertToken(i, t)),
        4 => (any::<Index>(), any::<Index>(), nasty_value()).prop_map(|(r, c, v)| Mutation::ReplaceField(r, c, v)),
        2 => (any::<Index>(), any::<Index>(), any::<Index>()).prop_map(|(r, a, b)| Mutation::SwapFields(r, a, b)),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(a, b)| Mutation::SwapRows(a, b)),
        1 => any::<Index>().prop_map(Mutation::DuplicateRow),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(a, b)| Mutation::SwapHeader(a, b)),
    ]
}

fn mutate(model: &Model, mutations: &[Mutation]) -> Vec<u8> {
    let mut m = model.clone();
    // Structured mutations first, then byte-level ones on the rendered text.
    for mu in mutations {
        match mu {
            Mutation::ReplaceField(r, c, v) => {
                let row = r.index(m.rows.len());
                let col = c.index(m.rows[row].len());
                m.rows[row][col] = v.clone();
            }
            Mutation::SwapFields(r, a, b) => {
                let row = r.index(m.rows.len());
                let n = m.rows[row].len();
                m.rows[row].swap(a.index(n), b.index(n));
            }
            Mutation::SwapRows(a, b) => {
                let n = m.rows.len();
                m.rows.swap(a.index(n), b.index(n));
            }
            Mutation::DuplicateRow(a) => {
                let i = a.index(m.rows.len());
                let row = m.rows[i].clone();
                m.rows.insert(i, row);
                m.blank_after.insert(i, false);
            }
            Mutation::SwapHeader(a, b) => {
                let n = m.columns.len();
                m.columns.swap(a.index(n), b.index(n));
            }
            _ => {}
        }
    }
    let mut bytes = m.render();
    for mu in mutations {
        match mu {
            Mutation::DeleteByte(i) if !bytes.is_empty() => {
                bytes.remove(i.index(bytes.len()));
            }
            Mutation::DuplicateByte(i) if !bytes.is_empty() => {
                let k = i.index(bytes.len());
                bytes.insert(k, bytes[k]);
            }
            Mutation::InsertToken(i, t) => {
                let k = i.index(bytes.len() + 1);
                bytes.splice(k..k, t.iter().copied());
            }
            _ => {}
        }
    }
    bytes
}

// ---------------------------------------------------------------------------------------
// Properties
// ---------------------------------------------------------------------------------------

#[test]
fn random_bytes_never_panic() {
    let ran = Cell::new(0);
    proptest!(
        ProptestConfig::with_cases(CASES_RANDOM_BYTES),
        |(
            bytes in prop::collection::vec(any::<u8>(), 0..400),
            chunks in prop::collection::vec(1usize..64, 0..4),
        )| {
            let _ = check(&bytes, &chunks);
            // With a valid header in front the row parser sees the bytes too.
            let mut with_header = b"t_s,theta_in_rad,theta_out_rad,load_nm\n".to_vec();
            with_header.extend_from_slice(&bytes);
            let _ = check(&with_header, &[]);
            count(&ran);
        }
    );
    finish("random_bytes_never_panic", &ran, CASES_RANDOM_BYTES);
}

#[test]
fn token_soup_never_panics() {
    let ran = Cell::new(0);
    proptest!(
        ProptestConfig::with_cases(CASES_TOKEN_SOUP),
        |(
            bytes in token_soup(),
            chunks in prop::collection::vec(1usize..16, 0..4),
        )| {
            let _ = check(&bytes, &chunks);
            count(&ran);
        }
    );
    finish("token_soup_never_panics", &ran, CASES_TOKEN_SOUP);
}

#[test]
fn mutated_valid_logs_never_panic() {
    let ran = Cell::new(0);
    proptest!(
        ProptestConfig::with_cases(CASES_MUTATED),
        |(
            model in model(),
            mutations in prop::collection::vec(mutation(), 1..4),
            chunks in prop::collection::vec(1usize..32, 1..4),
        )| {
            let bytes = mutate(&model, &mutations);
            let _ = check(&bytes, &chunks);
            count(&ran);
        }
    );
    finish("mutated_valid_logs_never_panic", &ran, CASES_MUTATED);
}

#[test]
fn valid_logs_parse_to_the_model() {
    let ran = Cell::new(0);
    proptest!(
        ProptestConfig::with_cases(CASES_VALID_MODEL),
        |(
            model in model(),
            chunks in prop::collection::vec(1usize..32, 0..3),
        )| {
            let bytes = model.render();
            let log = match check(&bytes, &chunks) {
                Ok(log) => log,
                Err(e) => panic!("valid log rejected: {e}\n{}", String::from_utf8_lossy(&bytes)),
            };
            prop_assert_eq!(log.len(), model.rows.len());
            let cols: [Option<&Vec<f64>>; 7] = [
                Some(&log.t_s),
                Some(&log.theta_in_rad),
                Some(&log.theta_out_rad),
                Some(&log.load_nm),
                log.tension_upper_n.as_ref(),
                log.tension_lower_n.as_ref(),
                log.motor_current_a.as_ref(),
            ];
            for (r, expect) in model.values.iter().enumerate() {
                for k in 0..7 {
                    let got = cols[k].map(|c| c[r].to_bits());
                    prop_assert_eq!(got, expect[k].map(f64::to_bits), "row {} column {}", r, KNOWN[k]);
                }
            }
            prop_assert_eq!(&log.extra_columns, &model.extras);
            prop_assert_eq!(log.comments, model.expected_comments());
            count(&ran);
        }
    );
    finish("valid_logs_parse_to_the_model", &ran, CASES_VALID_MODEL);
}

fn arbitrary_log() -> impl Strategy<Value = BenchLog> {
    (
        -1.0e6f64..1.0e6,
        prop::collection::vec(
            (1.0e-6f64..1.0e3, prop::collection::vec(finite(), 6)),
            1..20,
        ),
        prop::collection::vec(any::<bool>(), 3),
        prop::collection::vec("[^\r\n]{0,30}", 0..4),
    )
        .prop_map(|(t0, rows, optional, comments)| {
            let mut log = BenchLog {
                comments,
                ..BenchLog::default()
            };
            let mut t = t0;
            for (dt, v) in rows {
                t += dt;
                log.push(&Sample {
                    t_s: t,
                    theta_in_rad: v[0],
                    theta_out_rad: v[1],
                    load_nm: v[2],
                    tension_upper_n: optional[0].then_some(v[3]),
                    tension_lower_n: optional[1].then_some(v[4]),
                    motor_current_a: optional[2].then_some(v[5]),
                });
            }
            log
        })
}

fn assert_same(back: &BenchLog, log: &BenchLog) {
    assert_eq!(bits(&back.t_s), bits(&log.t_s));
    assert_eq!(bits(&back.theta_in_rad), bits(&log.theta_in_rad));
    assert_eq!(bits(&back.theta_out_rad), bits(&log.theta_out_rad));
    assert_eq!(bits(&back.load_nm), bits(&log.load_nm));
    for (a, b) in [
        (&back.tension_upper_n, &log.tension_upper_n),
        (&back.tension_lower_n, &log.tension_lower_n),
        (&back.motor_current_a, &log.motor_current_a),
    ] {
        assert_eq!(a.as_deref().map(bits), b.as_deref().map(bits));
    }
    assert_eq!(back.comments, log.comments);
}

#[test]
fn write_then_read_is_bit_exact_in_memory() {
    let ran = Cell::new(0);
    proptest!(
        ProptestConfig::with_cases(CASES_ROUND_TRIP_MEMORY),
        |(log in arbitrary_log())| {
            let mut bytes = Vec::new();
            write_bench_log_to(&mut bytes, NAME, &log).unwrap();
            let back = check(&bytes, &[]).unwrap();
            assert_same(&back, &log);
            count(&ran);
        }
    );
    finish(
        "write_then_read_is_bit_exact_in_memory",
        &ran,
        CASES_ROUND_TRIP_MEMORY,
    );
}

#[test]
fn write_then_read_is_bit_exact_via_file() {
    let ran = Cell::new(0);
    proptest!(
        ProptestConfig::with_cases(CASES_ROUND_TRIP_FILE),
        |(log in arbitrary_log())| {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("log.csv");
            write_bench_log(&path, &log).unwrap();
            let back = read_bench_log(&path).unwrap();
            assert_same(&back, &log);
            prop_assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
            count(&ran);
        }
    );
    finish(
        "write_then_read_is_bit_exact_via_file",
        &ran,
        CASES_ROUND_TRIP_FILE,
    );
}
