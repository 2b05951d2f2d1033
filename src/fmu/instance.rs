//! One FMU instance in safe Rust: the FMI 2.0 Co-Simulation state machine, parameters set
//! by the host over the scenario's defaults, and the plant stepped under held inputs.
//!
//! The C functions in [`super::ffi`] only convert arguments and statuses; everything a
//! host can get wrong (call order, values, step sizes) is checked here and answered with
//! an [`FmuError`] carrying the status and a message that says what to change.

use std::collections::BTreeMap;

use super::variables::{
    self, Causality, Inputs, Kind, Outputs, PlantModel, PlantParams, Regime, Values, Variable,
};
use crate::closed_loop::controller::Sensors;
use crate::closed_loop::period::{integrate_period, settle_boundary};
use crate::closed_loop::plant::{
    load_torque, BrakeState, Forces, PlantCable, PlantCoefficients, State, CURRENT, OMEGA_M,
    OMEGA_O, THETA_M, THETA_O,
};
use crate::closed_loop::{Amplifier, CableModel};
use crate::physics::{CableDrive, DriveFault, HysteresisModel};
use crate::scenario::{Scenario, Study};

/// FMI status of a call (`fmi2Status`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// `fmi2OK`.
    Ok = 0,
    /// `fmi2Warning`.
    Warning = 1,
    /// `fmi2Discard`: the step could not be completed; the plant stopped.
    Discard = 2,
    /// `fmi2Error`: the call did nothing (bad call order or value) or the instance broke.
    Error = 3,
}

/// A call that did not succeed: its status and what to change.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct FmuError {
    /// Status returned to the host.
    pub status: Status,
    /// Message for the host's logger.
    pub message: String,
}

impl FmuError {
    /// An `fmi2Error` with this message.
    pub fn error(message: impl Into<String>) -> Self {
        FmuError {
            status: Status::Error,
            message: message.into(),
        }
    }
}

/// Where the instance is in the FMI 2.0 Co-Simulation state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// After `fmi2Instantiate` or `fmi2Reset`: parameters and inputs may be set.
    Instantiated,
    /// Between `fmi2EnterInitializationMode` and `fmi2ExitInitializationMode`.
    Initialization,
    /// Initialised and stepping.
    StepComplete,
    /// The plant stopped (slack, gross slip): outputs hold the last good point.
    StepFailed,
    /// After `fmi2Terminate`.
    Terminated,
    /// A fault inside the library: only `fmi2FreeInstance` and `fmi2Reset` help.
    Error,
}

impl Phase {
    fn name(self) -> &'static str {
        match self {
            Phase::Instantiated => "instantiated",
            Phase::Initialization => "initialization mode",
            Phase::StepComplete => "step complete",
            Phase::StepFailed => "step failed (the plant stopped)",
            Phase::Terminated => "terminated",
            Phase::Error => "error",
        }
    }
}

/// The running plant: everything that changes over a simulation, cloned whole for
/// `fmi2GetFMUstate`.
#[derive(Clone, Debug)]
struct Plant {
    coeff: PlantCoefficients,
    cable: PlantCable,
    /// The scenario's loads with the external input added to `constant_nm`.
    load: crate::physics::LoadParams,
    base_constant_nm: f64,
    base_smooth_load: bool,
    x: State,
    brake: BrakeState,
    sensors: Sensors,
    /// Time of the last communication point, s.
    time_s: f64,
    ratio: f64,
    command_limit: f64,
    voltage_mode: bool,
    max_step_s: f64,
}

/// A saved simulation state (`fmi2FMUstate`).
#[derive(Clone, Debug)]
pub struct Snapshot {
    plant: Plant,
    inputs: Inputs,
    outputs: Outputs,
    phase: Phase,
    failure: Option<String>,
}

/// A message for the host's logger, queued by a call.
#[derive(Clone, Debug, PartialEq)]
pub struct LogLine {
    /// Status the message goes with.
    pub status: Status,
    /// FMI log category (`logStatusError`, `logEvents`...).
    pub category: &'static str,
    /// Text.
    pub message: String,
}

/// Log categories declared in modelDescription.xml.
pub const LOG_CATEGORIES: &[(&str, &str)] = &[
    ("logEvents", "Initialisation and the end of the plant's run"),
    ("logStatusWarning", "Calls that returned fmi2Warning"),
    (
        "logStatusDiscard",
        "Steps the plant could not complete (slack, gross slip)",
    ),
    ("logStatusError", "Calls that returned fmi2Error"),
];

/// One FMU instance.
#[derive(Debug)]
pub struct Instance {
    phase: Phase,
    amplifier: Amplifier,
    defaults: PlantParams,
    values: Values,
    /// Parameter values set by the host, checked and applied at initialisation.
    pending: BTreeMap<u32, f64>,
    start_s: f64,
    stop_s: Option<f64>,
    plant: Option<Plant>,
    failure: Option<String>,
    /// Whether `logEvents` messages are wanted.
    pub log_events: bool,
    /// Messages waiting for the logger.
    pub log: Vec<LogLine>,
}

/// The parameters of a closed-loop scenario, as the FMU's defaults.
pub fn plant_params(scenario: &Scenario) -> Result<PlantParams, String> {
    let cl = match (&scenario.study, &scenario.closed_loop) {
        (Study::ClosedLoop, Some(p)) => p.clone(),
        (study, _) => {
            return Err(format!(
                "scenario {}: study is \"{}\"; an FMU is built from a closed-loop scenario (study = \"closed_loop\"), whose [closed_loop] section gives motor, drum and sensors",
                scenario.name(),
                study.as_str()
            ))
        }
    };
    if let Some(path) = &scenario.load.disturbance_csv {
        return Err(format!(
            "load.disturbance_csv = {path}: an FMU carries no table; feed the torque series through the input external_load_torque_nm"
        ));
    }
    dropped_parts(&cl)?;
    let s = &cl.sensors;
    for (key, v) in [
        ("motor_counts_per_rev", s.motor_counts_per_rev),
        ("output_counts_per_rev", s.output_counts_per_rev),
        ("seed", s.seed),
    ] {
        if v > i32::MAX as u64 {
            return Err(format!(
                "closed_loop.sensors.{key} = {v} does not fit an FMI Integer (at most {})",
                i32::MAX
            ));
        }
    }
    let model = match cl.cable {
        CableModel::Hysteretic => PlantModel::Memory,
        CableModel::Linear => PlantModel::Linear,
    };
    let max_step_s = 1.0 / (cl.controller.sample_rate_hz * f64::from(cl.rk4_substeps.max(1)));
    Ok(PlantParams {
        drive: scenario.drive.clone(),
        load: scenario.load.clone(),
        closed_loop: cl,
        model,
        max_step_s,
        effects: scenario.effects.clone(),
    })
}

/// The parts of a closed-loop scenario that shape its loop but that the FMU (the plant
/// only: motor, cable drive, drum, loads, encoders) does not carry. Exporting them would
/// give an FMU whose loop behaves unlike the scenario's `run` without a word; every such
/// key is named, with what to do.
pub fn dropped_parts(cl: &crate::closed_loop::params::ClosedLoopParams) -> Result<(), String> {
    let c = &cl.controller;
    let mut keys: Vec<&str> = Vec::new();
    if cl.base_motion.is_some() {
        keys.push("closed_loop.base_motion");
    }
    if cl.gyro.is_some() {
        keys.push("closed_loop.gyro");
    }
    if c.rate_loop.is_some() {
        keys.push("closed_loop.controller.rate_loop");
    }
    for (key, filters) in [
        (
            "closed_loop.controller.measurement_filters",
            &c.measurement_filters,
        ),
        (
            "closed_loop.controller.rate_command_filters",
            &c.rate_command_filters,
        ),
        (
            "closed_loop.controller.rate_measurement_filters",
            &c.rate_measurement_filters,
        ),
        ("closed_loop.controller.command_filters", &c.command_filters),
    ] {
        if !filters.is_empty() {
            keys.push(key);
        }
    }
    if c.disturbance_observer.is_some() {
        keys.push("closed_loop.controller.disturbance_observer");
    }
    if keys.is_empty() {
        return Ok(());
    }
    Err(format!(
        "the FMU carries the plant only (motor, cable drive, drum, loads, encoders), not {}; the exported loop would differ from the scenario's. To export the plant without them knowingly, remove them from a copy of the scenario (a filter list also with --set KEY=[]) and build them into the co-simulation's controller",
        keys.join(", ")
    ))
}

/// Outputs of the plant at rest before initialisation (angles zero, spans at preload).
fn rest_outputs(p: &PlantParams) -> Outputs {
    Outputs {
        tension_upper_n: p.drive.preload_n,
        tension_lower_n: p.drive.preload_n,
        ..Outputs::default()
    }
}

/// Full check of the parameters as the plant will use them; the first problem, named by
/// its FMI variable.
fn check_params(p: &PlantParams) -> Result<(), String> {
    p.drive.validate().map_err(|e| e.to_string())?;
    p.load
        .validate()
        .map_err(|(k, m)| format!("load.{k}: {m}"))?;
    if let Some(fx) = &p.effects {
        fx.validate()
            .map_err(|(k, m)| format!("effects.{k} (from the scenario): {m}"))?;
        // Its angle output is the drum's: a jaw link behind the drum has no place in it.
        if fx.load_compliance() != 0.0 || fx.has_friction_memory() {
            return Err("effects.load_compliance and effects.friction_memory_* (from the scenario) describe the jaw link behind the drum, which the co-simulation plant does not carry; remove them from the exported scenario or run the closed loop with `run`".into());
        }
    }
    let modes = p.closed_loop.plant_modes(&p.drive);
    // Written so a NaN rate fails the check too.
    let stable = modes.fastest_rad_s * p.max_step_s <= 1.0;
    if !stable {
        return Err(format!(
            "solver.max_step_s = {} s is too long for the plant's fastest rate ({:.0} rad/s: drive mode {:.0} Hz, drum-held mode {:.0} Hz); use at most {:.3e} s",
            crate::number(p.max_step_s),
            modes.fastest_rad_s,
            modes.free_mode_rad_s / std::f64::consts::TAU,
            modes.locked_mode_rad_s / std::f64::consts::TAU,
            1.0 / modes.fastest_rad_s
        ));
    }
    Ok(())
}

impl Plant {
    fn new(p: &PlantParams, amplifier: Amplifier, start_s: f64) -> Self {
        let cable = match p.model {
            PlantModel::Memory => {
                PlantCable::Hysteretic(CableDrive::new(p.drive.clone(), HysteresisModel::Memory))
            }
            PlantModel::Memoryless => PlantCable::Hysteretic(CableDrive::new(
                p.drive.clone(),
                HysteresisModel::Memoryless,
            )),
            PlantModel::Linear => PlantCable::new(CableModel::Linear, &p.drive),
        };
        let mut load = p.load.clone();
        load.disturbance.clear();
        let coeff = PlantCoefficients::new(&p.closed_loop, &p.drive, &load, p.effects.as_ref());
        Plant {
            base_constant_nm: load.constant_nm,
            base_smooth_load: coeff.smooth_load,
            coeff,
            cable,
            load,
            x: State::zeros(),
            brake: BrakeState::Stuck,
            sensors: Sensors::new(&p.closed_loop.sensors),
            time_s: start_s,
            ratio: p.drive.ratio(),
            command_limit: p.closed_loop.motor.command_limit(),
            voltage_mode: amplifier == Amplifier::Voltage,
            max_step_s: p.max_step_s,
        }
    }

    /// The external torque input, held until it is set again.
    fn hold_external(&mut self, torque_nm: f64) {
        self.load.constant_nm = self.base_constant_nm + torque_nm;
        self.coeff.smooth_load = self.base_smooth_load || torque_nm != 0.0;
    }

    /// Period boundary at `t`: commit, brake, encoders, outputs.
    fn boundary(&mut self, t: f64) -> Result<Outputs, DriveFault> {
        let forces = settle_boundary(
            &self.coeff,
            &mut self.cable,
            &self.load,
            &mut self.brake,
            &mut self.x,
            t,
            (0.0, 0.0),
        )?;
        Ok(self.outputs(&forces))
    }

    fn outputs(&mut self, f: &Forces) -> Outputs {
        let x = &self.x;
        let rng = &mut self.sensors.rng;
        let motor_encoder_rad = self.sensors.motor.read(x[THETA_M], rng);
        let output_encoder_rad = self.sensors.output.read(x[THETA_O], rng);
        let regime = match &self.cable {
            PlantCable::Hysteretic(d) if d.state().slip_growth.iter().any(|&g| g > 1.0) => {
                Regime::Slip
            }
            _ => Regime::Contact,
        };
        Outputs {
            motor_angle_rad: x[THETA_M],
            motor_rate_rad_s: x[OMEGA_M],
            output_angle_rad: x[THETA_O],
            output_rate_rad_s: x[OMEGA_O],
            motor_current_a: x[CURRENT],
            motor_encoder_rad,
            output_encoder_rad,
            tension_upper_n: f.tension_upper_n,
            tension_lower_n: f.tension_lower_n,
            transmitted_torque_nm: f.cable_torque_nm,
            load_torque_nm: load_torque(&self.coeff, self.brake, f),
            transmission_error_rad: x[THETA_O] - x[THETA_M] / self.ratio,
            regime,
        }
    }
}

/// Fault message with the step's times; a slack span found by displacement carries no
/// torque, so the torque at the last good point fills it in.
fn describe_fault(fault: DriveFault, from_s: f64, to_s: f64, last_torque_nm: f64) -> String {
    let fault = match fault {
        DriveFault::Slack {
            half,
            needed_preload_n,
            ..
        } => DriveFault::Slack {
            half,
            torque_nm: last_torque_nm,
            needed_preload_n: needed_preload_n.max(last_torque_nm.abs() / 2.0),
        },
        other => other,
    };
    format!("the plant stopped in the step from t = {from_s} s to {to_s} s: {fault}")
}

impl Instance {
    /// A new instance with the scenario's values as defaults.
    pub fn new(scenario: &Scenario) -> Result<Self, String> {
        let params = plant_params(scenario)?;
        Ok(Instance {
            phase: Phase::Instantiated,
            amplifier: params.closed_loop.motor.amplifier,
            values: Values {
                outputs: rest_outputs(&params),
                params: params.clone(),
                inputs: Inputs::default(),
            },
            defaults: params,
            pending: BTreeMap::new(),
            start_s: 0.0,
            stop_s: None,
            plant: None,
            failure: None,
            log_events: false,
            log: Vec::new(),
        })
    }

    /// Current phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Amplifier of this FMU (which command input it has).
    pub fn amplifier(&self) -> Amplifier {
        self.amplifier
    }

    /// Puts the instance in the error phase (after a panic caught at the boundary).
    pub fn break_down(&mut self) {
        self.phase = Phase::Error;
    }

    fn event(&mut self, message: String) {
        if self.log_events {
            self.log.push(LogLine {
                status: Status::Ok,
                category: "logEvents",
                message,
            });
        }
    }

    fn require(&self, call: &str, allowed: &[Phase]) -> Result<(), FmuError> {
        if allowed.contains(&self.phase) {
            Ok(())
        } else {
            let names: Vec<&str> = allowed.iter().map(|p| p.name()).collect();
            Err(FmuError::error(format!(
                "{call} is not allowed in phase {}; it is allowed in: {}",
                self.phase.name(),
                names.join(", ")
            )))
        }
    }

    /// `fmi2SetupExperiment`.
    pub fn setup_experiment(&mut self, start_s: f64, stop_s: Option<f64>) -> Result<(), FmuError> {
        self.require("fmi2SetupExperiment", &[Phase::Instantiated])?;
        if !start_s.is_finite() {
            return Err(FmuError::error(format!(
                "start time {start_s} s must be finite"
            )));
        }
        if let Some(stop) = stop_s {
            if !(stop.is_finite() && stop >= start_s) {
                return Err(FmuError::error(format!(
                    "stop time {stop} s must be finite and not before the start time {start_s} s"
                )));
            }
        }
        self.start_s = start_s;
        self.stop_s = stop_s;
        Ok(())
    }

    /// `fmi2EnterInitializationMode`.
    pub fn enter_initialization(&mut self) -> Result<(), FmuError> {
        self.require("fmi2EnterInitializationMode", &[Phase::Instantiated])?;
        self.phase = Phase::Initialization;
        Ok(())
    }

    /// `fmi2ExitInitializationMode`: checks every parameter (the host keeps the
    /// initialization mode on a bad one and may set it again), builds the plant at rest
    /// and computes the outputs at the start time.
    pub fn exit_initialization(&mut self) -> Result<(), FmuError> {
        self.require("fmi2ExitInitializationMode", &[Phase::Initialization])?;
        let mut values = self.values.clone();
        for (&vr, &x) in &self.pending {
            let Some(var) = variables::find(vr, self.amplifier) else {
                continue;
            };
            if let Some(allowed) = var.range.check(x) {
                return Err(FmuError::error(format!(
                    "parameter {} = {}{}: must be {allowed}",
                    var.name,
                    crate::number(x),
                    unit_suffix(var)
                )));
            }
            if let Some(set) = var.set {
                set(&mut values, x);
            }
        }
        check_params(&values.params).map_err(FmuError::error)?;
        let mut plant = Plant::new(&values.params, self.amplifier, self.start_s);
        plant.hold_external(values.inputs.external_torque_nm);
        let outputs = plant.boundary(self.start_s).map_err(|f| {
            FmuError::error(format!(
                "the plant cannot start at rest with these parameters: {f}"
            ))
        })?;
        values.outputs = outputs;
        self.values = values;
        self.pending.clear();
        self.plant = Some(plant);
        self.failure = None;
        self.phase = Phase::StepComplete;
        let p = &self.values.params;
        self.event(format!(
            "initialised at t = {} s: cable model {:?}, preload {} N, brake {} N m, RK4 steps of at most {} s",
            self.start_s,
            p.model,
            crate::number(p.drive.preload_n),
            crate::number(p.load.brake_nm),
            crate::number(p.max_step_s)
        ));
        Ok(())
    }

    /// `fmi2DoStep`: integrates the plant from `t` over `h` seconds with the inputs held,
    /// commits the cable memory at the step's end. A slack span or gross slip leaves the
    /// state at `t` and answers `Discard`; later steps are refused.
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<(), FmuError> {
        if let (Phase::StepFailed, Some(why)) = (self.phase, &self.failure) {
            return Err(FmuError::error(format!(
                "fmi2DoStep after the plant stopped ({why}); fmi2Terminate, or fmi2Reset to start again"
            )));
        }
        self.require("fmi2DoStep", &[Phase::StepComplete])?;
        if !(h.is_finite() && h > 0.0) {
            return Err(FmuError::error(format!(
                "communication step size {h} s: must be a finite number > 0"
            )));
        }
        let stop_s = self.stop_s;
        let inputs = self.values.inputs;
        let last_torque = self.values.outputs.transmitted_torque_nm;
        let Some(plant) = self.plant.as_mut() else {
            return Err(FmuError::error("the plant is not initialised"));
        };
        let now = plant.time_s;
        if !t.is_finite() || (t - now).abs() > 1e-9 * now.abs().max(1.0) {
            return Err(FmuError::error(format!(
                "communication point t = {t} s, but the FMU is at t = {now} s: steps must follow each other"
            )));
        }
        let end = t + h;
        if let Some(stop) = stop_s {
            if end > stop + 1e-9 * stop.abs().max(1.0) {
                return Err(FmuError::error(format!(
                    "step to t = {end} s goes past the stop time {stop} s set by fmi2SetupExperiment"
                )));
            }
        }
        let ratio = h / plant.max_step_s;
        let substeps = if (ratio - ratio.round()).abs() <= 1e-9 * ratio {
            ratio.round()
        } else {
            ratio.ceil()
        }
        .max(1.0);
        if substeps > 1e7 {
            return Err(FmuError::error(format!(
                "step size {h} s needs {substeps:.0} RK4 steps of at most solver.max_step_s = {} s; make steps of at most {} s",
                plant.max_step_s,
                1e7 * plant.max_step_s
            )));
        }
        let before = (plant.x, plant.brake);
        let command = inputs
            .command
            .clamp(-plant.command_limit, plant.command_limit);
        if !plant.voltage_mode {
            plant.x[CURRENT] = command;
        }
        plant.hold_external(inputs.external_torque_nm);
        let period = integrate_period(
            &plant.coeff,
            &plant.cable,
            &plant.load,
            plant.brake,
            command,
            t,
            h,
            substeps as u32,
            Default::default(),
            &mut plant.x,
        );
        let result = match period.fault {
            Some(f) => Err(f),
            None if !plant.x.iter().all(|v| v.is_finite()) => {
                plant.x = before.0;
                let message = format!(
                    "the plant state became infinite or NaN in the step from t = {t} s to {end} s: the loop is unstable; lower the host controller's gains or the step size"
                );
                self.failure = Some(message.clone());
                self.phase = Phase::StepFailed;
                return Err(FmuError {
                    status: Status::Discard,
                    message,
                });
            }
            None => plant.boundary(end),
        };
        match result {
            Ok(outputs) => {
                plant.time_s = end;
                self.values.outputs = outputs;
                Ok(())
            }
            Err(fault) => {
                (plant.x, plant.brake) = before;
                self.values.outputs.regime = match fault {
                    DriveFault::Slack { .. } => Regime::Slack,
                    DriveFault::GrossSlip { .. } => Regime::GrossSlip,
                };
                let message = describe_fault(fault, t, end, last_torque);
                self.failure = Some(message.clone());
                self.phase = Phase::StepFailed;
                Err(FmuError {
                    status: Status::Discard,
                    message,
                })
            }
        }
    }

    /// Refusal of a step after the plant stopped, naming why it stopped.
    pub fn stopped_message(&self) -> Option<&str> {
        self.failure.as_deref()
    }

    /// `fmi2Terminate`.
    pub fn terminate(&mut self) -> Result<(), FmuError> {
        self.require("fmi2Terminate", &[Phase::StepComplete, Phase::StepFailed])?;
        self.phase = Phase::Terminated;
        Ok(())
    }

    /// `fmi2Reset`: back to the scenario's defaults, as after instantiation.
    pub fn reset(&mut self) {
        self.phase = Phase::Instantiated;
        self.values = Values {
            outputs: rest_outputs(&self.defaults),
            params: self.defaults.clone(),
            inputs: Inputs::default(),
        };
        self.pending.clear();
        self.start_s = 0.0;
        self.stop_s = None;
        self.plant = None;
        self.failure = None;
    }

    fn variable(&self, vr: u32, kind: Kind) -> Result<&'static Variable, FmuError> {
        let var = variables::find(vr, self.amplifier).ok_or_else(|| {
            let other = variables::VARIABLES.iter().find(|v| v.vr == vr);
            FmuError::error(match other {
                Some(v) => format!(
                    "value reference {vr} ({}) belongs to an FMU with a {:?} amplifier; this one's amplifier is {:?}",
                    v.name,
                    v.amplifier.unwrap_or(self.amplifier),
                    self.amplifier
                ),
                None => format!("no variable has value reference {vr}"),
            })
        })?;
        if var.kind != kind {
            return Err(FmuError::error(format!(
                "{} (value reference {vr}) is an FMI {}, not {}",
                var.name,
                var.kind.xml(),
                kind.xml()
            )));
        }
        Ok(var)
    }

    /// `fmi2GetReal`, `fmi2GetInteger`, `fmi2GetBoolean` (integers and booleans as exact
    /// `f64`).
    pub fn get(&mut self, vr: u32, kind: Kind) -> Result<f64, FmuError> {
        self.require(
            "getting a value",
            &[
                Phase::Initialization,
                Phase::StepComplete,
                Phase::StepFailed,
                Phase::Terminated,
                Phase::Error,
            ],
        )?;
        let var = self.variable(vr, kind)?;
        if let Some(&x) = self.pending.get(&vr) {
            return Ok(x);
        }
        if self.plant.is_none() && var.causality == Causality::Output {
            // Before initialisation the outputs are those of the plant at rest, with the
            // parameters set so far (those in range).
            let mut values = self.values.clone();
            for (&vr, &x) in &self.pending {
                if let Some(set) = variables::find(vr, self.amplifier)
                    .filter(|v| v.range.check(x).is_none())
                    .and_then(|v| v.set)
                {
                    set(&mut values, x);
                }
            }
            self.values.outputs = rest_outputs(&values.params);
        }
        Ok((var.get)(&self.values))
    }

    /// `fmi2SetReal`, `fmi2SetInteger`, `fmi2SetBoolean`. Parameters are kept and
    /// checked at `fmi2ExitInitializationMode`; inputs take effect at the next step.
    pub fn set(&mut self, vr: u32, kind: Kind, x: f64) -> Result<(), FmuError> {
        let var = self.variable(vr, kind)?;
        match var.causality {
            Causality::Output => {
                return Err(FmuError::error(format!(
                    "{} (value reference {vr}) is an output and cannot be set",
                    var.name
                )))
            }
            Causality::Parameter => {
                self.require(
                    &format!("setting parameter {}", var.name),
                    &[Phase::Instantiated, Phase::Initialization],
                )?;
                if !x.is_finite() {
                    return Err(FmuError::error(format!(
                        "parameter {} = {x}: must be {}",
                        var.name,
                        var.range.allowed()
                    )));
                }
                self.pending.insert(vr, x);
            }
            Causality::Input => {
                self.require(
                    &format!("setting input {}", var.name),
                    &[
                        Phase::Instantiated,
                        Phase::Initialization,
                        Phase::StepComplete,
                    ],
                )?;
                if !x.is_finite() {
                    return Err(FmuError::error(format!(
                        "input {} = {x}{}: must be finite",
                        var.name,
                        unit_suffix(var)
                    )));
                }
                if let Some(set) = var.set {
                    set(&mut self.values, x);
                }
            }
        }
        Ok(())
    }

    /// Time of the last successful communication point, s (`fmi2LastSuccessfulTime`).
    pub fn last_successful_time(&self) -> f64 {
        self.plant.as_ref().map_or(self.start_s, |p| p.time_s)
    }

    /// Whether the plant stopped and the host should end the simulation
    /// (`fmi2Terminated`).
    pub fn stopped(&self) -> bool {
        self.phase == Phase::StepFailed
    }

    /// `fmi2GetFMUstate`.
    pub fn snapshot(&self) -> Result<Snapshot, FmuError> {
        self.require(
            "fmi2GetFMUstate",
            &[Phase::StepComplete, Phase::StepFailed, Phase::Terminated],
        )?;
        let plant = self
            .plant
            .clone()
            .ok_or_else(|| FmuError::error("the plant is not initialised"))?;
        Ok(Snapshot {
            plant,
            inputs: self.values.inputs,
            outputs: self.values.outputs,
            phase: self.phase,
            failure: self.failure.clone(),
        })
    }

    /// `fmi2SetFMUstate`: the simulation continues from the saved state.
    pub fn restore(&mut self, s: &Snapshot) -> Result<(), FmuError> {
        self.require(
            "fmi2SetFMUstate",
            &[Phase::StepComplete, Phase::StepFailed, Phase::Terminated],
        )?;
        self.plant = Some(s.plant.clone());
        self.values.inputs = s.inputs;
        self.values.outputs = s.outputs;
        self.phase = s.phase;
        self.failure = s.failure.clone();
        Ok(())
    }

    /// The parameters in use (after initialisation) or that will be checked.
    pub fn params(&self) -> &PlantParams {
        &self.values.params
    }

    /// Whether the scenario's closed-loop parameters validate as the plant uses them (for
    /// tests and the exporter).
    pub fn check_defaults(&self) -> Result<(), String> {
        check_params(&self.defaults)
    }
}

fn unit_suffix(var: &Variable) -> String {
    if var.unit.is_empty() {
        String::new()
    } else {
        format!(" {}", var.unit)
    }
}
