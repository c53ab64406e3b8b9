//! `tactus build`: compile an instrument to firmware sources (being written).

use std::process::ExitCode;

/// Arguments of `tactus build`.
#[derive(Debug, clap::Args)]
pub struct BuildArgs {
    /// Instrument file or built-in name.
    pub file: String,
}

/// Runs `tactus build`.
pub fn run(args: BuildArgs) -> ExitCode {
    eprintln!("error: `tactus build` is not implemented yet ({})", args.file);
    ExitCode::FAILURE
}
