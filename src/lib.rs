//! cable-servo: preloaded cable-drive physics, closed-loop gimbal simulation, design sweeps
//! and bench-log diagnosis for electro-optical pointing systems.

pub mod physics;
