//! Physical effects beyond the base capstan model that a plant can carry and a compensator
//! can predict: pulley and drum runout, thermal drift, bearing friction, and the effects of
//! a multi-wrap instrument drive (ratio shape over the stroke, load compliance, friction
//! memory spread over many contacts). One formula serves the closed-loop plant, its
//! compensator and the diagnosis of bench logs.

use serde::{Deserialize, Serialize};

/// `[effects]`: identified effects the closed loop can compensate. Absent keys mean the
/// effect is not present.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectsParams {
    /// Input pulley eccentricity over radius.
    /// Allowed: 0 to 0.5.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_pulley_runout: Option<f64>,
    /// Phase `phi` of the input runout, rad.
    /// Allowed: -10 to 10.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub input_pulley_runout_phase_rad: Option<f64>,
    /// Output drum eccentricity over radius.
    /// Allowed: 0 to 0.5.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_drum_runout: Option<f64>,
    /// Phase `phi` of the drum runout, rad.
    /// Allowed: -10 to 10.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_drum_runout_phase_rad: Option<f64>,
    /// Output encoder lag, s.
    /// Allowed: -1 to 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoder_delay_s: Option<f64>,
    /// Output encoder scale error `s` (reading = (1+s) angle).
    /// Allowed: -0.5 to 0.5.
    /// Unit: 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoder_scale_error: Option<f64>,
    /// Preload loss rate, fraction of the initial preload per second: positive, the preload
    /// falls through the record (relaxation); negative, it rises.
    /// Allowed: -1 to 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preload_relaxation_per_s: Option<f64>,
    /// Unmeasured Coulomb torque at the drum, N m.
    /// Allowed: 0 to 1e4.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bearing_friction_nm: Option<f64>,
    /// Input travel over which the error settles after a reversal, rad.
    /// Allowed: 0 to 100.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cable_transport_rad: Option<f64>,
    /// Drift of the error with time, rad/s.
    /// Allowed: -1 to 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thermal_drift_rad_per_s: Option<f64>,
    /// Ratio shape: Legendre coefficients of `P_2, P_3, P_4` of the input angle scaled to
    /// `angle_dependent_ratio_stroke_rad`, rad of output error.
    /// Allowed: three numbers, each -1 to 1; needs `angle_dependent_ratio_stroke_rad`.
    /// Unit: rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_dependent_ratio_coefs: Option<Vec<f64>>,
    /// Input stroke `[low, high]` the ratio shape is defined over, rad.
    /// Allowed: `[low, high]`, finite, low below high.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_dependent_ratio_stroke_rad: Option<[f64; 2]>,
    /// Output deflection per transmitted torque `M` beyond the spans, rad/(N m): `+c M`
    /// on the output angle. Negative: the output gives way with the load like a flexible
    /// link, adding to the spans' stretch (a jaw or pin, typically -1e-4 to -1e-2 on
    /// instruments); positive: the drive is stiffer under a steady load than the cable
    /// model (3.41 for the da Vinci jaw). The closed loop puts it, with the friction
    /// memory, in a massless link between the drum and the output sensor.
    /// Allowed: -100 to 100.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub load_compliance_rad_per_nm: Option<f64>,
    /// Play thresholds of the distributed friction memory, rad of input.
    /// Allowed: each > 0; as many as `friction_memory_weights`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_thresholds_rad: Option<Vec<f64>>,
    /// Their weights, output rad per input rad (non-negative).
    /// Allowed: each 0 to 10; as many as `friction_memory_thresholds_rad`.
    /// Unit: rad/rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_weights: Option<Vec<f64>>,
    /// Growth of the weights with the transmitted torque's magnitude `|M|^p`, per (N m)^p
    /// with `p` = `friction_memory_load_exponent` (non-negative; friction at a contact
    /// grows with the tension pressing on it).
    /// Allowed: each 0 to 1e9; one per threshold.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_load_weights_per_nm: Option<Vec<f64>>,
    /// Exponent `p` of that growth: the load-scaled weights multiply `|M|^p` (absent: 1,
    /// growth proportional to the torque).
    /// Allowed: 0.5 to 8.
    /// Unit: 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_load_exponent: Option<f64>,
    /// Growth `beta` of every contact's slip threshold with the transmitted torque's
    /// magnitude: threshold `r_j (1 + beta |M|)` (the normal force on a wrap contact is the
    /// local cable tension, preload plus the load's share). 0 or absent: fixed thresholds;
    /// 4.16 for the da Vinci jaw.
    /// Allowed: 0 to 1e4.
    /// Unit: 1/(N m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_threshold_growth_per_nm: Option<f64>,
    /// Free travel of slack and clearances at no load, rad of input: a play whose width
    /// `s (1 - |M|/M_u)` shrinks as tension takes it up, to nothing at
    /// `friction_memory_slack_taken_up_nm` (`M_u`). Needs the other two slack keys; 0.211
    /// (weighing 0.076) for the da Vinci jaw.
    /// Allowed: 0 to 10.
    /// Unit: rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_slack_rad: Option<f64>,
    /// Torque magnitude `M_u` at which the slack is taken up, N m (a fraction of the working
    /// torque; 0.0298 N m for the da Vinci jaw).
    /// Allowed: above 0, up to 1e4.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_slack_taken_up_nm: Option<f64>,
    /// Weight of the slack's play, output rad per input rad (1/ratio for free travel of the
    /// input alone; non-negative).
    /// Allowed: 0 to 10.
    /// Unit: rad/rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_memory_slack_weight: Option<f64>,
}

/// Slip threshold of a friction contact under transmitted torque `m_nm` (N m): its
/// no-load threshold `r0` (rad of input) times `1 + growth |M|` (`growth` in 1/(N m)).
/// Only the torque's magnitude counts: a drive loaded the other way presses its contacts
/// as hard.
pub fn contact_threshold(r0: f64, growth: f64, m_nm: f64) -> f64 {
    r0 * (1.0 + growth * m_nm.abs())
}

/// Width of the slack's play under transmitted torque `m_nm` (N m): `slack (1 -
/// |M|/taken_up)` down to 0 at `taken_up` (N m) and beyond (rad of input).
pub fn slack_width(slack: f64, taken_up: f64, m_nm: f64) -> f64 {
    if taken_up > 0.0 {
        slack * (1.0 - m_nm.abs() / taken_up).max(0.0)
    } else {
        0.0
    }
}

impl EffectsParams {
    /// Check ranges; returns `(key below effects, message)`.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let check = |key: &str, v: Option<f64>, lo: f64, hi: f64| match v {
            Some(x) if !(x.is_finite() && x >= lo && x <= hi) => Err((
                key.to_string(),
                crate::out_of_range(
                    x,
                    &format!(
                        "a finite number in [{}, {}]",
                        crate::number(lo),
                        crate::number(hi)
                    ),
                ),
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
            -1.0,
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
            -100.0,
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
        check(
            "friction_memory_threshold_growth_per_nm",
            self.friction_memory_threshold_growth_per_nm,
            0.0,
            1e4,
        )?;
        check(
            "friction_memory_slack_rad",
            self.friction_memory_slack_rad,
            0.0,
            10.0,
        )?;
        check(
            "friction_memory_slack_weight",
            self.friction_memory_slack_weight,
            0.0,
            10.0,
        )?;
        check(
            "friction_memory_slack_taken_up_nm",
            self.friction_memory_slack_taken_up_nm,
            f64::MIN_POSITIVE,
            1e4,
        )?;
        let slack = [
            self.friction_memory_slack_rad.is_some(),
            self.friction_memory_slack_taken_up_nm.is_some(),
            self.friction_memory_slack_weight.is_some(),
        ];
        if slack.iter().any(|b| *b) && !slack.iter().all(|b| *b) {
            return Err((
                "friction_memory_slack_rad".into(),
                "friction_memory_slack_rad, friction_memory_slack_taken_up_nm and friction_memory_slack_weight go together: give all three or none".into(),
            ));
        }
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
    /// drift, ratio shape) is present with a nonzero size.
    pub fn has_kinematic(&self) -> bool {
        let nz = |v: Option<f64>| v.is_some_and(|x| x != 0.0);
        nz(self.input_pulley_runout)
            || nz(self.output_drum_runout)
            || nz(self.thermal_drift_rad_per_s)
            || self.ratio_shape().is_some()
    }

    /// Ratio shape as `(Legendre coefficients of P_2.., stroke)` when present and nonzero.
    fn ratio_shape(&self) -> Option<(&[f64], (f64, f64))> {
        match (
            &self.angle_dependent_ratio_coefs,
            self.angle_dependent_ratio_stroke_rad,
        ) {
            (Some(c), Some([lo, hi])) if c.iter().any(|v| *v != 0.0) && hi > lo => {
                Some((c.as_slice(), (lo, hi)))
            }
            _ => None,
        }
    }

    /// Output deflection per transmitted torque of the jaw link, rad/(N m) (0 when absent).
    pub fn load_compliance(&self) -> f64 {
        self.load_compliance_rad_per_nm.unwrap_or(0.0)
    }

    /// Whether the friction memory of many contacts is present with a nonzero weight.
    pub fn has_friction_memory(&self) -> bool {
        let nz = |v: &Option<Vec<f64>>| v.as_ref().is_some_and(|w| w.iter().any(|x| *x != 0.0));
        (self.friction_memory_thresholds_rad.is_some()
            && (nz(&self.friction_memory_weights) || nz(&self.friction_memory_load_weights_per_nm)))
            || self.slack().is_some()
    }

    /// The slack's `(width at no load, rad; torque that takes it up, N m; weight, rad/rad)`
    /// when present with a nonzero size.
    fn slack(&self) -> Option<(f64, f64, f64)> {
        match (
            self.friction_memory_slack_rad,
            self.friction_memory_slack_taken_up_nm,
            self.friction_memory_slack_weight,
        ) {
            (Some(s), Some(m), Some(w)) if s > 0.0 && m > 0.0 && w > 0.0 => Some((s, m, w)),
            _ => None,
        }
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
    ///   + sum_k c_k P_(k+2)(u),  u = 2 (theta_in - lo)/(hi - lo) - 1   ratio shape
    /// ```
    ///
    /// Absent effects contribute nothing; absent phases are 0. The ratio shape is known only
    /// over the calibrated stroke `[lo, hi]`: outside it the ratio keeps its value at the
    /// nearer end (the error continues along its end slope) rather than following a
    /// polynomial nobody measured; the slope stays continuous, so the cable's lever arm
    /// does not jump at the ends.
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
        if let Some((c, stroke)) = self.ratio_shape() {
            let u = scaled(theta_in, stroke);
            let du = 2.0 / (stroke.1 - stroke.0);
            // Inside the stroke `past` is 0; outside, the end's value continues along the
            // end's slope.
            let end = u.clamp(-1.0, 1.0);
            let past = (u - end) / du;
            for (j, cj) in c.iter().enumerate() {
                let slope = cj * legendre_slope(j + 2, end) * du;
                k.value_rad += cj * legendre(j + 2, end) + slope * past;
                k.d_theta_in += slope;
            }
        }
        k
    }

    /// Value of [`EffectsParams::kinematic_error`], rad.
    pub fn kinematic_error_rad(&self, theta_in: f64, theta_out: f64, t_s: f64, ratio: f64) -> f64 {
        self.kinematic_error(theta_in, theta_out, t_s, ratio)
            .value_rad
    }
}

/// Legendre polynomial `P_k(u)` for k = 0..=5 (higher orders give `P_5`).
pub fn legendre(k: usize, u: f64) -> f64 {
    let u2 = u * u;
    match k {
        0 => 1.0,
        1 => u,
        2 => 0.5 * (3.0 * u2 - 1.0),
        3 => 0.5 * u * (5.0 * u2 - 3.0),
        4 => (35.0 * u2 * u2 - 30.0 * u2 + 3.0) / 8.0,
        _ => u * (63.0 * u2 * u2 - 70.0 * u2 + 15.0) / 8.0,
    }
}

/// Derivative `dP_k/du` of [`legendre`].
pub fn legendre_slope(k: usize, u: f64) -> f64 {
    let u2 = u * u;
    match k {
        0 => 0.0,
        1 => 1.0,
        2 => 3.0 * u,
        3 => 0.5 * (15.0 * u2 - 3.0),
        4 => (140.0 * u2 * u - 60.0 * u) / 8.0,
        _ => (315.0 * u2 * u2 - 210.0 * u2 + 15.0) / 8.0,
    }
}

/// Input angle `theta_in` (rad) scaled to [-1, 1] over the stroke `(lo, hi)` (rad).
pub fn scaled(theta_in: f64, stroke: (f64, f64)) -> f64 {
    2.0 * (theta_in - stroke.0) / (stroke.1 - stroke.0) - 1.0
}

/// Friction memory spread over many contacts (a Prandtl-Ishlinskii sum of play operators on
/// the input angle), with its play states. Each contact sticks until the input has moved its
/// threshold `r_j (1 + beta |M|)` past a reversal; its lag `P_r(theta_in) - theta_in` weighs
/// `w_j + wl_j |M|^p` output rad per input rad, `M` the transmitted torque (N m). The
/// slack, when present, is one more play whose width shrinks with `|M|` (see
/// [`slack_width`]). Only magnitudes of the torque enter.
#[derive(Clone, Debug, PartialEq)]
pub struct ContactMemory {
    thresholds: Vec<f64>,
    weights: Vec<f64>,
    load_weights: Vec<f64>,
    load_exponent: f64,
    /// Threshold growth with `|M|`, 1/(N m).
    growth: f64,
    /// Slack: no-load width (rad), take-up torque (N m), weight (rad/rad).
    slack: Option<(f64, f64, f64)>,
    /// Play outputs, rad of input (the slack's last when present).
    state: Vec<f64>,
}

impl ContactMemory {
    /// From `[effects]` (`None` without a friction memory), every play centred on the
    /// input angle `theta_in` (rad): no lag at the start, as in the calibration.
    pub fn new(fx: &EffectsParams, theta_in: f64) -> Option<Self> {
        if !fx.has_friction_memory() {
            return None;
        }
        let thresholds = fx
            .friction_memory_thresholds_rad
            .clone()
            .unwrap_or_default();
        let n = thresholds.len();
        let weights = fx
            .friction_memory_weights
            .clone()
            .unwrap_or_else(|| vec![0.0; n]);
        let load_weights = fx
            .friction_memory_load_weights_per_nm
            .clone()
            .unwrap_or_else(|| vec![0.0; n]);
        let slack = fx.slack();
        Some(ContactMemory {
            state: vec![theta_in; n + usize::from(slack.is_some())],
            thresholds,
            weights,
            load_weights,
            load_exponent: fx.friction_memory_load_exponent.unwrap_or(1.0),
            growth: fx.friction_memory_threshold_growth_per_nm.unwrap_or(0.0),
            slack,
        })
    }

    /// Every play's `(half width, rad of input; weight, rad/rad)` under torque `m_nm`.
    fn plays(&self, m_nm: f64) -> impl Iterator<Item = (f64, f64)> + '_ {
        let f = m_nm.abs().powf(self.load_exponent);
        self.thresholds
            .iter()
            .zip(self.weights.iter().zip(&self.load_weights))
            .map(move |(r, (w, wl))| (contact_threshold(*r, self.growth, m_nm), w + wl * f))
            .chain(self.slack.map(|(s, mu, w)| (slack_width(s, mu, m_nm), w)))
    }

    /// Output lag (rad, negative behind the input's direction of travel) at input angle
    /// `theta_in` (rad) under transmitted torque `m_nm`, on the committed play states.
    pub fn lag_rad(&self, theta_in: f64, m_nm: f64) -> f64 {
        self.lag_and_slope(theta_in, m_nm).0
    }

    /// [`ContactMemory::lag_rad`] and its slope with respect to `theta_in` (rad/rad): a
    /// sticking contact (its play not at either edge) lags by `-w` per input rad, a
    /// sliding one no further.
    pub fn lag_and_slope(&self, theta_in: f64, m_nm: f64) -> (f64, f64) {
        let mut lag = 0.0;
        let mut slope = 0.0;
        for ((r, weight), y) in self.plays(m_nm).zip(&self.state) {
            let p = y.clamp(theta_in - r, theta_in + r);
            lag += weight * (p - theta_in);
            if (y - theta_in).abs() < r {
                slope -= weight;
            }
        }
        (lag, slope)
    }

    /// Move every play to input angle `theta_in` (rad) under torque `m_nm` (N m) and
    /// return the lag there.
    pub fn commit(&mut self, theta_in: f64, m_nm: f64) -> f64 {
        for j in 0..self.state.len() {
            let r = match self.thresholds.get(j) {
                Some(r0) => contact_threshold(*r0, self.growth, m_nm),
                None => self
                    .slack
                    .map_or(0.0, |(s, mu, _)| slack_width(s, mu, m_nm)),
            };
            self.state[j] = self.state[j].clamp(theta_in - r, theta_in + r);
        }
        self.lag_rad(theta_in, m_nm)
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

    fn shaped() -> EffectsParams {
        EffectsParams {
            angle_dependent_ratio_coefs: Some(vec![2e-3, -5e-3, 1e-3]),
            angle_dependent_ratio_stroke_rad: Some([0.2, 1.2]),
            ..EffectsParams::default()
        }
    }

    #[test]
    fn ratio_shape_is_its_legendre_terms_inside_the_stroke_and_a_constant_ratio_outside() {
        let fx = shaped();
        assert!(fx.has_kinematic());
        let closed = |th: f64| {
            let u = 2.0 * (th - 0.2) / 1.0 - 1.0;
            2e-3 * 0.5 * (3.0 * u * u - 1.0) - 5e-3 * 0.5 * u * (5.0 * u * u - 3.0)
                + 1e-3 * (35.0 * u.powi(4) - 30.0 * u * u + 3.0) / 8.0
        };
        let e = |th: f64| fx.kinematic_error(th, 0.0, 0.0, 3.0);
        for th in [0.2, 0.35, 0.7, 1.01, 1.2] {
            assert!((e(th).value_rad - closed(th)).abs() < 1e-15, "{th}");
        }
        // Slopes against central differences, inside and outside.
        for th in [0.31, 0.7, 1.13, -0.5, 0.1, 1.5, 3.0] {
            let h = 1e-6;
            let num = (e(th + h).value_rad - e(th - h).value_rad) / (2.0 * h);
            assert!((e(th).d_theta_in - num).abs() < 1e-8, "{th}");
        }
        // Outside the stroke the error continues along its end slope: value and slope
        // are continuous at both ends, so the cable's lever arm never jumps.
        for end in [0.2, 1.2] {
            let (a, b) = (e(end - 1e-9), e(end + 1e-9));
            assert!((a.value_rad - b.value_rad).abs() < 1e-9);
            assert!((a.d_theta_in - b.d_theta_in).abs() < 1e-6);
            let far = e(end + if end > 1.0 { 0.5 } else { -0.5 });
            assert!((far.d_theta_in - e(end).d_theta_in).abs() < 1e-12);
        }
        // A zero shape is no shape.
        let zero = EffectsParams {
            angle_dependent_ratio_coefs: Some(vec![0.0; 3]),
            ..shaped()
        };
        assert!(!zero.has_kinematic());
    }

    /// An independent play operator: the output follows the input only once it is `r` away.
    fn play_path(x: &[f64], r: f64) -> Vec<f64> {
        let mut y = x[0];
        x.iter()
            .map(|v| {
                if *v > y + r {
                    y = v - r;
                } else if *v < y - r {
                    y = v + r;
                }
                y
            })
            .collect()
    }

    /// Turning the other way under a load the other way is the same physics: mirrored
    /// input and mirrored torque give the mirrored lag, and the law reads only `|M|`.
    #[test]
    fn contact_memory_law_is_mirror_symmetric() {
        let fx = EffectsParams {
            friction_memory_thresholds_rad: Some(vec![0.01, 0.04]),
            friction_memory_weights: Some(vec![0.3, 0.2]),
            friction_memory_threshold_growth_per_nm: Some(9.0),
            friction_memory_slack_rad: Some(0.05),
            friction_memory_slack_taken_up_nm: Some(0.04),
            friction_memory_slack_weight: Some(0.5),
            ..EffectsParams::default()
        };
        assert_eq!(fx.validate(), Ok(()));
        let mut up = ContactMemory::new(&fx, 0.0).unwrap();
        let mut down = ContactMemory::new(&fx, 0.0).unwrap();
        let mut checked = 0.0f64;
        for k in 0..3000 {
            let t = k as f64 * 0.01;
            let x = 0.5 * (0.7 * t).sin() + 0.02 * (5.3 * t).sin();
            let m = 0.06 + 0.05 * (0.3 * t).sin();
            let a = up.commit(x, m);
            let b = down.commit(-x, -m);
            assert!((a + b).abs() < 1e-15, "{k}: {a} vs {b}");
            let (la, sa) = up.lag_and_slope(x + 0.003, -m);
            let (lb, sb) = down.lag_and_slope(-x - 0.003, m);
            assert!((la + lb).abs() < 1e-15 && (sa - sb).abs() < 1e-15);
            checked = checked.max(a.abs());
        }
        assert!(checked > 0.01, "{checked}");
        // Thresholds grow with the magnitude of the torque, the slack shrinks to nothing.
        assert_eq!(
            contact_threshold(0.01, 9.0, -0.1),
            contact_threshold(0.01, 9.0, 0.1)
        );
        assert!((contact_threshold(0.01, 9.0, 0.1) - 0.019).abs() < 1e-15);
        assert_eq!(
            slack_width(0.05, 0.04, -0.02),
            slack_width(0.05, 0.04, 0.02)
        );
        assert_eq!(slack_width(0.05, 0.04, 0.05), 0.0);
        // Slack keys go together.
        let partial = EffectsParams {
            friction_memory_slack_weight: None,
            ..fx
        };
        assert_eq!(
            partial.validate().map_err(|e| e.0),
            Err("friction_memory_slack_rad".to_string())
        );
    }

    #[test]
    fn contact_memory_is_the_weighted_sum_of_plays_and_its_slope_is_exact() {
        let fx = EffectsParams {
            friction_memory_thresholds_rad: Some(vec![0.01, 0.04, 0.1]),
            friction_memory_weights: Some(vec![0.2, 0.0, 0.3]),
            friction_memory_load_weights_per_nm: Some(vec![0.0, 50.0, 0.0]),
            friction_memory_load_exponent: Some(2.0),
            ..EffectsParams::default()
        };
        assert!(fx.has_friction_memory());
        let m_nm = -0.1;
        let x: Vec<f64> = (0..2000)
            .map(|k| {
                let t = k as f64 * 0.01;
                0.5 * (1.3 * t).sin() + 0.03 * (7.1 * t).sin()
            })
            .collect();
        let mut memory = ContactMemory::new(&fx, x[0]).unwrap();
        let plays: Vec<Vec<f64>> = [0.01, 0.04, 0.1]
            .iter()
            .map(|r| play_path(&x, *r))
            .collect();
        let w = [0.2, 50.0 * 0.01, 0.3];
        for (i, xi) in x.iter().enumerate() {
            // The lag ahead of a commit is the lag after it.
            let ahead = memory.lag_rad(*xi, m_nm);
            let lag = memory.commit(*xi, m_nm);
            assert!((ahead - lag).abs() < 1e-15);
            let want: f64 = (0..3).map(|j| w[j] * (plays[j][i] - xi)).sum();
            assert!((lag - want).abs() < 1e-12, "{i}: {lag} vs {want}");
            if i % 97 == 0 {
                let h = 1e-7;
                let (_, slope) = memory.lag_and_slope(*xi + 3.0 * h, m_nm);
                let num = (memory.lag_rad(*xi + 4.0 * h, m_nm)
                    - memory.lag_rad(*xi + 2.0 * h, m_nm))
                    / (2.0 * h);
                assert!((slope - num).abs() < 1e-6, "{i}: {slope} vs {num}");
            }
        }
        // No memory without weights.
        let none = EffectsParams {
            friction_memory_weights: Some(vec![0.0; 3]),
            friction_memory_load_weights_per_nm: Some(vec![0.0; 3]),
            ..fx
        };
        assert!(ContactMemory::new(&none, 0.0).is_none());
    }
}
