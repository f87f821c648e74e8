//! Issue 42, the reports and the values: a failsafe that keeps why (class 1), huge finite
//! numbers (6), hostile names in reports (7), messages that name the right thing (9), and
//! values that mean nothing (10). Each test names the class it covers; each failed before the
//! fix. The out-of-process routes are in `hardening4_link.rs`.

use crate::common::{build_plugin, exe};
use std::path::Path;
use std::process::{Command, Output};
use std::time::Duration;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
const BENCH: &str = "assets/scenarios/paper_2hz_gamma100.toml";
const LEG: &str = "assets/scenarios/default.toml";

fn exoleg(args: &[&str]) -> Output {
    Command::new(exe()).args(args).current_dir(ROOT).output().expect("exoleg runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Exit 2, the message naming every needle.
fn assert_bad(what: &str, o: &Output, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{what}: {e}");
    for n in needles {
        assert!(e.contains(n), "{what}: {n:?} not in {e:?}");
    }
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

/// `--set` pairs of a sampled plugin run of `lib`.
fn plugin(lib: &Path, extra: &[&str]) -> Vec<String> {
    let mut v = vec![
        "controller.kind=\"plugin\"".to_string(),
        "controller.sample_period_s=0.001".into(),
        format!("controller.plugin.library=\"{}\"", lib.display()),
    ];
    v.extend(extra.iter().map(|s| s.to_string()));
    v.into_iter().flat_map(|s| ["--set".to_string(), s]).collect()
}

fn args<'a>(head: &[&'a str], tail: &'a [String]) -> Vec<&'a str> {
    head.iter().copied().chain(tail.iter().map(String::as_str)).collect()
}

/// Class 1. Under `controller.on_stop = "failsafe"`: an isolated plugin that segfaults is kept
/// in summary.json (`controller_stop`, cause `crash`, the signal), named on stderr, and the run
/// does not pass (exit 4); a plugin's stop status keeps its reason (cause `stop`, its message)
/// on the report line and stderr, and the run goes on (exit 0). Before: exit 0 both, the reason
/// nowhere.
#[test]
fn a_failsafe_keeps_why_and_a_crash_does_not_pass() {
    let tmp = tempfile::tempdir().unwrap();
    let crashy = build_plugin("tests/plugins/crashy.c", "include");
    let out = tmp.path().join("crash");
    let sets = plugin(
        &crashy,
        &[
            "controller.on_stop=\"failsafe\"",
            "controller.plugin.isolate=true",
            "controller.plugin.params={crash=1}",
            "sim.duration_s=0.05",
        ],
    );
    let o = exoleg(&args(&["run", BENCH, "--quiet", "--out", out.to_str().unwrap()], &sets));
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(4), "{e}");
    assert!(e.contains("the controller crashed at t = 0.005000 s") && e.contains("SIGSEGV"), "{e}");
    let s = json(&out.join("summary.json"));
    assert_eq!(s["controller_stop"]["cause"], "crash", "{s}");
    assert!(s["controller_stop"]["message"].as_str().unwrap().contains("SIGSEGV"), "{s}");
    let faulty = build_plugin("tests/plugins/faulty.c", "include");
    let out = tmp.path().join("stop");
    let sets = plugin(
        &faulty,
        &["controller.on_stop=\"failsafe\"", "controller.plugin.params={mode=1, at_s=0.02}", "sim.duration_s=0.05"],
    );
    let o = exoleg(&args(&["run", BENCH, "--out", out.to_str().unwrap()], &sets));
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let s = json(&out.join("summary.json"));
    assert_eq!(s["controller_stop"]["cause"], "stop", "{s}");
    assert!(s["controller_stop"]["message"].as_str().unwrap().contains("pressure sensor fault"), "{s}");
    assert!(stdout(&o).contains("controller stop") && stdout(&o).contains("pressure sensor fault"), "{}", stdout(&o));
    assert!(stderr(&o).contains("pressure sensor fault"), "{}", stderr(&o));
}

/// Class 1. A campaign whose controller segfaults in every run (at 0.1 s, before every fault):
/// no run is "detected", every fault's onset is the injected one (0.3 s, 0.4 s; before: the
/// crash's 0.1 s, detection time 0), every row says `crashed` with the signal in `error`, and
/// the baseline is flagged. Before: "detected 2/2", exit 0.
#[test]
fn a_campaign_never_credits_a_crashing_controller_with_detection() {
    let tmp = tempfile::tempdir().unwrap();
    let crashy = build_plugin("tests/plugins/crashy.c", "include");
    let matrix = tmp.path().join("m.toml");
    std::fs::write(
        &matrix,
        "onsets_s = [0.3, 0.4]\n[[mode]]\ntarget = \"power\"\nkind = \"loss\"\n[[mode.severity]]\nlabel = \"50 ms\"\nduration_s = 0.05\n",
    )
    .unwrap();
    let out = tmp.path().join("campaign");
    let sets = plugin(
        &crashy,
        &[
            "controller.plugin.isolate=true",
            "controller.plugin.params={crash=1, at_s=0.1}",
            "actuator.failsafe=\"free\"",
            "sim.duration_s=0.6",
        ],
    );
    let head = ["faults", LEG, "--matrix", matrix.to_str().unwrap(), "--quiet", "--out", out.to_str().unwrap()];
    let o = exoleg(&args(&head, &sets));
    assert_eq!(o.status.code(), Some(4), "{}\n{}", stdout(&o), stderr(&o));
    let mut r = csv::Reader::from_path(out.join("faults.csv")).unwrap();
    let h = r.headers().unwrap().clone();
    let col = |row: &csv::StringRecord, name: &str| row[h.iter().position(|c| c == name).unwrap()].to_string();
    let rows: Vec<csv::StringRecord> = r.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 3);
    for row in &rows {
        assert_eq!(col(row, "status"), "crashed", "{row:?}");
        assert!(col(row, "error").contains("SIGSEGV"), "{row:?}");
        assert_eq!(col(row, "time_to_detection_s"), "", "{row:?}");
    }
    assert_eq!(col(&rows[1], "fault_onset_s"), "0.3");
    assert_eq!(col(&rows[2], "fault_onset_s"), "0.4");
    let fmea = std::fs::read_to_string(out.join("fmea.md")).unwrap();
    assert!(fmea.contains("| 0/2 |") && !fmea.contains("| 2/2 | 0.000"), "{fmea}");
    assert!(fmea.contains("the baseline's own controller crashed"), "{fmea}");
}

/// Class 6. `cuff_limits.comfort_n = 1e308` (before: the run hung drawing wearer.png) and the
/// other limits' huge values are exit 2 naming the key; the plots' ranges cannot overflow: a
/// panel of +-1e308 draws at once.
#[test]
fn huge_limits_are_refused_and_a_plot_of_huge_values_draws() {
    for key in
        ["cuff_limits.comfort_n", "cuff_limits.thigh_pain_n", "safety.safe_moment_nm", "safety.max_time_to_safe_s"]
    {
        let set = format!("{key}=1e308");
        let o = exoleg(&["run", "--quiet", "--out", "/nonexistent/never", "--set", &set]);
        assert_bad(key, &o, &[key]);
    }
    let (tx, rx) = std::sync::mpsc::channel();
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("huge.png");
    let p = png.clone();
    std::thread::spawn(move || {
        use exoleg::output::{panels_png, Panel};
        let pts = vec![(0.0, -1e308), (50.0, 1e308), (100.0, f64::MAX)];
        let panels = [Panel { y_label: "huge", series: vec![("x", pts, plotters::style::BLACK)] }];
        let _ = tx.send(panels_png(&p, "huge", "x", (0.0, 100.0), &panels, &[]).map_err(|e| e.to_string()));
    });
    let r = rx.recv_timeout(Duration::from_secs(30)).expect("the plot hung");
    assert!(r.is_ok(), "{r:?}");
    assert!(png.is_file());
}

/// A cell of a CSV exoleg wrote is either a number or text that no spreadsheet runs (no
/// leading `=`, `+`, `-`, `@`) and holds no control character.
fn assert_safe_cells(what: &str, path: &Path) {
    let mut r = csv::ReaderBuilder::new().has_headers(false).from_path(path).unwrap();
    for rec in r.records() {
        for cell in rec.unwrap().iter() {
            let number = cell.parse::<f64>().is_ok();
            assert!(number || !cell.starts_with(['=', '+', '-', '@']), "{what}: formula cell {cell:?}");
            assert!(!cell.chars().any(char::is_control), "{what}: control character in {cell:?}");
        }
    }
}

/// Class 7. Hostile names in gait-check (file names with `=`, an ANSI escape and a newline; a
/// subject `@evil` and an age group `+x` in subjects.csv) and in a fault matrix (severity labels
/// `=HYPERLINK(...)`, `-2 % FS`, an ANSI escape, `a|b` with a newline): no formula cell, no raw
/// escape in any file or on the terminal, every table intact (one line per row; the Markdown
/// table's columns). Before: the names went through as they were.
#[test]
fn hostile_names_reach_no_report_as_a_formula_an_escape_or_a_broken_table() {
    let tmp = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(Path::new(ROOT).join("assets/gait/v3/wbds30_treadmill_t05.csv")).unwrap();
    let dir = tmp.path().join("lab");
    std::fs::create_dir(&dir).unwrap();
    let names = ["=HYPERLINK(1).csv", "\u{1b}[31mred.csv", "two\nlines.csv"];
    let mut table = "subject,age_group,file,sex,height_m,mass_kg,leg_length_m,speed_m_s,stride_s\n".to_string();
    for (i, n) in names.iter().enumerate() {
        std::fs::write(dir.join(n), &good).unwrap();
        let subject = if i == 0 { "@evil" } else { "s" };
        table += &format!("{subject},+x,\"{n}\",F,1.57,48.4,0.79,1.08,0.9667\n");
    }
    std::fs::write(dir.join("subjects.csv"), table).unwrap();
    let out = tmp.path().join("gc");
    let o = Command::new(exe())
        .arg("gait-check")
        .arg(&dir)
        .args(["--quiet", "--strides", "2", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(matches!(o.status.code(), Some(0 | 4)), "{}\n{}", stdout(&o), stderr(&o));
    for text in [stdout(&o), stderr(&o)] {
        assert!(!text.contains('\u{1b}'), "a raw escape on the terminal: {text:?}");
    }
    let csv_path = out.join("gait_check.csv");
    assert_safe_cells("gait_check.csv", &csv_path);
    let text = std::fs::read_to_string(&csv_path).unwrap();
    assert_eq!(text.lines().count(), 1 + names.len(), "{text}");
    // A fault matrix's hostile labels.
    let matrix = tmp.path().join("m.toml");
    std::fs::write(
        &matrix,
        "onsets_s = [0.2]\n[[mode]]\ntarget = \"power\"\nkind = \"loss\"\n\
         [[mode.severity]]\nlabel = \"=HYPERLINK(\\\"http://x\\\")\"\nduration_s = 0.05\n\
         [[mode.severity]]\nlabel = \"-2 % FS\"\nduration_s = 0.06\n\
         [[mode.severity]]\nlabel = \"\\u001b[2J clear\"\nduration_s = 0.07\n\
         [[mode.severity]]\nlabel = \"a|b\\nc\"\n",
    )
    .unwrap();
    let out = tmp.path().join("campaign");
    let o = exoleg(&[
        "faults",
        LEG,
        "--matrix",
        matrix.to_str().unwrap(),
        "--set",
        "sim.duration_s=0.4",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(matches!(o.status.code(), Some(0 | 4)), "{}\n{}", stdout(&o), stderr(&o));
    for text in [stdout(&o), stderr(&o)] {
        assert!(!text.contains('\u{1b}'), "a raw escape on the terminal: {text:?}");
    }
    for f in ["faults.csv", "fmea.csv"] {
        assert_safe_cells(f, &out.join(f));
        let text = std::fs::read_to_string(out.join(f)).unwrap();
        let rows = if f == "faults.csv" { 1 + 1 + 4 } else { 1 + 1 };
        assert_eq!(text.lines().count(), rows, "{f}: {text}");
    }
    let md = std::fs::read_to_string(out.join("fmea.md")).unwrap();
    assert!(!md.contains('\u{1b}'), "{md}");
    let table: Vec<&str> = md.lines().filter(|l| l.starts_with('|')).collect();
    assert_eq!(table.len(), 3, "{md}");
    for l in &table {
        let cells = l.replace("\\|", "").matches('|').count();
        assert_eq!(cells, 12, "{l}");
    }
}

/// Class 9. gait-check names what is at a trial's path: a FIFO or a device is "not a regular
/// file", a link to a good file runs (before: "no file X" for all three, though they were
/// there).
#[test]
fn gait_check_names_what_is_there_instead_of_no_file() {
    let tmp = tempfile::tempdir().unwrap();
    let good = Path::new(ROOT).join("assets/gait/v3/wbds30_treadmill_t05.csv");
    let dir = tmp.path().join("lab");
    std::fs::create_dir(&dir).unwrap();
    std::os::unix::fs::symlink(&good, dir.join("link.csv")).unwrap();
    let fifo = std::ffi::CString::new(dir.join("fifo.csv").to_str().unwrap()).unwrap();
    // SAFETY: a valid path and mode.
    assert_eq!(unsafe { libc::mkfifo(fifo.as_ptr(), 0o600) }, 0);
    std::os::unix::fs::symlink("/dev/null", dir.join("dev.csv")).unwrap();
    let mut table = "file,sex,height_m,mass_kg,leg_length_m,speed_m_s,stride_s\n".to_string();
    for n in ["link.csv", "fifo.csv", "dev.csv"] {
        table += &format!("{n},F,1.57,48.4,0.79,1.08,0.9667\n");
    }
    std::fs::write(dir.join("subjects.csv"), table).unwrap();
    let out = tmp.path().join("out");
    let o = Command::new(exe())
        .arg("gait-check")
        .arg(&dir)
        .args(["--quiet", "--strides", "2", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(!e.contains("no file"), "{e}");
    assert!(e.lines().any(|l| l.contains("fifo.csv") && l.contains("a FIFO, not a regular file")), "{e}");
    assert!(e.lines().any(|l| l.contains("dev.csv") && l.contains("a device, not a regular file")), "{e}");
    let csv = std::fs::read_to_string(out.join("gait_check.csv")).unwrap();
    assert!(csv.lines().any(|l| l.starts_with("lab,link,") && l.contains(",ran,")), "{csv}");
}

/// Class 9. A figure's title and the campaign's report show the scenario's file name, not the
/// absolute path the command resolved (a user's folders in every figure they share).
#[test]
fn titles_show_the_scenario_file_name_not_its_absolute_path() {
    let sc = exoleg::scenario::Scenario::load(Some(&Path::new(ROOT).join(BENCH)), &[]).unwrap();
    let sc = sc.resolve(&exoleg::Resources::new()).unwrap();
    let title = exoleg::study::run_title(&sc);
    assert!(title.starts_with("paper_2hz_gamma100.toml |") && !title.contains(ROOT), "{title}");
    let tmp = tempfile::tempdir().unwrap();
    let matrix = tmp.path().join("m.toml");
    std::fs::write(
        &matrix,
        "onsets_s = [0.2]\n[[mode]]\ntarget = \"power\"\nkind = \"loss\"\n[[mode.severity]]\nlabel = \"x\"\n",
    )
    .unwrap();
    let out = tmp.path().join("c");
    let o = exoleg(&[
        "faults",
        LEG,
        "--matrix",
        matrix.to_str().unwrap(),
        "--set",
        "sim.duration_s=0.3",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(matches!(o.status.code(), Some(0 | 4)), "{}", stderr(&o));
    let md = std::fs::read_to_string(out.join("fmea.md")).unwrap();
    assert!(md.starts_with("# default.toml (with --set):") && !md.contains(ROOT), "{md}");
}

/// Class 10. Values that mean nothing are exit 2 naming them: gait-check targets that are NaN
/// or impossible (before: every trial "missed", exit 4), a fault of zero duration (before:
/// accepted, never acted), a dropout holding "the last reading" at onset 0 (before: held NaN),
/// `controller.overrun_policy` without a modelled computation to overrun (before: accepted
/// without effect).
#[test]
fn values_that_mean_nothing_are_exit_2() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("lab");
    std::fs::create_dir(&dir).unwrap();
    for (flags, want) in [
        (vec!["--min-stance", "0.9", "--max-stance", "0.1"], "--min-stance"),
        (vec!["--min-grf-r", "2"], "--min-grf-r"),
        (vec!["--min-knee-moment-r", "nan"], "--min-knee-moment-r"),
        (vec!["--flexor-within=-1"], "--flexor-within"),
        (vec!["--extensor-within-pct", "inf"], "--extensor-within-pct"),
    ] {
        let o = Command::new(exe())
            .arg("gait-check")
            .arg(&dir)
            .args(&flags)
            .arg("--out")
            .arg(tmp.path().join("o"))
            .output()
            .unwrap();
        assert_bad(want, &o, &[want]);
    }
    let cases = [
        (vec!["faults=[{target=\"valve\", kind=\"stuck\", onset_s=0.5, duration_s=0.0}]"], "faults.0.duration_s"),
        (
            vec![
                "controller.sample_period_s=0.001",
                "faults=[{target=\"force_n\", kind=\"dropout\", mode=\"hold\", onset_s=0.0}]",
            ],
            "faults.0.mode",
        ),
        (vec!["controller.overrun_policy=\"stop\""], "controller.overrun_policy"),
        (vec!["controller.sample_period_s=0.001", "controller.overrun_policy=\"hold\""], "controller.overrun_policy"),
    ];
    for (sets, want) in cases {
        let mut a = vec!["run", "--quiet", "--out", "/nonexistent/never"];
        for s in &sets {
            a.extend(["--set", s]);
        }
        let o = exoleg(&a);
        assert_bad(want, &o, &[want]);
    }
}
