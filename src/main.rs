//! The `tactus` command-line tool.

mod emu_cmd;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Tactus: touch profiles for force-feedback instruments.
#[derive(Debug, Parser)]
#[command(name = "tactus", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run ELF firmware on the emulated dual-core RP2040.
    #[command(subcommand)]
    Emu(emu_cmd::EmuCommand),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Emu(cmd) => emu_cmd::run(cmd),
    }
}
