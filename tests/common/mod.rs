//! Helpers shared by the integration tests (running the `tactus` binary, measuring signals).
#![allow(dead_code)] // each test binary uses a subset

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `tactus` binary under test.
pub fn tactus() -> Command {
    Command::new(env!("CARGO_BIN_EXE_tactus"))
}

/// A fresh, empty temporary folder unique to this test process and `name`.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tactus-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Asserts that a run succeeded, showing its stderr otherwise.
pub fn assert_ok(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The Hann-windowed discrete-time Fourier transform of `x` (its mean removed), sampled at
/// `fs` Hz: the power `|X(hz)|²` at any frequency.
pub struct Spectrum {
    windowed: Vec<f64>,
    fs: f64,
}

impl Spectrum {
    /// `x` sampled at `fs` Hz.
    pub fn new(x: &[f64], fs: f64) -> Self {
        let n = x.len() as f64;
        let m = x.iter().sum::<f64>() / n;
        let windowed = x
            .iter()
            .enumerate()
            .map(|(i, v)| (v - m) * (0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n).cos()))
            .collect();
        Spectrum { windowed, fs }
    }

    /// `|X(hz)|²`.
    pub fn power(&self, hz: f64) -> f64 {
        let (mut re, mut im) = (0.0, 0.0);
        for (i, v) in self.windowed.iter().enumerate() {
            let ph = 2.0 * std::f64::consts::PI * hz * i as f64 / self.fs;
            re += v * ph.cos();
            im -= v * ph.sin();
        }
        re * re + im * im
    }
}

/// Frequency of the strongest partial within ±10 % of `f` (Hz): the peak of the
/// Hann-windowed discrete-time Fourier transform, scanned in 0.5 Hz and then 0.01 Hz steps. For a periodic
/// signal whose fundamental is near `f`, this is the fundamental; for a free string, its
/// first mode. `fs`: the sample rate, Hz.
pub fn partial_hz(x: &[f64], f: f64, fs: f64) -> f64 {
    let spectrum = Spectrum::new(x, fs);
    let power = |hz: f64| spectrum.power(hz);
    // 0.5 Hz steps over ±10 %, then 0.01 Hz steps around the best.
    let scan = |from: f64, to: f64, step: f64| {
        let mut best = (from, f64::MIN);
        let mut hz = from;
        while hz <= to {
            let p = power(hz);
            if p > best.1 {
                best = (hz, p);
            }
            hz += step;
        }
        best.0
    };
    let coarse = scan(0.9 * f, 1.1 * f, 0.5);
    scan(coarse - 0.5, coarse + 0.5, 0.01)
}

/// A raised-cosine step from 0 to 1 between `t0` and `t1` (s): the smooth onsets of the pen
/// strokes the pen-instrument tests drive.
pub fn smooth_step(t: f64, t0: f64, t1: f64) -> f64 {
    let u = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    0.5 - 0.5 * (std::f64::consts::PI * u).cos()
}

/// Writes a format-0 MIDI file of `notes` (key, velocity, on s, off s) at 960 ticks per
/// second, with sustain-pedal changes `pedal` (time s, down).
pub fn write_midi(path: &Path, notes: &[(u8, u8, f64, f64)], pedal: &[(f64, bool)]) {
    use midly::num::{u15, u28, u4, u7};
    use midly::{Format, Header, MidiMessage, Smf, Timing, TrackEvent, TrackEventKind};
    let tick = |t: f64| (t * 960.0).round() as u64;
    let mut evs: Vec<(u64, MidiMessage)> = Vec::new();
    for &(key, vel, on, off) in notes {
        evs.push((
            tick(on),
            MidiMessage::NoteOn {
                key: u7::new(key),
                vel: u7::new(vel),
            },
        ));
        evs.push((
            tick(off),
            MidiMessage::NoteOff {
                key: u7::new(key),
                vel: u7::new(0),
            },
        ));
    }
    for &(t, down) in pedal {
        evs.push((
            tick(t),
            MidiMessage::Controller {
                controller: u7::new(64),
                value: u7::new(if down { 127 } else { 0 }),
            },
        ));
    }
    evs.sort_by_key(|e| e.0);
    let mut last = 0;
    let mut track: Vec<TrackEvent> = evs
        .into_iter()
        .map(|(t, message)| {
            let delta = u28::new((t - last) as u32);
            last = t;
            TrackEvent {
                delta,
                kind: TrackEventKind::Midi {
                    channel: u4::new(0),
                    message,
                },
            }
        })
        .collect();
    track.push(TrackEvent {
        delta: u28::new(0),
        kind: TrackEventKind::Meta(midly::MetaMessage::EndOfTrack),
    });
    Smf {
        header: Header::new(Format::SingleTrack, Timing::Metrical(u15::new(480))),
        tracks: vec![track],
    }
    .save(path)
    .unwrap();
}

/// A table's text with the timings (wall time and real-time factor) blanked: what must be
/// byte-identical between runs.
pub fn without_timings(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    match path.extension().and_then(|e| e.to_str()) {
        Some("csv") => {
            // The columns named `wall_s` and `rtf` in the header (no field of these rows
            // holds a comma).
            let head: Vec<&str> = text.lines().next().unwrap_or("").split(',').collect();
            let timed: Vec<usize> = (head.iter().enumerate())
                .filter(|(_, h)| ["wall_s", "rtf"].contains(h))
                .map(|(i, _)| i)
                .collect();
            text.lines()
                .map(|l| {
                    let mut f: Vec<&str> = l.split(',').collect();
                    if f.len() == head.len() && !l.starts_with("file,") {
                        timed.iter().for_each(|&i| f[i] = "-");
                    }
                    f.join(",")
                })
                .collect::<Vec<_>>()
                .join("\n")
        }
        _ => text
            .lines()
            .map(|l| match l.trim_start() {
                t if t.starts_with("\"wall_s\"") || t.starts_with("\"rtf\"") => "-",
                _ => l,
            })
            .collect::<Vec<_>>()
            .join("\n"),
    }
}

/// Writes `DIR/small.toml`: a layout of the grand piano on keys `first`–`last` (MIDI), one
/// program and few boards, for tests that need the firmware without grand88's 88 keys.
pub fn small_layout(dir: &Path, first: u8, last: u8) -> PathBuf {
    let path = dir.join("small.toml");
    std::fs::write(
        &path,
        format!(
            "name = \"small\"\n[[range]]\nkeys = [{first}, {last}]\ninstrument = \"grand_piano\"\n"
        ),
    )
    .unwrap();
    path
}
