//! Fuzzing `tactus play PERFORMANCE.mid` with its WAV rendering (issue 36): the demo as a
//! MIDI file (and a dense repetition), mutated at the byte level, is read (or refused,
//! naming the file), cut to its first second as `--seconds 1` does, played by both players
//! on a small striking instrument across the keyboard, and its strikes rendered to a WAV —
//! or the run says what it cannot do (a note left out, a rendering too large: "use
//! --no-wav"). The key motion stays within the cut (a dense repetition once stretched a
//! key's motion over hours). Never a panic, more than a bounded time or heap.
//! `TACTUS_FUZZ_CASES=100000` for a long run.

#[path = "../../tests/common/fuzz.rs"]
mod fuzz;

use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use std::cell::Cell;
use std::collections::BTreeMap;
use std::time::Duration;
use tactus_host::play::{
    self, output, HostProgram, Keyboard, PlayConfig, PlayEngine, Player, TraceWindow,
};
use tactus_runtime::keyboard::{BoardSpec, KeyAssignment};
use tactus_runtime::performance::{demo, parse_midi_reporting};
use tactus_runtime::player::FingerConfig;

/// The performance is cut here, s (`--seconds`).
const SECONDS: f64 = 1.0;

/// A key that strikes when pressed past 5 mm: cheap to interpret.
const STRIKER: &str = "instrument striker {
    sensor key: m in [0 mm, 10 mm]
    param k = 100 N/m
    force spring = k * key
    on key > 5 mm { emit strike(v = 1 m/s) }
}
";

fn vlq(mut d: u32, out: &mut Vec<u8>) {
    let mut bytes = vec![(d & 0x7f) as u8];
    d >>= 7;
    while d > 0 {
        bytes.insert(0, 0x80 | (d & 0x7f) as u8);
        d >>= 7;
    }
    out.extend(bytes);
}

/// A format-0 MIDI file, 480 ticks per quarter at 120 bpm, of (tick, message) events.
fn smf(mut timed: Vec<(u32, Vec<u8>)>) -> Vec<u8> {
    timed.sort_by_key(|e| e.0);
    let mut t = Vec::new();
    let mut last = 0;
    for (at, msg) in timed {
        vlq(at - last, &mut t);
        t.extend(msg);
        last = at;
    }
    t.extend([0, 0xff, 0x2f, 0]);
    let mut f = b"MThd\0\0\0\x06\0\0\0\x01\x01\xe0MTrk".to_vec();
    f.extend((t.len() as u32).to_be_bytes());
    f.extend(t);
    f
}

fn seeds() -> Vec<Vec<u8>> {
    let perf = demo();
    let mut timed: Vec<(u32, Vec<u8>)> = vec![(0, vec![0xB0, 64, 127])];
    for n in &perf.notes {
        timed.push(((n.on_s * 960.0) as u32, vec![0x90, n.key, n.velocity]));
        timed.push(((n.off_s * 960.0) as u32, vec![0x80, n.key, 0]));
    }
    let dense: Vec<(u32, Vec<u8>)> = (0..400)
        .flat_map(|i| [(i, vec![0x90, 60, 100]), (i + 1, vec![0x80, 60, 0])])
        .collect();
    vec![smf(timed), smf(dense)]
}

const TOKENS: &[&[u8]] = &[
    b"\x90\x3c\x7f",
    b"\x80\x3c\x00",
    b"\x90\x15\x01",
    b"\xb0\x40\x7f",
    b"\xff\x51\x03\x00\x00\x01",
    b"\xff\x51\x03\xff\xff\xff",
    b"\x8f\xff\xff\x7f",
    b"\x00\x90\x3c\x64\x00\x90\x3c\x64\x00\x90\x3c\x64",
];

struct Quiet;
impl play::Progress for Quiet {
    fn start(&self, _: u64, _: Option<f64>) {}
    fn inc(&self, _: u64) {}
}

#[test]
fn mutated_performances_play_and_render_or_say_why_not() {
    let seeds = seeds();
    let program = tactus_compiler::compile(STRIKER, &Default::default())
        .unwrap()
        .program;
    let keys: Vec<KeyAssignment> = (21u8..=108)
        .map(|key| KeyAssignment {
            key,
            instrument: "striker".into(),
            params: vec![],
        })
        .collect();
    let board = BoardSpec {
        name: "rp2040".into(),
        clock_hz: 133e6,
        cores: 2,
        sample_rate_hz: 44_100.0,
        core_voltage_v: None,
        converters: None,
    };
    let wav = std::env::temp_dir().join(format!("tactus-fuzz-play-{}.wav", std::process::id()));
    let (mut runner, cases) = fuzz::runner(40);
    let (run, read, rendered) = (Cell::new(0u32), Cell::new(0u32), Cell::new(0u32));
    runner
        .run(
            &(0..seeds.len(), fuzz::edits(TOKENS), any::<bool>()),
            |(seed, edits, force)| {
                let bytes = fuzz::apply(&seeds[seed], &edits);
                let (outcome, dt, peak) = fuzz::measured(|| {
                    let mut perf = match parse_midi_reporting(&bytes, "p.mid") {
                        Ok((p, _warnings)) => p,
                        Err(e) => {
                            assert!(e.to_string().contains("p.mid"), "{e}");
                            return 0;
                        }
                    };
                    perf.cut(SECONDS).unwrap();
                    perf.notes.retain(|n| (21..=108).contains(&n.key));
                    if perf.notes.is_empty() {
                        return 0;
                    }
                    let key_program: BTreeMap<u8, usize> =
                        perf.notes.iter().map(|n| (n.key, 0)).collect();
                    let keyboard = Keyboard {
                        keys: keys.clone(),
                        programs: vec![HostProgram {
                            name: "striker".into(),
                            program: program.clone(),
                        }],
                        key_program,
                        boards: None,
                        firmware: None,
                    };
                    let config = PlayConfig {
                        engine: PlayEngine::Interp,
                        player: if force {
                            Player::Force
                        } else {
                            Player::Position
                        },
                        finger: FingerConfig::default(),
                        trace: TraceWindow::default(),
                        board: board.clone(),
                        emulator: tactus_emulator::Engine::Interp,
                        quiescent_guard: true,
                        rest_replay: true,
                        io_trace: None,
                        span: None,
                        faults: Vec::new(),
                        sensor_check: None,
                        watchdog: None,
                    };
                    let played = match play::play(&perf, &keyboard, &config, &Quiet) {
                        Ok(p) => p,
                        // The force player cannot calibrate an instrument that does not strike
                        // under a finger: said, not played.
                        Err(e) => {
                            assert!(
                                matches!(e, play::RunError::Calibration { .. }),
                                "only a calibration may refuse a fuzzed performance: {e}"
                            );
                            return 1;
                        }
                    };
                    // The motion stayed within the cut: every key's simulated samples.
                    let per_key = played.key_samples as f64 / perf.notes.len().max(1) as f64;
                    assert!(
                        played.key_samples as f64 <= 88.0 * 44_100.0 * (SECONDS + 2.0),
                        "{} key-samples ({per_key:.0} a note)",
                        played.key_samples
                    );
                    for s in &played.strikes {
                        assert!(s.time_s.is_finite() && s.time_s < SECONDS + 2.0, "{s:?}");
                    }
                    match output::write_wav(&wav, &played.strikes, &perf, 44_100.0) {
                        Ok(()) => 3,
                        Err(e) => {
                            let e = e.to_string();
                            assert!(e.contains("use --no-wav"), "{e}");
                            2
                        }
                    }
                });
                run.set(run.get() + 1);
                read.set(read.get() + u32::from(outcome >= 1));
                rendered.set(rendered.get() + u32::from(outcome == 3));
                prop_assert!(dt < Duration::from_secs(30), "{dt:?}");
                prop_assert!(peak < 1 << 30, "{peak} bytes");
                Ok::<(), TestCaseError>(())
            },
        )
        .unwrap();
    let _ = std::fs::remove_file(&wav);
    eprintln!(
        "fuzz_play: {} cases, {} played, {} rendered to WAV",
        run.get(),
        read.get(),
        rendered.get()
    );
    assert!(run.get() >= cases);
    assert!(rendered.get() > 0);
}
