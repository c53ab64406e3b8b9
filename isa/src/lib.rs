//! What the ARMv6-M Thumb instruction set and the RP2040's Cortex-M0+ say about machine code,
//! with no machine: [`decode`] turns halfwords into an [`decode::Instr`], [`encode`] is its
//! inverse (the Thumb backend's and the firmware glue's encoder), [`timing`] is the one
//! Cortex-M0+ cycle table, [`effects`] the one table of the registers and flags each
//! instruction reads and writes, and [`wcet`] prices a function's longest path with them.
//!
//! The emulator executes what [`decode`] returns and charges [`timing::cycles`]; the static
//! WCET charges the same table, so a measured count can never disagree with a static one
//! because of two copies of a fact. Nothing here holds machine state, so the compiler and
//! the budget checker use it without the emulator (and without cranelift).
#![deny(missing_docs)]

pub mod decode;
pub mod effects;
pub mod encode;
pub mod timing;
pub mod wcet;
