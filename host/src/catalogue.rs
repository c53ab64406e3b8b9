//! The instruments, keyboard layouts and boards shipped with Tactus, and loading a source
//! by path or by built-in name: the one list of what is built in.
//!
//! A built-in is chosen only by its bare name (`grand_piano`: letters, digits and `_`, no
//! directory, no extension). A path that does not exist is an error naming it, never a
//! silent substitution of the built-in with the same file stem. A file is read only when it
//! is at most [`MAX_SOURCE_BYTES`] long.
//!
//! Loading a source reads the files it imports too ([`DiskLoader`], through
//! `tactus_compiler::imports::link`: next to the file, then Tactus's library, which is
//! built into the compiler): a [`Source`] is the whole program, its diagnostics rendered
//! over every file.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use tactus_compiler::imports::{self, Linked, LoadError, Loaded, Loader};
use tactus_compiler::sources::Origin;
use tactus_runtime::files::ReadErrorKind;
use tactus_runtime::keyboard::BoardSpec;

/// Instruments shipped in the toolchain, by name (the file stem in `instruments/`).
pub const INSTRUMENTS: &[(&str, &str)] = &[
    (
        "grand_piano",
        include_str!("../../instruments/grand_piano.tactus"),
    ),
    (
        "harpsichord",
        include_str!("../../instruments/harpsichord.tactus"),
    ),
    (
        "harpsichord_2x8",
        include_str!("../../instruments/harpsichord_2x8.tactus"),
    ),
    ("hammond", include_str!("../../instruments/hammond.tactus")),
    (
        "rubbed_bank",
        include_str!("../../instruments/rubbed_bank.tactus"),
    ),
    (
        "bowed_string",
        include_str!("../../instruments/bowed_string.tactus"),
    ),
    (
        "plucked_string",
        include_str!("../../instruments/plucked_string.tactus"),
    ),
];

/// Keyboard layouts shipped in the toolchain, by name (the file stem in
/// `instruments/layouts/`). Their instruments are built-ins, named bare.
pub const LAYOUTS: &[(&str, &str)] = &[
    (
        "grand88",
        include_str!("../../instruments/layouts/grand88.toml"),
    ),
    (
        "split_harpsichord_piano",
        include_str!("../../instruments/layouts/split_harpsichord_piano.toml"),
    ),
];

/// The default keyboard of `tactus play`: [`LAYOUTS`]' `grand88` (the grand piano on
/// A0…C8, hammer mass graded from 11 g to 3.5 g).
pub const DEFAULT_LAYOUT: &str = "grand88";

/// Boards shipped in the toolchain, by name (the file stem in `boards/`).
pub const BOARDS: &[(&str, &str)] = &[
    ("rp2040", include_str!("../../boards/rp2040.toml")),
    (
        "rp2040_200mhz",
        include_str!("../../boards/rp2040_200mhz.toml"),
    ),
    (
        "rp2040_20mhz",
        include_str!("../../boards/rp2040_20mhz.toml"),
    ),
    ("rp2040_io", include_str!("../../boards/rp2040_io.toml")),
    (
        "rp2040_io_200mhz",
        include_str!("../../boards/rp2040_io_200mhz.toml"),
    ),
];

/// The default board kind: [`BOARDS`]' `rp2040` (133 MHz, two cores, 44.1 kHz).
pub const DEFAULT_BOARD: &str = "rp2040";

/// An instrument's source: its file and the files it imports, read and linked.
#[derive(Clone, Debug)]
pub struct Source {
    /// File name or `builtin:NAME`.
    pub name: String,
    /// The text.
    pub text: String,
    /// The program: every file (its diagnostics render over `linked.sources`), parsed and
    /// linked, or the diagnostics of linking. Shared by every set of a keyboard.
    pub linked: Arc<Linked>,
}

impl Source {
    /// The source `text` named `name`, from `origin`, its imports read through `loader`.
    pub fn new(name: String, origin: Origin, text: String, loader: &mut dyn Loader) -> Self {
        let linked = Arc::new(imports::link(&name, origin, &text, loader));
        Source { name, text, linked }
    }
}

/// The files an instrument imports, read from disk: each at most [`MAX_SOURCE_BYTES`] (and
/// the budget [`imports::link`] gives), its size checked before it is read and the read
/// bounded ([`tactus_runtime::files`]); known by its canonical path.
#[derive(Clone, Copy, Debug, Default)]
pub struct DiskLoader;

impl Loader for DiskLoader {
    fn read(&mut self, path: &Path, max_bytes: u64) -> Result<Loaded, LoadError> {
        let max_bytes = max_bytes.min(MAX_SOURCE_BYTES);
        match std::fs::metadata(path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(LoadError::NotFound),
            Err(e) => return Err(LoadError::Other(e.to_string())),
            Ok(m) if m.is_dir() => return Err(LoadError::Directory),
            Ok(m) if m.len() > max_bytes => return Err(LoadError::TooLong { max_bytes }),
            Ok(_) => {}
        }
        let text = tactus_runtime::files::read_text_bounded(path, max_bytes, "an imported file")
            .map_err(|e| match e.kind {
                ReadErrorKind::TooLong { max_bytes, .. } => LoadError::TooLong { max_bytes },
                ReadErrorKind::NotUtf8(_) => LoadError::NotUtf8,
                ReadErrorKind::Io(e) if e.kind() == std::io::ErrorKind::NotFound => {
                    LoadError::NotFound
                }
                ReadErrorKind::Io(e) => LoadError::Other(e.to_string()),
            })?;
        let key = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
        Ok(Loaded { key, text })
    }
}

/// The largest instrument source read, in bytes: far beyond any hand-written profile (the
/// shipped ones are a few KB); a bound on what a mistaken path can make the compiler hold.
pub const MAX_SOURCE_BYTES: u64 = 16 << 20;

/// Whether `arg` is a bare name (`grand_piano`), the only way to ask for a built-in.
pub fn is_bare_name(arg: &str) -> bool {
    !arg.is_empty() && arg.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_')
}

fn names(list: &[(&str, &str)]) -> String {
    list.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
}

/// Reads instrument `arg` as a path, or as the name of a built-in instrument when it is a
/// bare name and no such file exists.
///
/// Errors (naming `arg`): a path that does not exist, a file larger than
/// [`MAX_SOURCE_BYTES`] or not UTF-8, a bare name that is neither a file nor a built-in.
pub fn load(arg: &str) -> Result<Source, String> {
    let path = Path::new(arg);
    if path.exists() {
        let text = tactus_runtime::files::read_text_bounded(
            path,
            MAX_SOURCE_BYTES,
            "an instrument source",
        )
        .map_err(|e| e.to_string())?;
        let key = std::fs::canonicalize(path).unwrap_or_else(|_| PathBuf::from(arg));
        return Ok(Source::new(
            arg.to_string(),
            Origin::File(key),
            text,
            &mut DiskLoader,
        ));
    }
    if !is_bare_name(arg) {
        return Err(format!(
            "no file `{arg}` (built-in instruments are named bare, without a directory or extension: {})",
            names(INSTRUMENTS)
        ));
    }
    match INSTRUMENTS.iter().find(|(n, _)| *n == arg) {
        Some((n, text)) => Ok(Source::new(
            format!("builtin:{n}"),
            Origin::Text,
            text.to_string(),
            &mut imports::NoFiles,
        )),
        None => Err(format!(
            "no file `{arg}`, and no built-in instrument of that name (built-ins: {})",
            names(INSTRUMENTS)
        )),
    }
}

/// The text of built-in layout `name`, if there is one.
pub fn layout(name: &str) -> Option<&'static str> {
    LAYOUTS.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The board named `arg`: a board file, or a built-in board's name (`rp2040-200mhz` and
/// `rp2040_200mhz.toml` name `rp2040_200mhz` too), checked by
/// `tactus_firmware::boards::read_board` (the one validation of boards).
///
/// Errors name the file and the field, or list the built-ins.
pub fn board(arg: &str) -> Result<BoardSpec, String> {
    let src = board_source(arg)?;
    tactus_firmware::boards::read_board(&src.text, &src.name)
}

/// A board file's text and the name its errors give it.
#[derive(Clone, Debug)]
pub struct BoardSource {
    /// The path, or `builtin:NAME`.
    pub name: String,
    /// The TOML text.
    pub text: String,
}

/// The text of board `arg` as [`board`] reads it (a board file, else a built-in board by
/// name), named as its errors name it: the path, or `builtin:NAME`.
///
/// Errors: the file cannot be read, or no built-in board has that name.
pub fn board_source(arg: &str) -> Result<BoardSource, String> {
    if Path::new(arg).exists() {
        let text = tactus_runtime::keyboard::read_text(Path::new(arg))?;
        return Ok(BoardSource {
            name: arg.to_string(),
            text,
        });
    }
    let stem = arg.trim_end_matches(".toml").replace('-', "_");
    match BOARDS.iter().find(|(n, _)| *n == stem) {
        Some((n, text)) => Ok(BoardSource {
            name: format!("builtin:{n}"),
            text: text.to_string(),
        }),
        None => Err(format!(
            "no board file `{arg}`, and no built-in board of that name (built-ins: {})",
            names(BOARDS)
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_reads() {
        for (n, _) in BOARDS {
            board(n).unwrap();
        }
        assert!(board("no-such-board")
            .unwrap_err()
            .contains("rp2040_200mhz"));
        for (n, _) in INSTRUMENTS {
            assert_eq!(load(n).unwrap().name, format!("builtin:{n}"));
        }
        for (n, text) in LAYOUTS {
            let l = tactus_runtime::keyboard::parse_layout(text, n).unwrap();
            for r in &l.ranges {
                assert!(
                    INSTRUMENTS.iter().any(|(i, _)| *i == r.instrument),
                    "{n}: `{}` is not a built-in instrument",
                    r.instrument
                );
            }
        }
        assert!(layout(DEFAULT_LAYOUT).is_some());
        assert!(load("no/such.tactus").unwrap_err().contains("no file"));
    }
}
