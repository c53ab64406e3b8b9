//! One IR value's definition as a word ([`Sel::def`]), the words of operands (constants
//! rematerialised, run-time params loaded from the param block) and their magnitude bounds.

use super::*;

impl<'a> Sel<'a> {
    pub(super) fn bound_of(&self, v: Value) -> u64 {
        let fp = self.fp;
        match self.p.values[v.index()].ty {
            Ty::Bool => 1,
            Ty::Mode(m) => self.p.modes[m.index()].variants.len() as u64,
            Ty::Real(_) => {
                let mag = fp.ranges.values[v.index()].mag();
                let f = fp.frac[v.index()];
                let b = (mag * 2f64.powi(f) * (1.0 + 1e-9)).ceil() + 1.0;
                if b.is_finite() && b < LIM as f64 {
                    b as u64
                } else {
                    LIM
                }
            }
        }
    }

    /// Signed bounds `[lo, hi]` on the word of real value `v`: its exact range
    /// ([`Sel::exact_word_range`]) where it has one, else its interval in its format widened
    /// as [`Sel::bound_of`] widens the magnitude, within `±bound_of(v)`.
    pub(super) fn signed_range(&self, v: Value) -> (i64, i64) {
        if let Some((lo, hi)) = self.exact_word_range(v) {
            return (lo as i64, hi as i64);
        }
        let b = self.bound_of(v) as i64;
        let iv = self.fp.ranges.values[v.index()];
        let scale = 2f64.powi(self.fp.frac[v.index()]);
        let margin = 2.0 + 1e-9 * iv.mag() * scale;
        let (lo, hi) = (
            (iv.lo * scale - margin).floor(),
            (iv.hi * scale + margin).ceil(),
        );
        if !(lo.is_finite() && hi.is_finite()) {
            return (-b, b);
        }
        ((lo.max(-(b as f64)) as i64), (hi.min(b as f64) as i64))
    }

    /// The word of an operand value (constants are rematerialised at each use).
    pub(super) fn word(&mut self, v: Value) -> W {
        if let Some(k) = self.fp.param_word_of(v) {
            // A run-time param: the key's word in the param block inside its state (an
            // `LDR` from r7, as cheap as the literal-pool `LDR` of a constant).
            let (lo, hi) = self.fp.param_words[k].raw_range;
            let t = self.load(MemOp::Ldr, Base::State, self.st.params + 4 * k);
            return W {
                v: t,
                b: (lo as i64).unsigned_abs().max((hi as i64).unsigned_abs()),
            };
        }
        match self.p.values[v.index()].op {
            Op::Const(_) | Op::Param(_) => {
                let c = self.fp.consts[v.index()];
                W {
                    v: self.movi(c),
                    b: c.unsigned_abs() as u64,
                }
            }
            Op::BoolConst(t) => W {
                v: self.movi(t as i32),
                b: 1,
            },
            Op::Variant(_, i) => W {
                v: self.movi(i as i32),
                b: i as u64,
            },
            _ => self.val[v.index()].expect("IR value used before its definition"),
        }
    }

    /// Whether `v` is the constant truth value `false` or a mode's first variant (word 0).
    pub(super) fn is_zero_word(&self, v: Value) -> bool {
        matches!(
            self.p.values[v.index()].op,
            Op::BoolConst(false) | Op::Variant(_, 0)
        )
    }

    pub(super) fn is_const(&self, v: Value) -> bool {
        self.p.const_value(v).is_some()
    }

    /// Where product `v` is a 32×16 product whose word is its unrounded sum (`p` in the
    /// format `fx + fy − b − k`, `fxy = fx + fy`) and its one reader converts it to a coarser
    /// format — a store into a state, or a real `select` of which it is an arm: that format.
    /// The product then rounds `p` once into it, which is exactly the reader's conversion
    /// (round half up; the word only gets smaller), and [`Sel::round_halves`] folds that
    /// rounding into the partial products.
    pub(super) fn product_into_store(&self, v: Value, kind: MulKind, fxy: i32) -> Option<i32> {
        let MulKind::Mul32x16 { b, k, .. } = kind else {
            return None;
        };
        let fr = self.fp.frac[v.index()];
        let sf = match (self.sole_store[v.index()], self.select_reader[v.index()]) {
            (Some(i), _) => self.fp.state_frac[i],
            // The select's arm in its store's format where that rounds only once.
            (None, Some(sel)) => match self.select_store_frac[sel.index()] {
                Some(t) if self.fp.frac[sel.index()] == fr => t,
                _ => self.fp.frac[sel.index()],
            },
            (None, None) => return None,
        };
        (fr == fxy - b.min(31) as i32 - k.min(16) as i32 && sf < fr).then_some(sf)
    }

    /// Where `n = −x0` on `x0`'s grid (exact: `x0`'s word is not `i32::MIN`) is read only by
    /// a 32×16 product that cuts the constant `c` to `ys = c >> b`: `(x0, c')` with
    /// `c' >> b = −ys`. The product is `floor(x·ys / 2^k)` with one floor (`fixed::mul_32x16`),
    /// so `(−x0)·ys` and `x0·(−ys)` give the same word, and `−x0`'s `RSBS` is gone (`−ys`
    /// is a 16-bit half: `ys ≠ −2^15`).
    pub(super) fn neg_into_constant(
        &self,
        n: Value,
        c: i32,
        kind: MulKind,
    ) -> Option<(Value, i32)> {
        let MulKind::Mul32x16 {
            cut: crate::fixed::Cut::Second,
            b,
            ..
        } = kind
        else {
            return None;
        };
        let Op::Neg(x0) = self.p.values[n.index()].op else {
            return None;
        };
        let fp = self.fp;
        let x0_bound = self.val[x0.index()].map_or(LIM, |w| w.b);
        if self.readers[n.index()] != 1
            || fp.frac[n.index()] != fp.frac[x0.index()]
            || x0_bound >= LIM
            || fp.param_word_of(x0).is_some()
            || self.is_const(x0)
        {
            return None;
        }
        let b = b.min(31) as u32;
        let ys = c >> b;
        if !(-32767..=32767).contains(&ys) {
            return None;
        }
        let c2 = i32::try_from(-(ys as i64) << b).ok()?;
        Some((x0, c2))
    }

    /// The word of a value's definition.
    pub(super) fn def(&mut self, v: Value) -> Result<W, ThumbError> {
        let (p, fp, st) = (self.p, self.fp, self.st);
        let fr = fp.frac[v.index()];
        let rb = self.bound_of(v);
        let f = |x: &Value| fp.frac[x.index()];
        let real = |x: &Value| matches!(p.values[x.index()].ty, Ty::Real(_));
        let op = p.values[v.index()].op.clone();
        Ok(match op {
            Op::Const(_) | Op::Param(_) | Op::BoolConst(_) | Op::Variant(..) => self.word(v),
            Op::Sensor(s) => {
                let x = self.sensors[s.index()];
                let w = self.convert(x, fp.sensor_frac[s.index()], fr);
                W {
                    v: w.v,
                    b: w.b.min(rb),
                }
            }
            Op::Deriv(s, order) if self.derivs_scaled.contains_key(&(s.index(), order, fr, rb)) => {
                self.derivs_scaled[&(s.index(), order, fr, rb)]
            }
            Op::Deriv(s, 2) if self.d2_parts[s.index()].is_some() => {
                let (d1, e) = self.d2_parts[s.index()].expect("checked");
                let (k, fk) = fp.deriv_gain[1];
                let sh = fr - (fp.sensor_frac[s.index()] + fk);
                let diff = self.smull_diff_const(d1.v, e.v, k);
                self.round64(diff, sh, rb)
            }
            Op::Deriv(s, order) => {
                let d = self.derivs[s.index()][order as usize - 1].ok_or_else(|| {
                    ThumbError::Unsupported(format!("a derivative of order {order}"))
                })?;
                let (k, fk) = fp.deriv_gain[order as usize - 1];
                let e = fr - (fp.sensor_frac[s.index()] + fk);
                let kind = if d.b.saturating_mul(k.unsigned_abs() as u64) < LIM {
                    MulKind::Muls(0, 0)
                } else {
                    MulKind::Wide
                };
                self.mul(d, 0, Operand::Const(k), 0, e, kind, rb)
            }
            Op::State(s) => {
                let x = self.load(MemOp::Ldr, Base::State, st.states + 4 * s.index());
                let (lo, hi) = fp.state_raw_range[s.index()];
                let b = (lo as i64).unsigned_abs().max((hi as i64).unsigned_abs());
                self.convert(W { v: x, b }, fp.state_frac[s.index()], fr)
            }
            Op::Mode(m) => W {
                v: self.load(MemOp::Ldrb, Base::State, st.modes + m.index()),
                b: rb,
            },
            Op::Edge(e) => W {
                v: self.load(MemOp::Ldrb, Base::State, st.edges + e.index()),
                b: 1,
            },
            Op::Neg(x) => {
                let w = self.word(x);
                let n = self.neg(w);
                self.round(n, fr - f(&x))
            }
            Op::Not(x) => {
                let w = self.word(x);
                let n = self.unary(AluOp::Rsb, w.v);
                W {
                    v: self.addi(false, n, 1),
                    b: 1,
                }
            }
            Op::Arith(o, x, y) => match o {
                ArithOp::Add | ArithOp::Sub => {
                    let (a, b) = (self.word(x), self.word(y));
                    self.add(a, f(&x), b, f(&y), fr, o == ArithOp::Sub, rb)
                }
                ArithOp::Mul => {
                    let kind = fp.mul_kind[v.index()].unwrap_or(MulKind::Wide);
                    let fr = match self.product_into_store(v, kind, f(&x) + f(&y)) {
                        Some(sf) => {
                            self.preconverted[v.index()] = true;
                            sf
                        }
                        None => fr,
                    };
                    if self.is_const(y) || self.is_const(x) {
                        // The plan's shifts are in operand order: (variable, constant) here.
                        let (x, y, kind) = if self.is_const(y) {
                            (x, y, kind)
                        } else {
                            (y, x, kind.swapped())
                        };
                        let (x, c) = self
                            .neg_into_constant(x, fp.consts[y.index()], kind)
                            .unwrap_or((x, fp.consts[y.index()]));
                        let a = self.word(x);
                        self.mul(a, f(&x), Operand::Const(c), f(&y), fr, kind, rb)
                    } else {
                        let (a, b) = (self.word(x), self.word(y));
                        self.mul(a, f(&x), Operand::Word(b), f(&y), fr, kind, rb)
                    }
                }
                ArithOp::Div => match fp.recip[v.index()] {
                    Some((r, fr_r)) => {
                        let kind = fp.mul_kind[v.index()].unwrap_or(MulKind::Wide);
                        let a = self.word(x);
                        self.mul(a, f(&x), Operand::Const(r), fr_r, fr, kind, rb)
                    }
                    None => {
                        let (a, b) = (self.word(x), self.word(y));
                        let iv = fp.ranges.values[y.index()];
                        let scale = 2f64.powi(f(&y));
                        let nonzero = iv.lo * scale > 2.0 || iv.hi * scale < -2.0;
                        if !nonzero || rb >= LIM {
                            return Err(ThumbError::Unsupported(
                                "division by a run-time value whose range contains 0 (use the C backend, or clamp the divisor away from 0)"
                                    .into(),
                            ));
                        }
                        // The divisor's planned pre-shift (`fixed::div_shifted`).
                        let sh = fp.div_shift[v.index()].min(31);
                        if sh == 0 {
                            return self.div(a, b, fr - f(&x) + f(&y), rb);
                        }
                        let shifted = (iv.lo * scale / 2f64.powi(sh as i32) > 2.0)
                            || (iv.hi * scale / 2f64.powi(sh as i32) < -2.0);
                        // The quotient by the floored divisor is larger by at most
                        // `2^(b+1) / min |y|` relatively (the planner keeps it below 2^31).
                        let ymin = (iv.lo * scale).abs().min((iv.hi * scale).abs());
                        let grow = (rb as f64 * 2f64.powi(sh as i32 + 1) / ymin).ceil() + 1.0;
                        let rb2 =
                            rb.saturating_add(if grow.is_finite() { grow as u64 } else { LIM });
                        if !shifted || rb2 >= LIM {
                            return Err(ThumbError::Unsupported(
                                "a division whose shifted divisor may be 0 or whose quotient may not fit"
                                    .into(),
                            ));
                        }
                        let bs = self.floor_shr(b, sh as i32);
                        self.div(a, bs, fr - f(&x) + f(&y) - sh as i32, rb2)?
                    }
                },
            },
            Op::Cmp(o @ (CmpOp::Eq | CmpOp::Ne), x, y)
                if !real(&x) && (self.is_zero_word(x) || self.is_zero_word(y)) =>
            {
                // A truth value or mode against 0: `RSBS t, a, #0` sets C exactly when
                // a = 0, so `ADCS t, a` leaves C; `a ≠ 0` is the sign of `-a | a`.
                let a = if self.is_zero_word(y) { x } else { y };
                let a = self.word(a).v;
                let t = self.unary(AluOp::Rsb, a);
                let v = if o == CmpOp::Eq {
                    self.alu2(AluOp::Adc, t, a)
                } else {
                    let t = self.alu2(AluOp::Orr, t, a);
                    self.sh(Shift::Lsr, t, 31)
                };
                W { v, b: 1 }
            }
            Op::Cmp(o, x, y) => match (fp.exact_const(x), fp.exact_const(y)) {
                (_, Some(k)) if real(&x) => {
                    let a = self.word(x);
                    let r = self.signed_range(x);
                    self.cmp_const(o, (a, r), f(&x), k, false)
                }
                (Some(k), _) if real(&y) => {
                    let a = self.word(y);
                    let r = self.signed_range(y);
                    self.cmp_const(o, (a, r), f(&y), k, true)
                }
                _ => {
                    let (a, b) = (self.word(x), self.word(y));
                    self.cmp(o, a, f(&x), b, f(&y))
                }
            },
            Op::And(x, y) | Op::Or(x, y) if self.fused[x.index()] || self.fused[y.index()] => {
                // `d = 0; if !(x op y) goto done; d = 1; done:` with the operands as
                // compare-and-branch chains.
                let d = self.movi(0);
                let done = self.label();
                self.branch_op(v, false, done)?;
                self.push(M::Movi { d, imm: 1 });
                self.push(M::Label(done));
                W { v: d, b: 1 }
            }
            Op::And(x, y) | Op::Or(x, y) => {
                let (a, b) = (self.word(x), self.word(y));
                let op = if matches!(op, Op::And(..)) {
                    AluOp::And
                } else {
                    AluOp::Orr
                };
                W {
                    v: self.alu2(op, a.v, b.v),
                    b: 1,
                }
            }
            Op::Select(c, x, y) if self.arms.branchy[v.index()] => {
                return self.select_branch(v, c, x, y);
            }
            Op::Select(c, x, y) => {
                let cw = self.word(c);
                let (a, b) = if real(&v) {
                    if self.select_store_frac[v.index()].is_some() {
                        self.preconverted[v.index()] = true;
                    }
                    (self.arm_word(v, x), self.arm_word(v, y))
                } else {
                    (self.word(x), self.word(y))
                };
                self.select(cw.v, a, b)
            }
            Op::Call(func, x, y) => {
                let a = self.word(x);
                let fa = f(&x);
                match func {
                    Builtin::Abs => {
                        let neg = self.neg(a);
                        let n = self.round(neg, fr - fa);
                        let pos = self.convert(a, fa, fr);
                        let c = self.sh(Shift::Lsr, a.v, 31);
                        let r = self.select(c, n, pos);
                        W { v: r.v, b: rb }
                    }
                    Builtin::Min | Builtin::Max => {
                        let (b, fb) = match y {
                            Some(y) => (self.word(y), f(&y)),
                            None => (a, fa),
                        };
                        // Against a known 0 (`max(c_dot, 0 m/s)`): the sign mask of the
                        // converted word, `r & ~(r >> 31)` (`r & (r >> 31)` for min). Exact:
                        // the conversion is monotone and keeps 0, so `max(conv(a), 0) =
                        // conv(max(a, 0))`, which the comparison and select compute.
                        let zero = |w: &W| self.konst.get(&w.v) == Some(&0);
                        let other = match (zero(&a), zero(&b)) {
                            (false, true) => Some((a, fa)),
                            (true, false) => Some((b, fb)),
                            _ => None,
                        };
                        if let Some((x, fx)) = other {
                            let r = self.convert(x, fx, fr);
                            let sign = self.sh(Shift::Asr, r.v, 31);
                            let op = if func == Builtin::Max {
                                AluOp::Bic
                            } else {
                                AluOp::And
                            };
                            return Ok(W {
                                v: self.alu2(op, r.v, sign),
                                b: rb,
                            });
                        }
                        let cop = if func == Builtin::Min {
                            CmpOp::Le
                        } else {
                            CmpOp::Ge
                        };
                        self.min_max(cop, (a, fa), (b, fb), fr, rb)
                    }
                    Builtin::Exp => self.exp(a, fa, fr, rb),
                    Builtin::Sqrt => self.sqrt(a, fa, fr, rb),
                }
            }
        })
    }
}
