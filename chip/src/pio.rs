//! The PIO blocks (datasheet chapter 3): PIO0 and PIO1, each four state machines sharing
//! 32 instruction words, with their FIFOs and the DMA requests they raise.

/// Base address of PIO0 (datasheet 2.2).
pub const PIO0_BASE: u32 = 0x5020_0000;
/// Base address of PIO1.
pub const PIO1_BASE: u32 = 0x5030_0000;

/// Register offsets (datasheet 3.7).
pub mod reg {
    /// State machine enables, restarts and clock-divider restarts.
    pub const CTRL: u32 = 0x000;
    /// FIFO status: RXFULL 3:0, RXEMPTY 11:8, TXFULL 19:16, TXEMPTY 27:24.
    pub const FSTAT: u32 = 0x004;
    /// FIFO debug (stall and overflow flags; reads 0 here).
    pub const FDEBUG: u32 = 0x008;
    /// FIFO levels: TX n at bits 8n+3:8n, RX n at 8n+7:8n+4.
    pub const FLEVEL: u32 = 0x00c;
    /// TX FIFO of state machine 0 (TXFn at `TXF0 + 4n`); write only.
    pub const TXF0: u32 = 0x010;
    /// RX FIFO of state machine 0 (RXFn at `RXF0 + 4n`); read only.
    pub const RXF0: u32 = 0x020;
    /// The eight IRQ flags; write 1 to clear.
    pub const IRQ: u32 = 0x030;
    /// Write 1 to set IRQ flags.
    pub const IRQ_FORCE: u32 = 0x034;
    /// GPIOs whose input synchroniser is bypassed.
    pub const INPUT_SYNC_BYPASS: u32 = 0x038;
    /// First instruction word (INSTR_MEMn at `INSTR_MEM0 + 4n`, n < 32); write only.
    pub const INSTR_MEM0: u32 = 0x048;
    /// State machine 0's clock divider (state machine n's registers at `+ 0x18 n`).
    pub const SM0_CLKDIV: u32 = 0x0c8;
    /// State machine 0's execution settings.
    pub const SM0_EXECCTRL: u32 = 0x0cc;
    /// State machine 0's shift settings.
    pub const SM0_SHIFTCTRL: u32 = 0x0d0;
    /// State machine 0's program counter (read only).
    pub const SM0_ADDR: u32 = 0x0d4;
    /// State machine 0's current instruction; a write executes one immediately.
    pub const SM0_INSTR: u32 = 0x0d8;
    /// State machine 0's pin mapping.
    pub const SM0_PINCTRL: u32 = 0x0dc;
    /// Distance between two state machines' register groups.
    pub const SM_STRIDE: u32 = 0x18;
}

/// Reset value of SMx_CLKDIV: INT = 1 (datasheet 3.7).
pub const CLKDIV_RESET: u32 = 0x0001_0000;
/// Reset value of SMx_EXECCTRL: WRAP_TOP = 31.
pub const EXECCTRL_RESET: u32 = 0x0001_f000;
/// Reset value of SMx_SHIFTCTRL: IN_SHIFTDIR and OUT_SHIFTDIR right.
pub const SHIFTCTRL_RESET: u32 = 0x000c_0000;
/// Reset value of SMx_PINCTRL: SET_COUNT = 5.
pub const PINCTRL_RESET: u32 = 0x1400_0000;

/// DREQ of PIO0's TX FIFO of state machine 0 (datasheet 2.5.3.1: PIO0 TX0–3 are 0–3, RX0–3
/// 4–7; PIO1 TX0–3 8–11, RX0–3 12–15).
pub const DREQ_PIO0_TX0: u32 = 0;
/// DREQ of PIO0's RX FIFO of state machine 0.
pub const DREQ_PIO0_RX0: u32 = 4;
/// DREQ of PIO1's TX FIFO of state machine 0.
pub const DREQ_PIO1_TX0: u32 = 8;
/// DREQ of PIO1's RX FIFO of state machine 0.
pub const DREQ_PIO1_RX0: u32 = 12;
