//! The flash chip the boot path expects behind the SSI: the Raspberry Pi Pico's 2 MB
//! Winbond W25Q16JV (its datasheet, rev. F), as far as boot2 programs it. Not the RP2040's
//! own map, but what every RP2040 board of this project carries, and both the emulator's
//! chip model (`tactus_emulator::xip`) and the firmware's boot2 need it.

/// Status register 2's quad-enable bit (W25Q16JV datasheet 7.1.10: QE, non-volatile): IO2
/// and IO3 are data lines only while it is set.
pub const SR2_QE: u8 = 1 << 1;
