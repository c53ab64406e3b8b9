//! Fuzzing the plan round trip (`tactus budget --write-plan`): a layout, as read from a
//! mutated layout file or generated with arbitrary names, params, grades and boards, is
//! written by `keyboard::layout_text` with a header of arbitrary text, and what is written
//! reads back as the same layout — or `layout_text` says it cannot, and nothing is written.
//! Never a panic, more than a bounded time or heap. `TACTUS_FUZZ_CASES=100000` for a long
//! run.

#[path = "../../tests/common/fuzz.rs"]
mod fuzz;

use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use std::cell::Cell;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;
use tactus_runtime::keyboard::{layout_text, parse_layout, BoardKeys, Grade, KeyRange, Layout};

fn seeds() -> Vec<Vec<u8>> {
    let dir = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../instruments/layouts"
    ));
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    let mut s: Vec<Vec<u8>> = files.iter().map(|f| std::fs::read(f).unwrap()).collect();
    s.push(
        b"name = \"a\\nb\"\nboard_kind = \"boards/x.toml\"\n[[range]]\nkeys = [60, 63]\ninstrument = \"hammond\"\n\
          params = { k = \"180 N/m\", \"odd name\" = \"1 g\" }\n[[board]]\nkeys = [60, 61]\n[[board]]\nkeys = [62, 63]\n"
            .to_vec(),
    );
    s
}

const TOKENS: &[&[u8]] = &[
    b"\\n",
    b"\\r",
    b"\\u0000",
    b"\\\"\"\"",
    b"'''",
    b"#",
    b"\n[[board]]\nkeys = [0, 127]\n",
    b"params = { \"a.b\" = \"1 g\" }\n",
    b"\xef\xbb\xbf",
    b"\xe2\x80\xa8",
];

/// Any text (control characters, quotes, line separators, non-ASCII).
fn text() -> impl Strategy<Value = String> {
    prop::collection::vec(
        prop_oneof![
            any::<char>(),
            prop::sample::select(vec![
                '\n', '\r', '"', '\'', '\\', '#', '\u{0}', '\u{7f}', '\u{2028}'
            ]),
        ],
        0..24,
    )
    .prop_map(|v| v.into_iter().collect())
}

fn layout() -> impl Strategy<Value = Layout> {
    let range = (
        any::<[u8; 2]>(),
        text(),
        prop::collection::btree_map(text(), text(), 0..3),
        prop::collection::vec((text(), text(), text()), 0..2),
    )
        .prop_map(|(keys, instrument, params, grade)| KeyRange {
            keys,
            instrument,
            params: params.into_iter().collect::<BTreeMap<_, _>>(),
            grade: grade
                .into_iter()
                .map(|(param, from, to)| Grade { param, from, to })
                .collect(),
        });
    (
        text(),
        prop::option::of(text()),
        prop::collection::vec(range, 0..4),
        prop::collection::vec(any::<[u8; 2]>().prop_map(|keys| BoardKeys { keys }), 0..4),
    )
        .prop_map(|(name, board_kind, ranges, boards)| Layout {
            name,
            board_kind,
            ranges,
            boards,
        })
}

#[test]
fn a_written_plan_reads_back_as_written() {
    let seeds = seeds();
    let (mut runner, cases) = fuzz::runner(2000);
    let (run, written) = (Cell::new(0u32), Cell::new(0u32));
    runner
        .run(
            &(
                0..seeds.len(),
                fuzz::edits(TOKENS),
                layout(),
                text(),
                any::<bool>(),
            ),
            |(seed, edits, generated, header, from_file)| {
                let bytes = fuzz::apply(&seeds[seed], &edits);
                let (ok, dt, peak) = fuzz::measured(|| {
                    let layout = match from_file {
                        true => match parse_layout(&String::from_utf8_lossy(&bytes), "f.toml") {
                            Ok(l) => l,
                            Err(e) => {
                                assert!(e.starts_with("f.toml"), "{e}");
                                return false;
                            }
                        },
                        false => generated.clone(),
                    };
                    match layout_text(&layout, &header) {
                        Ok(t) => {
                            // What was written is what is read.
                            assert_eq!(parse_layout(&t, "plan").as_ref(), Ok(&layout), "{t}");
                            true
                        }
                        // Only a layout TOML cannot hold (never one read from a file).
                        Err(e) => {
                            assert!(!from_file, "a layout read from a file: {e}");
                            false
                        }
                    }
                });
                run.set(run.get() + 1);
                written.set(written.get() + u32::from(ok));
                prop_assert!(dt < Duration::from_secs(10), "{dt:?}");
                prop_assert!(peak < 1 << 30, "{peak} bytes");
                Ok::<(), TestCaseError>(())
            },
        )
        .unwrap();
    eprintln!(
        "fuzz_plan: {} cases, {} plans written and read back",
        run.get(),
        written.get()
    );
    assert!(run.get() >= cases);
    assert!(written.get() > run.get() / 4, "too few plans written");
}
