//! Scenario structs of the closed loop (`[closed_loop]` and its sub-tables) and their checks.
//!
//! Every key carries its unit in its name; the typical values quoted are those of a small
//! electro-optical turret on the published cable bench (ratio 5.125).

use serde::{Deserialize, Serialize};

use super::filters::FilterSpec;
use crate::metrics::los::LosParams;
use crate::physics::EffectsParams;
use crate::physics::{CableDrive, DriveParams, HysteresisModel, Routing};
use crate::signal::Signal;

pub use super::mode::CompensationMode;

/// How the plant's cable behaves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum CableModel {
    /// Capstan friction with memory (physics.md section 3), the real cable.
    #[default]
    Hysteretic,
    /// Linear spring per half with the preloaded drive's small-signal stiffness; for
    /// verification against linear theory and as a cost reference.
    Linear,
}

/// What the controller's output commands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Amplifier {
    /// Ideal current amplifier: the winding current equals the command (A), clipped to
    /// `current_limit_a`. The usual drive for a frameless torque motor.
    #[default]
    Current,
    /// Voltage amplifier: the command is the winding voltage (V), clipped to
    /// `voltage_limit_v`; the current follows `L di/dt = u - R i - Ke omega`.
    Voltage,
}

/// Which encoder closes the position loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Feedback {
    /// Motor encoder: the loop controls the motor angle against `ic*(r_out - e_pred)`.
    #[default]
    Motor,
    /// Output encoder: the loop controls the drum angle directly (error scaled by `ic` so
    /// the same gains apply); the compensator's shift enters through the reference-rate
    /// feedforward only.
    Output,
    /// The payload's inertial angle as the controller knows it: the sum of its own gyro
    /// samples times the sample period (scaled by `ic` like the output encoder). What a
    /// stabilised line of sight holds without a tracker; gyro bias makes it drift.
    GyroAngle,
}

/// How the axis stands at the start of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum StartState {
    /// At rest on the base (the drum turns with a moving base until the loop acts).
    #[default]
    AtRestOnBase,
    /// The payload inertially still, the drum turning against the base's rate: a
    /// stabilisation loop that has been running (a gyro integrates the start-up of a
    /// loop engaged on a moving base with its own lag, which leaves the line of sight
    /// offset by about the base rate times the gyro's delay).
    InertiallyStill,
}

/// What the inner rate loop measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum RateSource {
    /// The payload gyro (`[closed_loop.gyro]`): inertial rate, so base motion is rejected.
    #[default]
    Gyro,
    /// The motor encoder's backward difference over `ic`, low-passed: the drum's rate
    /// relative to the base (damps the drive, does not see base motion).
    MotorVelocity,
}

/// Inner rate loop (`[closed_loop.controller.rate_loop]`): the position PID's output
/// becomes an output-rate command (rad/s), and this PI turns the rate error into the
/// motor command:
///
/// ```text
/// w_cmd = PID(position) + r'                 (output rad/s)
/// u     = kp (w_cmd - w_meas) + ki T sum(w_cmd - w_meas)    (A or V)
/// ```
/// The position gains then have units (rad/s) per motor rad: with a fast rate loop the
/// position loop crosses over near `kp ic` rad/s (kp = 20 with ic = 5.125: about 16 Hz).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RateLoopParams {
    /// What the rate loop measures.
    #[serde(default)]
    pub measurement: RateSource,
    /// Proportional gain, command per output rad/s (about 5 A s/rad for a 0.05 kg m^2
    /// payload at 60 Hz rate bandwidth).
    /// Unit: A s/rad (V s/rad with a voltage amplifier), per output rad/s.
    /// Allowed: 0 to 1e9.
    pub kp: f64,
    /// Integral gain, command per output rad (about 500 A/rad).
    /// Unit: A/rad (V/rad with a voltage amplifier), per output rad.
    /// Allowed: 0 to 1e12.
    #[serde(default)]
    pub ki: f64,
    /// Corner of the low-pass on the motor-velocity estimate, Hz (500); unused with the gyro.
    /// Allowed: > 0 and below the Nyquist frequency (half of `controller.sample_rate_hz`).
    #[serde(default = "default_velocity_filter")]
    pub velocity_filter_hz: f64,
}

fn default_velocity_filter() -> f64 {
    500.0
}

/// Disturbance observer on the motor side (`[closed_loop.controller.disturbance_observer]`):
/// the nominal rigid axis `J s^2 theta_m = Kt i - d` inverted on the motor encoder, minus
/// the current the controller applied, both through the same second-order Q-filter, is
/// the disturbance estimate in amperes; it is subtracted from the command. Needs a current
/// amplifier.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DisturbanceObserverParams {
    /// Q-filter bandwidth, Hz (a fifth to a half of the drive resonance; 20 to 200).
    /// Allowed: > 0 and below the Nyquist frequency; needs `motor.amplifier = "current"`.
    pub bandwidth_hz: f64,
    /// Q-filter damping ratio (0.7).
    /// Allowed: > 0 and at most 10.
    /// Unit: 1.
    #[serde(default = "default_q_damping")]
    pub damping: f64,
    /// Nominal inertia at the motor, kg m^2; default: rotor plus the output inertia
    /// reflected through `ic^2` (the rigid drive).
    /// Allowed: > 0.
    #[serde(default)]
    pub inertia_kg_m2: Option<f64>,
}

fn default_q_damping() -> f64 {
    std::f64::consts::FRAC_1_SQRT_2
}

/// Rate gyro on the payload (`[closed_loop.gyro]`): measures the payload's inertial rate
/// `omega_out + base rate` through a second-order response, adds white noise, a bias and
/// quantisation, and is sampled at its own rate (the control rate divided by a whole
/// number; the controller holds the latest sample).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GyroParams {
    /// Bandwidth of the second-order response, Hz (a MEMS or FOG gyro: 200 to 1000).
    /// Allowed: > 0 and below the Nyquist frequency (half of `controller.sample_rate_hz`).
    #[serde(default = "default_gyro_bandwidth")]
    pub bandwidth_hz: f64,
    /// Damping ratio of that response (0.7).
    /// Allowed: > 0 and at most 10.
    /// Unit: 1.
    #[serde(default = "default_q_damping")]
    pub damping: f64,
    /// Rate noise density, rad/s/sqrt(Hz), one-sided (a tactical FOG: 5e-6; a MEMS gyro:
    /// 5e-5). Each sample carries white noise of standard deviation
    /// `density * sqrt(sample_rate / 2)`.
    /// Allowed: 0 to 1.
    #[serde(default)]
    pub noise_density_rad_s_per_sqrt_hz: f64,
    /// Constant bias, rad/s (1e-6 for a FOG, 1e-4 for a MEMS gyro).
    /// Allowed: -1 to 1.
    #[serde(default)]
    pub bias_rad_s: f64,
    /// Output resolution, rad/s per count (0 = continuous; 1e-6 typical).
    /// Allowed: 0 to 1.
    #[serde(default)]
    pub quantization_rad_s: f64,
    /// Sample rate, Hz; the control rate divided by a whole number. Default: the control
    /// rate.
    /// Allowed: > 0 and at most the control rate, which it must divide by a whole number.
    #[serde(default)]
    pub sample_rate_hz: Option<f64>,
    /// Seed of the gyro's noise (kept apart from the encoders').
    /// Allowed: any whole number from 0.
    #[serde(default = "default_gyro_seed")]
    pub seed: u64,
}

fn default_gyro_bandwidth() -> f64 {
    500.0
}
fn default_gyro_seed() -> u64 {
    2
}

impl Default for GyroParams {
    fn default() -> Self {
        GyroParams {
            bandwidth_hz: default_gyro_bandwidth(),
            damping: default_q_damping(),
            noise_density_rad_s_per_sqrt_hz: 0.0,
            bias_rad_s: 0.0,
            quantization_rad_s: 0.0,
            sample_rate_hz: None,
            seed: default_gyro_seed(),
        }
    }
}

impl GyroParams {
    /// Control samples per gyro sample, given the control rate; `None` when the gyro rate
    /// is not the control rate divided by a whole number.
    pub fn decimation(&self, control_rate_hz: f64) -> Option<u32> {
        let fg = self.sample_rate_hz.unwrap_or(control_rate_hz);
        let n = control_rate_hz / fg;
        let r = n.round();
        ((n - r).abs() < 1e-9 * n.max(1.0) && (1.0..=1e6).contains(&r)).then_some(r as u32)
    }
}

/// Torque motor with rotor and input pulley.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotorParams {
    /// Amplifier type (what the controller output means).
    #[serde(default)]
    pub amplifier: Amplifier,
    /// Winding resistance, ohm (1 to 3 for a frameless torque motor).
    /// Allowed: 1e-3 to 1e3.
    pub resistance_ohm: f64,
    /// Winding inductance, H (about 1e-3).
    /// Allowed: 1e-7 to 10.
    pub inductance_h: f64,
    /// Torque constant `Kt`, N m/A (0.1 to 0.3).
    /// Allowed: 1e-4 to 100.
    pub torque_constant_nm_per_a: f64,
    /// Back-EMF constant `Ke`, V s/rad; defaults to `Kt` (equal in SI units).
    /// Allowed: 1e-4 to 100.
    #[serde(default)]
    pub back_emf_v_s_per_rad: Option<f64>,
    /// Rotor plus input pulley inertia, kg m^2 (about 1e-4).
    /// Allowed: 1e-9 to 10.
    pub inertia_kg_m2: f64,
    /// Viscous friction of the motor bearings, N m s/rad (about 1e-4).
    /// Allowed: 0 to 100.
    #[serde(default)]
    pub viscous_nm_s_per_rad: f64,
    /// Coulomb friction of the motor bearings and seals, N m (0.002 to 0.02).
    /// Allowed: 0 to 1e3.
    #[serde(default)]
    pub coulomb_nm: f64,
    /// Speed below which motor Coulomb friction is linear in speed, rad/s (0.01). Keeps the
    /// friction Lipschitz so the fixed-step integrator cannot chatter at zero speed.
    /// Allowed: 1e-6 to 10.
    #[serde(default = "default_coulomb_smoothing")]
    pub coulomb_smoothing_rad_s: f64,
    /// Largest current the amplifier delivers, A (5 to 10); also the controller's output
    /// limit with a current amplifier. None = unlimited.
    /// Allowed: 1e-3 to 1e4.
    #[serde(default)]
    pub current_limit_a: Option<f64>,
    /// Largest voltage the amplifier delivers, V (24 to 48); the controller's output limit
    /// with a voltage amplifier. None = unlimited.
    /// Allowed: 1e-3 to 1e5.
    #[serde(default)]
    pub voltage_limit_v: Option<f64>,
}

fn default_coulomb_smoothing() -> f64 {
    0.01
}

impl MotorParams {
    /// Back-EMF constant actually used, V s/rad.
    pub fn back_emf(&self) -> f64 {
        self.back_emf_v_s_per_rad
            .unwrap_or(self.torque_constant_nm_per_a)
    }

    /// Output limit of the controller in command units (A or V); `f64::INFINITY` if none.
    pub fn command_limit(&self) -> f64 {
        match self.amplifier {
            Amplifier::Current => self.current_limit_a,
            Amplifier::Voltage => self.voltage_limit_v,
        }
        .unwrap_or(f64::INFINITY)
    }
}

impl Default for MotorParams {
    fn default() -> Self {
        MotorParams {
            amplifier: Amplifier::Current,
            resistance_ohm: 2.0,
            inductance_h: 1e-3,
            torque_constant_nm_per_a: 0.2,
            back_emf_v_s_per_rad: None,
            inertia_kg_m2: 1e-4,
            viscous_nm_s_per_rad: 1e-4,
            coulomb_nm: 0.005,
            coulomb_smoothing_rad_s: default_coulomb_smoothing(),
            current_limit_a: Some(8.0),
            voltage_limit_v: Some(48.0),
        }
    }
}

/// Output drum with payload.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputParams {
    /// Drum plus payload inertia about the axis, kg m^2 (0.02 to 0.1).
    /// Allowed: 1e-6 to 1e4.
    pub inertia_kg_m2: f64,
    /// Viscous friction of the output bearings, N m s/rad (about 1e-3).
    /// Allowed: 0 to 1e3.
    #[serde(default)]
    pub viscous_nm_s_per_rad: f64,
}

impl Default for OutputParams {
    fn default() -> Self {
        OutputParams {
            inertia_kg_m2: 0.05,
            viscous_nm_s_per_rad: 0.0,
        }
    }
}

/// Encoders.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorParams {
    /// Motor encoder counts per revolution (2^20 = 1048576 is a common absolute encoder).
    /// Allowed: at least 4 when `quantize` is true.
    pub motor_counts_per_rev: u64,
    /// Output encoder counts per revolution (2^20 or more; 0.1 mrad needs well under
    /// 0.01 mrad per count, i.e. more than 6.3e5 counts).
    /// Allowed: at least 4 when `quantize` is true.
    pub output_counts_per_rev: u64,
    /// Standard deviation of white motor-encoder noise, rad (0 to 2e-6).
    /// Allowed: 0 to 0.1.
    #[serde(default)]
    pub motor_noise_rad: f64,
    /// Standard deviation of white output-encoder noise, rad (0 to 2e-6).
    /// Allowed: 0 to 0.1.
    #[serde(default)]
    pub output_noise_rad: f64,
    /// Whether readings are quantised to whole counts (false gives continuous readings).
    #[serde(default = "default_true")]
    pub quantize: bool,
    /// Seed of the noise generator; the same seed is used for every mode.
    /// Allowed: any whole number from 0.
    #[serde(default = "default_seed")]
    pub seed: u64,
}

fn default_true() -> bool {
    true
}
fn default_seed() -> u64 {
    1
}

impl Default for SensorParams {
    fn default() -> Self {
        SensorParams {
            motor_counts_per_rev: 1 << 20,
            output_counts_per_rev: 1 << 20,
            motor_noise_rad: 0.0,
            output_noise_rad: 0.0,
            quantize: true,
            seed: 1,
        }
    }
}

/// Sampled position controller. Gains act on the motor-angle error in rad (with output
/// feedback the output error times `ic`), the output is a command in A or V.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerParams {
    /// Sample rate with zero-order hold, Hz (10000 on the bench loop).
    /// Allowed: 10 to 1e6, at least ten times the plant's fastest mode (the message gives
    /// it), and 2 to 1e9 periods over `duration_s`.
    pub sample_rate_hz: f64,
    /// Encoder that closes the loop.
    #[serde(default)]
    pub feedback: Feedback,
    /// Proportional gain, command per rad (about 1000 A/rad for a 50 Hz loop).
    /// Unit: A/rad (V/rad with a voltage amplifier; with a rate loop, output rad/s per
    /// motor rad).
    /// Allowed: 0 to 1e9.
    pub kp: f64,
    /// Integral gain, command per rad s (about 5e4 A/(rad s)).
    /// Unit: A/(rad s) (V/(rad s) with a voltage amplifier).
    /// Allowed: 0 to 1e12.
    #[serde(default)]
    pub ki: f64,
    /// Derivative gain, command s per rad (about 5 A s/rad); acts on the measurement.
    /// Unit: A s/rad (V s/rad with a voltage amplifier).
    /// Allowed: 0 to 1e6.
    #[serde(default)]
    pub kd: f64,
    /// Corner of the first-order derivative filter, Hz (about 1000).
    /// Allowed: > 0.
    #[serde(default = "default_derivative_filter")]
    pub derivative_filter_hz: f64,
    /// Velocity feedforward, command per rad/s of motor reference rate (viscous and
    /// back-EMF terms; about 5e-4 A s/rad).
    /// Unit: A s/rad (V s/rad with a voltage amplifier).
    /// Allowed: 0 to 1e3.
    #[serde(default)]
    pub velocity_feedforward: f64,
    /// Acceleration feedforward, command per rad/s^2 of motor reference acceleration
    /// (total reflected inertia over `Kt`, about 0.01 A s^2/rad).
    /// Unit: A s^2/rad (V s^2/rad with a voltage amplifier).
    /// Allowed: 0 to 1e3.
    #[serde(default)]
    pub acceleration_feedforward: f64,
    /// Whether the predicted transmitted torque (load model plus output inertia) is fed
    /// forward as motor torque, in every mode.
    #[serde(default)]
    pub load_feedforward: bool,
    /// Time over which the predicted brake torque reverses after the reference turns, s
    /// (0.02). The real brake reverses only as the cable winds up; a gradual prediction
    /// keeps the shifted reference free of steps.
    /// Allowed: 0 to 100.
    #[serde(default = "default_brake_transition")]
    pub brake_transition_s: f64,
    /// Computation delay from sampling the sensors to applying the new command, in control
    /// periods (1 = the command computed from the samples at `t_k` is applied at
    /// `t_{k+1}`, as a drive that computes during the period does; fractions switch the
    /// held command inside the period). 0 to 4; default 1.
    /// Allowed: 0 to 4.
    /// Unit: control periods.
    #[serde(default = "default_computation_delay")]
    pub computation_delay_samples: f64,
    /// Inner rate loop; none: the PID commands the motor directly.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rate_loop: Option<RateLoopParams>,
    /// Filters on the position measurement, before the PID (e.g. a low-pass on a noisy
    /// integrated gyro angle).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub measurement_filters: Vec<FilterSpec>,
    /// Filters on the rate command (the position loop's output; rate loop only).
    /// Allowed: only with a `rate_loop`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rate_command_filters: Vec<FilterSpec>,
    /// Filters on the rate measurement (rate loop only; e.g. a low-pass above the gyro).
    /// Allowed: only with a `rate_loop`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rate_measurement_filters: Vec<FilterSpec>,
    /// Filters on the feedback command, before the feedforward is added and before the
    /// amplifier (a notch at the cable-drive resonance goes here).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub command_filters: Vec<FilterSpec>,
    /// Disturbance observer on the motor side; none by default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub disturbance_observer: Option<DisturbanceObserverParams>,
}

impl ControllerParams {
    /// Whether the law is today's single PID (no rate loop, filters or observer): that
    /// path is kept exactly as it was.
    pub fn is_plain_pid(&self) -> bool {
        self.rate_loop.is_none()
            && self.measurement_filters.is_empty()
            && self.rate_command_filters.is_empty()
            && self.rate_measurement_filters.is_empty()
            && self.command_filters.is_empty()
            && self.disturbance_observer.is_none()
    }
}

/// Largest computation delay accepted, control periods.
pub const MAX_COMPUTATION_DELAY_SAMPLES: f64 = 4.0;

fn default_computation_delay() -> f64 {
    1.0
}
fn default_derivative_filter() -> f64 {
    1000.0
}
fn default_brake_transition() -> f64 {
    0.02
}

impl Default for ControllerParams {
    fn default() -> Self {
        ControllerParams {
            sample_rate_hz: 10_000.0,
            feedback: Feedback::Motor,
            kp: 1000.0,
            ki: 5e4,
            kd: 5.0,
            derivative_filter_hz: default_derivative_filter(),
            velocity_feedforward: 0.0,
            acceleration_feedforward: 0.0,
            load_feedforward: false,
            brake_transition_s: default_brake_transition(),
            computation_delay_samples: default_computation_delay(),
            rate_loop: None,
            measurement_filters: Vec::new(),
            rate_command_filters: Vec::new(),
            rate_measurement_filters: Vec::new(),
            command_filters: Vec::new(),
            disturbance_observer: None,
        }
    }
}

/// Drive parameters of the compensator copy that differ from the plant's `[drive]` (to
/// study model mismatch). Unset keys take the plant's value.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct DriveOverride {
    /// Cable routing.
    #[serde(default)]
    pub routing: Option<Routing>,
    /// Motor pulley radius, m.
    /// Allowed: as `drive.pulley_radius_m`: 1e-4 to 10.
    #[serde(default)]
    pub pulley_radius_m: Option<f64>,
    /// Drum radius, m.
    /// Allowed: as `drive.drum_radius_m`: 1e-4 to 10.
    #[serde(default)]
    pub drum_radius_m: Option<f64>,
    /// Centre distance, m.
    /// Allowed: as `drive.center_distance_m`.
    #[serde(default)]
    pub center_distance_m: Option<f64>,
    /// Cable tensile stiffness `E*A`, N (1.4e4 nominal).
    /// Allowed: as `drive.cable_modulus_n`: 1 to 1e10.
    #[serde(default)]
    pub cable_modulus_n: Option<f64>,
    /// Friction coefficient (0.2 nominal).
    /// Allowed: as `drive.friction_coefficient`: > 0 and at most 1.
    #[serde(default)]
    pub friction_coefficient: Option<f64>,
    /// Preload, N (100 nominal).
    /// Allowed: as `drive.preload_n`: > 0 and at most 5 % of the cable modulus.
    #[serde(default)]
    pub preload_n: Option<f64>,
    /// Drum wrap per half, rad.
    /// Allowed: as `drive.drum_wrap_rad`: > 0 and at most 20 pi.
    #[serde(default)]
    pub drum_wrap_rad: Option<f64>,
    /// Total pulley wrap, rad.
    /// Allowed: as `drive.pulley_wrap_rad`: > 0 and at most 200 pi.
    #[serde(default)]
    pub pulley_wrap_rad: Option<f64>,
}

impl DriveOverride {
    /// The plant's parameters with these overrides applied.
    pub fn apply(&self, base: &DriveParams) -> DriveParams {
        DriveParams {
            routing: self.routing.unwrap_or(base.routing),
            pulley_radius_m: self.pulley_radius_m.unwrap_or(base.pulley_radius_m),
            drum_radius_m: self.drum_radius_m.unwrap_or(base.drum_radius_m),
            center_distance_m: self.center_distance_m.unwrap_or(base.center_distance_m),
            cable_modulus_n: self.cable_modulus_n.unwrap_or(base.cable_modulus_n),
            friction_coefficient: self
                .friction_coefficient
                .unwrap_or(base.friction_coefficient),
            preload_n: self.preload_n.unwrap_or(base.preload_n),
            drum_wrap_rad: self.drum_wrap_rad.unwrap_or(base.drum_wrap_rad),
            pulley_wrap_rad: self.pulley_wrap_rad.unwrap_or(base.pulley_wrap_rad),
        }
    }
}

/// Closed-loop study (`[closed_loop]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClosedLoopParams {
    /// Simulated time, s (20 for two periods of a 0.1 Hz sine).
    /// Allowed: > 0 and at most 1e5.
    pub duration_s: f64,
    /// Start of the metrics window, s; excludes start-up transients (2).
    /// Allowed: >= 0 and below `duration_s`.
    #[serde(default = "default_metrics_start")]
    pub metrics_start_s: f64,
    /// Pointing requirement on the output, mrad (0.1 for EOTS line of sight).
    /// Allowed: > 0.
    #[serde(default = "default_target")]
    pub target_mrad: f64,
    /// Band around the final value that counts as settled after a step, mrad; defaults to
    /// `target_mrad`.
    /// Allowed: > 0.
    #[serde(default)]
    pub settle_band_mrad: Option<f64>,
    /// Compensation modes to simulate side by side.
    /// Allowed: at least one of `"none"`, `"memoryless"`, `"memory"`, each once.
    #[serde(default = "default_modes")]
    pub modes: Vec<CompensationMode>,
    /// What the design must meet besides `target_mrad` (`[closed_loop.requirements]`):
    /// margins over the operating range, and optional RMS, jitter, settling and base-motion
    /// rejection. Every command judges the design by these.
    #[serde(default)]
    pub requirements: super::requirements::Requirements,
    /// Desired output (drum) angle `r_out` against time, rad.
    /// Allowed: any signal kind; it must stay within 100 rad of zero over the run.
    pub reference: Signal,
    /// Cable law of the plant.
    #[serde(default)]
    pub cable: CableModel,
    /// Damping ratio of the cable's structural damping on the first drive mode (0.02 to
    /// 0.1); converted to a viscous term per half by
    /// [`ClosedLoopParams::cable_damping_n_s_per_m`].
    /// Allowed: 0 to below 1.
    #[serde(default = "default_cable_damping")]
    pub cable_damping_ratio: f64,
    /// Fixed RK4 steps per control period (1 suffices when the fastest mode is well below
    /// the sample rate; the validation says when more are needed).
    /// Allowed: 1 to 1000, and enough for the plant's fastest rate (the message gives the
    /// least).
    #[serde(default = "default_substeps")]
    pub rk4_substeps: u32,
    /// Rows per second kept in the time series, Hz (1000: a row every millisecond, which
    /// resolves the loop's 30 Hz bandwidth; at most the control rate, which keeps every
    /// sample). Metrics always use every control sample.
    /// Allowed: > 0 (above the control rate keeps every sample).
    #[serde(default = "default_timeseries_rate")]
    pub timeseries_rate_hz: f64,
    /// Torque motor.
    #[serde(default)]
    pub motor: MotorParams,
    /// Output drum and payload.
    #[serde(default)]
    pub output: OutputParams,
    /// Encoders.
    #[serde(default)]
    pub sensors: SensorParams,
    /// Sampled controller.
    pub controller: ControllerParams,
    /// Compensator cable parameters where they differ from the plant's `[drive]`.
    #[serde(default)]
    pub compensator_drive: Option<DriveOverride>,
    /// Whether the memoryless and memory compensators also use the identified effects:
    /// they subtract the predicted kinematic error (runouts, thermal drift; rad) from the
    /// shifted motor reference and add the bearing friction (N m) to the predicted brake
    /// torque. Needs `[closed_loop.compensator_effects]` or the scenario's `[effects]`.
    /// Allowed: `true` needs `[effects]` or `[closed_loop.compensator_effects]`.
    #[serde(default)]
    pub compensate_effects: bool,
    /// The compensator's copy of the effects where it differs from the plant's `[effects]`
    /// (same keys and units); defaults to the plant's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compensator_effects: Option<EffectsParams>,
    /// Angular motion of the base (vehicle, aircraft) about the axis, rad: any signal kind
    /// (`sine`, `sum` of sines, a CSV `table`, or a random motion from a `psd` table).
    /// Bearing friction, drag and the motor act relative to the base; the line of sight is
    /// the base angle plus the drum's angle, and the pointing error is its inertial error.
    /// Allowed: any signal kind, with content below a tenth of the control rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_motion: Option<Signal>,
    /// How the axis stands at t = 0 (matters only under base motion).
    #[serde(default)]
    pub start: StartState,
    /// Rate gyro on the payload; needed by a gyro rate loop or gyro-angle feedback.
    /// Allowed: needed by a gyro rate loop or `feedback = "gyro_angle"`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gyro: Option<GyroParams>,
    /// Line-of-sight statistics: exposure time for jitter, PSD segment length.
    #[serde(default)]
    pub los: LosParams,
    /// Whether `run` also writes an error budget: the run repeated with each effect
    /// switched off in turn (one extra run per effect present, plus one with all off).
    #[serde(default)]
    pub error_budget: bool,
    /// How `cable-servo freqresp` measures this loop (`[closed_loop.freqresp]`): loop
    /// point, frequencies and amplitudes (the margins are judged by `requirements`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub freqresp: Option<super::probe::FreqRespParams>,
}

fn default_metrics_start() -> f64 {
    2.0
}
fn default_target() -> f64 {
    0.1
}
fn default_modes() -> Vec<CompensationMode> {
    vec![
        CompensationMode::None,
        CompensationMode::Memoryless,
        CompensationMode::Memory,
    ]
}
fn default_cable_damping() -> f64 {
    0.05
}
fn default_substeps() -> u32 {
    1
}

fn default_timeseries_rate() -> f64 {
    1000.0
}

/// Linearised rates of the plant used for step-size and sample-rate checks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantModes {
    /// Small-signal stiffness of one cable half at preload, N/m (`G/Lf` plus wrap terms;
    /// 1.8e5 on the bench).
    pub half_stiffness_n_per_m: f64,
    /// Drive mode with the drum free, rad/s.
    pub free_mode_rad_s: f64,
    /// Motor on the cable with the drum held by the brake, rad/s.
    pub locked_mode_rad_s: f64,
    /// Fastest rate of the plant (modes, electrical pole, friction linear zone), rad/s.
    pub fastest_rad_s: f64,
}

impl ClosedLoopParams {
    /// The compensation mode whose pointing error the verdict judges:
    /// `requirements.mode`, else the last mode listed.
    pub fn judged_mode(&self) -> CompensationMode {
        self.requirements
            .mode
            .or_else(|| self.modes.last().copied())
            .unwrap_or(CompensationMode::None)
    }

    /// Small-signal stiffness of one half of the preloaded drive, N/m: the inverse of
    /// `d elong / d T` at the preload (a virgin wrap adds nothing there, so this is `G/Lf`).
    pub fn half_stiffness_n_per_m(drive: &DriveParams) -> f64 {
        let d = CableDrive::new(drive.clone(), HysteresisModel::Memory);
        1.0 / d.upper().trial(drive.preload_n).d_elongation_m_per_n
    }

    /// Linearised plant rates for the given drive.
    pub fn plant_modes(&self, drive: &DriveParams) -> PlantModes {
        let k = Self::half_stiffness_n_per_m(drive);
        let (ri, ro) = (drive.pulley_radius_m, drive.drum_radius_m);
        let jm = self.motor.inertia_kg_m2;
        let jo = self.output.inertia_kg_m2;
        // Both halves act in parallel on D = ri*theta_in - ro*theta_out.
        let k_d = 2.0 * k;
        let free = (k_d * (ri * ri / jm + ro * ro / jo)).sqrt();
        let locked = (k_d * ri * ri / jm).sqrt();
        let mut fastest = free.max(locked);
        if self.motor.amplifier == Amplifier::Voltage {
            fastest = fastest.max(self.motor.resistance_ohm / self.motor.inductance_h);
        }
        if self.motor.coulomb_nm > 0.0 {
            fastest =
                fastest.max(self.motor.coulomb_nm / (self.motor.coulomb_smoothing_rad_s * jm));
        }
        let c = self.cable_damping_n_s_per_m(drive);
        fastest = fastest.max(2.0 * c * (ri * ri / jm + ro * ro / jo));
        if let Some(g) = &self.gyro {
            fastest = fastest.max(std::f64::consts::TAU * g.bandwidth_hz * g.damping.max(1.0));
        }
        PlantModes {
            half_stiffness_n_per_m: k,
            free_mode_rad_s: free,
            locked_mode_rad_s: locked,
            fastest_rad_s: fastest,
        }
    }

    /// Viscous coefficient of each half, N s/m (about 15 on the bench): the value that
    /// gives the free drive mode the damping ratio `cable_damping_ratio`.
    pub fn cable_damping_n_s_per_m(&self, drive: &DriveParams) -> f64 {
        let k = Self::half_stiffness_n_per_m(drive);
        let (ri, ro) = (drive.pulley_radius_m, drive.drum_radius_m);
        let inv_m = ri * ri / self.motor.inertia_kg_m2 + ro * ro / self.output.inertia_kg_m2;
        // Mode in D: D'' = -(2k D + 2c D') * inv_m, so 2c*inv_m = 2 zeta omega.
        let omega = (2.0 * k * inv_m).sqrt();
        self.cable_damping_ratio * omega / inv_m
    }

    /// Compensator drive parameters (plant's with the overrides).
    pub fn compensator_params(&self, drive: &DriveParams) -> DriveParams {
        match &self.compensator_drive {
            Some(o) => o.apply(drive),
            None => drive.clone(),
        }
    }

    /// Effects the compensator uses, given the plant's `[effects]`: `None` unless
    /// `compensate_effects` is on.
    pub fn compensator_effects<'a>(
        &'a self,
        plant: Option<&'a EffectsParams>,
    ) -> Option<&'a EffectsParams> {
        if self.compensate_effects {
            self.compensator_effects.as_ref().or(plant)
        } else {
            None
        }
    }

    /// Check the effects options against the plant's `[effects]`; returns `(dotted key,
    /// message)`.
    pub fn validate_effects(&self, plant: Option<&EffectsParams>) -> Result<(), (String, String)> {
        if let Some(fx) = &self.compensator_effects {
            fx.validate()
                .map_err(|(k, m)| (format!("closed_loop.compensator_effects.{k}"), m))?;
        }
        if self.compensate_effects && self.compensator_effects(plant).is_none() {
            return Err((
                "closed_loop.compensate_effects".into(),
                "true needs effects to compensate: an [effects] section (as written by `diagnose --save-model`) or [closed_loop.compensator_effects]".into(),
            ));
        }
        Ok(())
    }

    /// Number of control periods in the run.
    pub fn periods(&self) -> u64 {
        (self.duration_s * self.controller.sample_rate_hz).round() as u64
    }

    /// Control samples per time-series row (1 keeps every sample).
    pub fn timeseries_decimation(&self) -> usize {
        let ratio = self.controller.sample_rate_hz / self.timeseries_rate_hz;
        if ratio.is_finite() && ratio > 1.0 {
            ratio.round() as usize
        } else {
            1
        }
    }

    /// Check ranges and consistency; returns `(dotted key, message)` of the first problem.
    pub fn validate(&self, drive: &DriveParams) -> Result<(), (String, String)> {
        let key = |k: &str| format!("closed_loop.{k}");
        if !(self.timeseries_rate_hz.is_finite() && self.timeseries_rate_hz > 0.0) {
            return Err((
                key("timeseries_rate_hz"),
                format!(
                    "{} must be a positive rate in Hz (1000 keeps a row every millisecond; the control rate keeps every sample)",
                    crate::number(self.timeseries_rate_hz)
                ),
            ));
        }
        let pos = |k: &str, v: f64| -> Result<(), (String, String)> {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err((key(k), crate::out_of_range(v, "a finite number > 0")))
            }
        };
        let nonneg = |k: &str, v: f64| -> Result<(), (String, String)> {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err((key(k), crate::out_of_range(v, "a finite number >= 0")))
            }
        };
        pos("duration_s", self.duration_s)?;
        if self.duration_s > 1e5 {
            return Err((
                key("duration_s"),
                format!("{} s is longer than 1e5 s", crate::number(self.duration_s)),
            ));
        }
        nonneg("metrics_start_s", self.metrics_start_s)?;
        if self.metrics_start_s >= self.duration_s {
            return Err((
                key("metrics_start_s"),
                format!(
                    "{} must be below duration_s = {} so the metrics window is not empty",
                    crate::number(self.metrics_start_s),
                    crate::number(self.duration_s)
                ),
            ));
        }
        pos("target_mrad", self.target_mrad)?;
        if let Some(b) = self.settle_band_mrad {
            pos("settle_band_mrad", b)?;
        }
        if self.modes.is_empty() {
            return Err((
                key("modes"),
                "list at least one of \"none\", \"memoryless\", \"memory\"".into(),
            ));
        }
        for (i, m) in self.modes.iter().enumerate() {
            if self.modes[..i].contains(m) {
                return Err((key("modes"), format!("\"{}\" is listed twice", m.name())));
            }
        }
        self.requirements
            .validate(self.controller.sample_rate_hz)
            .map_err(|(k, m)| (key(&k), m))?;
        if let Some(m) = self.requirements.mode {
            if !self.modes.contains(&m) {
                return Err((
                    key("requirements.mode"),
                    format!(
                        "\"{}\" is not simulated: list it in closed_loop.modes",
                        m.name()
                    ),
                ));
            }
        }
        check_reference(&self.reference).map_err(|m| (key("reference"), m))?;
        // A reference the loop samples below twice its fastest repetition is aliased: the
        // run would track some other signal, or diverge and blame the gains.
        let nyquist = 0.5 * self.controller.sample_rate_hz;
        let fastest = self.reference.fastest_frequency_hz();
        // A rate that is no rate at all is named by its own check below.
        if self.controller.sample_rate_hz.is_finite() && nyquist > 0.0 && fastest >= nyquist {
            return Err((
                key("reference"),
                format!(
                    "it repeats at up to {} Hz, at or above the Nyquist frequency {} Hz of controller.sample_rate_hz = {} Hz: give a slower reference or a faster control rate",
                    crate::number(fastest),
                    crate::number(nyquist),
                    crate::number(self.controller.sample_rate_hz)
                ),
            ));
        }
        if !(self.cable_damping_ratio.is_finite()
            && self.cable_damping_ratio >= 0.0
            && self.cable_damping_ratio < 1.0)
        {
            return Err((
                key("cable_damping_ratio"),
                format!(
                    "{} must be in [0, 1)",
                    crate::number(self.cable_damping_ratio)
                ),
            ));
        }
        if !(1..=1000).contains(&self.rk4_substeps) {
            return Err((
                key("rk4_substeps"),
                format!("{} must be in 1..=1000", self.rk4_substeps),
            ));
        }
        let m = &self.motor;
        pos("motor.resistance_ohm", m.resistance_ohm)?;
        pos("motor.inductance_h", m.inductance_h)?;
        pos("motor.torque_constant_nm_per_a", m.torque_constant_nm_per_a)?;
        pos("motor.back_emf_v_s_per_rad", m.back_emf())?;
        pos("motor.inertia_kg_m2", m.inertia_kg_m2)?;
        nonneg("motor.viscous_nm_s_per_rad", m.viscous_nm_s_per_rad)?;
        nonneg("motor.coulomb_nm", m.coulomb_nm)?;
        pos("motor.coulomb_smoothing_rad_s", m.coulomb_smoothing_rad_s)?;
        if let Some(v) = m.current_limit_a {
            pos("motor.current_limit_a", v)?;
        }
        if let Some(v) = m.voltage_limit_v {
            pos("motor.voltage_limit_v", v)?;
        }
        pos("output.inertia_kg_m2", self.output.inertia_kg_m2)?;
        nonneg(
            "output.viscous_nm_s_per_rad",
            self.output.viscous_nm_s_per_rad,
        )?;
        let s = &self.sensors;
        if s.quantize {
            for (k, v) in [
                ("sensors.motor_counts_per_rev", s.motor_counts_per_rev),
                ("sensors.output_counts_per_rev", s.output_counts_per_rev),
            ] {
                if v < 4 {
                    return Err((key(k), format!("{v} must be at least 4 counts")));
                }
            }
        }
        nonneg("sensors.motor_noise_rad", s.motor_noise_rad)?;
        nonneg("sensors.output_noise_rad", s.output_noise_rad)?;
        let c = &self.controller;
        pos("controller.sample_rate_hz", c.sample_rate_hz)?;
        if !(0.0..=MAX_COMPUTATION_DELAY_SAMPLES).contains(&c.computation_delay_samples) {
            return Err((
                key("controller.computation_delay_samples"),
                format!(
                    "{} is outside 0 to {MAX_COMPUTATION_DELAY_SAMPLES} control periods (1 = the command computed at one sample is applied at the next)",
                    crate::number(c.computation_delay_samples)
                ),
            ));
        }
        for (k, v) in [
            ("controller.kp", c.kp),
            ("controller.ki", c.ki),
            ("controller.kd", c.kd),
            ("controller.velocity_feedforward", c.velocity_feedforward),
            (
                "controller.acceleration_feedforward",
                c.acceleration_feedforward,
            ),
            ("controller.brake_transition_s", c.brake_transition_s),
        ] {
            nonneg(k, v)?;
        }
        pos("controller.derivative_filter_hz", c.derivative_filter_hz)?;
        self.validate_ranges()?;
        let periods = self.duration_s * c.sample_rate_hz;
        if periods > 1e9 {
            return Err((
                key("controller.sample_rate_hz"),
                format!("{periods:.0} control periods is too many (at most 1e9); lower the rate or duration_s"),
            ));
        }
        if periods < 2.0 {
            return Err((
                key("controller.sample_rate_hz"),
                format!(
                    "{periods:.1} control periods in duration_s: raise the rate or the duration"
                ),
            ));
        }
        self.validate_structure()?;
        if self.compensator_drive.is_some() {
            self.compensator_params(drive).validate().map_err(|e| {
                (
                    key("compensator_drive"),
                    e.to_string().replace("drive.", "compensator_drive."),
                )
            })?;
        }
        let modes = self.plant_modes(drive);
        let fast_hz = modes.fastest_rad_s / std::f64::consts::TAU;
        if c.sample_rate_hz < 10.0 * fast_hz {
            return Err((
                key("controller.sample_rate_hz"),
                format!(
                    "{} Hz is not well above the plant's fastest mode ({} Hz: drive mode {} Hz, drum-held mode {} Hz, electrical and friction rates included); use at least {} Hz, or soften the fast element",
                    crate::number(c.sample_rate_hz),
                    crate::fixed(fast_hz, 0),
                    crate::fixed(modes.free_mode_rad_s / std::f64::consts::TAU, 0),
                    crate::fixed(modes.locked_mode_rad_s / std::f64::consts::TAU, 0),
                    crate::fixed(10.0 * fast_hz, 0)
                ),
            ));
        }
        let h = 1.0 / (c.sample_rate_hz * f64::from(self.rk4_substeps));
        if modes.fastest_rad_s * h > 1.0 {
            return Err((
                key("rk4_substeps"),
                format!(
                    "{} RK4 steps per period are too few for the fastest plant rate {:.0} rad/s: use at least {}",
                    self.rk4_substeps,
                    modes.fastest_rad_s,
                    (modes.fastest_rad_s / c.sample_rate_hz).ceil()
                ),
            ));
        }
        Ok(())
    }
}

/// Largest angle a closed-loop reference may reach, rad: about 16 turns, more than any
/// pointing run turns a gimbal axis (a larger value is a unit slip, degrees for radians).
pub const MAX_POINTING_RAD: f64 = 100.0;

impl ClosedLoopParams {
    /// Physical ranges of the loop's numbers: values far outside any servo axis (a
    /// resistance of 1e-300 ohm, an inertia of 1e30 kg m^2) pass the sign checks but only
    /// produce absurd angles or a solver that cannot keep up; each bound says why.
    fn validate_ranges(&self) -> Result<(), (String, String)> {
        let key = |k: &str| format!("closed_loop.{k}");
        let m = &self.motor;
        let c = &self.controller;
        let mut checks: Vec<(&str, f64, f64, f64, &str)> = vec![
            (
                "motor.resistance_ohm",
                m.resistance_ohm,
                1e-3,
                1e3,
                "a winding's resistance",
            ),
            (
                "motor.inductance_h",
                m.inductance_h,
                1e-7,
                10.0,
                "a winding's inductance",
            ),
            (
                "motor.torque_constant_nm_per_a",
                m.torque_constant_nm_per_a,
                1e-4,
                100.0,
                "a torque motor's constant",
            ),
            (
                "motor.back_emf_v_s_per_rad",
                m.back_emf(),
                1e-4,
                100.0,
                "a torque motor's constant",
            ),
            (
                "motor.inertia_kg_m2",
                m.inertia_kg_m2,
                1e-9,
                10.0,
                "a rotor with its pulley",
            ),
            (
                "motor.viscous_nm_s_per_rad",
                m.viscous_nm_s_per_rad,
                0.0,
                100.0,
                "bearing drag",
            ),
            (
                "motor.coulomb_nm",
                m.coulomb_nm,
                0.0,
                1e3,
                "bearing and seal friction",
            ),
            (
                "motor.coulomb_smoothing_rad_s",
                m.coulomb_smoothing_rad_s,
                1e-6,
                10.0,
                "the speed below which friction is linear",
            ),
            (
                "output.inertia_kg_m2",
                self.output.inertia_kg_m2,
                1e-6,
                1e4,
                "a drum with its payload",
            ),
            (
                "output.viscous_nm_s_per_rad",
                self.output.viscous_nm_s_per_rad,
                0.0,
                1e3,
                "bearing drag",
            ),
            (
                "sensors.motor_noise_rad",
                self.sensors.motor_noise_rad,
                0.0,
                0.1,
                "encoder noise",
            ),
            (
                "sensors.output_noise_rad",
                self.sensors.output_noise_rad,
                0.0,
                0.1,
                "encoder noise",
            ),
            (
                "controller.sample_rate_hz",
                c.sample_rate_hz,
                10.0,
                1e6,
                "a sampled servo",
            ),
            ("controller.kp", c.kp, 0.0, 1e9, "a servo gain"),
            ("controller.ki", c.ki, 0.0, 1e12, "a servo gain"),
            ("controller.kd", c.kd, 0.0, 1e6, "a servo gain"),
            (
                "controller.velocity_feedforward",
                c.velocity_feedforward,
                0.0,
                1e3,
                "a feedforward gain",
            ),
            (
                "controller.acceleration_feedforward",
                c.acceleration_feedforward,
                0.0,
                1e3,
                "a feedforward gain",
            ),
            (
                "controller.brake_transition_s",
                c.brake_transition_s,
                0.0,
                100.0,
                "a brake reversal",
            ),
        ];
        if let Some(v) = m.current_limit_a {
            checks.push((
                "motor.current_limit_a",
                v,
                1e-3,
                1e4,
                "an amplifier's current",
            ));
        }
        if let Some(v) = m.voltage_limit_v {
            checks.push((
                "motor.voltage_limit_v",
                v,
                1e-3,
                1e5,
                "an amplifier's voltage",
            ));
        }
        if let Some(r) = &c.rate_loop {
            checks.push(("controller.rate_loop.kp", r.kp, 0.0, 1e9, "a servo gain"));
            checks.push(("controller.rate_loop.ki", r.ki, 0.0, 1e12, "a servo gain"));
        }
        for (k, v, lo, hi, what) in checks {
            if !(v.is_finite() && v >= lo && v <= hi) {
                return Err((
                    key(k),
                    format!(
                        "{} is outside {} to {}, the range of {what}",
                        crate::number(v),
                        crate::number(lo),
                        crate::number(hi)
                    ),
                ));
            }
        }
        // Sampled on two coprime grids, so no periodic reference hides its peak between
        // the samples of both.
        let duration = if self.duration_s.is_finite() {
            self.duration_s.max(0.0)
        } else {
            0.0
        };
        // A bound within the limit stands in for the samples, which cannot exceed it; a
        // sweep validates every case, and the 8190 samples were about 1 % of a 2 s case.
        let peak = match self.reference.value_bound() {
            Some(bound) if bound <= MAX_POINTING_RAD => bound,
            _ => [4096u32, 4093]
                .iter()
                .flat_map(|&n| (0..=n).map(move |i| duration * f64::from(i) / f64::from(n)))
                .map(|t| self.reference.at(t).value.abs())
                .fold(0.0, f64::max),
        };
        if peak.is_nan() || peak > MAX_POINTING_RAD {
            return Err((
                key("reference"),
                format!(
                    "reaches {} rad, beyond the {} rad (about 16 turns) a pointing axis turns within a run",
                    crate::number(peak),
                    crate::number(MAX_POINTING_RAD)
                ),
            ));
        }
        Ok(())
    }

    /// Checks of the base motion, the gyro and the control law's structure.
    fn validate_structure(&self) -> Result<(), (String, String)> {
        let key = |k: &str| format!("closed_loop.{k}");
        let c = &self.controller;
        let fs = c.sample_rate_hz;
        let nyquist = 0.5 * fs;
        let in_band = |k: String, v: f64, what: &str| -> Result<(), (String, String)> {
            if v.is_finite() && v > 0.0 && v < nyquist {
                Ok(())
            } else {
                Err((
                    k,
                    format!(
                        "{} Hz must be a {what} above 0 and below the Nyquist frequency {} Hz",
                        crate::number(v),
                        crate::number(nyquist)
                    ),
                ))
            }
        };
        if let Some(b) = &self.base_motion {
            check_reference(b).map_err(|m| (key("base_motion"), m))?;
            let f = b.fastest_frequency_hz();
            if f >= 0.1 * fs {
                return Err((
                    key("base_motion"),
                    format!(
                        "content up to {} Hz is too fast for the control rate {} Hz (at most a tenth of it: the base is interpolated within each period)",
                        crate::number(f),
                        crate::number(fs)
                    ),
                ));
            }
        }
        if let Some(g) = &self.gyro {
            in_band(key("gyro.bandwidth_hz"), g.bandwidth_hz, "bandwidth")?;
            if !(g.damping.is_finite() && g.damping > 0.0 && g.damping <= 10.0) {
                return Err((
                    key("gyro.damping"),
                    format!(
                        "{} must be in (0, 10] (0.7 typical)",
                        crate::number(g.damping)
                    ),
                ));
            }
            for (k, v, typical) in [
                (
                    "gyro.noise_density_rad_s_per_sqrt_hz",
                    g.noise_density_rad_s_per_sqrt_hz,
                    "5e-6 for a FOG",
                ),
                ("gyro.quantization_rad_s", g.quantization_rad_s, "1e-6"),
            ] {
                if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                    return Err((
                        key(k),
                        format!("{} must be in [0, 1] ({typical})", crate::number(v)),
                    ));
                }
            }
            if !(g.bias_rad_s.is_finite() && g.bias_rad_s.abs() <= 1.0) {
                return Err((
                    key("gyro.bias_rad_s"),
                    format!(
                        "{} must be a finite rate of at most 1 rad/s in size (1e-6 for a FOG)",
                        crate::number(g.bias_rad_s)
                    ),
                ));
            }
            if let Some(fg) = g.sample_rate_hz {
                if !(fg.is_finite() && fg > 0.0 && fg <= fs) {
                    return Err((
                        key("gyro.sample_rate_hz"),
                        format!(
                            "{} Hz must be above 0 and at most the control rate {} Hz (the controller reads the gyro once per sample)",
                            crate::number(fg),
                            crate::number(fs)
                        ),
                    ));
                }
            }
            if g.decimation(fs).is_none() {
                return Err((
                    key("gyro.sample_rate_hz"),
                    format!(
                        "{} Hz must be the control rate {} Hz divided by a whole number",
                        crate::number(g.sample_rate_hz.unwrap_or(fs)),
                        crate::number(fs)
                    ),
                ));
            }
        }
        let needs_gyro = c.feedback == Feedback::GyroAngle
            || c.rate_loop
                .as_ref()
                .is_some_and(|r| r.measurement == RateSource::Gyro);
        if needs_gyro && self.gyro.is_none() {
            return Err((
                key("gyro"),
                "a gyro rate loop or feedback = \"gyro_angle\" needs a [closed_loop.gyro] section (bandwidth_hz = 500 is a start)".into(),
            ));
        }
        if let Some(r) = &c.rate_loop {
            for (k, v) in [
                ("controller.rate_loop.kp", r.kp),
                ("controller.rate_loop.ki", r.ki),
            ] {
                if !(v.is_finite() && v >= 0.0) {
                    return Err((key(k), crate::out_of_range(v, "a finite number >= 0")));
                }
            }
            in_band(
                key("controller.rate_loop.velocity_filter_hz"),
                r.velocity_filter_hz,
                "corner",
            )?;
        }
        for (name, list) in [
            ("measurement_filters", &c.measurement_filters),
            ("rate_command_filters", &c.rate_command_filters),
            ("rate_measurement_filters", &c.rate_measurement_filters),
            ("command_filters", &c.command_filters),
        ] {
            if !list.is_empty() && c.rate_loop.is_none() && name.starts_with("rate_") {
                return Err((
                    key(&format!("controller.{name}")),
                    "rate-loop filters need a [closed_loop.controller.rate_loop]".into(),
                ));
            }
            for (i, f) in list.iter().enumerate() {
                f.validate(fs)
                    .map_err(|m| (key(&format!("controller.{name}[{i}]")), m))?;
            }
        }
        if let Some(d) = &c.disturbance_observer {
            let k = |s: &str| key(&format!("controller.disturbance_observer.{s}"));
            in_band(k("bandwidth_hz"), d.bandwidth_hz, "bandwidth")?;
            if !(d.damping.is_finite() && d.damping > 0.0 && d.damping <= 10.0) {
                return Err((
                    k("damping"),
                    format!(
                        "{} must be in (0, 10] (0.7 typical)",
                        crate::number(d.damping)
                    ),
                ));
            }
            if let Some(j) = d.inertia_kg_m2 {
                if !(j.is_finite() && j > 0.0) {
                    return Err((
                        k("inertia_kg_m2"),
                        format!("{} must be a finite inertia > 0 kg m^2", crate::number(j)),
                    ));
                }
            }
            if self.motor.amplifier != Amplifier::Current {
                return Err((
                    k("bandwidth_hz"),
                    "the disturbance observer estimates a current: it needs motor.amplifier = \"current\"".into(),
                ));
            }
        }
        self.los
            .validate()
            .map_err(|(k, m)| (key(&format!("los.{k}")), m))?;
        Ok(())
    }
}

/// Like [`Signal::validate`], except that tables may still be empty: the I/O layer fills
/// them after the scenario is parsed.
fn check_reference(sig: &Signal) -> Result<(), String> {
    match sig {
        Signal::Table { .. } => Ok(()),
        Signal::Sum { parts } => parts.iter().try_for_each(check_reference),
        other => other.validate(),
    }
}
