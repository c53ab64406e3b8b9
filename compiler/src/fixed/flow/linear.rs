//! Linear facts between the values of one sample: can two conditions both hold?
//!
//! Intervals alone forget that two values move together: after `xmax = x`, the test
//! `x < xmax - slack` is false whatever `x` is, yet both sides span the same interval. Here
//! every real value of the sample is an *affine form* over atoms — the sensor words, their
//! derivatives, run-time params, each state's word at the start of the sample, and a fresh
//! atom for what is not linear (a product of two variables, a `min`, a clamped store) —
//! plus an interval of constant terms. A comparison that must hold becomes a linear
//! constraint `Σ aᵢ·tᵢ + c ≥ 0`, and bound propagation over the atoms' intervals (each
//! constraint bounds each of its atoms by the others' extremes, to a fixed point) proves
//! the conjunction empty or gives up. A state read after a store that certainly ran is the
//! stored value's form (the store's clamp, where live, links a fresh atom to it: once the
//! read is known off a range end, the form is within the rounding of the read).
//!
//! **What the forms mean.** A form describes the *exact* result of the value's operations
//! on the sample's words (state, sensor and param words as read, constants as written);
//! the fixed engines' word lies within [`super::super::report::local_errors`] of it. A
//! comparison of two words is therefore turned into a constraint on the forms with a margin
//! of twice both operands' error bounds plus a unit of the coarser format (the
//! comparison floors the finer word to the coarser grid); a value without a finite error
//! bound gives no constraint. So every fact proven here holds for every engine.

use super::super::range::Interval;
use super::super::FixedProgram;
use super::{Eval, Tri};
use crate::ir::*;
use std::collections::HashMap;

/// The most rounds of bound propagation per question (each round visits every
/// constraint; the piano's questions settle in two or three).
const MAX_ROUNDS: usize = 40;

/// Largest program (values × top-level statements, and states × top-level statements)
/// for which the linear facts are sought: beyond, [`super::exclusions`] keeps to intervals.
pub(super) const MAX_WORK: usize = 4_000_000;

/// An affine form `c + Σ coef·atom` (constant part an interval, SI).
#[derive(Clone, Debug)]
struct Form {
    c: Interval,
    terms: Vec<(usize, f64)>,
}

impl Form {
    fn constant(c: Interval) -> Form {
        Form {
            c,
            terms: Vec::new(),
        }
    }
    fn atom(a: usize) -> Form {
        Form {
            c: Interval::point(0.0),
            terms: vec![(a, 1.0)],
        }
    }
    /// `self + k·o`.
    fn add_scaled(&self, o: &Form, k: f64) -> Form {
        let mut terms = self.terms.clone();
        for &(a, x) in &o.terms {
            match terms.iter_mut().find(|t| t.0 == a) {
                Some(t) => t.1 += k * x,
                None => terms.push((a, k * x)),
            }
        }
        terms.retain(|t| t.1 != 0.0);
        let (p, q) = (k * o.c.lo, k * o.c.hi);
        Form {
            c: Interval::new(self.c.lo + p.min(q), self.c.hi + p.max(q)),
            terms,
        }
    }
    fn scale(&self, k: f64) -> Form {
        Form::constant(Interval::point(0.0)).add_scaled(self, k)
    }
    fn widen(mut self, d: f64) -> Form {
        self.c = Interval::new(self.c.lo - d, self.c.hi + d);
        self
    }
}

/// Where a state read's word comes from in the scenario being examined.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Source {
    /// The word the sample started with.
    Initial,
    /// The word a store that certainly ran left: this value, clamped and rounded.
    Stored(Value),
    /// Something a store that may or may not have run left: reads of the same version (no
    /// store in between) read the same word.
    Unknown(u32),
    /// A read inside an `if` body that writes the state itself.
    Inside,
}

/// What each state holds before each top-level statement (`snap`, filled in order by
/// [`Sources::before`] and [`Sources::apply`]) in the scenario being examined.
pub(super) struct Sources {
    cur: Vec<Source>,
    version: u32,
    /// Per top-level statement so far, what each state holds before it.
    pub(super) snap: Vec<Vec<Source>>,
}

impl Sources {
    pub(super) fn new(p: &Program) -> Self {
        Sources {
            cur: vec![Source::Initial; p.states.len()],
            version: 0,
            snap: Vec::with_capacity(p.body.len()),
        }
    }

    /// Records what holds before the next top-level statement.
    pub(super) fn before(&mut self) {
        self.snap.push(self.cur.clone());
    }

    /// The effect of top-level statement `s`: an `if` whose body certainly runs (`sure`),
    /// cannot run (`skip`: nothing changes), or may run (what it writes is unknown).
    pub(super) fn apply(&mut self, s: &Stmt, sure: bool, skip: bool) {
        match s {
            Stmt::SetState(st, v) => self.cur[st.index()] = Source::Stored(*v),
            Stmt::If(..) if skip => {}
            Stmt::If(_, body) if sure => {
                for t in body {
                    match t {
                        Stmt::SetState(st, v) => self.cur[st.index()] = Source::Stored(*v),
                        Stmt::If(..) => {
                            forget(std::slice::from_ref(t), &mut self.cur, &mut self.version)
                        }
                        _ => {}
                    }
                }
            }
            Stmt::If(..) => forget(std::slice::from_ref(s), &mut self.cur, &mut self.version),
            _ => {}
        }
    }
}

/// Marks every state `stmts` may write (at any depth) unknown, each with a new version.
fn forget(stmts: &[Stmt], cur: &mut [Source], version: &mut u32) {
    walk_stmts(stmts, &mut |t| {
        if let Stmt::SetState(st, _) = t {
            *version += 1;
            cur[st.index()] = Source::Unknown(*version);
        }
    });
}

/// Whether the `if` at top-level position `k` writes state `st` anywhere in its body.
fn body_writes(p: &Program, k: usize, st: usize) -> bool {
    let Some(Stmt::If(_, body)) = p.body.get(k) else {
        return false;
    };
    let mut w = false;
    walk_stmts(body, &mut |t| {
        if let Stmt::SetState(s, _) = t {
            w |= s.index() == st;
        }
    });
    w
}

#[derive(Clone, Copy, PartialEq, Eq, Hash)]
enum Leaf {
    Sensor(u32),
    Deriv(u32, u8),
    Param(u32),
    State(u32),
    /// A state's word after a store that may have run (version of [`Source::Unknown`]).
    Version(u32, u32),
    /// A state's word after a store that certainly ran (the stored value).
    Stored(u32, u32),
}

/// A clamped store's read: atom `read` = clamp(`form` ± `d`) into `[lo, hi]`.
struct Link {
    read: usize,
    form: Form,
    d: f64,
    lo: f64,
    hi: f64,
}

/// The linear view of one scenario: the forms of the values, the atoms' intervals, the
/// constraints gathered.
pub(super) struct Linear<'a, 'e> {
    fp: &'a FixedProgram,
    err: &'a [f64],
    ev: &'e Eval<'a>,
    src: &'a [Vec<Source>],
    atoms: Vec<Interval>,
    leaves: HashMap<Leaf, usize>,
    forms: HashMap<Value, Form>,
    /// The form of a state's read after a store that certainly ran, per state and value.
    stored: HashMap<Leaf, Form>,
    links: Vec<Link>,
    cons: Vec<Form>,
    /// A constraint with no atoms that cannot hold was met.
    empty: bool,
}

impl<'a, 'e> Linear<'a, 'e> {
    /// `err`: [`super::super::report::local_errors`]; `ev`: the interval evaluation of the
    /// same scenario (modes, select conditions); `src`: [`Sources::snap`] of the scenario.
    pub(super) fn new(
        fp: &'a FixedProgram,
        err: &'a [f64],
        ev: &'e Eval<'a>,
        src: &'a [Vec<Source>],
    ) -> Self {
        Linear {
            fp,
            err,
            ev,
            src,
            atoms: Vec::new(),
            leaves: HashMap::new(),
            forms: HashMap::new(),
            stored: HashMap::new(),
            links: Vec::new(),
            cons: Vec::new(),
            empty: false,
        }
    }

    fn fresh(&mut self, i: Interval) -> usize {
        self.atoms.push(i);
        self.atoms.len() - 1
    }

    fn leaf(&mut self, k: Leaf, i: Interval) -> Form {
        let a = match self.leaves.get(&k) {
            Some(&a) => a,
            None => {
                let a = self.fresh(i);
                self.leaves.insert(k, a);
                a
            }
        };
        Form::atom(a)
    }

    /// The range of a form over the atoms' current intervals.
    fn eval(&self, f: &Form) -> Interval {
        let (mut lo, mut hi) = (f.c.lo, f.c.hi);
        for &(a, k) in &f.terms {
            let t = self.atoms[a];
            let (p, q) = (k * t.lo, k * t.hi);
            lo += p.min(q);
            hi += p.max(q);
        }
        Interval::new(lo, hi)
    }

    fn range(&self, v: Value) -> Interval {
        self.fp.ranges.values[v.index()]
    }

    /// The affine form of `v` (a fresh atom over its analysed range where it is not linear).
    fn form(&mut self, v: Value, depth: u32) -> Form {
        if let Some(f) = self.forms.get(&v) {
            return f.clone();
        }
        let f = self.form_uncached(v, depth);
        self.forms.insert(v, f.clone());
        f
    }

    fn form_uncached(&mut self, v: Value, depth: u32) -> Form {
        let p = &self.fp.program;
        let r = self.range(v);
        if depth > 200 {
            let a = self.fresh(r);
            return Form::atom(a);
        }
        match p.values[v.index()].op {
            Op::Const(c) => Form::constant(Interval::point(c)),
            Op::Param(id) => match self.fp.exact_const(v) {
                Some(c) => Form::constant(Interval::point(c)),
                None => self.leaf(Leaf::Param(id.index() as u32), r),
            },
            Op::Sensor(id) => self.leaf(Leaf::Sensor(id.index() as u32), r),
            Op::Deriv(id, n) => self.leaf(Leaf::Deriv(id.index() as u32, n), r),
            Op::State(st) => self.state_read(v, st.index(), depth),
            Op::Neg(x) => self.form(x, depth + 1).scale(-1.0),
            Op::Arith(o, x, y) => {
                let (fx, fy) = (self.form(x, depth + 1), self.form(y, depth + 1));
                match o {
                    ArithOp::Add => fx.add_scaled(&fy, 1.0),
                    ArithOp::Sub => fx.add_scaled(&fy, -1.0),
                    ArithOp::Mul if fy.terms.is_empty() => self.times(&fx, fy.c, r),
                    ArithOp::Mul if fx.terms.is_empty() => self.times(&fy, fx.c, r),
                    ArithOp::Div if fy.terms.is_empty() && (fy.c.lo > 0.0 || fy.c.hi < 0.0) => {
                        let q = [1.0 / fy.c.lo, 1.0 / fy.c.hi];
                        self.times(&fx, Interval::new(q[0].min(q[1]), q[0].max(q[1])), r)
                    }
                    _ => {
                        let a = self.fresh(r);
                        Form::atom(a)
                    }
                }
            }
            Op::Select(c, x, y) => match self.ev.tri(c) {
                Tri::True => self.form(x, depth + 1),
                Tri::False => self.form(y, depth + 1),
                Tri::Unknown => {
                    let a = self.fresh(r);
                    Form::atom(a)
                }
            },
            _ => {
                let a = self.fresh(r);
                Form::atom(a)
            }
        }
    }

    /// `f · [k.lo, k.hi]`: the midpoint times the form, plus the radius times the form's
    /// largest magnitude as a constant interval (exact for a point `k`).
    fn times(&mut self, f: &Form, k: Interval, r: Interval) -> Form {
        if !(k.lo.is_finite() && k.hi.is_finite()) {
            let a = self.fresh(r);
            return Form::atom(a);
        }
        let mid = 0.5 * (k.lo + k.hi);
        let rad = 0.5 * (k.hi - k.lo);
        let out = f.scale(mid);
        if rad == 0.0 {
            out
        } else {
            let m = rad * self.eval(f).mag();
            out.widen(m)
        }
    }

    fn state_read(&mut self, v: Value, st: usize, depth: u32) -> Form {
        let p = &self.fp.program;
        let r = self.range(v);
        let at = self.ev.pos[v.index()];
        let source = if body_writes(p, at, st) {
            Source::Inside
        } else {
            self.src.get(at).map_or(Source::Inside, |s| s[st])
        };
        match source {
            Source::Initial => self.leaf(Leaf::State(st as u32), r),
            Source::Unknown(n) => self.leaf(Leaf::Version(st as u32, n), r),
            Source::Inside => {
                let a = self.fresh(r);
                Form::atom(a)
            }
            Source::Stored(x) => {
                if let Some(f) = self.stored.get(&Leaf::Stored(st as u32, x.index() as u32)) {
                    return f.clone();
                }
                let frac = self.fp.state_frac[st];
                let round = if frac < self.fp.frac[x.index()] {
                    0.5 * 2f64.powi(-frac)
                } else {
                    0.0
                };
                let d = self.err[x.index()] + round;
                let (rlo, rhi) = self.fp.state_raw_range[st];
                let scale = 2f64.powi(-frac);
                let (lo, hi) = (rlo as f64 * scale, rhi as f64 * scale);
                let fx = self.form(x, depth + 1);
                let key = Leaf::Stored(st as u32, x.index() as u32);
                if !d.is_finite() {
                    return self.leaf(key, r);
                }
                let e = self.eval(&fx);
                let f = if e.lo - d >= lo && e.hi + d <= hi {
                    // The clamp cannot act: the read is the stored value, within rounding.
                    fx.widen(d)
                } else {
                    let i = Interval::new((e.lo - d).clamp(lo, hi), (e.hi + d).clamp(lo, hi));
                    let a = self.fresh(i);
                    self.links.push(Link {
                        read: a,
                        form: fx,
                        d,
                        lo,
                        hi,
                    });
                    Form::atom(a)
                };
                self.stored.insert(key, f.clone());
                f
            }
        }
    }

    /// Adds what `cond` being true says: each `and`-ed comparison of real values as a
    /// linear constraint.
    pub(super) fn assume(&mut self, cond: Value) {
        for (o, x, y) in super::real_comparisons(&self.fp.program, cond) {
            let m = self.margin(x, y);
            if !m.is_finite() {
                continue;
            }
            let (fx, fy) = (self.form(x, 0), self.form(y, 0));
            // x ≥ y: x − y + m ≥ 0; x ≤ y: y − x + m ≥ 0.
            let ge = fx.add_scaled(&fy, -1.0).widen(m);
            let le = fy.add_scaled(&fx, -1.0).widen(m);
            match o {
                CmpOp::Ge | CmpOp::Gt => self.cons.push(ge),
                CmpOp::Le | CmpOp::Lt => self.cons.push(le),
                CmpOp::Eq => {
                    self.cons.push(ge);
                    self.cons.push(le);
                }
                CmpOp::Ne => {}
            }
        }
    }

    /// Adds what `cond` being false says, where that is one comparison of real values
    /// (`not (x < y)`: `x >= y`); returns whether it could.
    pub(super) fn assume_not(&mut self, cond: Value) -> bool {
        let p = &self.fp.program;
        let Op::Cmp(o, x, y) = p.values[cond.index()].op else {
            return false;
        };
        if !matches!(p.values[x.index()].ty, Ty::Real(_)) {
            return false;
        }
        let m = self.margin(x, y);
        if !m.is_finite() {
            return false;
        }
        let (fx, fy) = (self.form(x, 0), self.form(y, 0));
        match o {
            // not (x < y), not (x <= y): x ≥ y (within the margin).
            CmpOp::Lt | CmpOp::Le => self.cons.push(fx.add_scaled(&fy, -1.0).widen(m)),
            CmpOp::Gt | CmpOp::Ge => self.cons.push(fy.add_scaled(&fx, -1.0).widen(m)),
            CmpOp::Eq | CmpOp::Ne => return false,
        }
        true
    }

    /// How far apart the exact forms of `x` and `y` may be when their words compare the
    /// other way: twice both error bounds, plus a unit of the coarser format, plus 10⁻⁹ of
    /// the magnitudes for the propagation's own float rounding.
    fn margin(&self, x: Value, y: Value) -> f64 {
        let (ex, ey) = (self.err[x.index()], self.err[y.index()]);
        let f = self.fp.frac[x.index()].min(self.fp.frac[y.index()]);
        let mag = self.range(x).mag().max(self.range(y).mag());
        2.0 * (ex + ey) + 2f64.powi(-f) + 1e-9 * mag
    }

    /// Whether the constraints gathered cannot all hold (bound propagation finds an atom's
    /// interval empty, or a constraint that cannot be met).
    pub(super) fn infeasible(&mut self) -> bool {
        if self.empty {
            return true;
        }
        for _ in 0..MAX_ROUNDS {
            let mut changed = false;
            // Clamp links: the read within the clamp of its form, and off a range end the
            // form within rounding of the read.
            let mut extra = Vec::new();
            for l in &self.links {
                let e = self.eval(&l.form);
                let t = self.atoms[l.read];
                let i = Interval::new(
                    t.lo.max((e.lo - l.d).clamp(l.lo, l.hi)),
                    t.hi.min((e.hi + l.d).clamp(l.lo, l.hi)),
                );
                if i != t {
                    changed = true;
                    self.atoms[l.read] = i;
                }
                if i.lo > l.hi || i.lo > i.hi {
                    return true;
                }
                if i.lo > l.lo {
                    // read > lo ⇒ read ≤ form + d: form − read + d ≥ 0.
                    extra.push(l.form.add_scaled(&Form::atom(l.read), -1.0).widen(l.d));
                }
                if i.hi < l.hi {
                    // read < hi ⇒ read ≥ form − d: read − form + d ≥ 0.
                    extra.push(Form::atom(l.read).add_scaled(&l.form, -1.0).widen(l.d));
                }
            }
            let cons: Vec<Form> = self.cons.iter().cloned().chain(extra).collect();
            for c in &cons {
                let e = self.eval(c);
                let tol = 1e-12 * (e.lo.abs() + e.hi.abs());
                if e.hi < -tol {
                    return true;
                }
                for &(a, k) in &c.terms {
                    let t = self.atoms[a];
                    // The rest's largest value: e.hi minus this term's largest.
                    let own = (k * t.lo).max(k * t.hi);
                    let rest = e.hi - own;
                    // k·t ≥ −rest.
                    let bound = -rest / k;
                    let slack = 1e-12 * (bound.abs() + t.mag());
                    let n = if k > 0.0 {
                        Interval::new(t.lo.max(bound - slack), t.hi)
                    } else {
                        Interval::new(t.lo, t.hi.min(bound + slack))
                    };
                    if n.lo > n.hi {
                        return true;
                    }
                    let moved = (n.lo - t.lo).abs().max((n.hi - t.hi).abs());
                    if moved > 1e-9 * t.mag().max(1e-30) {
                        changed = true;
                        self.atoms[a] = n;
                    }
                }
            }
            if !changed {
                break;
            }
        }
        false
    }
}
