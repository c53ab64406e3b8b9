//! `tactus play`'s run: performances through a compiled keyboard. a [`Session`]
//! compiles the keyboard once for a whole corpus (and its firmware once, when the first
//! piece needs it); [`Session::play`] reads and cuts a performance, keeps the notes on the
//! keyboard's keys, plays them ([`crate::play::play`]) and writes the strikes
//! (CSV, MIDI, WAV), the traces (CSV, SVG) and the boards' cycles (SVG); [`Piece::report`]
//! and [`Piece::budget_report`] give what to print, [`Piece::row`] the corpus table's row.

use crate::keyboard::{Keyboard, KeyboardError, KeyboardSpec, Reporter};
use crate::play::output::{self, WriteError};
use crate::play::results::{sha3_hex, KeyboardManifest, RunOptions, SourceHash};
use crate::play::shard::Setup;
use crate::play::{self, corpus::PieceRow, strike, PlayConfig, PlayEngine, Played, Progress};
use crate::play::{BoardsReport, RunError, Silence, Traces};
use crate::plot::{plot_cycle_series, plot_lines, Line, PlotError};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::Instant;
use tactus_emulator::IoWindows;
use tactus_firmware::boards::KeyboardPlan;
use tactus_firmware::image::Program as FirmwareProgram;
use tactus_runtime::keyboard::BoardSpec;
use tactus_runtime::performance::{self, MidiError, Note, Performance};

/// Why a piece (or a session) cannot be played. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum PlayError {
    /// The keyboard cannot be made, or a played key's instrument cannot be played.
    #[error(transparent)]
    Keyboard(#[from] KeyboardError),
    /// The keyboard's firmware does not compile ([`Keyboard::firmware`]'s message; the same
    /// for every piece of a session, compiled once).
    #[error("{0}")]
    Firmware(String),
    /// The MIDI file cannot be read.
    #[error(transparent)]
    Midi(#[from] MidiError),
    /// `--seconds` is not a positive number.
    #[error("{0}")]
    Seconds(String),
    /// No note of the piece starts before the cut.
    #[error("{piece}: no note starts in the first {seconds} s")]
    NoNoteBeforeCut {
        /// The piece (its path, or `the demo`).
        piece: String,
        /// Where it was cut, s.
        seconds: f64,
    },
    /// No note of the piece is on a key of the keyboard.
    #[error("{piece}: none of its {notes} notes is on a key of the layout (its keys: {keys}): nothing to play")]
    NoNoteOnKeyboard {
        /// The piece (its path, or `the demo`).
        piece: String,
        /// Its notes.
        notes: usize,
        /// The keyboard's keys, as ranges.
        keys: String,
    },
    /// The play loop refused or failed (an instrument it cannot move, a firmware fault).
    #[error(transparent)]
    Run(#[from] RunError),
    /// A file of the piece cannot be written.
    #[error(transparent)]
    Write(#[from] WriteError),
    /// A plot of the piece cannot be drawn or written.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// The files [`Session::play`] writes for a piece, as `tactus play --help` explains them.
pub const FILES_HELP: &str = "Writes OUT/NAME-strikes.csv (one row per strike: key, time, hammer speed, MIDI velocity, \
the input note it answers), OUT/NAME-strikes.mid (the strikes as MIDI with velocities from the simulated hammer \
speed: 52 + 25·log2(speed in m/s), the Bösendorfer SE's convention, so 1 at 0.24 m/s, 52 at 1 m/s, 127 at 8 m/s) and OUT/NAME.wav (the strikes through a synthesized modal \
piano voice, 44.1 kHz 16-bit mono, normalised). With --trace-keys: OUT/NAME-key<K>.csv per traced key (time, key \
travel, instrument force, hammer position, finger force), OUT/NAME-force.svg, OUT/NAME-key.svg and OUT/NAME-hammer.svg; \
with --engine emu the force is the firmware's force word (before the safety limiter), the hammer its hammer_pos \
output word, every sample of the trace window (the emulated keys run all the time), and two more columns: \
motor_current_a (the current the firmware's safety limiter allowed) and dac_code (the word it wrote to the DAC). \
Example: tactus play ../shared/data/performances/Maestro_1.mid --seconds 20 --trace-keys 60,64";

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

/// A piece played: what [`Session::play`] returns.
#[derive(Debug)]
pub struct Piece {
    /// The player that moved the keys.
    pub player: play::Player,
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
    /// The sample rate it was played at (the board's), Hz.
    pub fs: f64,
    /// The files written: the strikes' CSV, MIDI and WAV, one CSV per traced key and the
    /// traces' plots, and with the emulated boards the plot of their cycles per sample and
    /// their fault records (`NAME-faults.csv`, `crate::fault::csv_text`).
    pub written: Vec<PathBuf>,
    /// Faults injected (`--fault`): with none, a trip of the firmware's checks is a false
    /// alarm ([`Piece::budget_report`]'s error).
    pub faults_injected: usize,
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

/// What `play` says after a board that did not boot again after a reset.
const RAM_RESET: &str = "(play runs each board's RAM image: after a watchdog reset the boot \
     ROM enters it again, its data restored, but a brown-out clears SRAM and the image with \
     it, and the boot ROM then waits in USB boot: the board stays at zero force to the end \
     of the run; the flash image `tactus build` writes boots from flash again: `tactus emu \
     run`)";

impl Piece {
    /// What to print of the boards' budget over the run ([`budget_text`], or a line saying
    /// a host engine checks none) and of their fault records ([`crate::fault::report_lines`]),
    /// and the error when a core missed a deadline or, with no fault injected, a fault check
    /// tripped (a false alarm).
    pub fn budget_report(&self) -> (String, Option<String>) {
        match &self.played.boards {
            None => (
                "  budget: not checked (host engine; `--engine emu` runs the firmware on the emulated board)\n".to_string(),
                None,
            ),
            Some(r) => {
                let mut text = budget_text(r) + &spans_text(&self.played.spans);
                let faults = r.faults();
                let mut lines = crate::fault::report_lines(&faults, self.fs);
                let summary = lines.pop().unwrap_or_default();
                // The resets (the watchdog's, a brown-out's) with the fault words: when, and
                // what the board did after.
                let mut dead = false;
                for b in &faults {
                    for reset in &b.resets {
                        dead |= reset.reboot.is_err();
                        let text = crate::fault::reset_text(reset, self.fs);
                        lines.push(format!("board {}: {text}", b.board));
                    }
                }
                if dead {
                    lines.push(RAM_RESET.to_string());
                }
                lines.push(summary);
                for line in lines {
                    text.push_str(&format!("  {line}\n"));
                }
                let trips = r.fault_trips();
                let resets: usize = faults.iter().map(|b| b.resets.len()).sum();
                let error = if r.missed() {
                    Some("the firmware missed sample deadlines: some board's keys do not fit it (see `tactus budget`)".to_string())
                } else if (trips > 0 || resets > 0) && self.faults_injected == 0 {
                    Some(format!(
                        "with no fault injected the firmware's fault checks tripped {trips} times and {resets} boards reset: a false alarm (see the faults above)"
                    ))
                } else {
                    None
                };
                (text, error)
            }
        }
    }

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

    /// What the piece says, as `tactus play` prints it: the lines (notes, keys, strikes and
    /// silent notes; key-samples, wall time and real-time factor; per instrument the force
    /// player's range; re-struck notes; the budget of the run on the emulated boards) and
    /// the warnings (notes without a strike, notes not placed as recorded, notes left out).
    pub fn report(&self) -> (Vec<String>, Vec<String>) {
        let (played, perf) = (&self.played, &self.perf);
        let (mut lines, mut warnings) = (Vec::new(), Vec::new());
        let plural = |n: usize| if n == 1 { "" } else { "s" };
        // Notes no strike answers: the instrument did not sound them.
        let silent = &played.silent;
        let too_soft = silent
            .iter()
            .filter(|s| s.cause == Silence::TooSoft)
            .count();
        for s in silent.iter().filter(|s| s.cause == Silence::Other).take(10) {
            warnings.push(format!(
                "note {} at {:.3} s (velocity {}{}) produced no strike within 50 ms",
                s.note.key,
                s.note.on_s,
                s.note.velocity,
                s.since_previous_s.map_or(String::new(), |d| format!(
                    ", {:.0} ms after the key's last note-on",
                    d * 1e3
                ))
            ));
        }
        if silent.len() - too_soft > 10 {
            warnings.push(format!(
                "… and {} more notes without a strike",
                silent.len() - too_soft - 10
            ));
        }
        // A hang on a key standing still waits for it to move (the quiescent-key guard).
        warnings.extend(played.resting_hangs.iter().map(|h| h.warning()));
        let force = self.player == play::Player::Force;
        let skipped = self.skipped.len();
        lines.push(format!(
            "{}: {} notes on {} keys ({} player) → {} strikes ({} answer a note within 50 ms; {} note{} without a strike{}); {} note{} outside the layout skipped",
            self.stem,
            perf.notes.len(),
            self.key_program.len(),
            if force { "force" } else { "position" },
            played.strikes.len(),
            self.answering,
            silent.len(),
            plural(silent.len()),
            match force && !silent.is_empty() {
                true => format!(
                    ": {too_soft} too soft to reach the string, below the calibrated minimum; {} other",
                    silent.len() - too_soft
                ),
                false => String::new(),
            },
            skipped,
            plural(skipped),
        ));
        let (once, more, most) = strike::per_note(&played.strikes);
        let stray = played.strikes.len().saturating_sub(self.answering);
        lines.push(format!(
            "  strikes per note: {once} note{} struck once, {more} struck more than once{}; {stray} strike{} answer{} no note{}",
            plural(once),
            match more {
                0 => String::new(),
                _ => format!(
                    " (at most {most} strikes; a key that re-struck its string under one note)"
                ),
            },
            plural(stray),
            if stray == 1 { "s" } else { "" },
            match stray {
                0 => String::new(),
                _ => " (more than 50 ms from every note-on of its key: a second blow under a held note, or a note struck early or late)".to_string(),
            },
        ));
        let (audio_s, wall) = (perf.duration_s, self.wall_s);
        lines.push(format!(
            "  {} key-samples in {wall:.2} s: real-time factor {:.2} ({audio_s:.2} s of music; above 1 is faster than real time); peak memory {}",
            played.key_samples,
            audio_s / wall.max(1e-9),
            peak_memory_kb().map_or("unknown".to_string(), |kb| format!("{:.1} MB", kb as f64 / 1024.0)),
        ));
        // What the finger can do on each instrument, and how many notes asked for more.
        for r in self.finger_ranges() {
            let ((push_lo, push_hi), (lo, hi)) = (r.push_n, r.speed_mps);
            lines.push(format!(
                "  force player on `{}`{}: finger pushes {push_lo:.2}–{push_hi:.1} N give hammer speeds {lo:.2}–{hi:.2} m/s on every key (MIDI {}–{}); {} note{} outside its key's range played at its nearest end",
                r.instrument,
                if r.sets > 1 { format!(" ({} parameter sets)", r.sets) } else { String::new() },
                strike::midi_velocity(lo),
                strike::midi_velocity(hi),
                r.outside,
                plural(r.outside),
            ));
        }
        // Notes the players could not play as recorded: said, not silently distorted.
        let mut rushed = played.rushed.clone();
        rushed.sort_by(|a, b| a.1.on_s.total_cmp(&b.1.on_s));
        for (key, r) in rushed.iter().take(5) {
            warnings.push(format!(
                "note {key} at {:.3} s (velocity {}) could not be placed as recorded: pressed in {:.1} ms where its velocity asks {:.1} ms{} ({})",
                r.on_s,
                r.velocity,
                r.pressed_s * 1e3,
                r.wanted_s * 1e3,
                if r.late_s > 1e-4 { format!(", reaching the bottom {:.1} ms late", r.late_s * 1e3) } else { String::new() },
                if r.on_s < r.wanted_s { "the piece starts too soon after it" } else { "the key was still moving for the previous note" }
            ));
        }
        if rushed.len() > 5 {
            warnings.push(format!(
                "… {} notes in all could not be placed as recorded (pressed faster or late: louder, or late, than the recording)",
                rushed.len()
            ));
        }
        let r = played.restrikes;
        if r.dropped > 0 {
            warnings.push(format!(
                "{} note{} left out: the key was still busy with earlier notes of a repetition past the note-on and the end of the piece",
                r.dropped,
                plural(r.dropped)
            ));
        }
        if r.restrikes > 0 || r.late > 0 {
            lines.push(format!(
                "  force player: {} notes re-struck before their key was back at rest, {} of them with no time for the asked softness, played louder; {} notes started late (no calibrated push fit before the note-on)",
                r.restrikes, r.raised, r.late
            ));
        }
        (lines, warnings)
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
            row.fault_trips = Some(r.fault_trips());
            row.faults_injected = self.faults_injected;
        }
        row
    }
}

/// What every piece of a `tactus play` run is played on and with: the keyboard compiled
/// once, its firmware (compiled once, when the first piece that needs it gets past its own
/// checks: a bad performance fails before the long compilation), the run's configuration
/// and options.
pub struct Session {
    /// The keyboard.
    pub kb: Keyboard,
    /// Its firmware's programs or why they do not compile, once tried
    /// ([`PlayConfig::needs_firmware`]): a corpus tries once, not once per piece.
    firmware: std::cell::OnceCell<Result<Vec<FirmwareProgram>, String>>,
    /// The keyboard's boards ([`Keyboard::plan`]) or why they cannot be planned, once tried
    /// (on emulated boards only).
    plan: std::cell::OnceCell<Result<KeyboardPlan, String>>,
    /// The run's configuration (its board is the keyboard's).
    pub config: PlayConfig,
    /// What to do with each piece besides playing it.
    pub opts: PieceOptions,
}

impl Session {
    /// Compiles the keyboard of `spec` as `tactus budget` and `tactus build` do (every
    /// program for its board's sample rate; diagnostics to `report`) and makes the run's
    /// configuration from its board (`config`).
    ///
    /// Errors: [`PlayError::Keyboard`], what [`crate::keyboard::compile`] reports.
    pub fn new(
        spec: &KeyboardSpec,
        config: impl FnOnce(BoardSpec) -> PlayConfig,
        opts: PieceOptions,
        report: &mut Reporter,
    ) -> Result<Session, PlayError> {
        let mut kb = crate::keyboard::compile(spec, report)?;
        let config = config(kb.board.clone());
        kb.sensor_check = config.sensor_check;
        kb.watchdog = config.watchdog;
        Ok(Session {
            kb,
            firmware: std::cell::OnceCell::new(),
            plan: std::cell::OnceCell::new(),
            config,
            opts,
        })
    }

    /// The options of this session that change a corpus's results (the manifest's).
    pub fn run_options(&self) -> RunOptions {
        RunOptions {
            engine: format!("{:?}", self.config.engine).to_lowercase(),
            player: format!("{:?}", self.config.player).to_lowercase(),
            seconds: self.opts.seconds,
            params: self.kb.overrides.clone(),
            quiescent_guard: self.config.quiescent_guard,
            sensor_check: self.config.sensor_check,
            watchdog: self.config.watchdog,
        }
    }

    /// This keyboard's entry of a corpus run's manifest: the SHA3-256 of its layout, board
    /// file and instrument sources and, when the engine runs them, of its firmware's
    /// programs (each distinct program's Thumb code and param block, in the order of
    /// [`Keyboard::sets`], with the program of every key) — compiled here if not yet.
    /// `on` is the command line's naming of the keyboard and board, recorded as given.
    ///
    /// Errors: the layout or board file cannot be read again.
    pub fn manifest(&self, on: &Setup) -> Result<KeyboardManifest, PlayError> {
        let kb = &self.kb;
        let hash = |name: String, text: &str| SourceHash {
            name,
            sha3: sha3_hex(text.as_bytes()),
        };
        let unreadable = |e: String| PlayError::Keyboard(KeyboardError::Input(e));
        let layout_sha3 = match &kb.layout {
            None => None,
            Some((_, path)) if path.as_os_str().is_empty() => crate::catalogue::layout(&kb.input)
                .map(|t| hash(format!("builtin:{}", kb.input), t)),
            Some((_, path)) => {
                let text = tactus_runtime::keyboard::read_text(path).map_err(unreadable)?;
                Some(hash(path.display().to_string(), &text))
            }
        };
        let board_src = crate::catalogue::board_source(&kb.kind).map_err(unreadable)?;
        let mut instruments: Vec<SourceHash> = Vec::new();
        // Every file of each instrument's program (the instrument and what it imports, the
        // built-in library included), once each: a change to an imported component changes
        // the manifest as a change to the instrument does.
        for set in &kb.sets {
            for f in set.source.linked.sources.files() {
                if !instruments.iter().any(|i| i.name == f.name) {
                    instruments.push(hash(f.name.clone(), &f.text));
                }
            }
        }
        let firmware_sha3 = match self.firmware() {
            Ok(None) => None,
            Ok(Some(programs)) => {
                let mut bytes = Vec::new();
                for p in programs {
                    bytes.extend((p.thumb.code.text.len() as u64).to_le_bytes());
                    bytes.extend(&p.thumb.code.text);
                    bytes.extend((p.params.len() as u64).to_le_bytes());
                    bytes.extend(p.params.iter().flat_map(|w| w.to_le_bytes()));
                }
                bytes.extend(kb.key_set.iter().flat_map(|&i| (i as u64).to_le_bytes()));
                Some(Ok(sha3_hex(&bytes)))
            }
            Err(e) => Some(Err(e.to_string())),
        };
        Ok(KeyboardManifest {
            on: on.clone(),
            name: kb.name.clone(),
            layout_sha3,
            board_sha3: hash(board_src.name, &board_src.text),
            instruments,
            firmware_sha3,
        })
    }

    /// The firmware's programs when the engine runs them ([`Keyboard::firmware`], compiled
    /// on the first call; its failure, too, is kept).
    fn firmware(&self) -> Result<Option<&[FirmwareProgram]>, PlayError> {
        if !self.config.needs_firmware() {
            return Ok(None);
        }
        let compiled = self
            .firmware
            .get_or_init(|| self.kb.firmware().map_err(|e| e.to_string()));
        match compiled {
            Ok(programs) => Ok(Some(programs)),
            Err(e) => Err(PlayError::Firmware(e.clone())),
        }
    }

    /// The keyboard's boards when the engine runs them on emulated boards ([`Keyboard::plan`]
    /// over [`Session::firmware`]'s programs, planned on the first call; its failure, too, is
    /// kept).
    fn plan(&self) -> Result<Option<&KeyboardPlan>, PlayError> {
        let Some(programs) = self
            .firmware()?
            .filter(|_| self.config.engine == PlayEngine::Emu)
        else {
            return Ok(None);
        };
        let planned = self
            .plan
            .get_or_init(|| (self.kb.plan(programs, &mut |_, _| {})).map_err(|e| e.to_string()));
        match planned {
            Ok(plan) => Ok(Some(plan)),
            Err(e) => Err(PlayError::Firmware(e.clone())),
        }
    }

    /// Plays `performance` (a MIDI file; `None`: the built-in demo) on the keyboard and
    /// writes its files to `opts.out`. Warnings (a MIDI file's oddities, notes on no key,
    /// traced keys never played) go to `warn` as they arise.
    ///
    /// Errors, naming the file: [`PlayError::Midi`] for a MIDI file that cannot be read,
    /// [`PlayError::Seconds`] for a `seconds` that is not positive,
    /// [`PlayError::NoNoteBeforeCut`] and [`PlayError::NoNoteOnKeyboard`] for nothing to play;
    /// [`PlayError::Keyboard`] for a played key's instrument `play` cannot move;
    /// [`PlayError::Firmware`] for firmware that does not compile;
    /// [`PlayError::Run`] for [`crate::play::play`]'s errors; [`PlayError::Write`] and
    /// [`PlayError::Plot`] for a file that cannot be written.
    pub fn play(
        &self,
        performance: Option<&Path>,
        warn: &mut dyn FnMut(String),
        progress: &dyn Progress,
    ) -> Result<Piece, PlayError> {
        let (kb, config, opts) = (&self.kb, &self.config, &self.opts);
        let name = || performance.map_or("the demo".to_string(), |p| p.display().to_string());
        let mut perf = match performance {
            Some(p) => {
                let (perf, warnings) = performance::read_midi_reporting(p)?;
                warnings.into_iter().for_each(|w| warn(w.to_string()));
                perf
            }
            None => performance::demo(),
        };
        if let Some(s) = opts.seconds {
            perf.cut(s).map_err(PlayError::Seconds)?;
            if perf.notes.is_empty() {
                return Err(PlayError::NoNoteBeforeCut {
                    piece: name(),
                    seconds: s,
                });
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
            return Err(PlayError::NoNoteOnKeyboard {
                piece: name(),
                notes: skipped.len(),
                keys: tactus_firmware::verdict::key_ranges(&keys),
            });
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
        let keyboard = kb.played(&played_keys, self.firmware()?, self.plan()?)?;
        let started = Instant::now();
        let played = play::play(&perf, &keyboard, config, progress)?;
        let wall_s = started.elapsed().as_secs_f64();

        let out = &opts.out;
        std::fs::create_dir_all(out).map_err(|e| WriteError::io(out, e))?;
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
            written.extend(plot_play_traces(out, &stem, &played.traces)?);
        }
        if let Some(r) = &played.boards {
            let svg = out.join(format!("{stem}-cycles.svg"));
            plot_play_cycles(r, &stem, &svg)?;
            written.push(svg);
            let csv = out.join(format!("{stem}-faults.csv"));
            let text = crate::fault::csv_text(&r.faults(), kb.board.sample_rate_hz);
            std::fs::write(&csv, text).map_err(|e| WriteError::io(&csv, e))?;
            written.push(csv);
        }
        Ok(Piece {
            player: config.player,
            stem,
            perf,
            skipped,
            program_names: keyboard.programs.iter().map(|p| p.name.clone()).collect(),
            key_program: keyboard.key_program.clone(),
            keys: keyboard.keys.len(),
            played,
            answering,
            wall_s,
            fs: kb.board.sample_rate_hz,
            written,
            faults_injected: config.faults.len(),
        })
    }
}

/// The budget of a run on the emulated boards as text: a header, then per board and core
/// the keys, the largest and mean cycles per sample, the static bound, the headroom and the
/// deadline misses, and the share of board-samples the rest replay gave. Lines end in `\n`.
pub fn budget_text(r: &BoardsReport) -> String {
    let mut s = format!(
        "  budget of the run on {} {} boards ({} cycles per sample per core; every key of every board every sample):\n",
        r.boards.len(),
        r.board,
        r.deadline
    );
    for (i, b) in r.boards.iter().enumerate() {
        let cores: Vec<String> = (0..b.max.len())
            .map(|c| {
                format!(
                    "core {c}: {} keys, max {} cycles per sample ({:.1} %, static {}, mean {:.1} %), headroom {}, deadline misses {}{}",
                    b.core_keys[c],
                    b.max[c],
                    100.0 * b.max[c] as f64 / r.deadline as f64,
                    b.bound[c],
                    100.0 * b.total[c] as f64 / (r.samples.max(1) * r.deadline) as f64,
                    r.deadline as i64 - b.max[c] as i64,
                    b.misses[c],
                    crate::fault::unfinished_text(b.unfinished.get(c).copied().unwrap_or(0)),
                )
            })
            .collect();
        s.push_str(&format!(
            "    board {} (keys {}): {}\n",
            i + 1,
            tactus_firmware::verdict::key_ranges(&b.keys),
            cores.join("; ")
        ));
    }
    let given: u64 = r.boards.iter().map(|b| b.rest_replayed.0).sum();
    if given > 0 {
        let all = r.samples * r.boards.len() as u64;
        s.push_str(&format!(
            "  rest replay: {given} of {all} board-samples ({:.1} %) given from recordings of boards at rest, the same results exactly (`--no-rest-replay` emulates them)\n",
            100.0 * given as f64 / all.max(1) as f64
        ));
    }
    let io = (r.boards.iter()).fold(IoWindows::default(), |a, b| a + b.io_windows);
    let undone = io.waited + io.stale + io.reach;
    if io.kept + undone > 0 {
        s.push_str(&format!(
            "  converters' I/O: {} windows replayed against the cores' accesses ({} given by the period memo, which recorded {} and took {} from other boards' recordings; {} of its hits by a plan), {undone} undone and run in lock-step ({} a core waited for the DMA, {} a load stale, {} a register store)\n",
            io.kept + undone,
            io.memo_hits,
            io.memo_recorded,
            io.memo_shared,
            io.memo_planned,
            io.waited,
            io.stale,
            io.reach
        ));
        // The parts' timing against their data sheets (`tactus_emulator::converters`).
        let breaches: Vec<(usize, &String)> = (r.boards.iter().enumerate())
            .flat_map(|(b, run)| run.io_breaches.iter().map(move |w| (b + 1, w)))
            .collect();
        match breaches.first() {
            None => s.push_str("  converters' timing against their data sheets: no breach\n"),
            Some((b, w)) => s.push_str(&format!(
                "  converters' timing against their data sheets: {} breaches (the first: board {b}, {w})\n",
                breaches.len()
            )),
        }
    }
    s
}

/// The budget of each span of a run played in spans (`PlayConfig::span`): per span a line
/// giving its first and last samples and times, then its [`budget_text`]; empty without
/// spans. The times are the performance's (each report's [`BoardsReport::timeline`]).
pub fn spans_text(spans: &[(u64, BoardsReport)]) -> String {
    let mut s = String::new();
    for (k, (from, r)) in spans.iter().enumerate() {
        let to = from + r.samples;
        s.push_str(&format!(
            "  span {} of {}: samples {from}–{to} ({:.3}–{:.3} s)\n",
            k + 1,
            spans.len(),
            r.timeline.sample_to_performance_s(*from),
            r.timeline.sample_to_performance_s(to)
        ));
        s.push_str(&budget_text(r));
    }
    s
}

/// Peak resident memory of this process (`VmHWM` of `/proc/self/status`), kB; `None` where
/// there is no such file (not Linux).
pub fn peak_memory_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Plots the cycles per sample of the busier core of each board (beyond eight boards, the
/// busiest and the mean of all) against the deadline, in the performance's time (from
/// before its 0 s with a lead-in: [`BoardsReport::timeline`]).
fn plot_play_cycles(r: &BoardsReport, stem: &str, path: &Path) -> Result<(), PlotError> {
    let named: Vec<(String, Vec<u64>)> = if r.boards.len() <= 8 {
        r.boards
            .iter()
            .enumerate()
            .map(|(i, b)| {
                (
                    format!(
                        "board {} ({})",
                        i + 1,
                        tactus_firmware::verdict::key_ranges(&b.keys)
                    ),
                    b.cycles.clone(),
                )
            })
            .collect()
    } else {
        let n = r.boards.iter().map(|b| b.cycles.len()).max().unwrap_or(0);
        let at = |i: usize| {
            r.boards
                .iter()
                .filter_map(move |b| b.cycles.get(i).copied())
        };
        vec![
            (
                format!("busiest of {} boards", r.boards.len()),
                (0..n).map(|i| at(i).max().unwrap_or(0)).collect(),
            ),
            (
                "mean of the boards".to_string(),
                (0..n)
                    .map(|i| at(i).sum::<u64>() / r.boards.len().max(1) as u64)
                    .collect(),
            ),
        ]
    };
    let series: Vec<(String, &[u64])> = named
        .iter()
        .map(|(l, v)| (l.clone(), v.as_slice()))
        .collect();
    plot_cycle_series(
        &series,
        r.timeline.fs / r.decimation as f64,
        r.timeline.sample_to_performance_s(0),
        r.deadline,
        &format!(
            "{stem}: cycles per sample, busier core of each board (max per {} samples)",
            r.decimation
        ),
        path,
    )
}

/// Plots the traces: `STEM-force.svg` (instrument force, and the finger's with the force
/// player, vs time), `STEM-key.svg` (key travel vs time) and `STEM-hammer.svg` (hammer
/// position vs time); returns the files written.
fn plot_play_traces(out: &Path, stem: &str, traces: &Traces) -> Result<Vec<PathBuf>, PlotError> {
    let mut wrote = Vec::new();
    let lines = |col: usize, scale: f64| -> Vec<Line> {
        traces
            .iter()
            .map(|(key, rows)| {
                // A break (NaN) where the key rested unsimulated between two stretches.
                let (mut x, mut y) = (Vec::new(), Vec::new());
                for (i, r) in rows.iter().enumerate() {
                    if i > 0 && r[0] - rows[i - 1][0] > 1e-3 {
                        x.push(f64::NAN);
                        y.push(f64::NAN);
                    }
                    x.push(r[0]);
                    y.push(r[col] * scale);
                }
                Line {
                    label: format!("key {key}"),
                    x,
                    y,
                }
            })
            .collect()
    };
    let force = out.join(format!("{stem}-force.svg"));
    let mut force_lines = lines(2, 1.0);
    for l in &mut force_lines {
        l.label.push_str(" instrument");
    }
    // With the force player, the finger's push beside the instrument's force.
    if traces.values().flatten().any(|r| r[4] != 0.0) {
        force_lines.extend(lines(4, 1.0).into_iter().map(|mut l| {
            l.label.push_str(" finger");
            l
        }));
    }
    plot_lines(
        &force_lines,
        &format!("{stem}: force at the key"),
        "time [s]",
        "force [N]",
        &force,
    )?;
    wrote.push(force);
    let key = out.join(format!("{stem}-key.svg"));
    plot_lines(
        &lines(1, 1e3),
        &format!("{stem}: key travel"),
        "time [s]",
        "key travel [mm]",
        &key,
    )?;
    wrote.push(key);
    let hammer_lines = lines(3, 1e3);
    if hammer_lines
        .iter()
        .any(|l| l.y.iter().any(|v| v.is_finite()))
    {
        let hammer = out.join(format!("{stem}-hammer.svg"));
        plot_lines(
            &hammer_lines,
            &format!("{stem}: hammer position"),
            "time [s]",
            "hammer travel [mm]",
            &hammer,
        )?;
        wrote.push(hammer);
    }
    Ok(wrote)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::play::emulated::BoardRun;

    /// A converter board's run reports its parts' timing: no breach, or how many and the
    /// first with its board.
    #[test]
    fn the_budget_text_reports_the_converters_breaches() {
        let io = tactus_emulator::IoWindows {
            kept: 10,
            ..Default::default()
        };
        let board = |breaches: &[&str]| BoardRun {
            io_windows: io,
            io_breaches: breaches.iter().map(|b| b.to_string()).collect(),
            ..BoardRun::default()
        };
        let report = |boards: Vec<BoardRun>| BoardsReport {
            board: "rp2040_io".into(),
            deadline: 3015,
            boards,
            decimation: 1,
            samples: 10,
            timeline: crate::play::Timeline::at_zero(44_100.0),
        };
        let clean = budget_text(&report(vec![board(&[]), board(&[])]));
        assert!(
            clean.contains("converters' timing against their data sheets: no breach"),
            "{clean}"
        );
        let what = "core 1 DAC, cycle 99: SYNC high for 10 ns, under 15 ns";
        let broken = budget_text(&report(vec![board(&[]), board(&[what, "another"])]));
        assert!(
            broken.contains(&format!("2 breaches (the first: board 2, {what})")),
            "{broken}"
        );
        // A plain board says nothing of converters.
        let plain = budget_text(&report(vec![BoardRun::default()]));
        assert!(!plain.contains("converters"), "{plain}");
    }
}
