//! Whole-keyboard emulation speed in emulated cycles per CPU-second, beside the emulator's
//! one-core loop rate measured in the same run (issue 37's machine-independent ratio).
//!
//! The workload is `tactus play`'s default run without its compile, plan and boot: the
//! first [`SECONDS`] of the built-in demo (the scale's first notes) through the firmware of
//! every board of grand88 (planned as `tactus budget` plans them; every key every sample,
//! unplayed keys at rest, the quiescent-key guard on), each board a [`BoardEngine`] stepped
//! by the one play loop (`run_keys`). The boards are built and booted outside the timed
//! part (criterion's `iter_batched`), and run one after the other on the bench's thread,
//! so wall time is CPU time. Criterion's "elements" are the emulated cycles of the sample
//! interrupts (every core's handler cycles, exception entry to return: the cycles the
//! cores are not asleep), so the throughput is emulated cycles per CPU-second. The
//! baseline in the same group is the emulator bench's speed loop on one core
//! (`emulator/benches/common/mod.rs`, block engine: SRAM load and store, MULS, a taken
//! branch, 10 cycles per iteration), elements = its emulated cycles. The keyboard runs on
//! the block engine as `tactus play` runs it (key updates and each core's keys part of the
//! handler memoized: `tactus_emulator::Board::memoize`), on the block engine with the
//! memos off, and on the interpreter (`--emu interp`, the lock-step reference). Compiled code is kept for the whole process
//! (`tactus_emulator`'s code store), so iterations after the first do not compile: the
//! figure is the steady state of a long performance.
//!
//! `grand88_demo_Block_rp2040_io` runs the same music on the board with converters
//! (`boards/rp2040_io.toml`, planned for it): every sample through the emulated ADCs,
//! DACs, PIOs and DMA (`tactus_emulator::io`); its time per iteration over
//! `grand88_demo_Block`'s is what the converter path costs (issue 40 asks the main job's
//! real-time factor to drop by at most 10 %).
//!
//! With `KEYBOARD_BENCH_ONCE=block` (or `interp`, or `block_io` for the board with
//! converters) in the environment the bench instead runs that engine once and prints a
//! summary that must not change between emulator versions (per board the handler cycles of
//! each core, the strikes), for `valgrind
//! --tool=callgrind --collect-atstart=no --toggle-collect='*run_keys*'`, whose
//! instruction counts do not depend on the machine's load. That one pass includes the
//! JIT's compiles (`Jit::miss`); `block_steady` (or `block_io_steady`) first plays the
//! music once on other boards, then measures a second pass on fresh boots
//! (`--toggle-collect='*steady_pass*'`): the steady state criterion times.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use std::collections::BTreeMap;
use std::path::Path;
use tactus_emulator::Engine;
use tactus_firmware::boards::{self, PlanKey, ProgramCosts};
use tactus_firmware::image::{compile_layout, Program};
use tactus_host::play::emulated::{BoardEngine, BoardRun, Motion};
use tactus_host::play::run::{run_keys, Drive, LoopConfig};
use tactus_host::play::TraceWindow;
use tactus_runtime::keyboard::{read_layout, BoardSpec};
use tactus_runtime::limiter::LimiterConfig;
use tactus_runtime::performance::{demo, key_tracks};
use tactus_runtime::player::FingerConfig;

#[path = "../../emulator/benches/common/mod.rs"]
mod common;

/// Music per criterion iteration, s.
const SECONDS: f64 = 0.25;
/// Sample rate, Hz.
const FS: f64 = 44_100.0;
/// Cycles per iteration of the one-core loop.
const LOOP_CYCLES: u64 = 20_000_000;

/// Everything a run needs: the programs, the planned boards (their keys), the board kind,
/// the key motions, the samples.
struct Setup {
    programs: Vec<Program>,
    costs: ProgramCosts,
    boards: Vec<Vec<PlanKey>>,
    board: BoardSpec,
    motions: BTreeMap<u8, Motion>,
    end: usize,
}

/// The run on the board kind `boards/{board}.toml` (`rp2040`, or `rp2040_io` for the
/// board with converters, planned for it as `tactus budget --board rp2040_io` plans).
fn setup(board: &str) -> Setup {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    let (_, keys) = read_layout(&root.join("instruments/layouts/grand88.toml")).unwrap();
    let source = |name: &str| {
        std::fs::read_to_string(root.join(format!("instruments/{name}.tactus")))
            .map_err(|e| e.to_string())
    };
    let (programs, key_programs) = compile_layout(&keys, &source, FS).unwrap();
    let text = std::fs::read_to_string(root.join(format!("boards/{board}.toml"))).unwrap();
    let board = tactus_firmware::boards::read_board(&text, board).unwrap();
    let mut perf = demo();
    perf.notes.retain(|n| n.on_s < SECONDS);
    let dip = programs[0].fixed.program.sensors[0].range.1;
    let motions = key_tracks(&perf, dip)
        .into_iter()
        .map(|t| (t.key, Motion::Track(t)))
        .collect();
    let lim = LimiterConfig::for_board(&board);
    let costs = ProgramCosts::new(&programs, &board, &lim).unwrap();
    let keys: Vec<PlanKey> = keys
        .iter()
        .zip(&key_programs)
        .map(|(k, &program)| PlanKey {
            key: k.key,
            program,
        })
        .collect();
    let planned = boards::plan(&programs, &costs, &keys, &board, &lim, &mut |_, _| {})
        .unwrap()
        .boards;
    let boards = planned
        .iter()
        .map(|b| {
            keys.iter()
                .filter(|k| b.keys.contains(&k.key))
                .copied()
                .collect()
        })
        .collect();
    Setup {
        programs,
        costs,
        boards,
        board,
        motions,
        end: (SECONDS * FS) as usize,
    }
}

/// Every board built and booted on `engine` (`memos`: with the emulator's memoized calls,
/// as `tactus play` runs), with the drives of its keys.
fn boot<'s>(s: &'s Setup, engine: Engine, memos: bool) -> Vec<(BoardEngine<'s>, Vec<Drive<'s>>)> {
    let lim = LimiterConfig::for_board(&s.board);
    s.boards
        .iter()
        .map(|keys| {
            let e =
                BoardEngine::new(&s.programs, &s.costs, keys, &s.board, &lim, engine, 1).unwrap();
            let e = if memos { e } else { e.without_memos() };
            let drives = keys
                .iter()
                .map(|k| Drive {
                    key: k.key,
                    motion: s.motions.get(&k.key),
                    dip_m: s.programs[k.program].fixed.program.sensors[0].range.1,
                })
                .collect();
            (e, drives)
        })
        .collect()
}

/// Plays the demo through every booted board, one after the other; each board's report
/// and its strikes.
fn play(s: &Setup, boards: Vec<(BoardEngine, Vec<Drive>)>) -> Vec<(BoardRun, usize)> {
    let trace = TraceWindow::default();
    let config = LoopConfig {
        clock: tactus_host::play::Timeline::at_zero(FS),
        finger: FingerConfig::default(),
        trace: &trace,
        stop_at_strike_after_s: None,
    };
    boards
        .into_iter()
        .map(|(mut e, drives)| {
            let run = run_keys(&mut e, &drives, 0..s.end, &config, &|_| {}).unwrap();
            (e.finish().unwrap(), run.strikes.len())
        })
        .collect()
}

/// Emulated cycles of every core's sample interrupts in a run.
fn handler_cycles(runs: &[(BoardRun, usize)]) -> u64 {
    runs.iter().map(|(r, _)| r.total.iter().sum::<u64>()).sum()
}

/// The measured pass of `KEYBOARD_BENCH_ONCE=block_steady` (a function of its own for
/// callgrind's `--toggle-collect='*steady_pass*'`).
#[inline(never)]
fn steady_pass(s: &Setup, boards: Vec<(BoardEngine, Vec<Drive>)>) -> Vec<(BoardRun, usize)> {
    play(s, boards)
}

/// `KEYBOARD_BENCH_ONCE=engine`: one run on `board`, with a summary; with `steady`, after a
/// first run on other boards that fills the process's code store, as in the criterion
/// iterations after the first (the second run is [`steady_pass`]).
fn once(engine: Engine, board: &str, steady: bool) {
    let s = setup(board);
    if steady {
        play(&s, boot(&s, engine, true));
    }
    let runs = steady_pass(&s, boot(&s, engine, true));
    let mut strikes = 0;
    for (i, (b, n)) in runs.iter().enumerate() {
        strikes += n;
        println!(
            "board {i}: keys {:?} handler cycles {:?} max {:?} misses {:?} strikes {n}",
            b.keys, b.total, b.max, b.misses
        );
        eprintln!("board {i}: {:?}", b.memo);
    }
    println!(
        "{engine:?}: {} samples, {} boards, {strikes} strikes, {} handler cycles",
        s.end,
        runs.len(),
        handler_cycles(&runs)
    );
}

fn bench(c: &mut Criterion) {
    let s = setup("rp2040");
    let cycles = handler_cycles(&play(&s, boot(&s, Engine::Block, true)));
    let io = setup("rp2040_io");
    let io_cycles = handler_cycles(&play(&io, boot(&io, Engine::Block, true)));
    let mut group = c.benchmark_group("cycles_per_cpu_second");
    group.sample_size(10);
    group.warm_up_time(std::time::Duration::from_secs(1));
    group.measurement_time(std::time::Duration::from_secs(5));
    group.throughput(Throughput::Elements(LOOP_CYCLES));
    let mut b = common::speed_loop(Engine::Block, 1);
    group.bench_function("loop_1_core_Block", |bench| {
        bench.iter(|| b.run_for(LOOP_CYCLES))
    });
    group.throughput(Throughput::Elements(cycles));
    for (engine, memos, name) in [
        (Engine::Block, true, "Block"),
        (Engine::Block, false, "Block_unmemoized"),
        (Engine::Interp, true, "Interp"),
    ] {
        group.bench_function(format!("grand88_demo_{name}"), |bench| {
            bench.iter_batched(
                || boot(&s, engine, memos),
                |b| play(&s, b),
                BatchSize::PerIteration,
            )
        });
    }
    // The board with converters (issue 40): the same music through the emulated ADCs,
    // DACs, PIOs and DMA; its time per iteration over `grand88_demo_Block`'s is what the
    // converter path costs the emulator.
    group.throughput(Throughput::Elements(io_cycles));
    group.bench_function("grand88_demo_Block_rp2040_io", |bench| {
        bench.iter_batched(
            || boot(&io, Engine::Block, true),
            |b| play(&io, b),
            BatchSize::PerIteration,
        )
    });
    group.finish();
}

fn main_or_once(c: &mut Criterion) {
    match std::env::var("KEYBOARD_BENCH_ONCE").as_deref() {
        Ok("block") => once(Engine::Block, "rp2040", false),
        Ok("block_steady") => once(Engine::Block, "rp2040", true),
        Ok("interp") => once(Engine::Interp, "rp2040", false),
        Ok("block_io") => once(Engine::Block, "rp2040_io", false),
        Ok("block_io_steady") => once(Engine::Block, "rp2040_io", true),
        Ok(other) => eprintln!(
            "KEYBOARD_BENCH_ONCE={other}: expected `block`, `block_steady`, `interp`, \
             `block_io` or `block_io_steady`"
        ),
        Err(_) => bench(c),
    }
}

criterion_group!(benches, main_or_once);
criterion_main!(benches);
