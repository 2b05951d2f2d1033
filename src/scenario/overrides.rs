//! `--set KEY=VALUE`: a dotted key and a TOML value applied to a scenario table.

use super::ScenarioError;

/// Parse `KEY=VALUE` into a dotted path and a TOML value. The value is read as TOML
/// (`70`, `1.4e4`, `true`, `[1, 2]`, `"open"`); anything else is taken as a bare string.
pub fn parse_assignment(arg: &str) -> Result<(Vec<String>, toml::Value), ScenarioError> {
    let err = |message: &str| ScenarioError::Override {
        arg: arg.to_string(),
        message: message.to_string(),
    };
    let (key, value) = arg
        .split_once('=')
        .ok_or_else(|| err("expected KEY=VALUE, e.g. drive.preload_n=70"))?;
    let key = key.trim();
    if key.is_empty() {
        return Err(err("the key before '=' is empty"));
    }
    let path: Vec<String> = key.split('.').map(|p| p.trim().to_string()).collect();
    if path.iter().any(|p| p.is_empty()) {
        return Err(err(
            "the key has an empty part; write sections with dots, e.g. drive.preload_n",
        ));
    }
    let value = value.trim();
    let parsed = toml::from_str::<toml::Table>(&format!("v = {value}"))
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_string()));
    Ok((path, parsed))
}

/// Set a dotted key in a TOML table, creating intermediate tables.
pub fn set_path(
    table: &mut toml::Table,
    path: &[String],
    value: toml::Value,
) -> Result<(), String> {
    let Some((last, parents)) = path.split_last() else {
        return Err("empty key".into());
    };
    let mut cur = table;
    for (i, part) in parents.iter().enumerate() {
        let entry = cur
            .entry(part.clone())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        cur = match entry {
            toml::Value::Table(t) => t,
            other => {
                return Err(format!(
                    "{} is a {}, not a section",
                    path[..=i].join("."),
                    other.type_str()
                ))
            }
        };
    }
    cur.insert(last.clone(), value);
    Ok(())
}
