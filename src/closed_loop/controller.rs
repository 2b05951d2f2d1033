//! Discrete-time controller: encoders, PID with filtered derivative and anti-windup,
//! feedforward, and the backlash compensator (a separate copy of the cable model).
//!
//! Difference equations at sample `k` (period `T`, error `e_k = r_k - y_k` in motor rad):
//!
//! ```text
//! d_k = a d_{k-1} - (1 - a) kd (y_k - y_{k-1}) / T      a = exp(-2 pi f_d T), y_{-1} = y_0
//! I'  = I_{k-1} + ki T e_k
//! v   = kp e_k + I' + d_k + u_ff
//! u_k = clamp(v, -limit, limit)
//! I_k = I_{k-1} if v was clipped and e_k pushes further into the limit, else I'
//! ```
//! `u_k` is applied after the computation delay ([`CommandDelay`]) and held (zero-order hold).

use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use super::params::{ControllerParams, SensorParams};
use crate::physics::{CableDrive, DriveParams, HysteresisModel};

/// PID state.
#[derive(Clone, Debug)]
pub struct Pid {
    kp: f64,
    ki_t: f64,
    kd_t: f64,
    a: f64,
    limit: f64,
    integral: f64,
    deriv: f64,
    last_y: Option<f64>,
}

impl Pid {
    /// From the controller parameters and the amplifier limit (A or V).
    pub fn new(p: &ControllerParams, limit: f64) -> Self {
        let t = 1.0 / p.sample_rate_hz;
        Pid {
            kp: p.kp,
            ki_t: p.ki * t,
            kd_t: p.kd / t,
            a: (-std::f64::consts::TAU * p.derivative_filter_hz * t).exp(),
            limit,
            integral: 0.0,
            deriv: 0.0,
            last_y: None,
        }
    }

    /// One sample: reference `r` and measurement `y` (motor rad), feedforward `u_ff`.
    /// Returns the held command.
    pub fn update(&mut self, r: f64, y: f64, u_ff: f64) -> f64 {
        let e = r - y;
        let dy = y - self.last_y.unwrap_or(y);
        self.last_y = Some(y);
        self.deriv = self.a * self.deriv - (1.0 - self.a) * self.kd_t * dy;
        let candidate = self.integral + self.ki_t * e;
        let v = self.kp * e + candidate + self.deriv + u_ff;
        let u = v.clamp(-self.limit, self.limit);
        let winding_up = u != v && e * (v - u) > 0.0;
        if !winding_up {
            self.integral = candidate;
        }
        u
    }
}

/// An encoder: quantisation to whole counts and white noise.
#[derive(Clone, Debug)]
pub struct Encoder {
    rad_per_count: Option<f64>,
    noise: Option<Normal<f64>>,
}

impl Encoder {
    /// From counts per revolution (`None` = continuous) and noise standard deviation, rad.
    pub fn new(counts_per_rev: Option<u64>, noise_rad: f64) -> Self {
        Encoder {
            rad_per_count: counts_per_rev.map(|c| std::f64::consts::TAU / c as f64),
            noise: if noise_rad > 0.0 {
                Normal::new(0.0, noise_rad).ok()
            } else {
                None
            },
        }
    }

    /// Reading of angle `theta` (rad).
    #[inline]
    pub fn read(&self, theta: f64, rng: &mut StdRng) -> f64 {
        let noisy = match &self.noise {
            Some(n) => theta + n.sample(rng),
            None => theta,
        };
        match self.rad_per_count {
            Some(q) => round(noisy / q) * q,
            None => noisy,
        }
    }
}

/// `x.round()` (half away from zero), bit for bit, without the library call that
/// `f64::round` compiles to on baseline x86-64, which has no rounding instruction: the
/// encoders and the gyro quantise a reading every control period.
#[inline(always)]
pub(crate) fn round(x: f64) -> f64 {
    // Adding 2^52 leaves no fraction bits, so the sum rounds `|x|` to the nearest
    // integer (ties to even); a tie that went down is moved up. `|x| - r` is exact, the
    // two being within a half of each other.
    const NO_FRACTION: f64 = 4_503_599_627_370_496.0;
    let a = x.abs();
    if a >= NO_FRACTION || a.is_nan() {
        return x;
    }
    let r = (a + NO_FRACTION) - NO_FRACTION;
    let r = if a - r == 0.5 { r + 1.0 } else { r };
    r.copysign(x)
}

/// Both encoders and their random source.
#[derive(Clone, Debug)]
pub struct Sensors {
    /// Motor encoder.
    pub motor: Encoder,
    /// Output encoder.
    pub output: Encoder,
    /// Noise generator (seeded).
    pub rng: StdRng,
}

impl Sensors {
    /// From the scenario.
    pub fn new(p: &SensorParams) -> Self {
        let q = |c: u64| if p.quantize { Some(c) } else { None };
        Sensors {
            motor: Encoder::new(q(p.motor_counts_per_rev), p.motor_noise_rad),
            output: Encoder::new(q(p.output_counts_per_rev), p.output_noise_rad),
            rng: StdRng::seed_from_u64(p.seed),
        }
    }
}

/// Predicts the transmission error from the expected transmitted torque, with its own
/// cable model and memory (parameters may differ from the plant's).
#[derive(Clone, Debug)]
pub struct Compensator {
    drive: CableDrive,
    last_error_rad: f64,
    last_torque_nm: f64,
    faults: u64,
}

/// Torque change below which the last prediction is kept, N m. At the bench's compliance
/// (about 0.3 mrad per N m) it moves the prediction by less than 1e-9 rad, and it spares
/// the solve in the many periods where only the small inertia term changes.
const TORQUE_DEADBAND_NM: f64 = 1e-6;

impl Compensator {
    /// A virgin compensator drive.
    pub fn new(params: DriveParams, model: HysteresisModel) -> Self {
        Compensator {
            drive: CableDrive::new(params, model),
            last_error_rad: 0.0,
            last_torque_nm: 0.0,
            faults: 0,
        }
    }

    /// Predicted transmission error `e = theta_out - theta_in/ic` (rad) under transmitted
    /// torque `torque_nm`; the memory is committed. If the model cannot carry the torque
    /// (its own slack or gross slip) the last prediction is held and counted.
    pub fn predict(&mut self, torque_nm: f64) -> f64 {
        if (torque_nm - self.last_torque_nm).abs() < TORQUE_DEADBAND_NM {
            return self.last_error_rad;
        }
        match self.drive.apply_torque(torque_nm) {
            Ok(s) => {
                self.last_error_rad = s.transmission_error_rad;
                self.last_torque_nm = torque_nm;
            }
            Err(_) => self.faults += 1,
        }
        self.last_error_rad
    }

    /// Samples at which the prediction was held because the model faulted.
    pub fn faults(&self) -> u64 {
        self.faults
    }
}

/// Expected brake torque seen by the cable, reversing gradually with the reference.
///
/// After each reversal, and after each start from rest, the cable has to pull the brake
/// free, so the prediction first climbs to the breakaway torque and then settles to the
/// sliding torque: the compensator copy then remembers the breakaway peak as the real cable
/// does (its slip zones reach as far as the peak tension drove them).
///
/// When the reference stands still the prediction falls to zero at the same rate. A stuck
/// brake holds whatever the cable transmits, so nothing in the reference fixes a standing
/// torque; predicting the sliding torque there would shift the motor reference by the
/// cable's stretch under that torque and park the output off target by as much. Zero is
/// the one standing torque that is consistent with the output resting on the reference.
#[derive(Clone, Debug)]
pub struct BrakePredictor {
    brake_nm: f64,
    breakaway_nm: f64,
    step_nm: f64,
    dir: f64,
    value_nm: f64,
    broke_free: bool,
}

impl BrakePredictor {
    /// Sliding torque `brake_nm` and breakaway torque `breakaway_nm` (N m), full reversal
    /// over `transition_s` at sample period `period_s`.
    pub fn new(brake_nm: f64, breakaway_nm: f64, transition_s: f64, period_s: f64) -> Self {
        let breakaway_nm = breakaway_nm.max(brake_nm);
        let step_nm = if transition_s > 0.0 {
            2.0 * breakaway_nm * period_s / transition_s
        } else {
            f64::INFINITY
        };
        BrakePredictor {
            brake_nm,
            breakaway_nm,
            step_nm,
            dir: 0.0,
            value_nm: 0.0,
            broke_free: false,
        }
    }

    /// Update with the reference's direction of motion (`delta` = rate or change of the
    /// reference, rad/s or rad; zero = standing still). Returns the transmitted torque the
    /// brake demands, N m (`+brake` when moving in `+`, falling to 0 at standstill).
    pub fn update(&mut self, delta: f64) -> f64 {
        if delta == 0.0 {
            // The next motion, whichever way, starts from a stuck brake again.
            self.dir = 0.0;
            self.broke_free = false;
        } else if delta.signum() != self.dir {
            self.dir = delta.signum();
            self.broke_free = false;
        }
        let level = if self.broke_free {
            self.brake_nm
        } else {
            self.breakaway_nm
        };
        let target = level * self.dir;
        self.value_nm += (target - self.value_nm).clamp(-self.step_nm, self.step_nm);
        if self.value_nm == target {
            self.broke_free = true;
        }
        self.value_nm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_is_the_library_round_bit_for_bit() {
        use rand::{Rng, SeedableRng};
        let same = |x: f64| {
            assert_eq!(round(x).to_bits(), x.round().to_bits(), "{x:e}");
            assert_eq!(round(-x).to_bits(), (-x).round().to_bits(), "{:e}", -x);
        };
        let two52 = 4_503_599_627_370_496.0_f64;
        for x in [
            0.0,
            f64::MIN_POSITIVE,
            1e-310,
            0.49999999999999994,
            0.5,
            0.5000000000000001,
            1.5,
            2.5,
            two52 - 0.5,
            two52 - 1.5,
            two52,
            two52 + 1.0,
            2.0 * two52 + 2.0,
            f64::MAX,
            f64::INFINITY,
        ] {
            same(x);
        }
        assert!(round(f64::NAN).is_nan());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200_000 {
            let x = rng.gen_range(-1.0..1.0) * 10f64.powi(rng.gen_range(-3..17));
            same(x);
            // Ties and their neighbours.
            let tie = x.trunc() + 0.5;
            same(tie);
            same(tie.next_up());
            same(tie.next_down());
        }
    }

    #[test]
    fn brake_prediction_peaks_at_breakaway_then_slides() {
        // 0.1 N m per sample.
        let mut b = BrakePredictor::new(0.5, 0.6, 1.2, 0.1);
        let seq: Vec<f64> = (0..9).map(|_| b.update(1.0)).collect();
        let expect = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.5, 0.5, 0.5];
        for (a, e) in seq.iter().zip(expect) {
            assert!((a - e).abs() < 1e-12, "{seq:?}");
        }
        // Reversing climbs to -breakaway, then slides.
        let back: Vec<f64> = (0..13).map(|_| b.update(-2.0)).collect();
        assert!((back[10] + 0.6).abs() < 1e-12, "{back:?}");
        assert!((back[12] + 0.5).abs() < 1e-12, "{back:?}");
    }

    #[test]
    fn brake_prediction_falls_to_zero_at_standstill_and_breaks_away_again() {
        let mut b = BrakePredictor::new(0.5, 0.6, 1.2, 0.1);
        for _ in 0..9 {
            b.update(1.0);
        }
        // The reference stops: down by 0.1 N m per sample, then held at zero.
        let rest: Vec<f64> = (0..7).map(|_| b.update(0.0)).collect();
        let expect = [0.4, 0.3, 0.2, 0.1, 0.0, 0.0, 0.0];
        for (a, e) in rest.iter().zip(expect) {
            assert!((a - e).abs() < 1e-12, "{rest:?}");
        }
        // Moving on in the same direction needs the breakaway torque again.
        let again: Vec<f64> = (0..8).map(|_| b.update(1.0)).collect();
        assert!((again[5] - 0.6).abs() < 1e-12, "{again:?}");
        assert!((again[7] - 0.5).abs() < 1e-12, "{again:?}");
    }

    #[test]
    fn pid_freezes_integral_in_saturation() {
        let p = ControllerParams {
            sample_rate_hz: 1000.0,
            kp: 1.0,
            ki: 100.0,
            kd: 0.0,
            ..ControllerParams::default()
        };
        let mut pid = Pid::new(&p, 2.0);
        // Error 10: saturated at +2 from the start; the integral must not grow.
        for _ in 0..100 {
            assert_eq!(pid.update(10.0, 0.0, 0.0), 2.0);
        }
        // Error back to zero: unsaturated output is the (small) integral only.
        let u = pid.update(0.0, 0.0, 0.0);
        assert!(u.abs() < 1e-12, "{u}");
        // Unsaturated: integral accumulates ki*T*e per sample.
        let mut pid = Pid::new(&p, 1e9);
        pid.update(1.0, 0.0, 0.0);
        let u = pid.update(1.0, 0.0, 0.0);
        assert!((u - (1.0 + 2.0 * 0.1)).abs() < 1e-12, "{u}");
    }
}

/// The commands the plant holds over one control period under a computation delay of
/// `m + f` periods (`m` whole, `0 <= f < 1`): `u_{k-m-1}` over the first `f` of the period,
/// then `u_{k-m}` (commands before the start are zero).
#[derive(Clone, Debug)]
pub struct CommandDelay {
    /// `[u_{k-m-1}, ..., u_k]` after the push of `u_k`.
    queue: std::collections::VecDeque<f64>,
    fraction: f64,
}

/// Held commands of one period: `first` over `[t_k, t_k + split*T)`, `second` over the rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeldCommands {
    /// Command held first (A or V).
    pub first: f64,
    /// Command held from the split on (A or V).
    pub second: f64,
    /// Fraction of the period the first command holds, 0 to 1 (0: `second` holds all of it).
    pub split: f64,
}

impl CommandDelay {
    /// Delay in control periods (0 to a few).
    pub fn new(delay_samples: f64) -> Self {
        let whole = delay_samples.max(0.0).floor();
        CommandDelay {
            queue: std::iter::repeat_n(0.0, whole as usize + 2).collect(),
            fraction: delay_samples - whole,
        }
    }

    /// Take the command computed at this sample; return what the plant holds until the next.
    pub fn push(&mut self, u: f64) -> HeldCommands {
        self.queue.pop_front();
        self.queue.push_back(u);
        HeldCommands {
            first: self.queue[0],
            second: self.queue[1],
            split: self.fraction,
        }
    }
}

#[cfg(test)]
mod delay_tests {
    use super::*;

    #[test]
    fn whole_and_fractional_delays_hold_the_right_commands() {
        let mut none = CommandDelay::new(0.0);
        let h = none.push(3.0);
        assert_eq!((h.second, h.split), (3.0, 0.0));
        let mut one = CommandDelay::new(1.0);
        assert_eq!(one.push(1.0).second, 0.0);
        assert_eq!(one.push(2.0).second, 1.0);
        let mut half = CommandDelay::new(0.5);
        let h = half.push(1.0);
        assert_eq!((h.first, h.second, h.split), (0.0, 1.0, 0.5));
        let h = half.push(2.0);
        assert_eq!((h.first, h.second), (1.0, 2.0));
        let mut late = CommandDelay::new(1.25);
        late.push(1.0);
        late.push(2.0);
        let h = late.push(3.0);
        assert_eq!((h.first, h.second, h.split), (1.0, 2.0, 0.25));
    }
}
