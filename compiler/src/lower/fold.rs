//! Constant folding: a pure operation whose operands are all constants becomes one constant.
//!
//! The folded value is computed with the interpreter's own arithmetic
//! ([`crate::interp::eval_op`]), so the f64 meaning of the program does not change; the
//! fixed-point build gains a single, once-rounded constant instead of a chain of rounded
//! operations, and a division by a constant expression (`peak / (theta2 - theta1)`) becomes
//! a multiplication by its reciprocal instead of a run-time division. Params stay `Param`
//! values (the IR keeps their names); truth-valued and mode-valued results are not folded.

use crate::ir::*;

/// Folds constant subexpressions of `p` in place.
pub fn fold_constants(p: &mut Program) {
    let mut konst: Vec<Option<f64>> = vec![None; p.values.len()];
    let body = std::mem::take(&mut p.body);
    walk(p, &body, &mut konst);
    p.body = body;
}

fn walk(p: &mut Program, stmts: &[Stmt], konst: &mut [Option<f64>]) {
    for s in stmts {
        match s {
            Stmt::Def(v) => {
                let i = v.index();
                let op = p.values[i].op.clone();
                konst[i] = match op {
                    Op::Const(c) => Some(c),
                    Op::Param(id) => Some(p.params[id.index()].value),
                    Op::Neg(_) | Op::Arith(..) | Op::Call(..) | Op::Select(..) => {
                        let operands = op.operands();
                        if operands.iter().all(|o| konst[o.index()].is_some())
                            && matches!(p.values[i].ty, Ty::Real(_))
                        {
                            let c = crate::interp::eval_op(
                                &op,
                                |x| konst[x.index()].unwrap_or(f64::NAN),
                                |id| p.params[id.index()].value,
                                &|_| f64::NAN,
                            );
                            p.values[i].op = Op::Const(c);
                            Some(c)
                        } else {
                            None
                        }
                    }
                    _ => None,
                };
            }
            Stmt::If(_, body) => walk(p, body, konst),
            _ => {}
        }
    }
}
