//! Loads on the output drum: magnetic powder brake, mass unbalance, external torques.
//!
//! Sign convention (physics.md section 2): `Ml` is the torque the load applies to the drum,
//! positive along `+theta_out`; a brake resisting positive motion gives `Ml < 0`. The cable
//! then transmits `M = -Ml` quasi-statically.

use serde::{Deserialize, Serialize};

/// Largest load torque accepted, N m.
pub const MAX_TORQUE_NM: f64 = 1e6;

/// Load applied to the output drum. All torques in N m.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct LoadParams {
    /// Sliding torque of the magnetic powder brake, N m (about 0.7 on the paper bench).
    #[serde(default)]
    pub brake_nm: f64,
    /// Breakaway (static) torque of the brake, N m; defaults to `brake_nm`. The brake holds
    /// the drum until the net driving torque exceeds it.
    #[serde(default)]
    pub brake_breakaway_nm: Option<f64>,
    /// Amplitude of the mass-unbalance torque `m*g*l`, N m (0.1 to 1 for a camera payload).
    #[serde(default)]
    pub unbalance_nm: f64,
    /// Angle of the unbalance at `theta_out = 0`, rad: `Ml = -unbalance_nm*sin(theta_out + phase)`;
    /// `pi/2` puts the centre of mass level, giving a nearly constant torque.
    #[serde(default)]
    pub unbalance_phase_rad: f64,
    /// Constant external torque, N m.
    #[serde(default)]
    pub constant_nm: f64,
    /// Amplitude of a sinusoidal disturbance torque, N m.
    #[serde(default)]
    pub sine_nm: f64,
    /// Frequency of the sinusoidal disturbance, Hz.
    #[serde(default)]
    pub sine_frequency_hz: f64,
    /// External torque time series (CSV with `t_s` and `torque_nm`), added to the rest.
    #[serde(default)]
    pub disturbance_csv: Option<String>,
    /// Samples of the external torque series `(t_s, N m)`, filled by the I/O layer.
    #[serde(skip)]
    pub disturbance: Vec<(f64, f64)>,
}

impl LoadParams {
    /// Breakaway torque actually used, N m.
    pub fn breakaway_nm(&self) -> f64 {
        self.brake_breakaway_nm
            .unwrap_or(self.brake_nm)
            .max(self.brake_nm)
    }

    /// Load torque on the drum without the brake, `Ml` in N m, at time `t_s` and output
    /// angle `theta_out_rad`.
    pub fn smooth_torque_nm(&self, t_s: f64, theta_out_rad: f64) -> f64 {
        let mut m =
            self.constant_nm - self.unbalance_nm * (theta_out_rad + self.unbalance_phase_rad).sin();
        if self.sine_nm != 0.0 {
            m += self.sine_nm * (std::f64::consts::TAU * self.sine_frequency_hz * t_s).sin();
        }
        if !self.disturbance.is_empty() {
            m += interpolate(&self.disturbance, t_s);
        }
        m
    }

    /// Quasi-static load torque `Ml` (N m) when the drum moves in direction `direction`
    /// (+1, -1; 0 keeps the brake at zero).
    pub fn quasi_static_torque_nm(&self, t_s: f64, theta_out_rad: f64, direction: f64) -> f64 {
        self.smooth_torque_nm(t_s, theta_out_rad) - self.brake_nm * direction
    }

    /// Check ranges; returns `(key, message)` of the first problem.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let nonneg = |key: &'static str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err((
                    key,
                    format!("{} must be a finite number >= 0", crate::number(v)),
                ))
            }
        };
        let finite = |key: &'static str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err((key, format!("{} must be a finite number", crate::number(v))))
            }
        };
        // Torques beyond any cable drive: they only make unreadable numbers.
        let torque = |key: &'static str, v: f64| {
            if v.abs() <= MAX_TORQUE_NM {
                Ok(())
            } else {
                Err((
                    key,
                    format!(
                        "{} N m is beyond any cable drive (at most {MAX_TORQUE_NM:e} N m)",
                        crate::number(v)
                    ),
                ))
            }
        };
        nonneg("brake_nm", self.brake_nm)?;
        if let Some(b) = self.brake_breakaway_nm {
            nonneg("brake_breakaway_nm", b)?;
            if b < self.brake_nm {
                return Err((
                    "brake_breakaway_nm",
                    format!(
                        "{} must be >= brake_nm = {}",
                        crate::number(b),
                        crate::number(self.brake_nm)
                    ),
                ));
            }
        }
        nonneg("unbalance_nm", self.unbalance_nm)?;
        finite("unbalance_phase_rad", self.unbalance_phase_rad)?;
        finite("constant_nm", self.constant_nm)?;
        finite("sine_nm", self.sine_nm)?;
        nonneg("sine_frequency_hz", self.sine_frequency_hz)?;
        torque("brake_nm", self.brake_nm)?;
        torque("brake_breakaway_nm", self.breakaway_nm())?;
        torque("unbalance_nm", self.unbalance_nm)?;
        torque("constant_nm", self.constant_nm)?;
        torque("sine_nm", self.sine_nm)?;
        Ok(())
    }

    /// Largest torque this load can put on the drum, N m (for capacity checks).
    pub fn peak_torque_nm(&self) -> f64 {
        let dist = self
            .disturbance
            .iter()
            .map(|s| s.1.abs())
            .fold(0.0, f64::max);
        self.breakaway_nm() + self.unbalance_nm + self.constant_nm.abs() + self.sine_nm.abs() + dist
    }
}

/// Linear interpolation in a time-sorted table, held constant outside it.
pub fn interpolate(samples: &[(f64, f64)], t: f64) -> f64 {
    match samples {
        [] => 0.0,
        [only] => only.1,
        _ => {
            let k = samples.partition_point(|s| s.0 <= t);
            if k == 0 {
                samples[0].1
            } else if k >= samples.len() {
                samples[samples.len() - 1].1
            } else {
                let (t0, v0) = samples[k - 1];
                let (t1, v1) = samples[k];
                v0 + (v1 - v0) * (t - t0) / (t1 - t0)
            }
        }
    }
}
