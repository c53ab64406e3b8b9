//! The block compiler's native code, one instruction at a time, against the interpreter's
//! executor (`Core::execute_op`, whose per-instruction methods define the semantics): a
//! random 16-bit instruction (or a BL pair), or two, followed by a BKPT, on random registers and
//! flags whose values are biased towards the memory map's interesting places (striped
//! SRAM, SRAM4/5, the non-striped aliases, flash, the code itself, the ends of SRAM and
//! of the striped view, either side of SRAM's start and unaligned addresses), with the other core's bank claims set so the arbiter's wait
//! states come into play (in a third of the cases claims all in the past: the engine's
//! solo code, which records claims without arbitrating). Both engines run the same cycles; the stop reason, every
//! register, flag, counter, the contention stalls and all of SRAM must agree after each
//! case. The block engine compiles every region at first sight (threshold 0). A quarter of
//! the cases run their code through the non-striped alias.

use tactus_emulator::{Board, Config, Engine};

mod common;
use common::Rng;

const CODE: u32 = 0x2000_4000;
/// The same code through the non-striped alias (SRAM0 at 0x1000), as the firmware images
/// place each core's code: its regions try the alias view first.
const CODE_ALIAS: u32 = 0x2100_1000;
const VTOR: u32 = 0x2003_0000;

fn value(rng: &mut Rng) -> u32 {
    let r = rng.next() as u32;
    match rng.below(11) {
        0 => r,
        1 => 0x2000_0000 + (r % 0x4_2000),
        2 => 0x2000_0000 + ((r % 0x4_2000) & !3),
        3 => 0x2100_0000 + ((r % 0x4_0000) & !3),
        4 => 0x1000_0000 + ((r % 0x1000) & !3),
        5 => CODE + ((r % 0x40) & !1),
        6 => 0x2004_2000 - 4 * (r % 8),
        7 => r % 64,
        // Either side of the striped view's end and of SRAM's start, aligned or not (the
        // native code's one comparison for an aligned striped access).
        8 => 0x2004_0000 - 4 + (r % 8),
        9 => 0x2000_0000 - 4 + (r % 8),
        _ => 0xd000_0000 + ((r % 0x80) & !3),
    }
}

fn instruction(rng: &mut Rng) -> Vec<u16> {
    let h = rng.next() as u16;
    match rng.below(12) {
        // BL with a small offset
        0 => vec![0xf000 | rng.below(8), 0xf800 | rng.below(0x40)],
        // B<cond> and B with short offsets
        1 => vec![0xd000 | (rng.below(14) << 8) | (h & 0x0f)],
        2 => vec![0xe000 | (h & 0x0f)],
        // PUSH/POP, LDM/STM, misc
        3 => vec![0xb000 | (h & 0x0fff)],
        4 => vec![0xc000 | (h & 0x0fff)],
        // the ALU group and high-register operations
        8 | 9 => vec![0x4000 | (h & 0x07ff)],
        // loads and stores with register or immediate offsets
        10 => vec![0x5000 | (h & 0x2fff)],
        // anything below 0xc000: shifts, add/sub, immediates, loads, stores, SP, misc
        _ => vec![h % 0xc000],
    }
}

fn board(engine: Engine) -> Board {
    let mut b = Board::new(Config {
        engine,
        ..Config::default()
    });
    b.set_compile_threshold(0);
    b
}

fn state(b: &Board) -> String {
    let c = &b.cores[0];
    format!(
        "cycle {} instr {} r {:08x?} nzcv {}{}{}{} state {:?} fault {:?} stalls {:?}",
        c.cycle,
        c.instructions,
        c.r,
        c.n as u8,
        c.z as u8,
        c.c as u8,
        c.v as u8,
        c.state,
        c.fault,
        b.system.contention_stalls
    )
}

#[test]
fn every_translated_instruction_matches_the_interpreter() {
    let mut rng = Rng(0x0b1e_c7ed);
    let mut boards = [board(Engine::Block), board(Engine::Interp)];
    let mut mismatches = 0;
    let cases = 20_000;
    for case in 0..cases {
        // One or two instructions: the second sees the first's pending cycles and flags.
        let mut code = instruction(&mut rng);
        if rng.below(2) == 0 {
            code.extend(instruction(&mut rng));
        }
        code.push(0xbe00); // bkpt: not translated, the region ends before it
        let bytes: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
        let regs: Vec<u32> = (0..15).map(|_| value(&mut rng)).collect();
        let sp = [0x2003_8000, 0x2004_1000, 0x2004_2000, 0x2000_0008][rng.below(4) as usize];
        let flags = rng.below(16);
        let claims = rng.next();
        // A third of the cases: every claim of core 1 in the past, so the block engine
        // runs its solo code (no arbitration, only its own claims recorded).
        let past = rng.below(3) == 0;
        let at = if rng.below(4) == 0 { CODE_ALIAS } else { CODE };
        let mut out = Vec::new();
        for b in boards.iter_mut() {
            b.write_bytes(at, &bytes).unwrap();
            b.start_core(0, at | 1, sp, VTOR);
            let now = b.cores[0].cycle;
            // Core 1 parked but with recent bank claims: the arbiter sees them (or, `past`,
            // claims that no access of core 0 can meet).
            for bank in 0..6 {
                let at = if past {
                    now.saturating_sub((claims >> (4 * bank)) & 3)
                } else {
                    now + 1 + ((claims >> (4 * bank)) & 3)
                };
                b.system.set_bank_claim(1, bank, at);
            }
            let c = &mut b.cores[0];
            c.r[..13].copy_from_slice(&regs[..13]);
            c.r[14] = regs[14];
            (c.n, c.z, c.c, c.v) = (
                flags & 8 != 0,
                flags & 4 != 0,
                flags & 2 != 0,
                flags & 1 != 0,
            );
            let stop = b.run_until(now + 40);
            out.push((stop, state(b)));
        }
        let same_sram = boards[0].system.sram == boards[1].system.sram;
        if out[0] != out[1] || !same_sram {
            if mismatches < 5 {
                eprintln!(
                    "case {case}: {code:04x?} regs {regs:08x?} sp {sp:#x} flags {flags:04b}\n  block  {:?}\n  interp {:?}\n  sram equal: {same_sram}",
                    out[0], out[1]
                );
            }
            mismatches += 1;
            // Start the next case from equal memories.
            let sram = boards[1].system.sram.clone();
            boards[0].system.sram = sram;
        }
    }
    assert!(boards[0].regions_compiled() > 100);
    assert_eq!(mismatches, 0, "{mismatches} of {cases} cases differ");
}

/// The same cases compiled *confined* (`board/window.rs`): core 1 sleeps in WFI in SRAM5
/// with nothing to wake it, core 0 owns every other bank, so each case runs in a window —
/// core 0's code from the journaled confined cache — unless it touches SRAM5, SIO or a
/// peripheral, which undoes the window and runs it in lock-step. Each case ends in a
/// `B .` loop (translated, so a kept window runs it to the end) instead of a BKPT. The
/// windows kept and undone are both counted.
#[test]
fn every_translated_instruction_matches_the_interpreter_confined() {
    let mut rng = Rng(0xc0f1_7ed5);
    let windowed = |engine| {
        let mut b = Board::new(Config {
            engine,
            own_banks: [0b01_1111, 0b10_0000],
            ..Config::default()
        });
        b.set_compile_threshold(0);
        b
    };
    let mut boards = [windowed(Engine::Block), windowed(Engine::Interp)];
    let sleeper = 0x2004_1800;
    for b in boards.iter_mut() {
        b.write_bytes(sleeper, &[0x30, 0xbf, 0xfd, 0xe7]).unwrap(); // wfi; b .-2
        b.start_core(1, sleeper | 1, 0x2004_1f00, VTOR);
    }
    let mut mismatches = 0;
    let cases = 20_000;
    for case in 0..cases {
        let mut code = instruction(&mut rng);
        if rng.below(2) == 0 {
            code.extend(instruction(&mut rng));
        }
        code.push(0xe7fe); // b .
        let bytes: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
        let regs: Vec<u32> = (0..15).map(|_| value(&mut rng)).collect();
        let sp = [0x2003_8000, 0x2004_1000, 0x2004_0800, 0x2000_0008][rng.below(4) as usize];
        let flags = rng.below(16);
        let at = if rng.below(4) == 0 { CODE_ALIAS } else { CODE };
        let mut out = Vec::new();
        for b in boards.iter_mut() {
            b.write_bytes(at, &bytes).unwrap();
            b.start_core(0, at | 1, sp, VTOR);
            // Past the lock-step stretch that follows an undone window.
            let now = b.cores[0].cycle.max(b.cores[1].cycle) + 5000;
            b.cores[0].cycle = now;
            b.cores[1].cycle = now;
            let c = &mut b.cores[0];
            c.r[..13].copy_from_slice(&regs[..13]);
            c.r[14] = regs[14];
            (c.n, c.z, c.c, c.v) = (
                flags & 8 != 0,
                flags & 4 != 0,
                flags & 2 != 0,
                flags & 1 != 0,
            );
            let stop = b.run_until(now + 100);
            out.push((stop, state(b), b.cores[1].cycle, b.cores[1].state));
        }
        let same_sram = boards[0].system.sram == boards[1].system.sram;
        if out[0] != out[1] || !same_sram {
            if mismatches < 5 {
                eprintln!(
                    "case {case}: {code:04x?} regs {regs:08x?} sp {sp:#x} flags {flags:04b}\n  block  {:?}\n  interp {:?}\n  sram equal: {same_sram}",
                    out[0], out[1]
                );
            }
            mismatches += 1;
            let sram = boards[1].system.sram.clone();
            boards[0].system.sram = sram;
        }
    }
    let (kept, undone) = boards[0].run_ahead_windows();
    eprintln!("windows kept {kept}, undone {undone}");
    assert!(kept > 1000 && undone > 1000, "kept {kept}, undone {undone}");
    assert_eq!(mismatches, 0, "{mismatches} of {cases} cases differ");
}

/// A firmware image's sample-interrupt glue (guard, skipped update call, inline limiter
/// with a literal pool between its arms, DAC store, miss check) run in windows with random
/// record words and limiter constants, against the interpreter: registers, cycles and the
/// instructions retired agree (the retired count of native code across a literal pool
/// that branches jump over).
#[test]
fn glue_with_a_literal_pool_matches_the_interpreter_in_a_window() {
    let mut code: Vec<u8> = vec![
        0x2c, 0x00, 0x14, 0x34, 0x30, 0x68, 0x23, 0x68, 0x43, 0x40, 0x20, 0x60, 0x00, 0x2b, 0x03,
        0xd1, 0x21, 0x6a, 0x11, 0x29, 0x02, 0xdb, 0x09, 0xe0, 0x00, 0x21, 0x21, 0x62, 0xe0, 0x69,
        0x21, 0x00, 0x22, 0x1d, 0xff, 0xf7, 0x39, 0xfe, 0x21, 0x6a, 0x01, 0x31, 0x21, 0x62, 0x60,
        0x69, 0xc2, 0x17, 0x50, 0x40, 0x80, 0x1a, 0xc0, 0x0a, 0xa1, 0x69, 0x40, 0x45, 0x0d, 0xd9,
        0x04, 0x39, 0x03, 0xd4, 0x48, 0x45, 0x0c, 0xd9, 0x02, 0x48, 0x0d, 0xe0, 0x05, 0x31, 0x02,
        0x48, 0x0a, 0xe0, 0xc0, 0x46, 0xff, 0x7f, 0x00, 0x00, 0x00, 0x20, 0x00, 0x00, 0x51, 0x45,
        0x00, 0xda, 0x01, 0x31, 0x0a, 0x4b, 0x58, 0x43, 0xc0, 0x0b, 0x50, 0x40, 0x80, 0x1a, 0xa1,
        0x61, 0x38, 0x60, 0x07, 0x48, 0x02, 0x68, 0x52, 0x01, 0x02, 0xd5, 0xe9, 0x68, 0x01, 0x31,
        0xe9, 0x60, 0xa9, 0x68, 0x01, 0x31, 0xa9, 0x60, 0x06, 0x20, 0xc0, 0x43, 0x86, 0x46, 0x70,
        0x47, 0xfe, 0xff, 0x00, 0x00, 0x04, 0xed, 0x00, 0xe0, 0x00, 0x00, 0x00, 0x00,
    ];
    // The handler's return (movs r0, #6; mvns; mov lr, r0; bx lr) becomes `b .`.
    let ret = code
        .windows(4)
        .position(|w| w == [0x06, 0x20, 0xc0, 0x43])
        .unwrap();
    code[ret..ret + 2].copy_from_slice(&[0xfe, 0xe7]);
    const AT: u32 = 0x2100_058c;
    const REC: u32 = 0x2100_8000;
    const CTRL: u32 = REC - 20;
    const SENSOR: u32 = 0x2100_fc00;
    const DAC: u32 = 0x2100_fd00;
    let mut rng = Rng(0x9100_1a55);
    let windowed = |engine| {
        let mut b = Board::new(Config {
            engine,
            own_banks: [0b01_0001, 0b10_0000],
            ..Config::default()
        });
        b.set_compile_threshold(0);
        b.write_bytes(AT, &code).unwrap();
        b.write_bytes(0x2004_1800, &[0x30, 0xbf, 0xfd, 0xe7])
            .unwrap(); // wfi; b .-2
        b.start_core(1, 0x2004_1800 | 1, 0x2004_1f00, VTOR);
        b
    };
    let mut boards = [windowed(Engine::Block), windowed(Engine::Interp)];
    let mut mismatches = 0;
    for case in 0..2000 {
        let words: Vec<u32> = (0..10).map(|_| value(&mut rng) >> rng.below(28)).collect();
        let consts: Vec<u32> = (0..4).map(|_| value(&mut rng) >> rng.below(28)).collect();
        let mut out = Vec::new();
        for b in boards.iter_mut() {
            b.write_u32(SENSOR, words[0]).unwrap();
            for (i, w) in words[1..].iter().enumerate() {
                b.write_u32(REC + 4 * i as u32, *w).unwrap();
            }
            b.start_core(0, AT | 1, 0x2004_1000, VTOR);
            let now = b.cores[0].cycle.max(b.cores[1].cycle) + 5000;
            b.cores[0].cycle = now;
            b.cores[1].cycle = now;
            let c = &mut b.cores[0];
            (c.r[4], c.r[5], c.r[6], c.r[7]) = (0, CTRL, SENSOR, DAC);
            c.r[8..12].copy_from_slice(&consts);
            let stop = b.run_until(now + 300);
            let mut rec = vec![0u8; 40];
            b.read_bytes(REC, &mut rec).unwrap();
            out.push((stop, state(b), rec, b.read_u32(0x2003_f400)));
        }
        if out[0] != out[1] {
            if mismatches < 5 {
                eprintln!("case {case}: words {words:08x?} consts {consts:08x?}\n  block  {:?}\n  interp {:?}", out[0], out[1]);
            }
            mismatches += 1;
        }
    }
    let (kept, undone) = boards[0].run_ahead_windows();
    eprintln!("windows kept {kept}, undone {undone}");
    assert_eq!(mismatches, 0);
}
