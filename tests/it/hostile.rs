//! Replays the hostile-input corpus (`tests/corpus/`) through the readers the fuzz targets
//! exercise, and a set of hostile command lines through the binary: every input gives a
//! result or a one-line error with no empty field; none panics, aborts or hangs.

use crate::common::exe;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// A user-facing message: one line, no empty `a: : b` field, nothing dangling.
fn check_message(what: &str, msg: &str) {
    assert!(!msg.is_empty(), "{what}: empty message");
    assert_eq!(msg.trim_end().lines().count(), 1, "{what}: not one line: {msg:?}");
    assert!(
        !msg.contains(": :") && !msg.starts_with(':') && !msg.trim_end().ends_with(':'),
        "{what}: empty field in {msg:?}"
    );
}

/// Replay a corpus folder: every file has its own expected outcome in the folder's
/// `expected.txt` (`accepted`, or `refused` and a text the one-line error must contain: the
/// key or element it names), and every line there has its file.
fn replay(folder: &str, read: fn(&str) -> exoleg::Result<()>) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus").join(folder);
    let expected = std::fs::read_to_string(dir.join("expected.txt")).unwrap();
    let mut want: std::collections::BTreeMap<String, Option<String>> = expected
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let mut parts = l.splitn(3, ' ');
            let (name, outcome, needle) = (parts.next().unwrap(), parts.next().unwrap_or(""), parts.next());
            match outcome {
                "accepted" => (name.to_string(), None),
                "refused" => (name.to_string(), Some(needle.unwrap_or("").to_string())),
                other => panic!("{folder}/expected.txt: `{other}` for {name}: accepted or refused"),
            }
        })
        .collect();
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().is_some_and(|n| n != "expected.txt"))
        .collect();
    files.sort();
    let mut wrong = Vec::new();
    for f in files {
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        let text = String::from_utf8_lossy(&std::fs::read(&f).unwrap()).to_string();
        let what = f.display().to_string();
        let Some(expect) = want.remove(&name) else { panic!("{what}: no line in {folder}/expected.txt") };
        let got = match std::panic::catch_unwind(|| read(&text)) {
            Err(_) => panic!("{what}: the reader panicked"),
            Ok(r) => r,
        };
        match (got, expect) {
            (Ok(()), None) => {}
            (Err(e), Some(needle)) => {
                let msg = e.to_string();
                check_message(&what, &msg);
                assert_eq!(e.exit_code(), 2, "{what}: bad input must be exit 2: {e}");
                if !msg.contains(&needle) {
                    wrong.push(format!("{name}: the error does not name `{needle}`: {msg}"));
                }
            }
            (Ok(()), Some(n)) => wrong.push(format!("{name}: accepted, expected refused naming `{n}`")),
            (Err(e), None) => wrong.push(format!("{name}: refused, expected accepted: {e}")),
        }
    }
    assert!(want.is_empty(), "{folder}/expected.txt names missing files: {:?}", want.keys().collect::<Vec<_>>());
    assert!(wrong.is_empty(), "{folder}:\n{}", wrong.join("\n"));
}

#[test]
fn scenario_corpus() {
    replay("scenario", exoleg::scenario::fuzz_scenario);
}

#[test]
fn muscles_corpus() {
    replay("muscles", exoleg::scenario::fuzz_muscles);
}

#[test]
fn urdf_corpus() {
    replay("urdf", exoleg::scenario::fuzz_urdf);
}

#[test]
fn gait_csv_corpus() {
    replay("gait_csv", exoleg::scenario::fuzz_gait_csv);
    // Too many rows: refused while reading, not after holding them all.
    let big: String = std::iter::once("gait_cycle_pct,knee_flexion_deg\n".to_string())
        .chain((0..100_005).map(|i| format!("{},1\n", i as f64 * 1e-3)))
        .collect();
    let e = exoleg::scenario::fuzz_gait_csv(&big).unwrap_err().to_string();
    assert!(e.contains("100000"), "{e}");
}

#[test]
fn subjects_csv_corpus() {
    replay("subjects_csv", exoleg::scenario::fuzz_subjects_csv);
    // Too many rows: refused while reading.
    let big: String = std::iter::once("file,sex,height_m,mass_kg,speed_m_s\n".to_string())
        .chain((0..10_005).map(|i| format!("t{i}.csv,M,1.7,70,1.2\n")))
        .collect();
    let e = exoleg::scenario::fuzz_subjects_csv(&big).unwrap_err().to_string();
    assert!(e.contains("10000"), "{e}");
}

#[test]
fn urdf_with_a_huge_fixed_chain_is_refused_at_once() {
    // Found by fuzzing: 82,000 links welded in a chain made the loader's per-link chain walks
    // quadratic (minutes); the loader now refuses more than 256 links before any walk.
    let mut u = String::from("<robot name=\"r\"><link name=\"l0\"/>");
    for i in 1..100_000 {
        u.push_str(&format!(
            "<link name=\"l{i}\"/><joint name=\"j{i}\" type=\"fixed\"><parent link=\"l{}\"/><child link=\"l{i}\"/></joint>",
            i - 1
        ));
    }
    u.push_str("</robot>");
    let e = exoleg::scenario::fuzz_urdf(&u).unwrap_err().to_string();
    assert!(e.contains("at most 256"), "{e}");
}

#[test]
fn shard_json_corpus() {
    replay("shard_json", exoleg::study::shard::fuzz_shard_json);
}

#[test]
fn journal_corpus() {
    replay("journal", |text| exoleg::study::journal::fuzz_journal(text.as_bytes()).map(|_| ()));
}

#[test]
fn set_flag_corpus() {
    replay("set_flag", exoleg::scenario::fuzz_set_flags);
}

/// Hostile command lines through the binary: the documented exit code, a one-line message
/// when it fails, and no hang (each has 60 s; they take well under one).
#[test]
fn hostile_command_lines() {
    let tmp = tempfile::tempdir().unwrap();
    let p =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/paper_2hz_gamma100.toml").display().to_string();
    let cases: Vec<(Vec<&str>, i32)> = vec![
        (vec!["run", "--out", "o", "--set", "plant.kind=\"bench\"", "--set", "sim.duration_s=0.01"], 0),
        (vec!["run", "nope.toml"], 2),
        (vec!["run", "--out", ""], 2),
        (vec!["run", "/dev/zero", "--out", "o"], 2),
        (vec!["run", "/tmp", "--out", "o"], 2),
        (vec!["sweep", &p, "--monte-carlo", "18446744073709551615", "--vary", "human.k_p=pct(1)"], 2),
        (vec!["sweep", &p, "--monte-carlo", "18446744073709551616", "--vary", "human.k_p=pct(1)"], 2),
        (vec!["sweep", &p, "--monte-carlo", "2", "--vary", "human.k_p=pct(nan)"], 2),
        (vec!["sweep", &p, "--monte-carlo", "2", "--vary", "nope.key=pct(5)"], 2),
        (vec!["sweep", &p, "--grid", "=1"], 2),
        (vec!["sweep", &p, "--grid", "seed="], 2),
        (vec!["sweep", &p], 2),
        (vec!["robustness", &p, "--percent", "nan"], 2),
        (vec!["robustness", &p, "--percent", "1e300"], 2),
        (vec!["robustness", &p, "--samples", "0"], 2),
        (vec!["compare", "--plant", "spaceship"], 2),
        (vec!["run", "--set", "disturbance.force_accel=[{kind=\"step\",amplitude=1e6}]", "--out", "o3"], 3),
        (vec!["run", &p, "--out", "o4", "--set", "criteria.max_force_error_n=0.0", "--set", "sim.duration_s=0.01"], 4),
    ];
    for (args, code) in cases {
        let start = Instant::now();
        let mut child = Command::new(exe())
            .args(&args)
            .current_dir(tmp.path())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        while child.try_wait().unwrap().is_none() {
            if start.elapsed() > Duration::from_secs(60) {
                let _ = child.kill();
                panic!("{args:?}: hung");
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr).to_string();
        assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
        if code != 0 {
            check_message(&format!("{args:?}"), &err);
        }
    }
}

#[test]
fn fault_matrix_corpus() {
    replay("fault_matrix", |text| exoleg::study::faults::parse_matrix("matrix.toml", text).map(|_| ()));
}

/// The out-of-process protocol's datagrams (`tests/corpus/wire/`, bytes): each decodes or is
/// refused with a one-line error naming what is wrong, as `expected.txt` says; a decoded one
/// encodes back to what it was (the fuzz target's check).
#[test]
fn wire_corpus() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/corpus/wire");
    let expected = std::fs::read_to_string(dir.join("expected.txt")).unwrap();
    let mut checked = 0;
    for l in expected.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty()) {
        let mut parts = l.splitn(3, ' ');
        let (name, outcome, needle) = (parts.next().unwrap(), parts.next().unwrap_or(""), parts.next().unwrap_or(""));
        let bytes = std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let got = std::panic::catch_unwind(|| exoleg::control::wire::fuzz_wire(&bytes)).expect("the decoder panicked");
        match (outcome, got) {
            ("accepted", Ok(())) => {}
            ("refused", Err(e)) => {
                check_message(name, &e);
                assert!(e.contains(needle), "{name}: the error does not name `{needle}`: {e}");
            }
            (o, r) => panic!("{name}: expected {o}, got {r:?}"),
        }
        checked += 1;
    }
    let files = std::fs::read_dir(&dir).unwrap().count() - 1;
    assert_eq!(checked, files, "every file has its line in expected.txt");
}
