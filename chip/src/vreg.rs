//! VREG_AND_CHIP_RESET, the core supply regulator (datasheet 2.10): VSEL sets the core
//! voltage, and the fastest clk_sys a voltage is specified for.

/// Base address of VREG_AND_CHIP_RESET (datasheet 2.10.7).
pub const VREG_AND_CHIP_RESET_BASE: u32 = 0x4006_4000;
/// The core voltage at reset, mV (VREG.VSEL = 0b1011, datasheet 2.10.7).
pub const DEFAULT_CORE_MV: u32 = 1100;

/// Register offsets (datasheet 2.10.7).
pub mod reg {
    /// VREG (EN bit 0, HIZ bit 1, VSEL 7:4, ROK bit 12).
    pub const VREG: u32 = 0x0;
    /// CHIP_RESET: the source of the last chip-level reset (datasheet 2.10.7 and 2.12.7,
    /// "Source of Last Reset"): [`super::HAD_POR`], [`super::HAD_RUN`],
    /// [`super::HAD_PSM_RESTART`], read only.
    pub const CHIP_RESET: u32 = 0x8;
}

/// CHIP_RESET: the last chip-level reset was from the power-on reset or the brown-out
/// detection block (bit 8). The two cannot be told apart on the RP2040. A watchdog reset
/// is not a chip-level reset and leaves CHIP_RESET as it was (WATCHDOG.REASON tells it;
/// a chip-level reset clears REASON): so after a watchdog reset of a board that powered
/// on, HAD_POR is still set, and a reset's cause is REASON's first, CHIP_RESET's only when
/// REASON is 0 (as CircuitPython's `common_hal_mcu_processor_get_reset_reason` reads
/// them: "watchdog doesn't clear chip_reset, while chip_reset clears the watchdog").
pub const HAD_POR: u32 = 1 << 8;
/// CHIP_RESET: the last chip-level reset was from the RUN pin (bit 16).
pub const HAD_RUN: u32 = 1 << 16;
/// CHIP_RESET: the last chip-level reset was from the debug port's PSM restart (bit 20).
pub const HAD_PSM_RESTART: u32 = 1 << 20;

/// VREG: VSEL's bits.
pub const VREG_VSEL_BITS: u32 = 0xf0;
/// VREG: regulation OK (read only).
pub const VREG_ROK: u32 = 1 << 12;
/// VREG's reset value: enabled, VSEL 0b1011 (1.10 V).
pub const VREG_RESET: u32 = 0xb1;

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vsel_and_mv_invert_each_other() {
        for vsel in 5..=15 {
            assert_eq!(vsel_of_mv(vsel_mv(vsel)), Some(vsel));
        }
        assert_eq!(vsel_mv(VREG_RESET >> 4 & 15), DEFAULT_CORE_MV);
        assert_eq!(vsel_of_mv(1125), None);
    }
}
