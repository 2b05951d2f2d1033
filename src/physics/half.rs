//! One half of the cable: free span, drum wrap and pulley wrap sharing the span tension.

use super::wrap::{CachedRoot, WrapLaw, WrapRegion, WrapTrial};

/// Elongation of a half if its span tension became a given value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfTrial {
    /// Elongation of the whole half relative to the preloaded state, m.
    pub elongation_m: f64,
    /// Its derivative with respect to the span tension, m/N (always > 0).
    pub d_elongation_m_per_n: f64,
    /// Second derivative, m/N^2 (the free span is linear: the wrap's).
    pub(crate) d2_elongation: f64,
    /// The wrap trial, for committing and for the slip zones.
    wrap: WrapTrial,
}

/// Where the slip zones of a half end for a trial tension.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfSlip {
    /// `exp(mu*s)` for the slip zone's length `s` over the stored profile (1 = no slip
    /// zone; about 1.1 for a 0.5 rad zone at mu = 0.2): the angles follow from it with a
    /// logarithm only when asked for ([`CableHalf::slip_angles_rad`]).
    pub growth: f64,
    /// The drum slip zone reaches the anchor (the profile is cut there).
    pub drum_anchor_reached: bool,
    /// The pulley slip zone reaches the neutral point: gross slip.
    pub pulley_neutral_reached: bool,
}

/// Span tension of a half solved for a prescribed elongation, with the wrap law that
/// holds there (valid until the next commit).
#[derive(Clone, Copy, Debug)]
pub(crate) struct HalfSolution {
    /// Span tension, N.
    pub tension_n: f64,
    law: WrapLaw,
    /// The elongation it was solved for, m.
    elongation_m: f64,
}

/// A cable half: free span of length `span_m`, a wrap on the drum and a wrap on the pulley.
///
/// Both wraps start at the free span and see the same boundary tension, so their tension
/// profiles are one function of the wrap angle cut at different lengths; they are stored
/// once ([`WrapRegion::with_regions`]).
#[derive(Clone, Debug)]
pub struct CableHalf {
    span_m: f64,
    modulus_n: f64,
    preload_n: f64,
    drum_wrap_rad: f64,
    pulley_wrap_rad: f64,
    drum_radius_m: f64,
    pulley_radius_m: f64,
    mu: f64,
    /// `exp(mu*drum_wrap)` and `exp(mu*pulley_wrap)`: the slip growths that reach the
    /// anchor and the neutral point.
    drum_growth: f64,
    pulley_growth: f64,
    /// Whether committed tensions are remembered (memory model) or every state is computed
    /// from the virgin preloaded cable (memoryless model).
    remembers: bool,
    wrap: WrapRegion,
}

impl CableHalf {
    /// A preloaded half.
    ///
    /// * `span_m`: free-span length (0.0777 m on the paper bench);
    /// * `drum_radius_m`, `drum_wrap_rad`: drum radius and wrap from contact point to anchor;
    /// * `pulley_radius_m`, `pulley_half_wrap_rad`: pulley radius and wrap from contact point
    ///   to the neutral point (half of the total pulley wrap).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        span_m: f64,
        drum_radius_m: f64,
        drum_wrap_rad: f64,
        pulley_radius_m: f64,
        pulley_half_wrap_rad: f64,
        mu: f64,
        preload_n: f64,
        modulus_n: f64,
        remembers: bool,
    ) -> Self {
        CableHalf {
            span_m,
            modulus_n,
            preload_n,
            drum_wrap_rad,
            pulley_wrap_rad: pulley_half_wrap_rad,
            drum_radius_m,
            pulley_radius_m,
            mu,
            drum_growth: (mu * drum_wrap_rad).exp(),
            pulley_growth: (mu * pulley_half_wrap_rad).exp(),
            remembers,
            wrap: WrapRegion::with_regions(
                &[
                    (drum_radius_m, drum_wrap_rad),
                    (pulley_radius_m, pulley_half_wrap_rad),
                ],
                mu,
                preload_n,
                modulus_n,
            )
            .with_series_span(span_m),
        }
    }

    /// Elongation if the span tension became `tension_n` (> 0), nothing committed.
    #[inline]
    pub fn trial(&self, tension_n: f64) -> HalfTrial {
        self.with_span(self.wrap.trial(tension_n), tension_n)
    }

    /// A wrap trial at `tension_n` with the free span added.
    #[inline]
    fn with_span(&self, wrap: WrapTrial, tension_n: f64) -> HalfTrial {
        let span_per_n = self.wrap.series_span_per_n();
        HalfTrial {
            elongation_m: span_per_n * (tension_n - self.preload_n) + wrap.elongation_m,
            d_elongation_m_per_n: span_per_n + wrap.d_elongation_m_per_n,
            d2_elongation: wrap.d2_elongation,
            wrap,
        }
    }

    /// Slip zones of a trial on the drum and on the pulley.
    #[inline]
    pub fn slip(&self, trial: &HalfTrial) -> HalfSlip {
        self.slip_for_growth(self.wrap.slip_growth(&trial.wrap))
    }

    #[inline]
    fn slip_for_growth(&self, g: f64) -> HalfSlip {
        HalfSlip {
            growth: g,
            drum_anchor_reached: g >= self.drum_growth,
            pulley_neutral_reached: g >= self.pulley_growth,
        }
    }

    /// Slip-zone lengths `(drum, pulley)`, rad, for a slip growth `exp(mu*s)` (see
    /// [`HalfSlip::growth`]): each at most its region's wrap.
    pub fn slip_angles_rad(&self, growth: f64) -> (f64, f64) {
        let s = (growth.max(1.0).ln() / self.mu).min(self.wrap.wrap_rad());
        (s.min(self.drum_wrap_rad), s.min(self.pulley_wrap_rad))
    }

    /// Span tension (N) at which the half's elongation equals `elongation_m` (m), the
    /// memory left unchanged: the displacement-driven solve of the dynamic plant. Exact
    /// (closed form on the current stored segment, safeguarded Newton across segments);
    /// `guess_n` (N, e.g. a tangent-line prediction) picks the segment when the last one
    /// used does not hold. `None` when no positive tension fits: the span goes slack.
    #[inline]
    pub fn tension_for_elongation(&self, elongation_m: f64, guess_n: f64) -> Option<f64> {
        self.wrap
            .tension_for_elongation(elongation_m, self.wrap.series_span_per_n(), guess_n)
    }

    /// [`Self::tension_for_elongation`] with what committing its result needs; a search,
    /// when one is needed, starts from the committed state.
    #[inline(always)]
    pub(crate) fn solve_for_elongation(&self, elongation_m: f64) -> Option<HalfSolution> {
        self.wrap
            .solve_for_elongation(elongation_m, self.wrap.series_span_per_n(), f64::NAN)
            .map(|(tension_n, law)| HalfSolution {
                tension_n,
                law,
                elongation_m,
            })
    }

    /// [`Self::solve_for_elongation`], the tension alone (N): the plant's right-hand
    /// side, which never commits.
    #[inline(always)]
    pub(crate) fn tension_series(&self, elongation_m: f64) -> Option<f64> {
        self.wrap.tension_series(elongation_m)
    }

    /// [`Self::solve_for_elongation`] in its usual case for a half that remembers: the
    /// root on the law cached for its direction ([`WrapRegion::boundary_root`]); `None`
    /// otherwise.
    #[inline(always)]
    pub(crate) fn boundary_root(&mut self, elongation_m: f64) -> Option<CachedRoot> {
        if self.remembers {
            self.wrap.boundary_root(elongation_m)
        } else {
            None
        }
    }

    /// [`Self::solution_slip`] of a root from [`Self::boundary_root`].
    #[inline(always)]
    pub(crate) fn cached_slip(&self, root: &CachedRoot) -> HalfSlip {
        self.slip_for_growth(self.wrap.cached_growth(root))
    }

    /// [`Self::commit_solution`] of a root from [`Self::boundary_root`] for elongation
    /// `elongation_m` (m), nothing committed since.
    #[inline(always)]
    pub(crate) fn commit_cached(&mut self, root: &CachedRoot, elongation_m: f64) {
        self.wrap.commit_cached(root, elongation_m);
    }

    /// Slip growth of a solution (see [`HalfSlip::growth`]), and whether its slip zones
    /// reach the drum anchor and the pulley's neutral point.
    #[inline]
    pub(crate) fn solution_slip(&self, solution: &HalfSolution) -> HalfSlip {
        self.slip_for_growth(self.wrap.slip_growth_on(solution.tension_n, &solution.law))
    }

    /// Commit a solution found on the current profile (no-op for the memoryless model).
    #[inline]
    pub(crate) fn commit_solution(&mut self, solution: &HalfSolution) {
        if self.remembers {
            self.wrap
                .commit_solved(solution.tension_n, &solution.law, solution.elongation_m);
        }
    }

    /// Commit the span tension (updates the wrap memory; no-op for the memoryless model).
    pub fn commit(&mut self, tension_n: f64) {
        if self.remembers {
            self.wrap.commit(tension_n);
        }
    }

    /// Commit a trial computed on the current profile (no-op for the memoryless model).
    pub fn commit_trial(&mut self, trial: &HalfTrial) {
        if self.remembers {
            self.wrap.commit_trial(&trial.wrap);
        }
    }

    /// [`Self::commit_trial`] for a trial known to be computed since the last commit.
    #[inline]
    pub(crate) fn commit_current(&mut self, trial: &HalfTrial) {
        if self.remembers {
            self.wrap.commit_current(&trial.wrap);
        }
    }

    /// [`Self::trial`] with a law held by the caller (see [`WrapRegion::trial_with`]).
    #[inline]
    pub(crate) fn trial_with(&self, law: &mut WrapLaw, tension_n: f64) -> HalfTrial {
        self.with_span(self.wrap.trial_with(law, tension_n), tension_n)
    }

    /// Forget all history.
    pub fn reset(&mut self) {
        self.wrap.reset();
    }

    /// The shared wrap profile (breakpoint counts, slope checks).
    pub fn wrap(&self) -> &WrapRegion {
        &self.wrap
    }

    /// The wrap profile at span tension `tension_n`: the committed one for the memory
    /// model (whose last commit is that tension), the virgin profile loaded to the tension
    /// for the memoryless model.
    fn profile_at(&self, tension_n: f64) -> std::borrow::Cow<'_, WrapRegion> {
        if self.remembers {
            std::borrow::Cow::Borrowed(&self.wrap)
        } else {
            let mut w = self.wrap.clone();
            w.reset();
            w.commit(tension_n);
            std::borrow::Cow::Owned(w)
        }
    }

    /// Drum wrap profile `(s rad, T N)` from the contact point to the anchor, at span
    /// tension `tension_n` (the last committed one for the memory model).
    pub fn drum_breakpoints(&self, tension_n: f64) -> Vec<(f64, f64)> {
        self.profile_at(tension_n)
            .breakpoints_within(self.drum_wrap_rad)
    }

    /// Pulley wrap profile `(s rad, T N)` from the contact point to the neutral point, at
    /// span tension `tension_n`.
    pub fn pulley_breakpoints(&self, tension_n: f64) -> Vec<(f64, f64)> {
        self.profile_at(tension_n)
            .breakpoints_within(self.pulley_wrap_rad)
    }

    /// Elongations relative to the preloaded state at span tension `tension_n` (the last
    /// committed one for the memory model), m: `(free span, drum wrap, pulley wrap)`.
    /// Off the hot path: for reports and plots.
    pub fn region_elongations_m(&self, tension_n: f64) -> (f64, f64, f64) {
        let profile = self.profile_at(tension_n);
        (
            self.span_m * (tension_n - self.preload_n) / self.modulus_n,
            self.drum_radius_m * profile.tension_integral_within(self.drum_wrap_rad)
                / self.modulus_n,
            self.pulley_radius_m * profile.tension_integral_within(self.pulley_wrap_rad)
                / self.modulus_n,
        )
    }

    /// Free-span length, m.
    pub fn span_m(&self) -> f64 {
        self.span_m
    }
}
