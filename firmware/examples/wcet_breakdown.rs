//! Where an update's static WCET goes: the instructions of its worst path (as
//! `budget::static_update` finds it) summed by category, each priced by the emulator's
//! timing table (`isa/src/timing.rs`, taken or not as the path goes).
//!
//! `cargo run -p tactus-firmware --example wcet_breakdown -- instruments/grand_piano.tactus [--list] [--asm] [--isr]`
//! (`--list`: the worst path instruction by instruction; `--asm`: the whole object's GNU
//! assembler listing first, to compare the code of two compiler versions; `--isr`: the
//! firmware image's calling convention, `thumb::Convention::SAMPLE_ISR`, instead of AAPCS).
//!
//! `… -- --layout instruments/layouts/grand88.toml [--list] [--asm]` analyses the programs
//! of a keyboard layout as `tactus budget` compiles them
//! (`tactus_firmware::image::compile_layout`: the param sets of one instrument share one
//! code, graded params as run-time data, the image's calling convention), one breakdown per
//! distinct code. A layout's
//! instrument names a file beside the layout, `instruments/NAME.tactus` under the layout's
//! parent directory, or `instruments/NAME.tactus` under the current one.
//!
//! Categories are by instruction: `MULS`; operand splitting for multi-word products
//! (`UXTH`); 64-bit carries (`ADCS`/`SBCS`); state loads and stores (`[r7, …]` and other
//! registers); spills (`[sp, …]`); literal-pool loads; register moves; shifts; other ALU
//! operations; compares; branches; prologue and epilogue (`PUSH`/`POP`, `SP` adjustments).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::lower::Config;
use tactus_compiler::thumb;
use tactus_compiler::thumb::ThumbObject;
use tactus_firmware::budget::{self, LOAD_ADDR};
use tactus_isa::decode::{decode, AluOp, Instr};
use tactus_isa::timing;

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
    let list = args.iter().any(|a| a == "--list");
    let asm = args.iter().any(|a| a == "--asm");
    if let Some(k) = args.iter().position(|a| a == "--layout") {
        let Some(layout) = args.get(k + 1) else {
            eprintln!("usage: wcet_breakdown --layout LAYOUT.toml [--list] [--asm]");
            std::process::exit(2);
        };
        return analyse_layout(Path::new(layout), list, asm);
    }
    let Some(path) = args.iter().find(|a| !a.starts_with("--")) else {
        eprintln!("usage: wcet_breakdown INSTRUMENT.tactus [--list] [--asm] | --layout LAYOUT.toml [--list] [--asm]");
        std::process::exit(2);
    };
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
    let conv = if args.iter().any(|a| a == "--isr") {
        thumb::Convention::SAMPLE_ISR
    } else {
        thumb::Convention::AAPCS
    };
    let obj = thumb::compile_with(&fp, conv).unwrap_or_else(|e| {
        eprintln!("{path}: {e}");
        std::process::exit(1)
    });
    breakdown(path, &fp, &obj, list, asm);
}

/// The source file of instrument `name` of the layout at `layout` (see the module's doc).
fn instrument_path(layout: &Path, name: &str) -> Option<PathBuf> {
    let dir = layout.parent().unwrap_or(Path::new("."));
    let file = format!("{name}.tactus");
    [
        dir.join(name),
        dir.join(&file),
        dir.join("..").join(&file),
        dir.join("../instruments").join(&file),
        Path::new("instruments").join(&file),
    ]
    .into_iter()
    .find(|p| p.is_file())
}

/// Breaks down each distinct code of the layout at `path` as the budget compiles it.
fn analyse_layout(path: &Path, list: bool, asm: bool) {
    let shown = path.display().to_string();
    let (_, keys) = tactus_runtime::keyboard::read_layout(path).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    });
    let source = |name: &str| -> Result<String, String> {
        let p = instrument_path(path, name)
            .ok_or_else(|| format!("no source file for instrument `{name}`"))?;
        std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))
    };
    let fs = Config::default().sample_rate_hz;
    let (programs, key_programs) = tactus_firmware::image::compile_layout(&keys, &source, fs)
        .unwrap_or_else(|e| {
            eprintln!("{shown}: {e}");
            std::process::exit(1)
        });
    for (i, p) in programs.iter().enumerate() {
        if programs[..i].iter().any(|q| q.same_code(p)) {
            continue;
        }
        let n = (0..programs.len())
            .filter(|&j| programs[j].same_code(p))
            .map(|j| key_programs.iter().filter(|&&k| k == j).count())
            .sum::<usize>();
        println!(
            "{shown}: program {i} ({} keys, {} run-time params)",
            n,
            p.params.len()
        );
        if std::env::args().any(|a| a == "--report") {
            let fp = &p.fixed;
            print!(
                "{}",
                tactus_compiler::fixed::render::render(
                    fp,
                    &tactus_compiler::fixed::report::analyse(fp)
                )
            );
        }
        breakdown(&shown, &p.fixed, &p.thumb, list, asm);
        // The glue a key of it costs beside its update, on the built-in 133 MHz board.
        let text = std::fs::read_to_string("boards/rp2040.toml").unwrap_or_default();
        if let Ok(board) = tactus_firmware::boards::read_board(&text, "boards/rp2040.toml") {
            let lim = tactus_runtime::limiter::LimiterConfig::default();
            let mut plain = p.clone();
            plain.quiescent_guard = false;
            let glue = |q: &tactus_firmware::image::Program| {
                tactus_firmware::image::FirmwareImage::key_glue(q, &board, &lim)
                    .map_or("—".to_string(), |g| g.cycles.to_string())
            };
            println!(
                "glue per key (boards/rp2040.toml): {} without the quiescent-key guard, {} with it",
                glue(&plain),
                glue(p)
            );
        }
    }
}

/// Prints the worst path of `obj`'s update by category (and instruction by instruction
/// with `list`, after the whole listing with `asm`); `path` names it in errors.
fn breakdown(path: &str, fp: &FixedProgram, obj: &ThumbObject, list: bool, asm: bool) {
    let program = &fp.program;
    if asm {
        println!("{}", obj.code.listing);
    }
    let name = obj.update_name();
    let w = budget::function_wcet(obj, &name).unwrap_or_else(|e| {
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
                // A literal-pool load shows its word, to spot constants a path loads twice.
                let word = match i {
                    Instr::LdrLit { imm, .. } => {
                        let at = (((off + 4) & !3) + u32::from(imm)) as usize;
                        text.get(at..at + 4).map_or(String::new(), |b| {
                            format!(" ={}", i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                        })
                    }
                    _ => String::new(),
                };
                println!("{off:6x}  {c}  {:<28} {cat}", format!("{i}{word}"));
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
