//! The Tactus touch-profile language: lexer, parser, name and dimension checks, the IR, and
//! the f64 reference interpreter that defines what every engine must compute.
//!
//! Pipeline: [`parse::parse`] (logos + lalrpop) → [`ast::File`] → [`imports::link`] (the
//! files it imports, read through the host's [`imports::Loader`] or from [`library`], laid
//! out in one [`sources::SourceMap`]) → [`lower::lower`] (name
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
pub mod imports;
pub mod interp;
pub mod ir;
pub mod lexer;
pub mod library;
pub mod lower;
pub mod parse;
pub mod print;
pub mod query;
pub mod share;
pub mod sim;
pub mod sources;
pub mod units;
pub mod verify;

use diagnostics::Diagnostic;

/// Parses and lowers a source file that has no file of its own (its imports name files of
/// Tactus's [`library`]): the whole front end in one call.
///
/// Errors: every syntax, import, name and dimension error found, as diagnostics with spans
/// (render them with [`diagnostics::emit`]; one in a library file lies past the end of
/// `source`, and [`compile_linked`] with [`diagnostics::emit_files`] shows it). On success,
/// the warnings are in [`lower::Lowered`].
pub fn compile(source: &str, config: &lower::Config) -> Result<lower::Lowered, Vec<Diagnostic>> {
    let linked = imports::link(
        "source",
        sources::Origin::Text,
        source,
        &mut imports::NoFiles,
    );
    compile_linked(&linked, config)
}

/// Lowers a program [`imports::link`] read: the front end after the files are read.
///
/// Errors: those of linking (syntax errors of every file, imports) or, when it linked, of
/// lowering; a diagnostic in an imported file also points at the import that brings it
/// ([`imports::Linked::with_import_site`]). On success, the warnings of both are in
/// [`lower::Lowered`].
pub fn compile_linked(
    linked: &imports::Linked,
    config: &lower::Config,
) -> Result<lower::Lowered, Vec<Diagnostic>> {
    let Some(file) = &linked.file else {
        return Err(linked.diagnostics.clone());
    };
    let sited = |ds: Vec<Diagnostic>| linked.sited(ds);
    match lower::lower(file, config) {
        Ok(mut l) => {
            l.warnings = sited(std::mem::take(&mut l.warnings));
            Ok(l)
        }
        Err(d) => Err(sited(d)),
    }
}
pub mod abi;
pub mod cgen;
pub mod fixed;
pub mod thumb;
