//! The fixed interpreter as the planner's simulated search runs it: key-samples per second
//! on the piano (constant params) and on grand88's shared program (88 keys, hammer mass
//! graded 11 g → 3.5 g, one program with run-time params, run with the middle key's param
//! block), over every built-in stimulus back to back; and one contract comparison
//! (`contract::compare`, the search's unit of work) on the same samples.
//! Run: `TACTUS_CACHE_DIR=<dir> cargo bench -p tactus-compiler --bench fixed_interp`
//! (the plans come from the cache after the first run).

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_compiler::fixed::{contract, report, FixedProgram};
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config;
use tactus_runtime::stimulus;

fn piano_source() -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments/grand_piano.tactus"),
    )
    .unwrap()
}

/// grand88's shared program (as `instruments/layouts/grand88.toml` grades it: `M_h` linear
/// from 11 g on the first key to 3.5 g on the last) and the middle key's SI param values.
fn grand88() -> (Program, Vec<f64>) {
    let src = piano_source();
    let irs: Vec<Program> = (0..88)
        .map(|k| {
            let m = 11.0 + (3.5 - 11.0) * f64::from(k) / 87.0;
            let config = Config {
                overrides: vec![("M_h".into(), format!("{m} g"))],
                ..Config::default()
            };
            tactus_compiler::compile(&src, &config).unwrap().program
        })
        .collect();
    let shared = tactus_compiler::share::share(&irs).unwrap();
    let values = shared.values()[44].clone();
    (shared.program, values)
}

/// Every built-in stimulus of `p`'s key back to back, as raw sensor words of `fp`.
fn stimuli(p: &Program, fp: &FixedProgram) -> Vec<i32> {
    stimulus::builtin_names()
        .iter()
        .filter_map(|(name, _)| {
            stimulus::builtin(name, p.sensors[0].range.1, p.sample_rate_hz).ok()
        })
        .flat_map(|s| s.key)
        .map(|k| FixedInstance::sensor_raw(fp, 0, Some(k)))
        .collect()
}

fn fixed_interp(c: &mut Criterion) {
    let mut g = c.benchmark_group("fixed_interp");
    g.measurement_time(Duration::from_secs(4))
        .warm_up_time(Duration::from_millis(500))
        .sample_size(20);
    let piano = tactus_compiler::compile(&piano_source(), &Config::default())
        .unwrap()
        .program;
    let (shared, values) = grand88();
    for (name, p, params) in [
        ("grand_piano", &piano, Vec::new()),
        ("grand88", &shared, values),
    ] {
        let fp = FixedProgram::new(p);
        let raw = stimuli(p, &fp);
        let block = if params.is_empty() {
            fp.nominal_param_block()
        } else {
            fp.param_block(&params).unwrap()
        };
        g.throughput(Throughput::Elements(raw.len() as u64));
        g.bench_with_input(BenchmarkId::new("step_raw", name), &raw, |b, raw| {
            b.iter(|| {
                let mut inst = FixedInstance::with_params(&fp, block.clone());
                for &k in raw {
                    black_box(inst.step_raw(&[k]).total);
                }
            })
        });
        let run = contract::reference_raw(p, &fp, &raw, &params).unwrap();
        let lsb = report::analyse(&fp).dac_lsb_n();
        g.bench_with_input(BenchmarkId::new("compare", name), &run, |b, run| {
            b.iter(|| black_box(contract::compare(p, &fp, run, lsb, &p.contract, false).unwrap()))
        });
    }
    g.finish();
}

criterion_group!(benches, fixed_interp);
criterion_main!(benches);
