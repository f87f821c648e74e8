//! Reading scenario text into a TOML table and applying `--set dotted.key=value`.

use crate::error::{Error, Result};

/// Parse TOML text; a syntax error names the file, line and column.
pub(super) fn parse_toml(name: &str, text: &str) -> Result<toml::Table> {
    text.parse::<toml::Table>().map_err(|e| {
        let msg = e.message().to_string();
        let loc = e.span().map(|s| {
            let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
            let col = s.start - text[..s.start.min(text.len())].rfind('\n').map_or(0, |i| i + 1) + 1;
            format!("line {line}, column {col}")
        });
        Error::input(name, loc.unwrap_or_default(), format!("malformed TOML: {msg}"))
    })
}

/// Parse a JSON scenario, or a `summary.json` (its `scenario` field is used).
/// A scenario in JSON, or a `summary.json`'s `scenario`; with it, for a summary, the
/// controller from outside the scenario that made the run (`external_controller`), if any.
pub(super) fn parse_json(name: &str, text: &str) -> Result<(toml::Table, Option<String>)> {
    let v: serde_json::Value =
        serde_json::from_str(text).map_err(|e| Error::input(name, "", format!("malformed JSON: {e}")))?;
    let (v, external) = match v.get("scenario") {
        Some(s) if v.get("max_abs_force_error_n").is_some() => {
            let external = match v.get("external_controller") {
                None | Some(serde_json::Value::Null) => None,
                Some(serde_json::Value::String(c)) => Some(c.chars().take(200).collect()),
                Some(other) => Some(other.to_string().chars().take(200).collect()),
            };
            (s.clone(), external)
        }
        _ => (v, None),
    };
    match json_to_toml(name, "", v)? {
        toml::Value::Table(t) => Ok((t, external)),
        _ => Err(Error::input(name, "", "a scenario must be a JSON object")),
    }
}

/// A JSON value as a scenario value (null = absent = default); errors name `key`.
pub(super) fn json_to_toml(name: &str, key: &str, v: serde_json::Value) -> Result<toml::Value> {
    if let Some(n) = first_out_of_range_integer(&v) {
        return Err(Error::input(
            name,
            key,
            format!("integer {n} is out of range (a scenario integer fits in 64 bits)"),
        ));
    }
    toml::Value::try_from(strip_nulls(v))
        .map_err(|e| Error::input(name, key, format!("cannot use as a scenario value: {e}")))
}

/// An integer beyond i64 in a JSON value (u64 above i64::MAX), as text.
fn first_out_of_range_integer(v: &serde_json::Value) -> Option<String> {
    match v {
        serde_json::Value::Number(n) if n.is_u64() && n.as_i64().is_none() => Some(n.to_string()),
        serde_json::Value::Array(a) => a.iter().find_map(first_out_of_range_integer),
        serde_json::Value::Object(m) => m.values().find_map(first_out_of_range_integer),
        _ => None,
    }
}

/// TOML has no null: an absent key means "default", which is what JSON's null means here.
fn strip_nulls(v: serde_json::Value) -> serde_json::Value {
    match v {
        serde_json::Value::Object(m) => serde_json::Value::Object(
            m.into_iter().filter(|(_, v)| !v.is_null()).map(|(k, v)| (k, strip_nulls(v))).collect(),
        ),
        serde_json::Value::Array(a) => serde_json::Value::Array(a.into_iter().map(strip_nulls).collect()),
        other => other,
    }
}

/// Apply one `dotted.key=value` override. The value is read as a TOML value
/// (`1e-3`, `true`, `"text"`, `[1, 2]`, `{kind = "znn"}`); anything that is not valid TOML is
/// taken as a string, except an integer too large for TOML's 64-bit signed integers, which is
/// an error (or, for `seed`, which is unsigned, kept as its decimal text). A table merges into
/// the table it overrides, key by key.
/// Most dotted segments a `--set` key may have (the deepest scenario key has 3).
const MAX_KEY_DEPTH: usize = 8;

pub(super) fn apply_set(table: &mut toml::Table, set: &str) -> Result<()> {
    let (key, raw) = set
        .split_once('=')
        .ok_or_else(|| Error::input("--set", set, "expected key=value (e.g. controller.gamma=200)"))?;
    let key = key.trim();
    let value = parse_value(key, raw.trim())?;
    apply_value(table, key, value)
}

/// Keys of which a scenario gives one: an override of either replaces the other (the gait is
/// the trial's file or the built-in trial; a file giving both is refused by validation).
const ONE_OF: &[(&str, &str, &str)] = &[("reference", "gait_file", "gait_trial")];

/// Set the dotted `key` to `value` (a table merges into the table it overrides): an override
/// given as data (the Python package), never parsed from text. An override of one key of an
/// [`ONE_OF`] pair removes the other.
pub(super) fn apply_value(table: &mut toml::Table, key: &str, value: toml::Value) -> Result<()> {
    for (section, a, b) in ONE_OF {
        let other = match key.strip_prefix(section).and_then(|k| k.strip_prefix('.')) {
            Some(k) if k == *a => b,
            Some(k) if k == *b => a,
            _ => continue,
        };
        if let Some(toml::Value::Table(t)) = table.get_mut(*section) {
            t.remove(*other);
        }
    }
    let parts: Vec<&str> = key.split('.').collect();
    if parts.iter().any(|p| p.trim().is_empty()) {
        return Err(Error::input("--set", key, "empty key segment"));
    }
    if parts.len() > MAX_KEY_DEPTH {
        let shown: String = key.chars().take(60).collect();
        return Err(Error::input(
            "--set",
            shown,
            format!("{} key segments; scenario keys have at most {MAX_KEY_DEPTH}", parts.len()),
        ));
    }
    let mut cur = table;
    let mut i = 0;
    while i < parts.len() {
        let p = parts[i];
        if i + 1 == parts.len() {
            put(cur, p, value);
            return Ok(());
        }
        let entry = cur.entry(p.to_string()).or_insert_with(|| toml::Value::Table(toml::Table::new()));
        cur = match entry {
            toml::Value::Table(t) => t,
            // An array of tables (`[[faults]]`): the next segment is an index into it.
            toml::Value::Array(a) => {
                let at = parts[..=i + 1].join(".");
                let idx = parts[i + 1].parse::<usize>().map_err(|_| {
                    Error::input(
                        "--set",
                        key,
                        format!("`{}` is an array: index it by number (`{p}.0`)", parts[..=i].join(".")),
                    )
                })?;
                let n = a.len();
                let el = a.get_mut(idx).ok_or_else(|| {
                    Error::input(
                        "--set",
                        key,
                        format!("`{at}`: the array has {n} entries (0..{})", n.saturating_sub(1)),
                    )
                })?;
                i += 1;
                if i + 1 == parts.len() {
                    match (el, value) {
                        (toml::Value::Table(old), toml::Value::Table(new)) => merge(old, new),
                        (el, v) => *el = v,
                    }
                    return Ok(());
                }
                match el {
                    toml::Value::Table(t) => t,
                    _ => return Err(Error::input("--set", key, format!("`{at}` is not a table"))),
                }
            }
            _ => {
                return Err(Error::input("--set", key, format!("`{}` is not a table", parts[..=i].join("."))));
            }
        };
        i += 1;
    }
    Ok(())
}

/// Set `key` of `t` to `value` (a table merges into the table there).
fn put(t: &mut toml::Table, key: &str, value: toml::Value) {
    match (t.get_mut(key), value) {
        (Some(toml::Value::Table(old)), toml::Value::Table(new)) => merge(old, new),
        (_, v) => {
            t.insert(key.to_string(), v);
        }
    }
}

/// A `--set` value: TOML if it parses, else a string (see [`apply_set`]).
fn parse_value(key: &str, raw: &str) -> Result<toml::Value> {
    if let Some(v) = format!("v = {raw}").parse::<toml::Table>().ok().and_then(|mut t| t.remove("v")) {
        return Ok(v);
    }
    let digits = raw.strip_prefix(['-', '+']).unwrap_or(raw);
    if !digits.is_empty() && digits.chars().all(|c| c.is_ascii_digit() || c == '_') {
        if key == "seed" && raw.parse::<u64>().is_ok() {
            return Ok(toml::Value::String(raw.to_string()));
        }
        return Err(Error::input(
            "--set",
            key,
            format!(
                "integer {raw} is out of range (a scenario integer fits in 64 bits; seed in 0..=18446744073709551615)"
            ),
        ));
    }
    Ok(toml::Value::String(raw.to_string()))
}

/// Merge `new` into `old` key by key (tables recursively).
fn merge(old: &mut toml::Table, new: toml::Table) {
    for (k, v) in new {
        match (old.get_mut(&k), v) {
            (Some(toml::Value::Table(o)), toml::Value::Table(n)) => merge(o, n),
            (_, v) => {
                old.insert(k, v);
            }
        }
    }
}

/// The first line of a serde error, with TOML's type names made plain ("invalid type: string"
/// for an out-of-range integer is what the deserialiser says when it cannot parse it at all).
pub(super) fn clean_serde_message(msg: &str) -> String {
    // The TOML deserialiser appends "in `key`" on a second line; the key is already named.
    msg.lines().next().unwrap_or_default().to_string()
}
