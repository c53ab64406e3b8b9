//! Why an image could not be built or run ([`ImageError`]): one error type for the
//! image's compilation, layout, assembly, static analysis and runs on the emulator.

use std::fmt;
use tactus_compiler::thumb::buffer::BufferError;

/// Why an image could not be built or run.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ImageError {
    /// An instrument did not compile.
    Compile(String),
    /// A key's specification is invalid (`key` is its index in the key list).
    BadKey {
        /// Index in the key list.
        key: usize,
        /// What is wrong.
        why: String,
    },
    /// The board cannot run an image (clock, sample rate or core count).
    Board(String),
    /// A program's plan breaks its instrument's accuracy contract
    /// (`tactus_compiler::fixed::contract::verdict`): no firmware is made from it.
    Contract(String),
    /// The limiter configuration cannot be built, or not in the firmware's arithmetic.
    Limiter(String),
    /// A core's code and data do not fit its SRAM bank.
    NoRoom {
        /// The core.
        core: usize,
        /// Bytes needed.
        need: u32,
        /// Bytes available.
        have: u32,
    },
    /// The glue code could not be assembled.
    Assemble(String),
    /// The static WCET analysis failed.
    Wcet(String),
    /// A host access to the emulated board failed.
    Emu(String),
    /// The firmware did not reach the expected state (faulted, did not finish its start-up
    /// before the first tick, did not complete a sample, overflowed its stack).
    Run(String),
    /// [`ImageRun::step`] got the wrong number of sensor words.
    ///
    /// [`ImageRun::step`]: super::ImageRun::step
    SensorCount {
        /// Sensor words of the image ([`FirmwareImage::sensor_words`]).
        ///
        /// [`FirmwareImage::sensor_words`]: super::FirmwareImage::sensor_words
        expected: usize,
        /// Words passed.
        got: usize,
    },
}

impl fmt::Display for ImageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ImageError::Compile(e) => write!(f, "cannot compile a key program: {e}"),
            ImageError::BadKey { key, why } => write!(f, "key {key}: {why}"),
            ImageError::Board(e) => write!(f, "board: {e}"),
            ImageError::Contract(e) => f.write_str(e),
            ImageError::Limiter(e) => write!(f, "limiter: {e}"),
            ImageError::NoRoom { core, need, have } => write!(
                f,
                "core {core}: code and data need {need} bytes, its SRAM bank has {have}"
            ),
            ImageError::Assemble(e) => write!(f, "cannot assemble the glue code: {e}"),
            ImageError::Wcet(e) => write!(f, "static WCET analysis failed: {e}"),
            ImageError::Emu(e) => write!(f, "emulator: {e}"),
            ImageError::Run(e) => write!(f, "firmware run: {e}"),
            ImageError::SensorCount { expected, got } => {
                write!(
                    f,
                    "{got} sensor words given, the image reads {expected} (one per sensor of each key)"
                )
            }
        }
    }
}

impl From<BufferError> for ImageError {
    fn from(e: BufferError) -> Self {
        ImageError::Assemble(e.to_string())
    }
}

impl std::error::Error for ImageError {}
