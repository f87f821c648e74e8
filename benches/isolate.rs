//! The cost per sample of a controller out of process (`cargo bench --bench isolate`): the same
//! 1 s bench run at 1 kHz (1000 samples) with ERL-SMC as an in-process C plugin and as an
//! isolated one (a child process over a socket pair), and the floor of the transport: a
//! READINGS/COMMAND round trip between two threads over a `SOCK_SEQPACKET` pair. Throughput is
//! in samples/s; the isolated run's time minus the in-process one's over 1000 is the overhead
//! per sample the README quotes. Needs `cc` (the plugin is compiled here) and the `exoleg`
//! executable built (`cargo build --release`).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use exoleg::record::NullSink;
use std::io::{Read, Write};
use std::os::unix::net::UnixStream;

fn plugin() -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let lib = dir.path().join("liberl_smc.so");
    let root = env!("CARGO_MANIFEST_DIR");
    let o = std::process::Command::new("cc")
        .args(["-O2", "-fPIC", "-shared", "-ffp-contract=off", "-I", "include", "-o"])
        .arg(&lib)
        .args(["examples/c_controller/erl_smc.c", "-lm"])
        .current_dir(root)
        .output()
        .expect("cc runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (dir, lib)
}

fn isolate(c: &mut Criterion) {
    let (_dir, lib) = plugin();
    let lib_set = format!("controller.plugin.library=\"{}\"", lib.display());
    let mut g = c.benchmark_group("controller_out_of_process");
    g.sample_size(20);
    g.throughput(Throughput::Elements(1000));
    for (name, isolate) in [("in_process_plugin", "false"), ("isolated_plugin", "true")] {
        let iso = format!("controller.plugin.isolate={isolate}");
        let sets = [
            "plant.kind=\"bench\"",
            "controller.kind=\"plugin\"",
            "controller.sample_period_s=0.001",
            "controller.plugin.params={k=100.0, delta=15.0, zeta=10.0}",
            lib_set.as_str(),
            iso.as_str(),
        ];
        let s = exoleg::load(None, &sets).unwrap();
        g.bench_function(name, |b| b.iter(|| exoleg::run(&s.model, &mut NullSink).expect("run")));
    }
    g.bench_function("seqpacket_round_trip_x1000", |b| {
        let (mut a, mut z) = UnixStream::pair().unwrap();
        let echo = std::thread::spawn(move || {
            let mut buf = [0u8; 600];
            while let Ok(n) = z.read(&mut buf) {
                if n == 0 || z.write_all(&buf[..n.min(288)]).is_err() {
                    break;
                }
            }
        });
        let msg = [7u8; 568];
        let mut buf = [0u8; 600];
        b.iter(|| {
            for _ in 0..1000 {
                a.write_all(&msg).unwrap();
                let mut got = 0;
                while got < 288 {
                    got += a.read(&mut buf[got..]).unwrap();
                }
            }
        });
        drop(a);
        echo.join().unwrap();
    });
    g.finish();
}

criterion_group!(benches, isolate);
criterion_main!(benches);
