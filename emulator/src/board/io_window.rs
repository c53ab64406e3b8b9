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
//! window, its accesses to the banks the DMA may reach (`L`, [`crate::bus::System::io_banks`]
//! at the start; of them its own) served as if no DMA were there, and logged: the
//! instruction's start cycle, the data phase, the SRAM offset, size, value and, for a
//! store, the word it overwrote ([`IoAccess`]). Native code does and logs single loads and
//! stores there (`jit::abi`'s `io_sram`, called before the access it then does as in any
//! of the core's banks); multiple transfers and exception frames take the general path,
//! whose bus (`board/window.rs`, `Confined`) logs the same, and no code is fetched from
//! `L`. A memoized call ([`crate::memo`]) recorded in such a window keeps its accesses to
//! `L` (cycles from its entry); a hit under the same `L` logs them at the hit's cycles,
//! each store with the word before the memo (the replay needs only the oldest version of a
//! word). A store to the DMA's or the PIOs' registers is logged instead of done (native
//! code's word stores through `jit::abi`'s `io_reg`; a load of them stops the core, as any
//! peripheral access). `tests/io_windows.rs` compares the logs of the two paths, window
//! by window ([`Board::check_io_logs`]).
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
//!
//! **The period memo.** A firmware's windows are its sample periods (a window ends at the
//! SysTick event), and once its keys rest the I/O does the same thing every period, in a
//! handful of states (the ring of results buffers, the PIO clock divider's phase at the tick, a
//! period of 3,015 or 3,016 cycles). So a kept replay is recorded, and a later one whose key
//! equals it takes its effect instead of running the I/O. The key: the I/O at the window's
//! start with its cycles moved to the memo's time base ([`Rebase`]; its parts' records left
//! out), compared whole — with the ADC codes and the DAC registers, so data is part of it;
//! the cores' logs with their cycles from the start, their register stores' values and, of
//! their SRAM accesses, the values only of stores to words the DMA reads (the replay checks
//! the loads and does the stores with the values of now); and each SRAM word the DMA read,
//! as it was before the replay. The effect: the DMA's SRAM writes and the cores' stores in
//! the recorded order, the loads checked there as the replay does (a stale one undoes the
//! window), the I/O's end state moved back to the window, and the frames and updates its
//! parts recorded. A replay that recorded a timing violation is not kept. Counts:
//! [`IoWindows::memo_hits`]; [`Board::set_io_memo`] turns it off.

use super::window::undo_stores;
use super::*;
use crate::bus::{load_le, sram_bank, store_le, ALL_BANKS};
use crate::io::{Checkpoint, Io, IoRecords, Rebase, SramOp};

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
    value: u32,
    /// A store's word before it (the word at `addr & !3`).
    pub(crate) old: u32,
    size: u8,
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
        }
    }
}

/// The period memo (module documentation): the replays recorded, newest last, at most
/// [`MEMO_ENTRIES`].
pub(crate) struct IoMemo {
    /// Whether replays are looked up and recorded.
    pub(crate) on: bool,
    entries: Vec<MemoEntry>,
    /// The entry the next recording replaces once the memo is full.
    next: usize,
    /// The buffer a recorded replay's trace ([`System::io_trace`]) is written into, kept
    /// with its capacity from one to the next.
    trace: Vec<SramOp>,
}

impl Default for IoMemo {
    fn default() -> Self {
        IoMemo {
            on: true,
            entries: Vec::new(),
            next: 0,
            trace: Vec::new(),
        }
    }
}

/// The most replays the period memo keeps per board (a board at rest has a handful of
/// keys; one whose keys move makes new ones, replacing the oldest).
const MEMO_ENTRIES: usize = 64;

/// One recorded replay: its key (the I/O at the window's start, the cores' logs, the
/// words the DMA read as they were before the window) and what it did.
struct MemoEntry {
    /// [`log_hash`] of `logs`.
    hash: u64,
    /// The logs as [`memo_logs`] keys them, the window's start at [`Rebase::MEMO`].
    logs: [Vec<IoAccess>; 2],
    /// The cores' stores to a word the DMA read (core, index in its log, value).
    valued: Vec<(usize, u32, u32)>,
    xip: bool,
    /// [`Io::data_hash`] of `start`.
    data: u64,
    /// The I/O at the window's start and after the replay, at the memo's time base.
    start: Box<Io>,
    end: Box<Io>,
    /// Each SRAM word the DMA read, with its value before the replay's first write.
    pre: Vec<(u32, u32)>,
    /// The replay's DMA writes and the logged accesses ([`SramOp::Entry`]) in order.
    ops: Vec<SramOp>,
    /// The parts' records of the replay.
    records: IoRecords,
}

/// The logs of a window as a memo's key: their cycles moved by `r`, the values of loads
/// and stores and the stores' old words left out (a replay checks the loads, does the
/// stores, and its entry keys the stores whose words the DMA reads: [`MemoEntry::valued`]).
fn memo_logs(logs: &[Vec<IoAccess>; 2], r: Rebase) -> [Vec<IoAccess>; 2] {
    logs.clone().map(|mut l| {
        for e in &mut l {
            e.start = r.at(e.start);
            e.cycle = r.at(e.cycle);
            e.old = 0;
            if e.kind != IoKind::Reg {
                e.value = 0;
            }
        }
        l
    })
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

/// Why a replay failed (module documentation).
enum Violation {
    Wait,
    Stale,
    Reach,
}

/// What [`Board::io_window_begin`] keeps for the end of the window.
pub(super) struct IoStart {
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

    /// Turns the period memo of the I/O's replays (module documentation) on or off; on by
    /// default. Results never depend on it: what it gives is the replay's.
    pub fn set_io_memo(&mut self, on: bool) {
        self.io_memo.on = on;
        if !on {
            self.io_memo.entries.clear();
        }
    }

    /// For tests: keeps a digest of every window's logs ([`Board::io_log_digest`]), and
    /// with `native` false has the cores' accesses to the DMA's banks and the I/O's
    /// registers take the general path instead of native code (`jit::abi`'s `io_sram`,
    /// `io_reg`), so that a test can compare the logs the two paths write. Results never
    /// depend on it.
    #[doc(hidden)]
    pub fn check_io_logs(&mut self, native: bool) {
        self.io_native = native;
        self.io_digest = Some(0);
    }

    /// The digest [`Board::check_io_logs`] keeps: FNV-1a over every access logged in a
    /// window, each window's logs in order; `None` unless asked for.
    #[doc(hidden)]
    pub fn io_log_digest(&self) -> Option<u64> {
        self.io_digest
    }

    /// At the start of a window from cycle `start`: on a board with an I/O, runs it up to
    /// `start`, keeps a clone and has the cores log their accesses to its DMA's banks;
    /// `None` without an I/O.
    pub(super) fn io_window_begin(&mut self, start: u64) -> Option<IoStart> {
        self.system.io.as_ref()?;
        self.system.io_advance_to(start, false);
        let banks = self.system.io_banks;
        // The cores' run does not touch the I/O: their accesses are logged instead.
        self.system.io_banks = 0;
        self.system.allowed_banks = self.system.fast_banks();
        self.io_window = Some(banks);
        for l in &mut self.io_logs {
            l.clear();
        }
        Some(IoStart { banks })
    }

    /// At the end of the cores' run of a window (`kept`: both reached its end): replays
    /// the I/O; true when the window is kept. When not, the I/O and the replay's SRAM
    /// writes are undone (the caller undoes the cores).
    pub(super) fn io_window_end(&mut self, start: IoStart, kept: bool) -> bool {
        self.io_window = None;
        self.system.io_banks = start.banks;
        self.system.allowed_banks = self.system.fast_banks();
        if let Some(d) = self.io_digest.as_mut() {
            *d = (*d ^ log_hash(&self.io_logs)).wrapping_mul(0x0000_0100_0000_01b3);
        }
        if !kept {
            return false;
        }
        let mut io = None;
        let r = self.io_replay(start.banks, &mut io);
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
                if let (Some(now), Some(then)) = (self.system.io.as_mut(), io) {
                    now.rewind(then);
                }
                self.system.io_banks = start.banks;
                self.system.allowed_banks = self.system.fast_banks();
            }
        }
        self.io_journal = journal;
        ok
    }

    /// The replay (module documentation), its SRAM writes journaled in
    /// [`System::io_journal`]; `io` becomes the I/O's checkpoint at the window's start
    /// when the I/O is run (not on a hit of the period memo, which changes the I/O only
    /// once it is kept; a recording takes it: the replay is then kept). The I/O is as the
    /// window's start left it: the cores' run does not touch it.
    fn io_replay(&mut self, banks: u8, io: &mut Option<Checkpoint>) -> Result<(), Violation> {
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
        let memo = self.io_memo.on && self.system.io.as_ref().is_some_and(|io| !io.stepwise);
        let r = match memo {
            true => self.io_memo_replay(&logs, banks, own, io),
            false => {
                *io = self.system.io.as_mut().map(|now| now.checkpoint());
                self.io_merge(&logs, banks, own)
            }
        };
        self.io_logs = logs;
        r
    }

    /// The replay through the period memo (module documentation): a hit does what the
    /// recorded replay did; a miss checkpoints the I/O into `io`, replays and records
    /// (when the replay is kept, taking the checkpoint).
    fn io_memo_replay(
        &mut self,
        logs: &[Vec<IoAccess>; 2],
        banks: u8,
        own: u8,
        io: &mut Option<Checkpoint>,
    ) -> Result<(), Violation> {
        let Some(now) = self.system.io.as_mut() else {
            return self.io_merge(logs, banks, own);
        };
        let base = now.cycle();
        let to_memo = Rebase {
            from: base,
            to: Rebase::MEMO,
        };
        let key = memo_logs(logs, to_memo);
        let hash = log_hash(&key);
        let xip = self.system.xip_answers;
        let data = now.data_hash();
        // The entries the key's parts that need no I/O at the memo's time base allow: a
        // busy board's codes differ from every entry's (most misses end here).
        let matches = |e: &MemoEntry| {
            e.hash == hash
                && e.xip == xip
                && e.data == data
                && e.logs == key
                && (e.valued.iter()).all(|&(k, i, v)| logs[k][i as usize].value == v)
        };
        let mut hit = None;
        if self.io_memo.entries.iter().any(matches) {
            // The I/O itself at the memo's time base while it is compared (its records
            // aside).
            now.rebase(to_memo);
            let records = now.take_records();
            let sys = &self.system;
            let live = sys.io.as_deref();
            hit = self.io_memo.entries.iter().position(|e| {
                matches(e)
                    && live.is_some_and(|l| *e.start == *l)
                    && (e.pre.iter()).all(|&(w, v)| load_le(&sys.sram, w as usize, 4) == v)
            });
            if let Some(now) = self.system.io.as_mut() {
                now.put_records(records);
                if hit.is_none() {
                    now.rebase(to_memo.back());
                }
            }
        }
        if let Some(i) = hit {
            let e = &self.io_memo.entries[i];
            let mut merged = Merged::new(logs);
            for op in &e.ops {
                match *op {
                    SramOp::Dma { off, size, value } => {
                        self.system.io_dma_write(off, u32::from(size), value)
                    }
                    SramOp::Entry => {
                        let Some(a) = merged.next() else {
                            continue;
                        };
                        match a.kind {
                            IoKind::Store => sram_put(&mut self.system, a.addr, a.size, a.value),
                            IoKind::Load => {
                                let now =
                                    load_le(&self.system.sram, a.addr as usize, a.size.into());
                                if now != a.value {
                                    if let Some(io) = self.system.io.as_mut() {
                                        io.rebase(to_memo.back());
                                    }
                                    return Err(Violation::Stale);
                                }
                            }
                            IoKind::Reg => {}
                        }
                    }
                    SramOp::Read { .. } => {}
                }
            }
            if let Some(now) = self.system.io.as_mut() {
                now.become_rebased(&e.end, to_memo.back(), &e.records);
            }
            self.system.io_refresh();
            self.io_windows.memo_hits += 1;
            return Ok(());
        }
        *io = self.system.io.as_mut().map(|now| now.checkpoint());
        let restored = self.system.io_journal.as_ref().map_or(0, Vec::len);
        let counts = self.system.io.as_mut().map(|io| io.record_counts());
        let mut trace = std::mem::take(&mut self.io_memo.trace);
        trace.clear();
        self.system.io_trace = Some(trace);
        let r = self.io_merge(logs, banks, own);
        let trace = self.system.io_trace.take().unwrap_or_default();
        let records = match (&r, counts, self.system.io.as_mut()) {
            (Ok(()), Some(counts), Some(now)) => now.records_since(&counts, to_memo),
            _ => None,
        };
        let (Some(records), Some(now)) = (records, self.system.io.as_mut()) else {
            self.io_memo.trace = trace;
            return r;
        };
        let end = now.rebased(to_memo);
        // Each word the DMA read, as it was before the replay's first write of it.
        let journal = self.system.io_journal.as_deref().unwrap_or_default();
        let reads = trace
            .iter()
            .filter(|op| matches!(op, SramOp::Read { .. }))
            .count();
        let mut pre: Vec<(u32, u32)> = Vec::with_capacity(reads);
        for op in &trace {
            if let SramOp::Read { word } = *op {
                if pre.iter().any(|&(w, _)| w == word) {
                    continue;
                }
                let first = journal[restored.min(journal.len())..]
                    .iter()
                    .find(|&&j| (j >> 32) as u32 == word)
                    .map(|&j| j as u32);
                let v = first.unwrap_or_else(|| load_le(&self.system.sram, word as usize, 4));
                pre.push((word, v));
            }
        }
        // The cores' stores to a word the DMA read: their values are part of the key.
        let valued = (0..2)
            .flat_map(|k| logs[k].iter().enumerate().map(move |(i, a)| (k, i, a)))
            .filter(|(_, _, a)| {
                a.kind == IoKind::Store && pre.iter().any(|&(w, _)| w == a.addr & !3)
            })
            .map(|(k, i, a)| (k, i as u32, a.value))
            .collect();
        let ops = (trace.iter())
            .filter(|op| !matches!(op, SramOp::Read { .. }))
            .copied()
            .collect();
        self.io_memo.trace = trace;
        let Some(mut start) = io.take() else {
            return r;
        };
        start.io.rebase(to_memo);
        let entry = MemoEntry {
            hash,
            logs: key,
            valued,
            xip,
            data: start.io.data_hash(),
            start: start.io,
            end,
            pre,
            ops,
            records,
        };
        let m = &mut self.io_memo;
        if m.entries.len() < MEMO_ENTRIES {
            m.entries.push(entry);
        } else {
            m.entries[m.next] = entry;
            m.next = (m.next + 1) % MEMO_ENTRIES;
        }
        self.io_windows.memo_recorded += 1;
        r
    }

    /// Does the logged accesses of `logs` in the lock-step order.
    fn io_merge(&mut self, logs: &[Vec<IoAccess>; 2], banks: u8, own: u8) -> Result<(), Violation> {
        for e in Merged::new(logs) {
            let sys = &mut self.system;
            match e.kind {
                IoKind::Load | IoKind::Store => {
                    let b = sram_bank(e.addr);
                    if sys.io_banks >> b & 1 != 0 && sys.io_claims(b, e.cycle) {
                        return Err(Violation::Wait);
                    }
                    if let Some(t) = sys.io_trace.as_mut() {
                        t.push(SramOp::Entry);
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
                    if let Some(t) = sys.io_trace.as_mut() {
                        t.push(SramOp::Entry);
                    }
                }
            }
        }
        Ok(())
    }
}

/// The two cores' logs in the lock-step order: the instruction that starts first, core 0
/// on ties, each core's accesses in their order.
struct Merged<'l> {
    logs: &'l [Vec<IoAccess>; 2],
    at: [usize; 2],
}

impl<'l> Merged<'l> {
    fn new(logs: &'l [Vec<IoAccess>; 2]) -> Self {
        Merged { logs, at: [0, 0] }
    }
}

impl<'l> Iterator for Merged<'l> {
    type Item = &'l IoAccess;
    fn next(&mut self) -> Option<&'l IoAccess> {
        let k = match (self.logs[0].get(self.at[0]), self.logs[1].get(self.at[1])) {
            (Some(a), Some(b)) if a.start <= b.start => 0,
            (_, Some(_)) => 1,
            (Some(_), None) => 0,
            (None, None) => return None,
        };
        self.at[k] += 1;
        self.logs[k].get(self.at[k] - 1)
    }
}
