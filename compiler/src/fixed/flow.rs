//! Flow facts over intervals: which top-level `if` bodies cannot both run in one sample.
//!
//! A backend-independent analysis beside the range analysis ([`super::range`]), whose
//! intervals it evaluates conditions over: a WCET analysis of any backend's code may use the
//! pairs to leave infeasible paths out (the Thumb backend marks each top-level `if` body and
//! the budget splits the worst path into scenarios, `Code::exclusive`). The facts are about
//! the program's meaning, not its machine code, so they hold for every engine.

use super::range::Interval;
use super::FixedProgram;
use crate::ir::*;

pub mod edges;
mod linear;

/// What one sample may hold in a state or mode after some statements: `None` = anything.
#[derive(Clone, Default)]
struct Known {
    state: std::collections::HashMap<usize, Interval>,
    mode: std::collections::HashMap<usize, Vec<u32>>,
    /// States whose word is exactly 0 (their initial 0, or a constant 0 stored): a
    /// comparison of their read with a constant 0 is decided exactly, with no margin.
    zero: std::collections::HashSet<usize>,
}

impl Known {
    /// The effect of `stmts`: `sure` when they certainly run (the assignments replace what is
    /// known), else they may run (what they assign joins what is known, and a state or mode
    /// not known stays unknown).
    fn apply(&mut self, fp: &FixedProgram, stmts: &[Stmt], sure: bool) {
        let p = &fp.program;
        for s in stmts {
            match s {
                Stmt::SetState(st, v) => {
                    if sure && fp.exact_const(*v) == Some(0.0) {
                        self.zero.insert(st.index());
                    } else if fp.exact_const(*v) != Some(0.0) {
                        self.zero.remove(&st.index());
                    }
                    let (lo, hi) = p.states[st.index()].range;
                    let w = fp.ranges.values[v.index()];
                    let w = Interval::new(w.lo.max(lo), w.hi.min(hi));
                    if sure {
                        self.state.insert(st.index(), w);
                    } else if let Some(k) = self.state.get_mut(&st.index()) {
                        *k = Interval::new(k.lo.min(w.lo), k.hi.max(w.hi));
                    }
                }
                Stmt::SetMode(m, i) => {
                    if sure {
                        self.mode.insert(m.index(), vec![*i]);
                    } else if let Some(k) = self.mode.get_mut(&m.index()) {
                        if !k.contains(i) {
                            k.push(*i);
                        }
                    }
                }
                Stmt::If(_, body) => self.apply(fp, body, false),
                _ => {}
            }
        }
    }
}

/// What is known before each top-level statement, a snapshot stored only where it changed
/// (a body of thousands of value definitions between two state assignments shares one).
#[derive(Default)]
struct KnownAt {
    snaps: Vec<Known>,
    /// Per statement pushed, its snapshot's index.
    at: Vec<u32>,
}

impl KnownAt {
    /// What is known before the next statement: `known`, which differs from the last
    /// snapshot only if `fresh`.
    fn push(&mut self, known: &Known, fresh: bool) {
        if fresh || self.snaps.is_empty() {
            self.snaps.push(known.clone());
        }
        self.at.push(self.snaps.len() as u32 - 1);
    }

    /// What was known before statement `k`, if it was pushed.
    fn get(&self, k: usize) -> Option<&Known> {
        self.at.get(k).map(|&i| &self.snaps[i as usize])
    }
}

/// Whether [`Known::apply`] of `s` can change what is known.
fn changes_known(s: &Stmt) -> bool {
    matches!(s, Stmt::SetState(..) | Stmt::SetMode(..) | Stmt::If(..))
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Tri {
    True,
    False,
    Unknown,
}

/// Flow facts for the WCET analysis: pairs `(i, j)` of top-level `if` statements (indices
/// into the body), `i` before `j`, such that when `i`'s body runs, `j`'s condition is false —
/// so no call runs both bodies. Found by evaluating `j`'s condition over intervals: states
/// and modes loaded after `i` hold what `i`'s body assigned them (joined with what the
/// statements in between may assign), every other value its analysed range. Example: the
/// piano's strike sets the hammer angle to the string's, so neither the back-check
/// (`s <= s_check`) nor the rest felt (`s <= 0`) can follow it in the same sample.
/// Comparisons count as decided only with a margin of 10⁻⁴ of the operands' magnitude, far
/// above the fixed-point errors of the compared words. Where the interval evaluation leaves
/// `j` open, [`linear`] asks whether both conditions can hold at once, with the values'
/// linear relations (after `xmax = x`, `x < xmax - slack` cannot).
///
/// Also pairs `(i, arm_mark(v, side))`: when `i`'s body runs, the top-level `select` `v`
/// after it does not take that arm ([`arm_mark`]; a backend that branches on the select
/// marks each arm's code). Example: the escapement's `hold` handler sets the mode that its
/// output's first `if phase == hold` tests, so the output's costlier else-arm cannot follow.
pub fn exclusions(fp: &FixedProgram) -> Vec<(u32, u32)> {
    let p = &fp.program;
    let pos = def_positions(p);
    let ifs: Vec<usize> = (0..p.body.len())
        .filter(|&k| matches!(p.body[k], Stmt::If(..)))
        .collect();
    // The linear facts ([`linear`]) where the program is small enough to ask them.
    let work = p.body.len() * p.values.len().max(p.states.len());
    let err = (work <= linear::MAX_WORK).then(|| super::report::local_errors(fp));
    let mut out = Vec::new();
    for &i in &ifs {
        let Stmt::If(cond_i, body_i) = &p.body[i] else {
            continue;
        };
        let mut known = Known {
            mode: mode_facts(p, &pos, i, *cond_i),
            ..Known::default()
        };
        known.apply(fp, body_i, true);
        let facts = sample_facts(fp, *cond_i);
        let nothing = known.state.is_empty() && known.mode.is_empty() && facts.is_empty();
        if nothing && err.is_none() {
            continue;
        }
        // What the states hold up to and through `i`'s body, for the linear facts.
        let mut src = err.as_ref().map(|_| linear::Sources::new(p));
        if let Some(src) = src.as_mut() {
            for k in 0..=i {
                src.before();
                src.apply(&p.body[k], k == i, false);
            }
        }
        // What is known before each top-level statement: nothing up to `i` (a read there
        // saw the sample before `i`'s body), then what `i`'s body and the statements since
        // left. A read is evaluated with what was known where it was read, not at the later
        // `if`: a state read before an assignment that certainly runs saw the older value.
        let mut at = KnownAt::default();
        for _ in 0..=i {
            at.push(&Known::default(), false);
        }
        let mut fresh = true;
        for k in i + 1..p.body.len() {
            at.push(&known, fresh);
            fresh = false;
            if let Some(src) = src.as_mut() {
                src.before();
            }
            let ev = Eval {
                fp,
                pos: &pos,
                facts: &facts,
                at: &at,
            };
            // Whether `c` (negated: `not`) cannot hold in a sample that runs `i`'s body.
            let never = |c: Value, not: bool| {
                let t = ev.tri(c);
                if t == if not { Tri::True } else { Tri::False } {
                    return true;
                }
                let (Some(err), Some(src)) = (&err, &src) else {
                    return false;
                };
                let mut l = linear::Linear::new(fp, err, &ev, &src.snap);
                l.assume(*cond_i);
                if not {
                    if !l.assume_not(c) {
                        return false;
                    }
                } else {
                    l.assume(c);
                }
                l.infeasible()
            };
            // A body that cannot run with `i`'s changes nothing after it.
            let mut skip = false;
            match &p.body[k] {
                Stmt::If(c, _) if never(*c, false) => {
                    out.push((i as u32, k as u32));
                    skip = true;
                }
                Stmt::Def(v) => {
                    if let Op::Select(c, _, _) = p.values[v.index()].op {
                        for side in [true, false] {
                            match arm_mark(*v, side) {
                                Some(m) if never(c, !side) => out.push((i as u32, m)),
                                _ => {}
                            }
                        }
                    }
                }
                _ => {}
            }
            if !skip {
                known.apply(fp, std::slice::from_ref(&p.body[k]), true);
                fresh = changes_known(&p.body[k]);
            }
            if let Some(src) = src.as_mut() {
                src.apply(&p.body[k], false, skip);
            }
            if err.is_none() && known.state.is_empty() && known.mode.is_empty() && facts.is_empty()
            {
                break;
            }
        }
    }
    out
}

/// The first-sample mark of differentiated sensor `h`'s history priming (its ring filled
/// with the first reading, once after `init`): `FIRST_SAMPLE_MARK - h`, beside the top-level
/// `if` indices of [`exclusions`].
pub const FIRST_SAMPLE_MARK: u32 = u32::MAX;

/// The first mark of the select arms ([`arm_mark`]), above every top-level index.
pub const ARM_MARK: u32 = 1 << 30;

/// The mark of the arm `side` (`true`: the value if the condition holds) of select `v`,
/// beside the top-level `if` indices of [`exclusions`]: `ARM_MARK + 4·v + 2·side`, or `None`
/// where the value index does not fit below [`FIRST_SAMPLE_MARK`]'s range. A backend marks
/// the arm's first instruction with it and the arm's end with the next number
/// ([`arm_end`]); an arm whose marks meet has no code of its own (its start is the join),
/// and its facts must not be used.
pub fn arm_mark(v: Value, side: bool) -> Option<u32> {
    let m = (v.0 as u64) * 4 + 2 * side as u64 + ARM_MARK as u64;
    (m + 1 < (FIRST_SAMPLE_MARK - (1 << 16)) as u64).then_some(m as u32)
}

/// The end mark of the arm whose start mark is `mark` (`Some` for an [`arm_mark`] only).
pub fn arm_end(mark: u32) -> Option<u32> {
    (ARM_MARK..FIRST_SAMPLE_MARK - (1 << 16))
        .contains(&mark)
        .then_some(mark | 1)
}

/// Top-level `if` statements (indices into the body) whose bodies cannot run in the first
/// call after `init`: every state and mode holds its initial value when the call starts,
/// and the statements before each `if` change them as [`exclusions`] follows them (an
/// assignment that certainly runs replaces what is known, one in an `if` body joins it).
/// The history priming runs exactly in that call, so it and these bodies never run in the
/// same call (`(FIRST_SAMPLE_MARK - h, k)` pairs). Example: the piano's hammer rests at
/// angle 0 with speed 0, so neither the strike (`s >= s_string`), the back-check nor the
/// rest felt (`w < 0`: the word 0 against the constant 0, decided exactly) can run then.
pub fn first_sample_exclusions(fp: &FixedProgram) -> Vec<u32> {
    let p = &fp.program;
    let pos = def_positions(p);
    let mut known = Known::default();
    for (i, st) in p.states.iter().enumerate() {
        known.state.insert(i, Interval::point(st.init));
        if fp.state_init[i] == 0 {
            known.zero.insert(i);
        }
    }
    for (m, md) in p.modes.iter().enumerate() {
        known.mode.insert(m, vec![md.init]);
    }
    let mut at = KnownAt::default();
    let mut fresh = true;
    let mut out = Vec::new();
    for (k, st) in p.body.iter().enumerate() {
        at.push(&known, fresh);
        fresh = false;
        if let Stmt::If(c, _) = st {
            let ev = Eval {
                fp,
                pos: &pos,
                facts: &[],
                at: &at,
            };
            if ev.tri(*c) == Tri::False {
                out.push(k as u32);
                continue;
            }
        }
        known.apply(fp, std::slice::from_ref(st), true);
        fresh = changes_known(st);
    }
    out
}

/// The top-level position of each value's definition (inside an `if`: that `if`'s index
/// in the body); `usize::MAX` for a value the body does not define.
fn def_positions(p: &Program) -> Vec<usize> {
    let mut pos = vec![usize::MAX; p.values.len()];
    for (k, s) in p.body.iter().enumerate() {
        walk_stmts(std::slice::from_ref(s), &mut |t| {
            if let Stmt::Def(v) = t {
                pos[v.index()] = k;
            }
        });
    }
    pos
}

/// Whether `v` has one value throughout a sample: it reads only sensors, their derivatives,
/// params and constants (no state, mode or edge, which handlers change).
fn sample_constant(p: &Program, v: Value) -> bool {
    match p.values[v.index()].op {
        Op::Const(_) | Op::Param(_) | Op::Sensor(_) | Op::Deriv(..) => true,
        Op::Neg(x) => sample_constant(p, x),
        Op::Arith(_, x, y) => sample_constant(p, x) && sample_constant(p, y),
        Op::Call(_, x, y) => sample_constant(p, x) && y.is_none_or(|y| sample_constant(p, y)),
        _ => false,
    }
}

/// Whether `a` and `b` compute the same thing from the same inputs (value ids may differ:
/// the front end re-emits a `let` at each use). Only for [`sample_constant`] values.
fn same_expr(p: &Program, a: Value, b: Value) -> bool {
    if a == b {
        return true;
    }
    match (&p.values[a.index()].op, &p.values[b.index()].op) {
        (Op::Const(x), Op::Const(y)) => x.to_bits() == y.to_bits(),
        (Op::Param(x), Op::Param(y)) => x == y,
        (Op::Sensor(x), Op::Sensor(y)) => x == y,
        (Op::Deriv(x, m), Op::Deriv(y, n)) => x == y && m == n,
        (Op::Neg(x), Op::Neg(y)) => same_expr(p, *x, *y),
        (Op::Arith(o, x1, y1), Op::Arith(q, x2, y2)) => {
            o == q && same_expr(p, *x1, *x2) && same_expr(p, *y1, *y2)
        }
        (Op::Call(f, x1, y1), Op::Call(g, x2, y2)) => {
            f == g
                && same_expr(p, *x1, *x2)
                && match (y1, y2) {
                    (None, None) => true,
                    (Some(y1), Some(y2)) => same_expr(p, *y1, *y2),
                    _ => false,
                }
        }
        _ => false,
    }
}

/// What an `if` condition being true says about values that keep their value through the
/// sample: for each comparison among its `and`-ed terms whose one side is
/// [`sample_constant`], that side's interval narrowed by the other side's range (`x >= y`:
/// x ≥ the least y). A later `if` testing the same expression of the same inputs sees the
/// narrowed interval: the plucked string's `rel >= release` excludes its `rel <= -release`.
fn sample_facts(fp: &FixedProgram, cond: Value) -> Vec<(Value, Interval)> {
    let p = &fp.program;
    let mut out = Vec::new();
    for (o, x, y) in real_comparisons(p, cond) {
        let (a, b) = (fp.ranges.values[x.index()], fp.ranges.values[y.index()]);
        // x o y: bounds on x from y's range, and on y from x's.
        let (ax, by) = match o {
            CmpOp::Ge | CmpOp::Gt => (
                Interval::new(a.lo.max(b.lo), a.hi),
                Interval::new(b.lo, b.hi.min(a.hi)),
            ),
            CmpOp::Le | CmpOp::Lt => (
                Interval::new(a.lo, a.hi.min(b.hi)),
                Interval::new(b.lo.max(a.lo), b.hi),
            ),
            _ => continue,
        };
        if sample_constant(p, x) && ax.lo <= ax.hi {
            out.push((x, ax));
        }
        if sample_constant(p, y) && by.lo <= by.hi {
            out.push((y, by));
        }
    }
    out
}

/// What the top-level `if` at body index `i` says about the modes where its body starts,
/// when its condition `cond` — a tree of `and`s — requires `mode == variant` (or `!=`) of
/// a mode read that no statement between the read and the `if` may set: the mode holds
/// that variant (or one of the others). With the bodies [`exclusions`] already rules out
/// skipped, that chains: the escapement's `phase == ready` handler excludes its `hold`
/// handler that sets `phase = hold`, and so the later `phase == hold` handlers.
fn mode_facts(
    p: &Program,
    pos: &[usize],
    i: usize,
    cond: Value,
) -> std::collections::HashMap<usize, Vec<u32>> {
    let mut out = std::collections::HashMap::new();
    let mut stack = vec![cond];
    while let Some(v) = stack.pop() {
        match p.values[v.index()].op {
            Op::And(x, y) => {
                stack.push(x);
                stack.push(y);
            }
            Op::Cmp(o @ (CmpOp::Eq | CmpOp::Ne), x, y) => {
                let (m, read, k) = match (&p.values[x.index()].op, &p.values[y.index()].op) {
                    (Op::Mode(m), Op::Variant(_, k)) => (*m, x, *k),
                    (Op::Variant(_, k), Op::Mode(m)) => (*m, y, *k),
                    _ => continue,
                };
                let at = pos[read.index()];
                if at > i {
                    continue;
                }
                let mut set_between = false;
                walk_stmts(&p.body[at..i], &mut |s| {
                    set_between |= matches!(s, Stmt::SetMode(n, _) if *n == m);
                });
                if set_between {
                    continue;
                }
                let all = p.modes[m.index()].variants.len() as u32;
                let allowed: Vec<u32> = match o {
                    CmpOp::Eq => vec![k],
                    _ => (0..all).filter(|&j| j != k).collect(),
                };
                let e: &mut Vec<u32> = out.entry(m.index()).or_insert_with(|| (0..all).collect());
                e.retain(|j| allowed.contains(j));
            }
            _ => {}
        }
    }
    out
}

/// The comparisons of real values that `cond` — a tree of `and`s — requires, each as
/// (operator, left, right), right operands of an `and` first. What a true condition says,
/// for the interval facts ([`sample_facts`]) and the linear ones (`linear::Facts::assume`).
fn real_comparisons(p: &Program, cond: Value) -> Vec<(CmpOp, Value, Value)> {
    let mut out = Vec::new();
    let mut stack = vec![cond];
    while let Some(v) = stack.pop() {
        match p.values[v.index()].op {
            Op::And(x, y) => {
                stack.push(x);
                stack.push(y);
            }
            Op::Cmp(o, x, y) if matches!(p.values[x.index()].ty, Ty::Real(_)) => {
                out.push((o, x, y))
            }
            _ => {}
        }
    }
    out
}

struct Eval<'a> {
    fp: &'a FixedProgram,
    pos: &'a [usize],
    /// Intervals of sample-constant expressions implied by the earlier `if`'s condition.
    facts: &'a [(Value, Interval)],
    /// What is known before each top-level statement (up to the `if` being evaluated): a
    /// value is read with what was known at its definition's position.
    at: &'a KnownAt,
}

impl Eval<'_> {
    fn real(&self, v: Value) -> Interval {
        let p = &self.fp.program;
        let r = self.real_unnarrowed(v);
        if !sample_constant(p, v) {
            return r;
        }
        self.facts
            .iter()
            .filter(|(f, _)| same_expr(p, *f, v))
            .fold(r, |r, (_, k)| {
                let n = Interval::new(r.lo.max(k.lo), r.hi.min(k.hi));
                if n.lo <= n.hi {
                    n
                } else {
                    r
                }
            })
    }

    /// What is known where `v` is read, if anything.
    fn known_at(&self, v: Value) -> Option<&Known> {
        self.at.get(self.pos[v.index()])
    }

    /// Whether `v` is certainly the word 0: a constant 0, or a state read known to hold 0
    /// where it is read (its initial 0 in the first sample, or a constant 0 that an earlier
    /// body certainly stored).
    fn zero(&self, v: Value) -> bool {
        match self.fp.program.values[v.index()].op {
            Op::State(s) => self
                .known_at(v)
                .is_some_and(|k| k.zero.contains(&s.index())),
            _ => self.fp.exact_const(v) == Some(0.0),
        }
    }

    fn real_unnarrowed(&self, v: Value) -> Interval {
        let p = &self.fp.program;
        match p.values[v.index()].op {
            Op::State(s) => self
                .known_at(v)
                .and_then(|k| k.state.get(&s.index()).copied())
                .unwrap_or(self.fp.ranges.values[v.index()]),
            _ => self.fp.ranges.values[v.index()],
        }
    }

    fn modes(&self, v: Value) -> Option<Vec<u32>> {
        match self.fp.program.values[v.index()].op {
            Op::Variant(_, i) => Some(vec![i]),
            Op::Mode(m) => self.known_at(v)?.mode.get(&m.index()).cloned(),
            _ => None,
        }
    }

    fn tri(&self, v: Value) -> Tri {
        let p = &self.fp.program;
        match p.values[v.index()].op {
            Op::BoolConst(b) => {
                if b {
                    Tri::True
                } else {
                    Tri::False
                }
            }
            Op::Not(x) => match self.tri(x) {
                Tri::True => Tri::False,
                Tri::False => Tri::True,
                Tri::Unknown => Tri::Unknown,
            },
            Op::And(x, y) => match (self.tri(x), self.tri(y)) {
                (Tri::False, _) | (_, Tri::False) => Tri::False,
                (Tri::True, Tri::True) => Tri::True,
                _ => Tri::Unknown,
            },
            Op::Or(x, y) => match (self.tri(x), self.tri(y)) {
                (Tri::True, _) | (_, Tri::True) => Tri::True,
                (Tri::False, Tri::False) => Tri::False,
                _ => Tri::Unknown,
            },
            Op::Cmp(o, x, y) => match p.values[x.index()].ty {
                Ty::Mode(_) => match (self.modes(x), self.modes(y), o) {
                    (Some(a), Some(b), CmpOp::Eq | CmpOp::Ne) => {
                        let eq = if a.len() == 1 && b.len() == 1 && a[0] == b[0] {
                            Tri::True
                        } else if a.iter().all(|k| !b.contains(k)) {
                            Tri::False
                        } else {
                            Tri::Unknown
                        };
                        match (o, eq) {
                            (CmpOp::Ne, Tri::True) => Tri::False,
                            (CmpOp::Ne, Tri::False) => Tri::True,
                            (_, t) => t,
                        }
                    }
                    _ => Tri::Unknown,
                },
                Ty::Real(_) if self.zero(x) && self.zero(y) => {
                    // Two words 0: decided exactly.
                    if matches!(o, CmpOp::Le | CmpOp::Ge | CmpOp::Eq) {
                        Tri::True
                    } else {
                        Tri::False
                    }
                }
                Ty::Real(_) => {
                    let (a, b) = (self.real(x), self.real(y));
                    let m = 1e-4 * a.mag().max(b.mag());
                    let lt = a.hi + m < b.lo; // certainly a < b
                    let ge = a.lo - m > b.hi; // certainly a > b
                    match o {
                        CmpOp::Lt | CmpOp::Le if lt => Tri::True,
                        CmpOp::Lt | CmpOp::Le if ge => Tri::False,
                        CmpOp::Gt | CmpOp::Ge if ge => Tri::True,
                        CmpOp::Gt | CmpOp::Ge if lt => Tri::False,
                        CmpOp::Eq if lt || ge => Tri::False,
                        CmpOp::Ne if lt || ge => Tri::True,
                        _ => Tri::Unknown,
                    }
                }
                Ty::Bool => Tri::Unknown,
            },
            _ => Tri::Unknown,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixed(src: &str) -> FixedProgram {
        let c = crate::compile(src, &crate::lower::Config::default()).expect("compiles");
        FixedProgram::new(&c.program)
    }

    /// The bodies of the `if`s (top-level indices) in the order they appear.
    fn ifs(fp: &FixedProgram) -> Vec<u32> {
        (0..fp.program.body.len() as u32)
            .filter(|&k| matches!(fp.program.body[k as usize], Stmt::If(..)))
            .collect()
    }

    #[test]
    fn the_first_sample_excludes_what_the_initial_states_rule_out() {
        // s starts at 0 and w at 0: `s >= 0.3` cannot hold, nor `w < 0` (the word 0 against
        // the constant 0, exactly); `x > 1 mm` can; after `w = x * 1000 Hz` (in an `if` that
        // may run) `w < 0` is no longer ruled out by the initial 0.
        let fp = fixed(
            "instrument t {\n sensor x: m in [0 mm, 10 mm]\n state s = 0 in [-1, 1]\n state w = 0 Hz in [-100 Hz, 100 Hz]\n on s >= 0.3 { s = 0 }\n while w < 0 Hz { w = 0 Hz }\n while x > 1 mm { s = 0.5 }\n on s >= 0.3 { s = 0 }\n while x > 2 mm { w = x * 1000 Hz/m }\n while w < 0 Hz { s = 0.1 }\n force f = s * 1 N\n}\n",
        );
        let k = ifs(&fp);
        assert_eq!(k.len(), 6);
        let first = first_sample_exclusions(&fp);
        // The first two bodies are ruled out; the third may run and set s = 0.5, so the
        // second `s >= 0.3` may hold; the last `w < 0` after a possible `w = x·1000`: x ≥ 0
        // keeps it out (the interval), not the exact zero.
        assert!(
            first.contains(&k[0]) && first.contains(&k[1]),
            "{first:?} of {k:?}"
        );
        assert!(!first.contains(&k[2]) && !first.contains(&k[3]) && !first.contains(&k[4]));
    }

    #[test]
    fn a_state_stored_from_a_sensor_moves_with_it() {
        // `m = x` then `x < m - 0.03 mm` is false whatever x is (intervals alone cannot
        // see it: both sides span [0, 10 mm]); `x < m + 0.03 mm` can hold (x = m), and
        // with `m` stored only maybe (a `while` before), the read is a word of its own.
        let fp = fixed(
            "instrument t {\n sensor x: m in [0 mm, 10 mm]\n state m = 0 mm in [0 mm, 10 mm]\n state a = 0 in [0, 1]\n while x > m { m = x }\n on x < m - 0.03 mm { a = 1 }\n on x < m + 0.03 mm { a = 0.5 }\n while x > 5 mm { a = 0.25 }\n force f = a * 1 N\n}\n",
        );
        let k = ifs(&fp);
        assert_eq!(k.len(), 4);
        let ex = exclusions(&fp);
        assert!(ex.contains(&(k[0], k[1])), "{ex:?} of {k:?}");
        assert!(!ex.contains(&(k[0], k[2])), "{ex:?} of {k:?}");
        assert!(!ex.contains(&(k[0], k[3])), "{ex:?} of {k:?}");
        // Whether (1, 2) may run together: `x < m − slack` and `x < m + slack` with the
        // same m: yes.
        assert!(!ex.contains(&(k[1], k[2])), "{ex:?} of {k:?}");
    }

    #[test]
    fn a_mode_tested_by_a_body_holds_there_until_a_later_body_sets_it() {
        // The escapement's chain: the `ready` handler that raises m runs only where the
        // mode is `ready`; the handler that sets `hold` cannot follow it (x < m − slack after
        // m = x), so neither can the `hold` handler. The `escaped` one can: `x >= 9 mm` may
        // set the mode between.
        let fp = fixed(
            "instrument t {\n sensor x: m in [0 mm, 10 mm]\n mode ph { ready, hold, escaped } = ready\n state m = 0 mm in [0 mm, 10 mm]\n state a = 0 in [0, 1]\n while ph == ready and x > m { m = x }\n on ph == ready and x > 5 mm and x < m - 0.03 mm { ph = hold }\n on ph == ready and x >= 9 mm { ph = escaped }\n while ph == hold and x < 4 mm { a = 1 }\n while ph == escaped and x < 8 mm { a = 0.5 }\n force f = a * 1 N\n}\n",
        );
        let k = ifs(&fp);
        assert_eq!(k.len(), 5);
        let ex = exclusions(&fp);
        assert!(ex.contains(&(k[0], k[1])), "{ex:?} of {k:?}");
        assert!(ex.contains(&(k[0], k[3])), "{ex:?} of {k:?}");
        assert!(!ex.contains(&(k[0], k[4])), "{ex:?} of {k:?}");
        // Without the `ready` test on the first handler nothing says the mode there.
        let fp = fixed(
            "instrument t {\n sensor x: m in [0 mm, 10 mm]\n mode ph { ready, hold, escaped } = ready\n state m = 0 mm in [0 mm, 10 mm]\n state a = 0 in [0, 1]\n while x > m { m = x }\n on ph == ready and x > 5 mm and x < m - 0.03 mm { ph = hold }\n on ph == ready and x >= 9 mm { ph = escaped }\n while ph == hold and x < 4 mm { a = 1 }\n while ph == escaped and x < 8 mm { a = 0.5 }\n force f = a * 1 N\n}\n",
        );
        let k = ifs(&fp);
        assert!(!exclusions(&fp).contains(&(k[0], k[3])));
    }

    #[test]
    fn a_clamped_store_is_its_value_off_the_range_ends() {
        // The escapement's hold (m from a second sensor, in an `if` that may run): `h =
        // 2250 N/m · (9.4 mm − m)` (clamped into [0, 5 N], live at both ends) is stored when `x > 9 mm` and `x < m − 0.03 mm`, so m > 9.03 mm and
        // h < 0.83 N; `1125 N/m · (x − 8.2 mm) <= h` needs h ≥ 0.9 N: never both. With
        // `x > 8.9 mm` instead, x = 8.91 mm, m = 8.95 mm gives h = 1.01 N ≥ 0.80 N: feasible,
        // and not excluded.
        let src = |lo: &str| {
            format!(
                "instrument t {{\n sensor x: m in [0 mm, 10 mm]\n state m = 0 mm in [0 mm, 20 mm]\n state h = 0 N in [0 N, 5 N]\n state a = 0 in [0, 1]\n sensor y: m in [0 mm, 20 mm]\n while y > 1 mm {{ m = y }}\n on x > {lo} and x < m - 0.03 mm {{ h = 2250 N/m * (9.4 mm - m) }}\n while 1125 N/m * (x - 8.2 mm) <= h {{ a = 1 }}\n force f = a * 1 N + h\n}}\n"
            )
        };
        let fp = fixed(&src("9 mm"));
        let k = ifs(&fp);
        assert!(
            exclusions(&fp).contains(&(k[1], k[2])),
            "{:?}",
            exclusions(&fp)
        );
        let fp = fixed(&src("8.9 mm"));
        let k = ifs(&fp);
        assert!(
            !exclusions(&fp).contains(&(k[1], k[2])),
            "{:?}",
            exclusions(&fp)
        );
    }
}
