//! The C backend compiled by real Cortex-M0+ compilers (clang -O2, arm-none-eabi-gcc -O2),
//! run on the emulated RP2040 through `UpdateRunner`, against the fixed interpreter bit for
//! bit: every instrument, every built-in stimulus, every sample (out words, states, modes).
//! Also: the state struct layout the runner computes is the one the compilers use
//! (`offsetof`/`sizeof` compiled into the image and read back from the board), and the
//! runner's typed errors.
//!
//! Without the compilers the tests print why and pass, unless the environment variable `CI`
//! is set (CI installs them: `.ci/run`), where they fail.

mod common;

use common::small_instruments;
use tactus_compiler::cgen::{self, CSource};
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::lower::Config;
use tactus_firmware::cc::{self, Compiler, Options};
use tactus_firmware::measure::{builtin_runs, compare, compare_many, Run};
use tactus_firmware::runner::RunError;
use tactus_firmware::{Interface, UpdateRunner};

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

/// Instruments whose C update costs far more than the others on the Cortex-M0+, with their
/// cap on samples per stimulus: `rubbed_bank` computes 11 software `exp` per sample,
/// 191k (gcc) to 355k (clang) cycles against at most 2.5k for the piano: at the common cap it
/// was 99 % of the emulated cycles and made this test take 8 minutes; at 2,000 samples per
/// stimulus it adds about half a minute. (Measured with the former Q60 `exp`, 16 Taylor terms
/// in `int64_t` with divisions; the current one — eight 32×32→64 products — is far cheaper,
/// but the cap stays until it is re-measured with both compilers.)
const HEAVY: &[(&str, usize)] = &[("rubbed_bank", 2_000)];

/// The built-in stimuli, every sample, except that stimuli longer than 1.1 s (`slow-dip`,
/// 4.3 s) are decimated to at most 1.1 s by taking every k-th sample: the whole down and up
/// stroke at a higher speed. This keeps the debug-build test within a minute on a 2-core
/// machine; the example `compilers` checks every sample of every stimulus (in release).
/// Instruments in [`HEAVY`] are decimated further, to their own cap.
fn test_runs(fp: &FixedProgram) -> Vec<Run> {
    const MAX: usize = 48_510; // 1.1 s at 44.1 kHz
    let max = HEAVY
        .iter()
        .find(|(n, _)| *n == fp.program.name)
        .map_or(MAX, |(_, m)| *m);
    builtin_runs(fp)
        .into_iter()
        .map(|r| {
            let k = r.records.len().div_ceil(max);
            Run {
                label: if k > 1 {
                    format!("{} (every {k}th sample)", r.label)
                } else {
                    r.label
                },
                records: r.records.into_iter().step_by(k).collect(),
            }
        })
        .collect()
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
    struct Inst {
        name: String,
        fp: FixedProgram,
        c: CSource,
        builds: Vec<cc::Build>,
        runs: Vec<Run>,
    }
    let insts: Vec<Inst> = small_instruments()
        .into_iter()
        .map(|(name, text)| {
            let (fp, c) = compile(&text);
            let builds = compilers
                .iter()
                .map(|&compiler| {
                    let b = cc::build(&c, compiler, &Options::default())
                        .unwrap_or_else(|e| panic!("{name} {}: {e}", compiler.name()));
                    let helpers: u32 = b.helpers.iter().map(|f| f.size).sum();
                    assert!(b.update_bytes > 0);
                    assert!(
                        b.update_with_helpers_bytes >= b.update_bytes + helpers,
                        "{name}: sizes"
                    );
                    b
                })
                .collect();
            let runs = test_runs(&fp);
            assert!(runs.len() >= 5, "{name}: built-in stimuli missing");
            Inst {
                name,
                fp,
                c,
                builds,
                runs,
            }
        })
        .collect();
    // Work items (instrument, stimulus), longest first, shared by one worker per core; each
    // item runs all builds in lock-step with one pass of the interpreter.
    let mut items: Vec<(usize, usize)> = insts
        .iter()
        .enumerate()
        .flat_map(|(i, inst)| (0..inst.runs.len()).map(move |r| (i, r)))
        .collect();
    items.sort_by_key(|&(i, r)| {
        std::cmp::Reverse(insts[i].runs[r].records.len() * insts[i].c.source.len())
    });
    let queue = std::sync::Mutex::new(items);
    let workers = std::thread::available_parallelism().map_or(2, |n| n.get());
    // Per (instrument, build): the comparisons of its stimuli.
    let results = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let Some((i, r)) = queue.lock().unwrap().pop() else {
                    break;
                };
                let inst = &insts[i];
                let mut runners: Vec<UpdateRunner> = inst
                    .builds
                    .iter()
                    .map(|b| {
                        let iface = Interface::new(&inst.fp, &inst.c.stem, &inst.c.layout);
                        UpdateRunner::from_elf(&b.elf, iface)
                            .unwrap_or_else(|e| panic!("{} {}: {e}", inst.name, b.compiler.name()))
                    })
                    .collect();
                let run = std::slice::from_ref(&inst.runs[r]);
                let cmps = compare_many(&mut runners, &inst.fp, &inst.c.layout, run)
                    .unwrap_or_else(|e| panic!("{} {}: {e}", inst.name, run[0].label));
                let mut res = results.lock().unwrap();
                for (k, cmp) in cmps.into_iter().enumerate() {
                    res.push((i, k, r, cmp));
                }
            });
        }
    });
    let results = results.into_inner().unwrap();
    let mut events = 0;
    for (i, inst) in insts.iter().enumerate() {
        let total: usize = inst.runs.iter().map(|r| r.records.len()).sum();
        for (k, b) in inst.builds.iter().enumerate() {
            let name = &inst.name;
            let compiler = b.compiler.name();
            let cmps: Vec<_> = results
                .iter()
                .filter(|(ri, rk, _, _)| (*ri, *rk) == (i, k))
                .map(|(_, _, _, c)| c)
                .collect();
            assert_eq!(
                cmps.len(),
                inst.runs.len(),
                "{name} {compiler}: runs missing"
            );
            let samples: usize = cmps.iter().map(|c| c.samples).sum();
            let calls: u64 = cmps.iter().map(|c| c.cycles.calls).sum();
            assert_eq!(samples, total);
            assert_eq!(calls as usize, total);
            for c in &cmps {
                assert!(
                    c.mismatches == 0,
                    "{name} {compiler}: {} mismatching samples; first:\n{}",
                    c.mismatches,
                    c.first_mismatches.join("\n")
                );
                // A real update costs more than the call overhead.
                assert!(c.cycles.best > 10, "{name}: implausible cycle count");
            }
            events += cmps.iter().map(|c| c.events).sum::<usize>();
            let worst = cmps.iter().map(|c| c.cycles.worst).max().unwrap_or(0);
            let cycles: u64 = cmps.iter().map(|c| c.cycles.total).sum();
            println!(
                "{name:<16} {compiler:<5} {samples} samples, worst {worst} mean {:.1} cycles, update {} B, with helpers {} B",
                cycles as f64 / calls as f64,
                b.update_bytes,
                b.update_with_helpers_bytes
            );
        }
    }
    // Some instrument emits events, so their comparison is not vacuous.
    assert!(events > 0, "no event in any instrument and stimulus");
    println!("{:.1} s", t0.elapsed().as_secs_f64());
}

/// The byte offsets and the size computed by `StateLayout` (the C backend's, which the Thumb
/// backend uses too) are the compilers' own: a probe
/// file puts `offsetof`/`sizeof` of the generated struct into a word array, linked into
/// the image and read back from the emulated memory.
#[test]
fn state_layout_matches_the_compilers() {
    for compiler in Compiler::ALL {
        if !available(compiler) {
            continue;
        }
        for (name, text) in small_instruments() {
            let (fp, c) = compile(&text);
            let st = &c.stem;
            let probe = format!(
                "#include <stddef.h>\n#include \"{st}.h\"\n\
                 #define S struct tactus_{st}_state\n\
                 const uint32_t tactus_layout_probe[8] = {{\n\
                 offsetof(S, states), offsetof(S, modes), offsetof(S, edges), offsetof(S, hist),\n\
                 offsetof(S, hist_pos), offsetof(S, published),\n\
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
            let got: Vec<usize> = (0..8)
                .map(|i| r.board().read_u32(addr + 4 * i).unwrap() as usize)
                .collect();
            let want = vec![
                l.states,
                l.modes,
                l.edges,
                l.hist,
                l.hist_pos,
                l.published,
                l.size,
                4, // _Alignof: the struct holds int32_t words
            ];
            assert_eq!(got, want, "{name} {}: state layout", compiler.name());
        }
    }
}

/// Typed errors, not panics: a missing symbol, code that faults (with its PC), code that
/// never returns, code that writes past `out`, and raw code with entry offsets.
#[test]
fn runner_errors_are_typed() {
    let (fp, c) = compile(&small_instruments()[0].1);
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
        other.header = other
            .header
            .replace(&format!("tactus_{}_", c.stem), "tactus_other_");
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
    let (fp, c) = compile(&small_instruments()[0].1);
    // Corrupt out[0] (a published word: a force term or the total) by + 1.
    let mut bad = c.clone();
    let needle = "out[i] = s->published[i];";
    assert!(
        bad.source.contains(needle),
        "cgen's copy loop changed; update this test"
    );
    bad.source = bad
        .source
        .replace(needle, "out[i] = s->published[i] + (i == 0);");
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
    for (name, text) in small_instruments() {
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
                slow.board()
                    .write_u32(sensors_addr + 4 * i as u32, *w as u32)
                    .unwrap();
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
