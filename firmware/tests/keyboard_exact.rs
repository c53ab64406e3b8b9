//! Every board of grand88 and of the split layout, as `tactus build` makes it, on the
//! emulator's block engine — the cores in windows, key updates memoized, boards at rest
//! replayed from a recorded period (the rest replay), what `tactus play` runs — against a
//! reference emulating every instruction (issue 37's "exact"): every sample's forces,
//! DAC words, events, handler cycles per core, contention stalls and miss counters equal,
//! and after the run every SRAM byte and each core's cycle, instruction count, registers
//! and flags. Two streams of sensor words: the budget corpus (each key's runs, with stretches
//! at rest between them, so that the memos both replay and stop replaying), and the key
//! travel of a recorded performance (`Maestro_1.mid` of the shared data folder beside the
//! repository, or `TACTUS_PERFORMANCES`; the position player's tracks).
//!
//! The references: the machine that defines the RP2040 with no accelerator at all
//! ([`Engine::LockStep`]: every instruction decoded from memory as it runs) for Maestro_1 on
//! every board and the corpus on grand88's ([`LOCK_STEP`] samples); the lock-step
//! interpreter ([`Engine::Interp`], which shares the accelerator's decode cache) for the
//! corpus on the split layout's boards and the long runs.
//!
//! In CI: [`SHORT`] samples of the corpus and [`MAESTRO_SHORT_S`] s of Maestro_1 from its
//! second [`MAESTRO_FROM_S`] (where boards rest long enough for the rest replay to give
//! samples: about 9,000 on grand88's boards); `cargo test --release -p tactus-firmware
//! --test keyboard_exact -- --ignored` runs a whole emulated second of the corpus and the
//! first 20 s of Maestro_1 on every board against the interpreter. The corpus's rests
//! ([`STRETCH`] samples) are shorter than the rest replay needs to give samples (64 + a
//! period of 1,071): `rest.rs` compares boards that rest long enough, the replay giving
//! samples and skipping periods, with and without converters, against the lock-step
//! machine in CI.

use std::path::PathBuf;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_emulator::Engine;
use tactus_firmware::flash::{BoardFirmware, Load};
use tactus_firmware::image::ImageRun;
use tactus_runtime::performance::{key_tracks, read_midi, KeyTrack};

#[path = "common/layouts.rs"]
mod layouts;
use layouts::{corpus_words, firmware, root};

/// Corpus samples per board in CI.
const SHORT: usize = 1_200;
/// Corpus samples per board of grand88 against the lock-step machine in CI: a stretch of
/// key runs and one at rest.
const LOCK_STEP: usize = 600;
/// Samples of a corpus stretch, and of the rest after it.
const STRETCH: usize = 300;
/// Seconds of Maestro_1 in CI, and from where.
const MAESTRO_SHORT_S: f64 = 0.1;
const MAESTRO_FROM_S: f64 = 2.0;

const LAYOUTS: [&str; 2] = [
    "instruments/layouts/grand88.toml",
    "instruments/layouts/split_harpsichord_piano.toml",
];

/// One board on the block engine and on `reference`: every sample's outputs, then memory
/// and cores, equal. `words(n)` gives the sensor words of sample `n`. Returns the memo hits
/// of the block engine's run (the rest replay on, as in `tactus play`), and the samples
/// the rest replay gave.
fn compare(
    fw: &BoardFirmware,
    samples: usize,
    words: &dyn Fn(usize) -> Vec<i32>,
    reference: Engine,
) -> (u64, u64) {
    let mut runs: [ImageRun; 2] = [fw.image.run().unwrap(), fw.image.run().unwrap()];
    assert_eq!(runs[0].board().config.engine, Engine::Block);
    runs[1].board().config.engine = reference;
    // What `tactus play` runs: the rest replay on (a board at rest gives its samples from a
    // recorded period and skips whole ones: `firmware/src/image/rest.rs`).
    runs[0].set_rest_replay(true).unwrap();
    for n in 0..samples {
        let w = words(n);
        let a = runs[0].step(&w).unwrap().clone();
        let b = runs[1].step(&w).unwrap();
        assert_eq!(&a, b, "board {} sample {n}", fw.index);
    }
    let [a, b] = &mut runs;
    assert!(
        a.board().system.sram == b.board().system.sram,
        "board {}: SRAM differs after {samples} samples",
        fw.index
    );
    for c in 0..2 {
        let (x, y) = (&a.board().cores[c], &b.board().cores[c]);
        assert_eq!(
            (x.cycle, x.instructions, x.r, x.n, x.z, x.c, x.v),
            (y.cycle, y.instructions, y.r, y.n, y.z, y.c, y.v),
            "board {} core {c}",
            fw.index
        );
    }
    (a.board().memo_stats().hits, a.rest_replayed().0)
}

/// The budget corpus on every board of `layouts`, `samples` samples each, the block engine
/// against `reference`.
fn corpus(layouts: &[&str], samples: usize, reference: Engine) {
    for &layout in layouts {
        let (boards, _) = firmware(layout, None, Load::Ram);
        let (mut hits, mut given) = (0, 0);
        for fw in &boards {
            let programs = fw.image.programs();
            let keys = fw.image.keys();
            let stream: Vec<(Vec<i32>, i32)> = keys
                .iter()
                .enumerate()
                .map(|(i, k)| {
                    let p = &programs[k.program];
                    let rest = FixedInstance::sensor_raw(&p.fixed, 0, Some(0.0));
                    (corpus_words(p, fw.keys[0] as usize + i, samples), rest)
                })
                .collect();
            let words = |n: usize| {
                stream
                    .iter()
                    .map(|(w, rest)| match (n / STRETCH) % 2 {
                        0 => w[n],
                        _ => *rest,
                    })
                    .collect()
            };
            let (h, g) = compare(fw, samples, &words, reference);
            (hits, given) = (hits + h, given + g);
        }
        eprintln!(
            "{layout}: {} boards exact against {reference:?}, {hits} memoized calls, {given} samples given by the rest replay",
            boards.len()
        );
        assert!(hits > 0, "{layout}: no call was memoized");
    }
}

/// `Maestro_1.mid` from the shared data folder beside the repository (or
/// `TACTUS_PERFORMANCES`); `None`, said loudly, when absent outside CI (under `CI` the test
/// fails).
fn maestro_1() -> Option<PathBuf> {
    let dir = std::env::var_os("TACTUS_PERFORMANCES")
        .map_or_else(|| root().join("../shared/data/performances"), PathBuf::from);
    let p = dir.join("Maestro_1.mid");
    if !p.exists() {
        assert!(
            std::env::var_os("CI").is_none(),
            "{} is missing: CI is set, so this test fails rather than skips",
            p.display()
        );
        eprintln!(
            "SKIPPED: {} is missing (set TACTUS_PERFORMANCES)",
            p.display()
        );
        return None;
    }
    Some(p)
}

/// Maestro_1 from `from_s` for `seconds` on every board of every layout.
fn maestro(from_s: f64, seconds: f64, reference: Engine) {
    let Some(path) = maestro_1() else {
        return;
    };
    let perf = read_midi(&path).unwrap();
    for layout in LAYOUTS {
        let (boards, board) = firmware(layout, None, Load::Ram);
        let fs = board.sample_rate_hz;
        let samples = (seconds * fs) as usize;
        let (mut hits, mut given) = (0, 0);
        for fw in &boards {
            let programs = fw.image.programs();
            let keys = fw.image.keys();
            let key_progs: Vec<_> = keys.iter().map(|k| &programs[k.program]).collect();
            let dip = key_progs[0].fixed.program.sensors[0].range.1;
            let tracks: Vec<KeyTrack> = key_tracks(&perf, dip);
            let mine: Vec<Option<&KeyTrack>> = fw
                .keys
                .iter()
                .map(|&k| tracks.iter().find(|t| t.key == k))
                .collect();
            let words = |n: usize| {
                let t = from_s + n as f64 / fs;
                key_progs
                    .iter()
                    .zip(&mine)
                    .map(|(p, track)| {
                        let x = track.map_or(0.0, |tr| tr.position(t));
                        FixedInstance::sensor_raw(&p.fixed, 0, Some(x))
                    })
                    .collect()
            };
            let (h, g) = compare(fw, samples, &words, reference);
            (hits, given) = (hits + h, given + g);
        }
        eprintln!(
            "{layout}: {} boards exact over Maestro_1, {hits} memoized calls, {given} samples given by the rest replay",
            boards.len()
        );
        assert!(hits > 0, "{layout}: no call was memoized");
    }
}

/// The split layout's boards against the interpreter (grand88's are held to the lock-step
/// machine below).
#[test]
fn every_split_board_runs_the_corpus_exactly_as_the_interpreter() {
    corpus(&LAYOUTS[1..], SHORT, Engine::Interp);
}

/// The accelerator (block engine, windows, memos, rest replay) against the machine that
/// defines the RP2040 with no accelerator at all ([`Engine::LockStep`]: every instruction
/// decoded from memory as it runs), on every board of grand88.
#[test]
fn every_grand88_board_runs_the_corpus_exactly_as_the_lock_step_machine() {
    corpus(&LAYOUTS[..1], LOCK_STEP, Engine::LockStep);
}

/// Every board of both layouts, the block engine (the rest replay on) against the lock-step
/// machine.
#[test]
fn every_board_plays_maestro_1_exactly_as_the_lock_step_machine() {
    maestro(MAESTRO_FROM_S, MAESTRO_SHORT_S, Engine::LockStep);
}

#[test]
#[ignore = "a second of the corpus on every board, both engines (minutes)"]
fn every_board_runs_a_second_of_the_corpus_exactly_as_the_interpreter() {
    corpus(&LAYOUTS, 44_100, Engine::Interp);
}

#[test]
#[ignore = "20 s of Maestro_1 on every board, both engines (tens of minutes)"]
fn every_board_plays_20_s_of_maestro_1_exactly_as_the_interpreter() {
    maestro(0.0, 20.0, Engine::Interp);
}
