//! The discrete state of a run, sample by sample: every branch decision of the update —
//! each `if`/`on`/`while` body's condition, each `if … else` expression's condition (a
//! Heaviside contact, a lever's `l3`), each `on` handler's remembered edge and each mode's
//! variant — as one bit per decision, so that the contract's switch clause
//! ([`super::ContractCheck::switches`]) can tell where the f64 and the fixed-point runs are
//! in different discrete states.
//!
//! The f64 reference runs the lowered program and the fixed engines the planned one
//! ([`crate::fixed::FixedProgram::program`]), whose values are renumbered by the passes
//! before the plan (`common.rs`, `recip.rs`, `chains.rs`). A decision is therefore named by
//! what survives those passes: its kind, its source span (the `if … else` expression's, or
//! the edge's handler; a body by its rank among the bodies, which the passes keep in order
//! while a condition may become an equal one from elsewhere), the bodies around it and its
//! rank among the decisions of that kind and place in body order (a component's instances
//! share spans). A decision of
//! one program with no partner in the other (`common.rs` computes two equal conditions
//! once: a `let` read in a handler's body and outside it is lowered twice) is not
//! compared: its partner's bit is the same decision. `min`/`max` are not decisions here: they are continuous, so a
//! sample apart they move the force by no more than the per-sample error does.

use crate::ast::Span;
use crate::ir::{EdgeId, ModeId, Op, Program, Stmt, Value};

/// What a decision is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Kind {
    /// The condition of an `if`/`on`/`while` body (the body runs).
    Body,
    /// The condition of an `if … else` expression (the first arm is taken).
    Select,
    /// The remembered condition of an `on` handler (its edge memory is set).
    Edge(EdgeId),
    /// A mode is in a variant.
    Mode(ModeId, u32),
}

/// One decision of a program's update.
#[derive(Clone, Debug)]
pub struct Site {
    /// Its kind.
    pub kind: Kind,
    /// The truth value deciding it (none for a mode).
    cond: Option<Value>,
    /// The conditions of the `if` bodies around it, outermost first: it is decided this
    /// sample only when all hold (else its bit is 0).
    guards: Vec<Value>,
    /// Their ranks among the program's bodies (part of the decision's name).
    place: Vec<usize>,
    /// The source span of the `if … else` expression, of the handler (an edge) or of the
    /// mode; a body's rank `r` as the empty span `r..r`.
    pub span: Span,
}

impl Site {
    /// The truth value deciding it (none for a mode, which follows from the bodies that set
    /// it).
    pub fn cond(&self) -> Option<Value> {
        self.cond
    }

    /// The decision in words, for a violation: its kind and source span (byte offsets).
    pub fn describe(&self, p: &Program) -> String {
        let at = format!("source bytes {}..{}", self.span.start, self.span.end);
        match &self.kind {
            Kind::Body => {
                let c = self.cond.map(|c| p.values[c.index()].span.clone());
                let c = c.map_or(String::new(), |c| {
                    format!(" at source bytes {}..{}", c.start, c.end)
                });
                format!(
                    "the condition of `if`/`on`/`while` body {}{c}",
                    self.span.start
                )
            }
            Kind::Select => format!("the condition of an `if … else` expression at {at}"),
            Kind::Edge(_) => format!("the edge memory of the `on` handler at {at}"),
            Kind::Mode(m, v) => {
                let d = &p.modes[m.index()];
                let variant = d.variants.get(*v as usize).map_or("?", String::as_str);
                format!("mode `{}` in `{variant}`", d.name)
            }
        }
    }
}

/// Every decision of `p`'s update, in body order, then the modes' variants.
pub fn sites(p: &Program) -> Vec<Site> {
    fn walk(
        p: &Program,
        stmts: &[Stmt],
        guards: &mut Vec<(Value, usize)>,
        bodies: &mut usize,
        out: &mut Vec<Site>,
    ) {
        let site = |kind, cond: Value, span: &Span, guards: &Vec<(Value, usize)>| Site {
            kind,
            cond: Some(cond),
            guards: guards.iter().map(|g| g.0).collect(),
            place: guards.iter().map(|g| g.1).collect(),
            span: span.clone(),
        };
        for s in stmts {
            match s {
                Stmt::Def(v) => {
                    if let Op::Select(c, _, _) = p.values[v.index()].op {
                        out.push(site(Kind::Select, c, &p.values[v.index()].span, guards));
                    }
                }
                Stmt::SetEdge(e, v) => {
                    out.push(site(Kind::Edge(*e), *v, &p.edges[e.index()].span, guards))
                }
                Stmt::If(c, body) => {
                    // A body is named by its rank: the passes keep every `if` in order, but
                    // its condition may be an equal one from elsewhere (`common.rs`).
                    out.push(site(Kind::Body, *c, &(*bodies..*bodies), guards));
                    guards.push((*c, *bodies));
                    *bodies += 1;
                    walk(p, body, guards, bodies, out);
                    guards.pop();
                }
                _ => {}
            }
        }
    }
    let mut out = Vec::new();
    walk(p, &p.body, &mut Vec::new(), &mut 0, &mut out);
    for (m, d) in p.modes.iter().enumerate() {
        for v in 0..d.variants.len() as u32 {
            out.push(Site {
                kind: Kind::Mode(ModeId(m as u32), v),
                cond: None,
                guards: Vec::new(),
                place: Vec::new(),
                span: d.span.clone(),
            });
        }
    }
    out
}

/// Per force term of `p`: whether its value depends on the update's state — a state, a mode
/// or an edge, through any chain of operations. The other terms read only sensors, their
/// derivatives, params and constants, which both runs share sample by sample (the same
/// sensor words), so a switch does not move them.
pub fn state_driven_terms(p: &Program) -> Vec<bool> {
    let n = p.values.len();
    let mut driven = vec![false; n];
    // Operands are defined before their readers; passes until nothing changes cover any
    // order all the same.
    loop {
        let mut changed = false;
        for i in 0..n {
            if driven[i] {
                continue;
            }
            let d = match &p.values[i].op {
                Op::State(_) | Op::Mode(_) | Op::Edge(_) => true,
                Op::Neg(x) | Op::Not(x) | Op::Call(_, x, None) => driven[x.index()],
                Op::Arith(_, x, y)
                | Op::Cmp(_, x, y)
                | Op::And(x, y)
                | Op::Or(x, y)
                | Op::Call(_, x, Some(y)) => driven[x.index()] || driven[y.index()],
                Op::Select(c, x, y) => driven[c.index()] || driven[x.index()] || driven[y.index()],
                Op::Const(_)
                | Op::BoolConst(_)
                | Op::Variant(..)
                | Op::Param(_)
                | Op::Sensor(_)
                | Op::Deriv(..) => false,
            };
            if d {
                driven[i] = true;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    let mut terms = vec![false; p.forces.len()];
    crate::ir::walk_stmts(&p.body, &mut |s| {
        if let Stmt::Force(f, v) = s {
            terms[f.index()] |= driven[v.index()];
        }
    });
    terms
}

/// A decision's name: kind, span, the bodies around it, rank.
type Key = (Kind, Span, Vec<usize>, usize);

/// Each decision's name: (kind, span, the bodies around it, rank among the decisions of
/// that kind and place).
fn keys(sites: &[Site]) -> Vec<Key> {
    let mut out: Vec<Key> = Vec::with_capacity(sites.len());
    for s in sites {
        let rank = out
            .iter()
            .filter(|(k, sp, g, _)| *k == s.kind && *sp == s.span && *g == s.place)
            .count();
        out.push((s.kind.clone(), s.span.clone(), s.place.clone(), rank));
    }
    out
}

/// The decisions the two programs share, as (index in `a`, index in `b`), in `a`'s order.
pub fn matched(a: &[Site], b: &[Site]) -> Vec<(usize, usize)> {
    let kb = keys(b);
    keys(a)
        .into_iter()
        .enumerate()
        .filter_map(|(i, k)| kb.iter().position(|x| *x == k).map(|j| (i, j)))
        .collect()
}

/// Words of a sample's signature over `n` decisions.
pub fn words(n: usize) -> usize {
    n.div_ceil(64)
}

/// Writes the signature of one sample — bit `i` set when decision `i` of `sites` holds —
/// into `out` ([`words`] long), reading each truth value with `truth` (the value as the
/// engine left it this sample) and the modes' variants from `modes`.
pub fn signature(sites: &[Site], truth: impl Fn(Value) -> bool, modes: &[u32], out: &mut [u64]) {
    out.iter_mut().for_each(|w| *w = 0);
    for (i, s) in sites.iter().enumerate() {
        let on = match (&s.kind, s.cond) {
            (Kind::Mode(m, v), _) => modes.get(m.index()) == Some(v),
            (_, Some(c)) => s.guards.iter().all(|&g| truth(g)) && truth(c),
            (_, None) => false,
        };
        if on {
            out[i / 64] |= 1 << (i % 64);
        }
    }
}

/// Whether bit `i` of a signature is set.
pub fn bit(sig: &[u64], i: usize) -> bool {
    sig[i / 64] >> (i % 64) & 1 == 1
}
