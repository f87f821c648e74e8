//! The examples that no other test runs: the speed benchmark (examples/speed.rs) and the
//! step-response figure (examples/step_response.rs), both built by `cargo test`.

use std::path::PathBuf;
use std::process::Command;

fn example(name: &str) -> PathBuf {
    std::path::Path::new(crate::common::exe()).parent().unwrap().join("examples").join(name)
}

/// `speed --case stand_reduced --repeats 1 --json`: one figure per case, finite and positive.
#[test]
fn the_speed_example_runs() {
    let o =
        Command::new(example("speed")).args(["--case", "stand_reduced", "--repeats", "1", "--json"]).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let loop_s = v["stand_reduced"]["loop_sim_s_per_s"].as_f64().unwrap();
    let whole_s = v["stand_reduced"]["whole_sim_s_per_s"].as_f64().unwrap();
    assert!(loop_s > 0.0 && whole_s > 0.0 && loop_s.is_finite(), "{v}");
}

/// `step_response OUT.png` writes the figure and prints the two wearers' answers: the muscle
/// wearer's moment at 150 ms well past the 10 N m step (measured -23.73 N m, limit -15), the
/// impedance wearer's within 10 % of it (measured -9.71 N m).
#[test]
fn the_step_response_example_draws_its_figure() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("step.png");
    let o = Command::new(example("step_response")).arg(&png).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::metadata(&png).unwrap().len() > 10_000);
    let out = String::from_utf8_lossy(&o.stdout);
    let line = out.lines().find(|l| l.trim_start().starts_with("150 ms")).unwrap_or_else(|| panic!("{out}"));
    let figures: Vec<f64> =
        line.split_whitespace().filter_map(|t| t.trim_end_matches(',').parse::<f64>().ok()).skip(1).collect();
    let (muscles_nm, impedance_nm) = (figures[0], figures[2]);
    assert!(muscles_nm < -15.0, "{line}");
    assert!((impedance_nm + 10.0).abs() < 1.0, "{line}");
}
