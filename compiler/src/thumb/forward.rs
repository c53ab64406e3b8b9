//! State words read again while a register still holds them: the semi-implicit Euler step
//! stores a velocity and reads it again for the position (`w' = …; s' = w`), and the IR
//! reads a state afresh at each use (the piano's key angle and hammer words are read by
//! every handler that tests them). A load of a state word becomes a copy of the register
//! that holds the word — the register of an earlier load of it, or the register an earlier
//! `STR` wrote it from — where that earlier instruction dominates the load and nothing
//! between may write the word or redefine the register. The code branches only forward, so
//! instruction `i` dominates `j > i` exactly when no label in `(i, j]` is the target of a
//! branch from before `i`, and every way from `i` to `j` runs through instructions between
//! them in program order: a store that may write the word anywhere in `(i, j)` ends the
//! reuse, whichever way it lies on. The copy is a renaming where both registers are
//! defined once (no instruction at all), else a `MOV` (flags kept, as the load kept them);
//! a renamed load register the allocator must spill is rematerialised from the state
//! struct when no store in its live range may write the word (`regalloc::Remat::State`),
//! so a longer live range costs no more than the load it replaced.

use super::mir::*;
use super::select::ARG2;
use std::collections::HashMap;
use tactus_emulator::decode::MemOp;

/// Replaces loads of a state word some register holds (see the module comment) by copies
/// or renamings.
pub(crate) fn forward(code: &mut Vec<M>, nregs: u32) {
    let defs = def_counts(code, nregs);
    let once = |v: V| defs.get(v.0 as usize) == Some(&1);
    let first_src = first_branch_sources(code);
    // Per (load kind, byte offset): the register holding the word and where it got it.
    let mut avail: HashMap<(MemOp, u16), (V, usize)> = HashMap::new();
    let mut rename: HashMap<V, V> = HashMap::new();
    let mut drop = vec![false; code.len()];
    for j in 0..code.len() {
        // Operands renamed so far read their new register.
        for u in code[j].uses_mut() {
            if let Some(&n) = rename.get(u) {
                *u = n;
            }
        }
        match code[j] {
            M::Label(l) => {
                if let Some(&s) = first_src.get(&l.0) {
                    avail.retain(|_, &mut (_, i)| s >= i);
                }
            }
            M::Load {
                op: op @ (MemOp::Ldr | MemOp::Ldrb),
                t,
                base: Base::State,
                off,
            } => match avail.get(&(op, off)) {
                Some(&(v, _)) if v != t => {
                    if once(t) && once(v) {
                        rename.insert(t, v);
                        drop[j] = true;
                    } else {
                        code[j] = M::Mov { d: t, s: v };
                        avail.retain(|_, &mut (w, _)| w != t);
                    }
                }
                _ => {
                    avail.retain(|_, &mut (w, _)| w != t);
                    avail.insert((op, off), (t, j));
                }
            },
            M::Store {
                op,
                t,
                base: Base::State,
                off,
            } => {
                avail.retain(|&(_, o), _| o / 4 != off / 4);
                if op == MemOp::Str {
                    avail.insert((MemOp::Ldr, off), (t, j));
                }
            }
            // The caller's output array is not the state.
            M::Store {
                base: Base::V(b), ..
            } if b == ARG2 => {}
            // A store at an address not known here (a region base, the history ring).
            M::Store { .. } | M::StoreR { .. } => avail.clear(),
            ref m => {
                if let Some(d) = m.def() {
                    avail.retain(|_, &mut (w, _)| w != d);
                }
            }
        }
    }
    if rename.is_empty() {
        return;
    }
    remove_marked(code, &drop);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn store(t: u32, off: u16) -> M {
        M::Store {
            op: MemOp::Str,
            t: V(t),
            base: Base::State,
            off,
        }
    }

    fn load(t: u32, off: u16) -> M {
        M::Load {
            op: MemOp::Ldr,
            t: V(t),
            base: Base::State,
            off,
        }
    }

    fn cmp(a: u32) -> M {
        M::CmpI { a: V(a), imm: 0 }
    }

    fn def(v: u32) -> M {
        M::Movi {
            d: V(v),
            imm: 1 << 20,
        }
    }

    /// A load right after the store of its word reads the stored register (the last
    /// store's, when two write it), a second load of a word the first load's; a
    /// redefinition of the register, a byte store into the word or a store at an unknown
    /// address in between keeps the load.
    #[test]
    fn forwards_stored_and_loaded_words() {
        let mut code = vec![def(3), store(3, 16), load(4, 8), load(5, 16), cmp(5)];
        forward(&mut code, 8);
        assert_eq!(code, vec![def(3), store(3, 16), load(4, 8), cmp(3)]);
        let mut code = vec![
            def(3),
            def(6),
            store(3, 16),
            store(6, 16),
            load(5, 16),
            cmp(5),
        ];
        forward(&mut code, 8);
        assert_eq!(code[4..], [cmp(6)]);
        let mut code = vec![load(3, 16), cmp(3), load(5, 16), cmp(5)];
        forward(&mut code, 8);
        assert_eq!(code, vec![load(3, 16), cmp(3), cmp(3)]);
        for between in [
            M::Movi { d: V(3), imm: 1 },
            M::Store {
                op: MemOp::Strb,
                t: V(6),
                base: Base::State,
                off: 17,
            },
            M::StoreR {
                op: MemOp::Str,
                t: V(6),
                idx: V(7),
            },
        ] {
            let mut code = vec![load(3, 16), between.clone(), load(5, 16), cmp(5)];
            forward(&mut code, 8);
            assert_eq!(code[2], load(5, 16), "{between:?}");
        }
        // A register defined twice (the arms of a diamond) is copied, not renamed.
        let mut code = vec![
            load(3, 16),
            load(5, 16),
            cmp(5),
            M::Movi { d: V(5), imm: 1 },
        ];
        forward(&mut code, 8);
        assert_eq!(code[1], M::Mov { d: V(5), s: V(3) });
    }

    /// Only a dominating load or store is reused: a label that a branch from before it
    /// targets ends it (another way into the label bypasses it); a label branched to only
    /// from after it keeps it.
    #[test]
    fn forwards_only_from_dominating_instructions() {
        let (l0, l1) = (Label(0), Label(1));
        let mut code = vec![
            M::Bc(Cond::Eq, l0),
            load(3, 16),
            cmp(3),
            M::Label(l0),
            load(5, 16),
            cmp(5),
        ];
        forward(&mut code, 8);
        assert_eq!(code[4], load(5, 16));
        let mut code = vec![
            load(3, 16),
            M::Bc(Cond::Eq, l1),
            cmp(3),
            M::Label(l1),
            load(5, 16),
            cmp(5),
        ];
        forward(&mut code, 8);
        assert_eq!(code.len(), 5);
        assert_eq!(code[4], cmp(3));
    }
}
