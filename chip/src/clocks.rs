//! CLOCKS, the clock generators (datasheet 2.15): clk_ref and clk_sys with their glitchless
//! source muxes and dividers.

/// Base address of CLOCKS (datasheet 2.15.7).
pub const CLOCKS_BASE: u32 = 0x4000_8000;

/// Register offsets (datasheet 2.15.7).
pub mod reg {
    /// CLK_REF_CTRL (SRC 1:0: 0 ROSC, 1 aux, 2 XOSC).
    pub const CLK_REF_CTRL: u32 = 0x30;
    /// CLK_REF_SELECTED (one-hot of the selected SRC).
    pub const CLK_REF_SELECTED: u32 = 0x38;
    /// CLK_SYS_CTRL (SRC bit 0: 0 clk_ref, 1 aux; AUXSRC 7:5: 0 PLL_SYS).
    pub const CLK_SYS_CTRL: u32 = 0x3c;
    /// CLK_SYS_DIV (integer part in 31:8).
    pub const CLK_SYS_DIV: u32 = 0x40;
    /// CLK_SYS_SELECTED (one-hot of the selected SRC).
    pub const CLK_SYS_SELECTED: u32 = 0x44;
}

/// CLK_SYS_DIV's reset value: divide by 1 (datasheet 2.15.7).
pub const CLK_SYS_DIV_RESET: u32 = 1 << 8;
