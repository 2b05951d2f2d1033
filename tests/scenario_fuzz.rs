//! Generated inputs for the scenario parser and the `--set` overrides (>= 100 000 each).
//!
//! Every input must give `Ok` or `Err` without panicking, and:
//! * an `Ok` scenario is physically usable: finite positive drive parameters, friction in
//!   (0, 1], a free span, finite loads, a usable study section; it validates again, and it
//!   survives a round trip through TOML unchanged;
//! * an `Ok` with overrides carries the overridden numbers;
//! * an `Err` is a one-line message naming the file (or `--set`), with a line number inside
//!   the file.
//!
//! Inputs come from a seeded generator (set `CABLE_SERVO_FUZZ_SEED` to explore other
//! seeds); a failing input is printed in full. The work of a case is bounded by its size,
//! not timed: inputs are a few hundred bytes or a shipped scenario with a few edits, and an
//! accepted quasi-static study holds at most 2e6 samples (checked, never simulated here).
//!
//! Each test counts the cases it ran through the parser and checks that count; the last
//! test of a parser to finish checks that parser's total (whatever order the tests run in).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};

use cable_servo::physics::Routing;
use cable_servo::scenario::{parse_assignment, Scenario, ScenarioError, Study};
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};

const NAME: &str = "fuzz.toml";

// Case counts: scenario parser (sum >= 100_000).
const CASES_RANDOM_BYTES: usize = 25_000;
const CASES_TOKEN_SOUP: usize = 25_000;
const CASES_MUTATED_FILES: usize = 55_000;
// Case counts: `--set` (sum >= 100_000).
const CASES_SET_MUTATED_KEYS: usize = 55_000;
const CASES_SET_GARBAGE: usize = 25_000;
const CASES_SET_NUMBERS: usize = 25_000;
/// `parse_assignment` alone (cheap).
const CASES_ASSIGNMENT_ONLY: usize = 100_000;

/// Cases run through one parser by the tests that feed it, and how many of those tests
/// have finished.
struct Tally {
    parser: &'static str,
    tests: usize,
    cases: AtomicUsize,
    finished: AtomicUsize,
}

impl Tally {
    const fn new(parser: &'static str, tests: usize) -> Self {
        Tally {
            parser,
            tests,
            cases: AtomicUsize::new(0),
            finished: AtomicUsize::new(0),
        }
    }

    /// A test that fed this parser finished having run `ran` cases, planned `planned`: it
    /// must have run them all; the last of the parser's tests checks the parser's total.
    fn finish(&self, test: &str, ran: usize, planned: usize) {
        assert!(
            ran >= planned,
            "{test}: {ran} cases ran of {planned} planned"
        );
        self.cases.fetch_add(ran, Ordering::SeqCst);
        if self.finished.fetch_add(1, Ordering::SeqCst) + 1 == self.tests {
            let total = self.cases.load(Ordering::SeqCst);
            assert!(
                total >= 100_000,
                "{}: {total} cases ran in all, fewer than 100 000",
                self.parser
            );
            eprintln!("{}: {total} cases ran in all", self.parser);
        }
    }
}

/// The scenario parser, fed by `fuzz_random_bytes`, `fuzz_token_soup` and
/// `fuzz_mutated_scenario_files`.
static SCENARIO_PARSER: Tally = Tally::new("scenario parser", 3);
/// Scenarios with `--set`, fed by the three `fuzz_set_*` tests.
static SET_PARSER: Tally = Tally::new("scenario with --set", 3);
/// `parse_assignment` alone.
static ASSIGNMENT_PARSER: Tally = Tally::new("parse_assignment", 1);

const BASES: &[&str] = &[
    include_str!("../scenarios/paper_bench.toml"),
    include_str!("../scenarios/paper_fig11.toml"),
    include_str!("../scenarios/paper_tension.toml"),
    include_str!("../scenarios/memory_vs_memoryless.toml"),
    include_str!("../scenarios/eots_tracking.toml"),
];

/// Every key a scenario may hold (and the sections), dotted.
const KEYS: &[&str] = &[
    "name",
    "description",
    "study",
    "drive",
    "drive.routing",
    "drive.pulley_radius_m",
    "drive.drum_radius_m",
    "drive.center_distance_m",
    "drive.cable_modulus_n",
    "drive.friction_coefficient",
    "drive.preload_n",
    "drive.drum_wrap_rad",
    "drive.pulley_wrap_rad",
    "load",
    "load.brake_nm",
    "load.brake_breakaway_nm",
    "load.unbalance_nm",
    "load.unbalance_phase_rad",
    "load.constant_nm",
    "load.sine_nm",
    "load.sine_frequency_hz",
    "load.disturbance_csv",
    "quasi_static",
    "quasi_static.duration_s",
    "quasi_static.sample_rate_hz",
    "quasi_static.models",
    "quasi_static.profile_times_s",
    "quasi_static.motion",
    "quasi_static.motion.kind",
    "quasi_static.motion.amplitude_rad",
    "quasi_static.motion.frequency_hz",
    "quasi_static.motion.phase_rad",
    "quasi_static.motion.offset_rad",
    "quasi_static.motion.time_s",
    "quasi_static.motion.period_s",
    "quasi_static.motion.steps_per_sweep",
    "quasi_static.motion.rate_rad_s",
    "quasi_static.motion.start_s",
    "quasi_static.motion.stop_s",
    "quasi_static.motion.turn_fraction",
    "quasi_static.motion.parts",
    "quasi_static.motion.path",
    "quasi_static.motion.column",
    "backlash",
    "backlash.load_nm",
    "backlash.model",
    "closed_loop",
    "sweep",
    "sweep.mode",
    "sweep.parameters",
];

/// Values that tend to break things, as TOML text.
const NASTY: &[&str] = &[
    "nan",
    "+nan",
    "-nan",
    "inf",
    "+inf",
    "-inf",
    "-1",
    "-1.0",
    "0",
    "0.0",
    "-0.0",
    "1",
    "1.5",
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "5e-324",
    "1e-320",
    "1e400",
    "9223372036854775807",
    "-9223372036854775808",
    "99999999999999999999999999999999999999",
    "0x7fffffff",
    "0o777",
    "0b101",
    "1_000",
    "1__0",
    "01",
    ".5",
    "5.",
    "1e",
    "true",
    "false",
    "\"\"",
    "\"x\"",
    "\"nan\"",
    "\"1.0\"",
    "'literal'",
    "\"\"\"multi\nline\"\"\"",
    "\"\\u0000\"",
    "\"\\uD800\"",
    "[]",
    "[1, 2]",
    "[1, \"a\"]",
    "[[1], [2]]",
    "[nan, inf]",
    "{}",
    "{ a = 1 }",
    "{ kind = \"sine\" }",
    "{ kind = \"sine\", amplitude_rad = 1, frequency_hz = 1 }",
    "{ kind = \"sum\", parts = [] }",
    "1979-05-27",
    "1979-05-27T07:32:00Z",
    "07:32:00",
    "\"figure_eight\"",
    "\"open\"",
    "\"sine\"",
    "\"step\"",
    "\"step_stare\"",
    "\"ramp\"",
    "\"triangle\"",
    "\"sum\"",
    "\"table\"",
    "\"memory\"",
    "\"memoryless\"",
    "[\"memory\"]",
    "\"quasi_static\"",
    "\"backlash\"",
    "\"closed_loop\"",
    "\"grid\"",
    "\"list\"",
    "\"../up\"",
    "\".hidden\"",
    "\"a/b\"",
    "[{ key = \"drive.preload_n\", values = [1, 2] }]",
    "[{ key = \"drive.preload_n\", values = [] }]",
    "[{ key = \"\", values = [1] }]",
    "[{ key = \"a..b\", values = [1] }]",
    "4294967296",
    "4294967295",
    "-4294967296",
    "1e9",
    "1e7",
    "2e7",
    "1e-9",
];

fn seed() -> u64 {
    std::env::var("CABLE_SERVO_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x5eed_cab1e)
}

// ---------------------------------------------------------------------------------------
// Checks
// ---------------------------------------------------------------------------------------

fn positive(v: f64) -> bool {
    v.is_finite() && v > 0.0
}

/// An accepted scenario must be one the physics can use.
fn check_ok(s: &Scenario, context: &str) {
    let d = &s.drive;
    for (k, v) in [
        ("pulley_radius_m", d.pulley_radius_m),
        ("drum_radius_m", d.drum_radius_m),
        ("center_distance_m", d.center_distance_m),
        ("cable_modulus_n", d.cable_modulus_n),
        ("preload_n", d.preload_n),
        ("drum_wrap_rad", d.drum_wrap_rad),
        ("pulley_wrap_rad", d.pulley_wrap_rad),
    ] {
        assert!(positive(v), "accepted drive.{k} = {v}\n{context}");
    }
    assert!(
        d.preload_n <= 0.05 * d.cable_modulus_n,
        "accepted a preload strain over 5 %\n{context}"
    );
    for r in [d.pulley_radius_m, d.drum_radius_m] {
        assert!((1e-4..=10.0).contains(&r), "accepted radius {r}\n{context}");
    }
    let mu = d.friction_coefficient;
    assert!(mu > 0.0 && mu <= 1.0, "accepted friction {mu}\n{context}");
    let min = match d.routing {
        Routing::FigureEight => d.drum_radius_m + d.pulley_radius_m,
        Routing::Open => (d.drum_radius_m - d.pulley_radius_m).abs(),
    };
    assert!(
        d.center_distance_m > min && d.free_span_m() > 0.0 && d.free_span_m().is_finite(),
        "accepted a drive without free span\n{context}"
    );
    assert!(d.ratio().is_finite() && d.ratio() > 0.0, "ratio\n{context}");
    let l = &s.load;
    for (k, v) in [
        ("brake_nm", l.brake_nm),
        ("unbalance_nm", l.unbalance_nm),
        ("unbalance_phase_rad", l.unbalance_phase_rad),
        ("constant_nm", l.constant_nm),
        ("sine_nm", l.sine_nm),
        ("sine_frequency_hz", l.sine_frequency_hz),
        ("breakaway", l.breakaway_nm()),
        ("peak", l.peak_torque_nm()),
    ] {
        assert!(v.is_finite(), "accepted load.{k} = {v}\n{context}");
    }
    assert!(l.brake_nm >= 0.0 && l.unbalance_nm >= 0.0, "{context}");
    assert!(l.peak_torque_nm() <= 5e6, "accepted load {l:?}\n{context}");
    match s.study {
        Study::QuasiStatic => {
            let qs = s.quasi_static.as_ref().expect("validated quasi_static");
            assert!(positive(qs.duration_s), "duration\n{context}");
            assert!(positive(qs.sample_rate_hz), "rate\n{context}");
            let n = qs.duration_s * qs.sample_rate_hz;
            assert!(n.is_finite() && n <= 2e6, "{n} samples accepted\n{context}");
            assert!(!qs.models.is_empty(), "{context}");
            assert!(qs.motion.validate().is_ok(), "{context}");
            for t in [0.0, 0.37 * qs.duration_s, qs.duration_s] {
                let p = qs.motion.at(t);
                assert!(
                    p.value.is_finite() && p.rate.is_finite() && p.accel.is_finite(),
                    "motion not finite at {t}: {p:?}\n{context}"
                );
                let m = l.quasi_static_torque_nm(t, p.value, 1.0);
                assert!(m.is_finite(), "load not finite at {t}\n{context}");
            }
            assert!(
                qs.profile_times_s
                    .iter()
                    .all(|t| t.is_finite() && *t >= 0.0 && *t <= qs.duration_s),
                "{context}"
            );
        }
        Study::Backlash => {
            let b = s.backlash.as_ref().expect("validated backlash");
            assert!(positive(b.load_nm) && b.load_nm <= 1e6, "{context}");
        }
        Study::ClosedLoop => assert!(s.closed_loop.is_some(), "{context}"),
    }
    if let Some(sweep) = &s.sweep {
        assert!(!sweep.parameters.is_empty(), "{context}");
        assert!(sweep.parameters.iter().all(|p| !p.values.is_empty()));
    }
    let name = s.name();
    assert!(
        !name.is_empty() && !name.starts_with('.') && !name.contains('/'),
        "accepted name {name:?}\n{context}"
    );
    assert!(s.validate("again").is_ok(), "{context}");
    // Round trip through TOML.
    let text = s.to_toml();
    let back = Scenario::from_toml(&text, "round_trip.toml", "x", &[])
        .unwrap_or_else(|e| panic!("round trip rejected: {e}\n{text}\n{context}"));
    assert_eq!(
        &back, s,
        "round trip changed the scenario\n{text}\n{context}"
    );
}

fn check_err(e: &ScenarioError, text: &str, context: &str) {
    let msg = e.to_string();
    assert!(!msg.is_empty(), "{context}");
    assert!(!msg.contains('\n'), "multi-line message: {msg}\n{context}");
    assert!(msg.len() < 2000, "overlong message: {msg}\n{context}");
    match e {
        ScenarioError::Parse { line, column, .. } => {
            assert!(msg.starts_with(NAME), "{msg}\n{context}");
            let lines = text.split('\n').count();
            assert!(
                *line >= 1 && *line <= lines && *column >= 1,
                "line {line} outside 1..={lines}: {msg}\n{context}"
            );
        }
        ScenarioError::Override { .. } => assert!(msg.starts_with("--set "), "{msg}"),
        ScenarioError::Invalid { .. } => assert!(msg.starts_with(NAME), "{msg}\n{context}"),
        ScenarioError::Io { .. }
        | ScenarioError::NotFound { .. }
        | ScenarioError::Directory { .. } => {
            panic!("file error from text: {msg}")
        }
    }
}

/// Parse `text` with `overrides`, checking invariants, and count the case in `ran`; panics
/// (with the input) on failure.
fn check(text: &str, overrides: &[String], ran: &mut usize) -> Result<Scenario, String> {
    let context = format!("--- input ---\n{text}\n--- overrides ---\n{overrides:?}");
    let result = catch_unwind(AssertUnwindSafe(|| {
        Scenario::from_toml(text, NAME, "fuzz", overrides)
    }));
    *ran += 1;
    let result = match result {
        Ok(r) => r,
        Err(_) => panic!("the parser panicked\n{context}"),
    };
    match result {
        Ok(s) => {
            check_ok(&s, &context);
            Ok(s)
        }
        Err(e) => {
            check_err(&e, text, &context);
            Err(e.to_string())
        }
    }
}

// ---------------------------------------------------------------------------------------
// Generators
// ---------------------------------------------------------------------------------------

fn random_number(rng: &mut impl Rng) -> String {
    match rng.gen_range(0..6) {
        0 => format!("{}", rng.gen_range(-10i64..1000)),
        1 => format!("{:?}", rng.gen_range(-1.0f64..2.0)),
        2 => format!(
            "{:e}",
            rng.gen_range(-1e3f64..1e3) * 10f64.powi(rng.gen_range(-30..30))
        ),
        3 => format!("{:?}", f64::from_bits(rng.gen())),
        4 => format!("{}", rng.gen::<i64>()),
        _ => format!(
            "{:?}",
            rng.gen_range(0.0f64..1.0) * 10f64.powi(rng.gen_range(-3..4))
        ),
    }
}

fn value(rng: &mut impl Rng) -> String {
    if rng.gen_bool(0.6) {
        NASTY.choose(rng).unwrap().to_string()
    } else {
        random_number(rng)
    }
}

/// Random edit of a name: drop, double, swap or replace one character.
fn typo(rng: &mut impl Rng, name: &str) -> String {
    let mut c: Vec<char> = name.chars().collect();
    if c.is_empty() {
        return "x".into();
    }
    let i = rng.gen_range(0..c.len());
    match rng.gen_range(0..5) {
        0 => {
            c.remove(i);
        }
        1 => c.insert(i, c[i]),
        2 if c.len() > 1 => {
            let j = (i + 1) % c.len();
            c.swap(i, j)
        }
        3 => c[i] = *b"abcxyz_.-= 0\"".choose(rng).unwrap() as char,
        _ => c.insert(i, rng.gen_range('a'..='z')),
    }
    c.into_iter().collect()
}

fn last_part(key: &str) -> &str {
    key.rsplit('.').next().unwrap_or(key)
}

/// One random edit of a scenario text, line-based.
fn mutate(rng: &mut impl Rng, text: &str) -> String {
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    if lines.is_empty() {
        lines.push(String::new());
    }
    let i = rng.gen_range(0..lines.len());
    match rng.gen_range(0..12) {
        0 => {
            lines.remove(i);
        }
        1 => {
            let l = lines[i].clone();
            lines.insert(i, l);
        }
        2 => {
            let j = rng.gen_range(0..lines.len());
            lines.swap(i, j);
        }
        // Replace a value.
        3..=5 => {
            if let Some((k, _)) = lines[i].split_once('=') {
                lines[i] = format!("{k}= {}", value(rng));
            } else {
                lines[i] = format!("{} = {}", last_part(KEYS.choose(rng).unwrap()), value(rng));
            }
        }
        // Rename a key.
        6 => {
            if let Some((k, v)) = lines[i].split_once('=') {
                lines[i] = format!("{} ={v}", typo(rng, k.trim()));
            }
        }
        // Insert a known or unknown key somewhere.
        7 => {
            let k = KEYS.choose(rng).unwrap();
            let k = if rng.gen_bool(0.5) {
                last_part(k).to_string()
            } else {
                typo(rng, k)
            };
            lines.insert(i, format!("{k} = {}", value(rng)));
        }
        // Section headers.
        8 => {
            let k = KEYS.choose(rng).unwrap();
            let k = if rng.gen_bool(0.7) {
                k.to_string()
            } else {
                typo(rng, k)
            };
            let h = if rng.gen_bool(0.8) {
                format!("[{k}]")
            } else {
                format!("[[{k}]]")
            };
            lines.insert(i, h);
        }
        // Change a number inside a line (keeps the key).
        9 => {
            let l = &lines[i];
            if let Some(p) = l.find(|c: char| c.is_ascii_digit()) {
                let end = l[p..]
                    .find(|c: char| {
                        !(c.is_ascii_alphanumeric() || c == '.' || c == '-' || c == '+')
                    })
                    .map_or(l.len(), |e| p + e);
                lines[i] = format!("{}{}{}", &l[..p], value(rng), &l[end..]);
            }
        }
        // Character-level damage.
        10 => {
            let mut chars: Vec<char> = lines[i].chars().collect();
            let at = rng.gen_range(0..=chars.len());
            let c = *b"=[]{}\",'#.\\\n\t \x00".choose(rng).unwrap() as char;
            if rng.gen_bool(0.5) || chars.is_empty() {
                chars.insert(at, c);
            } else {
                chars.remove(at.min(chars.len() - 1));
            }
            lines[i] = chars.into_iter().collect();
        }
        // Truncate.
        _ => {
            let joined = lines.join("\n");
            let mut cut = rng.gen_range(0..=joined.len());
            while !joined.is_char_boundary(cut) {
                cut -= 1;
            }
            return joined[..cut].to_string();
        }
    }
    let mut out = lines.join("\n");
    if rng.gen_bool(0.9) {
        out.push('\n');
    }
    out
}

const SOUP: &[&str] = &[
    "\n",
    "\n",
    "\n",
    " ",
    " = ",
    "=",
    "[",
    "]",
    "[[",
    "]]",
    "{",
    "}",
    ",",
    ".",
    "\"",
    "'",
    "#",
    "\r\n",
    "\t",
    "\\",
    "study",
    "drive",
    "load",
    "quasi_static",
    "motion",
    "kind",
    "sine",
    "backlash",
    "sweep",
    "parameters",
    "values",
    "key",
    "preload_n",
    "routing",
    "1",
    "0.5",
    "-2",
    "nan",
    "inf",
    "true",
    "\"quasi_static\"",
    "\"backlash\"",
    "\"sine\"",
    "[drive]",
    "[load]",
    "[quasi_static]",
    "[quasi_static.motion]",
    "[backlash]",
    "[[sweep.parameters]]",
    "duration_s = 1\n",
    "load_nm = 0.7\n",
    "study = \"backlash\"\n",
];

fn token_soup(rng: &mut impl Rng) -> String {
    let n = rng.gen_range(0..80);
    (0..n).map(|_| *SOUP.choose(rng).unwrap()).collect()
}

fn random_bytes(rng: &mut impl Rng) -> Vec<u8> {
    let n = rng.gen_range(0..300);
    if rng.gen_bool(0.5) {
        (0..n).map(|_| rng.gen()).collect()
    } else {
        let alphabet = b"abcdefghijklmnopqrstuvwxyz_.=[]{}\"',#\n \t0123456789-+eE";
        (0..n).map(|_| *alphabet.choose(rng).unwrap()).collect()
    }
}

/// A `--set` argument built from a real key, maybe damaged, with a nasty value.
fn set_arg(rng: &mut impl Rng) -> String {
    let key = KEYS.choose(rng).unwrap().to_string();
    let key = match rng.gen_range(0..6) {
        0 => typo(rng, &key),
        1 => format!("{key}.{}", last_part(KEYS.choose(rng).unwrap())),
        2 => format!(" {key} "),
        _ => key,
    };
    let sep = if rng.gen_bool(0.97) { "=" } else { "" };
    format!("{key}{sep}{}", value(rng))
}

fn garbage_arg(rng: &mut impl Rng) -> String {
    let n = rng.gen_range(0..40);
    let alphabet: Vec<char> = "abdeilnoprst_.=[]{}\"' 0123456789-+\u{e9}\u{1F600}\\\n"
        .chars()
        .collect();
    (0..n).map(|_| *alphabet.choose(rng).unwrap()).collect()
}

// ---------------------------------------------------------------------------------------
// Scenario parser
// ---------------------------------------------------------------------------------------

#[test]
fn fuzz_random_bytes() {
    let mut rng = StdRng::seed_from_u64(seed());
    let mut ran = 0;
    for _ in 0..CASES_RANDOM_BYTES {
        let bytes = random_bytes(&mut rng);
        let text = String::from_utf8_lossy(&bytes);
        let _ = check(&text, &[], &mut ran);
    }
    SCENARIO_PARSER.finish("fuzz_random_bytes", ran, CASES_RANDOM_BYTES);
}

#[test]
fn fuzz_token_soup() {
    let mut rng = StdRng::seed_from_u64(seed() ^ 1);
    let mut ran = 0;
    for _ in 0..CASES_TOKEN_SOUP {
        let text = token_soup(&mut rng);
        let _ = check(&text, &[], &mut ran);
    }
    SCENARIO_PARSER.finish("fuzz_token_soup", ran, CASES_TOKEN_SOUP);
}

#[test]
fn fuzz_mutated_scenario_files() {
    let mut rng = StdRng::seed_from_u64(seed() ^ 2);
    let mut accepted = 0;
    let mut ran = 0;
    for _ in 0..CASES_MUTATED_FILES {
        let mut text = BASES.choose(&mut rng).unwrap().to_string();
        for _ in 0..rng.gen_range(1..=4) {
            text = mutate(&mut rng, &text);
        }
        if check(&text, &[], &mut ran).is_ok() {
            accepted += 1;
        }
    }
    // The mutations must leave a fair share of valid files, or the checks on Ok are idle.
    eprintln!("mutated scenario files: {accepted} of {ran} accepted");
    assert!(
        ran > 0 && accepted > ran / 20,
        "only {accepted} of {ran} accepted"
    );
    SCENARIO_PARSER.finish("fuzz_mutated_scenario_files", ran, CASES_MUTATED_FILES);
}

// ---------------------------------------------------------------------------------------
// `--set`
// ---------------------------------------------------------------------------------------

/// Number at a dotted path of a table, if there is one.
fn number_at(table: &toml::Table, path: &[String]) -> Option<f64> {
    let (last, parents) = path.split_last()?;
    let mut cur = table;
    for p in parents {
        cur = cur.get(p)?.as_table()?;
    }
    match cur.get(last)? {
        toml::Value::Float(f) => Some(*f),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// Overrides that were accepted must show in the scenario (the last one for a key wins).
fn check_applied(s: &Scenario, overrides: &[String]) {
    let table = s.to_table();
    for (i, arg) in overrides.iter().enumerate() {
        let (path, value) = parse_assignment(arg).expect("accepted override parses");
        if overrides[i + 1..]
            .iter()
            .filter_map(|a| parse_assignment(a).ok())
            .any(|(p, _)| p.starts_with(&path) || path.starts_with(&p))
        {
            continue;
        }
        let want = match value {
            toml::Value::Float(f) => f,
            toml::Value::Integer(n) => n as f64,
            _ => continue,
        };
        if let Some(got) = number_at(&table, &path) {
            assert!(
                got == want,
                "--set {arg} accepted but the scenario has {got}\n{overrides:?}"
            );
        }
    }
}

/// `cases` scenarios with generated `--set` arguments; returns `(accepted, ran)`.
fn fuzz_sets(seed_xor: u64, cases: usize, gen: fn(&mut StdRng) -> String) -> (usize, usize) {
    let mut rng = StdRng::seed_from_u64(seed() ^ seed_xor);
    let mut accepted = 0;
    let mut ran = 0;
    for _ in 0..cases {
        let base = BASES.choose(&mut rng).unwrap();
        let n = rng.gen_range(1..=3);
        let overrides: Vec<String> = (0..n).map(|_| gen(&mut rng)).collect();
        for arg in &overrides {
            let r = catch_unwind(|| parse_assignment(arg));
            match r {
                Ok(Ok((path, _))) => {
                    assert!(!path.is_empty() && path.iter().all(|p| !p.is_empty()))
                }
                Ok(Err(e)) => assert!(e.to_string().starts_with("--set "), "{e}"),
                Err(_) => panic!("parse_assignment panicked on {arg:?}"),
            }
        }
        if let Ok(s) = check(base, &overrides, &mut ran) {
            check_applied(&s, &overrides);
            accepted += 1;
        }
    }
    (accepted, ran)
}

#[test]
fn fuzz_set_mutated_keys() {
    let (accepted, ran) = fuzz_sets(3, CASES_SET_MUTATED_KEYS, set_arg);
    eprintln!("--set with mutated keys: {accepted} of {ran} accepted");
    assert!(accepted > 100, "only {accepted} accepted");
    SET_PARSER.finish("fuzz_set_mutated_keys", ran, CASES_SET_MUTATED_KEYS);
}

#[test]
fn fuzz_set_garbage() {
    let (_, ran) = fuzz_sets(4, CASES_SET_GARBAGE, garbage_arg);
    SET_PARSER.finish("fuzz_set_garbage", ran, CASES_SET_GARBAGE);
}

#[test]
fn fuzz_set_numbers_on_real_keys() {
    let (accepted, ran) = fuzz_sets(5, CASES_SET_NUMBERS, |rng| {
        let key = KEYS.choose(rng).unwrap();
        format!("{key}={}", random_number(rng))
    });
    eprintln!("--set numbers on real keys: {accepted} of {ran} accepted");
    assert!(accepted > 1000, "only {accepted} accepted");
    SET_PARSER.finish("fuzz_set_numbers_on_real_keys", ran, CASES_SET_NUMBERS);
}

#[test]
fn fuzz_parse_assignment_alone() {
    let mut rng = StdRng::seed_from_u64(seed() ^ 6);
    let mut ran = 0;
    for _ in 0..CASES_ASSIGNMENT_ONLY {
        let arg = if rng.gen_bool(0.5) {
            garbage_arg(&mut rng)
        } else {
            set_arg(&mut rng)
        };
        match catch_unwind(|| parse_assignment(&arg)) {
            Ok(Ok((path, _))) => {
                assert!(
                    !path.is_empty() && path.iter().all(|p| !p.is_empty()),
                    "{arg:?}"
                )
            }
            Ok(Err(e)) => {
                let msg = e.to_string();
                assert!(msg.starts_with("--set ") && msg.len() < 2000, "{msg}");
            }
            Err(_) => panic!("parse_assignment panicked on {arg:?}"),
        }
        ran += 1;
    }
    ASSIGNMENT_PARSER.finish("fuzz_parse_assignment_alone", ran, CASES_ASSIGNMENT_ONLY);
}
