//! `tactus emu …`: run ELF files on the emulated RP2040 (owned by the emulator work, issue 4).

use std::process::ExitCode;

/// Subcommands of `tactus emu`.
#[derive(Debug, clap::Subcommand)]
pub enum EmuCommand {
    /// Run an ELF file on the emulated board (not yet implemented).
    Run {
        /// ELF file to load.
        file: std::path::PathBuf,
    },
}

/// Runs an `emu` subcommand; returns the process exit code.
pub fn run(cmd: EmuCommand) -> ExitCode {
    let EmuCommand::Run { file } = cmd;
    eprintln!("error: the emulator is not built yet (asked to run {})", file.display());
    ExitCode::FAILURE
}
