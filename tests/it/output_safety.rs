//! No user file is ever deleted, no temporary folder outlives its run (issue 22.4, 22.10):
//! exoleg replaces a folder only if it is empty, or it wrote it and it holds nothing else;
//! a signal (Ctrl-C, `kill`, Slurm, Kubernetes) removes the temporary folder; a run in another
//! process never removes a live run's temporary folder.

use crate::common::exe;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn run(dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new(exe()).args(args).current_dir(dir).output().unwrap()
}

const SHORT: [&str; 4] = ["--set", "plant.kind=\"bench\"", "--set", "sim.duration_s=0.01"];

fn hidden_temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.contains(".exoleg-tmp-"))
        .collect()
}

/// A folder without exoleg's marker, or with anything the marker does not list, is refused
/// with exit 2 and left exactly as it was; an exoleg folder is replaced.
#[test]
fn user_files_are_never_deleted() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let cases: [(&str, &str, &[u8]); 3] = [
        ("plotdir", "force_tracking.png/notes.txt", b"mine"),
        ("summary", "summary.json", b"{\"my\": \"own\"}"),
        ("thesis", "timeseries.csv", b"t,x\n"),
    ];
    for (dir, file, content) in cases {
        let p = t.join(dir).join(file);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, content).unwrap();
        let o = run(t, &[&["run", "--out", dir][..], &SHORT].concat());
        assert_eq!(o.status.code(), Some(2), "{dir}: {}", String::from_utf8_lossy(&o.stderr));
        assert!(String::from_utf8_lossy(&o.stderr).contains("did not write"));
        assert_eq!(std::fs::read(&p).unwrap(), content, "{dir}: the user's file");
    }
    // An exoleg folder is replaced; one a user has since put a file into is not.
    let args = [&["run", "--out", "ok"][..], &SHORT].concat();
    assert!(run(t, &args).status.success());
    assert!(run(t, &args).status.success(), "an exoleg folder is replaced");
    std::fs::write(t.join("ok/notes.md"), "keep").unwrap();
    assert_eq!(run(t, &args).status.code(), Some(2));
    assert_eq!(std::fs::read_to_string(t.join("ok/notes.md")).unwrap(), "keep");
    // A sweep's run folders: a user's file inside run_0001 keeps the whole sweep from replacing it.
    let sc = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/paper_2hz_gamma100.toml");
    let sweep = [
        &["sweep", sc.to_str().unwrap(), "--grid", "controller.gamma=100.0,200.0", "--run-outputs", "--quiet"][..],
        &["--set", "sim.duration_s=0.01", "--out", "sw"],
    ]
    .concat();
    assert!(run(t, &sweep).status.success());
    std::fs::write(t.join("sw/run_0001/thesis.tex"), "\\begin{document}").unwrap();
    let o = run(t, &sweep);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("run_0001/thesis.tex"));
    assert!(t.join("sw/run_0001/thesis.tex").exists());
    // `--out` holding an input of the run: refused before anything runs.
    std::fs::create_dir(t.join("in")).unwrap();
    std::fs::copy(&sc, t.join("in/s.toml")).unwrap();
    let o = run(t, &["run", "in/s.toml", "--out", "in", "--set", "sim.duration_s=0.01"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("holds an input"));
    // `--out out/.` names no folder: refused before the simulation.
    let start = Instant::now();
    let o = run(t, &["run", "--out", "fresh/.", "--set", "sim.duration_s=60.0"]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(start.elapsed() < Duration::from_secs(10), "refused only after the run");
    assert!(String::from_utf8_lossy(&o.stderr).contains("no folder name"));
}

/// SIGINT, SIGTERM and SIGHUP end a run with 128 + the signal and remove its temporary
/// folder; `--out` stays as it was.
#[test]
fn signals_leave_no_temporary_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    for (sig, code) in [("INT", 130), ("TERM", 143), ("HUP", 129)] {
        let mut child = Command::new(exe())
            .args(["run", "--quiet", "--out", "o", "--set", "sim.duration_s=3600.0"])
            .current_dir(t)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Wait until the run writes into its temporary folder.
        let start = Instant::now();
        while hidden_temporaries(t).is_empty() {
            assert!(start.elapsed() < Duration::from_secs(20), "no temporary folder");
            std::thread::sleep(Duration::from_millis(20));
        }
        std::thread::sleep(Duration::from_millis(200));
        let ok = Command::new("kill").args([&format!("-{sig}"), &child.id().to_string()]).status().unwrap();
        assert!(ok.success());
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(code), "SIG{sig}");
        assert!(hidden_temporaries(t).is_empty(), "SIG{sig} left {:?}", hidden_temporaries(t));
        assert!(!t.join("o").exists());
    }
}

/// A live run's temporary folder survives another run into the same place (its lock says it
/// is alive, whatever the PID namespace); a dead one's (kill -9) is removed by the next run.
#[test]
fn a_live_runs_temporary_folder_is_not_removed() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let mut live = Command::new(exe())
        .args(["run", "--quiet", "--out", "o", "--set", "sim.duration_s=3600.0"])
        .current_dir(t)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while hidden_temporaries(t).is_empty() {
        assert!(start.elapsed() < Duration::from_secs(20), "no temporary folder");
        std::thread::sleep(Duration::from_millis(20));
    }
    let theirs = hidden_temporaries(t);
    assert!(run(t, &[&["run", "--out", "o"][..], &SHORT].concat()).status.success());
    for n in &theirs {
        assert!(t.join(n).exists(), "the live run's {n} was removed");
    }
    live.kill().unwrap();
    live.wait().unwrap();
    // Killed without a chance to clean up: the next run into the same place removes it.
    assert!(run(t, &[&["run", "--out", "o"][..], &SHORT].concat()).status.success());
    assert!(hidden_temporaries(t).is_empty(), "{:?}", hidden_temporaries(t));
}
