//! A study keeps every finished run (issue 34, class 3): a 200-run sweep killed with SIGKILL
//! half way keeps the line of every run it finished, `--resume` makes only the missing runs,
//! and the final `runs.jsonl` and `aggregate.csv` are those of an uninterrupted sweep, byte
//! for byte, with one job and with two. A journal of another plan, or one a second study is
//! writing, is refused; a line cut short by the kill is dropped and its run made again.

use crate::common::exe;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn exoleg(t: &Path, args: &[&str]) -> Output {
    Command::new(exe()).args(args).current_dir(t).output().unwrap()
}

/// A 200-run Monte-Carlo sweep on the bench plant (10 s runs: about 3 s in all on one core).
fn sweep(sc: &str, jobs: &str, out: &str, extra: &[&str]) -> Vec<String> {
    let mut a: Vec<String> = [
        "sweep",
        sc,
        "--monte-carlo",
        "200",
        "--vary",
        "hydraulics.beta_pa=pct(10)",
        "--set",
        "plant.kind=\"bench\"",
        "--set",
        "sim.duration_s=10.0",
        "--quiet",
        "--jobs",
        jobs,
        "--out",
        out,
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    a.extend(extra.iter().map(|s| s.to_string()));
    a
}

fn lines(p: &Path) -> Vec<String> {
    std::fs::read_to_string(p).map(|t| t.lines().map(String::from).collect()).unwrap_or_default()
}

/// Start the sweep, wait until its journal holds `at` lines, SIGKILL it; returns the lines
/// seen before the kill.
fn kill_at(t: &Path, args: &[String], at: usize) -> Vec<String> {
    let journal = t.join(".k.exoleg-partial/runs.jsonl");
    let mut child = Command::new(exe()).args(args).current_dir(t).stdout(Stdio::null()).spawn().unwrap();
    let start = Instant::now();
    let seen = loop {
        let l = lines(&journal);
        if l.len() >= at {
            break l;
        }
        assert!(child.try_wait().unwrap().is_none(), "the sweep ended before {at} runs");
        assert!(start.elapsed() < Duration::from_secs(120), "no progress");
        std::thread::sleep(Duration::from_millis(2));
    };
    child.kill().unwrap();
    child.wait().unwrap();
    seen
}

#[test]
fn a_killed_sweep_keeps_its_runs_and_resume_completes_it_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let sc = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/paper_2hz_gamma100.toml");
    let sc = sc.to_str().unwrap();
    let args = sweep(sc, "2", "full", &[]);
    let o = exoleg(t, &args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let full = std::fs::read(t.join("full/runs.jsonl")).unwrap();
    let full_agg = std::fs::read(t.join("full/aggregate.csv")).unwrap();
    let full_lines = lines(&t.join("full/runs.jsonl"));
    assert!(!t.join(".full.exoleg-partial").exists(), "a finished study leaves no journal");
    for jobs in ["1", "2"] {
        let _ = std::fs::remove_dir_all(t.join("k"));
        let seen = kill_at(t, &sweep(sc, jobs, "k", &[]), 100);
        // Every line seen before the kill is still there, whole, and is the uninterrupted
        // sweep's line of that run; --out itself is untouched.
        let kept = lines(&t.join(".k.exoleg-partial/runs.jsonl"));
        assert!(kept.len() >= seen.len() && kept.len() < 200, "jobs {jobs}: {} kept", kept.len());
        assert_eq!(&kept[..seen.len()], &seen[..]);
        for l in &kept {
            let i = serde_json::from_str::<serde_json::Value>(l).unwrap()["index"].as_u64().unwrap() as usize;
            assert_eq!(l, &full_lines[i], "jobs {jobs}: run {i}");
        }
        assert!(!t.join("k").exists());
        eprintln!("jobs {jobs}: SIGKILL after {} runs seen, {} kept", seen.len(), kept.len());
        // Resumed: only the missing runs, then the uninterrupted sweep's bytes.
        let o = exoleg(t, &sweep(sc, jobs, "k", &["--resume"]).iter().map(String::as_str).collect::<Vec<_>>());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        assert!(err.contains(&format!("{} finished runs kept", kept.len())), "{err}");
        assert_eq!(std::fs::read(t.join("k/runs.jsonl")).unwrap(), full, "jobs {jobs}: runs.jsonl");
        assert_eq!(std::fs::read(t.join("k/aggregate.csv")).unwrap(), full_agg, "jobs {jobs}: aggregate.csv");
        assert!(!t.join(".k.exoleg-partial").exists());
    }
}

/// `--resume` refuses a journal of another plan (and a run of it leaves the journal as it
/// was); without `--resume` a new study replaces it; a last line cut short is dropped and its
/// run made again; a line of another run is refused; a second study into the same place
/// while one writes is refused; with nothing to resume, `--resume` runs the whole plan.
#[test]
fn resume_takes_only_a_journal_of_the_same_plan() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let sc = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/paper_2hz_gamma100.toml");
    let sc = sc.to_str().unwrap();
    let base = |out: &str, extra: &[&str]| {
        let mut a = vec!["sweep", sc, "--grid", "controller.gamma=100.0,150.0,200.0,250.0", "--quiet"];
        a.extend(["--set", "plant.kind=\"bench\"", "--set", "sim.duration_s=0.2", "--out", out]);
        a.extend(extra);
        a.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let run = |a: &[String]| exoleg(t, &a.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(run(&base("full", &[])).status.success());
    let full = std::fs::read(t.join("full/runs.jsonl")).unwrap();
    // Nothing to resume: the whole plan.
    assert!(run(&base("fresh", &["--resume"])).status.success());
    assert_eq!(std::fs::read(t.join("fresh/runs.jsonl")).unwrap(), full);
    // A journal as a kill leaves it: two whole lines and a third cut short.
    let journal = t.join(".k.exoleg-partial");
    let make = || {
        std::fs::create_dir_all(&journal).unwrap();
        let meta = serde_json::json!({
            "format": "exoleg-journal-1", "study": {"kind": "sweep"}, "plan_hash": "", "runs": 4,
            "shard": [0, 1], "run_outputs": false, "caller_controller": false
        });
        let lines: Vec<&[u8]> = full.split(|b| *b == b'\n').collect();
        let text = [lines[2], b"\n", lines[0], b"\n", &lines[1][..40]].concat();
        std::fs::write(journal.join("runs.jsonl"), text).unwrap();
        meta
    };
    // Its plan hash: what the sweep itself writes (a sweep killed at once).
    let mut meta = make();
    let hash = {
        let o = run(&base("probe", &["--shard", "0/1"]));
        assert!(o.status.success());
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(t.join("probe/shard.json")).unwrap()).unwrap();
        s["plan_hash"].as_str().unwrap().to_string()
    };
    meta["plan_hash"] = serde_json::json!(hash);
    std::fs::write(journal.join("journal.json"), meta.to_string()).unwrap();
    // Another plan: refused, the journal left as it was.
    let before = std::fs::read(journal.join("runs.jsonl")).unwrap();
    let o = run(&base("k", &["--resume", "--set", "seed=9"]));
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("another plan"));
    assert_eq!(std::fs::read(journal.join("runs.jsonl")).unwrap(), before);
    // The same plan: two runs kept, the cut line's run and the last made again.
    let o = run(&base("k", &["--resume"]));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("2 finished runs kept"));
    assert_eq!(std::fs::read(t.join("k/runs.jsonl")).unwrap(), full);
    assert!(!journal.exists());
    // A line that is no run of the plan: refused, naming the journal.
    make();
    std::fs::write(journal.join("journal.json"), meta.to_string()).unwrap();
    std::fs::write(journal.join("runs.jsonl"), "{\"index\": 7}\n").unwrap();
    let o = run(&base("k", &["--resume"]));
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("runs.jsonl"), "{}", String::from_utf8_lossy(&o.stderr));
    // Without --resume: a new study, the journal replaced.
    assert!(run(&base("k", &[])).status.success());
    assert_eq!(std::fs::read(t.join("k/runs.jsonl")).unwrap(), full);
    // A study writing the journal now: a second one into the same place is refused.
    std::fs::create_dir_all(&journal).unwrap();
    std::fs::write(journal.join("journal.json"), meta.to_string()).unwrap();
    let lock = std::fs::File::create(journal.join(".exoleg-lock")).unwrap();
    rustix::fs::flock(&lock, rustix::fs::FlockOperation::NonBlockingLockExclusive).unwrap();
    let o = run(&base("k", &[]));
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("another study is writing"));
    // Robustness resumes the same way.
    drop(lock);
    let rob = |out: &str, extra: &[&str]| {
        let mut a = vec!["robustness", sc, "--samples", "6", "--quiet", "--set", "plant.kind=\"bench\""];
        a.extend(["--set", "sim.duration_s=0.2", "--out", out]);
        a.extend(extra);
        exoleg(t, &a)
    };
    assert!(rob("rob", &[]).status.code().is_some_and(|c| c == 0 || c == 4));
    assert!(rob("robshard", &["--shard", "0/1"]).status.success());
    let want = std::fs::read(t.join("rob/runs.jsonl")).unwrap();
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(t.join("robshard/shard.json")).unwrap()).unwrap();
    let rj = t.join(".rob.exoleg-partial");
    std::fs::create_dir_all(&rj).unwrap();
    let meta = serde_json::json!({
        "format": "exoleg-journal-1", "study": s["study"], "plan_hash": s["plan_hash"], "runs": 6,
        "shard": [0, 1], "run_outputs": false, "caller_controller": false
    });
    std::fs::write(rj.join("journal.json"), meta.to_string()).unwrap();
    let first: Vec<u8> = want.split(|b| *b == b'\n').take(3).flat_map(|l| [l, b"\n"].concat()).collect();
    std::fs::write(rj.join("runs.jsonl"), first).unwrap();
    let o = rob("rob", &["--resume"]);
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("3 finished runs kept"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(std::fs::read(t.join("rob/runs.jsonl")).unwrap(), want);
}

/// A plugin that calls exit(0) in the fourth run of a sweep ends the process with exit 3, and
/// the three runs before it keep their lines; SIGTERM (Slurm's preemption) keeps them too.
#[test]
fn a_plugin_exit_or_sigterm_keeps_the_finished_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let lib = crate::common::build_plugin("tests/plugins/rogue.c", "include").display().to_string();
    let sc = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/paper_2hz_gamma100.toml");
    let sc = sc.to_str().unwrap();
    let lib_set = format!("controller.plugin.library={lib:?}");
    let mut a = vec!["sweep", sc, "--grid", "controller.plugin.params.at_s=9.0,9.0,9.0,0.005", "--jobs", "1"];
    a.extend(["--quiet", "--set", "controller.kind=\"plugin\"", "--set", &lib_set]);
    a.extend(["--set", "controller.plugin.params={mode=1.0}", "--set", "controller.sample_period_s=0.001"]);
    a.extend(["--set", "plant.kind=\"bench\"", "--set", "sim.duration_s=0.02", "--out", "p"]);
    let o = exoleg(t, &a);
    assert_eq!(o.status.code(), Some(3), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("called exit()"));
    assert_eq!(lines(&t.join(".p.exoleg-partial/runs.jsonl")).len(), 3);
    assert!(!t.join("p").exists());
    // SIGTERM half way: exit 143, the journal kept, the temporary output folder removed.
    let args = sweep(sc, "1", "k", &[]);
    let mut child = Command::new(exe()).args(&args).current_dir(t).stdout(Stdio::null()).spawn().unwrap();
    let journal = t.join(".k.exoleg-partial/runs.jsonl");
    while lines(&journal).len() < 20 {
        std::thread::sleep(Duration::from_millis(2));
    }
    assert!(Command::new("kill").args(["-TERM", &child.id().to_string()]).status().unwrap().success());
    assert_eq!(child.wait().unwrap().code(), Some(143));
    assert!(lines(&journal).len() >= 20);
    let tmp_left =
        std::fs::read_dir(t).unwrap().flatten().any(|e| e.file_name().to_string_lossy().contains("k.exoleg-tmp"));
    assert!(!tmp_left);
}
