//! Error budget: which effect costs how much of the line-of-sight error.
//!
//! The run is repeated with each effect present in the setup switched off in turn (cable
//! backlash -> the linear cable, brake friction, unbalance, base motion, sensor
//! quantisation and noise, external disturbance torques), and once with all of them off.
//! An effect's contribution is the part of the mean square it removes,
//!
//! ```text
//! c_i = sqrt(max(0, rms_total^2 - rms_without_i^2)),    RSS = sqrt(sum c_i^2 + rms_rest^2)
//! ```
//! where `rms_rest` is what remains with every listed effect off. When the effects do not
//! interact their mean squares add and the RSS equals the total; a RSS far from the total
//! says they do (a friction limit cycle that base motion breaks up, for instance), and the
//! budget then ranks effects rather than adding up.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::closed_loop::params::{CableModel, ClosedLoopParams, CompensationMode};
use crate::closed_loop::sim::{
    run_closed_loop, ClosedLoopError, ClosedLoopSetup, Completion, RunOptions,
};
use crate::physics::{DriveParams, EffectsParams, LoadParams};

/// An effect the budget can switch off.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BudgetEffect {
    /// Capstan hysteresis of the cable (replaced by its linear spring).
    CableBacklash,
    /// Brake or bearing friction on the drum.
    BrakeFriction,
    /// Mass unbalance.
    Unbalance,
    /// Base motion.
    BaseMotion,
    /// Encoder and gyro quantisation, noise and gyro bias.
    Sensors,
    /// External disturbance torques (constant, sine, CSV).
    Disturbance,
}

impl BudgetEffect {
    /// Every effect, in table order.
    pub const ALL: [BudgetEffect; 6] = [
        BudgetEffect::CableBacklash,
        BudgetEffect::BrakeFriction,
        BudgetEffect::Unbalance,
        BudgetEffect::BaseMotion,
        BudgetEffect::Sensors,
        BudgetEffect::Disturbance,
    ];

    /// Name in tables and files.
    pub fn name(self) -> &'static str {
        match self {
            BudgetEffect::CableBacklash => "cable_backlash",
            BudgetEffect::BrakeFriction => "brake_friction",
            BudgetEffect::Unbalance => "unbalance",
            BudgetEffect::BaseMotion => "base_motion",
            BudgetEffect::Sensors => "sensors",
            BudgetEffect::Disturbance => "disturbance",
        }
    }

    /// Whether the setup carries this effect.
    pub fn present(self, s: &Variant) -> bool {
        let (p, l) = (&s.params, &s.load);
        match self {
            BudgetEffect::CableBacklash => p.cable == CableModel::Hysteretic,
            BudgetEffect::BrakeFriction => {
                l.brake_nm != 0.0
                    || l.breakaway_nm() != 0.0
                    || s.effects
                        .as_ref()
                        .is_some_and(|e| e.bearing_friction() != 0.0)
            }
            BudgetEffect::Unbalance => l.unbalance_nm != 0.0,
            BudgetEffect::BaseMotion => p.base_motion.is_some(),
            BudgetEffect::Sensors => {
                let e = &p.sensors;
                e.quantize
                    || e.motor_noise_rad > 0.0
                    || e.output_noise_rad > 0.0
                    || p.gyro.as_ref().is_some_and(|g| {
                        g.noise_density_rad_s_per_sqrt_hz > 0.0
                            || g.bias_rad_s != 0.0
                            || g.quantization_rad_s > 0.0
                    })
            }
            BudgetEffect::Disturbance => {
                l.constant_nm != 0.0 || l.sine_nm != 0.0 || !l.disturbance.is_empty()
            }
        }
    }

    /// Switch the effect off in `s`.
    pub fn remove(self, s: &mut Variant) {
        let (p, l) = (&mut s.params, &mut s.load);
        match self {
            BudgetEffect::CableBacklash => p.cable = CableModel::Linear,
            BudgetEffect::BrakeFriction => {
                l.brake_nm = 0.0;
                l.brake_breakaway_nm = Some(0.0);
                if let Some(e) = s.effects.as_mut() {
                    e.bearing_friction_nm = None;
                }
            }
            BudgetEffect::Unbalance => l.unbalance_nm = 0.0,
            BudgetEffect::BaseMotion => p.base_motion = None,
            BudgetEffect::Sensors => {
                p.sensors.quantize = false;
                p.sensors.motor_noise_rad = 0.0;
                p.sensors.output_noise_rad = 0.0;
                if let Some(g) = p.gyro.as_mut() {
                    g.noise_density_rad_s_per_sqrt_hz = 0.0;
                    g.bias_rad_s = 0.0;
                    g.quantization_rad_s = 0.0;
                }
            }
            BudgetEffect::Disturbance => {
                l.constant_nm = 0.0;
                l.sine_nm = 0.0;
                l.disturbance.clear();
                l.disturbance_csv = None;
            }
        }
    }
}

/// An owned copy of a setup, to change.
#[derive(Clone, Debug)]
pub struct Variant {
    /// Drive.
    pub drive: DriveParams,
    /// Loads.
    pub load: LoadParams,
    /// Plant effects.
    pub effects: Option<EffectsParams>,
    /// Loop.
    pub params: ClosedLoopParams,
}

impl Variant {
    /// Copy of a setup.
    pub fn of(s: &ClosedLoopSetup<'_>) -> Self {
        Variant {
            drive: s.drive.clone(),
            load: s.load.clone(),
            effects: s.effects.cloned(),
            params: s.params.clone(),
        }
    }

    /// Borrowed as a setup.
    pub fn setup(&self) -> ClosedLoopSetup<'_> {
        ClosedLoopSetup {
            drive: &self.drive,
            load: &self.load,
            effects: self.effects.as_ref(),
            params: &self.params,
            instability: super::linear::LinearLoop::new(&self.params, &self.drive).instability(),
        }
    }
}

/// One line of a mode's budget.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BudgetLine {
    /// Effect switched off (`None` for the rest: all of them off).
    pub effect: Option<BudgetEffect>,
    /// RMS line-of-sight error without it, mrad; `None` when that run stopped.
    pub rms_without_mrad: Option<f64>,
    /// Its contribution `sqrt(total^2 - without^2)`, mrad (for the rest: its RMS).
    pub contribution_mrad: Option<f64>,
    /// `ok`, or the stop of the run without it.
    pub status: String,
}

/// The budget of one compensation mode.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModeBudget {
    /// The mode.
    pub mode: CompensationMode,
    /// RMS line-of-sight error with every effect, mrad; `None` when the full run stopped.
    pub total_mrad: Option<f64>,
    /// One line per effect present, then the rest.
    pub lines: Vec<BudgetLine>,
    /// Root sum square of the contributions and the rest, mrad (`None` if any is unknown).
    pub rss_mrad: Option<f64>,
}

/// Error budget of every mode of a setup.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorBudget {
    /// Effects present in the setup, in table order.
    pub effects: Vec<BudgetEffect>,
    /// Per mode.
    pub modes: Vec<ModeBudget>,
}

/// Run the budget: one run per present effect switched off, one with all off, one full
/// run (metrics only; runs side by side on the cores).
pub fn error_budget(setup: &ClosedLoopSetup<'_>) -> Result<ErrorBudget, ClosedLoopError> {
    error_budget_with_progress(setup, &crate::progress::Silent)
}

/// [`error_budget`], reporting each finished run to `progress` (units: closed-loop runs,
/// the number of present effects plus two; each as long as the scenario's run).
pub fn error_budget_with_progress(
    setup: &ClosedLoopSetup<'_>,
    progress: &dyn crate::progress::Progress,
) -> Result<ErrorBudget, ClosedLoopError> {
    let full = Variant::of(setup);
    let effects: Vec<BudgetEffect> = BudgetEffect::ALL
        .into_iter()
        .filter(|e| e.present(&full))
        .collect();
    let mut variants: Vec<Variant> = vec![full.clone()];
    for e in &effects {
        let mut v = full.clone();
        e.remove(&mut v);
        variants.push(v);
    }
    let mut rest = full.clone();
    for e in &effects {
        e.remove(&mut rest);
    }
    variants.push(rest);
    let runs = crate::progress::Counter::new(variants.len(), progress);
    let results = variants
        .par_iter()
        .map(|v| {
            let r = run_closed_loop(&v.setup(), &RunOptions::metrics_only());
            runs.tick();
            r
        })
        .collect::<Result<Vec<_>, _>>()?;
    let rms = |r: &crate::closed_loop::sim::ClosedLoopResult, i: usize| -> (Option<f64>, String) {
        let m = &r.modes[i];
        match &m.completion {
            Completion::Complete => (Some(m.metrics.rms_mrad), "ok".into()),
            c => (None, c.status().into()),
        }
    };
    let modes = (0..results[0].modes.len())
        .map(|i| {
            let (total, _) = rms(&results[0], i);
            let mut lines: Vec<BudgetLine> = effects
                .iter()
                .enumerate()
                .map(|(j, e)| {
                    let (without, status) = rms(&results[j + 1], i);
                    BudgetLine {
                        effect: Some(*e),
                        rms_without_mrad: without,
                        contribution_mrad: total
                            .zip(without)
                            .map(|(t, w)| (t * t - w * w).max(0.0).sqrt()),
                        status,
                    }
                })
                .collect();
            let (rest, status) = rms(&results[effects.len() + 1], i);
            lines.push(BudgetLine {
                effect: None,
                rms_without_mrad: rest,
                contribution_mrad: rest,
                status,
            });
            let rss = lines
                .iter()
                .map(|l| l.contribution_mrad.map(|c| c * c))
                .sum::<Option<f64>>()
                .map(f64::sqrt);
            ModeBudget {
                mode: results[0].modes[i].mode,
                total_mrad: total,
                lines,
                rss_mrad: rss,
            }
        })
        .collect();
    Ok(ErrorBudget { effects, modes })
}
