//! Compile-time constants: params (after `--param` overrides), sensor ranges, state initial
//! values and ranges.
//!
//! A constant expression is lowered like any other (so it gets the same name and dimension
//! checks) into scratch IR, then folded with the reference interpreter's arithmetic
//! ([`crate::interp::eval_op`]), so a constant means exactly what it would mean at run time.
//! A constant that folds to NaN or ±∞ (`0 N/m / 0`, `exp(1000)`, a `--param` of zero
//! under a division) is an error (E0312) at its span: no engine could give it a meaning.

use super::{Lowerer, Memo, ScopeId};
use crate::ast;
use crate::diagnostics::Diagnostic;
use crate::ir::*;
use crate::units::Dim;

impl<'a> Lowerer<'a> {
    /// Evaluates every constant of the program; clears the scratch IR afterwards.
    pub(super) fn evaluate_constants(&mut self) {
        self.const_ctx = true;
        self.blocks.push(Vec::new());
        for i in 0..self.params.len() {
            let _ = self.param_value(ParamId(i as u32));
        }
        for si in 0..self.scopes.len() {
            let scope = ScopeId(si);
            for d in &self.scopes[si].body.decls {
                match d {
                    ast::Decl::Sensor {
                        name,
                        ty,
                        range: Some(r),
                    } if si == 0 => {
                        let Some(Sym::Sensor(id)) =
                            self.scopes[si].syms.get(&name.node).map(|s| s.0)
                        else {
                            continue;
                        };
                        if let Some((lo, hi, dim)) = self.const_range(scope, r, ty.as_ref()) {
                            let s = &mut self.prog.sensors[id.index()];
                            s.range = (lo, hi);
                            s.dim = dim;
                        }
                    }
                    ast::Decl::State {
                        name,
                        ty,
                        index: _,
                        init,
                        range: Some(r),
                    } => {
                        let Some(Sym::State(id)) =
                            self.scopes[si].syms.get(&name.node).map(|s| s.0)
                        else {
                            continue;
                        };
                        let Some((lo, hi, dim)) = self.const_range(scope, r, ty.as_ref()) else {
                            continue;
                        };
                        let Some((v, vd)) = self.const_value(scope, init) else {
                            continue;
                        };
                        if vd != dim {
                            self.err(
                                Diagnostic::error(
                                    "E0308",
                                    format!("initial value is {vd} but the range is {dim}"),
                                    init.span.clone(),
                                )
                                .with_secondary(r.span.clone(), dim.to_string()),
                            );
                            continue;
                        }
                        if !(lo..=hi).contains(&v) {
                            self.err(
                                Diagnostic::error(
                                    "E0307",
                                    format!(
                                        "initial value of `{}` lies outside its range",
                                        name.node
                                    ),
                                    init.span.clone(),
                                )
                                .with_secondary(r.span.clone(), "declared range")
                                .hint("widen the range or change the initial value"),
                            );
                        }
                        let s = &mut self.prog.states[id.index()];
                        (s.init, s.range, s.dim) = (v, (lo, hi), dim);
                    }
                    ast::Decl::Require { cond, .. } => self.check_requirement(scope, cond),
                    // A solve's range: folded and checked (E0306, E0308) as any range.
                    ast::Decl::SolveRange { range, .. } => {
                        self.const_range(scope, range, None);
                    }
                    ast::Decl::Tolerance { .. } => self.evaluate_tolerance(scope, d),
                    ast::Decl::Dynamics { eqs, .. } => self.check_oscillators(scope, eqs),
                    _ => {}
                }
            }
        }
        self.blocks.pop();
        self.const_ctx = false;
        self.prog.values.clear();
        self.memo.clear();
    }

    /// Checks a `require`: comparisons of constants joined by `and`. A comparison that does
    /// not hold is an error giving both sides' values in SI units.
    fn check_requirement(&mut self, scope: ScopeId, cond: &'a ast::Expr) {
        use ast::BinOp::*;
        let ast::ExprKind::Binary(op, a, b) = &cond.node else {
            self.err(
                Diagnostic::error("E0311", "`require` takes comparisons of constants", cond.span.clone())
                    .hint("write e.g. `require 1 / sample_rate < 1 / (3.1416 * f0)`; join several with `and`"),
            );
            return;
        };
        if *op == And {
            self.check_requirement(scope, a);
            self.check_requirement(scope, b);
            return;
        }
        if !matches!(op, Lt | Le | Gt | Ge | Eq | Ne) {
            self.err(
                Diagnostic::error(
                    "E0311",
                    "`require` takes comparisons of constants",
                    cond.span.clone(),
                )
                .hint("write e.g. `require hx >= h_min`; join several with `and`"),
            );
            return;
        }
        let (Some((va, da)), Some((vb, db))) =
            (self.const_value(scope, a), self.const_value(scope, b))
        else {
            return;
        };
        if da != db {
            self.err(
                Diagnostic::error(
                    "E0226",
                    format!("cannot compare {da} with {db}"),
                    cond.span.clone(),
                )
                .hint("both sides of a requirement must have the same dimension"),
            );
            return;
        }
        let holds = match op {
            Lt => va < vb,
            Le => va <= vb,
            Gt => va > vb,
            Ge => va >= vb,
            Eq => va == vb,
            _ => va != vb,
        };
        if !holds {
            let unit = da.unit_string();
            let show = |v: f64| {
                if unit.is_empty() || unit == "1" {
                    format!("{v:.6}")
                } else {
                    format!("{v:.6e} {unit}")
                }
            };
            // A requirement on the sample rate is about the board the program is built for.
            let (label, hint) = match crate::expand::mentions(cond, super::SAMPLE_RATE) {
                true => (
                    format!(
                        "does not hold for these params at a sample rate of {} Hz",
                        self.config.sample_rate_hz
                    ),
                    "change the params (or `--param` overrides), or use a board whose `sample_rate_hz` meets it: requirements guard numerical stability and the uniqueness of solves",
                ),
                false => (
                    "does not hold for these params".to_string(),
                    "change the params (or `--param` overrides) so that it holds: requirements guard numerical stability and the uniqueness of solves",
                ),
            };
            self.err(
                Diagnostic::error(
                    "E0310",
                    format!(
                        "requirement not met: the left side is {}, the right side {}",
                        show(va),
                        show(vb)
                    ),
                    cond.span.clone(),
                )
                .label(label)
                .hint(hint),
            );
        }
    }

    /// Warns (W0003) about a mass–spring the sample rate cannot integrate: equations
    /// `x' = v` and `v' = RHS` where `∂RHS/∂x` (with the scope's `let`s inlined) is a
    /// constant `−ω²`. Semi-implicit Euler, which the dynamics use, is stable for an
    /// undamped oscillator only while `ω·T < 2` (T the sample period; Hairer, Lubich &
    /// Wanner, *Geometric Numerical Integration*, 2006, §I.1: the symplectic Euler map of
    /// the harmonic oscillator has eigenvalues on the unit circle iff |ωh| < 2). A stiffness
    /// the compiler cannot fold (it depends on a state) is not checked here; `tactus sim`
    /// reports the states that then saturate.
    fn check_oscillators(&mut self, scope: ScopeId, eqs: &'a [ast::Equation]) {
        let h = 1.0 / self.config.sample_rate_hz;
        let lets: std::collections::HashMap<&str, &ast::Expr> = self.scopes[scope.0]
            .body
            .decls
            .iter()
            .filter_map(|d| match d {
                ast::Decl::Let { name, value, .. } => Some((name.node.as_str(), value)),
                _ => None,
            })
            .collect();
        for eq in eqs {
            let ast::ExprKind::Path(p) = &eq.rhs.node else {
                continue;
            };
            let [v] = &p[..] else { continue };
            let Some(veq) = eqs.iter().find(|e| e.state.node == v.node) else {
                continue;
            };
            let mut budget = 10_000usize;
            let Some(rhs) = inline_lets(&veq.rhs, &lets, 16, &mut budget) else {
                continue;
            };
            let Ok(Some(slope)) = crate::expand::derivative(&rhs, &eq.state.node) else {
                continue;
            };
            // A slope that is not a constant (a nonlinear spring) is not checked.
            let Some((slope, dim)) = self.fold_slope(scope, &slope) else {
                continue;
            };
            if dim != Dim::FREQUENCY * Dim::FREQUENCY || slope >= 0.0 {
                continue;
            }
            let omega = (-slope).sqrt();
            if omega * h >= 2.0 {
                self.err(
                    Diagnostic::warning(
                        "W0003",
                        format!(
                            "`{}` and `{}` oscillate at ω = {omega:.4e} rad/s: ω·T = {:.3} ≥ 2, unstable under semi-implicit Euler at {} Hz",
                            eq.state.node, v.node, omega * h, self.config.sample_rate_hz
                        ),
                        veq.rhs.span.clone(),
                    )
                    .label(format!("∂/∂{} of this is −ω² = {slope:.4e} 1/s^2", eq.state.node))
                    .hint(format!(
                        "lower the stiffness (or raise the mass) so that ω < {:.4e} rad/s, or raise the sample rate; add `require` on the params to make it an error",
                        2.0 / h
                    )),
                );
            }
        }
    }

    /// The value and dimension of `e` when it is built from numbers and params of `scope`
    /// with `+ - * /` and integer powers; `None` otherwise. Reports nothing.
    fn fold_slope(&mut self, scope: ScopeId, e: &ast::Expr) -> Option<(f64, Dim)> {
        use ast::ExprKind as K;
        Some(match &e.node {
            K::Number(l) => (l.value, l.dim),
            K::Path(p) if p.len() == 1 => match self.scopes[scope.0].syms.get(&p[0].node) {
                Some((Sym::Param(id), _)) => self.param_value(*id)?,
                _ => return None,
            },
            K::Neg(a) => {
                let (v, d) = self.fold_slope(scope, a)?;
                (-v, d)
            }
            K::Binary(op, a, b) => {
                let ((x, dx), (y, dy)) = (self.fold_slope(scope, a)?, self.fold_slope(scope, b)?);
                match op {
                    ast::BinOp::Add if dx == dy => (x + y, dx),
                    ast::BinOp::Sub if dx == dy => (x - y, dx),
                    ast::BinOp::Mul => (x * y, dx * dy),
                    ast::BinOp::Div => (x / y, dx / dy),
                    _ => return None,
                }
            }
            K::Pow(a, n) => {
                let (v, d) = self.fold_slope(scope, a)?;
                (v.powi(n.node as i32), d.powi(n.node as i32))
            }
            _ => return None,
        })
    }

    fn const_range(
        &mut self,
        scope: ScopeId,
        r: &'a ast::Range,
        annot: Option<&'a ast::Spanned<ast::TypeAnn>>,
    ) -> Option<(f64, f64, Dim)> {
        let lo = self.const_value(scope, &r.lo);
        let hi = self.const_value(scope, &r.hi);
        let ((lo, dl), (hi, dh)) = (lo?, hi?);
        if dl != dh {
            self.err(
                Diagnostic::error(
                    "E0308",
                    format!("range bounds differ in dimension: {dl} and {dh}"),
                    r.span.clone(),
                )
                .hint("write both bounds with units of the same quantity, e.g. `[0 mm, 10 mm]`"),
            );
            return None;
        }
        if lo.partial_cmp(&hi) != Some(std::cmp::Ordering::Less) {
            self.err(
                Diagnostic::error(
                    "E0306",
                    "empty range: the lower bound is not below the upper bound",
                    r.span.clone(),
                )
                .hint("write `[lo, hi]` with lo < hi"),
            );
            return None;
        }
        if let Some(a) = annot {
            if let Some(t) = self.annot_ty(a) {
                if t != Ty::Real(dl) {
                    let msg = format!("declared as {} but its range is {dl}", self.ty_string(t));
                    self.err(
                        Diagnostic::error("E0309", msg, a.span.clone())
                            .with_secondary(r.span.clone(), dl.to_string()),
                    );
                    return None;
                }
            }
        }
        Some((lo, hi, dl))
    }

    /// A constant's value in SI and its dimension.
    pub(super) fn const_value(&mut self, scope: ScopeId, e: &'a ast::Expr) -> Option<(f64, Dim)> {
        let v = self.lower_expr(scope, e)?;
        match self.ty(v) {
            Ty::Real(d) => {
                let x = self.fold(v);
                if !x.is_finite() {
                    self.err(
                        Diagnostic::error(
                            "E0312",
                            format!("this constant is {x}, not a finite number"),
                            e.span.clone(),
                        )
                        .label(format!("folds to {x}"))
                        .hint("look for a division by zero (a param or `--param` of 0), `exp` or `^` of a large value, or a number beyond 1.8e308 in SI units"),
                    );
                    return None;
                }
                Some((x, d))
            }
            t => {
                let msg = format!("expected a quantity, found {}", self.ty_string(t));
                self.err(Diagnostic::error("E0225", msg, e.span.clone()));
                None
            }
        }
    }

    fn fold(&self, v: Value) -> f64 {
        let op = &self.prog.values[v.index()].op;
        crate::interp::eval_op(
            op,
            |x| self.fold(x),
            |p| self.prog.params[p.index()].value,
            &|_| 0.0,
        )
    }

    /// The value and dimension of a param, evaluating it (and what it depends on) once.
    pub(super) fn param_value(&mut self, p: ParamId) -> Option<(f64, Dim)> {
        if let Some(done) = self.params[p.index()].done {
            return done;
        }
        let key = Memo::Param(p);
        if !self.in_progress.insert(key) {
            let span = self.prog.params[p.index()].span.clone();
            let name = self.prog.params[p.index()].name.clone();
            self.err(
                Diagnostic::error(
                    "E0304",
                    format!("param `{name}` is defined in terms of itself"),
                    span,
                )
                .hint("a param's value must be computable from numbers and other params"),
            );
            self.params[p.index()].done = Some(None);
            return None;
        }
        let was_const = std::mem::replace(&mut self.const_ctx, true);
        self.blocks.push(Vec::new());
        let (expr, scope, annot) = (
            self.params[p.index()].expr,
            self.params[p.index()].scope,
            self.params[p.index()].annot,
        );
        let mut result = self.const_value(scope, expr);
        self.blocks.pop();
        self.const_ctx = was_const;
        self.in_progress.remove(&key);
        if let (Some((_, d)), Some(a)) = (result, annot) {
            if let Some(t) = self.annot_ty(a) {
                if t != Ty::Real(d) {
                    let msg = format!("declared as {} but its value is {d}", self.ty_string(t));
                    self.err(
                        Diagnostic::error("E0309", msg, expr.span.clone())
                            .with_secondary(a.span.clone(), "declared type"),
                    );
                    result = None;
                }
            }
        }
        if let (Some((_, d)), Some((ov, od, text))) =
            (result, self.overrides.get(&p.index()).cloned())
        {
            let name = self.prog.params[p.index()].name.clone();
            if od != d {
                let span = self.prog.params[p.index()].span.clone();
                self.err(
                    Diagnostic::error(
                        "E0303",
                        format!("`--param {name}={text}` is {od}, but `{name}` is {d}"),
                        span,
                    )
                    .label("declared here")
                    .hint(format!(
                        "give the override in a unit of {}",
                        d.unit_string()
                    )),
                );
                result = None;
            } else {
                result = Some((ov, d));
            }
        }
        if let Some((v, d)) = result {
            let decl = &mut self.prog.params[p.index()];
            (decl.value, decl.dim) = (v, d);
        }
        self.params[p.index()].done = Some(result);
        result
    }
}

use super::scope::Sym;

/// `e` with the names of `lets` replaced by their expressions, `depth` levels deep; `None`
/// when the result would pass `budget` nodes (shared lets can grow it exponentially).
fn inline_lets(
    e: &ast::Expr,
    lets: &std::collections::HashMap<&str, &ast::Expr>,
    depth: u32,
    budget: &mut usize,
) -> Option<ast::Expr> {
    use ast::ExprKind as K;
    *budget = budget.checked_sub(1)?;
    let b = |x: &ast::Expr, budget: &mut usize| inline_lets(x, lets, depth, budget).map(Box::new);
    let node = match &e.node {
        K::Path(p) if p.len() == 1 && depth > 0 => {
            if let Some(v) = lets.get(p[0].node.as_str()) {
                return inline_lets(v, lets, depth - 1, budget);
            }
            e.node.clone()
        }
        K::Neg(a) => K::Neg(b(a, budget)?),
        K::Binary(op, x, y) => K::Binary(*op, b(x, budget)?, b(y, budget)?),
        K::Pow(a, n) => K::Pow(b(a, budget)?, n.clone()),
        _ => e.node.clone(),
    };
    Some(ast::Spanned {
        node,
        span: e.span.clone(),
    })
}
