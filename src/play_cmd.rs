//! `tactus play`: parses the arguments, reads the performance and the layout, compiles the
//! played keys' instruments (rendering their diagnostics), hands the run to
//! [`tactus_firmware::play::play`] — the players, the one play loop, the strike rule and
//! the firmware of every board live there — and prints what it returns: the strikes' files,
//! the traces' plots, the calibration of the force player and, with `--engine emu`, the
//! budget of every board and core over the run.

use crate::check_cmd::parse_override;
use crate::plot;
use crate::source;
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use tactus_firmware::image::Program as FirmwareProgram;
use tactus_firmware::play::{self as play, corpus, strike, PlayConfig};
use tactus_firmware::play::{BoardsReport, TraceWindow};
use tactus_host::catalogue;
use tactus_host::keyboard::{self, Keyboard, KeyboardSpec};
use tactus_host::play::{self as host_play, PieceOptions};

use tactus_runtime::player::FingerConfig;

/// Arguments of `tactus play`.
#[derive(Debug, clap::Args)]
#[command(
    after_long_help = "Writes OUT/NAME-strikes.csv (one row per strike: key, time, hammer speed, MIDI velocity, \
the input note it answers), OUT/NAME-strikes.mid (the strikes as MIDI with velocities from the simulated hammer \
speed: 1 at 0.1 m/s to 127 at 6 m/s, logarithmic) and OUT/NAME.wav (the strikes through a synthesized modal \
piano voice, 44.1 kHz 16-bit mono, normalised). With --trace-keys: OUT/NAME-key<K>.csv per traced key (time, key \
travel, instrument force, hammer position, finger force), OUT/NAME-force.svg, OUT/NAME-key.svg and OUT/NAME-hammer.svg; \
with --engine emu the force is the firmware's force word (before the safety limiter), the hammer its hammer_pos \
output word, every sample of the trace window (the emulated keys run all the time), and two more columns: \
motor_current_a (the current the firmware's safety limiter allowed) and dac_code (the word it wrote to the DAC). \
Example: tactus play ../shared/data/performances/Maestro_1.mid --seconds 20 --trace-keys 60,64"
)]
pub struct PlayArgs {
    /// MIDI performance to play [default: a built-in 4.5 s demo]. Several files, or a
    /// directory of them (its *.mid, sorted): corpus mode — each played in turn with the
    /// same options, one progress bar over the corpus, and a summary of every piece in
    /// OUT/corpus.csv and OUT/corpus.json (a file that cannot be played is a row with its
    /// error; the run goes on).
    pub performances: Vec<PathBuf>,
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
    /// Board: a built-in name (`rp2040`, `rp2040_200mhz`, `rp2040_20mhz`) or a board file;
    /// every engine runs at its sample rate, `--engine emu` on its clock and cores
    /// [default: the layout's `board_kind`, else rp2040].
    #[arg(long, value_name = "NAME_OR_FILE")]
    pub board: Option<String>,
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
    /// The firmware of every board of the keyboard (`tactus_firmware::image`: Thumb updates,
    /// the safety limiter, a timer interrupt per core) on emulated RP2040s, every key every
    /// sample; reports cycles per core and deadline misses.
    Emu,
}

impl From<PlayEngine> for play::PlayEngine {
    fn from(e: PlayEngine) -> Self {
        match e {
            PlayEngine::Jit => play::PlayEngine::Jit,
            PlayEngine::Interp => play::PlayEngine::Interp,
            PlayEngine::Fixed => play::PlayEngine::Fixed,
            PlayEngine::Emu => play::PlayEngine::Emu,
        }
    }
}

/// Players of `tactus play`: what moves the keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Player {
    /// Key trajectories prescribed by the key-motion model (open loop).
    Position,
    /// A finger force profile against the instrument's force (closed loop).
    Force,
}

impl From<Player> for play::Player {
    fn from(p: Player) -> Self {
        match p {
            Player::Position => play::Player::Position,
            Player::Force => play::Player::Force,
        }
    }
}

/// Runs `tactus play`.
pub fn run(args: PlayArgs) -> ExitCode {
    let files = match corpus::expand(&args.performances) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    // The keyboard and its firmware, compiled once for every piece.
    let setup = match Setup::new(&args) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let corpus = files.len() > 1 || args.performances.iter().any(|p| p.is_dir());
    if corpus {
        return run_corpus(&args, &setup, &files);
    }
    match run_inner(&args, &setup, files.first().map(PathBuf::as_path), None) {
        Ok((c, _)) => c,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// What every piece is played on and with.
struct Setup {
    kb: Keyboard,
    firmware: Option<Vec<FirmwareProgram>>,
    config: PlayConfig,
    opts: PieceOptions,
}

impl Setup {
    /// The keyboard (resolved and compiled as `tactus budget` and `tactus build` do: every
    /// program for its board's sample rate), its firmware if the engine runs it, the run's
    /// configuration.
    fn new(args: &PlayArgs) -> Result<Setup, String> {
        let input = match (&args.layout, &args.instrument) {
            (Some(l), _) => l.display().to_string(),
            (None, Some(i)) => i.clone(),
            (None, None) => catalogue::DEFAULT_LAYOUT.to_string(),
        };
        let kb = keyboard::compile(
            &KeyboardSpec {
                input: &input,
                as_layout: Some(args.instrument.is_none()),
                board: args.board.as_deref(),
                keys: None,
                params: &args.params,
            },
            &mut source::report_compile,
        )
        .map_err(|e| e.to_string())?;
        let config = PlayConfig {
            engine: args.engine.into(),
            player: args.player.into(),
            finger: FingerConfig::default(),
            trace: TraceWindow {
                keys: args.trace_keys.iter().copied().collect(),
                from_s: args.trace_from,
                to_s: args.trace_to.unwrap_or(f64::INFINITY),
            },
            board: kb.board.clone(),
            emulator: args.emu.into(),
            quiescent_guard: !args.no_quiescent_guard,
        };
        let firmware = match config.needs_firmware() {
            true => Some(kb.firmware().map_err(|e| format!("firmware: {e}"))?),
            false => None,
        };
        let opts = PieceOptions {
            seconds: args.seconds,
            out: args.out.clone(),
            wav: !args.no_wav,
        };
        Ok(Setup {
            kb,
            firmware,
            config,
            opts,
        })
    }
}

/// Corpus mode: every file in turn, one row each, the table printed and written.
fn run_corpus(args: &PlayArgs, setup: &Setup, files: &[PathBuf]) -> ExitCode {
    let multi = MultiProgress::new();
    let outer = multi.add(ProgressBar::new(files.len() as u64));
    outer.set_style(
        ProgressStyle::with_template(
            "{msg} [{bar:30}] {pos}/{len} pieces, elapsed {elapsed}, eta {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut rows = Vec::with_capacity(files.len());
    for f in files {
        outer.set_message(format!("corpus: {}", f.display()));
        let row = match run_inner(args, setup, Some(f), Some(&multi)) {
            Ok((_, row)) => row,
            Err(e) => {
                multi.suspend(|| eprintln!("error: {}: {e}", f.display()));
                corpus::PieceRow::failed(f, e)
            }
        };
        rows.push(row);
        outer.inc(1);
    }
    outer.finish_and_clear();
    if let Err(e) = std::fs::create_dir_all(&args.out) {
        eprintln!("error: cannot create `{}`: {e}", args.out.display());
        return ExitCode::FAILURE;
    }
    println!(
        "corpus: {} performances ({})",
        rows.len(),
        match args.engine {
            PlayEngine::Emu => "the firmware of every board, emulated",
            _ => "host engine; no deadlines checked",
        }
    );
    print!("{}", corpus::table_text(&rows));
    if let Some(kb) = peak_memory() {
        println!("  peak memory of the run: {:.1} MB", kb as f64 / 1024.0);
    }
    for (path, write) in [
        (
            args.out.join("corpus.csv"),
            corpus::write_csv as fn(&Path, &[corpus::PieceRow]) -> Result<(), String>,
        ),
        (args.out.join("corpus.json"), corpus::write_json),
    ] {
        match write(&path, &rows) {
            Ok(()) => println!("  wrote {}", path.display()),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    if rows.iter().all(corpus::PieceRow::ok) {
        ExitCode::SUCCESS
    } else {
        eprintln!(
            "error: {} of {} performances failed or missed deadlines (see the table)",
            rows.iter().filter(|r| !r.ok()).count(),
            rows.len()
        );
        ExitCode::FAILURE
    }
}

/// The progress bar: key-samples on a host engine; music time, real-time factor and ETA on
/// the emulated boards.
struct Bar(ProgressBar);

impl play::Progress for Bar {
    fn start(&self, total: u64, per_second: Option<f64>) {
        self.0.set_length(total);
        match per_second {
            Some(k) => {
                self.0.set_style(music_style(k));
            }
            None => self.0.set_style(
                ProgressStyle::with_template(
                    "{spinner} {msg} [{bar:30}] {percent}% {per_sec} key-samples, eta {eta}",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            ),
        }
    }
    fn inc(&self, n: u64) {
        self.0.inc(n);
    }
}

/// Plays one performance (`None`: the demo) and prints what it returns; the row is the
/// corpus table's. `multi`: the corpus's progress bars, to which this piece's bar is added.
fn run_inner(
    args: &PlayArgs,
    setup: &Setup,
    performance: Option<&Path>,
    multi: Option<&MultiProgress>,
) -> Result<(ExitCode, corpus::PieceRow), String> {
    let bar = Bar(match multi {
        Some(m) => m.add(ProgressBar::new(0)),
        None => ProgressBar::new(0),
    });
    bar.0.set_message(match args.engine {
        PlayEngine::Emu => format!("{} keys on their boards", setup.kb.keys.len()),
        _ => "played keys".to_string(),
    });
    let mut warn = |w: String| bar.0.suspend(|| eprintln!("warning: {w}"));
    let piece = host_play::play_piece(
        &setup.kb,
        setup.firmware.as_deref(),
        performance,
        &setup.config,
        &setup.opts,
        &mut warn,
        &bar,
    )?;
    bar.0.finish_and_clear();
    let (played, perf, stem) = (&piece.played, &piece.perf, &piece.stem);
    let fs = setup.kb.board.sample_rate_hz;
    let mut wrote = piece.written.clone();
    if !played.traces.is_empty() {
        wrote.extend(plot::plot_play_traces(&args.out, stem, &played.traces)?);
    }
    // Notes no strike answers: the instrument did not sound them.
    let silent = &played.silent;
    let too_soft = silent
        .iter()
        .filter(|s| s.cause == play::Silence::TooSoft)
        .count();
    for s in silent
        .iter()
        .filter(|s| s.cause == play::Silence::Other)
        .take(10)
    {
        eprintln!(
            "warning: note {} at {:.3} s (velocity {}{}) produced no strike within 50 ms",
            s.note.key,
            s.note.on_s,
            s.note.velocity,
            s.since_previous_s.map_or(String::new(), |d| format!(
                ", {:.0} ms after the key's last note-on",
                d * 1e3
            ))
        );
    }
    if silent.len() - too_soft > 10 {
        eprintln!(
            "warning: … and {} more notes without a strike",
            silent.len() - too_soft - 10
        );
    }
    let (audio_s, wall, skipped) = (perf.duration_s, piece.wall_s, piece.skipped.len());
    let (strikes, matched) = (&played.strikes, piece.answering);
    println!(
        "{}: {} notes on {} keys ({} player) → {} strikes ({} answer a note within 50 ms; {} note{} without a strike{}); {} note{} outside the layout skipped",
        stem,
        perf.notes.len(),
        piece.key_program.len(),
        match args.player {
            Player::Position => "position",
            Player::Force => "force",
        },
        strikes.len(),
        matched,
        silent.len(),
        if silent.len() == 1 { "" } else { "s" },
        match (args.player, silent.is_empty()) {
            (Player::Force, false) => format!(
                ": {too_soft} too soft to reach the string, below the calibrated minimum; {} other",
                silent.len() - too_soft
            ),
            _ => String::new(),
        },
        skipped,
        if skipped == 1 { "" } else { "s" },
    );
    println!(
        "  {} key-samples in {:.2} s: real-time factor {:.2} ({:.2} s of music; above 1 is faster than real time); peak memory {}",
        played.key_samples,
        wall,
        audio_s / wall.max(1e-9),
        audio_s,
        peak_memory().map_or("unknown".to_string(), |kb| format!("{:.1} MB", kb as f64 / 1024.0)),
    );
    // What the finger can do on each instrument, and how many notes asked for more.
    for r in piece.finger_ranges() {
        let ((push_lo, push_hi), (lo, hi)) = (r.push_n, r.speed_mps);
        println!(
            "  force player on `{}`{}: finger pushes {push_lo:.2}–{push_hi:.1} N give hammer speeds {lo:.2}–{hi:.2} m/s on every key (MIDI {}–{}); {} note{} outside its key's range played at its nearest end",
            r.instrument,
            if r.sets > 1 { format!(" ({} parameter sets)", r.sets) } else { String::new() },
            strike::midi_velocity(lo),
            strike::midi_velocity(hi),
            r.outside,
            if r.outside == 1 { "" } else { "s" },
        );
    }
    // Notes the players could not play as recorded: said, not silently distorted.
    let mut rushed = played.rushed.clone();
    rushed.sort_by(|a, b| a.1.on_s.total_cmp(&b.1.on_s));
    for (key, r) in rushed.iter().take(5) {
        eprintln!(
            "warning: note {key} at {:.3} s (velocity {}) could not be placed as recorded: pressed in {:.1} ms where its velocity asks {:.1} ms{} ({})",
            r.on_s,
            r.velocity,
            r.pressed_s * 1e3,
            r.wanted_s * 1e3,
            if r.late_s > 1e-4 { format!(", reaching the bottom {:.1} ms late", r.late_s * 1e3) } else { String::new() },
            if r.on_s < r.wanted_s { "the piece starts too soon after it" } else { "the key was still moving for the previous note" }
        );
    }
    if rushed.len() > 5 {
        eprintln!(
            "warning: … {} notes in all could not be placed as recorded (pressed faster or late: louder, or late, than the recording)",
            rushed.len()
        );
    }
    let r = played.restrikes;
    if r.dropped > 0 {
        eprintln!(
            "warning: {} note{} left out: the key was still busy with earlier notes of a repetition past the note-on and the end of the piece",
            r.dropped,
            if r.dropped == 1 { "" } else { "s" }
        );
    }
    if r.restrikes > 0 || r.late > 0 {
        println!(
            "  force player: {} notes re-struck before their key was back at rest, {} of them with no time for the asked softness, played louder; {} notes started late (no calibrated push fit before the note-on)",
            r.restrikes, r.raised, r.late
        );
    }
    for w in &wrote {
        println!("  wrote {}", w.display());
    }
    let row = piece.row(performance.unwrap_or(Path::new("demo")));
    match &played.boards {
        Some(r) => {
            let path = args.out.join(format!("{stem}-cycles.svg"));
            plot::plot_play_cycles(r, fs, stem, &path)?;
            println!("  wrote {}", path.display());
            print_budget(r);
            if r.missed() {
                eprintln!("error: the firmware missed sample deadlines: some board's keys do not fit it (see `tactus budget`)");
                return Ok((ExitCode::FAILURE, row));
            }
        }
        None => println!(
            "  budget: not checked (host engine; `--engine emu` runs the firmware on the emulated board)"
        ),
    }
    Ok((ExitCode::SUCCESS, row))
}

/// Prints the budget of the run: per board and core the keys, the largest and mean cycles
/// per sample, the static bound, the headroom and the deadline misses.
fn print_budget(r: &BoardsReport) {
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

/// Peak resident memory of this process (`VmHWM` of `/proc/self/status`), kB; `None` where
/// there is no such file (not Linux).
fn peak_memory() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
