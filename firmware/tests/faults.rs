//! Faults injected into a running board (`ImageRun::inject`, `image/run/inject.rs`): a
//! faulted run is the same on the lock-step machine and on the block engine with its
//! memos, windows and the rest replay, and each fault changes what it says it changes.

use tactus_compiler::fixed::interp::FixedInstance;
use tactus_emulator::Engine;
use tactus_firmware::flash::Load;
use tactus_firmware::image::{FaultKind, FirmwareImage, ImageRun, Injection};

#[path = "common/layouts.rs"]
mod layouts;
use layouts::{firmware, firmware_with};

fn faults(io: bool) -> Vec<Injection> {
    let f = |kind, key, core, from, until| Injection {
        kind,
        key,
        core,
        from,
        until,
    };
    vec![
        f(FaultKind::Stuck(20_000), Some(0), None, 100, Some(400)),
        f(FaultKind::Noise(300), Some(1), None, 150, Some(300)),
        f(FaultKind::Jump(6_000), Some(2), None, 500, Some(700)),
        f(
            FaultKind::Flip { word: 0, bit: 20 },
            Some(1),
            None,
            800,
            None,
        ),
        // Key 5's escapement mode byte to 8 + its mode, no variant: with the sensor check,
        // its state check trips the key (`state-range`) at its next check.
        f(
            FaultKind::Flip { word: 0, bit: 3 },
            Some(5),
            None,
            600,
            None,
        ),
        // Key 4's ring position (byte 8 of its state, word 2's low byte) to no multiple of
        // 4: its next update's ring store is unaligned, a HardFault, whose handler resets
        // the board at once (the watchdog's trigger); it boots again before the faults
        // after it.
        f(FaultKind::Flip { word: 2, bit: 0 }, Some(4), None, 50, None),
        f(FaultKind::Open, Some(0), None, 900, Some(1000)),
        f(FaultKind::Short, Some(3), None, 950, Some(1050)),
        f(FaultKind::AdcSilent, None, Some(1), 1100, Some(1200)),
        f(FaultKind::DacStall, None, Some(0), 1250, Some(1350)),
    ]
    .into_iter()
    // A converter board's ADC without DREQ: its state machine stopped and started again.
    .chain(io.then(|| f(FaultKind::AdcNoDreq, None, Some(1), 1380, Some(1450))))
    .collect()
}

/// `image` run `samples` samples at rest on `engine` (the rest replay on when `rest`), with
/// the faults or without: every sample's outputs.
fn run(
    image: &FirmwareImage,
    engine: Engine,
    rest: bool,
    faulted: bool,
    samples: usize,
) -> Vec<tactus_firmware::image::SampleOut> {
    let list = if faulted {
        faults(image.io().is_some())
    } else {
        Vec::new()
    };
    run_with(image, engine, rest, &list, samples).0
}

/// `image` run `samples` samples at rest on `engine` (the rest replay on when `rest`) with
/// the faults `list`: every sample's outputs, and the run.
fn run_with(
    image: &FirmwareImage,
    engine: Engine,
    rest: bool,
    list: &[Injection],
    samples: usize,
) -> (Vec<tactus_firmware::image::SampleOut>, ImageRun) {
    let mut r: ImageRun = image.run().unwrap();
    r.board().config.engine = engine;
    r.set_rest_replay(rest).unwrap();
    for f in list {
        r.inject(*f).unwrap();
    }
    let words = rest_words(image);
    let outs = (0..samples)
        .map(|_| r.step(&words).unwrap().clone())
        .collect();
    r.settle().unwrap();
    (outs, r)
}

fn check(kind: Option<&str>, sensor_check: bool) {
    let layout = "instruments/layouts/grand88.toml";
    let (boards, _) = firmware_with(layout, kind, Load::Ram, Some(sensor_check));
    let image = &boards[0].image;
    assert!(image.keys().len() >= 6);
    let n = 1_500;
    let reference = run(image, Engine::LockStep, false, true, n);
    let fast = run(image, Engine::Block, true, true, n);
    for (i, (a, b)) in reference.iter().zip(&fast).enumerate() {
        assert_eq!(a, b, "{kind:?}: sample {i}");
    }
    // The faults did something: the faulted run is not the clean one while they last, and
    // the stalled DAC held core 0's codes.
    let clean = run(image, Engine::Block, true, false, n);
    let differs = |r: std::ops::Range<usize>| r.clone().any(|i| reference[i] != clean[i]);
    assert!(
        differs(100..450),
        "{kind:?}: the stuck sensor changed nothing"
    );
    assert!(
        differs(900..1060),
        "{kind:?}: open and short changed nothing"
    );
    if sensor_check {
        // The short of key 3 (at rest: a jump to full scale) tripped it: its DAC code 0
        // within 1 ms and until the short ends.
        let zero = (950..1050).filter(|&i| reference[i].dac[3] == 0).count();
        assert!(zero >= 100 - 44, "{kind:?}: key 3 at 0 for {zero} samples");
        // The mode flip of key 5 (at rest, where the piano's key pushes up: a DAC code not
        // 0) tripped its state check within its class's longest gap (7 samples), its DAC
        // code 0 from then on (its recovery takes 100 ms, past the run's core-1 faults).
        for i in 607..1100 {
            assert_eq!(reference[i].dac[5], 0, "{kind:?}: sample {i}: key 5 plays");
            assert_ne!(clean[i].dac[5], 0, "{kind:?}: sample {i}: key 5 at rest");
        }
    }
    let keys0: Vec<usize> = (0..image.keys().len())
        .filter(|&k| image.keys()[k].core == 0)
        .collect();
    for i in 1250..1350 {
        for &k in &keys0 {
            assert_eq!(
                reference[i].drives[k][0].dac, reference[1249].drives[k][0].dac,
                "{kind:?}: sample {i} key {k}: the stalled DAC moved"
            );
        }
    }
}

#[test]
fn a_faulted_plain_board_runs_the_same_on_every_engine() {
    check(None, false);
}

#[test]
fn a_faulted_converter_board_runs_the_same_on_every_engine() {
    check(Some("rp2040_io"), false);
}

/// With the sensor check on: its keys take turns (grand88's boards: four classes a core,
/// `glue::Turns`), the faults trip them, and the trip paths and the gated limiters run the
/// same on the lock-step machine and the block engine with the rest replay.
#[test]
fn a_checked_board_trips_the_same_on_every_engine() {
    check(None, true);
    check(Some("rp2040_io"), true);
}

#[test]
fn a_fault_outside_the_board_is_refused_with_its_field() {
    let (boards, _) = firmware("instruments/layouts/grand88.toml", None, Load::Ram);
    let mut r = boards[0].image.run().unwrap();
    let keys = boards[0].image.keys().len();
    let bad = |kind, key, core| Injection {
        kind,
        key,
        core,
        from: 0,
        until: None,
    };
    let e = r
        .inject(bad(FaultKind::Open, Some(keys), None))
        .unwrap_err();
    assert!(e.contains("`key`"), "{e}");
    let e = r
        .inject(bad(FaultKind::AdcSilent, None, Some(2)))
        .unwrap_err();
    assert!(e.contains("`core`"), "{e}");
    let e = r
        .inject(bad(
            FaultKind::Flip {
                word: 1 << 20,
                bit: 3,
            },
            Some(0),
            None,
        ))
        .unwrap_err();
    assert!(e.contains("`word`"), "{e}");
}

/// Every key's sensor words at rest (position 0), in key-list order: what [`ImageRun::step`]
/// takes for a board whose keys are not played.
fn rest_words(image: &FirmwareImage) -> Vec<i32> {
    let programs = image.programs();
    (image.keys().iter())
        .map(|k| FixedInstance::sensor_raw(&programs[k.program].fixed, 0, Some(0.0)))
        .collect()
}

/// The DAC code the image's current limiter never exceeds (its peak).
fn peak_code(image: &FirmwareImage) -> i32 {
    tactus_runtime::limiter::Limiter::new(image.limiter_config())
        .unwrap()
        .constants()
        .peak_code
}

/// A flipped bit in a key's state words (`FaultKind::Flip`) that leaves every mode byte a
/// variant is not detected (the state check tests the mode bytes alone: docs/firmware.md,
/// "Faults"; these flips, on the shipped firmware, hit edges, the ring's position within
/// the struct and states); what holds instead: every DAC code of every sample
/// stays within the limiter's peak, and the keys whose state was not hit play exactly as
/// without the flips.
fn flips_stay_under_the_peak(kind: Option<&str>) {
    let (boards, _) = firmware("instruments/layouts/grand88.toml", kind, Load::Ram);
    let image = &boards[0].image;
    let peak = peak_code(image);
    let programs = image.programs();
    let n = 600;
    // Keys 0 and 4 (one per core) take flips in low, middle and sign bits of their first
    // words while at rest, then pressed half-way (the limiter at work either way).
    let flips: Vec<Injection> = [
        (0, 0, 31, 50),
        (0, 1, 20, 120),
        (0, 2, 5, 200),
        (4, 0, 30, 60),
    ]
    .iter()
    .chain(&[(4, 3, 31, 250), (4, 1, 12, 400)])
    .map(|&(key, word, bit, from)| Injection {
        kind: FaultKind::Flip { word, bit },
        key: Some(key),
        core: None,
        from,
        until: None,
    })
    .collect();
    let words = |i: usize| -> Vec<i32> {
        (image.keys().iter())
            .map(|k| {
                let f = &programs[k.program].fixed;
                let (lo, hi) = f.sensor_raw_range[0];
                if i < 300 {
                    lo
                } else {
                    lo + (hi - lo) / 2
                }
            })
            .collect()
    };
    let mut clean = image.run().unwrap();
    let mut hit = image.run().unwrap();
    for f in &flips {
        hit.inject(*f).unwrap();
    }
    let mut changed = 0;
    for i in 0..n {
        let want = clean.step(&words(i)).unwrap().clone();
        let got = hit.step(&words(i)).unwrap().clone();
        changed += usize::from(got.drives != want.drives);
        for (k, d) in got.drives.iter().enumerate() {
            let code = i32::from(d[0].dac).abs();
            assert!(
                code <= peak,
                "{kind:?} sample {i} key {k}: DAC {code} > peak {peak}"
            );
            if k != 0 && k != 4 {
                assert_eq!(d, &want.drives[k], "{kind:?} sample {i} key {k}");
            }
        }
    }
    // The flips reached the hit keys' outputs (else this shows nothing).
    assert!(changed > 0, "{kind:?}: no flip changed an output");
    eprintln!("{kind:?}: {changed} of {n} samples differ from the clean run");
}

#[test]
fn flipped_state_bits_stay_under_the_limiters_peak() {
    flips_stay_under_the_peak(None);
    flips_stay_under_the_peak(Some("rp2040_io"));
}

/// A flip of bit 0 or 1 of a key's ring position (byte 8 of the grand piano's state, word
/// 2's low byte) leaves it no multiple of 4: the key's next update stores its reading
/// unaligned, a HardFault on its core. The core's HardFault handler records a `hard-fault`
/// trip and resets the board at once through the watchdog's trigger (docs/firmware.md,
/// "Faults"): on grand88's first board at rest (every key's update runs every sample),
/// for a key of each core, on a plain and a converter board,
/// - the reset comes in the flip's own sample (`watchdog trigger`), within
///   [`HARD_FAULT_CYCLES`] cycles of the handler's entry (measured against the same run
///   stopped at the fault);
/// - every motor at DAC code 0 from that sample until the board's sample loop runs again
///   (the boot's samples), never a code above the limiter's peak;
/// - the fault record of the key's core names it: kind `hard-fault`, the key's window slot
///   (the return slot's call site), one trip, the reset word's REASON.FORCE; the other
///   core's record untouched;
/// - the board plays again as from power-on: from its new boot's first sample every
///   key's outputs are the clean run's from its first (keys at rest, from rest);
/// - the lock-step machine and the block engine with the rest replay give the same samples.
///
/// Without the handler (`B .`) the core would hang until the watchdog's count ran out,
/// 40–45 samples later (a `watchdog timer` reset, kind `watchdog`), its motors at their
/// last codes meanwhile.
#[test]
fn a_flipped_low_bit_of_the_ring_position_resets_the_board_at_once() {
    use tactus_firmware::image::fault::{FaultKind as Trip, FaultWord, ResetCause};
    use tactus_firmware::image::glue::ctrl;
    for kind in [None, Some("rp2040_io")] {
        let (boards, _) = firmware("instruments/layouts/grand88.toml", kind, Load::Ram);
        let image = &boards[0].image;
        let peak = peak_code(image);
        let n = 500;
        let at = 100u64;
        let (clean, _) = run_with(image, Engine::Block, true, &[], n);
        let specs = image.keys();
        let first_of = |c: usize| specs.iter().position(|k| k.core == c).unwrap();
        for (key, bit) in [(first_of(0), 0u8), (first_of(1), 1)] {
            let case = format!("{kind:?}, key {key}, bit {bit}");
            let flip = [Injection {
                kind: FaultKind::Flip { word: 2, bit },
                key: Some(key),
                core: None,
                from: at,
                until: None,
            }];
            let (outs, mut r) = run_with(image, Engine::LockStep, false, &flip, n);
            let (fast, _) = run_with(image, Engine::Block, true, &flip, n);
            assert_eq!(outs, fast, "{case}: the engines differ");
            let resets = r.resets().to_vec();
            assert_eq!(resets.len(), 1, "{case}: {resets:?}");
            let reset = &resets[0];
            assert_eq!(
                (reset.sample, reset.why),
                (at, "watchdog trigger"),
                "{case}: {reset:?}"
            );
            let zero = *reset.reboot.as_ref().unwrap();
            // The reset's own sample and `zero` more at zero force, then the new boot's.
            let (from, back) = (at as usize, (at + zero + 1) as usize);
            assert!(zero <= 10, "{case}: {zero} samples booting");
            assert_eq!(outs[..from], clean[..from], "{case}: before the flip");
            for (i, o) in outs.iter().enumerate() {
                for d in o.drives.iter().flatten() {
                    assert!(i32::from(d.dac).abs() <= peak, "{case}: sample {i}: {d:?}");
                    if (from..back).contains(&i) {
                        assert_eq!(d.dac, 0, "{case}: sample {i}: not at zero");
                    }
                }
            }
            assert!(
                outs[back].drives.iter().flatten().any(|d| d.dac != 0),
                "{case}: the board does not play after its boot"
            );
            // The new boot plays as the board did from power-on: every key from rest, the
            // same sensor words, so its samples' drives are the clean run's first ones.
            for (i, o) in outs[back..].iter().enumerate() {
                assert_eq!(o.drives, clean[i].drives, "{case}: boot sample {i}");
            }
            // The fault records.
            let core = specs[key].core;
            for c in 0..image.cores() {
                let control = image.core_addresses(c).unwrap()[3];
                let mut at_word = |o: u32| r.board().read_u32(ctrl::fault_record(control) + o);
                let record = [at_word(0), at_word(4), at_word(8)].map(Result::unwrap);
                let w = FaultWord::decode_record(record);
                if c == core {
                    assert_eq!(w.kind, Some(Trip::HardFault), "{case}: {w:?}");
                    assert_eq!(usize::from(w.key), specs[key].slot, "{case}: {w:?}");
                    assert_eq!(w.trips, 1, "{case}: {w:?}");
                    assert_eq!(w.at_sample as u64, at, "{case}: {w:?}");
                } else {
                    assert!(!w.tripped(), "{case}: core {c}: {w:?}");
                }
                assert_eq!(w.reset_cause(), ResetCause::Watchdog, "{case}: {w:?}");
                assert_eq!(
                    w.reset_word & tactus_rp2040::watchdog::REASON_FORCE,
                    tactus_rp2040::watchdog::REASON_FORCE,
                    "{case}: {w:?}"
                );
            }
            // From the fault's exception to the reset: the same run, stopped at the fault.
            let mut stopped: ImageRun = image.run().unwrap();
            stopped.inject(flip[0]).unwrap();
            stopped.board().config.stop_on_fault = true;
            let words = rest_words(image);
            let e = (0..=at)
                .find_map(|_| stopped.step(&words).err())
                .unwrap_or_else(|| panic!("{case}: no HardFault"));
            assert!(
                e.to_string().contains(&format!("core {core} HardFault")),
                "{case}: {e}"
            );
            let faulted = stopped.board().cores[core].cycle;
            let cycles = reset.cycle - faulted;
            eprintln!(
                "{case}: reset {cycles} cycles ({:.3} µs) after the fault's exception",
                cycles as f64 * 1e6 / stopped.board().config.clock_hz as f64
            );
            assert!(cycles <= HARD_FAULT_CYCLES, "{case}: {cycles} cycles");
        }
    }
}

/// The most cycles from the HardFault handler's first instruction (the exception's 15
/// cycles of entry done) to the board's reset (`glue::checks::hard_fault_handler`: its
/// literals, loads, four stores and the trigger's APB store, then the other core's
/// instruction under way): 35 measured, so with the entry about 50 cycles, 0.38 µs at
/// 133 MHz, from the faulting store to the reset.
const HARD_FAULT_CYCLES: u64 = 50;
