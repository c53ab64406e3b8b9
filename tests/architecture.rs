//! The map in ARCHITECTURE.md, checked: no dependency cycle between the top-level modules
//! of the compiler, firmware and host crates (a module names another by `crate::NAME`,
//! outside comments and test modules), and the front end without cranelift.

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
    for krate in ["compiler", "firmware", "host"] {
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

/// Production code (`src/` of the crates listed by directory, `""` the root crate, outside
/// comments and test modules): each file's path and its lines of code.
fn production_lines(crates: &[&str]) -> Vec<(String, String)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = Vec::new();
    for krate in crates {
        let mut stack = vec![root.join(krate).join("src")];
        while let Some(dir) = stack.pop() {
            for entry in std::fs::read_dir(&dir).unwrap() {
                let path = entry.unwrap().path();
                if path.is_dir() {
                    stack.push(path);
                } else if path.extension().is_some_and(|e| e == "rs") {
                    let text = std::fs::read_to_string(&path).unwrap();
                    let code = text.split("#[cfg(test)]").next().unwrap_or("");
                    let name = path.strip_prefix(root).unwrap().display().to_string();
                    for line in code.lines().filter(|l| !l.trim_start().starts_with("//")) {
                        out.push((name.clone(), line.to_string()));
                    }
                }
            }
        }
    }
    out
}

/// A keyboard's boards are planned once (`host::keyboard::Keyboard::plan`) and read by
/// `build`, `budget` and `play`.
#[test]
fn boards_are_planned_in_one_place() {
    let plans: Vec<String> = production_lines(&["firmware", "host", ""])
        .into_iter()
        .filter(|(_, l)| l.contains("boards::plan("))
        .map(|(f, l)| format!("{f}: {}", l.trim()))
        .collect();
    assert_eq!(plans.len(), 1, "{plans:#?}");
    assert!(plans[0].starts_with("host/src/keyboard.rs"), "{plans:?}");
}

/// A board file has one reader (`firmware::boards::read_board`: the chip's rules and a
/// converter board's drivers checked where the file is read), and a keyboard's limiter one
/// configuration (`LimiterConfig::for_board`).
#[test]
fn one_board_reader_and_one_limiter_configuration() {
    let all = [
        "isa",
        "runtime",
        "compiler",
        "compiler/jit",
        "emulator",
        "firmware",
        "host",
        "lsp",
        "",
    ];
    let lines = production_lines(&all);
    let readers: Vec<&str> = (lines.iter())
        .filter(|(_, l)| l.contains("pub fn read_board"))
        .map(|(f, _)| f.as_str())
        .collect();
    assert_eq!(readers, ["firmware/src/boards.rs"]);
    // A limiter made from its fields: its definition, and the image's own copy at the
    // board's whole-hertz rate.
    let made: Vec<&str> = (lines.iter())
        .filter(|(_, l)| {
            l.contains("LimiterConfig {")
                && !["struct ", "impl ", "fn "].iter().any(|w| l.contains(w))
        })
        .map(|(f, _)| f.as_str())
        .collect();
    assert_eq!(
        made,
        [
            "runtime/src/limiter.rs",
            "runtime/src/limiter.rs",
            "firmware/src/image/mod.rs"
        ],
        "{made:?}"
    );
}
