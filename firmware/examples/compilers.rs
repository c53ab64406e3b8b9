//! Cycles per key-sample and code size of the C backend compiled by clang -O2 and
//! arm-none-eabi-gcc -O2 for the Cortex-M0+, on the emulated RP2040, every instrument over
//! every built-in stimulus (each sample also checked bit for bit against the fixed
//! interpreter).
//!
//! ```text
//! cargo run --release -p tactus-firmware --example compilers [--keep DIR] [INSTRUMENT...]
//! ```
//!
//! `--keep DIR` keeps each build's work directory (C files, objects, linker script, ELFs)
//! under DIR, for disassembly.
//!
//! Prints a Markdown table (see `tactus_firmware::report::table`) and, per build, the
//! helper functions linked for the update. Exits with status 1 on a mismatch or a failed
//! build.

use std::path::Path;
use tactus_compiler::cgen;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::lower::Config;
use tactus_firmware::cc::{self, Compiler, Options};
use tactus_firmware::measure::{builtin_runs, compare};
use tactus_firmware::report::{table, Row};
use tactus_firmware::{Interface, UpdateRunner};

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut opts = Options::default();
    if let Some(i) = args.iter().position(|a| a == "--keep") {
        if i + 1 >= args.len() {
            eprintln!("--keep needs a directory");
            std::process::exit(2);
        }
        opts.work_dir = Some(args.remove(i + 1).into());
        args.remove(i);
    }
    let only = args;
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("instruments/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "tactus"))
        .filter(|p| {
            only.is_empty()
                || only
                    .iter()
                    .any(|o| p.file_stem().is_some_and(|s| s.to_string_lossy() == *o))
        })
        .collect();
    files.sort();
    let mut ok = true;
    for c in Compiler::ALL {
        match c.version() {
            Ok(v) => println!("{}: {v}", c.name()),
            Err(e) => {
                println!("{}: {e}", c.name());
                ok = false;
            }
        }
    }
    let mut rows = Vec::new();
    let mut notes = Vec::new();
    for path in files {
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(&path).expect("read instrument");
        let p = match tactus_compiler::compile(&text, &Config::default()) {
            Ok(l) => l.program,
            Err(_) => {
                println!("{name}: does not compile");
                ok = false;
                continue;
            }
        };
        let fp = FixedProgram::new(&p);
        let c = match cgen::emit_c(&fp) {
            Ok(c) => c,
            Err(e) => {
                println!("{name}: {e}");
                ok = false;
                continue;
            }
        };
        let runs = builtin_runs(&fp);
        for compiler in Compiler::ALL {
            let b = match cc::build(&c, compiler, &opts) {
                Ok(b) => b,
                Err(e) => {
                    println!("{name} {}: {e}", compiler.name());
                    ok = false;
                    continue;
                }
            };
            let iface = Interface::new(&fp, &c.stem, &c.layout);
            let t0 = std::time::Instant::now();
            let cmp = UpdateRunner::from_elf(&b.elf, iface)
                .and_then(|mut r| compare(&mut r, &fp, &c.layout, &runs));
            let cmp = match cmp {
                Ok(cmp) => cmp,
                Err(e) => {
                    println!("{name} {}: {e}", compiler.name());
                    ok = false;
                    continue;
                }
            };
            if cmp.mismatches > 0 {
                ok = false;
                println!("{name} {}: {} mismatches", compiler.name(), cmp.mismatches);
                for m in &cmp.first_mismatches {
                    println!("{m}");
                }
            }
            notes.push(format!(
                "{name} {}: worst at {} sample {}; best {} cycles; init {} cycles; .rodata {} B; \
                 helpers: {}; {} samples in {:.2} s",
                compiler.name(),
                cmp.cycles.worst_at.0,
                cmp.cycles.worst_at.1,
                cmp.cycles.best,
                cmp.init_cycles,
                b.update_rodata_bytes,
                if b.helpers.is_empty() {
                    "none".to_string()
                } else {
                    b.helpers
                        .iter()
                        .map(|f| format!("{} ({} B)", f.name, f.size))
                        .collect::<Vec<_>>()
                        .join(", ")
                },
                cmp.samples,
                t0.elapsed().as_secs_f64()
            ));
            rows.push(Row {
                instrument: name.clone(),
                engine: format!("{} -O2", compiler.name()),
                comparison: cmp,
                update_bytes: Some(b.update_bytes),
                with_helpers_bytes: Some(b.update_with_helpers_bytes),
            });
        }
    }
    println!();
    print!("{}", table(&rows));
    println!();
    for n in notes {
        println!("{n}");
    }
    if !ok {
        std::process::exit(1);
    }
}
