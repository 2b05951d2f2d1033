//! `docs/keys.md`, the reference of every scenario key, is generated here from the source
//! and checked against the parser.
//!
//! The text comes from the parameter structs themselves: a small reader goes over the
//! `.rs` files under `src/`, keeps every struct and enum that derives `Deserialize`, and
//! walks them from `Scenario` down. A field's meaning is its `///` comment; its unit
//! follows from the key's suffix (`_hz`, `_nm`, `_rad_s`, ...) or a `Unit:` line in the
//! comment; its allowed range is an `Allowed:` line in the comment (the validation's
//! bounds, written where the field is); its default is read from the code (`#[serde(default
//! = "f")]` and the body of `f`, the struct's `impl Default` when the struct defaults as a
//! whole, the type's own default for a bare `#[serde(default)]`).
//!
//! The test fails when `docs/keys.md` differs from the generated text (regenerate with
//! `UPDATE_KEYS=1 cargo test --test keys_reference`), and when the keys documented differ
//! from `cable_servo::scenario::accepted_keys()`, which asks the strict parser itself.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// One field of a struct or of a struct variant.
#[derive(Clone, Debug)]
struct Field {
    name: String,
    ty: String,
    docs: Vec<String>,
    /// The contents of each `#[serde(...)]` on the field.
    serde: Vec<String>,
}

#[derive(Clone, Debug)]
struct Variant {
    name: String,
    docs: Vec<String>,
    fields: Vec<Field>,
    is_default: bool,
}

#[derive(Clone, Debug)]
enum Def {
    Struct {
        docs: Vec<String>,
        fields: Vec<Field>,
        /// `#[serde(default)]` on the struct: absent fields take its `impl Default`.
        whole_default: bool,
    },
    Enum {
        docs: Vec<String>,
        /// `Some("kind")` for a table tagged by `kind`.
        tag: Option<String>,
        variants: Vec<Variant>,
    },
}

/// Everything read from the source.
#[derive(Default)]
struct Source {
    defs: BTreeMap<String, Def>,
    /// Bodies of `fn name() -> T { body }` (default functions), by name.
    fns: BTreeMap<String, String>,
    /// `impl Default for T`: the expression of each field, by type then field.
    defaults: BTreeMap<String, BTreeMap<String, String>>,
}

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .expect("src/ readable")
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

fn indent(line: &str) -> usize {
    line.len() - line.trim_start().len()
}

/// Text of a doc line without `///` and one space.
fn doc_text(line: &str) -> String {
    let t = line.trim_start().trim_start_matches("///");
    t.strip_prefix(' ').unwrap_or(t).to_string()
}

/// The attribute starting at `lines[*i]`, joined over lines until its brackets close.
fn attribute(lines: &[&str], i: &mut usize) -> String {
    let mut text = String::new();
    loop {
        text.push_str(lines[*i].trim());
        let open = text.matches('[').count();
        let close = text.matches(']').count();
        if open <= close || *i + 1 >= lines.len() {
            return text;
        }
        *i += 1;
    }
}

/// The serde attribute's contents (`default = "f"`), if `attr` is `#[serde(...)]`.
fn serde_args(attr: &str) -> Option<String> {
    attr.strip_prefix("#[serde(")
        .and_then(|a| a.strip_suffix(")]"))
        .map(str::to_string)
}

/// Fields of a struct body (or struct variant) from `lines[*i]` until the line at
/// `close_indent` that closes it.
fn fields(lines: &[&str], i: &mut usize, close_indent: usize, public: bool) -> Vec<Field> {
    let mut out = Vec::new();
    let mut docs = Vec::new();
    let mut serde = Vec::new();
    while *i < lines.len() {
        let line = lines[*i];
        let t = line.trim();
        if indent(line) == close_indent && t.starts_with('}') {
            break;
        }
        if t.starts_with("///") {
            docs.push(doc_text(line));
        } else if t.starts_with("#[") {
            let a = attribute(lines, i);
            if let Some(s) = serde_args(&a) {
                serde.push(s);
            }
        } else if !t.is_empty() && !t.starts_with("//") {
            let body = if public {
                t.strip_prefix("pub ").unwrap_or(t)
            } else {
                t
            };
            let mut decl = body.to_string();
            while !decl.ends_with(',') && *i + 1 < lines.len() {
                let next = lines[*i + 1];
                if indent(next) <= close_indent {
                    break;
                }
                *i += 1;
                decl.push_str(next.trim());
            }
            if let Some((name, ty)) = decl.split_once(':') {
                out.push(Field {
                    name: name.trim().to_string(),
                    ty: ty.trim().trim_end_matches(',').trim().to_string(),
                    docs: std::mem::take(&mut docs),
                    serde: std::mem::take(&mut serde),
                });
            }
            docs.clear();
            serde.clear();
        }
        *i += 1;
    }
    out
}

/// Variants of an enum body.
fn variants(lines: &[&str], i: &mut usize) -> Vec<Variant> {
    let mut out = Vec::new();
    let mut docs = Vec::new();
    let mut is_default = false;
    while *i < lines.len() {
        let line = lines[*i];
        let t = line.trim();
        if indent(line) == 0 && t.starts_with('}') {
            break;
        }
        if t.starts_with("///") {
            docs.push(doc_text(line));
        } else if t.starts_with("#[") {
            let a = attribute(lines, i);
            is_default |= a == "#[default]";
        } else if !t.is_empty() && !t.starts_with("//") {
            let name: String = t
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            let mut fs = Vec::new();
            if t.ends_with('{') {
                *i += 1;
                fs = fields(lines, i, indent(line), false);
            }
            out.push(Variant {
                name,
                docs: std::mem::take(&mut docs),
                fields: fs,
                is_default,
            });
            is_default = false;
        }
        *i += 1;
    }
    out
}

/// The name after `keyword` on a declaration line (`pub struct Name {`).
fn declared(t: &str, keyword: &str) -> Option<String> {
    let rest = t.strip_prefix(keyword)?;
    Some(
        rest.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect(),
    )
}

/// The body of the block opened on `lines[*i]`, joined, up to its closing line at the
/// same indentation.
fn block(lines: &[&str], i: &mut usize) -> Vec<String> {
    let start = indent(lines[*i]);
    let mut body = Vec::new();
    *i += 1;
    while *i < lines.len() && !(indent(lines[*i]) == start && lines[*i].trim().starts_with('}')) {
        body.push(lines[*i].trim().to_string());
        *i += 1;
    }
    body
}

/// `field: expr,` entries of a struct literal (one level), expressions joined over lines.
fn literal_fields(body: &[String]) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    let mut current: Option<(String, String)> = None;
    let mut depth = 0i32;
    for line in body {
        if depth == 0 {
            if let Some((k, v)) = current.take() {
                out.insert(k, v.trim_end_matches(',').trim().to_string());
            }
            if let Some((k, v)) = line.split_once(':') {
                if k.chars().all(|c| c.is_alphanumeric() || c == '_') && !k.is_empty() {
                    current = Some((k.to_string(), v.trim().to_string()));
                    depth = bracket_depth(v);
                    continue;
                }
            }
        } else if let Some((_, v)) = current.as_mut() {
            v.push(' ');
            v.push_str(line);
            depth += bracket_depth(line);
        }
    }
    if let Some((k, v)) = current {
        out.insert(k, v.trim_end_matches(',').trim().to_string());
    }
    out
}

fn bracket_depth(s: &str) -> i32 {
    s.chars()
        .map(|c| match c {
            '(' | '[' | '{' => 1,
            ')' | ']' | '}' => -1,
            _ => 0,
        })
        .sum()
}

fn read_source() -> Source {
    let mut files = Vec::new();
    rust_files(&repo().join("src"), &mut files);
    let mut src = Source::default();
    for f in files {
        let text = std::fs::read_to_string(&f).expect("source file");
        let lines: Vec<&str> = text.lines().collect();
        let mut docs: Vec<String> = Vec::new();
        let mut attrs: Vec<String> = Vec::new();
        let mut i = 0;
        while i < lines.len() {
            let line = lines[i];
            let t = line.trim();
            if indent(line) != 0 {
                i += 1;
                continue;
            }
            if t.starts_with("///") {
                docs.push(doc_text(line));
            } else if t.starts_with("#[") {
                attrs.push(attribute(&lines, &mut i));
            } else {
                let deser = attrs
                    .iter()
                    .any(|a| a.starts_with("#[derive(") && a.contains("Deserialize"));
                let serde: Vec<String> = attrs.iter().filter_map(|a| serde_args(a)).collect();
                if let (Some(name), true) = (declared(t, "pub struct "), deser) {
                    if t.ends_with('{') {
                        i += 1;
                        let fs = fields(&lines, &mut i, 0, true);
                        let whole_default = serde
                            .iter()
                            .any(|s| s.split(',').any(|p| p.trim() == "default"));
                        src.defs.entry(name).or_insert(Def::Struct {
                            docs: docs.clone(),
                            fields: fs,
                            whole_default,
                        });
                    }
                } else if let (Some(name), true) = (declared(t, "pub enum "), deser) {
                    i += 1;
                    let vs = variants(&lines, &mut i);
                    let tag = serde.iter().find_map(|s| {
                        s.split(',')
                            .find_map(|p| p.trim().strip_prefix("tag = "))
                            .map(|v| v.trim_matches('"').to_string())
                    });
                    src.defs.entry(name).or_insert(Def::Enum {
                        docs: docs.clone(),
                        tag,
                        variants: vs,
                    });
                } else if let Some(name) = declared(t, "fn ") {
                    if t.ends_with('{') && !t.contains("(&") && t.contains("() ->") {
                        let body = block(&lines, &mut i);
                        src.fns.entry(name).or_insert(body.join(" "));
                    }
                } else if let Some(ty) = declared(t, "impl Default for ") {
                    let body = block(&lines, &mut i);
                    // The struct literal inside `fn default() -> Self { Type { ... } }`.
                    let start = body
                        .iter()
                        .position(|l| l.ends_with('{') && !l.starts_with("fn "));
                    if let Some(s) = start {
                        src.defaults.insert(ty, literal_fields(&body[s + 1..]));
                    }
                }
                docs.clear();
                attrs.clear();
            }
            i += 1;
        }
    }
    src
}

/// `CamelCase` as `snake_case`.
fn snake(name: &str) -> String {
    let mut s = String::new();
    for (k, c) in name.chars().enumerate() {
        if c.is_uppercase() {
            if k > 0 {
                s.push('_');
            }
            s.extend(c.to_lowercase());
        } else {
            s.push(c);
        }
    }
    s
}

/// The type inside a wrapper (`Option<T>` gives `T`).
fn inner<'a>(ty: &'a str, wrapper: &str) -> Option<&'a str> {
    ty.strip_prefix(wrapper)
        .and_then(|r| r.strip_prefix('<'))
        .and_then(|r| r.strip_suffix('>'))
}

/// The last segment of a path type (`super::probe::FreqRespParams`).
fn base_name(ty: &str) -> &str {
    ty.rsplit("::").next().unwrap_or(ty)
}

/// What a field's type is, for the reference.
enum Shape<'a> {
    Struct(&'a str),
    Tagged(&'a str),
    ArrayOfStruct(&'a str),
    ArrayOfTagged(&'a str),
    /// A number, string, name or array of those; the names when the type is an enum.
    Leaf(Option<Vec<String>>),
}

fn shape<'a>(src: &Source, ty: &'a str) -> Shape<'a> {
    let ty = inner(ty, "Option").unwrap_or(ty);
    if let Some(e) = inner(ty, "Vec") {
        return match shape(src, e) {
            Shape::Struct(n) => Shape::ArrayOfStruct(n),
            Shape::Tagged(n) => Shape::ArrayOfTagged(n),
            other => other,
        };
    }
    let name = base_name(ty);
    match src.defs.get(name) {
        Some(Def::Struct { .. }) => Shape::Struct(name),
        Some(Def::Enum { tag: Some(_), .. }) => Shape::Tagged(name),
        Some(Def::Enum { variants, .. }) => {
            Shape::Leaf(Some(variants.iter().map(|v| snake(&v.name)).collect()))
        }
        None => Shape::Leaf(None),
    }
}

/// A key's unit from its name's suffix, longest first.
fn unit_from_name(name: &str) -> &'static str {
    const SUFFIXES: [(&str, &str); 32] = [
        ("_rad_s_per_sqrt_hz", "rad/s/sqrt(Hz)"),
        ("_nm_s_per_rad", "N m s/rad"),
        ("_v_s_per_rad", "V s/rad"),
        ("_nm_per_a", "N m/A"),
        ("_rad_per_nm", "rad/(N m)"),
        ("_rad_per_s", "rad/s"),
        ("_per_nm", "1/(N m)^p"),
        ("_per_s", "1/s"),
        ("_kg_m2", "kg m^2"),
        ("_rad_s", "rad/s"),
        ("_mrad", "mrad"),
        ("_percent", "%"),
        ("_ohm", "ohm"),
        ("_deg", "deg"),
        ("_rad", "rad"),
        ("_hz", "Hz"),
        ("_nm", "N m"),
        ("_db", "dB"),
        ("_s", "s"),
        ("_n", "N"),
        ("_m", "m"),
        ("_a", "A"),
        ("_v", "V"),
        ("_h", "H"),
        ("_csv", "path"),
        ("_per_rev", "counts/rev"),
        ("_substeps", "steps per period"),
        ("_periods", "periods"),
        ("_fraction", "1"),
        ("_ratio", "1"),
        ("_coefficient", "1"),
        ("_runout", "1"),
    ];
    SUFFIXES
        .iter()
        .find(|(s, _)| name.ends_with(s))
        .map_or("", |(_, u)| u)
}

/// A Rust default expression as it reads in a scenario file.
fn show_expr(src: &Source, expr: &str) -> String {
    let e = expr
        .trim()
        .trim_end_matches(".into()")
        .trim_end_matches(".to_string()")
        .trim();
    if let Some(call) = e.strip_suffix("()") {
        if let Some(body) = src.fns.get(call) {
            return show_expr(src, body);
        }
        if call.ends_with("::new") {
            return "empty".into();
        }
    }
    if let Some(x) = e.strip_prefix("Some(").and_then(|r| r.strip_suffix(')')) {
        return show_expr(src, x);
    }
    if e == "None" {
        return "none".into();
    }
    if e == "true" || e == "false" {
        return e.into();
    }
    if e.starts_with('"') {
        return e.into();
    }
    let list = e
        .strip_prefix("vec![")
        .or_else(|| e.strip_prefix('['))
        .and_then(|r| r.strip_suffix(']'));
    if let Some(items) = list {
        if items.trim().is_empty() {
            return "empty".into();
        }
        let shown: Vec<String> = items
            .split(',')
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .map(|s| show_expr(src, s))
            .collect();
        return format!("[{}]", shown.join(", "));
    }
    if let Some(v) = number(e) {
        return v;
    }
    if let Some((a, b)) = e.split_once(" << ") {
        if let (Ok(a), Ok(b)) = (a.trim().parse::<u64>(), b.trim().parse::<u32>()) {
            return (a << b).to_string();
        }
    }
    let consts = [
        (
            "std::f64::consts::FRAC_1_SQRT_2",
            "1/sqrt(2)",
            std::f64::consts::FRAC_1_SQRT_2,
        ),
        ("std::f64::consts::PI", "pi", std::f64::consts::PI),
    ];
    for (path, word, value) in consts {
        if e == path {
            return format!("{} ({word})", short(value));
        }
        if let Some(factor) = e.strip_suffix(&format!(" * {path}")) {
            if let Ok(f) = factor.replace('_', "").parse::<f64>() {
                return format!("{} ({} {word})", short(f * value), short(f));
            }
        }
    }
    // `Type::Variant`: the name in a scenario.
    if let Some((_, v)) = e.rsplit_once("::") {
        if v.chars().all(|c| c.is_alphanumeric()) {
            return format!("\"{}\"", snake(v));
        }
    }
    format!("`{e}`")
}

/// A numeric literal as written in a scenario (`10_000.0` is `10000`).
fn number(e: &str) -> Option<String> {
    let clean = e.replace('_', "");
    let clean = clean
        .trim_end_matches("f64")
        .trim_end_matches("u64")
        .trim_end_matches("u32")
        .trim_end_matches("usize");
    let v: f64 = clean.parse().ok()?;
    Some(if clean.contains('e') {
        clean.trim_end_matches(".0").to_string()
    } else {
        short(v)
    })
}

/// Shortest text of a number, four significant digits for irrational values.
fn short(v: f64) -> String {
    let s = format!("{v}");
    if s.len() > 8 {
        let t = format!("{v:.4}");
        t.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// The default of a field, as read from the code.
fn default_of(src: &Source, owner: &str, whole_default: bool, f: &Field) -> String {
    let explicit = f.serde.iter().find_map(|s| {
        s.split(',').find_map(|p| {
            p.trim()
                .strip_prefix("default = ")
                .map(|v| v.trim_matches('"').to_string())
        })
    });
    if let Some(func) = explicit {
        return src
            .fns
            .get(&func)
            .map_or_else(|| format!("`{func}()`"), |b| show_expr(src, b));
    }
    let bare = f
        .serde
        .iter()
        .any(|s| s.split(',').any(|p| p.trim() == "default"));
    if whole_default {
        if let Some(e) = src.defaults.get(owner).and_then(|d| d.get(&f.name)) {
            return show_expr(src, e);
        }
    }
    let optional = inner(&f.ty, "Option").is_some();
    if !bare && !whole_default {
        return if optional {
            "none".into()
        } else {
            "required".into()
        };
    }
    if optional {
        return "none".into();
    }
    if inner(&f.ty, "Vec").is_some() {
        return "empty".into();
    }
    match f.ty.as_str() {
        "f64" | "u32" | "u64" | "usize" => "0".into(),
        "bool" => "false".into(),
        "String" => "\"\"".into(),
        ty => match src.defs.get(base_name(ty)) {
            Some(Def::Enum {
                tag: None,
                variants,
                ..
            }) => variants
                .iter()
                .find(|v| v.is_default)
                .map_or_else(|| "see below".into(), |v| format!("\"{}\"", snake(&v.name))),
            _ => "see below".into(),
        },
    }
}

/// Meaning, unit and allowed range from a doc comment: trailing `Unit:` and `Allowed:`
/// lines are taken out of the meaning.
fn split_docs(docs: &[String]) -> (String, Option<String>, Option<String>) {
    let mut meaning = Vec::new();
    let mut unit = Vec::new();
    let mut allowed = Vec::new();
    let mut bucket = 0;
    for d in docs {
        if let Some(r) = d.strip_prefix("Unit:") {
            bucket = 1;
            unit.push(r.trim().to_string());
        } else if let Some(r) = d.strip_prefix("Allowed:") {
            bucket = 2;
            allowed.push(r.trim().to_string());
        } else {
            match bucket {
                1 => unit.push(d.trim().to_string()),
                2 => allowed.push(d.trim().to_string()),
                _ => meaning.push(d.trim().to_string()),
            }
        }
    }
    let join =
        |v: Vec<String>| (!v.is_empty()).then(|| v.join(" ").trim_end_matches('.').to_string());
    (
        plain_links(meaning.join(" ").trim()),
        join(unit),
        join(allowed),
    )
}

/// A doc comment's intra-doc links (`[`Type::item`]`) as plain code.
fn plain_links(text: &str) -> String {
    let mut out = String::new();
    let mut rest = text;
    while let Some(start) = rest.find("[`") {
        let after = &rest[start + 2..];
        match after.find("`]") {
            Some(end) if !after[end + 2..].starts_with('(') => {
                out.push_str(&rest[..start]);
                out.push('`');
                out.push_str(&after[..end]);
                out.push('`');
                rest = &after[end + 2..];
            }
            _ => {
                out.push_str(&rest[..start + 2]);
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
}

/// A struct's or enum's doc comment as the paragraph above its table, line breaks kept
/// (a code block stays one).
fn intro(docs: &[String]) -> String {
    let kept: Vec<&str> = docs
        .iter()
        .map(String::as_str)
        .take_while(|d| !d.starts_with("Unit:") && !d.starts_with("Allowed:"))
        .collect();
    plain_links(kept.join("\n").trim())
}

/// The kinds of a tagged table type (`Signal`, `Vec<FilterSpec>`), quoted.
fn tagged_kinds(src: &Source, ty: &str) -> Option<Vec<String>> {
    let ty = inner(ty, "Option").unwrap_or(ty);
    let ty = inner(ty, "Vec").unwrap_or(ty);
    match src.defs.get(base_name(ty)) {
        Some(Def::Enum {
            tag: Some(_),
            variants,
            ..
        }) => Some(
            variants
                .iter()
                .map(|v| format!("`\"{}\"`", snake(&v.name)))
                .collect(),
        ),
        _ => None,
    }
}

fn cell(s: &str) -> String {
    s.replace('|', "\\|")
}

/// Whether a field is left out of the file format (`#[serde(skip)]`).
fn skipped(f: &Field) -> bool {
    f.serde
        .iter()
        .any(|s| s.contains("skip") && !s.contains("skip_serializing"))
}

/// One row of a table.
struct Row {
    key: String,
    unit: String,
    default: String,
    allowed: String,
    meaning: String,
}

/// The reference being written.
struct Writer<'a> {
    src: &'a Source,
    /// Heading, paragraph and rows of each section, in order.
    sections: Vec<(String, String, Option<Vec<Row>>)>,
    /// Where each tagged type is used, and the order of first use.
    shared: BTreeMap<String, Vec<String>>,
    shared_order: Vec<String>,
    /// Struct types already given a table, with the heading of that section.
    written: BTreeMap<String, String>,
    rows: usize,
}

impl Writer<'_> {
    /// A row for field `f` of `owner`.
    fn row(&mut self, owner: &str, whole_default: bool, f: &Field, extra: &str) -> Row {
        let (meaning, unit, allowed) = split_docs(&f.docs);
        let names = match shape(self.src, &f.ty) {
            Shape::Leaf(Some(n)) => Some(n),
            _ => None,
        };
        let allowed = allowed.unwrap_or_else(|| match (&names, tagged_kinds(self.src, &f.ty)) {
            (Some(n), _) => n
                .iter()
                .map(|x| format!("`\"{x}\"`"))
                .collect::<Vec<_>>()
                .join(", "),
            (None, Some(kinds)) => format!("kind {}", kinds.join(", ")),
            (None, None) if f.ty == "bool" => "`true`, `false`".into(),
            (None, None) => String::new(),
        });
        let default = default_of(self.src, owner, whole_default, f);
        let default = match default.as_str() {
            "required" | "none" | "empty" | "see below" => default,
            d if d.starts_with('`') => default,
            _ => format!("`{default}`"),
        };
        self.rows += 1;
        Row {
            key: format!("`{}`", f.name),
            unit: unit.unwrap_or_else(|| match unit_from_name(&f.name) {
                "" => "-".to_string(),
                u => u.to_string(),
            }),
            default,
            allowed,
            meaning: format!("{meaning}{extra}"),
        }
    }

    /// Section `path` for struct `name`, then its sub-tables.
    fn section(&mut self, path: &str, heading: &str, name: &str, table_default: bool) {
        let Some(Def::Struct {
            docs,
            fields,
            whole_default,
        }) = self.src.defs.get(name).cloned()
        else {
            return;
        };
        if let Some(first) = self.written.get(name) {
            let anchor = first.replace(['[', ']', '.'], "");
            self.sections.push((
                heading.to_string(),
                format!("The same keys as [`{first}`](#{anchor}), with the same meaning."),
                None,
            ));
            return;
        }
        self.written.insert(name.to_string(), heading.to_string());
        let mut rows = Vec::new();
        let mut below = Vec::new();
        for f in fields.iter().filter(|f| !skipped(f)) {
            let sub = if path.is_empty() {
                f.name.clone()
            } else {
                format!("{path}.{}", f.name)
            };
            match shape(self.src, &f.ty) {
                Shape::Struct(n) => {
                    let whole = inner(&f.ty, "Option").is_none()
                        && f.serde
                            .iter()
                            .any(|s| s.split(',').any(|p| p.trim() == "default"));
                    below.push((sub.clone(), format!("[{sub}]"), n.to_string(), whole))
                }
                Shape::ArrayOfStruct(n) => below.push((
                    format!("{sub}[]"),
                    format!("[[{sub}]]"),
                    n.to_string(),
                    false,
                )),
                Shape::Tagged(n) | Shape::ArrayOfTagged(n) => {
                    let title = shared_title(n);
                    let anchor = title.to_lowercase();
                    let array = matches!(shape(self.src, &f.ty), Shape::ArrayOfTagged(_));
                    let what = if array { "a list of" } else { "one of the" };
                    let extra = format!(" Takes {what} [{}](#{anchor}).", title.to_lowercase());
                    rows.push(self.row(name, whole_default, f, &extra));
                    if !self.shared_order.iter().any(|s| s == n) {
                        self.shared_order.push(n.to_string());
                    }
                    self.shared
                        .entry(n.to_string())
                        .or_default()
                        .push(format!("`{sub}`"));
                }
                Shape::Leaf(_) => rows.push(self.row(name, whole_default, f, "")),
            }
        }
        let mut text = intro(&docs);
        // A table left out entirely takes the struct's `impl Default`, which may give
        // values to keys that are required once the table is written.
        if let (true, false, Some(values)) =
            (table_default, whole_default, self.src.defaults.get(name))
        {
            let shown: Vec<String> = fields
                .iter()
                .filter(|f| !skipped(f))
                .filter_map(|f| {
                    let v = show_expr(self.src, values.get(&f.name)?);
                    let leaf = matches!(shape(self.src, &f.ty), Shape::Leaf(_));
                    (leaf && v != "none" && v != "empty")
                        .then(|| format!("`{} = {}`", f.name, v.trim_matches('`')))
                })
                .collect();
            if !shown.is_empty() {
                text.push_str(&format!(
                    "\n\nLeft out entirely, the table takes {}.",
                    shown.join(", ")
                ));
            }
        }
        self.sections.push((heading.to_string(), text, Some(rows)));
        for (p, h, n, whole) in below {
            self.section(&p, &h, &n, whole);
        }
    }

    /// The shared section of a tagged enum: one table per kind.
    fn tagged_section(&mut self, name: &str) -> String {
        let Some(Def::Enum { docs, variants, .. }) = self.src.defs.get(name).cloned() else {
            return String::new();
        };
        let title = shared_title(name);
        let used = self
            .shared
            .get(name)
            .cloned()
            .unwrap_or_default()
            .join(", ");
        let mut out = format!(
            "## {title}\n\n{}\n\nUsed by {used}. The kind is chosen by `kind`:\n",
            intro(&docs)
        );
        for v in &variants {
            out.push_str(&format!(
                "\n### kind = \"{}\"\n\n{}\n\n",
                snake(&v.name),
                intro(&v.docs)
            ));
            let mut rows = Vec::new();
            for f in v.fields.iter().filter(|f| !skipped(f)) {
                let extra = match shape(self.src, &f.ty) {
                    Shape::Tagged(n) | Shape::ArrayOfTagged(n) if n == name => {
                        format!(
                            " Each element is itself one of the {}.",
                            title.to_lowercase()
                        )
                    }
                    _ => String::new(),
                };
                rows.push(self.row(name, false, f, &extra));
            }
            if rows.is_empty() {
                out.push_str("No other keys.\n");
            } else {
                out.push_str(&table(&rows));
            }
        }
        out
    }
}

fn shared_title(name: &str) -> String {
    let base = name.strip_suffix("Spec").unwrap_or(name);
    format!("{base}s")
}

fn table(rows: &[Row]) -> String {
    let mut s =
        String::from("| key | unit | default | allowed | meaning |\n|---|---|---|---|---|\n");
    for r in rows {
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} |\n",
            r.key,
            cell(&r.unit),
            cell(&r.default),
            cell(&r.allowed),
            cell(&r.meaning)
        ));
    }
    s
}

/// Every key path the reference documents, in the parser's notation (see
/// `accepted_keys`): struct fields, tagged tables' `kind` and every kind's keys, arrays of
/// tables as `name[]`, a tagged table nested in its own kind by its key alone.
fn documented_paths(
    src: &Source,
    path: &str,
    ty: &str,
    tagged: &mut Vec<String>,
    out: &mut BTreeSet<String>,
) {
    let join = |k: &str| {
        if path.is_empty() {
            k.to_string()
        } else {
            format!("{path}.{k}")
        }
    };
    match src.defs.get(base_name(ty)) {
        Some(Def::Struct { fields, .. }) => {
            for f in fields {
                if f.serde
                    .iter()
                    .any(|s| s.contains("skip") && !s.contains("skip_serializing"))
                {
                    continue;
                }
                let p = join(&f.name);
                match shape(src, &f.ty) {
                    Shape::Struct(n) | Shape::Tagged(n) => {
                        documented_paths(src, &p, n, tagged, out)
                    }
                    Shape::ArrayOfStruct(n) => {
                        documented_paths(src, &format!("{p}[]"), n, tagged, out)
                    }
                    Shape::ArrayOfTagged(n) => {
                        if tagged.iter().any(|t| t == n) {
                            out.insert(p);
                        } else {
                            documented_paths(src, &format!("{p}[]"), n, tagged, out)
                        }
                    }
                    Shape::Leaf(_) => {
                        out.insert(p);
                    }
                }
            }
        }
        Some(Def::Enum {
            tag: Some(tag),
            variants,
            ..
        }) => {
            let name = base_name(ty).to_string();
            if tagged.contains(&name) {
                out.insert(path.trim_end_matches("[]").to_string());
                return;
            }
            out.insert(join(tag));
            tagged.push(name);
            for v in variants {
                for f in v.fields.iter().filter(|f| {
                    !f.serde
                        .iter()
                        .any(|s| s.contains("skip") && !s.contains("skip_serializing"))
                }) {
                    let p = join(&f.name);
                    match shape(src, &f.ty) {
                        Shape::Leaf(_) => {
                            out.insert(p);
                        }
                        Shape::Struct(n) | Shape::Tagged(n) => {
                            documented_paths(src, &p, n, tagged, out)
                        }
                        Shape::ArrayOfStruct(n) | Shape::ArrayOfTagged(n) => {
                            if tagged.iter().any(|t| t == n) {
                                out.insert(p);
                            } else {
                                documented_paths(src, &format!("{p}[]"), n, tagged, out)
                            }
                        }
                    }
                }
            }
            tagged.pop();
        }
        _ => {
            out.insert(path.to_string());
        }
    }
}

fn generate(src: &Source, accepted: usize) -> String {
    let mut w = Writer {
        src,
        sections: Vec::new(),
        shared: BTreeMap::new(),
        shared_order: Vec::new(),
        written: BTreeMap::new(),
        rows: 0,
    };
    w.section("", "Top level", "Scenario", false);
    let shared_names = w.shared_order.clone();
    let shared_text: Vec<String> = shared_names.iter().map(|n| w.tagged_section(n)).collect();
    let mut out = String::new();
    out.push_str("# Scenario keys\n\n");
    out.push_str(
        "Every key a scenario file accepts, with its unit, its default when the key is left\n\
out, its allowed range and its meaning. Generated from the parameter structs' doc comments\n\
and the code's defaults by `tests/keys_reference.rs`; do not edit it by hand: change the\n\
doc comment (a trailing `Unit:` or `Allowed:` line sets those columns) and regenerate with\n\
`UPDATE_KEYS=1 cargo test --test keys_reference`. The same test checks that the keys\n\
listed here are exactly those the strict parser accepts (`scenario::accepted_keys()`).\n\n",
    );
    out.push_str(&format!(
        "The {} rows below cover the {accepted} key paths the parser accepts: the keys of a\n\
signal or a filter are listed once, under [Signals](#signals) and [Filters](#filters),\n\
and are accepted wherever a signal or a filter is. `required` means the table cannot be\n\
given without the key; `none` means the key is unset (its meaning says what that does).\n\
Ranges are checked when the scenario is read, `--set KEY=VALUE` included; a limit that\n\
depends on another key names both in its message. `cable-servo show NAME` prints a\n\
complete built-in scenario to start from.\n\n",
        w.rows
    ));
    for (heading, intro, rows) in &w.sections {
        out.push_str(&format!("## {heading}\n\n"));
        if !intro.is_empty() {
            out.push_str(&format!("{intro}\n\n"));
        }
        match rows {
            Some(rows) if rows.is_empty() => out.push_str("Sub-tables only.\n\n"),
            Some(rows) => {
                out.push_str(&table(rows));
                out.push('\n');
            }
            None => {}
        }
    }
    for s in shared_text {
        out.push_str(&s);
        out.push('\n');
    }
    out.trim_end().to_string() + "\n"
}

#[test]
fn keys_reference_is_current_and_complete() {
    let src = read_source();
    let accepted: BTreeSet<String> = cable_servo::scenario::accepted_keys().into_iter().collect();
    let mut documented = BTreeSet::new();
    documented_paths(&src, "", "Scenario", &mut Vec::new(), &mut documented);
    let missing: Vec<&String> = accepted.difference(&documented).collect();
    let extra: Vec<&String> = documented.difference(&accepted).collect();
    assert!(
        missing.is_empty() && extra.is_empty(),
        "docs/keys.md does not match the parser.\naccepted but not documented: {missing:#?}\ndocumented but not accepted: {extra:#?}"
    );
    for key in [
        "closed_loop.controller.derivative_filter_hz",
        "closed_loop.controller.brake_transition_s",
        "closed_loop.motor.coulomb_smoothing_rad_s",
    ] {
        assert!(accepted.contains(key), "{key} is not accepted");
    }

    let text = generate(&src, accepted.len());
    let path = repo().join("docs/keys.md");
    if std::env::var_os("UPDATE_KEYS").is_some() {
        std::fs::write(&path, &text).expect("docs/keys.md written");
        return;
    }
    let current = std::fs::read_to_string(&path).unwrap_or_default();
    if current != text {
        let line = current
            .lines()
            .zip(text.lines())
            .position(|(a, b)| a != b)
            .unwrap_or_else(|| current.lines().count().min(text.lines().count()));
        panic!(
            "docs/keys.md is out of date with the source (first difference at line {}): regenerate it with `UPDATE_KEYS=1 cargo test --test keys_reference`",
            line + 1
        );
    }
}
