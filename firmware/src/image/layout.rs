//! The steps of [`FirmwareImage::build`], each named after what it lays out.
//!
//! The order is forced by what each step needs: the board and the keys are checked first
//! ([`check_board`], [`check_keys`], [`check_code_fits`]: nothing is analysed for a program
//! that cannot be placed); the tick schedule (`crate::board_file::tick_schedule`) and the start alarm
//! ([`start_alarm_us`]) follow from the board and the programs' `init` costs. Then the code:
//! per core a block of vector table and program copies ([`place_programs`]), whose glue's
//! size is measured at provisional addresses ([`place_code_blocks`], which also fixes where
//! the data starts: the same bank offset in every bank, past every core's block); then per
//! core the glue at its final address ([`assemble_glue`], with the key records
//! [`key_records`] lays out), the control block, records and states ([`data_block`]), the
//! vector table ([`vector_table`]) and the static WCET of the sample interrupt over the
//! core's whole code ([`analyse_handler`]).

use super::boot::{self, Boot};
use super::glue::{self, ctrl, DriveCode, KeyCode, Tick};
use super::{
    bank_base, window_alias, window_word, CorePlace, Drive, ImageError, IsrWcet, KeyPlace, KeySpec,
    Program, BANK_LIMIT, MAX_SENSORS, STACK_BYTES, STACK_CANARY, VECTORS,
};
use crate::windows::{DAC_BASE, MAX_KEYS, SENSOR_BASE};
use std::collections::BTreeMap;
use tactus_compiler::thumb::buffer::{CodeBuffer, Label, LongBranch};
use tactus_isa::wcet::{self, Bounds};
use tactus_rp2040::memory::{SRAM4_BASE, SRAM5_BASE};
use tactus_runtime::converters::AdcScale;
use tactus_runtime::keyboard::BoardSpec;
use tactus_runtime::limiter::{DacScale, LimiterConstants};

/// What the steps share: the inputs of the build and what the checks derived from them.
pub(super) struct Layout<'a> {
    pub programs: &'a [Program],
    pub keys: &'a [KeySpec],
    /// The limiter's constants at the board's sample rate.
    pub consts: LimiterConstants,
    /// Per key, the force words it drives ([`Program::drives`]).
    pub key_drives: Vec<Vec<Drive>>,
    pub tick: Tick,
    /// The board's cores.
    pub cores: usize,
    /// The converters' drivers, on a board that has them.
    pub io: Option<super::io::IoPlan>,
    /// The sample rate, Hz.
    pub fs: f64,
    /// Whether the image runs the watchdog ([`Program::watchdog`] of any of its programs).
    pub watchdog: bool,
}

impl Layout<'_> {
    /// Core `core`'s part of the watchdog's feed ([`glue::Feed`]), with the control blocks
    /// at bank offset `data_off`: core 0 feeds, watching core 1's sample count, and arms
    /// the boot ROM's watchdog entry into the RAM image's re-entry (`super::reboot`).
    pub fn feed(&self, data_off: u32) -> Option<glue::Feed> {
        self.watchdog.then(|| glue::Feed {
            other_samples: (self.cores > 1)
                .then(|| bank_base(1) + data_off + u32::from(glue::ctrl::SAMPLES)),
            // The RAM image's re-entry, with core 0's stack (`super::reboot`).
            entry: Some((super::reboot::REENTRY | 1, stack(0).1)),
            // Every sample, until core 0's turns are planned ([`assemble_glue`]).
            class: None,
        })
    }
}

/// The converters' drivers of `board` ([`super::io::IoPlan::new`]) for `keys` on `cores`
/// cores: per core, in key order, an ADC channel per sensor word of each key (its scale
/// from the sensor's declared range; a program without sensors reads 0) and a DAC channel
/// per force word. `None` for a board without converters.
///
/// Errors: those of [`super::io::IoPlan::new`].
pub(super) fn io_plan(
    board: &BoardSpec,
    chip: &crate::board_file::Chip,
    programs: &[Program],
    keys: &[KeySpec],
    key_drives: &[Vec<Drive>],
) -> Result<Option<super::io::IoPlan>, ImageError> {
    let Some((adc, _)) = board.converter_parts() else {
        if board.converters.is_some() {
            // Unknown parts: the plan names the field.
            return super::io::IoPlan::new(board, chip.clock_hz, 0, vec![], vec![]);
        }
        return Ok(None);
    };
    let mut scales = vec![Vec::new(); chip.cores];
    let mut dacs = vec![0u32; chip.cores];
    for (k, drives) in keys.iter().zip(key_drives) {
        let (Some(p), Some(sc)) = (programs.get(k.program), scales.get_mut(k.core)) else {
            continue;
        };
        let fp = &p.fixed;
        for i in 0..p.sensor_words() {
            let (lo, hi) = fp.sensor_raw_range.get(i).copied().unwrap_or((0, 0));
            sc.push(tactus_runtime::converters::AdcScale::new(lo, hi, adc.bits));
        }
        dacs[k.core] += drives.len() as u32;
    }
    super::io::IoPlan::new(board, chip.clock_hz, u64::from(chip.tick.q), scales, dacs)
}

/// The board's cores, sample rate (Hz) and clock (Hz) as the image needs them
/// ([`crate::board_file::image_board`], the one rule).
///
/// Errors: [`ImageError::Board`] naming the field.
pub(super) fn check_board(board: &BoardSpec) -> Result<crate::board_file::Chip, ImageError> {
    crate::board_file::image_board(board).map_err(|e| ImageError::Board(e.to_string()))
}

/// Checks every key — its program exists, its words in both windows are inside them and
/// no other key's, at most [`MAX_SENSORS`] sensors, its core exists, the limiter can scale
/// each of its force formats — and returns the force words each key drives.
///
/// Errors: [`ImageError::BadKey`], [`ImageError::Limiter`].
pub(super) fn check_keys(
    programs: &[Program],
    keys: &[KeySpec],
    cores: usize,
    consts: &LimiterConstants,
) -> Result<Vec<Vec<Drive>>, ImageError> {
    let mut used_sensor = BTreeMap::new();
    let mut used_dac = BTreeMap::new();
    let mut key_drives = Vec::with_capacity(keys.len());
    for (i, k) in keys.iter().enumerate() {
        let bad = |why: String| Err(ImageError::BadKey { key: i, why });
        let Some(p) = programs.get(k.program) else {
            return bad(format!("program {} does not exist", k.program));
        };
        let drives = p.drives()?;
        let ns = p.sensor_words();
        for (window, n, used) in [
            ("sensor", ns, &mut used_sensor),
            ("DAC", drives.len(), &mut used_dac),
        ] {
            if k.slot + n > MAX_KEYS {
                return bad(format!(
                    "slot {}: program `{}` needs {window} window words {}..{} ({n} from the                          slot), beyond the {MAX_KEYS} window words",
                    k.slot,
                    p.thumb.stem,
                    k.slot,
                    k.slot + n
                ));
            }
            for s in k.slot..k.slot + n {
                if let Some(j) = used.insert(s, i) {
                    return bad(format!("{window} slot {s} is also key {j}'s"));
                }
            }
        }
        if ns > MAX_SENSORS {
            return bad(format!(
                "program `{}` reads {ns} sensors; the image copies at most {MAX_SENSORS} \
                 per key",
                p.thumb.stem
            ));
        }
        if k.core >= cores {
            return bad(format!("core {} but the board has {cores}", k.core));
        }
        for d in &drives {
            consts
                .dac_scale(d.frac)
                .map_err(|e| ImageError::Limiter(format!("program `{}`: {e}", p.thumb.stem)))?;
        }
        key_drives.push(drives);
    }
    Ok(key_drives)
}

/// Per program, the program whose code copy serves it: the first with the same code
/// ([`Program::same_code`]: the parameter sets of one instrument share one code).
fn code_of(programs: &[Program]) -> Vec<usize> {
    programs
        .iter()
        .map(|p| programs.iter().position(|q| q.same_code(p)).unwrap_or(0))
        .collect()
}

/// Whether core `core` holds a copy of program `p`'s code: `p` is the first with its code
/// and a key of the core runs that code.
fn core_uses(code_of: &[usize], keys: &[KeySpec], core: usize, p: usize) -> bool {
    code_of[p] == p
        && keys
            .iter()
            .any(|k| k.core == core && code_of.get(k.program) == Some(&p))
}

/// The programs' code alone must fit each core's bank (checked before any analysis: a
/// program too large to place, such as `plucked_string`, is not analysed); one copy per
/// distinct code.
///
/// Errors: [`ImageError::NoRoom`].
pub(super) fn check_code_fits(
    programs: &[Program],
    keys: &[KeySpec],
    cores: usize,
) -> Result<(), ImageError> {
    let code_of = code_of(programs);
    for core in 0..cores {
        let mut need = VECTORS;
        for (p, prog) in programs.iter().enumerate() {
            if core_uses(&code_of, keys, core, p) {
                need = need.next_multiple_of(4) + prog.thumb.code.text.len() as u32;
            }
        }
        if need > BANK_LIMIT {
            return Err(ImageError::NoRoom {
                core,
                need,
                have: BANK_LIMIT,
            });
        }
    }
    Ok(())
}

/// Words of a key record after its sensor copies for the sensor check
/// ([`glue::SensorCheck`]): the recovery count and the last reading, then per drive its
/// gate's two words ([`glue::Gate`]).
const FAULT_WORDS: u32 = 2;

/// Words of a key record with `ns` sensor words, `out_len` out words and `nd` drives:
/// the sensor copies, the out words, the budgets, the state address, the guard's counter
/// and the check's words.
fn record_words(ns: u32, out_len: u32, nd: u32, checked: bool) -> u32 {
    ns + out_len + nd + 2 + if checked { FAULT_WORDS + 2 * nd } else { 0 }
}

/// Whether a key of program `p` has a rest image in its core's data: its first sensor is
/// a position (the one the sensor check can judge, [`sensor_check`]).
fn has_rest_image(p: &Program) -> bool {
    p.sensor_check
        && p.fixed.program.sensors.first().map(|s| s.dim)
            == Some(tactus_compiler::units::Dim::LENGTH)
}

/// The sensor check of a key of program `p` at `fs` Hz ([`glue::SensorCheck`]): on its
/// first sensor word (a key's position, a pen's depth), the check words at record offset
/// `words_at`, its fault word naming window slot `slot`; checked on turn `turn` with gaps
/// of at most `max_gap` samples between checks and `recovery` plausible checks before a
/// tripped key plays again ([`glue::Turns`]; `None`, 1 and the recovery's samples: every
/// sample), its limiters' gate words for `drives` (each drive's scale)
/// after the check's words when it takes turns. `None` for a program without sensors,
/// and where the words lie beyond an `LDR` immediate.
fn sensor_check(
    p: &Program,
    l: &Layout,
    words_at: u32,
    slot: usize,
    turn: Option<u8>,
    (max_gap, recovery): (u32, u32),
    drives: &[DacScale],
) -> Option<glue::SensorCheck> {
    if !checkable(p, words_at, drives.len()) {
        return None;
    }
    let sensor = p.fixed.program.sensors.first()?;
    let &(lo, hi) = p.fixed.sensor_raw_range.first()?;
    let step = super::fault::max_step_raw(lo, hi, sensor.range.1 - sensor.range.0, l.fs, max_gap);
    // The accepted change is [-2^k, 2^k) with 2^k the power of two at or above the bound.
    let k = (32 - (step.max(2) - 1).leading_zeros()).clamp(1, 30) as u8;
    let gate = match turn {
        Some(_) => drives
            .iter()
            .enumerate()
            .map(|(j, s)| glue::Gate {
                rated_offset: words_at + 8 + 8 * j as u32,
                gain_offset: words_at + 12 + 8 * j as u32,
                rated: s.last_magnitude_within(l.consts.rated_code),
                gain: s.gain,
            })
            .collect(),
        None => Vec::new(),
    };
    Some(glue::SensorCheck {
        lo,
        hi,
        shift: k,
        left_offset: words_at,
        last_offset: words_at + 4,
        slot: slot.min(0xfe) as u8,
        recovery,
        rest: 0,
        state_words: (p.thumb.state.size as u32).div_ceil(4),
        turn,
        gate,
        modes: state_check_modes(p),
    })
}

/// The mode bytes a key of program `p`'s state check tests ([`glue::SensorCheck::modes`]):
/// each mode's byte offset in the state struct and its variants, where the byte lies
/// within an `LDRB` immediate (31) and some byte value is no variant (fewer than 256).
fn state_check_modes(p: &Program) -> Vec<(u8, u8)> {
    let base = p.thumb.state.modes;
    (p.fixed.program.modes.iter().enumerate())
        .filter_map(|(i, m)| {
            let off = u8::try_from(base + i).ok().filter(|&o| o <= 31)?;
            let n = u8::try_from(m.variants.len()).ok()?;
            Some((off, n))
        })
        .collect()
}

/// Whether a key of program `p` with `nd` drives, its check's words at `words_at`, has a
/// sensor check: a position sensor, a drive, and every word within an `LDR` immediate.
fn checkable(p: &Program, words_at: u32, nd: usize) -> bool {
    has_rest_image(p)
        && nd > 0
        && words_at + 4 + 8 * nd as u32 <= 124
        && !p.fixed.sensor_raw_range.is_empty()
}

/// Cycles after the start alarm by which both cores have enabled their SysTick (the
/// exception entry and the start handler's first three instructions take about 20); the
/// run reads each core's first tick then, before it falls due.
pub const START_CYCLES: u64 = 64;

/// Microsecond time of the start alarm, at which both cores start their SysTick (the first
/// tick follows `q` cycles later, [`Tick`]): after every core's start-up (the run checks
/// that both were ready). Start-up is the boot (clock set-up and core 1's launch: a few hundred
/// cycles in the emulator, which does not model oscillator start-up or PLL lock times;
/// the timer counts from its release after them), the keys' `init` calls (their static
/// WCET; 4000 cycles for one that cannot be analysed) plus a few dozen cycles per key and
/// for the timer set-up (50 a key: its `init` call, and after a watchdog reset the reset
/// handler's search of its call sites for the key that hung, `glue::HangLookup`, at most
/// 4 copies of 8 cycles; the sum is over both cores' keys, which start up in parallel).
pub(super) fn start_alarm_us(programs: &[Program], keys: &[KeySpec], clock_hz: u64) -> u32 {
    let mut init_cycles = Vec::with_capacity(programs.len());
    for p in programs {
        init_cycles.push(p.init_wcet().unwrap_or(4000));
    }
    let startup: u64 = BOOT_CYCLES
        + 1000
        + keys
            .iter()
            .map(|k| {
                let p = &programs[k.program];
                // The rest image's copy ([`glue::SensorCheck`]), 8 cycles a word at most.
                let rest = if has_rest_image(p) {
                    2 * p.thumb.state.size as u64
                } else {
                    0
                };
                50 + init_cycles[k.program] + rest
            })
            .sum::<u64>();
    (20 + (startup * 1_000_000).div_ceil(clock_hz)) as u32
}

/// Cycles allowed for the boot before the keys' start-up ([`boot::core_start`]).
const BOOT_CYCLES: u64 = 1000;

/// One core's code block: its vector table, the copies of the programs its keys use
/// (fixed sizes), then its glue.
pub(super) struct CoreCode {
    /// Address of the block (the vector table), 256-aligned.
    pub start: u32,
    /// (program, offset of its .text copy in the block).
    pub texts: Vec<(usize, u32)>,
    /// Offset of the glue in the block.
    pub glue: u32,
}

/// Per core, the vector table and one copy of each code its keys use, at offsets in a
/// block provisionally at the start of the core's bank ([`place_code_blocks`] moves it).
pub(super) fn place_programs(
    programs: &[Program],
    keys: &[KeySpec],
    cores: usize,
) -> Vec<CoreCode> {
    let mut cc = Vec::new();
    let code_of = code_of(programs);
    for core in 0..cores {
        let mut at = VECTORS;
        let mut texts = Vec::new();
        for (p, prog) in programs.iter().enumerate() {
            if core_uses(&code_of, keys, core, p) {
                at = at.next_multiple_of(4);
                texts.push((p, at));
                at += prog.thumb.code.text.len() as u32;
            }
        }
        cc.push(CoreCode {
            start: bank_base(core),
            texts,
            glue: at.next_multiple_of(4),
        });
    }
    cc
}

/// The key records of core `core` (its control block at `ctrl_addr`, its code block `cc`):
/// the glue's view of each key ([`KeyCode`]), where each key lives ([`KeyPlace`]) and the
/// address after the last record.
///
/// Each record holds the sensor words first (the update's `sensors`), then the out words,
/// the budgets, the state address and the quiescent guard's calm counter — or, where the
/// out words would push those beyond an `LDR` immediate, the budgets, the state address
/// and the counter before the out words.
///
/// Errors: [`ImageError::Compile`] when a program lacks its update or init symbol.
pub(super) fn key_records(
    l: &Layout,
    core: usize,
    ctrl_addr: u32,
    cc: &CoreCode,
) -> Result<Records, ImageError> {
    let (programs, keys) = (l.programs, l.keys);
    let my: Vec<usize> = (0..keys.len()).filter(|&i| keys[i].core == core).collect();
    // Records after the control block, states after the records.
    let mut at = ctrl_addr + ctrl::SIZE;
    let mut kc = Vec::new();
    let mut kp = Vec::new();
    let code_of = code_of(programs);
    // The keys whose checks take turns ([`glue::Turns`]): checked, without the
    // quiescent-key guard (whose copy of the sensor word is the check's, every sample).
    let words_at = |i: usize| {
        let p = &programs[keys[i].program];
        4 * (p.sensor_words() as u32 + p.thumb.out.len as u32 + l.key_drives[i].len() as u32 + 2)
    };
    let taking_turns: Vec<usize> = my
        .iter()
        .copied()
        .filter(|&i| {
            let p = &programs[keys[i].program];
            checkable(p, words_at(i), l.key_drives[i].len()) && p.guard(0).is_none()
        })
        .collect();
    let turns = glue::Turns::plan(&l.tick, taking_turns.len());
    // The core's next window word (module documentation, "Split windows"), and with
    // converters its next ADC and DAC channels.
    let mut word = 0;
    let (mut adc_ch, mut dac_ch) = (0u32, 0u32);
    let scales: &[AdcScale] =
        l.io.as_ref()
            .and_then(|p| p.cores.get(core))
            .map_or(&[], |c| &c.scales[..]);
    for &i in &my {
        let p = &programs[keys[i].program];
        let text = cc
            .texts
            .iter()
            .find(|t| Some(&t.0) == code_of.get(keys[i].program))
            .map_or(0, |t| cc.start + t.1);
        let sym = |name: String| {
            p.thumb
                .symbol(&name)
                .map(|(o, _)| text + o as u32)
                .ok_or_else(|| ImageError::Compile(format!("no symbol `{name}`")))
        };
        let out_len = p.thumb.out.len as u32;
        let ns = p.sensor_words() as u32;
        let drives = &l.key_drives[i];
        let nd = drives.len() as u32;
        let (out_offset, budgets_offset) = if 4 * (ns + out_len + nd + 1) <= 124 {
            (4 * ns, 4 * (ns + out_len))
        } else {
            (4 * (ns + nd + 2), 4 * ns)
        };
        // The sensor check's two words end the record ([`glue::SensorCheck`]: the recovery
        // count and the last reading while tripped), where an `LDR` reaches them.
        let fs = 4 * (ns + out_len + nd + 2);
        let state_offset = budgets_offset + 4 * nd;
        let calm_offset = state_offset + 4;
        let size = 4 * record_words(ns, out_len, nd, has_rest_image(p));
        let budgets: Vec<u32> = (0..nd).map(|j| budgets_offset + 4 * j).collect();
        let update = sym(p.thumb.update_name())?;
        let width = ns.max(nd) as usize;
        let words: Vec<usize> = (word..word + width)
            .map(|j| window_word(l.cores, core, j))
            .collect::<Option<_>>()
            .ok_or(ImageError::BadKey {
                key: i,
                why: format!(
                    "core {core}'s keys need more than its {} window words",
                    (word..)
                        .take_while(|&j| window_word(l.cores, core, j).is_some())
                        .count()
                        + word
                ),
            })?;
        word += width;
        let sensor_words = words[..ns as usize].to_vec();
        let dac_words = words[..nd as usize].to_vec();
        let (adc_channels, dac_channels): (Vec<u32>, Vec<u32>) = if l.io.is_some() {
            let a = (adc_ch..adc_ch + ns).collect();
            let d = (dac_ch..dac_ch + nd).collect();
            adc_ch += ns;
            dac_ch += nd;
            (a, d)
        } else {
            (Vec::new(), Vec::new())
        };
        // With converters: the channels' words in results buffer A when the ADC pushes
        // them (`io::CoreIo::direct`), else each channel with its scale.
        let core_io = l.io.as_ref().and_then(|p| p.cores.get(core));
        let direct = core_io.is_some_and(|c| c.direct);
        let sensor_addrs: Vec<u32> = match core_io {
            Some(_) => adc_channels
                .iter()
                .map(|&ch| super::io::io_base(core) + super::io::RESULTS_A + 4 * ch)
                .collect(),
            None => sensor_words
                .iter()
                .map(|&w| window_alias(SENSOR_BASE, w))
                .collect(),
        };
        let sensor_channels = adc_channels
            .iter()
            .filter(|_| !direct)
            .map(|&ch| {
                let scale = scales
                    .get(ch as usize)
                    .copied()
                    .unwrap_or(AdcScale::new(0, 0, 16));
                (ch, scale)
            })
            .collect();
        let scales: Vec<DacScale> = drives
            .iter()
            .map(|d| {
                // Checked by `check_keys`, with the same constants.
                l.consts.dac_scale(d.frac).unwrap_or(DacScale {
                    pre_shift: 0,
                    gain: 1,
                    post_shift: 0,
                })
            })
            .collect();
        let recovery = super::fault::recovery_samples(l.fs);
        let (turn, gaps) = match taking_turns.iter().position(|&t| t == i) {
            Some(n) if turns.classes > 1 => {
                let c = turns.class_of(n);
                let max_gap = turns.gaps[usize::from(c)].0;
                (Some(c), (max_gap, turns.checks_in(c, recovery)))
            }
            _ => (None, (1, recovery)),
        };
        let check = sensor_check(p, l, fs, keys[i].slot, turn, gaps, &scales);
        kc.push(KeyCode {
            sensor_words: sensor_addrs,
            sensor_channels,
            out_offset,
            state_offset,
            drives: drives
                .iter()
                .zip(&budgets)
                .enumerate()
                .map(|(j, (d, &b))| DriveCode {
                    dac_channel: dac_channels.get(j).copied(),
                    force_offset: out_offset + 4 * d.out_index as u32,
                    budget_offset: b,
                    dac_word: window_alias(DAC_BASE, dac_words[j]),
                    scale: scales[j],
                })
                .collect(),
            record_size: size,
            update,
            init: sym(p.thumb.init_name())?,
            guard: p.guard(calm_offset),
            clobbers: p.thumb.clobbers,
            check: check.clone(),
        });
        kp.push(KeyPlace {
            index: i,
            update,
            spec: keys[i],
            record: at,
            out_len: out_len as usize,
            sensors: ns as usize,
            sensor_words,
            dac_words,
            adc_channels,
            dac_channels,
            out_offset,
            state_offset,
            drives: drives.iter().copied().zip(budgets).collect(),
            check,
            calls: Vec::new(),
        });
        at += size;
    }
    // The rest images of the checked keys, after every state ([`data_block`]'s order).
    let mut end = at.next_multiple_of(4);
    for k in &kp {
        let p = &programs[k.spec.program];
        let shadow = p.guard(0).map_or(0, |g| g.shadow_bytes());
        end = (end + shadow + p.thumb.state.size as u32).next_multiple_of(4);
    }
    for (k, code) in kp.iter().zip(kc.iter_mut()) {
        let p = &programs[k.spec.program];
        if has_rest_image(p) {
            if let Some(c) = code.check.as_mut() {
                c.rest = end;
            }
            end += 4 * (p.thumb.state.size as u32).div_ceil(4);
        }
    }
    Ok(Records {
        code: kc,
        places: kp,
        data_end: at,
        table: end,
        turns,
    })
}

/// A core's keys as [`key_records`] lays them out.
pub(super) struct Records {
    /// The keys as the glue sees them.
    pub code: Vec<KeyCode>,
    /// Where they live.
    pub places: Vec<KeyPlace>,
    /// The address after the last key record (the states follow).
    pub data_end: u32,
    /// The address after the last rest image: the table of call sites
    /// ([`glue::HangLookup`]), the data's last part.
    pub table: u32,
    /// The turns of the core's sensor checks.
    pub turns: glue::Turns,
}

/// One core's glue, assembled: the assembler (labels bound), the handlers' labels, the
/// key places and the address after the last key record.
pub(super) struct Glue {
    pub asm: CodeBuffer,
    pub labels: glue::CoreLabels,
    /// The turns of the core's sensor checks.
    pub turns: glue::Turns,
    /// The core's part of the watchdog's feed, as its glue runs it (core 0's with its
    /// feeding class).
    pub feed: Option<glue::Feed>,
    pub keys: Vec<KeyPlace>,
    pub data_end: u32,
    /// With the watchdog: where the reset handler finds which key hung; the data block
    /// ends with its table ([`data_block`]).
    pub hang: Option<glue::HangLookup>,
}

/// The glue of core `core` (reset handler, sample interrupt) for its control block at
/// bank offset `data_off`, core 0's reset handler booting as `boot` says.
///
/// Errors: those of [`key_records`] and [`glue::core_code`].
pub(super) fn assemble_glue(
    l: &Layout,
    core: usize,
    data_off: u32,
    cc: &CoreCode,
    boot: &Boot,
) -> Result<Glue, ImageError> {
    let ctrl_addr = bank_base(core) + data_off;
    let Records {
        code: kc,
        places: kp,
        data_end,
        table,
        mut turns,
    } = key_records(l, core, ctrl_addr, cc)?;
    let (bottom, top) = stack(core);
    // Which key hung, found at boot (`super::fault`, "Which key hung"): a call site per
    // key in each copy of the keys' code.
    let hang = |turns: &glue::Turns| {
        l.watchdog.then(|| glue::HangLookup {
            slot: super::fault::return_slot(top),
            table,
            entries: (kc.len() as u32) * turns.classes.max(1),
        })
    };
    let start = |a: &mut CodeBuffer| boot::core_start(a, core, boot, bottom, STACK_CANARY);
    // Core 0 feeds the watchdog in one class of its samples ([`glue::Feed::class`]).
    let feed = l.feed(data_off).map(|f| glue::Feed {
        class: if core == 0 {
            turns.feed_class(l.fs)
        } else {
            None
        },
        ..f
    });
    let emit = |turns: &glue::Turns| -> Result<_, ImageError> {
        let mut a = CodeBuffer::new(LongBranch::Hop);
        let labels = glue::core_code(
            &mut a,
            core,
            &kc,
            ctrl_addr,
            l.tick,
            &l.consts,
            &start,
            l.io.as_ref(),
            feed,
            hang(turns),
            turns,
        )?;
        Ok((a, labels))
    };
    let (mut a, mut labels) = emit(&turns)?;
    if turns.classes > 2 && a.finish_code(cc.start + cc.glue).is_err() {
        // The copies too long for the dispatch's branches: through hops.
        turns.hops = true;
        (a, labels) = emit(&turns)?;
    }
    if a.finish_code(cc.start + cc.glue).is_err() {
        // The trip paths too far from their keys' checks: each after its key's code.
        turns.near_trips = true;
        (a, labels) = emit(&turns)?;
    }
    Ok(Glue {
        asm: a,
        labels,
        feed,
        hang: hang(&turns),
        turns,
        keys: kp,
        data_end,
    })
}

/// Moves each core's block to its final place and returns the data's bank offset.
///
/// Core 0's block starts after the entry stub's [`boot::ENTRY_RESERVE`]; core 1's block
/// follows core 0's in bank offsets (the emulator's decode cache is indexed by the low
/// address bits, so the two cores' code would otherwise evict each other's); the data
/// start is the same bank offset in every bank, past both blocks. The glue's size is
/// measured at provisional addresses: literal values do not change instruction sizes, but
/// pool sharing may, so each block keeps 64 bytes of slack.
///
/// Errors: those of [`assemble_glue`], [`ImageError::Assemble`].
pub(super) fn place_code_blocks(
    l: &Layout,
    cc: &mut [CoreCode],
    clock_hz: u64,
    core_mv: Option<u32>,
) -> Result<u32, ImageError> {
    // Provisional launch words: large and distinct, as the final ones (same sizes).
    let provisional = Boot {
        io: l.io.is_some(),
        ..Boot::new(
            clock_hz,
            core_mv,
            (cc.len() == 2).then_some([0x2101_0100, 0x2004_2000, 0x2101_0201]),
        )
    };
    let mut block_off = boot::ENTRY_RESERVE;
    for (core, c) in cc.iter_mut().enumerate() {
        let g = assemble_glue(l, core, BANK_LIMIT / 2, c, &provisional)?;
        let bytes = g.asm.finish_code(c.start + c.glue)?.text;
        c.start += block_off;
        block_off += (c.glue + bytes.len() as u32 + 64).next_multiple_of(256);
    }
    Ok(block_off)
}

/// Core `core`'s data: its control block (start alarm, tick accumulator, counters; the
/// data's start), its keys'
/// records from there and their state structs from `data_end` (zeroed; each record's
/// budgets full and its state address set). Returns the bytes and the address after the
/// last state.
///
/// Errors: [`ImageError::NoRoom`] when the data passes [`BANK_LIMIT`].
pub(super) fn data_block(
    l: &Layout,
    core: usize,
    kp: &[KeyPlace],
    data_end: u32,
    start_us: u32,
    tick: &Tick,
    hang: Option<(&glue::HangLookup, &[u8])>,
) -> Result<Vec<u8>, ImageError> {
    let bank = bank_base(core);
    let mut at = data_end.next_multiple_of(4);
    let mut data = Vec::new();
    let word = |v: u32| v.to_le_bytes();
    data.extend(word(start_us)); // START
    data.extend(word(tick.rem)); // ACC: period 1's (period 0's step never carries)
    data.extend(word(0)); // SAMPLES
    data.extend(word(0)); // MISSES
    data.extend(word(0)); // READY
    data.extend(word(0)); // FAULT (the reset handler copies it from the watchdog's scratch)
    data.extend(word(0)); // FAULT_AT
    data.extend(word(0)); // RESET_CAUSE (the reset handler writes it at each boot)
    debug_assert_eq!(data.len(), ctrl::SIZE as usize);
    let mut states = Vec::new();
    for k in kp {
        let p = &l.programs[k.spec.program];
        // The quiescent guard's shadow copy directly below the state struct (zeros: the
        // guard's counter needs more than the first update, see `Program::guard`).
        let shadow = p.guard(0).map_or(0, |g| g.shadow_bytes());
        let state = at + shadow;
        at = (state + p.thumb.state.size as u32).next_multiple_of(4);
        states.push((
            shadow as usize,
            p.thumb.state.size,
            p.thumb.state.params,
            &p.params,
        ));
        let words = record_words(
            k.sensors as u32,
            k.out_len as u32,
            k.drives.len() as u32,
            has_rest_image(p),
        );
        let mut r = vec![0u8; 4 * words as usize];
        let put = |r: &mut Vec<u8>, off: u32, v: u32| {
            r[off as usize..off as usize + 4].copy_from_slice(&v.to_le_bytes())
        };
        for &(_, budget) in &k.drives {
            put(&mut r, budget, l.consts.budget_max as u32);
        }
        // The sensor check's words at power-on ([`glue::SensorCheck::seed`]), at the
        // offsets `key_records` gives them.
        if let Some(c) = &k.check {
            for (off, v) in c.seed() {
                put(&mut r, off, v);
            }
        }
        put(&mut r, k.state_offset, state);
        data.extend(r);
    }
    // Shadows and states are zero (init sets the states) but for the key's param block,
    // which init leaves alone.
    for (shadow, size, params_at, params) in &states {
        let mut st = vec![0u8; (shadow + size).next_multiple_of(4)];
        for (k, w) in params.iter().enumerate() {
            let at = shadow + params_at + 4 * k;
            if let Some(b) = st.get_mut(at..at + 4) {
                b.copy_from_slice(&w.to_le_bytes());
            }
        }
        data.extend(st);
    }
    // The rest images ([`key_records`]): zeros, which the reset handler overwrites.
    for k in kp {
        let p = &l.programs[k.spec.program];
        if has_rest_image(p) {
            let words = (p.thumb.state.size as u32).div_ceil(4);
            data.extend(vec![0u8; 4 * words as usize]);
            at += 4 * words;
        }
    }
    // The table of call sites (`super::fault`, "Which key hung"), where the glue reads it.
    if let Some((h, table)) = hang {
        if at != h.table || table.len() as u32 != 8 * h.entries {
            return Err(ImageError::Assemble(format!(
                "core {core}: the table of call sites at {at:#x} with {} bytes, where the \
                 reset handler reads it at {:#x} with {} entries",
                table.len(),
                h.table,
                h.entries
            )));
        }
        data.extend_from_slice(table);
        at += table.len() as u32;
    }
    let need = at - bank;
    if need > BANK_LIMIT {
        return Err(ImageError::NoRoom {
            core,
            need,
            have: BANK_LIMIT,
        });
    }
    Ok(data)
}

/// Core `core`'s stack: (bottom, top) in its scratch bank (SRAM4 for core 0, SRAM5 for
/// core 1, whose top leaves [`super::fault::CORE1_STACK_RESERVE`] for boot2 and the boot
/// ROM's frames on a boot from flash, so that its return slot outlives them).
pub(super) fn stack(core: usize) -> (u32, u32) {
    match core {
        0 => (SRAM4_BASE, SRAM4_BASE + STACK_BYTES),
        _ => (
            SRAM5_BASE,
            SRAM5_BASE + STACK_BYTES - super::fault::CORE1_STACK_RESERVE,
        ),
    }
}

/// The bytes of core `core`'s code block `cc`: its vector table (initial SP, reset
/// handler, the HardFault handler — exception 3 —, the sample interrupt at SysTick —
/// exception 15 —, the start handler at TIMER_IRQ_0 — exception 16 — and the default
/// handler everywhere else), its program copies and its glue. `addr` gives each glue
/// label's address.
pub(super) fn vector_table(
    core: usize,
    cc: &CoreCode,
    programs: &[Program],
    labels: &glue::CoreLabels,
    addr: &[u32],
    glue_bytes: &[u8],
) -> Vec<u8> {
    let lab = |l: Label| addr[l.index()];
    let mut vt = vec![lab(labels.default) | 1; 48];
    vt[0] = stack(core).1;
    vt[1] = lab(labels.reset) | 1;
    vt[3] = lab(labels.hard_fault) | 1;
    vt[15] = lab(labels.isr) | 1;
    vt[16] = lab(labels.start) | 1;
    let mut code = Vec::new();
    for w in &vt {
        code.extend(w.to_le_bytes());
    }
    for &(p, text) in &cc.texts {
        code.resize(text as usize, 0);
        code.extend(&programs[p].thumb.code.text);
    }
    code.resize(cc.glue as usize, 0);
    code.extend(glue_bytes);
    code
}

/// The static WCET of core `core`'s sample interrupt over its whole code (`code` at
/// `base`): each key's update priced by its own analysis (long branches, flow facts: one
/// call's worst case; SysTick's and the ICSR's registers on the private peripheral bus,
/// no wait states). Returns the handler's analysed cycles
/// and, of those, the update calls' (each `BL` and the update).
///
/// Errors: [`ImageError::Wcet`].
pub(super) fn analyse_handler(
    core: usize,
    base: u32,
    code: &[u8],
    labels: &glue::CoreLabels,
    addr: &[u32],
    kp: &[KeyPlace],
    update_wcets: &[u64],
) -> Result<IsrWcet, ImageError> {
    let lab = |l: Label| addr[l.index()];
    let mut bounds = Bounds::new();
    for k in kp {
        bounds = bounds.with_call(k.update, update_wcets[k.spec.program]);
    }
    let image = wcet::Image { base, bytes: code };
    let w = wcet::analyse_isr(&image, lab(labels.isr), &bounds)
        .map_err(|e| ImageError::Wcet(format!("core {core}: {e}")))?;
    // Each key's update once: the handler's copies ([`glue::Turns`]) each call every key,
    // and its worst path runs one copy.
    let updates = kp
        .iter()
        .map(|k| crate::runner::BL_CYCLES + update_wcets[k.spec.program])
        .sum();
    Ok(IsrWcet {
        analysed: w.cycles,
        contention: 0,
        updates,
    })
    // (`FirmwareImage::build` adds the contention: the other core's window words, or the
    // DMA's accesses to the core's I/O bank.)
}

/// The place of core `core`'s pieces (its key list filled by the caller).
pub(super) fn core_place(
    core: usize,
    cc: &CoreCode,
    labels: &glue::CoreLabels,
    addr: &[u32],
    ctrl_addr: u32,
) -> CorePlace {
    let lab = |l: Label| addr[l.index()];
    let (stack_bottom, stack_top) = stack(core);
    CorePlace {
        vtor: cc.start,
        reset: lab(labels.reset),
        isr: lab(labels.isr),
        keys_spans: (labels.copies.iter())
            .map(|&(start, end)| (lab(start), lab(end)))
            .collect(),
        ctrl: ctrl_addr,
        stack_top,
        stack_bottom,
        keys: Vec::new(),
        code_copies: cc.texts.len(),
    }
}

/// The boot of an image whose blocks are placed (`cc` after [`place_code_blocks`]): the
/// board's PLL dividers and, with two cores, core 1's vector table, stack top and reset
/// handler (the first code of its glue, [`glue::core_code`]).
pub(super) fn boot_of(cc: &[CoreCode], clock_hz: u64, core_mv: Option<u32>, io: bool) -> Boot {
    let core1 = cc
        .get(1)
        .map(|c| [c.start, stack(1).1, (c.start + c.glue) | 1]);
    Boot {
        io,
        ..Boot::new(clock_hz, core_mv, core1)
    }
}
