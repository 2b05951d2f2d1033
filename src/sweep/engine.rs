//! Running the cases of a sweep in parallel and streaming one row per case, in case order.

use std::collections::BTreeMap;
use std::sync::mpsc;

use rayon::prelude::*;

use super::spec::{SweepMode, SweepSpec};
use crate::scenario::{set_path, Scenario, ScenarioError};

/// One case: the scenario keys it sets.
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    /// Case number in the whole sweep, from 0; fixes the output order and the case's seed.
    pub index: usize,
    /// `(dotted key, column name, value)`.
    pub assignments: Vec<(String, String, toml::Value)>,
}

/// Expand a sweep declaration into its cases.
pub fn expand(spec: &SweepSpec) -> Vec<Case> {
    let params = &spec.parameters;
    let count = match spec.mode {
        SweepMode::Grid => params.iter().map(|p| p.values.len()).product(),
        SweepMode::List => params.first().map_or(0, |p| p.values.len()),
    };
    (0..count)
        .map(|index| {
            let mut rest = index;
            let mut picks = vec![0usize; params.len()];
            match spec.mode {
                SweepMode::Grid => {
                    // First parameter varies slowest, like nested loops written in order.
                    for (i, p) in params.iter().enumerate().rev() {
                        picks[i] = rest % p.values.len();
                        rest /= p.values.len();
                    }
                }
                SweepMode::List => picks.iter_mut().for_each(|k| *k = index),
            }
            Case {
                index,
                assignments: params
                    .iter()
                    .zip(&picks)
                    .map(|(p, &k)| {
                        (
                            p.key.clone(),
                            p.column_name().to_string(),
                            p.values[k].clone(),
                        )
                    })
                    .collect(),
            }
        })
        .collect()
}

/// Which part of a sweep this process runs: shard `k` of `n` (1-based) takes the cases whose
/// index is `k - 1` modulo `n`, so shards stay balanced when cost varies along the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This shard, 1..=n.
    pub k: usize,
    /// Number of shards.
    pub n: usize,
}

impl Shard {
    /// The whole sweep.
    pub const ALL: Shard = Shard { k: 1, n: 1 };

    /// Parse `K/N`.
    pub fn parse(text: &str) -> Result<Shard, String> {
        let (k, n) = text
            .split_once('/')
            .ok_or_else(|| format!("--shard {text}: expected K/N, e.g. 3/8"))?;
        let k: usize = k
            .trim()
            .parse()
            .map_err(|_| format!("--shard {text}: K must be a whole number"))?;
        let n: usize = n
            .trim()
            .parse()
            .map_err(|_| format!("--shard {text}: N must be a whole number"))?;
        if n == 0 || k == 0 || k > n {
            return Err(format!("--shard {text}: need 1 <= K <= N"));
        }
        Ok(Shard { k, n })
    }

    /// Whether this shard runs case `index`.
    pub fn owns(&self, index: usize) -> bool {
        index % self.n == self.k - 1
    }
}

/// One cell of the sweep table.
#[derive(Clone, Debug, PartialEq)]
pub enum Cell {
    /// A number; `None` writes an empty cell (figure not defined for this case).
    Num(Option<f64>),
    /// Text such as a regime name.
    Text(String),
}

impl Cell {
    /// CSV text: numbers in shortest round-trip form, missing values empty.
    pub fn render(&self) -> String {
        match self {
            Cell::Num(Some(v)) if v.is_finite() => format!("{v}"),
            Cell::Num(_) => String::new(),
            Cell::Text(s) => s.clone(),
        }
    }
}

/// Render a TOML value for a CSV cell.
pub fn render_value(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        toml::Value::Float(f) => format!("{f}"),
        toml::Value::Integer(i) => format!("{i}"),
        other => other.to_string(),
    }
}

/// What a sweep computes per case.
pub trait CaseRunner: Sync {
    /// Names of the figures, in order (units in the names).
    fn columns(&self) -> Vec<String>;
    /// Figures of one resolved case scenario; must return one cell per column. Failures of
    /// the physics are results (a regime column), not errors.
    fn run(&self, scenario: &Scenario, case: &Case) -> Vec<Cell>;
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
    Scenario::from_table(table, &format!("sweep case {}", case.index), default_name)
}

/// The cases to run and where.
pub struct Plan<'a> {
    /// Base scenario table (the sweep's own section is dropped per case).
    pub base: &'a toml::Table,
    /// Scenario name used when the table sets none.
    pub default_name: &'a str,
    /// All cases of the sweep.
    pub cases: &'a [Case],
    /// The part this process runs.
    pub shard: Shard,
    /// Worker threads (0 = all cores).
    pub threads: usize,
}

/// Run the plan's cases on its threads and hand each row to `sink` in case order as soon
/// as it and all earlier rows are done. `progress` is called after every case.
pub fn run_cases(
    plan: &Plan<'_>,
    runner: &dyn CaseRunner,
    sink: &mut dyn FnMut(&Case, Vec<Cell>) -> std::io::Result<()>,
    progress: &(dyn Fn() + Sync),
) -> Result<(), SweepError> {
    let (base, default_name) = (plan.base, plan.default_name);
    let mine: Vec<&Case> = plan
        .cases
        .iter()
        .filter(|c| plan.shard.owns(c.index))
        .collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(plan.threads)
        .build()
        .map_err(|e| SweepError::Threads(e.to_string()))?;
    let (tx, rx) = mpsc::sync_channel::<(usize, Result<Vec<Cell>, ScenarioError>)>(256);
    let n_cols = runner.columns().len();
    let mut outcome = Ok(());
    std::thread::scope(|scope| {
        let mine_ref = &mine;
        scope.spawn(move || {
            pool.install(|| {
                mine_ref
                    .par_iter()
                    .enumerate()
                    .for_each_with(tx, |tx, (pos, case)| {
                        let row =
                            case_scenario(base, case, default_name).map(|s| runner.run(&s, case));
                        progress();
                        // The receiver only stops early on a write error; then the rest is moot.
                        let _ = tx.send((pos, row));
                    });
            });
        });
        // Reorder buffer: rows arrive roughly in order, so it stays small.
        let mut waiting: BTreeMap<usize, Result<Vec<Cell>, ScenarioError>> = BTreeMap::new();
        let mut next = 0;
        for (pos, row) in rx.iter() {
            if outcome.is_err() {
                continue;
            }
            waiting.insert(pos, row);
            while let Some(row) = waiting.remove(&next) {
                let case = mine[next];
                let result = match row {
                    Ok(mut cells) => {
                        cells.resize(n_cols, Cell::Num(None));
                        sink(case, cells).map_err(SweepError::Write)
                    }
                    Err(e) => Err(SweepError::Case {
                        index: case.index,
                        source: Box::new(e),
                    }),
                };
                if let Err(e) = result {
                    outcome = Err(e);
                    break;
                }
                next += 1;
            }
        }
    });
    outcome
}

/// A sweep that could not finish.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A case's scenario is invalid (e.g. a varied value out of range).
    #[error("sweep case {index}: {source}")]
    Case {
        /// Case index.
        index: usize,
        /// Why.
        source: Box<ScenarioError>,
    },
    /// Writing the table failed.
    #[error("writing the sweep table: {0}")]
    Write(std::io::Error),
    /// The thread pool could not start.
    #[error("cannot start worker threads: {0}")]
    Threads(String),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::spec::SweepParameter;

    fn param(key: &str, n: usize) -> SweepParameter {
        SweepParameter {
            key: key.into(),
            values: (0..n).map(|i| toml::Value::Integer(i as i64)).collect(),
            column: None,
        }
    }

    #[test]
    fn grid_is_row_major_and_complete() {
        let spec = SweepSpec {
            mode: SweepMode::Grid,
            parameters: vec![param("a.x", 3), param("b.y", 2)],
        };
        let cases = expand(&spec);
        assert_eq!(cases.len(), 6);
        let picks: Vec<(String, String)> = cases
            .iter()
            .map(|c| {
                (
                    render_value(&c.assignments[0].2),
                    render_value(&c.assignments[1].2),
                )
            })
            .collect();
        assert_eq!(picks[1], ("0".into(), "1".into()));
        assert_eq!(picks[2], ("1".into(), "0".into()));
        assert_eq!(cases[0].assignments[0].1, "x");
    }

    #[test]
    fn shards_partition_the_cases() {
        for n in 1..6 {
            for index in 0..50 {
                let owners = (1..=n).filter(|&k| Shard { k, n }.owns(index)).count();
                assert_eq!(owners, 1);
            }
        }
        assert!(Shard::parse("0/3").is_err());
        assert!(Shard::parse("4/3").is_err());
        assert_eq!(Shard::parse("2/3"), Ok(Shard { k: 2, n: 3 }));
    }
}
