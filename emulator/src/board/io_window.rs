//! Windows on a board with converters (`crate::io`): the cores run ahead of the I/O, and
//! the I/O then replays the window against what they did.
//!
//! **When.** Only while the DMA wins every SRAM bank against both cores (BUS_PRIORITY,
//! [`crate::io::Io::dma_wins`]): its accesses then never wait for a core's, so what it
//! does depends on the cores only through the SRAM words it reads and the registers they
//! write. The I/O raises no interrupt line (its interrupts are not modelled), so a core
//! sees the I/O only through those words.
//!
//! **The cores' run.** At the window's start the I/O is run up to it (as a core's access
//! there would) and kept ([`crate::io::Io::checkpoint`]). Each core then runs alone as in any window, its
//! accesses to the banks the DMA may reach (`L`, [`crate::bus::System::io_banks`] at the
//! start) taking the general path — not compiled code or fetches — served as if no DMA
//! were there, and logged: the instruction's start cycle, the data phase, the SRAM offset,
//! size, value and, for a store, the word it overwrote ([`IoAccess`]). A memoized call
//! ([`crate::memo`]) recorded in such a window keeps its accesses to `L` (cycles from its
//! entry); a hit under the same `L` logs them at the hit's cycles, each store with the word
//! before the memo (the replay needs only the oldest version of a word). A store to
//! the DMA's or the PIOs' registers is logged instead of done (a load of them stops the
//! core, as any peripheral access).
//!
//! **The replay.** The logged stores are taken back to the words as they were before the
//! window; the two logs are merged in the lock-step order (the instruction that starts
//! first, core 0 on ties: `board/run.rs`) and each entry done as the lock-step bus does it
//! ([`crate::bus::System`]'s `io_sram`, `io_store`): for a bank the DMA may reach now, the
//! I/O run through the access's cycle without settling; a store's bytes written at its
//! place among the DMA's; a register store through the same code as the bus. The window is
//! undone — the replay's SRAM writes (journaled, the DMA's too), the I/O's clone, then the
//! cores as in any window — when the lock-step run would have differed:
//! - the DMA claims the bank in the access's cycle (the core would have waited: *wait*);
//! - a load finds another value than the core loaded (the DMA wrote the word before the
//!   core read it: *stale*);
//! - a register store refused, or making the DMA reach a bank of either core's that was not
//!   logged (*reach*).
//!
//! Otherwise every load returned what the lock-step run returns, every store and register
//! write happened in the same order among the DMA's accesses with the same I/O calls, so
//! registers, memory, cycles, stalls and the I/O come out as the lock-step run's. A DMA read
//! of a word a core stores later in the window sees the old word (the DAC frames the
//! firmware's DMA moves at the tick, before the handler writes the next ones), one after
//! the store the new. The I/O is left where the last logged access left it, as in
//! lock-step. Counts: [`Board::io_windows`].

use super::window::undo_stores;
use super::*;
use crate::bus::{load_le, sram_bank, store_le, ALL_BANKS};
use crate::io::Checkpoint;

/// What a window's core access to the I/O is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum IoKind {
    /// A load from a bank the DMA may reach.
    Load,
    /// A store to a bank the DMA may reach.
    Store,
    /// A store to the DMA's or the PIOs' registers, not done yet.
    Reg,
}

/// One logged access (module documentation).
#[derive(Clone, Copy, Debug)]
pub(crate) struct IoAccess {
    /// The cycle at which the instruction (or exception entry) started: the lock-step order.
    pub(crate) start: u64,
    /// The data phase's cycle.
    pub(crate) cycle: u64,
    /// SRAM offset (loads, stores) or the register's address.
    pub(crate) addr: u32,
    /// The value loaded or stored (the bytes of `size`).
    value: u32,
    /// A store's word before it (the word at `addr & !3`).
    pub(crate) old: u32,
    size: u8,
    pub(crate) kind: IoKind,
}

/// The log a window's [`super::window`] bus writes for one core.
pub(super) struct IoLog<'a> {
    /// The banks the DMA may reach, `L`.
    pub banks: u8,
    /// The start cycle of the instruction being run.
    pub start: u64,
    pub log: &'a mut Vec<IoAccess>,
}

impl IoLog<'_> {
    /// Logs an access of the instruction being run; returns it.
    pub fn push(
        &mut self,
        cycle: u64,
        kind: IoKind,
        addr: u32,
        size: u32,
        value: u32,
        old: u32,
    ) -> IoAccess {
        let a = IoAccess {
            start: self.start,
            cycle,
            addr,
            value,
            old,
            size: size as u8,
            kind,
        };
        self.log.push(a);
        a
    }
}

/// What became of the windows of a board with an I/O ([`Board::io_windows`]); windows
/// undone because a core could not run confined are counted by
/// [`Board::run_ahead_windows`] only.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IoWindows {
    /// Replayed and kept.
    pub kept: u64,
    /// Undone: a core's access to a bank in a cycle the DMA claimed it.
    pub waited: u64,
    /// Undone: a core loaded a word the DMA wrote before the load.
    pub stale: u64,
    /// Undone: a register store refused, or one that let the DMA reach a bank whose
    /// accesses were not logged.
    pub reach: u64,
}

/// Why a replay failed (module documentation).
enum Violation {
    Wait,
    Stale,
    Reach,
}

/// What [`Board::io_window_begin`] keeps for the end of the window.
pub(super) struct IoStart {
    io: Checkpoint,
    banks: u8,
}

/// Stores the `size` low bytes of `value` at SRAM offset `off`, journaling the word into
/// [`System::io_journal`].
fn sram_put(sys: &mut System, off: u32, size: u8, value: u32) {
    let word = off & !3;
    let old = sys.sram_peek(word);
    if let Some(j) = sys.io_journal.as_mut() {
        j.push(u64::from(word) << 32 | u64::from(old));
    }
    store_le(&mut sys.sram, off as usize, u32::from(size), value);
}

impl Board {
    /// The windows of a board with an I/O so far (module documentation).
    pub fn io_windows(&self) -> IoWindows {
        self.io_windows
    }

    /// At the start of a window from cycle `start`: on a board with an I/O, runs it up to
    /// `start`, keeps a clone and has the cores log their accesses to its DMA's banks;
    /// `None` without an I/O.
    pub(super) fn io_window_begin(&mut self, start: u64) -> Option<IoStart> {
        self.system.io.as_ref()?;
        self.system.io_advance_to(start, false);
        let io = self.system.io.as_mut()?.checkpoint();
        let banks = self.system.io_banks;
        // The cores' run does not touch the I/O: their accesses are logged instead.
        self.system.io_banks = 0;
        self.system.allowed_banks = self.system.fast_banks();
        self.io_window = Some(banks);
        for l in &mut self.io_logs {
            l.clear();
        }
        Some(IoStart { io, banks })
    }

    /// At the end of the cores' run of a window (`kept`: both reached its end): replays
    /// the I/O; true when the window is kept. When not, the I/O and the replay's SRAM
    /// writes are undone (the caller undoes the cores).
    pub(super) fn io_window_end(&mut self, start: IoStart, kept: bool) -> bool {
        self.io_window = None;
        self.system.io_banks = start.banks;
        self.system.allowed_banks = self.system.fast_banks();
        if !kept {
            return false;
        }
        let r = self.io_replay(start.banks);
        let journal = self.system.io_journal.take().unwrap_or_default();
        let s = &mut self.io_windows;
        let ok = r.is_ok();
        match r {
            Ok(()) => s.kept += 1,
            Err(v) => {
                match v {
                    Violation::Wait => s.waited += 1,
                    Violation::Stale => s.stale += 1,
                    Violation::Reach => s.reach += 1,
                }
                undo_stores(&mut self.system, &journal);
                if let Some(io) = self.system.io.as_mut() {
                    io.rewind(start.io);
                }
                self.system.io_banks = start.banks;
                self.system.allowed_banks = self.system.fast_banks();
            }
        }
        self.io_journal = journal;
        ok
    }

    /// The replay (module documentation), its SRAM writes journaled in
    /// [`System::io_journal`].
    fn io_replay(&mut self, banks: u8) -> Result<(), Violation> {
        let mut journal = std::mem::take(&mut self.io_journal);
        journal.clear();
        self.system.io_journal = Some(journal);
        let logs = std::mem::take(&mut self.io_logs);
        // The stored words as they were before the window, newest store first.
        for log in &logs {
            for e in log.iter().rev().filter(|e| e.kind == IoKind::Store) {
                sram_put(&mut self.system, e.addr & !3, 4, e.old);
            }
        }
        let own = (self.config.own_banks[0] | self.config.own_banks[1]) & ALL_BANKS;
        let r = self.io_merge(&logs, banks, own);
        self.io_logs = logs;
        r
    }

    /// Does the logged accesses of `logs` in the lock-step order.
    fn io_merge(&mut self, logs: &[Vec<IoAccess>; 2], banks: u8, own: u8) -> Result<(), Violation> {
        let (mut i, mut j) = (0, 0);
        loop {
            let e = match (logs[0].get(i), logs[1].get(j)) {
                (Some(a), Some(b)) if a.start <= b.start => {
                    i += 1;
                    a
                }
                (_, Some(b)) => {
                    j += 1;
                    b
                }
                (Some(a), None) => {
                    i += 1;
                    a
                }
                (None, None) => return Ok(()),
            };
            let sys = &mut self.system;
            match e.kind {
                IoKind::Load | IoKind::Store => {
                    let b = sram_bank(e.addr);
                    if sys.io_banks >> b & 1 != 0 && sys.io_claims(b, e.cycle) {
                        return Err(Violation::Wait);
                    }
                    if e.kind == IoKind::Store {
                        sram_put(sys, e.addr, e.size, e.value);
                    } else if load_le(&sys.sram, e.addr as usize, u32::from(e.size)) != e.value {
                        return Err(Violation::Stale);
                    }
                }
                IoKind::Reg => {
                    if sys
                        .io_store(e.cycle, e.addr, u32::from(e.size), e.value)
                        .is_err()
                        || sys.io_banks & !banks & own != 0
                    {
                        return Err(Violation::Reach);
                    }
                }
            }
        }
    }
}
