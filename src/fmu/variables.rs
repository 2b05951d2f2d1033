//! The FMU's variables: one table gives each its value reference, name, type, causality,
//! unit, allowed range and how it is read and written. The C functions and the
//! modelDescription writer both read it, so they cannot disagree.
//!
//! Value references: inputs 1-99, outputs 100-199, parameters 1000 and up. Reference 4 is
//! kept for the base angular rate input (`base_rate_rad_s`, the turret's carrier turning
//! under the drum), which the FMU does not take yet (the native loop models base motion).

use crate::closed_loop::{Amplifier, ClosedLoopParams};
use crate::physics::EffectsParams;
use crate::physics::{DriveParams, LoadParams};

/// FMI base type of a variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// `fmi2Real`.
    Real,
    /// `fmi2Integer`.
    Integer,
    /// `fmi2Boolean`.
    Boolean,
}

impl Kind {
    /// Element name in modelDescription.xml.
    pub fn xml(self) -> &'static str {
        match self {
            Kind::Real => "Real",
            Kind::Integer => "Integer",
            Kind::Boolean => "Boolean",
        }
    }
}

/// FMI causality of a variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Causality {
    /// Set before initialisation, fixed afterwards.
    Parameter,
    /// Set by the host between steps, held over a step.
    Input,
    /// Computed at every communication point.
    Output,
}

/// Values a parameter accepts (checked at `fmi2ExitInitializationMode`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    /// Any finite number.
    Finite,
    /// Finite and > 0.
    Positive,
    /// Finite and >= 0.
    NonNegative,
    /// In `[0, 1)`.
    Fraction,
    /// An integer in `0..n`.
    Choice(u32),
    /// An integer in `[lo, 2^31 - 1]`.
    IntegerFrom(i64),
}

impl Range {
    /// `None` when `v` is allowed, else what is allowed.
    pub fn check(self, v: f64) -> Option<String> {
        let ok = match self {
            Range::Finite => v.is_finite(),
            Range::Positive => v.is_finite() && v > 0.0,
            Range::NonNegative => v.is_finite() && v >= 0.0,
            Range::Fraction => (0.0..1.0).contains(&v),
            Range::Choice(n) => v.fract() == 0.0 && (0.0..f64::from(n)).contains(&v),
            Range::IntegerFrom(lo) => {
                v.fract() == 0.0 && v >= lo as f64 && v <= f64::from(i32::MAX)
            }
        };
        (!ok).then(|| self.allowed())
    }

    /// What the range allows, for messages.
    pub fn allowed(self) -> String {
        match self {
            Range::Finite => "a finite number".into(),
            Range::Positive => "a finite number > 0".into(),
            Range::NonNegative => "a finite number >= 0".into(),
            Range::Fraction => "in [0, 1)".into(),
            Range::Choice(n) => format!("an integer from 0 to {}", n - 1),
            Range::IntegerFrom(lo) => format!("an integer from {lo} to {}", i32::MAX),
        }
    }

    /// Bounds written to modelDescription.xml (`min`, `max`); open bounds are left out.
    pub fn xml_bounds(self) -> (Option<f64>, Option<f64>) {
        match self {
            Range::Finite | Range::Positive => (None, None),
            Range::NonNegative => (Some(0.0), None),
            Range::Fraction => (Some(0.0), Some(1.0)),
            Range::Choice(n) => (Some(0.0), Some(f64::from(n - 1))),
            Range::IntegerFrom(lo) => (Some(lo as f64), None),
        }
    }
}

/// Cable law of the FMU's plant (parameter `cable.model`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlantModel {
    /// Capstan friction with memory (0).
    Memory,
    /// Capstan friction computed from the virgin cable at every boundary (1).
    Memoryless,
    /// Linear springs with the preloaded drive's small-signal stiffness (2).
    Linear,
}

impl PlantModel {
    /// Integer code of the parameter.
    pub fn code(self) -> f64 {
        match self {
            PlantModel::Memory => 0.0,
            PlantModel::Memoryless => 1.0,
            PlantModel::Linear => 2.0,
        }
    }

    /// From the integer code; unknown codes give `None`.
    pub fn from_code(v: f64) -> Option<Self> {
        match v {
            0.0 => Some(PlantModel::Memory),
            1.0 => Some(PlantModel::Memoryless),
            2.0 => Some(PlantModel::Linear),
            _ => None,
        }
    }
}

/// Regime of the cable at the last communication point (output `regime`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Regime {
    /// Both spans taut, no slip zone moved at the last boundary (0).
    #[default]
    Contact,
    /// A slip zone grew on a wrap at the last boundary: the capstan's partial slip (1).
    Slip,
    /// A span went slack: the step was discarded (2).
    Slack,
    /// A pulley slip zone reached the neutral point, the cable slides round the pulley:
    /// the step was discarded (3).
    GrossSlip,
}

impl Regime {
    /// Integer code of the output.
    pub fn code(self) -> f64 {
        match self {
            Regime::Contact => 0.0,
            Regime::Slip => 1.0,
            Regime::Slack => 2.0,
            Regime::GrossSlip => 3.0,
        }
    }
}

/// Physical parameters of the FMU's plant, with the scenario's values as defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct PlantParams {
    /// The cable drive (`[drive]`).
    pub drive: DriveParams,
    /// Loads on the drum (`[load]`); the external torque series is not used.
    pub load: LoadParams,
    /// Motor, output, sensors and cable damping (`[closed_loop]`); the controller keys are
    /// not the plant's and are ignored.
    pub closed_loop: ClosedLoopParams,
    /// Cable law.
    pub model: PlantModel,
    /// Longest RK4 step inside `fmi2DoStep`, s: the scenario's control period over its
    /// `rk4_substeps` (1e-4 s on the bench). A communication step is cut into the fewest
    /// equal RK4 steps no longer than this.
    pub max_step_s: f64,
    /// The plant's `[effects]` from the scenario (not FMI parameters).
    pub effects: Option<EffectsParams>,
}

/// Inputs, held over a step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inputs {
    /// Motor command: current (A) or voltage (V) as the amplifier takes it; clipped to the
    /// amplifier's limit.
    pub command: f64,
    /// External torque on the drum along `+theta_out`, N m (added to the scenario's
    /// constant load).
    pub external_torque_nm: f64,
}

/// Outputs at the last communication point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Outputs {
    /// Motor angle, rad.
    pub motor_angle_rad: f64,
    /// Motor speed, rad/s.
    pub motor_rate_rad_s: f64,
    /// Output (drum) angle, rad.
    pub output_angle_rad: f64,
    /// Output speed, rad/s.
    pub output_rate_rad_s: f64,
    /// Winding current, A.
    pub motor_current_a: f64,
    /// Motor encoder reading (quantised, with noise), rad.
    pub motor_encoder_rad: f64,
    /// Output encoder reading, rad.
    pub output_encoder_rad: f64,
    /// Upper span tension with damping, N.
    pub tension_upper_n: f64,
    /// Lower span tension with damping, N.
    pub tension_lower_n: f64,
    /// Torque of the cable on the drum, N m.
    pub transmitted_torque_nm: f64,
    /// Torque of the loads on the drum (brake reaction included), N m.
    pub load_torque_nm: f64,
    /// Transmission error `theta_out - theta_in/ic`, rad.
    pub transmission_error_rad: f64,
    /// Cable regime.
    pub regime: Regime,
}

/// Everything the variables read and write.
#[derive(Clone, Debug, PartialEq)]
pub struct Values {
    /// Parameters.
    pub params: PlantParams,
    /// Inputs.
    pub inputs: Inputs,
    /// Outputs.
    pub outputs: Outputs,
}

/// One FMI variable.
#[derive(Clone, Copy, Debug)]
pub struct Variable {
    /// FMI value reference.
    pub vr: u32,
    /// Name (parameters: the scenario key without `closed_loop.`).
    pub name: &'static str,
    /// Base type.
    pub kind: Kind,
    /// Causality.
    pub causality: Causality,
    /// Unit as declared in modelDescription.xml (empty: dimensionless).
    pub unit: &'static str,
    /// What it is, with typical values.
    pub description: &'static str,
    /// Allowed values (parameters).
    pub range: Range,
    /// Present only with this amplifier (the motor command inputs).
    pub amplifier: Option<Amplifier>,
    /// Reads the value (integers and booleans as exact `f64`).
    pub get: fn(&Values) -> f64,
    /// Writes it (`None` for outputs).
    pub set: Option<fn(&mut Values, f64)>,
}

impl Variable {
    /// Whether the variable belongs to an FMU whose amplifier is `amp`.
    pub fn present(&self, amp: Amplifier) -> bool {
        self.amplifier.is_none_or(|a| a == amp)
    }
}

macro_rules! param {
    ($vr:expr, $name:expr, $kind:ident, $unit:expr, $range:expr, $desc:expr, |$p:ident| $field:expr) => {
        Variable {
            vr: $vr,
            name: $name,
            kind: Kind::$kind,
            causality: Causality::Parameter,
            unit: $unit,
            description: $desc,
            range: $range,
            amplifier: None,
            get: |v| {
                let $p = &v.params;
                $field as f64
            },
            set: Some(|v, x| {
                let $p = &mut v.params;
                $field = x as _;
            }),
        }
    };
}

macro_rules! output {
    ($vr:expr, $name:expr, $kind:ident, $unit:expr, $desc:expr, |$o:ident| $value:expr) => {
        Variable {
            vr: $vr,
            name: $name,
            kind: Kind::$kind,
            causality: Causality::Output,
            unit: $unit,
            description: $desc,
            range: Range::Finite,
            amplifier: None,
            get: |v| {
                let $o = &v.outputs;
                $value
            },
            set: None,
        }
    };
}

fn limit_get(v: Option<f64>) -> f64 {
    v.unwrap_or(0.0)
}

fn limit_set(x: f64) -> Option<f64> {
    (x != 0.0).then_some(x)
}

/// Every variable of the FMU (the motor command appears once per amplifier; an FMU
/// carries the one of its amplifier).
pub static VARIABLES: &[Variable] = &[
    // Inputs.
    Variable {
        vr: 1,
        name: "motor_current_command_a",
        kind: Kind::Real,
        causality: Causality::Input,
        unit: "A",
        description: "Current commanded to the current amplifier, A (clipped to motor.current_limit_a), held over a step",
        range: Range::Finite,
        amplifier: Some(Amplifier::Current),
        get: |v| v.inputs.command,
        set: Some(|v, x| v.inputs.command = x),
    },
    Variable {
        vr: 2,
        name: "motor_voltage_command_v",
        kind: Kind::Real,
        causality: Causality::Input,
        unit: "V",
        description: "Voltage commanded to the voltage amplifier, V (clipped to motor.voltage_limit_v), held over a step",
        range: Range::Finite,
        amplifier: Some(Amplifier::Voltage),
        get: |v| v.inputs.command,
        set: Some(|v, x| v.inputs.command = x),
    },
    Variable {
        vr: 3,
        name: "external_load_torque_nm",
        kind: Kind::Real,
        causality: Causality::Input,
        unit: "N.m",
        description: "External torque on the drum along +output angle, N m, added to load.constant_nm, held over a step",
        range: Range::Finite,
        amplifier: None,
        get: |v| v.inputs.external_torque_nm,
        set: Some(|v, x| v.inputs.external_torque_nm = x),
    },
    // Outputs.
    output!(100, "motor_angle_rad", Real, "rad", "Motor (input pulley) angle, rad", |o| o.motor_angle_rad),
    output!(101, "motor_rate_rad_s", Real, "rad/s", "Motor speed, rad/s", |o| o.motor_rate_rad_s),
    output!(102, "output_angle_rad", Real, "rad", "Output (drum and payload) angle, rad", |o| o.output_angle_rad),
    output!(103, "output_rate_rad_s", Real, "rad/s", "Output speed, rad/s", |o| o.output_rate_rad_s),
    output!(104, "motor_encoder_rad", Real, "rad", "Motor encoder reading (whole counts, noise), rad", |o| o.motor_encoder_rad),
    output!(105, "output_encoder_rad", Real, "rad", "Output encoder reading (whole counts, noise), rad", |o| o.output_encoder_rad),
    output!(106, "tension_upper_n", Real, "N", "Upper span tension with structural damping, N (about the preload, 100 N)", |o| o.tension_upper_n),
    output!(107, "tension_lower_n", Real, "N", "Lower span tension with structural damping, N", |o| o.tension_lower_n),
    output!(108, "transmitted_torque_nm", Real, "N.m", "Torque of the cable on the drum, N m", |o| o.transmitted_torque_nm),
    output!(109, "transmission_error_rad", Real, "rad", "Transmission error: output angle minus motor angle over the ratio, rad (tenths of a mrad)", |o| o.transmission_error_rad),
    output!(110, "regime", Integer, "", "Cable regime: 0 contact, 1 slip (a slip zone grew), 2 slack span, 3 gross slip on the pulley (2 and 3 end the run with fmi2Discard)", |o| o.regime.code()),
    output!(111, "motor_current_a", Real, "A", "Winding current, A", |o| o.motor_current_a),
    output!(112, "load_torque_nm", Real, "N.m", "Torque of the loads on the drum (brake reaction included), N m", |o| o.load_torque_nm),
    // Parameters: drive.
    param!(1000, "drive.pulley_radius_m", Real, "m", Range::Positive, "Motor pulley radius, m (0.02)", |p| p.drive.pulley_radius_m),
    param!(1001, "drive.drum_radius_m", Real, "m", Range::Positive, "Output drum radius, m (0.1025)", |p| p.drive.drum_radius_m),
    param!(1002, "drive.center_distance_m", Real, "m", Range::Positive, "Distance between pulley and drum axes, m (0.145)", |p| p.drive.center_distance_m),
    param!(1003, "drive.cable_modulus_n", Real, "N", Range::Positive, "Cable tensile stiffness E*A, N (1.4e4)", |p| p.drive.cable_modulus_n),
    param!(1004, "drive.friction_coefficient", Real, "", Range::NonNegative, "Cable-on-wrap friction coefficient (0.2)", |p| p.drive.friction_coefficient),
    param!(1005, "drive.preload_n", Real, "N", Range::Positive, "Cable preload, N (100)", |p| p.drive.preload_n),
    param!(1006, "drive.drum_wrap_rad", Real, "rad", Range::Positive, "Drum wrap per half, rad (pi)", |p| p.drive.drum_wrap_rad),
    param!(1007, "drive.pulley_wrap_rad", Real, "rad", Range::Positive, "Total pulley wrap, rad (6 pi)", |p| p.drive.pulley_wrap_rad),
    // Loads.
    param!(1020, "load.brake_nm", Real, "N.m", Range::NonNegative, "Sliding torque of the powder brake, N m (0.7)", |p| p.load.brake_nm),
    Variable {
        vr: 1021,
        name: "load.brake_breakaway_nm",
        kind: Kind::Real,
        causality: Causality::Parameter,
        unit: "N.m",
        description: "Breakaway torque of the brake, N m (0.75); at least load.brake_nm",
        range: Range::NonNegative,
        amplifier: None,
        get: |v| v.params.load.breakaway_nm(),
        set: Some(|v, x| v.params.load.brake_breakaway_nm = Some(x)),
    },
    param!(1022, "load.unbalance_nm", Real, "N.m", Range::NonNegative, "Mass unbalance torque m*g*l, N m (0.1 to 1)", |p| p.load.unbalance_nm),
    param!(1023, "load.unbalance_phase_rad", Real, "rad", Range::Finite, "Angle of the unbalance at output angle 0, rad (pi/2: level)", |p| p.load.unbalance_phase_rad),
    param!(1024, "load.constant_nm", Real, "N.m", Range::Finite, "Constant external torque on the drum, N m", |p| p.load.constant_nm),
    param!(1025, "load.sine_nm", Real, "N.m", Range::Finite, "Amplitude of a sinusoidal disturbance torque, N m", |p| p.load.sine_nm),
    param!(1026, "load.sine_frequency_hz", Real, "Hz", Range::NonNegative, "Frequency of the sinusoidal disturbance, Hz", |p| p.load.sine_frequency_hz),
    // Motor.
    param!(1040, "motor.resistance_ohm", Real, "Ohm", Range::Positive, "Winding resistance, ohm (2)", |p| p.closed_loop.motor.resistance_ohm),
    param!(1041, "motor.inductance_h", Real, "H", Range::Positive, "Winding inductance, H (1e-3)", |p| p.closed_loop.motor.inductance_h),
    param!(1042, "motor.torque_constant_nm_per_a", Real, "N.m/A", Range::Positive, "Torque constant, N m/A (0.2)", |p| p.closed_loop.motor.torque_constant_nm_per_a),
    Variable {
        vr: 1043,
        name: "motor.back_emf_v_s_per_rad",
        kind: Kind::Real,
        causality: Causality::Parameter,
        unit: "V.s/rad",
        description: "Back-EMF constant, V s/rad (equal to the torque constant in SI units)",
        range: Range::Positive,
        amplifier: None,
        get: |v| v.params.closed_loop.motor.back_emf(),
        set: Some(|v, x| v.params.closed_loop.motor.back_emf_v_s_per_rad = Some(x)),
    },
    param!(1044, "motor.inertia_kg_m2", Real, "kg.m2", Range::Positive, "Rotor plus input pulley inertia, kg m^2 (1e-4)", |p| p.closed_loop.motor.inertia_kg_m2),
    param!(1045, "motor.viscous_nm_s_per_rad", Real, "N.m.s/rad", Range::NonNegative, "Motor viscous friction, N m s/rad (1e-4)", |p| p.closed_loop.motor.viscous_nm_s_per_rad),
    param!(1046, "motor.coulomb_nm", Real, "N.m", Range::NonNegative, "Motor Coulomb friction, N m (0.005)", |p| p.closed_loop.motor.coulomb_nm),
    param!(1047, "motor.coulomb_smoothing_rad_s", Real, "rad/s", Range::Positive, "Speed below which motor Coulomb friction is linear in speed, rad/s (0.01)", |p| p.closed_loop.motor.coulomb_smoothing_rad_s),
    Variable {
        vr: 1048,
        name: "motor.current_limit_a",
        kind: Kind::Real,
        causality: Causality::Parameter,
        unit: "A",
        description: "Largest current of the current amplifier, A (8); 0 = unlimited",
        range: Range::NonNegative,
        amplifier: None,
        get: |v| limit_get(v.params.closed_loop.motor.current_limit_a),
        set: Some(|v, x| v.params.closed_loop.motor.current_limit_a = limit_set(x)),
    },
    Variable {
        vr: 1049,
        name: "motor.voltage_limit_v",
        kind: Kind::Real,
        causality: Causality::Parameter,
        unit: "V",
        description: "Largest voltage of the voltage amplifier, V (48); 0 = unlimited",
        range: Range::NonNegative,
        amplifier: None,
        get: |v| limit_get(v.params.closed_loop.motor.voltage_limit_v),
        set: Some(|v, x| v.params.closed_loop.motor.voltage_limit_v = limit_set(x)),
    },
    // Output drum.
    param!(1060, "output.inertia_kg_m2", Real, "kg.m2", Range::Positive, "Drum plus payload inertia, kg m^2 (0.05)", |p| p.closed_loop.output.inertia_kg_m2),
    param!(1061, "output.viscous_nm_s_per_rad", Real, "N.m.s/rad", Range::NonNegative, "Output bearing viscous friction, N m s/rad (1e-3)", |p| p.closed_loop.output.viscous_nm_s_per_rad),
    // Sensors.
    param!(1080, "sensors.motor_counts_per_rev", Integer, "", Range::IntegerFrom(4), "Motor encoder counts per revolution (2^20)", |p| p.closed_loop.sensors.motor_counts_per_rev),
    param!(1081, "sensors.output_counts_per_rev", Integer, "", Range::IntegerFrom(4), "Output encoder counts per revolution (2^23)", |p| p.closed_loop.sensors.output_counts_per_rev),
    param!(1082, "sensors.motor_noise_rad", Real, "rad", Range::NonNegative, "Standard deviation of motor encoder noise, rad (0 to 2e-6)", |p| p.closed_loop.sensors.motor_noise_rad),
    param!(1083, "sensors.output_noise_rad", Real, "rad", Range::NonNegative, "Standard deviation of output encoder noise, rad (0 to 2e-6)", |p| p.closed_loop.sensors.output_noise_rad),
    Variable {
        vr: 1084,
        name: "sensors.quantize",
        kind: Kind::Boolean,
        causality: Causality::Parameter,
        unit: "",
        description: "Whether encoder readings are whole counts",
        range: Range::Choice(2),
        amplifier: None,
        get: |v| f64::from(u8::from(v.params.closed_loop.sensors.quantize)),
        set: Some(|v, x| v.params.closed_loop.sensors.quantize = x != 0.0),
    },
    param!(1085, "sensors.seed", Integer, "", Range::IntegerFrom(0), "Seed of the encoder noise generator", |p| p.closed_loop.sensors.seed),
    // Cable law and solver.
    param!(1100, "cable.damping_ratio", Real, "", Range::Fraction, "Structural damping ratio of the cable's first drive mode (0.05)", |p| p.closed_loop.cable_damping_ratio),
    Variable {
        vr: 1101,
        name: "cable.model",
        kind: Kind::Integer,
        causality: Causality::Parameter,
        unit: "",
        description: "Cable law: 0 capstan with memory, 1 memoryless capstan, 2 linear springs",
        range: Range::Choice(3),
        amplifier: None,
        get: |v| v.params.model.code(),
        // Values reach the setters only after their range check.
        set: Some(|v, x| v.params.model = PlantModel::from_code(x).unwrap_or(PlantModel::Memory)),
    },
    param!(1102, "solver.max_step_s", Real, "s", Range::Positive, "Longest RK4 step inside a communication step, s (the scenario's control period, 1e-4)", |p| p.max_step_s),
];

/// The variable with value reference `vr` in an FMU with amplifier `amp`.
pub fn find(vr: u32, amp: Amplifier) -> Option<&'static Variable> {
    VARIABLES.iter().find(|v| v.vr == vr && v.present(amp))
}
