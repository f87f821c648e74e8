//! Sharded sweeps (issue 9): shards merged are byte-identical to the unsharded sweep; a
//! missing, duplicated or foreign shard is refused with exit 2; `--plan` lists the runs.
use crate::common::exe;
use std::path::Path;
use std::process::Command;

fn exoleg(args: &[&str], cwd: &Path) -> std::process::Output {
    Command::new(exe()).args(args).current_dir(cwd).output().unwrap()
}

const SWEEP: [&str; 12] = [
    "sweep",
    "SCENARIO",
    "--monte-carlo",
    "12",
    "--vary",
    "hydraulics.beta_pa=pct(10)",
    "--set",
    "plant.kind=\"bench\"",
    "--set",
    "sim.duration_s=0.1",
    "--quiet",
    "--jobs=2",
];

fn sweep_args<'a>(scenario: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    SWEEP.iter().map(|&a| if a == "SCENARIO" { scenario } else { a }).chain(extra.iter().copied()).collect()
}

#[test]
fn shards_merge_into_the_unsharded_sweep_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let sc = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/paper_2hz_gamma100.toml");
    let sc = sc.to_str().unwrap();
    assert!(exoleg(&sweep_args(sc, &["--out", "all"]), t).status.success());
    for k in 0..3 {
        let shard = format!("{k}/3");
        let out = format!("s{k}");
        let o = exoleg(&sweep_args(sc, &["--shard", &shard, "--out", &out]), t);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    // Given in any order.
    let o = exoleg(&["merge", "s2", "s0", "s1", "--out", "merged"], t);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["runs.jsonl", "aggregate.csv"] {
        assert_eq!(
            std::fs::read(t.join("all").join(f)).unwrap(),
            std::fs::read(t.join("merged").join(f)).unwrap(),
            "{f}"
        );
    }
    for (args, needle) in [
        (vec!["merge", "s0", "s1", "--out", "bad"], "shard 2/3 is missing"),
        (vec!["merge", "s0", "s1", "s1", "s2", "--out", "bad"], "given twice"),
    ] {
        let o = exoleg(&args, t);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!t.join("bad").exists());
    }
    // A shard of another plan.
    let o = exoleg(&sweep_args(sc, &["--set", "seed=7", "--shard", "1/3", "--out", "other"]), t);
    assert!(o.status.success());
    let o = exoleg(&["merge", "s0", "other", "s2", "--out", "bad"], t);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("another sweep"));
    // The plan, without running.
    let o = exoleg(&sweep_args(sc, &["--plan"]), t);
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(text.lines().count(), 12);
    assert!(text.lines().next().unwrap().starts_with("{\"index\":0,\"sets\":[\"hydraulics.beta_pa="), "{text}");
    // Hostile shard files: garbage, an absurd shard count, a multibyte hash.
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(t.join("s1/shard.json")).unwrap()).unwrap();
    let (mut huge, mut accented) = (meta.clone(), meta.clone());
    huge["shard"] = serde_json::json!([1, 1_000_000_000_000u64]);
    accented["plan_hash"] = serde_json::json!("éé");
    for (i, text) in ["not json".to_string(), huge.to_string(), accented.to_string()].iter().enumerate() {
        let d = t.join(format!("h{i}"));
        std::fs::create_dir_all(&d).unwrap();
        std::fs::copy(t.join("s1/runs.jsonl"), d.join("runs.jsonl")).unwrap();
        std::fs::write(d.join("shard.json"), text).unwrap();
        let o = exoleg(&["merge", d.to_str().unwrap(), "s0", "s2", "--out", "bad"], t);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "case {i}: {err}");
        assert!(err.contains("shard.json") || err.contains("shard"), "case {i}: {err}");
    }
    for bad in ["3/3", "1", "a/2", "0/0"] {
        let o = exoleg(&sweep_args(sc, &["--shard", bad, "--out", "x"]), t);
        assert_eq!(o.status.code(), Some(2), "--shard {bad}");
    }
}

/// Split an unsharded sweep's `runs.jsonl` into `n` shard folders (what `--shard K/N` writes),
/// with `template` as the shard.json of every shard but its `shard` field.
fn split_into_shards(t: &Path, all: &Path, template: &Path, n: usize) -> Vec<String> {
    let lines: Vec<String> = std::fs::read_to_string(all).unwrap().lines().map(String::from).collect();
    let meta: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(template).unwrap()).unwrap();
    (0..n)
        .map(|k| {
            let d = t.join(format!("many/s{k}"));
            std::fs::create_dir_all(&d).unwrap();
            let mut m = meta.clone();
            m["shard"] = serde_json::json!([k, n]);
            std::fs::write(d.join("shard.json"), m.to_string()).unwrap();
            let mine: String = lines.iter().skip(k).step_by(n).map(|l| format!("{l}\n")).collect();
            std::fs::write(d.join("runs.jsonl"), mine).unwrap();
            d.display().to_string()
        })
        .collect()
}

/// The merge reads one shard at a time (2000 shards under an open-file limit of 64), reads
/// every line with a size cap and refuses what is not a regular file (no hang on a FIFO, no
/// 13 GB read of a file without newlines), checks every line against the plan (changed
/// overrides, injected fields, a negative maximum are refused), and never writes onto a shard.
#[test]
fn merge_is_bounded_and_checks_every_line() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let sc = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/paper_2hz_gamma100.toml");
    let sc = sc.to_str().unwrap();
    let runs = ["sweep", sc, "--monte-carlo", "2000", "--vary", "hydraulics.beta_pa=pct(10)", "--quiet"];
    let short = ["--set", "plant.kind=\"bench\"", "--set", "sim.duration_s=0.001", "--set", "sim.dt_s=0.001"];
    let args: Vec<&str> = runs.iter().chain(&short).copied().chain(["--out", "all"]).collect();
    assert!(exoleg(&args, t).status.success());
    let args: Vec<&str> = runs.iter().chain(&short).copied().chain(["--shard", "0/2000", "--out", "one"]).collect();
    assert!(exoleg(&args, t).status.success());
    let dirs = split_into_shards(t, &t.join("all/runs.jsonl"), &t.join("one/shard.json"), 2000);
    let merge = |extra: &str| {
        let cmd = format!("ulimit -n 64 && exec '{}' merge {} --out {extra}", exe(), dirs.join(" "));
        Command::new("sh").arg("-c").arg(cmd).current_dir(t).output().unwrap()
    };
    let o = merge("merged");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(t.join("all/runs.jsonl")).unwrap(), std::fs::read(t.join("merged/runs.jsonl")).unwrap());
    // Onto one of its inputs: refused, the shard intact.
    let before = std::fs::read(t.join("many/s0/runs.jsonl")).unwrap();
    let o = merge(&dirs[0]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("holds an input"));
    assert_eq!(std::fs::read(t.join("many/s0/runs.jsonl")).unwrap(), before);
    let s7 = t.join("many/s7/runs.jsonl");
    let good = std::fs::read_to_string(&s7).unwrap();
    let refused = |what: &str, needle: &str| {
        let o = merge("bad");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{what}: {err}");
        assert!(err.contains(needle), "{what}: `{needle}` not in {err}");
        assert!(!t.join("bad").exists(), "{what}");
    };
    // Tampered lines.
    let first = good.lines().next().unwrap().to_string();
    for (what, line, needle) in [
        ("changed overrides", first.replacen("hydraulics.beta_pa=1", "hydraulics.beta_pa=2", 1), "not the plan's"),
        ("an injected field", first.replacen("{", "{\"x\":1,", 1), "not as exoleg writes it"),
        (
            "a negative maximum",
            first.replacen("\"max_abs_force_error_n\":", "\"max_abs_force_error_n\":-", 1),
            "max_abs_force_error_n",
        ),
    ] {
        assert_ne!(line, first, "{what}: the test must change the line");
        std::fs::write(&s7, good.replacen(&first, &line, 1)).unwrap();
        refused(what, needle);
    }
    // A file without newlines (16 MB), a FIFO, a folder, in place of runs.jsonl.
    std::fs::write(&s7, vec![b'x'; 16 << 20]).unwrap();
    refused("no newline", "longer than");
    std::fs::remove_file(&s7).unwrap();
    let fifo = Command::new("mkfifo").arg(&s7).status().unwrap();
    assert!(fifo.success());
    refused("a FIFO", "not a regular file");
    std::fs::remove_file(&s7).unwrap();
    std::fs::create_dir(&s7).unwrap();
    refused("a folder", "not a regular file");
}
