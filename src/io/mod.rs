//! Files at the edge: bench logs, scenario tables, staged results directories.

pub mod benchlog;
pub mod merge;
pub mod output;
pub mod tables;
