//! PLL_SYS, the system PLL (datasheet 2.18): clk_sys from the crystal as
//! XOSC / REFDIV × FBDIV / POSTDIV1 / POSTDIV2, with the VCO between 750 and 1600 MHz.

use crate::xosc::XOSC_HZ;

/// Base address of PLL_SYS (datasheet 2.18.4).
pub const PLL_SYS_BASE: u32 = 0x4002_8000;

/// Register offsets (datasheet 2.18.4).
pub mod reg {
    /// CS (REFDIV 5:0, LOCK bit 31).
    pub const CS: u32 = 0x0;
    /// PWR (PD bit 0, POSTDIVPD bit 3, VCOPD bit 5).
    pub const PWR: u32 = 0x4;
    /// FBDIV_INT.
    pub const FBDIV_INT: u32 = 0x8;
    /// PRIM (POSTDIV1 18:16, POSTDIV2 14:12).
    pub const PRIM: u32 = 0xc;
}

/// CS: the PLL is locked.
pub const CS_LOCK: u32 = 1 << 31;
/// CS's reset value: REFDIV 1 (datasheet 2.18.4).
pub const CS_RESET: u32 = 1;
/// PWR's reset value: PD, POSTDIVPD and VCOPD set (powered down).
pub const PWR_RESET: u32 = 0x2d;
/// PRIM's reset value: POSTDIV1 7, POSTDIV2 7.
pub const PRIM_RESET: u32 = 0x7 << 16 | 0x7 << 12;

/// PLL_SYS dividers for a clk_sys of `hz` from [`XOSC_HZ`]: (FBDIV, POSTDIV1, POSTDIV2)
/// with REFDIV 1, the VCO in 750–1600 MHz and POSTDIV1 ≥ POSTDIV2 (datasheet 2.18.2),
/// preferring the highest VCO (less jitter), then the larger POSTDIV1 (pico-sdk's 125 MHz:
/// 1500 MHz / 6 / 2). `None` when no setting gives exactly `hz`.
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
