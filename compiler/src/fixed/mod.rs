//! Fixed-point compilation: range analysis, Q-format choice, and the fixed-point program
//! that the fixed interpreter, the JIT and the firmware backends run.
//!
//! The fixed program is the IR plus a *format plan*: one binary point (fraction bits) per
//! value, per state and per sensor, the raw words of constants, and the reciprocal that
//! replaces each division by a constant. Each value's format is the finest that holds its
//! whole interval from [`range`] in a signed 32-bit word:
//! `frac = 30 − floor(log2(max |v|))`, so `|raw| < 2^31`. What an operation computes is
//! defined once, in [`tactus_runtime::fixed`]: the exact result rounded half up to the result
//! format and saturated. Because the formats hold the analysed intervals, saturation can fire
//! only where the analysis had to clamp an unbounded value, and those places are warned about.

pub mod interp;
pub mod range;
pub mod report;

use crate::diagnostics::Diagnostic;
use crate::ir::*;
use range::{Interval, Ranges};
use tactus_runtime::differentiator::WINDOW;
use tactus_runtime::fixed as fx;

pub use tactus_runtime::fixed::FRAC_RANGE;

/// The finest format holding `iv` in an `i32`: fraction bits ([`tactus_runtime::fixed::frac_for`]).
pub fn frac_for(iv: Interval) -> i32 {
    tactus_runtime::fixed::frac_for(iv.mag())
}

/// A multiplication may drop low operand bits to fit `MULS` when the error this adds is at
/// most this fraction of the product's largest magnitude (2^-22: 6 bits finer than a 16-bit
/// DAC at full scale).
pub const MULS_REL_TOLERANCE: f64 = 1.0 / (1u64 << 22) as f64;

/// How a multiplication is done on a 32-bit core without a 64-bit product instruction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MulKind {
    /// Operands pre-shifted right by (a, b) bits so the product fits 32 bits: one `MULS`
    /// plus shifts ([`tactus_runtime::fixed::mul_shifted`]).
    Muls(u8, u8),
    /// The exact product needs up to 64 bits: four 16×16 `MULS` partial products and adds
    /// (ARMv6-M has no `SMULL`).
    Wide,
}

impl MulKind {
    /// Estimated Cortex-M0+ cycles, including the final shift: `Muls` 3 (MULS 1 + shifts);
    /// `Wide` 18 (4 MULS, 6 shifts/extends, 4 adds with carry, 2 shifts for the result
    /// format, per the Cortex-M0+ TRM single-cycle ALU and fast-multiplier timings).
    pub fn cycles(self) -> u32 {
        match self {
            MulKind::Muls(..) => 3,
            MulKind::Wide => 18,
        }
    }
}

/// A program compiled to fixed point.
#[derive(Clone, Debug)]
pub struct FixedProgram {
    /// The IR (its statement list is what every fixed engine executes).
    pub program: Program,
    /// Interval of every value.
    pub ranges: Ranges,
    /// Fraction bits of every value (truth values and modes: 0).
    pub frac: Vec<i32>,
    /// Raw word of every constant and param value (0 for other values).
    pub consts: Vec<i32>,
    /// For a division by a constant: the raw word and fraction bits of the reciprocal it
    /// multiplies by instead.
    pub recip: Vec<Option<(i32, i32)>>,
    /// How each multiplication (and division by a constant) is done; `None` for other values.
    pub mul_kind: Vec<Option<MulKind>>,
    /// Fraction bits of each sensor (from its declared range).
    pub sensor_frac: Vec<i32>,
    /// Raw bounds of each sensor.
    pub sensor_raw_range: Vec<(i32, i32)>,
    /// Fraction bits of each state (from its declared range).
    pub state_frac: Vec<i32>,
    /// Raw bounds each state write saturates to.
    pub state_raw_range: Vec<(i32, i32)>,
    /// Raw initial value of each state.
    pub state_init: Vec<i32>,
    /// `fs/N` and `(fs/N)²` of the differentiators as (raw, fraction bits).
    pub deriv_gain: [(i32, i32); 2],
    /// Format of each force term (that of its value).
    pub force_frac: Vec<i32>,
    /// Format of the total force.
    pub total_frac: i32,
    /// Format of each output.
    pub output_frac: Vec<i32>,
    /// Format of each event argument: the coarsest among the emits of that event; `emit`
    /// converts its arguments to it.
    pub event_frac: Vec<Vec<i32>>,
    /// Saturation inserted where the analysis found no bound.
    pub warnings: Vec<Diagnostic>,
}

/// Formats of what the body publishes.
struct Published {
    force: Vec<i32>,
    total: i32,
    output: Vec<i32>,
    event: Vec<Vec<i32>>,
}

fn published(p: &Program, frac: &[i32]) -> Published {
    let mut out = Published {
        force: vec![0; p.forces.len()],
        total: 0,
        output: vec![0; p.outputs.len()],
        event: p
            .events
            .iter()
            .map(|e| vec![FRAC_RANGE.1; e.args.len()])
            .collect(),
    };
    fn walk(stmts: &[Stmt], frac: &[i32], out: &mut Published) {
        for s in stmts {
            match s {
                Stmt::Force(f, v) => out.force[f.index()] = frac[v.index()],
                Stmt::Total(v) => out.total = frac[v.index()],
                Stmt::Output(o, v) => out.output[o.index()] = frac[v.index()],
                Stmt::Emit(e, args) => {
                    for (slot, v) in out.event[e.index()].iter_mut().zip(args) {
                        *slot = (*slot).min(frac[v.index()]);
                    }
                }
                Stmt::If(_, body) => walk(body, frac, out),
                _ => {}
            }
        }
    }
    walk(&p.body, frac, &mut out);
    out
}

fn constant(v: f64) -> (i32, i32) {
    let f = frac_for(Interval::point(v));
    (fx::from_f64(v, f).0, f)
}

impl FixedProgram {
    /// Plans formats for `program`. Never fails: unbounded values get saturation and a warning.
    pub fn new(program: &Program) -> Self {
        let ranges = range::analyse(program);
        let n = program.values.len();
        let mut frac = vec![0; n];
        let mut consts = vec![0; n];
        let mut recip = vec![None; n];
        let mut mul_kind = vec![None; n];
        for (i, vd) in program.values.iter().enumerate() {
            frac[i] = match vd.ty {
                Ty::Real(_) => frac_for(ranges.values[i]),
                Ty::Bool | Ty::Mode(_) => 0,
            };
            match vd.op {
                Op::Const(c) => consts[i] = fx::from_f64(c, frac[i]).0,
                Op::Param(p) => {
                    consts[i] = fx::from_f64(program.params[p.index()].value, frac[i]).0
                }
                _ => {}
            }
        }
        let is_const =
            |v: Value| matches!(program.values[v.index()].op, Op::Const(_) | Op::Param(_));
        let const_value = |v: Value| match program.values[v.index()].op {
            Op::Const(c) => c,
            Op::Param(p) => program.params[p.index()].value,
            _ => f64::NAN,
        };
        for (i, vd) in program.values.iter().enumerate() {
            let (x, y, c) = match vd.op {
                Op::Arith(ArithOp::Div, x, y) if is_const(y) => {
                    let c = const_value(y);
                    if c == 0.0 {
                        continue;
                    }
                    let (raw, f) = constant(1.0 / c);
                    recip[i] = Some((raw, f));
                    (x, None, Some((raw, f)))
                }
                Op::Arith(ArithOp::Mul, x, y) => {
                    if is_const(y) {
                        (x, None, Some((consts[y.index()], frac[y.index()])))
                    } else if is_const(x) {
                        (y, None, Some((consts[x.index()], frac[x.index()])))
                    } else {
                        (x, Some(y), None)
                    }
                }
                _ => continue,
            };
            let fx_of = |v: Value| (frac[v.index()], ranges.values[v.index()]);
            let k = match (y, c) {
                (_, Some((raw, fc))) => {
                    let free = raw.trailing_zeros().min(31) as i32;
                    let k = Self::plan_mul(
                        fx_of(x),
                        0,
                        (fc, Interval::point(tactus_runtime::fixed::to_f64(raw, fc))),
                        free,
                        ranges.values[i],
                    );
                    // The constant operand is the second one of the planned pair; store the
                    // shifts in operand order (x, y), which is what every engine applies.
                    match (vd.op.clone(), k) {
                        (Op::Arith(ArithOp::Mul, a, _), MulKind::Muls(sa, sb)) if is_const(a) => {
                            MulKind::Muls(sb, sa)
                        }
                        (_, k) => k,
                    }
                }
                (Some(y), None) => Self::plan_mul(fx_of(x), 0, fx_of(y), 0, ranges.values[i]),
                (None, None) => continue,
            };
            mul_kind[i] = Some(k);
        }
        let sensor_frac: Vec<i32> = program
            .sensors
            .iter()
            .map(|s| frac_for(Interval::new(s.range.0, s.range.1)))
            .collect();
        let sensor_raw_range = program
            .sensors
            .iter()
            .zip(&sensor_frac)
            .map(|(s, &f)| (fx::from_f64(s.range.0, f).0, fx::from_f64(s.range.1, f).0))
            .collect();
        let state_frac: Vec<i32> = program
            .states
            .iter()
            .map(|s| frac_for(Interval::new(s.range.0, s.range.1)))
            .collect();
        let state_raw_range = program
            .states
            .iter()
            .zip(&state_frac)
            .map(|(s, &f)| (fx::from_f64(s.range.0, f).0, fx::from_f64(s.range.1, f).0))
            .collect();
        let state_init = program
            .states
            .iter()
            .zip(&state_frac)
            .map(|(s, &f)| fx::from_f64(s.init, f).0)
            .collect();
        let r = program.sample_rate_hz / WINDOW as f64;
        let deriv_gain = [constant(r), constant(r * r)];
        let warnings = ranges
            .clamped
            .iter()
            .map(|v| {
                let vd = &program.values[v.index()];
                Diagnostic::warning(
                    "W0101",
                    format!(
                        "no bound for this value: fixed-point saturation inserted at ±{} {}",
                        range::UNBOUNDED_CLAMP,
                        match vd.ty {
                            Ty::Real(d) => d.unit_string(),
                            _ => String::new(),
                        }
                    ),
                    vd.span.clone(),
                )
                .hint("bound it: a division by a range containing 0 or an exp of a wide range has no bound; clamp the operand or narrow the ranges it comes from")
            })
            .collect();
        let publ = published(program, &frac);
        FixedProgram {
            force_frac: publ.force,
            total_frac: publ.total,
            output_frac: publ.output,
            event_frac: publ.event,
            program: program.clone(),
            ranges,
            frac,
            consts,
            recip,
            mul_kind,
            sensor_frac,
            sensor_raw_range,
            state_frac,
            state_raw_range,
            state_init,
            deriv_gain,
            warnings,
        }
    }

    /// Plans one product `x · y` (each given as format and range, with the number of low
    /// bits known to be zero — a constant's trailing zeros — that shift off exactly): shift
    /// free bits first, then the operand with more significant bits, until the product fits
    /// 31 bits; accept when the floor shifts cost at most [`MULS_REL_TOLERANCE`] of the
    /// result's magnitude, else use the 64-bit product.
    fn plan_mul(
        (fx, rx): (i32, Interval),
        free_x: i32,
        (fy, ry): (i32, Interval),
        free_y: i32,
        result: Interval,
    ) -> MulKind {
        let bits = |f: i32, r: Interval| (r.mag() * 2f64.powi(f)).max(1.0).log2().ceil() as i32;
        let (mut a, mut b) = (0i32, 0i32);
        let (bx, by) = (bits(fx, rx), bits(fy, ry));
        while (bx - a) + (by - b) > 31 && a < 31 && b < 31 {
            if a < free_x {
                a += 1;
            } else if b < free_y {
                b += 1;
            } else if bx - a >= by - b {
                a += 1;
            } else {
                b += 1;
            }
        }
        let shift_err = |s: i32, f: i32, free: i32| if s <= free { 0.0 } else { 2f64.powi(s - f) };
        let (ex, ey) = (shift_err(a, fx, free_x), shift_err(b, fy, free_y));
        let err = ry.mag() * ex + rx.mag() * ey + ex * ey;
        if err <= MULS_REL_TOLERANCE * result.mag().max(f64::MIN_POSITIVE) {
            MulKind::Muls(a as u8, b as u8)
        } else {
            MulKind::Wide
        }
    }

    /// The exact (unquantised) value of a constant or param value, for comparisons.
    pub fn exact_const(&self, v: Value) -> Option<f64> {
        match self.program.values[v.index()].op {
            Op::Const(c) => Some(c),
            Op::Param(p) => Some(self.program.params[p.index()].value),
            _ => None,
        }
    }

    /// Number of multiplications of each kind and their estimated cycles on a Cortex-M0+.
    pub fn mul_cost(&self) -> (usize, usize, u32) {
        let muls = self
            .mul_kind
            .iter()
            .filter(|k| matches!(k, Some(MulKind::Muls(..))))
            .count();
        let wide = self
            .mul_kind
            .iter()
            .filter(|k| **k == Some(MulKind::Wide))
            .count();
        (
            muls,
            wide,
            muls as u32 * MulKind::Muls(0, 0).cycles() + wide as u32 * MulKind::Wide.cycles(),
        )
    }
}
