//! An independent truth for identification tests: bench logs made by a model built
//! differently from the one the diagnosis fits, so that a diagnosis which only recognises
//! its own model's output fails here.
//!
//! What differs from the library's own synthesis (`identify::synthesize`):
//! - **The cable.** Each wrap region is a grid of nodes carrying the tension (the library
//!   keeps the exact breakpoints of the profile and integrates in closed form); the
//!   elongation is the trapezoid sum over the grid and the two tensions come from a
//!   bracketing root search. Nothing of the cable model in `physics` is called (the free
//!   span is computed here too); `oracle_jump_mrad` checks the grid against the oracle
//!   table of physics.md. The load the scenario declares (brake, unbalance) is evaluated
//!   by the scenario's own load model: it is the input, which the diagnosis reads back from
//!   the log's load column.
//! - **Time.** The truth runs on a grid `substeps` times finer than the log and is read at
//!   the log's instants; an encoder delay is read off that finer grid.
//! - **The instrument.** Friction coefficient and preload a little off the scenario's
//!   values, which are what the diagnosis is told; the cable modulus, which it calibrates,
//!   further off.
//! - **The effects.** Drum runout by the implicit drum kinematics; cable transport as the
//!   continuous lag equation in input travel (the fit's law, a first-order lag), integrated
//!   exactly for a piecewise-linear input where the fit holds each sample; preload
//!   relaxation (the fit's law, a linear decay) as a preload that decays inside the cable's
//!   memory, scaling every stored tension; friction
//!   memory on contacts whose thresholds lie between those of the identification grid; an
//!   angle-dependent ratio whose shape is a cosine over the stroke, not a polynomial.
//! - **The noise.** White noise and quantisation as before, plus 1/f noise and a random-walk
//!   drift on the output encoder, a drifting load-cell offset, and a few outlier samples.
//!   On the gimbal-grade output encoder (2^20 counts, a 6 µrad step) the 1/f noise (1 µrad)
//!   and the wander (2 µrad over the record) are sub-count, as on a thermally settled
//!   bench, and move the reading across count boundaries with the white noise; the
//!   outliers (20 to 60 µrad) are several counts.

#![allow(dead_code)]

use cable_servo::identify::EffectName;
use cable_servo::measurement::BenchLog;
use cable_servo::scenario::Scenario;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use std::f64::consts::{PI, TAU};

/// One wrap region on a grid of `n` nodes from the contact point (node 0) inward.
#[derive(Clone, Debug)]
struct GridWrap {
    /// Tension at each node, N.
    t: Vec<f64>,
    /// `exp(-mu s)` and `exp(mu s)` at each node.
    em: Vec<f64>,
    ep: Vec<f64>,
    /// Trapezoid weight of each node, rad.
    wt: Vec<f64>,
    /// Suffix sums from node j inward of `wt*t` (N rad) and of `wt` (rad); one longer.
    st: Vec<f64>,
    sw: Vec<f64>,
}

impl GridWrap {
    fn new(wrap_rad: f64, mu: f64, preload_n: f64, n: usize) -> Self {
        let ds = wrap_rad / (n - 1) as f64;
        let s: Vec<f64> = (0..n).map(|j| j as f64 * ds).collect();
        let wt: Vec<f64> = (0..n)
            .map(|j| if j == 0 || j == n - 1 { 0.5 * ds } else { ds })
            .collect();
        let mut g = GridWrap {
            t: vec![preload_n; n],
            em: s.iter().map(|v| (-mu * v).exp()).collect(),
            ep: s.iter().map(|v| (mu * v).exp()).collect(),
            wt,
            st: vec![0.0; n + 1],
            sw: vec![0.0; n + 1],
        };
        for j in (0..n).rev() {
            g.st[j] = g.st[j + 1] + g.wt[j] * g.t[j];
            g.sw[j] = g.sw[j + 1] + g.wt[j];
        }
        g
    }

    /// `integral (T_new(s) - preload) ds` (N rad) after the boundary tension becomes `tb`,
    /// and whether slip reached the inner end. The clamp `T_new = clamp(T_old, tb e^-mu s,
    /// tb e^mu s)` changes a prefix of the nodes only: a node inside the band has every
    /// node beyond it inside too, as the stored profile obeys the slope bound.
    fn trial(&self, tb: f64, preload_n: f64) -> (f64, bool) {
        let mut acc = 0.0;
        for j in 0..self.t.len() {
            let (lo, hi) = (tb * self.em[j], tb * self.ep[j]);
            let old = self.t[j];
            if old >= lo && old <= hi && j > 0 {
                return (acc + self.st[j] - preload_n * self.sw[j], false);
            }
            acc += self.wt[j] * (old.clamp(lo, hi) - preload_n);
        }
        (acc, true)
    }

    fn commit(&mut self, tb: f64) {
        let n = self.t.len();
        let mut j = 0;
        while j < n {
            let (lo, hi) = (tb * self.em[j], tb * self.ep[j]);
            let old = self.t[j];
            if old >= lo && old <= hi && j > 0 {
                break;
            }
            self.t[j] = old.clamp(lo, hi);
            j += 1;
        }
        for k in (0..j).rev() {
            self.st[k] = self.st[k + 1] + self.wt[k] * self.t[k];
        }
    }

    /// Every tension scaled by `k`: a preload that creeps keeps the shape of the memory.
    fn scale(&mut self, k: f64) {
        for v in self.t.iter_mut().chain(self.st.iter_mut()) {
            *v *= k;
        }
    }
}

/// One half of the cable: drum wrap, free span, half the pulley wrap.
#[derive(Clone, Debug)]
struct GridHalf {
    drum: GridWrap,
    pulley: GridWrap,
}

/// Geometry and cable of a grid drive.
#[derive(Clone, Copy, Debug)]
pub struct GridSpec {
    /// Pulley and drum radii, m.
    pub ri_m: f64,
    pub ro_m: f64,
    /// Free span of each half, m.
    pub span_m: f64,
    /// `E*A`, N.
    pub modulus_n: f64,
    /// Friction coefficient.
    pub mu: f64,
    /// Preload, N.
    pub preload_n: f64,
    /// Drum wrap per half and total pulley wrap, rad.
    pub drum_wrap_rad: f64,
    pub pulley_wrap_rad: f64,
}

/// The cable drive on grids, quasi-static.
#[derive(Clone, Debug)]
pub struct GridDrive {
    upper: GridHalf,
    lower: GridHalf,
    ri: f64,
    ro: f64,
    span_m: f64,
    modulus_n: f64,
    preload_n: f64,
}

impl GridDrive {
    /// Drive with `nodes` grid nodes per wrap region.
    pub fn new(g: &GridSpec, nodes: usize) -> Self {
        let half = GridHalf {
            drum: GridWrap::new(g.drum_wrap_rad, g.mu, g.preload_n, nodes),
            pulley: GridWrap::new(g.pulley_wrap_rad / 2.0, g.mu, g.preload_n, nodes),
        };
        GridDrive {
            upper: half.clone(),
            lower: half,
            ri: g.ri_m,
            ro: g.ro_m,
            span_m: g.span_m,
            modulus_n: g.modulus_n,
            preload_n: g.preload_n,
        }
    }

    /// Elongation of a half (m) at boundary tension `tb`, and whether its pulley slip zone
    /// reaches the neutral point (gross slip).
    fn elongation(&self, h: &GridHalf, tb: f64) -> (f64, bool) {
        let (id, _) = h.drum.trial(tb, self.preload_n);
        let (ip, through) = h.pulley.trial(tb, self.preload_n);
        (
            (self.span_m * (tb - self.preload_n) + self.ro * id + self.ri * ip) / self.modulus_n,
            through,
        )
    }

    /// Preload creeps to `preload_n`, every tension with it.
    pub fn set_preload(&mut self, preload_n: f64) {
        let k = preload_n / self.preload_n;
        for h in [&mut self.upper, &mut self.lower] {
            h.drum.scale(k);
            h.pulley.scale(k);
        }
        self.preload_n = preload_n;
    }

    /// Apply the transmitted torque `m_nm` (N m) and return the transmission error
    /// `-D/ro`, rad. Errors on slack and gross slip.
    pub fn apply(&mut self, m_nm: f64) -> Result<f64, String> {
        let dt = m_nm / self.ro;
        // F(tu) = elong_u(tu) + elong_l(tu - dt) rises with tu; its root is the state.
        let f = |tu: f64| -> Result<f64, String> {
            Ok(self.elongation(&self.upper, tu).0 + self.elongation(&self.lower, tu - dt).0)
        };
        let floor = dt.max(0.0) + 1e-9 * self.preload_n;
        let mid = self.preload_n + 0.5 * dt;
        let mut w = 0.5 * dt.abs() + 1e-3 * self.preload_n;
        let (mut a, mut b);
        loop {
            a = (mid - w).max(floor);
            b = mid + w;
            let (fa, fb) = (f(a)?, f(b)?);
            if fa <= 0.0 && fb >= 0.0 {
                break;
            }
            if fa > 0.0 && a <= floor {
                return Err(format!("slack: the cable cannot carry {m_nm} N m"));
            }
            w *= 2.0;
            if w > 1e3 * self.preload_n {
                return Err("no tension balances the load".into());
            }
        }
        // Illinois regula falsi: bracketing, superlinear.
        let (mut fa, mut fb) = (f(a)?, f(b)?);
        let mut side = 0;
        for _ in 0..200 {
            if b - a <= 1e-12 * self.preload_n {
                break;
            }
            let c = if fb != fa {
                (a * fb - b * fa) / (fb - fa)
            } else {
                0.5 * (a + b)
            };
            let c = if c > a && c < b { c } else { 0.5 * (a + b) };
            let fc = f(c)?;
            if fc == 0.0 {
                a = c;
                b = c;
                break;
            }
            if fc < 0.0 {
                a = c;
                fa = fc;
                if side == -1 {
                    fb *= 0.5;
                }
                side = -1;
            } else {
                b = c;
                fb = fc;
                if side == 1 {
                    fa *= 0.5;
                }
                side = 1;
            }
        }
        let tu = 0.5 * (a + b);
        let (d, slip_u) = self.elongation(&self.upper, tu);
        let (_, slip_l) = self.elongation(&self.lower, tu - dt);
        if slip_u || slip_l {
            return Err(format!(
                "gross slip on the pulley ({} half) at {m_nm} N m",
                if slip_u { "upper" } else { "lower" }
            ));
        }
        for (h, tb) in [(&mut self.upper, tu), (&mut self.lower, tu - dt)] {
            h.drum.commit(tb);
            h.pulley.commit(tb);
        }
        Ok(-d / self.ro)
    }
}

/// Reversal jump of physics.md section 6 (mrad, signed: negative, the output lags): the
/// change of transmission error when the load goes from `-M` back to `+M` after `+M, -M`,
/// on the paper bench with `preload_n`.
pub fn oracle_jump_mrad(m_nm: f64, preload_n: f64, nodes: usize) -> Result<f64, String> {
    let ro = 0.1025;
    let ri = 0.020;
    let l: f64 = 0.1450595;
    let span = (l * l - (ro + ri) * (ro + ri)).sqrt();
    let spec = GridSpec {
        ri_m: ri,
        ro_m: ro,
        span_m: span,
        modulus_n: 1.4e4,
        mu: 0.2,
        preload_n,
        drum_wrap_rad: PI,
        pulley_wrap_rad: 6.0 * PI,
    };
    let mut d = GridDrive::new(&spec, nodes);
    d.apply(m_nm)?;
    let e1 = d.apply(-m_nm)?;
    let e2 = d.apply(m_nm)?;
    Ok((e2 - e1) * 1e3)
}

/// Free span of each half from the geometry (physics.md section 1), m.
fn free_span_m(d: &cable_servo::physics::DriveParams) -> f64 {
    let r = match d.routing {
        cable_servo::physics::Routing::FigureEight => d.drum_radius_m + d.pulley_radius_m,
        cable_servo::physics::Routing::Open => d.drum_radius_m - d.pulley_radius_m,
    };
    (d.center_distance_m.powi(2) - r * r).max(0.0).sqrt()
}

/// A decaying oscillation after every reversal: a resonance outside the effect library.
#[derive(Clone, Copy, Debug)]
pub struct Ringing {
    /// Initial amplitude, rad.
    pub amplitude_rad: f64,
    /// Frequency, Hz.
    pub frequency_hz: f64,
    /// Decay time constant, s.
    pub decay_s: f64,
}

/// A friction-memory contact whose lag after a long travel is `lag_rad_per_nm_p * |M|^p`.
#[derive(Clone, Copy, Debug)]
pub struct MemoryLoad {
    /// Lag at 1 N m, rad.
    pub lag_rad_per_nm_p: f64,
    /// Growth exponent `p`.
    pub exponent: f64,
}

/// The instrument behind a log: what the truth used, against which estimates are checked.
#[derive(Clone, Copy, Debug)]
pub struct Instrument {
    /// Friction coefficient.
    pub friction_coefficient: f64,
    /// Preload, N.
    pub preload_n: f64,
    /// Tensile stiffness `E*A`, N.
    pub cable_modulus_n: f64,
}

/// How the truth is made and recorded.
#[derive(Clone, Debug)]
pub struct TruthOptions {
    /// Record length, s (the scenario's when None).
    pub duration_s: Option<f64>,
    /// Log rate, Hz (the scenario's when None).
    pub sample_rate_hz: Option<f64>,
    /// Truth steps per log sample.
    pub substeps: usize,
    /// Grid nodes per wrap region.
    pub nodes: usize,
    /// Seed of the instrument (its parameters, runout phases, shapes, contacts); the log's
    /// seed when None, so logs of one instrument share it.
    pub instrument_seed: Option<u64>,
    /// Relative spread of friction coefficient and preload about the scenario's (uniform).
    pub friction_preload_spread: f64,
    /// Relative spread of the cable modulus about the scenario's (uniform).
    pub modulus_spread: f64,
    /// The instrument, when given: overrides the draw.
    pub instrument: Option<Instrument>,
    /// Encoder counts per revolution.
    pub input_counts_per_rev: f64,
    pub output_counts_per_rev: f64,
    /// White noise on each angle, rad.
    pub angle_noise_rad: f64,
    /// 1/f noise on the output reading (sum of first-order processes from 0.03 to 30 s), rad
    /// RMS.
    pub pink_noise_rad: f64,
    /// Random-walk drift of the output reading: its RMS at the end of the record, rad.
    pub drift_rad: f64,
    /// White noise on the load cell, N m.
    pub load_noise_nm: f64,
    /// Random-walk drift of the load cell's offset, RMS at the end of the record, N m.
    pub load_drift_nm: f64,
    /// Single-sample outliers on the output reading and their size range, rad.
    pub outliers: usize,
    pub outlier_rad: (f64, f64),
    /// Unmodelled resonance.
    pub ringing: Option<Ringing>,
    /// A friction-memory contact whose lag grows with the load.
    pub memory_load: Option<MemoryLoad>,
}

impl Default for TruthOptions {
    fn default() -> Self {
        TruthOptions {
            duration_s: None,
            sample_rate_hz: None,
            substeps: 4,
            nodes: 600,
            instrument_seed: None,
            friction_preload_spread: 0.02,
            modulus_spread: 0.10,
            instrument: None,
            input_counts_per_rev: 65536.0,
            output_counts_per_rev: 1_048_576.0,
            angle_noise_rad: 1e-6,
            pink_noise_rad: 1e-6,
            drift_rad: 2e-6,
            load_noise_nm: 0.002,
            load_drift_nm: 0.001,
            outliers: 3,
            outlier_rad: (2e-5, 6e-5),
            ringing: None,
            memory_load: None,
        }
    }
}

/// A log and the instrument that made it.
#[derive(Clone, Debug)]
pub struct TruthLog {
    pub log: BenchLog,
    pub instrument: Instrument,
}

/// Play operator of half-width `r` on one new input `x`, state `y`.
fn play_step(y: &mut f64, x: f64, r: f64) -> f64 {
    *y = y.clamp(x - r, x + r);
    *y
}

/// Sum of first-order processes with log-spaced time constants: about 1/f between them.
fn pink(n: usize, dt: f64, rms: f64, rng: &mut impl Rng) -> Vec<f64> {
    let mut out = vec![0.0; n];
    if rms <= 0.0 {
        return out;
    }
    let taus = [0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0];
    let unit = Normal::new(0.0, 1.0).expect("unit normal");
    let share = rms / (taus.len() as f64).sqrt();
    for tau in taus {
        let a = (-dt / tau).exp();
        let s = (1.0 - a * a).sqrt();
        let mut x: f64 = unit.sample(rng);
        for o in out.iter_mut() {
            x = a * x + s * unit.sample(rng);
            *o += share * x;
        }
    }
    out
}

fn random_walk(n: usize, end_rms: f64, rng: &mut impl Rng) -> Vec<f64> {
    let mut out = vec![0.0; n];
    if end_rms <= 0.0 || n < 2 {
        return out;
    }
    let step = Normal::new(0.0, end_rms / ((n - 1) as f64).sqrt()).expect("step");
    for k in 1..n {
        out[k] = out[k - 1] + step.sample(rng);
    }
    out
}

/// A bench log of the scenario's drive, load and `quasi_static.motion` with hidden effects
/// (sizes in the units of [`EffectName::unit`]), made by the independent truth.
pub fn truth_log(
    sc: &Scenario,
    effects: &[(EffectName, f64)],
    seed: u64,
    o: &TruthOptions,
) -> Result<TruthLog, String> {
    let qs = sc
        .quasi_static
        .as_ref()
        .ok_or("the truth needs a [quasi_static] section")?;
    let dur = o.duration_s.unwrap_or(qs.duration_s);
    let rate = o.sample_rate_hz.unwrap_or(qs.sample_rate_hz);
    let sub = o.substeps.max(1);
    let n = (dur * rate).round() as usize + 1;
    let nf = (n - 1) * sub + 1;
    let dtf = 1.0 / (rate * sub as f64);
    let get = |e: EffectName| effects.iter().find(|x| x.0 == e).map(|x| x.1);

    let mut irng = rand::rngs::StdRng::seed_from_u64(o.instrument_seed.unwrap_or(seed) ^ 0x5eed);
    let mut nrng = rand::rngs::StdRng::seed_from_u64(seed.wrapping_mul(6364136223846793005) ^ 1);
    let d = &sc.drive;
    let mut spread = |s: f64| 1.0 + irng.gen_range(-s..=s);
    let inst = o.instrument.unwrap_or(Instrument {
        friction_coefficient: d.friction_coefficient * spread(o.friction_preload_spread),
        preload_n: d.preload_n * spread(o.friction_preload_spread),
        cable_modulus_n: d.cable_modulus_n * spread(o.modulus_spread),
    });
    let (ri, ro) = (d.pulley_radius_m, d.drum_radius_m);
    let ic = ro / ri;
    let spec = GridSpec {
        ri_m: ri,
        ro_m: ro,
        span_m: free_span_m(d),
        modulus_n: inst.cable_modulus_n,
        mu: inst.friction_coefficient,
        preload_n: inst.preload_n,
        drum_wrap_rad: d.drum_wrap_rad,
        pulley_wrap_rad: d.pulley_wrap_rad,
    };
    let mut cable = GridDrive::new(&spec, o.nodes);

    // The input and its direction on the fine grid.
    let tf: Vec<f64> = (0..nf).map(|i| i as f64 * dtf).collect();
    let mut th = Vec::with_capacity(nf);
    let mut dir = Vec::with_capacity(nf);
    let mut cur = 1.0;
    for t in &tf {
        let p = qs.motion.at(*t);
        if p.rate != 0.0 {
            cur = p.rate.signum();
        }
        th.push(p.value);
        dir.push(cur);
    }
    let lo = th.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = th.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let stroke = (hi - lo).max(1e-9);

    // Instrument draws, in a fixed order so that one instrument seed gives one instrument.
    let phase_in = irng.gen_range(-PI..PI);
    let phase_out = irng.gen_range(-PI..PI);
    let shape_f = irng.gen_range(0.5..0.9);
    let shape_a = irng.gen_range(0.0..TAU);
    // Two contacts between grid thresholds (geometric 0.4 % to 20 % of the stroke, eight
    // of them): grid index positions at least a quarter step from any grid point.
    let off_grid = |rng: &mut rand::rngs::StdRng| {
        let k = rng.gen_range(0..7) as f64 + rng.gen_range(0.25..0.75);
        stroke * 0.004 * 50f64.powf(k / 7.0)
    };
    let contacts = [off_grid(&mut irng), off_grid(&mut irng)];
    let split = irng.gen_range(0.2..0.8);
    let mem_load_r = off_grid(&mut irng);

    let mb = get(EffectName::BearingFriction).unwrap_or(0.0);
    let relax = get(EffectName::PreloadRelaxation);
    let transport = get(EffectName::CableTransport);

    // The ratio shape: cos(pi f u + a) over the stroke, less its mean and slope (those are
    // an offset and a ratio), scaled to the RMS asked for.
    let shape = get(EffectName::AngleDependentRatio).map(|v| {
        let m = 4001;
        let us: Vec<f64> = (0..m)
            .map(|k| -1.0 + 2.0 * k as f64 / (m - 1) as f64)
            .collect();
        let raw = |u: f64| (PI * shape_f * u + shape_a).cos();
        let mean = us.iter().map(|u| raw(*u)).sum::<f64>() / m as f64;
        let slope =
            us.iter().map(|u| raw(*u) * u).sum::<f64>() / us.iter().map(|u| u * u).sum::<f64>();
        let rms = (us
            .iter()
            .map(|u| (raw(*u) - mean - slope * u).powi(2))
            .sum::<f64>()
            / m as f64)
            .sqrt();
        (mean, slope, v / rms)
    });

    let mut th_out: Vec<TruthSample> = Vec::with_capacity(nf);
    let mut load = Vec::with_capacity(nf);
    let mut y_tr = 0.0;
    let mut plays = [th[0]; 3];
    let mut last_rev: Option<f64> = None;
    for i in 0..nf {
        let t = tf[i];
        let x = th[i];
        if let Some(r) = relax {
            cable.set_preload(inst.preload_n * (1.0 - r * t).max(0.05));
        }
        let ml = sc.load.quasi_static_torque_nm(t, x / ic, dir[i]);
        let m = -ml + mb * dir[i];
        let e = cable.apply(m).map_err(|s| format!("t = {t} s: {s}"))?;
        // Transport: dy/dx = (e - y)/theta_c in input travel x, e linear over the step.
        let e_tr = match transport {
            Some(tc) if i > 0 => {
                let dx = (x - th[i - 1]).abs();
                let e0 = th_out[i - 1].e;
                if dx > 0.0 {
                    let beta = (-dx / tc).exp();
                    let slope = (e - e0) / dx;
                    y_tr = e - slope * tc + (y_tr - e0 + slope * tc) * beta;
                }
                y_tr
            }
            Some(_) => {
                y_tr = e;
                e
            }
            None => e,
        };
        let mut out = x / ic + e_tr;
        if let Some(eps) = get(EffectName::InputPulleyRunout) {
            out += eps / ic * ((x + phase_in).sin() - phase_in.sin());
        }
        if let Some((mean, slope, k)) = shape {
            let u = 2.0 * (x - lo) / stroke - 1.0;
            out += k * ((PI * shape_f * u + shape_a).cos() - mean - slope * u);
        }
        if let Some(c) = get(EffectName::LoadCompliance) {
            out += c * m;
        }
        if let Some(v) = get(EffectName::DistributedFrictionMemory) {
            let w = [v * split / contacts[0], v * (1.0 - split) / contacts[1]];
            for k in 0..2 {
                out += w[k] * (play_step(&mut plays[k], x, contacts[k]) - x);
            }
        }
        if let Some(ml) = o.memory_load {
            let lag = play_step(&mut plays[2], x, mem_load_r) - x;
            out += ml.lag_rad_per_nm_p / mem_load_r * m.abs().powf(ml.exponent) * lag;
        }
        if let Some(r) = o.ringing {
            if i > 0 && dir[i] != dir[i - 1] {
                last_rev = Some(t);
            }
            if let Some(t0) = last_rev {
                let s = t - t0;
                out += r.amplitude_rad * (-s / r.decay_s).exp() * (TAU * r.frequency_hz * s).sin();
            }
        }
        if let Some(eps) = get(EffectName::OutputDrumRunout) {
            // The drum pays out ro (1 + eps cos(theta + phi)) per radian: solve
            // theta + eps (sin(theta + phi) - sin phi) = out for theta.
            let mut y = out;
            for _ in 0..8 {
                let g = y + eps * ((y + phase_out).sin() - phase_out.sin()) - out;
                y -= g / (1.0 + eps * (y + phase_out).cos());
            }
            out = y;
        }
        th_out.push(TruthSample { out, e });
        load.push(ml);
    }

    // Readings at the log's instants.
    let dt = 1.0 / rate;
    let white = Normal::new(0.0, o.angle_noise_rad.max(0.0)).map_err(|e| e.to_string())?;
    let lwhite = Normal::new(0.0, o.load_noise_nm.max(0.0)).map_err(|e| e.to_string())?;
    let pink_out = pink(n, dt, o.pink_noise_rad, &mut nrng);
    let walk_out = random_walk(n, o.drift_rad, &mut nrng);
    let walk_load = random_walk(n, o.load_drift_nm, &mut nrng);
    let mut spikes = vec![0.0; n];
    for _ in 0..o.outliers {
        let k = nrng.gen_range(n / 20..n);
        let s = nrng.gen_range(o.outlier_rad.0..=o.outlier_rad.1);
        spikes[k] += if nrng.gen_bool(0.5) { s } else { -s };
    }
    let quant = |v: f64, counts: f64| {
        if counts > 0.0 {
            let q = TAU / counts;
            (v / q).round() * q
        } else {
            v
        }
    };
    // Outside the record the axis was moving: the end step's slope continued, not the
    // end value held.
    let out_at = |ts: f64| {
        let p = ts / dtf;
        let j = (p.max(0.0).floor() as usize).min(nf - 2);
        let f = p - j as f64;
        th_out[j].out + f * (th_out[j + 1].out - th_out[j].out)
    };
    let mut log = BenchLog {
        source: format!("truth(seed={seed})"),
        comments: vec![format!(
            "independent truth: scenario {}, effects {:?}, seed {seed}",
            sc.name.as_deref().unwrap_or("unnamed"),
            effects
        )],
        ..BenchLog::default()
    };
    for k in 0..n {
        let t = k as f64 * dt;
        let i = k * sub;
        let mut read = match get(EffectName::EncoderDelay) {
            Some(tau) => out_at(t - tau),
            None => th_out[i].out,
        };
        if let Some(s) = get(EffectName::EncoderScaleError) {
            read *= 1.0 + s;
        }
        if let Some(dr) = get(EffectName::ThermalDrift) {
            read += dr * t;
        }
        read += pink_out[k] + walk_out[k] + spikes[k] + white.sample(&mut nrng);
        log.t_s.push(t);
        log.theta_in_rad.push(quant(
            th[i] + white.sample(&mut nrng),
            o.input_counts_per_rev,
        ));
        log.theta_out_rad.push(quant(read, o.output_counts_per_rev));
        log.load_nm
            .push(load[i] + walk_load[k] + lwhite.sample(&mut nrng));
    }
    Ok(TruthLog {
        log,
        instrument: inst,
    })
}

#[derive(Clone, Copy, Debug)]
struct TruthSample {
    /// True output angle, rad.
    out: f64,
    /// Cable transmission error before transport, rad.
    e: f64,
}
