//! The Tactus touch-profile language: lexer, parser, name and dimension checks, the IR, and
//! the f64 reference interpreter that defines what every engine must compute.
//!
//! Pipeline: [`parse::parse`] (logos + lalrpop) → [`ast::File`] → [`lower::lower`] (name
//! resolution, dimension check, component instancing) → [`ir::Program`] →
//! [`interp::Instance`] (per sample: sensors in; forces, outputs, states and events out).
//! [`fixed`] plans the fixed-point formats; [`cgen`] and [`thumb`] are the backends.
//!
//! **Hostile input.** [`parse`] measures nesting as the grammar builds the tree and stops at
//! [`parse::MAX_NESTING`] (E0008), so no later recursive pass meets an unbounded depth;
//! lowering walks left-nested operator chains (a `sum` over 4096 indices) in a loop; [`expand`]
//! charges every node it produces to one budget per file ([`expand::MAX_EXPANDED_NODES`],
//! E0137); lowering stops at [`lower::MAX_LOWERED_VALUES`] IR values (E0139) and reports each
//! error once; `lower/scope.rs` bounds component instances by depth, count and total size
//! (E0135, E0136).
#![deny(missing_docs)]

pub mod ast;
pub mod diagnostics;
pub mod expand;
pub mod interp;
pub mod ir;
pub mod lexer;
pub mod lower;
pub mod parse;
pub mod print;
pub mod query;
pub mod share;
pub mod sim;
pub mod units;
pub mod verify;

use diagnostics::Diagnostic;

/// Parses and lowers a source file: the whole front end in one call.
///
/// Errors: every syntax, name and dimension error found, as diagnostics with spans (render
/// them with [`diagnostics::emit`]). On success, the warnings are in [`lower::Lowered`].
pub fn compile(source: &str, config: &lower::Config) -> Result<lower::Lowered, Vec<Diagnostic>> {
    let file = parse::parse(source).map_err(|d| vec![*d])?;
    lower::lower(&file, config)
}
pub mod cgen;
pub mod fixed;
pub mod thumb;
