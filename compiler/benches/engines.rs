//! Key-samples per second of the interpreters on every instrument, and front-end compile
//! time. Run: `cargo bench -p tactus-compiler --bench engines`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::interp::Instance;
use tactus_compiler::lower::Config;
use tactus_runtime::stimulus;

const INSTRUMENTS: [&str; 4] = ["hammond", "harpsichord", "harpsichord_2x8", "grand_piano"];

fn source(name: &str) -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../instruments/{name}.tactus")),
    )
    .unwrap()
}

fn engines(c: &mut Criterion) {
    let mut g = c.benchmark_group("key-samples");
    g.measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_millis(500))
        .sample_size(20);
    for name in INSTRUMENTS {
        let p = tactus_compiler::compile(&source(name), &Config::default())
            .unwrap()
            .program;
        let fp = FixedProgram::new(&p);
        let s = stimulus::builtin("mf-dip", p.sensors[0].range.1, p.sample_rate_hz).unwrap();
        let raw: Vec<i32> = s
            .key
            .iter()
            .map(|&k| FixedInstance::sensor_raw(&fp, 0, Some(k)))
            .collect();
        g.throughput(Throughput::Elements(s.key.len() as u64));
        g.bench_with_input(BenchmarkId::new("interp-f64", name), &s.key, |b, keys| {
            b.iter(|| {
                let mut inst = Instance::new(&p);
                for &k in keys {
                    black_box(inst.step(&[k]).total);
                }
            })
        });
        g.bench_with_input(BenchmarkId::new("interp-fixed", name), &raw, |b, raw| {
            b.iter(|| {
                let mut inst = FixedInstance::new(&fp);
                for &k in raw {
                    black_box(inst.step_raw(&[k]).total);
                }
            })
        });
    }
    g.finish();
}

fn compile_time(c: &mut Criterion) {
    let src = source("grand_piano");
    let mut g = c.benchmark_group("compile");
    g.measurement_time(Duration::from_secs(3)).sample_size(30);
    g.bench_function("grand_piano source→IR", |b| {
        b.iter(|| tactus_compiler::compile(black_box(&src), &Config::default()).unwrap())
    });
    g.bench_function("grand_piano source→fixed plan", |b| {
        b.iter(|| {
            let p = tactus_compiler::compile(black_box(&src), &Config::default())
                .unwrap()
                .program;
            FixedProgram::new(&p)
        })
    });
    g.finish();
}

criterion_group!(benches, engines, compile_time);
criterion_main!(benches);
