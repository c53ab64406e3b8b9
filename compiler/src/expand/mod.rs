//! Expansion: arrays, `for` loops, `sum`s and `solve`s become plain declarations.
//!
//! This pass runs on the AST before [`crate::lower`], so every later stage (the dimension
//! check, the fixed-point analysis, every engine and the WCET analysis) sees only scalars
//! and straight-line code, and a loop's trip count is part of the code's size — which is
//! what lets the budget checker bound it.
//!
//! * `for i in LO..HI { DECLS }` repeats `DECLS` once per index; `i` stands for the index
//!   as a dimensionless whole number.
//! * `NAME[INDEX]` — in a declaration, an equation, an assignment or an expression — is the
//!   element named `NAME[k]` with `k` the index's value. Indices are whole numbers known at
//!   compile time: integer literals, loop variables, and params of the same instrument or
//!   component whose values are whole numbers (with `--param` overrides), combined with
//!   `+ - * /` (a division must be exact). An element that was never declared is an error
//!   naming the array's extent.
//! * `sum(i in LO..HI, EXPR)` is `EXPR` added up over the indices (at least one).
//! * `solve X in [LO, HI] { start = … residual = … iterations = N [min_slope = …] }` is
//!   Newton–Raphson with a fixed number of iterations, each iterate clamped into the range
//!   (a safeguarded, projected Newton step): `X₀ = clamp(start)`, `Xₖ₊₁ = clamp(Xₖ −
//!   R(Xₖ)/R′(Xₖ))`, `X = X_N`. The derivative `R′` is taken symbolically from the
//!   residual's own expression ([`derivative`]); `min_slope` replaces it by
//!   `max(R′, min_slope)` for residuals known to be increasing (the uniqueness condition of
//!   the friction solve of Bilbao, *Numerical Sound Synthesis*, 2009, §7.3, gives such a
//!   bound). The iterates are `let`s named `X#0 … X#N`.
//! * A vector sensor `sensor pen: m in { z: [..], x: [..] }` becomes the scalar sensors
//!   `pen.z`, `pen.x` in the written order, and a vector force `force f = { x: A, z: B }`
//!   the scalar force terms `f.x`, `f.z`, each tagged with its [`crate::ir::Axis`] (a
//!   missing component is no term, i.e. 0 N). A read `pen.x` (or `d(pen.x)`, `f.z`) becomes
//!   the one name `pen.x`; reading `pen` bare is an error (E0133), as are an unknown
//!   component (E0130), a repeated one (E0131) and empty braces (E0132).
//!
//! Errors are diagnostics with the span of the offending index, range or field.

use crate::ast::*;
use crate::diagnostics::Diagnostic;
use crate::ir::Axis;
use crate::lexer::Literal;
use crate::units::Dim;
use std::collections::{HashMap, HashSet};

mod solve;

pub use solve::derivative;
use solve::desugar_solves;
pub(crate) use solve::mentions;

/// The most elements a loop, a sum or an array may have: a bound on compile time and code
/// size (every element is code of its own), far above what fits a Cortex-M0+ at 44.1 kHz.
pub const MAX_TRIP_COUNT: i64 = 4096;

/// The most AST nodes (declarations and expression nodes) the expansion of one file may
/// produce, over all its loops, sums, solves and component specialisations together: the
/// per-loop [`MAX_TRIP_COUNT`] alone lets nested loops multiply (4096 × 4096). The largest
/// shipped instrument, the bowed strings, produces 28,792.
pub const MAX_EXPANDED_NODES: usize = 1 << 18;

/// The most component specialisations (distinct whole-number argument sets) one file may
/// request; a component that uses itself with a growing argument would request them
/// without end.
pub const MAX_SPECIALISATIONS: usize = 1024;

/// The largest magnitude an index or loop bound may reach while it is computed (literals
/// are at most 10⁹ already; this keeps `+ - * /` of them away from i64 overflow).
const MAX_INDEX: i64 = 1 << 40;

/// The most steps one [`Expander::int`] may take: params defined by params
/// (`p2 = p1 + p1`, …) would otherwise make it exponential.
const MAX_INT_STEPS: usize = 1 << 20;

/// The most Newton–Raphson iterations a `solve` may ask for.
pub const MAX_ITERATIONS: i64 = 16;

/// Expands every instrument and component of `file`; `overrides` are the `--param`
/// overrides (name, value as source text), which index expressions honour.
///
/// Errors: every bad index, range, `sum` or `solve` found, as diagnostics.
pub fn expand(file: &File, overrides: &[(String, String)]) -> Result<File, Vec<Diagnostic>> {
    let mut diags = Vec::new();
    let mut components = HashMap::new();
    for item in &file.items {
        if let TopItem::Component(b) = item {
            components.entry(b.name.node.clone()).or_insert(b);
        }
    }
    let mut cx = Context {
        components: &components,
        diags: &mut diags,
        requests: Vec::new(),
        work: Budget::default(),
    };
    let mut items: Vec<TopItem> = file
        .items
        .iter()
        .map(|item| match item {
            TopItem::Instrument(b) => TopItem::Instrument(cx.body(b, None, overrides)),
            TopItem::Component(b) => TopItem::Component(cx.body(b, None, &[])),
            TopItem::Import(i) => TopItem::Import(i.clone()),
        })
        .collect();
    // Specialisations requested by `use`s (and by the specialisations' own `use`s).
    let mut done = HashSet::new();
    while let Some((spec, comp, args)) = cx.requests.pop() {
        if !done.insert(spec.clone()) {
            continue;
        }
        if done.len() > MAX_SPECIALISATIONS {
            let span = components.get(&comp).map_or(0..0, |b| b.name.span.clone());
            cx.diags.push(
                Diagnostic::error(
                    "E0138",
                    format!("more than {MAX_SPECIALISATIONS} specialisations of components"),
                    span,
                )
                .label(format!("`{spec}` is one too many"))
                .hint("a component used with ever new whole-number arguments (`use a = C(n = n + 1)`) never ends"),
            );
            break;
        }
        let Some(body) = components.get(&comp).copied() else {
            continue;
        };
        let overrides: Vec<(String, String)> = args
            .iter()
            .map(|(n, k)| (n.clone(), k.to_string()))
            .collect();
        items.push(TopItem::Component(cx.body(body, Some(spec), &overrides)));
    }
    if diags.is_empty() {
        Ok(File { items })
    } else {
        Err(diags)
    }
}

/// A component specialisation to expand: (its name, the component, whole-number params).
type Request = (String, String, Vec<(String, i64)>);

/// What the expansion of every body shares.
struct Context<'f, 'd> {
    /// The file's components by name (the first of duplicates; lowering reports those).
    components: &'f HashMap<String, &'f Body>,
    diags: &'d mut Vec<Diagnostic>,
    /// Component specialisations to expand: (name, component, whole-number params).
    requests: Vec<Request>,
    /// The nodes produced so far, against [`MAX_EXPANDED_NODES`].
    work: Budget,
}

/// Counts the AST nodes the expansion produces; once over [`MAX_EXPANDED_NODES`] it
/// reports E0137 once (at the span being expanded) and expansion stops producing code.
#[derive(Default)]
struct Budget {
    nodes: usize,
    over: bool,
}

impl Context<'_, '_> {
    /// Expands one body; `rename` names a specialisation, `overrides` set params by text.
    fn body(
        &mut self,
        body: &Body,
        rename: Option<String>,
        overrides: &[(String, String)],
    ) -> Body {
        let mut params = HashMap::new();
        for d in &body.decls {
            if let Decl::Param { name, value, .. } = d {
                params.insert(name.node.clone(), value.clone());
            }
        }
        for (name, text) in overrides {
            if params.contains_key(name) {
                if let Ok(e) = crate::parse::parse_expr(text) {
                    params.insert(name.clone(), e);
                }
            }
        }
        let mut vectors = HashMap::new();
        collect_vectors(&body.decls, &mut vectors);
        let mut x = Expander {
            vectors,
            params,
            env: Vec::new(),
            diags: &mut *self.diags,
            declared: HashSet::new(),
            refs: Vec::new(),
            depth: 0,
            components: self.components,
            requests: &mut self.requests,
            instance_overrides: if rename.is_none() { overrides } else { &[] },
            work: &mut self.work,
            int_steps: 0,
        };
        let decls = x.decls(&body.decls);
        x.check_refs();
        x.check_vector_names(&decls);
        let decls = desugar_solves(decls, self.diags);
        let mut name = body.name.clone();
        if let Some(r) = rename {
            name.node = r;
        }
        Body {
            name,
            decls,
            span: body.span.clone(),
        }
    }
}

/// The name a (scalar, expanded) declaration declares, if any.
fn declared_name(d: &Decl) -> Option<&Name> {
    match d {
        Decl::Sensor { name, .. }
        | Decl::Input { name, .. }
        | Decl::Param { name, .. }
        | Decl::State { name, .. }
        | Decl::Mode { name, .. }
        | Decl::Let { name, .. }
        | Decl::Force { name, .. }
        | Decl::Output { name, .. }
        | Decl::Use { name, .. }
        | Decl::Solve { name, .. } => Some(name),
        _ => None,
    }
}

/// A vector sensor or force of a body, by its name (without an element index).
struct Vector {
    /// `"sensor"` or `"force"`, for messages.
    kind: &'static str,
    /// Its name as written.
    name: Name,
    /// The components written (the union over the elements of an array of vector forces).
    components: Vec<String>,
}

/// Every vector sensor and force declared in `decls` (also inside loops), by name.
fn collect_vectors(decls: &[Decl], out: &mut HashMap<String, Vector>) {
    for d in decls {
        let (kind, name, comps): (_, _, Vec<&Name>) = match d {
            Decl::VectorSensor {
                name, components, ..
            } => ("sensor", name, components.iter().map(|(n, _)| n).collect()),
            Decl::VectorForce {
                name, components, ..
            } => ("force", name, components.iter().map(|(n, _)| n).collect()),
            Decl::For { decls, .. } => {
                collect_vectors(decls, out);
                continue;
            }
            _ => continue,
        };
        let v = out.entry(name.node.clone()).or_insert_with(|| Vector {
            kind,
            name: name.clone(),
            components: Vec::new(),
        });
        for c in comps {
            if !v.components.contains(&c.node) {
                v.components.push(c.node.clone());
            }
        }
    }
}

struct Expander<'d, 'f> {
    /// The body's vector sensors and forces by name (their reads are rewritten).
    vectors: HashMap<String, Vector>,
    /// The file's components, to specialise on whole-number arguments.
    components: &'f HashMap<String, &'f Body>,
    /// Where specialisations are requested.
    requests: &'d mut Vec<Request>,
    /// `--param INSTANCE.PARAM=…` overrides, which size the arrays of the instances of
    /// this body's `use`s (the instrument's only).
    instance_overrides: &'f [(String, String)],
    /// Params of the body by name (their expressions, overrides applied).
    params: HashMap<String, Expr>,
    /// Loop variables in scope, innermost last.
    env: Vec<(String, i64)>,
    diags: &'d mut Vec<Diagnostic>,
    /// Every name the expanded body declares.
    declared: HashSet<String>,
    /// Element references: (array name, element name, index value, span).
    refs: Vec<(String, String, Span)>,
    /// Param-evaluation depth (cycle guard).
    depth: usize,
    /// The file's expansion budget.
    work: &'d mut Budget,
    /// Steps taken by the current [`Expander::int`] (params defined by params can make
    /// one evaluation exponential).
    int_steps: usize,
}

impl Expander<'_, '_> {
    /// Charges `n` produced nodes to the budget; false (after reporting E0137 once) when
    /// the budget is spent.
    fn charge(&mut self, n: usize, span: &Span) -> bool {
        if self.work.over {
            return false;
        }
        self.work.nodes = self.work.nodes.saturating_add(n);
        if self.work.nodes > MAX_EXPANDED_NODES {
            self.work.over = true;
            self.diags.push(
                Diagnostic::error(
                    "E0137",
                    format!("the expansion produces more than {MAX_EXPANDED_NODES} nodes"),
                    span.clone(),
                )
                .label("the loops, sums or solves that go over the budget")
                .hint("nested loops and sums multiply: every index is code of its own; use fewer or shorter loops"),
            );
            return false;
        }
        true
    }

    fn decls(&mut self, decls: &[Decl]) -> Vec<Decl> {
        let mut out = Vec::new();
        for d in decls {
            self.decl(d, &mut out);
        }
        out
    }

    fn decl(&mut self, d: &Decl, out: &mut Vec<Decl>) {
        let decl = match d {
            Decl::For {
                var, range, decls, ..
            } => {
                let Some((lo, hi)) = self.range(range) else {
                    return;
                };
                for i in lo..hi {
                    // At least one per index: empty loops nested 4096 deep cost time too.
                    if !self.charge(decls.len().max(1), &range.span) {
                        return;
                    }
                    self.env.push((var.node.clone(), i));
                    for d in decls {
                        self.decl(d, out);
                    }
                    self.env.pop();
                }
                return;
            }
            Decl::Sensor { name, ty, range } => {
                self.declared.insert(name.node.clone());
                Decl::Sensor {
                    name: name.clone(),
                    ty: ty.clone(),
                    range: range.as_ref().map(|r| self.bounds(r)),
                }
            }
            Decl::VectorSensor {
                name,
                ty,
                components,
                span,
            } => {
                let names: Vec<&Name> = components.iter().map(|(n, _)| n).collect();
                let Some(axes) = self.axes("sensor", name, &names, span) else {
                    return;
                };
                for ((c, range), _) in components.iter().zip(axes) {
                    let full = format!("{}.{}", name.node, c.node);
                    self.declared.insert(full.clone());
                    out.push(Decl::Sensor {
                        name: Spanned {
                            node: full,
                            span: c.span.clone(),
                        },
                        ty: ty.clone(),
                        range: Some(self.bounds(range)),
                    });
                }
                return;
            }
            Decl::VectorForce {
                name,
                index,
                components,
                span,
            } => {
                // The vector itself is no value: only its components (and, for the element
                // check of `f[k].x`, the element `f[k]`) are declared.
                let base = match index {
                    None => name.clone(),
                    Some(i) => self.declare(name, Some(i)),
                };
                let names: Vec<&Name> = components.iter().map(|(n, _)| n).collect();
                let Some(axes) = self.axes("force", name, &names, span) else {
                    return;
                };
                for ((c, value), axis) in components.iter().zip(axes) {
                    let full = format!("{}.{}", base.node, c.node);
                    self.declared.insert(full.clone());
                    out.push(Decl::Force {
                        name: Spanned {
                            node: full,
                            span: c.span.clone(),
                        },
                        index: None,
                        value: self.expr(value),
                        axis: Some(axis),
                    });
                }
                return;
            }
            Decl::Input { name, ty } => {
                self.declared.insert(name.node.clone());
                Decl::Input {
                    name: name.clone(),
                    ty: ty.clone(),
                }
            }
            Decl::Param { name, ty, value } => {
                self.declared.insert(name.node.clone());
                Decl::Param {
                    name: name.clone(),
                    ty: ty.clone(),
                    value: self.expr(value),
                }
            }
            Decl::State {
                name,
                index,
                ty,
                init,
                range,
            } => Decl::State {
                name: self.declare(name, index.as_ref()),
                index: None,
                ty: ty.clone(),
                init: self.expr(init),
                range: range.as_ref().map(|r| self.bounds(r)),
            },
            Decl::Mode {
                name,
                variants,
                init,
            } => {
                self.declared.insert(name.node.clone());
                Decl::Mode {
                    name: name.clone(),
                    variants: variants.clone(),
                    init: init.clone(),
                }
            }
            Decl::Let { name, index, value } => Decl::Let {
                name: self.declare(name, index.as_ref()),
                index: None,
                value: self.expr(value),
            },
            Decl::Force {
                name,
                index,
                value,
                axis,
            } => Decl::Force {
                name: self.declare(name, index.as_ref()),
                index: None,
                value: self.expr(value),
                axis: *axis,
            },
            Decl::Output { name, index, value } => Decl::Output {
                name: self.declare(name, index.as_ref()),
                index: None,
                value: self.expr(value),
            },
            Decl::Dynamics { eqs, span } => Decl::Dynamics {
                eqs: eqs
                    .iter()
                    .map(|eq| Equation {
                        state: self.element(&eq.state, eq.index.as_ref()),
                        index: None,
                        rhs: self.expr(&eq.rhs),
                    })
                    .collect(),
                span: span.clone(),
            },
            Decl::Handler {
                trigger,
                cond,
                body,
                span,
            } => Decl::Handler {
                trigger: *trigger,
                cond: self.expr(cond),
                body: body.iter().map(|s| self.stmt(s)).collect(),
                span: span.clone(),
            },
            Decl::Use {
                name,
                index,
                component,
                args,
                span,
            } => {
                let args: Vec<(Name, Expr)> = args
                    .iter()
                    .map(|(n, e)| (n.clone(), self.expr(e)))
                    .collect();
                let name = self.declare(name, index.as_ref());
                Decl::Use {
                    component: self.specialise(&name.node, component, &args),
                    name,
                    index: None,
                    args,
                    span: span.clone(),
                }
            }
            Decl::Solve {
                name,
                index,
                range,
                fields,
                span,
            } => Decl::Solve {
                name: self.declare(name, index.as_ref()),
                index: None,
                range: range.as_ref().map(|r| self.bounds(r)),
                fields: fields
                    .iter()
                    .map(|(n, e)| (n.clone(), self.expr(e)))
                    .collect(),
                span: span.clone(),
            },
            Decl::Require { cond, span } => Decl::Require {
                cond: self.expr(cond),
                span: span.clone(),
            },
            Decl::SolveRange { name, range } => Decl::SolveRange {
                name: name.clone(),
                range: self.bounds(range),
            },
            Decl::Tolerance {
                kind,
                name,
                value,
                fields,
                span,
            } => Decl::Tolerance {
                kind: kind.clone(),
                name: name.clone(),
                value: value.as_ref().map(|v| self.expr(v)),
                fields: fields
                    .iter()
                    .map(|(n, e)| (n.clone(), self.expr(e)))
                    .collect(),
                span: span.clone(),
            },
        };
        out.push(decl);
    }

    /// A component used with whole-number arguments for its params is expanded once per
    /// distinct set of them (its arrays may be sized by them): `string<N=52>`. Returns the
    /// name of the component to instance.
    fn specialise(&mut self, instance: &str, component: &Name, args: &[(Name, Expr)]) -> Name {
        let Some(body) = self.components.get(&component.node) else {
            return component.clone();
        };
        let params: HashSet<&str> = body
            .decls
            .iter()
            .filter_map(|d| match d {
                Decl::Param { name, .. } => Some(name.node.as_str()),
                _ => None,
            })
            .collect();
        let mut whole = Vec::new();
        for p in &params {
            let qualified = format!("{instance}.{p}");
            let given = match self
                .instance_overrides
                .iter()
                .find(|(n, _)| *n == qualified)
            {
                Some((_, text)) => crate::parse::parse_expr(text).ok(),
                None => args
                    .iter()
                    .find(|(n, _)| n.node == *p)
                    .map(|(_, e)| e.clone()),
            };
            let Some(e) = given else {
                continue;
            };
            let saved = self.diags.len();
            let k = self.int(&e);
            self.diags.truncate(saved);
            if let Some(k) = k {
                whole.push((p.to_string(), k));
            }
        }
        whole.sort();
        if whole.is_empty() {
            return component.clone();
        }
        let list: Vec<String> = whole.iter().map(|(n, k)| format!("{n}={k}")).collect();
        let spec = format!("{}<{}>", component.node, list.join(", "));
        self.requests
            .push((spec.clone(), component.node.clone(), whole));
        Spanned {
            node: spec,
            span: component.span.clone(),
        }
    }

    fn stmt(&mut self, s: &Stmt) -> Stmt {
        match s {
            Stmt::Assign {
                target,
                index,
                value,
            } => Stmt::Assign {
                target: self.element(target, index.as_ref()),
                index: None,
                value: self.expr(value),
            },
            Stmt::Emit { event, args, span } => Stmt::Emit {
                event: event.clone(),
                args: args
                    .iter()
                    .map(|(n, e)| (n.clone(), self.expr(e)))
                    .collect(),
                span: span.clone(),
            },
        }
    }

    fn bounds(&mut self, r: &Range) -> Range {
        Range {
            lo: self.expr(&r.lo),
            hi: self.expr(&r.hi),
            span: r.span.clone(),
        }
    }

    /// The name a declaration declares: `NAME` or the element `NAME[k]`.
    fn declare(&mut self, name: &Name, index: Option<&Expr>) -> Name {
        let n = match index {
            None => name.clone(),
            Some(i) => match self.int(i) {
                Some(k) => element_name(name, k, i),
                None => name.clone(),
            },
        };
        self.declared.insert(n.node.clone());
        n
    }

    /// The name an equation, assignment or path segment refers to.
    fn element(&mut self, name: &Name, index: Option<&Expr>) -> Name {
        match index {
            None => name.clone(),
            Some(i) => match self.int(i) {
                Some(k) => {
                    let n = element_name(name, k, i);
                    self.refs
                        .push((name.node.clone(), n.node.clone(), n.span.clone()));
                    n
                }
                None => name.clone(),
            },
        }
    }

    fn range(&mut self, r: &IndexRange) -> Option<(i64, i64)> {
        let lo = self.int(&r.lo)?;
        let hi = self.int(&r.hi)?;
        if hi.saturating_sub(lo) > MAX_TRIP_COUNT {
            self.diags.push(
                Diagnostic::error(
                    "E0121",
                    format!(
                        "{lo}..{hi} has {} indices, more than the {MAX_TRIP_COUNT} a loop may have",
                        hi.saturating_sub(lo)
                    ),
                    r.span.clone(),
                )
                .hint("every index becomes code of its own; a Cortex-M0+ runs a few thousand cycles per sample"),
            );
            return None;
        }
        Some((lo, hi))
    }

    fn expr(&mut self, e: &Expr) -> Expr {
        if !self.charge(1, &e.span) {
            return number(0.0, e.span.clone());
        }
        let node = match &e.node {
            ExprKind::Number(_) | ExprKind::Bool(_) => return e.clone(),
            ExprKind::Path(p) => {
                if p.len() == 1 {
                    if let Some(k) = self.loop_var(&p[0].node) {
                        return number(k as f64, e.span.clone());
                    }
                }
                self.vector_path(p.clone())
            }
            ExprKind::Element(segs) => {
                let names = segs
                    .iter()
                    .map(|(n, i)| self.element(n, i.as_ref()))
                    .collect();
                self.vector_path(names)
            }
            ExprKind::Sum { var, range, body } => {
                let Some((lo, hi)) = self.range(range) else {
                    return number(0.0, e.span.clone());
                };
                if hi <= lo {
                    self.diags.push(
                        Diagnostic::error(
                            "E0123",
                            format!("the sum over {lo}..{hi} has no terms"),
                            range.span.clone(),
                        )
                        .hint("a sum needs at least one term (its zero would have no unit)"),
                    );
                    return number(0.0, e.span.clone());
                }
                let mut acc: Option<Expr> = None;
                for i in lo..hi {
                    self.env.push((var.node.clone(), i));
                    let t = self.expr(body);
                    self.env.pop();
                    acc = Some(match acc {
                        None => t,
                        Some(a) => binary(BinOp::Add, a, t, e.span.clone()),
                    });
                }
                return acc.unwrap_or_else(|| number(0.0, e.span.clone()));
            }
            ExprKind::Neg(a) => ExprKind::Neg(Box::new(self.expr(a))),
            ExprKind::Not(a) => ExprKind::Not(Box::new(self.expr(a))),
            ExprKind::Binary(op, a, b) => {
                ExprKind::Binary(*op, Box::new(self.expr(a)), Box::new(self.expr(b)))
            }
            ExprKind::Pow(a, n) => ExprKind::Pow(Box::new(self.expr(a)), n.clone()),
            ExprKind::Call(f, args) => {
                ExprKind::Call(f.clone(), args.iter().map(|a| self.expr(a)).collect())
            }
            ExprKind::If(c, a, b) => ExprKind::If(
                Box::new(self.expr(c)),
                Box::new(self.expr(a)),
                Box::new(self.expr(b)),
            ),
        };
        Spanned {
            node,
            span: e.span.clone(),
        }
    }

    /// A path, with a vector's component read (`pen.x`, `f[2].z`) merged into the one name
    /// of its scalar (`pen.x`, `f[2].z`). Reports a vector read bare or an unknown component.
    fn vector_path(&mut self, mut names: Vec<Name>) -> ExprKind {
        let first = &names[0].node;
        let base = first.split('[').next().unwrap_or(first);
        let Some(v) = self.vectors.get(base) else {
            return ExprKind::Path(names);
        };
        let Some(c) = names.get(1) else {
            let example = v.components.first().map_or("x", String::as_str);
            self.diags.push(
                Diagnostic::error(
                    "E0133",
                    format!("`{first}` is a vector {}: it has no single value", v.kind),
                    names[0].span.clone(),
                )
                .label("read one of its components")
                .hint(format!(
                    "a vector {} is read by component: `{first}.{example}` (it has {})",
                    v.kind,
                    v.components.join(", ")
                )),
            );
            return ExprKind::Path(names);
        };
        if !v.components.contains(&c.node) {
            let d = Diagnostic::error(
                "E0130",
                format!("vector {} `{base}` has no component `{}`", v.kind, c.node),
                c.span.clone(),
            )
            .label("not one of its components")
            .with_secondary(
                v.name.span.clone(),
                format!("declared with {}", v.components.join(", ")),
            )
            .hint(format!(
                "read one of {}: `{first}.{}`",
                v.components.join(", "),
                v.components[0]
            ));
            self.diags.push(d);
            return ExprKind::Path(names);
        }
        let merged = Spanned {
            node: format!("{first}.{}", c.node),
            span: names[0].span.start..c.span.end,
        };
        names.splice(0..2, [merged]);
        ExprKind::Path(names)
    }

    /// The axes of a vector's components as written, or `None` after reporting an empty
    /// list, a name other than `x`, `y`, `z`, or a repeated one.
    fn axes(
        &mut self,
        kind: &str,
        name: &Name,
        components: &[&Name],
        braces: &Span,
    ) -> Option<Vec<Axis>> {
        if components.is_empty() {
            let example = if kind == "sensor" {
                format!(
                    "sensor {}: m in {{ z: [0 mm, 10 mm], x: [0 mm, 160 mm] }}",
                    name.node
                )
            } else {
                format!("force {} = {{ z: k * pen.z }}", name.node)
            };
            self.diags.push(
                Diagnostic::error(
                    "E0132",
                    format!("vector {kind} `{}` has no components", name.node),
                    braces.clone(),
                )
                .label("empty")
                .hint(format!("name at least one of x, y, z: `{example}`")),
            );
            return None;
        }
        let mut axes: Vec<Axis> = Vec::new();
        let mut ok = true;
        for (i, c) in components.iter().enumerate() {
            let Some(a) = Axis::from_name(&c.node) else {
                self.diags.push(
                    Diagnostic::error(
                        "E0130",
                        format!("`{}` is not a component of a vector {kind}", c.node),
                        c.span.clone(),
                    )
                    .label("expected x, y or z")
                    .hint("the components are x (the stroke axis), y (across it) and z (the depth into the surface)"),
                );
                ok = false;
                continue;
            };
            if let Some(first) = components[..i].iter().find(|p| p.node == c.node) {
                self.diags.push(
                    Diagnostic::error(
                        "E0131",
                        format!("component `{}` of `{}` is given twice", c.node, name.node),
                        c.span.clone(),
                    )
                    .label("second time")
                    .with_secondary(first.span.clone(), "first given here")
                    .hint("give each of x, y, z at most once"),
                );
                ok = false;
                continue;
            }
            axes.push(a);
        }
        ok.then_some(axes)
    }

    /// A vector's name must not also name another declaration of the expanded `decls`.
    fn check_vector_names(&mut self, decls: &[Decl]) {
        let mut clashes: Vec<(Name, &'static str)> = self
            .vectors
            .values()
            .filter(|v| self.declared.contains(&v.name.node))
            .map(|v| (v.name.clone(), v.kind))
            .collect();
        clashes.sort_by_key(|(n, _)| n.span.start);
        for (name, kind) in clashes {
            let mut d = Diagnostic::error(
                "E0105",
                format!("`{}` is defined twice", name.node),
                name.span.clone(),
            )
            .label(format!("a vector {kind}"))
            .hint("every name in an instrument or component is unique; rename one of them");
            if let Some(other) = decls
                .iter()
                .filter_map(declared_name)
                .find(|n| n.node == name.node)
            {
                d = d.with_secondary(other.span.clone(), "also defined here");
            }
            self.diags.push(d);
        }
    }

    fn loop_var(&self, name: &str) -> Option<i64> {
        self.env
            .iter()
            .rev()
            .find(|(n, _)| n == name)
            .map(|&(_, k)| k)
    }

    /// A whole number known at compile time, or `None` after reporting why not.
    fn int(&mut self, e: &Expr) -> Option<i64> {
        self.int_steps = 0;
        self.int_inner(e)
    }

    fn int_inner(&mut self, e: &Expr) -> Option<i64> {
        let bad = |what: String| {
            Diagnostic::error("E0120", what, e.span.clone()).hint(
                "indices and loop bounds are whole numbers known at compile time: integer literals, loop variables and whole-number params, with + - * / (`u[i + 1]`, `0..N`)",
            )
        };
        self.int_steps += 1;
        if self.int_steps > MAX_INT_STEPS {
            if self.int_steps == MAX_INT_STEPS + 1 {
                self.diags.push(bad(format!(
                    "evaluating this index takes more than {MAX_INT_STEPS} steps"
                )));
            }
            return None;
        }
        let v = match &e.node {
            ExprKind::Number(l) => {
                if l.dim != Dim::NONE || l.value.fract() != 0.0 || l.value.abs() > 1e9 {
                    self.diags
                        .push(bad("an index must be a dimensionless whole number".into()));
                    return None;
                }
                l.value as i64
            }
            ExprKind::Path(p) if p.len() == 1 => {
                if let Some(k) = self.loop_var(&p[0].node) {
                    return Some(k);
                }
                let Some(value) = self.params.get(&p[0].node).cloned() else {
                    self.diags.push(bad(format!(
                        "`{}` is neither a loop variable nor a param of this definition",
                        p[0].node
                    )));
                    return None;
                };
                if self.depth > 32 {
                    self.diags.push(bad(format!(
                        "param `{}` is defined in terms of itself",
                        p[0].node
                    )));
                    return None;
                }
                self.depth += 1;
                let k = self.int_inner(&value);
                self.depth -= 1;
                return k;
            }
            ExprKind::Neg(a) => -self.int_inner(a)?,
            ExprKind::Binary(op @ (BinOp::Add | BinOp::Sub | BinOp::Mul | BinOp::Div), a, b) => {
                let (a, b) = (self.int_inner(a)?, self.int_inner(b)?);
                let v = match op {
                    BinOp::Add => a.checked_add(b),
                    BinOp::Sub => a.checked_sub(b),
                    BinOp::Mul => a.checked_mul(b),
                    _ => {
                        if b == 0 || a % b != 0 {
                            self.diags
                                .push(bad(format!("{a} / {b} is not a whole number")));
                            return None;
                        }
                        a.checked_div(b)
                    }
                };
                match v {
                    Some(v) if v.abs() <= MAX_INDEX => v,
                    _ => {
                        self.diags
                            .push(bad(format!("this index is beyond ±{MAX_INDEX}")));
                        return None;
                    }
                }
            }
            _ => {
                self.diags.push(bad(
                    "this is not a whole number known at compile time".into()
                ));
                return None;
            }
        };
        Some(v)
    }

    /// Every element reference must name a declared element.
    fn check_refs(&mut self) {
        for (array, elem, span) in std::mem::take(&mut self.refs) {
            if self.declared.contains(&elem) {
                continue;
            }
            let prefix = format!("{array}[");
            let indices: Vec<i64> = self
                .declared
                .iter()
                .filter_map(|n| n.strip_prefix(&prefix)?.strip_suffix(']')?.parse().ok())
                .collect();
            let d = if let (Some(lo), Some(hi)) = (indices.iter().min(), indices.iter().max()) {
                Diagnostic::error("E0122", format!("`{elem}` is outside the array"), span)
                    .label("no such element")
                    .hint(format!(
                        "`{array}` has elements {array}[{lo}] … {array}[{hi}]"
                    ))
            } else if self.declared.contains(&array) {
                Diagnostic::error("E0122", format!("`{array}` is not an array"), span).hint(
                    format!(
                    "declare its elements in a loop: `for i in 0..N {{ state {array}[i] = … }}`"
                ),
                )
            } else {
                Diagnostic::error("E0122", format!("no array named `{array}`"), span).hint(format!(
                    "declare its elements in a loop: `for i in 0..N {{ state {array}[i] = … }}`"
                ))
            };
            self.diags.push(d);
        }
    }
}

fn element_name(name: &Name, k: i64, index: &Expr) -> Name {
    Spanned {
        node: format!("{}[{k}]", name.node),
        span: name.span.start..(index.span.end + 1).max(name.span.end),
    }
}

fn number(v: f64, span: Span) -> Expr {
    Spanned {
        node: ExprKind::Number(Literal {
            value: v,
            dim: Dim::NONE,
            is_plain_integer: v.fract() == 0.0,
        }),
        span,
    }
}

fn binary(op: BinOp, a: Expr, b: Expr, span: Span) -> Expr {
    Spanned {
        node: ExprKind::Binary(op, Box::new(a), Box::new(b)),
        span,
    }
}
