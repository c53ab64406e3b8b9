//! The body of a [`FixedProgram`] resolved once into a flat instruction list.
//!
//! The planner's search runs the fixed interpreter over tens of thousands of samples per
//! candidate plan; walking the IR's statement tree and matching each value's [`Op`], its
//! types and its plan (product form, reciprocal, constant operands) every sample cost more
//! than the arithmetic. [`Code::new`] does that matching once per instance: each statement
//! becomes one [`Ins`] with its operands' slots and its shifts resolved (the runtime's
//! [`tactus_runtime::fixed::resolved`] forms), an `if` a forward jump over its body. What has
//! no `i64` form (divisions, square roots, exponentials, derivatives, operands more than 31
//! bits apart) stays [`Ins::Slow`]: the value evaluated by the interpreter's definition on
//! the IR, as before.

use crate::fixed::{FixedProgram, MulKind};
use crate::ir::*;
use std::cmp::Ordering;
use tactus_runtime::fixed::resolved::{Align, Product, Threshold};

/// One resolved statement. Slots (`dst`, `x`, `y`, `c`, `v`) index the instance's words:
/// the program's values, then the constant operands [`Code::consts`] adds.
#[derive(Clone, Copy, Debug)]
pub(super) enum Ins {
    /// A word known when the plan is (a constant, a truth constant, a variant index).
    Word { dst: u32, w: i32 },
    /// Word `slot` of the key's param block (0 when the block is shorter).
    Param { dst: u32, slot: u32 },
    /// Sensor `s`'s word shifted by `sh` into the value's format.
    Sensor { dst: u32, s: u32, sh: i32 },
    /// State `s`'s word shifted by `sh` into the value's format.
    State { dst: u32, s: u32, sh: i32 },
    /// Mode `m`'s variant index.
    Mode { dst: u32, m: u32 },
    /// Edge `e`'s flag (0/1).
    Edge { dst: u32, e: u32 },
    /// `−x` shifted by `sh`.
    Neg { dst: u32, x: u32, sh: i32 },
    /// `|x|` shifted by `sh`.
    Abs { dst: u32, x: u32, sh: i32 },
    /// Logical not.
    Not { dst: u32, x: u32 },
    /// Logical and.
    And { dst: u32, x: u32, y: u32 },
    /// Logical or.
    Or { dst: u32, x: u32, y: u32 },
    /// `x + y`.
    Add { dst: u32, x: u32, y: u32, al: Align },
    /// `x − y`.
    Sub { dst: u32, x: u32, y: u32, al: Align },
    /// `x · y` in the operand order of the product's form ([`product`]; a division by a
    /// constant: one operand is its reciprocal's slot).
    Mul {
        dst: u32,
        x: u32,
        y: u32,
        p: Product,
    },
    /// A comparison of two words: 1 when the ordering's bit is set in `mask`
    /// ([`ordering_mask`]).
    Cmp {
        dst: u32,
        x: u32,
        y: u32,
        al: Align,
        mask: u8,
    },
    /// A comparison of a word with a real constant, exactly.
    CmpConst {
        dst: u32,
        x: u32,
        t: Threshold,
        mask: u8,
    },
    /// `c ? x : y`, the operand taken shifted by its `sh`.
    Select {
        dst: u32,
        c: u32,
        x: u32,
        y: u32,
        shx: i32,
        shy: i32,
    },
    /// `min(x, y)` (`min`) or `max(x, y)`, the operand taken shifted by its `sh`.
    MinMax {
        dst: u32,
        x: u32,
        y: u32,
        al: Align,
        shx: i32,
        shy: i32,
        min: bool,
    },
    /// A value the interpreter evaluates on the IR.
    Slow { dst: u32 },
    /// A state write: the word shifted by `sh`, clamped to `[lo, hi]` (counted when moved).
    SetState {
        st: u32,
        v: u32,
        sh: i32,
        lo: i32,
        hi: i32,
    },
    /// A mode write.
    SetMode { m: u32, i: u32 },
    /// An edge write (nonzero: set).
    SetEdge { e: u32, v: u32 },
    /// `if c`: when `c` is 0, continue at instruction `to` (the end of the body).
    Skip { c: u32, to: u32 },
    /// An event with the arguments [`Code::args`]`[start..start + n]`.
    Emit { e: u32, start: u32, n: u32 },
    /// A force term's word.
    Force { f: u32, v: u32 },
    /// An output's word.
    Output { o: u32, v: u32 },
    /// The total force's word.
    Total { v: u32 },
}

/// A fixed program's body resolved for the interpreter.
#[derive(Clone, Debug)]
pub(super) struct Code {
    /// The body's statements in order, `if` bodies inline.
    pub ins: Vec<Ins>,
    /// Each emit's arguments: slot and shift into the event's argument format.
    pub args: Vec<(u32, i32)>,
    /// Words of the constant operands (reciprocals of divisors), in the slots after the
    /// program's values.
    pub consts: Vec<i32>,
    /// The values the body defines outside every `if` as a word known per instance: a
    /// constant's ([`Ins::Word`]) or a param block's ([`Ins::Param`]). Written once when the
    /// instance is made instead of every sample (the piano's body: 79 of its 339 statements).
    pub preset: Vec<Ins>,
}

/// The bit of `ord` in a comparison's mask: 1 for less, 2 for equal, 4 for greater.
#[inline(always)]
pub(super) fn ordering_bit(ord: Ordering) -> u8 {
    1 << (ord as i8 + 1)
}

/// The orderings for which `op` holds, as a mask of [`ordering_bit`]s.
fn ordering_mask(op: CmpOp) -> u8 {
    let (lt, eq, gt) = (1, 2, 4);
    match op {
        CmpOp::Eq => eq,
        CmpOp::Ne => lt | gt,
        CmpOp::Lt => lt,
        CmpOp::Le => lt | eq,
        CmpOp::Gt => gt,
        CmpOp::Ge => gt | eq,
    }
}

impl Code {
    /// Resolves `fp`'s body. With `slow`, every value is [`Ins::Slow`] (the tests' reference).
    pub(super) fn new(fp: &FixedProgram, slow: bool) -> Self {
        let mut code = Code {
            ins: Vec::new(),
            args: Vec::new(),
            consts: Vec::new(),
            preset: Vec::new(),
        };
        code.stmts(fp, &fp.program.body, slow, true);
        code
    }

    /// Appends `body` (`top`: outside every `if`).
    fn stmts(&mut self, fp: &FixedProgram, body: &[Stmt], slow: bool, top: bool) {
        let slot = |v: &Value| v.0;
        let frac = |v: &Value| fp.frac[v.index()];
        for s in body {
            let ins = match s {
                Stmt::Def(v) => {
                    let ins = if slow { None } else { self.def(fp, *v) };
                    match ins {
                        Some(i @ (Ins::Word { .. } | Ins::Param { .. })) if top => {
                            self.preset.push(i);
                            continue;
                        }
                        Some(i) => i,
                        None => Ins::Slow { dst: v.0 },
                    }
                }
                Stmt::SetState(st, v) => {
                    let (lo, hi) = fp.state_raw_range[st.index()];
                    Ins::SetState {
                        st: st.0,
                        v: slot(v),
                        sh: fp.state_frac[st.index()] - frac(v),
                        lo,
                        hi,
                    }
                }
                Stmt::SetMode(m, i) => Ins::SetMode { m: m.0, i: *i },
                Stmt::SetEdge(e, v) => Ins::SetEdge { e: e.0, v: slot(v) },
                Stmt::If(c, inner) => {
                    let at = self.ins.len();
                    self.ins.push(Ins::Skip { c: slot(c), to: 0 });
                    self.stmts(fp, inner, slow, false);
                    let end = self.ins.len() as u32;
                    self.ins[at] = Ins::Skip {
                        c: slot(c),
                        to: end,
                    };
                    continue;
                }
                Stmt::Emit(e, args) => {
                    let start = self.args.len() as u32;
                    self.args.extend(
                        args.iter()
                            .zip(&fp.event_frac[e.index()])
                            .map(|(v, &f)| (slot(v), f - frac(v))),
                    );
                    Ins::Emit {
                        e: e.0,
                        start,
                        n: self.args.len() as u32 - start,
                    }
                }
                Stmt::Force(f, v) => Ins::Force { f: f.0, v: slot(v) },
                Stmt::Output(o, v) => Ins::Output { o: o.0, v: slot(v) },
                Stmt::Total(v) => Ins::Total { v: slot(v) },
            };
            self.ins.push(ins);
        }
    }

    /// The resolved definition of `v`, or `None` where the IR's evaluation stays.
    fn def(&mut self, fp: &FixedProgram, v: Value) -> Option<Ins> {
        let p = &fp.program;
        let dst = v.0;
        let fr = fp.frac[v.index()];
        let frac = |x: &Value| fp.frac[x.index()];
        let real = |w: &Value| matches!(p.values[w.index()].ty, Ty::Real(_));
        Some(match &p.values[v.index()].op {
            Op::Param(q) if fp.param_slot[q.index()].is_some() => Ins::Param {
                dst,
                slot: u32::try_from(fp.param_slot[q.index()]?).ok()?,
            },
            Op::Const(_) | Op::Param(_) => Ins::Word {
                dst,
                w: fp.consts[v.index()],
            },
            Op::BoolConst(t) => Ins::Word {
                dst,
                w: i32::from(*t),
            },
            Op::Variant(_, i) => Ins::Word { dst, w: *i as i32 },
            Op::Sensor(s) => Ins::Sensor {
                dst,
                s: s.0,
                sh: fr - fp.sensor_frac[s.index()],
            },
            Op::Deriv(..) => return None,
            Op::State(s) => Ins::State {
                dst,
                s: s.0,
                sh: fr - fp.state_frac[s.index()],
            },
            Op::Mode(m) => Ins::Mode { dst, m: m.0 },
            Op::Edge(e) => Ins::Edge { dst, e: e.0 },
            Op::Neg(x) => Ins::Neg {
                dst,
                x: x.0,
                sh: fr - frac(x),
            },
            Op::Not(x) => Ins::Not { dst, x: x.0 },
            Op::Arith(o, x, y) => {
                let (fa, fc) = (frac(x), frac(y));
                match o {
                    ArithOp::Add => Ins::Add {
                        dst,
                        x: x.0,
                        y: y.0,
                        al: Align::new(fa, fc, fr)?,
                    },
                    ArithOp::Sub => Ins::Sub {
                        dst,
                        x: x.0,
                        y: y.0,
                        al: Align::new(fa, fc, fr)?,
                    },
                    ArithOp::Mul => {
                        let (x, y, p) = product(fp.mul_kind[v.index()], (x.0, fa), (y.0, fc), fr);
                        Ins::Mul { dst, x, y, p }
                    }
                    ArithOp::Div => {
                        // A division by a constant: the product by its reciprocal word, which
                        // gets a constant slot; a run-time division stays on the IR.
                        let (w, fw) = fp.recip[v.index()]?;
                        let y = (p.values.len() + self.consts.len()) as u32;
                        self.consts.push(w);
                        let (x, y, p) = product(fp.mul_kind[v.index()], (x.0, fa), (y, fw), fr);
                        Ins::Mul { dst, x, y, p }
                    }
                }
            }
            Op::Cmp(o, x, y) => {
                let mask = ordering_mask(*o);
                match (fp.exact_const(*x), fp.exact_const(*y)) {
                    (_, Some(k)) if real(x) => Ins::CmpConst {
                        dst,
                        x: x.0,
                        t: Threshold::new(frac(x), k),
                        mask,
                    },
                    (Some(k), _) if real(y) => Ins::CmpConst {
                        dst,
                        x: y.0,
                        t: Threshold::new(frac(y), k),
                        // The constant on the left: the word's ordering reversed.
                        mask: [Ordering::Less, Ordering::Equal, Ordering::Greater]
                            .into_iter()
                            .filter(|&o| mask & ordering_bit(o.reverse()) != 0)
                            .map(ordering_bit)
                            .fold(0, |a, b| a | b),
                    },
                    _ => Ins::Cmp {
                        dst,
                        x: x.0,
                        y: y.0,
                        al: Align::new(frac(x), frac(y), 0)?,
                        mask,
                    },
                }
            }
            Op::And(x, y) => Ins::And {
                dst,
                x: x.0,
                y: y.0,
            },
            Op::Or(x, y) => Ins::Or {
                dst,
                x: x.0,
                y: y.0,
            },
            Op::Select(c, x, y) => {
                // A truth value or a variant passes unconverted.
                let sh = |w: &Value| if real(&v) { fr - frac(w) } else { 0 };
                Ins::Select {
                    dst,
                    c: c.0,
                    x: x.0,
                    y: y.0,
                    shx: sh(x),
                    shy: sh(y),
                }
            }
            Op::Call(func, x, y) => match func {
                Builtin::Abs => Ins::Abs {
                    dst,
                    x: x.0,
                    sh: fr - frac(x),
                },
                Builtin::Sqrt | Builtin::Exp => return None,
                Builtin::Min | Builtin::Max => {
                    let y = y.unwrap_or(*x);
                    Ins::MinMax {
                        dst,
                        x: x.0,
                        y: y.0,
                        al: Align::new(frac(x), frac(&y), 0)?,
                        shx: fr - frac(x),
                        shy: fr - frac(&y),
                        min: *func == Builtin::Min,
                    }
                }
            },
        })
    }
}

/// Whether a comparison's `mask` holds for `ord`, as a truth word.
#[inline(always)]
pub(super) fn holds(mask: u8, ord: Ordering) -> i32 {
    i32::from(mask & ordering_bit(ord) != 0)
}

/// The product `x·y` (slots with their fraction bits, in operand order) into `fr` fraction
/// bits in the form the plan chose (`kind`; `None`: the exact product), resolved: the slots
/// in the order the form's runtime function takes them (a 32×16 product's cut operand
/// second, [`crate::fixed::Cut::kept_cut`]) and the [`Product`]. The resolved twin of
/// [`super::product`], held to it by this module's tests.
fn product(kind: Option<MulKind>, x: (u32, i32), y: (u32, i32), fr: i32) -> (u32, u32, Product) {
    let ((sx, fx), (sy, fy)) = (x, y);
    match kind {
        Some(MulKind::Muls(a, b)) => (sx, sy, Product::shifted(fx, a, fy, b, fr)),
        Some(MulKind::High(k)) => (sx, sy, Product::high(fx, fy, k, fr)),
        Some(MulKind::Mul32x16 { cut, b, k }) => {
            let ((sa, fa), (sc, fc)) = cut.kept_cut(x, y);
            (sa, sc, Product::cut_32x16(fa, fc, b, k, fr))
        }
        _ => (sx, sy, Product::exact(fx, fy, fr)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixed::Cut;
    use proptest::prelude::*;
    use tactus_runtime::fixed::FRAC_RANGE;

    fn kind() -> impl Strategy<Value = Option<MulKind>> {
        prop_oneof![
            Just(None),
            Just(Some(MulKind::Wide)),
            (0u8..40, 0u8..40).prop_map(|(a, b)| Some(MulKind::Muls(a, b))),
            (0u8..40).prop_map(|k| Some(MulKind::High(k))),
            (any::<bool>(), 0u8..40, 0u8..20).prop_map(|(first, b, k)| {
                let cut = if first { Cut::First } else { Cut::Second };
                Some(MulKind::Mul32x16 { cut, b, k })
            }),
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(5_000))]

        /// A resolved product, its operands taken from the slots it names, is the
        /// interpreter's product on the IR (every form, either cut operand).
        #[test]
        fn products_resolve_as_the_ir_dispatches(
            x in any::<i32>(), y in any::<i32>(),
            fx in FRAC_RANGE.0..FRAC_RANGE.1, fy in FRAC_RANGE.0..FRAC_RANGE.1,
            fr in FRAC_RANGE.0..FRAC_RANGE.1, kind in kind(),
        ) {
            let words = [x, y];
            let (a, c, p) = product(kind, (0, fx), (1, fy), fr);
            prop_assert_eq!(
                p.eval(words[a as usize], words[c as usize]),
                super::super::product(kind, (x, fx), (y, fy), fr)
            );
        }
    }
}
