//! SysTick as the ARMv6-M Architecture Reference Manual (DDI0419 B3.3) and the RP2040
//! datasheet (2.4, 4.6.1: one 24-bit SysTick per core; CLKSOURCE = 1 the processor clock,
//! 0 the 1 µs pulse of the watchdog's tick generator) describe it, register by register
//! on one core's [`Nvic`], then on a board: the period is RVR + 1 counts; the count from
//! 1 to 0 sets COUNTFLAG and pends the exception; the counter holds 0 for one count and
//! reloads on the next, so a write to RVR takes effect at the next reload (also one that
//! lands on the count at 0); reading SYST_CSR clears COUNTFLAG, writing SYST_CVR clears
//! the counter and COUNTFLAG; ICSR shows and clears the pending exception; each core's
//! handler is entered exactly at its own wraps, with a period its handler reprograms.

mod common;

use common::enc::*;
use common::load_program;
use tactus_emulator::nvic::{Nvic, SYSTICK};
use tactus_emulator::{Board, Config, StopReason};
use tactus_isa::timing::EXCEPTION_ENTRY;

const CSR: u32 = 0xe000_e010;
const RVR: u32 = 0xe000_e014;
const CVR: u32 = 0xe000_e018;
const ICSR: u32 = 0xe000_ed04;
/// SYST_CSR: ENABLE | TICKINT | CLKSOURCE (processor clock).
const ON: u32 = 7;

fn nvic(clock_hz: u64) -> Nvic {
    let mut n = Nvic::default();
    n.clock_hz = clock_hz;
    n
}

fn pending(n: &Nvic) -> bool {
    n.pending & (1 << SYSTICK) != 0
}

/// The cycles (among `from..to`) at which the counter reads 0, by reading SYST_CVR every
/// cycle, and the cycles at which the exception became pending (cleared after each).
fn zeros_and_pends(n: &mut Nvic, from: u64, to: u64) -> (Vec<u64>, Vec<u64>) {
    let (mut zeros, mut pends) = (Vec::new(), Vec::new());
    for t in from..to {
        if n.read(t, CVR, 0) == Some(0) {
            zeros.push(t);
        }
        if pending(n) {
            pends.push(t);
            n.pending &= !(1 << SYSTICK);
        }
    }
    (zeros, pends)
}

#[test]
fn the_period_is_rvr_plus_one_and_the_counter_holds_zero_for_one_count() {
    let mut n = nvic(133_000_000);
    assert!(n.write(0, RVR, 99));
    assert!(n.write(0, CVR, 5)); // clears the counter: it reloads on the next count
    assert!(n.write(0, CSR, ON));
    // Reloaded at cycle 1 to 99: 0 at 100, 200, …; RVR, … at the cycle after each.
    assert_eq!(n.read(1, CVR, 0), Some(99));
    assert_eq!(n.read(50, CVR, 0), Some(50));
    let (zeros, pends) = zeros_and_pends(&mut n, 2, 460);
    assert_eq!(zeros, [100, 200, 300, 400]);
    assert_eq!(pends, zeros, "the exception pends at the count from 1 to 0");
    assert_eq!(n.read(401, CVR, 0), Some(99));
    assert_eq!(n.read(460, CVR, 0), Some(40));
    // The 24-bit reload value.
    assert!(n.write(500, RVR, 0xff12_3456));
    assert_eq!(n.read(501, RVR, 0), Some(0x12_3456));
}

#[test]
fn a_write_to_rvr_takes_effect_at_the_next_reload() {
    let mut n = nvic(133_000_000);
    n.write(0, RVR, 99);
    n.write(0, CSR, ON);
    // Mid-count: the current count runs out as it was (0 at 100), then 50 per period.
    n.write(40, RVR, 49);
    assert_eq!(n.read(41, CVR, 0), Some(59));
    let (zeros, _) = zeros_and_pends(&mut n, 42, 260);
    assert_eq!(zeros, [100, 150, 200, 250]);
    // On the count at 0 (cycle 250): its reload (at 251) takes the new value.
    let mut m = nvic(133_000_000);
    m.write(0, RVR, 99);
    m.write(0, CSR, ON);
    m.tick(100);
    assert!(pending(&m) && m.syst_next == 100 && m.syst_fired);
    m.write(100, RVR, 9);
    assert_eq!(m.read(101, CVR, 0), Some(9));
    let (zeros, _) = zeros_and_pends(&mut m, 101, 125);
    assert_eq!(zeros, [110, 120]);
    // One count later it is the reload after: 0 at 200 as loaded, then 10 per period.
    let mut m = nvic(133_000_000);
    m.write(0, RVR, 99);
    m.write(0, CSR, ON);
    m.write(101, RVR, 9);
    let (zeros, _) = zeros_and_pends(&mut m, 101, 225);
    assert_eq!(zeros, [200, 210, 220]);
}

#[test]
fn countflag_is_set_by_the_wrap_and_cleared_by_reading_csr_or_writing_cvr() {
    let mut n = nvic(133_000_000);
    n.write(0, RVR, 99);
    n.write(0, CSR, ON);
    assert_eq!(n.read(99, CSR, 0), Some(ON), "no wrap yet");
    assert_eq!(n.read(100, CSR, 0), Some(ON | 1 << 16), "the count at 0");
    assert_eq!(n.read(101, CSR, 0), Some(ON), "cleared by the read");
    // Two wraps between reads: one flag.
    assert_eq!(n.read(350, CSR, 0), Some(ON | 1 << 16));
    assert_eq!(n.read(351, CSR, 0), Some(ON));
    // Writing CVR clears the flag and the counter, which reloads on the next count.
    n.tick(400);
    assert!(n.write(420, CVR, 0x1234));
    assert_eq!(n.read(421, CSR, 0), Some(ON));
    assert_eq!(n.read(421, CVR, 0), Some(99));
    let (zeros, _) = zeros_and_pends(&mut n, 422, 530);
    assert_eq!(zeros, [520]);
    // Without TICKINT the flag is set but nothing pends.
    let mut q = nvic(133_000_000);
    q.write(0, RVR, 9);
    q.write(0, CSR, 5);
    q.tick(10);
    assert!(!pending(&q) && q.countflag);
}

#[test]
fn icsr_shows_and_clears_the_pending_systick() {
    let mut n = nvic(133_000_000);
    n.write(0, RVR, 99);
    n.write(0, CSR, ON);
    assert_eq!(n.read(99, ICSR, 0).unwrap() & 1 << 26, 0);
    assert_ne!(n.read(100, ICSR, 0).unwrap() & 1 << 26, 0, "PENDSTSET");
    n.write(101, ICSR, 1 << 25); // PENDSTCLR
    assert_eq!(n.read(102, ICSR, 0).unwrap() & 1 << 26, 0);
    n.write(103, ICSR, 1 << 26); // PENDSTSET
    assert!(pending(&n));
}

#[test]
fn disabling_keeps_the_count_and_enabling_resumes_it() {
    let mut n = nvic(133_000_000);
    n.write(0, RVR, 99);
    n.write(0, CSR, ON);
    n.write(31, CSR, 6); // off with 69 left
    assert_eq!(n.read(500, CVR, 0), Some(69));
    n.tick(10_000);
    assert!(!pending(&n));
    n.write(1000, CSR, ON);
    let (zeros, _) = zeros_and_pends(&mut n, 1001, 1200);
    assert_eq!(zeros, [1069, 1169]);
    // A reload value of 0 stops the counter at 0 after its count from 1 to 0.
    let mut z = nvic(133_000_000);
    z.write(0, RVR, 9);
    z.write(0, CSR, ON);
    z.write(5, RVR, 0);
    let (zeros, pends) = zeros_and_pends(&mut z, 6, 100);
    assert_eq!(pends, [10]);
    assert_eq!(zeros, (10..100).collect::<Vec<_>>());
}

#[test]
fn clksource_zero_counts_the_1_us_reference_pulse() {
    // 133 MHz: pulse k at cycle ⌈133·k⌉.
    let mut n = nvic(133_000_000);
    n.write(0, RVR, 9);
    n.write(0, CSR, 3); // ENABLE | TICKINT, the reference clock
                        // Reloaded at pulse 1, 0 at pulse 10 (cycle 1330), 20 (2660), …
    assert_eq!(n.read(1329, CVR, 0), Some(1));
    let (zeros, pends) = zeros_and_pends(&mut n, 1330, 2800);
    assert_eq!(pends, [1330, 2660]);
    assert_eq!(zeros, (1330..1463).chain(2660..2793).collect::<Vec<_>>());
    // Switched to the processor clock at 2800 (count 1 of the next period left at pulse
    // 21): the same value, counted in cycles.
    let left = n.read(2800, CVR, 0).unwrap();
    assert_eq!(left, 9);
    n.write(2800, CSR, ON);
    assert_eq!(n.syst_next, 2809);
    // No reference connected (a core outside a board): the counter holds.
    let mut off = Nvic::default();
    off.write(0, RVR, 9);
    off.write(0, CSR, 3);
    off.tick(1_000_000);
    assert!(!pending(&off) && off.syst_next == u64::MAX);
}

/// A handler that alternates the period between 100 and 99 cycles, as the firmware's
/// sample tick alternates ⌊clock/fs⌋ and one more: each core is entered exactly
/// [`EXCEPTION_ENTRY`] cycles after each of its wraps, the wraps as far apart as the
/// periods its handler programs one reload ahead, and a core whose SysTick starts 7 cycles
/// later keeps its own schedule, 7 cycles behind.
#[test]
fn each_cores_handler_is_entered_at_its_own_wraps_with_the_period_it_programs() {
    let mut board = Board::new(Config::default());
    // Per core, a vector table at its base (SysTick = exception 15), code from base + 0x100:
    // main:  r0 = SYST (literal), RVR = 99, CVR = 0, [delay], CSR = 7; wfi; b wfi
    // isr:   RVR ^= 1 (99, 98, 99, …: periods 100, 99, 100, … one reload ahead); r4 += 1
    for (core, delay) in [(0usize, 0usize), (1, 7)] {
        // Own banks (non-striped SRAM0/SRAM1), own stacks (SRAM4/SRAM5): no contention.
        let base = 0x2100_0000 + 0x1_0000 * core as u32;
        let mut code = vec![
            0x480b, // ldr r0, [pc, #44]: PC = +4, the literal at +0x30
            movs(1, 99),
            str(1, 0, 4),
            str(1, 0, 8),
            movs(1, 7),
        ];
        code.extend(std::iter::repeat_n(nop(), delay));
        code.extend([str(1, 0, 0), 0xbf30, b(-2)]); // str; wfi; b wfi
        code.resize(0x18, nop());
        code.extend([0xe010, 0xe000]); // the literal 0xe000e010
        code.resize(0x20, nop());
        code.extend([
            0x6842, // ldr r2, [r0, #4]
            movs(1, 1),
            0x404a, // eors r2, r1
            0x6042, // str r2, [r0, #4]
            adds_imm8(4, 1),
            0x4770, // bx lr
        ]);
        let mut vt = vec![0u8; 0x100];
        vt[15 * 4..16 * 4].copy_from_slice(&((base + 0x140) | 1).to_le_bytes());
        board.write_bytes(base, &vt).unwrap();
        load_program(
            &mut board,
            core,
            base + 0x100,
            0x2004_0800 + 0x1000 * core as u32,
            &code,
        );
        board.cores[core].nvic.vtor = base;
    }
    let p = [
        board.profile_handler(0x2100_0140),
        board.profile_handler(0x2101_0140),
    ];
    assert_eq!(board.run_until(20_000), StopReason::CycleLimit);
    let starts: Vec<Vec<u64>> = p
        .iter()
        .map(|&h| board.calls(h).iter().map(|c| c.start).collect())
        .collect();
    // The first wrap: the enabling store's data phase + 1 + RVR.
    let first = starts[0][0] - EXCEPTION_ENTRY as u64;
    assert!((100..120).contains(&first), "first wrap at {first}");
    for (core, s) in starts.iter().enumerate() {
        assert!(s.len() > 150, "core {core}: {} entries", s.len());
        let mut wrap = first + 7 * core as u64;
        for (i, &at) in s.iter().enumerate() {
            assert_eq!(at, wrap + EXCEPTION_ENTRY as u64, "core {core}: entry {i}");
            wrap += 100 - (i as u64 % 2);
        }
        assert_eq!(
            board.cores[core].r[4] as usize,
            s.len(),
            "core {core}: handler runs"
        );
    }
}
