//! The shipped layouts' boards as `tactus build` makes them, and the budget corpus per key:
//! shared by the tests that run every board (`flash.rs`, `keyboard_exact.rs`).
#![allow(dead_code)] // each test binary uses a subset

use std::path::Path;
use tactus_firmware::boards::{self, BoardsError, PlanKey, ProgramCosts};
use tactus_firmware::corpus::{self, Size};
use tactus_firmware::flash::{self, BoardFirmware, KeyboardInput, Load};
use tactus_firmware::image::{compile_layout, Program};
use tactus_runtime::keyboard::{read_layout, BoardSpec};
use tactus_runtime::limiter::LimiterConfig;

/// The repository's root.
pub fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// A shipped instrument's source by name (or a path ending in `.tactus`).
pub fn shipped(name: &str) -> Result<String, String> {
    let p = if name.ends_with(".tactus") {
        root().join(name)
    } else {
        root().join(format!("instruments/{name}.tactus"))
    };
    std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))
}

/// The shipped board `boards/NAME.toml`, read and checked as `tactus` reads every board
/// ([`boards::read_board`]).
pub fn shipped_board(name: &str) -> BoardSpec {
    let path = root().join(format!("boards/{name}.toml"));
    let text = std::fs::read_to_string(&path).unwrap();
    boards::read_board(&text, &path.display().to_string()).unwrap()
}

/// Every board of `layout` as `tactus build` makes it (boards planned when the layout lists
/// none) on the board file `kind` (default: the layout's), with the board kind it uses.
pub fn firmware(layout: &str, kind: Option<&str>, load: Load) -> (Vec<BoardFirmware>, BoardSpec) {
    firmware_with(layout, kind, load, None)
}

/// [`firmware`] with the sensor check (`Program::sensor_check`) set on every program when
/// `check` is given.
pub fn firmware_with(
    layout: &str,
    kind: Option<&str>,
    load: Load,
    check: Option<bool>,
) -> (Vec<BoardFirmware>, BoardSpec) {
    let path = root().join(layout);
    let (l, keys) = read_layout(&path).unwrap();
    let kind = kind
        .map(str::to_string)
        .or(l.board_kind.clone())
        .unwrap_or_else(|| "rp2040".into());
    let board = shipped_board(kind.trim_end_matches(".toml"));
    let (mut programs, index) = compile_layout(&keys, &shipped, board.sample_rate_hz).unwrap();
    if let Some(on) = check {
        programs.iter_mut().for_each(|p| p.sensor_check = on);
    }
    let mut names = vec![(String::new(), Vec::new()); programs.len()];
    for (k, &p) in keys.iter().zip(&index) {
        names[p] = (k.instrument.clone(), k.params.clone());
    }
    let mut pairs: Vec<(u8, usize)> = keys.iter().map(|k| k.key).zip(index).collect();
    pairs.sort_unstable();
    let limiter = LimiterConfig::for_board(&board);
    let boards = match tactus_runtime::keyboard::board_keys(&l, layout, &keys).unwrap() {
        Some(lists) => lists,
        None => plan(&programs, &pairs, &board, &limiter).unwrap(),
    };
    let input = KeyboardInput {
        name: &l.name,
        programs: &programs,
        program_names: &names,
        keys: &pairs,
        board: &board,
        boards: &boards,
        images: &[],
        limiter: &limiter,
        load,
        command: "test",
    };
    let fw = flash::keyboard_firmware(&input, &mut |_, _, _| {}).unwrap();
    (fw, board)
}

/// The boards [`boards::plan`] gives `keys` ((MIDI key, program), ascending), as
/// `tactus_host::keyboard::Keyboard::plan` plans a keyboard whose layout lists none.
pub fn plan(
    programs: &[Program],
    keys: &[(u8, usize)],
    board: &BoardSpec,
    limiter: &LimiterConfig,
) -> Result<Vec<Vec<u8>>, BoardsError> {
    let costs = ProgramCosts::new(programs, board, limiter)?;
    let keys: Vec<PlanKey> = (keys.iter())
        .map(|&(key, program)| PlanKey { key, program })
        .collect();
    let planned = boards::plan(programs, &costs, &keys, board, limiter, &mut |_, _| {})?;
    Ok(planned.key_lists())
}

/// The budget corpus (quick) for each key, its runs concatenated and repeated, each key
/// starting at its own offset.
pub fn corpus_words(p: &Program, key: usize, samples: usize) -> Vec<i32> {
    words_of(p, key, samples, |_| true)
}

/// [`corpus_words`] of the runs a key makes (`corpus::by_design` left out: no glitch, no
/// random words): each starts and ends at rest, so the runs joined make no jump a key's
/// physics does not make, and the sensor check (on by default) lets every word through.
pub fn physical_words(p: &Program, key: usize, samples: usize) -> Vec<i32> {
    words_of(p, key, samples, |label| !corpus::by_design(label))
}

fn words_of(p: &Program, key: usize, samples: usize, take: impl Fn(&str) -> bool) -> Vec<i32> {
    let runs = corpus::corpus(&p.fixed, Size::Quick);
    let all: Vec<i32> = runs
        .iter()
        .filter(|r| take(&r.label))
        .flat_map(|r| r.records.iter().map(|w| w.first().copied().unwrap_or(0)))
        .collect();
    let off = key * 7919;
    (0..samples).map(|n| all[(off + n) % all.len()]).collect()
}

/// `run` of each board, the boards shared out in board order over two host threads (a
/// board's two cores on one thread; CI has two cores): the results in board order.
pub fn on_host_threads<T: Send>(
    boards: &[BoardFirmware],
    run: impl Fn(&BoardFirmware) -> T + Sync,
) -> Vec<T> {
    let run = &run;
    std::thread::scope(|s| {
        let handles: Vec<_> = boards
            .chunks(boards.len().div_ceil(2).max(1))
            .map(|c| s.spawn(move || c.iter().map(run).collect::<Vec<_>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    })
}
