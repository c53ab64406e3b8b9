//! Samples per second of the grand piano over the `mf-dip` stimulus: the reference
//! interpreter and the JIT in the same run, so their ratio is meaningful.
//!
//! `CARGO_TARGET_DIR=/work/target-jit cargo bench -p tactus-jit --bench jit`

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use std::hint::black_box;
use std::time::Duration;
use tactus_compiler::interp::Instance;
use tactus_compiler::lower::Config;
use tactus_jit::{JitInstance, JitProgram};

fn piano(c: &mut Criterion) {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../instruments/grand_piano.tactus"
    );
    let src = std::fs::read_to_string(path).expect("grand_piano.tactus");
    let program = tactus_compiler::compile(&src, &Config::default())
        .expect("compiles")
        .program;
    let dip = program.sensors[0].range.1;
    let stim = tactus_runtime::stimulus::builtin("mf-dip", dip, 44_100.0).expect("stimulus");
    let jit = JitProgram::compile(&program).expect("jit");

    let mut g = c.benchmark_group("grand_piano_mf_dip");
    g.throughput(Throughput::Elements(stim.key.len() as u64));
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    g.bench_function("interp", |b| {
        b.iter_batched_ref(
            || Instance::new(&program),
            |inst| {
                for &k in &stim.key {
                    black_box(inst.step(&[k]).total);
                }
            },
            BatchSize::LargeInput,
        )
    });
    g.bench_function("jit", |b| {
        b.iter_batched_ref(
            || JitInstance::new(&jit),
            |inst| {
                for &k in &stim.key {
                    black_box(inst.step(&[k]).total);
                }
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

criterion_group!(benches, piano);
criterion_main!(benches);
