//! Source files of one program — the instrument's file and the files it imports — laid out
//! in one address space of bytes, as rustc's `SourceMap` lays out a crate's files.
//!
//! Every file gets a base offset: the main file 0, each imported file one byte past the end
//! of the file before it. A span of the AST, of the IR or of a diagnostic is a plain byte
//! range in that space ([`crate::ast::Span`]), so the passes after parsing stay as they were
//! for one file, and a single-file program's spans are its own byte offsets. The gap of one
//! byte between files keeps a span at the very end of a file (an unexpected end of file) in
//! that file. [`SourceMap::locate`] turns a span back into a file and a local range, which is
//! all the renderer ([`crate::diagnostics::emit_files`]) and an editor need.

use crate::ast::Span;
use std::path::PathBuf;

/// Where a source came from, which decides where its imports are looked for
/// ([`crate::imports`]) and identifies it: two imports of one file read it once.
#[derive(Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Origin {
    /// A file read through the host's [`crate::imports::Loader`], by the path the loader
    /// gave for it (canonical, so that `a/../b.tactus` and `b.tactus` are one file). Its
    /// imports are looked for in its directory, then in the library.
    File(PathBuf),
    /// A file of Tactus's standard library ([`crate::library`]), by its name
    /// (`friction.tactus`). Its imports are looked for in the library only.
    Library(String),
    /// Text with no file of its own (a built-in instrument, a test's source, standard
    /// input): its imports are looked for in the library only.
    Text,
}

/// The index of a file in a [`SourceMap`]; the main file is `FileId(0)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct FileId(pub u32);

impl FileId {
    /// The main file of every map.
    pub const MAIN: FileId = FileId(0);

    /// Its index in [`SourceMap::files`].
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// One source file of a program.
#[derive(Clone, Debug, PartialEq)]
pub struct SourceFile {
    /// The name diagnostics show: the path as the user gave it or as an import joined it,
    /// `builtin:NAME` for a built-in instrument, `builtin:lib/NAME` for a library file.
    pub name: String,
    /// Where it came from.
    pub origin: Origin,
    /// Its text.
    pub text: String,
    /// The offset of its first byte in the map's address space.
    pub base: usize,
}

impl SourceFile {
    /// The span of the whole file, in the map's address space.
    pub fn span(&self) -> Span {
        self.base..self.base + self.text.len()
    }
}

/// The files of one program in one address space; see the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct SourceMap {
    files: Vec<SourceFile>,
}

impl SourceMap {
    /// A map holding the main file only, at base 0.
    pub fn new(name: impl Into<String>, origin: Origin, text: impl Into<String>) -> Self {
        SourceMap {
            files: vec![SourceFile {
                name: name.into(),
                origin,
                text: text.into(),
                base: 0,
            }],
        }
    }

    /// Adds a file after the last one (one byte of gap) and returns its id.
    pub fn add(
        &mut self,
        name: impl Into<String>,
        origin: Origin,
        text: impl Into<String>,
    ) -> FileId {
        let base = self.files.last().map_or(0, |f| f.base + f.text.len() + 1);
        self.files.push(SourceFile {
            name: name.into(),
            origin,
            text: text.into(),
            base,
        });
        FileId(self.files.len() as u32 - 1)
    }

    /// Every file, the main one first, in the order they were added.
    pub fn files(&self) -> &[SourceFile] {
        &self.files
    }

    /// The main file (the instrument's).
    pub fn main(&self) -> &SourceFile {
        &self.files[0]
    }

    /// The file `id` (panics on an id of another map).
    pub fn get(&self, id: FileId) -> &SourceFile {
        &self.files[id.index()]
    }

    /// The file whose bytes hold `offset` (or whose end it is): the last file whose base is
    /// at most `offset`. Every offset falls in some file; one past the last file's end falls
    /// in the last file.
    pub fn file_at(&self, offset: usize) -> FileId {
        let i = self.files.partition_point(|f| f.base <= offset);
        FileId(i.saturating_sub(1) as u32)
    }

    /// The file of `span` (that of its start) and the span in that file's own bytes,
    /// clamped to the file.
    pub fn locate(&self, span: &Span) -> (FileId, Span) {
        let id = self.file_at(span.start);
        let f = self.get(id);
        let len = f.text.len();
        let start = (span.start - f.base).min(len);
        let end = span.end.saturating_sub(f.base).clamp(start, len);
        (id, start..end)
    }

    /// The source text of `span`, or `None` when it is not on character boundaries.
    pub fn text(&self, span: &Span) -> Option<&str> {
        let (id, local) = self.locate(span);
        self.get(id).text.get(local)
    }

    /// The file with origin `origin`, if it is in the map.
    pub fn find(&self, origin: &Origin) -> Option<FileId> {
        self.files
            .iter()
            .position(|f| f.origin == *origin)
            .map(|i| FileId(i as u32))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spans_map_back_to_their_files() {
        let mut m = SourceMap::new("main.tactus", Origin::Text, "abc");
        let lib = m.add("lib.tactus", Origin::Library("lib.tactus".into()), "hello");
        assert_eq!(m.get(lib).base, 4);
        assert_eq!(m.locate(&(1..2)), (FileId::MAIN, 1..2));
        // The end of the main file stays in it; the next byte starts the library file.
        assert_eq!(m.locate(&(3..3)), (FileId::MAIN, 3..3));
        assert_eq!(m.locate(&(4..9)), (lib, 0..5));
        assert_eq!(m.text(&(5..7)), Some("el"));
        assert_eq!(m.locate(&(100..200)), (lib, 5..5));
    }
}
