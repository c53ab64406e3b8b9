//! `tactus play`: parses the arguments, makes the keyboard's [`Session`]
//! (`tactus_host::session`: the players, the play loop, the strike rule and the firmware live
//! there), plays each performance through it and prints what it returns.

use crate::check_cmd::parse_override;
use crate::progress::{CorpusBar, PlayBar};
use crate::source;
use crate::values;
use indicatif::MultiProgress;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use tactus_host::catalogue;
use tactus_host::corpus_run::{Combo, Corpus, CorpusError, CorpusRun, CorpusSpec};
use tactus_host::keyboard::KeyboardSpec;
use tactus_host::play::shard::{Setup, Shard};
use tactus_host::play::{corpus, PlayConfig, TraceWindow};
use tactus_host::session::{self as host_play, PieceOptions, PlayError, Session};
use tactus_runtime::keyboard::BoardSpec;
use tactus_runtime::player::FingerConfig;

/// Arguments of `tactus play`.
#[derive(Debug, clap::Args)]
#[command(after_long_help = host_play::FILES_HELP)]
pub struct PlayArgs {
    /// MIDI performance to play [default: a built-in 4.5 s demo]. Several files, or a
    /// directory of them (its *.mid, sorted): corpus mode — each played in turn with the
    /// same options, one progress bar over the corpus, each piece's row written to
    /// OUT/results.jsonl as it is done, and a summary of every piece in OUT/corpus.csv and
    /// OUT/corpus.json (a file that cannot be played is a row with its error; the run goes
    /// on). Exit status: 1 when the firmware failed validation (a deadline missed, a note
    /// without a strike), else 2 when a piece could not be played.
    pub performances: Vec<PathBuf>,
    /// Instrument on every key A0…C8 (file or built-in name), instead of the layout. Given
    /// more than once (or with --layout), each is one keyboard of a corpus run.
    #[arg(long)]
    pub instrument: Vec<String>,
    /// Keyboard layout (TOML): instruments and param grading per key range [default: the
    /// built-in grand88, instruments/layouts/grand88.toml: the grand piano on A0…C8 with
    /// the hammer mass graded from 11 g to 3.5 g]. Given more than once, each is one
    /// keyboard of a corpus run (every piece on every keyboard and board; each pair's files
    /// in OUT/LAYOUT-BOARD/).
    #[arg(long)]
    pub layout: Vec<PathBuf>,
    /// Play only the first SECONDS of the performance.
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Engine: `emu` (the default: the compiled firmware of every board of the keyboard on
    /// emulated RP2040s, every key every sample, with each core's cycles and deadline
    /// misses), or for quick looks on the host `fixed` (the fixed-point JIT: the firmware's
    /// bits), `jit` (cranelift f64) or `interp` (the f64 reference interpreter), which
    /// simulate only the played keys and check no budget.
    #[arg(long, value_enum, default_value = "emu")]
    pub engine: values::PlayEngine,
    /// Board: a built-in name (`rp2040`, `rp2040_200mhz`, `rp2040_20mhz`; with converters,
    /// an ADC and a DAC per core driven over PIO with DMA, `rp2040_io`, `rp2040_io_200mhz`)
    /// or a board file; every engine runs at its sample rate, `--engine emu` on its clock
    /// and cores (and on a board with converters through them: the key positions into the
    /// emulated ADCs, the motor commands from the emulated DACs) [default: the layout's
    /// `board_kind`, else rp2040]. Given more than once, each is one board kind of a corpus
    /// run.
    #[arg(long, value_name = "NAME_OR_FILE")]
    pub board: Vec<String>,
    /// The emulator's engine for `--engine emu`: `block` (code compiled to native code with
    /// cranelift), `interp` (the interpreter) or `lock-step` (the machine with no accelerator, the
    /// reference; tens of times slower): the same cycles and strikes; compare their speed.
    #[arg(long, value_enum, default_value = "block")]
    pub emu: values::EmuEngine,
    /// Player: `position` (prescribed key trajectories) or `force` (a finger force profile
    /// against the instrument's force: the closed loop; with `--engine emu` against the
    /// firmware's force word each sample, calibrated with the fixed-point JIT).
    #[arg(long, value_enum, default_value = "position")]
    pub player: values::Player,
    /// Override a param on every key: `--param M_h=10 g`.
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_override)]
    pub params: Vec<(String, String)>,
    /// Keys to trace (MIDI numbers, comma-separated): a CSV per key and SVG plots of force
    /// and hammer position vs time (with `--engine emu` also the limited motor current and
    /// the DAC code).
    #[arg(long, value_delimiter = ',', value_name = "KEYS")]
    pub trace_keys: Vec<u8>,
    /// Trace from this time on, s (the performance's time; negative to see the lead-in a
    /// piece whose first notes start at once is run from, e.g. `--trace-from=-0.1`).
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
    /// With `--engine emu`: emulate every sample of a board at rest instead of replaying
    /// the period its state repeats with (the same results, exactly; slower: to check, or
    /// to time the emulator itself).
    #[arg(long)]
    pub no_rest_replay: bool,
    /// Do not write the WAV rendering.
    #[arg(long)]
    pub no_wav: bool,
    /// With `--engine emu` on a board with converters (`--board rp2040_io`): write every
    /// board's frames at the pins (each ADC sample, each DAC update, with their cycles)
    /// into DIR/board-NN.csv. A traced board emulates every sample (no rest replay).
    #[arg(long, value_name = "DIR")]
    pub io_trace: Option<PathBuf>,
    /// With `--engine emu`: play the piece as consecutive spans of SECONDS (the boards
    /// carry their whole state from one to the next: the same strikes and budget as one
    /// run) and print the budget of each span after the whole run's — where in a long
    /// recital the worst sample fell, and that its first span equals a run cut there.
    #[arg(long, value_name = "SECONDS", value_parser = parse_span)]
    pub span: Option<f64>,
    /// With `--engine emu`: inject a fault (repeatable), as comma-separated fields:
    /// `kind=open|short|stuck|jump|noise|adc-silent|dac-stall|hang|flip|brownout`, the
    /// target `note=MIDI` or `board=N,key=K` (`board=N,core=C` for the converters,
    /// `board=N` for a brown-out), `at=TIME` and optionally `until=TIME` (`1.5s`,
    /// `200ms`), and the kind's value (`code=`, `delta=`, `amplitude=`, `word=` and
    /// `bit=`); `hang` hangs that key's update alone (its core stops: the watchdog resets
    /// the board, the trip on that core's record). E.g. `--fault kind=open,note=60,at=1s,until=1.2s`. After the run each
    /// board's resets and fault words are printed (the kind the firmware's check named, the
    /// key, the time, the trips) and written to OUT/NAME-faults.csv; the syntax, the kinds
    /// and the report: docs/faults.md.
    #[arg(long = "fault", value_name = "FAULT", value_parser = parse_fault)]
    pub fault: Vec<tactus_host::fault::FaultSpec>,
    /// With `--engine emu`: the firmware's per-key sensor check (range and largest step
    /// per sample, and on a converter board the ADC's burst check; a trip sets the motors
    /// to zero force and the fault word) `on` or `off` on every key, the boards planned and
    /// priced with it [default: on, the firmware's own]. With it on and no `--fault`, a trip is a false alarm: exit 1.
    #[arg(long, value_name = "on|off", value_parser = parse_on_off)]
    pub sensor_check: Option<bool>,
    /// With `--engine emu`: the RP2040's watchdog (datasheet 4.7) `on` or `off` on every
    /// board: fed by core 0 only when both cores finished their sample, so a core caught
    /// in a loop resets the board (its motors at zero force until it boots again: play
    /// runs RAM images, which the boot ROM enters again with their data restored, a board's
    /// flash image boots from flash again, `tactus emu run`; both leave a `watchdog` fault
    /// word; a brown-out leaves a RAM image in USB boot); the boards planned and priced with its feed
    /// [default: the firmware's own]. Each reset is printed with the fault report (the
    /// kind, the time, the board); with no `--fault`, a reset is a false alarm: exit 1.
    /// docs/faults.md.
    #[arg(long, value_name = "on|off", value_parser = parse_on_off)]
    pub watchdog: Option<bool>,
    /// Output directory.
    #[arg(long, short, default_value = "out")]
    pub out: PathBuf,
    /// Corpus mode on a cluster: play only shard K of N (K from 1: 1/2 and 2/2 are the two
    /// halves). Each item — a piece on a keyboard on a board — belongs to one shard by a
    /// hash of its name (the file as listed, the layout or instrument, the board), whatever
    /// the order or number of files listed, so every task of a job array, given the same
    /// arguments, plays its own items. Its rows go to OUT/results-K-of-N.jsonl (the tasks
    /// may share OUT); `tactus corpus merge` makes the tables. Without it, a Slurm array
    /// task takes its shard from SLURM_ARRAY_TASK_ID (from SLURM_ARRAY_TASK_MIN, of
    /// SLURM_ARRAY_TASK_COUNT), a Kubernetes Indexed Job's pod from JOB_COMPLETION_INDEX
    /// (from 0) with --shard-count. Examples: examples/slurm/corpus.sbatch,
    /// examples/k8s/corpus-indexed-job.yaml.
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    pub shard: Option<Shard>,
    /// The number of shards, for a scheduler's index (JOB_COMPLETION_INDEX: the Job's
    /// completions; with Slurm, instead of SLURM_ARRAY_TASK_COUNT).
    #[arg(long, value_name = "N", conflicts_with = "shard")]
    pub shard_count: Option<u32>,
    /// Corpus mode: go on with the results file a killed task left in OUT (the same run:
    /// its manifest must match), playing only the items it does not hold.
    #[arg(long)]
    pub resume: bool,
}

/// A `--fault` (`tactus_host::fault`): its error names the field.
pub fn parse_fault(s: &str) -> Result<tactus_host::fault::FaultSpec, String> {
    s.parse()
        .map_err(|e: tactus_host::fault::FaultError| e.to_string())
}

/// `on` or `off`.
pub fn parse_on_off(s: &str) -> Result<bool, String> {
    match s {
        "on" => Ok(true),
        "off" => Ok(false),
        _ => Err(format!("`{s}`: `on` or `off`")),
    }
}

/// `--span`'s parser: a positive number of seconds.
fn parse_span(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("`{s}` is not a positive number of seconds")),
    }
}

/// `--shard`'s parser: [`Shard::parse`], whose message clap prints (exit 2).
fn parse_shard(s: &str) -> Result<Shard, String> {
    Shard::parse(s).map_err(|e| e.to_string())
}

/// Runs `tactus play`.
pub fn run(args: PlayArgs) -> ExitCode {
    let spec = CorpusSpec {
        performances: args.performances.clone(),
        layouts: args
            .layout
            .iter()
            .map(|l| l.display().to_string())
            .collect(),
        instruments: args.instrument.clone(),
        boards: args.board.clone(),
    };
    // Corpus mode: more than one item, a directory, or a corpus option.
    let corpus = args.performances.len() > 1
        || args.performances.iter().any(|p| p.is_dir())
        || args.layout.len() + args.instrument.len() > 1
        || args.board.len() > 1
        || args.shard.is_some()
        || args.shard_count.is_some()
        || args.resume;
    if corpus {
        return match Corpus::new(&spec) {
            Ok(c) => run_corpus(&args, c),
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::from(2)
            }
        };
    }
    // One piece (or the demo) on one keyboard.
    let combo = Combo {
        on: Setup {
            layout: spec.layouts.first().cloned(),
            instrument: spec.instruments.first().cloned(),
            board: spec.boards.first().cloned(),
        },
        folder: None,
    };
    let result = session(&args, &combo)
        .map_err(|e| e.to_string())
        .and_then(|session| {
            run_piece(
                &args,
                &session,
                args.performances.first().map(PathBuf::as_path),
                None,
            )
            .map(|(code, _)| code)
            .map_err(|e| e.to_string())
        });
    result.unwrap_or_else(|e| {
        eprintln!("error: {e}");
        ExitCode::FAILURE
    })
}

/// The keyboard of `combo` (its layout, its instrument on every key, or the built-in
/// default layout, on its board), the run's configuration and options (its files in
/// OUT/FOLDER when it has a folder).
fn session(args: &PlayArgs, combo: &Combo) -> Result<Session, PlayError> {
    let on = &combo.on;
    let input = (on.layout.clone())
        .or_else(|| on.instrument.clone())
        .unwrap_or_else(|| catalogue::DEFAULT_LAYOUT.to_string());
    let spec = KeyboardSpec {
        input: &input,
        as_layout: Some(on.instrument.is_none()),
        board: on.board.as_deref(),
        keys: None,
        params: &args.params,
    };
    let config = |board: BoardSpec| PlayConfig {
        span: args
            .span
            .map(|s| (s * board.sample_rate_hz).round().max(1.0) as usize),
        engine: args.engine.into(),
        player: args.player.into(),
        finger: FingerConfig::default(),
        trace: TraceWindow {
            keys: args.trace_keys.iter().copied().collect(),
            from_s: args.trace_from,
            to_s: args.trace_to.unwrap_or(f64::INFINITY),
        },
        board,
        emulator: args.emu.into(),
        quiescent_guard: !args.no_quiescent_guard,
        rest_replay: !args.no_rest_replay,
        io_trace: args.io_trace.clone(),
        faults: args.fault.clone(),
        sensor_check: args.sensor_check,
        watchdog: args.watchdog,
    };
    let opts = PieceOptions {
        seconds: args.seconds,
        out: match &combo.folder {
            Some(f) => args.out.join(f),
            None => args.out.clone(),
        },
        wav: !args.no_wav,
    };
    Session::new(&spec, config, opts, &mut source::report_compile)
}

/// The shard this task plays: `--shard`, else a scheduler's index, else the whole corpus;
/// and where it came from, to print.
fn shard(args: &PlayArgs) -> Result<(Shard, Option<String>), String> {
    if let Some(s) = args.shard {
        return Ok((s, None));
    }
    match Shard::from_env(&|v| std::env::var(v).ok(), args.shard_count) {
        Ok(Some((s, origin))) => Ok((s, Some(origin))),
        Ok(None) if args.shard_count.is_some() => Err(
            "--shard-count is for a scheduler's index, and neither SLURM_ARRAY_TASK_ID nor JOB_COMPLETION_INDEX is set: give --shard K/N".into(),
        ),
        Ok(None) => Ok((Shard::WHOLE, None)),
        Err(e) => Err(e.to_string()),
    }
}

/// Corpus mode: this task's items in turn, each row written to the shard's results file as
/// it is done; the table printed (and with the whole corpus written). Exit 2 when the run
/// cannot be done, else the rows' verdict.
fn run_corpus(args: &PlayArgs, corpus: Corpus) -> ExitCode {
    let fail = |e: String| {
        eprintln!("error: {e}");
        ExitCode::from(2)
    };
    let (shard, origin) = match shard(args) {
        Ok(s) => s,
        Err(e) => return fail(e),
    };
    let sessions: Result<Vec<Session>, PlayError> =
        corpus.combos.iter().map(|c| session(args, c)).collect();
    let mut run = match sessions
        .map_err(CorpusError::from)
        .and_then(|s| CorpusRun::start(corpus, s, shard, &args.out, args.resume))
    {
        Ok(r) => r,
        Err(e) => return fail(e.to_string()),
    };
    let (mine, todo) = (run.mine().len(), run.todo());
    if shard != Shard::WHOLE || mine != todo.len() {
        println!(
            "shard {shard}{}: {mine} of the corpus's {} items{}",
            origin.map_or(String::new(), |o| format!(" ({o})")),
            run.corpus.items.len(),
            match mine - todo.len() {
                0 => String::new(),
                done => format!(", {done} done before (--resume), {} to play", todo.len()),
            }
        );
    }
    let bar = CorpusBar::new(todo.len());
    for i in todo {
        let file = run.corpus.items[i].file.clone();
        bar.piece(&file);
        let played = run_piece(args, run.session(i), Some(&file), Some(&bar.multi))
            .map(|(_, row)| row)
            .map_err(|e| {
                bar.multi
                    .suspend(|| eprintln!("error: {}: {e}", file.display()));
                e.to_string()
            });
        if let Err(e) = run.record(i, played) {
            bar.finish();
            return fail(e.to_string());
        }
        bar.inc();
    }
    bar.finish();
    let (rows, written, verdict) = match run.finish(&args.out) {
        Ok(r) => r,
        Err(e) => return fail(e.to_string()),
    };
    let emulated = matches!(args.engine, values::PlayEngine::Emu);
    print!(
        "{}",
        corpus::summary_text(&rows, emulated, host_play::peak_memory_kb())
    );
    written
        .iter()
        .for_each(|p| println!("  wrote {}", p.display()));
    if shard.count > 1 {
        println!(
            "  the tables: tactus corpus merge {} -o OUT, once every shard is done",
            args.out.display()
        );
    }
    if let Some(m) = verdict.message() {
        eprintln!("error: {m}");
    }
    ExitCode::from(verdict.exit_code())
}

/// Plays one performance (`None`: the demo) and prints what it returns; the row is the
/// corpus table's. `multi`: the corpus's progress bars, to which this piece's bar is added.
fn run_piece(
    args: &PlayArgs,
    session: &Session,
    performance: Option<&Path>,
    multi: Option<&MultiProgress>,
) -> Result<(ExitCode, corpus::PieceRow), PlayError> {
    let emulated = matches!(args.engine, values::PlayEngine::Emu);
    let what = format!("{} keys on their boards", session.kb.keys.len());
    let bar = PlayBar::new(multi, if emulated { what } else { "played keys".into() });
    let mut warn = |w: String| bar.0.suspend(|| eprintln!("warning: {w}"));
    let piece = session.play(performance, &mut warn, &bar)?;
    bar.0.finish_and_clear();
    let (lines, warnings) = piece.report();
    warnings.iter().for_each(|w| eprintln!("warning: {w}"));
    lines.iter().for_each(|l| println!("{l}"));
    (piece.written.iter()).for_each(|w| println!("  wrote {}", w.display()));
    let row = piece.row(performance.unwrap_or(Path::new("demo")));
    let (budget, missed) = piece.budget_report();
    print!("{budget}");
    missed.iter().for_each(|e| eprintln!("error: {e}"));
    let code = if missed.is_some() {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    };
    Ok((code, row))
}
