//! Lowering: AST → IR, with name resolution, the dimension check and component instancing.
//!
//! The pass works in three steps, so that declaration order never matters for names:
//! 1. **declare** ([`scope`]): every instrument and instanced component gets a scope; every
//!    name is entered with its kind (duplicates are reported here);
//! 2. **constants**: params, sensor ranges, state initial values and ranges are evaluated at
//!    compile time (after `--param` overrides), by lowering them to scratch IR and folding it;
//! 3. **body**: the per-sample update is generated phase by phase (events, outputs, dynamics;
//!    see [`crate::ir`]). `let`, `force` and `output` definitions and component inputs are
//!    lowered on first use and memoised until a state or mode is written, so a definition
//!    always sees the current values, and an unchanged one is computed once.
//!
//! Errors are collected, not thrown: a bad declaration is reported and lowering goes on, so
//! one run shows every problem. Dimension rules are in [`expr`].

mod consts;
mod expr;
mod fold;
mod scope;
mod tolerance;

use crate::ast::{self, Span};
use crate::diagnostics::Diagnostic;
use crate::ir::*;
use crate::units::Dim;
use std::collections::{HashMap, HashSet};

pub use expr::SAMPLE_RATE;
pub use scope::ScopeId;
use scope::{DefKind, Scope, Sym};

/// The built-in functions: (name, signature as written).
pub const BUILTINS: &[(&str, &str)] = &[
    ("abs", "abs(x)"),
    ("sqrt", "sqrt(x)"),
    ("exp", "exp(x)"),
    ("min", "min(a, b)"),
    ("max", "max(a, b)"),
    ("clamp", "clamp(x, lo, hi)"),
    ("d", "d(sensor)"),
    ("d2", "d2(sensor)"),
];

/// Whether `name` is a built-in function.
pub fn is_builtin(name: &str) -> bool {
    BUILTINS.iter().any(|(n, _)| *n == name)
}

/// What lowering needs besides the source.
#[derive(Clone, Debug)]
pub struct Config {
    /// Sample rate of the board the dynamics are discretised for, Hz.
    pub sample_rate_hz: f64,
    /// `--param name=value` overrides: (name, value as source text such as `200 N/m`).
    pub overrides: Vec<(String, String)>,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            sample_rate_hz: tactus_runtime::DEFAULT_SAMPLE_RATE_HZ,
            overrides: Vec::new(),
        }
    }
}

/// A lowered program and the warnings found on the way.
#[derive(Clone, Debug)]
pub struct Lowered {
    /// The IR.
    pub program: Program,
    /// Warnings (unused definitions, …).
    pub warnings: Vec<Diagnostic>,
}

/// The most IR values lowering may produce (E0139; hostile input — a definition re-lowered
/// in every place it is used, copies of copies — must not grow the program without bound).
/// The largest shipped instrument, the bowed string, has about 19,000.
pub const MAX_LOWERED_VALUES: usize = 1 << 19;

/// Lowers a parsed file. Fails with every error found (and the warnings) when any error
/// is found.
pub fn lower(file: &ast::File, config: &Config) -> Result<Lowered, Vec<Diagnostic>> {
    lower_indexed(file, config, None)
}

/// [`lower`], also appending every name the resolver resolves to `names`, as (where it is
/// written, the span of its declaration's name): what an editor asks for "go to
/// definition" and "find references" (`crate::query::NameIndex` sorts them). They are
/// recorded whether or not lowering succeeds; none when expansion fails.
pub fn lower_indexed(
    file: &ast::File,
    config: &Config,
    names: Option<&mut Vec<(Span, Span)>>,
) -> Result<Lowered, Vec<Diagnostic>> {
    let file = crate::expand::expand(file, &config.overrides)?;
    let mut l = Lowerer::new(config);
    if names.is_some() {
        l.refs = Some(Vec::new());
    }
    l.run(&file);
    if let (Some(out), Some(mut refs)) = (names, l.refs.take()) {
        out.append(&mut refs);
    }
    let (errors, warnings): (Vec<_>, Vec<_>) = l.diags.into_iter().partition(|d| d.is_error());
    if errors.is_empty() {
        Ok(Lowered {
            program: l.prog,
            warnings,
        })
    } else {
        Err(errors.into_iter().chain(warnings).collect())
    }
}

/// A definition lowered on demand.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Memo {
    Def(usize),
    Input(ScopeId, usize),
    State(StateId),
    Mode(ModeId),
    Sensor(SensorId),
    Deriv(SensorId, u8),
    Param(ParamId),
}

struct ParamInfo<'a> {
    expr: &'a ast::Expr,
    scope: ScopeId,
    annot: Option<&'a ast::Spanned<ast::TypeAnn>>,
    done: Option<Option<(f64, Dim)>>,
}

struct DefInfo<'a> {
    scope: ScopeId,
    kind: DefKind,
    name: &'a ast::Name,
    expr: &'a ast::Expr,
    used: bool,
}

struct Lowerer<'a> {
    config: &'a Config,
    components: HashMap<&'a str, &'a ast::Body>,
    prog: Program,
    diags: Vec<Diagnostic>,
    /// What `diags` holds, by (code, primary span, message): a definition lowered several
    /// times (once per memo epoch, or once per copy in an expansion — a `solve`'s symbolic
    /// slope copies its residual's factors) reports each error once, so the list is bounded
    /// by the source's size, not by how often lowering meets the same node.
    diag_keys: HashSet<(&'static str, std::ops::Range<usize>, String)>,
    /// Spans already reported as unknown names (E0201): a name in a loop body is looked up
    /// once per index, but reported once.
    unknown_reported: HashSet<Span>,
    /// AST nodes instanced so far (each component instance adds its body's), against
    /// [`scope::MAX_INSTANCED_NODES`].
    instanced: usize,
    scopes: Vec<Scope<'a>>,
    params: Vec<ParamInfo<'a>>,
    defs: Vec<DefInfo<'a>>,
    memo: HashMap<Memo, Value>,
    in_progress: HashSet<Memo>,
    /// Statement lists being filled; the last one is current.
    blocks: Vec<Vec<Stmt>>,
    /// True while lowering compile-time constants (params, ranges, initial values).
    const_ctx: bool,
    dynamics_of: HashMap<StateId, Span>,
    /// Span of the innermost expression being lowered (recorded on each value).
    cur_span: Span,
    /// `--param` overrides by param index: (value in SI, dimension, text as given).
    overrides: HashMap<usize, (f64, Dim, String)>,
    /// `tolerance` lines evaluated, resolved after the body ([`tolerance`]).
    tolerances: Vec<tolerance::PendingTolerance<'a>>,
    /// When indexing ([`lower_indexed`]): every resolved name, (where it is written, the
    /// span of the declaration's name it denotes).
    refs: Option<Vec<(Span, Span)>>,
}

impl<'a> Lowerer<'a> {
    fn new(config: &'a Config) -> Self {
        Lowerer {
            config,
            components: HashMap::new(),
            prog: Program {
                name: String::new(),
                sample_rate_hz: config.sample_rate_hz,
                sensors: vec![],
                params: vec![],
                states: vec![],
                modes: vec![],
                forces: vec![],
                outputs: vec![],
                events: vec![],
                edges: vec![],
                values: vec![],
                body: vec![],
                force_axes: vec![],
                contract: Contract::default(),
                runtime_keys: vec![],
            },
            diags: vec![],
            diag_keys: HashSet::new(),
            unknown_reported: HashSet::new(),
            instanced: 0,
            scopes: vec![],
            params: vec![],
            defs: vec![],
            memo: HashMap::new(),
            in_progress: HashSet::new(),
            blocks: vec![vec![]],
            const_ctx: false,
            dynamics_of: HashMap::new(),
            overrides: HashMap::new(),
            tolerances: Vec::new(),
            cur_span: 0..0,
            refs: None,
        }
    }

    /// Records that the name written at `at` denotes the declaration named at `def` (only
    /// when indexing).
    fn record_ref(&mut self, at: &Span, def: &Span) {
        if let Some(refs) = &mut self.refs {
            refs.push((at.clone(), def.clone()));
        }
    }

    fn err(&mut self, d: Diagnostic) {
        if self
            .diag_keys
            .insert((d.code, d.primary.0.clone(), d.message.clone()))
        {
            self.diags.push(d);
        }
    }

    fn run(&mut self, file: &'a ast::File) {
        let mut instrument: Option<&'a ast::Body> = None;
        for item in &file.items {
            match item {
                ast::TopItem::Component(b) => {
                    if let Some(prev) = self.components.insert(&b.name.node, b) {
                        self.err(
                            Diagnostic::error(
                                "E0101",
                                format!("component `{}` is defined twice", b.name.node),
                                b.name.span.clone(),
                            )
                            .with_secondary(prev.name.span.clone(), "first defined here"),
                        );
                    }
                }
                // Resolved by `crate::imports::link`.
                ast::TopItem::Import(_) => {}
                ast::TopItem::Instrument(b) => match instrument {
                    Some(first) => self.err(
                        Diagnostic::error(
                            "E0102",
                            "a file defines one instrument",
                            b.name.span.clone(),
                        )
                        .with_secondary(first.name.span.clone(), "the instrument of this file")
                        .hint("put each instrument in its own .tactus file"),
                    ),
                    None => instrument = Some(b),
                },
            }
        }
        let Some(inst) = instrument else {
            let end = file.items.last().map_or(0..0, |i| match i {
                ast::TopItem::Component(b) | ast::TopItem::Instrument(b) => b.span.clone(),
                ast::TopItem::Import(i) => i.span.clone(),
            });
            self.err(
                Diagnostic::error("E0103", "no instrument in this file", end)
                    .hint("add `instrument NAME { … }` that uses the components defined here; a file of components only is a library: import it from an instrument's file (`import \"FILE\"`)"),
            );
            return;
        };
        self.prog.name = inst.name.node.clone();
        let root = self.declare_scope(inst, String::new(), None, &[], inst.name.span.clone(), 0);
        self.apply_overrides();
        self.evaluate_constants();
        self.generate_body(root);
        self.resolve_tolerances();
        self.check_unused();
    }

    // ---- body generation -------------------------------------------------------------

    /// Visits the declarations of `scope` in source order, expanding `use` in place.
    fn expanded_decls(&self, scope: ScopeId) -> Vec<(ScopeId, &'a ast::Decl)> {
        let mut out = Vec::new();
        for d in &self.scopes[scope.0].body.decls {
            out.push((scope, d));
            if let ast::Decl::Use { name, .. } = d {
                if let Some((Sym::Instance(child), _)) = self.scopes[scope.0].syms.get(&name.node) {
                    out.extend(self.expanded_decls(*child));
                }
            }
        }
        out
    }

    fn generate_body(&mut self, root: ScopeId) {
        self.memo.clear();
        self.prog.values.clear();
        self.blocks = vec![vec![]];
        let decls = self.expanded_decls(root);
        // Phase 2: event handlers.
        for &(scope, d) in &decls {
            if let ast::Decl::Handler {
                trigger,
                cond,
                body,
                span,
            } = d
            {
                self.lower_handler(scope, *trigger, cond, body, span.clone());
            }
        }
        // Phase 3: force terms, outputs, total. An instrument with a vector force is a pen:
        // each term has an axis, and each axis its own sum (x and y as outputs, z the total).
        let first_vector = decls.iter().find_map(|(_, d)| match d {
            ast::Decl::Force {
                name,
                axis: Some(_),
                ..
            } => Some(name.span.clone()),
            _ => None,
        });
        let mut forces = Vec::new();
        let mut axis_terms: [Vec<Value>; 3] = Default::default();
        for &(scope, d) in &decls {
            match d {
                ast::Decl::Force { name, axis, .. } => {
                    if let (None, Some(pen)) = (axis, &first_vector) {
                        self.err(
                            Diagnostic::error(
                                "E0134",
                                format!(
                                    "force term `{}` has no axis, but this is a pen instrument",
                                    name.node
                                ),
                                name.span.clone(),
                            )
                            .label("a scalar force term")
                            .with_secondary(
                                pen.clone(),
                                "this vector force makes the commanded force a 3-vector",
                            )
                            .hint(format!(
                                "say which axis: `force {} = {{ z: … }}` (z pushes out of the surface, x along the stroke, y across)",
                                name.node
                            )),
                        );
                        continue;
                    }
                    let idx = self.def_index(scope, &name.node);
                    if let Some(v) = self.lower_def(idx, name.span.clone()) {
                        if self.ty(v) != Ty::Real(Dim::FORCE) {
                            let msg = format!(
                                "force term `{}` is {}, not a force",
                                name.node,
                                self.ty_string(self.ty(v))
                            );
                            self.err(
                                Diagnostic::error("E0206", msg, self.defs[idx].expr.span.clone())
                                    .label("must be in newtons")
                                    .hint("a force term's expression must have the dimension of N (kg*m/s^2)"),
                            );
                            continue;
                        }
                        let id = ForceId(self.prog.forces.len() as u32);
                        self.prog.forces.push(NamedDecl {
                            name: self.qualified(scope, &name.node),
                            ty: Ty::Real(Dim::FORCE),
                            span: name.span.clone(),
                            axis: *axis,
                        });
                        self.emit_stmt(Stmt::Force(id, v));
                        match axis {
                            Some(a) => axis_terms[*a as usize].push(v),
                            None => forces.push(v),
                        }
                    }
                }
                ast::Decl::Output { name, .. } if scope == root => {
                    let idx = self.def_index(scope, &name.node);
                    if let Some(v) = self.lower_def(idx, name.span.clone()) {
                        let id = OutputId(self.prog.outputs.len() as u32);
                        self.prog.outputs.push(NamedDecl {
                            name: name.node.clone(),
                            ty: self.ty(v),
                            span: name.span.clone(),
                            axis: None,
                        });
                        self.emit_stmt(Stmt::Output(id, v));
                    }
                }
                _ => {}
            }
        }
        if let Some(pen) = first_vector {
            let [x, y, z] = axis_terms;
            for (axis, terms) in [(Axis::X, x), (Axis::Y, y)] {
                let sum = self.force_sum(&terms);
                let id = OutputId(self.prog.outputs.len() as u32);
                self.prog.outputs.push(NamedDecl {
                    name: format!("force.{axis}"),
                    ty: Ty::Real(Dim::FORCE),
                    span: pen.clone(),
                    axis: Some(axis),
                });
                self.emit_stmt(Stmt::Output(id, sum));
                self.prog.force_axes.push((axis, AxisTotal::Output(id)));
            }
            forces = z;
            self.prog.force_axes.push((Axis::Z, AxisTotal::Total));
        }
        let total = match forces.split_first() {
            Some(_) => self.force_sum(&forces),
            None => {
                let span = self.scopes[root.0].body.name.span.clone();
                let declared = decls
                    .iter()
                    .any(|(_, d)| matches!(d, ast::Decl::Force { .. }));
                if !declared {
                    self.err(
                        Diagnostic::warning("W0002", "this instrument has no force terms", span)
                            .hint(
                                "declare `force NAME = …` terms; their sum is the commanded force",
                            ),
                    );
                }
                self.def(Op::Const(0.0), Ty::Real(Dim::FORCE))
            }
        };
        self.emit_stmt(Stmt::Total(total));
        // Phase 4: dynamics, semi-implicit Euler in source order.
        let h = 1.0 / self.config.sample_rate_hz;
        for &(scope, d) in &decls {
            if let ast::Decl::Dynamics { eqs, .. } = d {
                for eq in eqs {
                    self.lower_equation(scope, eq, h);
                }
            }
        }
        self.prog.body = self.blocks.pop().unwrap_or_default();
        fold::fold_constants(&mut self.prog);
        // A run-time expression whose constant part folds to NaN or ±∞ (`exp(1000) * 1 N`)
        // is as meaningless as such a param: report the first one, at its span.
        let bad = self.prog.values.iter().find_map(|v| match v.op {
            Op::Const(c) if !c.is_finite() => Some((c, v.span.clone())),
            _ => None,
        });
        if let Some((c, span)) = bad {
            self.err(
                Diagnostic::error("E0312", format!("this constant is {c}, not a finite number"), span)
                    .label(format!("folds to {c}"))
                    .hint("look for a division by zero (a param or `--param` of 0), `exp` or `^` of a large value, or a number beyond 1.8e308 in SI units"),
            );
        }
    }

    /// The saturating sum of force terms in declaration order (a constant 0 N for none).
    fn force_sum(&mut self, terms: &[Value]) -> Value {
        match terms.split_first() {
            Some((&first, rest)) => rest.iter().fold(first, |acc, &f| {
                self.def(Op::Arith(ArithOp::Add, acc, f), Ty::Real(Dim::FORCE))
            }),
            None => self.def(Op::Const(0.0), Ty::Real(Dim::FORCE)),
        }
    }

    fn lower_equation(&mut self, scope: ScopeId, eq: &'a ast::Equation, h: f64) {
        let state = match self.lookup(scope, &eq.state) {
            Some(Sym::State(s)) => s,
            Some(other) => {
                let what = other.describe();
                self.err(
                    Diagnostic::error(
                        "E0207",
                        format!("`{}` is a {what}; only states have dynamics", eq.state.node),
                        eq.state.span.clone(),
                    )
                    .hint(format!(
                        "declare it as `state {} = … in [lo, hi]`",
                        eq.state.node
                    )),
                );
                return;
            }
            None => return,
        };
        if let Some(prev) = self.dynamics_of.insert(state, eq.state.span.clone()) {
            self.err(
                Diagnostic::error(
                    "E0208",
                    format!("state `{}` has two dynamics equations", eq.state.node),
                    eq.state.span.clone(),
                )
                .with_secondary(prev, "first equation here"),
            );
            return;
        }
        let Some(rhs) = self.lower_expr(scope, &eq.rhs) else {
            return;
        };
        let sdim = self.prog.states[state.index()].dim;
        let want = Ty::Real(sdim / Dim::TIME);
        if self.ty(rhs) != want {
            let msg = format!(
                "the derivative of `{}` must be {}, but this is {}",
                eq.state.node,
                self.ty_string(want),
                self.ty_string(self.ty(rhs))
            );
            self.err(
                Diagnostic::error("E0209", msg, eq.rhs.span.clone())
                    .label("wrong dimension for a time derivative")
                    .hint(format!(
                        "`{}` is {}; its derivative is that per second",
                        eq.state.node, sdim
                    )),
            );
            return;
        }
        let hv = self.def(Op::Const(h), Ty::Real(Dim::TIME));
        let step = self.def(Op::Arith(ArithOp::Mul, rhs, hv), Ty::Real(sdim));
        let cur = self.read_state(state);
        let next = self.def(Op::Arith(ArithOp::Add, cur, step), Ty::Real(sdim));
        self.emit_stmt(Stmt::SetState(state, next));
        self.memo.clear();
    }

    fn lower_handler(
        &mut self,
        scope: ScopeId,
        trigger: ast::Trigger,
        cond: &'a ast::Expr,
        body: &'a [ast::Stmt],
        span: Span,
    ) {
        let Some(c) = self.lower_expr(scope, cond) else {
            return;
        };
        if self.ty(c) != Ty::Bool {
            let msg = format!(
                "a handler's condition must be true or false, but this is {}",
                self.ty_string(self.ty(c))
            );
            self.err(
                Diagnostic::error("E0210", msg, cond.span.clone()).hint("compare it: `x > 5 mm`"),
            );
            return;
        }
        let fire = match trigger {
            ast::Trigger::Level => c,
            ast::Trigger::Edge => {
                let e = EdgeId(self.prog.edges.len() as u32);
                self.prog.edges.push(EdgeDecl { span });
                let prev = self.def(Op::Edge(e), Ty::Bool);
                let was_false = self.def(Op::Not(prev), Ty::Bool);
                let fire = self.def(Op::And(c, was_false), Ty::Bool);
                self.emit_stmt(Stmt::SetEdge(e, c));
                fire
            }
        };
        self.blocks.push(Vec::new());
        for s in body {
            self.lower_stmt(scope, s);
        }
        let stmts = self.blocks.pop().unwrap_or_default();
        self.memo.clear();
        self.emit_stmt(Stmt::If(fire, stmts));
    }

    fn lower_stmt(&mut self, scope: ScopeId, s: &'a ast::Stmt) {
        match s {
            ast::Stmt::Assign { target, value, .. } => match self.lookup(scope, target) {
                Some(Sym::State(st)) => {
                    let Some(v) = self.lower_expr(scope, value) else {
                        return;
                    };
                    let want = Ty::Real(self.prog.states[st.index()].dim);
                    if self.ty(v) != want {
                        let msg = format!(
                            "cannot assign {} to state `{}` of {}",
                            self.ty_string(self.ty(v)),
                            target.node,
                            self.ty_string(want)
                        );
                        self.err(
                            Diagnostic::error("E0211", msg, value.span.clone())
                                .label("wrong dimension"),
                        );
                        return;
                    }
                    self.emit_stmt(Stmt::SetState(st, v));
                    self.memo.clear();
                }
                Some(Sym::Mode(m)) => {
                    let variants = &self.prog.modes[m.index()].variants;
                    let idx = match &value.node {
                        ast::ExprKind::Path(p) if p.len() == 1 => {
                            variants.iter().position(|v| *v == p[0].node)
                        }
                        _ => None,
                    };
                    match idx {
                        Some(i) => {
                            self.emit_stmt(Stmt::SetMode(m, i as u32));
                            self.memo.clear();
                        }
                        None => {
                            let list = variants.join(", ");
                            self.err(
                                Diagnostic::error(
                                    "E0212",
                                    format!(
                                        "mode `{}` can only be set to one of its variants",
                                        target.node
                                    ),
                                    value.span.clone(),
                                )
                                .label("not a variant of this mode")
                                .hint(format!("the variants are: {list}")),
                            );
                        }
                    }
                }
                Some(other) => {
                    let what = other.describe();
                    self.err(
                        Diagnostic::error("E0213", format!("cannot assign to `{}`: it is a {what}", target.node), target.span.clone())
                            .label("not assignable")
                            .hint("handlers may assign states and modes only; params are constants and sensors are inputs"),
                    );
                }
                None => {}
            },
            ast::Stmt::Emit { event, args, span } => {
                let mut vals = Vec::new();
                let mut sig = Vec::new();
                for (name, e) in args {
                    let Some(v) = self.lower_expr(scope, e) else {
                        return;
                    };
                    let Ty::Real(d) = self.ty(v) else {
                        self.err(Diagnostic::error(
                            "E0214",
                            "event arguments must be quantities",
                            e.span.clone(),
                        ));
                        return;
                    };
                    vals.push(v);
                    sig.push((name.node.clone(), d));
                }
                let id = match self.prog.events.iter().position(|ev| ev.name == event.node) {
                    Some(i) => {
                        if self.prog.events[i].args != sig {
                            let show = |s: &[(String, Dim)]| {
                                s.iter()
                                    .map(|(n, d)| format!("{n}: {}", d.unit_string()))
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            };
                            let msg = format!(
                                "event `{}` is emitted with ({}) here but with ({}) elsewhere",
                                event.node,
                                show(&sig),
                                show(&self.prog.events[i].args)
                            );
                            self.err(Diagnostic::error("E0215", msg, span.clone()).hint("every emit of an event has the same named arguments with the same units"));
                            return;
                        }
                        EventId(i as u32)
                    }
                    None => {
                        self.prog.events.push(EventDecl {
                            name: event.node.clone(),
                            args: sig,
                        });
                        EventId(self.prog.events.len() as u32 - 1)
                    }
                };
                self.emit_stmt(Stmt::Emit(id, vals));
            }
        }
    }

    fn check_unused(&mut self) {
        for i in 0..self.defs.len() {
            if !self.defs[i].used {
                // Lower it anyway (into a discarded block) so its errors are reported.
                self.blocks.push(Vec::new());
                let span = self.defs[i].name.span.clone();
                let _ = self.lower_def(i, span.clone());
                self.blocks.pop();
                self.memo.clear();
                if self.defs[i].kind == DefKind::Let {
                    let name = self.defs[i].name.node.clone();
                    self.err(
                        Diagnostic::warning("W0001", format!("`{name}` is never used"), span).hint(
                            "remove it, or use it in a force term, output, condition or equation",
                        ),
                    );
                }
            }
        }
    }

    // ---- helpers ------------------------------------------------------------------------

    fn emit_stmt(&mut self, s: Stmt) {
        if let Some(b) = self.blocks.last_mut() {
            b.push(s);
        }
    }

    /// Adds a value and its `Def` statement to the current block.
    fn def(&mut self, op: Op, ty: Ty) -> Value {
        let v = Value(self.prog.values.len() as u32);
        self.prog.values.push(ValueData {
            op,
            ty,
            span: self.cur_span.clone(),
        });
        self.emit_stmt(Stmt::Def(v));
        v
    }

    fn ty(&self, v: Value) -> Ty {
        self.prog.values[v.index()].ty
    }

    fn ty_string(&self, t: Ty) -> String {
        match t {
            Ty::Real(d) => d.to_string(),
            Ty::Bool => "a truth value".into(),
            Ty::Mode(m) => format!("a mode value of `{}`", self.prog.modes[m.index()].name),
        }
    }

    fn memoised(&mut self, key: Memo, op: Op, ty: Ty) -> Value {
        if let Some(&v) = self.memo.get(&key) {
            return v;
        }
        let v = self.def(op, ty);
        self.memo.insert(key, v);
        v
    }

    fn read_state(&mut self, s: StateId) -> Value {
        let d = self.prog.states[s.index()].dim;
        self.memoised(Memo::State(s), Op::State(s), Ty::Real(d))
    }

    fn qualified(&self, scope: ScopeId, name: &str) -> String {
        format!("{}{name}", self.scopes[scope.0].prefix)
    }

    fn def_index(&self, scope: ScopeId, name: &str) -> usize {
        match self.scopes[scope.0].syms.get(name) {
            Some((Sym::Def(i), _)) => *i,
            _ => usize::MAX,
        }
    }

    /// Lowers a let/force/output definition once per memo epoch; reports cycles.
    fn lower_def(&mut self, idx: usize, use_span: Span) -> Option<Value> {
        let def = self.defs.get_mut(idx)?;
        def.used = true;
        let (scope, expr, name) = (def.scope, def.expr, def.name);
        let key = Memo::Def(idx);
        if let Some(&v) = self.memo.get(&key) {
            return Some(v);
        }
        if !self.in_progress.insert(key) {
            self.err(
                Diagnostic::error("E0216", format!("`{}` is defined in terms of itself", name.node), use_span)
                    .with_secondary(name.span.clone(), "defined here")
                    .hint("break the cycle with a state: states keep their value from the previous sample"),
            );
            return None;
        }
        let v = self.lower_expr(scope, expr);
        self.in_progress.remove(&key);
        if let Some(v) = v {
            self.memo.insert(key, v);
        }
        v
    }
}
