//! Steps per second of whole simulations (`cargo bench`): the coupled leg (Rapier multibody +
//! hydraulics + ARBFNN-FDO-ZNN, the embedded default scenario) and the bench plant.
//! Criterion reports throughput in elements/s = simulated steps/s (1 ms steps).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use exoleg::Scenario;

fn scenario(sets: &[&str]) -> Scenario {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    Scenario::load(None, &sets).expect("scenario")
}

fn steps(c: &mut Criterion) {
    let cases = [
        ("leg_arbfnn_fdo_znn", scenario(&[])),
        ("leg_arbfnn_fdo_znn_4_iterations", scenario(&["leg.solver_iterations=4"])),
        ("leg_erl_smc", scenario(&["controller.kind=\"erl_smc\""])),
        ("bench_arbfnn_fdo_znn", scenario(&["plant.kind=\"bench\""])),
    ];
    let mut g = c.benchmark_group("simulation");
    g.sample_size(20);
    for (name, s) in &cases {
        g.throughput(Throughput::Elements(s.steps() as u64));
        g.bench_function(*name, |b| b.iter(|| exoleg::run(s).expect("run")));
    }
    g.finish();
}

criterion_group!(benches, steps);
criterion_main!(benches);
