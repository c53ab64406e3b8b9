//! Tactus's library (`instruments/lib/`, built into the compiler): every file parses and
//! defines components only; every component is documented (a comment block above it, a
//! comment on each param, input and output: its unit, range or source); and every component,
//! used alone by an instrument that connects each input to the key and reads each output,
//! compiles without a warning, plans its fixed point and runs a key stroke to finite values
//! (the FDTD string only compiles here: bowed_string plans and runs it in every suite).

use tactus_compiler::ast::{Decl, TopItem, TypeAnn};
use tactus_compiler::library;
use tactus_compiler::lower::Config;

fn components() -> Vec<(&'static str, &'static str, tactus_compiler::ast::Body)> {
    let mut v = Vec::new();
    for (file, text) in library::FILES {
        let parsed =
            tactus_compiler::parse::parse(text).unwrap_or_else(|d| panic!("{file}: {}", d.message));
        for item in parsed.items {
            match item {
                TopItem::Component(b) => v.push((*file, *text, b)),
                TopItem::Instrument(b) => {
                    panic!("{file}: instrument `{}` in the library", b.name.node)
                }
                TopItem::Import(i) => assert!(
                    library::file(&i.path.node).is_some(),
                    "{file}: imports `{}`, not a library file",
                    i.path.node
                ),
            }
        }
    }
    v
}

#[test]
fn the_library_lists_its_components() {
    let names: Vec<String> = components()
        .iter()
        .map(|(_, _, b)| b.name.node.clone())
        .collect();
    for expected in [
        "escapement",
        "plectrum",
        "hammer",
        "stick_friction",
        "bilbao_friction",
        "return_spring",
        "key_bed",
        "hunt_crossley",
        "detent",
        "resonator",
        "string",
    ] {
        assert!(
            names.iter().any(|n| n == expected),
            "no `{expected}` in {names:?}"
        );
    }
    assert_eq!(
        library::components().len(),
        names.len(),
        "library::components() disagrees"
    );
    let mut sorted = names.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(
        sorted.len(),
        names.len(),
        "a name twice in the library: {names:?}"
    );
}

/// The text of the source line holding byte `at`.
fn line_of(text: &str, at: usize) -> &str {
    let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let end = text[at..].find('\n').map_or(text.len(), |i| at + i);
    &text[start..end]
}

#[test]
fn every_component_and_its_interface_is_documented() {
    for (file, text, b) in components() {
        let name = &b.name.node;
        // A comment block of at least three lines right above `component NAME`.
        let above: Vec<&str> = text[..b.span.start]
            .lines()
            .rev()
            .take_while(|l| l.trim_start().starts_with("//"))
            .collect();
        assert!(
            above.len() >= 3,
            "{file}: `{name}` has {} comment lines above it",
            above.len()
        );
        for d in &b.decls {
            let (what, n) = match d {
                Decl::Param { name, .. } => ("param", name),
                Decl::Input { name, .. } => ("input", name),
                Decl::Output { name, .. } => ("output", name),
                _ => continue,
            };
            // A comment on its line, or closing the line above it (a comment block over a
            // group of declarations).
            let line = line_of(text, n.span.start);
            let prev = text[..n.span.start]
                .rfind('\n')
                .map(|i| line_of(text, i))
                .unwrap_or("");
            assert!(
                line.contains("//") || prev.trim_start().starts_with("//"),
                "{file}: {what} `{}` of `{name}` has no comment: {line}",
                n.node
            );
        }
    }
}

/// An instrument of one key that uses `component` alone: each input connected to the key
/// (by its unit), each output read.
fn harness(file: &str, b: &tactus_compiler::ast::Body) -> String {
    let mut args = Vec::new();
    let mut outputs = Vec::new();
    for d in &b.decls {
        match d {
            Decl::Input { name, ty } => {
                let unit = match ty.as_ref().map(|t| &t.node) {
                    Some(TypeAnn::Bool) => "bool".to_string(),
                    Some(TypeAnn::Unit(f)) => f
                        .iter()
                        .map(|(n, e)| format!("{}^{e}", n.node))
                        .collect::<Vec<_>>()
                        .join("*"),
                    None => String::new(),
                };
                // Within what every component documents for its inputs (a bow's ±0.4 m/s and
                // 28 mN, as bowed_string bounds them).
                let value = match unit.as_str() {
                    "m^1" => "key",
                    "m^1*s^-1" => "clamp(d(key), -0.4 m/s, 0.4 m/s)",
                    "N^1" => "key * 2 N/m",
                    "bool" => "key < 1 mm",
                    "" => "key / 10 mm",
                    other => panic!(
                        "{file}: `{}`: an input in `{other}`: teach the harness",
                        b.name.node
                    ),
                };
                args.push(format!("{} = {value}", name.node));
            }
            Decl::Output { name, .. } => outputs.push(name.node.clone()),
            _ => {}
        }
    }
    let reads: Vec<String> = outputs
        .iter()
        .map(|o| format!("    output o_{o} = c.{o}\n"))
        .collect();
    format!(
        "import \"{file}\" {{ {name} }}\ninstrument harness {{\n    sensor key: m in [0 mm, 10 mm]\n    use c = {name}({args})\n    force zero = 0 N\n{reads}}}\n",
        name = b.name.node,
        args = args.join(", "),
        reads = reads.concat()
    )
}

#[test]
fn every_component_compiles_plans_and_runs_alone() {
    for (file, _, b) in components() {
        let src = harness(file, &b);
        let l = tactus_compiler::compile(&src, &Config::default()).unwrap_or_else(|d| {
            let linked = tactus_compiler::imports::link(
                "harness",
                tactus_compiler::sources::Origin::Text,
                &src,
                &mut tactus_compiler::imports::NoFiles,
            );
            panic!(
                "{file}: `{}`:\n{src}\n{}",
                b.name.node,
                tactus_compiler::diagnostics::emit_files_to_string(&linked.sources, &d)
            )
        });
        assert!(
            l.warnings.is_empty(),
            "{file}: `{}`: {:?}",
            b.name.node,
            l.warnings
        );
        // The FDTD string (thousands of values) is planned and run in every engine's suite as
        // bowed_string's; here it is only compiled alone.
        if l.program.values.len() > 2_000 {
            continue;
        }
        let fp = tactus_compiler::fixed::FixedProgram::new(&l.program);
        assert!(
            fp.warnings.is_empty(),
            "{file}: `{}`: {:?}",
            b.name.node,
            fp.warnings
        );
        // A key stroke down to 10 mm and back, 0.2 s.
        let mut inst = tactus_compiler::interp::Instance::new(&l.program);
        for i in 0..8820 {
            let x = 0.01 * (1.0 - (i as f64 / 4410.0 - 1.0).abs());
            let out = inst.step(&[x]);
            assert!(
                out.total.is_finite() && out.outputs.iter().all(|o| o.is_finite()),
                "{file}: `{}` at sample {i}: {:?}",
                b.name.node,
                out.outputs
            );
        }
    }
}

/// The rows `docs/library.md` shows for a component: its inputs with their types, its
/// outputs, its params with their defaults as written.
fn signature(text: &str, b: &tactus_compiler::ast::Body) -> Vec<(String, String)> {
    let src = |s: &std::ops::Range<usize>| {
        text[s.clone()]
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")
    };
    let (mut inputs, mut outputs, mut params) = (Vec::new(), Vec::new(), Vec::new());
    for d in &b.decls {
        match d {
            Decl::Input { name, ty } => inputs.push(format!(
                "`{}`: {}",
                name.node,
                ty.as_ref().map_or(String::new(), |t| src(&t.span))
            )),
            Decl::Output { name, .. } => outputs.push(format!("`{}`", name.node)),
            Decl::Param { name, value, .. } => {
                params.push(format!("`{}` = {}", name.node, src(&value.span)))
            }
            _ => {}
        }
    }
    vec![
        ("inputs".into(), inputs.join(", ")),
        ("outputs".into(), outputs.join(", ")),
        ("params".into(), params.join(", ")),
    ]
}

#[test]
fn docs_library_md_shows_every_component_as_it_is() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/library.md");
    let doc = std::fs::read_to_string(&path).unwrap();
    let mut stale = Vec::new();
    for (file, text, b) in components() {
        let heading = format!("### `{}` — `import \"{file}\"`", b.name.node);
        let Some(at) = doc.find(&heading) else {
            stale.push(format!("no section `{heading}`"));
            continue;
        };
        let section = &doc[at..];
        let section = &section[..section[3..].find("\n### ").map_or(section.len(), |i| i + 3)];
        for (what, row) in signature(text, &b) {
            let line = format!("| {what} | {row} |");
            if !section.contains(&line) {
                stale.push(format!("`{}`: expected the row\n{line}", b.name.node));
            }
        }
    }
    assert!(
        stale.is_empty(),
        "docs/library.md is stale:\n{}",
        stale.join("\n")
    );
}
