//! XOSC, the crystal oscillator (datasheet 2.16).

/// Base address of XOSC (datasheet 2.16.7).
pub const XOSC_BASE: u32 = 0x4002_4000;
/// The crystal on the Raspberry Pi Pico and most RP2040 boards, Hz (datasheet 2.16.1).
pub const XOSC_HZ: u64 = 12_000_000;

/// Register offsets (datasheet 2.16.7).
pub mod reg {
    /// CTRL (FREQ_RANGE 11:0, ENABLE 23:12).
    pub const CTRL: u32 = 0x00;
    /// STATUS (STABLE is bit 31).
    pub const STATUS: u32 = 0x04;
    /// STARTUP (DELAY in units of 256 reference cycles).
    pub const STARTUP: u32 = 0x0c;
}

/// CTRL's FREQ_RANGE for a 1–15 MHz crystal.
pub const CTRL_FREQ_RANGE_1_15MHZ: u32 = 0xaa0;
/// CTRL value: enabled (ENABLE = 0xfab), 1–15 MHz range.
pub const CTRL_ENABLE_1_15MHZ: u32 = 0xfab << 12 | CTRL_FREQ_RANGE_1_15MHZ;
/// STATUS: the oscillator is running and stable.
pub const STATUS_STABLE: u32 = 1 << 31;
