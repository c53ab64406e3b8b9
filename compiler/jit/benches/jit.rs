//! Key-samples per second of the grand piano over the `mf-dip` stimulus, every engine in the
//! same run so that their ratios are meaningful: the f64 reference interpreter, the fixed
//! interpreter, the f64 JIT, the fixed JIT one sample per call (`step_raw`, what the tests
//! compare) and the fixed JIT one block per call (`run_block`: the whole stimulus in one
//! native call, histories in native code). The fixed engines read raw sensor words converted
//! once up front, as firmware reads its ADC. Plus the time from source text to JIT-ready
//! code, for both JITs.
//!
//! `CARGO_TARGET_DIR=/work/target-jit cargo bench -p tactus-jit --bench jit`

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use std::hint::black_box;
use std::time::Duration;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::interp::Instance;
use tactus_compiler::lower::Config;
use tactus_jit::{FixedJitInstance, FixedJitProgram, JitInstance, JitProgram};

fn source() -> String {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../instruments/grand_piano.tactus"
    );
    std::fs::read_to_string(path).expect("grand_piano.tactus")
}

fn piano(c: &mut Criterion) {
    let src = source();
    let program = tactus_compiler::compile(&src, &Config::default())
        .expect("compiles")
        .program;
    let dip = program.sensors[0].range.1;
    let stim = tactus_runtime::stimulus::builtin("mf-dip", dip, 44_100.0).expect("stimulus");
    let jit = JitProgram::compile(&program).expect("jit");
    let fp = FixedProgram::new(&program);
    let fjit = FixedJitProgram::compile(&fp).expect("fixed jit");
    let raw: Vec<i32> = stim
        .key
        .iter()
        .map(|&k| FixedInstance::sensor_raw(&fp, 0, Some(k)))
        .collect();

    let mut g = c.benchmark_group("grand_piano_mf_dip");
    g.throughput(Throughput::Elements(stim.key.len() as u64));
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    g.bench_function("interp_f64", |b| {
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
    g.bench_function("interp_fixed", |b| {
        b.iter_batched_ref(
            || FixedInstance::new(&fp),
            |inst| {
                for &k in &raw {
                    black_box(inst.step_raw(&[k]).total);
                }
            },
            BatchSize::LargeInput,
        )
    });
    g.bench_function("jit_f64", |b| {
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
    g.bench_function("jit_fixed_step", |b| {
        b.iter_batched_ref(
            || FixedJitInstance::new(&fjit),
            |inst| {
                for &k in &raw {
                    black_box(inst.step_raw(&[k]).total);
                }
            },
            BatchSize::LargeInput,
        )
    });
    g.bench_function("jit_fixed_block", |b| {
        b.iter_batched_ref(
            || (FixedJitInstance::new(&fjit), vec![0i32; raw.len()]),
            |(inst, totals)| {
                black_box(inst.run_block(&raw, totals));
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

fn compile_time(c: &mut Criterion) {
    let src = source();
    let mut g = c.benchmark_group("grand_piano_compile");
    g.sample_size(20)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(3));
    g.bench_function("source_to_jit_f64", |b| {
        b.iter(|| {
            let program = tactus_compiler::compile(black_box(&src), &Config::default())
                .expect("compiles")
                .program;
            black_box(JitProgram::compile(&program).expect("jit"))
        })
    });
    g.bench_function("source_to_jit_fixed", |b| {
        b.iter(|| {
            let program = tactus_compiler::compile(black_box(&src), &Config::default())
                .expect("compiles")
                .program;
            let fp = FixedProgram::new(&program);
            black_box(FixedJitProgram::compile(&fp).expect("fixed jit"))
        })
    });
    g.finish();
}

criterion_group!(benches, piano, compile_time);
criterion_main!(benches);
