//! Reciprocals of divisor states (`fixed::recip`) on a small instrument: the per-sample
//! division by a state that only events set disappears from the fixed program, the
//! reciprocal is recomputed at each assignment (symbolically where that removes the
//! division), saturation of the state carries over to its reciprocal, and the fixed engine
//! follows the f64 reference, which keeps the plain division.

use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::interp::Instance;
use tactus_compiler::ir::{ArithOp, Op, Program, Stmt};
use tactus_compiler::lower::Config;
use tactus_compiler::sim::Engine;
use tactus_runtime::stimulus;

/// A decaying pulse whose decay time events set: by a quotient (the piano's impact), by a
/// constant beyond the range (saturates), and by a value whose range reaches 0 (the
/// general form, one division at the assignment).
const DECAY: &str = r#"
instrument decay {
    sensor key: m in [0 mm, 10 mm]
    param gain = 2000 N/m
    param tau0 = 3 ms
    param v0 = 0.05 m/s
    param full_scale = 30 N
    state pulse = 0 N in [0 N, 30 N]
    state tau = 3 ms in [0.1 ms, 10 ms]
    dynamics {
        pulse' = -pulse / tau
    }
    on key > 5 mm {
        pulse = gain * key
        tau = tau0 / (1 + max(d(key), 0 m/s) / v0)
    }
    on key < 2 mm {
        tau = 20 ms
    }
    on key > 8 mm {
        tau = key * 2 s/m
    }
    force f = pulse
}
"#;

fn program(src: &str) -> Program {
    tactus_compiler::compile(src, &Config::default())
        .unwrap_or_else(|d| panic!("{d:?}"))
        .program
}

/// Divisions by a run-time value in the per-sample body (outside every `if`).
fn per_sample_divisions(p: &Program) -> usize {
    p.body
        .iter()
        .filter(|s| match s {
            Stmt::Def(v) => matches!(
                p.values[v.index()].op,
                Op::Arith(ArithOp::Div, _, y) if p.const_value(y).is_none()
            ),
            _ => false,
        })
        .count()
}

#[test]
fn the_division_by_an_event_set_state_leaves_the_per_sample_body() {
    let p = program(DECAY);
    assert_eq!(
        per_sample_divisions(&p),
        1,
        "the source divides every sample"
    );
    let fp = FixedProgram::new(&p);
    assert_eq!(per_sample_divisions(&fp.program), 0);
    assert_eq!(fp.reciprocals.len(), 1);
    let r = &fp.reciprocals[0];
    assert_eq!(fp.program.states[r.state.index()].name, "tau");
    let h = &fp.program.states[r.recip.index()];
    // The quotient's one reader is the dynamics' `· h` (h = 1/fs): the hidden word holds
    // h/tau, and that product is gone too.
    let step = 1.0 / p.sample_rate_hz;
    assert_eq!(r.scale, step);
    assert!(h.name.ends_with("/tau"), "{}", h.name);
    assert_eq!(r.recip.index(), p.states.len(), "after the declared states");
    let near = |a: f64, b: f64| ((a - b) / b).abs() < 1e-12;
    assert!(near(h.range.0, step * 100.0) && near(h.range.1, step * 10_000.0));
    assert!(near(h.init, step / 3e-3));
    assert_eq!(fp.declared_states(), p.states.len());
    // Three assignments: b/a with a constant a (a product), a folded constant, and the
    // general form (one division, in its event body only).
    let divides: Vec<bool> = r.writes.iter().map(|w| w.1).collect();
    assert_eq!(divides, [false, false, true]);
    assert_eq!(r.divisions.len(), 1);
    assert!(r.carried, "tau is read only as a divisor");
    assert_eq!(
        r.dropped.len(),
        1,
        "tau0 / (1 + …) is computed for nothing else"
    );
    let report =
        tactus_compiler::fixed::render::render(&fp, &tactus_compiler::fixed::report::analyse(&fp));
    assert!(
        report.contains("/tau of state `tau` (1/tau scaled by"),
        "{report}"
    );
    assert!(report.contains("gone, a product with `"), "{report}");
}

#[test]
fn the_fixed_engine_follows_f64_and_saturates_as_the_state_would() {
    let p = program(DECAY);
    let fp = FixedProgram::new(&p);
    let fs = p.sample_rate_hz;
    let mut a = Instance::new(&p);
    let mut b = tactus_compiler::fixed::interp::FixedInstance::new(&fp);
    let tau = p.states.iter().position(|s| s.name == "tau").unwrap();
    let (mut worst_tau, mut worst_force, mut changes) = (0.0f64, 0.0f64, 0);
    let mut last = f64::NAN;
    for descent in [0.02, 0.05, 0.2] {
        let s = stimulus::dip(descent, 0.05, 0.05, 10e-3, fs).unwrap();
        for &k in &s.key {
            let fa = Engine::step_si(&mut a, &[k]).total;
            let fb = Engine::step_si(&mut b, &[k]).total;
            worst_force = worst_force.max((fa - fb).abs());
            let (ta, tb) = (Engine::states_si(&a)[tau], Engine::states_si(&b)[tau]);
            assert_eq!(Engine::states_si(&b).len(), p.states.len());
            worst_tau = worst_tau.max(((ta - tb) / ta).abs());
            if ta != last {
                changes += 1;
                last = ta;
            }
        }
    }
    println!("tau changed {changes} times; worst relative error of tau {worst_tau:.2e}, of the force {worst_force:.2e} N");
    assert!(changes >= 6, "the stimuli must set tau by every assignment");
    assert!(worst_tau < 1e-4, "tau from its reciprocal: {worst_tau}");
    assert!(worst_force < 1e-3, "force error {worst_force} N");
    // `tau = 20 ms` and `tau = key · 2 s/m` (16 ms at 8 mm) saturate: the
    // reciprocal's saturations are the state's.
    let (sa, sb) = (
        Engine::state_saturations(&a)[tau],
        Engine::state_saturations(&b)[tau],
    );
    assert!(sa > 0, "the stimuli must saturate tau");
    assert_eq!(
        sa, sb,
        "saturations of tau in f64 and of 1/tau in fixed point"
    );
}

#[test]
fn a_divisor_state_with_dynamics_or_a_range_through_zero_or_too_wide_keeps_its_division() {
    for (src, reason) in [
        (
            DECAY.replace(
                "pulse' = -pulse / tau",
                "pulse' = -pulse / tau\n        tau' = 0 * pulse / (1 N)",
            ),
            "dynamics",
        ),
        (
            DECAY.replace("in [0.1 ms, 10 ms]", "in [-1 ms, 10 ms]"),
            "includes 0",
        ),
        (
            DECAY.replace("in [0.1 ms, 10 ms]", "in [0.000000000001 ms, 10 ms]"),
            "beyond what a word holds",
        ),
    ] {
        let p = program(&src);
        let fp = FixedProgram::new(&p);
        assert!(fp.reciprocals.is_empty(), "{reason}");
        assert_eq!(fp.refused_reciprocals.len(), 1, "{reason}");
        assert!(fp.refused_reciprocals[0].reason.contains(reason));
        assert_eq!(per_sample_divisions(&fp.program), 1, "{reason}");
    }
}
