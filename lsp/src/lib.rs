//! `tactus lsp`: a Language Server Protocol server for `.tactus` touch profiles.
//!
//! The server is synchronous (rust-analyzer's `lsp-server` message types, `lsp-types` for
//! the protocol's structures) and small: one thread reads frames ([`transport`]), the main
//! loop answers them, and one worker thread computes format plans, which can take seconds
//! for a profile the plan cache has not seen. Everything it says comes from the compiler:
//! diagnostics are the ones `tactus check` prints (codes, messages, labels, hints), names
//! are resolved by the compiler's resolver and facts read from its format plan and
//! precision report (`tactus_compiler::query`). Nothing is parsed or checked twice.
//!
//! Capabilities: diagnostics on open and change; hover (unit, declared and inferred range,
//! Q-format and error bound where the profile compiles); go to definition and find
//! references (sensors, params, states, modes, components and their instances, lets,
//! forces, outputs, inputs); completion (names in scope, an instance's members after `.`,
//! units after a number or `:`, the built-in functions); document symbols (the outline).
//!
//! Imports are followed ([`files`]): an imported file is read from the open documents, then
//! through the host's loader; a definition or reference in an imported file, and a
//! diagnostic's place there, are given at that file's URI (a library file's copy in the
//! cache directory); a diagnostic inside an imported file is also shown at the import that
//! brings it, and a document is analysed again when a file it imports changes.
#![deny(missing_docs)]

mod docs;
mod features;
pub mod files;
mod plan;
pub mod position;
mod server;
pub mod transport;

pub use server::{serve, Config, Outcome};
