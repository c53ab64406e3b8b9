//! The answers: capabilities, diagnostics, hover, definition, references, completion and
//! the outline, each a translation of a `tactus_compiler::query` answer into the
//! protocol's types.

use crate::docs::{Doc, Docs, PlanState};
use crate::position::LineIndex;
use lsp_types::*;
use std::collections::HashMap;
use std::path::Path;
use tactus_compiler::diagnostics::{Diagnostic as Diag, Severity};
use tactus_compiler::query::{self, SymbolKind as K};
use tactus_compiler::sources::{FileId, SourceMap};

/// What the server can do.
pub fn initialize_result() -> InitializeResult {
    InitializeResult {
        capabilities: ServerCapabilities {
            text_document_sync: Some(TextDocumentSyncCapability::Kind(TextDocumentSyncKind::FULL)),
            hover_provider: Some(HoverProviderCapability::Simple(true)),
            definition_provider: Some(OneOf::Left(true)),
            references_provider: Some(OneOf::Left(true)),
            document_symbol_provider: Some(OneOf::Left(true)),
            completion_provider: Some(CompletionOptions {
                trigger_characters: Some(vec![".".into(), ":".into()]),
                ..CompletionOptions::default()
            }),
            ..ServerCapabilities::default()
        },
        server_info: Some(ServerInfo {
            name: "tactus lsp".into(),
            version: Some(env!("CARGO_PKG_VERSION").into()),
        }),
    }
}

/// Where spans of a program's files are, for the client: each file's URI (the document's
/// own for the main file, [`crate::files::uri_of`] for the others) and its lines.
pub struct Places<'a> {
    doc_uri: &'a Uri,
    sources: &'a SourceMap,
    lib: Option<&'a std::path::Path>,
    lines: HashMap<FileId, LineIndex>,
}

impl<'a> Places<'a> {
    /// The places of `sources`, whose main file is the document at `doc_uri`; `lib` the
    /// directory of the library's files.
    pub fn new(doc_uri: &'a Uri, sources: &'a SourceMap, lib: Option<&'a std::path::Path>) -> Self {
        Places {
            doc_uri,
            sources,
            lib,
            lines: HashMap::new(),
        }
    }

    /// The file of `span` (in the program's address space) and its range there.
    fn range(&mut self, span: &std::ops::Range<usize>) -> (FileId, Range) {
        let (id, local) = self.sources.locate(span);
        let text = &self.sources.get(id).text;
        let li = self.lines.entry(id).or_insert_with(|| LineIndex::new(text));
        (id, li.range(text, &local))
    }

    /// The location of `span`, or `None` in a file the client cannot open.
    pub fn location(&mut self, span: &std::ops::Range<usize>) -> Option<Location> {
        let (id, range) = self.range(span);
        let uri = if id == FileId::MAIN {
            self.doc_uri.clone()
        } else {
            crate::files::uri_of(&self.sources.get(id).origin, self.lib)?
        };
        Some(Location { uri, range })
    }
}

/// The compiler's diagnostics in the protocol's form: the primary span is the range, the
/// message is `tactus check`'s headline, then the primary label and the hint on lines of
/// their own; secondary spans are related information, in whichever file they lie. A
/// diagnostic whose primary span lies in an imported file is shown at the import that
/// brings that file (its secondary span in the document), its message naming the place,
/// and its place in the imported file is related information.
pub fn diagnostics(
    uri: &Uri,
    sources: &SourceMap,
    lib: Option<&std::path::Path>,
    ds: &[Diag],
) -> Vec<Diagnostic> {
    let mut places = Places::new(uri, sources, lib);
    ds.iter()
        .map(|d| {
            let (file, primary) = places.range(&d.primary.0);
            let mut message = d.message.clone();
            let mut related: Vec<DiagnosticRelatedInformation> = Vec::new();
            let range = if file == FileId::MAIN {
                primary
            } else {
                let f = sources.get(file);
                message = format!(
                    "{}:{}:{}: {message}",
                    f.name,
                    primary.start.line + 1,
                    primary.start.character + 1
                );
                if let Some(location) = places.location(&d.primary.0) {
                    related.push(DiagnosticRelatedInformation {
                        location,
                        message: if d.primary.1.is_empty() {
                            d.message.clone()
                        } else {
                            d.primary.1.clone()
                        },
                    });
                }
                // The import in the document that brings the file.
                d.secondary
                    .iter()
                    .find(|(s, _)| sources.file_at(s.start) == FileId::MAIN)
                    .map_or(Range::default(), |(s, _)| places.range(s).1)
            };
            if !d.primary.1.is_empty() {
                message.push_str(&format!("\n{}", d.primary.1));
            }
            if let Some(h) = &d.hint {
                message.push_str(&format!("\nhint: {h}"));
            }
            related.extend(d.secondary.iter().filter_map(|(s, m)| {
                Some(DiagnosticRelatedInformation {
                    location: places.location(s)?,
                    message: m.clone(),
                })
            }));
            Diagnostic {
                range,
                severity: Some(match d.severity {
                    Severity::Error => DiagnosticSeverity::ERROR,
                    Severity::Warning => DiagnosticSeverity::WARNING,
                }),
                code: Some(NumberOrString::String(d.code.into())),
                source: Some("tactus".into()),
                message,
                related_information: (!related.is_empty()).then_some(related),
                ..Diagnostic::default()
            }
        })
        .collect()
}

fn doc_at<'s>(docs: &'s Docs, p: &TextDocumentPositionParams) -> Option<(&'s Doc, usize)> {
    let doc = docs.get(p.text_document.uri.as_str())?;
    let offset = doc.lines.offset(&doc.text, p.position);
    Some((doc, offset))
}

/// Hover: the facts of the declaration a name denotes or of the term under the cursor.
pub fn hover(docs: &Docs, p: HoverParams) -> Option<Hover> {
    let (doc, offset) = doc_at(docs, &p.text_document_position_params)?;
    let a = &doc.analysis;
    let planned = match &doc.plan {
        PlanState::Ready(p) => Some(p.clone()),
        _ => None,
    };
    let plan = planned.as_ref().map(|p| query::Plan {
        fixed: &p.fixed,
        precision: &p.precision,
    });
    let program = a.lowered.as_ref().map(|l| &l.program);
    let facts = query::facts_at(&a.sources, &a.outlines(), &a.names, program, plan, offset)?;
    let mut md = format!("**{}**\n\n", facts.heading);
    if !facts.doc.is_empty() {
        md.push_str(&format!("{}\n\n", facts.doc));
    }
    for (k, v) in &facts.rows {
        md.push_str(&format!("- {k}: {v}\n"));
    }
    match &doc.plan {
        PlanState::None if a.lowered.is_none() => {
            md.push_str("\n_ranges, formats and error bounds appear when the profile compiles_\n")
        }
        PlanState::Pending(_) => md.push_str("\n_the fixed-point plan is still being computed_\n"),
        PlanState::Failed(e) => md.push_str(&format!("\n_no fixed-point plan: {e}_\n")),
        _ => {}
    }
    Some(Hover {
        contents: HoverContents::Markup(MarkupContent {
            kind: MarkupKind::Markdown,
            value: md,
        }),
        range: Some(doc.lines.range(&doc.text, &facts.span)),
    })
}

fn flat(outline: &[query::Symbol]) -> Vec<query::Symbol> {
    outline.iter().flat_map(|s| s.flatten()).cloned().collect()
}

/// Go to definition: the declaration's name, in the document or in the file it imports it
/// from (`lib`: where Tactus's library is written for the client to open).
pub fn definition(
    docs: &Docs,
    lib: Option<&Path>,
    p: GotoDefinitionParams,
) -> Option<GotoDefinitionResponse> {
    let (doc, offset) = doc_at(docs, &p.text_document_position_params)?;
    let a = &doc.analysis;
    let def = a.names.definition_at(offset, &flat(&a.outlines()))?;
    let mut places = Places::new(&doc.uri, &a.sources, lib);
    places.location(&def).map(GotoDefinitionResponse::Scalar)
}

/// Find references: every place the resolver resolved to the same declaration, in the
/// document and in the files it imports (`lib` as for [`definition`]).
pub fn references(docs: &Docs, lib: Option<&Path>, p: ReferenceParams) -> Option<Vec<Location>> {
    let (doc, offset) = doc_at(docs, &p.text_document_position)?;
    let a = &doc.analysis;
    let def = a.names.definition_at(offset, &flat(&a.outlines()))?;
    let mut spans = Vec::new();
    if p.context.include_declaration {
        spans.push(def.clone());
    }
    spans.extend(a.names.references(&def));
    let mut places = Places::new(&doc.uri, &a.sources, lib);
    Some(spans.iter().filter_map(|sp| places.location(sp)).collect())
}

fn completion_kind(k: K) -> CompletionItemKind {
    match k {
        K::Param => CompletionItemKind::CONSTANT,
        K::State | K::Let | K::Solve | K::Index => CompletionItemKind::VARIABLE,
        K::Sensor | K::Input => CompletionItemKind::FIELD,
        K::Mode => CompletionItemKind::ENUM,
        K::Variant => CompletionItemKind::ENUM_MEMBER,
        K::Force | K::Output => CompletionItemKind::PROPERTY,
        K::Instance => CompletionItemKind::MODULE,
        K::Instrument | K::Component => CompletionItemKind::CLASS,
    }
}

fn symbol_kind(k: K) -> SymbolKind {
    match k {
        K::Instrument => SymbolKind::CLASS,
        K::Component => SymbolKind::STRUCT,
        K::Param => SymbolKind::CONSTANT,
        K::State | K::Let | K::Solve => SymbolKind::VARIABLE,
        K::Sensor | K::Input => SymbolKind::FIELD,
        K::Mode => SymbolKind::ENUM,
        K::Variant => SymbolKind::ENUM_MEMBER,
        K::Force | K::Output => SymbolKind::PROPERTY,
        K::Instance => SymbolKind::OBJECT,
        K::Index => SymbolKind::NAMESPACE,
    }
}

/// What the text before the cursor asks to complete.
enum Context<'t> {
    /// Members of the instance named before a `.`.
    Member(&'t str),
    /// A unit (after a number or a `:`).
    Unit,
    /// Any name.
    Name,
}

fn context(before: &str) -> Context<'_> {
    let ident = |c: char| c.is_alphanumeric() || c == '_';
    let head = before.trim_end_matches(ident);
    if let Some(h) = head.strip_suffix('.') {
        let name_start = h.trim_end_matches(ident).len();
        let name = &h[name_start..];
        if !name.is_empty() && !name.starts_with(|c: char| c.is_ascii_digit()) {
            return Context::Member(name);
        }
    }
    let h = head.trim_end();
    if h.ends_with(':') {
        return Context::Unit;
    }
    // A number literal just before (`180 N`, `2.5e-3 m`): its unit comes next.
    let num_start = h
        .trim_end_matches(|c: char| {
            c.is_ascii_digit() || matches!(c, '.' | '_' | 'e' | 'E' | '+' | '-')
        })
        .len();
    let token = &h[num_start..];
    let token_start = h[..num_start].chars().next_back();
    if token.starts_with(|c: char| c.is_ascii_digit())
        && !token_start.is_some_and(ident)
        && head.len() > h.len()
    {
        return Context::Unit;
    }
    Context::Name
}

/// Completion: names in scope, an instance's members, units, the built-in functions.
pub fn completion(docs: &Docs, p: CompletionParams) -> Option<CompletionResponse> {
    let (doc, offset) = doc_at(docs, &p.text_document_position)?;
    let before = doc.text.get(..offset).unwrap_or("");
    let outline = if doc.analysis.outline.is_empty() {
        &doc.last_outline
    } else {
        &doc.analysis.outline
    };
    let item = |s: &query::Symbol| CompletionItem {
        label: s.name.clone(),
        kind: Some(completion_kind(s.kind)),
        detail: Some(format!("{} {}", s.kind.word(), s.detail).trim().to_string()),
        ..CompletionItem::default()
    };
    let mut items: Vec<CompletionItem> = Vec::new();
    match context(before) {
        Context::Member(inst) => {
            // The instance's component may be an imported one.
            let mut all = outline.clone();
            all.extend(doc.analysis.imported.iter().cloned());
            items.extend(query::members(&all, offset, inst).into_iter().map(item));
        }
        Context::Unit => {
            items.extend(
                tactus_compiler::units::unit_names().map(|u| CompletionItem {
                    label: u.into(),
                    kind: Some(CompletionItemKind::UNIT),
                    detail: tactus_compiler::units::lookup(u).map(|x| x.dim.to_string()),
                    ..CompletionItem::default()
                }),
            );
        }
        Context::Name => {
            let mut names = query::names_in_scope(outline, offset);
            if names.is_empty() {
                // Outside every body, or an outline from an older text: the instrument's.
                names = outline
                    .iter()
                    .filter(|b| b.kind == K::Instrument)
                    .flat_map(|b| b.children.iter().flat_map(|c| c.flatten()))
                    .filter(|s| s.kind != K::Variant)
                    .collect();
            }
            let mut seen = std::collections::HashSet::new();
            items.extend(
                names
                    .into_iter()
                    .filter(|s| seen.insert(s.name.clone()))
                    .map(item),
            );
            items.extend(
                tactus_compiler::lower::BUILTINS
                    .iter()
                    .map(|(n, sig)| CompletionItem {
                        label: (*n).into(),
                        kind: Some(CompletionItemKind::FUNCTION),
                        detail: Some(format!("built-in {sig}")),
                        ..CompletionItem::default()
                    }),
            );
            items.push(CompletionItem {
                label: tactus_compiler::lower::SAMPLE_RATE.into(),
                kind: Some(CompletionItemKind::CONSTANT),
                detail: Some("built-in: the board's sample rate, Hz".into()),
                ..CompletionItem::default()
            });
        }
    }
    Some(CompletionResponse::Array(items))
}

#[allow(deprecated)] // `DocumentSymbol::deprecated` must be written out
fn document_symbol(doc: &Doc, s: &query::Symbol) -> DocumentSymbol {
    let range = doc.lines.range(&doc.text, &s.span);
    let mut selection = doc.lines.range(&doc.text, &s.name_span);
    if selection.start < range.start || selection.end > range.end {
        selection = range;
    }
    DocumentSymbol {
        name: s.name.clone(),
        detail: (!s.detail.is_empty()).then(|| s.detail.clone()),
        kind: symbol_kind(s.kind),
        tags: None,
        deprecated: None,
        range,
        selection_range: selection,
        children: (!s.children.is_empty())
            .then(|| s.children.iter().map(|c| document_symbol(doc, c)).collect()),
    }
}

/// The outline: instruments and components with their declarations.
pub fn document_symbols(docs: &Docs, p: DocumentSymbolParams) -> Option<DocumentSymbolResponse> {
    let doc = docs.get(p.text_document.uri.as_str())?;
    Some(DocumentSymbolResponse::Nested(
        doc.analysis
            .outline
            .iter()
            .map(|sym| document_symbol(doc, sym))
            .collect(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn completion_contexts() {
        assert!(matches!(
            context("  force f = esc."),
            Context::Member("esc")
        ));
        assert!(matches!(
            context("  force f = esc.ph"),
            Context::Member("esc")
        ));
        assert!(matches!(context("  param k = 180 "), Context::Unit));
        assert!(matches!(context("  param k = 180 N"), Context::Unit));
        assert!(matches!(context("  input x: "), Context::Unit));
        assert!(matches!(context("  force f = k"), Context::Name));
        assert!(matches!(context("  force f = x2 "), Context::Name));
        assert!(matches!(context("  force f = 1.5."), Context::Name));
        assert!(matches!(context(""), Context::Name));
    }
}
