//! State words read again while a register still holds them: the semi-implicit Euler step
//! stores a velocity and reads it again for the position (`w' = …; s' = w`), and the IR
//! reads a state afresh at each use (the piano's key angle and hammer words are read by
//! every handler that tests them). A load of a state word becomes a copy of the register
//! that holds the word on every way to it — the register of an earlier load of it, the
//! register an earlier `STR` wrote it from, or the `MOVS #imm` (0–255) an earlier `STRB`
//! stored — where nothing between may write its bytes or redefine the register. The code
//! branches only forward, so one pass in program order knows every way into a label when
//! it reaches it (the branches recorded what they knew; a label keeps what all ways agree
//! on); a byte store ends only the reuse of the bytes it writes (the piano's handlers set
//! edge bytes beside the mode byte every handler reads). A handler that sets the mode byte
//! in its arm makes the register of the byte's load before the arm take the stored
//! constant instead of a register of its own ([`phi_at`]), so that after the join the
//! register holds the byte on both ways. The copy is a renaming where both registers are
//! defined once by the selector (no instruction at all), else a `MOV` (flags kept, as the
//! load kept them); a renamed load register the allocator must spill is rematerialised
//! from the state struct when no store in its live range may write the word
//! (`regalloc::Remat::State`), so a longer live range costs no more than the load it
//! replaced.

use super::mir::*;
use std::collections::HashMap;
use tactus_isa::decode::MemOp;

/// A state access: its kind and byte offset.
type Key = (MemOp, u16);

/// Replaces loads of a state word some register holds (see the module comment) by copies
/// or renamings.
pub(crate) fn forward(code: &mut Vec<M>, nregs: u32) {
    let defs = def_counts(code, nregs);
    let once = |v: V| defs.get(v.0 as usize) == Some(&1);
    let mut def_at = vec![usize::MAX; nregs as usize];
    // The last instruction reading each register, or one a renaming made read it.
    let mut last_use = vec![0usize; nregs as usize];
    for (i, m) in code.iter().enumerate() {
        if let Some(d) = m.def() {
            if let Some(x) = def_at.get_mut(d.0 as usize) {
                *x = i;
            }
        }
        for u in m.uses() {
            if let Some(x) = last_use.get_mut(u.0 as usize) {
                *x = i;
            }
        }
    }
    // Per access: the register holding it on every way here.
    let mut avail: HashMap<Key, V> = HashMap::new();
    // Per label: what every branch to it lowered so far agrees on.
    let mut pending: HashMap<u32, HashMap<Key, V>> = HashMap::new();
    let mut reachable = true;
    let mut rename: HashMap<V, V> = HashMap::new();
    let mut drop = vec![false; code.len()];
    let branch =
        |pending: &mut HashMap<u32, HashMap<Key, V>>, l: Label, avail: &HashMap<Key, V>| {
            pending
                .entry(l.0)
                .and_modify(|w| w.retain(|k, v| avail.get(k) == Some(v)))
                .or_insert_with(|| avail.clone());
        };
    for j in 0..code.len() {
        // Operands renamed so far read their new register.
        for u in code[j].uses_mut() {
            if let Some(&n) = rename.get(u) {
                *u = n;
            }
        }
        match code[j] {
            M::Label(l) => {
                let ways = pending.remove(&l.0);
                avail = match (reachable, ways) {
                    (true, Some(w)) => avail
                        .into_iter()
                        .filter(|(k, v)| w.get(k) == Some(v))
                        .collect(),
                    (true, None) => avail,
                    (false, Some(w)) => w,
                    (false, None) => HashMap::new(),
                };
                reachable = true;
            }
            M::B(l) => {
                branch(&mut pending, l, &avail);
                reachable = false;
            }
            M::Bc(_, l) => branch(&mut pending, l, &avail),
            M::Load {
                op: op @ (MemOp::Ldr | MemOp::Ldrb),
                t,
                base: Base::State,
                off,
            } => match avail.get(&(op, off)) {
                Some(&v) if v != t => {
                    let k = v.0 as usize;
                    if once(t) && once(v) {
                        rename.insert(t, v);
                        last_use[k] = last_use[k].max(last_use[t.0 as usize]);
                        drop[j] = true;
                    } else {
                        code[j] = M::Mov { d: t, s: v };
                        last_use[k] = last_use[k].max(j);
                        avail.retain(|_, &mut w| w != t);
                    }
                }
                _ => {
                    avail.retain(|_, &mut w| w != t);
                    avail.insert((op, off), t);
                }
            },
            M::Store {
                op,
                t,
                base: Base::State,
                off,
            } => {
                let before = avail.get(&(MemOp::Ldrb, off)).copied();
                let before_word = avail.get(&(MemOp::Ldr, off)).copied();
                avail.retain(|&k, _| !accesses_overlap(k, (op, off)));
                match op {
                    MemOp::Str => {
                        // A constant word set in a handler's arm, as a mode byte below.
                        let phi = word_constant(code, &def_at, t, once(t))
                            .and(before_word)
                            .filter(|&v| v != t && once(v))
                            .filter(|_| {
                                code[j + 1..]
                                    .iter()
                                    .filter(|m| loads(m, (MemOp::Ldr, off)))
                                    .count()
                                    >= PHI_MIN_LOADS
                            })
                            .and_then(|v| Some((v, phi_at(code, &def_at, &last_use, v, t, j)?)));
                        match phi {
                            Some((v, q)) => {
                                if let M::Movi { d, .. } = &mut code[q] {
                                    *d = v;
                                }
                                if let M::Store { t: st, .. } = &mut code[j] {
                                    *st = v;
                                }
                                rename.insert(t, v);
                                let k = v.0 as usize;
                                last_use[k] = last_use[k].max(last_use[t.0 as usize]);
                                avail.retain(|_, &mut w| w != v);
                                avail.insert((MemOp::Ldr, off), v);
                            }
                            None => {
                                avail.insert((MemOp::Ldr, off), t);
                            }
                        }
                    }
                    MemOp::Strb => {
                        if let Some(byte) = byte_constant(code, &def_at, t, once(t)) {
                            let later = code[j + 1..]
                                .iter()
                                .filter(|m| loads(m, (MemOp::Ldrb, off)))
                                .count();
                            let v = before
                                .filter(|&v| v != t && once(v) && later >= PHI_MIN_LOADS)
                                .and_then(|v| {
                                    let q = phi_at(code, &def_at, &last_use, v, t, j)?;
                                    Some((v, q))
                                });
                            match v {
                                // `v` takes the byte's new value where `t` was defined:
                                // every way on holds the byte in `v`.
                                Some((v, q)) => {
                                    code[q] = M::Movi { d: v, imm: byte };
                                    if let M::Store { t: st, .. } = &mut code[j] {
                                        *st = v;
                                    }
                                    rename.insert(t, v);
                                    let k = v.0 as usize;
                                    last_use[k] = last_use[k].max(last_use[t.0 as usize]);
                                    avail.retain(|_, &mut w| w != v);
                                    avail.insert((MemOp::Ldrb, off), v);
                                }
                                None => {
                                    avail.insert((MemOp::Ldrb, off), t);
                                }
                            }
                        }
                    }
                    _ => {}
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
                    avail.retain(|_, &mut w| w != d);
                }
            }
        }
    }
    if drop.iter().any(|&d| d) {
        remove_marked(code, &drop);
    }
}

/// Loads of a byte after its `STRB` below which the register of the byte's earlier load
/// does not take the stored constant ([`phi_at`]): it then holds the byte over a longer
/// span, a register the allocator no longer has for others (the plucked string's mode byte,
/// read three times in all, cost 6 cycles of spills that way; the piano's, read seven
/// times, saves 8).
const PHI_MIN_LOADS: usize = 3;

/// Whether `m` loads the state byte or word `at` (kind, byte offset).
fn loads(m: &M, at: Key) -> bool {
    matches!(*m, M::Load { op, base: Base::State, off, .. } if (op, off) == at)
}

/// The constant byte a register stored with `STRB` holds (a `MOVS #imm` of 0–255 defining it
/// once, so that `LDRB` reads the register's value back).
fn byte_constant(code: &[M], def_at: &[usize], t: V, once: bool) -> Option<i32> {
    let at = *def_at.get(t.0 as usize)?;
    match code.get(at) {
        Some(&M::Movi { imm, .. }) if once && (0..=255).contains(&imm) => Some(imm),
        _ => None,
    }
}

/// The constant word a register stored with `STR` holds: a `Movi` (any 32-bit constant,
/// which the emitter materialises as `MOVS`, `MOVS`+`LSLS`, `MVNS` or a literal) defining it
/// once.
fn word_constant(code: &[M], def_at: &[usize], t: V, once: bool) -> Option<i32> {
    let at = *def_at.get(t.0 as usize)?;
    match code.get(at) {
        Some(&M::Movi { imm, .. }) if once => Some(imm),
        _ => None,
    }
}

/// Where register `v` (holding a byte of the state on every way to the `STRB` of constant
/// register `t` at `j`) may take `t`'s value instead, so that it still holds the byte after
/// the store: `t`'s definition, when nothing reads `v` from there on (its old value is
/// dead; every read of it so far, renamed ones included, lies before), nothing reads `t`
/// between its definition and the store, and no label or branch lies between them (every
/// way through the store runs through the new definition, and no way leaves between them
/// with `v` already changed and the byte not yet).
fn phi_at(code: &[M], def_at: &[usize], last_use: &[usize], v: V, t: V, j: usize) -> Option<usize> {
    let q = *def_at.get(t.0 as usize)?;
    if q >= j || last_use[v.0 as usize] >= q {
        return None;
    }
    let clear = code[q + 1..j]
        .iter()
        .all(|m| !m.uses().contains(&t) && !matches!(m, M::Label(_) | M::B(_) | M::Bc(..)));
    clear.then_some(q)
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

    fn ldrb(t: u32, off: u16) -> M {
        M::Load {
            op: MemOp::Ldrb,
            t: V(t),
            base: Base::State,
            off,
        }
    }

    fn strb(t: u32, off: u16) -> M {
        M::Store {
            op: MemOp::Strb,
            t: V(t),
            base: Base::State,
            off,
        }
    }

    /// A byte store leaves the other bytes of its word: a mode byte read again after a
    /// handler set an edge byte beside it is the first load's register.
    #[test]
    fn byte_stores_keep_the_other_bytes() {
        let mut code = vec![
            ldrb(3, 0),
            cmp(3),
            M::Movi { d: V(4), imm: 1 },
            strb(4, 1),
            ldrb(5, 0),
            cmp(5),
            ldrb(6, 1),
            cmp(6),
        ];
        forward(&mut code, 8);
        assert_eq!(
            code,
            vec![
                ldrb(3, 0),
                cmp(3),
                M::Movi { d: V(4), imm: 1 },
                strb(4, 1),
                cmp(3),
                cmp(4),
            ]
        );
        // A constant beyond a byte is not what `LDRB` reads back.
        let mut code = vec![
            M::Movi { d: V(4), imm: 300 },
            strb(4, 1),
            ldrb(6, 1),
            cmp(6),
        ];
        forward(&mut code, 8);
        assert_eq!(code[2], ldrb(6, 1));
    }

    /// A mode byte set in a handler's arm: the register of the load before the arm takes
    /// the stored constant in the arm, so after the join it holds the byte on both ways
    /// and the load there goes; not when the old value is read after the store's constant
    /// is defined, nor with a label between the constant and the store.
    #[test]
    fn a_byte_set_in_an_arm_stays_in_its_register() {
        let l = Label(0);
        // The byte read `reads` times after the join.
        let arm = |between: Option<M>, reads: u32| {
            let mut c = vec![
                ldrb(3, 0),
                cmp(3),
                M::Bc(Cond::Eq, l),
                M::Movi { d: V(4), imm: 2 },
            ];
            c.extend(between);
            c.extend([strb(4, 0), M::Label(l)]);
            for r in 0..reads {
                c.extend([ldrb(5 + r, 0), cmp(5 + r)]);
            }
            c
        };
        let mut code = arm(None, 3);
        forward(&mut code, 8);
        assert_eq!(
            code,
            vec![
                ldrb(3, 0),
                cmp(3),
                M::Bc(Cond::Eq, l),
                M::Movi { d: V(3), imm: 2 },
                strb(3, 0),
                M::Label(l),
                cmp(3),
                cmp(3),
                cmp(3),
            ]
        );
        // Read once after: not worth a register over the span (`PHI_MIN_LOADS`).
        let mut code = arm(None, 1);
        forward(&mut code, 8);
        assert_eq!(code, arm(None, 1));
        for between in [cmp(3), M::Label(Label(1))] {
            let mut code = arm(Some(between.clone()), 3);
            forward(&mut code, 8);
            assert_eq!(code[3], M::Movi { d: V(4), imm: 2 }, "{between:?}");
            assert!(code.contains(&ldrb(5, 0)), "{between:?}");
        }
    }

    /// A state word set to a constant in a handler's arm (the piano's back-check holding
    /// the hammer: `s = s_check; w = 0`): the register of the word's load before the arm
    /// takes the constant in the arm, so the loads after the join go; not when the stored
    /// register is computed (not one constant), nor when the word is read fewer than
    /// `PHI_MIN_LOADS` times after.
    #[test]
    fn a_word_set_in_an_arm_stays_in_its_register() {
        let l = Label(0);
        let arm = |value: M, reads: u32| {
            let mut c = vec![load(3, 16), cmp(3), M::Bc(Cond::Eq, l), value];
            c.extend([store(4, 16), M::Label(l)]);
            for r in 0..reads {
                c.extend([load(5 + r, 16), cmp(5 + r)]);
            }
            c
        };
        let word = M::Movi {
            d: V(4),
            imm: 1_040_703_614,
        };
        let mut code = arm(word.clone(), 3);
        forward(&mut code, 12);
        assert_eq!(
            code,
            vec![
                load(3, 16),
                cmp(3),
                M::Bc(Cond::Eq, l),
                M::Movi {
                    d: V(3),
                    imm: 1_040_703_614
                },
                store(3, 16),
                M::Label(l),
                cmp(3),
                cmp(3),
                cmp(3),
            ]
        );
        // Read twice after: the first read after the join stays a load.
        let mut code = arm(word.clone(), 2);
        forward(&mut code, 12);
        assert_eq!(code[..7], arm(word, 2)[..7]);
        let computed = M::Sh {
            op: Shift::Asr,
            d: V(4),
            m: V(3),
            imm: 1,
        };
        let mut code = arm(computed.clone(), 3);
        forward(&mut code, 12);
        assert_eq!(code[..5], arm(computed, 3)[..5]);
        assert!(code.contains(&load(5, 16)), "{code:?}");
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
