//! Constant chains (`fixed::chains`): `(x / k1) · k2` is planned as one product by `k2/k1`
//! (the dynamics' `· h` after a quotient by a mass), a chain with a short factor is left
//! alone, the fixed engine still follows f64, and keys with different constants share one
//! program whose folded constant is a run-time param.

use tactus_compiler::fixed::chains::{fold_constant_chains, significant_bits};
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::interp::Instance;
use tactus_compiler::ir::{ArithOp, Op, Program, Stmt};
use tactus_compiler::lower::Config;
use tactus_compiler::sim::Engine;
use tactus_runtime::stimulus;

fn mass(m: &str) -> String {
    format!(
        r#"
instrument mass {{
    sensor key: m in [0 mm, 10 mm]
    param k = 2000 N/m
    param M = {m}
    param full_scale = 30 N
    state v = 0 m/s in [-2 m/s, 2 m/s]
    state x = 0 m in [-20 mm, 20 mm]
    dynamics {{
        v' = (k * (key - x) - 0.3 N*s/m * v) / M
        x' = v
    }}
    force f = k * (key - x)
}}
"#
    )
}

fn program(src: &str) -> Program {
    tactus_compiler::compile(src, &Config::default())
        .unwrap_or_else(|d| panic!("{d:?}"))
        .program
}

/// Products and quotients by a constant defined in the body.
fn constant_products(p: &Program) -> usize {
    fn walk(p: &Program, stmts: &[Stmt]) -> usize {
        stmts
            .iter()
            .map(|s| match s {
                Stmt::Def(v) => match p.values[v.index()].op {
                    Op::Arith(ArithOp::Mul | ArithOp::Div, a, b)
                        if p.const_value(a).is_some() || p.const_value(b).is_some() =>
                    {
                        1
                    }
                    _ => 0,
                },
                Stmt::If(_, b) => walk(p, b),
                _ => 0,
            })
            .sum()
    }
    walk(p, &p.body)
}

#[test]
fn significant_bits_of_constants() {
    assert_eq!(significant_bits(1000.0), 7);
    assert_eq!(significant_bits(0.5), 1);
    assert_eq!(significant_bits(-3.0), 2);
    assert_eq!(significant_bits(0.0), 0);
    assert_eq!(significant_bits(f64::INFINITY), 0);
    assert!(significant_bits(1.0 / 44100.0) > 40);
}

#[test]
fn a_quotient_by_a_mass_times_the_step_is_one_product() {
    let p = program(&mass("3.7 g"));
    let q = fold_constant_chains(&p);
    assert_eq!(
        constant_products(&q),
        constant_products(&p) - 1,
        "(…) / M · h folds into (…) · (h/M)"
    );
    assert_eq!(fold_constant_chains(&q), q, "folding is idempotent");
    // A short factor (1/M = 1000 for 1 g) is left alone.
    let short = program(&mass("1 g"));
    assert_eq!(fold_constant_chains(&short), short);
    // The fixed engine, which plans the folded program, follows the f64 reference.
    let fp = FixedProgram::new(&p);
    assert_eq!(
        constant_products(&fp.program),
        constant_products(&tactus_compiler::fixed::common::share_common_values(&q))
    );
    let mut a = Instance::new(&p);
    let mut b = tactus_compiler::fixed::interp::FixedInstance::new(&fp);
    let s = stimulus::dip(0.05, 0.05, 0.05, 10e-3, p.sample_rate_hz).unwrap();
    let mut worst = 0.0f64;
    for &k in &s.key {
        let fa = Engine::step_si(&mut a, &[k]).total;
        let fb = Engine::step_si(&mut b, &[k]).total;
        worst = worst.max((fa - fb).abs());
    }
    println!("worst force error {worst:.3e} N");
    assert!(
        worst < 30.0 / 32768.0,
        "within 1 DAC LSB at 30 N: {worst} N"
    );
}

#[test]
fn keys_with_different_masses_share_one_folded_constant_as_a_runtime_param() {
    let keys = [program(&mass("3.7 g")), program(&mass("5.3 g"))];
    let shared = tactus_compiler::share::share(&keys).unwrap();
    let q = &shared.program;
    // `(…) / M · h` of each key is `(…) · P`, P = h/M a run-time param: one product fewer
    // by a constant, and that one by a run-time param.
    let by_param = q
        .values
        .iter()
        .filter(|vd| match vd.op {
            Op::Arith(ArithOp::Mul, a, b) => [a, b]
                .iter()
                .any(|x| matches!(q.values[x.index()].op, Op::Param(id) if q.params[id.index()].runtime.is_some())),
            _ => false,
        })
        .count();
    assert_eq!(by_param, 1);
    // The other: `k · (key − x)`, lowered for the force and the dynamics, computed once
    // (`fold_constants` shares common values before the keys are compared).
    assert_eq!(constant_products(q) + 3, constant_products(&keys[0]));
    let h = 1.0 / keys[0].sample_rate_hz;
    let ids: Vec<_> = q.runtime_params().collect();
    assert_eq!(ids.len(), 1, "{:?}", q.params);
    for (k, m) in [3.7e-3, 5.3e-3].iter().enumerate() {
        let want = h / m;
        assert!(((shared.values()[k][0] - want) / want).abs() < 1e-12);
    }
}
