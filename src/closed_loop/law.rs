//! The controller's structure around its PID: filters on any path, an optional inner rate
//! loop on the gyro or a motor-velocity estimate, and an optional disturbance observer,
//! plus the gyro as the controller reads it.
//!
//! At sample `k`, with `y` the position measurement (motor rad; `ic` times the drum angle
//! or the gyro angle) and `F_*` the filter chains:
//!
//! ```text
//! v     = PID(r_m, F_meas(y))                       position loop
//! fb    = v                                         without a rate loop
//! fb    = R(F_rc(v + r') - F_rm(w))                 with one: R = kp + ki T/(1 - z^-1)
//! u     = clamp(F_cmd(fb) + u_ff - d_hat)           d_hat: disturbance observer, A
//! d_hat = Q (J/Kt) s^2 theta_m - Q u_{k-m}          Q: 2nd-order low-pass, m = 1 + ceil(delay)
//! ```
//! With none of these parts the law is the PID alone, evaluated exactly as before. With
//! them, the PID holds its integral while its own output (before the filters) is clipped,
//! the rate PI while the final command is clipped; the command is clipped once more after
//! the filters, feedforward and observer.

use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use super::controller::Pid;
use super::filters::{FilterChain, FilterSpec};
use super::params::{ClosedLoopParams, GyroParams, RateSource};

/// The gyro as the controller reads it: samples of the filtered inertial rate (a plant
/// state) with bias, white noise and quantisation, taken every `decimation` control
/// samples and held in between.
#[derive(Clone, Debug)]
pub struct GyroReader {
    decimation: u32,
    count: u32,
    held: f64,
    bias: f64,
    quantum: f64,
    noise: Option<Normal<f64>>,
    rng: StdRng,
}

impl GyroReader {
    /// From the gyro's parameters at control rate `fs_hz`; `None` when its rate does not
    /// divide the control rate (the scenario check refuses that first).
    pub fn new(p: &GyroParams, fs_hz: f64) -> Option<Self> {
        let decimation = p.decimation(fs_hz)?;
        let fg = fs_hz / f64::from(decimation);
        let sigma = p.noise_density_rad_s_per_sqrt_hz * (0.5 * fg).sqrt();
        Some(GyroReader {
            decimation,
            count: 0,
            held: 0.0,
            bias: p.bias_rad_s,
            quantum: p.quantization_rad_s,
            noise: (sigma > 0.0)
                .then(|| Normal::new(0.0, sigma).ok())
                .flatten(),
            rng: StdRng::seed_from_u64(p.seed),
        })
    }

    /// Reading at this control sample, given the gyro's filtered rate `g` (rad/s).
    pub fn read(&mut self, g: f64) -> f64 {
        if self.count == 0 {
            let mut v = g + self.bias;
            if let Some(n) = &self.noise {
                v += n.sample(&mut self.rng);
            }
            if self.quantum > 0.0 {
                v = super::controller::round(v / self.quantum) * self.quantum;
            }
            self.held = v;
        }
        self.count = (self.count + 1) % self.decimation;
        self.held
    }
}

/// What the law reads at one sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LawInputs {
    /// Position reference, motor rad (`ic (r - e_pred)` or `ic r`).
    pub reference: f64,
    /// Position measurement, motor rad (motor encoder, or `ic` times the drum encoder or
    /// the gyro angle).
    pub measurement: f64,
    /// Reference rate fed forward to the rate loop, output rad/s.
    pub rate_feedforward: f64,
    /// Gyro reading, output rad/s (0 without a gyro).
    pub gyro: f64,
    /// Motor encoder reading, rad (for the velocity estimate and the observer).
    pub motor_encoder: f64,
    /// Feedforward command added after the filters (A or V).
    pub feedforward: f64,
}

/// Inner rate PI with its measurement.
#[derive(Clone, Debug)]
struct RateLoop {
    kp: f64,
    ki_t: f64,
    integral: f64,
    source: RateSource,
    velocity: Option<VelocityEstimate>,
    command_filters: FilterChain,
    measurement_filters: FilterChain,
}

/// Backward difference of the motor encoder over `ic`, low-passed: output rad/s relative
/// to the base.
#[derive(Clone, Debug)]
struct VelocityEstimate {
    a: f64,
    inv_t_ic: f64,
    last: Option<f64>,
    value: f64,
}

impl VelocityEstimate {
    fn update(&mut self, theta_m: f64) -> f64 {
        let d = theta_m - self.last.unwrap_or(theta_m);
        self.last = Some(theta_m);
        self.value = self.a * self.value + (1.0 - self.a) * d * self.inv_t_ic;
        self.value
    }
}

/// Motor-side disturbance observer.
#[derive(Clone, Debug)]
struct Observer {
    /// `Q (J/Kt) s^2` on the motor encoder.
    inverse: FilterChain,
    /// `Q` on the applied command.
    q: FilterChain,
    /// Commands of the last `m` samples, oldest first.
    history: std::collections::VecDeque<f64>,
}

/// The sampled control law of one run.
#[derive(Clone, Debug)]
pub struct ControlLaw {
    pid: Pid,
    plain: bool,
    limit: f64,
    measurement_filters: FilterChain,
    rate: Option<RateLoop>,
    command_filters: FilterChain,
    observer: Option<Observer>,
}

/// The observer's two filters, `(Q (J/Kt) s^2, Q)`, as continuous biquads.
pub fn observer_filters(p: &ClosedLoopParams, ic: f64) -> Option<(FilterSpec, FilterSpec)> {
    let d = p.controller.disturbance_observer.as_ref()?;
    let w = std::f64::consts::TAU * d.bandwidth_hz;
    let j = d
        .inertia_kg_m2
        .unwrap_or(p.motor.inertia_kg_m2 + p.output.inertia_kg_m2 / (ic * ic));
    let den = [w * w, 2.0 * d.damping * w, 1.0];
    let gain = j / p.motor.torque_constant_nm_per_a * w * w;
    Some((
        FilterSpec::Biquad {
            b: [0.0, 0.0, gain],
            a: den,
            prewarp_hz: Some(d.bandwidth_hz),
        },
        FilterSpec::Biquad {
            b: [w * w, 0.0, 0.0],
            a: den,
            prewarp_hz: Some(d.bandwidth_hz),
        },
    ))
}

/// Samples between a command and the observer's use of it: the command that drove the
/// motor over the last period, `u_{k-1-ceil(delay)}`.
pub fn observer_delay(p: &ClosedLoopParams) -> usize {
    p.controller.computation_delay_samples.ceil().max(0.0) as usize + 1
}

impl ControlLaw {
    /// The law of `p` for a drive of ratio `ic`, with output limit `limit` (A or V;
    /// `f64::INFINITY` for none).
    pub fn new(p: &ClosedLoopParams, ic: f64, limit: f64) -> Self {
        let c = &p.controller;
        let fs = c.sample_rate_hz;
        let ts = 1.0 / fs;
        let rate = c.rate_loop.as_ref().map(|r| RateLoop {
            kp: r.kp,
            ki_t: r.ki * ts,
            integral: 0.0,
            source: r.measurement,
            velocity: (r.measurement == RateSource::MotorVelocity).then(|| VelocityEstimate {
                a: (-std::f64::consts::TAU * r.velocity_filter_hz * ts).exp(),
                inv_t_ic: fs / ic,
                last: None,
                value: 0.0,
            }),
            command_filters: FilterChain::new(&c.rate_command_filters, fs),
            measurement_filters: FilterChain::new(&c.rate_measurement_filters, fs),
        });
        let observer = observer_filters(p, ic).map(|(inv, q)| Observer {
            inverse: FilterChain::new(&[inv], fs),
            q: FilterChain::new(&[q], fs),
            history: std::iter::repeat_n(0.0, observer_delay(p)).collect(),
        });
        ControlLaw {
            // With a rate loop the PID's output is a rate command, which has no limit.
            pid: Pid::new(c, if rate.is_some() { f64::INFINITY } else { limit }),
            plain: c.is_plain_pid(),
            limit,
            measurement_filters: FilterChain::new(&c.measurement_filters, fs),
            rate,
            command_filters: FilterChain::new(&c.command_filters, fs),
            observer,
        }
    }

    /// One sample: the command to hold (A or V), clipped to the limit.
    pub fn update(&mut self, i: &LawInputs) -> f64 {
        if self.plain {
            return self.pid.update(i.reference, i.measurement, i.feedforward);
        }
        let y = self.measurement_filters.step(i.measurement);
        let v = self.pid.update(i.reference, y, 0.0);
        let mut rate_error = None;
        let fb = match self.rate.as_mut() {
            None => v,
            Some(r) => {
                let w_cmd = r.command_filters.step(v + i.rate_feedforward);
                let w = match (r.source, r.velocity.as_mut()) {
                    (RateSource::MotorVelocity, Some(est)) => est.update(i.motor_encoder),
                    _ => i.gyro,
                };
                let e = w_cmd - r.measurement_filters.step(w);
                let candidate = r.integral + r.ki_t * e;
                rate_error = Some((e, candidate));
                r.kp * e + candidate
            }
        };
        let d_hat = self.observer.as_mut().map_or(0.0, |o| {
            let past = o.history.front().copied().unwrap_or(0.0);
            o.inverse.step(i.motor_encoder) - o.q.step(past)
        });
        let v_total = self.command_filters.step(fb) + i.feedforward - d_hat;
        let u = v_total.clamp(-self.limit, self.limit);
        if let (Some(r), Some((e, candidate))) = (self.rate.as_mut(), rate_error) {
            // Anti-windup: hold the integral while the command is clipped and the error
            // pushes further into the limit.
            if !(u != v_total && e * (v_total - u) > 0.0) {
                r.integral = candidate;
            }
        }
        if let Some(o) = self.observer.as_mut() {
            o.history.pop_front();
            o.history.push_back(u);
        }
        u
    }
}
