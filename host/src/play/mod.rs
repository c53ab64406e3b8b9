//! A recorded performance played through an instrument: `tactus play`'s work, the binary
//! only parses arguments and prints.
//!
//! [`play`] turns each played key's notes into a [`Motion`] (the position player's key track
//! or the force player's calibrated finger, [`motion`]), runs the keys through one engine
//! and returns the strikes, each matched to the note it answers ([`strike`]), the notes left
//! silent, the traced keys' samples and, on the emulated boards, each board's budget. Every
//! engine is a [`KeyEngine`] ([`engine`]) stepped by the one play loop ([`run::run_keys`]):
//!
//! * `Emu` (the default of `tactus play`): the compiled firmware of every board of the
//!   keyboard on emulated RP2040s, every key every sample, idle keys included
//!   ([`emulated::play_boards`]);
//! * `Fixed`: the fixed-point JIT of the programs the firmware runs (the layout compiled
//!   together, each key with its param block): the firmware's bits on the host, played keys
//!   only;
//! * `Jit`, `Interp`: the f64 JIT and reference interpreter of each played key's program.
//!
//! The host engines simulate a key only around its movements ([`motion::busy_stretches`]).
//! [`output`] writes the strikes as CSV, MIDI and WAV and the traces as CSV.

pub mod calibrate;
pub mod corpus;
pub mod emulated;
pub mod engine;
pub mod error;
pub mod motion;
pub mod output;
pub mod results;
pub mod run;
pub mod shard;
pub mod strike;
pub mod timeline;

pub use engine::{KeyEngine, KeySample};
pub use error::{BoardError, RunError};
pub use motion::Motion;
pub use run::{TraceRows, TraceWindow, Traces};
pub use strike::Strike;
pub use timeline::Timeline;

pub use crate::fault::RestingHang;
use calibrate::{calibrate, CALIBRATION_LEVELS_N};
use emulated::{play_boards, BoardRun, PerformOptions};
use engine::{FixedJitEngine, HostKey, JitEngine};
use motion::{busy_stretches, key_motion, stretch_samples};
pub use motion::{FingerCalibration, Restrikes};
use run::{run_keys, Drive};
use std::collections::BTreeMap;
use std::sync::Arc;
use tactus_compiler::ir::Program;
use tactus_firmware::boards::BoardImage;
use tactus_firmware::image::Program as FirmwareProgram;
use tactus_runtime::keyboard::{BoardSpec, KeyAssignment};
use tactus_runtime::performance::{Note, Performance};
use tactus_runtime::player::FingerConfig;

/// What computes the keys' instruments.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlayEngine {
    /// Cranelift JIT (f64).
    Jit,
    /// The f64 reference interpreter.
    Interp,
    /// Cranelift JIT of the fixed-point programs the firmware runs: its bits, on the host.
    Fixed,
    /// The firmware of every board of the keyboard on emulated RP2040s.
    Emu,
}

/// What moves the keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Player {
    /// Key trajectories prescribed by the key-motion model (open loop).
    Position,
    /// A finger force profile against the instrument's force (closed loop).
    Force,
}

/// A distinct instrument of the played keys, compiled.
#[derive(Clone, Debug)]
pub struct HostProgram {
    /// The instrument as the layout names it (built-in name or path).
    pub name: String,
    /// Its program with the key's overrides (the f64 engines run it; every engine reads its
    /// key dip from it).
    pub program: Program,
}

/// The keyboard a performance is played on.
pub struct Keyboard<'a> {
    /// Every key of the layout with its instrument and params (overrides last): what the
    /// firmware runs, played or not, and what `Fixed` compiles together.
    pub keys: Vec<KeyAssignment>,
    /// The distinct programs of the played keys.
    pub programs: Vec<HostProgram>,
    /// Played key (MIDI) → its index in `programs`; every note's key is here.
    pub key_program: BTreeMap<u8, usize>,
    /// The keyboard's boards (MIDI keys per board) as its plan gives them
    /// ([`crate::keyboard::Keyboard::plan`]: the boards `tactus budget` reports and `tactus
    /// build` builds): what `Emu` runs; `None` for the host engines.
    pub boards: Option<Vec<Vec<u8>>>,
    /// The firmware's programs of the keys, when the engine runs them
    /// ([`PlayConfig::needs_firmware`]); `None` otherwise.
    pub firmware: Option<Firmware<'a>>,
}

/// The programs the firmware runs: every key of the layout compiled together, so that an
/// instrument's graded params are run-time data planned over the interval all its keys span
/// (`tactus_host::keyboard::Keyboard::firmware`, or
/// [`tactus_firmware::image::compile_layout`]).
#[derive(Clone, Copy, Debug)]
pub struct Firmware<'a> {
    /// The distinct programs.
    pub programs: &'a [FirmwareProgram],
    /// `programs[key_program[i]]` is [`Keyboard::keys`]`[i]`'s program.
    pub key_program: &'a [usize],
    /// Per board of [`Keyboard::boards`]: the image its plan built of `programs`
    /// ([`tactus_firmware::boards::KeyboardPlan::images`]; `None`, or none given: the run
    /// builds it).
    pub images: &'a [Option<Arc<BoardImage>>],
}

/// How [`play`] runs.
#[derive(Clone, Debug)]
pub struct PlayConfig {
    /// The engine.
    pub engine: PlayEngine,
    /// The player.
    pub player: Player,
    /// The force player's finger.
    pub finger: FingerConfig,
    /// What to trace.
    pub trace: TraceWindow,
    /// The board: its sample rate is every engine's (the programs are compiled for it);
    /// `Emu` runs its firmware.
    pub board: BoardSpec,
    /// The emulator's engine (the same cycles and strikes either way).
    pub emulator: tactus_emulator::Engine,
    /// Whether the firmware guards quiescent keys (the same strikes either way).
    pub quiescent_guard: bool,
    /// Whether a board at rest replays its repeating period instead of emulating it
    /// (`tactus_firmware::image::ImageRun::set_rest_replay`: the same results exactly).
    pub rest_replay: bool,
    /// With `--engine emu` on a board with converters: the directory of the boards' I/O
    /// traces (their frames at the pins, `emulated::IO_TRACE_HEADER`).
    pub io_trace: Option<std::path::PathBuf>,
    /// With `--engine emu`: play the piece as consecutive spans of this many samples, the
    /// boards carrying their whole state from one to the next, and report the budget of
    /// each ([`Played::spans`]); the same strikes and whole-run budget as one span.
    /// `None`: one span.
    pub span: Option<usize>,
    /// With `--engine emu`: faults injected into the boards (`--fault`, `crate::fault`).
    pub faults: Vec<crate::fault::FaultSpec>,
    /// The firmware's sensor check (`tactus_firmware::image::Program::sensor_check`) on
    /// or off on every key, planned and priced with it; `None`: the programs' default. A
    /// [`crate::session::Session`] gives it to its keyboard
    /// ([`crate::keyboard::Keyboard::sensor_check`]) before it compiles and plans; a caller
    /// of [`play`] sets it on the programs it passes.
    pub sensor_check: Option<bool>,
    /// The firmware's watchdog (`tactus_firmware::image::Program::watchdog`) on or off on
    /// every board, as [`PlayConfig::sensor_check`] ([`crate::keyboard::Keyboard::watchdog`]);
    /// `None`: the programs' default.
    pub watchdog: Option<bool>,
}

impl PlayConfig {
    /// Whether [`play`] runs the firmware's programs ([`Keyboard::firmware`]): on the
    /// emulated boards (`Emu`), and in the fixed-point JIT (`Fixed`, and the force player's
    /// calibration for `Emu`).
    pub fn needs_firmware(&self) -> bool {
        matches!(self.engine, PlayEngine::Emu | PlayEngine::Fixed)
    }
}

/// Reports a run's progress, in key-samples.
pub trait Progress: Sync {
    /// The run starts: `total` key-samples. On the emulated boards every key of the
    /// keyboard runs every sample, so progress is music time: `per_second` key-samples per
    /// second of music (`None` on a host engine).
    fn start(&self, total: u64, per_second: Option<f64>);
    /// `n` more key-samples are done.
    fn inc(&self, n: u64);
}

/// No progress report.
impl Progress for () {
    fn start(&self, _: u64, _: Option<f64>) {}
    fn inc(&self, _: u64) {}
}

/// The most samples an `Emu` run may cover: 2³², 27 hours at 44.1 kHz, where the
/// firmware's 32-bit sample counter would wrap (no run has been checked through a wrap); a
/// stray event days into a MIDI file is refused, not played for days. Nothing of a run
/// grows with its length but its strikes (one per note), the traces asked for and a
/// board's cycle series (at most `emulated::MAX_POINTS` points): a 40-minute recital plays
/// in the memory of a 4-minute piece.
pub const MAX_EMU_SAMPLES: u64 = 1 << 32;

/// What the emulated boards reported over a run.
#[derive(Clone, Debug)]
pub struct BoardsReport {
    /// The board kind's name.
    pub board: String,
    /// Cycles per sample per core (the deadline).
    pub deadline: u64,
    /// Per board of the keyboard, in key order.
    pub boards: Vec<BoardRun>,
    /// Samples per point of [`BoardRun::cycles`].
    pub decimation: usize,
    /// Samples run.
    pub samples: u64,
    /// The run's clock: its first sample is `timeline.lead_in` samples before the
    /// performance's 0 s ([`Timeline`]; the cycles and the spans are the run's samples).
    pub timeline: Timeline,
}

impl BoardsReport {
    /// Whether any core of any board missed a deadline.
    pub fn missed(&self) -> bool {
        self.boards.iter().any(|b| b.misses.iter().any(|&m| m > 0))
    }

    /// Every board's fault records at the end of the run (boards from 1).
    pub fn faults(&self) -> Vec<crate::fault::BoardFaults> {
        (self.boards.iter().enumerate())
            .map(|(i, b)| crate::fault::BoardFaults {
                board: i + 1,
                cores: b.faults.clone(),
                slots: b
                    .slots
                    .iter()
                    .copied()
                    .zip(b.keys.iter().copied())
                    .collect(),
                resets: b.resets.clone(),
            })
            .collect()
    }

    /// Trips of the firmware's fault checks over every core of every board.
    pub fn fault_trips(&self) -> u64 {
        self.faults()
            .iter()
            .map(crate::fault::BoardFaults::trips)
            .sum()
    }
}

/// Why a note sounded no strike.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Silence {
    /// Too soft to reach the string: with the force player, its velocity asks for a hammer
    /// speed below the softest the calibrated finger strikes with from rest (less half a
    /// MIDI velocity step); a real piano leaves such a note silent too.
    TooSoft,
    /// Anything else: a miss of the player or the instrument.
    Other,
}

/// A note no strike answers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SilentNote {
    /// The note.
    pub note: Note,
    /// Why.
    pub cause: Silence,
    /// Time since the previous note-on of its key, s (`None` for its first note).
    pub since_previous_s: Option<f64>,
}

/// What [`play`] produced.
#[derive(Clone, Debug)]
pub struct Played {
    /// The strikes by time, each with the note it answers.
    pub strikes: Vec<Strike>,
    /// The notes no strike answers, each with why.
    pub silent: Vec<SilentNote>,
    /// The traced keys' samples.
    pub traces: Traces,
    /// The force player's calibration per program (`None` with the position player).
    pub calibrations: Vec<Option<FingerCalibration>>,
    /// How the force player played repeated notes, and the notes either player left out
    /// ([`Restrikes::dropped`]).
    pub restrikes: Restrikes,
    /// The position player's notes it could not place as recorded, with their keys
    /// (`tactus_runtime::performance::KeyTrack::rushed`): pressed faster than their
    /// velocity asks, or late.
    pub rushed: Vec<(u8, tactus_runtime::performance::Rushed)>,
    /// Key-samples simulated.
    pub key_samples: u64,
    /// With `Emu`: the boards' budget over the run.
    pub boards: Option<BoardsReport>,
    /// With `Emu` and [`PlayConfig::span`]: each span's first sample (the run's) and the
    /// boards' budget over it alone (its largest and mean cycles, its misses), in order.
    pub spans: Vec<(u64, BoardsReport)>,
    /// The run's clock: the lead-in it ran before the performance's 0 s. Every time above
    /// is the performance's; the samples of `boards` and `spans` are the run's.
    pub timeline: Timeline,
    /// With `Emu`: the `--fault kind=hang` whose key stands still when the hang begins
    /// (the quiescent-key guard skips such a key's update, so the hang waits for it to
    /// move), in the performance's time: [`RestingHang`].
    pub resting_hangs: Vec<RestingHang>,
}

/// The hangs of `faults` (resolved: board, injection in the run's samples) on keys of
/// `boards` that stand still when they begin ([`RestingHang::of`]), by the keys' `motions`
/// (the run's time of `timeline`; a key without one rests throughout); `end` is the run's
/// last sample. A key moved by a finger (the force player) moves with the force: none of
/// its hangs is listed. The times are the performance's.
fn resting_hangs(
    faults: &[(usize, tactus_firmware::image::Injection)],
    specs: &[crate::fault::FaultSpec],
    boards: &[Vec<u8>],
    motions: &BTreeMap<u8, &Motion>,
    timeline: &Timeline,
    end: usize,
) -> Vec<RestingHang> {
    use tactus_firmware::image::FaultKind;
    let mut out = Vec::new();
    for ((b, inj), spec) in faults.iter().zip(specs) {
        if inj.kind != FaultKind::Hang {
            continue;
        }
        let Some(&key) = inj.key.and_then(|k| boards.get(*b)?.get(k)) else {
            continue;
        };
        let run_s = |n: u64| n as f64 / timeline.fs;
        let (from, until) = (run_s(inj.from), run_s(inj.until.unwrap_or(end as u64)));
        // When the key next moves at or after `from` (run time, s): `from` while it moves,
        // infinite when it never does; none for a finger's key.
        let next = match motions.get(&key) {
            None => f64::INFINITY,
            Some(Motion::Finger(_)) => continue,
            Some(Motion::Track(t)) => t.steady_from(from, &mut 0).map_or(from, |s| s.1),
        };
        if let Some(mut h) = RestingHang::of(&spec.text, key, from, until, next, timeline.fs) {
            h.at_s = timeline.run_to_performance_s(h.at_s);
            h.moves_at_s = h.moves_at_s.map(|t| timeline.run_to_performance_s(t));
            out.push(h);
        }
    }
    out
}

/// The slack of a calibrated range of hammer speeds, as a fraction of the speed: about half
/// a MIDI velocity step (the velocity map is logarithmic, 25 steps for each doubling of the
/// speed, a step 2.8 %: [`strike::speed_for_velocity`]), since the range's ends are
/// measured, not exact.
pub const CALIBRATION_SLACK: f64 = 0.015;

/// Whether hammer speed `v` (m/s) lies outside the force player's calibrated range
/// `lo..=hi` (m/s) by more than [`CALIBRATION_SLACK`]: a note the finger cannot play as
/// recorded (below: too soft to reach the string; above: played at the loudest it can).
pub fn outside_calibration(v: f64, lo: f64, hi: f64) -> bool {
    v < lo * (1.0 - CALIBRATION_SLACK) || v > hi * (1.0 + CALIBRATION_SLACK)
}

/// Plays `perf` (its notes on keys of `keyboard.key_program`) on `keyboard` as `config`
/// says; see the module documentation.
///
/// Errors: a message when a program does not compile to fixed point or to the JIT, the
/// force player cannot calibrate an instrument (no calibration stroke strikes), an `Emu`
/// run is longer than [`MAX_EMU_SAMPLES`], a board's image cannot be built or faults, or an
/// f64 engine computes a non-finite value.
pub fn play(
    perf: &Performance,
    keyboard: &Keyboard,
    config: &PlayConfig,
    progress: &dyn Progress,
) -> Result<Played, RunError> {
    let programs = &keyboard.programs;
    // Every program runs at the board's sample rate, compiled for it.
    let fs = config.board.sample_rate_hz;
    if let Some(p) = programs.iter().find(|p| p.program.sample_rate_hz != fs) {
        return Err(RunError::SampleRate {
            program: p.name.clone(),
            program_hz: p.program.sample_rate_hz,
            board: config.board.name.clone(),
            board_hz: fs,
        });
    }
    // The fixed-point JIT runs the keys with `Fixed`, and calibrates the force player for
    // `Emu` (the same bits as the firmware's update).
    let fixed_needed = config.engine == PlayEngine::Fixed
        || (config.engine == PlayEngine::Emu && config.player == Player::Force);
    // The programs the firmware runs; each host program's is the shared code with the param
    // block of its first key.
    let (firmware, firmware_index): (&[FirmwareProgram], &[usize]) =
        match (config.needs_firmware(), keyboard.firmware) {
            (true, Some(f)) if f.key_program.len() == keyboard.keys.len() => {
                match f.key_program.iter().all(|&i| i < f.programs.len()) {
                    true => (f.programs, f.key_program),
                    false => {
                        return Err(RunError::FirmwareMismatch(
                            "a key's program index is out of range".into(),
                        ))
                    }
                }
            }
            (true, Some(f)) => {
                return Err(RunError::FirmwareMismatch(format!(
                    "{} key programs for {} keys",
                    f.key_program.len(),
                    keyboard.keys.len()
                )))
            }
            (true, None) => {
                return Err(RunError::FirmwareMismatch(format!(
                    "the {:?} engine{} runs the firmware's programs; none were given",
                    config.engine,
                    match config.player {
                        Player::Force => " with the force player",
                        Player::Position => "",
                    }
                )))
            }
            (false, _) => (&[], &[]),
        };
    let fixed_programs: Vec<&FirmwareProgram> = match fixed_needed {
        true => (0..programs.len())
            .map(|pi| {
                keyboard
                    .keys
                    .iter()
                    .position(|a| keyboard.key_program.get(&a.key) == Some(&pi))
                    .map(|i| &firmware[firmware_index[i]])
                    .ok_or_else(|| RunError::FirmwareMismatch(format!("program {pi} has no key")))
            })
            .collect::<Result<_, _>>()?,
        false => Vec::new(),
    };
    // One fixed JIT per distinct code.
    let mut fixed_jits: Vec<(usize, tactus_jit::fixed::FixedJitProgram)> = Vec::new();
    for (pi, p) in fixed_programs.iter().enumerate() {
        if !fixed_jits
            .iter()
            .any(|(q, _)| fixed_programs[*q].same_code(p))
        {
            let j = tactus_jit::fixed::FixedJitProgram::compile(&p.fixed).map_err(|e| {
                RunError::Jit {
                    engine: "fixed JIT",
                    message: e.to_string(),
                }
            })?;
            fixed_jits.push((pi, j));
        }
    }
    let jits: Vec<Option<tactus_jit::JitProgram>> = match config.engine {
        PlayEngine::Jit => programs
            .iter()
            .map(|p| {
                tactus_jit::JitProgram::compile(&p.program)
                    .map(Some)
                    .map_err(|e| RunError::Jit {
                        engine: "JIT",
                        message: e.to_string(),
                    })
            })
            .collect::<Result<_, _>>()?,
        _ => programs.iter().map(|_| None).collect(),
    };
    // A fresh host instance of program `pi`: the fixed JIT when it is needed, else the f64
    // JIT when compiled, else the interpreter.
    let host_key = |pi: usize| -> Box<dyn KeyEngine + '_> {
        let fixed = fixed_programs.get(pi).and_then(|p| {
            fixed_jits
                .iter()
                .find(|(q, _)| fixed_programs[*q].same_code(p))
                .map(|(_, j)| (*p, j))
        });
        Box::new(match (fixed, &jits[pi]) {
            (Some((p, j)), _) => HostKey::new(
                &p.fixed.program,
                Box::new(FixedJitEngine(
                    tactus_jit::fixed::FixedJitInstance::with_params(j, &p.params),
                    &p.fixed,
                )),
            ),
            (None, Some(j)) => HostKey::new(
                &programs[pi].program,
                Box::new(JitEngine(tactus_jit::JitInstance::new(j))),
            ),
            (None, None) => HostKey::new(
                &programs[pi].program,
                Box::new(tactus_compiler::interp::Instance::new(
                    &programs[pi].program,
                )),
            ),
        })
    };
    let dip_of = |pi: usize| programs[pi].program.sensors[0].range.1;
    let finger = config.finger;
    // The force player's calibration, per program.
    let calibrations: Vec<Option<FingerCalibration>> = match config.player {
        Player::Position => programs.iter().map(|_| None).collect(),
        Player::Force => (0..programs.len())
            .map(|pi| {
                calibrate(&|| host_key(pi), dip_of(pi), finger, fs)?
                    .map(Some)
                    .ok_or_else(|| RunError::Calibration {
                        instrument: programs[pi].name.clone(),
                        levels: CALIBRATION_LEVELS_N.to_vec(),
                    })
            })
            .collect::<Result<_, RunError>>()?,
    };
    // The lead-in: a piece whose first notes start sooner than their strokes need runs
    // from a lead-in before it (whole samples), so that every stroke is placed as
    // recorded. The players plan in the run's time; everything reported reads the
    // performance's through the one clock.
    let timeline = Timeline::new(fs, lead_in_samples(perf, keyboard, &calibrations, fs));
    let shifted;
    let run_perf = match timeline.lead_in {
        0 => perf,
        _ => {
            shifted = shifted_performance(perf, &timeline);
            &shifted
        }
    };
    let trace = &config.trace;
    // Each played key's motion and the stretches it moves.
    let mut motions: BTreeMap<u8, (Motion, Vec<(f64, f64)>)> = BTreeMap::new();
    let mut restrikes = Restrikes::default();
    let mut rushed = Vec::new();
    for (&key, &pi) in &keyboard.key_program {
        let notes: Vec<Note> = (run_perf.notes.iter())
            .filter(|n| n.key == key)
            .copied()
            .collect();
        let force = calibrations[pi].as_ref().map(|c| (c, finger));
        let (motion, busy, counts) = key_motion(&notes, dip_of(pi), run_perf.duration_s, force);
        restrikes += counts;
        if let Motion::Track(t) = &motion {
            rushed.extend(t.rushed.iter().map(|r| {
                let mut r = *r;
                r.on_s = timeline.run_to_performance_s(r.on_s);
                (key, r)
            }));
        }
        motions.insert(key, (motion, busy_stretches(busy)));
    }
    let mut strikes = Vec::new();
    let mut traces = Traces::new();
    let key_samples;
    let mut boards = None;
    let mut spans = Vec::new();
    let mut resting = Vec::new();
    if config.engine == PlayEngine::Emu {
        let end = motions
            .values()
            .flat_map(|(_, busy)| busy.iter().map(|&b| stretch_samples(b, fs).end))
            .max()
            .unwrap_or(0);
        // Bounded before anything runs.
        if end as u64 > MAX_EMU_SAMPLES {
            return Err(RunError::TooLong {
                seconds: end as f64 / fs,
                max_seconds: MAX_EMU_SAMPLES as f64 / fs,
                max_samples: MAX_EMU_SAMPLES,
            });
        }
        let keys: Vec<u8> = keyboard.keys.iter().map(|a| a.key).collect();
        key_samples = end as u64 * keys.len() as u64;
        progress.start(key_samples, Some(keys.len() as f64 * fs));
        let plan_boards = keyboard.boards.clone().ok_or_else(|| {
            RunError::FirmwareMismatch(
                "the Emu engine runs the keyboard's boards; no plan was given".to_string(),
            )
        })?;
        // A fault's times are the performance's: its samples follow the lead-in.
        let faults = (config.faults.iter())
            .map(|f| {
                f.resolve(&plan_boards, fs).map(|(b, mut i)| {
                    i.from = timeline.performance_sample_to_run(i.from);
                    i.until = i.until.map(|u| timeline.performance_sample_to_run(u));
                    (b, i)
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        if config.quiescent_guard {
            resting = resting_hangs(
                &faults,
                &config.faults,
                &plan_boards,
                &motions.iter().map(|(&k, (m, _))| (k, m)).collect(),
                &timeline,
                end,
            );
        }
        let opts = PerformOptions {
            end,
            clock: timeline,
            finger,
            trace: trace.clone(),
            boards: plan_boards,
            images: keyboard.firmware.map_or(Vec::new(), |f| f.images.to_vec()),
            limiter: tactus_runtime::limiter::LimiterConfig::for_board(&config.board),
            engine: config.emulator,
            quiescent_guard: config.quiescent_guard,
            rest_replay: config.rest_replay,
            io_trace: config.io_trace.clone(),
            span: config.span,
            faults,
        };
        let key_motions: BTreeMap<u8, &Motion> =
            motions.iter().map(|(&k, (m, _))| (k, m)).collect();
        let run = play_boards(
            firmware,
            &keys,
            firmware_index,
            &config.board,
            &key_motions,
            &opts,
            &|n| progress.inc(n),
        )?;
        let mut runs = Vec::with_capacity(run.boards.len());
        for mut b in run.boards {
            // The fault words and resets in the performance's samples (a trip in the
            // lead-in at 0).
            for w in &mut b.faults {
                w.at_sample = timeline.run_sample_to_performance(u64::from(w.at_sample)) as u32;
            }
            for r in &mut b.resets {
                r.sample = timeline.run_sample_to_performance(r.sample);
            }
            strikes.append(&mut b.strikes);
            traces.append(&mut b.traces);
            runs.push(b);
        }
        // Each span's budget, its boards' parts of it side by side.
        let mut from = 0u64;
        for (j, &len) in run.spans.iter().enumerate() {
            let boards: Vec<BoardRun> = (runs.iter())
                .map(|b| b.spans.get(j).cloned().unwrap_or_default())
                .collect();
            spans.push((
                from,
                BoardsReport {
                    board: config.board.name.clone(),
                    deadline: config.board.cycles_per_sample(),
                    boards,
                    decimation: 1,
                    samples: len,
                    timeline,
                },
            ));
            from += len;
        }
        boards = Some(BoardsReport {
            board: config.board.name.clone(),
            deadline: config.board.cycles_per_sample(),
            boards: runs,
            decimation: run.decimation,
            samples: end as u64,
            timeline,
        });
    } else {
        // One fresh instance per busy stretch of each played key.
        let jobs: Vec<(u8, std::ops::Range<usize>)> = motions
            .iter()
            .flat_map(|(&key, (_, busy))| busy.iter().map(move |&b| (key, stretch_samples(b, fs))))
            .collect();
        key_samples = jobs.iter().map(|(_, r)| r.len() as u64).sum();
        progress.start(key_samples, None);
        for (key, samples) in jobs {
            let pi = keyboard.key_program[&key];
            let drive = Drive {
                key,
                motion: Some(&motions[&key].0),
                dip_m: dip_of(pi),
            };
            let mut run = run_keys(
                &mut *host_key(pi),
                &[drive],
                samples,
                &run::LoopConfig {
                    clock: timeline,
                    finger,
                    trace,
                    stop_at_strike_after_s: None,
                },
                &|n| progress.inc(n),
            )?;
            strikes.append(&mut run.strikes);
            for (k, mut rows) in run.traces {
                traces.entry(k).or_default().append(&mut rows);
            }
        }
    }
    strike::answer(&mut strikes, &perf.notes);
    let silent = strike::silent(&perf.notes, &strikes)
        .into_iter()
        .map(|note| {
            let too_soft = keyboard
                .key_program
                .get(&note.key)
                .and_then(|&pi| calibrations[pi].as_ref())
                .is_some_and(|c| {
                    let lo = c.from_rest.levels()[0].2;
                    outside_calibration(
                        strike::speed_for_velocity(note.velocity),
                        lo,
                        f64::INFINITY,
                    )
                });
            let since_previous_s = perf
                .notes
                .iter()
                .filter(|n| n.key == note.key && n.on_s < note.on_s)
                .map(|n| note.on_s - n.on_s)
                .reduce(f64::min);
            SilentNote {
                note,
                cause: if too_soft {
                    Silence::TooSoft
                } else {
                    Silence::Other
                },
                since_previous_s,
            }
        })
        .collect();
    Ok(Played {
        strikes,
        silent,
        traces,
        calibrations,
        restrikes,
        rushed,
        key_samples,
        boards,
        spans,
        timeline,
        resting_hangs: resting,
    })
}

/// The samples to run before a performance's time 0 so that every key's first stroke is
/// placed as recorded (0 for a piece whose first notes leave their strokes the time): the
/// position player's key descent for the note's velocity
/// (`tactus_runtime::performance::descent_time_s`), the force player's calibrated lead for
/// its hammer speed, less the note-on, the largest over the played keys' first notes, at
/// `fs` Hz, rounded up to a whole sample.
fn lead_in_samples(
    perf: &Performance,
    keyboard: &Keyboard,
    calibrations: &[Option<FingerCalibration>],
    fs: f64,
) -> u64 {
    let mut lead: f64 = 0.0;
    for (&key, &pi) in &keyboard.key_program {
        let Some(first) = (perf.notes.iter())
            .filter(|n| n.key == key)
            .min_by(|a, b| a.on_s.total_cmp(&b.on_s))
        else {
            continue;
        };
        let needs = match calibrations.get(pi).and_then(Option::as_ref) {
            Some(c) => {
                c.from_rest
                    .for_speed(strike::speed_for_velocity(first.velocity))
                    .1
            }
            None => tactus_runtime::performance::descent_time_s(first.velocity),
        };
        lead = lead.max(needs - first.on_s);
    }
    match lead.is_finite() && lead > 0.0 {
        true => (lead * fs).ceil() as u64,
        false => 0,
    }
}

/// `perf` in the run's time of `timeline` (its lead-in later): every note-on and
/// note-off, pedal change and the end.
fn shifted_performance(perf: &Performance, timeline: &Timeline) -> Performance {
    let at = |t: f64| timeline.performance_to_run_s(t);
    Performance {
        notes: (perf.notes.iter())
            .map(|n| Note {
                on_s: at(n.on_s),
                off_s: at(n.off_s),
                ..*n
            })
            .collect(),
        sustain: perf.sustain.iter().map(|&(t, on)| (at(t), on)).collect(),
        duration_s: at(perf.duration_s),
    }
}
