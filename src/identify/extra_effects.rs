//! Signatures of the effects a real multi-wrap instrument drive shows beyond the capstan
//! model: a transmission ratio that varies over the stroke, output deflection proportional
//! to the transmitted load outside the modelled spans, and friction memory spread over many
//! contacts. Each is linear in its coefficients given the measured signals, so the fit
//! projects them out by least squares (non-negative where physics demands it).
//!
//! Functions take plain arrays: input angles, rad; torques, N m.

/// Legendre terms of the ratio shape: `P_2 .. P_(1+SHAPE_TERMS)` of the scaled input angle
/// (the constant and linear terms are the encoder zero and the mean ratio).
pub const SHAPE_TERMS: usize = 3;

/// Play thresholds of the distributed friction memory (a Prandtl-Ishlinskii sum).
pub const MEMORY_THRESHOLDS: usize = 8;

/// Threshold grid as fractions of the input stroke: geometric from 0.4 % to 20 %, dense
/// where a lag that builds up over tens of mrad of input travel is resolved.
pub fn memory_thresholds_rad(stroke_rad: f64) -> [f64; MEMORY_THRESHOLDS] {
    let mut r = [0.0; MEMORY_THRESHOLDS];
    let (lo, hi) = (0.004f64, 0.2f64);
    for (k, v) in r.iter_mut().enumerate() {
        let f = k as f64 / (MEMORY_THRESHOLDS - 1) as f64;
        *v = stroke_rad * lo * (hi / lo).powf(f);
    }
    r
}

/// Observed input stroke over several logs' input angles: (lowest, highest), rad.
pub fn stroke<'a>(angles: impl Iterator<Item = &'a [f64]>) -> (f64, f64) {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for a in angles {
        for v in a {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    if !(hi.is_finite() && lo.is_finite()) || hi <= lo {
        (lo.min(0.0), lo.min(0.0) + 1.0)
    } else {
        (lo, hi)
    }
}

pub use crate::physics::effects::{legendre, scaled};

/// Columns of the ratio shape: `P_(2+j)(u)` for j in 0..SHAPE_TERMS, rad per unit coefficient.
pub fn shape_columns(theta_in: &[f64], stroke: (f64, f64)) -> Vec<Vec<f64>> {
    (0..SHAPE_TERMS)
        .map(|j| {
            theta_in
                .iter()
                .map(|t| legendre(2 + j, scaled(*t, stroke)))
                .collect()
        })
        .collect()
}

/// RMS over the stroke of a ratio shape with Legendre coefficients `c` (P_2 first), rad:
/// the Legendre terms are orthogonal with mean square `1/(2k+1)` over [-1, 1].
pub fn shape_rms(c: &[f64]) -> f64 {
    c.iter()
        .enumerate()
        .map(|(j, v)| v * v / (2.0 * (j + 2) as f64 + 1.0))
        .sum::<f64>()
        .sqrt()
}

/// Gradient of [`shape_rms`] with respect to the coefficients.
pub fn shape_rms_gradient(c: &[f64]) -> Vec<f64> {
    let r = shape_rms(c).max(1e-300);
    c.iter()
        .enumerate()
        .map(|(j, v)| v / (2.0 * (j + 2) as f64 + 1.0) / r)
        .collect()
}

/// Columns of the distributed friction memory: `P_r(theta_in) - theta_in` for every
/// threshold `r` (the lag of one contact that sticks until the input has moved `r` past a
/// reversal). Weights are output rad per input rad, non-negative.
pub fn memory_columns(theta_in: &[f64], thresholds: &[f64]) -> Vec<Vec<f64>> {
    thresholds
        .iter()
        .map(|r| {
            super::play::play(theta_in, *r)
                .iter()
                .zip(theta_in)
                .map(|(p, x)| p - x)
                .collect()
        })
        .collect()
}

/// Load-scaled columns of the distributed friction memory:
/// `|M|^p (P_r(theta_in) - theta_in)`. Friction at a contact grows with the cable tension
/// pressing on it, so the lag grows with the transmitted torque `M` (N m); `p` (the
/// `load_exponent`, 1 for friction proportional to tension) lets it grow faster, as when
/// the contacts' stiffness also falls with load. Weights are output rad per input rad per
/// (N m)^p, >= 0.
pub fn memory_load_columns(
    theta_in: &[f64],
    torque_nm: &[f64],
    thresholds: &[f64],
    load_exponent: f64,
) -> Vec<Vec<f64>> {
    memory_columns(theta_in, thresholds)
        .into_iter()
        .map(|c| {
            c.iter()
                .zip(torque_nm)
                .map(|(v, m)| v * m.abs().powf(load_exponent))
                .collect()
        })
        .collect()
}

/// A play operator whose half width changes sample by sample (`width[i]`, rad): the
/// output stays put until the input is further than the current width from it, and a
/// width that shrinks pulls it along.
pub fn varying_play(x: &[f64], width: impl Fn(usize) -> f64) -> Vec<f64> {
    let mut y = x.first().copied().unwrap_or(0.0);
    x.iter()
        .enumerate()
        .map(|(i, v)| {
            let r = width(i);
            y = y.clamp(v - r, v + r);
            y
        })
        .collect()
}

/// Columns of the distributed friction memory with slip thresholds that grow with the
/// transmitted torque: `P_(r (1 + growth |M|))(theta_in) - theta_in` for every no-load
/// threshold `r` (rad of input); `growth` in 1/(N m), torques `M` in N m.
pub fn memory_law_columns(
    theta_in: &[f64],
    torque_nm: &[f64],
    thresholds: &[f64],
    growth: f64,
) -> Vec<Vec<f64>> {
    if growth == 0.0 {
        return memory_columns(theta_in, thresholds);
    }
    thresholds
        .iter()
        .map(|r| {
            varying_play(theta_in, |i| {
                crate::physics::effects::contact_threshold(*r, growth, torque_nm[i])
            })
            .iter()
            .zip(theta_in)
            .map(|(p, x)| p - x)
            .collect()
        })
        .collect()
}

/// Column of the slack's play: `P_s(theta_in) - theta_in` with the width `s(|M|)` of
/// [`crate::physics::effects::slack_width`] (`slack` rad at no load, gone at `taken_up`
/// N m).
pub fn slack_column(theta_in: &[f64], torque_nm: &[f64], slack: f64, taken_up: f64) -> Vec<f64> {
    varying_play(theta_in, |i| {
        crate::physics::effects::slack_width(slack, taken_up, torque_nm[i])
    })
    .iter()
    .zip(theta_in)
    .map(|(p, x)| p - x)
    .collect()
}

/// Bounds of the memory law's nonlinear parameters in a calibration, relative to the
/// largest torque magnitude `M_max` of the logs (N m) and the input stroke (rad): threshold
/// growth `0 ..= GROWTH_AT_MAX / M_max` (thresholds up to 21 times their no-load size at
/// the largest torque), slack `0 ..= SLACK_STROKE x stroke`, take-up torque
/// `TAKEN_UP.0 .. TAKEN_UP.1` times `M_max`.
pub const GROWTH_AT_MAX: f64 = 20.0;
/// See [`GROWTH_AT_MAX`].
pub const SLACK_STROKE: f64 = 0.2;
/// See [`GROWTH_AT_MAX`].
pub const TAKEN_UP: (f64, f64) = (0.05, 1.0);

/// Bounds and start of the friction memory's load exponent `p` in a calibration.
pub const MEMORY_LOAD_EXPONENT: (f64, f64, f64) = (0.5, 8.0, 1.0);

/// Lag of the memory after a long travel past a reversal, rad of output: `sum w_j r_j`.
pub fn memory_amplitude(w: &[f64], thresholds: &[f64]) -> f64 {
    w.iter().zip(thresholds).map(|(a, b)| a * b).sum()
}

/// How far input-pulley runout (period one input revolution) can be told apart from a
/// ratio shape over the observed stroke: the smaller relative residual of `sin` and `cos`
/// of the input angle after least-squares projection onto the shape's span (constant,
/// linear and [`SHAPE_TERMS`] Legendre terms). Near 0: indistinguishable (a stroke much
/// shorter than a revolution); near 1: fully separable.
pub fn runout_separability(theta_in: &[f64], stroke: (f64, f64)) -> f64 {
    let n = theta_in.len();
    if n < 2 * (SHAPE_TERMS + 2) {
        return 0.0;
    }
    let basis: Vec<Vec<f64>> = (0..SHAPE_TERMS + 2)
        .map(|k| {
            theta_in
                .iter()
                .map(|t| legendre(k, scaled(*t, stroke)))
                .collect()
        })
        .collect();
    let cols: Vec<&[f64]> = basis.iter().map(|c| c.as_slice()).collect();
    let mask = vec![true; n];
    let mut worst = f64::INFINITY;
    for f in [f64::sin, f64::cos] {
        let y: Vec<f64> = theta_in.iter().map(|t| f(*t)).collect();
        let mean = y.iter().sum::<f64>() / n as f64;
        let var: f64 = y.iter().map(|v| (v - mean).powi(2)).sum();
        if var <= 1e-12 * n as f64 {
            continue;
        }
        let Some(fit) = super::lm::linear_lsq(&cols, &y, &mask) else {
            return 0.0;
        };
        let res: f64 = (0..n)
            .map(|i| {
                let p: f64 = cols.iter().zip(&fit.coef).map(|(c, b)| c[i] * b).sum();
                (y[i] - p).powi(2)
            })
            .sum();
        worst = worst.min((res / var).sqrt());
    }
    if worst.is_finite() {
        worst
    } else {
        0.0
    }
}

/// Below this [`runout_separability`], ratio shape and input-pulley runout are reported as
/// indistinguishable (less than 5 % of a runout's signature lies outside the shape's span).
pub const SEPARABLE_MIN: f64 = 0.05;

/// What the extended effects' coefficients are defined on, shared by the logs of a fit.
pub(crate) struct Basis<'a> {
    /// Input stroke, rad.
    pub stroke: (f64, f64),
    /// Friction-memory thresholds, rad of input.
    pub thresholds: &'a [f64],
    /// Mean of `|M|^p` over the logs, (N m)^p, with `p` the fitted load exponent (where
    /// the memory's size is read).
    pub mean_load_factor: f64,
}

/// Parameter rows and stored effects of the extended effects in a fit; `cov` is laid out
/// as (nonlinear, linear) with `n_nonlinear` nonlinear parameters first. The friction
/// memory's size is its lag after a long travel at the basis's mean torque.
pub(crate) fn parameters(
    fit: &super::model::Fitted,
    n_nonlinear: usize,
    cov: &nalgebra::DMatrix<f64>,
    basis: &Basis,
    out: &mut Vec<super::ParamEstimate>,
    eff: &mut super::effects::EffectsParams,
) {
    let Basis {
        stroke,
        thresholds,
        mean_load_factor,
    } = *basis;
    use super::effects::EffectName;
    use super::model::LinParam;
    let coefs = |e: EffectName| -> Vec<(usize, f64)> {
        fit.lin
            .iter()
            .enumerate()
            .filter(|(_, p)| matches!(p, LinParam::Effect(q, _) if *q == e))
            .map(|(i, _)| (n_nonlinear + i, fit.coef[i]))
            .collect()
    };
    let std_of = |grad: &[(usize, f64)]| -> f64 {
        let mut v = 0.0;
        for (i, gi) in grad {
            for (j, gj) in grad {
                v += gi * gj * cov[(*i, *j)];
            }
        }
        v.max(0.0).sqrt()
    };
    let shape = coefs(EffectName::AngleDependentRatio);
    if !shape.is_empty() {
        let c: Vec<f64> = shape.iter().map(|x| x.1).collect();
        let g = shape_rms_gradient(&c);
        let grad: Vec<(usize, f64)> = shape.iter().zip(&g).map(|(a, b)| (a.0, *b)).collect();
        out.push(super::ParamEstimate::new(
            EffectName::AngleDependentRatio.to_string(),
            shape_rms(&c),
            std_of(&grad),
            EffectName::AngleDependentRatio.unit(),
        ));
        for (j, (i, v)) in shape.iter().enumerate() {
            out.push(super::ParamEstimate::new(
                format!("angle_dependent_ratio_P{}", j + 2),
                *v,
                std_of(&[(*i, 1.0)]),
                "rad",
            ));
        }
        eff.angle_dependent_ratio_coefs = Some(c);
        eff.angle_dependent_ratio_stroke_rad = Some([stroke.0, stroke.1]);
    }
    if let Some((i, v)) = coefs(EffectName::LoadCompliance).first() {
        out.push(super::ParamEstimate::new(
            EffectName::LoadCompliance.to_string(),
            *v,
            std_of(&[(*i, 1.0)]),
            EffectName::LoadCompliance.unit(),
        ));
        eff.load_compliance_rad_per_nm = Some(*v);
    }
    let mem = coefs(EffectName::DistributedFrictionMemory);
    if !mem.is_empty() {
        let nt = thresholds.len().min(mem.len());
        // Layout: constant weights, then the load-scaled ones when fitted, then the slack's
        // weight when the law is fitted.
        let has_load = mem.len() >= 2 * nt;
        let nv = if has_load { nt } else { 0 };
        let slack = mem.get(nt + nv).copied();
        let mem = &mem[..nt + nv];
        let w: Vec<f64> = mem[..nt].iter().map(|x| x.1).collect();
        let v: Vec<f64> = mem[nt..].iter().map(|x| x.1).collect();
        if let Some((i, sw)) = slack {
            out.push(super::ParamEstimate::new(
                "friction_memory_slack_weight",
                sw,
                std_of(&[(i, 1.0)]),
                "rad/rad",
            ));
            eff.friction_memory_slack_weight = Some(sw);
        }
        // Reported at the logs' mean torque magnitude: where the data pins it, whatever
        // the split between the constant and the load-scaled weights. Thresholds growing
        // with the torque are read there too (the basis's factor is the mean `|M|` when
        // there are no load-scaled weights, `p` being 1 then).
        let at_mean = if has_load {
            1.0
        } else {
            1.0 + eff.friction_memory_threshold_growth_per_nm.unwrap_or(0.0) * mean_load_factor
        };
        let grad: Vec<(usize, f64)> = mem[..nt]
            .iter()
            .zip(thresholds)
            .map(|(a, r)| (a.0, *r * at_mean))
            .chain(
                mem[nt..]
                    .iter()
                    .zip(thresholds)
                    .map(|(a, r)| (a.0, *r * mean_load_factor)),
            )
            .collect();
        out.push(super::ParamEstimate::new(
            EffectName::DistributedFrictionMemory.to_string(),
            at_mean * memory_amplitude(&w, thresholds)
                + mean_load_factor * memory_amplitude(&v, thresholds),
            std_of(&grad),
            EffectName::DistributedFrictionMemory.unit(),
        ));
        if !v.is_empty() {
            let grad: Vec<(usize, f64)> = mem[nt..]
                .iter()
                .zip(thresholds)
                .map(|(a, r)| (a.0, *r))
                .collect();
            out.push(super::ParamEstimate::new(
                "distributed_friction_memory_growth",
                memory_amplitude(&v, thresholds),
                std_of(&grad),
                "rad/(N m)^p (lag growth with transmitted torque)",
            ));
        }
        for ((i, v), r) in mem[..nt].iter().zip(thresholds) {
            out.push(super::ParamEstimate::new(
                format!("friction_memory_weight[r={r:.4} rad]"),
                *v,
                std_of(&[(*i, 1.0)]),
                "rad/rad",
            ));
        }
        for ((i, v), r) in mem[nt..].iter().zip(thresholds) {
            out.push(super::ParamEstimate::new(
                format!("friction_memory_load_weight[r={r:.4} rad]"),
                *v,
                std_of(&[(*i, 1.0)]),
                "rad/rad/(N m)^p",
            ));
        }
        eff.friction_memory_load_weights_per_nm = (!v.is_empty()).then_some(v);
        eff.friction_memory_thresholds_rad = Some(thresholds[..w.len()].to_vec());
        eff.friction_memory_weights = Some(w);
    }
}

/// Mean of `|M|^p` of the transmitted torque over logs, (N m)^p (`p` = 1: the mean
/// magnitude, N m).
pub fn mean_load_factor<'a>(torques: impl Iterator<Item = &'a [f64]>, p: f64) -> f64 {
    let (s, n) = torques.fold((0.0, 0usize), |(s, n), t| {
        (
            s + t.iter().map(|m| m.abs().powf(p)).sum::<f64>(),
            n + t.len(),
        )
    });
    s / n.max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legendre_terms_are_orthogonal_with_known_norms() {
        let n = 20000;
        for a in 0..6 {
            for b in 0..6 {
                // Midpoint rule over [-1, 1].
                let s: f64 = (0..n)
                    .map(|i| {
                        let u = -1.0 + (i as f64 + 0.5) * 2.0 / n as f64;
                        legendre(a, u) * legendre(b, u)
                    })
                    .sum::<f64>()
                    / n as f64;
                let expect = if a == b {
                    1.0 / (2 * a + 1) as f64
                } else {
                    0.0
                };
                assert!((s - expect).abs() < 1e-6, "P{a} P{b}: {s}");
            }
        }
        let c = [0.3, -0.2, 0.1];
        let direct: f64 = (0..n)
            .map(|i| {
                let u = -1.0 + (i as f64 + 0.5) * 2.0 / n as f64;
                let v: f64 = (0..3).map(|j| c[j] * legendre(j + 2, u)).sum();
                v * v
            })
            .sum::<f64>()
            / n as f64;
        assert!((shape_rms(&c) - direct.sqrt()).abs() < 1e-6);
    }

    #[test]
    fn memory_column_is_the_lag_of_a_play() {
        // Up 1 rad, down 1 rad: the lag is -r once the input has moved r, then +r after
        // moving 2r back.
        let x: Vec<f64> = (0..=200)
            .map(|i| {
                if i <= 100 {
                    i as f64 * 0.01
                } else {
                    2.0 - i as f64 * 0.01
                }
            })
            .collect();
        let c = &memory_columns(&x, &[0.1])[0];
        assert!((c[100] + 0.1).abs() < 1e-12);
        assert!(c[105].abs() < 0.05 + 1e-12);
        assert!((c[200] - 0.1).abs() < 1e-12);
        assert_eq!(memory_amplitude(&[0.5, 0.25], &[0.1, 0.2]), 0.1);
    }

    /// Mirrored input angle and mirrored torque give mirrored columns: the law reads only
    /// the torque's magnitude and the plays are odd in the input.
    #[test]
    fn memory_law_columns_are_mirror_symmetric() {
        let x: Vec<f64> = (0..4000)
            .map(|i| 0.5 * (i as f64 * 0.003).sin() + 0.01 * (i as f64 * 0.05).sin())
            .collect();
        let m: Vec<f64> = (0..4000)
            .map(|i| 0.07 + 0.04 * (i as f64 * 0.001).cos())
            .collect();
        let xm: Vec<f64> = x.iter().map(|v| -v).collect();
        let mm: Vec<f64> = m.iter().map(|v| -v).collect();
        let r = [0.01, 0.03];
        let a = memory_law_columns(&x, &m, &r, 9.0);
        let b = memory_law_columns(&xm, &mm, &r, 9.0);
        let sa = slack_column(&x, &m, 0.05, 0.09);
        let sb = slack_column(&xm, &mm, 0.05, 0.09);
        for i in 0..x.len() {
            for j in 0..r.len() {
                assert!((a[j][i] + b[j][i]).abs() < 1e-15);
            }
            assert!((sa[i] + sb[i]).abs() < 1e-15);
        }
        assert!(sa.iter().any(|v| v.abs() > 0.01));
        // No growth: the fixed-threshold columns.
        assert_eq!(memory_law_columns(&x, &m, &r, 0.0), memory_columns(&x, &r));
    }

    #[test]
    fn short_stroke_cannot_tell_runout_from_shape_but_a_revolution_can() {
        let short: Vec<f64> = (0..2000)
            .map(|i| 0.52 + 0.52 * (i as f64 * 0.01).sin())
            .collect();
        let s = runout_separability(&short, stroke(std::iter::once(short.as_slice())));
        assert!(s < SEPARABLE_MIN, "short stroke separability {s}");
        let long: Vec<f64> = (0..2000).map(|i| 6.0 * (i as f64 * 0.01).sin()).collect();
        let l = runout_separability(&long, stroke(std::iter::once(long.as_slice())));
        assert!(l > 0.3, "two-revolution stroke separability {l}");
    }
}
