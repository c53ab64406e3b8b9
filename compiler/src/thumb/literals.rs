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
//! is rematerialised at each read, as before.

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
    let mut defs = vec![0u32; nregs as usize];
    for m in code.iter() {
        if let Some(d) = m.def() {
            if let Some(n) = defs.get_mut(d.0 as usize) {
                *n += 1;
            }
        }
    }
    // The first branch source of each label.
    let mut first_src: HashMap<u32, usize> = HashMap::new();
    for (i, m) in code.iter().enumerate() {
        if let M::B(l) | M::Bc(_, l) = m {
            first_src.entry(l.0).or_insert(i);
        }
    }
    let mut avail: HashMap<i32, (V, usize)> = HashMap::new();
    let mut rename: HashMap<V, V> = HashMap::new();
    let mut drop = vec![false; code.len()];
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
                        avail.insert(imm, (d, j));
                    }
                }
            }
            _ => {}
        }
    }
    if rename.is_empty() {
        return;
    }
    let mut k = 0;
    code.retain(|_| {
        k += 1;
        !drop[k - 1]
    });
    for m in code.iter_mut() {
        for v in m.uses_mut() {
            if let Some(&n) = rename.get(v) {
                *v = n;
            }
        }
    }
}
