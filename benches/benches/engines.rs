//! Throughput of both engines on the papers' trees, in samples per second, and the
//! JIT's compile time.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use timbre_benches::{bell, compile, interpreter, swarm, CONFIG};
use timbre_jit::Jit;

const SAMPLES: usize = 48_000 / 10;

fn render(c: &mut Criterion) {
    let mut group = c.benchmark_group("render");
    group.throughput(Throughput::Elements(SAMPLES as u64));
    group.sample_size(10);
    let mut jit = Jit::new().unwrap();
    for workload in [bell(100), bell(500), swarm(50)] {
        let program = compile(&workload);
        let mut out = vec![0.0; SAMPLES];
        let mut voice = interpreter(&program);
        group.bench_function(format!("{}/interp", workload.name), |b| {
            b.iter(|| voice.render(&mut out))
        });
        let mut voice = jit
            .voice(&program.graph, program.root.unwrap(), CONFIG)
            .unwrap();
        group.bench_function(format!("{}/jit", workload.name), |b| {
            b.iter(|| voice.render(&mut out))
        });
    }
    group.finish();
}

fn compile_time(c: &mut Criterion) {
    let mut group = c.benchmark_group("compile");
    group.sample_size(10);
    for workload in [bell(100), swarm(50)] {
        let program = compile(&workload);
        let steps = interpreter(&program);
        group.bench_function(workload.name, |b| {
            b.iter(|| {
                // A fresh compiler each time, so nothing comes from the cache.
                Jit::new()
                    .unwrap()
                    .compile(steps.steps(), CONFIG.block_size)
                    .unwrap()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, render, compile_time);
criterion_main!(benches);
