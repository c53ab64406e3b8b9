//! IR → Cranelift IR: one function per program, run once per sample.
//!
//! The IR is already SSA with structured control flow, so the translation is a single walk
//! of the body: each IR [`Value`] becomes one Cranelift SSA value, [`Stmt::If`] a
//! conditional branch around its body, [`Op::Select`] a `select`. States, modes, edge
//! memories and saturation counters are loaded into Cranelift variables on entry and stored
//! back on exit, so within a sample they live in registers and the frontend builds the phis
//! at the joins of `if` bodies.
//!
//! Truth values: the interpreter holds every value as `f64`, truth values as exactly 0.0 or
//! 1.0 and reads any `f64` as true when it is `!= 0.0`. Here a value produced by a
//! comparison, `not`, `and`, `or`, a `true`/`false` constant or an edge memory (or a
//! `select` between two such) is held as an `i8` 0/1 instead — exactly the values the
//! interpreter would hold, so the conversions at the boundaries (`i8 → f64` by selecting
//! 1.0/0.0, `f64 → i8` by `!= 0.0`) are lossless. Which representation a value has depends
//! only on how it is computed, never on its declared type.
//!
//! Floating point: every operation is the IEEE operation the interpreter's Rust code
//! performs, in the same order, so results are bit-identical. `exp` calls a host function
//! holding the interpreter's own expression (`x.exp()`). `sqrt`, `min` and `max` are inline
//! and follow the interpreter's explicit definitions ([`tactus_compiler::interp::sqrt`],
//! [`min`](tactus_compiler::interp::min), [`max`](tactus_compiler::interp::max)):
//! `sqrt(x) = if x > 0 { √x } else { +0 }` (IEEE `sqrt` is correctly rounded, so the
//! instruction and Rust's `f64::sqrt` agree) and `max(a, b) = if a.is_nan() { b } else if
//! b > a { b } else { a }`, so even the sign of a zero result agrees in every build profile
//! (`f64::max` leaves it open, and rustc's choice for `x.max(0.0)` once depended on the
//! optimisation level).
//! profile. State writes saturate as `f64::clamp` does (`x < lo`, then `x > hi`; NaN → lo).

use crate::layout::Layout;
use crate::JitError;
use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{types, AbiParam, FuncRef, InstBuilder, MemFlagsData, Signature, Type};
use cranelift_frontend::{FunctionBuilder, Variable};
use tactus_compiler::ir::{ArithOp, Builtin, CmpOp, Op, Program, Stmt, Value};

/// Name of the host symbol behind `exp`.
pub const EXP_SYMBOL: &str = "tactus_jit_exp";

/// `exp` for the native code: the very function the interpreter calls.
pub extern "C" fn host_exp(x: f64) -> f64 {
    x.exp()
}

/// The signature of a compiled program: `(ctx, inputs, out, sat)`, four pointers, no
/// result, in the target's default calling convention (the C one on every host Cranelift
/// supports).
pub fn signature(pointer: Type, call_conv: cranelift_codegen::isa::CallConv) -> Signature {
    let mut sig = Signature::new(call_conv);
    for _ in 0..4 {
        sig.params.push(AbiParam::new(pointer));
    }
    sig
}

/// The host functions the native code calls, imported into the function being built.
#[derive(Clone, Copy, Debug)]
pub struct HostFns {
    /// [`host_exp`].
    pub exp: FuncRef,
}

/// The signature of the host functions: `f64 → f64`.
pub fn host_signature(call_conv: cranelift_codegen::isa::CallConv) -> Signature {
    let mut sig = Signature::new(call_conv);
    sig.params.push(AbiParam::new(types::F64));
    sig.returns.push(AbiParam::new(types::F64));
    sig
}

/// How one IR value is held (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Repr {
    /// An `f64`.
    F64,
    /// An `i8` that is 0 or 1.
    Bool,
}

type Cv = cranelift_codegen::ir::Value;

/// Translates a verified program's body into `b`, whose entry block is not yet created.
pub struct Translator<'a, 'f> {
    program: &'a Program,
    layout: &'a Layout,
    b: FunctionBuilder<'f>,
    host: HostFns,
    flags: MemFlagsData,
    /// Function parameters: ctx, inputs, out, sat.
    ctx: Cv,
    inputs: Cv,
    out: Cv,
    sat: Cv,
    states: Vec<Variable>,
    modes: Vec<Variable>,
    edges: Vec<Variable>,
    sats: Vec<Variable>,
    vals: Vec<Option<(Cv, Repr)>>,
    next_event: usize,
}

impl<'a, 'f> Translator<'a, 'f> {
    /// Emits the entry block: parameters, loads of the persistent variables, clearing of
    /// the event flags.
    pub fn new(
        program: &'a Program,
        layout: &'a Layout,
        mut b: FunctionBuilder<'f>,
        host: HostFns,
    ) -> Self {
        let entry = b.create_block();
        b.append_block_params_for_function_params(entry);
        b.switch_to_block(entry);
        let params = b.block_params(entry).to_vec();
        let (ctx, inputs, out, sat) = (params[0], params[1], params[2], params[3]);
        let flags = MemFlagsData::trusted();
        let load_vars = |b: &mut FunctionBuilder,
                         n: usize,
                         ty: Type,
                         slot: &dyn Fn(usize) -> usize,
                         base: Cv| {
            (0..n)
                .map(|i| {
                    let var = b.declare_var(ty);
                    let x = b.ins().load(ty, flags, base, offset(slot(i)));
                    b.def_var(var, x);
                    var
                })
                .collect::<Vec<_>>()
        };
        let states = load_vars(
            &mut b,
            layout.n_states,
            types::F64,
            &|i| layout.state(i),
            ctx,
        );
        let modes = load_vars(&mut b, layout.n_modes, types::F64, &|i| layout.mode(i), ctx);
        let sats = load_vars(&mut b, layout.n_states, types::I64, &|i| i, sat);
        let edges = (0..layout.n_edges)
            .map(|i| {
                let var = b.declare_var(types::I8);
                let x = b.ins().load(types::F64, flags, ctx, offset(layout.edge(i)));
                let zero = b.ins().f64const(0.0);
                let x = b.ins().fcmp(FloatCC::NotEqual, x, zero);
                b.def_var(var, x);
                var
            })
            .collect();
        if !layout.events.is_empty() {
            let zero = b.ins().f64const(0.0);
            for slot in &layout.events {
                b.ins().store(flags, zero, out, offset(slot.offset));
            }
        }
        Translator {
            program,
            layout,
            b,
            host,
            flags,
            ctx,
            inputs,
            out,
            sat,
            states,
            modes,
            edges,
            sats,
            vals: vec![None; program.values.len()],
            next_event: 0,
        }
    }

    /// Translates the body, stores the persistent variables back and returns.
    pub fn finish(mut self) -> Result<FunctionBuilder<'f>, JitError> {
        let p = self.program;
        self.stmts(&p.body)?;
        let (b, flags, l) = (&mut self.b, self.flags, self.layout);
        for (i, &var) in self.states.iter().enumerate() {
            let x = b.use_var(var);
            b.ins().store(flags, x, self.ctx, offset(l.state(i)));
        }
        for (i, &var) in self.modes.iter().enumerate() {
            let x = b.use_var(var);
            b.ins().store(flags, x, self.ctx, offset(l.mode(i)));
        }
        for (i, &var) in self.edges.iter().enumerate() {
            let x = b.use_var(var);
            let x = bool_to_f64(b, x);
            b.ins().store(flags, x, self.ctx, offset(l.edge(i)));
        }
        for (i, &var) in self.sats.iter().enumerate() {
            let x = b.use_var(var);
            b.ins().store(flags, x, self.sat, offset(i));
        }
        b.ins().return_(&[]);
        self.b.seal_all_blocks();
        Ok(self.b)
    }

    fn stmts(&mut self, stmts: &[Stmt]) -> Result<(), JitError> {
        let p = self.program;
        for s in stmts {
            match s {
                Stmt::Def(v) => {
                    let op = &p
                        .values
                        .get(v.index())
                        .ok_or(JitError::UndefinedValue { value: *v })?
                        .op;
                    let x = self.op(op)?;
                    self.vals[v.index()] = Some(x);
                }
                Stmt::SetState(st, v) => {
                    let i = st.index();
                    let (lo, hi) = p.states[i].range;
                    let x = self.f64(*v)?;
                    let b = &mut self.b;
                    let (lo, hi) = (b.ins().f64const(lo), b.ins().f64const(hi));
                    // f64::clamp: `if x < lo { lo }`, then `if x > hi { hi }`; NaN → lo.
                    let below = b.ins().fcmp(FloatCC::LessThan, x, lo);
                    let y = b.ins().select(below, lo, x);
                    let above = b.ins().fcmp(FloatCC::GreaterThan, y, hi);
                    let y = b.ins().select(above, hi, y);
                    let nan = b.ins().fcmp(FloatCC::Unordered, x, x);
                    let y = b.ins().select(nan, lo, y);
                    // Counted when the written value differs from the computed one.
                    let changed = b.ins().fcmp(FloatCC::NotEqual, y, x);
                    let changed = b.ins().uextend(types::I64, changed);
                    let n = b.use_var(self.sats[i]);
                    let n = b.ins().iadd(n, changed);
                    b.def_var(self.sats[i], n);
                    b.def_var(self.states[i], y);
                }
                Stmt::SetMode(m, i) => {
                    let x = self.b.ins().f64const(f64::from(*i));
                    self.b.def_var(self.modes[m.index()], x);
                }
                Stmt::SetEdge(e, v) => {
                    let x = self.bool(*v)?;
                    self.b.def_var(self.edges[e.index()], x);
                }
                Stmt::If(c, inner) => {
                    let c = self.bool(*c)?;
                    let then = self.b.create_block();
                    let join = self.b.create_block();
                    self.b.ins().brif(c, then, &[], join, &[]);
                    self.b.switch_to_block(then);
                    self.stmts(inner)?;
                    self.b.ins().jump(join, &[]);
                    self.b.switch_to_block(join);
                    // Values defined in the body are out of scope after it (verified).
                }
                Stmt::Emit(_, args) => {
                    let slot = self
                        .layout
                        .events
                        .get(self.next_event)
                        .cloned()
                        .ok_or(JitError::Internal("event slots"))?;
                    self.next_event += 1;
                    for (k, a) in args.iter().enumerate() {
                        let x = self.f64(*a)?;
                        self.b
                            .ins()
                            .store(self.flags, x, self.out, offset(slot.offset + 1 + k));
                    }
                    let one = self.b.ins().f64const(1.0);
                    self.b
                        .ins()
                        .store(self.flags, one, self.out, offset(slot.offset));
                }
                Stmt::Force(f, v) => self.publish(f.index(), *v)?,
                Stmt::Output(o, v) => self.publish(self.layout.output(o.index()), *v)?,
                Stmt::Total(v) => self.publish(self.layout.total(), *v)?,
            }
        }
        Ok(())
    }

    fn publish(&mut self, slot: usize, v: Value) -> Result<(), JitError> {
        let x = self.f64(v)?;
        self.b.ins().store(self.flags, x, self.out, offset(slot));
        Ok(())
    }

    fn get(&self, v: Value) -> Result<(Cv, Repr), JitError> {
        self.vals
            .get(v.index())
            .copied()
            .flatten()
            .ok_or(JitError::UndefinedValue { value: v })
    }

    /// The value as an `f64` (truth values as 0.0/1.0).
    fn f64(&mut self, v: Value) -> Result<Cv, JitError> {
        Ok(match self.get(v)? {
            (x, Repr::F64) => x,
            (x, Repr::Bool) => bool_to_f64(&mut self.b, x),
        })
    }

    /// The value as an `i8` truth value (an `f64` is true when `!= 0.0`, NaN included).
    fn bool(&mut self, v: Value) -> Result<Cv, JitError> {
        Ok(match self.get(v)? {
            (x, Repr::Bool) => x,
            (x, Repr::F64) => {
                let zero = self.b.ins().f64const(0.0);
                self.b.ins().fcmp(FloatCC::NotEqual, x, zero)
            }
        })
    }

    fn op(&mut self, op: &Op) -> Result<(Cv, Repr), JitError> {
        let p = self.program;
        let l = self.layout;
        let (flags, inputs) = (self.flags, self.inputs);
        let f = |x| (x, Repr::F64);
        Ok(match *op {
            Op::Const(c) => f(self.b.ins().f64const(c)),
            Op::BoolConst(x) => (self.b.ins().iconst(types::I8, i64::from(x)), Repr::Bool),
            Op::Variant(_, i) => f(self.b.ins().f64const(f64::from(i))),
            Op::Param(x) => f(self.b.ins().f64const(p.params[x.index()].value)),
            Op::Sensor(s) => f(self
                .b
                .ins()
                .load(types::F64, flags, inputs, offset(s.index()))),
            Op::Deriv(s, order) => {
                let order = if order == 1 { 1 } else { 2 };
                let slot = l
                    .derivs
                    .iter()
                    .find(|d| d.sensor == s && d.order == order)
                    .ok_or(JitError::Internal("derivative slots"))?;
                f(self
                    .b
                    .ins()
                    .load(types::F64, flags, inputs, offset(slot.offset)))
            }
            Op::State(s) => f(self.b.use_var(self.states[s.index()])),
            Op::Mode(m) => f(self.b.use_var(self.modes[m.index()])),
            Op::Edge(e) => (self.b.use_var(self.edges[e.index()]), Repr::Bool),
            Op::Neg(x) => {
                let x = self.f64(x)?;
                f(self.b.ins().fneg(x))
            }
            Op::Not(x) => {
                let x = self.bool(x)?;
                (self.b.ins().icmp_imm_u(IntCC::Equal, x, 0), Repr::Bool)
            }
            Op::Arith(o, x, y) => {
                let (x, y) = (self.f64(x)?, self.f64(y)?);
                let ins = self.b.ins();
                f(match o {
                    ArithOp::Add => ins.fadd(x, y),
                    ArithOp::Sub => ins.fsub(x, y),
                    ArithOp::Mul => ins.fmul(x, y),
                    ArithOp::Div => ins.fdiv(x, y),
                })
            }
            Op::Cmp(o, x, y) => {
                let r = if self.get(x)?.1 == Repr::Bool && self.get(y)?.1 == Repr::Bool {
                    // Both 0/1: unsigned integer order is the f64 order.
                    let (x, y) = (self.get(x)?.0, self.get(y)?.0);
                    let cc = match o {
                        CmpOp::Eq => IntCC::Equal,
                        CmpOp::Ne => IntCC::NotEqual,
                        CmpOp::Lt => IntCC::UnsignedLessThan,
                        CmpOp::Le => IntCC::UnsignedLessThanOrEqual,
                        CmpOp::Gt => IntCC::UnsignedGreaterThan,
                        CmpOp::Ge => IntCC::UnsignedGreaterThanOrEqual,
                    };
                    self.b.ins().icmp(cc, x, y)
                } else {
                    let (x, y) = (self.f64(x)?, self.f64(y)?);
                    // Rust's operators: `==` and the orderings are false on NaN, `!=` true.
                    let cc = match o {
                        CmpOp::Eq => FloatCC::Equal,
                        CmpOp::Ne => FloatCC::NotEqual,
                        CmpOp::Lt => FloatCC::LessThan,
                        CmpOp::Le => FloatCC::LessThanOrEqual,
                        CmpOp::Gt => FloatCC::GreaterThan,
                        CmpOp::Ge => FloatCC::GreaterThanOrEqual,
                    };
                    self.b.ins().fcmp(cc, x, y)
                };
                (r, Repr::Bool)
            }
            Op::And(x, y) => {
                let (x, y) = (self.bool(x)?, self.bool(y)?);
                (self.b.ins().band(x, y), Repr::Bool)
            }
            Op::Or(x, y) => {
                let (x, y) = (self.bool(x)?, self.bool(y)?);
                (self.b.ins().bor(x, y), Repr::Bool)
            }
            Op::Select(c, x, y) => {
                let c = self.bool(c)?;
                if self.get(x)?.1 == Repr::Bool && self.get(y)?.1 == Repr::Bool {
                    let (x, y) = (self.get(x)?.0, self.get(y)?.0);
                    (self.b.ins().select(c, x, y), Repr::Bool)
                } else {
                    let (x, y) = (self.f64(x)?, self.f64(y)?);
                    f(self.b.ins().select(c, x, y))
                }
            }
            Op::Call(func, x, y) => {
                let x = self.f64(x)?;
                let y = match y {
                    Some(y) => self.f64(y)?,
                    None => self.b.ins().f64const(0.0),
                };
                let b = &mut self.b;
                f(match func {
                    Builtin::Abs => b.ins().fabs(x),
                    Builtin::Sqrt => {
                        // if x > 0 { sqrt(x) } else { +0 } (NaN > 0 is false).
                        let zero = b.ins().f64const(0.0);
                        let pos = b.ins().fcmp(FloatCC::GreaterThan, x, zero);
                        let arg = b.ins().select(pos, x, zero);
                        b.ins().sqrt(arg)
                    }
                    Builtin::Exp => {
                        let call = b.ins().call(self.host.exp, &[x]);
                        b.inst_results(call)[0]
                    }
                    // a.min(b) / a.max(b): `if a.is_nan() { b } else if b <> a { b } else { a }`.
                    Builtin::Min => min_max(b, FloatCC::LessThan, x, y),
                    Builtin::Max => min_max(b, FloatCC::GreaterThan, x, y),
                })
            }
        })
    }
}

fn min_max(b: &mut FunctionBuilder, cc: FloatCC, x: Cv, y: Cv) -> Cv {
    let take_y = b.ins().fcmp(cc, y, x);
    let r = b.ins().select(take_y, y, x);
    let nan = b.ins().fcmp(FloatCC::Unordered, x, x);
    b.ins().select(nan, y, r)
}

fn bool_to_f64(b: &mut FunctionBuilder, x: Cv) -> Cv {
    let one = b.ins().f64const(1.0);
    let zero = b.ins().f64const(0.0);
    b.ins().select(x, one, zero)
}

/// Byte offset of slot `i`. `JitProgram::compile` rejects layouts whose buffers have more
/// than `i32::MAX / 8` slots, so the conversion never saturates.
fn offset(i: usize) -> i32 {
    i32::try_from(i.saturating_mul(8)).unwrap_or(i32::MAX)
}
