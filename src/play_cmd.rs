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
use tactus_host::keyboard::KeyboardSpec;
use tactus_host::play::{corpus, PlayConfig, TraceWindow};
use tactus_host::session::{self as host_play, PieceOptions, PlayError, Session};
use tactus_runtime::player::FingerConfig;

/// Arguments of `tactus play`.
#[derive(Debug, clap::Args)]
#[command(after_long_help = host_play::FILES_HELP)]
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
    pub engine: values::PlayEngine,
    /// Board: a built-in name (`rp2040`, `rp2040_200mhz`, `rp2040_20mhz`; with converters,
    /// an ADC and a DAC per core driven over PIO with DMA, `rp2040_io`, `rp2040_io_200mhz`)
    /// or a board file; every engine runs at its sample rate, `--engine emu` on its clock
    /// and cores (and on a board with converters through them: the key positions into the
    /// emulated ADCs, the motor commands from the emulated DACs) [default: the layout's
    /// `board_kind`, else rp2040].
    #[arg(long, value_name = "NAME_OR_FILE")]
    pub board: Option<String>,
    /// The emulator's engine for `--engine emu`: `block` (code compiled to native code with
    /// cranelift) or `interp` (the interpreter): the same cycles and strikes; compare their
    /// speed.
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
    /// Output directory.
    #[arg(long, short, default_value = "out")]
    pub out: PathBuf,
}

/// Runs `tactus play`.
pub fn run(args: PlayArgs) -> ExitCode {
    // The pieces, and the keyboard with its firmware, compiled once for every piece.
    let result = corpus::expand(&args.performances).and_then(|files| {
        let session = session(&args).map_err(|e| e.to_string())?;
        match files.len() > 1 || args.performances.iter().any(|p| p.is_dir()) {
            true => Ok(run_corpus(&args, &session, &files)),
            false => run_piece(&args, &session, files.first().map(PathBuf::as_path), None)
                .map(|(code, _)| code)
                .map_err(|e| e.to_string()),
        }
    });
    result.unwrap_or_else(|e| {
        eprintln!("error: {e}");
        ExitCode::FAILURE
    })
}

/// The keyboard of the arguments (the layout, the instrument on every key, or the built-in
/// default layout), the run's configuration and options.
fn session(args: &PlayArgs) -> Result<Session, PlayError> {
    let input = (args.layout.as_ref().map(|l| l.display().to_string()))
        .or_else(|| args.instrument.clone())
        .unwrap_or_else(|| catalogue::DEFAULT_LAYOUT.to_string());
    let spec = KeyboardSpec {
        input: &input,
        as_layout: Some(args.instrument.is_none()),
        board: args.board.as_deref(),
        keys: None,
        params: &args.params,
    };
    let config = |board| PlayConfig {
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
    };
    let opts = PieceOptions {
        seconds: args.seconds,
        out: args.out.clone(),
        wav: !args.no_wav,
    };
    Session::new(&spec, config, opts, &mut source::report_compile)
}

/// Corpus mode: every file in turn, one row each, the table printed and written.
fn run_corpus(args: &PlayArgs, session: &Session, files: &[PathBuf]) -> ExitCode {
    let bar = CorpusBar::new(files.len());
    let mut rows = Vec::with_capacity(files.len());
    for f in files {
        bar.piece(f);
        rows.push(match run_piece(args, session, Some(f), Some(&bar.multi)) {
            Ok((_, row)) => row,
            Err(e) => {
                bar.multi
                    .suspend(|| eprintln!("error: {}: {e}", f.display()));
                corpus::PieceRow::failed(f, e.to_string())
            }
        });
        bar.inc();
    }
    bar.finish();
    let emulated = matches!(args.engine, values::PlayEngine::Emu);
    let peak_kb = host_play::peak_memory_kb();
    print!("{}", corpus::summary_text(&rows, emulated, peak_kb));
    let written = corpus::write_tables(&args.out, &rows);
    (written.iter().flatten()).for_each(|p| println!("  wrote {}", p.display()));
    match written.err().or_else(|| corpus::failures_text(&rows)) {
        None => ExitCode::SUCCESS,
        Some(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
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
