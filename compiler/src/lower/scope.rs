//! Scopes: the names of an instrument or of one component instance, and what they denote.
//!
//! Every `use` creates a child scope whose names are qualified by the instance name in the
//! IR (`esc.phase`), so a component instanced three times gets three independent sets of
//! states and modes. A child sees only its own names; its inputs are bound to expressions
//! evaluated in the parent's scope.

use super::{DefInfo, Lowerer, ParamInfo};
use crate::ast::{self, Span};
use crate::diagnostics::Diagnostic;
use crate::ir::*;
use crate::units::{self, Dim};
use std::collections::HashMap;

/// Index of a scope (0 is the instrument).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ScopeId(pub usize);

/// What kind of definition a `let`-like name is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DefKind {
    Let,
    Force,
    Output,
}

/// What a name denotes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sym {
    Sensor(SensorId),
    Param(ParamId),
    State(StateId),
    Mode(ModeId),
    /// A let, force or output: index into the lowerer's definitions.
    Def(usize),
    /// A component input: index into the scope's inputs.
    Input(usize),
    /// A component instance.
    Instance(ScopeId),
}

impl Sym {
    /// "param", "sensor", … for messages.
    pub fn describe(self) -> &'static str {
        match self {
            Sym::Sensor(_) => "sensor",
            Sym::Param(_) => "param",
            Sym::State(_) => "state",
            Sym::Mode(_) => "mode",
            Sym::Def(_) => "definition (let, force or output)",
            Sym::Input(_) => "component input",
            Sym::Instance(_) => "component instance",
        }
    }
}

/// A component input and the expression bound to it.
pub struct Input<'a> {
    pub name: &'a ast::Name,
    pub dim: Option<Ty>,
    pub arg: Option<&'a ast::Expr>,
}

pub struct Scope<'a> {
    pub prefix: String,
    pub parent: Option<ScopeId>,
    pub body: &'a ast::Body,
    pub syms: HashMap<String, (Sym, Span)>,
    pub inputs: Vec<Input<'a>>,
}

impl<'a> Lowerer<'a> {
    /// Resolves a type annotation to a type, reporting unknown units.
    pub(super) fn annot_ty(&mut self, a: &ast::Spanned<ast::TypeAnn>) -> Option<Ty> {
        match &a.node {
            ast::TypeAnn::Bool => Some(Ty::Bool),
            ast::TypeAnn::Unit(factors) => {
                let mut d = Dim::NONE;
                for (n, e) in factors {
                    match units::lookup(&n.node) {
                        Some(u) => d = d * u.dim.powi(*e),
                        None => {
                            self.err(
                                Diagnostic::error(
                                    "E0104",
                                    format!("unknown unit `{}` in a type", n.node),
                                    n.span.clone(),
                                )
                                .hint(format!(
                                    "known units: {}",
                                    units::unit_names().collect::<Vec<_>>().join(", ")
                                )),
                            );
                            return None;
                        }
                    }
                }
                Some(Ty::Real(d))
            }
        }
    }

    fn add_sym(&mut self, scope: ScopeId, name: &ast::Name, sym: Sym) {
        if let Some((_, prev)) = self.scopes[scope.0].syms.get(&name.node) {
            let prev = prev.clone();
            self.err(
                Diagnostic::error(
                    "E0105",
                    format!("`{}` is defined twice", name.node),
                    name.span.clone(),
                )
                .label("second definition")
                .with_secondary(prev, "first defined here")
                .hint("every name in an instrument or component is unique; rename one of them"),
            );
            return;
        }
        if crate::lower::is_builtin(&name.node) {
            self.err(
                Diagnostic::error(
                    "E0106",
                    format!(
                        "`{}` is a built-in function and cannot be redefined",
                        name.node
                    ),
                    name.span.clone(),
                )
                .hint("choose another name"),
            );
        }
        self.scopes[scope.0]
            .syms
            .insert(name.node.clone(), (sym, name.span.clone()));
    }

    /// Declares every name of `body` in a new scope; instances its `use`s recursively (at
    /// most [`MAX_COMPONENT_DEPTH`] deep and [`MAX_INSTANCES`] scopes in all).
    pub(super) fn declare_scope(
        &mut self,
        body: &'a ast::Body,
        prefix: String,
        parent: Option<ScopeId>,
        args: &'a [(ast::Name, ast::Expr)],
        use_span: Span,
        depth: usize,
    ) -> ScopeId {
        let id = ScopeId(self.scopes.len());
        self.scopes.push(Scope {
            prefix: prefix.clone(),
            parent,
            body,
            syms: HashMap::new(),
            inputs: vec![],
        });
        let is_component = parent.is_some();
        let mut arg_used = vec![false; args.len()];
        let mut find_arg = |name: &str| {
            args.iter().position(|(n, _)| n.node == name).map(|i| {
                arg_used[i] = true;
                &args[i].1
            })
        };
        for d in &body.decls {
            match d {
                ast::Decl::Sensor { name, .. } if is_component => {
                    self.err(
                        Diagnostic::error("E0107", "components have inputs, not sensors", name.span.clone())
                            .hint(format!("declare `input {}: m` and pass the sensor when you `use` the component", name.node)),
                    );
                }
                ast::Decl::Sensor { name, ty, range } => {
                    let sid = SensorId(self.prog.sensors.len() as u32);
                    self.prog.sensors.push(SensorDecl {
                        name: name.node.clone(),
                        dim: Dim::NONE,
                        range: (0.0, 0.0),
                        differentiated: false,
                        span: name.span.clone(),
                    });
                    self.add_sym(id, name, Sym::Sensor(sid));
                    if range.is_none() {
                        self.err(
                            Diagnostic::error("E0108", format!("sensor `{}` has no range", name.node), name.span.clone())
                                .hint(format!("declare the range it reads, e.g. `sensor {} in [0 mm, 10 mm]`: fixed-point formats are chosen from it", name.node)),
                        );
                    }
                    let _ = ty;
                }
                ast::Decl::Input { name, ty } => {
                    if !is_component {
                        self.err(
                            Diagnostic::error(
                                "E0109",
                                "inputs belong to components; an instrument reads sensors",
                                name.span.clone(),
                            )
                            .hint(format!("write `sensor {} in [lo, hi]`", name.node)),
                        );
                        continue;
                    }
                    let dim = match ty {
                        Some(t) => self.annot_ty(t),
                        None => {
                            self.err(
                                Diagnostic::error(
                                    "E0110",
                                    format!("input `{}` needs a type", name.node),
                                    name.span.clone(),
                                )
                                .hint(format!(
                                    "write `input {}: m` (a unit) or `input {}: bool`",
                                    name.node, name.node
                                )),
                            );
                            None
                        }
                    };
                    let arg = find_arg(&name.node);
                    let idx = self.scopes[id.0].inputs.len();
                    self.scopes[id.0].inputs.push(Input { name, dim, arg });
                    self.add_sym(id, name, Sym::Input(idx));
                }
                ast::Decl::Param { name, ty, value } => {
                    let pid = ParamId(self.prog.params.len() as u32);
                    self.prog.params.push(ParamDecl {
                        name: format!("{prefix}{}", name.node),
                        dim: Dim::NONE,
                        value: f64::NAN,
                        span: name.span.clone(),
                        runtime: None,
                    });
                    let (expr, scope) = match (find_arg(&name.node), parent) {
                        (Some(a), Some(p)) => (a, p),
                        _ => (value, id),
                    };
                    self.params.push(ParamInfo {
                        expr,
                        scope,
                        annot: ty.as_ref(),
                        done: None,
                    });
                    self.add_sym(id, name, Sym::Param(pid));
                }
                ast::Decl::State { name, range, .. } => {
                    let sid = StateId(self.prog.states.len() as u32);
                    self.prog.states.push(StateDecl {
                        name: format!("{prefix}{}", name.node),
                        dim: Dim::NONE,
                        init: 0.0,
                        range: (0.0, 0.0),
                        span: name.span.clone(),
                    });
                    self.add_sym(id, name, Sym::State(sid));
                    if range.is_none() {
                        self.err(
                            Diagnostic::error("E0111", format!("state `{}` has no range", name.node), name.span.clone())
                                .hint("add `in [lo, hi]`: the range bounds the state (writes saturate to it) and sets its fixed-point format"),
                        );
                    }
                }
                ast::Decl::Mode {
                    name,
                    variants,
                    init,
                } => {
                    let mut names: Vec<String> = Vec::new();
                    for v in variants {
                        if names.contains(&v.node) {
                            self.err(Diagnostic::error(
                                "E0112",
                                format!("variant `{}` is listed twice", v.node),
                                v.span.clone(),
                            ));
                        }
                        names.push(v.node.clone());
                    }
                    if names.is_empty() {
                        self.err(
                            Diagnostic::error(
                                "E0113",
                                format!("mode `{}` has no variants", name.node),
                                name.span.clone(),
                            )
                            .hint(format!(
                                "list them: `mode {} {{ ready, escaped }}`",
                                name.node
                            )),
                        );
                    }
                    let init_idx = match init {
                        None => 0,
                        Some(i) => match names.iter().position(|n| *n == i.node) {
                            Some(p) => p as u32,
                            None => {
                                self.err(
                                    Diagnostic::error(
                                        "E0114",
                                        format!(
                                            "`{}` is not a variant of mode `{}`",
                                            i.node, name.node
                                        ),
                                        i.span.clone(),
                                    )
                                    .hint(format!("the variants are: {}", names.join(", "))),
                                );
                                0
                            }
                        },
                    };
                    let mid = ModeId(self.prog.modes.len() as u32);
                    self.prog.modes.push(ModeDecl {
                        name: format!("{prefix}{}", name.node),
                        variants: names,
                        init: init_idx,
                        span: name.span.clone(),
                    });
                    self.add_sym(id, name, Sym::Mode(mid));
                }
                ast::Decl::Let { name, value, .. }
                | ast::Decl::Force { name, value, .. }
                | ast::Decl::Output { name, value, .. } => {
                    let kind = match d {
                        ast::Decl::Let { .. } => DefKind::Let,
                        ast::Decl::Force { .. } => DefKind::Force,
                        _ => DefKind::Output,
                    };
                    let idx = self.defs.len();
                    // Component outputs are read from outside; do not warn that they are unused.
                    let used = kind != DefKind::Let;
                    self.defs.push(DefInfo {
                        scope: id,
                        kind,
                        name,
                        expr: value,
                        used,
                    });
                    self.add_sym(id, name, Sym::Def(idx));
                }
                ast::Decl::Dynamics { .. }
                | ast::Decl::Handler { .. }
                | ast::Decl::Require { .. }
                | ast::Decl::Tolerance { .. }
                | ast::Decl::SolveRange { .. } => {}
                // Removed by `crate::expand` before lowering.
                ast::Decl::For { .. }
                | ast::Decl::Solve { .. }
                | ast::Decl::VectorSensor { .. }
                | ast::Decl::VectorForce { .. } => {}
                ast::Decl::Use {
                    name,
                    index: _,
                    component,
                    args: uargs,
                    span,
                } => {
                    if let Some(comp) = self.components.get(component.node.as_str()) {
                        let def = comp.name.span.clone();
                        self.record_ref(&component.span, &def);
                    }
                    let Some(&comp) = self.components.get(component.node.as_str()) else {
                        // `crate::imports::link` clears a name its file does not see, and
                        // reports it (E0115, with the import that would bring it).
                        if component.node.is_empty() {
                            continue;
                        }
                        let known: Vec<&str> = self.components.keys().copied().collect();
                        let hint = match crate::diagnostics::closest(
                            &component.node,
                            known.iter().copied(),
                        ) {
                            Some(c) => format!("did you mean `{c}`?"),
                            None if known.is_empty() => {
                                "define it in this file with `component NAME { … }`".into()
                            }
                            None => format!("components in this file: {}", known.join(", ")),
                        };
                        self.err(
                            Diagnostic::error(
                                "E0115",
                                format!("no component named `{}`", component.node),
                                component.span.clone(),
                            )
                            .hint(hint),
                        );
                        continue;
                    };
                    // The chain of components from this scope up to the instrument: a
                    // component already on it would be instanced without end.
                    let mut chain = vec![body.name.node.as_str()];
                    let mut up = self.scopes[id.0].parent;
                    let mut recursive = std::ptr::eq(comp, body);
                    while let Some(s) = up {
                        recursive |= std::ptr::eq(comp, self.scopes[s.0].body);
                        chain.push(self.scopes[s.0].body.name.node.as_str());
                        up = self.scopes[s.0].parent;
                    }
                    if recursive {
                        chain.reverse();
                        let path = chain.join(" → ");
                        self.err(
                            Diagnostic::error(
                                "E0116",
                                format!("component `{}` uses itself", component.node),
                                span.clone(),
                            )
                            .label(format!("{path} → {}", component.node))
                            .hint("components are instanced at compile time; recursion has no end"),
                        );
                        continue;
                    }
                    if depth + 1 > MAX_COMPONENT_DEPTH {
                        self.err(
                            Diagnostic::error(
                                "E0135",
                                format!("components nested more than {MAX_COMPONENT_DEPTH} deep"),
                                span.clone(),
                            )
                            .hint("flatten the chain of components: each level is an instance of its own"),
                        );
                        continue;
                    }
                    self.instanced = self.instanced.saturating_add(body_weight(comp));
                    if self.instanced > MAX_INSTANCED_NODES {
                        if self.diags.iter().any(|d| d.code == "E0136") {
                            continue;
                        }
                        self.err(
                            Diagnostic::error(
                                "E0136",
                                format!("the component instances hold more than {MAX_INSTANCED_NODES} declarations and expression nodes"),
                                span.clone(),
                            )
                            .hint("every instance is code of its own; a large component used many times multiplies"),
                        );
                        continue;
                    }
                    if self.scopes.len() >= MAX_INSTANCES {
                        if self.diags.iter().any(|d| d.code == "E0136") {
                            continue;
                        }
                        self.err(
                            Diagnostic::error(
                                "E0136",
                                format!("more than {MAX_INSTANCES} component instances"),
                                span.clone(),
                            )
                            .hint("every instance is code of its own; components that use others several times multiply"),
                        );
                        continue;
                    }
                    let child_prefix = format!("{prefix}{}.", name.node);
                    let child = self.declare_scope(
                        comp,
                        child_prefix,
                        Some(id),
                        uargs,
                        span.clone(),
                        depth + 1,
                    );
                    self.add_sym(id, name, Sym::Instance(child));
                }
            }
        }
        // Arguments that name nothing, and inputs left unbound.
        for (i, (n, _)) in args.iter().enumerate() {
            if arg_used[i] {
                if let Some((_, def)) = self.scopes[id.0].syms.get(&n.node) {
                    let def = def.clone();
                    self.record_ref(&n.span, &def);
                }
            } else {
                let kinds: Vec<String> = self.scopes[id.0]
                    .syms
                    .iter()
                    .filter(|(_, (s, _))| matches!(s, Sym::Param(_) | Sym::Input(_)))
                    .map(|(k, _)| k.clone())
                    .collect();
                self.err(
                    Diagnostic::error(
                        "E0117",
                        format!(
                            "component `{}` has no param or input `{}`",
                            body.name.node, n.node
                        ),
                        n.span.clone(),
                    )
                    .hint(format!("it takes: {}", sorted(kinds).join(", "))),
                );
            }
        }
        if is_component {
            let unconnected: Vec<Diagnostic> = self.scopes[id.0]
                .inputs
                .iter()
                .filter(|inp| inp.arg.is_none())
                .map(|inp| {
                    Diagnostic::error(
                        "E0118",
                        format!(
                            "input `{}` of component `{}` is not connected",
                            inp.name.node, body.name.node
                        ),
                        use_span.clone(),
                    )
                    .with_secondary(inp.name.span.clone(), "input declared here")
                    .hint(format!("pass it in the `use`: `{} = …`", inp.name.node))
                })
                .collect();
            for d in unconnected {
                self.err(d);
            }
        }
        id
    }

    /// Resolves a single name in a scope; reports unknown names with a suggestion.
    pub(super) fn lookup(&mut self, scope: ScopeId, name: &ast::Name) -> Option<Sym> {
        if let Some((s, def)) = self.scopes[scope.0].syms.get(&name.node) {
            let (s, def) = (*s, def.clone());
            self.record_ref(&name.span, &def);
            return Some(s);
        }
        // A name inside a loop is looked up once per index: report (and search for a
        // suggestion among thousands of names) once per place, not once per index.
        if !self.unknown_reported.insert(name.span.clone()) {
            return None;
        }
        let names: Vec<String> = self.scopes[scope.0].syms.keys().cloned().collect();
        let mut d = Diagnostic::error(
            "E0201",
            format!("unknown name `{}`", name.node),
            name.span.clone(),
        )
        .label("not defined here");
        if let Some(c) = crate::diagnostics::closest(&name.node, names.iter().map(|s| s.as_str())) {
            d = d.hint(format!("did you mean `{c}`?"));
        } else if units::lookup(&name.node).is_some() {
            d = d.hint(format!(
                "`{}` is a unit: write it right after a number, e.g. `1 {}`",
                name.node, name.node
            ));
        } else if self.scopes[scope.0].parent.is_some() {
            d = d.hint("a component sees only its own names; pass outside values in as inputs");
        }
        self.err(d);
        None
    }

    /// Applies `--param` overrides: each replaces the param's expression with the override's.
    pub(super) fn apply_overrides(&mut self) {
        for (name, text) in &self.config.overrides {
            let Some(pid) = self.prog.params.iter().position(|p| p.name == *name) else {
                let known: Vec<&str> = self.prog.params.iter().map(|p| p.name.as_str()).collect();
                let hint = match crate::diagnostics::closest(name, known.iter().copied()) {
                    Some(c) => format!("did you mean `{c}`?"),
                    None => format!("the params are: {}", known.join(", ")),
                };
                self.err(
                    Diagnostic::error(
                        "E0301",
                        format!("`--param {name}=…`: this instrument has no param `{name}`"),
                        0..0,
                    )
                    .hint(hint),
                );
                continue;
            };
            let lit = crate::parse::parse_expr(text)
                .ok()
                .and_then(|e| match e.node {
                    ast::ExprKind::Number(l) => Some((l.value, l.dim)),
                    ast::ExprKind::Neg(inner) => match inner.node {
                        ast::ExprKind::Number(l) => Some((-l.value, l.dim)),
                        _ => None,
                    },
                    _ => None,
                });
            match lit {
                Some(v) => {
                    self.overrides.insert(pid, (v.0, v.1, text.clone()));
                }
                None => {
                    let span = self.prog.params[pid].span.clone();
                    self.err(
                        Diagnostic::error(
                            "E0302",
                            format!("`--param {name}={text}`: not a number with a unit"),
                            span,
                        )
                        .label("this param")
                        .hint("write a number with its unit, e.g. `--param k=200 N/m`"),
                    );
                }
            }
        }
    }
}

fn sorted(mut v: Vec<String>) -> Vec<String> {
    v.sort();
    v
}

/// The deepest a chain of component instances may be (a component using a component …):
/// far beyond any instrument, and a bound on the recursion of [`Lowerer::declare_scope`].
pub const MAX_COMPONENT_DEPTH: usize = 64;

/// The most scopes (the instrument and its component instances, at every depth) one
/// instrument may have. A component that uses another twice doubles the count per level,
/// so depth alone does not bound it.
pub const MAX_INSTANCES: usize = 4096;

/// The most AST nodes (declarations and expression nodes, after expansion) all component
/// instances of one instrument may hold together: [`MAX_INSTANCES`] bounds the count, this
/// their size (4096 instances of a 28,000-node body would be 115 M nodes of IR).
pub const MAX_INSTANCED_NODES: usize = 1 << 20;

/// The size of `body` in declarations and expression nodes (an explicit stack: a chain of
/// 4096 additions is 4096 deep).
fn body_weight(body: &ast::Body) -> usize {
    use ast::ExprKind as K;
    let mut stack: Vec<&ast::Expr> = Vec::new();
    let mut n = body.decls.len();
    for d in &body.decls {
        match d {
            ast::Decl::Param { value, .. }
            | ast::Decl::Let { value, .. }
            | ast::Decl::Force { value, .. }
            | ast::Decl::Output { value, .. } => stack.push(value),
            ast::Decl::State { init, .. } => stack.push(init),
            ast::Decl::Dynamics { eqs, .. } => stack.extend(eqs.iter().map(|e| &e.rhs)),
            ast::Decl::Handler { cond, body, .. } => {
                stack.push(cond);
                for s in body {
                    match s {
                        ast::Stmt::Assign { value, .. } => stack.push(value),
                        ast::Stmt::Emit { args, .. } => stack.extend(args.iter().map(|(_, e)| e)),
                    }
                }
            }
            ast::Decl::Use { args, .. } => stack.extend(args.iter().map(|(_, e)| e)),
            _ => {}
        }
    }
    while let Some(e) = stack.pop() {
        n += 1;
        match &e.node {
            K::Neg(a) | K::Not(a) | K::Pow(a, _) => stack.push(a),
            K::Binary(_, a, b) => stack.extend([&**a, &**b]),
            K::Call(_, args) => stack.extend(args.iter()),
            K::If(c, a, b) => stack.extend([&**c, &**a, &**b]),
            _ => {}
        }
    }
    n
}
