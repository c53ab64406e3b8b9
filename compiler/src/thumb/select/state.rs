//! State, sensor and output access: loads and stores with immediate offsets from the state
//! pointer (r7) or a region base beyond their reach, sensor clamps, the differentiator ring and
//! the published force/output slots.

use super::*;

/// Whether byte offset `off` fits the immediate form of a load/store (imm5, scaled by the
/// access size).
pub(super) fn imm_offset(op: MemOp, off: usize) -> bool {
    let size = op.size() as usize;
    off <= 31 * size && off.is_multiple_of(size)
}

impl<'a> Sel<'a> {
    /// For a word access at `off` bytes into the state struct beyond an immediate offset's
    /// reach: the base register of its 128-byte region and the offset within it (a delay
    /// line's shift then costs `LDR`/`STR` with immediate offsets, one address computation
    /// per 32 words).
    pub(super) fn state_region(&mut self, off: usize) -> (V, u16) {
        let region = off & !127;
        if let Some((r, b)) = self.region_base {
            if r == region {
                return (b, (off - region) as u16);
            }
        }
        let o = self.movi(region as i32);
        let s = self.nv();
        self.push(M::Mov { d: s, s: STATE_V });
        let b = self.addsub(false, s, o);
        self.region_base = Some((region, b));
        (b, (off - region) as u16)
    }

    pub(super) fn load(&mut self, op: MemOp, base: Base, off: usize) -> V {
        let t = self.nv();
        if imm_offset(op, off) {
            self.push(M::Load {
                op,
                t,
                base,
                off: off as u16,
            });
        } else if base == Base::State && op == MemOp::Ldr && off.is_multiple_of(4) {
            let (b, o) = self.state_region(off);
            self.push(M::Load {
                op,
                t,
                base: Base::V(b),
                off: o,
            });
        } else {
            let idx = self.movi(off as i32);
            self.push(M::LoadR { op, t, base, idx });
        }
        t
    }

    pub(super) fn store(&mut self, op: MemOp, t: V, base: Base, off: usize) {
        if imm_offset(op, off) {
            self.push(M::Store {
                op,
                t,
                base,
                off: off as u16,
            });
        } else {
            let addr = match base {
                // `STR Rt, [r7, Rm]` with the offset in a register (a delay line's shift
                // stores far into the state struct every sample).
                Base::State if op == MemOp::Str && off.is_multiple_of(4) => {
                    let (b, o) = self.state_region(off);
                    self.push(M::Store {
                        op,
                        t,
                        base: Base::V(b),
                        off: o,
                    });
                    return;
                }
                Base::State => {
                    let idx = self.movi(off as i32);
                    self.push(M::StoreR { op, t, idx });
                    return;
                }
                // Elsewhere the address is computed (such stores are rare).
                Base::V(b) => {
                    let o = self.movi(off as i32);
                    self.addsub(false, b, o)
                }
            };
            self.push(M::Store {
                op,
                t,
                base: Base::V(addr),
                off: 0,
            });
        }
    }

    /// Clamps `x` (redefined in place) to `[lo, hi]`.
    pub(super) fn clamp(&mut self, x: V, lo: i32, hi: i32) {
        self.clamp_sides(x, Some(lo), Some(hi));
    }

    /// [`Sel::clamp`] on the sides given (`None`: the word is proven inside on that side).
    pub(super) fn clamp_sides(&mut self, x: V, lo: Option<i32>, hi: Option<i32>) {
        if self
            .konst
            .get(&x)
            .is_some_and(|c| lo.is_none_or(|lo| *c >= lo) && hi.is_none_or(|hi| *c <= hi))
        {
            return;
        }
        for (bound, cond) in [(lo, Cond::Ge), (hi, Cond::Le)] {
            let Some(bound) = bound else { continue };
            if (cond == Cond::Ge && bound == i32::MIN) || (cond == Cond::Le && bound == i32::MAX) {
                continue;
            }
            let ok = self.label();
            let k = if (0..=255).contains(&bound) {
                self.push(M::CmpI {
                    a: x,
                    imm: bound as u8,
                });
                None
            } else {
                let k = self.movi(bound);
                self.push(M::Cmp { a: x, b: k });
                Some(k)
            };
            self.push(M::Bc(cond, ok));
            match k {
                Some(k) => self.push(M::Mov { d: x, s: k }),
                None => self.push(M::Movi { d: x, imm: bound }),
            }
            self.push(M::Label(ok));
        }
    }

    /// The differentiator ring of sensor `i` (history slot `h`): prime, advance, store,
    /// and the raw differences `d()`/`d2()` need. The ring's `2N + 1` words are kept twice
    /// (`abi::StateLayout::hist`): the newest reading at byte offset `pos − 4` (its
    /// position byte, counting down; 0 before the first sample) and `pos − 4 + 4·(2N + 1)`,
    /// so the readings `N` and `2N` samples ago are `4N` and `8N` bytes on, without a wrap.
    /// One address `r7 + pos` serves the two stores and the two loads as immediate offsets.
    pub(super) fn history(&mut self, i: usize, h: usize) -> Result<(), ThumbError> {
        let (p, st) = (self.p, self.st);
        let hlen = 2 * WINDOW + 1;
        let s = self.sensors[i];
        let base = st.hist + 8 * hlen * h;
        // q = pos − 4: 1..=4·2N, the new position; 0, the wrap to 2N; negative, the first
        // sample (pos 0 before it), which primes the words the next 2N samples read with
        // this reading and then starts at 2N like a wrap. Above 4·2N (a flipped high bit of
        // the byte): the wrap too, so that no store leaves the ring. Each of the three
        // paths that skip the priming takes 6 cycles (the step `SUBS`, `BLE`, `CMP`, `BGT`,
        // `B`; the wrap from 0 `SUBS`, `BLE`, `BPL`, `MOVS`; from above `SUBS`, `BLE`,
        // `CMP`, `BGT`, `MOVS`): a step taking 5 (`CMP`; `BLE ok`, the rest falling into
        // `BPL wrap`) would make the wrap from above, and so the static bound, 7.
        let pos = self.load(MemOp::Ldrb, Base::State, st.hist_pos + h);
        let q = self.addi(true, pos, 4);
        let (ok, wrap, other) = (self.label(), self.label(), self.label());
        self.push(M::Bc(Cond::Le, other));
        self.push(M::CmpI {
            a: q,
            imm: (4 * (hlen - 1)) as u8,
        });
        self.push(M::Bc(Cond::Gt, wrap));
        self.push(M::B(ok));
        self.push(M::Label(other));
        self.push(M::Bc(Cond::Pl, wrap));
        // (The first call after `init`: a flow fact's block, `fixed::flow::first_sample_exclusions`.)
        self.push(M::Mark(crate::fixed::flow::FIRST_SAMPLE_MARK - h as u32));
        for k in crate::abi::StateLayout::primed_slots() {
            self.store(MemOp::Str, s.v, Base::State, base + 4 * k);
        }
        self.push(M::Label(wrap));
        self.push(M::Movi {
            d: q,
            imm: 4 * hlen as i32,
        });
        self.push(M::Label(ok));
        self.store(MemOp::Strb, q, Base::State, st.hist_pos + h);
        // `r7 + q` is the newest word's address less `base − 4`; or its address, where the
        // ring's far words lie beyond an immediate offset's reach.
        let at = self.addsub(false, q, STATE_V);
        let (at, off) = if base - 4 + 4 * hlen <= 124 {
            (at, (base - 4) as u16)
        } else if base - 4 <= 255 {
            (self.addi(false, at, (base - 4) as u8), 0)
        } else {
            let o = self.movi(base as i32 - 4);
            (self.addsub(false, at, o), 0)
        };
        for copy in [0, 4 * hlen as u16] {
            self.push(M::Store {
                op: MemOp::Str,
                t: s.v,
                base: Base::V(at),
                off: off + copy,
            });
        }
        let span = {
            let (lo, hi) = self.fp.sensor_raw_range[i];
            (hi as i64 - lo as i64).unsigned_abs()
        };
        let ago = |this: &mut Self, back: usize| -> V {
            let w = this.nv();
            this.push(M::Load {
                op: MemOp::Ldr,
                t: w,
                base: Base::V(at),
                off: off + 4 * back as u16,
            });
            w
        };
        let used1 = self.deriv_used(i, 1);
        let used2 = self.deriv_used(i, 2);
        if used1 || used2 {
            if span >= LIM {
                return Err(ThumbError::Unsupported(format!(
                    "d() of sensor `{}`: its raw range spans more than 2^30, so its differences do not fit 32 bits",
                    p.sensors[i].name
                )));
            }
            let n_ago = ago(self, WINDOW);
            let d1 = self.addsub(true, s.v, n_ago);
            if used1 {
                self.derivs[i][0] = Some(W { v: d1, b: span });
            }
            if used2 {
                let n2_ago = ago(self, 2 * WINDOW);
                // x0 - 2 x_N + x_2N = d1 - (x_N - x_2N)
                let e = self.addsub(true, n_ago, n2_ago);
                if 2 * span < LIM {
                    let d2 = self.addsub(true, d1, e);
                    self.derivs[i][1] = Some(W { v: d2, b: 2 * span });
                } else {
                    // d2 needs 33 bits: keep its two differences (k·d2 = k·d1 − k·e).
                    self.d2_parts[i] = Some((W { v: d1, b: span }, W { v: e, b: span }));
                }
            }
        }
        Ok(())
    }

    pub(super) fn deriv_used(&self, s: usize, order: u8) -> bool {
        self.p.values.iter().enumerate().any(|(i, vd)| {
            self.used[i] && matches!(vd.op, Op::Deriv(x, o) if x.index() == s && o == order)
        })
    }

    pub(super) fn publish(&mut self, slot: usize, v: Value) {
        let w = self.word(v);
        if self.direct[slot] {
            self.store(MemOp::Str, w.v, Base::V(self.out_ptr), 4 * slot);
        } else {
            self.store(MemOp::Str, w.v, Base::State, self.st.published + 4 * slot);
        }
    }
}

impl<'a> Sel<'a> {
    /// The exact range `[lo, hi]` of the word of `v` (in its own format) where its
    /// definition bounds it exactly: a sensor or state read (clamped to its raw range on
    /// input and on every write), a constant, and a `select` of such; conversions between
    /// formats round monotonically, so the range converts with its ends.
    /// `None` where only the range analysis (with its rounding margins) bounds it.
    pub(super) fn exact_word_range(&self, v: Value) -> Option<(i32, i32)> {
        use tactus_runtime::fixed::convert;
        let (p, fp) = (self.p, self.fp);
        let fr = fp.frac[v.index()];
        let conv =
            |(lo, hi): (i32, i32), from: i32| (convert(lo, from, fr).0, convert(hi, from, fr).0);
        if fp.param_word_of(v).is_some() {
            return None;
        }
        match p.values[v.index()].op {
            Op::Sensor(s) => Some(conv(
                fp.sensor_raw_range[s.index()],
                fp.sensor_frac[s.index()],
            )),
            Op::State(s) => Some(conv(
                fp.state_raw_range[s.index()],
                fp.state_frac[s.index()],
            )),
            Op::Const(_) | Op::Param(_) => {
                let c = fp.consts[v.index()];
                Some((c, c))
            }
            Op::Select(_, x, y) if matches!(p.values[v.index()].ty, Ty::Real(_)) => {
                let a = conv(self.exact_word_range(x)?, fp.frac[x.index()]);
                let b = conv(self.exact_word_range(y)?, fp.frac[y.index()]);
                Some((a.0.min(b.0), a.1.max(b.1)))
            }
            _ => None,
        }
    }
}
