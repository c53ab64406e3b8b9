//! The accuracy contract (`fixed::contract`) on the keyboard instruments: the default format
//! plan keeps every clause on every built-in stimulus — force within 1 DAC LSB, the same
//! events (none lost or added) within 0.5 ms, event arguments within 1 %, states in range —
//! and a planner that ignores the contract (`PlanConfig::unlimited`) breaks it on the piano.

use std::path::Path;
use tactus_compiler::fixed::contract::{self, Contract, ContractCheck};
use tactus_compiler::fixed::{report, FixedProgram, PlanConfig};
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config;
use tactus_runtime::stimulus;

const INSTRUMENTS: [&str; 4] = ["hammond", "harpsichord", "harpsichord_2x8", "grand_piano"];

fn program(name: &str) -> Program {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../instruments/{name}.tactus"));
    tactus_compiler::compile(&std::fs::read_to_string(path).unwrap(), &Config::default())
        .unwrap()
        .program
}

/// Every built-in stimulus of `p` through both engines: (stimulus, what it showed).
fn runs(p: &Program, fp: &FixedProgram) -> Vec<(&'static str, ContractCheck)> {
    let lsb = report::analyse(fp).dac_lsb_n();
    stimulus::builtin_names()
        .iter()
        .map(|(stim, _)| {
            let s = stimulus::builtin(stim, p.sensors[0].range.1, p.sample_rate_hz).unwrap();
            (*stim, contract::check(p, fp, &s.key, lsb))
        })
        .collect()
}

#[test]
fn the_default_plan_keeps_the_contract_on_every_builtin_stimulus() {
    let c = Contract::default();
    let mut broken = Vec::new();
    for name in INSTRUMENTS {
        let p = program(name);
        let fp = FixedProgram::new(&p);
        for (stim, r) in runs(&p, &fp) {
            println!(
                "{name:<16} {stim:<9} force {:.4} LSB (of {}), events {}/{} unmatched {} shift {} samples, args {:.4} % (of {} %), states out {}",
                r.max_force_lsb,
                c.force_lsb,
                r.events_f64,
                r.events_fixed,
                r.unmatched,
                r.max_event_shift,
                100.0 * r.max_arg_rel,
                100.0 * c.event_arg_rel,
                r.state_out_of_range
            );
            assert!(r.samples > 0);
            for v in r.violations(&c, p.sample_rate_hz) {
                broken.push(format!("{name}/{stim}: {v}"));
            }
        }
    }
    assert!(broken.is_empty(), "contract broken:\n{}", broken.join("\n"));
}

/// The contract is not vacuous: the piano planned with no precision budget (every product
/// that fits `MULS` takes it, divisors shifted to 16 bits) breaks at least one clause.
#[test]
fn a_planner_greedier_than_the_contract_breaks_it() {
    let c = Contract::default();
    let p = program("grand_piano");
    let greedy = FixedProgram::with_config(&p, &PlanConfig::unlimited());
    let exact = FixedProgram::new(&p);
    let (g, e) = (greedy.mul_forms(), exact.mul_forms());
    println!(
        "greedy plan: {} MULS, {} high word, {} 64-bit; default plan: {} MULS, {} high word, {} 64-bit",
        g.0, g.1, g.2, e.0, e.1, e.2
    );
    assert!(g.0 > e.0, "the greedy plan must use more MULS products");
    let broken: Vec<String> = runs(&p, &greedy)
        .into_iter()
        .flat_map(|(stim, r)| {
            r.violations(&c, p.sample_rate_hz)
                .into_iter()
                .map(move |v| format!("{stim}: {v}"))
        })
        .collect();
    println!("greedy plan breaks:\n{}", broken.join("\n"));
    assert!(
        !broken.is_empty(),
        "the greedy plan kept the contract: the test shows nothing"
    );
}

/// The divisor tolerance is pinned by the contract too: shifting the piano's divisors to a
/// 2^-6 relative error (its impact pulse's decay) breaks the force clause, where the
/// default 2^-10 keeps it with a margin.
#[test]
fn a_greedier_divisor_shift_breaks_the_contract() {
    let c = Contract::default();
    let p = program("grand_piano");
    let greedy = FixedProgram::with_config(
        &p,
        &PlanConfig {
            div_rel_tolerance: 1.0 / 64.0,
            ..PlanConfig::default()
        },
    );
    let exact = FixedProgram::new(&p);
    assert!(
        greedy
            .div_shift
            .iter()
            .zip(&exact.div_shift)
            .any(|(g, e)| g > e),
        "the greedy plan must shift some divisor further"
    );
    let worst = runs(&p, &greedy)
        .iter()
        .map(|(_, r)| r.max_force_lsb)
        .fold(0.0, f64::max);
    println!("divisors within 2^-6: worst force error {worst:.3} DAC LSB");
    assert!(
        worst > c.force_lsb,
        "{worst} LSB: the contract did not catch it"
    );
}
