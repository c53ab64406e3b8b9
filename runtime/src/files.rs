//! Reading a file named by the user without trusting its size: the one bounded read behind
//! every input file of the toolchain (instrument sources, layouts, board files, key maps,
//! MIDI performances, firmware ELFs).
//!
//! A file is read through [`std::io::Read::take`] to one byte more than its limit, so a
//! file that grows, a FIFO, `/dev/zero` or a file whose metadata lies costs at most the
//! limit in memory, and a file over the limit is an error naming it, never a truncated read.

use std::fmt;
use std::path::{Path, PathBuf};

/// Why a bounded read failed. Its message starts with the file's path.
#[derive(Debug)]
pub struct ReadError {
    /// The file asked for.
    pub path: PathBuf,
    /// What went wrong.
    pub kind: ReadErrorKind,
}

/// What went wrong in a bounded read.
#[derive(Debug)]
pub enum ReadErrorKind {
    /// The file cannot be opened or read (missing, a directory, no permission).
    Io(std::io::Error),
    /// The file holds more than `max_bytes` bytes; `what` names the kind of file that may
    /// not (`"an instrument source"`).
    TooLong {
        /// The limit in bytes.
        max_bytes: u64,
        /// The kind of file, for the message.
        what: &'static str,
    },
    /// A text file is not UTF-8.
    NotUtf8(std::string::FromUtf8Error),
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = self.path.display();
        match &self.kind {
            ReadErrorKind::Io(e) => write!(f, "{p}: cannot read: {e}"),
            ReadErrorKind::TooLong { max_bytes, what } => {
                write!(f, "{p}: longer than the {max_bytes} bytes {what} may have")
            }
            ReadErrorKind::NotUtf8(e) => write!(f, "{p}: not UTF-8 text: {e}"),
        }
    }
}

impl std::error::Error for ReadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.kind {
            ReadErrorKind::Io(e) => Some(e),
            ReadErrorKind::NotUtf8(e) => Some(e),
            ReadErrorKind::TooLong { .. } => None,
        }
    }
}

/// Reads at most `max_bytes` bytes of the file at `path`.
///
/// Errors: [`ReadErrorKind::Io`] when it cannot be read, [`ReadErrorKind::TooLong`] (with
/// `what`, the kind of file, in the message) when it holds more than `max_bytes`.
pub fn read_bounded(path: &Path, max_bytes: u64, what: &'static str) -> Result<Vec<u8>, ReadError> {
    use std::io::Read;
    let fail = |kind| ReadError {
        path: path.to_path_buf(),
        kind,
    };
    let f = std::fs::File::open(path).map_err(|e| fail(ReadErrorKind::Io(e)))?;
    let mut bytes = Vec::new();
    f.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| fail(ReadErrorKind::Io(e)))?;
    if bytes.len() as u64 > max_bytes {
        return Err(fail(ReadErrorKind::TooLong { max_bytes, what }));
    }
    Ok(bytes)
}

/// [`read_bounded`], as UTF-8 text.
///
/// Errors: those of [`read_bounded`], and [`ReadErrorKind::NotUtf8`].
pub fn read_text_bounded(
    path: &Path,
    max_bytes: u64,
    what: &'static str,
) -> Result<String, ReadError> {
    let bytes = read_bounded(path, max_bytes, what)?;
    String::from_utf8(bytes).map_err(|e| ReadError {
        path: path.to_path_buf(),
        kind: ReadErrorKind::NotUtf8(e),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str, bytes: &[u8]) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("tactus-files-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    #[test]
    fn a_file_at_the_limit_is_read_and_one_byte_more_is_refused() {
        let p = temp("ten", b"0123456789");
        assert_eq!(read_bounded(&p, 10, "a test file").unwrap(), b"0123456789");
        let e = read_bounded(&p, 9, "a test file").unwrap_err();
        assert!(matches!(
            e.kind,
            ReadErrorKind::TooLong { max_bytes: 9, .. }
        ));
        let m = e.to_string();
        assert!(
            m.contains("ten") && m.contains("longer than the 9 bytes a test file may have"),
            "{m}"
        );
    }

    #[test]
    fn missing_files_and_non_utf8_text_name_the_file() {
        let missing = std::env::temp_dir().join("tactus-files-no-such-file");
        let e = read_bounded(&missing, 10, "a test file").unwrap_err();
        assert!(matches!(e.kind, ReadErrorKind::Io(_)));
        assert!(e.to_string().contains("no-such-file: cannot read"), "{e}");
        let p = temp("latin1", &[0x66, 0xe9, 0x65]);
        let e = read_text_bounded(&p, 10, "a test file").unwrap_err();
        assert!(matches!(e.kind, ReadErrorKind::NotUtf8(_)));
        assert!(e.to_string().contains("latin1: not UTF-8 text"), "{e}");
    }

    #[test]
    fn an_endless_file_costs_at_most_the_limit() {
        // /dev/zero claims length 0 and never ends: the read stops one byte past the limit.
        let p = Path::new("/dev/zero");
        if p.exists() {
            let e = read_bounded(p, 1 << 16, "a test file").unwrap_err();
            assert!(matches!(e.kind, ReadErrorKind::TooLong { .. }));
        }
    }
}
