//! The rest replay (`firmware/src/image/rest.rs`, `emulator/src/accel/rest.rs`): a board
//! whose keys rest, move and rest again, run as `tactus play` runs it (the block engine,
//! memoized, the cores in windows, the replay on) against the same board emulating every
//! sample on the machine that defines the RP2040 with no accelerator at all
//! ([`Engine::LockStep`]: every instruction decoded from memory as it runs, what
//! `--no-rest-replay --emu lock-step` runs) — every sample's outputs and out words equal,
//! and after the run every SRAM byte and each core's cycle, instruction count, registers,
//! flags and contention stalls, and the converters' frames and state; the replay must have
//! given samples and skipped whole periods. Boards: grand88's first (the grand piano) at 133
//! MHz (a period of 1,071 samples), with converters (`rp2040_io`, 1,071), the split layout's
//! first (the harpsichord). The two longest runs — the board at 200 MHz (a period of 7,497)
//! and the held key whose limiter works (76,000 samples) — are held to the lock-step
//! interpreter ([`Engine::Interp`], itself held to the lock-step machine by
//! `keyboard_exact.rs`): on the machine alone they would cost CI about 20 s more.

use tactus_compiler::fixed::interp::FixedInstance;
use tactus_emulator::Engine;
use tactus_firmware::flash::Load;
use tactus_firmware::image::ImageRun;

#[path = "common/layouts.rs"]
mod layouts;
use layouts::{corpus_words, firmware};

/// The boards' rest period at 133 MHz (lcm(63, 17)) and at 200 MHz (lcm(441, 17)).
const PERIOD_133: usize = 1_071;
const PERIOD_200: usize = 7_497;
/// With converters at 133 MHz: the plain board's, lcm(63, 17) (`firmware/src/image/io.rs`,
/// "A resting board repeats": the ring of three results buffers and the DMA channels'
/// numbering keep it; the PIO dividers, 2 and 1, divide its 3,230,000 cycles).
const PERIOD_IO_133: usize = 1_071;

#[test]
fn a_resting_piano_board_replays_exactly() {
    replays_exactly(
        "instruments/layouts/grand88.toml",
        None,
        PERIOD_133,
        4,
        12,
        Engine::LockStep,
    );
}

#[test]
fn a_resting_harpsichord_board_replays_exactly() {
    replays_exactly(
        "instruments/layouts/split_harpsichord_piano.toml",
        None,
        PERIOD_133,
        4,
        12,
        Engine::LockStep,
    );
}

#[test]
fn a_resting_piano_board_at_200_mhz_replays_exactly() {
    replays_exactly(
        "instruments/layouts/grand88.toml",
        Some("rp2040_200mhz"),
        PERIOD_200,
        4,
        3,
        Engine::Interp,
    );
}

#[test]
fn a_resting_piano_board_with_converters_replays_exactly() {
    replays_exactly(
        "instruments/layouts/grand88.toml",
        Some("rp2040_io"),
        PERIOD_IO_133,
        // From power-up its state settles in about three periods (the first found at
        // sample 3,277).
        6,
        6,
        Engine::LockStep,
    );
}

/// A key pressed to the keybed and held (its force above rated: the limiter spends its
/// budget each sample, then, the budget spent, cycles through `recovery + 1` samples), then
/// released (the budget earned back a unit a sample: 17,640 units full, 4 spent a sample), on grand88's first board: the replay
/// must give samples while the budget drains, while it cycles (a period of 5 tries) and
/// while it fills, each ending exactly where the budget's path would change.
#[test]
fn a_held_key_whose_limiter_works_replays_exactly() {
    let (boards, _) = firmware("instruments/layouts/grand88.toml", None, Load::Ram);
    let fw = &boards[0];
    let programs = fw.image.programs();
    let keys = fw.image.keys();
    let word =
        |k: usize, x: f64| FixedInstance::sensor_raw(&programs[keys[k].program].fixed, 0, Some(x));
    let rest: Vec<i32> = (0..keys.len()).map(|k| word(k, 0.0)).collect();
    let mut stream: Vec<Vec<i32>> = vec![rest.clone(); 200];
    let ramp = 300;
    let depth = HELD_DEPTH_M;
    for n in 0..=ramp {
        let mut w = rest.clone();
        w[1] = word(1, depth * n as f64 / ramp as f64);
        stream.push(w);
    }
    let mut held = rest.clone();
    held[1] = word(1, depth);
    stream.extend(std::iter::repeat_n(held, 45_000));
    for n in (0..=ramp).rev() {
        let mut w = rest.clone();
        w[1] = word(1, depth * n as f64 / ramp as f64);
        stream.push(w);
    }
    stream.extend(std::iter::repeat_n(rest.clone(), 30_000));
    let mut runs = replay_and(&fw.image, Engine::Interp);
    for (n, w) in stream.iter().enumerate() {
        let a = runs[0].step(w).unwrap().clone();
        assert_eq!(&a, runs[1].step(w).unwrap(), "sample {n}");
    }
    let (given, skipped) = runs[0].rest_replayed();
    let (longest, room_ends) = runs[0].rest_periods();
    eprintln!(
        "{} samples: {given} given, {skipped} periods skipped, longest period {longest}, \
         {room_ends} replays ended by a budget",
        stream.len()
    );
    runs[0].settle().unwrap();
    let [a, b] = &mut runs;
    assert!(
        a.board().system.sram == b.board().system.sram,
        "SRAM differs"
    );
    for c in 0..2 {
        let (x, y) = (&a.board().cores[c], &b.board().cores[c]);
        assert_eq!(
            (x.cycle, x.instructions, x.r),
            (y.cycle, y.instructions, y.r),
            "core {c}"
        );
    }
    assert_eq!(longest, 5 * PERIOD_133, "the cycling budget's period");
    assert!(room_ends >= 2, "{room_ends} replays ended by a budget");
    assert!(given > 40_000, "given {given}");
}

/// Two runs of `image`: `tactus play`'s (the block engine, memoized, the rest replay on) and
/// `reference`'s, every sample emulated.
fn replay_and(image: &tactus_firmware::image::FirmwareImage, reference: Engine) -> [ImageRun; 2] {
    let mut runs: [ImageRun; 2] = [image.run().unwrap(), image.run().unwrap()];
    assert_eq!(runs[0].board().config.engine, Engine::Block);
    runs[0].set_rest_replay(true).unwrap();
    runs[1].board().config.engine = reference;
    runs
}

/// A key's travel at the keybed and beyond (m): grand88's keys dip 10 mm.
const HELD_DEPTH_M: f64 = 0.0105;

/// The first board of `layout` on board kind `kind`, whose period at rest is `period`
/// samples: a first rest of `first` periods from power-up, rests of `periods` periods
/// after each move; the replay's run against `reference`'s.
fn replays_exactly(
    layout: &str,
    kind: Option<&str>,
    period: usize,
    first: usize,
    periods: usize,
    reference: Engine,
) {
    let (boards, _) = firmware(layout, kind, Load::Ram);
    let fw = &boards[0];
    let programs = fw.image.programs();
    let keys = fw.image.keys();
    let rest: Vec<i32> = keys
        .iter()
        .map(|k| FixedInstance::sensor_raw(&programs[k.program].fixed, 0, Some(0.0)))
        .collect();
    assert!(
        keys.len() >= 3,
        "{layout}: the board has {} keys",
        keys.len()
    );
    let moving: Vec<Vec<i32>> = keys
        .iter()
        .enumerate()
        .map(|(i, k)| corpus_words(&programs[k.program], i, 400))
        .collect();
    // Rest long enough for whole periods to be skipped, a move of one key then of all, rest
    // that ends mid-period, and rest again to the end (the run ends parked).
    let mut stream: Vec<Vec<i32>> = Vec::new();
    stream.extend(std::iter::repeat_n(rest.clone(), 64 + first * period + 123));
    for &x in &moving[2][..150] {
        let mut w = rest.clone();
        w[2] = x;
        stream.push(w);
    }
    stream.extend(std::iter::repeat_n(rest.clone(), periods * period + 700));
    for n in 0..300 {
        stream.push(moving.iter().map(|m| m[n]).collect());
    }
    stream.extend(std::iter::repeat_n(rest.clone(), periods * period + 10));

    let mut frames = 0;
    let mut runs = replay_and(&fw.image, reference);
    // The replay turned off for a while in the last rest (and the board looked at): it
    // must pick up again, exactly.
    let off = stream.len() - 2 * period..stream.len() - 2 * period + 37;
    for (n, w) in stream.iter().enumerate() {
        if n == off.start {
            runs[0].set_rest_replay(false).unwrap();
        } else if n == off.end {
            runs[0].board();
            runs[0].set_rest_replay(true).unwrap();
        }
        let a = runs[0].step(w).unwrap().clone();
        let b = runs[1].step(w).unwrap();
        assert_eq!(&a, b, "sample {n}");
        for k in 0..keys.len() {
            assert_eq!(
                runs[0].out(k),
                runs[1].out(k),
                "sample {n} key {k}: out words"
            );
        }
        // The converters' frames of each rest (those of the samples given, once the board
        // is brought to the present) before the words change, and at the end.
        if stream.get(n + 1) != Some(w) {
            let (fa, fb) = (runs[0].take_io(), runs[1].take_io());
            assert!(fa == fb, "sample {n}: the converters' frames differ");
            frames += fa.0.len();
        }
    }
    if fw.image.io().is_some() {
        assert!(
            frames > stream.len(),
            "{frames} frames in {} samples",
            stream.len()
        );
    }
    let (given, skipped) = runs[0].rest_replayed();
    let (longest, _) = runs[0].rest_periods();
    assert_eq!(longest, period, "{layout}: the rest period");
    eprintln!(
        "{layout}: {} samples against {reference:?}, {given} given from recordings, {skipped} periods skipped",
        stream.len()
    );
    assert!(
        runs[0].rest_refused().is_none(),
        "{:?}",
        runs[0].rest_refused()
    );
    assert!(
        given > 2 * period as u64 && skipped >= 1,
        "{layout}: given {given}, skipped {skipped}"
    );
    runs[0].settle().unwrap();
    let [a, b] = &mut runs;
    assert!(
        a.board().system.sram == b.board().system.sram,
        "SRAM differs"
    );
    assert_eq!(
        a.board().system.contention_stalls,
        b.board().system.contention_stalls
    );
    assert!(a.board().io_mut() == b.board().io_mut(), "the I/O differs");
    for c in 0..2 {
        let (x, y) = (&a.board().cores[c], &b.board().cores[c]);
        assert_eq!(
            (x.cycle, x.instructions, x.r, x.n, x.z, x.c, x.v, x.state),
            (y.cycle, y.instructions, y.r, y.n, y.z, y.c, y.v, y.state),
            "core {c}"
        );
    }
    // And on after the settle: the boards run on alike.
    for (n, w) in stream.iter().take(200).enumerate() {
        let a = runs[0].step(w).unwrap().clone();
        assert_eq!(&a, runs[1].step(w).unwrap(), "after the settle, sample {n}");
    }
}
