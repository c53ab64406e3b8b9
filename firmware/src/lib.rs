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
//! - [`play`]: a recorded performance played through an instrument (`tactus play`): the
//!   players, the one play loop over the one engine trait, the strike rule, the output files;
//!   `play::emulated`: its engine for the firmware of every board on emulated RP2040s.
//! - [`regulate`]: the regulation sheet of a key instrument (`tactus regulate`): down- and
//!   up-weight, friction, let-off, drop, blow, back-check, key-bottom times, repetition,
//!   measured with the closed-loop key model, and a spec's verdict.
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
pub mod play;
pub mod regulate;
pub mod report;
pub mod runner;
pub mod schedule;

pub mod flash;
pub mod uf2;
pub mod verdict;

pub use layout::{Interface, StateLayout};
pub use runner::{RunError, Sample, UpdateRunner};
