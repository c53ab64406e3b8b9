//! A small Thumb assembler for the image's glue code: instructions as the emulator's
//! [`Instr`], labels, branches to labels, `BL` to absolute addresses, literal loads from
//! explicitly placed pools, alignment and data words. Code is assembled at a known absolute
//! address (the image is laid out before it is assembled), so every size is known in one
//! pass and the second pass encodes with [`tactus_emulator::encode::encode`] — the ISA's
//! bit layouts stay in the emulator crate. Out-of-range branches and literals are errors,
//! never silently wrong code.

use tactus_emulator::decode::{AluOp, Instr, MemOp};
use tactus_emulator::encode::encode;

/// A label: an index into the assembler's label table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Label(usize);

impl Label {
    /// Its index into the address table [`Asm::assemble`] returns.
    pub fn index(self) -> usize {
        self.0
    }
}

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

#[derive(Clone, Debug)]
enum Item {
    Instr(Instr),
    Bind(Label),
    /// `B`/`B<cond>` to a label (`cond` 14 = always).
    Branch(u8, Label),
    /// `BL` to an absolute address (Thumb bit ignored).
    Bl(u32),
    /// `BL` to a label.
    BlLabel(Label),
    /// `LDR Rt, [PC, #imm]` of pool entry `n` of pool `pool`.
    Lit(u8, usize, usize),
    /// Align to 4 with a `NOP` (0xbf00) if needed.
    Align4,
    /// A data word (call only after [`Item::Align4`]).
    Word(u32),
    /// Pool `n`'s literals (aligned).
    Pool(usize),
}

/// Assembly in progress.
#[derive(Clone, Debug, Default)]
pub struct Asm {
    items: Vec<Item>,
    labels: usize,
    /// Literal pools: the first is open (collecting), later ones are placed.
    pools: Vec<Vec<u32>>,
}

/// Why glue code could not be assembled (an image-builder bug or an image too large for a
/// short branch); names what failed.
pub type AsmError = String;

impl Asm {
    /// An empty program.
    pub fn new() -> Self {
        Asm {
            pools: vec![Vec::new()],
            ..Asm::default()
        }
    }

    /// A fresh, unbound label.
    pub fn label(&mut self) -> Label {
        self.labels += 1;
        Label(self.labels - 1)
    }

    /// Binds `l` here.
    pub fn bind(&mut self, l: Label) {
        self.items.push(Item::Bind(l));
    }

    /// Any instruction.
    pub fn i(&mut self, i: Instr) {
        self.items.push(Item::Instr(i));
    }

    /// `B label`.
    pub fn b(&mut self, l: Label) {
        self.items.push(Item::Branch(14, l));
    }

    /// `B<cond> label`.
    pub fn bc(&mut self, c: u8, l: Label) {
        self.items.push(Item::Branch(c, l));
    }

    /// `BL addr`.
    pub fn bl(&mut self, addr: u32) {
        self.items.push(Item::Bl(addr));
    }

    /// `BL label`.
    pub fn bl_label(&mut self, l: Label) {
        self.items.push(Item::BlLabel(l));
    }

    /// `LDR rt, =value` from the current pool (placed by the next [`Asm::pool`]).
    pub fn ldr_const(&mut self, rt: u8, value: u32) {
        let cur = self.pools.len() - 1;
        let pool = &mut self.pools[cur];
        let n = pool.iter().position(|&v| v == value).unwrap_or_else(|| {
            pool.push(value);
            pool.len() - 1
        });
        self.items.push(Item::Lit(rt, cur, n));
    }

    /// `rd = value`: `MOVS` when it fits 8 bits, else a literal.
    pub fn mov_const(&mut self, rd: u8, value: u32) {
        if value < 256 {
            self.i(Instr::MovImm {
                rd,
                imm: value as u8,
            });
        } else {
            self.ldr_const(rd, value);
        }
    }

    /// Places the current pool here (aligned) and opens a new one. The caller makes sure
    /// control never falls into it (after a return or an unconditional branch).
    pub fn pool(&mut self) {
        let cur = self.pools.len() - 1;
        if !self.pools[cur].is_empty() {
            self.items.push(Item::Pool(cur));
            self.pools.push(Vec::new());
        }
    }

    /// Places the current pool here behind a `B` over it.
    pub fn pool_inline(&mut self) {
        if self.pools.last().is_some_and(|p| !p.is_empty()) {
            let over = self.label();
            self.b(over);
            self.pool();
            self.bind(over);
        }
    }

    /// Aligns to 4 bytes (with a `NOP`).
    pub fn align4(&mut self) {
        self.items.push(Item::Align4);
    }

    /// A data word (aligned first).
    pub fn word(&mut self, w: u32) {
        self.items.push(Item::Align4);
        self.items.push(Item::Word(w));
    }

    /// Assembles at `base` (even). Returns the bytes and each label's address.
    pub fn assemble(&self, base: u32) -> Result<(Vec<u8>, Vec<u32>), AsmError> {
        if self.pools.last().is_some_and(|p| !p.is_empty()) {
            return Err("a literal pool was never placed".into());
        }
        // Pass 1: addresses.
        let mut labels = vec![u32::MAX; self.labels];
        let mut pools = vec![u32::MAX; self.pools.len()];
        let mut at = base;
        for item in &self.items {
            match item {
                Item::Bind(l) => labels[l.0] = at,
                Item::Instr(_) | Item::Branch(..) | Item::Lit(..) => at += 2,
                Item::Bl(_) | Item::BlLabel(_) => at += 4,
                Item::Align4 => at = at.next_multiple_of(4),
                Item::Word(_) => at += 4,
                Item::Pool(n) => {
                    at = at.next_multiple_of(4);
                    pools[*n] = at;
                    at += 4 * self.pools[*n].len() as u32;
                }
            }
        }
        if let Some(i) = labels.iter().position(|&a| a == u32::MAX) {
            return Err(format!("label {i} is never bound"));
        }
        // Pass 2: encoding.
        let mut out: Vec<u8> = Vec::new();
        let half = |out: &mut Vec<u8>, i: &Instr| -> Result<(), AsmError> {
            let e = encode(i).map_err(|e| format!("cannot encode {i:?}: {e}"))?;
            out.extend(e.bytes());
            Ok(())
        };
        for item in &self.items {
            let pc = base + out.len() as u32;
            match item {
                Item::Bind(_) => {}
                Item::Instr(i) => half(&mut out, i)?,
                Item::Branch(c, l) => {
                    let offset = labels[l.0] as i64 - (pc as i64 + 4);
                    let offset = offset as i32;
                    let i = if *c == 14 {
                        Instr::B { offset }
                    } else {
                        Instr::BCond { cond: *c, offset }
                    };
                    half(&mut out, &i)?;
                }
                Item::Bl(_) | Item::BlLabel(_) => {
                    let addr = match item {
                        Item::BlLabel(l) => labels[l.0],
                        Item::Bl(addr) => *addr,
                        _ => pc, // not reached: the arm matches only the two above
                    };
                    let offset = (addr & !1) as i64 - (pc as i64 + 4);
                    half(
                        &mut out,
                        &Instr::Bl {
                            offset: offset as i32,
                        },
                    )?;
                }
                Item::Lit(rt, p, n) => {
                    let lit = pools[*p] + 4 * *n as u32;
                    let from = (pc + 4) & !3;
                    let imm = lit
                        .checked_sub(from)
                        .filter(|d| *d <= 1020)
                        .ok_or_else(|| {
                            format!("literal at {lit:#x} out of reach of the load at {pc:#x}")
                        })?;
                    half(
                        &mut out,
                        &Instr::LdrLit {
                            rt: *rt,
                            imm: imm as u16,
                        },
                    )?;
                }
                Item::Align4 => {
                    if !(base as usize + out.len()).is_multiple_of(4) {
                        out.extend([0x00, 0xbf]);
                    }
                }
                Item::Word(w) => out.extend(w.to_le_bytes()),
                Item::Pool(n) => {
                    if !(base as usize + out.len()).is_multiple_of(4) {
                        out.extend([0x00, 0xbf]);
                    }
                    for w in &self.pools[*n] {
                        out.extend(w.to_le_bytes());
                    }
                }
            }
        }
        Ok((out, labels))
    }
}

// ---- instruction shorthands (registers r0-r7 unless noted) ----

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

#[cfg(test)]
mod tests {
    use super::*;
    use tactus_emulator::decode;

    fn dec(bytes: &[u8], off: usize) -> Instr {
        let h = |o: usize| u16::from_le_bytes([bytes[o], bytes[o + 1]]);
        decode(h(off), if off + 3 < bytes.len() { h(off + 2) } else { 0 })
    }

    #[test]
    fn branches_literals_and_pools_land_where_they_should() {
        let mut a = Asm::new();
        let top = a.label();
        a.bind(top);
        a.ldr_const(0, 0x1234_5678);
        a.ldr_const(1, 0x1234_5678); // shared entry
        a.bc(cond::NE, top);
        a.bl(0x2000_0100);
        a.pool_inline();
        a.i(movs(2, 7));
        a.b(top);
        let (bytes, labels) = a.assemble(0x2000_0002).unwrap();
        assert_eq!(labels[0], 0x2000_0002);
        // ldr 0x..02, ldr 0x..04, bne 0x..06, bl 0x..08, b over 0x..0c, NOP padding at
        // 0x..0e, the pool's one (shared) literal at 0x..10: absolute alignment, whatever
        // the base.
        assert_eq!(&bytes[0x0c..0x0e], &[0x00, 0xbf]);
        assert_eq!(&bytes[0x0e..0x12], &0x1234_5678u32.to_le_bytes());
        assert_eq!(bytes.len(), 0x16);
        match dec(&bytes, 0) {
            Instr::LdrLit { rt: 0, imm } => {
                let lit = ((0x2000_0002u32 + 4) & !3) + imm as u32;
                let off = (lit - 0x2000_0002) as usize;
                assert_eq!(&bytes[off..off + 4], &0x1234_5678u32.to_le_bytes());
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(dec(&bytes, 2), {
            let Instr::LdrLit { imm, .. } = dec(&bytes, 0) else {
                unreachable!()
            };
            Instr::LdrLit {
                rt: 1,
                imm: imm - 4,
            }
        });
        // bne top: at 0x..06, target 0x..02: offset = 2 - 10 = -8.
        assert_eq!(
            dec(&bytes, 4),
            Instr::BCond {
                cond: cond::NE,
                offset: -8
            }
        );
        // bl at 0x..08 to 0x..100: offset 0x100 - 0x0c.
        assert_eq!(
            dec(&bytes, 6),
            Instr::Bl {
                offset: 0x100 - 0x0c
            }
        );
    }

    #[test]
    fn out_of_range_literals_and_unplaced_pools_are_errors() {
        let mut a = Asm::new();
        a.ldr_const(0, 5);
        assert!(a.assemble(0).unwrap_err().contains("never placed"));
        a.pool_inline();
        assert!(a.assemble(0).is_ok());
        let mut a = Asm::new();
        a.ldr_const(0, 5);
        for _ in 0..600 {
            a.i(movs(1, 1));
        }
        a.pool();
        assert!(a.assemble(0).unwrap_err().contains("out of reach"));
    }
}
