//! What a design must meet (`[closed_loop.requirements]`), declared once per scenario and
//! judged by one routine, `analysis::verdict::judge`, for every command.
//!
//! The pointing target itself is `closed_loop.target_mrad` (peak error over the metrics
//! window, or the error after settling of every step of a stare); this section adds the
//! margins an engineer signs and the optional figures a design review asks for.

use serde::{Deserialize, Serialize};

use super::mode::CompensationMode;

/// Requirements of a closed-loop design. Defaults are what a servo engineer signs:
/// PM >= 35 deg, GM >= 6 dB up and down, Ms <= 2, with the scenario's computation delay,
/// held at the free-span cable and at the tangent stiffness of the largest declared load.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Requirements {
    /// Least phase margin over every gain crossover, deg (35).
    /// Allowed: 0 to 90.
    pub min_phase_margin_deg: f64,
    /// Least gain margin over every phase crossover, upward and downward, dB (6).
    /// Allowed: 0 to 60.
    pub min_gain_margin_db: f64,
    /// Largest sensitivity peak `max |S|` (2).
    /// Allowed: 1 to 100.
    /// Unit: 1.
    pub max_ms: f64,
    /// Transmitted torque, N m, whose tangent stiffness (first loading from the preload)
    /// the margins must also hold at; `None` (the default) takes the largest torque the
    /// scenario's load can put on the drum (`[load]`: breakaway + unbalance + constant +
    /// sine + table peak). 0 judges the free span alone.
    /// Allowed: 0 to 1e4.
    pub operating_load_nm: Option<f64>,
    /// Compensation mode whose pointing error is judged; `None` (the default) takes the
    /// last mode `closed_loop.modes` lists (the others are shown for comparison).
    /// Allowed: one of `closed_loop.modes`.
    pub mode: Option<CompensationMode>,
    /// Largest RMS pointing error over the metrics window, mrad; `None`: not required.
    /// Allowed: > 0 and at most 1e6.
    pub max_rms_mrad: Option<f64>,
    /// Largest line-of-sight jitter (RMS about each exposure's mean, worst exposure),
    /// mrad; `None`: not required (0.01 to 0.05 for a long-exposure imager).
    /// Allowed: > 0 and at most 1e6.
    pub max_jitter_mrad: Option<f64>,
    /// Longest settling time of a reference step into `closed_loop.settle_band_mrad`, s;
    /// `None`: not required.
    /// Allowed: 0 to 1e5.
    pub max_settling_s: Option<f64>,
    /// Least base-motion rejection, dB (line of sight over base angle, `-20 log10 |LOS/base|`)
    /// at `base_rejection_hz`, on the exact linear reference; `None`: not required.
    /// Allowed: -60 to 200, given with `base_rejection_hz`.
    pub min_base_rejection_db: Option<f64>,
    /// Frequency the base-motion rejection is judged at, Hz (needed with
    /// `min_base_rejection_db`; 1 to 10 for aircraft vibration).
    /// Allowed: > 0 and below the Nyquist frequency (below a tenth of the control rate for
    /// `freqresp --point base_motion`), given with `min_base_rejection_db`.
    pub base_rejection_hz: Option<f64>,
}

impl Default for Requirements {
    fn default() -> Self {
        Requirements {
            min_phase_margin_deg: 35.0,
            min_gain_margin_db: 6.0,
            max_ms: 2.0,
            operating_load_nm: None,
            mode: None,
            max_rms_mrad: None,
            max_jitter_mrad: None,
            max_settling_s: None,
            min_base_rejection_db: None,
            base_rejection_hz: None,
        }
    }
}

impl Requirements {
    /// Checks every value; returns `(key, message)` with the key under
    /// `requirements.`.
    pub fn validate(&self, sample_rate_hz: f64) -> Result<(), (String, String)> {
        let bad = |key: &str, message: String| Err((format!("requirements.{key}"), message));
        let within = |key: &str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                bad(
                    key,
                    format!("{}: allowed {} to {}", crate::number(v), lo, hi),
                )
            }
        };
        within("min_phase_margin_deg", self.min_phase_margin_deg, 0.0, 90.0)?;
        within("min_gain_margin_db", self.min_gain_margin_db, 0.0, 60.0)?;
        within("max_ms", self.max_ms, 1.0, 100.0)?;
        if let Some(m) = self.operating_load_nm {
            within("operating_load_nm", m, 0.0, 1e4)?;
        }
        for (key, v) in [
            ("max_rms_mrad", self.max_rms_mrad),
            ("max_jitter_mrad", self.max_jitter_mrad),
        ] {
            if let Some(v) = v {
                if !(v.is_finite() && v > 0.0 && v <= 1e6) {
                    return bad(
                        key,
                        format!(
                            "{}: give an error > 0 and at most 1e6 mrad",
                            crate::number(v)
                        ),
                    );
                }
            }
        }
        if let Some(s) = self.max_settling_s {
            within("max_settling_s", s, 0.0, 1e5)?;
        }
        match (self.min_base_rejection_db, self.base_rejection_hz) {
            (None, None) => {}
            (Some(db), Some(f)) => {
                within("min_base_rejection_db", db, -60.0, 200.0)?;
                let nyquist = 0.5 * sample_rate_hz;
                if !(f.is_finite() && f > 0.0 && f < nyquist) {
                    return bad(
                        "base_rejection_hz",
                        format!(
                            "{}: give a frequency above 0 and below Nyquist ({} Hz)",
                            crate::number(f),
                            crate::number(nyquist)
                        ),
                    );
                }
            }
            (Some(_), None) => {
                return bad(
                    "base_rejection_hz",
                    "missing: min_base_rejection_db is judged at this frequency (Hz)".into(),
                )
            }
            (None, Some(_)) => {
                return bad(
                    "min_base_rejection_db",
                    "missing: base_rejection_hz names where a rejection is required, give the least rejection in dB".into(),
                )
            }
        }
        Ok(())
    }
}
