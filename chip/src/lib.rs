//! The RP2040's memory and register map, one module per block of the RP2040 datasheet
//! (Raspberry Pi Ltd, build date 2024-02-29), each citing its section: block base
//! addresses, register offsets, bit fields, reset values, and the few rules the datasheet
//! states as arithmetic (boot2's CRC, the PLL's dividers, the regulator's voltages).
//!
//! **Why a crate of its own.** Two crates speak to these addresses from opposite sides: the
//! emulator (`tactus-emulator`) answers at them, the firmware (`tactus-firmware`) writes
//! machine code that stores to them. Neither owns the chip, so the map lives below both and
//! each imports it; a fact here exists once. Nothing here holds state or models behaviour:
//! how a block behaves is the emulator's (`tactus_emulator::{dma, pio, …}`), how a board
//! uses memory is the firmware's image layout (`tactus_firmware::image::layout`).
//! Cortex-M0+ facts that are the architecture's rather than the RP2040's (exception
//! numbers, the private peripheral bus) are the emulator's `nvic`, instruction facts
//! `tactus-isa`'s.
//!
//! Every block on the APB and AHB-Lite segments has the atomic aliases of datasheet 2.1.2
//! ([`ATOMIC_XOR`], [`ATOMIC_SET`], [`ATOMIC_CLR`]).
#![deny(missing_docs)]

pub mod bootrom;
pub mod busctrl;
pub mod clocks;
pub mod dma;
pub mod flash;
pub mod io_bank0;
pub mod irq;
pub mod memory;
pub mod pio;
pub mod pll;
pub mod resets;
pub mod sio;
pub mod ssi;
pub mod timer;
pub mod vreg;
pub mod watchdog;
pub mod xosc;

/// Offset of a register's atomic XOR alias (datasheet 2.1.2).
pub const ATOMIC_XOR: u32 = 0x1000;
/// Offset of a register's atomic bitmask-set alias (datasheet 2.1.2).
pub const ATOMIC_SET: u32 = 0x2000;
/// Offset of a register's atomic bitmask-clear alias (datasheet 2.1.2).
pub const ATOMIC_CLR: u32 = 0x3000;
