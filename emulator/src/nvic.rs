//! The private peripheral bus of one Cortex-M0+ core: NVIC, SysTick and the SCB registers.
//!
//! These registers belong to the processor, not to the RP2040 bus fabric (each core has its
//! own at 0xe0000000), so they live inside [`crate::core::Core`] and the executor reaches them
//! without going through the shared [`crate::bus::Bus`]. Exception state is kept as bit masks
//! indexed by exception number (2 NMI, 3 HardFault, 11 SVCall, 14 PendSV, 15 SysTick, 16+n
//! external interrupt n; DDI0419 B1.5.2), so "anything pending?" is one AND. Priorities are
//! the two implemented bits (0-3) of the 8-bit priority fields (DDI0419 B3.4).
//!
//! **SysTick** (DDI0419 B3.3; "each Cortex M0+ is equipped with a 24-bit SysTick timer",
//! RP2040 datasheet, the Timer chapter's overview) is evaluated lazily: we store the cycle
//! at which the counter next reaches 0, not a counter that ticks. It counts the processor
//! clock with SYST_CSR.CLKSOURCE = 1 and the 1 µs pulse of the watchdog's tick generator
//! with CLKSOURCE = 0 (RP2040 datasheet, Cortex-M0+ section: "The SysTick timer uses a 1 µs
//! pulse as a clock enable. This is generated in the watchdog block as timer_tick";
//! SYST_CALIB reads 0, NOREF clear; here the pulse is the timer's microsecond,
//! `⌊cycle · 10⁶ / clock⌋`, whatever the watchdog's TICK register holds). Counting from 1 to 0 sets
//! COUNTFLAG and, with TICKINT, pends the SysTick exception; the counter holds 0 for one
//! count and is reloaded from SYST_RVR on the next, so the period is RVR + 1 counts and a
//! write to RVR takes effect at the next reload — also when it lands on the count at 0,
//! whose reload follows it. Reading SYST_CSR clears COUNTFLAG; any write to SYST_CVR clears
//! the counter and COUNTFLAG, and the counter reloads on the next count.

/// Exception number of NMI.
pub const NMI: u32 = 2;
/// Exception number of HardFault.
pub const HARDFAULT: u32 = 3;
/// Exception number of SVCall.
pub const SVCALL: u32 = 11;
/// Exception number of PendSV.
pub const PENDSV: u32 = 14;
/// Exception number of SysTick.
pub const SYSTICK: u32 = 15;
/// Exception number of external interrupt 0 (IRQ n is `IRQ0 + n`).
pub const IRQ0: u32 = 16;

/// Base address of the private peripheral bus (DDI0419 B3.2).
pub const PPB_BASE: u32 = 0xe000_0000;

/// The NVIC, SysTick and SCB state of one core.
#[derive(Clone, Debug)]
pub struct Nvic {
    /// Pending exceptions, bit = exception number.
    pub pending: u64,
    /// Active exceptions, bit = exception number.
    pub active: u64,
    /// NVIC_ISER: enabled external interrupts (bit n = IRQ n). Change it only through
    /// [`Nvic::write`] or [`Nvic::set_enabled`], which keep `enable_mask` in step.
    pub enabled: u32,
    /// Exceptions that may be taken when pending, bit = exception number: the system
    /// exceptions always, external interrupts when enabled (derived from `enabled`).
    enable_mask: u64,
    /// NVIC_IPR0-7: 8-bit priority fields of IRQ 0-31, only bits 7:6 implemented.
    pub ipr: [u32; 8],
    /// SHPR2 (SVCall priority in bits 31:30).
    pub shpr2: u32,
    /// SHPR3 (PendSV priority in bits 23:22, SysTick in 31:30).
    pub shpr3: u32,
    /// VTOR: vector table offset (RP2040 implements it, datasheet 2.4.8).
    pub vtor: u32,
    /// SCR (SEVONPEND bit 4 honoured by WFE; SLEEPDEEP/SLEEPONEXIT stored only).
    pub scr: u32,
    /// SYST_CSR bits ENABLE(0), TICKINT(1), CLKSOURCE(2); COUNTFLAG kept in `countflag`.
    /// Set it directly only with the counter's state ([`Nvic::syst_next`]) to match.
    pub syst_csr: u32,
    /// SYST_RVR (24 bits).
    pub syst_rvr: u32,
    /// COUNTFLAG: set by a wrap, cleared by reading SYST_CSR.
    pub countflag: bool,
    /// Cycle at which the counter next reaches 0 (meaningful while enabled; `u64::MAX`:
    /// never). With CLKSOURCE = 0 the cycle of that 1 µs pulse.
    pub syst_next: u64,
    /// Whether the count at 0 at [`Nvic::syst_next`] has been signalled (COUNTFLAG, the
    /// exception): the counter is at 0 and its reload, on the next count, is still to come.
    pub syst_fired: bool,
    /// Counter value while disabled.
    pub syst_cvr: u32,
    /// The processor clock in Hz, for the 1 µs reference pulse (CLKSOURCE = 0); 0: no
    /// reference connected (a core outside a board), the counter then holds.
    pub clock_hz: u64,
}

impl Default for Nvic {
    fn default() -> Self {
        Nvic {
            pending: 0,
            active: 0,
            enabled: 0,
            enable_mask: (1 << IRQ0) - 1,
            ipr: [0; 8],
            shpr2: 0,
            shpr3: 0,
            vtor: 0,
            scr: 0,
            syst_csr: 0,
            syst_rvr: 0,
            countflag: false,
            syst_next: u64::MAX,
            syst_fired: false,
            syst_cvr: 0,
            clock_hz: 0,
        }
    }
}

impl Nvic {
    /// Priority of exception `exc` as a signed level (lower is more urgent): NMI -2,
    /// HardFault -1, configurable exceptions 0-3.
    pub fn priority(&self, exc: u32) -> i32 {
        match exc {
            NMI => -2,
            HARDFAULT => -1,
            SVCALL => (self.shpr2 >> 30) as i32,
            PENDSV => ((self.shpr3 >> 22) & 3) as i32,
            SYSTICK => (self.shpr3 >> 30) as i32,
            n if (IRQ0..IRQ0 + 32).contains(&n) => {
                let irq = n - IRQ0;
                ((self.ipr[(irq / 4) as usize] >> (8 * (irq % 4) + 6)) & 3) as i32
            }
            _ => 4,
        }
    }

    /// Highest-priority active exception's level, or 4 (below every configurable level) when
    /// none is active.
    pub fn active_priority(&self) -> i32 {
        let mut best = 4;
        let mut bits = self.active;
        while bits != 0 {
            let exc = bits.trailing_zeros();
            bits &= bits - 1;
            best = best.min(self.priority(exc));
        }
        best
    }

    /// Advances SysTick to cycle `now`: signals the count at 0 (COUNTFLAG; the exception,
    /// with TICKINT) when `now` has reached it, and performs the reloads up to `now` with
    /// RVR as it is (a write to RVR first advances to the cycle of the write).
    #[inline]
    pub fn tick(&mut self, now: u64) {
        // At the count at 0 already signalled, nothing is due until the next count
        // (`syst_wrap` would find `now`'s count equal to that of `syst_next` and leave all
        // as it is).
        if now >= self.syst_next && (now != self.syst_next || !self.syst_fired) {
            self.syst_wrap(now);
        }
    }

    #[inline(never)]
    fn syst_wrap(&mut self, now: u64) {
        let t = self.count_at(now);
        let zero = self.count_at(self.syst_next);
        if !self.syst_fired {
            self.signal();
        }
        if t == zero {
            // At 0: the reload follows on the next count.
            self.syst_fired = true;
            return;
        }
        // Reloaded at zero + 1 with RVR, then every RVR + 1 counts.
        if self.syst_rvr == 0 {
            // A reload value of 0 stops the counter at 0 without another signal.
            self.syst_next = u64::MAX;
            self.syst_fired = false;
            return;
        }
        let period = self.syst_rvr as u64 + 1;
        let k = (t - zero) / period;
        let last = zero + k * period;
        if k >= 1 {
            self.signal();
        }
        if last == t {
            self.syst_next = self.cycle_of_count(last);
            self.syst_fired = true;
        } else {
            self.syst_next = self.cycle_of_count(last + period);
            self.syst_fired = false;
        }
    }

    /// COUNTFLAG and, with TICKINT, the exception.
    fn signal(&mut self) {
        self.countflag = true;
        if self.syst_csr & 2 != 0 {
            self.pending |= 1 << SYSTICK;
        }
    }

    /// The counter's clock: its counts by cycle `now` (the cycle itself with CLKSOURCE = 1;
    /// the 1 µs pulses, `⌊now · 10⁶ / clock⌋`, with CLKSOURCE = 0).
    fn count_at(&self, now: u64) -> u64 {
        if self.syst_csr & 4 != 0 || now == u64::MAX {
            return now;
        }
        if self.clock_hz == 0 {
            return 0;
        }
        (now as u128 * 1_000_000 / self.clock_hz as u128) as u64
    }

    /// The first cycle at which the counter's clock has made `count` counts (inverse of
    /// `count_at`; `u64::MAX` when the reference pulse is not connected).
    fn cycle_of_count(&self, count: u64) -> u64 {
        if self.syst_csr & 4 != 0 {
            return count;
        }
        if self.clock_hz == 0 {
            return u64::MAX;
        }
        let c = (count as u128 * self.clock_hz as u128).div_ceil(1_000_000);
        c.min(u64::MAX as u128 - 1) as u64
    }

    /// (Re)starts the counter at cycle `now` from value `cvr`: a counter at 0 reloads from
    /// RVR on the next count.
    fn syst_start(&mut self, now: u64, cvr: u32) {
        let t = self.count_at(now);
        self.syst_fired = false;
        self.syst_next = if cvr == 0 && self.syst_rvr == 0 {
            u64::MAX
        } else if cvr == 0 {
            self.cycle_of_count(t + 1 + self.syst_rvr as u64)
        } else {
            self.cycle_of_count(t + cvr as u64)
        };
    }

    /// Pending exceptions that may be taken: external interrupts must be enabled.
    #[inline]
    pub fn takeable(&self) -> u64 {
        self.pending & self.enable_mask
    }

    /// Sets NVIC_ISER's state (bit n = IRQ n enabled).
    pub fn set_enabled(&mut self, enabled: u32) {
        self.enabled = enabled;
        self.enable_mask = ((enabled as u64) << IRQ0) | ((1 << IRQ0) - 1);
    }

    /// The pending, enabled exception with the highest priority (lowest exception number on
    /// ties, DDI0419 B1.5.4) and its priority.
    pub fn highest_pending(&self) -> Option<(u32, i32)> {
        let mut bits = self.takeable();
        let mut best: Option<(u32, i32)> = None;
        while bits != 0 {
            let exc = bits.trailing_zeros();
            bits &= bits - 1;
            let p = self.priority(exc);
            if best.is_none_or(|(_, bp)| p < bp) {
                best = Some((exc, p));
            }
        }
        best
    }

    fn syst_cvr(&self, now: u64) -> u32 {
        if self.syst_csr & 1 != 0 && self.syst_next != u64::MAX {
            let left = self
                .count_at(self.syst_next)
                .saturating_sub(self.count_at(now));
            left as u32 & 0x00ff_ffff
        } else if self.syst_csr & 1 != 0 {
            0
        } else {
            self.syst_cvr
        }
    }

    /// Reads a PPB register (word access); `None` for an unimplemented address.
    pub fn read(&mut self, now: u64, addr: u32, ipsr: u32) -> Option<u32> {
        self.tick(now);
        Some(match addr {
            0xe000_e010 => {
                let v = self.syst_csr | ((self.countflag as u32) << 16);
                self.countflag = false;
                v
            }
            0xe000_e014 => self.syst_rvr,
            0xe000_e018 => self.syst_cvr(now),
            0xe000_e01c => 0, // SYST_CALIB: no reference clock calibration
            0xe000_e100 | 0xe000_e180 => self.enabled,
            0xe000_e200 | 0xe000_e280 => (self.pending >> IRQ0) as u32,
            0xe000_e400..=0xe000_e41c => self.ipr[((addr - 0xe000_e400) / 4) as usize],
            0xe000_ed00 => 0x410c_c601, // CPUID: Cortex-M0+ r0p1 (RP2040 datasheet 2.4.8)
            0xe000_ed04 => {
                let pend = self.pending;
                let vectpending = self.highest_pending().map_or(0, |(e, _)| e);
                ipsr | (vectpending << 12)
                    | (((pend >> IRQ0) != 0) as u32) << 22
                    | (((pend >> SYSTICK) & 1) as u32) << 26
                    | (((pend >> PENDSV) & 1) as u32) << 28
                    | (((pend >> NMI) & 1) as u32) << 31
            }
            0xe000_ed08 => self.vtor,
            0xe000_ed0c => 0xfa05_0000,
            0xe000_ed10 => self.scr,
            0xe000_ed14 => 0x0000_0208, // CCR: STKALIGN, UNALIGN_TRP (fixed on ARMv6-M)
            0xe000_ed1c => self.shpr2,
            0xe000_ed20 => self.shpr3,
            0xe000_ed24 => ((self.pending >> SVCALL) & 1) as u32 * (1 << 15),
            _ => return None,
        })
    }

    /// Writes a PPB register (word access); `false` for an unimplemented address.
    pub fn write(&mut self, now: u64, addr: u32, value: u32) -> bool {
        self.tick(now);
        match addr {
            0xe000_e010 => {
                let was_on = self.syst_csr & 1 != 0;
                let cvr = self.syst_cvr(now);
                let clock_changed = (self.syst_csr ^ value) & 4 != 0;
                self.syst_csr = value & 7;
                if value & 1 == 0 {
                    self.syst_cvr = cvr;
                    self.syst_next = u64::MAX;
                    self.syst_fired = false;
                } else if !was_on {
                    // Counting starts: a zero counter reloads from RVR on the next count.
                    self.syst_start(now, cvr);
                } else if clock_changed && !(self.syst_fired && cvr == 0) {
                    // The same value, counted on the other clock from here.
                    self.syst_start(now, cvr);
                }
            }
            0xe000_e014 => self.syst_rvr = value & 0x00ff_ffff,
            0xe000_e018 => {
                // Any write clears the counter and COUNTFLAG; it reloads on the next count.
                self.countflag = false;
                self.syst_cvr = 0;
                if self.syst_csr & 1 != 0 {
                    self.syst_start(now, 0);
                }
            }
            0xe000_e100 => self.set_enabled(self.enabled | value),
            0xe000_e180 => self.set_enabled(self.enabled & !value),
            0xe000_e200 => self.pending |= (value as u64) << IRQ0,
            0xe000_e280 => self.pending &= !((value as u64) << IRQ0),
            0xe000_e400..=0xe000_e41c => {
                self.ipr[((addr - 0xe000_e400) / 4) as usize] = value & 0xc0c0_c0c0
            }
            0xe000_ed04 => {
                if value & (1 << 31) != 0 {
                    self.pending |= 1 << NMI;
                }
                if value & (1 << 28) != 0 {
                    self.pending |= 1 << PENDSV;
                }
                if value & (1 << 27) != 0 {
                    self.pending &= !(1 << PENDSV);
                }
                if value & (1 << 26) != 0 {
                    self.pending |= 1 << SYSTICK;
                }
                if value & (1 << 25) != 0 {
                    self.pending &= !(1 << SYSTICK);
                }
            }
            0xe000_ed08 => self.vtor = value & 0xffff_ff00,
            0xe000_ed0c => {} // AIRCR: SYSRESETREQ is not modelled
            0xe000_ed10 => self.scr = value & 0x16,
            0xe000_ed14 => {}
            0xe000_ed1c => self.shpr2 = value & 0xc000_0000,
            0xe000_ed20 => self.shpr3 = value & 0xc0c0_0000,
            _ => return false,
        }
        true
    }
}
