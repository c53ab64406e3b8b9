//! The sensor check of the firmware (docs/firmware.md, "Faults"), driven in the emulator
//! with implausible sensor words: a short (full scale) or an open (0) that jumps mid-travel
//! sets the key's DAC word to zero in the sample it arrives, the core's fault word names the
//! key and the kind, the other keys play on bit for bit, and the key plays again after
//! the stated time of plausible readings — on a board without converters and on one with
//! them (`rp2040_io`, where the word is made of the ADC code).

#[path = "common/layouts.rs"]
mod layouts;
#[path = "common/spring.rs"]
mod spring;
use spring::{fault, turns_image};

use tactus_firmware::image::fault::{recovery_samples, FaultKind};
use tactus_firmware::image::{FaultKind as InjKind, FirmwareImage, ImageRun, Injection, Program};
use tactus_runtime::limiter::LimiterConfig;

fn image(board: &str) -> (Program, FirmwareImage) {
    let mut p = spring::spring();
    p.sensor_check = true;
    let image = spring::three_keys(&p, board);
    (p, image)
}

/// Runs a fault of key 0 (word `bad` from sample `from` for `len` samples) against the same
/// run without it; checks the bound, the fault word, the other keys and the recovery.
fn trip_and_recover(board: &str, bad: i32, kind: FaultKind) {
    let (p, image) = image(board);
    let (lo, hi) = p.fixed.sensor_raw_range[0];
    let mid = lo + (hi - lo) / 2;
    let quarter = lo + (hi - lo) / 4;
    let rec = recovery_samples(44_100.0) as usize;
    let (from, len) = (200usize, 100usize);
    let total = from + len + rec + 300;
    // Key 0 goes down to mid-travel and stays; keys 1 and 2 go down and up slowly
    // (12.5 µm a sample, below the bound).
    let _ = quarter;
    let slow = |n: usize| {
        let t = (n % 800) as i64;
        let tri = if t < 400 { t } else { 800 - t };
        lo + ((mid - lo) as i64 * tri / 400) as i32
    };
    let words = |n: usize, faulty: bool| {
        let k0 = if faulty && (from..from + len).contains(&n) {
            bad
        } else if n < from {
            lo + ((mid - lo) as i64 * n as i64 / from as i64) as i32
        } else {
            mid
        };
        vec![k0, slow(n), slow(n)]
    };
    let mut clean = image.run().unwrap();
    let mut run = image.run().unwrap();
    // The converters' pipeline: a word the ADC samples in period n reaches the handler of
    // tick n + 1 (`d` = 1); without converters the handler of tick n reads it (`d` = 0).
    let mut d = None;
    for n in 0..total {
        let w = clean.step(&words(n, false)).unwrap();
        let (want, want_force) = (w.dac.clone(), w.force[0]);
        let g = run.step(&words(n, true)).unwrap();
        let (got, got_force) = (g.dac.clone(), g.force[0]);
        if n >= from {
            assert_ne!(want[0], 0, "the spring's force is not 0 at mid-travel");
        }
        assert_eq!(
            got[1..],
            want[1..],
            "{board} sample {n}: the other keys play on"
        );
        if d.is_none() && got[0] != want[0] {
            assert!(n == from || n == from + 1, "{board}: first trip at {n}");
            d = Some(n - from);
        }
        let shift = d.unwrap_or(0);
        let tripped = d.is_some() && (from + shift..from + shift + len + 1 + rec).contains(&n);
        if tripped {
            assert_eq!(
                got[0], 0,
                "{board} sample {n}: key 0 tripped, its DAC word 0"
            );
        } else if d.is_none() {
            assert_eq!(got[0], want[0], "{board} sample {n}: key 0 plays");
        } else {
            // Back in the model: its force as the clean run's; its DAC code may be above
            // the clean run's, the limiter's time budget having recovered meanwhile.
            assert_eq!(
                got_force, want_force,
                "{board} sample {n}: key 0 plays again"
            );
            assert!(got[0] >= want[0] && want[0] > 0, "{board} sample {n}");
        }
    }
    let d = d.expect("the fault tripped") as u32;
    let f = fault(&mut run, &image, 0);
    assert_eq!(f.kind, Some(kind), "{board}: {f:?}");
    // One trip for the whole fault, however long; the sample it came in.
    assert_eq!(
        (f.key, f.trips, f.at_sample),
        (60, 1, from as u32 + d),
        "{f:?}"
    );
    assert!(!fault(&mut run, &image, 1).tripped());
    assert!(!fault(&mut clean, &image, 0).tripped());
}

#[test]
fn a_short_mid_travel_trips_within_the_sample_and_recovers() {
    // The window word at full scale: out of the sensor's range.
    trip_and_recover("rp2040", i32::MAX, FaultKind::SensorRange);
}

#[test]
fn an_open_wire_mid_travel_trips_as_a_jump() {
    // Code 0 is the key at rest: in range, but 5 mm away in one sample.
    trip_and_recover("rp2040", 0, FaultKind::SensorRate);
}

#[test]
fn a_converter_board_trips_on_its_adc_codes() {
    // Full scale and 0 reach the firmware as ADC codes made words; 0 is a jump again.
    trip_and_recover("rp2040_io", 0, FaultKind::SensorRate);
}

#[test]
fn a_key_held_down_at_power_on_plays_from_the_first_sample() {
    // A key's first reading in range is taken as it stands and its update runs on it
    // (`SensorCheck::seed`): a key away from rest at the start is no fault, and the
    // checked board is the unchecked one from the first sample. On a converter board the
    // first reading is the start handler's ADC burst: `FirmwareImage::run_from` sets the
    // ADC's codes before the boot, as a real board's keys stand at power-on
    // (`FirmwareImage::run`'s ADC reads 0 there, the key at rest, and the held key jumps
    // at the first step: a trip, below).
    for board in ["rp2040", "rp2040_io"] {
        let (p, image) = image(board);
        let mut plain = p.clone();
        plain.sensor_check = false;
        let unchecked = FirmwareImage::build(
            std::slice::from_ref(&plain),
            &image.keys(),
            &layouts::shipped_board(board),
            &LimiterConfig::default(),
        )
        .unwrap();
        let (lo, hi) = p.fixed.sensor_raw_range[0];
        // Key 0 held at 3/4 of its travel, key 1 at the bottom, key 2 at rest.
        let words = [lo + (hi - lo) / 4 * 3, hi, lo];
        let mut run = image.run_from(&words).unwrap();
        let mut reference = unchecked.run_from(&words).unwrap();
        for n in 0..50 {
            let got = run.step(&words).unwrap().clone();
            let want = reference.step(&words).unwrap().clone();
            assert_eq!(
                (&got.force, &got.dac),
                (&want.force, &want.dac),
                "{board} sample {n}"
            );
            if n == 0 {
                // Not trivially equal: the held keys push back from the first sample.
                assert!(got.force[..2].iter().all(|&f| f != 0), "{board}: {got:?}");
            }
        }
        for core in 0..2 {
            let f = fault(&mut run, &image, core);
            assert!(!f.tripped(), "{board} core {core}: {f:?}");
        }
        // Booted with the keys at rest instead, the converter board's held keys jump at
        // the first step: core 0's check sees it.
        let mut run = image.run().unwrap();
        for _ in 0..50 {
            run.step(&words).unwrap();
        }
        let f = fault(&mut run, &image, 0);
        assert_eq!(f.tripped(), board == "rp2040_io", "{board}: {f:?}");
    }
}

/// One injected fault (`ImageRun::inject`) on key 0 (or core 0) of the spring image with
/// the check, from flash, against the clean run; `want` the kind the fault word must show
/// (`None`: a fault no check sees). Checks the bound (the affected drives at DAC code 0
/// within 1 ms of the fault's start, while it lasts), never a code above the limiter's
/// peak, the keys the fault does not reach unchanged, the fault word, and the recovery
/// (the forces the clean run's again once the fault has cleared and 100 ms passed).
fn injected(board: &str, kind: InjKind, want: Option<FaultKind>) {
    let (p, image) = image(board);
    injected_on(&p, &image, board, kind, want, 0);
}

/// [`injected`] on key `target` of `image` (keys of program `p`).
fn injected_on(
    p: &Program,
    image: &FirmwareImage,
    board: &str,
    kind: InjKind,
    want: Option<FaultKind>,
    target: usize,
) {
    let peak = tactus_runtime::limiter::Limiter::new(image.limiter_config())
        .unwrap()
        .constants()
        .peak_code;
    let nk = image.keys().len();
    let (lo, hi) = p.fixed.sensor_raw_range[0];
    let mid = lo + (hi - lo) / 2;
    let rec = recovery_samples(44_100.0) as u64;
    let (from, until) = (200u64, 300u64);
    // The recovery counts checks: 100 ms within one period of the tick's accumulator (63
    // samples at 133 MHz) after the first check that reads the cleared sensor.
    let total = until + rec + 250;
    // Keys at rest, down to mid-travel slowly (below the bound) by sample 100, held.
    let words = |n: u64| {
        let w = lo + ((mid - lo) as i64 * n.min(100) as i64 / 100) as i32;
        vec![w; nk]
    };
    let core_wide = matches!(kind, InjKind::AdcSilent);
    let core = image.keys()[target].core;
    let flash = image.flash_image().unwrap().bytes;
    let mut clean = ImageRun::from_flash(image, &flash).unwrap();
    let mut run = ImageRun::from_flash(image, &flash).unwrap();
    run.inject(Injection {
        kind,
        key: (!core_wide).then_some(target),
        core: core_wide.then_some(core),
        from,
        until: Some(until),
    })
    .unwrap();
    // The keys the fault reaches: the target, and with the core's ADC its core's keys.
    let reached = |k: usize| k == target || (core_wide && image.keys()[k].core == core);
    let mut zero_by = None;
    for n in 0..total {
        let want_s = clean.step(&words(n)).unwrap().clone();
        let got = run.step(&words(n)).unwrap().clone();
        for (k, d) in got.drives.iter().enumerate() {
            let code = i32::from(d[0].dac).abs();
            assert!(
                code <= peak,
                "{board} {kind:?} sample {n} key {k}: {code} > {peak}"
            );
            if !reached(k) {
                assert_eq!(d, &want_s.drives[k], "{board} {kind:?} sample {n} key {k}");
            }
        }
        if want.is_some() && (from..until).contains(&n) {
            let zero = (0..nk).filter(|&k| reached(k)).all(|k| got.dac[k] == 0);
            match (zero_by, zero) {
                (None, true) => zero_by = Some(n),
                (Some(_), false) => {
                    panic!("{board} {kind:?} sample {n}: a tripped key's DAC moved")
                }
                _ => {}
            }
        }
        if n >= until + rec + 200 || n < from {
            assert_eq!(
                got.force, want_s.force,
                "{board} {kind:?} sample {n}: plays"
            );
        }
    }
    let f = fault(&mut run, image, core);
    let slot = |k: usize| image.keys()[k].slot as u8;
    match want {
        Some(kind_want) => {
            let by = zero_by.expect("the fault set the motors to zero") - from;
            // 1 ms at 44.1 kHz.
            assert!(by <= 44, "{board} {kind:?}: zero after {by} samples");
            // A noise burst may show out of range at the check that catches it.
            let kinds = match kind {
                InjKind::Noise(_) => vec![kind_want, FaultKind::SensorRange],
                _ => vec![kind_want],
            };
            assert!(
                f.kind.is_some_and(|k| kinds.contains(&k)),
                "{board} {kind:?}: {f:?}"
            );
            // A trip per key reached, the word naming the last to trip.
            let hit: Vec<usize> = (0..nk).filter(|&k| reached(k)).collect();
            assert_eq!(usize::from(f.trips), hit.len(), "{board} {kind:?}: {f:?}");
            assert!(
                hit.iter().any(|&k| slot(k) == f.key),
                "{board} {kind:?}: {f:?}"
            );
            if nk == 3 {
                // Every sample checks every key, in key order: the last is key 1.
                let key = if core_wide { 61 } else { 60 };
                assert_eq!(f.key, key, "{board} {kind:?}: {f:?}");
            }
        }
        None => assert!(!f.tripped(), "{board} {kind:?}: {f:?}"),
    }
}

#[test]
fn keys_taking_turns_trip_within_1_ms_and_recover_on_both_boards() {
    for board in ["rp2040", "rp2040_io"] {
        let (p, image) = turns_image(board);
        let turns = image.check_turns(0).unwrap();
        assert_eq!(turns.classes, 4, "{board}: {turns:?}");
        assert_eq!(image.check_turns(1).unwrap().classes, 1, "{board}");
        // Each of core 0's keys (the fourth class has the longest gap), and core 1's.
        for target in [0, 3, 4] {
            let on = |kind, want| injected_on(&p, &image, board, kind, want, target);
            on(InjKind::Short, Some(FaultKind::SensorRange));
            on(InjKind::Open, Some(FaultKind::SensorRate));
            on(InjKind::Jump(20_000), Some(FaultKind::SensorRate));
            on(InjKind::Noise(30_000), Some(FaultKind::SensorRate));
            on(InjKind::Stuck(5_000), Some(FaultKind::SensorRate));
        }
        injected_on(
            &p,
            &image,
            board,
            InjKind::AdcSilent,
            Some(FaultKind::SensorRange),
            0,
        );
        let (lo, hi) = p.fixed.sensor_raw_range[0];
        let scale = tactus_runtime::converters::AdcScale::new(lo, hi, 16);
        let held = scale.code(lo + (hi - lo) / 2) as u16;
        injected_on(&p, &image, board, InjKind::Stuck(held), None, 3);
        injected_on(&p, &image, board, InjKind::Jump(100), None, 3);
    }
}

#[test]
fn every_sensor_fault_kind_trips_bounded_and_recovers_on_both_boards() {
    for board in ["rp2040", "rp2040_io"] {
        injected(board, InjKind::Short, Some(FaultKind::SensorRange));
        injected(board, InjKind::Open, Some(FaultKind::SensorRate));
        injected(board, InjKind::Jump(20_000), Some(FaultKind::SensorRate));
        injected(board, InjKind::Noise(30_000), Some(FaultKind::SensorRate));
        injected(board, InjKind::Stuck(5_000), Some(FaultKind::SensorRate));
        injected(board, InjKind::AdcSilent, Some(FaultKind::SensorRange));
        // Stuck where the key is (mid-travel): a key held still, no fault.
        let (p, _) = image(board);
        let (lo, hi) = p.fixed.sensor_raw_range[0];
        let scale = tactus_runtime::converters::AdcScale::new(lo, hi, 16);
        let held = scale.code(lo + (hi - lo) / 2) as u16;
        injected(board, InjKind::Stuck(held), None);
        // A small jump within the bound: a key moving, no fault, never above the peak.
        injected(board, InjKind::Jump(100), None);
    }
}
