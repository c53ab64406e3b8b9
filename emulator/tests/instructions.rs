//! Per-instruction table test: results, flags and cycles of every row of
//! `tests/data/instructions.table`, one step each, and the table's encodings against the real
//! assembler. Add a row to add a case.

mod common;

use common::num;
use tactus_emulator::core::{FaultKind, RunState};
use tactus_emulator::{Board, Config, StopReason};

const CODE: u32 = 0x2000_0100;
const STACK: u32 = 0x2000_1000;

struct Row {
    line: usize,
    hex: Vec<u16>,
    asm: String,
    setup: String,
    expect: String,
    cycles: u64,
}

fn rows() -> Vec<Row> {
    let text = include_str!("data/instructions.table");
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|(i, l)| {
            let f: Vec<&str> = l.split('|').map(str::trim).collect();
            assert_eq!(f.len(), 5, "line {}: expected 5 fields", i + 1);
            Row {
                line: i + 1,
                hex: f[0]
                    .split_whitespace()
                    .map(|h| u16::from_str_radix(h, 16).expect("hex"))
                    .collect(),
                asm: f[1].to_string(),
                setup: f[2].to_string(),
                expect: f[3].to_string(),
                cycles: f[4].parse().expect("cycles"),
            }
        })
        .collect()
}

fn set_nzcv(board: &mut Board, bits: &str) {
    let b: Vec<bool> = bits.chars().map(|c| c == '1').collect();
    let c = &mut board.cores[0];
    (c.n, c.z, c.c, c.v) = (b[0], b[1], b[2], b[3]);
}

fn reg_index(name: &str) -> Option<usize> {
    match name {
        "sp" => Some(13),
        "lr" => Some(14),
        "pc" => Some(15),
        _ => name.strip_prefix('r').and_then(|n| n.parse().ok()),
    }
}

/// Runs one row; returns a description of each mismatch.
fn check(row: &Row) -> Vec<String> {
    let mut board = Board::new(Config::default());
    let mut addr = CODE;
    for hw in &row.hex {
        board.write_bytes(addr, &hw.to_le_bytes()).unwrap();
        addr += 2;
    }
    board.start_core(0, CODE | 1, STACK, 0);
    for item in row.setup.split_whitespace() {
        let (k, v) = item.split_once('=').expect("key=value");
        if let Some(a) = k.strip_prefix("m[").and_then(|k| k.strip_suffix(']')) {
            board.write_u32(num(a), num(v)).unwrap();
        } else if k == "nzcv" {
            set_nzcv(&mut board, v);
        } else if k == "primask" {
            board.cores[0].primask = num(v) != 0;
        } else {
            let r = reg_index(k).unwrap_or_else(|| panic!("line {}: bad key {k}", row.line));
            board.cores[0].r[r] = num(v);
        }
    }
    let before = board.cores[0].cycle;
    let outcome = board.step(u64::MAX);
    let cycles = board.cores[0].cycle - before;
    let mut errors = Vec::new();
    let fault = match outcome {
        Some(Err(StopReason::Fault { fault, .. })) => Some(fault.kind),
        Some(Ok(_)) => None,
        other => {
            errors.push(format!("unexpected outcome {other:?}"));
            None
        }
    };
    let mut want_fault = None;
    for item in row.expect.split_whitespace() {
        let (k, v) = item.split_once('=').expect("key=value");
        let c = &board.cores[0];
        let (got, want) = if let Some(a) = k.strip_prefix("m[").and_then(|k| k.strip_suffix(']')) {
            (board.read_u32(num(a)).unwrap(), num(v))
        } else if k == "nzcv" {
            let got = format!("{}{}{}{}", c.n as u8, c.z as u8, c.c as u8, c.v as u8);
            if got != v {
                errors.push(format!("nzcv {got}, want {v}"));
            }
            continue;
        } else if k == "primask" {
            (c.primask as u32, num(v))
        } else if k == "fault" {
            want_fault = Some(v.to_string());
            continue;
        } else {
            (c.r[reg_index(k).expect("register")], num(v))
        };
        if got != want {
            errors.push(format!("{k} = {got:#x}, want {want:#x}"));
        }
    }
    let fault_name = fault.map(|f| match f {
        FaultKind::Undefined { .. } => "undefined",
        FaultKind::Unaligned { .. } => "unaligned",
        FaultKind::Bus { .. } => "bus",
        FaultKind::InvalidState { .. } => "invalidstate",
        FaultKind::Breakpoint { .. } => "breakpoint",
        FaultKind::InvalidExcReturn { .. } => "excreturn",
        FaultKind::SvcEscalation => "svc",
    });
    if fault_name.map(str::to_string) != want_fault {
        errors.push(format!("fault {fault_name:?}, want {want_fault:?}"));
    }
    if fault.is_some() && board.cores[0].ipsr != 3 {
        errors.push("fault did not enter HardFault".into());
    }
    if cycles != row.cycles {
        errors.push(format!("{cycles} cycles, want {}", row.cycles));
    }
    if matches!(row.asm.as_str(), "wfi" | "wfe")
        && !matches!(board.cores[0].state, RunState::Sleeping { .. })
    {
        errors.push("did not sleep".into());
    }
    errors
}

#[test]
fn instruction_table() {
    let rows = rows();
    assert!(rows.len() > 150, "table has only {} rows", rows.len());
    let mut failures = Vec::new();
    for row in &rows {
        for e in check(row) {
            failures.push(format!("line {} `{}`: {e}", row.line, row.asm));
        }
    }
    assert!(
        failures.is_empty(),
        "{} mismatches:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn table_encodings_match_assembler() {
    if !common::have_tool("arm-none-eabi-as", "table_encodings_match_assembler") {
        return;
    }
    let rows = rows();
    let mut src = String::from(".syntax unified\n.cpu cortex-m0\n.thumb\n.text\n");
    for row in &rows {
        src.push_str(&row.asm);
        src.push('\n');
    }
    let dir = common::scratch_dir("table");
    let text = common::assemble_text(&dir, "table", &src);
    let got: Vec<u16> = text
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    let mut at = 0;
    for row in &rows {
        let n = row.hex.len();
        assert_eq!(
            &got[at..at + n],
            &row.hex[..],
            "line {} `{}`",
            row.line,
            row.asm
        );
        at += n;
    }
}

#[test]
fn every_halfword_decodes_prices_and_prints() {
    // Every first halfword decodes, prices and prints without panicking, and 32-bit
    // prefixes never decode as 16-bit instructions.
    for hw in 0..=u16::MAX {
        let i = tactus_isa::decode::decode(hw, 0xf800);
        assert!(!i.to_string().is_empty());
        if tactus_isa::decode::is_32bit(hw) {
            assert!(
                matches!(
                    i,
                    tactus_isa::decode::Instr::Bl { .. }
                        | tactus_isa::decode::Instr::Undefined { .. }
                ),
                "{hw:04x} f800 decoded as {i:?}"
            );
        }
        let _ = tactus_isa::timing::cycles(&i, true, false);
    }
}

#[test]
fn every_timing_class_has_a_cycle_row() {
    use std::collections::HashSet;
    use tactus_isa::timing::{class, Class};
    let covered: HashSet<Class> = rows()
        .iter()
        .map(|r| {
            class(&tactus_isa::decode::decode(
                r.hex[0],
                r.hex.get(1).copied().unwrap_or(0),
            ))
        })
        .collect();
    let missing: Vec<Class> = Class::ALL
        .iter()
        .copied()
        .filter(|c| !covered.contains(c))
        .collect();
    assert!(
        missing.is_empty(),
        "timing classes without a table row: {missing:?}"
    );
}

#[test]
fn disassembly_reassembles_to_the_same_encoding() {
    if !common::have_tool(
        "arm-none-eabi-as",
        "disassembly_reassembles_to_the_same_encoding",
    ) {
        return;
    }
    let rows = rows();
    let mut src = String::from(".syntax unified\n.cpu cortex-m0\n.thumb\n.text\n");
    for row in &rows {
        let instr = tactus_isa::decode::decode(row.hex[0], row.hex.get(1).copied().unwrap_or(0));
        src.push_str(&instr.to_string());
        src.push('\n');
    }
    let text = common::assemble_text(&common::scratch_dir("disasm"), "disasm", &src);
    let got: Vec<u16> = text
        .chunks(2)
        .map(|c| u16::from_le_bytes([c[0], c[1]]))
        .collect();
    let mut at = 0;
    for row in &rows {
        let n = row.hex.len();
        let shown = tactus_isa::decode::decode(row.hex[0], row.hex.get(1).copied().unwrap_or(0))
            .to_string();
        assert_eq!(
            &got[at..at + n],
            &row.hex[..],
            "line {}: `{}` shown as `{shown}`",
            row.line,
            row.asm
        );
        at += n;
    }
}
