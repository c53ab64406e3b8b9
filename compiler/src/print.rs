//! Text form of the IR, for snapshot tests and `tactus check --emit ir`.
//!
//! One line per declaration and statement; values print as `v12 = mul v3, v4 : N`. The form
//! is for reading, not parsing back.

use crate::ir::*;
use std::fmt::{self, Write};

impl fmt::Display for Program {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "instrument {} @ {} Hz", self.name, self.sample_rate_hz)?;
        for (i, s) in self.sensors.iter().enumerate() {
            let d = if s.differentiated {
                " differentiated"
            } else {
                ""
            };
            writeln!(
                f,
                "  sensor{i} {}: {:?} in [{}, {}]{d}",
                s.name,
                s.dim,
                g(s.range.0),
                g(s.range.1)
            )?;
        }
        for (i, p) in self.params.iter().enumerate() {
            writeln!(f, "  param{i} {}: {:?} = {}", p.name, p.dim, g(p.value))?;
        }
        for (i, s) in self.states.iter().enumerate() {
            writeln!(
                f,
                "  state{i} {}: {:?} = {} in [{}, {}]",
                s.name,
                s.dim,
                g(s.init),
                g(s.range.0),
                g(s.range.1)
            )?;
        }
        for (i, m) in self.modes.iter().enumerate() {
            writeln!(
                f,
                "  mode{i} {} {{ {} }} = {}",
                m.name,
                m.variants.join(", "),
                m.variants[m.init as usize]
            )?;
        }
        for (i, x) in self.forces.iter().enumerate() {
            match x.axis {
                Some(a) => writeln!(f, "  force{i} {} axis {a}", x.name)?,
                None => writeln!(f, "  force{i} {}", x.name)?,
            }
        }
        for (i, x) in self.outputs.iter().enumerate() {
            writeln!(f, "  output{i} {}: {}", x.name, ty(x.ty))?;
        }
        for (i, e) in self.events.iter().enumerate() {
            let args: Vec<String> = e.args.iter().map(|(n, d)| format!("{n}: {d:?}")).collect();
            writeln!(f, "  event{i} {}({})", e.name, args.join(", "))?;
        }
        if !self.force_axes.is_empty() {
            let axes: Vec<String> = self
                .force_axes
                .iter()
                .map(|(a, t)| match t {
                    AxisTotal::Total => format!("{a} = total"),
                    AxisTotal::Output(o) => format!("{a} = {o}"),
                })
                .collect();
            writeln!(f, "  force axes: {}", axes.join(", "))?;
        }
        writeln!(f, "  edges {}", self.edges.len())?;
        writeln!(f, "body:")?;
        let mut out = String::new();
        self.write_block(&mut out, &self.body, 1)?;
        f.write_str(&out)
    }
}

fn g(x: f64) -> String {
    format!("{x:e}")
}

fn ty(t: Ty) -> String {
    match t {
        Ty::Real(d) => format!("{d:?}"),
        Ty::Bool => "bool".into(),
        Ty::Mode(m) => format!("{m}"),
    }
}

impl Program {
    fn write_block(&self, out: &mut String, stmts: &[Stmt], depth: usize) -> fmt::Result {
        let pad = "  ".repeat(depth);
        for s in stmts {
            match s {
                Stmt::Def(v) => {
                    let d = self.value(*v);
                    writeln!(out, "{pad}{v} = {} : {}", self.op_text(&d.op), ty(d.ty))?
                }
                Stmt::SetState(s, v) => {
                    writeln!(out, "{pad}set {} = {v}", self.states[s.index()].name)?
                }
                Stmt::SetMode(m, i) => {
                    let md = &self.modes[m.index()];
                    writeln!(out, "{pad}set {} = {}", md.name, md.variants[*i as usize])?
                }
                Stmt::SetEdge(e, v) => writeln!(out, "{pad}set {e} = {v}")?,
                Stmt::If(c, body) => {
                    writeln!(out, "{pad}if {c} {{")?;
                    self.write_block(out, body, depth + 1)?;
                    writeln!(out, "{pad}}}")?;
                }
                Stmt::Emit(e, args) => {
                    let a: Vec<String> = args.iter().map(|v| v.to_string()).collect();
                    writeln!(
                        out,
                        "{pad}emit {}({})",
                        self.events[e.index()].name,
                        a.join(", ")
                    )?
                }
                Stmt::Force(x, v) => {
                    writeln!(out, "{pad}force {} = {v}", self.forces[x.index()].name)?
                }
                Stmt::Output(x, v) => {
                    writeln!(out, "{pad}output {} = {v}", self.outputs[x.index()].name)?
                }
                Stmt::Total(v) => writeln!(out, "{pad}total = {v}")?,
            }
        }
        Ok(())
    }

    fn op_text(&self, op: &Op) -> String {
        match op {
            Op::Const(c) => format!("const {}", g(*c)),
            Op::BoolConst(b) => format!("const {b}"),
            Op::Variant(m, i) => format!("variant {}", self.modes[m.index()].variants[*i as usize]),
            Op::Param(p) => format!("param {}", self.params[p.index()].name),
            Op::Sensor(s) => format!("sensor {}", self.sensors[s.index()].name),
            Op::Deriv(s, 1) => format!("d {}", self.sensors[s.index()].name),
            Op::Deriv(s, _) => format!("d2 {}", self.sensors[s.index()].name),
            Op::State(s) => format!("state {}", self.states[s.index()].name),
            Op::Mode(m) => format!("mode {}", self.modes[m.index()].name),
            Op::Edge(e) => format!("edge {e}"),
            Op::Neg(x) => format!("neg {x}"),
            Op::Not(x) => format!("not {x}"),
            Op::Arith(o, x, y) => format!("{} {x}, {y}", format!("{o:?}").to_lowercase()),
            Op::Cmp(o, x, y) => format!("{} {x}, {y}", format!("{o:?}").to_lowercase()),
            Op::And(x, y) => format!("and {x}, {y}"),
            Op::Or(x, y) => format!("or {x}, {y}"),
            Op::Select(c, x, y) => format!("select {c}, {x}, {y}"),
            Op::Call(b, x, None) => format!("{} {x}", format!("{b:?}").to_lowercase()),
            Op::Call(b, x, Some(y)) => format!("{} {x}, {y}", format!("{b:?}").to_lowercase()),
        }
    }
}
