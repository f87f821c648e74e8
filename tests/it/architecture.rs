//! The layout keeps its promise: no import circle between files anywhere in `src/` (through
//! `crate::` and `super::` paths alike), and the top-level modules depend on each other only in
//! the declared direction ([`LAYERS`], the same order as `src/lib.rs` states).
//!
//! A file's imports are the paths it names in code (comments and `#[cfg(test)]` parts left
//! out): `crate::a::b::Item`, `super::x::Item`, `self::x`, grouped `use` included. A path is
//! followed through modules to the file that defines its last module or item (an item
//! re-exported by a `mod.rs` is found in the sibling file that defines it). A module's
//! `mod.rs` declaring or re-exporting its children is its facade, not an import.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The top-level modules from the ground floor up: a module may import only from the layers
/// below its own.
const LAYERS: [&[&str]; 11] = [
    &["error", "integrator", "faults", "profile"],
    &["record", "hydraulics", "sensors", "fsio"],
    &["disturbance", "leg", "muscles"],
    &["reference"],
    &["human", "control", "metrics"],
    &["plant", "hil"],
    &["sim"],
    &["session", "output"],
    &["scenario"],
    &["study", "fmu"],
    &["cli"],
];

struct File {
    /// Module path, e.g. ["leg", "rapier", "build"] (a mod.rs is its directory's module).
    module: Vec<String>,
    /// The code, without comments and tests.
    code: String,
}

fn files(dir: &str) -> BTreeMap<PathBuf, File> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join(dir);
    let mut out = BTreeMap::new();
    let mut stack = vec![root.clone()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
                continue;
            }
            let rel = p.strip_prefix(&root).unwrap();
            // main.rs is the binary (it uses the library as `exoleg::`).
            if p.extension().is_none_or(|x| x != "rs") || rel == Path::new("main.rs") {
                continue;
            }
            let mut module: Vec<String> =
                rel.iter().map(|c| c.to_string_lossy().trim_end_matches(".rs").to_string()).collect();
            if matches!(module.last().map(String::as_str), Some("mod" | "lib" | "main")) {
                module.pop();
            }
            let text = std::fs::read_to_string(&p).unwrap();
            let code = text.split("#[cfg(test)]").next().unwrap();
            let code: String = code
                .lines()
                .filter(|l| !l.trim_start().starts_with("//"))
                .map(|l| l.split(" // ").next().unwrap_or(l))
                .collect::<Vec<_>>()
                .join("\n");
            out.insert(rel.to_path_buf(), File { module, code });
        }
    }
    out
}

/// Names a file defines at its top level (items, not methods).
fn defined(code: &str) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    for line in code.lines().filter(|l| !l.starts_with(' ') && !l.starts_with('}')) {
        let mut words = line.split(|c: char| !(c.is_alphanumeric() || c == '_')).filter(|w| !w.is_empty());
        while let Some(w) = words.next() {
            if matches!(w, "struct" | "enum" | "fn" | "trait" | "type" | "const" | "static" | "mod") {
                if let Some(name) = words.next() {
                    out.insert(name.to_string());
                }
                break;
            }
        }
    }
    out
}

/// Every `crate::`, `super::` and `self::` path in `code`, groups expanded.
fn paths(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    let b = code.as_bytes();
    let mut i = 0;
    while i < b.len() {
        let rest = &code[i..];
        let start = ["crate::", "super::", "self::"].iter().find(|p| rest.starts_with(**p));
        let boundary = i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_' || b[i - 1] == b':');
        match start {
            Some(_) if boundary => {
                let end = path_end(rest);
                expand(&rest[..end], &mut out);
                i += end.max(1);
            }
            _ => i += 1,
        }
    }
    out
}

/// Length of a path with its `{..}` groups (balanced).
fn path_end(s: &str) -> usize {
    let mut depth = 0i32;
    for (j, c) in s.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth > 0 => depth -= 1,
            c if depth == 0 && !(c.is_alphanumeric() || c == '_' || c == ':' || c == '*') => return j,
            _ => {}
        }
    }
    s.len()
}

/// `a::{b, c::{d}}` -> `a::b`, `a::c::d`.
fn expand(p: &str, out: &mut Vec<String>) {
    let Some(open) = p.find('{') else {
        out.push(p.trim_end_matches("::").to_string());
        return;
    };
    let prefix = &p[..open];
    let inner = &p[open + 1..p.rfind('}').unwrap_or(p.len())];
    let mut depth = 0;
    let mut part = String::new();
    for c in inner.chars().chain(std::iter::once(',')) {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            _ => {}
        }
        if c == ',' && depth == 0 {
            let t: String = part.split_whitespace().collect();
            if !t.is_empty() && t != "self" {
                expand(&format!("{prefix}{t}"), out);
            } else if t == "self" {
                out.push(prefix.trim_end_matches("::").to_string());
            }
            part.clear();
        } else {
            part.push(c);
        }
    }
}

/// The file a path leads to, from the file of module `from`.
fn resolve(
    path: &str,
    from: &[String],
    modules: &BTreeMap<Vec<String>, PathBuf>,
    defs: &BTreeMap<PathBuf, BTreeSet<String>>,
) -> Option<PathBuf> {
    let mut segs: Vec<&str> = path.split("::").filter(|s| !s.is_empty()).collect();
    let mut cur: Vec<String> = match segs.first().copied() {
        Some("crate") => Vec::new(),
        Some("self") => from.to_vec(),
        Some("super") => from.to_vec(),
        _ => return None,
    };
    while segs.first() == Some(&"super") {
        cur.pop();
        segs.remove(0);
    }
    if matches!(segs.first().copied(), Some("crate" | "self")) {
        segs.remove(0);
    }
    for s in segs {
        let mut next = cur.clone();
        next.push(s.to_string());
        if modules.contains_key(&next) {
            cur = next;
            continue;
        }
        // An item of module `cur`: the file that defines it (the module's own file, or a child
        // file it re-exports from).
        let own = modules.get(&cur)?;
        if defs.get(own).is_some_and(|d| d.contains(s)) {
            return Some(own.clone());
        }
        // A child's first, then any descendant's (the crate root re-exports `crate::Result`).
        let defining = |deep: bool| {
            modules
                .iter()
                .filter(|(m, _)| m.starts_with(&cur) && (m.len() == cur.len() + 1 || deep && m.len() > cur.len()))
                .find_map(|(_, f)| defs.get(f).filter(|d| d.contains(s)).map(|_| f.clone()))
        };
        return Some(defining(false).or_else(|| defining(true)).unwrap_or_else(|| own.clone()));
    }
    modules.get(&cur).cloned()
}

/// File -> the files it imports, for the crate in the folder `dir` (`src`, `python/src`).
fn file_graph(dir: &str) -> BTreeMap<PathBuf, BTreeSet<PathBuf>> {
    let files = files(dir);
    let modules: BTreeMap<Vec<String>, PathBuf> = files.iter().map(|(p, f)| (f.module.clone(), p.clone())).collect();
    let defs: BTreeMap<PathBuf, BTreeSet<String>> = files.iter().map(|(p, f)| (p.clone(), defined(&f.code))).collect();
    let mut g = BTreeMap::new();
    for (p, f) in &files {
        let mut to = BTreeSet::new();
        for path in paths(&f.code) {
            if let Some(t) = resolve(&path, &f.module, &modules, &defs) {
                // A facade (mod.rs) naming its own children is not an import.
                let facade = p.ends_with("mod.rs") && files[&t].module.starts_with(&f.module);
                if t != *p && !facade {
                    to.insert(t);
                }
            }
        }
        g.insert(p.clone(), to);
    }
    g
}

fn find_cycle<T: Ord + Clone + std::fmt::Debug>(g: &BTreeMap<T, BTreeSet<T>>) -> Option<Vec<T>> {
    fn visit<T: Ord + Clone>(
        n: &T,
        g: &BTreeMap<T, BTreeSet<T>>,
        path: &mut Vec<T>,
        done: &mut BTreeSet<T>,
    ) -> Option<Vec<T>> {
        if let Some(i) = path.iter().position(|p| p == n) {
            return Some(path[i..].to_vec());
        }
        if done.contains(n) {
            return None;
        }
        path.push(n.clone());
        for m in g.get(n).into_iter().flatten() {
            if let Some(c) = visit(m, g, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(n.clone());
        None
    }
    let mut done = BTreeSet::new();
    g.keys().find_map(|n| visit(n, g, &mut Vec::new(), &mut done))
}

#[test]
fn no_import_circle_between_files() {
    let g = file_graph("src");
    assert!(g.len() >= 60, "files found: {}", g.len());
    // The test sees what it must: the reduced plant imports the integrator, a rapier file its
    // module's Leg.
    assert!(g[Path::new("plant/reduced_knee_plant.rs")].contains(Path::new("integrator.rs")));
    assert!(g[Path::new("leg/rapier/step.rs")].contains(Path::new("leg/rapier/mod.rs")));
    if let Some(c) = find_cycle(&g) {
        let names: Vec<String> = c.iter().map(|p| p.display().to_string()).collect();
        panic!("import circle: {} -> {}", names.join(" -> "), names[0]);
    }
}

/// The Python bindings (python/src) have no import circle either: Obs and the command reader
/// (obs.rs) serve both the callback (controller.rs) and your loop (stepwise.rs).
#[test]
fn no_import_circle_in_the_python_bindings() {
    let g = file_graph("python/src");
    assert!(g.len() >= 4, "files found: {}", g.len());
    assert!(g[Path::new("stepwise.rs")].contains(Path::new("obs.rs")));
    assert!(g[Path::new("controller.rs")].contains(Path::new("stepwise.rs")));
    if let Some(c) = find_cycle(&g) {
        let names: Vec<String> = c.iter().map(|p| p.display().to_string()).collect();
        panic!("import circle in python/src: {} -> {}", names.join(" -> "), names[0]);
    }
}

#[test]
fn modules_depend_only_on_the_layers_below() {
    let layer = |m: &str| LAYERS.iter().position(|l| l.contains(&m));
    let top = |p: &Path| p.iter().next().unwrap().to_string_lossy().trim_end_matches(".rs").to_string();
    let mut wrong = Vec::new();
    for (from, to) in file_graph("src") {
        let a = top(&from);
        if a == "lib" || a == "main" {
            continue;
        }
        let la = layer(&a).unwrap_or_else(|| panic!("module `{a}` is in no layer of LAYERS"));
        for t in to {
            let b = top(&t);
            let lb = layer(&b).unwrap_or_else(|| panic!("module `{b}` is in no layer of LAYERS"));
            if a != b && lb >= la {
                wrong.push(format!("{} -> {} ({a} is layer {la}, {b} layer {lb})", from.display(), t.display()));
            }
        }
    }
    assert!(wrong.is_empty(), "imports against the declared direction:\n{}", wrong.join("\n"));
}

/// The path reader and resolver catch the kinds of import the layout is made of.
#[test]
fn the_import_reader_sees_grouped_and_super_paths() {
    let ps = paths("use super::{a::B, c, d::{E, F}};\nlet x = crate::leg::pose::pose_of(1);\nfoo::crate::x");
    assert_eq!(ps, vec!["super::a::B", "super::c", "super::d::E", "super::d::F", "crate::leg::pose::pose_of"]);
    assert_eq!(
        defined("pub struct Leg {\nfn helper() {}\n    fn method() {}\npub(crate) const X: u8 = 1;"),
        ["Leg", "X", "helper"].iter().map(|s| s.to_string()).collect()
    );
}
