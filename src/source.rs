//! Loading instrument sources: files on disk, or the instruments built into the binary so
//! that `tactus sim` works on a fresh machine from any directory.
//!
//! A built-in is chosen only by its bare name (`grand_piano`: letters, digits and `_`, no
//! directory, no extension). A path that does not exist is an error naming it, never a
//! silent substitution of the built-in with the same file stem. A file is read only when it
//! is at most [`MAX_SOURCE_BYTES`] long.

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

/// The default keyboard layout of `tactus play`: `instruments/layouts/grand88.toml` (the
/// grand piano on A0…C8, hammer mass graded), built in so that the default works from any
/// directory.
pub const GRAND88_LAYOUT: &str = include_str!("../instruments/layouts/grand88.toml");

/// A source text and the name to show in diagnostics.
pub struct Source {
    /// File name or `builtin:NAME`.
    pub name: String,
    /// The text.
    pub text: String,
}

/// The largest instrument source read, in bytes: far beyond any hand-written profile (the
/// shipped ones are a few KB); a bound on what a mistaken path can make the compiler hold.
pub const MAX_SOURCE_BYTES: u64 = 16 << 20;

/// Whether `arg` is a bare name (`grand_piano`), the only way to ask for a built-in.
pub fn is_bare_name(arg: &str) -> bool {
    !arg.is_empty() && arg.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_')
}

/// Reads `arg` as a path, or as the name of a built-in instrument when it is a bare name
/// and no such file exists.
///
/// Errors (naming `arg`): a path that does not exist, a file larger than
/// [`MAX_SOURCE_BYTES`] or not UTF-8, a bare name that is neither a file nor a built-in.
pub fn load(arg: &str) -> Result<Source, String> {
    let path = Path::new(arg);
    if path.exists() {
        let len = std::fs::metadata(path)
            .map_err(|e| format!("cannot read `{arg}`: {e}"))?
            .len();
        if len > MAX_SOURCE_BYTES {
            return Err(format!(
                "`{arg}` is {len} bytes, more than the {MAX_SOURCE_BYTES} an instrument source may have"
            ));
        }
        return std::fs::read_to_string(path)
            .map(|text| Source {
                name: arg.to_string(),
                text,
            })
            .map_err(|e| format!("cannot read `{arg}`: {e}"));
    }
    let names: Vec<&str> = BUILTIN_INSTRUMENTS.iter().map(|(n, _)| *n).collect();
    if !is_bare_name(arg) {
        return Err(format!(
            "no file `{arg}` (built-in instruments are named bare, without a directory or extension: {})",
            names.join(", ")
        ));
    }
    match BUILTIN_INSTRUMENTS.iter().find(|(n, _)| *n == arg) {
        Some((n, text)) => Ok(Source {
            name: format!("builtin:{n}"),
            text: text.to_string(),
        }),
        None => Err(format!(
            "no file `{arg}`, and no built-in instrument of that name (built-ins: {})",
            names.join(", ")
        )),
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
