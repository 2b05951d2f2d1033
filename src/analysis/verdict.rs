//! One verdict on a design: every requirement of `[closed_loop.requirements]` and the
//! pointing target, each with its measured value, its margin and pass or fail. Every
//! command (`run`, `compare`, `margins`, `freqresp`, `sweep`, `design`) judges a design
//! with [`judge`] or [`evaluate`], so they cannot disagree.
//!
//! What is judged:
//! - stability of the sampled closed loop, from its poles (never from margins);
//! - phase margin over every gain crossover, gain margin up and down over every phase
//!   crossover, and the sensitivity peak, each at the free-span cable and at the tangent
//!   stiffness of the operating load (the operating range of a cable drive: small motions
//!   see the free span, large loaded ones the softer tangent), with the scenario's
//!   computation delay;
//! - the pointing error of the judged compensation mode over the metrics window, from the
//!   nonlinear simulation; a mode that stopped has no figures, it fails with its reason;
//! - where declared: RMS error, line-of-sight jitter, step settling, base-motion rejection.

use serde::Serialize;

use super::linear::{tangent_half_stiffness, LinearLoop};
use super::margins::{GainDirection, Margins};
use crate::closed_loop::params::{ClosedLoopParams, CompensationMode};
use crate::closed_loop::sim::{
    run_closed_loop, ClosedLoopError, ClosedLoopSetup, ModeResult, RunOptions,
};
use crate::metrics::Criterion;

/// Points of the log grid the margins are read on (refined by bisection at each crossing).
pub const MARGIN_POINTS: usize = 4000;

/// One requirement judged.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Check {
    /// Short identifier: `stable`, `phase_margin`, `gain_margin_up`, `gain_margin_down`,
    /// `sensitivity_peak`, `operating_load`, `pointing`, `rms`, `jitter`, `settling`,
    /// `base_rejection`.
    pub requirement: &'static str,
    /// Where it was judged: `free span`, `tangent at 1.5 N m`, or the mode's name.
    pub condition: String,
    /// Measured value in `unit`; `None` when there is none (an unstable loop's margins, a
    /// stopped mode's error), with the reason in `note`.
    pub measured: Option<f64>,
    /// Required value in `unit`.
    pub limit: f64,
    /// Unit of `measured`, `limit` and `margin`.
    pub unit: &'static str,
    /// `>=` (at least the limit) or `<=` (at most).
    pub relation: &'static str,
    /// How far inside the limit the measured value is (negative: by how much it misses).
    pub margin: Option<f64>,
    /// Whether the requirement is met.
    pub passes: bool,
    /// Where the worst value was found, or why there is no value.
    pub note: String,
}

/// The loop's margins at one cable stiffness of the operating range.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OperatingPoint {
    /// `free span` or `tangent at M N m`.
    pub condition: String,
    /// Transmitted torque, N m (0 for the free span).
    pub load_nm: f64,
    /// Stiffness of each cable half, N/m.
    pub half_stiffness_n_per_m: f64,
    /// Margins over every crossing (none when unstable).
    pub margins: Margins,
}

/// The verdict on a design.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdict {
    /// Whether every requirement is met.
    pub passes: bool,
    /// Compensation mode whose pointing error was judged.
    pub judged_mode: CompensationMode,
    /// Every requirement, in a fixed order.
    pub checks: Vec<Check>,
    /// Margins at each stiffness of the operating range.
    pub operating_range: Vec<OperatingPoint>,
}

impl Verdict {
    /// The worst measured value of a requirement over its conditions (the one with the
    /// least margin); `None` when no condition has a value (an unstable loop's margins).
    pub fn worst_value(&self, requirement: &str) -> Option<f64> {
        self.checks
            .iter()
            .filter(|c| c.requirement == requirement)
            .filter_map(|c| Some((c.measured?, c.margin?)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(v, _)| v)
    }

    /// The failing requirements in words (empty when the design passes).
    pub fn reasons(&self) -> Vec<String> {
        self.checks
            .iter()
            .filter(|c| !c.passes)
            .map(Check::sentence)
            .collect()
    }

    /// One line: `meets every requirement (9 of 9)` or `FAILS 2 of 9: ...` with the
    /// first reason.
    pub fn headline(&self) -> String {
        let n = self.checks.len();
        let failing: Vec<&Check> = self.checks.iter().filter(|c| !c.passes).collect();
        match failing.first() {
            None => format!("verdict: PASS, meets every requirement ({n} of {n})"),
            Some(first) => format!(
                "verdict: FAIL, misses {} of {n} requirements; first: {}",
                failing.len(),
                first.sentence()
            ),
        }
    }

    /// Every crossing at each stiffness of the operating range, for the console.
    pub fn range_table(&self) -> String {
        range_table(&self.operating_range)
    }

    /// The verdict table for the console: one row per requirement, then the headline.
    pub fn table(&self) -> String {
        let mut out = format!(
            "{:<18} {:<22} {:>12} {:>12} {:>10}  {:<4}  {}\n",
            "requirement", "condition", "measured", "limit", "margin", "", "where / why"
        );
        for c in &self.checks {
            let value = |v: Option<f64>| v.map_or_else(|| "-".to_string(), fmt_value);
            let measured = c
                .measured
                .map_or_else(|| "-".to_string(), |v| fmt_measured(v, c.limit));
            out.push_str(&format!(
                "{:<18} {:<22} {:>12} {:>12} {:>10}  {:<4}  {}\n",
                c.requirement,
                c.condition,
                measured,
                format!("{} {}", c.relation, fmt_value(c.limit)),
                value(c.margin),
                if c.passes { "ok" } else { "FAIL" },
                if c.unit.is_empty() {
                    c.note.clone()
                } else if c.note.is_empty() {
                    format!("[{}]", c.unit)
                } else {
                    format!("[{}] {}", c.unit, c.note)
                }
            ));
        }
        out.push_str(&self.headline());
        out.push('\n');
        out
    }
}

/// Every crossing at each of `points` (stiffnesses of an operating range), for the console.
pub fn range_table(points: &[OperatingPoint]) -> String {
    let mut out = String::new();
    for point in points {
        out.push_str(&format!(
            "{} (each cable half {} N/m):\n",
            point.condition,
            crate::significant(point.half_stiffness_n_per_m, 4)
        ));
        for line in point.margins.crossing_lines() {
            out.push_str(&format!("  {line}\n"));
        }
        if let Some(bw) = point.margins.bandwidth_hz {
            out.push_str(&format!(
                "  bandwidth (-3 dB of T) {} Hz\n",
                crate::significant(bw, 4)
            ));
        }
    }
    out
}

fn fmt_value(v: f64) -> String {
    crate::compact(v)
}

/// A measured value beside its limit, with the digits that tell them apart: a pole at
/// 0.99995 against `< 1` must not read `1 < 1 ok`.
fn fmt_measured(v: f64, limit: f64) -> String {
    let short = fmt_value(v);
    if v == limit || short != fmt_value(limit) {
        return short;
    }
    (5..=17)
        .find(|&digits| {
            crate::significant(v, digits)
                .parse::<f64>()
                .is_ok_and(|shown| shown != limit)
        })
        .map_or_else(
            || crate::number(v),
            |digits| {
                let text = crate::significant(v, digits);
                if text.contains('.') && !text.contains('e') {
                    text.trim_end_matches('0').to_string()
                } else {
                    text
                }
            },
        )
}

impl Check {
    /// The check as a sentence: `phase margin at tangent at 1.5 N m: 24.1 deg, required
    /// >= 35 deg (at 31.2 Hz)`.
    pub fn sentence(&self) -> String {
        let with_unit = |v: f64| {
            if self.unit.is_empty() {
                fmt_value(v)
            } else {
                format!("{} {}", fmt_value(v), self.unit)
            }
        };
        let measured = self.measured.map_or_else(
            || "no value".to_string(),
            |v| {
                let text = fmt_measured(v, self.limit);
                if self.unit.is_empty() {
                    text
                } else {
                    format!("{text} {}", self.unit)
                }
            },
        );
        let mut s = format!(
            "{} ({}): {measured}, required {} {}",
            self.requirement.replace('_', " "),
            self.condition,
            self.relation,
            with_unit(self.limit)
        );
        if !self.note.is_empty() {
            s.push_str(&format!("; {}", self.note));
        }
        s
    }
}

fn check(
    requirement: &'static str,
    condition: &str,
    measured: Option<f64>,
    (relation, limit): (&'static str, f64),
    unit: &'static str,
    note: String,
) -> Check {
    let margin = measured.map(|m| {
        if relation.starts_with('>') {
            m - limit
        } else {
            limit - m
        }
    });
    Check {
        requirement,
        condition: condition.to_string(),
        measured,
        limit,
        unit,
        relation,
        margin,
        passes: margin.is_some_and(|m| m >= 0.0),
        note,
    }
}

/// The operating load the margins are held at, N m: `requirements.operating_load_nm`, or
/// the largest torque the scenario's load can put on the drum.
pub fn operating_load_nm(setup: &ClosedLoopSetup<'_>) -> f64 {
    setup
        .params
        .requirements
        .operating_load_nm
        .unwrap_or_else(|| setup.load.peak_torque_nm())
        .abs()
}

/// The margin checks of one operating point.
fn margin_checks(p: &ClosedLoopParams, point: &OperatingPoint, out: &mut Vec<Check>) {
    let req = &p.requirements;
    let m = &point.margins;
    let cond = point.condition.as_str();
    if !m.stable {
        let note = m.instability.map_or_else(
            || "the sampled closed loop has a pole on or outside the unit circle".to_string(),
            |i| {
                format!(
                    "largest pole |z| = {} at {} Hz, growing at {} 1/s: no margins",
                    crate::significant(i.pole_magnitude, 6),
                    crate::significant(i.frequency_hz, 4),
                    crate::significant(i.growth_per_s, 4)
                )
            },
        );
        // An unstable loop's margins are not numbers worth showing: only its pole.
        let mut c = check(
            "stable",
            cond,
            Some(m.spectral_radius),
            ("<", 1.0),
            "",
            note,
        );
        c.passes = false;
        out.push(c);
        return;
    }
    out.push(check(
        "stable",
        cond,
        Some(m.spectral_radius),
        ("<", 1.0),
        "",
        "largest closed-loop pole |z|".into(),
    ));
    let n_gain = m.gain_crossovers.len();
    out.push(match m.worst_gain_crossover() {
        Some(c) => check(
            "phase_margin",
            cond,
            Some(c.phase_margin_deg),
            (">=", req.min_phase_margin_deg),
            "deg",
            format!(
                "at {} Hz{}",
                crate::significant(c.frequency_hz, 4),
                if n_gain > 1 {
                    format!(", worst of {n_gain} gain crossovers")
                } else {
                    String::new()
                }
            ),
        ),
        None => {
            let mut c = check(
                "phase_margin",
                cond,
                None,
                (">=", req.min_phase_margin_deg),
                "deg",
                "|L| never crosses 1 below Nyquist: no phase margin".into(),
            );
            c.passes = false;
            c
        }
    });
    for (requirement, direction) in [
        ("gain_margin_up", GainDirection::Up),
        ("gain_margin_down", GainDirection::Down),
    ] {
        let n = m
            .phase_crossovers
            .iter()
            .filter(|c| c.direction == direction)
            .count();
        let c = match m.worst_phase_crossover(direction) {
            Some(c) => check(
                requirement,
                cond,
                Some(c.gain_margin_db),
                (">=", req.min_gain_margin_db),
                "dB",
                format!(
                    "at {} Hz{}",
                    crate::significant(c.frequency_hz, 4),
                    if n > 1 {
                        format!(", worst of {n} phase crossovers")
                    } else {
                        String::new()
                    }
                ),
            ),
            // No crossing in this direction: the gain may move without bound that way.
            None => Check {
                requirement,
                condition: cond.to_string(),
                measured: None,
                limit: req.min_gain_margin_db,
                unit: "dB",
                relation: ">=",
                margin: None,
                passes: true,
                note: format!(
                    "no phase crossover with the gain {} from 1: unbounded",
                    if direction == GainDirection::Up {
                        "below"
                    } else {
                        "above"
                    }
                ),
            },
        };
        out.push(c);
    }
    if let (Some(ms), Some(f)) = (m.ms, m.ms_hz) {
        out.push(check(
            "sensitivity_peak",
            cond,
            Some(ms),
            ("<=", req.max_ms),
            "",
            format!("Ms at {} Hz", crate::significant(f, 4)),
        ));
    }
}

/// One stiffness of the operating range and its linear loop.
#[derive(Clone, Debug)]
pub struct OperatingLoop {
    /// `free span` or `tangent at M N m`.
    pub condition: String,
    /// Transmitted torque, N m (0 for the free span).
    pub load_nm: f64,
    /// Stiffness of each cable half, N/m.
    pub half_stiffness_n_per_m: f64,
    /// The exact linear reference at that stiffness.
    pub lin: LinearLoop,
}

/// The linear loops of the operating range: the free span, and the tangent at the
/// operating load when that load is above zero; with them, why there is no tangent when
/// the cable cannot carry that load (a span would go slack first).
pub fn operating_loops(setup: &ClosedLoopSetup<'_>) -> (Vec<OperatingLoop>, Option<String>) {
    let p = setup.params;
    let free = ClosedLoopParams::half_stiffness_n_per_m(setup.drive);
    let mut loops = vec![OperatingLoop {
        condition: "free span".into(),
        load_nm: 0.0,
        half_stiffness_n_per_m: free,
        lin: LinearLoop::with_half_stiffness(p, setup.drive, free),
    }];
    let load = operating_load_nm(setup);
    let mut problem = None;
    if load > 0.0 {
        match tangent_half_stiffness(setup.drive, load) {
            Ok(k) => loops.push(OperatingLoop {
                condition: format!("tangent at {} N m", crate::compact(load)),
                load_nm: load,
                half_stiffness_n_per_m: k,
                lin: LinearLoop::with_half_stiffness(p, setup.drive, k),
            }),
            Err(message) => problem = Some(message),
        }
    }
    (loops, problem)
}

impl OperatingLoop {
    /// Its margins over every crossing, as the verdict reads them.
    pub fn point(&self) -> OperatingPoint {
        OperatingPoint {
            condition: self.condition.clone(),
            load_nm: self.load_nm,
            half_stiffness_n_per_m: self.half_stiffness_n_per_m,
            margins: self.lin.margins(MARGIN_POINTS),
        }
    }
}

/// The operating range of a setup with the margins at each stiffness (see
/// [`operating_loops`]).
pub fn operating_range(setup: &ClosedLoopSetup<'_>) -> (Vec<OperatingPoint>, Option<String>) {
    let (loops, problem) = operating_loops(setup);
    (loops.iter().map(OperatingLoop::point).collect(), problem)
}

/// The verdict of `setup` given the simulated result of its judged mode (`judged`, any
/// other mode is refused by the caller: see [`ClosedLoopParams::judged_mode`]).
pub fn judge(setup: &ClosedLoopSetup<'_>, judged: &ModeResult) -> Verdict {
    let p = setup.params;
    let req = &p.requirements;
    let mut checks = Vec::new();
    let (range, problem) = operating_range(setup);
    for point in &range {
        margin_checks(p, point, &mut checks);
    }
    if let Some(message) = problem {
        let mut c = check(
            "operating_load",
            &format!(
                "tangent at {} N m",
                crate::compact(operating_load_nm(setup))
            ),
            None,
            ("<=", operating_load_nm(setup)),
            "N m",
            format!("no tangent stiffness: {message}"),
        );
        c.passes = false;
        checks.push(c);
    }
    let mode = judged.mode.name();
    let no_figures = judged.no_figures_reason();
    let m = &judged.metrics;
    let none_because = |what: &str| no_figures.clone().unwrap_or_else(|| format!("no {what}"));
    // Pointing: the peak error, or under a stare the error after settling of every step.
    let pointing = if no_figures.is_some() {
        let mut c = check(
            "pointing",
            mode,
            None,
            ("<=", p.target_mrad),
            "mrad",
            none_because("error"),
        );
        c.passes = false;
        c
    } else if m.criterion == Criterion::Steps {
        let s = m.step_summary.as_ref();
        let after = s.and_then(|s| s.error_after_settling_peak_mrad);
        let settled = s.is_some_and(|s| s.settled == s.judged);
        let mut c = check(
            "pointing",
            mode,
            if settled { after } else { None },
            ("<=", p.target_mrad),
            "mrad",
            match s {
                Some(s) if s.settled < s.judged => format!(
                    "{} of {} steps did not settle (final error up to {} mrad)",
                    s.judged - s.settled,
                    s.judged,
                    crate::compact(s.max_final_error_mrad)
                ),
                _ => "peak error after settling, every step".into(),
            },
        );
        c.passes = c.passes && m.passes_target;
        c
    } else {
        check(
            "pointing",
            mode,
            Some(m.peak_mrad),
            ("<=", p.target_mrad),
            "mrad",
            format!(
                "peak error over {}-{} s",
                crate::compact(m.window_s[0]),
                crate::compact(m.window_s[1])
            ),
        )
    };
    checks.push(pointing);
    let ok = no_figures.is_none();
    let optional = |requirement: &'static str,
                    value: Option<f64>,
                    limit: f64,
                    unit: &'static str,
                    what: &str,
                    note: String| {
        let mut c = check(
            requirement,
            mode,
            value.filter(|_| ok),
            ("<=", limit),
            unit,
            if ok && value.is_some() {
                note
            } else {
                none_because(what)
            },
        );
        c.passes = c.passes && ok;
        c
    };
    if let Some(limit) = req.max_rms_mrad {
        checks.push(optional(
            "rms",
            Some(m.rms_mrad),
            limit,
            "mrad",
            "error",
            "RMS error over the metrics window".into(),
        ));
    }
    if let Some(limit) = req.max_jitter_mrad {
        let jitter = judged.los.as_ref().and_then(|l| l.jitter_rms_max_mrad);
        checks.push(optional(
            "jitter",
            jitter,
            limit,
            "mrad",
            "exposure-long stretch in the window",
            format!(
                "worst RMS about the mean of a {} s exposure",
                crate::compact(p.los.exposure_s)
            ),
        ));
    }
    if let Some(limit) = req.max_settling_s {
        let settling = if m.all_steps_settled {
            m.worst_settling_time_s
        } else {
            None
        };
        let note = if m.steps.is_empty() {
            "no reference step in the metrics window".to_string()
        } else if !m.all_steps_settled {
            "a step did not settle".to_string()
        } else {
            format!(
                "longest of {} steps into +-{} mrad",
                m.steps.len(),
                crate::compact(p.settle_band_mrad.unwrap_or(p.target_mrad))
            )
        };
        let mut c = optional("settling", settling, limit, "s", "step", note.clone());
        if ok && settling.is_none() {
            c.note = note;
        }
        checks.push(c);
    }
    if let (Some(db), Some(f)) = (req.min_base_rejection_db, req.base_rejection_hz) {
        let free = range
            .first()
            .map_or(ClosedLoopParams::half_stiffness_n_per_m(setup.drive), |r| {
                r.half_stiffness_n_per_m
            });
        let lin = LinearLoop::with_half_stiffness(p, setup.drive, free);
        let stable = range.iter().all(|r| r.margins.stable);
        let rejection = -20.0 * lin.base_to_los(f).norm().log10();
        let mut c = check(
            "base_rejection",
            &format!("{} Hz, free span", crate::compact(f)),
            Some(rejection).filter(|r| stable && r.is_finite()),
            (">=", db),
            "dB",
            if stable {
                "-20 log10 |LOS/base| on the exact linear reference".into()
            } else {
                "the loop is unstable: no rejection".into()
            },
        );
        c.passes = c.passes && stable;
        checks.push(c);
    }
    Verdict {
        passes: checks.iter().all(|c| c.passes),
        judged_mode: judged.mode,
        checks,
        operating_range: range,
    }
}

/// Simulates the judged mode (metrics only) and judges the design.
pub fn evaluate(setup: &ClosedLoopSetup<'_>) -> Result<Verdict, ClosedLoopError> {
    let mode = setup.params.judged_mode();
    let options = RunOptions {
        modes: Some(vec![mode]),
        // The jitter is kept when a requirement judges it, and read nowhere else here.
        line_of_sight: false,
        ..RunOptions::metrics_only()
    };
    let mut r = run_closed_loop(setup, &options)?;
    match r.modes.iter().position(|m| m.mode == mode) {
        Some(i) => Ok(judge(setup, &r.modes.swap_remove(i))),
        None => Err(ClosedLoopError::Invalid {
            key: "closed_loop.requirements.mode".into(),
            message: format!("mode {} was not simulated", mode.name()),
        }),
    }
}

/// The judged mode's result out of a run of several modes, when it was simulated.
pub fn judged_result<'a>(p: &ClosedLoopParams, modes: &'a [ModeResult]) -> Option<&'a ModeResult> {
    let mode = p.judged_mode();
    modes.iter().find(|m| m.mode == mode)
}

#[cfg(test)]
mod tests {
    use super::fmt_measured;

    #[test]
    fn a_measured_value_never_reads_as_its_limit() {
        assert_eq!(fmt_measured(0.99995, 1.0), "0.99995");
        assert_eq!(fmt_measured(0.9999999, 1.0), "0.9999999");
        assert_eq!(fmt_measured(35.0004, 35.0), "35.0004");
        assert_eq!(fmt_measured(0.9975, 1.0), "0.9975");
        assert_eq!(fmt_measured(43.73, 35.0), "43.73");
        assert_eq!(fmt_measured(1.0, 1.0), "1");
        for v in [0.999_999_999_999_9, 1.000_000_000_000_1, 2.0 - 1e-15] {
            assert_ne!(fmt_measured(v, 1.0), "1", "{v}");
        }
    }
}
