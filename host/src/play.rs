//! One performance through a compiled keyboard, as `tactus play` runs it: read and cut the
//! performance, keep the notes on the keyboard's keys, play them
//! ([`tactus_firmware::play::play`]) and write the strikes (CSV, MIDI, WAV) and the traces
//! (CSV). The caller compiles the keyboard once ([`crate::keyboard::compile`], and
//! [`Keyboard::firmware`] when [`PlayConfig::needs_firmware`]) for a whole corpus, and
//! prints.

use crate::keyboard::Keyboard;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::Instant;
use tactus_firmware::image::Program as FirmwareProgram;
use tactus_firmware::play::{self, corpus::PieceRow, output, PlayConfig, Played, Progress};
use tactus_runtime::performance::{self, Note, Performance};

/// What to do with a piece besides playing it.
#[derive(Clone, Debug)]
pub struct PieceOptions {
    /// Play only the first seconds of the performance (a note still held then is released
    /// there).
    pub seconds: Option<f64>,
    /// The directory the files go to (created if missing).
    pub out: PathBuf,
    /// Whether to write the WAV rendering.
    pub wav: bool,
}

/// A piece played: what [`play_piece`] returns.
#[derive(Debug)]
pub struct Piece {
    /// The file stem of the performance (`demo` for the built-in one): the files' names.
    pub stem: String,
    /// The performance as played: the notes on the keyboard's keys, after the cut.
    pub perf: Performance,
    /// The notes on no key of the keyboard, left out.
    pub skipped: Vec<Note>,
    /// The name of each played program (`played.calibrations` is per program).
    pub program_names: Vec<String>,
    /// Each played key (MIDI) and its program.
    pub key_program: BTreeMap<u8, usize>,
    /// Every key of the keyboard (the firmware runs them all).
    pub keys: usize,
    /// What the play loop returned.
    pub played: Played,
    /// Strikes that answer a note within 50 ms.
    pub answering: usize,
    /// Wall-clock seconds of the play loop.
    pub wall_s: f64,
    /// The files written: the strikes' CSV, MIDI and WAV, then one CSV per traced key.
    pub written: Vec<PathBuf>,
}

/// What the force player's finger can do on one instrument: the range of hammer speeds
/// every key of it covers, and how many notes asked for more.
#[derive(Clone, Debug, PartialEq)]
pub struct FingerRange {
    /// The instrument as the layout names it.
    pub instrument: String,
    /// Its parameter sets among the played keys.
    pub sets: usize,
    /// The smallest and largest finger push calibrated, N.
    pub push_n: (f64, f64),
    /// The hammer speeds every set reaches, m/s: the largest of the sets' slowest and the
    /// smallest of their fastest.
    pub speed_mps: (f64, f64),
    /// Notes whose velocity asks a hammer speed outside their key's calibrated range
    /// ([`play::outside_calibration`]): played at the nearest end.
    pub outside: usize,
}

impl Piece {
    /// Per instrument the force player calibrated (none with the position player), in
    /// order of first program: what the finger can do ([`FingerRange`]).
    pub fn finger_ranges(&self) -> Vec<FingerRange> {
        let mut out: Vec<FingerRange> = Vec::new();
        for (pi, cal) in self.played.calibrations.iter().enumerate() {
            let Some(cal) = cal else { continue };
            let name = &self.program_names[pi];
            let l = cal.from_rest.levels();
            let (Some(first), Some(last)) = (l.first(), l.last()) else {
                continue;
            };
            let (a, b) = (first.2, last.2);
            let outside = self
                .perf
                .notes
                .iter()
                .filter(|n| self.key_program.get(&n.key) == Some(&pi))
                .filter(|n| {
                    play::outside_calibration(play::strike::speed_for_velocity(n.velocity), a, b)
                })
                .count();
            match out.iter_mut().find(|r| &r.instrument == name) {
                Some(r) => {
                    r.sets += 1;
                    r.push_n = (r.push_n.0.min(first.0), r.push_n.1.max(last.0));
                    r.speed_mps = (r.speed_mps.0.max(a), r.speed_mps.1.min(b));
                    r.outside += outside;
                }
                None => out.push(FingerRange {
                    instrument: name.clone(),
                    sets: 1,
                    push_n: (first.0, last.0),
                    speed_mps: (a, b),
                    outside,
                }),
            }
        }
        out
    }

    /// The piece's row of the corpus table, for the performance `file`.
    pub fn row(&self, file: &Path) -> PieceRow {
        let music_s = self.perf.duration_s;
        let mut row = PieceRow {
            file: file.to_path_buf(),
            music_s,
            notes: self.perf.notes.len(),
            strikes: self.played.strikes.len(),
            answering: self.answering,
            silent: self.played.silent.len(),
            wall_s: self.wall_s,
            rtf: music_s / self.wall_s.max(1e-9),
            ..PieceRow::default()
        };
        if let Some(r) = &self.played.boards {
            row.misses_per_board = r
                .boards
                .iter()
                .map(|b| b.misses.iter().map(|&m| u64::from(m)).sum())
                .collect();
            row.worst_core_cycles = r.boards.iter().flat_map(|b| b.max.iter().copied()).max();
            row.deadline_cycles = Some(r.deadline);
        }
        row
    }
}

/// Plays `performance` (a MIDI file; `None`: the built-in demo) on `kb` as `config` says and
/// writes its files to `opts.out`; `firmware` is [`Keyboard::firmware`] when
/// [`PlayConfig::needs_firmware`]. Warnings (a MIDI file's oddities, notes on no key,
/// traced keys never played) go to `warn` as they arise.
///
/// Errors, as messages naming the file: a MIDI file that cannot be read, no note in the
/// first `seconds`, no note on a key of the keyboard, a played key's instrument `play`
/// cannot move, and [`tactus_firmware::play::play`]'s and the writers' errors.
pub fn play_piece(
    kb: &Keyboard,
    firmware: Option<&[FirmwareProgram]>,
    performance: Option<&Path>,
    config: &PlayConfig,
    opts: &PieceOptions,
    warn: &mut dyn FnMut(String),
    progress: &dyn Progress,
) -> Result<Piece, String> {
    let name = || performance.map_or("the demo".to_string(), |p| p.display().to_string());
    let mut perf = match performance {
        Some(p) => {
            let (perf, warnings) =
                performance::read_midi_reporting(p).map_err(|e| e.to_string())?;
            warnings.into_iter().for_each(|w| warn(w.to_string()));
            perf
        }
        None => performance::demo(),
    };
    if let Some(s) = opts.seconds {
        perf.cut(s)?;
        if perf.notes.is_empty() {
            return Err(format!("{}: no note starts in the first {s} s", name()));
        }
    }
    let on_keyboard: BTreeSet<u8> = kb.keys.iter().map(|a| a.key).collect();
    let (inside, skipped): (Vec<Note>, Vec<Note>) = perf
        .notes
        .iter()
        .partition(|n| on_keyboard.contains(&n.key));
    for n in &skipped {
        warn(format!(
            "note {} at {:.3} s is on no key of the layout: skipped",
            n.key, n.on_s
        ));
    }
    if inside.is_empty() {
        let keys: Vec<u8> = on_keyboard.iter().copied().collect();
        return Err(format!(
            "{}: none of its {} notes is on a key of the layout (its keys: {}): nothing to play",
            name(),
            skipped.len(),
            tactus_firmware::verdict::key_ranges(&keys)
        ));
    }
    let perf = Performance {
        notes: inside,
        ..perf
    };
    let played_keys: BTreeSet<u8> = perf.notes.iter().map(|n| n.key).collect();
    for k in config.trace.keys.difference(&played_keys) {
        warn(format!(
            "traced key {k} is never played: it stays at rest, no trace written"
        ));
    }
    let keyboard = kb
        .played(&played_keys, firmware)
        .map_err(|e| e.to_string())?;
    let started = Instant::now();
    let played = play::play(&perf, &keyboard, config, progress)?;
    let wall_s = started.elapsed().as_secs_f64();

    let out = &opts.out;
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create `{}`: {e}", out.display()))?;
    let stem = performance
        .and_then(|p| p.file_stem())
        .map_or("demo".to_string(), |s| s.to_string_lossy().into_owned());
    let mut written = Vec::new();
    let csv = out.join(format!("{stem}-strikes.csv"));
    let answering = output::write_strikes_csv(&csv, &played.strikes)?;
    written.push(csv);
    let mid = out.join(format!("{stem}-strikes.mid"));
    output::write_midi(&mid, &played.strikes)?;
    written.push(mid);
    if opts.wav {
        let wav = out.join(format!("{stem}.wav"));
        output::write_wav(&wav, &played.strikes, &perf, kb.board.sample_rate_hz)?;
        written.push(wav);
    }
    if !played.traces.is_empty() {
        let from_firmware = config.engine == play::PlayEngine::Emu;
        written.extend(output::write_trace_csvs(
            out,
            &stem,
            &played.traces,
            from_firmware,
        )?);
    }
    Ok(Piece {
        stem,
        perf,
        skipped,
        program_names: keyboard.programs.iter().map(|p| p.name.clone()).collect(),
        key_program: keyboard.key_program.clone(),
        keys: keyboard.keys.len(),
        played,
        answering,
        wall_s,
        written,
    })
}
