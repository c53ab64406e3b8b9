//! Memoized calls (`Board::memoize`, `src/memo.rs`) against the interpreter: random
//! functions called from a `BL`, each case four calls — the same inputs twice (the second
//! replayed from the first's recording when the function can be memoized), then twice
//! with one input changed: a register, a flag, a data byte or the bytes of the stack the
//! function may read. Core 0 runs in windows (core 1 sleeps in SRAM5), as the firmware
//! images' cores do. After every call the registers, flags, cycle and instruction counts,
//! the run state and all of SRAM must equal the interpreter's. The function bodies are
//! mostly what memos hold (data processing, loads and stores around a base register,
//! PUSH/POP pairs, short forward branches) and sometimes anything (SIO, peripherals,
//! faults, MRS, WFI, stores into the code): those calls must run exactly as before.

use tactus_emulator::{Board, Config, Engine, StopReason};

mod common;
use common::Rng;

const CALLER: u32 = 0x2000_4000;
const FUNC: u32 = 0x2000_4100;
const DATA: u32 = 0x2000_8000;
const SP: u32 = 0x2003_8000;
const VTOR: u32 = 0x2003_0000;

/// `BL` from `from` to `to` (both halfwords).
fn bl(from: u32, to: u32) -> [u16; 2] {
    let off = to.wrapping_sub(from + 4) as i32 >> 1;
    let s = ((off >> 23) & 1) as u16;
    let i1 = ((off >> 22) & 1) as u16;
    let i2 = ((off >> 21) & 1) as u16;
    let (j1, j2) = ((!i1 ^ s) & 1, (!i2 ^ s) & 1);
    [
        0xf000 | s << 10 | ((off >> 11) & 0x3ff) as u16,
        0xd000 | j1 << 13 | j2 << 11 | (off & 0x7ff) as u16,
    ]
}

/// One random instruction of a body (`wild`: any 16-bit encoding below 0xc000 too).
fn instruction(rng: &mut Rng, wild: bool) -> Vec<u16> {
    let lo = |rng: &mut Rng| rng.below(7); // r0-r6: r7 is the data base
    let any = |rng: &mut Rng| rng.below(8);
    match rng.below(if wild { 11 } else { 10 }) {
        0 => vec![(rng.below(3) << 11) | (rng.below(32) << 6) | (any(rng) << 3) | lo(rng)],
        1 => vec![0x1800 | (rng.below(4) << 9) | (any(rng) << 6) | (any(rng) << 3) | lo(rng)],
        2 => vec![0x2000 | (rng.below(4) << 11) | (lo(rng) << 8) | rng.below(256)],
        3 => vec![0x4000 | (rng.below(16) << 6) | (any(rng) << 3) | lo(rng)],
        // Loads and stores of every width at r7 + an immediate (in the data block).
        4 | 5 => {
            let op = [0x6000, 0x6800, 0x7000, 0x7800, 0x8000, 0x8800][rng.below(6) as usize];
            vec![op | (rng.below(16) << 6) | (7 << 3) | lo(rng)]
        }
        // A PUSH/POP pair around an ALU operation (stack bytes written and read back).
        6 => vec![
            0xb570,
            0x4000 | (rng.below(16) << 6) | (any(rng) << 3) | lo(rng),
            0xbc71,
        ],
        // A conditional branch over the next instruction.
        7 => vec![
            0xd000 | (rng.below(14) << 8),
            0x3000 | (lo(rng) << 8) | rng.below(256),
        ],
        // A load from the caller's stack (an input the function did not write).
        8 if rng.below(2) == 0 => vec![0x9800 | (lo(rng) << 8) | rng.below(4)],
        // A word load through r0-r3 (a based memo's base when nothing else reads it).
        8 => vec![0x6800 | (rng.below(8) << 6) | (rng.below(4) << 3) | lo(rng)],
        // ADD/MOV/CMP with a high register (r8-r12; never PC or SP as the destination).
        9 => {
            let hi = 8 + rng.below(5);
            match rng.below(3) {
                0 => vec![0x4600 | ((hi & 8) << 4) | (hi & 7) | (any(rng) << 3)],
                1 => vec![0x4600 | (hi << 3) | lo(rng)],
                _ => vec![0x4500 | (hi << 3) | lo(rng)],
            }
        }
        _ => vec![rng.below(0xc000)],
    }
}

fn board(engine: Engine) -> Board {
    let mut b = Board::new(Config {
        engine,
        own_banks: [0b01_1111, 0b10_0000],
        ..Config::default()
    });
    b.set_compile_threshold(0);
    let sleeper = 0x2004_1800;
    b.write_bytes(sleeper, &[0x30, 0xbf, 0xfd, 0xe7]).unwrap(); // wfi; b .-2
    b.start_core(1, sleeper | 1, 0x2004_1f00, VTOR);
    let mut caller: Vec<u8> = Vec::new();
    for h in bl(CALLER, FUNC).into_iter().chain([0xe7fe]) {
        caller.extend(h.to_le_bytes()); // bl FUNC; b .
    }
    b.write_bytes(CALLER, &caller).unwrap();
    b.memoize(&[FUNC | 1], &[]);
    b
}

/// The inputs of one call.
#[derive(Clone, Debug)]
struct Inputs {
    regs: [u32; 13],
    flags: u16,
    data: Vec<u8>,
    stack: Vec<u8>,
}

fn state(b: &mut Board) -> String {
    let c = &b.cores[0];
    let s = format!(
        "cycle {} instr {} r {:08x?} nzcv {}{}{}{} {:?} core 1 at {}",
        c.cycle,
        c.instructions,
        c.r,
        c.n as u8,
        c.z as u8,
        c.c as u8,
        c.v as u8,
        c.state,
        b.cores[1].cycle
    );
    s
}

/// Core 0 started at `from` (a caller's `BL`) with `regs` in r0…, both cores' cycles moved
/// past the lock-step stretch that follows an undone window, and run 600 cycles: why it
/// stopped and core 0's [`state`]. `set` sets anything more of core 0 (flags).
fn call_at(
    b: &mut Board,
    from: u32,
    regs: &[u32],
    set: impl FnOnce(&mut tactus_emulator::core::Core),
) -> (StopReason, String) {
    b.start_core(0, from | 1, SP, VTOR);
    let now = b.cores[0].cycle.max(b.cores[1].cycle) + 5000;
    b.cores[0].cycle = now;
    b.cores[1].cycle = now;
    b.cores[0].r[..regs.len()].copy_from_slice(regs);
    set(&mut b.cores[0]);
    let stop = b.run_until(now + 600);
    (stop, state(b))
}

#[test]
fn memoized_calls_match_the_interpreter() {
    let mut rng = Rng(0x3e30_ca11);
    let mut boards = [board(Engine::Block), board(Engine::Interp)];
    let mut mismatches = 0;
    let cases = 5000;
    for case in 0..cases {
        let wild = rng.below(4) == 0;
        let mut body: Vec<u16> = Vec::new();
        for _ in 0..1 + rng.below(12) {
            let w = wild && rng.below(3) == 0;
            body.extend(instruction(&mut rng, w));
        }
        body.push(0x4770); // bx lr
        let bytes: Vec<u8> = body.iter().flat_map(|h| h.to_le_bytes()).collect();
        for b in boards.iter_mut() {
            b.write_bytes(FUNC, &bytes).unwrap();
        }
        let base = Inputs {
            regs: std::array::from_fn(|i| match i {
                7 => DATA,
                _ => match rng.below(3) {
                    0 => rng.below(64) as u32,
                    1 => rng.next() as u32,
                    _ => DATA + 4 * rng.below(16) as u32,
                },
            }),
            flags: rng.below(16),
            // Half the cases' data repeats every 16 bytes: a base moved by 16 loads what
            // it loaded before.
            data: {
                let period = if rng.below(2) == 0 { 16 } else { 96 };
                let d: Vec<u8> = (0..period).map(|_| rng.next() as u8).collect();
                (0..96).map(|i| d[i % period]).collect()
            },
            stack: (0..16).map(|_| rng.next() as u8).collect(),
        };
        for call in 0..4 {
            let mut inputs = base.clone();
            if call >= 2 {
                match rng.below(5) {
                    0 => inputs.regs[rng.below(13) as usize] ^= 1 << rng.below(32),
                    // A base, or a register a function saves and restores, moved.
                    4 => {
                        let r = [0, 1, 2, 3, 4, 5, 6][rng.below(7) as usize];
                        inputs.regs[r] = inputs.regs[r].wrapping_add(16);
                    }
                    1 => inputs.flags ^= 1 << rng.below(4),
                    2 => inputs.data[rng.below(96) as usize] ^= 1 << rng.below(8),
                    _ => inputs.stack[rng.below(16) as usize] ^= 1 << rng.below(8),
                }
            }
            let mut out = Vec::new();
            for b in boards.iter_mut() {
                b.write_data(DATA, &inputs.data).unwrap();
                b.write_data(SP, &inputs.stack).unwrap();
                let f = inputs.flags;
                out.push(call_at(b, CALLER, &inputs.regs, |c| {
                    (c.n, c.z, c.c, c.v) = (f & 8 != 0, f & 4 != 0, f & 2 != 0, f & 1 != 0)
                }));
            }
            let same_sram = boards[0].system.sram == boards[1].system.sram;
            if out[0] != out[1] || !same_sram {
                if mismatches < 5 {
                    eprintln!(
                        "case {case} call {call}: body {body:04x?} inputs {inputs:x?}\n  block  {:?}\n  interp {:?}\n  sram equal: {same_sram}",
                        out[0], out[1]
                    );
                }
                mismatches += 1;
                let sram = boards[1].system.sram.clone();
                boards[0].system.sram = sram;
            }
        }
    }
    let stats = boards[0].memo_stats();
    let (kept, undone) = boards[0].run_ahead_windows();
    eprintln!("{stats:?}; windows kept {kept}, undone {undone}");
    assert_eq!(mismatches, 0, "{mismatches} calls of {} differ", 4 * cases);
    // The second call of a memoizable function replays the first; some calls with an
    // input changed replay too (the input was not one the function reads).
    assert!(stats.hits > cases as u64 / 3, "{stats:?}");
    assert!(stats.abandoned > 50, "{stats:?}");
    assert_eq!(
        boards[1].memo_stats().hits,
        0,
        "the interpreter never replays"
    );
}

/// A key update's shape, as the compiler makes it: r4-r7 saved and restored, its sensor
/// words loaded through r1 (a ring of results buffers), its results stored through r2.
/// The site's first memo compares r1 and r6 as any input; once a call comes with another
/// r1, the site's memos stand for every buffer holding the same words and every value of
/// the saved registers; a buffer with other words misses, and so does one that the call's
/// own stores reach before its loads. Every call equals the interpreter's, registers and
/// all of SRAM.
#[test]
fn a_memo_moves_with_its_base_and_keeps_the_saved_registers() {
    let body: [u16; 11] = [
        0xb5f0, // push {r4-r7, lr}
        0x2305, // movs r3, #5
        0x6013, // str r3, [r2, #0]
        0x680c, // ldr r4, [r1, #0]
        0x684d, // ldr r5, [r1, #4]
        0x1964, // adds r4, r4, r5
        0x6054, // str r4, [r2, #4]
        0x2603, // movs r6, #3
        0x1c37, // adds r7, r6, #0
        0x2000, // movs r0, #0
        0xbdf0, // pop {r4-r7, pc}
    ];
    let bytes: Vec<u8> = body.iter().flat_map(|h| h.to_le_bytes()).collect();
    let mut boards = [board(Engine::Block), board(Engine::Interp)];
    for b in boards.iter_mut() {
        b.write_bytes(FUNC, &bytes).unwrap();
    }
    // Three buffers in bank 2's non-striped alias (as the converter drivers' results),
    // the first two with the same words, and the results two words there too.
    let alias = |word: u32| 0x2102_0000 + 4 * word;
    let out = alias(0x11b);
    let buffers = [alias(0x100), alias(0x109), alias(0x112), out];
    let words: [[u32; 2]; 4] = [[7, 9], [7, 9], [8, 9], [7, 9]];
    // (buffer, r6 at the call): the second, through another buffer with the same words,
    // is recorded again (the site's calls move); the third (other saved registers) and
    // the fourth (the first buffer again: the base moved) are the second's; the fifth
    // reads other words; the sixth reads the same words, but where the call stores first.
    let calls = [
        (0, 0x1111),
        (1, 0x2222),
        (1, 0x3333),
        (0, 0x4444),
        (2, 0x2222),
        (3, 0x1111),
    ];
    let mut hits = Vec::new();
    let mut sums = Vec::new();
    for (i, &(buf, r6)) in calls.iter().enumerate() {
        let mut got = Vec::new();
        for b in boards.iter_mut() {
            for (k, w) in words.iter().enumerate() {
                let data: Vec<u8> = w.iter().flat_map(|x| x.to_le_bytes()).collect();
                b.write_data(buffers[k], &data).unwrap();
            }
            let regs = [0, buffers[buf], out, 0, 0x44, 0x55, r6, 0x77];
            got.push(call_at(b, CALLER, &regs, |_| {}));
        }
        assert_eq!(got[0], got[1], "call {i}");
        assert!(
            boards[0].system.sram == boards[1].system.sram,
            "call {i}: SRAM differs from the interpreter's"
        );
        hits.push(boards[0].memo_stats().hits);
        let mut sum = [0u8; 4];
        boards[1].read_bytes(out + 4, &mut sum).unwrap();
        sums.push(u32::from_le_bytes(sum));
    }
    assert_eq!(sums, [16, 16, 16, 16, 17, 14], "the sums");
    assert_eq!(hits, [0, 0, 1, 2, 2, 2], "hits after each call");
}

/// A span (a core's keys part) around a watched call: while the call's inputs change every
/// run (a key moving), the span is not recorded — its last run had a call miss, so a
/// recording would hold inputs the next run does not repeat — beyond its first run, before
/// any call missed; once they stop changing, the span is recorded and replaces the whole
/// run (its hits cover the `BL` too). Every run equals the interpreter's.
#[test]
fn a_span_whose_call_missed_last_run_is_not_recorded() {
    let body: [u16; 4] = [
        0x6838, // ldr r0, [r7, #0]
        0x3001, // adds r0, #1
        0x6078, // str r0, [r7, #4]
        0x4770, // bx lr
    ];
    let bytes: Vec<u8> = body.iter().flat_map(|h| h.to_le_bytes()).collect();
    // The span: the caller's `BL` (to the `B .` after it).
    let span = (CALLER, CALLER + 4);
    let mut boards = [
        board(Engine::Block),
        board(Engine::Block),
        board(Engine::Interp),
    ];
    boards[0].memoize(&[FUNC | 1], &[span]);
    for b in boards.iter_mut() {
        b.write_bytes(FUNC, &bytes).unwrap();
    }
    let run = |boards: &mut [Board; 3], word: u32| {
        let mut got = Vec::new();
        for b in boards.iter_mut() {
            b.write_data(DATA, &word.to_le_bytes()).unwrap();
            got.push(call_at(b, CALLER, &[], |c| c.r[7] = DATA));
        }
        assert_eq!(got[0], got[2], "the span's board against the interpreter");
        assert_eq!(got[1], got[2], "the call's board against the interpreter");
    };
    // Moving: a new word every run.
    for i in 0..64 {
        run(&mut boards, 1000 + i);
    }
    let (span, call) = (boards[0].memo_stats(), boards[1].memo_stats());
    assert!(
        span.recorded <= call.recorded + 1,
        "moving: the span recorded beyond its first run: {span:?} against {call:?}"
    );
    // At rest: the same word from now on.
    for _ in 0..256 {
        run(&mut boards, 7);
    }
    let (span2, call2) = (boards[0].memo_stats(), boards[1].memo_stats());
    assert!(span2.recorded > span.recorded, "at rest: {span2:?}");
    assert!(call2.hits > call.hits + 100, "at rest, the call: {call2:?}");
    let per_hit = |a: tactus_emulator::MemoStats, b: tactus_emulator::MemoStats| {
        (a.hit_cycles - b.hit_cycles) as f64 / (a.hits - b.hits).max(1) as f64
    };
    assert!(
        per_hit(span2, span) > per_hit(call2, call),
        "at rest the span's memo replaces the call and its BL: {span2:?} against {call2:?}"
    );
}

/// A span whose recording meets a watched call that has a memo takes the call from it
/// (`Recording::nest`: the memo's inputs and effect logged as the call's instructions),
/// as a span of the firmware's keys code takes each key's update: the span reads a word
/// of its own besides the call's (a new one every run, then the word of a run recorded
/// so again). Every run equals the interpreter's, registers, cycles and all of SRAM.
#[test]
fn a_span_recording_takes_a_call_from_its_memo() {
    let body: [u16; 5] = [
        0xb510, // push {r4, lr}
        0x683c, // ldr r4, [r7, #0]
        0x3401, // adds r4, #1
        0x607c, // str r4, [r7, #4]
        0xbd10, // pop {r4, pc}
    ];
    let bytes: Vec<u8> = body.iter().flat_map(|h| h.to_le_bytes()).collect();
    // The span: a word of its own copied, then the call (to the `B .` after it).
    let at = CALLER + 0x80;
    let mut code: Vec<u8> = Vec::new();
    let glue = [0x68bb, 0x60fb]; // ldr r3, [r7, #8]; str r3, [r7, #12]
    for h in glue.into_iter().chain(bl(at + 4, FUNC)).chain([0xe7fe]) {
        code.extend(h.to_le_bytes());
    }
    let mut boards = [board(Engine::Block), board(Engine::Interp)];
    boards[0].memoize(&[FUNC | 1], &[(at, at + 8)]);
    for b in boards.iter_mut() {
        b.write_bytes(FUNC, &bytes).unwrap();
        b.write_bytes(at, &code).unwrap();
        b.write_data(DATA, &[7, 0, 0, 0]).unwrap();
    }
    let mut run = |own: u32| {
        let before = boards[0].memo_stats();
        let mut got = Vec::new();
        for b in boards.iter_mut() {
            b.write_data(DATA + 8, &own.to_le_bytes()).unwrap();
            got.push(call_at(b, at, &[0, 0, 0, 0, 0x44], |c| c.r[7] = DATA));
        }
        assert_eq!(got[0], got[1], "the span with its own word {own}");
        assert!(
            boards[0].system.sram == boards[1].system.sram,
            "own word {own}: SRAM differs from the interpreter's"
        );
        (before, boards[0].memo_stats())
    };
    // A recording of the span during which the call hit its memo.
    let mut nested = None;
    for own in 100..124 {
        let (before, after) = run(own);
        if after.recorded > before.recorded && after.hits > before.hits {
            nested = Some(own);
        }
    }
    let own = nested.expect("no recording of the span took the call from its memo");
    // Its memo replaces the whole span, the call and the copy around it; with a new word
    // the call alone hits.
    let (b1, a1) = run(own);
    assert_eq!(
        (a1.hits, a1.recorded),
        (b1.hits + 1, b1.recorded),
        "the span's memo: {a1:?}"
    );
    let (b2, a2) = run(5000);
    assert_eq!(a2.hits, b2.hits + 1, "the call's memo: {a2:?}");
    assert!(
        a1.hit_cycles - b1.hit_cycles > a2.hit_cycles - b2.hit_cycles,
        "the span's hit covers more than the call's: {a1:?} {a2:?}"
    );
}

/// A function called from two return addresses shares its memos (its site is the core,
/// the entry and r0, not the return address): a call that pushes LR and pops it into PC,
/// reading it nowhere else, is replayed from a recording made at the other call site,
/// returning to its own caller. One that reads LR otherwise (stores it) compares it: no
/// hit from the other call site. Every call equals the interpreter's.
#[test]
fn a_memo_returns_to_its_own_caller() {
    let pushed: [u16; 6] = [
        0xb510, // push {r4, lr}
        0x680c, // ldr r4, [r1, #0]
        0x3401, // adds r4, #1
        0x6014, // str r4, [r2, #0]
        0x2000, // movs r0, #0
        0xbd10, // pop {r4, pc}
    ];
    let read: [u16; 6] = [
        0xb510, // push {r4, lr}
        0x4673, // mov r3, lr
        0x6053, // str r3, [r2, #4]
        0x680c, // ldr r4, [r1, #0]
        0x6014, // str r4, [r2, #0]
        0xbd10, // pop {r4, pc}
    ];
    // A second caller, 0x40 bytes after the first: `bl FUNC; b .`.
    let caller2 = CALLER + 0x40;
    let mut code: Vec<u8> = Vec::new();
    for h in bl(caller2, FUNC).into_iter().chain([0xe7fe]) {
        code.extend(h.to_le_bytes());
    }
    for (body, want) in [(&pushed, [0, 1, 2, 3]), (&read, [0, 0, 1, 2])] {
        let bytes: Vec<u8> = body.iter().flat_map(|h| h.to_le_bytes()).collect();
        let mut boards = [board(Engine::Block), board(Engine::Interp)];
        for b in boards.iter_mut() {
            b.write_bytes(FUNC, &bytes).unwrap();
            b.write_bytes(caller2, &code).unwrap();
        }
        let mut hits = Vec::new();
        for (i, from) in [CALLER, caller2, caller2, CALLER].into_iter().enumerate() {
            let mut got = Vec::new();
            for b in boards.iter_mut() {
                b.write_data(DATA, &[7, 0, 0, 0]).unwrap();
                let regs = [DATA + 0x40, DATA, DATA + 0x10, 0, 0x44, 0, 0, 0];
                got.push(call_at(b, from, &regs, |_| {}));
            }
            assert_eq!(got[0], got[1], "call {i} from {from:#x}");
            assert!(
                boards[0].system.sram == boards[1].system.sram,
                "call {i}: SRAM differs from the interpreter's"
            );
            assert_eq!(
                boards[0].cores[0].r[15],
                from + 4,
                "call {i}: returned to its caller"
            );
            hits.push(boards[0].memo_stats().hits);
        }
        assert_eq!(
            hits,
            want,
            "hits after each call: {:?}",
            boards[0].memo_stats()
        );
    }
}
