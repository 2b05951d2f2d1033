//! One control period of the plant, as the sample-and-hold loop and an external host (the
//! co-simulation adapter) both drive it: settle the boundary (commit the cable memory,
//! decide the brake), then integrate with the command held.

use ode_solvers::dop_shared::Stats;
use ode_solvers::Rk4;

use super::plant::{
    damped, update_brake, BaseSegment, BrakeState, Forces, PeriodRhs, PlantCable,
    PlantCoefficients, State, OMEGA_O, THETA_O,
};
use crate::physics::{DriveFault, LoadParams};

/// Period boundary at time `t` (s): commits the cable memory at the displacement of `x`,
/// then lets the brake stick or slip (which may zero the output speed in `x`). Returns
/// the forces at the boundary (tensions with damping). On a fault nothing is committed and
/// neither `brake` nor `x` changes. `base` is the base's `(angle, acceleration)` at `t`
/// (rad, rad/s^2; zeros without base motion): a held drum must also carry the base's
/// pseudo-torque `-Jo beta''`.
#[inline]
pub fn settle_boundary(
    c: &PlantCoefficients,
    cable: &mut PlantCable,
    load: &LoadParams,
    brake: &mut BrakeState,
    x: &mut State,
    t: f64,
    base: (f64, f64),
) -> Result<Forces, DriveFault> {
    let kin = c.kinematics(x, t);
    let el = cable.commit(kin.d)?;
    let (tu, tl) = damped(c, el, &kin);
    let forces = Forces {
        tension_upper_n: tu,
        tension_lower_n: tl,
        cable_torque_nm: kin.lever_out * (tu - tl),
        smooth_load_nm: if c.smooth_load {
            load.smooth_torque_nm(t, x[THETA_O] + base.0)
        } else {
            0.0
        },
    };
    let inertial = if c.base { -c.jo * base.1 } else { 0.0 };
    *brake = update_brake(
        c,
        *brake,
        forces.cable_torque_nm + forces.smooth_load_nm + inertial,
        x,
    );
    Ok(forces)
}

/// How an integrated period ended.
#[derive(Clone, Copy, Debug)]
pub struct PeriodEnd {
    /// Integrator statistics of the period (counted also when it faulted).
    pub stats: Stats,
    /// First cable fault met inside the period; the state was then left unchanged.
    pub fault: Option<DriveFault>,
}

/// Integrates `x` over `[t0, t0 + period_s]` with `command` held (V in voltage mode; the
/// current of a current amplifier is set in `x` by the caller) and the cable memory
/// frozen: `substeps` fixed RK4 steps, the integrator started afresh, so sample-and-hold
/// is exact. On success `x` holds the end state (output speed zero while the brake
/// holds); the state is not checked for finiteness.
#[allow(clippy::too_many_arguments)]
#[inline]
pub fn integrate_period(
    c: &PlantCoefficients,
    cable: &PlantCable,
    load: &LoadParams,
    brake: BrakeState,
    command: f64,
    t0: f64,
    period_s: f64,
    substeps: u32,
    base: BaseSegment,
    x: &mut State,
) -> PeriodEnd {
    let rhs = PeriodRhs {
        c,
        cable,
        load,
        brake,
        command,
        t0,
        h: period_s / f64::from(substeps),
        steps: f64::from(substeps),
        base,
        fault: std::cell::Cell::new(None),
    };
    // End point 2N: room for all N + 1 results; `solout` stops the run at N.
    let mut solver = Rk4::new(&rhs, 0.0, *x, 2.0 * f64::from(substeps), 1.0);
    // Rk4 never fails; a cable fault is reported through the RHS.
    let stats = solver.integrate().unwrap_or(Stats {
        num_eval: 0,
        accepted_steps: 0,
        rejected_steps: 0,
    });
    let fault = rhs.fault.get();
    if fault.is_none() {
        if let Some(y) = solver.y_out().last() {
            *x = *y;
        }
        if let BrakeState::Stuck = brake {
            x[OMEGA_O] = 0.0;
        }
    }
    PeriodEnd { stats, fault }
}
