//! C99 backend (being written): portable C with the fixed-point semantics of
//! `tactus_runtime::fixed`, bit-exact with the fixed interpreter.
