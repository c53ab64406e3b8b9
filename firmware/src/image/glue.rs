//! The image's hand-written Thumb: the safety limiter, the sample interrupt handler and the
//! reset handler of one core, emitted through [`super::asm::Asm`].
//!
//! Register use follows AAPCS: the per-key updates (compiled code) may clobber r0-r3 and
//! r12 and preserve r4-r11, so the handler keeps its record pointer in r4 and its control
//! block pointer in r5 across the `BL`s.

use super::asm::{self, cond, Asm, Label};
use super::ImageError;
use tactus_emulator::decode::{AluOp, Hint, Instr};
use tactus_emulator::timer::{reg, TIMER_BASE};
use tactus_runtime::limiter::LimiterConstants;

/// Byte offsets in a core's control block (words in the core's own SRAM bank).
pub mod ctrl {
    /// Microsecond time of the next sample tick (the armed alarm).
    pub const TARGET: u16 = 0;
    /// Remainder accumulator of the tick schedule (in 1/fs µs).
    pub const ACC: u16 = 4;
    /// Samples whose handler has completed.
    pub const SAMPLES: u16 = 8;
    /// Deadline misses: handlers that finished after the next tick.
    pub const MISSES: u16 = 12;
    /// 1 once the reset handler has initialised every key and armed the timer.
    pub const READY: u16 = 16;
    /// Size of the block; the key records follow it.
    pub const SIZE: u32 = 20;
}

/// Byte offsets in a key's record.
pub mod rec {
    /// The key's sensor word, copied from the sensor window (the update's `sensors`), for a
    /// key with one sensor; a key with more keeps them from [`OUT`] on (`KeyCode`).
    pub const SENSOR: u16 = 0;
    /// The limiter's time budget (1/`recovery` samples).
    pub const BUDGET: u16 = 4;
    /// The motor current the limiter allowed this sample, µA.
    pub const CURRENT: u16 = 8;
    /// Address of the key's sensor window word.
    pub const WINDOW: u16 = 12;
    /// Address of the key's DAC window word.
    pub const DAC: u16 = 16;
    /// Address of the key's state struct.
    pub const STATE: u16 = 20;
    /// The update's `out` words start here.
    pub const OUT: u32 = 24;
}

// The limiter stores the current in the word after the budget.
const _: () = assert!(rec::CURRENT == rec::BUDGET + 4);

/// NVIC_ISER (DDI0419 B3.4.3).
const NVIC_ISER: u32 = 0xe000_e100;

/// `rd += n` for any `n` (ADDS #imm8 steps).
fn add_big(a: &mut Asm, rd: u8, mut n: u32) {
    while n > 0 {
        let step = n.min(255);
        a.i(asm::adds_imm(rd, rd, step as u8));
        n -= step;
    }
}

/// `r0 = clamp(round(r0 · b / 2^s), -limit, limit)`, the exact result of
/// `fixed::mul(r0, f, b, fb, 0)` (s = f + fb) clamped to ±`limit`, as
/// `runtime/src/limiter.rs` computes it: the signed 64-bit product from four 16×16 `MULS`
/// of the magnitudes, negated back; `+ 2^(s-1)`, arithmetic shift by `s` (rounding half
/// up); saturation to ±`limit`. Clobbers r2, r3, r6, r7 (and r4, r5); preserves r1.
fn mul_round_clamp(a: &mut Asm, b: u32, s: u32, limit: u32) {
    use AluOp::*;
    a.i(asm::asrs(7, 0, 31)); // r7 = sign mask of a
    a.i(asm::alu(Eor, 0, 7));
    a.i(asm::subs(0, 0, 7)); // r0 = |a| (unsigned)
    a.i(Instr::Uxth { rd: 3, rm: 0 }); // al
    a.i(asm::lsrs(0, 0, 16)); // ah
    a.mov_const(4, b & 0xffff); // bl
    a.mov_const(5, b >> 16); // bh
    a.i(asm::mov(6, 3));
    a.i(asm::alu(Mul, 6, 4)); // lo = al·bl
    a.i(asm::alu(Mul, 3, 5)); // al·bh
    a.i(asm::mov(2, 0));
    a.i(asm::alu(Mul, 2, 5)); // hi = ah·bh
    a.i(asm::alu(Mul, 0, 4)); // ah·bl
    a.i(asm::movs(4, 0));
    a.i(asm::adds(0, 0, 3)); // mid = ah·bl + al·bh, carry out
    a.i(asm::alu(Adc, 4, 4)); // r4 = carry
    a.i(asm::lsls(4, 4, 16));
    a.i(asm::adds(2, 2, 4)); // hi += carry << 16
    a.i(asm::lsls(3, 0, 16));
    a.i(asm::lsrs(0, 0, 16));
    a.i(asm::adds(6, 6, 3)); // lo += mid << 16
    a.i(asm::alu(Adc, 2, 0)); // hi += mid >> 16 + carry
                              // Negate (64-bit) when a < 0: (x ^ m) - m.
    a.i(asm::alu(Eor, 6, 7));
    a.i(asm::alu(Eor, 2, 7));
    a.i(asm::subs(6, 6, 7));
    a.i(asm::alu(Sbc, 2, 7));
    // Round half up: + 2^(s-1).
    if s - 1 < 32 {
        a.mov_const(3, 1 << (s - 1));
        a.i(asm::movs(4, 0));
        a.i(asm::adds(6, 6, 3));
        a.i(asm::alu(Adc, 2, 4));
    } else {
        a.mov_const(3, 1 << (s - 33));
        a.i(asm::adds(2, 2, 3));
    }
    // Arithmetic shift right by s (64-bit): the result's low word in r6, high in r2.
    match s {
        1..=31 => {
            a.i(asm::lsrs(6, 6, s as u8));
            a.i(asm::lsls(3, 2, (32 - s) as u8));
            a.i(asm::alu(Orr, 6, 3));
            a.i(asm::asrs(2, 2, s as u8));
        }
        32 => {
            a.i(asm::mov(6, 2));
            a.i(asm::asrs(2, 2, 31));
        }
        _ => {
            a.i(asm::asrs(6, 2, (s - 32) as u8));
            a.i(asm::asrs(2, 2, 31));
        }
    }
    // Clamp to ±limit: in i32 range iff hi is the sign extension of lo.
    let (inside, done) = (a.label(), a.label());
    a.i(asm::asrs(3, 6, 31));
    a.i(asm::cmp(3, 2));
    a.bc(cond::EQ, inside);
    a.mov_const(0, limit);
    a.i(asm::cmp_imm(2, 0));
    a.bc(cond::GE, done);
    a.i(asm::negs(0, 0));
    a.b(done);
    a.bind(inside);
    a.mov_const(0, limit);
    a.i(asm::cmp(6, 0));
    a.bc(cond::GT, done);
    a.i(asm::negs(0, 0));
    a.i(asm::cmp(6, 0));
    a.bc(cond::LT, done);
    a.i(asm::mov(0, 6));
    a.bind(done);
}

/// The shift of `fixed::mul(x, f, y, fy, 0)` when it is one the limiter code supports.
fn shift(f: i32, fy: i32, what: &str) -> Result<u32, ImageError> {
    let s = f + fy;
    if (1..=62).contains(&s) {
        Ok(s as u32)
    } else {
        Err(ImageError::Limiter(format!(
            "{what}: a product with {s} fraction bits (the Thumb limiter handles 1 to 62)"
        )))
    }
}

/// The limiter of keys whose force words have `force_frac` fraction bits, as a function:
/// `r0` = force word, `r1` = address of the key's record budget word (the current follows
/// it); returns the DAC code in `r0` (sign-extended) and updates the budget and the current.
/// Exactly `Limiter::step` (runtime/src/limiter.rs).
pub fn limiter(
    a: &mut Asm,
    entry: Label,
    c: &LimiterConstants,
    force_frac: i32,
) -> Result<(), ImageError> {
    let bad = |what: &str| Err(ImageError::Limiter(what.to_string()));
    if c.gain.0 <= 0 || c.dac_scale.0 <= 0 {
        return bad("the gain and the DAC scale must be positive words");
    }
    if c.peak_ua <= 0 || c.rated_ua <= 0 || c.recovery <= 0 || c.budget_max < 0 {
        return bad("the peak and rated currents and the recovery must be positive");
    }
    if c.budget_max >= i32::MAX as i64 || c.recovery > i32::MAX as i64 {
        return bad("the time budget does not fit a 32-bit word");
    }
    let s1 = shift(force_frac, c.gain.1, "force → current")?;
    let s2 = shift(0, c.dac_scale.1, "current → DAC code")?;
    a.bind(entry);
    a.i(asm::push_lr(0xf0));
    mul_round_clamp(a, c.gain.0 as u32, s1, c.peak_ua as u32);
    let (earn, above, clamp, store) = (a.label(), a.label(), a.label(), a.label());
    a.i(asm::ldr(5, 1, 0)); // budget
    a.i(asm::asrs(3, 0, 31));
    a.i(asm::mov(2, 0));
    a.i(asm::alu(AluOp::Eor, 2, 3));
    a.i(asm::subs(2, 2, 3)); // |i|
    a.mov_const(4, c.rated_ua as u32);
    a.i(asm::cmp(2, 4));
    a.bc(cond::HI, above);
    a.bind(earn);
    a.i(asm::adds_imm(5, 5, 1));
    a.mov_const(6, c.budget_max as u32);
    a.i(asm::cmp(5, 6));
    a.bc(cond::LE, store);
    a.i(asm::mov(5, 6));
    a.b(store);
    a.bind(above);
    a.mov_const(6, c.recovery as u32);
    a.i(asm::cmp(5, 6));
    a.bc(cond::LT, clamp);
    a.i(asm::subs(5, 5, 6));
    a.b(store);
    a.bind(clamp);
    // Budget spent: clamp to ±rated (|i| is then rated, which earns).
    a.i(asm::mov(0, 4));
    a.i(asm::cmp_imm(3, 0));
    a.bc(cond::EQ, earn);
    a.i(asm::negs(0, 4));
    a.b(earn);
    a.bind(store);
    a.i(asm::str(5, 1, 0));
    a.i(asm::str(0, 1, 4));
    mul_round_clamp(a, c.dac_scale.0 as u32, s2, 32767);
    a.i(asm::pop_pc(0xf0));
    a.pool();
    Ok(())
}

/// One key of a core, as the handler sees it.
pub struct KeyCode {
    /// Sensor words the handler copies from the key's sensor window words (consecutive
    /// words from the record's [`rec::WINDOW`] address) into the record.
    pub sensors: u32,
    /// Byte offset in the record of the copied sensor words, the update's `sensors`
    /// array: [`rec::SENSOR`] for a key with one sensor (the keyboard record), else past
    /// the record's header (at most 124 minus 4 per sensor: a `STR` immediate).
    pub sensor_offset: u32,
    /// Byte offset of the update's `out` words in the record.
    pub out_offset: u32,
    /// The force words the key drives, each through the limiter to its own DAC window
    /// word: drive *j* to the word `4·j` bytes past the record's [`rec::DAC`] address.
    pub drives: Vec<DriveCode>,
    /// Record size in bytes.
    pub record_size: u32,
    /// Address of the key's program's update (this core's copy).
    pub update: u32,
    /// Address of the key's program's init (this core's copy).
    pub init: u32,
}

/// One force word of a key on its way to the DAC, as the handler sees it.
pub struct DriveCode {
    /// Byte offset of the force word in the record (`out[total]` for a keyboard key).
    pub force_offset: u32,
    /// Byte offset of the limiter's budget word in the record (the current follows it):
    /// [`rec::BUDGET`] for the first drive.
    pub budget_offset: u32,
    /// The limiter routine for the force word's format.
    pub limiter: Label,
}

/// The tick schedule: `period_us = q + rem/fs` µs, kept exactly by a remainder accumulator.
#[derive(Clone, Copy, Debug)]
pub struct Tick {
    /// Whole microseconds per period (`1e6 div fs`).
    pub q: u32,
    /// Remainder (`1e6 mod fs`), in 1/fs µs.
    pub rem: u32,
    /// Sample rate, Hz.
    pub fs: u32,
    /// Smallest lead (µs) with which an alarm is armed: a handler that starts later than
    /// that re-synchronises to now + `margin` (the alarm would otherwise wait for the
    /// 32-bit count to wrap).
    pub margin: u8,
}

/// Labels of a core's code, bound by [`core_code`].
pub struct CoreLabels {
    /// The reset handler.
    pub reset: Label,
    /// The sample interrupt handler.
    pub isr: Label,
    /// The default handler (`B .`) of every other vector.
    pub default: Label,
    /// Instructions of the handler that access the timer (APB), for the WCET's bounds.
    pub apb: Vec<Label>,
}

/// The reset and sample-interrupt handlers of core `core` with `keys`, its control block
/// at `ctrl_addr`. `inte` is written to the timer's INTE by core 0 (one alarm per core).
pub fn core_code(
    a: &mut Asm,
    core: usize,
    keys: &[KeyCode],
    ctrl_addr: u32,
    tick: Tick,
    inte: u32,
) -> CoreLabels {
    let labels = CoreLabels {
        reset: a.label(),
        isr: a.label(),
        default: a.label(),
        apb: Vec::new(),
    };
    let mut apb = Vec::new();
    let mut apb_here = |a: &mut Asm| {
        let l = a.label();
        a.bind(l);
        apb.push(l);
    };
    let alarm = reg::ALARM0 as u16 + 4 * core as u16;
    let walk = |a: &mut Asm, keys: &[KeyCode], f: &mut dyn FnMut(&mut Asm, &KeyCode)| {
        a.i(asm::mov(4, 5));
        add_big(a, 4, ctrl::SIZE);
        for (i, k) in keys.iter().enumerate() {
            f(a, k);
            if i + 1 < keys.len() {
                add_big(a, 4, k.record_size);
            }
        }
    };

    // ---- reset: init every key, arm the first tick, enable the interrupt, sleep ----
    a.bind(labels.reset);
    a.ldr_const(5, ctrl_addr);
    walk(a, keys, &mut |a, k| {
        a.i(asm::ldr(0, 4, rec::STATE));
        a.bl(k.init);
    });
    a.ldr_const(0, TIMER_BASE);
    if core == 0 {
        a.mov_const(1, inte);
        a.i(asm::str(1, 0, reg::INTE as u16));
    }
    a.i(asm::ldr(1, 5, ctrl::TARGET));
    a.i(asm::str(1, 0, alarm));
    a.ldr_const(0, NVIC_ISER);
    a.i(asm::movs(1, 1 << core));
    a.i(asm::str(1, 0, 0));
    a.i(asm::movs(1, 1));
    a.i(asm::str(1, 5, ctrl::READY));
    a.i(Instr::Cps { disable: false });
    let idle = a.label();
    a.bind(idle);
    a.i(Instr::Hint(Hint::Wfi));
    a.b(idle);
    a.pool();
    a.bind(labels.default);
    a.b(labels.default);

    // ---- the sample interrupt ----
    a.align4();
    a.bind(labels.isr);
    a.i(asm::push_lr(0x70)); // r4-r6 (r6 keeps the stack 8-aligned), lr
    a.ldr_const(5, ctrl_addr);
    a.ldr_const(0, TIMER_BASE);
    a.i(asm::movs(1, 1 << core));
    apb_here(a);
    a.i(asm::str(1, 0, reg::INTR as u16)); // acknowledge the alarm
                                           // Next tick: target += q (+1 when the remainder accumulator overflows).
    a.i(asm::ldr(1, 5, ctrl::TARGET));
    a.i(asm::ldr(2, 5, ctrl::ACC));
    a.mov_const(3, tick.q);
    a.i(asm::adds(1, 1, 3));
    a.mov_const(3, tick.rem);
    a.i(asm::adds(2, 2, 3));
    a.mov_const(3, tick.fs);
    let (no_carry, armed) = (a.label(), a.label());
    a.i(asm::cmp(2, 3));
    a.bc(cond::LT, no_carry);
    a.i(asm::subs(2, 2, 3));
    a.i(asm::adds_imm(1, 1, 1));
    a.bind(no_carry);
    a.i(asm::str(2, 5, ctrl::ACC));
    apb_here(a);
    a.i(asm::ldr(3, 0, reg::TIMERAWL as u16));
    a.i(asm::subs(3, 1, 3)); // target - now
    a.i(asm::cmp_imm(3, tick.margin));
    a.bc(cond::GE, armed);
    // Late by a whole period already (only after a miss): re-synchronise.
    apb_here(a);
    a.i(asm::ldr(1, 0, reg::TIMERAWL as u16));
    a.i(asm::adds_imm(1, 1, tick.margin));
    a.bind(armed);
    a.i(asm::str(1, 5, ctrl::TARGET));
    apb_here(a);
    a.i(asm::str(1, 0, alarm));
    a.pool_inline();
    // Every key: sensors → record, update, then each force word: limiter, DAC.
    walk(a, keys, &mut |a, k| {
        a.i(asm::ldr(0, 4, rec::WINDOW));
        if k.sensors == 1 && k.sensor_offset == rec::SENSOR as u32 {
            a.i(asm::ldr(0, 0, 0));
            a.i(asm::str(0, 4, rec::SENSOR));
        } else {
            for i in 0..k.sensors {
                a.i(asm::ldr(1, 0, 4 * i as u16));
                a.i(asm::str(1, 4, (k.sensor_offset + 4 * i) as u16));
            }
        }
        a.i(asm::ldr(0, 4, rec::STATE));
        a.i(asm::mov(1, 4));
        add_big(a, 1, k.sensor_offset);
        a.i(asm::mov(2, 4));
        add_big(a, 2, k.out_offset);
        a.bl(k.update);
        for (j, d) in k.drives.iter().enumerate() {
            if d.force_offset <= 124 {
                a.i(asm::ldr(0, 4, d.force_offset as u16));
            } else {
                a.mov_const(0, d.force_offset);
                a.i(asm::ldr_reg(0, 4, 0));
            }
            if d.budget_offset <= 7 {
                a.i(asm::adds_imm(1, 4, d.budget_offset as u8));
            } else {
                a.i(asm::mov(1, 4));
                add_big(a, 1, d.budget_offset);
            }
            a.bl_label(d.limiter);
            a.i(asm::ldr(1, 4, rec::DAC));
            a.i(asm::str(0, 1, 4 * j as u16));
        }
    });
    a.ldr_const(0, TIMER_BASE);
    apb_here(a);
    a.i(asm::ldr(2, 0, reg::TIMERAWL as u16));
    a.i(asm::ldr(1, 5, ctrl::TARGET));
    a.i(asm::subs(2, 2, 1)); // now - next tick
    let on_time = a.label();
    a.bc(cond::MI, on_time);
    a.i(asm::ldr(1, 5, ctrl::MISSES));
    a.i(asm::adds_imm(1, 1, 1));
    a.i(asm::str(1, 5, ctrl::MISSES));
    a.bind(on_time);
    a.i(asm::ldr(1, 5, ctrl::SAMPLES));
    a.i(asm::adds_imm(1, 1, 1));
    a.i(asm::str(1, 5, ctrl::SAMPLES));
    a.i(asm::pop_pc(0x70));
    a.pool();
    CoreLabels { apb, ..labels }
}
