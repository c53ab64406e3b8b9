//! Parsing: runs the lalrpop grammar over the logos tokens and turns every lexical and
//! syntax error into a [`Diagnostic`] with a span and a hint.

use crate::ast::File;
use crate::diagnostics::Diagnostic;
use crate::lexer::{self, LexError, Literal, Token};
use lalrpop_util::{lalrpop_mod, ParseError};

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
    let tokens = lexer::lex(src).map(|r| r.map_err(|(e, span)| SyntaxError::Lex(e, span)));
    grammar::FileParser::new()
        .parse(tokens)
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
            SyntaxError::Lex(e @ (LexError::BadNumber(_) | LexError::BadExponent(_)), span) => {
                Diagnostic::error("E0006", e.to_string(), span)
                    .hint("numbers look like `12`, `0.4` or `1.5e-3`, unit exponents like `m/s^2`")
            }
            SyntaxError::Lex(LexError::UnexpectedChar, span) => {
                Diagnostic::error("E0001", "unexpected character", span)
                    .hint("comments start with `//`")
            }
            SyntaxError::BadType(span) => Diagnostic::error("E0007", "not a type", span)
                .label("expected a unit such as `m` or `N*s/m`, `1`, or `bool`")
                .hint("a type names a dimension by a unit: `state v: m/s = 0 m/s in [...]`"),
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
        .parse(tokens)
        .map_err(|e| Box::new(to_diagnostic(e, src)))
}
