//! The wearer's answer to a step of device moment in mid-stance (issue 40; the README figure
//! `docs/src/images/step_response.png`): the reduced treadmill (treadmill_subject at 1 ms) with an ideal
//! device that gives nothing but a 10 N m flexion step 25 % into the third stride, once with
//! the muscle wearer and once with the impedance wearer, each against the same run without
//! the step.
//!
//! ```sh
//! cargo run --release --example step_response             # writes docs/src/images/step_response.png
//! cargo run --release --example step_response -- out.png
//! ```

use exoleg::output::{panels_png, Panel};
use exoleg::record::MemoryRecord;
use plotters::style::RGBColor;
use std::path::{Path, PathBuf};

/// The push: its size (N m, extensor +) and its time (s).
const STEP_NM: f64 = -10.0;
const AT_S: f64 = 2.392;

fn run(muscles: bool, step_nm: f64) -> MemoryRecord {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let step = format!("controller.ideal.step_nm={step_nm}");
    let at = format!("controller.ideal.step_at_s={AT_S}");
    let mut sets = vec![
        "leg.engine=\"reduced\"",
        "sim.dt_s=0.001",
        "sim.duration_s=2.6",
        "controller.kind=\"ideal_moment\"",
        "controller.ideal.max_nm_per_kg=0",
        &step,
        &at,
    ];
    if muscles {
        sets.extend(["wearer.model=\"muscles\"", "output.muscles=true"]);
    }
    let sc = exoleg::load(Some(&root.join("assets/scenarios/treadmill_subject.toml")), &sets).expect("scenario");
    exoleg::run_in_memory(&sc.model).expect("run").1
}

/// `name`'s change from `calm` to `pushed` over 50 ms before to 200 ms after the push, at
/// (ms since the push, change).
fn change(pushed: &MemoryRecord, calm: &MemoryRecord, name: &str) -> Vec<(f64, f64)> {
    let col = |r: &MemoryRecord| r.columns().into_iter().find(|(n, _)| n == name).expect(name).1;
    let (a, b, t) = (col(pushed), col(calm), col(calm).len());
    let k0 = (AT_S * 1000.0).round() as usize;
    (k0 - 50..(k0 + 200).min(t)).map(|k| (k as f64 - k0 as f64, a[k] - b[k])).collect()
}

fn main() {
    let out = std::env::args()
        .nth(1)
        .map_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/src/images/step_response.png"), PathBuf::from);
    let (m_calm, m_push) = (run(true, 0.0), run(true, STEP_NM));
    let (i_calm, i_push) = (run(false, 0.0), run(false, STEP_NM));
    let (blue, orange, grey) = (RGBColor(31, 119, 180), RGBColor(230, 120, 20), RGBColor(120, 120, 120));
    let push: Vec<(f64, f64)> = (-50..200).map(|k| (k as f64, if k >= 0 { -STEP_NM } else { 0.0 })).collect();
    let panels = [
        Panel {
            y_label: "knee angle change (deg, flexion +)",
            series: vec![
                ("muscle wearer", change(&m_push, &m_calm, "knee_angle_deg"), blue),
                ("impedance wearer", change(&i_push, &i_calm, "knee_angle_deg"), orange),
            ],
        },
        Panel {
            y_label: "wearer's knee moment change (N m, flexion +)",
            series: vec![
                ("muscle wearer", change(&m_push, &m_calm, "wearer_knee_torque_nm"), blue),
                ("impedance wearer", change(&i_push, &i_calm, "wearer_knee_torque_nm"), orange),
                ("the device's step (sign reversed)", push.iter().map(|&(t, v)| (t, -v)).collect(), grey),
            ],
        },
        Panel {
            y_label: "muscle wearer: activation change",
            series: vec![
                ("vasti", change(&m_push, &m_calm, "muscle_vasti_activation"), blue),
                ("hamstrings", change(&m_push, &m_calm, "muscle_hamstrings_activation"), orange),
                ("gastrocnemius", change(&m_push, &m_calm, "muscle_gastroc_activation"), grey),
            ],
        },
    ];
    let title = "A 10 N m flexion step of device moment in mid-stance; shaded: the knee's neural delay (10 ms)";
    panels_png(&out, title, "time since the step (ms)", (-50.0, 200.0), &panels, &[(0.0, 10.0)]).expect("plot");
    let at = |v: &[(f64, f64)], ms: f64| v.iter().find(|p| p.0 >= ms).map_or(f64::NAN, |p| p.1);
    let (mm, im) =
        (change(&m_push, &m_calm, "wearer_knee_torque_nm"), change(&i_push, &i_calm, "wearer_knee_torque_nm"));
    let (mq, iq) = (change(&m_push, &m_calm, "knee_angle_deg"), change(&i_push, &i_calm, "knee_angle_deg"));
    for ms in [4.0, 10.0, 20.0, 50.0, 100.0, 150.0] {
        println!(
            "{ms:>5} ms: muscles moment {:+7.2} N m, knee {:+6.2} deg | impedance moment {:+7.2} N m, knee {:+6.2} deg",
            at(&mm, ms),
            at(&mq, ms),
            at(&im, ms),
            at(&iq, ms)
        );
    }
    println!("wrote {}", out.display());
}
