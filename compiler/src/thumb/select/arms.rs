//! Which `select`s become branches, and where each value is then computed.
//!
//! A branch-free `select` computes both arms and picks one, so the worst path pays for
//! both. Where the arms cost more than the branch, the select becomes a diamond (its
//! condition a compare-and-branch), and each value used only by one arm — transitively — is
//! computed inside that arm: the WCET analysis then takes the longer arm, not the sum. A
//! value's *home* is the arm `(select, then?)` of the innermost branching select that
//! contains every use of it (the lowest common ancestor of its uses in the tree of arms),
//! or `None`: computed where the IR defines it. A read of a state, mode or edge word is
//! moved only where no assignment lies between its definition and the place the arm is
//! emitted (it would read the new word). Every other operation is a pure function of its
//! operands, so moving it into an arm changes no bits.

use super::*;
use std::collections::HashMap;

/// An arm: the select and whether it is the `then` side.
pub(super) type Node = (Value, bool);

/// The plan: branching selects and the home of every value.
pub(super) struct Arms {
    /// Per value: a select emitted as a diamond.
    pub branchy: Vec<bool>,
    /// Per value: the arm it is computed in (`None`: in place).
    pub home: Vec<Option<Node>>,
    /// Per arm: its values, in program order.
    pub members: HashMap<Node, Vec<Value>>,
}

/// Cycles an arm must cost at least (both arms) for its select to branch: a diamond costs
/// its compare-and-branch and one `B` where the branch-free select costs its 0/1 word and
/// three or four ALU operations.
const MIN_ARM_CYCLES: u32 = 2;

/// Rough Cortex-M0+ cycles of one value's definition (the plan's product estimates).
fn cost(fp: &FixedProgram, v: Value) -> u32 {
    let p = &fp.program;
    if fp.param_word_of(v).is_some() {
        return 2;
    }
    let mul = |v: Value| fp.mul_kind[v.index()].unwrap_or(MulKind::Wide).cycles();
    match &p.values[v.index()].op {
        Op::Const(_) | Op::Param(_) | Op::BoolConst(_) | Op::Variant(..) => 0,
        Op::Sensor(_) => 1,
        Op::Deriv(..) => 6,
        Op::State(_) | Op::Mode(_) | Op::Edge(_) => 2,
        Op::Neg(_) | Op::Not(_) => 1,
        Op::Arith(ArithOp::Add | ArithOp::Sub, ..) => 2,
        Op::Arith(ArithOp::Mul, ..) => mul(v),
        Op::Arith(ArithOp::Div, ..) => {
            if fp.recip[v.index()].is_some() {
                mul(v)
            } else {
                120
            }
        }
        Op::Cmp(..) => 3,
        Op::And(..) | Op::Or(..) => 2,
        Op::Select(..) => 4,
        Op::Call(Builtin::Exp | Builtin::Sqrt, ..) => 60,
        Op::Call(..) => 5,
    }
}

/// The values of `p` in program order, the number of state, mode and edge assignments
/// before each value's definition, and which values statements read.
fn walk(p: &Program) -> (Vec<Value>, Vec<u32>, Vec<bool>) {
    let n = p.values.len();
    let (mut order, mut setc, mut stmt_used) = (Vec::new(), vec![0u32; n], vec![false; n]);
    let mut sets = 0u32;
    crate::ir::walk_stmts(&p.body, &mut |s| {
        for v in s.reads() {
            stmt_used[v.index()] = true;
        }
        match s {
            Stmt::Def(v) => {
                order.push(*v);
                setc[v.index()] = sets;
            }
            Stmt::SetState(..) | Stmt::SetEdge(..) | Stmt::SetMode(..) => sets += 1,
            _ => {}
        }
    });
    (order, setc, stmt_used)
}

/// Decides the branching selects of a program and the home of each value.
pub(super) fn plan(fp: &FixedProgram, used: &[bool]) -> Arms {
    let p = &fp.program;
    let n = p.values.len();
    let (order, setc, stmt_used) = walk(p);
    let mut users: Vec<Vec<Value>> = vec![Vec::new(); n];
    for &v in &order {
        if used[v.index()] {
            for x in p.values[v.index()].op.operands() {
                users[x.index()].push(v);
            }
        }
    }
    let candidate: Vec<bool> = (0..n)
        .map(|i| {
            used[i]
                && matches!(p.values[i].ty, Ty::Real(_))
                && matches!(p.values[i].op, Op::Select(_, x, y) if x != y)
        })
        .collect();
    let homes = |branchy: &[bool]| -> Vec<Option<Node>> {
        let mut home: Vec<Option<Node>> = vec![None; n];
        for &v in order.iter().rev() {
            if !used[v.index()] || stmt_used[v.index()] {
                continue;
            }
            let chain = |mut a: Option<Node>, home: &[Option<Node>]| {
                let mut c = Vec::new();
                while let Some(x) = a {
                    c.push(x);
                    a = home[x.0.index()];
                }
                c
            };
            let mut h: Option<Vec<Node>> = None; // the ancestors of the common node
            let mut root = false;
            for &u in &users[v.index()] {
                let site = match p.values[u.index()].op {
                    Op::Select(c, x, y) if branchy[u.index()] && v != c && (v == x) != (v == y) => {
                        Some((u, v == x))
                    }
                    _ => home[u.index()],
                };
                let Some(site) = site else {
                    root = true;
                    break;
                };
                let c = chain(Some(site), &home);
                h = Some(match h {
                    None => c,
                    Some(prev) => prev.into_iter().filter(|x| c.contains(x)).collect(),
                });
            }
            let node = if root {
                None
            } else {
                h.and_then(|c| c.first().copied())
            };
            // A state, mode or edge read moves only where no assignment lies between.
            let node = node.filter(|&(s, _)| {
                if !matches!(
                    p.values[v.index()].op,
                    Op::State(_) | Op::Mode(_) | Op::Edge(_)
                ) {
                    return true;
                }
                let mut top = s;
                while let Some((t, _)) = home[top.index()] {
                    top = t;
                }
                setc[v.index()] == setc[top.index()]
            });
            home[v.index()] = node;
        }
        home
    };
    let members = |home: &[Option<Node>]| {
        let mut m: HashMap<Node, Vec<Value>> = HashMap::new();
        for &v in &order {
            if let Some(h) = home[v.index()] {
                m.entry(h).or_default().push(v);
            }
        }
        m
    };
    // First every candidate branches; an arm's cost is its values' (a branching select in
    // it: its longer arm); a select keeps branching where both arms cost enough.
    let home0 = homes(&candidate);
    let m0 = members(&home0);
    let mut memo: HashMap<Node, u32> = HashMap::new();
    fn arm_cost(
        fp: &FixedProgram,
        node: Node,
        m: &HashMap<Node, Vec<Value>>,
        candidate: &[bool],
        memo: &mut HashMap<Node, u32>,
    ) -> u32 {
        if let Some(&c) = memo.get(&node) {
            return c;
        }
        let c = m.get(&node).map_or(0, |vs| {
            vs.iter()
                .map(|&v| {
                    if candidate[v.index()] {
                        3 + arm_cost(fp, (v, true), m, candidate, memo).max(arm_cost(
                            fp,
                            (v, false),
                            m,
                            candidate,
                            memo,
                        ))
                    } else {
                        cost(fp, v)
                    }
                })
                .sum()
        });
        memo.insert(node, c);
        c
    }
    let branchy: Vec<bool> = (0..n)
        .map(|i| {
            candidate[i] && {
                let v = Value(i as u32);
                let t = arm_cost(fp, (v, true), &m0, &candidate, &mut memo);
                let e = arm_cost(fp, (v, false), &m0, &candidate, &mut memo);
                // A condition only this select reads is a compare-and-branch, no 0/1 word:
                // then one costly arm is enough.
                let Op::Select(c, ..) = p.values[i].op else {
                    unreachable!("candidates are selects")
                };
                let own = users[c.index()].len() == 1
                    && !stmt_used[c.index()]
                    && matches!(
                        p.values[c.index()].op,
                        Op::Cmp(..) | Op::And(..) | Op::Or(..) | Op::Not(_)
                    );
                t.min(e) >= MIN_ARM_CYCLES || (own && t.max(e) >= MIN_ARM_CYCLES)
            }
        })
        .collect();
    let home = homes(&branchy);
    let members = members(&home);
    Arms {
        branchy,
        home,
        members,
    }
}

impl Arms {
    /// The conditions of the branching selects (tested by compare-and-branch where they
    /// have no other use).
    pub(super) fn conditions(&self, p: &Program) -> Vec<Value> {
        (0..self.branchy.len())
            .filter(|&i| self.branchy[i])
            .filter_map(|i| match p.values[i].op {
                Op::Select(c, ..) => Some(c),
                _ => None,
            })
            .collect()
    }

    /// The estimated cycles of arm `node` (for the order of a diamond's arms).
    pub(super) fn cost(&self, fp: &FixedProgram, node: Node) -> u32 {
        self.members.get(&node).map_or(0, |vs| {
            vs.iter()
                .map(|&v| {
                    if self.branchy[v.index()] {
                        3 + self.cost(fp, (v, true)).max(self.cost(fp, (v, false)))
                    } else {
                        cost(fp, v)
                    }
                })
                .sum()
        })
    }
}
