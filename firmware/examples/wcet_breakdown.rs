//! Where an update's static WCET goes: the instructions of its worst path (as
//! `budget::static_update` finds it) summed by category, each priced by the emulator's
//! timing table (`emulator/src/timing.rs`, taken or not as the path goes).
//!
//! `cargo run -p tactus-firmware --example wcet_breakdown -- instruments/grand_piano.tactus [--list] [--asm]`
//! (`--list`: the worst path instruction by instruction; `--asm`: the whole object's GNU
//! assembler listing first, to compare the code of two compiler versions).
//!
//! Categories are by instruction: `MULS`; operand splitting for multi-word products
//! (`UXTH`); 64-bit carries (`ADCS`/`SBCS`); state loads and stores (`[r7, …]` and other
//! registers); spills (`[sp, …]`); literal-pool loads; register moves; shifts; other ALU
//! operations; compares; branches; prologue and epilogue (`PUSH`/`POP`, `SP` adjustments).

use std::collections::BTreeMap;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::lower::Config;
use tactus_compiler::thumb;
use tactus_emulator::decode::{decode, AluOp, Instr};
use tactus_emulator::timing;
use tactus_firmware::budget::{self, LOAD_ADDR};

fn category(i: &Instr) -> &'static str {
    match i {
        Instr::Alu { op: AluOp::Mul, .. } => "MULS",
        Instr::Uxth { .. } | Instr::Sxth { .. } => "operand halves (UXTH/SXTH)",
        Instr::Alu {
            op: AluOp::Adc | AluOp::Sbc,
            ..
        } => "64-bit carries (ADCS/SBCS)",
        Instr::LslImm { .. }
        | Instr::LsrImm { .. }
        | Instr::AsrImm { .. }
        | Instr::Alu {
            op: AluOp::Lsl | AluOp::Lsr | AluOp::Asr,
            ..
        } => "shifts",
        Instr::MemImm { rn: 13, .. } => "spills and reloads ([sp])",
        Instr::MemImm { .. } | Instr::MemReg { .. } => "state/sensor/output loads and stores",
        Instr::LdrLit { .. } => "literal-pool loads",
        Instr::MovHi { .. } | Instr::MovImm { .. } => "moves (MOV, MOVS #imm)",
        Instr::CmpImm { .. }
        | Instr::CmpHi { .. }
        | Instr::Alu {
            op: AluOp::Cmp | AluOp::Cmn | AluOp::Tst,
            ..
        } => "compares",
        Instr::Push { .. } | Instr::Pop { .. } | Instr::AddSp { .. } | Instr::SubSp { .. } => {
            "prologue/epilogue"
        }
        Instr::B { .. } | Instr::BCond { .. } | Instr::Bl { .. } | Instr::Bx { .. } => "branches",
        _ => "other ALU (ADDS/SUBS/RSBS/EORS/ORRS/ANDS/MVNS)",
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(path) = args.iter().find(|a| !a.starts_with("--")) else {
        eprintln!("usage: wcet_breakdown INSTRUMENT.tactus [--list] [--asm]");
        std::process::exit(2);
    };
    let list = args.iter().any(|a| a == "--list");
    let asm = args.iter().any(|a| a == "--asm");
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| {
        eprintln!("{path}: {e}");
        std::process::exit(2)
    });
    let program = match tactus_compiler::compile(&text, &Config::default()) {
        Ok(c) => c.program,
        Err(_) => {
            eprintln!("{path}: does not compile (run `tactus check {path}`)");
            std::process::exit(1)
        }
    };
    let fp = FixedProgram::new(&program);
    let obj = thumb::compile(&fp).unwrap_or_else(|e| {
        eprintln!("{path}: {e}");
        std::process::exit(1)
    });
    if asm {
        println!("{}", obj.code.listing);
    }
    let name = obj.update_name();
    let w = budget::function_wcet(&obj, &name).unwrap_or_else(|e| {
        eprintln!("{path}: {e}");
        std::process::exit(1)
    });
    let text = &obj.code.text;
    let half = |off: u32| -> u16 {
        let o = off as usize;
        u16::from_le_bytes([text[o], text[o + 1]])
    };
    let mut by: BTreeMap<&'static str, (u64, u64)> = BTreeMap::new();
    let mut total = 0u64;
    for (k, &start) in w.path.iter().enumerate() {
        let end = w
            .blocks
            .iter()
            .find(|b| b.start == start)
            .map_or(start, |b| b.end);
        let next = w.path.get(k + 1).copied();
        let mut a = start;
        while a < end {
            let off = a - LOAD_ADDR;
            let i = decode(half(off), half(off + 2));
            let size = match i {
                Instr::Bl { .. } => 4,
                _ => 2,
            };
            let last = a + size >= end;
            let taken = last && next.is_some_and(|n| n != end);
            let c = timing::cycles(&i, taken, false) as u64;
            let cat = category(&i);
            let e = by.entry(cat).or_default();
            e.0 += 1;
            e.1 += c;
            total += c;
            if list {
                println!("{off:6x}  {c}  {i:<28} {cat}");
            }
            a += size;
        }
    }
    let calls: u64 = w.calls.iter().map(|c| c.cycles).sum();
    println!(
        "{}: static WCET {} cycles (worst path {} + the caller's BL {}); by category on that path:",
        program.name,
        w.cycles + tactus_firmware::runner::BL_CYCLES,
        w.cycles,
        tactus_firmware::runner::BL_CYCLES
    );
    let mut rows: Vec<_> = by.into_iter().collect();
    rows.sort_by_key(|r| std::cmp::Reverse(r.1 .1));
    for (cat, (n, c)) in rows {
        println!(
            "  {cat:<40} {n:>5} instructions {c:>6} cycles  {:>5.1} %",
            100.0 * c as f64 / total.max(1) as f64
        );
    }
    println!("  (sum {total} cycles; calls out of the update: {calls})");
    println!("products: {} if all ran", fp.mul_forms());
}
