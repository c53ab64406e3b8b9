//! IO_BANK0, the user GPIOs' function select and status (datasheet 2.19).

/// IO_BANK0 (datasheet 2.19.6.1): GPIOn_STATUS at `8n`, GPIOn_CTRL at `8n + 4`.
pub const IO_BANK0_BASE: u32 = 0x4001_4000;
/// GPIOs of the RP2040's bank 0 (GPIO0–GPIO29).
pub const GPIOS: usize = 30;
/// GPIOn_CTRL's FUNCSEL giving the pad to PIO0 (datasheet 2.19.2; PIO1 is 7).
pub const FUNCSEL_PIO0: u32 = 6;
/// GPIOn_CTRL's FUNCSEL giving the pad to PIO1.
pub const FUNCSEL_PIO1: u32 = 7;
/// GPIOn_CTRL's FUNCSEL at reset: no function (NULL).
pub const FUNCSEL_NULL: u32 = 31;
