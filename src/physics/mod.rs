//! Cable-drive physics: capstan wrap regions with memory, cable halves, the drive, loads and
//! physical effects beyond the base model. Bottom layer: imports nothing of this crate.

pub mod drive;
pub mod effects;
pub mod half;
pub mod load;
pub mod newton;
pub mod wrap;

pub use drive::{CableDrive, DriveFault, DriveParams, DriveState, Half, HysteresisModel, Routing};
pub use effects::{ContactMemory, EffectsParams, KinematicError};
pub use load::{LoadParams, LoadTerm};
