//! The firmware's watchdog (`Program::watchdog`; `image/fault.rs`, "The watchdog"): a hung
//! update on either core stops core 0's feeds, the watchdog resets the board within its
//! period, the board boots again from flash with its DACs at zero meanwhile, the fault
//! word says so, and the key plays again — on a board without converters and on one with
//! them, the same on the lock-step machine and on the block engine with the rest replay.

#[path = "common/layouts.rs"]
mod layouts;
#[path = "common/spring.rs"]
mod spring;
use spring::{fault, turns_image};

use tactus_emulator::Engine;
use tactus_firmware::image::fault::{FaultKind, UNKNOWN_KEY, WATCHDOG_PERIOD_US};
use tactus_firmware::image::glue::ctrl;
use tactus_firmware::image::{self, FirmwareImage, ImageRun, Injection, SampleOut};

/// The spring's three keys, the watchdog on or off.
fn image(board: &str, watchdog: bool) -> FirmwareImage {
    let mut p = spring::spring();
    p.watchdog = watchdog;
    // Every update runs (the quiescent-key guard would skip a held key's, hung or not).
    p.quiescent_guard = false;
    // The sensor check off: the keys are held at mid-travel from the start, and on the
    // converter board the start handler's ADC burst samples them before the host sets a
    // code (at rest): a jump at the first step the check would rightly trip. The watchdog
    // with the check on: `fault.rs`, `faults.rs`.
    p.sensor_check = false;
    spring::three_keys(&p, board)
}

/// `samples` samples of the keys held at mid-travel from flash, key `hung`'s update hung
/// from sample `from`; every sample, the run, and the cycle of sample `from`'s tick.
/// Every sensor word of a board at the middle of the first program's sensor range (a key
/// held still, half down): three words, as many as the images' keys read.
fn mid_words(image: &FirmwareImage) -> Vec<i32> {
    let (lo, hi) = image.programs()[0].fixed.sensor_raw_range[0];
    vec![lo + (hi - lo) / 2; 3]
}

/// A brown-out of the whole board at sample `from`.
fn brown_out(from: u64) -> Injection {
    Injection {
        kind: image::FaultKind::BrownOut,
        key: None,
        core: None,
        from,
        until: None,
    }
}

fn run(
    image: &FirmwareImage,
    engine: Engine,
    hung: Option<usize>,
    from: u64,
    samples: usize,
) -> (Vec<SampleOut>, ImageRun, u64) {
    let words = mid_words(image);
    run_with(image, engine, hung, from, samples, &|_| words.clone())
}

/// [`run`] with the sensor words of sample `i` given by `words(i)`.
fn run_with(
    image: &FirmwareImage,
    engine: Engine,
    hung: Option<usize>,
    from: u64,
    samples: usize,
    words: &dyn Fn(usize) -> Vec<i32>,
) -> (Vec<SampleOut>, ImageRun, u64) {
    let flash = image.flash_image().unwrap().bytes;
    let mut r = ImageRun::from_flash(image, &flash).unwrap();
    r.board().config.engine = engine;
    r.set_rest_replay(engine != Engine::LockStep).unwrap();
    if let Some(k) = hung {
        r.inject(Injection {
            kind: image::FaultKind::Hang,
            key: Some(k),
            core: None,
            from,
            until: None,
        })
        .unwrap();
    }
    let at = r.tick_cycle(from);
    let out = (0..samples)
        .map(|i| r.step(&words(i)).unwrap().clone())
        .collect();
    (out, r, at)
}

/// The one reset of a run whose update hung at the tick of cycle `hang_cycle`: by the
/// watchdog, within the period of the last feed, which came at the latest at the end of
/// core 0's handler of the hang's sample (core 1's count one behind its own: core 1 may
/// still be finishing it), and at the earliest in the sample of the feeding class before
/// the hang's, at most the image's feed gap (`FirmwareImage::feed_gap`, 1 when every
/// sample feeds) before it: 1 ms and a sample from the hang's tick at most, and more than
/// 1 ms less the gap (no feed came later); the board boots again from flash and is back
/// 20 samples or more before the run's `n` end. Returns the samples of the reset and of
/// the return (the first after the reboot).
fn reset_after_hang(r: &ImageRun, hang_cycle: u64, n: usize, what: &str) -> (usize, usize) {
    let resets = r.resets();
    assert_eq!(resets.len(), 1, "{what}: {resets:?}");
    let reset = &resets[0];
    assert_eq!(reset.why, "watchdog timer", "{what}");
    let gap = u64::from(r.image().feed_gap().expect("the watchdog"));
    let (period, sample) = (133_000 * u64::from(WATCHDOG_PERIOD_US) / 1000, 3016);
    let after = reset.cycle.saturating_sub(hang_cycle);
    assert!(
        after > period - gap * sample && after <= period + sample,
        "{what}: reset {after} cycles after the hang's tick (period {period}, feeds every {gap} samples at most)"
    );
    let zero = *reset
        .reboot
        .as_ref()
        .expect("the board boots again from flash");
    let (at, back) = (reset.sample as usize, reset.sample as usize + zero as usize);
    assert!(back + 20 < n, "{what}: back at sample {back}");
    (at, back)
}

/// Around a hang's reset (`at`, `back` from [`reset_after_hang`]): every sample before the
/// hang's `from` is the clean run's, the DACs are at zero while the board reboots, and
/// from the second sample after it every key's force is the clean run's again.
fn assert_reboot(
    out: &[SampleOut],
    clean: &[SampleOut],
    from: u64,
    (at, back): (usize, usize),
    what: &str,
) {
    for (i, s) in out.iter().enumerate() {
        if i < from as usize {
            assert_eq!(s, &clean[i], "{what} sample {i}: before the hang");
        } else if (at..back).contains(&i) {
            assert!(
                s.dac.iter().all(|&d| d == 0),
                "{what} sample {i}: rebooting"
            );
        } else if i >= back + 2 {
            assert_eq!(s.force, clean[i].force, "{what} sample {i}: plays again");
        }
    }
}

fn hang_resets_and_recovers(board: &str, key: usize) {
    let image = image(board, true);
    let (from, n) = (100u64, 200usize);
    let (clean, ..) = run(&image, Engine::LockStep, None, from, n);
    let (out, mut r, hang_cycle) = run(&image, Engine::LockStep, Some(key), from, n);
    // A healthy board is fed every sample: the clean run never resets.
    assert!(clean.iter().all(|s| s.dac.iter().all(|&d| d != 0)));
    let (at, back) = reset_after_hang(&r, hang_cycle, n, board);
    assert_reboot(&out, &clean, from, (at, back), board);
    // The keys the hang does not reach play on until the reset.
    let core = image.keys()[key].core;
    for i in from as usize..at {
        for k in (0..3).filter(|&k| image.keys()[k].core != core) {
            assert_eq!(out[i].dac[k], clean[i].dac[k], "{board} sample {i} key {k}");
        }
    }
    // The trip on the hung key's core's record (core 0 saw core 1 fall behind, or core 0
    // itself stopped), the other core's untouched.
    // It names the key that hung (its window slot), read from the core's return slot.
    let f = fault(&mut r, &image, core);
    let slot = image.keys()[key].slot as u8;
    assert_eq!(
        (f.kind, f.key, f.trips, f.at_sample),
        (Some(FaultKind::Watchdog), slot, 1, 0),
        "{board} core {core}: {f:?}"
    );
    assert!(!fault(&mut r, &image, 1 - core).tripped(), "{board}");
    // The engines agree through the hang, the reset and the reboot, the records too.
    let (fast, mut rf, _) = run(&image, Engine::Block, Some(key), from, n);
    for (i, (a, b)) in out.iter().zip(&fast).enumerate() {
        assert_eq!(a, b, "{board} sample {i}: lock-step vs block engine");
    }
    for c in 0..2 {
        assert_eq!(
            fault(&mut rf, &image, c),
            fault(&mut r, &image, c),
            "{board} core {c}: the block engine's record"
        );
    }
}

#[test]
fn a_hung_key_beside_another_on_core_0_is_named_on_a_plain_board() {
    hang_resets_and_recovers("rp2040", 1);
}

#[test]
fn a_hung_core_0_resets_a_converter_board_within_the_period() {
    hang_resets_and_recovers("rp2040_io", 0);
}

/// The return slot (`image/fault.rs`, "Which key hung"): 0 after the boot (cleared after the
/// keys' `init`s), then after each sample the return address of the core's last update
/// call, the last key's in the copy of the keys' code that ran; the word below it is the
/// update's saved r7 or lower, never the return address (the update pushed LR there).
#[test]
fn the_return_slot_holds_the_last_update_calls_return_address() {
    for board in ["rp2040", "rp2040_io"] {
        let image = image(board, true);
        let mut r = image.run().unwrap();
        for c in 0..2 {
            let slot = image.return_slot(c).unwrap();
            assert_eq!(r.board().read_u32(slot).unwrap(), 0, "{board} core {c}");
        }
        let words = mid_words(&image);
        for _ in 0..5 {
            r.step(&words).unwrap();
            for c in 0..2 {
                let slot = image.return_slot(c).unwrap();
                let last = *image.core_keys(c).last().unwrap();
                let lr = r.board().read_u32(slot).unwrap();
                let calls = image.update_calls(last).unwrap();
                assert!(
                    calls.iter().any(|&a| a + 5 == lr),
                    "{board} core {c}: {lr:#010x} is no return of key {last}'s calls {calls:x?}"
                );
            }
        }
    }
}

/// A core that hangs before any update of the boot was entered (here core 0's sample
/// interrupt made a `B .` at its first instruction before the first tick, as a corrupted
/// handler would be) leaves its return slot as the boot cleared it: the record says the
/// key is unknown, not a wrong one; the boot from flash mends the code and the board plays.
#[test]
fn a_hang_before_any_update_names_no_key() {
    let image = image("rp2040", true);
    let flash = image.flash_image().unwrap().bytes;
    let mut r = ImageRun::from_flash(&image, &flash).unwrap();
    let isr = image.core_addresses(0).unwrap()[2];
    r.board().write_bytes(isr, &[0xfe, 0xe7]).unwrap();
    // A run follows resets once a fault is injected: one that starts after the run.
    r.inject(Injection {
        kind: image::FaultKind::Hang,
        key: Some(1),
        core: None,
        from: 1_000_000,
        until: None,
    })
    .unwrap();
    let words = mid_words(&image);
    let out: Vec<SampleOut> = (0..120).map(|_| r.step(&words).unwrap().clone()).collect();
    assert_eq!(r.resets().len(), 1, "{:?}", r.resets());
    let f = fault(&mut r, &image, 0);
    assert_eq!(
        (f.kind, f.key, f.trips),
        (Some(FaultKind::Watchdog), UNKNOWN_KEY, 1),
        "{f:?}"
    );
    assert!(!fault(&mut r, &image, 1).tripped());
    assert!(out[119].dac.iter().all(|&d| d != 0), "plays again");
}

#[test]
fn a_hung_core_0_resets_a_plain_board_within_the_period() {
    hang_resets_and_recovers("rp2040", 0);
}

#[test]
fn a_hung_core_1_resets_a_plain_board_within_the_period() {
    hang_resets_and_recovers("rp2040", 2);
}

#[test]
fn a_hung_core_resets_a_converter_board_within_the_period() {
    hang_resets_and_recovers("rp2040_io", 2);
}

/// A hang is its key's alone (`FaultKind::Hang` loops at that key's calls of its update,
/// every copy of its core's keys code). With the quiescent-key guard on, key 0, held still,
/// never calls its update: a hang of it never runs, and the board plays as without it,
/// although key 1 beside it on core 0 runs the same update code every sample (it moves).
/// A hang of key 1 (core 0) or key 2 (core 1), which move, resets the board within the
/// watchdog's period, the trip on that key's core's record; the motors are at zero through
/// the reboot and the keys play again after it.
fn a_hang_is_its_keys_alone(board: &str) {
    let mut p = spring::spring();
    p.watchdog = true;
    p.sensor_check = false;
    assert!(p.quiescent_guard, "the guard on by default");
    let image = spring::three_keys(&p, board);
    let (lo, hi) = image.programs()[0].fixed.sensor_raw_range[0];
    // Key 0 at mid-travel; keys 1 and 2 on a triangle over the middle half of the range.
    let words = move |i: usize| {
        let t = (i % 40) as i64;
        let tri = if t < 20 { t } else { 40 - t };
        let span = i64::from(hi) - i64::from(lo);
        let moving = (i64::from(lo) + span / 4 + span / 2 * tri / 20) as i32;
        vec![lo + (hi - lo) / 2, moving, moving]
    };
    let (from, n) = (100u64, 200usize);
    let (clean, mut r, _) = run_with(&image, Engine::LockStep, None, from, n, &words);
    assert!(r.resets().is_empty() && !fault(&mut r, &image, 0).tripped());
    let (still, r, _) = run_with(&image, Engine::LockStep, Some(0), from, n, &words);
    assert!(r.resets().is_empty(), "{board}: {:?}", r.resets());
    assert_eq!(
        still, clean,
        "{board}: a hang of a key that never calls its update"
    );
    for key in [1, 2] {
        let core = image.keys()[key].core;
        let (out, mut r, hang_cycle) =
            run_with(&image, Engine::LockStep, Some(key), from, n, &words);
        let what = format!("{board} key {key}");
        let (at, back) = reset_after_hang(&r, hang_cycle, n, &what);
        assert_reboot(&out, &clean, from, (at, back), &what);
        // Key 1, not key 0 beside it, whose update is the same code (key 0's guard skips
        // it): the return slot holds key 1's call site.
        let f = fault(&mut r, &image, core);
        assert_eq!(
            (f.kind, f.key, f.trips),
            (Some(FaultKind::Watchdog), image.keys()[key].slot as u8, 1),
            "{board} key {key}: {f:?}"
        );
        assert!(
            !fault(&mut r, &image, 1 - core).tripped(),
            "{board} key {key}"
        );
        let (fast, ..) = run_with(&image, Engine::Block, Some(key), from, n, &words);
        assert_eq!(out, fast, "{board} key {key}: lock-step vs block engine");
    }
}

#[test]
fn a_hang_is_its_keys_alone_on_a_plain_board() {
    a_hang_is_its_keys_alone("rp2040");
}

#[test]
fn a_hang_is_its_keys_alone_on_a_converter_board() {
    a_hang_is_its_keys_alone("rp2040_io");
}

/// Every key of [`turns_image`] at rest (the converter board's ADC reads its power-on code
/// 0 at the start handler's first burst, before the host sets one: a key held elsewhere
/// would trip at its first check).
fn rest_words(image: &FirmwareImage) -> Vec<i32> {
    vec![image.programs()[0].fixed.sensor_raw_range[0].0; 5]
}

/// Per sample of a clean run of `samples` samples: its class on core 0 (from the tick's
/// accumulator, as the handler's dispatch reads it: `glue::Turns`), and whether the
/// watchdog was fed during it (its reset cycle moved).
fn feeds(image: &FirmwareImage, engine: Engine, samples: usize) -> Vec<(u8, bool)> {
    let turns = image.check_turns(0).unwrap().clone();
    let acc = image.core_addresses(0).unwrap()[3] + u32::from(ctrl::ACC);
    let mut r = image.run().unwrap();
    r.board().config.engine = engine;
    r.set_rest_replay(engine != Engine::LockStep).unwrap();
    let words = rest_words(image);
    let mut fire_at = r.board().system.watchdog.fire_at;
    let out = (0..samples)
        .map(|_| {
            r.step(&words).unwrap();
            let a = r.board().read_u32(acc).unwrap();
            let class = ((a >> turns.shift) & (turns.classes - 1)) as u8;
            let now = r.board().system.watchdog.fire_at;
            let fed = now != fire_at;
            fire_at = now;
            (class, fed)
        })
        .collect();
    assert!(r.resets().is_empty(), "{:?}", r.resets());
    out
}

/// Core 0 feeds the watchdog in the samples of its feeding class and in no other (the
/// class with the smallest longest gap, the lowest of those), so a healthy board is fed
/// at most every `feed_gap` samples, well within the watchdog's period; the same on the
/// lock-step machine and on the block engine with the rest replay.
#[test]
fn core_0_feeds_the_watchdog_in_its_feeding_class_of_samples_alone() {
    for board in ["rp2040", "rp2040_io"] {
        let (_, image) = turns_image(board);
        let turns = image.check_turns(0).unwrap().clone();
        assert_eq!(turns.classes, 4, "{board}: {turns:?}");
        let class = image.watchdog_feed().unwrap().class;
        assert_eq!(class, Some(0), "{board}: {turns:?}");
        let gap = image.feed_gap().unwrap();
        assert_eq!(gap, turns.gaps[0].0, "{board}");
        assert!(gap > 1, "{board}: {turns:?}");
        // Within a quarter of the period: 11 samples at 44.1 kHz.
        assert!(
            gap <= WATCHDOG_PERIOD_US * 44_100 / 4_000_000,
            "{board}: {gap}"
        );
        // A whole period of the accumulator and more.
        let n = turns.period as usize + 2 * gap as usize;
        let got = feeds(&image, Engine::LockStep, n);
        let mut last = None;
        let mut longest = 0;
        for (i, &(c, fed)) in got.iter().enumerate() {
            assert_eq!(fed, c == 0, "{board} sample {i}: class {c}");
            if fed {
                if let Some(l) = last {
                    longest = longest.max(i - l);
                }
                last = Some(i);
            }
        }
        assert_eq!(
            longest as u32, gap,
            "{board}: the longest time between two feeds"
        );
        let fast = feeds(&image, Engine::Block, n);
        assert_eq!(got, fast, "{board}: lock-step vs block engine");
    }
}

/// With the feed in one class of samples, a hung update on either core still resets the
/// board within the watchdog's period and a sample of the hang's tick, and no sooner than
/// the period less the feed's gap: the last feed was the feeding class's last sample in
/// which both cores had finished theirs (core 1 one sample behind at most), whichever
/// class the hang's sample is of; the fault record names the key, and the engines agree.
#[test]
fn a_hang_resets_a_board_that_feeds_in_turns_within_the_period_and_a_sample() {
    for board in ["rp2040", "rp2040_io"] {
        let (_, image) = turns_image(board);
        let gap = image.feed_gap().unwrap() as u64;
        assert!(gap > 1, "{board}: the feed takes turns");
        let feeding = image.watchdog_feed().unwrap().class.unwrap();
        let classes = feeds(&image, Engine::LockStep, 200);
        let words = rest_words(&image);
        let n = 200usize;
        // Hangs from a sample of each class, on core 0 (key 3) and core 1 (key 4).
        for from in 100..100 + gap {
            for key in [3usize, 4] {
                let (out, mut r, hang_cycle) =
                    run_with(&image, Engine::LockStep, Some(key), from, n, &|_| {
                        words.clone()
                    });
                let what = format!("{board} key {key} from {from}");
                let (at, _) = reset_after_hang(&r, hang_cycle, n, &what);
                // The reset one period after the end of the last feeding sample: the hang's
                // own when core 1 hung (core 0 finished it with core 1 one behind), the one
                // before it when core 0 did.
                let last = (0..=from as usize)
                    .rev()
                    .filter(|&i| key == 4 || i < from as usize)
                    .find(|&i| classes[i].0 == feeding)
                    .unwrap() as u64;
                let reset = r.resets()[0].cycle;
                let period = 133_000 * u64::from(WATCHDOG_PERIOD_US) / 1000;
                // The ticks of the boot before the reset (`ImageRun::tick_cycle` counts
                // from the new boot's after it), from the hang's.
                let tick = |i: u64| {
                    let t = |n| tactus_runtime::keyboard::tick_cycle(0, n, 133_000_000, 44_100);
                    hang_cycle - t(from) + t(i)
                };
                assert!(
                    reset > tick(last) + period && reset <= tick(last + 1) + period,
                    "{what}: reset at {reset}, the last feed in sample {last} (ticks {} – {})",
                    tick(last),
                    tick(last + 1)
                );
                let core = usize::from(key == 4);
                let f = fault(&mut r, &image, core);
                assert_eq!(
                    (f.kind, f.key, f.trips),
                    (Some(FaultKind::Watchdog), 60 + key as u8, 1),
                    "{what}: {f:?}"
                );
                assert!(out[at].dac.iter().all(|&d| d == 0), "{what}: rebooting");
                if from == 100 {
                    let (fast, ..) = run_with(&image, Engine::Block, Some(key), from, n, &|_| {
                        words.clone()
                    });
                    assert_eq!(out, fast, "{what}: lock-step vs block engine");
                }
            }
        }
    }
}

#[test]
fn the_watchdog_costs_core_0_its_feed_and_core_1_a_wait_for_its_bank() {
    for board in ["rp2040", "rp2040_io"] {
        let (off, on) = (image(board, false), image(board, true));
        let (w0, w1) = (on.wcet(0).unwrap(), on.wcet(1).unwrap());
        // Core 1 runs no feed code; core 0's load of its count may make it wait a cycle
        // for its bank (`glue::Feed::other_core_cycles`).
        let w1_off = off.wcet(1).unwrap();
        assert_eq!(w1.analysed, w1_off.analysed, "{board}");
        assert_eq!(w1.bound(), w1_off.bound() + 1, "{board}");
        let extra = w0.bound() - off.wcet(0).unwrap().bound();
        assert!(
            extra > 0 && extra <= 18,
            "{board}: the feed costs {extra} cycles"
        );
    }
}

#[test]
fn a_brown_out_zeroes_the_motors_and_the_board_plays_again() {
    for board in ["rp2040", "rp2040_io"] {
        let image = image(board, true);
        let flash = image.flash_image().unwrap().bytes;
        let mut r = ImageRun::from_flash(&image, &flash).unwrap();
        let mut clean = ImageRun::from_flash(&image, &flash).unwrap();
        r.inject(brown_out(50)).unwrap();
        let words = mid_words(&image);
        let out: Vec<SampleOut> = (0..150).map(|_| r.step(&words).unwrap().clone()).collect();
        let want: Vec<SampleOut> = (0..150)
            .map(|_| clean.step(&words).unwrap().clone())
            .collect();
        let resets = r.resets().to_vec();
        assert_eq!(resets.len(), 1, "{board}: {resets:?}");
        assert_eq!(resets[0].why, "brown-out");
        let zero = *resets[0].reboot.as_ref().unwrap() as usize;
        for (i, s) in out.iter().enumerate().skip(50).take(zero) {
            assert!(s.dac.iter().all(|&d| d == 0), "{board} sample {i}");
        }
        for i in 50 + zero + 2..150 {
            assert_eq!(
                out[i].force, want[i].force,
                "{board} sample {i}: plays again"
            );
        }
        // A power-on: the scratch registers lost, no trip recorded.
        assert!(!fault(&mut r, &image, 0).tripped(), "{board}");
    }
}

/// `samples` samples of the keys held at mid-travel from a RAM image (as `tactus play`
/// runs it), key `hung`'s update hung from sample `from` until `until`; every sample and
/// the run.
fn run_ram(
    image: &FirmwareImage,
    engine: Engine,
    hung: Option<(usize, Option<u64>)>,
    from: u64,
    samples: usize,
) -> (Vec<SampleOut>, ImageRun) {
    let mut r = image.run().unwrap();
    r.board().config.engine = engine;
    r.set_rest_replay(engine != Engine::LockStep).unwrap();
    if let Some((k, until)) = hung {
        r.inject(Injection {
            kind: image::FaultKind::Hang,
            key: Some(k),
            core: None,
            from,
            until,
        })
        .unwrap();
    }
    let words = mid_words(image);
    let out = (0..samples)
        .map(|_| r.step(&words).unwrap().clone())
        .collect();
    (out, r)
}

/// A RAM image (no flash to boot from) with a hung update: the watchdog resets the board,
/// the boot ROM enters the image's re-entry (`image/reboot.rs`), which restores its data,
/// and the board plays again as a fresh board from its first sample, the watchdog's trip
/// counted. The hang lasts until the reboot (the injected hang is in the code, which the
/// re-entry does not restore: a hang that outlived the reset would hang the new boot too).
fn ram_image_boots_again(board: &str, key: usize) {
    let image = image(board, true);
    let reboot = image.ram_reboot().expect("a re-entry");
    assert_eq!(
        reboot.restores.len(),
        if board == "rp2040_io" { 4 } else { 2 }
    );
    let (from, n) = (100u64, 220usize);
    // Where the reset falls, and the boot after it, with the hang for good: the boot ROM
    // enters the image again, the hung code hangs it again, and the watchdog resets it
    // again, each reset counted.
    let (_, mut r) = run_ram(&image, Engine::LockStep, Some((key, None)), from, n);
    let resets = r.resets().to_vec();
    assert!(resets.len() >= 2, "{board}: {resets:?}");
    assert!(
        resets.iter().all(|x| x.reboot.is_ok()),
        "{board}: {resets:?}"
    );
    let f = fault(&mut r, &image, image.keys()[key].core);
    assert_eq!(
        (f.kind, f.trips as usize),
        (Some(FaultKind::Watchdog), resets.len()),
        "{board}: {f:?}"
    );
    // The hang cleared in the reboot's samples of zero force.
    let until = resets[0].sample + 1;
    let (out, mut r) = run_ram(&image, Engine::LockStep, Some((key, Some(until))), from, n);
    let (fresh, _) = run_ram(&image, Engine::LockStep, None, from, n);
    let resets = r.resets().to_vec();
    assert_eq!(resets.len(), 1, "{board}: {resets:?}");
    let reset = &resets[0];
    assert_eq!(reset.why, "watchdog timer");
    let zero = *reset.reboot.as_ref().expect("the RAM image boots again");
    let (at, back) = (reset.sample as usize, (reset.sample + zero) as usize);
    assert!(
        until as usize <= back && back + 60 < n,
        "{board}: {reset:?}"
    );
    // Zero force from the reset's sample through the boot's (the reset's own sample and
    // `zero` more), then the first sample of the new boot.
    let first = back + 1;
    for (i, s) in out.iter().enumerate() {
        if i < from as usize {
            assert_eq!(s, &fresh[i], "{board} sample {i}: before the hang");
        } else if (at..first).contains(&i) {
            assert!(
                s.dac.iter().all(|&d| d == 0),
                "{board} sample {i}: rebooting"
            );
        }
    }
    assert!(
        out[first].dac.iter().all(|&d| d != 0),
        "{board}: plays again"
    );
    // Playing again from rest as a fresh board plays from its first sample: the same
    // forces, currents, DAC codes and misses, sample for sample. But on the converter
    // board, whose fresh first sample reads the ADC's power-on code 0 (its first burst is
    // the start handler's, before the host sets a code: docs/firmware.md, "Faults"), the
    // rebooted board's ADC keeps the held key's code through the reset (the converters
    // are other chips): its first sample is the fresh board's second.
    for j in 0..n - first {
        let (a, mut b) = (&out[first + j], &fresh[j]);
        if board == "rp2040_io" && j == 0 {
            assert_ne!(fresh[0].force, fresh[1].force, "{board}: the power-on code");
            b = &fresh[1];
        }
        assert_eq!(
            (&a.force, &a.current_ua, &a.dac, &a.misses),
            (&b.force, &b.current_ua, &b.dac, &b.misses),
            "{board}: sample {j} after the reboot"
        );
    }
    // The watchdog's trip counted over the record the scratch registers kept, on the hung
    // key's core, naming the key.
    let core = image.keys()[key].core;
    let f = fault(&mut r, &image, core);
    assert_eq!(
        (f.kind, f.key, f.trips, f.at_sample),
        (
            Some(FaultKind::Watchdog),
            image.keys()[key].slot as u8,
            1,
            0
        ),
        "{board}: {f:?}"
    );
    assert!(!fault(&mut r, &image, 1 - core).tripped(), "{board}");
    // Armed again for the next reset: SCRATCH4 the boot ROM's magic, SCRATCH7 the entry.
    let wd = &r.board().system.watchdog;
    assert_eq!(
        wd.scratch(4),
        tactus_rp2040::watchdog::BOOT_MAGIC,
        "{board}"
    );
    assert_eq!(wd.scratch(7), image::reboot::REENTRY | 1, "{board}");
    // The engines agree through the hang, the reset, the re-entry and the reboot, the
    // records too.
    let (fast, mut rf) = run_ram(&image, Engine::Block, Some((key, Some(until))), from, n);
    for (i, (a, b)) in out.iter().zip(&fast).enumerate() {
        assert_eq!(a, b, "{board} sample {i}: lock-step vs block engine");
    }
    for c in 0..2 {
        assert_eq!(
            fault(&mut rf, &image, c),
            fault(&mut r, &image, c),
            "{board} core {c}: the block engine's record"
        );
    }
}

#[test]
fn a_hung_ram_image_boots_again_through_the_boot_rom_on_a_plain_board() {
    ram_image_boots_again("rp2040", 0);
}

#[test]
fn a_hung_ram_image_boots_again_through_the_boot_rom_on_a_converter_board() {
    ram_image_boots_again("rp2040_io", 2);
}

/// A brown-out clears SRAM: a RAM image is gone with it and the boot ROM finds no flash
/// image, so the board stays in USB boot, its motors at zero force for the rest of the run,
/// and the run says so (not a hang, not a board that seems to play).
#[test]
fn a_browned_out_ram_image_stays_in_usb_boot_and_says_so() {
    for board in ["rp2040", "rp2040_io"] {
        let image = image(board, true);
        let mut r = image.run().unwrap();
        r.inject(brown_out(50)).unwrap();
        let words = mid_words(&image);
        let out: Vec<SampleOut> = (0..150).map(|_| r.step(&words).unwrap().clone()).collect();
        assert!(out[49].dac.iter().all(|&d| d != 0), "{board}: played");
        for (i, s) in out.iter().enumerate().skip(50) {
            assert!(s.dac.iter().all(|&d| d == 0), "{board} sample {i}");
        }
        let resets = r.resets().to_vec();
        assert_eq!(resets.len(), 1, "{board}: {resets:?}");
        assert_eq!(resets[0].why, "brown-out");
        let why = resets[0].reboot.as_ref().expect_err("no image to boot");
        assert!(
            why.contains("USB boot") && why.contains("brown-out clears SRAM"),
            "{board}: {why}"
        );
    }
}

/// A hang for good of a RAM image's key: each boot hangs again and the watchdog resets the
/// board again. Every reset is reported at the run's sample during which it came (its
/// cycle between that sample's tick and the next, each within the run), one watchdog
/// period after the hang's tick and, after the first, one period after the boot's first
/// sample: the host's sample clock is the board's (`inject.rs`, "Late samples"). Meanwhile
/// the hung core's drives hold their codes, the other core plays on, and the hung core's
/// unfinished samples are counted, never measured as a handler: every sample's handler
/// cycles stay within the core's static bound.
fn a_hang_for_good_resets_at_the_runs_samples(board: &str, key: usize) {
    let image = image(board, true);
    let (from, n) = (100u64, 400usize);
    let mut r = image.run().unwrap();
    r.inject(Injection {
        kind: image::FaultKind::Hang,
        key: Some(key),
        core: None,
        from,
        until: None,
    })
    .unwrap();
    let words = mid_words(&image);
    let fs = 44_100;
    // The watchdog's period in samples: 44.1 at 44.1 kHz.
    let period = u64::from(WATCHDOG_PERIOD_US) * fs / 1_000_000;
    let core = image.keys()[key].core;
    let bounds: Vec<u64> = (0..2).map(|c| image.wcet(c).unwrap().bound()).collect();
    let mut out: Vec<SampleOut> = Vec::new();
    let mut seen = 0;
    for i in 0..n as u64 {
        assert_eq!(r.samples(), i, "{board}");
        let (tick, next) = (r.tick_cycle(i), r.tick_cycle(i + 1));
        out.push(r.step(&words).unwrap().clone());
        let resets = r.resets();
        if resets.len() > seen {
            assert_eq!(resets.len(), seen + 1, "{board}: two resets in sample {i}");
            let reset = &resets[seen];
            assert_eq!(reset.sample, i, "{board}: {reset:?}");
            assert!(
                (tick..=next).contains(&reset.cycle),
                "{board} sample {i} (ticks {tick}–{next}): {reset:?}"
            );
            seen += 1;
        }
        for (c, (&cycles, &bound)) in out[i as usize].core_cycles.iter().zip(&bounds).enumerate() {
            assert!(
                cycles <= bound,
                "{board} sample {i} core {c}: {cycles} cycles, static bound {bound}"
            );
        }
    }
    let resets = r.resets().to_vec();
    assert!(resets.len() >= 4, "{board}: {resets:?}");
    // The first reset one period after the hang's sample (it hangs at its tick; the last
    // feed came at the end of core 0's handler of the sample before, or of this one).
    let first = resets[0].sample;
    assert!(
        (from + period - 1..=from + period + 1).contains(&first),
        "{board}: hung at sample {from}, reset at {first} (period {period} samples)"
    );
    // Each next: the boot's zero samples, its first sample (where the key hangs again),
    // and a period.
    for w in resets.windows(2) {
        let zero = *w[0].reboot.as_ref().unwrap();
        let hangs = w[0].sample + zero + 1;
        assert!(
            (hangs + period - 1..=hangs + period + 1).contains(&w[1].sample),
            "{board}: {:?} then {:?}",
            w[0],
            w[1]
        );
    }
    // Between the hang and the reset the hung core's drives hold the codes of the sample
    // before the hang; the other core's keys play on (held still: their codes of before).
    for i in from as usize..first as usize {
        assert_eq!(out[i].dac, out[from as usize - 1].dac, "{board} sample {i}");
    }
    // The hung core's samples from each hang to its reset are unfinished; the other's none.
    let unfinished = r.unfinished().to_vec();
    let mut late = first - from;
    for w in resets.windows(2) {
        late += w[1].sample - (w[0].sample + w[0].reboot.as_ref().unwrap() + 1);
    }
    // And from the last boot's first sample, hung again, to the run's end.
    let last = resets.last().unwrap();
    late += n as u64 - (last.sample + last.reboot.as_ref().unwrap() + 1);
    assert_eq!(unfinished[core], late, "{board}: {unfinished:?}");
    assert_eq!(unfinished[1 - core], 0, "{board}: {unfinished:?}");
}

#[test]
fn a_hang_for_good_resets_a_plain_board_at_the_runs_samples() {
    a_hang_for_good_resets_at_the_runs_samples("rp2040", 0);
}

#[test]
fn a_hang_for_good_resets_a_converter_board_at_the_runs_samples() {
    a_hang_for_good_resets_at_the_runs_samples("rp2040_io", 2);
}
