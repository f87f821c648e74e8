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

/// One short real GIF: the frames and delay the plan gives (the plan's arithmetic is tested at
/// the unit level, `output::animate`), the same bytes twice, and the bench refused.
#[test]
fn leg_motion_gif_is_real_time_and_deterministic() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let a = run(t, "a", &["--set", "sim.duration_s=0.4"]);
    let b = run(t, "b", &["--set", "sim.duration_s=0.4"]);
    let plan = exoleg::output::animate::FramePlan::new(400, 1e-3);
    assert_eq!((plan.frames, plan.delay_cs), (11, 4));
    assert_eq!(frames(&a), (plan.frames, plan.delay_cs));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "not deterministic");
    // The bench has no leg to draw.
    let o = Command::new(exe())
        .args(["run", "--animate", "--set", "plant.kind=\"bench\"", "--out"])
        .arg(t.join("x"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--animate"));
}
