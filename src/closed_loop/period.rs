//! One control period of the plant, as the sample-and-hold loop and an external host (the
//! co-simulation adapter) both drive it: settle the boundary (commit the cable memory,
//! decide the brake), then integrate with the command held.

use ode_solvers::dop_shared::{Stats, System};

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
#[inline(always)]
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
#[inline(always)]
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
    let start = *x;
    let stats = rk4_fixed(&&rhs, x, substeps);
    let fault = rhs.fault.get();
    match fault {
        Some(_) => *x = start,
        None => {
            if let BrakeState::Stuck = brake {
                x[OMEGA_O] = 0.0;
            }
        }
    }
    PeriodEnd { stats, fault }
}

/// `steps` classical Runge-Kutta steps of unit length from `tau = 0`, in place: the same
/// arithmetic, in the same order, as `ode_solvers::Rk4` run with step 1 (a test holds the
/// two bit-identical), without the result vectors that solver allocates and fills on
/// every call: at one period per call they cost about a tenth of the whole simulation.
/// On return `x` holds the state at `tau = steps`.
#[inline]
pub fn rk4_fixed<S: System<f64, State>>(f: &S, x: &mut State, steps: u32) -> Stats {
    let mut k = [State::zeros(); 4];
    let mut buffer = State::zeros();
    let mut tau = 0.0;
    let sixth = 1.0 / 6.0;
    for _ in 0..steps {
        f.system(tau, x, &mut k[0]);
        for i in 0..buffer.len() {
            buffer[i] = x[i] + k[0][i] * 0.5;
        }
        f.system(tau + 0.5, &buffer, &mut k[1]);
        for i in 0..buffer.len() {
            buffer[i] = x[i] + k[1][i] * 0.5;
        }
        f.system(tau + 0.5, &buffer, &mut k[2]);
        for i in 0..buffer.len() {
            buffer[i] = x[i] + k[2][i];
        }
        f.system(tau + 1.0, &buffer, &mut k[3]);
        for i in 0..x.len() {
            x[i] += (k[0][i] + k[1][i] * 2.0 + k[2][i] * 2.0 + k[3][i]) * sixth;
        }
        tau += 1.0;
    }
    Stats {
        num_eval: 4 * steps,
        accepted_steps: steps,
        rejected_steps: 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ode_solvers::Rk4;

    /// A stiff-ish, nonlinear, time-varying system: every term of RK4 matters.
    struct Wobble;
    impl System<f64, State> for Wobble {
        fn system(&self, t: f64, x: &State, dx: &mut State) {
            for i in 0..7 {
                let j = (i + 1) % 7;
                dx[i] = -0.3 * x[i] + (x[j] * 1.7 + t).sin() - 0.01 * x[i].powi(3);
            }
        }
    }

    #[test]
    fn fixed_rk4_is_bit_identical_to_ode_solvers_rk4() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for steps in [1u32, 2, 3, 7] {
            for _ in 0..20 {
                let x0 = State::from_fn(|_, _| rng.gen_range(-3.0..3.0));
                let mut solver = Rk4::new(Wobble, 0.0, x0, f64::from(steps), 1.0);
                let s = solver.integrate().expect("Rk4 never fails");
                let want = *solver.y_out().last().expect("at least the start");
                let mut got = x0;
                let stats = rk4_fixed(&Wobble, &mut got, steps);
                assert_eq!(got, want, "{steps} steps from {x0:?}");
                assert_eq!(stats.num_eval, s.num_eval);
                assert_eq!(stats.accepted_steps, s.accepted_steps);
            }
        }
    }
}
