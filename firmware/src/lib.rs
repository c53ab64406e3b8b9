//! Compiled per-key updates on the emulated RP2040.
//!
//! - [`layout`]: the interface every compiled update implements (the state struct's byte
//!   layout, the sensor and out word counts), computed from the program.
//! - [`runner`]: [`UpdateRunner`] loads code (an ELF executable, or raw position-independent
//!   Thumb code with entry offsets) into an emulated board and calls `init`/`update` from
//!   the host, returning the out words, the states, the modes and the cycles per key-sample.
//! - [`image`]: the whole per-sample firmware of a keyboard (programs, limiter, sample
//!   interrupt per core) laid out in SRAM, run sample by sample, with its static WCET.
//! - [`cc`]: compiles the C backend's output with clang or arm-none-eabi-gcc for the
//!   Cortex-M0+ and links an ELF executable in SRAM, reporting code sizes.
//! - [`measure`]: runs stimuli through a runner and the fixed interpreter side by side,
//!   counting mismatches and collecting cycle statistics; [`report`] prints the table.
//! - [`board_file`]: the one validation of a board (clock, cores, sample rate) the firmware
//!   runs on.
//! - [`key_map`]: the one validation of a key map (`keys.json`) against its firmware image.
//! - [`corpus`]: the stimulus corpus of the budget (presses, repetitions, trills, half
//!   dips, noise, glitches, random words); [`budget`]: static WCET and measured cycles of
//!   an update; [`boards`]: a keyboard as a set of boards — the planner and the verdict,
//!   each board's sample interrupt as its image lays it out (`tactus budget`);
//!   [`schedule`]: keys to cores by longest processing time first (the planner's fallback
//!   beyond two cores or very large totals).
//!
//! Playing performances and the regulation sheet run on top of this crate, in
//! `tactus_host::play` and `tactus_host::regulate`.
#![deny(missing_docs)]

pub mod board_file;
pub mod boards;
pub mod budget;
pub mod cc;
pub mod corpus;
pub mod image;
pub mod key_map;
pub mod layout;
pub mod measure;
pub mod report;
pub mod runner;
pub mod schedule;

pub mod flash;
pub mod uf2;
pub mod verdict;
pub mod windows;

pub use layout::{Interface, StateLayout};
pub use runner::{RunError, Sample, UpdateRunner};
