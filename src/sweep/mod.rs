//! Design sweeps over scenario keys: case generation (grids, lists, random and Latin-hypercube
//! draws) and parallel execution of a closure the caller provides. Computation layer:
//! imports nothing of this crate above it.

pub mod engine;
pub mod sample;
pub mod spec;
pub mod vary;

pub use engine::{expand, run_cases, Case, CaseFn, Cell, Plan, Shard, SweepError};
pub use spec::{DistKind, SweepMode, SweepParameter, SweepSpec, MAX_CASES};

/// Check a sweep declaration; returns `(key, message)` of the first problem.
pub fn validate_spec(spec: &SweepSpec) -> Result<(), (String, String)> {
    spec.validate()
}
