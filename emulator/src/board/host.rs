//! The host's side of the board: loading an image, starting cores, reading and writing
//! memory without cycles, and calling one function.

use super::*;
use crate::elf::{self, ElfError};
use std::fmt;
use tactus_isa::decode::Instr;
use tactus_isa::timing::cycles;
use tactus_rp2040::memory::SRAM_END;
/// Where [`Board::call`] puts its return stub: the last word of SRAM (the stack given to a
/// call must be below it).
pub const CALL_STUB: u32 = SRAM_END - 4;

/// What a function called with [`Board::call`] returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CallResult {
    /// r0 at return (the AAPCS result word).
    pub r0: u32,
    /// r1 at return (the high word of a 64-bit result).
    pub r1: u32,
    /// Cycles from the first instruction to the return, the return included.
    pub cycles: u64,
}

/// Why [`Board::call`] did not return normally.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CallError {
    /// The board stopped before the function returned.
    Stopped {
        /// Why it stopped.
        reason: StopReason,
        /// The core's PC then.
        pc: u32,
    },
    /// A host access failed.
    Emu(EmuError),
}

impl fmt::Display for CallError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CallError::Stopped { reason, pc } => {
                write!(
                    f,
                    "the called function did not return: {reason:?} at pc {pc:#010x}"
                )
            }
            CallError::Emu(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for CallError {}

impl Board {
    /// Parses and loads an ELF executable, then starts core 0: from its vector table if the
    /// image has one (`.vectors`/`.vector_table`/`.isr_vector` section), else at the entry
    /// point with SP at the top of SRAM.
    pub fn load_elf(&mut self, bytes: &[u8]) -> Result<(), EmuError> {
        let image = elf::parse(bytes)?;
        for seg in &image.segments {
            self.write_bytes(seg.addr, &seg.data).map_err(|_| {
                EmuError::Elf(ElfError::Unmapped {
                    addr: seg.addr,
                    size: seg.data.len() as u32,
                })
            })?;
        }
        match image.vector_table {
            _ if image.boot2 => self.boot_from_flash()?,
            Some(vt) => self.boot_from_vectors(0, vt)?,
            None => self.enter_ram_image(image.entry),
        }
        self.image = image;
        Ok(())
    }

    /// Address of symbol `name` in the loaded image.
    pub fn symbol(&self, name: &str) -> Result<u32, EmuError> {
        self.image
            .symbol(name)
            .map(|s| s.addr)
            .ok_or_else(|| EmuError::NoSymbol(name.to_string()))
    }

    /// Calls the Thumb function at `addr` on `core` as AAPCS code would (arguments in r0–r3,
    /// at most 4), with the stack at `sp`, and runs until it returns or `limit` cycles pass.
    ///
    /// The return address is a stub at [`CALL_STUB`] (an `SVC #0xCA`, written by this call)
    /// that stops the board; the other core keeps running meanwhile. Returns r0 and r1 and the
    /// cycles from the function's first instruction to its return (the return instruction
    /// included, the stub and the caller's `BL` not: add 3 for a `BL`, Cortex-M0+ TRM 3.3).
    ///
    /// Errors: [`CallError::Stopped`] when the function faults, hits the cycle limit or the
    /// board stops for another reason; [`CallError::Emu`] when the stub cannot be written.
    pub fn call(
        &mut self,
        core: usize,
        addr: u32,
        args: &[u32],
        sp: u32,
        limit: u64,
    ) -> Result<CallResult, CallError> {
        const STUB_SVC: u8 = 0xca;
        // Rewriting an unchanged stub would empty the decode cache on every call.
        let stub = [STUB_SVC, 0xdf, 0, 0xbe];
        let mut now = [0u8; 4];
        self.read_bytes(CALL_STUB, &mut now)
            .map_err(CallError::Emu)?;
        if now != stub {
            self.write_bytes(CALL_STUB, &stub).map_err(CallError::Emu)?;
        }
        let halts = std::mem::replace(&mut self.config.svc_halts, true);
        let c = &mut self.cores[core];
        c.reset_to(addr | 1, sp);
        for (i, a) in args.iter().take(4).enumerate() {
            c.r[i] = *a;
        }
        c.r[14] = CALL_STUB | 1;
        let start = c.cycle;
        let stop = self.run_until(start.saturating_add(limit));
        self.config.svc_halts = halts;
        let c = &self.cores[core];
        match stop {
            StopReason::Svc { core: k, imm } if k == core && imm == STUB_SVC => {
                let svc = cycles(&Instr::Svc { imm }, false, false) as u64;
                Ok(CallResult {
                    r0: c.r[0],
                    r1: c.r[1],
                    cycles: c.cycle - start - svc,
                })
            }
            other => Err(CallError::Stopped {
                reason: other,
                pc: c.r[15],
            }),
        }
    }
}
