//! cable-servo: preloaded cable-drive physics, closed-loop gimbal simulation, design sweeps
//! and bench-log diagnosis for electro-optical pointing systems.

pub mod closed_loop;
pub mod design;
pub mod identify;
pub mod io;
pub mod metrics;
pub mod physics;
pub mod plot;
pub mod report;
pub mod run;
pub mod scenario;
pub mod signal;
pub mod study;
pub mod sweep;
