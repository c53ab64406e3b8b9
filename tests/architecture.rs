//! The map in ARCHITECTURE.md, checked: no dependency cycle between the top-level modules
//! of the compiler, emulator, firmware and host crates (a module names another by
//! `crate::NAME`, outside comments and test modules), no source file under a crate's `src/`
//! over 1,300 lines, and the front end without cranelift.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Top-level module → the top-level modules it names.
fn edges(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut stack = vec![src.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            if path.extension().is_none_or(|e| e != "rs") {
                continue;
            }
            let rel = path.strip_prefix(src).unwrap();
            let top = rel
                .components()
                .next()
                .unwrap()
                .as_os_str()
                .to_string_lossy()
                .trim_end_matches(".rs")
                .to_string();
            if top == "lib" || top == "main" {
                continue;
            }
            let text = std::fs::read_to_string(&path).unwrap();
            let code = text.split("#[cfg(test)]").next().unwrap_or("");
            for line in code.lines().filter(|l| !l.trim_start().starts_with("//")) {
                let mut rest = line;
                while let Some(at) = rest.find("crate::") {
                    rest = &rest[at + "crate::".len()..];
                    let name: String = rest
                        .chars()
                        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                        .collect();
                    if !name.is_empty() && name != top {
                        out.entry(top.clone()).or_default().insert(name);
                    }
                }
            }
        }
    }
    out
}

/// A cycle through `from`, if any (depth-first search).
fn cycle(g: &BTreeMap<String, BTreeSet<String>>) -> Option<Vec<String>> {
    fn visit(
        g: &BTreeMap<String, BTreeSet<String>>,
        v: &str,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) -> Option<Vec<String>> {
        if let Some(at) = path.iter().position(|p| p == v) {
            let mut c = path[at..].to_vec();
            c.push(v.to_string());
            return Some(c);
        }
        if done.contains(v) {
            return None;
        }
        path.push(v.to_string());
        for w in g.get(v).into_iter().flatten() {
            if let Some(c) = visit(g, w, path, done) {
                return Some(c);
            }
        }
        path.pop();
        done.insert(v.to_string());
        None
    }
    let mut done = BTreeSet::new();
    g.keys()
        .find_map(|v| visit(g, v, &mut Vec::new(), &mut done))
}

#[test]
fn no_cycle_between_the_modules_of_the_compiler_firmware_and_host() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for krate in ["compiler", "emulator", "firmware", "host"] {
        let g = edges(&root.join(krate).join("src"));
        assert!(g.len() > 1 || krate == "host", "{krate}: {g:?}");
        if let Some(c) = cycle(&g) {
            panic!("{krate}: modules in a cycle: {}", c.join(" → "));
        }
    }
    // The check sees a cycle when there is one.
    let mut g = BTreeMap::new();
    g.insert("a".to_string(), BTreeSet::from(["b".to_string()]));
    g.insert("b".to_string(), BTreeSet::from(["a".to_string()]));
    assert!(cycle(&g).is_some());
}

#[test]
fn the_front_end_builds_without_cranelift() {
    let manifest =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("compiler/Cargo.toml"))
            .unwrap();
    let deps = manifest.split("[dev-dependencies]").next().unwrap();
    assert!(!deps.contains("cranelift"), "{deps}");
    assert!(
        !deps.contains("tactus-jit") && !deps.contains("tactus-emulator"),
        "{deps}"
    );
}

/// The most lines a source file under a crate's `src/` may have: a file longer than this
/// holds more than one job (split it by job, as `emulator/src/io/` is).
const MAX_LINES: usize = 1300;

#[test]
fn no_source_file_is_over_1300_lines() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut stack = vec![root.to_path_buf()];
    let (mut seen, mut long) = (0, Vec::new());
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap_or_default().to_string_lossy();
            if path.is_dir() {
                if name != "target" && !name.starts_with('.') {
                    stack.push(path);
                }
                continue;
            }
            let in_src = path
                .strip_prefix(root)
                .unwrap()
                .components()
                .any(|c| c.as_os_str() == "src");
            if !in_src || path.extension().is_none_or(|e| e != "rs") {
                continue;
            }
            seen += 1;
            let lines = std::fs::read_to_string(&path).unwrap().lines().count();
            if lines > MAX_LINES {
                long.push(format!("{} ({lines} lines)", path.display()));
            }
        }
    }
    assert!(seen > 100, "only {seen} source files found under {}", root.display());
    assert!(long.is_empty(), "over {MAX_LINES} lines: {}", long.join(", "));
}
