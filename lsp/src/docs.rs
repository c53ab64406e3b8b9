//! The open documents the server keeps, by URI: each one's text, lines, the compiler's
//! analysis of it and the fixed-point plan of its version ([`PlanState`]). The server
//! ([`crate::server`]) updates them; the features ([`crate::features`]) answer from them.

use crate::plan::Planned;
use crate::position::LineIndex;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;
use tactus_compiler::query::{self, Analysis};

/// The open documents by URI (as the client wrote it).
pub type Docs = HashMap<String, Doc>;

/// The plan of a document's current version.
pub enum PlanState {
    /// The version does not compile (or plans are off).
    None,
    /// Being computed, as this generation.
    Pending(u64),
    /// Done.
    Ready(Arc<Planned>),
    /// The planner failed.
    Failed(String),
}

/// An open document.
pub struct Doc {
    /// Its URI as the client wrote it.
    pub uri: lsp_types::Uri,
    /// The file its URI names (a `file://` URI), where its imports are looked for.
    pub path: Option<PathBuf>,
    /// The version the client last gave.
    pub version: i32,
    /// The text.
    pub text: String,
    /// Its lines.
    pub lines: LineIndex,
    /// The compiler's answer for this text.
    pub analysis: Analysis,
    /// The outline of the last version that parsed (completion while the text does not).
    pub last_outline: Vec<query::Symbol>,
    /// The plan of this version.
    pub plan: PlanState,
}
