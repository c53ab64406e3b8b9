//! The DMA controller (datasheet 2.5): twelve channels, each with four control registers
//! seen through four aliases, paced by a data request (DREQ), a pacing timer or nothing.

/// Base address of the DMA's registers (datasheet 2.2).
pub const DMA_BASE: u32 = 0x5000_0000;

/// Channels of the RP2040's DMA (datasheet 2.5: "12 independent channels").
pub const CHANNELS: usize = 12;

/// Register offsets (datasheet 2.5.7).
pub mod reg {
    /// Bytes between one channel's registers and the next's.
    pub const CH_STRIDE: u32 = 0x40;
    /// Alias 0: READ_ADDR, WRITE_ADDR, TRANS_COUNT, CTRL_TRIG.
    pub const READ_ADDR: u32 = 0x00;
    /// Alias 0's write address.
    pub const WRITE_ADDR: u32 = 0x04;
    /// Alias 0's transfer count (reload value when written, remaining count when read).
    pub const TRANS_COUNT: u32 = 0x08;
    /// Alias 0's control register, a trigger.
    pub const CTRL_TRIG: u32 = 0x0c;
    /// Alias 1: CTRL, READ_ADDR, WRITE_ADDR, TRANS_COUNT_TRIG.
    pub const AL1_CTRL: u32 = 0x10;
    /// Alias 1's trigger: the transfer count, used at once.
    pub const AL1_TRANS_COUNT_TRIG: u32 = 0x1c;
    /// Alias 2: CTRL, TRANS_COUNT, READ_ADDR, WRITE_ADDR_TRIG.
    pub const AL2_CTRL: u32 = 0x20;
    /// Alias 2's trigger: the write address.
    pub const AL2_WRITE_ADDR_TRIG: u32 = 0x2c;
    /// Alias 3: CTRL, WRITE_ADDR, TRANS_COUNT, READ_ADDR_TRIG.
    pub const AL3_CTRL: u32 = 0x30;
    /// Alias 3's trigger: the read address.
    pub const AL3_READ_ADDR_TRIG: u32 = 0x3c;
    /// Raw interrupt flags, one bit a channel; write 1 to clear.
    pub const INTR: u32 = 0x400;
    /// Interrupt enables of DMA_IRQ_0.
    pub const INTE0: u32 = 0x404;
    /// Forced interrupts of DMA_IRQ_0.
    pub const INTF0: u32 = 0x408;
    /// Masked status of DMA_IRQ_0; write 1 to clear the raw flag.
    pub const INTS0: u32 = 0x40c;
    /// Interrupt enables of DMA_IRQ_1.
    pub const INTE1: u32 = 0x414;
    /// Forced interrupts of DMA_IRQ_1.
    pub const INTF1: u32 = 0x418;
    /// Masked status of DMA_IRQ_1; write 1 to clear the raw flag.
    pub const INTS1: u32 = 0x41c;
    /// Pacing timer 0 (X in bits 31:16, Y in 15:0); TIMER1–3 follow every 4 bytes.
    pub const TIMER0: u32 = 0x420;
    /// Starts every channel whose bit is set (as a trigger write would).
    pub const MULTI_CHAN_TRIGGER: u32 = 0x430;
    /// Ends the sequence of every channel whose bit is set, without an interrupt.
    pub const CHAN_ABORT: u32 = 0x444;
    /// The number of channels (reads 12).
    pub const N_CHANNELS: u32 = 0x448;
    /// Channel 0's transfer-count reload value (`CHn_DBG_TCR` at `DBG_TCR + CH_STRIDE·n`).
    pub const DBG_TCR: u32 = 0x804;
}

/// Fields of a channel's CTRL register (datasheet 2.5.7, CH0_CTRL_TRIG).
pub mod ctrl {
    /// The channel responds to triggers and issues transfers; clearing it pauses.
    pub const EN: u32 = 1 << 0;
    /// Served before low-priority channels in each scheduling round.
    pub const HIGH_PRIORITY: u32 = 1 << 1;
    /// Data size: bits 3:2, 0 byte, 1 halfword, 2 word.
    pub const DATA_SIZE_SHIFT: u32 = 2;
    /// The read address advances with each transfer.
    pub const INCR_READ: u32 = 1 << 4;
    /// The write address advances with each transfer.
    pub const INCR_WRITE: u32 = 1 << 5;
    /// Ring size: bits 9:6; n > 0 wraps the ring address on a 2^n-byte boundary.
    pub const RING_SIZE_SHIFT: u32 = 6;
    /// The ring applies to the write address (else the read address).
    pub const RING_SEL: u32 = 1 << 10;
    /// Channel triggered at the end of a sequence: bits 14:11 (itself: none).
    pub const CHAIN_TO_SHIFT: u32 = 11;
    /// Transfer request: bits 20:15, DREQ 0–0x3a, timers 0x3b–0x3e, 0x3f unpaced.
    pub const TREQ_SEL_SHIFT: u32 = 15;
    /// Interrupt on null triggers only, not at the end of each sequence.
    pub const IRQ_QUIET: u32 = 1 << 21;
    /// Swap the bytes of each halfword or word.
    pub const BSWAP: u32 = 1 << 22;
    /// Visible to the sniffer (not modelled).
    pub const SNIFF_EN: u32 = 1 << 23;
    /// The channel is in a transfer sequence (read only).
    pub const BUSY: u32 = 1 << 24;
    /// A write faulted; write 1 to clear.
    pub const WRITE_ERROR: u32 = 1 << 29;
    /// A read faulted; write 1 to clear.
    pub const READ_ERROR: u32 = 1 << 30;
    /// READ_ERROR or WRITE_ERROR (read only).
    pub const AHB_ERROR: u32 = 1 << 31;
    /// The fields software writes (everything but BUSY and the error flags).
    pub const WRITABLE: u32 = 0x00ff_ffff;
}

/// TREQ_SEL of the first pacing timer (TIMER1–3 follow).
pub const TREQ_TIMER0: u32 = 0x3b;
/// TREQ_SEL of an unpaced channel ("permanent request").
pub const TREQ_PERMANENT: u32 = 0x3f;

/// Whether DREQ `n` (datasheet table 2.5.3.1) is a receive request, whose transfer reaches
/// the peripheral with its read (the DMA takes a word out of an RX FIFO), rather than a
/// transmit request, whose transfer reaches it with its write. PIO RX 4–7 and 12–15, SPI
/// RX 17 and 19, UART RX 21 and 23, I2C RX 33 and 35, ADC 36, XIP_STREAM 37 and XIP_SSIRX
/// 39 receive; the others (the PWM wraps among them) transmit.
pub fn dreq_is_rx(n: u32) -> bool {
    matches!(n, 4..=7 | 12..=15 | 17 | 19 | 21 | 23 | 33 | 35 | 36 | 37 | 39)
}
