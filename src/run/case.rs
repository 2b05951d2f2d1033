//! One sweep case at the top layer: the case's scenario resolved from the base table, its
//! runner, and the folder for its own files. The sweep engine only sees a closure.

use std::path::{Path, PathBuf};

use crate::scenario::{set_path, Scenario, ScenarioError};
use crate::sweep::engine::{render_value, Case, Cell, SweepError};

/// What a sweep computes per case.
pub trait CaseRunner: Sync {
    /// Names of the figures, in order (units in the names).
    fn columns(&self) -> Vec<String>;
    /// Figures of one resolved case scenario; must return one cell per column. Failures of
    /// the physics are results (a regime column), not errors.
    fn run(&self, scenario: &Scenario, case: &Case) -> Vec<Cell>;

    /// Whether [`CaseRunner::run_case`] writes anything into a case folder (per-case time
    /// series); when false, asking for them only earns a warning.
    fn writes_case_files(&self) -> bool {
        false
    }

    /// Figures of one case, also writing its own files (time series) into `dir` when
    /// given. Runners with per-case files override this so the case is computed once.
    fn run_case(
        &self,
        scenario: &Scenario,
        case: &Case,
        dir: Option<&Path>,
    ) -> std::io::Result<Vec<Cell>> {
        let _ = dir;
        Ok(self.run(scenario, case))
    }
}

/// Folder of one case's own files under a sweep's results directory:
/// `cases/case-000123`.
pub fn case_dir(results: &Path, index: usize) -> PathBuf {
    results.join("cases").join(format!("case-{index:06}"))
}

/// A case's values as `key=value, ...`, for messages.
pub(crate) fn case_values(case: &Case) -> String {
    case.assignments
        .iter()
        .map(|(key, _, value)| format!("{key}={}", render_value(value)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Build the scenario of one case from the base scenario table.
pub fn case_scenario(
    base: &toml::Table,
    case: &Case,
    default_name: &str,
) -> Result<Scenario, ScenarioError> {
    let mut table = base.clone();
    table.remove("sweep");
    for (key, _, value) in &case.assignments {
        let path: Vec<String> = key.split('.').map(str::to_string).collect();
        set_path(&mut table, &path, value.clone()).map_err(|message| ScenarioError::Override {
            arg: format!("{key}={}", render_value(value)),
            message,
        })?;
    }
    let source = format!("the case's values {}", case_values(case));
    match Scenario::from_table(table, &source, default_name) {
        Err(ScenarioError::Invalid { key, message, .. }) if key == "scenario" => {
            // A value of the wrong type is reported without its key: the first assignment
            // that breaks the scenario on its own names it.
            let culprit = (1..=case.assignments.len()).find(|&n| {
                let mut partial = base.clone();
                partial.remove("sweep");
                case.assignments[..n].iter().all(|(key, _, value)| {
                    let path: Vec<String> = key.split('.').map(str::to_string).collect();
                    set_path(&mut partial, &path, value.clone()).is_ok()
                }) && Scenario::from_table(partial, &source, default_name).is_err()
            });
            Err(match culprit {
                Some(n) => {
                    let (key, _, _) = &case.assignments[n - 1];
                    ScenarioError::Invalid {
                        source_name: "the case's values".into(),
                        key: key.clone(),
                        message,
                    }
                }
                None => ScenarioError::Invalid {
                    source_name: source,
                    key,
                    message,
                },
            })
        }
        other => other,
    }
}

/// Resolve, run and (when asked) write the files of one case.
pub fn run_one_case(
    base: &toml::Table,
    default_name: &str,
    case: &Case,
    runner: &dyn CaseRunner,
    case_files: Option<&Path>,
) -> Result<Vec<Cell>, SweepError> {
    let scenario = case_scenario(base, case, default_name).map_err(|e| SweepError::Case {
        index: case.index,
        source: Box::new(e),
    })?;
    let dir = match case_files {
        Some(root) if runner.writes_case_files() => {
            let dir = case_dir(root, case.index);
            std::fs::create_dir_all(&dir).map_err(|source| SweepError::CaseFiles {
                index: case.index,
                source,
            })?;
            Some(dir)
        }
        _ => None,
    };
    runner
        .run_case(&scenario, case, dir.as_deref())
        .map_err(|source| SweepError::CaseFiles {
            index: case.index,
            source,
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::engine::tests::{num, uniform};
    use crate::sweep::engine::{expand, run_cases, Plan, Shard};
    use crate::sweep::spec::{DistKind, SweepMode, SweepParameter, SweepSpec};

    /// The built-in scenario `name`.
    fn builtin(name: &str) -> Scenario {
        Scenario::load(name, &[]).unwrap_or_else(|e| panic!("{e}"))
    }

    #[test]
    fn rows_do_not_depend_on_threads_or_shards() {
        let scenario = builtin("paper_fig11");
        let base = scenario.to_table();
        let spec = SweepSpec {
            mode: SweepMode::Random,
            samples: Some(40),
            seed: Some(17),
            parameters: vec![
                uniform("drive.preload_n", 5.0, 150.0),
                SweepParameter {
                    key: "backlash.load_nm".into(),
                    dist: Some(DistKind::TruncatedNormal),
                    mean: Some(0.7),
                    std: Some(0.3),
                    min: Some(0.1),
                    max: Some(2.0),
                    ..SweepParameter::default()
                },
            ],
        };
        let cases = expand(&spec, &base).unwrap();
        let run = |threads: usize, shard: Shard| {
            let plan = Plan {
                cases: &cases,
                shard,
                threads,
                stop: None,
            };
            let mut rows = Vec::new();
            let runner = crate::run::BacklashRunner;
            run_cases(
                &plan,
                runner.columns().len(),
                &|case| run_one_case(&base, "f", case, &runner, None),
                &mut |case, cells| {
                    rows.push(crate::report::sweep::row_line(case, &cells));
                    Ok(())
                },
                &|| {},
            )
            .unwrap();
            rows
        };
        let one = run(1, Shard::ALL);
        assert_eq!(one.len(), 40);
        assert_eq!(one, run(2, Shard::ALL));
        let mut sharded: Vec<String> = (1..=3).flat_map(|k| run(2, Shard { k, n: 3 })).collect();
        sharded.sort_by_key(|r| r.split(',').next().unwrap().parse::<usize>().unwrap());
        assert_eq!(one, sharded);
        // A fresh expansion draws the same values.
        assert_eq!(cases, expand(&spec, &base).unwrap());
    }

    /// Rows and outcomes of a grid sweep over the `paper_fig11` drive.
    fn fig11_grid(preloads: &[f64], loads: &[f64]) -> (Vec<String>, Vec<(Case, Vec<Cell>)>) {
        let scenario = builtin("paper_fig11");
        let base = scenario.to_table();
        let values = |v: &[f64]| v.iter().map(|&x| toml::Value::Float(x)).collect();
        let spec = SweepSpec {
            mode: SweepMode::Grid,
            parameters: vec![
                SweepParameter::with_values("drive.preload_n", values(preloads)),
                SweepParameter::with_values("backlash.load_nm", values(loads)),
            ],
            ..SweepSpec::default()
        };
        let cases = expand(&spec, &base).unwrap();
        let plan = Plan {
            cases: &cases,
            shard: Shard::ALL,
            threads: 1,
            stop: None,
        };
        let runner = crate::run::BacklashRunner;
        let mut rows = Vec::new();
        run_cases(
            &plan,
            runner.columns().len(),
            &|case| run_one_case(&base, "f", case, &runner, None),
            &mut |case, cells| {
                rows.push((case.clone(), cells));
                Ok(())
            },
            &|| {},
        )
        .unwrap();
        (runner.columns(), rows)
    }

    #[test]
    fn a_slack_case_names_its_reason_in_the_row_and_the_outcomes() {
        // 10 N of preload cannot carry 3 N m on a 0.1025 m drum; 100 N can.
        let (columns, rows) = fig11_grid(&[10.0, 100.0], &[3.0]);
        let col = |name: &str| columns.iter().position(|c| c == name).unwrap();
        let text = |cells: &[Cell], j: usize| match &cells[j] {
            Cell::Text(t) => t.clone(),
            other => panic!("column {} holds {other:?}", columns[j]),
        };
        let (slack, held) = (&rows[0].1, &rows[1].1);
        assert_eq!(text(slack, col("status")), "slack");
        let reason = text(slack, col("stop"));
        assert!(reason.contains("goes slack"), "{reason}");
        assert!(reason.contains("raise preload_n above"), "{reason}");
        assert_eq!(slack[col("reversal_mrad")], Cell::Num(None));
        assert_eq!(text(held, col("status")), "ok");
        assert_eq!(text(held, col("stop")), "");

        let parameters = ["preload_n".to_string(), "load_nm".to_string()];
        let (json, console) = crate::report::sweep::outcomes(&parameters, &columns, &rows);
        let first = &json["cases"]["first_not_finished"][0];
        assert_eq!(first["status"], "slack", "{json}");
        assert_eq!(first["reason"], reason.as_str(), "{json}");
        let line = console
            .lines()
            .find(|l| l.trim_start().starts_with("case 0 "))
            .unwrap_or_else(|| panic!("no line for case 0 in {console}"));
        assert!(line.ends_with(&format!("slack {reason}")), "{line}");
    }

    /// The outcomes read a case's reason from the `stop` column beside its `status`: a
    /// runner without one would report stopped cases with a blank reason.
    #[test]
    fn every_status_column_has_its_stop_column() {
        let closed_loop = builtin("eots_tracking");
        let runners: [(&str, Box<dyn CaseRunner>); 3] = [
            ("backlash", Box::new(crate::run::BacklashRunner)),
            ("quasi-static", Box::new(crate::run::QuasiStaticRunner)),
            (
                "closed loop",
                Box::new(crate::run::ClosedLoopRunner::for_scenario(&closed_loop)),
            ),
        ];
        for (study, runner) in runners {
            let columns = runner.columns();
            let statuses: Vec<&String> = columns.iter().filter(|c| c.ends_with("status")).collect();
            assert!(!statuses.is_empty(), "{study}: {columns:?}");
            for status in statuses {
                let stop = format!("{}stop", status.strip_suffix("status").unwrap_or(""));
                assert!(columns.contains(&stop), "{study}: {status} without {stop}");
            }
        }
    }

    #[test]
    fn tolerance_scenario_file_expands() {
        let text = include_str!("../../scenarios/paper_bench_tolerance.toml");
        let scenario = Scenario::from_toml(text, "t", "t", &[]).unwrap();
        let base = scenario.to_table();
        let cases = expand(scenario.sweep.as_ref().unwrap(), &base).unwrap();
        assert_eq!(cases.len(), 200);
        for c in &cases {
            let preload = num(&c.assignments[0].2);
            assert!((85.0..=115.0).contains(&preload), "{preload}");
            case_scenario(&base, c, "t").unwrap();
        }
    }
}
