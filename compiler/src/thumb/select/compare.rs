//! Comparisons and branches: conditions as flags, compare-and-branch chains (short-circuit
//! `and`/`or`, `not` by the branch sense), 0/1 words from comparisons, branch-free `select`.
//! Words on different grids are compared exactly ([`tactus_runtime::fixed::cmp`]); a
//! comparison with a constant uses the thresholds of [`crate::cgen::prim`].

use super::*;

/// The condition under which `a OP b` holds after `CMP a, b` (signed).
pub(super) fn cond_of(o: CmpOp) -> Cond {
    match o {
        CmpOp::Eq => Cond::Eq,
        CmpOp::Ne => Cond::Ne,
        CmpOp::Lt => Cond::Lt,
        CmpOp::Le => Cond::Le,
        CmpOp::Gt => Cond::Gt,
        CmpOp::Ge => Cond::Ge,
    }
}

/// Two comparison operands brought to one grid ([`Sel::common_grid`]).
pub(super) enum Grid {
    /// Both fit 32 bits on the finer grid.
    Words(W, W),
    /// They need 64 bits: each word with its left shift.
    Wide((W, i32), (W, i32)),
}

/// How a comparison came out when selected as flags.
pub(super) enum Flags {
    /// `CMP` was emitted; the comparison holds when this condition does.
    Cond(Cond),
    /// The comparison is decided at compile time (a constant beyond the word's range).
    Known(bool),
}

/// The conditions [`Sel::branch`] evaluates as control flow (see `Sel::fused`).
/// `selects`: the conditions of the selects emitted as branches ([`super::arms`]), roots
/// like an `if`'s.
pub(super) fn fused_conditions(p: &Program, used: &[bool], selects: &[Value]) -> Vec<bool> {
    let n = p.values.len();
    let mut uses = vec![0u32; n];
    for (vd, _) in p.values.iter().zip(used).filter(|(_, u)| **u) {
        for x in vd.op.operands() {
            uses[x.index()] += 1;
        }
    }
    let mut conds = Vec::new();
    walk_stmts(&p.body, &mut |s| {
        s.reads().iter().for_each(|v| uses[v.index()] += 1);
        if let Stmt::If(c, _) = s {
            conds.push(*c);
        }
    });
    let mut fused = vec![false; n];
    let fusable = |v: Value, uses: &[u32]| {
        uses[v.index()] == 1
            && matches!(
                p.values[v.index()].op,
                Op::And(..) | Op::Or(..) | Op::Not(_) | Op::Cmp(..)
            )
    };
    // Roots: `if` conditions used once, and the operands (used once) of `and`/`or` values
    // that are kept as words — those are materialised by branches (see `Sel::def`).
    let mut stack: Vec<Value> = conds
        .into_iter()
        .chain(selects.iter().copied())
        .filter(|c| fusable(*c, &uses))
        .collect();
    for (i, vd) in p.values.iter().enumerate() {
        if let Op::And(x, y) | Op::Or(x, y) = vd.op {
            if used[i] && !stack.iter().any(|c| c.index() == i) {
                stack.extend([x, y].into_iter().filter(|x| fusable(*x, &uses)));
            }
        }
    }
    while let Some(v) = stack.pop() {
        fused[v.index()] = true;
        if let Op::And(x, y) | Op::Or(x, y) = p.values[v.index()].op {
            stack.extend([x, y].into_iter().filter(|x| fusable(*x, &uses)));
        } else if let Op::Not(x) = p.values[v.index()].op {
            if fusable(x, &uses) {
                stack.push(x);
            }
        }
    }
    // A mode tested against a variant (`CMP r, #imm`, the mode's byte in a register) by
    // several conditions that are all branched on: tested again at each of them rather
    // than kept as a 0/1 word (2 instructions, then `CMP r, #0` at each use anyway).
    let roots: std::collections::HashSet<Value> = {
        let mut r: std::collections::HashSet<Value> = selects.iter().copied().collect();
        walk_stmts(&p.body, &mut |s| {
            if let Stmt::If(c, _) = s {
                r.insert(*c);
            }
        });
        r
    };
    let mut readers: Vec<Vec<Value>> = vec![Vec::new(); n];
    for (i, vd) in p.values.iter().enumerate() {
        if used[i] {
            for x in vd.op.operands() {
                readers[x.index()].push(Value(i as u32));
            }
        }
    }
    let mut other_reads = vec![0u32; n];
    walk_stmts(&p.body, &mut |s| match s {
        Stmt::If(..) => {}
        _ => s.reads().iter().for_each(|v| other_reads[v.index()] += 1),
    });
    for (i, vd) in p.values.iter().enumerate() {
        let Op::Cmp(CmpOp::Eq | CmpOp::Ne, x, y) = vd.op else {
            continue;
        };
        let mode_test = matches!(
            (&p.values[x.index()].op, &p.values[y.index()].op),
            (Op::Mode(_), Op::Variant(_, k)) | (Op::Variant(_, k), Op::Mode(_)) if *k <= 255
        );
        let v = Value(i as u32);
        if !used[i] || fused[i] || !mode_test || other_reads[i] > 0 {
            continue;
        }
        let branched = readers[i].iter().all(|r| {
            fused[r.index()] && matches!(p.values[r.index()].op, Op::And(..) | Op::Or(..))
        });
        if branched && (uses[i] as usize) <= readers[i].len() + usize::from(roots.contains(&v)) {
            fused[i] = true;
        }
    }
    fused
}

impl<'a> Sel<'a> {
    /// Branches to `target` when the truth value `v` equals `when`; falls through otherwise.
    /// A fused condition becomes compare-and-branch chains (short-circuit `and`/`or`, `not`
    /// by swapping the sense); any other value is tested as its 0/1 word.
    pub(super) fn branch(&mut self, v: Value, when: bool, target: Label) -> Result<(), ThumbError> {
        if !self.fused[v.index()] {
            let w = self.word(v);
            self.push(M::CmpI { a: w.v, imm: 0 });
            self.push(M::Bc(if when { Cond::Ne } else { Cond::Eq }, target));
            return Ok(());
        }
        self.branch_op(v, when, target)
    }

    /// [`Sel::branch`] on the operation of `v` itself (an `and`, `or`, `not` or comparison),
    /// whether or not `v` is fused; its operands follow their own fusion.
    pub(super) fn branch_op(
        &mut self,
        v: Value,
        when: bool,
        target: Label,
    ) -> Result<(), ThumbError> {
        match self.p.values[v.index()].op {
            Op::Not(x) => self.branch(x, !when, target),
            Op::And(x, y) | Op::Or(x, y) => {
                // `and` falls to `target` on the first false operand when testing for false;
                // `or` dually. The other sense needs a local label for the early exit.
                let is_and = matches!(self.p.values[v.index()].op, Op::And(..));
                if when != is_and {
                    self.branch(x, when, target)?;
                    self.branch(y, when, target)
                } else {
                    let out = self.label();
                    self.branch(x, !when, out)?;
                    self.branch(y, when, target)?;
                    self.push(M::Label(out));
                    Ok(())
                }
            }
            Op::Cmp(o, x, y) => match self.cmp_flags(o, x, y) {
                Some(Flags::Cond(c)) => {
                    self.push(M::Bc(if when { c } else { c.invert() }, target));
                    Ok(())
                }
                Some(Flags::Known(holds)) => {
                    if holds == when {
                        self.push(M::B(target));
                    }
                    Ok(())
                }
                None => {
                    let w = self.def(v)?;
                    self.push(M::CmpI { a: w.v, imm: 0 });
                    self.push(M::Bc(if when { Cond::Ne } else { Cond::Eq }, target));
                    Ok(())
                }
            },
            _ => unreachable!("only and/or/not/comparisons are branched on"),
        }
    }

    /// `x OP y` as a `CMP` and the condition under which it holds, when one 32-bit `CMP`
    /// decides it exactly (signed conditions use N, Z and V, so no overflow case is left
    /// out); `None` when it needs the 64-bit or two-threshold forms.
    pub(super) fn cmp_flags(&mut self, o: CmpOp, x: Value, y: Value) -> Option<Flags> {
        let fp = self.fp;
        let real = |v: Value| matches!(self.p.values[v.index()].ty, Ty::Real(_));
        // Compare with a known word: `CMP #imm` when it fits 8 bits.
        let with_word = |this: &mut Self, a: V, t: i32| {
            if (0..=255).contains(&t) {
                this.push(M::CmpI { a, imm: t as u8 });
            } else {
                let k = this.movi(t);
                this.push(M::Cmp { a, b: k });
            }
        };
        if !real(x) || !real(y) {
            // Truth values and modes: small non-negative words.
            let small = |v: Value| match self.p.values[v.index()].op {
                Op::Variant(_, i) => Some(i as i32),
                Op::BoolConst(t) => Some(t as i32),
                _ => None,
            };
            let (a, o, k) = match (small(x), small(y)) {
                (_, Some(k)) => (x, o, k),
                (Some(k), None) => (y, o.mirrored(), k),
                (None, None) => {
                    let (a, b) = (self.word(x), self.word(y));
                    self.push(M::Cmp { a: a.v, b: b.v });
                    return Some(Flags::Cond(cond_of(o)));
                }
            };
            let w = self.word(a);
            with_word(self, w.v, k);
            return Some(Flags::Cond(cond_of(o)));
        }
        let konst = |v: Value| fp.exact_const(v);
        if let (None, Some(c)) | (Some(c), None) = (konst(x), konst(y)) {
            let const_left = konst(x).is_some();
            let (v, o) = if const_left {
                (y, o.mirrored())
            } else {
                (x, o)
            };
            let (ge, gt) = prim::thresholds(fp.frac[v.index()], c);
            let (lo, hi) = (i32::MIN as i64, i32::MAX as i64);
            // x >= t, x < t as flags; a threshold beyond the word range decides alone.
            let at_least = |this: &mut Self, t: i64, holds_if_ge: bool| -> Flags {
                if t <= lo || t > hi {
                    return Flags::Known((t <= lo) == holds_if_ge);
                }
                let w = this.word(v);
                with_word(this, w.v, t as i32);
                Flags::Cond(if holds_if_ge { Cond::Ge } else { Cond::Lt })
            };
            return match o {
                CmpOp::Ge => Some(at_least(self, ge, true)),
                CmpOp::Lt => Some(at_least(self, ge, false)),
                CmpOp::Gt => Some(at_least(self, gt, true)),
                CmpOp::Le => Some(at_least(self, gt, false)),
                CmpOp::Eq | CmpOp::Ne if ge == gt => Some(Flags::Known(o == CmpOp::Ne)),
                CmpOp::Eq | CmpOp::Ne if gt == ge + 1 && ge > lo && ge <= hi => {
                    let w = self.word(v);
                    with_word(self, w.v, ge as i32);
                    Some(Flags::Cond(cond_of(o)))
                }
                _ => None,
            };
        }
        let (fa, fb) = (fp.frac[x.index()], fp.frac[y.index()]);
        let (a, b) = (self.word(x), self.word(y));
        if a.v == b.v && fa == fb {
            return Some(Flags::Known(matches!(o, CmpOp::Eq | CmpOp::Le | CmpOp::Ge)));
        }
        match self.common_grid(a, fa, b, fb) {
            Grid::Words(a, b) => {
                self.push(M::Cmp { a: a.v, b: b.v });
                Some(Flags::Cond(cond_of(o)))
            }
            // Equality of 64-bit words needs the word form (Z is not the 64-bit Z).
            Grid::Wide(..) if matches!(o, CmpOp::Eq | CmpOp::Ne) => None,
            Grid::Wide(a, b) => match self.floor_align(o, a, b) {
                Some((x, y, o2)) => {
                    self.push(M::Cmp { a: x.v, b: y.v });
                    Some(Flags::Cond(cond_of(o2)))
                }
                None => Some(Flags::Cond(self.cmp64_ordered(o, a, b))),
            },
        }
    }

    /// An ordered comparison of `a·2^da` with `b·2^db` (one of the shifts 0) in 32 bits,
    /// the finer word `f` floored to the coarser grid instead of the coarser `c` shifted up
    /// (which would not fit): `f ≥ c·2^d ⟺ ⌊f/2^d⌋ ≥ c` and `f > c·2^d ⟺ f − 1 ≥ c·2^d ⟺
    /// ⌊(f−1)/2^d⌋ ≥ c` (`c·2^d` is a multiple of `2^d`), so `<`, `≤` are their negations;
    /// `⌊f/2^d⌋ = f >> min(d, 31)` for `|f| < 2^31`. Returns the two words and `≥` or `<`;
    /// `None` for `=`/`≠` or a finer word that may be `i32::MIN` (no `f − 1`).
    pub(super) fn floor_align(
        &mut self,
        o: CmpOp,
        a: (W, i32),
        b: (W, i32),
    ) -> Option<(W, W, CmpOp)> {
        let (f, c, d, o) = if a.1 == 0 && b.1 > 0 {
            (a.0, b.0, b.1, o)
        } else if b.1 == 0 && a.1 > 0 {
            (b.0, a.0, a.1, o.mirrored())
        } else {
            return None;
        };
        let (less_one, o2) = match o {
            CmpOp::Ge => (false, CmpOp::Ge),
            CmpOp::Lt => (false, CmpOp::Lt),
            CmpOp::Gt => (true, CmpOp::Ge),
            CmpOp::Le => (true, CmpOp::Lt),
            CmpOp::Eq | CmpOp::Ne => return None,
        };
        if less_one && f.b >= LIM {
            return None;
        }
        let d = d.min(31) as u8;
        if let Some(&k) = self.konst.get(&f.v) {
            // A known word: `⌊(f − 1)/2^d⌋` at compile time (`f ≠ i32::MIN`, checked above).
            let t = self.known((k - i32::from(less_one)) >> d);
            return Some((t, c, o2));
        }
        let t = if less_one {
            self.addi(true, f.v, 1)
        } else {
            f.v
        };
        let t = self.sh(Shift::Asr, t, d);
        Some((
            W {
                v: t,
                b: (f.b >> d) + 1,
            },
            c,
            o2,
        ))
    }

    /// `min(a, b)` (`o` = `≤`) or `max(a, b)` (`o` = `≥`) in format `fr`: `a` where
    /// `a o b` holds (exactly, across the formats), `b` otherwise, each converted to `fr`.
    /// A branch over a copy: `d = first; CMP; B<cond> done; d = second; done:` — at most
    /// 3 cycles beside the comparison and the conversions, against 5–7 for a 0/1 word and
    /// the branch-free [`Sel::select`]. The second operand is converted inside the branch,
    /// where it is the result, so its word is bounded by the result's bound `rb`: a left
    /// shift that would need saturation on its own range needs none there (the clamp of a
    /// wide difference into a narrow, finer state). So that operand goes second.
    pub(super) fn min_max(&mut self, o: CmpOp, a: (W, i32), b: (W, i32), fr: i32, rb: u64) -> W {
        let known = |this: &Self, w: &W| this.konst.contains_key(&w.v);
        // A left shift that its own bound cannot prove in range.
        let saturates = |this: &Self, (w, f): (W, i32)| {
            fr > f && !known(this, &w) && shl_bound(w.b, fr - f) >= LIM
        };
        let swap = saturates(self, a) && !saturates(self, b);
        let ((first, ff), (second, fs)) = if swap { (b, a) } else { (a, b) };
        let cf = self.convert(first, ff, fr);
        let d = self.nv();
        match self.konst.get(&cf.v) {
            Some(&imm) => self.push(M::Movi { d, imm }),
            None => self.push(M::Mov { d, s: cf.v }),
        }
        let keep_first = match self.cmp_words_flags(o, a, b) {
            Flags::Known(holds) => Some(holds != swap),
            Flags::Cond(c) => {
                let done = self.label();
                self.push(M::Bc(if swap { c.invert() } else { c }, done));
                let sb = if fr > fs {
                    second.b.min(rb.checked_shr((fr - fs) as u32).unwrap_or(0))
                } else {
                    second.b
                };
                let cs = self.convert(W { v: second.v, b: sb }, fs, fr);
                match self.konst.get(&cs.v) {
                    Some(&imm) => self.push(M::Movi { d, imm }),
                    None => self.push(M::Mov { d, s: cs.v }),
                }
                self.push(M::Label(done));
                None
            }
        };
        match keep_first {
            Some(true) | None => W { v: d, b: rb },
            Some(false) => {
                let cs = self.convert(second, fs, fr);
                W { v: cs.v, b: rb }
            }
        }
    }

    /// `a OP b` for words of formats `a.1`, `b.1` as flags (an exact comparison, as
    /// [`Sel::cmp`]); ordered comparisons only.
    fn cmp_words_flags(&mut self, o: CmpOp, a: (W, i32), b: (W, i32)) -> Flags {
        if a.0.v == b.0.v && a.1 == b.1 {
            return Flags::Known(matches!(o, CmpOp::Eq | CmpOp::Le | CmpOp::Ge));
        }
        match self.common_grid(a.0, a.1, b.0, b.1) {
            Grid::Words(x, y) => {
                // A known 0–255 on either side: `CMP #imm` (mirrored on the left).
                let small = |this: &Self, w: &W| {
                    this.konst
                        .get(&w.v)
                        .copied()
                        .filter(|k| (0..=255).contains(k))
                };
                if let Some(k) = small(self, &y) {
                    self.push(M::CmpI {
                        a: x.v,
                        imm: k as u8,
                    });
                    Flags::Cond(cond_of(o))
                } else if let Some(k) = small(self, &x) {
                    self.push(M::CmpI {
                        a: y.v,
                        imm: k as u8,
                    });
                    Flags::Cond(cond_of(o.mirrored()))
                } else {
                    self.push(M::Cmp { a: x.v, b: y.v });
                    Flags::Cond(cond_of(o))
                }
            }
            Grid::Wide(x, y) => match self.floor_align(o, x, y) {
                Some((x, y, o2)) => {
                    self.push(M::Cmp { a: x.v, b: y.v });
                    Flags::Cond(cond_of(o2))
                }
                None => Flags::Cond(self.cmp64_ordered(o, x, y)),
            },
        }
    }

    /// `c ? a : b` for a 0/1 word `c`, branch-free: `b ^ ((a ^ b) & -c)`.
    pub(super) fn select(&mut self, c: V, a: W, b: W) -> W {
        let m = match self.masks.get(&c) {
            Some(&m) => m,
            None => self.unary(AluOp::Rsb, c),
        };
        // One side a known 0: `a & -c` or `b & ~(-c)` (`BICS`).
        let b_zero = self.konst.get(&b.v) == Some(&0);
        if b_zero || self.konst.get(&a.v) == Some(&0) {
            let (op, keep) = if b_zero {
                (AluOp::And, a)
            } else {
                (AluOp::Bic, b)
            };
            return W {
                v: self.alu2(op, keep.v, m),
                b: keep.b,
            };
        }
        // Two known words: their `EOR` is known too (one literal instead of two).
        let t = match (self.konst.get(&a.v), self.konst.get(&b.v)) {
            (Some(&ka), Some(&kb)) => self.movi(ka ^ kb),
            _ => self.alu2(AluOp::Eor, a.v, b.v),
        };
        let t = self.alu2(AluOp::And, t, m);
        W {
            v: self.alu2(AluOp::Eor, t, b.v),
            b: a.b.max(b.b),
        }
    }

    /// A 0/1 word from the flags of `CMP a, b` (a diamond).
    pub(super) fn set_flag(&mut self, cond: Cond) -> V {
        let d = self.nv();
        let (yes, done) = (self.label(), self.label());
        self.push(M::Bc(cond, yes));
        self.push(M::Movi { d, imm: 0 });
        self.push(M::B(done));
        self.push(M::Label(yes));
        self.push(M::Movi { d, imm: 1 });
        self.push(M::Label(done));
        d
    }

    /// `a OP b` of two 32-bit words on the same grid.
    pub(super) fn cmp32(&mut self, o: CmpOp, a: W, b: W) -> W {
        // `a − b`, zero exactly when they are equal: a known 0–7 on either side is the
        // immediate of `SUBS` (no `MOVS` of it), and 0 no subtraction at all.
        let differ = |this: &mut Self| {
            let (x, k) = match (this.konst.get(&a.v), this.konst.get(&b.v)) {
                (_, Some(&k)) => (a.v, k),
                (Some(&k), None) => (b.v, k),
                (None, None) => return this.addsub(true, a.v, b.v),
            };
            match k {
                0 => x,
                1..=7 => this.addi(true, x, k as u8),
                _ => this.addsub(true, a.v, b.v),
            }
        };
        let v = match o {
            CmpOp::Eq => {
                let d = differ(self);
                let n = self.unary(AluOp::Rsb, d);
                self.alu2(AluOp::Adc, d, n)
            }
            CmpOp::Ne => {
                let d = differ(self);
                let n = self.unary(AluOp::Rsb, d);
                let t = self.alu2(AluOp::Orr, n, d);
                self.sh(Shift::Lsr, t, 31)
            }
            _ if a.b + b.b < LIM => {
                // No overflow: the sign of the difference decides.
                let (x, y, invert) = match o {
                    CmpOp::Lt => (a, b, false),
                    CmpOp::Gt => (b, a, false),
                    CmpOp::Ge => (a, b, true),
                    _ => (b, a, true), // Le: !(b < a)
                };
                // A known small `y` is the immediate of `SUBS` (no `MOVS` of it), and 0 is
                // no subtraction at all.
                let d = match self.konst.get(&y.v) {
                    Some(0) => x.v,
                    Some(&k) if (1..=255).contains(&k) => self.addi(true, x.v, k as u8),
                    _ => self.addsub(true, x.v, y.v),
                };
                let d = if invert { self.unary(AluOp::Mvn, d) } else { d };
                self.sh(Shift::Lsr, d, 31)
            }
            _ => {
                self.push(M::Cmp { a: a.v, b: b.v });
                self.set_flag(cond_of(o))
            }
        };
        W { v, b: 1 }
    }

    /// Two words of formats `fa`, `fb` on the finer grid, for an exact comparison: as 32-bit
    /// words when the coarser one shifted left provably fits, else with their left shifts
    /// for [`Sel::scaled64`].
    pub(super) fn common_grid(&mut self, a: W, fa: i32, b: W, fb: i32) -> Grid {
        let (d_a, d_b) = match fa.cmp(&fb) {
            Ordering::Equal => (0, 0),
            Ordering::Greater => (0, fa - fb),
            Ordering::Less => (fb - fa, 0),
        };
        let fits = |w: W, d: i32| d <= 31 && shl_bound(w.b, d) < LIM;
        if !(fits(a, d_a) && fits(b, d_b)) {
            return Grid::Wide((a, d_a), (b, d_b));
        }
        let mut up = |w: W, d: i32| {
            if let (Some(&k), 1..) = (self.konst.get(&w.v), d) {
                // A known word shifted at compile time (it fits: checked above).
                self.known(k << d)
            } else if d > 0 {
                W {
                    v: self.sh(Shift::Lsl, w.v, d as u8),
                    b: shl_bound(w.b, d),
                }
            } else {
                w
            }
        };
        let a = up(a, d_a);
        Grid::Words(a, up(b, d_b))
    }

    /// An ordered comparison (`<`, `<=`, `>`, `>=`) of two scaled words in 64 bits:
    /// `SUBS`/`SBCS` of `x − y` (or `y − x`) leave N and V of the 64-bit difference; returns
    /// the condition under which the comparison holds.
    pub(super) fn cmp64_ordered(&mut self, o: CmpOp, a: (W, i32), b: (W, i32)) -> Cond {
        let x = self.scaled64(a.0, a.1);
        let y = self.scaled64(b.0, b.1);
        let (p, q, cond) = match o {
            CmpOp::Lt => (x, y, Cond::Lt),
            CmpOp::Ge => (x, y, Cond::Ge),
            CmpOp::Gt => (y, x, Cond::Lt),
            _ => (y, x, Cond::Ge),
        };
        let _ = self.add64(p, q, true);
        cond
    }

    /// `w · 2^d` as a 64-bit (lo, hi) pair for a comparison. When the shift is 32 or more
    /// only the sign of the scaled word matters (the other word is below 2^31): it becomes
    /// `sign(w) · 2^32`, as the definition's reduction does.
    pub(super) fn scaled64(&mut self, w: W, d: i32) -> (V, V) {
        if d <= 31 {
            self.shl64(w.v, d)
        } else {
            let s = self.sh(Shift::Asr, w.v, 31);
            let pos = self.unary(AluOp::Rsb, w.v);
            let pos = self.sh(Shift::Lsr, pos, 31); // 1 when w > 0
            let sign = self.alu2(AluOp::Orr, s, pos); // -1, 0 or 1
            let lo = self.movi(0);
            (lo, sign)
        }
    }

    /// [`fx::cmp`]: exact comparison of words in different formats.
    pub(super) fn cmp(&mut self, o: CmpOp, a: W, fa: i32, b: W, fb: i32) -> W {
        if a.v == b.v && fa == fb {
            let holds = matches!(o, CmpOp::Eq | CmpOp::Le | CmpOp::Ge);
            return W {
                v: self.movi(holds as i32),
                b: 1,
            };
        }
        let (a, b) = match self.common_grid(a, fa, b, fb) {
            Grid::Words(a, b) => return self.cmp32(o, a, b),
            Grid::Wide(a, b) => (a, b),
        };
        let v = match o {
            CmpOp::Eq | CmpOp::Ne => {
                let x = self.scaled64(a.0, a.1);
                let y = self.scaled64(b.0, b.1);
                let l = self.alu2(AluOp::Eor, x.0, y.0);
                let h = self.alu2(AluOp::Eor, x.1, y.1);
                let t = self.alu2(AluOp::Orr, l, h);
                let n = self.unary(AluOp::Rsb, t);
                if o == CmpOp::Eq {
                    self.alu2(AluOp::Adc, t, n)
                } else {
                    let t = self.alu2(AluOp::Orr, n, t);
                    self.sh(Shift::Lsr, t, 31)
                }
            }
            _ => {
                if let Some((x, y, o2)) = self.floor_align(o, a, b) {
                    return self.cmp32(o2, x, y);
                }
                let cond = self.cmp64_ordered(o, a, b);
                self.set_flag(cond)
            }
        };
        W { v, b: 1 }
    }

    /// [`fx::cmp_const`]: `x OP c` (or `c OP x`) as thresholds on the word grid. `x` comes
    /// with signed bounds on its word ([`Sel::signed_range`]): where `x − t` cannot
    /// overflow, `x < t` is the sign of that difference (branch-free) even when the
    /// magnitudes of `x` and `t` together reach 2^31.
    pub(super) fn cmp_const(
        &mut self,
        o: CmpOp,
        (x, (xlo, xhi)): (W, (i64, i64)),
        fx_: i32,
        c: f64,
        const_left: bool,
    ) -> W {
        let (ge, gt) = prim::thresholds(fx_, c);
        let o = if const_left { o.mirrored() } else { o };
        let (lo, hi) = (i32::MIN as i64, i32::MAX as i64);
        // x >= t as a 0/1 word (constant outside the word range).
        let at_least = |this: &mut Self, t: i64, neg: bool| -> W {
            if t <= lo || t > hi {
                return W {
                    v: this.movi(((t <= lo) != neg) as i32),
                    b: 1,
                };
            }
            let fits = |d: i64| (i32::MIN as i64..=i32::MAX as i64).contains(&d);
            if x.b + t.unsigned_abs() >= LIM && fits(xlo - t) && fits(xhi - t) {
                // `x − t` fits although the magnitudes do not prove it: its sign decides.
                let d = if (0..=255).contains(&t) {
                    this.addi(true, x.v, t as u8)
                } else {
                    let k = this.movi(t as i32);
                    this.addsub(true, x.v, k)
                };
                let d = if neg { d } else { this.unary(AluOp::Mvn, d) };
                return W {
                    v: this.sh(Shift::Lsr, d, 31),
                    b: 1,
                };
            }
            let t = t as i32;
            let k = W {
                v: this.movi(t),
                b: t.unsigned_abs() as u64,
            };
            this.cmp32(if neg { CmpOp::Lt } else { CmpOp::Ge }, x, k)
        };
        match o {
            CmpOp::Ge => at_least(self, ge, false),
            CmpOp::Lt => at_least(self, ge, true),
            CmpOp::Gt => at_least(self, gt, false),
            CmpOp::Le => at_least(self, gt, true),
            CmpOp::Eq | CmpOp::Ne => {
                if gt == ge + 1 && ge > lo && ge <= hi {
                    let k = W {
                        v: self.movi(ge as i32),
                        b: (ge as i32).unsigned_abs() as u64,
                    };
                    return self.cmp32(o, x, k);
                }
                let a = at_least(self, ge, false);
                let b = at_least(self, gt, true);
                let e = self.alu2(AluOp::And, a.v, b.v);
                let v = if o == CmpOp::Ne {
                    let n = self.unary(AluOp::Rsb, e);
                    self.addi(false, n, 1)
                } else {
                    e
                };
                W { v, b: 1 }
            }
        }
    }
}
