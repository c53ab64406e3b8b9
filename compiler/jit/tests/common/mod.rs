//! Program loading shared by the JIT equivalence tests.

#![allow(dead_code)] // each test binary uses a subset

use std::path::{Path, PathBuf};
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config;

#[path = "../../../tests/support/shipped.rs"]
mod shipped;

/// The `.tactus` files of a folder, sorted.
pub fn tactus_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "tactus"))
        .collect();
    files.sort();
    files
}

/// Programs with more IR values than this are left out of the JIT equivalence tests (none of
/// the shipped ones: `bowed_string` has 19,000). The fixed-point JIT once took 46 s to
/// compile `bowed_string` in a release build — the format planner's precision budget, one
/// error analysis per product, not Cranelift — and the largest programs were left out; with
/// products tried in groups it compiles in seconds and every instrument is compared.
pub const LARGE_PROGRAM_VALUES: usize = 50_000;

/// The shipped instruments and the experimental ones (`instruments/experimental/`: every
/// engine must agree on those too, as the firmware tests check them on Thumb and C), without
/// those over [`LARGE_PROGRAM_VALUES`] (each one left out is printed).
pub fn instruments() -> Vec<PathBuf> {
    shipped::instrument_files(true)
        .into_iter()
        .map(|(_, p)| p)
        .filter(|p| {
            let n = load_program(p).values.len();
            if n > LARGE_PROGRAM_VALUES {
                println!("{}: left out ({n} IR values)", p.display());
            }
            n <= LARGE_PROGRAM_VALUES
        })
        .collect()
}

/// The JIT's own test programs (`tests/data`).
pub fn test_programs() -> Vec<PathBuf> {
    tactus_files(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data"))
}

/// Compiles a source file; a compile error fails the test with the diagnostics.
pub fn load_program(path: &Path) -> Program {
    let src = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    match tactus_compiler::compile(&src, &Config::default()) {
        Ok(l) => l.program,
        Err(d) => panic!("{}: {d:?}", path.display()),
    }
}
