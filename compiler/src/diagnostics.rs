//! Diagnostics: every error and warning the compiler reports, with spans, and the one place
//! that renders them (codespan-reporting).
//!
//! Passes return `Vec<Diagnostic>`; nothing in the compiler prints. The CLI renders to the
//! terminal with colours, tests use [`emit_to_string`] for snapshots. A span may lie in any
//! file of a program (an instrument and the files it imports: [`crate::sources`]);
//! [`emit_files`] shows each label under its own file.

use crate::ast::Span;
use crate::sources::{Origin, SourceMap};
use codespan_reporting::diagnostic::{Diagnostic as CsDiagnostic, Label};
use codespan_reporting::files::SimpleFiles;
use codespan_reporting::term::{self, termcolor};

/// Whether a diagnostic stops compilation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Severity {
    /// Compilation fails.
    Error,
    /// Reported; compilation goes on.
    Warning,
}

/// One problem found in a source file.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// A stable code, e.g. `E0201`, one per kind of problem (listed in `docs/language.md`).
    pub code: &'static str,
    /// One-line summary.
    pub message: String,
    /// The primary span and what to say under it.
    pub primary: (Span, String),
    /// Related spans ("first defined here").
    pub secondary: Vec<(Span, String)>,
    /// What to do about it, when we know.
    pub hint: Option<String>,
}

impl Diagnostic {
    /// An error at `span`.
    pub fn error(code: &'static str, message: impl Into<String>, span: Span) -> Self {
        Diagnostic {
            severity: Severity::Error,
            code,
            message: message.into(),
            primary: (span, String::new()),
            secondary: Vec::new(),
            hint: None,
        }
    }
    /// A warning at `span`.
    pub fn warning(code: &'static str, message: impl Into<String>, span: Span) -> Self {
        Diagnostic {
            severity: Severity::Warning,
            ..Diagnostic::error(code, message, span)
        }
    }
    /// Sets the text under the primary span.
    pub fn label(mut self, text: impl Into<String>) -> Self {
        self.primary.1 = text.into();
        self
    }
    /// Adds a related span.
    pub fn with_secondary(mut self, span: Span, text: impl Into<String>) -> Self {
        self.secondary.push((span, text.into()));
        self
    }
    /// Adds a hint.
    pub fn hint(mut self, text: impl Into<String>) -> Self {
        self.hint = Some(text.into());
        self
    }
    /// Whether this is an error.
    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }

    fn to_codespan(&self, files: &SourceMap) -> CsDiagnostic<usize> {
        let d = match self.severity {
            Severity::Error => CsDiagnostic::error(),
            Severity::Warning => CsDiagnostic::warning(),
        };
        let label = |style: fn(usize, Span) -> Label<usize>, span: &Span, text: &str| {
            let (id, local) = files.locate(span);
            style(id.index(), local).with_message(text)
        };
        let mut labels = vec![label(Label::primary, &self.primary.0, &self.primary.1)];
        labels.extend(
            self.secondary
                .iter()
                .map(|(s, m)| label(Label::secondary, s, m)),
        );
        d.with_code(self.code)
            .with_message(&self.message)
            .with_labels(labels)
            .with_notes(self.hint.iter().map(|h| format!("hint: {h}")).collect())
    }
}

/// Renders diagnostics for `file_name`/`source` to a writer (colours as the writer allows):
/// [`emit_files`] of a program of one file.
pub fn emit(
    out: &mut dyn termcolor::WriteColor,
    file_name: &str,
    source: &str,
    diagnostics: &[Diagnostic],
) -> std::io::Result<()> {
    emit_files(
        out,
        &SourceMap::new(file_name, Origin::Text, source),
        diagnostics,
    )
}

/// Renders diagnostics whose spans lie in the files of `files` (an instrument and the files
/// it imports) to a writer: each label under the line of its own file, named as
/// [`crate::sources::SourceFile::name`] says.
pub fn emit_files(
    out: &mut dyn termcolor::WriteColor,
    files: &SourceMap,
    diagnostics: &[Diagnostic],
) -> std::io::Result<()> {
    let mut db = SimpleFiles::new();
    for f in files.files() {
        db.add(f.name.as_str(), f.text.as_str());
    }
    let config = term::Config::default();
    for d in diagnostics {
        let cs = match long_line(files, d) {
            // Rendering a megabyte-long line (and a caret line as long) takes minutes and
            // shows nothing readable: name the place instead.
            Some((file_name, line, column, len)) => {
                let mut notes = vec![format!(
                    "at {file_name}:{line}:{column} (a line of {len} bytes, not shown){}",
                    if d.primary.1.is_empty() {
                        String::new()
                    } else {
                        format!(": {}", d.primary.1)
                    }
                )];
                notes.extend(d.hint.iter().map(|h| format!("hint: {h}")));
                let base = match d.severity {
                    Severity::Error => CsDiagnostic::error(),
                    Severity::Warning => CsDiagnostic::warning(),
                };
                base.with_code(d.code)
                    .with_message(&d.message)
                    .with_notes(notes)
            }
            None => d.to_codespan(files),
        };
        term::emit_to_write_style(out, &config, &db, &cs).map_err(std::io::Error::other)?;
    }
    Ok(())
}

/// The longest source line [`emit_files`] shows under a diagnostic, bytes.
const MAX_SHOWN_LINE: usize = 4096;

/// (file name, line, column, line length), 1-based, of the first span of `d` whose line is
/// longer than [`MAX_SHOWN_LINE`].
fn long_line<'f>(files: &'f SourceMap, d: &Diagnostic) -> Option<(&'f str, usize, usize, usize)> {
    std::iter::once(&d.primary.0)
        .chain(d.secondary.iter().map(|(s, _)| s))
        .find_map(|span| {
            let (id, local) = files.locate(span);
            let file = files.get(id);
            let source = file.text.as_str();
            let mut at = local.start;
            while !source.is_char_boundary(at) {
                at -= 1;
            }
            let start = source[..at].rfind('\n').map_or(0, |i| i + 1);
            let end = source[at..].find('\n').map_or(source.len(), |i| at + i);
            (end - start > MAX_SHOWN_LINE).then(|| {
                let line = source[..start].matches('\n').count() + 1;
                let column = source[start..at].chars().count() + 1;
                (file.name.as_str(), line, column, end - start)
            })
        })
}

/// Renders diagnostics to a plain string (no colours), for tests and snapshots.
pub fn emit_to_string(file_name: &str, source: &str, diagnostics: &[Diagnostic]) -> String {
    emit_files_to_string(
        &SourceMap::new(file_name, Origin::Text, source),
        diagnostics,
    )
}

/// [`emit_files`] to a plain string (no colours), for tests and snapshots.
pub fn emit_files_to_string(files: &SourceMap, diagnostics: &[Diagnostic]) -> String {
    let mut buf = termcolor::NoColor::new(Vec::new());
    // Writing into a Vec cannot fail.
    let _ = emit_files(&mut buf, files, diagnostics);
    String::from_utf8_lossy(&buf.into_inner()).into_owned()
}

/// The candidate closest to `name` by edit distance, if it is close enough to be a typo.
pub fn closest<'s>(name: &str, candidates: impl Iterator<Item = &'s str>) -> Option<&'s str> {
    candidates
        .map(|c| (levenshtein(name, c), c))
        .filter(|&(d, c)| d <= (name.len().max(c.len()) / 3).max(1))
        .min()
        .map(|(_, c)| c)
}

/// Edit distance (Levenshtein) between `a` and `b`, in characters.
fn levenshtein(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1];
        for (j, &cb) in b.iter().enumerate() {
            cur.push(
                (prev[j] + usize::from(ca != cb))
                    .min(prev[j + 1] + 1)
                    .min(cur[j] + 1),
            );
        }
        prev = cur;
    }
    prev[b.len()]
}
