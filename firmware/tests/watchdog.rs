//! The firmware's watchdog (`Program::watchdog`; `image/fault.rs`, "The watchdog"): a hung
//! update on either core stops core 0's feeds, the watchdog resets the board within its
//! period, the board boots again from flash with its DACs at zero meanwhile, the fault
//! word says so, and the key plays again — on a board without converters and on one with
//! them, the same on the lock-step machine and on the block engine with the rest replay.

#[path = "common/layouts.rs"]
mod layouts;
#[path = "common/spring.rs"]
mod spring;
use spring::fault;

use tactus_emulator::Engine;
use tactus_firmware::image::fault::{FaultKind, NO_KEY, WATCHDOG_PERIOD_US};
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
fn run(
    image: &FirmwareImage,
    engine: Engine,
    hung: Option<usize>,
    from: u64,
    samples: usize,
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
    let p = &image.programs()[0];
    let (lo, hi) = p.fixed.sensor_raw_range[0];
    let words = vec![lo + (hi - lo) / 2; 3];
    let at = r.tick_cycle(from);
    let out = (0..samples)
        .map(|_| r.step(&words).unwrap().clone())
        .collect();
    (out, r, at)
}

fn hang_resets_and_recovers(board: &str, key: usize) {
    let image = image(board, true);
    let (from, n) = (100u64, 200usize);
    let (clean, ..) = run(&image, Engine::LockStep, None, from, n);
    let (out, mut r, hang_cycle) = run(&image, Engine::LockStep, Some(key), from, n);
    // A healthy board is fed every sample: the clean run never resets.
    assert!(clean.iter().all(|s| s.dac.iter().all(|&d| d != 0)));
    let resets = r.resets().to_vec();
    assert_eq!(resets.len(), 1, "{board}: {resets:?}");
    let reset = &resets[0];
    assert_eq!(reset.why, "watchdog timer");
    // Within the period of the last feed, which came at the latest at the end of core 0's
    // handler of the hang's sample (core 1's count one behind its own: core 1 may still be
    // finishing it): 1 ms and a sample from the hang's tick at most, and more than 1 ms
    // less a sample (no feed came later).
    let (period, sample) = (133_000 * u64::from(WATCHDOG_PERIOD_US) / 1000, 3016);
    let after = reset.cycle.saturating_sub(hang_cycle);
    assert!(
        after > period - sample && after <= period + sample,
        "{board}: reset {after} cycles after the hang's tick (period {period})"
    );
    let zero = *reset
        .reboot
        .as_ref()
        .expect("the board boots again from flash");
    let (at, back) = (reset.sample as usize, reset.sample as usize + zero as usize);
    assert!(back + 20 < n, "{board}: back at sample {back}");
    for (i, s) in out.iter().enumerate() {
        if i < from as usize {
            assert_eq!(s, &clean[i], "{board} sample {i}: before the hang");
        } else if (at..back).contains(&i) {
            assert!(
                s.dac.iter().all(|&d| d == 0),
                "{board} sample {i}: rebooting"
            );
        } else if i >= back + 2 {
            // Playing again: every key's force is the clean run's.
            assert_eq!(s.force, clean[i].force, "{board} sample {i}: plays again");
        }
    }
    // The keys the hang does not reach play on until the reset.
    let core = image.keys()[key].core;
    for i in from as usize..at {
        for k in (0..3).filter(|&k| image.keys()[k].core != core) {
            assert_eq!(out[i].dac[k], clean[i].dac[k], "{board} sample {i} key {k}");
        }
    }
    let f = fault(&mut r, &image, 0);
    assert_eq!(
        (f.kind, f.key, f.trips, f.at_sample),
        (Some(FaultKind::Watchdog), NO_KEY, 1, 0),
        "{board}: {f:?}"
    );
    // The engines agree through the hang, the reset and the reboot.
    let (fast, ..) = run(&image, Engine::Block, Some(key), from, n);
    for (i, (a, b)) in out.iter().zip(&fast).enumerate() {
        assert_eq!(a, b, "{board} sample {i}: lock-step vs block engine");
    }
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
        r.inject(Injection {
            kind: image::FaultKind::BrownOut,
            key: None,
            core: None,
            from: 50,
            until: None,
        })
        .unwrap();
        let p = &image.programs()[0];
        let (lo, hi) = p.fixed.sensor_raw_range[0];
        let words = vec![lo + (hi - lo) / 2; 3];
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
