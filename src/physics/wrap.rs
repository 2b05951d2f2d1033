//! Cable wrapped on a pulley or drum, with exact capstan memory.
//!
//! The tension profile `T(s)` along the wrap (`s` = wrap angle from the contact point
//! inward, rad) obeys the Coulomb slope bound `|d ln T/ds| <= mu`, and a new boundary
//! tension `Tb` updates it by `ln T_new(s) = clamp(ln T_old(s), ln Tb - mu*s, ln Tb + mu*s)`
//! (physics.md section 3). Every profile reachable from the flat preloaded state is
//! piecewise exponential in `s` with log-slopes `-mu`, `0`, `+mu`, so it is stored exactly
//! as a short list of breakpoints, one per un-wiped reversal, and every integral is
//! analytic per segment.
//!
//! Along a segment of log-slope `-mu` the product `T*exp(mu*s)` is constant, along one of
//! slope `+mu` the product `T*exp(-mu*s)`. Keeping both products at every breakpoint makes
//! the search for where a new slip zone meets the stored profile a walk of comparisons,
//! and the meeting tension a square root (`T* = sqrt(Tb * T_a*exp(-+mu*s_a))`): trials
//! need no logarithm or exponential, except on the untouched preload plateau, whose
//! elongation law is the virgin curve with its logarithm. A commit needs no logarithm
//! either: integrals along segments of log-slope `+-mu` follow from their end tensions,
//! so a new breakpoint's angle is left to be computed when a report asks for it.
//!
//! The elongation as a function of `Tb` is one closed form for as long as the slip zone
//! ends on the same stored segment (`WrapLaw`). The region keeps the last law for loading
//! and the last for unloading; a load that keeps rising (or falling) across commits keeps
//! the same law, so most trials skip the walk altogether.
//!
//! This file is long (about 1200 lines of code and 400 of tests) because it is one
//! algorithm: the breakpoint list, its closed-form laws and the commit share invariants
//! that only hold together, and splitting them would spread one proof over several files.

use std::cell::Cell;

/// One breakpoint of the tension profile.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Vertex {
    /// Wrap angle from the contact point, rad; NaN where a slip zone met a sloped segment,
    /// as nothing on the hot path needs it there (it follows from `ln(p/m)/(2*mu)`, see
    /// [`WrapRegion::angle`]), which spares a commit its logarithm.
    s: f64,
    /// Tension `T(s)`, N.
    t: f64,
    /// `T*exp(mu*s)`, N: constant along a segment of log-slope `-mu`.
    p: f64,
    /// `T*exp(-mu*s)`, N: constant along a segment of log-slope `+mu`.
    m: f64,
    /// `sum_regions r * integral_s^wrap T ds`, N m: lets a trial profile reuse the stuck
    /// part. The preload's share is left out, so that sloped segments add to it without
    /// their lengths.
    tail: f64,
    /// Beyond the shorter wrap (`s > cut_rad`): the segment ending here, inward, has the
    /// longer region's weight only.
    outer: bool,
}

impl Vertex {
    /// The contact point after a commit of boundary tension `tb` (N), with `tail` (N m).
    #[inline(always)]
    fn contact(tb: f64, tail: f64) -> Vertex {
        Vertex {
            s: 0.0,
            t: tb,
            p: tb,
            m: tb,
            tail,
            outer: false,
        }
    }
}

/// Shape of the elongation law of a wrap around a boundary tension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LawKind {
    /// The slip zone ends on a stored segment of opposite log-slope: the meeting tension
    /// is `sqrt(Tb*q)`.
    Sloped,
    /// The slip zone ends on the untouched preload plateau (virgin curve).
    Plateau,
    /// The slip zone reaches the inner end of the longest wrap.
    End,
    /// The boundary tension equals the committed one: no slip zone.
    Stuck,
    /// Nothing cached.
    Invalid,
}

/// Elongation of a wrap as a closed-form function of the boundary tension `Tb`, valid
/// while the slip zone ends on one stored segment (between `lo` and `hi`).
///
/// `E*A * elongation = a*Tb + bt*x + c`, where `x` is the meeting tension `sqrt(Tb*q)` for
/// [`LawKind::Sloped`], the slip angle for [`LawKind::Plateau`] and 0 otherwise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct WrapLaw {
    kind: LawKind,
    /// The boundary tension rises above the committed one (slip zone `Tb*exp(-mu*s)`).
    rising: bool,
    /// Profile generation the law was built on.
    generation: u64,
    /// Index of the stored breakpoint that closes the segment where the slip zone ends.
    index: usize,
    /// Range of `Tb` where the law holds, N: `(lo, hi]` when rising, `[lo, hi)` when
    /// falling, exactly `lo` when stuck.
    lo: f64,
    hi: f64,
    /// Coefficients of `E*A * elongation`, see the type's documentation. On an `End` law
    /// `q` holds the tension at the inner end of the longest wrap per unit `Tb` instead:
    /// one field for both keeps the law within 128 bytes, which its copies (a cache slot
    /// per search, a solution per half) then make without a call to `memcpy`.
    a: f64,
    bt: f64,
    q: f64,
    c: f64,
    /// `bt * sqrt(q)`, the linear coefficient of the quadratic in `sqrt(Tb)`.
    beta: f64,
    /// Free-span length in series the law was built for, m, and `1/(2*(span + a))`:
    /// spares the division in the plant's solves.
    span_m: f64,
    inv_two_alpha: f64,
    /// For that span, the quadratic's discriminant as `disc0 + disc1 * target_m` (N^2 m^2,
    /// N^2 m) and its constant term as `rest0 - E*A * target_m` (N m): a prescribed
    /// elongation `target_m` (m) is one multiply-add from the square root.
    disc0: f64,
    disc1: f64,
    rest0: f64,
    /// Weight (sum of radii, m) of the segment where the slip zone ends.
    w_seg: f64,
}

impl WrapLaw {
    const INVALID: WrapLaw = WrapLaw {
        kind: LawKind::Invalid,
        rising: true,
        generation: u64::MAX,
        index: 0,
        lo: f64::NAN,
        hi: f64::NAN,
        a: 0.0,
        bt: 0.0,
        q: 0.0,
        c: 0.0,
        beta: 0.0,
        span_m: f64::NAN,
        inv_two_alpha: 0.0,
        disc0: f64::NAN,
        disc1: 0.0,
        rest0: 0.0,
        w_seg: 0.0,
    };

    /// `(a, beta, c)` such that `E*A * elongation = a*Tb + beta*sqrt(Tb) + c` on this
    /// law, when it has that form (sloped segment or slip to the end).
    #[inline]
    pub(crate) fn sqrt_form(&self) -> Option<(f64, f64, f64)> {
        match self.kind {
            LawKind::Sloped => Some((self.a, self.beta, self.c)),
            LawKind::End => Some((self.a, 0.0, self.c)),
            _ => None,
        }
    }

    /// Whether the law holds at boundary tension `tb_n`.
    #[inline]
    pub(crate) fn covers(&self, tb_n: f64) -> bool {
        match self.kind {
            LawKind::Invalid => false,
            LawKind::Stuck => tb_n == self.lo,
            _ if self.rising => self.lo < tb_n && tb_n <= self.hi,
            _ => self.lo <= tb_n && tb_n < self.hi,
        }
    }

    /// `E*A` times the elongation and its first two derivatives with respect to `Tb`, at
    /// `tb_n`: N m, m and m/N.
    #[inline]
    fn eval(&self, tb_n: f64, mu: f64, preload_n: f64) -> (f64, f64, f64) {
        match self.kind {
            LawKind::Sloped => {
                let ts = (self.q * tb_n).sqrt();
                let inv = 1.0 / tb_n;
                let half_slope = 0.5 * self.bt * ts * inv;
                (
                    self.a * tb_n + self.bt * ts + self.c,
                    self.a + half_slope,
                    -0.5 * half_slope * inv,
                )
            }
            LawKind::Plateau => {
                let sign = if self.rising { 1.0 } else { -1.0 };
                let s = sign * (tb_n / preload_n).ln() / mu;
                let slope = self.bt * sign / (mu * tb_n);
                (
                    self.a * tb_n + self.bt * s + self.c,
                    self.a + slope,
                    -slope / tb_n,
                )
            }
            LawKind::End => (self.a * tb_n + self.c, self.a, 0.0),
            LawKind::Stuck | LawKind::Invalid => (self.c, 0.0, 0.0),
        }
    }

    /// Tension where the slip zone meets the stored profile, N.
    #[inline]
    fn meeting_tension(&self, tb_n: f64, preload_n: f64) -> f64 {
        match self.kind {
            LawKind::Sloped => (self.q * tb_n).sqrt(),
            LawKind::Plateau => preload_n,
            LawKind::End => tb_n * self.q,
            LawKind::Stuck | LawKind::Invalid => tb_n,
        }
    }

    /// The root `t` of this law if it lies in its range, or within rounding of it (the
    /// law is continuous across its ends, so clamping costs nothing measurable).
    #[inline(always)]
    fn accept(&self, t: f64) -> Option<f64> {
        if self.covers(t) {
            return Some(t);
        }
        const SLACK: f64 = 1e-12;
        match self.kind {
            LawKind::Sloped | LawKind::Plateau | LawKind::End
                if t >= self.lo * (1.0 - SLACK) && t <= self.hi * (1.0 + SLACK) =>
            {
                Some(t.clamp(self.lo, self.hi))
            }
            _ => None,
        }
    }

    /// Boundary tension at which `span * (Tb - Tpre) + E*A*elongation(Tb)` equals
    /// `target` (N m; `span` is the free span's length in m), on this law's closed form:
    /// a quadratic in `sqrt(Tb)` on a sloped segment, linear past the end, Newton from
    /// `start` on the plateau's virgin curve. `None` when the law has no such root.
    #[inline(always)]
    fn solve(&self, target: f64, span: f64, preload_n: f64, mu: f64, start: f64) -> Option<f64> {
        if self.kind != LawKind::Sloped {
            return self.solve_other(target, span, preload_n, mu, start);
        }
        let alpha = span + self.a;
        let rest = self.c - span * preload_n - target;
        // Quadratic in u = sqrt(Tb): alpha*u^2 + beta*u + rest = 0, on the branch
        // where the elongation increases (2*alpha*u + beta > 0). Each form avoids
        // cancellation for its sign of beta.
        let inv = if span == self.span_m {
            self.inv_two_alpha
        } else {
            0.5 / alpha
        };
        let disc = self.beta * self.beta - 4.0 * alpha * rest;
        Self::root_squared(disc, self.beta, inv, rest)
    }

    /// `u^2` for the root `u > 0` of `alpha*u^2 + beta*u + rest` on the branch where it
    /// increases, from its discriminant and `1/(2*alpha)`; `None` when there is none.
    #[inline(always)]
    fn root_squared(disc: f64, beta: f64, inv_two_alpha: f64, rest: f64) -> Option<f64> {
        if disc.is_nan() || disc < 0.0 {
            return None;
        }
        let root = disc.sqrt();
        let lift = root - beta;
        // (root - beta)/(2 alpha) loses digits only when root and beta nearly cancel
        // (beta > 0 and a small 4*alpha*rest); the other form is exact there.
        let u = if beta <= 0.0 || lift.abs() >= 0.125 * beta {
            lift * inv_two_alpha
        } else {
            -2.0 * rest / (beta + root)
        };
        // Finite and positive, in two comparisons (NaN fails both).
        (u > 0.0 && u <= f64::MAX).then_some(u * u)
    }

    /// [`Self::solve`] on a sloped law for the free span it was built for, with the
    /// elongation `target_m` (m) and `E*A` (`modulus_n`, N) unscaled.
    #[inline(always)]
    fn solve_series(&self, target_m: f64, modulus_n: f64) -> Option<f64> {
        Self::root_squared(
            self.disc0 + self.disc1 * target_m,
            self.beta,
            self.inv_two_alpha,
            self.rest0 - modulus_n * target_m,
        )
    }

    /// [`Self::solve`] off the sloped segments: past the end, on the plateau.
    #[cold]
    #[inline(never)]
    fn solve_other(
        &self,
        target: f64,
        span: f64,
        preload_n: f64,
        mu: f64,
        start: f64,
    ) -> Option<f64> {
        let alpha = span + self.a;
        let rest = self.c - span * preload_n - target;
        match self.kind {
            LawKind::End => {
                let t = -rest / alpha;
                (t > 0.0).then_some(t)
            }
            LawKind::Plateau => {
                // alpha*Tb + bt*s(Tb) + rest with s = +-ln(Tb/Tpre)/mu: increasing, and
                // convex or concave throughout, so Newton from inside the range converges
                // monotonically after its first step.
                let sign = if self.rising { 1.0 } else { -1.0 };
                let k = self.bt * sign / mu;
                let mut t = if self.covers(start) {
                    start
                } else if self.hi.is_finite() {
                    0.5 * (self.lo + self.hi)
                } else {
                    2.0 * self.lo
                };
                for _ in 0..50 {
                    let g = alpha * t + k * (t / preload_n).ln() + rest;
                    let dg = alpha + k / t;
                    let next = t - g / dg;
                    if !(next.is_finite() && dg > 0.0) {
                        return None;
                    }
                    let next = if next > 0.0 { next } else { 0.5 * t };
                    if (next - t).abs() <= 1e-15 * t {
                        return Some(next);
                    }
                    t = next;
                }
                None
            }
            LawKind::Sloped | LawKind::Stuck | LawKind::Invalid => None,
        }
    }
}

/// Outcome of putting a boundary tension on a wrap, without committing it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WrapTrial {
    /// Elongation of the wrapped cable relative to the preloaded state, m.
    pub elongation_m: f64,
    /// Derivative of the elongation with respect to the boundary tension, m/N.
    pub d_elongation_m_per_n: f64,
    /// Second derivative, m/N^2 (for Halley steps).
    pub(crate) d2_elongation: f64,
    /// Boundary tension of the trial, N.
    tb_n: f64,
    /// The law it was computed with, kept so that committing this trial needs no second
    /// search.
    law: WrapLaw,
}

impl WrapTrial {
    /// Whether the slip zone reaches the inner end of the longest wrap.
    pub fn reaches_end(&self) -> bool {
        self.law.kind == LawKind::End
    }
}

/// The series span's root at a period boundary in its usual case: on the sloped law cached
/// for its direction, which a commit then reads where it sits instead of receiving a copy
/// (see [`WrapRegion::boundary_root`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CachedRoot {
    /// Boundary tension, N.
    pub tension_n: f64,
    /// Tension where the slip zone meets the stored profile, `sqrt(q*Tb)`, N.
    meeting_n: f64,
    /// Direction of the slip zone (the cache slot of the law).
    rising: bool,
}

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
    /// `1/(E*A)`, 1/N: every trial and commit scales by it.
    inv_modulus: f64,
    /// Shorter wrap, rad (equal to `wrap_rad` for a single region).
    cut_rad: f64,
    /// Longest wrap, where the stored profile ends, rad.
    wrap_rad: f64,
    /// Sum of radii of regions covering `s < cut_rad`, m.
    weight_inner_m: f64,
    /// Radius of the region covering `cut_rad <= s < wrap_rad`, m.
    weight_outer_m: f64,
    /// `exp(-mu*cut)`, `exp(mu*cut)`, `exp(-mu*wrap)`, `exp(mu*wrap)`.
    decay_at_cut: f64,
    growth_at_cut: f64,
    decay_at_end: f64,
    growth_at_end: f64,
    /// Free-span length in series with the wrap (its compliance times `E*A`), m: laws
    /// precompute their quadratic's leading coefficient for it.
    series_span_m: f64,
    /// Its compliance `span/E*A`, m/N, as a cable half computes it: solves for this
    /// span take the fast path.
    series_span_per_n: f64,
    /// Elongation of wrap and series span as committed, m, and the band around it within
    /// which nothing slips (rounding), m; the committed boundary tension, N. Kept with
    /// every commit for the series span's solves.
    stuck_m: f64,
    stuck_band_m: f64,
    committed_n: f64,
    /// The elongation (m) the last commit was solved for, or NaN when it was committed
    /// from a tension: within rounding of `stuck_m`, and known to the plant well before
    /// the commit's own arithmetic has produced `stuck_m`, so a solve can pick its
    /// direction's law from it first (see [`Self::tension_series`]).
    solved_for_m: f64,
    /// `integral_0^wrap weight ds`, m rad: the preload's share of a whole profile's
    /// integral, which the stored tails leave out.
    weight_total_m: f64,
    /// The same over `mu`, m rad: the scale of a wrap's tension integrals per newton
    /// (kept, as every commit needs it).
    slip_weight_per_mu: f64,
    /// Breakpoints ordered from the inner end (`s = wrap`) to the contact point (`s = 0`),
    /// so that a new slip zone pops the wiped breakpoints off the end of the vector. A
    /// breakpoint always sits at `cut_rad`, so every segment has a single weight.
    verts: Vec<Vertex>,
    /// Counts commits that changed the profile; a law is valid only on its generation.
    generation: u64,
    /// The unloading (`[0]`) and loading (`[1]`) law of the last trials or commit: reused
    /// while the boundary tension stays in their range. Two, because a load that dithers
    /// about the committed state within a period alternates between them.
    laws: [Cell<WrapLaw>; 2],
    /// What every sloped law shares with the others of its way and weight, by
    /// `[outer][rising]`: see [`SlopedConsts`].
    sloped: [[SlopedConsts; 2]; 2],
}

/// The coefficients of a sloped law ([`LawKind::Sloped`]) that depend only on its
/// direction and on the weight of the segment it ends on, for the series span: computed
/// once per region with the very expressions a law's build uses, so that a law built from
/// them is bit for bit the one built from scratch.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SlopedConsts {
    /// The slip zone's coefficient of `Tb`, m (`WrapLaw::a`).
    a: f64,
    /// The meeting tension's coefficient, m (`WrapLaw::bt`).
    bt: f64,
    /// `+-w_seg`, m: the stored segment's end tension's coefficient before `/mu`.
    sign_w: f64,
    /// Weight of the segment, m.
    w_seg: f64,
    /// `4*(span + a)`, m, and `1/(2*(span + a))`, 1/m.
    four_alpha: f64,
    inv_two_alpha: f64,
    /// `4*(span + a)*E*A`, N m.
    disc1: f64,
}

impl SlopedConsts {
    const ZERO: SlopedConsts = SlopedConsts {
        a: 0.0,
        bt: 0.0,
        sign_w: 0.0,
        w_seg: 0.0,
        four_alpha: 0.0,
        inv_two_alpha: 0.0,
        disc1: 0.0,
    };
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
            inv_modulus: 1.0 / modulus_n,
            cut_rad,
            wrap_rad,
            weight_inner_m,
            weight_outer_m,
            decay_at_cut: (-mu * cut_rad).exp(),
            growth_at_cut: (mu * cut_rad).exp(),
            decay_at_end: (-mu * wrap_rad).exp(),
            growth_at_end: (mu * wrap_rad).exp(),
            series_span_m: 0.0,
            series_span_per_n: 0.0,
            stuck_m: 0.0,
            stuck_band_m: 0.0,
            committed_n: preload_n,
            solved_for_m: f64::NAN,
            weight_total_m: weight_inner_m * cut_rad + weight_outer_m * (wrap_rad - cut_rad),
            slip_weight_per_mu: (weight_inner_m * cut_rad + weight_outer_m * (wrap_rad - cut_rad))
                / mu,
            verts: Vec::with_capacity(16),
            generation: 0,
            laws: [Cell::new(WrapLaw::INVALID), Cell::new(WrapLaw::INVALID)],
            sloped: [[SlopedConsts::ZERO; 2]; 2],
        };
        region.refresh_sloped();
        region.reset();
        region
    }

    /// [`Self::sloped`] for the current series span.
    fn refresh_sloped(&mut self) {
        for outer in [false, true] {
            for rising in [false, true] {
                let sign = if rising { 1.0 } else { -1.0 };
                let at_cut = if rising {
                    self.decay_at_cut
                } else {
                    self.growth_at_cut
                };
                let w_seg = if outer {
                    self.weight_outer_m
                } else {
                    self.weight_inner_m
                };
                let a = if !outer {
                    sign * self.weight_inner_m / self.mu
                } else {
                    self.slip_coefficient(rising, at_cut, 0.0)
                };
                let alpha = self.series_span_m + a;
                self.sloped[usize::from(outer)][usize::from(rising)] = SlopedConsts {
                    a,
                    bt: -2.0 * sign * w_seg / self.mu,
                    sign_w: sign * w_seg,
                    w_seg,
                    four_alpha: 4.0 * alpha,
                    inv_two_alpha: 0.5 / alpha,
                    disc1: 4.0 * alpha * self.modulus_n,
                };
            }
        }
    }

    /// The same region with a free span of length `span_m` (m) in series, for which
    /// [`Self::tension_for_elongation`] is fastest (any span still works).
    pub fn with_series_span(mut self, span_m: f64) -> Self {
        self.series_span_m = span_m;
        self.series_span_per_n = span_m / self.modulus_n;
        self.refresh_sloped();
        self.reset();
        self
    }

    /// Compliance of the free span in series, `span/E*A`, m/N (0 when none was given):
    /// solves by elongation for it take the fast path.
    #[inline]
    pub fn series_span_per_n(&self) -> f64 {
        self.series_span_per_n
    }

    /// Forget all history: back to the uniform preloaded profile.
    pub fn reset(&mut self) {
        let t = self.preload_n;
        self.verts.clear();
        for s in [self.wrap_rad, self.cut_rad, 0.0] {
            if self.verts.last().is_none_or(|v| v.s > s) {
                self.verts.push(Vertex {
                    s,
                    t,
                    p: t * (self.mu * s).exp(),
                    m: t * (-self.mu * s).exp(),
                    tail: t * (self.weight_total_m - self.weighted_length(s)),
                    outer: s > self.cut_rad,
                });
            }
        }
        self.generation = self.generation.wrapping_add(1);
        self.refresh_committed();
    }

    /// Band around the committed elongation times `E*A` (N m) for committed tension
    /// `top_n` (N) and a series span `span_m` (m), within which a solve returns the
    /// committed tension: there the wrap's stiffness is the free span's alone, so this
    /// moves the tension by about 1e-11 of itself at most.
    #[inline]
    fn stuck_band(&self, top_n: f64, span_m: f64) -> f64 {
        1e-12 * top_n * (span_m + self.slip_weight_per_mu)
    }

    /// The committed state as the series span's solves see it (after every change).
    fn refresh_committed(&mut self) {
        let (per_ea, pre) = (self.inv_modulus, self.preload_n);
        let top = self.verts[self.verts.len() - 1];
        let span = self.series_span_m;
        self.committed_n = top.t;
        self.solved_for_m = f64::NAN;
        self.stuck_m = (span * (top.t - pre) + top.tail - pre * self.weight_total_m) * per_ea;
        self.stuck_band_m = self.stuck_band(top.t, span) * per_ea;
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

    /// Weight (sum of radii, m) of the segment ending at breakpoint `v` inward.
    #[inline]
    fn weight(&self, v: &Vertex) -> f64 {
        if v.outer {
            self.weight_outer_m
        } else {
            self.weight_inner_m
        }
    }

    /// Wrap angle of breakpoint `v`, rad: stored, or from its two invariants when the
    /// commit left it out (`p/m = exp(2*mu*s)`).
    #[inline]
    fn angle(&self, v: &Vertex) -> f64 {
        if v.s.is_nan() {
            ((v.p / v.m).ln() / (2.0 * self.mu)).clamp(0.0, self.wrap_rad)
        } else {
            v.s
        }
    }

    /// `integral_0^s weight ds`, m rad: the preload's share of a profile integral.
    #[inline]
    fn weighted_length(&self, s: f64) -> f64 {
        if s <= self.cut_rad {
            self.weight_inner_m * s
        } else {
            self.weight_inner_m * self.cut_rad + self.weight_outer_m * (s - self.cut_rad)
        }
    }

    /// Coefficient of `Tb` in the slip-zone integral `integral_0^s* w*Tb*exp(-+mu*s) ds`,
    /// given `exp(-+mu*s)` at the shorter wrap's end (`at_cut`) and at the slip zone's end
    /// (`at_end`), for a zone that passes the shorter wrap's end.
    #[inline]
    fn slip_coefficient(&self, rising: bool, at_cut: f64, at_end: f64) -> f64 {
        let sign = if rising { 1.0 } else { -1.0 };
        sign * (self.weight_inner_m * (1.0 - at_cut) + self.weight_outer_m * (at_cut - at_end))
            / self.mu
    }

    /// The elongation law around boundary tension `tb_n` (N > 0): walk from the contact
    /// point inward to the first breakpoint the new slip zone does not lift (rising) or
    /// lower (falling).
    fn build_law(&self, tb_n: f64) -> WrapLaw {
        let law = self.build_law_shape(tb_n);
        if law.kind == LawKind::Sloped && law.span_m == self.series_span_m {
            law
        } else {
            self.with_series(law)
        }
    }

    /// `law` with the coefficients of the series span's solves.
    #[inline]
    fn with_series(&self, law: WrapLaw) -> WrapLaw {
        let span = self.series_span_m;
        let alpha = span + law.a;
        let rest0 = law.c - span * self.preload_n;
        WrapLaw {
            span_m: span,
            inv_two_alpha: 0.5 / alpha,
            disc0: law.beta * law.beta - 4.0 * alpha * rest0,
            disc1: 4.0 * alpha * self.modulus_n,
            rest0,
            ..law
        }
    }

    fn build_law_shape(&self, tb_n: f64) -> WrapLaw {
        let top = self.verts.len() - 1;
        let top_v = self.verts[top];
        if tb_n == top_v.t {
            return self.stuck_law();
        }
        let rising = tb_n > top_v.t;
        let mut k = top;
        while k > 0 {
            let b = self.verts[k - 1];
            if (rising && b.p >= tb_n) || (!rising && b.m <= tb_n) {
                return self.segment_law(k, rising, tb_n);
            }
            k -= 1;
        }
        let (at_cut, at_end) = if rising {
            (self.decay_at_cut, self.decay_at_end)
        } else {
            (self.growth_at_cut, self.growth_at_end)
        };
        let pre = self.preload_n;
        let deepest = self.verts[0];
        let at_cut = if self.cut_rad < self.wrap_rad {
            at_cut
        } else {
            at_end
        };
        WrapLaw {
            kind: LawKind::End,
            rising,
            generation: self.generation,
            index: usize::MAX,
            lo: if rising { deepest.p } else { 0.0 },
            hi: if rising { f64::INFINITY } else { deepest.m },
            a: self.slip_coefficient(rising, at_cut, at_end),
            c: -pre * self.weight_total_m,
            w_seg: self.weight_outer_m,
            q: at_end,
            ..WrapLaw::INVALID
        }
    }

    /// The law of a slip zone that rises (or falls) from the contact point and ends on
    /// the stored segment between breakpoints `k - 1` and `k` (`k >= 1`), for boundary
    /// tension `tb_n` (N). Only a segment parallel to the slip zone depends on `tb_n`.
    #[inline]
    fn segment_law(&self, k: usize, rising: bool, tb_n: f64) -> WrapLaw {
        let (mu, pre) = (self.mu, self.preload_n);
        let sign = if rising { 1.0 } else { -1.0 };
        let b = self.verts[k - 1];
        let a = self.verts[k];
        // The way and weight's shared coefficients, as every law of this segment has them.
        let sc = self.sloped[usize::from(b.outer)][usize::from(rising)];
        let (w_seg, slip_a) = (sc.w_seg, sc.a);
        let (lo, hi) = if rising { (a.p, b.p) } else { (b.m, a.m) };
        let base = b.tail - pre * self.weight_total_m;
        let law = WrapLaw {
            rising,
            generation: self.generation,
            index: k - 1,
            lo,
            hi,
            a: slip_a,
            w_seg,
            ..WrapLaw::INVALID
        };
        if a.t == b.t {
            // The untouched plateau: T* = Tpre, s* = +-ln(Tb/Tpre)/mu.
            WrapLaw {
                kind: LawKind::Plateau,
                bt: -w_seg * pre,
                c: -sign * w_seg * pre / mu + w_seg * pre * self.angle(&b) + base,
                ..law
            }
        } else if (b.t > a.t) == rising {
            self.sloped_law(k, rising)
        } else {
            // A segment parallel to the new slip zone can only hold the crossing
            // through rounding: it sits at its inner breakpoint, for this Tb only.
            let (lo, hi) = if rising {
                (tb_n.next_down(), tb_n)
            } else {
                (tb_n, tb_n.next_up())
            };
            let bt = sc.bt;
            WrapLaw {
                kind: LawKind::Sloped,
                bt,
                q: b.t * b.t / tb_n,
                beta: bt * b.t / tb_n.sqrt(),
                c: sign * w_seg * b.t / mu + base,
                lo,
                hi,
                ..law
            }
        }
    }

    /// [`Self::segment_law`] where the segment has log-slope `+mu` (rising) or `-mu`
    /// (falling), with the series span's coefficients.
    #[inline(always)]
    fn sloped_law(&self, k: usize, rising: bool) -> WrapLaw {
        let (mu, pre, span) = (self.mu, self.preload_n, self.series_span_m);
        let (b, a) = (self.verts[k - 1], self.verts[k]);
        let sc = self.sloped[usize::from(b.outer)][usize::from(rising)];
        let (lo, hi, q) = if rising {
            (a.p, b.p, b.m)
        } else {
            (b.m, a.m, b.p)
        };
        let base = b.tail - pre * self.weight_total_m;
        let beta = sc.bt * q.sqrt();
        let c = sc.sign_w * b.t / mu + base;
        let rest0 = c - span * pre;
        WrapLaw {
            kind: LawKind::Sloped,
            rising,
            generation: self.generation,
            index: k - 1,
            lo,
            hi,
            a: sc.a,
            bt: sc.bt,
            q,
            c,
            beta,
            span_m: span,
            inv_two_alpha: sc.inv_two_alpha,
            disc0: beta * beta - sc.four_alpha * rest0,
            disc1: sc.disc1,
            rest0,
            w_seg: sc.w_seg,
        }
    }

    /// The law a load turning back from the committed state starts on, `rising` being
    /// the new direction: the one [`Self::build_law`] gives for every boundary tension
    /// whose slip zone ends on the top stored segment, when that segment slopes against
    /// the new slip zone (as the last commit's own slip zone does). `None` otherwise.
    /// A servo holding still dithers across its committed state, so most reversals end
    /// here: tried first, it spares them a search.
    #[inline]
    fn reversal_law(&self, rising: bool) -> Option<WrapLaw> {
        let top = self.verts.len() - 1;
        if top == 0 {
            return None;
        }
        let (a, b) = (self.verts[top], self.verts[top - 1]);
        let sloped_against = a.t != b.t && (b.t > a.t) == rising;
        let nonempty = if rising { a.p < b.p } else { b.m < a.m };
        (sloped_against && nonempty).then(|| self.sloped_law(top, rising))
    }

    /// The law for `tb_n`: the cached one when it holds there, else a fresh walk (cached).
    #[inline]
    pub(crate) fn law_at(&self, tb_n: f64) -> WrapLaw {
        let slot = &self.laws[usize::from(tb_n > self.boundary_tension_n())];
        let cached = slot.get();
        if cached.generation == self.generation && cached.covers(tb_n) {
            return cached;
        }
        let law = self.build_law(tb_n);
        slot.set(law);
        law
    }

    /// Elongation and its derivative if the boundary tension became `tb_n` (N > 0), the
    /// stored profile left unchanged.
    #[inline]
    pub fn trial(&self, tb_n: f64) -> WrapTrial {
        self.trial_from(self.law_at(tb_n), tb_n)
    }

    /// [`Self::trial`] with the law held by the caller: reused when it holds at `tb_n`,
    /// replaced otherwise. Saves the shared cache's traffic inside an iteration.
    #[inline]
    pub(crate) fn trial_with(&self, law: &mut WrapLaw, tb_n: f64) -> WrapTrial {
        if !(law.generation == self.generation && law.covers(tb_n)) {
            *law = self.build_law(tb_n);
        }
        self.trial_from(*law, tb_n)
    }

    #[inline]
    fn trial_from(&self, law: WrapLaw, tb_n: f64) -> WrapTrial {
        let (e, de, d2e) = law.eval(tb_n, self.mu, self.preload_n);
        let inv = self.inv_modulus;
        WrapTrial {
            elongation_m: e * inv,
            d_elongation_m_per_n: de * inv,
            d2_elongation: d2e * inv,
            tb_n,
            law,
        }
    }

    /// Boundary tension (N) at which `span_per_n * (Tb - Tpre) + elongation(Tb)` equals
    /// `target_m` (m), where `span_per_n` (m/N, > 0) is the compliance of a free span in
    /// series: the exact tension of a cable half whose elongation is prescribed. `guess_n`
    /// (N) picks the stored segment to start from when the cached law does not hold.
    ///
    /// Closed form (a quadratic in `sqrt(Tb)`) while the slip zone ends on one stored
    /// segment; safeguarded Newton otherwise. `None` when no positive tension fits (the
    /// span would go slack).
    #[inline]
    pub fn tension_for_elongation(
        &self,
        target_m: f64,
        span_per_n: f64,
        guess_n: f64,
    ) -> Option<f64> {
        self.solve_for_elongation(target_m, span_per_n, guess_n)
            .map(|(t, _)| t)
    }

    /// [`Self::tension_for_elongation`] with the law that holds at the tension found, for
    /// committing it ([`Self::commit_fresh`]) without searching again.
    #[inline(always)]
    pub(crate) fn solve_for_elongation(
        &self,
        target_m: f64,
        span_per_n: f64,
        guess_n: f64,
    ) -> Option<(f64, WrapLaw)> {
        if span_per_n == self.series_span_per_n {
            // The plant's case: everything about the committed state is at hand.
            let off = target_m - self.stuck_m;
            if off.abs() <= self.stuck_band_m {
                return Some((self.committed_n, self.stuck_law()));
            }
            let rising = off > 0.0;
            let cached = self.laws[usize::from(rising)].get();
            if let Some(t) = self.root_on_cached(&cached, target_m) {
                return Some((t, cached));
            }
            return self.series_miss(target_m, rising, &cached, guess_n);
        }
        self.solve_for_elongation_any(target_m, span_per_n, guess_n)
    }

    /// [`Self::solve_for_elongation`] for the series span where its root lies on the
    /// sloped law cached for its direction: the same tension, with the meeting tension the
    /// gross-slip check and the commit share. `None` in every other case (the committed
    /// state, a law to search for), which the caller leaves to the general solve.
    #[inline(always)]
    pub(crate) fn boundary_root(&mut self, target_m: f64) -> Option<CachedRoot> {
        let off = target_m - self.stuck_m;
        if off.abs() <= self.stuck_band_m {
            return None;
        }
        let rising = off > 0.0;
        let (generation, modulus_n) = (self.generation, self.modulus_n);
        // Read in place (a copy of the 128-byte law is what this path saves).
        let law = self.laws[usize::from(rising)].get_mut();
        if law.rising != rising || law.generation != generation || law.kind != LawKind::Sloped {
            return None;
        }
        let t = law
            .solve_series(target_m, modulus_n)
            .and_then(|t| law.accept(t))?;
        Some(CachedRoot {
            tension_n: t,
            // `meeting_tension` of a sloped law.
            meeting_n: (law.q * t).sqrt(),
            rising,
        })
    }

    /// [`Self::slip_growth_on`] of a root on its cached law.
    #[inline(always)]
    pub(crate) fn cached_growth(&self, root: &CachedRoot) -> f64 {
        self.growth(root.rising, root.tension_n, root.meeting_n)
    }

    /// `exp(mu*s*)` of a slip zone of direction `rising` from boundary tension `tb` (N)
    /// that meets the stored profile at tension `ts` (N), at most the longest wrap's.
    #[inline(always)]
    fn growth(&self, rising: bool, tb: f64, ts: f64) -> f64 {
        let g = if rising { tb / ts } else { ts / tb };
        g.clamp(1.0, self.growth_at_end)
    }

    /// [`Self::commit_solved`] of a root found by [`Self::boundary_root`] for elongation
    /// `target_m` (m), nothing committed since. The usual commit (the slip zone meets a
    /// sloped segment inside the shorter wrap, away from its breakpoints and the contact
    /// point) is made here on the cached law in place, by the very expressions of
    /// [`Self::commit_fresh`], which takes every other case.
    #[inline(always)]
    pub(crate) fn commit_cached(&mut self, root: &CachedRoot, target_m: f64) {
        let (tb, ts, rising) = (root.tension_n, root.meeting_n, root.rising);
        let slot = usize::from(rising);
        let (index, q, w_seg) = {
            let law = self.laws[slot].get_mut();
            (law.index, law.q, law.w_seg)
        };
        let b = self.verts[index];
        if b.outer || ts == tb || !self.meets_away(&b, ts) {
            self.commit_slot(tb, slot, target_m);
            return;
        }
        let meeting = self.meeting_vertex(rising, tb, ts, q, w_seg, &b, false);
        let tail = self.along(rising, self.weight_inner_m, tb, ts) + meeting.tail;
        self.verts.truncate(index + 1);
        self.verts.push(meeting);
        self.verts.push(Vertex::contact(tb, tail));
        self.generation = self.generation.wrapping_add(1);
        self.refresh_committed();
        let generation = self.generation;
        let cached = self.laws[slot].get_mut();
        cached.generation = generation;
        if rising {
            cached.lo = tb;
        } else {
            cached.hi = tb;
        }
        self.solved_for_m = target_m;
    }

    /// [`Self::commit_cached`] off its usual case: [`Self::commit_solved`] on a copy of
    /// the cached law of `slot`.
    #[cold]
    #[inline(never)]
    fn commit_slot(&mut self, tb: f64, slot: usize, target_m: f64) {
        let law = self.laws[slot].get();
        self.commit_solved(tb, &law, target_m);
    }

    /// [`Self::solve_for_elongation`] for the series span, the tension alone: the
    /// right-hand side's solve, which never commits, so no law leaves it.
    #[inline(always)]
    pub(crate) fn tension_series(&self, target_m: f64) -> Option<f64> {
        // The law is first chosen by the side of the elongation the last commit was
        // solved for: right after a commit its `stuck_m` is still being computed, and a
        // choice made from it would hold the whole solve back. The exact test below
        // confirms the choice (the two sides differ only within rounding), so the answer
        // is the one the exact test alone gives.
        let early = target_m > self.solved_for_m;
        let cached = self.laws[usize::from(early)].get();
        let off = target_m - self.stuck_m;
        if off.abs() <= self.stuck_band_m {
            return Some(self.committed_n);
        }
        let rising = off > 0.0;
        let cached = if rising == early {
            cached
        } else {
            self.laws[usize::from(rising)].get()
        };
        if let Some(t) = self.root_on_cached(&cached, target_m) {
            return Some(t);
        }
        self.series_miss(target_m, rising, &cached, f64::NAN)
            .map(|(t, _)| t)
    }

    /// The series span's root on the cached law `cached` of its direction, when that law
    /// is current, sloped and holds there.
    #[inline(always)]
    fn root_on_cached(&self, cached: &WrapLaw, target_m: f64) -> Option<f64> {
        if cached.generation == self.generation && cached.kind == LawKind::Sloped {
            cached
                .solve_series(target_m, self.modulus_n)
                .and_then(|t| cached.accept(t))
        } else {
            None
        }
    }

    /// The series span's solve when the cached law `cached` of direction `rising` does
    /// not give the root: the top segment's law after a commit the other way, then the
    /// search.
    #[cold]
    #[inline(never)]
    fn series_miss(
        &self,
        target_m: f64,
        rising: bool,
        cached: &WrapLaw,
        guess_n: f64,
    ) -> Option<(f64, WrapLaw)> {
        if cached.generation != self.generation {
            // The first solve this way since the last commit, which went the other way:
            // most such roots lie on the top segment, the last slip zone. The search
            // would start on the law at its guess; where that is this one, its first
            // step is taken here without the walk, so the answer is the search's own.
            let guess = self.search_guess(target_m, self.series_span_per_n, rising, guess_n);
            if let Some(back) = self.reversal_law(rising).filter(|l| l.covers(guess)) {
                self.laws[usize::from(rising)].set(back);
                if let Some(t) = back
                    .solve_series(target_m, self.modulus_n)
                    .and_then(|t| back.accept(t))
                {
                    return Some((t, back));
                }
            }
        }
        self.tension_for_elongation_search(target_m, self.series_span_per_n, rising, guess_n)
    }

    /// [`Self::solve_for_elongation`] for any series span and any kind of law.
    #[inline(never)]
    fn solve_for_elongation_any(
        &self,
        target_m: f64,
        span_per_n: f64,
        guess_n: f64,
    ) -> Option<(f64, WrapLaw)> {
        let (ea, pre, mu) = (self.modulus_n, self.preload_n, self.mu);
        let (target, span) = (target_m * ea, span_per_n * ea);
        let top = self.verts[self.verts.len() - 1];
        // The committed state splits loading from unloading: which way the boundary
        // tension moves follows from the target alone.
        let stuck = span * (top.t - pre) + top.tail - pre * self.weight_total_m;
        // Within rounding of the committed state nothing slips.
        let rounding = self.stuck_band(top.t, span);
        if (target - stuck).abs() <= rounding {
            return Some((top.t, self.stuck_law()));
        }
        let rising = target > stuck;
        let cached = self.laws[usize::from(rising)].get();
        if cached.generation == self.generation {
            if let Some(t) = cached
                .solve(target, span, pre, mu, guess_n)
                .and_then(|t| cached.accept(t))
            {
                return Some((t, cached));
            }
        }
        self.tension_for_elongation_search(target_m, span_per_n, rising, guess_n)
    }

    /// The law of an unchanged boundary tension: nothing slips.
    fn stuck_law(&self) -> WrapLaw {
        let top = self.verts[self.verts.len() - 1];
        WrapLaw {
            kind: LawKind::Stuck,
            generation: self.generation,
            lo: top.t,
            hi: top.t,
            c: top.tail - self.preload_n * self.weight_total_m,
            ..WrapLaw::INVALID
        }
    }

    /// [`Self::solve_for_elongation`] when the cached law does not give the root: from the
    /// law at the guess, then the laws where each root points (a smooth motion crosses a
    /// segment or two in a step), then safeguarded Newton over fresh trials. For the
    /// series span without a guess, the guess is the tangent at the committed state, where
    /// only the free span stretches (a slip zone starts with zero length): it overshoots,
    /// and the laws where the roots point lead back.
    #[cold]
    #[inline(never)]
    fn tension_for_elongation_search(
        &self,
        target_m: f64,
        span_per_n: f64,
        rising: bool,
        guess_n: f64,
    ) -> Option<(f64, WrapLaw)> {
        let (ea, pre, mu) = (self.modulus_n, self.preload_n, self.mu);
        let (target, span) = (target_m * ea, span_per_n * ea);
        let series = span_per_n == self.series_span_per_n;
        let root_on = |law: &WrapLaw, start: f64| {
            if series && law.kind == LawKind::Sloped {
                law.solve_series(target_m, ea)
            } else {
                law.solve(target, span, pre, mu, start)
            }
        };
        let guess = self.search_guess(target_m, span_per_n, rising, guess_n);
        let mut at = guess;
        for _ in 0..3 {
            let law = self.law_at(at);
            let Some(t) = root_on(&law, at) else {
                break;
            };
            // Any root a law accepts within its range solves the monotone equation.
            if let Some(t) = law.accept(t) {
                return Some((t, law));
            }
            at = t;
        }
        super::newton::solve_increasing(
            |tb| {
                let tr = self.trial(tb);
                (
                    span_per_n * (tb - pre) + tr.elongation_m - target_m,
                    span_per_n + tr.d_elongation_m_per_n,
                )
            },
            0.0,
            guess,
            pre,
            1e-13,
        )
        .ok()
        .map(|t| (t, self.law_at(t)))
    }

    /// The boundary tension (N) [`Self::tension_for_elongation_search`] starts from for
    /// elongation `target_m` (m) in direction `rising`: the caller's `guess_n`, or for the
    /// series span the tangent at the committed state, on the side of the committed
    /// tension the target lies.
    #[inline]
    fn search_guess(&self, target_m: f64, span_per_n: f64, rising: bool, guess_n: f64) -> f64 {
        let top_t = self.committed_n;
        let guess_n = if span_per_n == self.series_span_per_n && !guess_n.is_finite() {
            top_t + (target_m - self.stuck_m) / span_per_n
        } else {
            guess_n
        };
        // A guess on the wrong side of the committed tension would pick the other branch.
        if guess_n.is_finite() && guess_n > 0.0 && (guess_n > top_t) == rising {
            guess_n
        } else if rising {
            top_t * (1.0 + 1e-9)
        } else {
            top_t * (1.0 - 1e-9)
        }
    }

    /// `exp(mu*s*)` for the slip zone of a trial of length `s*` (at most the longest
    /// wrap; 1 when the boundary tension is unchanged): the ratio of the boundary tension
    /// to the tension where the zone meets the stored profile. Comparing it with
    /// `exp(mu*wrap)` tells whether a zone reaches a region's end without a logarithm.
    #[inline]
    pub fn slip_growth(&self, trial: &WrapTrial) -> f64 {
        self.slip_growth_on(trial.tb_n, &trial.law)
    }

    /// [`Self::slip_growth`] for boundary tension `tb_n` (N) on `law`.
    #[inline]
    pub(crate) fn slip_growth_on(&self, tb_n: f64, law: &WrapLaw) -> f64 {
        match law.kind {
            LawKind::End => self.growth_at_end,
            LawKind::Stuck | LawKind::Invalid => 1.0,
            LawKind::Sloped | LawKind::Plateau => {
                self.growth(law.rising, tb_n, law.meeting_tension(tb_n, self.preload_n))
            }
        }
    }

    /// Length of the slip zone of a trial (wrap angle where the new branch meets the old
    /// profile), rad, at most the longest wrap; zero when the boundary tension is
    /// unchanged.
    pub fn slip_angle_rad(&self, trial: &WrapTrial) -> f64 {
        match trial.law.kind {
            LawKind::End => self.wrap_rad,
            _ => (self.slip_growth(trial).ln() / self.mu).min(self.wrap_rad),
        }
    }

    /// Commit a boundary tension `tb_n` (N > 0): the slip zone replaces the part of the
    /// profile it wipes out.
    pub fn commit(&mut self, tb_n: f64) {
        let trial = self.trial(tb_n);
        self.commit_trial(&trial);
    }

    /// Commit a trial: directly when computed on the current profile (no second search
    /// for the crossing), recomputed when the profile has changed since.
    pub fn commit_trial(&mut self, trial: &WrapTrial) {
        if trial.law.generation == self.generation && trial.law.covers(trial.tb_n) {
            self.commit_fresh(trial.tb_n, &trial.law);
        } else {
            let law = self.build_law(trial.tb_n);
            self.commit_fresh(trial.tb_n, &law);
        }
    }

    /// Commit a trial known to be computed on the current profile (since its last
    /// commit): skips the check [`Self::commit_trial`] makes.
    #[inline]
    pub(crate) fn commit_current(&mut self, trial: &WrapTrial) {
        self.commit_fresh(trial.tb_n, &trial.law);
    }

    /// [`Self::commit_fresh`] of a solve for the series span's elongation `target_m` (m).
    #[inline]
    pub(crate) fn commit_solved(&mut self, tb: f64, law: &WrapLaw, target_m: f64) {
        self.commit_fresh(tb, law);
        self.solved_for_m = target_m;
    }

    /// The shortest segment a commit leaves, rad: a crossing closer than this to an
    /// existing breakpoint would leave a zero-length segment.
    #[inline(always)]
    fn min_length(&self) -> f64 {
        1e-14 * self.wrap_rad.max(1.0)
    }

    /// Whether a slip zone meeting the stored sloped segment that ends inward at `b`, at
    /// tension `ts` (N), meets it away from `b` (not within [`Self::min_length`] of it).
    #[inline(always)]
    fn meets_away(&self, b: &Vertex, ts: f64) -> bool {
        (b.t - ts).abs() > self.mu * self.min_length() * ts
    }

    /// `integral w*T ds` (N m) along a segment of log-slope `-+mu` (a slip zone of
    /// direction `rising`, or a stored segment of the opposite slope walked the other way)
    /// of weight `w` (m), from its end tensions `t_out` and `t_in` (N).
    #[inline(always)]
    fn along(&self, rising: bool, w: f64, t_out: f64, t_in: f64) -> f64 {
        let sign = if rising { 1.0 } else { -1.0 };
        w * (sign / self.mu) * (t_out - t_in)
    }

    /// The breakpoint where a slip zone of direction `rising` from boundary tension `tb`
    /// (N) meets, at tension `ts` (N), the stored sloped segment of weight `w_seg` (m)
    /// ending inward at `b`: the stored side keeps its invariant `q` (N), the slip zone's
    /// is `tb`; its angle is left out (see [`Vertex::s`]).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn meeting_vertex(
        &self,
        rising: bool,
        tb: f64,
        ts: f64,
        q: f64,
        w_seg: f64,
        b: &Vertex,
        outer: bool,
    ) -> Vertex {
        let (p, m) = if rising { (tb, q) } else { (q, tb) };
        Vertex {
            s: f64::NAN,
            t: ts,
            p,
            m,
            tail: self.along(rising, w_seg, b.t, ts) + b.tail,
            outer,
        }
    }

    /// Commit boundary tension `tb` (N) on `law`, which must hold there and be built on
    /// the current profile (as the laws [`Self::solve_for_elongation`] returns are).
    pub(crate) fn commit_fresh(&mut self, tb: f64, law: &WrapLaw) {
        debug_assert!(law.generation == self.generation || law.kind == LawKind::Stuck);
        if law.kind == LawKind::Stuck || law.kind == LawKind::Invalid {
            return;
        }
        let (mu, pre) = (self.mu, self.preload_n);
        let rising = law.rising;
        let sign = if rising { 1.0 } else { -1.0 };
        // A point of the new slip zone `Tb*exp(-+mu*s)` with tension `t`: along it
        // `T*exp(+-mu*s)` is Tb.
        let on_line = |s: f64, t: f64, tail: f64, outer: bool| {
            let other = t * t / tb;
            let (p, m) = if rising { (tb, other) } else { (other, tb) };
            Vertex {
                s,
                t,
                p,
                m,
                tail,
                outer,
            }
        };
        let ts = law.meeting_tension(tb, pre);
        // Whether the slip zone ends on a stored segment that survives (so a further load
        // the same way still ends on it), and whether it meets the profile at the contact
        // point itself (zero length).
        let mut continues = true;
        let mut at_contact = false;
        let min_length = self.min_length();
        if law.kind == LawKind::End {
            self.verts.clear();
            self.verts.push(on_line(
                self.wrap_rad,
                ts,
                0.0,
                self.wrap_rad > self.cut_rad,
            ));
        } else {
            self.verts.truncate(law.index + 1);
            let b = self.verts[law.index];
            if law.kind == LawKind::Plateau {
                // On the flat plateau the length matters, and the angle is a logarithm.
                let s_star = sign * (tb / pre).ln() / mu;
                if b.s - s_star > min_length {
                    let tail = law.w_seg * pre * (b.s - s_star) + b.tail;
                    self.verts
                        .push(on_line(s_star, pre, tail, s_star > self.cut_rad));
                    at_contact = s_star <= 0.0;
                } else {
                    continues = false;
                }
            } else if self.meets_away(&b, ts) {
                at_contact = ts == tb;
                let outer = b.outer && !at_contact;
                let meeting = self.meeting_vertex(rising, tb, ts, law.q, law.w_seg, &b, outer);
                self.verts.push(meeting);
            } else {
                continues = false;
            }
        }
        let last = self.verts[self.verts.len() - 1];
        if last.outer {
            // The slip zone passes the shorter wrap's end: keep a breakpoint there, as
            // segments must not straddle it.
            let t_cut = tb
                * if rising {
                    self.decay_at_cut
                } else {
                    self.growth_at_cut
                };
            let tail = self.along(rising, self.weight_outer_m, t_cut, last.t) + last.tail;
            self.verts.push(on_line(self.cut_rad, t_cut, tail, false));
        }
        let last = self.verts[self.verts.len() - 1];
        if at_contact {
            // Zero-length slip zone: the new breakpoint is the contact point.
            let top = self.verts.len() - 1;
            self.verts[top] = Vertex {
                s: 0.0,
                t: tb,
                p: tb,
                m: tb,
                ..last
            };
            continues = false;
        } else {
            let tail = self.along(rising, self.weight(&last), tb, last.t) + last.tail;
            self.verts.push(Vertex::contact(tb, tail));
        }
        self.generation = self.generation.wrapping_add(1);
        self.refresh_committed();
        // The same law carries on for a load that keeps going the same way: the segment it
        // ends on is still there, now starting at the new breakpoint.
        let generation = self.generation;
        let slot = self.laws[usize::from(rising)].get_mut();
        if !continues {
            *slot = WrapLaw::INVALID;
            return;
        }
        let (lo, hi) = if rising { (tb, law.hi) } else { (law.lo, tb) };
        if slot.generation.wrapping_add(1) == generation
            && slot.index == law.index
            && slot.kind == law.kind
            && slot.rising == rising
        {
            // The cached law is the one committed: only its range and generation move.
            slot.generation = generation;
            slot.lo = lo;
            slot.hi = hi;
        } else {
            *slot = WrapLaw {
                generation,
                lo,
                hi,
                ..*law
            };
        }
    }

    /// Elongation of the wrapped cable as committed, relative to the preloaded state, m.
    pub fn elongation_m(&self) -> f64 {
        (self.verts[self.verts.len() - 1].tail - self.preload_n * self.weight_total_m)
            / self.modulus_n
    }

    /// Tension at wrap angle `s_rad` (clamped to the wrap), N.
    pub fn tension_at(&self, s_rad: f64) -> f64 {
        let s = s_rad.clamp(0.0, self.wrap_rad);
        for k in (1..self.verts.len()).rev() {
            let (a, b) = (self.verts[k], self.verts[k - 1]);
            let (sa, sb) = (self.angle(&a), self.angle(&b));
            if s <= sb {
                let h = sb - sa;
                if h <= 0.0 || a.t == b.t {
                    return b.t;
                }
                // Log-linear between breakpoints.
                return a.t * ((b.t / a.t).ln() * (s - sa) / h).exp();
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
            .map(|v| (self.angle(v), v.t))
            .filter(|v| v.0 < end)
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
            .map(|w| (self.angle(&w[0]) - self.angle(&w[1]), w[0].t / w[1].t))
            .filter(|(h, _)| *h > 1e-12)
            .map(|(h, ratio)| (ratio.ln() / h).abs())
            .fold(0.0, f64::max)
    }
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
    fn a_law_fits_in_the_size_copied_without_a_call() {
        assert!(std::mem::size_of::<WrapLaw>() <= 128);
    }

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
            assert!((region.slip_angle_rad(&trial) - v.ln() / MU).abs() < 1e-12);
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
        assert!(trial.reaches_end());
        assert_eq!(region.slip_angle_rad(&trial), 0.5);
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
            assert_eq!(shared.slip_angle_rad(&tr) >= wd, a.reaches_end());
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

    /// Deterministic uniform numbers in [0, 1) for the history tests.
    fn lcg(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    #[test]
    fn cached_laws_agree_with_fresh_walks() {
        let (rd, wd, rp, wp) = (0.1025, 0.9, 0.02, 2.5);
        let mut region = WrapRegion::with_regions(&[(rd, wd), (rp, wp)], MU, TPRE, G);
        let mut rng = 99u64;
        let mut tb = TPRE;
        for _ in 0..3000 {
            // Runs of small same-direction moves (the law carries on) broken by reversals
            // and occasional jumps past earlier extremes.
            let step = if lcg(&mut rng) < 0.1 { 40.0 } else { 2.0 };
            tb = (tb + step * (lcg(&mut rng) - 0.45)).clamp(30.0, 260.0);
            let probe = tb * (1.0 + 0.02 * (lcg(&mut rng) - 0.5));
            let cached = region.trial(probe);
            let fresh = region.trial_from(region.build_law(probe), probe);
            let scale = (rd * wd + rp * wp) * probe / G;
            assert!((cached.elongation_m - fresh.elongation_m).abs() <= 1e-13 * scale);
            assert!(
                (cached.d_elongation_m_per_n - fresh.d_elongation_m_per_n).abs()
                    <= 1e-12 * fresh.d_elongation_m_per_n.abs() + 1e-18
            );
            region.commit(tb);
        }
    }

    #[test]
    fn tension_for_elongation_inverts_the_elongation_law() {
        // The closed-form (quadratic in sqrt(T)) solve against the independent route: the
        // trial's elongation at the returned tension, plus the free span in series.
        let (rd, wd, rp, wp, span) = (0.1025, 0.9, 0.02, 2.5, 0.0777);
        let mut region =
            WrapRegion::with_regions(&[(rd, wd), (rp, wp)], MU, TPRE, G).with_series_span(span);
        let span_per_n = span / G;
        let total = |t: f64, r: &WrapRegion| span_per_n * (t - TPRE) + r.trial(t).elongation_m;
        let mut rng = 7u64;
        let mut tb = TPRE;
        for k in 0..2000 {
            tb = (tb + 30.0 * (lcg(&mut rng) - 0.5)).clamp(20.0, 300.0);
            region.commit(tb);
            let want = tb * (1.0 + 0.1 * (lcg(&mut rng) - 0.5));
            let target = total(want, &region);
            // Guesses from exact to far off: the segment search must not depend on them.
            let guess = match k % 3 {
                0 => want,
                1 => tb,
                _ => f64::NAN,
            };
            let t = region
                .tension_for_elongation(target, span_per_n, guess)
                .expect("a positive tension fits");
            assert!((t - want).abs() <= 1e-12 * want, "k {k}: {t} vs {want}");
            // The other spans' path (no precomputed leading coefficient) agrees.
            let other = region
                .tension_for_elongation(
                    target + span_per_n * (want - TPRE),
                    2.0 * span_per_n,
                    guess,
                )
                .expect("a positive tension fits");
            assert!(
                (other - want).abs() <= 1e-12 * want,
                "k {k}: {other} vs {want}"
            );
        }
    }

    #[test]
    fn committing_a_solved_law_equals_committing_its_tension() {
        // The plant commits the law its displacement solve ended on; the quasi-static
        // route searches the law again from the tension. Both must leave the same memory.
        let (rd, wd, rp, wp, span) = (0.1025, 0.9, 0.02, 2.5, 0.0777);
        let fresh =
            || WrapRegion::with_regions(&[(rd, wd), (rp, wp)], MU, TPRE, G).with_series_span(span);
        let (mut solved, mut searched) = (fresh(), fresh());
        let span_per_n = span / G;
        let mut rng = 11u64;
        let mut target = 0.0;
        for k in 0..3000 {
            // Small steps with frequent reversals, and now and then a held displacement.
            if k % 7 != 0 {
                target += 2e-5 * (lcg(&mut rng) - 0.5);
            }
            let (t, law) = solved
                .solve_for_elongation(target, span_per_n, f64::NAN)
                .expect("a positive tension fits");
            solved.commit_fresh(t, &law);
            searched.commit(t);
            assert_eq!(
                solved.breakpoint_count(),
                searched.breakpoint_count(),
                "k {k}"
            );
            for (a, b) in solved.verts.iter().zip(&searched.verts) {
                assert_eq!(
                    (a.t, a.p, a.m, a.tail, a.outer),
                    (b.t, b.p, b.m, b.tail, b.outer)
                );
            }
            // The next solve sees the committed state as the stored profile has it, to far
            // within the band it treats as unchanged.
            let stuck = span_per_n * (t - TPRE) + searched.elongation_m();
            let off = (solved.stuck_m - stuck).abs();
            assert!(off <= 1e-3 * solved.stuck_band_m, "k {k}: {off:e}");
        }
    }

    /// A dithering series-span region (a held servo's cable) with occasional long moves,
    /// as `(region, displacement)` after each commit of `steps`.
    fn dithered(steps: usize, seed: u64, mut each: impl FnMut(&WrapRegion, f64)) {
        let (rd, wd, rp, wp, span) = (0.1025, 0.9, 0.02, 2.5, 0.0777);
        let mut region =
            WrapRegion::with_regions(&[(rd, wd), (rp, wp)], MU, TPRE, G).with_series_span(span);
        let span_per_n = span / G;
        let mut rng = seed;
        let mut target = 0.0;
        for _ in 0..steps {
            let size = if lcg(&mut rng) < 0.05 { 2e-4 } else { 1e-5 };
            target += size * (lcg(&mut rng) - 0.5);
            let (t, law) = region
                .solve_for_elongation(target, span_per_n, f64::NAN)
                .expect("a positive tension fits");
            // As the plant commits: the solve's own elongation is kept beside the profile.
            region.commit_solved(t, &law, target);
            each(&region, target);
        }
    }

    #[test]
    fn a_reversal_law_is_the_walk_of_every_tension_it_covers() {
        // The top segment's law is built without a walk; it must be the very law the
        // walk builds, field for field, wherever it claims to hold.
        let mut built = 0;
        dithered(4000, 5, |region, _| {
            let top_t = region.committed_n;
            for rising in [false, true] {
                let Some(law) = region.reversal_law(rising) else {
                    continue;
                };
                built += 1;
                for f in [0.0, 0.3, 0.7, 1.0] {
                    let tb = law.lo + f * (law.hi - law.lo);
                    if !law.covers(tb) || (tb > top_t) != rising {
                        continue;
                    }
                    assert_eq!(law, region.build_law(tb), "tb {tb} rising {rising}");
                }
            }
        });
        assert!(built > 3000, "only {built} reversal laws");
    }

    #[test]
    fn the_tension_alone_is_the_solves_tension_bit_for_bit() {
        // The right-hand side's solve and the commit's solve share every step; probe both
        // on twin regions at displacements around the committed one, both ways and past
        // the top segment, so that the cache and the searches are exercised too. The
        // right-hand side's region knows the elongation its last commit was solved for
        // and picks its law from it first; the twin does not, so the probes within
        // rounding of that elongation, where the first pick can be the wrong side, check
        // that the pick never changes the answer.
        let (rd, wd, rp, wp, span) = (0.1025, 0.9, 0.02, 2.5, 0.0777);
        let twin =
            WrapRegion::with_regions(&[(rd, wd), (rp, wp)], MU, TPRE, G).with_series_span(span);
        let mut other = twin.clone();
        let span_per_n = span / G;
        let mut rng = 17u64;
        dithered(3000, 9, |region, target| {
            // `other` follows the same commits, so both see the same memory.
            other.verts.clone_from(&region.verts);
            other.generation = region.generation;
            other.refresh_committed();
            for (a, b) in other.laws.iter().zip(&region.laws) {
                a.set(b.get());
            }
            assert_eq!(region.solved_for_m.to_bits(), target.to_bits());
            let near = [
                target,
                target.next_up(),
                target.next_down(),
                region.stuck_m + region.stuck_band_m,
                (region.stuck_m + region.stuck_band_m).next_up(),
                region.stuck_m - region.stuck_band_m,
                (region.stuck_m - region.stuck_band_m).next_down(),
            ];
            for k in 0..4 + near.len() {
                let probe = near.get(k).copied().unwrap_or_else(|| {
                    let size = if lcg(&mut rng) < 0.2 { 4e-4 } else { 2e-5 };
                    target + size * (lcg(&mut rng) - 0.5)
                });
                let alone = region.tension_series(probe);
                let solved = other
                    .solve_for_elongation(probe, span_per_n, f64::NAN)
                    .map(|(t, _)| t);
                assert_eq!(alone.map(f64::to_bits), solved.map(f64::to_bits));
                // A first pick on the wrong side (the elongation kept beside the profile
                // put on either side of every probe) must be caught by the exact test.
                for wrong in [f64::NEG_INFINITY, f64::INFINITY] {
                    let mut misled = region.clone();
                    misled.solved_for_m = wrong;
                    let got = misled.tension_series(probe);
                    assert_eq!(got.map(f64::to_bits), solved.map(f64::to_bits));
                }
            }
        });
    }

    /// Everything a commit leaves in `r`, bit for bit, for comparing two regions.
    fn committed_bits(r: &WrapRegion) -> Vec<u64> {
        let mut bits = vec![
            r.stuck_m.to_bits(),
            r.stuck_band_m.to_bits(),
            r.committed_n.to_bits(),
            r.solved_for_m.to_bits(),
            r.generation,
        ];
        for v in &r.verts {
            bits.extend([v.s, v.t, v.p, v.m, v.tail].map(f64::to_bits));
            bits.push(u64::from(v.outer));
        }
        for law in &r.laws {
            let l = law.get();
            bits.extend([l.generation, l.index as u64, u64::from(l.rising)]);
            bits.extend([l.lo, l.hi, l.a, l.bt, l.q, l.c, l.beta].map(f64::to_bits));
            bits.extend([l.disc0, l.disc1, l.rest0, l.w_seg].map(f64::to_bits));
        }
        bits
    }

    #[test]
    fn a_boundary_commit_in_place_leaves_the_general_commits_memory() {
        // The plant's boundary commit takes its usual case (the root on the law cached for
        // its direction) without the law leaving the cache; wherever it answers, the
        // region it leaves must be the one the general solve and commit leave, and where
        // it does not answer it must change nothing. Dithered histories with long moves
        // pass segments, the shorter wrap's end and the plateau.
        let (rd, wd, rp, wp, span) = (0.1025, 0.9, 0.02, 2.5, 0.0777);
        let span_per_n = span / G;
        for seed in [3u64, 29, 101] {
            let mut general =
                WrapRegion::with_regions(&[(rd, wd), (rp, wp)], MU, TPRE, G).with_series_span(span);
            let mut rng = seed;
            let (mut target, mut in_place) = (0.0, 0);
            for k in 0..4000 {
                let size = if lcg(&mut rng) < 0.05 { 3e-4 } else { 1e-5 };
                if k % 11 != 0 {
                    target += size * (lcg(&mut rng) - 0.5);
                }
                let mut fast = general.clone();
                let before = committed_bits(&fast);
                let root = fast.boundary_root(target);
                let (t, law) = general
                    .solve_for_elongation(target, span_per_n, f64::NAN)
                    .expect("a positive tension fits");
                general.commit_solved(t, &law, target);
                match root {
                    Some(root) => {
                        assert_eq!(root.tension_n.to_bits(), t.to_bits(), "seed {seed} k {k}");
                        // The gross-slip check's growth (of the law, not of the profile).
                        assert_eq!(
                            fast.cached_growth(&root).to_bits(),
                            general.slip_growth_on(t, &law).to_bits()
                        );
                        fast.commit_cached(&root, target);
                        assert_eq!(
                            committed_bits(&fast),
                            committed_bits(&general),
                            "seed {seed} k {k}"
                        );
                        in_place += 1;
                    }
                    None => assert_eq!(committed_bits(&fast), before, "seed {seed} k {k}"),
                }
            }
            // Both ways are exercised (here a third of the commits take the in-place path;
            // in the plant, whose stages leave the right law cached, nearly all do).
            assert!(in_place > 1000, "seed {seed}: {in_place} of 4000");
        }
    }

    #[test]
    fn tension_for_elongation_reports_slack() {
        let region = WrapRegion::new(R, 2.0, MU, TPRE, G).with_series_span(0.08);
        // Shorter than the cable can get with any positive tension.
        let slack = region.tension_for_elongation(-1.0, 0.08 / G, TPRE);
        assert_eq!(slack, None);
    }
}
