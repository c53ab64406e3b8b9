//! Run-time divisions ([`tactus_runtime::fixed::div`]): on the RP2040's SIO hardware divider
//! where the divisor fits its digits, else restoring division unrolled.

use super::*;

/// Cycles between the SIO divider's operand write and a valid result read
/// (`isa/src/timing.rs`, the one table).
pub(super) fn timing_divider_latency() -> u32 {
    tactus_isa::timing::DIVIDER_LATENCY
}

impl<'a> Sel<'a> {
    /// [`fx::div`] for a divisor that cannot be 0 and a quotient bounded by `rb < 2^31`:
    /// `trunc(x · 2^k / y)` by restoring division, one quotient bit per step, unrolled
    /// (`LSLS` feeds the next dividend bit into C, `ADCS` shifts it into the remainder,
    /// `SUBS` trial-subtracts, `ADCS` shifts the quotient bit in: 6 cycles a bit, the same on
    /// both paths). Signs are taken off first and put back on the quotient.
    ///
    /// [`fx::div`]: tactus_runtime::fixed::div
    pub(super) fn div(&mut self, x: W, y: W, k: i32, rb: u64) -> Result<W, ThumbError> {
        let nb = (64 - rb.leading_zeros()) as i32; // quotient bits
                                                   // The divisor's bound once scaled for k < 0.
        let d_bound = if k >= 0 { y.b } else { shl_bound(y.b, -k) };
        if (k >= 0 || -k <= 31) && d_bound < LIM {
            let (steps, _) = crate::fixed::division_cycles(nb, crate::fixed::bits_of(d_bound));
            if steps > 0 {
                return Ok(self.sio_div(x, y, k, rb, steps));
            }
        }
        let abs = |this: &mut Self, w: V| -> (V, V) {
            let m = this.sh(Shift::Asr, w, 31);
            let t = this.alu2(AluOp::Eor, w, m);
            (this.addsub(true, t, m), m)
        };
        let (ax, mx) = abs(self, x.v);
        let (ay, my) = abs(self, y.v);
        // Dividend N = |x|·2^k (k ≥ 0), divisor D = |y| (or |y|·2^-k for k < 0).
        let (d, k) = if k >= 0 {
            (ay, k)
        } else if -k <= 31 && shl_bound(y.b, -k) < LIM {
            (self.sh(Shift::Lsl, ay, (-k) as u8), 0)
        } else {
            return Err(ThumbError::Unsupported(
                "a division whose divisor must be scaled beyond 32 bits".into(),
            ));
        };
        // Remainder starts at N >> nb (< D because the quotient is below 2^nb).
        let r = if nb >= k {
            if nb - k == 0 {
                let r = self.nv();
                self.push(M::Mov { d: r, s: ax });
                r
            } else if nb - k >= 32 {
                self.movi(0)
            } else {
                self.sh(Shift::Lsr, ax, (nb - k) as u8)
            }
        } else if k - nb <= 31 {
            self.sh(Shift::Lsl, ax, (k - nb) as u8)
        } else {
            return Err(ThumbError::Unsupported(
                "a division scaled by more than 2^31".into(),
            ));
        };
        // The low nb bits of N, top-aligned: |x| << (k + 32 - nb).
        let sh = k + 32 - nb;
        let feed = if sh >= 32 {
            self.movi(0)
        } else if sh == 0 {
            let f = self.nv();
            self.push(M::Mov { d: f, s: ax });
            f
        } else {
            self.sh(Shift::Lsl, ax, sh as u8)
        };
        let q = self.movi(0);
        let t = self.nv();
        for _ in 0..nb {
            self.push(M::Sh {
                op: Shift::Lsl,
                d: feed,
                m: feed,
                imm: 1,
            });
            self.push(M::Alu2 {
                op: AluOp::Adc,
                d: r,
                a: r,
                m: r,
            });
            self.push(M::AddSub {
                sub: true,
                d: t,
                a: r,
                b: d,
            });
            let skip = self.label();
            self.push(M::Bc(Cond::Lo, skip));
            self.push(M::Mov { d: r, s: t });
            self.push(M::Label(skip));
            self.push(M::Alu2 {
                op: AluOp::Adc,
                d: q,
                a: q,
                m: q,
            });
        }
        // Sign: q = (q ^ m) - m with m = sign(x) ^ sign(y).
        let m = self.alu2(AluOp::Eor, mx, my);
        let t = self.alu2(AluOp::Eor, q, m);
        Ok(W {
            v: self.addsub(true, t, m),
            b: rb,
        })
    }

    /// [`fx::div`] on the RP2040's SIO hardware divider (datasheet 2.3.1.5: unsigned
    /// dividend at `0xd000_0060`, divisor at `0x064`, quotient `0x070` and remainder `0x074`
    /// valid 8 cycles after the last operand write): `trunc(|x|·2^k / |y|)` by long division
    /// in digits of `s = 32 − L` bits for a divisor of `L` bits, `steps` hardware divisions
    /// ([`crate::fixed::sio_division_steps`]). The first divides the top of the dividend
    /// (below `|y|·2^s`, since the quotient is below `2^nb` with `nb ≤ steps·s`); each later
    /// one divides the remainder with the next `s` dividend bits appended, whose quotient is
    /// the next digit. Unsigned throughout; the sign is put back at the end, so the quotient
    /// truncates toward zero as [`fx::div`] does. The divisor is written once: writing the
    /// dividend starts the next division with the divisor register unchanged.
    ///
    /// The divider is per core, and the update runs only from the firmware's sample
    /// interrupt, which does not nest (and from host calls on an idle core): nothing else
    /// uses the divider between our writes and reads, so its state needs no saving
    /// (the pico-sdk saves it only because its interrupts may interrupt a division).
    ///
    /// [`fx::div`]: tactus_runtime::fixed::div
    pub(super) fn sio_div(&mut self, x: W, y: W, k: i32, rb: u64, steps: u32) -> W {
        const SIO_BASE: i32 = 0xd000_0000u32 as i32;
        const UDIVIDEND: u16 = 0x060;
        const UDIVISOR: u16 = 0x064;
        const QUOTIENT: u16 = 0x070;
        const REMAINDER: u16 = 0x074;
        let abs = |this: &mut Self, w: V| -> (V, V) {
            let m = this.sh(Shift::Asr, w, 31);
            let t = this.alu2(AluOp::Eor, w, m);
            (this.addsub(true, t, m), m)
        };
        let (ax, mx) = abs(self, x.v);
        let (ay, my) = abs(self, y.v);
        let (d, d_bound, k) = if k >= 0 {
            (ay, y.b, k)
        } else {
            (self.sh(Shift::Lsl, ay, (-k) as u8), shl_bound(y.b, -k), 0)
        };
        let s = 32 - crate::fixed::bits_of(d_bound);
        let low = (steps as i32 - 1) * s; // dividend bits below the first step's
                                          // First dividend: |x|·2^k >> low.
        let e = k - low;
        let first = if e == 0 {
            ax
        } else if e > 0 {
            self.sh(Shift::Lsl, ax, e.min(31) as u8)
        } else if -e >= 32 {
            self.movi(0)
        } else {
            self.sh(Shift::Lsr, ax, (-e) as u8)
        };
        // The low `low` dividend bits, top-aligned: |x| << (k + 32 − low) (none if ≥ 32).
        let fsh = k + 32 - low;
        let mut feed = if steps > 1 && fsh < 32 {
            Some(if fsh == 0 {
                ax
            } else {
                self.sh(Shift::Lsl, ax, fsh as u8)
            })
        } else {
            None
        };
        let sio = self.movi(SIO_BASE);
        self.store(MemOp::Str, d, Base::V(sio), UDIVISOR as usize);
        self.store(MemOp::Str, first, Base::V(sio), UDIVIDEND as usize);
        // While the divider works (DIVIDER_LATENCY cycles): the next dividend digit from
        // the feed, the previous digits shifted up; NOPs for the rest of the wait. Every
        // instruction here is 1 cycle (spill code the allocator may add only waits longer).
        let wait = timing_divider_latency() as usize;
        let mut digit = None;
        let mut busy = 0;
        // (The feed is shifted on only when a later digit reads it: a dead shift would be
        // removed after selection and shorten the timed wait.)
        let next_digit = |this: &mut Self, feed: &mut Option<V>, busy: &mut usize, last: bool| {
            if let Some(f) = *feed {
                let dg = this.sh(Shift::Lsr, f, (32 - s) as u8);
                *busy += 1;
                if !last {
                    *feed = Some(this.sh(Shift::Lsl, f, s as u8));
                    *busy += 1;
                }
                Some(dg)
            } else {
                None
            }
        };
        if steps > 1 {
            digit = next_digit(self, &mut feed, &mut busy, steps == 2);
        }
        for _ in busy..wait {
            self.push(M::Nop);
        }
        let mut q = self.load(MemOp::Ldr, Base::V(sio), QUOTIENT as usize);
        for step in 1..steps {
            let r = self.load(MemOp::Ldr, Base::V(sio), REMAINDER as usize);
            let r = self.sh(Shift::Lsl, r, s as u8);
            let dv = match digit {
                Some(dg) => self.alu2(AluOp::Orr, r, dg),
                None => r,
            };
            self.store(MemOp::Str, dv, Base::V(sio), UDIVIDEND as usize);
            let qs = self.sh(Shift::Lsl, q, s as u8);
            busy = 1;
            digit = if step + 1 < steps {
                next_digit(self, &mut feed, &mut busy, step + 2 == steps)
            } else {
                None
            };
            for _ in busy..wait {
                self.push(M::Nop);
            }
            let dq = self.load(MemOp::Ldr, Base::V(sio), QUOTIENT as usize);
            q = self.alu2(AluOp::Orr, qs, dq);
        }
        // Sign: q = (q ^ m) - m with m = sign(x) ^ sign(y).
        let m = self.alu2(AluOp::Eor, mx, my);
        let t = self.alu2(AluOp::Eor, q, m);
        W {
            v: self.addsub(true, t, m),
            b: rb,
        }
    }
}
