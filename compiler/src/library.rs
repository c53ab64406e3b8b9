//! Tactus's standard library: the components instrument makers share (friction, contacts,
//! springs and stops, the pieces of keyboard actions, resonators), one `.tactus` file per
//! subject in `instruments/lib/`, each component headed by its physics, units, ranges and
//! sources.
//!
//! The files are built into the compiler, as a language's standard library ships with its
//! compiler: an import that finds no file next to the importing file is looked up here
//! ([`crate::imports`]), so a built-in instrument, a test, the command line and an editor
//! all see one library, and nothing reads it from disk at run time.

use std::sync::OnceLock;

/// The library's files: (file name as an import names it, text), from `instruments/lib/`.
pub const FILES: &[(&str, &str)] = &[
    (
        "action.tactus",
        include_str!("../../instruments/lib/action.tactus"),
    ),
    (
        "contact.tactus",
        include_str!("../../instruments/lib/contact.tactus"),
    ),
    (
        "friction.tactus",
        include_str!("../../instruments/lib/friction.tactus"),
    ),
    (
        "resonators.tactus",
        include_str!("../../instruments/lib/resonators.tactus"),
    ),
];

/// The text of library file `name` (`"friction.tactus"`), if there is one.
pub fn file(name: &str) -> Option<&'static str> {
    FILES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The name a diagnostic shows for library file `name`: `builtin:lib/NAME`.
pub fn display_name(name: &str) -> String {
    format!("builtin:lib/{name}")
}

/// Every component of the library, (component, file), in file order: the hint of an
/// unknown component names the import that brings it.
pub fn components() -> &'static [(String, &'static str)] {
    static LIST: OnceLock<Vec<(String, &'static str)>> = OnceLock::new();
    LIST.get_or_init(|| {
        let mut v = Vec::new();
        for (name, text) in FILES {
            // The library's files parse (tests/library.rs); one that did not would only
            // lose its hints.
            if let Ok(f) = crate::parse::parse(text) {
                for item in f.items {
                    if let crate::ast::TopItem::Component(b) = item {
                        v.push((b.name.node, *name));
                    }
                }
            }
        }
        v
    })
}
