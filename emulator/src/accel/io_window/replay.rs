//! **The replay.** The logged stores are taken back to the words as they were before the
//! window; the two logs are merged in the lock-step order (the instruction that starts
//! first, core 0 on ties: `board/run.rs`) and each entry done as the lock-step bus does it
//! ([`crate::system::System`]'s `io_sram`, `io_store`): for a bank the DMA may reach now, the
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

use super::*;

impl Drive<'_> {
    /// The replay (module documentation), its SRAM writes journaled in
    /// [`System::io_journal`]; `io` becomes the I/O's checkpoint at the window's start
    /// when the I/O is run (not on a hit of the period memo, which changes the I/O only
    /// once it is kept; a recording takes it: the replay is then kept). The I/O is as the
    /// window's start left it: the cores' run does not touch it.
    pub(super) fn io_replay(
        &mut self,
        banks: u8,
        end: u64,
        io: &mut Option<Checkpoint>,
    ) -> Result<(), Violation> {
        let mut journal = std::mem::take(&mut self.a.io_journal);
        journal.clear();
        self.m.system.io_journal = Some(journal);
        let logs = std::mem::take(&mut self.a.io_logs);
        let own = (self.cfg.own_banks[0] | self.cfg.own_banks[1]) & ALL_BANKS;
        let memo = self.a.io_memo.on && self.m.system.io.as_ref().is_some_and(|io| !io.stepwise);
        let r = match memo {
            true => self.io_memo_replay(&logs, banks, own, end, io),
            false => {
                self.io_take_back(&logs);
                self.m.system.io_unlazy();
                *io = self.m.system.io.as_mut().map(|now| now.checkpoint());
                self.io_merge(&logs, banks, own)
            }
        };
        self.a.io_logs = logs;
        r
    }

    /// The words the cores' logged stores overwrote put back, newest store first: the
    /// SRAM as it was before the window (journaled), for the replay to do the stores in
    /// their places among the DMA's accesses. (A planned hit does without: module
    /// documentation, "Plans".)
    pub(super) fn io_take_back(&mut self, logs: &[Vec<IoAccess>; 2]) {
        for log in logs {
            for e in log.iter().rev().filter(|e| e.kind == IoKind::Store) {
                sram_put(&mut self.m.system, e.addr & !3, 4, e.old);
            }
        }
    }

    /// Does the logged accesses of `logs` in the lock-step order.
    pub(super) fn io_merge(
        &mut self,
        logs: &[Vec<IoAccess>; 2],
        banks: u8,
        own: u8,
    ) -> Result<(), Violation> {
        for e in Merged::new(logs) {
            let sys = &mut self.m.system;
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
        Ok(())
    }
}

/// The two cores' logs in the lock-step order: the instruction that starts first, core 0
/// on ties, each core's accesses in their order.
pub(super) struct Merged<'l> {
    pub(super) logs: &'l [Vec<IoAccess>; 2],
    pub(super) at: [usize; 2],
}

impl<'l> Merged<'l> {
    pub(super) fn new(logs: &'l [Vec<IoAccess>; 2]) -> Self {
        Merged { logs, at: [0, 0] }
    }

    /// The next access's core and index in its log.
    #[inline]
    pub(super) fn next_index(&mut self) -> Option<(usize, usize)> {
        let k = match (self.logs[0].get(self.at[0]), self.logs[1].get(self.at[1])) {
            (Some(a), Some(b)) if a.start <= b.start => 0,
            (_, Some(_)) => 1,
            (Some(_), None) => 0,
            (None, None) => return None,
        };
        self.at[k] += 1;
        Some((k, self.at[k] - 1))
    }
}

impl<'l> Iterator for Merged<'l> {
    type Item = &'l IoAccess;
    fn next(&mut self) -> Option<&'l IoAccess> {
        let (k, i) = self.next_index()?;
        self.logs[k].get(i)
    }
}

/// One step of a period memo hit ([`Order`]): the entry's DMA access (op index), or a
/// core's logged SRAM access (core, index in its log).
#[derive(Clone, Copy)]
pub(super) enum Step {
    Dma(usize),
    Core(usize, usize),
}

/// The steps of a hit of an entry whose DMA accesses are `ops` (in their ticks' order) for
/// a window's `logs` (cycles from `base`), in the lock-step order: the cores' accesses
/// merged ([`Merged`], their register stores left out), each after the DMA's accesses at
/// or before its cycle and before the later ones (as the lock-step bus runs the I/O
/// through an access's cycle first), the DMA's last ones after all. The merged replay
/// ([`Board::io_memo_apply`]) does them; a [`Plan`] is worked out from them.
pub(super) struct Order<'l> {
    pub(super) ops: &'l [MemoOp],
    pub(super) logs: &'l [Vec<IoAccess>; 2],
    pub(super) base: u64,
    pub(super) merged: Merged<'l>,
    /// The DMA's next access, and the cores' next one if it is known.
    pub(super) next: usize,
    pub(super) core: Option<(usize, usize)>,
}

impl<'l> Order<'l> {
    pub(super) fn new(ops: &'l [MemoOp], logs: &'l [Vec<IoAccess>; 2], base: u64) -> Self {
        Order {
            ops,
            logs,
            base,
            merged: Merged::new(logs),
            next: 0,
            core: None,
        }
    }
}

impl Iterator for Order<'_> {
    type Item = Step;
    fn next(&mut self) -> Option<Step> {
        if self.core.is_none() {
            let logs = self.logs;
            self.core = std::iter::from_fn(|| self.merged.next_index())
                .find(|&(k, i)| logs[k].get(i).is_some_and(|a| a.kind != IoKind::Reg));
        }
        let due = (self.core)
            .and_then(|(k, i)| self.logs[k].get(i))
            .map_or(u64::MAX, |a| a.cycle.wrapping_sub(self.base));
        if self.ops.get(self.next).is_some_and(|op| op.tick <= due) {
            self.next += 1;
            return Some(Step::Dma(self.next - 1));
        }
        self.core.take().map(|(k, i)| Step::Core(k, i))
    }
}

/// Stores the `size` low bytes of `value` at SRAM offset `off`, journaling the word into
/// [`System::io_journal`].
pub(super) fn sram_put(sys: &mut System, off: u32, size: u8, value: u32) {
    let word = off & !3;
    let old = sys.sram_peek(word);
    if let Some(j) = sys.io_journal.as_mut() {
        j.push(u64::from(word) << 32 | u64::from(old));
    }
    store_le(&mut sys.sram, off as usize, u32::from(size), value);
}
