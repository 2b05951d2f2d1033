//! Scenario files: a TOML description that fully determines a run.
//!
//! Parsing is strict (unknown keys are errors, with the closest valid key suggested), and
//! `--set KEY=VALUE` overrides go through the same deserialisation and validation as the
//! file.

use serde::{Deserialize, Serialize};

use crate::closed_loop::ClosedLoopParams;
use crate::identify::{EffectsParams, IdentifyParams};
use crate::physics::{DriveParams, HysteresisModel, LoadParams};
use crate::signal::Signal;
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

/// Prescribed-motion quasi-static study.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QuasiStaticParams {
    /// Simulated time, s (20 for two periods of the bench's 0.1 Hz sine).
    pub duration_s: f64,
    /// Samples per second, Hz (200 is plenty at 0.1 Hz).
    #[serde(default = "default_qs_rate")]
    pub sample_rate_hz: f64,
    /// Input (motor pulley) angle against time.
    pub motion: Signal,
    /// Models to run side by side.
    #[serde(default = "default_models")]
    pub models: Vec<HysteresisModel>,
    /// Instants at which tension profiles along the wraps are recorded and plotted, s.
    #[serde(default)]
    pub profile_times_s: Vec<f64>,
}

fn default_qs_rate() -> f64 {
    200.0
}

fn default_models() -> Vec<HysteresisModel> {
    vec![HysteresisModel::Memory, HysteresisModel::Memoryless]
}

/// Backlash protocol parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BacklashParams {
    /// Magnitude of the transmitted torque `M`, N m (0.72 on the bench).
    pub load_nm: f64,
    /// History model.
    #[serde(default)]
    pub model: HysteresisModel,
}

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
    #[error("{source_name}:{line}:{column}: {message}")]
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
    #[error("--set {arg}: {message}")]
    Override {
        /// The argument as given.
        arg: String,
        /// What is wrong.
        message: String,
    },
    /// A value outside its physical range or an inconsistent combination.
    #[error("{source_name}: {key}: {message}")]
    Invalid {
        /// File name (with `+ --set` when overrides were applied).
        source_name: String,
        /// Dotted key.
        key: String,
        /// What is wrong and what is allowed.
        message: String,
    },
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
    let best = candidates
        .iter()
        .map(|c| (strsim::normalized_damerau_levenshtein(bad, c), *c))
        .filter(|(score, _)| *score > 0.5)
        .max_by(|a, b| a.0.total_cmp(&b.0));
    let first_line = message.lines().next().unwrap_or(message);
    match best {
        Some((_, c)) => format!("{first_line}; did you mean `{c}`?"),
        None => first_line.to_string(),
    }
}

fn parse_error(source_name: &str, text: &str, err: &toml::de::Error) -> ScenarioError {
    let (line, column) = err
        .span()
        .map(|s| line_col(text, s.start))
        .unwrap_or((1, 1));
    ScenarioError::Parse {
        source_name: source_name.to_string(),
        line,
        column,
        message: with_suggestion(err.message()),
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
        let text = std::fs::read_to_string(p).map_err(|source| ScenarioError::Io {
            path: path.to_string(),
            source,
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
                        message: with_suggestion(e.message()),
                    }
                })?;
            }
            scenario = Scenario::deserialize(toml::Value::Table(table)).map_err(|e| {
                ScenarioError::Override {
                    arg: overrides.join(" "),
                    message: with_suggestion(e.message()),
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
                message: with_suggestion(e.message()),
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
            bad(&key, e.to_string())
        })?;
        self.load
            .validate()
            .map_err(|(key, msg)| bad(&format!("load.{key}"), msg))?;
        match self.study {
            Study::QuasiStatic => {
                let qs = self.quasi_static.as_ref().ok_or_else(|| {
                    bad(
                        "quasi_static",
                        "study = \"quasi_static\" needs a [quasi_static] section with duration_s and [quasi_static.motion]".into(),
                    )
                })?;
                if !(qs.duration_s.is_finite() && qs.duration_s > 0.0 && qs.duration_s <= 1e6) {
                    return Err(bad(
                        "quasi_static.duration_s",
                        format!("{} must be in (0, 1e6] s", qs.duration_s),
                    ));
                }
                if !(qs.sample_rate_hz.is_finite() && qs.sample_rate_hz > 0.0) {
                    return Err(bad(
                        "quasi_static.sample_rate_hz",
                        format!("{} must be > 0", qs.sample_rate_hz),
                    ));
                }
                let samples = qs.duration_s * qs.sample_rate_hz;
                if samples > 5e7 {
                    return Err(bad(
                        "quasi_static.sample_rate_hz",
                        format!("{samples:.0} samples is too many (at most 5e7); lower the rate or the duration"),
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
                if let Some(t) = qs
                    .profile_times_s
                    .iter()
                    .find(|t| !(t.is_finite() && **t >= 0.0 && **t <= qs.duration_s))
                {
                    return Err(bad(
                        "quasi_static.profile_times_s",
                        format!("{t} must lie within [0, duration_s = {}]", qs.duration_s),
                    ));
                }
            }
            Study::Backlash => {
                let b = self.backlash.as_ref().ok_or_else(|| {
                    bad(
                        "backlash",
                        "study = \"backlash\" needs a [backlash] section with load_nm".into(),
                    )
                })?;
                if !(b.load_nm.is_finite() && b.load_nm > 0.0) {
                    return Err(bad(
                        "backlash.load_nm",
                        format!("{} must be a finite torque > 0 N m", b.load_nm),
                    ));
                }
            }
            Study::ClosedLoop => {
                let cl = self.closed_loop.as_ref().ok_or_else(|| {
                    bad(
                        "closed_loop",
                        "study = \"closed_loop\" needs a [closed_loop] section with duration_s, [closed_loop.reference] and [closed_loop.controller]".into(),
                    )
                })?;
                cl.validate(&self.drive)
                    .map_err(|(key, msg)| bad(&key, msg))?;
            }
        }
        if let Some(sweep) = &self.sweep {
            crate::sweep::validate_spec(sweep).map_err(|(key, msg)| bad(&key, msg))?;
        }
        if let Some(id) = &self.identify {
            id.validate()
                .map_err(|(key, msg)| bad(&format!("identify.{key}"), msg))?;
        }
        if let Some(fx) = &self.effects {
            fx.validate()
                .map_err(|(key, msg)| bad(&format!("effects.{key}"), msg))?;
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
}
