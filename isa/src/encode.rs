//! The encoder: [`Instr`] → Thumb machine code, the inverse of [`crate::decode`].
//!
//! One `enc_<format>` function per encoding class of the ARMv6-M Architecture Reference
//! Manual (DDI0419, section A5/A6), its arguments named after the bit fields, each field
//! checked for width. The code generator (issue 5) emits through this, so the ISA's bit
//! layouts live in this crate only: the decoder and encoder are tested against each other
//! on all 65,536 16-bit halfwords (decode → encode → decode gives the same instruction),
//! and the decoder against `arm-none-eabi-as`.
//!
//! Where an instruction has two encodings the encoder picks the one GNU `as` prefers for
//! the same unified-syntax text: `ADDS Rd, Rn, #imm` takes the 3-bit form when `imm ≤ 7`
//! and the `Rdn` 8-bit form otherwise; `MOVS Rd, Rm` is `LSLS Rd, Rm, #0`.

use crate::decode::{AluOp, Barrier, Hint, Instr, MemOp};
use std::fmt;

/// A 16-bit or 32-bit encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// One halfword.
    Half(u16),
    /// Two halfwords, first in memory first.
    Word(u16, u16),
}

impl Encoding {
    /// The halfwords in memory order.
    pub fn halfwords(self) -> Vec<u16> {
        match self {
            Encoding::Half(h) => vec![h],
            Encoding::Word(a, b) => vec![a, b],
        }
    }
    /// Little-endian bytes, as they sit in memory.
    pub fn bytes(self) -> Vec<u8> {
        self.halfwords()
            .into_iter()
            .flat_map(|h| h.to_le_bytes())
            .collect()
    }
}

/// An instruction whose fields do not fit any encoding (a code-generator bug).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EncodeError {
    /// The instruction, printed.
    pub instr: String,
    /// Which field and why.
    pub reason: String,
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "cannot encode `{}`: {}", self.instr, self.reason)
    }
}

impl std::error::Error for EncodeError {}

type R<T> = Result<T, String>;

/// Checks that `v` fits `bits` unsigned bits.
fn field(name: &str, v: u32, bits: u32) -> R<u16> {
    if v < (1 << bits) {
        Ok(v as u16)
    } else {
        Err(format!("`{name}` = {v} does not fit {bits} bits"))
    }
}

/// Checks a byte offset scaled by `scale` into `bits` bits (multiple of `scale`).
fn scaled(name: &str, v: u32, scale: u32, bits: u32) -> R<u16> {
    if !v.is_multiple_of(scale) {
        return Err(format!("`{name}` = {v} is not a multiple of {scale}"));
    }
    field(name, v / scale, bits)
}

/// Checks a signed halfword branch offset into `bits` bits (two's complement of offset/2).
fn branch(name: &str, offset: i32, bits: u32) -> R<u32> {
    if offset % 2 != 0 {
        return Err(format!("`{name}` = {offset} is odd"));
    }
    let half = offset / 2;
    let lim = 1i32 << (bits - 1);
    if half < -lim || half >= lim {
        return Err(format!(
            "`{name}` = {offset} bytes is out of range (±{} bytes)",
            lim * 2
        ));
    }
    Ok((half as u32) & ((1 << bits) - 1))
}

/// `op(2) imm5 Rm Rd` — LSLS/LSRS/ASRS (immediate), DDI0419 A6.7.35/37/10.
pub fn enc_shift_imm(op: u16, imm5: u16, rm: u16, rd: u16) -> u16 {
    (op << 11) | (imm5 << 6) | (rm << 3) | rd
}
/// `0001 1 op Rm Rn Rd` — ADDS/SUBS (register), T1.
pub fn enc_add_sub_reg(sub: bool, rm: u16, rn: u16, rd: u16) -> u16 {
    0x1800 | (u16::from(sub) << 9) | (rm << 6) | (rn << 3) | rd
}
/// `0001 1 1 op imm3 Rn Rd` — ADDS/SUBS (immediate), T1.
pub fn enc_add_sub_imm3(sub: bool, imm3: u16, rn: u16, rd: u16) -> u16 {
    0x1c00 | (u16::from(sub) << 9) | (imm3 << 6) | (rn << 3) | rd
}
/// `001 op(2) Rdn imm8` — MOVS/CMP/ADDS/SUBS (8-bit immediate).
pub fn enc_imm8(op: u16, rdn: u16, imm8: u16) -> u16 {
    0x2000 | (op << 11) | (rdn << 8) | imm8
}
/// `010000 op(4) Rm Rdn` — data processing (register).
pub fn enc_alu(op: u16, rm: u16, rdn: u16) -> u16 {
    0x4000 | (op << 6) | (rm << 3) | rdn
}
/// `010001 op(2) DN Rm(4) Rdn(3)` — ADD/CMP/MOV (high registers).
pub fn enc_hi(op: u16, rdn4: u16, rm4: u16) -> u16 {
    0x4400 | (op << 8) | ((rdn4 & 8) << 4) | (rm4 << 3) | (rdn4 & 7)
}
/// `010001 11 L Rm(4) 000` — BX/BLX (register).
pub fn enc_bx(link: bool, rm4: u16) -> u16 {
    0x4700 | (u16::from(link) << 7) | (rm4 << 3)
}
/// `01001 Rt imm8` — LDR (literal), imm8 = offset/4.
pub fn enc_ldr_lit(rt: u16, imm8: u16) -> u16 {
    0x4800 | (rt << 8) | imm8
}
/// `0101 opB(3) Rm Rn Rt` — load/store (register offset).
pub fn enc_mem_reg(opb: u16, rm: u16, rn: u16, rt: u16) -> u16 {
    0x5000 | (opb << 9) | (rm << 6) | (rn << 3) | rt
}
/// `opA(5) imm5 Rn Rt` — load/store (immediate offset): STR 01100, LDR 01101, STRB 01110,
/// LDRB 01111, STRH 10000, LDRH 10001; imm5 already scaled.
pub fn enc_mem_imm(opa: u16, imm5: u16, rn: u16, rt: u16) -> u16 {
    (opa << 11) | (imm5 << 6) | (rn << 3) | rt
}
/// `opA(5) Rd imm8` — SP-relative STR/LDR (10010/10011), ADR (10100), ADD Rd, SP (10101).
pub fn enc_rd_imm8(opa: u16, rd: u16, imm8: u16) -> u16 {
    (opa << 11) | (rd << 8) | imm8
}
/// `1011 0000 S imm7` — ADD/SUB SP, SP, #imm (imm7 = imm/4).
pub fn enc_sp_adjust(sub: bool, imm7: u16) -> u16 {
    0xb000 | (u16::from(sub) << 7) | imm7
}
/// `1011 op4 op2 Rm Rd` — extend (op4 0010) and reverse (op4 1010) instructions.
pub fn enc_misc_rr(op4: u16, op2: u16, rm: u16, rd: u16) -> u16 {
    0xb000 | (op4 << 8) | (op2 << 6) | (rm << 3) | rd
}
/// `1011 L 10 R list8` — PUSH (L=0, R=LR) / POP (L=1, R=PC).
pub fn enc_push_pop(pop: bool, extra: bool, list8: u16) -> u16 {
    0xb400 | (u16::from(pop) << 11) | (u16::from(extra) << 8) | list8
}
/// `1100 L Rn list8` — STM (L=0) / LDM (L=1).
pub fn enc_ldm_stm(load: bool, rn: u16, list8: u16) -> u16 {
    0xc000 | (u16::from(load) << 11) | (rn << 8) | list8
}
/// `1101 cond imm8` — B<cond>, UDF (cond 1110), SVC (cond 1111).
pub fn enc_cond(cond: u16, imm8: u16) -> u16 {
    0xd000 | (cond << 8) | imm8
}
/// `11100 imm11` — B.
pub fn enc_b(imm11: u16) -> u16 {
    0xe000 | imm11
}
/// BL: `11110 S imm10`, `11 J1 1 J2 imm11` with `J = NOT(I) XOR S`.
pub fn enc_bl(imm25: u32) -> (u16, u16) {
    let s = (imm25 >> 24) & 1;
    let i1 = (imm25 >> 23) & 1;
    let i2 = (imm25 >> 22) & 1;
    let j1 = (!i1 ^ s) & 1;
    let j2 = (!i2 ^ s) & 1;
    let hw1 = 0xf000 | (s << 10) | ((imm25 >> 12) & 0x3ff);
    let hw2 = 0xd000 | (j1 << 13) | (j2 << 11) | ((imm25 >> 1) & 0x7ff);
    (hw1 as u16, hw2 as u16)
}

fn alu_code(op: AluOp) -> u16 {
    AluOp::TABLE.iter().position(|o| *o == op).unwrap_or(0) as u16
}

fn mem_reg_code(op: MemOp) -> u16 {
    match op {
        MemOp::Str => 0,
        MemOp::Strh => 1,
        MemOp::Strb => 2,
        MemOp::Ldrsb => 3,
        MemOp::Ldr => 4,
        MemOp::Ldrh => 5,
        MemOp::Ldrb => 6,
        MemOp::Ldrsh => 7,
    }
}

/// Encodes one instruction; fails with the field that does not fit.
pub fn encode(i: &Instr) -> Result<Encoding, EncodeError> {
    encode_inner(i).map_err(|reason| EncodeError {
        instr: i.to_string(),
        reason,
    })
}

fn lo(name: &str, r: u8) -> R<u16> {
    if r < 8 {
        Ok(r as u16)
    } else {
        Err(format!("`{name}` = r{r} must be a low register (r0-r7)"))
    }
}

fn reg(name: &str, r: u8) -> R<u16> {
    field(name, r as u32, 4)
}

fn encode_inner(i: &Instr) -> R<Encoding> {
    use Encoding::Half;
    use Instr::*;
    Ok(match *i {
        LslImm { rd, rm, imm } => Half(enc_shift_imm(
            0,
            field("imm", imm as u32, 5)?,
            lo("rm", rm)?,
            lo("rd", rd)?,
        )),
        LsrImm { rd, rm, imm } | AsrImm { rd, rm, imm } => {
            let op = if matches!(i, LsrImm { .. }) { 1 } else { 2 };
            if !(1..=32).contains(&imm) {
                return Err(format!("`imm` = {imm} must be 1-32"));
            }
            Half(enc_shift_imm(
                op,
                (imm % 32) as u16,
                lo("rm", rm)?,
                lo("rd", rd)?,
            ))
        }
        AddReg { rd, rn, rm } => Half(enc_add_sub_reg(
            false,
            lo("rm", rm)?,
            lo("rn", rn)?,
            lo("rd", rd)?,
        )),
        SubReg { rd, rn, rm } => Half(enc_add_sub_reg(
            true,
            lo("rm", rm)?,
            lo("rn", rn)?,
            lo("rd", rd)?,
        )),
        AddImm { rd, rn, imm } | SubImm { rd, rn, imm } => {
            let sub = matches!(i, SubImm { .. });
            if imm <= 7 {
                Half(enc_add_sub_imm3(
                    sub,
                    imm as u16,
                    lo("rn", rn)?,
                    lo("rd", rd)?,
                ))
            } else if rd == rn {
                Half(enc_imm8(
                    if sub { 3 } else { 2 },
                    lo("rdn", rd)?,
                    imm as u16,
                ))
            } else {
                return Err(format!(
                    "`imm` = {imm} needs Rd = Rn (8-bit form) or imm ≤ 7"
                ));
            }
        }
        MovImm { rd, imm } => Half(enc_imm8(0, lo("rd", rd)?, imm as u16)),
        CmpImm { rn, imm } => Half(enc_imm8(1, lo("rn", rn)?, imm as u16)),
        Alu { op, rdn, rm } => Half(enc_alu(alu_code(op), lo("rm", rm)?, lo("rdn", rdn)?)),
        AddHi { rdn, rm } => Half(enc_hi(0, reg("rdn", rdn)?, reg("rm", rm)?)),
        CmpHi { rn, rm } => Half(enc_hi(1, reg("rn", rn)?, reg("rm", rm)?)),
        MovHi { rd, rm } => Half(enc_hi(2, reg("rd", rd)?, reg("rm", rm)?)),
        Bx { rm } => Half(enc_bx(false, reg("rm", rm)?)),
        Blx { rm } => Half(enc_bx(true, reg("rm", rm)?)),
        LdrLit { rt, imm } => Half(enc_ldr_lit(lo("rt", rt)?, scaled("imm", imm as u32, 4, 8)?)),
        MemReg { op, rt, rn, rm } => Half(enc_mem_reg(
            mem_reg_code(op),
            lo("rm", rm)?,
            lo("rn", rn)?,
            lo("rt", rt)?,
        )),
        MemImm {
            op,
            rt,
            rn: 13,
            imm,
        } => {
            let opa = match op {
                MemOp::Str => 0b10010,
                MemOp::Ldr => 0b10011,
                _ => return Err("only LDR/STR have an SP-relative form".into()),
            };
            Half(enc_rd_imm8(
                opa,
                lo("rt", rt)?,
                scaled("imm", imm as u32, 4, 8)?,
            ))
        }
        MemImm { op, rt, rn, imm } => {
            let (opa, scale) = match op {
                MemOp::Str => (0b01100, 4),
                MemOp::Ldr => (0b01101, 4),
                MemOp::Strb => (0b01110, 1),
                MemOp::Ldrb => (0b01111, 1),
                MemOp::Strh => (0b10000, 2),
                MemOp::Ldrh => (0b10001, 2),
                _ => return Err("LDRSB/LDRSH have only the register-offset form".into()),
            };
            Half(enc_mem_imm(
                opa,
                scaled("imm", imm as u32, scale, 5)?,
                lo("rn", rn)?,
                lo("rt", rt)?,
            ))
        }
        Adr { rd, imm } => Half(enc_rd_imm8(
            0b10100,
            lo("rd", rd)?,
            scaled("imm", imm as u32, 4, 8)?,
        )),
        AddSpImm { rd, imm } => Half(enc_rd_imm8(
            0b10101,
            lo("rd", rd)?,
            scaled("imm", imm as u32, 4, 8)?,
        )),
        AddSp { imm } => Half(enc_sp_adjust(false, scaled("imm", imm as u32, 4, 7)?)),
        SubSp { imm } => Half(enc_sp_adjust(true, scaled("imm", imm as u32, 4, 7)?)),
        Sxth { rd, rm } => Half(enc_misc_rr(0b0010, 0, lo("rm", rm)?, lo("rd", rd)?)),
        Sxtb { rd, rm } => Half(enc_misc_rr(0b0010, 1, lo("rm", rm)?, lo("rd", rd)?)),
        Uxth { rd, rm } => Half(enc_misc_rr(0b0010, 2, lo("rm", rm)?, lo("rd", rd)?)),
        Uxtb { rd, rm } => Half(enc_misc_rr(0b0010, 3, lo("rm", rm)?, lo("rd", rd)?)),
        Rev { rd, rm } => Half(enc_misc_rr(0b1010, 0, lo("rm", rm)?, lo("rd", rd)?)),
        Rev16 { rd, rm } => Half(enc_misc_rr(0b1010, 1, lo("rm", rm)?, lo("rd", rd)?)),
        Revsh { rd, rm } => Half(enc_misc_rr(0b1010, 3, lo("rm", rm)?, lo("rd", rd)?)),
        Push { list } => {
            if list & !0x40ff != 0 {
                return Err(format!("PUSH list {list:#06x} may hold only r0-r7 and LR"));
            }
            Half(enc_push_pop(false, list & 0x4000 != 0, list & 0xff))
        }
        Pop { list } => {
            if list & !0x80ff != 0 {
                return Err(format!("POP list {list:#06x} may hold only r0-r7 and PC"));
            }
            Half(enc_push_pop(true, list & 0x8000 != 0, list & 0xff))
        }
        Stm { rn, list } => Half(enc_ldm_stm(false, lo("rn", rn)?, list as u16)),
        Ldm { rn, list } => Half(enc_ldm_stm(true, lo("rn", rn)?, list as u16)),
        Cps { disable } => Half(0xb662 | (u16::from(disable) << 4)),
        Bkpt { imm } => Half(0xbe00 | imm as u16),
        Hint(h) => Half(
            0xbf00
                | (match h {
                    self::Hint::Nop => 0,
                    self::Hint::Yield => 1,
                    self::Hint::Wfe => 2,
                    self::Hint::Wfi => 3,
                    self::Hint::Sev => 4,
                } << 4),
        ),
        BCond { cond, offset } => {
            if cond >= 14 {
                return Err(format!("`cond` = {cond} is not a branch condition (0-13)"));
            }
            Half(enc_cond(cond as u16, branch("offset", offset, 8)? as u16))
        }
        B { offset } => Half(enc_b(branch("offset", offset, 11)? as u16)),
        Svc { imm } => Half(enc_cond(0b1111, imm as u16)),
        Udf { imm } => Half(enc_cond(0b1110, imm as u16)),
        Bl { offset } => {
            let imm25 = branch("offset", offset, 24)? << 1;
            let (a, b) = enc_bl(imm25);
            Encoding::Word(a, b)
        }
        Msr { sysm, rn } => Encoding::Word(0xf380 | reg("rn", rn)?, 0x8800 | sysm as u16),
        Mrs { rd, sysm } => Encoding::Word(0xf3ef, 0x8000 | (reg("rd", rd)? << 8) | sysm as u16),
        Barrier(b) => Encoding::Word(
            0xf3bf,
            match b {
                self::Barrier::Dsb => 0x8f4f,
                self::Barrier::Dmb => 0x8f5f,
                self::Barrier::Isb => 0x8f6f,
            },
        ),
        Undefined { hw1, hw2 } => {
            if crate::decode::is_32bit(hw1) {
                Encoding::Word(hw1, hw2)
            } else {
                Half(hw1)
            }
        }
    })
}
