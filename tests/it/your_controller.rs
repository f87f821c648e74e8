//! Your own controller in the loop (issue 21): the same controller (ERL-SMC) built in, as a
//! Rust trait object written here (outside the crate), and as a C plugin gives the same
//! time series, bit for bit; plugin faults and bad input are clean errors; sweeps with a
//! plugin are the same for any number of jobs; the C header agrees with the Rust structs.

use exoleg::control::plugin::{ExolegCommand, ExolegInfo, ExolegParam, ExolegReadings, ABI_MAJOR, ABI_MINOR};
use exoleg::control::{ControlOutput, ControlStop, DiscreteController, NominalModel, SampleInput};
use sha2::{Digest, Sha256};
use std::mem::{offset_of, size_of};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The firmware conditions of the acceptance: 1 kHz, 16-bit sensors, one sample of delay.
const FIRMWARE: [&str; 3] = ["controller.sample_period_s=0.001", "sensors.preset=\"adc16\"", "sensors.delay_samples=1"];

/// ERL-SMC as a user writes it against the public interface (the law of the paper's Eq. 50,
/// in the order of exoleg's built-in).
struct MyErlSmc {
    nominal: NominalModel,
    k: f64,
    delta: f64,
    zeta: f64,
}

impl DiscreteController for MyErlSmc {
    fn kind(&self) -> &str {
        "my_erl_smc"
    }
    fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop> {
        let (r, y, c) = (&s.r, &s.y, &self.nominal.c);
        let e = r.value - y.force_n;
        let e_dot = r.rate - y.force_rate_n_per_s;
        let sl = e_dot + self.delta * e;
        let accel = r.accel + self.delta * e_dot + self.k * sl + self.zeta * sl.tanh();
        let u = c.tau_s / (c.n1 * c.k_s)
            * (accel + c.n3 * y.force_rate_n_per_s + c.n2 * y.piston_accel_m_s2 + c.n1 * y.spool_m / c.tau_s);
        Ok(ControlOutput::command(u))
    }
}

fn exoleg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_exoleg")).args(args).current_dir(ROOT).output().expect("exoleg runs")
}

fn sha(p: &Path) -> String {
    format!("{:x}", Sha256::digest(std::fs::read(p).expect("read")))
}

/// Build a C file of `tests/plugins` (or the example) into a shared library, once per test
/// binary.
fn plugin(source: &str) -> PathBuf {
    crate::common::build_plugin(source, "include")
}

fn erl_plugin_sets(lib: &Path, k: f64) -> Vec<String> {
    vec![
        "controller.kind=\"plugin\"".into(),
        format!("controller.plugin.library={:?}", lib.display().to_string()),
        format!("controller.plugin.params={{k={k:?}, delta=15.0, zeta=10.0}}"),
    ]
}

fn run_cli(scenario: &str, sets: &[String], out: &Path) -> Output {
    let mut args = vec!["run".to_string(), "--quiet".into(), "--out".into(), out.display().to_string()];
    args.push(format!("assets/scenarios/{scenario}.toml"));
    for s in FIRMWARE.iter().map(|s| s.to_string()).chain(sets.iter().cloned()) {
        args.push("--set".into());
        args.push(s);
    }
    exoleg(&args.iter().map(String::as_str).collect::<Vec<_>>())
}

/// Built in, as a Rust trait object, as a C plugin: the same `timeseries.csv`, byte for byte
/// (the same arithmetic in the same order), on the paper's 2 Hz case and on gait_walk.
#[test]
fn one_controller_three_routes_give_identical_timeseries() {
    let tmp = tempfile::tempdir().unwrap();
    let lib = plugin("examples/c_controller/erl_smc.c");
    for (scenario, k) in [("paper_2hz_gamma100", 100.0), ("gait_walk", 200.0)] {
        let builtin = tmp.path().join(format!("{scenario}_builtin"));
        let o = run_cli(scenario, &["controller.kind=\"erl_smc\"".into()], &builtin);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let c_plugin = tmp.path().join(format!("{scenario}_plugin"));
        let o = run_cli(scenario, &erl_plugin_sets(&lib, k), &c_plugin);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let path = PathBuf::from(ROOT).join(format!("assets/scenarios/{scenario}.toml"));
        let sc = exoleg::load(Some(&path), &FIRMWARE).unwrap();
        let mine = MyErlSmc { nominal: sc.model.nominal, k, delta: 15.0, zeta: 10.0 };
        let rust = tmp.path().join(format!("{scenario}_rust"));
        exoleg::study::RunBuilder::new(&sc).controller(Box::new(mine)).write_to(&rust).unwrap();
        let want = sha(&builtin.join("timeseries.csv"));
        assert_eq!(sha(&c_plugin.join("timeseries.csv")), want, "{scenario}: C plugin");
        assert_eq!(sha(&rust.join("timeseries.csv")), want, "{scenario}: Rust trait object");
    }
}

fn expect_exit(o: &Output, code: i32, needles: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(code), "stderr: {err}");
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    for n in needles {
        assert!(err.contains(n), "`{n}` not in: {err}");
    }
}

fn faulty_sets(params: &str) -> Vec<String> {
    let lib = plugin("tests/plugins/faulty.c");
    vec![
        "controller.kind=\"plugin\"".into(),
        format!("controller.plugin.library={:?}", lib.display().to_string()),
        format!("controller.plugin.params={{{params}}}"),
        "controller.plugin.log=[\"force_counts\", \"counts_valid\"]".into(),
    ]
}

/// Bad input names the key (exit 2, nothing written); a plugin that stops the run or gives a
/// non-finite command fails it with exit 3, naming the plugin, the status and the time.
#[test]
fn plugin_faults_and_bad_input_are_clean_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let lib = |p: &str| vec!["controller.kind=\"plugin\"".to_string(), format!("controller.plugin.library={p:?}")];
    let missing = tmp.path().join("nope.so").display().to_string();
    expect_exit(&run_cli("paper_2hz_gamma100", &lib(&missing), &out), 2, &["controller.plugin.library", "not found"]);
    let step = plugin("tests/plugins/missing_step.c").display().to_string();
    expect_exit(&run_cli("paper_2hz_gamma100", &lib(&step), &out), 2, &["controller.plugin.library", "exoleg_step"]);
    let abi = plugin("tests/plugins/wrong_abi.c").display().to_string();
    expect_exit(&run_cli("paper_2hz_gamma100", &lib(&abi), &out), 2, &["controller.plugin.library", "ABI version 2.0"]);
    let text = tmp.path().join("text.so");
    std::fs::write(&text, "not a library").unwrap();
    let text = text.display().to_string();
    expect_exit(&run_cli("paper_2hz_gamma100", &lib(&text), &out), 2, &["controller.plugin.library", "cannot load"]);
    let nan_param = faulty_sets("gain=\"big\"");
    expect_exit(&run_cli("paper_2hz_gamma100", &nan_param, &out), 2, &["controller.plugin.params.gain", "number"]);
    expect_exit(&run_cli("paper_2hz_gamma100", &faulty_sets("mode=3"), &out), 2, &["controller.plugin", "NULL"]);
    let continuous = [faulty_sets("mode=0"), vec!["controller.sample_period_s=0.0".into()]].concat();
    expect_exit(&run_cli("paper_2hz_gamma100", &continuous, &out), 2, &["controller.kind", "sample_period_s"]);
    let stop = run_cli("paper_2hz_gamma100", &faulty_sets("mode=1, at_s=0.05"), &out);
    expect_exit(&stop, 3, &["libfaulty.so", "status 2", "pressure sensor fault", "t = 0.050000 s"]);
    let nan = run_cli("paper_2hz_gamma100", &faulty_sets("mode=2, at_s=0.05"), &out);
    expect_exit(&nan, 3, &["libfaulty.so", "NaN", "t = 0.050000 s"]);
    assert!(!out.exists(), "a failed run leaves no output folder");
}

/// A plugin's warnings are counted in summary.json; its logged channels are columns; the raw
/// A/D counts reach it (the reading is counts * lsb).
#[test]
fn plugin_warnings_logs_and_counts() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = run_cli("paper_2hz_gamma100", &faulty_sets("mode=4, gain=1e-5"), &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["controller_warnings"]["samples"], 1000, "one warning per sample at 1 kHz over 1 s");
    assert!(s["controller_warnings"]["last"].as_str().unwrap().contains("warned at 0.999"));
    let csv = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let (ic, iv) = (header.iter().position(|h| *h == "log_force_counts").unwrap(), header.len() - 1);
    assert_eq!(header[iv], "log_counts_valid");
    let lf = header.iter().position(|h| *h == "load_force_n").unwrap();
    let rows: Vec<Vec<f64>> = csv.lines().skip(1).map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    // adc16 over the load cell's default +-5000 N; the reading is one sample old (delay 1)
    // and noise-free, so counts * lsb is the previous sample's load force to half an LSB.
    let lsb = 2.0 * 5000.0 / 65536.0;
    let mut biggest = 0.0f64;
    for k in 2..rows.len() - 1 {
        assert_eq!(rows[k][iv], 1.0);
        let counts = rows[k][ic];
        assert_eq!(counts.fract(), 0.0);
        assert!((counts * lsb - rows[k - 1][lf]).abs() <= 0.5 * lsb + 1e-9, "row {k}: {counts}");
        biggest = biggest.max(counts.abs());
    }
    // Measured: the 200 N sine reaches about 1300 counts.
    assert!(biggest > 1000.0, "{biggest}");
}

/// A 64-run Monte Carlo with a C plugin: the same runs.jsonl on one and two jobs, and one
/// instance created and destroyed per run.
#[test]
fn plugin_sweeps_are_the_same_for_any_jobs_and_count_their_instances() {
    let tmp = tempfile::tempdir().unwrap();
    let counts = tmp.path().join("counts.txt");
    let mut args: Vec<String> = ["sweep", "assets/scenarios/paper_2hz_gamma100.toml", "--monte-carlo", "64"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    args.extend(["--vary".into(), "hydraulics.beta_pa=pct(10)".into(), "--quiet".into()]);
    for s in FIRMWARE.iter().map(|s| s.to_string()).chain(faulty_sets("gain=1e-6")).chain(["sim.duration_s=0.2".into()])
    {
        args.extend(["--set".into(), s]);
    }
    let mut outs = Vec::new();
    for jobs in ["1", "2"] {
        let out = tmp.path().join(format!("jobs{jobs}"));
        let mut a = args.clone();
        a.extend(["--jobs".into(), jobs.into(), "--out".into(), out.display().to_string()]);
        let o = Command::new(env!("CARGO_BIN_EXE_exoleg"))
            .args(&a)
            .env("EXOLEG_TEST_COUNTS", &counts)
            .current_dir(ROOT)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        outs.push(std::fs::read(out.join("runs.jsonl")).unwrap());
    }
    assert_eq!(outs[0], outs[1]);
    assert_eq!(String::from_utf8_lossy(&outs[0]).lines().count(), 64);
    let c = std::fs::read_to_string(&counts).unwrap();
    // 64 runs per sweep, two sweeps; validation builds no instance.
    assert_eq!(c.lines().filter(|l| *l == "c").count(), 128);
    assert_eq!(c.lines().filter(|l| *l == "d").count(), 128);
}

/// The header and the Rust structs agree: every size and offset, as a C compiler sees the
/// header.
#[test]
fn the_c_header_matches_the_rust_structs() {
    let tmp = tempfile::tempdir().unwrap();
    let exe = tmp.path().join("layout");
    let o = Command::new("cc")
        .args(["-I", "include", "-o"])
        .arg(&exe)
        .arg("tests/plugins/layout.c")
        .current_dir(ROOT)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let c = String::from_utf8(Command::new(&exe).output().unwrap().stdout).unwrap();
    macro_rules! f {
        ($t:ty, $($f:ident),*) => { vec![$(format!("{}.{} {}", stringify!($t), stringify!($f), offset_of!($t, $f))),*] };
    }
    let mut rust = vec![
        format!("ExolegParam {}", size_of::<ExolegParam>()),
        format!("ExolegInfo {}", size_of::<ExolegInfo>()),
        format!("ExolegReadings {}", size_of::<ExolegReadings>()),
        format!("ExolegCommand {}", size_of::<ExolegCommand>()),
    ];
    rust.extend(f!(ExolegParam, name, value));
    rust.extend(f!(
        ExolegInfo,
        size,
        abi_version,
        sample_period_s,
        valve_command_limit,
        nominal_n1,
        nominal_n2,
        nominal_n3,
        nominal_tau_s,
        nominal_k_s,
        seed,
        n_params,
        reserved,
        params
    ));
    rust.extend(f!(
        ExolegReadings,
        size,
        counts_valid,
        t_s,
        period_s,
        force_n,
        force_rate_n_per_s,
        spool_m,
        piston_m,
        piston_velocity_m_s,
        piston_accel_m_s2,
        knee_rad,
        knee_rate_rad_s,
        ref_force_n,
        ref_force_rate_n_per_s,
        ref_force_accel_n_per_s2,
        next_ref_force_n,
        next_ref_force_rate_n_per_s,
        next_ref_force_accel_n_per_s2,
        valve_command_limit,
        counts,
        hip_rad,
        hip_rate_rad_s,
        thigh_accel_m_s2,
        thigh_gyro_rad_s,
        shank_accel_m_s2,
        shank_gyro_rad_s,
        heel_force_n,
        forefoot_force_n,
        foot_contact,
        thigh_cuff_force_n,
        shank_cuff_force_n,
        pressure_a_pa,
        pressure_b_pa,
        supply_pressure_pa,
        load_pressure_pa,
        device_counts_valid,
        reserved1,
        device_counts
    ));
    // ABI 1.1: the device's sensors at the end of the readings; the 1.0 prefix as it was
    // (the offsets above for the fields up to `counts` are the 1.0 header's).
    rust.push(format!("EXOLEG_ABI_VERSION {}", (ABI_MAJOR << 16) | ABI_MINOR));
    assert_eq!((ABI_MAJOR, ABI_MINOR), (1, 1));
    rust.extend(f!(ExolegCommand, size, reserved, valve_command, disturbance_estimate_n_per_s2, log, message));
    assert_eq!(c.lines().collect::<Vec<_>>(), rust);
}

/// The Rust example (a PI force controller from outside the crate) runs and tracks: built by
/// `cargo test`, run here.
#[test]
fn the_rust_example_runs() {
    let exe = std::env::current_exe().unwrap();
    let example = exe.parent().unwrap().parent().unwrap().join("examples").join("pi_controller");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("pi");
    let o = Command::new(&example).arg("assets/scenarios/default.toml").arg(&out).current_dir(ROOT).output();
    let o = o.unwrap_or_else(|e| panic!("{}: {e}", example.display()));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    // Measured: 11.91 N max |F_L - F_d| on the 200 N, 2 Hz sine (RMS 5.76 N).
    let max = s["max_abs_force_error_n"].as_f64().unwrap();
    assert!(max < 30.0 && max > 1.0, "{max}");
    assert!(std::fs::read_to_string(out.join("timeseries.csv"))
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .ends_with("log_integral_n_s"));
}
