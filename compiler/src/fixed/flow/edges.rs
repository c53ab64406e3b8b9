//! `on` handlers that behave as `while` handlers: their edge memory is provably false
//! whenever their condition holds, so no engine needs to keep it.
//!
//! An `on c { body }` runs its body when `c` holds and held not at the previous sample; a
//! `while c` whenever `c` holds. They differ only where `c` holds at two consecutive
//! evaluations. The proof here is by a mode: `c` requires `m == v` (an `and`-ed term), the
//! body certainly leaves `m` at another variant, and every other handler that may set `m`
//! back to `v` cannot run where it would matter — after the body in the same sample (the
//! flow fact `(this, later)` of [`super::exclusions`]: the later condition is false when
//! this body ran), or before the condition's next evaluation in the next sample (the fact
//! `(earlier, this)`: this condition is false in a sample where the earlier body ran). Then
//! by induction over the samples: if `c` held at sample n − 1, the body ran there (the edge
//! was false, by the induction), left `m` ≠ `v`, and nothing set `m = v` again before the
//! evaluation at sample n, so `c` is false there. The escapement's phase changes are such:
//! `on phase == ready and x >= theta3 { phase = escaped }` cannot hold twice in a row,
//! since only the re-arm (`x < theta1`, excluded with `x >= theta3`) sets `ready` again.
//!
//! The facts are about the fixed-point program's meaning (the flow facts hold for every
//! engine), so the rewrite ([`level_edges`]) is made once, on the [`FixedProgram`] every
//! fixed engine runs: the handler's test loses its `not edge` term and the edge is never
//! stored. Its [`EdgeDecl`] stays (edge numbers and the state layout unchanged, the byte
//! keeps its initial 0), so the decisions of the fixed program still match those of the
//! f64 program one by one (`contract::switches`).

use super::super::FixedProgram;
use crate::ir::*;
use std::collections::HashSet;

/// Where `fire` is `c and not edge(e)` (either order): `c` and the `not` value.
pub(crate) fn edge_fire(p: &Program, e: EdgeId, fire: Value) -> Option<(Value, Value)> {
    let Op::And(x, y) = p.values[fire.index()].op else {
        return None;
    };
    let was_false = |v: Value| match p.values[v.index()].op {
        Op::Not(prev) => p.values[prev.index()].op == Op::Edge(e),
        _ => false,
    };
    if was_false(y) {
        Some((x, y))
    } else if was_false(x) {
        Some((y, x))
    } else {
        None
    }
}

/// The `m == v` terms among the `and`-ed terms of `c` (a mode read against a variant).
fn mode_terms(p: &Program, c: Value) -> Vec<(ModeId, u32)> {
    let mut out = Vec::new();
    let mut stack = vec![c];
    while let Some(v) = stack.pop() {
        match p.values[v.index()].op {
            Op::And(x, y) => {
                stack.push(x);
                stack.push(y);
            }
            Op::Cmp(CmpOp::Eq, x, y) => match (&p.values[x.index()].op, &p.values[y.index()].op) {
                (Op::Mode(m), Op::Variant(n, i)) | (Op::Variant(n, i), Op::Mode(m)) if m == n => {
                    out.push((*m, *i))
                }
                _ => {}
            },
            _ => {}
        }
    }
    out
}

/// Whether a `SetMode(m, v)` is anywhere in `stmts` (`if` bodies included).
fn may_set(stmts: &[Stmt], m: ModeId, v: u32) -> bool {
    let mut found = false;
    walk_stmts(stmts, &mut |s| {
        found |= matches!(s, Stmt::SetMode(n, i) if *n == m && *i == v);
    });
    found
}

/// Whether `body` certainly leaves mode `m` at a variant other than `v`: its last
/// top-level `SetMode(m, _)` sets another variant, and nothing after it (an `if` inside
/// the body included) sets `v`.
fn leaves_other(body: &[Stmt], m: ModeId, v: u32) -> bool {
    let mut other = false;
    for s in body {
        match s {
            Stmt::SetMode(n, i) if *n == m => other = *i != v,
            Stmt::If(_, b) if may_set(b, m, v) => other = false,
            _ => {}
        }
    }
    other
}

/// How many times each value is read: operands of other values and statements' reads.
fn readers(p: &Program) -> Vec<u32> {
    let mut n = vec![0u32; p.values.len()];
    let defined = defined_values(&p.body, p.values.len());
    for (vd, _) in p.values.iter().zip(&defined).filter(|(_, d)| **d) {
        for x in vd.op.operands() {
            n[x.index()] += 1;
        }
    }
    walk_stmts(&p.body, &mut |s| {
        s.reads().iter().for_each(|v| n[v.index()] += 1)
    });
    n
}

/// The top-level `on` handlers of `fp` (as `(k, e)`: `SetEdge(e, c)` at body index `k`, its
/// `If(c and not edge(e), …)` at `k + 1`) whose edge is false whenever `c` holds (the module
/// comment's proof), and whose edge, its `not` and the `and` nothing else reads.
pub fn level_handlers(fp: &FixedProgram) -> Vec<(usize, EdgeId)> {
    let p = &fp.program;
    let candidates: Vec<(usize, EdgeId, Value)> = (0..p.body.len().saturating_sub(1))
        .filter_map(|k| match (&p.body[k], &p.body[k + 1]) {
            (Stmt::SetEdge(e, c), Stmt::If(fire, _))
                if edge_fire(p, *e, *fire).is_some_and(|(x, _)| x == *c) =>
            {
                Some((k, *e, *c))
            }
            _ => None,
        })
        .collect();
    if candidates.is_empty() {
        return Vec::new();
    }
    let n = readers(p);
    let ex: HashSet<(u32, u32)> = super::exclusions(fp).into_iter().collect();
    let mut out = Vec::new();
    for (k, e, c) in candidates {
        let i = k + 1;
        let Stmt::If(fire, body) = &p.body[i] else {
            continue;
        };
        let Some((_, not)) = edge_fire(p, e, *fire) else {
            continue;
        };
        let Op::Not(prev) = p.values[not.index()].op else {
            continue;
        };
        // The edge is read only by this handler's test.
        if n[prev.index()] != 1 || n[not.index()] != 1 || n[fire.index()] != 1 {
            continue;
        }
        let level = mode_terms(p, c).into_iter().any(|(m, v)| {
            leaves_other(body, m, v)
                && p.body.iter().enumerate().all(|(j, s)| match s {
                    Stmt::SetMode(n, w) => !(*n == m && *w == v),
                    Stmt::If(_, b) if j != i && may_set(b, m, v) => {
                        let pair = if j > i { (i, j) } else { (j, i) };
                        ex.contains(&(pair.0 as u32, pair.1 as u32))
                    }
                    _ => true,
                })
        });
        if level {
            out.push((k, e));
        }
    }
    out
}

/// Rewrites the handlers [`level_handlers`] finds as `while` handlers: `SetEdge(e, c);
/// If(c and not edge(e), body)` becomes `If(c, body)`, and the definitions of the edge's
/// read, its `not` and the `and` (read by nothing now) go. Returns the edges no longer kept.
pub fn level_edges(fp: &mut FixedProgram) -> Vec<EdgeId> {
    let found = level_handlers(fp);
    if found.is_empty() {
        return Vec::new();
    }
    let p = &mut fp.program;
    let mut gone: HashSet<Value> = HashSet::new();
    let mut drop_stmt: HashSet<usize> = HashSet::new();
    for &(k, e) in &found {
        let Stmt::SetEdge(_, c) = p.body[k] else {
            unreachable!("a level handler starts with its edge store")
        };
        let Stmt::If(fire, _) = p.body[k + 1] else {
            unreachable!("a level handler's test follows its edge store")
        };
        let (_, not) = edge_fire(p, e, fire).expect("a level handler fires on `c and not edge`");
        let Op::Not(prev) = p.values[not.index()].op else {
            unreachable!("checked by level_handlers")
        };
        gone.extend([fire, not, prev]);
        drop_stmt.insert(k);
        if let Stmt::If(cond, _) = &mut p.body[k + 1] {
            *cond = c;
        }
    }
    let body = std::mem::take(&mut p.body);
    p.body = body
        .into_iter()
        .enumerate()
        .filter(|(k, s)| !drop_stmt.contains(k) && !matches!(s, Stmt::Def(v) if gone.contains(v)))
        .map(|(_, s)| s)
        .collect();
    found.into_iter().map(|(_, e)| e).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixed::interp::FixedInstance;
    use crate::fixed::PlanConfig;

    /// The program of `src`, planned with the rewrite (`level`) or without it (by the
    /// error analysis alone: no simulated search).
    fn fixed(src: &str, level: bool) -> FixedProgram {
        let c = crate::compile(src, &crate::lower::Config::default()).expect("compiles");
        let config = PlanConfig {
            level_edges: level,
            simulate: false,
            ..PlanConfig::default()
        };
        FixedProgram::with_config(&c.program, &config)
    }

    /// The edges a body stores.
    fn stored(p: &Program) -> Vec<u32> {
        let mut v = Vec::new();
        walk_stmts(&p.body, &mut |s| {
            if let Stmt::SetEdge(e, _) = s {
                v.push(e.0)
            }
        });
        v
    }

    /// A three-phase latch: `ready → armed` on `x > 5 mm`, `armed → ready` on `x < 2 mm`,
    /// `armed → fired` on `x > 8 mm`; two handlers that change no mode.
    const LATCH: &str = "instrument t {\n sensor x: m in [0 mm, 10 mm]\n mode ph { ready, armed, fired } = ready\n state a = 0 in [0, 1]\n on ph == ready and x > 5 mm { ph = armed }\n on ph == armed and x < 2 mm { ph = ready }\n on ph == armed and x > 8 mm { ph = fired\n a = 1 }\n on x > 9 mm { a = 0.5 }\n on ph == fired and x < 9.5 mm { a = 0.25 }\n force f = a * 1 N\n}\n";

    #[test]
    fn a_mode_change_that_only_excluded_handlers_undo_needs_no_edge() {
        // `ready → armed` cannot hold twice in a row: only `x < 2 mm` sets `ready` again,
        // later in the sample, excluded by `x > 5 mm`. `armed → ready`: the way back to
        // `armed` is the first handler, before it in the next sample, whose `x > 5 mm`
        // excludes `x < 2 mm`. `armed → fired`: the first handler sets `armed` before it,
        // and `x > 5 mm` does not exclude `x > 8 mm`: kept (the pairwise facts do not see
        // that the first needs `ready`). `x > 9 mm` tests no mode, and the last handler
        // changes none: kept.
        let fp = fixed(LATCH, false);
        let found: Vec<u32> = level_handlers(&fp).iter().map(|x| x.1 .0).collect();
        assert_eq!(found, vec![0, 1]);
        assert_eq!(stored(&fp.program), vec![0, 1, 2, 3, 4]);
        let level = fixed(LATCH, true);
        assert_eq!(stored(&level.program), vec![2, 3, 4]);
        // The declarations stay (the state layout and the edge numbers are unchanged).
        assert_eq!(level.program.edges.len(), 5);
        assert!(level_handlers(&level).is_empty(), "nothing left to rewrite");
        crate::verify::verify(&level.program).expect("a well-formed program");
    }

    #[test]
    fn a_handler_that_keeps_its_condition_true_keeps_its_edge() {
        // The strike of the piano: `s >= 0.3` stays true after `s = 0.3`, and no mode is
        // tested. Nor may a body that sets the mode back: `ready → armed → ready`.
        let fp = fixed(
            "instrument t {\n sensor x: m in [0 mm, 10 mm]\n mode ph { ready, armed } = ready\n state s = 0 in [-1, 1]\n on s >= 0.3 { s = 0.3 }\n on ph == ready and x > 5 mm { ph = armed\n ph = ready }\n while x > 1 mm { s = s + 0.001 }\n force f = s * 1 N\n}\n",
            false,
        );
        assert!(level_handlers(&fp).is_empty(), "{:?}", level_handlers(&fp));
    }

    #[test]
    fn the_rewritten_program_runs_as_the_one_with_edges() {
        // The fixed interpreter over slow sweeps up and down and a jittered hold, with and
        // without the rewrite: the same forces, states and modes sample by sample.
        for src in [
            LATCH,
            include_str!("../../../../instruments/grand_piano.tactus"),
        ] {
            let (a, b) = (fixed(src, true), fixed(src, false));
            assert!(stored(&a.program).len() < stored(&b.program).len());
            let (mut ia, mut ib) = (FixedInstance::new(&a), FixedInstance::new(&b));
            let (lo, hi) = a.sensor_raw_range[0];
            for n in 0..6000 {
                let t = (n % 2000) as f64 / 2000.0;
                let u = if t < 0.5 { 2.0 * t } else { 2.0 - 2.0 * t };
                let jitter = ((n * 7919) % 13) as f64 / 13.0 - 0.5;
                let w = lo + ((hi - lo) as f64 * u + jitter * 40.0) as i32;
                let w = w.clamp(lo, hi);
                let (oa, ob) = (ia.step_raw(&[w]).clone(), ib.step_raw(&[w]).clone());
                assert_eq!(oa, ob, "{} sample {n}", a.program.name);
                assert_eq!(ia.states(), ib.states(), "sample {n}");
                assert_eq!(ia.modes(), ib.modes(), "sample {n}");
            }
        }
    }
}
