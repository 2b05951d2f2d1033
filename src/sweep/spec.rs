//! Sweep declarations: which scenario keys vary and how.

use serde::{Deserialize, Serialize};

/// How the cases of a sweep are formed from its parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SweepMode {
    /// Every combination of the parameters' values (first parameter varies slowest).
    #[default]
    Grid,
    /// Parameters zipped: case `k` takes the `k`-th value of each list (same lengths).
    List,
}

/// One varied scenario key.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepParameter {
    /// Dotted scenario key, e.g. `drive.preload_n`.
    pub key: String,
    /// Values the key takes.
    pub values: Vec<toml::Value>,
    /// Column name in `sweep.csv`; defaults to the last part of the key (`preload_n`).
    #[serde(default)]
    pub column: Option<String>,
}

impl SweepParameter {
    /// Column name in the sweep table.
    pub fn column_name(&self) -> &str {
        match &self.column {
            Some(c) => c,
            None => self.key.rsplit('.').next().unwrap_or(&self.key),
        }
    }
}

/// A sweep declared in a scenario file (`[sweep]` with `[[sweep.parameters]]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// How cases are formed.
    #[serde(default)]
    pub mode: SweepMode,
    /// The varied keys.
    #[serde(default)]
    pub parameters: Vec<SweepParameter>,
}
