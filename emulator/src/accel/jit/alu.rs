//! Data processing as cranelift IR: N and Z, the add and subtract flags, the condition
//! codes and the ALU group (`Core::adds`, `Core::condition`, `Core::alu` in `exec.rs`).
//! The flag rules are not written here: the translator is a [`Domain`] whose operations
//! emit one IR instruction each, and the rules are `crate::semantics`' generic functions,
//! the same the interpreter runs on plain values.

use super::translate::{Flags, Translator, C};
use crate::semantics::{self, Domain, Flagged, HeldFlags, ShiftImm, ShiftReg};
use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, InstBuilder, Value};
use tactus_isa::decode::AluOp;

impl Translator<'_> {
    /// N and Z from the result `r` (held as `r` itself, see [`super::translate::Flags`]).
    pub(super) fn nz(&mut self, r: Value) {
        self.flags_set = true;
        self.b.def_var(self.flags.nz, r);
    }

    /// `Core::adds`: [`semantics::add_with_carry`] (ADCS, SBCS).
    pub(super) fn adds(&mut self, x: Value, y: Value, carry: Value) -> Value {
        let f = semantics::add_with_carry(self, x, y, carry);
        self.set_flagged(f)
    }

    /// `Core::add_flags`: [`semantics::add`] (ADDS, CMN).
    pub(super) fn add_flags(&mut self, x: Value, y: Value) -> Value {
        let f = semantics::add(self, x, y);
        self.set_flagged(f)
    }

    /// `Core::sub_flags`: [`semantics::sub`] (SUBS, CMP, RSBS).
    pub(super) fn sub_flags(&mut self, x: Value, y: Value) -> Value {
        let f = semantics::sub(self, x, y);
        self.set_flagged(f)
    }

    /// Sets C, V (held as its word), N and Z from the result; returns the result.
    fn set_flagged(&mut self, f: Flagged<Value, Value>) -> Value {
        self.set_c(f.c);
        self.flags_set = true;
        self.b.def_var(self.flags.v, f.v);
        self.nz(f.result);
        f.result
    }

    /// `Core::shift_imm`: LSLS, LSRS, ASRS by an immediate ([`semantics::shift_imm`]).
    pub(super) fn shift_imm(&mut self, kind: ShiftImm, rd: u8, x: Value, imm: u8) {
        let (r, c) = semantics::shift_imm(self, kind, x, imm);
        if let Some(c) = c {
            self.set_c(c);
        }
        self.set(rd, r);
        self.nz(r);
    }

    /// `Core::condition`: 1 when `cond` (0-13) holds ([`semantics::condition`] on the
    /// held flags).
    pub(super) fn condition(&mut self, cond: u8) -> Value {
        let flags = self.flags;
        semantics::condition(self, &flags, cond)
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
            AluOp::Lsl | AluOp::Lsr | AluOp::Asr | AluOp::Ror => {
                let kind = ShiftReg::of(op).expect("a shift or rotate");
                let old = self.flag(C);
                let (r, c) = semantics::shift_reg(self, kind, x, m, old);
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

/// The held flags ([`Flags`]) read as the common form: the N/Z word serves as both N's and
/// Z's word.
impl<'a> HeldFlags<Translator<'a>> for Flags {
    fn n(&self, d: &mut Translator<'a>) -> Value {
        d.b.use_var(self.nz)
    }
    fn z(&self, d: &mut Translator<'a>) -> Value {
        d.b.use_var(self.nz)
    }
    fn c(&self, d: &mut Translator<'a>) -> Value {
        d.b.use_var(self.c)
    }
    fn v(&self, d: &mut Translator<'a>) -> Value {
        d.b.use_var(self.v)
    }
}

/// Cranelift IR as the domain: words are i32 values, bits i8 values (0 or 1), and each
/// operation is one instruction (the carry-out add: through a 64-bit sum).
impl Domain for Translator<'_> {
    type Word = Value;
    type Bit = Value;
    fn add(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().iadd(x, y)
    }
    fn sub(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().isub(x, y)
    }
    fn add_carry(&mut self, x: Value, y: Value, carry: Value) -> (Value, Value) {
        let xw = self.b.ins().uextend(types::I64, x);
        let yw = self.b.ins().uextend(types::I64, y);
        let cw = self.b.ins().uextend(types::I64, carry);
        let s = self.b.ins().iadd(xw, yw);
        let wide = self.b.ins().iadd(s, cw);
        let r = self.b.ins().ireduce(types::I32, wide);
        let hi = self.b.ins().ushr_imm_u(wide, 32);
        (r, self.b.ins().ireduce(types::I8, hi))
    }
    fn xor(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().bxor(x, y)
    }
    fn and(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().band(x, y)
    }
    fn ult(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().icmp(IntCC::UnsignedLessThan, x, y)
    }
    fn uge(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, x, y)
    }
    fn sign_is(&mut self, w: Value, set: bool) -> Value {
        let cc = if set {
            IntCC::SignedLessThan
        } else {
            IntCC::SignedGreaterThanOrEqual
        };
        self.b.ins().icmp_imm_s(cc, w, 0)
    }
    fn zero_is(&mut self, w: Value, zero: bool) -> Value {
        let cc = if zero { IntCC::Equal } else { IntCC::NotEqual };
        self.b.ins().icmp_imm_u(cc, w, 0)
    }
    fn bit_is(&mut self, b: Value, set: bool) -> Value {
        let cc = if set { IntCC::NotEqual } else { IntCC::Equal };
        self.b.ins().icmp_imm_u(cc, b, 0)
    }
    fn and_not(&mut self, a: Value, b: Value) -> Value {
        self.b.ins().band_not(a, b)
    }
    fn one(&mut self) -> Value {
        self.b.ins().iconst(types::I8, 1)
    }
    fn word(&mut self, k: u32) -> Value {
        self.c32(k)
    }
    fn bit(&mut self, w: Value, i: u8) -> Value {
        let bit = self.b.ins().ushr_imm_u(w, i as i64);
        let bit = self.b.ins().band_imm_u(bit, 1);
        self.b.ins().ireduce(types::I8, bit)
    }
    fn shl_imm(&mut self, w: Value, n: u8) -> Value {
        self.b.ins().ishl_imm_u(w, n as i64)
    }
    fn ushr_imm(&mut self, w: Value, n: u8) -> Value {
        self.b.ins().ushr_imm_u(w, n as i64)
    }
    fn sshr_imm(&mut self, w: Value, n: u8) -> Value {
        self.b.ins().sshr_imm_u(w, n as i64)
    }
    fn and_imm(&mut self, w: Value, k: u32) -> Value {
        self.b.ins().band_imm_u(w, k as i64)
    }
    fn umin_imm(&mut self, w: Value, k: u32) -> Value {
        let k = self.c32(k);
        self.b.ins().umin(w, k)
    }
    fn rotr(&mut self, w: Value, s: Value) -> Value {
        self.b.ins().rotr(w, s)
    }
    fn select(&mut self, cond: Value, a: Value, b: Value) -> Value {
        self.b.ins().select(cond, a, b)
    }
    type Wide = Value;
    fn zext(&mut self, w: Value) -> Value {
        self.b.ins().uextend(types::I64, w)
    }
    fn sext(&mut self, w: Value) -> Value {
        self.b.ins().sextend(types::I64, w)
    }
    fn low(&mut self, w: Value) -> Value {
        self.b.ins().ireduce(types::I32, w)
    }
    fn wide_bit(&mut self, w: Value, i: u8) -> Value {
        let w = if i == 0 {
            w
        } else {
            self.b.ins().ushr_imm_u(w, i as i64)
        };
        let bit = self.b.ins().band_imm_u(w, 1);
        self.b.ins().ireduce(types::I8, bit)
    }
    fn wide_shl(&mut self, w: Value, s: Value) -> Value {
        self.b.ins().ishl(w, s)
    }
    fn wide_ushr(&mut self, w: Value, s: Value) -> Value {
        self.b.ins().ushr(w, s)
    }
    fn wide_sshr(&mut self, w: Value, s: Value) -> Value {
        self.b.ins().sshr(w, s)
    }
    fn wide_shl_imm(&mut self, w: Value, n: u8) -> Value {
        self.b.ins().ishl_imm_u(w, n as i64)
    }
    fn wide_sshr_imm(&mut self, w: Value, n: u8) -> Value {
        self.b.ins().sshr_imm_u(w, n as i64)
    }
}
