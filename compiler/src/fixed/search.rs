//! The planner's search by simulation: cheaper product forms are kept where a simulation of
//! the accuracy contract against the f64 reference, on the planner's stimuli
//! ([`super::stimuli`]), holds with half of every tolerance to spare ([`SIMULATION_MARGIN`])
//! and no worse than the analysis' own plan ([`within_base`]). Results are cached per
//! process and on disk ([`super::plan_cache`]).

use super::*;

/// The share of each contract clause the planner's simulation may spend: a cheaper product
/// form is kept only when the built-in stimuli stay within half of every tolerance, so
/// that what the built-in stimuli do not show (other params, other touches) has the other
/// half.
pub const SIMULATION_MARGIN: f64 = 0.5;

/// Whether a plan's check `c` of a run is no worse than `base`, the analysis' plan's check
/// of the same run, which breaks `strict` (the half-tolerance contract both were measured
/// against): clause by clause at most the base's figure plus the clause's `strict` bound —
/// the total force read within the events' time tolerance
/// ([`contract::ContractCheck::max_force_lsb_within_time`]: a switch a sample apart is what
/// broke the base), each force term and output as measured, the event shift and argument
/// ratios plus one tolerance — and no more events lost or added, samples out of range or
/// saturations than the base.
pub fn within_base(
    c: &contract::ContractCheck,
    base: &contract::ContractCheck,
    strict: &contract::Contract,
) -> bool {
    let lsb = c.dac_lsb_n;
    let force =
        c.max_force_lsb_within_time <= base.max_force_lsb_within_time + strict.force.lsb(lsb);
    let terms = strict
        .terms
        .iter()
        .zip(c.term_lsb.iter().zip(&base.term_lsb))
        .all(|((_, b), (x, y))| *x <= *y + b.lsb(lsb));
    let outputs = strict
        .outputs
        .iter()
        .zip(c.output_err.iter().zip(&base.output_err))
        .all(|((_, b), (x, y))| *x <= *y + *b);
    force
        && terms
        && outputs
        && c.unmatched <= base.unmatched
        && c.shift_ratio <= base.shift_ratio + 1.0
        && c.arg_ratio <= base.arg_ratio + 1.0
        && c.state_out_of_range <= base.state_out_of_range
        && c.overflowed <= base.overflowed
}

/// Most contract simulations per round of the planner's search
/// ([`FixedProgram::with_config`]).
pub const MAX_SIMULATIONS: usize = 40;

/// Most passes of the planner's rounds ([`FixedProgram::with_config`]): a second pass tries
/// again, in the plan the first settled in, the forms refused beside others.
pub const SEARCH_PASSES: usize = 2;

/// Programs with more IR values than this are not simulated by the planner (a rubbed bank
/// or a bowed string: a simulation of the built-in stimuli would take minutes).
pub const MAX_SIMULATED_VALUES: usize = 1500;

impl FixedProgram {
    /// The planner's second pass: cheaper product forms than the error analysis could prove,
    /// each kept only when the accuracy contract ([`contract`]) still holds with
    /// [`SIMULATION_MARGIN`] of every clause to spare, simulated against the f64 reference
    /// on every built-in stimulus, full dips of [`SIMULATED_DESCENTS_S`] and
    /// [`SIMULATED_RANDOM_RUNS`] runs of adversarial raw sensor words (where the
    /// analysis proves the force clause for every input, also keeping that proof), with
    /// the params' own values — for a shared program, at the param values of the keys
    /// [`simulated_keys`] picks (physical points: each key's values come from its own fold;
    /// a program with run-time params but no recorded keys also at the far corner of the
    /// intervals). It starts from the analysis' plan. A run on which that plan already breaks
    /// the half-tolerance contract (a contact switch decided by nanometres after a long free
    /// flight: grand88's E4 half dip closes the hammer–key contact with 11 nm to spare in
    /// f64, and every product 64-bit closes it a sample late too) cannot tell plans apart by
    /// holding the contract; there a cheaper plan must be no worse than the analysis' plan
    /// clause by clause, with the force read within the events' time tolerance
    /// ([`contract::ContractCheck::max_force_lsb_within_time`]), plus the search's share of
    /// each clause ([`within_base`]); this holds for every form's round. Four rounds: every
    /// product not yet `MULS` tries its `MULS` plan, every product still high word or 64-bit
    /// its first then its second 32×16 form, every product still 64-bit its high word; the
    /// rounds again while a pass changed the plan (at most [`SEARCH_PASSES`]). Each round tests
    /// groups of products, breadth first (the whole round, then the halves of a failing
    /// group), with at most [`MAX_SIMULATIONS`] simulations a round; a failing simulation
    /// stops at its first broken sample, and the stimulus that failed is tried first next
    /// time. Only keyboard programs (one sensor) of at most [`MAX_SIMULATED_VALUES`] values
    /// are simulated. Results are kept per process and on disk ([`plan_cache`]: the same
    /// program planned again by the same compiler costs nothing), and threads or processes
    /// planning the same program at once wait for one search
    /// ([`plan_cache::searched_once`]).
    pub(super) fn spend_by_simulation(
        &mut self,
        original: &Program,
        planned: &[(usize, MulOperands, bool)],
        config: &PlanConfig,
    ) {
        if original.sensors.len() != 1 || self.program.values.len() > MAX_SIMULATED_VALUES {
            return;
        }
        let key = format!("{config:?}{original:?}");
        let start = self.mul_kind.clone();
        self.mul_kind = plan_cache::searched_once(&key, &start, || {
            self.search_by_simulation(original, planned);
            self.mul_kind.clone()
        });
    }

    /// The search of [`Self::spend_by_simulation`], uncached.
    pub(super) fn search_by_simulation(
        &mut self,
        original: &Program,
        planned: &[(usize, MulOperands, bool)],
    ) {
        let strict = original.contract.scaled(SIMULATION_MARGIN);
        let lsb = report::analyse(self).dac_lsb_n();
        // The params' own values; for a shared program the param values of real keys
        // (`simulated_keys`); with run-time params but no keys also the far corner (each
        // param at the end farther from its own value).
        let ids: Vec<ParamId> = original.runtime_params().collect();
        let keys = simulated_keys(original);
        let mut points: Vec<Vec<f64>> = keys
            .iter()
            .map(|&k| original.runtime_keys[k].clone())
            .filter(|v| v.len() == ids.len())
            .collect();
        if points.is_empty() {
            points.push(Vec::new());
            if !ids.is_empty() {
                points.push(
                    ids.iter()
                        .map(|id| {
                            let d = &original.params[id.index()];
                            let (lo, hi) = d.runtime.unwrap_or((d.value, d.value));
                            if (d.value - lo).abs() > (hi - d.value).abs() {
                                lo
                            } else {
                                hi
                            }
                        })
                        .collect(),
                );
            }
        }
        // The inputs ([`simulated_inputs`]) at every point, recorded once (f64), each
        // independent: on every core, in a fixed order.
        let inputs = simulated_inputs(original, self.sensor_raw_range[0]);
        let this = &*self;
        let np = points.len();
        let mut runs: Vec<contract::ReferenceRun> = workers::map(inputs.len() * np, |j| {
            // Every point lies within the intervals the program was planned for.
            inputs[j / np]
                .1
                .reference(original, this, &points[j % np])
                .ok()
        })
        .into_iter()
        .flatten()
        .collect();
        // The shortest runs first: a failing plan is found sooner.
        runs.sort_by_key(|r| r.len());
        // What the analysis' plan shows on each run, where it breaks the half-tolerance
        // contract (`None` where it holds).
        let base: Vec<Option<contract::ContractCheck>> = workers::map(runs.len(), |i| {
            let c = contract::compare(original, this, &runs[i], lsb, &strict, false).ok()?;
            let broken = !c.violations(&strict, original.sample_rate_hz).is_empty();
            broken.then_some(c)
        });
        let mut order: Vec<usize> = (0..runs.len()).collect();
        // Where the analysis proves the force clause for every input (no integrated state
        // feeds the total), the search keeps it proven: simulation only adds to a proof.
        let proven = {
            let pr = report::analyse(self);
            !pr.total_is_local && pr.total <= original.contract.force.lsb(lsb) * lsb
        };
        let mut holds = |fp: &FixedProgram| -> bool {
            if proven {
                let pr = report::analyse(fp);
                if pr.total_is_local || pr.total > original.contract.force.lsb(lsb) * lsb {
                    return false;
                }
            }
            let fails = |&i: &usize| {
                let (r, b) = (&runs[i], &base[i]);
                // A run the analysis' plan breaks is compared whole (the force within the
                // time tolerance needs every sample).
                let check = contract::compare(original, fp, r, lsb, &strict, b.is_none());
                !match (b, check) {
                    (_, Err(_)) => false,
                    (None, Ok(c)) => c.violations(&strict, original.sample_rate_hz).is_empty(),
                    (Some(b), Ok(c)) => within_base(&c, b, &strict),
                }
            };
            // The run that broke the last refused plan first (it often breaks this one too),
            // then the others on every core ([`workers::find`]); a failing run goes first
            // next time.
            let failed = match order.first() {
                Some(i) if fails(i) => Some(0),
                Some(_) => workers::find(&order[1..], fails).map(|pos| pos + 1),
                None => None,
            };
            if let Some(pos) = failed {
                let i = order.remove(pos);
                order.insert(0, i);
                return false;
            }
            true
        };
        {
            // Round 0: every product not yet `MULS` tries its `MULS` form; rounds 1 and 2:
            // every product still high word or 64-bit its first, then its second 32×16 form
            // (the smaller error first; two run-time operands have two); round 3: every
            // product still 64-bit its high word — the forms `mul_options` lists. Then the
            // rounds again while a pass changed something (at most [`SEARCH_PASSES`]): a
            // product refused beside others may pass in the plan they settled in.
            for _ in 0..SEARCH_PASSES {
                let before = self.mul_kind.clone();
                for round in 0..4 {
                    let candidates: Vec<(usize, MulKind)> = planned
                        .iter()
                        .filter_map(|&(i, _, _)| {
                            let now = self.mul_kind[i];
                            let options = &self.mul_options[i];
                            let option = |f: fn(&MulKind) -> bool, nth: usize| {
                                options.iter().copied().filter(f).nth(nth).map(|k| (i, k))
                            };
                            let above_half = matches!(now, Some(MulKind::High(_) | MulKind::Wide));
                            match round {
                                0 if !matches!(now, Some(MulKind::Muls(..))) => {
                                    option(|k| matches!(k, MulKind::Muls(..)), 0)
                                }
                                1 | 2 if above_half => {
                                    option(|k| matches!(k, MulKind::Mul32x16 { .. }), round - 1)
                                }
                                3 if now == Some(MulKind::Wide) => {
                                    option(|k| matches!(k, MulKind::High(_)), 0)
                                }
                                _ => None,
                            }
                        })
                        .collect();
                    let mut queue: std::collections::VecDeque<&[(usize, MulKind)]> =
                        std::collections::VecDeque::from([&candidates[..]]);
                    let mut done = 0;
                    while let Some(group) = queue.pop_front() {
                        if group.is_empty() || done == MAX_SIMULATIONS {
                            continue;
                        }
                        done += 1;
                        let was: Vec<Option<MulKind>> =
                            group.iter().map(|(i, _)| self.mul_kind[*i]).collect();
                        for &(i, k) in group {
                            self.mul_kind[i] = Some(k);
                        }
                        if !holds(self) {
                            for (&(i, _), w) in group.iter().zip(was) {
                                self.mul_kind[i] = w;
                            }
                            if group.len() > 1 {
                                let (a, b) = group.split_at(group.len() / 2);
                                queue.push_back(a);
                                queue.push_back(b);
                            }
                        }
                    }
                }
                if self.mul_kind == before {
                    break;
                }
            }
        }
    }
}
