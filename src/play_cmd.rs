//! `tactus play`: a recorded performance played through an instrument, key by key, on the
//! host engines (the emulated-board engine comes with the firmware backend).
//!
//! Each played key runs its own instance of the instrument over its key trajectory (the
//! player model of `tactus_runtime::performance`), from 50 ms before its first press to
//! 500 ms after its last release; keys that are never played stay at rest and need no
//! simulation. Every `strike` the instrument emits becomes a note of the output MIDI file.

use crate::check_cmd::{compile_reporting, parse_override};
use crate::source;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;
use tactus_runtime::performance::{self, KeyTrack, Performance};

/// Arguments of `tactus play`.
#[derive(Debug, clap::Args)]
#[command(
    after_long_help = "Writes OUT/NAME-strikes.csv (one row per strike: key, time, hammer speed, MIDI velocity, \
the input note it answers) and OUT/NAME-strikes.mid (the strikes as MIDI with velocities from the simulated hammer \
speed: 1 at 0.1 m/s to 127 at 6 m/s, logarithmic). Example: tactus play ../shared/data/performances/Maestro_1.mid --seconds 20"
)]
pub struct PlayArgs {
    /// MIDI performance to play [default: a built-in 8 s demo].
    pub performance: Option<PathBuf>,
    /// Instrument on every key A0…C8 (file or built-in name) [default: grand_piano].
    #[arg(long, conflicts_with = "layout")]
    pub instrument: Option<String>,
    /// Keyboard layout (TOML): instruments and param grading per key range, e.g.
    /// instruments/layouts/grand88.toml.
    #[arg(long)]
    pub layout: Option<PathBuf>,
    /// Play only the first SECONDS of the performance.
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Engine: `jit` (cranelift, fast) or `interp` (the f64 reference interpreter).
    #[arg(long, value_enum, default_value = "jit")]
    pub engine: PlayEngine,
    /// Override a param on every key: `--param M_h=10 g`.
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_override)]
    pub params: Vec<(String, String)>,
    /// Output directory.
    #[arg(long, short, default_value = "out")]
    pub out: PathBuf,
}

/// Engines of `tactus play`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PlayEngine {
    /// Cranelift JIT (f64).
    Jit,
    /// The f64 reference interpreter.
    Interp,
}

/// A compiled instrument: (instrument name or path, overrides, program).
type Compiled = (String, Vec<(String, String)>, tactus_compiler::ir::Program);

/// One simulated hammer strike.
struct Strike {
    key: u8,
    time_s: f64,
    speed_mps: f64,
    /// The input note it answers: the note-on of its key nearest in time, if within 50 ms.
    answers: Option<performance::Note>,
}

/// MIDI velocity for a hammer speed: logarithmic, 0.1 m/s → 1, 6 m/s → 127.
pub fn midi_velocity(speed_mps: f64) -> u8 {
    let v = 1.0 + 126.0 * (speed_mps / 0.1).ln() / (6.0f64 / 0.1).ln();
    v.round().clamp(1.0, 127.0) as u8
}

/// Runs `tactus play`.
pub fn run(args: PlayArgs) -> ExitCode {
    match run_inner(&args) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run_inner(args: &PlayArgs) -> Result<ExitCode, String> {
    let mut perf = match &args.performance {
        Some(p) => performance::read_midi(p).map_err(|e| e.to_string())?,
        None => performance::demo(),
    };
    if let Some(s) = args.seconds {
        if !(s.is_finite() && s > 0.0) {
            return Err(format!("--seconds must be a positive number, got {s}"));
        }
        perf.notes.retain(|n| n.on_s < s);
        perf.duration_s = perf.duration_s.min(s);
    }
    // Which instrument (with which overrides) on which key.
    let assignments = match &args.layout {
        Some(l) => tactus_runtime::keyboard::read_layout(l)?.1,
        None => {
            let name = args
                .instrument
                .clone()
                .unwrap_or_else(|| "grand_piano".to_string());
            (21u8..=108)
                .map(|key| tactus_runtime::keyboard::KeyAssignment {
                    key,
                    instrument: name.clone(),
                    params: vec![],
                })
                .collect()
        }
    };
    let (inside, outside): (Vec<&performance::Note>, Vec<&performance::Note>) = perf
        .notes
        .iter()
        .partition(|n| assignments.iter().any(|a| a.key == n.key));
    for n in &outside {
        eprintln!(
            "warning: note {} at {:.3} s is on no key of the layout: skipped",
            n.key, n.on_s
        );
    }
    let perf = Performance {
        notes: inside.into_iter().copied().collect(),
        ..perf
    };
    // One compiled program per distinct (instrument, overrides), shared by its keys.
    let mut programs: Vec<Compiled> = Vec::new();
    let mut key_program = std::collections::BTreeMap::new();
    for a in assignments
        .iter()
        .filter(|a| perf.notes.iter().any(|n| n.key == a.key))
    {
        let mut params = a.params.clone();
        params.extend(args.params.iter().cloned());
        let idx = match programs
            .iter()
            .position(|(i, p, _)| *i == a.instrument && *p == params)
        {
            Some(i) => i,
            None => {
                let src = source::load(&a.instrument)?;
                let Some(lowered) = compile_reporting(&src, &params) else {
                    return Ok(ExitCode::FAILURE);
                };
                let program = lowered.program;
                if program.sensors.is_empty()
                    || !program
                        .events
                        .iter()
                        .any(|e| e.name == "strike" || e.name == "pluck")
                {
                    return Err(format!("instrument `{}` (key {}) has no sensor or emits no `strike`/`pluck` to play", program.name, a.key));
                }
                programs.push((a.instrument.clone(), params, program));
                programs.len() - 1
            }
        };
        key_program.insert(a.key, idx);
    }
    let jits = match args.engine {
        PlayEngine::Jit => programs
            .iter()
            .map(|(_, _, p)| {
                tactus_jit::JitProgram::compile(p)
                    .map(Some)
                    .map_err(|e| format!("JIT: {e}"))
            })
            .collect::<Result<Vec<_>, _>>()?,
        PlayEngine::Interp => programs.iter().map(|_| None).collect(),
    };
    let dip_of = |key: u8| programs[key_program[&key]].2.sensors[0].range.1;
    // Each played key's track, for its own instrument's key dip.
    let tracks: Vec<KeyTrack> = key_program
        .keys()
        .flat_map(|&key| {
            let notes = perf
                .notes
                .iter()
                .filter(|n| n.key == key)
                .copied()
                .collect();
            performance::key_tracks(
                &Performance {
                    notes,
                    sustain: vec![],
                    duration_s: perf.duration_s,
                },
                dip_of(key),
            )
        })
        .collect();
    let fs = programs
        .first()
        .map_or(tactus_runtime::DEFAULT_SAMPLE_RATE_HZ, |p| {
            p.2.sample_rate_hz
        });
    let total_samples: u64 = tracks.iter().map(|t| window(t, fs).1 as u64).sum();
    let bar = ProgressBar::new(total_samples);
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} {msg} [{bar:30}] {percent}% {per_sec} key-samples, eta {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_message(format!("{} keys", tracks.len()));
    let started = Instant::now();
    let mut strikes = Vec::new();
    for t in &tracks {
        let pi = key_program[&t.key];
        let program = &programs[pi].2;
        let strike_id = program
            .events
            .iter()
            .position(|e| e.name == "strike" || e.name == "pluck")
            .unwrap_or(0);
        let (first, n) = window(t, fs);
        let mut jit_inst = jits[pi].as_ref().map(tactus_jit::JitInstance::new);
        let mut interp = tactus_compiler::interp::Instance::new(program);
        for i in 0..n {
            let time = (first + i) as f64 / fs;
            let x = [t.position(time)];
            let out = match &mut jit_inst {
                Some(j) => j.step(&x),
                None => interp.step(&x),
            };
            for (e, a) in &out.events {
                if e.index() == strike_id {
                    strikes.push(Strike {
                        key: t.key,
                        time_s: time,
                        speed_mps: a.first().copied().unwrap_or(0.0),
                        answers: None,
                    });
                }
            }
        }
        bar.inc(n as u64);
    }
    bar.finish_and_clear();
    let wall = started.elapsed().as_secs_f64();
    strikes.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    for s in &mut strikes {
        s.answers = perf
            .notes
            .iter()
            .filter(|n| n.key == s.key)
            .min_by(|a, b| {
                (a.on_s - s.time_s)
                    .abs()
                    .total_cmp(&(b.on_s - s.time_s).abs())
            })
            .filter(|n| (n.on_s - s.time_s).abs() <= 0.050)
            .copied();
    }

    std::fs::create_dir_all(&args.out)
        .map_err(|e| format!("cannot create `{}`: {e}", args.out.display()))?;
    let stem = args
        .performance
        .as_ref()
        .and_then(|p| p.file_stem())
        .map_or("demo".to_string(), |s| s.to_string_lossy().into_owned());
    let csv = args.out.join(format!("{stem}-strikes.csv"));
    let matched = write_strikes_csv(&csv, &strikes)?;
    let mid = args.out.join(format!("{stem}-strikes.mid"));
    write_midi(&mid, &strikes)?;
    let audio_s = perf.duration_s;
    println!(
        "{}: {} notes on {} keys → {} strikes ({} answer a note within 50 ms); {} key-samples in {:.2} s ({:.1}× real time for the played keys)",
        stem,
        perf.notes.len(),
        tracks.len(),
        strikes.len(),
        matched,
        total_samples,
        wall,
        audio_s / wall.max(1e-9)
    );
    println!("  wrote {}\n  wrote {}", csv.display(), mid.display());
    println!("  budget: not checked — the emulated-board engine needs the Thumb backend (planned)");
    Ok(ExitCode::SUCCESS)
}

/// First sample and number of samples to simulate for a key.
fn window(t: &KeyTrack, fs: f64) -> (usize, usize) {
    let first = t.notes.first().map_or(0.0, |n| n.0) - performance::MAX_DESCENT_S - 0.05;
    let last = t.notes.last().map_or(0.0, |n| n.0);
    let end = t.last_move_end_s().max(last) + 0.5;
    let a = (first.max(0.0) * fs) as usize;
    (a, ((end * fs) as usize).saturating_sub(a))
}

/// Writes one row per strike with the input note it answers; returns how many answer one.
fn write_strikes_csv(path: &Path, strikes: &[Strike]) -> Result<usize, String> {
    let mut w = csv::Writer::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let err = |e: csv::Error| format!("{}: {e}", path.display());
    w.write_record([
        "key",
        "time_s",
        "hammer_speed_mps",
        "midi_velocity",
        "note_on_s",
        "note_velocity",
    ])
    .map_err(err)?;
    let mut matched = 0;
    for s in strikes {
        let (on, vel) = match s.answers {
            Some(n) => {
                matched += 1;
                (n.on_s.to_string(), n.velocity.to_string())
            }
            None => (String::new(), String::new()),
        };
        w.write_record([
            s.key.to_string(),
            s.time_s.to_string(),
            s.speed_mps.to_string(),
            midi_velocity(s.speed_mps).to_string(),
            on,
            vel,
        ])
        .map_err(err)?;
    }
    w.flush().map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(matched)
}

/// Writes the strikes as a format-0 MIDI file (480 ticks per quarter at 120 bpm: 960 ticks
/// per second); each strike lasts until the note-off of the note it answers (300 ms for a
/// strike that answers none).
fn write_midi(path: &Path, strikes: &[Strike]) -> Result<(), String> {
    use midly::num::{u15, u28, u4, u7};
    use midly::{Format, Header, MidiMessage, Smf, Timing, TrackEvent, TrackEventKind};
    let mut evs: Vec<(u64, bool, u8, u8)> = Vec::new();
    for s in strikes {
        let off = s.answers.map_or(s.time_s + 0.3, |n| n.off_s);
        let tick = |t: f64| (t * 960.0).round().max(0.0) as u64;
        evs.push((tick(s.time_s), true, s.key, midi_velocity(s.speed_mps)));
        evs.push((tick(off.max(s.time_s + 0.01)), false, s.key, 0));
    }
    evs.sort_by_key(|e| (e.0, e.1));
    let mut track = Vec::new();
    let mut last = 0u64;
    for (tick, on, key, vel) in evs {
        let delta = u28::new(((tick - last).min(0x0FFF_FFFF)) as u32);
        last = tick;
        let message = if on {
            MidiMessage::NoteOn {
                key: u7::new(key),
                vel: u7::new(vel),
            }
        } else {
            MidiMessage::NoteOff {
                key: u7::new(key),
                vel: u7::new(0),
            }
        };
        track.push(TrackEvent {
            delta,
            kind: TrackEventKind::Midi {
                channel: u4::new(0),
                message,
            },
        });
    }
    track.push(TrackEvent {
        delta: u28::new(0),
        kind: TrackEventKind::Meta(midly::MetaMessage::EndOfTrack),
    });
    let smf = Smf {
        header: Header::new(Format::SingleTrack, Timing::Metrical(u15::new(480))),
        tracks: vec![track],
    };
    smf.save(path)
        .map_err(|e| format!("{}: cannot write: {e}", path.display()))
}
