//! Tuning: the plain PID's gains an engineer can sign that point best, found on the exact
//! linear loop and proven on the nonlinear plant.
//!
//! Three stages, each reading the one before:
//! 1. **Linear screen.** Every point of a log grid over `kp`, `ki`, `kd` is judged on the
//!    exact sampled loop (zero-order hold, the scenario's computation delay, the PID as
//!    implemented) at each stiffness of the operating range: margins on a dense frequency
//!    grid, then stability from the closed-loop poles. The plant's responses do not depend
//!    on the gains, so they are computed once per stiffness and every candidate costs a
//!    few complex products per frequency. Feasible points are ranked by their peak drum
//!    compliance to a held torque (rad per N m), the linear measure of how far a brake's
//!    reversal pushes the line of sight.
//! 2. **Nonlinear search.** From the best-ranked, mutually distant seeds (and the
//!    scenario's own gains when they are signable), a pattern search
//!    on the grid (steps of 4, 2, 1 grid points, axis and `kp`-`ki` diagonal moves) keeps
//!    the candidate whose *verdict* is best: every candidate is judged by the one routine
//!    every command uses ([`crate::analysis::verdict::evaluate`]: exact margins over the
//!    operating range and a complete nonlinear run in the judged mode), with and without
//!    load feedforward. The linear ranking only chooses where to start: on this plant it
//!    misleads (the nonlinear peak prefers more `kp` than the linear optimum).
//! 3. **Pick and its neighbourhood.** The pick is the lowest peak among candidates that
//!    meet every requirement other than the pointing target and ran to the end (a stopped
//!    run is a named failing case, never a number); its gains are then moved by a small
//!    step each way to say how much its figures move, and the requirement closest to its
//!    limit is named (the active constraint).

use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use nalgebra::Complex;
use rayon::prelude::*;
use serde::Serialize;

use super::DesignError;
use crate::analysis::linear::LinearLoop;
use crate::analysis::margins::GainDirection;
use crate::analysis::verdict::{self, Verdict};
use crate::closed_loop::{self, ClosedLoopSource, CompensationMode};
use crate::scenario::Scenario;

/// Which load-feedforward settings the nonlinear stage tries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Feedforward {
    /// Without load feedforward only.
    Without,
    /// With load feedforward only.
    With,
    /// Both, picking on the better.
    Both,
}

impl Feedforward {
    /// The settings of `closed_loop.controller.load_feedforward` tried.
    pub fn settings(self) -> Vec<bool> {
        match self {
            Feedforward::Without => vec![false],
            Feedforward::With => vec![true],
            Feedforward::Both => vec![false, true],
        }
    }
}

/// How much a tune searches.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SearchSize {
    /// Grid points per gain on the linear screen (25 in full; 9 in tests).
    pub grid: usize,
    /// Factor each way of each gain's grid around the scenario's `kp`, `ki`, `kd`
    /// (10, 30, 10).
    pub span: [f64; 3],
    /// Nonlinear seeds from the linear ranking per load-feedforward setting, mutually
    /// distant (10; 1 in tests): each is judged once and the search goes on from the
    /// best-judged first while the budget lasts, so more seeds cost a verdict each and
    /// guard against a local optimum. The scenario's own gains are a further seed when
    /// signable.
    pub seeds: usize,
    /// Largest pattern-search step, grid points (4; 1 in tests).
    pub first_step: usize,
    /// Most nonlinear verdicts of the search, shared equally by the load-feedforward
    /// settings (150; a few in tests).
    pub max_verdicts: usize,
    /// Relative gain change of the sensitivity study (0.05; 0 leaves it out).
    pub sensitivity_step: f64,
}

impl SearchSize {
    /// The search `design tune` makes by default: under a minute on 2 cores for the
    /// built-in tracking loop at 20 kHz.
    pub fn full() -> Self {
        SearchSize {
            grid: 25,
            span: [10.0, 30.0, 10.0],
            seeds: 10,
            first_step: 4,
            max_verdicts: 150,
            sensitivity_step: 0.05,
        }
    }

    /// A reduced search for tests and quick looks: a coarse grid and a handful of runs.
    pub fn reduced() -> Self {
        SearchSize {
            grid: 9,
            span: [4.0, 8.0, 4.0],
            seeds: 1,
            first_step: 1,
            max_verdicts: 8,
            sensitivity_step: 0.0,
        }
    }

    fn validate(&self) -> Result<(), DesignError> {
        let spans_ok = self.span.iter().all(|s| s.is_finite() && *s >= 1.0);
        if !(3..=101).contains(&self.grid)
            || !spans_ok
            || self.seeds == 0
            || self.first_step == 0
            || self.max_verdicts == 0
            || !(0.0..0.5).contains(&self.sensitivity_step)
        {
            return Err(DesignError::Unsuitable(format!(
                "search size out of range: grid {} (3 to 101), spans {:?} (>= 1), seeds {}, first step {}, verdicts {} (>= 1 each), sensitivity step {} (0 to 0.5)",
                self.grid, self.span, self.seeds, self.first_step, self.max_verdicts, self.sensitivity_step
            )));
        }
        Ok(())
    }
}

/// What a tune is asked.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TuneOptions {
    /// Control rate, Hz; `None` keeps the scenario's.
    pub rate_hz: Option<f64>,
    /// Compensation mode whose pointing error is judged (it must be listed in
    /// `closed_loop.modes`).
    pub mode: CompensationMode,
    /// Load-feedforward settings tried.
    pub feedforward: Feedforward,
    /// How much to search.
    pub search: SearchSize,
    /// Further designs to start the search from (gains in the scenario's units), used
    /// when signable on the linear loop: the picks at neighbouring rates in
    /// [`least_rate`], whose gains move little with the rate.
    pub seeds_from: Vec<Gains>,
    /// Filters searched besides the gains (none by default: the scenario's own filters
    /// are kept).
    pub filters: FilterSearch,
}

/// Filters a tune may search besides the gains. Each asked filter multiplies the
/// variants: the derivative filter's corner at the scenario's and at 0.5 and 2 times it
/// where below the Nyquist frequency; no notch
/// or a notch 20 dB deep and half its centre wide at 0.8, 1 and 1.25 times the cable
/// resonance; no lead-lag or a lead of 4:1 (about 37 deg) centred at 0.67, 1 and 1.5
/// times the scenario's design's crossover. Every variant is screened on the exact linear
/// loop; the best two by their linear ranking and the scenario's own filters are then
/// searched on the nonlinear plant, each with the whole budget.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct FilterSearch {
    /// Search the derivative filter's corner.
    pub derivative: bool,
    /// Search a notch on the feedback command at the cable resonance.
    pub notch: bool,
    /// Search a lead-lag on the feedback command at the crossover.
    pub lead_lag: bool,
}

impl FilterSearch {
    /// Whether any filter is searched.
    pub fn any(&self) -> bool {
        self.derivative || self.notch || self.lead_lag
    }

    /// The filters asked in words: `derivative, notch` or `none`.
    pub fn words(&self) -> String {
        let v: Vec<&str> = [
            (self.derivative, "derivative filter"),
            (self.notch, "notch"),
            (self.lead_lag, "lead-lag"),
        ]
        .iter()
        .filter(|(on, _)| *on)
        .map(|(_, w)| *w)
        .collect();
        if v.is_empty() {
            "none".into()
        } else {
            v.join(", ")
        }
    }
}

/// One filter setting a tune screened: its filters, its best linear ranking and, when it
/// was searched on the nonlinear plant, its best peak.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FilterVariant {
    /// The filters in words (`derivative 1000 Hz, notch 52.3 Hz 20 dB 26.2 Hz wide`).
    pub label: String,
    /// Derivative filter corner, Hz.
    pub derivative_filter_hz: f64,
    /// Filters on the feedback command (`closed_loop.controller.command_filters`).
    pub command_filters: Vec<closed_loop::filters::FilterSpec>,
    /// Grid points signable on the exact linear loop at every stiffness.
    pub linear_feasible: usize,
    /// Least peak drum compliance among those, mrad per N m (`None`: none signable).
    pub best_linear_compliance_mrad_per_nm: Option<f64>,
    /// Whether it was searched on the nonlinear plant.
    pub searched: bool,
    /// Its best signable peak there, mrad (`None`: not searched, or nothing signable).
    pub best_peak_mrad: Option<f64>,
}

/// PID gains in the scenario's units.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Gains {
    /// Proportional gain, command per rad (A/rad with a current amplifier).
    pub kp: f64,
    /// Integral gain, command per rad s.
    pub ki: f64,
    /// Derivative gain, command s per rad (on the measurement, through its filter).
    pub kd: f64,
}

/// The margins of one candidate at one stiffness of the operating range.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PointFigures {
    /// `free span` or `tangent at M N m`.
    pub condition: String,
    /// Stiffness of each cable half, N/m.
    pub half_stiffness_n_per_m: f64,
    /// Whether the sampled closed loop is stable there.
    pub stable: bool,
    /// Worst phase margin over the gain crossovers, deg.
    pub phase_margin_deg: Option<f64>,
    /// Worst upward gain margin, dB (`None`: no crossing that way, unbounded).
    pub gain_margin_up_db: Option<f64>,
    /// Worst downward gain margin, dB (`None`: unbounded).
    pub gain_margin_down_db: Option<f64>,
    /// Sensitivity peak `max |S|`.
    pub ms: Option<f64>,
}

/// One candidate judged by the verdict: gains, margins at each stiffness, the judged
/// mode's figures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Candidate {
    /// The gains.
    pub gains: Gains,
    /// Control rate, Hz.
    pub rate_hz: f64,
    /// Whether the predicted load torque was fed forward.
    pub load_feedforward: bool,
    /// Where it came from: `search`, `sensitivity` or `scenario` (the design as given).
    pub origin: &'static str,
    /// Peak closed-loop drum compliance to a held drum torque over the operating range on
    /// the exact linear loop, mrad per N m (the linear ranking).
    pub linear_compliance_mrad_per_nm: Option<f64>,
    /// Margins at each stiffness of the operating range.
    pub margins: Vec<PointFigures>,
    /// Every requirement other than the pointing target is met (margins, stability and
    /// any declared RMS, jitter, settling or rejection) and the run completed.
    pub signable: bool,
    /// `complete`, or why the judged mode has no figures (a stop with its time and cause).
    pub status: String,
    /// Peak pointing error of the judged mode over the metrics window, mrad; `None` when
    /// the run stopped.
    pub peak_mrad: Option<f64>,
    /// RMS pointing error over the metrics window, mrad; `None` when the run stopped.
    pub rms_mrad: Option<f64>,
    /// The verdict passes: signable and within the pointing target.
    pub passes: bool,
    /// Least relative margin over the margin requirements (PM / limit, GM / limit and
    /// limit / Ms, less 1): 0 on a limit, above 0 inside; `None` when unstable.
    pub margin_class: Option<f64>,
    /// The failing requirements in words (empty when the verdict passes).
    pub failing: Vec<String>,
    /// On the trade-off front of its load-feedforward setting: no other signable
    /// candidate has both a lower peak and a larger margin class.
    pub on_front: bool,
}

/// How the pick's figures move when one gain moves.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Sensitivity {
    /// `kp`, `ki` or `kd`.
    pub gain: &'static str,
    /// Relative change applied (+0.05 = 5 % more).
    pub change: f64,
    /// Peak error there, mrad (`None`: the run stopped).
    pub peak_mrad: Option<f64>,
    /// Change of the peak against the pick, mrad.
    pub peak_change_mrad: Option<f64>,
    /// Worst phase margin over the operating range, deg.
    pub phase_margin_deg: Option<f64>,
    /// Worst gain margin, up or down, over the operating range, dB.
    pub gain_margin_db: Option<f64>,
    /// Worst sensitivity peak over the operating range.
    pub ms: Option<f64>,
    /// Whether the moved design is still signable.
    pub signable: bool,
}

/// Progress of a tune, for a display attached from outside.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    /// `linear screen`, `nonlinear search` or `sensitivity`.
    pub stage: &'static str,
    /// Work done in this stage.
    pub done: usize,
    /// Work of this stage (an upper bound for the search).
    pub total: usize,
}

/// The answer of a tune.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TuneResult {
    /// Scenario tuned.
    pub scenario: String,
    /// Control rate tuned at, Hz.
    pub rate_hz: f64,
    /// Compensation mode judged.
    pub mode: CompensationMode,
    /// Load-feedforward settings tried.
    pub feedforward: Feedforward,
    /// Pointing target, mrad.
    pub target_mrad: f64,
    /// What was searched, in words.
    pub searched: String,
    /// Points of the linear grid.
    pub linear_candidates: usize,
    /// Of those, the ones signable on the exact linear loop at every stiffness.
    pub linear_feasible: usize,
    /// Every candidate judged on the nonlinear plant, in the order judged.
    pub verified: Vec<Candidate>,
    /// Index in `verified` of the pick: the lowest peak among signable candidates.
    pub pick: Option<usize>,
    /// Index of the best signable candidate without load feedforward.
    pub best_without_feedforward: Option<usize>,
    /// Index of the best signable candidate with load feedforward.
    pub best_with_feedforward: Option<usize>,
    /// The scenario's own design as given (its own rate, gains and feedforward).
    pub scenario_design: Candidate,
    /// How the pick's figures move for a small change of each gain.
    pub sensitivity: Vec<Sensitivity>,
    /// The requirement closest to its limit at the pick, in words.
    pub active_constraint: Option<String>,
    /// Grid moves from the pick that the requirements forbid, in words (`kp up: phase
    /// margin at tangent at 0.75 N m`), and moves beyond the searched range.
    pub blocked_moves: Vec<String>,
    /// Wall time, s.
    pub elapsed_s: f64,
    /// Filter settings screened when filters were searched (empty otherwise); the result
    /// above is the search of the variant whose pick is best.
    pub filter_variants: Vec<FilterVariant>,
    /// The tuned scenario (complete and runnable), when there is a pick.
    #[serde(skip)]
    pub tuned: Option<Scenario>,
}

impl TuneResult {
    /// The picked candidate.
    pub fn picked(&self) -> Option<&Candidate> {
        self.pick.map(|i| &self.verified[i])
    }
}

/// A point of the frequency grid with the plant's gain-independent responses there.
struct PlantSample {
    /// `exp(-j w T)`.
    zi: Complex<f64>,
    /// Measured output per command (delay included).
    pu: Complex<f64>,
    /// Drum angle per command.
    du: Complex<f64>,
    /// Measured output per drum torque.
    pd: Complex<f64>,
    /// Drum angle per drum torque.
    dd: Complex<f64>,
}

/// One stiffness of the operating range on the linear screen.
struct Stiffness {
    condition: String,
    samples: Vec<PlantSample>,
}

/// Frequencies of the screen's grid per stiffness: dense enough to place every crossing
/// within a fraction of a degree on this kind of loop; the exact verdict judges anyway.
const SCREEN_POINTS: usize = 1500;

/// Slack the screen grants a candidate so a crossing between its grid points does not
/// drop a design the exact verdict would sign (deg, dB, and on Ms).
const SCREEN_SLACK: (f64, f64, f64) = (0.5, 0.2, 0.02);

impl Stiffness {
    /// The plant's responses at `lin`'s stiffness; `measured` weighs the motor and drum
    /// angles into the position loop's measurement (`[1, 0]` on the motor encoder,
    /// `[0, ic]` on the output encoder).
    fn new(
        condition: String,
        lin: &LinearLoop,
        measured: [f64; 2],
        command_filters: &closed_loop::filters::FilterChain,
    ) -> Self {
        let (lo, hi) = (0.1_f64, lin.nyquist_hz() * 0.9999);
        let ts = 0.5 / lin.nyquist_hz();
        let fs = 1.0 / ts;
        let samples = (0..SCREEN_POINTS)
            .map(|i| lo * (hi / lo).powf(i as f64 / (SCREEN_POINTS - 1) as f64))
            .map(|f| {
                let rows = lin.plant_rows(f);
                let drows = lin.drum_torque_rows(f);
                // Filters on the command act in series with the PID on every path.
                let fc = command_filters.response(f, fs);
                PlantSample {
                    zi: Complex::from_polar(1.0, -std::f64::consts::TAU * f * ts),
                    pu: (rows[0] * measured[0] + rows[1] * measured[1]) * fc,
                    du: rows[1],
                    pd: (drows[0] * measured[0] + drows[1] * measured[1]) * fc,
                    dd: drows[1],
                }
            })
            .collect();
        Stiffness { condition, samples }
    }
}

/// The PID's response `K(z)` as implemented (see `analysis::linear`).
fn pid_response(g: &Gains, ts: f64, a: f64, zi: Complex<f64>) -> Complex<f64> {
    let one = Complex::from(1.0);
    Complex::from(g.kp)
        + Complex::from(g.ki * ts) / (one - zi)
        + (one - zi) * ((1.0 - a) * g.kd / ts) / (one - zi * a)
}

/// The screen's judgement of one candidate at one stiffness.
struct Screened {
    /// First requirement missed, in words; `None` when signable there.
    missed: Option<String>,
    /// Peak drum compliance, rad per N m.
    compliance: f64,
}

fn screen_at(
    st: &Stiffness,
    g: &Gains,
    ts: f64,
    a: f64,
    req: &crate::closed_loop::Requirements,
) -> Screened {
    let mut pm = f64::INFINITY;
    let mut gm = f64::INFINITY;
    let mut ms: f64 = 0.0;
    let mut compliance: f64 = 0.0;
    let mut prev: Option<Complex<f64>> = None;
    let one = Complex::from(1.0);
    for s in &st.samples {
        let k = pid_response(g, ts, a, s.zi);
        let l = k * s.pu;
        let sens = (one + l).inv();
        ms = ms.max(sens.norm());
        // u = -K (pd d + pu u)  =>  u = -K pd / (1 + L) d
        let c = s.dd - s.du * k * s.pd * sens;
        compliance = compliance.max(c.norm());
        if let Some(l0) = prev {
            if (l0.norm() - 1.0) * (l.norm() - 1.0) <= 0.0 {
                // Phase at the crossing, from the nearer sample.
                let lx = if (l0.norm() - 1.0).abs() < (l.norm() - 1.0).abs() {
                    l0
                } else {
                    l
                };
                pm = pm.min(180.0 - lx.arg().to_degrees().abs());
            }
            if l0.im * l.im <= 0.0 && (l0.re < 0.0 || l.re < 0.0) {
                let lx = if l0.im.abs() < l.im.abs() { l0 } else { l };
                if lx.re < 0.0 {
                    gm = gm.min((20.0 * lx.norm().log10()).abs());
                }
            }
        }
        prev = Some(l);
    }
    let (pm_slack, gm_slack, ms_slack) = SCREEN_SLACK;
    let missed = if pm < req.min_phase_margin_deg - pm_slack {
        Some(format!("phase margin at {}", st.condition))
    } else if gm < req.min_gain_margin_db - gm_slack {
        Some(format!("gain margin at {}", st.condition))
    } else if ms > req.max_ms + ms_slack {
        Some(format!("sensitivity peak at {}", st.condition))
    } else if pm == f64::INFINITY {
        Some(format!("no gain crossover at {}", st.condition))
    } else {
        None
    };
    Screened { missed, compliance }
}

/// Grid indices of a point.
type Idx = [usize; 3];

/// The linear screen's answer for a design: the first requirement missed (none when
/// signable) and the worst peak drum compliance, rad per N m.
type ScreenRecord = (Option<String>, f64);

/// The linear screen's record of a grid point.
#[derive(Clone)]
struct GridPoint {
    /// First requirement missed over the operating range; `None` when signable.
    missed: Option<String>,
    /// Worst peak compliance over the operating range, rad per N m.
    compliance: f64,
}

/// The searched grid with its linear screen.
struct Grid {
    n: usize,
    points: Vec<GridPoint>,
}

impl Grid {
    fn at(&self, i: Idx) -> &GridPoint {
        &self.points[(i[0] * self.n + i[1]) * self.n + i[2]]
    }
    fn idx(&self, flat: usize) -> Idx {
        [
            flat / (self.n * self.n),
            (flat / self.n) % self.n,
            flat % self.n,
        ]
    }
}

/// Centre of each gain's grid: the scenario's gain, or where it is zero a value of the
/// usual shape around the scenario's `kp` (integral corner 10 Hz, derivative corner
/// 200 Hz), so a P-only or PI design can still be tuned to a full PID.
fn centre(kp: f64, ki: f64, kd: f64) -> Option<Gains> {
    if !(kp.is_finite() && kp > 0.0) {
        return None;
    }
    let tau = std::f64::consts::TAU;
    Some(Gains {
        kp,
        ki: if ki > 0.0 && ki.is_finite() {
            ki
        } else {
            kp * tau * 10.0
        },
        kd: if kd > 0.0 && kd.is_finite() {
            kd
        } else {
            kp / (tau * 200.0)
        },
    })
}

/// The scenario at `rate_hz` with `gains`, the judged `mode` and the feedforward setting.
fn design(base: &Scenario, gains: &Gains, load_feedforward: bool) -> Scenario {
    let mut s = base.clone();
    if let Some(cl) = s.closed_loop.as_mut() {
        cl.controller.kp = gains.kp;
        cl.controller.ki = gains.ki;
        cl.controller.kd = gains.kd;
        cl.controller.load_feedforward = load_feedforward;
    }
    s
}

/// Judges one design with the verdict every command uses.
fn judge(s: &Scenario, origin: &'static str, compliance: Option<f64>) -> Candidate {
    let cl = s.closed_loop.as_ref();
    let gains = cl.map_or(
        Gains {
            kp: 0.0,
            ki: 0.0,
            kd: 0.0,
        },
        |c| Gains {
            kp: c.controller.kp,
            ki: c.controller.ki,
            kd: c.controller.kd,
        },
    );
    let rate_hz = cl.map_or(0.0, |c| c.controller.sample_rate_hz);
    let load_feedforward = cl.is_some_and(|c| c.controller.load_feedforward);
    let failed = |status: String| Candidate {
        gains,
        rate_hz,
        load_feedforward,
        origin,
        linear_compliance_mrad_per_nm: compliance,
        margins: Vec::new(),
        signable: false,
        status: status.clone(),
        peak_mrad: None,
        rms_mrad: None,
        passes: false,
        margin_class: None,
        failing: vec![status],
        on_front: false,
    };
    if let Err(e) = s.validate("tuned design") {
        return failed(format!("error: {e}"));
    }
    let setup = match s.closed_loop_setup() {
        Ok(setup) => setup,
        Err(e) => return failed(format!("error: {e}")),
    };
    let mode = setup.params.judged_mode();
    let options = closed_loop::RunOptions {
        modes: Some(vec![mode]),
        // The jitter is kept when a requirement judges it, and read nowhere else here.
        line_of_sight: false,
        ..closed_loop::RunOptions::metrics_only()
    };
    let run = match closed_loop::run_closed_loop(&setup, &options) {
        Ok(r) => r,
        Err(e) => return failed(format!("error: {e}")),
    };
    let Some(result) = run.modes.iter().find(|m| m.mode == mode) else {
        return failed(format!("error: mode {} was not simulated", mode.name()));
    };
    let v = verdict::judge(&setup, result);
    let rms = result
        .no_figures_reason()
        .is_none()
        .then_some(result.metrics.rms_mrad);
    from_verdict(
        &v,
        gains,
        rate_hz,
        load_feedforward,
        origin,
        compliance,
        rms,
    )
}

fn from_verdict(
    v: &Verdict,
    gains: Gains,
    rate_hz: f64,
    load_feedforward: bool,
    origin: &'static str,
    compliance: Option<f64>,
    rms_mrad: Option<f64>,
) -> Candidate {
    let pointing = v.checks.iter().find(|c| c.requirement == "pointing");
    let complete = pointing.is_some_and(|c| c.measured.is_some());
    let status = match pointing {
        Some(c) if c.measured.is_none() => c.note.clone(),
        Some(_) => "complete".to_string(),
        None => "no pointing check".to_string(),
    };
    let signable = complete
        && v.checks
            .iter()
            .filter(|c| c.requirement != "pointing")
            .all(|c| c.passes);
    let margins: Vec<PointFigures> = v
        .operating_range
        .iter()
        .map(|p| {
            let m = &p.margins;
            PointFigures {
                condition: p.condition.clone(),
                half_stiffness_n_per_m: p.half_stiffness_n_per_m,
                stable: m.stable,
                phase_margin_deg: m.worst_gain_crossover().map(|c| c.phase_margin_deg),
                gain_margin_up_db: m
                    .worst_phase_crossover(GainDirection::Up)
                    .map(|c| c.gain_margin_db),
                gain_margin_down_db: m
                    .worst_phase_crossover(GainDirection::Down)
                    .map(|c| c.gain_margin_db),
                ms: m.ms,
            }
        })
        .collect();
    // Relative margins of the margin requirements: the class a design is signed in.
    let margin_class = v
        .checks
        .iter()
        .filter(|c| {
            matches!(
                c.requirement,
                "phase_margin" | "gain_margin_up" | "gain_margin_down" | "sensitivity_peak"
            )
        })
        .filter_map(|c| {
            let m = c.measured?;
            Some(if c.relation.starts_with('>') {
                m / c.limit - 1.0
            } else {
                c.limit / m - 1.0
            })
        })
        .fold(None, |acc: Option<f64>, r| {
            Some(acc.map_or(r, |a| a.min(r)))
        })
        .filter(|_| margins.iter().all(|p| p.stable));
    let (peak_mrad, rms_mrad) = if complete {
        (v.worst_value("pointing"), rms_mrad)
    } else {
        (None, None)
    };
    Candidate {
        gains,
        rate_hz,
        load_feedforward,
        origin,
        linear_compliance_mrad_per_nm: compliance.map(|c| c * 1e3),
        margins,
        signable,
        status,
        peak_mrad,
        rms_mrad,
        passes: v.passes,
        margin_class,
        failing: v.reasons(),
        on_front: false,
    }
}

/// The scenario prepared for tuning: at the rate asked, judged in `mode`, checked to be a
/// plain-PID closed loop whose operating range has a tangent stiffness.
fn prepared(base: &Scenario, options: &TuneOptions) -> Result<Scenario, DesignError> {
    let unsuitable = |m: String| Err(DesignError::Unsuitable(m));
    let mut s = base.clone();
    let Some(cl) = s.closed_loop.as_mut() else {
        return unsuitable(format!(
            "scenario {} is not a closed-loop study",
            base.name()
        ));
    };
    if !cl.modes.contains(&options.mode) {
        return unsuitable(format!(
            "mode {} is not listed in closed_loop.modes",
            options.mode.name()
        ));
    }
    let c = &cl.controller;
    let beyond_pid = c.rate_loop.is_some()
        || !c.measurement_filters.is_empty()
        || !c.rate_command_filters.is_empty()
        || !c.rate_measurement_filters.is_empty()
        || c.disturbance_observer.is_some();
    if beyond_pid || c.feedback == closed_loop::Feedback::GyroAngle {
        return unsuitable(
            "design tune searches a PID on an encoder with filters on its command; this controller has a rate loop, measurement filters, an observer or gyro-angle feedback".into(),
        );
    }
    if let Some(rate) = options.rate_hz {
        if !(rate.is_finite() && rate > 0.0) {
            return unsuitable(format!(
                "--rate {}: give a control rate above 0 Hz",
                crate::number(rate)
            ));
        }
        cl.controller.sample_rate_hz = rate;
    }
    cl.requirements.mode = Some(options.mode);
    s.validate("tuned design")
        .map_err(|e| DesignError::Unsuitable(e.to_string()))?;
    Ok(s)
}

/// Tunes the plain PID of `base` (see the module's description). `progress` is called
/// as work is done, from any thread.
pub fn tune(
    base: &Scenario,
    options: &TuneOptions,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<TuneResult, DesignError> {
    if !options.filters.any() {
        return match tune_gains(base, options, progress, false)? {
            Stage::Searched(r) => Ok(*r),
            Stage::Screened { .. } => Err(DesignError::Unsuitable(
                "the tune stopped after its linear screen".into(),
            )),
        };
    }
    tune_filters(base, options, progress)
}

/// What [`tune_gains`] returns: the linear screen alone, or the whole search.
enum Stage {
    /// Signable grid points and the least peak compliance among them, rad per N m.
    Screened {
        feasible: usize,
        best_compliance: Option<f64>,
    },
    /// The whole search.
    Searched(Box<TuneResult>),
}

/// Searches filter variants (see [`FilterSearch`]): every variant screened on the linear
/// loop, the best two and the scenario's own searched in full, the best pick kept.
fn tune_filters(
    base: &Scenario,
    options: &TuneOptions,
    progress: &(dyn Fn(Progress) + Sync),
) -> Result<TuneResult, DesignError> {
    let started = std::time::Instant::now();
    let s = prepared(base, options)?;
    let (resonance_hz, crossover_hz) = resonance_and_crossover(&s)?;
    let ctl = s
        .closed_loop
        .as_ref()
        .map(|c| c.controller.clone())
        .ok_or_else(|| DesignError::Unsuitable("not a closed-loop study".into()))?;
    let fs = ctl.sample_rate_hz;
    let f = &options.filters;
    // The scenario's own corner always, whatever the rate (it is the comparison); the
    // others only below the Nyquist frequency, where a corner still filters.
    let own_corner = ctl.derivative_filter_hz;
    let mut corners = vec![own_corner];
    if f.derivative {
        for k in [0.5, 2.0] {
            let c = k * own_corner;
            if c < 0.45 * fs {
                corners.push(c);
            }
        }
    }
    use closed_loop::filters::FilterSpec;
    let mut notches: Vec<Option<FilterSpec>> = vec![None];
    if f.notch {
        for k in [0.8, 1.0, 1.25] {
            let centre = k * resonance_hz;
            if centre < 0.4 * fs {
                notches.push(Some(FilterSpec::Notch {
                    center_hz: centre,
                    depth_db: 20.0,
                    width_hz: 0.5 * centre,
                }));
            }
        }
    }
    let mut leads: Vec<Option<FilterSpec>> = vec![None];
    if f.lead_lag {
        for k in [1.0 / 1.5, 1.0, 1.5] {
            let centre = k * crossover_hz;
            if 2.0 * centre < 0.4 * fs {
                leads.push(Some(FilterSpec::LeadLag {
                    zero_hz: 0.5 * centre,
                    pole_hz: 2.0 * centre,
                }));
            }
        }
    }
    let mut variants: Vec<(FilterVariant, Scenario)> = Vec::new();
    for &corner in &corners {
        for notch in &notches {
            for lead in &leads {
                let mut v = s.clone();
                let Some(cl) = v.closed_loop.as_mut() else {
                    continue;
                };
                cl.controller.derivative_filter_hz = corner;
                cl.controller.command_filters = ctl.command_filters.clone();
                cl.controller.command_filters.extend(notch.iter().cloned());
                cl.controller.command_filters.extend(lead.iter().cloned());
                let command_filters = cl.controller.command_filters.clone();
                let label = filter_label(corner, &command_filters);
                // A variant the scenario refuses (a filter beyond its rate) is left out.
                if v.validate("filter variant").is_err() {
                    continue;
                }
                variants.push((
                    FilterVariant {
                        label,
                        derivative_filter_hz: corner,
                        command_filters,
                        linear_feasible: 0,
                        best_linear_compliance_mrad_per_nm: None,
                        searched: false,
                        best_peak_mrad: None,
                    },
                    v,
                ));
            }
        }
    }
    let total = variants.len();
    for (k, (row, v)) in variants.iter_mut().enumerate() {
        if let Stage::Screened {
            feasible,
            best_compliance,
        } = tune_gains(v, options, &|_| {}, true)?
        {
            row.linear_feasible = feasible;
            row.best_linear_compliance_mrad_per_nm = best_compliance.map(|c| c * 1e3);
        }
        progress(Progress {
            stage: "filter screen",
            done: k + 1,
            total,
        });
    }
    // The scenario's own filters are searched whatever their ranking: the design an
    // engineer brings is the comparison every other variant must beat.
    let own = variants
        .iter()
        .position(|(r, _)| {
            r.derivative_filter_hz == own_corner && r.command_filters == ctl.command_filters
        })
        .ok_or_else(|| {
            DesignError::Unsuitable(
                "the scenario's own filters are refused at this rate; give filters it accepts"
                    .into(),
            )
        })?;
    let mut order: Vec<usize> = (0..variants.len())
        .filter(|&i| variants[i].0.best_linear_compliance_mrad_per_nm.is_some())
        .collect();
    order.sort_by(|&a, &b| {
        let c = |i: usize| variants[i].0.best_linear_compliance_mrad_per_nm;
        c(a).unwrap_or(f64::INFINITY)
            .total_cmp(&c(b).unwrap_or(f64::INFINITY))
    });
    let mut chosen: Vec<usize> = order.into_iter().filter(|&i| i != own).take(2).collect();
    chosen.push(own);
    let mut best: Option<TuneResult> = None;
    let peak_of = |r: &TuneResult| {
        r.picked()
            .and_then(|c| c.peak_mrad)
            .unwrap_or(f64::INFINITY)
    };
    for i in chosen {
        let plain = TuneOptions {
            filters: FilterSearch::default(),
            ..options.clone()
        };
        let Stage::Searched(r) = tune_gains(&variants[i].1, &plain, progress, false)? else {
            continue;
        };
        variants[i].0.searched = true;
        variants[i].0.best_peak_mrad = r.picked().and_then(|c| c.peak_mrad);
        if best.as_ref().is_none_or(|b| peak_of(&r) < peak_of(b)) {
            best = Some(*r);
        }
    }
    let Some(mut r) = best else {
        return Err(DesignError::Unsuitable(
            "no filter variant could be searched".into(),
        ));
    };
    r.searched = format!(
        "{} filter settings ({}) screened on the exact linear loop; the best two and the scenario's own searched in full; the pick's: {}",
        total,
        f.words(),
        r.searched
    );
    r.filter_variants = variants.into_iter().map(|(row, _)| row).collect();
    r.elapsed_s = started.elapsed().as_secs_f64();
    Ok(r)
}

/// A filter setting in words.
fn filter_label(derivative_hz: f64, filters: &[closed_loop::filters::FilterSpec]) -> String {
    use closed_loop::filters::FilterSpec;
    let mut parts = vec![format!(
        "derivative filter {} Hz",
        crate::significant(derivative_hz, 3)
    )];
    for f in filters {
        parts.push(match f {
            FilterSpec::Notch {
                center_hz,
                depth_db,
                width_hz,
            } => format!(
                "notch {} Hz, {} dB, {} Hz wide",
                crate::significant(*center_hz, 3),
                crate::significant(*depth_db, 3),
                crate::significant(*width_hz, 3)
            ),
            FilterSpec::LeadLag { zero_hz, pole_hz } => format!(
                "lead-lag zero {} Hz, pole {} Hz",
                crate::significant(*zero_hz, 3),
                crate::significant(*pole_hz, 3)
            ),
            other => format!("{other:?}"),
        });
    }
    parts.join(", ")
}

/// The cable resonance seen by the position loop at the free span (the peak of the
/// measured response times the frequency squared, which takes out the rigid body's
/// slope), and the lowest gain crossover of the scenario's own design there, Hz.
fn resonance_and_crossover(s: &Scenario) -> Result<(f64, f64), DesignError> {
    let setup = s
        .closed_loop_setup()
        .map_err(|e| DesignError::Unsuitable(e.to_string()))?;
    let p = setup.params;
    let ctl = &p.controller;
    let measured = match ctl.feedback {
        closed_loop::Feedback::Output => [0.0, setup.drive.ratio()],
        _ => [1.0, 0.0],
    };
    let (range, _) = verdict::operating_range(&setup);
    let free = range
        .first()
        .map(|pt| pt.half_stiffness_n_per_m)
        .ok_or_else(|| {
            DesignError::Unsuitable("the operating range has no free-span stiffness".into())
        })?;
    let lin = LinearLoop::with_half_stiffness(p, setup.drive, free);
    let st = Stiffness::new(
        "free span".into(),
        &lin,
        measured,
        &closed_loop::filters::FilterChain::new(&ctl.command_filters, ctl.sample_rate_hz),
    );
    let (lo, hi) = (0.1_f64, lin.nyquist_hz() * 0.9999);
    let freq = |i: usize| lo * (hi / lo).powf(i as f64 / (SCREEN_POINTS - 1) as f64);
    let resonance = st
        .samples
        .iter()
        .enumerate()
        .filter(|(i, _)| (5.0..0.45 * hi).contains(&freq(*i)))
        .map(|(i, smp)| (freq(i), smp.pu.norm() * freq(i) * freq(i)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(f, _)| f);
    let ts = 1.0 / ctl.sample_rate_hz;
    let a = (-std::f64::consts::TAU * ctl.derivative_filter_hz * ts).exp();
    let g = Gains {
        kp: ctl.kp,
        ki: ctl.ki,
        kd: ctl.kd,
    };
    let crossover = st
        .samples
        .iter()
        .enumerate()
        .find(|(_, smp)| (pid_response(&g, ts, a, smp.zi) * smp.pu).norm() < 1.0)
        .map(|(i, _)| freq(i));
    match (resonance, crossover) {
        (Some(r), Some(c)) => Ok((r, c)),
        _ => Err(DesignError::Unsuitable(
            "the filter search needs the cable resonance and the scenario's design's crossover on the free span; the design as given has no gain crossover".into(),
        )),
    }
}

/// The gains' search of [`tune`] for the filters of `base` as they are; with
/// `linear_only`, the linear screen alone.
fn tune_gains(
    base: &Scenario,
    options: &TuneOptions,
    progress: &(dyn Fn(Progress) + Sync),
    linear_only: bool,
) -> Result<Stage, DesignError> {
    let started = std::time::Instant::now();
    options.search.validate()?;
    let s = prepared(base, options)?;
    let setup = s
        .closed_loop_setup()
        .map_err(|e| DesignError::Unsuitable(e.to_string()))?;
    let p = setup.params;
    let ctl = &p.controller;
    let rate_hz = ctl.sample_rate_hz;
    let (range, problem) = verdict::operating_range(&setup);
    if let Some(message) = problem {
        return Err(DesignError::Unsuitable(format!(
            "the operating range has no tangent stiffness: {message}"
        )));
    }
    let measured = match ctl.feedback {
        closed_loop::Feedback::Output => [0.0, setup.drive.ratio()],
        _ => [1.0, 0.0],
    };
    let loops: Vec<LinearLoop> = range
        .iter()
        .map(|pt| LinearLoop::with_half_stiffness(p, setup.drive, pt.half_stiffness_n_per_m))
        .collect();
    let command_filters =
        closed_loop::filters::FilterChain::new(&ctl.command_filters, ctl.sample_rate_hz);
    let stiffness: Vec<Stiffness> = range
        .par_iter()
        .zip(loops.par_iter())
        .map(|(pt, lin)| Stiffness::new(pt.condition.clone(), lin, measured, &command_filters))
        .collect();
    let Some(c0) = centre(ctl.kp, ctl.ki, ctl.kd) else {
        return Err(DesignError::Unsuitable(format!(
            "closed_loop.controller.kp = {}: the search is centred on a positive kp",
            crate::number(ctl.kp)
        )));
    };
    let search = &options.search;
    let n = search.grid;
    let axis = |c: f64, span: f64| -> Vec<f64> {
        (0..n)
            .map(|i| c * span.powf(2.0 * i as f64 / (n - 1) as f64 - 1.0))
            .collect()
    };
    let (kps, kis, kds) = (
        axis(c0.kp, search.span[0]),
        axis(c0.ki, search.span[1]),
        axis(c0.kd, search.span[2]),
    );
    let ts = 1.0 / rate_hz;
    let a = (-std::f64::consts::TAU * ctl.derivative_filter_hz * ts).exp();
    let req = &p.requirements;
    let total = n * n * n;
    let screened = AtomicUsize::new(0);
    // The linear screen of one design over the operating range: the first requirement
    // missed (none when signable) and the worst peak compliance.
    let screen_gains = |gains: &Gains| -> (Option<String>, f64) {
        let mut missed = None;
        let mut compliance: f64 = 0.0;
        for st in &stiffness {
            let r = screen_at(st, gains, ts, a, req);
            compliance = compliance.max(r.compliance);
            if missed.is_none() {
                missed = r.missed;
            }
        }
        // Margins on the grid do not prove stability: the poles do.
        if missed.is_none() {
            for (lin, st) in loops.iter().zip(&stiffness) {
                let stable = lin.with_pid(gains.kp, gains.ki, gains.kd).spectral_radius() < 1.0;
                if !stable {
                    missed = Some(format!("unstable at {}", st.condition));
                    break;
                }
            }
        }
        (missed, compliance)
    };
    let points: Vec<GridPoint> = (0..total)
        .into_par_iter()
        .map(|flat| {
            let gains = Gains {
                kp: kps[flat / (n * n)],
                ki: kis[(flat / n) % n],
                kd: kds[flat % n],
            };
            let (missed, compliance) = screen_gains(&gains);
            let done = screened.fetch_add(1, Ordering::Relaxed) + 1;
            if done.is_multiple_of(256) || done == total {
                progress(Progress {
                    stage: "linear screen",
                    done,
                    total,
                });
            }
            GridPoint { missed, compliance }
        })
        .collect();
    let grid = Grid { n, points };
    let mut feasible: Vec<usize> = (0..total)
        .filter(|&i| grid.points[i].missed.is_none())
        .collect();
    feasible.sort_by(|&x, &y| {
        grid.points[x]
            .compliance
            .total_cmp(&grid.points[y].compliance)
    });
    let linear_feasible = feasible.len();
    if linear_only {
        return Ok(Stage::Screened {
            feasible: linear_feasible,
            best_compliance: feasible.first().map(|&i| grid.points[i].compliance),
        });
    }

    // Seeds: the best linear candidates, at least a few grid steps apart so the search
    // starts in distinct places.
    let mut seeds: Vec<Idx> = Vec::new();
    let apart = (n / 6).max(2);
    for &f in &feasible {
        let i = grid.idx(f);
        let far = seeds
            .iter()
            .all(|s| (0..3).map(|d| s[d].abs_diff(i[d])).max().unwrap_or(0) >= apart);
        if far {
            seeds.push(i);
            if seeds.len() == search.seeds {
                break;
            }
        }
    }

    let settings = options.feedforward.settings();
    let budget = search.max_verdicts;
    let judged = AtomicUsize::new(0);
    // Each setting gets its share, so the first cannot starve the second.
    let share = (budget / settings.len()).max(1);
    let limit = AtomicUsize::new(share);
    // Positions are grid coordinates (fractional between grid points), keyed at an
    // eighth of a grid step.
    let key_of = |x: [f64; 3]| x.map(|v| (v * 8.0).round() as i64);
    let gains_at = |x: [f64; 3]| {
        let g = |c: f64, span: f64, v: f64| c * span.powf(2.0 * v / (n - 1) as f64 - 1.0);
        Gains {
            kp: g(c0.kp, search.span[0], x[0]),
            ki: g(c0.ki, search.span[1], x[1]),
            kd: g(c0.kd, search.span[2], x[2]),
        }
    };
    // The linear screen anywhere: the grid's record at a grid point, else screened anew.
    let screen_cache: Mutex<HashMap<[i64; 3], ScreenRecord>> = Mutex::new(HashMap::new());
    let screen = |x: [f64; 3]| -> (Option<String>, f64) {
        if x.iter().any(|&v| v < -1e-9 || v > (n - 1) as f64 + 1e-9) {
            return (Some("beyond the searched range".into()), f64::INFINITY);
        }
        let k = key_of(x);
        if k.iter().all(|v| v % 8 == 0) {
            let gp = grid.at(k.map(|v| (v / 8) as usize));
            return (gp.missed.clone(), gp.compliance);
        }
        if let Some(r) = screen_cache
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(&k)
        {
            return r.clone();
        }
        let r = screen_gains(&gains_at(x));
        screen_cache
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(k, r.clone());
        r
    };
    let cache: Mutex<HashMap<([i64; 3], bool), usize>> = Mutex::new(HashMap::new());
    let verified: Mutex<Vec<Candidate>> = Mutex::new(Vec::new());
    let score = |c: &Candidate| -> f64 {
        match (c.signable, c.peak_mrad) {
            (true, Some(pk)) => pk,
            _ => f64::INFINITY,
        }
    };
    // Judges positions not judged before (in parallel), within the budget; returns each
    // position's score (infinite when not judged, not signable or stopped).
    let evaluate = |batch: &[([f64; 3], bool)]| -> Vec<f64> {
        let todo: Vec<([f64; 3], bool)> = {
            let c = cache.lock().unwrap_or_else(|e| e.into_inner());
            let mut seen = std::collections::HashSet::new();
            batch
                .iter()
                .copied()
                .filter(|(x, ff)| {
                    !c.contains_key(&(key_of(*x), *ff)) && seen.insert((key_of(*x), *ff))
                })
                .collect()
        };
        let room = limit
            .load(Ordering::Relaxed)
            .min(budget)
            .saturating_sub(judged.load(Ordering::Relaxed));
        let todo: Vec<([f64; 3], bool)> = todo.into_iter().take(room).collect();
        let done: Vec<(([i64; 3], bool), Candidate)> = todo
            .par_iter()
            .map(|&(x, ff)| {
                let (_, compliance) = screen(x);
                let cand = judge(&design(&s, &gains_at(x), ff), "search", Some(compliance));
                let d = judged.fetch_add(1, Ordering::Relaxed) + 1;
                progress(Progress {
                    stage: "nonlinear search",
                    done: d,
                    total: budget,
                });
                ((key_of(x), ff), cand)
            })
            .collect();
        {
            let mut c = cache.lock().unwrap_or_else(|e| e.into_inner());
            let mut v = verified.lock().unwrap_or_else(|e| e.into_inner());
            for (k, cand) in done {
                c.insert(k, v.len());
                v.push(cand);
            }
        }
        let c = cache.lock().unwrap_or_else(|e| e.into_inner());
        let v = verified.lock().unwrap_or_else(|e| e.into_inner());
        batch
            .iter()
            .map(|(x, ff)| {
                c.get(&(key_of(*x), *ff))
                    .map_or(f64::INFINITY, |&j| score(&v[j]))
            })
            .collect()
    };
    // Axis moves and every two-axis diagonal: the best designs sit where two or three
    // margin requirements meet, and a ridge between them is followed only diagonally.
    let mut moves: Vec<[f64; 3]> = Vec::new();
    for d in 0..3 {
        for sgn in [1.0, -1.0] {
            let mut m = [0.0; 3];
            m[d] = sgn;
            moves.push(m);
        }
    }
    for (d0, d1) in [(0, 1), (0, 2), (1, 2)] {
        for (s0, s1) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
            let mut m = [0.0; 3];
            m[d0] = s0;
            m[d1] = s1;
            moves.push(m);
        }
    }
    let finest = 0.25;
    // Every direction to a neighbour of the 3 x 3 x 3 cube around a point.
    let neighbours: Vec<[f64; 3]> = (0..27)
        .filter(|&i| i != 13)
        .map(|i| {
            [
                (i / 9) as f64 - 1.0,
                ((i / 3) % 3) as f64 - 1.0,
                (i % 3) as f64 - 1.0,
            ]
        })
        .collect();
    for (k_setting, &ff) in settings.iter().enumerate() {
        limit.store(share * (k_setting + 1), Ordering::Relaxed);
        let mut starts: Vec<([f64; 3], bool)> =
            seeds.iter().map(|&i| (i.map(|v| v as f64), ff)).collect();
        // The scenario's own gains (the grid's centre) start a search too when they are
        // signable on the linear loop: the design an engineer brings is a natural seed,
        // and where the linear ranking misleads it is often the better one.
        let middle = [(n - 1) as f64 / 2.0; 3];
        let given = options.seeds_from.iter().map(|g| {
            let at = |v: f64, c: f64, span: f64| {
                (n - 1) as f64 / 2.0 * ((v / c).ln() / span.ln().max(1e-12) + 1.0)
            };
            [
                at(g.kp, c0.kp, search.span[0]),
                at(g.ki, c0.ki, search.span[1]),
                at(g.kd, c0.kd, search.span[2]),
            ]
        });
        // Designs given (found at other rates) go first, so the budget is spent on them
        // before the linear seeds; the scenario's gains go last.
        let (mut first, mut last) = (Vec::new(), Vec::new());
        for (k, x) in std::iter::once(middle).chain(given).enumerate() {
            if !x.iter().all(|v| v.is_finite()) {
                continue;
            }
            // A seed the margins forbid here (a design from a faster rate) starts from
            // its nearest signable neighbour instead: the least step, then the least
            // compliance among all 26 directions.
            let x = if screen(x).0.is_none() {
                Some(x)
            } else {
                [0.25, 0.5, 1.0, 2.0].iter().find_map(|&step| {
                    neighbours
                        .iter()
                        .map(|d| [0, 1, 2].map(|k| x[k] + d[k] * step))
                        .filter_map(|y| {
                            let (missed, c) = screen(y);
                            missed.is_none().then_some((y, c))
                        })
                        .min_by(|a, b| a.1.total_cmp(&b.1))
                        .map(|(y, _)| y)
                })
            };
            if let Some(x) = x {
                if k == 0 {
                    last.push((x, ff));
                } else {
                    first.push((x, ff));
                }
            }
        }
        let linear = std::mem::take(&mut starts);
        for (x, ff) in first.into_iter().chain(linear).chain(last) {
            if !starts.iter().any(|(y, _)| key_of(*y) == key_of(x)) {
                starts.push((x, ff));
            }
        }
        let scores = evaluate(&starts);
        // The budget goes to the most promising starts first: a design found at another
        // rate can be far from the best here, and searching from it in the order given
        // would spend the budget before the good starts are reached.
        let mut ranked: Vec<([f64; 3], f64)> = starts.iter().map(|(x, _)| *x).zip(scores).collect();
        ranked.sort_by(|a, b| a.1.total_cmp(&b.1));
        for (x0, score0) in ranked {
            let mut best = (x0, score0);
            let mut step = search.first_step as f64;
            while step >= finest && judged.load(Ordering::Relaxed) < limit.load(Ordering::Relaxed) {
                // At the finest step every neighbour of the cube is tried: the best
                // designs sit where the margin requirements meet, and a ridge that runs
                // along all three gains is followed only by a three-axis diagonal.
                let dirs = if step > finest { &moves } else { &neighbours };
                let around: Vec<([f64; 3], bool)> = dirs
                    .iter()
                    .map(|m| [0, 1, 2].map(|d| best.0[d] + m[d] * step))
                    .filter(|&x| screen(x).0.is_none())
                    .map(|x| (x, ff))
                    .collect();
                let got = evaluate(&around);
                match around
                    .iter()
                    .zip(&got)
                    .filter(|(_, &sc)| sc < best.1)
                    .min_by(|a, b| a.1.total_cmp(b.1))
                {
                    Some((&(x, _), &sc)) => best = (x, sc),
                    None => step /= 2.0,
                }
            }
        }
    }
    let mut verified = verified.into_inner().unwrap_or_else(|e| e.into_inner());
    let cache = cache.into_inner().unwrap_or_else(|e| e.into_inner());
    let best_of = |v: &[Candidate], ff: Option<bool>| -> Option<usize> {
        v.iter()
            .enumerate()
            .filter(|(_, c)| ff.is_none_or(|f| c.load_feedforward == f))
            .filter(|(_, c)| score(c).is_finite())
            .min_by(|a, b| score(a.1).total_cmp(&score(b.1)))
            .map(|(i, _)| i)
    };
    // The pick and the bests are chosen among the search's candidates only: the
    // sensitivity runs below describe the pick, they do not compete with it.
    let pick = best_of(&verified, None);
    let best_without_feedforward = best_of(&verified, Some(false));
    let best_with_feedforward = best_of(&verified, Some(true));
    mark_front(&mut verified);

    // What stops the pick from moving: the first requirement the linear screen finds
    // missed a finest step away along each gain.
    let mut blocked_moves = Vec::new();
    if let Some(pi) = pick {
        let at = cache
            .iter()
            .find(|(_, &j)| j == pi)
            .map(|(k, _)| k.0.map(|v| v as f64 / 8.0));
        if let Some(at) = at {
            for (d, word) in [
                ([1.0, 0.0, 0.0], "kp up"),
                ([-1.0, 0.0, 0.0], "kp down"),
                ([0.0, 1.0, 0.0], "ki up"),
                ([0.0, -1.0, 0.0], "ki down"),
                ([0.0, 0.0, 1.0], "kd up"),
                ([0.0, 0.0, -1.0], "kd down"),
            ] {
                let x = [0, 1, 2].map(|k| at[k] + d[k] * finest);
                if let Some(m) = screen(x).0 {
                    blocked_moves.push(format!("{word}: {m}"));
                }
            }
        }
    }

    // Sensitivity: the pick's gains moved a little each way, judged in full.
    let mut sensitivity = Vec::new();
    if let (Some(pi), true) = (pick, search.sensitivity_step > 0.0) {
        let pc = verified[pi].clone();
        let h = search.sensitivity_step;
        let moves: Vec<(&'static str, f64)> = ["kp", "ki", "kd"]
            .iter()
            .flat_map(|&g| [(g, -h), (g, h)])
            .collect();
        let stage_total = moves.len();
        let done = AtomicUsize::new(0);
        let rows: Vec<(Candidate, Sensitivity)> = moves
            .par_iter()
            .map(|&(g, change)| {
                let mut gains = pc.gains;
                match g {
                    "kp" => gains.kp *= 1.0 + change,
                    "ki" => gains.ki *= 1.0 + change,
                    _ => gains.kd *= 1.0 + change,
                }
                let c = judge(
                    &design(&s, &gains, pc.load_feedforward),
                    "sensitivity",
                    None,
                );
                progress(Progress {
                    stage: "sensitivity",
                    done: done.fetch_add(1, Ordering::Relaxed) + 1,
                    total: stage_total,
                });
                let worst = |f: &dyn Fn(&PointFigures) -> Option<f64>, max: bool| {
                    c.margins
                        .iter()
                        .filter_map(f)
                        .fold(None, |acc: Option<f64>, v| {
                            Some(acc.map_or(v, |a| if max { a.max(v) } else { a.min(v) }))
                        })
                };
                let row = Sensitivity {
                    gain: g,
                    change,
                    peak_mrad: c.peak_mrad,
                    peak_change_mrad: c.peak_mrad.zip(pc.peak_mrad).map(|(a, b)| a - b),
                    phase_margin_deg: worst(&|m| m.phase_margin_deg, false),
                    gain_margin_db: worst(
                        &|m| match (m.gain_margin_up_db, m.gain_margin_down_db) {
                            (Some(u), Some(d)) => Some(u.min(d)),
                            (u, d) => u.or(d),
                        },
                        false,
                    ),
                    ms: worst(&|m| m.ms, true),
                    signable: c.signable,
                };
                (c, row)
            })
            .collect();
        for (c, row) in rows {
            verified.push(c);
            sensitivity.push(row);
        }
    }

    let active_constraint = pick.and_then(|pi| active_constraint(&s, &verified[pi]));
    let scenario_design = {
        let mut own = base.clone();
        if let Some(cl) = own.closed_loop.as_mut() {
            cl.requirements.mode = Some(options.mode);
        }
        judge(&own, "scenario", None)
    };
    let tuned = pick.map(|pi| {
        let c = &verified[pi];
        let mut t = design(&s, &c.gains, c.load_feedforward);
        t.name = Some(format!("{}_tuned", s.name()));
        t.description = Some(format!(
            "{} (PID tuned at {} Hz by cable-servo design tune: {} mode peak {} mrad)",
            s.description.as_deref().unwrap_or(s.name()),
            crate::compact(rate_hz),
            options.mode.name(),
            c.peak_mrad.map_or("-".into(), crate::compact)
        ));
        t
    });
    Ok(Stage::Searched(Box::new(TuneResult {
        scenario: s.name().to_string(),
        rate_hz,
        mode: options.mode,
        feedforward: options.feedforward,
        target_mrad: p.target_mrad,
        searched: format!(
            "PID gains (derivative filter {} Hz{} kept) on a {n} x {n} x {n} log grid: kp {} to {}, ki {} to {}, kd {} to {}; linear screen at {} frequencies per stiffness over {}; pattern search on the nonlinear plant ({} mode, load feedforward {}) from {} seed(s) of the linear ranking and the scenario's own gains where signable, at most {} verdicts",
            crate::compact(ctl.derivative_filter_hz),
            if ctl.command_filters.is_empty() {
                String::new()
            } else {
                format!(
                    " and the command filters {}",
                    filter_label(ctl.derivative_filter_hz, &ctl.command_filters)
                )
            },
            crate::significant(kps[0], 3),
            crate::significant(kps[n - 1], 3),
            crate::significant(kis[0], 3),
            crate::significant(kis[n - 1], 3),
            crate::significant(kds[0], 3),
            crate::significant(kds[n - 1], 3),
            SCREEN_POINTS,
            stiffness
                .iter()
                .map(|s| s.condition.as_str())
                .collect::<Vec<_>>()
                .join(" and "),
            options.mode.name(),
            match options.feedforward {
                Feedforward::Without => "off",
                Feedforward::With => "on",
                Feedforward::Both => "off and on",
            },
            seeds.len(),
            budget
        ),
        linear_candidates: total,
        linear_feasible,
        best_without_feedforward,
        best_with_feedforward,
        pick,
        verified,
        scenario_design,
        sensitivity,
        active_constraint,
        blocked_moves,
        elapsed_s: started.elapsed().as_secs_f64(),
        filter_variants: Vec::new(),
        tuned,
    })))
}

/// Relative margin under which a requirement counts as active at the pick (5 %: a grid
/// step of the search moves a margin by about that much).
const ACTIVE_WITHIN: f64 = 0.05;

/// The margin requirement with the least relative margin at `c`, in words, and whether
/// it is active (within [`ACTIVE_WITHIN`] of its limit).
fn active_constraint(s: &Scenario, c: &Candidate) -> Option<String> {
    let req = &s.closed_loop.as_ref()?.requirements;
    let mut rows: Vec<(f64, String)> = Vec::new();
    for m in &c.margins {
        if let Some(pm) = m.phase_margin_deg {
            rows.push((
                pm / req.min_phase_margin_deg - 1.0,
                format!(
                    "phase margin at {}: {} deg (>= {})",
                    m.condition,
                    crate::significant(pm, 4),
                    crate::compact(req.min_phase_margin_deg)
                ),
            ));
        }
        for (gm, dir) in [(m.gain_margin_up_db, "up"), (m.gain_margin_down_db, "down")] {
            if let Some(gm) = gm {
                rows.push((
                    gm / req.min_gain_margin_db - 1.0,
                    format!(
                        "gain margin {dir} at {}: {} dB (>= {})",
                        m.condition,
                        crate::significant(gm, 4),
                        crate::compact(req.min_gain_margin_db)
                    ),
                ));
            }
        }
        if let Some(ms) = m.ms {
            rows.push((
                req.max_ms / ms - 1.0,
                format!(
                    "sensitivity peak at {}: {} (<= {})",
                    m.condition,
                    crate::significant(ms, 4),
                    crate::compact(req.max_ms)
                ),
            ));
        }
    }
    // A requirement within a few percent of its limit is what holds the pick back; far
    // from every limit, the pick is an optimum of the peak itself.
    rows.into_iter()
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(r, words)| {
            let inside = crate::significant(100.0 * r, 2);
            if r <= ACTIVE_WITHIN {
                format!("{words}, {inside} % inside its limit")
            } else {
                format!(
                    "none: the pick is an optimum of the peak inside every limit; the closest is {words}, {inside} % inside"
                )
            }
        })
}

/// Marks the trade-off front of each load-feedforward setting: signable candidates no
/// other signable one beats on both the peak (lower) and the margin class (higher).
fn mark_front(v: &mut [Candidate]) {
    let key = |c: &Candidate| match (c.signable, c.peak_mrad, c.margin_class) {
        (true, Some(p), Some(m)) => Some((p, m)),
        _ => None,
    };
    let flags: Vec<bool> = v
        .iter()
        .map(|c| {
            let Some((p, m)) = key(c) else { return false };
            !v.iter().any(|o| {
                o.load_feedforward == c.load_feedforward
                    && key(o).is_some_and(|(po, mo)| po <= p && mo >= m && (po < p || mo > m))
            })
        })
        .collect();
    for (c, f) in v.iter_mut().zip(flags) {
        c.on_front = f;
    }
}

/// Passing designs with the most margin that each least-rate probe hands to the later
/// tunes as seeds, besides its pick.
const CARRIED_PER_PROBE: usize = 3;

/// Most tunes one least-rate search makes (the bisection needs about ten).
pub const MAX_RATE_PROBES: usize = 24;

/// One rate probed by [`least_rate`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RateProbe {
    /// Control rate, Hz.
    pub rate_hz: f64,
    /// The tune's pick there (`None`: no signable design completed a run).
    pub pick: Option<Candidate>,
    /// Whether the pick meets every requirement, the pointing target included.
    pub passes: bool,
    /// Verdicts the tune made.
    pub verdicts: usize,
    /// Wall time of the tune, s.
    pub elapsed_s: f64,
}

/// The least control rate at which a tuned, signable design meets the target.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LeastRate {
    /// Scenario.
    pub scenario: String,
    /// Compensation mode judged.
    pub mode: CompensationMode,
    /// Load-feedforward settings tried at each rate.
    pub feedforward: Feedforward,
    /// Pointing target, mrad.
    pub target_mrad: f64,
    /// Searched range, Hz.
    pub range_hz: (f64, f64),
    /// Tolerance asked, Hz.
    pub tolerance_hz: f64,
    /// Highest rate probed at which the tune found no passing design, Hz (`None`: even
    /// the lower end passes).
    pub failing_hz: Option<f64>,
    /// Lowest rate probed with a verified passing design, Hz (`None`: even the upper
    /// end fails).
    pub passing_hz: Option<f64>,
    /// Whether the failing end was tuned again with every design found by the search as
    /// a seed and still failed (false when the probe limit stopped the search first).
    pub failing_confirmed: bool,
    /// Every probe, in the order made.
    pub probes: Vec<RateProbe>,
    /// What the bracket proves, in words.
    pub definition: String,
}

/// The least control rate in `range_hz` at which `tune` finds a design meeting every
/// requirement in `options.mode`, by bisection to `tolerance_hz` with a tune at each
/// probe (the rate of `options` is ignored). The passing end of the bracket is proven by
/// a verified design; the failing end says only that the search found none there, and
/// the bisection assumes a faster loop never does worse.
pub fn least_rate(
    base: &Scenario,
    options: &TuneOptions,
    range_hz: (f64, f64),
    tolerance_hz: f64,
    progress: &(dyn Fn(f64, Progress) + Sync),
) -> Result<LeastRate, DesignError> {
    let (lo, hi) = range_hz;
    if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo && tolerance_hz > 0.0) {
        return Err(DesignError::Unsuitable(format!(
            "need rates 0 < lo < hi and a tolerance > 0, got {} to {} Hz and {} Hz",
            crate::number(lo),
            crate::number(hi),
            crate::number(tolerance_hz)
        )));
    }
    // Both ends must be rates the scenario accepts (fast enough for its plant), said
    // before any tune is spent.
    for (end, rate) in [("lower", lo), ("upper", hi)] {
        let o = TuneOptions {
            rate_hz: Some(rate),
            ..options.clone()
        };
        prepared(base, &o).map_err(|e| {
            DesignError::Unsuitable(format!(
                "the {end} end of the search, {} Hz: {e}",
                crate::compact(rate)
            ))
        })?;
    }
    let target = base
        .closed_loop
        .as_ref()
        .map_or(f64::NAN, |c| c.target_mrad);
    let mut probes: Vec<RateProbe> = Vec::new();
    // Continuation: designs that passed at earlier probes seed every later tune, so a
    // design found at one rate is not lost to a local search at the next. Besides each
    // pick, the passing designs with the most margin are carried: the pick sits on a
    // margin limit that a slower loop crosses, while a design with margin to spare
    // often still passes there.
    let carried: Mutex<Vec<Gains>> = Mutex::new(Vec::new());
    let probe = |probes: &mut Vec<RateProbe>, rate: f64| -> Result<bool, DesignError> {
        let mut seeds_from = options.seeds_from.clone();
        seeds_from.extend(
            probes
                .iter()
                .filter_map(|p| p.pick.as_ref().map(|c| c.gains)),
        );
        seeds_from.extend(carried.lock().unwrap_or_else(|e| e.into_inner()).iter());
        let o = TuneOptions {
            rate_hz: Some(rate),
            seeds_from,
            ..options.clone()
        };
        let r = tune(base, &o, &|p| progress(rate, p))?;
        {
            let mut passing: Vec<&Candidate> = r.verified.iter().filter(|c| c.passes).collect();
            passing.sort_by(|a, b| {
                b.margin_class
                    .unwrap_or(f64::NEG_INFINITY)
                    .total_cmp(&a.margin_class.unwrap_or(f64::NEG_INFINITY))
            });
            let mut c = carried.lock().unwrap_or_else(|e| e.into_inner());
            for cand in passing.into_iter().take(CARRIED_PER_PROBE) {
                if !c.contains(&cand.gains) {
                    c.push(cand.gains);
                }
            }
        }
        let pick = r.picked().cloned();
        let passes = pick.as_ref().is_some_and(|c| c.passes);
        probes.push(RateProbe {
            rate_hz: rate,
            passes,
            pick,
            verdicts: r.verified.len(),
            elapsed_s: r.elapsed_s,
        });
        Ok(passes)
    };
    // The upper end must pass and the lower end fail for a bracket; otherwise the
    // answer is the end itself. The search at each rate is local, so a failing end is
    // confirmed by tuning it again with every design found since as a seed; when that
    // passes, the bisection goes on below it.
    let mut confirmed = false;
    let (failing, passing) = if !probe(&mut probes, hi)? {
        (Some(hi), None)
    } else if probe(&mut probes, lo)? {
        (None, Some(lo))
    } else {
        let (mut a, mut b) = (lo, hi);
        while !confirmed && probes.len() < MAX_RATE_PROBES {
            while b - a > tolerance_hz && probes.len() < MAX_RATE_PROBES {
                let mid = 0.5 * (a + b);
                if probe(&mut probes, mid)? {
                    b = mid;
                } else {
                    a = mid;
                }
            }
            if probe(&mut probes, a)? {
                b = a;
                // The next failing rate below: the highest probed failure under `a`.
                a = probes
                    .iter()
                    .filter(|p| !p.passes && p.rate_hz < b)
                    .map(|p| p.rate_hz)
                    .fold(lo, f64::max);
                if a == lo && probes.iter().any(|p| p.rate_hz == lo && p.passes) {
                    break;
                }
            } else {
                confirmed = true;
            }
        }
        (Some(a).filter(|_| a < b), Some(b))
    };
    Ok(LeastRate {
        scenario: base.name().to_string(),
        mode: options.mode,
        feedforward: options.feedforward,
        target_mrad: target,
        range_hz,
        tolerance_hz,
        failing_hz: failing,
        passing_hz: passing,
        failing_confirmed: confirmed,
        probes,
        definition: format!(
            "least control rate at which design tune finds a design meeting every requirement ({} mode, pointing within {} mrad, the margins over the operating range): the passing rate carries a verified design; at the failing rate the search found none, which bounds what this search finds, not what a PID can do; bisection, assuming a faster loop never does worse",
            options.mode.name(),
            crate::compact(target)
        ),
    })
}
