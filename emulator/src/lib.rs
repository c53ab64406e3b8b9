//! Cycle-accurate emulator of the dual-core RP2040 (two ARMv6-M Cortex-M0+ cores).
//!
//! Under construction: see issue 4. The emulator is independent of the compiler; the
//! budget checker and the firmware harness will drive it through this crate's API.
#![deny(missing_docs)]
