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
//!
//! With `KEYBOARD_BENCH_ONCE=block` (or `interp`) in the environment the bench instead runs
//! that engine once and prints a summary that must not change between emulator versions
//! (per board the handler cycles of each core, the strikes), for `valgrind
//! --tool=callgrind --collect-atstart=no --toggle-collect='*play_boards*'`, whose
//! instruction counts do not depend on the machine's load (`RAYON_NUM_THREADS=1`).

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

/// Everything a run needs: the programs, the keys, the board, the key motions, the samples.
struct Setup {
    programs: Vec<tactus_firmware::image::Program>,
    key_programs: Vec<usize>,
    board: tactus_runtime::keyboard::Board,
    motions: Vec<(u8, Motion)>,
    midi: Vec<u8>,
    end: usize,
}

fn setup() -> Setup {
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
    let midi: Vec<u8> = keys.iter().map(|k| k.key).collect();
    let end = (SECONDS * 44_100.0) as usize;
    Setup {
        programs,
        key_programs,
        board,
        motions,
        midi,
        end,
    }
}

fn options(end: usize, engine: tactus_emulator::Engine) -> PerformOptions {
    PerformOptions {
        end,
        fs: 44_100.0,
        finger: FingerConfig::default(),
        trace: TraceWindow::default(),
        boards: None,
        limiter: LimiterConfig::default(),
        engine,
        quiescent_guard: true,
    }
}

/// `KEYBOARD_BENCH_ONCE=engine`: one run, with a summary.
fn once(engine: tactus_emulator::Engine) {
    let s = setup();
    let motions: BTreeMap<u8, &Motion> = s.motions.iter().map(|(k, m)| (*k, m)).collect();
    let run = play_boards(
        &s.programs,
        &s.midi,
        &s.key_programs,
        &s.board,
        &motions,
        &options(s.end, engine),
        &|_| {},
    )
    .unwrap();
    let mut strikes = 0;
    for (i, b) in run.boards.iter().enumerate() {
        strikes += b.strikes.len();
        println!(
            "board {i}: keys {:?} handler cycles {:?} max {:?} misses {:?} strikes {}",
            b.keys,
            b.total,
            b.max,
            b.misses,
            b.strikes.len()
        );
    }
    println!(
        "{engine:?}: {} samples, {} boards, {strikes} strikes",
        s.end,
        run.boards.len()
    );
}

fn bench(c: &mut Criterion) {
    let s = setup();
    let (programs, key_programs, board, midi, end) =
        (&s.programs, &s.key_programs, &s.board, &s.midi, s.end);
    let motions: BTreeMap<u8, &Motion> = s.motions.iter().map(|(k, m)| (*k, m)).collect();
    let mut group = c.benchmark_group("whole_keyboard");
    group.sample_size(10);
    group.warm_up_time(std::time::Duration::from_secs(1));
    group.measurement_time(std::time::Duration::from_secs(5));
    group.throughput(Throughput::Elements((end * midi.len()) as u64));
    for engine in [
        tactus_emulator::Engine::Block,
        tactus_emulator::Engine::Interp,
    ] {
        let opts = options(end, engine);
        let name = format!("grand88_demo_{engine:?}");
        group.bench_function(&name, |b| {
            b.iter(|| {
                play_boards(
                    programs,
                    midi,
                    key_programs,
                    board,
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

fn main_or_once(c: &mut Criterion) {
    match std::env::var("KEYBOARD_BENCH_ONCE").as_deref() {
        Ok("block") => once(tactus_emulator::Engine::Block),
        Ok("interp") => once(tactus_emulator::Engine::Interp),
        Ok(other) => eprintln!("KEYBOARD_BENCH_ONCE={other}: expected `block` or `interp`"),
        Err(_) => bench(c),
    }
}

criterion_group!(benches, main_or_once);
criterion_main!(benches);
