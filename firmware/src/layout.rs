//! The in-memory interface every compiled per-key update implements, whatever produced it
//! (the C backend through a C compiler, or the Thumb backend):
//!
//! ```c
//! struct tactus_<stem>_state {
//!     uint8_t modes[max(nm,1)];
//!     uint8_t edges[max(ne,1)];
//!     uint8_t pad_[…];              // to a word boundary, when needed
//!     uint8_t hist_pos[max(nh,1)];
//!     int32_t states[max(ns,1)];
//!     int32_t params[npar];        // only with run-time params
//!     int32_t hist[max(nh,1)][34];  // a ring of 17 readings, kept twice
//!     int32_t published[np];
//! };
//! void tactus_<stem>_init(struct tactus_<stem>_state *s);
//! void tactus_<stem>_update(struct tactus_<stem>_state *s, const int32_t *sensors, int32_t *out);
//! ```
//!
//! The byte offsets of that struct are [`StateLayout`], defined once in the compiler's ABI
//! (`tactus_compiler::abi::StateLayout`, re-exported here; the test
//! `state_layout_matches_the_compilers` checks it against clang's and gcc's `offsetof`);
//! [`Interface`] adds what a caller needs beyond it: the function names and the numbers of
//! sensor words, out words, states and modes.

use tactus_compiler::abi::OutLayout;
pub use tactus_compiler::abi::StateLayout;
use tactus_compiler::fixed::FixedProgram;

/// What a caller of `tactus_<stem>_init`/`_update` must know: the C identifier stem, how
/// many sensor words to pass, how many out words the update writes, and the state struct.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Interface {
    /// The identifier stem: the functions are `tactus_<stem>_init` and `tactus_<stem>_update`.
    pub stem: String,
    /// Raw sensor words read by the update (one per sensor, in declaration order).
    pub sensors: usize,
    /// Words written to `out` (`OutLayout::len`).
    pub out_len: usize,
    /// States of the program (`ns`): `int32_t` words at [`StateLayout::states`].
    pub states: usize,
    /// Modes of the program (`nm`): `uint8_t` variant indices at [`StateLayout::modes`].
    pub modes: usize,
    /// The state struct's byte offsets and size.
    pub state: StateLayout,
    /// The key's param block, written at [`StateLayout::params`] before every `init`
    /// (empty for a program without run-time params; `FixedProgram::param_block`).
    pub params: Vec<i32>,
}

impl Interface {
    /// The interface of a fixed-point program whose `out` array has layout `out` and whose
    /// identifier stem is `stem` (both as `tactus_compiler::abi::Interface` gives them).
    pub fn new(fp: &FixedProgram, stem: &str, out: &OutLayout) -> Self {
        let p = &fp.program;
        Interface {
            stem: stem.to_string(),
            sensors: p.sensors.len(),
            out_len: out.len,
            states: p.states.len(),
            modes: p.modes.len(),
            state: StateLayout::new(p),
            params: fp.nominal_param_block(),
        }
    }

    /// `tactus_<stem>_init`.
    pub fn init_symbol(&self) -> String {
        tactus_compiler::abi::init_symbol(&self.stem)
    }

    /// `tactus_<stem>_update`.
    pub fn update_symbol(&self) -> String {
        tactus_compiler::abi::update_symbol(&self.stem)
    }
}
