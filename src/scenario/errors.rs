//! What can be wrong with a scenario, and messages that name the file, line and key.

/// A scenario that cannot be used, with where and why.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file cannot be read.
    #[error("cannot read scenario {path}: {source}")]
    Io {
        /// File path.
        path: String,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The path names a directory (and no built-in scenario has that name).
    #[error("{path} is a directory, not a scenario file: give a scenario's .toml file or a built-in name (`cable-servo --help` lists them)")]
    Directory {
        /// The path given.
        path: String,
    },
    /// Neither a file nor a built-in scenario of that name exists.
    #[error("no scenario file {name} and no built-in scenario of that name{} (built-in: {builtins})", suggestion.as_ref().map_or(String::new(), |s| format!("; did you mean {s}?")))]
    NotFound {
        /// The name given.
        name: String,
        /// The nearest built-in name, when one is close.
        suggestion: Option<String>,
        /// Every built-in name, comma-separated.
        builtins: String,
    },
    /// Syntax or type error in the file.
    #[error("{source_name}:{line}:{column}: {}", printable(message))]
    Parse {
        /// File name.
        source_name: String,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A `--set` argument that cannot be applied.
    #[error("--set {}: {}", printable(arg), printable(message))]
    Override {
        /// The argument as given.
        arg: String,
        /// What is wrong.
        message: String,
    },
    /// A value outside its physical range or an inconsistent combination.
    #[error("{source_name}: {}: {}", printable(key), printable(message))]
    Invalid {
        /// File name (with `+ --set` when overrides were applied).
        source_name: String,
        /// Dotted key.
        key: String,
        /// What is wrong and what is allowed.
        message: String,
    },
}

/// Text for a one-line message: line breaks and other control characters escaped.
pub(super) fn printable(text: &str) -> String {
    if text.chars().any(char::is_control) {
        text.chars()
            .map(|c| {
                if c.is_control() {
                    c.escape_default().to_string()
                } else {
                    c.to_string()
                }
            })
            .collect()
    } else {
        text.to_string()
    }
}

impl ScenarioError {
    pub(super) fn invalid(
        source_name: &str,
        key: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        ScenarioError::Invalid {
            source_name: source_name.to_string(),
            key: key.into(),
            message: message.into(),
        }
    }
}

/// Line and column (1-based) of a byte offset.
pub(super) fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// Adds "did you mean" to serde's unknown-field and unknown-variant messages.
pub(super) fn with_suggestion(message: &str) -> String {
    let unknown = ["unknown field `", "unknown variant `"]
        .iter()
        .find_map(|p| message.find(p).map(|i| (i + p.len(), p)));
    let Some((start, _)) = unknown else {
        return message.to_string();
    };
    let rest = &message[start..];
    let Some(end) = rest.find('`') else {
        return message.to_string();
    };
    let bad = &rest[..end];
    let candidates: Vec<&str> = rest[end + 1..].split('`').skip(1).step_by(2).collect();
    // Edit distance for typos; a shared start for shortened spellings (`figure8`).
    let letters: String = bad
        .chars()
        .take_while(|c| c.is_ascii_alphabetic() || *c == '_')
        .collect();
    let best = candidates
        .iter()
        .map(|c| {
            let edits = strsim::normalized_damerau_levenshtein(bad, c);
            let shortened = letters.len() >= 4 && c.starts_with(letters.as_str());
            (if shortened { edits.max(0.6) } else { edits }, *c)
        })
        .filter(|(score, _)| *score > 0.5)
        .max_by(|a, b| a.0.total_cmp(&b.0));
    let first_line = message.lines().next().unwrap_or(message);
    match best {
        Some((_, c)) => format!("{first_line}; did you mean `{c}`?"),
        None => first_line.to_string(),
    }
}

/// Serde's type names in words a scenario author knows, on one line.
pub(super) fn plain_message(message: &str) -> String {
    let one_line = message
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join("; ");
    let mut out = one_line
        .replace("expected f64", "expected a number")
        .replace("expected u32", "expected a whole number >= 0")
        .replace("expected usize", "expected a whole number >= 0")
        .replace("expected u64", "expected a whole number >= 0")
        .replace("expected a string", "expected a quoted string")
        .replace("expected a sequence", "expected a list in brackets [ ]")
        .replace(
            "expected internally tagged enum Signal",
            "expected a signal table with a kind, e.g. { kind = \"sine\", amplitude_rad = 0.1, frequency_hz = 0.1 }",
        );
    // `expected struct DriveParams[ with N elements]` -> the section a user writes.
    if let Some(i) = out.find("expected struct ") {
        let rest = &out[i + "expected struct ".len()..];
        let name_len = rest
            .find(|c: char| !c.is_ascii_alphanumeric())
            .unwrap_or(rest.len());
        let mut tail = &rest[name_len..];
        if let Some(t) = tail.strip_prefix(" with ") {
            tail = t
                .find(" elements")
                .map_or(tail, |j| &t[j + " elements".len()..]);
        }
        let what = match &rest[..name_len] {
            "DriveParams" => "a [drive] section",
            "LoadParams" => "a [load] section",
            "QuasiStaticParams" => "a [quasi_static] section",
            "BacklashParams" => "a [backlash] section",
            "ClosedLoopParams" => "a [closed_loop] section",
            "SweepSpec" => "a [sweep] section",
            "SweepParameter" => "a table { key = \"drive.preload_n\", values = [...] }",
            _ => "a section (a table of key = value)",
        };
        out = format!("{}expected {what}{tail}", &out[..i]);
    }
    const SERDE: &[&str] = &[
        "invalid type",
        "invalid value",
        "invalid length",
        "missing field",
        "unknown field",
        "unknown variant",
        "duplicate field",
    ];
    if !out.is_empty() && !SERDE.iter().any(|p| out.starts_with(p)) {
        out = format!("TOML syntax error: {out}");
        if out.contains("invalid string") {
            out.push_str(" (text values need quotes, e.g. routing = \"open\")");
        }
    }
    out
}

/// The header of a `[section]` or `[[section]]` line, if it is one.
pub(super) fn header_name(line: &str) -> Option<String> {
    let t = line.trim();
    let t = t.strip_prefix('[')?;
    let t = t.strip_prefix('[').unwrap_or(t);
    let end = t.find(']')?;
    let name: String = t[..end].chars().filter(|c| !c.is_whitespace()).collect();
    (!name.is_empty()).then_some(name)
}

/// The dotted key (or section) at a byte offset of a scenario text, when the line shows it
/// plainly: `[section]` headers above and `key = ...` on the line.
pub(super) fn key_at(text: &str, offset: usize) -> Option<String> {
    let offset = offset.min(text.len());
    let before = text.get(..offset)?;
    let start = before.rfind('\n').map_or(0, |i| i + 1);
    let end = text[start..].find('\n').map_or(text.len(), |i| start + i);
    let line = &text[start..end];
    if let Some(h) = header_name(line) {
        return Some(h);
    }
    let section = text[..start].lines().rev().find_map(header_name);
    let key = line.split_once('=')?.0.trim();
    let plain = !key.is_empty()
        && key
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | '"' | '\'' | ' '));
    if !plain {
        return section;
    }
    let key: String = key
        .chars()
        .filter(|c| !matches!(c, '"' | '\'' | ' '))
        .collect();
    Some(match section {
        Some(s) => format!("{s}.{key}"),
        None => key,
    })
}

/// In the section whose header is on 1-based `header_line`, the single `key = value` line
/// whose value is the one quoted in a serde message (`integer `-2``, `string "x"`); returns
/// its line and dotted key.
pub(super) fn find_value_line(
    text: &str,
    header_line: usize,
    message: &str,
) -> Option<(usize, String)> {
    let quoted = if let Some(i) = message.find('`') {
        let rest = &message[i + 1..];
        rest[..rest.find('`')?].to_string()
    } else {
        let i = message.find('"')?;
        let rest = &message[i + 1..];
        format!("\"{}\"", &rest[..rest.find('"')?])
    };
    let mut hits = Vec::new();
    let mut offset = 0;
    for (i, l) in text.split('\n').enumerate() {
        let start = offset;
        offset += l.len() + 1;
        if i < header_line {
            continue;
        }
        if header_name(l).is_some() {
            break;
        }
        let Some((k, v)) = l.split_once('=') else {
            continue;
        };
        let v = v.split('#').next().unwrap_or("").trim();
        if v == quoted {
            let key = key_at(text, start).unwrap_or_else(|| k.trim().to_string());
            hits.push((i + 1, key));
        }
    }
    (hits.len() == 1).then(|| hits.remove(0))
}

pub(super) fn parse_error(source_name: &str, text: &str, err: &toml::de::Error) -> ScenarioError {
    let (mut line, mut column) = err
        .span()
        .map(|s| line_col(text, s.start))
        .unwrap_or((1, 1));
    let mut message = plain_message(&with_suggestion(err.message()));
    if message.starts_with("invalid type") || message.starts_with("invalid value") {
        let at_header = text.lines().nth(line - 1).and_then(header_name).is_some();
        let found = if at_header {
            // Tagged sections (`[quasi_static.motion]`) report the section, not the value:
            // find the line that holds the offending value.
            find_value_line(text, line, &message)
        } else {
            None
        };
        if let Some((l, key)) = found {
            line = l;
            column = 1;
            message = format!("{key}: {message}");
        } else if let Some(key) = err.span().and_then(|s| key_at(text, s.start)) {
            message = format!("{key}: {message}");
        }
    } else if message.starts_with("missing field") {
        match err.span().and_then(|s| key_at(text, s.start)) {
            Some(section) => message = format!("[{section}]: {message}"),
            None if text
                .lines()
                .all(|l| l.trim().is_empty() || l.trim_start().starts_with('#')) =>
            {
                message = format!("the file holds no settings ({message}); a scenario needs at least study, [drive] and the study's section, see `cable-servo show paper_bench`");
            }
            None => message.push_str(" at the top of the file"),
        }
    }
    ScenarioError::Parse {
        source_name: source_name.to_string(),
        line,
        column,
        message,
    }
}
