//! A board with converters (`boards/rp2040_io.toml`: per core an ADS8688 and a DAC8568 on
//! the core's PIO block, frames moved by DMA; `tactus_firmware::image::io`) on the emulated
//! RP2040 with the parts at its pins (`tactus_emulator::io`):
//!
//! - the keys' positions go in as ADC codes and the firmware computes, sample for sample,
//!   what the same image without converters computes from the same positions (quantised to
//!   the ADC's codes, one sample later: a burst sampled in one period is read at the next
//!   tick), and its DAC frames reach the DAC's outputs at the tick after;
//! - every frame keeps the parts' data-sheet timing, no deadline is missed, and each core's
//!   measured handler stays within its static bound, which counts the DMA's accesses to the
//!   core's I/O bank;
//! - more keys than a part has channels is an error naming the field.

use std::path::Path;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_compiler::lower::Config;
use tactus_emulator::Engine;
use tactus_firmware::image::{io, FirmwareImage, ImageError, KeySpec, Program};
use tactus_runtime::converters::AdcScale;
use tactus_runtime::keyboard::BoardSpec;
use tactus_runtime::limiter::LimiterConfig;
use tactus_runtime::stimulus;

#[path = "common/layouts.rs"]
mod layouts;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn board(name: &str) -> BoardSpec {
    layouts::shipped_board(name)
}

fn instrument(name: &str) -> Program {
    let text = std::fs::read_to_string(root().join(format!("instruments/{name}.tactus"))).unwrap();
    Program::compile(&text, &Config::default()).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Key `i`'s sensor words: the built-in stimuli in turn, from sample `from`.
fn stimulus_words(p: &Program, i: usize, from: usize, len: usize) -> Vec<i32> {
    let names = stimulus::builtin_names();
    let s0 = &p.fixed.program.sensors[0];
    let (name, _) = names[(i + 2) % names.len()];
    let s = stimulus::builtin(name, s0.range.1, 44_100.0).unwrap();
    (from..from + len)
        .map(|n| FixedInstance::sensor_raw(&p.fixed, 0, Some(s.key[n % s.key.len()])))
        .collect()
}

/// `p` on `keys` for board `name`, with the default limiter.
fn image(p: &Program, keys: &[KeySpec], name: &str) -> FirmwareImage {
    let lim = LimiterConfig::default();
    FirmwareImage::build(std::slice::from_ref(p), keys, &board(name), &lim).unwrap()
}

/// Keys 60–64 of `program`: three on core 0, two on core 1.
fn keys() -> Vec<KeySpec> {
    (0..5)
        .map(|i| KeySpec {
            slot: 60 + i,
            program: 0,
            core: usize::from(i >= 3),
        })
        .collect()
}

#[test]
fn converters_carry_the_same_positions_in_and_codes_out() {
    // The sensor check off: the stimuli start mid-travel, and on the converter board the
    // start handler's ADC burst samples the keys before the host sets any code (at rest),
    // a jump at the first step the check would rightly trip (`fault.rs` holds a key down
    // at power-on on a board without converters).
    let mut p = instrument("harpsichord");
    p.sensor_check = false;
    let keys = keys();
    let with = image(&p, &keys, "rp2040_io");
    let without = image(&p, &keys, "rp2040");
    let plan = with.io().expect("the reference board names converters");
    assert_eq!(
        plan.cores
            .iter()
            .map(|c| (c.adc_channels(), c.dac_channels))
            .collect::<Vec<_>>(),
        [(3, 3), (2, 2)]
    );
    let (lo, hi) = p.fixed.sensor_raw_range[0];
    let scale = AdcScale::new(lo, hi, 16);
    // Samples of the stimuli from where they move (the harpsichord's plectra).
    const N: usize = 48;
    let words: Vec<Vec<i32>> = (0..keys.len())
        .map(|i| stimulus_words(&p, i, 2000 + 300 * i, N))
        .collect();
    let mut a = with.run().unwrap();
    let mut b = without.run().unwrap();
    let mut moved = 0;
    let mut sent = vec![vec![0i16; 3]; 2];
    for n in 0..N {
        let now: Vec<i32> = words.iter().map(|w| w[n]).collect();
        // Without converters the handler of tick n reads what the host wrote before it:
        // the positions the ADC sampled in the period before (n − 1), quantised; at tick 0
        // the burst the start handler started (code 0 everywhere: nothing set yet).
        let seen: Vec<i32> = words
            .iter()
            .map(|w| match n {
                0 => scale.word(0),
                _ => scale.quantise(w[n - 1]),
            })
            .collect();
        let ga = a.step(&now).unwrap().clone();
        let gb = b.step(&seen).unwrap().clone();
        assert_eq!(ga.force, gb.force, "sample {n}: the updates' forces");
        assert_eq!(ga.dac, gb.dac, "sample {n}: the limiter's codes");
        assert_eq!(ga.events, gb.events, "sample {n}");
        for k in 0..keys.len() {
            assert_eq!(a.out(k), b.out(k), "sample {n} key {k}: out words");
        }
        assert_eq!(ga.misses, vec![0, 0], "sample {n}");
        for c in 0..2 {
            let w = with.wcet(c).unwrap();
            assert_eq!(ga.handler_runs[c], 1);
            assert!(
                ga.core_cycles[c] <= w.bound(),
                "sample {n} core {c}: measured {} over the static {}",
                ga.core_cycles[c],
                w.bound()
            );
        }
        // The DAC's outputs: the frames the handler of tick n sent, the codes of sample
        // n − 1 (midscale before any).
        let io = a.board().io().unwrap();
        for (k, spec) in keys.iter().enumerate() {
            let (_, dacs) = with.channels(k).unwrap();
            let out = io.dacs[spec.core].outputs()[dacs[0] as usize];
            let ch = dacs[0] as usize;
            assert_eq!(
                out,
                (sent[spec.core][ch] as u16).wrapping_add(0x8000),
                "sample {n} key {k}"
            );
            sent[spec.core][ch] = ga.dac[k];
        }
        moved += usize::from(ga.dac.iter().any(|&d| d != 0));
    }
    assert!(
        moved > N / 4,
        "the stimuli move the motors ({moved} samples)"
    );
    // Every frame inside the parts' timing: N + 1 bursts of each core's channels.
    let io = a.board().io().unwrap();
    for (c, n) in [(0, 3), (1, 2)] {
        let adc = &io.adcs[c];
        assert!(adc.violations().is_empty(), "{:?}", adc.violations());
        assert!(
            io.dacs[c].violations().is_empty(),
            "{:?}",
            io.dacs[c].violations()
        );
        assert_eq!(adc.frames().len(), (N + 1) * n, "core {c}");
        assert!(adc
            .frames()
            .iter()
            .enumerate()
            .all(|(i, f)| usize::from(f.channel) == i % n && f.sclks == 32));
        assert_eq!(io.dacs[c].updates().len(), N * n, "core {c}");
    }
    // The static bound counts the DMA's accesses to each core's I/O bank, and the watchdog
    // feed's cycles its analysis does not price (`glue::Feed`: core 0's APB store, its load
    // of core 1's count from core 1's bank, which either core may wait for).
    let feed = tactus_firmware::image::glue::Feed {
        other_samples: Some(0),
        entry: None,
        class: None,
    };
    for (c, n) in [(0u64, 3u64), (1, 2)] {
        let w = with.wcet(c as usize).unwrap();
        let fed = match c {
            0 => feed.unpriced_cycles(),
            _ => feed.other_core_cycles(),
        };
        assert_eq!(w.contention, 3 * n + fed, "core {c}");
        let wo = without.wcet(c as usize).unwrap();
        assert!(w.analysed > wo.analysed);
        println!(
            "core {c}, {n} harpsichord keys: static {} + {} contention with converters, {} without",
            w.analysed, w.contention, wo.analysed
        );
    }
    // Latency: from a key's sample (its frame's CS falling edge) to the DAC update that
    // answers it (the 32nd SCLK of its channel's frame), per key over the run.
    let clock = board("rp2040_io").clock_hz;
    for (c, n) in [(0usize, 3usize), (1, 2)] {
        let (frames, updates) = (io.adcs[c].frames(), io.dacs[c].updates());
        for k in 0..n {
            // Burst b (read at tick b) is answered by DAC burst b + 1; burst 0 is the start
            // handler's (its own offset from the tick).
            let lat: Vec<u64> = (1..N - 1)
                .map(|b| updates[(b + 1) * n + k].cycle - frames[b * n + k].cs_fall)
                .collect();
            let (lo, hi) = (lat.iter().min().unwrap(), lat.iter().max().unwrap());
            println!(
                "core {c} key {k}: latency {lo}–{hi} cycles, {:.2}–{:.2} µs",
                *lo as f64 / clock * 1e6,
                *hi as f64 / clock * 1e6
            );
            // The ticks' alternating periods and the state machines' clock phases.
            assert!(
                hi - lo <= 3,
                "the latency is the same every sample but a few cycles"
            );
            // The static latency (what `tactus budget` reports) bounds it, tightly.
            let key = keys.iter().filter(|s| s.core < c).count() + k;
            let bound = with.latency_cycles(key).unwrap();
            assert!(
                *hi <= bound && bound - hi <= 4,
                "key {key}: {lo}–{hi} against {bound}"
            );
        }
    }
    // The I/O trace's records (`tactus play --io-trace`): every frame once, then drained.
    let (records, breaches) = a.take_io();
    assert!(breaches.is_empty(), "{breaches:?}");
    let count = |dac: bool| records.iter().filter(|r| r.dac == dac).count();
    assert_eq!((count(false), count(true)), ((N + 1) * 5, N * 5));
    assert!(records
        .iter()
        .filter(|r| !r.dac)
        .all(|r| r.command >> 13 == 0b110 && r.channel < 3));
    assert!(a.take_io().0.is_empty());
}

/// Core `c`'s fault word (0: no trip since power-on; `tactus_firmware::image::fault`).
fn fault_word(image: &FirmwareImage, run: &mut tactus_firmware::image::ImageRun, c: usize) -> u32 {
    let ctrl = image.core_addresses(c).unwrap()[3];
    let at = tactus_firmware::image::glue::ctrl::fault_record(ctrl);
    run.board().read_u32(at).unwrap()
}

#[test]
fn a_board_powered_on_under_held_keys_reads_them_where_they_are() {
    // Keys held down from power-on (the budget corpus's `hold`): the converter board's
    // first handler reads the burst of the start alarm, before any step, which samples the
    // keys where `run_from` says they are. So the sensor check (on) sees keys that do not
    // move, and the board computes what the board without converters computes from the
    // same positions quantised, from the first sample on.
    let p = instrument("grand_piano");
    assert!(p.sensor_check, "the sensor check is on by default");
    let keys = keys();
    let with = image(&p, &keys, "rp2040_io");
    let without = image(&p, &keys, "rp2040");
    let (lo, hi) = p.fixed.sensor_raw_range[0];
    let scale = AdcScale::new(lo, hi, 16);
    let dip = p.fixed.program.sensors[0].range.1;
    let held: Vec<i32> = (0..keys.len())
        .map(|i| FixedInstance::sensor_raw(&p.fixed, 0, Some(dip * (0.3 + 0.1 * i as f64))))
        .collect();
    let seen: Vec<i32> = held.iter().map(|&w| scale.quantise(w)).collect();
    assert!(
        seen.iter().all(|&w| w != scale.word(0)),
        "held off the rest code"
    );
    let mut a = with.run_from(&held).unwrap();
    let mut b = without.run_from(&seen).unwrap();
    let mut pushed = 0;
    for n in 0..200 {
        let ga = a.step(&held).unwrap().clone();
        let gb = b.step(&seen).unwrap().clone();
        assert_eq!(ga.force, gb.force, "sample {n}: the updates' forces");
        assert_eq!(ga.dac, gb.dac, "sample {n}: the limiter's codes");
        pushed += usize::from(ga.dac.iter().any(|&d| d != 0));
    }
    assert!(pushed > 100, "held keys push back ({pushed} samples)");
    for c in 0..2 {
        assert_eq!(fault_word(&with, &mut a, c), 0, "core {c}: no trip");
        assert_eq!(fault_word(&without, &mut b, c), 0, "core {c}: no trip");
    }
    // `run` instead powers the keys on at rest (every ADC channel at code 0): the held
    // keys then move half the dip between the first handler's reading and the next, which
    // the sensor check rightly takes for a jump.
    let mut r = with.run().unwrap();
    for _ in 0..10 {
        r.step(&held).unwrap();
    }
    let words: Vec<u32> = (0..2).map(|c| fault_word(&with, &mut r, c)).collect();
    let rate = u32::from(tactus_firmware::image::fault::FaultKind::SensorRate.code());
    assert!(
        words.iter().all(|&w| w & 0xff == rate),
        "a jump from rest trips each core's check: {words:x?}"
    );
}

#[test]
fn more_keys_than_converter_channels_is_an_error_naming_the_field() {
    let p = instrument("hammond");
    let keys: Vec<KeySpec> = (0..9)
        .map(|i| KeySpec {
            slot: 40 + i,
            program: 0,
            core: 0,
        })
        .collect();
    let lim = LimiterConfig::default();
    let e = FirmwareImage::build(std::slice::from_ref(&p), &keys, &board("rp2040_io"), &lim)
        .unwrap_err();
    match &e {
        ImageError::Board(why) => assert!(
            why.contains("`converters.adc`") && why.contains("9 sensors") && why.contains('8'),
            "{why}"
        ),
        other => panic!("{other:?}"),
    }
    // Eight fit.
    let eight = FirmwareImage::build(&[p], &keys[..8], &board("rp2040_io"), &lim);
    assert!(eight.is_ok(), "{:?}", eight.err());
}

/// Eight checked hammond keys on one `rp2040_io` core: a copy too long for the `B`s
/// between a check and its trip path, so each path follows its key (`Turns::near_trips`).
/// From rest, the checked image plays as the unchecked one, sample for sample.
#[test]
fn eight_checked_keys_on_one_core_play_as_unchecked_ones() {
    let p = instrument("hammond");
    let mut plain = p.clone();
    plain.sensor_check = false;
    let keys: Vec<KeySpec> = (0..8)
        .map(|i| KeySpec {
            slot: 40 + i,
            program: 0,
            core: 0,
        })
        .collect();
    let checked = image(&p, &keys, "rp2040_io");
    let unchecked = image(&plain, &keys, "rp2040_io");
    // One built-in stimulus from its start, at rest (a stimulus starting mid-travel jumps
    // at the first step on a converter board, `converters_carry_…`), a sample later per key.
    const N: usize = 600;
    let one = stimulus_words(&p, 0, 0, N + keys.len());
    let words: Vec<Vec<i32>> = (0..keys.len()).map(|i| one[i..].to_vec()).collect();
    let (mut a, mut b) = (checked.run().unwrap(), unchecked.run().unwrap());
    let mut moved = 0;
    for n in 0..N {
        let now: Vec<i32> = words.iter().map(|w| w[n]).collect();
        let ga = a.step(&now).unwrap().clone();
        let gb = b.step(&now).unwrap().clone();
        assert_eq!((&ga.force, &ga.dac), (&gb.force, &gb.dac), "sample {n}");
        assert_eq!(ga.misses, vec![0, 0], "sample {n}");
        moved += usize::from(ga.dac.iter().any(|&d| d != 0));
    }
    assert!(moved > 0, "the stimuli never move a motor");
}

#[test]
fn the_drivers_keep_each_parts_timing_at_each_clock() {
    for name in ["rp2040_io", "rp2040_io_200mhz"] {
        let b = board(name);
        let clock = b.clock_hz;
        let plan = io::IoPlan::new(&b, clock as u64, 3000, vec![vec![]; 2], vec![0; 2])
            .unwrap()
            .unwrap();
        let adc_sclk = clock / f64::from(4 * plan.adc_div);
        let dac_sclk = clock / f64::from(4 * plan.dac_div);
        assert!(adc_sclk <= plan.adc.sclk_max_hz, "{name}: {adc_sclk}");
        assert!(dac_sclk <= plan.dac.sclk_max_hz, "{name}: {dac_sclk}");
        assert!(plan.adc_frame_cycles(0) as f64 / clock > plan.adc.frame_period_min_s);
        let sync = f64::from(plan.dac_program.cs_high_pio_cycles * plan.dac_div) / clock;
        assert!(sync > plan.dac.sync_high_min_s, "{name}: {sync}");
    }
}

#[test]
fn a_board_with_converters_boots_from_flash_as_from_ram() {
    // One harpsichord key a core: boot2, the copy to SRAM (the I/O blocks with it), the
    // drivers' set-up; then the same samples as the RAM image, frame for frame.
    let p = instrument("harpsichord");
    let keys: Vec<KeySpec> = (0..2)
        .map(|i| KeySpec {
            slot: 60 + i,
            program: 0,
            core: i,
        })
        .collect();
    let image = image(&p, &keys, "rp2040_io");
    let flash = image.flash_image().unwrap().bytes;
    let mut ram = image.run().unwrap();
    let mut rom = tactus_firmware::image::ImageRun::from_flash(&image, &flash).unwrap();
    let words: Vec<Vec<i32>> = (0..2).map(|i| stimulus_words(&p, i, 2500, 8)).collect();
    for n in 0..8 {
        let now: Vec<i32> = words.iter().map(|w| w[n]).collect();
        let a = ram.step(&now).unwrap().clone();
        let b = rom.step(&now).unwrap().clone();
        assert_eq!((&a.force, &a.dac), (&b.force, &b.dac));
        // The cycles too, but for the one a sample the watchdog's feed makes the cores
        // contend for core 1's bank (`glue::Feed::other_core_cycles`): which core waits
        // depends on the arbiter's history, which the boots leave differently.
        let (sa, sb): (u64, u64) = (a.core_cycles.iter().sum(), b.core_cycles.iter().sum());
        assert_eq!(
            sa, sb,
            "sample {n}: {:?} {:?}",
            a.core_cycles, b.core_cycles
        );
        for (x, y) in a.core_cycles.iter().zip(&b.core_cycles) {
            assert!(x.abs_diff(*y) <= 1, "sample {n}: {x} {y}");
        }
    }
    let (ra, _) = ram.take_io();
    let (rb, breaches) = rom.take_io();
    assert!(breaches.is_empty(), "{breaches:?}");
    // The same frames from each board's first tick (the flash boot takes longer): the
    // same codes in the same order; the DAC's at the same cycles, the ADC's within its
    // state machine's clock phase (÷ 2: which of two cycles the divider lets it run in
    // depends on how long the boot took).
    assert_eq!(ra.len(), rb.len());
    assert!(!ra.is_empty());
    let div = image.io().unwrap().adc_div as i64;
    let (t0a, t0b) = (ram.tick_cycle(0) as i64, rom.tick_cycle(0) as i64);
    for (x, y) in ra.iter().zip(&rb) {
        assert_eq!(
            (x.core, x.dac, x.channel, x.code, x.command),
            (y.core, y.dac, y.channel, y.code, y.command)
        );
        let (dx, dy) = (x.cycle as i64 - t0a, y.cycle as i64 - t0b);
        let slack = if x.dac { 0 } else { div - 1 };
        assert!((dx - dy).abs() <= slack, "{x:?} at {dx}, {y:?} at {dy}");
    }
}

#[test]
fn skipping_the_io_machine_equals_ticking_it_every_cycle() {
    // The I/O machine run by events (quiet stretches, idle divider cycles and delays
    // skipped in one step) against the same machine ticked every cycle
    // (`tactus_emulator::io::Io::stepwise`): sample for sample the same outputs, cycles and
    // stalls, the same SRAM, the same frames, and the same state of every PIO, DMA channel
    // and converter.
    let p = instrument("harpsichord");
    let keys = keys();
    let image = image(&p, &keys, "rp2040_io");
    let mut fast = image.run().unwrap();
    let mut slow = image.run().unwrap();
    slow.board().io_mut().unwrap().stepwise = true;
    const N: usize = 120;
    let words: Vec<Vec<i32>> = (0..keys.len())
        .map(|i| stimulus_words(&p, i, 2000 + 300 * i, N))
        .collect();
    let state = |run: &mut tactus_firmware::image::ImageRun| {
        let io = run.board().io_mut().unwrap();
        let stepwise = std::mem::replace(&mut io.stepwise, false);
        let text = format!("{io:?}");
        io.stepwise = stepwise;
        text
    };
    let mut frames = 0;
    for n in 0..N {
        let now: Vec<i32> = words.iter().map(|w| w[n]).collect();
        let a = fast.step(&now).unwrap().clone();
        let b = slow.step(&now).unwrap().clone();
        assert_eq!(a, b, "sample {n}");
        assert_eq!(fast.board().cycle(), slow.board().cycle(), "sample {n}");
        assert!(
            fast.board().system.sram == slow.board().system.sram,
            "sample {n}: SRAM"
        );
        assert_eq!(
            state(&mut fast),
            state(&mut slow),
            "sample {n}: the I/O machine"
        );
        let (ra, ba) = fast.take_io();
        let (rb, bb) = slow.take_io();
        assert_eq!((&ra, &ba), (&rb, &bb), "sample {n}: frames");
        assert!(ba.is_empty(), "{ba:?}");
        frames += ra.len();
    }
    // 5 ADC frames a sample (and one burst at start), 5 DAC updates.
    assert_eq!(frames, (N + 1) * 5 + N * 5);
}

#[test]
fn windows_on_a_board_with_converters_equal_the_lock_step() {
    // The block engine's windows (the cores run ahead of the I/O, which then replays
    // their accesses to its DMA's banks and their register stores:
    // `tactus_emulator::board`, `io_window.rs`) against the interpreter's lock-step run:
    // sample for sample the same outputs, cycles and stalls, SRAM, frames and I/O state.
    let p = instrument("harpsichord");
    let keys = keys();
    const N: usize = 120;
    let words: Vec<Vec<i32>> = (0..keys.len())
        .map(|i| stimulus_words(&p, i, 2000 + 300 * i, N))
        .collect();
    let io = windows_equal_the_lock_step(&p, &keys, &words, N);
    assert!(io.kept > N as u64 / 2, "{io:?}");
}

#[test]
fn the_period_memo_of_the_io_equals_the_lock_step() {
    // Keys held still for stretches, at levels that come back, and jumping between them:
    // the I/O's replays repeat in what they do while their data — the ADC codes, the DAC
    // frames the DMA reads — changes, which the period memo gives by its routes
    // (`io_window.rs`): the windows with the memo against the lock-step run, sample for
    // sample, as above.
    let p = instrument("harpsichord");
    let keys = keys();
    const N: usize = 360;
    let levels: Vec<Vec<i32>> = (0..keys.len())
        .map(|i| stimulus_words(&p, i, 2000 + 300 * i, 400))
        .collect();
    // Stretches of 40 samples at the levels of samples 0, 200, 0, 399, 200, 0, …
    let at = [0, 200, 0, 399, 200, 0, 399, 0, 200];
    let words: Vec<Vec<i32>> = levels
        .iter()
        .map(|l| (0..N).map(|n| l[at[n / 40 % at.len()]]).collect())
        .collect();
    let io = windows_equal_the_lock_step(&p, &keys, &words, N);
    // The memo gives nearly every window, whatever its data; a few are recorded (here or
    // by another board of the process).
    assert!(io.memo_hits >= N as u64 * 3 / 4, "{io:?}");
    assert!(
        (1..N as u64 / 8).contains(&(io.memo_recorded + io.memo_shared)),
        "{io:?}"
    );
}

/// Runs `p` on `keys` on rp2040_io through `words` (per key, per sample) for `n` samples
/// in windows (the block engine) and on the lock-step machine with no accelerator
/// ([`Engine::LockStep`]: every instruction decoded from memory as it runs), asserting each
/// sample the same outputs, cores, stalls, SRAM, I/O state and frames; returns the
/// windowed run's [`IoWindows`].
fn windows_equal_the_lock_step(
    p: &Program,
    keys: &[KeySpec],
    words: &[Vec<i32>],
    n: usize,
) -> tactus_emulator::IoWindows {
    let image = image(p, keys, "rp2040_io");
    let mut win = image.run().unwrap();
    let mut lock = image.run().unwrap();
    lock.board().config.engine = Engine::LockStep;
    for n in 0..n {
        let now: Vec<i32> = words.iter().map(|w| w[n]).collect();
        let a = win.step(&now).unwrap().clone();
        let b = lock.step(&now).unwrap().clone();
        assert_eq!(a, b, "sample {n}");
        let (x, y) = (win.board(), lock.board());
        for c in 0..2 {
            let (p, q) = (&x.cores[c], &y.cores[c]);
            assert_eq!(
                (p.cycle, p.instructions, p.r),
                (q.cycle, q.instructions, q.r),
                "sample {n} core {c}"
            );
        }
        assert_eq!(x.system.contention_stalls, y.system.contention_stalls);
        assert!(x.system.sram == y.system.sram, "sample {n}: SRAM");
        let (ix, iy) = (format!("{:?}", x.io()), format!("{:?}", y.io()));
        assert!(ix == iy, "sample {n}: the I/O machine");
        assert_eq!(win.take_io(), lock.take_io(), "sample {n}: frames");
    }
    let io = win.board().io_windows();
    let (kept, undone) = win.board().run_ahead_windows();
    eprintln!(
        "windows: {kept} kept, {undone} undone; on the I/O: {io:?}; memo: {:?}",
        win.board().memo_stats()
    );
    assert_eq!(lock.board().io_windows().kept, 0);
    io
}
