//! RP2040-specific timing and peripherals: the divider's 8-cycle latency, SRAM bank
//! contention, SIO FIFOs and spinlocks, the launch protocol, and lock-step determinism.

mod common;

use common::enc::*;
use common::load_program;
use tactus_emulator::{Board, Config, StopReason};

const SIO: u32 = 0xd000_0000;

fn board() -> Board {
    Board::new(Config {
        svc_halts: true,
        ..Config::default()
    })
}

/// r0 = SIO base (0xd0000000 = 0xd0 << 24), r1 = divisor, r2 = dividend, r3 = stale marker.
fn sio_prologue(divisor: u16, dividend: u16) -> Vec<u16> {
    vec![
        movs(0, 0xd0),
        lsls(0, 0, 24),
        movs(1, divisor),
        movs(2, dividend),
    ]
}

/// Writes dividend and divisor, waits `delay` cycles (NOPs), reads QUOTIENT, REMAINDER and
/// CSR after that. Returns (quotient, remainder, csr) as read by the program.
fn divide_after(delay: usize, signed: bool, divisor: u16, dividend: u16) -> (u32, u32, u32) {
    let mut b = board();
    let base = if signed { 0x68 } else { 0x60 };
    let mut code = sio_prologue(divisor, dividend);
    code.push(str(2, 0, base)); // DIVIDEND
    code.push(str(1, 0, base + 4)); // DIVISOR: the last operand write, 1 cycle (IO port)
    code.extend(std::iter::repeat_n(nop(), delay));
    code.push(ldr(5, 0, 0x78)); // CSR, 1 cycle
    code.push(ldr(3, 0, 0x70)); // QUOTIENT
    code.push(ldr(4, 0, 0x74)); // REMAINDER
    code.push(svc(0));
    load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, &code);
    assert!(matches!(
        b.run_for(1000),
        StopReason::Svc { core: 0, imm: 0 }
    ));
    let c = &b.cores[0];
    (c.r[3], c.r[4], c.r[5])
}

#[test]
fn divider_result_is_valid_8_cycles_after_the_operand_write() {
    // The CSR load issues `delay + 1` cycles after the divisor store; the quotient load one
    // cycle later. With 7 NOPs the CSR read (cycle +8) is early, the quotient read (+9) is not.
    let (q, r, csr) = divide_after(7, false, 7, 100);
    assert_eq!((q, r), (14, 2));
    assert_eq!(csr & 1, 0, "READY must be clear 8 cycles after the write");
    let (_, _, csr) = divide_after(8, false, 7, 100);
    assert_eq!(csr & 1, 1, "READY must be set 9 cycles after the write");
    // With 6 NOPs the quotient load is at +8: too early, it returns the previous result (0).
    let (q, r, _) = divide_after(6, false, 7, 100);
    assert_eq!(
        (q, r),
        (0, 2),
        "quotient read early is the stale value, remainder read at +9 is valid"
    );
}

#[test]
fn divider_signed_and_by_zero() {
    // 200 / 7 via the signed registers: small positive values, same as unsigned.
    assert_eq!(divide_after(8, true, 7, 200).0, 28);
    // Division by zero: unsigned quotient all ones, remainder = dividend.
    let (q, r, _) = divide_after(8, false, 0, 42);
    assert_eq!((q, r), (u32::MAX, 42));
    // Signed by zero with a non-negative dividend: quotient -1.
    assert_eq!(divide_after(8, true, 0, 42).0, u32::MAX);
}

#[test]
fn divider_signed_negative_operands_via_host_sio() {
    let mut sio = tactus_emulator::sio::Sio::default();
    use tactus_rp2040::sio::reg;
    sio.write(0, 100, reg::DIV_SDIVIDEND, (-7i32) as u32);
    sio.write(0, 100, reg::DIV_SDIVISOR, 2);
    assert_eq!(sio.read(0, 109, reg::DIV_QUOTIENT), Some((-3i32) as u32));
    assert_eq!(sio.read(0, 109, reg::DIV_REMAINDER), Some((-1i32) as u32));
    // Core 1's divider is separate.
    assert_eq!(sio.read(1, 109, reg::DIV_QUOTIENT), Some(0));
}

/// Both cores run `n` loads from `addr0` / `addr1` starting in the same cycle; returns each
/// core's cycle count and stalls.
fn two_core_loads(addr0: u32, addr1: u32, n: usize) -> ([u64; 2], [u64; 2]) {
    let mut b = board();
    for (core, addr, code_at) in [(0usize, addr0, 0x2000_0000u32), (1, addr1, 0x2000_8000)] {
        // r0 = address: build it in r0 with movs/lsls/adds from bytes.
        let mut code = vec![movs(0, (addr >> 24) as u16), lsls(0, 0, 8)];
        code.extend([adds_imm8(0, ((addr >> 16) & 0xff) as u16), lsls(0, 0, 8)]);
        code.extend([adds_imm8(0, ((addr >> 8) & 0xff) as u16), lsls(0, 0, 8)]);
        code.push(adds_imm8(0, (addr & 0xff) as u16));
        code.extend(std::iter::repeat_n(ldr(1, 0, 0), n));
        code.push(svc(core as u16));
        load_program(
            &mut b,
            core,
            code_at,
            0x2000_1000 + 0x100 * core as u32,
            &code,
        );
    }
    let mut cycles = [0; 2];
    for _ in 0..2 {
        match b.run_for(10_000) {
            StopReason::Svc { core, .. } => {
                cycles[core] = b.cores[core].cycle;
                b.cores[core].state = tactus_emulator::core::RunState::Parked;
            }
            other => panic!("unexpected stop {other:?}"),
        }
    }
    (cycles, b.system.contention_stalls)
}

#[test]
fn same_bank_same_cycle_stalls_one_core() {
    // Setup is 7 one-cycle instructions, then n 2-cycle loads, then SVC (0 cycles).
    let n = 10;
    let free = 7 + 2 * n as u64;
    // Striped SRAM: 0x20010000 and 0x20010004 are banks 0 and 1: no contention.
    let (cycles, stalls) = two_core_loads(0x2001_0000, 0x2001_0004, n);
    assert_eq!((cycles, stalls), ([free, free], [0, 0]));
    // 0x20010000 and 0x20010010 are both bank 0: the first loads collide; core 0 wins
    // (same issue cycle), core 1 waits one cycle and is then out of phase for good.
    let (cycles, stalls) = two_core_loads(0x2001_0000, 0x2001_0010, n);
    assert_eq!((cycles, stalls), ([free, free + 1], [0, 1]));
    // The non-striped alias puts consecutive words in one bank: 0x21000000 and 0x21000004
    // are both SRAM0.
    let (_, stalls) = two_core_loads(0x2100_0000, 0x2100_0004, n);
    assert_eq!(stalls, [0, 1]);
    // Scratch bank SRAM4 is one bank.
    let (_, stalls) = two_core_loads(0x2004_0000, 0x2004_0ff0, n);
    assert_eq!(stalls, [0, 1]);
    // SIO is on each core's private IO port: never contends.
    let (cycles, stalls) = two_core_loads(SIO, SIO, n);
    assert_eq!((cycles, stalls), ([7 + n as u64, 7 + n as u64], [0, 0]));
}

#[test]
fn fifo_and_spinlocks() {
    use tactus_emulator::sio::Sio;
    use tactus_rp2040::sio::{reg, FIFO_DEPTH};
    let mut sio = Sio::default();
    // Empty: core 1 sees RDY but not VLD.
    assert_eq!(sio.read(1, 0, reg::FIFO_ST), Some(0b10));
    for i in 0..FIFO_DEPTH as u32 {
        assert!(sio.write(0, 0, reg::FIFO_WR, 100 + i));
    }
    assert_eq!(
        sio.read(0, 0, reg::FIFO_ST).map(|s| s & 2),
        Some(0),
        "full: core 0 not RDY"
    );
    sio.write(0, 0, reg::FIFO_WR, 999); // overflow: dropped, WOF
    assert_eq!(sio.read(0, 0, reg::FIFO_ST).map(|s| s & 4), Some(4));
    assert!(sio.irq(0), "WOF raises SIO_IRQ_PROC0");
    assert_eq!(sio.read(1, 0, reg::FIFO_ST).map(|s| s & 1), Some(1));
    let got: Vec<u32> = (0..FIFO_DEPTH)
        .map(|_| sio.read(1, 0, reg::FIFO_RD).unwrap())
        .collect();
    assert_eq!(got, (100..100 + FIFO_DEPTH as u32).collect::<Vec<_>>());
    assert_eq!(sio.read(1, 0, reg::FIFO_RD), Some(0)); // underflow: ROE
    assert_eq!(sio.read(1, 0, reg::FIFO_ST).map(|s| s & 8), Some(8));
    sio.write(1, 0, reg::FIFO_ST, 0);
    assert_eq!(sio.read(1, 0, reg::FIFO_ST), Some(0b10));
    // Spinlocks: first claim succeeds (reads the lock's bit), second fails (0), release.
    let lock5 = reg::SPINLOCK0 + 4 * 5;
    assert_eq!(sio.read(0, 0, lock5), Some(1 << 5));
    assert_eq!(sio.read(1, 0, lock5), Some(0));
    assert_eq!(sio.read(0, 0, reg::SPINLOCK_ST), Some(1 << 5));
    sio.write(1, 0, lock5, 0);
    assert_eq!(sio.read(1, 0, lock5), Some(1 << 5));
    // CPUID differs per core, through the instruction path too.
    assert_eq!(sio.read(1, 0, reg::CPUID), Some(1));
}

#[test]
fn cpuid_through_both_cores() {
    let mut b = board();
    for core in 0..2usize {
        let code = [
            movs(0, 0xd0),
            lsls(0, 0, 24),
            movs(3, 7),
            ldr(3, 0, 0),
            svc(0),
        ];
        load_program(
            &mut b,
            core,
            0x2000_0000 + 0x100 * core as u32,
            0x2000_1000 + 0x100 * core as u32,
            &code,
        );
    }
    for _ in 0..2 {
        let StopReason::Svc { core, .. } = b.run_for(100) else {
            panic!("no svc")
        };
        b.cores[core].state = tactus_emulator::core::RunState::Parked;
    }
    assert_eq!((b.cores[0].r[3], b.cores[1].r[3]), (0, 1));
}

#[test]
fn core1_launch_protocol_echoes_and_starts() {
    let mut b = board();
    // Core 0 spins; core 1 is parked in the boot ROM, which sent its handshake 0 at reset.
    load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, &[0xe7fe]); // b .
    assert_eq!(b.system.sio.fifo_pop(0), Some(0), "the ROM's handshake 0");
    assert_eq!(b.system.sio.fifo_status(0) & 1, 0, "nothing more");
    // Core 1's program: r2 = 0x55, then SVC #1.
    let code1 = [movs(2, 0x55), svc(1)];
    let bytes: Vec<u8> = code1.iter().flat_map(|h| h.to_le_bytes()).collect();
    b.write_bytes(0x2000_2000, &bytes).unwrap();
    // Word by word, as pico-sdk's multicore_launch_core1_raw: each answered before the next.
    let exchange = |b: &mut Board, w: u32| {
        b.system.sio.fifo_push(0, w);
        let stop = b.run_for(10);
        (stop, b.system.sio.fifo_pop(0))
    };
    // A wrong command sends the ROM back to its handshake: it answers 0, not the word.
    for w in [0, 0] {
        assert_eq!(exchange(&mut b, w).1, Some(0));
    }
    assert_eq!(
        exchange(&mut b, 7).1,
        Some(0),
        "not 1: back to the handshake"
    );
    let seq = [0, 0, 1, 0x2000_3000, 0x2000_4000, 0x2000_2001];
    let mut last = StopReason::CycleLimit;
    for w in seq {
        let (stop, echo) = exchange(&mut b, w);
        assert_eq!(echo, Some(w), "echo of {w:#x}");
        last = stop;
    }
    assert_eq!(last, StopReason::Svc { core: 1, imm: 1 });
    assert_eq!(b.cores[1].r[2], 0x55);
    assert_eq!(b.cores[1].r[13], 0x2000_4000);
    assert_eq!(b.cores[1].nvic.vtor, 0x2000_3000);
    assert_eq!(
        b.system.sio.fifo_status(0) & 0xc,
        0,
        "no FIFO error on core 0"
    );
    assert_eq!(
        b.system.sio.fifo_status(1) & 0xc,
        0,
        "no FIFO error on core 1"
    );
}

#[test]
fn pll_set_up_is_decoded_and_status_bits_read_done() {
    use tactus_emulator::clocks::SysCtl;
    use tactus_rp2040::{clocks, pll, resets};
    let mut s = SysCtl::default();
    assert_eq!(s.pll_sys_hz(), None, "powered down at reset");
    assert_eq!(pll::pll_sys_dividers(125_000_000), Some((125, 6, 2)));
    assert_eq!(pll::pll_sys_dividers(200_000_000), Some((100, 6, 1)));
    assert_eq!(pll::pll_sys_dividers(1_000_000), None);
    let base = pll::PLL_SYS_BASE;
    assert!(s.write(base + pll::reg::FBDIV_INT, 125));
    assert!(s.write(base + pll::reg::PRIM, 6 << 16 | 2 << 12));
    assert!(s.write(base + 0x3000 + pll::reg::PWR, 1 | 1 << 5 | 1 << 3)); // CLR alias
    assert_eq!(
        s.read(base + pll::reg::CS).map(|v| v >> 31),
        Some(1),
        "locked"
    );
    assert_eq!(s.pll_sys_hz(), Some(125_000_000));
    assert_eq!(s.clk_sys_hz(), None, "clk_sys still on clk_ref");
    assert!(s.write(clocks::CLOCKS_BASE + clocks::reg::CLK_SYS_CTRL, 1));
    assert_eq!(
        s.read(clocks::CLOCKS_BASE + clocks::reg::CLK_SYS_SELECTED),
        Some(2)
    );
    assert_eq!(s.clk_sys_hz(), Some(125_000_000));
    assert!(s.write(resets::RESETS_BASE + 0x2000, resets::TIMER)); // SET alias
    assert_eq!(
        s.read(resets::RESETS_BASE + resets::reg::RESET_DONE)
            .map(|v| v & resets::TIMER),
        Some(0)
    );
}

#[test]
fn lock_step_is_deterministic() {
    // Two cores hammering the same banks with loads and stores: two runs, same state.
    let run = || {
        let mut b = board();
        for core in 0..2usize {
            let mut code = vec![movs(0, 0x20), lsls(0, 0, 24), movs(4, 200)];
            // loop: ldr r1,[r0]; adds r1,#1; str r1,[r0]; subs r4,#1; bne loop
            code.extend([
                ldr(1, 0, 0),
                adds_imm8(1, 1 + core as u16),
                str(1, 0, 0),
                subs_imm8(4, 1),
                bcond(1, -8),
            ]);
            code.push(svc(0));
            load_program(
                &mut b,
                core,
                0x2000_0100 + 0x100 * core as u32,
                0x2000_2000 + 0x100 * core as u32,
                &code,
            );
        }
        let mut stops = Vec::new();
        for _ in 0..2 {
            let stop = b.run_for(100_000);
            if let StopReason::Svc { core, .. } = stop {
                stops.push((core, b.cores[core].cycle));
                b.cores[core].state = tactus_emulator::core::RunState::Parked;
            }
        }
        (
            stops,
            b.read_u32(0x2000_0000).unwrap(),
            b.system.contention_stalls,
        )
    };
    let first = run();
    assert_eq!(first, run());
    assert_eq!(first.0.len(), 2, "both cores finished");
    assert!(
        first.2[0] + first.2[1] > 0,
        "the shared word's bank must be contended"
    );
}

#[test]
fn test_encoder_matches_assembler() {
    if !common::have_tool("arm-none-eabi-as", "test_encoder_matches_assembler") {
        return;
    }
    let ex = examples();
    let mut src = String::from(".syntax unified\n.cpu cortex-m0\n.thumb\n.text\n");
    for (_, asm) in &ex {
        src.push_str(asm);
        src.push('\n');
    }
    let text = common::assemble_text(&common::scratch_dir("enc"), "enc", &src);
    let got: Vec<u16> = text
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    let mut at = 0;
    for (hws, asm) in &ex {
        assert_eq!(
            &got[at..at + hws.len()],
            &hws[..],
            "`{asm}`: assembler vs encoder"
        );
        at += hws.len();
    }
}

#[test]
fn wfe_sleeps_until_the_other_core_sends_an_event() {
    let mut b = board();
    // Core 0: 20 NOPs (20 cycles), SEV, then spin. Core 1: WFE, movs r2,#1, SVC #1.
    let mut code0 = vec![nop(); 20];
    code0.extend([0xbf40, 0xe7fe]); // sev; b .
    load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, &code0);
    load_program(
        &mut b,
        1,
        0x2000_0100,
        0x2000_1100,
        &[0xbf20, movs(2, 1), svc(1)],
    ); // wfe
    assert_eq!(b.run_for(1000), StopReason::Svc { core: 1, imm: 1 });
    // Core 1 slept from cycle 2 (WFE costs 2) and woke at the cycle after core 0's SEV
    // (which executes at cycle 20): the MOVS runs at 21, the SVC at 22.
    assert_eq!(b.cores[1].cycle, 22);
    assert_eq!(b.cores[1].r[2], 1);
}

#[test]
fn fifo_interrupt_wakes_wfi() {
    // Core 1 enables SIO_IRQ_PROC1 (IRQ 16) in its NVIC and sleeps in WFI with PRIMASK set,
    // so the wake-up does not take the interrupt; it then reads the word from its FIFO.
    // Core 0 writes 0x5a to FIFO_WR after 30 NOPs.
    let mut b = board();
    let mut code0 = vec![movs(0, 0xd0), lsls(0, 0, 24), movs(1, 0x5a)];
    code0.extend(vec![nop(); 30]);
    code0.extend([str(1, 0, 0x54), 0xe7fe]);
    load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, &code0);
    let code1 = [
        0xb672, // cpsid i
        movs(3, 0xe0),
        lsls(3, 3, 16),
        adds_imm8(3, 0xe1),
        lsls(3, 3, 8), // r3 = 0xe000e100
        movs(4, 1),
        lsls(4, 4, 16), // r4 = 1 << 16
        str(4, 3, 0),   // NVIC_ISER = IRQ 16
        0xbf30,         // wfi
        movs(0, 0xd0),
        lsls(0, 0, 24),
        ldr(5, 0, 0x58), // FIFO_RD: 0 (and ROE) if read before core 0's write
        0xe7fe,          // b .
    ];
    load_program(&mut b, 1, 0x2000_0100, 0x2000_1100, &code1);
    b.cores[1].r[5] = 0xdead;
    assert_eq!(b.run_for(1000), StopReason::CycleLimit);
    assert_eq!(
        b.cores[1].r[5], 0x5a,
        "woke by the FIFO interrupt line and read the word"
    );
    assert_eq!(
        b.cores[1].ipsr, 0,
        "PRIMASK kept the interrupt from being taken"
    );
    assert_eq!(b.system.sio.fifo_status(1) & 8, 0, "no read underflow");
}
