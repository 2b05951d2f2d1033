//! Helpers shared by the integration tests and benchmarks.

pub mod faults;
pub mod rates;
pub mod truth;
