//! The reference sampled once and read by many runs: the cases of a tolerance sweep vary
//! the plant, not the reference, so each would otherwise evaluate the same signal at the
//! same instants (a sine's `sin` and `cos`, about 3 % of a 20 kHz memory-mode case).
//! Reading a sample from the table gives the very value the signal gives at that instant,
//! so runs that use it are bit for bit the runs that do not.

use std::sync::{Arc, Mutex};

use crate::signal::{Signal, SignalPoint};

/// Longest run a table is made for, control periods: 2 000 000 periods (100 s at
/// 20 kHz) take 48 MB; longer runs evaluate the signal at every period instead.
pub const MAX_SAMPLED_PERIODS: u64 = 2_000_000;

/// A signal's value, rate and acceleration at `t_k = k * ts` for `k = 0..=periods`, the
/// instants of a run's control periods, computed as the run computes them.
#[derive(Debug)]
pub struct SampledReference {
    signal: Signal,
    ts_bits: u64,
    points: Vec<SignalPoint>,
}

impl SampledReference {
    /// `signal` at `k * ts` (`ts` the control period, s, 5e-5 at 20 kHz) for `k` from 0
    /// to `periods`; `None` above [`MAX_SAMPLED_PERIODS`].
    pub fn new(signal: &Signal, ts: f64, periods: u64) -> Option<Self> {
        (periods <= MAX_SAMPLED_PERIODS).then(|| SampledReference {
            signal: signal.clone(),
            ts_bits: ts.to_bits(),
            points: (0..=periods).map(|k| signal.at(k as f64 * ts)).collect(),
        })
    }

    /// Whether this table holds `signal` at every instant `k * ts`, `k <= periods`.
    pub fn serves(&self, signal: &Signal, ts: f64, periods: u64) -> bool {
        self.ts_bits == ts.to_bits()
            && (self.points.len() as u64) > periods
            && self.signal == *signal
    }

    /// The sample at `t_k = k * ts`; `None` past the table.
    #[inline(always)]
    pub fn point(&self, k: u64) -> Option<SignalPoint> {
        usize::try_from(k)
            .ok()
            .and_then(|k| self.points.get(k))
            .copied()
    }
}

/// The last table made, shared by the runs of one study on every thread: a run whose
/// reference and instants it serves reads it, any other run makes (and leaves) its own.
#[derive(Debug, Default)]
pub struct ReferenceCache {
    last: Mutex<Option<Arc<SampledReference>>>,
}

impl ReferenceCache {
    /// An empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// The table of `signal` at `k * ts`, `k <= periods`, made on the first call for
    /// them; `None` when the run is too long for one.
    pub fn get(&self, signal: &Signal, ts: f64, periods: u64) -> Option<Arc<SampledReference>> {
        // A poisoned lock only means another run panicked; the table it guards is whole.
        let held = |g: &Option<Arc<SampledReference>>| {
            g.as_ref()
                .filter(|s| s.serves(signal, ts, periods))
                .cloned()
        };
        if let Some(s) = held(&self.last.lock().unwrap_or_else(|e| e.into_inner())) {
            return Some(s);
        }
        // Made outside the lock: another thread may make the same table meanwhile, which
        // costs a duplicate, never a wrong value.
        let fresh = Arc::new(SampledReference::new(signal, ts, periods)?);
        *self.last.lock().unwrap_or_else(|e| e.into_inner()) = Some(Arc::clone(&fresh));
        Some(fresh)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(f: f64) -> Signal {
        Signal::Sine {
            amplitude_rad: 0.01,
            frequency_hz: f,
            phase_rad: 0.3,
            offset_rad: 0.001,
        }
    }

    #[test]
    fn a_table_holds_the_signal_at_each_instant_bit_for_bit() {
        let ts = 1.0 / 20_000.0;
        let s = sine(0.25);
        let table = SampledReference::new(&s, ts, 40_000).expect("short enough");
        for k in [0u64, 1, 2, 17, 19_999, 40_000] {
            let want = s.at(k as f64 * ts);
            let got = table.point(k).expect("inside");
            assert_eq!(got.value.to_bits(), want.value.to_bits(), "k = {k}");
            assert_eq!(got.rate.to_bits(), want.rate.to_bits(), "k = {k}");
            assert_eq!(got.accel.to_bits(), want.accel.to_bits(), "k = {k}");
        }
        assert_eq!(table.point(40_001), None);
    }

    #[test]
    fn a_table_serves_only_its_signal_period_and_length() {
        let ts = 1.0 / 20_000.0;
        let table = SampledReference::new(&sine(0.25), ts, 100).expect("short");
        assert!(table.serves(&sine(0.25), ts, 100));
        assert!(table.serves(&sine(0.25), ts, 50));
        assert!(!table.serves(&sine(0.25), ts, 101));
        assert!(!table.serves(&sine(0.2500001), ts, 100));
        assert!(!table.serves(&sine(0.25), 1.0 / 10_000.0, 100));
        assert!(SampledReference::new(&sine(0.25), ts, MAX_SAMPLED_PERIODS + 1).is_none());
    }

    #[test]
    fn the_cache_hands_out_one_table_until_the_run_changes() {
        let ts = 1.0 / 20_000.0;
        let cache = ReferenceCache::new();
        let a = cache.get(&sine(0.25), ts, 1000).expect("short");
        let b = cache.get(&sine(0.25), ts, 1000).expect("short");
        assert!(Arc::ptr_eq(&a, &b));
        let c = cache.get(&sine(0.5), ts, 1000).expect("short");
        assert!(!Arc::ptr_eq(&a, &c));
        assert!(c.serves(&sine(0.5), ts, 1000));
        assert!(cache.get(&sine(0.5), ts, MAX_SAMPLED_PERIODS + 1).is_none());
    }
}
