//! The f64 reference interpreter: the meaning of a program, sample by sample.
//!
//! This is the definition every other engine reproduces (the fixed-point interpreter
//! within its stated error bounds; the JIT, Thumb and C code bit for bit against the
//! fixed-point interpreter). It walks [`Program::body`] once per sample; see [`crate::ir`]
//! for the phase order. Sensor readings are saturated to their declared ranges, state
//! writes to theirs (each saturation is counted, so a tool can warn about a range that is
//! too narrow). Truth values are held as 0.0/1.0 and mode values as variant indices.

use crate::ir::*;
use tactus_runtime::differentiator::Differentiator;

/// The value of a pure operation given its operands' values; reads of sensors, states,
/// modes and edges go through `read`. Shared with compile-time constant folding.
#[inline(always)]
pub fn eval_op(
    op: &Op,
    val: impl Fn(Value) -> f64,
    param: impl Fn(ParamId) -> f64,
    read: &dyn Fn(&Op) -> f64,
) -> f64 {
    let b = |x: bool| if x { 1.0 } else { 0.0 };
    match *op {
        Op::Const(c) => c,
        Op::BoolConst(x) => b(x),
        Op::Variant(_, i) => i as f64,
        Op::Param(p) => param(p),
        Op::Sensor(_) | Op::Deriv(..) | Op::State(_) | Op::Mode(_) | Op::Edge(_) => read(op),
        Op::Neg(x) => -val(x),
        Op::Not(x) => b(val(x) == 0.0),
        Op::Arith(o, x, y) => {
            let (x, y) = (val(x), val(y));
            match o {
                ArithOp::Add => x + y,
                ArithOp::Sub => x - y,
                ArithOp::Mul => x * y,
                ArithOp::Div => x / y,
            }
        }
        Op::Cmp(o, x, y) => {
            let (x, y) = (val(x), val(y));
            b(match o {
                CmpOp::Eq => x == y,
                CmpOp::Ne => x != y,
                CmpOp::Lt => x < y,
                CmpOp::Le => x <= y,
                CmpOp::Gt => x > y,
                CmpOp::Ge => x >= y,
            })
        }
        Op::And(x, y) => b(val(x) != 0.0 && val(y) != 0.0),
        Op::Or(x, y) => b(val(x) != 0.0 || val(y) != 0.0),
        Op::Select(c, x, y) => {
            if val(c) != 0.0 {
                val(x)
            } else {
                val(y)
            }
        }
        Op::Call(f, x, y) => {
            let x = val(x);
            let y = || y.map_or(0.0, &val);
            match f {
                Builtin::Abs => x.abs(),
                Builtin::Sqrt => sqrt(x),
                Builtin::Exp => x.exp(),
                Builtin::Min => min(x, y()),
                Builtin::Max => max(x, y()),
            }
        }
    }
}

/// The language's `sqrt` on f64: `√x` for `x > 0`, else `+0` (negative numbers, both zeros
/// and NaN give `+0`). Written as a comparison rather than `x.max(0.0).sqrt()` because Rust
/// leaves the sign of `max(-0.0, 0.0)` open and rustc's choice depended on the optimisation
/// level; every f64 engine (this interpreter, the JIT) uses exactly this definition.
pub fn sqrt(x: f64) -> f64 {
    if x > 0.0 {
        x.sqrt()
    } else {
        0.0
    }
}

/// The language's `min` on f64: `if a.is_nan() { b } else if b < a { b } else { a }` — a
/// NaN operand yields the other one, and of two equal operands (`-0`, `+0`) the first. Fixed
/// here, not left to `f64::min`, whose sign of a zero result is unspecified.
pub fn min(a: f64, b: f64) -> f64 {
    if a.is_nan() || b < a {
        b
    } else {
        a
    }
}

/// The language's `max` on f64: `if a.is_nan() { b } else if b > a { b } else { a }` (see
/// [`min`]).
pub fn max(a: f64, b: f64) -> f64 {
    if a.is_nan() || b > a {
        b
    } else {
        a
    }
}

/// What one sample produced. Indices follow the program's tables.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SampleOut {
    /// Each force term, newtons.
    pub forces: Vec<f64>,
    /// The commanded force (sum of the terms), newtons.
    pub total: f64,
    /// Each output, SI (truth values 0/1).
    pub outputs: Vec<f64>,
    /// Events emitted this sample, in order, with their argument values (SI).
    pub events: Vec<(EventId, Vec<f64>)>,
}

/// One running instance of a program (one key).
#[derive(Clone, Debug)]
pub struct Instance<'p> {
    program: &'p Program,
    states: Vec<f64>,
    modes: Vec<u32>,
    edges: Vec<bool>,
    sensors: Vec<f64>,
    diffs: Vec<Differentiator>,
    vals: Vec<f64>,
    saturations: Vec<u64>,
    out: SampleOut,
}

impl<'p> Instance<'p> {
    /// A fresh instance: states and modes at their initial values, edge memories false.
    pub fn new(program: &'p Program) -> Self {
        Instance {
            program,
            states: program.states.iter().map(|s| s.init).collect(),
            modes: program.modes.iter().map(|m| m.init).collect(),
            edges: vec![false; program.edges.len()],
            sensors: vec![0.0; program.sensors.len()],
            diffs: vec![Differentiator::default(); program.sensors.len()],
            vals: vec![0.0; program.values.len()],
            saturations: vec![0; program.states.len()],
            out: SampleOut {
                forces: vec![0.0; program.forces.len()],
                outputs: vec![0.0; program.outputs.len()],
                ..SampleOut::default()
            },
        }
    }

    /// Runs one sample. `sensors` holds one reading per declared sensor, SI; missing
    /// readings are taken as the sensor's lower bound, and every reading is saturated to
    /// the declared range.
    pub fn step(&mut self, sensors: &[f64]) -> &SampleOut {
        self.read(sensors);
        let body = &self.program.body;
        self.exec(body, &|_| None);
        &self.out
    }

    /// [`Self::step`] with some truth values decided from outside: each value `v` for which
    /// `decide(v)` is `Some(t)` is taken as `t` (1.0 or 0.0) wherever it is read, instead of
    /// what its operation computes. The accuracy contract's re-timed reference
    /// (`fixed::contract`) runs the f64 semantics with the branch decisions of another run
    /// this way: what its continuous values do with a switch taken a sample earlier or later.
    pub fn step_deciding(
        &mut self,
        sensors: &[f64],
        decide: &dyn Fn(Value) -> Option<bool>,
    ) -> &SampleOut {
        self.read(sensors);
        let body = &self.program.body;
        self.exec(body, decide);
        &self.out
    }

    /// Takes one sample's sensor readings: missing ones as the lower bound, each saturated
    /// to its declared range, the differentiated ones into their histories.
    fn read(&mut self, sensors: &[f64]) {
        for (i, s) in self.program.sensors.iter().enumerate() {
            let x = sensors.get(i).copied().unwrap_or(s.range.0);
            let x = if x.is_nan() {
                s.range.0
            } else {
                x.clamp(s.range.0, s.range.1)
            };
            self.sensors[i] = x;
            if s.differentiated {
                self.diffs[i].push(x);
            }
        }
        self.out.events.clear();
    }

    fn exec<F: Fn(Value) -> Option<bool> + ?Sized>(&mut self, stmts: &[Stmt], decide: &F) {
        let fs = self.program.sample_rate_hz;
        for s in stmts {
            match s {
                Stmt::Def(v) => {
                    let op = &self.program.values[v.index()].op;
                    let vals = &self.vals;
                    let read = |op: &Op| match *op {
                        Op::Sensor(s) => self.sensors[s.index()],
                        Op::Deriv(s, 1) => self.diffs[s.index()].d1(fs),
                        Op::Deriv(s, _) => self.diffs[s.index()].d2(fs),
                        Op::State(s) => self.states[s.index()],
                        Op::Mode(m) => self.modes[m.index()] as f64,
                        Op::Edge(e) => f64::from(u8::from(self.edges[e.index()])),
                        _ => f64::NAN,
                    };
                    let x = match decide(*v) {
                        Some(t) => f64::from(u8::from(t)),
                        None => eval_op(
                            op,
                            |x| vals[x.index()],
                            |p| self.program.params[p.index()].value,
                            &read,
                        ),
                    };
                    self.vals[v.index()] = x;
                }
                Stmt::SetState(st, v) => {
                    let (lo, hi) = self.program.states[st.index()].range;
                    let x = self.vals[v.index()];
                    let y = if x.is_nan() { lo } else { x.clamp(lo, hi) };
                    if y != x {
                        self.saturations[st.index()] += 1;
                    }
                    self.states[st.index()] = y;
                }
                Stmt::SetMode(m, i) => self.modes[m.index()] = *i,
                Stmt::SetEdge(e, v) => self.edges[e.index()] = self.vals[v.index()] != 0.0,
                Stmt::If(c, body) => {
                    if self.vals[c.index()] != 0.0 {
                        self.exec(body, decide);
                    }
                }
                Stmt::Emit(e, args) => {
                    let a = args.iter().map(|v| self.vals[v.index()]).collect();
                    self.out.events.push((*e, a));
                }
                Stmt::Force(f, v) => self.out.forces[f.index()] = self.vals[v.index()],
                Stmt::Output(o, v) => self.out.outputs[o.index()] = self.vals[v.index()],
                Stmt::Total(v) => self.out.total = self.vals[v.index()],
            }
        }
    }

    /// Makes this instance what `other.clone()` is (an instance of the same program),
    /// reusing its buffers: a step can be undone by copying back a copy taken before it.
    pub fn copy_from(&mut self, other: &Self) {
        self.program = other.program;
        self.states.clone_from(&other.states);
        self.modes.clone_from(&other.modes);
        self.edges.clone_from(&other.edges);
        self.sensors.clone_from(&other.sensors);
        self.diffs.clone_from(&other.diffs);
        self.vals.clone_from(&other.vals);
        self.saturations.clone_from(&other.saturations);
        self.out.forces.clone_from(&other.out.forces);
        self.out.total = other.out.total;
        self.out.outputs.clone_from(&other.out.outputs);
        self.out.events.clone_from(&other.out.events);
    }

    /// What the last step produced (nothing before the first).
    pub fn last(&self) -> &SampleOut {
        &self.out
    }

    /// Current state values (SI), in the program's state order.
    pub fn states(&self) -> &[f64] {
        &self.states
    }
    /// Current mode variant indices.
    pub fn modes(&self) -> &[u32] {
        &self.modes
    }
    /// How many writes each state had saturated to its declared range so far.
    pub fn saturations(&self) -> &[u64] {
        &self.saturations
    }
    /// Every value as the last sample left it (SI; truth values 0/1), indexed by
    /// [`Value`]: a value defined in an `if` body that did not run keeps an older sample's.
    pub fn values(&self) -> &[f64] {
        &self.vals
    }
}
