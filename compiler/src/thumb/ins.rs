//! Instruction shorthands for hand-written Thumb code (the firmware image's glue and boot
//! stub): the emulator's [`Instr`] values for the common forms, registers r0–r7 unless
//! noted, and the branch condition codes. Emit them into a
//! [`CodeBuffer`](super::buffer::CodeBuffer).

use tactus_isa::decode::{AluOp, Instr, MemOp};

/// Branch conditions (ARMv6-M A6.3).
pub mod cond {
    /// Equal (Z).
    pub const EQ: u8 = 0;
    /// Not equal.
    pub const NE: u8 = 1;
    /// Carry set (unsigned ≥).
    pub const CS: u8 = 2;
    /// Carry clear (unsigned <).
    pub const CC: u8 = 3;
    /// Negative (N).
    pub const MI: u8 = 4;
    /// Positive or zero.
    pub const PL: u8 = 5;
    /// Unsigned higher.
    pub const HI: u8 = 8;
    /// Unsigned lower or same.
    pub const LS: u8 = 9;
    /// Signed ≥.
    pub const GE: u8 = 10;
    /// Signed <.
    pub const LT: u8 = 11;
    /// Signed >.
    pub const GT: u8 = 12;
    /// Signed ≤.
    pub const LE: u8 = 13;
}

/// `LDR rt, [rn, #imm]` (imm a multiple of 4, ≤ 124).
pub fn ldr(rt: u8, rn: u8, imm: u16) -> Instr {
    Instr::MemImm {
        op: MemOp::Ldr,
        rt,
        rn,
        imm,
    }
}

/// `STR rt, [rn, #imm]`.
pub fn str(rt: u8, rn: u8, imm: u16) -> Instr {
    Instr::MemImm {
        op: MemOp::Str,
        rt,
        rn,
        imm,
    }
}

/// `LDR rt, [rn, rm]`.
pub fn ldr_reg(rt: u8, rn: u8, rm: u8) -> Instr {
    Instr::MemReg {
        op: MemOp::Ldr,
        rt,
        rn,
        rm,
    }
}

/// `MOVS rd, #imm`.
pub fn movs(rd: u8, imm: u8) -> Instr {
    Instr::MovImm { rd, imm }
}

/// `MOVS rd, rm` (encoded as `LSLS rd, rm, #0`).
pub fn mov(rd: u8, rm: u8) -> Instr {
    Instr::LslImm { rd, rm, imm: 0 }
}

/// `ADDS rd, rn, #imm` (imm ≤ 7, or rd = rn and imm ≤ 255).
pub fn adds_imm(rd: u8, rn: u8, imm: u8) -> Instr {
    Instr::AddImm { rd, rn, imm }
}

/// `SUBS rd, rn, #imm`.
pub fn subs_imm(rd: u8, rn: u8, imm: u8) -> Instr {
    Instr::SubImm { rd, rn, imm }
}

/// `ADDS rd, rn, rm`.
pub fn adds(rd: u8, rn: u8, rm: u8) -> Instr {
    Instr::AddReg { rd, rn, rm }
}

/// `SUBS rd, rn, rm`.
pub fn subs(rd: u8, rn: u8, rm: u8) -> Instr {
    Instr::SubReg { rd, rn, rm }
}

/// `<op>S rdn, rm`.
pub fn alu(op: AluOp, rdn: u8, rm: u8) -> Instr {
    Instr::Alu { op, rdn, rm }
}

/// `CMP rn, #imm`.
pub fn cmp_imm(rn: u8, imm: u8) -> Instr {
    Instr::CmpImm { rn, imm }
}

/// `CMP rn, rm`.
pub fn cmp(rn: u8, rm: u8) -> Instr {
    Instr::Alu {
        op: AluOp::Cmp,
        rdn: rn,
        rm,
    }
}

/// `LSLS rd, rm, #imm`.
pub fn lsls(rd: u8, rm: u8, imm: u8) -> Instr {
    Instr::LslImm { rd, rm, imm }
}

/// `LSRS rd, rm, #imm` (1-32).
pub fn lsrs(rd: u8, rm: u8, imm: u8) -> Instr {
    Instr::LsrImm { rd, rm, imm }
}

/// `ASRS rd, rm, #imm` (1-32).
pub fn asrs(rd: u8, rm: u8, imm: u8) -> Instr {
    Instr::AsrImm { rd, rm, imm }
}

/// `NEGS rd, rm` (`RSBS rd, rm, #0`).
pub fn negs(rd: u8, rm: u8) -> Instr {
    Instr::Alu {
        op: AluOp::Rsb,
        rdn: rd,
        rm,
    }
}

/// `PUSH {r<list>, lr}` (`list` bits 0-7).
pub fn push_lr(list: u8) -> Instr {
    Instr::Push {
        list: list as u16 | 0x4000,
    }
}

/// `POP {r<list>, pc}`.
pub fn pop_pc(list: u8) -> Instr {
    Instr::Pop {
        list: list as u16 | 0x8000,
    }
}
