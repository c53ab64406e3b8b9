//! Play a recorded MIDI performance through the firmware of one board of grand88, emulated
//! every sample: the keys of that board follow the position player's key tracks, the rest
//! of the keyboard is not run. What `tactus play` does for every board at once.
//!
//! ```text
//! cargo run --release --example play_board                       # Maestro_1.mid, 10 s, the busiest board
//! cargo run --release --example play_board -- PIECE.mid 5 3      # PERFORMANCE [SECONDS [BOARD]]
//! ```
//!
//! The default performance is `../shared/data/performances/Maestro_1.mid` beside the
//! repository (the project's shared data; an error says so when it is missing). The
//! library calls: `tactus_runtime::performance::read_midi` and `key_tracks`,
//! `tactus_host::keyboard::compile` (grand88), `Keyboard::firmware`, `Keyboard::plan`, then
//! `tactus_host::play::emulated::play_boards` on the one board's keys (its image built and
//! run as `tactus play` runs it: block engine, memoized, boards at rest replayed). Prints
//! each strike, the cores' worst cycles and misses.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use tactus_host::keyboard::{self, KeyboardSpec};
use tactus_host::play::emulated::{play_boards, Motion, PerformOptions};
use tactus_host::play::strike::midi_velocity;
use tactus_runtime::performance::{key_tracks, read_midi};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let shared = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/performances");
    let piece = args
        .first()
        .map_or(shared.join("Maestro_1.mid"), PathBuf::from);
    let result = (|| {
        let seconds: f64 = (args.get(1).map_or("10", String::as_str))
            .parse()
            .map_err(|e| format!("SECONDS: {e}"))?;
        let board = (args.get(2).map(|b| b.parse::<usize>()))
            .transpose()
            .map_err(|e| format!("BOARD: {e}"))?;
        run(&piece, seconds, board)
    })();
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(2),
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Plays `seconds` of `piece` on board `which` (from 1; `None`: the one with the most
/// notes); whether no core missed a deadline.
fn run(piece: &Path, seconds: f64, which: Option<usize>) -> Result<bool, String> {
    if !piece.exists() {
        return Err(format!(
            "{}: not found. The recorded performances live in ../shared/data/performances/ \
             beside the repository; give a MIDI file as the first argument",
            piece.display()
        ));
    }
    if !(seconds > 0.0 && seconds <= 60.0) {
        return Err(format!("SECONDS {seconds}: from just above 0 to 60"));
    }
    let mut perf = read_midi(piece).map_err(|e| e.to_string())?;
    perf.cut(seconds)?;

    let spec = KeyboardSpec {
        input: "grand88",
        as_layout: Some(true),
        board: None,
        keys: None,
        params: &[],
    };
    let kb = keyboard::compile(&spec, &mut |_, _| {}).map_err(|e| e.to_string())?;
    let programs = kb.firmware().map_err(|e| e.to_string())?;
    let plan = kb
        .plan(&programs, &mut |_, _| {})
        .map_err(|e| e.to_string())?;
    let lists = plan.key_lists();
    let notes_on = |list: &Vec<u8>| perf.notes.iter().filter(|n| list.contains(&n.key)).count();
    let index = match which {
        Some(b) if (1..=lists.len()).contains(&b) => b - 1,
        Some(b) => {
            return Err(format!(
                "BOARD {b}: grand88 has boards 1 to {}",
                lists.len()
            ))
        }
        None => (0..lists.len())
            .max_by_key(|&i| (notes_on(&lists[i]), std::cmp::Reverse(i)))
            .unwrap_or(0),
    };
    let list = &lists[index];

    // The position player's key tracks of the board's keys.
    let dip_m = programs[0].fixed.program.sensors[0].range.1;
    let tracks: BTreeMap<u8, Motion> = (key_tracks(&perf, dip_m).into_iter())
        .filter(|t| list.contains(&t.key))
        .map(|t| (t.key, Motion::Track(t)))
        .collect();
    let motions = tracks.iter().map(|(&k, m)| (k, m)).collect();
    let (keys, key_programs): (Vec<u8>, Vec<usize>) = kb.key_programs().into_iter().unzip();
    let fs = kb.board.sample_rate_hz;
    let opts = PerformOptions {
        end: (perf.duration_s * fs) as usize,
        clock: tactus_host::play::Timeline::at_zero(fs),
        finger: Default::default(),
        trace: Default::default(),
        boards: vec![list.clone()],
        // No plan's image: the board's is built.
        images: Vec::new(),
        limiter: kb.limiter(),
        engine: tactus_emulator::Engine::Block,
        quiescent_guard: true,
        rest_replay: true,
        io_trace: None,
        span: None,
        faults: Vec::new(),
    };
    let run = play_boards(
        &programs,
        &keys,
        &key_programs,
        &kb.board,
        &motions,
        &opts,
        &|_| {},
    )
    .map_err(|e| e.to_string())?;
    let b = &run.boards[0];
    println!(
        "{}: {:.1} s, board {} of {} (keys {}): {} notes, {} strikes",
        piece.display(),
        perf.duration_s,
        index + 1,
        lists.len(),
        tactus_firmware::verdict::key_ranges(list),
        notes_on(list),
        b.strikes.len()
    );
    for s in &b.strikes {
        println!(
            "{:8.3} s  key {:3}  hammer {:.2} m/s (velocity {})",
            s.time_s,
            s.key,
            s.speed_mps,
            midi_velocity(s.speed_mps)
        );
    }
    for c in 0..b.max.len() {
        println!(
            "core {c}: worst handler {} cycles (static bound {}), {} misses",
            b.max[c], b.bound[c], b.misses[c]
        );
    }
    println!(
        "rest replay: {} of {} samples given from recordings",
        b.rest_replayed.0, opts.end
    );
    Ok(b.misses.iter().all(|&m| m == 0))
}

/// `cargo test` builds this example and plays half a second of Maestro_1 on its busiest
/// board, so that it cannot go stale (the performance is the shared data beside the
/// repository: missing, the test fails under `CI` and says it skipped elsewhere).
#[cfg(test)]
mod tests {
    #[test]
    fn plays_half_a_second_through_one_board() {
        let piece = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/data/performances/Maestro_1.mid");
        if !piece.exists() {
            assert!(
                std::env::var_os("CI").is_none(),
                "{} is missing and CI is set",
                piece.display()
            );
            eprintln!("SKIPPED: {} is missing", piece.display());
            return;
        }
        assert!(super::run(&piece, 0.5, None).unwrap());
        let e = super::run(std::path::Path::new("no/such.mid"), 0.5, None).unwrap_err();
        assert!(e.contains("../shared/data/performances"), "{e}");
    }
}
