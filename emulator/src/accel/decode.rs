//! The decode cache: each instruction decoded once per address, with its pre-decoded
//! fast-path form ([`crate::accel::fast`]) and its timing-table costs, reused until a store
//! hits an SRAM page holding cached code or the host writes memory (both bump
//! [`System::code_epoch`], which tags every entry), so self-modifying code stays correct.
//! It is how the accelerator hands the machine its instructions ([`Decoder`]).

use super::*;
use crate::accel::fast::Op;
use crate::bus::Bus;
use tactus_isa::decode::{decode, Instr};
use tactus_isa::timing::cycles;
use tactus_rp2040::memory::sram_location;

/// Decode cache entry: the instruction, its pre-decoded fast-path form and its size,
/// tagged by its address and the code epoch.
#[derive(Clone, Copy)]
pub(crate) struct Cached {
    /// [`cache_key`] of the address and the [`System::code_epoch`] when decoded.
    pub(crate) key: u64,
    pub(crate) op: Op,
    pub(crate) instr: Instr,
    pub(crate) size: u32,
    /// Cycles from the timing table: (not taken, taken).
    pub(crate) cost: (u8, u8),
}

/// Decode cache tag: the instruction's address and the code epoch in one word (addresses
/// are even, so the empty tag `u64::MAX` never matches).
#[inline(always)]
pub(crate) fn cache_key(pc: u32, epoch: u32) -> u64 {
    (epoch as u64) << 32 | pc as u64
}

pub(crate) const CACHE_SLOTS: usize = 1 << 14;

/// A decode cache with every slot empty.
pub(crate) fn empty_cache() -> Box<[Cached; CACHE_SLOTS]> {
    vec![
        Cached {
            key: u64::MAX,
            op: Op::Other,
            instr: Instr::Undefined { hw1: 0, hw2: 0 },
            size: 2,
            cost: (0, 0)
        };
        CACHE_SLOTS
    ]
    .into_boxed_slice()
    .try_into()
    .unwrap_or_else(|_| unreachable!())
}

/// The decode cache's entry for the instruction at `pc` (decoded now if need be, its SRAM
/// pages marked as code pages): the instruction, its size and its `(not taken, taken)`
/// cycles; `None` when it cannot be fetched.
#[inline(always)]
pub(crate) fn cached(
    cache: &mut [Cached; CACHE_SLOTS],
    sys: &mut System,
    pc: u32,
) -> Option<(Instr, u32, (u8, u8))> {
    let slot = &mut cache[((pc >> 1) as usize) & (CACHE_SLOTS - 1)];
    if slot.key != cache_key(pc, sys.code_epoch) {
        let (hw1, hw2, size) = sys.fetch_instr(pc).ok()?;
        for a in [pc, pc.wrapping_add(size - 2)] {
            if let Some((off, _)) = sram_location(a) {
                sys.code_pages[off >> 8] = true;
            }
        }
        let instr = decode(hw1, hw2);
        let cost = (
            cycles(&instr, false, false) as u8,
            cycles(&instr, true, false) as u8,
        );
        *slot = Cached {
            key: cache_key(pc, sys.code_epoch),
            op: Op::new(&instr, pc),
            instr,
            size,
            cost,
        };
    }
    Some((slot.instr, slot.size, slot.cost))
}

/// The decode cache is how the accelerator gives the machine its instructions
/// ([`Decoder`]): decoded once per address and reused until a store hits an SRAM page holding
/// cached code or the host writes memory (both bump [`System::code_epoch`]), so
/// self-modifying code stays correct.
impl Decoder for Box<[Cached; CACHE_SLOTS]> {
    #[inline(always)]
    fn decoded(&mut self, sys: &mut System, pc: u32) -> Option<(Instr, u32, (u8, u8))> {
        cached(self, sys, pc)
    }
}
