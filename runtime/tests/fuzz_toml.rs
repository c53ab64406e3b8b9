//! Fuzzing the layout and board readers: the shipped layouts (with and without explicit
//! boards) and board files, mutated at the byte level, parse and resolve to keys and boards
//! or give an error naming the file — never a panic, more than a bounded time or a bounded
//! heap. A resolved layout's keys are ascending MIDI numbers with one assignment each; its
//! boards cover every key once; a parsed board has 1 to `MAX_CORES` cores and a finite
//! cycle count. `TACTUS_FUZZ_CASES=100000` for a long run.

#[path = "../../tests/common/fuzz.rs"]
mod fuzz;

use proptest::prop_assert;
use proptest::test_runner::TestCaseError;
use std::cell::Cell;
use std::path::Path;
use std::time::Duration;
use tactus_runtime::keyboard::{assign, board_keys, parse_board, parse_layout, MAX_CORES};

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// The shipped layouts, one with explicit boards, and the shipped boards.
fn seeds() -> Vec<Vec<u8>> {
    let mut s = Vec::new();
    for dir in ["instruments/layouts", "boards"] {
        let mut files: Vec<_> = std::fs::read_dir(root().join(dir))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        for f in files {
            s.push(std::fs::read(f).unwrap());
        }
    }
    s.push(
        b"name = \"x\"\nboard_kind = \"rp2040\"\n[[range]]\nkeys = [60, 63]\ninstrument = \"hammond\"\n\
          params = { k = \"180 N/m\" }\n[[board]]\nkeys = [60, 61]\n[[board]]\nkeys = [62, 63]\n"
            .to_vec(),
    );
    s
}

const TOKENS: &[&[u8]] = &[
    b"[[board]]\nkeys = [0, 127]\n",
    b"[[range]]\nkeys = [1, 2, 3]\ninstrument = \"a\"\n",
    b"keys = [255, 0]",
    b"cores = 4294967295",
    b"clock_hz = 1e300",
    b"sample_rate_hz = nan",
    b"\"11 g\"",
    b"grade = [ { param = \"M_h\", from = \"1e308 g\", to = \"-1e308 g\" } ]",
    b"board_kind = \"x\"",
    b"\xef\xbb\xbf",
];

#[test]
fn mutated_layouts_and_boards_parse_or_give_errors() {
    let seeds = seeds();
    assert!(seeds.len() >= 5);
    let (mut runner, cases) = fuzz::runner(3000);
    let (run, read) = (Cell::new(0u32), Cell::new(0u32));
    runner
        .run(&(0..seeds.len(), fuzz::edits(TOKENS)), |(seed, edits)| {
            let bytes = fuzz::apply(&seeds[seed], &edits);
            let text = String::from_utf8_lossy(&bytes);
            let (ok, dt, peak) = fuzz::measured(|| {
                let mut ok = false;
                match parse_layout(&text, "f.toml") {
                    Ok(l) => match assign(&l, "f.toml", Path::new("/nonexistent")) {
                        Ok(keys) => {
                            assert!(keys.windows(2).all(|w| w[0].key < w[1].key));
                            assert!(keys.iter().all(|k| k.key <= 127));
                            match board_keys(&l, "f.toml", &keys) {
                                Ok(Some(boards)) => {
                                    let mut all: Vec<u8> =
                                        boards.iter().flatten().copied().collect();
                                    all.sort_unstable();
                                    let want: Vec<u8> = keys.iter().map(|k| k.key).collect();
                                    assert_eq!(all, want);
                                    ok = true;
                                }
                                Ok(None) => ok = true,
                                Err(e) => assert!(e.starts_with("f.toml"), "{e}"),
                            }
                        }
                        Err(e) => assert!(e.starts_with("f.toml"), "{e}"),
                    },
                    Err(e) => assert!(e.starts_with("f.toml"), "{e}"),
                }
                match parse_board(&text, "b.toml") {
                    Ok(b) => {
                        assert!((1..=MAX_CORES).contains(&b.cores));
                        assert!(b.cycles_per_sample() >= 1 && b.clock_hz.is_finite());
                        ok = true;
                    }
                    Err(e) => assert!(e.starts_with("b.toml"), "{e}"),
                }
                ok
            });
            run.set(run.get() + 1);
            read.set(read.get() + u32::from(ok));
            prop_assert!(dt < Duration::from_secs(10), "{dt:?}");
            prop_assert!(peak < 1 << 30, "{peak} bytes");
            Ok::<(), TestCaseError>(())
        })
        .unwrap();
    eprintln!("fuzz_toml: {} cases, {} read", run.get(), read.get());
    assert!(run.get() >= cases);
}
