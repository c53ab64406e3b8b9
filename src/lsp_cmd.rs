//! `tactus lsp`: the language server for editors, on stdin and stdout (`tactus_lsp`).

use std::process::ExitCode;

/// Arguments of `tactus lsp`.
#[derive(Debug, clap::Args)]
pub struct LspArgs {
    /// Talk over stdin and stdout (the only transport, and the default; accepted because
    /// editors' LSP clients pass it).
    #[arg(long)]
    pub stdio: bool,
}

/// Runs `tactus lsp` until the editor sends `exit` or closes the pipe. Exit code 0 after
/// `shutdown` then `exit`, 1 otherwise (the protocol's rule); the log goes to stderr.
pub fn run(_args: LspArgs) -> ExitCode {
    let stdin = std::io::BufReader::new(std::io::stdin());
    // Imports are read from disk as `tactus check` reads them.
    let config = tactus_lsp::Config {
        disk: Some(|| Box::new(tactus_host::catalogue::DiskLoader)),
        ..tactus_lsp::Config::default()
    };
    let outcome = tactus_lsp::serve(stdin, std::io::stdout(), &config, &mut |line| {
        eprintln!("tactus lsp: {line}")
    });
    if outcome.clean_exit {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
