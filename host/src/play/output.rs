//! The files of a played performance: the strikes as CSV (each with the note it answers),
//! as a standard MIDI file (velocities from the simulated hammer speed,
//! [`midi_velocity`]) and as a WAV rendering through the modal voice of
//! `tactus_runtime::voice`; the traced keys' samples as CSV. Errors name the file
//! ([`WriteError`]).

use super::run::Traces;
use super::strike::{midi_velocity, Strike};
use std::path::{Path, PathBuf};
use tactus_runtime::performance::Performance;
use tactus_runtime::voice;

/// A file of a played performance that was not written, naming it.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// The file (or its folder) cannot be created or written: the system's or the encoder's
    /// reason.
    #[error("{}: cannot write: {reason}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// Why, as the system or the encoder says it.
        reason: String,
    },
    /// Writing it would pass a bound of the writer (a WAV longer, or costlier to render,
    /// than [`tactus_runtime::voice`] allows; a sample rate that is not a whole number of
    /// hertz): nothing was written.
    #[error("{}: {reason}", path.display())]
    Refused {
        /// The file.
        path: PathBuf,
        /// The bound and what to do (`use --no-wav`).
        reason: String,
    },
}

impl WriteError {
    /// An I/O or encoder failure on `path`.
    pub fn io(path: &Path, reason: impl std::fmt::Display) -> WriteError {
        WriteError::Io {
            path: path.to_path_buf(),
            reason: reason.to_string(),
        }
    }
}

/// Writes the strikes through the modal voice of `tactus_runtime::voice` as a 16-bit mono
/// WAV at the sample rate `fs` (Hz), normalised to 90 % of full scale. A strike's damper
/// falls at the note-off of the note it answers (300 ms after a strike that answers none),
/// or later while the sustain pedal is down.
pub fn write_wav(
    path: &Path,
    strikes: &[Strike],
    perf: &Performance,
    fs: f64,
) -> Result<(), WriteError> {
    let notes: Vec<voice::Strike> = strikes
        .iter()
        .map(|s| voice::Strike {
            key: s.key,
            time_s: s.time_s,
            speed_mps: s.speed_mps,
            damp_s: voice::damper_time(
                s.answers.map_or(s.time_s + 0.3, |n| n.off_s),
                &perf.sustain,
            ),
        })
        .collect();
    let last = strikes
        .iter()
        .map(|s| s.time_s)
        .fold(perf.duration_s, f64::max);
    let wanted = (last + 2.0) * fs;
    if wanted.is_nan() || wanted > voice::MAX_RENDER_SAMPLES as f64 {
        return Err(WriteError::Refused {
            path: path.to_path_buf(),
            reason: format!(
                "the piece is {last:.1} s long, more than the {:.0} s a WAV rendering may have; use --no-wav or --seconds",
                voice::MAX_RENDER_SAMPLES as f64 / fs - 2.0
            ),
        });
    }
    let work = voice::render_work(&notes, last + 2.0, fs);
    if work > voice::MAX_RENDER_WORK {
        let most = (0..=127u8)
            .map(|k| (strikes.iter().filter(|s| s.key == k).count(), k))
            .max()
            .unwrap_or_default();
        return Err(WriteError::Refused {
            path: path.to_path_buf(),
            reason: format!(
                "{} strikes ({} of them on key {}) ring for {work:.2e} oscillator steps, more than the {:.1e} a WAV rendering may take; use --no-wav",
                strikes.len(),
                most.0,
                most.1,
                voice::MAX_RENDER_WORK
            ),
        });
    }
    let samples = voice::render(&notes, last + 2.0, fs);
    write_mono_wav(path, &samples, fs)
}

/// Writes `samples` (any unit) as a 16-bit mono WAV at `fs` Hz, scaled so that the peak is
/// at 90 % of full scale (silence stays silence): the one WAV writer of `tactus play` and
/// `tactus sim`.
///
/// Errors: `fs` not a whole number of hertz from 1 to `u32::MAX`, or the file cannot be
/// written (naming it).
pub fn write_mono_wav(path: &Path, samples: &[f32], fs: f64) -> Result<(), WriteError> {
    let rate = fs.round();
    if !(1.0..=f64::from(u32::MAX)).contains(&rate) || (fs - rate).abs() > 1e-9 * fs {
        return Err(WriteError::Refused {
            path: path.to_path_buf(),
            reason: format!("the sample rate {fs} Hz is not a whole number of hertz"),
        });
    }
    let scale = voice::i16_scale(samples, 0.9);
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate as u32,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let err = |e: hound::Error| WriteError::io(path, e);
    let mut w = hound::WavWriter::create(path, spec).map_err(err)?;
    for &x in samples {
        w.write_sample(voice::to_i16(x, scale)).map_err(err)?;
    }
    w.finalize().map_err(err)
}

/// Writes one CSV per traced key, `OUT/STEM-key<K>.csv`: time_s, key_travel_m, force_n,
/// hammer_pos_m, finger_force_n and, with `firmware` (rows from the firmware on the
/// emulated board), motor_current_a and dac_code. Returns the files written.
pub fn write_trace_csvs(
    out: &Path,
    stem: &str,
    traces: &Traces,
    firmware: bool,
) -> Result<Vec<PathBuf>, WriteError> {
    let mut wrote = Vec::new();
    let header = [
        "time_s",
        "key_travel_m",
        "force_n",
        "hammer_pos_m",
        "finger_force_n",
        "motor_current_a",
        "dac_code",
    ];
    // The motor current and DAC code only from the firmware.
    let columns = if firmware { 7 } else { 5 };
    for (key, rows) in traces {
        let path = out.join(format!("{stem}-key{key}.csv"));
        let err = |e: csv::Error| WriteError::io(&path, e);
        let mut w = csv::Writer::from_path(&path).map_err(err)?;
        w.write_record(&header[..columns]).map_err(err)?;
        for r in rows {
            w.write_record(r[..columns].iter().map(|v| v.to_string()))
                .map_err(err)?;
        }
        w.flush().map_err(|e| WriteError::io(&path, e))?;
        wrote.push(path);
    }
    Ok(wrote)
}

/// Writes one row per strike with the input note it answers; returns how many answer one.
pub fn write_strikes_csv(path: &Path, strikes: &[Strike]) -> Result<usize, WriteError> {
    let err = |e: csv::Error| WriteError::io(path, e);
    let mut w = csv::Writer::from_path(path).map_err(err)?;
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
    w.flush().map_err(|e| WriteError::io(path, e))?;
    Ok(matched)
}

/// Writes the strikes as a format-0 MIDI file (480 ticks per quarter at 120 bpm: 960 ticks
/// per second); each strike lasts until the note-off of the note it answers (300 ms for a
/// strike that answers none).
pub fn write_midi(path: &Path, strikes: &[Strike]) -> Result<(), WriteError> {
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
    smf.save(path).map_err(|e| WriteError::io(path, e))
}
