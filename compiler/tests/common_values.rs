//! Common values (`fixed::common`): sharing never changes what a program computes — the f64
//! reference interpreter gives the same trace, bit for bit, on the shared program as on the
//! original, for every shipped instrument and built-in stimulus — and it removes the grand
//! piano's repeated products (a state read after a write is a new value: the piano's hammer
//! states are written by its impact handlers between reads, which this also exercises).

use tactus_compiler::fixed::common::share_common_values;
use tactus_compiler::ir::{ArithOp, Op, Program, Stmt};
use tactus_compiler::lower::Config;
use tactus_compiler::sim::simulate;
use tactus_runtime::stimulus;

#[path = "support/shipped.rs"]
mod shipped;

fn instruments() -> Vec<(String, Program)> {
    let mut out = Vec::new();
    for (name, text) in shipped::instrument_sources(false) {
        let p = tactus_compiler::compile(&text, &Config::default())
            .unwrap_or_else(|_| panic!("{name} does not compile"))
            .program;
        out.push((p.name.clone(), p));
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// Products and divisions the body runs (definitions of `mul`/`div` values, every branch).
fn products(stmts: &[Stmt], p: &Program) -> usize {
    stmts
        .iter()
        .map(|s| match s {
            Stmt::Def(v) => matches!(
                p.values[v.index()].op,
                Op::Arith(ArithOp::Mul | ArithOp::Div, ..)
            ) as usize,
            Stmt::If(_, b) => products(b, p),
            _ => 0,
        })
        .sum()
}

#[test]
fn sharing_keeps_every_f64_trace_bit_for_bit() {
    for (name, p) in instruments() {
        let shared = share_common_values(&p);
        assert_eq!(
            share_common_values(&shared).values.len(),
            shared.values.len()
        );
        // The keyboard instruments whole; the larger ones (the plucked string, the rubbed bank,
        // the bowed string: 650 to 21,000 values) on the first samples of one stimulus, to
        // keep the test short in debug builds.
        let samples = match p.values.len() {
            0..=500 => usize::MAX,
            501..=5000 => 3000,
            _ => 300,
        };
        let mut compared = 0;
        for (stim, _) in stimulus::builtin_names() {
            let mut s = stimulus::builtin(stim, p.sensors[0].range.1, p.sample_rate_hz).unwrap();
            s.key.truncate(samples);
            let (a, _) = simulate(&p, &s);
            let (b, _) = simulate(&shared, &s);
            for (ca, cb) in a.columns.iter().zip(&b.columns) {
                assert_eq!((&ca.name, ca.values.len()), (&cb.name, cb.values.len()));
                if let Some(n) =
                    (0..ca.values.len()).find(|&n| ca.values[n].to_bits() != cb.values[n].to_bits())
                {
                    panic!(
                        "{name}/{stim}: sharing changed `{}` at sample {n}: {} → {}",
                        ca.name, ca.values[n], cb.values[n]
                    );
                }
            }
            // (`Trace`'s `==` would fail on the NaN of events that did not fire: bits here.)
            assert_eq!(a.columns.len(), b.columns.len());
            assert!(a.columns.iter().all(|c| c.values.len() == s.key.len()));
            compared += 1;
            if samples != usize::MAX {
                break;
            }
        }
        println!(
            "{name:<16} values {:>6} → {:>6}, products {:>5} → {:>5}, {compared} stimuli identical",
            p.values.len(),
            shared.values.len(),
            products(&p.body, &p),
            products(&shared.body, &shared)
        );
        if name == "grand_piano" {
            assert!(
                products(&shared.body, &shared) + 10 <= products(&p.body, &p),
                "the piano's repeated products are not shared"
            );
        }
    }
}
