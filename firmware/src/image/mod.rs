//! The whole per-sample firmware of a keyboard (or of pens): compiled key programs, the
//! safety limiter, a timer-paced sample interrupt per core, laid out in SRAM and run on the
//! emulated RP2040.
//!
//! [`FirmwareImage::build`] takes the compiled programs ([`Program`]: one per distinct
//! instrument and parameter set; the sets of one instrument share one code and differ in
//! their param block, [`compile_shared`]), the keys ([`KeySpec`]: which program, which core, which
//! sensor/DAC window slots), the board (clock, sample rate) and the limiter's configuration,
//! and produces machine code and data for SRAM plus the static worst-case cycles of each
//! core's interrupt ([`IsrWcet`]). [`FirmwareImage::run`] loads it into an emulated board
//! ([`ImageRun`]), which steps one sample at a time.
//!
//! **Memory.** Each core owns one 64 KB SRAM bank through the non-striped alias
//! (core *c*: bank *c* at `0x21000000 + c·0x10000`, RP2040 datasheet 2.6.1): its vector
//! table, its copy of every program's `.text` that its keys use (one copy per distinct
//! code per core, [`Program::same_code`]: the code is position independent, and a copy per core keeps each
//! core's literal-pool loads in its own bank), its glue code (reset handler, sample
//! interrupt with the limiter inline per force word), its control block, its keys' records
//! and their state structs (each holding its key's param block, which `init` leaves
//! alone). Its stack is in a scratch bank (SRAM4 for core 0, SRAM5 for
//! core 1, its top 1 KiB below the end of SRAM: [`fault::CORE1_STACK_RESERVE`]). Its
//! keys' words of the sensor and DAC windows lie in its own banks too (the *split
//! windows*, below). So the two cores share no SRAM bank after the boot: no access
//! ever waits for the other core ([`IsrWcet::contention`] is 0), and the emulator runs the
//! two cores of a board as independent machines over each sample period
//! (`tactus_emulator::Config::own_banks`, [`FirmwareImage::own_banks`]). Where the cores
//! meet is the boot alone: core 1's launch over the SIO FIFOs and the start alarm, whose
//! timer interrupt reaches both.
//! Code and data occupy disjoint ranges of bank offsets in both banks (core 1's code
//! block follows core 0's in bank offsets, the data of both starts after both blocks), so
//! no data store ever lands in a physical 256-byte page that holds code (the emulator's
//! decode cache would be emptied on each), and the two cores' code does not collide in the
//! emulator's direct-mapped decode cache (indexed by the low address bits: with it, a
//! sample of six hammond keys steps in about 35 µs of host time in a debug build, against
//! 290 µs with both blocks at bank offset 0).
//!
//! **Flash** (modules [`boot2`], `flash_image`): [`FirmwareImage::flash_image`] puts the
//! image in flash behind a second-stage boot loader, with a reset handler that copies
//! every segment below to its SRAM address and jumps to the entry stub; from there on the
//! boot is the RAM image's.
//!
//! **Start** (module [`boot`]): from reset, as on the chip. The image's lowest address,
//! the striped 0x20000000 where the boot ROM enters a RAM image, holds an entry stub that
//! enters core 0's vector table (core 0's block therefore starts at bank offset
//! [`boot::ENTRY_RESERVE`]). Core 0's reset handler writes its stack canary, sets the
//! clocks up (the core voltage the board file gives, PLL_SYS to the board's clock from the
//! 12 MHz crystal, the timer's 1 µs tick, the timer released from reset) and launches core 1 over the SIO FIFOs (0, 0, 1, vector
//! table, stack pointer, entry: RP2040 datasheet 2.8.2), where core 1 waits in the boot
//! ROM; core 1's reset handler, the first code of its glue, writes its canary. Then each
//! reset handler calls `init` for its keys, prepares its SysTick (the sample tick, below),
//! enables TIMER_IRQ_0 and sleeps in `WFI`; core 0 arms the timer's ALARM0 for the start
//! alarm [`FirmwareImage::start_alarm_us`], after both cores' start-up. The alarm wakes both
//! cores on the same cycle, and each core's start handler enables its SysTick on the same
//! cycle ([`glue::core_code`]), so core 1's later start changes nothing after it.
//!
//! **The sample tick** is each core's own SysTick counting the processor clock
//! (CLKSOURCE = 1), its period alternating between `⌊clock/fs⌋` and one cycle more by a
//! remainder accumulator ([`glue::Tick`]) so that the mean period is exactly `1/fs` and
//! tick *n* falls on cycle `first + ⌊n·clock/fs⌋`
//! (`tactus_runtime::keyboard::tick_cycle`), the same cycle on both cores; the deadline is
//! the shorter period, `⌊clock/fs⌋` cycles (`tactus_runtime::keyboard::deadline_cycles`:
//! 3,015 at 133 MHz and 44.1 kHz). The handler starts a fixed exception entry after each
//! tick: no jitter but the cycle of the alternating periods.
//!
//! **Split windows.** The sensor and DAC windows are the [`MAX_KEYS`] words each from
//! [`SENSOR_BASE`] and [`crate::windows::DAC_BASE`], in the striped SRAM, so window word *w*
//! lies in bank *w* mod 4. The image gives each core's keys the words of the core's own
//! banks ([`window_word`]: on a two-core board core *c* takes banks *c* and *c* + 2, 32
//! words each; a one-core board's core all four), in key order, and its handler reads and
//! writes them through the non-striped alias, where a bank's words are consecutive.
//! [`FirmwareImage::window_words`] tells the host (and the key map) which words a key has.
//!
//! **Keys and pens.** A key occupies consecutive words of its core's share of the sensor
//! and DAC windows ([`KeySpec::slot`] orders and names it): one sensor word per sensor of its program, in the program's
//! sensor order ([`Program::sensor_words`]; a pen's vector sensor `pen: m in { z: …, x: …,
//! y: … }` is `pen.z`, `pen.x`, `pen.y` in that order), and one DAC word per force word it
//! drives ([`Program::drives`]): a keyboard program one, its total force `out[total]`; a pen
//! program (`ir::Program::force_axes`) one per axis, **z first** (the total: a pen's first
//! DAC word is its normal force, as a key's), then x and y (the outputs `force.x`,
//! `force.y`). Every force word passes its own limiter (its own time budget and current)
//! through the limiter inline with the scale of its own fixed-point format
//! (`LimiterConstants::dac_scale`). A key's record holds its sensor words (the update's
//! `sensors`), its out words, one limiter budget per force word and its state's address
//! (the budgets and the address before the out words when the out words would push them
//! beyond an `LDR` immediate). [`FirmwareImage::key_glue`] prices one key's glue
//! statically (at the time of writing: a keyboard key 33 cycles, the step to its record
//! included; a pen with three sensors and three axes more, per sensor and per axis). A program's
//! `.text` must fit a core's bank: `plucked_string` (≈100 KB) does not
//! ([`ImageError::NoRoom`]).
//!
//! **The sample interrupt** (per core, SysTick's exception, straight-line code: no loop, so
//! the static WCET needs no loop bounds; it saves no register and loads no base, `glue`'s
//! module documentation says why): set the reload value of the period after the current
//! one (SysTick takes a new RVR at its next reload); then for each key of the core: copy
//! its sensor window words into the key's record, `BL` the program's update (state,
//! &sensors, out in the record), and per force word run the limiter on the word
//! (`out[total]`, or a pen's `force.x`/`force.y` output) and store the DAC code in its DAC
//! window word. Finally: if SysTick is pending again (ICSR.PENDSTSET: the next tick came
//! while the handler ran), the deadline was missed and the core's miss counter is
//! incremented; the sample counter is incremented last. SysTick reloads by itself, so a
//! late handler needs no re-synchronisation: the schedule stands (after a handler longer
//! than a period, the one tick that came during it is served late).

mod access;
pub mod boot;
pub mod boot2;
mod elf;
mod error;
pub mod fault;
mod flash_image;
pub mod glue;
pub mod io;
mod keys;
mod layout;
mod program;
pub mod reboot;
mod rest;
mod run;
mod sample;

pub use error::ImageError;
pub use flash_image::{FlashImage, FlashPiece};
pub use keys::{assign_cores, key_specs, KeySpec};
pub use program::{compile_layout, compile_shared, Drive, Program, MAX_GUARDED_WORDS};
pub use run::{
    code_word, run_to_first_tick, run_to_timer, FaultKind, ImageRun, Injection, IoRecord,
    ResetRecord, HANG_STUB, NOISE_SEED,
};
pub use sample::{DriveOut, KeyEvent, SampleOut};

use crate::windows::{MAX_KEYS, SENSOR_BASE};
use tactus_compiler::thumb::buffer::{CodeBuffer, LongBranch};
use tactus_rp2040::memory::{SRAM_ALIAS_BASE, SRAM_BASE};
use tactus_runtime::keyboard::BoardSpec;
use tactus_runtime::limiter::{Limiter, LimiterConfig};

/// The firmware's limiter routine alone, assembled at `base`, for keys whose force words
/// have `force_frac` fraction bits: returns the code and the routine's address. Calling
/// convention: `r0` = force word, `r1` = address of the budget word (it starts full:
/// `Limiter::constants().budget_max`); returns the DAC code in `r0`. The image inlines
/// exactly this limiter ([`glue::limiter_inline`]) per force word, its scale's constants in
/// registers or (a key whose force format is not its core's main one) from literals, as
/// `scale` says; tests call the routine with arbitrary words.
///
/// Errors: [`ImageError::Limiter`], [`ImageError::Assemble`].
pub fn limiter_routine(
    limiter: &LimiterConfig,
    force_frac: i32,
    scale: glue::Scale,
    base: u32,
) -> Result<(Vec<u8>, u32), ImageError> {
    let consts = Limiter::new(limiter)
        .map_err(ImageError::Limiter)?
        .constants();
    let dac = consts.dac_scale(force_frac).map_err(ImageError::Limiter)?;
    let mut a = CodeBuffer::new(LongBranch::Refuse);
    let entry = a.label();
    glue::limiter_function(&mut a, entry, &consts, &dac, scale)?;
    let out = a.finish_code(base)?;
    Ok((out.text, out.labels[entry.index()]))
}

/// The quiescent-key guard's bookkeeping after an update ([`glue::guard_record`]) alone, as
/// a function assembled at `base`, for tests: the state words at byte offsets `words`
/// (ascending) of a state struct whose shadow lies directly below it. Calling convention:
/// `r0` = the address of a two-word record (the state struct's address, then the calm
/// counter); returns nothing. Returns the code and the routine's address.
///
/// Errors: [`ImageError::Assemble`].
pub fn guard_record_routine(words: &[u32], base: u32) -> Result<(Vec<u8>, u32), ImageError> {
    let g = glue::GuardCode {
        calm_offset: 4,
        calm_needed: 2,
        words: words.to_vec(),
    };
    let mut a = CodeBuffer::new(LongBranch::Refuse);
    let entry = a.label();
    a.bind(entry);
    a.i(tactus_compiler::thumb::ins::push_lr(0xf0));
    a.i(tactus_compiler::thumb::ins::mov(4, 0));
    glue::guard_record(&mut a, &g, 0, None);
    a.i(tactus_compiler::thumb::ins::pop_pc(0xf0));
    a.pool();
    let out = a.finish_code(base)?;
    Ok((out.text, out.labels[entry.index()]))
}

/// Static worst case of one core's sample interrupt, in core clock cycles, from the
/// exception being taken to its return completing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IsrWcet {
    /// [`tactus_isa::wcet::analyse_isr`] of the handler with every key's update and limiter call
    /// (no bank contention).
    pub analysed: u64,
    /// Bank-contention allowance: one wait cycle per access of this core's handler, and of
    /// the other core's handler in the same sample, to a window word in a bank both cores'
    /// keys use (none with the split windows of the module documentation: 0); on core 0 of
    /// an image with the watchdog, the feed's cycles the analysis does not price
    /// ([`glue::Feed::unpriced_cycles`]), on core 1 the wait it may cause there
    /// ([`glue::Feed::other_core_cycles`]).
    pub contention: u64,
    /// Of `analysed`: the keys' update calls (each `BL` and the update's WCET). The rest,
    /// `analysed - updates`, is the handler's own cost: exception entry and return, the
    /// tick, and per key the sensor copy, the limiter and the DAC store.
    pub updates: u64,
}

impl IsrWcet {
    /// The bound: `analysed + contention`.
    pub fn bound(&self) -> u64 {
        self.analysed + self.contention
    }
}

/// The static cost of one key's glue in the sample interrupt
/// ([`FirmwareImage::key_glue`]): what a key costs the handler beyond its update (the
/// planner's per-key estimate, `crate::boards::ProgramCosts`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyGlue {
    /// Core clock cycles of the key's glue (static WCET, no bank contention).
    pub cycles: u64,
    /// Sensor and DAC window words the key accesses per sample (sensor words plus force
    /// words); with the split windows none waits for the other core
    /// ([`IsrWcet::contention`]).
    pub window_words: u64,
}

/// Where one key lives in the image.
#[derive(Clone, Debug)]
pub(crate) struct KeyPlace {
    pub index: usize,
    /// Address of the update this key calls (its core's copy).
    pub update: u32,
    pub spec: KeySpec,
    pub record: u32,
    pub out_len: usize,
    /// Sensor words it reads ([`Program::sensor_words`]).
    pub sensors: usize,
    /// Its sensor window words (indices from `SENSOR_BASE`), in sensor order.
    pub sensor_words: Vec<usize>,
    /// Its DAC window words (indices from `DAC_BASE`), one per force word it drives.
    pub dac_words: Vec<usize>,
    /// With converters: its core's ADC channels, one per sensor word (else empty).
    pub adc_channels: Vec<u32>,
    /// With converters: its core's DAC channels, one per force word (else empty).
    pub dac_channels: Vec<u32>,
    /// Byte offset of the out words in the record.
    pub out_offset: u32,
    /// Byte offset of the state struct's address in the record.
    pub state_offset: u32,
    /// Its force words, each with the byte offset of its limiter budget in the record.
    pub drives: Vec<(Drive, u32)>,
    /// Its sensor check, if it has one.
    pub check: Option<glue::SensorCheck>,
    /// Its update's call sites in its core's sample interrupt (each `BL`'s address), one
    /// per copy of the keys' code ([`glue::CoreLabels::calls`]).
    pub calls: Vec<u32>,
}

/// Where one core's pieces live.
#[derive(Clone, Debug, Default)]
pub(crate) struct CorePlace {
    pub vtor: u32,
    pub reset: u32,
    pub isr: u32,
    /// The runs of the sample interrupt's copies of the keys' code
    /// ([`glue::CoreLabels::copies`]): start and end of each.
    pub keys_spans: Vec<(u32, u32)>,
    pub ctrl: u32,
    pub stack_top: u32,
    pub stack_bottom: u32,
    pub keys: Vec<usize>,
    /// Copies of program code in the core's bank (one per distinct code its keys run).
    pub code_copies: usize,
}

/// A built firmware image: bytes for SRAM, entry points, and what the host needs to run
/// and read it.
#[derive(Clone, Debug)]
pub struct FirmwareImage {
    pub(crate) segments: Vec<(u32, Vec<u8>)>,
    pub(crate) cores: Vec<CorePlace>,
    pub(crate) keys: Vec<KeyPlace>,
    pub(crate) programs: Vec<Program>,
    pub(crate) clock_hz: u64,
    pub(crate) sample_rate_hz: u32,
    pub(crate) start_alarm_us: u32,
    pub(crate) wcet: Vec<IsrWcet>,
    pub(crate) tick: glue::Tick,
    pub(crate) limiter: LimiterConfig,
    code_bytes: Vec<u32>,
    /// How core 0's reset handler boots the board.
    pub(crate) boot: boot::Boot,
    /// The converters' drivers, on a board that has them.
    pub(crate) io: Option<io::IoPlan>,
    /// Per core: the turns of its sensor checks ([`glue::Turns`]).
    pub(crate) turns: Vec<glue::Turns>,
    /// The watchdog's feed as core 0's handler runs it (its feeding class); `None` without
    /// the watchdog.
    pub(crate) feed: Option<glue::Feed>,
    /// The RAM image's re-entry after a watchdog reset, or why it has none ([`reboot`]).
    pub(crate) reentry: Result<reboot::Reboot, String>,
}

/// Bytes of each core's bank below the sensor/DAC windows' share of it (the windows take
/// the striped addresses from [`SENSOR_BASE`], i.e. bank offsets from 0xfc00).
const BANK_LIMIT: u32 = (SENSOR_BASE - SRAM_BASE) / 4;
/// Size of the vector table (16 system exceptions + 32 interrupts), bytes.
const VECTORS: u32 = 48 * 4;
/// Stack bytes per core (the whole scratch bank).
const STACK_BYTES: u32 = 4096;
/// Most sensor words one key may read (its copies are `STR` with an immediate offset past
/// the record's header).
const MAX_SENSORS: usize = 24;
/// A word written at the bottom of each stack; the run checks it after every sample.
pub(crate) const STACK_CANARY: u32 = 0x57AC_CA11;

fn bank_base(core: usize) -> u32 {
    SRAM_ALIAS_BASE + 0x1_0000 * core as u32
}

/// Rows of one bank in each window: window word *w* is row *w* / 4 of bank *w* mod 4.
const WINDOW_ROWS: usize = MAX_KEYS / 4;

/// Writes `bytes` at address `at` into the segment of `segments` that holds them all;
/// `false` when none does.
fn write_at(segments: &mut [(u32, Vec<u8>)], at: u32, bytes: &[u8]) -> bool {
    let len = bytes.len() as u32;
    let Some((base, data)) =
        (segments.iter_mut()).find(|(b, d)| at >= *b && at - *b + len <= d.len() as u32)
    else {
        return false;
    };
    let o = (at - *base) as usize;
    data[o..o + bytes.len()].copy_from_slice(bytes);
    true
}

/// The window word (index from `SENSOR_BASE` / `DAC_BASE`) of core `core`'s `j`-th word on
/// a board of `cores` cores: its own banks' rows in order (core *c* of two: bank *c*, then
/// bank *c* + 2; a single core: banks 0 to 3), `None` past them — the split windows of the
/// module documentation.
pub fn window_word(cores: usize, core: usize, j: usize) -> Option<usize> {
    let banks: &[usize] = match (cores, core) {
        (1, _) => &[0, 1, 2, 3],
        (_, 0) => &[0, 2],
        _ => &[1, 3],
    };
    let bank = *banks.get(j / WINDOW_ROWS)?;
    Some(4 * (j % WINDOW_ROWS) + bank)
}

/// The address of window word `w` of the window at striped address `base` through the
/// non-striped alias of its bank (RP2040 datasheet 2.6.1), where a bank's words are
/// consecutive.
fn window_alias(base: u32, w: usize) -> u32 {
    let striped = base - SRAM_BASE + 4 * w as u32;
    let (bank, row) = ((striped >> 2) & 3, striped >> 4);
    SRAM_ALIAS_BASE + 0x1_0000 * bank + 4 * row
}

impl FirmwareImage {
    /// Lays out and assembles the firmware for `keys` running `programs` on `board`, with
    /// every force word limited by a [`Limiter`] configured by `limiter` (its sample rate
    /// is replaced by the board's).
    ///
    /// Errors: [`ImageError::BadKey`] naming the program (a key's sensor or DAC words beyond
    /// the [`MAX_KEYS`] window words, a window word used by two keys, an unknown program, a
    /// core beyond the board's, a program with more than 24 sensors),
    /// [`ImageError::Board`] (more than 2 cores, a sample rate that is not a whole number of
    /// Hz, a clock below 1 MHz), [`ImageError::Limiter`], [`ImageError::NoRoom`],
    /// [`ImageError::Assemble`], [`ImageError::Wcet`].
    pub fn build(
        programs: &[Program],
        keys: &[KeySpec],
        board: &BoardSpec,
        limiter: &LimiterConfig,
    ) -> Result<FirmwareImage, ImageError> {
        let chip = layout::check_board(board)?;
        let (cores, fs, clock_hz) = (chip.cores, chip.sample_rate_hz, chip.clock_hz);
        let lim_cfg = LimiterConfig {
            sample_rate_hz: fs as f64,
            ..*limiter
        };
        let consts = Limiter::new(&lim_cfg)
            .map_err(ImageError::Limiter)?
            .constants();
        let key_drives = layout::check_keys(programs, keys, cores, &consts)?;
        layout::check_code_fits(programs, keys, cores)?;
        let io = layout::io_plan(board, &chip, programs, keys, &key_drives)?;
        let l = layout::Layout {
            programs,
            keys,
            consts,
            key_drives,
            tick: chip.tick,
            cores,
            io,
            fs: fs as f64,
            watchdog: programs.iter().any(|p| p.watchdog),
        };
        let start_alarm_us = layout::start_alarm_us(programs, keys, clock_hz);

        let mut cc = layout::place_programs(programs, keys, cores);
        let data_off = layout::place_code_blocks(&l, &mut cc, clock_hz, board.core_mv())?;
        let boot = layout::boot_of(&cc, clock_hz, board.core_mv(), l.io.is_some());
        let update_wcets: Vec<u64> = programs
            .iter()
            .map(Program::update_wcet)
            .collect::<Result<_, _>>()?;

        // The entry stub first: made last, once the re-entry is known (`reboot`).
        let mut segments = vec![(boot::ENTRY, Vec::new())];
        let mut places: Vec<CorePlace> = Vec::with_capacity(cores);
        let mut key_places: Vec<Option<KeyPlace>> = vec![None; keys.len()];
        let mut wcet = Vec::with_capacity(cores);
        // Per core: window accesses per bank, and the banks its window words use.
        let mut window_accesses = vec![[0u64; 4]; cores];
        let mut window_banks = vec![0u8; cores];
        let mut code_bytes = vec![0u32; cores];
        let mut turns = Vec::with_capacity(cores);
        let mut feed = None;
        for (core, c) in cc.iter().enumerate() {
            let (bank, base) = (bank_base(core), c.start);
            let g = layout::assemble_glue(&l, core, data_off, c, &boot)?;
            turns.push(g.turns.clone());
            if core == 0 {
                feed = g.feed;
            }
            let out = g.asm.finish_code(base + c.glue)?;
            let (glue_bytes, addr) = (out.text, out.labels);
            if addr[g.labels.reset.index()] != base + c.glue {
                return Err(ImageError::Assemble(format!(
                    "core {core}: the reset handler is not the first code of the glue"
                )));
            }
            let code_end = base + c.glue + glue_bytes.len() as u32;
            let next = cc
                .get(core + 1)
                .map_or(bank + data_off, |n| n.start - 0x1_0000);
            if code_end > next {
                return Err(ImageError::Assemble(format!(
                    "core {core}: the glue grew past its block ({code_end:#x} > {next:#x})"
                )));
            }
            code_bytes[core] = code_end - base;
            let ctrl_addr = bank + data_off;
            // Each call site of the core's keys and its key's window slot, for the reset
            // handler's search of a hung key (`fault`, "Which key hung").
            let at = &addr;
            let sites: Vec<(u32, u8)> = (g.keys.iter().zip(&g.labels.calls))
                .flat_map(|(k, calls)| {
                    let slot = k.spec.slot.min(usize::from(fault::UNKNOWN_KEY) - 1) as u8;
                    calls.iter().map(move |l| (at[l.index()], slot))
                })
                .collect();
            let table = glue::HangLookup::table_bytes(&sites);
            let data = layout::data_block(
                &l,
                core,
                &g.keys,
                g.data_end,
                start_alarm_us,
                &l.tick,
                g.hang.as_ref().map(|h| (h, &table[..])),
            )?;
            let code = layout::vector_table(core, c, programs, &g.labels, &addr, &glue_bytes);
            wcet.push(layout::analyse_handler(
                core,
                base,
                &code,
                &g.labels,
                &addr,
                &g.keys,
                &update_wcets,
            )?);
            for k in &g.keys {
                for &w in k.sensor_words.iter().chain(&k.dac_words) {
                    window_accesses[core][w % 4] += 1;
                    window_banks[core] |= 1 << (w % 4);
                }
            }
            segments.push((base, code));
            segments.push((ctrl_addr, data));
            let mut place = layout::core_place(core, c, &g.labels, &addr, ctrl_addr);
            for (mut k, calls) in g.keys.into_iter().zip(&g.labels.calls) {
                k.calls = calls.iter().map(|l| addr[l.index()]).collect();
                let i = k.index;
                place.keys.push(i);
                if let Some(slot) = key_places.get_mut(i) {
                    *slot = Some(k);
                }
            }
            places.push(place);
        }
        // Bank contention: the window accesses of both cores' handlers to banks both cores'
        // window words use (none: each core's words lie in its own banks), on a core with
        // keys.
        let shared = window_banks[0] & window_banks.get(1).copied().unwrap_or(0);
        let total: u64 = window_accesses
            .iter()
            .map(|by_bank| {
                (0..4)
                    .filter(|b| shared >> b & 1 != 0)
                    .map(|b| by_bank[b])
                    .sum::<u64>()
            })
            .sum();
        for (c, (w, p)) in wcet.iter_mut().zip(&places).enumerate() {
            w.contention = if p.keys.is_empty() { 0 } else { total };
            // The watchdog's feed on core 0: its APB store and its load from core 1's bank,
            // which core 1 may be the one to wait for.
            if let Some(f) = l.feed(data_off) {
                w.contention += match c {
                    0 => f.unpriced_cycles(),
                    _ => f.other_core_cycles(),
                };
            }
            // With converters, the DMA's accesses to the core's I/O bank (`io.rs`).
            if let Some(cio) = l.io.as_ref().and_then(|io| io.cores.get(c)) {
                w.contention += cio.contention();
            }
        }
        // Each core's I/O block (results, commands, DAC frames) in bank 2 + core.
        if let Some(io) = &l.io {
            for c in 0..io.cores.len() {
                segments.push((io::io_base(c), io.io_block(c)));
            }
        }
        // A RAM image's way back after a watchdog reset, and the entry stub.
        let data_at: Vec<u32> = (places.iter().map(|p| p.ctrl))
            .chain((0..cores).filter(|_| l.io.is_some()).map(io::io_base))
            .collect();
        let reentry = reboot::finish(&mut segments, &data_at, l.watchdog, cc[0].start)?;
        let keys = key_places
            .into_iter()
            .enumerate()
            .map(|(i, k)| {
                k.ok_or(ImageError::BadKey {
                    key: i,
                    why: "not placed".into(),
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(FirmwareImage {
            segments,
            cores: places,
            keys,
            programs: programs.to_vec(),
            clock_hz,
            sample_rate_hz: fs,
            start_alarm_us,
            wcet,
            tick: l.tick,
            limiter: lim_cfg,
            code_bytes,
            boot,
            io: l.io,
            turns,
            feed,
            reentry,
        })
    }

    /// The same image for keys whose programs differ from this image's in their param
    /// blocks only: `programs` as many as [`FirmwareImage::programs`], each of the same code,
    /// fixed-point program and flags as the image's program of its index and with a param
    /// block of the same length. Each key's param block is written into its state (and into
    /// the state's pristine copy of the watchdog's re-entry, [`reboot`]). A param block is
    /// data the image places and nothing else reads (no code, layout or static bound depends
    /// on it, [`Program::params`]), so this is byte for byte the image
    /// [`FirmwareImage::build`] makes of `programs` for the same keys: what the planner's
    /// boards of one shape share (`crate::boards`).
    ///
    /// Errors: [`ImageError::BadKey`] naming the first key whose program is not such a
    /// program (or a program count unlike the image's), or whose param block is not in a
    /// data segment.
    pub fn with_params(&self, programs: &[Program]) -> Result<FirmwareImage, ImageError> {
        let alike = |a: &Program, b: &Program| {
            a.same_code(b)
                && std::sync::Arc::ptr_eq(&a.fixed, &b.fixed)
                && a.params.len() == b.params.len()
                && a.quiescent_guard == b.quiescent_guard
                && a.sensor_check == b.sensor_check
                && a.watchdog == b.watchdog
        };
        let bad = |key: usize, why: &str| ImageError::BadKey {
            key,
            why: why.to_string(),
        };
        if programs.len() != self.programs.len() {
            return Err(bad(0, "not as many programs as the image's"));
        }
        let mut image = self.clone();
        for (k, key) in self.keys.iter().enumerate() {
            let (old, new) = (
                &self.programs[key.spec.program],
                &programs[key.spec.program],
            );
            if !alike(old, new) {
                return Err(bad(k, "its program is not the image's with other params"));
            }
            if new.params.is_empty() {
                continue;
            }
            let (_, state) = self.key_addresses(k).ok_or_else(|| bad(k, "no state"))?;
            let at = state + new.thumb.state.params as u32;
            let bytes: Vec<u8> = new.params.iter().flat_map(|w| w.to_le_bytes()).collect();
            let copy = (self.reentry.as_ref().ok()).map(|r| r.copy_of(at, bytes.len() as u32));
            if !write_at(&mut image.segments, at, &bytes) || copy == Some(None) {
                return Err(bad(k, "its param block is not in the image's data"));
            }
            if let (Some(Some(copy)), Ok(r)) = (copy, image.reentry.as_mut()) {
                // The copy is in the image's segments and in the re-entry's own.
                if !write_at(&mut image.segments, copy, &bytes)
                    || !write_at(&mut r.segments, copy, &bytes)
                {
                    return Err(bad(k, "its param block's copy is not in the image"));
                }
            }
        }
        image.programs = programs.to_vec();
        Ok(image)
    }

    /// Static cost of one key of `program` in the sample interrupt beyond its update: its
    /// sensor copies (with the quiescent-key guard; without it the update reads its window
    /// words in place), the update's call set-up, per force word the limiter and the DAC
    /// store, the step to the next key's record ([`KeyGlue`]). Measured from the generated
    /// glue, as the most one such key adds to core 0's handler on `board` (static WCET
    /// minus the update calls): the first key over the handler without keys, or a second
    /// over the first. So a core with `n` such keys costs at most the handler without keys
    /// plus `n` times this. A keyboard key costs the same whatever its program; a pen more,
    /// per sensor and per axis.
    ///
    /// Errors: those of [`FirmwareImage::build`] (e.g. [`ImageError::NoRoom`] for a
    /// program too large for a core's bank).
    pub fn key_glue(
        program: &Program,
        board: &BoardSpec,
        limiter: &LimiterConfig,
    ) -> Result<KeyGlue, ImageError> {
        let programs = [program.clone()];
        let drives = program.drives()?.len();
        let width = program.sensor_words().max(drives);
        // The second key two widths on: its window words beyond an `ADDS #imm3` of the
        // first's (what a third or fourth key of a core pays to point at its sensors).
        let keys: Vec<KeySpec> = (0..2)
            .map(|i| KeySpec {
                slot: 2 * i * width,
                program: 0,
                core: 0,
            })
            .collect();
        // The handler's own cycles with 0, 1 and 2 keys.
        let own = |n: usize| -> Result<u64, ImageError> {
            let w = FirmwareImage::build(&programs, &keys[..n], board, limiter)?.wcet[0];
            Ok(w.analysed.saturating_sub(w.updates))
        };
        let (none, one) = (own(0)?, own(1)?);
        // Two keys may not fit a bank where one does: then one key is all a core holds.
        let second = own(2).map_or(0, |two| two.saturating_sub(one));
        Ok(KeyGlue {
            cycles: one.saturating_sub(none).max(second),
            window_words: (program.sensor_words() + drives) as u64,
        })
    }

    /// Whether the image can run on a chip, not only in the emulator: `Err` naming the
    /// board's clock when no PLL_SYS setting makes it from the 12 MHz crystal (the reset
    /// handler then leaves the clocks alone; the emulator runs at the board's clock from
    /// power-on whatever the firmware sets), or when the board's core voltage is too low
    /// for it ([`tactus_rp2040::vreg::min_core_mv`]: the emulator refuses such an
    /// image when it switches clk_sys).
    ///
    /// Errors: [`ImageError::Board`].
    pub fn flashable(&self) -> Result<(), ImageError> {
        if let Some(why) = crate::board_file::pll_error(self.clock_hz) {
            return Err(ImageError::Board(format!("clock {why}")));
        }
        let core_mv = self.boot.vsel.map_or(
            tactus_rp2040::vreg::DEFAULT_CORE_MV,
            tactus_rp2040::vreg::vsel_mv,
        );
        match tactus_rp2040::vreg::min_core_mv(self.clock_hz) {
            None => Err(ImageError::Board(format!(
                "clock {} MHz: beyond the 200 MHz the RP2040 is specified for (at 1.15 V, \
                 pico-sdk 2.1.1)",
                self.clock_hz as f64 / 1e6
            ))),
            Some(need) if core_mv < need => Err(ImageError::Board(format!(
                "clock {} MHz at a core voltage of {:.2} V: the RP2040 needs {:.2} V for it \
                 (pico-sdk 2.1.1); add `core_voltage_v = {:.2}` to the board file",
                self.clock_hz as f64 / 1e6,
                core_mv as f64 / 1e3,
                need as f64 / 1e3,
                need as f64 / 1e3
            ))),
            Some(_) => Ok(()),
        }
    }
}
