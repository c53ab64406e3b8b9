//! Machine IR: ARMv6-M Thumb instructions over virtual registers, before register
//! allocation.
//!
//! Each [`M`] is one Thumb instruction (or a label, or a constant load that [`super::emit`]
//! turns into `MOVS`, `MOVS`+`LSLS`, `MVNS` or a literal-pool `LDR`). Operands are virtual
//! registers ([`V`]); the state pointer is pinned in `r7` ([`Base::State`]) and the stack
//! pointer is [`Base::Sp`]. Control flow is forward only (no loops), so a virtual register's
//! live range is the interval from its first definition to its last use in program order;
//! a register may be defined again later in that interval (the arms of a diamond).

use std::collections::HashMap;
use tactus_isa::decode::{AluOp, MemOp};

/// A virtual register (32-bit word).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct V(pub u32);

/// `r1` and `r2` on entry: the sensors and out pointers (virtual registers pre-coloured
/// by the allocator).
pub(crate) const ARG1: V = V(0);
pub(crate) const ARG2: V = V(1);
/// The first virtual register instruction selection allocates.
pub(crate) const FIRST_FREE: u32 = 2;

/// The pinned state pointer as a virtual register for address arithmetic (allocated to r7).
pub(crate) const STATE_V: V = V(u32::MAX);

/// A branch target.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Label(pub u32);

/// The base register of a load or store.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Base {
    /// The instance's state struct (`r7`, pinned for the whole update).
    State,
    /// A virtual register holding an address.
    V(V),
}

/// Shift-by-immediate operations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shift {
    /// `LSLS` (0–31)
    Lsl,
    /// `LSRS` (1–32)
    Lsr,
    /// `ASRS` (1–32)
    Asr,
}

/// ARMv6-M condition codes (DDI0419 A7.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(missing_docs)]
pub enum Cond {
    Eq = 0,
    Ne = 1,
    Hs = 2,
    Lo = 3,
    Mi = 4,
    Pl = 5,
    Ge = 10,
    Lt = 11,
    Gt = 12,
    Le = 13,
}

impl Cond {
    /// The opposite condition.
    pub fn invert(self) -> Cond {
        use Cond::*;
        match self {
            Eq => Ne,
            Ne => Eq,
            Hs => Lo,
            Lo => Hs,
            Mi => Pl,
            Pl => Mi,
            Ge => Lt,
            Lt => Ge,
            Gt => Le,
            Le => Gt,
        }
    }
}

/// One machine instruction over virtual registers (fields: `d` destination, `a`/`b`/`m`
/// sources, `t` transfer register, `imm` immediate, `off` byte offset).
#[derive(Clone, Debug, PartialEq)]
#[allow(missing_docs)]
pub enum M {
    /// `d = imm` (flags N, Z may change; C, V kept).
    Movi { d: V, imm: i32 },
    /// `d = s` (`MOV`, flags kept).
    Mov { d: V, s: V },
    /// `d = a + b` / `a - b` (`ADDS`/`SUBS` three registers).
    AddSub { sub: bool, d: V, a: V, b: V },
    /// `d = a ± imm` (`ADDS`/`SUBS` with imm3, or imm8 when `d` and `a` share a register).
    AddSubI { sub: bool, d: V, a: V, imm: u8 },
    /// `d = a op m` for a two-address data-processing op (`ANDS`, `ORRS`, `EORS`, `ADCS`,
    /// `SBCS`, `MULS`): emitted as `MOV d, a` (if needed) then `op d, m`.
    Alu2 { op: AluOp, d: V, a: V, m: V },
    /// `d = -m` (`RSBS d, m, #0`) or `d = ~m` (`MVNS`).
    Unary { op: AluOp, d: V, m: V },
    /// `d = m shift imm`.
    Sh { op: Shift, d: V, m: V, imm: u8 },
    /// `UXTH d, m`.
    Uxth { d: V, m: V },
    /// `CMP a, b`.
    Cmp { a: V, b: V },
    /// `CMP a, #imm`.
    CmpI { a: V, imm: u8 },
    /// Load `t = [base + off]`.
    Load {
        op: MemOp,
        t: V,
        base: Base,
        off: u16,
    },
    /// Load `t = [base + idx]`.
    LoadR { op: MemOp, t: V, base: Base, idx: V },
    /// Store `[state + idx] = t` (`STR Rt, [r7, Rm]`; the state base only, so that `t` and
    /// `idx` are the two operands that may need scratch registers).
    StoreR { op: MemOp, t: V, idx: V },
    /// Store `[base + off] = t`.
    Store {
        op: MemOp,
        t: V,
        base: Base,
        off: u16,
    },
    /// A branch target.
    Label(Label),
    /// `B label`.
    B(Label),
    /// `B<cond> label`.
    Bc(Cond, Label),
    /// A comment for the listing (source-level event names for the WCET report).
    Note(String),
    /// Marks the start of the body of the top-level `if` statement with this index (a
    /// block start the WCET analysis' flow facts refer to).
    Mark(u32),
    /// A one-cycle no-op (`MOV r8, r8`, GNU as's `nop` on ARMv6-M): waiting out the SIO
    /// divider's latency.
    Nop,
}

impl M {
    /// Virtual registers read.
    pub fn uses(&self) -> Vec<V> {
        let base = |b: &Base| match b {
            Base::V(v) => Some(*v),
            _ => None,
        };
        match self {
            M::Movi { .. }
            | M::Label(_)
            | M::B(_)
            | M::Bc(..)
            | M::Note(_)
            | M::Mark(_)
            | M::Nop => vec![],
            M::Mov { s, .. } => vec![*s],
            M::AddSub { a, b, .. } => vec![*a, *b],
            M::AddSubI { a, .. } => vec![*a],
            M::Alu2 { a, m, .. } => vec![*a, *m],
            M::Unary { m, .. } | M::Sh { m, .. } | M::Uxth { m, .. } => vec![*m],
            M::Cmp { a, b } => vec![*a, *b],
            M::CmpI { a, .. } => vec![*a],
            M::Load { base: b, .. } => base(b).into_iter().collect(),
            M::LoadR { base: b, idx, .. } => base(b).into_iter().chain([*idx]).collect(),
            M::Store { t, base: b, .. } => std::iter::once(*t).chain(base(b)).collect(),
            M::StoreR { t, idx, .. } => vec![*t, *idx],
        }
    }

    /// The virtual registers read, to rewrite in place: the operands of [`M::uses`], in
    /// the same order.
    pub fn uses_mut(&mut self) -> Vec<&mut V> {
        fn base(b: &mut Base) -> Option<&mut V> {
            match b {
                Base::V(v) => Some(v),
                _ => None,
            }
        }
        match self {
            M::Movi { .. }
            | M::Label(_)
            | M::B(_)
            | M::Bc(..)
            | M::Note(_)
            | M::Mark(_)
            | M::Nop => vec![],
            M::Mov { s, .. } => vec![s],
            M::AddSub { a, b, .. } => vec![a, b],
            M::AddSubI { a, .. } => vec![a],
            M::Alu2 { a, m, .. } => vec![a, m],
            M::Unary { m, .. } | M::Sh { m, .. } | M::Uxth { m, .. } => vec![m],
            M::Cmp { a, b } => vec![a, b],
            M::CmpI { a, .. } => vec![a],
            M::Load { base: b, .. } => base(b).into_iter().collect(),
            M::LoadR { base: b, idx, .. } => base(b).into_iter().chain([idx]).collect(),
            M::Store { t, base: b, .. } => std::iter::once(t).chain(base(b)).collect(),
            M::StoreR { t, idx, .. } => vec![t, idx],
        }
    }

    /// The virtual register written, if any.
    pub fn def(&self) -> Option<V> {
        match self {
            M::Movi { d, .. }
            | M::Mov { d, .. }
            | M::AddSub { d, .. }
            | M::AddSubI { d, .. }
            | M::Alu2 { d, .. }
            | M::Unary { d, .. }
            | M::Sh { d, .. }
            | M::Uxth { d, .. } => Some(*d),
            M::Load { t, .. } | M::LoadR { t, .. } => Some(*t),
            _ => None,
        }
    }

    /// Uses that must not share a register with the definition (the second operand of a
    /// two-address op that is not commutative, which `MOV d, a` would overwrite; a
    /// commutative op is emitted as `op d, a` when `d` shares `m`'s register).
    pub fn late_use(&self) -> Option<V> {
        match self {
            M::Alu2 { op, a, m, .. } if a != m && !commutative(*op) => Some(*m),
            _ => None,
        }
    }

    /// The operands whose register the definition would like to share (a two-address
    /// instruction then needs no `MOV`): `a` of an [`M::Alu2`] (either operand when the op
    /// is commutative), of an [`M::AddSubI`] with an 8-bit immediate, and the source of an
    /// [`M::Mov`] (which then emits nothing).
    pub fn tied(&self) -> [Option<V>; 2] {
        match *self {
            M::Alu2 { op, a, m, .. } if commutative(op) => [Some(a), Some(m)],
            M::Alu2 { a, .. } => [Some(a), None],
            M::AddSubI { a, imm, .. } if imm > 7 => [Some(a), None],
            M::Mov { s, .. } => [Some(s), None],
            _ => [None, None],
        }
    }
}

/// Whether a two-address data-processing op gives the same result with its operands
/// swapped (`ANDS`, `ORRS`, `EORS`, `ADCS`, `MULS`).
pub fn commutative(op: AluOp) -> bool {
    matches!(
        op,
        AluOp::And | AluOp::Orr | AluOp::Eor | AluOp::Adc | AluOp::Mul
    )
}

/// How many instructions of `code` define each virtual register below `nregs` (1: defined
/// once, so a rename of it is safe).
pub(crate) fn def_counts(code: &[M], nregs: u32) -> Vec<u32> {
    let mut defs = vec![0u32; nregs as usize];
    for m in code {
        if let Some(d) = m.def() {
            if let Some(n) = defs.get_mut(d.0 as usize) {
                *n += 1;
            }
        }
    }
    defs
}

/// The first branch source of each label of `code` (label number → instruction index).
/// The code only branches forward, so instruction `i` dominates `j > i` exactly when no
/// label in `(i, j]` is the target of a branch from before `i`.
pub(crate) fn first_branch_sources(code: &[M]) -> HashMap<u32, usize> {
    let mut first_src: HashMap<u32, usize> = HashMap::new();
    for (i, m) in code.iter().enumerate() {
        if let M::B(l) | M::Bc(_, l) = m {
            first_src.entry(l.0).or_insert(i);
        }
    }
    first_src
}

/// Whether an access `a` and an access `b` of the state struct, each (kind, byte offset),
/// touch a common byte: a byte store into a word leaves the word's other bytes (a mode byte
/// beside the edge bytes a handler sets) as they were.
pub(crate) fn accesses_overlap(a: (MemOp, u16), b: (MemOp, u16)) -> bool {
    let (sa, sb) = (a.0.size() as u16, b.0.size() as u16);
    a.1 < b.1 + sb && b.1 < a.1 + sa
}

/// Removes the instructions of `code` whose `drop` flag is set (`drop` as long as `code`).
pub(crate) fn remove_marked(code: &mut Vec<M>, drop: &[bool]) {
    let mut k = 0;
    code.retain(|_| {
        k += 1;
        !drop[k - 1]
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `uses_mut` reaches exactly the registers `uses` lists, in order, for every kind of
    /// instruction that reads one (and renaming through it changes what `uses` reports).
    #[test]
    fn uses_mut_agrees_with_uses() {
        let v = V;
        let all = [
            M::Movi { d: v(1), imm: 3 },
            M::Mov { d: v(1), s: v(2) },
            M::AddSub {
                sub: true,
                d: v(1),
                a: v(2),
                b: v(3),
            },
            M::AddSubI {
                sub: false,
                d: v(1),
                a: v(2),
                imm: 4,
            },
            M::Alu2 {
                op: AluOp::Mul,
                d: v(1),
                a: v(2),
                m: v(3),
            },
            M::Unary {
                op: AluOp::Mvn,
                d: v(1),
                m: v(2),
            },
            M::Sh {
                op: Shift::Asr,
                d: v(1),
                m: v(2),
                imm: 16,
            },
            M::Uxth { d: v(1), m: v(2) },
            M::Cmp { a: v(2), b: v(3) },
            M::CmpI { a: v(2), imm: 0 },
            M::Load {
                op: MemOp::Ldr,
                t: v(1),
                base: Base::V(v(2)),
                off: 0,
            },
            M::Load {
                op: MemOp::Ldr,
                t: v(1),
                base: Base::State,
                off: 4,
            },
            M::LoadR {
                op: MemOp::Ldr,
                t: v(1),
                base: Base::V(v(2)),
                idx: v(3),
            },
            M::StoreR {
                op: MemOp::Str,
                t: v(2),
                idx: v(3),
            },
            M::Store {
                op: MemOp::Str,
                t: v(2),
                base: Base::V(v(3)),
                off: 8,
            },
            M::Store {
                op: MemOp::Str,
                t: v(2),
                base: Base::State,
                off: 8,
            },
            M::Label(Label(0)),
            M::B(Label(0)),
            M::Bc(Cond::Eq, Label(0)),
            M::Note(String::new()),
            M::Mark(0),
            M::Nop,
        ];
        for m in all {
            let mut n = m.clone();
            let seen: Vec<V> = n.uses_mut().into_iter().map(|r| *r).collect();
            assert_eq!(seen, m.uses(), "{m:?}");
            for r in n.uses_mut() {
                r.0 += 100;
            }
            let moved: Vec<V> = m.uses().iter().map(|r| V(r.0 + 100)).collect();
            assert_eq!(n.uses(), moved, "{m:?}");
        }
    }
}
