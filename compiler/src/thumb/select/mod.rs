//! Instruction selection: the fixed-point IR to [`M`] over virtual registers.
//!
//! Every IR operation computes the bits `tactus_runtime::fixed` defines (the same
//! reductions as the C backend's [`crate::cgen::prim`], written as ARMv6-M sequences). The
//! range analysis bounds every word: `bound(v) ≥ |raw word|` for each value, from its
//! interval and format, widened by a relative 1e-9 and one unit so that the f64 interval
//! arithmetic's rounding cannot make it unsound. Those bounds choose the sequence:
//!
//! * a sum whose terms provably fit 32 bits is `ADDS`/`SUBS` (plus the format shifts); other
//!   sums extend to 64 bits (`ADDS`/`ADCS`);
//! * saturation to `i32` is emitted only where the bound does not prove the word fits;
//! * a comparison of two words that cannot overflow is `SUBS` and a sign extraction
//!   (branch-free); a comparison with a constant uses the exact thresholds of
//!   [`crate::cgen::prim`];
//! * a multiplication planned for `MULS` is `ASRS` pre-shifts, one `MULS` and the rounding
//!   shift; a 64-bit product is four 16×16 `MULS` partial products combined with
//!   `ADDS`/`ADCS` (ARMv6-M has no `SMULL`);
//! * a right shift rounding half up by `m ≤ 31` is `ASRS #m-1; ADDS #1; ASRS #1`
//!   (`floor((floor(x/2^(m-1)) + 1)/2) = floor(x/2^m + 1/2)`), or `ADDS #2^(m-1); ASRS #m`
//!   where `m ≤ 8` and the bound proves the sum fits;
//! * a `select` whose arms cost more than a branch is a diamond, the values only one arm
//!   uses computed inside it ([`arms`]); the others stay branch-free.
//!
//! Booleans are words 0/1 where a value needs them (an edge, an output); a condition that
//! only an `if` tests is a chain of compare-and-branch instructions (short-circuit `and`/`or`,
//! `not` by the branch sense), and an `and`/`or` word with such operands is materialised by
//! branches. For the WCET analysis the selector also attaches flow facts
//! ([`crate::fixed::flow::exclusions`]):
//! pairs of top-level `if` bodies that cannot both run in one call.
//!
//! The selector's core (this module: the [`Sel`] state, the small builders, the statement
//! walk) and one module per kind of sequence: [`values`] (an IR value's definition),
//! [`words`] (shifts, rounding, saturation, 64-bit pairs), [`sums`], [`products`],
//! [`divide`], [`elementary`] (`exp`, `sqrt`), [`compare`] (comparisons and branches) and
//! [`state`] (state, sensor and output access).

mod arms;
mod compare;
mod divide;
mod elementary;
mod products;
mod state;
mod sums;
mod values;
mod words;

use super::mir::*;
use super::ThumbError;
use crate::abi::{OutLayout, StateLayout};
use crate::cgen::prim;
use crate::fixed::flow::exclusions;
use crate::fixed::{FixedProgram, MulKind};
use crate::ir::*;
use compare::fused_conditions;
use products::Operand;
use std::cmp::Ordering;
use tactus_isa::decode::{AluOp, MemOp};
use tactus_runtime::differentiator::WINDOW;

const LIM: u64 = 1 << 31;

/// A word and a bound on its magnitude.
#[derive(Clone, Copy, Debug)]
pub(crate) struct W {
    v: V,
    b: u64,
}

/// A selected function body and its number of virtual registers.
pub(crate) struct Selected {
    pub code: Vec<M>,
    pub nregs: u32,
    /// Pairs of top-level `if` statements (their [`M::Mark`]s) whose bodies never both run
    /// in one call ([`crate::fixed::flow::exclusions`]).
    pub exclusive: Vec<(u32, u32)>,
}

pub(crate) struct Sel<'a> {
    fp: &'a FixedProgram,
    p: &'a Program,
    st: &'a StateLayout,
    out: &'a OutLayout,
    code: Vec<M>,
    nv: u32,
    nl: u32,
    val: Vec<Option<W>>,
    used: Vec<bool>,
    sensors: Vec<W>,
    derivs: Vec<[Option<W>; 2]>,
    /// `d2()` of a sensor whose second difference does not fit 32 bits, as `(d1, e)` with
    /// `d2 = d1 − e`.
    d2_parts: Vec<Option<(W, W)>>,
    out_ptr: V,
    next_site: usize,
    /// Force/output/total slots written unconditionally exactly once: stored straight to
    /// `out[]`, not through `published[]`.
    direct: Vec<bool>,
    /// `state + region` in a register, for word accesses beyond the 124-byte reach of an
    /// immediate offset from r7 (`(region, register)`, region a multiple of 128): reused by
    /// the following accesses to the same region until the next label, where control may
    /// arrive from a path that did not define it.
    region_base: Option<(usize, V)>,
    /// Virtual registers holding a known word: defined once, by [`Sel::movi`] (a later
    /// definition removes the entry). A rounding of such a word is folded to its result
    /// ([`Sel::round`], [`Sel::floor_shr`]): a constant's conversion to another format costs
    /// nothing at run time.
    konst: std::collections::HashMap<V, i32>,
    /// The first construct found that this backend cannot compile.
    unsupported: Option<String>,
    /// Whether [`Sel::stmts`] is at the body's top level (for [`M::Mark`]s).
    top: bool,
    /// Conditions evaluated as branches where an `if` (or a branching `select`) tests them,
    /// never as 0/1 words: `and`/`or`/`not`/comparisons whose only use is that test (or
    /// another such condition).
    fused: Vec<bool>,
    /// The selects emitted as diamonds and the values computed inside their arms.
    arms: arms::Arms,
    /// Per value: the state it is stored into, when that store is its only reader (its word
    /// may then be clamped where it is computed, where the state keeps its format, or
    /// rounded to the state's format there: [`Sel::product_into_store`]).
    sole_store: Vec<Option<usize>>,
    /// Per value: how many operands of used values and statements read it.
    readers: Vec<u32>,
    /// Per value: the real `select` that reads it as an arm, where that is its one reader.
    select_reader: Vec<Option<Value>>,
    /// Per real `select` whose one reader stores it into a state of a coarser format, and
    /// whose arms are constants or words of its own format: that state's format. The select
    /// then picks between its arms converted to it (a conversion commutes with a select;
    /// each arm is rounded once, as the store would round the select) and the store
    /// converts nothing.
    select_store_frac: Vec<Option<i32>>,
    /// Values whose word is already in the format of their one reader, a state's store or a
    /// `select` ([`Sel::product_into_store`]): that reader converts nothing.
    preconverted: Vec<bool>,
    /// Values whose word was clamped to their state's range where computed
    /// ([`Sel::fuse_store_clamp`]): their store clamps nothing.
    store_clamped: Vec<bool>,
    /// The last saturating left shift emitted ([`Sel::shl_sat`]), while it ends the code.
    last_shl: Option<ShlSat>,
    /// Per value: an edge handler's condition `c` whose only readers are `SetEdge(e, c)`
    /// and the `If(c and not edge(e))` right after it ([`edge_conditions`]): no word of its
    /// own, each path of its compare-and-branch chain stores the edge's constant.
    edge_cond: Vec<bool>,
    /// Per value: how many branch-free `select`s test it; a truth value tested by two or
    /// more gets its mask `-c` once, where it is defined ([`Sel::masks`]).
    select_uses: Vec<u32>,
    /// The mask `-c` of a 0/1 word `c` ([`Sel::select`]), computed right after `c`'s
    /// definition (so it dominates every use of `c`), until `c`'s register is redefined.
    masks: std::collections::HashMap<V, V>,
    /// The force terms' words of `out[]` are left unwritten ([`super::Convention::skip_terms`]).
    skip_terms: bool,
    /// Scaled derivatives computed once, before the body ([`Sel::hoist_derivatives`]): per
    /// (sensor, order, fraction bits, bound) the word every `d()`/`d2()` value of that
    /// format reads.
    derivs_scaled: std::collections::HashMap<(usize, u8, i32, u64), W>,
}

/// The conditions of edge handlers (`on c { … }`, lowered to `SetEdge(e, c)` then
/// `If(c and not edge(e), body)`) that nothing else reads and that [`Sel::branch_op`] can
/// test: [`Sel::edge_handler`] branches on them once, storing 1 or 0 on each way.
fn edge_conditions(p: &Program, used: &[bool], fused: &[bool]) -> Vec<bool> {
    let n = p.values.len();
    let mut uses = vec![0u32; n];
    for (vd, _) in p.values.iter().zip(used).filter(|(_, u)| **u) {
        for x in vd.op.operands() {
            uses[x.index()] += 1;
        }
    }
    walk_stmts(&p.body, &mut |s| {
        s.reads().iter().for_each(|v| uses[v.index()] += 1)
    });
    let mut edge = vec![false; n];
    fn walk(stmts: &[Stmt], f: &mut dyn FnMut(&Stmt, Option<&Stmt>)) {
        for (k, s) in stmts.iter().enumerate() {
            f(s, stmts.get(k + 1));
            if let Stmt::If(_, body) = s {
                walk(body, f);
            }
        }
    }
    walk(&p.body, &mut |s, next| {
        if let (Stmt::SetEdge(e, c), Some(Stmt::If(fire, _))) = (s, next) {
            if crate::fixed::flow::edges::edge_fire(p, *e, *fire).map(|(x, _)| x) == Some(*c)
                && fused[fire.index()]
                && uses[c.index()] == 2
                && matches!(
                    p.values[c.index()].op,
                    Op::And(..) | Op::Or(..) | Op::Not(_) | Op::Cmp(..)
                )
            {
                edge[c.index()] = true;
            }
        }
    });
    edge
}

/// A saturating left shift `d = sat(x · 2^e)` occupying `code[start..end]`.
#[derive(Clone, Copy, Debug)]
struct ShlSat {
    d: V,
    x: W,
    e: u8,
    start: usize,
    end: usize,
}

/// Per value of `fp`: the state `SetState` stores it into where that store is the value's
/// only reader (no operand of a used value, no other statement); and per value its number
/// of readers (operands of used values and statements' reads).
fn sole_stores(fp: &FixedProgram, used: &[bool]) -> (Vec<Option<usize>>, Vec<u32>) {
    let p = &fp.program;
    let n = p.values.len();
    let mut readers = vec![0u32; n];
    for (i, vd) in p.values.iter().enumerate() {
        if used[i] {
            for x in vd.op.operands() {
                readers[x.index()] += 1;
            }
        }
    }
    let mut store = vec![None; n];
    walk_stmts(&p.body, &mut |s| {
        for v in s.reads() {
            readers[v.index()] += 1;
        }
        if let Stmt::SetState(sid, v) = s {
            store[v.index()] = Some(sid.index());
        }
    });
    let sole = (0..n)
        .map(|i| store[i].filter(|_| readers[i] == 1))
        .collect();
    (sole, readers)
}

fn pow2(e: i32) -> u64 {
    if e >= 63 {
        u64::MAX
    } else {
        1u64 << e.max(0)
    }
}

fn shl_bound(b: u64, e: i32) -> u64 {
    if b == 0 {
        0
    } else if e >= 40 {
        u64::MAX
    } else {
        b.saturating_mul(pow2(e))
    }
}

impl<'a> Sel<'a> {
    pub(crate) fn new(
        fp: &'a FixedProgram,
        st: &'a StateLayout,
        out: &'a OutLayout,
        used: Vec<bool>,
    ) -> Self {
        let p = &fp.program;
        let np = p.forces.len() + 1 + p.outputs.len();
        let mut count = vec![(0usize, false); np];
        fn walk(stmts: &[Stmt], p: &Program, nested: bool, count: &mut [(usize, bool)]) {
            let nf = p.forces.len();
            for s in stmts {
                let slot = match s {
                    Stmt::Force(f, _) => Some(f.index()),
                    Stmt::Total(_) => Some(nf),
                    Stmt::Output(o, _) => Some(nf + 1 + o.index()),
                    Stmt::If(_, body) => {
                        walk(body, p, true, count);
                        None
                    }
                    _ => None,
                };
                if let Some(i) = slot {
                    count[i].0 += 1;
                    count[i].1 |= nested;
                }
            }
        }
        walk(&p.body, p, false, &mut count);
        let direct = count.iter().map(|&(n, nested)| n == 1 && !nested).collect();
        let arms = arms::plan(fp, &used);
        let (sole_store, readers) = sole_stores(fp, &used);
        let mut select_reader = vec![None; p.values.len()];
        for (i, vd) in p.values.iter().enumerate() {
            if let (Op::Select(_, x, y), Ty::Real(_), true) = (&vd.op, &vd.ty, used[i]) {
                for a in [x, y] {
                    if readers[a.index()] == 1 {
                        select_reader[a.index()] = Some(Value(i as u32));
                    }
                }
            }
        }
        let mut select_store_frac = vec![None; p.values.len()];
        for (i, vd) in p.values.iter().enumerate() {
            let (Op::Select(_, x, y), Ty::Real(_), true, Some(st)) =
                (&vd.op, &vd.ty, used[i], sole_store[i])
            else {
                continue;
            };
            let own = |a: &Value| {
                fp.frac[a.index()] == fp.frac[i]
                    || (matches!(p.values[a.index()].op, Op::Const(_) | Op::Param(_))
                        && fp.param_word_of(*a).is_none())
            };
            if fp.state_frac[st] < fp.frac[i] && own(x) && own(y) {
                select_store_frac[i] = Some(fp.state_frac[st]);
            }
        }
        let mut fused = fused_conditions(p, &used, &arms.conditions(p));
        let edge_cond = edge_conditions(p, &used, &fused);
        let mut select_uses = vec![0u32; p.values.len()];
        for (i, vd) in p.values.iter().enumerate() {
            if let Op::Select(c, ..) = vd.op {
                if used[i] && !arms.branchy[i] {
                    select_uses[c.index()] += 1;
                }
            }
        }
        // An edge handler's condition is branched on like a fused one.
        for (f, e) in fused.iter_mut().zip(&edge_cond) {
            *f |= *e;
        }
        Sel {
            fp,
            p,
            st,
            out,
            code: Vec::new(),
            nv: 0,
            nl: 0,
            val: vec![None; p.values.len()],
            used,
            sensors: Vec::new(),
            derivs: vec![[None, None]; p.sensors.len()],
            d2_parts: vec![None; p.sensors.len()],
            out_ptr: V(0),
            next_site: 0,
            direct,
            region_base: None,
            konst: std::collections::HashMap::new(),
            unsupported: None,
            fused,
            arms,
            top: false,
            sole_store,
            readers,
            store_clamped: vec![false; p.values.len()],
            select_reader,
            select_store_frac,
            preconverted: vec![false; p.values.len()],
            last_shl: None,
            edge_cond,
            select_uses,
            masks: std::collections::HashMap::new(),
            derivs_scaled: std::collections::HashMap::new(),
            skip_terms: false,
        }
    }

    fn nv(&mut self) -> V {
        self.nv += 1;
        V(self.nv - 1)
    }

    fn label(&mut self) -> Label {
        self.nl += 1;
        Label(self.nl - 1)
    }

    fn push(&mut self, m: M) {
        if matches!(m, M::Label(_)) {
            self.region_base = None;
        }
        if let Some(d) = m.def() {
            self.konst.remove(&d);
            self.masks.remove(&d);
        }
        self.code.push(m);
    }

    // ---- small builders ----

    fn movi(&mut self, imm: i32) -> V {
        let d = self.nv();
        self.push(M::Movi { d, imm });
        self.konst.insert(d, imm);
        d
    }

    /// A known word `c` as a `W` (its bound is its magnitude).
    fn known(&mut self, c: i32) -> W {
        W {
            v: self.movi(c),
            b: c.unsigned_abs() as u64,
        }
    }

    fn sh(&mut self, op: Shift, m: V, imm: u8) -> V {
        let d = self.nv();
        self.push(M::Sh { op, d, m, imm });
        d
    }

    fn alu2(&mut self, op: AluOp, a: V, m: V) -> V {
        let d = self.nv();
        self.push(M::Alu2 { op, d, a, m });
        d
    }

    fn addsub(&mut self, sub: bool, a: V, b: V) -> V {
        let d = self.nv();
        self.push(M::AddSub { sub, d, a, b });
        d
    }

    fn addi(&mut self, sub: bool, a: V, imm: u8) -> V {
        let d = self.nv();
        self.push(M::AddSubI { sub, d, a, imm });
        d
    }

    fn unary(&mut self, op: AluOp, m: V) -> V {
        let d = self.nv();
        self.push(M::Unary { op, d, m });
        d
    }

    /// Records the first construct this backend cannot compile ([`Sel::run`] reports it).
    fn unsupported(&mut self, what: &str) {
        self.unsupported.get_or_insert_with(|| what.to_string());
    }
}

impl<'a> Sel<'a> {
    /// Leaves the force terms' words of `out[]` unwritten (or not): [`super::Convention::skip_terms`].
    pub(crate) fn skip_terms(mut self, skip: bool) -> Self {
        self.skip_terms = skip;
        self
    }

    /// Selects the whole update body.
    pub(crate) fn run(mut self) -> Result<Selected, ThumbError> {
        let (p, fp, st) = (self.p, self.fp, self.st);
        // Arguments: r0 = state (copied to r7 by the prologue), r1 = sensors, r2 = out.
        let sensors_ptr = ARG1;
        self.out_ptr = ARG2;
        self.nv = FIRST_FREE;
        // 1. Sensors: load, clamp, push the histories.
        for (i, _sd) in p.sensors.iter().enumerate() {
            let raw = self.load(MemOp::Ldr, Base::V(sensors_ptr), 4 * i);
            let (lo, hi) = fp.sensor_raw_range[i];
            self.clamp(raw, lo, hi);
            let b = (lo as i64).unsigned_abs().max((hi as i64).unsigned_abs());
            self.sensors.push(W { v: raw, b });
        }
        let mut slot = 0;
        for (i, sd) in p.sensors.iter().enumerate() {
            if !sd.differentiated {
                continue;
            }
            self.history(i, slot)?;
            slot += 1;
        }
        self.hoist_derivatives()?;
        // Clear the emit slots of out[].
        if !self.out.emits.is_empty() {
            let z = self.movi(0);
            for site in self.out.emits.clone() {
                let n = 1 + p.events[site.event.index()].args.len();
                for k in 0..n {
                    self.store(MemOp::Str, z, Base::V(self.out_ptr), 4 * (site.offset + k));
                }
            }
        }
        let body = p.body.clone();
        self.top = true;
        self.stmts(&body)?;
        // Published slots not stored directly: copy published[] to out[].
        let np = p.forces.len() + 1 + p.outputs.len();
        let first = if self.skip_terms { p.forces.len() } else { 0 };
        for i in first..np {
            if !self.direct[i] {
                let w = self.load(MemOp::Ldr, Base::State, st.published + 4 * i);
                self.store(MemOp::Str, w, Base::V(self.out_ptr), 4 * i);
            }
        }
        if let Some(what) = self.unsupported {
            return Err(ThumbError::Unsupported(what));
        }
        // Words nothing reads (the zero side of a `select` folded to `ANDS`/`BICS`, a
        // negated term of a difference that took the 64-bit path, …) and their flags.
        super::forward::forward(&mut self.code, self.nv);
        super::cse::share(&mut self.code, self.nv);
        super::dce::remove_dead(&mut self.code, self.nv);
        super::literals::share(&mut self.code, self.nv);
        // Flow facts: exclusive `if` bodies, then the history primings (the first call)
        // against the bodies that cannot run in it.
        let mut exclusive = exclusions(fp);
        let first = crate::fixed::flow::first_sample_exclusions(fp);
        let primings = p.sensors.iter().filter(|s| s.differentiated).count() as u32;
        for h in 0..primings {
            let mark = crate::fixed::flow::FIRST_SAMPLE_MARK - h;
            exclusive.extend(first.iter().map(|&k| (mark, k)));
        }
        Ok(Selected {
            code: self.code,
            nregs: self.nv,
            exclusive,
        })
    }

    fn stmts(&mut self, stmts: &[Stmt]) -> Result<(), ThumbError> {
        let (p, fp, st) = (self.p, self.fp, self.st);
        let top = std::mem::replace(&mut self.top, false);
        let mut threaded = None;
        for (k, s) in stmts.iter().enumerate() {
            if threaded == Some(k) {
                continue;
            }
            match s {
                Stmt::SetEdge(e, c) if self.edge_cond[c.index()] => {
                    let Some(Stmt::If(fire, body)) = stmts.get(k + 1) else {
                        unreachable!("an edge condition is followed by its handler")
                    };
                    self.edge_handler(*e, *c, *fire, body, top.then_some(k as u32 + 1))?;
                    threaded = Some(k + 1);
                }
                // (A value computed in a branching select's arm waits for it.)
                Stmt::Def(v) if self.arms.home[v.index()].is_none() => {
                    let since = self.code.len();
                    self.define(*v)?;
                    self.fuse_store_clamp(*v, since);
                }
                Stmt::Def(_) => {}
                Stmt::SetState(sid, v) => {
                    let i = sid.index();
                    let x = self.word(*v);
                    let since = self.code.len();
                    let t = if self.preconverted[v.index()] {
                        x
                    } else {
                        self.convert(x, fp.frac[v.index()], fp.state_frac[i])
                    };
                    let (lo, hi) = fp.state_raw_range[i];
                    // The clamp is omitted where the value's interval proves it inside.
                    let iv = fp.ranges.values[v.index()];
                    let scale = 2f64.powi(fp.state_frac[i]);
                    let margin = 2.0 + 1e-9 * iv.mag() * scale;
                    // A state copied into a state of the same format and a range at least
                    // as wide (a delay line's shift) is inside too: every state word is
                    // within its own raw range (initialised in it, clamped on each write).
                    let copy = match p.values[v.index()].op {
                        Op::State(src) => {
                            let (slo, shi) = fp.state_raw_range[src.index()];
                            fp.state_frac[src.index()] == fp.state_frac[i]
                                && fp.frac[v.index()] == fp.state_frac[i]
                                && slo >= lo
                                && shi <= hi
                        }
                        _ => false,
                    };
                    // Each side of the clamp is omitted where the value's interval proves
                    // it inside, or where its word's exact range does (a sensor, a state,
                    // a constant: no rounding margin, so `xmax = key` stores key's word).
                    let exact = self.exact_word_range(*v).map(|(a, b)| {
                        let conv = |w| {
                            tactus_runtime::fixed::convert(w, fp.frac[v.index()], fp.state_frac[i])
                                .0
                        };
                        (conv(a), conv(b))
                    });
                    let lo_in = copy
                        || iv.lo * scale - margin >= lo as f64
                        || exact.is_some_and(|(a, _)| a >= lo);
                    let hi_in = copy
                        || iv.hi * scale + margin <= hi as f64
                        || exact.is_some_and(|(_, b)| b <= hi);
                    let (lo_o, hi_o) = ((!lo_in).then_some(lo), (!hi_in).then_some(hi));
                    let t = if (lo_in && hi_in) || self.store_clamped[v.index()] {
                        t.v
                    } else if self.fuse_shl_clamp(t.v, since, lo_o, hi_o).is_some() {
                        // The conversion's saturating shift and the clamp in one.
                        t.v
                    } else {
                        let c = self.nv();
                        self.push(M::Mov { d: c, s: t.v });
                        self.clamp_sides(c, (!lo_in).then_some(lo), (!hi_in).then_some(hi));
                        c
                    };
                    self.store(MemOp::Str, t, Base::State, st.states + 4 * i);
                }
                Stmt::SetMode(m, i) => {
                    let k = self.movi(*i as i32);
                    self.store(MemOp::Strb, k, Base::State, st.modes + m.index());
                }
                Stmt::SetEdge(e, v) => {
                    let w = self.word(*v);
                    self.store(MemOp::Strb, w.v, Base::State, st.edges + e.index());
                }
                // `while true { … }`: the body, without a test (no flow fact can name it:
                // a body that always runs excludes nothing).
                Stmt::If(c, body) if p.values[c.index()].op == Op::BoolConst(true) => {
                    self.stmts(body)?;
                }
                Stmt::If(c, body) => {
                    let skip = self.label();
                    self.branch(*c, false, skip)?;
                    if top {
                        self.push(M::Mark(k as u32));
                    }
                    self.push(M::Note(format!("if {}", describe(p, *c))));
                    self.stmts(body)?;
                    self.push(M::Label(skip));
                }
                Stmt::Emit(e, args) => {
                    let site = self.out.emits[self.next_site];
                    self.next_site += 1;
                    self.push(M::Note(format!("emit {}", p.events[e.index()].name)));
                    let one = self.movi(1);
                    self.store(MemOp::Str, one, Base::V(self.out_ptr), 4 * site.offset);
                    for (j, (a, f)) in args.iter().zip(&fp.event_frac[e.index()]).enumerate() {
                        let x = self.word(*a);
                        let w = self.convert(x, fp.frac[a.index()], *f);
                        self.store(
                            MemOp::Str,
                            w.v,
                            Base::V(self.out_ptr),
                            4 * (site.offset + 1 + j),
                        );
                    }
                }
                Stmt::Force(_, _) if self.skip_terms => {}
                Stmt::Force(f, v) => self.publish(f.index(), *v),
                Stmt::Total(v) => self.publish(p.forces.len(), *v),
                Stmt::Output(o, v) => self.publish(p.forces.len() + 1 + o.index(), *v),
            }
        }
        Ok(())
    }
}

impl<'a> Sel<'a> {
    /// The scaled derivatives (`d(x)`, `d2(x)`: a raw difference times `fs/N` or `(fs/N)²`,
    /// rounded) that the body computes at its top level and that an `if` body before that
    /// computes too, computed once before the body: the `if` body then reads that word
    /// instead of computing it again (the piano's impact pulse and its contact damping both
    /// read `d(key)`). A word computed at the top level runs on every path anyway, so no
    /// path gets longer; the raw difference usually dies there instead of living on. So are
    /// the derivatives of a sensor whose second difference needs 33 bits (two raw words live
    /// up to its use, one scaled word instead). Others stay where they are: a longer live
    /// range for nothing (hammond: 2 cycles more).
    fn hoist_derivatives(&mut self) -> Result<(), ThumbError> {
        let p = self.p;
        type Key = (usize, u8, i32, u64);
        let key = |this: &Self, v: Value| -> Option<Key> {
            match p.values[v.index()].op {
                Op::Deriv(x, o) if this.used[v.index()] => {
                    Some((x.index(), o, this.fp.frac[v.index()], this.bound_of(v)))
                }
                _ => None,
            }
        };
        // Keys an `if` body has computed so far, and the top-level definitions to hoist.
        let mut nested: Vec<Key> = Vec::new();
        let mut hoist: Vec<(Key, Value)> = Vec::new();
        for s in &p.body {
            match s {
                Stmt::Def(v) if self.arms.home[v.index()].is_none() => {
                    if let Some(k) = key(self, *v) {
                        // A 33-bit second difference keeps two raw words (`d2_parts`) alive
                        // up to its use: its scaled word is one.
                        let wide = k.1 == 2 && self.d2_parts[k.0].is_some();
                        if (wide || nested.contains(&k)) && !hoist.iter().any(|(h, _)| *h == k) {
                            hoist.push((k, *v));
                        }
                    }
                }
                Stmt::If(_, body) => walk_stmts(body, &mut |t| {
                    if let Stmt::Def(v) = t {
                        if let Some(k) = key(self, *v) {
                            nested.push(k);
                        }
                    }
                }),
                _ => {}
            }
        }
        for (k, v) in hoist {
            let w = self.def(v)?;
            self.derivs_scaled.insert(k, w);
        }
        Ok(())
    }

    /// Computes `v` into [`Sel::val`] where it has a word of its own (not a constant,
    /// rematerialised at each use, nor a condition fused into its branch).
    fn define(&mut self, v: Value) -> Result<(), ThumbError> {
        let word_only = matches!(
            self.p.values[v.index()].op,
            Op::Const(_) | Op::Param(_) | Op::BoolConst(_) | Op::Variant(..)
        );
        if self.used[v.index()] && !word_only && !self.fused[v.index()] {
            let w = self.def(v)?;
            self.val[v.index()] = Some(w);
            if self.select_uses[v.index()] >= 2 && !self.konst.contains_key(&w.v) {
                let m = self.unary(AluOp::Rsb, w.v);
                self.masks.insert(w.v, m);
            }
        }
        Ok(())
    }

    /// `c ? x : y` as a diamond ([`arms`]): the condition as a compare-and-branch, each arm's
    /// own values computed inside it; the costlier arm is the branch target (a taken
    /// branch costs what the other arm's `B` over it does, minus the not-taken cycle).
    fn select_branch(&mut self, v: Value, c: Value, x: Value, y: Value) -> Result<W, ThumbError> {
        let (p, fp) = (self.p, self.fp);
        let real = matches!(p.values[v.index()].ty, Ty::Real(_));
        let d = self.nv();
        let (second, done) = (self.label(), self.label());
        let then_first = self.arms.cost(fp, (v, true)) <= self.arms.cost(fp, (v, false));
        self.branch(c, !then_first, second)?;
        let mut b = 0;
        for (k, side) in [then_first, !then_first].into_iter().enumerate() {
            if k == 1 {
                self.push(M::B(done));
                self.push(M::Label(second));
            }
            // Each arm's first block, for the flow facts (`fixed::flow::arm_mark`).
            if let Some(m) = crate::fixed::flow::arm_mark(v, side) {
                self.push(M::Mark(m));
            }
            let members = self
                .arms
                .members
                .get(&(v, side))
                .cloned()
                .unwrap_or_default();
            for m in members {
                self.define(m)?;
            }
            let a = if side { x } else { y };
            let w = if real {
                self.arm_word(v, a)
            } else {
                self.word(a)
            };
            match self.konst.get(&w.v) {
                Some(&imm) => self.push(M::Movi { d, imm }),
                None => self.push(M::Mov { d, s: w.v }),
            }
            if let Some(m) = crate::fixed::flow::arm_mark(v, side) {
                self.push(M::Mark(m + 1));
            }
            b = b.max(w.b);
        }
        self.push(M::Label(done));
        if real && self.select_store_frac[v.index()].is_some() {
            self.preconverted[v.index()] = true;
        }
        Ok(W { v: d, b })
    }

    /// The word of arm `a` of the real select `sel` in the select's format — or in its
    /// store's format ([`Sel::select_store_frac`]), where the arm's own format is the
    /// select's (one rounding) or the arm is a constant (folded exactly, both roundings).
    fn arm_word(&mut self, sel: Value, a: Value) -> W {
        let w = self.word(a);
        if self.preconverted[a.index()] {
            return w;
        }
        let (fa, fs) = (self.fp.frac[a.index()], self.fp.frac[sel.index()]);
        let w = self.convert(w, fa, fs);
        match self.select_store_frac[sel.index()] {
            Some(t) => self.convert(w, fs, t),
            None => w,
        }
    }
}

impl<'a> Sel<'a> {
    /// `SetEdge(e, c); If(c and not edge(e), body)` with `c` tested once: the edge's old
    /// byte (loaded where `edge(e)` was defined), then `c`'s compare-and-branch chain to
    /// `yes`; the fall-through stores 0 and skips the body, `yes` skips the body when the old
    /// byte is 1 (which it keeps), else stores 1 and runs the body. (The generic form stores the 0/1 word of `c` and tests it
    /// again.) `mark`: the top-level statement index of the `if`, for the flow facts.
    fn edge_handler(
        &mut self,
        e: EdgeId,
        c: Value,
        fire: Value,
        body: &[Stmt],
        mark: Option<u32>,
    ) -> Result<(), ThumbError> {
        let (p, st) = (self.p, self.st);
        let Op::And(x, y) = p.values[fire.index()].op else {
            unreachable!("an edge handler fires on `c and not edge`")
        };
        let prev = [x, y]
            .into_iter()
            .find_map(|v| match p.values[v.index()].op {
                Op::Not(prev) if p.values[prev.index()].op == Op::Edge(e) => Some(prev),
                _ => None,
            })
            .expect("an edge handler's condition reads its edge");
        let old = self.word(prev);
        let (yes, skip) = (self.label(), self.label());
        self.branch(c, true, yes)?;
        let z = self.movi(0);
        self.store(MemOp::Strb, z, Base::State, st.edges + e.index());
        self.push(M::B(skip));
        self.push(M::Label(yes));
        // Where the old byte is 1 already, the body is skipped and no store is needed.
        self.push(M::CmpI { a: old.v, imm: 0 });
        self.push(M::Bc(Cond::Ne, skip));
        // (The mark starts the block after the branch: the flow facts name block starts.)
        if let Some(k) = mark {
            self.push(M::Mark(k));
        }
        let one = self.movi(1);
        self.store(MemOp::Strb, one, Base::State, st.edges + e.index());
        self.push(M::Note(format!("if {}", describe(p, c))));
        self.stmts(body)?;
        self.push(M::Label(skip));
        Ok(())
    }
}

/// A short source-level description of a condition value, for the listing and the WCET
/// report (`on hammer_hits_string`-style names come from the handler's span text).
fn describe(p: &Program, v: Value) -> String {
    let span = &p.values[v.index()].span;
    format!("condition v{} @{}..{}", v.0, span.start, span.end)
}

impl<'a> Sel<'a> {
    /// The body of `init`: zero the struct, then the initial states and modes.
    pub(crate) fn init_body(mut self) -> Selected {
        let (p, fp, st) = (self.p, self.fp, self.st);
        self.nv = FIRST_FREE;
        let z = self.movi(0);
        // Every word but the param block, which the firmware wrote before.
        let params = st.params / 4..st.params / 4 + fp.param_words.len();
        for w in (0..st.size / 4).filter(|w| !params.contains(w)) {
            self.store(MemOp::Str, z, Base::State, 4 * w);
        }
        for (i, &init) in fp.state_init.iter().enumerate() {
            if init != 0 {
                let k = self.movi(init);
                self.store(MemOp::Str, k, Base::State, st.states + 4 * i);
            }
        }
        for (i, md) in p.modes.iter().enumerate() {
            if md.init != 0 {
                let k = self.movi(md.init as i32);
                self.store(MemOp::Strb, k, Base::State, st.modes + i);
            }
        }
        Selected {
            code: self.code,
            nregs: self.nv,
            exclusive: Vec::new(),
        }
    }
}
