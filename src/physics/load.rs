//! Loads on the output drum: magnetic powder brake, mass unbalance, external torques.
//!
//! Sign convention (physics.md section 2): `Ml` is the torque the load applies to the drum,
//! positive along `+theta_out`; a brake resisting positive motion gives `Ml < 0`. The cable
//! then transmits `M = -Ml` quasi-statically.

use serde::{Deserialize, Serialize};

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// Largest load torque accepted, N m.
pub const MAX_TORQUE_NM: f64 = 1e6;

/// Load applied to the output drum. All torques in N m.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct LoadParams {
    /// Sliding torque of the magnetic powder brake, N m (about 0.7 on the paper bench).
    /// Allowed: 0 to 1e6.
    #[serde(default)]
    pub brake_nm: f64,
    /// Breakaway (static) torque of the brake, N m; defaults to `brake_nm`. The brake holds
    /// the drum until the net driving torque exceeds it.
    /// Allowed: `brake_nm` to 1e6.
    #[serde(default)]
    pub brake_breakaway_nm: Option<f64>,
    /// Amplitude of the mass-unbalance torque `m*g*l`, N m (0.1 to 1 for a camera payload).
    /// Allowed: 0 to 1e6.
    #[serde(default)]
    pub unbalance_nm: f64,
    /// Angle of the unbalance at `theta_out = 0`, rad: `Ml = -unbalance_nm*sin(theta_out + phase)`;
    /// `pi/2` puts the centre of mass level, giving a nearly constant torque.
    /// Allowed: any finite number.
    #[serde(default)]
    pub unbalance_phase_rad: f64,
    /// Constant external torque, N m.
    /// Allowed: -1e6 to 1e6.
    #[serde(default)]
    pub constant_nm: f64,
    /// Whether the constant torque is a declared model the compensator is given (a set
    /// bench torque, a grasp the controller commands); by default it is a disturbance that
    /// reaches the controller only through its sensors.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub constant_declared: bool,
    /// Time over which the constant torque rises linearly from zero, s (0: a step at
    /// t = 0; 0.5 for a grasp that closes over half a second).
    /// Allowed: 0 (a step) to 1e5.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub constant_ramp_s: f64,
    /// Amplitude of a sinusoidal disturbance torque, N m.
    /// Allowed: -1e6 to 1e6.
    #[serde(default)]
    pub sine_nm: f64,
    /// Frequency of the sinusoidal disturbance, Hz.
    /// Allowed: >= 0; in a quasi-static study with `sine_nm` set, at most a tenth of
    /// `quasi_static.sample_rate_hz`.
    #[serde(default)]
    pub sine_frequency_hz: f64,
    /// External torque time series (CSV with `t_s` and `torque_nm`), added to the rest.
    /// Allowed: a CSV file, relative to the scenario file's folder, with increasing `t_s`
    /// and a `torque_nm` column.
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
        let mut m = self.constant_at(t_s)
            - self.unbalance_nm * (theta_out_rad + self.unbalance_phase_rad).sin();
        if self.sine_nm != 0.0 {
            m += self.sine_nm * (std::f64::consts::TAU * self.sine_frequency_hz * t_s).sin();
        }
        if !self.disturbance.is_empty() {
            m += interpolate(&self.disturbance, t_s);
        }
        m
    }

    /// The part of `smooth_torque_nm` a compensator may predict, N m: only the terms whose
    /// `LoadTerm::known_to_compensator` is true (the unbalance, a declared model of the
    /// payload). Constant, sine and CSV torques are disturbances a real controller meets
    /// only when they act, so they are left out; the result depends on the angle alone.
    pub fn known_torque_nm(&self, t_s: f64, theta_out_rad: f64) -> f64 {
        let mut m = 0.0;
        if self.is_known(LoadTerm::Unbalance) {
            m -= self.unbalance_nm * (theta_out_rad + self.unbalance_phase_rad).sin();
        }
        if self.is_known(LoadTerm::Constant) {
            m += self.constant_at(t_s);
        }
        m
    }

    /// The constant torque at time `t_s` (s), N m, on its ramp.
    pub fn constant_at(&self, t_s: f64) -> f64 {
        if self.constant_ramp_s > 0.0 && t_s < self.constant_ramp_s {
            self.constant_nm * (t_s / self.constant_ramp_s).max(0.0)
        } else {
            self.constant_nm
        }
    }

    /// Whether the compensator is given load term `term` of this load in advance.
    pub fn is_known(&self, term: LoadTerm) -> bool {
        term.known_to_compensator() || (term == LoadTerm::Constant && self.constant_declared)
    }

    /// Load terms present in this load whose torque the compensator is given in advance.
    pub fn known_terms(&self) -> Vec<LoadTerm> {
        self.present_terms()
            .into_iter()
            .filter(|t| self.is_known(*t))
            .collect()
    }

    /// Load terms present in this load that act on the plant unannounced.
    pub fn unknown_terms(&self) -> Vec<LoadTerm> {
        self.present_terms()
            .into_iter()
            .filter(|t| !self.is_known(*t))
            .collect()
    }

    fn present_terms(&self) -> Vec<LoadTerm> {
        let mut v = Vec::new();
        if self.brake_nm != 0.0 || self.breakaway_nm() != 0.0 {
            v.push(LoadTerm::Brake);
        }
        if self.unbalance_nm != 0.0 {
            v.push(LoadTerm::Unbalance);
        }
        if self.constant_nm != 0.0 {
            v.push(LoadTerm::Constant);
        }
        if self.sine_nm != 0.0 {
            v.push(LoadTerm::Sine);
        }
        if !self.disturbance.is_empty() || self.disturbance_csv.is_some() {
            v.push(LoadTerm::Csv);
        }
        v
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
                Err((key, crate::out_of_range(v, "a finite number >= 0")))
            }
        };
        let finite = |key: &'static str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err((key, crate::out_of_range(v, "a finite number")))
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
        if !(self.constant_ramp_s.is_finite() && (0.0..=1e5).contains(&self.constant_ramp_s)) {
            return Err((
                "constant_ramp_s",
                format!(
                    "{} must be a time in s from 0 (a step) to 1e5",
                    crate::number(self.constant_ramp_s)
                ),
            ));
        }
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

/// One term of the load on the drum.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LoadTerm {
    /// Magnetic powder brake (declared model, direction from the reference).
    Brake,
    /// Mass unbalance (declared model, angle from the reference).
    Unbalance,
    /// Constant external torque (a disturbance).
    Constant,
    /// Sinusoidal disturbance torque.
    Sine,
    /// Measured external torque series.
    Csv,
}

impl LoadTerm {
    /// Whether the feedforward may use this term: true for modelled loads that follow
    /// from the reference (brake, unbalance), false for time-driven disturbances, which a
    /// real controller cannot know before they act (a constant torque is known only when
    /// declared, [`LoadParams::is_known`]).
    pub fn known_to_compensator(self) -> bool {
        matches!(self, LoadTerm::Brake | LoadTerm::Unbalance)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disturbances_are_not_known_to_the_compensator() {
        let base = LoadParams {
            brake_nm: 0.7,
            unbalance_nm: 0.3,
            unbalance_phase_rad: 0.4,
            ..Default::default()
        };
        let disturbed = LoadParams {
            constant_nm: 0.5,
            sine_nm: 0.2,
            sine_frequency_hz: 3.0,
            disturbance: vec![(0.0, 0.1), (1.0, -0.4)],
            ..base.clone()
        };
        for k in 0..50 {
            let t = 0.02 * k as f64;
            let th = 0.01 * k as f64 - 0.2;
            assert_eq!(
                base.known_torque_nm(0.0, th),
                disturbed.known_torque_nm(0.0, th)
            );
            let want = -0.3 * (th + 0.4_f64).sin();
            assert!((disturbed.known_torque_nm(0.0, th) - want).abs() < 1e-15);
            assert_ne!(
                base.smooth_torque_nm(t, th),
                disturbed.smooth_torque_nm(t, th)
            );
        }
        assert_eq!(
            disturbed.unknown_terms(),
            vec![LoadTerm::Constant, LoadTerm::Sine, LoadTerm::Csv]
        );
        assert_eq!(
            disturbed.known_terms(),
            vec![LoadTerm::Brake, LoadTerm::Unbalance]
        );
    }

    #[test]
    fn a_declared_constant_torque_is_known_and_ramps_in() {
        let mut l = LoadParams {
            constant_nm: 0.08,
            constant_ramp_s: 0.5,
            ..LoadParams::default()
        };
        assert_eq!(l.known_torque_nm(1.0, 0.3), 0.0);
        assert_eq!(l.unknown_terms(), vec![LoadTerm::Constant]);
        l.constant_declared = true;
        assert_eq!(l.known_terms(), vec![LoadTerm::Constant]);
        assert!(l.unknown_terms().is_empty());
        for (t, want) in [(0.0, 0.0), (0.25, 0.04), (0.5, 0.08), (3.0, 0.08)] {
            assert!((l.smooth_torque_nm(t, 0.3) - want).abs() < 1e-15, "{t}");
            assert!((l.known_torque_nm(t, 0.3) - want).abs() < 1e-15, "{t}");
        }
        l.constant_ramp_s = -1.0;
        assert_eq!(l.validate().unwrap_err().0, "constant_ramp_s");
    }
}
