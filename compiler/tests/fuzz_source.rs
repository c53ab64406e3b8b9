//! Fuzzing `.tactus` sources: the shipped instruments and the error cases, mutated at the
//! byte level (edits, long repeats, inserted keywords and extreme numbers), compile to a
//! program or to diagnostics — never a panic, a stack overflow, more than a bounded time or
//! a bounded heap. A program that compiles also runs 64 samples in the reference
//! interpreter. `TACTUS_FUZZ_CASES=100000` for a long run.

#[path = "../../tests/common/fuzz.rs"]
mod fuzz;

use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use std::cell::Cell;
use std::path::Path;
use std::time::Duration;
use tactus_compiler::lower::Config;
use tactus_compiler::sim::Engine;

const TOKENS: &[&[u8]] = &[
    b" + key",
    b" * ",
    b"(",
    b")",
    b"{",
    b"}",
    b"[",
    b"]",
    b" - ",
    b"not ",
    b"if key > 0 mm { 1 N } else { 2 N }",
    b"1e309",
    b"0 N/m / 0",
    b"exp(1000)",
    b"for i in 0..4096 { ",
    b"sum(i in 0..4096, 1 N)",
    b"\nforce g = 1 N\n",
    b"\nstate s: m = 0 mm in [0 mm, 1 mm]\n",
    b"\xef\xbb\xbf",
    b"use a = ",
    b"\ncomponent c { input x: m\n use a = c(x = x) }\n",
    b"-9223372036854775808",
    b"m^8*m^8*m^8",
    b"d(",
    b"d2(",
    b"solve x in [0 m, 1 m] { start = 0 m residual = x iterations = 16 }",
];

const LINES: &[&[u8]] = &[
    b"    force g = 1 N\n",
    b"    param q = 0 N/m / 0\n",
    b"    let z = key * key * key\n",
    b"    for i in 0..4096 { let w[i] = 1 N }\n",
    b"    state s2: m = 0 mm in [0 mm, 1 mm]\n",
    b"    dynamics { s2' = 1e12 m/s }\n",
    b"    force h = exp(1000) * 1 N\n",
    b"    require 1 < 0\n",
    b"    output o = key / (key - key)\n",
    b"    on key > 1 mm { emit e(v = 1 m/s) }\n",
];

const NUMBERS: &[&[u8]] = &[
    b"0",
    b"1e309",
    b"1e-320",
    b"4096",
    b"65536",
    b"9223372036854775807",
    b"1e12",
    b"0.0",
    b"17",
    b"2",
];

fn error_cases() -> usize {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/errors");
    std::fs::read_dir(dir)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|e| e == "tactus")
        })
        .count()
}

/// The shipped instruments first, then the error cases.
fn seeds() -> Vec<Vec<u8>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = Vec::new();
    for dir in [root.join("../instruments"), root.join("tests/errors")] {
        let mut files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "tactus"))
            .collect();
        files.sort();
        out.extend(files.iter().map(|p| std::fs::read(p).unwrap()));
    }
    assert!(out.len() > 30, "only {} seeds", out.len());
    out
}

#[test]
fn mutated_sources_compile_or_give_diagnostics() {
    let seeds = seeds();
    let (mut runner, cases) = fuzz::runner(2000);
    // Half the cases edit bytes (mostly syntax errors), half keep lines whole (mostly
    // programs that get through parsing into expansion, lowering and the interpreter).
    let instruments = seeds.len() - error_cases();
    let strategy = prop_oneof![
        (0..seeds.len(), fuzz::edits(TOKENS)),
        (0..instruments, fuzz::line_edits(LINES, NUMBERS)),
    ];
    let last = std::env::temp_dir().join("tactus-fuzz-source-last.tactus");
    let compiled = Cell::new(0u32);
    let run = Cell::new(0u32);
    runner
        .run(&strategy, |(seed, edits)| {
            let bytes = fuzz::apply(&seeds[seed], &edits);
            let src = String::from_utf8_lossy(&bytes).into_owned();
            // The case being run, for a case that ends the process (abort, kill).
            let _ = std::fs::write(&last, &src);
            let (ok, dt, peak) = fuzz::measured(|| {
                let linked = tactus_compiler::imports::link(
                    "f",
                    tactus_compiler::sources::Origin::Text,
                    &src,
                    &mut tactus_compiler::imports::NoFiles,
                );
                match tactus_compiler::compile_linked(&linked, &Config::default()) {
                    Ok(l) => {
                        let mut inst = tactus_compiler::interp::Instance::new(&l.program);
                        let sensors: Vec<f64> =
                            l.program.sensors.iter().map(|s| s.range.1).collect();
                        for _ in 0..64 {
                            let _ = inst.step_si(&sensors);
                        }
                        true
                    }
                    Err(d) => {
                        // Every error has a span inside one file of the program: the
                        // source, or a library file it imports.
                        assert!(d.iter().any(|d| d.is_error()));
                        for d in &d {
                            let span = &d.primary.0;
                            let file = linked.sources.get(linked.sources.file_at(span.start));
                            assert!(span.end <= file.base + file.text.len(), "{d:?}");
                        }
                        let _ =
                            tactus_compiler::diagnostics::emit_files_to_string(&linked.sources, &d);
                        false
                    }
                }
            });
            run.set(run.get() + 1);
            compiled.set(compiled.get() + u32::from(ok));
            prop_assert!(dt < Duration::from_secs(10), "{dt:?} for {edits:?}");
            prop_assert!(peak < 1 << 30, "{peak} bytes for {edits:?}");
            Ok::<(), TestCaseError>(())
        })
        .unwrap();
    let (run, compiled) = (run.get(), compiled.get());
    eprintln!("fuzz_source: {run} cases, {compiled} compiled, the rest diagnostics");
    assert!(run >= cases, "{run} of {cases} cases ran");
}

/// A case the fuzzer found (session 14): the bowed string's friction residual, inside a
/// `solve`, made a product of 40 factors, 19 of them calls of an unknown function. The
/// solve's symbolic slope copies the product's factors into every term, and lowering
/// re-lowered the copies until it ran out of memory (2.3 GB). Lowering now stops at
/// `MAX_LOWERED_VALUES` (E0139) and reports each error once.
#[test]
fn a_long_product_in_a_solve_with_unknown_calls_is_bounded() {
    // The bowed string as one file: the library's `string` (where the residual is) and the
    // instrument, its import taken out.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let instrument =
        std::fs::read_to_string(root.join("../instruments/bowed_string.tactus")).unwrap();
    let import = "import \"resonators.tactus\" { string }\n";
    assert!(instrument.contains(import), "bowed_string's import changed");
    let lib = tactus_compiler::library::file("resonators.tactus").unwrap();
    let src = format!("{lib}\n{}", instrument.replacen(import, "", 1));
    let from = "sqrt(2 * a) * w * exp(";
    assert!(src.contains(from), "the bowed string's residual changed");
    let long = format!("sqrt(2 * a) * w * {}exp(", "t(2 * a) * w * ".repeat(19));
    let src = src.replacen(from, &long, 1);
    let (r, dt, peak) =
        fuzz::measured(|| tactus_compiler::compile(&src, &Config::default()).map(|_| ()));
    let d = r.expect_err("`t` is unknown");
    assert!(d.iter().any(|d| d.code == "E0217"), "{d:?}");
    let unknown = d.iter().filter(|d| d.code == "E0217").count();
    assert!(unknown <= 19, "each unknown call reported once: {unknown}");
    assert!(dt < Duration::from_secs(10), "{dt:?}");
    assert!(peak < 1 << 30, "{peak} bytes");
}
