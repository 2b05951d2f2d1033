//! Files at the edge: bench logs, scenario tables, staged results directories, shard merges.
//! Edge layer: imports the bottom layer and fills a scenario's tables.

pub mod benchlog;
pub mod manifest;
pub mod merge;
pub mod output;
pub mod signals;
pub mod staging;
pub mod sweep_columns;
pub mod tables;
