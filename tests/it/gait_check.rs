//! `exoleg gait-check` (issue 33): the training set (v3's 21 treadmill trials of young and
//! older adults and v2's six) walks from each subject's numbers alone, both engines agree on
//! it, and bad input is named (file, row, column) while the good trials still run.
use crate::common::*;
use exoleg::study::gait_check::{gait_check, CheckOptions, Outcome, Report};
use std::path::{Path, PathBuf};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn training_set() -> Vec<PathBuf> {
    ["assets/gait/v3", "assets/gait/v2"].iter().map(|d| Path::new(ROOT).join(d)).collect()
}

/// Every trial's (stance, GRF r, GRF peak ratio, knee-moment r), by name.
fn figures(r: &Report) -> Vec<(String, [f64; 4])> {
    r.trials
        .iter()
        .map(|t| match &t.outcome {
            Outcome::Ran(f) => (t.name.clone(), {
                let (c, d) = (&f.contact, &f.dataset);
                [c.stance_fraction, d.grf_correlation, d.grf_peak_ratio, d.knee_moment_stance_correlation]
            }),
            other => panic!("{}: {other:?}", t.name),
        })
        .collect()
}

fn check(engine: &str) -> Report {
    let dir = tempfile::tempdir().unwrap();
    let opts = CheckOptions { engine: engine.into(), ..Default::default() };
    gait_check(&training_set(), &dir.path().join("out"), &opts).unwrap()
}

/// The 27 treadmill trials on the reduced engine at 1 ms with each subject's numbers: the
/// issue's acceptance (>= 19 of v3's 21 and all six of v2 meet stance 45-70 %, GRF r >= 0.8,
/// stance knee-moment r >= 0.7 without a not-walking flag; the extensor timing within 5 % and
/// the flexor within 50 % on >= 80 % of the trials).
#[test]
fn the_training_set_walks_from_each_subjects_numbers() {
    let r = check("reduced");
    print!("{}", r.table());
    let group = |folder: &str, g: &str| {
        r.count_meeting(r.trials.iter().filter(|t| t.folder == folder && t.row.as_ref().unwrap().group == g))
    };
    // Measured: v3 young 6 of 6, older 15 of 15, v2 6 of 6 (before the pelvis's fore-aft
    // path and the other leg's data ground reaction: 2 of 6, 11 of 15, 6 of 6).
    let (young, older, v2) = (group("v3", "young"), group("v3", "older"), group("v2", ""));
    assert_eq!((young.1, older.1, v2.1), (6, 15, 6));
    assert!(young.0 + older.0 >= 19, "v3: {young:?} {older:?}");
    assert_eq!(v2.0, 6, "v2");
    // Measured: the peaks hold on 26 of 27 (35's extensor 6 % late); the acceptance 80 % is 22.
    let (peaks, ran) = r.peaks_holding();
    assert!(peaks >= 22 && ran == 27, "peaks hold on {peaks} of {ran}");
    // The knee moment's shape, not just the count: measured the lowest stance knee-moment r
    // 0.740 (30 T05), the mean over the 27 trials 0.915 (before the fix: -0.23 and 0.71).
    let f = figures(&r);
    let mean = f.iter().map(|x| x.1[3]).sum::<f64>() / f.len() as f64;
    let lowest = f.iter().map(|x| x.1[3]).fold(f64::INFINITY, f64::min);
    assert!(mean > 0.85 && lowest > 0.7, "knee-moment r: mean {mean}, lowest {lowest}");
    assert!(r.bad_input().is_empty());
}

/// The same table on Rapier at 0.25 ms (its usual step) and the reduced engine at 1 ms: each
/// dimensionless figure within 0.02 (the issue's tolerance).
#[test]
fn both_engines_agree_on_the_training_set() {
    let (a, b) = (figures(&check("reduced")), figures(&check("rapier")));
    let mut worst = [0.0f64; 4];
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        for i in 0..4 {
            worst[i] = worst[i].max((x[i] - y[i]).abs());
        }
        assert!(x.iter().zip(y).all(|(x, y)| (x - y).abs() < 0.02), "{name}: reduced {x:?}, Rapier {y:?}");
    }
    // Measured (largest difference over the 27 trials): stance 0.0006, GRF r 0.0010, GRF
    // peak ratio 0.0053, knee-moment r 0.0069; limits 2-3x those.
    let limits = [0.002, 0.003, 0.015, 0.02];
    assert!(worst.iter().zip(limits).all(|(w, l)| *w < l), "worst {worst:?} (limits {limits:?})");
}

/// Write a folder: `subjects.csv` with `table` and the named files (text).
fn folder(root: &Path, name: &str, table: &str, files: &[(&str, String)]) -> PathBuf {
    let d = root.join(name);
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join("subjects.csv"), table).unwrap();
    for (f, text) in files {
        std::fs::write(d.join(f), text).unwrap();
    }
    d
}

fn gait_check_cli(dirs: &[&Path], out: &Path, extra: &[&str]) -> (Option<i32>, String, String) {
    let o = std::process::Command::new(exe())
        .arg("gait-check")
        .args(dirs)
        .args(["--quiet", "--strides", "2", "--out"])
        .arg(out)
        .args(extra)
        .output()
        .unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stdout).to_string(), String::from_utf8_lossy(&o.stderr).to_string())
}

/// A folder without `subjects.csv`, or with a table missing a required column, stops the
/// check: exit 2 naming the file (and column), nothing written.
#[test]
fn a_folder_without_its_table_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(Path::new(ROOT).join("assets/gait/v3/wbds30_treadmill_t05.csv")).unwrap();
    let bare = tmp.path().join("bare");
    std::fs::create_dir_all(&bare).unwrap();
    std::fs::write(bare.join("t.csv"), &good).unwrap();
    let out = tmp.path().join("out");
    let (code, _, err) = gait_check_cli(&[&bare], &out, &[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("subjects.csv") && err.contains("cannot read"), "{err}");
    assert!(!out.exists());
    let no_speed = folder(tmp.path(), "no_speed", "file,sex,height_m,mass_kg\nt.csv,F,1.57,48.4\n", &[("t.csv", good)]);
    let (code, _, err) = gait_check_cli(&[&no_speed], &out, &[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("subjects.csv") && err.contains("speed_m_s") && err.contains("missing column"), "{err}");
    assert!(!out.exists());
    assert_eq!(err.lines().count(), 1, "one line: {err}");
    // The output never goes into a data folder.
    let inside = no_speed.join("out");
    let (code, _, err) = gait_check_cli(&[&no_speed], &inside, &[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--out") && err.contains("inside the gait folder"), "{err}");
    assert!(!inside.exists());
}

/// A partly bad folder: the good trial runs, every bad one is reported naming its file, row
/// and column, the table lists them all, and the exit code is 2.
#[test]
fn a_partly_bad_folder_runs_the_good_trials_and_names_the_bad_ones() {
    let tmp = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(Path::new(ROOT).join("assets/gait/v3/wbds30_treadmill_t05.csv")).unwrap();
    let lines: Vec<&str> = good.lines().collect();
    let no_grf = good.lines().map(|l| l.rsplitn(3, ',').nth(2).unwrap().to_string() + "\n").collect::<String>();
    let ragged = good.replacen(lines[20], &lines[20][..lines[20].rfind(',').unwrap()], 1);
    let mut fields: Vec<&str> = lines[30].split(',').collect();
    fields[2] = "abc";
    let word = good.replacen(lines[30], &fields.join(","), 1);
    let half = lines[..52].join("\n") + "\n";
    let row = |f: &str, h: &str, m: &str| format!("{f},F,{h},{m},0.79,1.08,0.9667\n");
    let table = "file,sex,height_m,mass_kg,leg_length_m,speed_m_s,stride_s\n".to_string()
        + &row("good.csv", "1.57", "48.4")
        + &row("no_grf.csv", "1.57", "48.4")
        + &row("ragged.csv", "1.57", "48.4")
        + &row("word.csv", "1.57", "48.4")
        + &row("half.csv", "1.57", "48.4")
        + &row("massless.csv", "1.57", "0")
        + &row("giant.csv", "5", "48.4")
        + &row("gone.csv", "1.57", "48.4");
    let files = [
        ("good.csv", good.clone()),
        ("no_grf.csv", no_grf),
        ("ragged.csv", ragged),
        ("word.csv", word),
        ("half.csv", half),
        ("massless.csv", good.clone()),
        ("giant.csv", good.clone()),
        ("orphan.csv", good.clone()),
    ];
    let dir = folder(tmp.path(), "lab", &table, &files);
    let out = tmp.path().join("out");
    let (code, stdout, err) = gait_check_cli(&[&dir], &out, &[]);
    assert_eq!(code, Some(2), "{stdout}\n{err}");
    let expect = [
        ("no_grf.csv", "grf_vertical_n_per_kg"),
        ("ragged.csv", "row 21"),
        ("word.csv", "row 31"),
        ("half.csv", "gait_cycle_pct"),
        ("subjects.csv", "row 7, mass_kg"),
        ("subjects.csv", "row 8, height_m"),
        ("subjects.csv", "row 9, file"),
        ("orphan.csv", "no row for orphan.csv"),
    ];
    for (file, what) in expect {
        assert!(
            err.lines().any(|l| l.starts_with("bad input:") && l.contains(file) && l.contains(what)),
            "{file} / {what}:\n{err}"
        );
    }
    assert!(err.lines().last().unwrap().contains("8 of 9 trials are bad input"), "{err}");
    let csv = std::fs::read_to_string(out.join("gait_check.csv")).unwrap();
    assert_eq!(csv.lines().count(), 10, "{csv}");
    let good_line = csv.lines().find(|l| l.starts_with("lab,good,")).unwrap();
    assert!(good_line.contains(",ran,"), "{good_line}");
    assert!(out.join("figures/lab/good.png").is_file());
    assert_eq!(csv.lines().filter(|l| l.contains(",bad_input,")).count(), 8, "{csv}");
}

/// A trial that misses the targets (here a target no run meets) is reported and exits 4,
/// with the outputs written; a blank stride is estimated and marked.
#[test]
fn missed_targets_exit_4_and_an_estimated_stride_is_marked() {
    let tmp = tempfile::tempdir().unwrap();
    let v2 = Path::new(ROOT).join("assets/gait/v2");
    let table = std::fs::read_to_string(v2.join("subjects.csv")).unwrap();
    let t05 =
        table.lines().filter(|l| l.starts_with("subject") || l.contains("wbds02_treadmill_t05")).collect::<Vec<_>>();
    let data = std::fs::read_to_string(v2.join("wbds02_treadmill_t05.csv")).unwrap();
    let dir = folder(tmp.path(), "s02", &(t05.join("\n") + "\n"), &[("wbds02_treadmill_t05.csv", data)]);
    let out = tmp.path().join("out");
    let (code, stdout, err) = gait_check_cli(&[&dir], &out, &["--min-knee-moment-r", "0.999"]);
    assert_eq!(code, Some(4), "{stdout}\n{err}");
    assert!(stdout.contains("MISSES: knee moment r") && stdout.contains("1.009*"), "{stdout}");
    let csv = std::fs::read_to_string(out.join("gait_check.csv")).unwrap();
    assert!(csv.contains(",estimated,ran,"), "{csv}");
}
