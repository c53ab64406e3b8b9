//! The host API the budget checker and the harness use: per-function cycle accounting,
//! sensor and DAC blocks, host memory access, cycle-exact `run_for`, and self-modifying code
//! through the decode cache.

mod common;

use common::enc::*;
use common::load_program;
use tactus_emulator::{Board, Config, EmuError, StopReason};

/// The words the test program reads and writes: a firmware image's sensor and DAC windows.
const SENSOR_BASE: u32 = 0x2003_f000;
const DAC_BASE: u32 = 0x2003_f400;

fn board() -> Board {
    Board::new(Config {
        svc_halts: true,
        ..Config::default()
    })
}

#[test]
fn function_cycles_between_entry_and_return() {
    // main: movs r4,#3; loop: bl func; subs r4,#1; bne loop; svc 0
    // func (at +0x40): push {lr}; movs r0,#5; pop {pc}
    let mut code = vec![movs(4, 3)];
    code.extend(bl(0x40 - 2)); // at 0x2: target 0x40
    code.extend([subs_imm8(4, 1), bcond(1, -6), svc(0)]);
    code.resize(0x20, nop());
    code.extend([push_lr(), movs(0, 5), pop_pc()]);
    let mut b = board();
    load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, &code);
    let f = b.profile_addr(0x2000_0040);
    assert_eq!(b.run_for(1000), StopReason::Svc { core: 0, imm: 0 });
    let calls = b.calls(f);
    // push {lr} 1+1, movs 1, pop {pc} 3+N with N = 0 low registers: 2 + 1 + 3.
    assert_eq!(
        calls.iter().map(|c| c.cycles).collect::<Vec<_>>(),
        [6, 6, 6]
    );
    // Call k starts after movs (1) + k * (bl 3 + body 6 + subs 1 + bne taken 2) + bl 3.
    assert_eq!(
        calls.iter().map(|c| c.start).collect::<Vec<_>>(),
        [4, 16, 28]
    );
    assert_eq!(b.cores[0].cycle, 1 + 3 * 12 - 1, "last bne not taken");
}

#[test]
fn cleared_calls_are_forgotten_and_measuring_goes_on() {
    // loop: bl func; b loop — func (at +0x40): push {lr}; movs r0,#5; pop {pc}
    let mut code = bl(0x40).to_vec();
    code.push(0xe7fc); // b loop
    code.resize(0x20, nop());
    code.extend([push_lr(), movs(0, 5), pop_pc()]);
    let mut b = board();
    load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, &code);
    let f = b.profile_addr(0x2000_0040);
    b.run_for(100);
    let before = b.calls(f).len();
    assert!(before >= 5, "{before} calls");
    b.clear_calls(f);
    assert!(b.calls(f).is_empty());
    b.clear_calls(f + 7); // unknown handle: ignored
    b.run_for(100);
    let after = b.calls(f);
    assert!(after.len() >= 5 && after.iter().all(|c| c.cycles == 6));
    assert!(after[0].start >= 100, "only calls after the clear");
}

#[test]
fn profile_by_symbol_name_needs_a_loaded_symbol() {
    let mut b = board();
    assert_eq!(b.profile("nope"), Err(EmuError::NoSymbol("nope".into())));
}

#[test]
fn sensors_in_forces_out() {
    // For keys 0..4: dac[k] = 2 * sensor[k]. r0 = SENSOR_BASE, r1 = DAC_BASE = r0 + 0x400.
    let mut code = vec![
        movs(0, 0x20),
        lsls(0, 0, 8),
        adds_imm8(0, 0x03),
        lsls(0, 0, 8),
        adds_imm8(0, 0xf0),
        lsls(0, 0, 8),
    ];
    code.extend([movs(1, 4), lsls(1, 1, 8), 0x1809]); // adds r1, r1, r0
    for k in 0..4 {
        code.extend([ldr(2, 0, 4 * k), lsls(2, 2, 1), str(2, 1, 4 * k)]);
    }
    code.push(svc(0));
    let mut b = board();
    load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, &code);
    for (k, v) in [100u32, 0, 0xffff, 1234].into_iter().enumerate() {
        b.write_u32(SENSOR_BASE + 4 * k as u32, v).unwrap();
    }
    assert_eq!(b.run_for(1000), StopReason::Svc { core: 0, imm: 0 });
    let forces: Vec<u32> = (0..4)
        .map(|k| b.read_u32(DAC_BASE + 4 * k).unwrap())
        .collect();
    assert_eq!(forces, [200, 0, 0x1fffe, 2468]);
    assert_eq!(b.read_u32(DAC_BASE + 4).unwrap(), 0);
    assert_eq!(b.read_u32(SENSOR_BASE + 12).unwrap(), 1234);
}

#[test]
fn host_memory_access_is_checked() {
    let mut b = board();
    assert_eq!(
        b.write_u32(0x3000_0000, 1),
        Err(EmuError::Unmapped(0x3000_0000))
    );
    assert_eq!(
        b.read_u32(0x2004_1ffe),
        Err(EmuError::Unmapped(0x2004_2000))
    );
    b.write_u32(0x2004_1ffc, 0xa5a5_5a5a).unwrap();
    assert_eq!(b.read_u32(0x2004_1ffc), Ok(0xa5a5_5a5a));
    // The non-striped alias: word 1 of SRAM1 is striped word 4*1 + 1 = byte 0x14.
    b.write_u32(0x2101_0004, 77).unwrap();
    assert_eq!(b.read_u32(0x2000_0014), Ok(77));
}

#[test]
fn run_for_is_cycle_exact_and_resumable() {
    // An endless loop of 1-cycle adds and a 2-cycle branch: 3 adds + b = 5 cycles.
    let code = [adds_imm8(0, 1), adds_imm8(0, 1), adds_imm8(0, 1), b(-6)];
    let mut b = board();
    load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, &code);
    assert_eq!(b.run_for(500), StopReason::CycleLimit);
    assert_eq!(b.cores[0].cycle, 500);
    assert_eq!(b.cores[0].r[0], 300);
    assert_eq!(b.run_for(1000), StopReason::CycleLimit);
    assert_eq!((b.cycle(), b.cores[0].r[0]), (1500, 900));
}

#[test]
fn self_modifying_code_is_seen() {
    // 0: movs r0,#1 / cmp r7,#0 / bne done / movs r7,#1 / r1 = 0x20000000 / r2 = 0x2002
    //    (movs r0,#2) / strh r2,[r1] / b 0 / done: svc 0
    let code = [
        movs(0, 1),
        cmp_imm(7, 0),
        bcond(1, 20), // at 0x4 -> 0x18
        movs(7, 1),
        movs(1, 0x20),
        lsls(1, 1, 24),
        movs(2, 0x20),
        lsls(2, 2, 8),
        adds_imm8(2, 2),
        strh(2, 1, 0),
        b(-20), // at 0x14 -> 0x0
        nop(),
        svc(0), // 0x18
    ];
    let mut b = board();
    load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, &code);
    assert_eq!(b.run_for(1000), StopReason::Svc { core: 0, imm: 0 });
    assert_eq!(b.cores[0].r[0], 2, "the rewritten instruction must execute");
}

/// `Board::call` runs an AAPCS function and returns r0 and its cycles (return included).
#[test]
fn call_runs_a_function_and_counts_its_cycles() {
    use tactus_isa::decode::Instr;
    use tactus_isa::encode::encode;
    let mut b = tactus_emulator::Board::new(Default::default());
    // r0 = r0 + r1; r0 = r0 * r2; bx lr  → 1 + 1 + 2 cycles (BX: 2, Cortex-M0+ TRM 3.3)
    let code = [
        Instr::AddReg {
            rd: 0,
            rn: 0,
            rm: 1,
        },
        Instr::Alu {
            op: tactus_isa::decode::AluOp::Mul,
            rdn: 0,
            rm: 2,
        },
        Instr::Bx { rm: 14 },
    ];
    let bytes: Vec<u8> = code
        .iter()
        .flat_map(|i| encode(i).unwrap().bytes())
        .collect();
    b.write_bytes(0x2000_0000, &bytes).unwrap();
    let r = b
        .call(0, 0x2000_0000, &[3, 4, 5], 0x2004_0000, 1000)
        .unwrap();
    assert_eq!(r.r0, 35);
    assert_eq!(r.cycles, 4);
    // A function that never returns stops at the limit with an error, not a hang.
    let spin = encode(&Instr::B { offset: -4 }).unwrap().bytes();
    b.write_bytes(0x2000_0100, &spin).unwrap();
    assert!(b.call(0, 0x2000_0100, &[], 0x2004_0000, 500).is_err());
}

#[test]
fn word_runs_read_and_write_what_single_bytes_do() {
    // Host reads and writes of whole aligned words take one path per view (striped,
    // SRAM4/5, a bank of the non-striped alias); byte by byte they take the general one.
    // Both must see the same memory, including runs that cross from one view or bank
    // into the next (and so fall back).
    let mut b = board();
    let mut seed = 0x1234_5678u32;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed
    };
    let starts = [
        0x2000_0000,
        0x2000_0100,
        0x2003_fff0,
        0x2004_0000,
        0x2004_0ff8,
        0x2004_1ff0,
        0x2100_0000,
        0x2100_fff8,
        0x2101_0040,
        0x2103_fff0,
    ];
    for &start in &starts {
        for len in [4usize, 8, 16, 40] {
            let data: Vec<u8> = (0..len).map(|_| next() as u8).collect();
            let fits = b.read_bytes(start, &mut vec![0; len]).is_ok();
            if !fits {
                continue;
            }
            b.write_data(start, &data).unwrap();
            let mut bytes = vec![0; len];
            for (i, x) in bytes.iter_mut().enumerate() {
                let mut one = [0u8];
                b.read_bytes(start + i as u32, &mut one).unwrap();
                *x = one[0];
            }
            assert_eq!(bytes, data, "word write, byte reads at {start:#x}+{len}");
            let data: Vec<u8> = (0..len).map(|_| next() as u8).collect();
            for (i, x) in data.iter().enumerate() {
                b.write_data(start + i as u32, &[*x]).unwrap();
            }
            let mut words = vec![0; len];
            b.read_bytes(start, &mut words).unwrap();
            assert_eq!(words, data, "byte writes, word read at {start:#x}+{len}");
            // `read_words`/`write_words` (the harness's `u32` runs) against bytes.
            let mut got = vec![0u32; len / 4];
            b.read_words(start, &mut got).unwrap();
            let want: Vec<u32> = data
                .chunks(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            assert_eq!(got, want, "byte writes, read_words at {start:#x}+{len}");
            let put: Vec<u32> = (0..len / 4).map(|_| next()).collect();
            b.write_words(start, &put).unwrap();
            let mut bytes = vec![0; len];
            for (i, x) in bytes.iter_mut().enumerate() {
                let mut one = [0u8];
                b.read_bytes(start + i as u32, &mut one).unwrap();
                *x = one[0];
            }
            let want: Vec<u8> = put.iter().flat_map(|w| w.to_le_bytes()).collect();
            assert_eq!(bytes, want, "write_words, byte reads at {start:#x}+{len}");
        }
    }
    // Runs that leave mapped memory are errors, not panics, whichever path they take.
    let mut w = [0u32; 4];
    assert!(b.read_words(0x2004_1ff8, &mut w).is_err());
    assert!(b.write_words(0x2004_1ff8, &w).is_err());
    assert!(b.read_words(0x2103_fff8 + 0x1_0000, &mut w).is_err());
    // The alias and the striped view are one memory: bank 1's word 3 is striped word 13.
    b.write_u32(0x2101_000c, 0xdead_beef).unwrap();
    assert_eq!(b.read_u32(0x2000_0034).unwrap(), 0xdead_beef);
}
