//! Files at the edge: bench logs, scenario tables, staged results directories.

pub mod benchlog;
pub mod manifest;
pub mod output;
pub mod signals;
pub mod staging;
pub mod tables;
