//! The blocks a firmware's start-up programs before anything runs at speed: RESETS, the
//! crystal oscillator (XOSC), the system PLL (PLL_SYS), the clock generators (CLOCKS), the
//! core voltage regulator (VREG_AND_CHIP_RESET) (RP2040 datasheet 2.14 Subsystem resets,
//! 2.15 Clocks, 2.16 XOSC, 2.18 PLL, 2.10 Core supply regulator; the watchdog and its
//! tick generator are [`crate::watchdog`]).
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
//!
//! **The source of the last reset.** CHIP_RESET (datasheet 2.12.7) reads
//! [`vreg::HAD_POR`]: every chip-level reset the emulator makes is a power-on or a
//! brown-out (`Machine::brown_out`); it models no RUN pin and no debugger's PSM restart. A
//! watchdog reset is not a chip-level reset and leaves CHIP_RESET as it was
//! ([`SysCtl::watchdog_reset`]; WATCHDOG.REASON says it, `crate::watchdog`). Its
//! PSM_RESTART_FLAG (bit 24, the debugger's) is not modelled: writes are ignored.

use tactus_rp2040::clocks::{self, CLOCKS_BASE};
use tactus_rp2040::pll::{self, PLL_SYS_BASE};
use tactus_rp2040::resets::{self, RESETS_BASE};
use tactus_rp2040::vreg::{self, min_core_mv, vsel_mv, VREG_AND_CHIP_RESET_BASE};
use tactus_rp2040::xosc::{self, XOSC_BASE, XOSC_HZ};

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
    /// CHIP_RESET (module documentation, "The source of the last reset").
    chip_reset: u32,
}

impl Default for SysCtl {
    /// Every block out of reset (what reset state the boot ROM leaves is not modelled);
    /// PLL_SYS powered down with REFDIV 1, FBDIV 0 and post dividers 7 × 7, clk_sys
    /// divided by 1, VREG enabled at 1.10 V (datasheet 2.18.4, 2.15.7 and 2.10.7 reset
    /// values).
    fn default() -> Self {
        let mut regs = std::collections::BTreeMap::new();
        regs.insert((PLL_SYS_BASE, pll::reg::CS), pll::CS_RESET);
        regs.insert((PLL_SYS_BASE, pll::reg::PWR), pll::PWR_RESET);
        regs.insert((PLL_SYS_BASE, pll::reg::PRIM), pll::PRIM_RESET);
        regs.insert(
            (CLOCKS_BASE, clocks::reg::CLK_SYS_DIV),
            clocks::CLK_SYS_DIV_RESET,
        );
        regs.insert(
            (VREG_AND_CHIP_RESET_BASE, vreg::reg::VREG),
            vreg::VREG_RESET,
        );
        SysCtl {
            regs,
            refusal: None,
            chip_reset: vreg::HAD_POR,
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
            (RESETS_BASE, resets::reg::RESET_DONE) => {
                !self.get(RESETS_BASE, resets::reg::RESET) & resets::ALL
            }
            (XOSC_BASE, xosc::reg::STATUS) => {
                let enabled = self.get(XOSC_BASE, xosc::reg::CTRL) >> 12 & 0xfff == 0xfab;
                v | (enabled as u32) << 31 | (enabled as u32) << 12
            }
            (PLL_SYS_BASE, pll::reg::CS) => v | pll::CS_LOCK,
            (CLOCKS_BASE, clocks::reg::CLK_REF_SELECTED) => {
                1 << (self.get(CLOCKS_BASE, clocks::reg::CLK_REF_CTRL) & 3)
            }
            (CLOCKS_BASE, clocks::reg::CLK_SYS_SELECTED) => {
                1 << (self.get(CLOCKS_BASE, clocks::reg::CLK_SYS_CTRL) & 1)
            }
            (VREG_AND_CHIP_RESET_BASE, vreg::reg::VREG) => v | ((v & 1) << 12),
            (VREG_AND_CHIP_RESET_BASE, vreg::reg::CHIP_RESET) => self.chip_reset,
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
        if (base, off) == (VREG_AND_CHIP_RESET_BASE, vreg::reg::CHIP_RESET) {
            return true; // read only (module documentation)
        }
        let old = self.get(base, off);
        let mut new = match (addr >> 12) & 3 {
            0 => value,
            1 => old ^ value,
            2 => old | value,
            _ => old & !value,
        };
        if (base, off) == (VREG_AND_CHIP_RESET_BASE, vreg::reg::VREG) {
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

    /// The registers after a watchdog reset: every one at its power-on value but
    /// CHIP_RESET, which a watchdog reset leaves as it was (module documentation).
    pub fn watchdog_reset(&mut self) {
        *self = SysCtl {
            chip_reset: self.chip_reset,
            ..SysCtl::default()
        };
    }

    /// CHIP_RESET as the firmware reads it (module documentation).
    pub fn chip_reset(&self) -> u32 {
        self.chip_reset
    }

    /// The refused write's reason, once (module documentation).
    pub fn take_refusal(&mut self) -> Option<Refusal> {
        self.refusal.take()
    }

    /// The core voltage VREG.VSEL sets, mV ([`vsel_mv`]).
    pub fn core_mv(&self) -> u32 {
        vsel_mv(self.get(VREG_AND_CHIP_RESET_BASE, vreg::reg::VREG) >> 4)
    }

    /// Whether RESETS holds the blocks of `bits` in reset.
    pub fn held_in_reset(&self, bits: u32) -> bool {
        self.get(RESETS_BASE, resets::reg::RESET) & bits != 0
    }

    /// The PLL_SYS output the firmware programmed, Hz: `XOSC_HZ / REFDIV × FBDIV /
    /// (POSTDIV1 × POSTDIV2)` (datasheet 2.18.2), or `None` while it is powered down,
    /// unlocked by its divider values (FBDIV outside 16–320, a zero divider) or the VCO
    /// outside 750–1600 MHz.
    pub fn pll_sys_hz(&self) -> Option<u64> {
        let cs = self.get(PLL_SYS_BASE, pll::reg::CS);
        let pwr = self.get(PLL_SYS_BASE, pll::reg::PWR);
        let fbdiv = self.get(PLL_SYS_BASE, pll::reg::FBDIV_INT) as u64 & 0xfff;
        let prim = self.get(PLL_SYS_BASE, pll::reg::PRIM);
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
        let ctrl = self.get(CLOCKS_BASE, clocks::reg::CLK_SYS_CTRL);
        let div = (self.get(CLOCKS_BASE, clocks::reg::CLK_SYS_DIV) >> 8) as u64;
        if ctrl & 1 != 1 || ctrl >> 5 & 7 != 0 || div == 0 {
            return None;
        }
        self.pll_sys_hz().map(|f| f / div)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chip_reset_reads_a_power_on_and_a_watchdog_reset_keeps_it() {
        let at = VREG_AND_CHIP_RESET_BASE + vreg::reg::CHIP_RESET;
        let mut s = SysCtl::default();
        assert_eq!(s.read(at), Some(vreg::HAD_POR));
        // Read only: a write (any alias) changes nothing.
        assert!(s.write(at, 0));
        assert!(s.write(at + 0x3000, vreg::HAD_POR));
        assert_eq!(s.read(at), Some(vreg::HAD_POR));
        // A watchdog reset puts VREG back but keeps CHIP_RESET.
        s.chip_reset = vreg::HAD_RUN;
        let vreg_at = VREG_AND_CHIP_RESET_BASE + vreg::reg::VREG;
        assert!(s.write(vreg_at, 0xc1));
        s.watchdog_reset();
        assert_eq!(s.read(at), Some(vreg::HAD_RUN));
        assert_eq!(s.read(vreg_at), Some(vreg::VREG_RESET | vreg::VREG_ROK));
    }
}
