//! The exact linear reference as records to export and to draw: per operating point of
//! the cable (free span, tangent at the operating load) the plant's matrices, the discrete
//! controller's coefficients, the loop gain on the grid the margins are read on, every
//! crossing, the closed loop's poles and the loop's zeros, and the reference step with
//! its rise, settling and overshoot. Another tool (python-control, MATLAB) rebuilds the
//! loop from these numbers alone; `docs/linear-model.md` gives the format.

use nalgebra::Complex;
use serde::Serialize;

use super::linear::{LinearLoop, PlantModel};
use super::margins::{margin_grid, Margins};
use super::verdict::{operating_loops, OperatingLoop, MARGIN_POINTS};
use crate::closed_loop::sim::ClosedLoopSetup;

/// Settling band of the reference step, as a fraction of the step (2 %, the usual one).
pub const STEP_SETTLE_FRACTION: f64 = 0.02;
/// Longest reference step computed, s.
pub const STEP_MAX_S: f64 = 5.0;

/// A pole or zero in the z-plane, with its continuous-time equivalent `s = ln(z) / T`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ZPoint {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
    /// `|z|` (below 1 inside the unit circle).
    pub magnitude: f64,
    /// Natural frequency of `s = ln(z) / T`, Hz; `None` at `z = 0` (a pure delay).
    pub natural_hz: Option<f64>,
    /// Damped frequency `|Im s| / 2 pi`, Hz (0 for a positive real point).
    pub frequency_hz: Option<f64>,
    /// Damping ratio `-Re s / |s|` (1 for a positive real point inside the circle).
    pub damping: Option<f64>,
}

impl ZPoint {
    fn new(z: Complex<f64>, ts: f64) -> Self {
        let m = z.norm();
        let (natural_hz, frequency_hz, damping) = if m > 0.0 && m.is_finite() {
            let s = z.ln() / ts;
            let wn = s.norm();
            (
                Some(wn / std::f64::consts::TAU),
                Some(s.im.abs() / std::f64::consts::TAU),
                (wn > 0.0).then(|| -s.re / wn),
            )
        } else {
            (None, None, None)
        };
        ZPoint {
            re: z.re,
            im: z.im,
            magnitude: m,
            natural_hz,
            frequency_hz,
            damping,
        }
    }
}

/// The reference step of the sampled loop and its figures (rise, settling, overshoot).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StepResponse {
    /// Control period, s: sample `k` is at `k T`.
    pub sample_period_s: f64,
    /// Drum angle at each sample as a fraction of the step (1 when it has followed).
    pub output: Vec<f64>,
    /// Settling band, fraction of the step.
    pub settle_band: f64,
    /// Time from 10 % to 90 % of the step, s; `None` when it never reaches 90 %.
    pub rise_time_s: Option<f64>,
    /// Time after which the output stays within the band, s; `None` when it did not
    /// settle within the computed window (`settled` false).
    pub settling_time_s: Option<f64>,
    /// Whether the output stays within the band from some sample to the window's end.
    pub settled: bool,
    /// Largest output, fraction of the step.
    pub peak: f64,
    /// When it occurs, s.
    pub peak_time_s: f64,
    /// Overshoot above the step, percent (0 when the output never exceeds it).
    pub overshoot_percent: f64,
}

impl StepResponse {
    /// Figures of the sampled output `y` (fraction of the step) at period `ts`.
    pub fn from_samples(y: Vec<f64>, ts: f64) -> Self {
        let t = |k: usize| k as f64 * ts;
        // Linear interpolation between samples for the level crossings.
        let first_at = |level: f64| {
            y.iter().position(|&v| v >= level).map(|k| {
                if k == 0 {
                    0.0
                } else {
                    let (a, b) = (y[k - 1], y[k]);
                    t(k - 1) + ts * (level - a) / (b - a)
                }
            })
        };
        let rise = match (first_at(0.1), first_at(0.9)) {
            (Some(a), Some(b)) => Some(b - a),
            _ => None,
        };
        let band = STEP_SETTLE_FRACTION;
        let outside = y.iter().rposition(|v| (v - 1.0).abs() > band);
        let (settled, settling) = match outside {
            None => (true, Some(0.0)),
            Some(k) if k + 1 < y.len() => (true, Some(t(k + 1))),
            Some(_) => (false, None),
        };
        let (peak_k, peak) =
            y.iter()
                .copied()
                .enumerate()
                .fold((0, f64::NEG_INFINITY), |best, (k, v)| {
                    if v > best.1 {
                        (k, v)
                    } else {
                        best
                    }
                });
        let peak = if peak.is_finite() { peak } else { 0.0 };
        StepResponse {
            sample_period_s: ts,
            settle_band: band,
            rise_time_s: rise,
            settling_time_s: settling,
            settled,
            peak,
            peak_time_s: t(peak_k),
            overshoot_percent: (100.0 * (peak - 1.0)).max(0.0),
            output: y,
        }
    }
}

/// The discrete controller as a transfer function in `z^-1`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ControllerModel {
    /// How the command is formed.
    pub form: &'static str,
    /// Numerator in powers of `z^-1` (`b0 + b1 z^-1 + ...`), the whole periods of
    /// computation delay included as leading zeros.
    pub numerator_z_inv: Vec<f64>,
    /// Denominator in powers of `z^-1`.
    pub denominator_z_inv: Vec<f64>,
    /// The numerator without the delay's leading zeros.
    pub numerator_without_delay_z_inv: Vec<f64>,
    /// Whole periods of delay folded into `numerator_z_inv`.
    pub delay_whole_samples: usize,
    /// How the computation delay is modelled.
    pub delay_model: String,
    /// Gains as declared: kp (command/rad), ki (command/(rad s)), kd (command s/rad) and
    /// the derivative filter's pole `a = exp(-2 pi f_d T)`.
    pub gains: PidGains,
}

/// The PID's declared gains.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PidGains {
    /// Proportional gain, command per rad.
    pub kp: f64,
    /// Integral gain, command per rad s.
    pub ki: f64,
    /// Derivative gain, command s per rad.
    pub kd: f64,
    /// Pole of the derivative's first-order filter in z.
    pub derivative_pole: f64,
}

/// The loop gain on a frequency grid.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LoopResponse {
    /// Frequencies, Hz.
    pub freq_hz: Vec<f64>,
    /// Real part of `L(e^{j 2 pi f T})`.
    pub re: Vec<f64>,
    /// Imaginary part.
    pub im: Vec<f64>,
}

impl LoopResponse {
    /// `L` at sample `i`.
    pub fn at(&self, i: usize) -> Complex<f64> {
        Complex::new(self.re[i], self.im[i])
    }

    /// Number of frequencies.
    pub fn len(&self) -> usize {
        self.freq_hz.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.freq_hz.is_empty()
    }
}

/// Everything about the loop at one stiffness of the operating range.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PointModel {
    /// `free span` or `tangent at M N m`.
    pub condition: String,
    /// Transmitted torque, N m (0 for the free span).
    pub load_nm: f64,
    /// Stiffness of each cable half, N/m.
    pub half_stiffness_n_per_m: f64,
    /// Margins over every crossing, as the verdict reads them.
    pub margins: Margins,
    /// The plant as matrices.
    pub plant: PlantModel,
    /// The controller's coefficients; `None` for a law beyond the plain PID (rate loop,
    /// filters, observer), whose loop is exported only as `loop_response`.
    pub controller: Option<ControllerModel>,
    /// The loop gain `L` on the grid the margins are read on.
    pub loop_response: LoopResponse,
    /// Poles of the sampled closed loop (every state: plant, delay, PID).
    pub closed_loop_poles: Vec<ZPoint>,
    /// Zeros of `L` (the controller's and the plant's), which `T = L/(1+L)` shares; empty
    /// for a law beyond the plain PID, with `loop_zeros_note`.
    pub loop_zeros: Vec<ZPoint>,
    /// Why there are no zeros.
    pub loop_zeros_note: Option<String>,
    /// The reference step; `None` with `step_note` when it is not computed.
    pub step: Option<StepResponse>,
    /// Why there is no step.
    pub step_note: Option<String>,
}

/// The exact linear reference over the operating range.
#[derive(Clone, Debug, PartialEq)]
pub struct LoopModels {
    /// One entry per stiffness of the operating range, free span first.
    pub points: Vec<PointModel>,
    /// Why the operating load has no tangent stiffness, when it has none.
    pub problem: Option<String>,
}

/// The records of every stiffness of `setup`'s operating range.
pub fn loop_models(setup: &ClosedLoopSetup<'_>) -> LoopModels {
    let (loops, problem) = operating_loops(setup);
    LoopModels {
        points: loops.iter().map(|l| point_model(setup, l)).collect(),
        problem,
    }
}

fn point_model(setup: &ClosedLoopSetup<'_>, op: &OperatingLoop) -> PointModel {
    let lin = &op.lin;
    let ts = lin.sample_period_s();
    let plant = lin.plant_model();
    let ctl = &setup.params.controller;
    let controller = lin.pid_coefficients().map(|(num, den)| {
        let m = plant.delay_whole_samples;
        let mut delayed = vec![0.0; m];
        delayed.extend(num);
        ControllerModel {
            form: "u = -K(z) y: the loop is L = K P, the command from the measurement alone (the reference adds only through kp and ki)",
            numerator_z_inv: delayed,
            denominator_z_inv: den.to_vec(),
            numerator_without_delay_z_inv: num.to_vec(),
            delay_whole_samples: m,
            delay_model: delay_words(&plant),
            gains: PidGains {
                kp: ctl.kp,
                ki: ctl.ki,
                kd: ctl.kd,
                derivative_pole: den[2],
            },
        }
    });
    let margins = op.point().margins;
    let poles: Vec<Complex<f64>> = lin.closed_loop_poles();
    // The zeros of L are the plant's and the PID's; a law with a rate loop, filters or
    // an observer mixes several measured paths, whose zeros these are not.
    let (zeros, zeros_note) = match lin.pid_coefficients() {
        Some((num, _)) => {
            let mut z = lin.plant_zeros();
            z.extend(quadratic_roots(num));
            (z, None)
        }
        None => (
            Vec::new(),
            Some("zeros of L are computed for a plain PID only (this law has a rate loop, filters or an observer)".to_string()),
        ),
    };
    let (step, step_note) = if !margins.stable {
        (
            None,
            Some("the closed loop is unstable: no step response".to_string()),
        )
    } else {
        // Long enough for the slowest pole to decay eight time constants, at most
        // `STEP_MAX_S`.
        let slowest = poles
            .iter()
            .map(|z| z.norm())
            .filter(|&m| m > 0.0 && m < 1.0)
            .map(|m| -ts / m.ln())
            .fold(0.0, f64::max);
        let duration = (8.0 * slowest).clamp(200.0 * ts, STEP_MAX_S);
        match lin.reference_step(duration) {
            Some(y) => (Some(StepResponse::from_samples(y, ts)), None),
            None => (
                None,
                Some(
                    "the reference step is computed for a plain PID only (this law has a rate loop, filters or an observer)"
                        .to_string(),
                ),
            ),
        }
    };
    PointModel {
        condition: op.condition.clone(),
        load_nm: op.load_nm,
        half_stiffness_n_per_m: op.half_stiffness_n_per_m,
        margins,
        plant,
        controller,
        loop_response: lin.loop_response(),
        closed_loop_poles: poles.iter().map(|&z| ZPoint::new(z, ts)).collect(),
        loop_zeros: zeros.iter().map(|&z| ZPoint::new(z, ts)).collect(),
        loop_zeros_note: zeros_note,
        step,
        step_note,
    }
}

/// The delay model in words.
fn delay_words(p: &PlantModel) -> String {
    let m = p.delay_whole_samples;
    if p.delay_fraction == 0.0 {
        format!(
            "{m} whole period(s): the command computed from y_k is held from t_(k+{m}) to t_(k+{}), which is z^-{m} in numerator_z_inv; plant.sampled is the plain zero-order hold",
            m + 1
        )
    } else {
        format!(
            "{} periods: z^-{m} in numerator_z_inv, and within the period u_(k-1) held over its first {} T, u_k over the rest, which plant.sampled carries as its last state u_prev",
            crate::compact(p.delay_samples),
            crate::compact(p.delay_fraction)
        )
    }
}

/// Roots in z of `n0 + n1 z^-1 + n2 z^-2`, i.e. of `n0 z^2 + n1 z + n2`.
fn quadratic_roots([a, b, c]: [f64; 3]) -> Vec<Complex<f64>> {
    if a == 0.0 {
        return if b != 0.0 {
            vec![Complex::from(-c / b)]
        } else {
            Vec::new()
        };
    }
    let d = Complex::from(b * b - 4.0 * a * c).sqrt();
    // The root away from cancellation first, the other from the product c/a.
    let q = if b >= 0.0 {
        -(Complex::from(b) + d) / 2.0
    } else {
        -(Complex::from(b) - d) / 2.0
    };
    if q.norm() == 0.0 {
        return vec![Complex::from(0.0), Complex::from(0.0)];
    }
    vec![q / a, Complex::from(c) / q]
}

impl LinearLoop {
    /// The loop gain on the margins' grid.
    pub fn loop_response(&self) -> LoopResponse {
        let freq_hz = margin_grid(self, MARGIN_POINTS);
        let l: Vec<Complex<f64>> = freq_hz.iter().map(|&f| self.loop_gain(f)).collect();
        LoopResponse {
            re: l.iter().map(|c| c.re).collect(),
            im: l.iter().map(|c| c.im).collect(),
            freq_hz,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_figures_of_a_known_sequence() {
        let mut y: Vec<f64> = (0..100).map(|k| 1.0 - (-0.1 * k as f64).exp()).collect();
        y[10] = 1.3;
        let s = StepResponse::from_samples(y.clone(), 0.01);
        assert!((s.overshoot_percent - 30.0).abs() < 1e-9);
        assert!((s.peak_time_s - 0.1).abs() < 1e-12);
        assert!(s.settled);
        let last_out = y.iter().rposition(|v| (v - 1.0).abs() > 0.02).unwrap();
        assert_eq!(s.settling_time_s, Some((last_out + 1) as f64 * 0.01));
        let slow: Vec<f64> = (0..10).map(|k| 0.05 * k as f64).collect();
        let s = StepResponse::from_samples(slow, 0.01);
        assert!(!s.settled && s.settling_time_s.is_none() && s.rise_time_s.is_none());
    }

    #[test]
    fn quadratic_roots_solve_their_polynomial() {
        for p in [[1.0, -1.9, 0.9], [2.0, 0.5, 3.0], [1.0, 0.0, 0.0]] {
            for z in quadratic_roots(p) {
                let v = z * z * p[0] + z * p[1] + p[2];
                assert!(v.norm() < 1e-12, "{p:?} {z}");
            }
        }
    }
}
