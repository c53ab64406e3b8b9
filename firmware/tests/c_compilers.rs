//! The C backend compiled by real Cortex-M0+ compilers (clang -O2, arm-none-eabi-gcc -O2),
//! run on the emulated RP2040 through `UpdateRunner`, against the fixed interpreter bit for
//! bit: every instrument, every built-in stimulus, every sample (out words, states, modes).
//! Also: the state struct layout the runner computes is the one the compilers use
//! (`offsetof`/`sizeof` compiled into the image and read back from the board), and the
//! runner's typed errors.
//!
//! Without the compilers the tests print why and pass, unless the environment variable `CI`
//! is set (CI installs them: `.ci/run`), where they fail.

use std::path::Path;
use tactus_compiler::cgen::{self, CSource};
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::lower::Config;
use tactus_firmware::cc::{self, Compiler, Options};
use tactus_firmware::measure::{builtin_runs, compare, Run};
use tactus_firmware::runner::RunError;
use tactus_firmware::{Interface, UpdateRunner};

fn instruments() -> Vec<(String, String)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments");
    let mut v: Vec<(String, String)> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "tactus"))
        .map(|p| {
            (
                p.file_stem().unwrap().to_string_lossy().into_owned(),
                std::fs::read_to_string(&p).unwrap(),
            )
        })
        .collect();
    v.sort();
    assert!(!v.is_empty());
    v
}

/// True when `compiler` and the binutils can be run; otherwise prints why, and panics when
/// `CI` is set.
fn available(compiler: Compiler) -> bool {
    match cc::check_tools(compiler) {
        Ok(()) => true,
        Err(e) => {
            let msg = format!("{} build not tested: {e}", compiler.name());
            if std::env::var_os("CI").is_some() {
                panic!("{msg} (CI is set: .ci/run installs the tools)");
            }
            println!("SKIPPED: {msg}");
            false
        }
    }
}

fn compile(text: &str) -> (FixedProgram, CSource) {
    let p = tactus_compiler::compile(text, &Config::default())
        .unwrap()
        .program;
    let fp = FixedProgram::new(&p);
    let c = cgen::emit_c(&fp).unwrap();
    (fp, c)
}

#[test]
fn compiled_c_matches_the_fixed_interpreter_on_every_instrument_and_stimulus() {
    let compilers: Vec<Compiler> = Compiler::ALL
        .into_iter()
        .filter(|&c| available(c))
        .collect();
    if compilers.is_empty() {
        return;
    }
    let t0 = std::time::Instant::now();
    // One thread per instrument (the emulator dominates).
    let results: Vec<(String, usize)> = std::thread::scope(|scope| {
        let handles: Vec<_> = instruments()
            .into_iter()
            .map(|(name, text)| {
                let compilers = &compilers;
                scope.spawn(move || {
                    let (fp, c) = compile(&text);
                    let runs = builtin_runs(&fp);
                    assert!(runs.len() >= 5, "{name}: built-in stimuli missing");
                    let mut lines = Vec::new();
                    let mut events = 0;
                    for &compiler in compilers {
                        let b = cc::build(&c, compiler, &Options::default())
                            .unwrap_or_else(|e| panic!("{name} {}: {e}", compiler.name()));
                        assert!(b.update_bytes > 0 && b.update_with_helpers_bytes >= b.update_bytes);
                        let iface = Interface::new(&fp, &c.stem, &c.layout);
                        let mut r = UpdateRunner::from_elf(&b.elf, iface)
                            .unwrap_or_else(|e| panic!("{name} {}: {e}", compiler.name()));
                        let cmp = compare(&mut r, &fp, &c.layout, &runs)
                            .unwrap_or_else(|e| panic!("{name} {}: {e}", compiler.name()));
                        let total: usize = runs.iter().map(|r| r.records.len()).sum();
                        assert_eq!(cmp.samples, total);
                        assert_eq!(cmp.cycles.calls as usize, total);
                        assert!(
                            cmp.mismatches == 0,
                            "{name} {}: {} mismatching samples; first:\n{}",
                            compiler.name(),
                            cmp.mismatches,
                            cmp.first_mismatches.join("\n")
                        );
                        // A real update costs more than the call overhead.
                        assert!(cmp.cycles.best > 10, "{name}: implausible cycle count");
                        events += cmp.events;
                        lines.push(format!(
                            "{name:<16} {:<5} {} samples, {} events, worst {} mean {:.1} cycles, update {} B, with helpers {} B",
                            compiler.name(),
                            cmp.samples,
                            cmp.events,
                            cmp.cycles.worst,
                            cmp.cycles.mean(),
                            b.update_bytes,
                            b.update_with_helpers_bytes
                        ));
                    }
                    (lines.join("\n"), events)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    for (lines, _) in &results {
        println!("{lines}");
    }
    // Some instrument emits events, so their comparison is not vacuous.
    assert!(results.iter().any(|(_, e)| *e > 0), "no event in any instrument and stimulus");
    println!("{:.1} s", t0.elapsed().as_secs_f64());
}

/// The byte offsets and the size computed by `StateLayout` are the compilers' own: a probe
/// file puts `offsetof`/`sizeof` of the generated struct into a word array, linked into
/// the image and read back from the emulated memory.
#[test]
fn state_layout_matches_the_compilers() {
    for compiler in Compiler::ALL {
        if !available(compiler) {
            continue;
        }
        for (name, text) in instruments() {
            let (fp, c) = compile(&text);
            let st = &c.stem;
            let probe = format!(
                "#include <stddef.h>\n#include \"{st}.h\"\n\
                 #define S struct tactus_{st}_state\n\
                 const uint32_t tactus_layout_probe[9] = {{\n\
                 offsetof(S, states), offsetof(S, modes), offsetof(S, edges), offsetof(S, hist),\n\
                 offsetof(S, hist_pos), offsetof(S, hist_primed), offsetof(S, published),\n\
                 sizeof(S), _Alignof(S) }};\n"
            );
            let opts = Options {
                extra_sources: vec![("probe.c".into(), probe)],
                keep: vec!["tactus_layout_probe".into()],
                ..Options::default()
            };
            let b = cc::build(&c, compiler, &opts)
                .unwrap_or_else(|e| panic!("{name} {}: {e}", compiler.name()));
            let iface = Interface::new(&fp, &c.stem, &c.layout);
            let l = iface.state;
            let mut r = UpdateRunner::from_elf(&b.elf, iface).unwrap();
            let addr = r.board().symbol("tactus_layout_probe").unwrap();
            let got: Vec<usize> = (0..9)
                .map(|i| r.board().read_u32(addr + 4 * i).unwrap() as usize)
                .collect();
            let want = vec![
                l.states,
                l.modes,
                l.edges,
                l.hist,
                l.hist_pos,
                l.hist_primed,
                l.published,
                l.size,
                l.align,
            ];
            assert_eq!(got, want, "{name} {}: state layout", compiler.name());
        }
    }
}

/// Typed errors, not panics: a missing symbol, code that faults (with its PC), code that
/// never returns, code that writes past `out`, and raw code with entry offsets.
#[test]
fn runner_errors_are_typed() {
    let (fp, c) = compile(&instruments()[0].1);
    let iface = Interface::new(&fp, &c.stem, &c.layout);
    // Raw Thumb code: init = `bx lr`; update = `ldr r0, [r0]` from an unmapped address
    // set up by `movs r0, #0; subs r0, #1` → 0xffffffff, which faults.
    let bx_lr: [u8; 2] = [0x70, 0x47];
    let fault = [0x00, 0x20, 0x01, 0x38, 0x00, 0x68, 0x70, 0x47]; // movs r0,#0; subs r0,#1; ldr r0,[r0]; bx lr
    let spin = [0xfe, 0xe7]; // b .
    let mut code = bx_lr.to_vec();
    code.extend_from_slice(&fault);
    code.extend_from_slice(&spin);
    let load = 0x2000_1000;
    let sensors = vec![0; iface.sensors];
    let mut r = UpdateRunner::from_code(&code, load, 0, 2, iface.clone()).unwrap();
    match r.step(&sensors) {
        Err(RunError::Call { pc, .. }) => assert_eq!(pc, load + 6, "the faulting ldr"),
        other => panic!("expected a fault, got {other:?}"),
    }
    let mut r = UpdateRunner::from_code(&code, load, 0, 10, iface.clone()).unwrap();
    r.set_call_limit(10_000);
    assert!(matches!(r.step(&sensors), Err(RunError::Call { .. })));
    assert!(matches!(
        r.step(&sensors[..sensors.len() - 1]),
        Err(RunError::SensorCount { .. })
    ));
    assert!(matches!(
        UpdateRunner::from_code(&code, load, 0, 64, iface.clone()),
        Err(RunError::BadEntry { .. })
    ));
    // Writes one word past out: `str r0, [r2, #4*len]` (len < 32), `bx lr`.
    let len = iface.out_len as u16;
    assert!(len < 32);
    let str_past = 0x6010 | (len << 6); // str r0, [r2, #imm5*4]
    let mut overrun = bx_lr.to_vec();
    overrun.extend_from_slice(&str_past.to_le_bytes());
    overrun.extend_from_slice(&bx_lr);
    let mut r = UpdateRunner::from_code(&overrun, load, 0, 2, iface.clone()).unwrap();
    assert!(matches!(
        r.step(&sensors),
        Err(RunError::Overrun { buffer: "out", .. })
    ));
    // An ELF without the symbols.
    if available(Compiler::Gcc) {
        let mut other = c.clone();
        other.stem = "other".into();
        other.header = other.header.replace(&format!("tactus_{}_", c.stem), "tactus_other_");
        other.source = other
            .source
            .replace(&format!("tactus_{}_", c.stem), "tactus_other_")
            .replace(&format!("\"{}.h\"", c.stem), "\"other.h\"");
        let b = cc::build(&other, Compiler::Gcc, &Options::default()).unwrap();
        match UpdateRunner::from_elf(&b.elf, iface.clone()) {
            Err(RunError::MissingSymbol(s)) => assert_eq!(s, iface.init_symbol()),
            other => panic!("expected a missing symbol, got {:?}", other.err()),
        }
    }
}

/// `compare` detects a corrupted update (a wrong published word): the check can fail.
#[test]
fn compare_detects_a_wrong_result() {
    if !available(Compiler::Gcc) {
        return;
    }
    let (fp, c) = compile(&instruments()[0].1);
    // Corrupt out[0] (a published word: a force term or the total) by + 1.
    let mut bad = c.clone();
    let needle = "out[i] = s->published[i];";
    assert!(bad.source.contains(&needle), "cgen's copy loop changed; update this test");
    bad.source = bad.source.replace(needle, "out[i] = s->published[i] + (i == 0);");
    let b = cc::build(&bad, Compiler::Gcc, &Options::default()).unwrap();
    let iface = Interface::new(&fp, &c.stem, &c.layout);
    let mut r = UpdateRunner::from_elf(&b.elf, iface).unwrap();
    let runs: Vec<Run> = builtin_runs(&fp)
        .into_iter()
        .map(|mut r| {
            r.records.truncate(200);
            r
        })
        .collect();
    let cmp = compare(&mut r, &fp, &c.layout, &runs).unwrap();
    assert_eq!(cmp.mismatches, cmp.samples);
    assert!(!cmp.first_mismatches.is_empty());
}

/// The runner's repeated calls (which skip rewriting `Board::call`'s return stub) give the
/// same out words and the same cycles as `Board::call` itself.
#[test]
fn repeated_calls_agree_with_board_call() {
    if !available(Compiler::Clang) {
        return;
    }
    for (name, text) in instruments() {
        let (fp, c) = compile(&text);
        let b = cc::build(&c, Compiler::Clang, &Options::default()).unwrap();
        let iface = Interface::new(&fp, &c.stem, &c.layout);
        let mut fast = UpdateRunner::from_elf(&b.elf, iface.clone()).unwrap();
        let mut slow = UpdateRunner::from_elf(&b.elf, iface.clone()).unwrap();
        let (sensors_addr, out_addr) = slow.buffers();
        let (state, update) = (slow.state_addr(), slow.update_addr());
        let runs = builtin_runs(&fp);
        let run = runs.iter().find(|r| r.label == "ff-dip").unwrap();
        let mut distinct = std::collections::BTreeSet::new();
        for rec in run.records.iter().step_by(7).take(1500) {
            let got = fast.step(rec).unwrap().clone();
            for (i, w) in rec.iter().enumerate() {
                slow.board().write_u32(sensors_addr + 4 * i as u32, *w as u32).unwrap();
            }
            let cycles = slow
                .call_via_board(update, &[state, sensors_addr, out_addr])
                .unwrap();
            let out: Vec<i32> = (0..iface.out_len as u32)
                .map(|i| slow.board().read_u32(out_addr + 4 * i).unwrap() as i32)
                .collect();
            assert_eq!((got.cycles, &got.out), (cycles, &out), "{name}");
            distinct.insert(cycles);
        }
        assert!(!distinct.is_empty());
    }
}
