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

/// CTRL: the count down runs (datasheet 4.7.6; cleared, it is paused).
pub const CTRL_ENABLE: u32 = 1 << 30;
/// CTRL: writing 1 resets the chip at once (REASON FORCE); reads 0.
pub const CTRL_TRIGGER: u32 = 1 << 31;
/// CTRL: TIME, the count down (bits 23:0, read only).
pub const CTRL_TIME: u32 = 0x00ff_ffff;
/// CTRL: PAUSE_JTAG, PAUSE_DBG0, PAUSE_DBG1 (bits 26:24; reset value all set).
pub const CTRL_PAUSE: u32 = 0x0700_0000;
/// LOAD's width: the count down is 24 bits (datasheet 4.7.6).
pub const LOAD_MAX: u32 = 0x00ff_ffff;
/// REASON: the last reset was the count reaching 0.
pub const REASON_TIMER: u32 = 1 << 0;
/// REASON: the last reset was CTRL.TRIGGER.
pub const REASON_FORCE: u32 = 1 << 1;
/// Decrements of the count per tick: 2, not 1 (erratum RP2040-E1, "the watchdog counts
/// down twice as fast as it should": LOAD must be twice the microseconds wanted).
pub const DECREMENTS_PER_TICK: u32 = 2;
/// The boot ROM's watchdog entry: after a reset with `SCRATCH4` = this, `SCRATCH5` =
/// `SCRATCH7 ^ -SCRATCH4`, it clears `SCRATCH4` and enters `SCRATCH7` (Thumb bit set) with
/// SP = `SCRATCH6` instead of booting from flash (pico-bootrom `bootrom/bootrom_rt0.S`,
/// `check_wdog`; pico-sdk `watchdog_reboot` writes them so).
pub const BOOT_MAGIC: u32 = 0xb007_c0d3;

/// Whether the scratch registers hold a boot ROM watchdog entry ([`BOOT_MAGIC`]): the
/// entry `(pc, sp)` it takes.
pub fn boot_entry(scratch: &[u32; 8]) -> Option<(u32, u32)> {
    (scratch[4] == BOOT_MAGIC && scratch[5] == scratch[7] ^ BOOT_MAGIC.wrapping_neg())
        .then_some((scratch[7], scratch[6]))
}
