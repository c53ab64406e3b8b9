//! The firmware's watchdog (`Program::watchdog`; `image/fault.rs`, "The watchdog"): a hung
//! update on either core stops core 0's feeds, the watchdog resets the board within its
//! period, the board boots again from flash with its DACs at zero meanwhile, the fault
//! word says so, and the key plays again — on a board without converters and on one with
//! them, the same on the lock-step machine and on the block engine with the rest replay.

#[path = "common/layouts.rs"]
mod layouts;

use tactus_compiler::lower::Config;
use tactus_emulator::Engine;
use tactus_firmware::image::fault::{FaultKind, FaultWord, NO_KEY, WATCHDOG_PERIOD_US};
use tactus_firmware::image::glue::ctrl;
use tactus_firmware::image::{
    self, FirmwareImage, ImageRun, Injection, KeySpec, Program, SampleOut,
};
use tactus_runtime::limiter::LimiterConfig;

/// A position-sensed key whose force is its spring: a DAC code that is not 0 at mid-travel.
const SPRING: &str =
    "instrument spring {\n sensor key: m in [0 mm, 10 mm]\n force out = 300 N/m * key + 0.2 N\n}\n";

/// Keys 0 and 1 on core 0, key 2 on core 1, the watchdog on.
fn image(board: &str, watchdog: bool) -> FirmwareImage {
    let mut p = Program::compile(SPRING, &Config::default()).unwrap();
    p.watchdog = watchdog;
    // Every update runs (the quiescent-key guard would skip a held key's, hung or not).
    p.quiescent_guard = false;
    let keys: Vec<KeySpec> = [(60, 0), (61, 0), (62, 1)]
        .iter()
        .map(|&(slot, core)| KeySpec {
            slot,
            program: 0,
            core,
        })
        .collect();
    let board = layouts::shipped_board(board);
    FirmwareImage::build(
        std::slice::from_ref(&p),
        &keys,
        &board,
        &LimiterConfig::default(),
    )
    .unwrap()
}

/// Core `core`'s fault record.
fn fault(run: &mut ImageRun, image: &FirmwareImage, core: usize) -> FaultWord {
    let ctrl_addr = image.core_addresses(core).unwrap()[3];
    let b = run.board();
    let w = b.read_u32(ctrl_addr + u32::from(ctrl::FAULT)).unwrap();
    let at = b.read_u32(ctrl_addr + u32::from(ctrl::FAULT_AT)).unwrap();
    FaultWord::decode(w, at)
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
fn the_watchdog_costs_core_0_its_feed_and_nothing_on_core_1() {
    for board in ["rp2040", "rp2040_io"] {
        let (off, on) = (image(board, false), image(board, true));
        let (w0, w1) = (on.wcet(0).unwrap(), on.wcet(1).unwrap());
        assert_eq!(w1.bound(), off.wcet(1).unwrap().bound(), "{board}");
        let extra = w0.bound() - off.wcet(0).unwrap().bound();
        assert!(
            extra > 0 && extra <= 18,
            "{board}: the feed costs {extra} cycles"
        );
    }
}
