//! The whole controller (issue 32): a controller that decides the assistance from the device's
//! own sensors (phase_assist), `reference.force = "none"`, the wearer's figures and indicator
//! files, ABI 1.1 with a 1.0 plugin, and the device's keys refused when wrong.

use crate::common::{build_plugin, exe};
use sha2::{Digest, Sha256};
use std::path::Path;
use std::process::{Command, Output};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn exoleg(args: &[&str]) -> Output {
    Command::new(exe()).args(args).current_dir(ROOT).output().expect("exoleg runs")
}

fn sha(bytes: &[u8]) -> String {
    format!("{:x}", Sha256::digest(bytes))
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("summary.json")).unwrap()).unwrap()
}

/// `examples/phase_assist.toml` with the C plugin: it walks, detects every heel strike with
/// the heel sensor within a few samples (the `device` preset: a 20 N threshold, 500 Hz),
/// logs its phase within a few % of the truth, supports the loading response, and the run
/// writes the wearer's figures, `wearer.png` and the indicator files. Measured: 5 of 5 heel
/// strikes, median latency 1.0 ms, phase RMSE 0.33 %, stance device share 0.052, cuff RMS
/// 21 / 17 N.
#[test]
fn phase_assist_walks_on_the_devices_sensors() {
    let lib = build_plugin("examples/c_controller/phase_assist.c", "include");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("pa");
    let lib_set = format!("controller.plugin.library=\"{}\"", lib.display());
    let o =
        exoleg(&["run", "--quiet", "--out", out.to_str().unwrap(), "examples/phase_assist.toml", "--set", &lib_set]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = summary(&out);
    assert_eq!(s["not_walking"].as_array().unwrap().len(), 0, "{}", s["not_walking"]);
    assert!(s["max_abs_force_error_n"].is_null() && s["rms_force_error_n"].is_null());
    let w = &s["wearer"];
    let p = &w["phase_estimate"];
    assert_eq!(p["detected"], p["heel_strikes"]);
    assert!(p["heel_strikes"].as_u64().unwrap() >= 4);
    let latency = p["median_latency_s"].as_f64().unwrap();
    let rmse = p["phase_rmse_pct"].as_f64().unwrap();
    assert!((0.0..=0.003).contains(&latency), "{latency}");
    assert!(rmse < 1.0, "{rmse}");
    // The loading response's extension support: the device gives a positive share there.
    assert!(w["phases"][0]["device_share"].as_f64().unwrap() > 0.03, "{}", w["phases"][0]);
    assert!(w["thigh_cuff"]["rms_n"].as_f64().unwrap() < 60.0, "{}", w["thigh_cuff"]);
    assert!(out.join("wearer.png").exists());
    let ind = std::fs::read_to_string(out.join("indicators/gait_phase_rmse_pct.yaml")).unwrap();
    assert_eq!(ind, format!("type: 'scalar'\nvalue: {}\n", ryu::Buffer::new().format(rmse)));
    assert!(std::fs::read_dir(out.join("indicators")).unwrap().count() >= 30);
}

/// A plugin built against the ABI 1.0 header (git 36f8bac, kept in tests/plugins/abi_1_0)
/// loads under the 1.1 host and gives the same time series as before 1.1, bit for bit: on the
/// bench the whole file is the one the 1.0 host wrote; on the leg the file without the
/// device's new columns is. The 1.1 build of the same source gives the same bytes.
#[test]
fn a_plugin_built_against_abi_1_0_gives_the_same_output() {
    let old = build_plugin("examples/c_controller/erl_smc.c", "tests/plugins/abi_1_0");
    let new = build_plugin("examples/c_controller/erl_smc.c", "include");
    let tmp = tempfile::tempdir().unwrap();
    // (scenario, controller.plugin.params.k, the timeseries.csv of the 1.0 host (exoleg at
    // 36f8bac) with the 1.0 build, without the device's columns on the leg).
    let cases = [
        ("assets/scenarios/paper_2hz_gamma100.toml", "100.0", PRE_ABI_1_1[0]),
        ("assets/scenarios/gait_walk.toml", "200.0", PRE_ABI_1_1[1]),
    ];
    for (scenario, k, before) in cases {
        let mut files = Vec::new();
        for (tag, lib) in [("old", &old), ("new", &new)] {
            let out = tmp.path().join(format!("{tag}_{}", Path::new(scenario).file_stem().unwrap().to_string_lossy()));
            let sets = [
                "controller.kind=\"plugin\"".to_string(),
                format!("controller.plugin.library=\"{}\"", lib.display()),
                format!("controller.plugin.params={{k={k}, delta=15.0, zeta=10.0}}"),
                "controller.sample_period_s=0.001".into(),
                "sensors.preset=\"adc16\"".into(),
                "sensors.delay_samples=1".into(),
            ];
            let mut args = vec!["run", "--quiet", "--out", out.to_str().unwrap(), scenario];
            for s in &sets {
                args.extend(["--set", s.as_str()]);
            }
            let o = exoleg(&args);
            assert!(o.status.success(), "{tag} {scenario}: {}", String::from_utf8_lossy(&o.stderr));
            files.push(std::fs::read_to_string(out.join("timeseries.csv")).unwrap());
        }
        assert_eq!(files[0], files[1], "{scenario}: the 1.0 and 1.1 builds");
        let stripped = crate::shipped_outputs::without_device_columns(&files[0]);
        assert_eq!(sha(stripped.as_bytes()), before, "{scenario}: the 1.0 host's file");
    }
}

/// What exoleg wrote before ABI 1.1 (exoleg at 36f8bac, the 1.0 build of erl_smc.c, the
/// settings of the test above): the SHA-256 of `timeseries.csv` on paper_2hz_gamma100 and
/// gait_walk.
const PRE_ABI_1_1: [&str; 2] = [
    "2c84e2f408f7e9ba284b3f22879762c91faf45daf19b3da40cb1f4ce23a56dca",
    "bda0f0e0a0aee638f45770b662a5a375b63356546f84646f356e1f2a6eadf770",
];
