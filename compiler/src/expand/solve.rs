//! The symbolic derivative of an expression ([`derivative`]) and the desugaring of `solve`
//! blocks into Newton–Raphson iterates (`X#0 … X#N` lets, each clamped into the solve's
//! range; [`super`]'s module documentation gives the rule), with the small AST builders
//! both use.

use super::{binary, number, MAX_ITERATIONS};
use crate::ast::*;
use crate::diagnostics::Diagnostic;
use std::collections::HashMap;

fn call(f: &str, args: Vec<Expr>, span: Span) -> Expr {
    Spanned {
        node: ExprKind::Call(
            Spanned {
                node: f.into(),
                span: span.clone(),
            },
            args,
        ),
        span,
    }
}

fn path(name: &str, span: Span) -> Expr {
    Spanned {
        node: ExprKind::Path(vec![Spanned {
            node: name.into(),
            span: span.clone(),
        }]),
        span,
    }
}

fn neg(a: Expr) -> Expr {
    let span = a.span.clone();
    Spanned {
        node: ExprKind::Neg(Box::new(a)),
        span,
    }
}

fn if_expr(c: Expr, a: Expr, b: Expr) -> Expr {
    let span = c.span.clone();
    Spanned {
        node: ExprKind::If(Box::new(c), Box::new(a), Box::new(b)),
        span,
    }
}

/// A zero with the dimension of `e`: `e * 0`.
fn zero_like(e: &Expr) -> Expr {
    binary(
        BinOp::Mul,
        e.clone(),
        number(0.0, e.span.clone()),
        e.span.clone(),
    )
}

/// `e` with every bare `x` replaced by `by`.
fn substitute(e: &Expr, x: &str, by: &str) -> Expr {
    let node = match &e.node {
        ExprKind::Path(p) if p.len() == 1 && p[0].node == x => {
            return path(by, e.span.clone());
        }
        ExprKind::Number(_) | ExprKind::Bool(_) | ExprKind::Path(_) => return e.clone(),
        ExprKind::Neg(a) => ExprKind::Neg(Box::new(substitute(a, x, by))),
        ExprKind::Not(a) => ExprKind::Not(Box::new(substitute(a, x, by))),
        ExprKind::Binary(op, a, b) => ExprKind::Binary(
            *op,
            Box::new(substitute(a, x, by)),
            Box::new(substitute(b, x, by)),
        ),
        ExprKind::Pow(a, n) => ExprKind::Pow(Box::new(substitute(a, x, by)), n.clone()),
        ExprKind::Call(f, args) => ExprKind::Call(
            f.clone(),
            args.iter().map(|a| substitute(a, x, by)).collect(),
        ),
        ExprKind::If(c, a, b) => ExprKind::If(
            Box::new(substitute(c, x, by)),
            Box::new(substitute(a, x, by)),
            Box::new(substitute(b, x, by)),
        ),
        ExprKind::Element(_) | ExprKind::Sum { .. } => return e.clone(),
    };
    Spanned {
        node,
        span: e.span.clone(),
    }
}

/// Whether `e` reads the bare name `x`.
pub(crate) fn mentions(e: &Expr, x: &str) -> bool {
    let mut found = false;
    visit_paths(e, &mut |n| found |= n == x);
    found
}

fn visit_paths(e: &Expr, f: &mut impl FnMut(&str)) {
    match &e.node {
        ExprKind::Path(p) => f(&p[0].node),
        ExprKind::Number(_) | ExprKind::Bool(_) | ExprKind::Element(_) | ExprKind::Sum { .. } => {}
        ExprKind::Neg(a) | ExprKind::Not(a) | ExprKind::Pow(a, _) => visit_paths(a, f),
        ExprKind::Binary(_, a, b) => {
            visit_paths(a, f);
            visit_paths(b, f);
        }
        ExprKind::Call(_, args) => args.iter().for_each(|a| visit_paths(a, f)),
        ExprKind::If(c, a, b) => {
            visit_paths(c, f);
            visit_paths(a, f);
            visit_paths(b, f);
        }
    }
}

/// The derivative of `e` with respect to the bare name `x`, symbolically: `Ok(None)` when it
/// is zero. The result has the dimension of `e` divided by that of `x` (d`x`/d`x` is the
/// dimensionless 1), so it passes the dimension check wherever `e` does.
///
/// Rules: sum, product, quotient and power rules; `exp`, `sqrt`; `abs` (the sign of its
/// argument, tested as `u >= -u`); `min`, `max`, `clamp` and `if` by the branch that is
/// taken (a clamp's slope is 0 outside its bounds). Errors: a function of `x` it cannot
/// differentiate (`d`, `d2`, a clamp whose bounds depend on `x`).
#[allow(clippy::result_large_err)] // a diagnostic, once per compile error
pub fn derivative(e: &Expr, x: &str) -> Result<Option<Expr>, Diagnostic> {
    let sp = e.span.clone();
    let one = |sp: Span| number(1.0, sp);
    Ok(match &e.node {
        ExprKind::Number(_) | ExprKind::Bool(_) => None,
        ExprKind::Path(p) => (p.len() == 1 && p[0].node == x).then(|| one(sp)),
        ExprKind::Neg(a) => derivative(a, x)?.map(neg),
        ExprKind::Not(_) | ExprKind::Element(_) | ExprKind::Sum { .. } => None,
        ExprKind::Binary(op, a, b) => {
            let (da, db) = (derivative(a, x)?, derivative(b, x)?);
            match op {
                BinOp::Add | BinOp::Sub => match (da, db) {
                    (None, None) => None,
                    (Some(da), None) => Some(da),
                    (None, Some(db)) => Some(if *op == BinOp::Add { db } else { neg(db) }),
                    (Some(da), Some(db)) => Some(binary(*op, da, db, sp)),
                },
                BinOp::Mul => {
                    let l = da.map(|da| binary(BinOp::Mul, da, (**b).clone(), sp.clone()));
                    let r = db.map(|db| binary(BinOp::Mul, (**a).clone(), db, sp.clone()));
                    add(l, r, sp)
                }
                BinOp::Div => {
                    let l = da.map(|da| binary(BinOp::Div, da, (**b).clone(), sp.clone()));
                    let r = db.map(|db| {
                        let num = binary(BinOp::Mul, (**a).clone(), db, sp.clone());
                        let den = binary(BinOp::Mul, (**b).clone(), (**b).clone(), sp.clone());
                        binary(BinOp::Div, num, den, sp.clone())
                    });
                    match (l, r) {
                        (l, None) => l,
                        (None, Some(r)) => Some(neg(r)),
                        (Some(l), Some(r)) => Some(binary(BinOp::Sub, l, r, sp)),
                    }
                }
                // Comparisons and logic are truth values: no slope.
                _ => None,
            }
        }
        ExprKind::Pow(a, n) => derivative(a, x)?.map(|da| {
            let k = n.node;
            let base = if k - 1.0 == 1.0 {
                (**a).clone()
            } else {
                Spanned {
                    node: ExprKind::Pow(
                        a.clone(),
                        Spanned {
                            node: k - 1.0,
                            span: n.span.clone(),
                        },
                    ),
                    span: sp.clone(),
                }
            };
            let scaled = binary(BinOp::Mul, number(k, n.span.clone()), base, sp.clone());
            if k - 1.0 == 0.0 {
                binary(BinOp::Mul, number(k, n.span.clone()), da, sp.clone())
            } else {
                binary(BinOp::Mul, scaled, da, sp.clone())
            }
        }),
        ExprKind::If(c, a, b) => {
            let (da, db) = (derivative(a, x)?, derivative(b, x)?);
            branch((**c).clone(), da, db, a, b)
        }
        ExprKind::Call(f, args) => {
            let ds = args
                .iter()
                .map(|a| derivative(a, x))
                .collect::<Result<Vec<_>, _>>()?;
            if ds.iter().all(Option::is_none) {
                return Ok(None);
            }
            let arg = |i: usize| args[i].clone();
            match (f.node.as_str(), ds.as_slice()) {
                ("exp", [Some(d)]) => Some(binary(BinOp::Mul, e.clone(), d.clone(), sp)),
                ("sqrt", [Some(d)]) => {
                    let two_root = binary(BinOp::Mul, number(2.0, sp.clone()), e.clone(), sp.clone());
                    Some(binary(BinOp::Div, d.clone(), two_root, sp))
                }
                ("abs", [Some(d)]) => {
                    let c = binary(BinOp::Ge, arg(0), neg(arg(0)), sp.clone());
                    Some(if_expr(c, d.clone(), neg(d.clone())))
                }
                ("min" | "max", [da, db]) => {
                    let op = if f.node == "min" { BinOp::Le } else { BinOp::Ge };
                    let c = binary(op, arg(0), arg(1), sp.clone());
                    branch(c, da.clone(), db.clone(), &args[0], &args[1])
                }
                ("clamp", [Some(d), None, None]) => {
                    let lo = binary(BinOp::Ge, arg(0), arg(1), sp.clone());
                    let hi = binary(BinOp::Le, arg(0), arg(2), sp.clone());
                    let inside = binary(BinOp::And, lo, hi, sp.clone());
                    Some(if_expr(inside, d.clone(), zero_like(d)))
                }
                _ => {
                    return Err(Diagnostic::error(
                        "E0127",
                        format!("cannot differentiate `{}` of the unknown `{x}`", f.node),
                        e.span.clone(),
                    )
                    .hint("a solve's residual may use + - * / ^, exp, sqrt, abs, min, max, clamp (with constant bounds) and if"))
                }
            }
        }
    })
}

fn add(l: Option<Expr>, r: Option<Expr>, sp: Span) -> Option<Expr> {
    match (l, r) {
        (None, r) => r,
        (l, None) => l,
        (Some(l), Some(r)) => Some(binary(BinOp::Add, l, r, sp)),
    }
}

/// `if c { da } else { db }`, a missing slope written as a zero of the other's dimension.
fn branch(c: Expr, da: Option<Expr>, db: Option<Expr>, a: &Expr, b: &Expr) -> Option<Expr> {
    let _ = (a, b);
    match (da, db) {
        (None, None) => None,
        (Some(da), None) => {
            let z = zero_like(&da);
            Some(if_expr(c, da, z))
        }
        (None, Some(db)) => {
            let z = zero_like(&db);
            Some(if_expr(c, z, db))
        }
        (Some(da), Some(db)) => Some(if_expr(c, da, db)),
    }
}

/// Replaces every `solve` by its Newton–Raphson iterates (see the module doc).
pub(super) fn desugar_solves(decls: Vec<Decl>, diags: &mut Vec<Diagnostic>) -> Vec<Decl> {
    // Lets by name, to find residuals that read the unknown through a let.
    let lets: HashMap<String, Expr> = decls
        .iter()
        .filter_map(|d| match d {
            Decl::Let { name, value, .. } => Some((name.node.clone(), value.clone())),
            _ => None,
        })
        .collect();
    let mut out = Vec::with_capacity(decls.len());
    for d in decls {
        let Decl::Solve {
            name,
            range,
            fields,
            span,
            ..
        } = d
        else {
            out.push(d);
            continue;
        };
        match solve_lets(&name, range.as_ref(), &fields, &span, &lets) {
            Ok(v) => {
                if let Some(range) = range {
                    out.push(Decl::SolveRange { name, range });
                }
                out.extend(v)
            }
            Err(d) => diags.push(d),
        }
    }
    out
}

#[allow(clippy::result_large_err)] // a diagnostic, once per compile error
fn solve_lets(
    name: &Name,
    range: Option<&Range>,
    fields: &[(Name, Expr)],
    span: &Span,
    lets: &HashMap<String, Expr>,
) -> Result<Vec<Decl>, Diagnostic> {
    const FIELDS: &str = "start, residual, iterations, min_slope";
    let x = name.node.as_str();
    let mut get = HashMap::new();
    for (n, e) in fields {
        if !FIELDS.split(", ").any(|f| f == n.node) {
            return Err(Diagnostic::error(
                "E0124",
                format!("a solve has no field `{}`", n.node),
                n.span.clone(),
            )
            .hint(format!("the fields are: {FIELDS}")));
        }
        if get.insert(n.node.as_str(), e).is_some() {
            return Err(Diagnostic::error(
                "E0124",
                format!("field `{}` is given twice", n.node),
                n.span.clone(),
            ));
        }
    }
    let missing = |f: &str| {
        Diagnostic::error("E0124", format!("solve `{x}` has no `{f}`"), span.clone())
            .hint("write `solve X in [lo, hi] { start = …  residual = …  iterations = 3 }`")
    };
    let Some(range) = range else {
        return Err(Diagnostic::error("E0125", format!("solve `{x}` has no range"), name.span.clone())
            .hint("add `in [lo, hi]`: every iterate is clamped into it, and it sets the fixed-point format"));
    };
    let start = *get.get("start").ok_or_else(|| missing("start"))?;
    let residual = *get.get("residual").ok_or_else(|| missing("residual"))?;
    let iters_e = *get.get("iterations").ok_or_else(|| missing("iterations"))?;
    let iterations = match &iters_e.node {
        ExprKind::Number(l)
            if l.is_plain_integer && l.value >= 1.0 && l.value <= MAX_ITERATIONS as f64 =>
        {
            l.value as i64
        }
        _ => {
            return Err(Diagnostic::error(
                "E0126",
                format!("the iteration count must be a whole number from 1 to {MAX_ITERATIONS}"),
                iters_e.span.clone(),
            )
            .hint("Newton–Raphson converges quadratically: 2 to 4 iterations are usual"))
        }
    };
    if !mentions(residual, x) {
        return Err(Diagnostic::error(
            "E0128",
            format!("the residual does not depend on `{x}`"),
            residual.span.clone(),
        )
        .hint(format!(
            "write the equation `{x}` must satisfy as `residual = … ` that is 0 at the solution"
        )));
    }
    // A let read by the residual must not depend on x: its slope would be missed.
    let mut via = None;
    visit_paths(residual, &mut |n| {
        if via.is_none() && n != x && depends_on(n, x, lets, 0) {
            via = Some(n.to_string());
        }
    });
    if let Some(l) = via {
        return Err(Diagnostic::error(
            "E0129",
            format!("the residual reads `{l}`, which depends on `{x}`"),
            residual.span.clone(),
        )
        .hint(
            "write it out in the residual: the slope is taken from the residual's own expression",
        ));
    }
    let slope = derivative(residual, x)?.ok_or_else(|| {
        Diagnostic::error(
            "E0128",
            format!("the residual's slope in `{x}` is zero"),
            residual.span.clone(),
        )
    })?;
    let rs = residual.span.clone();
    let clamp = |e: Expr| {
        call(
            "clamp",
            vec![e, range.lo.clone(), range.hi.clone()],
            rs.clone(),
        )
    };
    let iterate = |k: i64| format!("{x}#{k}");
    let let_decl = |n: String, value: Expr| Decl::Let {
        name: Spanned {
            node: n,
            span: name.span.clone(),
        },
        index: None,
        value,
    };
    let mut out = vec![let_decl(iterate(0), clamp(start.clone()))];
    for k in 1..=iterations {
        let prev = iterate(k - 1);
        let r = substitute(residual, x, &prev);
        let mut s = substitute(&slope, x, &prev);
        if let Some(m) = get.get("min_slope") {
            s = call("max", vec![s, (*m).clone()], rs.clone());
        }
        let step = binary(BinOp::Div, r, s, rs.clone());
        let next = binary(BinOp::Sub, path(&prev, rs.clone()), step, rs.clone());
        out.push(let_decl(iterate(k), clamp(next)));
    }
    out.push(let_decl(x.to_string(), path(&iterate(iterations), rs)));
    Ok(out)
}

/// Whether the let `n` (transitively) reads `x`.
fn depends_on(n: &str, x: &str, lets: &HashMap<String, Expr>, depth: usize) -> bool {
    if depth > 64 {
        return false;
    }
    let Some(e) = lets.get(n) else {
        return false;
    };
    let mut found = false;
    visit_paths(e, &mut |m| {
        found |= m == x || (!found && depends_on(m, x, lets, depth + 1));
    });
    found
}
