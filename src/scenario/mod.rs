//! Scenario files: a TOML description that fully determines a run, read into the parameter
//! structs of the computation layer. Edge layer: imports computation and bottom modules.
//!
//! Parsing is strict (unknown keys are errors, with the closest valid key suggested), and
//! `--set KEY=VALUE` overrides go through the same deserialisation and validation as the
//! file.
//!
//! The parts: `errors` (what can be wrong, with file, line and key), `builtin` (the
//! scenarios compiled into the binary), `overrides` (`--set KEY=VALUE`), `validate`
//! (ranges and cross-checks).

use serde::{Deserialize, Serialize};

use crate::closed_loop::ClosedLoopParams;
use crate::identify::{EffectsParams, IdentifyParams};
use crate::physics::{DriveParams, LoadParams};
use crate::signal::Signal;
pub use crate::study::quasi_static::{BacklashParams, QuasiStaticParams};
use crate::sweep::SweepSpec;

mod builtin;
mod errors;
mod keys;
mod overrides;
#[cfg(test)]
mod tests;
mod validate;

pub use builtin::{builtin, BUILTIN, DEFAULT_SCENARIO};
pub use errors::ScenarioError;
use errors::{line_col, parse_error, plain_message, with_suggestion};
pub use keys::accepted_keys;
pub use overrides::{parse_assignment, set_path};

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

/// Longest scenario `name`, characters: the results folder and its staging folder are
/// named after it, and a file system allows 255 bytes for a name.
pub const MAX_NAME_CHARS: usize = 100;

/// Most samples a quasi-static run may take (memory and run time grow with it).
pub const MAX_QS_SAMPLES: f64 = 2e6;

/// Fewest samples per period of the fastest motion or load component.
pub const SAMPLES_PER_PERIOD: f64 = 10.0;

/// A complete run description.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Name used for the results folder; defaults to the file stem.
    /// Allowed: letters, digits, `_`, `-` and `.`, not starting with `.` (a folder name).
    #[serde(default)]
    pub name: Option<String>,
    /// One-line description for reports.
    /// Allowed: any text.
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

/// Whether serde's message says a name was expected and something else was given (a
/// number where `routing` wants `"open"`): its own words name neither the key's names
/// nor the key.
fn wrong_type_for_a_name(message: &str) -> bool {
    [
        "unit variant",
        "expected string only",
        "wanted string or table",
    ]
    .iter()
    .any(|p| message.contains(p))
}

/// The names a key of an enumeration accepts (`expected one of `a`, `b``), found by
/// offering it a name no enumeration has and reading the refusal; `None` when the key
/// takes something else.
fn names_at(table: &toml::Table, path: &[String]) -> Option<String> {
    const PROBE: &str = "\u{1}";
    let mut probe = table.clone();
    set_path(&mut probe, path, toml::Value::String(PROBE.into())).ok()?;
    let err = Scenario::deserialize(toml::Value::Table(probe)).err()?;
    let message = err.message();
    let rest = message
        .split(&format!("unknown variant `{PROBE}`, "))
        .nth(1)?;
    Some(rest.lines().next().unwrap_or(rest).to_string())
}

impl Scenario {
    /// Read a scenario file, or a built-in scenario when `path` names one (`eots_tracking`)
    /// and is not a file; a directory is refused with [`ScenarioError::Directory`].
    pub fn load(path: &str, overrides: &[String]) -> Result<Scenario, ScenarioError> {
        let p = std::path::Path::new(path);
        // A directory is never a scenario file: a results directory named after a built-in
        // scenario (`--out eots_tracking`) must not hide it.
        // `None`: nothing readable at that path.
        let is_dir = std::fs::metadata(p).ok().map(|meta| meta.is_dir());
        if is_dir != Some(false) {
            if let Some(text) = builtin(path) {
                return Scenario::from_toml(text, &format!("{path} (built-in)"), path, overrides);
            }
        }
        match is_dir {
            None => return Err(not_found(path)),
            Some(true) => {
                return Err(ScenarioError::Directory {
                    path: path.to_string(),
                })
            }
            Some(false) => {}
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
        let mut scenario: Scenario = toml::from_str(text).map_err(|e| {
            let mut err = parse_error(source_name, text, &e);
            // A number or table where a name belongs: say which names.
            if let (ScenarioError::Parse { message, .. }, true) =
                (&mut err, wrong_type_for_a_name(e.message()))
            {
                let names = e
                    .span()
                    .and_then(|s| errors::key_at(text, s.start))
                    .and_then(|key| {
                        let table = toml::from_str::<toml::Table>(text).ok()?;
                        let path: Vec<String> = key.split('.').map(String::from).collect();
                        names_at(&table, &path).map(|n| (key, n))
                    });
                if let Some((key, names)) = names {
                    *message = format!("{key} takes a name in quotes: {names}");
                }
            }
            err
        })?;
        let mut shown_name = source_name.to_string();
        if !overrides.is_empty() {
            let mut table: toml::Table =
                toml::from_str(text).map_err(|e| parse_error(source_name, text, &e))?;
            let parsed = overrides
                .iter()
                .map(|arg| parse_assignment(arg).map(|(path, value)| (arg, path, value)))
                .collect::<Result<Vec<_>, _>>()?;
            // A new `kind` replaces its table's keys: switched first, so the new kind's
            // keys may come in any order around it.
            let mut switched: Vec<(Vec<String>, Vec<String>)> = Vec::new();
            for (arg, path, value) in &parsed {
                if path.last().map(String::as_str) == Some("kind") {
                    let dropped =
                        switch_kind(&mut table, path, value.clone()).map_err(|message| {
                            ScenarioError::Override {
                                arg: (*arg).clone(),
                                message,
                            }
                        })?;
                    if !dropped.is_empty() {
                        switched.push((path[..path.len() - 1].to_vec(), dropped));
                    }
                }
            }
            for (arg, path, value) in &parsed {
                if path.last().map(String::as_str) == Some("kind") {
                    continue;
                }
                set_path(&mut table, path, value.clone()).map_err(|message| {
                    ScenarioError::Override {
                        arg: (*arg).clone(),
                        message,
                    }
                })?;
                // Each override is checked on its own so the message names it (inside a
                // switched table the new kind is complete only after all its keys).
                if switched.iter().any(|(t, _)| path.starts_with(t)) {
                    continue;
                }
                Scenario::deserialize(toml::Value::Table(table.clone())).map_err(|e| {
                    let names = wrong_type_for_a_name(e.message())
                        .then(|| names_at(&table, path))
                        .flatten();
                    ScenarioError::Override {
                        arg: (*arg).clone(),
                        message: match names {
                            Some(names) => format!(
                                "{} takes a name in quotes, not {value}: {names}",
                                path.join(".")
                            ),
                            None => plain_message(&with_suggestion(e.message())),
                        },
                    }
                })?;
            }
            scenario = Scenario::deserialize(toml::Value::Table(table)).map_err(|e| {
                let mut message = plain_message(&with_suggestion(e.message()));
                for (t, dropped) in &switched {
                    message.push_str(&format!(
                        "; the new {}.kind replaced the old kind's keys ({}): give the new kind's keys with --set {}.KEY=VALUE",
                        t.join("."),
                        dropped.join(", "),
                        t.join(".")
                    ));
                }
                ScenarioError::Override {
                    arg: overrides.join(" "),
                    message,
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
            .map(|c| {
                let mut v = vec![&mut c.reference];
                v.extend(c.base_motion.as_mut());
                v
            })
            .unwrap_or_default()
    }

    /// Scenario name (file stem unless set).
    pub fn name(&self) -> &str {
        self.name.as_deref().unwrap_or("scenario")
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
                "peak load {} N m reaches the slack limit 2*preload_n*drum_radius_m = {} N m: expect a slack span; raise drive.preload_n above {} N",
                crate::fixed_or_significant(peak, 3),
                crate::fixed_or_significant(capacity, 3),
                crate::fixed_or_significant(peak / (2.0 * self.drive.drum_radius_m), 1)
            ));
        } else if peak >= 0.8 * capacity {
            out.push(format!(
                "peak load {} N m is {:.0} % of the slack limit {} N m",
                crate::fixed_or_significant(peak, 3),
                100.0 * peak / capacity,
                crate::fixed_or_significant(capacity, 3)
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
                instability: crate::analysis::linear::LinearLoop::new(params, &self.drive)
                    .instability(),
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
            effects: self.effects.as_ref(),
        }
    }
}

/// The error for a name that is neither a file nor built in, with the nearest built-in
/// name when it is within a third of the name's length.
fn not_found(name: &str) -> ScenarioError {
    let names: Vec<&str> = BUILTIN.iter().map(|(n, _)| *n).collect();
    let stem = std::path::Path::new(name)
        .file_stem()
        .map_or(name.to_string(), |s| s.to_string_lossy().into_owned());
    let suggestion = names
        .iter()
        .map(|n| (strsim::levenshtein(&stem, n), *n))
        .min()
        .filter(|(d, _)| *d > 0 && *d <= stem.chars().count().div_ceil(3))
        .map(|(_, n)| n.to_string());
    ScenarioError::NotFound {
        name: name.to_string(),
        suggestion,
        builtins: names.join(", "),
    }
}

/// Sets `path` (ending in `kind`) to `value`; when its table held another kind, the old
/// kind's other keys are removed first. Returns the keys removed.
fn switch_kind(
    table: &mut toml::Table,
    path: &[String],
    value: toml::Value,
) -> Result<Vec<String>, String> {
    let mut cur: &toml::Table = table;
    for part in &path[..path.len() - 1] {
        match cur.get(part) {
            Some(toml::Value::Table(t)) => cur = t,
            _ => {
                set_path(table, path, value)?;
                return Ok(Vec::new());
            }
        }
    }
    let same = cur.get("kind") == Some(&value) || cur.get("kind").is_none();
    let dropped: Vec<String> = if same {
        Vec::new()
    } else {
        cur.keys().filter(|k| *k != "kind").cloned().collect()
    };
    let mut parent = toml::Table::new();
    if !same {
        parent.insert("kind".into(), value.clone());
        set_path(table, &path[..path.len() - 1], toml::Value::Table(parent))?;
    } else {
        set_path(table, path, value)?;
    }
    Ok(dropped)
}
