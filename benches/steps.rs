//! Steps per second of whole simulations (`cargo bench`): the coupled leg (Rapier multibody +
//! hydraulics + ARBFNN-FDO-ZNN, the embedded default scenario), the same on the reduced engine,
//! and the bench plant (same controller and hydraulics, no mechanics), whose step is the unit
//! the README's ratios use. Criterion reports throughput in elements/s = simulated steps/s
//! (1 ms steps).

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
    g.finish();
}

criterion_group!(benches, steps);
criterion_main!(benches);
