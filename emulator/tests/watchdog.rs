//! The watchdog (RP2040 datasheet 4.7, `emulator/src/watchdog.rs`): its count (twice per
//! tick, erratum RP2040-E1), the reset when it reaches 0 or is triggered, what the reset
//! keeps (SRAM, scratch, REASON), the boot ROM's watchdog entry, and the same resets at
//! the same cycles on every engine.

mod common;

use common::enc::*;
use common::{cores_state, load_program};
use tactus_emulator::watchdog::Reason;
use tactus_emulator::{Board, Config, Engine, StopReason};
use tactus_rp2040::timer::reg::TIMERAWL;
use tactus_rp2040::watchdog::{BOOT_MAGIC, REASON_FORCE, REASON_TIMER};

const CODE: u32 = 0x2000_0000;
/// The program's data: its boot count, then the four scratch words it arms (4–7).
const DATA: u32 = 0x2000_1000;
const CLOCK_HZ: u64 = 125_000_000;

/// `ADDS Rd, Rn, Rm`
fn adds_reg(rd: u16, rn: u16, rm: u16) -> u16 {
    0x1800 | rm << 6 | rn << 3 | rd
}

/// `BICS Rdn, Rm`
fn bics(rdn: u16, rm: u16) -> u16 {
    0x4380 | rm << 3 | rdn
}

/// A program that counts its boots at `DATA`, arms the boot ROM's watchdog entry (the
/// words at `DATA + 16`), loads the watchdog with `load`, enables it, feeds it `feeds`
/// times and then hangs in `b .` (or, with `trigger`, writes CTRL.TRIGGER).
fn program(load: u16, feeds: u16, trigger: bool) -> Vec<u16> {
    let mut c = vec![
        movs(0, 0x40),
        lsls(0, 0, 24),
        movs(1, 0x58),
        lsls(1, 1, 12),
        adds_reg(0, 0, 1), // r0 = WATCHDOG_BASE
        movs(4, 0x20),
        lsls(4, 4, 24),
        movs(1, 0x10),
        lsls(1, 1, 8),
        adds_reg(4, 4, 1), // r4 = DATA
        ldr(2, 4, 0),
        adds_imm8(2, 1),
        str(2, 4, 0), // boots + 1
    ];
    for i in 0..4 {
        c.push(ldr(1, 4, 16 + 4 * i));
        c.push(str(1, 0, 0x1c + 4 * i)); // SCRATCH4..7
    }
    c.extend([
        movs(1, load & 0xff),
        lsls(1, 1, 2), // LOAD = 4 × load
        str(1, 0, 4),
        movs(2, 0x40),
        lsls(2, 2, 24), // CTRL.ENABLE
        str(2, 0, 0),
        movs(3, feeds),
        // feed loop: reload, a few NOPs, count down
        str(1, 0, 4),
        nop(),
        nop(),
        nop(),
        subs_imm8(3, 1),
        bcond(1, -10), // bne to the reload
    ]);
    if trigger {
        c.extend([movs(2, 0x80), lsls(2, 2, 24), str(2, 0, 0)]); // CTRL.TRIGGER
    }
    c.push(b(0)); // b .
    c
}

fn board(engine: Engine, code: &[u16]) -> Board {
    let mut b = Board::new(Config {
        clock_hz: CLOCK_HZ,
        engine,
        ..Config::default()
    });
    load_program(&mut b, 0, CODE, 0x2002_0000, code);
    let entry = CODE | 1;
    let words = [
        BOOT_MAGIC,
        entry ^ BOOT_MAGIC.wrapping_neg(),
        0x2002_0000,
        entry,
    ];
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    b.write_bytes(DATA + 16, &bytes).unwrap();
    b
}

fn boots(b: &mut Board) -> u32 {
    b.read_u32(DATA).unwrap()
}

#[test]
fn the_count_falls_twice_a_tick_and_a_hung_core_is_reset_after_load_over_two_microseconds() {
    // LOAD = 4 × 50 = 200: 100 µs (RP2040-E1), so a core that stops feeding is reset 100 µs
    // after its last feed.
    let mut b = board(Engine::LockStep, &program(50, 3, false));
    assert_eq!(b.run_until(2_000), StopReason::CycleLimit);
    let wd = &b.system.watchdog;
    assert!(wd.is_enabled());
    let (c0, t0) = (wd.count_at(2_000), 2_000u64);
    assert!(c0 > 100 && c0 < 200, "fed, then counting down: {c0}");
    // 10 µs later the count is down by 20, not 10.
    let t1 = t0 + 10 * CLOCK_HZ / 1_000_000;
    assert_eq!(b.run_until(t1), StopReason::CycleLimit);
    assert_eq!(b.system.watchdog.count_at(t1), c0 - 20);
    assert_eq!(b.system.watchdog.resets().0, 0);
    // It fires when the count reaches 0, c0 / 2 µs after t0: the program boots again
    // (SRAM kept, the scratch registers' entry taken, REASON TIMER) and hangs again.
    let fire = b.system.watchdog.fire_at;
    let us_after = (fire as f64 - t0 as f64) * 1e6 / CLOCK_HZ as f64;
    let want = f64::from(c0) / 2.0;
    assert!(
        (want - 1.0..=want).contains(&us_after),
        "fires {us_after} µs after t0, want {want}"
    );
    assert_eq!(b.run_until(fire + 1_000), StopReason::CycleLimit);
    let (n, last) = b.system.watchdog.resets();
    assert_eq!(n, 1);
    let last = last.unwrap();
    assert_eq!(last.reason, Reason::Timer);
    assert!(
        last.cycle >= fire && last.cycle < fire + 4,
        "reset at {}",
        last.cycle
    );
    assert_eq!(b.system.watchdog.reason(), REASON_TIMER);
    assert_eq!(boots(&mut b), 2, "SRAM survives, the image entered again");
    assert_eq!(
        b.system.watchdog.scratch(4),
        BOOT_MAGIC,
        "armed again by the program"
    );
    // Core 1 is back in the boot ROM's launch protocol; the timer is held in reset (the
    // watchdog entry skips the ROM's `main`, which releases it) and this program never
    // releases it.
    assert_eq!(
        b.cores[1].state,
        tactus_emulator::core::RunState::Parked,
        "core 1 parked"
    );
    let now = b.cycle();
    assert_eq!(b.system.timer.read(now, TIMERAWL), Some(0), "held");
    assert_eq!(b.system.timer.released_at(), None);
}

#[test]
fn after_a_reset_through_the_boot_entry_the_firmware_releases_the_timer() {
    // The program with a release of the timer first (RESETS.RESET's TIMER bit set, then
    // cleared): after the reset the timer counts from the firmware's release, as after
    // power-on, not from the reset.
    let release = [
        movs(5, 0x40),
        lsls(5, 5, 24),
        movs(6, 0xc0),
        lsls(6, 6, 8),
        adds_reg(5, 5, 6), // r5 = RESETS_BASE, 0x4000_c000
        movs(6, 0x20),
        lsls(6, 6, 16), // r6 = 1 << 21, TIMER
        ldr(7, 5, 0),
        bics(7, 6),
        str(7, 5, 0), // out of reset
    ];
    let code: Vec<u16> = release.into_iter().chain(program(50, 1, false)).collect();
    let mut b = board(Engine::LockStep, &code);
    let fire = loop {
        assert_eq!(b.run_for(2_000), StopReason::CycleLimit);
        if b.system.watchdog.resets().0 == 1 {
            break b.system.watchdog.resets().1.unwrap().cycle;
        }
    };
    assert_eq!(b.run_until(fire + 500), StopReason::CycleLimit);
    assert_eq!(boots(&mut b), 2);
    let released = b
        .system
        .timer
        .released_at()
        .expect("released by the program");
    assert!(
        released > fire && released < fire + 40,
        "{released} after {fire}"
    );
    let now = b.cycle();
    let t = u64::from(b.system.timer.read(now, TIMERAWL).unwrap());
    let want = (now - released) * 1_000_000 / CLOCK_HZ;
    assert!(t.abs_diff(want) <= 1, "{t} µs, want {want}");
}

#[test]
fn without_a_boot_entry_the_board_boots_from_flash_and_an_empty_flash_stops_it() {
    let mut b = board(Engine::LockStep, &program(50, 1, false));
    // No entry armed: the program's words at DATA + 16 are zero.
    b.write_bytes(DATA + 16, &[0; 16]).unwrap();
    let stop = b.run_until(1_000_000);
    assert_eq!(stop, StopReason::Idle, "USB boot: nothing runs");
    assert_eq!(b.system.watchdog.resets().0, 1);
    assert_eq!(boots(&mut b), 1);
    // The ROM's `main` pulsed the timer's reset before it looked for flash: the timer
    // counts from the reset, with no release by a firmware recorded.
    let reset = b.system.watchdog.resets().1.unwrap().cycle;
    let now = b.cycle();
    let t = u64::from(b.system.timer.read(now, TIMERAWL).unwrap());
    let want = (now - reset) * 1_000_000 / CLOCK_HZ;
    assert!(t.abs_diff(want) <= 1, "{t} µs, want {want}");
    assert_eq!(b.system.timer.released_at(), None);
}

#[test]
fn trigger_resets_at_once_with_reason_force() {
    let mut b = board(Engine::Interp, &program(200, 2, true));
    assert_eq!(b.run_until(300), StopReason::CycleLimit);
    let (n, last) = b.system.watchdog.resets();
    assert!(n >= 1);
    assert_eq!(last.unwrap().reason, Reason::Force);
    assert_eq!(b.system.watchdog.reason(), REASON_FORCE);
}

/// Every engine resets at the same cycles with the same state: the lock-step machine, the
/// interpreter and the block engine (compiled at once), run in steps that fall before,
/// across and after the firings.
#[test]
fn every_engine_resets_where_the_lock_step_machine_does() {
    let code = program(20, 5, false);
    let mut reference = board(Engine::LockStep, &code);
    let steps: Vec<u64> = (1..=40).map(|i| i * 3_001).collect();
    let mut want = Vec::new();
    for &t in &steps {
        assert_eq!(reference.run_until(t), StopReason::CycleLimit);
        want.push((
            cores_state(&reference),
            reference.system.watchdog.resets(),
            boots(&mut reference),
        ));
    }
    assert!(
        want.last().unwrap().1 .0 >= 5,
        "several resets: {:?}",
        want.last()
    );
    for engine in [Engine::Interp, Engine::Block] {
        let mut b = board(engine, &code);
        b.set_compile_threshold(0);
        for (&t, w) in steps.iter().zip(&want) {
            assert_eq!(b.run_until(t), StopReason::CycleLimit);
            let got = (cores_state(&b), b.system.watchdog.resets(), boots(&mut b));
            assert_eq!(&got, w, "{engine:?} at cycle {t}");
        }
        assert_eq!(b.system.sram, reference.system.sram);
    }
}

/// Who feeds the watchdog in [`fed_board`]'s program.
#[derive(Clone, Copy, Debug)]
enum Feeding {
    /// Core 0 at the end of each sample.
    Core0,
    /// Core 0 at the end of each sample, after reading core 1's sample count from core 1's
    /// bank: the firmware's way (at that load the window meets core 1).
    Checked,
    /// As `Checked`, with core 1's sample starting just before core 0's and its work longer:
    /// at the load core 1 is inside its work loop, which runs to core 0's cycle natively,
    /// timed (`Board::timed_stops`).
    Met,
    /// Both cores each sample (their writes in one window: the window is undone).
    Both,
    /// Core 0, with a LOAD shorter than a sample from the 10th sample on: the watchdog
    /// fires inside what would be a window.
    Starved,
}

/// Cycles of a sample: SysTick on the processor clock, reload `SAMPLE - 1`.
const SAMPLE: u64 = 2_834;
/// Each core's bank through the non-striped alias: its vector table at +0, SysTick
/// handler at +0x100, main at +0x200, sample count at +0x800.
fn own_bank(core: usize) -> u32 {
    0x2100_0000 + 0x1_0000 * core as u32
}

/// A two-core "firmware" on the images' bank layout (core 0 SRAM0, 2, 4; core 1 SRAM1, 3,
/// 5): each core's SysTick fires every [`SAMPLE`] cycles, its handler counts the sample,
/// does some work and (as `feeding` says) stores to the watchdog's LOAD; core 0's main
/// loads the watchdog and enables it first; both sleep in WFI between samples.
fn fed_board(engine: Engine, feeding: Feeding) -> Board {
    let mut board = Board::new(Config {
        clock_hz: CLOCK_HZ,
        engine,
        own_banks: [0b01_0101, 0b10_1010],
        ..Config::default()
    });
    board.set_compile_threshold(0);
    for core in 0..2 {
        let base = own_bank(core);
        let feeds = match feeding {
            Feeding::Core0 | Feeding::Checked | Feeding::Met | Feeding::Starved => core == 0,
            Feeding::Both => true,
        };
        let mut handler = vec![
            ldr(0, 4, 0),
            adds_imm8(0, 1),
            str(0, 4, 0), // the sample count + 1
            movs(
                1,
                if matches!(feeding, Feeding::Met) {
                    200
                } else {
                    30
                },
            ),
            subs_imm8(1, 1),
            bcond(1, -2), // some work
        ];
        if matches!(feeding, Feeding::Starved) && core == 0 {
            handler.extend([cmp_imm(0, 10), bcond(1, 4), movs(6, 20)]); // LOAD 20: 10 µs
        }
        if matches!(feeding, Feeding::Checked | Feeding::Met) && core == 0 {
            handler.push(ldr(2, 3, 0)); // core 1's sample count
        }
        if feeds {
            handler.push(str(6, 5, 4)); // WATCHDOG LOAD
        }
        handler.push(0x4770); // bx lr
        let mut main = Vec::new();
        if core == 0 {
            main.extend([str(6, 5, 4), str(7, 5, 0)]); // LOAD, CTRL.ENABLE
        }
        main.extend([0xbf30, b(-2)]); // wfi; b .-2
        let bytes =
            |code: &[u16]| -> Vec<u8> { code.iter().flat_map(|h| h.to_le_bytes()).collect() };
        board.write_u32(base + 4 * 15, base + 0x101).unwrap();
        board.write_bytes(base + 0x100, &bytes(&handler)).unwrap();
        board.write_bytes(base + 0x200, &bytes(&main)).unwrap();
        board.start_core(
            core,
            (base + 0x200) | 1,
            0x2004_1000 + 0x1000 * core as u32,
            base,
        );
        let c = &mut board.cores[core];
        c.r[3] = own_bank(1) + 0x800;
        c.r[4] = base + 0x800;
        c.r[5] = tactus_rp2040::watchdog::WATCHDOG_BASE;
        c.r[6] = 0x1_0000; // 32.8 ms (two counts a tick)
        c.r[7] = tactus_rp2040::watchdog::CTRL_ENABLE;
        c.nvic.syst_rvr = (SAMPLE - 1) as u32;
        c.nvic.syst_csr = 7; // enabled, interrupting, on the processor clock
        c.nvic.syst_next = match feeding {
            // Core 1's tick a little before core 0's, its work past core 0's load.
            Feeding::Met => 500 - 37 * core as u64,
            _ => 500 + 700 * core as u64,
        };
    }
    board
}

/// The SRAM offsets of the two sample counts (counters for the rest replay).
fn sample_counts() -> Vec<usize> {
    (0..2)
        .map(|k| {
            tactus_rp2040::memory::sram_location(own_bank(k) + 0x800)
                .unwrap()
                .0
        })
        .collect()
}

/// What two runs of [`fed_board`] must agree on: the cores, SRAM and the watchdog (its
/// count, when it was loaded, when it fires, its resets).
fn fed_state(b: &Board) -> (String, Vec<u8>, tactus_emulator::watchdog::Watchdog) {
    (
        cores_state(b),
        b.system.sram.clone(),
        b.system.watchdog.clone(),
    )
}

/// Asserts that `b` and the lock-step `reference` agree ([`fed_state`]).
fn assert_same(b: &Board, reference: &Board, at: &str) {
    assert!(
        fed_state(b) == fed_state(reference),
        "{at}: {}\nwant {}\nwatchdog {:?}\nwant {:?}",
        cores_state(b),
        cores_state(reference),
        b.system.watchdog,
        reference.system.watchdog
    );
}

/// A watchdog fed once a sample does not end the block engine's windows (core 0's feeds are
/// applied at their cycles inside them) and gives the lock-step machine's run; both cores'
/// feeds, or a feed that brings the firing inside a window, undo the window and still give
/// the lock-step run (the firing at the same cycle).
#[test]
fn feeds_inside_windows_give_the_lock_step_run() {
    for feeding in [
        Feeding::Core0,
        Feeding::Checked,
        Feeding::Met,
        Feeding::Both,
        Feeding::Starved,
    ] {
        let mut reference = fed_board(Engine::LockStep, feeding);
        let mut block = fed_board(Engine::Block, feeding);
        let mut stops = Vec::new();
        for i in 1..=60u64 {
            let t = i * SAMPLE + 97 * (i % 7);
            let want = reference.run_until(t);
            stops.push(want);
            assert_eq!(block.run_until(t), want, "{feeding:?} at {t}");
            assert_same(&block, &reference, &format!("{feeding:?} at cycle {t}"));
        }
        let (kept, undone) = block.run_ahead_windows();
        let resets = reference.system.watchdog.resets().0;
        match feeding {
            Feeding::Core0 => {
                assert_eq!(resets, 0);
                assert!(reference.system.watchdog.is_enabled());
                assert!(
                    kept >= 50 && undone <= 1,
                    "windows kept {kept}, undone {undone}"
                );
            }
            Feeding::Checked => {
                // One window a sample, core 1 met at the load (before: 9 kept, 30 undone).
                assert_eq!(resets, 0);
                assert!(
                    kept >= 50 && undone <= 1,
                    "windows kept {kept}, undone {undone}"
                );
            }
            Feeding::Met => {
                assert_eq!(resets, 0);
                assert!(
                    kept >= 50 && undone <= 1,
                    "windows kept {kept}, undone {undone}"
                );
                // Core 1 ran to the meeting natively, timed, in 24 of the 60 samples (the
                // others' meetings fall where its loop's region fits, or the run's limits
                // cut the window first).
                assert!(block.timed_stops() >= 20, "{}", block.timed_stops());
            }
            // After an undone window the lock-step loop runs 4,096 cycles before the next.
            Feeding::Both => assert!(undone >= 20, "windows kept {kept}, undone {undone}"),
            Feeding::Starved => {
                assert_eq!(resets, 1, "fired once (then no flash to boot)");
                assert!(stops.contains(&StopReason::Idle));
                assert!(
                    kept >= 5 && undone >= 1,
                    "windows kept {kept}, undone {undone}"
                );
            }
        }
    }
}

/// An enabled, fed watchdog is rest state relative to its last feed: a board that feeds it
/// at the same point of every sample repeats, the rest replay skips periods of it, and the
/// run after the skip equals the lock-step machine's run of every sample.
#[test]
fn a_fed_watchdog_repeats_and_the_rest_replay_skips_it_exactly() {
    let counters = sample_counts();
    let mut reference = fed_board(Engine::LockStep, Feeding::Core0);
    let mut b = fed_board(Engine::Block, Feeding::Core0);
    let t0 = 20 * SAMPLE + 300;
    assert_eq!(b.run_until(t0), StopReason::CycleLimit);
    let start = b.rest_point(&counters).unwrap();
    assert_eq!(b.run_until(t0 + SAMPLE), StopReason::CycleLimit);
    let end = b.rest_point(&counters).unwrap();
    let period = b.period(&start, &end).expect("a fed watchdog repeats");
    assert_eq!(period.cycles(), SAMPLE);
    assert_eq!(period.counter_increases(), &[1, 1]);
    let skipped = 500;
    b.skip_periods(&period, skipped).unwrap();
    for t in [
        t0 + (skipped + 1) * SAMPLE,
        t0 + (skipped + 3) * SAMPLE + 1_234,
    ] {
        assert_eq!(b.run_until(t), StopReason::CycleLimit);
        assert_eq!(reference.run_until(t), StopReason::CycleLimit);
        assert_same(&b, &reference, &format!("at cycle {t}"));
    }
    assert!(reference.system.watchdog.is_enabled());
    assert_eq!(reference.system.watchdog.resets().0, 0);
}
