//! Sums and differences ([`tactus_runtime::fixed::add`]): `ADDS`/`SUBS` with the format shifts
//! where the bounds prove 32 bits enough, else the 64-bit reduction.

use super::*;

impl<'a> Sel<'a> {
    /// `x ± y` into `fr` ([`fx::add`]); `rb` bounds the result.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn add(&mut self, x: W, fx_: i32, y: W, fy: i32, fr: i32, sub: bool, rb: u64) -> W {
        let (ex, ey) = (fr - fx_, fr - fy);
        // Both terms on the result grid or coarser: exact integer shifts.
        // One term on or above the grid: result = coarse·2^e1 ± round(fine·2^e2).
        let (coarse, e1, fine, e2, fine_is_y) = if ex >= ey {
            (x, ex, y, ey, true)
        } else {
            (y, ey, x, ex, false)
        };
        if e1 >= 0 && shl_bound(coarse.b, e1) < LIM {
            let cb = shl_bound(coarse.b, e1);
            let fb = shl_bound(fine.b, e2.max(0)) + 1;
            let fine_fits = e2 < 0 || shl_bound(fine.b, e2) < LIM;
            if fine_fits && cb + (fb >> (-e2).max(0)) + 1 < LIM {
                if sub && fine_is_y && e2 < 0 {
                    if let Some(f) = self.round_negated(fine, -e2) {
                        let c = self.round(coarse, e1);
                        let v = self.addsub(true, c.v, f);
                        return W { v, b: rb.min(LIM) };
                    }
                }
                // The fine term, negated first when it is the subtrahend.
                let fine_signed = if sub && fine_is_y {
                    self.neg(fine)
                } else {
                    fine
                };
                let f = if e2 >= 0 {
                    self.round(fine_signed, e2)
                } else {
                    self.rshr(fine_signed, -e2)
                };
                let c = self.round(coarse, e1);
                let (a, b, s) = if fine_is_y {
                    (c, f, false)
                } else {
                    (f, c, sub)
                };
                // fine_is_y: c + f (f already negated for a subtraction);
                // else the coarse term is y: f - c or f + c.
                let v = self.addsub(s, a.v, b.v);
                return W { v, b: rb.min(LIM) };
            }
        }
        // Both one bit finer than the result: the rounded half of a sum that may not fit.
        if ex == -1 && ey == -1 {
            if let Some(w) = self.halved_sum(x, y, sub, rb) {
                return w;
            }
        }
        // Both finer than the result (or no 32-bit proof): the definition's reduction.
        let g = e2.max(e1.min(-1));
        let sy = (g - e2).min(63);
        let dx = e1 - g;
        if dx > 31 {
            return self.add64_path(x, fx_, y, fy, fr, sub, rb);
        }
        let fine_signed = if sub && fine_is_y {
            self.neg(fine)
        } else {
            fine
        };
        let f = self.floor_shr(fine_signed, sy);
        let cb = shl_bound(coarse.b, dx);
        if cb + f.b < LIM {
            let c = if dx > 0 {
                W {
                    v: self.sh(Shift::Lsl, coarse.v, dx as u8),
                    b: cb,
                }
            } else {
                coarse
            };
            let s = if fine_is_y {
                self.addsub(false, c.v, f.v)
            } else {
                self.addsub(sub, f.v, c.v)
            };
            let r = self.round(W { v: s, b: cb + f.b }, g);
            return W {
                v: r.v,
                b: rb.min(r.b),
            };
        }
        self.add64_path(x, fx_, y, fy, fr, sub, rb)
    }

    /// `−round(−y / 2^m)` (round half up, as [`Sel::rshr`]) without negating `y`, where that
    /// is one `ADDS` and one `ASRS` (`m ≤ 8`, no overflow): `round(−y / 2^m) =
    /// floor((−y + 2^(m−1)) / 2^m) = −floor((y + 2^(m−1) − 1) / 2^m)`. So a difference
    /// `c − y` rounded to a coarser grid is `SUBS c, floor((y + 2^(m−1) − 1) / 2^m)`
    /// instead of `RSBS`, the rounding and `ADDS`. `None` (nothing emitted) otherwise.
    fn round_negated(&mut self, y: W, m: i32) -> Option<V> {
        let half = (1u64 << (m.clamp(1, 8) - 1)) - 1;
        if !(1..=8).contains(&m) || y.b + half >= LIM || self.konst.contains_key(&y.v) {
            return None;
        }
        let t = if half > 0 {
            self.addi(false, y.v, half as u8)
        } else {
            y.v
        };
        Some(self.sh(Shift::Asr, t, m as u8))
    }

    /// `round((a ± b) / 2)` (half up) of two words on one grid whose sum may not fit 32
    /// bits, without the 64-bit sum: with `a = 2p + x` (`x` its low bit),
    /// `floor((a + b + 1) / 2) = p + floor((b + x + 1) / 2)` and
    /// `floor((a − b + 1) / 2) = p + floor((x + 1 − b) / 2)`. `ASRS t, a, #1` leaves `x` in
    /// the carry; `MOVS k, #1` (`#2`) keeps it, and `ADCS k, b` (`SBCS k, b`: `2 − b −
    /// (1 − x)`) adds it; `ASRS #1`, `ADDS`: five instructions where the 64-bit sum and
    /// its rounding take nine. `b` (the subtrahend, or the smaller term) must leave room
    /// for the 2 added; the result `|a ± b| / 2` always fits. `None` (nothing emitted)
    /// otherwise.
    fn halved_sum(&mut self, x: W, y: W, sub: bool, rb: u64) -> Option<W> {
        let (a, b) = if sub || x.b >= y.b { (x, y) } else { (y, x) };
        if b.b + 2 >= LIM || self.konst.contains_key(&a.v) || self.konst.contains_key(&b.v) {
            return None;
        }
        let p = self.sh(Shift::Asr, a.v, 1);
        let k = self.movi(if sub { 2 } else { 1 });
        let op = if sub { AluOp::Sbc } else { AluOp::Adc };
        let t = self.alu2(op, k, b.v);
        let h = self.sh(Shift::Asr, t, 1);
        let v = self.addsub(false, p, h);
        Some(W {
            v,
            b: rb.min(((a.b + b.b) >> 1) + 1).min(LIM),
        })
    }

    /// The sum in 64 bits (both terms extended and shifted to the finer grid, which is at
    /// most 31 bits below the coarser), then rounded.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn add64_path(
        &mut self,
        x: W,
        fx_: i32,
        y: W,
        fy: i32,
        fr: i32,
        sub: bool,
        rb: u64,
    ) -> W {
        let f = fx_.max(fy);
        let (sx, sy) = (f - fx_, f - fy);
        if sx > 31 || sy > 31 {
            // Formats more than 31 bits apart: not reachable from the shipped instruments.
            self.unsupported("a sum of operands whose formats differ by more than 31 bits");
            return W {
                v: self.movi(0),
                b: 0,
            };
        }
        let a = self.shl64(x.v, sx);
        let b = self.shl64(y.v, sy);
        let s = self.add64(a, b, sub);
        self.round64(s, fr - f, rb)
    }
}
