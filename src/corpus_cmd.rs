//! `tactus corpus merge`: parses the arguments, merges the shards' results
//! (`tactus_host::corpus_merge`) and prints the table, the files written and the verdict.

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
    }
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
