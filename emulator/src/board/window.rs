//! Running ahead: one core runs a window of compiled code ahead of the other, with an undo
//! journal.
//!
//! **Running ahead** ([`Config::own_banks`], block engine only). With both cores on the
//! fast path, lock-step turns last an instruction or two. Instead, the core that is behind
//! (A) runs a *window* of compiled code ahead, *confined* to its own SRAM banks S_A: every
//! load and store, and every instruction fetch from SRAM, is checked against S_A and the
//! code leaves before an instruction that would touch anything else (another bank,
//! SIO, a peripheral, the PPB; flash and ROM are read-only and always allowed), and every
//! store journals the word it overwrites. The window ends where A leaves, at the first
//! deadline of either core (the run's limit, the next timer event, either core's SysTick),
//! or when the journal is full. Then the other core (B) catches up to A's cycle (one past
//! it when B is core 0, which goes first on a tie) confined to the *other* banks. If B
//! gets there, the window is kept; if B stops before (it needs one of A's banks, SIO, a
//! peripheral, an exception, a sleep, a fetch from A's banks), A is rolled back — its
//! stores undone from the journal, newest first, its bank claims, stall count and core
//! state restored — and the cores go on in lock-step from there, B's instructions
//! standing. *Why this is the lock-step result:* in the window A touches only S_A, B
//! touches none of S_A, and neither touches anything else the other can see (no SIO, no
//! peripheral, no interrupt line, no event: those leave; the timer has no event and no
//! SysTick wraps before the window's end; nothing is fetched from a bank the other core
//! writes). So no word either core reads is written by the other in the window, and an
//! access's arbitration depends only on the other core's last claim of the *same* bank,
//! which the other core does not change in the window: it is the value it had at the
//! window's start, whichever order the two cores' instructions run in. The instructions of
//! the two cores in the window therefore commute, and running all of A's before all of
//! B's gives the registers, memory, cycles and stalls of the interleaved order. A rollback
//! is exact for the same reason: B's instructions commute with A's, and A re-runs from
//! the same state. Tests: `tests/block_engine.rs` (random two-core programs on own banks
//! with shared, other-bank and SIO traffic, SysTick, WFI/WFE/SEV; the own-bank speed
//! loop), `firmware/tests/image.rs` (an image of every shipped instrument, both cores).

use super::*;
use crate::block;
use crate::bus::ALL_BANKS;
/// What a run-ahead attempt ([`Board::run_ahead`]) did.
pub(super) enum Window {
    /// The window was kept, or its first part (the core behind moved on).
    Kept,
    /// The core behind ran nothing (its next instruction needs the general path, its code
    /// is not compiled yet, or the deadlines leave no room).
    Idle,
    /// The window was rolled back.
    RolledBack,
}

/// Fewest cycles a run-ahead window may span ([`Board::run_ahead`]).
pub(super) const MIN_WINDOW: u64 = 64;

/// Lock-step cycles after a run-ahead window that could not be kept, before the next.
pub(super) const RETRY: u64 = 4096;

/// A core's state at the start of a run-ahead window ([`Board::run_ahead`]).
pub(super) struct Saved {
    core: Core,
    claims: [u64; crate::bus::BANKS],
    stalls: u64,
}

/// Undoes (the end of) core `a`'s run-ahead window: its stores in `journal` (newest
/// first), its bank claims, stalls and state as `saved`; decoded code is dropped when a
/// store in the window hit a code page (`epoch` moved), since the undo may have changed
/// that memory back.
pub(super) fn undo(
    core: &mut Core,
    sys: &mut System,
    a: usize,
    saved: &Saved,
    journal: &[u64],
    epoch: u32,
) {
    for &e in journal.iter().rev() {
        let off = (e >> 32) as usize;
        sys.sram[off..off + 4].copy_from_slice(&(e as u32).to_le_bytes());
    }
    *core = saved.core.clone();
    for (bank, c) in saved.claims.iter().enumerate() {
        sys.bank_claim[bank][a] = *c;
    }
    sys.contention_stalls[a] = saved.stalls;
    if sys.code_epoch != epoch {
        sys.invalidate_code();
    }
}

impl Board {
    /// Run-ahead windows so far ("Running ahead" in the module documentation): (kept,
    /// rolled back because the other core could not catch up confined). A window whose
    /// first part was kept ([`Board::run_ahead_partly_kept`]) counts in neither.
    pub fn run_ahead_windows(&self) -> (u64, u64) {
        (self.windows[0], self.windows[1])
    }

    /// Run-ahead windows of which only the part before the other core's stop was kept
    /// (the core that ran ahead rolled back and run again up to there).
    pub fn run_ahead_partly_kept(&self) -> u64 {
        self.windows[2]
    }

    /// One window of running ahead (see "Running ahead" in the module documentation): core
    /// `a` (the one behind, both cores on the fast path with `deadline`s as in
    /// [`Board::run_until`]) runs compiled code confined to its own banks, the other core
    /// then catches up confined to every other bank. When the other core stops before
    /// catching up, core `a` is rolled back and runs again up to where the other stopped
    /// (the window's first part is kept); it is rolled back for good when that part is
    /// shorter than [`MIN_WINDOW`] (the other core's instructions stand either way: they
    /// commute with the window).
    pub(super) fn run_ahead(&mut self, a: usize, deadline: [u64; 2]) -> Window {
        let b = 1 - a;
        let start = self.cores[a].cycle;
        // The other core must be able to reach the window's end (`+ 1` when it is core 0,
        // which runs first on a tie) before its own deadline.
        let end = deadline[a].min(deadline[b].saturating_sub((b == 0) as u64));
        if start.saturating_add(MIN_WINDOW) > end {
            return Window::Idle;
        }
        let saved = Saved {
            core: self.cores[a].clone(),
            claims: self.system.bank_claim.map(|c| c[a]),
            stalls: self.system.contention_stalls[a],
        };
        let epoch = self.system.code_epoch;
        let (sys, blocks) = (&mut self.system, &mut self.blocks);
        let mut journal = std::mem::take(&mut blocks.journal);
        let mut marks = std::mem::take(&mut blocks.marks);
        journal.clear();
        marks.clear();
        sys.allowed_banks = self.config.own_banks[a] & ALL_BANKS;
        let _ = block::run_confined(
            &mut self.cores[a],
            sys,
            blocks,
            end,
            Some(&mut journal),
            Some(&mut marks),
        );
        let reached = self.cores[a].cycle;
        let mut kept = reached > start;
        let mut partly = false;
        if kept {
            let target = reached + (b == 0) as u64;
            sys.allowed_banks = ALL_BANKS & !self.config.own_banks[a];
            let caught = block::run_confined(&mut self.cores[b], sys, blocks, target, None, None);
            kept = caught.is_ok() && self.cores[b].cycle >= target;
            if !kept {
                // Core `b` stopped at `t`, before an instruction it could not run confined.
                // Cut core `a` back to its last mark before `b`'s next instruction in the
                // lock-step order (at or before `t`, `t + 1` when `a` is core 0): what it
                // ran up to there is in the window and stands.
                let redo = self.cores[b].cycle + (a == 0) as u64;
                let mark = marks
                    .iter()
                    .rev()
                    .find(|m| m.core.cycle <= redo)
                    .filter(|m| m.core.cycle >= start.saturating_add(MIN_WINDOW));
                let cut = match mark {
                    Some(m) => Saved {
                        core: m.core.clone(),
                        claims: m.claims,
                        stalls: m.stalls,
                    },
                    None => saved,
                };
                let from = mark.map_or(0, |m| m.journal);
                partly = mark.is_some();
                undo(&mut self.cores[a], sys, a, &cut, &journal[from..], epoch);
            }
        }
        sys.allowed_banks = ALL_BANKS;
        blocks.journal = journal;
        blocks.marks = marks;
        if reached == start {
            return Window::Idle;
        }
        self.windows[if kept {
            0
        } else if partly {
            2
        } else {
            1
        }] += 1;
        if kept || partly {
            Window::Kept
        } else {
            Window::RolledBack
        }
    }
}
