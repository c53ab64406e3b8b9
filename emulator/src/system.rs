//! The RP2040 outside the cores ([`System`]): its memories, SIO, timer, start-up blocks,
//! XIP path and, on a board with converters, the I/O, behind the memory map and bus fabric
//! as the two cores see it (RP2040 datasheet 2.1, 2.2).
//!
//! Memory is plain byte vectors laid out by *physical* address, so the striped SRAM
//! (0x20000000-0x2003ffff, four 64 KB banks interleaved word by word: bank = address bits
//! 3:2) is one contiguous slice, and the non-striped aliases at 0x21000000 are an address
//! transformation onto it (datasheet 2.6.1). Everything a core reaches outside its own
//! private peripheral bus goes through the [`Bus`] trait, which returns wait states so the
//! executor can count cycles. The addresses are the `tactus_rp2040` crate's (`memory`,
//! one module per block). The XIP flash window has no wait states (the XIP cache and the
//! serial transfer are not timed) and reads only while the SSI and the flash chip are set
//! up for XIP ([`crate::xip`]): a board from [`System::new`] finds them set up for 03h
//! reads, a board booted through the boot ROM ([`crate::Board::boot_from_flash`]) as boot2
//! leaves them.
//!
//! **Bank arbitration.** Each of the six SRAM banks (SRAM0-3 striped, SRAM4 and SRAM5 the 4 KB
//! scratch banks at 0x20040000 and 0x20041000) serves one master per cycle. The emulator
//! executes instructions in lock-step order (the core whose next instruction starts earlier
//! goes first, core 0 first on a tie), and each data access claims its bank for one cycle;
//! an access that finds its bank already claimed by the other core in the same cycle waits a
//! cycle and tries again. So the earlier-issued access wins, core 0 on a tie: a fixed
//! priority, as the RP2040 crossbar gives with both cores at the same BUS_PRIORITY and
//! deterministic by construction. Instruction fetches are assumed not to contend (the
//! Cortex-M0+ timing table presumes zero-wait fetches); ROM, flash, APB and SIO do not
//! contend either. APB accesses cost [`tactus_isa::timing::APB_LOAD_WAIT`] /
//! [`tactus_isa::timing::APB_STORE_WAIT`] extra cycles.

use crate::bus::{
    load_le, plain_sram_span, read_each_word, span_banks, sram_bank, store_le, write_each_word,
    Bus, BusFault, ALL_BANKS,
};
use crate::clocks::{self, SysCtl};
use crate::sio::Sio;
use crate::timer::Timer;
use crate::watchdog::Watchdog;
use crate::xip::Xip;
use tactus_isa::timing::{APB_LOAD_WAIT, APB_STORE_WAIT};
use tactus_rp2040::irq::{SIO_IRQ_PROC0, SIO_IRQ_PROC1};
use tactus_rp2040::memory::{sram_location, BANKS, FLASH_BASE, FLASH_SIZE, ROM_SIZE, SRAM_SIZE};
use tactus_rp2040::resets;
use tactus_rp2040::sio::SIO_BASE;
use tactus_rp2040::ssi::{XIP_SSI_BASE, XIP_SSI_SIZE};
use tactus_rp2040::timer::TIMER_BASE;
use tactus_rp2040::watchdog::WATCHDOG_BASE;

/// The RP2040 outside the cores: memories, SIO, timer, and the bank arbiter.
#[derive(Clone, Debug)]
pub struct System {
    /// Boot ROM contents.
    pub rom: Vec<u8>,
    /// Flash contents.
    pub flash: Vec<u8>,
    /// SRAM contents, by physical address from [`SRAM_BASE`].
    pub sram: Vec<u8>,
    /// Single-cycle IO block.
    pub sio: Sio,
    /// System timer.
    pub timer: Timer,
    /// RESETS, XOSC, PLL_SYS, CLOCKS and VREG: the start-up's registers
    /// (`clocks.rs`, a minimal model).
    pub sysctl: SysCtl,
    /// The watchdog ([`crate::watchdog`]): its count, REASON, scratch and TICK.
    pub watchdog: Watchdog,
    /// The SSI and the flash chip behind the XIP window ([`crate::xip`]).
    pub xip: Xip,
    /// Whether an XIP access reads the flash now ([`Xip::xip_read`] with the programmed
    /// clock), kept current by every SSI and clock write. While it is false every core runs
    /// on the general path, whose flash accesses fault.
    pub(crate) xip_answers: bool,
    /// Last cycle in which each core claimed each bank.
    pub(crate) bank_claim: [[u64; 2]; BANKS],
    /// Cycles each core has lost to bank contention.
    pub contention_stalls: [u64; 2],
    /// Bumped on every SIO access, peripheral write and timer read that fires an alarm,
    /// which may change interrupt lines: the
    /// board recomputes [`System::irq_lines`] only when this changed or a timer event is due.
    pub irq_epoch: u64,
    /// One flag per 256-byte SRAM page: does the board's decode cache hold an instruction
    /// from it? A store to such a page bumps [`System::code_epoch`].
    pub code_pages: Vec<bool>,
    /// Generation of the decode cache: cached instructions from an older epoch are stale.
    pub code_epoch: u32,
    /// SRAM banks the executor's fast path may access (bit per bank: 0-3 SRAM0-3, 4 SRAM4,
    /// 5 SRAM5): [`ALL_BANKS`] except while a core runs confined to some banks
    /// ([`crate::board`], "Running ahead"); an access elsewhere leaves the fast path.
    pub(crate) allowed_banks: u8,
    /// The converters' I/O (PIO, DMA, the parts at the pins), on a board that has them
    /// ([`crate::Board::attach_io`]); `None` otherwise, which costs nothing.
    pub io: Option<Box<crate::io::Io>>,
    /// SRAM banks the I/O's DMA may reach now ([`crate::io::Io::reach_banks`], 0 without
    /// I/O): the fast path leaves them ([`System::fast_banks`]), and every core access to one
    /// runs the I/O up to it first.
    pub(crate) io_banks: u8,
    /// While a window's I/O is replayed (`board/io_window.rs`): each SRAM word the DMA
    /// writes, before it is written (`offset << 32 | old word`), so that the replay can be
    /// undone; `None` otherwise.
    pub(crate) io_journal: Option<Vec<u64>>,
    /// While a window's replay is recorded for the period memo, what the DMA does to SRAM
    /// and the banks, with lanes (`board/io_window.rs`, `crate::lanes`).
    pub(crate) io_rec: Option<Box<crate::io::slots::LaneRec>>,
    /// The machine a period memo's hit left behind instead of making it (`io` is then stale:
    /// `board/io_window.rs`, "The lazy end"); made `io` by [`System::io_unlazy`] before
    /// anything but the period memo looks at it.
    pub(crate) io_lazy: Option<Box<crate::io::slots::LazyEnd>>,
}

impl System {
    /// A fresh system with zeroed memories, clocked at `clock_hz`.
    pub fn new(clock_hz: u64) -> Self {
        System {
            rom: vec![0; ROM_SIZE as usize],
            flash: vec![0; FLASH_SIZE as usize],
            sram: vec![0; SRAM_SIZE as usize],
            sio: Sio::default(),
            timer: Timer::new(clock_hz),
            sysctl: SysCtl::default(),
            watchdog: Watchdog::new(clock_hz),
            xip: Xip::configured_03h(clock_hz),
            xip_answers: true,
            bank_claim: [[u64::MAX; 2]; BANKS],
            contention_stalls: [0; 2],
            irq_epoch: 0,
            code_pages: vec![false; (SRAM_SIZE / 256) as usize],
            code_epoch: 0,
            allowed_banks: ALL_BANKS,
            io: None,
            io_lazy: None,
            io_banks: 0,
            io_journal: None,
            io_rec: None,
        }
    }

    /// The SRAM banks the fast path may access outside windows: every bank but those the
    /// I/O's DMA may reach ([`System::io_banks`]).
    #[inline(always)]
    pub(crate) fn fast_banks(&self) -> u8 {
        ALL_BANKS & !self.io_banks
    }

    /// Runs the I/O (if any) through cycle `to − 1` ([`crate::io`]), everything in it as of
    /// that cycle.
    pub fn io_advance(&mut self, to: u64) {
        self.io_advance_to(to, true);
    }

    /// [`System::io_advance`]; without `settle`, a state machine that alone drives its
    /// converters may stay behind at a bit loop's head (`crate::io::Io::advance`).
    pub(crate) fn io_advance_to(&mut self, to: u64, settle: bool) {
        // A lazy end already there (settled, as every period memo's end is): nothing runs.
        if let Some(l) = self.io_lazy.as_deref() {
            if to <= l.cycle() && !l.end.io.is_behind() {
                return;
            }
        }
        self.io_unlazy();
        if let (Some(io), mut mem) = self.io_parts() {
            io.advance(to, &mut mem, settle);
        }
    }

    /// Runs the I/O (if any) through cycle `to − 1`, settled, and makes it the live machine
    /// ([`System::io_unlazy`]): what a register access or a reset reads and changes.
    fn io_live_at(&mut self, to: u64) {
        self.io_advance(to);
        self.io_unlazy();
    }

    /// Makes the machine a period memo's hit left behind the live one
    /// ([`System::io_lazy`]; nothing when there is none).
    pub(crate) fn io_unlazy(&mut self) {
        if let Some(l) = self.io_lazy.take() {
            if let Some(io) = self.io.as_deref_mut() {
                io.become_lazy(&l);
            }
        }
    }

    /// The I/O's control state, for what does not depend on its cycles or data (which
    /// registers it accepts, the DMA's bus priority and reach, whether it steps): the lazy
    /// end's ([`System::io_lazy`]) while there is one.
    #[inline]
    pub(crate) fn io_control(&self) -> Option<&crate::io::Io> {
        match self.io_lazy.as_deref() {
            Some(l) => Some(&l.end.io),
            None => self.io.as_deref(),
        }
    }

    /// The I/O, and what it reaches of the system ([`crate::io::port::Memory`]).
    fn io_parts(&mut self) -> (Option<&mut crate::io::Io>, crate::io::port::Memory<'_>) {
        let mem = crate::io::port::Memory {
            sram: &mut self.sram,
            code_pages: &mut self.code_pages,
            code_epoch: &mut self.code_epoch,
            bank_claim: &self.bank_claim,
            rom: &self.rom,
            flash: &self.flash,
            xip_answers: self.xip_answers,
            journal: self.io_journal.as_mut(),
            rec: self.io_rec.as_deref_mut(),
        };
        (self.io.as_deref_mut(), mem)
    }

    /// The DMA's write of `size` bytes of `value` at SRAM offset `off`, as the I/O's run
    /// does it ([`crate::io::port::dma_sram_write`]): a period memo's hit (`board/io_window.rs`).
    /// `journaled`: the word before it goes into [`System::io_journal`] (a hit that may
    /// yet be undone).
    #[inline]
    pub(crate) fn io_dma_write(&mut self, off: u32, size: u32, value: u32, journaled: bool) {
        let journal = self.io_journal.as_mut().filter(|_| journaled);
        let (sram, pages, epoch) = (&mut self.sram, &mut self.code_pages, &mut self.code_epoch);
        crate::io::port::dma_sram_store(sram, pages, epoch, journal, off as usize, size, value);
    }

    /// Core `core`'s access to SRAM bank `bank` (one the DMA may reach) in `cycle`: the I/O
    /// run up to it; where the DMA wins against the core, also through the cycles in which
    /// the DMA claims the bank, each a wait state. Returns the wait states.
    fn io_sram(&mut self, core: usize, cycle: u64, bank: usize) -> u32 {
        let wins = self.io_control().is_some_and(|io| io.dma_wins(core));
        if !wins {
            self.io_advance_to(cycle, false);
            return 0;
        }
        let mut at = cycle;
        while self.io_claims(bank, at) {
            at += 1;
        }
        (at - cycle) as u32
    }

    /// One try of [`System::io_sram`] where the DMA wins: the I/O run through `at`, and
    /// whether the DMA claims `bank` in `at` (the core's access then waits a cycle).
    pub(crate) fn io_claims(&mut self, bank: usize, at: u64) -> bool {
        self.io_advance_to(at + 1, false);
        self.io_unlazy();
        self.io.as_ref().is_some_and(|io| io.dma_claims(bank, at))
    }

    /// A core's store of `size` bytes of `value` to the I/O's register at `addr` (one
    /// [`crate::io::Io::owns`], in the AHB-Lite space) in `cycle`, as [`Bus::write`] does it:
    /// a narrow value replicated across the word, the I/O run up to the cycle, the write,
    /// the DMA's banks refreshed. Errors: a block held in reset.
    pub(crate) fn io_store(
        &mut self,
        cycle: u64,
        addr: u32,
        size: u32,
        value: u32,
    ) -> Result<u32, BusFault> {
        let value = match size {
            1 => (value & 0xff) * 0x0101_0101,
            2 => (value & 0xffff) * 0x0001_0001,
            _ => value,
        };
        self.io_live_at(cycle);
        let ok = self
            .io
            .as_mut()
            .is_some_and(|io| io.write(addr & !3, value));
        self.io_refresh();
        if ok {
            Ok(crate::io::AHB_PERIPHERAL_WAIT)
        } else {
            Err(BusFault { addr })
        }
    }

    /// After a write to the I/O's registers: the banks the DMA may reach now, and the fast
    /// path's banks with them.
    pub(crate) fn io_refresh(&mut self) {
        self.io_banks = self.io_control().map_or(0, |io| io.reach_banks());
        self.allowed_banks = self.fast_banks();
    }

    /// Whether the fast path may access SRAM offset `off` (below [`SRAM_SIZE`]) now
    /// ([`System::allowed_banks`]).
    #[inline(always)]
    pub(crate) fn allows(&self, off: u32) -> bool {
        self.allowed_banks == ALL_BANKS || (self.allowed_banks >> sram_bank(off)) & 1 != 0
    }

    /// Whether the fast path may access the `count` words from SRAM offset `off` now.
    #[inline(always)]
    pub(crate) fn allows_words(&self, off: u32, count: u32) -> bool {
        self.allowed_banks == ALL_BANKS || (0..count).all(|k| self.allows(off + 4 * k))
    }

    /// The memory slice and offset backing `addr`, for side-effect-free access (loader,
    /// harness, debugger). Covers ROM, flash and SRAM (both views).
    pub fn backing(&mut self, addr: u32) -> Option<(&mut [u8], usize)> {
        if let Some((off, _)) = sram_location(addr) {
            return Some((&mut self.sram, off));
        }
        let off = addr.wrapping_sub(FLASH_BASE);
        if off < FLASH_SIZE {
            return Some((&mut self.flash, off as usize));
        }
        if addr < ROM_SIZE {
            return Some((&mut self.rom, addr as usize));
        }
        None
    }

    /// Why an XIP access does not read the flash now, `None` when it does ([`Xip::xip_read`]
    /// with the programmed clk_sys).
    pub fn xip_error(&self) -> Option<String> {
        self.xip.xip_read(self.sysctl.clk_sys_hz()).err()
    }

    /// Recomputes [`System::xip_answers`] after an SSI or clock write; a change to "no"
    /// drops the decode cache, whose flash instructions must not run any more.
    pub(crate) fn refresh_xip(&mut self) {
        let answers = self.xip_error().is_none();
        if self.xip_answers && !answers {
            self.invalidate_code();
        }
        self.xip_answers = answers;
    }

    /// Puts back the SRAM words of an undo journal (`offset << 32 | old word` per store,
    /// oldest first), newest first: what a window's or a replay's stores did, undone
    /// (`crate::accel`). The caller drops decoded code if the stores may have changed it.
    pub fn undo_stores(&mut self, journal: &[u64]) {
        for &e in journal.iter().rev() {
            let off = (e >> 32) as usize;
            self.sram[off..off + 4].copy_from_slice(&(e as u32).to_le_bytes());
        }
    }

    /// Marks every cached instruction stale (self-modifying code, host writes).
    pub fn invalidate_code(&mut self) {
        self.code_epoch = self.code_epoch.wrapping_add(1);
        self.code_pages.fill(false);
    }

    /// Sets the last cycle in which `core` (0 or 1) claimed SRAM bank `bank` (0-5), as if
    /// it had accessed the bank then: for tests that put the arbiter in a given state.
    /// Out-of-range arguments are ignored.
    pub fn set_bank_claim(&mut self, core: usize, bank: usize, cycle: u64) {
        if let Some(c) = self.bank_claim.get_mut(bank).and_then(|b| b.get_mut(core)) {
            *c = cycle;
        }
    }

    /// Claims `bank` for `core` at `cycle`, returning the stall cycles.
    #[inline]
    fn arbitrate(&mut self, core: usize, cycle: u64, bank: usize) -> u32 {
        let other = self.bank_claim[bank][1 - core];
        let mut at = cycle;
        while other == at {
            at += 1;
        }
        self.bank_claim[bank][core] = at;
        let stall = (at - cycle) as u32;
        self.contention_stalls[core] += stall as u64;
        stall
    }

    /// Claims for `core` in data phase `cycle` the banks of the `n` words from plain SRAM
    /// offset `off` ([`plain_sram_span`]), as `n` [`System::arbitrate`]s of those words in
    /// order would: a word's claim and stall depend only on the other core's claim of its
    /// bank, which these claims do not change, so each bank is claimed once and its stall
    /// counted once for every word in it.
    #[inline(always)]
    fn arbitrate_span(&mut self, core: usize, cycle: u64, off: u32, n: u32) {
        let claim = |sys: &mut Self, bank: usize, words: u32| {
            if words > 0 {
                let stall = sys.arbitrate(core, cycle, bank);
                sys.contention_stalls[core] += u64::from(stall) * u64::from(words - 1);
            }
        };
        if off >= 0x4_0000 {
            // SRAM4/5: the words up to the 4 KiB boundary, then the rest.
            let first = ((0x1000 - (off & 0xfff)) / 4).min(n);
            claim(self, sram_bank(off), first);
            claim(self, sram_bank(off + 4 * first), n - first);
        } else {
            // Striped: word i is in the bank of word i mod 4.
            for i in 0..n.min(4) {
                claim(self, sram_bank(off + 4 * i), (n - i).div_ceil(4));
            }
        }
    }

    /// Stores `words` at plain SRAM offset `off` ([`plain_sram_span`], none of them in the
    /// I/O's banks) for `core` in data phase `cycle`, as that many word [`Bus::write`]s do:
    /// their claims and stalls ([`System::arbitrate_span`]), the data, and the decode cache
    /// invalidated once when any of them lands in a code page (the first such store would
    /// clear every code page, so the later ones find none).
    #[inline(always)]
    pub(crate) fn store_span(&mut self, core: usize, cycle: u64, off: u32, words: &[u32]) {
        let n = words.len() as u32;
        if n == 0 {
            return;
        }
        self.arbitrate_span(core, cycle, off, n);
        let bytes = &mut self.sram[off as usize..(off + 4 * n) as usize];
        for (b, w) in bytes.chunks_exact_mut(4).zip(words) {
            b.copy_from_slice(&w.to_le_bytes());
        }
        let (first, last) = (off >> 8, (off + 4 * n - 1) >> 8);
        if (first..=last).any(|p| self.code_pages[p as usize]) {
            self.invalidate_code();
        }
    }

    /// Loads `out.len()` words from plain SRAM offset `off` ([`plain_sram_span`], none of
    /// them in the I/O's banks) for `core` in data phase `cycle`, as that many word
    /// [`Bus::read`]s do: their claims and stalls, then the data.
    #[inline(always)]
    pub(crate) fn load_span(&mut self, core: usize, cycle: u64, off: u32, out: &mut [u32]) {
        let n = out.len() as u32;
        self.arbitrate_span(core, cycle, off, n);
        let bytes = &self.sram[off as usize..(off + 4 * n) as usize];
        for (w, b) in out.iter_mut().zip(bytes.chunks_exact(4)) {
            *w = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
    }

    /// Direct SRAM access for the executor's fast path (`off` from [`SRAM_BASE`], below
    /// [`SRAM_SIZE`], aligned to `size`): the same arbitration and data as [`Bus::read`]
    /// on the striped view or SRAM4/5, without the address decode. Returns (value, wait).
    #[inline(always)]
    pub(crate) fn sram_read(&mut self, core: usize, cycle: u64, off: u32, size: u32) -> (u32, u32) {
        let wait = self.arbitrate_fast(core, cycle, sram_bank(off));
        (load_le(&self.sram, off as usize, size), wait)
    }

    /// Direct SRAM store for the fast path, as [`Bus::write`] does it (arbitration, data,
    /// decode-cache invalidation for a page holding cached code). Returns the wait states.
    #[inline(always)]
    pub(crate) fn sram_write(
        &mut self,
        core: usize,
        cycle: u64,
        off: u32,
        size: u32,
        value: u32,
    ) -> u32 {
        let wait = self.arbitrate_fast(core, cycle, sram_bank(off));
        store_le(&mut self.sram, off as usize, size, value);
        if self.code_pages[(off >> 8) as usize] {
            self.invalidate_code();
        }
        wait
    }

    /// A side-effect-free word of SRAM at offset `off` (aligned, in range).
    #[inline(always)]
    pub(crate) fn sram_peek(&self, off: u32) -> u32 {
        load_le(&self.sram, off as usize, 4)
    }

    /// Direct flash load for the fast path (`off` from [`FLASH_BASE`], in range, aligned):
    /// flash never waits or contends.
    #[inline(always)]
    pub(crate) fn flash_read(&self, off: u32, size: u32) -> u32 {
        load_le(&self.flash, off as usize, size)
    }

    /// [`System::arbitrate`] with the loop written out: the other core's last claim is one
    /// cycle, so an access waits at most one cycle.
    #[inline(always)]
    fn arbitrate_fast(&mut self, core: usize, cycle: u64, bank: usize) -> u32 {
        let claims = &mut self.bank_claim[bank];
        let stall = (claims[(core ^ 1) & 1] == cycle) as u32;
        claims[core & 1] = cycle + stall as u64;
        self.contention_stalls[core & 1] += stall as u64;
        stall
    }

    /// Interrupt lines (bit n = IRQ n) as seen by `core` at cycle `now`.
    #[inline]
    pub fn irq_lines(&mut self, core: usize, now: u64) -> u32 {
        self.timer.update(now);
        let _ = core;
        self.current_irq_lines()
    }

    /// Interrupt lines without advancing the timer: what [`System::irq_lines`] returns at
    /// any cycle before [`Timer::next_event`].
    #[inline]
    pub(crate) fn current_irq_lines(&self) -> u32 {
        let mut lines = self.timer.irq_lines();
        if self.sio.irq(0) {
            lines |= 1 << SIO_IRQ_PROC0;
        }
        if self.sio.irq(1) {
            lines |= 1 << SIO_IRQ_PROC1;
        }
        lines
    }

    fn peripheral_read(&mut self, core: usize, cycle: u64, addr: u32) -> Option<u32> {
        if addr & 0xf000_0000 == SIO_BASE {
            // A FIFO read changes its status, hence the SIO interrupt lines.
            self.irq_epoch += 1;
            return self.sio.read(core, cycle, addr - SIO_BASE);
        }
        if addr & !0x3fff == TIMER_BASE {
            // A timer read changes no line, unless it fires an alarm that is due (the
            // timer's `update`); the sample interrupt reads the time twice per sample.
            if cycle >= self.timer.next_event {
                self.irq_epoch += 1;
            }
            return self.timer.read(cycle, addr & 0xfff);
        }
        if crate::io::Io::owns(addr) && self.io.is_some() {
            // IO_BANK0, BUSCTRL: the I/O as of this cycle.
            self.io_live_at(cycle);
            return self.io.as_mut()?.read(addr);
        }
        if addr & !0x3fff == WATCHDOG_BASE {
            return self.watchdog.read(cycle, addr & 0xffc);
        }
        // RESETS, clocks, PLL, XOSC, VREG: no interrupt lines.
        self.sysctl.read(addr)
    }

    /// The SSI's register at `addr` (any of its words), read at `cycle`.
    fn ssi_read(&mut self, cycle: u64, addr: u32) -> Option<u32> {
        self.xip.read(cycle, addr - XIP_SSI_BASE)
    }

    /// Writes the SSI's register at `addr` at `cycle`; false for no register.
    fn ssi_write(&mut self, cycle: u64, addr: u32, value: u32) -> bool {
        let ok = self
            .xip
            .write(cycle, addr - XIP_SSI_BASE, value, &self.flash);
        self.refresh_xip();
        ok
    }

    fn peripheral_write(&mut self, core: usize, cycle: u64, addr: u32, value: u32) -> bool {
        self.irq_epoch += 1;
        if addr & 0xf000_0000 == SIO_BASE {
            return self.sio.write(core, cycle, addr - SIO_BASE, value);
        }
        if addr & !0x3fff == TIMER_BASE {
            // Atomic aliases: +0x1000 XOR, +0x2000 SET, +0x3000 CLR (datasheet 2.1.2).
            let reg = addr & 0xfff;
            let alias = (addr >> 12) & 3;
            let value = if alias == 0 {
                value
            } else {
                let Some(old) = self.timer.read(cycle, reg) else {
                    return false;
                };
                match alias {
                    1 => old ^ value,
                    2 => old | value,
                    _ => old & !value,
                }
            };
            return self.timer.write(cycle, reg, value);
        }
        if crate::io::Io::owns(addr) && self.io.is_some() {
            self.io_live_at(cycle);
            let ok = self.io.as_mut().is_some_and(|io| io.write(addr, value));
            self.io_refresh();
            return ok;
        }
        if addr & !0x3fff == WATCHDOG_BASE {
            return self.watchdog.write(cycle, addr, value);
        }
        let was_held = self.sysctl.held_in_reset(resets::TIMER);
        let ok = self.sysctl.write(addr, value);
        if self.io.is_some() && clocks::block_of(addr) == Some(resets::RESETS_BASE) {
            // PIO0, PIO1, the DMA, IO_BANK0 and BUSCTRL follow RESETS.
            self.io_live_at(cycle);
            let held = self.sysctl.read(resets::RESETS_BASE).unwrap_or(0);
            if let Some(io) = self.io.as_mut() {
                io.set_resets(held);
            }
            self.io_refresh();
        }
        // The timer counts from its release from reset (datasheet 4.6: held in reset it
        // reads 0 and its alarms are disarmed).
        match (was_held, self.sysctl.held_in_reset(resets::TIMER)) {
            (false, true) => self.timer.hold(),
            (true, false) => self.timer.release(cycle),
            _ => {}
        }
        self.refresh_xip();
        ok
    }
}

impl Bus for System {
    #[inline(always)]
    fn read(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        size: u32,
    ) -> Result<(u32, u32), BusFault> {
        if let Some((off, bank)) = sram_location(addr) {
            let io = if self.io_banks >> bank & 1 != 0 {
                self.io_sram(core, cycle, bank)
            } else {
                0
            };
            let wait = io + self.arbitrate(core, cycle + u64::from(io), bank);
            return Ok((load_le(&self.sram, off, size), wait));
        }
        match addr >> 28 {
            0x5 if self.io.is_some() && crate::io::Io::owns(addr) => {
                // The DMA and the PIOs (AHB-Lite), as of this cycle.
                self.io_live_at(cycle);
                let io = self.io.as_mut().ok_or(BusFault { addr })?;
                match io.read(addr & !3) {
                    Some(v) => Ok((
                        v >> ((addr & 3) * 8) & (u32::MAX >> (32 - 8 * size)),
                        crate::io::AHB_PERIPHERAL_WAIT,
                    )),
                    None => Err(BusFault { addr }),
                }
            }
            0x0 if addr < ROM_SIZE => Ok((load_le(&self.rom, addr as usize, size), 0)),
            0x1 if addr - FLASH_BASE < FLASH_SIZE && self.xip_answers => {
                Ok((load_le(&self.flash, (addr - FLASH_BASE) as usize, size), 0))
            }
            0x1 if addr.wrapping_sub(XIP_SSI_BASE) < XIP_SSI_SIZE => {
                match self.ssi_read(cycle, addr & !3) {
                    Some(v) => Ok((
                        v >> ((addr & 3) * 8) & (u32::MAX >> (32 - 8 * size)),
                        APB_LOAD_WAIT,
                    )),
                    None => Err(BusFault { addr }),
                }
            }
            0x4 | 0xd => {
                let wait = if addr >> 28 == 4 { APB_LOAD_WAIT } else { 0 };
                // Peripherals are 32-bit registers; narrower loads see the low bits.
                match self.peripheral_read(core, cycle, addr & !3) {
                    Some(v) => Ok((v >> ((addr & 3) * 8) & (u32::MAX >> (32 - 8 * size)), wait)),
                    None => Err(BusFault { addr }),
                }
            }
            _ => Err(BusFault { addr }),
        }
    }

    #[inline(always)]
    fn write(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        size: u32,
        value: u32,
    ) -> Result<u32, BusFault> {
        if let Some((off, bank)) = sram_location(addr) {
            let io = if self.io_banks >> bank & 1 != 0 {
                self.io_sram(core, cycle, bank)
            } else {
                0
            };
            let wait = io + self.arbitrate(core, cycle + u64::from(io), bank);
            store_le(&mut self.sram, off, size, value);
            if self.code_pages[off >> 8] {
                self.invalidate_code();
            }
            return Ok(wait);
        }
        match addr >> 28 {
            0x5 if self.io.is_some() && crate::io::Io::owns(addr) => {
                self.io_store(cycle, addr, size, value)
            }
            0x4 | 0xd => {
                let wait = if addr >> 28 == 4 { APB_STORE_WAIT } else { 0 };
                // Narrow stores to 32-bit registers replicate the data across the word
                // (datasheet 2.1.4).
                let value = match size {
                    1 => (value & 0xff) * 0x0101_0101,
                    2 => (value & 0xffff) * 0x0001_0001,
                    _ => value,
                };
                if self.peripheral_write(core, cycle, addr & !3, value) {
                    Ok(wait)
                } else {
                    Err(BusFault { addr })
                }
            }
            0x1 if addr.wrapping_sub(XIP_SSI_BASE) < XIP_SSI_SIZE => {
                if self.ssi_write(cycle, addr & !3, value) {
                    Ok(APB_STORE_WAIT)
                } else {
                    Err(BusFault { addr })
                }
            }
            // ROM and flash are read-only to the cores (flash programming is not modelled).
            _ => Err(BusFault { addr }),
        }
    }

    /// Words in plain SRAM (the striped view or SRAM4/5, word-aligned, not crossing from
    /// one to the other: contiguous bytes of [`System::sram`]) outside the I/O's banks are
    /// stored in one go ([`System::store_span`]: the claims, stalls, data and code-page
    /// check of [`Bus::write`]); anything else takes the general path word by word.
    #[inline]
    fn write_words(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        words: &[u32],
    ) -> Result<(), BusFault> {
        let n = words.len() as u32;
        let Some(off) =
            plain_sram_span(addr, 4 * n).filter(|&off| span_banks(off, n) & self.io_banks == 0)
        else {
            return write_each_word(self, core, cycle, addr, words);
        };
        self.store_span(core, cycle, off, words);
        Ok(())
    }

    /// As [`System::write_words`]: plain SRAM directly, the rest word by word.
    #[inline]
    fn read_words(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        out: &mut [u32],
    ) -> Result<(), BusFault> {
        let n = out.len() as u32;
        let Some(off) =
            plain_sram_span(addr, 4 * n).filter(|&off| span_banks(off, n) & self.io_banks == 0)
        else {
            return read_each_word(self, core, cycle, addr, out);
        };
        self.load_span(core, cycle, off, out);
        Ok(())
    }

    #[inline]
    fn fetch(&mut self, addr: u32) -> Result<u16, BusFault> {
        if let Some((off, _)) = sram_location(addr) {
            return Ok(load_le(&self.sram, off, 2) as u16);
        }
        if addr < ROM_SIZE {
            return Ok(load_le(&self.rom, addr as usize, 2) as u16);
        }
        let off = addr.wrapping_sub(FLASH_BASE);
        if off < FLASH_SIZE && self.xip_answers {
            return Ok(load_le(&self.flash, off as usize, 2) as u16);
        }
        Err(BusFault { addr })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The general path: every word through [`Bus::write`] / [`Bus::read`] (the trait's
    /// provided `write_words` / `read_words`).
    struct WordByWord<'a>(&'a mut System);

    impl Bus for WordByWord<'_> {
        fn read(&mut self, c: usize, t: u64, a: u32, n: u32) -> Result<(u32, u32), BusFault> {
            self.0.read(c, t, a, n)
        }
        fn write(&mut self, c: usize, t: u64, a: u32, n: u32, v: u32) -> Result<u32, BusFault> {
            self.0.write(c, t, a, n, v)
        }
        fn fetch(&mut self, a: u32) -> Result<u16, BusFault> {
            self.0.fetch(a)
        }
    }

    /// Exception entry's and return's frames (and runs of 1 to 12 words) through
    /// [`System`]'s direct path equal the general path word by word: data, both cores'
    /// bank claims, stalls, the code epoch (a frame over a code page) and the fault of a
    /// frame that leaves memory.
    #[test]
    fn frames_equal_word_by_word() {
        let mut seed = 0x9e37_79b9u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        let frames = [
            0x2000_0000,
            0x2000_1008,
            0x2003_fff0, // crosses into SRAM4
            0x2004_0000,
            0x2004_0ff0, // crosses SRAM4 → SRAM5
            0x2004_0ffc, // crosses SRAM4 → SRAM5 after one word
            0x2004_1fe0,
            0x2004_1ff0, // leaves SRAM
            0x2100_0100, // the non-striped alias
            0x1000_0000, // flash: read-only
        ];
        for _ in 0..200 {
            let mut a = System::new(125_000_000);
            for bank in 0..BANKS {
                for core in 0..2 {
                    a.bank_claim[bank][core] = 100 + (next() % 4) as u64;
                }
            }
            let page = next() as usize % a.code_pages.len();
            a.code_pages[page] = true;
            a.code_pages[(0x1000 >> 8) + (next() as usize % 2)] = true;
            let mut b = a.clone();
            let frame = frames[next() as usize % frames.len()];
            let (core, cycle) = ((next() & 1) as usize, 100 + (next() % 4) as u64);
            // Mostly a frame's 8 words; also fewer (some striped banks only) and more.
            let n = if next() % 2 == 0 {
                8
            } else {
                1 + next() as usize % 12
            };
            let words: Vec<u32> = (0..n).map(|_| next()).collect();
            let ra = a.write_words(core, cycle, frame, &words);
            let rb = WordByWord(&mut b).write_words(core, cycle, frame, &words);
            assert_eq!(ra, rb);
            let mut wa = vec![0; n];
            let mut wb = vec![0; n];
            let other = if next() % 2 == 0 { core } else { 1 - core };
            let ra = a.read_words(other, cycle, frame, &mut wa);
            let rb = WordByWord(&mut b).read_words(other, cycle, frame, &mut wb);
            assert_eq!((ra, wa), (rb, wb), "frame {frame:#x}, {n} words");
            assert_eq!(a.sram, b.sram);
            assert_eq!(a.bank_claim, b.bank_claim);
            assert_eq!(a.contention_stalls, b.contention_stalls);
            assert_eq!(a.code_epoch, b.code_epoch);
            assert_eq!(a.code_pages, b.code_pages);
        }
    }
}
