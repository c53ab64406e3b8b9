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
