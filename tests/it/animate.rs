//! `exoleg run --animate` (issue 9): leg_motion.gif in real time, frames capped, the same
//! bytes for the same run.
use crate::common::exe;
use std::path::Path;
use std::process::Command;

/// Frame count and delay (centiseconds) of a GIF.
fn frames(path: &Path) -> (usize, u16) {
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::Indexed);
    let mut d = opts.read_info(std::fs::File::open(path).unwrap()).unwrap();
    let (mut n, mut delay) = (0, 0);
    while let Some(f) = d.read_next_frame().unwrap() {
        n += 1;
        delay = f.delay;
    }
    (n, delay)
}

fn run(dir: &Path, name: &str, args: &[&str]) -> std::path::PathBuf {
    let out = dir.join(name);
    let o = Command::new(exe()).args(["run", "--quiet", "--animate", "--out"]).arg(&out).args(args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out.join("leg_motion.gif")
}

#[test]
fn leg_motion_gif_is_real_time_capped_and_deterministic() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let gait = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/gait_treadmill.toml");
    let gait = gait.to_str().unwrap();
    // Default scenario, 2 s: a frame every 40 ms from t = 0 (51 frames), 4 cs each.
    let a = run(t, "a", &["--set", "sim.duration_s=2.0"]);
    let b = run(t, "b", &["--set", "sim.duration_s=2.0"]);
    assert_eq!(frames(&a), (51, 4));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "not deterministic");
    // Loaded walking with the ground, 1.1 s.
    let g = run(t, "g", &[gait, "--set", "sim.duration_s=1.1", "--set", "metrics.settle_s=0.0"]);
    assert_eq!(frames(&g).0, 28);
    // A 60 s run: at most 500 frames, 12 cs apart (still real time).
    let long = run(t, "l", &["--set", "sim.duration_s=60.0", "--set", "leg.engine=\"reduced\""]);
    assert_eq!(frames(&long), (500, 12));
    // The bench has no leg to draw.
    let o = Command::new(exe())
        .args(["run", "--animate", "--set", "plant.kind=\"bench\"", "--out"])
        .arg(t.join("x"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--animate"));
}
