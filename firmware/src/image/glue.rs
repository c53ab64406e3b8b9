//! The image's hand-written Thumb: the safety limiter, the sample interrupt handler and the
//! reset handler of one core, emitted through [`CodeBuffer`] (the compiler's code buffer).
//!
//! **Registers.** The per-key updates (compiled code) may clobber r0-r3 and r12, and
//! preserve r4-r11 but those their object declares ([`KeyCode::clobbers`]: under the
//! image's convention, `thumb::Convention::SAMPLE_ISR`, r5 and r8-r11). The handler keeps
//! its record pointer in r4, its control block in r5, the sensor and DAC window bases in r6
//! and r7; r5-r7 and the limiter's constants in r8-r11 ([`hi`]) hold for the whole run
//! where no update clobbers them: the reset handler sets them once, and the only code a
//! sample interrupt ever interrupts is the reset handler's idle loop (`WFI; B`), which
//! touches no register. So the handler saves nothing: it clobbers r0-r4 freely, loads r5
//! again once before its end where an update or the quiescent-key guard took it, restores
//! r6 where the guard borrowed it ([`guard_uses_r5`]), and returns with
//! `BX LR` after setting LR to EXC_RETURN `0xfffffff9` (Thread mode, main stack: the only
//! state it ever interrupts; DDI0419 B1.5.8). Without a push the stack stays as exception
//! entry aligned it, on 8 bytes (DDI0419 B1.5.7), for the AAPCS updates.
//!
//! **The limiter** is [`limiter_inline`]: `runtime/src/limiter.rs` on the 16-bit DAC code,
//! one `MULS`, no call; at the time of writing 20 cycles on its worst path.

use super::ImageError;
pub use crate::board_file::Tick;
use tactus_compiler::thumb::buffer::{CodeBuffer, Label};
use tactus_compiler::thumb::ins::{self as asm, cond};
use tactus_isa::decode::{AluOp, Hint, Instr};
use tactus_rp2040::timer::{reg, TIMER_BASE};
use tactus_runtime::limiter::{DacScale, LimiterConstants};

mod checks;
mod reset_cause;
mod stall;
mod tail;
use checks::{
    check_modes, check_step, clear_return_slot, copy_words, enable_watchdog, hard_fault_handler,
    record_watchdog_trip, restore_fault_record, trip_paths, CopyMode, PendingTrip,
};
pub use checks::{Feed, Gate, HangLookup, SensorCheck, Turns, MAX_GAP};
use tail::handler_tail;

/// Byte offsets in a core's control block (words in the core's own SRAM bank).
pub mod ctrl {
    /// Timer time (µs) of the start alarm, at which both cores start their SysTick.
    pub const START: u16 = 0;
    /// Remainder accumulator of the tick schedule ([`super::Tick`]: in `[0, den)`, the
    /// next period's; unused when the period is a whole number of cycles).
    pub const ACC: u16 = 4;
    /// Samples whose handler has completed.
    pub const SAMPLES: u16 = 8;
    /// Deadline misses: handlers that finished after the next tick.
    pub const MISSES: u16 = 12;
    /// 1 once the reset handler has initialised every key and prepared the tick.
    pub const READY: u16 = 16;
    /// The core's fault word: kind, key, trips (`super::super::fault`, "The fault word").
    pub const FAULT: u16 = 20;
    /// The core's sample count at its last trip (`super::super::fault`).
    pub const FAULT_AT: u16 = 24;
    /// The reset word: why the board last booted, WATCHDOG.REASON | CHIP_RESET as the
    /// reset handler read them (`super::super::fault`, "The reset word").
    pub const RESET_CAUSE: u16 = 28;
    /// Size of the block; the key records follow it.
    pub const SIZE: u32 = 32;

    /// The address of a core's fault record (the fault word at [`FAULT`], then the fault
    /// time) in an image whose control block is at `control`: the rule `keys.json`'s
    /// `cores[c].fault` is written and checked by, and the host reads by.
    pub fn fault_record(control: u32) -> u32 {
        control.wrapping_add(u32::from(FAULT))
    }
}

/// SysTick's registers (DDI0419 B3.3.2) and the ICSR (B3.2.4), each core's own.
pub mod syst {
    /// SYST_CSR: ENABLE (bit 0), TICKINT (1), CLKSOURCE (2); COUNTFLAG (16).
    pub const CSR: u32 = 0xe000_e010;
    /// SYST_RVR: the reload value, 24 bits.
    pub const RVR: u32 = 0xe000_e014;
    /// SYST_CVR: the current value; any write clears it.
    pub const CVR: u32 = 0xe000_e018;
    /// ENABLE | TICKINT | CLKSOURCE = 1 (the processor clock).
    pub const ON: u8 = 7;
    /// ICSR; PENDSTSET is bit 26.
    pub const ICSR: u32 = 0xe000_ed04;
    /// Bit of PENDSTSET in ICSR.
    pub const PENDSTSET_BIT: u8 = 26;
}

/// The high registers that hold the limiter's constants for the whole run: the full budget,
/// and the scale of the core's most used force format ([`super::Scale::InRegisters`]).
pub mod hi {
    /// The largest shifted force magnitude whose code is at most the rated code
    /// (`DacScale::last_magnitude_within(rated_code)`).
    pub const RATED_MAG: u8 = 8;
    /// The largest shifted force magnitude whose code is at most the peak code.
    pub const PEAK_MAG: u8 = 9;
    /// The full time budget (`LimiterConstants::budget_max`).
    pub const BUDGET_MAX: u8 = 10;
    /// The gain of the scale (`DacScale::gain`).
    pub const GAIN: u8 = 11;
}

/// EXC_RETURN for a return to Thread mode on the main stack (DDI0419 B1.5.8): `MVNS` of 6.
const EXC_RETURN_NOT: u8 = 6;

/// NVIC_ISER (DDI0419 B3.4.3).
const NVIC_ISER: u32 = 0xe000_e100;
/// NVIC_ICER (DDI0419 B3.4.4).
const NVIC_ICER: u32 = 0xe000_e180;

/// `rd += n` for any `n` (ADDS #imm8 steps).
fn add_big(a: &mut CodeBuffer, rd: u8, mut n: u32) {
    while n > 0 {
        let step = n.min(255);
        a.i(asm::adds_imm(rd, rd, step as u8));
        n -= step;
    }
}

/// `MOV rd, rm` with high registers (no flags).
fn mov_hi(rd: u8, rm: u8) -> Instr {
    Instr::MovHi { rd, rm }
}

/// `rt = [r4 + off]`: one `LDR` within its immediate's reach, else through `rt` as index.
fn ldr_rec(a: &mut CodeBuffer, rt: u8, off: u32) {
    if off <= 124 && off.is_multiple_of(4) {
        a.i(asm::ldr(rt, 4, off as u16));
    } else {
        a.mov_const(rt, off);
        a.i(asm::ldr_reg(rt, 4, rt));
    }
}

/// Where [`limiter_inline`] finds the constants of its force format's scale (the gain and
/// the two magnitude thresholds) and the full budget.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scale {
    /// In [`hi`] (`CMP`/`MOV` with a high register, 1 cycle each).
    InRegisters,
    /// The scale's from the literal pool (`LDR`, 2 cycles each), the full budget in
    /// [`hi::BUDGET_MAX`]: a key whose force format is not the one the core keeps in the
    /// registers.
    Literal,
    /// Every constant from the literal pool (or an immediate, where it fits 8 bits): the
    /// registers in [`hi`] hold nothing, an update having clobbered them (a program
    /// compiled under `Convention::SAMPLE_ISR`, [`KeyCode::clobbers`]).
    Clobbered,
}

/// Checks that the Thumb limiter can use `c`; errors say which constant does not fit.
fn check_constants(c: &LimiterConstants) -> Result<(), ImageError> {
    if !(1..=255).contains(&c.recovery) {
        return Err(ImageError::Limiter(format!(
            "recovery {} is not 1 to 255 (a CMP immediate)",
            c.recovery
        )));
    }
    if c.rated_code < 1 || c.peak_code < c.rated_code || c.budget_max < c.recovery {
        return Err(ImageError::Limiter(
            "need 1 ≤ rated code ≤ peak code and a budget of at least one sample".into(),
        ));
    }
    Ok(())
}

/// The limiter of one force word, inline: `r0` = the force word in, the DAC code out
/// (sign-extended); the budget word at `[r<base> + budget_off]` updated. Exactly
/// `Limiter::step` (runtime/src/limiter.rs) with scale `s`. Needs [`hi`] set (for `s` when
/// `scale` is [`Scale::InRegisters`]; not at all with [`Scale::Clobbered`]); clobbers
/// r1-r3; `base` must be r4-r7 and `budget_off` ≤ 124. Places the literal pool open so far
/// (behind a branch, free).
///
/// It decides on the shifted magnitude `m = |F| >> a` before multiplying: `m` above
/// [`hi::RATED_MAG`] ⇔ a saturated force or a code above rated, `m` above [`hi::PEAK_MAG`]
/// ⇔ saturated or above the peak (`DacScale::last_magnitude_within`), so no saturation
/// test is needed and only a kept magnitude (≤ 32767) is multiplied. Four paths, each a
/// case of `Limiter::step`:
///
/// - at or below rated: earn one unit up to the full budget; the code asked;
/// - above rated, budget spent (`budget − recovery < 0`): earn one; the rated code;
/// - above rated with budget, at or below the peak: spend; the code asked;
/// - above the peak with budget: spend; the peak code.
///
/// Worst path 20 cycles (with both shifts) with its constants in registers, 25 with
/// [`Scale::Clobbered`] (three of them on each path, each a literal load more): 6 for the
/// magnitude and the budget's load, 4 for the sign and the budget's store, the rest the
/// decisions and the product.
pub fn limiter_inline(
    a: &mut CodeBuffer,
    c: &LimiterConstants,
    s: &DacScale,
    scale: Scale,
    base: u8,
    budget_off: u16,
) -> Result<(), ImageError> {
    let lost = match scale {
        Scale::Clobbered => HI_REGISTERS,
        _ => 0,
    };
    limiter_with(a, c, s, scale, lost, base, budget_off, None, &mut |_| {})
}

/// Bits of [`hi`]'s registers in a register mask.
const HI_REGISTERS: u16 = 0xf << 8;

/// [`limiter_inline`] where the registers of [`hi`] in `lost` (bit *n* = r*n*) hold
/// nothing: their constants come from the literal pool, or an immediate where one fits
/// (`CMP #imm8`, `MOVS #imm8`: 1 cycle, as the register). `aside` emits code that no
/// path of the limiter falls into (a sensor check's trip path, [`SensorCheck`]): it is
/// placed behind the limiter's last unconditional branch, before its literal pool. With
/// `gate` (byte offsets from r`base` of a rated-magnitude threshold word and a gain word,
/// [`SensorCheck::gate`]) the limiter reads those two constants from there (`LDR`, as a
/// literal's) instead of a register or the pool.
#[allow(clippy::too_many_arguments)]
fn limiter_with(
    a: &mut CodeBuffer,
    c: &LimiterConstants,
    s: &DacScale,
    scale: Scale,
    lost: u16,
    base: u8,
    budget_off: u16,
    gate: Option<(u16, u16)>,
    aside: &mut dyn FnMut(&mut CodeBuffer),
) -> Result<(), ImageError> {
    use AluOp::*;
    check_constants(c)?;
    if !(4..=7).contains(&base) || budget_off > 124 || !budget_off.is_multiple_of(4) {
        return Err(ImageError::Limiter(format!(
            "budget word at r{base} + {budget_off}: needs r4-r7 and an offset ≤ 124"
        )));
    }
    if s.pre_shift > 31 || s.post_shift > 31 || !(1..=65535).contains(&s.gain) {
        return Err(ImageError::Limiter(format!("scale {s:?} out of range")));
    }
    let in_reg = |reg: u8, of_scale: bool| {
        lost & 1 << reg == 0 && (!of_scale || scale == Scale::InRegisters)
    };
    let rec = c.recovery as u8;
    let (earn, spent, mul, apply) = (a.label(), a.label(), a.label(), a.label());
    // Compares r`rn` with a constant: its register, an immediate, or a literal through r3.
    let cmp_const = |a: &mut CodeBuffer, rn: u8, reg: u8, of_scale: bool, v: u32| {
        if in_reg(reg, of_scale) {
            a.i(Instr::CmpHi { rn, rm: reg });
        } else if v <= 255 {
            a.i(asm::cmp_imm(rn, v as u8));
        } else {
            a.ldr_const(3, v);
            a.i(asm::cmp(rn, 3));
        }
    };
    // r2 = sign mask, r0 = |force| >> a (i32::MIN is 2^31 as an unsigned magnitude),
    // r1 = the budget.
    a.i(asm::asrs(2, 0, 31));
    a.i(asm::alu(Eor, 0, 2));
    a.i(asm::subs(0, 0, 2));
    if s.pre_shift > 0 {
        a.i(asm::lsrs(0, 0, s.pre_shift as u8));
    }
    a.i(asm::ldr(1, base, budget_off));
    match gate {
        Some((rated, _)) => {
            a.i(asm::ldr(3, base, rated));
            a.i(asm::cmp(0, 3));
        }
        None => cmp_const(
            a,
            0,
            hi::RATED_MAG,
            true,
            s.last_magnitude_within(c.rated_code),
        ),
    }
    a.bc(cond::LS, earn);
    // Above rated (or saturated): spend, if the budget allows.
    a.i(asm::subs_imm(1, 1, rec));
    a.bc(cond::MI, spent);
    cmp_const(
        a,
        0,
        hi::PEAK_MAG,
        true,
        s.last_magnitude_within(c.peak_code),
    );
    a.bc(cond::LS, mul);
    a.ldr_const(0, c.peak_code as u32);
    a.b(apply);
    // Budget spent: back to the old budget plus one; the rated code.
    a.bind(spent);
    match rec.checked_add(1) {
        Some(back) => a.i(asm::adds_imm(1, 1, back)),
        None => {
            a.i(asm::adds_imm(1, 1, rec));
            a.i(asm::adds_imm(1, 1, 1));
        }
    }
    a.ldr_const(0, c.rated_code as u32);
    a.b(apply);
    aside(a);
    a.pool();
    // At or below rated: earn one unit, up to the full budget (never above it).
    a.bind(earn);
    cmp_const(a, 1, hi::BUDGET_MAX, false, c.budget_max as u32);
    a.bc(cond::GE, mul);
    a.i(asm::adds_imm(1, 1, 1));
    // The code asked: m ≤ 32767, so the product fits.
    a.bind(mul);
    if let Some((_, gain)) = gate {
        a.i(asm::ldr(3, base, gain));
    } else if in_reg(hi::GAIN, true) {
        a.i(mov_hi(3, hi::GAIN));
    } else {
        a.mov_const(3, s.gain);
    }
    a.i(asm::alu(Mul, 0, 3));
    if s.post_shift > 0 {
        a.i(asm::lsrs(0, 0, s.post_shift as u8));
    }
    a.bind(apply);
    // The sign back.
    a.i(asm::alu(Eor, 0, 2));
    a.i(asm::subs(0, 0, 2));
    a.i(asm::str(1, base, budget_off));
    Ok(())
}

/// Sets [`hi`] for `c` and the scale `s` (clobbers r0).
pub fn set_limiter_registers(a: &mut CodeBuffer, c: &LimiterConstants, s: &DacScale) {
    for (reg, v) in [
        (hi::RATED_MAG, s.last_magnitude_within(c.rated_code)),
        (hi::PEAK_MAG, s.last_magnitude_within(c.peak_code)),
        (hi::BUDGET_MAX, c.budget_max as u32),
        (hi::GAIN, s.gain),
    ] {
        a.mov_const(0, v);
        a.i(mov_hi(reg, 0));
    }
}

/// The limiter as a function, for tests: `r0` = force word, `r1` = address of the budget
/// word; returns the DAC code in `r0` (sign-extended). Preserves r4-r11 (AAPCS). With
/// [`Scale::Literal`] the registers hold another scale's constants, which the code must
/// not use.
pub fn limiter_function(
    a: &mut CodeBuffer,
    entry: Label,
    c: &LimiterConstants,
    s: &DacScale,
    scale: Scale,
) -> Result<(), ImageError> {
    a.bind(entry);
    a.i(asm::push_lr(0xf0));
    for r in 8..12 {
        a.i(mov_hi(r - 4, r));
    }
    a.i(Instr::Push { list: 0xf0 });
    a.i(asm::mov(4, 1));
    a.i(asm::mov(5, 0));
    let other = DacScale {
        pre_shift: 0,
        gain: 1,
        post_shift: 0,
    };
    let kept = match scale {
        Scale::InRegisters => s,
        Scale::Literal | Scale::Clobbered => &other,
    };
    set_limiter_registers(a, c, kept);
    if scale == Scale::Clobbered {
        // Nothing the limiter may use: r10 (the full budget) off by one.
        a.mov_const(0, c.budget_max as u32 + 1);
        a.i(mov_hi(hi::BUDGET_MAX, 0));
    }
    a.i(asm::mov(0, 5));
    limiter_inline(a, c, s, scale, 4, 0)?;
    a.i(Instr::Pop { list: 0xf0 });
    for r in 8..12 {
        a.i(mov_hi(r, r - 4));
    }
    a.i(asm::pop_pc(0xf0));
    a.pool();
    Ok(())
}

/// One key of a core, as the handler sees it.
///
/// Its record (at r4 while the handler serves it) holds the update's `sensors` words first
/// (copied from the sensor window), then, in whichever order keeps the handler's offsets
/// within an `LDR` immediate ([`super::KeyPlace`]), the update's `out` words, one limiter
/// budget word per drive and the address of its state struct.
pub struct KeyCode {
    /// Addresses of the sensor window words the handler copies, in order, to the record's
    /// first words.
    pub sensor_words: Vec<u32>,
    /// On a board with converters whose ADC does not push the sensor words themselves
    /// ([`super::io::CoreIo::direct`]): per sensor word, in order, the ADC channel it is
    /// read from and the scale that makes it of the code (then `sensor_words` is not
    /// read); empty otherwise (with converters, `sensor_words` are then the words in
    /// results buffer A, read relative to `r6`).
    pub sensor_channels: Vec<(u32, tactus_runtime::converters::AdcScale)>,
    /// Byte offset of the update's `out` words in the record.
    pub out_offset: u32,
    /// Byte offset of the state struct's address in the record (≤ 124).
    pub state_offset: u32,
    /// The force words the key drives, each through the limiter to its DAC window word.
    pub drives: Vec<DriveCode>,
    /// Record size in bytes.
    pub record_size: u32,
    /// Address of the key's program's update (this core's copy).
    pub update: u32,
    /// Address of the key's program's init (this core's copy).
    pub init: u32,
    /// The quiescent-key guard around the update, if the program has one.
    pub guard: Option<GuardCode>,
    /// Registers the key's update (and init) may leave modified beyond r0–r3, r12 and LR
    /// (`ThumbObject::clobbers`: r5 and r8–r11 at most, `Convention::SAMPLE_ISR`): the
    /// handler reloads r5 before its end, and on a core where any key clobbers one of
    /// [`hi`], every limiter takes that constant from the literal pool.
    pub clobbers: u16,
    /// The plausibility check of its first sensor word, if it has sensors.
    pub check: Option<SensorCheck>,
}

/// Registers an update may clobber in the image: r5 and [`hi`]'s (r4, r6, r7 the handler
/// keeps across the calls).
pub const CLOBBERABLE: u16 = 1 << 5 | HI_REGISTERS;

/// The quiescent-key guard of one key (docs/language.md, "Quiescent keys").
///
/// The update is a deterministic function of its state struct and its sensor words. The
/// guard keeps, in the key's record, a *calm* counter: the number of consecutive updates,
/// most recent last, that ran with the sensor words they have now and left the compared
/// state words (states, modes, edges: bytes `[0, 4·words)` of the struct) as they found
/// them, as a shadow copy of those words shows. With the counter at least `calm_needed`
/// and the sensor words unchanged, the next update would compute exactly what the last
/// did, so the handler skips the `BL` and the limiter runs on the kept out words. The
/// history rings are not compared: `calm_needed` = 2·WINDOW + 1 updates with one sensor
/// value fill a ring with it, and a ring of equal words reads the same whatever its
/// position. Static cost: [`guard_check`]'s and [`guard_record`]'s instructions on every
/// path that runs the update, so the static WCET counts the full update plus the guard.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GuardCode {
    /// Byte offset of the calm counter in the record (≤ 124).
    pub calm_offset: u32,
    /// Calm updates after which the update is skipped (1 to 255).
    pub calm_needed: u8,
    /// Byte offsets in the state struct of the words compared (the words holding the
    /// program's states that the update writes — a state it never writes keeps its
    /// initial word — its modes and its edges), ascending.
    pub words: Vec<u32>,
}

impl GuardCode {
    /// Bytes of the shadow copy, placed directly below the state struct: word `j` shadows
    /// `words[j]`.
    pub fn shadow_bytes(&self) -> u32 {
        4 * self.words.len() as u32
    }
}

/// The guard's test before the update: `r3` holds the OR of the XORs of each new sensor
/// word with its record copy (0: unchanged). Resets the calm counter when the sensors
/// moved; branches to `skip` when the key is quiescent. Clobbers r1.
/// Static cost: 7 cycles on the path that runs the update (6 when the sensors moved).
pub fn guard_check(a: &mut CodeBuffer, g: &GuardCode, skip: Label) {
    let (moved, run) = (a.label(), a.label());
    a.i(asm::cmp_imm(3, 0));
    a.bc(cond::NE, moved);
    a.i(asm::ldr(1, 4, g.calm_offset as u16));
    a.i(asm::cmp_imm(1, g.calm_needed));
    a.bc(cond::LT, run);
    // `skip` lies beyond the update's call and the comparison: out of a `B<cc>`'s reach.
    a.b(skip);
    a.bind(moved);
    a.i(asm::movs(1, 0));
    a.i(asm::str(1, 4, g.calm_offset as u16));
    a.bind(run);
}

/// The compared words of a guard in chunks of at most `k` words that are consecutive in
/// the state struct: (byte offset in the struct, words).
fn guard_chunks(words: &[u32], k: usize) -> Vec<(u32, usize)> {
    let mut chunks: Vec<(u32, usize)> = Vec::new();
    for &o in words {
        match chunks.last_mut() {
            Some((at, n)) if *n < k && *at + 4 * *n as u32 == o => *n += 1,
            _ => chunks.push((o, 1)),
        }
    }
    chunks
}

/// A register list of LDM/STM.
fn reg_list(regs: &[u8]) -> u8 {
    regs.iter().fold(0, |m, &r| m | 1 << r)
}

/// Whether [`guard_record`] of `g` uses r5 and r6 (it then restores r6 itself, and the
/// handler reloads r5 before its epilogue).
pub fn guard_uses_r5(g: &GuardCode) -> bool {
    g.words.len() >= 3
}

/// The guard's bookkeeping after the update: compares the state words with the shadow
/// copy below the struct, then counts a calm update or — at the first word that differs —
/// refreshes the shadow from there on and resets the counter.
///
/// The words go in chunks of up to two consecutive words: `LDM` of the state chunk
/// (pointer r0), `LDM` of its shadow (r1), a `CMP`/`BNE` per word; nothing is stored while
/// the words agree (the shadow already holds them). A difference branches to the chunk's
/// fix-up, which stores the chunk over its shadow (`STM`) and copies the remaining chunks
/// (`LDM`/`STM`), so the shadow always ends equal to the state. With three words or more
/// the chunks are pairs in r2-r3 against r5-r6 (r6 is set again by `restore_r6` when given;
/// r5 by the handler, [`guard_uses_r5`]); else single words in r2 against r3.
/// Clobbers r0-r3.
///
/// Static cost (piano, 8 words in 4 pairs): 10 cycles per pair plus about 12 (see
/// docs/benchmarks-log.md, "Session 13 (glue16)"); 5 cycles without state words.
pub fn guard_record(
    a: &mut CodeBuffer,
    g: &GuardCode,
    state_offset: u32,
    restore_r6: Option<&dyn Fn(&mut CodeBuffer)>,
) {
    let calm = g.calm_offset as u16;
    if g.words.is_empty() {
        // Nothing but the history rings persists: every update with unchanged sensors is
        // calm.
        a.i(asm::ldr(1, 4, calm));
        a.i(asm::adds_imm(1, 1, 1));
        a.i(asm::str(1, 4, calm));
        return;
    }
    let pairs = guard_uses_r5(g);
    let (a_regs, c_regs): (&[u8], &[u8]) = if pairs {
        (&[2, 3], &[5, 6])
    } else {
        (&[2], &[3])
    };
    let chunks = guard_chunks(&g.words, a_regs.len());
    // r0 = the state, r1 = the shadow (below the state, one word per compared word).
    ldr_rec(a, 0, state_offset);
    a.i(asm::mov(1, 0));
    let back = g.shadow_bytes();
    if back <= 255 {
        a.i(asm::subs_imm(1, 1, back as u8));
    } else {
        a.mov_const(2, back);
        a.i(asm::subs(1, 1, 2));
    }
    // The state pointer's offset in the struct before each chunk (gaps between runs are
    // stepped over with ADDS).
    let step_to = |a: &mut CodeBuffer, at: &mut u32, o: u32| {
        if o > *at {
            add_big(a, 0, o - *at);
        }
        *at = o;
    };
    let fixes: Vec<Label> = chunks.iter().map(|_| a.label()).collect();
    let copies: Vec<Label> = chunks.iter().map(|_| a.label()).collect();
    let (tail, join) = (a.label(), a.label());
    let mut at = 0u32;
    for (&(o, n), &fix) in chunks.iter().zip(&fixes) {
        step_to(a, &mut at, o);
        a.i(Instr::Ldm {
            rn: 0,
            list: reg_list(&a_regs[..n]),
        });
        a.i(Instr::Ldm {
            rn: 1,
            list: reg_list(&c_regs[..n]),
        });
        at += 4 * n as u32;
        for j in 0..n {
            a.i(asm::cmp(a_regs[j], c_regs[j]));
            a.bc(cond::NE, fix);
        }
    }
    // Every word as it was: one more calm update.
    a.i(asm::ldr(2, 4, calm));
    a.i(asm::adds_imm(2, 2, 1));
    a.i(asm::str(2, 4, calm));
    a.b(join);
    // Fix-ups: the differing chunk is in registers; store it over its shadow, then copy the
    // rest. The last chunk's fix-up falls into the counter's reset.
    let last = chunks.len() - 1;
    let store_chunk = |a: &mut CodeBuffer, n: usize| {
        a.i(asm::subs_imm(1, 1, 4 * n as u8));
        a.i(Instr::Stm {
            rn: 1,
            list: reg_list(&a_regs[..n]),
        });
    };
    for (i, &(_, n)) in chunks.iter().enumerate().take(last) {
        a.bind(fixes[i]);
        store_chunk(a, n);
        a.b(copies[i + 1]);
    }
    if last > 0 {
        // The copy chain: chunk i from `copies[i]`, the pointers just past chunk i - 1.
        let mut at = chunks[0].0 + 4 * chunks[0].1 as u32;
        for (i, &(o, n)) in chunks.iter().enumerate().skip(1) {
            // Entered from chunk i - 1's fix-up or copy, r0 just past that chunk.
            a.bind(copies[i]);
            if o > at {
                add_big(a, 0, o - at);
            }
            at = o + 4 * n as u32;
            a.i(Instr::Ldm {
                rn: 0,
                list: reg_list(&a_regs[..n]),
            });
            a.i(Instr::Stm {
                rn: 1,
                list: reg_list(&a_regs[..n]),
            });
        }
        a.b(tail);
    }
    a.bind(fixes[last]);
    store_chunk(a, chunks[last].1);
    a.bind(tail);
    a.i(asm::movs(2, 0));
    a.i(asm::str(2, 4, calm));
    a.bind(join);
    if let (true, Some(restore)) = (pairs, restore_r6) {
        restore(a);
    }
}

/// One force word of a key on its way to the DAC, as the handler sees it.
pub struct DriveCode {
    /// Byte offset of the force word in the record (`out[total]` for a keyboard key).
    pub force_offset: u32,
    /// Byte offset of the limiter's budget word in the record (≤ 124).
    pub budget_offset: u32,
    /// Address of its DAC window word.
    pub dac_word: u32,
    /// The force → DAC code scale of its force format.
    pub scale: DacScale,
    /// On a board with converters: the DAC channel whose frame it writes (then `dac_word`
    /// is not written).
    pub dac_channel: Option<u32>,
}

/// Labels of a core's code, bound by [`core_code`].
pub struct CoreLabels {
    /// The reset handler.
    pub reset: Label,
    /// The sample interrupt handler (SysTick, exception 15).
    pub isr: Label,
    /// The start handler (TIMER_IRQ_0 on both cores: starts the core's SysTick at the
    /// start alarm, then disables the interrupt).
    pub start: Label,
    /// The default handler (`B .`) of every other vector.
    pub default: Label,
    /// The HardFault handler (exception 3): with the watchdog (`feed`), the fault's record
    /// and a watchdog reset at once ([`checks::hard_fault_handler`]); without it the
    /// default handler's `B .`.
    pub hard_fault: Label,
    /// The sample interrupt's keys: from after the tick's step (the SYST_RVR store) and,
    /// with the sensor check's turns, the `LSLS` that sets the flags of the dispatch to the
    /// copies of the keys' code ([`Turns`]), to the ICSR load that checks for a miss.
    /// Everything between touches only the core's own SRAM. On core 0 with a feeding
    /// class ([`Feed::class`]) that class's copy ends at the ICSR load of its own tail
    /// instead, which is not [`CoreLabels::keys_end`]. What the emulator memoizes is each
    /// copy's run ([`CoreLabels::copies`]).
    pub keys: Label,
    /// See [`CoreLabels::keys`].
    pub keys_end: Label,
    /// Per copy of the keys' code ([`Turns`], in copy order; one without turns, at
    /// [`CoreLabels::keys`]): its first instruction, after the dispatch, and the ICSR load
    /// its run ends at ([`CoreLabels::keys_end`], or the feeding copy's own). The emulator
    /// memoizes each such run (`ImageRun`): a run of one copy repeats where a run of the
    /// whole keys part would not, since a key at rest cycles through its differentiator
    /// ring's 17 states while the copies take turns (68 states of the keys part, more than
    /// a memoized site keeps, each read with the dispatch's flags).
    pub copies: Vec<(Label, Label)>,
    /// Per key of the core, in the order given: its update's call sites (each `BL`), one
    /// in each copy of the keys' code ([`Turns`]), in copy order. What an injected hang
    /// of that key alone patches (`super::run`'s `FaultKind::Hang`).
    pub calls: Vec<Vec<Label>>,
}

/// The reset, start and sample-interrupt handlers of core `core` with `keys`, its control
/// block at `ctrl_addr`. `limiter` gives the constants kept in [`hi`]. `start` emits what
/// the reset handler does before its keys' `init`s (`super::boot::core_start`: the stack
/// canary; on core 0 the clocks and core 1's launch); the reset handler is the first code
/// emitted, so its address is where `a` is assembled.
///
/// **The tick.** Each core's sample tick is its own SysTick ([`Tick`]). To tick on the
/// same cycles, both cores start it at the same event: the reset handler of each prepares
/// it (RVR = `q − 1`, the counter cleared, not yet enabled), core 0 arms the timer's
/// ALARM0 for the control block's [`ctrl::START`], each core enables TIMER_IRQ_0 and
/// sleeps in `WFI`. The alarm wakes both cores on the same cycle; each enters its start
/// handler (identical code in its own bank, its stack in its own scratch bank: no shared
/// access before the enabling store), which enables its SysTick on the same cycle, then
/// disables TIMER_IRQ_0 in its own NVIC; core 0 also acknowledges the alarm. So both
/// SysTicks count the same periods from the same cycle: tick 0 is `q` cycles after the
/// enabling store, and the cores' ticks coincide ever after.
///
/// Errors: [`ImageError::Limiter`] (constants the Thumb limiter cannot use).
#[allow(clippy::too_many_arguments)]
pub fn core_code(
    a: &mut CodeBuffer,
    core: usize,
    keys: &[KeyCode],
    ctrl_addr: u32,
    tick: Tick,
    limiter: &LimiterConstants,
    start: &dyn Fn(&mut CodeBuffer),
    io: Option<&super::io::IoPlan>,
    feed: Option<Feed>,
    hang: Option<HangLookup>,
    turns: &Turns,
) -> Result<CoreLabels, ImageError> {
    let labels = CoreLabels {
        reset: a.label(),
        isr: a.label(),
        start: a.label(),
        default: a.label(),
        hard_fault: a.label(),
        keys: a.label(),
        keys_end: a.label(),
        copies: Vec::new(),
        calls: vec![Vec::new(); keys.len()],
    };
    let mut calls = vec![Vec::new(); keys.len()];
    // The watchdog's enabling and feed: core 0's alone (`feed` on core 1: its fault
    // record restored at reset).
    let fed = feed.filter(|_| core == 0);
    if let Some(k) = keys.iter().find(|k| k.clobbers & !CLOBBERABLE != 0) {
        return Err(ImageError::Compile(format!(
            "an update clobbers registers {:#06x}; the image's glue allows only {CLOBBERABLE:#06x}",
            k.clobbers
        )));
    }
    // The core's converters, when the board has them and its keys use them.
    let io = io.filter(|p| {
        p.cores
            .get(core)
            .is_some_and(|c| c.adc_channels() + c.dac_channels > 0)
    });
    let clobbered = keys.iter().fold(0, |m, k| m | k.clobbers);
    // The limiter's constants no update on this core touches stay in their registers.
    let lost = clobbered & HI_REGISTERS;
    // The scale kept in registers: the most used force format's.
    let mut scales: Vec<(DacScale, usize)> = Vec::new();
    for d in keys.iter().flat_map(|k| &k.drives) {
        match scales.iter_mut().find(|g| g.0 == d.scale) {
            Some(g) => g.1 += 1,
            None => scales.push((d.scale, 1)),
        }
    }
    let scale = scales.iter().max_by_key(|g| g.1).map_or(
        DacScale {
            pre_shift: 0,
            gain: 1,
            post_shift: 0,
        },
        |g| g.0,
    );
    // Window bases: the lowest word of each window the core's keys use, so that a board's
    // keys (consecutive slots) are reached by immediate offsets.
    let sensor_base = keys
        .iter()
        .flat_map(|k| k.sensor_words.iter().copied())
        .min()
        .unwrap_or(0);
    let dac_base = keys
        .iter()
        .flat_map(|k| k.drives.iter().map(|d| d.dac_word))
        .min()
        .unwrap_or(0);
    let walk = |a: &mut CodeBuffer,
                keys: &[KeyCode],
                f: &mut dyn FnMut(&mut CodeBuffer, &KeyCode) -> Result<(), ImageError>|
     -> Result<(), ImageError> {
        a.i(asm::mov(4, 5));
        add_big(a, 4, ctrl::SIZE);
        for (i, k) in keys.iter().enumerate() {
            f(a, k)?;
            if i + 1 < keys.len() {
                add_big(a, 4, k.record_size);
            }
        }
        Ok(())
    };

    // ---- reset: init every key, prepare the tick, set the limiter's registers, mark the
    // core ready, enable the start interrupt, sleep ----
    a.bind(labels.reset);
    if let Some(f) = fed {
        // Before core 1's launch: its pair is final when it copies it.
        record_watchdog_trip(a, 1 + usize::from(f.other_samples.is_some()));
    }
    start(a);
    a.ldr_const(5, ctrl_addr);
    reset_cause::record_reset_cause(a);
    if feed.is_some() {
        restore_fault_record(a, core, hang.as_ref());
    }
    walk(a, keys, &mut |a, k| {
        ldr_rec(a, 0, k.state_offset);
        a.bl_addr(k.init);
        if let Some(c) = k.check.as_ref().filter(|c| c.state_words > 0) {
            // The rest image of the sensor check's recovery ([`SensorCheck::rest`]).
            ldr_rec(a, 0, k.state_offset);
            a.ldr_const(1, c.rest);
            copy_words(a, 0, 1, c.state_words, CopyMode::Looped);
        }
        Ok(())
    })?;
    if let Some(h) = &hang {
        clear_return_slot(a, h);
    }
    if clobbered & 1 << 5 != 0 {
        a.ldr_const(5, ctrl_addr);
    }
    // SysTick: RVR = q − 1, the counter cleared (its reset value is UNKNOWN), off.
    a.ldr_const(0, syst::CSR);
    a.i(asm::movs(1, 0));
    a.i(asm::str(1, 0, 0));
    a.ldr_const(1, tick.q - 1);
    a.i(asm::str(1, 0, (syst::RVR - syst::CSR) as u16));
    a.i(asm::str(1, 0, (syst::CVR - syst::CSR) as u16));
    if core == 0 {
        // The start alarm: ALARM0 at START, its interrupt enabled (TIMER_IRQ_0 reaches
        // both cores' NVICs).
        a.ldr_const(0, TIMER_BASE);
        a.i(asm::movs(1, 1));
        a.i(asm::str(1, 0, reg::INTE as u16));
        a.i(asm::ldr(1, 5, ctrl::START));
        a.i(asm::str(1, 0, reg::ALARM0 as u16));
    }
    set_limiter_registers(a, limiter, &scale);
    if let Some(p) = io {
        // Its converters' drivers; r7 = its DAC frames (r6 is each sample's results).
        p.core_set_up(a, core);
    } else if !keys.is_empty() {
        a.ldr_const(6, sensor_base);
        a.ldr_const(7, dac_base);
    }
    a.i(asm::movs(1, 1));
    a.i(asm::str(1, 5, ctrl::READY));
    // From here on only the idle loop runs between interrupts: it uses no register.
    a.ldr_const(0, NVIC_ISER);
    a.i(asm::movs(1, 1));
    a.i(asm::str(1, 0, 0));
    a.i(Instr::Cps { disable: false });
    let idle = a.label();
    a.bind(idle);
    a.i(Instr::Hint(Hint::Wfi));
    a.b(idle);
    a.pool();
    a.bind(labels.default);
    if feed.is_none() {
        a.bind(labels.hard_fault);
    }
    a.b(labels.default);
    if feed.is_some() {
        // Off the sample path: no exception but a fault enters it.
        a.align4();
        a.bind(labels.hard_fault);
        hard_fault_handler(a, core, ctrl_addr);
    }

    // ---- the start handler: both cores at once, from the same alarm (see above) ----
    a.align4();
    a.bind(labels.start);
    a.ldr_const(0, syst::CSR);
    a.i(asm::movs(1, syst::ON));
    a.i(asm::str(1, 0, 0));
    a.ldr_const(0, NVIC_ICER);
    a.i(asm::movs(1, 1));
    a.i(asm::str(1, 0, 0));
    if core == 0 {
        a.ldr_const(0, TIMER_BASE);
        a.i(asm::str(1, 0, reg::INTR as u16));
    }
    if let Some(p) = io {
        // The first ADC burst, for the first sample.
        p.start_burst(a, core);
    }
    if let Some(f) = fed {
        enable_watchdog(a, &f);
    }
    a.i(Instr::Bx { rm: 14 });
    a.pool();

    // ---- the sample interrupt ----
    // The sensor checks' trip paths, branched to but not yet emitted.
    let mut trips: Vec<PendingTrip> = Vec::new();
    // The burst check's stall path, before the handler (within a `B<cond>`'s reach of the
    // check): the tick's step, the stall's record and the motors at zero, and the
    // handler's end (feeding the watchdog on core 0: the core is not hung).
    // With the sensor check (`Program::sensor_check`: a key's checks need its ADC's
    // bursts), not without it.
    let burst_check = keys.iter().any(|k| k.check.is_some());
    let stall = io
        .filter(|_| burst_check)
        .and_then(|p| Some((p.burst_mark(core)?, p.cores.get(core)?)))
        .map(|(_, c)| {
            stall::adc_stall_path(a, core, c.dac_channels, &tick, ctrl_addr, fed.as_ref())
        });
    a.align4();
    a.bind(labels.isr);
    if let Some(p) = io {
        // Converters: start this sample's bursts first (`super::io`); r6 = the results.
        let borrow_r6 = keys
            .iter()
            .any(|k| k.guard.as_ref().is_some_and(guard_uses_r5));
        p.handler_start(a, core, borrow_r6, stall.is_some());
    }
    if let Some(l) = stall {
        // The burst check: the mark still in this sample's results.
        a.i(asm::cmp(2, 7));
        a.bc(cond::EQ, l);
    }
    // The reload value of the period after this one (r2 = the accumulator after it).
    tick_step(a, &tick);
    // The copies of the keys' code ([`Turns`]): the class's bits of the accumulator into
    // N (bit `shift`) and C (bit `shift + 1`), read by the dispatch's branches (each
    // copy's run, which the emulator memoizes, starts after them).
    let copies = turns.classes.max(1);
    // The watchdog's feed (core 0): in the tail of its feeding class's copy alone
    // ([`Feed::class`]), or every sample in the one tail.
    let fed_copy = fed
        .and_then(|f| f.class)
        .map(u32::from)
        .filter(|&c| c < copies && copies > 1);
    let reload_r5 = clobbered & 1 << 5 != 0
        || keys
            .iter()
            .any(|k| k.guard.as_ref().is_some_and(guard_uses_r5));
    let tail = |a: &mut CodeBuffer, feeds: bool, keys_end: Option<Label>| {
        let f = fed.as_ref().filter(|_| feeds);
        handler_tail(a, ctrl_addr, reload_r5, f, keys_end);
    };
    if copies > 1 {
        a.i(asm::lsls(0, 2, 31 - turns.shift));
    }
    a.bind(labels.keys);
    let starts: Vec<Label> = (0..copies).map(|_| a.label()).collect();
    // Where each copy's run ends: the feeding copy's at the ICSR load of its own tail.
    let ends: Vec<Label> = (0..copies)
        .map(|c| match Some(c) == fed_copy {
            true => a.label(),
            false => labels.keys_end,
        })
        .collect();
    let tails: Vec<Label> = (0..copies).map(|_| a.label()).collect();
    let (upper, end) = (a.label(), a.label());
    // Trampolines: [to copy 1, to copy 2 (hop), to copy 3 (hop), to copy 3 (second hop)].
    let tramp: Vec<Label> = (0..4).map(|_| a.label()).collect();
    match copies {
        1 => {}
        2 => a.bc(cond::MI, tramp[0]),
        _ => {
            a.bc(cond::CS, upper);
            a.bc(cond::MI, tramp[0]);
        }
    }
    for copy in 0..copies {
        a.bind(starts[copy as usize]);
        let mut first_aside = copies > 1;
        // Every key: sensors → record, update, then each force word: limiter, DAC.
        walk(a, keys, &mut |a, k| {
            // This copy checks the key: on its turn, or every sample.
            let check = k
                .check
                .as_ref()
                .filter(|c| !k.drives.is_empty() && c.turn.is_none_or(|t| u32::from(t) == copy))
                .cloned();
            // Its limiters read the gate's words while it takes turns.
            let gates: Vec<(u16, u16)> =
                k.check
                    .as_ref()
                    .filter(|c| c.turn.is_some())
                    .map_or(Vec::new(), |c| {
                        c.gate
                            .iter()
                            .map(|g| (g.rated_offset as u16, g.gain_offset as u16))
                            .collect()
                    });
            // Without the guard the update reads its sensor words straight from the window
            // (they are consecutive words: the key's slots); the guard compares a copy.
            // With converters whose ADC does not push the words themselves, every sensor
            // word is made of its ADC code into the record (`super::io::read_sensor`);
            // otherwise the words lie in the window or this sample's results (r6).
            let convert = !k.sensor_channels.is_empty();
            // The sensor check reads the copy its word replaces: a checked key's words are
            // copied.
            let (trip, resume) = (a.label(), a.label());
            let in_window =
                !convert && k.guard.is_none() && check.is_none() && !k.sensor_words.is_empty();
            let copied = match (in_window, convert) {
                (true, _) => 0,
                (false, true) => k.sensor_channels.len(),
                (false, false) => k.sensor_words.len(),
            };
            for i in 0..copied {
                if convert {
                    let (ch, scale) = &k.sensor_channels[i];
                    super::io::read_sensor(a, *ch, scale);
                } else {
                    let w = k.sensor_words[i];
                    let off = w.wrapping_sub(sensor_base);
                    if off <= 124 && off % 4 == 0 {
                        a.i(asm::ldr(0, 6, off as u16));
                    } else {
                        a.ldr_const(0, w);
                        a.i(asm::ldr(0, 0, 0));
                    }
                }
                if let (0, Some(c)) = (i, &check) {
                    check_step(a, c, 0, trip);
                    a.bind(resume);
                }
                if k.guard.is_some() {
                    // r3 = new ^ old for the first word, r3 |= new ^ old for the others
                    // (the image keeps at most 24 sensors: offsets ≤ 92).
                    if i == 0 {
                        a.i(asm::ldr(3, 4, 0));
                        a.i(asm::alu(AluOp::Eor, 3, 0));
                    } else {
                        a.i(asm::ldr(1, 4, 4 * i as u16));
                        a.i(asm::alu(AluOp::Eor, 1, 0));
                        a.i(asm::alu(AluOp::Orr, 3, 1));
                    }
                }
                if 4 * i <= 124 {
                    a.i(asm::str(0, 4, 4 * i as u16));
                } else {
                    a.mov_const(1, 4 * i as u32);
                    a.i(Instr::MemReg {
                        op: tactus_isa::decode::MemOp::Str,
                        rt: 0,
                        rn: 4,
                        rm: 1,
                    });
                }
            }
            let skip = a.label();
            if let Some(g) = &k.guard {
                guard_check(a, g, skip);
            }
            ldr_rec(a, 0, k.state_offset);
            // The state check of the key this copy checks (its mode bytes in range).
            let state_trip = check.as_ref().filter(|c| !c.modes.is_empty()).map(|c| {
                let l = a.label();
                check_modes(a, c, l);
                l
            });
            if in_window {
                let off = k.sensor_words[0].wrapping_sub(sensor_base);
                if off <= 7 {
                    a.i(asm::adds_imm(1, 6, off as u8));
                } else if off <= 255 {
                    a.i(asm::mov(1, 6));
                    a.i(asm::adds_imm(1, 1, off as u8));
                } else {
                    a.ldr_const(1, k.sensor_words[0]);
                }
            } else {
                a.i(asm::mov(1, 4));
            }
            if k.out_offset <= 7 {
                a.i(asm::adds_imm(2, 4, k.out_offset as u8));
            } else {
                a.i(asm::mov(2, 4));
                add_big(a, 2, k.out_offset);
            }
            let call = a.label();
            a.bind(call);
            if let Some(c) = keys.iter().position(|x| std::ptr::eq(x, k)) {
                calls[c].push(call);
            }
            a.bl_addr(k.update);
            if let Some(g) = &k.guard {
                let window = |a: &mut CodeBuffer| a.ldr_const(6, sensor_base);
                let restore: &dyn Fn(&mut CodeBuffer) = match io {
                    Some(_) => &super::io::restore_r6,
                    None => &window,
                };
                guard_record(a, g, k.state_offset, Some(restore));
            }
            a.bind(skip);
            for (j, d) in k.drives.iter().enumerate() {
                ldr_rec(a, 0, d.force_offset);
                let in_regs = if d.scale == scale {
                    Scale::InRegisters
                } else {
                    Scale::Literal
                };
                let off = d.budget_offset as u16;
                // The trip path behind the first limiter's last branch: within a `BNE`'s
                // reach of the check; the dispatch's trampolines behind the first copy's
                // first limiter, within a `B<cc>`'s reach of the dispatch.
                let mut aside = |a: &mut CodeBuffer| {
                    if let (0, Some(c)) = (j, &check) {
                        // The path itself after the handler's end (within a `B`'s reach).
                        let far = a.label();
                        a.bind(trip);
                        a.b(far);
                        let state = state_trip.map(|near| {
                            let far = a.label();
                            a.bind(near);
                            a.b(far);
                            far
                        });
                        let i = keys.iter().position(|x| std::ptr::eq(x, k)).unwrap_or(0);
                        trips.push(PendingTrip {
                            check: c.clone(),
                            far,
                            join: skip,
                            resume,
                            state,
                            key: i,
                        });
                    }
                    if std::mem::take(&mut first_aside) {
                        dispatch_trampolines(a, copy, turns, upper, &tramp, &starts);
                    }
                };
                let gate = gates.get(j).copied();
                limiter_with(
                    a, limiter, &d.scale, in_regs, lost, 4, off, gate, &mut aside,
                )?;
                let off = d.dac_word.wrapping_sub(dac_base);
                if let (Some(ch), Some(_)) = (d.dac_channel, io) {
                    super::io::write_dac(a, ch);
                } else if off <= 124 && off % 4 == 0 {
                    a.i(asm::str(0, 7, off as u16));
                } else {
                    a.ldr_const(1, d.dac_word);
                    a.i(asm::str(0, 1, 0));
                }
            }
            // The literals this key needs after its last limiter (a far DAC word, another
            // format's gain) wait for the next key's limiter's pool, or the end's.
            if turns.near_trips && !trips.is_empty() {
                // Its trip path here, over a `B` ([`Turns::near_trips`]).
                let over = a.label();
                a.b(over);
                trip_paths(a, &mut trips, keys, ctrl_addr, core);
                a.bind(over);
            }
            Ok(())
        })?;
        if first_aside {
            // No limiter in the first copy (no drives): the trampolines here.
            let over = a.label();
            a.b(over);
            dispatch_trampolines(a, copy, turns, upper, &tramp, &starts);
            a.bind(over);
        }
        if Some(copy) == fed_copy {
            // The feeding class's copy: its own tail, which feeds, in place of the branch
            // to the others' (and the keys part's end, `labels.keys_end`).
            tail(a, true, Some(ends[copy as usize]));
            a.pool();
        }
        if copy + 1 < copies && (Some(copy) != fed_copy || turns.hops) {
            // To the end, or with hops to the next copy's branch to it (for the copies
            // before hopping through here, after the feeding copy's own tail).
            a.bind(tails[copy as usize]);
            match (turns.hops, copy + 2 < copies) {
                (true, true) => a.b(tails[copy as usize + 1]),
                _ => a.b(end),
            }
            a.pool();
        }
        if copy + 1 < copies {
            // This copy's trip paths here, within a `B`'s reach of its checks.
            trip_paths(a, &mut trips, keys, ctrl_addr, core);
        }
    }
    a.bind(end);
    tail(a, fed_copy.is_none(), Some(labels.keys_end));
    a.pool();
    trip_paths(a, &mut trips, keys, ctrl_addr, core);
    let copies = starts.into_iter().zip(ends).collect();
    Ok(CoreLabels {
        calls,
        copies,
        ..labels
    })
}

/// The dispatch's far half ([`Turns`]) that copy `copy` hosts, out of the copies' flow
/// (behind its first limiter: within a `B<cc>`'s reach of what branches here). Copy 0
/// hosts the branch to copy 1 and `upper` (C set: classes 2 and 3), which tests N for
/// class 3; the branches to copies 2 and 3 are there too, or, with [`Turns::hops`] (copies
/// beyond a `B`'s 2 KiB), one copy on at a time.
fn dispatch_trampolines(
    a: &mut CodeBuffer,
    copy: u32,
    turns: &Turns,
    upper: Label,
    tramp: &[Label],
    starts: &[Label],
) {
    let copies = turns.classes;
    match (copy, turns.hops && copies > 2) {
        (0, false) => {
            a.bind(tramp[0]);
            a.b(starts[1]);
            if copies > 2 {
                a.bind(upper);
                a.bc(cond::MI, tramp[2]);
                a.b(starts[2]);
                a.bind(tramp[2]);
                a.b(starts[3]);
            }
        }
        (0, true) => {
            let three = a.label();
            a.bind(tramp[0]);
            a.b(starts[1]);
            a.bind(upper);
            a.bc(cond::MI, three);
            a.b(tramp[1]);
            a.bind(three);
            a.b(tramp[2]);
        }
        (1, true) => {
            a.bind(tramp[1]);
            a.b(starts[2]);
            a.bind(tramp[2]);
            a.b(tramp[3]);
        }
        (2, true) => {
            a.bind(tramp[3]);
            a.b(starts[3]);
        }
        _ => {}
    }
}

/// `rd += n` through r3 when `n` is beyond two `ADDS #imm8`.
fn add_const(a: &mut CodeBuffer, rd: u8, n: u32) {
    if n <= 510 {
        add_big(a, rd, n);
    } else {
        a.ldr_const(3, n);
        a.i(asm::adds(rd, rd, 3));
    }
}

/// The tick's step: SYST_RVR = `q − 1`, plus one when the accumulator ([`ctrl::ACC`],
/// through r2) carries (clobbers r0-r3; r5 kept). With `d = den − rem`: `acc − d ≥ 0`
/// exactly when `acc + rem` reaches `den` (a carry, and the new `acc`); else the new `acc`
/// is `acc − d + den`. Nothing when the period is a whole number of cycles (the reload
/// value set at reset stays). 44.1 kHz at 133 MHz: 14 cycles on the worst path (no carry).
fn tick_step(a: &mut CodeBuffer, t: &Tick) {
    if t.rem == 0 {
        return;
    }
    let done = a.label();
    a.i(asm::ldr(2, 5, ctrl::ACC));
    a.mov_const(1, t.q);
    let d = t.den - t.rem;
    if d <= 255 {
        a.i(asm::subs_imm(2, 2, d as u8));
    } else {
        a.ldr_const(3, d);
        a.i(asm::subs(2, 2, 3));
    }
    a.bc(cond::PL, done);
    add_const(a, 2, t.den);
    a.i(asm::subs_imm(1, 1, 1));
    a.bind(done);
    a.i(asm::str(2, 5, ctrl::ACC));
    a.ldr_const(0, syst::RVR);
    a.i(asm::str(1, 0, 0));
}
