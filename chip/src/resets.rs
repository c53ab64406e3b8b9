//! RESETS, the subsystem resets (datasheet 2.14): a bit per block in RESET holds it in
//! reset; RESET_DONE reads which are out of reset and ready.

/// Base address of RESETS (datasheet 2.14.3).
pub const RESETS_BASE: u32 = 0x4000_c000;

/// Register offsets (datasheet 2.14.3).
pub mod reg {
    /// Blocks held in reset (bit per block).
    pub const RESET: u32 = 0x0;
    /// Watchdog select: blocks the watchdog resets (bit per block).
    pub const WDSEL: u32 = 0x4;
    /// Blocks out of reset and ready.
    pub const RESET_DONE: u32 = 0x8;
}

/// BUSCTRL's bit.
pub const BUSCTRL: u32 = 1 << 1;
/// The DMA's bit.
pub const DMA: u32 = 1 << 2;
/// IO_BANK0's bit.
pub const IO_BANK0: u32 = 1 << 5;
/// PIO0's bit.
pub const PIO0: u32 = 1 << 10;
/// PIO1's bit.
pub const PIO1: u32 = 1 << 11;
/// PLL_SYS's bit.
pub const PLL_SYS: u32 = 1 << 12;
/// TIMER's bit.
pub const TIMER: u32 = 1 << 21;
/// Every block's bit (bits 24:0).
pub const ALL: u32 = 0x01ff_ffff;
