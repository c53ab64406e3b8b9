//! The IR invariants every engine and backend relies on, checked before any of them runs.
//!
//! The front end guarantees all of them, so a failure here is a front-end bug, not a user
//! error; checking anyway turns such a bug into a [`VerifyError`] instead of a panic or, worse,
//! native code that reads outside its buffers. A code generator that maps each IR [`Value`]
//! to one SSA value (the JIT) or one virtual register (the Thumb backend) is sound exactly
//! when every use is dominated by the one definition: the definition precedes the use in the
//! same statement list or in an enclosing one.

use crate::ir::{Op, Program, Stmt, Value};
use std::fmt;

/// A broken IR invariant (a compiler bug).
#[derive(Clone, Debug, PartialEq)]
pub enum VerifyError {
    /// A value is used where no definition of it is in scope.
    UndefinedValue {
        /// The value.
        value: Value,
    },
    /// A value is defined twice.
    Redefined {
        /// The value.
        value: Value,
    },
    /// An index into one of the program's tables is out of range.
    BadIndex {
        /// Which table (`"state"`, `"value"`, …).
        kind: &'static str,
        /// The index.
        index: usize,
        /// The table's length.
        len: usize,
    },
    /// A declared range is not `lo <= hi` (or has a NaN bound).
    BadRange {
        /// `"sensor"` or `"state"`.
        kind: &'static str,
        /// Its name.
        name: String,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
}

impl fmt::Display for VerifyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            VerifyError::UndefinedValue { value } => write!(
                f,
                "value {value} is used where it is not defined (IR invariant: its definition precedes every use)"
            ),
            VerifyError::Redefined { value } => write!(
                f,
                "value {value} is defined twice (IR invariant: exactly one definition)"
            ),
            VerifyError::BadIndex { kind, index, len } => {
                write!(f, "{kind} index {index} is out of range (the program has {len})")
            }
            VerifyError::BadRange { kind, name, lo, hi } => {
                write!(f, "{kind} `{name}` has the invalid range [{lo}, {hi}]")
            }
        }
    }
}

impl std::error::Error for VerifyError {}

/// Checks `program`: every index in range, every declared range ordered and NaN-free, every
/// value defined once and before each use in scope.
pub fn verify(program: &Program) -> Result<(), VerifyError> {
    for s in &program.sensors {
        check_range("sensor", &s.name, s.range)?;
    }
    for s in &program.states {
        check_range("state", &s.name, s.range)?;
    }
    let mut v = Verifier {
        program,
        defined: vec![false; program.values.len()],
    };
    v.body(&program.body)
}

fn check_range(kind: &'static str, name: &str, (lo, hi): (f64, f64)) -> Result<(), VerifyError> {
    // `f64::clamp` panics unless lo <= hi, both non-NaN; the interpreter would too.
    if lo <= hi {
        Ok(())
    } else {
        Err(VerifyError::BadRange {
            kind,
            name: name.to_string(),
            lo,
            hi,
        })
    }
}

fn index(kind: &'static str, index: usize, len: usize) -> Result<(), VerifyError> {
    if index < len {
        Ok(())
    } else {
        Err(VerifyError::BadIndex { kind, index, len })
    }
}

struct Verifier<'p> {
    program: &'p Program,
    /// Whether each value is defined at the current point (in scope).
    defined: Vec<bool>,
}

impl Verifier<'_> {
    fn body(&mut self, stmts: &[Stmt]) -> Result<(), VerifyError> {
        let p = self.program;
        let mut local = Vec::new();
        for s in stmts {
            match s {
                Stmt::Def(v) => {
                    index("value", v.index(), p.values.len())?;
                    self.op(&p.values[v.index()].op)?;
                    if self.defined[v.index()] {
                        return Err(VerifyError::Redefined { value: *v });
                    }
                    self.defined[v.index()] = true;
                    local.push(*v);
                }
                Stmt::SetState(st, v) => {
                    index("state", st.index(), p.states.len())?;
                    self.use_(*v)?;
                }
                Stmt::SetMode(m, _) => index("mode", m.index(), p.modes.len())?,
                Stmt::SetEdge(e, v) => {
                    index("edge", e.index(), p.edges.len())?;
                    self.use_(*v)?;
                }
                Stmt::If(c, inner) => {
                    self.use_(*c)?;
                    self.body(inner)?;
                }
                Stmt::Emit(e, args) => {
                    index("event", e.index(), p.events.len())?;
                    for a in args {
                        self.use_(*a)?;
                    }
                }
                Stmt::Force(f, v) => {
                    index("force", f.index(), p.forces.len())?;
                    self.use_(*v)?;
                }
                Stmt::Output(o, v) => {
                    index("output", o.index(), p.outputs.len())?;
                    self.use_(*v)?;
                }
                Stmt::Total(v) => self.use_(*v)?,
            }
        }
        // Values defined in this list go out of scope with it.
        for v in local {
            self.defined[v.index()] = false;
        }
        Ok(())
    }

    fn use_(&self, v: Value) -> Result<(), VerifyError> {
        if self.defined.get(v.index()).copied().unwrap_or(false) {
            Ok(())
        } else {
            Err(VerifyError::UndefinedValue { value: v })
        }
    }

    fn op(&self, op: &Op) -> Result<(), VerifyError> {
        let p = self.program;
        match *op {
            Op::Const(_) | Op::BoolConst(_) => Ok(()),
            Op::Variant(m, _) | Op::Mode(m) => index("mode", m.index(), p.modes.len()),
            Op::Param(x) => index("param", x.index(), p.params.len()),
            Op::Sensor(s) | Op::Deriv(s, _) => index("sensor", s.index(), p.sensors.len()),
            Op::State(s) => index("state", s.index(), p.states.len()),
            Op::Edge(e) => index("edge", e.index(), p.edges.len()),
            Op::Neg(x) | Op::Not(x) | Op::Call(_, x, None) => self.use_(x),
            Op::Arith(_, x, y)
            | Op::Cmp(_, x, y)
            | Op::And(x, y)
            | Op::Or(x, y)
            | Op::Call(_, x, Some(y)) => {
                self.use_(x)?;
                self.use_(y)
            }
            Op::Select(c, x, y) => {
                self.use_(c)?;
                self.use_(x)?;
                self.use_(y)
            }
        }
    }
}
