//! Data processing as cranelift IR: N and Z, the add and subtract flags, the condition
//! codes and the ALU group (`Core::adds`, `Core::condition`, `Core::alu` in `exec.rs`).

use super::translate::{Translator, C, Z};
use crate::decode::AluOp;
use cranelift_codegen::ir::condcodes::{CondCode, IntCC};
use cranelift_codegen::ir::{types, InstBuilder, Value};

impl Translator<'_> {
    /// N and Z from the result `r` (held as `r` itself, see [`super::translate::Flags`]).
    pub(super) fn nz(&mut self, r: Value) {
        self.b.def_var(self.flags.nz, r);
    }

    /// `Core::adds`: `x + y + carry` with N, Z, C and V.
    pub(super) fn adds(&mut self, x: Value, y: Value, carry: Value) -> Value {
        let ins = self.b.ins();
        let xw = ins.uextend(types::I64, x);
        let yw = self.b.ins().uextend(types::I64, y);
        let cw = self.b.ins().uextend(types::I64, carry);
        let s = self.b.ins().iadd(xw, yw);
        let wide = self.b.ins().iadd(s, cw);
        let r = self.b.ins().ireduce(types::I32, wide);
        let hi = self.b.ins().ushr_imm_u(wide, 32);
        let c = self.b.ins().ireduce(types::I8, hi);
        let a = self.b.ins().bxor(x, r);
        let bb = self.b.ins().bxor(y, r);
        self.set_cvnz(r, c, a, bb)
    }

    /// `Core::adds(x, y, false)` (ADDS, CMN) in 32-bit operations: the carry is the
    /// unsigned wrap, the overflow the sign rule.
    pub(super) fn add_flags(&mut self, x: Value, y: Value) -> Value {
        let r = self.b.ins().iadd(x, y);
        let c = self.b.ins().icmp(IntCC::UnsignedLessThan, r, x);
        let a = self.b.ins().bxor(x, r);
        let bb = self.b.ins().bxor(y, r);
        self.set_cvnz(r, c, a, bb)
    }

    /// `Core::adds(x, !y, true)` (SUBS, CMP, NEGS) in 32-bit operations: the carry is
    /// "no borrow" (`x >= y` unsigned), the overflow the sign rule of a subtraction.
    pub(super) fn sub_flags(&mut self, x: Value, y: Value) -> Value {
        let r = self.b.ins().isub(x, y);
        let c = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, x, y);
        let a = self.b.ins().bxor(x, y);
        let bb = self.b.ins().bxor(x, r);
        self.set_cvnz(r, c, a, bb)
    }

    /// Sets C to `c`, V to the sign of `a & bb` (the overflow rule over the operand and
    /// result XORs its caller computed; held as that word), N and Z from `r`; returns `r`.
    fn set_cvnz(&mut self, r: Value, c: Value, a: Value, bb: Value) -> Value {
        let both = self.b.ins().band(a, bb);
        self.set_c(c);
        self.b.def_var(self.flags.v, both);
        self.nz(r);
        r
    }

    /// `Core::condition`: 1 when `cond` (0-13) holds.
    pub(super) fn condition(&mut self, cond: u8) -> Value {
        let nz = self.b.use_var(self.flags.nz);
        let odd = cond & 1 == 1;
        // Each test with its negation folded into the comparison.
        let cc = |yes: IntCC| if odd { yes.complement() } else { yes };
        match cond >> 1 {
            0 => self.b.ins().icmp_imm_u(cc(IntCC::Equal), nz, 0),
            1 => {
                let c = self.flag(C);
                self.b.ins().icmp_imm_u(cc(IntCC::NotEqual), c, 0)
            }
            2 => self.b.ins().icmp_imm_s(cc(IntCC::SignedLessThan), nz, 0),
            3 => {
                let v = self.b.use_var(self.flags.v);
                self.b.ins().icmp_imm_s(cc(IntCC::SignedLessThan), v, 0)
            }
            4 => {
                let c = self.flag(C);
                let z = self.flag(Z);
                let hi = self.b.ins().band_not(c, z);
                self.b.ins().icmp_imm_u(cc(IntCC::NotEqual), hi, 0)
            }
            5 => {
                // N == V: the signs of the two words agree.
                let v = self.b.use_var(self.flags.v);
                let x = self.b.ins().bxor(nz, v);
                self.b
                    .ins()
                    .icmp_imm_s(cc(IntCC::SignedGreaterThanOrEqual), x, 0)
            }
            _ => {
                // N == V and not Z.
                let v = self.b.use_var(self.flags.v);
                let x = self.b.ins().bxor(nz, v);
                let ge = self
                    .b
                    .ins()
                    .icmp_imm_s(IntCC::SignedGreaterThanOrEqual, x, 0);
                let z = self.flag(Z);
                let gt = self.b.ins().band_not(ge, z);
                self.b.ins().icmp_imm_u(cc(IntCC::NotEqual), gt, 0)
            }
        }
    }

    /// `Core::alu`: the ALU group on `Rdn` and `m`.
    pub(super) fn alu(&mut self, op: AluOp, rdn: u8, m: Value) {
        let x = self.reg(rdn, 0);
        let r = match op {
            AluOp::And => self.b.ins().band(x, m),
            AluOp::Eor => self.b.ins().bxor(x, m),
            AluOp::Orr => self.b.ins().bor(x, m),
            AluOp::Bic => self.b.ins().band_not(x, m),
            AluOp::Mvn => self.b.ins().bnot(m),
            AluOp::Mul => self.b.ins().imul(m, x),
            AluOp::Tst => {
                let r = self.b.ins().band(x, m);
                self.nz(r);
                return;
            }
            AluOp::Lsl | AluOp::Lsr | AluOp::Asr => {
                // Shift by the bottom byte of Rm, through a 64-bit word (see the
                // module tests): the carry is the last bit shifted out.
                let s = self.b.ins().band_imm_u(m, 0xff);
                let s33 = self.c32(33);
                let s = self.b.ins().umin(s, s33);
                let s64 = self.b.ins().uextend(types::I64, s);
                let (r, c) = match op {
                    AluOp::Lsl => {
                        let w = self.b.ins().uextend(types::I64, x);
                        let w = self.b.ins().ishl(w, s64);
                        let r = self.b.ins().ireduce(types::I32, w);
                        let c = self.b.ins().ushr_imm_u(w, 32);
                        let c = self.b.ins().band_imm_u(c, 1);
                        (r, c)
                    }
                    _ => {
                        let w = if op == AluOp::Lsr {
                            self.b.ins().uextend(types::I64, x)
                        } else {
                            self.b.ins().sextend(types::I64, x)
                        };
                        let w = self.b.ins().ishl_imm_u(w, 1);
                        let u = if op == AluOp::Lsr {
                            self.b.ins().ushr(w, s64)
                        } else {
                            self.b.ins().sshr(w, s64)
                        };
                        let r = self.b.ins().sshr_imm_u(u, 1);
                        let r = self.b.ins().ireduce(types::I32, r);
                        let c = self.b.ins().band_imm_u(u, 1);
                        (r, c)
                    }
                };
                let c = self.b.ins().ireduce(types::I8, c);
                let zero = self.b.ins().icmp_imm_u(IntCC::Equal, s, 0);
                let old = self.flag(C);
                let c = self.b.ins().select(zero, old, c);
                self.set_c(c);
                r
            }
            AluOp::Ror => {
                let s = self.b.ins().band_imm_u(m, 0xff);
                let s31 = self.b.ins().band_imm_u(m, 31);
                let r = self.b.ins().rotr(x, s31);
                let c = self.b.ins().icmp_imm_s(IntCC::SignedLessThan, r, 0);
                let zero = self.b.ins().icmp_imm_u(IntCC::Equal, s, 0);
                let old = self.flag(C);
                let c = self.b.ins().select(zero, old, c);
                self.set_c(c);
                r
            }
            AluOp::Cmp => {
                self.sub_flags(x, m);
                return;
            }
            AluOp::Cmn => {
                self.add_flags(x, m);
                return;
            }
            AluOp::Rsb => {
                let zero = self.c32(0);
                let r = self.sub_flags(zero, m);
                self.set(rdn, r);
                return;
            }
            AluOp::Adc | AluOp::Sbc => {
                let (a, b, carry) = match op {
                    AluOp::Adc => (x, m, self.flag(C)),
                    _ => (x, self.b.ins().bnot(m), self.flag(C)),
                };
                let r = self.adds(a, b, carry);
                self.set(rdn, r);
                return;
            }
        };
        self.set(rdn, r);
        self.nz(r);
    }
}
