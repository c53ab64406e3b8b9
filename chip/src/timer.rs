//! The system timer (datasheet 4.6): a 64-bit microsecond count from the watchdog's tick
//! and four alarms on its low 32 bits, alarm n raising [`crate::irq::TIMER_IRQ_0`] + n.

/// Base address of the timer (datasheet 2.2).
pub const TIMER_BASE: u32 = 0x4005_4000;

/// Register offsets (datasheet 4.6.5).
pub mod reg {
    /// Write high word of time (after TIMELW).
    pub const TIMEHW: u32 = 0x00;
    /// Write low word of time.
    pub const TIMELW: u32 = 0x04;
    /// Read high word (latched by reading TIMELR).
    pub const TIMEHR: u32 = 0x08;
    /// Read low word (latches TIMEHR).
    pub const TIMELR: u32 = 0x0c;
    /// ALARM0 (ALARMn at `ALARM0 + 4n`, n < 4).
    pub const ALARM0: u32 = 0x10;
    /// Armed alarms; write 1 to disarm.
    pub const ARMED: u32 = 0x20;
    /// Raw high word, no latching.
    pub const TIMERAWH: u32 = 0x24;
    /// Raw low word, no latching.
    pub const TIMERAWL: u32 = 0x28;
    /// Raw interrupts; write 1 to clear.
    pub const INTR: u32 = 0x34;
    /// Interrupt enable.
    pub const INTE: u32 = 0x38;
    /// Interrupt force.
    pub const INTF: u32 = 0x3c;
    /// Interrupt status after masking and forcing.
    pub const INTS: u32 = 0x40;
}
