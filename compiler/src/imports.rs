//! Imports: a source file and the files it imports, read, parsed, checked and linked into one
//! AST for [`crate::lower`].
//!
//! `import "friction.tactus"` brings every component that file defines into the importing
//! file; `import "friction.tactus" { stick_friction }` only the ones listed. The file is
//! looked for next to the importing file, then in Tactus's library ([`crate::library`]); a
//! library file, a built-in instrument and a text without a file look in the library only
//! ([`Origin`]). Imports do not pass on: a file sees its own components and those it
//! imports, not what its imports import.
//!
//! **Who reads.** The compiler does no I/O: the host reads files through a [`Loader`] (the
//! command line from disk, an editor from its open buffers, then disk), and [`NoFiles`]
//! serves programs that import from the library only. The compiler decides where to look
//! and what an import means; the loader only reads.
//!
//! **What comes out.** [`link`] lays the files out in one [`SourceMap`] (so every span keeps
//! its file), parses each once, and returns the program as one [`ast::File`]: the main
//! file's instrument and components, and every component of every imported file, each `use`
//! renamed to the component its own file sees. A component keeps its name unless two files
//! define the same one; then the one outside the main file is known as `FILE::NAME`
//! (`builtin:lib/contact.tactus::spring`), which no source can write, so no file reaches a
//! component it did not import. Expansion and lowering then work as on one file.
//!
//! **Hostile input.** Files are read from a worklist, never recursively, at most
//! [`MAX_FILES`] of them and [`MAX_READ_BYTES`] read in all (the loader is given what is
//! left, so a 100 MB file costs no more than the budget); the cycle check is an iterative
//! depth-first search. A chain of a thousand files is a loop of a thousand steps.
//!
//! Errors: E0115 (a `use` of a component the file neither defines nor imports, with the
//! import that would bring it), E0101 (a component defined twice in a file), E0140 (a file
//! found nowhere), E0141 (a file that cannot be read: a directory, too long, not UTF-8),
//! E0142 (an import cycle), E0143 (one name for two components), E0144 (a file or name
//! imported twice), E0145 (a name the imported file does not define), E0146 (too many
//! files or bytes); a syntax error in an imported file is its own, shown with the import
//! that brought the file.

use crate::ast::{self, Decl, Span, TopItem};
use crate::diagnostics::{closest, Diagnostic};
use crate::library;
use crate::sources::{FileId, Origin, SourceMap};
use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};

/// The most files one program may consist of (its own and every file imported, directly or
/// not): far above any instrument (the shipped ones import two or three), and a bound on
/// what an import chain can make the compiler hold.
pub const MAX_FILES: usize = 1024;

/// The most bytes the imports of one program may read in all (the main file aside):
/// the size limit of one instrument source, `tactus_host::catalogue::MAX_SOURCE_BYTES`.
pub const MAX_READ_BYTES: u64 = 16 << 20;

/// The most files of an import cycle its diagnostic names (and imports it shows).
const CYCLE_SHOWN: usize = 8;

/// Why a [`Loader`] could not read a file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LoadError {
    /// No file at that path: the library is tried next.
    NotFound,
    /// The path names a directory.
    Directory,
    /// The file holds more than the `max_bytes` the loader was given.
    TooLong {
        /// The limit the loader was given, bytes.
        max_bytes: u64,
    },
    /// The file is not UTF-8 text.
    NotUtf8,
    /// Anything else (no permission, an I/O error), as the system says it.
    Other(String),
}

/// What a [`Loader`] read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Loaded {
    /// The path the file is known by: the same for two paths that name one file (a
    /// canonical path), so that it is read once and a cycle through it is seen.
    pub key: PathBuf,
    /// Its text.
    pub text: String,
}

/// Reads the files imports name: the host's side of [`link`].
pub trait Loader {
    /// Reads the file at `path` (an importing file's directory joined with the name the
    /// import wrote), at most `max_bytes` bytes of it.
    ///
    /// Errors: [`LoadError::NotFound`] when there is no such file (the library is tried
    /// next), the other [`LoadError`]s when it exists and cannot be read.
    fn read(&mut self, path: &Path, max_bytes: u64) -> Result<Loaded, LoadError>;
}

/// The loader of a program that has no files around it: every import is looked up in the
/// library.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoFiles;

impl Loader for NoFiles {
    fn read(&mut self, _: &Path, _: u64) -> Result<Loaded, LoadError> {
        Err(LoadError::NotFound)
    }
}

/// One import as resolved: which file wrote it, where, and the file it brings.
#[derive(Clone, Debug, PartialEq)]
pub struct Edge {
    /// The importing file.
    pub from: FileId,
    /// The whole `import …` in it.
    pub span: Span,
    /// The imported file.
    pub to: FileId,
}

/// A program's files, parsed and linked; see the module documentation.
#[derive(Clone, Debug)]
pub struct Linked {
    /// Every file of the program, the main one first.
    pub sources: SourceMap,
    /// Each file's AST as written (imports included), by [`FileId`]; `None` where it does
    /// not parse.
    pub parsed: Vec<Option<ast::File>>,
    /// Every import resolved to a file, in the order read.
    pub edges: Vec<Edge>,
    /// The program as one file, imports resolved; `None` when an error stops linking.
    pub file: Option<ast::File>,
    /// Errors (every file's syntax error among them) and warnings of linking.
    pub diagnostics: Vec<Diagnostic>,
}

impl Linked {
    /// Whether linking found an error.
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(Diagnostic::is_error)
    }

    /// The import in the main file through which the program reaches file `id` (directly,
    /// or through the files it imports): its span. `None` for the main file.
    pub fn import_site(&self, id: FileId) -> Option<Span> {
        let mut at = id;
        // Each file's first importer was read before it, so following first importers
        // ends at the main file within as many steps as there are files.
        for _ in 0..self.sources.files().len() {
            let e = self.edges.iter().find(|e| e.to == at && e.from != at)?;
            if e.from == FileId::MAIN {
                return Some(e.span.clone());
            }
            at = e.from;
        }
        None
    }

    /// The components the main file imports (all of a file's, or those listed), as written
    /// in their files: what its names may resolve to besides its own.
    pub fn imported_components(&self) -> Vec<&ast::Body> {
        let Some(Some(main)) = self.parsed.first() else {
            return Vec::new();
        };
        let mut out = Vec::new();
        for item in &main.items {
            let TopItem::Import(imp) = item else { continue };
            let Some(e) = self
                .edges
                .iter()
                .find(|e| e.from == FileId::MAIN && e.span == imp.span)
            else {
                continue;
            };
            let Some(Some(file)) = self.parsed.get(e.to.index()) else {
                continue;
            };
            for it in &file.items {
                if let TopItem::Component(b) = it {
                    let listed = imp
                        .names
                        .as_ref()
                        .is_none_or(|ns| ns.iter().any(|n| n.node == b.name.node));
                    if listed && !out.iter().any(|o: &&ast::Body| o.name.node == b.name.node) {
                        out.push(b);
                    }
                }
            }
        }
        out
    }

    /// Linking's diagnostics, then `ds` (a later pass's) each [`Linked::with_import_site`]:
    /// what a program's check reports.
    pub fn sited(&self, ds: Vec<Diagnostic>) -> Vec<Diagnostic> {
        self.diagnostics
            .iter()
            .cloned()
            .chain(ds.into_iter().map(|d| self.with_import_site(d)))
            .collect()
    }

    /// `d` with, when its primary span lies in an imported file, the import in the main
    /// file that brings that file as a secondary span, and a hint saying where the
    /// problem is when it has none.
    pub fn with_import_site(&self, mut d: Diagnostic) -> Diagnostic {
        let id = self.sources.file_at(d.primary.0.start);
        if id == FileId::MAIN {
            return d;
        }
        let name = &self.sources.get(id).name;
        let Some(site) = self.import_site(id) else {
            return d;
        };
        let direct = self
            .edges
            .iter()
            .any(|e| e.from == FileId::MAIN && e.to == id);
        let label = if direct {
            format!("`{name}` is imported here")
        } else {
            format!("`{name}` is imported through this import")
        };
        if !d.secondary.iter().any(|(s, _)| *s == site) {
            d.secondary.push((site, label));
        }
        if d.hint.is_none() && d.is_error() {
            d.hint = Some(format!(
                "the problem is in `{name}`, which this instrument imports: fix it there, or import another file"
            ));
        }
        d
    }
}

/// Reads, parses, checks and links `text` (the main file, shown as `name`, from `origin`)
/// and every file it imports, through `loader`; see the module documentation.
pub fn link(name: &str, origin: Origin, text: &str, loader: &mut dyn Loader) -> Linked {
    let mut l = Linker {
        sources: SourceMap::new(name, origin, text),
        parsed: Vec::new(),
        edges: Vec::new(),
        diags: Vec::new(),
        read_bytes: 0,
        seen_paths: HashMap::new(),
        over: false,
        unread: HashSet::new(),
    };
    l.read_all(loader);
    let cycle = l.check_cycles();
    let file = if cycle { None } else { l.link() };
    let linked = Linked {
        sources: l.sources,
        parsed: l.parsed,
        edges: l.edges,
        file,
        diagnostics: Vec::new(),
    };
    let diagnostics = l
        .diags
        .into_iter()
        .map(|d| linked.with_import_site(d))
        .collect();
    let has_errors = |ds: &Vec<Diagnostic>| ds.iter().any(Diagnostic::is_error);
    let file = if has_errors(&diagnostics) {
        None
    } else {
        linked.file
    };
    Linked {
        file,
        diagnostics,
        ..linked
    }
}

struct Linker {
    sources: SourceMap,
    parsed: Vec<Option<ast::File>>,
    edges: Vec<Edge>,
    diags: Vec<Diagnostic>,
    /// Bytes read by imports so far, against [`MAX_READ_BYTES`].
    read_bytes: u64,
    /// Paths already read (as joined, and as the loader's key), to the file they gave.
    seen_paths: HashMap<PathBuf, FileId>,
    /// [`MAX_FILES`] or [`MAX_READ_BYTES`] was reached (reported once).
    over: bool,
    /// Files with an import that brought no file: their unknown components are that
    /// import's, already reported (no E0115 after E0140).
    unread: HashSet<FileId>,
}

/// What a file sees: component name → (defining file, its item, `None` for the file's own
/// or the span of the import that brings it).
type Seen<'a> = HashMap<&'a str, (usize, usize, Option<Span>)>;

/// Where an import was found.
enum Found {
    /// A file already in the map.
    Known(FileId),
    /// A new file: (display name, origin, text).
    New(String, Origin, String),
}

impl Linker {
    /// Parses every file in turn, reading what each imports: a worklist over the map.
    fn read_all(&mut self, loader: &mut dyn Loader) {
        let mut next = 0;
        while next < self.sources.files().len() {
            let id = FileId(next as u32);
            next += 1;
            let f = self.sources.get(id);
            let parsed = match crate::parse::parse_at(&f.text, f.base) {
                Ok(file) => file,
                Err(d) => {
                    self.diags.push(*d);
                    self.parsed.push(None);
                    continue;
                }
            };
            for item in &parsed.items {
                let TopItem::Import(imp) = item else {
                    continue;
                };
                if self.over {
                    break;
                }
                match self.find(id, &imp.path, loader) {
                    Ok(Found::Known(to)) => self.edges.push(Edge {
                        from: id,
                        span: imp.span.clone(),
                        to,
                    }),
                    Ok(Found::New(name, origin, text)) => {
                        if self.sources.files().len() >= MAX_FILES {
                            self.too_much(
                                imp,
                                format!("more than {MAX_FILES} files imported"),
                                "an import chain this long is no instrument: is a file importing a copy of itself under another name?",
                            );
                            break;
                        }
                        let to = self.sources.add(name, origin, text);
                        self.edges.push(Edge {
                            from: id,
                            span: imp.span.clone(),
                            to,
                        });
                    }
                    Err(d) => {
                        self.diags.push(*d);
                        self.unread.insert(id);
                    }
                }
            }
            self.parsed.push(Some(parsed));
        }
    }

    fn too_much(&mut self, imp: &ast::Import, message: String, hint: &str) {
        self.over = true;
        self.diags.push(
            Diagnostic::error("E0146", message, imp.path.span.clone())
                .label("the import that goes over")
                .hint(hint),
        );
    }

    /// Finds the file `path` names, imported by file `from`: next to `from`, then in the
    /// library.
    fn find(
        &mut self,
        from: FileId,
        path: &ast::Spanned<String>,
        loader: &mut dyn Loader,
    ) -> Result<Found, Box<Diagnostic>> {
        let written = path.node.as_str();
        let span = path.span.clone();
        if written.is_empty() {
            return Err(Box::new(
                Diagnostic::error("E0140", "an import of no file", span)
                    .hint("name a file: `import \"friction.tactus\"`"),
            ));
        }
        let importer = self.sources.get(from);
        // Next to a file: in the directory of the path it was named by (so that a
        // diagnostic shows `instruments/friction.tactus` to who named
        // `instruments/piano.tactus`).
        let dir = match &importer.origin {
            Origin::File(_) => Some(
                Path::new(&importer.name)
                    .parent()
                    .map(Path::to_path_buf)
                    .unwrap_or_default(),
            ),
            Origin::Library(_) | Origin::Text => None,
        };
        let mut looked = Vec::new();
        if let Some(dir) = dir {
            let joined = dir.join(written);
            looked.push(format!("`{}`", joined.display()));
            if let Some(&id) = self.seen_paths.get(&joined) {
                return Ok(Found::Known(id));
            }
            let left = MAX_READ_BYTES.saturating_sub(self.read_bytes);
            match loader.read(&joined, left) {
                Ok(loaded) => {
                    self.read_bytes += loaded.text.len() as u64;
                    let origin = Origin::File(loaded.key.clone());
                    if let Some(id) = self.sources.find(&origin) {
                        self.seen_paths.insert(joined, id);
                        return Ok(Found::Known(id));
                    }
                    self.seen_paths
                        .insert(joined.clone(), FileId(self.sources.files().len() as u32));
                    return Ok(Found::New(
                        joined.display().to_string(),
                        origin,
                        loaded.text,
                    ));
                }
                Err(LoadError::NotFound) => {}
                Err(e) => {
                    let (label, hint) = match e {
                        LoadError::Directory => (
                            "a directory, not a file".to_string(),
                            "import a `.tactus` file: `import \"DIR/FILE.tactus\"`".to_string(),
                        ),
                        LoadError::TooLong { .. } if left < MAX_READ_BYTES => (
                            format!("the imports of this program read more than {MAX_READ_BYTES} bytes in all"),
                            "a touch profile's files are a few kilobytes each: is this the right file?".to_string(),
                        ),
                        LoadError::TooLong { max_bytes } => (
                            format!("longer than the {max_bytes} bytes an imported file may have"),
                            "a touch profile's files are a few kilobytes each: is this the right file?".to_string(),
                        ),
                        LoadError::NotUtf8 => (
                            "not UTF-8 text".to_string(),
                            "a .tactus file is UTF-8 text".to_string(),
                        ),
                        LoadError::Other(why) => (why, "check the file's permissions".to_string()),
                        LoadError::NotFound => unreachable!("handled above"),
                    };
                    return Err(Box::new(
                        Diagnostic::error(
                            "E0141",
                            format!("cannot read `{}`", joined.display()),
                            span,
                        )
                        .label(label)
                        .hint(hint),
                    ));
                }
            }
        }
        let origin = Origin::Library(written.to_string());
        if let Some(id) = self.sources.find(&origin) {
            return Ok(Found::Known(id));
        }
        if let Some(text) = library::file(written) {
            return Ok(Found::New(
                library::display_name(written),
                origin,
                text.to_string(),
            ));
        }
        looked.push("Tactus's library".into());
        let names = library::FILES.iter().map(|(n, _)| *n);
        let hint = match closest(written, names) {
            Some(c) => format!("did you mean `{c}`, a file of Tactus's library?"),
            None if !written.ends_with(".tactus") => {
                format!("name the file with its extension: `import \"{written}.tactus\"`")
            }
            None => format!(
                "an import names a file next to the importing file, or one of Tactus's library: {}",
                library::FILES
                    .iter()
                    .map(|(n, _)| *n)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        };
        Err(Box::new(
            Diagnostic::error("E0140", format!("no file `{written}` to import"), span)
                .label(format!("looked in {}", looked.join(" and in ")))
                .hint(hint),
        ))
    }

    /// Reports an import cycle, if there is one (the first the depth-first search from the
    /// main file meets). Iterative: a chain of a thousand files is no deeper on the stack.
    fn check_cycles(&mut self) -> bool {
        let n = self.sources.files().len();
        let mut out: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (i, e) in self.edges.iter().enumerate() {
            out[e.from.index()].push(i);
        }
        // 0: not visited, 1: on the path, 2: done.
        let mut state = vec![0u8; n];
        // The path: (file, next edge to follow, the edge that entered it).
        let mut path: Vec<(usize, usize, Option<usize>)> = vec![(0, 0, None)];
        state[0] = 1;
        while let Some(top) = path.last_mut() {
            let (file, next) = (top.0, top.1);
            let Some(&e) = out[file].get(next) else {
                state[file] = 2;
                path.pop();
                continue;
            };
            top.1 += 1;
            let to = self.edges[e].to.index();
            match state[to] {
                0 => {
                    state[to] = 1;
                    path.push((to, 0, Some(e)));
                }
                1 => {
                    // The cycle: the edges entering the files after `to` on the path, and
                    // this one.
                    let at = path.iter().position(|p| p.0 == to).unwrap_or(0);
                    let mut cycle: Vec<usize> = path[at + 1..].iter().filter_map(|p| p.2).collect();
                    cycle.push(e);
                    self.report_cycle(&cycle);
                    return true;
                }
                _ => {}
            }
        }
        false
    }

    fn report_cycle(&mut self, cycle: &[usize]) {
        let name = |id: FileId| self.sources.get(id).name.clone();
        let first = &self.edges[cycle[0]];
        let mut chain = vec![name(first.from)];
        chain.extend(cycle.iter().map(|&e| name(self.edges[e].to)));
        // A long cycle is named by its ends, and its imports shown up to a screenful.
        if chain.len() > CYCLE_SHOWN {
            let n = chain.len() - 1;
            chain.splice(
                CYCLE_SHOWN / 2..chain.len() - 2,
                [format!("… ({n} files in all) …")],
            );
        }
        let mut d = Diagnostic::error(
            "E0142",
            format!("an import cycle: {}", chain.join(" → ")),
            first.span.clone(),
        )
        .label(if cycle.len() == 1 {
            "this file imports itself".to_string()
        } else {
            format!("`{}` imports `{}` here", name(first.from), name(first.to))
        })
        .hint("a file cannot import itself, even through others: move the components both need into a file of their own that neither imports back");
        for &e in cycle.iter().skip(1).take(CYCLE_SHOWN) {
            let e = &self.edges[e];
            d = d.with_secondary(
                e.span.clone(),
                format!("…which imports `{}` here", name(e.to)),
            );
        }
        self.diags.push(d);
    }

    /// The program as one file (see the module documentation), or `None` when a file did
    /// not parse.
    fn link(&mut self) -> Option<ast::File> {
        let parsed: Vec<&ast::File> = self
            .parsed
            .iter()
            .map(Option::as_ref)
            .collect::<Option<_>>()?;
        let n = parsed.len();
        let mut diags = Vec::new();
        // Each file's own components (item indices), the first of duplicates (a second is
        // E0101).
        let mut own: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (f, file) in parsed.iter().enumerate() {
            let mut firsts: HashMap<&str, &ast::Name> = HashMap::new();
            for (i, item) in file.items.iter().enumerate() {
                let TopItem::Component(b) = item else {
                    continue;
                };
                match firsts.get(b.name.node.as_str()) {
                    Some(prev) => diags.push(
                        Diagnostic::error(
                            "E0101",
                            format!("component `{}` is defined twice", b.name.node),
                            b.name.span.clone(),
                        )
                        .with_secondary(prev.span.clone(), "first defined here"),
                    ),
                    None => {
                        firsts.insert(&b.name.node, &b.name);
                        own[f].push(i);
                    }
                }
            }
        }
        let body = |f: usize, i: usize| -> &ast::Body {
            match &parsed[f].items[i] {
                TopItem::Component(b) => b,
                _ => unreachable!("own[] holds components"),
            }
        };
        // The name each component is known by in the linked file: its own, unless another
        // file defines one of that name and it is not the main file's.
        let mut defined: HashMap<&str, usize> = HashMap::new();
        for (f, list) in own.iter().enumerate() {
            for &i in list {
                *defined.entry(body(f, i).name.node.as_str()).or_default() += 1;
            }
        }
        let key = |f: usize, i: usize| -> String {
            let name = &body(f, i).name.node;
            if f == 0 || defined.get(name.as_str()).copied().unwrap_or(0) <= 1 {
                name.clone()
            } else {
                format!("{}::{name}", self.sources.get(FileId(f as u32)).name)
            }
        };
        // What each file sees: name → (defining file, item, where it came from: `None` for
        // its own, else the import's span).
        let mut visible: Vec<Seen> = Vec::new();
        for (f, file) in parsed.iter().enumerate() {
            let mut v: Seen = HashMap::new();
            for &i in &own[f] {
                v.insert(&body(f, i).name.node, (f, i, None));
            }
            let mut imported: HashMap<usize, &Span> = HashMap::new();
            for item in &file.items {
                let TopItem::Import(imp) = item else { continue };
                let Some(edge) = self
                    .edges
                    .iter()
                    .find(|e| e.from.index() == f && e.span == imp.span)
                else {
                    continue; // found nowhere: reported
                };
                let g = edge.to.index();
                let gname = &self.sources.get(edge.to).name;
                if let Some(prev) = imported.insert(g, &imp.span) {
                    imported.insert(g, prev);
                    diags.push(
                        Diagnostic::error("E0144", format!("`{gname}` is imported twice"), imp.span.clone())
                            .with_secondary(prev.clone(), "first imported here")
                            .hint("import a file once, listing every component you need: `import \"FILE\" { a, b }`"),
                    );
                    continue;
                }
                // The components this import brings, each with the span that names it.
                let mut brought: Vec<(usize, &Span)> = Vec::new();
                match &imp.names {
                    None => brought.extend(own[g].iter().map(|&i| (i, &imp.path.span))),
                    Some(names) => {
                        let mut listed: HashMap<&str, &Span> = HashMap::new();
                        for name in names {
                            if let Some(prev) = listed.insert(&name.node, &name.span) {
                                diags.push(
                                    Diagnostic::error(
                                        "E0144",
                                        format!("`{}` is imported twice", name.node),
                                        name.span.clone(),
                                    )
                                    .with_secondary(prev.clone(), "first listed here")
                                    .hint("list each component once"),
                                );
                                continue;
                            }
                            match own[g].iter().find(|&&i| body(g, i).name.node == name.node) {
                                Some(&i) => brought.push((i, &name.span)),
                                None => {
                                    let names =
                                        own[g].iter().map(|&i| body(g, i).name.node.as_str());
                                    let hint = match closest(&name.node, names.clone()) {
                                        Some(c) => format!("did you mean `{c}`?"),
                                        None if own[g].is_empty() => {
                                            format!("`{gname}` defines no component")
                                        }
                                        None => format!(
                                            "`{gname}` defines: {}",
                                            names.collect::<Vec<_>>().join(", ")
                                        ),
                                    };
                                    diags.push(
                                        Diagnostic::error(
                                            "E0145",
                                            format!("`{gname}` has no component `{}`", name.node),
                                            name.span.clone(),
                                        )
                                        .hint(hint),
                                    );
                                }
                            }
                        }
                    }
                }
                for (i, at) in brought {
                    let b = body(g, i);
                    match v.get(b.name.node.as_str()) {
                        None => {
                            v.insert(&b.name.node, (g, i, Some(imp.span.clone())));
                        }
                        Some((pf, pi, _)) if (*pf, *pi) == (g, i) => {}
                        Some((pf, pi, from)) => {
                            let prev = body(*pf, *pi);
                            let name = &b.name.node;
                            let mut d = Diagnostic::error(
                                "E0143",
                                format!("two components named `{name}`"),
                                at.clone(),
                            )
                            .label(format!("imports `{name}` from `{gname}`"))
                            .with_secondary(b.name.span.clone(), "defined here");
                            d = match from {
                                None => d.with_secondary(
                                    prev.name.span.clone(),
                                    "and here, in this file",
                                ),
                                Some(s) => d
                                    .with_secondary(s.clone(), "also imported here")
                                    .with_secondary(prev.name.span.clone(), "defined here"),
                            };
                            diags.push(d.hint(format!(
                                "one name, one component: rename one, or import only what you use: `import \"{}\" {{ … }}`",
                                imp.path.node
                            )));
                        }
                    }
                }
            }
            visible.push(v);
        }
        // The linked file: the main file's instrument and components, then every imported
        // file's components, renamed, each `use` resolved (`""` where its file sees no such
        // component: E0115 below).
        let mut items = Vec::new();
        let mut components = Vec::new();
        let mut unknown: Vec<(usize, ast::Name)> = Vec::new();
        for (f, file) in parsed.iter().enumerate() {
            for (i, item) in file.items.iter().enumerate() {
                let (b, is_instrument) = match item {
                    TopItem::Instrument(b) if f == 0 => (b, true),
                    TopItem::Component(b) if own[f].contains(&i) => (b, false),
                    _ => continue,
                };
                let mut b = b.clone();
                resolve_uses(
                    &mut b.decls,
                    &mut |component: &mut ast::Name| match visible[f].get(component.node.as_str()) {
                        Some((g, j, _)) => component.node = key(*g, *j),
                        None => {
                            unknown.push((f, component.clone()));
                            component.node.clear();
                        }
                    },
                );
                if is_instrument {
                    items.push(TopItem::Instrument(b));
                } else {
                    b.name.node = key(f, i);
                    components.push(TopItem::Component(b));
                }
            }
        }
        items.extend(components);
        for (f, name) in &unknown {
            if self.over || self.unread.contains(&FileId(*f as u32)) {
                continue;
            }
            let seen: Vec<&str> = visible[*f].keys().copied().collect();
            diags.push(self.unknown_component(*f, name, seen));
        }
        self.diags.extend(diags);
        Some(ast::File { items })
    }

    /// E0115 for `use … = NAME(…)` in file `f`, which sees no component `NAME` (it sees
    /// `seen`): the hint names the import that would bring one.
    fn unknown_component(&self, f: usize, name: &ast::Name, mut seen: Vec<&str>) -> Diagnostic {
        let wanted = name.node.as_str();
        seen.sort_unstable();
        let defines = |g: usize| {
            self.parsed[g].as_ref().is_some_and(|file| {
                file.items
                    .iter()
                    .any(|it| matches!(it, TopItem::Component(b) if b.name.node == wanted))
            })
        };
        let elsewhere = (0..self.parsed.len()).find(|&g| g != f && defines(g));
        let library = library::components();
        let hint = if let Some(g) = elsewhere {
            let other = self.sources.get(FileId(g as u32));
            match &other.origin {
                Origin::Library(file) => format!(
                    "`{wanted}` is in `{}`, which this file does not import: add `import \"{file}\"`",
                    other.name
                ),
                _ => format!(
                    "`{wanted}` is defined in `{}`, which this file does not import: import it here",
                    other.name
                ),
            }
        } else if let Some((_, file)) = library.iter().find(|(c, _)| c == wanted) {
            format!(
                "`{wanted}` is in Tactus's library: add `import \"{file}\"` at the top of the file"
            )
        } else if let Some(c) = closest(wanted, seen.iter().copied()) {
            format!("did you mean `{c}`?")
        } else if let Some((c, file)) = closest(wanted, library.iter().map(|(c, _)| c.as_str()))
            .and_then(|c| library.iter().find(|(n, _)| n == c))
        {
            format!("did you mean `{c}`, in Tactus's library (`import \"{file}\"`)?")
        } else if seen.is_empty() {
            "define it in this file with `component NAME { … }`, or import the file that defines it"
                .into()
        } else {
            format!("components this file sees: {}", seen.join(", "))
        };
        Diagnostic::error(
            "E0115",
            format!("no component named `{wanted}`"),
            name.span.clone(),
        )
        .hint(hint)
    }
}

/// Calls `f` on the component name of every `use` in `decls`, inside `for` loops too
/// (nested at most [`crate::parse::MAX_NESTING`] deep).
fn resolve_uses(decls: &mut [Decl], f: &mut dyn FnMut(&mut ast::Name)) {
    for d in decls {
        match d {
            Decl::Use { component, .. } => f(component),
            Decl::For { decls, .. } => resolve_uses(decls, f),
            _ => {}
        }
    }
}
