//! How far a long computation has got, reported to whoever asked, never printed here:
//! the computation calls a [`Progress`] with `done` of `total` units (runs, logs,
//! frequencies, cases), and the command line renders it (`run::progress`).

use std::sync::atomic::{AtomicUsize, Ordering};

/// Receives `done` of `total` units of a long computation. Called from worker threads
/// (hence `Sync`), in any order when the units run in parallel; `done` never exceeds
/// `total`. Any `Fn(usize, usize) + Sync` closure is one.
pub trait Progress: Sync {
    /// `done` of `total` units are finished.
    fn update(&self, done: usize, total: usize);
}

impl<F: Fn(usize, usize) + Sync> Progress for F {
    fn update(&self, done: usize, total: usize) {
        self(done, total)
    }
}

/// A [`Progress`] that ignores every report (library callers and tests).
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Progress for Silent {
    fn update(&self, _done: usize, _total: usize) {}
}

/// Counts finished units of parallel work and reports each to a [`Progress`].
pub struct Counter<'a> {
    done: AtomicUsize,
    total: usize,
    sink: &'a dyn Progress,
}

impl<'a> Counter<'a> {
    /// A counter of `total` units; reports `0 of total` at once, so a renderer can show
    /// the size of the work before the first unit ends.
    pub fn new(total: usize, sink: &'a dyn Progress) -> Self {
        sink.update(0, total);
        Self {
            done: AtomicUsize::new(0),
            total,
            sink,
        }
    }

    /// One more unit is finished.
    pub fn tick(&self) {
        let done = (self.done.fetch_add(1, Ordering::Relaxed) + 1).min(self.total);
        self.sink.update(done, self.total);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    #[test]
    fn a_counter_reports_every_unit_and_never_past_the_total() {
        let seen = Mutex::new(Vec::new());
        let sink = |d: usize, t: usize| seen.lock().map(|mut v| v.push((d, t))).unwrap_or(());
        let c = Counter::new(3, &sink);
        for _ in 0..4 {
            c.tick();
        }
        let seen = seen.into_inner().unwrap_or_default();
        assert_eq!(seen, vec![(0, 3), (1, 3), (2, 3), (3, 3), (3, 3)]);
        Silent.update(1, 2);
    }
}
