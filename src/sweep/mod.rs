//! Design sweeps over scenario keys.

pub mod answers;
pub mod engine;
pub mod merge;
pub mod sample;
pub mod spec;
pub mod vary;

pub use engine::{expand, run_cases, Case, CaseRunner, Cell, Shard, SweepError};
pub use spec::{DistKind, SweepMode, SweepParameter, SweepSpec, MAX_CASES};

/// Check a sweep declaration; returns `(key, message)` of the first problem.
pub fn validate_spec(spec: &SweepSpec) -> Result<(), (String, String)> {
    spec.validate()
}
