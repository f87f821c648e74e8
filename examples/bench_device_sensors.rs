//! The cost of the device's sensors (issue 32) on the reduced treadmill at 1 ms, one stride,
//! every step a 1 kHz sample: a benchmark, not a test.
//!
//! ```sh
//! cargo run --release --example bench_device_sensors            # wall time, alternate rounds
//! valgrind --tool=callgrind target/release/examples/bench_device_sensors none 1   # instructions
//! valgrind --tool=callgrind target/release/examples/bench_device_sensors device 1
//! ```
//! `none`: the model without its device setup (the sampled step as it was before the device's
//! sensors); `ideal`: every device sensor sampled, ideal; `device`: every one with the
//! `device` preset's noise, biases, walks, rates and A/D.

use exoleg::record::NullSink;
use std::sync::Arc;
use std::time::Instant;

fn model(variant: &str) -> Arc<exoleg::Model> {
    let treadmill = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios/gait_treadmill.toml");
    let mut sets = vec!["sim.duration_s=1.1", "leg.engine=\"reduced\"", "sim.dt_s=0.001", "metrics.settle_s=0.5"];
    if variant == "device" {
        sets.push("sensors.preset=\"device\"");
    }
    let s = exoleg::load(Some(&treadmill), &sets).expect("scenario");
    let mut m = (*s.model).clone();
    if variant == "none" {
        m.device = None;
        m.device_columns = false;
    }
    Arc::new(m)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let (Some(v), Some(n)) = (args.get(1), args.get(2)) {
        let m = model(v);
        for _ in 0..n.parse::<usize>().expect("runs") {
            exoleg::run(&m, &mut NullSink).expect("run");
        }
        return;
    }
    let variants = ["none", "ideal", "device"];
    let models: Vec<_> = variants.iter().map(|v| model(v)).collect();
    let mut times: Vec<Vec<f64>> = vec![Vec::new(); 3];
    for _round in 0..15 {
        for (i, m) in models.iter().enumerate() {
            let t0 = Instant::now();
            for _ in 0..10 {
                exoleg::run(m, &mut NullSink).expect("run");
            }
            times[i].push(t0.elapsed().as_secs_f64() / 10.0);
        }
    }
    for (v, t) in variants.iter().zip(&mut times) {
        t.sort_by(f64::total_cmp);
        println!("{v:>7}: median {:.3} ms per stride (1100 steps)", 1e3 * t[t.len() / 2]);
    }
    let med = |i: usize| times[i][times[i].len() / 2];
    println!("ideal / none {:.3}, device / none {:.3}", med(1) / med(0), med(2) / med(0));
}
