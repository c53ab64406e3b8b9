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
//! there would); the cores' run leaves it there, and the replay checkpoints it
//! ([`crate::io::Io::checkpoint`]) before it runs it. Each core then runs alone as in any
//! window, its accesses to the banks the DMA may reach (`L`, [`crate::system::System::io_banks`]
//! at the start; of them its own) served as if no DMA were there, and logged: the
//! instruction's start cycle, the data phase, the SRAM offset, size, value and, for a
//! store, the word it overwrote ([`IoAccess`]). Native code does and logs single loads and
//! stores there (`jit::abi`'s `io_sram`, called before the access it then does as in any
//! of the core's banks); multiple transfers and exception frames take the general path,
//! whose bus (`accel/window.rs`, `Confined`) logs the same, and no code is fetched from
//! `L`. A memoized call ([`crate::accel::memo`]) recorded in such a window keeps its accesses to
//! `L` (cycles from its entry); a hit under the same `L` logs them at the hit's cycles,
//! each store with the word before the memo (the replay needs only the oldest version of a
//! word). A store to the DMA's or the PIOs' registers is logged instead of done (native
//! code's word stores through `jit::abi`'s `io_reg`; a load of them stops the core, as any
//! peripheral access). `tests/io_windows.rs` compares the logs of the two paths, window
//! by window ([`Board::check_io_logs`]).
//!
//!
//! **Modules, by job.** This one: the cores' access log ([`IoAccess`], [`IoLog`]) and a
//! window's start and end; `replay.rs`: the replay in the merged lock-step order;
//! `memo.rs`: the period memo, its entries and hits; `record.rs`: a replay recorded with
//! lanes for it; `plan.rs`: the plans a hit takes instead of the merged order.

use super::*;
use crate::bus::{load_le, sram_bank, store_le, ALL_BANKS};
use crate::io::slots::{
    Checkpoint, EndState, IoRecords, LaneOp, LaneRec, LazyEnd, RecordCodes, Slot,
};
use crate::io::Io;
use crate::lanes::{self, Lane, Route};
use crate::replay::Rebase;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

mod memo;
mod plan;
mod record;
mod replay;

pub(crate) use memo::IoMemo;
use memo::{
    at_cycle, data_inputs, MemoEntry, MemoOp, MemoOpKind, Probe, Tried, SHARED, SHARED_ENTRIES,
};
use plan::{reg_stores, Plans};
use record::Violation;
use replay::{sram_put, Order, Step};

/// What [`Board::io_window_begin`] keeps for the end of the window.
pub(crate) struct IoStart {
    pub(super) banks: u8,
    /// The window's end (the cores run to it).
    pub(super) end: u64,
}

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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct IoAccess {
    /// The cycle at which the instruction (or exception entry) started: the lock-step order.
    pub(crate) start: u64,
    /// The data phase's cycle.
    pub(crate) cycle: u64,
    /// SRAM offset (loads, stores) or the register's address.
    pub(crate) addr: u32,
    /// The value loaded or stored (the bytes of `size`).
    pub(super) value: u32,
    /// A store's word before it (the word at `addr & !3`).
    pub(crate) old: u32,
    pub(super) size: u8,
    pub(crate) kind: IoKind,
}

impl IoAccess {
    /// The access of the instruction (or exception entry) that started at cycle `start`,
    /// its data phase at `cycle`: `size` bytes (1, 2 or 4) at SRAM offset or register
    /// address `addr`, `value` loaded or stored, `old` a store's word before it (else 0).
    pub(crate) fn new(
        start: u64,
        cycle: u64,
        kind: IoKind,
        addr: u32,
        size: u32,
        value: u32,
        old: u32,
    ) -> IoAccess {
        IoAccess {
            start,
            cycle,
            addr,
            value,
            old,
            size: size as u8,
            kind,
        }
    }

    /// The access with its cycles counted from `base` (a memo's time base).
    pub(crate) fn since(&self, base: u64) -> IoAccess {
        IoAccess {
            start: self.start.wrapping_sub(base),
            cycle: self.cycle.wrapping_sub(base),
            ..*self
        }
    }
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
        let a = IoAccess::new(self.start, cycle, kind, addr, size, value, old);
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
    /// Of the kept, those whose replay the period memo gave.
    pub memo_hits: u64,
    /// Replays recorded into the period memo.
    pub memo_recorded: u64,
    /// Replays the period memo took from the process's store, recorded by another board
    /// (module documentation).
    pub memo_shared: u64,
    /// Of the memo's hits, those a plan gave (module documentation, "Plans").
    pub memo_planned: u64,
}

impl std::ops::Add for IoWindows {
    type Output = IoWindows;

    /// Both counts together (a keyboard's boards summed).
    fn add(self, o: IoWindows) -> IoWindows {
        IoWindows {
            kept: self.kept + o.kept,
            waited: self.waited + o.waited,
            stale: self.stale + o.stale,
            reach: self.reach + o.reach,
            memo_hits: self.memo_hits + o.memo_hits,
            memo_recorded: self.memo_recorded + o.memo_recorded,
            memo_shared: self.memo_shared + o.memo_shared,
            memo_planned: self.memo_planned + o.memo_planned,
        }
    }
}

/// A hash of logs (FNV-1a over their fields).
fn log_hash(logs: &[Vec<IoAccess>; 2]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut mix = |v: u64| h = (h ^ v).wrapping_mul(0x0000_0100_0000_01b3);
    for l in logs {
        for e in l {
            mix(e.start);
            mix(e.cycle);
            mix(u64::from(e.addr) << 32 | u64::from(e.value));
            mix(u64::from(e.old) << 16 | u64::from(e.size) << 8 | e.kind as u64);
        }
        mix(u64::MAX);
    }
    h
}

impl Drive<'_> {
    /// At the start of a window from cycle `start`: on a board with an I/O, runs it up to
    /// `start`, keeps a clone and has the cores log their accesses to its DMA's banks;
    /// `None` without an I/O.
    pub(super) fn io_window_begin(&mut self, start: u64, end: u64) -> Option<IoStart> {
        self.m.system.io.as_ref()?;
        self.m.system.io_advance_to(start, false);
        let banks = self.m.system.io_banks;
        // The cores' run does not touch the I/O: their accesses are logged instead.
        self.m.system.io_banks = 0;
        self.m.system.allowed_banks = self.m.system.fast_banks();
        self.a.io_window = Some(banks);
        for l in &mut self.a.io_logs {
            l.clear();
        }
        Some(IoStart { banks, end })
    }

    /// At the end of the cores' run of a window (`kept`: both reached its end): replays
    /// the I/O; true when the window is kept. When not, the I/O and the replay's SRAM
    /// writes are undone (the caller undoes the cores).
    pub(super) fn io_window_end(&mut self, start: IoStart, kept: bool) -> bool {
        self.a.io_window = None;
        self.m.system.io_banks = start.banks;
        self.m.system.allowed_banks = self.m.system.fast_banks();
        if let Some(d) = self.a.io_digest.as_mut() {
            *d = (*d ^ log_hash(&self.a.io_logs)).wrapping_mul(0x0000_0100_0000_01b3);
        }
        if !kept {
            return false;
        }
        let mut io = None;
        let r = self.io_replay(start.banks, start.end, &mut io);
        let journal = self.m.system.io_journal.take().unwrap_or_default();
        let s = &mut self.a.io_windows;
        let ok = r.is_ok();
        match r {
            Ok(()) => s.kept += 1,
            Err(v) => {
                match v {
                    Violation::Wait => s.waited += 1,
                    Violation::Stale => s.stale += 1,
                    Violation::Reach => s.reach += 1,
                }
                self.m.system.undo_stores(&journal);
                if let (Some(now), Some(then)) = (self.m.system.io.as_mut(), io) {
                    now.rewind(then);
                }
                self.m.system.io_banks = start.banks;
                self.m.system.allowed_banks = self.m.system.fast_banks();
            }
        }
        self.a.io_journal = journal;
        ok
    }
}

impl Accel {
    /// [`crate::Board::io_windows`].
    pub(crate) fn io_windows(&self) -> IoWindows {
        self.io_windows
    }

    /// [`crate::Board::set_io_memo`].
    pub(crate) fn set_io_memo(&mut self, on: bool) {
        self.io_memo = IoMemo {
            on,
            ..IoMemo::default()
        };
    }

    /// [`crate::Board::set_io_lazy`].
    pub(crate) fn set_io_lazy(&mut self, on: bool) {
        self.io_memo.lazy = on;
    }

    /// [`crate::Board::set_io_plans`].
    pub(crate) fn set_io_plans(&mut self, on: bool) {
        self.io_memo.planned = on;
    }

    /// [`crate::Board::check_io_logs`].
    pub(crate) fn check_io_logs(&mut self, native: bool) {
        self.io_native = native;
        self.io_digest = Some(0);
    }

    /// [`crate::Board::io_log_digest`].
    pub(crate) fn io_log_digest(&self) -> Option<u64> {
        self.io_digest
    }
}
