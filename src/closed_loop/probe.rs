//! How a frequency response is to be measured (`[closed_loop.freqresp]`): the loop point,
//! frequencies and amplitudes, checked against the loop they are measured on. The
//! checks and the measurement are `analysis::freqresp`.

use serde::{Deserialize, Serialize};

/// Where the sinusoid enters the loop.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LoopPoint {
    /// Added to the controller's command: the loop gain `L` (margins).
    #[default]
    PlantInput,
    /// Added to the measurement: the sensitivity `S` (margins through `L = 1/S - 1`).
    OutputDisturbance,
    /// Added to the command, the measurement observed: `P S`.
    InputDisturbance,
    /// The reference itself: reference to measured output, `T_r`.
    Reference,
    /// A sine of the base angle: line of sight over base angle (the stabilisation's
    /// disturbance rejection; near 1 at low frequency for a loop on the encoders).
    BaseMotion,
    /// The whole command, the controller disconnected: the plant's describing function
    /// `P` (loop gain `K P` with the exact controller, and the limit cycles it predicts).
    Plant,
}

impl LoopPoint {
    /// Every name accepted in a scenario or on the command line.
    pub const NAMES: [&'static str; 6] = [
        "plant_input",
        "output_disturbance",
        "input_disturbance",
        "reference",
        "base_motion",
        "plant",
    ];

    /// Name as written in a scenario.
    pub fn name(self) -> &'static str {
        match self {
            LoopPoint::PlantInput => "plant_input",
            LoopPoint::OutputDisturbance => "output_disturbance",
            LoopPoint::InputDisturbance => "input_disturbance",
            LoopPoint::Reference => "reference",
            LoopPoint::BaseMotion => "base_motion",
            LoopPoint::Plant => "plant",
        }
    }

    /// The point by name; the error names the allowed ones.
    pub fn parse(name: &str) -> Result<Self, String> {
        Self::NAMES
            .iter()
            .position(|n| *n == name)
            .map(|i| {
                [
                    LoopPoint::PlantInput,
                    LoopPoint::OutputDisturbance,
                    LoopPoint::InputDisturbance,
                    LoopPoint::Reference,
                    LoopPoint::BaseMotion,
                    LoopPoint::Plant,
                ][i]
            })
            .ok_or_else(|| {
                format!(
                    "unknown loop point {name:?}; allowed: {}",
                    Self::NAMES.join(", ")
                )
            })
    }

    /// Symbol of the measured transfer.
    pub fn transfer(self) -> &'static str {
        match self {
            LoopPoint::PlantInput => "L",
            LoopPoint::OutputDisturbance => "S",
            LoopPoint::InputDisturbance => "PS",
            LoopPoint::Reference => "T_r",
            LoopPoint::BaseMotion => "LOS/base",
            LoopPoint::Plant => "P",
        }
    }

    /// Unit of the injection amplitude: the command's (A, or V with a voltage amplifier)
    /// at the plant input, mrad of output angle elsewhere.
    pub fn amplitude_unit(self, voltage: bool) -> &'static str {
        match self {
            LoopPoint::PlantInput | LoopPoint::InputDisturbance | LoopPoint::Plant if voltage => {
                "V"
            }
            LoopPoint::PlantInput | LoopPoint::InputDisturbance | LoopPoint::Plant => "A",
            _ => "mrad",
        }
    }

    /// Whether the loop gain (and so the margins) follows from this point's transfer.
    pub fn gives_loop_gain(self) -> bool {
        matches!(
            self,
            LoopPoint::PlantInput | LoopPoint::OutputDisturbance | LoopPoint::Plant
        )
    }
}

/// The state of the axis the sinusoid is measured about.
///
/// A magnetic powder brake with breakaway, or Coulomb friction, holds the drum while the
/// injected motion is small: at rest the loop then sees the motor on the cable spring,
/// not the design. A bench measures with the axis slewing at a constant rate, so that the
/// friction slides in one direction and acts as a constant torque.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OperatingPoint {
    /// The reference held at zero: the sinusoid alone moves the axis.
    Rest,
    /// The reference a ramp at `slew_rate_rad_s` (output rad/s), the sinusoid on top.
    Slewing,
}

impl OperatingPoint {
    /// Every name accepted in a scenario or on the command line.
    pub const NAMES: [&'static str; 2] = ["rest", "slewing"];

    /// Name as written in a scenario.
    pub fn name(self) -> &'static str {
        match self {
            OperatingPoint::Rest => "rest",
            OperatingPoint::Slewing => "slewing",
        }
    }

    /// The operating point by name; the error names the allowed ones.
    pub fn parse(name: &str) -> Result<Self, String> {
        match name {
            "rest" => Ok(OperatingPoint::Rest),
            "slewing" => Ok(OperatingPoint::Slewing),
            _ => Err(format!(
                "unknown operating point {name:?}; allowed: {}",
                Self::NAMES.join(", ")
            )),
        }
    }
}

/// Settings of a frequency-response measurement (`[closed_loop.freqresp]`, every key
/// optional).
/// The ranges are checked when `cable-servo freqresp` runs, against the loop it measures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FreqRespParams {
    /// Loop point (`plant_input`).
    pub point: LoopPoint,
    /// Frequencies, Hz; empty = `points` log-spaced from `f_min_hz` to `f_max_hz`.
    /// Allowed: each > 0 and below the Nyquist frequency (`base_motion`: below a tenth of
    /// the control rate).
    pub frequencies_hz: Vec<f64>,
    /// Lowest frequency of the log range, Hz (1).
    /// Allowed: > 0, below `f_max_hz` and the Nyquist frequency.
    pub f_min_hz: f64,
    /// Highest frequency of the log range, Hz; `None` = 0.4 x Nyquist (base motion: just
    /// under a tenth of the control rate, the highest the base is simulated at).
    /// Allowed: above `f_min_hz` and below the Nyquist frequency (`base_motion`: below a
    /// tenth of the control rate).
    pub f_max_hz: Option<f64>,
    /// Frequencies in the log range (20).
    /// Allowed: 2 to 500.
    /// Unit: frequencies.
    pub points: usize,
    /// Injection amplitudes in the point's unit (A or V at the plant input, output mrad
    /// elsewhere); empty = 0.1 %, 1 % and 10 % of the amplifier limit at the plant input,
    /// 0.01, 0.1 and 1 mrad elsewhere.
    /// Allowed: each > 0; at the command, below the amplifier's limit.
    /// Unit: A (V with a voltage amplifier) at the command points, output mrad elsewhere.
    pub amplitudes: Vec<f64>,
    /// Periods left to settle before measuring (3), at least `settle_min_s`.
    /// Allowed: 0 to 1000.
    pub settle_periods: f64,
    /// Shortest settling time, s (0.2: the integral action's transient).
    /// Allowed: 0 to 100.
    pub settle_min_s: f64,
    /// Whole periods measured (4), more at high frequency to reach `min_samples`.
    /// Allowed: 1 to 10000.
    pub measure_periods: u32,
    /// Fewest samples measured (2000): bounds the frequency snap to 1/2000.
    /// Allowed: 16 to 1e7.
    /// Unit: control samples.
    pub min_samples: u32,
    /// Harmonics (2nd to this) in the distortion figure (5).
    /// Allowed: 0 to 50.
    pub harmonics: u32,
    /// Extra measurements per margin, peak and bandwidth to refine them between grid
    /// frequencies (6; 0 = interpolate only).
    /// Allowed: 0 to 50.
    pub refine_iterations: u32,
    /// Transmitted torque, N m, at whose tangent stiffness (first loading from the
    /// preload) the exact linear reference takes its cable; `None` (the default) takes the
    /// free-span stiffness, the small-amplitude limit. The two bracket the drive: small
    /// motions see the free span, large monotone ones the tangent.
    /// Allowed: >= 0 and within what the drive carries (about `2 preload_n drum_radius_m`;
    /// the message gives the preload that would).
    pub reference_load_nm: Option<f64>,
    /// Operating point (`rest` or `slewing`); `None` (the default) slews where a brake,
    /// motor Coulomb friction or bearing friction would hold the axis, and rests
    /// otherwise. The `plant` point (loop open) is measured at rest.
    /// Allowed: `"rest"`, `"slewing"` (not `"slewing"` with `point = "plant"`).
    pub operating_point: Option<OperatingPoint>,
    /// Slew rate of the `slewing` operating point, output rad/s; `None` (the default)
    /// chooses it per amplitude: twice the largest output velocity the injection gives on
    /// the exact linear reference over the frequencies measured (at least 0.01 rad/s), so
    /// the drum never reverses and the friction never sticks.
    /// Allowed: > 0 and at most 10.
    pub slew_rate_rad_s: Option<f64>,
}

impl Default for FreqRespParams {
    fn default() -> Self {
        FreqRespParams {
            point: LoopPoint::PlantInput,
            frequencies_hz: Vec::new(),
            f_min_hz: 1.0,
            f_max_hz: None,
            points: 20,
            amplitudes: Vec::new(),
            settle_periods: 3.0,
            settle_min_s: 0.2,
            measure_periods: 4,
            min_samples: 2000,
            harmonics: 5,
            refine_iterations: 6,
            reference_load_nm: None,
            operating_point: None,
            slew_rate_rad_s: None,
        }
    }
}
