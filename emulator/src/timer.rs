//! The RP2040 system timer (0x40054000, RP2040 datasheet section 4.6).
//!
//! The real timer counts microseconds from a 1 MHz tick. We derive the count from the
//! emulated cycle (`us = cycle * 1_000_000 / clock_hz`) instead of ticking it, and turn each
//! armed alarm into the cycle at which it fires, so the board only has to compare the current
//! cycle with [`Timer::next_event`]. A 44.1 kHz sample tick is paced by advancing ALARM0 by 22
//! or 23 µs alternately (mean 22.676 µs) in the alarm's interrupt handler.
//!
//! **Reset.** RESETS holds the timer in reset or releases it (`crate::clocks`; the bus
//! calls [`Timer::hold`] and [`Timer::release`]): held, it reads 0 and its alarms and
//! interrupts are cleared; released at cycle *r*, it counts the microsecond ticks after *r*
//! (the ticks come from the watchdog's tick generator, which runs on: the count is the
//! ticks since power-on minus those up to *r*). At power-on it runs, as the boot ROM leaves
//! it (it pulses the timer's reset, pico-bootrom `bootrom_main.c`, `main`). After a
//! watchdog reset it is held until that pulse, or, when the boot ROM takes the watchdog
//! entry and skips `main`, until the firmware releases it (`crate::machine`'s `reset.rs`).

use tactus_rp2040::timer::reg;

/// Timer state.
#[derive(Clone, Debug)]
pub struct Timer {
    clock_hz: u64,
    /// Microseconds added by writes to TIMELW/TIMEHW (time = offset + cycle-derived count).
    offset: u64,
    latched_high: u32,
    written_low: u32,
    alarm: [u32; 4],
    /// Cycle at which each armed alarm fires (u64::MAX when disarmed).
    fire_at: [u64; 4],
    intr: u32,
    inte: u32,
    intf: u32,
    /// Earliest `fire_at`.
    pub next_event: u64,
    /// Held in reset by RESETS.
    in_reset: bool,
    /// Cycle of the last release from reset (`None` before any).
    released_at: Option<u64>,
    /// Reads of the count (TIMEHR, TIMELR, TIMERAWH, TIMERAWL) so far: the only registers
    /// whose value depends on the absolute time, so a run that made none is unchanged by a
    /// shift of its start by whole microseconds (`Board::skip_periods`).
    pub count_reads: u64,
}

impl Timer {
    /// A timer for a system clocked at `clock_hz`.
    pub fn new(clock_hz: u64) -> Self {
        Timer {
            clock_hz,
            offset: 0,
            latched_high: 0,
            written_low: 0,
            alarm: [0; 4],
            fire_at: [u64::MAX; 4],
            intr: 0,
            inte: 0,
            intf: 0,
            next_event: u64::MAX,
            in_reset: false,
            released_at: None,
            count_reads: 0,
        }
    }

    /// RESETS holds the timer in reset: its count, alarms and interrupts are cleared.
    pub fn hold(&mut self) {
        *self = Timer {
            in_reset: true,
            released_at: self.released_at,
            count_reads: self.count_reads,
            ..Timer::new(self.clock_hz)
        };
    }

    /// RESETS releases the timer at cycle `now`: it counts the microsecond ticks from
    /// there, from 0.
    pub fn release(&mut self, now: u64) {
        self.in_reset = false;
        self.released_at = Some(now);
        self.offset = 0;
        self.offset = 0u64.wrapping_sub(self.micros(now));
    }

    /// A chip reset (`crate::machine`, the watchdog's): RESETS holds the timer as
    /// [`Timer::hold`] does, and no release by the firmware is recorded since.
    pub(crate) fn chip_reset(&mut self) {
        self.hold();
        self.released_at = None;
    }

    /// The boot ROM's pulse of the timer's reset at cycle `now` (after a chip reset,
    /// `crate::machine`): it counts from 0 there, and like at power-on no release by the
    /// firmware is recorded ([`Timer::released_at`] is `None`).
    pub(crate) fn restart_as_at_power_on(&mut self, now: u64) {
        self.release(now);
        self.released_at = None;
    }

    /// The cycle of the firmware's last release of the timer from reset, `None` while it
    /// runs as the boot ROM left it (since power-on or the last chip reset).
    pub fn released_at(&self) -> Option<u64> {
        self.released_at
    }

    /// First cycle at which the count reaches `us` (as the timer runs now: a later release
    /// from reset moves it).
    pub fn cycle_at_us(&self, us: u64) -> u64 {
        self.cycle_of(us)
    }

    /// Microsecond count at cycle `now`.
    pub fn micros(&self, now: u64) -> u64 {
        // The same quotient in 64 bits while the product fits (the first 5 hours at
        // 1 GHz): a 128-bit division is a library call.
        let us = match now.checked_mul(1_000_000) {
            Some(p) => p / self.clock_hz,
            None => ((now as u128 * 1_000_000) / self.clock_hz as u128) as u64,
        };
        self.offset.wrapping_add(us)
    }

    /// First cycle at which the count reaches `us`.
    fn cycle_of(&self, us: u64) -> u64 {
        let rel = us.wrapping_sub(self.offset);
        match rel.checked_mul(self.clock_hz) {
            Some(p) => p.div_ceil(1_000_000),
            None => (rel as u128 * self.clock_hz as u128).div_ceil(1_000_000) as u64,
        }
    }

    /// Fires alarms due by cycle `now`.
    pub fn update(&mut self, now: u64) {
        if now < self.next_event {
            return;
        }
        for n in 0..4 {
            if now >= self.fire_at[n] {
                self.fire_at[n] = u64::MAX;
                self.intr |= 1 << n;
            }
        }
        self.next_event = self.fire_at.iter().copied().min().unwrap_or(u64::MAX);
    }

    /// Interrupt lines TIMER_IRQ_0..3 as bits 0-3.
    pub fn irq_lines(&self) -> u32 {
        (self.intr & self.inte) | self.intf
    }

    fn arm(&mut self, now: u64, n: usize, value: u32) {
        self.alarm[n] = value;
        let t = self.micros(now);
        // The alarm compares the low 32 bits each microsecond; a target equal to now (or
        // in the past) matches only after the count wraps (datasheet 4.6.4).
        let mut delta = value.wrapping_sub(t as u32) as u64;
        if delta == 0 {
            delta = 1 << 32;
        }
        self.fire_at[n] = self.cycle_of(t + delta);
        self.next_event = self.fire_at.iter().copied().min().unwrap_or(u64::MAX);
    }

    /// Reads register `offset` at cycle `now`; `None` if unmapped.
    pub fn read(&mut self, now: u64, offset: u32) -> Option<u32> {
        if self.in_reset {
            return (offset <= reg::INTS).then_some(0);
        }
        self.update(now);
        let t = self.micros(now);
        if matches!(
            offset,
            reg::TIMEHR | reg::TIMELR | reg::TIMERAWH | reg::TIMERAWL
        ) {
            self.count_reads += 1;
        }
        Some(match offset {
            reg::TIMEHR => self.latched_high,
            reg::TIMELR => {
                self.latched_high = (t >> 32) as u32;
                t as u32
            }
            0x10..=0x1c => self.alarm[((offset - reg::ALARM0) / 4) as usize],
            reg::ARMED => (0..4).fold(0, |a, n| a | ((self.fire_at[n] != u64::MAX) as u32) << n),
            reg::TIMERAWH => (t >> 32) as u32,
            reg::TIMERAWL => t as u32,
            0x2c | 0x30 => 0, // DBGPAUSE, PAUSE
            reg::INTR => self.intr,
            reg::INTE => self.inte,
            reg::INTF => self.intf,
            reg::INTS => self.irq_lines(),
            _ => return None,
        })
    }

    /// Writes register `offset` at cycle `now`; false if unmapped.
    pub fn write(&mut self, now: u64, offset: u32, value: u32) -> bool {
        if self.in_reset {
            return offset <= reg::INTS;
        }
        self.update(now);
        match offset {
            reg::TIMELW => self.written_low = value,
            reg::TIMEHW => {
                let want = ((value as u64) << 32) | self.written_low as u64;
                let base = self.micros(now).wrapping_sub(self.offset);
                self.offset = want.wrapping_sub(base);
            }
            0x10..=0x1c => self.arm(now, ((offset - reg::ALARM0) / 4) as usize, value),
            reg::ARMED => {
                for n in 0..4 {
                    if value & (1 << n) != 0 {
                        self.fire_at[n] = u64::MAX;
                    }
                }
                self.next_event = self.fire_at.iter().copied().min().unwrap_or(u64::MAX);
            }
            reg::INTR => self.intr &= !value,
            reg::INTE => self.inte = value & 15,
            reg::INTF => self.intf = value & 15,
            0x2c | 0x30 => {}
            _ => return false,
        }
        true
    }
}
