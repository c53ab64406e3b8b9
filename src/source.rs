//! Loading instrument sources: files on disk, or the instruments built into the binary so
//! that `tactus sim` works on a fresh machine from any directory.

use std::path::Path;

/// Instruments shipped in the binary, by name (the file stem in `instruments/`).
pub const BUILTIN_INSTRUMENTS: &[(&str, &str)] = &[
    (
        "grand_piano",
        include_str!("../instruments/grand_piano.tactus"),
    ),
    (
        "harpsichord",
        include_str!("../instruments/harpsichord.tactus"),
    ),
    (
        "harpsichord_2x8",
        include_str!("../instruments/harpsichord_2x8.tactus"),
    ),
    ("hammond", include_str!("../instruments/hammond.tactus")),
    (
        "rubbed_bank",
        include_str!("../instruments/rubbed_bank.tactus"),
    ),
    (
        "bowed_string",
        include_str!("../instruments/bowed_string.tactus"),
    ),
    (
        "plucked_string",
        include_str!("../instruments/plucked_string.tactus"),
    ),
];

/// A source text and the name to show in diagnostics.
pub struct Source {
    /// File name or `builtin:NAME`.
    pub name: String,
    /// The text.
    pub text: String,
}

/// Reads `arg` as a path, or as the name of a built-in instrument when no such file exists.
pub fn load(arg: &str) -> Result<Source, String> {
    let path = Path::new(arg);
    if path.exists() {
        return std::fs::read_to_string(path)
            .map(|text| Source {
                name: arg.to_string(),
                text,
            })
            .map_err(|e| format!("cannot read `{arg}`: {e}"));
    }
    let stem = arg.trim_end_matches(".tactus");
    let stem = Path::new(stem)
        .file_name()
        .and_then(|s| s.to_str())
        .unwrap_or(stem);
    match BUILTIN_INSTRUMENTS.iter().find(|(n, _)| *n == stem) {
        Some((n, text)) => Ok(Source {
            name: format!("builtin:{n}"),
            text: text.to_string(),
        }),
        None => {
            let names: Vec<&str> = BUILTIN_INSTRUMENTS.iter().map(|(n, _)| *n).collect();
            Err(format!(
                "no file `{arg}`, and no built-in instrument of that name (built-ins: {})",
                names.join(", ")
            ))
        }
    }
}

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
    let _ = tactus_compiler::diagnostics::emit(&mut err, &src.name, &src.text, diagnostics);
}
