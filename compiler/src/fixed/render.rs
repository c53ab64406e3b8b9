//! The precision report as text (`tactus check --report precision`): each value's
//! Q-format and error bound from the analysis ([`super::report`]), each product's form and
//! cycles, the reciprocals and divisions, the contract and the margins the simulation
//! measured ([`super::contract`]).

use super::report::{force_values, pow2, Precision};
use super::{q_name, FixedProgram};
use crate::ir::*;
use std::fmt::Write;

/// Renders the precision report as text (the output of `tactus check --report precision`).
pub fn render(fp: &FixedProgram, pr: &Precision) -> String {
    let p = &fp.program;
    let mut s = String::new();
    let lsb = pr.dac_lsb_n();
    let _ = writeln!(
        s,
        "precision report: {} (32-bit fixed point, round half up, saturating)",
        p.name
    );
    let _ = writeln!(
        s,
        "DAC: 16-bit at full scale ±{} N → 1 LSB = {:.3e} N{}",
        pr.full_scale_n,
        lsb,
        if p.params.iter().any(|x| x.name == "full_scale") {
            ""
        } else {
            " (full scale from the total's range: declare `param full_scale = … N`)"
        }
    );
    let _ = writeln!(s, "\nstates                     range                          format      LSB          error bound");
    for (i, st) in p.states.iter().enumerate() {
        let f = fp.state_frac[i];
        let unit = st.dim.unit_string();
        let _ = writeln!(
            s,
            "  {:<24} [{:>11.4e}, {:>11.4e}] {:<6} {:<11} {:.3e}    {:.3e} {unit}  {}",
            st.name,
            st.range.0,
            st.range.1,
            unit,
            q_name(f),
            2f64.powi(-f),
            pr.state[i],
            if pr.accumulating[i] {
                "(per sample; accumulates)".to_string()
            } else {
                match fp.narrowed.get(i).copied().flatten() {
                    Some((lo, hi)) => format!(
                        "(declared [{lo:.4e}, {hi:.4e}]: narrowed to what its assignments can hold)"
                    ),
                    None => String::new(),
                }
            }
        );
    }
    let _ = writeln!(s, "\nforce terms                range                          format      error bound (N)   (DAC LSB; contract: total ≤ 1)");
    let forces = force_values(p);
    for (i, fd) in p.forces.iter().enumerate() {
        let v = forces[i];
        let r = fp.ranges.values[v.index()];
        let _ = writeln!(
            s,
            "  {:<24} [{:>11.4e}, {:>11.4e}] N      {:<11} {:.3e}         {:.4}",
            fd.name,
            r.lo,
            r.hi,
            q_name(fp.frac[v.index()]),
            pr.force[i],
            pr.force[i] / lsb
        );
    }
    // A pen's x and y totals are outputs (`force.x`, `force.y`); z is the total word.
    let outputs = output_values(p);
    for (axis, at) in &p.force_axes {
        let crate::ir::AxisTotal::Output(o) = at else {
            continue;
        };
        let Some(v) = outputs[o.index()] else {
            continue;
        };
        let r = fp.ranges.values[v.index()];
        let e = pr.value[v.index()];
        let _ = writeln!(
            s,
            "  {:<24} [{:>11.4e}, {:>11.4e}] N      {:<11} {:.3e}         {:.4}",
            format!("total ({axis})"),
            r.lo,
            r.hi,
            q_name(fp.frac[v.index()]),
            e,
            e / lsb
        );
    }
    let _ = writeln!(
        s,
        "  {:<24} {:>40} {:<11} {:.3e}         {:.4}{}",
        if p.is_pen() { "total (z)" } else { "total" },
        "",
        q_name(fp.total_frac),
        pr.total,
        pr.total / lsb,
        if pr.total_is_local {
            "  per sample, given exact states"
        } else {
            ""
        }
    );
    render_arithmetic(&mut s, fp);
    render_reciprocals(&mut s, fp);
    render_contract(&mut s, fp, pr);
    if fp.warnings.is_empty() {
        let _ = writeln!(
            s,
            "overflow: none possible — every value's format holds its analysed range"
        );
    } else {
        let _ = writeln!(
            s,
            "overflow: saturation inserted at {} unbounded value(s) (see the warnings)",
            fp.warnings.len()
        );
    }
    s
}

/// The accuracy contract (the program's `tolerance` lines or the defaults) and its static
/// side: the total force's error bound.
fn render_contract(s: &mut String, fp: &FixedProgram, pr: &Precision) {
    let p = &fp.program;
    let c = &p.contract;
    let lsb = pr.dac_lsb_n();
    let _ = writeln!(
        s,
        "\naccuracy contract ({}; checked by simulating against f64 on the built-in stimuli):",
        if *c == super::contract::Contract::default() {
            "the defaults"
        } else {
            "the instrument's `tolerance` lines, defaults elsewhere"
        }
    );
    let _ = writeln!(
        s,
        "  force at the key within {} = {:.4} DAC LSB = {:.3e} N: static bound {:.4} LSB{}",
        c.force,
        c.force.lsb(lsb),
        c.force.lsb(lsb) * lsb,
        pr.total / lsb,
        if pr.total_is_local {
            " per sample (integrated states: measured by simulation)"
        } else {
            ""
        }
    );
    for (f, b) in &c.terms {
        let _ = writeln!(
            s,
            "  force term `{}` within {} = {:.4} DAC LSB: static bound {:.4} LSB",
            p.forces[f.index()].name,
            b,
            b.lsb(lsb),
            pr.force[f.index()] / lsb
        );
    }
    for (o, b) in &c.outputs {
        let _ = writeln!(
            s,
            "  output `{}` within {b:e} (SI)",
            p.outputs[o.index()].name
        );
    }
    let _ = writeln!(
        s,
        "  events on the same key as in f64, none lost or added, within {} ms ({:.0} samples); arguments within {} %; states within their declared ranges",
        c.event_time_s * 1e3,
        c.event_time_s * p.sample_rate_hz,
        c.event_arg_rel * 100.0
    );
    let _ = writeln!(
        s,
        "  switches: where the runs are in different discrete states (a mode, an `on` edge, a body's or an `if … else`'s condition) they agree again within {} ms ({:.0} samples), and for that long the force of each is within the force bound plus the f64 force's own one-sample change there of the other's at some sample within it; the per-sample force clause elsewhere",
        c.switch_time_s * 1e3,
        (c.switch_time_s * p.sample_rate_hz).ceil()
    );
    let _ = writeln!(
        s,
        "  or, where that reading breaks, every clause sample by sample against the f64 run re-timed to the fixed run's switches: the f64 semantics taking the fixed run's branch decisions where its own differ, for at most {} ms at a time — the switch's timing excused, not its arithmetic",
        c.switch_time_s * 1e3
    );
    for e in &c.events {
        let d = &p.events[e.event.index()];
        let args: Vec<String> = e
            .args_rel
            .iter()
            .map(|(i, r)| format!("`{}` within {} %", d.args[*i].0, r * 100.0))
            .collect();
        let _ = writeln!(
            s,
            "  event `{}`: within {} ms{}{}",
            d.name,
            c.time_of(e.event.index()) * 1e3,
            if args.is_empty() { "" } else { "; " },
            args.join(", ")
        );
    }
}

/// The margins of each clause of the contract, worst over the built-in stimuli (from
/// [`super::contract::check_builtin`]), as report lines.
pub fn render_margins(p: &Program, runs: &[(&str, super::contract::ContractCheck)]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\ncontract margins (worst over {} built-in stimuli, fixed point against f64):",
        runs.len()
    );
    let mut worst: Vec<(String, f64, f64, &str, &str)> = Vec::new();
    for (stim, r) in runs {
        for (clause, w, b, unit) in r.margins(p, &p.contract) {
            match worst.iter_mut().find(|x| x.0 == clause) {
                Some(x) if w > x.1 => (x.1, x.4) = (w, stim),
                Some(_) => {}
                None => worst.push((clause, w, b, unit, stim)),
            }
        }
    }
    // Which reading each run is measured by ([`super::contract::ContractCheck::retimed`]):
    // the recorded f64 run (switches as time shifts), or, where that broke, the f64 run
    // re-timed to the fixed run's switches; a run broken in both is shown by the first.
    let names = |f: &dyn Fn(&super::contract::ContractCheck) -> bool| -> Vec<&str> {
        runs.iter().filter(|(_, r)| f(r)).map(|r| r.0).collect()
    };
    let retimed = names(&|r| r.retimed);
    let both = names(&|r| r.retimed_force_lsb.is_some());
    let _ = writeln!(
        s,
        "  reading: {} run(s) against the recorded f64 run; {} against the f64 run re-timed to the fixed run's switches{}{}",
        runs.len() - retimed.len(),
        retimed.len(),
        if retimed.is_empty() {
            String::new()
        } else {
            format!(" ({})", retimed.join(", "))
        },
        if both.is_empty() {
            String::new()
        } else {
            format!("; broken in both readings: {}", both.join(", "))
        }
    );
    for (clause, w, b, unit, stim) in worst {
        let verdict = if w <= b { "holds" } else { "BROKEN" };
        let _ = writeln!(
            s,
            "  {clause:<48} worst {w:<10.4} of {b:<8} {unit:<8} margin {:<10.4} ({stim}) {verdict}",
            b - w
        );
    }
    s
}

/// The form and estimated cycles of every product and run-time division.
fn render_arithmetic(s: &mut String, fp: &FixedProgram) {
    let p = &fp.program;
    let _ = writeln!(
        s,
        "\nproducts (form chosen by the precision budget and the contract's simulation; Cortex-M0+ cycles estimated; the cheaper forms considered)"
    );
    for (i, k) in fp.mul_kind.iter().enumerate() {
        let (Some(k), Op::Arith(_, x, y)) = (k, &p.values[i].op) else {
            continue;
        };
        let span = &p.values[i].span;
        let fy = fp.recip[i].map_or(fp.frac[y.index()], |(_, f)| f);
        let tried: Vec<String> = fp.mul_options[i]
            .iter()
            .filter(|o| o.cycles() < k.cycles())
            .map(|o| format!("{} ≈ {}", o.name(), o.cycles()))
            .collect();
        let _ = writeln!(
            s,
            "  v{i:<5} source {:>5}..{:<5} {:<8} × {:<8} → {:<8} {:<46} ≈ {:>2}{}",
            span.start,
            span.end,
            q_name(fp.frac[x.index()]),
            q_name(fy),
            q_name(fp.frac[i]),
            k.name(),
            k.cycles(),
            if tried.is_empty() {
                String::new()
            } else {
                format!("   (refused: {})", tried.join("; "))
            }
        );
    }
    let forms = fp.mul_forms();
    let _ = writeln!(
        s,
        "multiplications: {} MULS (32×32→32, operands pre-shifted where needed), {} 32×16 (one operand cut to 16 bits, 2 MULS), {} high word of 32×32, {} 64-bit (ARMv6-M has no SMULL): ≈ {} Cortex-M0+ cycles",
        forms.muls, forms.m32x16, forms.high, forms.wide, forms.cycles
    );
    for (i, vd) in p.values.iter().enumerate() {
        let Op::Arith(ArithOp::Div, _, y) = vd.op else {
            continue;
        };
        if fp.recip[i].is_some() {
            continue;
        }
        let b = fp.div_shift[i];
        let word = |v: usize, f: i32| (fp.ranges.values[v].mag() * pow2(f)).ceil() as u64 + 1;
        let qbits = super::bits_of(word(i, fp.frac[i]));
        let dbits = super::bits_of(word(y.index(), fp.frac[y.index()]) >> b);
        let (steps, cycles) = super::division_cycles(qbits, dbits);
        let _ = writeln!(
            s,
            "division v{i} (source {}..{}): divisor >> {b} (relative error ≤ {:.1e}), {qbits}-bit quotient, {dbits}-bit divisor: {} ≈ {cycles} cycles",
            vd.span.start,
            vd.span.end,
            if b > 0 { pow2(b as i32) / (fp.ranges.values[y.index()].lo.abs().min(fp.ranges.values[y.index()].hi.abs()) * pow2(fp.frac[y.index()])) } else { 0.0 },
            if steps > 0 {
                format!("SIO divider, {steps} steps")
            } else {
                "restoring division".to_string()
            }
        );
    }
}

/// The reciprocals of divisor states ([`super::recip`]): which state, the hidden word's
/// format, where it is recomputed, and the divisions that are gone.
fn render_reciprocals(s: &mut String, fp: &FixedProgram) {
    let p = &fp.program;
    if fp.reciprocals.is_empty() && fp.refused_reciprocals.is_empty() {
        return;
    }
    let span = |r: &std::ops::Range<usize>| format!("source {}..{}", r.start, r.end);
    let _ = writeln!(
        s,
        "\nreciprocals (a division by a state that only events set is a product with a hidden word 1/state, recomputed where the state is assigned):"
    );
    for r in &fp.reciprocals {
        let (st, h) = (&p.states[r.state.index()], &p.states[r.recip.index()]);
        let f = fp.state_frac[r.recip.index()];
        let writes: Vec<String> = r
            .writes
            .iter()
            .map(|(w, divides)| {
                format!(
                    "{} ({})",
                    span(w),
                    if *divides {
                        "one run-time division"
                    } else {
                        "no division"
                    }
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "  {} of state `{}`{}: range [{:.4e}, {:.4e}] {}, {} (LSB {:.3e}); init {:.4e}; recomputed at {} assignment(s): {}",
            h.name,
            st.name,
            if r.scale == 1.0 {
                String::new()
            } else {
                format!(" (1/{} scaled by {:e}, the constant every quotient by it was multiplied by: that product is gone too)", st.name, r.scale)
            },
            h.range.0,
            h.range.1,
            h.dim.unit_string(),
            q_name(f),
            pow2(-f),
            h.init,
            r.writes.len(),
            writes.join(", ")
        );
        for d in &r.divisions {
            let _ = writeln!(
                s,
                "    division by `{}` ({}): gone, a product with `{}`",
                st.name,
                span(d),
                h.name
            );
        }
        if r.carried {
            let _ = writeln!(
                s,
                "    `{}` is read nowhere else: carried by `{}` (its writes dropped; its value is {:e} / `{}`)",
                st.name, h.name, r.scale, h.name
            );
            for d in &r.dropped {
                let _ = writeln!(
                    s,
                    "    division ({}) computed only for `{}`'s writes: gone",
                    span(d),
                    st.name
                );
            }
        }
    }
    for r in &fp.refused_reciprocals {
        let _ = writeln!(
            s,
            "  state `{}` keeps its divisions: {}",
            p.states[r.state.index()].name,
            r.reason
        );
    }
}

/// The value published by each output (`None` for an output never published).
fn output_values(p: &Program) -> Vec<Option<Value>> {
    let mut out = vec![None; p.outputs.len()];
    fn walk(stmts: &[Stmt], out: &mut [Option<Value>]) {
        for s in stmts {
            match s {
                Stmt::Output(o, v) => out[o.index()] = Some(*v),
                Stmt::If(_, b) => walk(b, out),
                _ => {}
            }
        }
    }
    walk(&p.body, &mut out);
    out
}
