//! `cable-servo margins` writes its analysis: `margins.json` with every crossing (the
//! same numbers the margins analysis returns), `linear_model.json` a tool outside can
//! rebuild the loop from, `summary.json` with the verdict, and the figures. The check that
//! python-control reproduces every margin from `linear_model.json` alone needs Python and
//! is ignored here; `.ci/run` runs it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use cable_servo::analysis::verdict;
use cable_servo::closed_loop::ClosedLoopSource;
use cable_servo::scenario::Scenario;
use serde_json::Value;

const SHORT: &str = "closed_loop.duration_s=6";

/// One run of `margins` on the shipped tracking design, shared by the tests.
fn results() -> &'static (tempfile::TempDir, PathBuf, Output) {
    static RUN: OnceLock<(tempfile::TempDir, PathBuf, Output)> = OnceLock::new();
    RUN.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("m");
        let out = Command::new(env!("CARGO_BIN_EXE_cable-servo"))
            .args(["margins", "eots_tracking", "--set", SHORT, "--out"])
            .arg(&dir)
            .current_dir(tmp.path())
            .output()
            .unwrap();
        (tmp, dir, out)
    })
}

fn json(dir: &Path, name: &str) -> Value {
    let text = std::fs::read_to_string(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    serde_json::from_str(&text).unwrap()
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// `v` read back from JSON equals `want` (the reader may round the last bit).
fn same(v: &Value, want: f64) {
    let got = num(v);
    assert!(
        (got - want).abs() <= 4.0 * f64::EPSILON * want.abs(),
        "{got} in the file, {want} from the analysis"
    );
}

fn matrix(v: &Value, rows: usize, cols: usize, what: &str) {
    let r = v
        .as_array()
        .unwrap_or_else(|| panic!("{what}: not a list of rows"));
    assert_eq!(r.len(), rows, "{what}: rows");
    for row in r {
        let row = row.as_array().unwrap();
        assert_eq!(row.len(), cols, "{what}: columns");
        assert!(
            row.iter().all(|x| x.as_f64().is_some_and(f64::is_finite)),
            "{what}"
        );
    }
}

#[test]
fn margins_writes_its_files_and_exit_code() {
    let (_, dir, out) = results();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("results: "), "{stdout}");
    for stem in ["bode", "nyquist", "nichols", "pole_zero", "step"] {
        for ext in ["png", "svg"] {
            let f = dir.join(format!("{stem}.{ext}"));
            let len = std::fs::metadata(&f).map(|m| m.len()).unwrap_or(0);
            assert!(len > 1000, "{} missing or empty", f.display());
        }
    }
    let summary = json(dir, "summary.json");
    assert_eq!(summary["study"], "closed_loop");
    assert_eq!(summary["verdict"]["passes"], Value::Bool(true));
    assert_eq!(summary["passes"], Value::Bool(true));
    assert!(summary["margins"]["operating_points"].is_array());
}

/// The crossings in `margins.json` and `linear_model.json` are the analysis' own.
#[test]
fn the_files_hold_the_crossings_the_analysis_returns() {
    let (_, dir, _) = results();
    let scenario = Scenario::load("eots_tracking", &[SHORT.to_string()]).unwrap();
    let setup = scenario.closed_loop_setup().unwrap();
    let (range, problem) = verdict::operating_range(&setup);
    assert!(problem.is_none());
    assert_eq!(
        range.len(),
        2,
        "free span and the tangent at the operating load"
    );
    let margins = json(dir, "margins.json");
    let model = json(dir, "linear_model.json");
    let points = margins["operating_points"].as_array().unwrap();
    let exported = model["operating_points"].as_array().unwrap();
    assert_eq!(points.len(), range.len());
    assert_eq!(exported.len(), range.len());
    for ((want, got), lm) in range.iter().zip(points).zip(exported) {
        let m = &want.margins;
        assert_eq!(got["condition"], want.condition.as_str());
        same(&got["half_stiffness_n_per_m"], want.half_stiffness_n_per_m);
        assert_eq!(got["stable"], Value::Bool(m.stable));
        same(&got["spectral_radius"], m.spectral_radius);
        let gains = got["gain_crossovers"].as_array().unwrap();
        assert_eq!(gains.len(), m.gain_crossovers.len());
        assert!(m.gain_crossovers.len() >= 2, "{:?}", m.gain_crossovers);
        for (g, w) in gains.iter().zip(&m.gain_crossovers) {
            same(&g["frequency_hz"], w.frequency_hz);
            same(&g["phase_margin_deg"], w.phase_margin_deg);
            assert_eq!(g["direction"], serde_json::to_value(w.direction).unwrap());
        }
        let phases = got["phase_crossovers"].as_array().unwrap();
        assert_eq!(phases.len(), m.phase_crossovers.len());
        for (p, w) in phases.iter().zip(&m.phase_crossovers) {
            same(&p["frequency_hz"], w.frequency_hz);
            same(&p["gain_margin_db"], w.gain_margin_db);
            assert_eq!(p["direction"], w.direction.name());
        }
        same(
            &got["worst"]["phase_margin_deg"],
            m.phase_margin_deg.unwrap(),
        );
        same(
            &got["worst"]["gain_margin_up_db"],
            m.gain_margin_db.unwrap(),
        );
        same(&got["ms"], m.ms.unwrap());
        same(&got["ms_hz"], m.ms_hz.unwrap());
        // linear_model.json carries the same crossings, written from the same numbers.
        assert_eq!(lm["margins"]["gain_crossovers"], got["gain_crossovers"]);
        assert_eq!(lm["margins"]["phase_crossovers"], got["phase_crossovers"]);
        assert_eq!(lm["margins"]["ms"], got["ms"]);

        // Closed-loop poles: all inside the unit circle, the largest the spectral radius.
        let poles = got["closed_loop_poles"].as_array().unwrap();
        let largest = poles
            .iter()
            .map(|p| num(&p["magnitude"]))
            .fold(0.0, f64::max);
        assert!((largest - m.spectral_radius).abs() <= 4.0 * f64::EPSILON);
        for p in poles {
            let (re, im) = (num(&p["re"]), num(&p["im"]));
            assert!((re.hypot(im) - num(&p["magnitude"])).abs() < 1e-12);
        }
        // The step: a result, settled or not, never a NaN.
        let step = &got["step"];
        assert!(num(&step["rise_time_s"]) > 0.0);
        assert_eq!(step["settled"], Value::Bool(true));
        assert!(num(&step["settling_time_s"]) > num(&step["rise_time_s"]));
        assert!(num(&step["overshoot_percent"]) >= 0.0);
    }
}

/// `linear_model.json` has the matrices, the controller and the loop response in the
/// documented shapes (docs/linear-model.md).
#[test]
fn the_linear_model_has_the_documented_shape() {
    let (_, dir, _) = results();
    let model = json(dir, "linear_model.json");
    assert_eq!(model["format_version"], 1);
    let ts = 1.0 / num(&model["sample_rate_hz"]);
    for p in model["operating_points"].as_array().unwrap() {
        let plant = &p["plant"];
        let n = plant["states"].as_array().unwrap().len();
        assert_eq!(n, 4, "motor and drum angles and rates");
        for s in plant["states"].as_array().unwrap() {
            assert!(s["name"].is_string() && s["unit"].is_string(), "{s}");
        }
        assert_eq!(plant["input"]["unit"], "A");
        assert_eq!(plant["output"]["unit"], "rad");
        matrix(&plant["a"], n, n, "a");
        matrix(&plant["b"], n, 1, "b");
        matrix(&plant["c"], 1, n, "c");
        matrix(&plant["d"], 1, 1, "d");
        matrix(&plant["ad"], n, n, "ad");
        matrix(&plant["bd"], n, 1, "bd");
        same(&plant["sample_period_s"], ts);
        same(&plant["delay_samples"], 1.0);
        assert_eq!(plant["delay_whole_samples"], 1);
        // A whole period of delay: the sampled plant is the plain zero-order hold.
        assert_eq!(plant["sampled"]["a"], plant["ad"]);
        assert_eq!(plant["sampled"]["b"], plant["bd"]);
        let k = &p["controller"];
        let numer = k["numerator_z_inv"].as_array().unwrap();
        assert_eq!(numer.len(), 4, "z^-1 times a second-order numerator");
        assert_eq!(num(&numer[0]), 0.0, "the delay's leading zero");
        assert_eq!(k["denominator_z_inv"].as_array().unwrap().len(), 3);
        same(&k["denominator_z_inv"][0], 1.0);
        assert!(k["delay_model"].as_str().unwrap().contains("z^-1"));
        let r = &p["loop_response"];
        let f: Vec<f64> = r["freq_hz"].as_array().unwrap().iter().map(num).collect();
        assert_eq!(f.len(), verdict::MARGIN_POINTS);
        assert!(f.windows(2).all(|w| w[1] > w[0]));
        assert!(f[f.len() - 1] < 0.5 / ts);
        assert_eq!(r["re"].as_array().unwrap().len(), f.len());
        assert_eq!(r["im"].as_array().unwrap().len(), f.len());
    }
}

/// python-control rebuilds the loop from `linear_model.json` alone and finds every
/// crossing the tool lists, within 0.1 deg and 0.1 dB.
#[test]
#[ignore = "needs python-control: run by .ci/run"]
fn python_control_reproduces_every_crossing_from_the_linear_model() {
    let (_, dir, out) = results();
    assert_eq!(out.status.code(), Some(0));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/check_linear_model.py");
    let check = match Command::new("python3").arg(&script).arg(dir).output() {
        Ok(o) => o,
        Err(e) => panic!(
            "python3 cannot be started ({e}): the check needs Python 3 with python-control (python3 -m pip install control)"
        ),
    };
    let stdout = String::from_utf8_lossy(&check.stdout);
    let stderr = String::from_utf8_lossy(&check.stderr);
    assert!(
        check.status.code() != Some(2),
        "the python-control check could not run: {stdout}{stderr}\ninstall python-control: python3 -m pip install control"
    );
    assert!(
        check.status.success(),
        "python-control does not reproduce the margins:\n{stdout}{stderr}"
    );
    assert_eq!(stdout.matches(": agrees").count(), 2, "{stdout}");
}
