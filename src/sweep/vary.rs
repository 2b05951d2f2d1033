//! `--vary KEY=SPEC` and the other command-line changes to a scenario's sweep.
//!
//! SPEC forms (values in the key's unit):
//!
//! | form                         | meaning                                              |
//! |------------------------------|------------------------------------------------------|
//! | `10,20,30` (or `70`)         | listed values (any TOML value or bare word)          |
//! | `10:100:10`                  | start:stop:step, stop included when on the step      |
//! | `lin(10,100,5)`              | 5 evenly spaced values from 10 to 100                |
//! | `log(1,1000,4)`              | 4 log-spaced values from 1 to 1000                   |
//! | `uniform(90,110)`            | uniform between min and max                          |
//! | `normal(100,5)`              | normal, mean and standard deviation                  |
//! | `tnormal(100,5,90,110)`      | normal truncated to [min, max]                       |
//! | `uniform_rel(0.05)`          | uniform within +-5 % of the scenario's value         |
//! | `normal_rel(0.05[,0.15])`    | normal, std 5 % of the scenario's value [cut at 15 %] |

use super::spec::{DistKind, SweepMode, SweepParameter, SweepSpec};

/// The SPEC forms, for error messages.
pub const FORMS: &str = "a,b,c | start:stop:step | lin(start,stop,n) | log(start,stop,n) | \
uniform(min,max) | normal(mean,std) | tnormal(mean,std,min,max) | uniform_rel(tol) | \
normal_rel(std[,tol])";

/// Values of a range form, rounded to 12 significant digits so `0.1:0.5:0.1` gives `0.3`
/// rather than `0.30000000000000004` in the table.
fn tidy(x: f64) -> f64 {
    format!("{x:.11e}").parse().unwrap_or(x)
}

fn numbers(arg: &str, text: &str, count: &[usize]) -> Result<Vec<f64>, String> {
    let xs: Vec<f64> = text
        .split(',')
        .map(|t| {
            let t = t.trim();
            t.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("--vary {arg}: {t:?} is not a finite number"))
        })
        .collect::<Result<_, _>>()?;
    if !count.contains(&xs.len()) {
        let want: Vec<String> = count.iter().map(usize::to_string).collect();
        return Err(format!(
            "--vary {arg}: expected {} numbers, got {}",
            want.join(" or "),
            xs.len()
        ));
    }
    Ok(xs)
}

/// A whole count such as `n` in `lin(a,b,n)`.
fn count_of(arg: &str, x: f64) -> Result<usize, String> {
    if x.fract() != 0.0 || !(1.0..=1e7).contains(&x) {
        return Err(format!(
            "--vary {arg}: the count {x} must be a whole number from 1 to 1e7"
        ));
    }
    Ok(x as usize)
}

/// Float values unless every number of the range is a whole number written without a
/// point, so integer keys can be swept too.
fn range_values(xs: Vec<f64>, integers: bool) -> Vec<toml::Value> {
    xs.into_iter()
        .map(|x| {
            if integers && x.fract() == 0.0 && x.abs() < 9e15 {
                toml::Value::Integer(x as i64)
            } else {
                toml::Value::Float(tidy(x))
            }
        })
        .collect()
}

/// Parse one `--vary KEY=SPEC` into a sweep parameter.
pub fn parse_vary(arg: &str) -> Result<SweepParameter, String> {
    let (key, spec) = arg
        .split_once('=')
        .ok_or_else(|| format!("--vary {arg}: expected KEY=SPEC with SPEC one of {FORMS}"))?;
    let key = key.trim();
    if key.is_empty() || key.split('.').any(|p| p.trim().is_empty()) {
        return Err(format!(
            "--vary {arg}: {key:?} is not a dotted scenario key, e.g. drive.preload_n"
        ));
    }
    let spec = spec.trim();
    if spec.is_empty() {
        return Err(format!(
            "--vary {arg}: nothing after '='; SPEC is one of {FORMS}"
        ));
    }
    let mut p = SweepParameter {
        key: key.to_string(),
        ..SweepParameter::default()
    };
    if let Some((name, rest)) = spec.split_once('(') {
        let inner = rest.strip_suffix(')').ok_or_else(|| {
            format!("--vary {arg}: missing ')' at the end; SPEC is one of {FORMS}")
        })?;
        let name = name.trim();
        match name {
            "lin" | "log" => {
                let xs = numbers(arg, inner, &[3])?;
                let n = count_of(arg, xs[2])?;
                let (a, b) = (xs[0], xs[1]);
                if name == "log" && (a <= 0.0 || b <= 0.0) {
                    return Err(format!("--vary {arg}: log() needs start and stop > 0"));
                }
                let at = |k: usize| {
                    let f = if n == 1 {
                        0.0
                    } else {
                        k as f64 / (n - 1) as f64
                    };
                    if name == "lin" {
                        a + (b - a) * f
                    } else {
                        (a.ln() + (b.ln() - a.ln()) * f).exp()
                    }
                };
                p.values = range_values((0..n).map(at).collect(), false);
            }
            "uniform" => {
                let xs = numbers(arg, inner, &[2])?;
                (p.dist, p.min, p.max) = (Some(DistKind::Uniform), Some(xs[0]), Some(xs[1]));
            }
            "normal" => {
                let xs = numbers(arg, inner, &[2])?;
                (p.dist, p.mean, p.std) = (Some(DistKind::Normal), Some(xs[0]), Some(xs[1]));
            }
            "tnormal" => {
                let xs = numbers(arg, inner, &[4])?;
                p.dist = Some(DistKind::TruncatedNormal);
                (p.mean, p.std, p.min, p.max) =
                    (Some(xs[0]), Some(xs[1]), Some(xs[2]), Some(xs[3]));
            }
            "uniform_rel" => {
                let xs = numbers(arg, inner, &[1])?;
                (p.dist, p.rel_tol) = (Some(DistKind::UniformRelative), Some(xs[0]));
            }
            "normal_rel" => {
                let xs = numbers(arg, inner, &[1, 2])?;
                (p.dist, p.rel_std, p.rel_tol) = (
                    Some(DistKind::NormalRelative),
                    Some(xs[0]),
                    xs.get(1).copied(),
                );
            }
            other => {
                return Err(format!(
                    "--vary {arg}: unknown form {other:?}(...); SPEC is one of {FORMS}"
                ))
            }
        }
    } else if spec.contains(':') && !spec.contains(',') {
        let parts: Vec<&str> = spec.split(':').collect();
        if parts.len() != 3 {
            return Err(format!(
                "--vary {arg}: a range is start:stop:step (three numbers); SPEC is one of {FORMS}"
            ));
        }
        let xs = numbers(arg, &parts.join(","), &[3])?;
        let (a, b, step) = (xs[0], xs[1], xs[2]);
        if step == 0.0 || (b - a) * step < 0.0 {
            return Err(format!(
                "--vary {arg}: step {step} does not lead from {a} to {b}"
            ));
        }
        // The stop counts as reached within a small fraction of a step (float steps).
        let n = ((b - a) / step + 1e-9).floor() + 1.0;
        let n = count_of(arg, n)?;
        let integers = parts.iter().all(|t| t.trim().parse::<i64>().is_ok());
        p.values = range_values((0..n).map(|k| a + step * k as f64).collect(), integers);
    } else {
        p.values = spec
            .split(',')
            .map(|t| {
                let t = t.trim();
                if t.is_empty() {
                    return Err(format!(
                        "--vary {arg}: empty item in the list; SPEC is one of {FORMS}"
                    ));
                }
                Ok(toml::from_str::<toml::Table>(&format!("v = {t}"))
                    .ok()
                    .and_then(|mut tab| tab.remove("v"))
                    .unwrap_or_else(|| toml::Value::String(t.to_string())))
            })
            .collect::<Result<_, _>>()?;
    }
    Ok(p)
}

/// Command-line changes to a sweep.
#[derive(Clone, Debug, Default)]
pub struct SweepOverrides {
    /// `--vary KEY=SPEC` arguments, in order.
    pub vary: Vec<String>,
    /// `--mode`.
    pub mode: Option<SweepMode>,
    /// `--samples`: cases drawn in random and latin_hypercube modes.
    pub samples: Option<usize>,
    /// `--seed`: master seed of the draws.
    pub seed: Option<u64>,
}

impl SweepOverrides {
    /// Whether any change is asked for.
    pub fn is_empty(&self) -> bool {
        self.vary.is_empty() && self.mode.is_none() && self.samples.is_none() && self.seed.is_none()
    }

    /// Apply to a scenario's sweep (or to none). A `--vary` replaces the parameter of the
    /// same key or adds one. Without `--mode`, giving `--samples`, `--seed` or a
    /// distribution switches a grid or list sweep to random sampling, since those only
    /// mean something there.
    pub fn apply(&self, sweep: Option<SweepSpec>) -> Result<SweepSpec, String> {
        let mut spec = sweep.unwrap_or_default();
        let mut varied: Vec<String> = Vec::new();
        for arg in &self.vary {
            let p = parse_vary(arg)?;
            // A second `--vary` of one key would silently drop the first.
            if varied.contains(&p.key) {
                return Err(format!(
                    "--vary {arg}: {} is already varied by an earlier --vary; give all its values in one",
                    p.key
                ));
            }
            varied.push(p.key.clone());
            match spec.parameters.iter_mut().find(|q| q.key == p.key) {
                Some(q) => {
                    let column = q.column.take();
                    *q = SweepParameter { column, ..p };
                }
                None => spec.parameters.push(p),
            }
        }
        let wants_sampling = self.samples.is_some()
            || self.seed.is_some()
            || spec.parameters.iter().any(|p| p.dist.is_some());
        spec.mode = match self.mode {
            Some(m) => m,
            None if wants_sampling && !spec.mode.is_sampled() => SweepMode::Random,
            None => spec.mode,
        };
        if self.samples.is_some() {
            spec.samples = self.samples;
        }
        if self.seed.is_some() {
            spec.seed = self.seed;
        }
        if !spec.mode.is_sampled() {
            // Left over from the file's sampled sweep; meaningless for a grid or list.
            spec.samples = None;
            spec.seed = None;
        }
        spec.validate().map_err(|(key, msg)| {
            format!("sweep after --vary/--mode/--samples/--seed: {key}: {msg}")
        })?;
        Ok(spec)
    }
}

/// Parse `--mode`.
pub fn parse_mode(text: &str) -> Result<SweepMode, String> {
    match text {
        "grid" => Ok(SweepMode::Grid),
        "list" => Ok(SweepMode::List),
        "random" => Ok(SweepMode::Random),
        "latin_hypercube" | "lhs" => Ok(SweepMode::LatinHypercube),
        other => Err(format!(
            "--mode {other}: expected grid, list, random or latin_hypercube (lhs)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn values(arg: &str) -> Vec<String> {
        parse_vary(arg)
            .unwrap()
            .values
            .iter()
            .map(crate::sweep::engine::render_value)
            .collect()
    }

    #[test]
    fn a_key_varied_twice_is_refused() {
        let overrides = SweepOverrides {
            vary: vec![
                "drive.preload_n=10:100:10".into(),
                "load.brake_nm=0.3".into(),
                "drive.preload_n=5,6".into(),
            ],
            ..SweepOverrides::default()
        };
        let err = overrides.apply(None).unwrap_err();
        assert!(
            err.starts_with("--vary drive.preload_n=5,6: drive.preload_n is already varied"),
            "{err}"
        );
        // Once each, they make a sweep.
        let once = SweepOverrides {
            vary: overrides.vary[..2].to_vec(),
            ..SweepOverrides::default()
        };
        assert_eq!(once.apply(None).unwrap().parameters.len(), 2);
    }

    #[test]
    fn value_forms() {
        assert_eq!(values("drive.preload_n=10,20,30"), ["10", "20", "30"]);
        assert_eq!(values("drive.preload_n=70"), ["70"]);
        assert_eq!(
            values("drive.routing=open,figure_eight"),
            ["open", "figure_eight"]
        );
        assert_eq!(values("a.b=10:50:10"), ["10", "20", "30", "40", "50"]);
        assert_eq!(
            values("a.b=0.1:0.5:0.1"),
            ["0.1", "0.2", "0.3", "0.4", "0.5"]
        );
        assert_eq!(values("a.b=10:45:10"), ["10", "20", "30", "40"]);
        assert_eq!(values("a.b=lin(10,100,4)"), ["10", "40", "70", "100"]);
        assert_eq!(values("a.b=log(1,1000,4)"), ["1", "10", "100", "1000"]);
        let p = parse_vary("a.b=10:30:10").unwrap();
        assert!(matches!(p.values[0], toml::Value::Integer(10)));
        let p = parse_vary("a.b=10.0:30:10").unwrap();
        assert!(matches!(p.values[0], toml::Value::Float(_)));
    }

    #[test]
    fn distribution_forms() {
        let p = parse_vary("drive.preload_n=tnormal(100, 5, 90, 110)").unwrap();
        assert_eq!(p.dist, Some(DistKind::TruncatedNormal));
        assert_eq!(
            (p.mean, p.std, p.min, p.max),
            (Some(100.0), Some(5.0), Some(90.0), Some(110.0))
        );
        let p = parse_vary("drive.preload_n=normal_rel(0.05,0.15)").unwrap();
        assert_eq!((p.rel_std, p.rel_tol), (Some(0.05), Some(0.15)));
        assert_eq!(
            parse_vary("a.b=uniform(1,2)").unwrap().dist,
            Some(DistKind::Uniform)
        );
        assert_eq!(
            parse_vary("a.b=normal(1,2)").unwrap().dist,
            Some(DistKind::Normal)
        );
    }

    #[test]
    fn errors_name_the_argument_and_forms() {
        for bad in [
            "preload",
            "a.b=",
            "a.b=gamma(1,2)",
            "a.b=normal(1)",
            "a.b=lin(1,2,2.5)",
            "a.b=1:2",
            "a.b=10:1:1",
            "a.b=log(0,10,3)",
            "a.b=normal(1,x)",
            ".b=1",
        ] {
            let err = parse_vary(bad).unwrap_err();
            assert!(err.starts_with(&format!("--vary {bad}:")), "{err}");
        }
        assert!(parse_vary("a.b=gamma(1,2)")
            .unwrap_err()
            .contains("tnormal(mean,std,min,max)"));
    }

    #[test]
    fn overrides_replace_add_and_switch_mode() {
        let file = SweepSpec {
            parameters: vec![SweepParameter {
                column: Some("P".into()),
                ..SweepParameter::with_values("drive.preload_n", vec![toml::Value::Float(1.0)])
            }],
            ..SweepSpec::default()
        };
        let o = SweepOverrides {
            vary: vec![
                "drive.preload_n=10,20".into(),
                "backlash.load_nm=1,2,3".into(),
            ],
            ..SweepOverrides::default()
        };
        let spec = o.apply(Some(file.clone())).unwrap();
        assert_eq!(spec.mode, SweepMode::Grid);
        assert_eq!(spec.case_count(), 6);
        assert_eq!(spec.parameters[0].column_name(), "P");
        let o = SweepOverrides {
            vary: vec!["drive.preload_n=normal(100,5)".into()],
            samples: Some(12),
            ..SweepOverrides::default()
        };
        let spec = o.apply(None).unwrap();
        assert_eq!((spec.mode, spec.case_count()), (SweepMode::Random, 12));
        let o = SweepOverrides {
            vary: vec!["drive.preload_n=normal(100,5)".into()],
            mode: Some(SweepMode::Grid),
            ..SweepOverrides::default()
        };
        assert!(o
            .apply(None)
            .unwrap_err()
            .contains("sweep.parameters[0].dist"));
        let o = SweepOverrides {
            vary: vec!["drive.preload_n=normal(100,5)".into()],
            ..SweepOverrides::default()
        };
        assert!(o.apply(None).unwrap_err().contains("sweep.samples"));
    }
}
