//! What a debugger watches on a board — breakpoints on instruction addresses and
//! watchpoints on data, hardware and software alike (nothing is written into the program)
//! — and what it keeps on the board between its client's packets ([`DebugState`]). A leaf:
//! the board holds it, the debugger ([`crate::debug`]) fills it, and neither names the
//! other for it.

use crate::profile::Call;

/// What a debugger watches: breakpoints (on instruction addresses; any core) and
/// watchpoints (on data addresses). Hardware and software breakpoints are the same thing
/// here: nothing is written into the program.
#[derive(Clone, Debug, Default)]
pub struct Watches {
    /// Instruction addresses (Thumb bit clear).
    pub breakpoints: Vec<u32>,
    /// Data watchpoints.
    pub watchpoints: Vec<Watchpoint>,
}

/// Which accesses a watchpoint reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// Loads.
    Read,
    /// Stores.
    Write,
    /// Both.
    Any,
}

/// A data watchpoint: `len` bytes from `addr`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Watchpoint {
    /// First byte.
    pub addr: u32,
    /// Bytes (at least 1).
    pub len: u32,
    /// Which accesses.
    pub access: Access,
}

impl Watches {
    /// The watchpoint an access of `len` bytes at `addr` hits, if any.
    pub fn hit(&self, addr: u32, len: u32, access: Access) -> Option<&Watchpoint> {
        let end = addr as u64 + len as u64;
        self.watchpoints.iter().find(|w| {
            let w_end = w.addr as u64 + w.len.max(1) as u64;
            (addr as u64) < w_end
                && (w.addr as u64) < end
                && (w.access == Access::Any || w.access == access)
        })
    }
}

/// What a debugger keeps on the board between its client's packets ([`crate::debug::gdb`]): what it watches, what the client
/// asked the next resume to do, and what `monitor cycles` reports.
#[derive(Debug, Default)]
pub struct DebugState {
    /// Breakpoints and watchpoints.
    pub watches: Watches,
    /// The core the next resume single-steps, if any.
    pub step: Option<usize>,
    /// Per core: the profile handle of its sample interrupt, if the image names one.
    pub isr: [Option<usize>; 2],
    /// Per core: the last completed sample interrupt.
    pub last_isr: [Option<Call>; 2],
}
