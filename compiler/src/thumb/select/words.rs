//! Shifts, rounding and saturation of words, and 64-bit `(lo, hi)` pairs: the reductions
//! `tactus_runtime::fixed` defines (round half up, saturate to `i32`), each emitted only where
//! the word bounds do not prove it a no-op; a known word is folded at compile time.

use super::*;

impl<'a> Sel<'a> {
    /// `floor(x / 2^s)`.
    pub(super) fn floor_shr(&mut self, x: W, s: i32) -> W {
        if s <= 0 {
            return x;
        }
        if let Some(&c) = self.konst.get(&x.v) {
            return self.known(c >> s.min(31));
        }
        let s = s.min(31) as u8;
        W {
            v: self.sh(Shift::Asr, x.v, s),
            b: (x.b >> s) + 1,
        }
    }

    /// `floor(x / 2^m + 1/2)` (round half up), `m ≥ 1`.
    pub(super) fn rshr(&mut self, x: W, m: i32) -> W {
        if m >= 32 {
            // |x| < 2^31 ≤ 2^(m-1): rounds to 0.
            return W {
                v: self.movi(0),
                b: 0,
            };
        }
        if let (Some(&c), 1..) = (self.konst.get(&x.v), m) {
            // A known word: the rounding at compile time (exact in i64).
            return self.known((((c as i64 >> (m - 1)) + 1) >> 1) as i32);
        }
        let b = (x.b >> m) + 1;
        let half = 1u64 << (m - 1);
        if m <= 8 && x.b + half < LIM {
            // The half added first where it cannot overflow: `ADDS #2^(m-1); ASRS #m`
            // (`floor((x + 2^(m-1)) / 2^m)`, one instruction fewer than the shifted form).
            let t = self.addi(false, x.v, half as u8);
            return W {
                v: self.sh(Shift::Asr, t, m as u8),
                b,
            };
        }
        if m >= 2 || x.b < LIM - 1 {
            let t = if m >= 2 {
                self.sh(Shift::Asr, x.v, (m - 1) as u8)
            } else {
                x.v
            };
            let t = self.addi(false, t, 1);
            W {
                v: self.sh(Shift::Asr, t, 1),
                b,
            }
        } else {
            // m = 1 at the top of the range: the carry out of ASRS is the half bit.
            let t = self.sh(Shift::Asr, x.v, 1);
            let z = self.movi(0);
            W {
                v: self.alu2(AluOp::Adc, t, z),
                b,
            }
        }
    }

    /// How many instructions [`Sel::rshr`] emits for a word of bound `b` shifted by `m`
    /// (a known word aside): what a sequence that folds a rounding compares against.
    pub(super) fn rshr_len(b: u64, m: i32) -> u32 {
        if m >= 32 {
            1
        } else if m <= 8 && b + (1u64 << (m - 1)) < LIM {
            2
        } else if m >= 2 {
            3
        } else if b < LIM - 1 {
            2
        } else {
            3
        }
    }

    /// `x · 2^e` saturated to i32, `e ≥ 1`.
    pub(super) fn shl_sat(&mut self, x: W, e: i32) -> W {
        let b = shl_bound(x.b, e);
        if b < LIM {
            return W {
                v: self.sh(Shift::Lsl, x.v, e as u8),
                b,
            };
        }
        let done = self.label();
        let start = self.code.len();
        let d;
        if e >= 32 {
            d = self.movi(0);
            self.push(M::CmpI { a: x.v, imm: 0 });
            self.push(M::Bc(Cond::Eq, done));
        } else {
            d = self.sh(Shift::Lsl, x.v, e as u8);
            let back = self.sh(Shift::Asr, d, e as u8);
            self.push(M::Cmp { a: back, b: x.v });
            self.push(M::Bc(Cond::Eq, done));
        }
        self.saturate_into(d, x.v);
        self.push(M::Label(done));
        if e < 32 {
            self.last_shl = Some(ShlSat {
                d,
                x,
                e: e as u8,
                start,
                end: self.code.len(),
            });
        }
        W { v: d, b: LIM }
    }

    /// Where value `v` was just computed by a saturating left shift and its only reader
    /// stores it into a state of its format: [`Sel::fuse_shl_clamp`] with the state's range
    /// (the store then clamps nothing).
    pub(super) fn fuse_store_clamp(&mut self, v: Value, since: usize) {
        let Some(i) = self.sole_store[v.index()] else {
            return;
        };
        if self.fp.frac[v.index()] != self.fp.state_frac[i] {
            return;
        }
        let Some(w) = self.val[v.index()] else {
            return;
        };
        let (lo, hi) = self.fp.state_raw_range[i];
        if let Some(b) = self.fuse_shl_clamp(w.v, since, Some(lo), Some(hi)) {
            self.val[v.index()] = Some(W { v: w.v, b });
            self.store_clamped[v.index()] = true;
        }
    }

    /// Where the code ends with the saturating left shift `d = sat(x · 2^e)`, emitted at or
    /// after `code[since]`, and `d`'s one reader clamps it to `[lo, hi]` (`None`: a side
    /// proven inside): the shift and the clamp become one clamp of `x`, so nothing
    /// saturates. With `L = ⌈lo / 2^e⌉` and `H = ⌊hi / 2^e⌋`, `x < L` gives `x · 2^e < lo`
    /// (a saturated `i32::MIN` too), so `lo`; `x > H` gives `hi` likewise; in between
    /// `x · 2^e` lies in `[lo, hi]` and fits. `d` is redefined as
    /// `clamp(sat(x · 2^e), lo, hi)` exactly; the result is its magnitude bound, or `None`
    /// (nothing changed) when the code does not end so.
    pub(super) fn fuse_shl_clamp(
        &mut self,
        d: V,
        since: usize,
        lo: Option<i32>,
        hi: Option<i32>,
    ) -> Option<u64> {
        let sh = self.last_shl?;
        if sh.d != d || sh.start < since || sh.end != self.code.len() {
            return None;
        }
        self.code.truncate(sh.start);
        self.last_shl = None;
        let x = sh.x;
        let b = x.b.min(i64::MAX as u64) as i64;
        // A side is checked where it is not proven and `x`'s bound reaches past it.
        let lo = lo
            .map(|lo| (lo, -((-(lo as i64)) >> sh.e)))
            .filter(|&(_, l)| -b < l);
        let hi = hi
            .map(|hi| (hi, (hi as i64) >> sh.e))
            .filter(|&(_, h)| b > h);
        let (low, high, done) = (self.label(), self.label(), self.label());
        for (side, cond, to) in [(lo, Cond::Lt, low), (hi, Cond::Gt, high)] {
            let Some((_, k)) = side else { continue };
            if (0..=255).contains(&k) {
                self.push(M::CmpI {
                    a: x.v,
                    imm: k as u8,
                });
            } else {
                let kv = self.movi(k as i32);
                self.push(M::Cmp { a: x.v, b: kv });
            }
            self.push(M::Bc(cond, to));
        }
        self.push(M::Sh {
            op: Shift::Lsl,
            d,
            m: x.v,
            imm: sh.e,
        });
        if lo.is_some() || hi.is_some() {
            self.push(M::B(done));
        }
        if let Some((lo, _)) = lo {
            self.push(M::Label(low));
            self.push(M::Movi { d, imm: lo });
            if hi.is_some() {
                self.push(M::B(done));
            }
        }
        if let Some((hi, _)) = hi {
            self.push(M::Label(high));
            self.push(M::Movi { d, imm: hi });
        }
        self.push(M::Label(done));
        let ends = [lo.map(|s| s.0), hi.map(|s| s.0)];
        let inner = shl_bound(x.b, sh.e as i32);
        Some(
            ends.iter()
                .flatten()
                .map(|&c| (c as i64).unsigned_abs())
                .fold(inner.min(LIM), u64::max),
        )
    }

    /// `d = sign(s) < 0 ? i32::MIN : i32::MAX` (a redefinition of `d`).
    pub(super) fn saturate_into(&mut self, d: V, s: V) {
        let t = self.sh(Shift::Asr, s, 31);
        let t = self.unary(AluOp::Mvn, t);
        let min = self.movi(i32::MIN);
        self.push(M::Alu2 {
            op: AluOp::Eor,
            d,
            a: t,
            m: min,
        });
    }

    /// `x · 2^e` rounded half up and saturated (any `e`).
    pub(super) fn round(&mut self, x: W, e: i32) -> W {
        if let Some(&c) = self.konst.get(&x.v) {
            if e != 0 {
                // The definition itself (`fixed::convert`: round half up, saturate).
                return self.known(tactus_runtime::fixed::convert(c, 0, e).0);
            }
        }
        match e.cmp(&0) {
            Ordering::Equal => x,
            Ordering::Greater => self.shl_sat(x, e),
            Ordering::Less => self.rshr(x, -e),
        }
    }

    pub(super) fn convert(&mut self, x: W, from: i32, to: i32) -> W {
        self.round(x, to - from)
    }

    /// `-x` (exact: bounds are below 2^31, so `x ≠ i32::MIN`... unless unbounded).
    pub(super) fn neg(&mut self, x: W) -> W {
        if let Some(&c) = self.konst.get(&x.v) {
            // A known word: `-c`, saturated as below for i32::MIN.
            return self.known(c.checked_neg().unwrap_or(i32::MAX));
        }
        if x.b < LIM {
            W {
                v: self.unary(AluOp::Rsb, x.v),
                b: x.b,
            }
        } else {
            // -i32::MIN saturates.
            let d = self.unary(AluOp::Rsb, x.v);
            let done = self.label();
            self.push(M::Bc(Cond::Pl, done));
            self.push(M::Cmp { a: d, b: x.v });
            self.push(M::Bc(Cond::Ne, done));
            let m = self.movi(i32::MAX);
            self.push(M::Mov { d, s: m });
            self.push(M::Label(done));
            W { v: d, b: LIM - 1 }
        }
    }

    /// A 64-bit word pair `(lo, hi)` from a 32-bit word.
    pub(super) fn ext(&mut self, x: V) -> (V, V) {
        (x, self.sh(Shift::Asr, x, 31))
    }

    /// `x · 2^k` as 64 bits, `0 ≤ k ≤ 31`.
    pub(super) fn shl64(&mut self, x: V, k: i32) -> (V, V) {
        if k == 0 {
            return self.ext(x);
        }
        let lo = self.sh(Shift::Lsl, x, k as u8);
        let hi = self.sh(Shift::Asr, x, (32 - k) as u8);
        (lo, hi)
    }

    pub(super) fn add64(&mut self, a: (V, V), b: (V, V), sub: bool) -> (V, V) {
        let lo = self.addsub(sub, a.0, b.0);
        let hi = self.alu2(if sub { AluOp::Sbc } else { AluOp::Adc }, a.1, b.1);
        (lo, hi)
    }

    /// Saturates a 64-bit pair to i32.
    pub(super) fn sat64(&mut self, x: (V, V)) -> V {
        let d = self.nv();
        self.push(M::Mov { d, s: x.0 });
        let sign = self.sh(Shift::Asr, x.0, 31);
        self.push(M::Cmp { a: sign, b: x.1 });
        let done = self.label();
        self.push(M::Bc(Cond::Eq, done));
        self.saturate_into(d, x.1);
        self.push(M::Label(done));
        d
    }

    /// `round(x · 2^e)` of a 64-bit pair to a saturated i32; `bound` is the result's
    /// magnitude bound (saturation omitted when below 2^31).
    pub(super) fn round64(&mut self, x: (V, V), e: i32, bound: u64) -> W {
        let fits = bound < LIM;
        if e >= 0 {
            let v = if e == 0 {
                if fits {
                    x.0
                } else {
                    self.sat64(x)
                }
            } else if fits {
                self.sh(Shift::Lsl, x.0, e.min(31) as u8)
            } else {
                // sat(x·2^e) = shl_sat(sat(x), e): a word outside i32 saturates either way.
                let s = self.sat64(x);
                self.shl_sat(W { v: s, b: LIM }, e).v
            };
            return W { v, b: bound };
        }
        let m = -e;
        if m >= 64 {
            return W {
                v: self.movi(0),
                b: 0,
            };
        }
        if fits {
            // Low word of floor(x / 2^m) plus the half bit (the carry out of the last shift).
            let v = if m < 32 {
                let t = self.sh(Shift::Lsl, x.1, (32 - m) as u8);
                let r = self.sh(Shift::Lsr, x.0, m as u8);
                let r = self.alu2(AluOp::Orr, r, t);
                let z = self.movi(0);
                self.alu2(AluOp::Adc, r, z)
            } else if m == 32 {
                let r = self.nv();
                self.push(M::Mov { d: r, s: x.1 });
                let _c = self.sh(Shift::Lsl, x.0, 1);
                let z = self.movi(0);
                self.alu2(AluOp::Adc, r, z)
            } else {
                let r = self.sh(Shift::Asr, x.1, (m - 32) as u8);
                let z = self.movi(0);
                self.alu2(AluOp::Adc, r, z)
            };
            return W { v, b: bound };
        }
        // Full 64-bit rounding shift, then saturation.
        let (lo, hi) = if m < 32 {
            let t = self.sh(Shift::Lsl, x.1, (32 - m) as u8);
            let hi = self.sh(Shift::Asr, x.1, m as u8);
            let lo = self.sh(Shift::Lsr, x.0, m as u8);
            let lo = self.alu2(AluOp::Orr, lo, t);
            let z = self.movi(0);
            let lo = self.alu2(AluOp::Adc, lo, z);
            let hi = self.alu2(AluOp::Adc, hi, z);
            (lo, hi)
        } else if m == 32 {
            let hi = self.sh(Shift::Asr, x.1, 31);
            let lo = self.nv();
            self.push(M::Mov { d: lo, s: x.1 });
            let _c = self.sh(Shift::Lsl, x.0, 1);
            let z = self.movi(0);
            let lo = self.alu2(AluOp::Adc, lo, z);
            let hi = self.alu2(AluOp::Adc, hi, z);
            (lo, hi)
        } else {
            let hi = self.sh(Shift::Asr, x.1, 31);
            let lo = self.sh(Shift::Asr, x.1, (m - 32) as u8);
            let z = self.movi(0);
            let lo = self.alu2(AluOp::Adc, lo, z);
            let hi = self.alu2(AluOp::Adc, hi, z);
            (lo, hi)
        };
        W {
            v: self.sat64((lo, hi)),
            b: bound.min(LIM),
        }
    }
}
