//! Fuzzing `tactus build LAYOUT --target rp2040` (issue 36): small layouts of shipped
//! instruments (with and without explicit boards, params and grades), mutated at the byte
//! level, either build firmware — every key on exactly one board, every board within its
//! deadline with a key map that describes its image — or give an error naming the file (an
//! empty layout built 0 boards and exited 0 before). Never a panic, more than a bounded time
//! or heap. Layouts of more than [`MAX_BUILT_KEYS`] keys are resolved and checked but not
//! built (planning 88 keys takes seconds a case). `TACTUS_FUZZ_CASES=100000` for a long run.

#[path = "../../tests/common/fuzz.rs"]
mod fuzz;
#[path = "common/layouts.rs"]
mod layouts;

use proptest::prop_assert;
use proptest::test_runner::TestCaseError;
use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::path::Path;
use std::time::Duration;
use tactus_firmware::flash::{self, KeyboardInput};
use tactus_firmware::image::{compile_layout, Program};
use tactus_runtime::keyboard::{assign, board_keys, parse_layout, KeyAssignment};
use tactus_runtime::limiter::LimiterConfig;

/// Most keys a case builds firmware for.
const MAX_BUILT_KEYS: usize = 8;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn shipped(name: &str) -> Result<String, String> {
    if !name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_') {
        return Err(format!("`{name}`: not a built-in instrument"));
    }
    let p = root().join(format!("instruments/{name}.tactus"));
    std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))
}

const SEEDS: &[&[u8]] = &[
    b"name = \"organ\"\n[[range]]\nkeys = [60, 63]\ninstrument = \"hammond\"\nparams = { k = \"200 N/m\" }\n",
    b"name = \"split\"\nboard_kind = \"rp2040_200mhz\"\n[[range]]\nkeys = [48, 50]\ninstrument = \"harpsichord\"\n\
      [[range]]\nkeys = [51, 53]\ninstrument = \"hammond\"\ngrade = [ { param = \"k\", from = \"150 N/m\", to = \"250 N/m\" } ]\n\
      [[board]]\nkeys = [48, 50]\n[[board]]\nkeys = [51, 53]\n",
    b"name = \"piano\"\n[[range]]\nkeys = [21, 22]\ninstrument = \"grand_piano\"\ngrade = [ { param = \"M_h\", from = \"11 g\", to = \"10 g\" } ]\n",
];

const TOKENS: &[&[u8]] = &[
    b"range = []\n",
    b"[[range]]\nkeys = [64, 64]\ninstrument = \"hammond\"\n",
    b"[[board]]\nkeys = [0, 127]\n",
    b"keys = [255, 0]",
    b"keys = [0, 127]",
    b"instrument = \"bowed_string\"",
    b"instrument = \"plucked_string\"",
    b"instrument = \"../x.tactus\"",
    b"board_kind = \"rp2040_20mhz\"",
    b"board_kind = \"nope\"",
    b"\"1e400 g\"",
    b"\"-5 N/m\"",
    b"\"1e12 N/m\"",
    b"\xef\xbb\xbf",
];

/// Whole lines inserted and numbers replaced (keeping the TOML a layout more often), or
/// byte edits.
const LINES: &[&[u8]] = &[
    b"[[range]]\nkeys = [64, 65]\ninstrument = \"hammond\"\n",
    b"[[range]]\nkeys = [0, 127]\ninstrument = \"hammond\"\n",
    b"[[board]]\nkeys = [60, 61]\n",
    b"[[board]]\nkeys = [62, 127]\n",
    b"board_kind = \"rp2040_20mhz\"\n",
    b"params = { k = \"1e12 N/m\" }\n",
    b"params = { nope = \"1 g\" }\n",
    b"grade = [ { param = \"k\", from = \"1 N/m\", to = \"1e308 N/m\" } ]\n",
];
const NUMBERS: &[&[u8]] = &[
    b"0", b"1", b"21", b"60", b"64", b"108", b"127", b"128", b"255", b"1e400",
];

fn edits() -> impl proptest::strategy::Strategy<Value = Vec<fuzz::Edit>> {
    use proptest::prelude::*;
    prop_oneof![fuzz::line_edits(LINES, NUMBERS), fuzz::edits(TOKENS)]
}

type Compiled = (Vec<Program>, Vec<usize>);

/// One layout `text` (as the file `f.toml`): 0 when it is refused before its keys resolve
/// (with an error naming the file), 1 when its keys resolve but no firmware is built (too
/// many keys, a missing board kind, or an error from the build), 2 when firmware is built
/// and checked.
fn one_case(
    text: &str,
    memo: &RefCell<HashMap<String, Result<Compiled, String>>>,
    dir: &Path,
) -> u32 {
    let err = |e: &str| assert!(e.starts_with("f.toml"), "{e}");
    let l = match parse_layout(text, "f.toml") {
        Ok(l) => l,
        Err(e) => {
            err(&e);
            return 0;
        }
    };
    let keys: Vec<KeyAssignment> = match assign(&l, "f.toml", dir) {
        Ok(k) => k,
        Err(e) => {
            err(&e);
            return 0;
        }
    };
    assert!(!keys.is_empty(), "an empty layout resolved");
    let lists = match board_keys(&l, "f.toml", &keys) {
        Ok(b) => b,
        Err(e) => {
            err(&e);
            return 0;
        }
    };
    let kind = l.board_kind.clone().unwrap_or_else(|| "rp2040".into());
    let board = match std::fs::read_to_string(root().join(format!("boards/{kind}.toml"))) {
        Ok(t) => match tactus_firmware::boards::read_board(&t, &kind) {
            Ok(b) => b,
            Err(e) => panic!("a shipped board refused: {e}"),
        },
        Err(_) => return 1,
    };
    if keys.len() > MAX_BUILT_KEYS {
        return 1;
    }
    let id = format!(
        "{kind}{:?}",
        keys.iter()
            .map(|k| (&k.instrument, &k.params))
            .collect::<Vec<_>>()
    );
    let compiled = memo
        .borrow_mut()
        .entry(id)
        .or_insert_with(|| {
            compile_layout(&keys, &shipped, board.sample_rate_hz).map_err(|e| e.to_string())
        })
        .clone();
    let (programs, index) = match compiled {
        Ok(c) => c,
        Err(e) => {
            assert!(!e.is_empty());
            return 1;
        }
    };
    let mut names = vec![(String::new(), Vec::new()); programs.len()];
    for (k, &p) in keys.iter().zip(&index) {
        names[p] = (k.instrument.clone(), k.params.clone());
    }
    let pairs: Vec<(u8, usize)> = keys.iter().map(|k| k.key).zip(index).collect();
    let limiter = LimiterConfig::for_board(&board);
    // The layout's boards, or planned (as `tactus build` plans them).
    let lists = match lists.map_or_else(
        || layouts::plan(&programs, &pairs, &board, &limiter).map_err(|e| e.to_string()),
        Ok,
    ) {
        Ok(l) => l,
        Err(e) => {
            assert!(!e.is_empty());
            return 1;
        }
    };
    let input = KeyboardInput {
        name: &l.name,
        programs: &programs,
        program_names: &names,
        keys: &pairs,
        board: &board,
        boards: &lists,
        images: &[],
        limiter: &limiter,
        command: "fuzz",
        load: flash::Load::Ram,
    };
    match flash::keyboard_firmware(&input, &mut |_, _, _| {}) {
        Ok(fw) => {
            // Every key on exactly one board, each within its deadline, each key
            // map describing its image.
            let mut on: Vec<u8> = fw.iter().flat_map(|b| b.keys.clone()).collect();
            on.sort_unstable();
            let want: Vec<u8> = keys.iter().map(|k| k.key).collect();
            assert_eq!(on, want);
            for b in &fw {
                for c in 0..b.image.cores() {
                    let w = b.image.wcet(c).unwrap();
                    assert!(w.bound() <= b.image.cycles_per_sample());
                }
                let image = tactus_emulator::elf::parse(&b.elf).unwrap();
                tactus_firmware::key_map::check(&b.key_map, &image).unwrap();
            }
            2
        }
        Err(e) => {
            assert!(!e.is_empty());
            1
        }
    }
}

#[test]
fn mutated_layouts_build_firmware_or_name_the_problem() {
    // Compiled programs per distinct list of (instrument, params): a mutation mostly keeps them.
    let memo: RefCell<HashMap<String, Result<Compiled, String>>> = RefCell::default();
    let (mut runner, cases) = fuzz::runner(40);
    let (run, resolved, built) = (Cell::new(0u32), Cell::new(0u32), Cell::new(0u32));
    let dir = root().join("instruments/layouts");
    // The seeds themselves build firmware: the path every mutation departs from is exercised
    // whatever the random cases do.
    for (i, seed) in SEEDS.iter().enumerate() {
        let text = String::from_utf8_lossy(seed);
        assert_eq!(
            one_case(&text, &memo, &dir),
            2,
            "seed {i} does not build firmware"
        );
    }
    runner
        .run(&(0..SEEDS.len(), edits()), |(seed, edits)| {
            let bytes = fuzz::apply(SEEDS[seed], &edits);
            let text = String::from_utf8_lossy(&bytes);
            let (outcome, dt, peak) = fuzz::measured(|| one_case(&text, &memo, &dir));
            run.set(run.get() + 1);
            resolved.set(resolved.get() + u32::from(outcome >= 1));
            built.set(built.get() + u32::from(outcome == 2));
            prop_assert!(dt < Duration::from_secs(60), "{dt:?}");
            prop_assert!(peak < 1 << 30, "{peak} bytes");
            Ok::<(), TestCaseError>(())
        })
        .unwrap();
    eprintln!(
        "fuzz_layout: {} cases, {} resolved, {} built firmware",
        run.get(),
        resolved.get(),
        built.get()
    );
    assert!(run.get() >= cases);
}
