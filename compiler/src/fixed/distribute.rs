//! Constant factors distributed over sums: `(a·k1 − b·k2 − c) · K` is `a·(k1·K) −
//! b·(k2·K) − c·K`, one product fewer.
//!
//! A model writes a force as a sum of scaled terms and then scales the sum: the piano's
//! hammer is `w' = (l3·f − B_h·w − M_h·grav·l4) / I_h`, integrated as `w + w'·h`, and its
//! contact force reaches the key as `f · l2 / l1`. After the constant chains are folded
//! ([`super::chains`]) each is a product of a sum by one constant — on the Cortex-M0+ a
//! multi-`MULS` product (for the graded hammer mass a 64-bit one: `h/I_h` is a run-time
//! param) after products that already multiply each term by a constant. Distributing the
//! outer constant into the terms' factors leaves the same number of term products and no
//! outer one.
//!
//! The rewrite takes a value `a` whose every reader multiplies it by a constant or by a
//! `select` of two constants (the hammer's `l3`, which its lever switches), and whose
//! definition is a tree of sums, differences, negations, `select`s, `min`/`max` (for a
//! positive factor, which they commute with), constants, and products or quotients of any
//! value by a constant or a `select` of constants (the tree's leaves), each node read only
//! by its parent. One reader's constant `K` (a long one: a short factor such as `· 1000` is
//! a cheap exact `MULS` partner, see [`super::chains::SHORT_BITS`]) is multiplied into every
//! constant of the tree; that reader becomes `a` itself, and every other reader's factor is
//! divided by `K`. The rewrite is made only where it saves by a rough price of each
//! product by its factor (none for ±1, a `MULS` for a short constant, more for a long one):
//! the product gone against the leaves' and the other readers' factors that a short
//! constant turns into a long one (the piano's impact pulse `20 · max(ċ, 0)` keeps its
//! `MULS` rather than give its long decay product away).
//!
//! As with the chains, the f64 reference keeps the source's order of operations and defines
//! the meaning; in exact arithmetic the two are equal, and the fixed program rounds each
//! term's product once instead of the term's and the sum's. The format plan then proves or
//! simulates the new products like any other. [`crate::share`] runs the rewrite on every
//! key's program before comparing them, so a distributed constant that differs between keys
//! (`l3·h/I_h` for a graded hammer mass) becomes a run-time param.

use super::chains::{significant_bits, SHORT_BITS};
use crate::ir::*;
use crate::units::Dim;

/// A reader's factor of the value it multiplies.
#[derive(Clone, Copy, Debug)]
enum Factor {
    /// A constant (a quotient's divisor already inverted).
    Const(f64),
    /// `select(c, k1, k2)` of two constants.
    Select(Value, f64, f64),
}

/// The folds every program gets before it is shared ([`crate::share`], per key) or planned:
/// constant chains ([`super::chains`]), each common value once ([`super::common`]), constant
/// factors distributed, and the common values once more (two leaves may now agree).
pub fn fold_constants(p: &Program) -> Program {
    let q = super::common::share_common_values(&super::chains::fold_constant_chains(p));
    super::common::share_common_values(&distribute_constant_factors(&q))
}

/// The program with constant factors distributed (see the module documentation); a program
/// with none comes back equal.
pub fn distribute_constant_factors(p: &Program) -> Program {
    let mut q = p.clone();
    // Each application removes one product; the bound only guards against a bug.
    let mut any = false;
    for _ in 0..q.values.len() {
        if !distribute_one(&mut q) {
            break;
        }
        any = true;
    }
    if any {
        drop_dead_defs(&mut q);
    }
    q
}

/// Removes the definitions nothing reads any more (a factor `select` whose product now
/// multiplies by a scaled copy): the switch clause would otherwise see a decision the
/// lowered program has no partner for, and the plan a value to format for nothing.
fn drop_dead_defs(q: &mut Program) {
    loop {
        let (readers, stmt) = readers(q);
        let dead: Vec<bool> = (0..q.values.len())
            .map(|i| readers[i].is_empty() && stmt[i] == 0)
            .collect();
        let defined = defined_values(&q.body, q.values.len());
        if !(0..q.values.len()).any(|i| dead[i] && defined[i]) {
            return;
        }
        q.body = rebuild_stmts(&q.body, &mut |s, out| match s {
            Stmt::Def(v) if dead[v.index()] => {}
            other => out.push(other.clone()),
        });
    }
}

/// Readers of each value among the defined values, and per value how many statements read it.
fn readers(p: &Program) -> (Vec<Vec<usize>>, Vec<u32>) {
    let n = p.values.len();
    let defined = defined_values(&p.body, n);
    let mut r = vec![Vec::new(); n];
    for (i, vd) in p.values.iter().enumerate() {
        if defined[i] {
            for x in vd.op.operands() {
                if !r[x.index()].contains(&i) {
                    r[x.index()].push(i);
                }
            }
        }
    }
    let mut stmt = vec![0u32; n];
    walk_stmts(&p.body, &mut |s| {
        s.reads().iter().for_each(|v| stmt[v.index()] += 1)
    });
    (r, stmt)
}

/// The factor `f` of a product `x · f` or `f · x` (or `x / k`): a constant, or a `select`
/// of two constants.
fn factor(p: &Program, f: Value) -> Option<Factor> {
    if let Some(k) = p.const_value(f) {
        return k.is_finite().then_some(Factor::Const(k));
    }
    match p.values[f.index()].op {
        Op::Select(c, x, y) => match (p.const_value(x), p.const_value(y)) {
            (Some(a), Some(b)) if a.is_finite() && b.is_finite() => Some(Factor::Select(c, a, b)),
            _ => None,
        },
        _ => None,
    }
}

/// `r` multiplies `a` by a factor: `(factor operand or None for a divisor, factor)`.
fn multiplies(p: &Program, r: usize, a: Value) -> Option<(Option<Value>, Factor)> {
    match p.values[r].op {
        Op::Arith(ArithOp::Mul, x, y) if x == a && y != a => Some((Some(y), factor(p, y)?)),
        Op::Arith(ArithOp::Mul, x, y) if y == a && x != a => Some((Some(x), factor(p, x)?)),
        Op::Arith(ArithOp::Div, x, y) if x == a && y != a => {
            let k = p.const_value(y)?;
            (k != 0.0 && (1.0 / k).is_finite()).then_some((None, Factor::Const(1.0 / k)))
        }
        _ => None,
    }
}

fn dim_of(p: &Program, v: Value) -> Option<Dim> {
    match p.values[v.index()].ty {
        Ty::Real(d) => Some(d),
        _ => None,
    }
}

/// The tree of `a` (see the module documentation) for a positive or negative `k`:
/// its internal nodes (including `a`) and leaves, or `None` when `a` is no such tree.
fn tree(
    p: &Program,
    a: Value,
    k: f64,
    readers: &[Vec<usize>],
    stmt: &[u32],
    nodes: &mut Vec<Value>,
) -> Option<()> {
    nodes.push(a);
    let inner = |v: Value| -> bool {
        p.const_value(v).is_some() || (readers[v.index()].len() == 1 && stmt[v.index()] == 0)
    };
    let sub = |v: Value, nodes: &mut Vec<Value>| -> Option<()> {
        if p.const_value(v).is_some() {
            return Some(()); // a constant operand: scaled in place
        }
        if !inner(v) {
            return None;
        }
        tree(p, v, k, readers, stmt, nodes)
    };
    match p.values[a.index()].op {
        Op::Arith(ArithOp::Add | ArithOp::Sub, x, y) => {
            sub(x, nodes)?;
            sub(y, nodes)
        }
        Op::Neg(x) => sub(x, nodes),
        Op::Select(_, x, y) => {
            sub(x, nodes)?;
            sub(y, nodes)
        }
        Op::Call(Builtin::Max | Builtin::Min, x, Some(y)) if k > 0.0 => {
            sub(x, nodes)?;
            sub(y, nodes)
        }
        Op::Arith(ArithOp::Mul, x, y) => [y, x].into_iter().find_map(|f| factor(p, f)).map(|_| ()),
        Op::Arith(ArithOp::Div, _, y) => {
            let c = p.const_value(y)?;
            (c != 0.0 && (k / c).is_finite()).then_some(())
        }
        _ => None,
    }
}

/// What a product by a constant factor `c` roughly costs, in cycles of the Cortex-M0+: none
/// for ±1, a `MULS` for a short constant (at most [`SHORT_BITS`] significant bits), a
/// multi-`MULS` product for a long one ([`super::MulKind`]'s forms).
fn factor_cost(c: f64) -> i32 {
    if c.abs() == 1.0 {
        0
    } else if significant_bits(c) <= SHORT_BITS {
        4
    } else {
        12
    }
}

/// The cost of a factor: a `select`'s the costlier arm's.
fn cost_of(f: Factor) -> i32 {
    match f {
        Factor::Const(c) => factor_cost(c),
        Factor::Select(_, a, b) => factor_cost(a).max(factor_cost(b)),
    }
}

/// A factor scaled by `s`.
fn scaled(f: Factor, s: f64) -> Factor {
    match f {
        Factor::Const(c) => Factor::Const(c * s),
        Factor::Select(v, a, b) => Factor::Select(v, a * s, b * s),
    }
}

/// What the distribution of `k` over `nodes` with `readers` saves (negative) or costs
/// (positive), by [`factor_cost`]: the product of the reader whose constant goes in is
/// gone; each leaf's and each other reader's factor changes. A short `MULS` partner that
/// becomes a long constant costs more than it did (the rubbed bank's `· 1000` folded into a
/// `/ M`: 126 cycles slower, see [`super::chains`]).
fn score(
    p: &Program,
    k: f64,
    nodes: &[Value],
    facs: &[(usize, (Option<Value>, Factor))],
    r0: usize,
) -> i32 {
    let mut d = -factor_cost(k);
    for &n in nodes {
        match p.values[n.index()].op {
            Op::Arith(ArithOp::Mul, x, y) => {
                if let Some(f) = factor(p, y).or_else(|| factor(p, x)) {
                    d += cost_of(scaled(f, k)) - cost_of(f);
                }
            }
            Op::Arith(ArithOp::Div, _, y) => {
                if let Some(c) = p.const_value(y) {
                    d += factor_cost(k / c) - factor_cost(1.0 / c);
                }
            }
            _ => {}
        }
    }
    for &(r, (_, f)) in facs {
        if r != r0 {
            d += cost_of(scaled(f, 1.0 / k)) - cost_of(f);
        }
    }
    d
}

/// Defines a new constant `c` of dimension `dim` (spanned as `like`), to be defined before
/// value `at`.
fn new_const(
    q: &mut Program,
    c: f64,
    dim: Dim,
    like: Value,
    before: &mut Vec<(usize, Value)>,
    at: usize,
) -> Value {
    let span = q.values[like.index()].span.clone();
    q.values.push(ValueData {
        op: Op::Const(c),
        ty: Ty::Real(dim),
        span,
    });
    let v = Value((q.values.len() - 1) as u32);
    before.push((at, v));
    v
}

/// A new factor `f · s` in place of factor value `old` (a constant or a select of
/// constants), defined before value `at`.
fn scaled_factor(
    q: &mut Program,
    old: Value,
    f: Factor,
    s: f64,
    sdim: Dim,
    before: &mut Vec<(usize, Value)>,
    at: usize,
) -> Option<Value> {
    let dim = dim_of(q, old)? * sdim;
    match f {
        Factor::Const(c) => Some(new_const(q, c * s, dim, old, before, at)),
        Factor::Select(cond, k1, k2) => {
            let Op::Select(_, x, y) = q.values[old.index()].op else {
                return None;
            };
            let a = new_const(q, k1 * s, dim, x, before, at);
            let b = new_const(q, k2 * s, dim, y, before, at);
            let span = q.values[old.index()].span.clone();
            q.values.push(ValueData {
                op: Op::Select(cond, a, b),
                ty: Ty::Real(dim),
                span,
            });
            let v = Value((q.values.len() - 1) as u32);
            before.push((at, v));
            Some(v)
        }
    }
}

/// One distribution, the first found from the end of the body; whether there was one.
fn distribute_one(q: &mut Program) -> bool {
    let (readers, stmt) = readers(q);
    let mut order = Vec::new();
    walk_stmts(&q.body, &mut |s| {
        if let Stmt::Def(v) = s {
            order.push(*v);
        }
    });
    for &a in order.iter().rev() {
        if stmt[a.index()] > 0 || readers[a.index()].is_empty() || dim_of(q, a).is_none() {
            continue;
        }
        let Some(facs) = readers[a.index()]
            .iter()
            .map(|&r| multiplies(q, r, a).map(|f| (r, f)))
            .collect::<Option<Vec<_>>>()
        else {
            continue;
        };
        // The reader whose long constant goes into the tree.
        let Some(&(r0, (f0, Factor::Const(k)))) = facs.iter().find(|(_, (_, f))| {
            matches!(f, Factor::Const(k) if *k != 0.0 && significant_bits(*k) > SHORT_BITS)
        }) else {
            continue;
        };
        let kdim = match f0 {
            Some(f) => match dim_of(q, f) {
                Some(d) => d,
                None => continue,
            },
            None => match &q.values[r0].op {
                Op::Arith(ArithOp::Div, _, y) => match dim_of(q, *y) {
                    Some(d) => Dim::NONE / d,
                    None => continue,
                },
                _ => continue,
            },
        };
        let mut nodes = Vec::new();
        if tree(q, a, k, &readers, &stmt, &mut nodes).is_none() {
            continue;
        }
        if score(q, k, &nodes, &facs, r0) >= 0 {
            continue;
        }
        // A node read twice in the tree would be scaled twice.
        let mut seen = nodes.clone();
        seen.sort_unstable_by_key(|v| v.0);
        seen.dedup();
        if seen.len() != nodes.len() {
            continue;
        }
        apply(q, a, k, kdim, r0, &facs, &nodes);
        return true;
    }
    false
}

/// Rewrites `a`'s tree `nodes` scaled by `k` (dimension `kdim`), reader `r0` replaced by
/// `a`, the other readers' factors divided by `k`.
fn apply(
    q: &mut Program,
    a: Value,
    k: f64,
    kdim: Dim,
    r0: usize,
    facs: &[(usize, (Option<Value>, Factor))],
    nodes: &[Value],
) {
    let mut before: Vec<(usize, Value)> = Vec::new();
    for &n in nodes {
        let i = n.index();
        if let Some(d) = dim_of(q, n) {
            q.values[i].ty = Ty::Real(d * kdim);
        }
        let op = q.values[i].op.clone();
        let scale_const = |q: &mut Program, v: Value, before: &mut Vec<(usize, Value)>| -> Value {
            match q.const_value(v) {
                Some(c) => {
                    let d = dim_of(q, v).unwrap_or(Dim::NONE) * kdim;
                    new_const(q, c * k, d, v, before, i)
                }
                None => v,
            }
        };
        q.values[i].op = match op {
            Op::Arith(o @ (ArithOp::Add | ArithOp::Sub), x, y) => {
                let x = scale_const(q, x, &mut before);
                let y = scale_const(q, y, &mut before);
                Op::Arith(o, x, y)
            }
            Op::Neg(x) => Op::Neg(scale_const(q, x, &mut before)),
            Op::Select(c, x, y) => {
                let x = scale_const(q, x, &mut before);
                let y = scale_const(q, y, &mut before);
                Op::Select(c, x, y)
            }
            Op::Call(b, x, Some(y)) => {
                let x = scale_const(q, x, &mut before);
                let y = scale_const(q, y, &mut before);
                Op::Call(b, x, Some(y))
            }
            Op::Arith(ArithOp::Mul, x, y) => {
                let (fv, other, f) = match factor(q, y) {
                    Some(f) => (y, x, f),
                    None => (x, y, factor(q, x).expect("a leaf has a factor")),
                };
                let nf = scaled_factor(q, fv, f, k, kdim, &mut before, i)
                    .expect("a factor has a dimension");
                Op::Arith(ArithOp::Mul, other, nf)
            }
            Op::Arith(ArithOp::Div, x, y) => {
                let c = q.const_value(y).expect("a leaf divisor is constant");
                let d = kdim / dim_of(q, y).unwrap_or(Dim::NONE);
                let nf = new_const(q, k / c, d, y, &mut before, i);
                Op::Arith(ArithOp::Mul, x, nf)
            }
            other => other,
        };
    }
    // The other readers: their factor over k.
    for &(r, (fv, f)) in facs {
        if r == r0 {
            continue;
        }
        let nf = match fv {
            Some(fv) => scaled_factor(q, fv, f, 1.0 / k, Dim::NONE / kdim, &mut before, r),
            None => {
                // `a / c`: `a · (1/(c·k))`.
                let Factor::Const(inv) = f else { continue };
                let Op::Arith(ArithOp::Div, _, y) = q.values[r].op else {
                    continue;
                };
                let d = Dim::NONE / (dim_of(q, y).unwrap_or(Dim::NONE) * kdim);
                Some(new_const(q, inv / k, d, y, &mut before, r))
            }
        };
        if let Some(nf) = nf {
            q.values[r].op = Op::Arith(ArithOp::Mul, a, nf);
        }
    }
    // Reader r0 is `a` now: every use of it reads `a`.
    let r0v = Value(r0 as u32);
    let swap = |v: Value| if v == r0v { a } else { v };
    for (i, vd) in q.values.iter_mut().enumerate() {
        if i != r0 {
            vd.op = super::common::map_op(&vd.op, swap);
        }
    }
    q.body = rebuild_stmts(&q.body, &mut |s, out| match s {
        Stmt::Def(v) if *v == r0v => {}
        Stmt::Def(v) => {
            out.extend(
                before
                    .iter()
                    .filter(|(at, _)| *at == v.index())
                    .map(|&(_, n)| Stmt::Def(n)),
            );
            out.push(Stmt::Def(*v));
        }
        Stmt::SetState(st, v) => out.push(Stmt::SetState(*st, swap(*v))),
        Stmt::SetEdge(e, v) => out.push(Stmt::SetEdge(*e, swap(*v))),
        Stmt::Force(f, v) => out.push(Stmt::Force(*f, swap(*v))),
        Stmt::Output(o, v) => out.push(Stmt::Output(*o, swap(*v))),
        Stmt::Total(v) => out.push(Stmt::Total(swap(*v))),
        Stmt::Emit(e, args) => out.push(Stmt::Emit(*e, args.iter().map(|&v| swap(v)).collect())),
        other => out.push(other.clone()),
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lowered(src: &str) -> Program {
        crate::compile(src, &crate::lower::Config::default())
            .expect("compiles")
            .program
    }

    /// Products by a constant or by a `select` of constants.
    fn scaled_products(p: &Program) -> usize {
        let defined = defined_values(&p.body, p.values.len());
        (0..p.values.len())
            .filter(|&i| defined[i])
            .filter(|&i| match p.values[i].op {
                Op::Arith(ArithOp::Mul, x, y) => factor(p, x).is_some() || factor(p, y).is_some(),
                Op::Arith(ArithOp::Div, _, y) => p.const_value(y).is_some(),
                _ => false,
            })
            .count()
    }

    /// Runs both programs on the same key travel; the largest difference of the total and
    /// of any state, relative to the larger magnitude (1e-300 at least).
    fn differ(a: &Program, b: &Program, samples: usize) -> f64 {
        let (mut x, mut y) = (
            crate::interp::Instance::new(a),
            crate::interp::Instance::new(b),
        );
        let mut worst = 0f64;
        let rel = |u: f64, v: f64| (u - v).abs() / u.abs().max(v.abs()).max(1e-300);
        for n in 0..samples {
            let t = n as f64 / samples as f64;
            let key = 0.01 * (0.5 - 0.5 * (std::f64::consts::TAU * 3.0 * t).cos());
            let (ox, oy) = (x.step(&[key]).total, y.step(&[key]).total);
            worst = worst.max(rel(ox, oy));
            for (s, t) in x.states().iter().zip(y.states()) {
                worst = worst.max(rel(*s, *t));
            }
        }
        worst
    }

    #[test]
    fn a_scaled_sum_of_scaled_terms_is_one_product_fewer_and_the_same_meaning() {
        // `(k·c + b·ċ) · 0.48` behind a Heaviside switch and a `max`, read once more by the
        // hammer through a lever `select`: the 0.48 goes into k and b, the force is the sum
        // itself, and the hammer's factor is l3/0.48 (one product fewer, in exact arithmetic
        // the same values).
        let src = "instrument t {\n sensor key: m in [0 mm, 10 mm]\n mode ph { a, b } = a\n state s = 0 in [-1, 1]\n state w = 0 Hz in [-100 Hz, 100 Hz]\n on key > 5 mm { ph = b }\n on key < 1 mm { ph = a }\n let k = if ph == b { 500 N/m } else { 30000 N/m }\n let l3 = if ph == b { 13 mm } else { 13.5 mm }\n let c = 0.48 * key - l3 * s\n let f = if c > 0 m { max(k * c + 2.37 N*s/m * d(key), 0 N) } else { 0 N }\n dynamics {\n  w' = (l3 * f - 0.0002 N*m*s * w - 0.0102 N*m) / 1.352e-4 kg*m^2\n  s' = w\n }\n force contact = f * 120 mm / 250 mm\n}\n";
        let p = lowered(src);
        let before = super::super::common::share_common_values(
            &super::super::chains::fold_constant_chains(&p),
        );
        let after = fold_constants(&p);
        // The contact's 0.48 and the hammer's h/I: two products fewer.
        assert_eq!(
            scaled_products(&after) + 2,
            scaled_products(&before),
            "{after}"
        );
        let d = differ(&p, &after, 4000);
        assert!(d < 1e-9, "relative difference {d}");
    }

    #[test]
    fn a_short_factor_stays_where_a_long_one_would_replace_it() {
        // `2 · x` and `3 · y` are exact `MULS` partners; `(2·x + 3·y) · 0.4123` would make
        // both long (0.8246·x, 1.2369·y) to save the one long outer product: left alone.
        // With 0.37 · x and 3.7 · y (long already): distributed, one product fewer.
        let src = |kx: &str, ky: &str, outer: &str| {
            format!("instrument t {{\n sensor x: m in [0 mm, 10 mm]\n sensor y: m in [0 mm, 10 mm]\n force f = ({kx} N/m * x + {ky} N/m * y) * {outer}\n}}\n")
        };
        let p = lowered(&src("2", "3", "0.4123"));
        assert_eq!(distribute_constant_factors(&p), p);
        let p = lowered(&src("0.37", "3.7", "0.4123"));
        assert_eq!(
            scaled_products(&distribute_constant_factors(&p)) + 1,
            scaled_products(&p)
        );
    }
}
