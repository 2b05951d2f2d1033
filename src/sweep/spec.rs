//! Sweep declarations: which scenario keys vary and how.
//!
//! ```toml
//! [sweep]
//! mode = "latin_hypercube"   # grid | list | random | latin_hypercube
//! samples = 200              # random and latin_hypercube only
//! seed = 7                   # random and latin_hypercube only (default 0)
//!
//! [[sweep.parameters]]
//! key = "drive.preload_n"
//! dist = "truncated_normal"
//! mean = 100.0
//! std = 5.0
//! min = 90.0
//! max = 110.0
//!
//! [[sweep.parameters]]
//! key = "drive.cable_modulus_n"
//! dist = "normal_relative"   # relative to the scenario's own value
//! rel_std = 0.05
//! ```
//!
//! Distribution bounds and moments are in the unit of the varied key (N for
//! `drive.preload_n`, N m for `backlash.load_nm`, ...); `rel_*` figures are fractions of the
//! base scenario's value (0.05 = 5 %).

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
    /// `samples` independent draws; each parameter from its distribution (or uniformly
    /// from its `values`).
    Random,
    /// `samples` draws stratified per parameter: the range of probability is cut into
    /// `samples` equal strata and every stratum is hit exactly once per parameter.
    LatinHypercube,
}

impl SweepMode {
    /// Whether the mode draws samples (needs `samples`, accepts `dist`).
    pub fn is_sampled(self) -> bool {
        matches!(self, SweepMode::Random | SweepMode::LatinHypercube)
    }

    /// Name as written in scenario files.
    pub fn as_str(self) -> &'static str {
        match self {
            SweepMode::Grid => "grid",
            SweepMode::List => "list",
            SweepMode::Random => "random",
            SweepMode::LatinHypercube => "latin_hypercube",
        }
    }
}

/// Probability distribution of a sampled parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DistKind {
    /// Uniform between `min` and `max`.
    Uniform,
    /// Normal with `mean` and standard deviation `std`.
    Normal,
    /// Normal with `mean` and `std`, restricted to `[min, max]` (renormalised, not clipped).
    TruncatedNormal,
    /// Uniform within `base * (1 - rel_tol)` and `base * (1 + rel_tol)`, `base` being the
    /// scenario's own value of the key.
    UniformRelative,
    /// Normal around the scenario's own value `base` with standard deviation
    /// `rel_std * |base|`; truncated to `base * (1 -+ rel_tol)` when `rel_tol` is given.
    NormalRelative,
}

impl DistKind {
    /// Name as written in scenario files.
    pub fn as_str(self) -> &'static str {
        match self {
            DistKind::Uniform => "uniform",
            DistKind::Normal => "normal",
            DistKind::TruncatedNormal => "truncated_normal",
            DistKind::UniformRelative => "uniform_relative",
            DistKind::NormalRelative => "normal_relative",
        }
    }

    /// Fields this distribution requires and those it also accepts.
    fn fields(self) -> (&'static [&'static str], &'static [&'static str]) {
        match self {
            DistKind::Uniform => (&["min", "max"], &[]),
            DistKind::Normal => (&["mean", "std"], &[]),
            DistKind::TruncatedNormal => (&["mean", "std", "min", "max"], &[]),
            DistKind::UniformRelative => (&["rel_tol"], &[]),
            DistKind::NormalRelative => (&["rel_std"], &["rel_tol"]),
        }
    }
}

/// One varied scenario key: either a list of `values` (any mode) or a distribution `dist`
/// (random and latin_hypercube modes).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct SweepParameter {
    /// Dotted scenario key, e.g. `drive.preload_n`.
    /// Allowed: a dotted scenario key, varied by one parameter only.
    pub key: String,
    /// Values the key takes (grid and list modes; in sampled modes one is picked per case,
    /// each equally likely).
    /// Allowed: values of the key's type, each making a valid scenario.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub values: Vec<toml::Value>,
    /// Distribution the key is drawn from (sampled modes only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dist: Option<DistKind>,
    /// Lower bound, in the key's unit (`uniform`, `truncated_normal`).
    /// Allowed: finite, below `max`.
    /// Unit: the swept key's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min: Option<f64>,
    /// Upper bound, in the key's unit (`uniform`, `truncated_normal`).
    /// Allowed: finite, above `min`.
    /// Unit: the swept key's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max: Option<f64>,
    /// Mean, in the key's unit (`normal`, `truncated_normal`).
    /// Allowed: finite.
    /// Unit: the swept key's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean: Option<f64>,
    /// Standard deviation, in the key's unit (`normal`, `truncated_normal`).
    /// Allowed: > 0.
    /// Unit: the swept key's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std: Option<f64>,
    /// Standard deviation as a fraction of the base value (`normal_relative`; 0.05 = 5 %).
    /// Allowed: > 0.
    /// Unit: 1 (fraction of the scenario's value).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rel_std: Option<f64>,
    /// Half-width as a fraction of the base value (`uniform_relative`; bound of
    /// `normal_relative`); in (0, 1).
    /// Allowed: above 0 and below 1.
    /// Unit: 1 (fraction of the scenario's value).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rel_tol: Option<f64>,
    /// Column name in `sweep.csv`; defaults to the last part of the key (`preload_n`).
    /// Allowed: any name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub column: Option<String>,
}

impl SweepParameter {
    /// A parameter taking listed values.
    pub fn with_values(key: impl Into<String>, values: Vec<toml::Value>) -> Self {
        SweepParameter {
            key: key.into(),
            values,
            ..SweepParameter::default()
        }
    }

    /// Column name in the sweep table.
    pub fn column_name(&self) -> &str {
        match &self.column {
            Some(c) => c,
            None => self.key.rsplit('.').next().unwrap_or(&self.key),
        }
    }

    fn field(&self, name: &str) -> Option<f64> {
        match name {
            "min" => self.min,
            "max" => self.max,
            "mean" => self.mean,
            "std" => self.std,
            "rel_std" => self.rel_std,
            "rel_tol" => self.rel_tol,
            _ => None,
        }
    }

    /// Check the distribution fields; `at` is the parameter's key path for messages.
    fn validate_dist(&self, at: &str, kind: DistKind) -> Result<(), (String, String)> {
        let (required, optional) = kind.fields();
        for name in ["min", "max", "mean", "std", "rel_std", "rel_tol"] {
            let given = self.field(name).is_some();
            if given && !required.contains(&name) && !optional.contains(&name) {
                return Err((
                    format!("{at}.{name}"),
                    format!(
                        "not used by dist = \"{}\", which takes {}",
                        kind.as_str(),
                        required
                            .iter()
                            .chain(optional)
                            .copied()
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                ));
            }
            if !given && required.contains(&name) {
                return Err((
                    format!("{at}.{name}"),
                    format!("dist = \"{}\" needs {}", kind.as_str(), required.join(", ")),
                ));
            }
            if let Some(v) = self.field(name) {
                if !v.is_finite() {
                    return Err((format!("{at}.{name}"), format!("{v} is not finite")));
                }
            }
        }
        let bad = |name: &str, msg: String| Err((format!("{at}.{name}"), msg));
        if let (Some(lo), Some(hi)) = (self.min, self.max) {
            if lo >= hi {
                return bad("max", format!("{hi} must exceed min = {lo}"));
            }
        }
        if let Some(s) = self.std {
            if s <= 0.0 {
                return bad("std", format!("{s} must be > 0"));
            }
        }
        if let Some(s) = self.rel_std {
            if s <= 0.0 {
                return bad("rel_std", format!("{s} must be > 0 (0.05 = 5 %)"));
            }
        }
        if let Some(t) = self.rel_tol {
            if !(t > 0.0 && t < 1.0) {
                return bad(
                    "rel_tol",
                    format!("{t} must lie in (0, 1) (0.05 = +-5 %; 1 would reach zero)"),
                );
            }
        }
        Ok(())
    }
}

/// A sweep declared in a scenario file (`[sweep]` with `[[sweep.parameters]]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct SweepSpec {
    /// How cases are formed.
    #[serde(default)]
    pub mode: SweepMode,
    /// Number of cases drawn (random and latin_hypercube modes).
    /// Allowed: at least 1; required by, and only used by, `"random"` and
    /// `"latin_hypercube"`.
    /// Unit: cases.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
    /// Master seed of the draws (random and latin_hypercube modes; default 0). Case `k`
    /// draws from a stream seeded by `(seed, k, parameter)`, so rows do not depend on the
    /// thread count or the shard.
    /// Allowed: 0 to 2^63 - 1; only with `"random"` and `"latin_hypercube"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// The varied keys.
    /// Allowed: at least one (or `--vary` on the command line).
    #[serde(default)]
    pub parameters: Vec<SweepParameter>,
}

/// Most cases one sweep may hold (the case list is kept in memory, a few hundred bytes each).
pub const MAX_CASES: usize = 1_000_000;

impl SweepSpec {
    /// Number of cases the sweep expands to.
    pub fn case_count(&self) -> usize {
        match self.mode {
            SweepMode::Grid => self
                .parameters
                .iter()
                .map(|p| p.values.len())
                .fold(1usize, usize::saturating_mul),
            SweepMode::List => self.parameters.first().map_or(0, |p| p.values.len()),
            SweepMode::Random | SweepMode::LatinHypercube => self.samples.unwrap_or(0),
        }
    }

    /// Check the declaration; returns `(key, message)` of the first problem. Relative
    /// distributions are checked against the scenario's values when the sweep expands.
    pub fn validate(&self) -> Result<(), (String, String)> {
        if self.parameters.is_empty() {
            return Err((
                "sweep.parameters".into(),
                "declare at least one [[sweep.parameters]] with key and values (or dist), or pass --vary KEY=SPEC".into(),
            ));
        }
        let mode = self.mode.as_str();
        if self.mode.is_sampled() {
            match self.samples {
                None => {
                    return Err((
                        "sweep.samples".into(),
                        format!("mode = \"{mode}\" needs samples = N (number of cases)"),
                    ))
                }
                Some(0) => return Err(("sweep.samples".into(), "must be at least 1".into())),
                Some(_) => {}
            }
            if let Some(seed) = self.seed.filter(|&s| s > i64::MAX as u64) {
                // Results record the scenario as TOML, whose integers are signed 64-bit.
                return Err((
                    "sweep.seed".into(),
                    format!("{seed} is above {}; pick a smaller seed", i64::MAX),
                ));
            }
        } else {
            if self.samples.is_some() {
                return Err((
                    "sweep.samples".into(),
                    format!(
                        "only used by mode = \"random\" or \"latin_hypercube\", not \"{mode}\""
                    ),
                ));
            }
            if self.seed.is_some() {
                return Err((
                    "sweep.seed".into(),
                    format!(
                        "only used by mode = \"random\" or \"latin_hypercube\", not \"{mode}\""
                    ),
                ));
            }
        }
        for (i, p) in self.parameters.iter().enumerate() {
            let at = format!("sweep.parameters[{i}]");
            if p.key.is_empty() || p.key.split('.').any(str::is_empty) {
                return Err((
                    format!("{at}.key"),
                    format!("{:?} is not a dotted scenario key", p.key),
                ));
            }
            if let Some(j) = self.parameters[..i].iter().position(|q| q.key == p.key) {
                return Err((
                    format!("{at}.key"),
                    format!("{} is already varied by sweep.parameters[{j}]", p.key),
                ));
            }
            match (&p.dist, p.values.is_empty()) {
                (Some(_), false) => {
                    return Err((
                        at.clone(),
                        format!("{}: give either values or dist, not both", p.key),
                    ))
                }
                (None, true) => {
                    return Err((
                        format!("{at}.values"),
                        format!(
                            "{} has no values{}",
                            p.key,
                            if self.mode.is_sampled() {
                                " and no dist"
                            } else {
                                ""
                            }
                        ),
                    ))
                }
                (Some(kind), true) => {
                    if !self.mode.is_sampled() {
                        return Err((
                            format!("{at}.dist"),
                            format!("{}: distributions need mode = \"random\" or \"latin_hypercube\", not \"{mode}\"", p.key),
                        ));
                    }
                    p.validate_dist(&at, *kind)?;
                }
                (None, false) => {
                    if let Some(name) = ["min", "max", "mean", "std", "rel_std", "rel_tol"]
                        .into_iter()
                        .find(|n| p.field(n).is_some())
                    {
                        return Err((
                            format!("{at}.{name}"),
                            format!("{}: only used with dist", p.key),
                        ));
                    }
                }
            }
        }
        if self.mode == SweepMode::List {
            let n = self.parameters[0].values.len();
            if let Some(p) = self.parameters.iter().find(|p| p.values.len() != n) {
                return Err((
                    "sweep.parameters".into(),
                    format!(
                        "mode = \"list\" needs equal-length value lists: {} has {}, {} has {n}",
                        p.key,
                        p.values.len(),
                        self.parameters[0].key
                    ),
                ));
            }
        }
        let mut columns: Vec<&str> = Vec::new();
        for (i, p) in self.parameters.iter().enumerate() {
            let column = p.column_name();
            if column.is_empty()
                || column == "case"
                || column
                    .chars()
                    .any(|c| c.is_control() || matches!(c, ',' | '"'))
            {
                return Err((
                    format!("sweep.parameters[{i}].column"),
                    format!("{column:?} is not usable as a column name: use letters, digits and '_' (not \"case\")"),
                ));
            }
            if columns.contains(&column) {
                return Err((
                    format!("sweep.parameters[{i}].column"),
                    format!(
                        "column {column:?} is used twice; give the parameters different `column` names"
                    ),
                ));
            }
            columns.push(column);
        }
        let count = self.case_count();
        if count > MAX_CASES {
            return Err((
                "sweep.parameters".into(),
                format!("the sweep has {count} cases, more than {MAX_CASES} cases; sweep fewer values or split the study"),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<SweepSpec, String> {
        let spec: SweepSpec = toml::from_str(text).map_err(|e| e.to_string())?;
        spec.validate().map_err(|(k, m)| format!("{k}: {m}"))?;
        Ok(spec)
    }

    #[test]
    fn distributions_parse_and_validate() {
        let spec = parse(
            r#"
            mode = "latin_hypercube"
            samples = 10
            seed = 3
            [[parameters]]
            key = "drive.preload_n"
            dist = "truncated_normal"
            mean = 100.0
            std = 5.0
            min = 90.0
            max = 110.0
            [[parameters]]
            key = "drive.cable_modulus_n"
            dist = "normal_relative"
            rel_std = 0.05
            "#,
        )
        .unwrap();
        assert_eq!(spec.case_count(), 10);
        assert_eq!(spec.parameters[1].dist, Some(DistKind::NormalRelative));
    }

    #[test]
    fn errors_name_the_key() {
        let base = "[[parameters]]\nkey = \"drive.preload_n\"\n";
        let cases = [
            (
                "mode = \"random\"\n",
                "dist = \"uniform\"\nmin = 1.0\nmax = 2.0",
                "sweep.samples",
            ),
            (
                "mode = \"random\"\nsamples = 4\n",
                "dist = \"uniform\"\nmin = 1.0",
                "sweep.parameters[0].max",
            ),
            (
                "mode = \"random\"\nsamples = 4\n",
                "dist = \"normal\"\nmean = 1.0\nstd = 1.0\nmin = 0.0",
                "sweep.parameters[0].min",
            ),
            (
                "mode = \"random\"\nsamples = 4\n",
                "dist = \"uniform\"\nmin = 2.0\nmax = 1.0",
                "sweep.parameters[0].max",
            ),
            (
                "mode = \"random\"\nsamples = 4\n",
                "dist = \"uniform_relative\"\nrel_tol = 1.5",
                "sweep.parameters[0].rel_tol",
            ),
            (
                "mode = \"grid\"\n",
                "dist = \"uniform\"\nmin = 1.0\nmax = 2.0",
                "sweep.parameters[0].dist",
            ),
            (
                "mode = \"grid\"\nsamples = 3\n",
                "values = [1]",
                "sweep.samples",
            ),
        ];
        for (head, param, key) in cases {
            let err = parse(&format!("{head}{base}{param}\n")).unwrap_err();
            assert!(err.starts_with(key), "{head}{param}: {err}");
        }
        let err = parse(
            "mode = \"random\"\nsamples = 2\n[[parameters]]\nkey = \"a.b\"\ndist = \"gamma\"\n",
        )
        .unwrap_err();
        assert!(err.contains("gamma"), "{err}");
    }
}
