//! The C99 backend: a [`FixedProgram`] as one portable header and one source file.
//!
//! The generated code is the fixed interpreter ([`crate::fixed::interp`]) unrolled: one
//! `int32_t` local per live IR value, one C statement per IR statement, in the body's order,
//! with every format baked in as a constant (shift amounts, thresholds, saturation bounds).
//! The primitives come from [`prim`], which reduces each `i128` definition of
//! `tactus_runtime::fixed` to `int64_t`/`uint64_t` arithmetic on the compile-time formats,
//! so the C code gives the interpreter's bits on every sample; `compiler/tests/cgen.rs`
//! checks that on every instrument and stimulus.
//!
//! The interface — the symbol names, the state struct, the `out` array's layout and the
//! header — is [`crate::abi`]'s, which the Thumb backend shares; this module writes the
//! implementation. The `out` array of the update is flat `int32_t` words whose layout
//! ([`OutLayout`]) is also given as macros in the header: force terms, total, outputs, then
//! one slot per `emit` site (a fired flag and the arguments).

pub mod prim;

use crate::abi::{self, lit, CConfig, Interface, OutLayout, StateLayout};
use crate::fixed::{FixedProgram, MulKind};
use crate::ir::*;
use std::collections::HashSet;
use std::fmt::Write as _;
use tactus_runtime::differentiator::WINDOW;

/// The C backend's errors: the interface's ([`abi::InterfaceError`]); the implementation
/// adds none of its own.
pub type CgenError = abi::InterfaceError;

/// Generated C: the header (`<name>.h`) and the source (`<name>.c`), and the layout of the
/// update's `out` array.
#[derive(Clone, Debug)]
pub struct CSource {
    /// The header: state struct, prototypes, Q-format and layout macros.
    pub header: String,
    /// The implementation; includes the header as `"<name>.h"`.
    pub source: String,
    /// The C identifier stem: functions are `tactus_<stem>_init`/`_update`, the header is
    /// `<stem>.h`.
    pub stem: String,
    /// Where the update writes what.
    pub layout: OutLayout,
}

/// Generates C99 for a fixed-point program, with default annotations.
pub fn emit_c(fp: &FixedProgram) -> Result<CSource, CgenError> {
    emit_c_with(fp, &CConfig::default())
}

/// Generates C99 for a fixed-point program.
///
/// Errors: see [`CgenError`]; none occurs for the shipped instruments.
pub fn emit_c_with(fp: &FixedProgram, config: &CConfig) -> Result<CSource, CgenError> {
    // A broken IR invariant is a compiler bug; say which instead of emitting wrong C.
    crate::verify::verify(&fp.program)
        .map_err(|e| CgenError::Unsupported(format!("a broken IR invariant: {e}")))?;
    Gen::new(fp, config)?.run()
}

/// A product `x·y` (C expressions with their fraction bits) into `fr` fraction bits in the
/// form the plan chose for it (`kind`: pre-shifted `MULS`, 32×16 with its cut operand, high
/// word, else exact): the one dispatch for a product and a product by a reciprocal, as the
/// fixed interpreter has it.
fn product(kind: Option<MulKind>, x: (String, i32), y: (String, i32), fr: i32) -> String {
    match kind {
        Some(MulKind::High(k)) => prim::mul_high(&x.0, x.1, &y.0, y.1, k, fr),
        Some(MulKind::Mul32x16 { cut, b, k }) => {
            let ((a, fa), (c, fc)) = cut.kept_cut(x, y);
            prim::mul_32x16(&a, fa, &c, fc, b, k, fr)
        }
        Some(MulKind::Muls(sa, sb)) => prim::mul(&x.0, x.1, &y.0, y.1, fr, Some((sa, sb))),
        _ => prim::mul(&x.0, x.1, &y.0, y.1, fr, None),
    }
}

struct Gen<'a> {
    fp: &'a FixedProgram,
    p: &'a Program,
    config: &'a CConfig,
    stem: String,
    /// The interface's header ([`abi::Interface`]).
    header: String,
    used: Vec<bool>,
    /// History slot of each differentiated sensor.
    hist_slot: Vec<Option<usize>>,
    /// Which (sensor, order) derivatives are used.
    deriv_used: HashSet<(usize, u8)>,
    layout: OutLayout,
    /// Flag offset of each emit site, in program order.
    emit_sites: Vec<usize>,
    body: String,
    next_site: usize,
}

impl<'a> Gen<'a> {
    fn new(fp: &'a FixedProgram, config: &'a CConfig) -> Result<Self, CgenError> {
        let p = &fp.program;
        let interface = Interface::new(fp, config)?;
        let (used, _) = live_values(p);
        let mut deriv_used = HashSet::new();
        for (v, vd) in p.values.iter().enumerate() {
            if let (true, Op::Deriv(s, order)) = (used[v], &vd.op) {
                deriv_used.insert((s.index(), *order));
            }
        }
        let mut hist_slot = vec![None; p.sensors.len()];
        let mut n = 0;
        for (i, s) in p.sensors.iter().enumerate() {
            if s.differentiated {
                hist_slot[i] = Some(n);
                n += 1;
            }
        }
        let emit_sites = interface.layout.emits.iter().map(|e| e.offset).collect();
        Ok(Gen {
            fp,
            p,
            config,
            stem: interface.stem,
            header: interface.header,
            used,
            hist_slot,
            deriv_used,
            layout: interface.layout,
            emit_sites,
            body: String::new(),
            next_site: 0,
        })
    }

    fn run(mut self) -> Result<CSource, CgenError> {
        let source = self.source()?;
        Ok(CSource {
            header: std::mem::take(&mut self.header),
            source,
            stem: self.stem,
            layout: self.layout,
        })
    }

    fn line(&mut self, depth: usize, text: &str) {
        for _ in 0..depth {
            self.body.push_str("    ");
        }
        self.body.push_str(text);
        self.body.push('\n');
    }

    fn source(&mut self) -> Result<String, CgenError> {
        let (p, fp) = (self.p, self.fp);
        let st = self.stem.clone();
        let hlen = 2 * WINDOW + 1;
        let mut c = abi::banner(p, self.config, "Implementation");
        let _ = write!(c, "#include \"{st}.h\"\n\n");
        c.push_str(prim::RUNTIME);
        // init
        let _ = write!(
            c,
            "\nvoid {}(struct {} *s) {{\n",
            abi::init_symbol(&st),
            abi::state_struct(&st)
        );
        let _ = writeln!(c, "    int i, j;");
        let _ = writeln!(c, "    int32_t *w = &s->hist[0][0];");
        let _ = writeln!(c, "    for (i = 0; i < (int)(sizeof s->states / sizeof s->states[0]); i++) s->states[i] = 0;");
        let _ = writeln!(
            c,
            "    for (i = 0; i < (int)sizeof s->modes; i++) s->modes[i] = 0;"
        );
        let _ = writeln!(
            c,
            "    for (i = 0; i < (int)sizeof s->edges; i++) s->edges[i] = 0;"
        );
        let _ = writeln!(c, "    for (i = 0; i < (int)sizeof s->hist_pos; i++) {{");
        let _ = writeln!(c, "        s->hist_pos[i] = 0;");
        let _ = writeln!(
            c,
            "        for (j = 0; j < {}; j++) w[i * {} + j] = 0;\n    }}",
            2 * hlen,
            2 * hlen
        );
        let _ = writeln!(c, "    for (i = 0; i < (int)(sizeof s->published / sizeof s->published[0]); i++) s->published[i] = 0;");
        for (i, (sd, init)) in p.states.iter().zip(&fp.state_init).enumerate() {
            let _ = writeln!(
                c,
                "    s->states[{i}] = {}; /* {} = {} */",
                lit(*init),
                sd.name,
                sd.init
            );
        }
        for (i, md) in p.modes.iter().enumerate() {
            let _ = writeln!(
                c,
                "    s->modes[{i}] = {}; /* {} = {} */",
                md.init,
                md.name,
                md.variants.get(md.init as usize).map_or("?", |v| v)
            );
        }
        c.push_str("}\n");
        // update
        let _ = write!(
            c,
            "\nvoid {}(struct {} *s, const int32_t *sensors, int32_t *out) {{\n",
            abi::update_symbol(&st),
            abi::state_struct(&st)
        );
        self.body.clear();
        self.line(1, "int i;");
        // 1. sensors: clamp, then push the differentiator histories.
        for (i, sd) in p.sensors.iter().enumerate() {
            let (lo, hi) = fp.sensor_raw_range[i];
            self.line(
                1,
                &format!("int32_t s{i} = sensors[{i}]; /* {} */", sd.name),
            );
            // (A bound at the end of the word range needs no test, and C compilers warn.)
            if lo != i32::MIN {
                self.line(1, &format!("if (s{i} < {}) s{i} = {};", lit(lo), lit(lo)));
            }
            if hi != i32::MAX {
                self.line(1, &format!("if (s{i} > {}) s{i} = {};", lit(hi), lit(hi)));
            }
            if let Some(h) = self.hist_slot[i] {
                // The ring kept twice, its position counting down (the layout's
                // `hist_pos`, 0 before the first sample): the readings N and 2N samples
                // back need no wrap.
                self.line(1, &format!("int q{h} = s->hist_pos[{h}] - 4;"));
                self.line(1, &format!("if (q{h} <= 0) {{"));
                self.line(2, &format!("if (q{h} < 0)"));
                self.line(
                    3,
                    &format!(
                        "for (i = {}; i < {}; i++) s->hist[{h}][i] = s{i};",
                        StateLayout::primed_slots().start,
                        StateLayout::primed_slots().end
                    ),
                );
                self.line(2, &format!("q{h} = {};", 4 * hlen));
                self.line(1, "}");
                self.line(1, &format!("s->hist_pos[{h}] = (uint8_t)q{h};"));
                self.line(1, &format!("int32_t *h{h} = &s->hist[{h}][q{h} / 4 - 1];"));
                self.line(1, &format!("h{h}[0] = s{i};"));
                self.line(1, &format!("h{h}[{hlen}] = s{i};"));
                let (ago0, agon, ago2n) = (
                    format!("(int64_t)h{h}[0]"),
                    format!("(int64_t)h{h}[{WINDOW}]"),
                    format!("(int64_t)h{h}[{}]", 2 * WINDOW),
                );
                if self.deriv_used.contains(&(i, 1)) {
                    self.line(1, &format!("int64_t d{i}_1 = {ago0} - {agon};"));
                }
                if self.deriv_used.contains(&(i, 2)) {
                    self.line(
                        1,
                        &format!("int64_t d{i}_2 = {ago0} - 2 * {agon} + {ago2n};"),
                    );
                }
            }
        }
        self.line(1, "(void)sensors;");
        self.line(1, "(void)i;");
        for site in self.layout.emits.clone() {
            let n = 1 + p.events[site.event.index()].args.len();
            self.line(
                1,
                &format!("for (i = 0; i < {n}; i++) out[{} + i] = 0;", site.offset),
            );
        }
        // 2-4. the body.
        self.stmts(&p.body, 1)?;
        let np = p.forces.len() + 1 + p.outputs.len();
        self.line(
            1,
            &format!("for (i = 0; i < {np}; i++) out[i] = s->published[i];"),
        );
        c.push_str(&self.body);
        c.push_str("}\n");
        Ok(c)
    }

    fn stmts(&mut self, stmts: &[Stmt], depth: usize) -> Result<(), CgenError> {
        let (p, fp) = (self.p, self.fp);
        for s in stmts {
            match s {
                Stmt::Def(v) => {
                    if self.used[v.index()] {
                        let e = self.expr(*v)?;
                        self.line(depth, &format!("int32_t v{} = {e};", v.0));
                    }
                }
                Stmt::SetState(sid, v) => {
                    let i = sid.index();
                    let (lo, hi) = fp.state_raw_range[i];
                    let conv =
                        prim::convert(&format!("v{}", v.0), fp.frac[v.index()], fp.state_frac[i]);
                    self.line(depth, "{");
                    self.line(
                        depth + 1,
                        &format!("int32_t t = {conv}; /* {} */", p.states[i].name),
                    );
                    if lo != i32::MIN {
                        self.line(depth + 1, &format!("if (t < {}) t = {};", lit(lo), lit(lo)));
                    }
                    if hi != i32::MAX {
                        self.line(depth + 1, &format!("if (t > {}) t = {};", lit(hi), lit(hi)));
                    }
                    self.line(depth + 1, &format!("s->states[{i}] = t;"));
                    self.line(depth, "}");
                }
                Stmt::SetMode(m, i) => {
                    let md = &p.modes[m.index()];
                    self.line(
                        depth,
                        &format!(
                            "s->modes[{}] = {i}; /* {} = {} */",
                            m.0,
                            md.name,
                            md.variants.get(*i as usize).map_or("?", |v| v)
                        ),
                    );
                }
                Stmt::SetEdge(e, v) => {
                    self.line(depth, &format!("s->edges[{}] = v{} != 0;", e.0, v.0))
                }
                Stmt::If(c, body) => {
                    self.line(depth, &format!("if (v{}) {{", c.0));
                    self.stmts(body, depth + 1)?;
                    self.line(depth, "}");
                }
                Stmt::Emit(e, args) => {
                    let off = self.emit_sites[self.next_site];
                    self.next_site += 1;
                    let ed = &p.events[e.index()];
                    self.line(depth, &format!("out[{off}] = 1; /* emit {} */", ed.name));
                    for (j, (a, f)) in args.iter().zip(&fp.event_frac[e.index()]).enumerate() {
                        let conv = prim::convert(&format!("v{}", a.0), fp.frac[a.index()], *f);
                        self.line(depth, &format!("out[{}] = {conv};", off + 1 + j));
                    }
                }
                Stmt::Force(f, v) => {
                    let name = &p.forces[f.index()].name;
                    self.line(
                        depth,
                        &format!(
                            "s->published[{}] = v{}; /* force {name} */",
                            self.layout.forces + f.index(),
                            v.0
                        ),
                    );
                }
                Stmt::Output(o, v) => {
                    let name = &p.outputs[o.index()].name;
                    self.line(
                        depth,
                        &format!(
                            "s->published[{}] = v{}; /* output {name} */",
                            self.layout.outputs + o.index(),
                            v.0
                        ),
                    );
                }
                Stmt::Total(v) => self.line(
                    depth,
                    &format!(
                        "s->published[{}] = v{}; /* total */",
                        self.layout.total, v.0
                    ),
                ),
            }
        }
        Ok(())
    }

    /// The C expression of a value's definition.
    fn expr(&self, v: Value) -> Result<String, CgenError> {
        let (p, fp) = (self.p, self.fp);
        let fr = fp.frac[v.index()];
        let name = |x: &Value| format!("v{}", x.0);
        let f = |x: &Value| fp.frac[x.index()];
        let real = |x: &Value| matches!(p.values[x.index()].ty, Ty::Real(_));
        Ok(match &p.values[v.index()].op {
            Op::Param(_) if fp.param_word_of(v).is_some() => {
                format!("s->params[{}]", fp.param_word_of(v).unwrap_or(0))
            }
            Op::Const(_) | Op::Param(_) => lit(fp.consts[v.index()]),
            Op::BoolConst(t) => i32::from(*t).to_string(),
            Op::Variant(_, i) => i.to_string(),
            Op::Sensor(s) => prim::convert(&format!("s{}", s.0), fp.sensor_frac[s.index()], fr),
            Op::Deriv(s, order) => {
                let (lo, hi) = fp.sensor_raw_range[s.index()];
                let span = hi as i64 - lo as i64;
                let dmax = if *order == 1 { span } else { 2 * span };
                let (k, fk) = fp.deriv_gain[*order as usize - 1];
                prim::deriv(
                    &format!("d{}_{order}", s.0),
                    dmax,
                    k,
                    fr - (fp.sensor_frac[s.index()] + fk),
                )
            }
            Op::State(s) => {
                prim::convert(&format!("s->states[{}]", s.0), fp.state_frac[s.index()], fr)
            }
            Op::Mode(m) => format!("(int32_t)s->modes[{}]", m.0),
            Op::Edge(e) => format!("(int32_t)s->edges[{}]", e.0),
            Op::Neg(x) => prim::neg(&name(x), f(x), fr),
            Op::Not(x) => format!("!{}", name(x)),
            Op::Arith(o, x, y) => match o {
                ArithOp::Add => prim::add(&name(x), f(x), &name(y), f(y), fr, false),
                ArithOp::Sub => prim::add(&name(x), f(x), &name(y), f(y), fr, true),
                ArithOp::Mul => {
                    product(fp.mul_kind[v.index()], (name(x), f(x)), (name(y), f(y)), fr)
                }
                ArithOp::Div => match fp.recip[v.index()] {
                    Some((r, fr_r)) => {
                        let prod =
                            product(fp.mul_kind[v.index()], (name(x), f(x)), (lit(r), fr_r), fr);
                        // The divisor's word is not read: keep it used for the C compiler.
                        format!("((void){}, {})", name(y), prod)
                    }
                    None => prim::div(&name(x), f(x), &name(y), f(y), fp.div_shift[v.index()], fr),
                },
            },
            Op::Cmp(o, x, y) => match (fp.exact_const(*x), fp.exact_const(*y)) {
                (_, Some(k)) if real(x) => format!(
                    "((void){}, {})",
                    name(y),
                    prim::cmp_const(*o, &name(x), f(x), k, false)
                ),
                (Some(k), _) if real(y) => format!(
                    "((void){}, {})",
                    name(x),
                    prim::cmp_const(*o, &name(y), f(y), k, true)
                ),
                _ => prim::cmp(*o, &name(x), f(x), &name(y), f(y)),
            },
            Op::And(x, y) => format!("({} && {})", name(x), name(y)),
            Op::Or(x, y) => format!("({} || {})", name(x), name(y)),
            Op::Select(c, x, y) => match p.values[v.index()].ty {
                Ty::Real(_) => format!(
                    "({} ? {} : {})",
                    name(c),
                    prim::convert(&name(x), f(x), fr),
                    prim::convert(&name(y), f(y), fr)
                ),
                _ => format!("({} ? {} : {})", name(c), name(x), name(y)),
            },
            Op::Call(func, x, y) => {
                let (a, fa) = (name(x), f(x));
                match func {
                    Builtin::Abs => format!(
                        "({a} < 0 ? {} : {})",
                        prim::neg(&a, fa, fr),
                        prim::convert(&a, fa, fr)
                    ),
                    Builtin::Sqrt => prim::sqrt(&a, fa, fr),
                    Builtin::Exp => prim::exp(&a, fa, fr),
                    Builtin::Min | Builtin::Max => {
                        let (c, fc) = match y {
                            Some(y) => (name(y), f(y)),
                            None => (a.clone(), fa),
                        };
                        let op = if *func == Builtin::Min {
                            CmpOp::Le
                        } else {
                            CmpOp::Ge
                        };
                        format!(
                            "({} ? {} : {})",
                            prim::cmp(op, &a, fa, &c, fc),
                            prim::convert(&a, fa, fr),
                            prim::convert(&c, fc, fr)
                        )
                    }
                }
            }
        })
    }
}
