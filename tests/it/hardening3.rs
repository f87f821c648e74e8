//! Issue 34, one test (or a few) per class: outputs never replace a device, a FIFO, a link or an
//! input of the command; every input is a regular file read with a cap, and the FMU library
//! is checked before it is packed; plugins fail at load and cannot fake a finished run;
//! logged channel names are names; a failed run never looks like a good one.

use crate::common::exe;
use std::os::unix::fs::{FileTypeExt, MetadataExt};
use std::path::Path;
use std::process::{Command, Output};

fn run_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(exe()).args(args).current_dir(dir).output().expect("spawn exoleg")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// Exit 2 with one line containing every needle.
fn assert_bad(what: &str, o: &Output, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{what}: {e}");
    assert_eq!(e.trim_end().lines().count(), 1, "{what}: one line: {e}");
    for n in needles {
        assert!(e.contains(n), "{what}: {n:?} not in {e:?}");
    }
}

fn scenario_path(f: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios").join(f).display().to_string()
}

/// What is at a path, to compare before and after: its kind, identity, device number, link
/// target and content.
fn state(p: &Path) -> String {
    let Ok(m) = std::fs::symlink_metadata(p) else { return "absent".into() };
    let t = m.file_type();
    let content = if t.is_file() { format!("{:?}", std::fs::read(p).unwrap()) } else { String::new() };
    let link = std::fs::read_link(p).map(|l| l.display().to_string()).unwrap_or_default();
    format!(
        "{:?} dev {} ino {} rdev {} char {} fifo {} link {link} {content}",
        t,
        m.dev(),
        m.ino(),
        m.rdev(),
        t.is_char_device(),
        t.is_fifo()
    )
}

/// Every command that writes (run, sweep, robustness, merge, compare --json, compare
/// --firmware --json, urdf --out, fmu --out), pointed at a device node (/dev/null itself and
/// one made here), a FIFO, a symbolic link, one of its own inputs and a file exoleg did not
/// write: each refused with exit 2 before it does its work, the target exactly as it was,
/// nothing left behind. Run as root, as this machine runs it: /dev/null is still the system's
/// character device afterwards.
#[test]
fn no_command_replaces_a_device_a_fifo_a_link_or_its_own_input() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let sc = t.join("s.toml");
    std::fs::copy(scenario_path("paper_2hz_gamma100.toml"), &sc).unwrap();
    let sc = sc.display().to_string();
    let short = ["--set", "plant.kind=\"bench\"", "--set", "sim.duration_s=0.01"];
    // A shard to merge, and the stand-in FMU library.
    let mut a = vec!["sweep", &sc, "--grid", "controller.gamma=100.0,200.0", "--quiet", "--shard", "0/1"];
    a.extend(short);
    a.extend(["--out", "shard"]);
    assert!(run_in(t, &a).status.success());
    let lib = crate::fmu::stand_in_library().display().to_string();
    let fifo = t.join("fifo");
    rustix::fs::mknodat(rustix::fs::CWD, &fifo, rustix::fs::FileType::Fifo, rustix::fs::Mode::from_raw_mode(0o644), 0)
        .unwrap();
    let mine = t.join("null");
    let own_device = rustix::fs::mknodat(
        rustix::fs::CWD,
        &mine,
        rustix::fs::FileType::CharacterDevice,
        rustix::fs::Mode::from_raw_mode(0o666),
        rustix::fs::makedev(1, 3),
    )
    .is_ok();
    std::fs::write(t.join("notes.txt"), "my notes").unwrap();
    // A leg scenario and a one-mode matrix for the fault campaign; a gait folder of one trial.
    let leg = t.join("leg.toml");
    std::fs::copy(scenario_path("default.toml"), &leg).unwrap();
    let leg = leg.display().to_string();
    std::fs::write(
        t.join("m.toml"),
        "onsets_s = [0.005]\n[[mode]]\ntarget = \"valve\"\nkind = \"stuck\"\n[[mode.severity]]\nlabel = \"held\"\n",
    )
    .unwrap();
    let gait = t.join("gait");
    std::fs::create_dir(&gait).unwrap();
    let v3 = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/gait/v3");
    let rows = std::fs::read_to_string(v3.join("subjects.csv")).unwrap();
    let mut rows = rows.lines();
    std::fs::write(gait.join("subjects.csv"), format!("{}\n{}\n", rows.next().unwrap(), rows.next().unwrap())).unwrap();
    std::fs::copy(v3.join("wbds20_treadmill_t05.csv"), gait.join("wbds20_treadmill_t05.csv")).unwrap();
    std::os::unix::fs::symlink("notes.txt", t.join("link")).unwrap();
    let commands: Vec<(Vec<String>, Vec<String>)> = {
        let v = |x: &[&str]| x.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let with_short = |x: &[&str]| v(&[x, &short[..]].concat());
        vec![
            (with_short(&["run", &sc, "--out"]), v(&[&sc])),
            (with_short(&["sweep", &sc, "--grid", "controller.gamma=100.0", "--quiet", "--out"]), v(&[&sc])),
            (with_short(&["robustness", &sc, "--samples", "1", "--quiet", "--out"]), v(&[&sc])),
            (v(&["merge", "shard", "--out"]), v(&["shard", "shard/runs.jsonl"])),
            (with_short(&["compare", &sc, "--json"]), v(&[&sc])),
            (v(&["compare", "--firmware", "--json"]), v(&[exe()])),
            (v(&["urdf", "--mass-kg", "70", "--height-m", "1.75", "--out"]), v(&[exe()])),
            (v(&["fmu", &sc, "--library", &lib, "--out"]), v(&[&sc, &lib])),
            (
                v(&[
                    "faults",
                    &leg,
                    "--set",
                    "sim.duration_s=0.01",
                    "--set",
                    "actuator.spool_limit_m=0.01",
                    "--matrix",
                    "m.toml",
                    "--quiet",
                    "--out",
                ]),
                v(&[&leg, "m.toml"]),
            ),
            (v(&["gait-check", "gait", "--strides", "2", "--quiet", "--out"]), v(&["gait", "gait/subjects.csv"])),
        ]
    };
    let mut targets: Vec<String> = vec!["/dev/null".into(), "fifo".into(), "link".into(), "notes.txt".into()];
    if own_device {
        targets.push("null".into());
    }
    for (cmd, inputs) in &commands {
        for target in targets.iter().chain(inputs) {
            let before = state(&t.join(target));
            let mut args: Vec<&str> = cmd.iter().map(String::as_str).collect();
            let at = args.iter().position(|a| *a == "--out" || *a == "--json").unwrap();
            args.insert(at + 1, target);
            let o = run_in(t, &args);
            assert_bad(&format!("{args:?}"), &o, &[]);
            assert_eq!(state(&t.join(target)), before, "{args:?} changed {target}");
        }
    }
    let null = std::fs::symlink_metadata("/dev/null").unwrap();
    assert!(null.file_type().is_char_device() && null.rdev() == rustix::fs::makedev(1, 3));
    let left: Vec<String> = std::fs::read_dir(t)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.contains("exoleg-tmp"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// The single files a command writes replace only exoleg's own file of that format (an FMU
/// over an FMU, a report over a report, a URDF over a URDF), written with mode 0644.
#[test]
fn single_files_replace_only_their_own_kind() {
    use std::os::unix::fs::PermissionsExt;
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let lib = crate::fmu::stand_in_library().display().to_string();
    let fmu = ["fmu", "--set", "plant.kind=\"bench\"", "--library", &lib, "--out", "a.fmu"];
    let urdf = ["urdf", "--mass-kg", "70", "--height-m", "1.75", "--out", "a.urdf"];
    let json = ["compare", "--plant", "bench", "--set", "sim.duration_s=0.01", "--json", "a.json"];
    for args in [&fmu[..], &urdf[..], &json[..]] {
        for _ in 0..2 {
            let o = run_in(t, args);
            assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        }
        let path = t.join(args.last().unwrap());
        assert_eq!(std::fs::metadata(&path).unwrap().permissions().mode() & 0o777, 0o644, "{args:?}");
    }
    // Each one's file is foreign to the others.
    for (args, other) in [(&fmu[..], "a.urdf"), (&urdf[..], "a.json"), (&json[..], "a.fmu")] {
        let mut a = args.to_vec();
        *a.last_mut().unwrap() = other;
        let before = state(&t.join(other));
        assert_bad(&format!("{a:?}"), &run_in(t, &a), &["exoleg did not write"]);
        assert_eq!(state(&t.join(other)), before);
    }
}

/// Every input path is a regular file read with a cap: `fmu --library` refuses a FIFO (no
/// hang), /dev/zero (no endless read), a text file, an empty file, a plugin and the exoleg
/// executable, and takes only exoleg's FMU library of this version; scenarios, URDFs and gait
/// files refuse FIFOs and devices the same way, and a link loop is a link loop, not "file not
/// found".
#[test]
fn inputs_are_regular_files_and_the_fmu_library_is_exolegs() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let fifo = t.join("fifo");
    rustix::fs::mknodat(rustix::fs::CWD, &fifo, rustix::fs::FileType::Fifo, rustix::fs::Mode::from_raw_mode(0o644), 0)
        .unwrap();
    std::fs::write(t.join("text.so"), "not a library").unwrap();
    std::fs::write(t.join("empty.so"), "").unwrap();
    let plugin = crate::common::build_plugin("tests/plugins/faulty.c", "include").display().to_string();
    // Another version's library: the stand-in with the version changed.
    let other = std::fs::read(crate::fmu::stand_in_library()).unwrap();
    let marker = format!("exoleg-fmu-library/{}/", env!("CARGO_PKG_VERSION"));
    let at = other.windows(marker.len()).position(|w| w == marker.as_bytes()).unwrap();
    let mut old = other.clone();
    old[at + marker.len() - 2] = b'9';
    std::fs::write(t.join("old.so"), old).unwrap();
    let cases: [(&str, &str); 7] = [
        ("fifo", "a FIFO"),
        ("/dev/zero", "a device"),
        ("text.so", "not a shared library"),
        ("empty.so", "is empty"),
        (&plugin, "not exoleg's FMU library"),
        (exe(), "not exoleg's FMU library"),
        ("old.so", "the FMU library of exoleg"),
    ];
    for (lib, needle) in cases {
        let start = std::time::Instant::now();
        let o = run_in(t, &["fmu", "--library", lib, "--out", "x.fmu"]);
        assert_bad(lib, &o, &["--library", needle]);
        assert!(start.elapsed() < std::time::Duration::from_secs(20), "{lib}: took {:?}", start.elapsed());
        assert!(!t.join("x.fmu").exists());
    }
    // Scenario, URDF and gait file: a FIFO and a device are refused, not read.
    let (a, b) = (t.join("loop_a"), t.join("loop_b"));
    std::os::unix::fs::symlink(&a, &b).unwrap();
    std::os::unix::fs::symlink(&b, &a).unwrap();
    let walk = scenario_path("gait_walk.toml");
    for (args, needle) in [
        (vec!["run", "fifo", "--out", "o"], "a FIFO"),
        (vec!["run", "/dev/zero", "--out", "o"], "a device"),
        (vec!["run", "--set", "leg.urdf=\"fifo\"", "--out", "o"], "FIFO"),
        (vec!["run", &walk, "--set", "reference.gait_file=\"/dev/zero\"", "--out", "o"], "device"),
        (vec!["run", "loop_a", "--out", "o"], "symbolic link loop"),
        (vec!["run", "--set", "leg.urdf=\"loop_a\"", "--out", "o"], "symbolic link loop"),
    ] {
        let o = run_in(t, &args);
        assert_bad(&format!("{args:?}"), &o, &[needle]);
        assert!(!stderr(&o).contains("not found"), "{args:?}: {}", stderr(&o));
    }
}

fn plugin_sets(lib: &Path, params: &str) -> Vec<String> {
    vec![
        "--set".into(),
        "controller.kind=\"plugin\"".into(),
        "--set".into(),
        format!("controller.plugin.library={:?}", lib.display().to_string()),
        "--set".into(),
        format!("controller.plugin.params={{{params}}}"),
        "--set".into(),
        "controller.sample_period_s=0.001".into(),
        "--set".into(),
        "plant.kind=\"bench\"".into(),
        "--set".into(),
        "sim.duration_s=0.02".into(),
    ]
}

fn args<'a>(head: &[&'a str], sets: &'a [String]) -> Vec<&'a str> {
    head.iter().copied().chain(sets.iter().map(String::as_str)).collect()
}

/// A plugin calling a function nothing defines is refused when it loads, naming the symbol
/// (exit 2, before any run: also in a sweep), not exit 127 at its first sample.
#[test]
fn a_plugin_with_an_unresolved_symbol_is_refused_at_load() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let lib = crate::common::build_plugin("tests/plugins/unresolved.c", "include");
    let sets = plugin_sets(&lib, "");
    let o = run_in(t, &args(&["run", "--out", "o"], &sets));
    assert_bad("run", &o, &["controller.plugin.library", "exoleg_test_no_such_function"]);
    let sc = scenario_path("paper_2hz_gamma100.toml");
    let o = run_in(t, &args(&["sweep", &sc, "--grid", "seed=1,2,3,4", "--quiet", "--jobs", "2", "--out", "sw"], &sets));
    assert_bad("sweep", &o, &["exoleg_test_no_such_function"]);
    assert!(!t.join("o").exists() && !t.join("sw").exists());
}

/// A plugin that calls exit(0) in a run or at creation cannot make the run look finished:
/// exit 3 with a message, no outputs; one that changes the working directory (when it loads,
/// or at every sample) does not move the outputs of a relative `--out`.
#[test]
fn a_plugin_cannot_fake_a_finished_run_or_move_its_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let lib = crate::common::build_plugin("tests/plugins/rogue.c", "include");
    for params in ["mode=1.0", "mode=2.0"] {
        let sets = plugin_sets(&lib, params);
        let o = run_in(t, &args(&["run", "--out", "o"], &sets));
        assert_eq!(o.status.code(), Some(3), "{params}: {}", stderr(&o));
        assert!(stderr(&o).contains("called exit()"), "{params}: {}", stderr(&o));
        assert!(!t.join("o").exists(), "{params}");
    }
    let elsewhere = tempfile::tempdir().unwrap();
    let sets = plugin_sets(&lib, "mode=3.0");
    let o = Command::new(exe())
        .args(args(&["run", "--out", "moved"], &sets))
        .current_dir(t)
        .env("EXOLEG_TEST_CHDIR", elsewhere.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(t.join("moved/summary.json").is_file() && t.join("moved/timeseries.csv").is_file());
    assert_eq!(std::fs::read_dir(elsewhere.path()).unwrap().count(), 0);
    assert!(!Path::new("/moved").exists());
}

/// A controller from Rust naming its channels (what the CSV header and the Parquet schema
/// are made of).
struct Named(Vec<String>);

impl exoleg::control::DiscreteController for Named {
    fn kind(&self) -> &str {
        "named"
    }
    fn update(
        &mut self,
        _: &exoleg::control::SampleInput,
    ) -> Result<exoleg::control::ControlOutput, exoleg::control::ControlStop> {
        Ok(exoleg::control::ControlOutput::command(0.0))
    }
    fn log_names(&self) -> Vec<String> {
        self.0.clone()
    }
}

/// Logged channel names are names, whatever route they take: a plugin's
/// (`controller.plugin.log`, the hostile corpus has the rest), a Rust controller's; refused with
/// exit 2 before anything is written, naming the name. A plugin's message is printed with its
/// control characters escaped.
#[test]
fn logged_channel_names_are_names_and_messages_are_one_line() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let lib = crate::common::build_plugin("tests/plugins/rogue.c", "include");
    let mut sets = plugin_sets(&lib, "mode=4.0");
    sets.extend(["--set".into(), "controller.plugin.log=[\"a,b\", \"c\"]".into()]);
    let o = run_in(t, &args(&["run", "--out", "o"], &sets));
    assert_bad("comma", &o, &["controller.plugin.log", "\"a,b\""]);
    assert!(!t.join("o").exists());
    // The warning's message, escaped, in summary.json.
    let sets = plugin_sets(&lib, "mode=4.0");
    let o = run_in(t, &args(&["run", "--out", "o"], &sets));
    assert!(o.status.success(), "{}", stderr(&o));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(t.join("o/summary.json")).unwrap()).unwrap();
    let last = summary["controller_warnings"]["last"].as_str().unwrap();
    assert!(!last.chars().any(char::is_control), "{last:?}");
    assert!(last.contains("bad\\n\\u{1b}[2Jline"), "{last:?}");
    // A Rust controller: the same rule, when the run starts.
    for (names, needle) in [
        (vec!["ok".to_string(), "ok".into()], "given twice"),
        (vec!["x\"y".into()], "\"x\\\"y\""),
        (vec![String::new()], "empty name"),
        (vec!["two\nlines".into()], "\"two\\nlines\""),
    ] {
        let sc =
            exoleg::load(None, &["plant.kind=\"bench\"", "sim.duration_s=0.01", "controller.sample_period_s=0.001"])
                .unwrap();
        let e = exoleg::study::RunBuilder::new(&sc)
            .controller(Box::new(Named(names.clone())))
            .write_to(&t.join("rust"))
            .unwrap_err();
        assert_eq!(e.exit_code(), 2, "{names:?}: {e}");
        assert!(e.to_string().contains(needle), "{names:?}: {e}");
        assert_eq!(e.to_string().lines().count(), 1);
        assert!(!t.join("rust").exists());
    }
}

/// A failed run never looks like a good one when replayed: the summary.json of a run whose
/// controller came from outside the scenario (Rust here; Python in the pytest suite) is
/// refused by `exoleg run` (exit 2, naming the controller), while a plugin run's, whose
/// scenario holds the plugin, replays the plugin (the same time series, byte for byte).
#[test]
fn a_summary_replays_only_the_controller_it_holds() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let sc = exoleg::load(None, &["plant.kind=\"bench\"", "sim.duration_s=0.01", "controller.sample_period_s=0.001"])
        .unwrap();
    exoleg::study::RunBuilder::new(&sc)
        .controller(Box::new(Named(vec!["fine".into()])))
        .write_to(&t.join("r"))
        .unwrap();
    let o = run_in(t, &["run", "r/summary.json", "--out", "again"]);
    assert_bad("replay", &o, &["external_controller", "`named`"]);
    assert!(!t.join("again").exists());
    let lib = crate::common::build_plugin("tests/plugins/rogue.c", "include");
    let sets = plugin_sets(&lib, "mode=0.0");
    assert!(run_in(t, &args(&["run", "--out", "p"], &sets)).status.success());
    let o = run_in(t, &["run", "p/summary.json", "--out", "p2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = |d: &str| std::fs::read(t.join(d).join("timeseries.csv")).unwrap();
    assert_eq!(csv("p"), csv("p2"));
}

/// The audit's smaller items: `not_walking` is absent where it is not evaluated; merge checks
/// a shard's study against its plan; a sample period longer than the run is refused; a huge
/// value is not echoed whole.
#[test]
fn smaller_items() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // Standing on the carriage is not walking, nor evaluated as such: no `not_walking`.
    let stand = scenario_path("stand.toml");
    let o =
        run_in(t, &["run", &stand, "--set", "sim.duration_s=2.2", "--set", "leg.engine=\"reduced\"", "--out", "st"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(t.join("st/summary.json")).unwrap()).unwrap();
    assert!(s.get("not_walking").is_none(), "{}", s["not_walking"]);
    // A robustness shard relabelled with another percent (its plan hash still matches).
    let sc = scenario_path("paper_2hz_gamma100.toml");
    let mut a = vec!["robustness", &sc, "--samples", "2", "--quiet", "--shard", "0/1", "--out", "r"];
    a.extend(["--set", "plant.kind=\"bench\"", "--set", "sim.duration_s=0.01"]);
    assert!(run_in(t, &a).status.success());
    let meta = std::fs::read_to_string(t.join("r/shard.json")).unwrap();
    let mut m: serde_json::Value = serde_json::from_str(&meta).unwrap();
    m["study"]["percent"] = serde_json::json!(5.0);
    std::fs::write(t.join("r/shard.json"), m.to_string()).unwrap();
    assert_bad("relabelled", &run_in(t, &["merge", "r", "--out", "m"]), &["study", "robustness at 5 %"]);
    // A sample period longer than the run.
    let o = run_in(t, &["run", "--set", "controller.kind=\"dtznn\"", "--set", "controller.sample_period_s=2.0"]);
    assert_bad("period", &o, &["controller.sample_period_s", "longer than the run"]);
    // A 100 kB value in an error: clipped, on one line.
    let big = format!("controller.kind=\"{}\"", "x".repeat(100_000));
    let o = run_in(t, &["run", "--set", &big, "--out", "o"]);
    assert_bad("big", &o, &["bytes in all"]);
    assert!(stderr(&o).len() < 10_000, "{} bytes", stderr(&o).len());
}
