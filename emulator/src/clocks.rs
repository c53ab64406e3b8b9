//! The blocks a firmware's start-up programs before anything runs at speed: RESETS, the
//! crystal oscillator (XOSC), the system PLL (PLL_SYS), the clock generators (CLOCKS) and
//! the watchdog's tick generator (RP2040 datasheet 2.14 Subsystem resets, 2.15 Clocks,
//! 2.16 XOSC, 2.18 PLL, 4.7 Watchdog).
//!
//! **A minimal model.** Each register is plain memory (with the datasheet's atomic SET,
//! CLR and XOR aliases, 2.1.2), except for the status bits a start-up polls, which read as
//! done at once: `RESET_DONE` is set for every block not held in reset, `XOSC STATUS.STABLE`
//! once the oscillator is enabled, `PLL CS.LOCK` always, and `CLK_REF_SELECTED` /
//! `CLK_SYS_SELECTED` follow the glitchless mux selected in `CTRL.SRC`. Nothing here
//! changes the emulated clock, which is [`crate::board::Config::clock_hz`] from power-on;
//! the timer counts microseconds from power-on whatever the watchdog tick or its reset
//! say. [`SysCtl::pll_sys_hz`] decodes what the firmware programmed, so a test can check
//! that a start-up sets the clock its board file names. Not modelled: oscillator start-up
//! and PLL lock times (about 1 ms and tens of µs on the chip), clock dividers other than
//! the PLL's, the USB PLL.

/// RESETS (datasheet 2.14.3).
pub const RESETS_BASE: u32 = 0x4000_c000;
/// CLOCKS (datasheet 2.15.7).
pub const CLOCKS_BASE: u32 = 0x4000_8000;
/// XOSC (datasheet 2.16.7).
pub const XOSC_BASE: u32 = 0x4002_4000;
/// PLL_SYS (datasheet 2.18.4).
pub const PLL_SYS_BASE: u32 = 0x4002_8000;
/// WATCHDOG (datasheet 4.7.6).
pub const WATCHDOG_BASE: u32 = 0x4005_8000;
/// The crystal on the Raspberry Pi Pico and most RP2040 boards, Hz.
pub const XOSC_HZ: u64 = 12_000_000;

/// Register offsets (datasheet sections as in the module documentation).
pub mod reg {
    /// RESETS: blocks held in reset (bit per block).
    pub const RESET: u32 = 0x0;
    /// RESETS: blocks out of reset and ready.
    pub const RESET_DONE: u32 = 0x8;
    /// RESETS bit of PLL_SYS.
    pub const RESET_PLL_SYS: u32 = 1 << 12;
    /// RESETS bit of TIMER.
    pub const RESET_TIMER: u32 = 1 << 21;
    /// XOSC: CTRL (FREQ_RANGE 11:0, ENABLE 23:12).
    pub const XOSC_CTRL: u32 = 0x00;
    /// XOSC: STATUS (STABLE is bit 31).
    pub const XOSC_STATUS: u32 = 0x04;
    /// XOSC: STARTUP (DELAY in units of 256 reference cycles).
    pub const XOSC_STARTUP: u32 = 0x0c;
    /// XOSC CTRL value: enabled, 1–15 MHz range.
    pub const XOSC_ENABLE_1_15MHZ: u32 = 0xfab << 12 | 0xaa0;
    /// PLL: CS (REFDIV 5:0, LOCK bit 31).
    pub const PLL_CS: u32 = 0x0;
    /// PLL: PWR (PD bit 0, POSTDIVPD bit 3, VCOPD bit 5).
    pub const PLL_PWR: u32 = 0x4;
    /// PLL: FBDIV_INT.
    pub const PLL_FBDIV_INT: u32 = 0x8;
    /// PLL: PRIM (POSTDIV1 18:16, POSTDIV2 14:12).
    pub const PLL_PRIM: u32 = 0xc;
    /// CLOCKS: CLK_REF_CTRL (SRC 1:0: 0 ROSC, 1 aux, 2 XOSC).
    pub const CLK_REF_CTRL: u32 = 0x30;
    /// CLOCKS: CLK_REF_SELECTED (one-hot of the selected SRC).
    pub const CLK_REF_SELECTED: u32 = 0x38;
    /// CLOCKS: CLK_SYS_CTRL (SRC bit 0: 0 clk_ref, 1 aux; AUXSRC 7:5: 0 PLL_SYS).
    pub const CLK_SYS_CTRL: u32 = 0x3c;
    /// CLOCKS: CLK_SYS_DIV (integer part in 31:8).
    pub const CLK_SYS_DIV: u32 = 0x40;
    /// CLOCKS: CLK_SYS_SELECTED (one-hot of the selected SRC).
    pub const CLK_SYS_SELECTED: u32 = 0x44;
    /// WATCHDOG: TICK (CYCLES 8:0, ENABLE bit 9).
    pub const WATCHDOG_TICK: u32 = 0x2c;
}

/// The registers of the start-up blocks (see the module documentation).
#[derive(Clone, Debug)]
pub struct SysCtl {
    /// (block base, register offset) → value.
    regs: std::collections::BTreeMap<(u32, u32), u32>,
}

impl Default for SysCtl {
    /// Every block out of reset (what reset state the boot ROM leaves is not modelled);
    /// PLL_SYS powered down with REFDIV 1, FBDIV 0 and post dividers 7 × 7, clk_sys
    /// divided by 1 (datasheet 2.18.4 and 2.15.7 reset values).
    fn default() -> Self {
        let mut regs = std::collections::BTreeMap::new();
        regs.insert((PLL_SYS_BASE, reg::PLL_CS), 1);
        regs.insert((PLL_SYS_BASE, reg::PLL_PWR), 0x2d);
        regs.insert((PLL_SYS_BASE, reg::PLL_PRIM), 0x7 << 16 | 0x7 << 12);
        regs.insert((CLOCKS_BASE, reg::CLK_SYS_DIV), 1 << 8);
        SysCtl { regs }
    }
}

/// The block base of `addr` (any of its four aliases) if it is one of this module's.
pub fn block_of(addr: u32) -> Option<u32> {
    let base = addr & !0x3fff;
    [
        RESETS_BASE,
        CLOCKS_BASE,
        XOSC_BASE,
        PLL_SYS_BASE,
        WATCHDOG_BASE,
    ]
    .contains(&base)
    .then_some(base)
}

impl SysCtl {
    fn get(&self, base: u32, off: u32) -> u32 {
        self.regs.get(&(base, off)).copied().unwrap_or(0)
    }

    /// Reads the register at `addr` (an address of one of the blocks, any alias reads the
    /// register), with the polled status bits as described in the module documentation.
    pub fn read(&self, addr: u32) -> Option<u32> {
        let base = block_of(addr)?;
        let off = addr & 0xffc;
        let v = self.get(base, off);
        Some(match (base, off) {
            (RESETS_BASE, reg::RESET_DONE) => !self.get(RESETS_BASE, reg::RESET) & 0x01ff_ffff,
            (XOSC_BASE, reg::XOSC_STATUS) => {
                let enabled = self.get(XOSC_BASE, reg::XOSC_CTRL) >> 12 & 0xfff == 0xfab;
                v | (enabled as u32) << 31 | (enabled as u32) << 12
            }
            (PLL_SYS_BASE, reg::PLL_CS) => v | 1 << 31,
            (CLOCKS_BASE, reg::CLK_REF_SELECTED) => {
                1 << (self.get(CLOCKS_BASE, reg::CLK_REF_CTRL) & 3)
            }
            (CLOCKS_BASE, reg::CLK_SYS_SELECTED) => {
                1 << (self.get(CLOCKS_BASE, reg::CLK_SYS_CTRL) & 1)
            }
            _ => v,
        })
    }

    /// Writes `value` at `addr`: `+0x1000` XOR, `+0x2000` SET, `+0x3000` CLR (datasheet
    /// 2.1.2). False when `addr` is not in one of the blocks.
    pub fn write(&mut self, addr: u32, value: u32) -> bool {
        let Some(base) = block_of(addr) else {
            return false;
        };
        let off = addr & 0xffc;
        let old = self.get(base, off);
        let new = match (addr >> 12) & 3 {
            0 => value,
            1 => old ^ value,
            2 => old | value,
            _ => old & !value,
        };
        self.regs.insert((base, off), new);
        true
    }

    /// The PLL_SYS output the firmware programmed, Hz: `XOSC_HZ / REFDIV × FBDIV /
    /// (POSTDIV1 × POSTDIV2)` (datasheet 2.18.2), or `None` while it is powered down,
    /// unlocked by its divider values (FBDIV outside 16–320, a zero divider) or the VCO
    /// outside 750–1600 MHz.
    pub fn pll_sys_hz(&self) -> Option<u64> {
        let cs = self.get(PLL_SYS_BASE, reg::PLL_CS);
        let pwr = self.get(PLL_SYS_BASE, reg::PLL_PWR);
        let fbdiv = self.get(PLL_SYS_BASE, reg::PLL_FBDIV_INT) as u64 & 0xfff;
        let prim = self.get(PLL_SYS_BASE, reg::PLL_PRIM);
        let (refdiv, pd1, pd2) = (
            (cs & 0x3f) as u64,
            (prim >> 16 & 7) as u64,
            (prim >> 12 & 7) as u64,
        );
        if pwr & (1 | 1 << 3 | 1 << 5) != 0 || refdiv == 0 || pd1 == 0 || pd2 == 0 {
            return None;
        }
        let vco = XOSC_HZ / refdiv * fbdiv;
        ((16..=320).contains(&fbdiv) && (750_000_000..=1_600_000_000).contains(&vco))
            .then(|| vco / (pd1 * pd2))
    }

    /// clk_sys as programmed, Hz: PLL_SYS divided by CLK_SYS_DIV's integer part when the
    /// clk_sys mux selects its auxiliary source and that is PLL_SYS; `None` otherwise.
    pub fn clk_sys_hz(&self) -> Option<u64> {
        let ctrl = self.get(CLOCKS_BASE, reg::CLK_SYS_CTRL);
        let div = (self.get(CLOCKS_BASE, reg::CLK_SYS_DIV) >> 8) as u64;
        if ctrl & 1 != 1 || ctrl >> 5 & 7 != 0 || div == 0 {
            return None;
        }
        self.pll_sys_hz().map(|f| f / div)
    }

    /// The watchdog tick's divider when enabled: the reference clock cycles per
    /// microsecond tick the timer counts (12 for a 12 MHz crystal).
    pub fn tick_cycles(&self) -> Option<u32> {
        let t = self.get(WATCHDOG_BASE, reg::WATCHDOG_TICK);
        (t & 1 << 9 != 0).then_some(t & 0x1ff)
    }
}

/// PLL_SYS dividers for a clk_sys of `hz` from [`XOSC_HZ`]: (FBDIV, POSTDIV1, POSTDIV2)
/// with REFDIV 1, the VCO in 750–1600 MHz and POSTDIV1 ≥ POSTDIV2, preferring the highest
/// VCO (less jitter), then the larger POSTDIV1 (pico-sdk's 125 MHz: 1500 MHz / 6 / 2). `None` when no setting
/// gives exactly `hz`.
pub fn pll_sys_dividers(hz: u64) -> Option<(u32, u32, u32)> {
    let mut best = None;
    for fbdiv in (16..=320u64).rev() {
        let vco = XOSC_HZ * fbdiv;
        if !(750_000_000..=1_600_000_000).contains(&vco) {
            continue;
        }
        for pd1 in (1..=7u64).rev() {
            for pd2 in 1..=pd1 {
                if vco == hz * pd1 * pd2 {
                    best = best.or(Some((fbdiv as u32, pd1 as u32, pd2 as u32)));
                }
            }
        }
    }
    best
}
