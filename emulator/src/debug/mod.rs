//! Debugging the board without changing it: breakpoints, watchpoints and single steps on
//! either core, and a hook through which a debugger ([`gdb`]) takes over
//! [`Board::run_until`].
//!
//! **Why the emulated time does not change.** A debugged run is the same machine stepped
//! one instruction at a time with [`Board::step`], which the board's module documents as
//! giving every result of [`Board::run_until`] (the lock-step order, the decode cache and
//! the fast path change speed, never a result). Between two steps the debugger only
//! *looks* — registers, the instruction just retired, host reads of memory, which cost the
//! cores nothing — and stops before handing control back to the host. A debugger's writes
//! (a register, a memory word) do change the program, as on hardware; reads never do. So
//! a run whose debugger only reads ends on the same cycle with the same outputs as the
//! run without it (`tests/gdb_client.rs` at the root checks this with a real gdb).
//!
//! **The hook.** A host loop (the firmware runner's sample loop, `tactus emu run`) calls
//! [`Board::run_until`] as usual. With a [`crate::board::Debugger`] attached ([`Board::attach_debugger`]),
//! that call goes to the debugger, which runs the board (with [`Board::run_watched`], or
//! plainly when nothing is watched) and may stop it in the middle — at a breakpoint, after
//! a step, on a watched access — and serve its client until told to go on. The host loop
//! never knows: when its `run_until` returns, the board is at its limit, as without a
//! debugger.

pub mod arch;
pub mod gdb;

use crate::board::Board;
use crate::core::RunState;
use crate::machine::StopReason;
use crate::watch::{Access, Watches};
use tactus_isa::decode::Instr;

/// Why [`Board::run_watched`] returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WatchStop {
    /// The board stopped as [`Board::run_until`] would have (the limit reached, a fault
    /// with `stop_on_fault`, a lockup, no core running).
    Board(StopReason),
    /// `core` is about to execute the instruction at a breakpoint.
    Breakpoint {
        /// The core.
        core: usize,
    },
    /// `core` retired the instruction (or took the exception) a single step asked for.
    Stepped {
        /// The core.
        core: usize,
    },
    /// `core`'s last instruction accessed a watched address.
    Watch {
        /// The core.
        core: usize,
        /// The watchpoint's first byte.
        addr: u32,
        /// What the instruction did: [`Access::Read`] or [`Access::Write`].
        access: Access,
    },
    /// `poll` asked to stop (the client sent something: an interrupt, say).
    Polled,
}

/// How many instructions [`Board::run_watched`] runs between two calls of its `poll`.
pub const POLL_EVERY: u32 = 1 << 14;

/// The data an instruction reads or writes: (address, bytes, access), from the registers
/// `r` it started with (ARMv6-M ARM DDI0419 A6.7: the load/store forms of Thumb).
/// `None` for instructions that touch no data memory (exception stacking is not counted).
pub fn data_access(instr: &Instr, pc: u32, r: &[u32; 16]) -> Option<(u32, u32, Access)> {
    let kind = |store: bool| if store { Access::Write } else { Access::Read };
    let count = |list: u32| list.count_ones() * 4;
    match *instr {
        Instr::MemImm { op, rn, imm, .. } => Some((
            r[rn as usize].wrapping_add(imm as u32),
            op.size(),
            kind(op.is_store()),
        )),
        Instr::MemReg { op, rn, rm, .. } => Some((
            r[rn as usize].wrapping_add(r[rm as usize]),
            op.size(),
            kind(op.is_store()),
        )),
        Instr::LdrLit { imm, .. } => Some((
            (pc.wrapping_add(4) & !3).wrapping_add(imm as u32),
            4,
            Access::Read,
        )),
        Instr::Push { list } => {
            let n = count(list as u32 & 0x40ff);
            Some((r[13].wrapping_sub(n), n, Access::Write))
        }
        Instr::Pop { list } => Some((r[13], count(list as u32 & 0x80ff), Access::Read)),
        Instr::Stm { rn, list } => Some((r[rn as usize], count(list as u32), Access::Write)),
        Instr::Ldm { rn, list } => Some((r[rn as usize], count(list as u32), Access::Read)),
        _ => None,
    }
}

impl Board {
    /// Runs to cycle `limit` one instruction at a time ([`Board::step`], so with the same
    /// results as [`Board::run_until`]), stopping before an instruction at a breakpoint of
    /// `watches` (one the core arrived at since the call began, so a resumed core first
    /// leaves the breakpoint it stands on), after an instruction that touched a watched
    /// address, after `step`'s core retired an instruction or took an exception, or when
    /// `poll` (called every [`POLL_EVERY`] instructions) returns true.
    pub fn run_watched(
        &mut self,
        limit: u64,
        watches: &Watches,
        step: Option<usize>,
        poll: &mut dyn FnMut() -> bool,
    ) -> WatchStop {
        let mut budget = POLL_EVERY;
        loop {
            budget -= 1;
            if budget == 0 {
                budget = POLL_EVERY;
                if poll() {
                    return WatchStop::Polled;
                }
            }
            let before = [
                (self.cores[0].r, self.cores[0].instructions),
                (self.cores[1].r, self.cores[1].instructions),
            ];
            let k = match self.step(limit) {
                None => return WatchStop::Board(StopReason::CycleLimit),
                Some(Ok(k)) => k,
                Some(Err(stop)) => return WatchStop::Board(stop),
            };
            let core = &self.cores[k];
            let (regs, count) = &before[k];
            let retired = core.instructions != *count;
            let moved = core.r[15] != regs[15];
            if retired && !watches.watchpoints.is_empty() {
                if let Some(last) = core.last {
                    if let Some((addr, len, access)) = data_access(&last.instr, last.pc, regs) {
                        if let Some(w) = watches.hit(addr, len, access) {
                            return WatchStop::Watch {
                                core: k,
                                addr: w.addr,
                                access,
                            };
                        }
                    }
                }
            }
            if step == Some(k) && (retired || moved) {
                return WatchStop::Stepped { core: k };
            }
            if (retired || moved)
                && core.state == RunState::Running
                && watches.breakpoints.contains(&core.r[15])
            {
                return WatchStop::Breakpoint { core: k };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::watch::Watchpoint;
    use tactus_isa::decode::MemOp;

    #[test]
    fn data_accesses_of_the_load_store_forms() {
        let mut r = [0u32; 16];
        r[1] = 0x2000_0100;
        r[2] = 8;
        r[13] = 0x2004_0000;
        let str_imm = Instr::MemImm {
            op: MemOp::Str,
            rt: 0,
            rn: 1,
            imm: 4,
        };
        assert_eq!(
            data_access(&str_imm, 0, &r),
            Some((0x2000_0104, 4, Access::Write))
        );
        let ldrb = Instr::MemReg {
            op: MemOp::Ldrb,
            rt: 0,
            rn: 1,
            rm: 2,
        };
        assert_eq!(
            data_access(&ldrb, 0, &r),
            Some((0x2000_0108, 1, Access::Read))
        );
        // PUSH {r4, r5, lr}: 12 bytes below SP.
        let push = Instr::Push { list: 0x4030 };
        assert_eq!(
            data_access(&push, 0, &r),
            Some((0x2003_fff4, 12, Access::Write))
        );
        // LDR r0, [pc, #8] at 0x102: Align(0x106, 4) + 8.
        let lit = Instr::LdrLit { rt: 0, imm: 8 };
        assert_eq!(data_access(&lit, 0x102, &r), Some((0x10c, 4, Access::Read)));
        let w = Watches {
            breakpoints: vec![],
            watchpoints: vec![Watchpoint {
                addr: 0x2003_fffc,
                len: 4,
                access: Access::Write,
            }],
        };
        assert!(w.hit(0x2003_fff4, 12, Access::Write).is_some());
        assert!(w.hit(0x2003_fff4, 8, Access::Write).is_none());
        assert!(w.hit(0x2003_fffc, 4, Access::Read).is_none());
    }
}
