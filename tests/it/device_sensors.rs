//! The device's own sensors (issue 32) against independent truth: the accelerometers at rest,
//! the gyroscopes against the recorded segment angles, the cuffs and pressures against what
//! exoleg applies, the heel sensor against the contact, both engines against each other, and
//! the `device` preset's noise model against its configuration.

use crate::common::shipped;
use exoleg::control::{ControlOutput, ControlStop, DiscreteController, SampleInput};
use exoleg::record::{MemoryRecord, Row};
use exoleg::sensors::{DeviceReadings, ACCEL_RANGE_M_S2, FOOT_RANGE_N, GYRO_RANGE_RAD_S};
use exoleg::sim::Simulation;
use exoleg::Resources;
use std::sync::{Arc, Mutex};

/// The run's own sampled controller, recording every sample's device readings.
struct Recorder {
    inner: Box<dyn DiscreteController>,
    samples: Arc<Mutex<Vec<(f64, DeviceReadings)>>>,
}

impl DiscreteController for Recorder {
    fn kind(&self) -> &str {
        self.inner.kind()
    }
    fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop> {
        self.samples.lock().unwrap().push((s.t_s, s.device));
        self.inner.update(s)
    }
}

/// A run of `s` with its own controller: the samples' device readings and the rows.
fn recorded(s: &exoleg::Scenario) -> (Vec<(f64, DeviceReadings)>, MemoryRecord, exoleg::metrics::Summary) {
    let sc = s.resolve(&Resources::new()).unwrap();
    let m = &sc.model;
    let inner = m.controller.discrete(m.nominal, m.valve_limit).unwrap();
    let samples = Arc::new(Mutex::new(Vec::new()));
    let rec = Recorder { inner, samples: samples.clone() };
    let sim = Simulation::with_controller(m.clone(), Box::new(rec)).unwrap();
    let mut mem = MemoryRecord::default();
    let (summary, _) = exoleg::session::run_simulation(sim, &mut mem).unwrap();
    let v = samples.lock().unwrap().clone();
    (v, mem, summary)
}

/// The row at time `t` (s) of a run stepped by `dt` (s).
fn row_at(rows: &[Row], t: f64, dt: f64) -> &Row {
    let r = &rows[(t / dt).round() as usize];
    assert!((r.t_s - t).abs() < 1e-9);
    r
}

/// Standing still on the carriage (stand.toml, ideal sensors): each accelerometer reads
/// gravity in its frame, |a| = 9.81 m/s^2, tilted by its segment's angle. Measured after 2.5 s:
/// |a| within 4.6e-7 m/s^2 of 9.81, the tilt within 4.6e-6 deg of the recorded segment angle
/// (the residual settling motion); the limits are 0.01 m/s^2 and 0.05 deg (the test's).
#[test]
fn accelerometers_at_rest_read_gravity_in_their_frame() {
    let s = shipped("stand.toml", &["controller.sample_period_s=0.001"]);
    let (samples, rec, _) = recorded(&s);
    let (mut worst_g, mut worst_tilt) = (0.0f64, 0.0f64);
    for (t, d) in samples.iter().filter(|(t, _)| *t >= 2.5) {
        let row = row_at(&rec.rows, *t, 0.001).device.unwrap();
        for (a, angle) in [(d.thigh_accel_m_s2, row.thigh_angle_deg), (d.shank_accel_m_s2, row.shank_angle_deg)] {
            let norm = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            worst_g = worst_g.max((norm - 9.81).abs());
            worst_tilt = worst_tilt.max((a[0].atan2(a[2]).to_degrees() - angle).abs());
        }
    }
    println!("at rest: |a| - 9.81 up to {worst_g:.2e} m/s^2, tilt - angle up to {worst_tilt:.2e} deg");
    assert!(worst_g < 0.01, "{worst_g}");
    assert!(worst_tilt < 0.05, "{worst_tilt}");
}

/// Treadmill walking (gait_treadmill.toml, ideal sensors): each gyroscope's sagittal axis is
/// the segment's angular velocity (the central difference of the recorded segment angle; the
/// gyroscope's y axis turns about the world's y, the segment angle is a forward turn, so
/// -gyro_y); its integral over a stride returns the segment's change of angle; each cuff
/// sensor reads the force exoleg applies there, exactly; the pressures times the areas give
/// the load force; the heel sensor's onset is the foot's first contact. Measured: RMS
/// difference 0.010 % (thigh) and 0.020 % (shank) of the 2000 deg/s range (limit 1 %, the
/// issue's), the stride integral within 0.0002 deg of the angle's change (limit 0.1 deg),
/// pressures within 2.6e-13 relative (limit 1e-9), the heel onset at the first sample at or
/// after the contact (0.25 ms after it at most; limit one sample).
#[test]
fn gyroscopes_cuffs_pressures_and_heel_against_the_truth() {
    let dt = 0.00025;
    let s = shipped("gait_treadmill.toml", &[]);
    let (samples, rec, _) = recorded(&s);
    let rows = &rec.rows;
    let range_deg_s = GYRO_RANGE_RAD_S.to_degrees();
    let mut worst_rms = 0.0f64;
    for seg in 0..2 {
        let angle = |r: &Row| {
            let d = r.device.unwrap();
            [d.thigh_angle_deg, d.shank_angle_deg][seg]
        };
        let gyro = |d: &DeviceReadings| -[d.thigh_gyro_rad_s, d.shank_gyro_rad_s][seg][1].to_degrees();
        let (mut sum, mut n) = (0.0, 0);
        for (t, d) in samples.iter().filter(|(t, _)| *t >= 1.1 && *t < 6.5) {
            let diff = (angle(row_at(rows, t + dt, dt)) - angle(row_at(rows, t - dt, dt))) / (2.0 * dt);
            sum += (gyro(d) - diff).powi(2);
            n += 1;
        }
        let rms_pct = 100.0 * (sum / n as f64).sqrt() / range_deg_s;
        worst_rms = worst_rms.max(rms_pct);
        // One stride from 2.2 s (1.1 s long): trapezoid of the 1 kHz readings.
        let stride: Vec<&(f64, DeviceReadings)> =
            samples.iter().filter(|(t, _)| *t >= 2.2 - 1e-9 && *t <= 3.3 + 1e-9).collect();
        let integral: f64 = stride.windows(2).map(|w| 0.5 * (gyro(&w[0].1) + gyro(&w[1].1)) * (w[1].0 - w[0].0)).sum();
        let change = angle(row_at(rows, 3.3, dt)) - angle(row_at(rows, 2.2, dt));
        println!("segment {seg}: gyro RMS difference {rms_pct:.4} % of range, stride integral {integral:.4} vs {change:.4} deg");
        assert!(rms_pct < 1.0, "segment {seg}: {rms_pct} %");
        assert!((integral - change).abs() < 0.1, "segment {seg}: {integral} vs {change}");
    }
    let (a1, a2) = (3.25e-4, 2.1e-4);
    let mut worst_p = 0.0f64;
    for (t, d) in &samples {
        let r = row_at(rows, *t, dt);
        let dev = r.device.unwrap();
        assert_eq!(d.thigh_cuff_force_n.to_bits(), dev.thigh_cuff_force_n.to_bits(), "t {t}");
        assert_eq!(d.shank_cuff_force_n.to_bits(), dev.shank_cuff_force_n.to_bits(), "t {t}");
        let f = r.load_force_n;
        let scale = f.abs().max(1.0);
        worst_p = worst_p.max((a1 * d.pressure_a_pa - a2 * d.pressure_b_pa - f).abs() / scale);
        worst_p = worst_p.max((0.5 * (a1 + a2) * d.load_pressure_pa - f).abs() / scale);
    }
    println!("pressures x areas - load force: {worst_p:.2e} relative; gyro worst {worst_rms:.4} %");
    assert!(worst_p < 1e-9, "{worst_p}");
    heel_onsets_follow_the_contact(&samples, rows);
}

/// Each heel strike after the first swing: the heel sensor's first positive reading is the
/// first sample at or after the first step with a vertical ground reaction.
fn heel_onsets_follow_the_contact(samples: &[(f64, DeviceReadings)], rows: &[Row]) {
    let vertical = |r: &Row| r.contact.unwrap().ground_reaction_vertical_n;
    let mut contacts = Vec::new();
    for w in rows.windows(2).filter(|w| w[0].t_s > 0.5) {
        if vertical(&w[0]) == 0.0 && vertical(&w[1]) > 0.0 {
            contacts.push(w[1].t_s);
        }
    }
    let mut onsets = Vec::new();
    for w in samples.windows(2).filter(|w| w[0].0 > 0.5) {
        if w[0].1.heel_force_n == 0.0 && w[1].1.heel_force_n > 0.0 {
            onsets.push(w[1].0);
        }
    }
    assert!(contacts.len() >= 5, "{contacts:?}");
    assert_eq!(contacts.len(), onsets.len(), "{contacts:?} {onsets:?}");
    for (c, o) in contacts.iter().zip(&onsets) {
        println!("contact {c:.5} s, heel onset {o:.5} s");
        assert!(*o >= *c - 1e-9 && *o - *c <= 0.001 + 1e-9, "contact {c}, onset {o}");
    }
}

/// The six shipped treadmill trials on both engines (Rapier at 0.125 ms, the oracle of the
/// engines' other comparisons; the reduced engine at 1 ms; the same 1 kHz samples): the IMUs'
/// and foot sensors' readings agree. Measured with issue 33's walking model (RMS difference
/// after the first stride, % of the channel's range; accelerometers, gyroscopes, foot): 01 T03
/// 0.051, 0.008, 0.054; 01 T05 0.112, 0.016, 0.097; 01 T06 0.084, 0.014, 0.091; 02 T03 0.021,
/// 0.004, 0.046; 02 T05 0.076, 0.008, 0.056; 02 T06 0.843, 0.026, 0.156 (limit 2 %, the
/// issue's). Against Rapier at 0.25 ms 02 T06's accelerometers differ by 3.8 %: after each
/// heel strike Rapier's thigh rings at the sample rate for some 30 ms at 0.25 ms steps (+-40
/// m/s^2 sample to sample; about 3 ms at 0.125 ms), which the reduced engine does not; the IMU
/// shows Rapier's step artefact.
#[test]
fn both_engines_read_the_same_imus_and_feet() {
    let trials = [
        ("01", "t03", 0.85, 1.3833),
        ("01", "t05", 1.21, 1.0633),
        ("01", "t06", 1.40, 1.0067),
        ("02", "t03", 0.88, 1.21),
        ("02", "t05", 1.25, 1.01),
        ("02", "t06", 1.44, 0.94),
    ];
    let mut worst = [0.0f64; 3];
    for (subject, trial, belt, stride) in trials {
        let who = if subject == "01" {
            ["subject.mass_kg=74.3", "subject.height_m=1.725", "subject.leg_length_m=0.89", "subject.sex=\"male\""]
        } else {
            ["subject.mass_kg=52.9", "subject.height_m=1.668", "subject.leg_length_m=0.865", "subject.sex=\"female\""]
        };
        let run = |dt: f64, engine: &str| {
            let dur = (4.0 * stride / 0.001_f64).round() * 0.001;
            let mut sets = vec![
                format!("reference.gait_trial=\"wbds{subject}_treadmill_{trial}\""),
                format!("ground.belt_speed_m_s={belt}"),
                format!("sim.duration_s={dur}"),
                format!("metrics.settle_s={stride}"),
                format!("sim.dt_s={dt}"),
                format!("leg.engine=\"{engine}\""),
            ];
            sets.extend(who.iter().map(|w| w.to_string()));
            recorded(&shipped("treadmill_subject.toml", &sets.iter().map(String::as_str).collect::<Vec<_>>())).0
        };
        let (a, b) = (run(0.000125, "rapier"), run(0.001, "reduced"));
        assert_eq!(a.len(), b.len());
        let mut sums = [0.0f64; 3];
        let mut n = 0;
        for ((ta, da), (_, db)) in a.iter().zip(&b).filter(|((t, _), _)| *t >= stride) {
            let (va, vb) = (da.values(), db.values());
            let sq = |r: std::ops::Range<usize>, range: f64| r.map(|i| ((va[i] - vb[i]) / range).powi(2)).sum::<f64>();
            sums[0] += (sq(2..5, ACCEL_RANGE_M_S2) + sq(8..11, ACCEL_RANGE_M_S2)) / 6.0;
            sums[1] += (sq(5..8, GYRO_RANGE_RAD_S) + sq(11..14, GYRO_RANGE_RAD_S)) / 6.0;
            sums[2] += sq(14..16, FOOT_RANGE_N) / 2.0;
            n += 1;
            let _ = ta;
        }
        let pct = sums.map(|s| 100.0 * (s / n as f64).sqrt());
        println!("{subject} {trial}: accel {:.3} %, gyro {:.3} %, foot {:.3} % of range", pct[0], pct[1], pct[2]);
        for k in 0..3 {
            worst[k] = worst[k].max(pct[k]);
        }
    }
    assert!(worst.iter().all(|w| *w < 2.0), "{worst:?}");
}

/// The `device` preset's noise model over a 60 s still stand (stand.toml on the reduced engine,
/// the controller sampled at 1 kHz, fixed seed): per channel, the mean of (reading - (1 + s)
/// truth) is the configured bias and its standard deviation the configured noise (datasheet
/// density times sqrt(rate), or the channel's noise), within 5 %. The truth of an IMU at rest
/// is gravity turned by its segment's recorded angle, the other channels' their truth columns.
/// Measured (printed per channel): worst |mean / bias - 1| 0.027 (a gyroscope's y: its bias
/// random walk over the minute), worst |sd / noise - 1| 0.010; the means of the channels
/// without a bias within 0.002 of their noise.
#[test]
fn the_device_presets_noise_matches_its_configuration() {
    use exoleg::sensors::device_preset as d;
    // The force loop's own sensors kept ideal (52 bits, no noise), so the noise does not make
    // the knee tremble: the leg stands still and the IMUs' truth is gravity alone.
    let mut sets: Vec<String> = [
        "controller.sample_period_s=0.001",
        "sensors.preset=\"device\"",
        "leg.engine=\"reduced\"",
        "sim.duration_s=62.0",
    ]
    .map(String::from)
    .to_vec();
    for c in ["force", "spool", "piston", "knee", "piston_velocity"] {
        sets.push(format!("sensors.{c}.noise_std=0.0"));
        sets.push(format!("sensors.{c}.bits=52"));
    }
    let s = shipped("stand.toml", &sets.iter().map(String::as_str).collect::<Vec<_>>());
    let (samples, rec, _) = recorded(&s);
    let still: Vec<&(f64, DeviceReadings)> = samples.iter().filter(|(t, _)| *t >= 2.0).collect();
    let g = 9.81;
    let mut report = Vec::new();
    for (imu, name) in [(0usize, "thigh"), (1, "shank")] {
        for axis in 0..3 {
            let mut err = Vec::new();
            let mut gerr = Vec::new();
            for (t, dv) in &still {
                let row = row_at(&rec.rows, *t, 0.001).device.unwrap();
                let angle = [row.thigh_angle_deg, row.shank_angle_deg][imu].to_radians();
                let f = [g * angle.sin(), 0.0, g * angle.cos()][axis];
                let acc = [dv.thigh_accel_m_s2, dv.shank_accel_m_s2][imu][axis];
                err.push(acc - (1.0 + d::ACCEL_SCALE[axis]) * f);
                // At rest the gyroscope's truth is 0.
                gerr.push([dv.thigh_gyro_rad_s, dv.shank_gyro_rad_s][imu][axis]);
            }
            report.push((
                format!("{name} accel {axis}"),
                err,
                d::ACCEL_BIAS[axis],
                d::ACCEL_NOISE_DENSITY * 1000f64.sqrt(),
            ));
            report.push((
                format!("{name} gyro {axis}"),
                gerr,
                d::GYRO_BIAS[axis],
                d::GYRO_NOISE_DENSITY * 1000f64.sqrt(),
            ));
        }
    }
    // The plain channels against their truth columns: no bias; the noise with the A/D's
    // quantisation (LSB^2 / 12).
    let lsb = |range: f64, bits: u32| 2.0 * range / 2f64.powi(bits as i32);
    let with_q = |sd: f64, l: f64| (sd * sd + l * l / 12.0).sqrt();
    let (cuff, press, foot) = (d::CUFF, d::PRESSURE, d::FOOT);
    type Channel = (&'static str, fn(&DeviceReadings) -> f64, fn(&exoleg::record::DeviceRow) -> f64, f64);
    let plain: [Channel; 6] = [
        ("thigh cuff", |d| d.thigh_cuff_force_n, |r| r.thigh_cuff_force_n, with_q(cuff.0, lsb(1000.0, cuff.1))),
        ("shank cuff", |d| d.shank_cuff_force_n, |r| r.shank_cuff_force_n, with_q(cuff.0, lsb(1000.0, cuff.1))),
        ("pressure A", |d| d.pressure_a_pa, |r| r.pressure_a_pa, with_q(press.0, lsb(25e6, press.1))),
        ("pressure B", |d| d.pressure_b_pa, |r| r.pressure_b_pa, with_q(press.0, lsb(25e6, press.1))),
        ("heel", |d| d.heel_force_n, |r| r.heel_force_n, with_q(foot.1, lsb(foot.2, foot.3))),
        ("forefoot", |d| d.forefoot_force_n, |r| r.forefoot_force_n, with_q(foot.1, lsb(foot.2, foot.3))),
    ];
    for (name, read, truth, noise) in plain {
        let e = still.iter().map(|(t, dv)| read(dv) - truth(&row_at(&rec.rows, *t, 0.001).device.unwrap())).collect();
        report.push((name.to_string(), e, 0.0, noise));
    }
    let (mut worst_mean, mut worst_sd) = (0.0f64, 0.0f64);
    for (name, e, bias, noise) in &report {
        let n = e.len() as f64;
        let mean = e.iter().sum::<f64>() / n;
        let sd = (e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
        println!("{name}: mean {mean:.5} (bias {bias:.5}), sd {sd:.5} (noise {noise:.5})");
        // Without a bias, the mean within 5 % of the noise.
        let m = if *bias == 0.0 { mean.abs() / noise } else { (mean / bias - 1.0).abs() };
        worst_mean = worst_mean.max(m);
        worst_sd = worst_sd.max((sd / noise - 1.0).abs());
    }
    println!("worst: mean {worst_mean:.4}, sd {worst_sd:.4}");
    assert!(worst_mean < 0.05 && worst_sd < 0.05, "{worst_mean} {worst_sd}");
}

/// The device sensors' benchmark example (examples/bench_device_sensors.rs, built by `cargo
/// test`) runs: one stride of each variant.
#[test]
fn the_device_sensors_benchmark_example_runs() {
    let dir = std::path::Path::new(&crate::common::exe()).parent().unwrap().join("examples");
    let exe = dir.join("bench_device_sensors");
    for variant in ["none", "ideal", "device"] {
        let o = std::process::Command::new(&exe).args([variant, "1"]).output().expect("the example runs");
        assert!(o.status.success(), "{variant}: {}", String::from_utf8_lossy(&o.stderr));
    }
}
