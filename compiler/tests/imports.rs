//! Imports: each directory of `tests/imports/` is a program (`main.tactus` and the files it
//! imports) that must fail with diagnostics whose rendering, over every file, is a snapshot
//! (`INSTA_UPDATE=always` re-blesses them); programs that link compile as if written in one
//! file; hostile imports (long chains and cycles, unreadable files) give a diagnostic within
//! a small stack.

use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};
use tactus_compiler::diagnostics::emit_files_to_string;
use tactus_compiler::imports::{link, LoadError, Loaded, Loader, MAX_FILES};
use tactus_compiler::lower::Config;
use tactus_compiler::sources::Origin;

/// Files in memory, by path with `.` and `..` taken out (the key a real loader would
/// canonicalise to).
#[derive(Default)]
struct Memory {
    files: HashMap<PathBuf, Result<String, LoadError>>,
    reads: usize,
}

fn normal(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

impl Memory {
    fn with(files: &[(&str, &str)]) -> Self {
        let mut m = Memory::default();
        for (p, t) in files {
            m.files.insert(PathBuf::from(p), Ok(t.to_string()));
        }
        m
    }

    /// Every file under `dir`, by its path relative to `dir`.
    fn from_dir(dir: &Path) -> Self {
        let mut m = Memory::default();
        let mut todo = vec![dir.to_path_buf()];
        while let Some(d) = todo.pop() {
            for e in std::fs::read_dir(&d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    todo.push(p);
                } else {
                    let rel = p.strip_prefix(dir).unwrap().to_path_buf();
                    m.files
                        .insert(rel, Ok(std::fs::read_to_string(&p).unwrap()));
                }
            }
        }
        m
    }
}

impl Loader for Memory {
    fn read(&mut self, path: &Path, max_bytes: u64) -> Result<Loaded, LoadError> {
        self.reads += 1;
        let key = normal(path);
        match self.files.get(&key) {
            None => Err(LoadError::NotFound),
            Some(Err(e)) => Err(e.clone()),
            Some(Ok(t)) if t.len() as u64 > max_bytes => Err(LoadError::TooLong { max_bytes }),
            Some(Ok(t)) => Ok(Loaded {
                key,
                text: t.clone(),
            }),
        }
    }
}

/// Links and compiles `main.tactus` of `loader`: the program's rendering of its
/// diagnostics, or its IR.
fn compile(loader: &mut Memory) -> Result<tactus_compiler::lower::Lowered, String> {
    let text = match loader.files.get(Path::new("main.tactus")) {
        Some(Ok(t)) => t.clone(),
        _ => panic!("no main.tactus"),
    };
    let linked = link(
        "main.tactus",
        Origin::File("main.tactus".into()),
        &text,
        loader,
    );
    tactus_compiler::compile_linked(&linked, &Config::default())
        .map_err(|d| emit_files_to_string(&linked.sources, &d))
}

#[test]
fn every_import_error_case_gives_its_diagnostics() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/imports");
    let mut cases: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .collect();
    cases.sort();
    assert!(cases.len() >= 12, "{cases:?}");
    for case in cases {
        let name = case.file_name().unwrap().to_str().unwrap().to_string();
        let rendered = match compile(&mut Memory::from_dir(&case)) {
            Ok(_) => panic!("{name}: expected an error, compiled fine"),
            Err(r) => r,
        };
        assert!(rendered.contains("error["), "{name}: {rendered}");
        insta::assert_snapshot!(format!("import_{name}"), rendered);
    }
}

const SPRING: &str =
    "component spring {\n    param k = 100 N/m\n    input x: m\n    output f = k * x\n}\n";

const USES_SPRING: &str = "instrument main {\n    sensor key: m in [0 mm, 10 mm]\n    use s = spring(x = key, k = 200 N/m)\n    force f = s.f\n}\n";

#[test]
fn an_imported_component_compiles_as_if_written_in_the_file() {
    let mut m = Memory::with(&[
        (
            "main.tactus",
            &format!("import \"lib/springs.tactus\"\n{USES_SPRING}"),
        ),
        ("lib/springs.tactus", SPRING),
    ]);
    let linked = compile(&mut m).unwrap();
    let one_file =
        tactus_compiler::compile(&format!("{SPRING}{USES_SPRING}"), &Config::default()).unwrap();
    assert_eq!(linked.program.to_string(), one_file.program.to_string());
    assert!(linked.warnings.is_empty(), "{:?}", linked.warnings);
    // A listed import is the same program.
    m.files.insert(
        "main.tactus".into(),
        Ok(format!(
            "import \"lib/springs.tactus\" {{ spring }}\n{USES_SPRING}"
        )),
    );
    assert_eq!(
        compile(&mut m).unwrap().program.to_string(),
        one_file.program.to_string()
    );
}

#[test]
fn two_files_may_keep_private_components_of_one_name() {
    // `a.tactus` and `b.tactus` each build on a `spring` of their own; the main file imports
    // only `stiff` and `soft`, and each instance uses its own file's spring.
    let a = "component spring {\n    input x: m\n    output f = 1000 N/m * x\n}\ncomponent stiff {\n    input x: m\n    use s = spring(x = x)\n    output f = s.f\n}\n";
    let b = "component spring {\n    input x: m\n    output f = 10 N/m * x\n}\ncomponent soft {\n    input x: m\n    use s = spring(x = x)\n    output f = s.f\n}\n";
    let main = "import \"a.tactus\" { stiff }\nimport \"b.tactus\" { soft }\ninstrument main {\n    sensor key: m in [0 mm, 10 mm]\n    use h = stiff(x = key)\n    use l = soft(x = key)\n    force f = h.f - l.f\n}\n";
    let mut m = Memory::with(&[("main.tactus", main), ("a.tactus", a), ("b.tactus", b)]);
    let l = compile(&mut m).unwrap();
    let mut inst = tactus_compiler::interp::Instance::new(&l.program);
    let total = inst.step(&[0.01]).total;
    // 1000 N/m · 10 mm − 10 N/m · 10 mm
    assert!((total - 9.9).abs() < 1e-9, "{total}");
}

#[test]
fn a_file_imported_by_two_files_is_read_once() {
    let a = "import \"springs.tactus\"\ncomponent stiff {\n    input x: m\n    use s = spring(x = x)\n    output f = s.f\n}\n";
    let main = format!("import \"./springs.tactus\"\nimport \"a.tactus\"\n{USES_SPRING}");
    let mut m = Memory::with(&[
        ("main.tactus", &main),
        ("a.tactus", a),
        ("springs.tactus", SPRING),
    ]);
    let text = main.clone();
    let linked = link(
        "main.tactus",
        Origin::File("main.tactus".into()),
        &text,
        &mut m,
    );
    assert!(!linked.has_errors(), "{:?}", linked.diagnostics);
    assert_eq!(linked.sources.files().len(), 3);
}

/// A chain main → f1 → … → fN, each file's component using the next one's: the whole
/// program on a thread with a 256 KB stack.
fn chain(n: usize, cycle: bool) -> (Vec<&'static str>, String) {
    let mut m = Memory::default();
    let main = "import \"f1.tactus\"\ninstrument main {\n    sensor key: m in [0 mm, 10 mm]\n    use c = c1(x = key)\n    force f = c.f\n}\n";
    m.files.insert("main.tactus".into(), Ok(main.into()));
    for i in 1..=n {
        let text = if i < n {
            format!("import \"f{}.tactus\"\ncomponent c{i} {{\n    input x: m\n    output f = 1 N/m * x\n}}\n", i + 1)
        } else if cycle {
            format!("import \"f1.tactus\"\ncomponent c{i} {{\n    input x: m\n    output f = 1 N/m * x\n}}\n")
        } else {
            format!("component c{i} {{\n    input x: m\n    output f = 1 N/m * x\n}}\n")
        };
        m.files.insert(format!("f{i}.tactus").into(), Ok(text));
    }
    std::thread::Builder::new()
        .stack_size(256 << 10)
        .spawn(move || {
            let text = main.to_string();
            let linked = link(
                "main.tactus",
                Origin::File("main.tactus".into()),
                &text,
                &mut m,
            );
            let codes: Vec<&'static str> =
                match tactus_compiler::compile_linked(&linked, &Config::default()) {
                    Ok(_) => vec![],
                    Err(d) => d.iter().map(|d| d.code).collect(),
                };
            let rendered = tactus_compiler::diagnostics::emit_files_to_string(
                &linked.sources,
                &linked.diagnostics,
            );
            (codes, rendered)
        })
        .unwrap()
        .join()
        .unwrap()
}

#[test]
fn a_chain_of_a_thousand_files_links_on_a_small_stack() {
    let (codes, _) = chain(1000, false);
    assert!(codes.is_empty(), "{codes:?}");
}

#[test]
fn a_cycle_of_a_thousand_files_is_one_short_diagnostic() {
    let (codes, rendered) = chain(1000, true);
    assert_eq!(codes, ["E0142"]);
    assert!(rendered.contains("(1000 files in all)"), "{rendered}");
    assert!(rendered.lines().count() < 60, "{rendered}");
}

#[test]
fn more_files_than_the_limit_is_a_diagnostic() {
    let (codes, rendered) = chain(MAX_FILES + 10, false);
    assert_eq!(codes, ["E0146"], "{rendered}");
    assert!(
        rendered.contains(&format!("more than {MAX_FILES} files")),
        "{rendered}"
    );
}

#[test]
fn unreadable_files_are_diagnostics_at_the_import() {
    let main = "import \"x.tactus\"\ninstrument main {\n    sensor key: m in [0 mm, 10 mm]\n    force f = 1 N\n}\n";
    for (err, says) in [
        (LoadError::Directory, "a directory, not a file"),
        (
            LoadError::TooLong { max_bytes: 1 << 24 },
            "longer than the 16777216 bytes",
        ),
        (LoadError::NotUtf8, "not UTF-8 text"),
        (
            LoadError::Other("Permission denied (os error 13)".into()),
            "Permission denied",
        ),
    ] {
        let mut m = Memory::with(&[("main.tactus", main)]);
        m.files.insert("x.tactus".into(), Err(err.clone()));
        let r = compile(&mut m).unwrap_err();
        assert!(
            r.contains("error[E0141]: cannot read `x.tactus`") && r.contains(says),
            "{err:?}: {r}"
        );
        assert!(r.contains("main.tactus:1:8"), "{r}");
    }
}

#[test]
fn the_imports_read_no_more_than_their_budget() {
    // Two files of 10 MB: the second is refused, however the loader would read it.
    let big = format!("// {}\n", "x".repeat(10 << 20));
    let main = "import \"a.tactus\"\nimport \"b.tactus\"\ninstrument main {\n    sensor key: m in [0 mm, 10 mm]\n    force f = 1 N\n}\n";
    let mut m = Memory::with(&[
        ("main.tactus", main),
        ("a.tactus", &big),
        ("b.tactus", &big),
    ]);
    let r = compile(&mut m).unwrap_err();
    assert!(
        r.contains("E0141") && r.contains("read more than 16777216 bytes in all"),
        "{r}"
    );
}

#[test]
fn a_text_without_a_file_imports_from_the_library_only() {
    // The loader is never asked: `compile` of a text looks in the library.
    let src = "import \"springs.tactus\"\ninstrument main {\n    sensor key: m in [0 mm, 10 mm]\n    force f = 1 N\n}\n";
    let d = tactus_compiler::compile(src, &Config::default()).unwrap_err();
    assert_eq!(d[0].code, "E0140");
    assert!(d[0].primary.1.contains("Tactus's library"), "{:?}", d[0]);
    assert!(!d[0].primary.1.contains("springs.tactus`"), "{:?}", d[0]);
}
