//! The fast path of `Board::run_until` (decode cache, bursts, both cores interleaved in one
//! loop) against `Board::step`, which runs the general path one instruction at a time:
//! seeded random programs of data processing, SRAM/flash/SIO loads and stores, timer reads, PUSH/POP,
//! LDM/STM and forward branches, looping forever, on one core and on both (sharing a data
//! area, so the SRAM banks contend), some with WFI/WFE/SEV (so one core sleeps while the other
//! runs) and some with a SysTick interrupt whose handler returns at once.
//! Some runs profile functions (`Board::profile_addr`). After every run the cycle counters,
//! registers, flags, instruction counts, contention stalls, stop reason, all of SRAM and the
//! profiled calls must agree exactly. The last cases address their data through the
//! non-striped SRAM aliases (one bank per core, as firmware that keeps each core's data in
//! its own bank does), which the fast path maps to the same bytes and banks.

use tactus_emulator::{Board, Config, StopReason};

mod common;
use common::Rng;

const DATA: u32 = 0x2002_0000;
const SIO: u32 = 0xd000_0000;

/// One random unit (one to three instructions). Registers: r0-r4 are scratch, r5 holds
/// the SIO base, r6 the data area, r7 a small offset; SP is balanced within a unit.
fn unit(rng: &mut Rng, out: &mut Vec<u16>) {
    let d = rng.below(5);
    let s = rng.below(8);
    let t = rng.below(8);
    match rng.below(22) {
        0 => out.push(0x2000 | d << 8 | rng.below(256)), // movs
        1 => out.push([0x1800, 0x1a00][rng.below(2) as usize] | t << 6 | s << 3 | d),
        2 => out.push([0x1c00, 0x1e00][rng.below(2) as usize] | rng.below(8) << 6 | s << 3 | d),
        3 => out.push([0x3000, 0x3800, 0x2800][rng.below(3) as usize] | d << 8 | rng.below(256)),
        4 => out.push(
            [0x0000, 0x0800, 0x1000][rng.below(3) as usize] | rng.below(32) << 6 | s << 3 | d,
        ),
        5 | 6 => out.push(0x4000 | rng.below(16) << 6 | s << 3 | d), // data processing
        7 | 8 => {
            // ldr/str/ldrb/strb/ldrh/strh [r6, #imm]
            let (base, scale) = [
                (0x6000, 4),
                (0x6800, 4),
                (0x7000, 1),
                (0x7800, 1),
                (0x8000, 2),
                (0x8800, 2),
            ][rng.below(6) as usize];
            let _ = scale; // imm5 is scaled by the access size, so every offset is aligned
            out.push(base | rng.below(32) << 6 | 6 << 3 | d)
        }
        9 => {
            // register offset, all eight ops: [r6, r7]
            let op = rng.below(8);
            let d = if op < 3 { s.min(7) } else { d };
            out.push(0x5000 | op << 9 | 7 << 6 | 6 << 3 | d)
        }
        10 => {
            // hi registers: add / cmp / mov among r0-r4, r8-r12
            let hi = [0, 1, 2, 3, 4, 8, 9, 10, 11, 12];
            let rd = hi[rng.below(10) as usize];
            let rm = hi[rng.below(10) as usize];
            let op = [0x4400, 0x4500, 0x4600][rng.below(3) as usize];
            out.push(op | (rd & 8) << 4 | rm << 3 | (rd & 7))
        }
        11 => {
            // push {list}; one unit; pop {list}
            let list = rng.below(32) | 1;
            out.push(0xb400 | list | rng.below(2) << 8);
            let lr = out.last().unwrap() & 0x100;
            out.push(0x2000 | d << 8 | rng.below(256));
            out.push(0xbc00 | list);
            if lr != 0 {
                // pop lr's slot too: add sp, #4
                out.push(0xb001);
            }
        }
        12 => {
            // stm/ldm r6!, {list}; subs r6, #4n
            let list = rng.below(32) | 1;
            out.push([0xc600, 0xce00][rng.below(2) as usize] | list);
            out.push(0x3e00 | (4 * list.count_ones() as u16));
        }
        13 => {
            // forward conditional branch over 0-2 movs
            let n = rng.below(3);
            out.push(0xd000 | rng.below(14) << 8 | n);
            for _ in 0..n {
                out.push(0x2000 | d << 8 | rng.below(256));
            }
        }
        14 => {
            // SIO: CPUID, divider operands and results
            let (offset, op) = [
                (0x00, 0x6800), // ldr CPUID
                (0x60, 0x6000), // str DIV_UDIVIDEND
                (0x64, 0x6000), // str DIV_UDIVISOR
                (0x70, 0x6800), // ldr DIV_QUOTIENT
                (0x74, 0x6800), // ldr DIV_REMAINDER
                (0x74, 0x6000), // str DIV_REMAINDER
                (0x78, 0x6800), // ldr DIV_CSR
            ][rng.below(7) as usize];
            out.push(op | (offset / 4) << 6 | 5 << 3 | d)
        }
        15 => out.push(
            [0xb2c0, 0xb280, 0xba00, 0xba40, 0xbac0, 0xb240, 0xb200][rng.below(7) as usize]
                | s << 3
                | d,
        ),
        16 => out.push(0xbf00), // nop
        17 => {
            // add rd, sp, #imm; adr
            out.push([0xa800, 0xa000][rng.below(2) as usize] | d << 8 | rng.below(256))
        }
        18 => out.push(0x4840 | d << 8 | rng.below(4)), // ldr rd, [pc, #n] (even n*4)
        19 if rng.below(4) == 0 => out.push([0xbf30, 0xbf20, 0xbf40][rng.below(3) as usize]), // wfi, wfe, sev
        20 => {
            // A timer read (the firmware's TIMERAWL): rd = 0x40054000 by movs/lsls/adds,
            // then ldr rd, [rd, #offset] — TIMELR, TIMERAWH, TIMERAWL, ARMED, INTR, or an
            // unmapped offset (a fault).
            out.push(0x2040 | d << 8); // movs rd, #0x40
            out.push(0x0200 | d << 3 | d); // lsls rd, rd, #8
            out.push(0x3005 | d << 8); // adds rd, #5
            out.push(0x0380 | d << 3 | d); // lsls rd, rd, #14
            let offset = [0x0c, 0x24, 0x28, 0x28, 0x20, 0x34, 0x3c][rng.below(7) as usize];
            out.push(0x6800 | (offset / 4) << 6 | d << 3 | d);
        }
        _ => {
            // b forward over one movs
            out.push(0xe001);
            out.push(0x2000 | d << 8 | rng.below(256));
            out.push(0xbf00);
        }
    }
}

fn program(rng: &mut Rng, sev: bool) -> Vec<u16> {
    let mut code = Vec::new();
    while code.len() < 200 {
        unit(rng, &mut code);
        if sev && rng.below(8) == 0 {
            code.push(0xbf40);
        }
    }
    let back = -(code.len() as i32) * 2 - 4;
    code.push(0xe000 | ((back >> 1) as u16 & 0x7ff)); // b start
    code
}

/// `sleeper`: core 1 runs `wfe; adds r4, #1; b .-4` and core 0's program has extra SEVs.
/// `profile`: two addresses of each program are profiled, with LR pointing into it.
fn board(
    rng: &mut Rng,
    cores: usize,
    in_flash: bool,
    systick: bool,
    sleeper: bool,
    profile: bool,
    alias: bool,
) -> Board {
    let mut b = Board::new(Config::default());
    let mut data = vec![0u8; 1024];
    for x in data.iter_mut() {
        *x = rng.next() as u8;
    }
    b.write_bytes(DATA, &data).unwrap();
    // Vector table at 0x20030000: SysTick -> handler (adds r4, #1; bx lr).
    let vtor = 0x2003_0000;
    b.write_u32(vtor + 4 * 15, 0x2003_0101).unwrap();
    b.write_bytes(0x2003_0100, &[0x01, 0x34, 0x70, 0x47])
        .unwrap();
    for core in 0..cores {
        let code = if sleeper && core == 1 {
            vec![0xbf20, 0x3401, 0xe7fc]
        } else {
            program(rng, sleeper)
        };
        let bytes: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
        let at = if in_flash && core == 0 {
            0x1000_0000
        } else {
            0x2000_4000 + 0x1000 * core as u32
        };
        b.write_bytes(at, &bytes).unwrap();
        b.start_core(core, at | 1, 0x2003_8000 + 0x1000 * core as u32, vtor);
        if profile {
            let len = code.len() as u32;
            b.profile_addr(at + 2 * rng.below(len) as u32);
            b.profile_addr(at + 2 * rng.below(len) as u32);
            b.cores[core].r[14] = (at + 2 * rng.below(len) as u32) | 1;
        }
        let c = &mut b.cores[core];
        for r in 0..13 {
            c.r[r] = rng.next() as u32;
        }
        c.r[5] = SIO;
        c.r[6] = if alias {
            // Bank `core` through its non-striped alias (0x21000000 + 64 KB per bank).
            0x2100_0000 + 0x1_0000 * core as u32 + 0x8000
        } else {
            DATA + 0x100 + 0x40 * core as u32
        };
        c.r[7] = 4 * rng.below(16) as u32;
        if systick {
            c.nvic.syst_rvr = 300 + 37 * core as u32;
            c.nvic.syst_csr = 7;
            c.nvic.syst_next = 500 + core as u64;
        }
    }
    b
}

fn state(b: &mut Board, profiles: usize) -> String {
    let mut s = String::new();
    for h in 0..profiles {
        s += &format!("calls {h}: {:?}\n", b.calls(h));
    }
    s += &common::cores_state(b);
    let mut sram = vec![0u8; 0x4_2000];
    b.read_bytes(0x2000_0000, &mut sram).unwrap();
    let h = sram.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &x| {
        (h ^ x as u64).wrapping_mul(0x100_0000_01b3)
    });
    s += &format!("sram {h:016x}\n");
    s
}

fn stepped(b: &mut Board, limit: u64) -> StopReason {
    loop {
        match b.step(limit) {
            None => return StopReason::CycleLimit,
            Some(Ok(_)) => {}
            Some(Err(stop)) => return stop,
        }
    }
}

#[test]
fn run_until_matches_single_steps() {
    let mut rng = Rng(0x5eed_fa57);
    let mut runs = 0;
    for case in 0..96 {
        let cores = 1 + case % 2;
        let in_flash = case % 4 >= 2;
        let systick = case % 8 >= 4;
        let sleeper = (48..64).contains(&case) && cores == 2;
        let profile = (64..80).contains(&case);
        let alias = case >= 80;
        let profiles = if profile { 2 * cores } else { 0 };
        let seed = rng.next();
        let mut fast = board(
            &mut Rng(seed),
            cores,
            in_flash,
            systick,
            sleeper,
            profile,
            alias,
        );
        let mut slow = board(
            &mut Rng(seed),
            cores,
            in_flash,
            systick,
            sleeper,
            profile,
            alias,
        );
        // Several slices, so runs stop and resume mid-stream.
        for slice in [1, 7, 500, 3000, 20_000] {
            let limit = fast.cycle() + slice;
            let a = fast.run_until(limit);
            let b = stepped(&mut slow, limit);
            let (sa, sb) = (state(&mut fast, profiles), state(&mut slow, profiles));
            assert_eq!(a, b, "case {case} seed {seed:#x}: stop reasons differ");
            assert_eq!(
                sa, sb,
                "case {case} seed {seed:#x} slice {slice}: states differ"
            );
            runs += 1;
            if a != StopReason::CycleLimit {
                break;
            }
        }
    }
    assert!(runs > 96);
}

/// `Board::profile_handler` on the SysTick handler (entered only by exception entry) counts
/// the same calls as `Board::profile_addr` on it, while the fast path watches nothing; the
/// runs agree with single steps in everything else too.
#[test]
fn a_profiled_handler_costs_the_fast_path_nothing_and_counts_like_a_profiled_function() {
    let mut rng = Rng(0x4a4d_1e55);
    let mut calls = 0;
    for case in 0..16 {
        let cores = 1 + case % 2;
        let seed = rng.next();
        let make = |handler: bool| {
            let mut b = board(
                &mut Rng(seed),
                cores,
                case % 4 >= 2,
                true,
                false,
                false,
                false,
            );
            if handler {
                b.profile_handler(0x2003_0101);
            } else {
                b.profile_addr(0x2003_0101);
            }
            b
        };
        let (mut fast, mut slow) = (make(true), make(false));
        for slice in [1, 7, 500, 3000, 20_000] {
            let limit = fast.cycle() + slice;
            let a = fast.run_until(limit);
            let b = stepped(&mut slow, limit);
            assert_eq!(a, b, "case {case} seed {seed:#x}: stop reasons differ");
            let (sa, sb) = (state(&mut fast, 1), state(&mut slow, 1));
            assert_eq!(
                sa, sb,
                "case {case} seed {seed:#x} slice {slice}: states differ"
            );
            if a != StopReason::CycleLimit {
                break;
            }
        }
        calls += fast.calls(0).len();
    }
    assert!(calls > 16, "{calls} handler calls");
}
