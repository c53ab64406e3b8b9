//! The files an open profile imports: read from the editor's open documents first (what the
//! user sees, saved or not), then through the host's loader (disk); and the places the
//! client can open for each file of a program.
//!
//! A file on disk is named by its `file://` URI. A file of Tactus's library lives in the
//! `tactus` binary, so the server writes the library, once, into a cache directory
//! (`$TACTUS_CACHE_DIR`, else `$XDG_CACHE_HOME/tactus`, else `$HOME/.cache/tactus`, else the
//! system's temporary directory; `lib-HASH/`, named by a hash of the library's text so that
//! two versions of `tactus` never share one) and names its files by their `file://` URIs.
//! A custom scheme (`tactus-lib:`) would need every editor to fetch its text through the
//! server, which Neovim's and most clients' go-to-definition does not; a file opens in any
//! editor, shows the library's comments (its documentation), and is written read-only.

use lsp_types::Uri;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::OnceLock;
use tactus_compiler::imports::{LoadError, Loaded, Loader};
use tactus_compiler::library;
use tactus_compiler::sources::Origin;

/// The path a `file://` URI names (percent-decoded), or `None` for another scheme.
pub fn uri_to_path(uri: &str) -> Option<PathBuf> {
    let rest = uri.strip_prefix("file://")?;
    // `file:///p` (empty authority) or `file://localhost/p`.
    let path = match rest.find('/') {
        Some(0) => rest,
        Some(i) if &rest[..i] == "localhost" => &rest[i..],
        _ => return None,
    };
    let bytes = path.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 3 <= bytes.len() {
            let hex = std::str::from_utf8(&bytes[i + 1..i + 3]).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    Some(PathBuf::from(String::from_utf8(out).ok()?))
}

/// The `file://` URI of an absolute path (percent-encoded but for unreserved characters and
/// `/`).
pub fn path_to_uri(path: &Path) -> Option<Uri> {
    let s = path.to_str()?;
    if !s.starts_with('/') {
        return None;
    }
    let mut uri = String::from("file://");
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~/".contains(&b) {
            uri.push(b as char);
        } else {
            uri.push_str(&format!("%{b:02X}"));
        }
    }
    Uri::from_str(&uri).ok()
}

/// Reads imports from the open documents (by path) before `disk` (if any).
pub struct Overlay<'a> {
    /// The open documents' texts, by the path their URI names.
    pub open: &'a HashMap<PathBuf, &'a str>,
    /// The host's loader of files on disk (none: the library only).
    pub disk: Option<Box<dyn Loader>>,
}

impl Loader for Overlay<'_> {
    fn read(&mut self, path: &Path, max_bytes: u64) -> Result<Loaded, LoadError> {
        let key = std::fs::canonicalize(path).unwrap_or_else(|_| normal(path));
        let open = self
            .open
            .iter()
            .find(|(p, _)| **p == key || std::fs::canonicalize(p).is_ok_and(|c| c == key));
        if let Some((_, text)) = open {
            if text.len() as u64 > max_bytes {
                return Err(LoadError::TooLong { max_bytes });
            }
            return Ok(Loaded {
                key,
                text: text.to_string(),
            });
        }
        match &mut self.disk {
            Some(d) => d.read(path, max_bytes),
            None => Err(LoadError::NotFound),
        }
    }
}

/// `path` with `.` and `..` taken out, for a file that does not exist (yet) on disk.
fn normal(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// The directory the library is written into, under `base` (the cache directory when
/// `None`), with every library file in it; `None` when no directory can be written.
pub fn library_dir(base: Option<&Path>) -> Option<PathBuf> {
    static DEFAULT: OnceLock<Option<PathBuf>> = OnceLock::new();
    match base {
        Some(b) => write_library(b),
        None => DEFAULT
            .get_or_init(|| {
                let cache = std::env::var_os("TACTUS_CACHE_DIR")
                    .filter(|d| !d.is_empty() && d != "off")
                    .map(PathBuf::from)
                    .or_else(|| {
                        std::env::var_os("XDG_CACHE_HOME").map(|d| PathBuf::from(d).join("tactus"))
                    })
                    .or_else(|| {
                        std::env::var_os("HOME").map(|d| PathBuf::from(d).join(".cache/tactus"))
                    });
                cache
                    .and_then(|c| write_library(&c))
                    .or_else(|| write_library(&std::env::temp_dir().join("tactus")))
            })
            .clone(),
    }
}

/// FNV-1a of every library file's name and text: the name of this library's directory.
fn library_hash() -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for (name, text) in library::FILES {
        for b in name.bytes().chain([0]).chain(text.bytes()).chain([0]) {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

fn write_library(base: &Path) -> Option<PathBuf> {
    let dir = base.join(format!("lib-{:016x}", library_hash()));
    std::fs::create_dir_all(&dir).ok()?;
    for (name, text) in library::FILES {
        let p = dir.join(name);
        if std::fs::read_to_string(&p).is_ok_and(|t| t == *text) {
            continue;
        }
        // Written to a temporary name and renamed, so a reader never sees half a file;
        // read-only, since an edit there changes nothing the compiler reads.
        let tmp = dir.join(format!(".{name}.{}", std::process::id()));
        std::fs::write(&tmp, text).ok()?;
        let mut perms = std::fs::metadata(&tmp).ok()?.permissions();
        perms.set_readonly(true);
        let _ = std::fs::set_permissions(&tmp, perms);
        std::fs::rename(&tmp, &p).ok()?;
    }
    Some(dir)
}

/// The URI a client opens for a file of `origin`: a file on disk by its path, a library
/// file by its copy in [`library_dir`] (`lib` the directory, `None` when none could be
/// written); `None` for a text without a file.
pub fn uri_of(origin: &Origin, lib: Option<&Path>) -> Option<Uri> {
    match origin {
        Origin::File(p) => path_to_uri(p),
        Origin::Library(name) => path_to_uri(&lib?.join(name)),
        Origin::Text => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_uris_round_trip() {
        for p in ["/tmp/a.tactus", "/home/me/my key/θ.tactus", "/a%b"] {
            let u = path_to_uri(Path::new(p)).unwrap();
            assert_eq!(
                uri_to_path(u.as_str()).unwrap(),
                PathBuf::from(p),
                "{}",
                u.as_str()
            );
        }
        assert_eq!(
            uri_to_path("file://localhost/x").unwrap(),
            PathBuf::from("/x")
        );
        assert_eq!(uri_to_path("untitled:Untitled-1"), None);
        assert_eq!(uri_to_path("file://host/x"), None);
    }

    #[test]
    fn the_library_is_written_once_and_read_only() {
        let base = std::env::temp_dir().join(format!("tactus-lsp-lib-{}", std::process::id()));
        let dir = library_dir(Some(&base)).unwrap();
        for (name, text) in library::FILES {
            let p = dir.join(name);
            assert_eq!(std::fs::read_to_string(&p).unwrap(), *text);
            assert!(std::fs::metadata(&p).unwrap().permissions().readonly());
        }
        assert_eq!(library_dir(Some(&base)).unwrap(), dir);
        let _ = std::fs::remove_dir_all(&base);
    }
}
