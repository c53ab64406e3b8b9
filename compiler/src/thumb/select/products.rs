//! Products: the plan's forms ([`MulKind`]) as ARMv6-M sequences — a pre-shifted `MULS`, a
//! 32×16 product from two 16×16 partial products, the high word of 32×32 from three, the
//! full 64-bit product from four (ARMv6-M has no `SMULL`).

use super::*;
use crate::fixed::Cut;

/// The second operand of a multiplication.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Operand {
    /// A word in a register.
    Word(W),
    /// A raw constant word.
    Const(i32),
}

impl<'a> Sel<'a> {
    /// Signed 32×32 → 64-bit product from four 16×16 `MULS`.
    pub(super) fn smull(&mut self, a: V, b: V) -> (V, V) {
        let al = self.nv();
        self.push(M::Uxth { d: al, m: a });
        let ah = self.sh(Shift::Asr, a, 16);
        let bl = self.nv();
        self.push(M::Uxth { d: bl, m: b });
        let bh = self.sh(Shift::Asr, b, 16);
        // In this order only the first `MULS` needs a copy of an operand: each later one
        // overwrites an operand at its last use (`bl`, `al`, then both).
        let lo = self.alu2(AluOp::Mul, al, bl);
        let m1 = self.alu2(AluOp::Mul, ah, bl);
        let m2 = self.alu2(AluOp::Mul, al, bh);
        let hi = self.alu2(AluOp::Mul, ah, bh);
        self.add_cross_terms((lo, hi), m1, m2)
    }

    /// `(lo, hi) + m1·2^16 + m2·2^16` as a 64-bit pair: the cross terms of a product from
    /// 16-bit halves (`lo`, `hi` the low·low and high·high products, `m1`, `m2` the mixed
    /// ones, each shifted into both words with its sign).
    pub(super) fn add_cross_terms(&mut self, (lo, hi): (V, V), m1: V, m2: V) -> (V, V) {
        let t1 = self.sh(Shift::Lsl, m1, 16);
        let u1 = self.sh(Shift::Asr, m1, 16);
        let (lo, hi) = self.add64((lo, hi), (t1, u1), false);
        let t2 = self.sh(Shift::Lsl, m2, 16);
        let u2 = self.sh(Shift::Asr, m2, 16);
        self.add64((lo, hi), (t2, u2), false)
    }

    /// `x · y` with the given plan into a result of bound `rb`: `fx`, `fy` the operands'
    /// fraction bits, `fr` the result's.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn mul(
        &mut self,
        x: W,
        fx_: i32,
        y: Operand,
        fy: i32,
        fr: i32,
        kind: MulKind,
        rb: u64,
    ) -> W {
        match kind {
            MulKind::Muls(a, b) => {
                let xs = self.floor_shr(x, a as i32);
                let e = fr - (fx_ - a as i32) - (fy - b as i32);
                let prod = match y {
                    Operand::Const(c) => {
                        let c = ((c as i64) >> b.min(31)) as i32;
                        if c == 0 {
                            return W {
                                v: self.movi(0),
                                b: 0,
                            };
                        }
                        let k = c.unsigned_abs();
                        if k.is_power_of_two() {
                            // x · ±2^j: a shift (exact), negated when the constant is.
                            let j = k.trailing_zeros() as i32;
                            let base = if c < 0 { self.neg(xs) } else { xs };
                            return self.round(base, e + j);
                        }
                        let cv = self.movi(c);
                        W {
                            v: self.alu2(AluOp::Mul, xs.v, cv),
                            b: xs.b.saturating_mul(k as u64),
                        }
                    }
                    Operand::Word(y) => {
                        let ys = self.floor_shr(y, b as i32);
                        W {
                            v: self.alu2(AluOp::Mul, xs.v, ys.v),
                            b: xs.b.saturating_mul(ys.b),
                        }
                    }
                };
                self.round(prod, e)
            }
            MulKind::Mul32x16 { cut, b, k } => {
                // The operand order of `mul` is (word, operand); the cut one is `c`.
                let (kept, fk, c, fc) = match (cut, y) {
                    (Cut::Second, y) => (x, fx_, y, fy),
                    (Cut::First, Operand::Word(w)) => (w, fy, Operand::Word(x), fx_),
                    (Cut::First, Operand::Const(_)) => {
                        // The planner cuts the constant of a product by a constant.
                        self.unsupported(
                            "a 32×16 product that cuts its run-time operand against a constant",
                        );
                        return W {
                            v: self.movi(0),
                            b: 0,
                        };
                    }
                };
                self.mul_32x16(kept, fk, c, fc, b, k, fr)
            }
            MulKind::High(k) => {
                // fixed::mul_high: xh·yh·2^(32−k) + floor(xh·yl / 2^(k−16)) +
                // floor(xl·yh / 2^(k−16)), each partial product one MULS.
                let k = k.clamp(16, 32) as i32;
                let xh = self.sh(Shift::Asr, x.v, 16);
                // A constant's zero half contributes nothing: its partial products are 0
                // (`None`), and its register is never loaded.
                let (yh, yl, yb) = match y {
                    Operand::Const(c) => {
                        let half = |this: &mut Self, h: i32| (h != 0).then(|| this.movi(h));
                        (
                            half(self, c >> 16),
                            half(self, c & 0xffff),
                            c.unsigned_abs() as u64,
                        )
                    }
                    Operand::Word(w) => {
                        let yl = self.nv();
                        self.push(M::Uxth { d: yl, m: w.v });
                        (Some(self.sh(Shift::Asr, w.v, 16)), Some(yl), w.b)
                    }
                };
                let mut parts = Vec::with_capacity(3);
                // x's low half only where a high half of y multiplies it.
                let xl = yh.map(|_| {
                    let xl = self.nv();
                    self.push(M::Uxth { d: xl, m: x.v });
                    xl
                });
                // The mixed products first, `xh·yh` last: each `MULS` then overwrites an
                // operand at its last use (`yl`, then `xl`, then both), and no `MOV` copies
                // one (the sum is the same word in any order: the bound proves it fits).
                for (a, b) in [(Some(xh), yl), (xl, yh)] {
                    let (Some(a), Some(b)) = (a, b) else { continue };
                    let mut t = self.alu2(AluOp::Mul, a, b);
                    if k > 16 {
                        t = self.sh(Shift::Asr, t, (k - 16) as u8);
                    }
                    parts.push(t);
                }
                if let Some(yh) = yh {
                    let mut hh = self.alu2(AluOp::Mul, xh, yh);
                    if k < 32 {
                        hh = self.sh(Shift::Lsl, hh, (32 - k) as u8);
                    }
                    parts.push(hh);
                }
                let mut p = match parts.first() {
                    Some(&t) => t,
                    None => self.movi(0),
                };
                for &t in parts.iter().skip(1) {
                    p = self.addsub(false, p, t);
                }
                // The planner's bound (`MulOperands::high`): the sum fits an i32.
                let (hx, hy) = ((x.b.min(LIM) >> 16) + 1, (yb.min(LIM) >> 16) + 1);
                let pb = ((hx * hy + hx + hy) << (32 - k)) + 2;
                if pb >= LIM {
                    self.unsupported("a high-word product whose partial sum may not fit 32 bits");
                }
                self.round(
                    W {
                        v: p,
                        b: pb.min(LIM),
                    },
                    fr - (fx_ + fy - k),
                )
            }
            MulKind::Wide => {
                let yv = match y {
                    Operand::Const(c) => self.movi(c),
                    Operand::Word(w) => w.v,
                };
                let p = self.smull(x.v, yv);
                self.round64(p, fr - fx_ - fy, rb)
            }
        }
    }

    /// `fixed::mul_32x16`: `ys = c >> b` (a signed 16-bit half), `x = xh·2^16 + xl`, and
    /// `xh·ys·2^(16−k) + floor(xl·ys / 2^k)` from two `MULS`, rounded to `fr`. `x` has
    /// `fx_` fraction bits, `c` `fc`.
    ///
    /// `ASRS xh, x, #16; UXTH xl, x;` the cut word's `ASRS` (or its constant's load);
    /// `MULS` twice (each overwrites an operand at its last use: `xh`, then `xl` or `ys`);
    /// `LSLS #(16−k)`, `ASRS #k`, `ADDS`; then the rounding shift, if the plan left one.
    #[allow(clippy::too_many_arguments)]
    fn mul_32x16(&mut self, x: W, fx_: i32, c: Operand, fc: i32, b: u8, k: u8, fr: i32) -> W {
        let (b, k) = (b.min(31) as i32, k.min(16) as i32);
        let (ys, ysb) = match c {
            Operand::Const(c) => {
                let ys = c >> b;
                if ys == 0 {
                    return W {
                        v: self.movi(0),
                        b: 0,
                    };
                }
                (self.movi(ys), ys.unsigned_abs() as u64)
            }
            Operand::Word(w) => {
                let v = if b > 0 {
                    self.sh(Shift::Asr, w.v, b as u8)
                } else {
                    w.v
                };
                (v, (w.b.min(LIM) >> b) + 1)
            }
        };
        // The planner's bounds (`MulOperands::half`): `ys` a 16-bit half, every part of
        // the sum and the sum within an i32.
        let hx = (x.b.min(LIM) >> 16) + 1;
        let high = (hx * ysb) << (16 - k);
        let pb = high + ((65535 * ysb) >> k) + 2;
        if ysb > 1 << 15 || pb >= LIM {
            self.unsupported("a 32×16 product whose partial sum may not fit 32 bits");
        }
        let xh = self.sh(Shift::Asr, x.v, 16);
        let xl = self.nv();
        self.push(M::Uxth { d: xl, m: x.v });
        let mut hh = self.alu2(AluOp::Mul, xh, ys);
        let mut ll = self.alu2(AluOp::Mul, xl, ys);
        if k < 16 {
            hh = self.sh(Shift::Lsl, hh, (16 - k) as u8);
        }
        if k > 0 {
            ll = self.sh(Shift::Asr, ll, k as u8);
        }
        let p = self.addsub(false, hh, ll);
        self.round(
            W {
                v: p,
                b: pb.min(LIM),
            },
            fr - (fx_ + fc - b - k),
        )
    }

    /// `floor(p · r / 2^32)` for `0 ≤ p < 2^31` and the word `r` given as its halves
    /// `rl = r & 0xFFFF`, `rh = r >> 16` (arithmetic): the exact 64-bit product from four
    /// 16×16 `MULS`, high word kept.
    pub(super) fn mulhi_halves(&mut self, p: V, rl: V, rh: V) -> V {
        let pl = self.nv();
        self.push(M::Uxth { d: pl, m: p });
        let ph = self.sh(Shift::Lsr, p, 16);
        let lo = self.alu2(AluOp::Mul, pl, rl);
        let hi = self.alu2(AluOp::Mul, ph, rh);
        let m1 = self.alu2(AluOp::Mul, pl, rh);
        let m2 = self.alu2(AluOp::Mul, ph, rl);
        self.add_cross_terms((lo, hi), m1, m2).1
    }
}
