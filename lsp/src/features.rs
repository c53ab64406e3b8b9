//! The answers: capabilities, diagnostics, hover, definition, references, completion and
//! the outline, each a translation of a `tactus_compiler::query` answer into the
//! protocol's types.

use crate::docs::{Doc, Docs, PlanState};
use crate::position::LineIndex;
use lsp_types::*;
use tactus_compiler::diagnostics::{Diagnostic as Diag, Severity};
use tactus_compiler::query::{self, SymbolKind as K};

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

/// The compiler's diagnostics in the protocol's form: the primary span is the range, the
/// message is `tactus check`'s headline, then the primary label and the hint on lines of
/// their own; secondary spans are related information.
pub fn diagnostics(uri: &Uri, text: &str, lines: &LineIndex, ds: &[Diag]) -> Vec<Diagnostic> {
    ds.iter()
        .map(|d| {
            let mut message = d.message.clone();
            if !d.primary.1.is_empty() {
                message.push_str(&format!("\n{}", d.primary.1));
            }
            if let Some(h) = &d.hint {
                message.push_str(&format!("\nhint: {h}"));
            }
            let related: Vec<DiagnosticRelatedInformation> = d
                .secondary
                .iter()
                .map(|(s, m)| DiagnosticRelatedInformation {
                    location: Location {
                        uri: uri.clone(),
                        range: lines.range(text, s),
                    },
                    message: m.clone(),
                })
                .collect();
            Diagnostic {
                range: lines.range(text, &d.primary.0),
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
    let facts = query::facts_at(&doc.text, &a.outline, &a.names, program, plan, offset)?;
    let mut md = format!("**{}**\n\n", facts.heading);
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

/// Go to definition: the declaration's name.
pub fn definition(docs: &Docs, p: GotoDefinitionParams) -> Option<GotoDefinitionResponse> {
    let (doc, offset) = doc_at(docs, &p.text_document_position_params)?;
    let a = &doc.analysis;
    let def = a.names.definition_at(offset, &flat(&a.outline))?;
    Some(GotoDefinitionResponse::Scalar(Location {
        uri: doc.uri.clone(),
        range: doc.lines.range(&doc.text, &def),
    }))
}

/// Find references: every place the resolver resolved to the same declaration.
pub fn references(docs: &Docs, p: ReferenceParams) -> Option<Vec<Location>> {
    let (doc, offset) = doc_at(docs, &p.text_document_position)?;
    let a = &doc.analysis;
    let def = a.names.definition_at(offset, &flat(&a.outline))?;
    let mut spans = Vec::new();
    if p.context.include_declaration {
        spans.push(def.clone());
    }
    spans.extend(a.names.references(&def));
    Some(
        spans
            .iter()
            .map(|sp| Location {
                uri: doc.uri.clone(),
                range: doc.lines.range(&doc.text, sp),
            })
            .collect(),
    )
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
            items.extend(query::members(outline, offset, inst).into_iter().map(item));
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
