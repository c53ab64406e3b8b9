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

/// Computes the interval of every value of `p`, a state read bounded by its declared range.
pub fn analyse(p: &Program) -> Ranges {
    analyse_with(p, &declared(p))
}

/// Each state's declared range, as an interval.
fn declared(p: &Program) -> Vec<Interval> {
    p.states
        .iter()
        .map(|s| Interval::new(s.range.0, s.range.1))
        .collect()
}

/// [`analyse`] with each state read bounded by `states` (one interval per state).
fn analyse_with(p: &Program, states: &[Interval]) -> Ranges {
    let mut values = vec![Interval::point(0.0); p.values.len()];
    let mut clamped = Vec::new();
    walk_stmts(&p.body, &mut |s| {
        let Stmt::Def(v) = s else { return };
        let iv = interval(p, &p.values[v.index()].op, &values, states);
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
    });
    Ranges { values, clamped }
}

/// Rounds of [`state_hulls`]' iteration after which a state whose interval still grows
/// takes its whole declared range.
pub const NARROWING_ROUNDS: usize = 6;

/// Relative margin (of the hull's magnitude) added to each side of a narrowed state's hull
/// that lies inside its declared range, so that a word rounded up at the hull's end (a
/// product rounded half up) is not saturated: 2^-20.
pub const NARROWING_MARGIN: f64 = 1.0 / (1u64 << 20) as f64;

/// Per state of `p`, the interval it can hold: for a state that only `if` bodies write (an
/// event's or a `while`'s: never integrated, never written every sample) the hull of its
/// initial value and of every value assigned to it, saturated to its declared range (with
/// [`NARROWING_MARGIN`] inside it); for any other state its declared range. The hulls are a
/// fixed point of the interval analysis: starting from the initial values, each round
/// analyses the body with the states bounded by the current hulls and joins what the
/// writes can assign; a state still growing after [`NARROWING_ROUNDS`] rounds takes its
/// declared range, so the iteration ends; when no hull grows, every write lies in its
/// state's hull given that every state read does, and by induction over samples (the
/// initial values lie in the hulls) every state stays in its hull (Cousot & Cousot,
/// *Abstract interpretation*, POPL 1977: a post-fixed point of a monotone abstract
/// transformer, with widening to the declared range). The piano's escapement records the
/// deepest key travel `xmax = x`: its hull is the key's range `[0, 10 mm]`, half of the
/// declared `[0, 20 mm]`, so it takes the key's format and its compares and its store need
/// no alignment shift.
pub fn state_hulls(p: &Program) -> Vec<(f64, f64)> {
    let ns = p.states.len();
    let declared = declared(p);
    let top_level = crate::ir::states_set_every_sample(&p.body, ns);
    let mut writes: Vec<(usize, Value)> = Vec::new();
    walk_stmts(&p.body, &mut |s| {
        if let Stmt::SetState(st, v) = s {
            writes.push((st.index(), *v));
        }
    });
    let saturate = |iv: Interval, d: Interval| {
        let c = |x: f64| {
            if x.is_nan() {
                d.lo
            } else {
                x.clamp(d.lo, d.hi)
            }
        };
        Interval::new(c(iv.lo), c(iv.hi))
    };
    let mut hull: Vec<Interval> = (0..ns)
        .map(|i| {
            if top_level[i] || !(declared[i].lo.is_finite() && declared[i].hi.is_finite()) {
                declared[i]
            } else {
                saturate(Interval::point(p.states[i].init), declared[i])
            }
        })
        .collect();
    let mut round = 0;
    loop {
        let values = analyse_with(p, &hull).values;
        let mut next = hull.clone();
        for &(st, v) in &writes {
            next[st] = next[st].union(saturate(values[v.index()], declared[st]));
        }
        if next == hull {
            break;
        }
        round += 1;
        for i in 0..ns {
            if next[i] != hull[i] && round >= NARROWING_ROUNDS {
                next[i] = declared[i];
            }
        }
        hull = next;
    }
    hull.iter()
        .zip(&declared)
        .map(|(h, d)| {
            let m = NARROWING_MARGIN * h.mag();
            (d.lo.max(h.lo - m), d.hi.min(h.hi + m))
        })
        .collect()
}

fn interval(p: &Program, op: &Op, v: &[Interval], states: &[Interval]) -> Interval {
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
        Op::State(s) => states[s.index()],
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
