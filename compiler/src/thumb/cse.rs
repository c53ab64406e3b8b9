//! Machine instructions computed again from the same operands a few instructions after a
//! first computation that dominates them, replaced by the first one's register.
//!
//! The selector emits each IR value's sequence on its own, so two values that the plan
//! happens to compute alike (the piano's contact pulse and its decay time both scale
//! `max(ċ, 0)` by the same raw `ASRS #3; MULS #5`; two products splitting one word into its
//! 16-bit halves) repeat instructions. An arithmetic instruction (`ADDS`/`SUBS`, shifts,
//! `ANDS`/`ORRS`/`EORS`/`MULS`, `RSBS`/`MVNS`, `UXTH`) whose operands are registers the
//! selector defines once (or constants, compared by value: each use has its own `MOVS`) and
//! that an earlier instruction computed from the same operands is dropped and its register
//! renamed to the earlier one's — where that earlier one dominates it (the code branches
//! only forward: no label between is the target of a branch from before the first), at
//! most [`WINDOW`] instructions back (the longer live range stays short), and where the
//! flags the dropped instruction would set are dead ([`super::literals::flags_dead_after`]).
//! `ADCS`/`SBCS` read the flags and loads read memory: neither is shared.

use super::literals::flags_dead_after;
use super::mir::*;
use std::collections::HashMap;
use tactus_isa::decode::AluOp;

/// Instructions between a computation and a reuse of its register.
pub(crate) const WINDOW: usize = 24;

/// An operand as the key compares it: a known constant by value, else its register.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Opd {
    K(i32),
    R(V),
}

/// What an instruction computes, independent of its destination.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Key {
    AddSub(bool, Opd, Opd),
    AddSubI(bool, Opd, u8),
    Alu2(AluOp, Opd, Opd),
    Unary(AluOp, Opd),
    Sh(Shift, Opd, u8),
    Uxth(Opd),
}

/// Replaces dominated recomputations in `code` (see the module comment).
///
/// Each dropped instruction whose register a kept instruction reads lengthens the first
/// one's live range (a register held longer, a `MOV` or a spill where they run short):
/// it is shared only where it saves more than its own cycle — a `MULS` (whose constant's
/// `MOVS` goes too) or the end of a shared chain (the piano's `ASRS; MULS`). Others are
/// banned and the pass runs again without them, until none is.
pub(crate) fn share(code: &mut Vec<M>, nregs: u32) {
    let mut banned = vec![false; code.len()];
    loop {
        let (drop, rename) = plan(code, nregs, &banned);
        let mut reads_kept = std::collections::HashSet::new();
        for (m, _) in code.iter().zip(&drop).filter(|(_, d)| !**d) {
            reads_kept.extend(m.uses());
        }
        let mut again = false;
        for (j, m) in code.iter().enumerate().filter(|&(j, _)| drop[j]) {
            let d = m.def().expect("only definitions are shared");
            let chain = m.uses().iter().any(|u| rename.contains_key(u));
            let mul = matches!(m, M::Alu2 { op: AluOp::Mul, .. });
            if reads_kept.contains(&d) && !mul && !chain && matches!(m, M::Uxth { .. }) {
                banned[j] = true;
                again = true;
            }
        }
        if again {
            continue;
        }
        if rename.is_empty() {
            return;
        }
        remove_marked(code, &drop);
        for m in code.iter_mut() {
            for v in m.uses_mut() {
                if let Some(&n) = rename.get(v) {
                    *v = n;
                }
            }
        }
        return;
    }
}

/// The instructions to drop and the renaming of their registers, `banned` ones kept.
fn plan(code: &[M], nregs: u32, banned: &[bool]) -> (Vec<bool>, HashMap<V, V>) {
    let defs = def_counts(code, nregs);
    let once = |v: V| defs.get(v.0 as usize) == Some(&1);
    let konst: HashMap<V, i32> = code
        .iter()
        .filter_map(|m| match *m {
            M::Movi { d, imm } if once(d) => Some((d, imm)),
            _ => None,
        })
        .collect();
    let first_src = first_branch_sources(code);
    let mut avail: HashMap<Key, (V, usize)> = HashMap::new();
    let mut rename: HashMap<V, V> = HashMap::new();
    let mut drop = vec![false; code.len()];
    for (j, m) in code.iter().enumerate() {
        if let M::Label(l) = m {
            if let Some(&s) = first_src.get(&l.0) {
                avail.retain(|_, &mut (_, i)| s >= i);
            }
            continue;
        }
        let Some(d) = m.def().filter(|&d| once(d) && !banned[j]) else {
            continue;
        };
        let opd = |v: V| -> Option<Opd> {
            let v = *rename.get(&v).unwrap_or(&v);
            if let Some(&k) = konst.get(&v) {
                Some(Opd::K(k))
            } else {
                once(v).then_some(Opd::R(v))
            }
        };
        let key = match *m {
            M::AddSub { sub, a, b, .. } => {
                let (a, b) = (opd(a), opd(b));
                a.zip(b).map(|(a, b)| {
                    // Addition commutes.
                    let (a, b) = if sub { (a, b) } else { (a.min(b), a.max(b)) };
                    Key::AddSub(sub, a, b)
                })
            }
            M::AddSubI { sub, a, imm, .. } => opd(a).map(|a| Key::AddSubI(sub, a, imm)),
            M::Alu2 { op, a, m, .. } if !matches!(op, AluOp::Adc | AluOp::Sbc) => {
                opd(a).zip(opd(m)).map(|(a, b)| {
                    let (a, b) = if commutative(op) {
                        (a.min(b), a.max(b))
                    } else {
                        (a, b)
                    };
                    Key::Alu2(op, a, b)
                })
            }
            M::Unary { op, m, .. } => opd(m).map(|a| Key::Unary(op, a)),
            M::Sh { op, m, imm, .. } => opd(m).map(|a| Key::Sh(op, a, imm)),
            M::Uxth { m, .. } => opd(m).map(Key::Uxth),
            _ => None,
        };
        let Some(key) = key else { continue };
        match avail.get(&key) {
            Some(&(r, i))
                if j - i <= WINDOW
                    && (matches!(m, M::Uxth { .. }) || flags_dead_after(code, j)) =>
            {
                rename.insert(d, r);
                drop[j] = true;
            }
            _ => {
                avail.insert(key, (d, j));
            }
        }
    }
    (drop, rename)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same scaling of one word by the same constant, twice: the second `ASRS` and
    /// `MULS` go (their `MOVS` is left for the dead-code pass) and its reader reads the
    /// first product; behind a label a branch from before the first reaches, or where a
    /// branch reads the dropped instruction's flags, both stay.
    #[test]
    fn shares_dominated_recomputations_only() {
        let (x, s1, k1, p1, s2, k2, p2) = (V(0), V(1), V(2), V(3), V(4), V(5), V(6));
        let seq = |s, k, p| {
            vec![
                M::Sh {
                    op: Shift::Asr,
                    d: s,
                    m: x,
                    imm: 3,
                },
                M::Movi { d: k, imm: 5 },
                M::Alu2 {
                    op: AluOp::Mul,
                    d: p,
                    a: s,
                    m: k,
                },
            ]
        };
        let store = |t| M::Store {
            op: tactus_isa::decode::MemOp::Str,
            t,
            base: Base::State,
            off: 0,
        };
        let load_x = M::Load {
            op: tactus_isa::decode::MemOp::Ldr,
            t: x,
            base: Base::State,
            off: 4,
        };
        let mut code = vec![load_x.clone()];
        code.extend(seq(s1, k1, p1));
        code.push(store(p1));
        code.extend(seq(s2, k2, p2));
        code.push(store(p2));
        code.push(M::CmpI { a: x, imm: 0 });
        share(&mut code, 7);
        assert_eq!(code.len(), 8);
        assert_eq!(code[6], store(p1));
        // A branch from before the first to a label between: the second stays.
        let mut code = vec![load_x.clone(), M::Bc(Cond::Eq, Label(0))];
        code.extend(seq(s1, k1, p1));
        code.push(M::Label(Label(0)));
        code.extend(seq(s2, k2, p2));
        code.push(store(p2));
        share(&mut code, 7);
        assert_eq!(code.len(), 10);
        // The flags of the second `MULS` read by a branch: it stays.
        let mut code = vec![load_x];
        code.extend(seq(s1, k1, p1));
        code.extend(seq(s2, k2, p2));
        code.push(M::Bc(Cond::Eq, Label(0)));
        share(&mut code, 7);
        assert_eq!(code.len(), 8);
        assert!(code.contains(&M::Alu2 {
            op: AluOp::Mul,
            d: p2,
            a: s2,
            m: k2
        }));
    }
}
