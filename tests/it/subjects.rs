//! Loaded walking for any subject (issue 23): `[subject]` scales the built-in leg (the same
//! leg `exoleg urdf` writes), a user's URDF is used as given, a contradicting mass is refused;
//! the shipped treadmill trials with each subject's own numbers.
use crate::common::*;
use exoleg::Resources;
use std::path::Path;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// The leg `[subject]` runs is the one `exoleg urdf` writes: the same subject through a
/// written URDF and `hip.subject_mass_kg` gives the same rows; the scaled cylinder is the
/// template's times the thigh ratio at every knee angle (the same knee range).
#[test]
fn a_subject_scales_the_builtin_leg_and_exoleg_urdf_writes_it() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = dir.path().join("s02.urdf");
    let o = std::process::Command::new(exe())
        .args([
            "urdf",
            "--mass-kg",
            "52.9",
            "--height-m",
            "1.668",
            "--leg-length-m",
            "0.865",
            "--sex",
            "female",
            "--out",
        ])
        .arg(&urdf)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let short = ["sim.duration_s=1.0", "metrics.settle_s=0.5", "reference.gait_trial=\"wbds02_treadmill_t03\""];
    let mut with_subject = shipped("treadmill_subject.toml", &short);
    with_subject.file.subject = Some(exoleg::scenario::SubjectParams {
        mass_kg: 52.9,
        height_m: 1.668,
        leg_length_m: Some(0.865),
        sex: exoleg::leg::subject::Sex::Female,
    });
    let mut with_file = with_subject.clone();
    with_file.file.subject = None;
    with_file.file.leg.urdf = urdf.display().to_string();
    with_file.file.hip.subject_mass_kg = Some(52.9);
    let (a, b) = (run_scenario(&with_subject).unwrap(), run_scenario(&with_file).unwrap());
    assert_eq!(a.record.rows, b.record.rows, "the same leg either way");
    let sc = with_subject.resolve(&Resources::new()).unwrap();
    assert!(sc.inputs.iter().any(|i| i.origin.contains("scaled to [subject]")), "{:?}", sc.inputs);
    assert_eq!(sc.file.hip.subject_mass_kg, None, "the mass recorded once, in [subject]");
    let leg = &sc.model.leg().unwrap().model;
    // The template at its own subject (the built-in exo_leg_small, unrounded).
    let template = exoleg::leg::subject::SubjectBody {
        mass_kg: 60.0,
        height_m: 1.60,
        leg_length_m: None,
        sex: exoleg::leg::subject::Sex::Female,
    };
    let small = exoleg::leg::subject::scaled_urdf(&template);
    let small = exoleg::leg::LegSpec::from_urdf_with(&small, &Default::default()).unwrap();
    let k = leg.knee_joint().origin_xyz[2] / small.knee_joint().origin_xyz[2];
    // Measured k = 1.0800 (her thigh 0.3743 m against the template's 0.3398 m).
    assert!((k - 1.08).abs() < 1e-3, "k = {k}");
    for q in [-10.0f64, 0.0, 30.0, 60.0, 100.0] {
        let (l, t) = (
            exoleg::leg::cylinder_length_at(leg, q.to_radians()),
            exoleg::leg::cylinder_length_at(&small, q.to_radians()),
        );
        assert!((l / t - k).abs() < 1e-9, "at {q} deg: {l} vs {k} x {t}");
    }
    let mass: f64 = leg.links().iter().map(|l| l.mass_kg).sum();
    // de Leva: thigh 14.78 %, shank 4.81 %, foot 1.29 % of 52.9 kg, plus the 1.35 kg cylinder.
    assert!((mass - (0.2088 * 52.9 + 1.35)).abs() < 1e-6, "leg mass {mass}");
}

/// A user's URDF is used as given (a warning says so); the mass given twice and differently is
/// refused naming both keys.
#[test]
fn subject_with_a_user_urdf_warns_and_a_contradiction_is_refused() {
    let urdf = Path::new(ROOT).join("urdf/exo_leg.urdf").display().to_string();
    let s = shipped("treadmill_subject.toml", &[&format!("leg.urdf={urdf:?}")]);
    let sc = s.resolve(&Resources::new()).unwrap();
    assert!(
        sc.warnings.iter().any(|w| w.contains("leg.urdf is your own URDF: it is used as given")),
        "{:?}",
        sc.warnings
    );
    let p = Path::new(ROOT).join("assets/scenarios/treadmill_subject.toml");
    let e = exoleg::Scenario::load(Some(&p), &["hip.subject_mass_kg=80.0".to_string()]).unwrap_err().to_string();
    assert!(e.contains("hip.subject_mass_kg") && e.contains("subject.mass_kg = 74.3"), "{e}");
    let e = exoleg::Scenario::load(Some(&p), &["subject.leg_length_m=1.5".to_string()]).unwrap_err().to_string();
    assert!(e.contains("subject.leg_length_m"), "{e}");
}

/// The six shipped treadmill trials with each subject's own numbers (assets/gait/v2/subjects.csv: mass,
/// stature, leg length, belt speed, stride time; subject 02's stride time is an estimate) and
/// nothing else changed meet the walking figures (README table).
#[test]
fn the_shipped_treadmill_trials_walk_with_each_subjects_numbers() {
    walk_the_shipped_trials(0.00025, &[]);
}

/// The same six trials on the reduced engine at 1 ms. Measured (as below): 01 T03: 0.587;
/// 0.988, 1.09; 816 / 745; 0.968; 1 / 2, -49 / -44. 01 T05: 0.559; 0.986, 1.12; 949 / 766;
/// 0.964; 15 / 15, -57 / -48. 01 T06: 0.548; 0.985, 1.18; 1268 / 822; 0.966; 16 / 21, -61 / -52.
/// 02 T03: 0.616; 0.988, 1.19; 623 / 527; 0.965; -14 / -10, -46 / -46. 02 T05: 0.587; 0.941,
/// 1.09; 663 / 543; 0.844; -6 / -13, -24 / -43. 02 T06: 0.551; 0.966, 1.23; 688 / 562; 0.953;
/// -7 / 2, -55 / -49: every figure within 0.01 of Rapier's at 0.25 ms but the unfiltered heel
/// strike (a one-step peak).
#[test]
fn the_shipped_treadmill_trials_walk_on_the_reduced_engine() {
    walk_the_shipped_trials(0.001, &["leg.engine=\"reduced\""]);
}

/// Run the six shipped treadmill trials with each subject's numbers at the step `dt` (s) with
/// the overrides `extra`, and check the acceptance.
fn walk_the_shipped_trials(dt: f64, extra: &[&str]) {
    // Measured (subject trial: stance; GRF r, 10 Hz peak ratio; unfiltered peak / data's;
    // knee moment r; extensor, flexor peak / data's, N m; Rapier at 0.25 ms):
    // 01 T03: 0.587; 0.988, 1.09; 815 / 745; 0.968; 1 / 2, -49 / -44
    // 01 T05: 0.559; 0.986, 1.11; 939 / 766; 0.965; 15 / 15, -57 / -48
    // 01 T06: 0.549; 0.985, 1.18; 1269 / 822; 0.967; 16 / 21, -60 / -52
    // 02 T03: 0.616; 0.989, 1.19; 622 / 527; 0.967; -14 / -10, -46 / -46
    // 02 T05: 0.587; 0.941, 1.09; 662 / 543; 0.839; -6 / -13, -24 / -43 (belt 16 % over the sweep)
    // 02 T06: 0.552; 0.965, 1.23; 825 / 562; 0.954; -7 / 2, -55 / -49
    // (issue 23's model, before the pelvis followed the foot's sweep and the other leg took the
    // data's ground reaction: knee moment r 0.923, 0.921, 0.912, 0.868, 0.753, 0.872.)
    // The limits are the acceptance (the closest: 02 T05's flexor at 0.55 of the
    // data's; 01 T06's unfiltered peak at 1.54x).
    let trials = [
        ("01", "t03", 0.85, 1.3833),
        ("01", "t05", 1.21, 1.0633),
        ("01", "t06", 1.40, 1.0067),
        ("02", "t03", 0.88, 1.21),
        ("02", "t05", 1.25, 1.01),
        ("02", "t06", 1.44, 0.94),
    ];
    for (subject, trial, belt, stride) in trials {
        let who = if subject == "01" {
            ["subject.mass_kg=74.3", "subject.height_m=1.725", "subject.leg_length_m=0.89", "subject.sex=\"male\""]
        } else {
            ["subject.mass_kg=52.9", "subject.height_m=1.668", "subject.leg_length_m=0.865", "subject.sex=\"female\""]
        };
        let dur = (6.0 * stride / dt).round() * dt;
        let mut sets = vec![
            format!("reference.gait_trial=\"wbds{subject}_treadmill_{trial}\""),
            format!("ground.belt_speed_m_s={belt}"),
            format!("sim.duration_s={dur}"),
            format!("metrics.settle_s={stride}"),
            format!("sim.dt_s={dt}"),
        ];
        sets.extend(who.iter().chain(extra).map(|w| w.to_string()));
        let s = shipped("treadmill_subject.toml", &sets.iter().map(String::as_str).collect::<Vec<_>>());
        let out = run_scenario(&s).unwrap();
        let c = out.summary.contact.unwrap();
        let d = c.dataset.unwrap();
        let at = format!("{subject} {trial}");
        assert_eq!(c.not_walking, Some(vec![]), "{at}");
        assert!((0.45..=0.70).contains(&c.stance_fraction), "{at}: stance {}", c.stance_fraction);
        assert!(
            d.grf_correlation >= 0.8 && d.grf_peak_ratio <= 1.5,
            "{at}: GRF {} x{}",
            d.grf_correlation,
            d.grf_peak_ratio
        );
        assert!(
            c.peak_ground_reaction_n <= 2.0 * d.data_peak_ground_reaction_n,
            "{at}: peak {}",
            c.peak_ground_reaction_n
        );
        assert!(d.knee_moment_stance_correlation >= 0.7, "{at}: knee moment r {}", d.knee_moment_stance_correlation);
        let within = |sim: f64, data: f64| (0.5..=1.5).contains(&(sim / data));
        if d.data_flexor_peak_nm < -10.0 {
            assert!(
                within(d.flexor_peak_nm, d.data_flexor_peak_nm),
                "{at}: flexor {} vs {}",
                d.flexor_peak_nm,
                d.data_flexor_peak_nm
            );
        }
        if d.data_extensor_peak_nm > 10.0 {
            assert!(
                within(d.extensor_peak_nm, d.data_extensor_peak_nm),
                "{at}: extensor {} vs {}",
                d.extensor_peak_nm,
                d.data_extensor_peak_nm
            );
        }
    }
}
