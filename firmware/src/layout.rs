//! The in-memory interface every compiled per-key update implements, whatever produced it
//! (the C backend through a C compiler, or the Thumb backend):
//!
//! ```c
//! struct tactus_<stem>_state {
//!     int32_t states[max(ns,1)];
//!     uint8_t modes[max(nm,1)];
//!     uint8_t edges[max(ne,1)];
//!     int32_t hist[max(nh,1)][17];
//!     uint8_t hist_pos[max(nh,1)];
//!     uint8_t hist_primed[max(nh,1)];
//!     int32_t published[np];
//! };
//! void tactus_<stem>_init(struct tactus_<stem>_state *s);
//! void tactus_<stem>_update(struct tactus_<stem>_state *s, const int32_t *sensors, int32_t *out);
//! ```
//!
//! [`StateLayout`] computes the byte offsets of that struct with the C layout rules of the
//! AAPCS (natural alignment: `int32_t` 4, `uint8_t` 1; the struct's alignment is its largest
//! member's, and its size is rounded up to it), exactly as `cgen` writes the header;
//! [`Interface`] adds the numbers of sensor and out words.

use tactus_compiler::cgen::OutLayout;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::ir::Program;
use tactus_runtime::differentiator::WINDOW;

/// Words in one sensor history ring (`2N + 1` with N = [`WINDOW`]): the `17` of `hist[][17]`.
pub const HIST_LEN: usize = 2 * WINDOW + 1;

/// The element counts that determine the state struct (before C99's "at least one element"
/// rule is applied).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StateCounts {
    /// States (`ns`): one `int32_t` each.
    pub states: usize,
    /// Modes (`nm`): one `uint8_t` each.
    pub modes: usize,
    /// Edge memories of `on` handlers (`ne`): one `uint8_t` each.
    pub edges: usize,
    /// Differentiated sensors (`nh`): a history ring, a position and a primed flag each.
    pub hist: usize,
    /// Published words (`np` = force terms + 1 total + outputs).
    pub published: usize,
}

impl StateCounts {
    /// The counts of a program: `nh` is the number of sensors marked `differentiated`
    /// (used by `d()`/`d2()`), `np` is forces + 1 + outputs.
    pub fn of(p: &Program) -> Self {
        StateCounts {
            states: p.states.len(),
            modes: p.modes.len(),
            edges: p.edges.len(),
            hist: p.sensors.iter().filter(|s| s.differentiated).count(),
            published: p.forces.len() + 1 + p.outputs.len(),
        }
    }
}

/// Byte offsets of the members of `struct tactus_<stem>_state`, its size and alignment.
///
/// All offsets and sizes are in bytes from the start of the struct.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StateLayout {
    /// The counts it was computed from.
    pub counts: StateCounts,
    /// `int32_t states[max(ns,1)]`: state `i` is the word at `states + 4 i`.
    pub states: usize,
    /// `uint8_t modes[max(nm,1)]`: mode `i` is the byte at `modes + i`.
    pub modes: usize,
    /// `uint8_t edges[max(ne,1)]`.
    pub edges: usize,
    /// `int32_t hist[max(nh,1)][17]` (4-aligned).
    pub hist: usize,
    /// `uint8_t hist_pos[max(nh,1)]`.
    pub hist_pos: usize,
    /// `uint8_t hist_primed[max(nh,1)]`.
    pub hist_primed: usize,
    /// `int32_t published[np]` (4-aligned).
    pub published: usize,
    /// `sizeof(struct tactus_<stem>_state)`: the end of `published`, rounded up to `align`.
    pub size: usize,
    /// `_Alignof(struct tactus_<stem>_state)`: 4 (it holds `int32_t`s).
    pub align: usize,
}

impl StateLayout {
    /// The layout for these counts (C99: an array has at least one element; the AAPCS's
    /// natural alignment).
    pub fn new(counts: StateCounts) -> Self {
        fn up(x: usize, a: usize) -> usize {
            x.div_ceil(a) * a
        }
        let one = |n: usize| n.max(1);
        let states = 0;
        let modes = states + 4 * one(counts.states);
        let edges = modes + one(counts.modes);
        let hist = up(edges + one(counts.edges), 4);
        let hist_pos = hist + 4 * HIST_LEN * one(counts.hist);
        let hist_primed = hist_pos + one(counts.hist);
        let published = up(hist_primed + one(counts.hist), 4);
        let align = 4;
        let size = up(published + 4 * counts.published, align);
        StateLayout {
            counts,
            states,
            modes,
            edges,
            hist,
            hist_pos,
            hist_primed,
            published,
            size,
            align,
        }
    }

    /// The layout for a program's state struct.
    pub fn of(p: &Program) -> Self {
        Self::new(StateCounts::of(p))
    }
}

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
    /// The state struct.
    pub state: StateLayout,
}

impl Interface {
    /// The interface of a fixed-point program whose `out` array has layout `out` and whose
    /// identifier stem is `stem` (both as `cgen::emit_c` reports them).
    pub fn new(fp: &FixedProgram, stem: &str, out: &OutLayout) -> Self {
        Interface {
            stem: stem.to_string(),
            sensors: fp.program.sensors.len(),
            out_len: out.len,
            state: StateLayout::of(&fp.program),
        }
    }

    /// `tactus_<stem>_init`.
    pub fn init_symbol(&self) -> String {
        format!("tactus_{}_init", self.stem)
    }

    /// `tactus_<stem>_update`.
    pub fn update_symbol(&self) -> String {
        format!("tactus_{}_update", self.stem)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_arrays_get_one_element_and_words_are_aligned() {
        let l = StateLayout::new(StateCounts {
            states: 0,
            modes: 0,
            edges: 0,
            hist: 0,
            published: 1,
        });
        assert_eq!(
            (
                l.modes,
                l.edges,
                l.hist,
                l.hist_pos,
                l.hist_primed,
                l.published,
                l.size
            ),
            (4, 5, 8, 8 + 68, 8 + 69, 8 + 72, 8 + 72 + 4)
        );
        let l = StateLayout::new(StateCounts {
            states: 3,
            modes: 2,
            edges: 5,
            hist: 2,
            published: 4,
        });
        // 12 | 12..14 | 14..19 → pad to 20 | 20..156 | 156,157 | 158,159 | 160..176
        assert_eq!(
            (
                l.modes,
                l.edges,
                l.hist,
                l.hist_pos,
                l.hist_primed,
                l.published,
                l.size
            ),
            (12, 14, 20, 156, 158, 160, 176)
        );
    }
}
