//! The block engine (`Engine::Block`) against the interpreter (`Engine::Interp`, which
//! `fast_path.rs` checks against single steps) on seeded random programs: data processing, SRAM, flash and SIO
//! (divider, FIFO between the cores, CPUID) loads and stores, PUSH/POP, LDM/STM, forward
//! branches, counted backward loops, calls (BL / BX LR), stores into the page that holds the
//! program's own code (the blocks must be dropped), SysTick interrupts, WFI/WFE/SEV with one
//! core asleep, on one core and on both. Each pair of boards runs in slices of random length
//! (1 to 2,500 cycles), so the block engine stops at a deadline in the middle of blocks as
//! well as at their ends; after every slice the stop reason, both cores' cycle counters,
//! instruction counts, registers, flags, exception and run state, the contention stalls and
//! the data area must agree exactly, and all of SRAM at the end of each program. The suite
//! must run at least 10 M instructions per run, and counts its mismatches (which must be 0).
//! The same comparison runs on the firmware-like key updates of the speed bench (SysTick
//! interrupt, one or both cores, sleeping in WFI between samples).

use tactus_emulator::{Board, Config, Engine, StopReason};

/// The banks each core of a two-core firmware image owns (`tactus_firmware`'s
/// `FirmwareImage::own_banks`: core 0 SRAM0, SRAM2 and SRAM4, core 1 SRAM1, SRAM3 and SRAM5).
const OWN_BANKS: [u8; 2] = [0b01_0101, 0b10_1010];
/// The firmware images' DAC window.
const DAC_BASE: u32 = 0x2003_f400;

#[path = "../benches/common/mod.rs"]
mod workloads;

mod common;
use common::Rng;

const SIO: u32 = 0xd000_0000;
/// Code of core k at `CODE + 0x1000 * k` (SRAM) or at flash; its data area, in the same
/// 256-byte page as the end of its code when `code_page_data`, else in its own page.
const CODE: u32 = 0x2000_4000;
const FLASH: u32 = 0x1000_0000;
const VTOR: u32 = 0x2003_0000;
/// Halfwords of straight-line units in each program (before the loop back and the callee).
const UNITS_HALFWORDS: usize = 150;

/// One random unit. Registers: r0-r3 scratch, r4 a loop counter (only inside a loop unit),
/// r5 the SIO base, r6 the data area, r7 a small word offset, r12 a second data area (shared
/// with the other core, or in its bank, or in this core's); SP is balanced within a unit.
/// `leaf`: no loops, calls or branches (inside a loop body).
/// `shared`: the r12 units are generated (two cores), and unit 10 leaves r12 alone.
fn unit(rng: &mut Rng, out: &mut Vec<u16>, leaf: bool, sleepy: bool, shared: bool) {
    if shared && rng.below(24) == 0 {
        // mov r1, r12; ldr/str r0, [r1, #imm]
        out.push(0x4661);
        out.push([0x6008, 0x6808][rng.below(2) as usize] | rng.below(8) << 6);
        return;
    }
    let d = rng.below(4);
    let s = rng.below(8);
    let t = rng.below(8);
    match rng.below(if leaf { 16 } else { 22 }) {
        0 => out.push(0x2000 | d << 8 | rng.below(256)), // movs
        1 => out.push([0x1800, 0x1a00][rng.below(2) as usize] | t << 6 | s << 3 | d),
        2 => out.push([0x1c00, 0x1e00][rng.below(2) as usize] | rng.below(8) << 6 | s << 3 | d),
        3 => out.push([0x3000, 0x3800, 0x2800][rng.below(3) as usize] | d << 8 | rng.below(256)),
        4 => out.push(
            [0x0000, 0x0800, 0x1000][rng.below(3) as usize] | rng.below(32) << 6 | s << 3 | d,
        ),
        5 | 6 => out.push(0x4000 | rng.below(16) << 6 | s << 3 | d), // ALU group
        7 | 8 => {
            // ldr/str/ldrb/strb/ldrh/strh [r6, #imm] (imm5 scaled: always aligned)
            let base = [0x6000, 0x6800, 0x7000, 0x7800, 0x8000, 0x8800][rng.below(6) as usize];
            out.push(base | rng.below(16) << 6 | 6 << 3 | d)
        }
        9 => {
            // register offset, all eight ops: [r6, r7]
            let op = rng.below(8);
            out.push(0x5000 | op << 9 | 7 << 6 | 6 << 3 | d)
        }
        10 => {
            // hi registers: add / cmp / mov among r0-r3, r8-r12 (r8-r11 with `shared`)
            let hi = [0, 1, 2, 3, 8, 9, 10, 11, 12];
            let n = 9 - shared as u32;
            let rd = hi[rng.below(n) as usize];
            let rm = hi[rng.below(n) as usize];
            let op = [0x4400, 0x4500, 0x4600][rng.below(3) as usize];
            out.push(op | (rd & 8) << 4 | rm << 3 | (rd & 7))
        }
        11 => {
            // push {list}; movs; pop {list}
            let list = rng.below(16) | 1;
            out.push(0xb400 | list);
            out.push(0x2000 | d << 8 | rng.below(256));
            out.push(0xbc00 | list);
        }
        12 => {
            // stm/ldm r6!, {list}; subs r6, #4n
            let list = rng.below(16) | 1;
            out.push([0xc600, 0xce00][rng.below(2) as usize] | list);
            out.push(0x3e00 | (4 * list.count_ones() as u16));
        }
        13 => {
            // SIO: CPUID, divider, FIFO status / write / read
            let (offset, op) = [
                (0x00, 0x6800), // ldr CPUID
                (0x60, 0x6000), // str DIV_UDIVIDEND
                (0x64, 0x6000), // str DIV_UDIVISOR
                (0x70, 0x6800), // ldr DIV_QUOTIENT
                (0x78, 0x6800), // ldr DIV_CSR
                (0x50, 0x6800), // ldr FIFO_ST
                (0x54, 0x6000), // str FIFO_WR
                (0x58, 0x6800), // ldr FIFO_RD
            ][rng.below(8) as usize];
            out.push(op | (offset / 4) << 6 | 5 << 3 | d)
        }
        14 => out.push(
            [0xb2c0, 0xb280, 0xba00, 0xba40, 0xbac0, 0xb240, 0xb200][rng.below(7) as usize]
                | s << 3
                | d,
        ),
        15 => out.push(0x4340 | s << 3 | d), // muls
        16 => {
            // forward conditional branch over 0-2 movs
            let n = rng.below(3);
            out.push(0xd000 | rng.below(14) << 8 | n);
            for _ in 0..n {
                out.push(0x2000 | d << 8 | rng.below(256));
            }
        }
        17 | 18 => {
            // counted loop: movs r4, #n; body; subs r4, #1; bne body
            out.push(0x2400 | (1 + rng.below(12)));
            let start = out.len();
            for _ in 0..1 + rng.below(6) {
                unit(rng, out, true, sleepy, shared);
            }
            out.push(0x3c01);
            let back = (start as i32 - out.len() as i32) * 2 - 4;
            out.push(0xd100 | ((back >> 1) as u16 & 0xff));
        }
        19 => out.extend([0xf000, 0xf800]), // bl callee, aimed in `program`
        20 if sleepy && rng.below(3) == 0 => {
            out.push([0xbf30, 0xbf20, 0xbf40][rng.below(3) as usize]) // wfi, wfe, sev
        }
        _ => {
            // b forward over one movs
            out.push(0xe000);
            out.push(0x2000 | d << 8 | rng.below(256));
        }
    }
}

/// A program looping forever, with a callee (`adds r0, #1; bx lr`) after the loop branch;
/// every BL placeholder (`f000 f800`) is aimed at the callee.
fn program(rng: &mut Rng, sleepy: bool, shared: bool) -> Vec<u16> {
    let mut code = Vec::new();
    while code.len() < UNITS_HALFWORDS {
        unit(rng, &mut code, false, sleepy, shared);
    }
    let back = -(code.len() as i32) * 2 - 4;
    code.push(0xe000 | ((back >> 1) as u16 & 0x7ff)); // b start
    let callee = code.len();
    code.extend([0x3001, 0x4770]); // adds r0, #1; bx lr
                                   // Only BL placeholders have the 32-bit prefix 0b11110 in their first halfword.
    for i in 0..callee {
        if code[i] == 0xf000 && code[i + 1] == 0xf800 {
            let imm = (((callee as i32 - i as i32) * 2 - 4) >> 1) as u32;
            code[i] = 0xf000 | ((imm >> 11) & 0x3ff) as u16;
            code[i + 1] = 0xf800 | (imm & 0x7ff) as u16;
        }
    }
    code
}

#[derive(Clone, Copy, Debug)]
struct Case {
    cores: usize,
    in_flash: bool,
    systick: bool,
    sleeper: bool,
    code_page_data: bool,
    /// Each core's code and data in its own SRAM bank (the non-striped alias), its stack in
    /// its scratch bank: the layout on which the cores run ahead of each other.
    own_banks: bool,
}

/// Core `core`'s bank through the non-striped alias.
fn bank(core: usize) -> u32 {
    0x2100_0000 + 0x1_0000 * core as u32
}

fn board(seed: u64, case: Case, engine: Engine) -> Board {
    let mut rng = Rng(seed);
    // One of SRAM0-3 each (the confined code's one-comparison path), or in a third of the
    // programs the firmware images' banks, two of SRAM0-3 each (its general bank check).
    let own_banks = if seed.is_multiple_of(3) {
        OWN_BANKS
    } else {
        [0b01_0001, 0b10_0010]
    };
    let mut b = Board::new(Config {
        engine,
        own_banks,
        ..Config::default()
    });
    // Native code from the first visit on most programs; some run cold code on the
    // pre-decoded path first.
    b.set_compile_threshold((seed % 4).saturating_sub(2) as u32);
    // SysTick handler: adds r4, #1 is not safe (r4 counts loops): adds r3, #1; bx lr.
    b.write_u32(VTOR + 4 * 15, VTOR + 0x101).unwrap();
    b.write_bytes(VTOR + 0x100, &[0x01, 0x33, 0x70, 0x47])
        .unwrap();
    for core in 0..case.cores {
        let code = if case.sleeper && core == 1 {
            vec![0xbf20, 0x3301, 0xe7fc] // wfe; adds r3, #1; b .-4
        } else {
            program(&mut rng, case.sleeper, case.cores == 2)
        };
        assert!(code.len() * 2 <= 0x1c0, "program too long: {}", code.len());
        let bytes: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
        let at = if case.in_flash && core == 0 {
            FLASH
        } else if case.own_banks {
            bank(core) + 0x4000
        } else {
            CODE + 0x1000 * core as u32
        };
        b.write_bytes(at, &bytes).unwrap();
        let data = if case.code_page_data && !(case.in_flash && core == 0) {
            at + 0x1c0 // the page that holds the end of the code
        } else if case.own_banks {
            bank(core) + 0x8000
        } else {
            0x2002_0000 + 0x100 * core as u32
        };
        let fill: Vec<u8> = (0..0x100).map(|_| rng.next() as u8).collect();
        b.write_bytes(data, &fill).unwrap();
        let sp = if case.own_banks {
            0x2004_1000 + 0x1000 * core as u32
        } else {
            0x2003_8000 + 0x1000 * core as u32
        };
        b.start_core(core, at | 1, sp, VTOR);
        let c = &mut b.cores[core];
        for r in 0..13 {
            c.r[r] = rng.next() as u32;
        }
        if case.cores == 2 {
            c.r[12] =
                [0x2002_0800, bank(1 - core) + 0x8000, bank(core) + 0x9000][rng.below(3) as usize];
        }
        c.r[5] = SIO;
        c.r[6] = data;
        c.r[7] = 4 * rng.below(16) as u32;
        if case.systick {
            c.nvic.syst_rvr = 700 + 37 * core as u32;
            c.nvic.syst_csr = 7;
            c.nvic.syst_next = 900 + core as u64;
        }
    }
    b
}

/// Everything a slice must agree on, but all of SRAM (only the data areas, cheaply).
fn state(b: &mut Board) -> String {
    let mut s = common::cores_state(b);
    for area in [
        0x2002_0000u32,
        CODE + 0x1c0,
        CODE + 0x11c0,
        bank(0) + 0x41c0,
        bank(1) + 0x41c0,
        bank(0) + 0x8000,
        bank(1) + 0x8000,
    ] {
        let mut d = vec![0u8; 0x200];
        b.read_bytes(area, &mut d).unwrap();
        s += &format!("data {area:#x} {:016x}\n", hash(&d));
    }
    s
}

fn hash(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &x| {
        (h ^ x as u64).wrapping_mul(0x100_0000_01b3)
    })
}

fn sram(b: &mut Board) -> u64 {
    let mut m = vec![0u8; 0x4_2000];
    b.read_bytes(0x2000_0000, &mut m).unwrap();
    hash(&m)
}

/// Runs one case on both engines; returns (instructions run by the block engine,
/// mismatching slices, windows kept and undone, regions compiled), printing the first
/// mismatch.
fn compare(seed: u64, case: Case, cycles: u64) -> (u64, u32, (u64, u64), u64) {
    let mut block = board(seed, case, Engine::Block);
    let mut interp = board(seed, case, Engine::Interp);
    let mut rng = Rng(seed ^ 0x51ce);
    let mut mismatches = 0;
    let end = cycles;
    while block.cycle() < end {
        let limit = block.cycle() + 1 + rng.below(2500) as u64;
        let a = block.run_until(limit);
        let b = interp.run_until(limit);
        let (sa, sb) = (state(&mut block), state(&mut interp));
        if a != b || sa != sb {
            if mismatches == 0 {
                eprintln!(
                    "case {case:?} seed {seed:#x} at limit {limit}:\nblock  {a:?}\n{sa}\ninterp {b:?}\n{sb}"
                );
            }
            mismatches += 1;
        }
        if a != StopReason::CycleLimit || b != StopReason::CycleLimit {
            break;
        }
    }
    if sram(&mut block) != sram(&mut interp) {
        eprintln!("case {case:?} seed {seed:#x}: SRAM differs at the end");
        mismatches += 1;
    }
    assert_eq!(interp.blocks_decoded(), 0);
    // (With both cores running the block engine leaves the lock-step turns to the
    // interpreter unless they run in windows on their own banks — compiled code only —; it
    // runs while one core sleeps or is parked.)
    if case.cores == 1 || case.sleeper {
        assert!(
            block.blocks_decoded() + block.regions_compiled() > 0,
            "the block engine never ran"
        );
        if case.cores == 1 {
            assert!(
                block.regions_compiled() > 0,
                "no region was compiled on one core: {case:?} seed {seed:#x}"
            );
        }
    }
    let instructions = block.cores.iter().map(|c| c.instructions).sum();
    (
        instructions,
        mismatches,
        block.run_ahead_windows(),
        block.regions_compiled(),
    )
}

#[test]
fn block_engine_matches_the_interpreter_on_random_programs() {
    let mut rng = Rng(0xb10c_e761);
    let (mut instructions, mut mismatches, mut cases) = (0u64, 0u32, 0);
    let mut code_page_runs = 0;
    let mut windows = (0, 0);
    // Two-core cases with a sleeper: (with compiled regions, all). Short lock-step turns
    // (the sleeper awake) run on the interpreter's loop, so a case whose sleeper wakes
    // often may compile nothing; most must.
    let mut sleeper_native = (0, 0);
    for i in 0..64u32 {
        let case = Case {
            cores: 1 + (i % 2) as usize,
            in_flash: i % 4 >= 2,
            systick: i % 8 >= 4,
            sleeper: (i % 16 >= 8) && i % 2 == 1,
            code_page_data: i % 3 == 0,
            own_banks: i % 4 == 1,
        };
        code_page_runs += case.code_page_data as u32;
        let (n, m, w, regions) = compare(rng.next(), case, 300_000);
        if case.cores == 2 && case.sleeper {
            sleeper_native = (
                sleeper_native.0 + (regions > 0) as u32,
                sleeper_native.1 + 1,
            );
        }
        windows = (windows.0 + w.0, windows.1 + w.1);
        instructions += n;
        mismatches += m;
        cases += 1;
    }
    eprintln!(
        "{cases} programs, {instructions} instructions, {mismatches} mismatches, \
         windows kept {}, undone {}",
        windows.0, windows.1
    );
    // Both outcomes of a window are exercised.
    assert!(windows.0 > 0 && windows.1 > 0, "{windows:?}");
    assert_eq!(mismatches, 0, "{mismatches} mismatching slices");
    assert!(
        instructions >= 10_000_000,
        "only {instructions} instructions compared"
    );
    assert!(code_page_runs > 0);
    assert!(
        4 * sleeper_native.0 >= 3 * sleeper_native.1,
        "regions compiled in only {} of {} two-core cases with a sleeper",
        sleeper_native.0,
        sleeper_native.1
    );
}

/// Self-modifying code: a store into the page holding the running block rewrites the
/// block's next instruction, which must run as rewritten.
#[test]
fn a_store_into_the_running_block_takes_effect_at_once() {
    // 0x20004000: str r1, [r0]  (r0 = 0x20004004, r1 = `movs r2, #7; movs r2, #7`)
    //             nop
    //             movs r2, #1   <- overwritten by the store before it runs
    //             movs r2, #1
    //             b .
    for engine in [Engine::Block, Engine::Interp] {
        let mut b = Board::new(Config {
            engine,
            own_banks: OWN_BANKS,
            ..Config::default()
        });
        let code: [u16; 5] = [0x6001, 0xbf00, 0x2201, 0x2201, 0xe7fe];
        let bytes: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
        b.write_bytes(CODE, &bytes).unwrap();
        b.start_core(0, CODE | 1, 0x2003_8000, VTOR);
        b.cores[0].r[0] = CODE + 4;
        b.cores[0].r[1] = 0x2207_2207;
        b.set_compile_threshold(0);
        b.run_for(50);
        assert_eq!(b.cores[0].r[2], 7, "{engine:?}");
    }
}

/// A board on `engine` running `code` (Thumb halfwords at `CODE`) on core 0 with the
/// registers `regs` (number, value) set, compiling a region at its first sight (threshold 0).
fn native_board(engine: Engine, code: &[u16], regs: &[(usize, u32)]) -> Board {
    let mut b = Board::new(Config {
        engine,
        ..Config::default()
    });
    let bytes: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
    b.write_bytes(CODE, &bytes).unwrap();
    b.start_core(0, CODE | 1, 0x2003_8000, VTOR);
    for &(r, v) in regs {
        b.cores[0].r[r] = v;
    }
    b.set_compile_threshold(0);
    b
}

/// A loop whose body sets the flags after an instruction the native code leaves on the
/// second round (a load of SIO): that exit must write the flags back, although no
/// instruction before it sets them in the translation's order (the loop's head is reached
/// again from the back edge; `accel/jit/translate.rs`, `flags_set`), for the `bmi` after
/// the load reads them.
#[test]
fn an_exit_at_a_loop_head_writes_back_the_flags_the_loop_set() {
    // 0x000: mov r2, r2 (four: where the run starts native code, the loop is in its region)
    // 0x008: ldr r0, [r1]     (r1: SRAM, then SIO's CPUID: the native code leaves before it)
    // 0x00a: bmi 0x010        (N clear at the start: the first round goes on)
    // 0x00c: movs r1, r4      (r4 = SIO: N set, Z clear)
    // 0x00e: b 0x008
    // 0x010: adds r5, #1
    // 0x012: b .
    let code: [u16; 10] = [
        0x4612, 0x4612, 0x4612, 0x4612, 0x6808, 0xd401, 0x0021, 0xe7fb, 0x3501, 0xe7fe,
    ];
    let make = |engine| native_board(engine, &code, &[(1, 0x2002_0000), (4, SIO)]);
    let (mut block, mut interp) = (make(Engine::Block), make(Engine::Interp));
    for limit in [100, 200] {
        assert_eq!(block.run_until(limit), interp.run_until(limit));
        assert_eq!(state(&mut block), state(&mut interp), "at {limit}");
    }
    assert_eq!(block.cores[0].r[5], 1, "the second round left the loop");
    assert!(block.regions_compiled() >= 1, "the loop ran as native code");
}

/// A branch island chain (a `B` far ahead to a `B`, to a `B` back, as the firmware's
/// assembler lays out a conditional branch's hop): the region that reaches the first `B`
/// goes on through the islands ([`tactus_emulator`]'s `accel/jit/scan.rs`), so no region
/// starts at an island; and every slice agrees with the interpreter, cut anywhere in the
/// chain.
#[test]
fn a_branch_island_chain_runs_in_one_region_exactly() {
    // 0x000: adds r1, #3
    // 0x002: b 0x400
    // 0x004: subs r4, #1      <- the last island's target
    // 0x006: bne 0x000
    // 0x008: b .
    // 0x400: b 0x500          (an island)
    // 0x500: b 0x004          (an island back)
    // Every other halfword `adds r4, #1`, which no run reaches.
    let mut code = vec![0x3401u16; 0x281];
    code[..5].copy_from_slice(&[0x3103, 0xe1fd, 0x3c01, 0xd1fb, 0xe7fe]);
    code[0x200] = 0xe07e;
    code[0x280] = 0xe580;
    let make = |engine| native_board(engine, &code, &[(4, 50)]);
    // 20 rounds of 6 instructions and 10 cycles (`adds`, the three `B`s, `subs`, `bne`
    // taken) in one run: the native code that reaches the first `B` runs on through both
    // islands, so no region starts at one: three regions compiled (at the head, at the
    // first `B`, where the run's first step leaves the core, and at the islands' target),
    // five without the hops.
    let (mut block, mut interp) = (make(Engine::Block), make(Engine::Interp));
    assert_eq!(block.run_until(200), interp.run_until(200));
    assert_eq!(state(&mut block), state(&mut interp));
    assert_eq!(block.cores[0].r[1], 3 * (50 - block.cores[0].r[4]));
    assert!(block.cores[0].r[4] < 50);
    assert_eq!(block.regions_compiled(), 3, "a region starts at an island");
    // Slices of random length: cut anywhere, with regions that do not fit before the
    // slice's end run pre-decoded.
    let (mut block, mut interp) = (make(Engine::Block), make(Engine::Interp));
    let mut rng = Rng(0x0015_1a4d);
    while block.cycle() < 1_000 {
        let limit = block.cycle() + 1 + rng.below(12) as u64;
        assert_eq!(block.run_until(limit), interp.run_until(limit));
        assert_eq!(state(&mut block), state(&mut interp), "at {limit}");
    }
}

/// The speed bench's firmware-like workload (key updates in the SysTick handler, WFI
/// between samples) on one and on both cores: every slice agrees, and so do the DAC words
/// the handlers wrote.
#[test]
fn block_engine_matches_the_interpreter_on_key_updates() {
    let mut rng = Rng(0x6b65_7973);
    for (cores, keys, period) in [(1, 44, 3016), (2, 44, 3016), (2, 13, 1500), (1, 100, 4000)] {
        let mut block = workloads::key_updates(Engine::Block, cores, keys, period);
        block.set_compile_threshold(0);
        let mut interp = workloads::key_updates(Engine::Interp, cores, keys, period);
        while block.cycle() < 200_000 {
            let limit = block.cycle() + 1 + rng.below(5000) as u64;
            let a = block.run_until(limit);
            let b = interp.run_until(limit);
            assert_eq!(a, b, "{cores} cores, {keys} keys: stop reasons differ");
            assert_eq!(
                state(&mut block),
                state(&mut interp),
                "{cores} cores, {keys} keys at {limit}"
            );
        }
        let mut dac = [vec![0u8; 4 * 128], vec![0u8; 4 * 128]];
        block.read_bytes(DAC_BASE, &mut dac[0]).unwrap();
        interp.read_bytes(DAC_BASE, &mut dac[1]).unwrap();
        assert_eq!(dac[0], dac[1]);
        assert!(
            dac[0].iter().any(|&x| x != 0),
            "the handlers wrote no force"
        );
        assert_eq!(sram(&mut block), sram(&mut interp));
        assert!(block.blocks_decoded() > 0);
        assert!(block.regions_compiled() > 0);
        let handled: u64 = block.cores.iter().map(|c| c.instructions).sum();
        assert!(handled > 10_000, "{handled} instructions");
    }
}

/// Two cores on their own banks (the speed loop with each core's code and data in its own
/// SRAM bank, stacks in the scratch banks) run ahead of each other: the windows are kept
/// and every slice agrees with the interpreter's lock-step.
#[test]
fn two_cores_on_their_own_banks_run_ahead_exactly() {
    let mut rng = Rng(0x0a7e_ad00);
    let mut block = workloads::speed_loop_own_banks(Engine::Block, 2);
    block.set_compile_threshold(0);
    let mut interp = workloads::speed_loop_own_banks(Engine::Interp, 2);
    while block.cycle() < 400_000 {
        let limit = block.cycle() + 1 + rng.below(20_000) as u64;
        assert_eq!(block.run_until(limit), interp.run_until(limit));
        assert_eq!(state(&mut block), state(&mut interp), "at {limit}");
    }
    assert_eq!(sram(&mut block), sram(&mut interp));
    let (kept, rolled_back) = block.run_ahead_windows();
    eprintln!("windows kept {kept}, rolled back {rolled_back}");
    assert!(kept > 10, "{kept} windows kept");
    assert_eq!(interp.run_ahead_windows(), (0, 0));
}

/// Windows with self-modifying code and undos: core 0 rewrites an instruction of its own
/// loop every iteration (in its own bank), core 1 reads the FIFO status (shared SIO) every
/// 50 iterations of its own loop, so windows in which core 0 ran — rewriting and
/// recompiling its code — are undone when core 1 cannot reach the end past its SIO load.
/// Every slice agrees with the interpreter, and both outcomes occur.
#[test]
fn running_ahead_rolls_back_self_modifying_code_exactly() {
    let setup = |engine| {
        let mut b = Board::new(Config {
            engine,
            own_banks: OWN_BANKS,
            ..Config::default()
        });
        // Core 0: ldr r1,[r0]; eors r1,r2; str r1,[r0]; nop;
        //   target: movs r3,#1 (toggled with #2); adds r4,r4,r3; subs r5,#1; bne loop
        let c0: [u16; 8] = [
            0x6801, 0x4051, 0x6001, 0xbf00, 0x2301, 0x18e4, 0x3d01, 0xd1f7,
        ];
        // Core 1: loop: ldr r1,[r0]; adds r1,#1; str r1,[r0]; subs r5,#1; bne loop;
        //   ldr r2,[r6] (SIO FIFO_ST); movs r5,#50; b loop
        let c1: [u16; 8] = [
            0x6801, 0x3101, 0x6001, 0x3d01, 0xd1fa, 0x6832, 0x2532, 0xe7f7,
        ];
        for (core, code, at) in [(0, c0, bank(0) + 0x100), (1, c1, bank(1) + 0x500)] {
            let bytes: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
            b.write_bytes(at, &bytes).unwrap();
            b.start_core(core, at | 1, 0x2004_1000 + 0x1000 * core as u32, 0);
        }
        let c = &mut b.cores[0];
        (c.r[0], c.r[2], c.r[5]) = (bank(0) + 0x108, 3, u32::MAX);
        let c = &mut b.cores[1];
        (c.r[0], c.r[5], c.r[6]) = (bank(1) + 0x8000, 50, SIO + 0x50);
        b
    };
    let mut block = setup(Engine::Block);
    block.set_compile_threshold(0);
    let mut interp = setup(Engine::Interp);
    let mut rng = Rng(0x5e1f);
    while block.cycle() < 100_000 {
        let limit = block.cycle() + 1 + rng.below(8000) as u64;
        assert_eq!(block.run_until(limit), interp.run_until(limit));
        assert_eq!(state(&mut block), state(&mut interp), "at {limit}");
    }
    assert_eq!(sram(&mut block), sram(&mut interp));
    let (kept, rolled_back) = block.run_ahead_windows();
    eprintln!("windows kept {kept}, rolled back {rolled_back}");
    assert!(
        kept > 0 && rolled_back > 0,
        "{kept} kept, {rolled_back} rolled back"
    );
}

/// Each core's SysTick handler reads SysTick's and the SCB's registers (SYST_CSR, which
/// clears COUNTFLAG; SYST_CVR, SYST_RVR, ICSR), stores SYST_RVR (a reload alternating by
/// one, as the firmware images' fractional sample period does) and SYST_CSR, and sums what
/// it read into its own bank, between WFIs: the sample interrupt's private peripheral
/// accesses, which native code makes in windows (`jit::abi::ppb_load`, `ppb_store`; the
/// CSR store leaves for the general path). Every slice agrees with the interpreter's
/// lock-step — registers, SysTick's state, the sums — and the windows are kept.
#[test]
fn private_peripheral_accesses_in_windows_match_the_interpreter() {
    let bytes = |code: &[u16]| -> Vec<u8> { code.iter().flat_map(|h| h.to_le_bytes()).collect() };
    let setup = |engine| {
        let mut b = Board::new(Config {
            engine,
            own_banks: OWN_BANKS,
            ..Config::default()
        });
        b.set_compile_threshold(0);
        for core in 0..2 {
            let base = bank(core);
            let handler = base + 0x100 + 0x400 * core as u32;
            let main = handler + 0x200;
            let data = base + 0x8000;
            let mut h: Vec<u16> = vec![
                0x4800, // ldr r0, =SYST_CSR
                0x6801, // ldr r1, [r0]      SYST_CSR (clears COUNTFLAG)
                0x6882, // ldr r2, [r0, #8]  SYST_CVR
                0x6843, // ldr r3, [r0, #4]  SYST_RVR
                0x4c00, // ldr r4, =ICSR
                0x6824, // ldr r4, [r4]
                0x2501, // movs r5, #1
                0x406b, // eors r3, r5
                0x6043, // str r3, [r0, #4]  SYST_RVR
                0x2507, // movs r5, #7
                0x6005, // str r5, [r0]      SYST_CSR (the general path)
                0x4e00, // ldr r6, =data
                0x6837, // ldr r7, [r6]
                0x187f, // adds r7, r7, r1
                0x18bf, // adds r7, r7, r2
                0x193f, // adds r7, r7, r4
                0x6037, // str r7, [r6]
                0x6877, // ldr r7, [r6, #4]
                0x3701, // adds r7, #1
                0x6077, // str r7, [r6, #4]
                0x4770, // bx lr
                0xbf00, // nop (the pool word-aligned)
            ];
            let pool = h.len();
            for (i, at) in [0usize, 4, 11].into_iter().enumerate() {
                let pc = handler + 2 * at as u32;
                let lit = handler + 2 * pool as u32 + 4 * i as u32;
                h[at] |= ((lit - ((pc + 4) & !3)) / 4) as u16;
            }
            let mut code = bytes(&h);
            for l in [0xe000_e010u32, 0xe000_ed04, data] {
                code.extend(l.to_le_bytes());
            }
            b.write_bytes(handler, &code).unwrap();
            b.write_bytes(main, &bytes(&[0xbf30, 0xe7fd])).unwrap(); // wfi; b .-2
            b.write_u32(base + 4 * 15, handler | 1).unwrap();
            b.start_core(core, main | 1, 0x2004_1000 + 0x1000 * core as u32, base);
            let c = &mut b.cores[core];
            c.nvic.syst_rvr = 700 + 37 * core as u32;
            c.nvic.syst_csr = 7;
            c.nvic.syst_next = 900 + core as u64;
        }
        b
    };
    let mut block = setup(Engine::Block);
    let mut interp = setup(Engine::Interp);
    let nvic = |b: &Board| -> String {
        b.cores
            .iter()
            .map(|c| {
                let n = &c.nvic;
                format!(
                    "rvr {} csr {} countflag {} next {} fired {} pending {:x} active {:x}\n",
                    n.syst_rvr,
                    n.syst_csr,
                    n.countflag,
                    n.syst_next,
                    n.syst_fired,
                    n.pending,
                    n.active
                )
            })
            .collect()
    };
    let mut rng = Rng(0x5157_5452);
    while block.cycle() < 300_000 {
        let limit = block.cycle() + 1 + rng.below(8000) as u64;
        assert_eq!(block.run_until(limit), interp.run_until(limit));
        assert_eq!(state(&mut block), state(&mut interp), "at {limit}");
        assert_eq!(nvic(&block), nvic(&interp), "at {limit}");
    }
    for core in 0..2 {
        let count = block.read_u32(bank(core) + 0x8004).unwrap();
        assert!(count > 300, "core {core}: {count} handler runs");
    }
    let (kept, _) = block.run_ahead_windows();
    assert!(kept > 30, "{kept} windows kept");
}
