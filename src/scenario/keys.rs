//! The keys a scenario file accepts, read from the parser itself.
//!
//! Nothing here lists keys by hand: the strict parser (serde with `deny_unknown_fields`)
//! already knows them, and says so when refusing a key it does not know ("unknown field
//! `x`, expected one of `a`, `b`"). [`accepted_keys`] offers each table a key no struct
//! has and reads the refusal, then does the same below every key it learnt, so the list
//! cannot drift from what `Scenario::load` accepts.

use serde::Deserialize;

use super::Scenario;

/// A key no scenario struct has: its refusal lists the keys the table accepts.
const PROBE: &str = "\u{1}probe";

/// One step of a path: a key of a table, an element of an array of tables, or the
/// `kind` a tagged table must carry for the parser to read its other keys.
#[derive(Clone, Debug)]
enum Step {
    Key(String),
    Element,
    Kind(String),
}

/// What the parser says about a table put at some path.
enum Answer {
    /// A struct: the keys it accepts.
    Keys(Vec<String>),
    /// A table tagged by `kind` (a signal, a filter): needs the tag first.
    Tagged,
    /// An array: look at an element.
    Array,
    /// Anything else (a number, a string, a name, an array of numbers).
    Leaf,
}

/// Every key a scenario accepts, as dotted paths from the top of the file, sorted.
///
/// An array of tables is written `name[]` (`closed_loop.controller.command_filters[].kind`,
/// `sweep.parameters[].key`); a table tagged by `kind` lists the keys of every kind under
/// one path (`closed_loop.reference.amplitude_rad` is accepted by the `sine`, `step`,
/// `step_stare` and `triangle` references). A tagged table nested in a table of the same
/// kinds (a `sum` signal's `parts`) is listed by its key alone
/// (`closed_loop.reference.parts`): its elements accept the same keys again.
pub fn accepted_keys() -> Vec<String> {
    let mut keys = Vec::new();
    explore(&[], &mut Vec::new(), &mut keys);
    keys.sort();
    keys.dedup();
    keys
}

/// The dotted form of a path (`a.b[].c`).
fn dotted(path: &[Step]) -> String {
    let mut s = String::new();
    for step in path {
        match step {
            Step::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Step::Element => s.push_str("[]"),
            Step::Kind(_) => {}
        }
    }
    s
}

/// The scenario table with `leaf` put at `path`.
fn nest(path: &[Step], leaf: toml::Value) -> toml::Value {
    path.iter().rev().fold(leaf, |inner, step| match step {
        Step::Key(k) => {
            let mut t = toml::Table::new();
            t.insert(k.clone(), inner);
            toml::Value::Table(t)
        }
        Step::Element => toml::Value::Array(vec![inner]),
        Step::Kind(kind) => match inner {
            toml::Value::Table(mut t) => {
                t.insert("kind".into(), toml::Value::String(kind.clone()));
                toml::Value::Table(t)
            }
            other => other,
        },
    })
}

/// The backquoted names after `after` in a serde message (`expected one of `a`, `b``).
fn quoted_after(message: &str, after: &str) -> Option<Vec<String>> {
    let rest = message.split(after).nth(1)?;
    let rest = rest.lines().next().unwrap_or(rest);
    Some(
        rest.split('`')
            .skip(1)
            .step_by(2)
            .map(str::to_string)
            .collect(),
    )
}

/// The parser's message for the scenario holding `value` at `path`; `None` if accepted.
fn refusal(path: &[Step], value: toml::Value) -> Option<String> {
    Scenario::deserialize(nest(path, value))
        .err()
        .map(|e| e.message().to_string())
}

/// What the parser answers for a table holding only the probe key at `path`.
fn ask(path: &[Step]) -> Answer {
    let mut table = toml::Table::new();
    table.insert(PROBE.to_string(), toml::Value::Integer(0));
    let Some(message) = refusal(path, toml::Value::Table(table)) else {
        return Answer::Leaf;
    };
    if message.contains(&format!("unknown field `{PROBE}`")) {
        if message.contains("there are no fields") {
            return Answer::Keys(Vec::new());
        }
        if let Some(keys) = quoted_after(&message, ", expected") {
            return Answer::Keys(keys);
        }
    }
    if message.contains("missing field `kind`") {
        return Answer::Tagged;
    }
    if message.contains("expected a sequence") || message.contains("expected an array") {
        return Answer::Array;
    }
    Answer::Leaf
}

/// The kinds a tagged table at `path` accepts.
fn kinds(path: &[Step]) -> Vec<String> {
    let mut table = toml::Table::new();
    table.insert("kind".into(), toml::Value::String(PROBE.into()));
    refusal(path, toml::Value::Table(table))
        .and_then(|m| quoted_after(&m, ", expected"))
        .unwrap_or_default()
}

/// Adds the keys at and below `path`; `tagged` holds the kinds of the tagged tables
/// above, to stop where one nests a table of its own kinds.
fn explore(path: &[Step], tagged: &mut Vec<Vec<String>>, keys: &mut Vec<String>) {
    match ask(path) {
        Answer::Keys(fields) => {
            for f in fields {
                let mut p = path.to_vec();
                p.push(Step::Key(f));
                explore(&p, tagged, keys);
            }
        }
        Answer::Tagged => {
            let names = kinds(path);
            if tagged.contains(&names) {
                let outer = match path.last() {
                    Some(Step::Element) => &path[..path.len() - 1],
                    _ => path,
                };
                keys.push(dotted(outer));
                return;
            }
            let mut kind_key = path.to_vec();
            kind_key.push(Step::Key("kind".into()));
            keys.push(dotted(&kind_key));
            tagged.push(names.clone());
            for kind in names {
                let mut p = path.to_vec();
                p.push(Step::Kind(kind));
                explore(&p, tagged, keys);
            }
            tagged.pop();
        }
        Answer::Array => {
            let mut p = path.to_vec();
            p.push(Step::Element);
            match ask(&p) {
                Answer::Keys(_) | Answer::Tagged => explore(&p, tagged, keys),
                Answer::Array | Answer::Leaf => keys.push(dotted(path)),
            }
        }
        Answer::Leaf => keys.push(dotted(path)),
    }
}
