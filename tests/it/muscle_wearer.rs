//! A wearer as strong and as slow as a person (issue 40, `wearer.model = "muscles"`): it walks
//! the training set, it answers a push a neural delay late through activation dynamics while
//! the impedance wearer answers at once, its nervous system alone is delayed and rate-limited,
//! and its keys refuse what has no meaning.

use crate::common::exe;
use exoleg::human::{MuscleWearer, WearerInputs};
use exoleg::study::gait_check::{gait_check, CheckOptions, Outcome};
use std::path::Path;
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// v3's 21 treadmill trials with the muscle wearer on the reduced engine (the built-in
/// treadmill_subject with its DT-ZNN device): the issue's >= 19 meet today's targets; measured
/// 20 (the miss: wbds29, whose stance knee moment's correlation is low), the peak reserves
/// at most 0.1 % of a joint's moment (limit 0.5 %), the gross metabolic rate 10.5 W/kg on
/// average (7.5..13.1).
#[test]
fn the_muscle_wearer_walks_the_training_set() {
    let dir = tempfile::tempdir().unwrap();
    let opts = CheckOptions { sets: vec!["wearer.model=\"muscles\"".into()], ..Default::default() };
    let r = gait_check(&[root().join("assets/gait/v3")], &dir.path().join("out"), &opts).unwrap();
    print!("{}", r.table());
    let meeting = r.trials.iter().filter(|t| t.meets(&r.targets)).count();
    assert!(meeting >= 19, "{meeting} of 21 meet the targets");
    let (mut worst_reserve, mut gross) = (0.0f64, Vec::new());
    for t in &r.trials {
        let Outcome::Ran(f) = &t.outcome else { panic!("{}: {:?}", t.name, t.outcome) };
        let m = f.metabolics.as_ref().expect("the muscle wearer's figures");
        worst_reserve = m.peak_reserve_pct.iter().fold(worst_reserve, |a, b| a.max(*b));
        gross.push(m.gross_w_per_kg);
    }
    assert!(worst_reserve < 0.5, "peak reserve {worst_reserve} %");
    let mean = gross.iter().sum::<f64>() / gross.len() as f64;
    assert!((8.0..13.0).contains(&mean), "gross {mean} W/kg");
}

/// A column of a run in memory.
fn column(rec: &exoleg::record::MemoryRecord, name: &str) -> Vec<f64> {
    rec.columns().into_iter().find(|(n, _)| n == name).unwrap_or_else(|| panic!("no column {name}")).1
}

/// The reduced treadmill (treadmill_subject at 1 ms) with an ideal device that gives nothing
/// but a step of `step_nm` (extensor +) at `at_s`, in mid-stance.
fn pushed(muscles: bool, step_nm: f64, at_s: f64) -> exoleg::record::MemoryRecord {
    let step = format!("controller.ideal.step_nm={step_nm}");
    let at = format!("controller.ideal.step_at_s={at_s}");
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
    let sc = exoleg::load(Some(&root().join("assets/scenarios/treadmill_subject.toml")), &sets).unwrap();
    exoleg::run_in_memory(&sc.model).unwrap().1
}

/// A 10 N m flexion push in mid-stance (2.392 s, 25 % into the third stride). The impedance
/// wearer answers in the same millisecond (its knee moment changes by 7 N m in the first 4 ms
/// of a 20 N m push), the knee hardly moves. The muscle wearer's activations do not change
/// before the hip's neural delay (5 ms; measured: the hamstrings and gastrocnemius share the
/// hip's answer to the body's motion from 7 ms), the knee's own vasti not before the knee's
/// 10 ms (measured 12 ms: the angle moves the millisecond after the push, the activation the
/// step after the target; limit the delay plus 3 ms), its moment changes before then only
/// through the muscles' own force-velocity (measured 0.41 N m, 2 % of its answer 150 ms on,
/// 23.3 N m; limit 5 %), and the knee sinks (measured 8.5 deg at 150 ms
/// against the impedance wearer's 1.1 deg for a push twice as large).
#[test]
fn a_push_is_answered_a_neural_delay_late() {
    let (t0, k0) = (2.392, 2392);
    let (calm, push) = (pushed(true, 0.0, 0.0), pushed(true, -10.0, t0));
    let diff =
        |name: &str| -> Vec<f64> { column(&push, name).iter().zip(column(&calm, name)).map(|(a, b)| a - b).collect() };
    let (dq, dm) = (diff("knee_angle_deg"), diff("wearer_knee_torque_nm"));
    let acts: Vec<Vec<f64>> = ["vasti", "hamstrings", "bifemsh", "rect_fem", "gastroc"]
        .iter()
        .map(|m| diff(&format!("muscle_{m}_activation")))
        .collect();
    let first = |a: &[f64]| (k0..k0 + 150).find(|&k| a[k].abs() > 1e-12).map_or(150, |k| k - k0);
    let firsts: Vec<usize> = acts.iter().map(|a| first(a)).collect();
    eprintln!("first activation change (ms) vasti, hamstrings, bifemsh, rect_fem, gastroc: {firsts:?}");
    // The hip's delay is 5 ms: the biarticular muscles may answer the hip's motion then; the
    // knee's own muscles (vasti, biceps femoris short head) wait for the knee's 10 ms.
    assert!(firsts.iter().all(|&f| f >= 5), "activations changed before any delay: {firsts:?}");
    assert!(firsts[0] >= 10 && firsts[2] >= 10, "knee muscles before the knee's delay: {firsts:?}");
    assert!(firsts[0] <= 13, "no answer at the delay: {firsts:?}");
    let answer = dm[k0 + 150];
    assert!(answer < -15.0, "the muscles' answer {answer} N m (extensor -)");
    let intrinsic = dm[k0..k0 + 10].iter().fold(0.0f64, |a, b| a.max(b.abs()));
    assert!(intrinsic < 0.05 * answer.abs(), "before the delay {intrinsic} N m of {answer}");
    assert!(dq[k0 + 150] > 4.0, "the knee sank {} deg", dq[k0 + 150]);
    // The impedance wearer: the knee stays within 2 deg under a push twice as large, and its
    // moment has changed by a third of the push within 4 ms.
    let (icalm, ipush) = (pushed(false, 0.0, 0.0), pushed(false, 20.0, t0));
    let idq: Vec<f64> =
        column(&ipush, "knee_angle_deg").iter().zip(column(&icalm, "knee_angle_deg")).map(|(a, b)| a - b).collect();
    let idm: Vec<f64> = column(&ipush, "wearer_knee_torque_nm")
        .iter()
        .zip(column(&icalm, "wearer_knee_torque_nm"))
        .map(|(a, b)| a - b)
        .collect();
    assert!(idq[k0..k0 + 150].iter().all(|d| d.abs() < 2.0), "impedance knee moved");
    assert!(idm[k0 + 4] > 5.0, "the impedance wearer's answer at 4 ms: {} N m", idm[k0 + 4]);
}

/// The nervous system alone (the wearer of the reduced treadmill, frozen at 30 % of its cycle
/// on the gait it learned): a 2 deg knee deviation appears at 0.1 s. Its muscles' knee moment
/// does not change before the knee's delay (10 ms), then follows the command through De
/// Groote's activation dynamics: half of its change in 10 ms after the delay (measured; the
/// limit 20 ms is about twice the 9.6 ms a full excitation step takes to half activation).
#[test]
fn the_answer_starts_after_the_delay_and_rises_with_activation() {
    let sc = exoleg::load(
        Some(&root().join("assets/scenarios/treadmill_subject.toml")),
        &["leg.engine=\"reduced\"", "sim.dt_s=0.001", "wearer.model=\"muscles\""],
    )
    .unwrap();
    let setup = sc.model.muscle_wearer.clone().expect("a muscle wearer");
    let tilt = 7.6f64.to_radians();
    let [_, q, _] = setup.feedforward.at(30.0);
    let input = |knee_offset_rad: f64| {
        let mut body = q;
        body[1] += knee_offset_rad;
        WearerInputs {
            joints: exoleg::muscles::analysis::Joints {
                q_rad: [q[0] + tilt, q[1], q[2]],
                qd_rad_s: [0.0; 3],
                moment_nm: [0.0; 3],
            },
            body_rad: body,
            body_rate_rad_s: [0.0; 3],
            pct: 30.0,
            stance_weight: 1.0,
            device_torque_nm: 0.0,
        }
    };
    let mut w = MuscleWearer::new(setup.clone());
    let dt = 1e-3;
    let knee: Vec<f64> = (0..400)
        .map(|k| {
            let t = k as f64 * dt;
            w.step(t, dt, &input(if t >= 0.1 - 1e-9 { 2f64.to_radians() } else { 0.0 }))[1]
        })
        .collect();
    let before = knee[99];
    assert!(knee[100..110].iter().all(|m| (m - before).abs() < 1e-9), "changed before the delay");
    let last = knee[399] - before;
    // The stance knee gain (2 N m/rad/kg) times 2 deg: the command's change, less than the
    // whole when the deviation is extrapolated along a zero rate.
    let expected = -setup.stiffness_nm_per_rad[0][1] * 2f64.to_radians();
    assert!((last - expected).abs() < 0.05 * expected.abs(), "final change {last} N m, command {expected}");
    let half = (110..400).find(|&k| (knee[k] - before).abs() >= 0.5 * last.abs()).unwrap();
    assert!(half - 110 <= 20, "half of the answer {} ms after the delay", half - 110);
}

/// `wearer.model = "muscles"` needs a walking run; its keys mean nothing without it; its
/// delays and gains have ranges.
#[test]
fn muscle_wearer_keys_refuse_what_means_nothing() {
    let treadmill = root().join("assets/scenarios/gait_treadmill.toml");
    for (scenario, sets, key) in [
        (None, vec!["wearer.model=\"muscles\""], "wearer.model"),
        (Some(&treadmill), vec!["wearer.neural_delay_s=0.02"], "wearer.neural_delay_s"),
        (Some(&treadmill), vec!["wearer.adapted=false"], "wearer.adapted"),
        (
            Some(&treadmill),
            vec!["wearer.model=\"muscles\"", "wearer.neural_delay_s=[0.01,0.5,0.02]"],
            "wearer.neural_delay_s (knee)",
        ),
        (
            Some(&treadmill),
            vec!["wearer.model=\"muscles\"", "wearer.stance_stiffness_nm_per_rad_kg=[1,2,-3]"],
            "wearer.stance_stiffness_nm_per_rad_kg (ankle)",
        ),
        (
            Some(&treadmill),
            vec!["wearer.model=\"muscles\"", "wearer.swing_damping_nm_s_per_rad_kg=[1,2,30]"],
            "wearer.swing_damping_nm_s_per_rad_kg (ankle)",
        ),
        (
            Some(&treadmill),
            vec!["controller.kind=\"ideal_moment\"", "controller.ideal.step_nm=1e9"],
            "controller.ideal.step_nm",
        ),
    ] {
        let mut cmd = Command::new(exe());
        cmd.args(["run", "--quiet", "--out"]).arg(tempfile::tempdir().unwrap().path());
        cmd.args(sets.iter().flat_map(|s| ["--set", s]));
        if let Some(s) = scenario {
            cmd.arg(s);
        }
        let o = cmd.output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{sets:?}: {err}");
        assert!(err.contains(key), "{sets:?}: {err}");
    }
}

/// The dimensionless figures of a gait check: stance, GRF r, GRF peak ratio, knee-moment r.
fn figures(r: &exoleg::study::gait_check::Report) -> Vec<(String, [f64; 4])> {
    r.trials
        .iter()
        .map(|t| match &t.outcome {
            Outcome::Ran(f) => {
                let (c, d) = (&f.contact, &f.dataset);
                (
                    t.name.clone(),
                    [c.stance_fraction, d.grf_correlation, d.grf_peak_ratio, d.knee_moment_stance_correlation],
                )
            }
            other => panic!("{}: {other:?}", t.name),
        })
        .collect()
}

/// Both leg engines walk v3 with the muscle wearer alike at the same step (0.25 ms): measured
/// largest differences over the 21 trials stance 0.0005, GRF r 0.0009, GRF peak ratio 0.0041,
/// knee-moment r 0.0026 (limits 1.5-3x; each muscle at its own delay since this round, 0.0006 /
/// 0.0022 / 0.0024 before). At their usual steps (reduced 1 ms, Rapier 0.25 ms) they
/// differ more than the impedance wearer's (peak ratio 0.022, knee-moment r 0.019): the step
/// itself, not the engine, as the reduced engine at 0.25 ms shows; the delayed feedback loop
/// is more sensitive to the step's half-millisecond of hold than an instant impedance.
#[test]
fn both_engines_walk_alike_with_the_muscle_wearer() {
    let check = |engine: &str| {
        let dir = tempfile::tempdir().unwrap();
        let opts = CheckOptions {
            engine: engine.into(),
            dt_s: Some(0.00025),
            sets: vec!["wearer.model=\"muscles\"".into()],
            ..Default::default()
        };
        gait_check(&[root().join("assets/gait/v3")], &dir.path().join("out"), &opts).unwrap()
    };
    let (a, b) = (figures(&check("reduced")), figures(&check("rapier")));
    let mut worst = [0.0f64; 4];
    for ((_, x), (_, y)) in a.iter().zip(&b) {
        for i in 0..4 {
            worst[i] = worst[i].max((x[i] - y[i]).abs());
        }
    }
    let limits = [0.0015, 0.0015, 0.006, 0.006];
    assert!(worst.iter().zip(limits).all(|(w, l)| *w < l), "worst {worst:?} (limits {limits:?})");
}

/// A fault campaign with the muscle wearer (gait_treadmill on the reduced engine, a stuck
/// valve and a 0.1 s power loss at two onsets): every run completes (a wearer who cannot hold
/// the gait is a hazard, not a failed run), `faults.csv` gives each run's metabolic rate and
/// its change against the baseline, and `faults_metabolic.png` maps it. The stuck valve locks
/// the walking knee: the wearer works harder (measured +47.1 %; limit > +15 %).
#[test]
fn a_fault_campaign_runs_with_the_muscle_wearer() {
    let tmp = tempfile::tempdir().unwrap();
    let matrix = tmp.path().join("m.toml");
    std::fs::write(
        &matrix,
        "onsets_pct = [30.0, 60.0]\n[[mode]]\ntarget = \"valve\"\nkind = \"stuck\"\n[[mode.severity]]\nlabel = \"at centre\"\nvalue = 0.0\n\
         [[mode]]\ntarget = \"power\"\nkind = \"loss\"\n[[mode.severity]]\nlabel = \"0.1 s\"\nduration_s = 0.1\n",
    )
    .unwrap();
    let out = tmp.path().join("out");
    let o = Command::new(exe())
        .current_dir(root())
        .args(["faults", "assets/scenarios/gait_treadmill.toml", "--set", "leg.engine=\"reduced\""])
        .args(["--set", "sim.dt_s=0.001", "--set", "wearer.model=\"muscles\"", "--quiet", "--matrix"])
        .args([matrix.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(matches!(o.status.code(), Some(0 | 4)), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("faults.csv")).unwrap();
    let mut rows = csv.lines().map(|l| l.split(',').collect::<Vec<_>>());
    let header = rows.next().unwrap();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (status, change) = (col("status"), col("metabolic_change_pct"));
    let rows: Vec<Vec<&str>> = rows.collect();
    assert_eq!(rows.len(), 5, "{csv}");
    let mut stuck = f64::NEG_INFINITY;
    for r in &rows {
        // (The severity labels hold no comma here, so a plain split finds the columns.)
        assert!(r[status] == "ok" || r[status] == "hazard", "a run failed: {r:?}");
        if r[1] != "baseline" {
            let c: f64 = r[change].parse().unwrap_or_else(|_| panic!("no metabolic change: {r:?}"));
            if r[1] == "valve stuck" {
                stuck = stuck.max(c);
            }
        }
    }
    eprintln!("valve stuck: metabolic change up to {stuck:+.1} %");
    assert!(stuck > 15.0, "valve stuck: {stuck} %");
    assert!(out.join("faults_metabolic.png").exists());
}
