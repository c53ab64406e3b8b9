//! The blocks a firmware's start-up programs before anything runs at speed: RESETS, the
//! crystal oscillator (XOSC), the system PLL (PLL_SYS), the clock generators (CLOCKS), the
//! core voltage regulator (VREG_AND_CHIP_RESET) and the watchdog's tick generator (RP2040
//! datasheet 2.14 Subsystem resets, 2.15 Clocks, 2.16 XOSC, 2.18 PLL, 2.10 Core supply
//! regulator, 4.7 Watchdog).
//!
//! **A minimal model.** Each register is plain memory (with the datasheet's atomic SET,
//! CLR and XOR aliases, 2.1.2), except for the status bits a start-up polls, which read as
//! done at once: `RESET_DONE` is set for every block not held in reset, `XOSC STATUS.STABLE`
//! once the oscillator is enabled, `PLL CS.LOCK` always, and `CLK_REF_SELECTED` /
//! `CLK_SYS_SELECTED` follow the glitchless mux selected in `CTRL.SRC`. Nothing here
//! changes the emulated clock, which is [`crate::board::Config::clock_hz`] from power-on;
//! the timer counts microseconds of that clock whatever the watchdog tick says, from its
//! last release from reset ([`crate::timer`]). [`SysCtl::pll_sys_hz`] decodes what the firmware programmed, so a test can check
//! that a start-up sets the clock its board file names. Not modelled: oscillator start-up
//! and PLL lock times (about 1 ms and tens of µs on the chip), clock dividers other than
//! the PLL's, the USB PLL.
//!
//! **The core voltage.** VREG's VSEL sets the core supply (reset value 1.10 V, datasheet
//! 2.10.7; ROK reads as in regulation at once: the settling time is not modelled). The
//! RP2040 is specified up to 133 MHz at that voltage and, since pico-sdk 2.1.1, up to
//! 200 MHz at 1.15 V ([`min_core_mv`]). A write that would run clk_sys from the PLL faster
//! than the core voltage allows — switching clk_sys to a PLL above 133 MHz before raising
//! VREG, or lowering VREG under a fast clock — is refused: the store faults and the board
//! stops with [`crate::StopReason::Refused`] naming the clock and the voltage
//! ([`Refusal`]), where a real chip might run on with timing failures.

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
/// VREG_AND_CHIP_RESET (datasheet 2.10.7).
pub const VREG_AND_CHIP_RESET_BASE: u32 = 0x4006_4000;
/// The core voltage at reset, mV (VREG.VSEL = 0b1011, datasheet 2.10.7).
pub const DEFAULT_CORE_MV: u32 = 1100;
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
    /// VREG_AND_CHIP_RESET: VREG (EN bit 0, HIZ bit 1, VSEL 7:4, ROK bit 12).
    pub const VREG: u32 = 0x0;
    /// VREG: VSEL's bits.
    pub const VREG_VSEL_BITS: u32 = 0xf0;
    /// VREG: regulation OK (read only).
    pub const VREG_ROK: u32 = 1 << 12;
}

/// The core voltage of VREG.VSEL `vsel` (datasheet 2.10.7: 0b0000–0b0101 are 0.80 V, then
/// 50 mV a step up to 0b1111, 1.30 V), mV.
pub fn vsel_mv(vsel: u32) -> u32 {
    800 + 50 * (vsel & 15).saturating_sub(5)
}

/// The VREG.VSEL that gives `mv` (0.85 V to 1.30 V in 50 mV steps; 0.80 V is 0b0101),
/// `None` for a voltage the regulator does not make.
pub fn vsel_of_mv(mv: u32) -> Option<u32> {
    ((800..=1300).contains(&mv) && mv.is_multiple_of(50)).then(|| (mv - 800) / 50 + 5)
}

/// The least core voltage at which the RP2040 is specified to run clk_sys at `clk_hz`, mV:
/// 1.10 V (the default) up to 133 MHz (RP2040 datasheet, 1.2: "up to 133 MHz"), 1.15 V up
/// to 200 MHz (pico-sdk 2.1.1, `hardware/clocks.h`: for `SYS_CLK_MHZ=200` on the RP2040,
/// `SYS_CLK_VREG_VOLTAGE_MIN = VREG_VOLTAGE_1_15`, raised before clk_sys is switched to the
/// PLL; the release notes add the 200 MHz PLL configuration as supported); `None` above
/// 200 MHz, which nothing certifies.
pub fn min_core_mv(clk_hz: u64) -> Option<u32> {
    match clk_hz {
        0..=133_000_000 => Some(DEFAULT_CORE_MV),
        133_000_001..=200_000_000 => Some(1150),
        _ => None,
    }
}

/// Why the emulator refused a clock or voltage write (module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Refusal {
    /// clk_sys the write would run, Hz.
    pub clk_sys_hz: u64,
    /// The core voltage then, mV.
    pub core_mv: u32,
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (mhz, v) = (self.clk_sys_hz as f64 / 1e6, self.core_mv as f64 / 1e3);
        match min_core_mv(self.clk_sys_hz) {
            Some(need) => write!(
                f,
                "clk_sys would run at {mhz} MHz with the core at {v:.2} V: the RP2040 needs                  {:.2} V or more for that clock (pico-sdk 2.1.1); raise VREG (VSEL) before                  switching clk_sys to the PLL, as pico-sdk's clock set-up does (in a board file:                  `core_voltage_v = {:.2}`)",
                need as f64 / 1e3,
                need as f64 / 1e3
            ),
            None => write!(
                f,
                "clk_sys would run at {mhz} MHz: beyond the 200 MHz the RP2040 is specified for                  (at 1.15 V, pico-sdk 2.1.1)"
            ),
        }
    }
}

/// The registers of the start-up blocks (see the module documentation).
#[derive(Clone, Debug)]
pub struct SysCtl {
    /// (block base, register offset) → value.
    regs: std::collections::BTreeMap<(u32, u32), u32>,
    /// The last write refused (module documentation), until the board takes it.
    pub(crate) refusal: Option<Refusal>,
}

impl Default for SysCtl {
    /// Every block out of reset (what reset state the boot ROM leaves is not modelled);
    /// PLL_SYS powered down with REFDIV 1, FBDIV 0 and post dividers 7 × 7, clk_sys
    /// divided by 1, VREG enabled at 1.10 V (datasheet 2.18.4, 2.15.7 and 2.10.7 reset
    /// values).
    fn default() -> Self {
        let mut regs = std::collections::BTreeMap::new();
        regs.insert((PLL_SYS_BASE, reg::PLL_CS), 1);
        regs.insert((PLL_SYS_BASE, reg::PLL_PWR), 0x2d);
        regs.insert((PLL_SYS_BASE, reg::PLL_PRIM), 0x7 << 16 | 0x7 << 12);
        regs.insert((CLOCKS_BASE, reg::CLK_SYS_DIV), 1 << 8);
        regs.insert((VREG_AND_CHIP_RESET_BASE, reg::VREG), 0xb1);
        SysCtl {
            regs,
            refusal: None,
        }
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
        VREG_AND_CHIP_RESET_BASE,
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
            (VREG_AND_CHIP_RESET_BASE, reg::VREG) => v | ((v & 1) << 12),
            _ => v,
        })
    }

    /// Writes `value` at `addr`: `+0x1000` XOR, `+0x2000` SET, `+0x3000` CLR (datasheet
    /// 2.1.2). False when `addr` is not in one of the blocks, or when the write is refused
    /// (clk_sys faster than the core voltage allows, module documentation: the write is
    /// made and [`SysCtl::take_refusal`] says why).
    pub fn write(&mut self, addr: u32, value: u32) -> bool {
        let Some(base) = block_of(addr) else {
            return false;
        };
        let off = addr & 0xffc;
        let old = self.get(base, off);
        let mut new = match (addr >> 12) & 3 {
            0 => value,
            1 => old ^ value,
            2 => old | value,
            _ => old & !value,
        };
        if (base, off) == (VREG_AND_CHIP_RESET_BASE, reg::VREG) {
            new &= 0xf3; // EN, HIZ, VSEL; ROK is read only
        }
        self.regs.insert((base, off), new);
        if let Some(clk) = self.clk_sys_hz() {
            let core_mv = self.core_mv();
            if min_core_mv(clk).is_none_or(|need| core_mv < need) {
                self.refusal = Some(Refusal {
                    clk_sys_hz: clk,
                    core_mv,
                });
                return false;
            }
        }
        true
    }

    /// The refused write's reason, once (module documentation).
    pub fn take_refusal(&mut self) -> Option<Refusal> {
        self.refusal.take()
    }

    /// The core voltage VREG.VSEL sets, mV ([`vsel_mv`]).
    pub fn core_mv(&self) -> u32 {
        vsel_mv(self.get(VREG_AND_CHIP_RESET_BASE, reg::VREG) >> 4)
    }

    /// Whether RESETS holds the blocks of `bits` in reset.
    pub fn held_in_reset(&self, bits: u32) -> bool {
        self.get(RESETS_BASE, reg::RESET) & bits != 0
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
