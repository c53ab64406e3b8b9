//! Every instrument in `instruments/` compiles without warnings, and its IR is a snapshot;
//! a mutation test feeds 10,000+ damaged versions of them to the front end, which must
//! answer with diagnostics, never a panic.

use std::path::{Path, PathBuf};
use tactus_compiler::lower::Config;
use tactus_runtime::rng::XorShift64;

fn instrument_files() -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments");
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    v.retain(|p| p.extension().is_some_and(|e| e == "tactus"));
    v.sort();
    v
}

/// Lines of an instrument's IR kept in its snapshot.
const SNAPSHOT_LINES: usize = 3_000;

#[test]
fn ir_of_every_instrument() {
    let files = instrument_files();
    assert!(files.len() >= 4, "{files:?}");
    for path in files {
        let name = path.file_stem().unwrap().to_str().unwrap().to_string();
        let src = std::fs::read_to_string(&path).unwrap();
        let lowered = tactus_compiler::compile(&src, &Config::default()).unwrap_or_else(|d| {
            panic!(
                "{name}:\n{}",
                tactus_compiler::diagnostics::emit_to_string(&name, &src, &d)
            )
        });
        assert!(
            lowered.warnings.is_empty(),
            "{name}: {:?}",
            lowered.warnings
        );
        // The IR of an FDTD string runs to tens of thousands of lines: its snapshot keeps the
        // declarations and the first part of the body, and counts the rest.
        let text = lowered.program.to_string();
        let lines: Vec<&str> = text.lines().collect();
        let shown = if lines.len() > SNAPSHOT_LINES {
            format!(
                "{}\n… {} more lines ({} values)\n",
                lines[..SNAPSHOT_LINES].join("\n"),
                lines.len() - SNAPSHOT_LINES,
                lowered.program.values.len()
            )
        } else {
            text
        };
        insta::assert_snapshot!(format!("ir_{name}"), shown);
    }
}

const SNIPPETS: &[&str] = &[
    "{",
    "}",
    "(",
    ")",
    "[",
    "]",
    ",",
    "=",
    "==",
    "'",
    ".",
    "^",
    "-",
    "*",
    "/",
    " mm",
    " N*s/m",
    "1e",
    "9999999999999999999999",
    "0",
    " m^-3",
    " if ",
    " else ",
    " on ",
    " while ",
    " emit x()",
    " use ",
    " state ",
    " mode ",
    "//",
    "\n",
    "é",
    "\u{0}",
    " d(",
    " d2(",
    " and ",
    " not ",
    ": bool",
    "1/s",
];

fn mutate(src: &str, rng: &mut XorShift64) -> String {
    let mut s: Vec<char> = src.chars().collect();
    for _ in 0..1 + rng.below(3) {
        if s.is_empty() {
            break;
        }
        let at = rng.below(s.len());
        match rng.below(5) {
            0 => {
                let len = 1 + rng.below(12);
                s.drain(at..(at + len).min(s.len()));
            }
            1 => {
                let snippet = SNIPPETS[rng.below(SNIPPETS.len())];
                s.splice(at..at, snippet.chars());
            }
            2 => {
                let from = rng.below(s.len());
                let len = 1 + rng.below(30);
                let piece: Vec<char> = s[from..(from + len).min(s.len())].to_vec();
                s.splice(at..at, piece);
            }
            3 => {
                let b = rng.below(s.len());
                s.swap(at, b);
            }
            _ => s.truncate(at),
        }
    }
    s.into_iter().collect()
}

#[test]
fn mutated_instruments_never_panic() {
    let sources: Vec<String> = instrument_files()
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect();
    // Instruments of thousands of values (arrays of nodes) cost a hundred times a piano key
    // to compile: they get one turn in 20.
    let large: Vec<bool> = sources
        .iter()
        .map(|s| {
            tactus_compiler::compile(s, &Config::default())
                .is_ok_and(|l| l.program.values.len() > 2_000)
        })
        .collect();
    let mut rng = XorShift64::new(0x007A_C705);
    let (mut ok, mut failed) = (0usize, 0usize);
    for i in 0..10_400 {
        let k = i % sources.len();
        if large[k] && !(i / sources.len()).is_multiple_of(20) {
            continue;
        }
        let m = mutate(&sources[k], &mut rng);
        match tactus_compiler::compile(&m, &Config::default()) {
            Ok(_) => ok += 1,
            Err(diags) => {
                assert!(diags.iter().any(|d| d.is_error()));
                for d in &diags {
                    assert!(
                        d.primary.0.start <= d.primary.0.end && d.primary.0.end <= m.len(),
                        "span out of file: {d:?}"
                    );
                }
                // Rendering must not panic either.
                let _ = tactus_compiler::diagnostics::emit_to_string("m.tactus", &m, &diags);
                failed += 1;
            }
        }
    }
    // Mutations that happen to be harmless are fine, but most must be caught.
    assert!(
        failed > ok,
        "only {failed} of {} mutants rejected",
        ok + failed
    );
}
