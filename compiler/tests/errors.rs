//! Every file in `tests/errors/` must fail to compile with a diagnostic that has a span, a
//! message and (where we can give one) a hint; the rendered diagnostics are snapshots
//! (`INSTA_UPDATE=always cargo test` or `cargo insta review` re-blesses them).

use std::collections::BTreeSet;
use std::path::Path;
use tactus_compiler::diagnostics::emit_to_string;
use tactus_compiler::lower::Config;

#[test]
fn every_error_case_gives_its_diagnostic() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/errors");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.retain(|p| p.extension().is_some_and(|e| e == "tactus"));
    files.sort();
    let mut codes = BTreeSet::new();
    for path in &files {
        let name = path.file_stem().unwrap().to_str().unwrap();
        let src = std::fs::read_to_string(path).unwrap();
        let diags = match tactus_compiler::compile(&src, &Config::default()) {
            Ok(_) => panic!("{name}: expected an error, compiled fine"),
            Err(d) => d,
        };
        let errors: Vec<_> = diags.iter().filter(|d| d.is_error()).collect();
        assert!(!errors.is_empty(), "{name}: no error among {diags:?}");
        for d in &errors {
            assert!(!d.message.is_empty(), "{name}: empty message");
            assert!(
                d.primary.0.end <= src.len(),
                "{name}: span outside the file"
            );
            codes.insert(d.code);
        }
        let rendered = emit_to_string(&format!("{name}.tactus"), &src, &diags);
        insta::assert_snapshot!(name, rendered);
    }
    assert!(files.len() >= 25, "only {} error cases", files.len());
    assert!(
        codes.len() >= 25,
        "only {} distinct error codes: {codes:?}",
        codes.len()
    );
}

#[test]
fn param_overrides_are_checked() {
    let src = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments/hammond.tactus"),
    )
    .unwrap();
    let with = |k: &str, v: &str| Config {
        overrides: vec![(k.into(), v.into())],
        ..Config::default()
    };
    // A good override changes the folded value.
    let ok = tactus_compiler::compile(&src, &with("k", "200 N/m")).unwrap();
    let k = ok.program.params.iter().find(|p| p.name == "k").unwrap();
    assert_eq!(k.value, 200.0);
    // Wrong unit, unknown name and non-number all fail with their codes.
    for (name, value, code) in [
        ("k", "2 mm", "E0303"),
        ("kk", "1 N/m", "E0301"),
        ("k", "fast", "E0302"),
    ] {
        let err = tactus_compiler::compile(&src, &with(name, value)).unwrap_err();
        assert!(
            err.iter().any(|d| d.code == code),
            "{name}={value}: {err:?}"
        );
    }
}
