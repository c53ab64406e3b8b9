//! The format plan: [`FixedProgram::with_config`] runs the program transformations
//! (reciprocals, constant chains, common values), the range analysis and the format of
//! every value, then spends the precision budget ([`PlanConfig`]) on cheaper products —
//! by error analysis, then by simulating the accuracy contract ([`super::search`]) — and
//! widens every interval by its local error bound. The budget itself is [`super::budget`].

use super::*;

/// The largest local error bound, relative to a value's magnitude, by which
/// [`FixedProgram::widen_by_local_errors`] widens its interval (2^-10: 64 times a 32×16
/// product's cut).
pub const WIDEN_MAX_REL: f64 = 1.0 / 1024.0;

/// Work (candidate products × IR values) up to which the precision budget is spent one
/// product at a time, one error analysis each (every shipped keyboard instrument, the bank
/// and the plucked string: at most 3.6 M). Above it, products are tried in groups
/// ([`MAX_GROUP_ANALYSES`]).
pub const SEQUENTIAL_BUDGET_WORK: usize = 4_000_000;

/// Most error analyses spent on a large program's products, tried in groups.
pub const MAX_GROUP_ANALYSES: usize = 64;

/// Values whose error the budget watches: operands of comparisons, event arguments, outputs.
pub(super) fn watched_values(p: &Program) -> Vec<Value> {
    let mut out: Vec<Value> = p
        .values
        .iter()
        .filter_map(|vd| match vd.op {
            Op::Cmp(_, x, y) => Some([x, y]),
            _ => None,
        })
        .flatten()
        .filter(|v| matches!(p.values[v.index()].ty, Ty::Real(_)))
        .collect();
    fn walk(stmts: &[Stmt], out: &mut Vec<Value>) {
        for s in stmts {
            match s {
                Stmt::Emit(_, args) => out.extend(args.iter().copied()),
                Stmt::Output(_, v) => out.push(*v),
                Stmt::If(_, b) => walk(b, out),
                _ => {}
            }
        }
    }
    walk(&p.body, &mut out);
    out.sort_by_key(|v| v.index());
    out.dedup();
    out
}

impl FixedProgram {
    /// Plans formats for `program` with the default budget ([`PlanConfig::default`]). Never
    /// fails: unbounded values get saturation and a warning.
    pub fn new(program: &Program) -> Self {
        Self::with_config(program, &PlanConfig::default())
    }

    /// Plans formats for `program` under the precision budget `config`.
    pub fn with_config(program: &Program, config: &PlanConfig) -> Self {
        let original = program;
        // Divisions by states that only events set: products with their reciprocals
        // (`recip`), recomputed where the states are assigned.
        let recips = if config.reciprocals {
            recip::reciprocals(program)
        } else {
            recip::Reciprocals {
                program: program.clone(),
                recips: Vec::new(),
                refused: Vec::new(),
            }
        };
        // Products of products by constants: one product by the constants' product (`chains`);
        // each common value once (`common`): the same meaning, fewer products to plan and
        // run; constant factors of sums distributed into their terms (`distribute`).
        let mut shared = distribute::fold_constants(&recips.program);
        // States only events set: the hull of what they are assigned, within their declared
        // ranges (`range::state_hulls`); their words take that hull's format.
        let mut narrowed = vec![None; shared.states.len()];
        let hulls = if config.narrow_states {
            range::state_hulls(&shared)
        } else {
            shared.states.iter().map(|s| s.range).collect()
        };
        for ((st, h), n) in shared.states.iter_mut().zip(hulls).zip(&mut narrowed) {
            if h != st.range {
                *n = Some(st.range);
                st.range = h;
            }
        }
        let program = &shared;
        let ranges = range::analyse(program);
        let n = program.values.len();
        let mut frac = vec![0; n];
        let mut consts = vec![0; n];
        let mut recip = vec![None; n];
        let mut mul_kind = vec![None; n];
        let mut div_shift = vec![0u8; n];
        for (i, vd) in program.values.iter().enumerate() {
            frac[i] = match vd.ty {
                Ty::Real(_) => frac_for(ranges.values[i]),
                Ty::Bool | Ty::Mode(_) => 0,
            };
            match vd.op {
                Op::Const(c) => consts[i] = fx::from_f64(c, frac[i]).0,
                Op::Param(p) => {
                    consts[i] = fx::from_f64(program.params[p.index()].value, frac[i]).0
                }
                _ => {}
            }
        }
        let mut param_slot = vec![None; program.params.len()];
        let mut param_words: Vec<ParamWord> = program
            .runtime_params()
            .enumerate()
            .map(|(k, id)| {
                param_slot[id.index()] = Some(k);
                let (lo, hi) = program.params[id.index()].runtime.unwrap_or((0.0, 0.0));
                let f = frac_for(Interval::new(lo, hi));
                ParamWord {
                    param: id,
                    frac: f,
                    raw_range: (fx::from_f64(lo, f).0, fx::from_f64(hi, f).0),
                }
            })
            .collect();
        // A word has the format of the values reading it (their intervals are the param's).
        for (i, vd) in program.values.iter().enumerate() {
            if let Op::Param(p) = vd.op {
                if let Some(k) = param_slot[p.index()] {
                    let w = &mut param_words[k];
                    let (lo, hi) = program.params[p.index()].runtime.unwrap_or((0.0, 0.0));
                    w.frac = frac[i];
                    w.raw_range = (fx::from_f64(lo, frac[i]).0, fx::from_f64(hi, frac[i]).0);
                }
            }
        }
        let is_const = |v: Value| program.const_value(v).is_some();
        let const_value = |v: Value| program.const_value(v).unwrap_or(f64::NAN);
        // Per multiplication: its operands as planned (format, range, free low bits) and
        // whether the plan's pair is swapped against operand order.
        let mut planned: Vec<(usize, MulOperands, bool)> = Vec::new();
        for (i, vd) in program.values.iter().enumerate() {
            let (x, y, c) = match vd.op {
                Op::Arith(ArithOp::Div, _, y) if !is_const(y) => {
                    if matches!(program.values[y.index()].ty, Ty::Real(_)) {
                        div_shift[i] = plan_div_shift(
                            frac[y.index()],
                            ranges.values[y.index()],
                            frac[i],
                            ranges.values[i],
                            config.div_rel_tolerance,
                        );
                    }
                    continue;
                }
                Op::Arith(ArithOp::Div, x, y) if is_const(y) => {
                    let c = const_value(y);
                    if c == 0.0 {
                        continue;
                    }
                    let (raw, f) = constant(1.0 / c);
                    recip[i] = Some((raw, f));
                    (x, None, Some((raw, f)))
                }
                Op::Arith(ArithOp::Mul, x, y) => {
                    if is_const(y) {
                        (x, None, Some((consts[y.index()], frac[y.index()])))
                    } else if is_const(x) {
                        (y, None, Some((consts[x.index()], frac[x.index()])))
                    } else {
                        (x, Some(y), None)
                    }
                }
                _ => continue,
            };
            let fx_of = |v: Value| (frac[v.index()], ranges.values[v.index()]);
            let (ops, swapped) = match (y, c) {
                (_, Some((raw, fc))) => {
                    let free = raw.trailing_zeros().min(31) as i32;
                    let ops = MulOperands {
                        x: fx_of(x),
                        free_x: 0,
                        y: (fc, Interval::point(tactus_runtime::fixed::to_f64(raw, fc))),
                        free_y: free,
                        constant: true,
                        result: ranges.values[i],
                        fr: frac[i],
                    };
                    // The constant operand is the second one of the planned pair; the shifts
                    // are stored in operand order (x, y), which is what every engine applies.
                    let swapped = matches!(vd.op, Op::Arith(ArithOp::Mul, a, _) if is_const(a));
                    (ops, swapped)
                }
                (Some(y), None) => (
                    MulOperands {
                        x: fx_of(x),
                        free_x: 0,
                        y: fx_of(y),
                        free_y: 0,
                        constant: false,
                        result: ranges.values[i],
                        fr: frac[i],
                    },
                    false,
                ),
                (None, None) => continue,
            };
            mul_kind[i] = Some(ops.plan(swapped, true));
            planned.push((i, ops, swapped));
        }
        let mut mul_options = vec![Vec::new(); n];
        for (i, ops, swapped) in &planned {
            let muls = Some(ops.plan(*swapped, false)).filter(|k| matches!(k, MulKind::Muls(..)));
            let halves = ops.halves(*swapped);
            let high = ops.high().map(|(k, _)| MulKind::High(k));
            mul_options[*i] = muls.into_iter().chain(halves).chain(high).collect();
        }
        let sensor_frac: Vec<i32> = program
            .sensors
            .iter()
            .map(|s| frac_for(Interval::new(s.range.0, s.range.1)))
            .collect();
        let sensor_raw_range = program
            .sensors
            .iter()
            .zip(&sensor_frac)
            .map(|(s, &f)| (fx::from_f64(s.range.0, f).0, fx::from_f64(s.range.1, f).0))
            .collect();
        let state_frac: Vec<i32> = program
            .states
            .iter()
            .map(|s| frac_for(Interval::new(s.range.0, s.range.1)))
            .collect();
        let state_raw_range = program
            .states
            .iter()
            .zip(&state_frac)
            .map(|(s, &f)| (fx::from_f64(s.range.0, f).0, fx::from_f64(s.range.1, f).0))
            .collect();
        let state_init = program
            .states
            .iter()
            .zip(&state_frac)
            .map(|(s, &f)| fx::from_f64(s.init, f).0)
            .collect();
        let r = program.sample_rate_hz / WINDOW as f64;
        let deriv_gain = [constant(r), constant(r * r)];
        let warnings = ranges
            .clamped
            .iter()
            .map(|v| {
                let vd = &program.values[v.index()];
                Diagnostic::warning(
                    "W0101",
                    format!(
                        "no bound for this value: fixed-point saturation inserted at ±{} {}",
                        range::UNBOUNDED_CLAMP,
                        match vd.ty {
                            Ty::Real(d) => d.unit_string(),
                            _ => String::new(),
                        }
                    ),
                    vd.span.clone(),
                )
                .hint("bound it: a division by a range containing 0 or an exp of a wide range has no bound; clamp the operand or narrow the ranges it comes from")
            })
            .collect();
        let publ = published(program, &frac);
        let mut fp = FixedProgram {
            force_frac: publ.force,
            total_frac: publ.total,
            output_frac: publ.output,
            event_frac: publ.event,
            program: program.clone(),
            ranges,
            frac,
            consts,
            recip,
            mul_kind,
            mul_options,
            div_shift: vec![0; n],
            sensor_frac,
            sensor_raw_range,
            state_frac,
            state_raw_range,
            state_init,
            deriv_gain,
            warnings,
            param_slot,
            param_words,
            reciprocals: recips.recips,
            refused_reciprocals: recips.refused,
            narrowed,
        };
        // Products are budgeted against the exact divisions: the divisor shifts' error is
        // charged to the divisions' own tolerance, not handed on to the products.
        fp.spend_precision_budget(&planned, config);
        fp.div_shift = div_shift;
        if config.simulate {
            fp.spend_by_simulation(original, &planned, config);
        }
        fp.widen_by_local_errors();
        // Once the plan (and with it every value's error bound) is final: the flow facts
        // the rewrite rests on hold for the words every fixed engine computes.
        if config.level_edges {
            flow::edges::level_edges(&mut fp);
        }
        fp
    }

    /// Widens every real value's interval by its local error bound
    /// ([`report::local_errors`]), once the plan is final: the interval of the exact result
    /// then also holds the word every fixed engine computes — a cut 32×16 product or a
    /// pre-shifted `MULS` lies up to 2^-15 of its magnitude outside the exact one. Backends
    /// that drop a saturation or a state store's clamp where the interval proves it dead
    /// (the Thumb code) rely on this. Formats are not changed: a widened interval beyond its
    /// format's reach only makes those backends keep the saturation. Values whose bound is
    /// not finite or above [`WIDEN_MAX_REL`] of their magnitude keep their interval (as
    /// before the widening): there the bound is the analysis' looseness over long chains
    /// (a bowed string's divisors would all seem to reach 0), not a form's error.
    pub(super) fn widen_by_local_errors(&mut self) {
        let errors = report::local_errors(self);
        for ((iv, e), vd) in self
            .ranges
            .values
            .iter_mut()
            .zip(errors)
            .zip(&self.program.values)
        {
            let small = e <= WIDEN_MAX_REL * iv.mag();
            if matches!(vd.ty, Ty::Real(_)) && e.is_finite() && e > 0.0 && small {
                *iv = Interval::new(iv.lo - e, iv.hi + e);
            }
        }
    }

    /// Turns 64-bit products into `MULS` products while the error bounds of
    /// [`report::analyse`] stay within the precision budget: the total force and every force
    /// term within [`BUDGET_FORCE_LSB`] DAC LSB (or their bound with exact products, if
    /// larger); every state's one-sample bound within [`BUDGET_STATE_REL`] of its range;
    /// every value that is compared, emitted or output within [`BUDGET_VALUE_REL`] of its
    /// range. Products are tried in program order; each one kept spends part of the budget.
    /// Large programs (over [`SEQUENTIAL_BUDGET_WORK`]) try them in groups instead, with at
    /// most [`MAX_GROUP_ANALYSES`] analyses: whole groups kept, the others left exact.
    pub(super) fn spend_precision_budget(
        &mut self,
        planned: &[(usize, MulOperands, bool)],
        config: &PlanConfig,
    ) {
        let not_muls = |k: Option<MulKind>| !matches!(k, Some(MulKind::Muls(..)));
        if !planned.iter().any(|(i, _, _)| not_muls(self.mul_kind[*i])) {
            return;
        }
        let base = report::analyse(self);
        let watched = watched_values(&self.program);
        let lsb = base.dac_lsb_n();
        // A bound that is not finite proves nothing: such a candidate is never accepted.
        let within_growth = |pr: &report::Precision, growth: f64| -> bool {
            let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
            if !(pr.total.is_finite() && finite(&pr.force) && finite(&pr.write)) {
                return false;
            }
            let force_ok = |now: f64, was: f64| now <= was.max(config.force_lsb * lsb);
            force_ok(pr.total, base.total)
                && pr
                    .force
                    .iter()
                    .zip(&base.force)
                    .all(|(n, w)| force_ok(*n, *w))
                && self.program.states.iter().enumerate().all(|(i, st)| {
                    let mag = st.range.0.abs().max(st.range.1.abs());
                    if base.accumulating[i] || pr.accumulating[i] {
                        growth == f64::INFINITY || pr.write[i] <= growth * base.write[i]
                    } else {
                        pr.state[i].is_finite()
                            && pr.state[i] <= base.state[i].max(config.state_rel * mag)
                    }
                })
                && watched.iter().all(|v| {
                    let mag = self.ranges.values[v.index()].mag();
                    pr.value[v.index()].is_finite()
                        && pr.value[v.index()] <= base.value[v.index()].max(config.value_rel * mag)
                })
        };
        let within = |pr: &report::Precision| within_growth(pr, config.accumulating_growth);
        // A high-word product's floors are a bias, not noise: on an integrated state it adds
        // up sample after sample (three of the piano's hammer-velocity products moved a
        // slow dip's force by 48 DAC LSB with a 2× growth allowed), so it may not grow an
        // integrated state's one-sample bound at all.
        let within_high =
            |pr: &report::Precision| within_growth(pr, config.accumulating_growth.min(1.0 + 1e-9));
        // (product, its MULS plan, its plan within the tolerance to fall back to).
        let candidates: Vec<(usize, MulKind, MulKind)> = planned
            .iter()
            .filter(|(i, _, _)| not_muls(self.mul_kind[*i]))
            .map(|(i, ops, swapped)| {
                let was = self.mul_kind[*i].unwrap_or(MulKind::Wide);
                (*i, ops.plan(*swapped, false), was)
            })
            .filter(|(_, k, _)| matches!(k, MulKind::Muls(..)))
            .collect();
        // The high-word form of each 64-bit product, tried where `MULS` is refused.
        let high: std::collections::HashMap<usize, MulKind> = planned
            .iter()
            .filter_map(|(i, ops, _)| ops.high().map(|(k, _)| (*i, MulKind::High(k))))
            .collect();
        let values = self.program.values.len().max(1);
        if candidates.len().saturating_mul(values) <= SEQUENTIAL_BUDGET_WORK {
            // One analysis per product, in program order.
            for &(i, k, was) in &candidates {
                self.mul_kind[i] = Some(k);
                if !within(&report::analyse(self)) {
                    self.mul_kind[i] = Some(was);
                }
            }
            // Then the 32×16 forms for every product still 64-bit, the smaller error first
            // (its floors and cut are a bias like the high word's: no growth of an
            // integrated state), one analysis each.
            for (i, _, _) in planned {
                if self.mul_kind[*i] != Some(MulKind::Wide) {
                    continue;
                }
                let halves: Vec<MulKind> = self.mul_options[*i]
                    .iter()
                    .copied()
                    .filter(|k| matches!(k, MulKind::Mul32x16 { .. }))
                    .collect();
                for h in halves {
                    self.mul_kind[*i] = Some(h);
                    if within_high(&report::analyse(self)) {
                        break;
                    }
                    self.mul_kind[*i] = Some(MulKind::Wide);
                }
            }
            // Then the high-word form for every product still 64-bit (also those with no
            // `MULS` plan), one analysis each.
            for (i, _, _) in planned {
                if self.mul_kind[*i] != Some(MulKind::Wide) {
                    continue;
                }
                if let Some(&h) = high.get(i) {
                    self.mul_kind[*i] = Some(h);
                    if !within_high(&report::analyse(self)) {
                        self.mul_kind[*i] = Some(MulKind::Wide);
                    }
                }
            }
            return;
        }
        // Large programs: groups of products, breadth first — the whole list, then the
        // halves of each rejected group, level by level in program order, so that large
        // acceptable groups are found before the analyses run out — with at most `tries`
        // analyses. A product
        // not reached stays a 64-bit product (exact, only slower). On a bowed string
        // (19,000 values, 2,946 candidates) one analysis per product took 46 s and kept
        // none of them.
        let tries = (SEQUENTIAL_BUDGET_WORK / values).clamp(1, MAX_GROUP_ANALYSES);
        let mut queue: std::collections::VecDeque<&[(usize, MulKind, MulKind)]> =
            std::collections::VecDeque::from([&candidates[..]]);
        let mut done = 0;
        while let Some(group) = queue.pop_front() {
            if done == tries {
                break;
            }
            done += 1;
            for &(i, k, _) in group {
                self.mul_kind[i] = Some(k);
            }
            if !within(&report::analyse(self)) {
                for &(i, _, was) in group {
                    self.mul_kind[i] = Some(was);
                }
                if group.len() > 1 {
                    let (a, b) = group.split_at(group.len() / 2);
                    queue.push_back(a);
                    queue.push_back(b);
                }
            }
        }
    }
}
