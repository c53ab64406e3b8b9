//! The SSI, a Synopsys DW_apb_ssi, between the cores and the QSPI flash (datasheet 4.10):
//! what boot2 programs to set up execute-in-place.

/// The SSI's registers (datasheet 4.10.13).
pub const XIP_SSI_BASE: u32 = 0x1800_0000;
/// Bytes of the SSI's register block.
pub const XIP_SSI_SIZE: u32 = 0x100;
/// Depth of each SSI FIFO (datasheet 4.10.2: 16 entries).
pub const FIFO_DEPTH: usize = 16;

/// SSI register offsets and fields (datasheet 4.10.13).
pub mod reg {
    /// Control register 0: DFS_32 (20:16), SPI_FRF (22:21), TMOD (9:8), SCPOL, SCPH.
    pub const CTRLR0: u32 = 0x00;
    /// Control register 1: NDF (15:0), data frames of an EEPROM read minus one.
    pub const CTRLR1: u32 = 0x04;
    /// SSI enable.
    pub const SSIENR: u32 = 0x08;
    /// Slave enable (bit 0: the flash).
    pub const SER: u32 = 0x10;
    /// Baud rate: SCKDV (15:0), system clock cycles per serial clock (even).
    pub const BAUDR: u32 = 0x14;
    /// TX FIFO level.
    pub const TXFLR: u32 = 0x20;
    /// RX FIFO level.
    pub const RXFLR: u32 = 0x24;
    /// Status: BUSY 0, TFNF 1, TFE 2, RFNE 3, RFF 4.
    pub const SR: u32 = 0x28;
    /// Interrupt clear (read): clears the sticky errors.
    pub const ICR: u32 = 0x48;
    /// Identification code (reads 0x51535049).
    pub const IDR: u32 = 0x58;
    /// Component version (reads 0x3430312a).
    pub const SSI_VERSION_ID: u32 = 0x5c;
    /// Data register 0: write to push a TX frame, read to pop an RX frame.
    pub const DR0: u32 = 0x60;
    /// RX sample delay.
    pub const RX_SAMPLE_DLY: u32 = 0xf0;
    /// Enhanced SPI control: TRANS_TYPE (1:0), ADDR_L (5:2, in 4-bit units), INST_L (9:8:
    /// 0, 4, 8, 16 bits), WAIT_CYCLES (15:11), XIP_CMD (31:24).
    pub const SPI_CTRLR0: u32 = 0xf4;
    /// TX drive edge.
    pub const TXD_DRIVE_EDGE: u32 = 0xf8;
    /// SR: a transfer is in progress.
    pub const SR_BUSY: u32 = 1 << 0;
    /// SR: the TX FIFO is not full.
    pub const SR_TFNF: u32 = 1 << 1;
    /// SR: the TX FIFO is empty.
    pub const SR_TFE: u32 = 1 << 2;
    /// SR: the RX FIFO is not empty.
    pub const SR_RFNE: u32 = 1 << 3;
    /// SR: the RX FIFO is full.
    pub const SR_RFF: u32 = 1 << 4;
    /// CTRLR0.TMOD: transmit and receive.
    pub const TMOD_TX_AND_RX: u32 = 0;
    /// CTRLR0.TMOD: EEPROM read (send instruction and address, receive data).
    pub const TMOD_EEPROM_READ: u32 = 3;
    /// CTRLR0.SPI_FRF: standard (one wire each way).
    pub const FRF_STD: u32 = 0;
    /// CTRLR0.SPI_FRF: quad.
    pub const FRF_QUAD: u32 = 2;
    /// SPI_CTRLR0.TRANS_TYPE: instruction and address on one wire.
    pub const TT_1C1A: u32 = 0;
    /// SPI_CTRLR0.TRANS_TYPE: instruction on one wire, address on SPI_FRF's wires.
    pub const TT_1C2A: u32 = 1;
    /// SPI_CTRLR0.TRANS_TYPE: instruction and address on SPI_FRF's wires.
    pub const TT_2C2A: u32 = 2;
}
