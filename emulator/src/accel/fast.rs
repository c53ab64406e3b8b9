//! Pre-decoded operations for the board's fast path.
//!
//! The decode cache keeps, next to each [`Instr`], an [`Op`]: the same instruction with the
//! work that depends only on its address done once — branch targets, literal addresses and
//! ADR values are absolute — and the most frequent forms given variants of their own (one
//! per data-processing operation, memory access width and branch condition), so executing
//! one is a single `match` with no nested dispatch. Everything else is [`Op::Other`], which
//! runs through [`Core::execute_fast`] on the `Instr`. [`Core::execute_op`] has the same
//! contract as `execute_fast`: do the whole instruction exactly as [`Core::execute`] would
//! and return true, or touch nothing and return false for the general path.

use crate::core::Core;
use crate::exec::{branch_target, literal_address};
use crate::system::System;
use tactus_isa::decode::{AluOp, Hint, Instr, MemOp};

/// A pre-decoded instruction (see the module documentation). Register fields are 0-15,
/// `imm`s are in bytes, `target`s and `addr`/`value`s absolute.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Op {
    LslImm {
        rd: u8,
        rm: u8,
        imm: u8,
    },
    LsrImm {
        rd: u8,
        rm: u8,
        imm: u8,
    },
    AsrImm {
        rd: u8,
        rm: u8,
        imm: u8,
    },
    AddReg {
        rd: u8,
        rn: u8,
        rm: u8,
    },
    SubReg {
        rd: u8,
        rn: u8,
        rm: u8,
    },
    AddImm {
        rd: u8,
        rn: u8,
        imm: u8,
    },
    SubImm {
        rd: u8,
        rn: u8,
        imm: u8,
    },
    MovImm {
        rd: u8,
        imm: u8,
    },
    CmpImm {
        rn: u8,
        imm: u8,
    },
    And {
        rdn: u8,
        rm: u8,
    },
    Eor {
        rdn: u8,
        rm: u8,
    },
    Orr {
        rdn: u8,
        rm: u8,
    },
    Bic {
        rdn: u8,
        rm: u8,
    },
    Mvn {
        rdn: u8,
        rm: u8,
    },
    Tst {
        rdn: u8,
        rm: u8,
    },
    Mul {
        rdn: u8,
        rm: u8,
    },
    Cmp {
        rdn: u8,
        rm: u8,
    },
    /// The other register data-processing operations.
    Alu {
        op: AluOp,
        rdn: u8,
        rm: u8,
    },
    /// `MOV Rd, Rm` with Rd not SP or PC and Rm not PC.
    Mov {
        rd: u8,
        rm: u8,
    },
    /// `ADD Rdn, Rm` with Rdn not SP or PC and Rm not PC.
    AddHi {
        rdn: u8,
        rm: u8,
    },
    Ldr {
        rt: u8,
        rn: u8,
        imm: u16,
    },
    Str {
        rt: u8,
        rn: u8,
        imm: u16,
    },
    Ldrb {
        rt: u8,
        rn: u8,
        imm: u16,
    },
    Strb {
        rt: u8,
        rn: u8,
        imm: u16,
    },
    Ldrh {
        rt: u8,
        rn: u8,
        imm: u16,
    },
    Strh {
        rt: u8,
        rn: u8,
        imm: u16,
    },
    LdrReg {
        rt: u8,
        rn: u8,
        rm: u8,
    },
    StrReg {
        rt: u8,
        rn: u8,
        rm: u8,
    },
    LdrbReg {
        rt: u8,
        rn: u8,
        rm: u8,
    },
    StrbReg {
        rt: u8,
        rn: u8,
        rm: u8,
    },
    LdrLit {
        rt: u8,
        addr: u32,
    },
    Adr {
        rd: u8,
        value: u32,
    },
    AddSp {
        imm: u16,
    },
    SubSp {
        imm: u16,
    },
    B {
        target: u32,
    },
    Beq {
        target: u32,
    },
    Bne {
        target: u32,
    },
    Bcs {
        target: u32,
    },
    Bcc {
        target: u32,
    },
    Bmi {
        target: u32,
    },
    Bpl {
        target: u32,
    },
    Bhi {
        target: u32,
    },
    Bls {
        target: u32,
    },
    Bge {
        target: u32,
    },
    Blt {
        target: u32,
    },
    Bgt {
        target: u32,
    },
    Ble {
        target: u32,
    },
    /// `B<cond>` for VS and VC.
    BCond {
        cond: u8,
        target: u32,
    },
    Bl {
        target: u32,
    },
    Push {
        list: u16,
    },
    Pop {
        list: u16,
    },
    Nop,
    /// Anything else: run the `Instr` through [`Core::execute_fast`].
    Other,
}

impl Op {
    /// The operation for `instr` at address `pc`.
    pub(crate) fn new(instr: &Instr, pc: u32) -> Op {
        let rel = |offset: i32| branch_target(pc, offset);
        let lit = |imm: u16| literal_address(pc, imm);
        match *instr {
            Instr::LslImm { rd, rm, imm } => Op::LslImm { rd, rm, imm },
            Instr::LsrImm { rd, rm, imm } => Op::LsrImm { rd, rm, imm },
            Instr::AsrImm { rd, rm, imm } => Op::AsrImm { rd, rm, imm },
            Instr::AddReg { rd, rn, rm } => Op::AddReg { rd, rn, rm },
            Instr::SubReg { rd, rn, rm } => Op::SubReg { rd, rn, rm },
            Instr::AddImm { rd, rn, imm } => Op::AddImm { rd, rn, imm },
            Instr::SubImm { rd, rn, imm } => Op::SubImm { rd, rn, imm },
            Instr::MovImm { rd, imm } => Op::MovImm { rd, imm },
            Instr::CmpImm { rn, imm } => Op::CmpImm { rn, imm },
            Instr::Alu { op, rdn, rm } => match op {
                AluOp::And => Op::And { rdn, rm },
                AluOp::Eor => Op::Eor { rdn, rm },
                AluOp::Orr => Op::Orr { rdn, rm },
                AluOp::Bic => Op::Bic { rdn, rm },
                AluOp::Mvn => Op::Mvn { rdn, rm },
                AluOp::Tst => Op::Tst { rdn, rm },
                AluOp::Mul => Op::Mul { rdn, rm },
                AluOp::Cmp => Op::Cmp { rdn, rm },
                _ => Op::Alu { op, rdn, rm },
            },
            Instr::MovHi { rd, rm } if rd < 13 && rm != 15 => Op::Mov { rd, rm },
            Instr::AddHi { rdn, rm } if rdn < 13 && rm != 15 => Op::AddHi { rdn, rm },
            Instr::MemImm { op, rt, rn, imm } if rn != 15 => match op {
                MemOp::Ldr => Op::Ldr { rt, rn, imm },
                MemOp::Str => Op::Str { rt, rn, imm },
                MemOp::Ldrb => Op::Ldrb { rt, rn, imm },
                MemOp::Strb => Op::Strb { rt, rn, imm },
                MemOp::Ldrh => Op::Ldrh { rt, rn, imm },
                MemOp::Strh => Op::Strh { rt, rn, imm },
                _ => Op::Other,
            },
            Instr::MemReg { op, rt, rn, rm } if rn != 15 && rm != 15 => match op {
                MemOp::Ldr => Op::LdrReg { rt, rn, rm },
                MemOp::Str => Op::StrReg { rt, rn, rm },
                MemOp::Ldrb => Op::LdrbReg { rt, rn, rm },
                MemOp::Strb => Op::StrbReg { rt, rn, rm },
                _ => Op::Other,
            },
            Instr::LdrLit { rt, imm } => Op::LdrLit { rt, addr: lit(imm) },
            Instr::Adr { rd, imm } => Op::Adr {
                rd,
                value: lit(imm),
            },
            Instr::AddSp { imm } => Op::AddSp { imm },
            Instr::SubSp { imm } => Op::SubSp { imm },
            Instr::B { offset } => Op::B {
                target: rel(offset),
            },
            Instr::BCond { cond, offset } => {
                let target = rel(offset);
                match cond {
                    0 => Op::Beq { target },
                    1 => Op::Bne { target },
                    2 => Op::Bcs { target },
                    3 => Op::Bcc { target },
                    4 => Op::Bmi { target },
                    5 => Op::Bpl { target },
                    8 => Op::Bhi { target },
                    9 => Op::Bls { target },
                    10 => Op::Bge { target },
                    11 => Op::Blt { target },
                    12 => Op::Bgt { target },
                    13 => Op::Ble { target },
                    _ => Op::BCond { cond, target },
                }
            }
            Instr::Bl { offset } => Op::Bl {
                target: rel(offset),
            },
            Instr::Push { list } => Op::Push { list },
            Instr::Pop { list } => Op::Pop { list },
            Instr::Hint(Hint::Nop) => Op::Nop,
            _ => Op::Other,
        }
    }
}

impl Core {
    /// [`Core::execute_fast`] out of line, for the less common instructions: keeps the hot
    /// loops (two copies of them when both cores run) small.
    #[inline(never)]
    fn execute_other(
        &mut self,
        sys: &mut System,
        instr: &Instr,
        pc: u32,
        size: u32,
        cost: (u8, u8),
    ) -> bool {
        self.execute_fast(sys, *instr, pc, size, cost)
    }

    /// Executes pre-decoded `op` (the instruction `instr` at `pc`, of `size` bytes, costing
    /// `cost` = (not taken, taken) cycles): the contract of [`Core::execute_fast`].
    #[inline(always)]
    pub(crate) fn execute_op(
        &mut self,
        sys: &mut System,
        op: &Op,
        instr: &Instr,
        pc: u32,
        size: u32,
        cost: (u8, u8),
    ) -> bool {
        let next = pc.wrapping_add(2);
        let base = cost.0 as u64;
        let now = self.cycle;
        macro_rules! r {
            ($i:expr) => {
                self.r[($i & 15) as usize]
            };
        }
        // A 16-bit instruction that falls through: write PC and count it.
        macro_rules! done {
            ($cycles:expr) => {{
                self.r[15] = next;
                return self.retire($cycles);
            }};
        }
        macro_rules! branch {
            ($taken:expr, $target:expr) => {{
                if $taken {
                    self.r[15] = $target;
                    return self.retire(cost.1 as u64);
                }
                done!(base)
            }};
        }
        macro_rules! dp {
            ($call:expr) => {{
                $call;
                done!(base)
            }};
        }
        macro_rules! alu {
            ($op:expr, $rdn:expr, $rm:expr) => {
                dp!(self.alu($op, ($rdn & 15) as usize, r!($rm)))
            };
        }
        macro_rules! mem {
            ($op:expr, $rt:expr, $addr:expr) => {{
                match self.mem_fast(sys, $op, $rt, $addr, now + 1) {
                    Some(w) => done!(base + w as u64),
                    None => return false,
                }
            }};
        }
        match *op {
            // Data processing: the one definition of each (`exec.rs`), as the interpreter's
            // `Core::data_processing` calls it.
            Op::LslImm { rd, rm, imm } => dp!(self.lsl_imm(rd, rm, imm)),
            Op::LsrImm { rd, rm, imm } => dp!(self.lsr_imm(rd, rm, imm)),
            Op::AsrImm { rd, rm, imm } => dp!(self.asr_imm(rd, rm, imm)),
            Op::AddReg { rd, rn, rm } => dp!(self.add_reg(rd, rn, rm)),
            Op::SubReg { rd, rn, rm } => dp!(self.sub_reg(rd, rn, rm)),
            Op::AddImm { rd, rn, imm } => dp!(self.add_imm(rd, rn, imm)),
            Op::SubImm { rd, rn, imm } => dp!(self.sub_imm(rd, rn, imm)),
            Op::MovImm { rd, imm } => dp!(self.mov_imm(rd, imm)),
            Op::CmpImm { rn, imm } => dp!(self.cmp_imm(rn, imm)),
            Op::And { rdn, rm } => alu!(AluOp::And, rdn, rm),
            Op::Eor { rdn, rm } => alu!(AluOp::Eor, rdn, rm),
            Op::Orr { rdn, rm } => alu!(AluOp::Orr, rdn, rm),
            Op::Bic { rdn, rm } => alu!(AluOp::Bic, rdn, rm),
            Op::Mvn { rdn, rm } => alu!(AluOp::Mvn, rdn, rm),
            Op::Tst { rdn, rm } => alu!(AluOp::Tst, rdn, rm),
            Op::Mul { rdn, rm } => alu!(AluOp::Mul, rdn, rm),
            Op::Cmp { rdn, rm } => alu!(AluOp::Cmp, rdn, rm),
            Op::Alu { op, rdn, rm } => alu!(op, rdn, rm),
            Op::Mov { rd, rm } => {
                self.hi_reg_op(Instr::MovHi { rd, rm }, pc);
                done!(base)
            }
            Op::AddHi { rdn, rm } => {
                self.hi_reg_op(Instr::AddHi { rdn, rm }, pc);
                done!(base)
            }
            Op::Ldr { rt, rn, imm } => mem!(MemOp::Ldr, rt, r!(rn).wrapping_add(imm as u32)),
            Op::Str { rt, rn, imm } => mem!(MemOp::Str, rt, r!(rn).wrapping_add(imm as u32)),
            Op::Ldrb { rt, rn, imm } => mem!(MemOp::Ldrb, rt, r!(rn).wrapping_add(imm as u32)),
            Op::Strb { rt, rn, imm } => mem!(MemOp::Strb, rt, r!(rn).wrapping_add(imm as u32)),
            Op::Ldrh { rt, rn, imm } => mem!(MemOp::Ldrh, rt, r!(rn).wrapping_add(imm as u32)),
            Op::Strh { rt, rn, imm } => mem!(MemOp::Strh, rt, r!(rn).wrapping_add(imm as u32)),
            Op::LdrReg { rt, rn, rm } => mem!(MemOp::Ldr, rt, r!(rn).wrapping_add(r!(rm))),
            Op::StrReg { rt, rn, rm } => mem!(MemOp::Str, rt, r!(rn).wrapping_add(r!(rm))),
            Op::LdrbReg { rt, rn, rm } => mem!(MemOp::Ldrb, rt, r!(rn).wrapping_add(r!(rm))),
            Op::StrbReg { rt, rn, rm } => mem!(MemOp::Strb, rt, r!(rn).wrapping_add(r!(rm))),
            Op::LdrLit { rt, addr } => mem!(MemOp::Ldr, rt, addr),
            Op::Adr { rd, value } => {
                r!(rd) = value;
                done!(base)
            }
            Op::AddSp { imm } => {
                self.r[13] = self.r[13].wrapping_add(imm as u32);
                done!(base)
            }
            Op::SubSp { imm } => {
                self.r[13] = self.r[13].wrapping_sub(imm as u32);
                done!(base)
            }
            Op::B { target } => {
                self.r[15] = target;
                self.retire(base)
            }
            Op::Beq { target } => branch!(self.condition(0), target),
            Op::Bne { target } => branch!(self.condition(1), target),
            Op::Bcs { target } => branch!(self.condition(2), target),
            Op::Bcc { target } => branch!(self.condition(3), target),
            Op::Bmi { target } => branch!(self.condition(4), target),
            Op::Bpl { target } => branch!(self.condition(5), target),
            Op::Bhi { target } => branch!(self.condition(8), target),
            Op::Bls { target } => branch!(self.condition(9), target),
            Op::Bge { target } => branch!(self.condition(10), target),
            Op::Blt { target } => branch!(self.condition(11), target),
            Op::Bgt { target } => branch!(self.condition(12), target),
            Op::Ble { target } => branch!(self.condition(13), target),
            Op::BCond { cond, target } => branch!(self.condition(cond), target),
            Op::Bl { target } => {
                self.r[14] = pc.wrapping_add(4) | 1;
                self.r[15] = target;
                self.retire(base)
            }
            Op::Push { list } => self.push_fast(sys, list, next, base),
            Op::Pop { list } => self.pop_fast(sys, list, next, base),
            Op::Nop => done!(base),
            Op::Other => self.execute_other(sys, instr, pc, size, cost),
        }
    }
}
