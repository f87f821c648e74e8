//! Steps per second of whole simulations (`cargo bench`): the coupled leg (Rapier multibody +
//! hydraulics + ARBFNN-FDO-ZNN, the embedded default scenario), the same on the reduced engine,
//! and the bench plant (same controller and hydraulics, no mechanics), whose step is the unit
//! the README's ratios use. Criterion reports throughput in elements/s = simulated steps/s
//! (1 ms steps). `leg_rapier_step_only` is the floor of the Rapier path: the same leg built and
//! stepped by `Leg::step` alone (Rapier's step plus our force application and pin readout, same
//! solver settings, 1000 steps of 1 ms) under the reference force, with no controller,
//! hydraulics or recording.
//!
//! `treadmill_*`: `gait_treadmill.toml` (0.25 ms steps, 1.1 s: one stride) with the compliant
//! sole (the default) and with Rapier's rigid contacts; `treadmill_reduced` the same stride on
//! the reduced engine at 0.5 ms (the step its accuracy allows, README "Speed"), and at 0.25 ms.
//! Compare per simulated second: a 0.5 ms step covers twice the time of a 0.25 ms one. `*_csv`: the same run as its `_memory`
//! twin writing `timeseries.csv` (to a temporary folder, flushed and synced as the CLI does)
//! instead of keeping the rows in memory: the output path's cost (10 s runs, 10,000 rows).
//! `gait_check/v3_reduced_2_jobs`: the whole v3 gait-check table (see below).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use exoleg::record::NullSink;

fn steps(c: &mut Criterion) {
    let cases = [
        ("leg_arbfnn_fdo_znn", exoleg::load(None, &[]).unwrap()),
        ("leg_arbfnn_fdo_znn_4_iterations", exoleg::load(None, &["leg.solver_iterations=4"]).unwrap()),
        ("leg_erl_smc", exoleg::load(None, &["controller.kind=\"erl_smc\""]).unwrap()),
        ("leg_reduced_arbfnn_fdo_znn", exoleg::load(None, &["leg.engine=\"reduced\""]).unwrap()),
        ("bench_arbfnn_fdo_znn", exoleg::load(None, &["plant.kind=\"bench\""]).unwrap()),
    ];
    let mut g = c.benchmark_group("simulation");
    g.sample_size(20);
    for (name, s) in &cases {
        g.throughput(Throughput::Elements(s.model.steps as u64));
        g.bench_function(*name, |b| b.iter(|| exoleg::run(&s.model, &mut NullSink).expect("run")));
    }
    let treadmill = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/gait_treadmill.toml");
    for (name, sets) in [
        ("treadmill_compliant", &["sim.duration_s=1.1"][..]),
        ("treadmill_rigid", &["sim.duration_s=1.1", "ground.contact=\"rigid\""][..]),
        ("treadmill_reduced", &["sim.duration_s=1.1", "leg.engine=\"reduced\"", "sim.dt_s=0.0005"][..]),
        ("treadmill_reduced_250us", &["sim.duration_s=1.1", "leg.engine=\"reduced\""][..]),
        ("treadmill_reduced_1ms", &["sim.duration_s=1.1", "leg.engine=\"reduced\"", "sim.dt_s=0.001"][..]),
    ] {
        let s =
            exoleg::load(Some(&treadmill), &sets.iter().chain(&["metrics.settle_s=0.5"]).copied().collect::<Vec<_>>())
                .unwrap();
        g.throughput(Throughput::Elements(s.model.steps as u64));
        g.bench_function(name, |b| b.iter(|| exoleg::run(&s.model, &mut NullSink).expect("run")));
    }
    // The device's sensors (issue 32) on the reduced treadmill at 1 ms (every step a sample):
    // none sampled (the model without its device setup: the sampled step as it was), and every
    // one on with the `device` preset's noise, biases, walks, rates and A/D.
    let base = ["sim.duration_s=1.1", "leg.engine=\"reduced\"", "sim.dt_s=0.001", "metrics.settle_s=0.5"];
    let with = exoleg::load(Some(&treadmill), &base).unwrap();
    let mut without = (*with.model).clone();
    without.device = None;
    without.device_columns = false;
    let without = std::sync::Arc::new(without);
    let device = exoleg::load(Some(&treadmill), &[&base[..], &["sensors.preset=\"device\""]].concat()).unwrap();
    g.throughput(Throughput::Elements(with.model.steps as u64));
    g.bench_function("treadmill_reduced_1ms_no_device_sensors", |b| {
        b.iter(|| exoleg::run(&without, &mut NullSink).expect("run"))
    });
    g.bench_function("treadmill_reduced_1ms_device_preset", |b| {
        b.iter(|| exoleg::run(&device.model, &mut NullSink).expect("run"))
    });
    let tmp = tempfile::tempdir().unwrap();
    for (name, sets) in [
        ("reduced", &["leg.engine=\"reduced\"", "sim.duration_s=10.0"][..]),
        ("bench", &["plant.kind=\"bench\"", "sim.duration_s=10.0"][..]),
    ] {
        let s = exoleg::load(None, sets).unwrap();
        g.throughput(Throughput::Elements(s.model.steps as u64));
        g.bench_function(format!("{name}_memory"), |b| {
            b.iter(|| {
                let mut rec = exoleg::record::MemoryRecord::default();
                exoleg::run(&s.model, &mut rec).expect("run");
                rec.rows.len()
            })
        });
        let out = tmp.path().join(name);
        g.bench_function(format!("{name}_csv"), |b| {
            b.iter(|| {
                let mut sink = exoleg::output::CsvSink::create(&out).expect("csv");
                exoleg::run(&s.model, &mut sink).expect("run");
                sink.finish().expect("flush")
            })
        });
    }
    let urdf = exoleg::leg::BUILTIN_URDFS.iter().find(|(n, _)| *n == "builtin:exo_leg").expect("builtin leg").1;
    let model = exoleg::leg::LegSpec::from_urdf_str(urdf, "knee").expect("builtin leg parses");
    g.throughput(Throughput::Elements(1000));
    g.bench_function("leg_rapier_step_only", |b| {
        b.iter(|| {
            let mut leg = exoleg::leg::Leg::new(&model, 30f64.to_radians(), 1e-3).expect("leg");
            for k in 0..1000 {
                leg.step(200.0 * (4.0 * std::f64::consts::PI * k as f64 * 1e-3).sin(), None);
            }
            leg.knee_angle_rad()
        })
    });
    g.finish();
}

/// `gait_check/v3_reduced_2_jobs`: the whole v3 table as `exoleg gait-check assets/gait/v3`
/// runs it (21 trials, six strides each on the reduced engine at 1 ms, the table and the 21
/// figures written into a fresh folder) on two worker threads.
fn gait_check(c: &mut Criterion) {
    let v3 = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/gait/v3");
    let tmp = tempfile::tempdir().unwrap();
    let opts = exoleg::study::gait_check::CheckOptions { jobs: 2, ..Default::default() };
    let mut g = c.benchmark_group("gait_check");
    g.sample_size(10);
    g.bench_function("v3_reduced_2_jobs", |b| {
        b.iter(|| {
            exoleg::study::gait_check::gait_check(std::slice::from_ref(&v3), &tmp.path().join("out"), &opts)
                .expect("check")
        })
    });
}

criterion_group!(benches, steps, gait_check);
criterion_main!(benches);
