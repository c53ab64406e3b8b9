//! Constants loaded from the literal pool once where an earlier load of the same word
//! dominates.
//!
//! The selector rematerialises a constant at each use (a fresh register per `MOVS`/literal
//! `LDR`), which keeps live ranges short. A word that needs a literal-pool `LDR` (2 cycles;
//! it is neither `MOVS #imm8` nor `MVNS` of one) and is loaded again a few instructions
//! later is read from the first load's register instead, when that load dominates the
//! second: the code only branches forward, so instruction `i` dominates `j > i` exactly when
//! no label in `(i, j]` is the target of a branch from before `i`. The window bounds the
//! longer live range; if the allocator must still spill the register, it is a constant and
//! is rematerialised at each read, as before. A word that is the negation of such an
//! earlier literal, or within ±7 of it, is computed from it in one cycle (`RSBS`, `ADDS`/
//! `SUBS #imm3`) where the flags those set are dead ([`derived`]).

use super::mir::*;
use std::collections::HashMap;

/// Instructions between a load and a reuse of its register.
pub(crate) const WINDOW: usize = 12;

/// Whether `imm` needs a literal-pool load (see `emit::Emitter::movi`).
fn literal(imm: i32) -> bool {
    !(0..=255).contains(&imm) && !(0..=255).contains(&!imm)
}

/// Replaces dominated reloads of the same literal word in `code` by the first load's
/// register.
pub(crate) fn share(code: &mut Vec<M>, nregs: u32) {
    let defs = def_counts(code, nregs);
    let first_src = first_branch_sources(code);
    let mut avail: HashMap<i32, (V, usize)> = HashMap::new();
    let mut rename: HashMap<V, V> = HashMap::new();
    let mut drop = vec![false; code.len()];
    let mut derive: Vec<(usize, M)> = Vec::new();
    for (j, m) in code.iter().enumerate() {
        match *m {
            M::Label(l) => {
                if let Some(&s) = first_src.get(&l.0) {
                    avail.retain(|_, &mut (_, i)| s >= i);
                }
            }
            M::Movi { d, imm } if literal(imm) && defs.get(d.0 as usize) == Some(&1) => {
                match avail.get(&imm) {
                    Some(&(r, i)) if j - i <= WINDOW => {
                        rename.insert(d, r);
                        drop[j] = true;
                    }
                    _ => {
                        if let Some(n) = derived(&avail, d, imm, j, code) {
                            derive.push((j, n));
                        }
                        avail.insert(imm, (d, j));
                    }
                }
            }
            _ => {}
        }
    }
    for (j, n) in derive {
        code[j] = n;
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
}

/// A literal word `imm` (into `d`, at `code[j]`) computed in one cycle from an available
/// literal a few instructions back instead of loaded in two: its negation (`RSBS`, a
/// symmetric clamp's other bound) or it plus or minus at most 7 (`ADDS`/`SUBS #imm3`,
/// the thresholds `t` and `t + 1` of `>` and `≥`). Those set the flags, which a literal
/// load leaves alone: only where no instruction after `j` reads them before a comparison
/// or an `ADDS`/`SUBS`/`RSBS` sets them all again.
fn derived(avail: &HashMap<i32, (V, usize)>, d: V, imm: i32, j: usize, code: &[M]) -> Option<M> {
    let near = avail.iter().filter(|(_, &(_, i))| j - i <= WINDOW);
    let mut best: Option<(usize, M)> = None;
    for (&c, &(r, i)) in near {
        let m = if c != i32::MIN && imm == c.wrapping_neg() {
            M::Unary {
                op: tactus_isa::decode::AluOp::Rsb,
                d,
                m: r,
            }
        } else {
            let delta = imm as i64 - c as i64;
            if delta == 0 || delta.abs() > 7 {
                continue;
            }
            M::AddSubI {
                sub: delta < 0,
                d,
                a: r,
                imm: delta.unsigned_abs() as u8,
            }
        };
        // The nearest one keeps the longer live range shortest.
        if best.as_ref().is_none_or(|(bi, _)| i > *bi) {
            best = Some((i, m));
        }
    }
    let (_, m) = best?;
    flags_dead_after(code, j).then_some(m)
}

/// Whether the flags after `code[j]` are set again (by `CMP`, `ADDS`/`SUBS`, `RSBS`) before
/// anything reads them (a conditional branch, `ADCS`/`SBCS`), along the fall-through; an
/// unconditional branch or the end ends the search (conservatively: read).
pub(crate) fn flags_dead_after(code: &[M], j: usize) -> bool {
    use tactus_isa::decode::AluOp;
    for m in &code[j + 1..] {
        match m {
            M::Bc(..) | M::B(_) => return false,
            M::Alu2 {
                op: AluOp::Adc | AluOp::Sbc,
                ..
            } => return false,
            M::Cmp { .. }
            | M::CmpI { .. }
            | M::AddSub { .. }
            | M::AddSubI { .. }
            | M::Unary { op: AluOp::Rsb, .. } => return true,
            _ => {}
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    const K: i32 = 1_258_291_200;

    /// A symmetric clamp's second bound is the first's negation and a threshold's `t + 1`
    /// is `t` plus one, where the flags are set again before they are read; where a branch
    /// reads the flags of an earlier `CMP` past the load, the literal load stays.
    #[test]
    fn derives_nearby_literals_only_where_the_flags_are_dead() {
        let (x, a, b) = (V(0), V(1), V(2));
        let cmp = |k| M::Cmp { a: x, b: k };
        let mut code = vec![
            M::Movi { d: a, imm: -K },
            cmp(a),
            M::Movi { d: b, imm: K },
            cmp(b),
            M::Bc(Cond::Le, Label(0)),
        ];
        share(&mut code, 3);
        assert_eq!(
            code[2],
            M::Unary {
                op: tactus_isa::decode::AluOp::Rsb,
                d: b,
                m: a
            }
        );
        let mut code = vec![
            M::Movi { d: a, imm: K },
            cmp(a),
            M::Movi { d: b, imm: K + 1 },
            M::Bc(Cond::Le, Label(0)),
            cmp(b),
        ];
        share(&mut code, 3);
        assert_eq!(code[2], M::Movi { d: b, imm: K + 1 });
        let mut code = vec![
            M::Movi { d: a, imm: K },
            M::Movi { d: b, imm: K + 1 },
            cmp(b),
        ];
        share(&mut code, 3);
        assert_eq!(
            code[1],
            M::AddSubI {
                sub: false,
                d: b,
                a,
                imm: 1
            }
        );
    }
}
