//! Fuzzing board files as `tactus budget`, `build` and `play` read them (issue 36): the
//! shipped boards and a few more, mutated at the byte level and with extreme values, are
//! read by the one validation of boards (`boards::read_board`) or give an error naming
//! the file; a board it accepts is one the firmware is built for — a key's image on it
//! builds, is flashable (a PLL_SYS setting makes its clock), ticks every `⌊clock/fs⌋` or
//! one more cycles as the deadline says, and its verdict is the budget's. Never a panic,
//! more than a bounded time or heap. `TACTUS_FUZZ_CASES=100000` for a long run.

#[path = "../../tests/common/fuzz.rs"]
mod fuzz;

use proptest::prop_assert;
use proptest::test_runner::TestCaseError;
use std::cell::Cell;
use std::path::Path;
use std::time::Duration;
use tactus_firmware::boards::{self, read_board, PlanKey, ProgramCosts};
use tactus_firmware::image::Program;
use tactus_runtime::limiter::LimiterConfig;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn seeds() -> Vec<Vec<u8>> {
    let mut files: Vec<_> = std::fs::read_dir(root().join("boards"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    let mut s: Vec<Vec<u8>> = files.iter().map(|f| std::fs::read(f).unwrap()).collect();
    s.push(
        b"name = \"one core\"\nclock_hz = 125000000\ncores = 1\nsample_rate_hz = 48000\n".to_vec(),
    );
    s
}

const TOKENS: &[&[u8]] = &[
    b"133.3e6",
    b"125e6",
    b"1.6e9",
    b"1e12",
    b"18446744073709551615",
    b"4294967295",
    b"64",
    b"0",
    b"1e6",
    b"96000",
    b"nan",
    b"inf",
    b"-44100",
    b"\ncores = 3\n",
    b"\nio_cycles_per_key = 40\n",
];

/// One hammond program, compiled once.
fn hammond() -> Program {
    let text = std::fs::read_to_string(root().join("instruments/hammond.tactus")).unwrap();
    Program::compile(&text, &Default::default()).unwrap()
}

#[test]
fn mutated_board_files_are_boards_the_firmware_runs_on_or_errors() {
    let seeds = seeds();
    let program = hammond();
    let (mut runner, cases) = fuzz::runner(300);
    let (run, read, built) = (Cell::new(0u32), Cell::new(0u32), Cell::new(0u32));
    runner
        .run(&(0..seeds.len(), fuzz::edits(TOKENS)), |(seed, edits)| {
            let bytes = fuzz::apply(&seeds[seed], &edits);
            let text = String::from_utf8_lossy(&bytes);
            let (outcome, dt, peak) = fuzz::measured(|| {
                let board = match read_board(&text, "b.toml") {
                    Ok(b) => b,
                    Err(e) => {
                        assert!(e.starts_with("b.toml"), "{e}");
                        return 0;
                    }
                };
                // What budget, build and play do with it: price a key, check a board of one
                // key; its image is flashable firmware.
                let lim = LimiterConfig::for_board(&board);
                let programs = std::slice::from_ref(&program);
                let costs = ProgramCosts::new(programs, &board, &lim).unwrap();
                let one = [PlanKey {
                    key: 60,
                    program: 0,
                }];
                let verdict = boards::check_board(programs, &costs, &one, &board, &lim).unwrap();
                let (_, image) = boards::board_image(programs, &costs, &one, &board, &lim).unwrap();
                match image {
                    Ok(image) => {
                        image.flashable().unwrap();
                        assert_eq!(image.cycles_per_sample(), board.cycles_per_sample());
                        let t = image.tick();
                        assert_eq!(u64::from(t.q), board.cycles_per_sample());
                        assert!(verdict.error.is_none());
                        2
                    }
                    Err(e) => {
                        // Only what does not fit: never the board itself.
                        assert!(!e.to_string().starts_with("board:"), "{e}");
                        assert!(!verdict.fits());
                        1
                    }
                }
            });
            run.set(run.get() + 1);
            read.set(read.get() + u32::from(outcome >= 1));
            built.set(built.get() + u32::from(outcome == 2));
            prop_assert!(dt < Duration::from_secs(20), "{dt:?}");
            prop_assert!(peak < 1 << 30, "{peak} bytes");
            Ok::<(), TestCaseError>(())
        })
        .unwrap();
    eprintln!(
        "fuzz_board: {} cases, {} boards read, {} built a key's firmware",
        run.get(),
        read.get(),
        built.get()
    );
    assert!(run.get() >= cases);
    assert!(built.get() > 0);
}
