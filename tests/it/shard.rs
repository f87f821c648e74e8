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
