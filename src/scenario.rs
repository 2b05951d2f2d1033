//! Scenario files: a TOML description that fully determines a run, read into the parameter
//! structs of the computation layer. Edge layer: imports computation and bottom modules.
//!
//! Parsing is strict (unknown keys are errors, with the closest valid key suggested), and
//! `--set KEY=VALUE` overrides go through the same deserialisation and validation as the
//! file.

use serde::{Deserialize, Serialize};

use crate::closed_loop::ClosedLoopParams;
use crate::identify::{EffectsParams, IdentifyParams};
use crate::physics::{DriveParams, LoadParams};
use crate::signal::Signal;
pub use crate::study::quasi_static::{BacklashParams, QuasiStaticParams};
use crate::sweep::SweepSpec;

/// What a scenario computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Study {
    /// Prescribed input motion and load, drive quasi-static (no inertia): tensions,
    /// transmission error, tension profiles; memory and memoryless models side by side.
    QuasiStatic,
    /// Backlash protocol: `+M`, `-M`, `+M` applied to the preloaded drive; initial and
    /// reversal backlash (the unit case of the paper's Fig. 11 sweep).
    Backlash,
    /// Motor, cable drive and output inertia in a discrete PID loop.
    ClosedLoop,
}

/// Most samples a quasi-static run may take (memory and run time grow with it).
pub const MAX_QS_SAMPLES: f64 = 2e6;

/// Fewest samples per period of the fastest motion or load component.
pub const SAMPLES_PER_PERIOD: f64 = 10.0;

/// A complete run description.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Name used for the results folder; defaults to the file stem.
    #[serde(default)]
    pub name: Option<String>,
    /// One-line description for reports.
    #[serde(default)]
    pub description: Option<String>,
    /// What the scenario computes.
    pub study: Study,
    /// The cable drive.
    pub drive: DriveParams,
    /// Loads on the output drum.
    #[serde(default)]
    pub load: LoadParams,
    /// Quasi-static study settings (`study = "quasi_static"`).
    #[serde(default)]
    pub quasi_static: Option<QuasiStaticParams>,
    /// Backlash protocol settings (`study = "backlash"`).
    #[serde(default)]
    pub backlash: Option<BacklashParams>,
    /// Closed-loop settings (`study = "closed_loop"`).
    #[serde(default)]
    pub closed_loop: Option<ClosedLoopParams>,
    /// Optional sweep over scenario keys.
    #[serde(default)]
    pub sweep: Option<SweepSpec>,
    /// How bench logs calibrate the drive and which effects are searched (`diagnose`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub identify: Option<IdentifyParams>,
    /// Identified effects beyond the base model (written by `diagnose --save-model`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub effects: Option<EffectsParams>,
}

/// A scenario that cannot be used, with where and why.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file cannot be read.
    #[error("cannot read scenario {path}: {source}")]
    Io {
        /// File path.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// Syntax or type error in the file.
    #[error("{source_name}:{line}:{column}: {}", printable(message))]
    Parse {
        /// File name.
        source_name: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A `--set` argument that cannot be applied.
    #[error("--set {}: {}", printable(arg), printable(message))]
    Override {
        /// The argument as given.
        arg: String,
        /// What is wrong.
        message: String,
    },
    /// A value outside its physical range or an inconsistent combination.
    #[error("{source_name}: {}: {}", printable(key), printable(message))]
    Invalid {
        /// File name (with `+ --set` when overrides were applied).
        source_name: String,
        /// Dotted key.
        key: String,
        /// What is wrong and what is allowed.
        message: String,
    },
}

/// Text for a one-line message: line breaks and other control characters escaped.
fn printable(text: &str) -> String {
    if text.chars().any(char::is_control) {
        text.chars()
            .map(|c| {
                if c.is_control() {
                    c.escape_default().to_string()
                } else {
                    c.to_string()
                }
            })
            .collect()
    } else {
        text.to_string()
    }
}

impl ScenarioError {
    fn invalid(source_name: &str, key: impl Into<String>, message: impl Into<String>) -> Self {
        ScenarioError::Invalid {
            source_name: source_name.to_string(),
            key: key.into(),
            message: message.into(),
        }
    }
}

/// Scenarios compiled into the binary, by name.
pub const BUILTIN: &[(&str, &str)] = &[
    (
        "eots_tracking",
        include_str!("../scenarios/eots_tracking.toml"),
    ),
    (
        "eots_mismatch",
        include_str!("../scenarios/eots_mismatch.toml"),
    ),
    ("eots_runout", include_str!("../scenarios/eots_runout.toml")),
    ("eots_scan", include_str!("../scenarios/eots_scan.toml")),
    ("step_stare", include_str!("../scenarios/step_stare.toml")),
    (
        "gimbal_ident",
        include_str!("../scenarios/gimbal_ident.toml"),
    ),
    (
        "davinci_tool4",
        include_str!("../scenarios/davinci_tool4.toml"),
    ),
    ("paper_bench", include_str!("../scenarios/paper_bench.toml")),
    ("paper_fig11", include_str!("../scenarios/paper_fig11.toml")),
    (
        "eots_tolerance",
        include_str!("../scenarios/eots_tolerance.toml"),
    ),
    (
        "paper_tension",
        include_str!("../scenarios/paper_tension.toml"),
    ),
    (
        "memory_vs_memoryless",
        include_str!("../scenarios/memory_vs_memoryless.toml"),
    ),
];

/// The scenario `cable-servo run` uses when given none.
pub const DEFAULT_SCENARIO: &str = "eots_tracking";

/// Text of a built-in scenario.
pub fn builtin(name: &str) -> Option<&'static str> {
    BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// Line and column (1-based) of a byte offset.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// Adds "did you mean" to serde's unknown-field and unknown-variant messages.
fn with_suggestion(message: &str) -> String {
    let unknown = ["unknown field `", "unknown variant `"]
        .iter()
        .find_map(|p| message.find(p).map(|i| (i + p.len(), p)));
    let Some((start, _)) = unknown else {
        return message.to_string();
    };
    let rest = &message[start..];
    let Some(end) = rest.find('`') else {
        return message.to_string();
    };
    let bad = &rest[..end];
    let candidates: Vec<&str> = rest[end + 1..].split('`').skip(1).step_by(2).collect();
    // Edit distance for typos; a shared start for shortened spellings (`figure8`).
    let letters: String = bad
        .chars()
        .take_while(|c| c.is_ascii_alphabetic() || *c == '_')
        .collect();
    let best = candidates
        .iter()
        .map(|c| {
            let edits = strsim::normalized_damerau_levenshtein(bad, c);
            let shortened = letters.len() >= 4 && c.starts_with(letters.as_str());
            (if shortened { edits.max(0.6) } else { edits }, *c)
        })
        .filter(|(score, _)| *score > 0.5)
        .max_by(|a, b| a.0.total_cmp(&b.0));
    let first_line = message.lines().next().unwrap_or(message);
    match best {
        Some((_, c)) => format!("{first_line}; did you mean `{c}`?"),
        None => first_line.to_string(),
    }
}

/// Serde's type names in words a scenario author knows, on one line.
fn plain_message(message: &str) -> String {
    let one_line = message
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join("; ");
    let mut out = one_line
        .replace("expected f64", "expected a number")
        .replace("expected u32", "expected a whole number >= 0")
        .replace("expected a string", "expected a quoted string")
        .replace("expected a sequence", "expected a list in brackets [ ]")
        .replace(
            "expected internally tagged enum Signal",
            "expected a signal table with a kind, e.g. { kind = \"sine\", amplitude_rad = 0.1, frequency_hz = 0.1 }",
        );
    // `expected struct DriveParams[ with N elements]` -> the section a user writes.
    if let Some(i) = out.find("expected struct ") {
        let rest = &out[i + "expected struct ".len()..];
        let name_len = rest
            .find(|c: char| !c.is_ascii_alphanumeric())
            .unwrap_or(rest.len());
        let mut tail = &rest[name_len..];
        if let Some(t) = tail.strip_prefix(" with ") {
            tail = t
                .find(" elements")
                .map_or(tail, |j| &t[j + " elements".len()..]);
        }
        let what = match &rest[..name_len] {
            "DriveParams" => "a [drive] section",
            "LoadParams" => "a [load] section",
            "QuasiStaticParams" => "a [quasi_static] section",
            "BacklashParams" => "a [backlash] section",
            "ClosedLoopParams" => "a [closed_loop] section",
            "SweepSpec" => "a [sweep] section",
            "SweepParameter" => "a table { key = \"drive.preload_n\", values = [...] }",
            _ => "a section (a table of key = value)",
        };
        out = format!("{}expected {what}{tail}", &out[..i]);
    }
    const SERDE: &[&str] = &[
        "invalid type",
        "invalid value",
        "invalid length",
        "missing field",
        "unknown field",
        "unknown variant",
        "duplicate field",
    ];
    if !out.is_empty() && !SERDE.iter().any(|p| out.starts_with(p)) {
        out = format!("TOML syntax error: {out}");
        if out.contains("invalid string") {
            out.push_str(" (text values need quotes, e.g. routing = \"open\")");
        }
    }
    out
}

/// The header of a `[section]` or `[[section]]` line, if it is one.
fn header_name(line: &str) -> Option<String> {
    let t = line.trim();
    let t = t.strip_prefix('[')?;
    let t = t.strip_prefix('[').unwrap_or(t);
    let end = t.find(']')?;
    let name: String = t[..end].chars().filter(|c| !c.is_whitespace()).collect();
    (!name.is_empty()).then_some(name)
}

/// The dotted key (or section) at a byte offset of a scenario text, when the line shows it
/// plainly: `[section]` headers above and `key = ...` on the line.
fn key_at(text: &str, offset: usize) -> Option<String> {
    let offset = offset.min(text.len());
    let before = text.get(..offset)?;
    let start = before.rfind('\n').map_or(0, |i| i + 1);
    let end = text[start..].find('\n').map_or(text.len(), |i| start + i);
    let line = &text[start..end];
    if let Some(h) = header_name(line) {
        return Some(h);
    }
    let section = text[..start].lines().rev().find_map(header_name);
    let key = line.split_once('=')?.0.trim();
    let plain = !key.is_empty()
        && key
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '"' | '\'' | ' '));
    if !plain {
        return section;
    }
    let key: String = key
        .chars()
        .filter(|c| !matches!(c, '"' | '\'' | ' '))
        .collect();
    Some(match section {
        Some(s) => format!("{s}.{key}"),
        None => key,
    })
}

/// In the section whose header is on 1-based `header_line`, the single `key = value` line
/// whose value is the one quoted in a serde message (`integer `-2``, `string "x"`); returns
/// its line and dotted key.
fn find_value_line(text: &str, header_line: usize, message: &str) -> Option<(usize, String)> {
    let quoted = if let Some(i) = message.find('`') {
        let rest = &message[i + 1..];
        rest[..rest.find('`')?].to_string()
    } else {
        let i = message.find('"')?;
        let rest = &message[i + 1..];
        format!("\"{}\"", &rest[..rest.find('"')?])
    };
    let mut hits = Vec::new();
    let mut offset = 0;
    for (i, l) in text.split('\n').enumerate() {
        let start = offset;
        offset += l.len() + 1;
        if i < header_line {
            continue;
        }
        if header_name(l).is_some() {
            break;
        }
        let Some((k, v)) = l.split_once('=') else {
            continue;
        };
        let v = v.split('#').next().unwrap_or("").trim();
        if v == quoted {
            let key = key_at(text, start).unwrap_or_else(|| k.trim().to_string());
            hits.push((i + 1, key));
        }
    }
    (hits.len() == 1).then(|| hits.remove(0))
}

fn parse_error(source_name: &str, text: &str, err: &toml::de::Error) -> ScenarioError {
    let (mut line, mut column) = err
        .span()
        .map(|s| line_col(text, s.start))
        .unwrap_or((1, 1));
    let mut message = plain_message(&with_suggestion(err.message()));
    if message.starts_with("invalid type") || message.starts_with("invalid value") {
        let at_header = text.lines().nth(line - 1).and_then(header_name).is_some();
        let found = if at_header {
            // Tagged sections (`[quasi_static.motion]`) report the section, not the value:
            // find the line that holds the offending value.
            find_value_line(text, line, &message)
        } else {
            None
        };
        if let Some((l, key)) = found {
            line = l;
            column = 1;
            message = format!("{key}: {message}");
        } else if let Some(key) = err.span().and_then(|s| key_at(text, s.start)) {
            message = format!("{key}: {message}");
        }
    } else if message.starts_with("missing field") {
        match err.span().and_then(|s| key_at(text, s.start)) {
            Some(section) => message = format!("[{section}]: {message}"),
            None if text
                .lines()
                .all(|l| l.trim().is_empty() || l.trim_start().starts_with('#')) =>
            {
                message = format!("the file holds no settings ({message}); a scenario needs at least study, [drive] and the study's section, see `cable-servo show paper_bench`");
            }
            None => message.push_str(" at the top of the file"),
        }
    }
    ScenarioError::Parse {
        source_name: source_name.to_string(),
        line,
        column,
        message,
    }
}

/// Parse `KEY=VALUE` into a dotted path and a TOML value. The value is read as TOML
/// (`70`, `1.4e4`, `true`, `[1, 2]`, `"open"`); anything else is taken as a bare string.
pub fn parse_assignment(arg: &str) -> Result<(Vec<String>, toml::Value), ScenarioError> {
    let err = |message: &str| ScenarioError::Override {
        arg: arg.to_string(),
        message: message.to_string(),
    };
    let (key, value) = arg
        .split_once('=')
        .ok_or_else(|| err("expected KEY=VALUE, e.g. drive.preload_n=70"))?;
    let key = key.trim();
    if key.is_empty() {
        return Err(err("the key before '=' is empty"));
    }
    let path: Vec<String> = key.split('.').map(|p| p.trim().to_string()).collect();
    if path.iter().any(|p| p.is_empty()) {
        return Err(err(
            "the key has an empty part; write sections with dots, e.g. drive.preload_n",
        ));
    }
    let value = value.trim();
    let parsed = toml::from_str::<toml::Table>(&format!("v = {value}"))
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_string()));
    Ok((path, parsed))
}

/// Set a dotted key in a TOML table, creating intermediate tables.
pub fn set_path(
    table: &mut toml::Table,
    path: &[String],
    value: toml::Value,
) -> Result<(), String> {
    let Some((last, parents)) = path.split_last() else {
        return Err("empty key".into());
    };
    let mut cur = table;
    for (i, part) in parents.iter().enumerate() {
        let entry = cur
            .entry(part.clone())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        cur = match entry {
            toml::Value::Table(t) => t,
            other => {
                return Err(format!(
                    "{} is a {}, not a section",
                    path[..=i].join("."),
                    other.type_str()
                ))
            }
        };
    }
    cur.insert(last.clone(), value);
    Ok(())
}

impl Scenario {
    /// Read a scenario file, or a built-in scenario when `path` names one (`eots_tracking`).
    pub fn load(path: &str, overrides: &[String]) -> Result<Scenario, ScenarioError> {
        let p = std::path::Path::new(path);
        if !p.exists() {
            if let Some(text) = builtin(path) {
                return Scenario::from_toml(text, &format!("{path} (built-in)"), path, overrides);
            }
        }
        let bytes = std::fs::read(p).map_err(|source| ScenarioError::Io {
            path: path.to_string(),
            source,
        })?;
        let text = String::from_utf8(bytes).map_err(|e| {
            let good = e.utf8_error().valid_up_to();
            let bytes = e.as_bytes();
            let prefix = std::str::from_utf8(&bytes[..good]).unwrap_or_default();
            let (line, column) = line_col(prefix, good);
            ScenarioError::Parse {
                source_name: path.to_string(),
                line,
                column,
                message: format!(
                    "byte 0x{:02x} is not UTF-8 text; a scenario is a TOML text file saved as UTF-8",
                    bytes[good]
                ),
            }
        })?;
        let stem = p
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("scenario")
            .to_string();
        Scenario::from_toml(&text, path, &stem, overrides)
    }

    /// Parse scenario text; `source_name` names it in messages, `default_name` is used when
    /// the file sets no `name`.
    pub fn from_toml(
        text: &str,
        source_name: &str,
        default_name: &str,
        overrides: &[String],
    ) -> Result<Scenario, ScenarioError> {
        // Typed parse of the file alone first, so errors carry its line numbers.
        let mut scenario: Scenario =
            toml::from_str(text).map_err(|e| parse_error(source_name, text, &e))?;
        let mut shown_name = source_name.to_string();
        if !overrides.is_empty() {
            let mut table: toml::Table =
                toml::from_str(text).map_err(|e| parse_error(source_name, text, &e))?;
            for arg in overrides {
                let (path, value) = parse_assignment(arg)?;
                set_path(&mut table, &path, value).map_err(|message| ScenarioError::Override {
                    arg: arg.clone(),
                    message,
                })?;
                // Each override is checked on its own so the message names it.
                Scenario::deserialize(toml::Value::Table(table.clone())).map_err(|e| {
                    ScenarioError::Override {
                        arg: arg.clone(),
                        message: plain_message(&with_suggestion(e.message())),
                    }
                })?;
            }
            scenario = Scenario::deserialize(toml::Value::Table(table)).map_err(|e| {
                ScenarioError::Override {
                    arg: overrides.join(" "),
                    message: plain_message(&with_suggestion(e.message())),
                }
            })?;
            shown_name = format!("{source_name} with --set");
        }
        if scenario.name.is_none() {
            scenario.name = Some(default_name.to_string());
        }
        scenario.validate(&shown_name)?;
        Ok(scenario)
    }

    /// Build from an already parsed table (sweep cases); `source_name` names it in messages.
    pub fn from_table(
        table: toml::Table,
        source_name: &str,
        default_name: &str,
    ) -> Result<Scenario, ScenarioError> {
        let mut scenario = Scenario::deserialize(toml::Value::Table(table)).map_err(|e| {
            ScenarioError::Invalid {
                source_name: source_name.to_string(),
                key: "scenario".into(),
                message: plain_message(&with_suggestion(e.message())),
            }
        })?;
        if scenario.name.is_none() {
            scenario.name = Some(default_name.to_string());
        }
        scenario.validate(source_name)?;
        Ok(scenario)
    }

    /// The scenario as a TOML table (fields filled from files at run time are not included).
    pub fn to_table(&self) -> toml::Table {
        match toml::Value::try_from(self) {
            Ok(toml::Value::Table(t)) => t,
            _ => toml::Table::new(),
        }
    }

    /// Signals other than the quasi-static motion (closed-loop references), for the I/O
    /// layer to fill tabulated ones.
    pub fn signals_mut(&mut self) -> Vec<&mut Signal> {
        self.closed_loop
            .as_mut()
            .map(|c| vec![&mut c.reference])
            .unwrap_or_default()
    }

    /// Scenario name (file stem unless set).
    pub fn name(&self) -> &str {
        self.name.as_deref().unwrap_or("scenario")
    }

    /// Ranges and cross-checks; `source_name` is used in messages.
    pub fn validate(&self, source_name: &str) -> Result<(), ScenarioError> {
        let bad = |key: &str, msg: String| ScenarioError::invalid(source_name, key, msg);
        if let Some(name) = &self.name {
            if name.is_empty()
                || !name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.')
                || name.starts_with('.')
            {
                return Err(bad(
                    "name",
                    format!("{name:?} must be a non-empty folder name of letters, digits, '_', '-' or '.'"),
                ));
            }
        }
        self.drive.validate().map_err(|e| {
            let key = match &e {
                crate::physics::drive::DriveParamError::OutOfRange { key, .. } => {
                    format!("drive.{key}")
                }
                crate::physics::drive::DriveParamError::NoFreeSpan { .. } => {
                    "drive.center_distance_m".to_string()
                }
            };
            let full = e.to_string();
            let message = full
                .strip_prefix(&format!("{key} = "))
                .unwrap_or(&full)
                .to_string();
            bad(&key, message)
        })?;
        self.load
            .validate()
            .map_err(|(key, msg)| bad(&format!("load.{key}"), msg))?;
        // Every section present is checked, used by the study or not: a bad value in the
        // file is a mistake either way.
        match self.study {
            Study::QuasiStatic if self.quasi_static.is_none() => {
                return Err(bad(
                    "quasi_static",
                    "study = \"quasi_static\" needs a [quasi_static] section with duration_s and [quasi_static.motion]".into(),
                ));
            }
            Study::Backlash if self.backlash.is_none() => {
                return Err(bad(
                    "backlash",
                    "study = \"backlash\" needs a [backlash] section with load_nm".into(),
                ));
            }
            Study::ClosedLoop if self.closed_loop.is_none() => {
                return Err(bad(
                    "closed_loop",
                    "study = \"closed_loop\" needs a [closed_loop] section with duration_s, [closed_loop.reference] and [closed_loop.controller]".into(),
                ));
            }
            _ => {}
        }
        if let Some(qs) = &self.quasi_static {
            if !(qs.duration_s.is_finite() && qs.duration_s > 0.0 && qs.duration_s <= 1e6) {
                return Err(bad(
                    "quasi_static.duration_s",
                    format!("{} must be in (0, 1e6] s", crate::number(qs.duration_s)),
                ));
            }
            if !(qs.sample_rate_hz.is_finite() && qs.sample_rate_hz > 0.0) {
                return Err(bad(
                    "quasi_static.sample_rate_hz",
                    format!(
                        "{} must be a finite rate > 0 Hz",
                        crate::number(qs.sample_rate_hz)
                    ),
                ));
            }
            let samples = qs.duration_s * qs.sample_rate_hz;
            if !(samples.is_finite() && samples <= MAX_QS_SAMPLES) {
                return Err(bad(
                    "quasi_static.sample_rate_hz",
                    format!(
                        "{} Hz over duration_s = {} s is {samples:.3e} samples, too many (at most {MAX_QS_SAMPLES:.0e}); lower the rate or the duration",
                        crate::number(qs.sample_rate_hz), crate::number(qs.duration_s)),
                ));
            }
            if qs.models.is_empty() {
                return Err(bad(
                    "quasi_static.models",
                    "list at least one of \"memory\", \"memoryless\"".into(),
                ));
            }
            qs.motion
                .validate()
                .map_err(|m| bad("quasi_static.motion", m))?;
            let resolve = |key: &str, what: &str, f: f64| {
                if f * SAMPLES_PER_PERIOD > qs.sample_rate_hz {
                    Err(bad(
                        key,
                        format!(
                            "{what} = {} Hz is too fast for sample_rate_hz = {}: use at least {SAMPLES_PER_PERIOD} samples per period (sample_rate_hz >= {}) or a slower signal", crate::number(f), crate::number(qs.sample_rate_hz), crate::number(f * SAMPLES_PER_PERIOD)
                        ),
                    ))
                } else {
                    Ok(())
                }
            };
            resolve(
                "quasi_static.motion",
                "the motion's frequency_hz (or 1/period_s)",
                qs.motion.fastest_frequency_hz(),
            )?;
            if self.load.sine_nm != 0.0 {
                resolve(
                    "load.sine_frequency_hz",
                    "sine_frequency_hz",
                    self.load.sine_frequency_hz,
                )?;
            }
            if let Some(t) = qs
                .profile_times_s
                .iter()
                .find(|t| !(t.is_finite() && **t >= 0.0 && **t <= qs.duration_s))
            {
                return Err(bad(
                    "quasi_static.profile_times_s",
                    format!(
                        "{} must lie within [0, duration_s = {}]",
                        crate::number(*t),
                        crate::number(qs.duration_s)
                    ),
                ));
            }
        }
        if let Some(b) = &self.backlash {
            if !(b.load_nm.is_finite()
                && b.load_nm > 0.0
                && b.load_nm <= crate::physics::load::MAX_TORQUE_NM)
            {
                return Err(bad(
                    "backlash.load_nm",
                    format!(
                        "{} must be a torque > 0 and at most 1e6 N m",
                        crate::number(b.load_nm)
                    ),
                ));
            }
        }
        if let Some(cl) = &self.closed_loop {
            cl.validate(&self.drive)
                .map_err(|(key, msg)| bad(&key, msg))?;
        }
        if let Some(id) = &self.identify {
            id.validate()
                .map_err(|(key, msg)| bad(&format!("identify.{key}"), msg))?;
        }
        if let Some(fx) = &self.effects {
            fx.validate()
                .map_err(|(key, msg)| bad(&format!("effects.{key}"), msg))?;
        }
        if let Some(sweep) = &self.sweep {
            crate::sweep::validate_spec(sweep).map_err(|(key, msg)| bad(&key, msg))?;
            self.validate_sweep_values(sweep, source_name)?;
        }
        Ok(())
    }

    /// Every value a sweep gives a key must make a valid scenario on its own (combinations
    /// are checked again before a sweep runs).
    fn validate_sweep_values(
        &self,
        sweep: &SweepSpec,
        source_name: &str,
    ) -> Result<(), ScenarioError> {
        let mut base = self.to_table();
        base.remove("sweep");
        for (i, p) in sweep.parameters.iter().enumerate() {
            let path: Vec<String> = p.key.split('.').map(str::to_string).collect();
            for (j, value) in p.values.iter().enumerate() {
                let key = format!("sweep.parameters[{i}].values[{j}]");
                let mut table = base.clone();
                let shown = format!("{} = {value}", p.key);
                set_path(&mut table, &path, value.clone()).map_err(|m| {
                    ScenarioError::invalid(source_name, &key, format!("{shown}: {m}"))
                })?;
                let case = Scenario::from_table(table, source_name, self.name()).map_err(|e| {
                    let why = match e {
                        ScenarioError::Invalid { key, message, .. }
                            if key != "scenario" && key != p.key =>
                        {
                            format!("{key}: {message}")
                        }
                        ScenarioError::Invalid { message, .. } => message,
                        other => other.to_string(),
                    };
                    ScenarioError::invalid(source_name, &key, format!("{shown}: {why}"))
                });
                case?;
            }
        }
        Ok(())
    }

    /// Warnings that do not stop a run (e.g. load near the drive's capacity).
    pub fn warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        let capacity = 2.0 * self.drive.preload_n * self.drive.drum_radius_m;
        let peak = self
            .load
            .peak_torque_nm()
            .max(self.backlash.as_ref().map_or(0.0, |b| b.load_nm));
        if peak >= capacity {
            out.push(format!(
                "peak load {peak:.3} N m reaches the slack limit 2*preload_n*drum_radius_m = {capacity:.3} N m: expect a slack span; raise drive.preload_n above {:.1} N",
                peak / (2.0 * self.drive.drum_radius_m)
            ));
        } else if peak >= 0.8 * capacity {
            out.push(format!(
                "peak load {peak:.3} N m is {:.0} % of the slack limit {capacity:.3} N m",
                100.0 * peak / capacity
            ));
        }
        out
    }

    /// The scenario as TOML (as resolved, overrides applied), for summaries.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }
}

impl Study {
    /// The name a scenario file uses for this study.
    pub fn as_str(self) -> &'static str {
        match self {
            Study::QuasiStatic => "quasi_static",
            Study::Backlash => "backlash",
            Study::ClosedLoop => "closed_loop",
        }
    }
}

impl crate::closed_loop::ClosedLoopSource for Scenario {
    fn closed_loop_setup(
        &self,
    ) -> Result<crate::closed_loop::ClosedLoopSetup<'_>, crate::closed_loop::ClosedLoopError> {
        match (&self.study, &self.closed_loop) {
            (Study::ClosedLoop, Some(params)) => Ok(crate::closed_loop::ClosedLoopSetup {
                drive: &self.drive,
                load: &self.load,
                effects: self.effects.as_ref(),
                params,
            }),
            (study, _) => Err(crate::closed_loop::ClosedLoopError::NotClosedLoop {
                study: format!("\"{}\"", study.as_str()),
            }),
        }
    }
}

impl crate::identify::IdentifySource for Scenario {
    fn identify_setup(&self) -> crate::identify::IdentifySetup<'_> {
        crate::identify::IdentifySetup {
            name: self.name(),
            drive: &self.drive,
            load: &self.load,
            identify: self.identify.as_ref(),
            quasi_static: self.quasi_static.as_ref(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_parse_and_validate() {
        for (name, text) in BUILTIN {
            let s = Scenario::from_toml(text, name, name, &[]);
            assert!(s.is_ok(), "{name}: {:?}", s.err());
        }
    }

    #[test]
    fn unknown_key_suggests_the_closest() {
        let text = builtin("paper_bench")
            .unwrap()
            .replace("preload_n", "prelod_n");
        let err = Scenario::from_toml(&text, "x.toml", "x", &[])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("prelod_n") && err.contains("did you mean `preload_n`"),
            "{err}"
        );
        assert!(err.starts_with("x.toml:"), "{err}");
    }

    #[test]
    fn type_error_names_line() {
        let text = builtin("paper_bench")
            .unwrap()
            .replace("preload_n = 100.0", "preload_n = \"lots\"");
        let line = text.lines().position(|l| l.contains("\"lots\"")).unwrap() + 1;
        let err = Scenario::from_toml(&text, "x.toml", "x", &[])
            .unwrap_err()
            .to_string();
        assert!(err.starts_with(&format!("x.toml:{line}:")), "{err}");
    }

    #[test]
    fn overrides_apply_and_validate() {
        let text = builtin("paper_bench").unwrap();
        let s = Scenario::from_toml(
            text,
            "x",
            "x",
            &["drive.preload_n=70".into(), "drive.routing=open".into()],
        )
        .unwrap();
        assert_eq!(s.drive.preload_n, 70.0);
        assert_eq!(s.drive.routing, crate::physics::Routing::Open);
        let err = Scenario::from_toml(text, "x", "x", &["drive.prelod_n=70".into()])
            .unwrap_err()
            .to_string();
        assert!(err.contains("did you mean `preload_n`"), "{err}");
        let err = Scenario::from_toml(text, "x", "x", &["drive.preload_n=-3".into()])
            .unwrap_err()
            .to_string();
        assert!(err.contains("drive.preload_n"), "{err}");
        let err = Scenario::from_toml(text, "x", "x", &["drive.friction_coefficient=1.5".into()])
            .unwrap_err()
            .to_string();
        assert!(err.contains("(0, 1]"), "{err}");
    }
    #[test]
    fn shortened_spellings_get_a_suggestion() {
        let m = with_suggestion("unknown variant `figure8`, expected `figure_eight` or `open`");
        assert!(m.ends_with("did you mean `figure_eight`?"), "{m}");
        let m = with_suggestion("unknown variant `diagonal`, expected `figure_eight` or `open`");
        assert!(!m.contains("did you mean"), "{m}");
    }

    #[test]
    fn type_errors_in_tagged_sections_name_the_key_and_its_line() {
        let text = builtin("paper_bench")
            .unwrap()
            .replace("amplitude_rad = 0.1", "amplitude_rad = \"big\"");
        let line = text.lines().position(|l| l.contains("\"big\"")).unwrap() + 1;
        let err = Scenario::from_toml(&text, "x.toml", "x", &[])
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with(&format!(
                "x.toml:{line}:1: quasi_static.motion.amplitude_rad: invalid type"
            )),
            "{err}"
        );
        assert!(err.contains("expected a number"), "{err}");
    }

    #[test]
    fn sweep_values_are_checked_one_by_one() {
        let text = builtin("paper_fig11")
            .unwrap()
            .replace("values = [10.0,", "values = [-10.0,");
        let err = Scenario::from_toml(&text, "x.toml", "x", &[])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("sweep.parameters[0].values[0]: drive.preload_n = -10.0"),
            "{err}"
        );
    }

    #[test]
    fn sections_the_study_does_not_use_are_checked_too() {
        let text = format!(
            "{}\n[backlash]\nload_nm = -1.0\n",
            builtin("paper_bench").unwrap()
        );
        let err = Scenario::from_toml(&text, "x.toml", "x", &[])
            .unwrap_err()
            .to_string();
        assert!(err.contains("backlash.load_nm: -1"), "{err}");
    }

    #[test]
    fn messages_stay_on_one_line() {
        let err = Scenario::from_toml(
            builtin("paper_bench").unwrap(),
            "x",
            "x",
            &["name=\"\"\"a\nb\"\"\"".into()],
        )
        .unwrap_err()
        .to_string();
        assert!(!err.contains('\n'), "{err}");
    }
}
