//! Which key of an image runs which program on which core ([`KeySpec`]): a layout's keys
//! as the image places them (the window slot is the MIDI key number), their cores assigned
//! as the budget assigns them.

use super::error::ImageError;
use super::program::Program;
use tactus_runtime::keyboard::KeyAssignment;

/// One key (or pen) of the image.
///
/// A key occupies consecutive words of both windows from `slot`: in the sensor window one
/// word per sensor of its program ([`Program::sensor_words`], in sensor order: a pen
/// `pen: m in { z: …, x: …, y: … }` reads `pen.z` at `slot`, `pen.x` at `slot + 1`, …),
/// in the DAC window one word per force word it drives ([`Program::drives`]: a keyboard
/// key one, a pen z at `slot`, then x, then y). A keyboard key uses the word `slot` of
/// each window, as before.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeySpec {
    /// Its first slot in the sensor and DAC windows (word index from [`SENSOR_BASE`] /
    /// [`crate::windows::DAC_BASE`]; e.g. the MIDI key number); its last word in either window must be
    /// below [`MAX_KEYS`].
    ///
    /// [`SENSOR_BASE`]: crate::windows::SENSOR_BASE
    /// [`MAX_KEYS`]: crate::windows::MAX_KEYS
    pub slot: usize,
    /// Index of its program in the programs given to [`FirmwareImage::build`].
    ///
    /// [`FirmwareImage::build`]: super::FirmwareImage::build
    pub program: usize,
    /// The core that runs it (0 or 1).
    pub core: usize,
}

/// The keys of a layout as the image places them: each key's window slot is its MIDI key
/// number, with its program (an index into [`compile_layout`]'s programs) and its core
/// ([`assign_cores`]). `keys`, `key_programs` and `cores` run in parallel (the shortest
/// decides the length).
///
/// [`compile_layout`]: super::compile_layout
pub fn key_specs(keys: &[KeyAssignment], key_programs: &[usize], cores: &[usize]) -> Vec<KeySpec> {
    keys.iter()
        .zip(key_programs)
        .zip(cores)
        .map(|((a, &program), &core)| KeySpec {
            slot: a.key as usize,
            program,
            core,
        })
        .collect()
}

/// Assigns keys to `cores` cores as the budget does ([`crate::schedule::partition`]: an exact
/// two-way partition) with each key's cost the static WCET of its program's update; returns
/// the core of each key.
pub fn assign_cores(
    programs: &[Program],
    key_programs: &[usize],
    cores: usize,
) -> Result<Vec<usize>, ImageError> {
    let mut cost = Vec::with_capacity(programs.len());
    for p in programs {
        cost.push(p.update_wcet()?);
    }
    let mut costs = Vec::with_capacity(key_programs.len());
    for (i, &p) in key_programs.iter().enumerate() {
        costs.push(*cost.get(p).ok_or(ImageError::BadKey {
            key: i,
            why: format!("program {p} does not exist"),
        })?);
    }
    Ok(crate::schedule::partition(&costs, cores))
}
