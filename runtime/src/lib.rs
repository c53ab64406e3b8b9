//! What runs beside generated Tactus code.
//!
//! Everything here is shared by every engine (reference interpreter, JIT, Thumb, C) or by
//! the host tools around them: the multi-sample differentiators that define `d()`/`d2()`,
//! the built-in key stimuli, and the traces a simulation writes.
#![deny(missing_docs)]

pub mod converters;
pub mod differentiator;
pub mod files;
pub mod fixed;
pub mod friction;
pub mod keyboard;
pub mod limiter;
pub mod performance;
pub mod player;
pub mod rng;
pub mod stimulus;
pub mod trace;
pub mod voice;

/// The board's default sample rate in hertz (MIKEY: 16-bit ADC sampled at 44.1 kHz).
pub const DEFAULT_SAMPLE_RATE_HZ: f64 = 44_100.0;
