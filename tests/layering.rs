//! The module structure, enforced: every `crate::` path in `src/` must point to the same
//! module, a lower layer, or one of the few same-layer arrows listed here. A new upward
//! import or a circle fails this test with the file and line.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// Layers from the bottom up. A module may use every module of a lower layer.
const LAYERS: &[(&str, &[&str])] = &[
    // Physics and the plain data and numerics everything else builds on.
    (
        "bottom",
        &[
            "number",
            "NOT_A_NUMBER",
            "compact",
            "long_numbers_compacted",
            "significant",
            "readable",
            "fixed",
            "fixed_or_significant",
            "out_of_range",
            "duration_words",
            "physics",
            "signal",
            "stats",
            "metrics",
            "measurement",
            "progress",
        ],
    ),
    // Computation over parameter structs, returning result records.
    (
        "computation",
        &["closed_loop", "analysis", "study", "identify", "sweep"],
    ),
    // Scenario files, logs and tables, figures, result files.
    ("edge", &["scenario", "io", "plot", "report"]),
    // Orchestration and the command line.
    ("top", &["run", "design", "fmu"]),
];

/// Arrows allowed between modules of the same layer (importer, imported). Anything not
/// listed here, within a layer, is refused, which also rules out circles.
const SAME_LAYER: &[(&str, &str)] = &[
    ("physics", "number"),
    ("physics", "fixed"),
    ("physics", "fixed_or_significant"),
    ("physics", "out_of_range"),
    ("signal", "out_of_range"),
    ("signal", "number"),
    ("metrics", "number"),
    ("analysis", "closed_loop"),
    ("identify", "study"),
    ("sweep", "study"),
    ("io", "scenario"),
    ("report", "io"),
    ("report", "plot"),
    ("report", "scenario"),
    ("design", "run"),
    ("fmu", "run"),
];

fn layer_of(module: &str) -> Option<usize> {
    LAYERS.iter().position(|(_, mods)| mods.contains(&module))
}

/// Top-level module a source file belongs to (`src/closed_loop/sim.rs` -> `closed_loop`).
fn module_of(src: &Path, file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src).ok()?;
    let first = rel.components().next()?.as_os_str().to_str()?;
    Some(first.trim_end_matches(".rs").to_string())
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// `crate::NAME` paths of a line, comments removed; `crate::{a, b}` groups are expanded.
fn crate_paths(line: &str) -> Vec<String> {
    let code = line.split("//").next().unwrap_or("");
    let mut found = Vec::new();
    let mut rest = code;
    while let Some(i) = rest.find("crate::") {
        // `cable_servo::` or an identifier ending in `crate` is not the path keyword.
        let before = rest[..i].chars().last();
        rest = &rest[i + "crate::".len()..];
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        if let Some(group) = rest.strip_prefix('{') {
            let inner = group.split('}').next().unwrap_or("");
            found.extend(
                inner
                    .split(',')
                    .map(|p| p.trim().split("::").next().unwrap_or("").to_string())
                    .filter(|p| !p.is_empty()),
            );
        } else {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            found.push(name);
        }
    }
    found
}

/// Every arrow of the crate: (importer, imported) -> first place seen.
fn arrows(src: &Path) -> BTreeMap<(String, String), String> {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    files.sort();
    let mut out = BTreeMap::new();
    for file in files {
        let Some(from) = module_of(src, &file) else {
            continue;
        };
        if from == "lib" || from == "main" {
            // The crate root declares the modules; the binary sees only the public API.
            continue;
        }
        let text = std::fs::read_to_string(&file).unwrap();
        for (n, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("//") {
                continue;
            }
            for to in crate_paths(line) {
                if to != from {
                    out.entry((from.clone(), to))
                        .or_insert_with(|| format!("{}:{}", file.display(), n + 1));
                }
            }
        }
    }
    out
}

fn violations(arrows: &BTreeMap<(String, String), String>) -> Vec<String> {
    let mut bad = Vec::new();
    for ((from, to), place) in arrows {
        let (Some(lf), Some(lt)) = (layer_of(from), layer_of(to)) else {
            bad.push(format!(
                "{place}: {from} -> {to}: a module missing from the LAYERS table of tests/layering.rs"
            ));
            continue;
        };
        let ok = lt < lf || (lt == lf && SAME_LAYER.contains(&(from.as_str(), to.as_str())));
        if !ok {
            bad.push(format!(
                "{place}: {from} ({}) imports {to} ({}): imports must point down",
                LAYERS[lf].0, LAYERS[lt].0
            ));
        }
    }
    bad
}

#[test]
fn imports_point_down() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let found = arrows(&src);
    assert!(found.len() > 20, "too few arrows found: {found:?}");
    let bad = violations(&found);
    assert!(
        bad.is_empty(),
        "upward or sideways imports:\n{}",
        bad.join("\n")
    );
}

#[test]
fn same_layer_arrows_form_no_circle() {
    // Depth-first search over the allowed same-layer arrows.
    let mut graph: BTreeMap<&str, BTreeSet<&str>> = BTreeMap::new();
    for (a, b) in SAME_LAYER {
        graph.entry(a).or_default().insert(b);
    }
    fn visit<'a>(
        n: &'a str,
        graph: &BTreeMap<&'a str, BTreeSet<&'a str>>,
        stack: &mut Vec<&'a str>,
    ) -> Result<(), String> {
        if stack.contains(&n) {
            return Err(format!("{} -> {n}", stack.join(" -> ")));
        }
        stack.push(n);
        for m in graph.get(n).into_iter().flatten() {
            visit(m, graph, stack)?;
        }
        stack.pop();
        Ok(())
    }
    for n in graph.keys() {
        visit(n, &graph, &mut Vec::new()).unwrap();
    }
}

#[test]
fn an_upward_import_is_caught() {
    let mut found = BTreeMap::new();
    found.insert(
        ("physics".to_string(), "plot".to_string()),
        "src/physics/drive.rs:1".to_string(),
    );
    found.insert(
        ("closed_loop".to_string(), "scenario".to_string()),
        "src/closed_loop/sim.rs:1".to_string(),
    );
    found.insert(
        ("report".to_string(), "plot".to_string()),
        "src/report/mod.rs:1".to_string(),
    );
    found.insert(
        ("plot".to_string(), "report".to_string()),
        "src/plot/mod.rs:1".to_string(),
    );
    let bad = violations(&found);
    assert_eq!(bad.len(), 3, "{bad:?}");
    assert!(bad
        .iter()
        .any(|b| b.contains("physics (bottom) imports plot (edge)")));
    assert!(bad
        .iter()
        .any(|b| b.contains("plot (edge) imports report (edge)")));
    assert_eq!(
        crate_paths("use crate::{physics::X, signal::Signal}; // crate::plot"),
        vec!["physics", "signal"]
    );
    assert!(crate_paths("use cable_servo::scenario::Scenario;").is_empty());
}

/// Sibling files of a room that `file` imports: `super::NAME` and
/// `crate::ROOM::NAME`, test modules and comments left out.
fn sibling_imports(room: &str, file: &Path, siblings: &BTreeSet<String>) -> BTreeSet<String> {
    let text = std::fs::read_to_string(file).unwrap();
    let code = text.split("#[cfg(test)]").next().unwrap_or("");
    let mut out = BTreeSet::new();
    for line in code.lines() {
        let line = line.split("//").next().unwrap_or("");
        for prefix in ["super::".to_string(), format!("crate::{room}::")] {
            let mut rest = line;
            while let Some(i) = rest.find(&prefix) {
                rest = &rest[i + prefix.len()..];
                let name: String = rest
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if siblings.contains(&name) {
                    out.insert(name);
                }
            }
        }
    }
    out
}

/// Inside the rooms of the loop, no file imports one that imports it back (directly or
/// round a longer circle): the simulated loop and its parameters below, the analysis of a
/// loop above them.
#[test]
fn no_file_circle_in_the_loop_rooms() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    for room in ["closed_loop", "analysis"] {
        let dir = src.join(room);
        let mut files = Vec::new();
        rust_files(&dir, &mut files);
        let name = |p: &Path| p.file_stem().unwrap().to_string_lossy().into_owned();
        let siblings: BTreeSet<String> = files
            .iter()
            .map(|f| name(f))
            .filter(|n| n != "mod")
            .collect();
        let edges: BTreeMap<String, BTreeSet<String>> = files
            .iter()
            .filter(|f| name(f) != "mod")
            .map(|f| (name(f), sibling_imports(room, f, &siblings)))
            .map(|(n, mut e)| {
                e.remove(&n);
                (n, e)
            })
            .collect();
        // Depth-first search for a back edge.
        fn visit(
            n: &str,
            edges: &BTreeMap<String, BTreeSet<String>>,
            path: &mut Vec<String>,
            done: &mut BTreeSet<String>,
        ) -> Option<Vec<String>> {
            if let Some(i) = path.iter().position(|p| p == n) {
                let mut circle = path[i..].to_vec();
                circle.push(n.to_string());
                return Some(circle);
            }
            if done.contains(n) {
                return None;
            }
            path.push(n.to_string());
            for m in edges.get(n).into_iter().flatten() {
                if let Some(c) = visit(m, edges, path, done) {
                    return Some(c);
                }
            }
            path.pop();
            done.insert(n.to_string());
            None
        }
        let mut done = BTreeSet::new();
        for n in edges.keys() {
            if let Some(circle) = visit(n, &edges, &mut Vec::new(), &mut done) {
                panic!("src/{room}: a file circle: {}", circle.join(" -> "));
            }
        }
        assert!(edges.len() >= 3, "{room}: {edges:?}");
    }
}
