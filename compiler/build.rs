//! Generates the parser (lalrpop) and fingerprints the sources the format planner's
//! simulated search depends on (`src/fixed/plan_cache.rs` keys its on-disk cache with it).

use sha3::{Digest, Sha3_256};
use std::path::Path;

/// The runtime's files the compiler's planner reads, directly or through each other
/// (`lib.rs` for the default sample rate): the planner's cache key covers these.
const RUNTIME_MODULES: &[&str] = &[
    "lib.rs",
    "differentiator.rs",
    "fixed",
    "rng.rs",
    "stimulus.rs",
    "trace.rs",
];

fn main() {
    lalrpop::Configuration::new()
        .use_cargo_dir_conventions()
        .process()
        .expect("lalrpop grammar failed to compile");
    // Every source of this crate and the runtime modules it uses (the fixed-point rules,
    // the differentiators, the stimuli; `RUNTIME_MODULES`): a change to any of them may
    // change what the search chooses, so it changes the key. The Thumb backend is the one
    // exception: it reads the plan and nothing in the search reads it (`src/fixed` never
    // names `crate::thumb`), so a code-generator change keeps the cached plans. So do the
    // runtime's host-side modules (MIDI, layouts, the player, the converters): the test
    // `planner_key_covers_every_runtime_module_the_compiler_uses` keeps the list complete.
    let mut files = Vec::new();
    println!("cargo:rerun-if-changed=src");
    collect(Path::new("src"), &mut files);
    files.retain(|f| !f.starts_with("src/thumb"));
    for m in RUNTIME_MODULES {
        let path = Path::new("../runtime/src").join(m);
        println!("cargo:rerun-if-changed={}", path.display());
        match path.is_dir() {
            true => collect(&path, &mut files),
            false => files.push(path),
        }
    }
    files.sort();
    let mut h = Sha3_256::new();
    for f in &files {
        h.update(f.to_string_lossy().as_bytes());
        h.update(std::fs::read(f).unwrap_or_default());
    }
    let hex: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    println!("cargo:rustc-env=TACTUS_PLANNER_SOURCE_SHA3={hex}");
    println!(
        "cargo:rustc-env=TACTUS_PLANNER_RUNTIME_MODULES={}",
        RUNTIME_MODULES.join(",")
    );
}

fn collect(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            collect(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs" || x == "lalrpop") {
            out.push(p);
        }
    }
}
