//! Thumb (ARMv6-M) instruction decoding, independent of any machine state.
//!
//! An [`Instr`] is a small `Copy` value whose fields are already extracted and scaled
//! (immediates in bytes, branch offsets sign-extended relative to the instruction's
//! address plus 4), so that the executor, the timing table and a static analyser (the budget checker)
//! all look at the same thing without re-reading bit fields. The decoder is one hand-written
//! `match` over the encoding tables of the ARMv6-M Architecture Reference Manual (DDI0419,
//! section A5 "The Thumb Instruction Set Encoding"); everything that table marks UNDEFINED
//! (including 32-bit encodings other than BL, MSR, MRS, DMB, DSB, ISB) decodes to
//! [`Instr::Undefined`], which the core turns into a HardFault.

/// Data-processing operations of the "Data processing" encoding class (DDI0419 A5.2.2),
/// `op Rdn, Rm` with flags set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AluOp {
    /// `ANDS Rdn, Rm`
    And,
    /// `EORS Rdn, Rm`
    Eor,
    /// `LSLS Rdn, Rm` (shift by the bottom byte of Rm)
    Lsl,
    /// `LSRS Rdn, Rm`
    Lsr,
    /// `ASRS Rdn, Rm`
    Asr,
    /// `ADCS Rdn, Rm`
    Adc,
    /// `SBCS Rdn, Rm`
    Sbc,
    /// `RORS Rdn, Rm`
    Ror,
    /// `TST Rn, Rm` (flags only)
    Tst,
    /// `RSBS Rd, Rn, #0` (a.k.a. `NEGS`)
    Rsb,
    /// `CMP Rn, Rm` (low registers)
    Cmp,
    /// `CMN Rn, Rm`
    Cmn,
    /// `ORRS Rdn, Rm`
    Orr,
    /// `MULS Rdm, Rn, Rdm` (N and Z only; C and V unchanged on ARMv6-M)
    Mul,
    /// `BICS Rdn, Rm`
    Bic,
    /// `MVNS Rd, Rm`
    Mvn,
}

impl AluOp {
    pub(crate) const TABLE: [AluOp; 16] = [
        AluOp::And,
        AluOp::Eor,
        AluOp::Lsl,
        AluOp::Lsr,
        AluOp::Asr,
        AluOp::Adc,
        AluOp::Sbc,
        AluOp::Ror,
        AluOp::Tst,
        AluOp::Rsb,
        AluOp::Cmp,
        AluOp::Cmn,
        AluOp::Orr,
        AluOp::Mul,
        AluOp::Bic,
        AluOp::Mvn,
    ];
}

/// Width and signedness of a single load or store.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MemOp {
    /// `STR`: store word.
    Str,
    /// `STRH`: store halfword.
    Strh,
    /// `STRB`: store byte.
    Strb,
    /// `LDRSB`: load byte, sign-extend.
    Ldrsb,
    /// `LDR`: load word.
    Ldr,
    /// `LDRH`: load halfword, zero-extend.
    Ldrh,
    /// `LDRB`: load byte, zero-extend.
    Ldrb,
    /// `LDRSH`: load halfword, sign-extend.
    Ldrsh,
}

impl MemOp {
    /// True for the store operations.
    pub const fn is_store(self) -> bool {
        matches!(self, MemOp::Str | MemOp::Strh | MemOp::Strb)
    }
    /// Access size in bytes (1, 2 or 4).
    pub const fn size(self) -> u32 {
        match self {
            MemOp::Str | MemOp::Ldr => 4,
            MemOp::Strh | MemOp::Ldrh | MemOp::Ldrsh => 2,
            MemOp::Strb | MemOp::Ldrb | MemOp::Ldrsb => 1,
        }
    }
}

/// Hint instructions (DDI0419 A5.2.5, "If-Then and hints"; ARMv6-M has no IT).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Hint {
    /// `NOP`
    Nop,
    /// `YIELD` (a NOP on the M0+)
    Yield,
    /// `WFE`: wait for event.
    Wfe,
    /// `WFI`: wait for interrupt.
    Wfi,
    /// `SEV`: send event (to both RP2040 cores).
    Sev,
}

/// Memory barriers (32-bit encodings, DDI0419 A5.3.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Barrier {
    /// `DMB`
    Dmb,
    /// `DSB`
    Dsb,
    /// `ISB`
    Isb,
}

/// A decoded ARMv6-M instruction. Register fields are register numbers 0-15; immediates are
/// already scaled to bytes; branch `offset`s are relative to the instruction's address + 4
/// (the value of PC as an operand).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[allow(missing_docs)] // the fields are the operand names of the ARM ARM syntax
pub enum Instr {
    /// `LSLS Rd, Rm, #imm` (imm 0-31; imm 0 is `MOVS Rd, Rm`).
    LslImm { rd: u8, rm: u8, imm: u8 },
    /// `LSRS Rd, Rm, #imm` (imm 1-32).
    LsrImm { rd: u8, rm: u8, imm: u8 },
    /// `ASRS Rd, Rm, #imm` (imm 1-32).
    AsrImm { rd: u8, rm: u8, imm: u8 },
    /// `ADDS Rd, Rn, Rm`
    AddReg { rd: u8, rn: u8, rm: u8 },
    /// `SUBS Rd, Rn, Rm`
    SubReg { rd: u8, rn: u8, rm: u8 },
    /// `ADDS Rd, Rn, #imm` (imm 0-7 or, for the Rdn form, 0-255).
    AddImm { rd: u8, rn: u8, imm: u8 },
    /// `SUBS Rd, Rn, #imm`
    SubImm { rd: u8, rn: u8, imm: u8 },
    /// `MOVS Rd, #imm8`
    MovImm { rd: u8, imm: u8 },
    /// `CMP Rn, #imm8`
    CmpImm { rn: u8, imm: u8 },
    /// Register data processing, `op Rdn, Rm`, flags set.
    Alu { op: AluOp, rdn: u8, rm: u8 },
    /// `ADD Rdn, Rm` (any registers, no flags; Rdn = PC is a branch).
    AddHi { rdn: u8, rm: u8 },
    /// `CMP Rn, Rm` (at least one high register).
    CmpHi { rn: u8, rm: u8 },
    /// `MOV Rd, Rm` (any registers, no flags; Rd = PC is a branch).
    MovHi { rd: u8, rm: u8 },
    /// `BX Rm`
    Bx { rm: u8 },
    /// `BLX Rm`
    Blx { rm: u8 },
    /// `LDR Rt, [PC, #imm]` (imm in bytes, base is Align(PC, 4)).
    LdrLit { rt: u8, imm: u16 },
    /// `op Rt, [Rn, Rm]`
    MemReg { op: MemOp, rt: u8, rn: u8, rm: u8 },
    /// `op Rt, [Rn, #imm]` (Rn = 13 for the SP-relative forms; imm in bytes).
    MemImm { op: MemOp, rt: u8, rn: u8, imm: u16 },
    /// `ADR Rd, label` = Align(PC, 4) + imm.
    Adr { rd: u8, imm: u16 },
    /// `ADD Rd, SP, #imm`
    AddSpImm { rd: u8, imm: u16 },
    /// `ADD SP, SP, #imm`
    AddSp { imm: u16 },
    /// `SUB SP, SP, #imm`
    SubSp { imm: u16 },
    /// `SXTH Rd, Rm`
    Sxth { rd: u8, rm: u8 },
    /// `SXTB Rd, Rm`
    Sxtb { rd: u8, rm: u8 },
    /// `UXTH Rd, Rm`
    Uxth { rd: u8, rm: u8 },
    /// `UXTB Rd, Rm`
    Uxtb { rd: u8, rm: u8 },
    /// `REV Rd, Rm`
    Rev { rd: u8, rm: u8 },
    /// `REV16 Rd, Rm`
    Rev16 { rd: u8, rm: u8 },
    /// `REVSH Rd, Rm`
    Revsh { rd: u8, rm: u8 },
    /// `PUSH {list}`: bits 0-7 are r0-r7, bit 14 is LR.
    Push { list: u16 },
    /// `POP {list}`: bits 0-7 are r0-r7, bit 15 is PC.
    Pop { list: u16 },
    /// `STM Rn!, {list}`
    Stm { rn: u8, list: u8 },
    /// `LDM Rn{!}, {list}` (writeback unless Rn is in the list).
    Ldm { rn: u8, list: u8 },
    /// `CPSID i` (`disable`) / `CPSIE i`.
    Cps { disable: bool },
    /// `BKPT #imm`
    Bkpt { imm: u8 },
    /// A hint.
    Hint(Hint),
    /// `B<cond> label` (cond 0-13).
    BCond { cond: u8, offset: i32 },
    /// `B label`
    B { offset: i32 },
    /// `SVC #imm`
    Svc { imm: u8 },
    /// `UDF #imm` (permanently undefined, 16-bit).
    Udf { imm: u8 },
    /// `BL label` (32-bit).
    Bl { offset: i32 },
    /// `MSR spec_reg, Rn` (32-bit).
    Msr { sysm: u8, rn: u8 },
    /// `MRS Rd, spec_reg` (32-bit).
    Mrs { rd: u8, sysm: u8 },
    /// `DMB`, `DSB`, `ISB` (32-bit).
    Barrier(Barrier),
    /// Any UNDEFINED encoding (including `UDF.W`): executes as a HardFault.
    Undefined { hw1: u16, hw2: u16 },
}

/// True when `hw1` is the first halfword of a 32-bit Thumb instruction (DDI0419 A5.1: bits
/// 15:11 are 0b11101, 0b11110 or 0b11111).
#[inline]
pub const fn is_32bit(hw1: u16) -> bool {
    (hw1 >> 11) >= 0b11101
}

/// Size in bytes (2 or 4) of the instruction starting with `hw1`.
pub const fn size_of(hw1: u16) -> u32 {
    if is_32bit(hw1) {
        4
    } else {
        2
    }
}

fn sign_extend(value: u32, bits: u32) -> i32 {
    let shift = 32 - bits;
    ((value << shift) as i32) >> shift
}

/// Decodes one instruction from its first halfword `hw1` and, for 32-bit encodings, the
/// following halfword `hw2` (ignored for 16-bit encodings). Pure: needs no machine state.
#[inline]
pub fn decode(hw1: u16, hw2: u16) -> Instr {
    use Instr::*;
    let h = hw1 as u32;
    let lo3 = |shift: u32| ((h >> shift) & 7) as u8;
    if is_32bit(hw1) {
        return decode32(hw1, hw2);
    }
    match h >> 10 {
        // 00xxxx: shift (immediate), add, subtract, move, and compare
        0b000000..=0b001111 => {
            let op = (h >> 9) & 0x1f;
            match op {
                0b00000..=0b00011 => LslImm {
                    rd: lo3(0),
                    rm: lo3(3),
                    imm: ((h >> 6) & 31) as u8,
                },
                0b00100..=0b00111 => {
                    let imm = ((h >> 6) & 31) as u8;
                    LsrImm {
                        rd: lo3(0),
                        rm: lo3(3),
                        imm: if imm == 0 { 32 } else { imm },
                    }
                }
                0b01000..=0b01011 => {
                    let imm = ((h >> 6) & 31) as u8;
                    AsrImm {
                        rd: lo3(0),
                        rm: lo3(3),
                        imm: if imm == 0 { 32 } else { imm },
                    }
                }
                0b01100 => AddReg {
                    rd: lo3(0),
                    rn: lo3(3),
                    rm: lo3(6),
                },
                0b01101 => SubReg {
                    rd: lo3(0),
                    rn: lo3(3),
                    rm: lo3(6),
                },
                0b01110 => AddImm {
                    rd: lo3(0),
                    rn: lo3(3),
                    imm: lo3(6),
                },
                0b01111 => SubImm {
                    rd: lo3(0),
                    rn: lo3(3),
                    imm: lo3(6),
                },
                0b10000..=0b10011 => MovImm {
                    rd: lo3(8),
                    imm: h as u8,
                },
                0b10100..=0b10111 => CmpImm {
                    rn: lo3(8),
                    imm: h as u8,
                },
                0b11000..=0b11011 => AddImm {
                    rd: lo3(8),
                    rn: lo3(8),
                    imm: h as u8,
                },
                _ => SubImm {
                    rd: lo3(8),
                    rn: lo3(8),
                    imm: h as u8,
                },
            }
        }
        // 010000: data processing
        0b010000 => Alu {
            op: AluOp::TABLE[((h >> 6) & 15) as usize],
            rdn: lo3(0),
            rm: lo3(3),
        },
        // 010001: special data instructions and branch and exchange
        0b010001 => {
            let rdn = (((h >> 4) & 8) | (h & 7)) as u8;
            let rm = ((h >> 3) & 15) as u8;
            match (h >> 8) & 3 {
                0b00 => AddHi { rdn, rm },
                0b01 => {
                    // CMP with two low registers is UNPREDICTABLE; we execute it like the
                    // low-register CMP, as the Cortex-M0+ does.
                    if rdn == 15 || rm == 15 {
                        Undefined { hw1, hw2: 0 }
                    } else {
                        CmpHi { rn: rdn, rm }
                    }
                }
                0b10 => MovHi { rd: rdn, rm },
                _ => {
                    if h & 7 != 0 {
                        Undefined { hw1, hw2: 0 }
                    } else if h & 0x80 == 0 {
                        Bx { rm }
                    } else if rm == 15 {
                        Undefined { hw1, hw2: 0 }
                    } else {
                        Blx { rm }
                    }
                }
            }
        }
        // 01001x: LDR (literal)
        0b010010 | 0b010011 => LdrLit {
            rt: lo3(8),
            imm: ((h & 0xff) << 2) as u16,
        },
        // 0101xx: load/store register offset
        0b010100..=0b010111 => {
            let op = match (h >> 9) & 7 {
                0 => MemOp::Str,
                1 => MemOp::Strh,
                2 => MemOp::Strb,
                3 => MemOp::Ldrsb,
                4 => MemOp::Ldr,
                5 => MemOp::Ldrh,
                6 => MemOp::Ldrb,
                _ => MemOp::Ldrsh,
            };
            MemReg {
                op,
                rt: lo3(0),
                rn: lo3(3),
                rm: lo3(6),
            }
        }
        // 011xxx: load/store word/byte immediate
        0b011000..=0b011111 => {
            let imm5 = ((h >> 6) & 31) as u16;
            let (op, imm) = match (h >> 11) & 3 {
                0 => (MemOp::Str, imm5 << 2),
                1 => (MemOp::Ldr, imm5 << 2),
                2 => (MemOp::Strb, imm5),
                _ => (MemOp::Ldrb, imm5),
            };
            MemImm {
                op,
                rt: lo3(0),
                rn: lo3(3),
                imm,
            }
        }
        // 1000xx: load/store halfword immediate
        0b100000..=0b100011 => {
            let imm = (((h >> 6) & 31) << 1) as u16;
            let op = if h & 0x800 != 0 {
                MemOp::Ldrh
            } else {
                MemOp::Strh
            };
            MemImm {
                op,
                rt: lo3(0),
                rn: lo3(3),
                imm,
            }
        }
        // 1001xx: load/store SP-relative
        0b100100..=0b100111 => {
            let op = if h & 0x800 != 0 {
                MemOp::Ldr
            } else {
                MemOp::Str
            };
            MemImm {
                op,
                rt: lo3(8),
                rn: 13,
                imm: ((h & 0xff) << 2) as u16,
            }
        }
        // 10100x: ADR
        0b101000 | 0b101001 => Adr {
            rd: lo3(8),
            imm: ((h & 0xff) << 2) as u16,
        },
        // 10101x: ADD Rd, SP, #imm
        0b101010 | 0b101011 => AddSpImm {
            rd: lo3(8),
            imm: ((h & 0xff) << 2) as u16,
        },
        // 1011xx: miscellaneous 16-bit instructions
        0b101100..=0b101111 => decode_misc(hw1),
        // 11000x: STM
        0b110000 | 0b110001 => Stm {
            rn: lo3(8),
            list: h as u8,
        },
        // 11001x: LDM
        0b110010 | 0b110011 => Ldm {
            rn: lo3(8),
            list: h as u8,
        },
        // 1101xx: conditional branch, UDF, SVC
        0b110100..=0b110111 => match (h >> 8) & 15 {
            14 => Udf { imm: h as u8 },
            15 => Svc { imm: h as u8 },
            cond => BCond {
                cond: cond as u8,
                offset: sign_extend((h & 0xff) << 1, 9),
            },
        },
        // 11100x: B
        0b111000 | 0b111001 => B {
            offset: sign_extend((h & 0x7ff) << 1, 12),
        },
        _ => Undefined { hw1, hw2: 0 },
    }
}

fn decode_misc(hw1: u16) -> Instr {
    use Instr::*;
    let h = hw1 as u32;
    let rd = (h & 7) as u8;
    let rm = ((h >> 3) & 7) as u8;
    let op2 = (h >> 6) & 3; // bits 7:6
    let undefined = Undefined { hw1, hw2: 0 };
    match (h >> 8) & 0xf {
        0x0 if h & 0x80 == 0 => AddSp {
            imm: ((h & 0x7f) << 2) as u16,
        },
        0x0 => SubSp {
            imm: ((h & 0x7f) << 2) as u16,
        },
        0x2 => match op2 {
            0 => Sxth { rd, rm },
            1 => Sxtb { rd, rm },
            2 => Uxth { rd, rm },
            _ => Uxtb { rd, rm },
        },
        0x4 | 0x5 => Push {
            list: ((h & 0xff) | ((h & 0x100) << 6)) as u16,
        },
        // CPS: 1011 0110 011 im 0010 (only the I bit exists on ARMv6-M)
        0x6 if h & 0xef == 0x62 => Cps {
            disable: h & 0x10 != 0,
        },
        0xa => match op2 {
            0 => Rev { rd, rm },
            1 => Rev16 { rd, rm },
            3 => Revsh { rd, rm },
            _ => undefined,
        },
        0xc | 0xd => Pop {
            list: ((h & 0xff) | ((h & 0x100) << 7)) as u16,
        },
        0xe => Bkpt { imm: h as u8 },
        0xf if h & 0xf == 0 => match (h >> 4) & 0xf {
            1 => Hint(self::Hint::Yield),
            2 => Hint(self::Hint::Wfe),
            3 => Hint(self::Hint::Wfi),
            4 => Hint(self::Hint::Sev),
            // NOP, and unallocated hints execute as NOP (DDI0419 A5.2.5)
            _ => Hint(self::Hint::Nop),
        },
        // IT, CBZ/CBNZ and the rest do not exist on ARMv6-M
        _ => undefined,
    }
}

fn decode32(hw1: u16, hw2: u16) -> Instr {
    use Instr::*;
    let (a, b) = (hw1 as u32, hw2 as u32);
    let undefined = Undefined { hw1, hw2 };
    // DDI0419 A5.3: only op1 = 0b10 with op = 1 (branch and miscellaneous control) exists.
    if (a >> 11) != 0b11110 || b & 0x8000 == 0 {
        return undefined;
    }
    let op1 = (b >> 12) & 0b101;
    if op1 == 0b101 {
        // BL: S:I1:I2:imm10:imm11:'0', I1 = NOT(J1 XOR S), I2 = NOT(J2 XOR S)
        let s = (a >> 10) & 1;
        let j1 = (b >> 13) & 1;
        let j2 = (b >> 11) & 1;
        let i1 = !(j1 ^ s) & 1;
        let i2 = !(j2 ^ s) & 1;
        let imm = (s << 24) | (i1 << 23) | (i2 << 22) | ((a & 0x3ff) << 12) | ((b & 0x7ff) << 1);
        return Bl {
            offset: sign_extend(imm, 25),
        };
    }
    if op1 != 0b000 {
        return undefined;
    }
    let op = (a >> 4) & 0x7f;
    match op {
        0b0111000 | 0b0111001 => {
            // MSR: 11110 0 1110 0 0 Rn | 10 0 0 1000 SYSm
            if b & 0x3f00 == 0x0800 {
                Msr {
                    sysm: b as u8,
                    rn: (a & 15) as u8,
                }
            } else {
                undefined
            }
        }
        0b0111011 => {
            // DSB/DMB/ISB: 11110 0 111 01 1 1111 | 10 0 0 1111 op(4) option(4)
            match (b >> 4) & 15 {
                0b0100 => Barrier(self::Barrier::Dsb),
                0b0101 => Barrier(self::Barrier::Dmb),
                0b0110 => Barrier(self::Barrier::Isb),
                _ => undefined,
            }
        }
        0b0111110 | 0b0111111 => {
            // MRS: 11110 0 1111 1 (1)(1)(1)(1) | 10 (0) 0 Rd SYSm
            Mrs {
                rd: ((b >> 8) & 15) as u8,
                sysm: b as u8,
            }
        }
        _ => undefined,
    }
}

const REG_NAMES: [&str; 16] = [
    "r0", "r1", "r2", "r3", "r4", "r5", "r6", "r7", "r8", "r9", "r10", "r11", "r12", "sp", "lr",
    "pc",
];

fn reg_list(f: &mut std::fmt::Formatter<'_>, list: u16) -> std::fmt::Result {
    let names: Vec<&str> = (0..16)
        .filter(|r| list & (1 << r) != 0)
        .map(|r| REG_NAMES[r])
        .collect();
    write!(f, "{{{}}}", names.join(", "))
}

const CONDS: [&str; 14] = [
    "eq", "ne", "cs", "cc", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le",
];

/// Unified assembler syntax (branch targets as `.+offset` from the instruction).
impl std::fmt::Display for Instr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use Instr::*;
        let r = |n: u8| REG_NAMES[n as usize];
        match *self {
            LslImm { rd, rm, imm: 0 } => write!(f, "movs {}, {}", r(rd), r(rm)),
            LslImm { rd, rm, imm } => write!(f, "lsls {}, {}, #{imm}", r(rd), r(rm)),
            LsrImm { rd, rm, imm } => write!(f, "lsrs {}, {}, #{imm}", r(rd), r(rm)),
            AsrImm { rd, rm, imm } => write!(f, "asrs {}, {}, #{imm}", r(rd), r(rm)),
            AddReg { rd, rn, rm } => write!(f, "adds {}, {}, {}", r(rd), r(rn), r(rm)),
            SubReg { rd, rn, rm } => write!(f, "subs {}, {}, {}", r(rd), r(rn), r(rm)),
            AddImm { rd, rn, imm } => write!(f, "adds {}, {}, #{imm}", r(rd), r(rn)),
            SubImm { rd, rn, imm } => write!(f, "subs {}, {}, #{imm}", r(rd), r(rn)),
            MovImm { rd, imm } => write!(f, "movs {}, #{imm}", r(rd)),
            CmpImm { rn, imm } => write!(f, "cmp {}, #{imm}", r(rn)),
            Alu {
                op: AluOp::Rsb,
                rdn,
                rm,
            } => write!(f, "rsbs {}, {}, #0", r(rdn), r(rm)),
            Alu {
                op: AluOp::Mul,
                rdn,
                rm,
            } => write!(f, "muls {}, {}, {}", r(rdn), r(rm), r(rdn)),
            Alu { op, rdn, rm } => {
                let name = match op {
                    AluOp::And => "ands",
                    AluOp::Eor => "eors",
                    AluOp::Lsl => "lsls",
                    AluOp::Lsr => "lsrs",
                    AluOp::Asr => "asrs",
                    AluOp::Adc => "adcs",
                    AluOp::Sbc => "sbcs",
                    AluOp::Ror => "rors",
                    AluOp::Tst => "tst",
                    AluOp::Cmp => "cmp",
                    AluOp::Cmn => "cmn",
                    AluOp::Orr => "orrs",
                    AluOp::Bic => "bics",
                    _ => "mvns",
                };
                write!(f, "{name} {}, {}", r(rdn), r(rm))
            }
            AddHi { rdn, rm } => write!(f, "add {}, {}", r(rdn), r(rm)),
            CmpHi { rn, rm } => write!(f, "cmp {}, {}", r(rn), r(rm)),
            MovHi { rd, rm } => write!(f, "mov {}, {}", r(rd), r(rm)),
            Bx { rm } => write!(f, "bx {}", r(rm)),
            Blx { rm } => write!(f, "blx {}", r(rm)),
            LdrLit { rt, imm } => write!(f, "ldr {}, [pc, #{imm}]", r(rt)),
            MemReg { op, rt, rn, rm } => {
                write!(f, "{} {}, [{}, {}]", mem_name(op), r(rt), r(rn), r(rm))
            }
            MemImm { op, rt, rn, imm } => {
                write!(f, "{} {}, [{}, #{imm}]", mem_name(op), r(rt), r(rn))
            }
            Adr { rd, imm } => write!(f, "add {}, pc, #{imm}", r(rd)),
            AddSpImm { rd, imm } => write!(f, "add {}, sp, #{imm}", r(rd)),
            AddSp { imm } => write!(f, "add sp, #{imm}"),
            SubSp { imm } => write!(f, "sub sp, #{imm}"),
            Sxth { rd, rm } => write!(f, "sxth {}, {}", r(rd), r(rm)),
            Sxtb { rd, rm } => write!(f, "sxtb {}, {}", r(rd), r(rm)),
            Uxth { rd, rm } => write!(f, "uxth {}, {}", r(rd), r(rm)),
            Uxtb { rd, rm } => write!(f, "uxtb {}, {}", r(rd), r(rm)),
            Rev { rd, rm } => write!(f, "rev {}, {}", r(rd), r(rm)),
            Rev16 { rd, rm } => write!(f, "rev16 {}, {}", r(rd), r(rm)),
            Revsh { rd, rm } => write!(f, "revsh {}, {}", r(rd), r(rm)),
            Push { list } => {
                f.write_str("push ")?;
                reg_list(f, list)
            }
            Pop { list } => {
                f.write_str("pop ")?;
                reg_list(f, list)
            }
            Stm { rn, list } => {
                write!(f, "stmia {}!, ", r(rn))?;
                reg_list(f, list as u16)
            }
            Ldm { rn, list } => {
                let wb = if list & (1 << rn) == 0 { "!" } else { "" };
                write!(f, "ldmia {}{wb}, ", r(rn))?;
                reg_list(f, list as u16)
            }
            Cps { disable } => f.write_str(if disable { "cpsid i" } else { "cpsie i" }),
            Bkpt { imm } => write!(f, "bkpt #{imm}"),
            Hint(h) => f.write_str(match h {
                self::Hint::Nop => "nop",
                self::Hint::Yield => "yield",
                self::Hint::Wfe => "wfe",
                self::Hint::Wfi => "wfi",
                self::Hint::Sev => "sev",
            }),
            BCond { cond, offset } => write!(f, "b{} .{:+}", CONDS[cond as usize], offset + 4),
            B { offset } => write!(f, "b .{:+}", offset + 4),
            Svc { imm } => write!(f, "svc #{imm}"),
            Udf { imm } => write!(f, "udf #{imm}"),
            Bl { offset } => write!(f, "bl .{:+}", offset + 4),
            Msr { sysm, rn } => write!(f, "msr {}, {}", sysreg(sysm), r(rn)),
            Mrs { rd, sysm } => write!(f, "mrs {}, {}", r(rd), sysreg(sysm)),
            Barrier(b) => f.write_str(match b {
                self::Barrier::Dmb => "dmb sy",
                self::Barrier::Dsb => "dsb sy",
                self::Barrier::Isb => "isb sy",
            }),
            Undefined { hw1, hw2 } if is_32bit(hw1) => write!(f, ".inst.w 0x{hw1:04x}{hw2:04x}"),
            Undefined { hw1, .. } => write!(f, ".inst.n 0x{hw1:04x}"),
        }
    }
}

fn mem_name(op: MemOp) -> &'static str {
    match op {
        MemOp::Str => "str",
        MemOp::Strh => "strh",
        MemOp::Strb => "strb",
        MemOp::Ldrsb => "ldrsb",
        MemOp::Ldr => "ldr",
        MemOp::Ldrh => "ldrh",
        MemOp::Ldrb => "ldrb",
        MemOp::Ldrsh => "ldrsh",
    }
}

fn sysreg(sysm: u8) -> &'static str {
    match sysm {
        0 => "apsr",
        1 => "iapsr",
        2 => "eapsr",
        3 => "xpsr",
        5 => "ipsr",
        6 => "epsr",
        7 => "iepsr",
        8 => "msp",
        9 => "psp",
        16 => "primask",
        20 => "control",
        _ => "?",
    }
}
