//! BUSCTRL, the bus fabric's controls (datasheet 2.1.5): which masters win arbitration.

/// BUSCTRL (datasheet 2.1.5): BUS_PRIORITY at 0.
pub const BUSCTRL_BASE: u32 = 0x4003_0000;

/// Register offsets (datasheet 2.1.5).
pub mod reg {
    /// BUS_PRIORITY: a bit per master ([`super::priority`]).
    pub const BUS_PRIORITY: u32 = 0x00;
    /// BUS_PRIORITY_ACK: reads 1 once the new priorities are in force.
    pub const BUS_PRIORITY_ACK: u32 = 0x04;
}

/// BUS_PRIORITY's fields (datasheet 2.1.5): 1 is high priority.
pub mod priority {
    /// Core 0.
    pub const PROC0: u32 = 1 << 0;
    /// Core 1.
    pub const PROC1: u32 = 1 << 4;
    /// The DMA's read master.
    pub const DMA_R: u32 = 1 << 8;
    /// The DMA's write master.
    pub const DMA_W: u32 = 1 << 12;
}
