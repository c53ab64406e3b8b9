//! The ARMv6-M flag rules, written once over a value domain.
//!
//! The interpreter (`exec.rs`) computes on `u32`s and `bool`s; the block compiler
//! (`jit/alu.rs`) builds cranelift IR that computes them later. Both need the same rules —
//! which bit of an add is C, which word's sign is V, what each condition code tests — and a
//! rule written twice drifts. So each rule here is a generic function over a [`Domain`]: the
//! handful of word and bit operations the rules are made of. [`Host`] is the domain of plain
//! values (every method `#[inline(always)]`, so the interpreter compiles to what it would
//! with the formulas written in place); the translator's domain emits one IR instruction per
//! method, so an instruction's IR is exactly the operations its rule names.
//!
//! The common form of the flags is the block compiler's lazy one, which costs the least in
//! both domains: N as the sign of a word, Z as "a word is zero" (both the result word after
//! a data-processing instruction), C as a bit, and V as the sign of a word (the overflow
//! rule's XOR term, its sign not yet extracted). The unit tests check every rule on `u32`
//! against DDI0419's own definitions (A2.2.1 `AddWithCarry`, A6.3 the conditions).

/// The operations the flag rules are built from. `Word` is a 32-bit word, `Bit` a truth
/// value (0 or 1). Methods take `&mut self` so a domain can emit code.
pub trait Domain {
    /// A 32-bit word.
    type Word: Copy;
    /// A truth value.
    type Bit: Copy;
    /// `x + y` modulo 2³².
    fn add(&mut self, x: Self::Word, y: Self::Word) -> Self::Word;
    /// `x - y` modulo 2³².
    fn sub(&mut self, x: Self::Word, y: Self::Word) -> Self::Word;
    /// `x + y + carry` modulo 2³² and the adder's carry out (bit 32 of the exact sum).
    fn add_carry(
        &mut self,
        x: Self::Word,
        y: Self::Word,
        carry: Self::Bit,
    ) -> (Self::Word, Self::Bit);
    /// Bitwise exclusive or.
    fn xor(&mut self, x: Self::Word, y: Self::Word) -> Self::Word;
    /// Bitwise and.
    fn and(&mut self, x: Self::Word, y: Self::Word) -> Self::Word;
    /// `x < y`, unsigned.
    fn ult(&mut self, x: Self::Word, y: Self::Word) -> Self::Bit;
    /// `x >= y`, unsigned.
    fn uge(&mut self, x: Self::Word, y: Self::Word) -> Self::Bit;
    /// Whether bit 31 of `w` equals `set`.
    fn sign_is(&mut self, w: Self::Word, set: bool) -> Self::Bit;
    /// Whether "`w` is zero" equals `zero`.
    fn zero_is(&mut self, w: Self::Word, zero: bool) -> Self::Bit;
    /// Whether the bit `b` equals `set`.
    fn bit_is(&mut self, b: Self::Bit, set: bool) -> Self::Bit;
    /// `a AND NOT b`.
    fn and_not(&mut self, a: Self::Bit, b: Self::Bit) -> Self::Bit;
    /// The constant true.
    fn one(&mut self) -> Self::Bit;
    /// The constant word `k`.
    fn word(&mut self, k: u32) -> Self::Word;
    /// Bit `i` (0-31) of `w`.
    fn bit(&mut self, w: Self::Word, i: u8) -> Self::Bit;
    /// `w << n` (n 1-31).
    fn shl_imm(&mut self, w: Self::Word, n: u8) -> Self::Word;
    /// `w >> n`, logical (n 1-31).
    fn ushr_imm(&mut self, w: Self::Word, n: u8) -> Self::Word;
    /// `w >> n`, arithmetic (n 1-31).
    fn sshr_imm(&mut self, w: Self::Word, n: u8) -> Self::Word;
    /// `w & k`.
    fn and_imm(&mut self, w: Self::Word, k: u32) -> Self::Word;
    /// The unsigned minimum of `w` and `k`.
    fn umin_imm(&mut self, w: Self::Word, k: u32) -> Self::Word;
    /// `w` rotated right by `s` (0-31).
    fn rotr(&mut self, w: Self::Word, s: Self::Word) -> Self::Word;
    /// `a` if `cond` else `b`.
    fn select(&mut self, cond: Self::Bit, a: Self::Bit, b: Self::Bit) -> Self::Bit;

    /// A 64-bit word (the register shifts' carry rides in it).
    type Wide: Copy;
    /// `w` zero-extended to 64 bits.
    fn zext(&mut self, w: Self::Word) -> Self::Wide;
    /// `w` sign-extended to 64 bits.
    fn sext(&mut self, w: Self::Word) -> Self::Wide;
    /// The low 32 bits of `w`.
    fn low(&mut self, w: Self::Wide) -> Self::Word;
    /// Bit `i` (0-63) of `w`.
    fn wide_bit(&mut self, w: Self::Wide, i: u8) -> Self::Bit;
    /// `w << s` (s 0-33).
    fn wide_shl(&mut self, w: Self::Wide, s: Self::Wide) -> Self::Wide;
    /// `w >> s`, logical (s 0-33).
    fn wide_ushr(&mut self, w: Self::Wide, s: Self::Wide) -> Self::Wide;
    /// `w >> s`, arithmetic (s 0-33).
    fn wide_sshr(&mut self, w: Self::Wide, s: Self::Wide) -> Self::Wide;
    /// `w << n` (n 1-63).
    fn wide_shl_imm(&mut self, w: Self::Wide, n: u8) -> Self::Wide;
    /// `w >> n`, arithmetic (n 1-63).
    fn wide_sshr_imm(&mut self, w: Self::Wide, n: u8) -> Self::Wide;
}

/// A shift or rotate by a register (the ALU group's LSLS, LSRS, ASRS, RORS).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShiftReg {
    /// `LSLS Rdn, Rm`.
    Lsl,
    /// `LSRS Rdn, Rm`.
    Lsr,
    /// `ASRS Rdn, Rm`.
    Asr,
    /// `RORS Rdn, Rm`.
    Ror,
}

impl ShiftReg {
    /// The shift or rotate of an ALU-group operation, `None` for the others.
    pub fn of(op: tactus_isa::decode::AluOp) -> Option<ShiftReg> {
        use tactus_isa::decode::AluOp;
        match op {
            AluOp::Lsl => Some(ShiftReg::Lsl),
            AluOp::Lsr => Some(ShiftReg::Lsr),
            AluOp::Asr => Some(ShiftReg::Asr),
            AluOp::Ror => Some(ShiftReg::Ror),
            _ => None,
        }
    }
}

/// `Shift_C(x, type, m<7:0>, carry)` for a shift by a register (DDI0419 A2.2.2, A6.7.37,
/// A6.7.69, A6.7.11, A6.7.57): the result and the carry out; an amount of 0 keeps `carry`.
/// The amount is clamped to 33, which shifts everything out as any larger one does, and
/// the shift is done in 64 bits so the last bit shifted out stays in the word: bit 32
/// after a left shift; bit 0 after a right shift of the operand moved up by one (`ASR`
/// extends the sign, so amounts past 32 leave copies of it). A rotate's carry is the
/// result's bit 31.
#[inline(always)]
pub fn shift_reg<D: Domain>(
    d: &mut D,
    kind: ShiftReg,
    x: D::Word,
    m: D::Word,
    carry: D::Bit,
) -> (D::Word, D::Bit) {
    let s = d.and_imm(m, 0xff);
    let (r, c) = match kind {
        ShiftReg::Ror => {
            let s31 = d.and_imm(m, 31);
            let r = d.rotr(x, s31);
            (r, d.sign_is(r, true))
        }
        ShiftReg::Lsl => {
            let s = d.umin_imm(s, 33);
            let s64 = d.zext(s);
            let w = d.zext(x);
            let w = d.wide_shl(w, s64);
            (d.low(w), d.wide_bit(w, 32))
        }
        ShiftReg::Lsr | ShiftReg::Asr => {
            let s = d.umin_imm(s, 33);
            let s64 = d.zext(s);
            let w = if kind == ShiftReg::Lsr {
                d.zext(x)
            } else {
                d.sext(x)
            };
            let w = d.wide_shl_imm(w, 1);
            let u = if kind == ShiftReg::Lsr {
                d.wide_ushr(w, s64)
            } else {
                d.wide_sshr(w, s64)
            };
            let r = d.wide_sshr_imm(u, 1);
            (d.low(r), d.wide_bit(u, 0))
        }
    };
    let zero = d.zero_is(s, true);
    (r, d.select(zero, carry, c))
}

/// A shift by an immediate (LSLS, LSRS, ASRS with `imm5`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShiftImm {
    /// `LSLS Rd, Rm, #n`, n 0-31 (0 is `MOVS Rd, Rm`: carry unchanged).
    Lsl,
    /// `LSRS Rd, Rm, #n`, n 1-32.
    Lsr,
    /// `ASRS Rd, Rm, #n`, n 1-32.
    Asr,
}

/// `Shift_C(x, type, n, carry)` for an immediate amount (DDI0419 A2.2.2; the decoded `n`
/// of A6.7.36/68/10): the result and the carry out, `None` where the carry is unchanged
/// (LSL #0). The carry out is the last bit shifted out: bit `32 - n` of `x` to the left,
/// bit `n - 1` to the right (for ASR too: `n - 1` is at most 31, below the copies of the
/// sign).
#[inline(always)]
pub fn shift_imm<D: Domain>(
    d: &mut D,
    kind: ShiftImm,
    x: D::Word,
    n: u8,
) -> (D::Word, Option<D::Bit>) {
    match kind {
        ShiftImm::Lsl if n == 0 => (x, None),
        ShiftImm::Lsl => {
            let c = d.bit(x, 32 - n);
            (d.shl_imm(x, n), Some(c))
        }
        ShiftImm::Lsr => {
            let c = d.bit(x, n - 1);
            let r = if n == 32 { d.word(0) } else { d.ushr_imm(x, n) };
            (r, Some(c))
        }
        ShiftImm::Asr => {
            let c = d.bit(x, n - 1);
            (d.sshr_imm(x, n.min(31)), Some(c))
        }
    }
}

/// The result of a flag-setting add or subtract: the result word (N and Z come from it),
/// C, and the word whose sign is V.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Flagged<W, B> {
    /// The result; N is its sign, Z whether it is zero.
    pub result: W,
    /// The carry flag.
    pub c: B,
    /// A word whose sign is the overflow flag.
    pub v: W,
}

/// The overflow word of `r = x + y (+ carry)`: signed overflow happened exactly when both
/// operands' signs differ from the result's, i.e. when bit 31 of `(x ^ r) & (y ^ r)` is set.
#[inline(always)]
fn add_overflow<D: Domain>(d: &mut D, x: D::Word, y: D::Word, r: D::Word) -> D::Word {
    let a = d.xor(x, r);
    let b = d.xor(y, r);
    d.and(a, b)
}

/// `AddWithCarry(x, y, carry)` (DDI0419 A2.2.1): ADCS, SBCS (with `y = NOT Rm`).
#[inline(always)]
pub fn add_with_carry<D: Domain>(
    d: &mut D,
    x: D::Word,
    y: D::Word,
    carry: D::Bit,
) -> Flagged<D::Word, D::Bit> {
    let (result, c) = d.add_carry(x, y, carry);
    let v = add_overflow(d, x, y, result);
    Flagged { result, c, v }
}

/// `AddWithCarry(x, y, '0')`: ADDS, CMN. The carry out is the unsigned wrap, `r < x`.
#[inline(always)]
pub fn add<D: Domain>(d: &mut D, x: D::Word, y: D::Word) -> Flagged<D::Word, D::Bit> {
    let result = d.add(x, y);
    let c = d.ult(result, x);
    let v = add_overflow(d, x, y, result);
    Flagged { result, c, v }
}

/// `AddWithCarry(x, NOT y, '1')`: SUBS, CMP, RSBS/NEGS (`x = 0`). The carry is "no borrow",
/// `x >= y` unsigned; signed overflow happened exactly when the operands' signs differ and
/// the result's differs from `x`'s: bit 31 of `(x ^ y) & (x ^ r)`.
#[inline(always)]
pub fn sub<D: Domain>(d: &mut D, x: D::Word, y: D::Word) -> Flagged<D::Word, D::Bit> {
    let result = d.sub(x, y);
    let c = d.uge(x, y);
    let a = d.xor(x, y);
    let b = d.xor(x, result);
    let v = d.and(a, b);
    Flagged { result, c, v }
}

/// The flags as a condition reads them, in the common form (see the module doc). Reads
/// are on demand, so a condition reads (and a translation emits) only what it tests.
pub trait HeldFlags<D: Domain> {
    /// A word whose sign is N.
    fn n(&self, d: &mut D) -> D::Word;
    /// A word that is zero exactly when Z is set.
    fn z(&self, d: &mut D) -> D::Word;
    /// C.
    fn c(&self, d: &mut D) -> D::Bit;
    /// A word whose sign is V.
    fn v(&self, d: &mut D) -> D::Word;
}

/// `ConditionPassed` for condition code `cond` (0-14; DDI0419 A6.3, table A6-1): each pair
/// `2k`/`2k + 1` is a test and its complement, the complement folded into the test's last
/// comparison. 14 (AL) holds; 15 is not a condition (B with 15 is SVC) and reads as AL.
#[inline(always)]
pub fn condition<D: Domain, F: HeldFlags<D>>(d: &mut D, f: &F, cond: u8) -> D::Bit {
    let holds = cond & 1 == 0;
    match cond >> 1 {
        // EQ/NE: Z.
        0 => {
            let z = f.z(d);
            d.zero_is(z, holds)
        }
        // CS/CC: C.
        1 => {
            let c = f.c(d);
            d.bit_is(c, holds)
        }
        // MI/PL: N.
        2 => {
            let n = f.n(d);
            d.sign_is(n, holds)
        }
        // VS/VC: V.
        3 => {
            let v = f.v(d);
            d.sign_is(v, holds)
        }
        // HI/LS: C and not Z.
        4 => {
            let c = f.c(d);
            let z = f.z(d);
            let z = d.zero_is(z, true);
            let hi = d.and_not(c, z);
            d.bit_is(hi, holds)
        }
        // GE/LT: N == V, i.e. the sign of N ^ V is clear.
        5 => {
            let (n, v) = (f.n(d), f.v(d));
            let x = d.xor(n, v);
            d.sign_is(x, !holds)
        }
        // GT/LE: N == V and not Z.
        6 => {
            let (n, v) = (f.n(d), f.v(d));
            let x = d.xor(n, v);
            let ge = d.sign_is(x, false);
            let z = f.z(d);
            let z = d.zero_is(z, true);
            let gt = d.and_not(ge, z);
            d.bit_is(gt, holds)
        }
        _ => d.one(),
    }
}

/// The domain of plain values: the interpreter's.
#[derive(Clone, Copy, Debug, Default)]
pub struct Host;

impl Domain for Host {
    type Word = u32;
    type Bit = bool;
    #[inline(always)]
    fn add(&mut self, x: u32, y: u32) -> u32 {
        x.wrapping_add(y)
    }
    #[inline(always)]
    fn sub(&mut self, x: u32, y: u32) -> u32 {
        x.wrapping_sub(y)
    }
    #[inline(always)]
    fn add_carry(&mut self, x: u32, y: u32, carry: bool) -> (u32, bool) {
        let wide = x as u64 + y as u64 + carry as u64;
        (wide as u32, wide >> 32 != 0)
    }
    #[inline(always)]
    fn xor(&mut self, x: u32, y: u32) -> u32 {
        x ^ y
    }
    #[inline(always)]
    fn and(&mut self, x: u32, y: u32) -> u32 {
        x & y
    }
    #[inline(always)]
    fn ult(&mut self, x: u32, y: u32) -> bool {
        x < y
    }
    #[inline(always)]
    fn uge(&mut self, x: u32, y: u32) -> bool {
        x >= y
    }
    #[inline(always)]
    fn sign_is(&mut self, w: u32, set: bool) -> bool {
        ((w as i32) < 0) == set
    }
    #[inline(always)]
    fn zero_is(&mut self, w: u32, zero: bool) -> bool {
        (w == 0) == zero
    }
    #[inline(always)]
    fn bit_is(&mut self, b: bool, set: bool) -> bool {
        b == set
    }
    #[inline(always)]
    fn and_not(&mut self, a: bool, b: bool) -> bool {
        a && !b
    }
    #[inline(always)]
    fn one(&mut self) -> bool {
        true
    }
    #[inline(always)]
    fn word(&mut self, k: u32) -> u32 {
        k
    }
    #[inline(always)]
    fn bit(&mut self, w: u32, i: u8) -> bool {
        (w >> i) & 1 == 1
    }
    #[inline(always)]
    fn shl_imm(&mut self, w: u32, n: u8) -> u32 {
        w << n
    }
    #[inline(always)]
    fn ushr_imm(&mut self, w: u32, n: u8) -> u32 {
        w >> n
    }
    #[inline(always)]
    fn sshr_imm(&mut self, w: u32, n: u8) -> u32 {
        ((w as i32) >> n) as u32
    }
    #[inline(always)]
    fn and_imm(&mut self, w: u32, k: u32) -> u32 {
        w & k
    }
    #[inline(always)]
    fn umin_imm(&mut self, w: u32, k: u32) -> u32 {
        w.min(k)
    }
    #[inline(always)]
    fn rotr(&mut self, w: u32, s: u32) -> u32 {
        w.rotate_right(s)
    }
    #[inline(always)]
    fn select(&mut self, cond: bool, a: bool, b: bool) -> bool {
        if cond {
            a
        } else {
            b
        }
    }
    type Wide = u64;
    #[inline(always)]
    fn zext(&mut self, w: u32) -> u64 {
        w as u64
    }
    #[inline(always)]
    fn sext(&mut self, w: u32) -> u64 {
        w as i32 as i64 as u64
    }
    #[inline(always)]
    fn low(&mut self, w: u64) -> u32 {
        w as u32
    }
    #[inline(always)]
    fn wide_bit(&mut self, w: u64, i: u8) -> bool {
        (w >> i) & 1 == 1
    }
    #[inline(always)]
    fn wide_shl(&mut self, w: u64, s: u64) -> u64 {
        w << s
    }
    #[inline(always)]
    fn wide_ushr(&mut self, w: u64, s: u64) -> u64 {
        w >> s
    }
    #[inline(always)]
    fn wide_sshr(&mut self, w: u64, s: u64) -> u64 {
        ((w as i64) >> s) as u64
    }
    #[inline(always)]
    fn wide_shl_imm(&mut self, w: u64, n: u8) -> u64 {
        w << n
    }
    #[inline(always)]
    fn wide_sshr_imm(&mut self, w: u64, n: u8) -> u64 {
        ((w as i64) >> n) as u64
    }
}

/// Four flags as bools (the interpreter's [`crate::core::Core`] holds them so), read in the
/// common form: N and V as bit 31 of a word, Z as a word that is zero exactly when Z is
/// set. Exact for every combination, including N and Z both set (`MSR APSR`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Nzcv {
    /// Negative.
    pub n: bool,
    /// Zero.
    pub z: bool,
    /// Carry.
    pub c: bool,
    /// Overflow.
    pub v: bool,
}

impl HeldFlags<Host> for Nzcv {
    #[inline(always)]
    fn n(&self, _: &mut Host) -> u32 {
        (self.n as u32) << 31
    }
    #[inline(always)]
    fn z(&self, _: &mut Host) -> u32 {
        !self.z as u32
    }
    #[inline(always)]
    fn c(&self, _: &mut Host) -> bool {
        self.c
    }
    #[inline(always)]
    fn v(&self, _: &mut Host) -> u32 {
        (self.v as u32) << 31
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// DDI0419 A2.2.1 `AddWithCarry`, literally: the unsigned and the signed sums, C when
    /// the unsigned sum differs from the result read unsigned, V when the signed sum
    /// differs from the result read signed.
    fn ddi0419_add_with_carry(x: u32, y: u32, carry: bool) -> (u32, bool, bool) {
        let unsigned_sum = x as u64 + y as u64 + carry as u64;
        let signed_sum = x as i32 as i64 + y as i32 as i64 + carry as i64;
        let result = unsigned_sum as u32;
        (
            result,
            result as u64 != unsigned_sum,
            result as i32 as i64 != signed_sum,
        )
    }

    /// DDI0419 A6.3, table A6-1, literally.
    fn ddi0419_condition(cond: u8, n: bool, z: bool, c: bool, v: bool) -> bool {
        match cond {
            0 => z,
            1 => !z,
            2 => c,
            3 => !c,
            4 => n,
            5 => !n,
            6 => v,
            7 => !v,
            8 => c && !z,
            9 => !c || z,
            10 => n == v,
            11 => n != v,
            12 => !z && n == v,
            13 => z || n != v,
            _ => true,
        }
    }

    /// Edge operands, then pseudo-random ones (xorshift, fixed seed).
    fn operands() -> Vec<u32> {
        let mut v = vec![
            0,
            1,
            2,
            0x7fff_ffff,
            0x8000_0000,
            0x8000_0001,
            0xffff_fffe,
            0xffff_ffff,
        ];
        let mut s = 0x9e37_79b9u32;
        for _ in 0..120 {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            v.push(s);
        }
        v
    }

    fn split(f: Flagged<u32, bool>) -> (u32, bool, bool) {
        (f.result, f.c, (f.v as i32) < 0)
    }

    #[test]
    fn add_and_subtract_flags_are_ddi0419s_add_with_carry() {
        let ops = operands();
        for &x in &ops {
            for &y in &ops {
                for carry in [false, true] {
                    assert_eq!(
                        split(add_with_carry(&mut Host, x, y, carry)),
                        ddi0419_add_with_carry(x, y, carry),
                        "ADCS {x:#x} {y:#x} {carry}"
                    );
                }
                assert_eq!(
                    split(add(&mut Host, x, y)),
                    ddi0419_add_with_carry(x, y, false),
                    "ADDS {x:#x} {y:#x}"
                );
                assert_eq!(
                    split(sub(&mut Host, x, y)),
                    ddi0419_add_with_carry(x, !y, true),
                    "SUBS {x:#x} {y:#x}"
                );
            }
        }
    }

    /// DDI0419 A2.2.2 `LSL_C`, `LSR_C`, `ASR_C` literally: the operand extended to 64 + n
    /// bits, shifted, the result its low word, the carry the bit just past it.
    fn ddi0419_shift_c(kind: ShiftImm, x: u32, n: u8) -> (u32, Option<bool>) {
        let n = n as u32;
        match kind {
            ShiftImm::Lsl if n == 0 => (x, None),
            ShiftImm::Lsl => {
                let extended = (x as u64) << n;
                (extended as u32, Some((extended >> 32) & 1 == 1))
            }
            ShiftImm::Lsr | ShiftImm::Asr => {
                let extended = if kind == ShiftImm::Lsr {
                    x as u64
                } else {
                    x as i32 as i64 as u64
                };
                ((extended >> n) as u32, Some((extended >> (n - 1)) & 1 == 1))
            }
        }
    }

    #[test]
    fn immediate_shifts_are_ddi0419s_shift_c() {
        for &x in &operands() {
            for n in 0..=32u8 {
                let kinds: &[ShiftImm] = match n {
                    0 => &[ShiftImm::Lsl],
                    32 => &[ShiftImm::Lsr, ShiftImm::Asr],
                    _ => &[ShiftImm::Lsl, ShiftImm::Lsr, ShiftImm::Asr],
                };
                for &kind in kinds {
                    assert_eq!(
                        shift_imm(&mut Host, kind, x, n),
                        ddi0419_shift_c(kind, x, n),
                        "{kind:?} {x:#x} #{n}"
                    );
                }
            }
        }
    }

    /// DDI0419's register shifts, one bit at a time: the carry is the last bit shifted
    /// (or rotated) out; an amount of 0 keeps it.
    fn ddi0419_shift_reg(kind: ShiftReg, x: u32, m: u32, carry: bool) -> (u32, bool) {
        let (mut r, mut c) = (x, carry);
        for _ in 0..m & 0xff {
            match kind {
                ShiftReg::Lsl => (r, c) = (r << 1, r >> 31 == 1),
                ShiftReg::Lsr => (r, c) = (r >> 1, r & 1 == 1),
                ShiftReg::Asr => (r, c) = (((r as i32) >> 1) as u32, r & 1 == 1),
                ShiftReg::Ror => (r, c) = (r.rotate_right(1), r & 1 == 1),
            }
        }
        (r, c)
    }

    #[test]
    fn register_shifts_are_ddi0419s() {
        let mut amounts: Vec<u32> = (0..=40).chain([63, 64, 127, 128, 255, 256, 257]).collect();
        amounts.extend(operands().into_iter().take(40));
        for &x in &operands() {
            for &m in &amounts {
                for kind in [ShiftReg::Lsl, ShiftReg::Lsr, ShiftReg::Asr, ShiftReg::Ror] {
                    for carry in [false, true] {
                        assert_eq!(
                            shift_reg(&mut Host, kind, x, m, carry),
                            ddi0419_shift_reg(kind, x, m, carry),
                            "{kind:?} {x:#x} by {m:#x}, carry {carry}"
                        );
                    }
                }
            }
        }
    }

    /// Every condition on every combination of the four flags held as bools (sixteen,
    /// including N and Z both set), and on the flags an add and a subtract of the edge and
    /// random operands leave in the lazy form (N/Z as the result word, V as the XOR word).
    #[test]
    fn conditions_are_ddi0419s() {
        for cond in 0..15u8 {
            for bits in 0..16u8 {
                let f = Nzcv {
                    n: bits & 8 != 0,
                    z: bits & 4 != 0,
                    c: bits & 2 != 0,
                    v: bits & 1 != 0,
                };
                assert_eq!(
                    condition(&mut Host, &f, cond),
                    ddi0419_condition(cond, f.n, f.z, f.c, f.v),
                    "cond {cond} on {f:?}"
                );
            }
        }
        /// The lazy form: one word for N and Z, the V word.
        struct Lazy(Flagged<u32, bool>);
        impl HeldFlags<Host> for Lazy {
            fn n(&self, _: &mut Host) -> u32 {
                self.0.result
            }
            fn z(&self, _: &mut Host) -> u32 {
                self.0.result
            }
            fn c(&self, _: &mut Host) -> bool {
                self.0.c
            }
            fn v(&self, _: &mut Host) -> u32 {
                self.0.v
            }
        }
        let ops = operands();
        let mut seen = [[0u32; 2]; 15];
        for &x in &ops {
            for &y in &ops {
                for (f, (r, c, v)) in [
                    (add(&mut Host, x, y), ddi0419_add_with_carry(x, y, false)),
                    (sub(&mut Host, x, y), ddi0419_add_with_carry(x, !y, true)),
                ] {
                    let (n, z) = ((r as i32) < 0, r == 0);
                    for cond in 0..15u8 {
                        let want = ddi0419_condition(cond, n, z, c, v);
                        assert_eq!(
                            condition(&mut Host, &Lazy(f), cond),
                            want,
                            "cond {cond} after {x:#x}, {y:#x}"
                        );
                        seen[cond as usize][want as usize] += 1;
                    }
                }
            }
        }
        // Each condition was seen both holding and failing (AL only holding).
        for (cond, s) in seen.iter().enumerate() {
            assert!(s[1] > 0 && (cond == 14 || s[0] > 0), "cond {cond}: {s:?}");
        }
    }
}
