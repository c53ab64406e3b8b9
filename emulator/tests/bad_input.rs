//! Bad input never panics the host: malformed ELF files give an error, bad machine code gives
//! a HardFault (or a lockup), and random garbage runs to a stop.

mod common;

use common::enc::*;
use common::load_program;
use tactus_emulator::core::FaultKind;
use tactus_emulator::elf::ElfError;
use tactus_emulator::{Board, Config, EmuError, StopReason};

/// A minimal ELF32 executable with one PT_LOAD segment holding `code` at `addr`.
fn elf(class: u8, data: u8, etype: u16, machine: u16, addr: u32, code: &[u8]) -> Vec<u8> {
    let mut f = vec![0x7f, b'E', b'L', b'F', class, data, 1, 0];
    f.resize(16, 0);
    let h16 = |f: &mut Vec<u8>, v: u16| f.extend(v.to_le_bytes());
    let h32 = |f: &mut Vec<u8>, v: u32| f.extend(v.to_le_bytes());
    h16(&mut f, etype);
    h16(&mut f, machine);
    h32(&mut f, 1); // e_version
    h32(&mut f, addr | 1); // e_entry
    h32(&mut f, 52); // e_phoff
    h32(&mut f, 0); // e_shoff
    h32(&mut f, 0x0500_0000); // e_flags: EABI5
    h16(&mut f, 52); // e_ehsize
    h16(&mut f, 32); // e_phentsize
    h16(&mut f, 1); // e_phnum
    h16(&mut f, 40); // e_shentsize
    h16(&mut f, 0); // e_shnum
    h16(&mut f, 0); // e_shstrndx
    for v in [
        1,
        84,
        addr,
        addr,
        code.len() as u32,
        code.len() as u32,
        5,
        4,
    ] {
        h32(&mut f, v);
    }
    f.extend(code);
    f
}

fn code(halfwords: &[u16]) -> Vec<u8> {
    halfwords.iter().flat_map(|h| h.to_le_bytes()).collect()
}

const EM_ARM: u16 = 40;

fn load(bytes: &[u8]) -> Result<Board, EmuError> {
    let mut b = Board::new(Config {
        svc_halts: true,
        ..Config::default()
    });
    b.load_elf(bytes)?;
    Ok(b)
}

#[test]
fn minimal_elf_loads_and_runs() {
    let bytes = elf(1, 1, 2, EM_ARM, 0x2000_0000, &code(&[movs(0, 42), svc(0)]));
    let mut b = load(&bytes).expect("valid ELF");
    assert_eq!(b.run_for(100), StopReason::Svc { core: 0, imm: 0 });
    assert_eq!(b.cores[0].r[0], 42);
}

#[test]
fn every_truncation_is_an_error() {
    let bytes = elf(1, 1, 2, EM_ARM, 0x2000_0000, &code(&[movs(0, 42), svc(0)]));
    for len in 0..bytes.len() {
        let err = load(&bytes[..len]).err();
        assert!(
            matches!(err, Some(EmuError::Elf(ElfError::Malformed(_)))),
            "length {len}: {err:?}"
        );
    }
}

#[test]
fn wrong_kind_of_elf_is_named() {
    let c = code(&[svc(0)]);
    let cases = [
        (elf(1, 1, 2, 62, 0x2000_0000, &c), "e_machine 62"),
        (elf(2, 1, 2, EM_ARM, 0x2000_0000, &c), "64-bit"),
        (elf(1, 2, 2, EM_ARM, 0x2000_0000, &c), "big-endian"),
        (elf(1, 1, 1, EM_ARM, 0x2000_0000, &c), "relocatable"),
        (elf(1, 1, 3, EM_ARM, 0x2000_0000, &c), "not an executable"),
        (elf(1, 1, 2, EM_ARM, 0x3000_0000, &c), "outside the RP2040"),
        (b"#!/bin/sh\necho hi\n".to_vec(), "missing ELF magic"),
    ];
    for (bytes, want) in cases {
        let msg = load(&bytes)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(msg.contains(want), "`{msg}` should mention `{want}`");
    }
}

fn run_code(halfwords: &[u16], regs: &[(usize, u32)]) -> (Board, StopReason) {
    let mut b = Board::new(Config {
        svc_halts: true,
        ..Config::default()
    });
    load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, halfwords);
    for &(r, v) in regs {
        b.cores[0].r[r] = v;
    }
    let stop = b.run_for(1000);
    (b, stop)
}

#[test]
fn bad_code_faults_with_a_clear_reason() {
    // BX to an even address: the branch happens, the next fetch faults (ARM state).
    let (_, stop) = run_code(&[0x4700 | (1 << 3)], &[(1, 0x2000_0100)]); // bx r1
    let StopReason::Fault { fault, .. } = stop else {
        panic!("{stop:?}")
    };
    assert_eq!(
        fault.kind,
        FaultKind::InvalidState {
            target: 0x2000_0100
        }
    );
    assert!(fault.to_string().contains("ARM state"), "{fault}");
    // Jump to an unmapped address: instruction fetch bus fault.
    let (_, stop) = run_code(&[0x4700 | (1 << 3)], &[(1, 0x3000_0001)]);
    let StopReason::Fault { fault, .. } = stop else {
        panic!("{stop:?}")
    };
    assert_eq!(fault.kind, FaultKind::Bus { addr: 0x3000_0000 });
    // Undefined 32-bit encoding.
    let (b, stop) = run_code(&[0xf000, 0x8000], &[]);
    let StopReason::Fault { fault, .. } = stop else {
        panic!("{stop:?}")
    };
    assert!(
        fault
            .to_string()
            .contains("undefined instruction f000 8000 at pc 0x20000000"),
        "{fault}"
    );
    assert_eq!(b.cores[0].ipsr, 3, "in HardFault");
    // Unaligned store.
    let (_, stop) = run_code(&[str(0, 1, 0)], &[(1, 0x2000_0102)]);
    let StopReason::Fault { fault, .. } = stop else {
        panic!("{stop:?}")
    };
    assert_eq!(fault.kind, FaultKind::Unaligned { addr: 0x2000_0102 });
    // SVC with PRIMASK set cannot be taken: escalates to HardFault.
    let (_, stop) = run_code(&[0xb672, svc(1)], &[]); // cpsid i; svc #1
    let StopReason::Fault { fault, .. } = stop else {
        panic!("{stop:?}")
    };
    assert_eq!(fault.kind, FaultKind::SvcEscalation);
}

#[test]
fn fault_inside_hardfault_locks_up() {
    // No vector table (zeros): HardFault's vector is 0, an even address, so the handler's
    // first fetch faults again inside HardFault: lockup.
    let mut b = Board::new(Config {
        stop_on_fault: false,
        ..Config::default()
    });
    load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, &[0xde00]); // udf #0
    let stop = b.run_for(1000);
    let StopReason::Lockup { core: 0, fault } = stop else {
        panic!("{stop:?}")
    };
    assert_eq!(fault.kind, FaultKind::InvalidState { target: 0 });
    assert_eq!(
        b.run_for(1000),
        StopReason::Idle,
        "a locked-up core stays stopped"
    );
}

#[test]
fn random_garbage_never_panics() {
    let mut seed = 0x1234_5678_9abc_def0u64;
    let mut rand = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let mut faults = 0;
    for _ in 0..400 {
        let mut b = Board::new(Config {
            stop_on_fault: false,
            svc_halts: false,
            ..Config::default()
        });
        let prog: Vec<u16> = (0..64).map(|_| rand() as u16).collect();
        load_program(&mut b, 0, 0x2000_0000, 0x2000_1000, &prog);
        for r in 0..15 {
            b.cores[0].r[r] = match rand() % 3 {
                0 => 0x2000_0000 + (rand() as u32 % 0x4_2000),
                1 => rand() as u32 % 64,
                _ => rand() as u32,
            };
        }
        let stop = b.run_for(2_000);
        if matches!(stop, StopReason::Lockup { .. }) || b.cores[0].ipsr == 3 {
            faults += 1;
        }
    }
    assert!(
        faults > 100,
        "garbage should mostly fault; only {faults} of 400 did"
    );
}
