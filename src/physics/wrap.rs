//! Cable wrapped on a pulley or drum, with exact capstan memory.
//!
//! The tension profile `T(s)` along the wrap (`s` = wrap angle from the contact point
//! inward, rad) is held in log space, `g(s) = ln T(s)`. Coulomb friction bounds the slope,
//! `|dg/ds| <= mu`, and a new boundary tension `Tb` updates the profile by
//! `g_new(s) = clamp(g_old(s), ln Tb - mu*s, ln Tb + mu*s)` (physics.md section 3).
//! Every profile reachable from the flat preloaded state is piecewise linear in `s` with
//! slopes `-mu`, `0`, `+mu`, so it is stored exactly as a short list of breakpoints, one per
//! un-wiped reversal, and every integral is analytic per segment.

/// One breakpoint of the log-tension profile.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Vertex {
    /// Wrap angle from the contact point, rad.
    s: f64,
    /// Log-tension `ln T(s)`, with `T` in newtons.
    g: f64,
    /// Tension `exp(g)`, N, kept to spare the exponential in every trial.
    t: f64,
    /// `sum_regions r * integral_s^wrap (T - Tpre) ds`, N m: lets a trial profile reuse the
    /// stuck part.
    tail: f64,
}

/// Outcome of putting a boundary tension on a wrap, without committing it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WrapTrial {
    /// Elongation of the wrapped cable relative to the preloaded state, m.
    pub elongation_m: f64,
    /// Derivative of the elongation with respect to the boundary tension, m/N.
    pub d_elongation_m_per_n: f64,
    /// Length of the slip zone (wrap angle where the new branch meets the old profile), rad,
    /// at most the longest wrap. Zero when the boundary tension is unchanged.
    pub slip_angle_rad: f64,
    /// True when the slip zone reaches the inner end of the longest wrap.
    pub reaches_end: bool,
    /// Where the new branch meets the stored profile, kept so that committing this trial
    /// needs no second search.
    crossing: Crossing,
}

impl WrapTrial {
    /// Slip-zone length within a region of wrap `wrap_rad`, rad.
    pub fn slip_within(&self, wrap_rad: f64) -> f64 {
        self.slip_angle_rad.min(wrap_rad)
    }

    /// Whether the slip zone reaches the inner end of a region of wrap `wrap_rad`.
    pub fn reaches(&self, wrap_rad: f64) -> bool {
        self.slip_angle_rad >= wrap_rad
    }
}

/// Meeting point of a new slip zone with the stored profile.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
struct Crossing {
    /// Index of the first stored breakpoint beyond the meeting point (`usize::MAX`: the zone
    /// reaches the inner end; `NO_SLIP`: boundary tension unchanged).
    index: usize,
    /// Wrap angle of the meeting point, rad.
    s: f64,
    /// Log-tension there.
    g: f64,
    /// Tension there, N.
    t: f64,
    /// Boundary tension, N.
    tb: f64,
    /// Log of the boundary tension.
    ln_tb: f64,
    /// Whether the boundary tension rose (slip zone `Tb*exp(-mu*s)`).
    rising: bool,
}

/// `Crossing::index` value for a trial that leaves the profile unchanged.
const NO_SLIP: usize = usize::MAX - 1;

/// Cable wrapped on one or two surfaces that see the same boundary tension history.
///
/// A cable half wraps the drum (up to its anchor) and the pulley (up to the neutral point),
/// both starting at the same free-span tension. The memory rule acts pointwise in `s`, so
/// both profiles are the same function of `s`, cut at different lengths: one profile is
/// stored and each region integrates it up to its own wrap with its own radius. For a
/// single region pass one `(radius, wrap)` pair.
///
/// Typical values: drum wrap `pi` rad at radius 0.1025 m; pulley half-wrap `3*pi` rad at
/// radius 0.020 m; friction coefficient 0.2; preload 100 N; cable modulus `E*A` 1.4e4 N.
#[derive(Clone, Debug)]
pub struct WrapRegion {
    mu: f64,
    preload_n: f64,
    modulus_n: f64,
    /// Shorter wrap, rad (equal to `wrap_rad` for a single region).
    cut_rad: f64,
    /// Longest wrap, where the stored profile ends, rad.
    wrap_rad: f64,
    /// Sum of radii of regions covering `s < cut_rad`, m.
    weight_inner_m: f64,
    /// Radius of the region covering `cut_rad <= s < wrap_rad`, m.
    weight_outer_m: f64,
    /// `exp(-mu*cut)` and `exp(mu*cut)`, for slip zones that pass the shorter wrap's end.
    decay_at_cut: f64,
    growth_at_cut: f64,
    /// Breakpoints ordered from the inner end (`s = wrap`) to the contact point (`s = 0`),
    /// so that a new slip zone pops the wiped breakpoints off the end of the vector. A
    /// breakpoint always sits at `cut_rad`, so every segment has a single weight.
    verts: Vec<Vertex>,
}

/// `integral_0^h exp(ga + (gb - ga) * x / h) dx`: exact for a log-linear segment whose
/// end tensions are `ta = exp(ga)` and `tb = exp(gb)`.
#[inline]
fn segment_integral(h: f64, ga: f64, gb: f64, ta: f64, tb: f64) -> f64 {
    let delta = gb - ga;
    if delta.abs() < 1e-9 {
        // Series of expm1(d)/d keeps full precision on nearly flat segments.
        h * ta * (1.0 + 0.5 * delta + delta * delta / 6.0)
    } else {
        h * (tb - ta) / delta
    }
}

impl WrapRegion {
    /// A single virgin region at uniform preload.
    ///
    /// Parameters must be positive and finite (checked by scenario validation upstream).
    pub fn new(radius_m: f64, wrap_rad: f64, mu: f64, preload_n: f64, modulus_n: f64) -> Self {
        Self::with_regions(&[(radius_m, wrap_rad)], mu, preload_n, modulus_n)
    }

    /// One or two regions `(radius m, wrap rad)` sharing a boundary tension. More than two
    /// are not needed by a cable half; extra entries are ignored.
    pub fn with_regions(regions: &[(f64, f64)], mu: f64, preload_n: f64, modulus_n: f64) -> Self {
        let (a, b) = match regions {
            [] => ((0.0, 0.0), None),
            [one] => (*one, None),
            [x, y, ..] => (*x, Some(*y)),
        };
        let (cut_rad, wrap_rad, weight_inner_m, weight_outer_m) = match b {
            None => (a.1, a.1, a.0, a.0),
            Some(b) if a.1 == b.1 => (a.1, a.1, a.0 + b.0, a.0 + b.0),
            Some(b) => {
                let (short, long) = if a.1 < b.1 { (a, b) } else { (b, a) };
                (short.1, long.1, short.0 + long.0, long.0)
            }
        };
        let mut region = WrapRegion {
            mu,
            preload_n,
            modulus_n,
            cut_rad,
            wrap_rad,
            weight_inner_m,
            weight_outer_m,
            decay_at_cut: (-mu * cut_rad).exp(),
            growth_at_cut: (mu * cut_rad).exp(),
            verts: Vec::with_capacity(16),
        };
        region.reset();
        region
    }

    /// Forget all history: back to the uniform preloaded profile.
    pub fn reset(&mut self) {
        let g = self.preload_n.ln();
        let t = self.preload_n;
        self.verts.clear();
        for s in [self.wrap_rad, self.cut_rad, 0.0] {
            if self.verts.last().is_none_or(|v| v.s > s) {
                self.verts.push(Vertex { s, g, t, tail: 0.0 });
            }
        }
    }

    /// Longest wrap angle, rad.
    pub fn wrap_rad(&self) -> f64 {
        self.wrap_rad
    }

    /// Number of breakpoints currently held (grows by one per un-wiped reversal).
    pub fn breakpoint_count(&self) -> usize {
        self.verts.len()
    }

    /// Tension at the contact point (the boundary tension last committed), N.
    pub fn boundary_tension_n(&self) -> f64 {
        self.verts[self.verts.len() - 1].t
    }

    /// Weight (sum of radii, m) of the segment ending at wrap angle `s_end`.
    #[inline]
    fn weight(&self, s_end: f64) -> f64 {
        if s_end <= self.cut_rad {
            self.weight_inner_m
        } else {
            self.weight_outer_m
        }
    }

    /// Where the line `ln Tb -+ mu*s` first meets the stored profile.
    ///
    /// Returns `(index of the first breakpoint beyond the crossing, s*, g*, T*)`; the index
    /// is `usize::MAX` when the new slip zone reaches the inner end.
    #[inline]
    fn crossing(&self, ln_tb: f64, rising: bool) -> (usize, f64, f64, f64) {
        let slope = if rising { -self.mu } else { self.mu };
        // For a rising boundary, d(s) = g_old(s) - line(s) is non-decreasing (the old profile
        // obeys the slope bound), so the first breakpoint with d >= 0 closes the crossing
        // segment. Mirror image for a falling boundary.
        let sign = if rising { 1.0 } else { -1.0 };
        let top = self.verts.len() - 1;
        let mut d_prev = sign * (self.verts[top].g - ln_tb);
        let mut k = top;
        while k > 0 {
            let b = self.verts[k - 1];
            let d_b = sign * (b.g - (ln_tb + slope * b.s));
            if d_b >= 0.0 {
                let a = self.verts[k];
                let frac = if d_b > d_prev {
                    (-d_prev / (d_b - d_prev)).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                let s_star = a.s + (b.s - a.s) * frac;
                let g_star = ln_tb + slope * s_star;
                // On the untouched plateau the tension is known exactly.
                let t_star = if a.g == b.g { b.t } else { g_star.exp() };
                return (k - 1, s_star, g_star, t_star);
            }
            d_prev = d_b;
            k -= 1;
        }
        let g_end = ln_tb + slope * self.wrap_rad;
        (usize::MAX, self.wrap_rad, g_end, g_end.exp())
    }

    /// Weighted integral of `T - Tpre` over the slip zone `[0, s*]` and its derivative with
    /// respect to `Tb`: closed forms of `Tb*exp(-+mu*s)`, split at the shorter wrap's end.
    #[inline]
    fn slip_zone(&self, c: &Crossing) -> (f64, f64) {
        let (mu, pre) = (self.mu, self.preload_n);
        // integral_x0^x1 T ds for T = Tb*exp(-+mu*s), given T at both ends.
        let line = |t0: f64, t1: f64| {
            if c.rising {
                (t0 - t1) / mu
            } else {
                (t1 - t0) / mu
            }
        };
        if c.s <= self.cut_rad {
            let w = self.weight_inner_m;
            (w * (line(c.tb, c.t) - pre * c.s), w * line(1.0, c.t / c.tb))
        } else {
            let e = if c.rising {
                self.decay_at_cut
            } else {
                self.growth_at_cut
            };
            let t_cut = c.tb * e;
            let (wi, wo) = (self.weight_inner_m, self.weight_outer_m);
            (
                wi * (line(c.tb, t_cut) - pre * self.cut_rad)
                    + wo * (line(t_cut, c.t) - pre * (c.s - self.cut_rad)),
                wi * line(1.0, e) + wo * line(e, c.t / c.tb),
            )
        }
    }

    /// Elongation and its derivative if the boundary tension became `tb_n` (N > 0), the
    /// stored profile left unchanged.
    #[inline]
    pub fn trial(&self, tb_n: f64) -> WrapTrial {
        let ln_tb = tb_n.ln();
        let top = self.verts.len() - 1;
        let g0 = self.verts[top].g;
        if ln_tb == g0 {
            return WrapTrial {
                elongation_m: self.verts[top].tail / self.modulus_n,
                d_elongation_m_per_n: 0.0,
                slip_angle_rad: 0.0,
                reaches_end: false,
                crossing: Crossing {
                    index: NO_SLIP,
                    tb: tb_n,
                    ln_tb,
                    ..Crossing::default()
                },
            };
        }
        let rising = ln_tb > g0;
        let (index, s, g, t) = self.crossing(ln_tb, rising);
        let crossing = Crossing {
            index,
            s,
            g,
            t,
            tb: tb_n,
            ln_tb,
            rising,
        };
        let (mut integral, d_integral) = self.slip_zone(&crossing);
        let reaches_end = index == usize::MAX;
        if !reaches_end {
            let b = self.verts[index];
            let h = b.s - s;
            integral += self.weight(b.s)
                * (segment_integral(h, g, b.g, t, b.t) - self.preload_n * h)
                + b.tail;
        }
        WrapTrial {
            elongation_m: integral / self.modulus_n,
            d_elongation_m_per_n: d_integral / self.modulus_n,
            slip_angle_rad: s,
            reaches_end,
            crossing,
        }
    }

    /// Commit a boundary tension `tb_n` (N > 0): the slip zone replaces the part of the
    /// profile it wipes out.
    pub fn commit(&mut self, tb_n: f64) {
        let trial = self.trial(tb_n);
        self.commit_trial(&trial);
    }

    /// Commit a trial computed on the current profile (saves searching the crossing again).
    pub fn commit_trial(&mut self, trial: &WrapTrial) {
        let c = trial.crossing;
        if c.index == NO_SLIP {
            return;
        }
        let pre = self.preload_n;
        if c.index == usize::MAX {
            self.verts.clear();
            self.verts.push(Vertex {
                s: self.wrap_rad,
                g: c.g,
                t: c.t,
                tail: 0.0,
            });
        } else {
            self.verts.truncate(c.index + 1);
            let b = self.verts[c.index];
            // A crossing at an existing breakpoint would leave a zero-length segment.
            if b.s - c.s > 1e-14 * self.wrap_rad.max(1.0) {
                let h = b.s - c.s;
                let tail =
                    self.weight(b.s) * (segment_integral(h, c.g, b.g, c.t, b.t) - pre * h) + b.tail;
                self.verts.push(Vertex {
                    s: c.s,
                    g: c.g,
                    t: c.t,
                    tail,
                });
            }
        }
        let slope = if c.rising { -self.mu } else { self.mu };
        let line_integral = |t0: f64, t1: f64, h: f64| {
            (if c.rising { t0 - t1 } else { t1 - t0 }) / self.mu - pre * h
        };
        let last = self.verts[self.verts.len() - 1];
        if c.s > self.cut_rad && last.s > self.cut_rad {
            // Keep the breakpoint at the shorter wrap's end: segments must not straddle it.
            let g_cut = c.ln_tb + slope * self.cut_rad;
            let t_cut = c.tb
                * if c.rising {
                    self.decay_at_cut
                } else {
                    self.growth_at_cut
                };
            let tail = self.weight_outer_m * line_integral(t_cut, last.t, last.s - self.cut_rad)
                + last.tail;
            self.verts.push(Vertex {
                s: self.cut_rad,
                g: g_cut,
                t: t_cut,
                tail,
            });
        }
        let last = self.verts[self.verts.len() - 1];
        if last.s > 0.0 {
            let tail = self.weight(last.s) * line_integral(c.tb, last.t, last.s) + last.tail;
            self.verts.push(Vertex {
                s: 0.0,
                g: c.ln_tb,
                t: c.tb,
                tail,
            });
        } else {
            // Zero-length slip zone (only when the crossing is at s = 0).
            let top = self.verts.len() - 1;
            self.verts[top].g = c.ln_tb;
            self.verts[top].t = c.tb;
        }
    }

    /// Elongation of the wrapped cable as committed, relative to the preloaded state, m.
    pub fn elongation_m(&self) -> f64 {
        self.verts[self.verts.len() - 1].tail / self.modulus_n
    }

    /// Tension at wrap angle `s_rad` (clamped to the wrap), N.
    pub fn tension_at(&self, s_rad: f64) -> f64 {
        let s = s_rad.clamp(0.0, self.wrap_rad);
        for k in (1..self.verts.len()).rev() {
            let a = self.verts[k];
            let b = self.verts[k - 1];
            if s <= b.s {
                let h = b.s - a.s;
                let g = if h > 0.0 {
                    a.g + (b.g - a.g) * (s - a.s) / h
                } else {
                    b.g
                };
                return g.exp();
            }
        }
        self.verts[0].t
    }

    /// The committed profile's breakpoints as `(wrap angle rad, tension N)` from the contact
    /// point inward up to `wrap_rad` (a region's own wrap; clamped to the stored profile).
    /// Exact: straight lines between them in `(s, ln T)`.
    pub fn breakpoints_within(&self, wrap_rad: f64) -> Vec<(f64, f64)> {
        let end = wrap_rad.min(self.wrap_rad);
        let mut out: Vec<(f64, f64)> = self
            .verts
            .iter()
            .rev()
            .filter(|v| v.s < end)
            .map(|v| (v.s, v.t))
            .collect();
        out.push((end, self.tension_at(end)));
        out
    }

    /// `integral_0^wrap (T - Tpre) ds` of the committed profile up to `wrap_rad` (clamped to
    /// the stored profile), N rad: times `radius / E*A` it is the elongation of a region
    /// that wraps that far.
    pub fn tension_integral_within(&self, wrap_rad: f64) -> f64 {
        let points = self.breakpoints_within(wrap_rad);
        points
            .windows(2)
            .map(|w| {
                let ((s0, t0), (s1, t1)) = (w[0], w[1]);
                let h = s1 - s0;
                segment_integral(h, t0.ln(), t1.ln(), t0, t1) - self.preload_n * h
            })
            .sum()
    }

    /// The whole committed profile's breakpoints, `(wrap angle rad, tension N)`.
    pub fn breakpoints(&self) -> Vec<(f64, f64)> {
        self.breakpoints_within(self.wrap_rad)
    }

    /// Largest magnitude of the log-tension slope over all segments, 1/rad. Never exceeds
    /// the friction coefficient (up to rounding).
    pub fn max_log_slope(&self) -> f64 {
        self.verts
            .windows(2)
            .filter(|w| w[0].s - w[1].s > 1e-12)
            .map(|w| ((w[0].g - w[1].g) / (w[0].s - w[1].s)).abs())
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `x - 1 - ln x`, written to keep its precision near `x = 1`.
    fn f(x: f64) -> f64 {
        let d = x - 1.0;
        d - d.ln_1p()
    }

    const R: f64 = 0.1;
    const MU: f64 = 0.2;
    const TPRE: f64 = 100.0;
    const G: f64 = 1.4e4;

    #[test]
    fn first_loading_matches_closed_form() {
        let region = WrapRegion::new(R, 20.0, MU, TPRE, G);
        for v in [1.001, 1.07, 1.5, 3.0] {
            let trial = region.trial(v * TPRE);
            let expect = R * TPRE / (G * MU) * f(v);
            // The slip integral and the preload term nearly cancel for tiny loads, so the
            // error floor is set by the size of those terms, not of their difference.
            let floor = 1e-12 * R * TPRE / (G * MU);
            let err = (trial.elongation_m - expect).abs();
            assert!(err < 1e-10 * expect.abs() + floor, "v {v}: err {err}");
            assert!((trial.slip_angle_rad - v.ln() / MU).abs() < 1e-12);
        }
    }

    #[test]
    fn first_unloading_matches_closed_form() {
        let region = WrapRegion::new(R, 20.0, MU, TPRE, G);
        for u in [0.999, 0.93, 0.5, 0.2] {
            let trial = region.trial(u * TPRE);
            let expect = -R * TPRE / (G * MU) * f(u);
            // The slip integral and the preload term nearly cancel for tiny loads, so the
            // error floor is set by the size of those terms, not of their difference.
            let floor = 1e-12 * R * TPRE / (G * MU);
            let err = (trial.elongation_m - expect).abs();
            assert!(err < 1e-10 * expect.abs() + floor, "u {u}: err {err}");
        }
    }

    #[test]
    fn reversal_with_surviving_bump_matches_closed_form() {
        let mut region = WrapRegion::new(R, 20.0, MU, TPRE, G);
        let (t1, t2) = (130.0, 90.0);
        assert!(t1 * t2 >= TPRE * TPRE);
        region.commit(t1);
        let before = region.elongation_m();
        region.commit(t2);
        let drop = before - region.elongation_m();
        let expect = R / (G * MU) * (t1.sqrt() - t2.sqrt()).powi(2);
        assert!((drop - expect).abs() <= 1e-12 * expect);
        // The bump sits at s_M = ln(T1/T2)/(2 mu) with tension sqrt(T1 T2).
        let s_m = (t1 / t2).ln() / (2.0 * MU);
        assert!((region.tension_at(s_m) - (t1 * t2).sqrt()).abs() < 1e-9);
        assert_eq!(region.breakpoint_count(), 4);
    }

    #[test]
    fn derivative_matches_finite_difference() {
        let mut region = WrapRegion::new(R, 2.0, MU, TPRE, G);
        for t in [140.0, 80.0, 120.0, 95.0] {
            region.commit(t);
        }
        for tb in [60.0, 97.0, 105.0, 118.0, 125.0, 200.0, 400.0] {
            let h = 1e-5 * tb;
            let num =
                (region.trial(tb + h).elongation_m - region.trial(tb - h).elongation_m) / (2.0 * h);
            let ana = region.trial(tb).d_elongation_m_per_n;
            assert!(
                (num - ana).abs() <= 1e-6 * ana.abs().max(1e-12),
                "tb {tb}: {num} vs {ana}"
            );
        }
    }

    #[test]
    fn committed_elongation_equals_trial() {
        let mut region = WrapRegion::new(R, 1.0, MU, TPRE, G);
        for t in [150.0, 70.0, 130.0, 110.0, 400.0, 20.0] {
            let trial = region.trial(t);
            region.commit(t);
            assert!((trial.elongation_m - region.elongation_m()).abs() < 1e-15);
        }
    }

    #[test]
    fn slip_to_the_end_cuts_the_profile() {
        let mut region = WrapRegion::new(R, 0.5, MU, TPRE, G);
        let trial = region.trial(200.0);
        assert!(trial.reaches_end);
        assert_eq!(trial.slip_angle_rad, 0.5);
        region.commit(200.0);
        assert!((region.tension_at(0.5) - 200.0 * (-MU * 0.5f64).exp()).abs() < 1e-9);
        // Integral of the cut line minus preload.
        let expect = R / G * (200.0 * (1.0 - (-MU * 0.5f64).exp()) / MU - TPRE * 0.5);
        assert!((region.elongation_m() - expect).abs() < 1e-15);
    }

    #[test]
    fn shared_profile_equals_two_separate_regions() {
        let mut rng_state = 12345u64;
        let mut next = || {
            rng_state = rng_state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (rng_state >> 11) as f64 / (1u64 << 53) as f64
        };
        let (rd, wd, rp, wp) = (0.1025, 0.9, 0.02, 2.5);
        let mut shared = WrapRegion::with_regions(&[(rd, wd), (rp, wp)], MU, TPRE, G);
        let mut drum = WrapRegion::new(rd, wd, MU, TPRE, G);
        let mut pulley = WrapRegion::new(rp, wp, MU, TPRE, G);
        for _ in 0..400 {
            // Wide swings so slip zones pass the shorter wrap's end and reach the longer one.
            let tb = TPRE * (0.35 + 1.6 * next());
            let tr = shared.trial(tb);
            let (a, b) = (drum.trial(tb), pulley.trial(tb));
            let sum = a.elongation_m + b.elongation_m;
            let dsum = a.d_elongation_m_per_n + b.d_elongation_m_per_n;
            // Elongations are small differences of integrals of size r*T*wrap/G: the
            // rounding floor scales with those.
            let floor = 1e-12 * (rd * wd + rp * wp) * TPRE / G;
            assert!(
                (tr.elongation_m - sum).abs() < floor,
                "{tb}: {} vs {sum}",
                tr.elongation_m
            );
            assert!((tr.d_elongation_m_per_n - dsum).abs() < 1e-9 * dsum.abs());
            assert_eq!(tr.reaches(wd), a.reaches_end);
            shared.commit_trial(&tr);
            drum.commit(tb);
            pulley.commit(tb);
            assert!(shared.max_log_slope() <= MU * (1.0 + 1e-9));
        }
    }

    #[test]
    fn region_integrals_add_up_to_the_committed_elongation() {
        let (rd, wd, rp, wp) = (0.1025, 0.9, 0.02, 2.5);
        let mut shared = WrapRegion::with_regions(&[(rd, wd), (rp, wp)], MU, TPRE, G);
        for tb in [130.0, 80.0, 120.0, 95.0, 240.0, 40.0, 101.0] {
            shared.commit(tb);
            let sum = (rd * shared.tension_integral_within(wd)
                + rp * shared.tension_integral_within(wp))
                / G;
            let floor = 1e-12 * (rd * wd + rp * wp) * TPRE / G;
            assert!((sum - shared.elongation_m()).abs() < floor, "{tb}");
        }
    }
}
