//! Cycle-accurate emulator of the dual-core RP2040 (two ARMv6-M Cortex-M0+ cores).
//!
//! The instruction set's facts come from `tactus_isa`, which needs no machine:
//! [`tactus_isa::decode::decode`] turns halfwords into an [`tactus_isa::decode::Instr`] and [`tactus_isa::timing::cycles`] prices
//! it from the one timing table. On them, [`core::Core`] executes instructions against the
//! [`bus::Bus`] trait, [`system::System`] is the RP2040's memory map (striped SRAM banks with
//! contention, [`sio`], [`timer`], the start-up's registers in [`clocks`], the XIP path to
//! the flash in [`xip`]), and [`board::Board`] runs two cores in lock-step and offers the
//! host API: load an ELF ([`elf`]), power on from flash through the boot ROM's path, run N
//! cycles, read and write memory, and count cycles per
//! function. [`pio`] models a PIO block (state machines, FIFOs, side-set, the clock
//! divider), [`dma`] the DMA controller (channels, triggers, chaining, DREQ pacing) and
//! [`converters`] the SPI converters at the pins; [`io`] puts them on the bus of a board
//! that has converters ([`board::Board::attach_io`], issue 40). [`block`] is the
//! default engine of the board's fast path: Thumb regions compiled to native code with cranelift
//! (module `jit`), pre-decoded basic blocks otherwise ([`board::Engine`]).
#![deny(missing_docs)]

pub mod block;
pub mod board;
pub mod bus;
pub mod clocks;
pub mod converters;
pub mod core;
pub mod debug;
pub mod dma;
pub mod elf;
pub mod exec;
mod fast;
pub mod io;
mod jit;
#[doc(hidden)]
pub mod lanes;
mod memo;
pub mod nvic;
pub mod pio;
mod replay;
pub mod semantics;
pub mod sio;
pub mod system;
pub mod timer;
pub mod xip;

pub use board::{
    Board, Call, CallError, CallResult, Config, EmuError, Engine, IoWindows, Period, RestPoint,
    StopReason, CALL_STUB,
};
pub use memo::MemoStats;
