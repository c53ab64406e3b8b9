//! What a core sees beyond its private peripheral bus: the [`Bus`] trait, which the
//! executor calls for every load, store and fetch and which answers with the wait states
//! the access cost, and the fault of an address nothing answers ([`BusFault`]). Below it,
//! the vocabulary every route to memory shares — little-endian loads and stores on byte
//! arrays ([`load_le`], [`store_le`]) and where SRAM words lie in the banks
//! ([`sram_bank`], [`plain_sram_span`], [`span_banks`], [`sram_word_run`]) — so that the
//! system ([`crate::system::System`], the lock-step machine's bus), a window's confined bus
//! (`board/window.rs`) and the DMA's port (`crate::io`) read and write memory the same way.
//! The addresses are the `tactus_rp2040` crate's.

use tactus_rp2040::memory::{BANKS, SRAM_ALIAS_BASE, SRAM_BASE, SRAM_SIZE};

/// An access to an address that nothing answers (or a fetch from a non-executable region).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusFault {
    /// The faulting address.
    pub addr: u32,
}

/// What a core sees beyond its private peripheral bus. Sizes are 1, 2 or 4 bytes and the
/// caller has already checked alignment. `cycle` is the cycle of the data phase; results
/// carry the wait states added to the instruction.
pub trait Bus {
    /// Loads `size` bytes at `addr` for `core`: (zero-extended value, wait states).
    fn read(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        size: u32,
    ) -> Result<(u32, u32), BusFault>;
    /// Stores the low `size` bytes of `value` at `addr` for `core`: wait states.
    fn write(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        size: u32,
        value: u32,
    ) -> Result<u32, BusFault>;
    /// Fetches the halfword at `addr` (even) for execution.
    fn fetch(&mut self, addr: u32) -> Result<u16, BusFault>;

    /// Stores `words` at `addr`, `addr + 4`, … for `core`, all in the data phase `cycle`:
    /// exactly `words.len()` word [`Bus::write`]s in order (exception entry's stacking,
    /// DDI0419 B1.5.6), with their claims, stalls and data; the wait states are not
    /// returned (the caller's cost is fixed). Errors: the first fault, the words before it
    /// written. [`System`] does it without the per-word address decode when the words lie
    /// in plain SRAM.
    #[inline]
    fn write_words(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        words: &[u32],
    ) -> Result<(), BusFault> {
        write_each_word(self, core, cycle, addr, words)
    }

    /// Loads `out.len()` words from `addr`, `addr + 4`, … for `core` in the data phase
    /// `cycle`: exactly that many word [`Bus::read`]s in order (exception return's
    /// unstacking, DDI0419 B1.5.8), wait states dropped as in [`Bus::write_words`].
    /// Errors: the first fault.
    #[inline]
    fn read_words(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        out: &mut [u32],
    ) -> Result<(), BusFault> {
        read_each_word(self, core, cycle, addr, out)
    }

    /// Fetches the instruction at `addr`: `(hw1, hw2, size in bytes)`, `hw2` 0 for a 16-bit
    /// instruction (ARMv6-M ARM A5.1: the first halfword says whether a second follows).
    /// Errors: the fault of the first halfword fetch that fails.
    #[inline]
    fn fetch_instr(&mut self, addr: u32) -> Result<(u16, u16, u32), BusFault> {
        let hw1 = self.fetch(addr)?;
        if tactus_isa::decode::is_32bit(hw1) {
            Ok((hw1, self.fetch(addr.wrapping_add(2))?, 4))
        } else {
            Ok((hw1, 0, 2))
        }
    }
}

/// [`Bus::write_words`]' general path: each word through [`Bus::write`], in order.
#[inline]
pub(crate) fn write_each_word<B: Bus + ?Sized>(
    bus: &mut B,
    core: usize,
    cycle: u64,
    addr: u32,
    words: &[u32],
) -> Result<(), BusFault> {
    for (i, w) in words.iter().enumerate() {
        bus.write(core, cycle, addr.wrapping_add(4 * i as u32), 4, *w)?;
    }
    Ok(())
}

/// [`Bus::read_words`]' general path: each word through [`Bus::read`], in order.
#[inline]
pub(crate) fn read_each_word<B: Bus + ?Sized>(
    bus: &mut B,
    core: usize,
    cycle: u64,
    addr: u32,
    out: &mut [u32],
) -> Result<(), BusFault> {
    for (i, w) in out.iter_mut().enumerate() {
        *w = bus.read(core, cycle, addr.wrapping_add(4 * i as u32), 4)?.0;
    }
    Ok(())
}

/// Every SRAM bank ([`System::allowed_banks`]).
pub(crate) const ALL_BANKS: u8 = (1 << BANKS) - 1;

/// The `size` bytes (1, 2 or 4) at `off` of `mem`, little-endian, zero-extended.
#[inline(always)]
pub(crate) fn load_le(mem: &[u8], off: usize, size: u32) -> u32 {
    // One bounds check per access (the fixed-size conversions cannot fail).
    match size {
        1 => mem[off] as u32,
        2 => u16::from_le_bytes(mem[off..off + 2].try_into().unwrap_or([0; 2])) as u32,
        _ => u32::from_le_bytes(mem[off..off + 4].try_into().unwrap_or([0; 4])),
    }
}

/// Stores the `size` (1, 2 or 4) low bytes of `value` at `off` of `mem`, little-endian.
#[inline(always)]
pub(crate) fn store_le(mem: &mut [u8], off: usize, size: u32, value: u32) {
    match size {
        1 => mem[off] = value as u8,
        2 => mem[off..off + 2].copy_from_slice(&(value as u16).to_le_bytes()),
        _ => mem[off..off + 4].copy_from_slice(&value.to_le_bytes()),
    }
}

/// The offset into [`System::sram`] of `len` bytes from `addr` when they are contiguous
/// there and `addr` is word-aligned: all in the striped view or all in SRAM4/5 (the
/// non-striped aliases map consecutive words to other rows).
#[inline(always)]
pub(crate) fn plain_sram_span(addr: u32, len: u32) -> Option<u32> {
    let off = addr.wrapping_sub(SRAM_BASE);
    let end = off.checked_add(len)?;
    let striped = end <= 0x4_0000;
    let scratch = off >= 0x4_0000 && end <= SRAM_SIZE;
    (addr & 3 == 0 && (striped || scratch)).then_some(off)
}

/// Where the `len` bytes (a multiple of 4) from word-aligned `addr` lie in
/// [`System::sram`] when they are all in one view: `(offset of the first word, bytes from
/// one word to the next)` — 4 in the striped view or SRAM4/5 ([`plain_sram_span`]), 16 in
/// one bank of the non-striped alias (its consecutive words are a bank's consecutive rows).
pub(crate) fn sram_word_run(addr: u32, len: u32) -> Option<(u32, u32)> {
    if !len.is_multiple_of(4) {
        return None;
    }
    if let Some(off) = plain_sram_span(addr, len) {
        return Some((off, 4));
    }
    let alias = addr.wrapping_sub(SRAM_ALIAS_BASE);
    let in_bank = alias & 0xffff;
    (addr & 3 == 0 && alias < 0x4_0000 && in_bank.checked_add(len)? <= 0x1_0000)
        .then_some((in_bank * 4 + (alias >> 16) * 4, 16))
}

/// The arbitration banks (bit b = bank b, as [`sram_bank`]) of the `n` words from plain
/// SRAM offset `off` (a [`plain_sram_span`]: all in the striped banks or all in SRAM4/5).
#[inline(always)]
pub(crate) fn span_banks(off: u32, n: u32) -> u8 {
    if n == 0 {
        return 0;
    }
    if off >= 0x4_0000 {
        // SRAM4 then SRAM5: the first word's bank and the last's.
        1 << sram_bank(off) | 1 << sram_bank(off + 4 * (n - 1))
    } else if n >= 4 {
        0xf
    } else {
        (0..n).fold(0, |m, i| m | 1 << sram_bank(off + 4 * i))
    }
}

/// Arbitration bank of SRAM offset `off` (below [`SRAM_SIZE`]): address bits 3:2 in the
/// striped banks, then SRAM4 and SRAM5.
#[inline(always)]
pub(crate) fn sram_bank(off: u32) -> usize {
    if off < 0x4_0000 {
        ((off >> 2) & 3) as usize
    } else {
        (4 + ((off >> 12) & 1)) as usize
    }
}
