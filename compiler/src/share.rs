//! Params as run-time data: one program for keys that run one instrument with different
//! param values (the graded hammer mass of an 88-key grand).
//!
//! Each key's program is lowered on its own first (its `--param` overrides and `require`s
//! checked as usual), so constant folding has already reduced every expression of params
//! and numbers to one constant. Lowering is structural: the same source gives the same
//! value table and statement list whatever the param values, except for the folded
//! constants. [`share`] checks that, and turns every constant that differs between the keys
//! into a **run-time param**: a word of each key's param block, planned over the interval
//! the keys span ([`ParamDecl::runtime`]). Nothing derived from params is recomputed per
//! sample: the block holds the folded values themselves (`M_h·grav·l4`, not `M_h`), each
//! key's computed by the same fold as its own program's constant. A division by a run-time
//! param becomes a multiplication by a run-time reciprocal (the fixed-point plan turns a
//! division by a constant into a multiplication by its reciprocal in the same way), so the
//! per-sample code loads words and multiplies, never divides.
//!
//! Declarations that would have to differ between keys (a state range or initial value, a
//! sensor range computed from a param) cannot be shared: [`share`] says which, and the
//! caller compiles one program per parameter set as before.

use crate::ir::*;
use std::cmp::Ordering;
use std::collections::{BTreeMap, HashMap};

/// One program for several parameter sets of one instrument.
#[derive(Clone, Debug)]
pub struct Shared {
    /// The shared program: the first input's (its constants folded,
    /// `fixed::distribute::fold_constants`), with every differing constant a run-time param
    /// ([`ParamDecl::runtime`]) and each input's values of them in
    /// [`Program::runtime_keys`]. Plans exactly as the first input when all agree.
    pub program: Program,
    /// Number of input programs.
    keys: usize,
}

impl Shared {
    /// Per input program (in input order), the SI value of each run-time param of
    /// `program`, in [`Program::runtime_params`] order: [`Program::runtime_keys`], or one
    /// empty list per input when all agree.
    pub fn values(&self) -> Vec<Vec<f64>> {
        if self.program.runtime_keys.is_empty() {
            vec![Vec::new(); self.keys]
        } else {
            self.program.runtime_keys.clone()
        }
    }
}

/// Shares one program among `programs` (each the same instrument lowered with its own param
/// values; at least one).
///
/// Errors: a sentence saying what differs beyond constants (then each needs its own
/// program), or that `programs` is empty.
pub fn share(programs: &[Program]) -> Result<Shared, String> {
    // Constants folded first (`fixed::distribute::fold_constants`: chains, common values,
    // distributed factors): a folded constant that differs between keys (`h/I_h`,
    // `l3·h/I_h`) becomes one run-time param, not a run-time param times a constant. Keys
    // whose constants fold differently (a factor short for some keys only) share unfolded.
    // Each program folded on its own (in parallel: a graded keyboard is one program per key).
    use rayon::prelude::*;
    let folded: Vec<Program> = programs
        .par_iter()
        .map(crate::fixed::distribute::fold_constants)
        .collect();
    share_as_lowered(&folded).or_else(|_| share_as_lowered(programs))
}

/// Whether two keys' values of one folded constant differ: by more than the rounding of
/// their folds (10⁻¹² relative, far below a 32-bit word's resolution). Equal in exact
/// arithmetic but not in f64 — the piano's `M_h·grav·l4 · h/I_h`, which is `grav·h/l4`
/// for every hammer — they stay one constant, not a run-time param.
fn differs(a: f64, b: f64) -> bool {
    // Not "≤ the rounding": a NaN difference (an infinite value) differs too.
    let within = (a - b).abs().partial_cmp(&(1e-12 * a.abs().max(b.abs())));
    a.to_bits() != b.to_bits() && !matches!(within, Some(Ordering::Less | Ordering::Equal))
}

fn share_as_lowered(programs: &[Program]) -> Result<Shared, String> {
    let Some(first) = programs.first() else {
        return Err("no programs to share".into());
    };
    for q in &programs[1..] {
        same_shape(first, q)?;
    }
    let mut p = first.clone();
    // The values each differing constant takes, per program.
    let mut varying: BTreeMap<usize, Vec<f64>> = BTreeMap::new();
    for i in 0..p.values.len() {
        let vals: Vec<f64> = programs
            .iter()
            .map(|q| match q.values[i].op {
                Op::Const(c) => c,
                Op::Param(id) => q.params[id.index()].value,
                _ => f64::NAN,
            })
            .collect();
        let is_const = matches!(p.values[i].op, Op::Const(_) | Op::Param(_));
        if is_const && vals.iter().any(|&v| differs(v, vals[0])) {
            varying.insert(i, vals);
        }
    }
    if varying.is_empty() {
        return Ok(Shared {
            program: p,
            keys: programs.len(),
        });
    }
    // Divisions by a differing constant of one sign: multiplications by its reciprocal.
    let mut before: HashMap<usize, usize> = HashMap::new();
    let mut recip_of: HashMap<usize, usize> = HashMap::new();
    for i in 0..p.values.len() {
        let Op::Arith(ArithOp::Div, x, y) = p.values[i].op else {
            continue;
        };
        let Some(vals) = varying.get(&y.index()) else {
            continue;
        };
        let positive = vals.iter().all(|&v| v > 0.0);
        let negative = vals.iter().all(|&v| v < 0.0);
        if !(positive || negative) {
            continue;
        }
        let recip: Vec<f64> = vals.iter().map(|v| 1.0 / v).collect();
        let Ty::Real(dim) = p.values[y.index()].ty else {
            continue;
        };
        let n = p.values.len();
        p.values.push(ValueData {
            op: Op::Const(recip[0]),
            ty: Ty::Real(crate::units::Dim::NONE / dim),
            span: p.values[y.index()].span.clone(),
        });
        varying.insert(n, recip);
        p.values[i].op = Op::Arith(ArithOp::Mul, x, Value(n as u32));
        before.insert(i, n);
        recip_of.insert(n, y.index());
    }
    if !before.is_empty() {
        p.body = insert_defs(&p.body, &before);
    }
    // Only constants something still reads need a word.
    let referenced = referenced(&p);
    let names: Vec<String> = p
        .params
        .iter()
        .enumerate()
        .filter(|(k, _)| {
            programs
                .iter()
                .any(|q| q.params[*k].value.to_bits() != first.params[*k].value.to_bits())
        })
        .map(|(_, d)| d.name.clone())
        .collect();
    let from = names.join(", ");
    // Run-time params in declaration order, with their values per program.
    let mut runtime: Vec<(ParamId, Vec<f64>)> = Vec::new();
    for (&i, vals) in &varying {
        if !referenced[i] {
            continue;
        }
        let hull = (
            vals.iter().copied().fold(f64::INFINITY, f64::min),
            vals.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        );
        let id = match p.values[i].op {
            Op::Param(id) if p.params[id.index()].runtime.is_none() => {
                p.params[id.index()].runtime = Some(hull);
                id
            }
            Op::Param(id) => {
                // Already made run-time by another value reading the same param.
                debug_assert!(runtime.iter().any(|(r, _)| *r == id));
                continue;
            }
            _ => {
                let Ty::Real(dim) = p.values[i].ty else {
                    continue;
                };
                let id = ParamId(p.params.len() as u32);
                let name = match recip_of.get(&i) {
                    Some(y) => format!("1/v{y} of {from}"),
                    None => format!("v{i} of {from}"),
                };
                p.params.push(ParamDecl {
                    name,
                    dim,
                    value: vals[0],
                    span: p.values[i].span.clone(),
                    runtime: Some(hull),
                });
                p.values[i].op = Op::Param(id);
                id
            }
        };
        runtime.push((id, vals.clone()));
    }
    runtime.sort_by_key(|(id, _)| *id);
    p.runtime_keys = (0..programs.len())
        .map(|k| runtime.iter().map(|(_, v)| v[k]).collect())
        .collect();
    Ok(Shared {
        program: p,
        keys: programs.len(),
    })
}

/// `body` with `Def(n)` inserted before each `Def(i)` of `before` (`i → n`).
fn insert_defs(body: &[Stmt], before: &HashMap<usize, usize>) -> Vec<Stmt> {
    rebuild_stmts(body, &mut |s, out| {
        if let Stmt::Def(v) = s {
            if let Some(&n) = before.get(&v.index()) {
                out.push(Stmt::Def(Value(n as u32)));
            }
        }
        out.push(s.clone());
    })
}

/// Whether each value is read: by a statement other than its definition, or by the
/// operation of a value the body defines (folded constants and values a fold left
/// undefined read nothing).
fn referenced(p: &Program) -> Vec<bool> {
    let mut r = vec![false; p.values.len()];
    let defined = defined_values(&p.body, p.values.len());
    for (vd, _) in p.values.iter().zip(&defined).filter(|(_, d)| **d) {
        for x in vd.op.operands() {
            r[x.index()] = true;
        }
    }
    walk_stmts(&p.body, &mut |s| {
        s.reads().iter().for_each(|v| r[v.index()] = true)
    });
    r
}

/// Whether `a` and `b` are the same program but for the values of constants and params.
fn same_shape(a: &Program, b: &Program) -> Result<(), String> {
    let differ = |what: &str| Err(format!("`{}`: {what} differ between the keys", a.name));
    if a.name != b.name || a.sample_rate_hz != b.sample_rate_hz {
        return differ("the instruments");
    }
    if a.sensors != b.sensors {
        return differ("sensor declarations (a range computed from a param?)");
    }
    if a.states != b.states {
        return differ("state declarations (a range or initial value computed from a param?)");
    }
    if a.modes != b.modes
        || a.forces != b.forces
        || a.outputs != b.outputs
        || a.events != b.events
        || a.edges != b.edges
        || a.force_axes != b.force_axes
    {
        return differ("declarations");
    }
    if a.params.len() != b.params.len()
        || a.params
            .iter()
            .zip(&b.params)
            .any(|(x, y)| x.name != y.name || x.dim != y.dim || x.runtime.is_some())
    {
        return differ("params");
    }
    if a.body != b.body || a.values.len() != b.values.len() {
        return differ("the per-sample code (an array size or loop count from a param?)");
    }
    for (x, y) in a.values.iter().zip(&b.values) {
        let same_op = match (&x.op, &y.op) {
            (Op::Const(_), Op::Const(_)) => true,
            (o, q) => o == q,
        };
        if !same_op || x.ty != y.ty {
            return differ("the per-sample code");
        }
    }
    Ok(())
}
