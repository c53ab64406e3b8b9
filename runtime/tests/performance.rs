//! The real performances in `../shared/data/performances/` (MAESTRO, via miditok's test
//! files; not copied into this repository). Their README's table is the expectation.

use std::path::PathBuf;
use tactus_runtime::performance::{key_tracks, read_midi};

fn shared(name: &str) -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/data/performances")
        .join(name);
    if p.exists() {
        Some(p)
    } else {
        let why = format!(
            "{} is absent (the shared data folder must sit beside the repository)",
            p.display()
        );
        // In CI the data is there: missing, the test fails rather than skips.
        assert!(std::env::var_os("CI").is_none(), "{why}: CI is set");
        eprintln!("SKIPPED: {why}");
        None
    }
}

#[test]
fn maestro_files_match_their_published_summary() {
    // (file, notes, velocity range, pitch range, length s) from shared/data/performances/README.md
    let table = [
        ("Maestro_1.mid", 2367, (3, 97), (35, 99), 349.0),
        ("Maestro_2.mid", 12418, (1, 126), (21, 104), 901.0),
        ("Maestro_3.mid", 3142, (4, 104), (29, 94), 222.0),
    ];
    for (name, n, vel, pitch, len) in table {
        let Some(path) = shared(name) else { continue };
        let p = read_midi(&path).unwrap();
        assert_eq!(p.notes.len(), n, "{name}");
        let vmin = p.notes.iter().map(|x| x.velocity).min().unwrap();
        let vmax = p.notes.iter().map(|x| x.velocity).max().unwrap();
        let kmin = p.notes.iter().map(|x| x.key).min().unwrap();
        let kmax = p.notes.iter().map(|x| x.key).max().unwrap();
        assert_eq!(((vmin, vmax), (kmin, kmax)), (vel, pitch), "{name}");
        assert!(
            (p.duration_s - len).abs() < 1.0,
            "{name}: {} s",
            p.duration_s
        );
        assert!(!p.sustain.is_empty(), "{name}: no sustain pedal events");
        assert!(p.notes.iter().all(|x| x.off_s >= x.on_s));
    }
}

#[test]
fn every_note_is_a_press_reaching_the_bottom_at_its_note_on() {
    let Some(path) = shared("Maestro_1.mid") else {
        return;
    };
    let p = read_midi(&path).unwrap();
    let dip = 0.010;
    let tracks = key_tracks(&p, dip);
    assert_eq!(
        tracks.iter().map(|t| t.notes.len()).sum::<usize>(),
        p.notes.len()
    );
    for t in &tracks {
        for &(on, _) in &t.notes {
            assert!(
                (t.position(on) - dip).abs() < 1e-9,
                "key {} at {on} s: {}",
                t.key,
                t.position(on)
            );
        }
        for i in 0..2000 {
            let x = t.position(i as f64 * 0.2);
            assert!((0.0..=dip).contains(&x), "key {} out of range: {x}", t.key);
        }
    }
}

#[test]
fn malformed_midi_is_an_error_naming_the_file() {
    let dir = std::env::temp_dir().join(format!("tactus-midi-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join("broken.mid");
    std::fs::write(&f, b"MThd\0\0\0\x06\0\0\0\x01").unwrap();
    let e = read_midi(&f).unwrap_err().to_string();
    assert!(e.contains("broken.mid"), "{e}");
    let e = read_midi(&dir.join("missing.mid")).unwrap_err().to_string();
    assert!(
        e.contains("missing.mid") && e.contains("cannot read"),
        "{e}"
    );
}
