//! cable-servo: preloaded cable-drive physics, closed-loop gimbal simulation, design sweeps
//! and bench-log diagnosis for electro-optical pointing systems.
//!
//! The modules form four layers; each imports only from the layers below it (and the few
//! same-layer arrows listed in `tests/layering.rs`, which enforces this):
//!
//! | layer | modules | job |
//! |---|---|---|
//! | top | [`run`], [`design`], the `cable-servo` binary | orchestration and the command line |
//! | edge | [`scenario`], [`io`], [`plot`], [`report`] | scenario files, logs and tables, figures, result files |
//! | computation | [`closed_loop`], [`study`], [`identify`], [`sweep`] | parameter structs in, result records out |
//! | bottom | [`physics`], [`signal`], [`metrics`], [`measurement`] | the drive's physics, signals, metrics, data in memory |

pub mod closed_loop;
pub mod design;
pub mod fmu;
pub mod identify;
pub mod io;
pub mod measurement;
pub mod metrics;
pub mod physics;
pub mod plot;
pub mod report;
pub mod run;
pub mod scenario;
pub mod signal;
pub mod study;
pub mod sweep;

/// A number as shown in messages: plain for everyday magnitudes, in exponent form for very
/// large or small ones (`1e300`, not three hundred digits).
pub fn number(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..1e9).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}
