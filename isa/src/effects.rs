//! What an instruction that runs on to the next one does to the general registers and the
//! APSR flags: the registers it reads and writes, the flags it reads and sets, and which
//! register's value N and Z then reflect — the per-instruction operations of the ARMv6-M
//! Architecture Reference Manual (DDI 0419, A6.7; the conditions' flags, A6.3), as bit
//! sets a data-flow analysis combines.
//!
//! One definition for every analysis of machine code: the Thumb backend's peepholes (flag
//! and register liveness, known values) and the static WCET's register-value tracker
//! ([`crate::wcet`]) read it; neither keeps its own list of what an instruction writes.
//! Control transfers have no [`Effect`]: a client decides what a branch, a call or a
//! return means to it.

use crate::decode::{AluOp, Instr};

/// The APSR's N flag (negative) as a bit of a flag set.
pub const N: u8 = 1;
/// The APSR's Z flag (zero).
pub const Z: u8 = 2;
/// The APSR's C flag (carry).
pub const C: u8 = 4;
/// The APSR's V flag (overflow).
pub const V: u8 = 8;
/// All four flags.
pub const ALL: u8 = N | Z | C | V;

/// The flags condition `cond` (0-13, ARMv6-M A6.3) reads; 0 for `AL` and beyond.
#[inline]
pub fn cond_reads(cond: u8) -> u8 {
    match cond {
        0 | 1 => Z,
        2 | 3 => C,
        4 | 5 => N,
        6 | 7 => V,
        8 | 9 => C | Z,
        10 | 11 => N | V,
        12 | 13 => N | Z | V,
        _ => 0,
    }
}

/// What an instruction that neither branches nor returns does to registers and flags
/// (bit *n* of a register set is r*n*; r13 stands for SP where the instruction uses it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Effect {
    /// Registers read. A literal load and `ADR` read none (PC, the only operand they
    /// read, is no register a set holds); a store reads the register it stores.
    pub reads: u16,
    /// Registers written.
    pub writes: u16,
    /// Flags read ([`N`], [`Z`], [`C`], [`V`]).
    pub flags_read: u8,
    /// Flags always written (a shift by a register, which leaves C alone when the amount
    /// is 0, counts N and Z only).
    pub flags_set: u8,
    /// The register whose new value N and Z then reflect (`None` when they reflect no
    /// register's value, or are not written). `CMP Rn, #0` reflects `Rn`.
    pub nz: Option<u8>,
}

/// [`Effect`] of `i`, or `None` for what an analysis cannot follow as straight-line code:
/// control transfers (branches, calls, `BX`/`BLX`, writes of PC by `ADD`, `MOV` or `POP`),
/// `MSR` (a special register, and the flags), traps and undefined encodings.
// Inlined: the emulator's memo recording asks it of every instruction it records.
#[inline]
pub fn effect(i: &Instr) -> Option<Effect> {
    use Instr::*;
    let e = |reads: u16, writes: u16, flags_read: u8, flags_set: u8, nz: Option<u8>| {
        Some(Effect {
            reads,
            writes,
            flags_read,
            flags_set,
            nz,
        })
    };
    let r = |x: u8| 1u16 << x;
    let stored = |op: crate::decode::MemOp, rt: u8| if op.is_store() { r(rt) } else { 0 };
    let loaded = |op: crate::decode::MemOp, rt: u8| if op.is_store() { 0 } else { r(rt) };
    match *i {
        LslImm { rd, rm, imm } => {
            let sets = if imm == 0 { N | Z } else { N | Z | C };
            e(r(rm), r(rd), 0, sets, Some(rd))
        }
        LsrImm { rd, rm, .. } | AsrImm { rd, rm, .. } => e(r(rm), r(rd), 0, N | Z | C, Some(rd)),
        AddReg { rd, rn, rm } | SubReg { rd, rn, rm } => e(r(rn) | r(rm), r(rd), 0, ALL, Some(rd)),
        AddImm { rd, rn, .. } | SubImm { rd, rn, .. } => e(r(rn), r(rd), 0, ALL, Some(rd)),
        MovImm { rd, .. } => e(0, r(rd), 0, N | Z, Some(rd)),
        CmpImm { rn, imm } => e(r(rn), 0, 0, ALL, (imm == 0).then_some(rn)),
        CmpHi { rn, rm } => e(r(rn) | r(rm), 0, 0, ALL, None),
        Alu { op, rdn, rm } => {
            let reads = match op {
                AluOp::Rsb | AluOp::Mvn => r(rm),
                _ => r(rdn) | r(rm),
            };
            match op {
                AluOp::Tst => e(reads, 0, 0, N | Z, None),
                AluOp::Cmp | AluOp::Cmn => e(reads, 0, 0, ALL, None),
                AluOp::Adc | AluOp::Sbc => e(reads, r(rdn), C, ALL, Some(rdn)),
                AluOp::Rsb => e(reads, r(rdn), 0, ALL, Some(rdn)),
                // A shift by a register leaves C alone when the amount is 0.
                AluOp::Lsl | AluOp::Lsr | AluOp::Asr | AluOp::Ror => {
                    e(reads, r(rdn), 0, N | Z, Some(rdn))
                }
                AluOp::And | AluOp::Eor | AluOp::Orr | AluOp::Mul | AluOp::Bic | AluOp::Mvn => {
                    e(reads, r(rdn), 0, N | Z, Some(rdn))
                }
            }
        }
        AddHi { rdn, rm } if rdn != 15 => e(r(rdn) | r(rm), r(rdn), 0, 0, None),
        MovHi { rd, rm } if rd != 15 => e(r(rm), r(rd), 0, 0, None),
        LdrLit { rt, .. } => e(0, r(rt), 0, 0, None),
        MemReg { op, rt, rn, rm } => e(r(rn) | r(rm) | stored(op, rt), loaded(op, rt), 0, 0, None),
        MemImm { op, rt, rn, .. } => e(r(rn) | stored(op, rt), loaded(op, rt), 0, 0, None),
        Adr { rd, .. } => e(0, r(rd), 0, 0, None),
        AddSpImm { rd, .. } => e(r(13), r(rd), 0, 0, None),
        AddSp { .. } | SubSp { .. } => e(r(13), r(13), 0, 0, None),
        Push { list } => e(list | r(13), r(13), 0, 0, None),
        Pop { list } if list & 1 << 15 == 0 => e(r(13), list | r(13), 0, 0, None),
        Sxth { rd, rm }
        | Sxtb { rd, rm }
        | Uxth { rd, rm }
        | Uxtb { rd, rm }
        | Rev { rd, rm }
        | Rev16 { rd, rm }
        | Revsh { rd, rm } => e(r(rm), r(rd), 0, 0, None),
        Stm { rn, list } => e(r(rn) | u16::from(list), r(rn), 0, 0, None),
        Ldm { rn, list } => e(r(rn), r(rn) | u16::from(list), 0, 0, None),
        Mrs { rd, .. } => e(0, r(rd), 0, 0, None),
        Hint(_) | Cps { .. } | Barrier(_) => e(0, 0, 0, 0, None),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decode::MemOp;

    #[test]
    fn loads_write_what_stores_read() {
        let (rt, rn) = (2, 5);
        let ld = effect(&Instr::MemImm {
            op: MemOp::Ldr,
            rt,
            rn,
            imm: 4,
        })
        .unwrap();
        let st = effect(&Instr::MemImm {
            op: MemOp::Str,
            rt,
            rn,
            imm: 4,
        })
        .unwrap();
        assert_eq!((ld.reads, ld.writes), (1 << rn, 1 << rt));
        assert_eq!((st.reads, st.writes), (1 << rn | 1 << rt, 0));
    }

    #[test]
    fn control_transfers_and_msr_have_no_effect() {
        for i in [
            Instr::B { offset: 0 },
            Instr::Bl { offset: 0 },
            Instr::Bx { rm: 14 },
            Instr::Pop { list: 1 << 15 | 1 },
            Instr::MovHi { rd: 15, rm: 0 },
            Instr::AddHi { rdn: 15, rm: 0 },
            Instr::Msr { sysm: 0, rn: 0 },
        ] {
            assert_eq!(effect(&i), None, "{i:?}");
        }
    }

    #[test]
    fn conditions_read_their_flags() {
        // EQ reads Z, HI (8) C and Z, GT (12) N, Z and V, AL none (A6.3).
        assert_eq!([0, 8, 12, 14].map(cond_reads), [Z, C | Z, N | Z | V, 0]);
        let adcs = effect(&Instr::Alu {
            op: AluOp::Adc,
            rdn: 1,
            rm: 2,
        })
        .unwrap();
        assert_eq!(
            (adcs.flags_read, adcs.flags_set, adcs.nz),
            (C, ALL, Some(1))
        );
    }
}
