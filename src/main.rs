//! The `tactus` command-line tool. Only this crate prints; the libraries return values and
//! diagnostics.

mod budget_cmd;
mod build_cmd;
mod check_cmd;
mod corpus_cmd;
mod emu_cmd;
mod lsp_cmd;
mod play_cmd;
mod plot_cmd;
mod progress;
mod regulate_cmd;
mod sim_cmd;
mod source;
mod values;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Tactus: touch profiles for force-feedback instruments.
///
/// Write how a key should feel in a `.tactus` file (states, events, force terms), check it,
/// simulate it on the host, and run firmware on the emulated RP2040.
#[derive(Debug, Parser)]
#[command(name = "tactus", version, about, long_about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Check an instrument: syntax, names, dimensions; exit code 1 on error.
    Check(check_cmd::CheckArgs),
    /// Simulate an instrument over a key stimulus; write a CSV trace and SVG plots.
    Sim(sim_cmd::SimArgs),
    /// Play a recorded performance (MIDI) through an instrument; write the hammer strikes.
    Play(play_cmd::PlayArgs),
    /// Compile an instrument to firmware: portable C99, or a Thumb ELF object for the RP2040.
    Build(build_cmd::BuildArgs),
    /// Check a keyboard's timing budget: static WCET and measured cycles per key, keys on
    /// the board's cores, fits or not (exit 0/1; 2 on bad input).
    Budget(budget_cmd::BudgetArgs),
    /// The regulation sheet of a key instrument, as a piano technician measures an action:
    /// down- and up-weight, friction, let-off, drop, blow, back-check, key-bottom times,
    /// repetition; with `--spec`, a verdict per figure (exit 1 when one is out of range).
    Regulate(regulate_cmd::RegulateArgs),
    /// Work on the results of corpus runs: `tactus corpus merge` gathers a sharded run's
    /// shards (a Slurm job array's tasks, a Kubernetes Indexed Job's pods) into its tables.
    #[command(subcommand)]
    Corpus(corpus_cmd::CorpusCommand),
    /// Plot the models behind the instruments (e.g. `tactus plot friction`: Bilbao's
    /// friction characteristic, Onofrei et al. 2023 Fig. 9).
    #[command(subcommand)]
    Plot(plot_cmd::PlotCommand),
    /// Run ELF firmware on the emulated dual-core RP2040.
    #[command(subcommand)]
    Emu(emu_cmd::EmuCommand),
    /// Language server for editors (LSP over stdin/stdout): diagnostics as `tactus check`
    /// gives them, hover with units, ranges, Q-formats and error bounds, go to definition,
    /// references, completion, outline. Editor set-up: docs/editors.md.
    Lsp(lsp_cmd::LspArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Check(args) => check_cmd::run(args),
        Command::Sim(args) => sim_cmd::run(args),
        Command::Build(args) => build_cmd::run(args),
        Command::Budget(args) => budget_cmd::run(args),
        Command::Play(args) => play_cmd::run(args),
        Command::Emu(cmd) => emu_cmd::run(cmd),
        Command::Plot(cmd) => plot_cmd::run(cmd),
        Command::Corpus(cmd) => corpus_cmd::run(cmd),
        Command::Lsp(args) => lsp_cmd::run(args),
        Command::Regulate(args) => regulate_cmd::run(args),
    }
}
