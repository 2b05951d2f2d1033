//! The exact linear reference of a closed loop: computed, not simulated.
//!
//! The plant with the cable replaced by its linear spring (both free spans, `k = G/Lf` per
//! half, plus the structural damping), the motor (current amplifier: the winding current is
//! the held command; voltage amplifier: `R`, `L`, `Ke`), both inertias and viscous
//! friction, discretised exactly with a zero-order hold at the control period (matrix
//! exponential). The computation delay of `m + f` periods holds `u_{k-m-1}` over the first
//! `f` of a period and `u_{k-m}` over the rest, which discretises exactly as
//! `x_{k+1} = Ad x_k + B1 u_{k-m-1} + B2 u_{k-m}`. The PID is the implemented difference
//! equation (derivative on the measurement through its first-order filter, integral by
//! forward sums), so the loop gain broken at the plant input is
//!
//! ```text
//! K(z) = kp + ki T / (1 - z^-1) + (1 - a) (kd / T) (1 - z^-1) / (1 - a z^-1)
//! L(z) = K(z) P(z),   P(z) = C (zI - Ad)^-1 (B1 z^-1 + B2) z^-m
//! S = 1 / (1 + L),    T = L / (1 + L)
//! ```
//!
//! Margins are read on a dense logarithmic grid up to Nyquist and refined by bisection. A
//! PID around a double integrator is conditionally stable (its phase starts at -270 deg),
//! so the gain margin is split into the upward one (crossings of the negative real axis
//! with `|L| < 1`, the classical margin) and the downward one (`|L| > 1`). Stability of
//! the closed loop is decided by the eigenvalues of the assembled sampled system, not by
//! the margins.

use nalgebra::{Complex, DMatrix, DVector};
use serde::Serialize;

use super::resolvent::{self, StateMatrix};
use crate::closed_loop::filters::{Biquad, FilterSpec};
use crate::closed_loop::params::{Amplifier, ClosedLoopParams, Feedback, RateSource};
pub use crate::closed_loop::sim::Instability;
use crate::physics::DriveParams;

/// The linear sampled loop of a closed-loop setup.
#[derive(Clone, Debug)]
pub struct LinearLoop {
    /// Continuous state matrix (for the base motion's forcing).
    a_cont: DMatrix<f64>,
    /// Continuous input matrix of the held command (A or V).
    b_cont: DVector<f64>,
    /// Whether the command is a voltage (a fifth state: the winding current).
    voltage: bool,
    /// State transition over one period.
    ad: DMatrix<f64>,
    /// `ad` on the stack, for its resolvent at the margins' thousands of frequencies;
    /// `None` beyond [`resolvent::MAX_DIM`] states.
    ad_stack: Option<StateMatrix>,
    /// Input matrix of the command held over the first `fraction` of the period.
    b1: DVector<f64>,
    /// Input matrix of the command held over the rest.
    b2: DVector<f64>,
    /// Measured output row of the position loop (motor angle, or `ic` times the output
    /// angle), motor rad; with gyro-angle feedback, `ic` times the gyro's rate.
    c: DVector<f64>,
    /// Rows of the motor angle, the drum angle and the gyro's rate.
    rows: [DVector<f64>; 3],
    /// `c` as a combination of `rows`.
    c_scale: [f64; 3],
    /// Base rate's entry (the gyro sees it), per rad/s.
    base_rate: DVector<f64>,
    /// Transmission ratio `ro / ri`: motor rad per drum rad.
    ic: f64,
    /// Whole periods of computation delay.
    whole: usize,
    /// The fraction of a period beyond `whole` (0 to 1).
    fraction: f64,
    /// Sample period, s.
    ts: f64,
    kp: f64,
    ki_t: f64,
    kd_t: f64,
    a: f64,
    /// The rest of the control law (rate loop, filters, observer); `None` for a plain PID.
    law: Option<LawModel>,
    /// Gain inserted between the law and the plant (1; margin checks scale it).
    scale: f64,
    /// Input matrix of a torque held on the drum over one period (ZOH, no delay: a load
    /// acts at once), per N m.
    drum_torque: DVector<f64>,
}

/// Indices of [`LinearLoop::rows`].
const ROW_MOTOR: usize = 0;
const ROW_DRUM: usize = 1;
const ROW_GYRO: usize = 2;

/// The linear control law beyond the PID, as difference equations and responses.
#[derive(Clone, Debug)]
struct LawModel {
    feedback: Feedback,
    ic: f64,
    measurement_filters: Vec<Biquad>,
    rate: Option<RateModel>,
    command_filters: Vec<Biquad>,
    /// Observer filters `(Q (J/Kt) s^2, Q)` and the command delay it uses.
    observer: Option<(Biquad, Biquad, usize)>,
    /// Control rate, Hz.
    fs: f64,
}

#[derive(Clone, Debug)]
struct RateModel {
    kp: f64,
    ki_t: f64,
    source: RateSource,
    /// Velocity estimate's pole.
    a_v: f64,
    command_filters: Vec<Biquad>,
    measurement_filters: Vec<Biquad>,
}

fn augmented_exp(a: &DMatrix<f64>, b: &DVector<f64>, tau: f64) -> (DMatrix<f64>, DVector<f64>) {
    let n = a.nrows();
    let mut m = DMatrix::<f64>::zeros(n + 1, n + 1);
    m.view_mut((0, 0), (n, n)).copy_from(a);
    m.view_mut((0, n), (n, 1)).copy_from(b);
    let e = (m * tau).exp();
    (
        e.view((0, 0), (n, n)).into_owned(),
        e.view((0, n), (n, 1)).column(0).into_owned(),
    )
}

/// Tangent stiffness of the preloaded drive on first loading to the transmitted torque
/// `load_nm` (N m), as the stiffness of each of two equal linear halves (N/m): half of
/// `d(Tu - Tl)/dD` on the loading branch, where `D` is the span displacement that carries
/// `ro (Tu - Tl) = load_nm` from a virgin preloaded state.
///
/// At zero load this is the free-span stiffness [`ClosedLoopParams::half_stiffness_n_per_m`];
/// as the load grows the slip zones on the wraps add compliance and it falls. It is the
/// stiffness of continued loading: a small motion reversed about that load sees the wraps
/// stick again, and with them the free-span stiffness. A load the drive cannot carry on
/// first loading (a slack span or gross slip) is an error that says which.
pub fn tangent_half_stiffness(drive: &DriveParams, load_nm: f64) -> Result<f64, String> {
    use crate::closed_loop::params::CableModel;
    use crate::closed_loop::plant::PlantCable;
    let free = ClosedLoopParams::half_stiffness_n_per_m(drive);
    if !load_nm.is_finite() {
        return Err(format!("load {load_nm} N m is not a finite torque"));
    }
    if load_nm == 0.0 {
        return Ok(free);
    }
    let cable = PlantCable::new(CableModel::Hysteretic, drive);
    let sign = load_nm.signum();
    let target = load_nm.abs() / drive.drum_radius_m;
    let force = |d: f64| {
        cable
            .tensions(sign * d)
            .map(|(u, l)| sign * (u - l))
            .map_err(|e| e.to_string())
    };
    // The free span is the stiffest the drive gets: from there the load needs more.
    let mut hi = target / (2.0 * free);
    let mut doublings = 0;
    let slack = |_| {
        // A load beyond any double's preload has no preload to suggest.
        let needed_n = load_nm.abs() / (2.0 * drive.drum_radius_m);
        let remedy = if needed_n.is_finite() {
            format!(
                "raise drive.preload_n above about {} N or lower the load",
                crate::compact(needed_n)
            )
        } else {
            "lower the load".to_string()
        };
        format!(
            "the drive cannot carry {} N m on first loading from its {} N preload: a span goes slack first (the halves carry at most about 2 x preload_n x drum_radius_m = {} N m); {remedy}",
            crate::number(load_nm),
            crate::number(drive.preload_n),
            crate::compact(2.0 * drive.preload_n * drive.drum_radius_m),
        )
    };
    // Bracket the displacement between one that carries less than the load and one that
    // carries it or leaves a span slack: a doubling can step past the slack point of a
    // load the drive still carries just short of it.
    let mut lo = 0.0;
    loop {
        match force(hi) {
            Ok(f) if f < target => {
                lo = hi;
                hi *= 2.0;
                doublings += 1;
                if doublings > 200 {
                    return Err(format!(
                        "no span displacement carries {} N m",
                        crate::number(load_nm)
                    ));
                }
            }
            _ => break,
        }
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        match force(mid) {
            Ok(f) if f < target => lo = mid,
            _ => hi = mid,
        }
    }
    // Bisection closes on the load, or on the slack point when the drive cannot carry it.
    force(hi).map_err(slack)?;
    let d = hi;
    let mut committed = cable.clone();
    committed.commit(sign * d).map_err(|e| {
        format!(
            "the drive cannot carry {} N m on first loading from its {} N preload: {e}",
            crate::number(load_nm),
            crate::number(drive.preload_n)
        )
    })?;
    // Central difference on the loading curve (smooth for D > 0, and through D = 0 where
    // both sides start at the free span). The step is large enough that the difference of
    // two spans of about the preload keeps its digits, small enough for the curvature.
    let h = (d * 1e-4).max(1e-10);
    let k_d = (force(d + h)? - force(d - h)?) / (2.0 * h);
    if !(k_d.is_finite() && k_d > 0.0) {
        return Err(format!(
            "the drive has no stiffness left at {} N m",
            crate::number(load_nm)
        ));
    }
    Ok(0.5 * k_d)
}

impl LinearLoop {
    /// The loop of `p` around `drive`, with the cable as its linear spring.
    pub fn new(p: &ClosedLoopParams, drive: &DriveParams) -> Self {
        Self::with_half_stiffness(p, drive, ClosedLoopParams::half_stiffness_n_per_m(drive))
    }

    /// The loop with each half of the cable a linear spring of `k` N/m: the free-span
    /// stiffness of [`Self::new`], or a tangent stiffness from [`tangent_half_stiffness`].
    pub fn with_half_stiffness(p: &ClosedLoopParams, drive: &DriveParams, k: f64) -> Self {
        let (ri, ro) = (drive.pulley_radius_m, drive.drum_radius_m);
        let cd = p.cable_damping_n_s_per_m(drive);
        let m = &p.motor;
        let (jm, bm, kt) = (
            m.inertia_kg_m2,
            m.viscous_nm_s_per_rad,
            m.torque_constant_nm_per_a,
        );
        let (jo, bo) = (p.output.inertia_kg_m2, p.output.viscous_nm_s_per_rad);
        let voltage = m.amplifier == Amplifier::Voltage;
        // States [theta_m, omega_m, theta_o, omega_o] (+ current with a voltage amplifier)
        // (+ the gyro's rate and its derivative).
        let n_mech = if voltage { 5 } else { 4 };
        let gyro = p.gyro.as_ref();
        let n = n_mech + if gyro.is_some() { 2 } else { 0 };
        let mut a = DMatrix::<f64>::zeros(n, n);
        let mut b = DVector::<f64>::zeros(n);
        let mut base_rate = DVector::<f64>::zeros(n);
        if let Some(g) = gyro {
            let wn = std::f64::consts::TAU * g.bandwidth_hz;
            let (gi, gd) = (n_mech, n_mech + 1);
            a[(gi, gd)] = 1.0;
            a[(gd, gi)] = -wn * wn;
            a[(gd, gd)] = -2.0 * g.damping * wn;
            a[(gd, 3)] = wn * wn;
            base_rate[gd] = wn * wn;
        }
        // F = Tu - Tl = 2k (ri th_m - ro th_o) + 2c (ri w_m - ro w_o)
        let f = [2.0 * k * ri, 2.0 * cd * ri, -2.0 * k * ro, -2.0 * cd * ro];
        a[(0, 1)] = 1.0;
        a[(2, 3)] = 1.0;
        for (j, fj) in f.iter().enumerate() {
            a[(1, j)] = -ri * fj / jm;
            a[(3, j)] = ro * fj / jo;
        }
        a[(1, 1)] -= bm / jm;
        a[(3, 3)] -= bo / jo;
        if voltage {
            a[(1, 4)] = kt / jm;
            a[(4, 1)] = -m.back_emf() / m.inductance_h;
            a[(4, 4)] = -m.resistance_ohm / m.inductance_h;
            b[4] = 1.0 / m.inductance_h;
        } else {
            b[1] = kt / jm;
        }
        let ctl = &p.controller;
        let ts = 1.0 / ctl.sample_rate_hz;
        let delay = ctl.computation_delay_samples.max(0.0);
        let whole = delay.floor();
        let f = delay - whole;
        let (ad, _) = augmented_exp(&a, &b, ts);
        let mut on_drum = DVector::<f64>::zeros(n);
        on_drum[3] = 1.0 / jo;
        let (_, drum_torque) = augmented_exp(&a, &on_drum, ts);
        let (phi_rest, gam_rest) = augmented_exp(&a, &b, (1.0 - f) * ts);
        let (_, gam_first) = augmented_exp(&a, &b, f * ts);
        let ic = drive.ratio();
        let unit = |i: usize| {
            let mut v = DVector::<f64>::zeros(n);
            if i < n {
                v[i] = 1.0;
            }
            v
        };
        let rows = [
            unit(0),
            unit(2),
            if gyro.is_some() {
                unit(n_mech)
            } else {
                DVector::zeros(n)
            },
        ];
        let c_scale = match ctl.feedback {
            Feedback::Motor => [1.0, 0.0, 0.0],
            Feedback::Output => [0.0, ic, 0.0],
            Feedback::GyroAngle => [0.0, 0.0, ic],
        };
        let c = &rows[0] * c_scale[0] + &rows[1] * c_scale[1] + &rows[2] * c_scale[2];
        let fs = ctl.sample_rate_hz;
        let chain = |v: &[FilterSpec]| v.iter().map(|f| Biquad::design(f, fs)).collect();
        // Gyro-angle feedback integrates the gyro inside the law: never the plain path.
        let law = (!ctl.is_plain_pid() || ctl.feedback == Feedback::GyroAngle).then(|| LawModel {
            feedback: ctl.feedback,
            ic,
            measurement_filters: chain(&ctl.measurement_filters),
            rate: ctl.rate_loop.as_ref().map(|r| RateModel {
                kp: r.kp,
                ki_t: r.ki * ts,
                source: r.measurement,
                a_v: (-std::f64::consts::TAU * r.velocity_filter_hz * ts).exp(),
                command_filters: chain(&ctl.rate_command_filters),
                measurement_filters: chain(&ctl.rate_measurement_filters),
            }),
            command_filters: chain(&ctl.command_filters),
            observer: crate::closed_loop::law::observer_filters(p, ic).map(|(inv, q)| {
                (
                    Biquad::design(&inv, fs),
                    Biquad::design(&q, fs),
                    crate::closed_loop::law::observer_delay(p),
                )
            }),
            fs,
        });
        LinearLoop {
            a_cont: a,
            b_cont: b,
            voltage,
            ad_stack: StateMatrix::of(&ad),
            ad,
            b1: phi_rest * gam_first,
            b2: gam_rest,
            c,
            rows,
            c_scale,
            base_rate,
            ic,
            whole: whole as usize,
            fraction: f,
            ts,
            kp: ctl.kp,
            ki_t: ctl.ki * ts,
            kd_t: ctl.kd / ts,
            a: (-std::f64::consts::TAU * ctl.derivative_filter_hz * ts).exp(),
            law,
            scale: 1.0,
            drum_torque,
        }
    }

    /// The same loop with the position PID's gains replaced: `kp` (command per rad), `ki`
    /// (command per rad s), `kd` (command s per rad); the derivative filter, the rest of
    /// the law (filters, rate loop, observer), the delay and the plant are kept. Every
    /// path of the law reads the PID's gains from this loop, so nothing else needs
    /// rebuilding.
    pub fn with_pid(&self, kp: f64, ki: f64, kd: f64) -> Self {
        // A plain PID carries a margin check's gain in its gains; a law applies it at
        // its output.
        let g = if self.law.is_none() { self.scale } else { 1.0 };
        LinearLoop {
            kp: kp * g,
            ki_t: ki * self.ts * g,
            kd_t: kd / self.ts * g,
            ..self.clone()
        }
    }

    /// Open-loop responses of the motor angle, the drum angle and the gyro's rate to a
    /// torque held on the drum at `f_hz` (rad, or rad/s for the gyro, per N m); with
    /// [`Self::plant_rows`] they give the loop's compliance to a load such as a brake.
    pub fn drum_torque_rows(&self, f_hz: f64) -> [Complex<f64>; 3] {
        let x = self.resolvent(f_hz, |i| Complex::from(self.drum_torque[i]));
        [0, 1, 2].map(|j| dot(&self.rows[j], x.as_slice()))
    }

    /// Closed-loop compliance of the drum to a torque held on it, rad per N m at `f_hz`:
    /// how far a load such as a brake's reversal pushes the line of sight, with every
    /// path of the law closed (`u = sum k_j y_j`, so `u = sum k_j P_jd / (1 - sum k_j P_ju) d`).
    pub fn drum_compliance(&self, f_hz: f64) -> Complex<f64> {
        let pu = self.plant_rows(f_hz);
        let pd = self.drum_torque_rows(f_hz);
        let k = self.law_row(f_hz);
        let one = Complex::from(1.0);
        let num: Complex<f64> = (0..3).map(|j| k[j] * pd[j]).sum();
        let den: Complex<f64> = one - (0..3).map(|j| k[j] * pu[j]).sum::<Complex<f64>>();
        pd[ROW_DRUM] + pu[ROW_DRUM] * num / den
    }

    /// Whether the law is a plain PID (no rate loop, filters or observer).
    pub fn is_plain_pid(&self) -> bool {
        self.law.is_none()
    }

    /// `(zI - Ad)^-1 v` at `f_hz`, `v` given by its components: on the stack for the
    /// usual sizes, through nalgebra's LU beyond them.
    fn resolvent(&self, f_hz: f64, v: impl Fn(usize) -> Complex<f64>) -> Resolved {
        self.resolvent_at(self.z_inverse(f_hz).conj(), v)
    }

    /// [`Self::resolvent`] at `z` (on the unit circle: `e^{j 2 pi f T}`).
    fn resolvent_at(&self, z: Complex<f64>, v: impl Fn(usize) -> Complex<f64>) -> Resolved {
        let n = self.ad.nrows();
        if let Some(r) = &self.ad_stack {
            let mut rhs = [Complex::new(0.0, 0.0); resolvent::MAX_DIM];
            for (i, e) in rhs.iter_mut().enumerate().take(n) {
                *e = v(i);
            }
            if let Some(x) = r.resolvent(z, &rhs[..n]) {
                return Resolved::Stack(x);
            }
        }
        let m = DMatrix::<Complex<f64>>::identity(n, n) * z - self.ad.map(Complex::from);
        let rhs = DVector::from_fn(n, |i, _| v(i));
        Resolved::Heap(m.lu().solve(&rhs).unwrap_or_else(|| DVector::zeros(n)))
    }

    /// Responses of the motor angle, the drum angle and the gyro's rate to the held
    /// command at `f_hz`, delay included (rad, or rad/s for the gyro, per A or V).
    pub fn plant_rows(&self, f_hz: f64) -> [Complex<f64>; 3] {
        let zi = self.z_inverse(f_hz);
        let x = self.resolvent_at(zi.conj(), |i| {
            Complex::from(self.b1[i]) * zi + Complex::from(self.b2[i])
        });
        let d = zi.powi(self.whole as i32);
        [0, 1, 2].map(|j| dot(&self.rows[j], x.as_slice()) * d)
    }

    /// The command as a combination of the three measured quantities, `u = sum k_j y_j`
    /// (reference zero), at `f_hz`.
    fn law_row(&self, f_hz: f64) -> [Complex<f64>; 3] {
        let zi = Complex::from_polar(1.0, -std::f64::consts::TAU * f_hz * self.ts);
        let one = Complex::from(1.0);
        let pid = Complex::from(self.kp)
            + Complex::from(self.ki_t) / (one - zi)
            + (one - zi) * ((1.0 - self.a) * self.kd_t) / (one - zi * self.a);
        let zero = Complex::from(0.0);
        let Some(law) = &self.law else {
            // The plain PID on its one measurement.
            return self.c_scale.map(|w| -pid * w);
        };
        let fs = law.fs;
        // Position measurement in terms of the three quantities.
        let mut meas = [zero; 3];
        match law.feedback {
            Feedback::Motor => meas[ROW_MOTOR] = one,
            Feedback::Output => meas[ROW_DRUM] = Complex::from(law.ic),
            Feedback::GyroAngle => {
                meas[ROW_GYRO] = Complex::from(law.ic * self.ts) * zi / (one - zi);
            }
        }
        let pos = pid * chain_response(&law.measurement_filters, f_hz, fs);
        let mut fb = meas.map(|m| -pos * m);
        if let Some(r) = &law.rate {
            let pi = Complex::from(r.kp) + Complex::from(r.ki_t) / (one - zi);
            let frc = chain_response(&r.command_filters, f_hz, fs);
            let frm = chain_response(&r.measurement_filters, f_hz, fs);
            let mut w = [zero; 3];
            match r.source {
                RateSource::Gyro => w[ROW_GYRO] = one,
                RateSource::MotorVelocity => {
                    w[ROW_MOTOR] =
                        (one - zi) * ((1.0 - r.a_v) / (self.ts * law.ic)) / (one - zi * r.a_v);
                }
            }
            for j in 0..3 {
                fb[j] = pi * (frc * fb[j] - frm * w[j]);
            }
        }
        let fc = chain_response(&law.command_filters, f_hz, fs);
        let mut u = fb.map(|v| fc * v);
        if let Some((inv, q, md)) = &law.observer {
            let denom = one - q.response(f_hz, fs) * zi.powi(*md as i32);
            u[ROW_MOTOR] -= inv.response(f_hz, fs);
            u = u.map(|v| v / denom);
        }
        u.map(|v| v * self.scale)
    }

    /// Nyquist frequency, Hz.
    pub fn nyquist_hz(&self) -> f64 {
        0.5 / self.ts
    }

    /// Plant `P` from held command to the position loop's measurement at `f_hz`, delay
    /// included (for gyro-angle feedback: to `ic` times the gyro's rate).
    pub fn plant(&self, f_hz: f64) -> Complex<f64> {
        self.plant_at(self.z_inverse(f_hz))
    }

    /// `z^-1 = e^{-j 2 pi f T}` at `f_hz`.
    fn z_inverse(&self, f_hz: f64) -> Complex<f64> {
        Complex::from_polar(1.0, -std::f64::consts::TAU * f_hz * self.ts)
    }

    /// [`Self::plant`] with its `z^-1` given.
    fn plant_at(&self, zi: Complex<f64>) -> Complex<f64> {
        // On the unit circle z is the conjugate of z^-1: one sine and cosine for both.
        let x = self.resolvent_at(zi.conj(), |i| {
            Complex::from(self.b1[i]) * zi + Complex::from(self.b2[i])
        });
        dot(&self.c, x.as_slice()) * zi.powi(self.whole as i32)
    }

    /// Line of sight over base angle at `f_hz` (complex ratio at the samples): the base
    /// turns as `sin(2 pi f t)`, the loop answers through the drum, the gyro and the
    /// motor, and the line of sight is the base angle plus the drum's. 1 at low frequency
    /// for a loop on the encoders (the drum follows the base), small for a stabilised one.
    ///
    /// Evaluated on the sampled closed loop, `(zI - Acl)^-1` applied to the base's input,
    /// whose poles lie inside the unit circle. A NaN ratio means the closed loop is
    /// singular at `f_hz` (a pole on the unit circle there).
    pub fn base_to_los(&self, f_hz: f64) -> Complex<f64> {
        // Coordinates: the drum's inertial angle (the line of sight itself) and the motor's
        // angle relative to the base plus `ic` times the base's (where the motor must
        // stand for the cable to be unstretched under a drum held still), speeds alike.
        // In them the base stretches no cable: it enters only through friction, drag and
        // back-EMF on relative speeds, the motor's inertia (it turns by (1 - ic) beta)
        // and the encoders' readings, all of the size of the loop's answer, so nothing
        // cancels. In relative angles the line of sight is the difference of two numbers
        // near the base angle; in plain inertial angles the cable is stretched by
        // (ro - ri) beta, an order-one forcing that the open loop's double pole at z = 1
        // amplifies and the loop's answer cancels. Both lost every digit below ~1 Hz.
        let n = self.ad.nrows();
        let w = std::f64::consts::TAU * f_hz;
        let jw = Complex::new(0.0, w);
        let mut shift_rate = DVector::<f64>::zeros(n);
        shift_rate[1] = self.ic;
        shift_rate[3] = 1.0;
        let mut shift_angle = DVector::<f64>::zeros(n);
        shift_angle[0] = self.ic;
        shift_angle[2] = 1.0;
        // Both inertias feel -J beta'' in the relative angles the plant is written in.
        let mut accel = DVector::<f64>::zeros(n);
        accel[1] = -1.0;
        accel[3] = -1.0;
        // x' = A x + B u + (shift_angle + base_rate - A shift_rate) beta'
        //      + (shift_rate + accel) beta''; A shift_angle is the cable's stretch under
        // the shift, zero by construction, and left out rather than rounded.
        let by_rate = &shift_angle + &self.base_rate - &self.a_cont * &shift_rate;
        let by_accel = &shift_rate + &accel;
        let v: DVector<Complex<f64>> =
            by_rate.map(|x| jw * x) + by_accel.map(|x| Complex::from(-w * w * x));
        // Forcing of beta = e^{jwt} over the period from t = 0: the integral of
        // e^{A(T-s)} v e^{jws} ds, the corner of the exponential of [[A, v], [0, jw]].
        let scale = v.norm();
        let mut forcing = DVector::<Complex<f64>>::zeros(n);
        if scale > 0.0 {
            let mut m = DMatrix::<Complex<f64>>::zeros(n + 1, n + 1);
            m.view_mut((0, 0), (n, n))
                .copy_from(&self.a_cont.map(Complex::from));
            m.view_mut((0, n), (n, 1))
                .copy_from(&(&v / Complex::from(scale)));
            m[(n, n)] = jw;
            let e = (m * Complex::from(self.ts)).exp();
            forcing = e.view((0, n), (n, 1)).column(0).into_owned() * Complex::from(scale);
        }
        // The encoders read relative angles: the motor's is the shifted one less
        // ic beta, the drum's the inertial one less beta; the gyro reads the state.
        let law = self.step_read(
            &DVector::zeros(self.closed_loop_dim()),
            &[self.ic, 1.0, 0.0],
        );
        let mut input = law.map(Complex::from);
        for i in 0..n {
            input[i] += forcing[i];
        }
        let acl = self.closed_loop_matrix();
        let dim = acl.nrows();
        let z = Complex::from_polar(1.0, w * self.ts);
        let lhs = DMatrix::<Complex<f64>>::identity(dim, dim) * z - acl.map(Complex::from);
        match lhs.lu().solve(&input) {
            Some(s) => s[2],
            None => Complex::new(f64::NAN, f64::NAN),
        }
    }

    /// Controller `K` at `f_hz`.
    pub fn controller(&self, f_hz: f64) -> Complex<f64> {
        self.controller_at(self.z_inverse(f_hz))
    }

    /// [`Self::controller`] at a given `z^-1`.
    fn controller_at(&self, zi: Complex<f64>) -> Complex<f64> {
        let one = Complex::from(1.0);
        Complex::from(self.kp)
            + Complex::from(self.ki_t) / (one - zi)
            + (one - zi) * ((1.0 - self.a) * self.kd_t) / (one - zi * self.a)
    }

    /// The part of the controller acting on the error, `kp + ki T / (1 - z^-1)` (the
    /// derivative acts on the measurement alone): the reference reaches the output
    /// through `P Kr S`.
    pub fn error_path(&self, f_hz: f64) -> Complex<f64> {
        let zi = Complex::from_polar(1.0, -std::f64::consts::TAU * f_hz * self.ts);
        Complex::from(self.kp) + Complex::from(self.ki_t) / (Complex::from(1.0) - zi)
    }

    /// Loop gain broken at the plant input, `L = K P` (with a rate loop, filters or an
    /// observer: minus the sum over every measured path of its law term times its plant
    /// term).
    pub fn loop_gain(&self, f_hz: f64) -> Complex<f64> {
        if self.law.is_none() {
            // One z^-1 for both: the margins read the loop at thousands of frequencies.
            let zi = self.z_inverse(f_hz);
            return self.controller_at(zi) * self.plant_at(zi);
        }
        let p = self.plant_rows(f_hz);
        let k = self.law_row(f_hz);
        -(0..3).map(|j| k[j] * p[j]).sum::<Complex<f64>>()
    }

    /// Sensitivity `S = 1/(1+L)`.
    pub fn sensitivity(&self, f_hz: f64) -> Complex<f64> {
        (Complex::from(1.0) + self.loop_gain(f_hz)).inv()
    }

    /// Complementary sensitivity `T = L/(1+L)`.
    pub fn complementary(&self, f_hz: f64) -> Complex<f64> {
        let l = self.loop_gain(f_hz);
        l / (Complex::from(1.0) + l)
    }

    /// Extra states of the law beyond the PID: filter states, the gyro angle, the rate
    /// loop's integral and velocity estimate, the observer's filters and command history.
    fn law_states(&self) -> usize {
        let Some(l) = &self.law else { return 0 };
        let chain = |v: &[Biquad]| 2 * v.len();
        usize::from(l.feedback == Feedback::GyroAngle)
            + chain(&l.measurement_filters)
            + l.rate.as_ref().map_or(0, |r| {
                3 + chain(&r.command_filters) + chain(&r.measurement_filters)
            })
            + chain(&l.command_filters)
            + l.observer.as_ref().map_or(0, |o| 4 + o.2)
    }

    /// Response of the drum to a reference step on the sampled loop of a plain PID, over
    /// `duration_s`: the drum angle at each sample as a fraction of the step (1 when it
    /// has followed; motor feedback reaches `1` on the motor, and the drum with it at
    /// rest). The step is the law reading the measurement less the new reference, with
    /// the derivative's previous measurement set to match (the derivative acts on the
    /// measurement, so a reference step gives it no kick). `None` for any other law.
    pub fn reference_step(&self, duration_s: f64) -> Option<Vec<f64>> {
        if self.law.is_some() || !(duration_s.is_finite() && duration_s > 0.0) {
            return None;
        }
        let samples = ((duration_s / self.ts).ceil() as usize).clamp(1, 1_000_000);
        let n = self.ad.nrows();
        // One motor radian, and the drum's share of it.
        let offset = [1.0, 1.0 / self.ic, 0.0];
        let read: f64 = (0..3).map(|j| self.c_scale[j] * offset[j]).sum();
        let mut s = DVector::<f64>::zeros(self.closed_loop_dim());
        s[n + 2] = -read;
        let mut out = Vec::with_capacity(samples);
        for _ in 0..samples {
            let x = s.rows(0, n);
            out.push(self.rows[ROW_DRUM].dot(&x) * self.ic);
            s = self.step_read(&s, &offset);
        }
        Some(out)
    }

    /// One period of the sampled closed loop with zero reference: the state is
    /// `[x, I, d, y_prev, u_{k-1}, ..., u_{k-m-1}, law states]`, linear in itself. The
    /// law is written out here again as difference equations, apart from its code in
    /// `law.rs`, so the two can be checked against each other.
    fn step(&self, s: &DVector<f64>) -> DVector<f64> {
        self.step_read(s, &[0.0; 3])
    }

    /// [`Self::step`] with the law reading the motor angle, the drum angle and the gyro's
    /// rate less `offset` (the encoders' view of a turning base; rad, rad, rad/s).
    fn step_read(&self, s: &DVector<f64>, offset: &[f64; 3]) -> DVector<f64> {
        let n = self.ad.nrows();
        let x = s.rows(0, n);
        let (integ, deriv, y_prev) = (s[n], s[n + 1], s[n + 2]);
        let hist_at = n + 3;
        let mut out = DVector::<f64>::zeros(s.len());
        // Each law state has a fixed slot, handed out in order.
        let slot = std::cell::Cell::new(hist_at + self.whole + 1);
        let alloc = |k: usize| {
            let i = slot.get();
            slot.set(i + k);
            i
        };
        // Transposed direct form II; states at `at`, `at + 1`.
        let biquad = |b: &Biquad, v: f64, at: usize, out: &mut DVector<f64>| {
            let [b0, b1, b2, a1, a2] = b.coefficients();
            let y = b0 * v + s[at];
            out[at] = b1 * v - a1 * y + s[at + 1];
            out[at + 1] = b2 * v - a2 * y;
            y
        };
        let chain = |c: &[Biquad], v: f64, out: &mut DVector<f64>| {
            c.iter().fold(v, |v, b| biquad(b, v, alloc(2), out))
        };
        let rows = [
            self.rows[ROW_MOTOR].dot(&x) - offset[ROW_MOTOR],
            self.rows[ROW_DRUM].dot(&x) - offset[ROW_DRUM],
            self.rows[ROW_GYRO].dot(&x) - offset[ROW_GYRO],
        ];
        let pid = |y: f64, out: &mut DVector<f64>| {
            let integ = integ - self.ki_t * y;
            let deriv = self.a * deriv - (1.0 - self.a) * self.kd_t * (y - y_prev);
            out[n] = integ;
            out[n + 1] = deriv;
            out[n + 2] = y;
            -self.kp * y + integ + deriv
        };
        let u = match &self.law {
            None => {
                let read: f64 = (0..3).map(|j| self.c_scale[j] * offset[j]).sum();
                pid(self.c.dot(&x) - read, &mut out)
            }
            Some(l) => {
                let raw = match l.feedback {
                    Feedback::Motor => rows[ROW_MOTOR],
                    Feedback::Output => l.ic * rows[ROW_DRUM],
                    Feedback::GyroAngle => {
                        // Read before this sample's rate is added to it.
                        let g_at = alloc(1);
                        out[g_at] = s[g_at] + self.ts * rows[ROW_GYRO];
                        l.ic * s[g_at]
                    }
                };
                let y = chain(&l.measurement_filters, raw, &mut out);
                let v = pid(y, &mut out);
                let fb = match &l.rate {
                    None => v,
                    Some(r) => {
                        let (ri_at, last_at, vel_at) = (alloc(1), alloc(1), alloc(1));
                        let w_cmd = chain(&r.command_filters, v, &mut out);
                        let w = match r.source {
                            RateSource::Gyro => rows[ROW_GYRO],
                            RateSource::MotorVelocity => {
                                r.a_v * s[vel_at]
                                    + (1.0 - r.a_v) * (rows[ROW_MOTOR] - s[last_at])
                                        / (self.ts * l.ic)
                            }
                        };
                        out[last_at] = rows[ROW_MOTOR];
                        out[vel_at] = w;
                        let e = w_cmd - chain(&r.measurement_filters, w, &mut out);
                        let ri = s[ri_at] + r.ki_t * e;
                        out[ri_at] = ri;
                        r.kp * e + ri
                    }
                };
                let fc = chain(&l.command_filters, fb, &mut out);
                match &l.observer {
                    None => fc,
                    Some((inv, q, md)) => {
                        let d_inv = chain(std::slice::from_ref(inv), rows[ROW_MOTOR], &mut out);
                        // History [u_{k-md}, ..., u_{k-1}], oldest first.
                        let h_at = alloc(*md);
                        let d_q = chain(std::slice::from_ref(q), s[h_at], &mut out);
                        let u = fc - (d_inv - d_q);
                        for j in 0..md - 1 {
                            out[h_at + j] = s[h_at + j + 1];
                        }
                        out[h_at + md - 1] = u;
                        u
                    }
                }
            }
        };
        // History after the push of u_k: [u_k, u_{k-1}, ..., u_{k-m-1}].
        let mut hist = vec![u * self.scale];
        hist.extend(s.rows(hist_at, self.whole + 1).iter().copied());
        let first = hist[self.whole + 1];
        let second = hist[self.whole];
        let x_next = &self.ad * x + &self.b1 * first + &self.b2 * second;
        out.rows_mut(0, n).copy_from(&x_next);
        for (j, h) in hist.iter().take(self.whole + 1).enumerate() {
            out[hist_at + j] = *h;
        }
        out
    }

    /// The sampled closed loop as a matrix (its columns are the responses to unit states).
    pub fn closed_loop_matrix(&self) -> DMatrix<f64> {
        let dim = self.closed_loop_dim();
        let mut m = DMatrix::<f64>::zeros(dim, dim);
        for j in 0..dim {
            let mut e = DVector::<f64>::zeros(dim);
            e[j] = 1.0;
            m.set_column(j, &self.step(&e));
        }
        m
    }

    /// Size of the sampled closed loop's state.
    fn closed_loop_dim(&self) -> usize {
        self.ad.nrows() + 3 + self.whole + 1 + self.law_states()
    }

    /// Poles of the sampled closed loop. A loop that holds the gyro-integrated angle reads
    /// no encoder angle, so shifting the drum and the motor together (the cable unchanged)
    /// is a drift it neither sees nor corrects: an exact pole at `z = 1` that is no
    /// instability. That one pole, the one nearest to 1, is left out.
    pub fn closed_loop_poles(&self) -> Vec<Complex<f64>> {
        let mut poles: Vec<Complex<f64>> = self
            .closed_loop_matrix()
            .complex_eigenvalues()
            .iter()
            .copied()
            .collect();
        let free_drift = self
            .law
            .as_ref()
            .is_some_and(|l| l.feedback == Feedback::GyroAngle);
        if free_drift {
            if let Some(i) = poles
                .iter()
                .enumerate()
                .min_by(|a, b| (a.1 - 1.0).norm().total_cmp(&(b.1 - 1.0).norm()))
                .map(|(i, _)| i)
            {
                poles.swap_remove(i);
            }
        }
        poles
    }

    /// The sampled closed loop's largest pole when it lies outside the unit circle: how an
    /// unstable loop grows, to name it before the slack or slip it ends in.
    pub fn instability(&self) -> Option<Instability> {
        let fs = 1.0 / self.ts;
        self.closed_loop_poles()
            .into_iter()
            .max_by(|a, b| a.norm().total_cmp(&b.norm()))
            .filter(|z| z.norm() > 1.0)
            .map(|z| Instability {
                pole_magnitude: z.norm(),
                growth_per_s: z.norm().ln() * fs,
                frequency_hz: z.arg().abs() * fs / std::f64::consts::TAU,
            })
    }

    /// Largest closed-loop pole magnitude.
    pub fn spectral_radius(&self) -> f64 {
        self.closed_loop_poles()
            .iter()
            .map(|l| l.norm())
            .fold(0.0, f64::max)
    }

    /// The same loop with every controller gain scaled by `g` (for margin checks).
    pub fn with_gain(&self, g: f64) -> Self {
        if self.law.is_some() {
            return LinearLoop {
                scale: self.scale * g,
                ..self.clone()
            };
        }
        LinearLoop {
            kp: self.kp * g,
            ki_t: self.ki_t * g,
            kd_t: self.kd_t * g,
            ..self.clone()
        }
    }
}

/// A state, input or output of the linear model, with its unit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Signal {
    /// Short name, e.g. `theta_m`.
    pub name: &'static str,
    /// Unit, e.g. `rad`.
    pub unit: &'static str,
    /// What it is.
    pub meaning: &'static str,
}

/// A discrete state-space realisation `x_{k+1} = A x_k + B u_k`, `y_k = C x_k + D u_k`
/// (single input, single output), matrices as rows.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DiscreteRealisation {
    /// States, in the order of the rows of `a`.
    pub states: Vec<Signal>,
    /// State transition, n x n.
    pub a: Vec<Vec<f64>>,
    /// Input matrix, n x 1.
    pub b: Vec<Vec<f64>>,
    /// Output matrix, 1 x n.
    pub c: Vec<Vec<f64>>,
    /// Feedthrough, 1 x 1 (zero: the held command moves no angle at once).
    pub d: Vec<Vec<f64>>,
}

/// The plant of the loop as matrices: the continuous model, its zero-order-hold
/// discretisation at the control period, and the computation delay.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlantModel {
    /// States, in the order of the rows of `a`.
    pub states: Vec<Signal>,
    /// The held command.
    pub input: Signal,
    /// The position loop's measurement.
    pub output: Signal,
    /// Continuous state matrix, n x n, 1/s and mixed units (`dx/dt = A x + B u`).
    pub a: Vec<Vec<f64>>,
    /// Continuous input matrix, n x 1.
    pub b: Vec<Vec<f64>>,
    /// Output matrix, 1 x n.
    pub c: Vec<Vec<f64>>,
    /// Feedthrough, 1 x 1.
    pub d: Vec<Vec<f64>>,
    /// Control period, s (5e-5 at 20 kHz).
    pub sample_period_s: f64,
    /// Zero-order-hold transition `exp(A T)`, n x n.
    pub ad: Vec<Vec<f64>>,
    /// Zero-order-hold input matrix `int_0^T exp(A s) ds B`, n x 1, no delay.
    pub bd: Vec<Vec<f64>>,
    /// Computation delay, control periods (1: the command computed at `t_k` acts from
    /// `t_k+1`).
    pub delay_samples: f64,
    /// Whole periods of it, `m`: the loop carries `z^-m`.
    pub delay_whole_samples: usize,
    /// The fraction beyond them, `f`: `u_{k-m-1}` is held over the first `f T` of a
    /// period and `u_{k-m}` over the rest.
    pub delay_fraction: f64,
    /// The sampled plant with the fractional part of the delay and without the whole
    /// periods: the plain ZOH model when `delay_fraction` is 0, else extended by the state
    /// `u_{k-1}`.
    pub sampled: DiscreteRealisation,
}

fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| m.row(i).iter().copied().collect())
        .collect()
}

fn column(v: &DVector<f64>) -> Vec<Vec<f64>> {
    v.iter().map(|&x| vec![x]).collect()
}

impl LinearLoop {
    /// The states of the plant model, in order.
    pub fn state_signals(&self) -> Vec<Signal> {
        let mut s = vec![
            Signal {
                name: "theta_m",
                unit: "rad",
                meaning: "motor angle",
            },
            Signal {
                name: "omega_m",
                unit: "rad/s",
                meaning: "motor rate",
            },
            Signal {
                name: "theta_o",
                unit: "rad",
                meaning: "drum (output) angle",
            },
            Signal {
                name: "omega_o",
                unit: "rad/s",
                meaning: "drum (output) rate",
            },
        ];
        if self.voltage {
            s.push(Signal {
                name: "i",
                unit: "A",
                meaning: "winding current",
            });
        }
        if s.len() < self.ad.nrows() {
            s.push(Signal {
                name: "gyro_rate",
                unit: "rad/s",
                meaning: "gyro's rate reading (second-order sensor)",
            });
            s.push(Signal {
                name: "gyro_rate_dot",
                unit: "rad/s^2",
                meaning: "derivative of the gyro's rate reading",
            });
        }
        s
    }

    /// The plant as matrices: continuous, sampled with a zero-order hold at the control
    /// period, and with the computation delay's fractional part (see [`PlantModel`]).
    pub fn plant_model(&self) -> PlantModel {
        let (_, bd) = augmented_exp(&self.a_cont, &self.b_cont, self.ts);
        let states = self.state_signals();
        let input = if self.voltage {
            Signal {
                name: "u",
                unit: "V",
                meaning: "winding voltage command, held over the period",
            }
        } else {
            Signal {
                name: "u",
                unit: "A",
                meaning: "current command, held over the period",
            }
        };
        let output = if self.c_scale[1] == 0.0 && self.c_scale[2] == 0.0 {
            Signal {
                name: "y",
                unit: "rad",
                meaning: "measured motor angle (motor encoder)",
            }
        } else if self.c_scale[2] == 0.0 {
            Signal {
                name: "y",
                unit: "rad",
                meaning: "drum encoder angle times ro/ri, in motor radians",
            }
        } else {
            Signal {
                name: "y",
                unit: "rad/s",
                meaning: "gyro rate times ro/ri (the law integrates it)",
            }
        };
        let (a, b, c) = self.sampled_plant();
        let mut sampled_states = states.clone();
        if a.nrows() > states.len() {
            sampled_states.push(Signal {
                name: "u_prev",
                unit: input.unit,
                meaning: "command of the previous period (fractional delay)",
            });
        }
        PlantModel {
            states,
            input,
            output,
            a: rows(&self.a_cont),
            b: column(&self.b_cont),
            c: vec![self.c.iter().copied().collect()],
            d: vec![vec![0.0]],
            sample_period_s: self.ts,
            ad: rows(&self.ad),
            bd: column(&bd),
            delay_samples: self.whole as f64 + self.fraction,
            delay_whole_samples: self.whole,
            delay_fraction: self.fraction,
            sampled: DiscreteRealisation {
                states: sampled_states,
                a: rows(&a),
                b: column(&b),
                c: vec![c.iter().copied().collect()],
                d: vec![vec![0.0]],
            },
        }
    }

    /// `(A, B, C)` of the sampled plant with the fractional delay and without the whole
    /// periods: `P(z) z^m = C (zI - A)^-1 B`.
    fn sampled_plant(&self) -> (DMatrix<f64>, DVector<f64>, DVector<f64>) {
        if self.fraction == 0.0 {
            return (self.ad.clone(), self.b2.clone(), self.c.clone());
        }
        // x_{k+1} = Ad x_k + B1 u_{k-1} + B2 u_k, with u_{k-1} a state of its own.
        let n = self.ad.nrows();
        let mut a = DMatrix::<f64>::zeros(n + 1, n + 1);
        a.view_mut((0, 0), (n, n)).copy_from(&self.ad);
        a.view_mut((0, n), (n, 1)).copy_from(&self.b1);
        let mut b = DVector::<f64>::zeros(n + 1);
        b.rows_mut(0, n).copy_from(&self.b2);
        b[n] = 1.0;
        let mut c = DVector::<f64>::zeros(n + 1);
        c.rows_mut(0, n).copy_from(&self.c);
        (a, b, c)
    }

    /// Zeros of the sampled plant `P(z) z^m` (finite ones, from its zero dynamics: with
    /// `CB != 0` they are the eigenvalues of `(I - B (CB)^-1 C) A` but for the one at 0
    /// that `C` forces). Empty when `CB` vanishes to rounding (a relative degree above one,
    /// which a zero-order hold of this plant does not give).
    pub fn plant_zeros(&self) -> Vec<Complex<f64>> {
        let (a, b, c) = self.sampled_plant();
        let cb = c.dot(&b);
        // NaN fails the comparison too: no zeros then.
        if cb.abs().partial_cmp(&(1e-12 * c.norm() * b.norm())) != Some(std::cmp::Ordering::Greater)
        {
            return Vec::new();
        }
        let n = a.nrows();
        let m = (DMatrix::<f64>::identity(n, n) - &b * c.transpose() / cb) * &a;
        let mut z: Vec<Complex<f64>> = m.complex_eigenvalues().iter().copied().collect();
        if let Some(i) = z
            .iter()
            .enumerate()
            .min_by(|p, q| p.1.norm().total_cmp(&q.1.norm()))
            .map(|(i, _)| i)
        {
            z.swap_remove(i);
        }
        z
    }

    /// The plain PID as `(numerator, denominator)` in powers of `z^-1`, computation delay
    /// left out: `K(z) = (n0 + n1 z^-1 + n2 z^-2) / (1 - (1 + a) z^-1 + a z^-2)`, the
    /// command being `u = -K y` (the derivative acts on the measurement, so the loop
    /// broken at the plant input sees the whole of `K`). `None` for any other law.
    pub fn pid_coefficients(&self) -> Option<([f64; 3], [f64; 3])> {
        if self.law.is_some() {
            return None;
        }
        let (kp, ki_t, a) = (self.kp, self.ki_t, self.a);
        let g = (1.0 - a) * self.kd_t;
        Some((
            [
                kp + ki_t + g,
                -kp * (1.0 + a) - a * ki_t - 2.0 * g,
                kp * a + g,
            ],
            [1.0, -(1.0 + a), a],
        ))
    }

    /// Control period, s.
    pub fn sample_period_s(&self) -> f64 {
        self.ts
    }
}

/// Response of filters in series at `f_hz`.
fn chain_response(chain: &[Biquad], f_hz: f64, fs: f64) -> Complex<f64> {
    chain
        .iter()
        .fold(Complex::from(1.0), |acc, b| acc * b.response(f_hz, fs))
}

fn dot(r: &DVector<f64>, x: &[Complex<f64>]) -> Complex<f64> {
    r.iter().zip(x.iter()).map(|(c, x)| x * *c).sum()
}

/// A resolvent's solution, on the stack or (beyond [`resolvent::MAX_DIM`] states) not.
enum Resolved {
    Stack(resolvent::Solved),
    Heap(DVector<Complex<f64>>),
}

impl Resolved {
    fn as_slice(&self) -> &[Complex<f64>] {
        match self {
            Resolved::Stack(s) => s.as_slice(),
            Resolved::Heap(v) => v.as_slice(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tangent stiffness against physics.md's closed forms for first loading of a virgin
    /// wrap (`(r Tpre/(G mu)) f(v)`, `f(x) = x - 1 - ln x`, on the pulley and on the drum,
    /// plus the free span), solved here by plain bisection: the tension split at the load,
    /// its oracle `Tu = 103.52112 N` at 0.72 N m, and `d(Tu - Tl)/dD`.
    #[test]
    fn tangent_stiffness_matches_the_first_loading_closed_forms() {
        let drive = DriveParams::default();
        let (p, g, mu) = (
            drive.preload_n,
            drive.cable_modulus_n,
            drive.friction_coefficient,
        );
        let lf = 77.6918e-3; // physics.md section 6, figure-eight free span
        let r = drive.pulley_radius_m + drive.drum_radius_m;
        let f = |x: f64| x - 1.0 - x.ln();
        // Elongation of a half at tension t (rising above the preload or falling below).
        let elong = |t: f64| {
            let x = t / p;
            let wraps = r * p * f(x) / (g * mu);
            lf * (t - p) / g + if t >= p { wraps } else { -wraps }
        };
        let d_elong = |t: f64| lf / g + r * (1.0 - p / t).abs() / (g * mu);
        let tension_for = |e: f64| {
            let (mut lo, mut hi) = (1e-6 * p, 3.0 * p);
            for _ in 0..200 {
                let m = 0.5 * (lo + hi);
                if elong(m) < e {
                    lo = m;
                } else {
                    hi = m;
                }
            }
            0.5 * (lo + hi)
        };
        let split = |m_nm: f64| {
            let (mut lo, mut hi) = (0.0, 1e-3);
            for _ in 0..200 {
                let d = 0.5 * (lo + hi);
                let torque = drive.drum_radius_m * (tension_for(d) - tension_for(-d));
                if torque < m_nm {
                    lo = d;
                } else {
                    hi = d;
                }
            }
            let d = 0.5 * (lo + hi);
            (tension_for(d), tension_for(-d))
        };
        let (tu, _) = split(0.72);
        assert!((tu - 103.52112).abs() < 1e-4, "oracle Tu {tu}");
        for m_nm in [0.05, 0.3, 0.72, 1.3] {
            let (tu, tl) = split(m_nm);
            let want = 0.5 * (1.0 / d_elong(tu) + 1.0 / d_elong(tl));
            let got = tangent_half_stiffness(&drive, m_nm).expect("carried");
            assert!(
                (got / want - 1.0).abs() < 1e-4,
                "{m_nm} N m: {got} N/m, closed forms {want} N/m"
            );
            let neg = tangent_half_stiffness(&drive, -m_nm).expect("carried");
            assert!((neg / got - 1.0).abs() < 1e-6, "{neg} vs {got}");
        }
        let free = ClosedLoopParams::half_stiffness_n_per_m(&drive);
        assert_eq!(tangent_half_stiffness(&drive, 0.0), Ok(free));
        let tiny = tangent_half_stiffness(&drive, 1e-6).expect("carried");
        assert!((tiny / free - 1.0).abs() < 1e-3, "{tiny} vs {free}");
        let mut last = free;
        for m_nm in [0.1, 0.5, 1.0, 2.0, 4.0] {
            let k = tangent_half_stiffness(&drive, m_nm).expect("carried");
            assert!(k < last, "{m_nm} N m: {k} not below {last}");
            last = k;
        }
        // Past slack: the lower span would have to push.
        let e = tangent_half_stiffness(&drive, 25.0).expect_err("not carried");
        assert!(e.contains("cannot carry 25 N m"), "{e}");
        // A load beyond any double's preload reads as numbers still.
        let e = tangent_half_stiffness(&drive, 1e308).expect_err("not carried");
        assert!(
            e.contains("cannot carry 1e308 N m") && !e.contains("inf"),
            "{e}"
        );
    }

    /// The bench loop of `scenarios/eots_tracking.toml`, read without the scenario layer.
    fn bench() -> (ClosedLoopParams, DriveParams) {
        let t: toml::Table =
            toml::from_str(include_str!("../../scenarios/eots_tracking.toml")).unwrap();
        (
            t["closed_loop"].clone().try_into().unwrap(),
            t["drive"].clone().try_into().unwrap(),
        )
    }

    /// A pure inertia `1/(J s^2)` under a zero-order hold has the closed form
    /// `P(z) = T^2 (z + 1) / (2 J (z - 1)^2)`; a whole period of delay multiplies it by
    /// `z^-1`, and half a period splits the input matrix into the hand-integrated
    /// `B1 = [h^2 + h^2/2, h]/J` and `B2 = [h^2/2, h]/J` with `h = T/2`.
    #[test]
    fn zoh_of_an_inertia_matches_the_closed_form() {
        let j = 2.0;
        let ts = 1e-3;
        let mut a = DMatrix::<f64>::zeros(2, 2);
        a[(0, 1)] = 1.0;
        let b = DVector::from_vec(vec![0.0, 1.0 / j]);
        let (ad, bd) = augmented_exp(&a, &b, ts);
        assert!((ad[(0, 1)] - ts).abs() < 1e-15);
        assert!((bd[0] - ts * ts / (2.0 * j)).abs() < 1e-18);
        assert!((bd[1] - ts / j).abs() < 1e-15);
        let lp = LinearLoop {
            a_cont: a.clone(),
            b_cont: b.clone(),
            voltage: false,
            ad_stack: StateMatrix::of(&ad),
            ad: ad.clone(),
            b1: DVector::zeros(2),
            b2: bd.clone(),
            c: DVector::from_vec(vec![1.0, 0.0]),
            rows: [
                DVector::from_vec(vec![1.0, 0.0]),
                DVector::zeros(2),
                DVector::zeros(2),
            ],
            c_scale: [1.0, 0.0, 0.0],
            base_rate: DVector::zeros(2),
            ic: 1.0,
            whole: 0,
            fraction: 0.0,
            ts,
            kp: 0.0,
            ki_t: 0.0,
            kd_t: 0.0,
            a: 0.0,
            law: None,
            scale: 1.0,
            drum_torque: DVector::zeros(2),
        };
        for f in [1.0, 17.0, 230.0] {
            let z = Complex::from_polar(1.0, std::f64::consts::TAU * f * ts);
            let one = Complex::from(1.0);
            let exact = (z + one) * (ts * ts / (2.0 * j)) / ((z - one) * (z - one));
            assert!((lp.plant(f) - exact).norm() < 1e-9 * exact.norm(), "{f} Hz");
            // One whole period of delay multiplies by z^-1.
            let delayed = LinearLoop {
                whole: 1,
                ..lp.clone()
            };
            assert!((delayed.plant(f) - exact / z).norm() < 1e-9 * exact.norm());
        }
        // Half a period of delay: u_{k-1} over [0, T/2), u_k over [T/2, T).
        let (phi_h, gam_h) = augmented_exp(&a, &b, ts / 2.0);
        let half = LinearLoop {
            b1: &phi_h * &gam_h,
            b2: gam_h.clone(),
            ..lp.clone()
        };
        // By hand: B2 = [(T/2)^2/2, T/2]/J, B1 = [T/2*T/2 + (T/2)^2/2, T/2]/J.
        let h = ts / 2.0;
        assert!((half.b2[0] - h * h / (2.0 * j)).abs() < 1e-18);
        assert!((half.b1[0] - (h * h + h * h / 2.0) / j).abs() < 1e-18);
        assert!((half.b1[1] - h / j).abs() < 1e-15);
    }

    /// The gain margin is where the closed loop loses stability: scaling every gain by
    /// the margin puts a pole on the unit circle (eigenvalues of the assembled sampled
    /// system, an independent route from the frequency response).
    #[test]
    fn gain_margin_agrees_with_closed_loop_poles() {
        let (mut p, drive) = bench();
        p.controller.computation_delay_samples = 1.0;
        let lp = LinearLoop::new(&p, &drive);
        let m = lp.margins(3000);
        assert!(m.stable, "{m:?}");
        let gm = m.gain_margin_db.expect("a phase crossover");
        let g = 10f64.powf(gm / 20.0);
        let below = lp.with_gain(g * 0.995).spectral_radius();
        let above = lp.with_gain(g * 1.005).spectral_radius();
        assert!(below < 1.0 && above > 1.0, "{below} {above} at {gm} dB");
        // The phase margin's crossover has |L| = 1 and the stated angle to -1.
        let f = m.crossover_hz.unwrap();
        let l = lp.loop_gain(f);
        assert!((l.norm() - 1.0).abs() < 1e-9);
        let pm = m.phase_margin_deg.unwrap();
        assert!(
            ((Complex::from(-1.0) - l).norm() - 2.0 * (pm.to_radians() / 2.0).sin()).abs() < 1e-6
        );
    }
}
