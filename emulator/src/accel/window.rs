//! Windows: the two cores as independent machines over a stretch of cycles, with undo
//! journals.
//!
//! **Windows** ([`Config::own_banks`], block engine only). Lock-step turns last an
//! instruction or two, and every turn costs the scheduler. When the two cores touch
//! disjoint memory, nothing one does can change what the other sees, so the board runs
//! them one after the other instead, each over a whole *window* from where it is to E, the
//! first of the run's limit and the next timer event. Each core runs *alone*: compiled
//! code, pre-decoded blocks and the general path — exception entry and return, its own
//! private peripheral bus (NVIC, SysTick, SCB), its own SIO divider and CPUID — and sleep
//! in WFI or WFE up to its next wake-up (its own SysTick; the interrupt lines are those at
//! the window's start, since no timer event falls in it and no one touches a peripheral).
//! Each is *confined* to its own SRAM banks: every load, store, instruction fetch and
//! exception frame is checked, and a core stops at an instruction that touches anything
//! else (another bank, a peripheral, the FIFOs, the spinlocks), that signals (SEV), faults
//! or traps (SVC, BKPT), or whose store finds its undo journal full. Every store journals
//! the word it overwrites. If both cores reach E the window is kept;
//! otherwise both are put back as they were at its start — their stores undone from the
//! journals, newest first; their cores, bank claims, stalls, dividers and profiling
//! restored — and the lock-step loop runs the stretch instead (for [`RETRY`] cycles before
//! the next window).
//!
//! *Why this is the lock-step result.* In a kept window each core touched only its own
//! banks and its own private state, and neither touched a shared peripheral or signalled
//! the other. So no word or register either core reads is written by the other; the
//! interrupt lines cannot change (no peripheral is touched and no timer event falls before
//! E); a sleeping core wakes only by its own SysTick, its own event register or those
//! lines. An access's arbitration depends only on the other core's last claim of the
//! *same* bank, which the other core does not change in the window. The instructions of
//! the two cores therefore commute, and running all of one core's before all of the
//! other's gives the registers, memory, cycles, stalls, exceptions and sleeps of the
//! interleaved order. The window ends where a lock-step run would stop too — the run's
//! limit or a timer event, at which a sleeping core's cycle counter is that limit in both
//! (in between, the lock-step loop moves a sleeper's counter along with the other core's
//! instructions, which a window does not reproduce: hence no window ends anywhere else,
//! and one that cannot reach E is undone whole, with the instruction that was not confined
//! or that signalled, faulted or trapped).
//!
//! On a board with converters (`crate::io`) the banks its DMA may reach are the cores' own
//! too: there their accesses are logged and the I/O replays them after the cores' run, the
//! window undone where the lock-step run would have differed (`accel/io_window/`).
//!
//! *Meetings.* Core 0 runs first. When it stops at a single load it cannot make confined
//! at cycle C (a word of core 1's banks: the firmware's watchdog feed reads core 1's
//! sample count), which it finds before running the load (its one access would be
//! refused), core 1 runs to C: both then stand at their first instruction
//! boundary at or after C, as a lock-step run to C leaves them, so the load, which goes
//! first in lock-step order (core 0 at C, core 1 at or after it), runs there with core 1's
//! banks readable and reads what the lock-step run would (core 1's stores before C, its
//! bank claims); core 0 then goes on alone to E and core 1 from C to E. Only loads of
//! SRAM: a store into the other core's banks would interleave the two undo journals, and
//! a peripheral's load (its state may depend on more than time) undoes the window.
//!
//! *The watchdog.* A firmware feeds the watchdog once a sample (a store to its LOAD or
//! CTRL), so a store to the watchdog's registers does not end a window: it is applied at
//! once, at its cycle, as the lock-step machine would, when one core alone writes the
//! watchdog in the window (two cores' writes would land in the order the cores ran, not
//! the lock-step order: the second core's first write undoes the window) and the firing
//! stays at or after E (else the lock-step run would have reset the chip inside the
//! window: undone). The watchdog as it was before the window's first write is kept
//! ([`Feeds`]) and put back with an undone window. Reads of the watchdog's count still
//! end a window (the other core may have run past the write).
//!
//! On the firmware images each core's code, data, stack and sensor and DAC window words
//! lie in its own banks, so a window spans a whole sample period of both cores' sample
//! interrupts (`tactus-firmware`, `image/mod.rs`). Tests: `tests/block_engine.rs` (random
//! two-core programs on own banks with shared, other-bank and SIO traffic, SysTick,
//! WFI/WFE/SEV; the own-bank speed loop; self-modifying code), `firmware/tests/image.rs`
//! (an image of every shipped instrument, both cores) and `firmware/tests/keyboard_exact.rs`
//! (every board of grand88 and the split layout against the lock-step interpreter).

use super::decode::cached;
use super::io_window::{IoKind, IoLog};
use super::*;
use crate::accel::block::{self, Leave};
use crate::accel::memo::Recording;
use crate::bus::{plain_sram_span, span_banks, Bus, BusFault, ALL_BANKS};
use crate::core::Event;
use crate::nvic::IRQ0;
use crate::watchdog::Watchdog;
use tactus_rp2040::memory::{sram_location, FLASH_BASE, FLASH_SIZE, ROM_SIZE};
use tactus_rp2040::sio::{reg, SIO_BASE};
use tactus_rp2040::watchdog::WATCHDOG_BASE;

/// What a window ([`Board::window`]) did.
pub(super) enum Window {
    /// Both cores reached its end.
    Kept,
    /// Nothing ran: the window was undone, or would be too short.
    Idle,
}

/// Fewest cycles a window may span.
pub(super) const MIN_WINDOW: u64 = 64;

/// Lock-step cycles after a window in which nothing or little ran, before the next.
pub(super) const RETRY: u64 = 4096;

/// Most undo-journal entries of one window: a store that finds it full stops the core.
const JOURNAL: usize = 1 << 16;

/// A window's writes to the watchdog (module documentation, "The watchdog").
#[derive(Default)]
pub(super) struct Feeds {
    /// The window's end E: a write that brings the firing before it undoes the window.
    end: u64,
    /// The core that wrote the watchdog in this window, if any.
    writer: Option<usize>,
    /// The watchdog before the window's first write, put back when it is undone.
    saved: Option<Watchdog>,
}

impl Feeds {
    /// Whether core `core` may write the watchdog `wd` now: the first writer of the
    /// window (the watchdog kept as it was, to undo), or the same core again.
    fn admit(&mut self, core: usize, wd: &Watchdog) -> bool {
        match self.writer {
            None => {
                self.writer = Some(core);
                self.saved = Some(wd.clone());
                true
            }
            Some(w) => w == core,
        }
    }
}

/// A core's state at some moment of a window, for undoing what it did since: the machine's
/// snapshot of it ([`crate::machine::CoreSnapshot`]) and where its undo journal was.
struct Saved {
    snap: crate::machine::CoreSnapshot,
    journal: usize,
}

/// The bus as a core in a window sees it ([`Board::window`]): its allowed SRAM banks, ROM
/// and flash, its own SIO registers (CPUID, the divider); any other access is refused —
/// a bus fault to the executor, which the caller undoes — and marked `foreign`. Stores
/// into SRAM are journaled, when there is a journal.
struct Confined<'a> {
    sys: &'a mut System,
    banks: u8,
    /// The SRAM banks it may load from: `banks`, or at a meeting also the other core's
    /// (module documentation, "Meetings").
    readable: u8,
    journal: &'a mut Vec<u64>,
    foreign: bool,
    /// A call being recorded ([`crate::accel::memo`]): its SRAM accesses are logged, any other
    /// access spoils it.
    log: Option<&'a mut Recording>,
    /// On a board with an I/O (`accel/io_window/`): the accesses the I/O's replay needs.
    io: Option<IoLog<'a>>,
    /// The window's writes to the watchdog.
    feeds: &'a mut Feeds,
}

impl Confined<'_> {
    /// Whether SRAM offset `off`'s bank is allowed.
    #[inline(always)]
    fn bank_ok(&self, bank: usize) -> bool {
        self.banks >> bank & 1 != 0
    }

    /// Whether a load or store at `addr` (not SRAM) stays within the core: ROM and flash
    /// (loads; a store faults, which stops the core anyway), its own SIO registers.
    #[inline(always)]
    fn private(addr: u32) -> bool {
        match addr >> 28 {
            0x0 => addr < ROM_SIZE,
            0x1 => addr.wrapping_sub(FLASH_BASE) < FLASH_SIZE,
            0xd => {
                let off = (addr & !3).wrapping_sub(SIO_BASE);
                off == reg::CPUID || (reg::DIV_UDIVIDEND..=reg::DIV_CSR).contains(&off)
            }
            _ => false,
        }
    }

    fn refuse(&mut self, addr: u32) -> BusFault {
        self.foreign = true;
        BusFault { addr }
    }

    /// Whether SRAM bank `bank` is one the I/O's DMA may reach (its accesses are logged).
    #[inline(always)]
    fn io_bank(&self, bank: usize) -> bool {
        self.io.as_ref().is_some_and(|l| l.banks >> bank & 1 != 0)
    }

    /// The plain SRAM offset of the `n` words from `addr` when they can move in one go: a
    /// [`plain_sram_span`] in allowed banks, none of them the I/O's (logged, or served by
    /// [`System`]'s I/O), and no call being recorded (whose log needs each access).
    #[inline(always)]
    fn span(&self, addr: u32, n: u32) -> Option<u32> {
        let off = plain_sram_span(addr, 4 * n)?;
        let banks = span_banks(off, n);
        let io = self.io.as_ref().map_or(0, |l| l.banks) | self.sys.io_banks;
        (self.log.is_none() && banks & !self.banks == 0 && banks & io == 0).then_some(off)
    }
}

impl Bus for Confined<'_> {
    fn read(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        size: u32,
    ) -> Result<(u32, u32), BusFault> {
        let Some((off, bank)) = sram_location(addr) else {
            if !Self::private(addr) {
                return Err(self.refuse(addr));
            }
            let r = self.sys.read(core, cycle, addr, size);
            if let Some(rec) = self.log.as_deref_mut() {
                rec.spoil();
            }
            return r;
        };
        if self.readable >> bank & 1 == 0 {
            return Err(self.refuse(addr));
        }
        let r = self.sys.read(core, cycle, addr, size);
        if let Ok((value, _)) = r {
            if self.io_bank(bank) {
                if let Some(l) = self.io.as_mut() {
                    let a = l.push(cycle, IoKind::Load, off as u32, size, value, 0);
                    if let Some(rec) = self.log.as_deref_mut() {
                        rec.io_access(a);
                    }
                }
            }
        }
        if let Some(rec) = self.log.as_deref_mut() {
            match r {
                Ok((value, _)) => {
                    let code = self.sys.code_pages[off >> 8];
                    rec.load(off as u32, size, value, code);
                }
                _ => rec.spoil(),
            }
        }
        r
    }

    fn write(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        size: u32,
        value: u32,
    ) -> Result<u32, BusFault> {
        match sram_location(addr) {
            Some((off, bank)) => {
                if !self.bank_ok(bank) {
                    return Err(self.refuse(addr));
                }
                if self.journal.len() >= JOURNAL {
                    return Err(self.refuse(addr));
                }
                let word = off & !3;
                let old = self.sys.sram_peek(word as u32);
                self.journal.push((word as u64) << 32 | old as u64);
                if self.io_bank(bank) {
                    if let Some(l) = self.io.as_mut() {
                        let a = l.push(cycle, IoKind::Store, off as u32, size, value, old);
                        if let Some(rec) = self.log.as_deref_mut() {
                            rec.io_access(a);
                        }
                    }
                }
            }
            None if addr >> 28 == 0x5
                && self.io.is_some()
                && self.sys.io_control().is_some_and(|io| io.accepts(addr)) =>
            {
                // A store to the DMA's or the PIOs' registers: applied by the replay, at
                // its place among the DMA's accesses (`System::io_store`).
                if let Some(l) = self.io.as_mut() {
                    l.push(cycle, IoKind::Reg, addr, size, value, 0);
                }
                if let Some(rec) = self.log.as_deref_mut() {
                    rec.spoil();
                }
                return Ok(crate::io::AHB_PERIPHERAL_WAIT);
            }
            None if addr & !0x3fff == WATCHDOG_BASE => {
                // A feed (module documentation, "The watchdog"): one core's, at its cycle.
                if !self.feeds.admit(core, &self.sys.watchdog) {
                    return Err(self.refuse(addr));
                }
                if let Some(rec) = self.log.as_deref_mut() {
                    rec.spoil();
                }
                let r = self.sys.write(core, cycle, addr, size, value);
                if self.sys.watchdog.fire_at < self.feeds.end {
                    self.foreign = true; // it fires inside the window: undone
                }
                return r;
            }
            None if !Self::private(addr) => return Err(self.refuse(addr)),
            None => {}
        }
        let r = self.sys.write(core, cycle, addr, size, value);
        if let Some(rec) = self.log.as_deref_mut() {
            match (sram_location(addr), r) {
                (Some((off, _)), Ok(_)) => rec.store(off as u32, size),
                _ => rec.spoil(),
            }
        }
        r
    }

    /// Exception entry's frame: when it can move in one go ([`Confined::span`]) and the
    /// journal has room, journaled and stored in one go ([`System::store_span`]); else word
    /// by word.
    fn write_words(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        words: &[u32],
    ) -> Result<(), BusFault> {
        let n = words.len() as u32;
        match self.span(addr, n) {
            Some(off) if self.journal.len() + words.len() <= JOURNAL => {
                let sram = &self.sys.sram[off as usize..(off + 4 * n) as usize];
                // An exact-size iterator: the journal grows once, not per entry.
                self.journal
                    .extend(sram.chunks_exact(4).enumerate().map(|(i, b)| {
                        let o = off as u64 + 4 * i as u64;
                        o << 32 | u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64
                    }));
                self.sys.store_span(core, cycle, off, words);
                Ok(())
            }
            _ => {
                for (i, &w) in words.iter().enumerate() {
                    self.write(core, cycle, addr.wrapping_add(4 * i as u32), 4, w)?;
                }
                Ok(())
            }
        }
    }

    /// Exception return's frame: in one go ([`System::load_span`]) when it can move in one
    /// go ([`Confined::span`]); else word by word.
    fn read_words(
        &mut self,
        core: usize,
        cycle: u64,
        addr: u32,
        out: &mut [u32],
    ) -> Result<(), BusFault> {
        match self.span(addr, out.len() as u32) {
            Some(off) => {
                self.sys.load_span(core, cycle, off, out);
                Ok(())
            }
            _ => {
                for (i, w) in out.iter_mut().enumerate() {
                    *w = self
                        .read(core, cycle, addr.wrapping_add(4 * i as u32), 4)?
                        .0;
                }
                Ok(())
            }
        }
    }

    fn fetch(&mut self, addr: u32) -> Result<u16, BusFault> {
        if let Some(rec) = self.log.as_deref_mut() {
            // Only the general path fetches through the bus (exception entry, a fault).
            rec.spoil();
        }
        if let Some((_, bank)) = sram_location(addr) {
            // Code in the DMA's banks is not run ahead of it.
            if !self.bank_ok(bank) || self.io_bank(bank) {
                return Err(self.refuse(addr));
            }
        }
        self.sys.fetch(addr)
    }
}

impl Drive<'_> {
    /// Whether the cores may run in windows now: the block engine, disjoint own banks,
    /// core 1 launched, no address watched for profiling, no I/O attached or one whose DMA
    /// wins the banks against both cores (`accel/io_window/`: its accesses then do not
    /// depend on the cores'), both cores running or asleep.
    pub(super) fn windows_allowed(&self) -> bool {
        let [a, b] = self.cfg.own_banks;
        self.cfg.engine == Engine::Block
            && a & ALL_BANKS != 0
            && b & ALL_BANKS != 0
            && a & b == 0
            && self.m.launch.is_none()
            && self.prof.watch_free
            && self
                .m
                .system
                .io
                .as_ref()
                .is_none_or(|io| io.dma_wins(0) && io.dma_wins(1))
            && self
                .m
                .cores
                .iter()
                .all(|c| matches!(c.state, RunState::Running | RunState::Sleeping { .. }))
    }

    fn save(&self, k: usize, journal: usize) -> Saved {
        Saved {
            snap: self.m.snapshot_core(k),
            journal,
        }
    }

    /// Puts core `k` back as `saved`, undoing the stores journaled since, and its
    /// profiling with it.
    fn restore(&mut self, k: usize, saved: Saved, journal: &mut Vec<u64>) {
        let from = saved.journal.min(journal.len());
        self.m.restore_core(k, saved.snap, &journal[from..]);
        journal.truncate(from);
        let mark = std::mem::take(&mut self.prof.marks[k]);
        self.prof.restore(k, &mark);
        self.prof.marks[k] = mark;
    }

    /// One window (module documentation), the run's `limit` bounding it.
    pub(super) fn window(&mut self, limit: u64) -> Window {
        let start = self.m.cores[0].cycle.min(self.m.cores[1].cycle);
        let end = limit.min(self.m.system.timer.next_event);
        if start.saturating_add(MIN_WINDOW) > end {
            return Window::Idle;
        }
        let lines = self.m.system.current_irq_lines();
        let mut journals = [
            std::mem::take(&mut self.a.blocks.journal),
            std::mem::take(&mut self.a.blocks.journal_other),
        ];
        for j in &mut journals {
            j.clear();
        }
        let saved = [self.save(0, 0), self.save(1, 0)];
        for k in 0..2 {
            let mut mark = std::mem::take(&mut self.prof.marks[k]);
            self.prof.mark(k, &mut mark);
            self.prof.marks[k] = mark;
        }
        let io = self.io_window_begin(start, end);
        self.a.feeds = Feeds {
            end,
            writer: None,
            saved: None,
        };
        let mut kept = true;
        self.a.cut = None;
        let own = self.cfg.own_banks.map(|b| b & ALL_BANKS);
        let [j0, j1] = &mut journals;
        // Core 0 to the window's end, meeting core 1 at each load it cannot make confined
        // (module documentation, "Meetings").
        while !self.run_alone(0, end, lines, own[0], own[0], j0) {
            let Some(c) = self.a.cut.take() else {
                kept = false;
                break;
            };
            if !self.run_alone(1, c, lines, own[1], own[1], j1) {
                kept = false;
                break;
            }
            // Both stand as a lock-step run to C leaves them: core 0's load goes first,
            // core 1's banks readable.
            if self.step_confined(0, lines, own[0], own[0] | own[1], j0, None) {
                if !self.prof.is_empty() {
                    self.prof.step(0, &self.m.cores[0]);
                }
                continue;
            }
            // Not a load of SRAM (a peripheral's): undone.
            kept = false;
            break;
        }
        if kept && !self.run_alone(1, end, lines, own[1], own[1], j1) {
            kept = false;
        }
        if let Some(io) = io {
            kept = self.io_window_end(io, kept);
        }
        if !kept {
            // Newest first: core 1's stores, then core 0's.
            for (k, s) in saved.into_iter().enumerate().rev() {
                self.restore(k, s, &mut journals[k]);
            }
            if let Some(wd) = self.a.feeds.saved.take() {
                self.m.system.watchdog = wd;
            }
        }
        self.a.windows[if kept { 0 } else { 1 }] += 1;
        let [j0, j1] = journals;
        self.a.blocks.journal = j0;
        self.a.blocks.journal_other = j1;
        if kept {
            Window::Kept
        } else {
            Window::Idle
        }
    }

    /// Runs core `k` alone, confined to SRAM banks `banks`, while its cycle is below
    /// `until` (it stops at its first instruction boundary at or after `until`) with the
    /// interrupt lines `lines`; stores are journaled into `journal` when given. True when
    /// it reached `until`; false when it stopped before an instruction it cannot run
    /// confined (module documentation), with nothing of that instruction done.
    fn run_alone(
        &mut self,
        k: usize,
        until: u64,
        lines: u32,
        banks: u8,
        readable: u8,
        journal: &mut Vec<u64>,
    ) -> bool {
        let pending_lines = (lines as u64) << IRQ0;
        loop {
            let core = &mut self.m.cores[k];
            let now = core.cycle;
            if now >= until {
                return true;
            }
            match core.state {
                RunState::Running => {}
                RunState::Sleeping { wfe } => {
                    // As `Board::step`: wake, or skip to the next cycle at which something
                    // could wake the core (no timer event falls before `until`).
                    if (wfe && core.event) || core.wakes_from_sleep(lines) {
                        if wfe {
                            core.event = false;
                        }
                        core.state = RunState::Running;
                    } else {
                        let next = self
                            .m
                            .system
                            .timer
                            .next_event
                            .min(core.nvic.syst_next)
                            .min(until);
                        core.cycle = next.max(now + 1);
                    }
                    continue;
                }
                _ => return false,
            }
            // A SysTick whose count reached 0 at or before `now` (the wrap that pended the
            // exception being handled: it reloads on the next count) first brings its next
            // wrap up to date, as the general step's exception check would at this cycle;
            // else the handler's first instruction would take the general path.
            if core.nvic.syst_next <= now {
                core.nvic.tick(now);
            }
            // The fast path, where `Board::fast_ready` would allow it.
            if core.thumb
                && core.nvic.takeable() == 0
                && pending_lines & !core.nvic.active & !core.nvic.pending == 0
            {
                let deadline = until.min(core.nvic.syst_next);
                if now < deadline {
                    let sys = &mut self.m.system;
                    // Not the DMA's banks: their accesses go through `Confined`, logged.
                    sys.allowed_banks = banks & !self.a.io_window.unwrap_or(0);
                    let native = match self.a.io_native {
                        true => banks & self.a.io_window.unwrap_or(0),
                        false => 0,
                    };
                    let io = self
                        .a
                        .io_window
                        .map(|l| (&mut self.a.io_logs[k], l, native));
                    let r = block::run_confined(
                        core,
                        sys,
                        &mut self.a.blocks,
                        deadline,
                        Some(&mut *journal),
                        io,
                    );
                    sys.allowed_banks = sys.fast_banks();
                    match r {
                        Ok(()) => continue,
                        Err(Leave::Record) => {
                            if !self.record_call(k, deadline, lines, banks, readable, journal) {
                                return false;
                            }
                            continue;
                        }
                        Err(Leave::General | Leave::Miss) => {}
                    }
                    if self.m.cores[k].cycle >= until {
                        return true;
                    }
                }
            }
            if !self.step_confined(k, lines, banks, readable, journal, None) {
                return false;
            }
            if !self.prof.is_empty() {
                self.prof.step(k, &self.m.cores[k]);
            }
        }
    }

    /// Runs the call core `k` is about to make (its PC at a watched entry, [`crate::accel::memo`])
    /// one general step at a time as [`Board::run_alone`] would, recording it, until it
    /// returns (the memo is kept), something a memo cannot hold happens or the core reaches
    /// `deadline` (the recording is given up; the core has run exactly as without it).
    /// False as [`Board::step_confined`]: the window is undone.
    fn record_call(
        &mut self,
        k: usize,
        deadline: u64,
        lines: u32,
        banks: u8,
        readable: u8,
        journal: &mut Vec<u64>,
    ) -> bool {
        let mut rec = self.a.blocks.memo.begin(&self.m.cores[k], &self.m.system);
        rec.io_banks = self.a.io_window.unwrap_or(0);
        // A watched function's call inside the recorded one (a key's update in a span) is
        // taken from its memo where one applies, as `block::run_confined` would, with the
        // memo's accesses logged as the call's (`Recording::nest`): no access can wait once
        // the core is past the other core's last claim of its banks, which the other core
        // does not touch meanwhile.
        let nesting = self.a.io_window.is_none();
        let quiet_from = crate::accel::block::quiet_from(&self.m.system, k, banks);
        loop {
            let core = &self.m.cores[k];
            if rec.returned(core) {
                self.a.blocks.memo.finish(rec, core, &self.m.system);
                return true;
            }
            let general =
                core.nvic.takeable() != 0 || core.nvic.syst_next <= core.cycle || !core.thumb;
            if core.cycle >= deadline || general {
                self.a.blocks.memo.abandon(rec);
                return true;
            }
            let pc = core.r[15];
            if nesting && core.cycle >= quiet_from && self.a.blocks.memo.watches(pc) {
                let tried = self.a.blocks.memo.call::<true>(
                    &mut self.m.cores[k],
                    &mut self.m.system,
                    deadline,
                    true,
                    banks,
                    Some(&mut *journal),
                    None,
                    Some(&mut rec),
                );
                if tried == crate::accel::memo::Try::Applied {
                    continue;
                }
            }
            let admitted = match cached(&mut self.a.cache, &mut self.m.system, pc) {
                Some((instr, size, _)) => rec.admit(&self.m.cores[k], &instr, size),
                None => false,
            };
            if !admitted {
                self.a.blocks.memo.abandon(rec);
                return true;
            }
            if !self.step_confined(k, lines, banks, readable, journal, Some(&mut rec)) {
                self.a.blocks.memo.abandon(rec);
                return false;
            }
            if !self.prof.is_empty() {
                self.prof.step(k, &self.m.cores[k]);
            }
            if !rec.after(&self.m.cores[k]) {
                self.a.blocks.memo.abandon(rec);
                return true;
            }
        }
    }

    /// One general step of core `k` (as [`Board::step_cached`]) on the [`Confined`] bus;
    /// false when it was not confined or had an event (the caller undoes the whole window).
    fn step_confined(
        &mut self,
        k: usize,
        lines: u32,
        banks: u8,
        readable: u8,
        journal: &mut Vec<u64>,
        log: Option<&mut Recording>,
    ) -> bool {
        let pc = self.m.cores[k].r[15];
        let core = &mut self.m.cores[k];
        if lines != 0 {
            core.nvic.pending |= ((lines as u64) << IRQ0) & !core.nvic.active;
        }
        let general = core.nvic.takeable() != 0 || core.nvic.syst_next <= core.cycle || !core.thumb;
        // The instruction's fetch is confined too (and not from the DMA's banks).
        let io_banks = self.a.io_window.unwrap_or(0);
        let fetched = if general {
            None
        } else {
            let in_banks = |a: u32| {
                sram_location(a).is_none_or(|(_, bank)| (banks & !io_banks) >> bank & 1 != 0)
            };
            match cached(&mut self.a.cache, &mut self.m.system, pc) {
                Some(d) if in_banks(pc) && in_banks(pc.wrapping_add(d.1 - 2)) => Some(d),
                Some(_) => return false,
                None => None,
            }
        };
        let start = core.cycle;
        // Core 0 runs first: at a single load of SRAM it may not read it meets core 1
        // (module documentation, "Meetings"). The load's only access would be refused, so
        // nothing of it runs: the core stands before it for the meeting.
        let cut = k == 0
            && fetched.is_some_and(|(instr, ..)| {
                let r = &self.m.cores[0].r;
                let addr = match instr {
                    tactus_isa::decode::Instr::MemImm { op, rn, imm, .. } if !op.is_store() => {
                        r[rn as usize].wrapping_add(u32::from(imm))
                    }
                    tactus_isa::decode::Instr::MemReg { op, rn, rm, .. } if !op.is_store() => {
                        r[rn as usize].wrapping_add(r[rm as usize])
                    }
                    _ => return false,
                };
                sram_location(addr).is_some_and(|(_, bank)| readable >> bank & 1 == 0)
            });
        if cut {
            self.a.cut = Some(start);
            return false;
        }
        let core = &mut self.m.cores[k];
        let mut bus = Confined {
            sys: &mut self.m.system,
            banks,
            readable,
            journal,
            foreign: false,
            log,
            io: self.a.io_window.map(|banks| IoLog {
                banks,
                start,
                log: &mut self.a.io_logs[k],
            }),
            feeds: &mut self.a.feeds,
        };
        let event = match fetched {
            Some((instr, size, cost)) => {
                core.run_priced::<_, false>(&mut bus, pc, instr, size, Some(cost))
            }
            None => core.step(&mut bus, lines),
        };
        !bus.foreign && event == Event::None
    }
}

impl Accel {
    /// [`crate::Board::run_ahead_windows`].
    pub(crate) fn run_ahead_windows(&self) -> (u64, u64) {
        (self.windows[0], self.windows[1])
    }
}
