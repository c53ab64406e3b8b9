//! Parsing: runs the lalrpop grammar over the logos tokens and turns every lexical and
//! syntax error into a [`Diagnostic`] with a span and a hint.
//!
//! The parser itself keeps its stack on the heap, but every later pass (expansion,
//! lowering, even dropping the tree) walks the AST recursively. So the grammar's actions
//! measure each expression's and each `for` loop's nesting depth as they build it
//! ([`Nesting`]) and stop at [`MAX_NESTING`] with E0008: a 20,000-term sum or a 10 MB
//! one-line file is a diagnostic, not a stack overflow. A sum of N terms is N levels deep
//! (the operators group to the left), so the cap also bounds the length of an operator
//! chain in one expression.

use crate::ast::File;
use crate::ast::{Decl, Expr, ExprKind, Span, Spanned};
use crate::diagnostics::Diagnostic;
use crate::lexer::{self, LexError, Literal, Token};
use lalrpop_util::{lalrpop_mod, ParseError};
use std::cell::RefCell;
use std::collections::HashMap;

/// The deepest an expression (operators, calls, `if`s, indices, `sum`s; a chain of `+` is
/// as deep as it is long) or a nest of `for` loops may be in the source. Far above any
/// hand-written profile; low enough that every recursive pass stays within a 2 MB stack.
pub const MAX_NESTING: u32 = 200;

/// The nesting depth of the subtrees the grammar has built and not yet put into a parent,
/// by span. A parent takes its children's entries out (so the table holds only the trees
/// waiting on the parser's stack and the top-level expressions of declarations).
#[derive(Default)]
pub struct Nesting {
    exprs: RefCell<HashMap<(usize, usize), u32>>,
    loops: RefCell<HashMap<(usize, usize), u32>>,
}

type GrammarResult<T> = Result<T, ParseError<usize, Token, SyntaxError>>;

impl Nesting {
    fn take(map: &RefCell<HashMap<(usize, usize), u32>>, span: &Span) -> u32 {
        map.borrow_mut()
            .remove(&(span.start, span.end))
            .unwrap_or(1)
    }

    /// Builds an expression node at `span`, or E0008 when it nests deeper than
    /// [`MAX_NESTING`].
    pub fn expr(&self, node: ExprKind, span: Span) -> GrammarResult<Expr> {
        let mut children: Vec<&Expr> = Vec::new();
        match &node {
            ExprKind::Number(_) | ExprKind::Bool(_) | ExprKind::Path(_) => {}
            ExprKind::Neg(a) | ExprKind::Not(a) | ExprKind::Pow(a, _) => children.push(a),
            ExprKind::Binary(_, a, b) => children.extend([&**a, &**b]),
            ExprKind::Call(_, args) => children.extend(args.iter()),
            ExprKind::If(c, a, b) => children.extend([&**c, &**a, &**b]),
            ExprKind::Element(segs) => children.extend(segs.iter().filter_map(|(_, i)| i.as_ref())),
            ExprKind::Sum { range, body, .. } => children.extend([&range.lo, &range.hi, &**body]),
        }
        let depth = 1 + children
            .iter()
            .map(|c| Self::take(&self.exprs, &c.span))
            .max()
            .unwrap_or(0);
        if depth > MAX_NESTING {
            // Point at the operand that went over (a long chain's last term), not at the
            // whole chain, which may be megabytes long.
            let at = match &node {
                ExprKind::Binary(_, _, b) => b.span.clone(),
                _ => span.start..(span.start + 1).min(span.end),
            };
            return Err(ParseError::User {
                error: SyntaxError::TooDeep(at),
            });
        }
        let mut map = self.exprs.borrow_mut();
        let e = map.entry((span.start, span.end)).or_insert(0);
        *e = (*e).max(depth);
        Ok(Spanned { node, span })
    }

    /// A `for` loop at `span`, or E0008 when loops nest deeper than [`MAX_NESTING`].
    pub fn decl(&self, d: Decl, span: Span) -> GrammarResult<Decl> {
        let depth = match &d {
            Decl::For { decls, .. } => {
                1 + decls
                    .iter()
                    .filter_map(|c| match c {
                        Decl::For { span, .. } => Some(Self::take(&self.loops, span)),
                        _ => None,
                    })
                    .max()
                    .unwrap_or(0)
            }
            _ => 1,
        };
        if depth > MAX_NESTING {
            return Err(ParseError::User {
                error: SyntaxError::TooDeep(span.start..(span.start + 3).min(span.end)),
            });
        }
        self.loops
            .borrow_mut()
            .insert((span.start, span.end), depth);
        Ok(d)
    }
}

lalrpop_mod!(
    #[allow(clippy::all, missing_docs, unused_parens)]
    grammar
);

/// Errors raised inside grammar actions or by the lexer.
#[derive(Clone, Debug, PartialEq)]
pub enum SyntaxError {
    /// A lexical error at a span.
    Lex(LexError, std::ops::Range<usize>),
    /// A type annotation that is not a unit, `1` or `bool`, at a span.
    BadType(std::ops::Range<usize>),
    /// An exponent that is not a small integer, at a span.
    BadExponent(std::ops::Range<usize>),
    /// An expression or a nest of loops deeper than [`MAX_NESTING`], at the span of the
    /// node that went over.
    TooDeep(std::ops::Range<usize>),
}

/// An integer literal's value, for exponents (`x^2`, `m^-1`).
pub fn int_literal(
    l: &Literal,
    span: std::ops::Range<usize>,
) -> Result<i64, ParseError<usize, Token, SyntaxError>> {
    if l.is_plain_integer && l.value <= 8.0 {
        Ok(l.value as i64)
    } else {
        Err(ParseError::User {
            error: SyntaxError::BadExponent(span),
        })
    }
}

/// Parses a `.tactus` source into its AST, or the first syntax error as a diagnostic.
pub fn parse(src: &str) -> Result<File, Box<Diagnostic>> {
    parse_at(src, 0)
}

/// [`parse`] of a file whose bytes start at `base` in a [`crate::sources::SourceMap`]:
/// every span of the tree and of the diagnostic is offset by `base`.
pub fn parse_at(src: &str, base: usize) -> Result<File, Box<Diagnostic>> {
    let tokens = lexer::lex(src).map(|r| match r {
        Ok((l, t, r)) => Ok((l + base, t, r + base)),
        Err((e, span)) => Err(SyntaxError::Lex(e, span.start + base..span.end + base)),
    });
    grammar::FileParser::new()
        .parse(&Nesting::default(), tokens)
        .map_err(|e| Box::new(to_diagnostic(e, src)))
}

fn to_diagnostic(e: ParseError<usize, Token, SyntaxError>, src: &str) -> Diagnostic {
    match e {
        ParseError::InvalidToken { location } => {
            Diagnostic::error("E0001", "unexpected character", location..location + 1)
        }
        ParseError::UnrecognizedEof { location, expected } => {
            let unclosed = src.matches('{').count() > src.matches('}').count();
            let d = Diagnostic::error("E0002", "unexpected end of file", location..location)
                .label(format!("expected {}", expected_list(&expected)));
            if unclosed {
                d.hint("a `{` is never closed: add the matching `}`")
            } else {
                d
            }
        }
        ParseError::UnrecognizedToken {
            token: (l, tok, r),
            expected,
        } => {
            let d = Diagnostic::error("E0003", format!("unexpected {tok}"), l..r)
                .label(format!("expected {}", expected_list(&expected)));
            match tok {
                Token::Ident(_) | Token::Number(_)
                    if expected.iter().any(|x| x == "\"}\"") =>
                {
                    d.hint("each declaration starts with a keyword: sensor, param, state, mode, let, force, output, dynamics, on, while, use")
                }
                _ if tok.is_keyword() && expected.iter().any(|x| x == "\"ident\"") => {
                    d.hint(format!("{tok} is a keyword and cannot be used as a name"))
                }
                _ => d,
            }
        }
        ParseError::ExtraToken { token: (l, tok, r) } => {
            Diagnostic::error("E0004", format!("unexpected {tok} after the end"), l..r)
        }
        ParseError::User { error } => match error {
            SyntaxError::Lex(LexError::UnknownUnit(u), span) => {
                let hint = format!(
                    "known units: {}; write a product of units without spaces, e.g. `0.4 N*s/m`",
                    crate::units::unit_names().collect::<Vec<_>>().join(", ")
                );
                Diagnostic::error("E0005", format!("unknown unit `{u}`"), span)
                    .label("not a unit")
                    .hint(hint)
            }
            SyntaxError::Lex(
                e @ (LexError::BadNumber(_) | LexError::BadExponent(_) | LexError::OutOfRange(_)),
                span,
            ) => {
                Diagnostic::error("E0006", e.to_string(), span)
                    .hint("numbers look like `12`, `0.4` or `1.5e-3`, unit exponents like `m/s^2`")
            }
            SyntaxError::Lex(LexError::UnterminatedString, span) => {
                Diagnostic::error("E0009", "a string without its closing `\"`", span)
                    .label("the line ends inside this string")
                    .hint("an import names its file in double quotes on one line: `import \"friction.tactus\"`")
            }
            SyntaxError::Lex(LexError::UnexpectedChar, span) => {
                Diagnostic::error("E0001", "unexpected character", span)
                    .hint("comments start with `//`")
            }
            SyntaxError::BadType(span) => Diagnostic::error("E0007", "not a type", span)
                .label("expected a unit such as `m` or `N*s/m`, `1`, or `bool`")
                .hint("a type names a dimension by a unit: `state v: m/s = 0 m/s in [...]`"),
            SyntaxError::TooDeep(span) => Diagnostic::error(
                "E0008",
                format!("nested more than {MAX_NESTING} levels deep"),
                span,
            )
            .label("this expression or loop nest goes over the limit")
            .hint("split it with `let`s (`let a = …`), or write a long sum as `sum(i in 0..N, …)` over an array"),
            SyntaxError::BadExponent(span) => {
                Diagnostic::error("E0007", "an exponent must be a small integer", span)
                    .label("expected an integer from -8 to 8")
                    .hint("write powers as `x^2` or units as `m/s^2`")
            }
        },
    }
}

fn expected_list(expected: &[String]) -> String {
    let pretty: Vec<String> = expected
        .iter()
        .map(|e| match e.as_str() {
            "\"ident\"" => "a name".to_string(),
            "\"num\"" => "a number".to_string(),
            "\"str\"" => "a file name in quotes".to_string(),
            other => format!("`{}`", other.trim_matches('"')),
        })
        .collect();
    match pretty.len() {
        0 => "nothing".into(),
        1 => pretty[0].clone(),
        n if n > 8 => format!("one of {}, …", pretty[..8].join(", ")),
        _ => format!("one of {}", pretty.join(", ")),
    }
}

/// Parses a single expression (e.g. the value of a `--param` override).
pub fn parse_expr(src: &str) -> Result<crate::ast::Expr, Box<Diagnostic>> {
    let tokens = lexer::lex(src).map(|r| r.map_err(|(e, span)| SyntaxError::Lex(e, span)));
    grammar::ExprParser::new()
        .parse(&Nesting::default(), tokens)
        .map_err(|e| Box::new(to_diagnostic(e, src)))
}
