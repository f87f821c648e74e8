#![allow(dead_code)]
//! Helpers shared by the integration tests.

pub mod leg_reference;

use exoleg::metrics::Summary;
use exoleg::record::MemoryRecord;
use exoleg::{Resources, Scenario};

/// A finished run with its whole record.
pub struct Out {
    pub summary: Summary,
    pub record: MemoryRecord,
}

/// Resolve and run a scenario, keeping the record.
pub fn run_scenario(s: &Scenario) -> exoleg::Result<Out> {
    let sc = s.resolve(&Resources::new())?;
    let (summary, record) = exoleg::run_in_memory(&sc.model)?;
    Ok(Out { summary, record })
}

fn strings(sets: &[&str]) -> Vec<String> {
    sets.iter().map(|s| s.to_string()).collect()
}

/// The embedded default scenario (paper Figure 5 case) moved to the bench plant, with overrides.
pub fn scenario(sets: &[&str]) -> Scenario {
    let sets: Vec<String> =
        std::iter::once("plant.kind=\"bench\"").chain(sets.iter().copied()).map(String::from).collect();
    Scenario::load(None, &sets).expect("scenario")
}

/// Run the bench version of the embedded default scenario with overrides.
pub fn run(sets: &[&str]) -> Out {
    run_scenario(&scenario(sets)).expect("run")
}

/// The embedded default scenario as it is (the leg plant), with overrides.
pub fn leg_scenario(sets: &[&str]) -> Scenario {
    Scenario::load(None, &strings(sets)).expect("scenario")
}

/// Run the embedded default scenario on the leg with overrides.
pub fn leg_run(sets: &[&str]) -> Out {
    run_scenario(&leg_scenario(sets)).expect("run")
}

/// A shipped scenario file with overrides.
pub fn shipped(file: &str, sets: &[&str]) -> Scenario {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios").join(file);
    Scenario::load(Some(&p), &strings(sets)).expect("scenario")
}

/// Knee angle series (deg) of a leg run.
pub fn knee_deg(out: &Out) -> Vec<f64> {
    out.record.series(|r| r.leg.expect("leg run").knee_angle_deg)
}

/// Mean of a slice.
pub fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len() as f64
}

/// Path of the exoleg binary.
pub fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_exoleg")
}

/// Build a C file (a path under the repository) against the header folder `include` into a
/// shared library, once per test binary and (source, include) pair.
pub fn build_plugin(source: &str, include: &str) -> std::path::PathBuf {
    use std::path::Path;
    use std::process::Command;
    static DIR: std::sync::OnceLock<tempfile::TempDir> = std::sync::OnceLock::new();
    // One build at a time: two tests asking for the same library at once compiled it to the
    // same temporary name, and one loaded the other's half-written file.
    static BUILD: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one = BUILD.lock().unwrap_or_else(|e| e.into_inner());
    let root = env!("CARGO_MANIFEST_DIR");
    let dir = DIR.get_or_init(|| tempfile::tempdir().expect("tempdir"));
    let stem = Path::new(source).file_stem().unwrap().to_string_lossy().to_string();
    let tag = if include == "include" { String::new() } else { format!("_{}", include.replace(['/', '.'], "_")) };
    let lib = dir.path().join(format!("lib{stem}{tag}.so"));
    if !lib.exists() {
        let tmp = dir.path().join(format!("lib{stem}{tag}.{}.so", std::process::id()));
        let o = Command::new("cc")
            .args(["-O2", "-fPIC", "-shared", "-ffp-contract=off", "-I", include, "-o"])
            .arg(&tmp)
            .arg(source)
            .arg("-lm")
            .current_dir(root)
            .output()
            .expect("cc runs");
        assert!(o.status.success(), "cc {source}: {}", String::from_utf8_lossy(&o.stderr));
        std::fs::rename(&tmp, &lib).unwrap();
    }
    lib
}
