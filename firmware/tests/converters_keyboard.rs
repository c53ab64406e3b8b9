//! Every board of grand88 and of the split layout on the reference board with converters
//! (`boards/rp2040_io.toml`), as `tactus build --board rp2040_io` makes it, against the same
//! keys' image without converters (issue 40's "every board plays the corpus through the
//! converters"): the key positions go in as ADC codes, and every sample the forces, the
//! limiter's DAC codes, the events (the strikes among them) and every key's out words equal
//! those of the image without converters fed the same positions quantised to the ADC's
//! codes one sample later (a burst sampled in one period is read at the next tick:
//! `converters.rs`); no deadline is missed; each core's measured handler stays within its
//! static bound (which counts the DMA's accesses); no frame breaks its part's data-sheet
//! timing.
//!
//! In CI: [`SHORT`] samples on the first board of each layout. `cargo test --release -p
//! tactus-firmware --test converters_keyboard -- --ignored` runs a whole emulated second
//! of the budget corpus on every board (about half a minute on two cores), and 0.05 s of
//! it on the first board of each layout against the interpreter's lock-step run (the
//! reference for the windows in which the cores run ahead of the I/O).

use tactus_compiler::fixed::interp::FixedInstance;
use tactus_emulator::{Engine, IoWindows};
use tactus_firmware::flash::{BoardFirmware, Load};
use tactus_firmware::image::FirmwareImage;
use tactus_runtime::converters::AdcScale;
use tactus_runtime::limiter::LimiterConfig;

#[path = "common/layouts.rs"]
mod layouts;
use layouts::{corpus_words, firmware, on_host_threads};

/// Samples per board in CI.
const SHORT: usize = 150;

const LAYOUTS: [&str; 2] = [
    "instruments/layouts/grand88.toml",
    "instruments/layouts/split_harpsichord_piano.toml",
];

/// What one board did: strikes (events) and samples run.
struct Played {
    events: usize,
    samples: usize,
    /// The windows the cores ran ahead of the I/O in, kept and undone.
    windows: IoWindows,
}

/// Each key of board `fw`'s corpus words (`samples` of them) and the scale of its ADC
/// channel.
fn streams(fw: &BoardFirmware, samples: usize) -> Vec<(Vec<i32>, AdcScale)> {
    let with = &fw.image;
    let plan = with
        .io()
        .unwrap_or_else(|| panic!("board {}: rp2040_io names converters", fw.index));
    let keys = with.keys();
    // Each key's corpus words and the scale of its ADC channel.
    keys.iter()
        .enumerate()
        .map(|(i, k)| {
            let p = &with.programs()[k.program];
            assert_eq!(p.fixed.program.sensors.len(), 1, "one sensor per key");
            let (adcs, _) = with.channels(i).unwrap();
            let scale = plan.cores[k.core].scales[adcs[0] as usize];
            let rest = FixedInstance::sensor_raw(&p.fixed, 0, Some(0.0));
            let words = corpus_words(p, fw.keys[0] as usize + i, samples);
            // Stretches of the corpus and of rest, as `keyboard_exact.rs`.
            let words = words
                .iter()
                .enumerate()
                .map(|(n, &w)| if (n / 300) % 2 == 0 { w } else { rest })
                .collect();
            (words, scale)
        })
        .collect()
}

/// Board `fw` (built with converters) against its keys without converters, `samples`
/// samples of the budget corpus.
fn play(fw: &BoardFirmware, samples: usize) -> Played {
    let with = &fw.image;
    let plain = layouts::shipped_board("rp2040");
    let limiter = LimiterConfig::for_board(&plain);
    let keys = with.keys();
    let without = FirmwareImage::build(with.programs(), &keys, &plain, &limiter)
        .unwrap_or_else(|e| panic!("board {}: the keys without converters: {e}", fw.index));
    let streams = streams(fw, samples);
    let mut a = with.run().unwrap();
    let mut b = without.run().unwrap();
    let mut events = 0;
    for n in 0..samples {
        let now: Vec<i32> = streams.iter().map(|(w, _)| w[n]).collect();
        let seen: Vec<i32> = streams
            .iter()
            .map(|(w, s)| match n {
                0 => s.word(0),
                _ => s.quantise(w[n - 1]),
            })
            .collect();
        let ga = a.step(&now).unwrap().clone();
        let gb = b.step(&seen).unwrap();
        let at = |what: &str| format!("board {} sample {n}: {what}", fw.index);
        assert_eq!(ga.force, gb.force, "{}", at("the updates' forces"));
        assert_eq!(ga.dac, gb.dac, "{}", at("the limiter's codes"));
        assert_eq!(ga.events, gb.events, "{}", at("events"));
        assert!(
            ga.misses.iter().all(|&m| m == 0),
            "{}",
            at("a missed deadline")
        );
        for c in 0..ga.core_cycles.len() {
            let bound = with.wcet(c).unwrap().bound();
            assert_eq!(ga.handler_runs[c], 1, "{}", at("one handler run per core"));
            assert!(
                ga.core_cycles[c] <= bound,
                "{}: core {c} measured {} over the static {bound}",
                at("WCET"),
                ga.core_cycles[c]
            );
        }
        events += ga.events.len();
    }
    for k in 0..keys.len() {
        assert_eq!(a.out(k), b.out(k), "board {} key {k}: out words", fw.index);
    }
    let (_, breaches) = a.take_io();
    assert!(breaches.is_empty(), "board {}: {breaches:?}", fw.index);
    let windows = a.board().io_windows();
    Played {
        events,
        samples,
        windows,
    }
}

/// `boards` of each layout (all when `None`), `samples` samples each, on two host
/// threads; the events of each layout's boards.
fn run(boards: Option<usize>, samples: usize) -> Vec<usize> {
    let mut all = Vec::new();
    for layout in LAYOUTS {
        let (fws, _) = firmware(layout, Some("rp2040_io"), Load::Ram);
        let fws = &fws[..boards.unwrap_or(fws.len()).min(fws.len())];
        let played = on_host_threads(fws, |fw| play(fw, samples));
        let events: usize = played.iter().map(|p| p.events).sum();
        for (fw, p) in fws.iter().zip(&played) {
            let w = p.windows;
            eprintln!(
                "  board {}: windows ahead of the I/O {} kept, undone {} (DMA claim), {} (stale load), {} (reach)",
                fw.index, w.kept, w.waited, w.stale, w.reach
            );
        }
        eprintln!(
            "{layout} on rp2040_io: {} boards × {} samples through the converters, {events} events, \
             as without them",
            played.len(),
            played.first().map_or(0, |p| p.samples)
        );
        all.push(events);
    }
    all
}

#[test]
fn the_first_board_of_each_layout_plays_the_corpus_through_its_converters() {
    run(Some(1), SHORT);
}

#[test]
#[ignore = "a second of the corpus on every board through the converters (minutes, release)"]
fn every_board_plays_a_second_of_the_corpus_through_its_converters() {
    // The corpus strikes and lets off on every layout: the comparison covers events.
    assert!(run(None, 44_100).iter().all(|&e| e > 0));
}

#[test]
#[ignore = "0.05 s of the corpus on the first board of each layout, interpreted in lock-step (release)"]
fn the_first_board_of_each_layout_through_its_converters_equals_the_lock_step() {
    // The tests above compare the board with converters against the image without them,
    // both on the default engine, where the cores run in windows ahead of the I/O
    // (`tactus_emulator::board`, `io_window.rs`). Here the reference is the interpreter's
    // lock-step run of the same image with converters: the same samples, cycles, SRAM,
    // frames and I/O state.
    const SAMPLES: usize = 2205;
    for layout in LAYOUTS {
        let (fws, _) = firmware(layout, Some("rp2040_io"), Load::Ram);
        let fw = &fws[0];
        let streams = streams(fw, SAMPLES);
        let mut win = fw.image.run().unwrap();
        let mut lock = fw.image.run().unwrap();
        lock.board().config.engine = Engine::Interp;
        for n in 0..SAMPLES {
            let now: Vec<i32> = streams.iter().map(|(w, _)| w[n]).collect();
            let a = win.step(&now).unwrap().clone();
            let b = lock.step(&now).unwrap();
            assert_eq!(&a, b, "{layout} sample {n}");
            assert_eq!(win.take_io(), lock.take_io(), "{layout} sample {n}: frames");
            let (x, y) = (win.board(), lock.board());
            assert_eq!(x.cycle(), y.cycle(), "{layout} sample {n}");
            if n % 100 == 99 {
                assert!(x.system.sram == y.system.sram, "{layout} sample {n}: SRAM");
            }
        }
        let (x, y) = (win.board(), lock.board());
        assert!(x.system.sram == y.system.sram, "{layout}: SRAM");
        assert_eq!(x.system.contention_stalls, y.system.contention_stalls);
        assert!(
            format!("{:?}", x.io()) == format!("{:?}", y.io()),
            "{layout}: the I/O"
        );
        let io = x.io_windows();
        eprintln!(
            "{layout} board 0: {SAMPLES} samples as the lock-step; windows {:?}, on the I/O {io:?}",
            x.run_ahead_windows()
        );
        assert!(io.kept > SAMPLES as u64 / 2, "{io:?}");
    }
}
