//! `tactus corpus merge`: parses the arguments, merges the shards' results
//! (`tactus_host::corpus_merge`) and prints the table, the files written and the verdict.
//! `tactus corpus trips`: the budget corpus through every board of a keyboard, the fault
//! checks' trips per run (`tactus_host::fault_corpus::budget_corpus_trips`).

use std::path::PathBuf;
use std::process::ExitCode;
use tactus_host::corpus_merge;
use tactus_host::play::corpus;

/// `tactus corpus`'s subcommands.
#[derive(Debug, clap::Subcommand)]
pub enum CorpusCommand {
    /// Merge the results of a sharded corpus run (`tactus play CORPUS --shard K/N`, one task
    /// per shard) into OUT/corpus.csv and OUT/corpus.json: the tables one machine's run
    /// writes, row for row. Refuses shards of different runs (their manifests: version,
    /// options, layout, board, instrument and firmware hashes, items), a shard missing or
    /// given twice, and items missing, naming them. Exit status: 0 when every piece played
    /// without a deadline miss and struck every note; 1 when the firmware failed validation
    /// (a deadline missed, a note without a strike); 2 when the run could not be done (a
    /// refusal above, or a piece that could not be played).
    Merge(MergeArgs),
    /// Run the budget corpus (the key motions `tactus budget` measures: dips at every
    /// speed, repetitions, half dips, let-off reversals, sensor noise; and the runs faulty
    /// by design: glitches to corner words, adversarial random words) through the firmware
    /// of every board of a keyboard, every key of a board following each run from a fresh
    /// boot, and count the trips of the firmware's fault checks per run. The physical runs
    /// must trip none (a trip is a false alarm: exit 1); the runs faulty by design show the
    /// checks at work. Example: `tactus corpus trips grand88 --quick`.
    Trips(TripsArgs),
}

/// Arguments of `tactus corpus trips`.
#[derive(Debug, clap::Args)]
pub struct TripsArgs {
    /// Layout (file or built-in name) or instrument [default: grand88].
    #[arg(default_value = "grand88")]
    pub input: String,
    /// Board kind (built-in name or board file) [default: the layout's, else rp2040].
    #[arg(long, value_name = "NAME_OR_FILE")]
    pub board: Option<String>,
    /// The quick corpus (about a fifth of the samples) instead of the full one.
    #[arg(long)]
    pub quick: bool,
    /// The firmware's sensor check on every key (`on`, the default here: what the run
    /// checks) or `off`.
    #[arg(long, value_name = "on|off", value_parser = crate::play_cmd::parse_on_off, default_value = "on", action = clap::ArgAction::Set)]
    pub sensor_check: bool,
    /// The firmware's watchdog on every board, `on` or `off` [default: the firmware's
    /// own]: the physical runs must not reset a board either.
    #[arg(long, value_name = "on|off", value_parser = crate::play_cmd::parse_on_off)]
    pub watchdog: Option<bool>,
}

/// Arguments of `tactus corpus merge`.
#[derive(Debug, clap::Args)]
pub struct MergeArgs {
    /// The shards' results: results-K-of-N.jsonl files, or directories holding them (the
    /// tasks' OUT).
    #[arg(required = true, value_name = "SHARD_OUTPUTS")]
    pub inputs: Vec<PathBuf>,
    /// Output directory of the tables.
    #[arg(long, short, default_value = "out")]
    pub out: PathBuf,
}

/// Runs `tactus corpus …`.
pub fn run(cmd: CorpusCommand) -> ExitCode {
    match cmd {
        CorpusCommand::Merge(args) => merge(&args),
        CorpusCommand::Trips(args) => trips(&args),
    }
}

fn trips(args: &TripsArgs) -> ExitCode {
    use tactus_host::keyboard::{self, KeyboardSpec};
    let kb = keyboard::compile(
        &KeyboardSpec {
            input: &args.input,
            as_layout: None,
            board: args.board.as_deref(),
            keys: None,
            params: &[],
        },
        &mut crate::source::report_compile,
    );
    let mut kb = match kb {
        Ok(kb) => kb,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    kb.sensor_check = Some(args.sensor_check);
    kb.watchdog = args.watchdog;
    let bar = indicatif::ProgressBar::new(1);
    let runs = tactus_host::fault_corpus::budget_corpus_trips(&kb, args.quick, &mut |d, n| {
        bar.set_length(n as u64);
        bar.set_position(d as u64);
    });
    bar.finish_and_clear();
    let runs = match runs {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    println!(
        "{} on {}, sensor check {}, watchdog {}: the budget corpus ({}) through every board",
        kb.name,
        kb.board.name,
        tactus_host::keyboard::on_off(args.sensor_check),
        args.watchdog
            .map_or("as the firmware's default", tactus_host::keyboard::on_off),
        if args.quick { "quick" } else { "full" }
    );
    let (lines, physical) =
        tactus_host::fault_corpus::corpus_trips_text(&runs, kb.board.sample_rate_hz);
    lines.iter().for_each(|l| println!("{l}"));
    if physical > 0 {
        eprintln!("error: {physical} trips and resets in physical runs: false alarms");
        return ExitCode::from(1);
    }
    ExitCode::SUCCESS
}

fn merge(args: &MergeArgs) -> ExitCode {
    let merged = match corpus_merge::merge(&args.inputs, &args.out) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let h = &merged.header;
    println!(
        "merged {} shards of a run of {} items (tactus {}, engine {}):",
        h.shard.count,
        h.manifest.items.len(),
        h.manifest.tactus,
        h.manifest.options.engine
    );
    let emulated = h.manifest.options.engine == "emu";
    print!("{}", corpus::summary_text(&merged.rows, emulated, None));
    (merged.written.iter()).for_each(|p| println!("  wrote {}", p.display()));
    if let Some(m) = merged.verdict.message() {
        eprintln!("error: {m}");
    }
    ExitCode::from(merged.verdict.exit_code())
}
