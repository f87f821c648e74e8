//! The manual's examples run (issue 43): every block of README.md and docs/src marked
//! ```` ```sh run ```` is run with bash (`-euo pipefail`), in order within its page, in a fresh
//! workspace that sees the repository's assets, examples, headers and build folder, with
//! `exoleg` on the PATH (`cargo run --release --` in a block means the built binary); every
//! block marked ```` ```toml scenario ```` is loaded and resolved as a scenario. A broken example
//! fails the test with its page, line and output.

use crate::common::exe;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// What a marked block is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Shell,
    Scenario,
    /// ```` ```text output ````: lines the shell block before it prints (in order, among others),
    /// each figure within the precision shown.
    Output,
}

/// The marked blocks of a Markdown page: (line of the fence, kind, text).
fn blocks(md: &str) -> Vec<(usize, Kind, String)> {
    let mut out = Vec::new();
    let mut open: Option<(usize, Option<Kind>, String)> = None;
    for (i, line) in md.lines().enumerate() {
        let fence = line.trim_start().starts_with("```");
        match (&mut open, fence) {
            (None, true) => {
                let info: Vec<&str> = line.trim_start().trim_start_matches('`').split_whitespace().collect();
                let kind = match info.as_slice() {
                    ["sh", "run"] => Some(Kind::Shell),
                    ["toml", "scenario"] => Some(Kind::Scenario),
                    ["text", "output"] => Some(Kind::Output),
                    _ => None,
                };
                open = Some((i + 1, kind, String::new()));
            }
            (Some(_), true) => {
                let (at, kind, text) = open.take().unwrap();
                if let Some(k) = kind {
                    out.push((at, k, text));
                }
            }
            (Some((_, _, text)), false) => {
                text.push_str(line);
                text.push('\n');
            }
            (None, false) => {}
        }
    }
    out
}

/// A workspace for one page: the repository's inputs by link, `out/` its own.
fn workspace() -> tempfile::TempDir {
    let ws = tempfile::tempdir().unwrap();
    for d in ["assets", "examples", "include", "scripts", "python", "target"] {
        std::os::unix::fs::symlink(root().join(d), ws.path().join(d)).unwrap();
    }
    std::fs::create_dir(ws.path().join("out")).unwrap();
    ws
}

/// Run a shell block in `ws`: its standard output, or Err with its output when it fails.
fn run_shell(ws: &Path, text: &str) -> Result<String, String> {
    let bin = Path::new(exe()).parent().unwrap();
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
    let script = text.replace("cargo run --release --", "exoleg");
    let o = Command::new("bash")
        .args(["-euo", "pipefail", "-c", &script])
        .current_dir(ws)
        .env("PATH", path)
        .output()
        .map_err(|e| e.to_string())?;
    if o.status.success() {
        Ok(String::from_utf8_lossy(&o.stdout).into_owned())
    } else {
        Err(format!("{}\n{}{}", o.status, String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr)))
    }
}

/// Load and resolve a scenario block (written into `ws`, so relative paths are the workspace's).
fn check_scenario(ws: &Path, text: &str) -> Result<(), String> {
    let file = ws.join("doc_scenario.toml");
    std::fs::write(&file, text).unwrap();
    exoleg::load(Some(&file), &[]).map(|_| ()).map_err(|e| e.to_string())
}

/// Run every marked block of `md` in one workspace; the failures as "page:line: output", and
/// how many blocks ran.
fn check_page(name: &str, md: &str) -> (Vec<String>, usize) {
    // One page at a time: pages build the same plugin into target/ and load it.
    static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let ws = workspace();
    let mut failures = Vec::new();
    let found = blocks(md);
    let mut printed: Option<String> = None;
    for (line, kind, text) in &found {
        let r = match kind {
            Kind::Shell => run_shell(ws.path(), text).map(|out| printed = Some(out)),
            Kind::Scenario => check_scenario(ws.path(), text),
            Kind::Output => match printed.take() {
                Some(out) => shows(text, &out),
                None => Err("an output block without a shell block that ran before it".into()),
            },
        };
        if let Err(e) = r {
            failures.push(format!("{name}:{line}: {e}"));
        }
    }
    (failures, found.len())
}

/// A token as (text before the number, the number, its precision: half a unit of its last
/// shown digit, text after), or None when it holds no number.
fn figure(token: &str) -> Option<(&str, f64, f64, &str)> {
    let start = token.find(|c: char| c.is_ascii_digit() || c == '-' || c == '+')?;
    let body = &token[start..];
    let end = body
        .char_indices()
        .take_while(|&(i, c)| c.is_ascii_digit() || c == '.' || (i == 0 && (c == '-' || c == '+')) || c == 'e')
        .last()
        .map(|(i, c)| i + c.len_utf8())?;
    let (num, after) = body.split_at(end);
    let value: f64 = num.parse().ok()?;
    let (mantissa, exp) = num.split_once('e').map_or((num, 0), |(m, e)| (m, e.parse().unwrap_or(0)));
    let decimals = mantissa.split_once('.').map_or(0, |(_, d)| d.len() as i32);
    Some((&token[..start], value, 0.5 * 10f64.powi(exp - decimals), after))
}

/// `shown` and `got` are the same line: the same words, each figure within the precision shown.
fn same_line(shown: &str, got: &str) -> bool {
    let (a, b): (Vec<&str>, Vec<&str>) = (shown.split_whitespace().collect(), got.split_whitespace().collect());
    a.len() == b.len()
        && a.iter().zip(&b).all(|(x, y)| match (figure(x), figure(y)) {
            (Some((px, vx, tol, sx)), Some((py, vy, _, sy))) => {
                px == py && sx == sy && (vx - vy).abs() <= tol * (1.0 + 1e-9)
            }
            _ => x == y,
        })
}

/// Every line of `shown` is a line of `out`, in order.
fn shows(shown: &str, out: &str) -> Result<(), String> {
    let mut lines = out.lines();
    for want in shown.lines().filter(|l| !l.trim().is_empty()) {
        if !lines.any(|got| same_line(want, got)) {
            return Err(format!("the page shows\n  {want}\nbut the command printed\n{out}"));
        }
    }
    Ok(())
}

/// The pages: README.md and every Markdown file of docs/src.
fn pages() -> Vec<PathBuf> {
    let mut v = vec![root().join("README.md")];
    let mut stack = vec![root().join("docs/src")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "md") {
                v.push(p);
            }
        }
    }
    v.sort();
    v
}

/// Every marked block of the README and the manual runs (measured: 16 blocks, 5 in the README,
/// 8 in the tutorial, the gait check, the C ABI's plugin run and the HIL loop).
#[test]
fn the_manuals_examples_run() {
    let (mut failures, mut count) = (Vec::new(), 0);
    for p in pages() {
        let md = std::fs::read_to_string(&p).unwrap();
        let name = p.strip_prefix(root()).unwrap().display().to_string();
        let (f, n) = check_page(&name, &md);
        failures.extend(f);
        count += n;
    }
    eprintln!("{count} marked blocks run");
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
    assert!(count >= 10, "only {count} marked blocks: the markers were lost");
}

/// A broken copy of the tutorial fails: a command with a misspelt key and a scenario block with
/// an unknown key are both reported with their lines.
#[test]
fn a_broken_example_fails() {
    let md = std::fs::read_to_string(root().join("docs/src/tutorial.md")).unwrap();
    let broken = md.replacen("--set sim.dt_s=0.001", "--set sim.dt=0.001", 1).replacen(
        "duration_s = 6.38",
        "duration = 6.38",
        1,
    );
    assert_ne!(broken, md);
    let (failures, _) = check_page("tutorial (broken)", &broken);
    // The misspelt command fails, so its output block has nothing to compare: three failures.
    assert_eq!(failures.len(), 3, "{failures:#?}");
    assert!(failures[0].contains("sim.dt") && failures[2].contains("duration"), "{failures:#?}");
    // A shown figure off by more than its precision fails; within it, passes.
    let shown = "knee error          RMS 1.0801 deg, max 2.5556 deg";
    assert!(same_line(shown, "knee error          RMS 1.08014 deg, max 2.55555 deg"));
    assert!(!same_line(shown, "knee error          RMS 1.0807 deg, max 2.5556 deg"));
    assert!(!same_line(shown, "knee error          RMS 1.0801 rad, max 2.5556 deg"));
    let off = md.replacen("RMS 1.0801 deg", "RMS 1.0901 deg", 1);
    assert_ne!(off, md, "the tutorial shows the knee error");
    let (failures, _) = check_page("tutorial (a shown figure off)", &off);
    assert!(failures.len() == 1 && failures[0].contains("1.0901"), "{failures:#?}");
}

/// The fields of the scenario table at `prefix` ("" or "a.b.") as the code's deserializer
/// names them (serde's "expected one of" for an unknown field), or None when `prefix` is not a
/// table of named fields.
fn code_fields(prefix: &str) -> Option<Vec<String>> {
    let set = format!("{prefix}zz_not_a_key=1");
    let e = exoleg::Scenario::from_toml_str("keys", "", &[set]).err()?.to_string();
    // serde: "unknown field `x`, expected `a`", "... expected `a` or `b`", "... expected one
    // of `a`, `b`, `c`" (an enum's "unknown variant" is not a table).
    let list = e.split("unknown field `zz_not_a_key`, expected ").nth(1)?;
    let list = list.strip_prefix("one of ").unwrap_or(list);
    Some(list.split(", ").flat_map(|f| f.split(" or ")).map(|f| f.trim().trim_matches('`').to_string()).collect())
}

/// Every scenario key the code reads, depth first (tables included).
fn code_keys(prefix: &str, depth: usize, out: &mut Vec<String>) {
    for f in code_fields(prefix).unwrap_or_default() {
        let key = format!("{prefix}{f}");
        out.push(key.clone());
        if depth < 4 {
            code_keys(&format!("{key}."), depth + 1, out);
        }
    }
}

/// The keys a Markdown keys table documents: the backticked names of each row's first cell,
/// `.name` continuing the previous key's table, `{a,b}` for each of a and b.
fn documented_keys(md: &str) -> std::collections::BTreeSet<String> {
    let mut keys = std::collections::BTreeSet::new();
    for line in md.lines().filter(|l| l.starts_with("| `")) {
        let cell = line.split('|').nth(1).unwrap_or("");
        let mut table = String::new();
        for tok in cell.split('`').skip(1).step_by(2) {
            let tok = tok.split([' ', '=']).next().unwrap_or("").trim();
            // A key has a dot (or continues a table with one), but for the top-level ones.
            let key_like = tok.contains('.') || ["seed", "faults"].contains(&tok);
            if tok.is_empty() || tok.starts_with('[') || tok.starts_with('"') || !key_like {
                continue;
            }
            let full = if let Some(rest) = tok.strip_prefix('.') { format!("{table}{rest}") } else { tok.to_string() };
            table = full.rfind('.').map_or(String::new(), |i| full[..=i].to_string());
            // Expand {a,b} groups (at most two).
            let mut variants = vec![full];
            while let Some(v) = variants.iter().find(|v| v.contains('{')).cloned() {
                variants.retain(|x| *x != v);
                let (open, close) = (v.find('{').unwrap(), v.find('}').unwrap());
                for alt in v[open + 1..close].split(',') {
                    variants.push(format!("{}{}{}", &v[..open], alt.trim(), &v[close + 1..]));
                }
            }
            keys.extend(variants);
        }
    }
    keys
}

/// The scenario keys reference and the code name the same keys: every key the deserializer
/// reads is in docs/src/reference/scenario-keys.md (itself, or a table documented whole), and
/// every key the page names is one the code reads. A new key without a row fails here.
#[test]
fn the_keys_reference_names_every_key_of_the_code() {
    let mut code = Vec::new();
    code_keys("", 0, &mut code);
    assert!(code.len() > 150, "only {} keys found in the code", code.len());
    let md = std::fs::read_to_string(root().join("docs/src/reference/scenario-keys.md")).unwrap();
    let doc = documented_keys(&md);
    let documented = |k: &str| {
        let mut p = k.to_string();
        loop {
            if doc.contains(&p) {
                return true;
            }
            match p.rfind('.') {
                Some(i) => p.truncate(i),
                None => return false,
            }
        }
    };
    // Tables are documented by their keys (or whole); every leaf must be.
    let leaves: Vec<&String> = code.iter().filter(|k| !code.iter().any(|c| c.starts_with(&format!("{k}.")))).collect();
    let missing: Vec<&&String> = leaves.iter().filter(|k| !documented(k)).collect();
    let code_set: std::collections::BTreeSet<&str> = code.iter().map(String::as_str).collect();
    let stale: Vec<&String> = doc.iter().filter(|k| !code_set.contains(k.as_str())).collect();
    assert!(
        missing.is_empty() && stale.is_empty(),
        "undocumented keys: {missing:?}\nkeys the page names that the code does not read: {stale:?}"
    );
}

/// Every backticked name in the manual's pages (column names, keys, fields).
fn documented_names() -> Vec<String> {
    let mut names = Vec::new();
    for p in pages() {
        let md = std::fs::read_to_string(&p).unwrap();
        names.extend(md.split('`').skip(1).step_by(2).flat_map(|t| t.split([',', ' '])).map(|t| t.trim().to_string()));
    }
    names
}

/// `name` matches `pattern`, whose `<...>` parts stand for any non-empty run of characters.
fn matches(pattern: &str, name: &str) -> bool {
    let Some(open) = pattern.find('<') else { return pattern == name };
    let Some(close) = pattern[open..].find('>').map(|c| open + c) else { return false };
    let (head, rest) = (&pattern[..open], &pattern[close + 1..]);
    name.starts_with(head) && (head.len() + 1..=name.len()).any(|i| matches(rest, &name[i..]))
}

/// The output columns reference and the record agree: every column of a run with the most
/// columns (the leg walking on the reduced engine, the device's sensors, a fault, the muscle
/// wearer with its per-muscle columns) is named in the manual, as itself or as a pattern such
/// as `muscle_<name>_activation`.
#[test]
fn the_manual_names_every_output_column() {
    let sets = [
        "leg.engine=\"reduced\"",
        "sim.dt_s=0.001",
        "sim.duration_s=0.05",
        "metrics.settle_s=0.01",
        "sensors.preset=\"device\"",
        "wearer.model=\"muscles\"",
        "output.muscles=true",
        "faults=[{ kind = \"bias\", target = \"force_n\", onset_s = 0.01, bias = 10.0 }]",
    ];
    let sc = exoleg::load(Some(&root().join("assets/scenarios/treadmill_subject.toml")), &sets).unwrap();
    let (_, record) = exoleg::run_in_memory(&sc.model).unwrap();
    let columns: Vec<String> = record.columns().into_iter().map(|(n, _)| n).collect();
    assert!(columns.len() > 100, "{} columns", columns.len());
    let names = documented_names();
    let missing: Vec<&String> = columns.iter().filter(|c| !names.iter().any(|n| matches(n, c))).collect();
    assert!(missing.is_empty(), "columns the manual does not name: {missing:?}");
}
