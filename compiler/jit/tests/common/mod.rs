//! Program loading shared by the JIT equivalence tests.

#![allow(dead_code)] // each test binary uses a subset

use std::path::{Path, PathBuf};
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config;

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

/// The shipped instruments.
pub fn instruments() -> Vec<PathBuf> {
    let files = tactus_files(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../instruments"));
    assert!(files.len() >= 4, "instruments not found: {files:?}");
    files
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
