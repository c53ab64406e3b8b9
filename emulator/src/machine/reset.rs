//! Resets of the chip while it runs: the watchdog's ([`crate::watchdog`]) and a brown-out.
//!
//! **What a reset keeps.** The watchdog's reset is the one pico-sdk's `watchdog_enable`
//! selects in PSM.WDSEL, every block but the oscillators (RP2040 datasheet 2.13 Power-on
//! state machine, 4.7): both cores restart, SIO (FIFOs, spinlocks, dividers), the timer,
//! RESETS, the clocks, PLL and VREG registers (`crate::clocks`) and on a board with
//! converters the PIOs, the DMA and IO_BANK0 go back to their power-on values; SRAM keeps
//! its contents, the watchdog its REASON and scratch registers, VREG_AND_CHIP_RESET its
//! CHIP_RESET (the source of the last chip-level reset: HAD_POR from the power-on). The converters at the pins
//! are other chips and keep their state, but the DACs are cleared (`Dac8568::clear`:
//! the board's CLR wiring). Not modelled: the SSI's reset on this path (the XIP window
//! stays as it was; a boot from flash sets it up again), the PSM's WDSEL register itself.
//! A brown-out ([`Machine::brown_out`]) is a power-on: SRAM and the watchdog lost too.
//!
//! **The boot path after it** is the boot ROM's (pico-bootrom `bootrom/bootrom_rt0.S`,
//! `check_wdog`, then `main` and `_flash_boot`): the watchdog entry when the scratch
//! registers hold one (`SCRATCH4` cleared, core 0 entered at `SCRATCH7` in Thumb state with
//! SP = `SCRATCH6`, VTOR 0), else boot from flash ([`Machine::boot_from_flash`] without the
//! power-on's SRAM pattern); when boot2 fails its check the ROM would start USB boot: core 0
//! stays parked (the board then stops, [`StopReason::Idle`]). Core 1 restarts in the boot
//! ROM's launch protocol.
//!
//! **The timer.** RESETS is reset with the rest, so it holds the timer (RESETS.RESET's
//! reset value holds every block, datasheet 2.14). The ROM's `main` pulses the timer's
//! reset (`reset_unreset_block_wait` of IO_QSPI, PADS_QSPI and TIMER) before it looks for
//! flash, so on that path the timer runs from the reset as from a power-on
//! ([`crate::timer::Timer::restart_as_at_power_on`]); the watchdog entry skips `main`, so
//! there the timer stays held until the firmware releases it through RESETS. The other
//! blocks' reset bits are not modelled (every block reads as out of reset,
//! [`crate::clocks::SysCtl`]).
//!
//! **When.** The chip resets when the core whose turn it is ([`Machine::next_core`]) is at
//! or past [`crate::watchdog::Watchdog::fire_at`]: each core is then at its first
//! instruction boundary at or after the firing, and both restart at the later of the two
//! cycles. Every engine stops there (`accel/run.rs` bounds its runs by `fire_at`).

use super::*;
use crate::watchdog::Reason;
use tactus_rp2040::resets::{self, RESETS_BASE};
use tactus_rp2040::{ATOMIC_CLR, ATOMIC_SET};

impl Machine {
    /// The watchdog fires (module documentation): the chip resets and boots again as the
    /// boot ROM does. Returns why it fired.
    pub(crate) fn watchdog_reset(&mut self) -> Reason {
        let at = self.reset_cycle();
        let reason = self.system.watchdog.fire(at);
        self.chip_reset(at);
        self.boot_again(at);
        reason
    }

    /// A brown-out: the supply dips below the chip's reset threshold at the board's cycle
    /// (the power-on reset, datasheet 2.12.3). Everything resets as at power-on — SRAM
    /// back to the power-on pattern ([`Machine::boot_from_flash`]), the watchdog with its
    /// scratch registers and REASON (its count of resets kept, for reports) — and the board
    /// boots from flash; a board whose firmware lived in SRAM only (a RAM image) is then
    /// in USB boot, as the chip would be. The DACs are cleared (a DAC8568 powers up at
    /// midscale, the board's 0 A).
    pub fn brown_out(&mut self) {
        let at = self.reset_cycle();
        self.system.watchdog.power_on();
        // CHIP_RESET.HAD_POR: "power-on reset or brown-out detection" (datasheet 2.12.7).
        self.system.sysctl = Default::default();
        self.fill_power_on_pattern();
        self.system.invalidate_code();
        self.chip_reset(at);
        self.boot_again(at);
    }

    /// A store to an I/O register (the PIOs', the DMA's) by the host between two runs, as a
    /// core's store there would make it (any alias, datasheet 2.1.2), at the later of the
    /// running cores' cycles: what a fault injection changes in the chip, such as a
    /// converter's state machine that stops (its `CTRL.SM_ENABLE` cleared). False without
    /// I/O, or for an address it does not own or a block held in reset.
    pub fn io_write(&mut self, addr: u32, value: u32) -> bool {
        let at = self.reset_cycle();
        self.system.io_unlazy();
        if self.system.io.is_none() {
            return false;
        }
        self.system.io_advance(at);
        let done = (self.system.io.as_deref_mut())
            .is_some_and(|io| io.accepts(addr) && io.write(addr, value));
        self.system.io_refresh();
        done
    }

    /// The later of the running cores' cycles (of all cores when none runs).
    fn reset_cycle(&self) -> u64 {
        let running = self.cores.iter().filter(|c| active(c)).map(|c| c.cycle);
        running
            .max()
            .unwrap_or(self.cores[0].cycle.max(self.cores[1].cycle))
    }

    /// Everything the reset selects back to power-on at cycle `at` (module documentation).
    fn chip_reset(&mut self, at: u64) {
        self.system.io_unlazy();
        if self.system.io.is_some() {
            self.system.io_advance(at);
            if let Some(io) = self.system.io.as_deref_mut() {
                io.chip_reset(at);
            }
            self.system.io_refresh();
        }
        for c in &mut self.cores {
            let clock_hz = c.nvic.clock_hz;
            *c = Core::new(c.id);
            c.cycle = at;
            c.nvic.clock_hz = clock_hz;
        }
        self.system.sio = Default::default();
        // A power-on's CHIP_RESET is the default's (HAD_POR); a watchdog reset keeps it.
        self.system.sysctl.watchdog_reset();
        // RESETS holds the timer (PSM.WDSEL selects RESETS): only the boot ROM's `main`
        // releases it ([`Machine::boot_again`]).
        self.system.timer.chip_reset();
        self.system
            .sysctl
            .write(RESETS_BASE + ATOMIC_SET + resets::reg::RESET, resets::TIMER);
        self.system.irq_epoch += 1;
        self.launch = Some(Launch::default());
        self.launch_handshake();
    }

    /// Core 0 into the boot ROM's path after a reset at cycle `at` (module documentation).
    fn boot_again(&mut self, at: u64) {
        if let Some((pc, sp)) = self.system.watchdog.take_boot_entry().filter(|e| e.0 != 0) {
            self.cores[0].reset_to(pc | 1, sp);
            self.cores[0].nvic.vtor = 0;
            return;
        }
        // The ROM's `main` pulses the timer's reset before it looks for flash: the timer
        // runs from here as it does from power-on.
        self.system
            .sysctl
            .write(RESETS_BASE + ATOMIC_CLR + resets::reg::RESET, resets::TIMER);
        self.system.timer.restart_as_at_power_on(at);
        if self.flash_boot().is_err() {
            // USB boot: nothing of the image runs.
            self.cores[0].state = RunState::Parked;
        }
    }
}
