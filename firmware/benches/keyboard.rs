//! Whole-keyboard emulation speed: the first quarter second of the built-in demo (the
//! scale's first notes) through the firmware of every board of grand88 (44 planned RP2040
//! boards of two grand-piano keys, every key every sample, unplayed keys at rest, the
//! quiescent-key guard on) with `tactus_firmware::perform::play_boards`, the boards as
//! rayon tasks on the machine's cores — `tactus play`'s default run without its compile and
//! plan. Criterion's "elements" are key-samples; real time is 88 × 44 100 = 3 880 800
//! key-samples per second, so the real-time factor is the throughput divided by that.
//! Two variants in the same run: the block engine (`tactus play`'s default) and, as the
//! baseline, the interpreter (`--emu interp`). Compiled code is kept for the whole process
//! (`tactus_emulator`'s code store), so the block engine's iterations after the first do
//! not compile: the figure is the steady state of a long performance.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::collections::BTreeMap;
use std::path::Path;
use tactus_firmware::image::compile_layout;
use tactus_firmware::perform::{play_boards, Motion, PerformOptions};
use tactus_firmware::play::TraceWindow;
use tactus_runtime::keyboard::{read_board, read_layout};
use tactus_runtime::limiter::LimiterConfig;
use tactus_runtime::performance::{demo, key_tracks};
use tactus_runtime::player::FingerConfig;

/// Music per criterion iteration, s.
const SECONDS: f64 = 0.25;

fn bench(c: &mut Criterion) {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    let (_, keys) = read_layout(&root.join("instruments/layouts/grand88.toml")).unwrap();
    let source = |name: &str| {
        std::fs::read_to_string(root.join(format!("instruments/{name}.tactus")))
            .map_err(|e| e.to_string())
    };
    let (programs, key_programs) = compile_layout(&keys, &source, 44_100.0).unwrap();
    let board = read_board(&root.join("boards/rp2040.toml")).unwrap();
    let mut perf = demo();
    perf.notes.retain(|n| n.on_s < SECONDS);
    let dip = programs[0].fixed.program.sensors[0].range.1;
    let motions: Vec<(u8, Motion)> = key_tracks(&perf, dip)
        .into_iter()
        .map(|t| (t.key, Motion::Track(t)))
        .collect();
    let motions: BTreeMap<u8, &Motion> = motions.iter().map(|(k, m)| (*k, m)).collect();
    let midi: Vec<u8> = keys.iter().map(|k| k.key).collect();
    let end = (SECONDS * 44_100.0) as usize;
    let mut group = c.benchmark_group("whole_keyboard");
    group.sample_size(10);
    group.warm_up_time(std::time::Duration::from_secs(1));
    group.measurement_time(std::time::Duration::from_secs(5));
    group.throughput(Throughput::Elements((end * midi.len()) as u64));
    for engine in [
        tactus_emulator::Engine::Block,
        tactus_emulator::Engine::Interp,
    ] {
        let opts = PerformOptions {
            end,
            fs: 44_100.0,
            finger: FingerConfig::default(),
            trace: TraceWindow::default(),
            boards: None,
            limiter: LimiterConfig::default(),
            engine,
            quiescent_guard: true,
        };
        let name = format!("grand88_demo_{engine:?}");
        group.bench_function(&name, |b| {
            b.iter(|| {
                play_boards(
                    &programs,
                    &midi,
                    &key_programs,
                    &board,
                    &motions,
                    &opts,
                    &|_| {},
                )
                .unwrap()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
