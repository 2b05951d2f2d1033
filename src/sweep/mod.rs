//! Design sweeps over scenario keys.

pub mod answers;
pub mod engine;
pub mod merge;
pub mod spec;

pub use engine::{expand, run_cases, Case, CaseRunner, Cell, Shard, SweepError};
pub use spec::{SweepMode, SweepParameter, SweepSpec};
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
