//! Physical effects beyond the base capstan model that a plant can carry and a compensator
//! can predict: pulley and drum runout, thermal drift, bearing friction. One formula serves
//! the closed-loop plant, its compensator and the diagnosis of bench logs.

use serde::{Deserialize, Serialize};

/// `[effects]`: identified effects the closed loop can compensate. Absent keys mean the
/// effect is not present.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectsParams {
    /// Input pulley eccentricity over radius.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_pulley_runout: Option<f64>,
    /// Phase `phi` of the input runout, rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_pulley_runout_phase_rad: Option<f64>,
    /// Output drum eccentricity over radius.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_drum_runout: Option<f64>,
    /// Phase `phi` of the drum runout, rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_drum_runout_phase_rad: Option<f64>,
    /// Output encoder lag, s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoder_delay_s: Option<f64>,
    /// Output encoder scale error `s` (reading = (1+s) angle).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoder_scale_error: Option<f64>,
    /// Preload loss rate, fraction per second.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preload_relaxation_per_s: Option<f64>,
    /// Unmeasured Coulomb torque at the drum, N m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bearing_friction_nm: Option<f64>,
    /// Input travel over which the error settles after a reversal, rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cable_transport_rad: Option<f64>,
    /// Drift of the error with time, rad/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermal_drift_rad_per_s: Option<f64>,
    /// Ratio shape: Legendre coefficients of `P_2, P_3, P_4` of the input angle scaled to
    /// `angle_dependent_ratio_stroke_rad`, rad of output error.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_dependent_ratio_coefs: Option<Vec<f64>>,
    /// Input stroke `[low, high]` the ratio shape is defined over, rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_dependent_ratio_stroke_rad: Option<[f64; 2]>,
    /// Output deflection per transmitted torque beyond the spans, rad/(N m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_compliance_rad_per_nm: Option<f64>,
    /// Play thresholds of the distributed friction memory, rad of input.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_thresholds_rad: Option<Vec<f64>>,
    /// Their weights, output rad per input rad (non-negative).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_weights: Option<Vec<f64>>,
    /// Growth of the weights with the transmitted torque's magnitude `|M|^p`, per (N m)^p
    /// with `p` = `friction_memory_load_exponent` (non-negative; friction at a contact
    /// grows with the tension pressing on it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_load_weights_per_nm: Option<Vec<f64>>,
    /// Exponent `p` of that growth: the load-scaled weights multiply `|M|^p` (absent: 1,
    /// growth proportional to the torque).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_load_exponent: Option<f64>,
}

impl EffectsParams {
    /// Check ranges; returns `(key below effects, message)`.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let check = |key: &str, v: Option<f64>, lo: f64, hi: f64| match v {
            Some(x) if !(x.is_finite() && x >= lo && x <= hi) => Err((
                key.to_string(),
                format!("{x} must be a finite number in [{lo}, {hi}]"),
            )),
            _ => Ok(()),
        };
        check("input_pulley_runout", self.input_pulley_runout, 0.0, 0.5)?;
        check("output_drum_runout", self.output_drum_runout, 0.0, 0.5)?;
        check(
            "input_pulley_runout_phase_rad",
            self.input_pulley_runout_phase_rad,
            -10.0,
            10.0,
        )?;
        check(
            "output_drum_runout_phase_rad",
            self.output_drum_runout_phase_rad,
            -10.0,
            10.0,
        )?;
        check("encoder_delay_s", self.encoder_delay_s, -1.0, 1.0)?;
        check("encoder_scale_error", self.encoder_scale_error, -0.5, 0.5)?;
        check(
            "preload_relaxation_per_s",
            self.preload_relaxation_per_s,
            0.0,
            1.0,
        )?;
        check("bearing_friction_nm", self.bearing_friction_nm, 0.0, 1e4)?;
        check("cable_transport_rad", self.cable_transport_rad, 0.0, 100.0)?;
        check(
            "thermal_drift_rad_per_s",
            self.thermal_drift_rad_per_s,
            -1.0,
            1.0,
        )?;
        check(
            "load_compliance_rad_per_nm",
            self.load_compliance_rad_per_nm,
            0.0,
            100.0,
        )?;
        if let Some(c) = &self.angle_dependent_ratio_coefs {
            if c.len() != 3 || c.iter().any(|v| !(v.is_finite() && v.abs() <= 1.0)) {
                return Err((
                    "angle_dependent_ratio_coefs".into(),
                    "must be 3 finite numbers (rad) of magnitude <= 1".into(),
                ));
            }
            match self.angle_dependent_ratio_stroke_rad {
                Some([a, b]) if a.is_finite() && b.is_finite() && a < b => {}
                _ => {
                    return Err((
                        "angle_dependent_ratio_stroke_rad".into(),
                        "needed with angle_dependent_ratio_coefs: [low, high] finite, low < high"
                            .into(),
                    ))
                }
            }
        }
        match (
            &self.friction_memory_thresholds_rad,
            &self.friction_memory_weights,
        ) {
            (None, None) => {}
            (Some(r), Some(w))
                if r.len() == w.len()
                    && r.iter().all(|v| v.is_finite() && *v > 0.0)
                    && w.iter().all(|v| v.is_finite() && *v >= 0.0 && *v <= 10.0) => {}
            _ => {
                return Err((
                    "friction_memory_weights".into(),
                    "friction_memory_thresholds_rad (> 0) and friction_memory_weights (0 to 10) must both be given, of equal length".into(),
                ))
            }
        }
        check(
            "friction_memory_load_exponent",
            self.friction_memory_load_exponent,
            0.5,
            8.0,
        )?;
        if let Some(v) = &self.friction_memory_load_weights_per_nm {
            let n = self
                .friction_memory_thresholds_rad
                .as_ref()
                .map_or(0, |r| r.len());
            // Per (N m)^p: a steep growth (large p) on jaw torques well below 1 N m needs
            // weights in the thousands.
            if v.len() != n || v.iter().any(|x| !(x.is_finite() && *x >= 0.0 && *x <= 1e9)) {
                return Err((
                    "friction_memory_load_weights_per_nm".into(),
                    format!("needs one weight (0 to 1e9 per (N m)^p) per threshold ({n})"),
                ));
            }
        }
        Ok(())
    }
}

/// Kinematic effect error and its partial derivatives at one state (see
/// [`EffectsParams::kinematic_error`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct KinematicError {
    /// Added transmission error `theta_out - theta_in/ic`, rad.
    pub value_rad: f64,
    /// Derivative with respect to the input (pulley) angle, rad/rad.
    pub d_theta_in: f64,
    /// Derivative with respect to the output (drum) angle, rad/rad.
    pub d_theta_out: f64,
    /// Derivative with respect to time, rad/s.
    pub d_t: f64,
}

impl EffectsParams {
    /// Whether any effect that moves the output relative to the input (runouts, thermal
    /// drift) is present with a nonzero size.
    pub fn has_kinematic(&self) -> bool {
        let nz = |v: Option<f64>| v.is_some_and(|x| x != 0.0);
        nz(self.input_pulley_runout)
            || nz(self.output_drum_runout)
            || nz(self.thermal_drift_rad_per_s)
    }

    /// Unmeasured Coulomb torque at the drum, N m (0 when absent).
    pub fn bearing_friction(&self) -> f64 {
        self.bearing_friction_nm.unwrap_or(0.0)
    }

    /// Transmission error the kinematic effects add at input angle `theta_in` (rad),
    /// output angle `theta_out` (rad) and time `t_s` (s), for the radius ratio
    /// `ratio = ro/ri` (physics.md section 7), with its partial derivatives:
    ///
    /// ```text
    /// e = (eps_i/ic)*(sin(theta_in + phi_i) - sin(phi_i))      input pulley runout
    ///   + eps_o*(sin(theta_out + phi_o) - sin(phi_o))           output drum runout
    ///   + drift*t                                               thermal drift
    /// ```
    ///
    /// Absent effects contribute nothing; absent phases are 0.
    pub fn kinematic_error(
        &self,
        theta_in: f64,
        theta_out: f64,
        t_s: f64,
        ratio: f64,
    ) -> KinematicError {
        let mut k = KinematicError::default();
        if let Some(eps) = self.input_pulley_runout {
            let phi = self.input_pulley_runout_phase_rad.unwrap_or(0.0);
            let a = eps / ratio;
            k.value_rad += a * ((theta_in + phi).sin() - phi.sin());
            k.d_theta_in += a * (theta_in + phi).cos();
        }
        if let Some(eps) = self.output_drum_runout {
            let phi = self.output_drum_runout_phase_rad.unwrap_or(0.0);
            k.value_rad += eps * ((theta_out + phi).sin() - phi.sin());
            k.d_theta_out += eps * (theta_out + phi).cos();
        }
        if let Some(rate) = self.thermal_drift_rad_per_s {
            k.value_rad += rate * t_s;
            k.d_t += rate;
        }
        k
    }

    /// Value of [`EffectsParams::kinematic_error`], rad.
    pub fn kinematic_error_rad(&self, theta_in: f64, theta_out: f64, t_s: f64, ratio: f64) -> f64 {
        self.kinematic_error(theta_in, theta_out, t_s, ratio)
            .value_rad
    }
}

#[cfg(test)]
mod kinematic_tests {
    use super::*;

    #[test]
    fn kinematic_error_matches_closed_forms_and_slopes() {
        let fx = EffectsParams {
            input_pulley_runout: Some(0.01),
            input_pulley_runout_phase_rad: Some(0.3),
            output_drum_runout: Some(5e-4),
            output_drum_runout_phase_rad: Some(-1.0),
            thermal_drift_rad_per_s: Some(2e-6),
            ..EffectsParams::default()
        };
        let (ti, to, t, ic) = (1.7, 0.4, 3.0, 5.125);
        let k = fx.kinematic_error(ti, to, t, ic);
        let e = (0.01 / ic) * ((ti + 0.3f64).sin() - 0.3f64.sin())
            + 5e-4 * ((to - 1.0f64).sin() - (-1.0f64).sin())
            + 2e-6 * t;
        assert!((k.value_rad - e).abs() < 1e-15);
        let h = 1e-6;
        let f = |a: f64, b: f64, c: f64| fx.kinematic_error_rad(a, b, c, ic);
        let num_in = (f(ti + h, to, t) - f(ti - h, to, t)) / (2.0 * h);
        let num_out = (f(ti, to + h, t) - f(ti, to - h, t)) / (2.0 * h);
        let num_t = (f(ti, to, t + h) - f(ti, to, t - h)) / (2.0 * h);
        assert!((k.d_theta_in - num_in).abs() < 1e-9);
        assert!((k.d_theta_out - num_out).abs() < 1e-9);
        assert!((k.d_t - num_t).abs() < 1e-9);
        // Zero at zero angles and time; nothing when absent.
        assert_eq!(fx.kinematic_error_rad(0.0, 0.0, 0.0, ic), 0.0);
        assert!(!EffectsParams::default().has_kinematic());
        assert_eq!(
            EffectsParams::default().kinematic_error_rad(ti, to, t, ic),
            0.0
        );
    }
}
