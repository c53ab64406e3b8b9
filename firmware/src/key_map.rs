//! The one validation of a key map (`keys.json`) against the firmware image it describes,
//! before `tactus emu run` allocates or loops on anything the map says.
//!
//! A key map is input like any other: a hand-edited or mismatched one must not make the
//! run allocate for an absurd clock, spin for hours through a start alarm or a tick period
//! the firmware never set, or report handler cycles and "0 misses" of a sample interrupt
//! that is not the firmware's. So every field is checked against what the image's bytes
//! hold, or against the rule by which [`crate::image::FirmwareImage::build`] laid it out:
//!
//! - the board fields (`clock_hz`, `sample_rate_hz`, the number of `cores`) by the one rule
//!   for boards ([`crate::board_file::check_clock`]), and `period_cycles` /
//!   `period_fraction` equal to the tick schedule they give;
//! - `entry` equal to the ELF's entry point;
//! - per core: its vector table's stack pointer, reset handler and SysTick vector (the
//!   sample interrupt, exception 15) equal to `stack_top`, `reset` and `sample_isr`, its
//!   control block inside the image with the start alarm word equal to `start_alarm_us`
//!   (itself at most [`MAX_START_ALARM_US`]);
//! - per key: a MIDI number at most 127 used once, a core of the map, listed in that
//!   core's `keys` (and every listed key exists with that core), its sensor and DAC words
//!   at the window words the image gives its core's keys in order (the split windows,
//!   `crate::image::window_word`: each core's words in its own banks, a key taking the
//!   larger of its sensor and DAC word counts), its record and
//!   state inside the image.
//!
//! - `sensor_check` and `watchdog`, the options the firmware was built with, are not in the
//!   image's layout rules: `tactus emu run` rebuilds the firmware with them and compares
//!   the build with the ELF byte for byte. [`parse`] refuses a key map without them.
//!
//! What only running shows — that the firmware set PLL_SYS to `clock_hz` and each core's
//! SysTick to `period_cycles` — [`crate::flash::run_elf`] checks after the boot (bounded by
//! the checked start alarm) and before the first sample; and after the run, that each core
//! completed the samples run.

use crate::board_file::{self, Chip};
use crate::image::glue::ctrl;
use crate::windows::{DAC_BASE, MAX_KEYS, SENSOR_BASE};
use serde::{Deserialize, Serialize};
use tactus_emulator::elf::Image;
use tactus_runtime::keyboard::BoardSpec;

/// The key map of one board (`keys.json`): where each key's words live and what runs it.
/// Addresses are hexadecimal strings (`"0x2003f000"`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct KeyMap {
    /// Board number, from 1 along the keyboard.
    pub board: usize,
    /// The board file's name (`rp2040`, …).
    pub board_kind: String,
    /// Core clock the image sets up, Hz.
    pub clock_hz: u64,
    /// Sample rate, Hz.
    pub sample_rate_hz: u32,
    /// The core voltage the image sets before its PLL, V (`None`: the regulator's 1.10 V).
    #[serde(default)]
    pub core_voltage_v: Option<f64>,
    /// Whether the firmware checks its keys' first sensor word every sample
    /// ([`crate::image::Program::sensor_check`], `tactus build --sensor-check`). Recorded
    /// so that `tactus emu run` rebuilds the firmware with its options in one build; a key
    /// map without it was written by an older tactus ([`parse`] says so).
    pub sensor_check: bool,
    /// Whether the firmware runs the RP2040's watchdog ([`crate::image::Program::watchdog`],
    /// `tactus build --watchdog`); recorded as `sensor_check` is.
    pub watchdog: bool,
    /// Where the image starts (Thumb bit set): the flash reset handler that boot2 enters
    /// (a flash image), or the entry stub at 0x20000000 that the boot ROM enters (a RAM
    /// image).
    pub entry: String,
    /// Timer time of the start alarm, µs after the timer's release: at it both cores start
    /// their SysTick, the sample tick; the first tick follows `period_cycles` cycles and
    /// the start handler's latency later (tens of cycles).
    pub start_alarm_us: u32,
    /// Core clock cycles per sample tick, whole part: the period is `period_cycles` or one
    /// more, `period_cycles + period_fraction[0] / period_fraction[1]` on average (tick `n`
    /// at cycle `first + ⌊n·clock/fs⌋`).
    pub period_cycles: u32,
    /// The fractional cycle of the mean period, as numerator and denominator.
    pub period_fraction: [u32; 2],
    /// The sensor window: one 32-bit word per sensor, the ADC sample in the low 16 bits,
    /// written by a driver, DMA channel or PIO program before each tick.
    pub sensor_window: String,
    /// The DAC window: one 32-bit word per force word, the signed 16-bit DAC code, read by
    /// a driver after each sample.
    pub dac_window: String,
    /// Per core: its entry points, control block and keys.
    pub cores: Vec<CoreMap>,
    /// Per key, in window order.
    pub keys: Vec<KeyMapEntry>,
    /// The board's converters (the board file's `[converters]`: the parts and their GPIOs)
    /// when the firmware drives them: its keys then read ADC channels and drive DAC
    /// channels (each key's `adc_channels`, `dac_channels`), not the windows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub converters: Option<tactus_runtime::converters::Converters>,
}

/// The fields a key map has recorded since a later version of tactus than its first: an
/// older `keys.json` lacks them ([`parse`]).
pub const RECORDED_SINCE_OPTIONS: [&str; 2] = ["sensor_check", "watchdog"];

/// The key map in `text` (a `keys.json`).
///
/// Errors, as a message the caller prefixes with the file: not JSON, or not a key map's
/// fields (serde's message, with its line and column); a key map written by an older tactus
/// that did not record the firmware's options ([`RECORDED_SINCE_OPTIONS`]), naming the
/// missing field and telling the user to build the firmware again. No default is assumed
/// for a missing option: a guess that is wrong would rebuild other firmware than the ELF,
/// and the byte-for-byte check would then reject the board with a less helpful message.
pub fn parse(text: &str) -> Result<KeyMap, String> {
    let value: serde_json::Value =
        serde_json::from_str(text).map_err(|e| format!("not a Tactus key map: {e}"))?;
    if let Some(fields) = value.as_object() {
        if fields.contains_key("board") && fields.contains_key("keys") {
            if let Some(missing) = RECORDED_SINCE_OPTIONS
                .iter()
                .find(|f| !fields.contains_key(**f))
            {
                return Err(format!(
                    "no `{missing}` field: written by an older tactus, which did not record \
                     the firmware's options (`sensor_check`, `watchdog`); build the firmware \
                     again with `tactus build LAYOUT --target rp2040`"
                ));
            }
        }
    }
    serde_json::from_value(value).map_err(|e| format!("not a Tactus key map: {e}"))
}

/// One core in a [`KeyMap`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoreMap {
    /// The core (0 or 1).
    pub core: usize,
    /// Its vector table (VTOR).
    pub vector_table: String,
    /// Its reset handler.
    pub reset: String,
    /// Its sample interrupt (its SysTick's exception).
    pub sample_isr: String,
    /// Its control block: start alarm (µs), tick accumulator, samples, misses, ready,
    /// fault word, fault time, reset word (words).
    pub control: String,
    /// Its fault record: the fault word (kind, key, trips), in the next word the sample
    /// count at the last trip, in the next the reset word (why the board last booted:
    /// WATCHDOG.REASON | CHIP_RESET) (`crate::image::fault`); in its control block.
    pub fault: String,
    /// Its initial stack pointer.
    pub stack_top: String,
    /// The MIDI keys it runs.
    pub keys: Vec<u8>,
}

/// One key in a [`KeyMap`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct KeyMapEntry {
    /// MIDI key number.
    pub midi: u8,
    /// Instrument (a built-in name or a path, as the layout names it).
    pub instrument: String,
    /// Its param overrides, `name=value unit`.
    pub params: Vec<String>,
    /// The core that runs it.
    pub core: usize,
    /// Its sensor words (one per sensor, in the program's sensor order).
    pub sensor_words: Vec<String>,
    /// Its DAC words (one per force word: a keyboard key one, a pen z, x, y).
    pub dac_words: Vec<String>,
    /// With converters: its core's ADC channels, one per sensor word.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub adc_channels: Vec<u32>,
    /// With converters: its core's DAC channels, one per force word.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub dac_channels: Vec<u32>,
    /// Its record: the update's sensor copy, out words, limiter budgets, state address.
    pub record: String,
    /// Its state struct.
    pub state: String,
    /// Its param block (inside its state struct, at `StateLayout::params`: one word per
    /// run-time param, its graded values in their planned formats); `null` when the
    /// program has no run-time params (every value compiled in as a constant).
    pub param_block: Option<String>,
    /// Its update's call sites in its core's sample interrupt: the address of each `BL`
    /// that calls it, one in each copy of the core's keys code (`image::glue::Turns`), in
    /// copy order. A hang injected on this key (`--fault kind=hang`) loops there, so that
    /// only this key's update never returns.
    #[serde(default)]
    pub update_calls: Vec<String>,
}

/// The latest start alarm a key map may name, µs after the timer's release: the images
/// `tactus build` writes start their tick within tens of µs (the keys' `init`s and the
/// boot); a second bounds the boot run whatever the map says.
pub const MAX_START_ALARM_US: u32 = 1_000_000;

/// A key map checked against its image: the addresses the run needs, parsed.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckedMap {
    /// The board as the firmware runs it.
    pub chip: Chip,
    /// Per core: (sample interrupt without the Thumb bit, control block).
    pub cores: Vec<(u32, u32)>,
    /// Per key, in window order: its sensor word addresses.
    pub sensor_words: Vec<Vec<u32>>,
    /// Per key, in window order: its DAC word addresses.
    pub dac_words: Vec<Vec<u32>>,
}

/// An address field: `"0x2003f000"` (hexadecimal, the `0x` optional).
fn addr(s: &str, field: &str) -> Result<u32, String> {
    let digits = s.strip_prefix("0x").unwrap_or(s);
    if digits.is_empty() || digits.len() > 8 {
        return Err(format!(
            "`{field}` = {s:?} is not a 32-bit hexadecimal address"
        ));
    }
    u32::from_str_radix(digits, 16)
        .map_err(|_| format!("`{field}` = {s:?} is not a 32-bit hexadecimal address"))
}

/// The `len` bytes at `at` of one loaded segment of `image` as the program runs (its
/// virtual address: a flash image's pieces at the SRAM addresses its reset handler copies
/// them to), if one holds them all.
fn bytes(image: &Image, at: u32, len: u32) -> Option<&[u8]> {
    image.segments.iter().find_map(|s| {
        let off = at.checked_sub(s.run_addr)? as usize;
        s.data.get(off..off.checked_add(len as usize)?)
    })
}

/// The word at `at` in the image.
fn word(image: &Image, at: u32) -> Option<u32> {
    bytes(image, at, 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Checks `map` against `image` (the parsed ELF); see the module documentation. Nothing in
/// it allocates or loops by more than the map's own length.
///
/// Errors: a message naming the field (`cores[1].sample_isr`, `keys[3].sensor_words`, …)
/// and what the image holds instead.
pub fn check(map: &KeyMap, image: &Image) -> Result<CheckedMap, String> {
    let board = BoardSpec {
        name: map.board_kind.clone(),
        clock_hz: map.clock_hz as f64,
        cores: u32::try_from(map.cores.len()).unwrap_or(u32::MAX),
        sample_rate_hz: f64::from(map.sample_rate_hz),
        core_voltage_v: None,
        converters: None,
    };
    // The board's fields; `cores` is the length of the map's list.
    let chip = board_file::check_clock(&board).map_err(|e| e.to_string())?;
    let tick = chip.tick;
    if map.period_cycles != tick.q || map.period_fraction != [tick.rem, tick.den] {
        return Err(format!(
            "`period_cycles` = {}, `period_fraction` = {:?}: {} Hz at {} Hz is {} cycles and {}/{} a period",
            map.period_cycles, map.period_fraction, map.sample_rate_hz, map.clock_hz, tick.q, tick.rem, tick.den
        ));
    }
    let entry = addr(&map.entry, "entry")?;
    if entry != image.entry {
        return Err(format!(
            "`entry` = {}: the ELF's entry point is {:#010x}",
            map.entry, image.entry
        ));
    }
    if map.start_alarm_us > MAX_START_ALARM_US {
        return Err(format!(
            "`start_alarm_us` = {}: at most {MAX_START_ALARM_US} (the firmware `tactus build` \
             writes starts its tick within tens of µs)",
            map.start_alarm_us
        ));
    }
    let mut cores = Vec::with_capacity(map.cores.len());
    for (i, c) in map.cores.iter().enumerate() {
        let f = |name: &str| format!("cores[{i}].{name}");
        if c.core != i {
            return Err(format!(
                "`{}` = {}: the cores are listed 0, 1",
                f("core"),
                c.core
            ));
        }
        let vt = addr(&c.vector_table, &f("vector_table"))?;
        let vector = |n: u32, name: &str, want: u32| -> Result<(), String> {
            match word(image, vt.wrapping_add(4 * n)) {
                Some(w) if w == want => Ok(()),
                Some(w) => Err(format!(
                    "`{}` = {want:#010x}: the vector table at {:#010x} holds {w:#010x} there",
                    f(name),
                    vt
                )),
                None => Err(format!(
                    "`{}` = {:#010x}: no vector table of the image is there",
                    f("vector_table"),
                    vt
                )),
            }
        };
        vector(0, "stack_top", addr(&c.stack_top, &f("stack_top"))?)?;
        vector(1, "reset", addr(&c.reset, &f("reset"))?)?;
        let isr = addr(&c.sample_isr, &f("sample_isr"))?;
        // The sample interrupt is the SysTick exception's handler (exception 15).
        vector(15, "sample_isr", isr)?;
        let control = addr(&c.control, &f("control"))?;
        match word(image, control.wrapping_add(u32::from(ctrl::START))) {
            _ if bytes(image, control, ctrl::SIZE).is_none() => {
                return Err(format!(
                    "`{}` = {}: no control block of the image is there",
                    f("control"),
                    c.control
                ))
            }
            Some(w) if w == map.start_alarm_us => {}
            w => {
                return Err(format!(
                    "`start_alarm_us` = {}: core {i}'s control block holds {}",
                    map.start_alarm_us,
                    w.unwrap_or(0)
                ))
            }
        }
        let fault = addr(&c.fault, &f("fault"))?;
        if fault != ctrl::fault_record(control) {
            return Err(format!(
                "`{}` = {}: core {i}'s fault record is word {} of its control block, {:#010x}",
                f("fault"),
                c.fault,
                ctrl::FAULT / 4,
                ctrl::fault_record(control)
            ));
        }
        cores.push((isr & !1, control));
    }
    if map.keys.len() > MAX_KEYS {
        return Err(format!(
            "`keys`: {} keys; a board has at most {MAX_KEYS}",
            map.keys.len()
        ));
    }
    let mut seen = [false; 128];
    let mut next = vec![0usize; map.cores.len()];
    let mut sensor_words = Vec::with_capacity(map.keys.len());
    let mut dac_words = Vec::with_capacity(map.keys.len());
    for (i, k) in map.keys.iter().enumerate() {
        let f = |name: &str| format!("keys[{i}].{name}");
        let midi = usize::from(k.midi);
        if midi > 127 || seen[midi] {
            return Err(format!(
                "`{}` = {}: a MIDI key number (0–127) used once",
                f("midi"),
                k.midi
            ));
        }
        seen[midi] = true;
        let Some(core) = map.cores.get(k.core) else {
            return Err(format!(
                "`{}` = {}: the map has {} cores",
                f("core"),
                k.core,
                map.cores.len()
            ));
        };
        if !core.keys.contains(&k.midi) {
            return Err(format!(
                "`{}` = {}: `cores[{}].keys` does not list key {}",
                f("core"),
                k.core,
                k.core,
                k.midi
            ));
        }
        // The core's next window words, in order (the image's split windows:
        // `crate::image::window_word`).
        let width = k.sensor_words.len().max(k.dac_words.len());
        let from = next[k.core];
        let window: Option<Vec<u32>> = (from..from + width)
            .map(|j| crate::image::window_word(map.cores.len(), k.core, j).map(|w| w as u32))
            .collect();
        let window = match window {
            Some(w) if !k.sensor_words.is_empty() && !k.dac_words.is_empty() => w,
            _ => {
                return Err(format!(
                    "`{}`, `{}`: {} and {} words from core {}'s window word {from}: each key has at least one of each, all within its core's share of the windows' {MAX_KEYS} words",
                    f("sensor_words"),
                    f("dac_words"),
                    k.sensor_words.len(),
                    k.dac_words.len(),
                    k.core
                ))
            }
        };
        let mut words = Vec::with_capacity(k.sensor_words.len());
        for (j, w) in k.sensor_words.iter().enumerate() {
            let a = addr(w, &f("sensor_words"))?;
            let want = SENSOR_BASE + 4 * window[j];
            if a != want {
                return Err(format!(
                    "`{}[{j}]` = {w}: the image reads that sensor at {want:#010x} (window word {})",
                    f("sensor_words"),
                    window[j]
                ));
            }
            words.push(a);
        }
        let mut dacs = Vec::with_capacity(k.dac_words.len());
        for (j, w) in k.dac_words.iter().enumerate() {
            let want = DAC_BASE + 4 * window[j];
            dacs.push(want);
            if addr(w, &f("dac_words"))? != want {
                return Err(format!(
                    "`{}[{j}]` = {w}: the image writes that force at {want:#010x} (window word {})",
                    f("dac_words"),
                    window[j]
                ));
            }
        }
        next[k.core] += width;
        for (name, v) in [("record", &k.record), ("state", &k.state)] {
            let a = addr(v, &f(name))?;
            if bytes(image, a, 4).is_none() {
                return Err(format!("`{}` = {v}: not inside the image", f(name)));
            }
        }
        for (j, c) in k.update_calls.iter().enumerate() {
            let a = addr(c, &f("update_calls"))?;
            // A 32-bit `BL`: 0xf000 | imm, then 0xd000 | imm (DDI0419 A6.7.13, T1).
            let bl = bytes(image, a, 4)
                .is_some_and(|b| b[1] & 0xf8 == 0xf0 && b[3] & 0xd0 == 0xd0 && a % 2 == 0);
            if !bl {
                return Err(format!(
                    "`{}[{j}]` = {c}: not a `BL` of the image",
                    f("update_calls")
                ));
            }
        }
        if let Some(p) = &k.param_block {
            let a = addr(p, &f("param_block"))?;
            if bytes(image, a, 4).is_none() {
                return Err(format!(
                    "`{}` = {p}: not inside the image",
                    f("param_block")
                ));
            }
        }
        sensor_words.push(words);
        dac_words.push(dacs);
    }
    for (i, c) in map.cores.iter().enumerate() {
        if let Some(m) = c
            .keys
            .iter()
            .find(|&&m| !map.keys.iter().any(|k| k.midi == m && k.core == i))
        {
            return Err(format!(
                "`cores[{i}].keys` lists key {m}, which is not a key of `keys` on core {i}"
            ));
        }
    }
    Ok(CheckedMap {
        chip,
        cores,
        sensor_words,
        dac_words,
    })
}
