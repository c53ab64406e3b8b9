//! Where a firmware image meets the world: the sensor and DAC windows, each [`MAX_KEYS`]
//! words in the last 4 KB of the striped SRAM (RP2040 datasheet 2.6.2). The host (or, on a
//! board with converters, the converters' DMA) leaves each sensor's latest sample in its
//! sensor window word; the firmware leaves each motor's DAC code in its DAC window word.
//! Which words a key has is the image's choice (`image`, "Split windows"); the key map
//! (`keys.json`) names them. A leaf, so that everything that reads or writes the windows
//! (the image, the runner, the key map, the flash image's description) agrees on one
//! address without depending on the others.

/// The sensor window: [`MAX_KEYS`] words from 0x2003f000 (the last 4 KB of the striped
/// SRAM, RP2040 datasheet 2.6.2), window word *w* a sensor's latest ADC sample (the low 16
/// bits) as the host or the converters' DMA leaves it (`image`, "Split windows").
pub const SENSOR_BASE: u32 = 0x2003_f000;

/// The DAC window: [`MAX_KEYS`] words from 0x2003f400, window word *w* the DAC code the
/// firmware last wrote for a motor (the low 16 bits).
pub const DAC_BASE: u32 = 0x2003_f400;

/// Words of each window: the most keys (and pens' axes) a board's image addresses.
pub const MAX_KEYS: usize = 128;
