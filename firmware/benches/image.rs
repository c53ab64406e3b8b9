//! Key-samples per host second of the firmware image on the emulated board
//! (`tactus_firmware::image`): the demo's 11 harpsichord keys of `tactus play --engine emu
//! --instrument harpsichord --board rp2040_200mhz` (MIDI keys 60–70, keys to cores by LPT),
//! each fed a built-in stimulus (`tactus_runtime::stimulus`, the built-ins in turn), every
//! key every sample through `ImageRun::step`. Criterion's "elements" are key-samples; a
//! real-time run of these keys needs 11 × 44 100 = 485 100 key-samples per second.
//!
//! With `IMAGE_BENCH_ONCE=N` in the environment the bench instead runs N samples once and
//! prints the image's cycles, stalls and misses (for `valgrind --tool=callgrind`, whose
//! instruction counts do not depend on the machine's load).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::path::Path;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_firmware::image::{assign_cores, compile_layout, key_specs, FirmwareImage};
use tactus_runtime::keyboard::KeyAssignment;
use tactus_runtime::limiter::LimiterConfig;
use tactus_runtime::stimulus;

/// Samples per criterion iteration (0.1 s at 44.1 kHz).
const SAMPLES: usize = 4410;

/// The image and one sensor word per key and sample (`len` samples).
fn image(len: usize) -> (FirmwareImage, Vec<Vec<i32>>) {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    let keys: Vec<KeyAssignment> = (60u8..71)
        .map(|key| KeyAssignment {
            key,
            instrument: "harpsichord".to_string(),
            params: vec![],
        })
        .collect();
    let source = |name: &str| {
        std::fs::read_to_string(root.join(format!("instruments/{name}.tactus")))
            .map_err(|e| e.to_string())
    };
    let (programs, key_programs) = compile_layout(&keys, &source, 44_100.0).unwrap();
    let text = std::fs::read_to_string(root.join("boards/rp2040_200mhz.toml")).unwrap();
    let board = tactus_firmware::boards::read_board(&text, "rp2040_200mhz").unwrap();
    let cores = assign_cores(&programs, &key_programs, board.cores as usize).unwrap();
    let specs = key_specs(&keys, &key_programs, &cores);
    let image = FirmwareImage::build(&programs, &specs, &board, &LimiterConfig::default()).unwrap();
    let names = stimulus::builtin_names();
    let sensors = specs
        .iter()
        .enumerate()
        .map(|(i, k)| {
            let fp = &programs[k.program].fixed;
            let (name, _) = names[i % names.len()];
            let s = stimulus::builtin(name, fp.program.sensors[0].range.1, 44_100.0).unwrap();
            (0..len)
                .map(|n| FixedInstance::sensor_raw(fp, 0, Some(s.key[n % s.key.len()])))
                .collect()
        })
        .collect();
    (image, sensors)
}

fn bench(c: &mut Criterion) {
    let (image, sensors) = image(SAMPLES);
    let keys = sensors.len();
    let mut run = image.run().unwrap();
    let mut words = vec![0; keys];
    let mut group = c.benchmark_group("firmware_image");
    group.throughput(Throughput::Elements((SAMPLES * keys) as u64));
    group.bench_function(format!("{keys}_harpsichord_keys_200mhz"), |b| {
        b.iter(|| {
            for n in 0..SAMPLES {
                for (w, s) in words.iter_mut().zip(&sensors) {
                    *w = s[n];
                }
                run.step(&words).unwrap();
            }
        })
    });
    group.finish();
}

/// `IMAGE_BENCH_ONCE=N`: N samples once, with a summary that must not change between
/// emulator versions.
fn once(samples: usize) {
    let (image, sensors) = image(samples);
    let mut run = image.run().unwrap();
    let mut words = vec![0; sensors.len()];
    let (mut cycles, mut stalls, mut events) = ([0u64; 2], [0u64; 2], 0);
    let mut dac_sum = 0i64;
    for n in 0..samples {
        for (w, s) in words.iter_mut().zip(&sensors) {
            *w = s[n];
        }
        let out = run.step(&words).unwrap();
        for c in 0..out.core_cycles.len() {
            cycles[c] += out.core_cycles[c];
            stalls[c] += out.stalls[c];
        }
        events += out.events.len();
        dac_sum += out.dac.iter().map(|&d| d as i64).sum::<i64>();
    }
    let out = run.step(&words).unwrap();
    println!(
        "{samples} samples of {} keys: handler cycles {cycles:?}, stalls {stalls:?}, misses {:?}, events {events}, DAC sum {dac_sum}",
        words.len(),
        out.misses
    );
}

fn main_or_once(c: &mut Criterion) {
    match std::env::var("IMAGE_BENCH_ONCE")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        Some(n) => once(n),
        None => bench(c),
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10).measurement_time(std::time::Duration::from_secs(5)).warm_up_time(std::time::Duration::from_secs(1));
    targets = main_or_once
}
criterion_main!(benches);
