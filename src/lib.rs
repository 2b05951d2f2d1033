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

/// A duration as shown in messages: `40 s`, `12 min`, `3.5 h`, `9.2 days`.
pub fn duration_words(s: f64) -> String {
    if !s.is_finite() {
        return format!("{s} s");
    }
    if s < 120.0 {
        format!("{} s", (s * 10.0).round() / 10.0)
    } else if s < 7200.0 {
        format!("{} min", (s / 60.0).round())
    } else if s < 2.0 * 86400.0 {
        format!("{} h", (s / 360.0).round() / 10.0)
    } else {
        let days = s / 86400.0;
        if days < 1e4 {
            format!("{} days", (days * 10.0).round() / 10.0)
        } else {
            format!("{days:.1e} days")
        }
    }
}

#[cfg(test)]
mod words_tests {
    #[test]
    fn durations_read_as_words() {
        assert_eq!(super::duration_words(0.25), "0.3 s");
        assert_eq!(super::duration_words(45.0), "45 s");
        assert_eq!(super::duration_words(600.0), "10 min");
        assert_eq!(super::duration_words(43200.0), "12 h");
        assert_eq!(super::duration_words(9.0 * 86400.0), "9 days");
        assert_eq!(super::duration_words(3e15), "3.5e10 days");
    }
}
