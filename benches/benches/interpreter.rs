//! Interpreter throughput on the papers' trees, in samples per second.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use timbre_benches::{bell, compile, interpreter, swarm};

const SAMPLES: usize = 48_000 / 10;

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("interpreter");
    group.throughput(Throughput::Elements(SAMPLES as u64));
    group.sample_size(10);
    for workload in [bell(100), bell(500), swarm(50)] {
        let program = compile(&workload);
        let mut voice = interpreter(&program);
        let mut out = vec![0.0; SAMPLES];
        group.bench_function(workload.name, |b| b.iter(|| voice.render(&mut out)));
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
