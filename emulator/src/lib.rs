//! Cycle-accurate emulator of the dual-core RP2040 (two ARMv6-M Cortex-M0+ cores).
//!
//! The crate is layered so that the pieces a static analyser needs come without a machine:
//! [`decode::decode`] turns halfwords into an [`decode::Instr`] and [`timing::cycles`] prices
//! it from the one timing table. Above them, [`core::Core`] executes instructions against the
//! [`bus::Bus`] trait, [`bus::System`] is the RP2040's memory map (striped SRAM banks with
//! contention, [`sio`], [`timer`], the start-up's registers in [`clocks`], the XIP path to
//! the flash in [`xip`]), and [`board::Board`] runs two cores in lock-step and offers the
//! host API: load an ELF ([`elf`]), power on from flash through the boot ROM's path, run N
//! cycles, read and write memory, feed sensors, read the DAC, and count cycles per
//! function. [`block`] is the default
//! engine of the board's fast path: Thumb regions compiled to native code with cranelift
//! (module `jit`), pre-decoded basic blocks otherwise ([`board::Engine`]).
#![deny(missing_docs)]

pub mod block;
pub mod board;
pub mod bus;
pub mod clocks;
pub mod core;
pub mod debug;
pub mod decode;
pub mod elf;
pub mod encode;
pub mod exec;
mod fast;
mod jit;
pub mod nvic;
pub mod schedule;
pub mod semantics;
pub mod sio;
pub mod timer;
pub mod timing;
pub mod wcet;
pub mod xip;

pub use board::{
    Board, Call, CallError, CallResult, Config, EmuError, Engine, StopReason, CALL_STUB, DAC_BASE,
    FIRMWARE_OWN_BANKS, MAX_KEYS, SENSOR_BASE,
};
pub use decode::{decode, Instr};
pub use timing::cycles;
