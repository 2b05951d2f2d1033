//! Synthetic bench logs from a truth model with hidden effects, sensor noise and encoder
//! quantisation, for testing the diagnosis against known answers.

use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

use super::effects::EffectName;
use super::model::{relaxing_replay, transport_filter};
use super::IdentifyError;
use super::IdentifySource;
use crate::measurement::BenchLog;

/// A decaying oscillation after every reversal: a resonance outside the effect library.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ringing {
    /// Initial amplitude, rad (e.g. 1e-4).
    pub amplitude_rad: f64,
    /// Frequency, Hz (e.g. 4).
    pub frequency_hz: f64,
    /// Decay time constant, s (e.g. 0.4).
    pub decay_s: f64,
}

/// Sensors and record of a synthetic log.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthOptions {
    /// Record length, s (scenario's `quasi_static.duration_s` when None).
    pub duration_s: Option<f64>,
    /// Sample rate, Hz (scenario's `quasi_static.sample_rate_hz` when None).
    pub sample_rate_hz: Option<f64>,
    /// Input encoder counts per revolution (65536 typical).
    pub input_counts_per_rev: f64,
    /// Output encoder counts per revolution (2^20 for a gimbal-grade encoder).
    pub output_counts_per_rev: f64,
    /// White noise on each angle before quantisation, rad (1e-6 typical).
    pub angle_noise_rad: f64,
    /// White noise on the load cell, N m (0.002 typical).
    pub load_noise_nm: f64,
    /// Unmodelled resonance, for `unexplained` tests.
    pub ringing: Option<Ringing>,
    /// A friction-memory contact whose lag grows with the transmitted torque, for
    /// calibrations across loads.
    pub memory_load: Option<MemoryLoad>,
    /// A friction memory following the `[effects]` law (contact thresholds growing with
    /// the transmitted torque, a slack it takes up), replayed by the closed loop's own
    /// contact model on the true input angle and torque.
    pub memory_law: Option<crate::physics::EffectsParams>,
}

/// One friction-memory contact (the middle threshold of the identification grid) whose lag
/// after a long travel is `lag_rad_per_nm_p * |M|^exponent` at transmitted torque `M`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MemoryLoad {
    /// Lag at 1 N m, rad (1e-4 typical for a gimbal drive).
    pub lag_rad_per_nm_p: f64,
    /// How fast the lag grows with the torque (1: proportional).
    pub exponent: f64,
}

impl Default for SynthOptions {
    fn default() -> Self {
        SynthOptions {
            duration_s: None,
            sample_rate_hz: None,
            input_counts_per_rev: 65536.0,
            output_counts_per_rev: 1_048_576.0,
            angle_noise_rad: 1e-6,
            load_noise_nm: 0.002,
            ringing: None,
            memory_load: None,
            memory_law: None,
        }
    }
}

/// Make a bench log from the scenario's drive, load and `quasi_static.motion`, with the
/// given hidden effects (sizes in the units of [`EffectName::unit`]); runout phases are
/// drawn from `seed`.
pub fn synthesize(
    source: &(impl IdentifySource + ?Sized),
    effects: &[(EffectName, f64)],
    seed: u64,
    options: &SynthOptions,
) -> Result<BenchLog, IdentifyError> {
    let scenario = source.identify_setup();
    let qs = scenario.quasi_static.ok_or_else(|| IdentifyError::Config {
        key: "quasi_static".into(),
        message: "synthesis needs a [quasi_static] section with the motion".into(),
    })?;
    let dur = options.duration_s.unwrap_or(qs.duration_s);
    let rate = options.sample_rate_hz.unwrap_or(qs.sample_rate_hz);
    if !(dur > 0.0 && rate > 0.0 && dur * rate >= 40.0 && dur * rate <= 1e7) {
        return Err(IdentifyError::Config {
            key: "duration_s/sample_rate_hz".into(),
            message: format!("{dur} s at {rate} Hz must give 40 to 1e7 samples"),
        });
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let get = |e: EffectName| effects.iter().find(|x| x.0 == e).map(|x| x.1);
    let drive = scenario.drive;
    let ic = drive.ratio();
    let n = (dur * rate).round() as usize + 1;
    let t: Vec<f64> = (0..n).map(|k| k as f64 / rate).collect();
    let mut dir = Vec::with_capacity(n);
    let mut th_in = Vec::with_capacity(n);
    let mut cur = 1.0;
    for tk in &t {
        let p = qs.motion.at(*tk);
        if p.rate != 0.0 {
            cur = p.rate.signum();
        }
        dir.push(cur);
        th_in.push(p.value);
    }
    let mb = get(EffectName::BearingFriction).unwrap_or(0.0);
    let load: Vec<f64> = (0..n)
        .map(|k| {
            scenario
                .load
                .quasi_static_torque_nm(t[k], th_in[k] / ic, dir[k])
        })
        .collect();
    let torque: Vec<f64> = (0..n).map(|k| -load[k] + mb * dir[k]).collect();
    // There is no logged load to check here: what the drive cannot carry is the scenario's
    // load with the hidden effects, so the message names them.
    let hidden: Vec<String> = effects
        .iter()
        .map(|(e, v)| format!("--effect {e}={}", crate::number(*v)))
        .collect();
    let fail = |(i, m): (usize, String)| {
        IdentifyError::Config {
        key: if hidden.is_empty() {
            format!("{} [load]", scenario.name)
        } else {
            hidden.join(" ")
        },
        message: format!(
            "the synthetic log cannot be made: the drive's replay fails at t = {} s: {m}; hide a smaller bearing_friction or preload_relaxation, or raise drive.preload_n in the scenario",
            crate::compact(t.get(i).copied().unwrap_or(0.0))
        ),
    }
    };
    let rel = get(EffectName::PreloadRelaxation).unwrap_or(0.0);
    let mut e = relaxing_replay(drive, &torque, &t, dur, rel).map_err(fail)?;
    if let Some(tc) = get(EffectName::CableTransport) {
        let travel: Vec<f64> = (0..n)
            .map(|k| {
                if k == 0 {
                    0.0
                } else {
                    (th_in[k] - th_in[k - 1]).abs()
                }
            })
            .collect();
        e = transport_filter(&e, &travel, tc);
    }
    let mut out: Vec<f64> = (0..n).map(|k| th_in[k] / ic + e[k]).collect();
    if let Some(eps) = get(EffectName::InputPulleyRunout) {
        let ph = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
        for k in 0..n {
            out[k] += eps / ic * ((th_in[k] + ph).sin() - ph.sin());
        }
    }
    if let Some(eps) = get(EffectName::OutputDrumRunout) {
        let ph = rng.gen_range(-std::f64::consts::PI..std::f64::consts::PI);
        for o in out.iter_mut() {
            *o += eps * ((*o + ph).sin() - ph.sin());
        }
    }
    if let Some(v) = get(EffectName::AngleDependentRatio) {
        // A random mix of the two lowest shape terms with RMS `v` over the stroke.
        let st = super::extra_effects::stroke(std::iter::once(th_in.as_slice()));
        let a = rng.gen_range(0.0..std::f64::consts::TAU);
        let (c2, c3) = (v * 5f64.sqrt() * a.cos(), v * 7f64.sqrt() * a.sin());
        for k in 0..n {
            let u = super::extra_effects::scaled(th_in[k], st);
            out[k] += c2 * super::extra_effects::legendre(2, u)
                + c3 * super::extra_effects::legendre(3, u);
        }
    }
    if let Some(c) = get(EffectName::LoadCompliance) {
        for k in 0..n {
            out[k] += c * torque[k];
        }
    }
    if let Some(v) = get(EffectName::DistributedFrictionMemory) {
        // Two contacts of the identification grid share the lag `v` at random.
        let st = super::extra_effects::stroke(std::iter::once(th_in.as_slice()));
        let r = super::extra_effects::memory_thresholds_rad(st.1 - st.0);
        let i = rng.gen_range(1..r.len() - 1);
        let j = (i + rng.gen_range(1..r.len() - 1)) % r.len();
        let f = rng.gen_range(0.2..0.8);
        let cols = super::extra_effects::memory_columns(&th_in, &[r[i], r[j]]);
        let (wi, wj) = (v * f / r[i], v * (1.0 - f) / r[j]);
        let fx = crate::physics::EffectsParams {
            friction_memory_thresholds_rad: Some(vec![r[i], r[j]]),
            friction_memory_weights: Some(vec![wi, wj]),
            ..Default::default()
        };
        if let Err((key, m)) = fx.validate() {
            return Err(IdentifyError::Config {
                key: format!("--effect {}={}", EffectName::DistributedFrictionMemory, crate::number(v)),
                message: format!(
                    "over this stroke the lag needs contact weights {} and {} rad/rad, outside the [effects] {key} limit: {m}",
                    crate::compact(wi),
                    crate::compact(wj)
                ),
            });
        }
        for k in 0..n {
            out[k] += wi * cols[0][k] + wj * cols[1][k];
        }
    }
    if let Some(m) = options.memory_load {
        let st = super::extra_effects::stroke(std::iter::once(th_in.as_slice()));
        let r = super::extra_effects::memory_thresholds_rad(st.1 - st.0)
            [super::extra_effects::MEMORY_THRESHOLDS / 2];
        let col = &super::extra_effects::memory_columns(&th_in, &[r])[0];
        for k in 0..n {
            out[k] += m.lag_rad_per_nm_p / r * torque[k].abs().powf(m.exponent) * col[k];
        }
    }
    if let Some(fx) = &options.memory_law {
        if let Some(mut m) = crate::physics::ContactMemory::new(fx, th_in[0]) {
            for k in 0..n {
                out[k] += m.commit(th_in[k], torque[k]);
            }
        }
    }
    if let Some(r) = options.ringing {
        let mut last_rev: Option<f64> = None;
        for k in 0..n {
            if k > 0 && dir[k] != dir[k - 1] {
                last_rev = Some(t[k]);
            }
            if let Some(t0) = last_rev {
                let s = t[k] - t0;
                out[k] += r.amplitude_rad
                    * (-s / r.decay_s).exp()
                    * (std::f64::consts::TAU * r.frequency_hz * s).sin();
            }
        }
    }
    let mut meas_out = out.clone();
    if let Some(tau) = get(EffectName::EncoderDelay) {
        // Before the first sample (and, for a reading that leads, after the last) the
        // axis was moving as the motion says, so a reading from then continues the end
        // step's slope; holding the end value instead would start the log with a jump of
        // the delay times the speed (2.4 mrad at 2 ms on the gimbal scan) that no delayed
        // encoder makes.
        // Inside the log the reading between samples is the cubic through the four
        // nearest: a straight line between samples 10 ms apart bends a 0.1 Hz sine by
        // f (1 - f) / 2 of its curvature over a step squared, a scale error of 1.8e-6 at
        // 1 ms that a diagnosis rightly found as a second effect.
        for k in 0..n {
            let p = (t[k] - tau) * rate;
            let j = (p.max(0.0).floor() as usize).min(n - 2);
            let f = p - j as f64;
            meas_out[k] = if j >= 1 && j + 2 < n {
                let w = [
                    -f * (f - 1.0) * (f - 2.0) / 6.0,
                    (f + 1.0) * (f - 1.0) * (f - 2.0) / 2.0,
                    -(f + 1.0) * f * (f - 2.0) / 2.0,
                    (f + 1.0) * f * (f - 1.0) / 6.0,
                ];
                w[0] * out[j - 1] + w[1] * out[j] + w[2] * out[j + 1] + w[3] * out[j + 2]
            } else {
                out[j] + f * (out[j + 1] - out[j])
            };
        }
    }
    if let Some(s) = get(EffectName::EncoderScaleError) {
        for o in meas_out.iter_mut() {
            *o *= 1.0 + s;
        }
    }
    if let Some(d) = get(EffectName::ThermalDrift) {
        for k in 0..n {
            meas_out[k] += d * t[k];
        }
    }
    let noise =
        Normal::new(0.0, options.angle_noise_rad.max(0.0)).map_err(|e| IdentifyError::Config {
            key: "angle_noise_rad".into(),
            message: e.to_string(),
        })?;
    let lnoise =
        Normal::new(0.0, options.load_noise_nm.max(0.0)).map_err(|e| IdentifyError::Config {
            key: "load_noise_nm".into(),
            message: e.to_string(),
        })?;
    let quant = |v: f64, counts: f64| {
        if counts > 0.0 {
            let q = std::f64::consts::TAU / counts;
            (v / q).round() * q
        } else {
            v
        }
    };
    let mut log = BenchLog {
        source: format!("synthetic(seed={seed})"),
        comments: vec![format!(
            "synthetic log: scenario {}, effects [{}], seed {seed}",
            scenario.name,
            effects
                .iter()
                .map(|(e, v)| format!("{e}={}", crate::number(*v)))
                .collect::<Vec<_>>()
                .join(", ")
        )],
        ..BenchLog::default()
    };
    for k in 0..n {
        log.t_s.push(t[k]);
        log.theta_in_rad.push(quant(
            th_in[k] + noise.sample(&mut rng),
            options.input_counts_per_rev,
        ));
        log.theta_out_rad.push(quant(
            meas_out[k] + noise.sample(&mut rng),
            options.output_counts_per_rev,
        ));
        log.load_nm.push(load[k] + lnoise.sample(&mut rng));
    }
    Ok(log)
}

/// Parse a command-line `NAME=VALUE` effect (`encoder_delay=0.001`), value in the unit of
/// [`EffectName::unit`].
pub fn parse_effect_arg(arg: &str) -> Result<(EffectName, f64), IdentifyError> {
    let bad = |message: String| IdentifyError::Config {
        key: format!("--effect {arg}"),
        message,
    };
    let (name, value) = arg
        .split_once('=')
        .ok_or_else(|| bad("expected NAME=VALUE, e.g. encoder_delay=0.001".into()))?;
    let e: EffectName = name.trim().parse().map_err(bad)?;
    let v: f64 = value
        .trim()
        .parse()
        .map_err(|_| bad(format!("`{}` is not a number ({})", value.trim(), e.unit())))?;
    if !v.is_finite() {
        return Err(bad("the value must be finite".into()));
    }
    within_effects_limits(e, v).map_err(bad)?;
    Ok((e, v))
}

/// Whether a hidden effect of size `v` stays within what a scenario's `[effects]` section
/// accepts for it (`EffectsParams::validate`, the limits docs/keys.md lists), so a
/// synthetic log holds nothing a scenario could not: a compliance of 1e300 wrote numbers
/// of three hundred digits, an encoder delay of 10 s a log of nothing but the delay.
fn within_effects_limits(e: EffectName, v: f64) -> Result<(), String> {
    use crate::physics::EffectsParams;
    let mut fx = EffectsParams::default();
    match e {
        EffectName::InputPulleyRunout => fx.input_pulley_runout = Some(v),
        EffectName::OutputDrumRunout => fx.output_drum_runout = Some(v),
        EffectName::EncoderDelay => fx.encoder_delay_s = Some(v),
        EffectName::EncoderScaleError => fx.encoder_scale_error = Some(v),
        EffectName::PreloadRelaxation => fx.preload_relaxation_per_s = Some(v),
        EffectName::BearingFriction => fx.bearing_friction_nm = Some(v),
        EffectName::CableTransport => fx.cable_transport_rad = Some(v),
        EffectName::ThermalDrift => fx.thermal_drift_rad_per_s = Some(v),
        EffectName::LoadCompliance => fx.load_compliance_rad_per_nm = Some(v),
        // The shape is drawn as P_2 and P_3 terms of up to sqrt 7 times its RMS, each
        // held to the [effects] limit of 1 rad.
        EffectName::AngleDependentRatio => {
            let most = 1.0 / 7f64.sqrt();
            return if (0.0..=most).contains(&v) {
                Ok(())
            } else {
                Err(format!(
                    "{e} {} (RMS of the ratio shape, rad) must be in [0, {}], where its Legendre coefficients stay within the [effects] limit of 1 rad",
                    crate::number(v),
                    crate::compact(most)
                ))
            };
        }
        // Contact weights are checked against [effects] where the stroke gives them.
        EffectName::DistributedFrictionMemory => {
            return if v >= 0.0 {
                Ok(())
            } else {
                Err(format!(
                    "{e} {} (lag after a long travel, rad) must be 0 or more",
                    crate::number(v)
                ))
            };
        }
    }
    fx.validate()
        .map_err(|(key, m)| format!("{e} {m}, the range of [effects] {key} (docs/keys.md)"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn effect_arguments_parse_or_explain() {
        let (e, v) = parse_effect_arg("encoder_delay=0.002").unwrap();
        assert_eq!((e, v), (EffectName::EncoderDelay, 0.002));
        let err = parse_effect_arg("encoder_dealy=1").unwrap_err().to_string();
        assert!(err.contains("encoder_delay"), "{err}");
        assert!(parse_effect_arg("thermal_drift=abc").is_err());
        assert!(parse_effect_arg("thermal_drift").is_err());
    }

    #[test]
    fn effect_sizes_outside_the_effects_limits_are_refused() {
        for arg in [
            "load_compliance=1e300",
            "input_pulley_runout=5",
            "input_pulley_runout=-0.003",
            "encoder_delay=10",
            "thermal_drift=1e10",
            "angle_dependent_ratio=0.5",
            "distributed_friction_memory=-1e-4",
        ] {
            let err = parse_effect_arg(arg)
                .map(|r| format!("{r:?}"))
                .expect_err(arg)
                .to_string();
            let name = arg.split('=').next().unwrap_or(arg);
            assert!(
                err.contains("--effect") && err.contains(name),
                "{arg}: {err}"
            );
            assert!(
                err.contains("must") && !err.contains("000000000"),
                "{arg}: {err}"
            );
        }
        for arg in [
            "input_pulley_runout=0.003",
            "load_compliance=-5e-4",
            "encoder_delay=0.002",
            "preload_relaxation=-0.01",
        ] {
            assert!(parse_effect_arg(arg).is_ok(), "{arg}");
        }
    }
}
