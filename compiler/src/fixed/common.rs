//! Common values: one computation for each value the body computes twice.
//!
//! Lowering writes what the source says, and the source says the same thing in several
//! places: the grand piano's contact compression `l2·θ − l3·s` and its rate appear in the
//! let-off re-arm condition, in the hammer–key impact and in the contact force, so
//! `key / l1`, `l2 · θ`, `l3 · s`, `l2 · d(key) / l1` and `l3 · w` are each computed two or
//! three times per sample — on the Cortex-M0+ each one a multi-`MULS` product. Before the
//! format plan the body is rewritten so that a value whose operation and operands equal an
//! earlier one's, and whose earlier definition dominates it (same or enclosing `if` body,
//! earlier in order), is that earlier value.
//!
//! A state, mode or edge read is the same value only while nothing wrote it in between:
//! every write (anywhere, also in a nested `if` body that may not run) starts a new
//! *generation* of what it writes, and reads of different generations never match. All other
//! operations are pure within a sample (sensors and their derivatives are fixed once the
//! histories are pushed), and equal operations on equal operands give equal ranges, so equal
//! formats and equal bits: the fixed-point meaning of the program does not change, only how
//! often each value is computed. Values no longer defined are dropped and the rest
//! renumbered in order, so every table of the plan sees only what runs.

use crate::ir::*;
use std::collections::HashMap;

/// The program with common values shared (see the module documentation). An already
/// shared program comes back unchanged.
pub fn share_common_values(p: &Program) -> Program {
    let n = p.values.len();
    let mut repl: Vec<Value> = (0..n as u32).map(Value).collect();
    let mut vn = repl.clone();
    let mut gens = Generations::default();
    let mut scopes: Vec<HashMap<Key, Value>> = vec![HashMap::new()];
    let body = rewrite(p, &p.body, &mut repl, &mut vn, &mut gens, &mut scopes);
    // Renumber the values still defined, in their old order (definitions precede uses).
    let mut defined = vec![false; n];
    mark(&body, &mut defined);
    // A value used without a definition of its own (none today) is kept too.
    for i in (0..n).rev() {
        if defined[i] {
            let used = std::cell::RefCell::new(Vec::new());
            map_op(&p.values[i].op, |x| {
                used.borrow_mut().push(repl[x.index()]);
                x
            });
            for u in used.into_inner() {
                defined[u.index()] = true;
            }
        }
    }
    let mut new_index = vec![u32::MAX; n];
    let mut values = Vec::with_capacity(n);
    for (i, vd) in p.values.iter().enumerate() {
        if defined[i] {
            new_index[i] = values.len() as u32;
            values.push(vd.clone());
        }
    }
    let map = |v: Value| Value(new_index[repl[v.index()].index()]);
    for vd in &mut values {
        vd.op = map_op(&vd.op, map);
    }
    let body = map_stmts(&body, &map);
    Program {
        values,
        body,
        ..p.clone()
    }
}

/// Per state, mode and edge: how many writes the walk has passed.
#[derive(Default)]
struct Generations {
    state: HashMap<StateId, u32>,
    mode: HashMap<ModeId, u32>,
    edge: HashMap<EdgeId, u32>,
}

/// What makes two definitions the same value: the operation on (already shared) operands,
/// the type, and for a read of a state, mode or edge the generation it reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Key {
    op: OpKey,
    ty: Ty,
    generation: u32,
}

/// An [`Op`] as a hashable key: a constant by its bits (every NaN one key, as its
/// printed form was), everything else as it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum OpKey {
    Const(u64),
    BoolConst(bool),
    Variant(ModeId, u32),
    Param(ParamId),
    Sensor(SensorId),
    Deriv(SensorId, u8),
    State(StateId),
    Mode(ModeId),
    Edge(EdgeId),
    Neg(Value),
    Not(Value),
    Arith(ArithOp, Value, Value),
    Cmp(CmpOp, Value, Value),
    And(Value, Value),
    Or(Value, Value),
    Select(Value, Value, Value),
    Call(Builtin, Value, Option<Value>),
}

impl OpKey {
    fn of(op: &Op) -> OpKey {
        match *op {
            Op::Const(c) if c.is_nan() => OpKey::Const(f64::NAN.to_bits()),
            Op::Const(c) => OpKey::Const(c.to_bits()),
            Op::BoolConst(b) => OpKey::BoolConst(b),
            Op::Variant(m, v) => OpKey::Variant(m, v),
            Op::Param(p) => OpKey::Param(p),
            Op::Sensor(s) => OpKey::Sensor(s),
            Op::Deriv(s, o) => OpKey::Deriv(s, o),
            Op::State(s) => OpKey::State(s),
            Op::Mode(m) => OpKey::Mode(m),
            Op::Edge(e) => OpKey::Edge(e),
            Op::Neg(x) => OpKey::Neg(x),
            Op::Not(x) => OpKey::Not(x),
            Op::Arith(o, x, y) => OpKey::Arith(o, x, y),
            Op::Cmp(o, x, y) => OpKey::Cmp(o, x, y),
            Op::And(x, y) => OpKey::And(x, y),
            Op::Or(x, y) => OpKey::Or(x, y),
            Op::Select(c, x, y) => OpKey::Select(c, x, y),
            Op::Call(b, x, y) => OpKey::Call(b, x, y),
        }
    }
}

pub(crate) fn map_op(op: &Op, f: impl Fn(Value) -> Value) -> Op {
    match *op {
        Op::Neg(x) => Op::Neg(f(x)),
        Op::Not(x) => Op::Not(f(x)),
        Op::Arith(o, x, y) => Op::Arith(o, f(x), f(y)),
        Op::Cmp(o, x, y) => Op::Cmp(o, f(x), f(y)),
        Op::And(x, y) => Op::And(f(x), f(y)),
        Op::Or(x, y) => Op::Or(f(x), f(y)),
        Op::Select(c, x, y) => Op::Select(f(c), f(x), f(y)),
        Op::Call(b, x, y) => Op::Call(b, f(x), y.map(&f)),
        ref other => other.clone(),
    }
}

fn rewrite(
    p: &Program,
    stmts: &[Stmt],
    repl: &mut [Value],
    vn: &mut [Value],
    gens: &mut Generations,
    scopes: &mut Vec<HashMap<Key, Value>>,
) -> Vec<Stmt> {
    let mut out = Vec::with_capacity(stmts.len());
    for s in stmts {
        let r = |v: Value, repl: &[Value]| repl[v.index()];
        match s {
            Stmt::Def(v) => {
                let vd = &p.values[v.index()];
                let op = map_op(&vd.op, |x| vn[x.index()]);
                let generation = match op {
                    Op::State(s) => *gens.state.get(&s).unwrap_or(&0),
                    Op::Mode(m) => *gens.mode.get(&m).unwrap_or(&0),
                    Op::Edge(e) => *gens.edge.get(&e).unwrap_or(&0),
                    _ => 0,
                };
                let key = Key {
                    op: OpKey::of(&op),
                    ty: vd.ty,
                    generation,
                };
                match scopes.iter().rev().find_map(|m| m.get(&key)) {
                    Some(&earlier) => {
                        vn[v.index()] = earlier;
                        if cheap_to_repeat(&vd.op) {
                            out.push(Stmt::Def(*v));
                        } else {
                            repl[v.index()] = earlier;
                        }
                    }
                    None => {
                        scopes.last_mut().expect("a scope").insert(key, *v);
                        out.push(Stmt::Def(*v));
                    }
                }
            }
            Stmt::SetState(st, v) => {
                *gens.state.entry(*st).or_default() += 1;
                out.push(Stmt::SetState(*st, r(*v, repl)));
            }
            Stmt::SetMode(m, k) => {
                *gens.mode.entry(*m).or_default() += 1;
                out.push(Stmt::SetMode(*m, *k));
            }
            Stmt::SetEdge(e, v) => {
                *gens.edge.entry(*e).or_default() += 1;
                out.push(Stmt::SetEdge(*e, r(*v, repl)));
            }
            Stmt::If(c, b) => {
                let c = r(*c, repl);
                scopes.push(HashMap::new());
                let b = rewrite(p, b, repl, vn, gens, scopes);
                scopes.pop();
                out.push(Stmt::If(c, b));
            }
            Stmt::Emit(e, args) => {
                out.push(Stmt::Emit(*e, args.iter().map(|a| r(*a, repl)).collect()))
            }
            Stmt::Force(f, v) => out.push(Stmt::Force(*f, r(*v, repl))),
            Stmt::Output(o, v) => out.push(Stmt::Output(*o, r(*v, repl))),
            Stmt::Total(v) => out.push(Stmt::Total(r(*v, repl))),
        }
    }
    out
}

/// Whether a repeated value is better read again than kept in a register: constants and
/// params (a literal or param-block `LDR`), sensor, state, mode and edge reads (one `LDR`
/// or `LDRB`, where keeping the word alive would spill it to the stack: a store and a load;
/// the harpsichord's update was 3 cycles slower so). They still match for the values
/// computed from them (two `select`s on equal conditions are one value).
fn cheap_to_repeat(op: &Op) -> bool {
    matches!(
        op,
        Op::Const(_)
            | Op::BoolConst(_)
            | Op::Variant(..)
            | Op::Param(_)
            | Op::Sensor(_)
            | Op::State(_)
            | Op::Mode(_)
            | Op::Edge(_)
    )
}

fn mark(stmts: &[Stmt], defined: &mut [bool]) {
    for s in stmts {
        match s {
            Stmt::Def(v) => defined[v.index()] = true,
            Stmt::If(c, b) => {
                defined[c.index()] = true;
                mark(b, defined)
            }
            Stmt::SetState(_, v)
            | Stmt::SetEdge(_, v)
            | Stmt::Force(_, v)
            | Stmt::Output(_, v)
            | Stmt::Total(v) => defined[v.index()] = true,
            Stmt::Emit(_, args) => args.iter().for_each(|a| defined[a.index()] = true),
            Stmt::SetMode(..) => {}
        }
    }
}

fn map_stmts(stmts: &[Stmt], f: &impl Fn(Value) -> Value) -> Vec<Stmt> {
    stmts
        .iter()
        .map(|s| match s {
            Stmt::Def(v) => Stmt::Def(f(*v)),
            Stmt::SetState(st, v) => Stmt::SetState(*st, f(*v)),
            Stmt::SetMode(m, k) => Stmt::SetMode(*m, *k),
            Stmt::SetEdge(e, v) => Stmt::SetEdge(*e, f(*v)),
            Stmt::If(c, b) => Stmt::If(f(*c), map_stmts(b, f)),
            Stmt::Emit(e, args) => Stmt::Emit(*e, args.iter().map(|a| f(*a)).collect()),
            Stmt::Force(fo, v) => Stmt::Force(*fo, f(*v)),
            Stmt::Output(o, v) => Stmt::Output(*o, f(*v)),
            Stmt::Total(v) => Stmt::Total(f(*v)),
        })
        .collect()
}
