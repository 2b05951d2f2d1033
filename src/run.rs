//! Running a scenario end to end: compute, write CSV and JSON, then plots, into a staged
//! results directory that appears only when complete (or marked incomplete).

use std::path::{Path, PathBuf};

use crate::io::output::{OutputError, StagedDir};
use crate::report::{self, ReportError};
use crate::scenario::{Scenario, ScenarioError, Study};
use crate::study::quasi_static::{self, BacklashResult};
use crate::sweep::engine::{self, Case, CaseRunner, Cell, Shard, SweepError};

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
}

/// Where and how to write results.
#[derive(Debug, Clone)]
pub struct OutputOptions {
    /// Final results directory.
    pub dir: PathBuf,
    /// Replace an existing directory.
    pub force: bool,
}

/// Run a single scenario (quasi-static, backlash or closed-loop study).
pub fn run_scenario(scenario: &Scenario, out: &OutputOptions) -> Result<RunReport, RunError> {
    let mut warnings = scenario.warnings();
    let staged = StagedDir::create(&out.dir, out.force)?;
    let dir = staged.path().to_path_buf();
    let (table, failure) = match scenario.study {
        Study::QuasiStatic => run_quasi_static(scenario, &dir, &mut warnings)?,
        Study::Backlash => run_backlash(scenario, &dir, &warnings)?,
        Study::ClosedLoop => {
            return Err(RunError::Unsupported(
                "closed-loop studies are not available in this build".into(),
            ))
        }
    };
    finish(staged, table, failure, warnings)
}

fn finish(
    staged: StagedDir,
    table: String,
    failure: Option<String>,
    warnings: Vec<String>,
) -> Result<RunReport, RunError> {
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
    })
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
        [
            "initial_mrad",
            "reversal_mrad",
            "first_reversal_mrad",
            "regime",
            "anchor_reached",
            "tension_upper_n",
        ]
        .map(String::from)
        .to_vec()
    }

    fn run(&self, scenario: &Scenario, _case: &Case) -> Vec<Cell> {
        let r: BacklashResult = match &scenario.backlash {
            Some(p) => quasi_static::backlash(&scenario.drive, p),
            None => return vec![Cell::Text("no_backlash_section".into())],
        };
        vec![
            Cell::Num(r.initial_mrad),
            Cell::Num(r.reversal_mrad),
            Cell::Num(r.first_reversal_mrad),
            Cell::Text(r.regime.as_str().into()),
            Cell::Text(r.anchor_reached.to_string()),
            Cell::Num(r.tension_upper_n),
        ]
    }
}

/// Figures of one quasi-static case (first model of the scenario).
pub struct QuasiStaticRunner;

impl CaseRunner for QuasiStaticRunner {
    fn columns(&self) -> Vec<String> {
        [
            "peak_error_mrad",
            "peak_to_peak_error_mrad",
            "rms_error_mrad",
            "largest_jump_mrad",
            "tension_min_n",
            "tension_max_n",
            "complete",
        ]
        .map(String::from)
        .to_vec()
    }

    fn run(&self, scenario: &Scenario, _case: &Case) -> Vec<Cell> {
        let Some(qs) = &scenario.quasi_static else {
            return Vec::new();
        };
        let model = qs.models.first().copied().unwrap_or_default();
        let trace = quasi_static::run_model(&scenario.drive, &scenario.load, qs, model);
        let f = trace.figures();
        // An empty trace has no figures (its zeros would read as results).
        let some = |v: f64| (!trace.samples.is_empty()).then_some(v);
        vec![
            Cell::Num(some(f.peak_error_mrad)),
            Cell::Num(some(f.peak_to_peak_error_mrad)),
            Cell::Num(some(f.rms_error_mrad)),
            Cell::Num(some(f.largest_jump_mrad)),
            Cell::Num(some(f.tension_min_n)),
            Cell::Num(some(f.tension_max_n)),
            Cell::Text(f.complete.to_string()),
        ]
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
}

/// The case runner for a scenario's study.
pub fn runner_for(scenario: &Scenario) -> Result<Box<dyn CaseRunner>, RunError> {
    match scenario.study {
        Study::Backlash => Ok(Box::new(BacklashRunner)),
        Study::QuasiStatic => Ok(Box::new(QuasiStaticRunner)),
        Study::ClosedLoop => Err(RunError::Unsupported(
            "closed-loop sweeps are not available in this build".into(),
        )),
    }
}

/// Run the sweep declared in `scenario` (with `base` its resolved table), streaming
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
    let cases = engine::expand(spec);
    let base = scenario.to_table();
    let runner = runner_for(scenario)?;
    // Validate every case before anything is written: bad input leaves no results.
    for case in cases.iter().filter(|c| options.shard.owns(c.index)) {
        engine::case_scenario(&base, case, scenario.name()).map_err(|e| SweepError::Case {
            index: case.index,
            source: Box::new(e),
        })?;
    }
    let warnings = scenario.warnings();
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
        base: &base,
        default_name: scenario.name(),
        cases: &cases,
        shard: options.shard,
        threads: options.threads,
    };
    let outcome = engine::run_cases(
        &plan,
        runner.as_ref(),
        &mut |case, cells| table.push(case, cells),
        progress,
    );
    table.finish()?;
    let failure = outcome.err().map(|e| e.to_string());
    let answers = design_answers(scenario, &parameter_columns, &figure_columns, &table.rows);
    let mut warnings = warnings;
    report::write_json(
        &dir.join("summary.json"),
        &serde_json::json!({
            "program": "cable-servo",
            "program_version": env!("CARGO_PKG_VERSION"),
            "scenario_name": scenario.name(),
            "study": scenario.study,
            "complete": failure.is_none(),
            "cases_total": cases.len(),
            "cases_written": table.rows.len(),
            "shard": format!("{}/{}", options.shard.k, options.shard.n),
            "design_answers": answers.0,
            "scenario": scenario,
        }),
    )?;
    plots(
        report::sweep::plot(
            &dir,
            &parameter_columns,
            &figure_columns,
            &table.rows,
            Some(0.1),
            3,
        ),
        &mut warnings,
    );
    let mut text = format!(
        "{} cases written to sweep.csv ({} in the sweep)\n",
        table.rows.len(),
        cases.len()
    );
    text.push_str(&answers.1);
    finish(staged, text, failure, warnings)
}

/// Answers a designer reads off a sweep: for backlash sweeps over preload and load, the
/// preload above which backlash flattens, per load. Returns JSON and a printable text.
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
        "Preload above which backlash flattens (reversal backlash within {:.0} % of its\ninfinite-preload limit Lf*M/(ro^2*G), the free-span stretch alone):\n",
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
        let threshold = crate::sweep::answers::flattening_preload(&pts, limit, TOLERANCE);
        text.push_str(&format!(
            "  load {load:>6.3} N m: limit {limit:.4} mrad, threshold {}\n",
            threshold.map_or("above the swept range".to_string(), |p| format!("{p:.1} N"))
        ));
        json_rows.push(serde_json::json!({
            "load_nm": load,
            "infinite_preload_backlash_mrad": limit,
            "flattening_preload_n": threshold,
        }));
    }
    (
        serde_json::json!({
            "flattening_preload": {
                "definition": "smallest preload at which reversal backlash is within tolerance of its infinite-preload limit Lf*M/(ro^2*G) (free-span stretch only); linear interpolation between swept preloads",
                "tolerance": TOLERANCE,
                "per_load": json_rows,
            }
        }),
        text,
    )
}
