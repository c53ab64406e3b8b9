//! The RP2040's watchdog (datasheet 4.7): a 24-bit count down that resets the chip when it
//! reaches 0 while enabled, the reason of the last reset, eight scratch registers that
//! survive it, and the tick generator's register.
//!
//! **Why the count is kept as "the count at a cycle".** The count decrements on each tick
//! of the watchdog's tick generator, the 1 µs pulse (clk_ref divided by `TICK.CYCLES`);
//! like the timer ([`crate::timer`]) the emulator derives the ticks from the emulated cycle
//! (tick *t* starts at the first cycle `c` with `c·10⁶ / clock ≥ t`, ticks counted from
//! power-on, whatever `TICK` says) instead of ticking it. So the state is the count at the
//! cycle `since` of the last LOAD (or of enabling), and the cycle at which it reaches 0,
//! [`Watchdog::fire_at`], follows from them: a board need only compare its cycle with it.
//! It decrements by 2 per tick, not 1 (erratum RP2040-E1: LOAD is twice the microseconds
//! wanted, [`tactus_rp2040::watchdog::DECREMENTS_PER_TICK`]).
//!
//! **What a firing does** ([`crate::machine::Machine`]'s `reset.rs`): the reset pico-sdk's
//! `watchdog_enable` selects in PSM.WDSEL (every block but the oscillators): both cores,
//! SIO, the timer, the start-up registers, the I/O's PIOs and DMA; SRAM keeps its contents,
//! the scratch registers theirs, and REASON says TIMER (the count reached 0) or FORCE
//! (CTRL.TRIGGER). Firing clears ENABLE (a count at 0 would otherwise fire again at once:
//! our model; the boot ROM and the firmware enable it again as they wish). The boot path
//! then is the boot ROM's: its watchdog entry when the scratch registers hold one
//! ([`tactus_rp2040::watchdog::boot_entry`]), else boot from flash.
//!
//! **Exactness.** The rest replay (`accel/rest.rs`) compares the count, ENABLE and the
//! cycles since `since`, not `fire_at`, whose distance also depends on the phase of the
//! 1 µs ticks; so it refuses a period in which a core read the count (CTRL.TIME) or fed
//! the watchdog within two ticks of its firing ([`Watchdog::close_calls`]): a period
//! shifted by a fraction of a tick then fires where the recorded one fed. A fed watchdog
//! is state relative to its last feed (the count loaded, the cycles since): a firmware
//! that feeds it at the same point of every sample repeats. The block engine's windows
//! apply one core's feeds at their cycles (`accel/window.rs`, "The watchdog").

use tactus_rp2040::watchdog::{self as wd, reg};

/// Why the watchdog reset the chip (REASON).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reason {
    /// The count reached 0.
    Timer,
    /// CTRL.TRIGGER was written.
    Force,
}

/// One reset by the watchdog ([`Watchdog::resets`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reset {
    /// The board's cycle at the reset (the later of the cores' first instruction
    /// boundaries at or after the firing).
    pub cycle: u64,
    /// Why.
    pub reason: Reason,
}

/// The watchdog's registers and count (module documentation).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Watchdog {
    clock_hz: u64,
    /// CTRL's ENABLE and PAUSE bits as written.
    ctrl: u32,
    /// The count at `since` (24 bits).
    count: u32,
    /// The cycle from which `count` counts down.
    since: u64,
    reason: u32,
    scratch: [u32; 8],
    tick: u32,
    /// The cycle at which the chip resets: the count's zero while enabled, the write's
    /// cycle after CTRL.TRIGGER; `u64::MAX` otherwise.
    pub fire_at: u64,
    forced: bool,
    /// Resets by the watchdog since power-on (state: part of what the rest replay compares).
    resets: u64,
    /// The last reset, if any.
    last: Option<Reset>,
    /// Reads of CTRL (its TIME field depends on the ticks' phase): not state.
    pub(crate) time_reads: u64,
    /// Feeds (a LOAD, or disabling) with the count within two ticks of 0: not state
    /// (module documentation, "Exactness").
    pub(crate) close_calls: u64,
}

impl Watchdog {
    /// A watchdog at its power-on values (datasheet 4.7.6): disabled, count 0, PAUSE bits
    /// set, REASON 0, scratch 0, the tick generator off.
    pub fn new(clock_hz: u64) -> Watchdog {
        Watchdog {
            clock_hz: clock_hz.max(1),
            ctrl: wd::CTRL_PAUSE,
            count: 0,
            since: 0,
            reason: 0,
            scratch: [0; 8],
            tick: 0,
            fire_at: u64::MAX,
            forced: false,
            resets: 0,
            last: None,
            time_reads: 0,
            close_calls: 0,
        }
    }

    /// The tick (µs) that cycle `c` falls in, from power-on.
    fn tick_of(&self, c: u64) -> u64 {
        (c as u128 * 1_000_000 / self.clock_hz as u128) as u64
    }

    /// The first cycle of tick `t`.
    fn cycle_of_tick(&self, t: u64) -> u64 {
        (t as u128 * self.clock_hz as u128)
            .div_ceil(1_000_000)
            .min(u64::MAX as u128 - 1) as u64
    }

    fn enabled(&self) -> bool {
        self.ctrl & wd::CTRL_ENABLE != 0
    }

    /// The count at cycle `now`.
    pub fn count_at(&self, now: u64) -> u32 {
        if !self.enabled() || now <= self.since {
            return self.count;
        }
        let ticks = self.tick_of(now) - self.tick_of(self.since);
        let down = ticks.saturating_mul(u64::from(wd::DECREMENTS_PER_TICK));
        u64::from(self.count).saturating_sub(down) as u32
    }

    /// `fire_at` from the count (module documentation).
    fn refresh(&mut self) {
        if self.forced {
            return;
        }
        self.fire_at = if self.enabled() {
            let per = u64::from(wd::DECREMENTS_PER_TICK);
            let ticks = u64::from(self.count).div_ceil(per).max(1);
            self.cycle_of_tick(self.tick_of(self.since) + ticks)
        } else {
            u64::MAX
        };
    }

    /// A feed at `now`: counted as a close call when the count was within two ticks of 0.
    fn note_feed(&mut self, now: u64) {
        if self.enabled() && self.count_at(now) <= 2 * wd::DECREMENTS_PER_TICK {
            self.close_calls += 1;
        }
    }

    fn get(&self, now: u64, off: u32) -> Option<u32> {
        Some(match off {
            reg::CTRL => self.ctrl | self.count_at(now),
            reg::LOAD => 0,
            reg::REASON => self.reason,
            reg::TICK => self.tick | (self.tick & wd::TICK_ENABLE) << 1,
            o if (reg::SCRATCH0..reg::SCRATCH0 + 32).contains(&o) => {
                self.scratch[((o - reg::SCRATCH0) / 4) as usize]
            }
            _ => return None,
        })
    }

    /// Reads the register at offset `off` (bits 11:0 of the address, any alias) at cycle
    /// `now`: CTRL with TIME the count now, LOAD 0 (write only), TICK with RUNNING =
    /// ENABLE (COUNT reads 0: not modelled). `None` for no register.
    pub fn read(&mut self, now: u64, off: u32) -> Option<u32> {
        if off == reg::CTRL {
            self.time_reads += 1;
        }
        self.get(now, off)
    }

    /// Writes `value` at `addr` (a WATCHDOG address: `+0x1000` XOR, `+0x2000` SET,
    /// `+0x3000` CLR, datasheet 2.1.2) at cycle `now`. False for no register.
    pub fn write(&mut self, now: u64, addr: u32, value: u32) -> bool {
        let off = addr & 0xffc;
        let Some(old) = self.get(now, off) else {
            return false;
        };
        let value = match (addr >> 12) & 3 {
            0 => value,
            1 => old ^ value,
            2 => old | value,
            _ => old & !value,
        };
        match off {
            reg::CTRL => {
                let was = self.enabled();
                let now_on = value & wd::CTRL_ENABLE != 0;
                if was && !now_on {
                    self.note_feed(now);
                    self.count = self.count_at(now);
                    self.since = now;
                } else if !was && now_on {
                    self.since = now;
                }
                self.ctrl = value & (wd::CTRL_ENABLE | wd::CTRL_PAUSE);
                if value & wd::CTRL_TRIGGER != 0 {
                    self.forced = true;
                    self.fire_at = now;
                }
            }
            reg::LOAD => {
                self.note_feed(now);
                self.count = value & wd::LOAD_MAX;
                self.since = now;
            }
            reg::REASON => {}
            reg::TICK => self.tick = value & 0x3ff,
            o => self.scratch[((o - reg::SCRATCH0) / 4) as usize] = value,
        }
        self.refresh();
        true
    }

    /// The chip resets at cycle `at` (`reset.rs`): REASON set, ENABLE cleared, the count
    /// at 0; the scratch registers and the tick kept. Returns why.
    pub(crate) fn fire(&mut self, at: u64) -> Reason {
        let reason = if self.forced {
            Reason::Force
        } else {
            Reason::Timer
        };
        self.reason = match reason {
            Reason::Timer => wd::REASON_TIMER,
            Reason::Force => wd::REASON_FORCE,
        };
        self.forced = false;
        self.ctrl &= !wd::CTRL_ENABLE;
        self.count = 0;
        self.since = at;
        self.fire_at = u64::MAX;
        self.resets += 1;
        self.last = Some(Reset { cycle: at, reason });
        reason
    }

    /// A power-on (a brown-out, `reset.rs`): every register at its power-on value; the
    /// count of resets and the counts that are not state kept.
    pub(crate) fn power_on(&mut self) {
        *self = Watchdog {
            resets: self.resets,
            last: self.last,
            time_reads: self.time_reads,
            close_calls: self.close_calls,
            ..Watchdog::new(self.clock_hz)
        };
    }

    /// The boot ROM's watchdog entry, taken once: `(pc, sp)` when the scratch registers
    /// hold one ([`wd::boot_entry`]), `SCRATCH4` then cleared as the ROM clears it.
    pub(crate) fn take_boot_entry(&mut self) -> Option<(u32, u32)> {
        let entry = wd::boot_entry(&self.scratch)?;
        self.scratch[4] = 0;
        Some(entry)
    }

    /// Sets scratch register `n` (0–7; others ignored), as the boot ROM or a host does.
    pub fn set_scratch(&mut self, n: usize, value: u32) {
        if let Some(s) = self.scratch.get_mut(n) {
            *s = value;
        }
    }

    /// Scratch register `n` (0 for `n` ≥ 8).
    pub fn scratch(&self, n: usize) -> u32 {
        self.scratch.get(n).copied().unwrap_or(0)
    }

    /// REASON: [`wd::REASON_TIMER`], [`wd::REASON_FORCE`] or 0 (power-on).
    pub fn reason(&self) -> u32 {
        self.reason
    }

    /// Whether the count runs.
    pub fn is_enabled(&self) -> bool {
        self.enabled()
    }

    /// Resets by the watchdog since power-on, and the last.
    pub fn resets(&self) -> (u64, Option<Reset>) {
        (self.resets, self.last)
    }

    /// The tick generator's divider when enabled: the reference clock cycles per
    /// microsecond tick (12 for a 12 MHz crystal).
    pub fn tick_cycles(&self) -> Option<u32> {
        (self.tick & wd::TICK_ENABLE != 0).then_some(self.tick & 0x1ff)
    }

    /// Its state with cycles relative to `now` (`accel/rest.rs`): everything but
    /// `fire_at` (which follows) and the counts that are not state.
    pub(crate) fn rest_state(&self, now: u64) -> String {
        // Disabled, the count does not move: when it was loaded decides nothing.
        let since = if self.enabled() || self.forced {
            now as i128 - self.since as i128
        } else {
            0
        };
        format!(
            "{:#x} {} {} {} {:?} {:#x} {} {}",
            self.ctrl,
            self.count,
            since,
            self.reason,
            self.scratch,
            self.tick,
            self.forced,
            self.resets
        )
    }

    /// Moves its cycles `delta` later (`accel/rest.rs`: whole periods skipped); `fire_at`
    /// recomputed from the ticks there.
    pub(crate) fn move_later(&mut self, delta: u64) {
        self.since = self.since.saturating_add(delta);
        if self.forced {
            self.fire_at = self.fire_at.saturating_add(delta);
        }
        self.refresh();
    }
}
