//! Continuous-time plant: torque motor, cable drive as a history-dependent spring, output
//! drum with its loads, and the brake's stick/slip state.
//!
//! State `x = [theta_m, omega_m, i, theta_o, omega_o, g, g']` (rad, rad/s, A, rad, rad/s,
//! rad/s, rad/s^2): angles and speeds relative to the base, and the gyro's filtered
//! inertial rate `g`. Under base motion `beta(t)` both inertias feel `-J beta''`, the gyro
//! sees `omega_o + beta'`, and friction, drag and the motor act on relative speeds.
//! The cable's wrap memory is frozen during a control period and committed at its end, so
//! the right-hand side is a pure function of `(t, x)` inside a period.

use std::cell::Cell;

use nalgebra::SVector;
use ode_solvers::System;

use super::params::{Amplifier, CableModel, ClosedLoopParams};
use crate::physics::half::HalfSolution;
use crate::physics::EffectsParams;
use crate::physics::{CableDrive, DriveFault, DriveParams, Half, HysteresisModel, LoadParams};

/// Plant state vector.
pub type State = SVector<f64, 7>;

/// Index of the motor angle in [`State`].
pub const THETA_M: usize = 0;
/// Index of the motor speed.
pub const OMEGA_M: usize = 1;
/// Index of the winding current.
pub const CURRENT: usize = 2;
/// Index of the output angle.
pub const THETA_O: usize = 3;
/// Index of the output speed.
pub const OMEGA_O: usize = 4;
/// Index of the gyro's filtered inertial rate, rad/s.
pub const GYRO: usize = 5;
/// Index of its derivative, rad/s^2.
pub const GYRO_DOT: usize = 6;

/// Base motion over one period (or piece of one): rate and acceleration at its start and
/// end. The rate in between is the cubic Hermite curve through both ends with those
/// accelerations as slopes, and the acceleration is its derivative, so the two stay
/// consistent and the error is of order `(f T)^4` (a linear interpolation of each left an
/// error of order `(f T)^2` that a stiff stabilisation loop could see).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BaseSegment {
    /// Base rate at the start, rad/s.
    pub rate0: f64,
    /// Base rate at the end, rad/s.
    pub rate1: f64,
    /// Base acceleration at the start, rad/s^2.
    pub accel0: f64,
    /// Base acceleration at the end, rad/s^2.
    pub accel1: f64,
    /// Base angle at the start, rad (unbalance acts on the inertial angle).
    pub angle0: f64,
}

impl BaseSegment {
    /// `(angle, rate, acceleration)` at fraction `s` (0 to 1) of the piece of length `dt`.
    #[inline]
    pub fn at(&self, s: f64, dt: f64) -> (f64, f64, f64) {
        let (p0, p1) = (self.rate0, self.rate1);
        let (m0, m1) = (self.accel0 * dt, self.accel1 * dt);
        let [rate, d_ds, _] = super::base::hermite_cubic(p0, m0, p1, m1, s);
        let (s2, s3, s4) = (s * s, s * s * s, s * s * s * s);
        let integral = (0.5 * s4 - s3 + s) * p0
            + (0.25 * s4 - 2.0 / 3.0 * s3 + 0.5 * s2) * m0
            + (-0.5 * s4 + s3) * p1
            + (0.25 * s4 - s3 / 3.0) * m1;
        (self.angle0 + dt * integral, rate, d_ds / dt)
    }
}

/// Whether the powder brake holds the drum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BrakeState {
    /// Drum held: no output motion until the driving torque exceeds the breakaway torque.
    Stuck,
    /// Drum sliding in direction `+1` or `-1`; the brake opposes with the sliding torque.
    Slipping(f64),
}

/// Cable law of the plant.
// One instance per run, read on every RHS evaluation: kept inline rather than boxed.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum PlantCable {
    /// Capstan model with memory.
    Hysteretic(CableDrive),
    /// Linear halves: `Tu = Tpre + k D`, `Tl = Tpre - k D`.
    Linear {
        /// Stiffness of each half, N/m.
        k_n_per_m: f64,
        /// Preload, N.
        preload_n: f64,
    },
}

impl PlantCable {
    /// The plant cable for a scenario.
    pub fn new(model: CableModel, drive: &DriveParams) -> Self {
        match model {
            CableModel::Hysteretic => {
                PlantCable::Hysteretic(CableDrive::new(drive.clone(), HysteresisModel::Memory))
            }
            CableModel::Linear => PlantCable::Linear {
                k_n_per_m: ClosedLoopParams::half_stiffness_n_per_m(drive),
                preload_n: drive.preload_n,
            },
        }
    }

    /// Elastic span tensions `(Tu, Tl)` for displacement `D` (m); memory not committed.
    #[inline(always)]
    pub fn tensions(&self, d: f64) -> Result<(f64, f64), DriveFault> {
        match self {
            PlantCable::Hysteretic(drive) => hysteretic_tensions(drive, d),
            PlantCable::Linear {
                k_n_per_m,
                preload_n,
            } => linear_tensions(*k_n_per_m, *preload_n, d),
        }
    }

    /// Full check at a period boundary (slack and gross slip on the pulley) and commit of
    /// the memory. Returns the elastic tensions.
    pub fn commit(&mut self, d: f64) -> Result<(f64, f64), DriveFault> {
        match self {
            PlantCable::Hysteretic(drive) => {
                if let Some(tensions) = drive.commit_cached(d) {
                    return tensions;
                }
                let (u, l) = hysteretic_solutions(drive, d)?;
                drive.commit_solutions(&u, &l, d)?;
                Ok((u.tension_n, l.tension_n))
            }
            PlantCable::Linear {
                k_n_per_m,
                preload_n,
            } => linear_tensions(*k_n_per_m, *preload_n, d),
        }
    }
}

/// Both halves of the hysteretic cable solved for displacement `d` (m) on the current
/// memory, with the laws a commit needs. Exact: closed form on the stored segment each
/// slip zone ended on last time, which holds for most of a period and across periods of
/// monotone loading; the halves search from their committed state when it does not.
#[inline(always)]
fn hysteretic_solutions(
    drive: &CableDrive,
    d: f64,
) -> Result<(HalfSolution, HalfSolution), DriveFault> {
    let u = drive.upper().solve_for_elongation(d);
    let u = u.ok_or_else(|| slack(drive, Half::Upper))?;
    let l = drive.lower().solve_for_elongation(-d);
    Ok((u, l.ok_or_else(|| slack(drive, Half::Lower))?))
}

/// [`hysteretic_solutions`], the tensions alone `(Tu, Tl)`, N: the same solves, without
/// the laws a commit needs, which the right-hand side would only copy. (One generic
/// body for both was measured: the compiler then kept the solves out of line.)
#[inline(always)]
fn hysteretic_tensions(drive: &CableDrive, d: f64) -> Result<(f64, f64), DriveFault> {
    let u = drive.upper().tension_series(d);
    let u = u.ok_or_else(|| slack(drive, Half::Upper))?;
    let l = drive.lower().tension_series(-d);
    Ok((u, l.ok_or_else(|| slack(drive, Half::Lower))?))
}

/// A half of `drive` without a positive tension: it goes slack.
#[cold]
fn slack(drive: &CableDrive, half: Half) -> DriveFault {
    DriveFault::Slack {
        half,
        torque_nm: 0.0,
        needed_preload_n: drive.params().preload_n,
    }
}

/// Span tensions `(Tu, Tl)` of the linear cable at displacement `d` (m).
#[inline]
fn linear_tensions(k_n_per_m: f64, preload_n: f64, d: f64) -> Result<(f64, f64), DriveFault> {
    let tu = preload_n + k_n_per_m * d;
    let tl = preload_n - k_n_per_m * d;
    if tu <= 0.0 || tl <= 0.0 {
        Err(DriveFault::Slack {
            half: if tu <= 0.0 { Half::Upper } else { Half::Lower },
            torque_nm: 0.0,
            needed_preload_n: k_n_per_m * d.abs(),
        })
    } else {
        Ok((tu, tl))
    }
}

/// Constant coefficients of the plant equations.
#[derive(Clone, Debug)]
pub struct PlantCoefficients {
    /// Pulley radius, m.
    pub ri: f64,
    /// Drum radius, m.
    pub ro: f64,
    /// Viscous coefficient per half, N s/m.
    pub cable_damping: f64,
    /// Motor parameters in SI units.
    pub jm: f64,
    /// Motor viscous friction, N m s/rad.
    pub bm: f64,
    /// Motor Coulomb friction, N m.
    pub tcm: f64,
    /// Motor friction smoothing speed, rad/s.
    pub wcm: f64,
    /// Torque constant, N m/A.
    pub kt: f64,
    /// Back-EMF constant, V s/rad.
    pub ke: f64,
    /// Resistance, ohm.
    pub r: f64,
    /// Inductance, H.
    pub l: f64,
    /// Whether the command is a voltage.
    pub voltage_mode: bool,
    /// Output inertia, kg m^2.
    pub jo: f64,
    /// Output viscous friction, N m s/rad.
    pub bo: f64,
    /// Sliding brake torque, N m.
    pub brake: f64,
    /// Breakaway brake torque, N m.
    pub breakaway: f64,
    /// Whether any smooth load (unbalance, constant, sine, series) is present; saves a
    /// sine per evaluation when none is.
    pub smooth_load: bool,
    /// Radius ratio `ic = ro/ri`.
    pub ratio: f64,
    /// Kinematic effects of the plant (runouts, thermal drift); `None` when absent or all
    /// zero, so the plain geometry is used.
    pub effects: Option<EffectsParams>,
    /// `1/jm`, `1/l`, `1/jo` and `1/wcm`: the right-hand side multiplies, as divisions
    /// would dominate its latency.
    pub inv: Reciprocals,
    /// Whether the base moves (saves the base terms when it does not).
    pub base: bool,
    /// Gyro natural frequency squared and `2 zeta wn`, (rad/s)^2 and rad/s; `None`
    /// without a gyro (its states stay zero).
    pub gyro: Option<(f64, f64)>,
}

/// Reciprocals of the coefficients the right-hand side divides by.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reciprocals {
    /// `1/jm`, 1/(kg m^2).
    pub jm: f64,
    /// `1/l`, 1/H.
    pub l: f64,
    /// `1/jo`, 1/(kg m^2).
    pub jo: f64,
    /// `1/wcm`, s/rad.
    pub wcm: f64,
}

/// Cable geometry at one state: displacement, its rate and the lever arms through which
/// the span force acts (the base geometry has `ri` and `ro`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kinematics {
    /// Surface displacement `D = ri*theta_m - ro*(theta_o - e_fx)`, m, where `e_fx` is the
    /// effects' added transmission error.
    pub d: f64,
    /// `dD/dt`, m/s.
    pub d_dot: f64,
    /// `dD/d theta_m`, m/rad: the motor feels `-lever_in*(Tu - Tl)`.
    pub lever_in: f64,
    /// `-dD/d theta_o`, m/rad: the drum feels `lever_out*(Tu - Tl)`.
    pub lever_out: f64,
}

impl PlantCoefficients {
    /// From the scenario parts; `effects` are the plant's `[effects]`: the kinematic ones
    /// shift the output against the cable, the bearing friction adds to the brake's
    /// sliding and breakaway torques.
    pub fn new(
        p: &ClosedLoopParams,
        drive: &DriveParams,
        load: &LoadParams,
        effects: Option<&EffectsParams>,
    ) -> Self {
        let bearing = effects.map_or(0.0, EffectsParams::bearing_friction);
        PlantCoefficients {
            ri: drive.pulley_radius_m,
            ro: drive.drum_radius_m,
            cable_damping: p.cable_damping_n_s_per_m(drive),
            jm: p.motor.inertia_kg_m2,
            bm: p.motor.viscous_nm_s_per_rad,
            tcm: p.motor.coulomb_nm,
            wcm: p.motor.coulomb_smoothing_rad_s,
            kt: p.motor.torque_constant_nm_per_a,
            ke: p.motor.back_emf(),
            r: p.motor.resistance_ohm,
            l: p.motor.inductance_h,
            voltage_mode: p.motor.amplifier == Amplifier::Voltage,
            jo: p.output.inertia_kg_m2,
            bo: p.output.viscous_nm_s_per_rad,
            brake: if bearing > 0.0 {
                load.brake_nm + bearing
            } else {
                load.brake_nm
            },
            breakaway: if bearing > 0.0 {
                load.breakaway_nm() + bearing
            } else {
                load.breakaway_nm()
            },
            smooth_load: load.unbalance_nm != 0.0
                || load.constant_nm != 0.0
                || load.sine_nm != 0.0
                || !load.disturbance.is_empty(),
            ratio: drive.ratio(),
            effects: effects.filter(|e| e.has_kinematic()).cloned(),
            inv: Reciprocals {
                jm: 1.0 / p.motor.inertia_kg_m2,
                l: 1.0 / p.motor.inductance_h,
                jo: 1.0 / p.output.inertia_kg_m2,
                wcm: 1.0 / p.motor.coulomb_smoothing_rad_s,
            },
            base: p.base_motion.is_some(),
            gyro: p.gyro.as_ref().map(|g| {
                let wn = std::f64::consts::TAU * g.bandwidth_hz;
                (wn * wn, 2.0 * g.damping * wn)
            }),
        }
    }

    /// Cable geometry at state `x` and time `t` (s).
    #[inline]
    pub fn kinematics(&self, x: &State, t: f64) -> Kinematics {
        match &self.effects {
            None => Kinematics {
                d: self.ri * x[THETA_M] - self.ro * x[THETA_O],
                d_dot: self.ri * x[OMEGA_M] - self.ro * x[OMEGA_O],
                lever_in: self.ri,
                lever_out: self.ro,
            },
            Some(fx) => {
                let k = fx.kinematic_error(x[THETA_M], x[THETA_O], t, self.ratio);
                let lever_in = self.ri + self.ro * k.d_theta_in;
                let lever_out = self.ro * (1.0 - k.d_theta_out);
                Kinematics {
                    d: self.ri * x[THETA_M] - self.ro * (x[THETA_O] - k.value_rad),
                    d_dot: lever_in * x[OMEGA_M] - lever_out * x[OMEGA_O] + self.ro * k.d_t,
                    lever_in,
                    lever_out,
                }
            }
        }
    }
}

/// Right-hand side for one control period, in scaled time: the integrator runs
/// `tau = 0..N` with unit steps and `t = t0 + tau*h`, so exactly `N` RK4 steps land on
/// the period's end without floating-point step counting.
pub struct PeriodRhs<'a> {
    /// Coefficients.
    pub c: &'a PlantCoefficients,
    /// Cable with memory frozen for the period.
    pub cable: &'a PlantCable,
    /// Loads (smooth part; the brake is handled by `brake`).
    pub load: &'a LoadParams,
    /// Brake state for the period.
    pub brake: BrakeState,
    /// Held command (V in voltage mode; ignored in current mode).
    pub command: f64,
    /// Period start time, s.
    pub t0: f64,
    /// Substep length, s.
    pub h: f64,
    /// Substeps in the period, `N`: the integrator stops once `tau` reaches it.
    pub steps: f64,
    /// Base motion over the piece.
    pub base: BaseSegment,
    /// First fault met inside the period.
    pub fault: Cell<Option<DriveFault>>,
}

/// Forces in the plant at one state, for records and the brake logic.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Forces {
    /// Upper span tension including damping, N.
    pub tension_upper_n: f64,
    /// Lower span tension including damping, N.
    pub tension_lower_n: f64,
    /// Torque of the cable on the drum, `ro*(Tu - Tl)`, N m.
    pub cable_torque_nm: f64,
    /// Smooth load torque on the drum (unbalance, constant, sine, series), N m.
    pub smooth_load_nm: f64,
}

/// Tensions including structural damping for elastic tensions `el` and geometry `k`.
#[inline]
pub fn damped(c: &PlantCoefficients, el: (f64, f64), k: &Kinematics) -> (f64, f64) {
    let f = c.cable_damping * k.d_dot;
    (el.0 + f, el.1 - f)
}

/// State derivative for tensions `(tu, tl)` (damping included) acting through the lever
/// arms of `k`, with the base at `(rate, acceleration)` = `base` (rad/s, rad/s^2).
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn derivative(
    c: &PlantCoefficients,
    x: &State,
    k: &Kinematics,
    tensions: (f64, f64),
    smooth_load: f64,
    brake: BrakeState,
    command: f64,
    base: (f64, f64),
) -> State {
    let f = tensions.0 - tensions.1;
    let wm = x[OMEGA_M];
    let friction = c.bm * wm + c.tcm * (wm * c.inv.wcm).clamp(-1.0, 1.0);
    let dwm = (c.kt * x[CURRENT] - friction - k.lever_in * f) * c.inv.jm;
    let di = if c.voltage_mode {
        (command - c.r * x[CURRENT] - c.ke * wm) * c.inv.l
    } else {
        0.0
    };
    let (dto, mut dwo) = match brake {
        BrakeState::Stuck => (0.0, 0.0),
        BrakeState::Slipping(dir) => (
            x[OMEGA_O],
            (k.lever_out * f + smooth_load - c.bo * x[OMEGA_O] - c.brake * dir) * c.inv.jo,
        ),
    };
    let mut dwm = dwm;
    if c.base {
        // Relative coordinates: the base's acceleration is a pseudo-torque on each
        // inertia (a held drum turns with the base, so it feels none relative to it).
        dwm -= base.1;
        if let BrakeState::Slipping(_) = brake {
            dwo -= base.1;
        }
    }
    let (dg, ddg) = match c.gyro {
        Some((wn2, two_zw)) => (
            x[GYRO_DOT],
            wn2 * (x[OMEGA_O] + base.0 - x[GYRO]) - two_zw * x[GYRO_DOT],
        ),
        None => (0.0, 0.0),
    };
    State::from([wm, dwm, di, dto, dwo, dg, ddg])
}

impl System<f64, State> for &PeriodRhs<'_> {
    #[inline(always)]
    fn system(&self, tau: f64, x: &State, dx: &mut State) {
        let c = self.c;
        let t = self.t0 + tau * self.h;
        let k = c.kinematics(x, t);
        let el = match self.cable.tensions(k.d) {
            Ok(t) => t,
            Err(e) => {
                if self.fault.get().is_none() {
                    self.fault.set(Some(e));
                }
                *dx = State::zeros();
                return;
            }
        };
        let (angle, rate, accel) = if c.base {
            self.base.at(tau / self.steps, self.h * self.steps)
        } else {
            (0.0, 0.0, 0.0)
        };
        let smooth = if c.smooth_load {
            self.load.smooth_torque_nm(t, x[THETA_O] + angle)
        } else {
            0.0
        };
        let dxt = derivative(
            c,
            x,
            &k,
            damped(c, el, &k),
            smooth,
            self.brake,
            self.command,
            (rate, accel),
        );
        *dx = dxt * self.h;
    }

    // Rk4 sizes its result vectors from its end point and grows both for the closing
    // sample; run towards `2N` and stopped here at `N` it never reallocates, which was the
    // largest cost of a period outside the cable.
    #[inline]
    fn solout(&mut self, tau: f64, _x: &State, _dx: &State) -> bool {
        tau >= self.steps
    }
}

/// Stick/slip decision at a period boundary, given the driving torque on the drum
/// (`cable + smooth load`, N m) and the state (output speed may be reset to 0).
///
/// Stuck -> slipping only when the driving torque exceeds the breakaway torque; slipping
/// -> stuck only when the speed has reached or crossed zero and the driving torque is
/// below it. A reversal therefore always passes through `Stuck` and needs the full
/// breakaway torque the other way, so the drum cannot chatter between directions. The
/// overshoot of a speed crossing inside a period (at most `brake*T/Jo` in speed) is
/// removed by resetting the speed to zero.
pub fn update_brake(
    c: &PlantCoefficients,
    state: BrakeState,
    driving_nm: f64,
    x: &mut State,
) -> BrakeState {
    if c.breakaway <= 0.0 {
        // No brake: always free; the direction is irrelevant.
        return BrakeState::Slipping(1.0);
    }
    let from_rest = |x: &mut State| {
        x[OMEGA_O] = 0.0;
        if driving_nm.abs() > c.breakaway {
            BrakeState::Slipping(driving_nm.signum())
        } else {
            BrakeState::Stuck
        }
    };
    match state {
        BrakeState::Stuck => from_rest(x),
        BrakeState::Slipping(dir) => {
            if x[OMEGA_O] * dir > 0.0 {
                state
            } else {
                from_rest(x)
            }
        }
    }
}

/// Load torque the brake and the other loads put on the drum, N m (reaction of a held
/// brake included), for records.
pub fn load_torque(c: &PlantCoefficients, brake: BrakeState, f: &Forces) -> f64 {
    match brake {
        BrakeState::Stuck => -f.cable_torque_nm,
        BrakeState::Slipping(dir) => f.smooth_load_nm - c.brake * dir,
    }
}
