//! Loading instrument sources (files on disk, or the instruments built into the toolchain:
//! `tactus_host::catalogue`, with the files they import) and printing their diagnostics.

pub use tactus_host::catalogue::{load, Source};

/// Prints diagnostics of `src` to stderr: coloured on a terminal, plain in pipes and logs.
pub fn report(src: &Source, diagnostics: &[tactus_compiler::diagnostics::Diagnostic]) {
    use codespan_reporting::term::termcolor::{ColorChoice, StandardStream};
    use std::io::IsTerminal;
    if diagnostics.is_empty() {
        return;
    }
    let choice = if std::io::stderr().is_terminal() {
        ColorChoice::Auto
    } else {
        ColorChoice::Never
    };
    let mut err = StandardStream::stderr(choice);
    // A failed write to stderr leaves nothing better to report it to.
    let _ = tactus_compiler::diagnostics::emit_files(&mut err, &src.linked.sources, diagnostics);
}

/// Prints a source's diagnostics ([`report`]) and, when any is an error, one line counting
/// them: the reporter every command hands to `tactus_host`.
pub fn report_compile(src: &Source, diagnostics: &[tactus_compiler::diagnostics::Diagnostic]) {
    report(src, diagnostics);
    let n = diagnostics.iter().filter(|d| d.is_error()).count();
    if n > 0 {
        eprintln!(
            "error: {} has {n} error{}",
            src.name,
            if n == 1 { "" } else { "s" }
        );
    }
}
