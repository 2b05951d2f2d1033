//! `cable-servo export-fmu`: the FMU archive of a closed-loop scenario's plant.
//!
//! Contents: `modelDescription.xml` (variables from [`super::variables`] with the
//! scenario's values as start values), `binaries/linux64/cable_servo.so` (this crate's
//! shared library), `resources/scenario.toml` (the resolved scenario, read at
//! `fmi2Instantiate` for the defaults) and `documentation/` (the variable list with units).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::instance::{plant_params, Instance, LOG_CATEGORIES};
use super::variables::{Causality, Kind, Values, Variable, VARIABLES};
use super::zip::{store, Entry};
use super::{guid, MODEL_IDENTIFIER, SCENARIO_RESOURCE};
use crate::closed_loop::Amplifier;
use crate::scenario::Scenario;

/// Why no FMU was written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The scenario cannot become an FMU.
    #[error("{0}")]
    Scenario(String),
    /// The shared library is missing.
    #[error("the FMU's shared library {} is missing: it is built next to the cable-servo binary by `cargo build --release` (the library target is also a cdylib); run export-fmu from that build or give --library PATH", .0.display())]
    NoLibrary(PathBuf),
    /// The file given as the shared library is not one a Linux x86-64 host can load.
    #[error("--library {}: {why}; give the libcable_servo.so that `cargo build --release` builds next to the cable-servo binary", path.display())]
    NotALibrary {
        /// The file.
        path: PathBuf,
        /// What it is instead.
        why: String,
    },
    /// The FMU would replace an existing file.
    #[error("{} exists; use --force to replace it or --out for another file", .0.display())]
    Exists(PathBuf),
    /// A file cannot be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// This platform has no FMI 2.0 platform name the exporter knows.
    #[error("export-fmu packs Linux x86-64 binaries (binaries/linux64); this build is for another platform")]
    Platform,
}

/// What was written.
#[derive(Debug, Clone)]
pub struct ExportReport {
    /// The FMU file.
    pub path: PathBuf,
    /// Its GUID.
    pub guid: String,
    /// Variables declared.
    pub variables: usize,
    /// Size of the archive, bytes.
    pub bytes: usize,
}

/// Why `bytes` are not an x86-64 ELF shared object (the only binary an FMU of this build
/// packs, and what an FMI host will try to load), or `None` when they are.
fn not_a_shared_library(bytes: &[u8]) -> Option<String> {
    const ET_DYN: u16 = 3;
    const EM_X86_64: u16 = 62;
    if bytes.len() < 20 || &bytes[..4] != b"\x7fELF" {
        return Some("not a shared library (no ELF header)".into());
    }
    let half = |at: usize| u16::from_le_bytes([bytes[at], bytes[at + 1]]);
    // Class 2 is 64-bit, data 1 little-endian.
    if bytes[4] != 2 || bytes[5] != 1 || half(18) != EM_X86_64 {
        return Some("an ELF file for another machine than 64-bit x86".into());
    }
    (half(16) != ET_DYN).then(|| "an ELF file that is not a shared library".into())
}

/// Where the shared library is expected: next to the executable.
pub fn library_beside(exe: &Path) -> PathBuf {
    exe.with_file_name(format!("lib{}.so", env!("CARGO_CRATE_NAME")))
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// SI base-unit exponents `(kg, m, s, A, rad)` of the units the variables use.
fn base_unit(unit: &str) -> [i32; 5] {
    match unit {
        "rad" => [0, 0, 0, 0, 1],
        "rad/s" => [0, 0, -1, 0, 1],
        "m" => [0, 1, 0, 0, 0],
        "N" => [1, 1, -2, 0, 0],
        "N.m" => [1, 2, -2, 0, 0],
        "A" => [0, 0, 0, 1, 0],
        "V" => [1, 2, -3, -1, 0],
        "Ohm" => [1, 2, -3, -2, 0],
        "H" => [1, 2, -2, -2, 0],
        "kg.m2" => [1, 2, 0, 0, 0],
        "N.m.s/rad" => [1, 2, -1, 0, -1],
        "V.s/rad" => [1, 2, -2, -1, -1],
        "N.m/A" => [1, 2, -2, -1, 0],
        "s" => [0, 0, 1, 0, 0],
        "Hz" => [0, 0, -1, 0, 0],
        _ => [0; 5],
    }
}

/// Variables of an FMU with amplifier `amp`, in modelDescription order.
fn declared(amp: Amplifier) -> Vec<&'static Variable> {
    VARIABLES.iter().filter(|v| v.present(amp)).collect()
}

fn start_text(var: &Variable, values: &Values) -> String {
    let v = (var.get)(values);
    match var.kind {
        Kind::Real => format!("{v:?}"),
        Kind::Integer => format!("{}", v as i64),
        Kind::Boolean => (if v != 0.0 { "true" } else { "false" }).into(),
    }
}

/// modelDescription.xml of the FMU with these defaults.
pub fn model_description(scenario: &Scenario, values: &Values, guid: &str) -> String {
    let amp = values.params.closed_loop.motor.amplifier;
    let vars = declared(amp);
    let cl = &values.params.closed_loop;
    let mut x = String::new();
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        x,
        r#"<fmiModelDescription fmiVersion="2.0" modelName="cable_servo {name}" guid="{guid}" description="{desc}" generationTool="cable-servo {ver}" variableNamingConvention="structured" numberOfEventIndicators="0">"#,
        name = xml_escape(scenario.name()),
        // Only what the FMU carries: the scenario's own description names its whole loop
        // (controller, gyro, base motion), which the plant FMU does not hold.
        desc = xml_escape(&format!(
            "Cable-drive gimbal plant of scenario {}: motor ({} amplifier), capstan cable drive, output drum, loads and encoders; the host closes the loop",
            scenario.name(),
            match amp {
                Amplifier::Current => "current",
                Amplifier::Voltage => "voltage",
            }
        )),
        ver = env!("CARGO_PKG_VERSION"),
    );
    let _ = writeln!(
        x,
        r#"  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" needsExecutionTool="false" canHandleVariableCommunicationStepSize="true" canInterpolateInputs="false" maxOutputDerivativeOrder="0" canRunAsynchronuously="false" canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="true" canGetAndSetFMUstate="true" canSerializeFMUstate="false" providesDirectionalDerivative="false"/>"#
    );
    let mut units: Vec<&str> = vars
        .iter()
        .map(|v| v.unit)
        .filter(|u| !u.is_empty())
        .collect();
    units.sort_unstable();
    units.dedup();
    let _ = writeln!(x, "  <UnitDefinitions>");
    for u in units {
        let [kg, m, s, a, rad] = base_unit(u);
        let mut attrs = String::new();
        for (name, e) in [("kg", kg), ("m", m), ("s", s), ("A", a), ("rad", rad)] {
            if e != 0 {
                let _ = write!(attrs, r#" {name}="{e}""#);
            }
        }
        let _ = writeln!(
            x,
            r#"    <Unit name="{}"><BaseUnit{attrs}/></Unit>"#,
            xml_escape(u)
        );
    }
    let _ = writeln!(x, "  </UnitDefinitions>");
    let _ = writeln!(x, "  <LogCategories>");
    for (name, desc) in LOG_CATEGORIES {
        let _ = writeln!(
            x,
            r#"    <Category name="{name}" description="{}"/>"#,
            xml_escape(desc)
        );
    }
    let _ = writeln!(x, "  </LogCategories>");
    let _ = writeln!(
        x,
        r#"  <DefaultExperiment startTime="0.0" stopTime="{:?}" stepSize="{:?}"/>"#,
        cl.duration_s,
        1.0 / cl.controller.sample_rate_hz
    );
    let _ = writeln!(x, "  <ModelVariables>");
    for (i, v) in vars.iter().enumerate() {
        let (causality, variability, initial) = match (v.causality, v.kind) {
            (Causality::Parameter, _) => ("parameter", "fixed", Some("exact")),
            (Causality::Input, _) => ("input", "continuous", None),
            (Causality::Output, Kind::Real) => ("output", "continuous", None),
            (Causality::Output, _) => ("output", "discrete", None),
        };
        let _ = writeln!(x, r#"    <!-- index {} -->"#, i + 1);
        let _ = writeln!(
            x,
            r#"    <ScalarVariable name="{}" valueReference="{}" description="{}" causality="{causality}" variability="{variability}"{}>"#,
            xml_escape(v.name),
            v.vr,
            xml_escape(v.description),
            initial.map_or(String::new(), |s| format!(r#" initial="{s}""#)),
        );
        let mut attrs = String::new();
        if v.causality != Causality::Output {
            let _ = write!(attrs, r#" start="{}""#, start_text(v, values));
        }
        if !v.unit.is_empty() {
            let _ = write!(attrs, r#" unit="{}""#, xml_escape(v.unit));
        }
        if v.causality == Causality::Parameter && v.kind != Kind::Boolean {
            let (lo, hi) = v.range.xml_bounds();
            let fmt = |b: f64| match v.kind {
                Kind::Integer => format!("{}", b as i64),
                _ => format!("{b:?}"),
            };
            if let Some(lo) = lo {
                let _ = write!(attrs, r#" min="{}""#, fmt(lo));
            }
            if let Some(hi) = hi {
                let _ = write!(attrs, r#" max="{}""#, fmt(hi));
            }
        }
        let _ = writeln!(x, "      <{}{attrs}/>", v.kind.xml());
        let _ = writeln!(x, "    </ScalarVariable>");
    }
    let _ = writeln!(x, "  </ModelVariables>");
    let _ = writeln!(x, "  <ModelStructure>");
    let outputs: Vec<usize> = vars
        .iter()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Output)
        .map(|(i, _)| i + 1)
        .collect();
    // No output depends directly on an input: a held command acts through the step.
    let _ = writeln!(x, "    <Outputs>");
    for i in &outputs {
        let _ = writeln!(x, r#"      <Unknown index="{i}" dependencies=""/>"#);
    }
    let _ = writeln!(x, "    </Outputs>");
    let _ = writeln!(x, "    <InitialUnknowns>");
    for i in &outputs {
        let _ = writeln!(x, r#"      <Unknown index="{i}"/>"#);
    }
    let _ = writeln!(x, "    </InitialUnknowns>");
    let _ = writeln!(x, "  </ModelStructure>");
    let _ = writeln!(x, "</fmiModelDescription>");
    x
}

/// documentation/variables.csv: one row per variable.
pub fn variables_csv(values: &Values) -> String {
    let amp = values.params.closed_loop.motor.amplifier;
    let mut s =
        String::from("value_reference,name,causality,type,unit,start,allowed,description\n");
    for v in declared(amp) {
        let start = if v.causality == Causality::Output {
            String::new()
        } else {
            start_text(v, values)
        };
        let allowed = if v.causality == Causality::Parameter {
            v.range.allowed()
        } else {
            String::new()
        };
        let causality = match v.causality {
            Causality::Parameter => "parameter",
            Causality::Input => "input",
            Causality::Output => "output",
        };
        let _ = writeln!(
            s,
            "{},{},{causality},{},{},{start},\"{allowed}\",\"{}\"",
            v.vr,
            v.name,
            v.kind.xml(),
            v.unit,
            v.description.replace('"', "'")
        );
    }
    s
}

/// documentation/index.html: what the FMU does, and its variables with units.
pub fn documentation(scenario: &Scenario, values: &Values) -> String {
    let amp = values.params.closed_loop.motor.amplifier;
    let mut h = String::new();
    let _ = writeln!(
        h,
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>cable_servo FMU: {name}</title></head><body>\n<h1>Cable-drive gimbal plant: scenario {name}</h1>",
        name = xml_escape(scenario.name())
    );
    let _ = writeln!(
        h,
        "<p>FMI 2.0 Co-Simulation FMU exported by cable-servo {}. The plant: a torque motor with a {} amplifier, a preloaded capstan cable drive (with load-history memory, memoryless or linear: parameter <code>cable.model</code>), the output drum with its inertia, powder brake (stick/slip), unbalance and external torques, and both encoders. The host closes the loop: it reads the encoders and sets the motor command.</p>",
        env!("CARGO_PKG_VERSION"),
        match amp {
            Amplifier::Current => "current",
            Amplifier::Voltage => "voltage",
        }
    );
    h.push_str(
        "<ul>\n\
<li><b>Stepping.</b> <code>fmi2DoStep</code> integrates with the inputs held (fixed-step RK4, steps of at most <code>solver.max_step_s</code>, the integrator restarted at every step) and commits the cable's wrap memory at the step's end. A step equal to the controller period reproduces the project's own sample-and-hold loop.</li>\n\
<li><b>Parameters</b> start at the scenario's values (resources/scenario.toml); values set by the host before <code>fmi2ExitInitializationMode</code> override them and are checked there: a bad one returns fmi2Error with the parameter, its value and the allowed range, and the instance stays in initialization mode.</li>\n\
<li><b>Faults.</b> A slack span or gross slip on the pulley ends the step with fmi2Discard, the time and the cause logged; outputs hold the last good communication point, <code>regime</code> says which fault (2 slack, 3 gross slip), <code>fmi2GetBooleanStatus(fmi2Terminated)</code> is true. Bad calls (order, step size, value) return fmi2Error with a message and change nothing; a fault inside the library returns fmi2Error and never reaches the host as a crash.</li>\n\
<li><b>Saved states.</b> <code>fmi2GetFMUstate</code>/<code>fmi2SetFMUstate</code> copy the whole state, cable memory included; serialisation is not supported.</li>\n\
<li><b>Base motion.</b> A base angular rate input (the carrier turning under the drum) is reserved as value reference 4, <code>base_rate_rad_s</code>; the FMU does not take it yet (the native simulation models base motion: <code>closed_loop.base_motion</code>).</li>\n\
</ul>\n",
    );
    let _ = writeln!(
        h,
        "<table border=\"1\" cellpadding=\"3\"><tr><th>vr</th><th>name</th><th>causality</th><th>type</th><th>unit</th><th>start</th><th>allowed</th><th>description</th></tr>"
    );
    for v in declared(amp) {
        let (causality, start, allowed) = match v.causality {
            Causality::Parameter => ("parameter", start_text(v, values), v.range.allowed()),
            Causality::Input => ("input", start_text(v, values), String::new()),
            Causality::Output => ("output", String::new(), String::new()),
        };
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td><code>{}</code></td><td>{causality}</td><td>{}</td><td>{}</td><td>{start}</td><td>{}</td><td>{}</td></tr>",
            v.vr,
            xml_escape(v.name),
            v.kind.xml(),
            xml_escape(v.unit),
            xml_escape(&allowed),
            xml_escape(v.description)
        );
    }
    h.push_str("</table>\n<p>The same list as CSV: <a href=\"variables.csv\">variables.csv</a>.</p>\n</body></html>\n");
    h
}

/// Writes the FMU of `scenario`'s plant to `out` with the shared library `library`.
/// Nothing is written unless the whole archive is; an existing file is replaced only with
/// `force`.
pub fn export_fmu(
    scenario: &Scenario,
    library: &Path,
    out: &Path,
    force: bool,
) -> Result<ExportReport, ExportError> {
    if !(cfg!(target_os = "linux") && cfg!(target_arch = "x86_64")) {
        return Err(ExportError::Platform);
    }
    plant_params(scenario).map_err(ExportError::Scenario)?;
    let text = scenario.to_toml();
    // The library reads the defaults back from this text: it must give the same scenario.
    let reread = Scenario::from_toml(&text, "resources/scenario.toml", scenario.name(), &[])
        .map_err(|e| {
            ExportError::Scenario(format!("the resolved scenario does not read back: {e}"))
        })?;
    let instance = Instance::new(&reread).map_err(ExportError::Scenario)?;
    instance.check_defaults().map_err(|m| {
        ExportError::Scenario(format!("the scenario's plant cannot run as an FMU: {m}"))
    })?;
    if out.exists() && !force {
        return Err(ExportError::Exists(out.to_path_buf()));
    }
    if library.is_dir() {
        return Err(ExportError::NotALibrary {
            path: library.to_path_buf(),
            why: "a directory, not a file".into(),
        });
    }
    let lib = std::fs::read(library).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => ExportError::NoLibrary(library.to_path_buf()),
        _ => ExportError::Io {
            path: library.to_path_buf(),
            source: e,
        },
    })?;
    if let Some(why) = not_a_shared_library(&lib) {
        return Err(ExportError::NotALibrary {
            path: library.to_path_buf(),
            why,
        });
    }
    let id = guid(&text);
    let values = Values {
        params: instance.params().clone(),
        inputs: Default::default(),
        outputs: Default::default(),
    };
    let entries = [
        Entry {
            name: "modelDescription.xml".into(),
            data: model_description(&reread, &values, &id).into_bytes(),
            executable: false,
        },
        Entry {
            name: format!("binaries/linux64/{MODEL_IDENTIFIER}.so"),
            data: lib,
            executable: true,
        },
        Entry {
            name: format!("resources/{SCENARIO_RESOURCE}"),
            data: text.into_bytes(),
            executable: false,
        },
        Entry {
            name: "documentation/index.html".into(),
            data: documentation(&reread, &values).into_bytes(),
            executable: false,
        },
        Entry {
            name: "documentation/variables.csv".into(),
            data: variables_csv(&values).into_bytes(),
            executable: false,
        },
    ];
    let bytes = store(&entries).ok_or_else(|| ExportError::Io {
        path: out.to_path_buf(),
        source: std::io::Error::other("the archive passes the 4 GiB limit of zip"),
    })?;
    // Written as every result is: whole or not at all, with the umask's permissions.
    crate::io::output::write_atomic(out, &bytes).map_err(|e| ExportError::Io {
        path: out.to_path_buf(),
        source: std::io::Error::other(e.to_string()),
    })?;
    Ok(ExportReport {
        path: out.to_path_buf(),
        guid: id,
        variables: declared(values.params.closed_loop.motor.amplifier).len(),
        bytes: bytes.len(),
    })
}
