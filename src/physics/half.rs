//! One half of the cable: free span, drum wrap and pulley wrap sharing the span tension.

use super::wrap::{WrapRegion, WrapTrial};

/// Elongation of a half if its span tension became a given value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfTrial {
    /// Elongation of the whole half relative to the preloaded state, m.
    pub elongation_m: f64,
    /// Its derivative with respect to the span tension, m/N (always > 0).
    pub d_elongation_m_per_n: f64,
    /// Drum wrap region.
    pub drum: WrapTrial,
    /// Pulley wrap region (from the contact point to the neutral point).
    pub pulley: WrapTrial,
}

/// A cable half: free span of length `span_m`, a wrap on the drum and a wrap on the pulley.
#[derive(Clone, Debug)]
pub struct CableHalf {
    span_m: f64,
    modulus_n: f64,
    preload_n: f64,
    /// Whether committed tensions are remembered (memory model) or every state is computed
    /// from the virgin preloaded cable (memoryless model).
    remembers: bool,
    drum: WrapRegion,
    pulley: WrapRegion,
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
            remembers,
            drum: WrapRegion::new(drum_radius_m, drum_wrap_rad, mu, preload_n, modulus_n),
            pulley: WrapRegion::new(
                pulley_radius_m,
                pulley_half_wrap_rad,
                mu,
                preload_n,
                modulus_n,
            ),
        }
    }

    /// Elongation if the span tension became `tension_n` (> 0), nothing committed.
    #[inline]
    pub fn trial(&self, tension_n: f64) -> HalfTrial {
        let drum = self.drum.trial(tension_n);
        let pulley = self.pulley.trial(tension_n);
        let span_per_n = self.span_m / self.modulus_n;
        HalfTrial {
            elongation_m: span_per_n * (tension_n - self.preload_n)
                + drum.elongation_m
                + pulley.elongation_m,
            d_elongation_m_per_n: span_per_n
                + drum.d_elongation_m_per_n
                + pulley.d_elongation_m_per_n,
            drum,
            pulley,
        }
    }

    /// Commit the span tension (updates the wrap memory; no-op for the memoryless model).
    pub fn commit(&mut self, tension_n: f64) {
        if self.remembers {
            self.drum.commit(tension_n);
            self.pulley.commit(tension_n);
        }
    }

    /// Commit a trial computed on the current profiles (no-op for the memoryless model).
    pub fn commit_trial(&mut self, trial: &HalfTrial) {
        if self.remembers {
            self.drum.commit_trial(&trial.drum);
            self.pulley.commit_trial(&trial.pulley);
        }
    }

    /// Forget all history.
    pub fn reset(&mut self) {
        self.drum.reset();
        self.pulley.reset();
    }

    /// Drum wrap region (for profiles and breakpoint counts).
    pub fn drum(&self) -> &WrapRegion {
        &self.drum
    }

    /// Pulley wrap region.
    pub fn pulley(&self) -> &WrapRegion {
        &self.pulley
    }

    /// Free-span length, m.
    pub fn span_m(&self) -> f64 {
        self.span_m
    }
}
