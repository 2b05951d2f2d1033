//! Running the cases of a sweep in parallel and streaming one row per case, in case order.

use std::collections::BTreeMap;
use std::sync::mpsc;

use rayon::prelude::*;

use super::sample::{self, Draw};
use super::spec::{DistKind, SweepMode, SweepParameter, SweepSpec};

/// One case: the scenario keys it sets.
#[derive(Clone, Debug, PartialEq)]
pub struct Case {
    /// Case number in the whole sweep, from 0; fixes the output order and the case's seed.
    pub index: usize,
    /// `(dotted key, column name, value)`.
    pub assignments: Vec<(String, String, toml::Value)>,
}

/// How one parameter gets its value in each case.
enum Source<'a> {
    /// Listed values, picked by position.
    Values(&'a [toml::Value]),
    /// A distribution.
    Draw(Draw),
}

/// Numeric value of a dotted key in a scenario table.
fn base_number(base: &toml::Table, key: &str) -> Option<f64> {
    let mut parts = key.split('.');
    let first = parts.next()?;
    let mut cur = base.get(first)?;
    for part in parts {
        cur = cur.as_table()?.get(part)?;
    }
    match cur {
        toml::Value::Float(f) => Some(*f),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// The distribution of a parameter, relative ones resolved against the base scenario.
fn draw_of(
    p: &SweepParameter,
    kind: DistKind,
    at: &str,
    base: &toml::Table,
) -> Result<Draw, (String, String)> {
    let need = |v: Option<f64>, name: &str| {
        v.ok_or_else(|| {
            (
                format!("{at}.{name}"),
                format!("dist = \"{}\" needs {name}", kind.as_str()),
            )
        })
    };
    let base_value = || {
        base_number(base, &p.key)
            .filter(|b| b.is_finite() && *b != 0.0)
            .ok_or_else(|| {
                (
                    format!("{at}.key"),
                    format!(
                        "dist = \"{}\" is relative to the scenario's value of {}, which is not a non-zero number",
                        kind.as_str(),
                        p.key
                    ),
                )
            })
    };
    Ok(match kind {
        DistKind::Uniform => Draw::Uniform {
            lo: need(p.min, "min")?,
            hi: need(p.max, "max")?,
        },
        DistKind::Normal => Draw::Normal {
            mean: need(p.mean, "mean")?,
            std: need(p.std, "std")?,
        },
        DistKind::TruncatedNormal => Draw::TruncatedNormal {
            mean: need(p.mean, "mean")?,
            std: need(p.std, "std")?,
            lo: need(p.min, "min")?,
            hi: need(p.max, "max")?,
        },
        DistKind::UniformRelative => {
            let b = base_value()?;
            let t = need(p.rel_tol, "rel_tol")?;
            let (lo, hi) = (b * (1.0 - t), b * (1.0 + t));
            Draw::Uniform {
                lo: lo.min(hi),
                hi: lo.max(hi),
            }
        }
        DistKind::NormalRelative => {
            let b = base_value()?;
            let std = need(p.rel_std, "rel_std")? * b.abs();
            match p.rel_tol {
                None => Draw::Normal { mean: b, std },
                Some(t) => {
                    let (lo, hi) = (b * (1.0 - t), b * (1.0 + t));
                    Draw::TruncatedNormal {
                        mean: b,
                        std,
                        lo: lo.min(hi),
                        hi: lo.max(hi),
                    }
                }
            }
        }
    })
}

/// Expand a sweep declaration into its cases. `base` is the scenario table the sweep
/// varies (relative distributions take their centre from it). Errors are `(key, message)`.
pub fn expand(spec: &SweepSpec, base: &toml::Table) -> Result<Vec<Case>, (String, String)> {
    spec.validate()?;
    let params = &spec.parameters;
    let count = spec.case_count();
    let seed = spec.seed.unwrap_or(0);
    let sources: Vec<Source> = params
        .iter()
        .enumerate()
        .map(|(i, p)| match p.dist {
            Some(kind) => {
                draw_of(p, kind, &format!("sweep.parameters[{i}]"), base).map(Source::Draw)
            }
            None => Ok(Source::Values(&p.values)),
        })
        .collect::<Result<_, _>>()?;
    let strata: Vec<Vec<u32>> = if spec.mode == SweepMode::LatinHypercube {
        (0..params.len())
            .map(|j| sample::lhs_strata(seed, j, count))
            .collect()
    } else {
        Vec::new()
    };
    let cases = (0..count)
        .map(|index| {
            let mut rest = index;
            let mut picks = vec![0usize; params.len()];
            if spec.mode == SweepMode::Grid {
                // First parameter varies slowest, like nested loops written in order.
                for (i, p) in params.iter().enumerate().rev() {
                    picks[i] = rest % p.values.len();
                    rest /= p.values.len();
                }
            } else {
                picks.iter_mut().for_each(|k| *k = index);
            }
            let assignments = params
                .iter()
                .zip(&sources)
                .enumerate()
                .map(|(j, (p, source))| {
                    let value = if spec.mode.is_sampled() {
                        let u = sample::case_uniform(seed, index, j);
                        let u = match strata.get(j) {
                            Some(s) => (f64::from(s[index]) + u) / count as f64,
                            None => u,
                        };
                        match source {
                            Source::Draw(d) => toml::Value::Float(d.quantile(u)),
                            Source::Values(v) => {
                                v[((u * v.len() as f64) as usize).min(v.len() - 1)].clone()
                            }
                        }
                    } else {
                        match source {
                            Source::Values(v) => v[picks[j]].clone(),
                            // Rejected by validation: distributions only in sampled modes.
                            Source::Draw(d) => toml::Value::Float(d.quantile(0.5)),
                        }
                    };
                    (p.key.clone(), p.column_name().to_string(), value)
                })
                .collect();
            Case { index, assignments }
        })
        .collect();
    Ok(cases)
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

/// The cases to run and where.
pub struct Plan<'a> {
    /// All cases of the sweep.
    pub cases: &'a [Case],
    /// The part this process runs.
    pub shard: Shard,
    /// Worker threads (0 = all cores).
    pub threads: usize,
    /// Asked before each case; once it says true, cases not yet started are skipped (an
    /// interrupted sweep keeps the rows it finished).
    pub stop: Option<&'a (dyn Fn() -> bool + Sync)>,
}

/// How far a sweep got.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Progress {
    /// Rows handed to the sink.
    pub written: usize,
    /// Cases skipped because `stop` said so.
    pub skipped: usize,
}

/// What a sweep computes for one case: the caller resolves the case into whatever its
/// study needs, runs it and returns one cell per column. Physical stops are results (a
/// status cell), not errors; an error ends the sweep.
pub type CaseFn<'a> = dyn Fn(&Case) -> Result<Vec<Cell>, SweepError> + Sync + 'a;

/// Run the plan's cases on its threads and hand each row of `n_cols` cells to `sink` in
/// case order as soon as it and all earlier rows are done. `progress` is called after
/// every case.
pub fn run_cases(
    plan: &Plan<'_>,
    n_cols: usize,
    run_one: &CaseFn<'_>,
    sink: &mut dyn FnMut(&Case, Vec<Cell>) -> std::io::Result<()>,
    progress: &(dyn Fn() + Sync),
) -> Result<Progress, SweepError> {
    let stop = plan.stop;
    let mine: Vec<&Case> = plan
        .cases
        .iter()
        .filter(|c| plan.shard.owns(c.index))
        .collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(plan.threads)
        .build()
        .map_err(|e| SweepError::Threads(e.to_string()))?;
    type Row = Option<Result<Vec<Cell>, SweepError>>;
    let (tx, rx) = mpsc::sync_channel::<(usize, Row)>(256);
    let mut outcome = Ok(());
    let mut done = Progress::default();
    std::thread::scope(|scope| {
        let mine_ref = &mine;
        scope.spawn(move || {
            pool.install(|| {
                mine_ref
                    .par_iter()
                    .enumerate()
                    .for_each_with(tx, |tx, (pos, case)| {
                        if stop.is_some_and(|s| s()) {
                            let _ = tx.send((pos, None));
                            return;
                        }
                        let row = run_one(case);
                        progress();
                        // The receiver only stops early on a write error; then the rest is moot.
                        let _ = tx.send((pos, Some(row)));
                    });
            });
        });
        // Reorder buffer: rows arrive roughly in order, so it stays small.
        let mut waiting: BTreeMap<usize, Row> = BTreeMap::new();
        let mut next = 0;
        for (pos, row) in rx.iter() {
            if outcome.is_err() {
                continue;
            }
            waiting.insert(pos, row);
            while let Some(row) = waiting.remove(&next) {
                let case = mine[next];
                let result = match row {
                    None => {
                        done.skipped += 1;
                        Ok(())
                    }
                    Some(Ok(mut cells)) => {
                        cells.resize(n_cols, Cell::Num(None));
                        done.written += 1;
                        sink(case, cells).map_err(SweepError::Write)
                    }
                    Some(Err(e)) => Err(e),
                };
                if let Err(e) = result {
                    outcome = Err(e);
                    break;
                }
                next += 1;
            }
        }
    });
    outcome.map(|()| done)
}

/// A sweep that could not finish.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A case's description is invalid (e.g. a varied value out of range).
    #[error("sweep case {index}: {source}")]
    Case {
        /// Case index.
        index: usize,
        /// Why.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// Writing the table failed.
    #[error("writing the sweep table: {0}")]
    Write(std::io::Error),
    /// A case's own files (time series) could not be written.
    #[error("writing the files of sweep case {index}: {source}")]
    CaseFiles {
        /// Case index.
        index: usize,
        /// Cause.
        source: std::io::Error,
    },
    /// The thread pool could not start.
    #[error("cannot start worker threads: {0}")]
    Threads(String),
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::sweep::spec::SweepParameter;

    fn param(key: &str, n: usize) -> SweepParameter {
        SweepParameter::with_values(
            key,
            (0..n).map(|i| toml::Value::Integer(i as i64)).collect(),
        )
    }

    /// A swept value as a number (test helper shared with the sweep runner's tests).
    pub(crate) fn num(v: &toml::Value) -> f64 {
        match v {
            toml::Value::Float(f) => *f,
            toml::Value::Integer(i) => *i as f64,
            other => panic!("not a number: {other}"),
        }
    }

    #[test]
    fn grid_is_row_major_and_complete() {
        let spec = SweepSpec {
            mode: SweepMode::Grid,
            parameters: vec![param("a.x", 3), param("b.y", 2)],
            ..SweepSpec::default()
        };
        let cases = expand(&spec, &toml::Table::new()).unwrap();
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

    /// A uniformly drawn parameter (test helper shared with the sweep runner's tests).
    pub(crate) fn uniform(key: &str, lo: f64, hi: f64) -> SweepParameter {
        SweepParameter {
            key: key.into(),
            dist: Some(DistKind::Uniform),
            min: Some(lo),
            max: Some(hi),
            ..SweepParameter::default()
        }
    }

    #[test]
    fn latin_hypercube_hits_every_stratum_once() {
        let n = 37;
        let spec = SweepSpec {
            mode: SweepMode::LatinHypercube,
            samples: Some(n),
            seed: Some(9),
            parameters: vec![
                uniform("a.x", 0.0, 1.0),
                uniform("b.y", -10.0, 30.0),
                SweepParameter {
                    key: "c.z".into(),
                    dist: Some(DistKind::Normal),
                    mean: Some(0.0),
                    std: Some(1.0),
                    ..SweepParameter::default()
                },
            ],
        };
        let cases = expand(&spec, &toml::Table::new()).unwrap();
        assert_eq!(cases.len(), n);
        let to_u: [&dyn Fn(f64) -> f64; 3] =
            [&|x| x, &|y| (y + 10.0) / 40.0, &crate::stats::normal_cdf];
        for (j, u_of) in to_u.iter().enumerate() {
            let mut hits = vec![0; n];
            for c in &cases {
                let u = u_of(num(&c.assignments[j].2));
                hits[((u * n as f64) as usize).min(n - 1)] += 1;
            }
            assert!(hits.iter().all(|&h| h == 1), "parameter {j}: {hits:?}");
        }
        // Columns are not stratified in lockstep.
        assert_ne!(cases[0].assignments[0].2, cases[1].assignments[0].2);
    }

    #[test]
    fn relative_distributions_centre_on_the_base_value() {
        let base: toml::Table = toml::from_str("[drive]\npreload_n = 80.0").unwrap();
        let spec = SweepSpec {
            mode: SweepMode::Random,
            samples: Some(200),
            parameters: vec![SweepParameter {
                key: "drive.preload_n".into(),
                dist: Some(DistKind::UniformRelative),
                rel_tol: Some(0.1),
                ..SweepParameter::default()
            }],
            ..SweepSpec::default()
        };
        let cases = expand(&spec, &base).unwrap();
        assert!(cases
            .iter()
            .all(|c| (72.0..=88.0).contains(&num(&c.assignments[0].2))));
        let (key, msg) = expand(&spec, &toml::Table::new()).unwrap_err();
        assert_eq!(key, "sweep.parameters[0].key");
        assert!(msg.contains("drive.preload_n"), "{msg}");
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
