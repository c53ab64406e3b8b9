//! Cycles per key-sample and code size of the Tactus Thumb backend on the emulated RP2040,
//! every instrument over every built-in stimulus (each sample checked bit for bit against
//! the fixed interpreter) — the same runs and table as `--example compilers`, so the rows
//! compare directly.
//!
//! ```text
//! cargo run --release -p tactus-firmware --example thumb [INSTRUMENT...]
//! ```

use std::path::Path;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::lower::Config;
use tactus_compiler::thumb;
use tactus_firmware::measure::{builtin_runs, compare};
use tactus_firmware::report::{table, Row};
use tactus_firmware::{Interface, UpdateRunner};

fn main() {
    let only: Vec<String> = std::env::args().skip(1).collect();
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
    let mut rows = Vec::new();
    for path in files {
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(&path).expect("read instrument");
        let Ok(l) = tactus_compiler::compile(&text, &Config::default()) else {
            println!("{name}: does not compile");
            ok = false;
            continue;
        };
        let fp = FixedProgram::new(&l.program);
        let obj = match thumb::compile(&fp) {
            Ok(o) => o,
            Err(e) => {
                println!("{name}: {e}");
                ok = false;
                continue;
            }
        };
        let (init, _) = obj.symbol(&obj.init_name()).expect("init symbol");
        let (update, update_bytes) = obj.symbol(&obj.update_name()).expect("update symbol");
        let runs = builtin_runs(&fp);
        let iface = Interface::new(&fp, &obj.stem, &obj.out);
        let cmp = UpdateRunner::from_code(
            &obj.code.text,
            0x2000_0000,
            init as u32,
            update as u32,
            iface,
        )
        .and_then(|mut r| compare(&mut r, &fp, &obj.out, &runs));
        let cmp = match cmp {
            Ok(c) => c,
            Err(e) => {
                println!("{name}: {e}");
                ok = false;
                continue;
            }
        };
        if cmp.mismatches > 0 {
            ok = false;
            println!("{name}: {} mismatches", cmp.mismatches);
        }
        println!(
            "{name}: worst at {} sample {}",
            cmp.cycles.worst_at.0, cmp.cycles.worst_at.1
        );
        rows.push(Row {
            instrument: name,
            engine: "tactus thumb".into(),
            comparison: cmp,
            update_bytes: Some(update_bytes as u32),
            with_helpers_bytes: Some(obj.code.text.len() as u32),
        });
    }
    println!();
    print!("{}", table(&rows));
    if !ok {
        std::process::exit(1);
    }
}
