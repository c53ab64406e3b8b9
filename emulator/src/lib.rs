//! Cycle-accurate emulator of the dual-core RP2040 (two ARMv6-M Cortex-M0+ cores).
//!
//! Two owners, one below the other's speed:
//!
//! - **The machine** ([`machine::Machine`]) *is* the RP2040: two [`core::Core`]s executing
//!   the instructions `tactus_isa` decodes ([`tactus_isa::decode::decode`]) at the cycles
//!   its one timing table gives ([`tactus_isa::timing::cycles`]), against the [`bus::Bus`]
//!   of the [`system::System`] — striped SRAM banks with contention, [`sio`], [`timer`],
//!   the start-up's registers in [`clocks`], the XIP path to the flash in [`xip`], and on a
//!   board with converters the [`io`]: the PIO blocks ([`pio`]), the DMA ([`dma`]) and the
//!   SPI converters at the pins ([`converters`]). Run in lock-step, one instruction at a
//!   time ([`machine::Machine::step_core`]), it defines every result. The chip's addresses
//!   are the `tactus_rp2040` crate's.
//! - **The accelerator** (module `accel`) runs that machine faster and gives the same
//!   results: a decode cache and the interpreter's loop, the block engine (pre-decoded
//!   basic blocks; Thumb regions compiled to native code with cranelift), memoized calls,
//!   the two cores as independent machines over windows, the I/O's replay of a window and
//!   its period memo, and the jump of a repeating board over whole periods. It drives the
//!   machine through a narrow interface and never the façade.
//!
//! [`board::Board`] is the façade the host uses: the machine (to which it dereferences),
//! the accelerator, the loaded image ([`elf`]), profiles of functions and handlers
//! ([`profile`]) and a debugger ([`debug`], [`watch`]); [`config::Config`] says how it
//! runs.
#![deny(missing_docs)]

mod accel;
pub mod board;
pub mod bus;
pub mod clocks;
pub mod config;
pub mod converters;
pub mod core;
pub mod debug;
pub mod dma;
pub mod elf;
pub mod exec;
pub mod io;
#[doc(hidden)]
pub mod lanes;
pub mod machine;
pub mod nvic;
pub mod pio;
pub mod profile;
mod replay;
pub mod semantics;
pub mod sio;
pub mod system;
pub mod timer;
pub mod watch;
pub mod watchdog;
pub mod xip;

pub use accel::{IoWindows, MemoStats, Period, RestPoint};
pub use board::{Board, CallError, CallResult, Debugger, CALL_STUB};
pub use config::{Config, Engine};
pub use machine::{EmuError, Machine, StopReason};
pub use profile::Call;
