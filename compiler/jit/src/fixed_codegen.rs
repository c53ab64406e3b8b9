//! Fixed-point IR → Cranelift IR: one function running a block of samples.
//!
//! Every IR value is one `i32` SSA value holding exactly the word the fixed interpreter
//! holds (raw fixed-point word, variant index, or 0/1). Every operation follows the rule of
//! `tactus_runtime::fixed`: the *exact* result, rounded half up to the result format
//! (`floor(v·2^fr + 1/2)`), saturated to `i32`.
//!
//! Each word carries, at compile time, an interval its raw value is known to lie in,
//! derived from what the native code itself enforces — sensor words saturated to their raw
//! ranges, state words to theirs, constants exact — through the exact operations. It is
//! never taken from the range analysis, whose claims the interpreter checks rather than
//! trusts, and host-call results get none. The exact intermediate of an operation is an
//! integer in some format with such an interval; the interval picks the cheapest exact
//! representation (`i32`, `i64`, or `i128` for alignments beyond 31 bits and large
//! derivative gains), drops the saturation sides that cannot fire, folds results that can
//! take one value only, and decides comparisons it already knows. Left shifts whose exact
//! result would not fit first clamp the operand to `±2^31` and shift by at most 31: the
//! result saturates exactly when the exact one would, to the same side.
//!
//! Comparisons with a constant (`tactus_runtime::fixed::cmp_const`) become integer
//! comparisons with thresholds found at compile time by binary search over the raw words,
//! *with `cmp_const` itself* as the predicate (`fixed::cmp_const_thresholds`, shared with the
//! C and Thumb backends), so they decide as the interpreter does on every word by
//! construction. Division by a non-constant, `sqrt` and `exp` call the runtime's own
//! functions through `extern "C"` wrappers.
//!
//! The sample loop keeps states, modes, edges, saturation counters and history positions
//! in Cranelift variables, so across the samples of a block they live in registers.

use crate::layout::{FixedLayout, HISTORY_LEN};
use crate::JitError;
use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, AbiParam, FuncRef, InstBuilder, MemFlagsData, Signature, Type};
use cranelift_frontend::{FunctionBuilder, Variable};
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

/// An exact intermediate: the integer `v` (type `ty`: `I32`, `I64` or `I128`) standing for
/// `v · 2^-frac`, known to lie in `[lo, hi]`. Every bound stays within `±2^126`.
#[derive(Clone, Copy, Debug)]
struct Wide {
    v: Cv,
    ty: Type,
    lo: i128,
    hi: i128,
    frac: i32,
    /// The same value as a word, when it came straight from one.
    narrow: Option<Word>,
}

/// A word: an `i32` SSA value and the interval its raw word is known to lie in, derived
/// from the sensors' and states' raw ranges (which the native code enforces) and the
/// constants, through the exact operations — never from the range analysis.
#[derive(Clone, Copy, Debug)]
struct Word {
    v: Cv,
    lo: i128,
    hi: i128,
}

impl Word {
    /// A word with no known bound.
    fn full(v: Cv) -> Word {
        Word {
            v,
            lo: I32_LO,
            hi: I32_HI,
        }
    }
}

const I32_LO: i128 = i32::MIN as i128;
const I32_HI: i128 = i32::MAX as i128;

fn fits64(lo: i128, hi: i128) -> bool {
    lo >= i64::MIN as i128 && hi <= i64::MAX as i128
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
    sensor_words: Vec<Word>,
    vals: Vec<Option<Word>>,
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
        let (ctx, sensors, n, out, sat, totals) = (
            params[0], params[1], params[2], params[3], params[4], params[5],
        );
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
        let total = b
            .ins()
            .load(types::I32, flags, self.out, word(self.layout.slots.total()));
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
            let (lo, hi) = fp.sensor_raw_range[i];
            self.sensor_words.push(Word {
                v: x,
                lo: i128::from(lo),
                hi: i128::from(hi),
            });
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
                    let (lo, hi) = (i128::from(lo), i128::from(hi));
                    let y = self.clamp_value(x.v, types::I32, x.lo, x.hi, lo, hi);
                    if x.lo < lo || x.hi > hi {
                        // Counted when the written word differs from the computed one.
                        let b = &mut self.b;
                        let changed = b.ins().icmp(IntCC::NotEqual, y, x.v);
                        let changed = b.ins().uextend(types::I64, changed);
                        let n = b.use_var(self.sats[i]);
                        let n = b.ins().iadd(n, changed);
                        b.def_var(self.sats[i], n);
                    }
                    self.b.def_var(self.states[i], y);
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
                    self.b.ins().brif(c.v, then, &[], join, &[]);
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
                            .store(self.flags, x.v, self.out, word(slot.offset + 1 + k));
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
        self.b.ins().store(self.flags, x.v, self.out, word(slot));
        Ok(())
    }

    fn val(&self, v: Value) -> Result<Word, JitError> {
        self.vals
            .get(v.index())
            .copied()
            .flatten()
            .ok_or(JitError::UndefinedValue { value: v })
    }

    /// 0/1 of `x != 0`, as an `i32`.
    fn truth(&mut self, x: Word) -> Cv {
        if x.lo == x.hi {
            return self.b.ins().iconst(types::I32, i64::from(x.lo != 0));
        }
        if x.lo >= 0 && x.hi <= 1 {
            return x.v;
        }
        let t = self.b.ins().icmp_imm_s(IntCC::NotEqual, x.v, 0);
        self.b.ins().uextend(types::I32, t)
    }

    fn bool_const(&mut self, t: bool) -> Cv {
        self.b.ins().iconst(types::I8, i64::from(t))
    }

    /// An `i8` truth value as a 0/1 word.
    fn bool_word(&mut self, t: Cv) -> Word {
        let v = self.b.ins().uextend(types::I32, t);
        Word { v, lo: 0, hi: 1 }
    }

    fn op(&mut self, v: Value) -> Result<Word, JitError> {
        let fp = self.fp;
        let p = &fp.program;
        let fr = fp.frac[v.index()];
        let frac = |x: Value| fp.frac[x.index()];
        if let Some(k) = fp.param_word_of(v) {
            // A run-time param: the key's word, clamped to the param's raw interval so that
            // the bounds this code relies on are its own.
            let (lo, hi) = fp.param_words[k].raw_range;
            let x = self.b.ins().load(
                types::I32,
                self.flags,
                self.ctx,
                word(self.layout.params + k),
            );
            let x = self.clamp_value(
                x,
                types::I32,
                i128::from(i32::MIN),
                i128::from(i32::MAX),
                i128::from(lo),
                i128::from(hi),
            );
            return Ok(Word {
                v: x,
                lo: i128::from(lo),
                hi: i128::from(hi),
            });
        }
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
                let i = s.index();
                let v = self.b.use_var(self.states[i]);
                let (lo, hi) = fp.state_raw_range[i];
                let init = fp.state_init[i];
                let x = Word {
                    v,
                    lo: i128::from(lo.min(init)),
                    hi: i128::from(hi.max(init)),
                };
                self.convert(x, fp.state_frac[i], fr)
            }
            Op::Mode(m) => Word::full(self.b.use_var(self.modes[m.index()])),
            Op::Edge(e) => Word {
                v: self.b.use_var(self.edges[e.index()]),
                lo: 0,
                hi: 1,
            },
            Op::Neg(x) => {
                let w = self.wide(self.val(x)?, frac(x));
                let w = self.neg(w);
                self.rescale(w, fr)
            }
            Op::Not(x) => {
                let x = self.val(x)?;
                let t = self.b.ins().icmp_imm_s(IntCC::Equal, x.v, 0);
                self.bool_word(t)
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
                        let wc = if o == ArithOp::Add { wc } else { self.neg(wc) };
                        let w = self.add(wa, wc);
                        self.rescale(w, fr)
                    }
                    ArithOp::Mul => self.product(fp.mul_kind[v.index()], (a, fa), (c, fc), fr),
                    ArithOp::Div => match fp.recip[v.index()] {
                        // A division by a constant: the product by its reciprocal word.
                        Some((r, f)) => {
                            let r = self.iconst(r);
                            self.product(fp.mul_kind[v.index()], (a, fa), (r, f), fr)
                        }
                        None => {
                            let b = fp.div_shift[v.index()].min(31);
                            let c = self.sshr(c, u32::from(b));
                            self.div(a, fa, c, fc - i32::from(b), fr)
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
                self.bool_word(t)
            }
            Op::And(x, y) | Op::Or(x, y) => {
                let (a, c) = (self.val(x)?, self.val(y)?);
                let (a, c) = (self.truth(a), self.truth(c));
                let t = if matches!(p.values[v.index()].op, Op::And(..)) {
                    self.b.ins().band(a, c)
                } else {
                    self.b.ins().bor(a, c)
                };
                Word { v: t, lo: 0, hi: 1 }
            }
            Op::Select(c, x, y) => {
                let c = self.val(c)?;
                let (a, c2) = (self.val(x)?, self.val(y)?);
                let (a, c2) = match p.values[v.index()].ty {
                    Ty::Real(_) => (self.convert(a, frac(x), fr), self.convert(c2, frac(y), fr)),
                    _ => (a, c2),
                };
                self.select(c.v, a, c2)
            }
            Op::Call(func, x, y) => {
                let (a, fa) = (self.val(x)?, frac(x));
                match func {
                    Builtin::Abs => {
                        // a < 0 ? neg(a) : convert(a) = |a| (exact in i64), rescaled.
                        let w = self.wide(a, fa);
                        let (lo, hi) = if w.lo >= 0 {
                            (w.lo, w.hi)
                        } else if w.hi <= 0 {
                            (-w.hi, -w.lo)
                        } else {
                            (0, w.hi.max(-w.lo))
                        };
                        let ty = ty_for(lo, hi);
                        let x = self.retype(w, ty);
                        let v = self.b.ins().iabs(x);
                        let w = Wide {
                            v,
                            ty,
                            lo,
                            hi,
                            frac: fa,
                            narrow: None,
                        };
                        self.rescale(w, fr)
                    }
                    Builtin::Sqrt => {
                        let args = [a.v, self.iconst(fa).v, self.iconst(fr).v];
                        // No interval: the runtime's function is the definition, whatever it
                        // returns (its `i128` shifts can wrap in extreme formats).
                        Word::full(self.call(self.host.sqrt, &args))
                    }
                    Builtin::Exp => {
                        let args = [a.v, self.iconst(fa).v, self.iconst(fr).v];
                        // No interval, not even `>= 0`: for large arguments the final
                        // `rescale` of `fixed::exp` shifts bits out of its `i128` and can
                        // return a negative word, which the definition makes the answer.
                        Word::full(self.call(self.host.exp, &args))
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
                        self.select(take_a, a, c)
                    }
                }
            }
        })
    }

    fn select(&mut self, c: Cv, a: Word, b: Word) -> Word {
        let v = self.b.ins().select(c, a.v, b.v);
        Word {
            v,
            lo: a.lo.min(b.lo),
            hi: a.hi.max(b.hi),
        }
    }

    fn iconst(&mut self, x: i32) -> Word {
        Word {
            v: self.b.ins().iconst(types::I32, i64::from(x)),
            lo: i128::from(x),
            hi: i128::from(x),
        }
    }

    fn call(&mut self, f: FuncRef, args: &[Cv]) -> Cv {
        let call = self.b.ins().call(f, args);
        self.b.inst_results(call)[0]
    }

    /// `fixed::div`, truncating toward zero; `y = 0` gives the sign of `x` saturated. With
    /// `k = fr − fx + fy`, the quotient is `(x·2^k) / y` (`k >= 0`) or `x / (y·2^-k)`: an
    /// `i64` division for `|k| <= 31`; for `k < −31` the divisor outweighs any `i32`, so the
    /// quotient is 0; for `k > 31` the runtime's function is called.
    fn div(&mut self, a: Word, fa: i32, c: Word, fc: i32, fr: i32) -> Word {
        let k = fr - fa + fc;
        if k > 31 {
            let args = [a.v, self.iconst(fa).v, c.v, self.iconst(fr).v];
            let args = [args[0], args[1], args[2], self.iconst(fc).v, args[3]];
            let v = self.call(self.host.div, &args);
            return Word::full(v);
        }
        let may_be_zero = c.lo <= 0 && c.hi >= 0;
        let b = &mut self.b;
        let q = if k < -31 {
            Word {
                v: b.ins().iconst(types::I32, 0),
                lo: 0,
                hi: 0,
            }
        } else {
            let one = b.ins().iconst(types::I32, 1);
            let y = if may_be_zero {
                let z = b.ins().icmp_imm_s(IntCC::Equal, c.v, 0);
                b.ins().select(z, one, c.v)
            } else {
                c.v
            };
            let n = b.ins().sextend(types::I64, a.v);
            let d = b.ins().sextend(types::I64, y);
            let (n, d) = if k >= 0 {
                (b.ins().ishl_imm_s(n, i64::from(k)), d)
            } else {
                (n, b.ins().ishl_imm_s(d, i64::from(-k)))
            };
            let q = b.ins().sdiv(n, d);
            let m = a.lo.abs().max(a.hi.abs()) << k.max(0);
            self.narrow(q, types::I64, -m, m)
        };
        if !may_be_zero {
            return q;
        }
        let b = &mut self.b;
        let max = b.ins().iconst(types::I32, I32_HI as i64);
        let min = b.ins().iconst(types::I32, I32_LO as i64);
        let zero = b.ins().iconst(types::I32, 0);
        let pos = b.ins().icmp_imm_s(IntCC::SignedGreaterThan, a.v, 0);
        let neg = b.ins().icmp_imm_s(IntCC::SignedLessThan, a.v, 0);
        let s = b.ins().select(neg, min, zero);
        let s = b.ins().select(pos, max, s);
        let z = b.ins().icmp_imm_s(IntCC::Equal, c.v, 0);
        let v = b.ins().select(z, s, q.v);
        Word::full(v)
    }

    /// `d()`/`d2()`: the exact history difference times the gain, rounded to `fr`. As the
    /// interpreter: order 1 takes `diff1`, every other order `diff2`; the gain is
    /// `deriv_gain[min(order − 1, 1)]` (order 0 takes gain 0); a sensor without history
    /// (not differentiated) differentiates to 0.
    fn deriv(&mut self, s: usize, order: u8, fr: i32) -> Word {
        let fp = self.fp;
        let (k, fk) = fp.deriv_gain[(order as usize).saturating_sub(1).min(1)];
        let from = fp.sensor_frac[s] + fk;
        let (Some((pos, _)), Some(at)) = (self.hist[s], self.layout.history[s]) else {
            return self.iconst(0);
        };
        let (slo, shi) = fp.sensor_raw_range[s];
        let span = i128::from(shi) - i128::from(slo);
        let x0 = self.sensor_words[s].v;
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

    /// A product `x·y` (words with their fraction bits) into `fr` fraction bits in the form the
    /// plan chose for it (`kind`: pre-shifted `MULS`, 32×16 with its cut operand, high word,
    /// else exact): the one dispatch for a product and a product by a reciprocal, as
    /// [`tactus_compiler::fixed::interp`] has it.
    fn product(&mut self, kind: Option<MulKind>, x: (Word, i32), y: (Word, i32), fr: i32) -> Word {
        let ((a, fa), (c, fc)) = (x, y);
        match kind {
            Some(MulKind::Muls(sa, sb)) => self.mul(a, fa, sa, c, fc, sb, fr),
            Some(MulKind::High(k)) => self.mul_high(a, fa, c, fc, k, fr),
            Some(MulKind::Mul32x16 { cut, b, k }) => {
                let ((a, fa), (c, fc)) = cut.kept_cut(x, y);
                self.mul_32x16(a, fa, c, fc, b, k, fr)
            }
            _ => self.mul(a, fa, 0, c, fc, 0, fr),
        }
    }

    /// `fixed::mul_shifted` (`fixed::mul` when `sa = sb = 0`): operands floored by `sa`,
    /// `sb` bits, their exact product rounded once.
    #[allow(clippy::too_many_arguments)]
    fn mul(&mut self, a: Word, fa: i32, sa: u8, c: Word, fc: i32, sb: u8, fr: i32) -> Word {
        let (ka, kc) = (u32::from(sa.min(31)), u32::from(sb.min(31)));
        let a = self.sshr(a, ka);
        let c = self.sshr(c, kc);
        let corners = [a.lo * c.lo, a.lo * c.hi, a.hi * c.lo, a.hi * c.hi];
        let lo = corners.iter().copied().min().unwrap_or(0);
        let hi = corners.iter().copied().max().unwrap_or(0);
        let ty = ty_for(lo, hi);
        let x = self.retype(self.wide(a, 0), ty);
        let y = self.retype(self.wide(c, 0), ty);
        let v = self.b.ins().imul(x, y);
        let w = Wide {
            v,
            ty,
            lo,
            hi,
            frac: fa - i32::from(sa) + fc - i32::from(sb),
            narrow: None,
        };
        self.rescale(w, fr)
    }

    /// `fixed::mul_high`: three 16×16 partial products (each exact in an `i32`: `|xh| ≤
    /// 2^15`, `0 ≤ yl < 2^16`) summed exactly in an `i64`, then rounded to `fr`.
    fn mul_high(&mut self, a: Word, fa: i32, c: Word, fc: i32, k: u8, fr: i32) -> Word {
        let k = i64::from(k.clamp(16, 32));
        let b = &mut self.b;
        let halves = |b: &mut FunctionBuilder, x: Cv| {
            let h = b.ins().sshr_imm_s(x, 16);
            let l = b.ins().band_imm_u(x, 0xffff);
            (h, l)
        };
        let (xh, xl) = halves(b, a.v);
        let (yh, yl) = halves(b, c.v);
        let hh = b.ins().imul(xh, yh);
        let hl = b.ins().imul(xh, yl);
        let lh = b.ins().imul(xl, yh);
        let hh = b.ins().sextend(types::I64, hh);
        let hh = b.ins().ishl_imm_s(hh, 32 - k);
        let hl = b.ins().sshr_imm_s(hl, k - 16);
        let hl = b.ins().sextend(types::I64, hl);
        let lh = b.ins().sshr_imm_s(lh, k - 16);
        let lh = b.ins().sextend(types::I64, lh);
        let p = b.ins().iadd(hh, hl);
        let p = b.ins().iadd(p, lh);
        // |p| ≤ (2^30·2^(32−k) + 2·2^31) for any words: within an i64.
        let m = (1i128 << (62 - k)) + (1i128 << 32);
        let w = Wide {
            v: p,
            ty: types::I64,
            lo: -m,
            hi: m,
            frac: fa + fc - k as i32,
            narrow: None,
        };
        self.rescale(w, fr)
    }

    /// `fixed::mul_32x16`: `c` cut to `ys = c >> b`, `a` split into its halves, the two
    /// partial products `xh·ys·2^(16−k)` and `floor(xl·ys / 2^k)` summed in an `i64` (exact
    /// for any words: `|xh·ys| ≤ 2^46`, `0 ≤ xl < 2^16`), then rounded to `fr`. The bounds
    /// come from the words' own (`a`'s, and `c`'s shifted), not from the plan.
    #[allow(clippy::too_many_arguments)]
    fn mul_32x16(&mut self, a: Word, fa: i32, c: Word, fc: i32, b: u8, k: u8, fr: i32) -> Word {
        let (b, k) = (u32::from(b.min(31)), i64::from(k.min(16)));
        let ys = self.sshr(c, b);
        let bb = &mut self.b;
        let xh = bb.ins().sshr_imm_s(a.v, 16);
        let xl = bb.ins().band_imm_u(a.v, 0xffff);
        let (xh, xl) = (
            bb.ins().sextend(types::I64, xh),
            bb.ins().sextend(types::I64, xl),
        );
        let y64 = bb.ins().sextend(types::I64, ys.v);
        let hh = bb.ins().imul(xh, y64);
        let hh = bb.ins().ishl_imm_s(hh, 16 - k);
        let ll = bb.ins().imul(xl, y64);
        let ll = bb.ins().sshr_imm_s(ll, k);
        let p = bb.ins().iadd(hh, ll);
        // Bounds: the corners of xh (a's high halves) and of [0, 2^16) against ys.
        let corners = |lo: i128, hi: i128| {
            let c = [lo * ys.lo, lo * ys.hi, hi * ys.lo, hi * ys.hi];
            (*c.iter().min().unwrap_or(&0), *c.iter().max().unwrap_or(&0))
        };
        let (hlo, hhi) = corners(a.lo >> 16, a.hi >> 16);
        let (llo, lhi) = corners(0, 0xffff);
        let w = Wide {
            v: p,
            ty: types::I64,
            lo: (hlo << (16 - k)) + (llo >> k),
            hi: (hhi << (16 - k)) + (lhi >> k),
            frac: fa + fc - b as i32 - k as i32,
            narrow: None,
        };
        self.rescale(w, fr)
    }

    /// `x >> s` (floor).
    fn sshr(&mut self, x: Word, s: u32) -> Word {
        if s == 0 {
            return x;
        }
        Word {
            v: self.b.ins().sshr_imm_s(x.v, i64::from(s)),
            lo: x.lo >> s,
            hi: x.hi >> s,
        }
    }

    /// The exact order of `a·2^-fa` and `c·2^-fc` under `cc`, as an `i8` truth value. The
    /// coarser operand is aligned by at most 32 bits: beyond 31, a non-zero operand already
    /// outweighs any `i32` of the finer format, so the order is unchanged.
    fn cmp(&mut self, cc: IntCC, a: Word, fa: i32, c: Word, fc: i32) -> Cv {
        if fa == fc {
            return self.b.ins().icmp(cc, a.v, c.v);
        }
        let (sa, sc) = if fa < fc {
            ((fc - fa).min(32) as u32, 0)
        } else {
            (0, (fa - fc).min(32) as u32)
        };
        let ty = ty_for((a.lo << sa).min(c.lo << sc), (a.hi << sa).max(c.hi << sc));
        let ty = if ty == types::I128 { types::I64 } else { ty };
        let x = self.retype(self.wide(a, 0), ty);
        let y = self.retype(self.wide(c, 0), ty);
        let b = &mut self.b;
        let x = if sa > 0 {
            b.ins().ishl_imm_s(x, i64::from(sa))
        } else {
            x
        };
        let y = if sc > 0 {
            b.ins().ishl_imm_s(y, i64::from(sc))
        } else {
            y
        };
        b.ins().icmp(cc, x, y)
    }

    /// `fixed::cmp_const(a, fa, k)` under `o` (with the order reversed when the constant is
    /// the left operand), as an `i8` truth value: integer thresholds on the raw word.
    fn cmp_const(&mut self, o: CmpOp, a: Word, fa: i32, k: f64, reversed: bool) -> Cv {
        // The order is Less below `l`, Greater from `g` on, Equal in between.
        let (l, g) = fx::cmp_const_thresholds(fa, k);
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

    /// `a < t` for a threshold `t` in `[i32::MIN, i32::MAX + 1]`, as an `i8`; a constant
    /// when `a`'s interval decides it.
    fn below(&mut self, a: Word, t: i64) -> Cv {
        let t128 = i128::from(t);
        if a.hi < t128 {
            self.bool_const(true)
        } else if a.lo >= t128 {
            self.bool_const(false)
        } else {
            self.b.ins().icmp_imm_s(IntCC::SignedLessThan, a.v, t)
        }
    }

    /// A word as an exact intermediate.
    fn wide(&self, x: Word, frac: i32) -> Wide {
        Wide {
            v: x.v,
            ty: types::I32,
            lo: x.lo,
            hi: x.hi,
            frac,
            narrow: Some(x),
        }
    }

    /// `w` in type `ty`: sign-extended to a wider type, or reduced to a narrower one —
    /// exact when `w`'s interval fits `ty`, and otherwise correct modulo `2^bits(ty)`, which
    /// suffices when only ring operations (add, neg, mul, shl) follow and their result fits.
    fn retype(&mut self, w: Wide, ty: Type) -> Cv {
        if w.ty == ty {
            w.v
        } else if w.ty.bits() < ty.bits() {
            self.b.ins().sextend(ty, w.v)
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
        let ty = ty_for(lo, hi);
        let x = self.retype(w, ty);
        let v = if ty == types::I128 {
            let s = self.b.ins().iconst(types::I64, i64::from(s));
            self.b.ins().ishl(x, s)
        } else {
            self.b.ins().ishl_imm_s(x, i64::from(s))
        };
        Wide {
            v,
            ty,
            lo,
            hi,
            frac,
            narrow: None,
        }
    }

    fn neg(&mut self, w: Wide) -> Wide {
        let (lo, hi) = (-w.hi, -w.lo);
        let ty = ty_for(lo, hi);
        let x = self.retype(w, ty);
        let v = self.b.ins().ineg(x);
        Wide {
            v,
            ty,
            lo,
            hi,
            frac: w.frac,
            narrow: None,
        }
    }

    /// Exact sum of two intermediates in the same format.
    fn add(&mut self, x: Wide, y: Wide) -> Wide {
        let (lo, hi) = (x.lo + y.lo, x.hi + y.hi);
        let ty = ty_for(lo, hi);
        let (a, c) = (self.retype(x, ty), self.retype(y, ty));
        let v = self.b.ins().iadd(a, c);
        Wide {
            v,
            ty,
            lo,
            hi,
            frac: x.frac,
            narrow: None,
        }
    }

    /// A word converted between formats: `fixed::convert`.
    fn convert(&mut self, x: Word, from: i32, to: i32) -> Word {
        if from == to {
            return x;
        }
        let w = self.wide(x, from);
        self.rescale(w, to)
    }

    /// `sat32(rescale(w, w.frac, to))`: rounded half up to `to`, saturated.
    fn rescale(&mut self, w: Wide, to: i32) -> Word {
        let s = to - w.frac;
        if s == 0 {
            if let Some(x) = w.narrow {
                return x;
            }
        }
        if s >= 0 {
            let s = s as u32;
            if s <= 62 && w.lo >= (i64::MIN >> s) as i128 && w.hi <= (i64::MAX >> s) as i128 {
                // Exact.
                let (lo, hi) = (w.lo << s, w.hi << s);
                let ty = ty_for(lo, hi);
                let x = self.retype(w, ty);
                let v = if s == 0 {
                    x
                } else {
                    self.b.ins().ishl_imm_s(x, i64::from(s))
                };
                return self.narrow(v, ty, lo, hi);
            }
            // Would not fit: clamp to ±2^31 (which saturates after any shift >= 1 exactly
            // when the exact value does, to the same side), shift at most 31 (2^31·2^31
            // fits an i64; any non-zero word shifted by 31 already saturates).
            let lim = 1i128 << 31;
            let (lo, hi) = (w.lo.max(-lim), w.hi.min(lim));
            let x = self.clamp_value(w.v, w.ty, w.lo, w.hi, -lim, lim);
            let ty = if w.ty == types::I128 {
                types::I64
            } else {
                w.ty
            };
            let x = self.retype(
                Wide {
                    v: x,
                    ty,
                    lo,
                    hi,
                    ..w
                },
                types::I64,
            );
            let s = s.min(31);
            let v = self.b.ins().ishl_imm_s(x, i64::from(s));
            return self.narrow(v, types::I64, lo << s, hi << s);
        }
        let r = (-s) as u32;
        if r > 126 {
            return self.iconst(0);
        }
        let half = 1i128 << (r - 1);
        let (lo, hi) = ((w.lo + half) >> r, (w.hi + half) >> r);
        if lo == hi {
            return self.iconst(lo.clamp(I32_LO, I32_HI) as i32);
        }
        let ty = ty_for(w.lo + half, w.hi + half);
        let x = self.retype(w, ty);
        let v = if ty == types::I128 {
            let h = self.const128(half);
            let x = self.b.ins().iadd(x, h);
            let r = self.b.ins().iconst(types::I64, i64::from(r));
            self.b.ins().sshr(x, r)
        } else {
            let x = self.b.ins().iadd_imm_s(x, half as i64);
            self.b.ins().sshr_imm_s(x, i64::from(r))
        };
        self.narrow(v, ty, lo, hi)
    }

    /// `v` (type `ty`, in `[vlo, vhi]`) clamped to `[lo, hi]`, only on the sides the
    /// interval crosses; an `i128` is first saturated to `i64` (see [`Self::sat64`]), so the
    /// result has type `i64` then (`lo`, `hi` must lie within `i64`).
    fn clamp_value(&mut self, v: Cv, ty: Type, vlo: i128, vhi: i128, lo: i128, hi: i128) -> Cv {
        let (mut v, ty) = if ty == types::I128 {
            (self.sat64(v), types::I64)
        } else {
            (v, ty)
        };
        let (vlo, vhi) = (vlo.max(i64::MIN as i128), vhi.min(i64::MAX as i128));
        if vlo < lo {
            let k = self.b.ins().iconst(ty, lo as i64);
            v = self.b.ins().smax(v, k);
        }
        if vhi > hi {
            let k = self.b.ins().iconst(ty, hi as i64);
            v = self.b.ins().smin(v, k);
        }
        v
    }

    /// An `i128` saturated to `i64`: the low half when the high half is its sign extension,
    /// else `i64::MIN`/`MAX` by the sign. (Cranelift's mid-end turns a compare-and-select on
    /// `i128` into `smin.i128`/`smax.i128`, which the x64 backend lacks; this avoids both.)
    /// Saturating to `i64` first does not change a later saturation to `i32`.
    fn sat64(&mut self, v: Cv) -> Cv {
        let b = &mut self.b;
        let (lo, hi) = b.ins().isplit(v);
        let sign = b.ins().sshr_imm_s(lo, 63);
        let fits = b.ins().icmp(IntCC::Equal, hi, sign);
        let neg = b.ins().icmp_imm_s(IntCC::SignedLessThan, hi, 0);
        let min = b.ins().iconst(types::I64, i64::MIN);
        let max = b.ins().iconst(types::I64, i64::MAX);
        let sat = b.ins().select(neg, min, max);
        b.ins().select(fits, lo, sat)
    }

    /// `sat32` of `v` (type `ty`, interval `[lo, hi]`) as a word.
    fn narrow(&mut self, v: Cv, ty: Type, lo: i128, hi: i128) -> Word {
        let (clo, chi) = (lo.clamp(I32_LO, I32_HI), hi.clamp(I32_LO, I32_HI));
        if clo == chi {
            return self.iconst(clo as i32);
        }
        // An i128 comes back as an i64.
        let v = self.clamp_value(v, ty, lo, hi, I32_LO, I32_HI);
        let v = if ty == types::I32 {
            v
        } else {
            self.b.ins().ireduce(types::I32, v)
        };
        Word {
            v,
            lo: clo,
            hi: chi,
        }
    }
}

/// The narrowest of `i32`, `i64`, `i128` holding `[lo, hi]`.
fn ty_for(lo: i128, hi: i128) -> Type {
    if lo >= I32_LO && hi <= I32_HI {
        types::I32
    } else if fits64(lo, hi) {
        types::I64
    } else {
        types::I128
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
