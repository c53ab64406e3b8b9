//! The watchdog (RP2040 datasheet 4.7, `emulator/src/watchdog.rs`): its count (twice per
//! tick, erratum RP2040-E1), the reset when it reaches 0 or is triggered, what the reset
//! keeps (SRAM, scratch, REASON), the boot ROM's watchdog entry, and the same resets at
//! the same cycles on every engine.

mod common;

use common::enc::*;
use common::{cores_state, load_program};
use tactus_emulator::watchdog::Reason;
use tactus_emulator::{Board, Config, Engine, StopReason};
use tactus_rp2040::watchdog::{BOOT_MAGIC, REASON_FORCE, REASON_TIMER};

const CODE: u32 = 0x2000_0000;
/// The program's data: its boot count, then the four scratch words it arms (4–7).
const DATA: u32 = 0x2000_1000;
const CLOCK_HZ: u64 = 125_000_000;

/// `ADDS Rd, Rn, Rm`
fn adds_reg(rd: u16, rn: u16, rm: u16) -> u16 {
    0x1800 | rm << 6 | rn << 3 | rd
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
    // Core 1 is back in the boot ROM's launch protocol; the timer restarted at the reset.
    assert_eq!(
        b.cores[1].state,
        tactus_emulator::core::RunState::Parked,
        "core 1 parked"
    );
    assert!(b.system.timer.micros(b.cycle()) < 20);
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
