//! SIO, the single-cycle IO block (datasheet 2.3.1): each core's own view at one address
//! (CPUID, its end of the inter-core FIFOs, its divider), the shared spinlocks.

/// Base address of SIO (datasheet 2.2).
pub const SIO_BASE: u32 = 0xd000_0000;
/// Depth of each inter-core FIFO in 32-bit words (datasheet 2.3.1.4).
pub const FIFO_DEPTH: usize = 8;

/// Register offsets within SIO (datasheet 2.3.1.7).
pub mod reg {
    /// Processor core identifier: 0 or 1.
    pub const CPUID: u32 = 0x000;
    /// FIFO status: VLD(0), RDY(1), WOF(2), ROE(3).
    pub const FIFO_ST: u32 = 0x050;
    /// Write to the other core's RX FIFO.
    pub const FIFO_WR: u32 = 0x054;
    /// Read from this core's RX FIFO.
    pub const FIFO_RD: u32 = 0x058;
    /// Spinlock state, bit n = lock n held.
    pub const SPINLOCK_ST: u32 = 0x05c;
    /// Unsigned dividend.
    pub const DIV_UDIVIDEND: u32 = 0x060;
    /// Unsigned divisor.
    pub const DIV_UDIVISOR: u32 = 0x064;
    /// Signed dividend.
    pub const DIV_SDIVIDEND: u32 = 0x068;
    /// Signed divisor.
    pub const DIV_SDIVISOR: u32 = 0x06c;
    /// Quotient (reading clears DIRTY).
    pub const DIV_QUOTIENT: u32 = 0x070;
    /// Remainder.
    pub const DIV_REMAINDER: u32 = 0x074;
    /// Divider status: READY(0), DIRTY(1).
    pub const DIV_CSR: u32 = 0x078;
    /// Spinlock 0 (spinlock n at `SPINLOCK0 + 4n`, n < 32).
    pub const SPINLOCK0: u32 = 0x100;
}
