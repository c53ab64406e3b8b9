//! Fixed-point IR → Cranelift IR: one function running a block of samples.
//!
//! Every IR value is one `i32` SSA value holding exactly the word the fixed interpreter
//! holds (raw fixed-point word, variant index, or 0/1). Every operation follows the rule of
//! `tactus_runtime::fixed`: the *exact* result, rounded half up to the result format
//! (`floor(v·2^fr + 1/2)`), saturated to `i32`. The exact intermediate is a [`Wide`]: an
//! integer in some format together with the interval it lies in, known at compile time from
//! the formats alone (never from the range analysis, whose claims the interpreter checks
//! rather than trusts). The interval picks the cheapest exact representation — `i64` when
//! the intermediate and its rounding addend fit, `i128` otherwise (alignments by more than
//! 31 bits, large derivative gains) — and drops the saturation sides that cannot fire.
//! Left shifts whose exact result would not fit first clamp the operand to `±2^31` and shift
//! by at most 32: the result saturates exactly when the exact one would, to the same side.
//!
//! Comparisons with a constant (`tactus_runtime::fixed::cmp_const`) become integer
//! comparisons with thresholds found at compile time by binary search over the raw words,
//! *with `cmp_const` itself* as the predicate, so they decide as the interpreter does on every
//! word by construction. Division by a non-constant, `sqrt` and `exp` call the runtime's own
//! functions through `extern "C"` wrappers.
//!
//! The sample loop keeps states, modes, edges, saturation counters and history positions
//! in Cranelift variables, so across the samples of a block they live in registers.

use crate::fixed::{FixedLayout, HISTORY_LEN};
use crate::JitError;
use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, AbiParam, FuncRef, InstBuilder, MemFlagsData, Signature, Type};
use cranelift_frontend::{FunctionBuilder, Variable};
use std::cmp::Ordering;
use tactus_compiler::fixed::{FixedProgram, MulKind};
use tactus_compiler::ir::{ArithOp, Builtin, CmpOp, Op, Stmt, Ty, Value};
use tactus_runtime::differentiator::WINDOW;
use tactus_runtime::fixed as fx;

/// Name of the host symbol behind division by a non-constant.
pub const DIV_SYMBOL: &str = "tactus_jit_fixed_div";
/// Name of the host symbol behind `sqrt`.
pub const SQRT_SYMBOL: &str = "tactus_jit_fixed_sqrt";
/// Name of the host symbol behind `exp`.
pub const EXP_SYMBOL: &str = "tactus_jit_fixed_exp";

/// `tactus_runtime::fixed::div` for the native code.
pub extern "C" fn host_div(x: i32, fx_: i32, y: i32, fy: i32, fr: i32) -> i32 {
    fx::div(x, fx_, y, fy, fr).0
}
/// `tactus_runtime::fixed::sqrt` for the native code.
pub extern "C" fn host_sqrt(x: i32, fx_: i32, fr: i32) -> i32 {
    fx::sqrt(x, fx_, fr).0
}
/// `tactus_runtime::fixed::exp` for the native code.
pub extern "C" fn host_exp(x: i32, fx_: i32, fr: i32) -> i32 {
    fx::exp(x, fx_, fr).0
}

/// The signature of the block function: `(ctx, sensors, n, out, sat, totals)`, six
/// pointer-sized parameters (`n` as a pointer-sized integer), no result.
pub fn signature(pointer: Type, call_conv: cranelift_codegen::isa::CallConv) -> Signature {
    let mut sig = Signature::new(call_conv);
    for _ in 0..6 {
        sig.params.push(AbiParam::new(pointer));
    }
    sig
}

/// The signature of a host function: `n` `i32` parameters, one `i32` result.
pub fn host_signature(call_conv: cranelift_codegen::isa::CallConv, n: usize) -> Signature {
    let mut sig = Signature::new(call_conv);
    for _ in 0..n {
        sig.params.push(AbiParam::new(types::I32));
    }
    sig.returns.push(AbiParam::new(types::I32));
    sig
}

/// The host functions, imported into the function being built.
#[derive(Clone, Copy, Debug)]
pub struct HostFns {
    /// [`host_div`].
    pub div: FuncRef,
    /// [`host_sqrt`].
    pub sqrt: FuncRef,
    /// [`host_exp`].
    pub exp: FuncRef,
}

type Cv = cranelift_codegen::ir::Value;

/// An exact intermediate: the integer `v` (type `ty`, `I64` or `I128`) standing for
/// `v · 2^-frac`, known to lie in `[lo, hi]`. Every bound stays within `±2^126`.
#[derive(Clone, Copy, Debug)]
struct Wide {
    v: Cv,
    ty: Type,
    lo: i128,
    hi: i128,
    frac: i32,
    /// The same value as an `i32`, when it came straight from one.
    narrow: Option<Cv>,
}

const I32_LO: i128 = i32::MIN as i128;
const I32_HI: i128 = i32::MAX as i128;

fn fits64(lo: i128, hi: i128) -> bool {
    lo >= i64::MIN as i128 && hi <= i64::MAX as i128
}

/// Smallest raw word `a` (as `i64`, up to `i32::MAX + 1` when there is none) with `pred(a)`,
/// for a predicate that is false then true as `a` grows.
fn first_true(pred: impl Fn(i32) -> bool) -> i64 {
    let (mut lo, mut hi) = (i64::from(i32::MIN), i64::from(i32::MAX) + 1);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        // `mid <= i32::MAX` because `mid < hi`.
        if pred(mid as i32) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

/// Translates a verified fixed program into `b`, whose entry block is not yet created.
pub struct Translator<'a, 'f> {
    fp: &'a FixedProgram,
    layout: &'a FixedLayout,
    b: FunctionBuilder<'f>,
    host: HostFns,
    flags: MemFlagsData,
    ctx: Cv,
    out: Cv,
    sat: Cv,
    states: Vec<Variable>,
    modes: Vec<Variable>,
    edges: Vec<Variable>,
    sats: Vec<Variable>,
    /// Per sensor: its history's ring position and primed flag (differentiated sensors).
    hist: Vec<Option<(Variable, Variable)>>,
    /// Row pointer into `sensors`, remaining sample count, pointer into `totals`.
    row: Variable,
    remaining: Variable,
    totals: Variable,
    /// This sample's saturated sensor words.
    sensor_words: Vec<Cv>,
    vals: Vec<Option<Cv>>,
    next_event: usize,
    exit: cranelift_codegen::ir::Block,
    header: cranelift_codegen::ir::Block,
}

impl<'a, 'f> Translator<'a, 'f> {
    /// Emits the entry block (parameters, loads of the persistent variables) and the loop
    /// header; leaves the builder at the start of the loop body.
    pub fn new(
        fp: &'a FixedProgram,
        layout: &'a FixedLayout,
        mut b: FunctionBuilder<'f>,
        host: HostFns,
    ) -> Self {
        let entry = b.create_block();
        b.append_block_params_for_function_params(entry);
        b.switch_to_block(entry);
        let params = b.block_params(entry).to_vec();
        let (ctx, sensors, n, out, sat, totals) =
            (params[0], params[1], params[2], params[3], params[4], params[5]);
        let ptr = b.func.dfg.value_type(ctx);
        let flags = MemFlagsData::trusted();
        let l = &layout.slots;
        let load_vars =
            |b: &mut FunctionBuilder, n: usize, ty: Type, slot: &dyn Fn(usize) -> i32, base: Cv| {
                (0..n)
                    .map(|i| {
                        let var = b.declare_var(ty);
                        let x = b.ins().load(ty, flags, base, slot(i));
                        b.def_var(var, x);
                        var
                    })
                    .collect::<Vec<_>>()
            };
        let states = load_vars(&mut b, l.n_states, types::I32, &|i| word(l.state(i)), ctx);
        let modes = load_vars(&mut b, l.n_modes, types::I32, &|i| word(l.mode(i)), ctx);
        let edges = load_vars(&mut b, l.n_edges, types::I32, &|i| word(l.edge(i)), ctx);
        let sats = load_vars(&mut b, l.n_states, types::I64, &|i| offset(i, 8), sat);
        let hist = layout
            .history
            .iter()
            .map(|h| {
                h.map(|at| {
                    let v = load_vars(&mut b, 2, types::I32, &|i| word(at + i), ctx);
                    (v[0], v[1])
                })
            })
            .collect();
        let var = |b: &mut FunctionBuilder, x: Cv| {
            let v = b.declare_var(ptr);
            b.def_var(v, x);
            v
        };
        let row = var(&mut b, sensors);
        let remaining = var(&mut b, n);
        let totals = var(&mut b, totals);
        let header = b.create_block();
        let body = b.create_block();
        let exit = b.create_block();
        b.ins().jump(header, &[]);
        b.switch_to_block(header);
        let left = b.use_var(remaining);
        b.ins().brif(left, body, &[], exit, &[]);
        b.switch_to_block(body);
        Translator {
            fp,
            layout,
            b,
            host,
            flags,
            ctx,
            out,
            sat,
            states,
            modes,
            edges,
            sats,
            hist,
            row,
            remaining,
            totals,
            sensor_words: Vec::new(),
            vals: vec![None; fp.program.values.len()],
            next_event: 0,
            exit,
            header,
        }
    }

    /// Translates one sample (sensor rows, histories, event flags, the body, the total),
    /// closes the loop, stores the persistent variables back and returns.
    pub fn finish(mut self) -> Result<FunctionBuilder<'f>, JitError> {
        self.sample_prologue();
        let p = &self.fp.program;
        self.stmts(&p.body)?;
        let (b, flags) = (&mut self.b, self.flags);
        // The total of this sample, then the next row.
        let total = b.ins().load(
            types::I32,
            flags,
            self.out,
            word(self.layout.slots.total()),
        );
        let t = b.use_var(self.totals);
        b.ins().store(flags, total, t, 0);
        let t = b.ins().iadd_imm_s(t, 4);
        b.def_var(self.totals, t);
        let r = b.use_var(self.row);
        let r = b.ins().iadd_imm_s(r, 4 * self.sensor_words.len() as i64);
        b.def_var(self.row, r);
        let n = b.use_var(self.remaining);
        let n = b.ins().iadd_imm_s(n, -1);
        b.def_var(self.remaining, n);
        b.ins().jump(self.header, &[]);

        b.switch_to_block(self.exit);
        let l = &self.layout.slots;
        let persistent = self
            .states
            .iter()
            .enumerate()
            .map(|(i, &v)| (v, l.state(i)))
            .chain(self.modes.iter().enumerate().map(|(i, &v)| (v, l.mode(i))))
            .chain(self.edges.iter().enumerate().map(|(i, &v)| (v, l.edge(i))));
        for (var, slot) in persistent {
            let x = b.use_var(var);
            b.ins().store(flags, x, self.ctx, word(slot));
        }
        for (i, &var) in self.sats.iter().enumerate() {
            let x = b.use_var(var);
            b.ins().store(flags, x, self.sat, offset(i, 8));
        }
        for (h, at) in self.hist.iter().zip(&self.layout.history) {
            if let (Some((pos, primed)), Some(at)) = (h, at) {
                let x = b.use_var(*pos);
                b.ins().store(flags, x, self.ctx, word(*at));
                let x = b.use_var(*primed);
                b.ins().store(flags, x, self.ctx, word(*at + 1));
            }
        }
        b.ins().return_(&[]);
        self.b.seal_all_blocks();
        Ok(self.b)
    }

    /// Reads and saturates this sample's sensor row, pushes the differentiated readings into
    /// their histories, clears the event flags.
    fn sample_prologue(&mut self) {
        let fp = self.fp;
        let flags = self.flags;
        let row = self.b.use_var(self.row);
        for (i, &(lo, hi)) in fp.sensor_raw_range.iter().enumerate() {
            let b = &mut self.b;
            let x = b.ins().load(types::I32, flags, row, word(i));
            let lo = b.ins().iconst(types::I32, i64::from(lo));
            let hi = b.ins().iconst(types::I32, i64::from(hi));
            let x = b.ins().smax(x, lo);
            let x = b.ins().smin(x, hi);
            self.sensor_words.push(x);
            if let (Some((pos, primed)), Some(at)) = (self.hist[i], self.layout.history[i]) {
                self.push_history(x, pos, primed, at);
            }
        }
        let zero = self.b.ins().iconst(types::I32, 0);
        for slot in &self.layout.slots.events {
            self.b
                .ins()
                .store(self.flags, zero, self.out, word(slot.offset));
        }
    }

    /// `RawHistory::push`: prime the ring with the first reading, advance, store (twice).
    fn push_history(&mut self, x: Cv, pos: Variable, primed: Variable, at: usize) {
        let (flags, ctx) = (self.flags, self.ctx);
        let b = &mut self.b;
        let ring = at + 2;
        let is_primed = b.use_var(primed);
        let fill = b.create_block();
        let go = b.create_block();
        b.ins().brif(is_primed, go, &[], fill, &[]);
        b.switch_to_block(fill);
        for k in 0..2 * HISTORY_LEN {
            b.ins().store(flags, x, ctx, word(ring + k));
        }
        let one = b.ins().iconst(types::I32, 1);
        b.def_var(primed, one);
        b.ins().jump(go, &[]);
        b.switch_to_block(go);
        let p = b.use_var(pos);
        let p1 = b.ins().iadd_imm_s(p, 1);
        let wrap = b.ins().icmp_imm_s(IntCC::Equal, p1, HISTORY_LEN as i64);
        let zero = b.ins().iconst(types::I32, 0);
        let p = b.ins().select(wrap, zero, p1);
        b.def_var(pos, p);
        let addr = self.ring_addr(p, at);
        let b = &mut self.b;
        b.ins().store(flags, x, addr, word(2));
        b.ins().store(flags, x, addr, word(2 + HISTORY_LEN));
    }

    /// `ctx + 4·(at + pos)` for the ring position `pos` (an `i32`).
    fn ring_addr(&mut self, pos: Cv, at: usize) -> Cv {
        let b = &mut self.b;
        let ptr = b.func.dfg.value_type(self.ctx);
        let p = b.ins().uextend(ptr, pos);
        let p = b.ins().ishl_imm_s(p, 2);
        let base = b.ins().iadd(self.ctx, p);
        b.ins().iadd_imm_s(base, 4 * at as i64)
    }

    /// The reading `k` samples ago of the history at `at` (`k <= 2N`).
    fn ago(&mut self, pos: Variable, at: usize, k: usize) -> Cv {
        let p = self.b.use_var(pos);
        let addr = self.ring_addr(p, at);
        self.b
            .ins()
            .load(types::I32, self.flags, addr, word(2 + HISTORY_LEN - k))
    }

    fn stmts(&mut self, stmts: &[Stmt]) -> Result<(), JitError> {
        let fp = self.fp;
        for s in stmts {
            match s {
                Stmt::Def(v) => {
                    let x = self.op(*v)?;
                    self.vals[v.index()] = Some(x);
                }
                Stmt::SetState(st, v) => {
                    let i = st.index();
                    let x = self.val(*v)?;
                    let x = self.convert(x, fp.frac[v.index()], fp.state_frac[i]);
                    let (lo, hi) = fp.state_raw_range[i];
                    let b = &mut self.b;
                    let lo = b.ins().iconst(types::I32, i64::from(lo));
                    let hi = b.ins().iconst(types::I32, i64::from(hi));
                    let y = b.ins().smax(x, lo);
                    let y = b.ins().smin(y, hi);
                    let changed = b.ins().icmp(IntCC::NotEqual, y, x);
                    let changed = b.ins().uextend(types::I64, changed);
                    let n = b.use_var(self.sats[i]);
                    let n = b.ins().iadd(n, changed);
                    b.def_var(self.sats[i], n);
                    b.def_var(self.states[i], y);
                }
                Stmt::SetMode(m, i) => {
                    let x = self.b.ins().iconst(types::I32, i64::from(*i as i32));
                    self.b.def_var(self.modes[m.index()], x);
                }
                Stmt::SetEdge(e, v) => {
                    let x = self.val(*v)?;
                    let x = self.truth(x);
                    self.b.def_var(self.edges[e.index()], x);
                }
                Stmt::If(c, inner) => {
                    let c = self.val(*c)?;
                    let then = self.b.create_block();
                    let join = self.b.create_block();
                    self.b.ins().brif(c, then, &[], join, &[]);
                    self.b.switch_to_block(then);
                    self.stmts(inner)?;
                    self.b.ins().jump(join, &[]);
                    self.b.switch_to_block(join);
                }
                Stmt::Emit(e, args) => {
                    let slot = self
                        .layout
                        .slots
                        .events
                        .get(self.next_event)
                        .cloned()
                        .ok_or(JitError::Internal("event slots"))?;
                    self.next_event += 1;
                    let formats = &fp.event_frac[e.index()];
                    for (k, (a, &f)) in args.iter().zip(formats).enumerate() {
                        let x = self.val(*a)?;
                        let x = self.convert(x, fp.frac[a.index()], f);
                        self.b
                            .ins()
                            .store(self.flags, x, self.out, word(slot.offset + 1 + k));
                    }
                    let one = self.b.ins().iconst(types::I32, 1);
                    self.b
                        .ins()
                        .store(self.flags, one, self.out, word(slot.offset));
                }
                Stmt::Force(f, v) => self.publish(f.index(), *v)?,
                Stmt::Output(o, v) => self.publish(self.layout.slots.output(o.index()), *v)?,
                Stmt::Total(v) => self.publish(self.layout.slots.total(), *v)?,
            }
        }
        Ok(())
    }

    fn publish(&mut self, slot: usize, v: Value) -> Result<(), JitError> {
        let x = self.val(v)?;
        self.b.ins().store(self.flags, x, self.out, word(slot));
        Ok(())
    }

    fn val(&self, v: Value) -> Result<Cv, JitError> {
        self.vals
            .get(v.index())
            .copied()
            .flatten()
            .ok_or(JitError::UndefinedValue { value: v })
    }

    /// 0/1 of `x != 0`, as an `i32`.
    fn truth(&mut self, x: Cv) -> Cv {
        let t = self.b.ins().icmp_imm_s(IntCC::NotEqual, x, 0);
        self.b.ins().uextend(types::I32, t)
    }

    fn bool_const(&mut self, t: bool) -> Cv {
        self.b.ins().iconst(types::I8, i64::from(t))
    }

    fn op(&mut self, v: Value) -> Result<Cv, JitError> {
        let fp = self.fp;
        let p = &fp.program;
        let fr = fp.frac[v.index()];
        let frac = |x: Value| fp.frac[x.index()];
        Ok(match p.values[v.index()].op {
            Op::Const(_) | Op::Param(_) => self.iconst(fp.consts[v.index()]),
            Op::BoolConst(t) => self.iconst(i32::from(t)),
            Op::Variant(_, i) => self.iconst(i as i32),
            Op::Sensor(s) => {
                let x = *self
                    .sensor_words
                    .get(s.index())
                    .ok_or(JitError::Internal("sensor words"))?;
                self.convert(x, fp.sensor_frac[s.index()], fr)
            }
            Op::Deriv(s, order) => self.deriv(s.index(), order, fr),
            Op::State(s) => {
                let x = self.b.use_var(self.states[s.index()]);
                self.convert(x, fp.state_frac[s.index()], fr)
            }
            Op::Mode(m) => self.b.use_var(self.modes[m.index()]),
            Op::Edge(e) => self.b.use_var(self.edges[e.index()]),
            Op::Neg(x) => {
                let w = self.wide(self.val(x)?, frac(x));
                let w = self.neg(w);
                self.rescale(w, fr)
            }
            Op::Not(x) => {
                let x = self.val(x)?;
                let t = self.b.ins().icmp_imm_s(IntCC::Equal, x, 0);
                self.b.ins().uextend(types::I32, t)
            }
            Op::Arith(o, x, y) => {
                let (a, fa, c, fc) = (self.val(x)?, frac(x), self.val(y)?, frac(y));
                match o {
                    ArithOp::Add | ArithOp::Sub => {
                        let f = fa.max(fc);
                        let wa = self.wide(a, fa);
                        let wa = self.shl(wa, (f - fa) as u32);
                        let wc = self.wide(c, fc);
                        let wc = self.shl(wc, (f - fc) as u32);
                        let w = if o == ArithOp::Add {
                            self.add(wa, wc)
                        } else {
                            let wc = self.neg(wc);
                            self.add(wa, wc)
                        };
                        self.rescale(w, fr)
                    }
                    ArithOp::Mul => match fp.mul_kind[v.index()] {
                        Some(MulKind::Muls(sa, sb)) => self.mul_shifted(a, fa, sa, c, fc, sb, fr),
                        _ => self.mul(a, fa, c, fc, fr),
                    },
                    ArithOp::Div => match (fp.recip[v.index()], fp.mul_kind[v.index()]) {
                        (Some((r, f)), Some(MulKind::Muls(sa, sb))) => {
                            let r = self.iconst(r);
                            self.mul_shifted(a, fa, sa, r, f, sb, fr)
                        }
                        (Some((r, f)), _) => {
                            let r = self.iconst(r);
                            self.mul(a, fa, r, f, fr)
                        }
                        (None, _) => {
                            let args = [a, self.iconst(fa), c, self.iconst(fc), self.iconst(fr)];
                            self.call(self.host.div, &args)
                        }
                    },
                }
            }
            Op::Cmp(o, x, y) => {
                let real = |w: Value| matches!(p.values[w.index()].ty, Ty::Real(_));
                let t = match (fp.exact_const(x), fp.exact_const(y)) {
                    (_, Some(k)) if real(x) => {
                        let a = self.val(x)?;
                        self.cmp_const(o, a, frac(x), k, false)
                    }
                    (Some(k), _) if real(y) => {
                        let c = self.val(y)?;
                        self.cmp_const(o, c, frac(y), k, true)
                    }
                    _ => {
                        let (a, c) = (self.val(x)?, self.val(y)?);
                        let cc = match o {
                            CmpOp::Eq => IntCC::Equal,
                            CmpOp::Ne => IntCC::NotEqual,
                            CmpOp::Lt => IntCC::SignedLessThan,
                            CmpOp::Le => IntCC::SignedLessThanOrEqual,
                            CmpOp::Gt => IntCC::SignedGreaterThan,
                            CmpOp::Ge => IntCC::SignedGreaterThanOrEqual,
                        };
                        self.cmp(cc, a, frac(x), c, frac(y))
                    }
                };
                self.b.ins().uextend(types::I32, t)
            }
            Op::And(x, y) | Op::Or(x, y) => {
                let (a, c) = (self.val(x)?, self.val(y)?);
                let b = &mut self.b;
                let a = b.ins().icmp_imm_s(IntCC::NotEqual, a, 0);
                let c = b.ins().icmp_imm_s(IntCC::NotEqual, c, 0);
                let t = if matches!(p.values[v.index()].op, Op::And(..)) {
                    b.ins().band(a, c)
                } else {
                    b.ins().bor(a, c)
                };
                b.ins().uextend(types::I32, t)
            }
            Op::Select(c, x, y) => {
                let c = self.val(c)?;
                let (a, c2) = (self.val(x)?, self.val(y)?);
                let (a, c2) = match p.values[v.index()].ty {
                    Ty::Real(_) => (self.convert(a, frac(x), fr), self.convert(c2, frac(y), fr)),
                    _ => (a, c2),
                };
                self.b.ins().select(c, a, c2)
            }
            Op::Call(func, x, y) => {
                let (a, fa) = (self.val(x)?, frac(x));
                match func {
                    Builtin::Abs => {
                        // a < 0 ? neg(a) : convert(a) = |a| (exact in i64), rescaled.
                        let w = self.wide(a, fa);
                        let m = self.b.ins().iabs(w.v);
                        let w = Wide {
                            v: m,
                            lo: 0,
                            hi: -I32_LO,
                            narrow: None,
                            ..w
                        };
                        self.rescale(w, fr)
                    }
                    Builtin::Sqrt => {
                        let args = [a, self.iconst(fa), self.iconst(fr)];
                        self.call(self.host.sqrt, &args)
                    }
                    Builtin::Exp => {
                        let args = [a, self.iconst(fa), self.iconst(fr)];
                        self.call(self.host.exp, &args)
                    }
                    Builtin::Min | Builtin::Max => {
                        let (c, fc) = match y {
                            Some(y) => (self.val(y)?, frac(y)),
                            None => (a, fa),
                        };
                        // min takes a when a <= c, max when a >= c (exact values).
                        let cc = if func == Builtin::Min {
                            IntCC::SignedLessThanOrEqual
                        } else {
                            IntCC::SignedGreaterThanOrEqual
                        };
                        let take_a = self.cmp(cc, a, fa, c, fc);
                        let a = self.convert(a, fa, fr);
                        let c = self.convert(c, fc, fr);
                        self.b.ins().select(take_a, a, c)
                    }
                }
            }
        })
    }

    fn iconst(&mut self, x: i32) -> Cv {
        self.b.ins().iconst(types::I32, i64::from(x))
    }

    fn call(&mut self, f: FuncRef, args: &[Cv]) -> Cv {
        let call = self.b.ins().call(f, args);
        self.b.inst_results(call)[0]
    }

    /// `d()`/`d2()`: the exact history difference times the gain, rounded to `fr`. As the
    /// interpreter: order 1 takes `diff1`, every other order `diff2`; the gain is
    /// `deriv_gain[min(order − 1, 1)]` (order 0 takes gain 0); a sensor without history
    /// (not differentiated) differentiates to 0.
    fn deriv(&mut self, s: usize, order: u8, fr: i32) -> Cv {
        let fp = self.fp;
        let (k, fk) = fp.deriv_gain[(order as usize).saturating_sub(1).min(1)];
        let from = fp.sensor_frac[s] + fk;
        let (Some((pos, _)), Some(at)) = (self.hist[s], self.layout.history[s]) else {
            return self.iconst(0);
        };
        let (slo, shi) = fp.sensor_raw_range[s];
        let span = i128::from(shi) - i128::from(slo);
        let x0 = self.sensor_words[s];
        let b = &mut self.b;
        let x0 = b.ins().sextend(types::I64, x0);
        let x8 = self.ago(pos, at, WINDOW);
        let x8 = self.b.ins().sextend(types::I64, x8);
        let (d, bound) = if order == 1 {
            (self.b.ins().isub(x0, x8), span)
        } else {
            let x16 = self.ago(pos, at, 2 * WINDOW);
            let b = &mut self.b;
            let x16 = b.ins().sextend(types::I64, x16);
            let t = b.ins().ishl_imm_s(x8, 1);
            let d = b.ins().isub(x0, t);
            (b.ins().iadd(d, x16), 2 * span)
        };
        let k = i128::from(k);
        let (lo, hi) = ((-bound * k).min(bound * k), (-bound * k).max(bound * k));
        let (v, ty) = if fits64(lo, hi) {
            (self.b.ins().imul_imm_s(d, k as i64), types::I64)
        } else {
            let b = &mut self.b;
            let d = b.ins().sextend(types::I128, d);
            let kk = b.ins().iconst(types::I64, k as i64);
            let kk = b.ins().sextend(types::I128, kk);
            (b.ins().imul(d, kk), types::I128)
        };
        let w = Wide {
            v,
            ty,
            lo,
            hi,
            frac: from,
            narrow: None,
        };
        self.rescale(w, fr)
    }

    /// `fixed::mul`: the exact 64-bit product rounded once.
    fn mul(&mut self, a: Cv, fa: i32, c: Cv, fc: i32, fr: i32) -> Cv {
        let wa = self.wide(a, fa);
        let wc = self.wide(c, fc);
        let v = self.b.ins().imul(wa.v, wc.v);
        let m = I32_LO * I32_LO;
        let w = Wide {
            v,
            ty: types::I64,
            lo: I32_LO * I32_HI,
            hi: m,
            frac: fa + fc,
            narrow: None,
        };
        self.rescale(w, fr)
    }

    /// `fixed::mul_shifted`: operands floored by `sa`, `sb` bits, exact product rounded once.
    #[allow(clippy::too_many_arguments)]
    fn mul_shifted(&mut self, a: Cv, fa: i32, sa: u8, c: Cv, fc: i32, sb: u8, fr: i32) -> Cv {
        let (ka, kc) = (sa.min(31), sb.min(31));
        let b = &mut self.b;
        let a = b.ins().sshr_imm_s(a, i64::from(ka));
        let c = b.ins().sshr_imm_s(c, i64::from(kc));
        let (alo, ahi) = (I32_LO >> ka, I32_HI >> ka);
        let (clo, chi) = (I32_LO >> kc, I32_HI >> kc);
        let corners = [alo * clo, alo * chi, ahi * clo, ahi * chi];
        let a = b.ins().sextend(types::I64, a);
        let c = b.ins().sextend(types::I64, c);
        let v = b.ins().imul(a, c);
        let w = Wide {
            v,
            ty: types::I64,
            lo: corners.iter().copied().min().unwrap_or(0),
            hi: corners.iter().copied().max().unwrap_or(0),
            frac: fa - i32::from(sa) + fc - i32::from(sb),
            narrow: None,
        };
        self.rescale(w, fr)
    }

    /// The exact order of `a·2^-fa` and `c·2^-fc` under `cc`, as an `i8` truth value. The
    /// coarser operand is aligned by at most 32 bits: beyond 31, a non-zero operand already
    /// outweighs any `i32` of the finer format, so the order is unchanged.
    fn cmp(&mut self, cc: IntCC, a: Cv, fa: i32, c: Cv, fc: i32) -> Cv {
        if fa == fc {
            return self.b.ins().icmp(cc, a, c);
        }
        let b = &mut self.b;
        let mut a = b.ins().sextend(types::I64, a);
        let mut c = b.ins().sextend(types::I64, c);
        if fa < fc {
            a = b.ins().ishl_imm_s(a, i64::from((fc - fa).min(32)));
        } else {
            c = b.ins().ishl_imm_s(c, i64::from((fa - fc).min(32)));
        }
        b.ins().icmp(cc, a, c)
    }

    /// `fixed::cmp_const(a, fa, k)` under `o` (with the order reversed when the constant is
    /// the left operand), as an `i8` truth value: integer thresholds on the raw word.
    fn cmp_const(&mut self, o: CmpOp, a: Cv, fa: i32, k: f64, reversed: bool) -> Cv {
        // The order is Less below `l`, Greater from `g` on, Equal in between.
        let l = first_true(|x| fx::cmp_const(x, fa, k) != Ordering::Less);
        let g = first_true(|x| fx::cmp_const(x, fa, k) == Ordering::Greater);
        // Which order (of the word against k) makes the comparison true.
        let (less, equal, greater) = match o {
            CmpOp::Eq => (false, true, false),
            CmpOp::Ne => (true, false, true),
            CmpOp::Lt => (true, false, false),
            CmpOp::Le => (true, true, false),
            CmpOp::Gt => (false, false, true),
            CmpOp::Ge => (false, true, true),
        };
        let (less, greater) = if reversed {
            (greater, less)
        } else {
            (less, greater)
        };
        match (less, equal, greater) {
            (false, false, false) => self.bool_const(false),
            (true, true, true) => self.bool_const(true),
            (true, false, false) => self.below(a, l),
            (true, true, false) => self.below(a, g),
            (false, true, true) => {
                let t = self.below(a, l);
                self.b.ins().bxor_imm_u(t, 1)
            }
            (false, false, true) => {
                let t = self.below(a, g);
                self.b.ins().bxor_imm_u(t, 1)
            }
            (false, true, false) => {
                let lo = self.below(a, l);
                let hi = self.below(a, g);
                // l <= a < g
                let lo = self.b.ins().bxor_imm_u(lo, 1);
                self.b.ins().band(lo, hi)
            }
            (true, false, true) => {
                let lo = self.below(a, l);
                let hi = self.below(a, g);
                let hi = self.b.ins().bxor_imm_u(hi, 1);
                self.b.ins().bor(lo, hi)
            }
        }
    }

    /// `a < t` for a threshold `t` in `[i32::MIN, i32::MAX + 1]`, as an `i8`.
    fn below(&mut self, a: Cv, t: i64) -> Cv {
        if t <= i64::from(i32::MIN) {
            self.bool_const(false)
        } else if t > i64::from(i32::MAX) {
            self.bool_const(true)
        } else {
            self.b.ins().icmp_imm_s(IntCC::SignedLessThan, a, t)
        }
    }

    /// An `i32` word as an exact intermediate.
    fn wide(&mut self, x: Cv, frac: i32) -> Wide {
        let v = self.b.ins().sextend(types::I64, x);
        Wide {
            v,
            ty: types::I64,
            lo: I32_LO,
            hi: I32_HI,
            frac,
            narrow: Some(x),
        }
    }

    /// `w` in type `ty` (widening always; narrowing only when its interval fits).
    fn retype(&mut self, w: Wide, ty: Type) -> Cv {
        if w.ty == ty {
            w.v
        } else if ty == types::I128 {
            self.b.ins().sextend(types::I128, w.v)
        } else {
            self.b.ins().ireduce(ty, w.v)
        }
    }

    /// An `i128` constant.
    fn const128(&mut self, x: i128) -> Cv {
        let b = &mut self.b;
        let lo = b.ins().iconst(types::I64, x as u64 as i64);
        let hi = b.ins().iconst(types::I64, (x >> 64) as i64);
        b.ins().iconcat(lo, hi)
    }

    /// `w · 2^s` in format `frac + s`, exact (`s <= 94`, so bounds stay within `±2^126`).
    fn shl(&mut self, w: Wide, s: u32) -> Wide {
        if s == 0 {
            return w;
        }
        let (lo, hi) = (w.lo << s, w.hi << s);
        let frac = w.frac + s as i32;
        if fits64(lo, hi) {
            let x = self.retype(w, types::I64);
            let v = self.b.ins().ishl_imm_s(x, i64::from(s));
            Wide { v, ty: types::I64, lo, hi, frac, narrow: None }
        } else {
            let x = self.retype(w, types::I128);
            let s = self.b.ins().iconst(types::I64, i64::from(s));
            let v = self.b.ins().ishl(x, s);
            Wide { v, ty: types::I128, lo, hi, frac, narrow: None }
        }
    }

    fn neg(&mut self, w: Wide) -> Wide {
        let (lo, hi) = (-w.hi, -w.lo);
        let ty = if fits64(lo, hi) { w.ty } else { types::I128 };
        let x = self.retype(w, ty);
        let v = self.b.ins().ineg(x);
        Wide { v, ty, lo, hi, frac: w.frac, narrow: None }
    }

    /// Exact sum of two intermediates in the same format.
    fn add(&mut self, x: Wide, y: Wide) -> Wide {
        let (lo, hi) = (x.lo + y.lo, x.hi + y.hi);
        let ty = if fits64(lo, hi) && x.ty == types::I64 && y.ty == types::I64 {
            types::I64
        } else {
            types::I128
        };
        let (a, c) = (self.retype(x, ty), self.retype(y, ty));
        let v = self.b.ins().iadd(a, c);
        Wide { v, ty, lo, hi, frac: x.frac, narrow: None }
    }

    /// A word converted between formats: `fixed::convert`.
    fn convert(&mut self, x: Cv, from: i32, to: i32) -> Cv {
        if from == to {
            return x;
        }
        let w = self.wide(x, from);
        self.rescale(w, to)
    }

    /// `sat32(rescale(w, w.frac, to))`: rounded half up to `to`, saturated.
    fn rescale(&mut self, w: Wide, to: i32) -> Cv {
        let s = to - w.frac;
        if s == 0 {
            if let Some(x) = w.narrow {
                return x;
            }
        }
        if s >= 0 {
            let s = s as u32;
            if s <= 62 && w.lo >= (i64::MIN >> s) as i128 && w.hi <= (i64::MAX >> s) as i128 {
                // Exact in i64.
                let x = self.retype(w, types::I64);
                let v = if s == 0 { x } else { self.b.ins().ishl_imm_s(x, i64::from(s)) };
                return self.narrow(v, types::I64, w.lo << s, w.hi << s);
            }
            // Would not fit: clamp to ±2^31 (which saturates after any shift >= 1 exactly
            // when the exact value does, to the same side), shift at most 32.
            let lim = 1i128 << 31;
            let (lo, hi) = (w.lo.max(-lim), w.hi.min(lim));
            let x = self.clamp(w, -lim, lim);
            let x = if w.ty == types::I128 {
                self.b.ins().ireduce(types::I64, x)
            } else {
                x
            };
            let s = s.min(32);
            let v = self.b.ins().ishl_imm_s(x, i64::from(s));
            return self.narrow(v, types::I64, lo << s, hi << s);
        }
        let r = (-s) as u32;
        if r > 126 {
            return self.b.ins().iconst(types::I32, 0);
        }
        let half = 1i128 << (r - 1);
        let (lo, hi) = ((w.lo + half) >> r, (w.hi + half) >> r);
        if lo == hi {
            let c = lo.clamp(I32_LO, I32_HI);
            return self.b.ins().iconst(types::I32, c as i64);
        }
        if fits64(w.lo + half, w.hi + half) && r < 64 {
            let x = self.retype(w, types::I64);
            let x = self.b.ins().iadd_imm_s(x, half as i64);
            let v = self.b.ins().sshr_imm_s(x, i64::from(r));
            self.narrow(v, types::I64, lo, hi)
        } else {
            let x = self.retype(w, types::I128);
            let h = self.const128(half);
            let x = self.b.ins().iadd(x, h);
            let r = self.b.ins().iconst(types::I64, i64::from(r));
            let v = self.b.ins().sshr(x, r);
            self.narrow(v, types::I128, lo, hi)
        }
    }

    /// `w.v` clamped to `[lo, hi]` (in `w.ty`), only on the sides `w`'s interval crosses.
    fn clamp(&mut self, w: Wide, lo: i128, hi: i128) -> Cv {
        self.clamp_value(w.v, w.ty, w.lo, w.hi, lo, hi)
    }

    fn clamp_value(&mut self, mut v: Cv, ty: Type, vlo: i128, vhi: i128, lo: i128, hi: i128) -> Cv {
        for (bound, crosses, cc) in [
            (lo, vlo < lo, IntCC::SignedLessThan),
            (hi, vhi > hi, IntCC::SignedGreaterThan),
        ] {
            if !crosses {
                continue;
            }
            if ty == types::I128 {
                let k = self.const128(bound);
                let out = self.b.ins().icmp(cc, v, k);
                v = self.b.ins().select(out, k, v);
            } else {
                let k = self.b.ins().iconst(ty, bound as i64);
                v = if cc == IntCC::SignedLessThan {
                    self.b.ins().smax(v, k)
                } else {
                    self.b.ins().smin(v, k)
                };
            }
        }
        v
    }

    /// `sat32` of `v` (type `ty`, interval `[lo, hi]`) as an `i32`.
    fn narrow(&mut self, v: Cv, ty: Type, lo: i128, hi: i128) -> Cv {
        if lo == hi {
            let c = lo.clamp(I32_LO, I32_HI);
            return self.b.ins().iconst(types::I32, c as i64);
        }
        let v = self.clamp_value(v, ty, lo, hi, I32_LO, I32_HI);
        let v = if ty == types::I128 {
            self.b.ins().ireduce(types::I64, v)
        } else {
            v
        };
        self.b.ins().ireduce(types::I32, v)
    }
}

/// Byte offset of word `i` of a 4-byte buffer. `FixedJitProgram::compile` rejects layouts
/// with more than `i32::MAX / 8` words, so the conversion never saturates.
fn word(i: usize) -> i32 {
    offset(i, 4)
}

fn offset(i: usize, size: usize) -> i32 {
    i32::try_from(i.saturating_mul(size)).unwrap_or(i32::MAX)
}
