//! The map in ARCHITECTURE.md, checked: no import circle between the modules of any crate
//! (siblings under one parent: a module names another by `crate::…`, `super::…` or
//! `self::…`, outside comments and test modules; a file's references count for every
//! enclosing module), no dependency a crate does not use, no source file under a crate's
//! `src/` over 1,300 lines, the front end without cranelift, and the facts said once (one
//! plan of a keyboard's boards, one board-file reader, one limiter configuration).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// A crate of the workspace, by directory (`""`: the root package, `tactus`).
struct Crate {
    /// Its directory under the workspace root.
    dir: &'static str,
    /// Whether its modules are known to import in a circle yet: the test then says so
    /// instead of failing, and fails once the circle is gone (no crate is marked now; the
    /// emulator's were broken by its split into a machine and an accelerator).
    known_circles: bool,
}

/// Every crate of the workspace: the data the checks below run over.
const CRATES: &[Crate] = &[
    Crate {
        dir: "isa",
        known_circles: false,
    },
    Crate {
        dir: "chip",
        known_circles: false,
    },
    Crate {
        dir: "runtime",
        known_circles: false,
    },
    Crate {
        dir: "compiler",
        known_circles: false,
    },
    Crate {
        dir: "compiler/jit",
        known_circles: false,
    },
    Crate {
        dir: "emulator",
        known_circles: false,
    },
    Crate {
        dir: "firmware",
        known_circles: false,
    },
    Crate {
        dir: "host",
        known_circles: false,
    },
    Crate {
        dir: "lsp",
        known_circles: false,
    },
    Crate {
        dir: "",
        known_circles: false,
    },
];

/// [`CRATES`] is every crate of the workspace: the root package and each of the root
/// manifest's `members`.
#[test]
fn the_checks_cover_every_crate_of_the_workspace() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let manifest = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let members = manifest
        .lines()
        .find_map(|l| l.trim().strip_prefix("members = ["))
        .expect("the root manifest lists its members on one line");
    let mut want: BTreeSet<&str> = members
        .trim_end_matches(']')
        .split(',')
        .map(|m| m.trim().trim_matches('"'))
        .filter(|m| !m.is_empty())
        .collect();
    want.insert("");
    let have: BTreeSet<&str> = CRATES.iter().map(|c| c.dir).collect();
    assert_eq!(
        have, want,
        "tests/architecture.rs's CRATES against the workspace"
    );
}

/// A module's path from its file's path under `src/` (`a/b.rs` and `a/b/mod.rs`: `a::b`;
/// `lib.rs`, `main.rs`: the crate root, empty).
fn module_path(rel: &Path) -> Vec<String> {
    let mut parts: Vec<String> = (rel.components())
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    let last = parts.pop().unwrap_or_default();
    let stem = last.trim_end_matches(".rs");
    if !(parts.is_empty() && (stem == "lib" || stem == "main")) && stem != "mod" {
        parts.push(stem.to_string());
    }
    parts
}

/// The paths a use tree names from `at` in `chars` (`a::b`, `a::{b, c::d}`, `a::*`), each
/// appended to `prefix`.
fn use_tree(chars: &[char], at: &mut usize, prefix: Vec<String>, out: &mut Vec<Vec<String>>) {
    let is_ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    let skip = |at: &mut usize| {
        while chars.get(*at).is_some_and(|c| c.is_whitespace()) {
            *at += 1;
        }
    };
    skip(at);
    match chars.get(*at) {
        Some('{') => {
            *at += 1;
            loop {
                skip(at);
                match chars.get(*at) {
                    None => return,
                    Some('}') => {
                        *at += 1;
                        return;
                    }
                    Some(',') => *at += 1,
                    Some(_) => {
                        let before = *at;
                        use_tree(chars, at, prefix.clone(), out);
                        if *at == before {
                            *at += 1;
                        }
                    }
                }
            }
        }
        Some('*') => {
            *at += 1;
            out.push(prefix);
        }
        _ => {
            let start = *at;
            while chars.get(*at).copied().is_some_and(is_ident) {
                *at += 1;
            }
            let name: String = chars[start..*at].iter().collect();
            let mut path = prefix;
            if !name.is_empty() && name != "self" {
                path.push(name);
            }
            let mut look = *at;
            skip(&mut look);
            if chars.get(look) == Some(&':') && chars.get(look + 1) == Some(&':') {
                *at = look + 2;
                use_tree(chars, at, path, out);
            } else {
                out.push(path);
            }
        }
    }
}

/// The module paths `code` (of the module at `here`) names through `crate::`, `super::`
/// and `self::`, as written (not yet cut to the modules that exist).
fn named_paths(code: &str, here: &[String]) -> Vec<Vec<String>> {
    let chars: Vec<char> = code.chars().collect();
    let is_ident = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '$';
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        if i > 0 && is_ident(chars[i - 1]) || !chars[i].is_ascii_alphabetic() {
            i += 1;
            continue;
        }
        let rest: String = chars[i..(i + 7).min(chars.len())].iter().collect();
        let (mut base, mut at) = if rest.starts_with("crate::") {
            (Vec::new(), i + 7)
        } else if rest.starts_with("self::") {
            (here.to_vec(), i + 6)
        } else if rest.starts_with("super::") {
            // A file's `super` is its parent module (a `mod.rs` file is its directory's
            // module, so the same rule holds).
            let mut base = here.to_vec();
            let mut at = i;
            while chars[at..].iter().take(7).collect::<String>() == "super::" {
                base.pop();
                at += 7;
            }
            (base, at)
        } else {
            i += 1;
            continue;
        };
        let mut paths = Vec::new();
        use_tree(&chars, &mut at, std::mem::take(&mut base), &mut paths);
        out.extend(paths);
        i = at.max(i + 1);
    }
    out
}

/// Sibling module → the sibling modules it names (its files' references, and those of the
/// modules inside it), for every parent in the crate whose sources are `src`. Nodes are
/// module paths (`board::run`); an edge joins two children of one parent.
fn edges(src: &Path) -> BTreeMap<String, BTreeSet<String>> {
    let files: Vec<(Vec<String>, std::path::PathBuf)> = rust_files(src)
        .into_iter()
        .map(|p| (module_path(p.strip_prefix(src).unwrap()), p))
        .collect();
    let modules: BTreeSet<Vec<String>> = files.iter().map(|f| f.0.clone()).collect();
    let mut out: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (here, path) in &files {
        let text = std::fs::read_to_string(path).unwrap();
        let code: String = (text.split("#[cfg(test)]").next().unwrap_or(""))
            .lines()
            .map(|l| l.split("//").next().unwrap_or(""))
            .collect::<Vec<_>>()
            .join("\n");
        for named in named_paths(&code, here) {
            // The module it names: the longest prefix that is one.
            let target = (0..=named.len())
                .rev()
                .map(|n| named[..n].to_vec())
                .find(|p| modules.contains(p))
                .unwrap_or_default();
            let common = here.iter().zip(&target).take_while(|(a, b)| a == b).count();
            if common < here.len() && common < target.len() {
                out.entry(here[..=common].join("::"))
                    .or_default()
                    .insert(target[..=common].join("::"));
            }
        }
    }
    out
}

/// The modules of `g` that lie on a circle, grouped by circle (strongly connected
/// components of more than one module), each sorted.
fn circles(g: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    let reach = |from: &str| {
        let mut seen = BTreeSet::new();
        let mut stack = vec![from.to_string()];
        while let Some(v) = stack.pop() {
            for w in g.get(&v).into_iter().flatten() {
                if seen.insert(w.clone()) {
                    stack.push(w.clone());
                }
            }
        }
        seen
    };
    let reached: BTreeMap<&String, BTreeSet<String>> = g.keys().map(|v| (v, reach(v))).collect();
    let mut out: Vec<Vec<String>> = Vec::new();
    for (v, r) in &reached {
        if !r.contains(*v) || out.iter().any(|c| c.contains(v)) {
            continue;
        }
        let circle: Vec<String> = (r.iter())
            .filter(|w| reached.get(w).is_some_and(|rw| rw.contains(*v)))
            .cloned()
            .collect();
        out.push(circle);
    }
    out
}

/// No import circle between the modules of any crate ([`CRATES`]): the compiler's front
/// end → IR → backends, the firmware's image below its boards, the host's runs over its
/// keyboard, each a graph without cycles. A crate marked `known_circles` prints its circle
/// and fails once it has none (so that its mark is taken off).
#[test]
fn no_import_circle_between_the_modules_of_any_crate() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut failed = Vec::new();
    for c in CRATES {
        let g = edges(&root.join(c.dir).join("src"));
        let name = if c.dir.is_empty() {
            "tactus (src/)"
        } else {
            c.dir
        };
        let found: Vec<String> = circles(&g).iter().map(|c| c.join(", ")).collect();
        match (found.is_empty(), c.known_circles) {
            (false, false) => failed.push(format!("{name}: modules in a circle: {found:?}")),
            (false, true) => eprintln!("{name}: known circles (to be split): {found:?}"),
            (true, true) => failed.push(format!(
                "{name}: no circle left: take off its `known_circles` mark"
            )),
            (true, false) => {}
        }
    }
    assert!(failed.is_empty(), "{failed:#?}");
    // The check sees a circle when there is one, and reads the ways Rust names modules.
    let mut g = BTreeMap::new();
    g.insert("a".to_string(), BTreeSet::from(["b".to_string()]));
    g.insert("b".to_string(), BTreeSet::from(["a".to_string()]));
    assert_eq!(circles(&g), [["a", "b"]]);
    let here = ["board".to_string(), "run".to_string()];
    let named = named_paths(
        "use crate::{memo::Memo, io::{self, Io}};\nlet x = super::window::f(self::inner::g());\nuse super::super::bus::*;",
        &here,
    );
    let show: Vec<String> = named.iter().map(|p| p.join("::")).collect();
    assert_eq!(
        show,
        [
            "memo::Memo",
            "io",
            "io::Io",
            "board::window::f",
            "board::run::inner::g",
            "bus"
        ]
    );
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
        for path in rust_files(&root.join(krate).join("src")) {
            let text = std::fs::read_to_string(&path).unwrap();
            let code = text.split("#[cfg(test)]").next().unwrap_or("");
            let name = path.strip_prefix(root).unwrap().display().to_string();
            for line in code.lines().filter(|l| !l.trim_start().starts_with("//")) {
                out.push((name.clone(), line.to_string()));
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
    let all: Vec<&str> = CRATES.iter().map(|c| c.dir).collect();
    let lines = production_lines(&all);
    let readers: Vec<&str> = (lines.iter())
        .filter(|(_, l)| l.contains("pub fn read_board"))
        .map(|(f, _)| f.as_str())
        .collect();
    assert_eq!(readers, ["firmware/src/boards/mod.rs"]);
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

/// The Rust files under `dir` (recursively), or `dir` itself when it is a file.
fn rust_files(dir: &Path) -> Vec<std::path::PathBuf> {
    if dir.is_file() {
        return vec![dir.to_path_buf()];
    }
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for entry in entries {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    out
}

/// Whether `text` names the crate `ident` as Rust code does: `ident::…`, `ident!`, or
/// `use ident`.
fn names_crate(text: &str, ident: &str) -> bool {
    let is_ident = |c: char| c.is_ascii_alphanumeric() || c == '_';
    text.match_indices(ident).any(|(i, _)| {
        let before = text[..i].chars().next_back();
        let rest = &text[i + ident.len()..];
        if before.is_some_and(|c| is_ident(c) || c == ':' || c == '$')
            || rest.chars().next().is_some_and(is_ident)
        {
            return false;
        }
        let rest = rest.trim_start();
        rest.starts_with("::") || rest.starts_with('!') || text[..i].trim_end().ends_with("use")
    })
}

/// The dependencies a manifest's `[section]` declares.
fn declared(manifest: &str, section: &str) -> Vec<String> {
    let header = format!("[{section}]");
    let Some(at) = manifest.find(&format!("\n{header}\n")) else {
        return Vec::new();
    };
    manifest[at + header.len() + 2..]
        .lines()
        .take_while(|l| !l.starts_with('['))
        .filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
        .map(|l| l.split(['.', '=', ' ']).next().unwrap().trim().to_string())
        .collect()
}

/// Every crate uses every dependency it declares: a `[dependencies]` entry in its `src/`,
/// a `[dev-dependencies]` entry in its tests, benches, examples or `src/`, a
/// `[build-dependencies]` entry in `build.rs` (`cargo machete`'s rule, by reading).
#[test]
fn no_crate_declares_a_dependency_it_does_not_use() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut unused = Vec::new();
    for krate in CRATES.iter().map(|c| c.dir) {
        let dir = root.join(krate);
        let manifest = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
        for (section, places) in [
            ("dependencies", &["src"][..]),
            (
                "dev-dependencies",
                &["src", "tests", "benches", "examples"][..],
            ),
            ("build-dependencies", &["build.rs"][..]),
        ] {
            let texts: Vec<String> = (places.iter())
                .flat_map(|p| rust_files(&dir.join(p)))
                .map(|p| std::fs::read_to_string(p).unwrap())
                .collect();
            for dep in declared(&manifest, section) {
                let ident = dep.replace('-', "_");
                if !texts.iter().any(|t| names_crate(t, &ident)) {
                    unused.push(format!("{}: [{section}] {dep}", dir.display()));
                }
            }
        }
    }
    assert!(unused.is_empty(), "declared and not used: {unused:#?}");
    // The check sees a use when there is one, and none in a comment's prose.
    assert!(names_crate("use serde::Serialize;", "serde"));
    assert!(names_crate("x = toml::from_str(t)", "toml"));
    assert!(!names_crate("a .toml file, tactus_toml::x", "toml"));
}

/// BENCHMARKS.md is a map: the current figure of each measure with its command, no line
/// over 300 characters, no commit hashes (history is in git).
#[test]
fn benchmarks_is_a_map() {
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("BENCHMARKS.md"))
        .unwrap();
    for (n, line) in text.lines().enumerate() {
        assert!(
            line.chars().count() <= 300,
            "BENCHMARKS.md:{}: {} characters",
            n + 1,
            line.chars().count()
        );
        let hashes: Vec<&str> = line
            .split(|c: char| !c.is_ascii_alphanumeric())
            .filter(|w| {
                (7..=40).contains(&w.len())
                    && w.chars()
                        .all(|c| c.is_ascii_hexdigit() && !c.is_ascii_uppercase())
                    && w.chars().any(|c| c.is_ascii_digit())
                    && w.chars().any(|c| c.is_ascii_alphabetic())
            })
            .collect();
        assert!(hashes.is_empty(), "BENCHMARKS.md:{}: {hashes:?}", n + 1);
    }
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
    assert!(
        seen > 100,
        "only {seen} source files found under {}",
        root.display()
    );
    assert!(
        long.is_empty(),
        "over {MAX_LINES} lines: {}",
        long.join(", ")
    );
}
