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

/// The longest WAV [`write_wav`] writes, samples: as many 16-bit samples as fit, with the
/// 44-byte header, in the 4 GiB a RIFF file's 32-bit sizes can describe (13.5 hours at
/// 44.1 kHz). The rendering itself is streamed (`voice::Renderer`), in the memory of
/// [`WAV_BLOCK`] samples.
pub const MAX_WAV_SAMPLES: u64 = (u32::MAX as u64 - 44) / 2;

/// Samples rendered at a time.
pub const WAV_BLOCK: usize = 1 << 16;

/// Writes the strikes through the modal voice of `tactus_runtime::voice` as a 16-bit mono
/// WAV at the sample rate `fs` (Hz), normalised to 90 % of full scale. A strike's damper
/// falls at the note-off of the note it answers (300 ms after a strike that answers none),
/// or later while the sustain pedal is down. The rendering streams: once to find its peak,
/// once to write it, a block at a time, so a recital of any length (up to
/// [`MAX_WAV_SAMPLES`]) takes the memory of a block.
///
/// Errors: [`WriteError::Refused`] for a WAV longer than [`MAX_WAV_SAMPLES`] or costlier
/// than `voice::max_render_work`, or a sample rate that is not a whole number of hertz;
/// [`WriteError::Io`] when the file cannot be written.
pub fn write_wav(
    path: &Path,
    strikes: &[Strike],
    perf: &Performance,
    fs: f64,
) -> Result<(), WriteError> {
    let (notes, seconds) = voice_strikes(strikes, perf);
    let wanted = seconds * fs;
    if wanted.is_nan() || wanted > MAX_WAV_SAMPLES as f64 {
        return Err(WriteError::Refused {
            path: path.to_path_buf(),
            reason: format!(
                "the piece is {:.1} h long, more than the {:.1} h a WAV rendering may have (its 4 GiB); use --no-wav or --seconds",
                (seconds - 2.0) / 3600.0,
                (MAX_WAV_SAMPLES as f64 / fs - 2.0) / 3600.0
            ),
        });
    }
    let work = voice::render_work(&notes, seconds, fs);
    let most_work = voice::max_render_work(wanted);
    if work > most_work {
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
                most_work
            ),
        });
    }
    let mut block = Vec::with_capacity(WAV_BLOCK);
    let mut peak = 0f32;
    let mut r = voice::Renderer::new(&notes, seconds, fs);
    while r.next_block(WAV_BLOCK, &mut block) {
        peak = voice::peak(&block, peak);
    }
    let scale = voice::peak_scale(peak, 0.9);
    let mut r = voice::Renderer::new(&notes, seconds, fs);
    let mut at = 0;
    let samples = std::iter::from_fn(move || {
        if at == block.len() {
            at = 0;
            if !r.next_block(WAV_BLOCK, &mut block) {
                return None;
            }
        }
        at += 1;
        Some(voice::to_i16(block[at - 1], scale))
    });
    write_pcm(path, fs, samples)
}

/// The strikes as the voice renders them, each damper placed (at the note-off of the note
/// it answers, 300 ms after a strike that answers none, later while the sustain pedal is
/// down), and the seconds to render: to the later of the last strike and the performance's
/// end, and 2 s of ringing past it.
fn voice_strikes(strikes: &[Strike], perf: &Performance) -> (Vec<voice::Strike>, f64) {
    let notes = strikes
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
    (notes, last + 2.0)
}

/// Writes `samples` as a 16-bit mono WAV at `fs` Hz on `path`, as they come (the memory of
/// the writer's buffer). A file left half written by a failure (a full disk) is removed,
/// if it is a regular file.
///
/// Errors: `fs` not a whole number of hertz from 1 to `u32::MAX`, or the file cannot be
/// created or written (naming it, with the system's reason).
fn write_pcm(
    path: &Path,
    fs: f64,
    mut samples: impl Iterator<Item = i16>,
) -> Result<(), WriteError> {
    let rate = fs.round();
    if !(1.0..=f64::from(u32::MAX)).contains(&rate) || (fs - rate).abs() > 1e-9 * fs {
        return Err(WriteError::Refused {
            path: path.to_path_buf(),
            reason: format!("the sample rate {fs} Hz is not a whole number of hertz"),
        });
    }
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate as u32,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let err = |e: hound::Error| WriteError::io(path, e);
    let mut w = hound::WavWriter::create(path, spec).map_err(err)?;
    let written = samples
        .try_for_each(|x| w.write_sample(x))
        .and_then(|()| w.finalize());
    if written.is_err() && std::fs::symlink_metadata(path).is_ok_and(|m| m.is_file()) {
        let _ = std::fs::remove_file(path);
    }
    written.map_err(err)
}

/// Writes `samples` (any unit) as a 16-bit mono WAV at `fs` Hz, scaled so that the peak is
/// at 90 % of full scale (silence stays silence): `tactus sim`'s WAV, as [`write_wav`]'s.
///
/// Errors: `fs` not a whole number of hertz from 1 to `u32::MAX`, or the file cannot be
/// written (naming it).
pub fn write_mono_wav(path: &Path, samples: &[f32], fs: f64) -> Result<(), WriteError> {
    let scale = voice::i16_scale(samples, 0.9);
    write_pcm(path, fs, samples.iter().map(|&x| voice::to_i16(x, scale)))
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

#[cfg(test)]
mod tests {
    use super::*;
    use tactus_runtime::performance::Note;

    const FS: f64 = 44_100.0;

    /// A short performance played: chords and runs over 4 s, the pedal down from 1 s to
    /// 2.5 s, one strike answering no note.
    fn played() -> (Vec<Strike>, Performance) {
        let notes: Vec<Note> = (0..30)
            .map(|j| {
                let on_s = 0.13 * j as f64;
                Note {
                    key: 36 + (j * 17 % 60) as u8,
                    velocity: 20 + (j * 29 % 100) as u8,
                    on_s,
                    off_s: on_s + 0.05 + 0.04 * (j % 7) as f64,
                }
            })
            .collect();
        let mut strikes: Vec<Strike> = (notes.iter())
            .map(|n| Strike {
                key: n.key,
                time_s: n.on_s + 0.004,
                speed_mps: 0.3 + f64::from(n.velocity) / 30.0,
                answers: Some(*n),
            })
            .collect();
        strikes.push(Strike {
            key: 100,
            time_s: 3.9,
            speed_mps: 2.0,
            answers: None,
        });
        let perf = Performance {
            notes,
            sustain: vec![(1.0, true), (2.5, false)],
            duration_s: 4.0,
        };
        (strikes, perf)
    }

    /// A fresh folder for one test.
    fn temp(test: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("tactus-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// The WAV streamed in blocks (several of them here: 6 s, 4 blocks) is the file the
    /// whole buffer gives, byte for byte.
    #[test]
    fn the_streamed_wav_is_the_whole_renderings_file() {
        let (strikes, perf) = played();
        let dir = temp("streamed-wav");
        let (streamed, whole) = (dir.join("streamed.wav"), dir.join("whole.wav"));
        write_wav(&streamed, &strikes, &perf, FS).unwrap();
        let (notes, seconds) = voice_strikes(&strikes, &perf);
        let samples = voice::render(&notes, seconds, FS);
        assert_eq!(samples.len(), 264_600);
        assert!(samples.len() > 3 * WAV_BLOCK);
        write_mono_wav(&whole, &samples, FS).unwrap();
        let (a, b) = (
            std::fs::read(&streamed).unwrap(),
            std::fs::read(&whole).unwrap(),
        );
        assert_eq!(a.len(), 44 + 2 * samples.len());
        assert!(
            a == b,
            "the streamed WAV differs from the whole rendering's"
        );
        // Not silence: the loudest sample at 90 % of full scale.
        let pcm = a[44..].chunks(2).map(|c| i16::from_le_bytes([c[0], c[1]]));
        assert_eq!(pcm.map(|x| x.unsigned_abs()).max(), Some(29_490));
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A full disk and a folder that does not exist are errors naming the file; a WAV too
    /// long for its format is refused.
    #[test]
    fn a_wav_that_cannot_be_written_is_an_error_naming_it() {
        let (strikes, perf) = played();
        let full = Path::new("/dev/full");
        if full.exists() {
            let e = write_wav(full, &strikes, &perf, FS)
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("/dev/full: cannot write: "), "{e}");
            assert!(e.contains("No space left"), "{e}");
            assert!(full.exists(), "a device is never removed");
        }
        let dir = temp("unwritable-wav");
        // Past the 4 GiB of a RIFF file: refused before anything is written.
        let long = Performance {
            duration_s: 13.6 * 3600.0,
            ..perf.clone()
        };
        let wav = dir.join("long.wav");
        let e = write_wav(&wav, &strikes, &long, FS)
            .unwrap_err()
            .to_string();
        assert!(e.contains("13.6 h long, more than the 13.5 h"), "{e}");
        assert!(
            e.ends_with("use --no-wav or --seconds") && !wav.exists(),
            "{e}"
        );
        let nowhere = dir.join("no such folder").join("piece.wav");
        let e = write_wav(&nowhere, &strikes, &perf, FS)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(&format!("{}: cannot write: ", nowhere.display())),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
