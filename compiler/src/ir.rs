//! The IR: one flat program per instrument, components already instanced.
//!
//! Declarations live in tables indexed by `u32` newtypes ([`SensorId`], [`StateId`], …);
//! computed values live in one table indexed by [`Value`], each defined exactly once by a
//! [`Stmt::Def`] that precedes every use (structured control flow: the only branch is
//! [`Stmt::If`], and a value defined inside its body is not used after it). The body is the
//! whole per-sample update in execution order, so every engine — the f64 reference
//! interpreter, the fixed-point interpreter, the JIT, the Thumb and C backends — runs the same
//! statement list. All quantities are SI (the lexer converts units); [`Ty`] records the
//! dimension of each value, which the backends use for range analysis and reports.
//!
//! Per-sample semantics (the full text is in `docs/language.md`, "Execution model"):
//! 1. sensors are read and the differentiators behind `d()`/`d2()` take the new sample;
//! 2. event handlers run in source order (`on`: rising edge; `while`: level);
//! 3. force terms and outputs are computed, and the total force as their sum in declaration
//!    order (for a pen instrument one sum per axis: `x` and `y` as the outputs `force.x`,
//!    `force.y`, `z` as the total; see [`Program::force_axes`]);
//! 4. the dynamics equations are applied in source order (semi-implicit Euler).

use crate::ast::Span;
use crate::units::Dim;
use std::fmt;

macro_rules! entity {
    ($(#[$m:meta])* $name:ident, $prefix:literal) => {
        $(#[$m])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub struct $name(pub u32);
        impl $name {
            /// The index into its table.
            pub fn index(self) -> usize {
                self.0 as usize
            }
        }
        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, concat!($prefix, "{}"), self.0)
            }
        }
    };
}

entity!(
    /// A computed value (SSA): index into [`Program::values`].
    Value, "v"
);
entity!(
    /// A sensor input: index into [`Program::sensors`].
    SensorId, "sensor"
);
entity!(
    /// A param: index into [`Program::params`]. A compile-time constant unless the param is
    /// run-time data ([`ParamDecl::runtime`]).
    ParamId, "param"
);
entity!(
    /// A continuous state: index into [`Program::states`].
    StateId, "state"
);
entity!(
    /// An enumerated mode: index into [`Program::modes`].
    ModeId, "mode"
);
entity!(
    /// A force term: index into [`Program::forces`].
    ForceId, "force"
);
entity!(
    /// A traced output: index into [`Program::outputs`].
    OutputId, "output"
);
entity!(
    /// A kind of emitted event: index into [`Program::events`].
    EventId, "event"
);
entity!(
    /// The remembered condition of an `on` handler: index into [`Program::edges`].
    EdgeId, "edge"
);

/// The type of a value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Ty {
    /// A real quantity of the given dimension, in SI.
    Real(Dim),
    /// A truth value (engines may hold it as 0/1).
    Bool,
    /// A variant index of the given mode.
    Mode(ModeId),
}

/// A sensor: read once per sample from the outside world.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorDecl {
    /// Source name.
    pub name: String,
    /// Dimension (SI).
    pub dim: Dim,
    /// Declared range `[lo, hi]` in SI; the range analysis starts from it.
    pub range: (f64, f64),
    /// Whether `d()`/`d2()` is taken of it (engines keep its history only then).
    pub differentiated: bool,
    /// Declaration span.
    pub span: Span,
}

/// A param: a constant, folded at compile time (after `--param` overrides), or — in a
/// program shared by keys that give it different values ([`crate::share`]) — run-time data:
/// a word of the key's param block, planned over the interval the keys span.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamDecl {
    /// Source name, qualified by the instance for component params (`esc.peak`); for a
    /// param-derived word of a shared program, the expression it stands for.
    pub name: String,
    /// Dimension.
    pub dim: Dim,
    /// Value in SI (for a run-time param: the first key's value, what the f64 engines use).
    pub value: f64,
    /// Declaration span.
    pub span: Span,
    /// `Some([lo, hi])` (SI) for a run-time param: every key of the shared program gives it
    /// a value in `[lo, hi]`, the interval the range analysis and the format plan use; each
    /// key's value is a word of its param block. `None` for a compile-time constant.
    pub runtime: Option<(f64, f64)>,
}

/// A continuous state with its declared range. Writes saturate to the range.
#[derive(Clone, Debug, PartialEq)]
pub struct StateDecl {
    /// Qualified name.
    pub name: String,
    /// Dimension.
    pub dim: Dim,
    /// Initial value in SI.
    pub init: f64,
    /// Declared range `[lo, hi]` in SI.
    pub range: (f64, f64),
    /// Declaration span.
    pub span: Span,
}

/// An enumerated mode (a finite state machine's current state).
#[derive(Clone, Debug, PartialEq)]
pub struct ModeDecl {
    /// Qualified name.
    pub name: String,
    /// Variant names; a mode value is an index into this list.
    pub variants: Vec<String>,
    /// Initial variant index.
    pub init: u32,
    /// Declaration span.
    pub span: Span,
}

/// A named force term or output.
#[derive(Clone, Debug, PartialEq)]
pub struct NamedDecl {
    /// Qualified name.
    pub name: String,
    /// Type of the value.
    pub ty: Ty,
    /// Declaration span.
    pub span: Span,
    /// The axis of a pen instrument's force term (a component of a vector force such as
    /// `contact.x`); `None` for outputs and for a keyboard instrument's scalar force terms.
    pub axis: Option<Axis>,
}

/// The axes of a pen instrument, as the AST has them (one definition, [`crate::ast::Axis`]).
pub use crate::ast::Axis;

/// Where the total of one axis of a pen instrument's commanded force is published.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisTotal {
    /// The total force word, [`Stmt::Total`] (the `z` axis: what a keyboard firmware's force
    /// word drives).
    Total,
    /// A compiler-generated output (`force.x`, `force.y`), newtons.
    Output(OutputId),
}

/// A kind of event that `emit` produces, with its named arguments.
#[derive(Clone, Debug, PartialEq)]
pub struct EventDecl {
    /// Event name (`strike`).
    pub name: String,
    /// Argument names and dimensions, in order.
    pub args: Vec<(String, Dim)>,
}

/// The remembered condition of one `on` handler (false before the first sample).
#[derive(Clone, Debug, PartialEq)]
pub struct EdgeDecl {
    /// Span of the handler.
    pub span: Span,
}

/// Arithmetic operators. Dimension rule: `Add`/`Sub` need equal dimensions and keep it;
/// `Mul` adds exponents, `Div` subtracts them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[allow(missing_docs)]
pub enum ArithOp {
    Add,
    Sub,
    Mul,
    Div,
}

/// Comparisons: operands of equal dimension (or the same mode, for `Eq`/`Ne`); result `Bool`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[allow(missing_docs)]
pub enum CmpOp {
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
}

impl CmpOp {
    /// The comparison with its operands swapped: `a OP b` ⇔ `b OP.mirrored() a`.
    pub fn mirrored(self) -> CmpOp {
        match self {
            CmpOp::Lt => CmpOp::Gt,
            CmpOp::Le => CmpOp::Ge,
            CmpOp::Gt => CmpOp::Lt,
            CmpOp::Ge => CmpOp::Le,
            o => o,
        }
    }
}

/// Built-in functions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Builtin {
    /// `abs(x)`: same dimension.
    Abs,
    /// `sqrt(x)`: halves the exponents (which must be even); `sqrt` of a negative is 0.
    Sqrt,
    /// `exp(x)`: dimensionless in and out.
    Exp,
    /// `min(a, b)`: equal dimensions.
    Min,
    /// `max(a, b)`: equal dimensions.
    Max,
}

/// How a value is computed. Each variant states its typing rule.
#[derive(Clone, Debug, PartialEq)]
pub enum Op {
    /// A constant in SI. Type: `Real(dim)` as recorded in [`ValueData::ty`].
    Const(f64),
    /// `true`/`false`. Type: `Bool`.
    BoolConst(bool),
    /// A mode variant index. Type: `Mode(m)`.
    Variant(ModeId, u32),
    /// A param's value: folded at compile time, or for a run-time param
    /// ([`ParamDecl::runtime`]) the key's word in its param block, in the interval the
    /// param declares. Type: `Real(param.dim)`.
    Param(ParamId),
    /// This sample's sensor reading. Type: `Real(sensor.dim)`.
    Sensor(SensorId),
    /// `d(x)` (order 1) or `d2(x)` (order 2) of a sensor by the multi-sample differentiator
    /// of `tactus_runtime::differentiator`. Type: `Real(sensor.dim / s^order)`.
    Deriv(SensorId, u8),
    /// The state's current value (as left by earlier statements of this sample).
    State(StateId),
    /// The mode's current variant. Type: `Mode(m)`.
    Mode(ModeId),
    /// The condition an `on` handler had at the previous sample. Type: `Bool`.
    Edge(EdgeId),
    /// `-x`. Same type.
    Neg(Value),
    /// `not x`. Bool.
    Not(Value),
    /// `a OP b`. See [`ArithOp`].
    Arith(ArithOp, Value, Value),
    /// `a OP b`. See [`CmpOp`].
    Cmp(CmpOp, Value, Value),
    /// `a and b`. Bool.
    And(Value, Value),
    /// `a or b`. Bool.
    Or(Value, Value),
    /// `if c { a } else { b }`: both arms are evaluated (they have no effects). Type of `a`.
    Select(Value, Value, Value),
    /// A built-in function; unary ones use only the first operand.
    Call(Builtin, Value, Option<Value>),
}

/// A value's definition and type.
#[derive(Clone, Debug, PartialEq)]
pub struct ValueData {
    /// How it is computed.
    pub op: Op,
    /// Its type.
    pub ty: Ty,
    /// The source expression it was lowered from (for warnings of later passes).
    pub span: Span,
}

/// A statement of the per-sample body, executed in order.
#[derive(Clone, Debug, PartialEq)]
pub enum Stmt {
    /// Computes a value.
    Def(Value),
    /// Writes a state, saturated to its declared range.
    SetState(StateId, Value),
    /// Sets a mode to a variant.
    SetMode(ModeId, u32),
    /// Remembers an `on` handler's condition for the next sample.
    SetEdge(EdgeId, Value),
    /// Runs the statements when the Bool value is true.
    If(Value, Vec<Stmt>),
    /// Emits an event with its argument values.
    Emit(EventId, Vec<Value>),
    /// Publishes a force term's value (newtons).
    Force(ForceId, Value),
    /// Publishes an output's value.
    Output(OutputId, Value),
    /// Publishes the total commanded force (newtons).
    Total(Value),
}

impl Op {
    /// The values this operation reads, in operand order: none for a leaf (a constant, a
    /// param, a sensor, a derivative, a state, a mode or an edge read). With
    /// [`Stmt::reads`], the one answer to "what does this read" for every pass.
    pub fn operands(&self) -> Vec<Value> {
        match self {
            Op::Neg(x) | Op::Not(x) => vec![*x],
            Op::Arith(_, x, y) | Op::Cmp(_, x, y) | Op::And(x, y) | Op::Or(x, y) => {
                vec![*x, *y]
            }
            Op::Select(c, x, y) => vec![*c, *x, *y],
            Op::Call(_, x, y) => std::iter::once(*x).chain(*y).collect(),
            Op::Const(_)
            | Op::BoolConst(_)
            | Op::Variant(..)
            | Op::Param(_)
            | Op::Sensor(_)
            | Op::Deriv(..)
            | Op::State(_)
            | Op::Mode(_)
            | Op::Edge(_) => vec![],
        }
    }
}

impl Stmt {
    /// The values this statement itself reads: the value it writes or publishes, an event's
    /// arguments, an `if`'s condition (not the statements of its body). A `Def` reads
    /// nothing here (its value's operands are [`Op`]'s), nor does a `SetMode`.
    pub fn reads(&self) -> &[Value] {
        match self {
            Stmt::Def(_) | Stmt::SetMode(..) => &[],
            Stmt::SetState(_, v)
            | Stmt::SetEdge(_, v)
            | Stmt::Force(_, v)
            | Stmt::Output(_, v)
            | Stmt::Total(v)
            | Stmt::If(v, _) => std::slice::from_ref(v),
            Stmt::Emit(_, args) => args,
        }
    }
}

/// Which values the body of `p` needs (read by a statement, or transitively by the
/// operands of one), and the event of every `emit` statement in program order.
pub fn live_values(p: &Program) -> (Vec<bool>, Vec<EventId>) {
    let mut used = vec![false; p.values.len()];
    let mut work = Vec::new();
    let mut sites = Vec::new();
    walk_stmts(&p.body, &mut |s| {
        work.extend_from_slice(s.reads());
        if let Stmt::Emit(e, _) = s {
            sites.push(*e);
        }
    });
    while let Some(v) = work.pop() {
        if std::mem::replace(&mut used[v.index()], true) {
            continue;
        }
        work.extend(p.values[v.index()].op.operands());
    }
    (used, sites)
}

/// Calls `f` on every statement of `stmts` in body order, each `if`'s body right after
/// the `if` itself.
pub fn walk_stmts<'a>(stmts: &'a [Stmt], f: &mut impl FnMut(&'a Stmt)) {
    for s in stmts {
        f(s);
        if let Stmt::If(_, body) = s {
            walk_stmts(body, f);
        }
    }
}

/// `stmts` rebuilt: each statement other than an `if` replaced by what `f` pushes for it
/// (nothing drops it; itself and others keep it with statements beside it), each `if` kept
/// with its condition and its body rebuilt the same way. The one recursive filter and
/// insertion over a body, for every pass that drops or inserts statements.
pub fn rebuild_stmts(stmts: &[Stmt], f: &mut impl FnMut(&Stmt, &mut Vec<Stmt>)) -> Vec<Stmt> {
    let mut out = Vec::with_capacity(stmts.len());
    for s in stmts {
        match s {
            Stmt::If(c, body) => out.push(Stmt::If(*c, rebuild_stmts(body, f))),
            other => f(other, &mut out),
        }
    }
    out
}

/// Which of a program's `n` values have a `Def` in `stmts` (`if` bodies included): a flag
/// per value.
pub fn defined_values(stmts: &[Stmt], n: usize) -> Vec<bool> {
    let mut d = vec![false; n];
    walk_stmts(stmts, &mut |s| {
        if let Stmt::Def(v) = s {
            d[v.index()] = true;
        }
    });
    d
}

/// Which of a program's `n` states a `SetState` in `stmts` writes (`if` bodies included): a
/// flag per state.
pub fn written_states(stmts: &[Stmt], n: usize) -> Vec<bool> {
    let mut w = vec![false; n];
    walk_stmts(stmts, &mut |s| {
        if let Stmt::SetState(st, _) = s {
            w[st.index()] = true;
        }
    });
    w
}

/// Which of a program's `n` states a top-level `SetState` of `stmts` writes, i.e. every
/// sample (integrated or assigned unconditionally): a flag per state.
pub fn states_set_every_sample(stmts: &[Stmt], n: usize) -> Vec<bool> {
    let mut w = vec![false; n];
    for s in stmts {
        if let Stmt::SetState(st, _) = s {
            w[st.index()] = true;
        }
    }
    w
}

/// One instrument, lowered and checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Program {
    /// Instrument name.
    pub name: String,
    /// The sample rate the dynamics are discretised at, Hz.
    pub sample_rate_hz: f64,
    /// Sensors, in declaration order.
    pub sensors: Vec<SensorDecl>,
    /// Params (constants), instance params qualified.
    pub params: Vec<ParamDecl>,
    /// States.
    pub states: Vec<StateDecl>,
    /// Modes.
    pub modes: Vec<ModeDecl>,
    /// Force terms; the commanded force is their sum (per axis, for a pen instrument).
    pub forces: Vec<NamedDecl>,
    /// Outputs (e.g. hammer position for a synthesizer).
    pub outputs: Vec<NamedDecl>,
    /// Event kinds.
    pub events: Vec<EventDecl>,
    /// Edge memories of `on` handlers.
    pub edges: Vec<EdgeDecl>,
    /// Value table.
    pub values: Vec<ValueData>,
    /// The per-sample update.
    pub body: Vec<Stmt>,
    /// For a pen instrument (one with a vector force), where each axis' total force is
    /// published, in the order `x, y, z`: `x` and `y` in the compiler-generated outputs
    /// `force.x` and `force.y` (the sums of those axes' terms in declaration order, newtons),
    /// `z` in [`Stmt::Total`]. Empty for a keyboard instrument, whose total is the one
    /// scalar [`Stmt::Total`].
    pub force_axes: Vec<(Axis, AxisTotal)>,
    /// The accuracy contract a fixed-point plan of the program must keep against these f64
    /// semantics (`fixed::contract`): the defaults, or what the instrument's `tolerance`
    /// lines state.
    pub contract: Contract,
    /// For a program several keys share ([`crate::share`]): per key, in the keys' order, the
    /// SI value of each run-time param ([`Program::runtime_params`] order), each computed by
    /// that key's own constant fold — so values derived from one param (the piano's
    /// `M_h·grav·l4` and `dt/I_h`) belong to one real hammer. The planner simulates the
    /// accuracy contract at these physical points (`fixed::FixedProgram::with_config`).
    /// Empty for a program without run-time params.
    pub runtime_keys: Vec<Vec<f64>>,
}

impl Program {
    /// True for a pen instrument: its commanded force is a 3-vector (see
    /// [`Program::force_axes`]).
    pub fn is_pen(&self) -> bool {
        !self.force_axes.is_empty()
    }

    /// The compile-time value of `v` (SI) when it is a constant or a compile-time param;
    /// `None` for a run-time param ([`ParamDecl::runtime`]) and every other value.
    pub fn const_value(&self, v: Value) -> Option<f64> {
        match self.values[v.index()].op {
            Op::Const(c) => Some(c),
            Op::Param(p) if self.params[p.index()].runtime.is_none() => {
                Some(self.params[p.index()].value)
            }
            _ => None,
        }
    }

    /// The run-time params ([`ParamDecl::runtime`]) in declaration order: the words of a
    /// key's param block, in this order.
    pub fn runtime_params(&self) -> impl Iterator<Item = ParamId> + '_ {
        self.params
            .iter()
            .enumerate()
            .filter(|(_, d)| d.runtime.is_some())
            .map(|(i, _)| ParamId(i as u32))
    }

    /// The data of a value.
    pub fn value(&self, v: Value) -> &ValueData {
        &self.values[v.index()]
    }

    /// How many samples of this program fit a budget of `evaluations` value evaluations (at
    /// least 1): a per-sample cost proportional to the value table, which is what the
    /// interpreters pay. Tests that run every shipped instrument use it to give a bowed string
    /// of 20 000 values as much interpreter time as a piano key gets, not 60 times more.
    pub fn samples_within(&self, evaluations: usize) -> usize {
        (evaluations / self.values.len().max(1)).max(1)
    }
}

/// The clauses of an accuracy contract: how far a fixed-point plan's run may stray from the
/// f64 semantics on the same sensor samples (checked by `fixed::contract`). The defaults are
/// issue 16's; an instrument's `tolerance` lines replace them (docs/language.md).
#[derive(Clone, Debug, PartialEq)]
pub struct Contract {
    /// How far the total force at the key may differ from f64, at every sample.
    pub force: ForceBound,
    /// An event may happen this much earlier or later than in f64, seconds (0.5 ms: 22
    /// samples at 44.1 kHz), unless its own clause says otherwise ([`Contract::events`]).
    pub event_time_s: f64,
    /// An event's arguments may differ from f64 by this fraction of the f64 value (1 %: a
    /// third of a MIDI velocity step at mf), unless its own clause says otherwise.
    pub event_arg_rel: f64,
    /// Clauses on single force terms: how far the term may differ from f64 at every sample
    /// (`tolerance force TERM = …`).
    pub terms: Vec<(ForceId, ForceBound)>,
    /// Clauses on outputs: the output may differ from f64 by this much, SI, at every sample
    /// (`tolerance output NAME = …`).
    pub outputs: Vec<(OutputId, f64)>,
    /// Clauses on single events (`tolerance event NAME { time = …, ARG = … }`).
    pub events: Vec<EventTolerance>,
    /// The switch clause's window, seconds (0.5 ms, the events' default; `tolerance switch =
    /// …`): where the two runs are in different discrete states (a branch decision of the
    /// update differs), they must agree again within it, and for this long after the
    /// disagreement began the total force is held to the switch clause instead of the
    /// per-sample one (`fixed::contract::ContractCheck::switches`).
    pub switch_time_s: f64,
}

/// A bound on a force: LSBs of a 16-bit DAC at `full_scale` (the report's
/// `fixed::report::Precision::dac_lsb_n`), or newtons.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ForceBound {
    /// DAC LSB (`tolerance force = 0.5`).
    Lsb(f64),
    /// Newtons (`tolerance force = 2 mN`).
    Newtons(f64),
}

impl ForceBound {
    /// The bound in DAC LSB, given one LSB in newtons.
    pub fn lsb(self, dac_lsb_n: f64) -> f64 {
        match self {
            ForceBound::Lsb(x) => x,
            ForceBound::Newtons(n) => n / dac_lsb_n,
        }
    }

    /// The bound times `factor`.
    pub fn scaled(self, factor: f64) -> ForceBound {
        match self {
            ForceBound::Lsb(x) => ForceBound::Lsb(x * factor),
            ForceBound::Newtons(n) => ForceBound::Newtons(n * factor),
        }
    }
}

impl std::fmt::Display for ForceBound {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ForceBound::Lsb(x) => write!(f, "{x} DAC LSB"),
            ForceBound::Newtons(n) => write!(f, "{n:e} N"),
        }
    }
}

/// The clause of one event kind.
#[derive(Clone, Debug, PartialEq)]
pub struct EventTolerance {
    /// The event.
    pub event: EventId,
    /// Its time tolerance, seconds (`None`: [`Contract::event_time_s`]).
    pub time_s: Option<f64>,
    /// Relative tolerances of single arguments (argument index, fraction); the others
    /// keep [`Contract::event_arg_rel`].
    pub args_rel: Vec<(usize, f64)>,
}

impl Default for Contract {
    fn default() -> Self {
        Contract {
            force: ForceBound::Lsb(1.0),
            event_time_s: 0.5e-3,
            event_arg_rel: 0.01,
            terms: Vec::new(),
            outputs: Vec::new(),
            events: Vec::new(),
            switch_time_s: 0.5e-3,
        }
    }
}

impl Contract {
    /// The contract with every tolerance multiplied by `factor` (the planner's search keeps
    /// `fixed::SIMULATION_MARGIN` of each clause in reserve).
    pub fn scaled(&self, factor: f64) -> Contract {
        Contract {
            force: self.force.scaled(factor),
            event_time_s: self.event_time_s * factor,
            event_arg_rel: self.event_arg_rel * factor,
            terms: self
                .terms
                .iter()
                .map(|&(f, t)| (f, t.scaled(factor)))
                .collect(),
            outputs: self.outputs.iter().map(|&(o, t)| (o, t * factor)).collect(),
            events: self
                .events
                .iter()
                .map(|e| EventTolerance {
                    event: e.event,
                    time_s: e.time_s.map(|t| t * factor),
                    args_rel: e.args_rel.iter().map(|&(i, t)| (i, t * factor)).collect(),
                })
                .collect(),
            switch_time_s: self.switch_time_s * factor,
        }
    }

    /// The time tolerance of event `e`, seconds.
    pub fn time_of(&self, e: usize) -> f64 {
        self.events
            .iter()
            .find(|t| t.event.index() == e)
            .and_then(|t| t.time_s)
            .unwrap_or(self.event_time_s)
    }

    /// The relative tolerance of argument `arg` of event `e`.
    pub fn arg_rel_of(&self, e: usize, arg: usize) -> f64 {
        self.events
            .iter()
            .find(|t| t.event.index() == e)
            .and_then(|t| t.args_rel.iter().find(|a| a.0 == arg).map(|a| a.1))
            .unwrap_or(self.event_arg_rel)
    }

    /// The largest time tolerance of any event, seconds (the window events are paired in).
    pub fn max_time_s(&self) -> f64 {
        self.events
            .iter()
            .filter_map(|t| t.time_s)
            .fold(self.event_time_s, f64::max)
    }
}
