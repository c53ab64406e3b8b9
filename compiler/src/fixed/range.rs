//! Interval range analysis over the IR.
//!
//! Every value gets a closed interval that contains every value it can take at run time.
//! The analysis is one forward pass: sensor readings and state writes are saturated to their
//! declared ranges (see [`crate::interp`]), so a state read is bounded by its declaration and
//! no feedback loop needs iterating. Sources: interval arithmetic as in Moore, *Interval
//! Analysis* (1966); bounds are widened by a relative 1e-12 to cover f64 rounding of the
//! bounds themselves.
//!
//! A value whose interval is unbounded (a division by an interval containing 0, `exp` of a
//! large argument) is **clamped** to [`UNBOUNDED_CLAMP`] in its own unit: the fixed-point
//! code saturates there, and the analysis reports it as a warning with the span.

use crate::ir::*;
use tactus_runtime::differentiator::WINDOW;

/// Magnitude at which an unbounded value is clamped (and saturates at run time), SI.
pub const UNBOUNDED_CLAMP: f64 = 1.0e6;

/// A closed interval `[lo, hi]` (SI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Lower bound.
    pub lo: f64,
    /// Upper bound.
    pub hi: f64,
}

impl Interval {
    /// `[lo, hi]`.
    pub fn new(lo: f64, hi: f64) -> Self {
        Interval { lo, hi }
    }
    /// `[v, v]`.
    pub fn point(v: f64) -> Self {
        Interval { lo: v, hi: v }
    }
    /// The largest magnitude.
    pub fn mag(self) -> f64 {
        self.lo.abs().max(self.hi.abs())
    }
    fn union(self, o: Interval) -> Interval {
        Interval::new(self.lo.min(o.lo), self.hi.max(o.hi))
    }
    fn widen(self) -> Interval {
        let e = 1e-12;
        Interval::new(self.lo - self.lo.abs() * e, self.hi + self.hi.abs() * e)
    }
    fn bounded(self) -> bool {
        self.lo.is_finite() && self.hi.is_finite() && self.mag() <= UNBOUNDED_CLAMP
    }
    fn contains_zero(self) -> bool {
        self.lo <= 0.0 && self.hi >= 0.0
    }
}

fn products(a: Interval, b: Interval) -> Interval {
    let c = [a.lo * b.lo, a.lo * b.hi, a.hi * b.lo, a.hi * b.hi];
    let c = c.map(|x| if x.is_nan() { 0.0 } else { x });
    Interval::new(
        c.iter().cloned().fold(f64::INFINITY, f64::min),
        c.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
    )
}

/// The result of the analysis.
#[derive(Clone, Debug)]
pub struct Ranges {
    /// One interval per value (truth values `[0, 1]`, modes `[0, n-1]`).
    pub values: Vec<Interval>,
    /// Values whose interval had to be clamped (saturation inserted), in body order.
    pub clamped: Vec<Value>,
}

/// The interval of `d()` (order 1) or `d2()` (order 2) of a sensor with range `[lo, hi]`
/// at sample rate `fs`: the differentiator formulas of `tactus_runtime::differentiator`.
pub fn deriv_interval(lo: f64, hi: f64, order: u8, fs: f64) -> Interval {
    let span = hi - lo;
    let r = fs / WINDOW as f64;
    match order {
        1 => Interval::new(-span * r, span * r),
        _ => Interval::new(-2.0 * span * r * r, 2.0 * span * r * r),
    }
}

/// Computes the interval of every value of `p`.
pub fn analyse(p: &Program) -> Ranges {
    let mut values = vec![Interval::point(0.0); p.values.len()];
    let mut clamped = Vec::new();
    fn walk(p: &Program, stmts: &[Stmt], values: &mut [Interval], clamped: &mut Vec<Value>) {
        for s in stmts {
            match s {
                Stmt::Def(v) => {
                    let iv = interval(p, &p.values[v.index()].op, values);
                    let iv = iv.widen();
                    values[v.index()] = if iv.bounded() {
                        iv
                    } else {
                        clamped.push(*v);
                        let c = UNBOUNDED_CLAMP;
                        let lo = if iv.lo.is_nan() {
                            -c
                        } else {
                            iv.lo.clamp(-c, c)
                        };
                        let hi = if iv.hi.is_nan() {
                            c
                        } else {
                            iv.hi.clamp(-c, c)
                        };
                        Interval::new(lo.min(hi), hi.max(lo))
                    };
                }
                Stmt::If(_, body) => walk(p, body, values, clamped),
                _ => {}
            }
        }
    }
    walk(p, &p.body, &mut values, &mut clamped);
    Ranges { values, clamped }
}

fn interval(p: &Program, op: &Op, v: &[Interval]) -> Interval {
    let g = |x: &Value| v[x.index()];
    let unit = Interval::new(0.0, 1.0);
    match op {
        Op::Const(c) => Interval::point(*c),
        Op::BoolConst(b) => Interval::point(if *b { 1.0 } else { 0.0 }),
        Op::Variant(_, i) => Interval::point(*i as f64),
        Op::Param(id) => match p.params[id.index()].runtime {
            Some((lo, hi)) => Interval::new(lo, hi),
            None => Interval::point(p.params[id.index()].value),
        },
        Op::Sensor(s) => {
            let r = p.sensors[s.index()].range;
            Interval::new(r.0, r.1)
        }
        Op::Deriv(s, order) => {
            let r = p.sensors[s.index()].range;
            deriv_interval(r.0, r.1, *order, p.sample_rate_hz)
        }
        Op::State(s) => {
            let r = p.states[s.index()].range;
            Interval::new(r.0, r.1)
        }
        Op::Mode(m) => Interval::new(0.0, (p.modes[m.index()].variants.len().max(1) - 1) as f64),
        Op::Edge(_) | Op::Not(_) | Op::Cmp(..) | Op::And(..) | Op::Or(..) => unit,
        Op::Neg(x) => Interval::new(-g(x).hi, -g(x).lo),
        Op::Arith(o, x, y) => {
            let (a, b) = (g(x), g(y));
            match o {
                ArithOp::Add => Interval::new(a.lo + b.lo, a.hi + b.hi),
                ArithOp::Sub => Interval::new(a.lo - b.hi, a.hi - b.lo),
                ArithOp::Mul => products(a, b),
                ArithOp::Div => {
                    if b.contains_zero() {
                        Interval::new(f64::NEG_INFINITY, f64::INFINITY)
                    } else {
                        products(a, Interval::new(1.0 / b.hi, 1.0 / b.lo))
                    }
                }
            }
        }
        Op::Select(_, x, y) => g(x).union(g(y)),
        Op::Call(f, x, y) => {
            let a = g(x);
            let b = y.map(|y| g(&y)).unwrap_or(a);
            match f {
                Builtin::Abs => {
                    if a.contains_zero() {
                        Interval::new(0.0, a.mag())
                    } else {
                        Interval::new(a.lo.abs().min(a.hi.abs()), a.mag())
                    }
                }
                Builtin::Sqrt => Interval::new(a.lo.max(0.0).sqrt(), a.hi.max(0.0).sqrt()),
                Builtin::Exp => Interval::new(a.lo.exp(), a.hi.exp()),
                Builtin::Min => Interval::new(a.lo.min(b.lo), a.hi.min(b.hi)),
                Builtin::Max => Interval::new(a.lo.max(b.lo), a.hi.max(b.hi)),
            }
        }
    }
}
