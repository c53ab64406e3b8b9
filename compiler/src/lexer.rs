//! The lexer: one `logos` token enum whose callbacks parse literals.
//!
//! A number literal swallows the unit written right after it (`10 mm`, `0.4 N*s/m`,
//! `9.81 m/s^2`), so the parser sees one [`Token::Number`] already converted to SI with its
//! dimension. The unit rule is what makes `2 N * k` and `0.4 N*s/m` both unambiguous:
//! a unit follows its number after at most spaces or tabs, is itself written **without
//! spaces**, and each factor after `*` or `/` must be a known unit — otherwise the literal
//! ends before the operator. So `2 N * s` is two newtons times the value named `s`,
//! whereas `2 N*s` is an impulse. A number directly followed by a word that is not a unit is
//! an error (no valid program has a name right after a number).

use crate::units::{self, Dim};
use logos::Logos;
use std::fmt;

/// A number with its unit, converted to SI.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Literal {
    /// The value in SI units (`10 mm` → 0.01).
    pub value: f64,
    /// The dimension of the unit (`Dim::NONE` when no unit was written).
    pub dim: Dim,
    /// Whether the digits were an integer without unit (usable as an exponent or bound).
    pub is_plain_integer: bool,
}

/// Lexical errors. Spans come from the lexer, so the variants carry only what the message
/// needs.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum LexError {
    /// A character that starts no token.
    #[default]
    UnexpectedChar,
    /// A word right after a number that is not a known unit.
    UnknownUnit(String),
    /// A number the float parser rejects (e.g. `1e`).
    BadNumber(String),
    /// A unit exponent that is not a small integer (`m^x`).
    BadExponent(String),
    /// A number whose value in SI units is not a finite f64 (`1e309`, `1e308 km`).
    OutOfRange(String),
    /// A string (an import's file name) without its closing `"` on the same line.
    UnterminatedString,
}

impl fmt::Display for LexError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LexError::UnexpectedChar => write!(f, "unexpected character"),
            LexError::UnknownUnit(u) => write!(f, "unknown unit `{u}`"),
            LexError::BadNumber(n) => write!(f, "malformed number `{n}`"),
            LexError::BadExponent(e) => write!(f, "malformed unit exponent `{e}`"),
            LexError::OutOfRange(n) => {
                write!(
                    f,
                    "`{n}` is too large: in SI units it is beyond the range of f64"
                )
            }
            LexError::UnterminatedString => write!(f, "a string without its closing `\"`"),
        }
    }
}

/// The tokens of the Tactus language.
#[derive(Logos, Clone, Debug, PartialEq)]
#[logos(error = LexError)]
#[logos(skip r"[ \t\r\n\f\u{FEFF}]+")]
#[logos(skip(r"//[^\n]*", allow_greedy = true))]
#[allow(missing_docs)]
pub enum Token {
    #[token("instrument")]
    Instrument,
    #[token("component")]
    Component,
    #[token("sensor")]
    Sensor,
    #[token("param")]
    Param,
    #[token("state")]
    State,
    #[token("mode")]
    Mode,
    #[token("let")]
    Let,
    #[token("dynamics")]
    Dynamics,
    #[token("on")]
    On,
    #[token("while")]
    While,
    #[token("emit")]
    Emit,
    #[token("force")]
    Force,
    #[token("output")]
    Output,
    #[token("input")]
    Input,
    #[token("use")]
    Use,
    #[token("if")]
    If,
    #[token("else")]
    Else,
    #[token("and")]
    And,
    #[token("or")]
    Or,
    #[token("not")]
    Not,
    #[token("in")]
    In,
    #[token("true")]
    True,
    #[token("false")]
    False,
    #[token("bool")]
    Bool,
    #[token("for")]
    For,
    #[token("sum")]
    Sum,
    #[token("solve")]
    Solve,
    #[token("require")]
    Require,
    #[token("tolerance")]
    Tolerance,
    #[token("import")]
    Import,

    #[regex(r"[A-Za-z_][A-Za-z0-9_]*", |lex| lex.slice().to_string())]
    Ident(String),
    #[regex(r"[0-9]+(\.[0-9]+)?([eE][+-]?[0-9]+)?", number)]
    #[regex(r"[0-9]+(\.[0-9]+)?[eE][+-]?", bad_number)]
    Number(Literal),
    /// A string: an import's file name, `"friction.tactus"`, without its quotes. It has no
    /// escapes and ends on its line.
    #[regex(r#""[^"\n]*""#, string)]
    #[regex(r#""[^"\n]*"#, unterminated)]
    Str(String),

    #[token("{")]
    LBrace,
    #[token("}")]
    RBrace,
    #[token("(")]
    LParen,
    #[token(")")]
    RParen,
    #[token("[")]
    LBracket,
    #[token("]")]
    RBracket,
    #[token(",")]
    Comma,
    #[token(":")]
    Colon,
    #[token(".")]
    Dot,
    #[token("..")]
    DotDot,
    #[token("'")]
    Prime,
    #[token("=")]
    Eq,
    #[token("==")]
    EqEq,
    #[token("!=")]
    NotEq,
    #[token("<")]
    Lt,
    #[token("<=")]
    Le,
    #[token(">")]
    Gt,
    #[token(">=")]
    Ge,
    #[token("+")]
    Plus,
    #[token("-")]
    Minus,
    #[token("*")]
    Star,
    #[token("/")]
    Slash,
    #[token("^")]
    Caret,
}

impl Token {
    /// Whether this is a reserved word (it cannot be used as a name).
    pub fn is_keyword(&self) -> bool {
        use Token::*;
        matches!(
            self,
            Instrument
                | Component
                | Sensor
                | Param
                | State
                | Mode
                | Let
                | Dynamics
                | On
                | While
                | Emit
                | Force
                | Output
                | Input
                | Use
                | If
                | Else
                | And
                | Or
                | Not
                | In
                | True
                | False
                | Bool
                | For
                | Sum
                | Solve
                | Require
                | Tolerance
                | Import
        )
    }
}

impl fmt::Display for Token {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Token::Ident(s) => write!(f, "`{s}`"),
            Token::Number(_) => write!(f, "number"),
            Token::Str(s) => write!(f, "string \"{s}\""),
            other => {
                let text = match other {
                    Token::LBrace => "{",
                    Token::RBrace => "}",
                    Token::LParen => "(",
                    Token::RParen => ")",
                    Token::LBracket => "[",
                    Token::RBracket => "]",
                    Token::Comma => ",",
                    Token::Colon => ":",
                    Token::Dot => ".",
                    Token::DotDot => "..",
                    Token::Prime => "'",
                    Token::Eq => "=",
                    Token::EqEq => "==",
                    Token::NotEq => "!=",
                    Token::Lt => "<",
                    Token::Le => "<=",
                    Token::Gt => ">",
                    Token::Ge => ">=",
                    Token::Plus => "+",
                    Token::Minus => "-",
                    Token::Star => "*",
                    Token::Slash => "/",
                    Token::Caret => "^",
                    _ => "",
                };
                if text.is_empty() {
                    write!(f, "`{}`", format!("{other:?}").to_lowercase())
                } else {
                    write!(f, "`{text}`")
                }
            }
        }
    }
}

fn string(lex: &mut logos::Lexer<Token>) -> String {
    let s = lex.slice();
    s[1..s.len() - 1].to_string()
}

fn unterminated(_: &mut logos::Lexer<Token>) -> Result<String, LexError> {
    Err(LexError::UnterminatedString)
}

fn bad_number(lex: &mut logos::Lexer<Token>) -> Result<Literal, LexError> {
    Err(LexError::BadNumber(lex.slice().to_string()))
}

/// Parses the digits and then the unit written after them (see the module doc).
fn number(lex: &mut logos::Lexer<Token>) -> Result<Literal, LexError> {
    let digits = lex.slice();
    let mut value: f64 = digits
        .parse()
        .map_err(|_| LexError::BadNumber(digits.to_string()))?;
    let is_int = digits.bytes().all(|b| b.is_ascii_digit());
    let rest = lex.remainder();
    let gap = rest.len() - rest.trim_start_matches([' ', '\t']).len();
    let after = &rest[gap..];
    let first = word(after);
    if !value.is_finite() && units::lookup(first).is_none() {
        return Err(LexError::OutOfRange(digits.to_string()));
    }
    if first.is_empty() {
        return Ok(Literal {
            value,
            dim: Dim::NONE,
            is_plain_integer: is_int,
        });
    }
    let Some(unit) = units::lookup(first) else {
        if is_keyword(first) {
            return Ok(Literal {
                value,
                dim: Dim::NONE,
                is_plain_integer: is_int,
            });
        }
        lex.bump(gap + first.len());
        return Err(LexError::UnknownUnit(first.to_string()));
    };
    let mut dim = Dim::NONE;
    let mut consumed = gap;
    let mut factor = Some((unit, first.len(), false));
    while let Some((unit, len, divide)) = factor.take() {
        consumed += len;
        let (exp, exp_len) = exponent(&lex.remainder()[consumed..])?;
        consumed += exp_len;
        let (d, s) = (unit.dim.powi(exp), unit.scale.powi(exp));
        if divide {
            dim = dim / d;
            value /= s;
        } else {
            dim = dim * d;
            value *= s;
        }
        let tail = &lex.remainder()[consumed..];
        if let Some(op @ ('*' | '/')) = tail.chars().next() {
            let next = word(&tail[1..]);
            if let Some(u) = units::lookup(next) {
                factor = Some((u, 1 + next.len(), op == '/'));
            }
        }
    }
    lex.bump(consumed);
    if !value.is_finite() {
        return Err(LexError::OutOfRange(lex.slice().to_string()));
    }
    Ok(Literal {
        value,
        dim,
        is_plain_integer: false,
    })
}

/// Reads `^N` or `^-N` after a unit factor; returns (exponent, characters consumed).
fn exponent(s: &str) -> Result<(i32, usize), LexError> {
    let Some(tail) = s.strip_prefix('^') else {
        return Ok((1, 0));
    };
    let len = tail
        .char_indices()
        .take_while(|&(i, c)| c.is_ascii_digit() || (i == 0 && c == '-'))
        .count();
    let text = &tail[..len];
    match text.parse::<i32>() {
        Ok(e) if (-8..=8).contains(&e) => Ok((e, 1 + len)),
        _ => Err(LexError::BadExponent(format!("^{text}"))),
    }
}

fn word(s: &str) -> &str {
    let end = s
        .char_indices()
        .find(|&(i, c)| !(c.is_ascii_alphabetic() || c == '_' || (i > 0 && c.is_ascii_digit())))
        .map_or(s.len(), |(i, _)| i);
    &s[..end]
}

fn is_keyword(w: &str) -> bool {
    matches!(w, "and" | "or" | "in" | "else" | "not")
}

/// A lexed token with its byte span, as lalrpop's external-lexer interface wants it.
pub type Spanned = (usize, Token, usize);

/// Lexes a whole source into lalrpop triples; the first error stops it.
pub fn lex(
    src: &str,
) -> impl Iterator<Item = Result<Spanned, (LexError, std::ops::Range<usize>)>> + '_ {
    Token::lexer(src).spanned().map(|(tok, span)| match tok {
        Ok(t) => Ok((span.start, t, span.end)),
        Err(e) => Err((e, span)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lit(src: &str) -> Literal {
        match Token::lexer(src).next() {
            Some(Ok(Token::Number(l))) => l,
            other => panic!("{src}: {other:?}"),
        }
    }

    #[test]
    fn literals_with_units() {
        let cases: &[(&str, f64, &str)] = &[
            ("10 mm", 0.01, "m"),
            ("0.4 N*s/m", 0.4, "N*s/m"),
            ("0.007 N*m/A", 0.007, "N*m/A"),
            ("44.1 kHz", 44100.0, "1/s"),
            ("9.81 m/s^2", 9.81, "m/s^2"),
            ("1.5e3 g", 1.5, "kg"),
            ("3 rad", 3.0, "1"),
            ("2", 2.0, "1"),
            ("10mm", 0.01, "m"),
        ];
        for (src, v, u) in cases {
            let l = lit(src);
            assert!((l.value - v).abs() <= 1e-12 * v.abs(), "{src}: {}", l.value);
            assert_eq!(l.dim.unit_string(), *u, "{src}");
        }
    }

    #[test]
    fn unit_stops_before_non_unit_factor() {
        let toks: Vec<_> = Token::lexer("2 N * s 2 N/k")
            .collect::<Result<_, _>>()
            .unwrap();
        assert_eq!(toks.len(), 6, "{toks:?}");
        assert!(matches!(toks[1], Token::Star));
        assert!(matches!(toks[4], Token::Slash));
    }

    #[test]
    fn unknown_unit_is_an_error() {
        let r: Vec<_> = Token::lexer("10 mmm").spanned().collect();
        assert_eq!(r[0].0, Err(LexError::UnknownUnit("mmm".into())));
        assert_eq!(r[0].1, 0..6);
    }
}
