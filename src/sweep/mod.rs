//! Design sweeps over scenario keys.

pub mod answers;
pub mod engine;
pub mod merge;
pub mod spec;

pub use engine::{expand, run_cases, Case, CaseRunner, Cell, Shard, SweepError};
pub use spec::{SweepMode, SweepParameter, SweepSpec};
/// Most cases a sweep may declare.
pub const MAX_CASES: usize = 1_000_000;

/// Check a sweep declaration; returns `(key, message)` of the first problem.
pub fn validate_spec(spec: &SweepSpec) -> Result<(), (String, String)> {
    if spec.parameters.is_empty() {
        return Err((
            "sweep.parameters".into(),
            "declare at least one [[sweep.parameters]] with key and values".into(),
        ));
    }
    for (i, p) in spec.parameters.iter().enumerate() {
        let key = format!("sweep.parameters[{i}]");
        if p.key.is_empty() || p.key.split('.').any(str::is_empty) {
            return Err((
                format!("{key}.key"),
                format!("{:?} is not a dotted scenario key", p.key),
            ));
        }
        if p.values.is_empty() {
            return Err((format!("{key}.values"), format!("{} has no values", p.key)));
        }
    }
    let mut columns: Vec<&str> = Vec::new();
    for (i, p) in spec.parameters.iter().enumerate() {
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
    if spec.mode == SweepMode::Grid {
        let total = spec
            .parameters
            .iter()
            .try_fold(1usize, |n, p| n.checked_mul(p.values.len()));
        if total.is_none_or(|n| n > MAX_CASES) {
            return Err((
                "sweep.parameters".into(),
                format!("the grid has more than {MAX_CASES} cases; sweep fewer values or split the study"),
            ));
        }
    }
    if spec.mode == SweepMode::List {
        let n = spec.parameters[0].values.len();
        if let Some(p) = spec.parameters.iter().find(|p| p.values.len() != n) {
            return Err((
                "sweep.parameters".into(),
                format!(
                    "mode = \"list\" needs equal-length value lists: {} has {}, {} has {n}",
                    p.key,
                    p.values.len(),
                    spec.parameters[0].key
                ),
            ));
        }
    }
    Ok(())
}
