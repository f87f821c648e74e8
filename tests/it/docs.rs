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

/// Run a shell block in `ws`: Err with its output when it fails.
fn run_shell(ws: &Path, text: &str) -> Result<(), String> {
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
        Ok(())
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
    let ws = workspace();
    let mut failures = Vec::new();
    let found = blocks(md);
    for (line, kind, text) in &found {
        let r = match kind {
            Kind::Shell => run_shell(ws.path(), text),
            Kind::Scenario => check_scenario(ws.path(), text),
        };
        if let Err(e) = r {
            failures.push(format!("{name}:{line}: {e}"));
        }
    }
    (failures, found.len())
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

/// Every marked block of the README and the manual runs (measured: 12 blocks, 4 in the README,
/// 8 in the tutorial).
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
    assert_eq!(failures.len(), 2, "{failures:#?}");
    assert!(failures[0].contains("sim.dt") && failures[1].contains("duration"), "{failures:#?}");
}
