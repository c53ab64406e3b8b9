//! The contract's second reading of a run: the fixed run against the f64 reference re-timed
//! to its switches ([`super::ContractCheck::retimed`]).
//!
//! The f64 reference is itself a sampled simulation of a hybrid system: it decides each
//! switch at a sample, and the continuous-time switch lies somewhere in the sample period
//! before it. A fixed-point run whose hammer is a few ppm behind after a long free flight
//! closes the same contact a sample later — a switch time within the contract's switch
//! tolerance — and what follows is the exact consequence of that timing: the hammer has
//! missed a sample of contact deceleration, and keeps the speed it did not lose. Read as a
//! time shift of the recorded run (the switch clause of [`super::compare`]) that is an
//! error; it is not one. So where the recorded reading breaks after the runs fell into
//! different discrete states, the contract asks the f64 semantics what *it* does with the
//! fixed run's timing: its interpreter is stepped beside the fixed run and, at each sample
//! where its own branch decisions differ from the fixed run's, the sample is run again with
//! the fixed run's — for at most the switch tolerance at a time (a disagreement longer than
//! that is a switch lost or added, as in the recorded reading), and only where the f64
//! semantics itself takes the fixed run's decision within the switch tolerance of that
//! sample, in its own last or next samples (a decision it does not take there is a switch
//! added, not moved, and breaks this reading). The re-timed run's
//! continuous values are the f64 semantics' throughout; only the timing of its switches is
//! the fixed run's. Every clause is then held against it sample by sample: the force within
//! its tolerance at every sample (no time-shift reading), the terms and outputs, the events
//! and their arguments, the states.
//!
//! What it does not excuse: an arithmetic error moves the fixed run's continuous values
//! away from the re-timed run's exactly as from the recorded run's (the re-timed run never
//! reads the fixed run's values, only its decisions), and a decision the fixed run gets
//! wrong for longer than the switch tolerance is a lost or added switch.

use super::{
    closeness, pair_events, push_fixed_events, states_out_of_range, switches, with_params,
    Contract, ContractCheck, FixedInstance, FixedProgram, Switch, MAX_SWITCHES_KEPT,
};
use crate::interp::Instance;
use crate::ir::{Program, Value};
use tactus_runtime::fixed as fx;

/// The fixed run of `fp` (param block `block`) against the f64 run of `p` re-timed to its
/// switches, on the sensor words of `run` with its params, every clause of `c` measured
/// (see the module). With `stop`, the run ends at the first sample whose force, terms,
/// outputs or states break `c`, or at a switch lost or added.
pub(super) fn compare(
    p: &Program,
    fp: &FixedProgram,
    run: &super::ReferenceRun,
    block: Vec<i32>,
    dac_lsb_n: f64,
    c: &Contract,
    stop: bool,
) -> ContractCheck {
    let prog = with_params(p, &run.params);
    let prog = &*prog;
    let mut a = Instance::new(prog);
    let mut before = a.clone();
    let mut b = FixedInstance::with_params(fp, block);
    let mut out = ContractCheck {
        dac_lsb_n,
        retimed: true,
        term_lsb: vec![0.0; c.terms.len()],
        output_err: vec![0.0; c.outputs.len()],
        ..ContractCheck::default()
    };
    let force_limit = c.force.lsb(dac_lsb_n);
    let window = (c.switch_time_s * p.sample_rate_hz).ceil() as usize;
    let sites_a = switches::sites(prog);
    let sites_b = switches::sites(&fp.program);
    let pairs = switches::matched(&sites_a, &sites_b);
    let mut sig_a = vec![0u64; switches::words(sites_a.len())];
    let mut sig_b = vec![0u64; switches::words(sites_b.len())];
    // Per lowered value that decides a compared decision: the planned value whose truth the
    // fixed run decided it with.
    let mut decided: Vec<Option<Value>> = vec![None; prog.values.len()];
    for &(i, j) in &pairs {
        if let (Some(ca), Some(cb)) = (sites_a[i].cond(), sites_b[j].cond()) {
            decided[ca.index()].get_or_insert(cb);
        }
    }
    let scale = |frac: i32| 2f64.powi(-frac);
    let (total_scale, force_scale): (f64, Vec<f64>) = (
        scale(fp.total_frac),
        fp.force_frac.iter().map(|&f| scale(f)).collect(),
    );
    let mut ev_a: Vec<(usize, usize, Vec<f64>)> = Vec::new();
    let mut ev_b: Vec<(usize, usize, Vec<f64>)> = Vec::new();
    let (mut totals_a, mut totals_b) = (Vec::new(), Vec::new());
    // The f64 semantics' own decisions over the last `window` samples, newest last.
    let mut history: std::collections::VecDeque<Vec<u64>> = std::collections::VecDeque::new();
    // The open disagreement: its switch's index in `out.switches` (if kept) and start.
    let mut open: Option<(Option<usize>, usize)> = None;
    // Whether the open disagreement holds a decision that is no time shift.
    let mut refused = false;
    for (n, &raw) in run.raw.iter().enumerate() {
        // (A copy: the fixed run's decisions are read from it below.)
        let ob = b.step_raw(&[raw]).clone();
        let vals_b = b.values();
        switches::signature(&sites_b, |v| vals_b[v.index()] != 0, b.modes(), &mut sig_b);
        let x = [run.reading(raw)];
        before.copy_from(&a);
        a.step(&x);
        let vals_a = a.values();
        switches::signature(
            &sites_a,
            |v| vals_a[v.index()] != 0.0,
            a.modes(),
            &mut sig_a,
        );
        let differ = pairs
            .iter()
            .find(|&&(i, j)| switches::bit(&sig_a, i) != switches::bit(&sig_b, j));
        let mut broken = false;
        // Each decision the fixed run takes apart from the f64 semantics must be one the
        // f64 semantics itself takes within the switch tolerance of this sample — in its
        // last `window` samples (the fixed run is late) or its next `window` (early) — or
        // it is no switch moved in time but a decision of the fixed run's own: a switch
        // added, never taken over.
        let shifted = differ.is_none()
            || pairs.iter().all(|&(i, j)| {
                let x = switches::bit(&sig_b, j);
                switches::bit(&sig_a, i) == x
                    || history.iter().any(|h| switches::bit(h, i) == x)
                    || takes_within(&a, &run.raw[n + 1..], window, &sites_a, i, x, run)
            });
        history.push_back(sig_a.clone());
        if history.len() > window {
            history.pop_front();
        }
        match (differ, open) {
            (Some(&(i, _)), None) => {
                out.switch_count += 1;
                let kept = (out.switches.len() < MAX_SWITCHES_KEPT).then(|| {
                    out.switches.push(Switch {
                        sample: n,
                        resolved: true,
                        decision: sites_a[i].describe(p),
                        bound_lsb: force_limit,
                        slope_lsb: 0.0,
                        ..Switch::default()
                    });
                    out.switches.len() - 1
                });
                open = Some((kept, n));
            }
            (None, Some((kept, start))) => {
                if let Some(k) = kept {
                    out.switches[k].samples = n - start;
                }
                open = None;
                refused = false;
            }
            _ => {}
        }
        if let Some((kept, start)) = open {
            if !shifted && n - start < window {
                // A decision the f64 semantics does not take within the tolerance: not
                // taken over, a switch added or lost (once per disagreement).
                if !refused {
                    out.switches_unresolved += 1;
                    if let Some(k) = kept {
                        out.switches[k].resolved = false;
                    }
                    refused = true;
                }
                broken = true;
            } else if refused {
                broken = true;
            } else if n - start < window {
                // The re-timed run takes the fixed run's decisions this sample.
                a.copy_from(&before);
                let vals_b = b.values();
                a.step_deciding(&x, &|v| {
                    decided[v.index()].map(|cb| vals_b[cb.index()] != 0)
                });
                out.retimed_samples += 1;
            } else if n - start == window {
                // Still apart when the window closes: a switch lost or added.
                out.switches_unresolved += 1;
                if let Some(k) = kept {
                    out.switches[k].resolved = false;
                }
                broken = true;
            }
        }
        let oa = a.last();
        out.samples += 1;
        let ft = f64::from(ob.total) * total_scale;
        let diff = (oa.total - ft).abs() / dac_lsb_n;
        out.max_force_lsb = out.max_force_lsb.max(diff);
        out.max_force_lsb_all = out.max_force_lsb_all.max(diff);
        broken |= diff > force_limit;
        if let Some((Some(k), _)) = open {
            // The per-sample clause holds here; the switch keeps what it saw.
            let s = &mut out.switches[k];
            s.strict_lsb = s.strict_lsb.max(diff);
        }
        for (k, (f, bound)) in c.terms.iter().enumerate() {
            let i = f.index();
            let e = (oa.forces[i] - f64::from(ob.forces[i]) * force_scale[i]).abs() / dac_lsb_n;
            out.term_lsb[k] = out.term_lsb[k].max(e);
            broken |= e > bound.lsb(dac_lsb_n);
        }
        for (k, (o, bound)) in c.outputs.iter().enumerate() {
            let i = o.index();
            let e = (oa.outputs[i] - fx::to_f64(ob.outputs[i], fp.output_frac[i])).abs();
            out.output_err[k] = out.output_err[k].max(e);
            broken |= e > *bound;
        }
        ev_a.extend(oa.events.iter().map(|e| (n, e.0.index(), e.1.clone())));
        push_fixed_events(fp, n, &ob.events, &mut ev_b);
        if !stop {
            totals_a.push(oa.total);
            totals_b.push(ft);
        }
        let outside = states_out_of_range(fp, b.states());
        out.state_out_of_range += outside as usize;
        if stop && (broken || outside) {
            break;
        }
    }
    if let Some((Some(k), start)) = open {
        out.switches[k].samples = out.samples - start;
    }
    if !stop {
        let window = (c.event_time_s * p.sample_rate_hz).ceil() as usize;
        out.max_force_lsb_within_time = closeness(&totals_a, &totals_b, window)
            .max(closeness(&totals_b, &totals_a, window))
            / dac_lsb_n;
    }
    out.overflowed = b.overflowed().iter().filter(|o| **o).count();
    let ev_a: Vec<&(usize, usize, Vec<f64>)> = ev_a.iter().collect();
    pair_events(&mut out, &ev_a, &ev_b, c, p.sample_rate_hz);
    out
}

/// Whether the f64 semantics, stepped on from `a` (its own decisions, nothing taken over)
/// over at most `window` of the sensor words `raw`, takes decision `i` of `sites` as `x` at
/// some sample: a decision the fixed run took early.
fn takes_within(
    a: &Instance,
    raw: &[i32],
    window: usize,
    sites: &[switches::Site],
    i: usize,
    x: bool,
    run: &super::ReferenceRun,
) -> bool {
    let mut ahead = a.clone();
    let mut sig = vec![0u64; switches::words(sites.len())];
    raw.iter().take(window).any(|&w| {
        ahead.step(&[run.reading(w)]);
        let vals = ahead.values();
        switches::signature(sites, |v| vals[v.index()] != 0.0, ahead.modes(), &mut sig);
        switches::bit(&sig, i) == x
    })
}
