//! The shipped scenarios' `timeseries.csv`, byte for byte. Recorded before the structure
//! redesign (issue 8) and the hardening (issue 10); a refactor must leave these unchanged, and
//! a deliberate change of the numbers updates a hash here with the reason below.
//!
//! Changes so far (the bench scenarios are unchanged since the first record):
//! - default, gait_walk, gait_walk_fast: the moment-arm slope d2L/dq2 is analytic instead of a
//!   central difference (piston predictor and initial free acceleration), the cuff point is
//!   taken from the URDF's fixed-joint chain instead of a round trip through Rapier's world
//!   poses, and the gait feedforward's Fourier fit is a QR least squares instead of normal
//!   equations. Every column moves by at most 4e-7 of its peak (force error by <= 1.9e-6 N).
//! - gait_walk, gait_walk_fast (issue 12.5): the cascade fits only the inverse dynamics and
//!   adds the seal friction in closed form (its own model, smooth sign 5 mm/s) instead of
//!   fitting the sum, which was off by up to 29 N at every velocity reversal. F_d changes by up
//!   to ~30 N near reversals; knee RMS 0.0089 -> 0.0098 deg (comfortable), force RMS after the
//!   first stride 0.935 -> 1.034 N.
//! - gait_treadmill (issue 12, stance knee moment): a compliant hip by default (500 N m/rad,
//!   30 N m s/rad instead of 3000 / 100) and the belt at the subject's treadmill speed (1.21 m/s
//!   instead of the stance kinematics' 1.04): stance knee moment correlation -0.06 -> 0.79.
//!   `stand` holds its hip locked and is unchanged.
//! - default, gait_walk, gait_walk_fast and the four paper scenarios (issue 11, speed): the
//!   FDO's powers for the paper's r = 1/3 are a cube root and a cube instead of `powf` (which
//!   rounds differently in the last bit). Every column moves by at most 3.3e-8 of its peak
//!   (gait_walk's disturbance estimate; force error <= 1.1e-9 N); the controller's shared terms,
//!   the friction's one `exp`/`tanh`, and the leg's pins and moment arm computed once per step
//!   change no number (checked with the general `powf` path: all hashes were equal).
//! - default, gait_walk, gait_walk_fast, stand, gait_treadmill (issue 22, end stops): the
//!   built-in URDFs' knee range starts at -10 deg instead of 0 (the gait data hyperextend to
//!   -2.1 deg, which the new end stop at the URDF limit would otherwise hold), so the leg's
//!   effective-mass table spans -10..100 deg and samples other angles. No run touches a stop;
//!   the numbers move by the table's interpolation: load force by at most 5.6 mN (gait_walk, at
//!   one impulse), knee angle by 2.5e-6 deg, the FDO's spiky disturbance estimate at one sample
//!   of a velocity reversal; the leg scenarios' structure refactors before it (issue 20) were
//!   byte-identical. The Rapier ankle's joint limit is replaced by the same end-stop law (no
//!   shipped run reaches it). The four bench scenarios are unchanged.
//! - stand, gait_treadmill (issue 23, a foot that lands): the sole's contact is the compliant
//!   Hunt-Crossley law instead of Rapier's rigid contacts (`ground.contact = "compliant"`, the
//!   new default): the heel strike's peak goes from 25.97 kN to 1.2 kN, standing sinks 5.1 mm
//!   into the heel pad instead of 0.15 mm; gait_treadmill's figures are in tests/it/walking.rs.
//!   gait_treadmill kept its constant 10 deg pelvic tilt explicitly then (the data files now
//!   carry the pelvis tilt, which a run uses by default). The other scenarios have no ground.
//! - all (issue 24, output speed): floats are written by `ryu` instead of `Display`: the same
//!   values in another notation (`0.0` for `0`, `1e-7` for `0.0000001`). Checked on the seven
//!   scenarios without ground against the previous build: every one of their 1.12 million
//!   values parses back to the same bits (files 2 % smaller on the gait runs, 5 % larger on the
//!   paper's). The test `output::csv::tests` checks the round trip on a million bit patterns.
//! - stand, gait_treadmill, treadmill_subject (issue 23, walking for any subject): the virtual
//!   other leg's damper defaults to 3000 N s/m instead of 6000 and its support never pulls
//!   (clamped at 0): `stand` differs in its settling transient only (the settled knee angle,
//!   ground reaction, pelvis height and load force agree with the 6000 run to 2e-5 N; with
//!   6000 its hash is the previous one). The walking runs also take the gait events from the
//!   foot's contact (the cascade's switch, the other leg's share), a data-implied hip height
//!   with the sole's static sink, a swing clearance and this leg's reach in double support,
//!   smoothed with 8 harmonics instead of 20; gait_treadmill takes the data's pelvis tilt
//!   instead of a constant 10 deg. gait_treadmill: stance knee moment correlation 0.735 ->
//!   0.922, GRF correlation 0.934 -> 0.974, unfiltered peak 1215 -> 867 N (tests/it/walking.rs);
//!   treadmill_subject (subject 01, T05): GRF correlation 0.951 -> 0.984, 10 Hz peak 1.42x ->
//!   1.10x the data's, knee moment correlation 0.899 -> 0.964.
//! - stand, gait_treadmill, treadmill_subject (issue 23, the belt and the leg's sweep): a new
//!   column `pelvis_x_m` after `pelvis_height_m` (stand's tether is locked: the column is 0
//!   and the file without it hashes to the previous record); the tether defaults to 1000 N/m
//!   and 1000 N s/m instead of 200 / 300 and pulls the pelvis toward a fore-aft target that
//!   carries the difference between the belt and the leg's stance sweep (0.007 m/s on
//!   gait_treadmill, 0.044 m/s on treadmill_subject): gait_treadmill's extensor peak 19.2 ->
//!   15.8 N m, flexor -35.3 -> -37.7 N m (tests/it/walking.rs); treadmill_subject's knee moment
//!   correlation 0.964 -> 0.959, flexor peak -41 -> -49 N m (data -48).
//! - gait_treadmill, treadmill_subject (issue 23, the support's inertial term): the virtual
//!   other leg carries its share of `m_subject (g + z_d'')` instead of the weight alone (the
//!   spring lagged the data's hip height by about `m z_d'' / K`, and the foot landed late):
//!   gait_treadmill's extensor peak 15.8 -> 20.8 N m (data 29.8), knee moment correlation
//!   0.912 -> 0.830, unfiltered peak 865 -> 985 N; treadmill_subject (subject 01, T05):
//!   extensor peak 6 -> 9 N m (data 15), knee moment correlation 0.959 -> 0.921.
//! - gait_treadmill, treadmill_subject (issue 33, walking for anyone): the pelvis's fore-aft
//!   target follows the supporting foot as the data's angles sweep it (the pelvis slows over
//!   the first half of each stance and speeds up over the second, as a person's does), and the
//!   virtual other leg carries the data's other-foot ground reaction instead of its share of
//!   `m_subject (g + z_d'')` (`hip.support_force` now defaults to `data` when walking; `stand`,
//!   a pose, keeps `weight` and is unchanged). gait_treadmill: knee moment correlation 0.830
//!   -> 0.929, extensor peak 20.8 -> 32.4 N m at 12.5 % (data 29.8 at 12.5 %), flexor peak
//!   -37.2 -> -45.6 N m (data -29.5; tests/it/walking.rs says why), GRF correlation 0.932 ->
//!   0.981, unfiltered peak 985 -> 956 N; treadmill_subject (subject 01, T05): knee moment
//!   correlation 0.921 -> 0.965, extensor peak 9 -> 15 N m (data 15), flexor -49 -> -57 N m
//!   (data -48), GRF correlation 0.951 -> 0.986. The 27 treadmill trials of the training set:
//!   README, "Walking for anyone".
//! - gait_treadmill, treadmill_subject (issue 32, the device's sensors): leg runs with a
//!   sampled controller record the device's 13 truth columns (segment angles and rates, heel
//!   and forefoot forces, cuff forces, pressures, hydraulic power, the device's knee moment)
//!   after the contact columns. Nothing else changed: the files without those columns hash
//!   to issue 33's records (checked below, `WITHOUT_DEVICE_COLUMNS`).
//! - gait_treadmill, treadmill_subject, and the reduced-engine records added before it (issue
//!   41, speed): a sampled controller's reference preview `r_next` is taken at the next sample
//!   instant's time as that step computes it, `(k + every) dt`, instead of `k dt + period`
//!   (which differ in the last bit of the time), so the preview is the next step's present and
//!   is computed once. Rounding only: every column moves by at most 2.7e-11 of its peak (the
//!   lumped-disturbance column, numerically zero, by 3e-8 N/s^2), every number in
//!   `summary.json` by at most 9e-10 relative (the loop gap of 1.5e-7 m; the others 2e-11),
//!   and every figure `exoleg run` prints for the ten scenarios on both engines, the
//!   `compare --plant bench|leg` tables and the 27-trial `gait-check` table is unchanged at its
//!   printed precision. The other optimisations of that issue change no bit (the records of
//!   `stand` and the non-walking scenarios are unchanged).

use sha2::{Digest, Sha256};
use std::path::Path;
use std::process::Command;

const EXPECTED: [(&str, &str); 10] = [
    ("default", "5ac8c3e27d09af9e58d18d5cbc45a0c6f714874123733f5e6c2a3aec99da997f"),
    ("gait_walk", "b2a449ced7f3f5b19d0d2290ba499d78846845d4b4709de21cf6339021fad488"),
    ("gait_walk_fast", "6f63153cc5a031d41460d350ce5af2d9a1c699f40e4ec97c2e84454bd7c1c19b"),
    ("paper_10hz_gamma200", "4c14aa1485fb6ee489af6ef10ffe123a1778b73c49fd3af4fd3c00f79d4160a3"),
    ("paper_10hz_gamma300", "93841bf446b30cc78bb0ce464fa37d5c007cc4b4f83849aca706724447eb61aa"),
    ("paper_2hz_gamma100", "aa207ba433dfb64397d956b72da15f0ff803059e904f3bc4c533a8ab73062d6b"),
    ("paper_2hz_gamma200", "8bfafba8298a3886711e89216a95b04f8e046d5d8290bc4959a31cad5ff6172e"),
    // Added with issue 12 (loaded walking).
    ("stand", "1db9d3ff5af0e9a9cd5ca7655aa63166708ad14ecf1fcbb01ead55ca02b9e79b"),
    ("gait_treadmill", "3429044405382fde7aa6ba10c14fc6c74f98d00c6a823f977f66e389134e9e8c"),
    // Added with issue 23 (any subject).
    ("treadmill_subject", "b13182f58e50b26e263cafcfc315a03e38eccdc7dfce333562eb27281429f7fe"),
];

/// The records (issue 33's) of the runs that now carry the device's columns (issue 32): the
/// files without those columns.
const WITHOUT_DEVICE_COLUMNS: [(&str, &str); 2] = [
    ("gait_treadmill", "95a5ad6e8b06c7ca90d7c69fb31cc2c005e3cf2f2780d43821e602f9e1d3defc"),
    ("treadmill_subject", "6dbca6c04e9ddae99b57b0385a97b3effc3bc04fd0832f6bb06e5d96a4f36d8a"),
];

/// A CSV without the device's columns (`exoleg::record::DEVICE_COLUMNS`).
pub(crate) fn without_device_columns(csv: &str) -> String {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let keep: Vec<usize> =
        (0..header.len()).filter(|i| !exoleg::record::DEVICE_COLUMNS.contains(&header[*i])).collect();
    let pick = |l: &str| {
        let v: Vec<&str> = l.split(',').collect();
        keep.iter().map(|i| v[*i]).collect::<Vec<_>>().join(",") + "\n"
    };
    std::iter::once(header.join(",")).map(|h| pick(&h)).chain(lines.map(pick)).collect()
}

/// The walking scenarios on the reduced engine at 1 ms (`--set 'leg.engine="reduced"' --set
/// sim.dt_s=0.001`), the speed issue's (41) case: recorded before its optimisations of the
/// step (the preview's time since: see the module's list).
const REDUCED_1MS: [(&str, &str); 3] = [
    ("gait_treadmill", "c092c69ed7503f91d433496be788101879234867f9cb973df20d3c4d1b9b8137"),
    ("treadmill_subject", "40209cced71986e9d27b3e6acbe0105316d9a6aa2cee2d59cb7afc27d409b017"),
    ("stand", "fc438d0be671f3164128a742875d9e52707ecf9f8a63cb0957f3630d40ce0f73"),
];

#[test]
fn shipped_walking_scenarios_on_the_reduced_engine_give_the_recorded_timeseries() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
    let tmp = tempfile::tempdir().unwrap();
    let mut wrong = Vec::new();
    for (name, hash) in REDUCED_1MS {
        let out = tmp.path().join(name);
        let o = Command::new(env!("CARGO_BIN_EXE_exoleg"))
            .args(["run", "--quiet", "--set", "leg.engine=\"reduced\"", "--set", "sim.dt_s=0.001", "--out"])
            .arg(&out)
            .arg(dir.join(format!("{name}.toml")))
            .output()
            .unwrap();
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        let got = format!("{:x}", Sha256::digest(std::fs::read(out.join("timeseries.csv")).unwrap()));
        if got != hash {
            wrong.push(format!("{name} (reduced, 1 ms): {got}"));
        }
    }
    assert!(wrong.is_empty(), "changed time series:\n{}", wrong.join("\n"));
}

#[test]
fn shipped_scenarios_give_the_recorded_timeseries() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
    let tmp = tempfile::tempdir().unwrap();
    let mut wrong = Vec::new();
    for (name, hash) in EXPECTED {
        let out = tmp.path().join(name);
        let o = Command::new(env!("CARGO_BIN_EXE_exoleg"))
            .args(["run", "--quiet", "--out"])
            .arg(&out)
            .arg(dir.join(format!("{name}.toml")))
            .output()
            .unwrap();
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        let bytes = std::fs::read(out.join("timeseries.csv")).unwrap();
        let got = format!("{:x}", Sha256::digest(&bytes));
        if got != hash {
            wrong.push(format!("{name}: {got}"));
        }
        if let Some((_, old)) = WITHOUT_DEVICE_COLUMNS.iter().find(|(n, _)| *n == name) {
            let stripped = without_device_columns(std::str::from_utf8(&bytes).unwrap());
            let got = format!("{:x}", Sha256::digest(stripped.as_bytes()));
            if got != *old {
                wrong.push(format!("{name} without the device's columns: {got}"));
            }
        }
    }
    assert!(wrong.is_empty(), "changed time series:\n{}", wrong.join("\n"));
}

/// `output.every_steps = 10` keeps rows 0, 10, 20, ... of the full file (the same bytes) and
/// leaves the summary's figures as they are.
#[test]
fn every_tenth_row_thins_the_file_and_not_the_summary() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
    let tmp = tempfile::tempdir().unwrap();
    let run = |name: &str, every: usize| {
        let out = tmp.path().join(name);
        let o = Command::new(env!("CARGO_BIN_EXE_exoleg"))
            .args(["run", "--quiet", "--set", &format!("output.every_steps={every}"), "--out"])
            .arg(&out)
            .arg(dir.join("paper_2hz_gamma100.toml"))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let csv = std::fs::read_to_string(out.join("timeseries.csv")).unwrap();
        let mut summary: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
        for k in ["wall_time_s", "steps_per_second", "scenario"] {
            summary.as_object_mut().unwrap().remove(k);
        }
        (csv, summary)
    };
    let (full, s1) = run("full", 1);
    let (thin, s10) = run("thin", 10);
    let full: Vec<&str> = full.lines().collect();
    let thin: Vec<&str> = thin.lines().collect();
    // 1,001 rows (1 ms rows over 1 s) -> 101.
    assert_eq!(thin.len() - 1, (full.len() - 2) / 10 + 1);
    assert_eq!(thin[0], full[0]);
    for (i, line) in thin.iter().enumerate().skip(1) {
        assert_eq!(*line, full[1 + (i - 1) * 10], "row {i}");
    }
    assert_eq!(s1, s10, "the summary's figures");
}

/// `output.format = "parquet"` holds the same values as `timeseries.csv`, bit for bit, under
/// the same column names (read back with the parquet crate's reader).
#[test]
fn parquet_holds_the_csv_values() {
    use parquet::file::reader::{FileReader, SerializedFileReader};
    use parquet::record::RowAccessor;
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
    let tmp = tempfile::tempdir().unwrap();
    let run = |name: &str, format: &str| {
        let out = tmp.path().join(name);
        let o = Command::new(env!("CARGO_BIN_EXE_exoleg"))
            .args(["run", "--quiet", "--set", &format!("output.format=\"{format}\""), "--out"])
            .arg(&out)
            .arg(dir.join("gait_walk.toml"))
            .args(["--set", "sim.duration_s=0.5", "--set", "metrics.settle_s=0.1"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        out
    };
    let (csv, pq) = (run("csv", "csv"), run("pq", "parquet"));
    assert!(!pq.join("timeseries.csv").exists() && !csv.join("timeseries.parquet").exists());
    let text = std::fs::read_to_string(csv.join("timeseries.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let reader = SerializedFileReader::new(std::fs::File::open(pq.join("timeseries.parquet")).unwrap()).unwrap();
    let schema = reader.metadata().file_metadata().schema_descr();
    let names: Vec<String> = schema.columns().iter().map(|c| c.name().to_string()).collect();
    assert_eq!(names, header);
    let mut rows = 0;
    for (row, line) in reader.get_row_iter(None).unwrap().zip(lines) {
        let row = row.unwrap();
        for (j, v) in line.split(',').enumerate() {
            let want: f64 = v.parse().unwrap();
            let got = row.get_double(j).unwrap();
            assert!(got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()), "row {rows} {}", header[j]);
        }
        rows += 1;
    }
    assert_eq!(rows, text.lines().count() - 1);
}
