//! Cable-drive physics: capstan wrap regions with memory, cable halves and the drive.
//!
//! Knows nothing of files, plots or the command line.

pub mod drive;
pub mod effects;
pub mod half;
pub mod load;
pub mod newton;
pub mod wrap;

pub use drive::{CableDrive, DriveFault, DriveParams, DriveState, Half, HysteresisModel, Routing};
pub use effects::{EffectsParams, KinematicError};
pub use load::LoadParams;
