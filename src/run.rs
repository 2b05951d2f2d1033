//! Running a scenario end to end: compute, write CSV and JSON, then plots, into a staged
//! results directory that appears only when complete (or marked incomplete).
//! Top layer: may import every module below.

use std::path::{Path, PathBuf};

use crate::closed_loop;
use crate::io::output::{OutputError, StagedDir};
use crate::io::sweep_columns;
use crate::report::{self, ReportError};
use crate::scenario::{Scenario, ScenarioError, Study};
use crate::study::quasi_static::{self, BacklashResult};
use crate::sweep::engine::{self, Case, Cell, Shard, SweepError};

mod case;
pub mod progress;
pub use case::{case_dir, case_scenario, run_one_case, CaseRunner};

/// Why a run produced no (complete) results.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The scenario is unusable.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// A table the scenario references is unusable.
    #[error(transparent)]
    Table(#[from] crate::io::tables::TableError),
    /// The results directory cannot be prepared or moved into place.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// A result file cannot be written.
    #[error(transparent)]
    Report(#[from] ReportError),
    /// A sweep failed.
    #[error(transparent)]
    Sweep(#[from] SweepError),
    /// The requested study cannot run here.
    #[error("{0}")]
    Unsupported(String),
    /// The closed loop cannot start with this scenario.
    #[error(transparent)]
    ClosedLoop(#[from] crate::closed_loop::ClosedLoopError),
    /// A diagnosis cannot be made.
    #[error(transparent)]
    Identify(#[from] crate::identify::IdentifyError),
    /// A bench log cannot be read.
    #[error(transparent)]
    Log(#[from] crate::io::benchlog::LogError),
    /// A frequency response cannot be measured with these settings.
    #[error(transparent)]
    FreqResp(#[from] crate::analysis::freqresp::FreqRespError),
}

/// What a run produced.
#[derive(Debug, Clone)]
pub struct RunReport {
    /// Results directory.
    pub dir: PathBuf,
    /// Short table for the terminal.
    pub table: String,
    /// False when the physics stopped the run early (results kept, marked incomplete).
    pub complete: bool,
    /// What stopped it, when incomplete.
    pub failure: Option<String>,
    /// Warnings (capacity, plots that failed).
    pub warnings: Vec<String>,
    /// The signal (SIGINT 2, SIGTERM 15) that interrupted the run, if one did.
    pub signal: Option<i32>,
    /// Whether the design(s) meet every requirement (closed-loop runs, comparisons,
    /// sweeps); `None` where nothing is judged (quasi-static studies, diagnoses).
    pub requirements_met: Option<bool>,
}

/// Where and how to write results.
#[derive(Debug, Clone)]
pub struct OutputOptions {
    /// Final results directory.
    pub dir: PathBuf,
    /// Replace an existing directory.
    pub force: bool,
}

/// Results directory used when the user names none: `base` itself when it is free or
/// `force` asks to replace it, else the first free `base-2`, `base-3`, ... so repeating a
/// command keeps earlier results and still succeeds.
pub fn default_results_dir(base: &Path, force: bool) -> PathBuf {
    if force || std::fs::symlink_metadata(base).is_err() {
        return base.to_path_buf();
    }
    let name = base
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    (2u64..)
        .map(|k| base.with_file_name(format!("{name}-{k}")))
        .find(|p| std::fs::symlink_metadata(p).is_err())
        .unwrap_or_else(|| base.to_path_buf())
}

/// Whether `--load-nm` (N m), when given, is a torque [`run_margins`] can explore: finite
/// and > 0. Checked before anything runs or is printed.
pub fn check_load_nm(load_nm: Option<f64>) -> Result<(), RunError> {
    match load_nm {
        Some(load) if !(load.is_finite() && load > 0.0) => Err(RunError::Unsupported(format!(
            "--load-nm {}: give a transmitted torque > 0 N m",
            crate::readable(load)
        ))),
        _ => Ok(()),
    }
}

/// Run a single scenario (quasi-static, backlash or closed-loop study).
pub fn run_scenario(scenario: &Scenario, out: &OutputOptions) -> Result<RunReport, RunError> {
    run_scenario_with_progress(scenario, out, &crate::progress::Silent)
}

/// [`run_scenario`], reporting the long parts (the error budget's runs) to `progress`.
pub fn run_scenario_with_progress(
    scenario: &Scenario,
    out: &OutputOptions,
    progress: &dyn crate::progress::Progress,
) -> Result<RunReport, RunError> {
    let mut warnings = scenario.warnings();
    let staged = StagedDir::create(&out.dir, out.force)?;
    let dir = staged.path().to_path_buf();
    let mut met = None;
    let (table, failure) = match scenario.study {
        Study::QuasiStatic => run_quasi_static(scenario, &dir, &mut warnings)?,
        Study::Backlash => run_backlash(scenario, &dir, &warnings)?,
        Study::ClosedLoop => run_closed_loop(scenario, &dir, &mut warnings, &mut met, progress)?,
    };
    let mut report = finish(staged, table, failure, warnings)?;
    report.requirements_met = met;
    Ok(report)
}

fn finish(
    staged: StagedDir,
    table: String,
    failure: Option<String>,
    mut warnings: Vec<String>,
) -> Result<RunReport, RunError> {
    html_report(staged.path(), &mut warnings, failure.as_deref());
    let dir = match &failure {
        None => staged.commit()?,
        Some(reason) => staged.commit_incomplete(reason)?,
    };
    Ok(RunReport {
        dir,
        table,
        complete: failure.is_none(),
        failure,
        warnings,
        signal: None,
        requirements_met: None,
    })
}

/// `report.html`, written last into the staged directory so it shows every file and
/// warning of the run; like the plots it never breaks a run: a failure becomes a warning.
fn html_report(dir: &Path, warnings: &mut Vec<String>, stopped: Option<&str>) {
    if let Err(e) = report::html::write_report_with(dir, warnings, stopped) {
        warnings.push(format!("{} not written: {e}", report::html::REPORT_FILE));
    }
}

/// Plots never break a run: a failure becomes a warning.
fn plots(result: Result<Vec<PathBuf>, ReportError>, warnings: &mut Vec<String>) {
    if let Err(e) = result {
        warnings.push(format!("plots incomplete: {e}"));
    }
}

fn run_quasi_static(
    scenario: &Scenario,
    dir: &Path,
    warnings: &mut Vec<String>,
) -> Result<(String, Option<String>), RunError> {
    let qs = scenario
        .quasi_static
        .as_ref()
        .ok_or_else(|| RunError::Unsupported("no [quasi_static] section".into()))?;
    let traces: Vec<_> = qs
        .models
        .iter()
        .map(|&m| quasi_static::run_model(&scenario.drive, &scenario.load, qs, m))
        .collect();
    report::quasi_static::write_tables(dir, &traces)?;
    report::quasi_static::write_summary(dir, scenario, &traces, warnings)?;
    plots(
        report::quasi_static::plot(dir, &scenario.drive, &traces),
        warnings,
    );
    let mut table = format!(
        "{:<12} {:>12} {:>12} {:>12} {:>10} {:>10}\n",
        "model", "peak_mrad", "p2p_mrad", "jump_mrad", "Tmin_n", "Tmax_n"
    );
    for t in &traces {
        let f = t.figures();
        if t.samples.is_empty() {
            // No sample: no figure to show (zeros would read as results).
            table.push_str(&format!(
                "{:<12} {:>12} {:>12} {:>12} {:>10} {:>10}  no samples: stopped at the start\n",
                f.model, "-", "-", "-", "-", "-"
            ));
            continue;
        }
        table.push_str(&format!(
            "{:<12} {:>12.6} {:>12.6} {:>12.6} {:>10.3} {:>10.3}\n",
            f.model,
            f.peak_error_mrad,
            f.peak_to_peak_error_mrad,
            f.largest_jump_mrad,
            f.tension_min_n,
            f.tension_max_n
        ));
    }
    let failure = traces.iter().find_map(|t| {
        t.stop.map(|s| {
            format!(
                "{} model stopped at t = {:.4} s: {}",
                quasi_static::model_name(t.model),
                s.t_s,
                s.fault
            )
        })
    });
    Ok((table, failure))
}

fn run_closed_loop(
    scenario: &Scenario,
    dir: &Path,
    warnings: &mut Vec<String>,
    requirements_met: &mut Option<bool>,
    progress: &dyn crate::progress::Progress,
) -> Result<(String, Option<String>), RunError> {
    let options = scenario
        .closed_loop
        .as_ref()
        .map_or_else(closed_loop::RunOptions::default, recording);
    let (result, rows) = closed_loop::run_closed_loop_then(
        scenario,
        &options,
        report::closed_loop::timeseries_rows,
    )?;
    let target = scenario.closed_loop.as_ref().map_or(0.1, |c| c.target_mrad);
    let setup = closed_loop::ClosedLoopSource::closed_loop_setup(scenario)?;
    let verdict = crate::analysis::verdict::judged_result(setup.params, &result.modes)
        .map(|judged| crate::analysis::verdict::judge(&setup, judged));
    *requirements_met = Some(verdict.as_ref().is_some_and(|v| v.passes));
    // The figures are drawn from the result in memory while the data files are written:
    // neither waits for the other, and a figure that fails, even by a panic in the
    // drawing library, becomes a warning and never touches the data.
    let (written, drawn) = std::thread::scope(|s| {
        let figures = s.spawn(|| {
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                report::closed_loop::plot_closed_loop(
                    dir,
                    &result,
                    target,
                    report::closed_loop::command_unit(scenario),
                )
            }))
        });
        let written = report::closed_loop::write_closed_loop_outputs_with_rows(
            dir,
            scenario,
            &result,
            rows,
            verdict.as_ref(),
        );
        (written, figures.join())
    });
    written?;
    match drawn {
        Ok(Ok(Ok(_))) => {}
        Ok(Ok(Err(e))) => warnings.push(format!("plots incomplete: {e}")),
        Ok(Err(_)) | Err(_) => {
            warnings.push("plots incomplete: the drawing library failed (panicked)".into())
        }
    }
    let failure = result.modes.iter().find_map(|m| match &m.completion {
        closed_loop::Completion::Complete => None,
        closed_loop::Completion::Incomplete { fault, time_s, .. } => Some(format!(
            "mode {} stopped at t = {} s: {fault}",
            m.mode.name(),
            crate::readable(*time_s)
        )),
    });
    let mut table = report::closed_loop::format_table(&result);
    if scenario
        .closed_loop
        .as_ref()
        .is_some_and(|c| c.error_budget)
    {
        let setup = closed_loop::ClosedLoopSource::closed_loop_setup(scenario)?;
        let budget = crate::analysis::budget::error_budget_with_progress(&setup, progress)?;
        report::closed_loop::write_budget(dir, &budget)?;
        table.push_str(&report::closed_loop::format_budget(&budget));
    }
    if let Some(v) = &verdict {
        table.push_str(&v.table());
    }
    Ok((table, failure))
}

fn run_backlash(
    scenario: &Scenario,
    dir: &Path,
    warnings: &[String],
) -> Result<(String, Option<String>), RunError> {
    let params = scenario
        .backlash
        .as_ref()
        .ok_or_else(|| RunError::Unsupported("no [backlash] section".into()))?;
    let result = quasi_static::backlash(&scenario.drive, params);
    report::quasi_static::write_backlash(dir, scenario, &result, warnings)?;
    let show = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.6}"));
    let table = format!(
        "{:<10} {:>10} {:>14} {:>14} {}\n{:<10} {:>10.3} {:>14} {:>14} {}\n",
        "preload_n",
        "load_nm",
        "initial_mrad",
        "reversal_mrad",
        "regime",
        scenario.drive.preload_n,
        params.load_nm,
        show(result.initial_mrad),
        show(result.reversal_mrad),
        result.regime.as_str()
    );
    Ok((table, result.fault.clone()))
}

/// Figures of one backlash case.
pub struct BacklashRunner;

impl CaseRunner for BacklashRunner {
    fn columns(&self) -> Vec<String> {
        sweep_columns::BACKLASH.map(String::from).to_vec()
    }

    fn run(&self, scenario: &Scenario, _case: &Case) -> Vec<Cell> {
        let r: BacklashResult = match &scenario.backlash {
            Some(p) => quasi_static::backlash(&scenario.drive, p),
            // Validation requires the section; should a case lack it all the same, the
            // row says why it has no figures rather than leaving a blank status.
            None => {
                let mut cells: Vec<Cell> = (0..3).map(|_| Cell::Num(None)).collect();
                cells.extend([
                    Cell::Text(String::new()),
                    Cell::Text("false".into()),
                    Cell::Num(None),
                    Cell::Text("error".into()),
                    Cell::Text(
                        "study = \"backlash\" needs a [backlash] section with load_nm".into(),
                    ),
                ]);
                return cells;
            }
        };
        let stop = match (r.regime, &r.fault) {
            (quasi_static::Regime::Ok, _) => String::new(),
            (_, Some(fault)) => fault.clone(),
            // The protocol records its fault with every stop; this only guards the row
            // against a blank reason.
            (regime, None) => format!("{} during the +M, -M, +M protocol", regime.as_str()),
        };
        vec![
            Cell::Num(r.initial_mrad),
            Cell::Num(r.reversal_mrad),
            Cell::Num(r.first_reversal_mrad),
            Cell::Text(r.regime.as_str().into()),
            Cell::Text(r.anchor_reached.to_string()),
            Cell::Num(r.tension_upper_n),
            Cell::Text(r.regime.as_str().into()),
            Cell::Text(stop),
        ]
    }
}

/// Figures of one quasi-static case (first model of the scenario).
pub struct QuasiStaticRunner;

impl CaseRunner for QuasiStaticRunner {
    fn columns(&self) -> Vec<String> {
        sweep_columns::QUASI_STATIC.map(String::from).to_vec()
    }

    fn run(&self, scenario: &Scenario, _case: &Case) -> Vec<Cell> {
        let Some(qs) = &scenario.quasi_static else {
            // Validation requires the section; should a case lack it all the same, the
            // row says why it has no figures rather than leaving a blank status.
            let mut cells: Vec<Cell> = (0..6).map(|_| Cell::Num(None)).collect();
            cells.extend([
                Cell::Text("error".into()),
                Cell::Text("study = \"quasi_static\" needs a [quasi_static] section".into()),
            ]);
            return cells;
        };
        let model = qs.models.first().copied().unwrap_or_default();
        let trace = quasi_static::run_model(&scenario.drive, &scenario.load, qs, model);
        Self::cells(&trace)
    }

    fn writes_case_files(&self) -> bool {
        true
    }

    /// With a folder, every model of the scenario runs (as `run` does) and their traces go
    /// to `timeseries.csv` and `profiles.csv`; the row keeps the first model's figures.
    fn run_case(
        &self,
        scenario: &Scenario,
        case: &Case,
        dir: Option<&Path>,
    ) -> std::io::Result<Vec<Cell>> {
        let (Some(dir), Some(qs)) = (dir, &scenario.quasi_static) else {
            return Ok(self.run(scenario, case));
        };
        let traces: Vec<_> = qs
            .models
            .iter()
            .map(|&m| quasi_static::run_model(&scenario.drive, &scenario.load, qs, m))
            .collect();
        report::quasi_static::write_tables(dir, &traces)
            .map_err(|e| std::io::Error::other(e.to_string()))?;
        Ok(traces.first().map(Self::cells).unwrap_or_default())
    }
}

impl QuasiStaticRunner {
    fn cells(trace: &quasi_static::QsTrace) -> Vec<Cell> {
        let f = trace.figures();
        // A case that stopped (or holds no sample) has no figures: its partial ones would
        // read as results.
        let finished = trace.stop.is_none() && !trace.samples.is_empty();
        let some = |v: f64| finished.then_some(v);
        let (status, stop) = match &trace.stop {
            None if trace.samples.is_empty() => ("stopped".to_string(), "no samples".to_string()),
            None => ("ok".to_string(), String::new()),
            Some(st) => (
                crate::closed_loop::StopKind::of(&st.fault)
                    .name()
                    .to_string(),
                format!("t = {:.4} s: {}", st.t_s, st.fault),
            ),
        };
        vec![
            Cell::Num(some(f.peak_error_mrad)),
            Cell::Num(some(f.peak_to_peak_error_mrad)),
            Cell::Num(some(f.rms_error_mrad)),
            Cell::Num(some(f.largest_jump_mrad)),
            Cell::Num(some(f.tension_min_n)),
            Cell::Num(some(f.tension_max_n)),
            Cell::Text(status),
            Cell::Text(stop),
        ]
    }
}

/// Figures of one closed-loop case: per compensation mode, the pointing metrics.
pub struct ClosedLoopRunner {
    modes: Vec<closed_loop::CompensationMode>,
    // The cases vary the plant, not the reference: it is sampled once for all of them.
    reference: closed_loop::ReferenceCache,
}

impl ClosedLoopRunner {
    /// Columns for the modes the scenario lists.
    pub fn for_scenario(scenario: &Scenario) -> Self {
        ClosedLoopRunner {
            modes: scenario
                .closed_loop
                .as_ref()
                .map(|c| c.modes.clone())
                .unwrap_or_default(),
            reference: closed_loop::ReferenceCache::new(),
        }
    }

    const FIGURES: [&'static str; 7] = sweep_columns::CLOSED_LOOP_MODE;

    /// The case's verdict: every requirement, the judged mode's pointing included.
    const VERDICT: [&'static str; 6] = sweep_columns::CLOSED_LOOP_VERDICT;

    /// A mode's cells (one per [`Self::FIGURES`]) when it has no result: no figures, not
    /// passing, status `error` and `reason`.
    fn mode_error(reason: String) -> [Cell; 7] {
        [
            Cell::Num(None),
            Cell::Num(None),
            Cell::Num(None),
            Cell::Num(None),
            Cell::Text("false".into()),
            Cell::Text("error".into()),
            Cell::Text(reason),
        ]
    }
}

impl CaseRunner for ClosedLoopRunner {
    fn columns(&self) -> Vec<String> {
        let mut columns: Vec<String> = self
            .modes
            .iter()
            .flat_map(|m| {
                Self::FIGURES
                    .iter()
                    .map(move |f| format!("{}_{f}", m.name()))
            })
            .collect();
        columns.extend(Self::VERDICT.iter().map(|c| c.to_string()));
        columns
    }

    fn run(&self, scenario: &Scenario, _case: &Case) -> Vec<Cell> {
        let result = match closed_loop::run_closed_loop_metrics_shared(scenario, &self.reference) {
            Ok(r) => r,
            // Could not run at all: every mode is an error, apart from a physical stop.
            Err(e) => {
                let mut cells: Vec<Cell> = self
                    .modes
                    .iter()
                    .flat_map(|_| Self::mode_error(e.to_string()))
                    .collect();
                cells.push(Cell::Text("false".into()));
                cells.extend((0..4).map(|_| Cell::Num(None)));
                cells.push(Cell::Text(format!("cannot run: {e}")));
                return cells;
            }
        };
        let mut cells = Vec::new();
        for mode in &self.modes {
            match result.modes.iter().find(|r| r.mode == *mode) {
                Some(r) => {
                    // A stopped mode has no metrics: what it ran is not the design's answer.
                    let done = matches!(r.completion, closed_loop::Completion::Complete)
                        && r.metrics.samples > 0;
                    let m = &r.metrics;
                    let some = |v: f64| done.then_some(v);
                    let stop = match &r.completion {
                        closed_loop::Completion::Complete if r.metrics.samples == 0 => {
                            "no samples in the metrics window".to_string()
                        }
                        closed_loop::Completion::Complete => String::new(),
                        closed_loop::Completion::Incomplete { fault, .. } => fault.clone(),
                    };
                    let status = match &r.completion {
                        closed_loop::Completion::Complete if r.metrics.samples == 0 => "stopped",
                        c => c.status(),
                    };
                    cells.extend([
                        Cell::Num(some(m.rms_mrad)),
                        Cell::Num(some(m.peak_mrad)),
                        Cell::Num(some(m.p95_mrad)),
                        Cell::Num(some(m.within_target_fraction)),
                        Cell::Text((m.passes_target && done).to_string()),
                        Cell::Text(status.into()),
                        Cell::Text(stop),
                    ]);
                }
                None => cells.extend(Self::mode_error(format!(
                    "mode {} was not simulated",
                    mode.name()
                ))),
            }
        }
        let verdict = closed_loop::ClosedLoopSource::closed_loop_setup(scenario)
            .ok()
            .and_then(|setup| {
                let judged = crate::analysis::verdict::judged_result(setup.params, &result.modes)?;
                Some(crate::analysis::verdict::judge(&setup, judged))
            });
        match verdict {
            Some(v) => cells.extend([
                Cell::Text(v.passes.to_string()),
                Cell::Num(v.worst_value("phase_margin")),
                Cell::Num(v.worst_value("gain_margin_up")),
                Cell::Num(v.worst_value("gain_margin_down")),
                Cell::Num(v.worst_value("sensitivity_peak")),
                Cell::Text(v.reasons().join("; ")),
            ]),
            None => {
                cells.push(Cell::Text("false".into()));
                cells.extend((0..4).map(|_| Cell::Num(None)));
                cells.push(Cell::Text("the judged mode was not simulated".into()));
            }
        }
        cells
    }
}

/// How to run a sweep.
#[derive(Debug, Clone)]
pub struct SweepOptions {
    /// Output directory options.
    pub output: OutputOptions,
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Part of the sweep to run.
    pub shard: Shard,
    /// Also write each case's time series to `cases/case-NNNNNN/` (quasi-static studies).
    pub case_timeseries: bool,
}

/// The case runner for a scenario's study.
pub fn runner_for(scenario: &Scenario) -> Result<Box<dyn CaseRunner>, RunError> {
    match scenario.study {
        Study::Backlash => Ok(Box::new(BacklashRunner)),
        Study::QuasiStatic => Ok(Box::new(QuasiStaticRunner)),
        Study::ClosedLoop => Ok(Box::new(ClosedLoopRunner::for_scenario(scenario))),
    }
}

/// Longest a sweep (or one shard of it) may plan to compute, s of wall time (7 days).
pub const MAX_SWEEP_WALL_S: f64 = 7.0 * 86400.0;

/// Worker threads a sweep uses for `threads` (0 = all cores).
fn threads_used(threads: usize) -> usize {
    if threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        threads
    }
}

/// Estimated work of a closed-loop run of `scenario` as `run` makes it (every mode, the
/// time series at its rate); `None` for the other studies, which take milliseconds.
pub fn work_estimate(scenario: &Scenario) -> Option<closed_loop::WorkEstimate> {
    let p = scenario.closed_loop.as_ref()?;
    Some(closed_loop::estimate_work(p, p.modes.len(), &recording(p)))
}

/// The options of a run that records its time series at the scenario's rate.
fn recording(p: &closed_loop::ClosedLoopParams) -> closed_loop::RunOptions {
    closed_loop::RunOptions {
        decimation: p.timeseries_decimation(),
        ..closed_loop::RunOptions::default()
    }
}

/// Estimated `(wall time, one case on one core)` of `cases` closed-loop sweep cases like
/// the scenario's own (metrics only) on `threads` workers, s; `None` for the other studies.
pub fn sweep_wall_estimate(
    scenario: &Scenario,
    cases: usize,
    threads: usize,
) -> Option<(f64, f64)> {
    let p = scenario.closed_loop.as_ref()?;
    let per_case =
        closed_loop::estimate_work(p, p.modes.len(), &closed_loop::RunOptions::metrics_only())
            .compute_s;
    let lanes = threads_used(threads).min(cases.max(1)) as f64;
    Some((per_case * cases as f64 / lanes, per_case))
}

/// Run the sweep declared in `scenario` (with `base` its resolved table), streaming
/// A case the scenario refuses before the sweep starts, named by its values and where
/// they come from (a mistyped `--vary` key is the usual cause).
fn case_input_error(case: &Case, e: ScenarioError) -> RunError {
    match e {
        ScenarioError::Invalid { key, message, .. } => RunError::Scenario(ScenarioError::Invalid {
            source_name: format!(
                "sweep case {} ({}; set by --vary or [[sweep.parameters]])",
                case.index,
                case::case_values(case)
            ),
            key,
            message,
        }),
        other => SweepError::Case {
            index: case.index,
            source: Box::new(other),
        }
        .into(),
    }
}

/// `sweep.csv`; `progress` is called after every case.
pub fn run_sweep(
    scenario: &Scenario,
    options: &SweepOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<RunReport, RunError> {
    let spec = scenario.sweep.as_ref().ok_or_else(|| {
        RunError::Unsupported(format!(
            "scenario {} declares no [sweep]; add [[sweep.parameters]] or pass --vary",
            scenario.name()
        ))
    })?;
    let base = scenario.to_table();
    let cases = engine::expand(spec, &base).map_err(|(key, message)| {
        RunError::Scenario(ScenarioError::Invalid {
            source_name: scenario.name().to_string(),
            key,
            message,
        })
    })?;
    let runner = runner_for(scenario)?;
    // Validate every case before anything is written: bad input leaves no results.
    for case in cases.iter().filter(|c| options.shard.owns(c.index)) {
        case_scenario(&base, case, scenario.name()).map_err(|e| case_input_error(case, e))?;
    }
    let owned_cases = cases.iter().filter(|c| options.shard.owns(c.index)).count();
    if let Some((wall_s, per_case_s)) = sweep_wall_estimate(scenario, owned_cases, options.threads)
    {
        if wall_s > MAX_SWEEP_WALL_S {
            return Err(RunError::Unsupported(format!(
                "the sweep would compute for about {} ({owned_cases} cases of this shard, each about {} on one core), more than the {} a sweep (or one shard of it) may take: run it in shards across machines (--shard i/n), draw fewer cases, or shorten closed_loop.duration_s",
                crate::duration_words(wall_s),
                crate::duration_words(per_case_s),
                crate::duration_words(MAX_SWEEP_WALL_S)
            )));
        }
    }
    let mut warnings = scenario.warnings();
    if options.case_timeseries && !runner.writes_case_files() {
        warnings.push(format!(
            "--case-timeseries: {} cases have no time series; only sweep.csv is written",
            serde_json::to_value(scenario.study)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default()
        ));
    }
    let staged = StagedDir::create(&options.output.dir, options.output.force)?;
    let dir = staged.path().to_path_buf();
    let parameter_columns: Vec<String> = spec
        .parameters
        .iter()
        .map(|p| p.column_name().to_string())
        .collect();
    let figure_columns = runner.columns();
    let mut table = report::sweep::SweepTable::create(
        &dir.join("sweep.csv"),
        &parameter_columns,
        &figure_columns,
    )?;
    let plan = engine::Plan {
        cases: &cases,
        shard: options.shard,
        threads: options.threads,
        stop: Some(&|| crate::io::signals::interrupted().is_some()),
    };
    let case_files = options.case_timeseries.then_some(dir.as_path());
    let outcome = engine::run_cases(
        &plan,
        runner.columns().len(),
        &|case| run_one_case(&base, scenario.name(), case, runner.as_ref(), case_files),
        &mut |case, cells| table.push(case, cells),
        progress,
    );
    table.finish()?;
    let owned = cases.iter().filter(|c| options.shard.owns(c.index)).count();
    let signal = crate::io::signals::interrupted();
    let failure = match (&outcome, signal) {
        (Err(e), _) => Some(e.to_string()),
        (Ok(done), Some(sig)) => Some(format!(
            "interrupted by {} (exit {}): the sweep stopped taking cases; kept: sweep.csv with the {} finished cases of {} (cases in flight were finished), lost: {} cases not run; rerun the sweep, or its shard, for a complete table",
            crate::io::signals::name(sig),
            crate::io::signals::exit_code(sig),
            done.written,
            owned,
            owned - done.written.min(owned)
        )),
        (Ok(_), None) => None,
    };
    let sampled = spec.mode.is_sampled();
    let answers = if sampled {
        report::sweep::statistics(&figure_columns, &table.rows)
    } else {
        design_answers(scenario, &parameter_columns, &figure_columns, &table.rows)
    };
    let outcomes = report::sweep::outcomes(&parameter_columns, &figure_columns, &table.rows);
    report::write_summary(
        &dir.join("summary.json"),
        scenario,
        failure.is_none(),
        &serde_json::json!({
            "cases_total": cases.len(),
            "cases_written": table.rows.len(),
            "outcomes": outcomes.0,
            "interrupted_by": signal.map(crate::io::signals::name),
            "shard": crate::io::manifest::ShardManifest::new(&cases, options.shard.k, options.shard.n),
            "mode": spec.mode.as_str(),
            "seed": sampled.then(|| spec.seed.unwrap_or(0)),
            "design_answers": if sampled { serde_json::Value::Null } else { answers.0.clone() },
            "statistics": if sampled { answers.0.clone() } else { serde_json::Value::Null },
        }),
    )?;
    // The scenario's own pointing target; a study without a loop is drawn against the
    // tool's 0.1 mrad.
    let target = Some(scenario.closed_loop.as_ref().map_or(0.1, |c| c.target_mrad));
    let drawn = if sampled {
        report::sweep::plot_samples(
            &dir,
            &parameter_columns,
            &figure_columns,
            &table.rows,
            target,
            3,
        )
    } else {
        report::sweep::plot(
            &dir,
            &parameter_columns,
            &figure_columns,
            &table.rows,
            target,
            3,
        )
    };
    plots(drawn, &mut warnings);
    let mut text = format!(
        "{} cases written to sweep.csv ({} in the sweep)\n",
        table.rows.len(),
        cases.len()
    );
    text.push_str(&outcomes.1);
    text.push_str(&answers.1);
    let verdicts = figure_columns.iter().position(|c| c == "passes").map(|j| {
        let passing = table
            .rows
            .iter()
            .filter(|(_, cells)| matches!(cells.get(j), Some(Cell::Text(t)) if t == "true"))
            .count();
        (passing, table.rows.len())
    });
    if let Some((passing, total)) = verdicts {
        text.push_str(&if passing == total {
            format!("verdict: every case meets every requirement ({total} of {total})\n")
        } else {
            format!(
                "verdict: {} of {total} cases miss a requirement (sweep.csv column `failing` says which; a stopped case counts as missing)\n",
                total - passing
            )
        });
    }
    let mut report = finish(staged, text, failure, warnings)?;
    report.signal = signal;
    report.requirements_met = verdicts.map(|(passing, total)| passing == total);
    Ok(report)
}

/// Answers a designer reads off a sweep: for backlash sweeps over preload and load, the
/// preload above which backlash flattens, and the least preload free of slack and gross
/// slip (by bisection, independent of the swept preloads), per load. Returns JSON and a printable text.
fn design_answers(
    scenario: &Scenario,
    parameter_columns: &[String],
    figure_columns: &[String],
    rows: &[(Case, Vec<Cell>)],
) -> (serde_json::Value, String) {
    let ip = parameter_columns.iter().position(|c| c == "preload_n");
    let il = parameter_columns.iter().position(|c| c == "load_nm");
    let ir = figure_columns.iter().position(|c| c == "reversal_mrad");
    let (Study::Backlash, Some(ip), Some(il), Some(ir)) = (scenario.study, ip, il, ir) else {
        return (serde_json::Value::Null, String::new());
    };
    const TOLERANCE: f64 = 0.2;
    let num = |v: &toml::Value| report::sweep::numeric(v);
    let mut loads: Vec<f64> = rows
        .iter()
        .filter_map(|r| num(&r.0.assignments[il].2))
        .collect();
    loads.sort_by(f64::total_cmp);
    loads.dedup();
    let mut json_rows = Vec::new();
    let mut text = format!(
        "Preload above which backlash flattens (reversal backlash within {:.0} % of its\ninfinite-preload limit Lf*M/(ro^2*G), the free-span stretch alone), and least preload\nwith no slack span and no gross slip:\n",
        TOLERANCE * 100.0
    );
    for load in loads {
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| num(&r.0.assignments[il].2) == Some(load))
            .filter_map(|r| {
                let p = num(&r.0.assignments[ip].2)?;
                match r.1.get(ir) {
                    Some(Cell::Num(Some(b))) => Some((p, *b)),
                    _ => None,
                }
            })
            .collect();
        let limit = report::quasi_static::free_span_backlash_mrad(&scenario.drive, load);
        let threshold = crate::study::answers::flattening_preload(&pts, limit, TOLERANCE);
        let model = scenario
            .backlash
            .as_ref()
            .map(|b| b.model)
            .unwrap_or_default();
        let least = crate::study::answers::least_preload_at_load(
            &scenario.drive,
            load,
            model,
            (0.01, 1e5),
            0.01,
        );
        text.push_str(&format!(
            "  load {load:>6.3} N m: limit {limit:.4} mrad, threshold {}, least preload {}\n",
            threshold.map_or("above the swept range".to_string(), |p| format!("{p:.1} N")),
            least
                .preload_n
                .map_or("none up to 1e5 N".to_string(), |p| format!("{p:.2} N"))
        ));
        json_rows.push(serde_json::json!({
            "load_nm": load,
            "infinite_preload_backlash_mrad": limit,
            "flattening_preload_n": threshold,
            "least_preload_n": least.preload_n,
        }));
    }
    (
        serde_json::json!({
            "flattening_preload": {
                "definition": "smallest preload at which reversal backlash is within tolerance of its infinite-preload limit Lf*M/(ro^2*G) (free-span stretch only); linear interpolation between swept preloads",
                "tolerance": TOLERANCE,
                "per_load": json_rows,
            },
            "least_preload": {
                "definition": crate::study::answers::LEAST_PRELOAD_DEFINITION,
                "tolerance_n": 0.01,
                "search_range_n": [0.01, 1e5],
            },
        }),
        text,
    )
}

/// Diagnose bench logs (read from `paths`) against `scenario` and write the report into a
/// staged results directory; optionally also the JSON elsewhere and the extended model as
/// a scenario file. Bad logs leave nothing behind.
pub fn run_diagnosis(
    scenario: &Scenario,
    paths: &[PathBuf],
    options: &crate::identify::DiagnoseOptions,
    out: &OutputOptions,
    json: Option<&Path>,
    save_model: Option<&Path>,
) -> Result<RunReport, RunError> {
    run_diagnosis_with_progress(
        scenario,
        paths,
        options,
        out,
        json,
        save_model,
        &crate::progress::Silent,
    )
}

/// [`run_diagnosis`], reporting each candidate effect judged to `progress`
/// ([`crate::identify::diagnose_with_progress`]).
pub fn run_diagnosis_with_progress(
    scenario: &Scenario,
    paths: &[PathBuf],
    options: &crate::identify::DiagnoseOptions,
    out: &OutputOptions,
    json: Option<&Path>,
    save_model: Option<&Path>,
    progress: &dyn crate::progress::Progress,
) -> Result<RunReport, RunError> {
    use crate::io::staging::{check_file_target, FileKind};
    // Checked before the work: an output that cannot be written costs no diagnosis.
    if let Some(path) = json {
        check_file_target(path, out.force, FileKind::DiagnosisJson).map_err(OutputError::from)?;
    }
    if let Some(path) = save_model {
        check_file_target(path, out.force, FileKind::SavedModel).map_err(OutputError::from)?;
    }
    let logs: Vec<crate::measurement::BenchLog> = paths
        .iter()
        .map(|p| crate::io::benchlog::read_drive_log(p))
        .collect::<Result<_, _>>()?;
    let diagnosis = crate::identify::diagnose_with_progress(scenario, &logs, options, progress)?;
    let staged = StagedDir::create(&out.dir, out.force)?;
    report::diagnosis::write_diagnosis(staged.path(), scenario, &diagnosis, None)?;
    if let Some(path) = json {
        let text = std::fs::read(staged.path().join("diagnosis.json"))
            .map_err(|e| ReportError::io(path, e))?;
        crate::io::output::write_atomic(path, &text)?;
    }
    if let Some(path) = save_model {
        report::diagnosis::save_model(path, scenario, &diagnosis)?;
    }
    let mut table = report::diagnosis::summary_text(&diagnosis);
    table.push_str(&saved_model_line(save_model));
    finish(staged, table, None, Vec::new())
}

/// Joint calibration over several logs and leave-one-log-out validation of the extension
/// `effects` (empty: the scenario's `[identify] candidates`, every effect when that list
/// is empty), written as
/// `leave_one_out.json` and `leave_one_out.txt` into a staged results directory.
pub fn run_leave_one_out(
    scenario: &Scenario,
    paths: &[PathBuf],
    effects: &[crate::identify::EffectName],
    start: crate::identify::startup::StartMode,
    out: &OutputOptions,
    json: Option<&Path>,
    save_model: Option<&Path>,
) -> Result<RunReport, RunError> {
    run_leave_one_out_with_progress(
        scenario,
        paths,
        effects,
        start,
        false,
        out,
        json,
        save_model,
        &crate::progress::Silent,
    )
}

/// [`run_leave_one_out`], reporting each log held out to `progress`
/// ([`crate::identify::loo::leave_one_out_with_segments`]); `keep_segments` fits and scores
/// the stretches flagged as not the drive instead of excluding them.
#[allow(clippy::too_many_arguments)]
pub fn run_leave_one_out_with_progress(
    scenario: &Scenario,
    paths: &[PathBuf],
    effects: &[crate::identify::EffectName],
    start: crate::identify::startup::StartMode,
    keep_segments: bool,
    out: &OutputOptions,
    json: Option<&Path>,
    save_model: Option<&Path>,
    progress: &dyn crate::progress::Progress,
) -> Result<RunReport, RunError> {
    let ident = scenario.identify.clone().unwrap_or_default();
    let effects: Vec<crate::identify::EffectName> = if effects.is_empty() {
        // As the single diagnosis's search: a free ratio and an output scale error are the
        // same column.
        ident
            .searched()
            .into_iter()
            .filter(|e| {
                !(ident.is_unknown("ratio") && *e == crate::identify::EffectName::EncoderScaleError)
            })
            .collect()
    } else {
        effects.to_vec()
    };
    let logs: Vec<crate::identify::BenchLog> = paths
        .iter()
        .map(|p| crate::io::benchlog::read_drive_log(p))
        .collect::<Result<_, _>>()?;
    let table = crate::identify::loo::leave_one_out_with_segments(
        &scenario.drive,
        &ident,
        &logs,
        &effects,
        start,
        keep_segments,
        progress,
    )?;
    let mut text = crate::identify::loo::loo_text(&table);
    let staged = StagedDir::create(&out.dir, out.force)?;
    let body = serde_json::to_vec_pretty(&report::with_provenance(
        scenario,
        true,
        &serde_json::json!({
            "logs": paths.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "leave_one_out": table,
        }),
    ))
    .map_err(|e| ReportError::io(&out.dir, std::io::Error::other(e)))?;
    crate::io::output::write_atomic(&staged.path().join("leave_one_out.json"), &body)?;
    crate::io::output::write_atomic(&staged.path().join("leave_one_out.txt"), text.as_bytes())?;
    if let Some(path) = json {
        crate::io::output::write_atomic(path, &body)?;
    }
    if let Some(path) = save_model {
        let mut s = scenario.clone();
        s.drive = table.drive.clone();
        s.effects = Some(table.effects_params.clone());
        crate::report::diagnosis::calibrated_identity(
            &mut s,
            &format!(
                "calibrated jointly on {} logs ({}); leave-one-log-out: extended beats base on {}/{}",
                table.rows.len(),
                paths
                    .iter()
                    .filter_map(|p| p.file_name())
                    .map(|n| n.to_string_lossy().into_owned())
                    .collect::<Vec<_>>()
                    .join(", "),
                table.wins_over_base,
                table.rows.len()
            ),
        );
        let model =
            toml::to_string(&s).map_err(|e| ReportError::io(path, std::io::Error::other(e)))?;
        let header = format!(
            "# Calibrated jointly on {} logs; leave-one-log-out: extended beats base on {}/{}, the per-log play operator on {}/{}\n",
            table.rows.len(),
            table.wins_over_base,
            table.rows.len(),
            table.wins_over_play,
            table.rows.len()
        );
        crate::io::output::write_atomic(path, (header + &model).as_bytes())?;
    }
    text.push_str(&saved_model_line(save_model));
    finish(staged, text, None, Vec::new())
}

/// The console's line for a model saved with `--save-model` (empty without one).
fn saved_model_line(save_model: Option<&Path>) -> String {
    save_model.map_or_else(String::new, |path| {
        format!(
            "model: {} (a complete scenario: `cable-servo run {}` runs it)\n",
            path.display(),
            path.display()
        )
    })
}

/// What `freqresp` measured and where it went.
#[derive(Debug)]
pub struct FreqRespReport {
    /// Results directory.
    pub dir: PathBuf,
    /// Console table.
    pub table: String,
    /// Whether every amplitude met the requirements with every frequency measured.
    pub passes: bool,
    /// The design's verdict, judged as every command judges it.
    pub verdict: crate::analysis::verdict::Verdict,
    /// Whether every frequency of every amplitude was measured: no run stopped (points the
    /// measurement could not resolve are named, not counted here).
    pub complete: bool,
    /// Points left out as unresolved (no response or too noisy at their amplitude).
    pub unresolved: usize,
    /// Plots that could not be drawn.
    pub warnings: Vec<String>,
    /// Simulation runs and simulated seconds.
    pub runs: (usize, f64),
}

/// Measure the frequency response of a closed-loop scenario (`spec` already merged from
/// the scenario and the command line), write its files, then its plots.
pub fn run_freqresp(
    scenario: &Scenario,
    spec: &crate::analysis::freqresp::FreqRespParams,
    threads: usize,
    out: &OutputOptions,
    progress: &(dyn Fn() + Sync),
) -> Result<FreqRespReport, RunError> {
    let p = scenario.closed_loop.as_ref().ok_or_else(|| {
        RunError::Unsupported(format!(
            "{} is not a closed-loop scenario (study = \"closed_loop\"): a frequency response needs a loop",
            scenario.name()
        ))
    })?;
    // Bad settings stop here, before a results directory exists.
    spec.validate(p)?;
    let setup = closed_loop::ClosedLoopSource::closed_loop_setup(scenario)?;
    // A slew the plant cannot take is refused here too, before a results directory exists.
    crate::analysis::freqresp::operating_plan(
        &setup,
        spec,
        &crate::analysis::linear::LinearLoop::new(p, &scenario.drive),
    )?;
    // The design's verdict (which simulates the judged mode), as every command gives it.
    let verdict = crate::analysis::verdict::evaluate(&setup)?;
    let staged = StagedDir::create(&out.dir, out.force)?;
    let dir = staged.path().to_path_buf();
    let r = crate::analysis::freqresp::measure(setup, spec, threads, progress)?;
    report::freqresp::write_outputs(&dir, scenario, &r, &verdict)?;
    let mut warnings = scenario.warnings();
    let lin = crate::analysis::linear::LinearLoop::new(p, &scenario.drive);
    plots(
        report::freqresp::plot(&dir, &r, &lin, p.requirements.max_ms),
        &mut warnings,
    );
    let complete = r.complete();
    let stopped = "a measurement run stopped (each is listed in freqresp.csv with its reason)";
    html_report(&dir, &mut warnings, (!complete).then_some(stopped));
    let dir = if complete {
        staged.commit()?
    } else {
        staged.commit_incomplete(stopped)?
    };
    Ok(FreqRespReport {
        dir,
        table: report::freqresp::format_table(&r),
        // No verdict (base motion without a declared rejection) is no failure.
        passes: r.verdict().unwrap_or(true),
        verdict,
        complete,
        unresolved: r
            .amplitudes
            .iter()
            .map(|a| a.points.iter().filter(|p| p.unresolved()).count())
            .sum(),
        warnings,
        runs: (r.runs, r.simulated_s),
    })
}

/// What `margins` computed and where it went.
#[derive(Debug)]
pub struct MarginsReport {
    /// Results directory.
    pub dir: PathBuf,
    /// The design's verdict (its crossings and requirements), judged at the scenario's
    /// declared operating load whatever load was explored.
    pub verdict: crate::analysis::verdict::Verdict,
    /// With an explored load: the crossings at the free span and at that load's tangent,
    /// and why there is no tangent when the cable cannot carry the load.
    pub explored: Option<(
        Vec<crate::analysis::verdict::OperatingPoint>,
        Option<String>,
    )>,
    /// The operating load the verdict holds its margins at, N m (declared, or the load's
    /// peak torque).
    pub judged_load_nm: f64,
    /// Non-fatal problems (a plot that could not be drawn).
    pub warnings: Vec<String>,
}

/// `margins`: the exact linear reference over the operating range, the verdict, and
/// their files (`margins.json`, `linear_model.json`, `summary.json`, figures).
///
/// `explore_load_nm` (N m, > 0) puts the tangent stiffness of that transmitted torque in
/// the files, figures and [`MarginsReport::explored`] in place of the declared operating
/// load's. It is a look at another load, not another requirement: the verdict, its exit
/// code and `summary.json`'s verdict stay those of the design as declared, as every other
/// command judges it.
pub fn run_margins(
    scenario: &Scenario,
    explore_load_nm: Option<f64>,
    out: &OutputOptions,
) -> Result<MarginsReport, RunError> {
    let p = scenario.closed_loop.as_ref().ok_or_else(|| {
        RunError::Unsupported(format!(
            "{} is not a closed-loop scenario (study = \"closed_loop\"): margins need a loop",
            scenario.name()
        ))
    })?;
    check_load_nm(explore_load_nm)?;
    let setup = closed_loop::ClosedLoopSource::closed_loop_setup(scenario)?;
    // The verdict (which simulates the judged mode) before a results directory exists.
    let verdict = crate::analysis::verdict::evaluate(&setup)?;
    let explored_scenario = explore_load_nm.map(|load| {
        let mut explored = scenario.clone();
        if let Some(c) = explored.closed_loop.as_mut() {
            c.requirements.operating_load_nm = Some(load);
        }
        explored
    });
    let shown = explored_scenario.as_ref().unwrap_or(scenario);
    let shown_setup = closed_loop::ClosedLoopSource::closed_loop_setup(shown)?;
    let shown_p = shown.closed_loop.as_ref().unwrap_or(p);
    let models = crate::analysis::linear_model::loop_models(&shown_setup);
    // The explored range is read off the models just computed, not computed again.
    let explored = explore_load_nm.is_some().then(|| {
        let points = models
            .points
            .iter()
            .map(|m| crate::analysis::verdict::OperatingPoint {
                condition: m.condition.clone(),
                load_nm: m.load_nm,
                half_stiffness_n_per_m: m.half_stiffness_n_per_m,
                margins: m.margins.clone(),
            })
            .collect();
        (points, models.problem.clone())
    });
    let staged = StagedDir::create(&out.dir, out.force)?;
    let dir = staged.path().to_path_buf();
    report::margins::write_outputs(&dir, scenario, shown_p, &models, &verdict, explore_load_nm)?;
    let mut warnings = scenario.warnings();
    plots(
        report::margins::plot(&dir, shown, shown_p, &models),
        &mut warnings,
    );
    html_report(&dir, &mut warnings, None);
    let dir = staged.commit()?;
    Ok(MarginsReport {
        dir,
        verdict,
        explored,
        judged_load_nm: crate::analysis::verdict::operating_load_nm(&setup),
        warnings,
    })
}

/// A design of a comparison: a resolved closed-loop scenario under a name.
#[derive(Debug, Clone)]
pub struct CompareDesign {
    /// Name in tables, files and legends (a file name: letters, digits, `-`, `_`, `.`).
    pub name: String,
    /// Where it came from (scenario file, or the overrides applied to the base).
    pub description: String,
    /// The scenario, tables loaded.
    pub scenario: Scenario,
}

/// What a comparison produced.
#[derive(Debug, Clone)]
pub struct CompareReport {
    /// The run's files, its table and whether it completed.
    pub run: RunReport,
    /// Designs that ran to the end and met their pointing target.
    pub passing: usize,
    /// Designs compared.
    pub designs: usize,
}

/// Run every design (one compensation mode each: `mode`, or the last mode its scenario
/// lists) side by side on the cores, then write the table, each design's files and the
/// overlay figures.
pub fn run_compare(
    designs: &[CompareDesign],
    mode: Option<closed_loop::CompensationMode>,
    out: &OutputOptions,
) -> Result<CompareReport, RunError> {
    use rayon::prelude::*;
    if designs.is_empty() {
        return Err(RunError::Unsupported(
            "compare needs at least one design: scenario files, or one scenario with --design NAME:KEY=VALUE;...".into(),
        ));
    }
    for (i, d) in designs.iter().enumerate() {
        if designs[..i].iter().any(|e| e.name == d.name) {
            return Err(RunError::Unsupported(format!(
                "two designs are named {:?}: give each its own name",
                d.name
            )));
        }
        let Some(p) = d.scenario.closed_loop.as_ref() else {
            return Err(RunError::Unsupported(format!(
                "design {:?}: compare needs closed-loop scenarios (study = \"closed_loop\")",
                d.name
            )));
        };
        if let Some(m) = mode {
            // A declared judged mode is the design's requirement: judging another would
            // give this design a verdict no other command gives it.
            if let Some(declared) = p.requirements.mode.filter(|&d| d != m) {
                return Err(RunError::Unsupported(format!(
                    "design {:?} declares closed_loop.requirements.mode = {:?}: --mode {} would judge it by another requirement; drop --mode, or declare the mode to judge",
                    d.name,
                    declared.name(),
                    m.name()
                )));
            }
            if !p.modes.contains(&m) {
                return Err(RunError::Unsupported(format!(
                    "design {:?} does not list mode {:?} in closed_loop.modes",
                    d.name,
                    m.name()
                )));
            }
        }
    }
    let mut warnings = Vec::new();
    let staged = StagedDir::create(&out.dir, out.force)?;
    let dir = staged.path().to_path_buf();
    let outcomes = designs
        .par_iter()
        .map(|d| -> Result<report::compare::DesignOutcome, RunError> {
            // `--mode` asks for the designs to be judged in that mode: the same as
            // `--set closed_loop.requirements.mode=...`, so every command agrees.
            let mut scenario = d.scenario.clone();
            let p = scenario.closed_loop.as_mut().ok_or_else(|| {
                RunError::Unsupported(format!("design {:?} is not a closed-loop study", d.name))
            })?;
            if mode.is_some() {
                p.requirements.mode = mode;
            }
            let p = p.clone();
            let m = p.judged_mode();
            let options = closed_loop::RunOptions {
                modes: Some(vec![m]),
                ..recording(&p)
            };
            let mut r = closed_loop::run_closed_loop(&scenario, &options)?;
            let result = r.modes.remove(0);
            let setup = closed_loop::ClosedLoopSource::closed_loop_setup(&scenario)?;
            let verdict = crate::analysis::verdict::judge(&setup, &result);
            Ok(report::compare::DesignOutcome {
                name: d.name.clone(),
                description: d.description.clone(),
                scenario: scenario.clone(),
                mode: m,
                result,
                verdict,
                target_mrad: p.target_mrad,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    report::compare::write_compare(&dir, &outcomes)?;
    if let Err(e) = report::compare::plot_compare(&dir, &outcomes) {
        warnings.push(format!("plots incomplete: {e}"));
    }
    let passing = outcomes.iter().filter(|d| d.passes()).count();
    // A design that stops has its verdict (named in its row, counted as missing the
    // target); the comparison itself is complete.
    for d in &outcomes {
        if let closed_loop::Completion::Incomplete { fault, time_s, .. } = &d.result.completion {
            warnings.push(format!(
                "design {} stopped at t = {} s: {fault}",
                d.name,
                crate::readable(*time_s)
            ));
        }
    }
    let table = report::compare::format_compare(&outcomes);
    let mut run = finish(staged, table, None, warnings)?;
    run.requirements_met = Some(passing == outcomes.len());
    Ok(CompareReport {
        run,
        passing,
        designs: outcomes.len(),
    })
}
