//! Products: the plan's forms ([`MulKind`]) as ARMv6-M sequences — a pre-shifted `MULS`, a
//! 32×16 product from two 16×16 partial products, the high word of 32×32 from three, the
//! full 64-bit product from four (ARMv6-M has no `SMULL`).

use super::*;
use crate::fixed::Cut;

/// Cycles to load the word `imm` into a register (`emit::Emitter::movi`): `MOVS #imm8`
/// 1; `MOVS`+`MVNS` or a literal-pool `LDR` 2.
pub(super) fn load_cost(imm: i32) -> u32 {
    if (0..=255).contains(&imm) {
        1
    } else {
        2
    }
}

/// The second operand of a multiplication.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Operand {
    /// A word in a register.
    Word(W),
    /// A raw constant word.
    Const(i32),
}

impl<'a> Sel<'a> {
    /// Signed 32×32 → 64-bit product from four 16×16 `MULS` (fewer by a known word:
    /// [`Sel::smull_const`]).
    pub(super) fn smull(&mut self, a: V, b: V) -> (V, V) {
        if let Some(&c) = self.konst.get(&b) {
            if let Some(p) = self.smull_const(a, c) {
                return p;
            }
        }
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

    /// `a · c` as a 64-bit pair for a known `c` with a zero half, `None` (nothing emitted)
    /// otherwise. With `c = ch·2^16 + cl` (`cl = c & 0xFFFF`) and `a = ah·2^16 + al`:
    ///
    /// * `cl = 0`: `a·c = ah·ch·2^32 + al·ch·2^16` — two `MULS` (`|al·ch| < 2^31`), the
    ///   second shifted into both words; the low word of the first term is 0, so nothing
    ///   carries: `hi = ah·ch + (al·ch >> 16)`, `lo = al·ch << 16`.
    /// * `ch = 0` (`0 < c < 2^16`): `a·c = al·cl + ah·cl·2^16` — two `MULS`, `al·cl < 2^32`
    ///   the unsigned low word, `ah·cl` added into both words with its carry.
    ///
    /// The constant's halves are known words (no `UXTH`/`ASRS` of a loaded constant), and
    /// the two partial products of the zero half are never computed.
    fn smull_const(&mut self, a: V, c: i32) -> Option<(V, V)> {
        let (cl, ch) = (c & 0xffff, c >> 16);
        if cl != 0 && ch != 0 {
            return None;
        }
        let al = self.nv();
        self.push(M::Uxth { d: al, m: a });
        let ah = self.sh(Shift::Asr, a, 16);
        if cl == 0 {
            let kv = self.movi(ch);
            let mid = self.alu2(AluOp::Mul, al, kv);
            let hi = self.alu2(AluOp::Mul, ah, kv);
            let lo = self.sh(Shift::Lsl, mid, 16);
            let carry = self.sh(Shift::Asr, mid, 16);
            let hi = self.addsub(false, hi, carry);
            Some((lo, hi))
        } else {
            let kv = self.movi(cl);
            let lo = self.alu2(AluOp::Mul, al, kv);
            let mid = self.alu2(AluOp::Mul, ah, kv);
            let t = self.sh(Shift::Lsl, mid, 16);
            let u = self.sh(Shift::Asr, mid, 16);
            let z = self.movi(0);
            let lo = self.addsub(false, lo, t);
            let hi = self.alu2(AluOp::Adc, u, z);
            Some((lo, hi))
        }
    }

    /// `(a − e) · k` as a 64-bit pair for any words `a`, `e` (their difference may need 33
    /// bits) and a known `k`, from four `MULS` — where `a·k − e·k` from two products would
    /// take eight and a 64-bit subtraction. The halves are differenced first: with
    /// `a = ah·2^16 + al`, `e = eh·2^16 + el` (`al`, `el` unsigned), `Dh = ah − eh` and
    /// `Dl = al − el` lie in `[−65535, 65535]` and `a − e = Dh·2^16 + Dl` exactly. `k` is cut
    /// into signed halves `k = kh·2^16 + kl` with `−2^15 < kl ≤ 2^15` (so `|kh| ≤ 2^15`), and
    /// every partial product is at most `65535·2^15 < 2^31` in magnitude:
    /// `(a − e)·k = Dh·kh·2^32 + (Dh·kl + Dl·kh)·2^16 + Dl·kl`, summed in 64 bits.
    pub(super) fn smull_diff_const(&mut self, a: V, e: V, k: i32) -> (V, V) {
        let (mut kl, mut kh) = (k & 0xffff, k >> 16);
        if kl > 1 << 15 {
            kl -= 1 << 16;
            kh += 1;
        }
        let (al, el) = (self.nv(), self.nv());
        self.push(M::Uxth { d: al, m: a });
        self.push(M::Uxth { d: el, m: e });
        let ah = self.sh(Shift::Asr, a, 16);
        let eh = self.sh(Shift::Asr, e, 16);
        let dl = self.addsub(true, al, el);
        let dh = self.addsub(true, ah, eh);
        let klv = self.movi(kl);
        let khv = self.movi(kh);
        // Each `MULS` but the first overwrites an operand at its last use.
        let p0 = self.alu2(AluOp::Mul, dl, klv);
        let p1 = self.alu2(AluOp::Mul, dh, klv);
        let p2 = self.alu2(AluOp::Mul, dl, khv);
        let p3 = self.alu2(AluOp::Mul, dh, khv);
        let sign = self.sh(Shift::Asr, p0, 31);
        let hi = self.addsub(false, p3, sign);
        self.add_cross_terms((p0, hi), p1, p2)
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
                        let pb = xs.b.saturating_mul(k as u64);
                        // A left rounding shift folded into the constant: `(x·c)·2^e` is
                        // `x·(c·2^e)` where the bound proves the product fits (the shift
                        // would be a plain `LSLS`) and `c·2^e` loads no dearer.
                        if e > 0 && e < 31 && shl_bound(pb, e) < LIM {
                            let lifted = (c as i64) << e;
                            if i32::try_from(lifted).is_ok_and(|l| load_cost(l) <= load_cost(c)) {
                                let cv = self.movi(lifted as i32);
                                return W {
                                    v: self.alu2(AluOp::Mul, xs.v, cv),
                                    b: shl_bound(pb, e),
                                };
                            }
                        }
                        let cv = self.movi(c);
                        W {
                            v: self.alu2(AluOp::Mul, xs.v, cv),
                            b: pb,
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
                // A constant's high half pre-shifted: `Y = yh·2^(32−k)` makes `xh·yh·2^(32−k)`
                // one `MULS` (no `LSLS`) and `floor(xl·yh / 2^(k−16)) = floor(xl·Y / 2^16)`
                // (the same `ASRS`), where both products fit and `Y` loads no dearer.
                //
                // Where `xl·Y` may not fit a signed word but `0 < Y < 2^16` (a positive
                // constant, `k = 31` mostly), it fits an unsigned one (`xl < 2^16`): the
                // `MULS` low word is the exact product, and `LSRS #16` its floor
                // (`unsigned_low`); `|xh·Y| ≤ 2^15·Y < 2^31` still.
                let (lifted, unsigned_low) = match y {
                    Operand::Const(c) if k > 16 && k < 32 && c >> 16 != 0 => {
                        let (yh, y2) = ((c >> 16) as i64, ((c >> 16) as i64) << (32 - k));
                        let hx = ((x.b.min(LIM) >> 16) + 1).min(1 << 15);
                        let cheap =
                            i32::try_from(y2).is_ok_and(|l| load_cost(l) <= load_cost(yh as i32));
                        let signed = 65535 * y2.unsigned_abs() < LIM;
                        let unsigned = y2 > 0 && y2 < 1 << 16;
                        if cheap && hx * y2.unsigned_abs() < LIM && (signed || unsigned) {
                            (Some(y2 as i32), !signed)
                        } else {
                            (None, false)
                        }
                    }
                    _ => (None, false),
                };
                // A constant's zero half contributes nothing: its partial products are 0
                // (`None`), and its register is never loaded.
                let (yh, yl, yb) = match y {
                    Operand::Const(c) => {
                        let half = |this: &mut Self, h: i32| (h != 0).then(|| this.movi(h));
                        (
                            half(self, lifted.unwrap_or(c >> 16)),
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
                // `xl·Y` by 2^16 where `Y` carries the 2^(32−k).
                let s_low = if lifted.is_some() { 16 } else { k - 16 };
                for (a, b, s, op) in [
                    (Some(xh), yl, k - 16, Shift::Asr),
                    (
                        xl,
                        yh,
                        s_low,
                        if unsigned_low { Shift::Lsr } else { Shift::Asr },
                    ),
                ] {
                    let (Some(a), Some(b)) = (a, b) else { continue };
                    let mut t = self.alu2(AluOp::Mul, a, b);
                    if s > 0 {
                        t = self.sh(op, t, s as u8);
                    }
                    parts.push(t);
                }
                if let Some(yh) = yh {
                    let mut hh = self.alu2(AluOp::Mul, xh, yh);
                    if k < 32 && lifted.is_none() {
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
                if let Operand::Const(c) = y {
                    if let Some(w) = self.wide_by_high_half(x, c, fx_ + fy - fr, rb) {
                        return w;
                    }
                }
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
        let e = fr - (fx_ + fc - b - k);
        // A positive constant half lifted by the high part's shift: with
        // `Y = ys·2^(16−k) < 2^16`, `xh·Y` is the shifted high part (no `LSLS`) and
        // `floor(xl·ys / 2^k) = floor(xl·Y / 2^16)`, `xl·Y < 2^32` exact in the `MULS`
        // low word read unsigned (`LSRS #16`); where `Y` loads no dearer and no rounding
        // of the halves follows (that one reads `xl·ys` signed).
        if let (Some(&c), true, 0..) = (self.konst.get(&ys), k < 16, e) {
            let lifted = (c as i64) << (16 - k);
            if c > 0 && lifted < 1 << 16 && load_cost(lifted as i32) <= load_cost(c) {
                let yv = self.movi(lifted as i32);
                let xh = self.sh(Shift::Asr, x.v, 16);
                let xl = self.nv();
                self.push(M::Uxth { d: xl, m: x.v });
                let hh = self.alu2(AluOp::Mul, xh, yv);
                let ll = self.alu2(AluOp::Mul, xl, yv);
                let ll = self.sh(Shift::Lsr, ll, 16);
                let p = self.addsub(false, hh, ll);
                return self.round(
                    W {
                        v: p,
                        b: pb.min(LIM),
                    },
                    e,
                );
            }
        }
        let xh = self.sh(Shift::Asr, x.v, 16);
        let xl = self.nv();
        self.push(M::Uxth { d: xl, m: x.v });
        let mut hh = self.alu2(AluOp::Mul, xh, ys);
        let mut ll = self.alu2(AluOp::Mul, xl, ys);
        if e < 0 {
            // `round(p / 2^s)` with `p = floor(Q / 2^k)` is `round(Q / 2^(k+s))`: one
            // rounding of the partial products ([`Sel::round_halves`]).
            let (hh, ll) = (
                W { v: hh, b: hx * ysb },
                W {
                    v: ll,
                    b: 65535 * ysb,
                },
            );
            let pb = pb.min(LIM);
            let direct = (k < 16) as u32 + (k > 0) as u32 + 1 + Self::rshr_len(pb, -e);
            if let Some(w) = self.round_halves(hh, ll, k - e, direct, (pb >> -e) + 1) {
                return w;
            }
        }
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
            e,
        )
    }

    /// `round(x · c / 2^s)` for a constant `c = ch·2^16` whose low half is zero and a result
    /// that fits 32 bits: `x·c = Q·2^16` with `Q = xh·ch·2^16 + xl·ch`, so the exact 64-bit
    /// product rounded is `round(Q / 2^(s−16))` from two `MULS` ([`Sel::round_halves`])
    /// instead of four and a 64-bit rounding. `None` (nothing emitted) otherwise.
    fn wide_by_high_half(&mut self, x: W, c: i32, s: i32, rb: u64) -> Option<W> {
        let ch = c >> 16;
        if c & 0xffff != 0 || ch == 0 || rb >= LIM || s <= 16 || self.konst.contains_key(&x.v) {
            return None;
        }
        let chb = ch.unsigned_abs() as u64;
        let hh_b = ((x.b.min(LIM) >> 16) + 1) * chb;
        let ll_b = 65535 * chb;
        let m = s - 16;
        // Feasible (every word fits) before anything is emitted.
        let fits = if m <= 16 {
            shl_bound(hh_b, 16 - m) + (ll_b >> m) + 2 < LIM
        } else {
            hh_b + (ll_b >> 16) + 1 < LIM
        };
        if !fits {
            return None;
        }
        let xh = self.sh(Shift::Asr, x.v, 16);
        let xl = self.nv();
        self.push(M::Uxth { d: xl, m: x.v });
        let cv = self.movi(ch);
        let ll = self.alu2(AluOp::Mul, xl, cv);
        let hh = self.alu2(AluOp::Mul, xh, cv);
        let (hh, ll) = (W { v: hh, b: hh_b }, W { v: ll, b: ll_b });
        // (Feasible as checked above; a `None` would leave two dead `MULS` for the DCE.)
        self.round_halves(hh, ll, m, u32::MAX, rb)
    }

    /// `round(Q / 2^m)` (half up) of `Q = hh·2^16 + ll`, the exact 48-bit sum of two
    /// partial products `hh = xh·c`, `ll = xl·c` (`xl` unsigned), where it takes fewer than
    /// `direct` instructions after the `MULS`; `None` (nothing emitted) otherwise, or when
    /// a word might not fit. `rb` bounds the result.
    ///
    /// For `m ≤ 16` it is `hh·2^(16−m) + round(ll / 2^m)` (`hh·2^(16−m)` is a whole
    /// number): `LSLS`, the rounding of `ll`, `ADDS`. For `m > 16` it is
    /// `round(floor(Q/2^16) / 2^(m−16))` (nested floors of divisions by powers of two
    /// compose) with `floor(Q/2^16) = hh + (ll >> 16)`: `ASRS #16`, `ADDS`, the rounding.
    fn round_halves(&mut self, hh: W, ll: W, m: i32, direct: u32, rb: u64) -> Option<W> {
        if m < 1 {
            return None;
        }
        if m <= 16 {
            let hb = shl_bound(hh.b, 16 - m);
            if hb + (ll.b >> m) + 2 >= LIM
                || (m < 16) as u32 + 1 + Self::rshr_len(ll.b, m) >= direct
            {
                return None;
            }
            let h = if m < 16 {
                self.sh(Shift::Lsl, hh.v, (16 - m) as u8)
            } else {
                hh.v
            };
            let l = self.rshr(ll, m);
            let v = self.addsub(false, h, l.v);
            Some(W { v, b: rb })
        } else {
            let qb = hh.b + (ll.b >> 16) + 1;
            if qb >= LIM || 2 + Self::rshr_len(qb, m - 16) >= direct {
                return None;
            }
            let t = self.sh(Shift::Asr, ll.v, 16);
            let q = self.addsub(false, hh.v, t);
            let r = self.rshr(W { v: q, b: qb }, m - 16);
            Some(W {
                v: r.v,
                b: r.b.min(rb),
            })
        }
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
