//! Constant chains: a product (or quotient) by a constant of a value that is itself only a
//! product (or quotient) by a constant is one product by the constants' product.
//!
//! The dynamics are integrated as `x + f · h` (semi-implicit Euler, `h = 1/fs`), and `f`
//! is often itself a quotient by a constant: the piano's hammer `w' = (…) / I_h` was
//! `((…) · (1/I_h)) · h`, two products on every sample's path, both 64-bit (≈ 23 cycles
//! each) because `h` and `1/I_h` are far from 1. `(x / k1) · k2` becomes `x · (k2/k1)`
//! (and `(x · k1) / k2`, `(x / k1) / k2` alike), so that one rounding and one product
//! remain, when the inner value has no other use (it is not published, compared, stored or
//! read by anything else). One of the two steps must be a division: a reciprocal fills a
//! word anyway, but two short constants (`2 · 0.5`) may each fit a cheap `MULS` that their
//! product does not (folding those too made the rubbed bank's update 126 cycles slower).
//!
//! A chain with a *short* factor (at most [`SHORT_BITS`] significant bits, `· 1000`,
//! `/ 2`) is left alone: such a factor is a cheap exact `MULS` partner, and folding it into
//! a long one makes a long constant (the rubbed bank's `(…) / M · h` with `M = 1 g` was 126
//! cycles slower folded). [`crate::share`] runs the fold on every key's program before
//! comparing them, so a folded constant that differs between keys (`h/I_h` of a graded
//! hammer mass) becomes one run-time param; keys whose chains fold differently are shared
//! unfolded. The f64 reference keeps the source's order of
//! operations and defines the meaning; in exact arithmetic the two are equal, and the fixed
//! program's one rounding of `k1·k2` replaces two. A product that folds to a constant that
//! is not finite keeps its two steps.

use crate::ir::*;

/// The program with constant chains folded (see the module documentation); a program with
/// none comes back equal.
pub fn fold_constant_chains(p: &Program) -> Program {
    let mut q = p.clone();
    let mut uses = vec![0u32; q.values.len()];
    for vd in &q.values {
        for x in vd.op.operands() {
            uses[x.index()] += 1;
        }
    }
    count_statement_uses(&q.body, &mut uses);
    let mut dropped = vec![false; q.values.len()];
    // The folded constant of each rewritten product, defined just before it.
    let mut before: Vec<Option<Value>> = vec![None; q.values.len()];
    let order = def_order(&q.body);
    for i in order {
        let Some((a, k2)) = by_constant(&q, Value(i as u32)) else {
            continue;
        };
        if uses[a.index()] != 1 {
            continue;
        }
        let Some((x, k1)) = by_constant(&q, a) else {
            continue;
        };
        // A short factor (`· 1000`, `/ 2`) is a cheap exact `MULS` partner; folded into a
        // long one it would make a long constant (the rubbed bank's `/ M` with `M = 1 g`:
        // its update was 126 cycles slower folding those).
        if significant_bits(k1) <= SHORT_BITS || significant_bits(k2) <= SHORT_BITS {
            continue;
        }
        let k = k1 * k2;
        let (Ty::Real(dim_i), Ty::Real(dim_x)) = (q.values[i].ty, q.values[x.index()].ty) else {
            continue;
        };
        if !k.is_finite() {
            continue;
        }
        let span = q.values[i].span.clone();
        q.values.push(ValueData {
            op: Op::Const(k),
            ty: Ty::Real(dim_i / dim_x),
            span,
        });
        uses.push(1);
        dropped.push(false);
        let c = Value((q.values.len() - 1) as u32);
        q.values[i].op = Op::Arith(ArithOp::Mul, x, c);
        before[i] = Some(c);
        dropped[a.index()] = true;
        uses[a.index()] = 0;
    }
    if dropped.iter().any(|d| *d) {
        q.body = rewrite_defs(&q.body, &dropped, &before);
    }
    q
}

/// A constant of at most this many significant bits is *short*: it is not folded into a
/// chain (see [`fold_constant_chains`]).
pub const SHORT_BITS: u32 = 16;

/// Significant bits of `k`'s binary mantissa (from its highest to its lowest set bit); 0
/// for 0 and for what is not finite.
pub fn significant_bits(k: f64) -> u32 {
    if k == 0.0 || !k.is_finite() {
        return 0;
    }
    let bits = k.abs().to_bits();
    let exp = (bits >> 52) & 0x7ff;
    let frac = bits & ((1u64 << 52) - 1);
    let m = if exp == 0 { frac } else { frac | (1u64 << 52) };
    64 - m.leading_zeros() - m.trailing_zeros()
}

/// `v = y · k`, `k · y` or `y / k` with `k` a compile-time constant: `(y, k or 1/k)`.
pub(crate) fn by_constant(p: &Program, v: Value) -> Option<(Value, f64)> {
    match p.values[v.index()].op {
        Op::Arith(ArithOp::Mul, x, y) => match (p.const_value(x), p.const_value(y)) {
            (_, Some(k)) => Some((x, k)),
            (Some(k), None) => Some((y, k)),
            (None, None) => None,
        },
        Op::Arith(ArithOp::Div, x, y) => p.const_value(y).map(|k| (x, 1.0 / k)),
        _ => None,
    }
}

/// Adds one to `uses` for each value a statement of `stmts` reads ([`Stmt::reads`]).
pub(super) fn count_statement_uses(stmts: &[Stmt], uses: &mut [u32]) {
    walk_stmts(stmts, &mut |s| {
        s.reads().iter().for_each(|v| uses[v.index()] += 1)
    });
}

/// The defined values in body order (a definition precedes its uses).
fn def_order(stmts: &[Stmt]) -> Vec<usize> {
    let mut out = Vec::new();
    walk_stmts(stmts, &mut |s| {
        if let Stmt::Def(v) = s {
            out.push(v.index())
        }
    });
    out
}

/// `stmts` without the definitions of `dropped` values and with each folded constant's
/// definition before the product that reads it.
fn rewrite_defs(stmts: &[Stmt], dropped: &[bool], before: &[Option<Value>]) -> Vec<Stmt> {
    rebuild_stmts(stmts, &mut |s, out| match s {
        Stmt::Def(v) if dropped[v.index()] => {}
        Stmt::Def(v) => {
            out.extend(before[v.index()].map(Stmt::Def));
            out.push(s.clone());
        }
        other => out.push(other.clone()),
    })
}
