//! The preloaded cable drive: two halves between a motor pulley and an output drum.

use serde::{Deserialize, Serialize};

use super::half::{CableHalf, HalfSlip, HalfSolution, HalfTrial};
use super::newton::{solve_increasing_curved, RootError};
use super::wrap::WrapLaw;

/// How the cable crosses between pulley and drum.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Routing {
    /// Crossed spans (internal tangents): `Lf = sqrt(L^2 - (ro + ri)^2)`. The usual layout.
    #[default]
    FigureEight,
    /// Open spans (external tangents): `Lf = sqrt(L^2 - (ro - ri)^2)`.
    Open,
}

impl Routing {
    /// The name used in scenario files (`figure_eight`, `open`).
    pub fn as_str(self) -> &'static str {
        match self {
            Routing::FigureEight => "figure_eight",
            Routing::Open => "open",
        }
    }

    /// Smallest centre distance that leaves the spans a length, m.
    pub fn min_center_distance_m(self, pulley_radius_m: f64, drum_radius_m: f64) -> f64 {
        match self {
            Routing::FigureEight => drum_radius_m + pulley_radius_m,
            Routing::Open => (drum_radius_m - pulley_radius_m).abs(),
        }
    }
}

impl std::fmt::Display for Routing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Geometry and material of the cable drive. Field names carry their units; the values
/// in parentheses are the published bench (physics.md section 6), which is also what
/// `DriveParams::default()` gives.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveParams {
    /// Cable routing between pulley and drum.
    #[serde(default)]
    pub routing: Routing,
    /// Motor pulley radius `ri`, m (0.020 on the bench).
    /// Allowed: 1e-4 to 10.
    pub pulley_radius_m: f64,
    /// Output drum radius `ro`, m (0.1025 on the bench).
    /// Allowed: 1e-4 to 10.
    pub drum_radius_m: f64,
    /// Distance between pulley and drum axes `L`, m (0.1450595 on the bench).
    /// Allowed: > 0 and at most 100; above `drum_radius_m + pulley_radius_m`
    /// (`figure_eight`) or `|drum_radius_m - pulley_radius_m|` (`open`), so the spans have
    /// a length.
    pub center_distance_m: f64,
    /// Tensile stiffness `E*A` of the cable, N (1.4e4 on the bench).
    /// Allowed: 1 to 1e10.
    pub cable_modulus_n: f64,
    /// Coulomb friction coefficient between cable and pulley surfaces (0.2 on the bench).
    /// Allowed: > 0 and at most 1.
    pub friction_coefficient: f64,
    /// Cable preload set by the turnbuckle, N (100 on the bench).
    /// Allowed: > 0 and at most 5 % of `cable_modulus_n` (a strain of 5 %).
    pub preload_n: f64,
    /// Wrap on the drum per half, from contact point to anchor, rad (pi on the bench).
    /// Allowed: > 0 and at most 20 pi (ten turns).
    pub drum_wrap_rad: f64,
    /// Total wrap around the pulley, rad (6*pi, three turns, on the bench); each half owns
    /// half of it.
    /// Allowed: > 0 and at most 200 pi (a hundred turns).
    pub pulley_wrap_rad: f64,
}

impl Default for DriveParams {
    fn default() -> Self {
        DriveParams {
            routing: Routing::FigureEight,
            pulley_radius_m: 0.020,
            drum_radius_m: 0.1025,
            center_distance_m: 0.1450595,
            cable_modulus_n: 1.4e4,
            friction_coefficient: 0.2,
            preload_n: 100.0,
            drum_wrap_rad: std::f64::consts::PI,
            pulley_wrap_rad: 6.0 * std::f64::consts::PI,
        }
    }
}

/// Largest preload strain `preload_n / cable_modulus_n` accepted.
pub const MAX_PRELOAD_STRAIN: f64 = 0.05;

/// A parameter set the model cannot use, with what is allowed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DriveParamError {
    /// A value outside its physical range.
    #[error("drive.{key} = {} is out of range: it must be {allowed}", crate::number(*value))]
    OutOfRange {
        /// Scenario key below `[drive]`.
        key: &'static str,
        /// The offending value.
        value: f64,
        /// What is allowed.
        allowed: &'static str,
    },
    /// Pulleys overlap for the chosen routing: no free span exists.
    #[error(
        "drive.center_distance_m = {} is too small for routing = \"{routing}\": it must exceed {min_m:.6} m ({}; the spans would have no length)",
        crate::number(*center_distance_m),
        if matches!(routing, Routing::FigureEight) { "drum_radius_m + pulley_radius_m" } else { "|drum_radius_m - pulley_radius_m|" }
    )]
    NoFreeSpan {
        /// The given centre distance, m.
        center_distance_m: f64,
        /// Routing in use.
        routing: Routing,
        /// Smallest admissible centre distance, m.
        min_m: f64,
    },
}

impl DriveParams {
    /// Transmission ratio `ic = ro / ri` (5.125 on the bench).
    pub fn ratio(&self) -> f64 {
        self.drum_radius_m / self.pulley_radius_m
    }

    /// Free-span length `Lf` of each half for the routing, m (0.0777 on the bench).
    pub fn free_span_m(&self) -> f64 {
        let l = self.center_distance_m;
        let r = match self.routing {
            Routing::FigureEight => self.drum_radius_m + self.pulley_radius_m,
            Routing::Open => self.drum_radius_m - self.pulley_radius_m,
        };
        (l * l - r * r).max(0.0).sqrt()
    }

    /// Check physical ranges and the geometry.
    pub fn validate(&self) -> Result<(), DriveParamError> {
        fn positive(key: &'static str, value: f64) -> Result<(), DriveParamError> {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(DriveParamError::OutOfRange {
                    key,
                    value,
                    allowed: "a finite number > 0",
                })
            }
        }
        /// Physical ranges, generous on both sides: outside them the model's assumptions
        /// (thin cable, small strain, exponentials of the wrap) stop holding or the numbers
        /// overflow.
        fn within(
            key: &'static str,
            value: f64,
            low: f64,
            high: f64,
            allowed: &'static str,
        ) -> Result<(), DriveParamError> {
            if (low..=high).contains(&value) {
                Ok(())
            } else {
                Err(DriveParamError::OutOfRange {
                    key,
                    value,
                    allowed,
                })
            }
        }
        use std::f64::consts::PI;
        positive("pulley_radius_m", self.pulley_radius_m)?;
        positive("drum_radius_m", self.drum_radius_m)?;
        positive("center_distance_m", self.center_distance_m)?;
        positive("cable_modulus_n", self.cable_modulus_n)?;
        positive("preload_n", self.preload_n)?;
        positive("drum_wrap_rad", self.drum_wrap_rad)?;
        positive("pulley_wrap_rad", self.pulley_wrap_rad)?;
        let radius = "between 1e-4 m (0.1 mm) and 10 m";
        within("pulley_radius_m", self.pulley_radius_m, 1e-4, 10.0, radius)?;
        within("drum_radius_m", self.drum_radius_m, 1e-4, 10.0, radius)?;
        within(
            "center_distance_m",
            self.center_distance_m,
            0.0,
            100.0,
            "at most 100 m",
        )?;
        within(
            "cable_modulus_n",
            self.cable_modulus_n,
            1.0,
            1e10,
            "a tensile stiffness E*A between 1 N and 1e10 N (1.4e4 N on the bench)",
        )?;
        within(
            "drum_wrap_rad",
            self.drum_wrap_rad,
            0.0,
            20.0 * PI,
            "at most 20*pi rad (ten turns)",
        )?;
        within(
            "pulley_wrap_rad",
            self.pulley_wrap_rad,
            0.0,
            200.0 * PI,
            "at most 200*pi rad (a hundred turns)",
        )?;
        within(
            "preload_n",
            self.preload_n,
            0.0,
            MAX_PRELOAD_STRAIN * self.cable_modulus_n,
            "at most 5 % of cable_modulus_n (a strain of 5 %; cables break at a few percent and the model assumes small strains)",
        )?;
        let mu = self.friction_coefficient;
        if !(mu.is_finite() && mu > 0.0 && mu <= 1.0) {
            return Err(DriveParamError::OutOfRange {
                key: "friction_coefficient",
                value: mu,
                allowed: "a number in (0, 1]",
            });
        }
        let min_m = self
            .routing
            .min_center_distance_m(self.pulley_radius_m, self.drum_radius_m);
        let ratio = self.ratio();
        if !(ratio.is_finite() && ratio > 0.0) {
            return Err(DriveParamError::OutOfRange {
                key: "drum_radius_m",
                value: self.drum_radius_m,
                allowed: "such that drum_radius_m / pulley_radius_m is a finite ratio",
            });
        }
        if !self.free_span_m().is_finite() {
            return Err(DriveParamError::OutOfRange {
                key: "center_distance_m",
                value: self.center_distance_m,
                allowed: "small enough for a finite span length",
            });
        }
        if self.center_distance_m <= min_m || self.free_span_m() <= 0.0 {
            return Err(DriveParamError::NoFreeSpan {
                center_distance_m: self.center_distance_m,
                routing: self.routing,
                min_m,
            });
        }
        Ok(())
    }
}

/// Which history model the drive uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum HysteresisModel {
    /// Capstan friction with memory of past loads (tension bumps, wiping-out).
    #[default]
    Memory,
    /// Every state computed from the virgin preloaded cable (Lu and Fan style baseline).
    Memoryless,
}

/// Which cable half.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Half {
    /// Upper half (free span C-D); tightened by positive transmitted torque.
    Upper,
    /// Lower half (free span G-H).
    Lower,
}

impl std::fmt::Display for Half {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Half::Upper => "upper",
            Half::Lower => "lower",
        })
    }
}

/// A fault's number with `decimals` decimals, in exponent form when huge: a friction
/// coefficient of 1e-300 demands a slip zone of 1e300 rad, which must not print 300 digits.
/// A value too small for its decimals keeps three significant digits: a drive preloaded
/// to 1e-7 N carries 2e-8 N m, which `0.0000` would hide.
fn shown(v: &f64, decimals: usize) -> String {
    // An infinite tension or slip zone (a load beyond any drive) is said in words: `inf`
    // is no number a user can act on.
    if v.is_infinite() {
        format!("{}more than 1e308", if *v < 0.0 { "-" } else { "" })
    } else {
        crate::fixed_or_significant(*v, decimals)
    }
}

/// A state the cable cannot reach: the drive's capacity is exceeded.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum DriveFault {
    /// A span would need negative tension: the cable cannot push.
    #[error("{half} span goes slack (tension would fall to 0 N) at transmitted torque {} N m; raise preload_n above about {} N or reduce the load", shown(.torque_nm, 4), shown(.needed_preload_n, 1))]
    Slack {
        /// The half that goes slack.
        half: Half,
        /// Transmitted torque at which it happens, N m (NaN-free; 0 in displacement mode).
        torque_nm: f64,
        /// Rough preload needed to carry this torque, `|M|/(2 ro)`, N.
        needed_preload_n: f64,
    },
    /// A pulley slip zone reached the neutral point: the cable slides around the pulley.
    #[error("gross slip of the {half} half on the pulley: slip zone {} rad reaches the neutral point at {} rad (tension {} N); increase the pulley wrap, preload or friction, or reduce the load", shown(.slip_angle_rad, 3), shown(.available_rad, 3), shown(.tension_n, 2))]
    GrossSlip {
        /// The half that slips.
        half: Half,
        /// Slip-zone length the load demands, rad.
        slip_angle_rad: f64,
        /// Wrap available to that half on the pulley, rad.
        available_rad: f64,
        /// Span tension demanded, N.
        tension_n: f64,
    },
}

/// One quasi-static or dynamic state of the drive.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct DriveState {
    /// Upper span tension `Tu`, N.
    pub tension_upper_n: f64,
    /// Lower span tension `Tl`, N.
    pub tension_lower_n: f64,
    /// Relative surface displacement `D = ri*theta_in - ro*theta_out`, m.
    pub surface_displacement_m: f64,
    /// Transmission error `e = theta_out - theta_in/ic = -D/ro`, rad.
    pub transmission_error_rad: f64,
    /// Elongation of the upper half, m (equals `D` at equilibrium).
    pub elongation_upper_m: f64,
    /// Elongation of the lower half, m (equals `-D` at equilibrium).
    pub elongation_lower_m: f64,
    /// Slip growth `exp(mu*s)` of `[upper, lower]` for a slip zone of length `s` over the
    /// stored profile (1 = none): [`CableDrive::slip_angles_rad`] turns it into angles.
    pub slip_growth: [f64; 2],
    /// Whether the drum slip zone of `[upper, lower]` reaches the anchor (profile cut there).
    pub anchor_reached: [bool; 2],
}

impl DriveState {
    /// Torque the cable transmits to the drum, `ro*(Tu - Tl)`, N m.
    pub fn torque_nm(&self, drum_radius_m: f64) -> f64 {
        drum_radius_m * (self.tension_upper_n - self.tension_lower_n)
    }
}

/// The cable drive with its wrap memory.
#[derive(Clone, Debug)]
pub struct CableDrive {
    params: DriveParams,
    model: HysteresisModel,
    upper: CableHalf,
    lower: CableHalf,
    state: DriveState,
    /// Last non-zero change of `Tu - Tl`, N (its sign tells a reversal).
    last_change: f64,
    /// Torque of the last committed quasi-static step, N m: the same torque again changes
    /// nothing (a held brake load, for one), so its state is returned as it is.
    committed_torque_nm: Option<f64>,
    /// Share of a change of `Tu - Tl` taken by the upper span at the last state.
    upper_share: f64,
    /// `1/ro`, 1/m: the step's first and last operations multiply by it.
    inv_drum_radius: f64,
}

/// A solved quasi-static state with the trials its commit needs.
struct Solved {
    state: DriveState,
    up: HalfTrial,
    lo: HalfTrial,
}

/// Relative tolerance on span tensions of every solve (far below any measurable effect).
const TENSION_RTOL: f64 = 1e-13;

/// Stored segments the closed-form quasi-static solve may move through before the
/// general solver takes over (a step of a smooth load history crosses one or two).
const MAX_SEGMENT_HOPS: usize = 4;

/// Outcome of the closed-form quasi-static solve on a pair of laws.
enum ClosedRoot {
    /// The root, within both laws' ranges.
    Found(f64),
    /// The laws' root lies outside one of their ranges: the upper tension there, N.
    Outside(f64),
    /// A law without the square-root form, or no convergence.
    NotClosed,
}

impl CableDrive {
    /// A preloaded drive in its virgin state. `params` should have passed
    /// [`DriveParams::validate`].
    pub fn new(params: DriveParams, model: HysteresisModel) -> Self {
        let remembers = model == HysteresisModel::Memory;
        let half = || {
            CableHalf::new(
                params.free_span_m(),
                params.drum_radius_m,
                params.drum_wrap_rad,
                params.pulley_radius_m,
                0.5 * params.pulley_wrap_rad,
                params.friction_coefficient,
                params.preload_n,
                params.cable_modulus_n,
                remembers,
            )
        };
        let state = DriveState {
            tension_upper_n: params.preload_n,
            tension_lower_n: params.preload_n,
            ..DriveState::default()
        };
        let inv_drum_radius = 1.0 / params.drum_radius_m;
        CableDrive {
            upper: half(),
            lower: half(),
            params,
            model,
            state,
            last_change: 0.0,
            committed_torque_nm: Some(0.0),
            upper_share: 0.5,
            inv_drum_radius,
        }
    }

    /// Parameters in use.
    pub fn params(&self) -> &DriveParams {
        &self.params
    }

    /// History model in use.
    pub fn model(&self) -> HysteresisModel {
        self.model
    }

    /// Last committed state.
    pub fn state(&self) -> &DriveState {
        &self.state
    }

    /// Upper half (wrap profiles for plots).
    pub fn upper(&self) -> &CableHalf {
        &self.upper
    }

    /// Lower half.
    pub fn lower(&self) -> &CableHalf {
        &self.lower
    }

    /// Back to the virgin preloaded state.
    pub fn reset(&mut self) {
        self.upper.reset();
        self.lower.reset();
        self.last_change = 0.0;
        self.committed_torque_nm = Some(0.0);
        self.upper_share = 0.5;
        self.state = DriveState {
            tension_upper_n: self.params.preload_n,
            tension_lower_n: self.params.preload_n,
            ..DriveState::default()
        };
    }

    fn state_from(
        &self,
        tu: f64,
        tl: f64,
        up: &HalfTrial,
        lo: &HalfTrial,
        slip: (&HalfSlip, &HalfSlip),
    ) -> DriveState {
        // Both halves give D at equilibrium; their mean cancels the residual of the solve.
        let d = 0.5 * (up.elongation_m - lo.elongation_m);
        let (su, sl) = slip;
        DriveState {
            tension_upper_n: tu,
            tension_lower_n: tl,
            surface_displacement_m: d,
            transmission_error_rad: -d * self.inv_drum_radius,
            elongation_upper_m: up.elongation_m,
            elongation_lower_m: lo.elongation_m,
            slip_growth: [su.growth, sl.growth],
            anchor_reached: [su.drum_anchor_reached, sl.drum_anchor_reached],
        }
    }

    /// Slip-zone lengths of a state, rad: `[upper drum, upper pulley, lower drum, lower
    /// pulley]`, each at most its region's wrap (0 to pi on the bench drum).
    pub fn slip_angles_rad(&self, state: &DriveState) -> [f64; 4] {
        let (ud, up) = self.upper.slip_angles_rad(state.slip_growth[0]);
        let (ld, lp) = self.lower.slip_angles_rad(state.slip_growth[1]);
        [ud, up, ld, lp]
    }

    fn half(&self, half: Half) -> &CableHalf {
        match half {
            Half::Upper => &self.upper,
            Half::Lower => &self.lower,
        }
    }

    fn check_pulley(&self, half: Half, tension_n: f64, slip: &HalfSlip) -> Result<(), DriveFault> {
        if slip.pulley_neutral_reached {
            // Where the slip zone would end on an infinitely long pulley wrap.
            let demanded =
                (tension_n / self.params.preload_n).ln().abs() / self.params.friction_coefficient;
            return Err(DriveFault::GrossSlip {
                half,
                slip_angle_rad: demanded.max(self.half(half).slip_angles_rad(slip.growth).1),
                available_rad: 0.5 * self.params.pulley_wrap_rad,
                tension_n,
            });
        }
        Ok(())
    }

    /// Full state of both halves at span tensions `(tu, tl)` from their trials, with the
    /// gross-slip check, and what a commit of it needs.
    fn solved(&self, tu: f64, tl: f64, up: HalfTrial, lo: HalfTrial) -> Result<Solved, DriveFault> {
        let su = self.upper.slip(&up);
        let sl = self.lower.slip(&lo);
        self.check_pulley(Half::Upper, tu, &su)?;
        self.check_pulley(Half::Lower, tl, &sl)?;
        Ok(Solved {
            state: self.state_from(tu, tl, &up, &lo, (&su, &sl)),
            up,
            lo,
        })
    }

    /// Quasi-static state when the cable transmits torque `torque_nm` (N m, `M = -Ml`,
    /// positive tightens the upper span), without committing it to memory.
    ///
    /// Solves `Tu - Tl = M/ro` and `elong_u(Tu) + elong_l(Tl) = 0`: Halley steps on the
    /// halves' closed-form laws, safeguarded Newton when a slip zone changes segment.
    pub fn trial_torque(&self, torque_nm: f64) -> Result<DriveState, DriveFault> {
        if self.committed_torque_nm == Some(torque_nm) {
            return Ok(self.state);
        }
        self.solve_torque(torque_nm).map(|solved| solved.state)
    }

    #[inline(always)]
    fn solve_torque(&self, torque_nm: f64) -> Result<Solved, DriveFault> {
        let dt = torque_nm * self.inv_drum_radius;
        let pre = self.params.preload_n;
        // Tl = Tu - dt > 0 and Tu > 0.
        let lower_bound = dt.max(0.0);
        // Linearised length constraint: the upper span takes the share dl/(du+dl) of a change
        // of Tu - Tl. Right after a reversal both slip zones restart from zero length and
        // the halves are equally stiff, so the share is one half.
        let change = dt - (self.state.tension_upper_n - self.state.tension_lower_n);
        let share = if change * self.last_change > 0.0 {
            self.upper_share
        } else {
            0.5
        };
        let guess = (self.state.tension_upper_n + share * change).max(lower_bound + 1e-3 * pre);
        // Each half's law is iterated on a local copy: it holds across the whole solve
        // unless a slip zone moves onto another stored segment.
        let mut law_u = self.upper.wrap().law_at(guess);
        let mut law_l = self.lower.wrap().law_at(guess - dt);
        let mut start = guess;
        // A root past a law's range lies on a neighbouring stored segment: the laws there
        // give it in closed form too (the elongation is monotone, so the segments holding
        // the root are reached in a few hops).
        for _ in 0..MAX_SEGMENT_HOPS {
            match self.solve_closed(&law_u, &law_l, dt, start) {
                ClosedRoot::Found(tu) => {
                    let up = self.upper.trial_with(&mut law_u, tu);
                    let lo = self.lower.trial_with(&mut law_l, tu - dt);
                    // The length constraint's residual, as a tension error, within the
                    // tolerance?
                    let residual = (up.elongation_m + lo.elongation_m)
                        / (up.d_elongation_m_per_n + lo.d_elongation_m_per_n);
                    if residual.abs() <= 0.1 * TENSION_RTOL * tu.max(pre) {
                        return self.solved(tu, tu - dt, up, lo);
                    }
                    break;
                }
                ClosedRoot::Outside(tu) => {
                    if !law_u.covers(tu) {
                        law_u = self.upper.wrap().law_at(tu);
                    }
                    if !law_l.covers(tu - dt) {
                        law_l = self.lower.wrap().law_at(tu - dt);
                    }
                    start = tu;
                }
                ClosedRoot::NotClosed => break,
            }
        }
        self.solve_torque_general(torque_nm, guess, law_u, law_l)
    }

    /// [`Self::solve_torque`] when the closed form does not settle it (a slip zone on the
    /// untouched plateau, or crossing more segments than the hops allow): safeguarded
    /// Halley iteration over the halves' trials, then one Newton correction.
    #[cold]
    #[inline(never)]
    fn solve_torque_general(
        &self,
        torque_nm: f64,
        guess: f64,
        mut law_u: WrapLaw,
        mut law_l: WrapLaw,
    ) -> Result<Solved, DriveFault> {
        let dt = torque_nm * self.inv_drum_radius;
        let pre = self.params.preload_n;
        let lower_bound = dt.max(0.0);
        let mut last = None;
        let residual = |tu: f64| {
            let up = self.upper.trial_with(&mut law_u, tu);
            let lo = self.lower.trial_with(&mut law_l, tu - dt);
            last = Some((tu, up, lo));
            (
                up.elongation_m + lo.elongation_m,
                up.d_elongation_m_per_n + lo.d_elongation_m_per_n,
                up.d2_elongation + lo.d2_elongation,
            )
        };
        let tu = match solve_increasing_curved(residual, lower_bound, guess, pre, TENSION_RTOL) {
            Ok(tu) => tu,
            Err(RootError::BelowDomain) => {
                return Err(DriveFault::Slack {
                    half: if dt >= 0.0 { Half::Lower } else { Half::Upper },
                    torque_nm,
                    needed_preload_n: dt.abs() / 2.0,
                })
            }
        };
        let (mut tu, mut tl) = (tu, tu - dt);
        let (mut up, mut lo) = match last {
            Some((x, up, lo)) if x == tu => (up, lo),
            _ => (self.upper.trial(tu), self.lower.trial(tl)),
        };
        // The general solver stops once its step is within the tolerance, so its last
        // iterate can be off by that step: one more Newton correction brings it to rounding.
        let off = (up.elongation_m + lo.elongation_m)
            / (up.d_elongation_m_per_n + lo.d_elongation_m_per_n);
        if off.abs() > 0.1 * TENSION_RTOL * tu.max(pre) && tu - off > lower_bound {
            tu -= off;
            tl = tu - dt;
            up = self.upper.trial(tu);
            lo = self.lower.trial(tl);
        }
        self.solved(tu, tl, up, lo)
    }

    /// The usual quasi-static solve: both slip zones end on stored segments whose laws are
    /// `a*T + beta*sqrt(T) + c`, so the length constraint is a scalar equation in `Tu`
    /// solved by Halley steps on those coefficients alone. The root is reported outside
    /// when it leaves a law's range (the caller moves to the segment there), not closed
    /// when a law has another form or the iteration does not settle.
    fn solve_closed(&self, law_u: &WrapLaw, law_l: &WrapLaw, dt: f64, guess: f64) -> ClosedRoot {
        let (Some((au, bu, cu)), Some((al, bl, cl))) = (law_u.sqrt_form(), law_l.sqrt_form())
        else {
            return ClosedRoot::NotClosed;
        };
        let pre = self.params.preload_n;
        let span = self.upper.span_m();
        // E*A * (elong_u(x) + elong_l(x - dt)) = alpha*x + bu*sqrt(x) + bl*sqrt(x - dt) + gamma
        let alpha = 2.0 * span + au + al;
        let gamma = cu + cl - al * dt - span * (2.0 * pre + dt);
        let floor = dt.max(0.0);
        let mut x = guess;
        for _ in 0..8 {
            if x.is_nan() || x <= floor {
                return ClosedRoot::NotClosed;
            }
            let (u, v) = (x.sqrt(), (x - dt).sqrt());
            let p = u * v;
            let f = alpha * x + bu * u + bl * v + gamma;
            // The derivatives scaled by p and p^3 (f' = d/p, f'' = d2/p^3) leave Halley's
            // step a single division: the iteration is latency-bound.
            let d = alpha * p + 0.5 * (bu * v + bl * u);
            let d2 = -0.25 * (bu * v * v * v + bl * u * u * u);
            let step = if d * d * p - f * d2 > 0.0 {
                2.0 * f * d * p * p / (2.0 * d * d * p - f * d2)
            } else {
                f * p / d
            };
            if !step.is_finite() {
                return ClosedRoot::NotClosed;
            }
            // Once the step is small Halley's next iterate is exact to far below the
            // tolerance; the caller verifies it with the trials it needs anyway.
            if step.abs() <= 1e-6 * x {
                let next = x - step;
                return if next <= floor {
                    ClosedRoot::NotClosed
                } else if law_u.covers(next) && law_l.covers(next - dt) {
                    ClosedRoot::Found(next)
                } else {
                    ClosedRoot::Outside(next)
                };
            }
            x -= step;
        }
        ClosedRoot::NotClosed
    }

    /// Quasi-static step: apply transmitted torque `torque_nm` and commit the new tension
    /// profiles. On a fault nothing is committed.
    pub fn apply_torque(&mut self, torque_nm: f64) -> Result<DriveState, DriveFault> {
        if self.committed_torque_nm == Some(torque_nm) {
            return Ok(self.state);
        }
        let solved = self.solve_torque(torque_nm)?;
        let (state, up, lo) = (solved.state, solved.up, solved.lo);
        let change = (state.tension_upper_n - state.tension_lower_n)
            - (self.state.tension_upper_n - self.state.tension_lower_n);
        if change != 0.0 {
            self.last_change = change;
        }
        self.upper_share =
            lo.d_elongation_m_per_n / (up.d_elongation_m_per_n + lo.d_elongation_m_per_n);
        self.commit_solved(&solved);
        self.committed_torque_nm = Some(torque_nm);
        Ok(state)
    }

    /// Commit span tensions solved by the dynamic plant for the displacement
    /// `displacement_m` (m) at a period boundary, each half's by elongation on the current
    /// memory ([`CableHalf::solve_for_elongation`]): the gross-slip check, then both
    /// profiles and the state (whose elongations are `D` and `-D` by construction). On a
    /// fault nothing is committed.
    pub(crate) fn commit_solutions(
        &mut self,
        upper: &HalfSolution,
        lower: &HalfSolution,
        displacement_m: f64,
    ) -> Result<(), DriveFault> {
        let su = self.upper.solution_slip(upper);
        let sl = self.lower.solution_slip(lower);
        self.check_pulley(Half::Upper, upper.tension_n, &su)?;
        self.check_pulley(Half::Lower, lower.tension_n, &sl)?;
        self.upper.commit_solution(upper);
        self.lower.commit_solution(lower);
        self.set_displaced(
            (upper.tension_n, lower.tension_n),
            displacement_m,
            (&su, &sl),
        );
        Ok(())
    }

    /// The state after a commit of the displacement-driven plant: span tensions `(Tu, Tl)`
    /// (N) at displacement `d` (m), whose elongations are `D` and `-D` by construction,
    /// with the halves' slip zones.
    #[inline(always)]
    fn set_displaced(&mut self, tensions: (f64, f64), d: f64, slips: (&HalfSlip, &HalfSlip)) {
        let (su, sl) = slips;
        self.state = DriveState {
            tension_upper_n: tensions.0,
            tension_lower_n: tensions.1,
            surface_displacement_m: d,
            transmission_error_rad: -d * self.inv_drum_radius,
            elongation_upper_m: d,
            elongation_lower_m: -d,
            slip_growth: [su.growth, sl.growth],
            anchor_reached: [su.drum_anchor_reached, sl.drum_anchor_reached],
        };
        self.committed_torque_nm = None;
    }

    /// The boundary commit of the displacement-driven plant at displacement `d` (m) in its
    /// usual case, both halves' roots on the laws cached for their directions: the same
    /// gross-slip check, commit and state as [`Self::commit_solutions`] of the halves'
    /// solves, without a law copied out of the cache and back. Returns the span tensions
    /// `(Tu, Tl)` (N), or `None`, with nothing changed, when either half's root is not on
    /// its cached law (the caller then solves in full).
    #[inline(always)]
    pub(crate) fn commit_cached(&mut self, d: f64) -> Option<Result<(f64, f64), DriveFault>> {
        let ru = self.upper.boundary_root(d)?;
        let rl = self.lower.boundary_root(-d)?;
        let su = self.upper.cached_slip(&ru);
        let sl = self.lower.cached_slip(&rl);
        let (tu, tl) = (ru.tension_n, rl.tension_n);
        if let Err(e) = self
            .check_pulley(Half::Upper, tu, &su)
            .and_then(|()| self.check_pulley(Half::Lower, tl, &sl))
        {
            return Some(Err(e));
        }
        self.upper.commit_cached(&ru, d);
        self.lower.commit_cached(&rl, -d);
        self.set_displaced((tu, tl), d, (&su, &sl));
        Some(Ok((tu, tl)))
    }

    /// Commit both halves' profiles and the state of a solve on the current memory.
    fn commit_solved(&mut self, solved: &Solved) {
        // Solved on the current memory, with nothing committed since.
        self.upper.commit_current(&solved.up);
        self.lower.commit_current(&solved.lo);
        self.state = solved.state;
    }
}
