//! The shipped instruments as every crate's tests see them: one definition, included by
//! path (`#[path = ".../compiler/tests/support/shipped.rs"] mod shipped;`) into the
//! compiler's, the JIT's and the firmware's tests. No library can serve it: the catalogue
//! (`tactus_host::catalogue`) sits above the compiler, and the tests also need the
//! experimental instruments, which ship in no catalogue.

#![allow(dead_code)] // each test binary uses a part

use std::path::{Path, PathBuf};

/// The workspace's `instruments/` directory (found upward from the including crate).
pub fn instruments_dir() -> PathBuf {
    let mut dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    loop {
        let candidate = dir.join("instruments");
        if candidate.join("grand_piano.tactus").is_file() {
            return candidate;
        }
        dir = dir
            .parent()
            .unwrap_or_else(|| panic!("no instruments/ above {}", env!("CARGO_MANIFEST_DIR")));
    }
}

/// The shipped instruments' files, `(name, path)`, sorted by name: every
/// `instruments/*.tactus` (named by its stem) and, with `experimental`, every
/// `instruments/experimental/*.tactus` (named `experimental/STEM`; none while that directory
/// does not exist, as when the last experimental instrument shipped) and every user
/// instrument of `instruments/examples/` (named `examples/STEM`: the tutorial's clavichord,
/// the tour of the library; they import from Tactus's library only, so
/// `tactus_compiler::compile` of their text compiles them).
pub fn instrument_files(experimental: bool) -> Vec<(String, PathBuf)> {
    let root = instruments_dir();
    let mut dirs = vec![(root.clone(), "")];
    if experimental {
        for sub in ["experimental", "examples"] {
            if root.join(sub).is_dir() {
                dirs.push((
                    root.join(sub),
                    if sub == "examples" {
                        "examples/"
                    } else {
                        "experimental/"
                    },
                ));
            }
        }
    }
    let mut v = Vec::new();
    for (dir, prefix) in dirs {
        let entries = std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        for p in entries.map(|e| e.expect("directory entry").path()) {
            if p.extension().is_some_and(|e| e == "tactus") {
                let stem = p.file_stem().unwrap().to_string_lossy().into_owned();
                v.push((format!("{prefix}{stem}"), p));
            }
        }
    }
    v.sort();
    assert!(
        v.len() >= 4,
        "instruments not found in {}: {v:?}",
        root.display()
    );
    v
}

/// [`instrument_files`] with their sources, `(name, source)`.
pub fn instrument_sources(experimental: bool) -> Vec<(String, String)> {
    instrument_files(experimental)
        .into_iter()
        .map(|(n, p)| {
            let text =
                std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            (n, text)
        })
        .collect()
}
