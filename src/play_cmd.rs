//! `tactus play`: a recorded performance played through an instrument, key by key, on the
//! host engines — the f64 JIT or interpreter, or the fixed-point JIT (`--engine fixed`: the
//! bits the firmware computes) — or (`--engine emu`) as the compiled firmware of the played
//! keys on the emulated board, every key every sample, with the cycles each core spends and
//! the deadline misses the firmware counts.
//!
//! Each played key runs its own instance of the instrument ([`KeyEngine`], stepped once per
//! sample) from 50 ms before a press to 500 ms after its release; keys that are never played
//! stay at rest and need no simulation, and a key at rest for more than a second between
//! notes is simulated as separate stretches, each from a fresh instance (a key that has been
//! at rest that long is back in its initial state — hammer on the rest felt, jack re-armed,
//! impact pulses decayed — so this changes no strike, and a whole piece costs the time its
//! keys move, not its length times its keys). Two players move the keys:
//!
//! * `position` (default): the key-motion model of `tactus_runtime::performance` prescribes
//!   the key travel; the instrument's force is computed but does not move the key;
//! * `force`: a finger pushes with a force profile and the key moves under the finger's and
//!   the instrument's forces (`tactus_runtime::player`): the closed loop. Each instrument is
//!   first calibrated with single strokes at [`CALIBRATION_LEVELS_N`], so a note of MIDI
//!   velocity `v` is played with the finger force that gives the hammer speed
//!   [`speed_for_velocity`]`(v)`, started that stroke's lead time before the note-on.
//!
//! With `--engine emu` both players run on the firmware's words: the force player's key is
//! pushed against the force word the key's firmware computed that sample, and traces also
//! record the safety limiter's current and the DAC code.
//!
//! Every `strike` (or `pluck`) the instrument emits becomes a note of the output MIDI file and
//! of the WAV rendering (`tactus_runtime::voice`).

use crate::check_cmd::{compile_reporting, parse_override};
use crate::plot;
use crate::source;
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;
use tactus_runtime::performance::{self, Performance};
use tactus_runtime::player::{Calibration, FingerConfig, ForcePlayer, ForceProfile, Stroke};
use tactus_runtime::voice;

/// Arguments of `tactus play`.
#[derive(Debug, clap::Args)]
#[command(
    after_long_help = "Writes OUT/NAME-strikes.csv (one row per strike: key, time, hammer speed, MIDI velocity, \
the input note it answers), OUT/NAME-strikes.mid (the strikes as MIDI with velocities from the simulated hammer \
speed: 1 at 0.1 m/s to 127 at 6 m/s, logarithmic) and OUT/NAME.wav (the strikes through a synthesized modal \
piano voice, 44.1 kHz 16-bit mono, normalised). With --trace-keys: OUT/NAME-key<K>.csv per traced key (time, key \
travel, instrument force, hammer position, finger force), OUT/NAME-force.svg and OUT/NAME-hammer.svg; \
with --engine emu the force is the firmware's force word (before the safety limiter), the hammer its hammer_pos \
output word, every sample of the trace window (the emulated keys run all the time), and two more columns: \
motor_current_a (the current the firmware's safety limiter allowed) and dac_code (the word it wrote to the DAC). \
Example: tactus play ../shared/data/performances/Maestro_1.mid --seconds 20 --trace-keys 60,64"
)]
pub struct PlayArgs {
    /// MIDI performance to play [default: a built-in 8 s demo].
    pub performance: Option<PathBuf>,
    /// Instrument on every key A0…C8 (file or built-in name), instead of the layout.
    #[arg(long, conflicts_with = "layout")]
    pub instrument: Option<String>,
    /// Keyboard layout (TOML): instruments and param grading per key range [default: the
    /// built-in grand88, instruments/layouts/grand88.toml: the grand piano on A0…C8 with
    /// the hammer mass graded from 11 g to 3.5 g].
    #[arg(long)]
    pub layout: Option<PathBuf>,
    /// Play only the first SECONDS of the performance.
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Engine: `emu` (the default: the compiled firmware of every board of the keyboard on
    /// emulated RP2040s, every key every sample, with each core's cycles and deadline
    /// misses), or for quick looks on the host `fixed` (the fixed-point JIT: the firmware's
    /// bits), `jit` (cranelift f64) or `interp` (the f64 reference interpreter), which
    /// simulate only the played keys and check no budget.
    #[arg(long, value_enum, default_value = "emu")]
    pub engine: PlayEngine,
    /// Board of `--engine emu`: a built-in name (`rp2040`, `rp2040_200mhz`, `rp2040_20mhz`)
    /// or a board file.
    #[arg(long, default_value = "rp2040", value_name = "NAME_OR_FILE")]
    pub board: String,
    /// The emulator's engine for `--engine emu`: `block` (code compiled to native code with
    /// cranelift) or `interp` (the interpreter): the same cycles and strikes; compare their
    /// speed.
    #[arg(long, value_enum, default_value = "block")]
    pub emu: crate::budget_cmd::EmuEngine,
    /// Player: `position` (prescribed key trajectories) or `force` (a finger force profile
    /// against the instrument's force: the closed loop; with `--engine emu` against the
    /// firmware's force word each sample, calibrated with the fixed-point JIT).
    #[arg(long, value_enum, default_value = "position")]
    pub player: Player,
    /// Override a param on every key: `--param M_h=10 g`.
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_override)]
    pub params: Vec<(String, String)>,
    /// Keys to trace (MIDI numbers, comma-separated): a CSV per key and SVG plots of force
    /// and hammer position vs time (with `--engine emu` also the limited motor current and
    /// the DAC code).
    #[arg(long, value_delimiter = ',', value_name = "KEYS")]
    pub trace_keys: Vec<u8>,
    /// Trace from this time on, s.
    #[arg(long, default_value_t = 0.0)]
    pub trace_from: f64,
    /// Trace until this time, s [default: the end].
    #[arg(long)]
    pub trace_to: Option<f64>,
    /// With `--engine emu`: build the firmware without the quiescent-key guard, so that
    /// every key's update runs every sample (the same strikes; to measure what the guard
    /// saves).
    #[arg(long)]
    pub no_quiescent_guard: bool,
    /// Do not write the WAV rendering.
    #[arg(long)]
    pub no_wav: bool,
    /// Output directory.
    #[arg(long, short, default_value = "out")]
    pub out: PathBuf,
}

/// Engines of `tactus play`: what computes a key's instrument each sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PlayEngine {
    /// Cranelift JIT (f64).
    Jit,
    /// The f64 reference interpreter.
    Interp,
    /// Cranelift JIT of the fixed-point program: the bits the firmware computes (the Thumb
    /// code in the emulator equals it bit for bit).
    Fixed,
    /// The firmware image of the played keys (`tactus_firmware::image`: Thumb updates, the
    /// safety limiter, a timer interrupt per core) on the emulated board, every key every
    /// sample; reports cycles per core and deadline misses.
    Emu,
}

/// Players of `tactus play`: what moves the keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Player {
    /// Key trajectories prescribed by the key-motion model (open loop).
    Position,
    /// A finger force profile against the instrument's force (closed loop).
    Force,
}

/// What one sample of one key's instrument gives the play loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeySample {
    /// The commanded force at the key, N (positive pushes the key up).
    pub force_n: f64,
    /// Hammer-head travel from rest, m (`NaN` when the instrument has no `hammer_pos`).
    pub hammer_m: f64,
    /// The hammer speed of a `strike`/`pluck` emitted this sample, m/s.
    pub strike_mps: Option<f64>,
}

/// One key's instrument instance as the play loop sees it: one call per sample with the key
/// travel (m). Engines (the host JIT and interpreter here; the emulated board later)
/// implement it.
pub trait KeyEngine {
    /// Runs one sample with key travel `key_m` (m).
    fn step(&mut self, key_m: f64) -> KeySample;
}

/// A compiled instrument: (instrument name or path, overrides, program).
type Compiled = (String, Vec<(String, String)>, tactus_compiler::ir::Program);

/// A host engine instance: the JIT when compiled, else the interpreter.
struct HostKey<'a> {
    jit: Option<tactus_jit::JitInstance<'a>>,
    interp: tactus_compiler::interp::Instance<'a>,
    strike_id: usize,
    hammer_out: Option<usize>,
}

impl<'a> HostKey<'a> {
    fn new(
        program: &'a tactus_compiler::ir::Program,
        jit: Option<&'a tactus_jit::JitProgram>,
    ) -> Self {
        HostKey {
            jit: jit.map(tactus_jit::JitInstance::new),
            interp: tactus_compiler::interp::Instance::new(program),
            strike_id: program
                .events
                .iter()
                .position(|e| e.name == "strike" || e.name == "pluck")
                .unwrap_or(0),
            hammer_out: program.outputs.iter().position(|o| o.name == "hammer_pos"),
        }
    }
}

impl KeyEngine for HostKey<'_> {
    fn step(&mut self, key_m: f64) -> KeySample {
        let x = [key_m];
        let out = match &mut self.jit {
            Some(j) => j.step(&x),
            None => self.interp.step(&x),
        };
        KeySample {
            force_n: out.total,
            hammer_m: self.hammer_out.map_or(f64::NAN, |i| out.outputs[i]),
            strike_mps: out
                .events
                .iter()
                .find(|(e, _)| e.index() == self.strike_id)
                .map(|(_, a)| a.first().copied().unwrap_or(0.0)),
        }
    }
}

/// A fixed-point instance: the fixed JIT of the program, its words read back in SI.
struct FixedKey<'a> {
    jit: tactus_jit::fixed::FixedJitInstance<'a>,
    fp: &'a tactus_compiler::fixed::FixedProgram,
    strike_id: usize,
    hammer_out: Option<usize>,
}

impl KeyEngine for FixedKey<'_> {
    fn step(&mut self, key_m: f64) -> KeySample {
        let fp = self.fp;
        let out = self.jit.step(&[key_m]);
        let si = tactus_runtime::fixed::to_f64;
        KeySample {
            force_n: si(out.total, fp.total_frac),
            hammer_m: self
                .hammer_out
                .map_or(f64::NAN, |i| si(out.outputs[i], fp.output_frac[i])),
            strike_mps: out
                .events
                .iter()
                .find(|(e, _)| e.index() == self.strike_id)
                .map(|(e, a)| {
                    a.first()
                        .map_or(0.0, |&w| si(w, fp.event_frac[e.index()][0]))
                }),
        }
    }
}

/// The engine of one key: a host f64 engine or the fixed-point JIT.
enum AnyKey<'a> {
    Host(Box<HostKey<'a>>),
    Fixed(Box<FixedKey<'a>>),
}

impl KeyEngine for AnyKey<'_> {
    fn step(&mut self, key_m: f64) -> KeySample {
        match self {
            AnyKey::Host(k) => k.step(key_m),
            AnyKey::Fixed(k) => k.step(key_m),
        }
    }
}

/// One simulated hammer strike.
struct Strike {
    key: u8,
    time_s: f64,
    speed_mps: f64,
    /// The input note it answers: the note-on of its key nearest in time, if within 50 ms.
    answers: Option<performance::Note>,
}

/// MIDI velocity for a hammer-head speed at the strike (m/s):
/// `v = 1 + 126 · ln(speed / 0.1 m/s) / ln(60)`, rounded and clamped to 1–127, so
/// 0.1 m/s → 1 and 6 m/s → 127. The end points span grand-piano hammer speeds from the
/// softest audible blow to *fff*; the map is logarithmic because reproducing pianos record
/// velocities close to logarithmic in hammer speed (the same assumption as the key-motion
/// model of `tactus_runtime::performance`, which is what keeps input and output velocities
/// in the same order). Its inverse is [`speed_for_velocity`].
pub fn midi_velocity(speed_mps: f64) -> u8 {
    let v = 1.0 + 126.0 * (speed_mps / 0.1).ln() / (6.0f64 / 0.1).ln();
    v.round().clamp(1.0, 127.0) as u8
}

/// The hammer speed (m/s) that [`midi_velocity`] maps to MIDI velocity `v`: its inverse,
/// `0.1 m/s · 60^((v − 1)/126)`.
pub fn speed_for_velocity(v: u8) -> f64 {
    0.1 * 60f64.powf((f64::from(v.clamp(1, 127)) - 1.0) / 126.0)
}

/// Peak finger forces of the calibration strokes, N (log-spaced from a push barely above a
/// piano key's down-weight to a hard *fff* blow).
pub const CALIBRATION_LEVELS_N: [f64; 14] = [
    0.6, 0.75, 0.9, 1.1, 1.4, 1.8, 2.3, 3.0, 4.0, 5.5, 7.5, 10.0, 14.0, 20.0,
];

/// Time a stroke waits for the key to rise after the previous note's finger lifted, s: a
/// note that follows sooner lifts the previous finger earlier.
const RISE_GAP_S: f64 = 0.030;

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

/// One busy stretch of a key to simulate from rest: its samples `first..first + n` and what
/// moves it (an index into the motions).
struct KeyJob {
    key: u8,
    first: usize,
    n: usize,
    motion: usize,
}

/// Simulated time before a key's first movement, s.
const LEAD_IN_S: f64 = 0.05;
/// Simulated time after a key's last movement ends, s (the hammer settles on its rest felt).
const TAIL_S: f64 = 0.5;
/// A key at rest for longer than this between two movements, s, is simulated as two
/// stretches, each from a fresh instance.
const IDLE_GAP_S: f64 = 1.0;

/// Merges movement intervals (start s, end s) into busy stretches: intervals closer than
/// [`IDLE_GAP_S`] belong to one stretch.
fn busy_stretches(mut busy: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    busy.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (a, b) in busy {
        match out.last_mut() {
            Some(last) if a - last.1 < IDLE_GAP_S => last.1 = last.1.max(b),
            _ => out.push((a, b)),
        }
    }
    out
}

// How a key moves, the trace rows (the last two columns, motor current and DAC code, only
// with `--engine emu`; `NaN` otherwise): defined with the firmware run.
use tactus_firmware::perform::{Motion, TraceRows, Traces};

fn run_inner(args: &PlayArgs) -> Result<ExitCode, String> {
    let mut perf = match &args.performance {
        Some(p) => {
            let (perf, warnings) =
                performance::read_midi_reporting(p).map_err(|e| e.to_string())?;
            for w in warnings {
                eprintln!("warning: {w}");
            }
            perf
        }
        None => performance::demo(),
    };
    if let Some(s) = args.seconds {
        if !(s.is_finite() && s > 0.0) {
            return Err(format!("--seconds must be a positive number, got {s}"));
        }
        perf.notes.retain(|n| n.on_s < s);
        // `--seconds` bounds the simulated time: a note still held at `s` is released there.
        for n in &mut perf.notes {
            n.off_s = n.off_s.min(s);
        }
        perf.duration_s = perf.duration_s.min(s);
        if perf.notes.is_empty() {
            return Err(format!(
                "{}: no note starts in the first {s} s",
                args.performance
                    .as_ref()
                    .map_or("the demo".to_string(), |p| p.display().to_string())
            ));
        }
    }
    // Which instrument (with which overrides) on which key.
    let mut layout_boards = None;
    let assignments = match &args.layout {
        Some(l) => {
            let (layout, keys) = tactus_runtime::keyboard::read_layout(l)?;
            layout_boards =
                tactus_runtime::keyboard::board_keys(&layout, &l.display().to_string(), &keys)?;
            keys
        }
        None if args.instrument.is_none() => {
            let name = "grand88 (built in)";
            let layout = tactus_runtime::keyboard::parse_layout(source::GRAND88_LAYOUT, name)?;
            let keys = tactus_runtime::keyboard::assign(&layout, name, Path::new(""))?;
            layout_boards = tactus_runtime::keyboard::board_keys(&layout, name, &keys)?;
            keys
        }
        None => {
            let name = args.instrument.clone().unwrap_or_default();
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
    let skipped = outside.len();
    let perf = Performance {
        notes: inside.into_iter().copied().collect(),
        ..perf
    };
    // One compiled program per distinct (instrument, overrides), shared by its keys.
    let mut programs: Vec<Compiled> = Vec::new();
    let mut key_program = BTreeMap::new();
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
                if program.is_pen() || program.sensors.len() > 1 {
                    return Err(format!(
                        "instrument `{}` (key {}) reads {} sensors{}: `tactus play` moves one \
                         key sensor per key; run a pen with \
                         `tactus sim <instrument> --stimulus <pen gesture>`",
                        program.name,
                        a.key,
                        program.sensors.len(),
                        if program.is_pen() {
                            " and pushes a 3-D force (a pen)"
                        } else {
                            ""
                        }
                    ));
                }
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
        PlayEngine::Interp | PlayEngine::Fixed | PlayEngine::Emu => {
            programs.iter().map(|_| None).collect()
        }
    };
    // The fixed-point JIT runs the keys with `--engine fixed`, and calibrates the force
    // player for `--engine emu` (the same bits as the firmware's update).
    let fixed_needed = args.engine == PlayEngine::Fixed
        || (args.engine == PlayEngine::Emu && args.player == Player::Force);
    let fs = programs
        .first()
        .map_or(tactus_runtime::DEFAULT_SAMPLE_RATE_HZ, |p| {
            p.2.sample_rate_hz
        });
    // Every key of the layout with its params (`--param` last): what the firmware runs,
    // played or not (as on the hardware), and what `--engine fixed` compiles with it.
    let all: Vec<tactus_runtime::keyboard::KeyAssignment> = assignments
        .iter()
        .map(|a| {
            let mut a = a.clone();
            a.params.extend(args.params.iter().cloned());
            a
        })
        .collect();
    // They run the programs the firmware runs: every key of the layout compiled together,
    // so that an instrument's graded params are run-time data planned over the interval
    // all its keys span ([`tactus_firmware::image::compile_layout`]); each played program
    // is the shared code with the param block of its first key.
    let fixed_programs: Vec<tactus_firmware::image::Program> = match fixed_needed {
        true => {
            let source = |name: &str| source::load(name).map(|s| s.text);
            let (shared, index) = tactus_firmware::image::compile_layout(&all, &source, fs)
                .map_err(|e| format!("fixed point: {e}"))?;
            (0..programs.len())
                .map(|pi| {
                    all.iter()
                        .position(|a| key_program.get(&a.key) == Some(&pi))
                        .map(|i| shared[index[i]].clone())
                        .ok_or_else(|| format!("program {pi} has no key"))
                })
                .collect::<Result<_, _>>()?
        }
        _ => Vec::new(),
    };
    // One fixed JIT per distinct code.
    let mut fixed_jits: Vec<(usize, tactus_jit::fixed::FixedJitProgram)> = Vec::new();
    for (pi, p) in fixed_programs.iter().enumerate() {
        if !fixed_jits
            .iter()
            .any(|(q, _)| fixed_programs[*q].same_code(p))
        {
            let j = tactus_jit::fixed::FixedJitProgram::compile(&p.fixed)
                .map_err(|e| format!("fixed JIT: {e}"))?;
            fixed_jits.push((pi, j));
        }
    }
    let engine_for = |pi: usize| -> AnyKey<'_> {
        let jit = fixed_programs.get(pi).and_then(|p| {
            fixed_jits
                .iter()
                .find(|(q, _)| fixed_programs[*q].same_code(p))
                .map(|(_, j)| (p, j))
        });
        match jit {
            Some((p, j)) => {
                let fp = &*p.fixed;
                AnyKey::Fixed(Box::new(FixedKey {
                    jit: tactus_jit::fixed::FixedJitInstance::with_params(j, &p.params),
                    fp,
                    strike_id: fp
                        .program
                        .events
                        .iter()
                        .position(|e| e.name == "strike" || e.name == "pluck")
                        .unwrap_or(0),
                    hammer_out: fp
                        .program
                        .outputs
                        .iter()
                        .position(|o| o.name == "hammer_pos"),
                }))
            }
            None => AnyKey::Host(Box::new(HostKey::new(&programs[pi].2, jits[pi].as_ref()))),
        }
    };
    let dip_of = |key: u8| programs[key_program[&key]].2.sensors[0].range.1;
    let finger = FingerConfig::default();
    // The force player's calibration, per program.
    let calibrations: Vec<Option<Calibration>> = match args.player {
        Player::Position => programs.iter().map(|_| None).collect(),
        Player::Force => (0..programs.len())
            .map(|pi| {
                let dip = programs[pi].2.sensors[0].range.1;
                calibrate(|| engine_for(pi), dip, finger, fs)
                    .map(Some)
                    .ok_or_else(|| {
                        format!(
                            "instrument `{}`: no calibration stroke of {:?} N struck; the force player cannot play it",
                            programs[pi].0, CALIBRATION_LEVELS_N
                        )
                    })
            })
            .collect::<Result<_, _>>()?,
    };
    // One job per busy stretch of each played key (see the module documentation).
    let mut motions = Vec::new();
    let mut jobs = Vec::new();
    for &key in key_program.keys() {
        let notes: Vec<performance::Note> = perf
            .notes
            .iter()
            .filter(|n| n.key == key)
            .copied()
            .collect();
        let (motion, busy): (Motion, Vec<(f64, f64)>) = match args.player {
            Player::Position => {
                let track = performance::key_tracks(
                    &Performance {
                        notes: notes.clone(),
                        sustain: vec![],
                        duration_s: perf.duration_s,
                    },
                    dip_of(key),
                )
                .remove(0);
                let busy = notes
                    .iter()
                    .map(|n| {
                        (
                            n.on_s - performance::MAX_DESCENT_S,
                            n.off_s.max(n.on_s) + performance::RELEASE_S,
                        )
                    })
                    .collect();
                (Motion::Track(track), busy)
            }
            Player::Force => {
                let cal = calibrations[key_program[&key]]
                    .as_ref()
                    .expect("calibrated");
                let profile = finger_profile(&notes, cal, finger);
                let busy = profile
                    .strokes()
                    .iter()
                    .map(|s| (s.start_s, s.lift_s))
                    .collect();
                (Motion::Finger(profile), busy)
            }
        };
        motions.push(motion);
        for (start_s, end_s) in busy_stretches(busy) {
            let a = ((start_s - LEAD_IN_S).max(0.0) * fs) as usize;
            let b = ((end_s + TAIL_S) * fs) as usize;
            jobs.push(KeyJob {
                key,
                motion: motions.len() - 1,
                first: a,
                n: b.saturating_sub(a),
            });
        }
    }
    let traced: BTreeSet<u8> = args.trace_keys.iter().copied().collect();
    for k in &traced {
        if !key_program.contains_key(k) {
            eprintln!(
                "warning: traced key {k} is never played: it stays at rest, no trace written"
            );
        }
    }
    let trace_to = args.trace_to.unwrap_or(f64::INFINITY);
    let total_samples: u64 = jobs.iter().map(|j| j.n as u64).sum();
    let bar = ProgressBar::new(total_samples);
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} {msg} [{bar:30}] {percent}% {per_sec} key-samples, eta {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_message(format!("{} keys", key_program.len()));
    let started = Instant::now();
    let mut strikes = Vec::new();
    let mut traces: BTreeMap<u8, TraceRows> = BTreeMap::new();
    let mut emu_report = None;
    let mut emu_samples = 0usize;
    if args.engine == PlayEngine::Emu {
        let key_motions: BTreeMap<u8, &Motion> =
            jobs.iter().map(|j| (j.key, &motions[j.motion])).collect();
        let end = jobs.iter().map(|j| j.first + j.n).max().unwrap_or(0);
        emu_samples = end;
        bar.set_length(end as u64 * all.len() as u64);
        bar.set_style(music_style(all.len() as f64 * fs));
        bar.set_message(format!("{} keys on their boards", all.len()));
        let trace = EmuTrace {
            keys: &traced,
            from_s: args.trace_from,
            to_s: trace_to,
        };
        let opts = EmuOptions {
            board: &args.board,
            end,
            fs,
            finger,
            trace,
            boards: layout_boards.clone(),
            emu: args.emu,
            quiescent_guard: !args.no_quiescent_guard,
        };
        let (s, report, t) = emu_strikes(&all, &key_motions, &opts, &bar)?;
        strikes = s;
        traces = t;
        emu_report = Some(report);
    }
    for job in jobs.iter().filter(|_| args.engine != PlayEngine::Emu) {
        let pi = key_program[&job.key];
        let mut engine = engine_for(pi);
        let mut rows = traced.contains(&job.key).then(TraceRows::new);
        let mut finger_player = ForcePlayer::new(dip_of(job.key), finger.mass_kg, fs);
        for i in 0..job.n {
            let time = (job.first + i) as f64 / fs;
            let (x, push) = match &motions[job.motion] {
                Motion::Track(t) => (t.position(time), 0.0),
                Motion::Finger(p) => (finger_player.x_m, p.force(time)),
            };
            let s = engine.step(x);
            // The f64 engines can lose the program's meaning (a division by zero, an
            // overflow): stop at the first such sample rather than play NaN.
            if !s.force_n.is_finite() || s.strike_mps.is_some_and(|v| !v.is_finite()) {
                return Err(format!(
                    "key {}: the simulation computed a non-finite value at sample {} (t = {time:.6} s): force {} N, strike speed {:?} m/s",
                    job.key,
                    job.first + i,
                    s.force_n,
                    s.strike_mps
                ));
            }
            if let Motion::Finger(_) = motions[job.motion] {
                finger_player.step(push, s.force_n);
            }
            if let Some(speed) = s.strike_mps {
                strikes.push(Strike {
                    key: job.key,
                    time_s: time,
                    speed_mps: speed,
                    answers: None,
                });
            }
            if let Some(r) = &mut rows {
                if time >= args.trace_from && time <= trace_to {
                    r.push([time, x, s.force_n, s.hammer_m, push, f64::NAN, f64::NAN]);
                }
            }
            if i % 65_536 == 65_535 {
                bar.inc(65_536);
            }
        }
        bar.inc((job.n % 65_536) as u64);
        if let Some(r) = rows {
            traces.entry(job.key).or_default().extend(r);
        }
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
    let mut wrote = Vec::new();
    let csv = args.out.join(format!("{stem}-strikes.csv"));
    let matched = write_strikes_csv(&csv, &strikes)?;
    wrote.push(csv);
    let mid = args.out.join(format!("{stem}-strikes.mid"));
    write_midi(&mid, &strikes)?;
    wrote.push(mid);
    if !args.no_wav {
        let wav = args.out.join(format!("{stem}.wav"));
        write_wav(&wav, &strikes, &perf, fs)?;
        wrote.push(wav);
    }
    if !traces.is_empty() {
        let emu = args.engine == PlayEngine::Emu;
        wrote.extend(write_traces(&args.out, &stem, &traces, emu)?);
    }
    // Notes no strike answers: the instrument did not sound them.
    let silent: Vec<&performance::Note> = perf
        .notes
        .iter()
        .filter(|n| {
            !strikes.iter().any(|s| {
                s.answers
                    .is_some_and(|a| a.key == n.key && a.on_s == n.on_s)
            })
        })
        .collect();
    for n in silent.iter().take(10) {
        eprintln!(
            "warning: note {} at {:.3} s (velocity {}) produced no strike within 50 ms",
            n.key, n.on_s, n.velocity
        );
    }
    if silent.len() > 10 {
        eprintln!(
            "warning: … and {} more notes without a strike",
            silent.len() - 10
        );
    }
    let audio_s = perf.duration_s;
    println!(
        "{}: {} notes on {} keys ({} player) → {} strikes ({} answer a note within 50 ms; {} note{} without a strike); {} note{} outside the layout skipped",
        stem,
        perf.notes.len(),
        key_program.len(),
        match args.player {
            Player::Position => "position",
            Player::Force => "force",
        },
        strikes.len(),
        matched,
        silent.len(),
        if silent.len() == 1 { "" } else { "s" },
        skipped,
        if skipped == 1 { "" } else { "s" },
    );
    println!(
        "  {} key-samples in {:.2} s: real-time factor {:.2} ({:.2} s of music; above 1 is faster than real time); peak memory {}",
        emu_report.as_ref().map_or(total_samples, |r| r
            .boards
            .iter()
            .map(|b| b.keys.len() as u64)
            .sum::<u64>()
            * emu_samples as u64),
        wall,
        audio_s / wall.max(1e-9),
        audio_s,
        peak_memory().map_or("unknown".to_string(), |kb| format!("{:.1} MB", kb as f64 / 1024.0)),
    );
    if args.player == Player::Force {
        // What the finger can do on each instrument, and how many notes asked for more.
        for (pi, cal) in calibrations.iter().enumerate() {
            let Some(cal) = cal else { continue };
            let l = cal.levels();
            let (lo, hi) = (l[0].2, l[l.len() - 1].2);
            let outside = perf
                .notes
                .iter()
                .filter(|n| key_program.get(&n.key) == Some(&pi))
                .filter(|n| {
                    let v = speed_for_velocity(n.velocity);
                    // Half a MIDI velocity step of slack: the ends are measured, not exact.
                    v < lo * 0.985 || v > hi * 1.015
                })
                .count();
            println!(
                "  force player on `{}`: finger pushes {:.2}–{:.1} N give hammer speeds {:.2}–{:.2} m/s (MIDI {}–{}); {} note{} outside that range played at its nearest end",
                programs[pi].0,
                l[0].0,
                l[l.len() - 1].0,
                lo,
                hi,
                midi_velocity(lo),
                midi_velocity(hi),
                outside,
                if outside == 1 { "" } else { "s" },
            );
        }
    }
    for w in &wrote {
        println!("  wrote {}", w.display());
    }
    match &emu_report {
        Some(r) => {
            // One line per board; beyond eight boards, the busiest and the mean of all.
            let named: Vec<(String, Vec<u64>)> = if r.boards.len() <= 8 {
                r.boards
                    .iter()
                    .enumerate()
                    .map(|(i, b)| {
                        (
                            format!("board {} ({})", i + 1, tactus_firmware::verdict::key_ranges(&b.keys)),
                            b.cycles.clone(),
                        )
                    })
                    .collect()
            } else {
                let n = r.boards.iter().map(|b| b.cycles.len()).max().unwrap_or(0);
                let at = |i: usize| r.boards.iter().filter_map(move |b| b.cycles.get(i).copied());
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
            let series: Vec<(String, &[u64])> =
                named.iter().map(|(l, v)| (l.clone(), v.as_slice())).collect();
            let path = args.out.join(format!("{stem}-cycles.svg"));
            plot::plot_cycle_series(
                &series,
                fs / r.decimation as f64,
                r.deadline,
                &format!("{stem}: cycles per sample, busier core of each board (max per {} samples)", r.decimation),
                &path,
            )
            .map_err(|e| e.to_string())?;
            println!("  wrote {}", path.display());
            println!(
                "  budget of the run on {} {} boards ({} cycles per sample per core; every key of every board every sample):",
                r.boards.len(),
                r.board,
                r.deadline
            );
            for (i, b) in r.boards.iter().enumerate() {
                let cores: Vec<String> = (0..b.max.len())
                    .map(|c| {
                        format!(
                            "core {c}: {} keys, max {} cycles per sample ({:.1} %, static {}, mean {:.1} %), headroom {}, deadline misses {}",
                            b.core_keys[c],
                            b.max[c],
                            100.0 * b.max[c] as f64 / r.deadline as f64,
                            b.bound[c],
                            100.0 * b.total[c] as f64 / (r.samples.max(1) * r.deadline) as f64,
                            r.deadline as i64 - b.max[c] as i64,
                            b.misses[c]
                        )
                    })
                    .collect();
                println!(
                    "    board {} (keys {}): {}",
                    i + 1,
                    tactus_firmware::verdict::key_ranges(&b.keys),
                    cores.join("; ")
                );
            }
            if r.boards.iter().any(|b| b.misses.iter().any(|m| *m > 0)) {
                eprintln!("error: the firmware missed sample deadlines: some board's keys do not fit it (see `tactus budget`)");
                return Ok(ExitCode::FAILURE);
            }
        }
        None => println!(
            "  budget: not checked (host engine; `--engine emu` runs the firmware on the emulated board)"
        ),
    }
    Ok(ExitCode::SUCCESS)
}

/// The progress bar of `--engine emu`, whose position counts key-samples
/// (`key_samples_per_s` per second of music): music time done and in all, the real-time
/// factor so far and the time left.
fn music_style(key_samples_per_s: f64) -> ProgressStyle {
    let k = key_samples_per_s.max(1.0);
    ProgressStyle::with_template(
        "{spinner} {msg} [{bar:30}] {music} of music, real-time factor {rtf}, eta {eta}",
    )
    .unwrap_or_else(|_| ProgressStyle::default_bar())
    .with_key(
        "music",
        move |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
            let total = s.len().map_or(0.0, |l| l as f64 / k);
            let _ = write!(w, "{:.1} s / {total:.1} s", s.pos() as f64 / k);
        },
    )
    .with_key(
        "rtf",
        move |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
            let secs = s.elapsed().as_secs_f64();
            let _ = match secs > 0.0 {
                true => write!(w, "{:.2}", s.pos() as f64 / k / secs),
                false => write!(w, "–"),
            };
        },
    )
}

/// The most samples one `--engine emu` run may cover (2²⁶, 25 minutes at 44.1 kHz): a
/// stray event hours into a MIDI file would otherwise start a run of hours.
const MAX_EMU_SAMPLES: usize = 1 << 26;

/// What the emulated boards reported over a run.
struct EmuReport {
    board: String,
    /// Cycles per sample per core (the deadline).
    deadline: u64,
    /// Per board of the keyboard.
    boards: Vec<tactus_firmware::perform::BoardRun>,
    /// Samples per point of [`BoardRun::cycles`].
    decimation: usize,
    /// Samples run.
    samples: u64,
}

/// What `--engine emu` records per traced key ([`emu_strikes`]).
struct EmuTrace<'a> {
    /// The traced keys (MIDI numbers).
    keys: &'a BTreeSet<u8>,
    /// Trace from this time on, s.
    from_s: f64,
    /// Trace until this time, s.
    to_s: f64,
}

/// How [`emu_strikes`] runs: the board, the samples, the finger of the force player and
/// the traces.
struct EmuOptions<'a> {
    /// Board name or file (`--board`).
    board: &'a str,
    /// Samples to run, from sample 0.
    end: usize,
    /// Sample rate, Hz.
    fs: f64,
    /// The finger of the force player.
    finger: FingerConfig,
    /// What to trace.
    trace: EmuTrace<'a>,
    /// The layout's boards (MIDI keys per board), or `None` to plan them as `tactus budget`
    /// does.
    boards: Option<Vec<Vec<u8>>>,
    /// The emulator's engine.
    emu: crate::budget_cmd::EmuEngine,
    /// Whether the firmware guards quiescent keys.
    quiescent_guard: bool,
}

/// Plays the keys through the firmware of every board of the keyboard
/// ([`tactus_firmware::perform::play_boards`]): the boards as the layout lists them or as
/// `tactus budget` plans them, every key of every board every sample.
fn emu_strikes(
    all: &[tactus_runtime::keyboard::KeyAssignment],
    motions: &BTreeMap<u8, &Motion>,
    opts: &EmuOptions,
    bar: &ProgressBar,
) -> Result<(Vec<Strike>, EmuReport, Traces), String> {
    let (end, fs) = (opts.end, opts.fs);
    // Bounded before anything runs or is allocated per sample.
    if end > MAX_EMU_SAMPLES {
        return Err(format!(
            "--engine emu: the piece is {:.1} s long, more than the {:.0} s ({MAX_EMU_SAMPLES} samples) one emulated run may cover; play a part of it with --seconds",
            end as f64 / fs,
            MAX_EMU_SAMPLES as f64 / fs
        ));
    }
    let board = crate::budget_cmd::board_named(opts.board)?;
    let source = |name: &str| source::load(name).map(|s| s.text);
    let (programs, key_programs) = tactus_firmware::image::compile_layout(all, &source, fs)
        .map_err(|e| format!("firmware: {e}"))?;
    let keys: Vec<u8> = all.iter().map(|a| a.key).collect();
    let popts = tactus_firmware::perform::PerformOptions {
        end: opts.end,
        fs,
        finger: opts.finger,
        trace_keys: opts.trace.keys.clone(),
        trace_from_s: opts.trace.from_s,
        trace_to_s: opts.trace.to_s,
        boards: opts.boards.clone(),
        limiter: tactus_runtime::limiter::LimiterConfig {
            sample_rate_hz: board.sample_rate_hz,
            ..Default::default()
        },
        engine: opts.emu.into(),
        quiescent_guard: opts.quiescent_guard,
    };
    let run = tactus_firmware::perform::play_boards(
        &programs,
        &keys,
        &key_programs,
        &board,
        motions,
        &popts,
        &|n| bar.inc(n),
    )
    .map_err(|e| format!("firmware: {e}"))?;
    let mut strikes = Vec::new();
    let mut traces = Traces::new();
    let mut boards = Vec::with_capacity(run.boards.len());
    for mut b in run.boards {
        strikes.extend(b.strikes.drain(..).map(|s| Strike {
            key: s.key,
            time_s: s.time_s,
            speed_mps: s.speed_mps,
            answers: None,
        }));
        traces.append(&mut b.traces);
        boards.push(b);
    }
    let report = EmuReport {
        board: board.name.clone(),
        deadline: board.cycles_per_sample(),
        boards,
        decimation: run.decimation,
        samples: opts.end as u64,
    };
    Ok((strikes, report, traces))
}

/// Measures single strokes at [`CALIBRATION_LEVELS_N`] on fresh instances of one instrument
/// (key at rest, push held until the strike or 0.6 s): the lead from the start of the push
/// to the strike and the strike's hammer speed. `None` when fewer than two levels strike.
fn calibrate<E: KeyEngine>(
    mut fresh: impl FnMut() -> E,
    dip_m: f64,
    finger: FingerConfig,
    fs: f64,
) -> Option<Calibration> {
    let start = 0.01;
    let levels = CALIBRATION_LEVELS_N
        .iter()
        .filter_map(|&peak| {
            let profile = ForceProfile::new(
                finger,
                vec![Stroke {
                    start_s: start,
                    peak_n: peak,
                    push_end_s: 10.0,
                    lift_s: 10.0,
                }],
            );
            let mut engine = fresh();
            let mut key = ForcePlayer::new(dip_m, finger.mass_kg, fs);
            for i in 0..(0.6 * fs) as usize {
                let t = i as f64 / fs;
                let s = engine.step(key.x_m);
                if let Some(v) = s.strike_mps {
                    return Some((peak, t - start, v));
                }
                key.step(profile.force(t), s.force_n);
            }
            None
        })
        .collect();
    Calibration::new(levels)
}

/// The finger's strokes for one key's notes: each aims at the hammer speed of its MIDI
/// velocity ([`speed_for_velocity`]) with the calibrated force, starts the calibrated lead
/// before its note-on, pushes until 10 ms after the note-on, holds until the note-off and
/// lifts then — or [`RISE_GAP_S`] before the next stroke, if that comes sooner.
fn finger_profile(
    notes: &[performance::Note],
    cal: &Calibration,
    finger: FingerConfig,
) -> ForceProfile {
    let mut strokes: Vec<Stroke> = notes
        .iter()
        .map(|n| {
            let (peak, lead) = cal.for_speed(speed_for_velocity(n.velocity));
            let start = (n.on_s - lead).max(0.0);
            let push_end = n.on_s.max(start) + 0.010;
            Stroke {
                start_s: start,
                peak_n: peak,
                push_end_s: push_end,
                lift_s: n.off_s.max(push_end),
            }
        })
        .collect();
    for i in 1..strokes.len() {
        let next = strokes[i].start_s;
        let prev = &mut strokes[i - 1];
        prev.lift_s = prev.lift_s.min(next - RISE_GAP_S).max(prev.start_s);
        prev.push_end_s = prev.push_end_s.min(prev.lift_s);
    }
    ForceProfile::new(finger, strokes)
}

/// Peak resident memory of this process (`VmHWM` of `/proc/self/status`), kB; `None` where
/// there is no such file (not Linux).
fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Writes the strikes through the modal voice of `tactus_runtime::voice` as a 16-bit mono
/// WAV at the sample rate `fs` (Hz), normalised to 90 % of full scale. A strike's damper
/// falls at the note-off of the note it answers (300 ms after a strike that answers none),
/// or later while the sustain pedal is down.
fn write_wav(path: &Path, strikes: &[Strike], perf: &Performance, fs: f64) -> Result<(), String> {
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
        return Err(format!(
            "{}: the piece is {last:.1} s long, more than the {:.0} s a WAV rendering may have; use --no-wav or --seconds",
            path.display(),
            voice::MAX_RENDER_SAMPLES as f64 / fs - 2.0
        ));
    }
    let samples = voice::render(&notes, last + 2.0, fs);
    let scale = voice::i16_scale(&samples, 0.9);
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: fs.round() as u32,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let err = |e: hound::Error| format!("{}: cannot write: {e}", path.display());
    let mut w = hound::WavWriter::create(path, spec).map_err(err)?;
    for &x in &samples {
        w.write_sample(voice::to_i16(x, scale)).map_err(err)?;
    }
    w.finalize().map_err(err)
}

/// Writes one CSV per traced key (`STEM-key<K>.csv`: time_s, key_travel_m, force_n,
/// hammer_pos_m, finger_force_n, and with `emu` (rows from the firmware on the emulated
/// board) motor_current_a and dac_code) and the plots `STEM-force.svg` (instrument force, and the
/// finger's with the force player, vs time) and `STEM-hammer.svg` (hammer position vs
/// time); returns the files written.
fn write_traces(
    out: &Path,
    stem: &str,
    traces: &BTreeMap<u8, TraceRows>,
    emu: bool,
) -> Result<Vec<PathBuf>, String> {
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
    // The motor current and DAC code only from the firmware (`--engine emu`).
    let columns = if emu { 7 } else { 5 };
    for (key, rows) in traces {
        let path = out.join(format!("{stem}-key{key}.csv"));
        let err = |e: csv::Error| format!("{}: {e}", path.display());
        let mut w = csv::Writer::from_path(&path).map_err(err)?;
        w.write_record(&header[..columns]).map_err(err)?;
        for r in rows {
            w.write_record(r[..columns].iter().map(|v| v.to_string()))
                .map_err(err)?;
        }
        w.flush().map_err(|e| format!("{}: {e}", path.display()))?;
        wrote.push(path);
    }
    let lines = |col: usize, scale: f64| -> Vec<plot::Line> {
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
                plot::Line {
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
    plot::plot_lines(
        &force_lines,
        &format!("{stem}: force at the key"),
        "time [s]",
        "force [N]",
        &force,
    )
    .map_err(|e| e.to_string())?;
    wrote.push(force);
    let hammer_lines = lines(3, 1e3);
    if hammer_lines
        .iter()
        .any(|l| l.y.iter().any(|v| v.is_finite()))
    {
        let hammer = out.join(format!("{stem}-hammer.svg"));
        plot::plot_lines(
            &hammer_lines,
            &format!("{stem}: hammer position"),
            "time [s]",
            "hammer travel [mm]",
            &hammer,
        )
        .map_err(|e| e.to_string())?;
        wrote.push(hammer);
    }
    Ok(wrote)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn busy_stretches_merge_only_short_rests() {
        let s = busy_stretches(vec![(5.0, 5.2), (0.0, 0.5), (1.2, 1.4), (0.4, 0.6)]);
        // 0.6 → 1.2 is a rest shorter than IDLE_GAP_S: one stretch; 1.4 → 5.0 is longer.
        assert_eq!(s, vec![(0.0, 1.4), (5.0, 5.2)]);
        assert!(busy_stretches(vec![]).is_empty());
    }

    #[test]
    fn velocity_and_speed_maps_are_inverse() {
        for v in 1..=127u8 {
            assert_eq!(midi_velocity(speed_for_velocity(v)), v);
        }
        assert_eq!(midi_velocity(0.1), 1);
        assert_eq!(midi_velocity(6.0), 127);
        assert_eq!(midi_velocity(100.0), 127);
        assert_eq!(midi_velocity(0.0), 1);
    }
}
