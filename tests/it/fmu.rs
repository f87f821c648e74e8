//! The FMU (issue 25) from the Rust side: `exoleg fmu` packs a scenario, the instance
//! ([`exoleg::fmu::Slave`], what the C entry points wrap) runs it under a master's controller
//! exactly as `exoleg run` runs the same controller in the loop, and a master's wrong calls
//! are refused with a message (never a panic). The C library itself is exercised through FMPy
//! in `python/tests/test_fmu.py`.

use exoleg::control::{ControlOutput, ControlStop, DiscreteController, SampleInput, N_READINGS, READINGS};
use exoleg::fmu::{Phase, Slave, VarType};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The firmware conditions: 1 kHz, 16-bit sensors, one sample of delay.
const FIRMWARE: [&str; 3] = ["controller.sample_period_s=0.001", "sensors.preset=\"adc16\"", "sensors.delay_samples=1"];

fn exoleg(args: &[String]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_exoleg")).args(args).current_dir(ROOT).output().expect("exoleg runs")
}

/// An unpacked FMU.
struct Unpacked {
    _dir: tempfile::TempDir,
    resources: PathBuf,
    xml: String,
    guid: String,
}

/// A stand-in for the FMU library (the Rust side never loads it): a shared library that
/// carries the `exoleg-fmu` crate's marker for this version, as `exoleg fmu` requires.
pub fn stand_in_library() -> &'static Path {
    static LIB: std::sync::OnceLock<(tempfile::TempDir, PathBuf)> = std::sync::OnceLock::new();
    let (_, lib) = LIB.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let src = dir.path().join("stand_in.c");
        let marker = format!("exoleg-fmu-library/{}/fmi2-cs", env!("CARGO_PKG_VERSION"));
        std::fs::write(&src, format!("const char *exoleg_fmu_library_id(void) {{ return \"{marker}\"; }}\n")).unwrap();
        let lib = dir.path().join("libexoleg_fmu.so");
        let o = Command::new("cc").args(["-O2", "-fPIC", "-shared", "-o"]).arg(&lib).arg(&src).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (dir, lib)
    });
    lib
}

/// `exoleg fmu SCENARIO --set ..`, unzipped, with the [`stand_in_library`].
fn pack(scenario: &str, sets: &[&str]) -> Unpacked {
    let dir = tempfile::tempdir().unwrap();
    let fmu = dir.path().join("plant.fmu");
    let mut args = vec!["fmu".to_string(), scenario.to_string(), "--out".into(), fmu.display().to_string()];
    args.extend(["--library".to_string(), stand_in_library().display().to_string()]);
    for s in sets {
        args.extend(["--set".to_string(), s.to_string()]);
    }
    let o = exoleg(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut zip = zip::ZipArchive::new(std::fs::File::open(&fmu).unwrap()).unwrap();
    let root = dir.path().join("unzipped");
    for i in 0..zip.len() {
        let mut f = zip.by_index(i).unwrap();
        let path = root.join(f.enclosed_name().expect("names stay inside the FMU"));
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        let mut bytes = Vec::new();
        f.read_to_end(&mut bytes).unwrap();
        std::fs::write(&path, bytes).unwrap();
    }
    let xml = std::fs::read_to_string(root.join("modelDescription.xml")).unwrap();
    let guid = attr(&xml, "guid").to_string();
    assert!(root.join("binaries/linux64/exoleg.so").exists() || cfg!(not(target_os = "linux")));
    Unpacked { resources: root.join("resources"), _dir: dir, xml, guid }
}

fn attr<'a>(xml: &'a str, name: &str) -> &'a str {
    let start =
        xml.find(&format!(" {name}=\"")).unwrap_or_else(|| panic!("no {name} in the description")) + name.len() + 3;
    &xml[start..start + xml[start..].find('"').unwrap()]
}

/// ERL-SMC (the paper's Eq. 50) over the readings in the order of [`READINGS`] and the
/// nominal model (n1, n2, n3, tau_s, k_s): the one law both routes run.
fn erl_smc(v: &[f64; N_READINGS], nominal: [f64; 5]) -> f64 {
    let [n1, n2, n3, tau, ks] = nominal;
    let (k, delta, zeta) = (100.0, 15.0, 10.0);
    let e = v[10] - v[2];
    let e_dot = v[11] - v[3];
    let sl = e_dot + delta * e;
    let accel = v[12] + delta * e_dot + k * sl + zeta * sl.tanh();
    tau / (n1 * ks) * (accel + n3 * v[3] + n2 * v[7] + n1 * v[4] / tau)
}

struct ByReadings([f64; 5]);

impl DiscreteController for ByReadings {
    fn kind(&self) -> &str {
        "erl_smc_by_readings"
    }
    fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop> {
        Ok(ControlOutput::command(erl_smc(&s.reading_values(), self.0)))
    }
}

fn vr_of(slave: &Slave, name: &str) -> u32 {
    slave.variables().iter().find(|v| v.name == name).unwrap_or_else(|| panic!("no variable {name}")).vr
}

fn get(slave: &mut Slave, vrs: &[u32]) -> Vec<f64> {
    let mut out = vec![0.0; vrs.len()];
    slave.get(VarType::Real, vrs, &mut out).unwrap();
    out
}

/// A master running ERL-SMC on the FMU for `duration_s`: per communication point, the
/// command it set and the states it read (the `true_*` outputs of `states`).
fn master_run(u: &Unpacked, states: &[&str], duration_s: f64) -> (Vec<f64>, Vec<Vec<f64>>) {
    let (mut slave, _) = Slave::instantiate(&u.resources, &u.guid).unwrap();
    slave.setup_experiment(0.0, Some(duration_s)).unwrap();
    slave.enter_initialization_mode().unwrap();
    slave.exit_initialization_mode().unwrap();
    let readings: Vec<u32> = READINGS.iter().map(|r| vr_of(&slave, r.name)).collect();
    let nominal_vrs: Vec<u32> =
        ["n1", "n2", "n3", "tau_s", "k_s"].iter().map(|n| vr_of(&slave, &format!("nominal.{n}"))).collect();
    let nominal: [f64; 5] = get(&mut slave, &nominal_vrs).try_into().unwrap();
    let truth: Vec<u32> = states.iter().map(|s| vr_of(&slave, &format!("true_{s}"))).collect();
    let h = attr(&u.xml, "stepSize").parse::<f64>().unwrap();
    let n = (duration_s / h).round() as usize;
    let (mut commands, mut rows) = (Vec::new(), Vec::new());
    for k in 0..n {
        let v: [f64; N_READINGS] = get(&mut slave, &readings).try_into().unwrap();
        let cmd = erl_smc(&v, nominal);
        slave.set(VarType::Real, &[1000], &[cmd]).unwrap();
        rows.push(get(&mut slave, &truth));
        commands.push(cmd);
        slave.do_step(k as f64 * h, h).unwrap();
    }
    rows.push(get(&mut slave, &truth));
    assert!(slave.do_step(n as f64 * h, h).unwrap_err().message.contains("past the run's end"));
    (commands, rows)
}

/// The same controller through the FMU and inside `exoleg run` (a Rust trait object): the
/// same commands and the same states at every sample, bit for bit, on the bench and on the
/// Rapier leg walking a gait.
#[test]
fn master_controller_matches_the_same_controller_in_exoleg_run() {
    let cases: [(&str, &[&str], f64); 2] = [
        ("assets/scenarios/paper_2hz_gamma100.toml", &["load_force_n", "spool_m", "piston_m"], 1.0),
        ("assets/scenarios/gait_walk.toml", &["load_force_n", "spool_m", "piston_m", "knee_angle_deg"], 1.5),
    ];
    for (scenario, states, duration) in cases {
        let dur = format!("sim.duration_s={duration}");
        let sets: Vec<&str> = FIRMWARE.iter().copied().chain([dur.as_str()]).collect();
        let u = pack(scenario, &sets);
        let (commands, rows) = master_run(&u, states, duration);
        let sc = exoleg::load(Some(&Path::new(ROOT).join(scenario)), &sets).unwrap();
        let nominal = exoleg::fmu::nominal_values(&sc.model);
        let mem = exoleg::study::RunBuilder::new(&sc).controller(Box::new(ByReadings(nominal))).in_memory().unwrap();
        let w = mem.columns.len();
        let col = |name: &str| mem.columns.iter().position(|c| c == name).unwrap_or_else(|| panic!("no column {name}"));
        let (t, valve) = (col("t_s"), col("valve_command"));
        let mut compared = 0;
        for row in mem.values.chunks(w) {
            let k = (row[t] / 0.001).round() as usize;
            if (row[t] - k as f64 * 0.001).abs() > 1e-12 || k >= rows.len() {
                continue;
            }
            if k < commands.len() {
                assert_eq!(row[valve].to_bits(), commands[k].to_bits(), "{scenario}: command at sample {k}");
            }
            for (j, s) in states.iter().enumerate() {
                assert_eq!(row[col(s)].to_bits(), rows[k][j].to_bits(), "{scenario}: {s} at sample {k}");
            }
            compared += 1;
        }
        assert_eq!(compared, rows.len(), "{scenario}: every communication point compared");
        let peak = rows.iter().map(|r| r[0].abs()).fold(0.0, f64::max);
        assert!(peak > 50.0, "{scenario}: the controller drives the load ({peak} N)");
    }
}

/// The description lists every reading, the input, the parameters with the scenario's
/// values, the units, and a default experiment at the sample period.
#[test]
fn description_lists_readings_input_parameters_and_units() {
    let u = pack(
        "assets/scenarios/gait_treadmill.toml",
        &["reference.gait_file=\"assets/gait/wbds02_overground_slow.csv\"", "reference.stride_s=1.2"],
    );
    assert!(u.xml.contains("fmiVersion=\"2.0\""));
    assert!(u.xml.contains("<CoSimulation modelIdentifier=\"exoleg\""));
    for r in READINGS {
        assert!(u.xml.contains(&format!("name=\"{}\"", r.name)), "{}", r.name);
    }
    let input = u.xml.lines().find(|l| l.contains("name=\"valve_command\"")).expect("the input");
    assert!(input.contains("valueReference=\"1000\"") && input.contains("causality=\"input\""), "{input}");
    assert!(u.xml.contains("name=\"hydraulics.beta_pa\""));
    assert!(u.xml.contains("name=\"leg.mass_scale\""));
    assert!(u.xml.contains("<Unit name=\"N\"><BaseUnit kg=\"1\" m=\"1\" s=\"-2\"/></Unit>"));
    assert!(u.xml.contains("<Unit name=\"deg\"><BaseUnit rad=\"1\" factor=\"0.017453292519943295\"/></Unit>"));
    assert_eq!(attr(&u.xml, "stepSize"), "0.001");
    let (slave, _) = Slave::instantiate(&u.resources, &u.guid).unwrap();
    let names: Vec<&str> = slave.variables().iter().map(|v| v.name.as_str()).collect();
    let mut unique = names.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), names.len(), "names are unique");
    // ABI 1.1's readings take new value references after the force loop's 0-16, which keep
    // their meaning; the device's truth columns follow the contact columns.
    assert_eq!((vr_of(&slave, "force_n"), vr_of(&slave, "valve_command_limit")), (2, 16));
    assert_eq!((vr_of(&slave, "hip_rad"), vr_of(&slave, "load_pressure_pa")), (17, 39));
    assert!(names.contains(&"true_shank_cuff_force_n") && names.contains(&"true_wearer_knee_torque_nm"));
    let copied = std::fs::read(u.resources.join("files/wbds02_overground_slow.csv")).expect("the gait file travels");
    assert_eq!(copied, std::fs::read(Path::new(ROOT).join("assets/gait/wbds02_overground_slow.csv")).unwrap());
    let text = std::fs::read_to_string(u.resources.join("scenario.toml")).unwrap();
    assert!(text.contains("gait_file = \"files/wbds02_overground_slow.csv\""), "{text}");
}

/// Parameters set before initialization change the run; the start values give the
/// scenario's run; a parameter set after initialization, an output set, an unknown value
/// reference, steps out of order, a wrong GUID are refused with a message and leave the
/// instance usable.
#[test]
fn parameters_and_wrong_calls() {
    let u = pack("assets/scenarios/paper_2hz_gamma100.toml", &FIRMWARE);
    let force_after = |beta: Option<f64>| {
        let (mut s, _) = Slave::instantiate(&u.resources, &u.guid).unwrap();
        let beta_vr = vr_of(&s, "hydraulics.beta_pa");
        s.enter_initialization_mode().unwrap();
        if let Some(b) = beta {
            s.set(VarType::Real, &[beta_vr], &[b]).unwrap();
        }
        s.exit_initialization_mode().unwrap();
        s.set(VarType::Real, &[1000], &[0.002]).unwrap();
        s.do_step(0.0, 0.005).unwrap();
        let f = vr_of(&s, "true_load_force_n");
        get(&mut s, &[f])[0]
    };
    let (nominal, soft) = (force_after(None), force_after(Some(2e8)));
    assert!(nominal > 1.0 && soft > 0.0 && (nominal - soft).abs() > 0.05 * nominal, "{nominal} vs {soft}");

    let (mut s, _) = Slave::instantiate(&u.resources, &u.guid).unwrap();
    let err = |r: Result<(), exoleg::fmu::FmiError>| r.unwrap_err().message;
    assert!(err(s.do_step(0.0, 0.001)).contains("fmi2ExitInitializationMode"));
    assert!(err(s.setup_experiment(1.0, None)).contains("start time must be 0"));
    s.enter_initialization_mode().unwrap();
    s.exit_initialization_mode().unwrap();
    let beta = vr_of(&s, "hydraulics.beta_pa");
    assert!(err(s.set(VarType::Real, &[beta], &[1e9])).contains("fixed parameter"));
    assert!(err(s.set(VarType::Real, &[0], &[1.0])).contains("output"));
    assert!(err(s.set(VarType::Real, &[99_999], &[1.0])).contains("unknown Real value reference 99999"));
    assert!(err(s.do_step(0.0, -0.001)).contains("positive"));
    assert!(err(s.do_step(0.0, 0.00015)).contains("whole multiple"));
    assert!(err(s.do_step(0.5, 0.001)).contains("not the FMU's time"));
    assert!(err(s.do_step(0.0, f64::NAN)).contains("positive"));
    assert_eq!(s.phase(), Phase::Running, "refused calls leave the instance usable");
    s.do_step(0.0, 0.003).unwrap();
    assert!((s.time_s() - 0.003).abs() < 1e-12);
    s.terminate().unwrap();
    assert!(err(s.do_step(0.003, 0.001)).contains("Terminated"));
    s.reset();
    assert_eq!(s.phase(), Phase::Instantiated);

    let wrong = Slave::instantiate(&u.resources, "{00000000-0000-0000-0000-000000000000}").err().unwrap();
    assert!(wrong.message.contains("does not match"), "{}", wrong.message);
    let missing = Slave::instantiate(&u.resources.join("nope"), &u.guid).err().unwrap();
    assert!(missing.message.contains("resources folder"), "{}", missing.message);
}

/// A diverging run fails the step with the simulation's message; the instance then refuses
/// steps until it is reset, and runs again after.
#[test]
fn a_failed_step_is_an_error_and_reset_recovers() {
    let u = pack("assets/scenarios/paper_2hz_gamma100.toml", &FIRMWARE);
    let (mut s, _) = Slave::instantiate(&u.resources, &u.guid).unwrap();
    s.enter_initialization_mode().unwrap();
    s.exit_initialization_mode().unwrap();
    let e = s.set(VarType::Real, &[1000], &[f64::NAN]).and_then(|_| s.do_step(0.0, 0.001));
    assert!(e.is_err(), "a NaN command is refused");
    assert!(matches!(s.phase(), Phase::Failed | Phase::Running));
    s.reset();
    s.enter_initialization_mode().unwrap();
    s.exit_initialization_mode().unwrap();
    s.set(VarType::Real, &[1000], &[0.01]).unwrap();
    s.do_step(0.0, 0.01).unwrap();
}

/// `exoleg fmu` without its library says how to build it (exit 2, no file written).
#[test]
fn fmu_without_library_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.fmu");
    let o = exoleg(&[
        "fmu".into(),
        "--out".into(),
        out.display().to_string(),
        "--library".into(),
        dir.path().join("missing.so").display().to_string(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("missing.so"), "{err}");
    assert!(err.contains("cargo build --release -p exoleg-fmu"), "{err}");
    assert!(!out.exists());
}

/// A gait FMU takes a stop time shorter than its scenario's `metrics.settle_s` (1.1 s on
/// `gait_walk.toml`): an FMU has no summary for the settling window to shape.
#[test]
fn a_gait_fmu_takes_a_stop_time_shorter_than_its_settling_window() {
    let u = pack("assets/scenarios/gait_walk.toml", &["controller.sample_period_s=0.001"]);
    let (mut slave, _) = Slave::instantiate(&u.resources, &u.guid).unwrap();
    slave.setup_experiment(0.0, Some(0.5)).unwrap();
    slave.enter_initialization_mode().unwrap();
    slave.exit_initialization_mode().unwrap();
    slave.set(VarType::Real, &[1000], &[0.0]).unwrap();
    slave.do_step(0.0, 0.001).unwrap();
}
