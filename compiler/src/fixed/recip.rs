//! Reciprocals of divisor states: a division by a state that only events set becomes a
//! product with a hidden word holding the state's reciprocal, recomputed only where the
//! state is assigned.
//!
//! The grand piano's impact pulse decays as `pulse' = -pulse / tau`, a run-time division
//! every sample (≈ 60 cycles on the RP2040's SIO divider), although `tau` changes only at
//! the hammer–key impact and at the rest felt. Before the format plan (beside
//! [`super::common`], so the fixed interpreter, the fixed JIT, the C and the Thumb backends
//! run the same program and stay bit-exact; the f64 reference keeps the plain division and
//! defines the meaning) a state `s` is given a reciprocal when
//! - the program divides by it (`x / s`),
//! - it has no dynamics: every write is inside an `if` body (an event or `while` body), so
//!   the writes run only when it changes, not every sample,
//! - its declared range excludes 0 (a range through 0 has no bounded reciprocal: refused).
//!
//! Then the fixed program gets a hidden state `1/s` after the declared ones: range
//! `[1/hi, 1/lo]`, initial value `1/init`. Every `x / s` becomes `x · (1/s)`, and every
//! assignment `s = v` is followed by `1/s = r(v)`, with the algebra done symbolically where
//! it removes a division: `r(constant) = 1/constant` folded (a compile-time param is a
//! constant), `r(a / b) = b / a` — a product when `a` is a constant, which the plan turns
//! into a multiplication by its reciprocal (a run-time param `a` is a run-time division,
//! as every division by a run-time param outside [`crate::share`] is) — and otherwise one
//! division `1 / max(v, lo/2)` (for a negative range `1 / min(v, hi/2)`) at the
//! assignment, which runs only when `s` changes.
//!
//! **Saturation.** Every engine saturates a state write to the state's declared range. On a
//! range of one sign `x ↦ 1/x` is monotonic, so for a value `v` of that sign
//! `clamp(1/v, 1/hi, 1/lo) = 1/clamp(v, lo, hi)`: saturating the reciprocal's write to its
//! range is saturating the state's, up to the rounding of the two bounds (half an LSB of
//! the reciprocal's format). The symbolic forms are used only where the range analysis
//! proves `v` on the side of 0 the range is on; elsewhere (`v` may be 0 or of the other sign,
//! where the state saturates to its bound nearer 0 but `1/v` would saturate to the wrong
//! end) `v` is first limited to half that bound, on the range's side of 0: a value below
//! the bound still gives a reciprocal beyond `1/lo`, which saturates to `1/lo`. So the
//! reciprocal saturates exactly when the state would (the fixed engines count a carried
//! state's saturations as its reciprocal's), and a folded constant outside the range is
//! left to saturate the same way.
//!
//! **Carried states.** When the divisions were the state's only reads, the fixed program
//! reads the declared state nowhere; its writes (and what only they computed: the piano's
//! `pulse_tau / (1 + …)`, a second division) are dropped, and the state is *carried by its
//! reciprocal*: its word keeps the initial value and its value is `1 / (1/s)`
//! ([`super::FixedProgram::states_si`], what traces of the fixed engines show).

use super::range;
use crate::ast::Span;
use crate::ir::*;
use crate::units::Dim;
use std::collections::HashMap;

/// A state whose divisions became products with its reciprocal.
#[derive(Clone, Debug, PartialEq)]
pub struct Reciprocal {
    /// The declared state.
    pub state: StateId,
    /// The hidden state holding `1/state` (after the declared states).
    pub recip: StateId,
    /// Source spans of the divisions by the state that became products.
    pub divisions: Vec<Span>,
    /// Per assignment of the state (the assigned expression's span): whether a run-time
    /// division remains there to recompute the reciprocal.
    pub writes: Vec<(Span, bool)>,
    /// Whether the declared state is read nowhere else, so that the fixed program no longer
    /// writes it (see the module documentation).
    pub carried: bool,
    /// Source spans of the run-time divisions that only the dropped writes of a carried
    /// state computed (they are gone too).
    pub dropped: Vec<Span>,
    /// The constant `k` the hidden word is scaled by: it holds `k/state`. 1, unless every
    /// division by the state is read only by a product by the same constant `k` (the
    /// dynamics' `· h`), which then disappears: `(x / s) · k = x · (k/s)`.
    pub scale: f64,
}

/// A state used as a divisor that keeps its divisions, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Refused {
    /// The state.
    pub state: StateId,
    /// Why: a sentence.
    pub reason: &'static str,
}

/// The program with reciprocals, and what was done.
#[derive(Clone, Debug)]
pub struct Reciprocals {
    /// The rewritten program (the input itself when no state qualifies).
    pub program: Program,
    /// One per state given a reciprocal, in state order; their hidden states are the last
    /// `recips.len()` states of `program`, in this order.
    pub recips: Vec<Reciprocal>,
    /// States used as divisors that were not given one.
    pub refused: Vec<Refused>,
}

/// Gives every qualifying divisor state a reciprocal (see the module documentation).
pub fn reciprocals(p: &Program) -> Reciprocals {
    let ns = p.states.len();
    let defined = defined_values(&p.body, p.values.len());
    // Per state: the divisions by a read of it.
    let mut divisions: Vec<Vec<usize>> = vec![Vec::new(); ns];
    for (i, vd) in p.values.iter().enumerate() {
        if let (true, Op::Arith(ArithOp::Div, _, y), Ty::Real(_)) = (defined[i], &vd.op, vd.ty) {
            if let Op::State(s) = p.values[y.index()].op {
                divisions[s.index()].push(i);
            }
        }
    }
    let top_level = crate::ir::states_set_every_sample(&p.body, ns);
    let mut out = Reciprocals {
        program: p.clone(),
        recips: Vec::new(),
        refused: Vec::new(),
    };
    for (s, divs) in divisions.iter().enumerate() {
        if divs.is_empty() {
            continue;
        }
        let (lo, hi) = p.states[s].range;
        let reason = if top_level[s] {
            Some("it has dynamics (written every sample): a reciprocal would cost a division every sample too")
        } else if !(lo.is_finite() && hi.is_finite()) || lo <= 0.0 && hi >= 0.0 {
            Some("its declared range includes 0: its reciprocal has no bound")
        } else if p.states[s].init == 0.0 {
            Some("its initial value is 0")
        } else if !within_words(1.0, lo, hi) {
            Some("its reciprocal's range is beyond what a word holds at the state's precision")
        } else {
            None
        };
        match reason {
            Some(reason) => out.refused.push(Refused {
                state: StateId(s as u32),
                reason,
            }),
            None => out.recips.push(Reciprocal {
                state: StateId(s as u32),
                recip: StateId((ns + out.recips.len()) as u32),
                divisions: divs.iter().map(|&i| p.values[i].span.clone()).collect(),
                writes: Vec::new(),
                carried: false,
                dropped: Vec::new(),
                scale: 1.0,
            }),
        }
    }
    if out.recips.is_empty() {
        return out;
    }
    // The one reader of each division, when it is a product by a constant: `(j, k)`.
    let scaled_by = scaled_readers(p, &defined);
    let mut scale_dim: Vec<Dim> = Vec::new();
    for r in &mut out.recips {
        let divs = &divisions[r.state.index()];
        let ks: Vec<Option<(usize, f64)>> = divs.iter().map(|&i| scaled_by[i]).collect();
        let k = ks.first().copied().flatten().map(|(_, k)| k);
        let same = ks
            .iter()
            .all(|x| x.map(|(_, k2)| Some(k2.to_bits()) == k.map(f64::to_bits)) == Some(true));
        let mut dim = Dim::NONE;
        if let (true, Some(k)) = (same, k) {
            let (j, i) = (ks[0].map_or(0, |x| x.0), divs[0]);
            if let (Ty::Real(dj), Ty::Real(di)) = (p.values[j].ty, p.values[i].ty) {
                let (lo, hi) = p.states[r.state.index()].range;
                if k.is_finite() && k != 0.0 && within_words(k, lo, hi) {
                    r.scale = k;
                    dim = dj / di;
                }
            }
        }
        scale_dim.push(dim);
    }
    let q = &mut out.program;
    for (r, &kd) in out.recips.iter().zip(&scale_dim) {
        let d = &p.states[r.state.index()];
        let (lo, hi) = d.range;
        let k = r.scale;
        let (a, b) = (k / hi, k / lo);
        q.states.push(StateDecl {
            name: if k == 1.0 {
                format!("1/{}", d.name)
            } else {
                format!("{k:.6e}/{}", d.name)
            },
            dim: kd / d.dim,
            init: k / d.init,
            range: (a.min(b), a.max(b)),
            span: d.span.clone(),
        });
    }
    let recip_of: HashMap<StateId, usize> = out
        .recips
        .iter()
        .enumerate()
        .map(|(k, r)| (r.state, k))
        .collect();
    // Each divisor read gets a read of the reciprocal beside it (same generation), and the
    // division becomes a product with it.
    let mut after: HashMap<Value, Value> = HashMap::new();
    for (k, r) in out.recips.iter().enumerate() {
        for &i in &divisions[r.state.index()] {
            let Op::Arith(ArithOp::Div, x, y) = q.values[i].op else {
                continue;
            };
            let ry = *after.entry(y).or_insert_with(|| {
                let ty = Ty::Real(q.states[ns + k].dim);
                let span = q.values[y.index()].span.clone();
                push(&mut q.values, Op::State(StateId((ns + k) as u32)), ty, span)
            });
            // Scaled: the reader `(x / s) · k` is `x · (k/s)`; the division is left unread.
            match scaled_by[i] {
                Some((j, _)) if r.scale != 1.0 => q.values[j].op = Op::Arith(ArithOp::Mul, x, ry),
                _ => q.values[i].op = Op::Arith(ArithOp::Mul, x, ry),
            }
        }
    }
    let ranges = range::analyse(p);
    let mut writes: Vec<Vec<(Span, bool)>> = vec![Vec::new(); out.recips.len()];
    let body = std::mem::take(&mut q.body);
    let scales: Vec<f64> = out.recips.iter().map(|r| r.scale).collect();
    let hidden_dims: Vec<Dim> = q.states[ns..].iter().map(|d| d.dim).collect();
    let mut ctx = Rewrite {
        p,
        ranges: &ranges,
        scales: &scales,
        hidden_dims: &hidden_dims,
        values: &mut q.values,
        after: &after,
        recip_of: &recip_of,
        ns,
        writes: &mut writes,
    };
    q.body = ctx.stmts(&body);
    for (r, w) in out.recips.iter_mut().zip(writes) {
        r.writes = w;
    }
    // States read nowhere any more are carried by their reciprocals: their writes go, and
    // with them what only those writes computed.
    let live_before = live_values(p);
    let live = live_values(q);
    for r in &mut out.recips {
        r.carried = !q
            .values
            .iter()
            .enumerate()
            .any(|(i, vd)| live[i] && vd.op == Op::State(r.state));
    }
    let is_division = |i: usize| match q.values[i].op {
        Op::Arith(ArithOp::Div, _, y) => q.const_value(y).is_none(),
        _ => false,
    };
    for r in out.recips.iter_mut().filter(|r| r.carried) {
        let unwritten = Program {
            body: without(&q.body, writes_of(&[r.state])),
            ..q.clone()
        };
        let live_without = live_values(&unwritten);
        r.dropped = (0..q.values.len())
            .filter(|&i| live[i] && !live_without[i] && is_division(i))
            .map(|i| q.values[i].span.clone())
            .collect();
    }
    let carried: Vec<StateId> = out
        .recips
        .iter()
        .filter(|r| r.carried)
        .map(|r| r.state)
        .collect();
    q.body = without(&q.body, writes_of(&carried));
    let live = live_values(q);
    let n_orig = p.values.len();
    let dead = |v: Value| !live[v.index()] && (v.index() >= n_orig || live_before[v.index()]);
    q.body = without(&q.body, |s| matches!(s, Stmt::Def(v) if dead(*v)));
    out
}

/// Magnitudes a hidden word's range may reach: `[2^-40, 2^40]`, so that its format stays
/// well inside `tactus_runtime::fixed::FRAC_RANGE` and the word resolves its near end.
const MAX_RECIPROCAL: f64 = (1u64 << 40) as f64;

/// Whether `k/x` over a range `[lo, hi]` of one sign stays within [`MAX_RECIPROCAL`].
fn within_words(k: f64, lo: f64, hi: f64) -> bool {
    let (a, b) = ((k / lo).abs(), (k / hi).abs());
    let (small, large) = (a.min(b), a.max(b));
    small.is_finite()
        && large.is_finite()
        && small >= 1.0 / MAX_RECIPROCAL
        && large <= MAX_RECIPROCAL
}

fn push(values: &mut Vec<ValueData>, op: Op, ty: Ty, span: Span) -> Value {
    values.push(ValueData { op, ty, span });
    Value((values.len() - 1) as u32)
}

struct Rewrite<'a> {
    p: &'a Program,
    ranges: &'a range::Ranges,
    scales: &'a [f64],
    hidden_dims: &'a [Dim],
    values: &'a mut Vec<ValueData>,
    after: &'a HashMap<Value, Value>,
    recip_of: &'a HashMap<StateId, usize>,
    ns: usize,
    writes: &'a mut Vec<Vec<(Span, bool)>>,
}

impl Rewrite<'_> {
    fn stmts(&mut self, stmts: &[Stmt]) -> Vec<Stmt> {
        let mut out = Vec::with_capacity(stmts.len());
        for s in stmts {
            match s {
                Stmt::Def(v) => {
                    out.push(s.clone());
                    if let Some(&r) = self.after.get(v) {
                        out.push(Stmt::Def(r));
                    }
                }
                Stmt::SetState(st, v) => {
                    out.push(s.clone());
                    if let Some(&k) = self.recip_of.get(st) {
                        let (r, divides) = self.reciprocal(*st, *v, k, &mut out);
                        out.push(Stmt::SetState(StateId((self.ns + k) as u32), r));
                        let span = self.p.values[v.index()].span.clone();
                        self.writes[k].push((span, divides));
                    }
                }
                Stmt::If(c, b) => {
                    let b = self.stmts(b);
                    out.push(Stmt::If(*c, b));
                }
                other => out.push(other.clone()),
            }
        }
        out
    }

    /// A value whose write saturated to `[1/hi, 1/lo]` is `1 / clamp(v, lo, hi)` of state
    /// `st`'s range, saturating exactly when the state's write does; its definitions pushed
    /// to `out`, and whether it divides at run time.
    fn reciprocal(
        &mut self,
        st: StateId,
        v: Value,
        k: usize,
        out: &mut Vec<Stmt>,
    ) -> (Value, bool) {
        let d = &self.p.states[st.index()];
        let (lo, hi) = d.range;
        let (scale, rdim) = (self.scales[k], self.hidden_dims[k]);
        let rty = Ty::Real(rdim);
        let kty = Ty::Real(rdim * d.dim);
        let span = self.p.values[v.index()].span.clone();
        let mut def = |values: &mut Vec<ValueData>, op: Op, ty: Ty| {
            let x = push(values, op, ty, span.clone());
            out.push(Stmt::Def(x));
            x
        };
        // The bound nearer 0, and half of it: a value between 0 and it, or across 0, is
        // taken as the half, whose reciprocal lies beyond the range and saturates to the
        // same end as the state (so that saturations are counted alike).
        let near = if lo > 0.0 { lo } else { hi };
        if let Some(c) = self.p.const_value(v) {
            let c = if c.is_nan() || c * near <= 0.0 {
                near / 2.0
            } else {
                c
            };
            return (def(self.values, Op::Const(scale / c), rty), false);
        }
        let iv = self.ranges.values[v.index()];
        let same_side = if lo > 0.0 { iv.lo > 0.0 } else { iv.hi < 0.0 };
        if let (true, Op::Arith(ArithOp::Div, a, b)) = (same_side, &self.p.values[v.index()].op) {
            let ia = self.ranges.values[a.index()];
            let a_nonzero = ia.lo > 0.0 || ia.hi < 0.0;
            if a_nonzero && iv.lo.is_finite() && iv.hi.is_finite() {
                let (Ty::Real(adim), Ty::Real(vdim)) =
                    (self.p.values[a.index()].ty, self.p.values[v.index()].ty)
                else {
                    unreachable!("a real quotient has real operands")
                };
                // k/(a/b) = b/(a/k) for a constant a (a product, planned with the constant's
                // reciprocal); else (b/a)·k.
                if let (Some(ca), true) = (self.p.const_value(*a), scale != 1.0) {
                    let ak = def(
                        self.values,
                        Op::Const(ca / scale),
                        Ty::Real(adim / kdim(rdim, d.dim)),
                    );
                    return (
                        def(self.values, Op::Arith(ArithOp::Div, *b, ak), rty),
                        false,
                    );
                }
                let divides = self.p.const_value(*a).is_none();
                if scale == 1.0 {
                    return (
                        def(self.values, Op::Arith(ArithOp::Div, *b, *a), rty),
                        divides,
                    );
                }
                let ba = def(
                    self.values,
                    Op::Arith(ArithOp::Div, *b, *a),
                    Ty::Real(Dim::NONE / vdim),
                );
                let kc = def(self.values, Op::Const(scale), kty);
                return (
                    def(self.values, Op::Arith(ArithOp::Mul, ba, kc), rty),
                    divides,
                );
            }
        }
        let ty = self.p.values[v.index()].ty;
        let half = def(self.values, Op::Const(near / 2.0), ty);
        let side = if lo > 0.0 { Builtin::Max } else { Builtin::Min };
        let m = def(self.values, Op::Call(side, v, Some(half)), ty);
        let one = def(self.values, Op::Const(scale), kty);
        (def(self.values, Op::Arith(ArithOp::Div, one, m), rty), true)
    }
}

/// The dimension of the scale of a hidden word of dimension `rdim` for a state of `sdim`.
fn kdim(rdim: Dim, sdim: Dim) -> Dim {
    rdim * sdim
}

/// Per value: when its only use is one value's operand and that value is a product by a
/// constant of it (`v · k`, `k · v` or `v / k`), that reader and `k` (1/k for `/ k`).
fn scaled_readers(p: &Program, defined: &[bool]) -> Vec<Option<(usize, f64)>> {
    let n = p.values.len();
    let mut uses = vec![0u32; n];
    let mut reader = vec![usize::MAX; n];
    for (j, vd) in p.values.iter().enumerate() {
        if !defined[j] {
            continue;
        }
        for x in vd.op.operands() {
            uses[x.index()] += 1;
            reader[x.index()] = j;
        }
    }
    super::chains::count_statement_uses(&p.body, &mut uses);
    (0..n)
        .map(|i| {
            if uses[i] != 1 || reader[i] == usize::MAX {
                return None;
            }
            let j = reader[i];
            match super::chains::by_constant(p, Value(j as u32)) {
                Some((x, k)) if x.index() == i => Some((j, k)),
                _ => None,
            }
        })
        .collect()
}

/// Which values something the body does (a write, a condition, a publication) needs.
fn live_values(p: &Program) -> Vec<bool> {
    crate::ir::live_values(p).0
}

/// `stmts` without the statements `drop` picks, in `if` bodies too.
fn without(stmts: &[Stmt], drop: impl Fn(&Stmt) -> bool) -> Vec<Stmt> {
    rebuild_stmts(stmts, &mut |s, out| {
        if !drop(s) {
            out.push(s.clone())
        }
    })
}

/// The writes of `carried` states.
fn writes_of(carried: &[StateId]) -> impl Fn(&Stmt) -> bool + '_ {
    move |s| matches!(s, Stmt::SetState(st, _) if carried.contains(st))
}
