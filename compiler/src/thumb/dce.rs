//! Dead-code removal over the machine IR, before register allocation.
//!
//! The selector emits some words nothing reads: the zero side of a `select` folded to
//! `ANDS`/`BICS`, the negated term of a difference that then took the 64-bit path, the high
//! word of a sum whose low word alone is stored. An instruction is dead when nothing reads
//! the register it defines and no instruction reads a flag it sets before that flag is set
//! again: ARMv6-M data-processing instructions set N, Z (and C, V for additions, subtractions
//! and shifts; ARM DDI 0419, A6.7), and `ADCS`/`SBCS` and conditional branches read them, so
//! a `SUBS` whose low word is dead but whose carry feeds an `SBCS`, or an `SBCS` whose flags
//! a branch tests, stays. The scan forward for flag readers is conservative: it stops at a
//! branch (the flags may reach its target) unless every flag was set again before it.
//! A `MOVS #imm` is dead whenever its register is (it may become a literal-pool `LDR`, which
//! sets no flags, so no code relies on its N and Z). Loads stay (a read of the SIO divider's
//! quotient is not free of effects).

use super::mir::*;
use tactus_isa::decode::AluOp;

/// Flag bits.
const FN: u8 = 1;
const FZ: u8 = 2;
const FC: u8 = 4;
const FV: u8 = 8;
const NZCV: u8 = FN | FZ | FC | FV;

/// The flags an instruction certainly sets when emitted.
fn sets(m: &M) -> u8 {
    match m {
        M::AddSub { .. } | M::AddSubI { .. } | M::Cmp { .. } | M::CmpI { .. } => NZCV,
        M::Alu2 { op, .. } => match op {
            AluOp::Adc | AluOp::Sbc => NZCV,
            _ => FN | FZ,
        },
        M::Unary { op: AluOp::Rsb, .. } => NZCV,
        M::Unary { .. } => FN | FZ,
        M::Sh {
            op: Shift::Lsl,
            imm: 0,
            ..
        } => FN | FZ,
        M::Sh { .. } => FN | FZ | FC,
        _ => 0,
    }
}

/// The flags an instruction reads.
fn reads(m: &M) -> u8 {
    match m {
        M::Alu2 {
            op: AluOp::Adc | AluOp::Sbc,
            ..
        } => FC,
        M::Bc(c, _) => match c {
            Cond::Eq | Cond::Ne => FZ,
            Cond::Hs | Cond::Lo => FC,
            Cond::Mi | Cond::Pl => FN,
            Cond::Ge | Cond::Lt => FN | FV,
            Cond::Gt | Cond::Le => FN | FZ | FV,
        },
        _ => 0,
    }
}

/// Whether an instruction may be removed when its register is dead (no effect but the
/// register and the flags).
fn pure(m: &M) -> bool {
    matches!(
        m,
        M::Movi { .. }
            | M::Mov { .. }
            | M::AddSub { .. }
            | M::AddSubI { .. }
            | M::Alu2 { .. }
            | M::Unary { .. }
            | M::Sh { .. }
            | M::Uxth { .. }
    )
}

/// Removes the instructions of `code` whose register and flags nothing reads, repeatedly
/// (an operand of a removed instruction may become dead in turn). Nothing is live out of a
/// body but memory: its results are stored.
pub(crate) fn remove_dead(code: &mut Vec<M>, nregs: u32) {
    let mut uses = vec![0u32; nregs as usize];
    let count = |m: &M, uses: &mut [u32], add: bool| {
        for u in m.uses() {
            if let Some(x) = uses.get_mut(u.0 as usize) {
                if add {
                    *x += 1;
                } else {
                    *x -= 1;
                }
            }
        }
    };
    for m in code.iter() {
        count(m, &mut uses, true);
    }
    let mut dead = vec![false; code.len()];
    loop {
        let mut changed = false;
        for i in (0..code.len()).rev() {
            if dead[i] || !pure(&code[i]) {
                continue;
            }
            let Some(d) = code[i].def() else { continue };
            if uses.get(d.0 as usize).is_none_or(|&n| n != 0) {
                continue;
            }
            if !matches!(code[i], M::Movi { .. }) && flags_read(code, &dead, i) {
                continue;
            }
            dead[i] = true;
            changed = true;
            count(&code[i], &mut uses, false);
        }
        if !changed {
            break;
        }
    }
    let mut k = 0;
    code.retain(|_| {
        k += 1;
        !dead[k - 1]
    });
}

/// Whether a flag instruction `i` sets may be read (by a later instruction, before it is
/// set again, along the fall-through path; conservatively yes at a branch).
fn flags_read(code: &[M], dead: &[bool], i: usize) -> bool {
    let mut live = sets(&code[i]);
    for (m, _) in code[i + 1..]
        .iter()
        .zip(&dead[i + 1..])
        .filter(|(_, &d)| !d)
    {
        if live == 0 {
            return false;
        }
        if reads(m) & live != 0 {
            return true;
        }
        if matches!(m, M::B(_) | M::Bc(..)) {
            return true;
        }
        live &= !sets(m);
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(n: u32) -> V {
        V(n)
    }

    #[test]
    fn a_dead_negation_goes_but_a_carry_feeding_sbcs_stays() {
        // rsbs v3 = -v2 (dead); subs v4 = v2 - v5 (dead word, carry read); sbcs v6 (dead
        // word, flags read by the branch).
        let mut code = vec![
            M::Unary {
                op: AluOp::Rsb,
                d: v(3),
                m: v(2),
            },
            M::AddSub {
                sub: true,
                d: v(4),
                a: v(2),
                b: v(5),
            },
            M::Alu2 {
                op: AluOp::Sbc,
                d: v(6),
                a: v(7),
                m: v(8),
            },
            M::Bc(Cond::Lt, Label(0)),
            M::Label(Label(0)),
        ];
        remove_dead(&mut code, 9);
        assert_eq!(code.len(), 4);
        assert!(matches!(code[0], M::AddSub { .. }));
    }

    #[test]
    fn a_dead_word_whose_flags_a_branch_reads_stays() {
        // lsrs v3 = v2 >> 1 sets C; the branch reads C.
        let mut code = vec![
            M::Sh {
                op: Shift::Lsr,
                d: v(3),
                m: v(2),
                imm: 1,
            },
            M::Bc(Cond::Hs, Label(0)),
            M::Label(Label(0)),
        ];
        remove_dead(&mut code, 4);
        assert_eq!(code.len(), 3);
        // V is not set by a shift: an RSBS before it still feeds a `BLT` after it.
        let mut code = vec![
            M::Unary {
                op: AluOp::Rsb,
                d: v(3),
                m: v(2),
            },
            M::Sh {
                op: Shift::Asr,
                d: v(4),
                m: v(2),
                imm: 31,
            },
            M::Bc(Cond::Lt, Label(0)),
            M::Label(Label(0)),
            M::Store {
                op: tactus_isa::decode::MemOp::Str,
                t: v(4),
                base: Base::State,
                off: 0,
            },
        ];
        remove_dead(&mut code, 5);
        assert_eq!(code.len(), 5);
    }

    #[test]
    fn chains_die_together() {
        let mut code = vec![
            M::Movi { d: v(2), imm: 5 },
            M::Sh {
                op: Shift::Lsl,
                d: v(3),
                m: v(2),
                imm: 2,
            },
            M::AddSubI {
                sub: false,
                d: v(4),
                a: v(3),
                imm: 1,
            },
            M::CmpI { a: v(5), imm: 0 },
            M::Bc(Cond::Eq, Label(0)),
            M::Label(Label(0)),
        ];
        remove_dead(&mut code, 6);
        assert_eq!(code.len(), 3);
        assert!(matches!(code[0], M::CmpI { .. }));
    }
}
