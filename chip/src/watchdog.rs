//! WATCHDOG (datasheet 4.7): the watchdog timer, its scratch registers, and the tick
//! generator whose 1 µs pulse clocks the timer and the cores' SysTick.

/// Base address of WATCHDOG (datasheet 4.7.6).
pub const WATCHDOG_BASE: u32 = 0x4005_8000;

/// Register offsets (datasheet 4.7.6).
pub mod reg {
    /// CTRL: TIME 23:0 (the count down, read only), PAUSE_JTAG 24, PAUSE_DBG0 25,
    /// PAUSE_DBG1 26, ENABLE 30, TRIGGER 31 (reset value 0x07000000).
    pub const CTRL: u32 = 0x00;
    /// LOAD: writes the count down (the chip counts it down twice a tick: erratum RP2040-E1).
    pub const LOAD: u32 = 0x04;
    /// REASON: why the last reset was the watchdog's (TIMER 0, FORCE 1).
    pub const REASON: u32 = 0x08;
    /// SCRATCH0 (SCRATCHn at `SCRATCH0 + 4n`, n < 8): kept across a watchdog reset.
    pub const SCRATCH0: u32 = 0x0c;
    /// TICK (CYCLES 8:0, ENABLE bit 9, RUNNING bit 10, COUNT 19:11).
    pub const TICK: u32 = 0x2c;
}

/// TICK: the tick generator is enabled.
pub const TICK_ENABLE: u32 = 1 << 9;
