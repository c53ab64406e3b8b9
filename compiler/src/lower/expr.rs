//! Expressions: name resolution and the dimension rules.
//!
//! | form | rule |
//! |---|---|
//! | `a + b`, `a - b`, `min`, `max`, `clamp`, comparisons, `if` arms | equal dimensions |
//! | `a * b`, `a / b` | exponents add / subtract |
//! | `x ^ n` | exponents times the integer `n` |
//! | `sqrt(x)` | exponents halved (must be even) |
//! | `exp(x)` | dimensionless |
//! | `d(s)`, `d2(s)` | a sensor's dimension per second, per second squared |
//! | `and`, `or`, `not`, conditions | truth values |
//! | `m == v`, `m != v` | a mode and one of its variants |
//!
//! A plain number is dimensionless: `0` is not `0 N`. This is deliberate — a missing unit is
//! the commonest modelling slip — and the error says which unit to write.

use super::scope::Sym;
use super::{Lowerer, Memo, ScopeId};
use crate::ast::{self, BinOp, ExprKind, Span};
use crate::diagnostics::Diagnostic;
use crate::ir::*;
use crate::units::Dim;

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

/// The built-in constant `sample_rate`: the board's sample rate in Hz, the rate the dynamics
/// are integrated at (so `1 / sample_rate` is the time step of stability conditions). A name
/// declared in the instrument or component takes precedence.
pub const SAMPLE_RATE: &str = "sample_rate";

/// Whether `name` is a built-in function.
pub fn is_builtin(name: &str) -> bool {
    BUILTINS.iter().any(|(n, _)| *n == name)
}

/// The candidate closest to `name` by edit distance, if it is close enough to be a typo.
pub fn closest<'s>(name: &str, candidates: impl Iterator<Item = &'s str>) -> Option<&'s str> {
    candidates
        .map(|c| (levenshtein(name, c), c))
        .filter(|&(d, c)| d <= (name.len().max(c.len()) / 3).max(1))
        .min()
        .map(|(_, c)| c)
}

fn levenshtein(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1];
        for (j, &cb) in b.iter().enumerate() {
            cur.push(
                (prev[j] + usize::from(ca != cb))
                    .min(prev[j + 1] + 1)
                    .min(cur[j] + 1),
            );
        }
        prev = cur;
    }
    prev[b.len()]
}

impl<'a> Lowerer<'a> {
    /// Lowers an expression into the current block; `None` after reporting an error.
    pub(super) fn lower_expr(&mut self, scope: ScopeId, e: &'a ast::Expr) -> Option<Value> {
        if self.prog.values.len() > super::MAX_LOWERED_VALUES {
            self.err(
                Diagnostic::error(
                    "E0139",
                    format!(
                        "the program lowers to more than {} values",
                        super::MAX_LOWERED_VALUES
                    ),
                    e.span.clone(),
                )
                .label("lowering went over the budget here")
                .hint("a definition used in many places is code in each (a `solve`'s slope copies its residual's products): name shared parts, shorten long products"),
            );
            return None;
        }
        let outer = std::mem::replace(&mut self.cur_span, e.span.clone());
        let v = self.lower_expr_inner(scope, e);
        self.cur_span = outer;
        v
    }

    fn lower_expr_inner(&mut self, scope: ScopeId, e: &'a ast::Expr) -> Option<Value> {
        match &e.node {
            ExprKind::Number(l) => Some(self.def(Op::Const(l.value), Ty::Real(l.dim))),
            ExprKind::Bool(b) => Some(self.def(Op::BoolConst(*b), Ty::Bool)),
            ExprKind::Path(p) => self.lower_path(scope, p, e.span.clone()),
            ExprKind::Neg(a) => {
                let x = self.lower_expr(scope, a)?;
                let t = self.real(x, &a.span, "negate")?;
                Some(self.def(Op::Neg(x), Ty::Real(t)))
            }
            ExprKind::Not(a) => {
                let x = self.lower_expr(scope, a)?;
                self.boolean(x, &a.span, "`not`")?;
                Some(self.def(Op::Not(x), Ty::Bool))
            }
            ExprKind::Binary(op, a, b) if matches!(op, BinOp::Eq | BinOp::Ne) => {
                self.lower_binary(scope, *op, a, b, e.span.clone())
            }
            ExprKind::Binary(..) => self.lower_chain(scope, e),
            ExprKind::Pow(a, n) => {
                let x = self.lower_expr(scope, a)?;
                let d = self.real(x, &a.span, "raise to a power")?;
                let n = n.node as i32;
                let mut acc = if n == 0 {
                    self.def(Op::Const(1.0), Ty::Real(Dim::NONE))
                } else {
                    x
                };
                for k in 2..=n.abs() {
                    acc = self.def(Op::Arith(ArithOp::Mul, acc, x), Ty::Real(d.powi(k)));
                }
                if n < 0 {
                    let one = self.def(Op::Const(1.0), Ty::Real(Dim::NONE));
                    acc = self.def(Op::Arith(ArithOp::Div, one, acc), Ty::Real(d.powi(n)));
                }
                Some(acc)
            }
            ExprKind::Call(f, args) => self.lower_call(scope, f, args, e.span.clone()),
            ExprKind::Element(_) | ExprKind::Sum { .. } => {
                self.err(Diagnostic::error(
                    "E0001",
                    "internal error: an array element or sum reached lowering unexpanded",
                    e.span.clone(),
                ));
                None
            }
            ExprKind::If(c, a, b) => {
                let cv = self.lower_expr(scope, c)?;
                self.boolean(cv, &c.span, "an `if` condition")?;
                let av = self.lower_expr(scope, a);
                let bv = self.lower_expr(scope, b);
                let (av, bv) = (av?, bv?);
                let (ta, tb) = (self.ty(av), self.ty(bv));
                if ta != tb {
                    let msg = format!(
                        "the arms of this `if` differ: {} and {}",
                        self.ty_string(ta),
                        self.ty_string(tb)
                    );
                    self.err(
                        Diagnostic::error("E0204", msg, e.span.clone())
                            .with_secondary(a.span.clone(), self.ty_string(ta))
                            .with_secondary(b.span.clone(), self.ty_string(tb))
                            .hint("both arms must have the same unit (a bare `0` is dimensionless: write `0 N`)"),
                    );
                    return None;
                }
                Some(self.def(Op::Select(cv, av, bv), ta))
            }
        }
    }

    fn real(&mut self, v: Value, span: &Span, what: &str) -> Option<Dim> {
        match self.ty(v) {
            Ty::Real(d) => Some(d),
            t => {
                let msg = format!("cannot {what} {}", self.ty_string(t));
                self.err(
                    Diagnostic::error("E0225", msg, span.clone()).label("expected a quantity"),
                );
                None
            }
        }
    }

    fn boolean(&mut self, v: Value, span: &Span, what: &str) -> Option<()> {
        if self.ty(v) == Ty::Bool {
            return Some(());
        }
        let msg = format!(
            "{what} needs a truth value, but this is {}",
            self.ty_string(self.ty(v))
        );
        self.err(Diagnostic::error("E0205", msg, span.clone()).hint("compare it, e.g. `x > 1 mm`"));
        None
    }

    /// The variant of `mode` a bare name denotes.
    fn variant_of(&self, e: &ast::Expr, mode: ModeId) -> Option<u32> {
        let ExprKind::Path(p) = &e.node else {
            return None;
        };
        if p.len() != 1 {
            return None;
        }
        self.prog.modes[mode.index()]
            .variants
            .iter()
            .position(|v| *v == p[0].node)
            .map(|i| i as u32)
    }

    /// A left-nested chain of binary operators (`a + b + c …`, what a `sum` over 4096
    /// indices expands to), lowered along its left spine in a loop rather than by one
    /// recursion per operator, so its length costs no stack. The IR is what the recursion
    /// gives: the leftmost operand first, then each right operand and its operation.
    fn lower_chain(&mut self, scope: ScopeId, e: &'a ast::Expr) -> Option<Value> {
        let mut spine = Vec::new();
        let mut leaf = e;
        while let ExprKind::Binary(op, a, _) = &leaf.node {
            if matches!(op, BinOp::Eq | BinOp::Ne) {
                break;
            }
            spine.push(leaf);
            leaf = a;
        }
        let mut acc = self.lower_expr(scope, leaf);
        for node in spine.into_iter().rev() {
            let ExprKind::Binary(op, a, b) = &node.node else {
                continue; // the spine holds binary nodes only
            };
            self.cur_span = node.span.clone();
            let y = self.lower_expr(scope, b);
            acc = match (acc, y) {
                (Some(x), Some(y)) => self.finish_binary(*op, x, y, a, b, node.span.clone()),
                _ => None,
            };
        }
        acc
    }

    fn lower_binary(
        &mut self,
        scope: ScopeId,
        op: BinOp,
        a: &'a ast::Expr,
        b: &'a ast::Expr,
        span: Span,
    ) -> Option<Value> {
        if matches!(op, BinOp::Eq | BinOp::Ne) {
            // `mode == variant` in either order. A variant name on the right of a mode wins
            // over any other meaning of that name; on the left only an otherwise unknown name
            // is taken as a variant.
            let bare = |e: &ast::Expr| matches!(&e.node, ExprKind::Path(p) if p.len() == 1);
            let unknown = |e: &ast::Expr| matches!(&e.node, ExprKind::Path(p) if p.len() == 1 && !self.scopes[scope.0].syms.contains_key(&p[0].node));
            let swapped = unknown(a) && !unknown(b);
            let (mode_side, var_side) = if swapped { (b, a) } else { (a, b) };
            let mv = self.lower_expr(scope, mode_side)?;
            if let (Ty::Mode(m), true) = (self.ty(mv), bare(var_side)) {
                let Some(idx) = self.variant_of(var_side, m) else {
                    let list = self.prog.modes[m.index()].variants.join(", ");
                    let name = self.prog.modes[m.index()].name.clone();
                    self.err(
                        Diagnostic::error("E0224", format!("mode `{name}` is compared with something that is not one of its variants"), var_side.span.clone())
                            .hint(format!("the variants are: {list}")),
                    );
                    return None;
                };
                let vv = self.def(Op::Variant(m, idx), Ty::Mode(m));
                let cmp = if op == BinOp::Eq {
                    CmpOp::Eq
                } else {
                    CmpOp::Ne
                };
                return Some(self.def(Op::Cmp(cmp, mv, vv), Ty::Bool));
            }
            let other = self.lower_expr(scope, var_side)?;
            let (x, y) = if swapped { (other, mv) } else { (mv, other) };
            return self.finish_binary(op, x, y, a, b, span);
        }
        let x = self.lower_expr(scope, a);
        let y = self.lower_expr(scope, b);
        self.finish_binary(op, x?, y?, a, b, span)
    }

    fn finish_binary(
        &mut self,
        op: BinOp,
        x: Value,
        y: Value,
        a: &ast::Expr,
        b: &ast::Expr,
        span: Span,
    ) -> Option<Value> {
        let (tx, ty) = (self.ty(x), self.ty(y));
        match op {
            BinOp::And | BinOp::Or => {
                self.boolean(x, &a.span, if op == BinOp::And { "`and`" } else { "`or`" })?;
                self.boolean(y, &b.span, if op == BinOp::And { "`and`" } else { "`or`" })?;
                let o = if op == BinOp::And {
                    Op::And(x, y)
                } else {
                    Op::Or(x, y)
                };
                Some(self.def(o, Ty::Bool))
            }
            BinOp::Eq | BinOp::Ne | BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => {
                let cmp = match op {
                    BinOp::Eq => CmpOp::Eq,
                    BinOp::Ne => CmpOp::Ne,
                    BinOp::Lt => CmpOp::Lt,
                    BinOp::Le => CmpOp::Le,
                    BinOp::Gt => CmpOp::Gt,
                    _ => CmpOp::Ge,
                };
                let ok = match (tx, ty) {
                    (Ty::Real(p), Ty::Real(q)) => p == q,
                    (Ty::Bool, Ty::Bool) => matches!(cmp, CmpOp::Eq | CmpOp::Ne),
                    _ => false,
                };
                if !ok {
                    let msg = format!(
                        "cannot compare {} with {}",
                        self.ty_string(tx),
                        self.ty_string(ty)
                    );
                    self.err(
                        Diagnostic::error("E0203", msg, span)
                            .with_secondary(a.span.clone(), self.ty_string(tx))
                            .with_secondary(b.span.clone(), self.ty_string(ty))
                            .hint(
                                zero_hint(tx, ty).unwrap_or("both sides must have the same unit"),
                            ),
                    );
                    return None;
                }
                Some(self.def(Op::Cmp(cmp, x, y), Ty::Bool))
            }
            BinOp::Add | BinOp::Sub | BinOp::Mul | BinOp::Div => {
                let verb = match op {
                    BinOp::Add => "add",
                    BinOp::Sub => "subtract",
                    BinOp::Mul => "multiply",
                    _ => "divide",
                };
                let dx = self.real(x, &a.span, verb)?;
                let dy = self.real(y, &b.span, verb)?;
                let (aop, d) = match op {
                    BinOp::Add => (ArithOp::Add, dx),
                    BinOp::Sub => (ArithOp::Sub, dx),
                    BinOp::Mul => (ArithOp::Mul, dx * dy),
                    _ => (ArithOp::Div, dx / dy),
                };
                if matches!(aop, ArithOp::Add | ArithOp::Sub) && dx != dy {
                    let msg = format!("cannot {verb} {} and {}", dx, dy);
                    self.err(
                        Diagnostic::error("E0202", format!("dimension mismatch: {msg}"), span)
                            .with_secondary(a.span.clone(), dx.to_string())
                            .with_secondary(b.span.clone(), dy.to_string())
                            .hint(zero_hint(tx, ty).unwrap_or("terms of a sum must have the same unit; check for a missing factor")),
                    );
                    return None;
                }
                Some(self.def(Op::Arith(aop, x, y), Ty::Real(d)))
            }
        }
    }

    fn lower_path(&mut self, scope: ScopeId, p: &'a [ast::Name], span: Span) -> Option<Value> {
        if p.len() == 1
            && p[0].node == SAMPLE_RATE
            && !self.scopes[scope.0].syms.contains_key(SAMPLE_RATE)
        {
            let fs = self.config.sample_rate_hz;
            return Some(self.def(Op::Const(fs), Ty::Real(Dim::FREQUENCY)));
        }
        let sym = self.lookup(scope, &p[0])?;
        if p.len() == 1 {
            return self.lower_sym(scope, sym, &p[0], span);
        }
        let mut cur_scope = scope;
        let mut sym = sym;
        let mut last = &p[0];
        let mut i = 1;
        while i < p.len() {
            let seg = &p[i];
            let Sym::Instance(child) = sym else {
                let what = sym.describe();
                self.err(Diagnostic::error(
                    "E0223",
                    format!("`{}` is a {what}, it has no members", p[i - 1].node),
                    p[i - 1].span.clone(),
                ));
                return None;
            };
            cur_scope = child;
            // A component's vector force read from outside: `w.push.y` names `push.y`.
            let component = p
                .get(i + 1)
                .map(|c| format!("{}.{}", seg.node, c.node))
                .and_then(|n| self.scopes[cur_scope.0].syms.get(&n).map(|s| s.0));
            match component {
                Some(s) => {
                    sym = s;
                    i += 2;
                }
                None => {
                    sym = self.lookup(cur_scope, seg)?;
                    i += 1;
                }
            }
            last = seg;
        }
        let visible = match sym {
            Sym::Def(i) => self.defs[i].kind != super::DefKind::Let,
            Sym::State(_) | Sym::Mode(_) | Sym::Param(_) | Sym::Instance(_) => true,
            Sym::Input(_) | Sym::Sensor(_) => false,
        };
        if !visible {
            self.err(
                Diagnostic::error(
                    "E0223",
                    format!("`{}` is not visible outside its component", last.node),
                    last.span.clone(),
                )
                .hint("declare it as `output NAME = …` in the component to read it from outside"),
            );
            return None;
        }
        self.lower_sym(cur_scope, sym, last, span)
    }

    fn not_constant(&mut self, name: &ast::Name, what: &str) -> Option<Value> {
        self.err(
            Diagnostic::error("E0305", format!("`{}` is a {what}, so this is not a constant", name.node), name.span.clone())
                .hint("params, ranges and initial values are computed at compile time from numbers and other params"),
        );
        None
    }

    fn lower_sym(
        &mut self,
        scope: ScopeId,
        sym: Sym,
        name: &'a ast::Name,
        span: Span,
    ) -> Option<Value> {
        if self.const_ctx && !matches!(sym, Sym::Param(_)) {
            return self.not_constant(name, sym.describe());
        }
        match sym {
            Sym::Sensor(s) => {
                let d = self.prog.sensors[s.index()].dim;
                Some(self.memoised(Memo::Sensor(s), Op::Sensor(s), Ty::Real(d)))
            }
            Sym::Param(p) => {
                let (_, d) = self.param_value(p)?;
                Some(self.memoised(Memo::Param(p), Op::Param(p), Ty::Real(d)))
            }
            Sym::State(s) => Some(self.read_state(s)),
            Sym::Mode(m) => Some(self.memoised(Memo::Mode(m), Op::Mode(m), Ty::Mode(m))),
            Sym::Def(i) => self.lower_def(i, span),
            Sym::Input(i) => self.lower_input(scope, i, span),
            Sym::Instance(_) => {
                self.err(
                    Diagnostic::error(
                        "E0222",
                        format!("`{}` is a component instance, not a value", name.node),
                        name.span.clone(),
                    )
                    .hint(format!("read one of its outputs: `{}.NAME`", name.node)),
                );
                None
            }
        }
    }

    fn lower_input(&mut self, scope: ScopeId, i: usize, span: Span) -> Option<Value> {
        let key = Memo::Input(scope, i);
        if let Some(&v) = self.memo.get(&key) {
            return Some(v);
        }
        let inp = &self.scopes[scope.0].inputs[i];
        let (arg, want, parent) = (inp.arg?, inp.dim, self.scopes[scope.0].parent?);
        if !self.in_progress.insert(key) {
            self.err(Diagnostic::error(
                "E0216",
                "this component input is defined in terms of itself",
                span,
            ));
            return None;
        }
        let v = self.lower_expr(parent, arg);
        self.in_progress.remove(&key);
        let v = v?;
        if let Some(want) = want {
            if self.ty(v) != want {
                let name = self.scopes[scope.0].inputs[i].name.node.clone();
                let msg = format!(
                    "input `{name}` expects {}, but is given {}",
                    self.ty_string(want),
                    self.ty_string(self.ty(v))
                );
                self.err(Diagnostic::error("E0226", msg, arg.span.clone()).label("connected here"));
                return None;
            }
        }
        self.memo.insert(key, v);
        Some(v)
    }

    /// The sensor an expression denotes directly or through component inputs.
    fn sensor_of(&self, scope: ScopeId, e: &ast::Expr) -> Option<SensorId> {
        let ExprKind::Path(p) = &e.node else {
            return None;
        };
        if p.len() != 1 {
            return None;
        }
        match self.scopes[scope.0].syms.get(&p[0].node)?.0 {
            Sym::Sensor(s) => Some(s),
            Sym::Input(i) => {
                let arg = self.scopes[scope.0].inputs[i].arg?;
                self.sensor_of(self.scopes[scope.0].parent?, arg)
            }
            _ => None,
        }
    }

    fn lower_call(
        &mut self,
        scope: ScopeId,
        f: &'a ast::Name,
        args: &'a [ast::Expr],
        span: Span,
    ) -> Option<Value> {
        let Some(&(name, sig)) = BUILTINS.iter().find(|(n, _)| *n == f.node) else {
            let hint = match closest(&f.node, BUILTINS.iter().map(|(n, _)| *n)) {
                Some(c) => format!("did you mean `{c}`?"),
                None => format!(
                    "the functions are: {}",
                    BUILTINS
                        .iter()
                        .map(|(_, s)| *s)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            };
            self.err(
                Diagnostic::error(
                    "E0217",
                    format!("unknown function `{}`", f.node),
                    f.span.clone(),
                )
                .hint(hint),
            );
            return None;
        };
        let arity = match name {
            "min" | "max" => 2,
            "clamp" => 3,
            _ => 1,
        };
        if args.len() != arity {
            self.err(
                Diagnostic::error(
                    "E0218",
                    format!("`{name}` takes {arity} argument(s), {} given", args.len()),
                    span,
                )
                .hint(format!("write `{sig}`")),
            );
            return None;
        }
        if name == "d" || name == "d2" {
            if self.const_ctx {
                self.err(Diagnostic::error(
                    "E0305",
                    format!("`{name}(…)` is not a constant"),
                    span,
                ));
                return None;
            }
            let Some(s) = self.sensor_of(scope, &args[0]) else {
                self.err(
                    Diagnostic::error("E0219", format!("`{name}()` differentiates a sensor, and this is not one"), args[0].span.clone())
                        .hint("for the rate of a state, declare its dynamics; for a sensor pass its name, e.g. `d(key)`"),
                );
                return None;
            };
            let order = if name == "d" { 1u8 } else { 2 };
            self.prog.sensors[s.index()].differentiated = true;
            let d = self.prog.sensors[s.index()].dim / Dim::TIME.powi(order as i32);
            return Some(self.memoised(Memo::Deriv(s, order), Op::Deriv(s, order), Ty::Real(d)));
        }
        let vals: Vec<Option<Value>> = args.iter().map(|a| self.lower_expr(scope, a)).collect();
        let vals: Vec<Value> = vals.into_iter().collect::<Option<_>>()?;
        let mut dims = Vec::new();
        for (v, a) in vals.iter().zip(args) {
            dims.push(self.real(*v, &a.span, &format!("pass to `{name}`"))?);
        }
        let d0 = dims[0];
        if let Some(bad) = dims.iter().position(|d| *d != d0) {
            self.err(
                Diagnostic::error(
                    "E0202",
                    format!("dimension mismatch: `{name}` of {} and {}", d0, dims[bad]),
                    span,
                )
                .with_secondary(args[bad].span.clone(), dims[bad].to_string())
                .hint(
                    zero_hint(Ty::Real(d0), Ty::Real(dims[bad]))
                        .unwrap_or("all arguments must have the same unit"),
                ),
            );
            return None;
        }
        let (op, d) = match name {
            "abs" => (Op::Call(Builtin::Abs, vals[0], None), d0),
            "min" => (Op::Call(Builtin::Min, vals[0], Some(vals[1])), d0),
            "max" => (Op::Call(Builtin::Max, vals[0], Some(vals[1])), d0),
            "clamp" => {
                let lo = self.def(Op::Call(Builtin::Max, vals[0], Some(vals[1])), Ty::Real(d0));
                (Op::Call(Builtin::Min, lo, Some(vals[2])), d0)
            }
            "sqrt" => {
                let Some(h) = d0.sqrt() else {
                    self.err(
                        Diagnostic::error("E0220", format!("the square root of {d0} has no unit"), args[0].span.clone())
                            .hint("the exponents of every base unit must be even, e.g. `sqrt(k / m)` for N/m over kg"),
                    );
                    return None;
                };
                (Op::Call(Builtin::Sqrt, vals[0], None), h)
            }
            _ => {
                if !d0.is_none() {
                    self.err(
                        Diagnostic::error(
                            "E0221",
                            format!("`exp` needs a dimensionless argument, but this is {d0}"),
                            args[0].span.clone(),
                        )
                        .hint("divide by a reference value first, e.g. `exp(-v*v / (v0*v0))`"),
                    );
                    return None;
                }
                (Op::Call(Builtin::Exp, vals[0], None), Dim::NONE)
            }
        };
        Some(self.def(op, Ty::Real(d)))
    }
}

fn zero_hint(a: Ty, b: Ty) -> Option<&'static str> {
    match (a, b) {
        (Ty::Real(x), Ty::Real(y)) if x.is_none() != y.is_none() => {
            Some("a plain number is dimensionless: give it the unit of the other side, e.g. `0 N` or `5 mm`")
        }
        _ => None,
    }
}
