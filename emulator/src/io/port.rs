//! The DMA's side of the I/O machine for one tick: what it reaches of the system (SRAM
//! with the cores' bank claims and the decode cache's code pages, ROM, flash: [`Memory`])
//! and the PIO blocks' FIFOs and DREQs ([`Port`], the [`DmaPort`] the DMA runs against).
//! Its SRAM accesses arbitrate with the cores' ([`Port::claim_bank`]: the bus priority of
//! [`super::Io::dma_wins`]), journal the words they overwrite while a window is replayed,
//! and, while a replay is recorded for the period memo, log what they read and write with
//! their lanes ([`super::LaneRec`]).

use super::*;

/// What the machine reaches of the rest of the system while it runs: SRAM (with the cores'
/// bank claims and the decode cache's code pages), ROM and flash.
pub(crate) struct Memory<'a> {
    pub sram: &'a mut [u8],
    pub code_pages: &'a mut [bool],
    pub code_epoch: &'a mut u32,
    pub bank_claim: &'a [[u64; 2]; BANKS],
    pub rom: &'a [u8],
    pub flash: &'a [u8],
    pub xip_answers: bool,
    /// Where the DMA's SRAM writes journal the word they overwrite (`offset << 32 | old`),
    /// while a window's I/O is replayed (`System::io_journal`).
    pub journal: Option<&'a mut Vec<u64>>,
    /// What the DMA does while a window's replay is recorded with lanes for the period
    /// memo (`System::io_rec`, `accel/io_window/`).
    pub rec: Option<&'a mut LaneRec>,
}

/// Writes `size` bytes of `value` at SRAM offset `off` for the DMA: journaled while a
/// window is replayed, invalidating decoded code on the page.
#[inline]
pub(crate) fn dma_sram_write(mem: &mut Memory, off: usize, size: u32, value: u32) {
    let journal = mem.journal.as_deref_mut();
    dma_sram_store(
        mem.sram,
        mem.code_pages,
        mem.code_epoch,
        journal,
        off,
        size,
        value,
    );
}

/// [`dma_sram_write`] on the system's parts themselves (a period memo's hit,
/// `crate::system::System::io_dma_write`): the SRAM, its pages of decoded code and their
/// epoch, and the journal.
#[inline]
pub(crate) fn dma_sram_store(
    sram: &mut [u8],
    code_pages: &mut [bool],
    code_epoch: &mut u32,
    journal: Option<&mut Vec<u64>>,
    off: usize,
    size: u32,
    value: u32,
) {
    if let Some(j) = journal {
        let word = off & !3;
        j.push((word as u64) << 32 | u64::from(load_le(sram, word, 4)));
    }
    store_le(sram, off, size, value);
    if code_pages[off >> 8] {
        *code_epoch = code_epoch.wrapping_add(1);
        code_pages.fill(false);
    }
}

/// The DMA's side of the machine for one tick: memory, the PIO FIFOs and DREQs.
pub(super) struct Port<'m, 'a> {
    pub(super) mem: &'m mut Memory<'a>,
    pub(super) pio: &'m mut [Pio; 2],
    pub(super) claim: &'m mut [[u64; BANKS]; 2],
    /// Whether each DMA master (read, write) wins a bank against core 0 and core 1.
    pub(super) wins: [[bool; 2]; 2],
    /// The PIO blocks whose registers (FIFOs) the DMA read or wrote (bit b: PIO b).
    pub(super) touched: u8,
}

/// Which PIO block `addr` is in (0 or 1) and the register offset (the atomic aliases of
/// DMA transfers are not decoded: an offset within the first 4 KB).
pub(super) fn pio_of(addr: u32) -> Option<(usize, u32)> {
    match addr & !0xfff {
        PIO0_BASE => Some((0, addr & 0xfff)),
        PIO1_BASE => Some((1, addr & 0xfff)),
        _ => None,
    }
}

impl<'m, 'a> Port<'m, 'a> {
    /// The DMA's side of `mem` and the blocks `pio` for a tick, the masters' bank claims in
    /// `claim`, winning banks against the cores as `wins` says.
    pub(super) fn new(
        mem: &'m mut Memory<'a>,
        pio: &'m mut [Pio; 2],
        claim: &'m mut [[u64; BANKS]; 2],
        wins: [[bool; 2]; 2],
    ) -> Self {
        Port {
            mem,
            pio,
            claim,
            wins,
            touched: 0,
        }
    }

    /// The wait states of master `m`'s access to `bank` in `cycle`, claiming it.
    pub(super) fn claim_bank(&mut self, m: usize, bank: usize, cycle: u64) -> u32 {
        let mut wait = 0u32;
        let core_claims =
            |at: u64, k: usize| self.mem.bank_claim[bank][k] == at && !self.wins[m][k];
        while core_claims(cycle + u64::from(wait), 0)
            || core_claims(cycle + u64::from(wait), 1)
            || (m == 1 && self.claim[0][bank] == cycle + u64::from(wait))
        {
            wait += 1;
        }
        self.claim[m][bank] = cycle + u64::from(wait);
        if let Some(rec) = self.mem.rec.as_deref_mut() {
            rec.claims.push((cycle + u64::from(wait), bank as u8));
        }
        wait
    }
}

impl DmaPort for Port<'_, '_> {
    fn read(&mut self, cycle: u64, addr: u32, size: u32) -> Result<(u32, u32), BusFault> {
        if let Some((off, bank)) = sram_location(addr) {
            let wait = self.claim_bank(0, bank, cycle);
            if let Some(rec) = self.mem.rec.as_deref_mut() {
                // Each SRAM word it reads is an input of the recording.
                let input = rec.next_input;
                rec.next_input += 1;
                rec.ops.push(LaneOp::Read {
                    tick: cycle,
                    off: off as u32,
                    size: size as u8,
                    input,
                });
                rec.read_lanes = lanes::input_word(input, 8 * size);
            }
            return Ok((load_le(self.mem.sram, off, size), wait));
        }
        if let Some((b, off)) = pio_of(addr) {
            self.touched |= 1 << b;
            let v = self.pio[b].read(off & !3);
            let mask = u32::MAX >> (32 - 8 * size);
            if let Some(rec) = self.mem.rec.as_deref_mut() {
                let l = self.pio[b].lanes.as_ref().map_or(CONST, |l| l.last_read);
                rec.read_lanes = lanes::and(&lanes::shr(&l, 8 * (addr & 3)), mask);
            }
            let v = v >> (8 * (addr & 3)) & mask;
            return Ok((v, 0));
        }
        if let Some(rec) = self.mem.rec.as_deref_mut() {
            rec.poisoned = true;
            rec.read_lanes = CONST;
        }
        let flash = addr.wrapping_sub(tactus_rp2040::memory::FLASH_BASE);
        if addr < tactus_rp2040::memory::ROM_SIZE {
            return Ok((load_le(self.mem.rom, addr as usize, size), 0));
        }
        if flash < tactus_rp2040::memory::FLASH_SIZE && self.mem.xip_answers {
            return Ok((load_le(self.mem.flash, flash as usize, size), 0));
        }
        Err(BusFault { addr })
    }

    fn write(&mut self, cycle: u64, addr: u32, size: u32, value: u32) -> Result<u32, BusFault> {
        if let Some((off, bank)) = sram_location(addr) {
            let wait = self.claim_bank(1, bank, cycle);
            if let Some(rec) = self.mem.rec.as_deref_mut() {
                let mask = u32::MAX >> (32 - 8 * size);
                rec.ops.push(LaneOp::Write {
                    tick: cycle,
                    off: off as u32,
                    size: size as u8,
                    value: value & mask,
                    lanes: Box::new(lanes::and(&rec.write_lanes, mask)),
                });
            }
            dma_sram_write(self.mem, off, size, value);
            return Ok(wait);
        }
        if let Some((b, off)) = pio_of(addr) {
            // A narrow write reaches a 32-bit register replicated (datasheet 2.1.4).
            let v = match size {
                1 => (value & 0xff) * 0x0101_0101,
                2 => (value & 0xffff) * 0x0001_0001,
                _ => value,
            };
            if let Some(rec) = self.mem.rec.as_deref_mut() {
                let l = rec.write_lanes;
                let w: Word = std::array::from_fn(|i| match size {
                    1 => l[i % 8],
                    2 => l[i % 16],
                    _ => l[i],
                });
                let fifo = (tactus_rp2040::pio::reg::TXF0..tactus_rp2040::pio::reg::TXF0 + 16)
                    .contains(&(off & !3));
                match self.pio[b].lanes.as_deref_mut() {
                    Some(pl) if fifo => pl.next_write = w,
                    // Data written to any other register decides what the block does.
                    _ => lanes::fix(&mut w.clone(), v, u32::MAX, &mut rec.fixed),
                }
            }
            self.touched |= 1 << b;
            self.pio[b].write(off & !3, v);
            return Ok(0);
        }
        Err(BusFault { addr })
    }

    fn read_lanes(&mut self) -> Word {
        self.mem.rec.as_deref().map_or(CONST, |r| r.read_lanes)
    }

    fn write_lanes(&mut self, lanes: &Word) {
        if let Some(rec) = self.mem.rec.as_deref_mut() {
            rec.write_lanes = *lanes;
        }
    }

    fn dreq_room(&self, n: u32) -> u32 {
        let (b, i) = ((n / 8) as usize, (n % 8) as usize);
        match (b, i) {
            (0 | 1, 0..=3) => self.pio[b].tx_room(i),
            (0 | 1, _) => self.pio[b].rx_level(i - 4),
            _ => 0,
        }
    }
}

/// The SRAM banks the bytes `[addr, addr + len)` of the address space touch.
pub(super) fn banks_of(addr: u32, len: u64) -> u8 {
    let (lo, hi) = (u64::from(addr), u64::from(addr).saturating_add(len));
    let overlaps = |a: u64, b: u64| lo < b && a < hi;
    let mut banks = 0u8;
    // The striped view: four or more bytes past a word boundary reach more banks; 16
    // bytes reach all four.
    let (s0, s1) = (0x2000_0000u64, 0x2004_0000u64);
    if overlaps(s0, s1) {
        let (a, b) = (lo.max(s0), hi.min(s1));
        if b - a >= 16 {
            banks |= 0xf;
        } else {
            let mut w = a & !3;
            while w < b {
                banks |= 1 << ((w >> 2) & 3);
                w += 4;
            }
        }
    }
    for (bank, base) in [(4, 0x2004_0000u64), (5, 0x2004_1000)] {
        if overlaps(base, base + 0x1000) {
            banks |= 1 << bank;
        }
    }
    for bank in 0..4u64 {
        let base = 0x2100_0000 + bank * 0x1_0000;
        if overlaps(base, base + 0x1_0000) {
            banks |= 1 << bank;
        }
    }
    banks
}
