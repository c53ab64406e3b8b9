//! What a firmware image's run gives back for one sample ([`SampleOut`]): per key its force
//! word, the current the limiter allowed and the DAC code, per force word it drives the
//! same ([`DriveOut`]), the events its update emitted ([`KeyEvent`]), and per core the
//! handler's cycles, runs, misses and stalls. [`super::run::ImageRun::step`] reads it off
//! the emulated board, and the rest replay ([`super::rest`]) gives recorded ones back: the
//! one shape both return, kept apart from both.

use tactus_compiler::ir::{Axis, EventId};

/// One event a key's update emitted this sample.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KeyEvent {
    /// Index of the key in the image's key list.
    pub key: usize,
    /// The event.
    pub event: EventId,
    /// Its raw argument words (formats `FixedProgram::event_frac`).
    pub args: Vec<i32>,
}

/// One force word of a key after one sample: the word, the limiter's current and the DAC
/// code it wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DriveOut {
    /// The pen axis ([`super::Drive::axis`]); `None` for a keyboard key's force word.
    pub axis: Option<Axis>,
    /// The DAC window word written (word index from `DAC_BASE`;
    /// [`super::FirmwareImage::window_words`]).
    pub slot: usize,
    /// The force word the update computed, before the limiter (format [`super::Drive::frac`]).
    pub force: i32,
    /// The motor current of the DAC code (`LimiterConstants::current_ua`), µA.
    pub current_ua: i32,
    /// The DAC code written to the DAC window word `slot`.
    pub dac: i16,
}

/// What one sample produced.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SampleOut {
    /// Per key: the force word the update computed (`out[total]`, format
    /// `FixedProgram::total_frac`; a pen's z axis), before the limiter.
    pub force: Vec<i32>,
    /// Per key: the motor current the limiter allowed for that word, µA.
    pub current_ua: Vec<i32>,
    /// Per key: the DAC code written for that word (the key's first DAC window word).
    pub dac: Vec<i16>,
    /// Per key: every force word it drives, in its DAC window order ([`super::Program::drives`]:
    /// one for a keyboard key, equal to `force`/`current_ua`/`dac`; a pen's z, then x, y).
    pub drives: Vec<Vec<DriveOut>>,
    /// Events emitted this sample, by key in key order, each key's in program order.
    pub events: Vec<KeyEvent>,
    /// Per core: cycles of the sample handler runs completed during this step (exception
    /// entry to the completed return; normally exactly one run).
    pub core_cycles: Vec<u64>,
    /// Per core: handler runs completed during this step.
    pub handler_runs: Vec<u32>,
    /// Per core: the firmware's deadline-miss counter (since start).
    pub misses: Vec<u32>,
    /// Per core: cycles lost to SRAM bank contention during this step.
    pub stalls: Vec<u64>,
}
