//! Parameter estimates of a diagnosis: calibrated values with their standard deviations
//! from the fit's covariance, in the units an engineer reads.

use nalgebra::DMatrix;

use super::effects::{EffectName, EffectsParams};
use super::model::{Fitted, LinParam, MemoryLaw, NlParam};
use super::{Diagnosis, ParamEstimate};
use crate::physics::DriveParams;

fn std_of(cov: &DMatrix<f64>, grad: &[(usize, f64)]) -> f64 {
    let mut v = 0.0;
    for (i, gi) in grad {
        for (j, gj) in grad {
            v += gi * gj * cov[(*i, *j)];
        }
    }
    v.max(0.0).sqrt()
}

/// Physical parameters from a fit: calibrated drive, effects, and the table with stds.
pub(crate) fn parameters(
    drive0: &DriveParams,
    drive_nl: &DriveParams,
    nl: &[(NlParam, f64, f64, f64)],
    fit: &Fitted,
    cov: &DMatrix<f64>,
) -> (Vec<ParamEstimate>, DriveParams, EffectsParams) {
    let mut out = Vec::new();
    let mut drive = drive_nl.clone();
    let mut eff = EffectsParams::default();
    let nn = nl.len();
    let lin = |p: LinParam| {
        fit.lin
            .iter()
            .position(|q| *q == p)
            .map(|i| (nn + i, fit.coef[i]))
    };
    for (k, n) in nl.iter().enumerate() {
        let v = fit.x[k];
        let s = std_of(cov, &[(k, 1.0)]);
        let unit = match n.0 {
            NlParam::Mu => "1",
            NlParam::Preload => "N",
            NlParam::Effect(EffectName::BearingFriction) => {
                eff.bearing_friction_nm = Some(v);
                "N m"
            }
            NlParam::Effect(EffectName::PreloadRelaxation) => {
                eff.preload_relaxation_per_s = Some(v);
                "1/s"
            }
            NlParam::Effect(EffectName::CableTransport) => {
                eff.cable_transport_rad = Some(v);
                "rad (input travel)"
            }
            NlParam::Effect(EffectName::DistributedFrictionMemory) => {
                eff.friction_memory_load_exponent = Some(v);
                "1 (lag growth as |torque|^p)"
            }
            NlParam::Memory(MemoryLaw::Growth) => {
                eff.friction_memory_threshold_growth_per_nm = Some(v);
                "1/(N m) (contact thresholds grow as 1 + beta |torque|)"
            }
            NlParam::Memory(MemoryLaw::Slack) => {
                eff.friction_memory_slack_rad = Some(v);
                "rad of input (free travel at no load)"
            }
            NlParam::Memory(MemoryLaw::TakenUp) => {
                eff.friction_memory_slack_taken_up_nm = Some(v);
                "N m (torque that takes the slack up)"
            }
            NlParam::Effect(_) => continue,
        };
        out.push(ParamEstimate::new(n.0.name(), v, s, unit));
    }
    if let Some((i, c)) = lin(LinParam::ModulusScale) {
        let g = drive0.cable_modulus_n / c.max(1e-12);
        drive.cable_modulus_n = g;
        out.push(ParamEstimate::new(
            "cable_modulus_n",
            g,
            std_of(cov, &[(i, g / c.max(1e-12))]),
            "N",
        ));
    }
    let mut ic = drive0.ratio();
    if let Some((i, d)) = lin(LinParam::InverseRatio) {
        ic = 1.0 / (1.0 / ic + d);
        drive.pulley_radius_m = drive.drum_radius_m / ic;
        out.push(ParamEstimate::new(
            "ratio",
            ic,
            std_of(cov, &[(i, ic * ic)]),
            "1",
        ));
    }
    let pair = |e: EffectName, scale: f64| -> Option<(f64, f64, f64, f64)> {
        let (i, a) = lin(LinParam::Effect(e, 0))?;
        let (j, b) = lin(LinParam::Effect(e, 1))?;
        let h = a.hypot(b).max(1e-300);
        let amp = scale * h;
        let s = std_of(cov, &[(i, scale * a / h), (j, scale * b / h)]);
        let ph = b.atan2(a);
        let sp = std_of(cov, &[(i, -b / (h * h)), (j, a / (h * h))]);
        Some((amp, s, ph, sp))
    };
    // A runout is fitted as two quadrature terms; it is reported as amplitude and phase.
    let mut push_runout = |name: &str, (v, s, ph, sp): (f64, f64, f64, f64)| {
        out.push(ParamEstimate::new(name, v, s, "1 (eccentricity/radius)"));
        out.push(ParamEstimate::new(format!("{name}_phase"), ph, sp, "rad"));
        (v, ph)
    };
    if let Some(fit) = pair(EffectName::InputPulleyRunout, ic) {
        let (v, ph) = push_runout("input_pulley_runout", fit);
        eff.input_pulley_runout = Some(v);
        eff.input_pulley_runout_phase_rad = Some(ph);
    }
    if let Some(fit) = pair(EffectName::OutputDrumRunout, 1.0) {
        let (v, ph) = push_runout("output_drum_runout", fit);
        eff.output_drum_runout = Some(v);
        eff.output_drum_runout_phase_rad = Some(ph);
    }
    for (e, unit) in [
        (EffectName::EncoderDelay, "s"),
        (EffectName::EncoderScaleError, "1"),
        (EffectName::ThermalDrift, "rad/s"),
    ] {
        if let Some((i, v)) = lin(LinParam::Effect(e, 0)) {
            match e {
                EffectName::EncoderDelay => eff.encoder_delay_s = Some(v),
                EffectName::EncoderScaleError => eff.encoder_scale_error = Some(v),
                _ => eff.thermal_drift_rad_per_s = Some(v),
            }
            out.push(ParamEstimate::new(
                e.to_string(),
                v,
                std_of(cov, &[(i, 1.0)]),
                unit,
            ));
        }
    }
    for (k, p) in fit.lin.iter().enumerate() {
        let (name, unit) = match p {
            LinParam::Offset(l) => (format!("encoder_zero[{l}]"), "rad"),
            // A log's own part of a term the calibrated instrument carries, added to it.
            LinParam::PerLog(e, l) => (format!("{e}_per_log[{l}]"), e.unit()),
            _ => continue,
        };
        out.push(ParamEstimate::new(
            name,
            fit.coef[k],
            std_of(cov, &[(nn + k, 1.0)]),
            unit,
        ));
    }
    (out, drive, eff)
}

/// Size of an effect in a diagnosis, by name (None when not identified).
pub fn effect_value(d: &Diagnosis, e: EffectName) -> Option<f64> {
    d.params
        .iter()
        .find(|p| p.name == e.as_str())
        .map(|p| p.value)
}
