//! Progress of long work on the terminal: one line on stderr, rewritten in place, e.g.
//! `error budget: 4/7 runs, 12 s`; nothing at all when stderr is not a terminal (a pipe,
//! a log file, CI), so redirected output stays clean.
//!
//! Hooking a computation: pass a [`Bar`] wherever a [`crate::progress::Progress`] is
//! taken, and [`Bar::finish`] it when the work returns; for work that reports no counts,
//! hold a [`Spinner`] while it runs.

use std::io::IsTerminal;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A bar of `done/total units` with the elapsed time, on stderr.
pub struct Bar {
    bar: ProgressBar,
    /// Whether the bar was put on the terminal (at its first report: work that never
    /// reports, like a run without an error budget, shows nothing).
    shown: std::sync::Once,
}

/// Draw target: stderr when it is a terminal, nothing otherwise.
fn target() -> ProgressDrawTarget {
    if std::io::stderr().is_terminal() {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    }
}

impl Bar {
    /// A bar for the stage `label` (`"error budget"`) counting `unit`s (`"runs"`); drawn
    /// from its first update on.
    pub fn new(label: &str, unit: &str) -> Self {
        let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::hidden());
        let template = format!("{{msg}}: {{pos}}/{{len}} {unit}, {{elapsed}} [{{bar:30}}]");
        bar.set_style(
            ProgressStyle::with_template(&template)
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_message(label.to_string());
        Self {
            bar,
            shown: std::sync::Once::new(),
        }
    }

    /// Removes the line: the work is over.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

impl crate::progress::Progress for Bar {
    fn update(&self, done: usize, total: usize) {
        self.bar.set_length(total as u64);
        self.shown.call_once(|| {
            self.bar.reset_elapsed();
            self.bar.set_draw_target(target());
        });
        // Parallel units report out of order: the bar only moves forward.
        if done as u64 > self.bar.position() {
            self.bar.set_position(done as u64);
        }
    }
}

/// A line `label: what, 12 s` that keeps its elapsed time current while work that
/// reports no counts runs; removed when dropped.
pub struct Spinner {
    bar: ProgressBar,
}

impl Spinner {
    /// Starts showing `label: what` (`"leave-one-out"`, `"11 logs"`) with the time since.
    pub fn start(label: &str, what: &str) -> Self {
        let bar = ProgressBar::with_draw_target(None, target());
        bar.set_style(
            ProgressStyle::with_template("{spinner} {msg}, {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        bar.set_message(format!("{label}: {what}"));
        bar.enable_steady_tick(Duration::from_millis(250));
        Self { bar }
    }
}

impl Drop for Spinner {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}
