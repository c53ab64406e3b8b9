//! Inlined elementary functions: `exp` and `sqrt` with the bits the fixed-point definitions
//! give.

use super::*;

impl<'a> Sel<'a> {
    /// [`fx::exp`] of the word `x` (format `fx_`) into `fr` fraction bits; `rb` bounds the
    /// result as the range analysis sees it. Straight-line apart from the shortcuts: words
    /// beyond the limits of [`prim::exp_limits`] give 0 or saturate (compared only where
    /// `x`'s bound reaches them); otherwise `k` by one `MULS`, `r` in Q32 by two `MULS`
    /// modulo 2^32, eight Horner steps of a 32×32→64 product's high word (four `MULS` on the
    /// 16-bit halves; `r`'s halves taken once), and the final `P·2^(k + fr − 30)` as a
    /// rounding right shift by the register `30 − fr − k ∈ [0, 32]` (`−1` only where `x`'s
    /// bound reaches it: then `2P`, saturated).
    ///
    /// [`fx::exp`]: tactus_runtime::fixed::exp
    pub(super) fn exp(&mut self, x: W, fx_: i32, fr: i32, rb: u64) -> W {
        use tactus_runtime::fixed as fx;
        let (xlo, xhi) = prim::exp_limits(fx_, fr);
        // The reach of x: [-lo_reach, hi_reach].
        let (lo_reach, hi_reach) = (x.b.min(LIM) as i64, x.b.min(LIM - 1) as i64);
        // The result may exceed the interval's bound by exp's relative error (2^-28).
        let b = if rb >= LIM {
            LIM
        } else {
            (rb + (rb >> 27) + 2).min(LIM)
        };
        if xlo > hi_reach {
            return W {
                v: self.movi(0),
                b: 0,
            };
        }
        if xhi < -lo_reach {
            return W {
                v: self.movi(i32::MAX),
                b,
            };
        }
        let d = self.nv();
        let done = self.label();
        let shortcut = |this: &mut Self, limit: i64, ok: Cond, value: i32| {
            let k = this.movi(limit as i32);
            this.push(M::Cmp { a: x.v, b: k });
            let ok_l = this.label();
            this.push(M::Bc(ok, ok_l));
            this.push(M::Movi { d, imm: value });
            this.push(M::B(done));
            this.push(M::Label(ok_l));
        };
        if xhi < hi_reach {
            shortcut(self, xhi, Cond::Le, i32::MAX);
        }
        if xlo > -lo_reach {
            shortcut(self, xlo, Cond::Ge, 0);
        }
        // Within the limits |k| <= 64, |t| < 2^14.
        let t = if fx_ >= 8 {
            match (fx_ - 8).min(31) {
                0 => x.v,
                s => self.sh(Shift::Asr, x.v, s as u8),
            }
        } else if 8 - fx_ <= 31 {
            self.sh(Shift::Lsl, x.v, (8 - fx_) as u8)
        } else {
            self.movi(0) // only x = 0 is within the limits
        };
        let c = self.movi(fx::EXP_INV_LN2_Q16);
        let tk = self.alu2(AluOp::Mul, t, c);
        let k = self.rshr(W { v: tk, b: LIM - 2 }, 24).v;
        // r = X − k·L − round(k·D / 2^24), modulo 2^32.
        let big_x = if fx_ > 32 {
            Some(self.sh(Shift::Asr, x.v, (fx_ - 32) as u8))
        } else if fx_ == 32 {
            Some(x.v)
        } else if fx_ > 0 {
            Some(self.sh(Shift::Lsl, x.v, (32 - fx_) as u8))
        } else {
            None
        };
        let dl = self.movi(fx::EXP_LN2_LO_Q56);
        let kd = self.alu2(AluOp::Mul, k, dl);
        let corr = self.rshr(W { v: kd, b: LIM - 2 }, 24).v;
        let l = self.movi(fx::EXP_LN2_Q32 as i32);
        let kl = self.alu2(AluOp::Mul, k, l);
        let kl = self.addsub(false, kl, corr);
        let r = match big_x {
            Some(bx) => self.addsub(true, bx, kl),
            None => self.unary(AluOp::Rsb, kl),
        };
        // P = exp(r) in Q30 by Horner.
        let rl = self.nv();
        self.push(M::Uxth { d: rl, m: r });
        let rh = self.sh(Shift::Asr, r, 16);
        let mut p = self.movi(fx::EXP_COEFFS_Q30[8]);
        for n in (0..8).rev() {
            let hi = self.mulhi_halves(p, rl, rh);
            let cn = self.movi(fx::EXP_COEFFS_Q30[n]);
            p = self.addsub(false, hi, cn);
        }
        // P·2^(k + fr − 30) = P / 2^s, s = 30 − fr − k.
        let c = self.movi(30 - fr);
        let s = self.addsub(true, c, k);
        let kmax = fx::exp_k(xhi.min(hi_reach) as i32, fx_);
        let normal = self.label();
        if kmax + fr as i64 >= 31 {
            // s = −1: 2P, saturated (P < 2^31, so 2P as a word is negative when it overflows).
            self.push(M::Bc(Cond::Pl, normal));
            let two = self.sh(Shift::Lsl, p, 1);
            self.push(M::Mov { d, s: two });
            self.push(M::Bc(Cond::Pl, done));
            self.push(M::Movi { d, imm: i32::MAX });
            self.push(M::B(done));
        }
        self.push(M::Label(normal));
        // round(P / 2^s) = ((2P >> s) + 1) >> 1, unsigned: 2P < 2^32.
        let two = self.sh(Shift::Lsl, p, 1);
        let q = self.alu2(AluOp::Lsr, two, s);
        let q = self.addi(false, q, 1);
        let q = self.sh(Shift::Lsr, q, 1);
        self.push(M::Mov { d, s: q });
        self.push(M::Label(done));
        W { v: d, b }
    }

    /// [`fx::sqrt`] of the word `x` (format `fx_`) into `fr` fraction bits: 0 for `x ≤ 0`;
    /// with `M = x·2^e` (`e`, `post` as the definition computes them), the integer root
    /// `s = floor(sqrt(M))` and remainder `M − s²` digit by digit (two radicand bits per
    /// step, unrolled: `ADCS` shifts the next bits in from a feed register, `SUBS` trial-
    /// subtracts `4s + 1`, `ADCS` shifts the root bit in; about 10 cycles a root bit). Then
    /// `floor(2·sqrt(M)) = 2s + (rem > s)`, rounded by `1 + post` bits; for `post = 0` that is
    /// `s + (rem > s)`, and words above the compile-time limit `(2^62 − 2^31) >> e` saturate
    /// (as [`prim::sqrt`]'s `tx_sqrt`). The root has at most 31 bits (`M < 2^62`): only its
    /// last step can see a 33-bit remainder, taken from the carry.
    ///
    /// [`fx::sqrt`]: tactus_runtime::fixed::sqrt
    pub(super) fn sqrt(&mut self, x: W, fx_: i32, fr: i32, rb: u64) -> W {
        let mut e = 2 * fr - fx_;
        let mut post = 0;
        if e < 0 {
            let p = (-e + 1) / 2;
            e += 2 * p;
            post = p;
        }
        let hi_reach = x.b.min(LIM - 1) as i64;
        if hi_reach <= 0 {
            return W {
                v: self.movi(0),
                b: 0,
            };
        }
        let b = rb.min(LIM);
        // Words above xs saturate (post = 0 only).
        let xs: i64 = if post > 0 {
            i64::MAX
        } else if e >= 62 {
            0
        } else {
            (((1u64 << 62) - (1u64 << 31)) >> e) as i64
        };
        let d = self.nv();
        let done = self.label();
        // x <= 0 → 0.
        let pos = self.label();
        self.push(M::CmpI { a: x.v, imm: 0 });
        self.push(M::Bc(Cond::Gt, pos));
        self.push(M::Movi { d, imm: 0 });
        self.push(M::B(done));
        self.push(M::Label(pos));
        if xs < hi_reach {
            if xs == 0 {
                self.push(M::Movi { d, imm: i32::MAX });
                self.push(M::B(done));
                self.push(M::Label(done));
                return W { v: d, b: LIM - 1 };
            }
            let k = self.movi(xs as i32);
            self.push(M::Cmp { a: x.v, b: k });
            let ok = self.label();
            self.push(M::Bc(Cond::Le, ok));
            self.push(M::Movi { d, imm: i32::MAX });
            self.push(M::B(done));
            self.push(M::Label(ok));
        }
        // M = x·2^e < 2^62 (0 < x < 2^31 and x <= xs): `pairs` pairs of bits from the top;
        // the feed register holds M's top 32 bits, top-aligned (x has at most 62 − e bits).
        let bits = (31 + e).min(62);
        let pairs = (bits + 1) / 2;
        let feed = self.nv();
        match 32 - 2 * pairs + e {
            0 => self.push(M::Mov { d: feed, s: x.v }),
            sh => self.push(M::Sh {
                op: Shift::Lsl,
                d: feed,
                m: x.v,
                imm: sh as u8,
            }),
        }
        let rem = self.movi(0);
        let root = self.movi(0);
        let t = self.nv();
        let u = self.nv();
        for j in 1..=pairs {
            // Bits fed so far: 2(j-1); the feed register holds 32 of them.
            let from_feed = 2 * (j - 1) < 32;
            self.push(M::Sh {
                op: Shift::Lsl,
                d: t,
                m: root,
                imm: 2,
            });
            self.push(M::AddSubI {
                sub: false,
                d: t,
                a: t,
                imm: 1,
            });
            if from_feed {
                for _ in 0..2 {
                    self.push(M::Sh {
                        op: Shift::Lsl,
                        d: feed,
                        m: feed,
                        imm: 1,
                    });
                    self.push(M::Alu2 {
                        op: AluOp::Adc,
                        d: rem,
                        a: rem,
                        m: rem,
                    });
                }
            } else {
                self.push(M::Sh {
                    op: Shift::Lsl,
                    d: rem,
                    m: rem,
                    imm: 2,
                });
            }
            let (skip, next) = (self.label(), self.label());
            let force = self.label();
            if j == 31 {
                // rem·4 may have 33 bits: its carry forces the subtraction (the difference
                // fits 32 bits again).
                self.push(M::Bc(Cond::Hs, force));
            }
            // u = rem − t; C (no borrow) = rem >= t: keep u, and shift C into the root.
            self.push(M::AddSub {
                sub: true,
                d: u,
                a: rem,
                b: t,
            });
            self.push(M::Bc(Cond::Lo, skip));
            self.push(M::Mov { d: rem, s: u });
            self.push(M::Label(skip));
            self.push(M::Alu2 {
                op: AluOp::Adc,
                d: root,
                a: root,
                m: root,
            });
            if j == 31 {
                self.push(M::B(next));
                self.push(M::Label(force));
                self.push(M::AddSub {
                    sub: true,
                    d: rem,
                    a: rem,
                    b: t,
                });
                self.push(M::AddSub {
                    sub: false,
                    d: root,
                    a: root,
                    b: root,
                });
                self.push(M::AddSubI {
                    sub: false,
                    d: root,
                    a: root,
                    imm: 1,
                });
            }
            self.push(M::Label(next));
        }
        // c = (rem > s): after `CMP s, rem`, LO.
        if post == 0 {
            self.push(M::Mov { d, s: root });
            self.push(M::Cmp { a: root, b: rem });
            self.push(M::Bc(Cond::Hs, done));
            self.push(M::AddSubI {
                sub: false,
                d,
                a: d,
                imm: 1,
            });
        } else {
            let r2 = self.addsub(false, root, root);
            let c_done = self.label();
            self.push(M::Cmp { a: root, b: rem });
            self.push(M::Bc(Cond::Hs, c_done));
            self.push(M::AddSubI {
                sub: false,
                d: r2,
                a: r2,
                imm: 1,
            });
            self.push(M::Label(c_done));
            let r = self.rshr(W { v: r2, b: 1 << 17 }, 1 + post);
            self.push(M::Mov { d, s: r.v });
        }
        self.push(M::Label(done));
        W { v: d, b }
    }
}
