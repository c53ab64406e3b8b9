//! `tactus play` on real input: the first 20 s of Maestro_1 (MAESTRO via miditok's test
//! files, in ../shared; the test says SKIPPED when it is absent).

mod common;
use common::{assert_ok, tactus, temp_dir};
use std::path::PathBuf;
use tactus_runtime::performance::read_midi;

/// One row of a strikes CSV: (key, time, speed, note_on, note_velocity).
type Row = (u8, f64, f64, Option<f64>, Option<u8>);

fn strikes(path: &PathBuf) -> Vec<Row> {
    let mut r = csv::Reader::from_path(path).unwrap();
    r.records()
        .map(|rec| {
            let rec = rec.unwrap();
            (
                rec[0].parse().unwrap(),
                rec[1].parse().unwrap(),
                rec[2].parse().unwrap(),
                rec[4].parse().ok(),
                rec[5].parse().ok(),
            )
        })
        .collect()
}

fn ranks(v: &[f64]) -> Vec<f64> {
    let mut idx: Vec<usize> = (0..v.len()).collect();
    idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
    let mut r = vec![0.0; v.len()];
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
            j += 1;
        }
        for k in i..=j {
            r[idx[k]] = (i + j) as f64 / 2.0;
        }
        i = j + 1;
    }
    r
}

fn spearman(a: &[f64], b: &[f64]) -> f64 {
    let (ra, rb) = (ranks(a), ranks(b));
    let n = a.len() as f64;
    let (ma, mb) = (ra.iter().sum::<f64>() / n, rb.iter().sum::<f64>() / n);
    let cov: f64 = ra.iter().zip(&rb).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = ra.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = rb.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

#[test]
fn maestro_1_first_20_s_one_strike_per_note() {
    let midi =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/performances/Maestro_1.mid");
    if !midi.exists() {
        eprintln!(
            "SKIPPED: {} is absent (the shared data folder must sit beside the repository)",
            midi.display()
        );
        return;
    }
    let dir = temp_dir("play-maestro");
    let out = tactus()
        .arg("play")
        .arg(&midi)
        .args(["--seconds", "20", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    let rows = strikes(&dir.join("Maestro_1-strikes.csv"));
    let perf = read_midi(&midi).unwrap();
    let notes: Vec<_> = perf.notes.iter().filter(|n| n.on_s < 20.0).collect();
    assert!(notes.len() > 50, "{} notes", notes.len());
    // Every note-on: exactly one strike on its key within 50 ms.
    let mut vin = Vec::new();
    let mut vout = Vec::new();
    for n in &notes {
        let hits: Vec<_> = rows
            .iter()
            .filter(|s| s.0 == n.key && (s.1 - n.on_s).abs() <= 0.050)
            .collect();
        assert_eq!(
            hits.len(),
            1,
            "note {} at {:.3} s: {} strikes",
            n.key,
            n.on_s,
            hits.len()
        );
        vin.push(n.velocity as f64);
        vout.push(hits[0].2);
    }
    // No strike without a note.
    assert!(
        rows.iter().all(|s| s.3.is_some()),
        "a strike answers no note"
    );
    assert_eq!(rows.len(), notes.len());
    let rho = spearman(&vin, &vout);
    eprintln!(
        "Maestro_1, 20 s: {} notes, {} strikes, Spearman {rho:.4}",
        notes.len(),
        rows.len()
    );
    assert!(rho >= 0.95, "Spearman rank correlation {rho}");
    // The MIDI output parses back with one note per strike.
    let back = read_midi(&dir.join("Maestro_1-strikes.mid")).unwrap();
    assert_eq!(back.notes.len(), rows.len());
}

#[test]
fn engines_agree_and_the_default_runs_without_arguments() {
    let dir = temp_dir("play-demo");
    let run = |engine: &str| {
        let out = tactus()
            .args(["play", "--seconds", "3", "--engine", engine, "--out"])
            .arg(&dir)
            .output()
            .unwrap();
        assert_ok(&out);
        std::fs::read_to_string(dir.join("demo-strikes.csv")).unwrap()
    };
    let (jit, interp) = (run("jit"), run("interp"));
    assert!(jit.lines().count() > 5, "{jit}");
    assert_eq!(
        jit, interp,
        "the JIT and the interpreter disagree on a strike"
    );
}

#[test]
fn bad_midi_is_a_clear_error() {
    let dir = temp_dir("play-bad");
    let f = dir.join("empty.mid");
    std::fs::write(&f, b"").unwrap();
    let out = tactus().arg("play").arg(&f).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("empty.mid") && !err.contains("panicked"),
        "{err}"
    );
}

#[test]
fn layouts_grade_keys_and_report_notes_outside() {
    let dir = temp_dir("play-layout");
    let layout = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("instruments/layouts/grand88.toml");
    let out = tactus()
        .args(["play", "--seconds", "3", "--layout"])
        .arg(&layout)
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    let rows = strikes(&dir.join("demo-strikes.csv"));
    assert!(
        !rows.is_empty() && rows.iter().all(|r| r.3.is_some()),
        "{rows:?}"
    );
    // A layout covering only 60–64: the demo's other notes are reported and skipped.
    let small = dir.join("small.toml");
    std::fs::write(
        &small,
        "name = \"small\"\n[[range]]\nkeys = [60, 64]\ninstrument = \"grand_piano\"\n",
    )
    .unwrap();
    let out = tactus()
        .args(["play", "--seconds", "3", "--layout"])
        .arg(&small)
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("on no key of the layout: skipped"), "{err}");
    assert!(strikes(&dir.join("demo-strikes.csv"))
        .iter()
        .all(|r| (60..=64).contains(&r.0)));
    // A broken layout names the file and the field.
    std::fs::write(
        &small,
        "name = \"small\"\n[[range]]\nkeys = [60, 64]\ninstrumnt = \"grand_piano\"\n",
    )
    .unwrap();
    let out = tactus()
        .args(["play", "--layout"])
        .arg(&small)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("small.toml") && err.contains("instrumnt"),
        "{err}"
    );
}
