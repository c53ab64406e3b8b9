//! Firmware a user can flash: per board of a keyboard, the linked ELF, its UF2, a key map
//! and a README (what `tactus build LAYOUT --target rp2040 -o DIR` writes).
//!
//! The boards are the keyboard's plan (the layout's own `[[board]]`s or planned by
//! [`crate::boards::plan`], once per keyboard: [`crate::boards::KeyboardPlan`], the plan
//! `tactus budget` reports); each board's image is the plan's
//! ([`crate::boards::KeyboardPlan::images`]) or, without one, [`crate::boards::board_image`]
//! of its keys: the very image whose sample interrupt the budget proved, so a board that does not fit is an
//! error here rather than firmware that misses its deadline. By default the firmware lives
//! in flash and boots at power-on through its second-stage boot loader, copying itself to
//! SRAM ([`Load::Flash`], `crate::image::flash_image`); [`Load::Ram`] writes the RAM-only
//! image of earlier versions (for development: [`crate::uf2`] says what each costs). From
//! the RAM image's entry stub on both run the same code at the same addresses
//! ([`crate::image::boot`]).

use crate::boards::{self, BoardImage, PlanKey, ProgramCosts};
use crate::image::{FirmwareImage, FlashImage, Program};
use crate::windows::{DAC_BASE, SENSOR_BASE};
use std::sync::Arc;
use tactus_runtime::keyboard::{self, BoardSpec};
use tactus_runtime::limiter::LimiterConfig;

pub use crate::key_map::{CoreMap, KeyMap, KeyMapEntry};

/// Where a board's firmware lives (module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Load {
    /// In flash: boots at power-on through boot2 and copies itself to SRAM.
    #[default]
    Flash,
    /// In SRAM only: loaded by the boot ROM over USB, gone at power-off (development).
    Ram,
}

/// Everything written for one board.
#[derive(Clone, Debug)]
pub struct BoardFirmware {
    /// Board number, from 1.
    pub index: usize,
    /// Its MIDI keys.
    pub keys: Vec<u8>,
    /// The image.
    pub image: FirmwareImage,
    /// The image in flash ([`FirmwareImage::flash_image`]; `None` for [`Load::Ram`]).
    pub flash: Option<FlashImage>,
    /// The linked ELF ([`FirmwareImage::flash_elf`], or [`FirmwareImage::elf`] for
    /// [`Load::Ram`]).
    pub elf: Vec<u8>,
    /// The UF2: flash ([`crate::uf2::rp2040_flash`]) or RAM-only
    /// ([`crate::uf2::rp2040_ram`]).
    pub uf2: Vec<u8>,
    /// The key map.
    pub key_map: KeyMap,
    /// The README of its directory.
    pub readme: String,
}

impl BoardFirmware {
    /// The board's directory name: `board-01`, …
    pub fn dir_name(&self) -> String {
        format!("board-{:02}", self.index)
    }

    /// Where this firmware lives.
    pub fn load(&self) -> Load {
        match self.flash {
            Some(_) => Load::Flash,
            None => Load::Ram,
        }
    }
}

/// What [`keyboard_firmware`] builds.
pub struct KeyboardInput<'a> {
    /// The keyboard's name (the layout's).
    pub name: &'a str,
    /// Distinct programs.
    pub programs: &'a [Program],
    /// Per program, its instrument (as the layout names it) and param overrides.
    pub program_names: &'a [(String, Vec<(String, String)>)],
    /// (MIDI key, program), ascending by key.
    pub keys: &'a [(u8, usize)],
    /// The board kind.
    pub board: &'a BoardSpec,
    /// The keyboard's boards (MIDI keys each), as its plan gives them
    /// ([`crate::boards::KeyboardPlan::key_lists`]); each is checked again here, and one
    /// that does not fit is an error.
    pub boards: &'a [Vec<u8>],
    /// Per board, the image the plan built for it ([`crate::boards::KeyboardPlan::images`]),
    /// taken when it holds the board's keys ([`crate::boards::BoardImage::holds`]); a board
    /// past the end of the list, or `None`, is built here ([`crate::boards::board_image`]).
    /// Empty: every board built here.
    pub images: &'a [Option<Arc<BoardImage>>],
    /// The safety limiter.
    pub limiter: &'a LimiterConfig,
    /// Flash (the default) or RAM-only firmware.
    pub load: Load,
    /// The command that built it, for the README.
    pub command: &'a str,
}

fn hex(a: u32) -> String {
    format!("{a:#010x}")
}

/// The firmware of every board of a keyboard (`input.boards`, as its plan gives them).
/// `progress(stage, done, total)` reports the building.
///
/// Errors (a message naming the board and its keys): a board that does not fit its
/// deadline or memory, a clock no PLL setting makes, an image or ELF that cannot be
/// written.
pub fn keyboard_firmware(
    input: &KeyboardInput,
    progress: &mut dyn FnMut(&str, usize, usize),
) -> Result<Vec<BoardFirmware>, String> {
    let (programs, board, lim) = (input.programs, input.board, input.limiter);
    if input.keys.is_empty() {
        return Err(format!("{}: no keys to build firmware for", input.name));
    }
    let costs = ProgramCosts::new(programs, board, lim).map_err(|e| e.to_string())?;
    let keys: Vec<PlanKey> = input
        .keys
        .iter()
        .map(|&(key, program)| PlanKey { key, program })
        .collect();
    let lists = input.boards;
    let mut out = Vec::with_capacity(lists.len());
    for (i, list) in lists.iter().enumerate() {
        progress("building boards", i, lists.len());
        let what = || {
            format!(
                "board {} (keys {})",
                i + 1,
                crate::verdict::key_ranges(list)
            )
        };
        let bkeys: Vec<PlanKey> = keys
            .iter()
            .filter(|k| list.contains(&k.key))
            .copied()
            .collect();
        // The image, the plan's or built here, and its verdict (`boards::check_board`'s).
        let planned =
            (input.images.get(i).and_then(Option::as_ref)).filter(|b| b.holds(programs, &bkeys));
        let (core_of, image) = match planned {
            Some(b) => (b.core_of.clone(), Ok(b.image.clone())),
            None => boards::board_image(programs, &costs, &bkeys, board, lim)
                .map_err(|e| format!("{}: {e}", what()))?,
        };
        let verdict = boards::image_verdict(programs, &bkeys, board, &core_of, &image);
        if !verdict.fits() {
            // The budget's rule and words: a key that fits no board says why.
            let alone = match bkeys.as_slice() {
                [k] => boards::fits_no_board(programs, &costs, k.program, board, lim)
                    .map_err(|e| format!("{}: {e}", what()))?,
                _ => None,
            };
            return Err(match alone {
                Some(why) => format!(
                    "key {} (`{}`) fits no {} board: {why}",
                    list.first().copied().unwrap_or(0),
                    input
                        .program_names
                        .get(bkeys[0].program)
                        .map_or("?", |n| n.0.as_str()),
                    board.name
                ),
                None => format!(
                    "{}: does not fit the {}: {}; `tactus budget` shows the plan",
                    what(),
                    board.name,
                    verdict
                        .why_not(board.cycles_per_sample())
                        .unwrap_or_default()
                ),
            });
        }
        let image = image.map_err(|e| format!("{}: {e}", what()))?;
        image.flashable().map_err(|e| format!("{}: {e}", what()))?;
        let fail = |e: crate::image::ImageError| format!("{}: {e}", what());
        let (flash, elf, uf2) = match input.load {
            Load::Flash => {
                let flash = image.flash_image().map_err(fail)?;
                let elf = image.flash_elf(&flash).map_err(fail)?;
                let uf2 = crate::uf2::rp2040_flash(&flash.bytes);
                (Some(flash), elf, uf2)
            }
            Load::Ram => {
                let uf2 = crate::uf2::rp2040_ram(image.segments())
                    .map_err(|e| format!("{}: {e}", what()))?;
                (None, image.elf().map_err(fail)?, uf2)
            }
        };
        let entry = flash
            .as_ref()
            .map_or(crate::image::boot::ENTRY, |f| f.reset);
        let key_map = key_map(input, i + 1, &image, &bkeys, &core_of, entry);
        let mut fw = BoardFirmware {
            index: i + 1,
            keys: list.clone(),
            image,
            flash,
            elf,
            uf2,
            key_map,
            readme: String::new(),
        };
        fw.readme = readme(input, &fw, lists.len());
        out.push(fw);
    }
    progress("building boards", lists.len(), lists.len());
    Ok(out)
}

/// The key map of board `index`, whose image holds `bkeys` (slots in order) on the cores
/// `core_of` and starts at `entry`.
fn key_map(
    input: &KeyboardInput,
    index: usize,
    image: &FirmwareImage,
    bkeys: &[PlanKey],
    core_of: &[usize],
    entry: u32,
) -> KeyMap {
    let specs = image.keys();
    let programs = image.programs();
    let mut keys = Vec::with_capacity(bkeys.len());
    for (i, (k, spec)) in bkeys.iter().zip(&specs).enumerate() {
        let p = &programs[spec.program];
        let (record, state) = image.key_addresses(i).unwrap_or((0, 0));
        let (sensor_words, dac_words) = image.window_words(i).unwrap_or_default();
        let (adc_channels, dac_channels) = image.channels(i).unwrap_or_default();
        keys.push(KeyMapEntry {
            midi: k.key,
            instrument: input
                .program_names
                .get(k.program)
                .map(|n| n.0.clone())
                .unwrap_or_default(),
            params: input
                .program_names
                .get(k.program)
                .map(|n| n.1.iter().map(|(a, b)| format!("{a}={b}")).collect())
                .unwrap_or_default(),
            core: core_of.get(i).copied().unwrap_or(spec.core),
            sensor_words: sensor_words
                .iter()
                .map(|&w| hex(SENSOR_BASE + 4 * w as u32))
                .collect(),
            dac_words: dac_words
                .iter()
                .map(|&w| hex(DAC_BASE + 4 * w as u32))
                .collect(),
            adc_channels: adc_channels.to_vec(),
            dac_channels: dac_channels.to_vec(),
            record: hex(record),
            state: hex(state),
            param_block: (!p.params.is_empty()).then(|| hex(state + p.thumb.state.params as u32)),
            update_calls: (image.update_calls(i).unwrap_or_default().iter())
                .map(|&a| hex(a))
                .collect(),
        });
    }
    let cores = (0..image.cores())
        .map(|c| {
            let [vt, reset, isr, ctrl, sp] = image.core_addresses(c).unwrap_or_default();
            CoreMap {
                core: c,
                vector_table: hex(vt),
                reset: hex(reset | 1),
                sample_isr: hex(isr | 1),
                control: hex(ctrl),
                fault: hex(crate::image::glue::ctrl::fault_record(ctrl)),
                stack_top: hex(sp),
                keys: image
                    .core_keys(c)
                    .iter()
                    .filter_map(|&i| bkeys.get(i).map(|k| k.key))
                    .collect(),
            }
        })
        .collect();
    KeyMap {
        board: index,
        board_kind: input.board.name.clone(),
        clock_hz: input.board.clock_hz as u64,
        sample_rate_hz: input.board.sample_rate_hz as u32,
        core_voltage_v: input.board.core_voltage_v,
        sensor_check: input.programs.iter().any(|p| p.sensor_check),
        watchdog: input.programs.iter().any(|p| p.watchdog),
        entry: hex(entry | 1),
        start_alarm_us: image.start_alarm_us(),
        period_cycles: image.tick().q,
        period_fraction: [image.tick().rem, image.tick().den],
        sensor_window: hex(SENSOR_BASE),
        dac_window: hex(DAC_BASE),
        cores,
        keys,
        converters: image.io().and(input.board.converters.clone()),
    }
}

/// The README of one board's directory.
fn readme(input: &KeyboardInput, fw: &BoardFirmware, boards: usize) -> String {
    let m = &fw.key_map;
    let blocks = fw.uf2.len() / crate::uf2::BLOCK;
    let mut keys = String::new();
    for k in &m.keys {
        let instrument = if k.params.is_empty() {
            k.instrument.clone()
        } else {
            format!("{} ({})", k.instrument, k.params.join(", "))
        };
        keys.push_str(&format!(
            "| {} | {} | {} | {} | {} |\n",
            k.midi,
            instrument,
            k.core,
            k.sensor_words.join(" "),
            k.dac_words.join(" ")
        ));
    }
    let (files, flashing) = match fw.load() {
        Load::Flash => (
            format!(
                "- `firmware.uf2`: the flash image as a UF2 for the RP2040 boot ROM ({blocks} blocks of\n  \
                 256 bytes, family ID 0xe48bff56, written to flash from 0x10000000): boot2, then the\n  \
                 image that copies itself to SRAM at power-on.\n\
                 - `firmware.elf`: the same image as a linked ELF (sections loaded from flash, run\n  \
                 from SRAM: for a debugger, `objdump`, or `tactus emu run firmware.elf --stimulus\n  \
                 mf-dip`, which boots it through the emulated boot ROM).\n"
            ),
            "1. Hold BOOTSEL while plugging the board in (or while pressing RESET): it appears as a USB\n   \
             drive named `RPI-RP2`.\n\
             2. Copy `firmware.uf2` onto that drive. The boot ROM writes it to flash and reboots.\n\
             \n\
             Or, with picotool: `picotool load firmware.uf2 && picotool reboot`, or over SWD with a\n\
             debugger that programs flash (OpenOCD: `program firmware.elf verify reset`).\n\
             \n\
             The image stays in flash: at every power-on the boot ROM checks boot2's CRC and runs it,\n\
             boot2 sets the flash up for fast quad reads (XIP) and enters the image, which copies its\n\
             code and data to SRAM (the per-sample code never runs from flash) and starts as below.\n"
                .to_string(),
        ),
        Load::Ram => (
            format!(
                "- `firmware.uf2`: a RAM-only UF2 for the RP2040 boot ROM ({blocks} blocks of 256 bytes,\n  \
                 family ID 0xe48bff56, written to 0x20000000 upwards).\n\
                 - `firmware.elf`: the same image as a linked ELF (for a debugger, `objdump`, or\n  \
                 `tactus emu run firmware.elf --stimulus mf-dip`).\n"
            ),
            "1. Hold BOOTSEL while plugging the board in (or while pressing RESET): it appears as a USB\n   \
             drive named `RPI-RP2`.\n\
             2. Copy `firmware.uf2` onto that drive. The boot ROM loads it into SRAM and starts it.\n\
             \n\
             Or, with picotool: `picotool load firmware.uf2 && picotool reboot` (a RAM image: picotool\n\
             loads it into SRAM and runs it), or over SWD: `arm-none-eabi-gdb firmware.elf`, `load`,\n\
             `jump _entry_point`.\n\
             \n\
             This image lives in SRAM only (built with `--ram`: nothing in flash): it is gone after a\n\
             power cycle; copy it again after each power-up. Without `--ram`, `tactus build` writes a\n\
             flash image that boots at power-on.\n"
                .to_string(),
        ),
    };
    let vreg = match m.core_voltage_v {
        Some(v) => {
            format!("raises the core voltage to {v:.2} V (VREG) and waits 1 ms for it to settle, ")
        }
        None => String::new(),
    };
    format!(
        "# {name}: board {b} of {boards} (keys {range})\n\
\n\
Built by `{cmd}`.\n\
\n\
{files}\
- `keys.json`: each key's MIDI number, instrument, core, sensor and DAC words, record and\n  \
state addresses; whether the firmware checks its sensors and runs the watchdog.\n\
\n\
## Flashing\n\
\n\
{flashing}\
\n\
## What runs\n\
\n\
Core 0 {vreg}sets the clocks to {mhz} MHz (PLL_SYS from the 12 MHz crystal), starts the\n\
timer's 1 µs tick and launches core 1 through the boot ROM's FIFO protocol. At a timer alarm\n\
both cores start their SysTick on the same cycle; each then runs its keys' sample interrupt\n\
at {fs} Hz on its SysTick (every {q} or {q1} processor cycles, {fs} per second exactly): read\n\
each key's sensor word, run its update, pass each force word through the safety limiter,\n\
write the DAC word.\n\
\n\
| MIDI | instrument | core | sensor words | DAC words |\n\
|---|---|---|---|---|\n\
{keys}\n\
## What is not in this firmware\n\
\n\
- **ADC and DAC drivers.** The sensor and DAC words are plain SRAM words (sensor window\n  \
{sw}, DAC window {dw}, one 32-bit word each); a driver, a DMA channel or a PIO program\n  \
must fill the sensor words from the converters before each sample tick and send the DAC\n  \
words out after it. Without one the keys read 0 and the motors get nothing.\n\
- Verified in Tactus's cycle-accurate emulator, not on hardware. The emulator does not\n  \
model oscillator start-up, PLL lock or regulator settling times, the boot ROM's own run,\n  \
the XIP cache or the flash's read timing: they delay the first tick, never a sample (the\n  \
image runs from SRAM once copied). boot2 is written for the Pico's W25Q16JV (any\n  \
W25Q-family part with the 01h status write and EBh quad reads); another flash chip may\n  \
need another boot2.\n",
        name = input.name,
        b = fw.index,
        range = crate::verdict::key_ranges(&fw.keys),
        cmd = input.command,
        mhz = m.clock_hz as f64 / 1e6,
        fs = m.sample_rate_hz,
        q = m.period_cycles,
        q1 = m.period_cycles + 1,
        sw = m.sensor_window,
        dw = m.dac_window,
    )
}

/// One core of an [`ElfRun`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CoreRun {
    /// Samples its handler completed.
    pub samples: u32,
    /// Its deadline-miss counter at the end.
    pub misses: u32,
    /// Longest handler run, cycles (exception entry to the completed return).
    pub worst_cycles: u64,
    /// Mean handler run, cycles.
    pub mean_cycles: f64,
}

/// What [`run_elf`] measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ElfRun {
    /// Samples run.
    pub samples: usize,
    /// Per core.
    pub cores: Vec<CoreRun>,
    /// Core clock cycles per sample period.
    pub cycles_per_sample: u64,
    /// Each core's cycle counter at the end.
    pub final_cycles: [u64; 2],
    /// Every key's DAC words at the end, in key-map order.
    pub dac_final: Vec<u32>,
    /// FNV-1a (64-bit) over every key's DAC words after every sample: one number that
    /// changes when any word of the run does.
    pub dac_digest: u64,
    /// Per core, its fault record at the end (the key map's `cores[c].fault`: the fault
    /// word, the fault time and the reset word, raw;
    /// `crate::image::fault::FaultWord::decode_record`).
    pub fault_records: Vec<[u32; 3]>,
}

/// Most samples [`run_elf`] runs (one emulated minute at 44.1 kHz).
pub const MAX_RUN_SAMPLES: usize = 60 * 44_100;

/// Boots firmware `elf` from reset on an emulated RP2040 at the key map's clock (the boot
/// ROM enters it at its entry point; it launches core 1 itself) and runs `samples` samples:
/// before tick *n*, key *k*'s first sensor word gets `sensors[k][n mod len]` (a stimulus,
/// repeated; its other sensor words stay 0; an empty list leaves the key at 0). Returns per
/// core the handler's completed samples, worst and mean cycles, and misses.
///
/// Errors: a message for an ELF the loader rejects, a key map that does not describe it
/// ([`crate::key_map::check`] before anything runs; after the boot, a clock or tick the
/// firmware did not set; after the run, more completed samples than ticks, or fewer without
/// a miss), more than [`MAX_RUN_SAMPLES`] samples, sensor lists that do not match the keys,
/// or firmware that faults or does not start.
pub fn run_elf(
    elf: &[u8],
    map: &KeyMap,
    sensors: &[&[i32]],
    samples: usize,
    progress: &mut dyn FnMut(usize, usize),
    debugger: Option<Box<dyn tactus_emulator::Debugger>>,
) -> Result<ElfRun, String> {
    use crate::image::glue::ctrl;
    use tactus_emulator::{Config, StopReason};
    use tactus_isa::timing::EXCEPTION_ENTRY;
    if samples > MAX_RUN_SAMPLES {
        return Err(format!(
            "{samples} samples: at most {MAX_RUN_SAMPLES} (one emulated minute)"
        ));
    }
    // The map against the image, before anything is allocated or run for it.
    let image =
        tactus_emulator::elf::parse(elf).map_err(|e| format!("cannot load the ELF: {e}"))?;
    let checked = crate::key_map::check(map, &image).map_err(|e| format!("key map: {e}"))?;
    if sensors.len() != map.keys.len() {
        return Err(format!(
            "{} sensor lists for the key map's {} keys",
            sensors.len(),
            map.keys.len()
        ));
    }
    let clock_hz = checked.chip.clock_hz;
    let mut board = tactus_emulator::Board::new(Config {
        clock_hz,
        ..Config::default()
    });
    board
        .load_elf(elf)
        .map_err(|e| format!("cannot load the ELF: {e}"))?;
    if let Some(d) = debugger {
        board.attach_debugger(d);
    }
    let cores: Vec<(usize, u32)> = checked
        .cores
        .iter()
        .map(|&(isr, ctrl)| (board.profile_handler(isr), ctrl))
        .collect();
    let words = &checked.sensor_words;
    let dac_addrs: Vec<u32> = checked.dac_words.iter().flatten().copied().collect();
    let mut dac = vec![0u32; dac_addrs.len()];
    let mut digest: u64 = 0xcbf2_9ce4_8422_2325;
    let check = |stop: StopReason, board: &tactus_emulator::Board| match stop {
        StopReason::CycleLimit => Ok(()),
        other => Err(format!(
            "the firmware stopped: {}",
            board.describe_stop(&other)
        )),
    };
    let alarm = u64::from(map.start_alarm_us);
    // At most a second of boot (the checked start alarm), mostly asleep in WFI.
    crate::image::run_to_timer(&mut board, alarm)?;
    for (i, (_, ctrl)) in cores.iter().enumerate() {
        let ready = board
            .read_u32(ctrl + u32::from(ctrl::READY))
            .map_err(|e| e.to_string())?;
        if ready != 1 {
            return Err(format!(
                "core {i} did not finish its start-up before the start alarm"
            ));
        }
    }
    // What the firmware set up is what the map says: the clock and each core's tick.
    if let Some(hz) = board.system.sysctl.clk_sys_hz() {
        if hz != clock_hz {
            return Err(format!(
                "key map: `clock_hz` = {clock_hz}: the firmware sets clk_sys to {hz} Hz"
            ));
        }
    }
    for (i, core) in board.cores.iter().take(cores.len()).enumerate() {
        let rvr = core.nvic.syst_rvr;
        if rvr + 1 != map.period_cycles {
            return Err(format!(
                "key map: `period_cycles` = {}: core {i}'s firmware ticks every {} cycles",
                map.period_cycles,
                rvr + 1
            ));
        }
    }
    let first = crate::image::run_to_first_tick(&mut board, alarm, cores.len())?;
    let tick = |n: u64| keyboard::tick_cycle(first, n, clock_hz, map.sample_rate_hz);
    let mut totals = vec![(0u64, 0u64, 0u64); cores.len()];
    for n in 0..samples {
        for (k, w) in words.iter().enumerate() {
            let s = sensors[k];
            let v = if s.is_empty() { 0 } else { s[n % s.len()] };
            if let Some(&a) = w.first() {
                board
                    .write_data(a, &v.to_le_bytes())
                    .map_err(|e| e.to_string())?;
            }
        }
        let stop = board.run_until(tick(n as u64 + 1));
        check(stop, &board)?;
        for (w, &a) in dac.iter_mut().zip(&dac_addrs) {
            *w = board.read_u32(a).map_err(|e| e.to_string())?;
            for b in w.to_le_bytes() {
                digest = (digest ^ b as u64).wrapping_mul(0x0100_0000_01b3);
            }
        }
        for (c, (h, _)) in cores.iter().enumerate() {
            for call in board.calls(*h) {
                let cyc = call.cycles + EXCEPTION_ENTRY as u64;
                totals[c].0 = totals[c].0.max(cyc);
                totals[c].1 += cyc;
                totals[c].2 += 1;
            }
            board.clear_calls(*h);
        }
        if n % 4410 == 0 {
            progress(n, samples);
        }
    }
    progress(samples, samples);
    board.finish_debugging();
    let mut out = Vec::new();
    let mut fault_records = Vec::with_capacity(cores.len());
    for (c, (_, ctrl)) in cores.iter().enumerate() {
        let mut record = [0u32; 3];
        board
            .read_words(crate::image::glue::ctrl::fault_record(*ctrl), &mut record)
            .map_err(|e| e.to_string())?;
        fault_records.push(record);
        let done = board
            .read_u32(ctrl + u32::from(ctrl::SAMPLES))
            .map_err(|e| e.to_string())?;
        let misses = board
            .read_u32(ctrl + u32::from(ctrl::MISSES))
            .map_err(|e| e.to_string())?;
        // Each core completed no more samples than ticks came, and without misses all of
        // them (the last one's handler may still be running): otherwise the map described
        // another firmware.
        let (done64, run) = (u64::from(done), samples as u64);
        if done64 > run || (misses == 0 && done64 + 1 < run) {
            return Err(format!(
                "core {c} completed {done} samples in a run of {samples}: the key map does not \
                 describe this firmware's tick"
            ));
        }
        out.push(CoreRun {
            samples: done,
            misses,
            worst_cycles: totals[c].0,
            mean_cycles: totals[c].1 as f64 / totals[c].2.max(1) as f64,
        });
    }
    Ok(ElfRun {
        samples,
        cores: out,
        cycles_per_sample: keyboard::deadline_cycles(clock_hz as f64, map.sample_rate_hz as f64),
        final_cycles: [board.cores[0].cycle, board.cores[1].cycle],
        dac_final: dac,
        dac_digest: digest,
        fault_records,
    })
}
