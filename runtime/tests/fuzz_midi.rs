//! Fuzzing the MIDI reader: standard MIDI files (the demo performance written as format 0
//! and format 1, a tempo change and the sustain pedal; the MAESTRO performances of
//! `../shared/data/performances` when present), mutated at the byte level, parse to a
//! performance (with warnings for repairs) or to an error naming the file — never a
//! panic, more than a bounded time or a bounded heap. Parsed performances also become key
//! tracks (the player model). `TACTUS_FUZZ_CASES=100000` for a long run.

#[path = "../../tests/common/fuzz.rs"]
mod fuzz;

use proptest::prop_assert;
use proptest::test_runner::TestCaseError;
use std::cell::Cell;
use std::path::Path;
use std::time::Duration;
use tactus_runtime::performance::{demo, key_tracks, parse_midi_reporting, MAX_HELD_S};

fn vlq(mut d: u32, out: &mut Vec<u8>) {
    let mut bytes = vec![(d & 0x7f) as u8];
    d >>= 7;
    while d > 0 {
        bytes.insert(0, 0x80 | (d & 0x7f) as u8);
        d >>= 7;
    }
    out.extend(bytes);
}

fn track(events: &[(u32, Vec<u8>)]) -> Vec<u8> {
    let mut t = Vec::new();
    for (d, msg) in events {
        vlq(*d, &mut t);
        t.extend(msg);
    }
    t.extend([0, 0xff, 0x2f, 0]);
    let mut c = b"MTrk".to_vec();
    c.extend((t.len() as u32).to_be_bytes());
    c.extend(t);
    c
}

/// The demo performance as a standard MIDI file (480 ticks per quarter, 120 bpm).
fn demo_smf(format: u16) -> Vec<u8> {
    let perf = demo();
    let mut ev: Vec<(u32, Vec<u8>)> = Vec::new();
    let mut timed: Vec<(u32, Vec<u8>)> = Vec::new();
    for n in &perf.notes {
        timed.push(((n.on_s * 960.0) as u32, vec![0x90, n.key, n.velocity]));
        timed.push(((n.off_s * 960.0) as u32, vec![0x80, n.key, 0]));
    }
    timed.push((0, vec![0xB0, 64, 127]));
    timed.push((960, vec![0xFF, 0x51, 3, 0x07, 0xA1, 0x20]));
    timed.sort_by_key(|e| e.0);
    let mut last = 0;
    for (t, m) in timed {
        ev.push((t - last, m));
        last = t;
    }
    let tracks: Vec<Vec<u8>> = if format == 0 {
        vec![track(&ev)]
    } else {
        vec![
            track(&[(0, vec![0xFF, 0x51, 3, 0x07, 0xA1, 0x20])]),
            track(&ev),
        ]
    };
    let mut f = b"MThd\0\0\0\x06".to_vec();
    f.extend(format.to_be_bytes());
    f.extend((tracks.len() as u16).to_be_bytes());
    f.extend(480u16.to_be_bytes());
    for t in tracks {
        f.extend(t);
    }
    f
}

fn seeds() -> Vec<Vec<u8>> {
    let mut s = vec![demo_smf(0), demo_smf(1)];
    // Beside the repository (as `runtime/tests/performance.rs` looks), or beside a worktree.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for i in 1..=3 {
        let found = ["../../shared", "../../../shared"].iter().find_map(|d| {
            std::fs::read(
                root.join(d)
                    .join(format!("data/performances/Maestro_{i}.mid")),
            )
            .ok()
        });
        // In CI the MAESTRO files are there: without them the seeds are not the test's.
        assert!(
            found.is_some() || std::env::var_os("CI").is_none(),
            "Maestro_{i}.mid is absent from ../shared/data/performances and CI is set"
        );
        s.extend(found);
    }
    eprintln!(
        "fuzz_midi: {} seeds ({} MAESTRO files)",
        s.len(),
        s.len() - 2
    );
    s
}

const TOKENS: &[&[u8]] = &[
    b"MTrk",
    b"MThd",
    b"\x90\x3c\x64",
    b"\x80\x3c\x00",
    b"\xff\x51\x03\x00\x00\x01",
    b"\xff\x2f\x00",
    b"\x8f\xff\xff\x7f",
    b"\xb0\x40\x7f",
    b"\xf0\x7f",
    b"\x00\x02",
];

#[test]
fn mutated_midi_files_parse_or_give_errors() {
    let seeds = seeds();
    for s in &seeds {
        let (p, w) = parse_midi_reporting(s, "seed.mid").unwrap();
        assert!(!p.notes.is_empty() && w.is_empty(), "{w:?}");
    }
    let (mut runner, cases) = fuzz::runner(3000);
    let (run, read) = (Cell::new(0u32), Cell::new(0u32));
    runner
        .run(&(0..seeds.len(), fuzz::edits(TOKENS)), |(seed, edits)| {
            let bytes = fuzz::apply(&seeds[seed], &edits);
            let (r, dt, peak) = fuzz::measured(|| match parse_midi_reporting(&bytes, "f.mid") {
                Ok((perf, _warnings)) => {
                    for n in &perf.notes {
                        assert!(n.off_s >= n.on_s && n.off_s - n.on_s <= MAX_HELD_S + 1e-9);
                        assert!(n.on_s.is_finite());
                    }
                    let tracks = key_tracks(&perf, 0.01);
                    assert!(tracks.len() <= 128);
                    true
                }
                Err(e) => {
                    assert!(e.to_string().starts_with("f.mid"), "{e}");
                    false
                }
            });
            run.set(run.get() + 1);
            read.set(read.get() + u32::from(r));
            prop_assert!(dt < Duration::from_secs(10), "{dt:?}");
            prop_assert!(peak < 1 << 30, "{peak} bytes");
            Ok::<(), TestCaseError>(())
        })
        .unwrap();
    eprintln!("fuzz_midi: {} cases, {} read", run.get(), read.get());
    assert!(run.get() >= cases);
}
