//! Programs that break an IR invariant are rejected with an error, never a panic or bad
//! native code. Each case: a name, a mutation of the grand piano's IR, the error message.

use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::ir::{Program, SensorId, StateId, Stmt, Value};
use tactus_compiler::lower::Config;
use tactus_jit::{FixedJitProgram, JitProgram};

fn piano() -> Program {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../instruments/grand_piano.tactus"
    );
    let src = std::fs::read_to_string(path).expect("grand_piano.tactus");
    tactus_compiler::compile(&src, &Config::default())
        .expect("compiles")
        .program
}

/// The first value defined directly inside an `if` body, and the index of that `if`.
fn defined_in_if(p: &Program) -> (usize, Value) {
    for (i, s) in p.body.iter().enumerate() {
        if let Stmt::If(_, inner) = s {
            if let Some(v) =
                inner
                    .iter()
                    .find_map(|s| if let Stmt::Def(v) = s { Some(*v) } else { None })
            {
                return (i, v);
            }
        }
    }
    panic!("the piano has no value defined inside an if");
}

fn first_def(p: &Program) -> Value {
    p.body
        .iter()
        .find_map(|s| if let Stmt::Def(v) = s { Some(*v) } else { None })
        .expect("a definition")
}

type Mutation = fn(&mut Program);
type FixedMutation = fn(&mut FixedProgram);

fn cases() -> Vec<(&'static str, Mutation, &'static str)> {
    vec![
        ("unchanged", |_| {}, "ok"),
        (
            "value out of the table",
            |p| p.body.push(Stmt::Total(Value(1_000_000))),
            "value v1000000 is used where it is not defined (IR invariant: its definition precedes every use)",
        ),
        (
            "use before definition",
            |p| {
                let v = first_def(p);
                p.body.insert(0, Stmt::Total(v));
            },
            "value v0 is used where it is not defined (IR invariant: its definition precedes every use)",
        ),
        (
            "use after the if that defines it",
            |p| {
                let (i, v) = defined_in_if(p);
                p.body.insert(i + 1, Stmt::Total(v));
            },
            "used where it is not defined",
        ),
        (
            "defined twice",
            |p| {
                let v = first_def(p);
                p.body.push(Stmt::Def(v));
            },
            "value v0 is defined twice (IR invariant: exactly one definition)",
        ),
        (
            "state out of the table",
            |p| {
                let v = first_def(p);
                p.body.push(Stmt::SetState(StateId(99), v));
            },
            // the program has 6 states, its fixed program 7 (the hidden reciprocal of `tau`,
            // `fixed::recip`)
            "state index 99 is out of range (the program has ",
        ),
        (
            "sensor out of the table",
            |p| {
                p.values[0].op = tactus_compiler::ir::Op::Deriv(SensorId(7), 1);
            },
            "sensor index 7 is out of range (the program has 1)",
        ),
        (
            "inverted state range",
            |p| p.states[0].range = (1.0, -1.0),
            "state `s` has the invalid range [1, -1]",
        ),
        (
            "NaN sensor bound",
            |p| p.sensors[0].range.1 = f64::NAN,
            "sensor `key` has the invalid range [0, NaN]",
        ),
    ]
}

#[test]
fn invalid_programs_are_errors() {
    for (name, mutate, want) in cases() {
        let mut p = piano();
        mutate(&mut p);
        let got = match JitProgram::compile(&p) {
            Ok(_) => "ok".to_string(),
            Err(e) => e.to_string(),
        };
        assert!(got.contains(want), "{name}: got {got:?}, want {want:?}");
    }
}

/// The fixed JIT runs the same verifier on the IR of a fixed program, and checks that the
/// format plan has one entry per value, state, sensor and event.
#[test]
fn invalid_fixed_programs_are_errors() {
    let fixed_cases: Vec<(&str, FixedMutation, &str)> = vec![
        ("plan unchanged", |_| {}, "ok"),
        (
            "a format missing",
            |fp| {
                fp.frac.pop();
            },
            "internal error: inconsistent fixed-point plan tables",
        ),
        (
            "inverted raw sensor range",
            |fp| fp.sensor_raw_range[0] = (1, -1),
            "internal error: inconsistent fixed-point plan tables",
        ),
        (
            "a format beyond FRAC_RANGE",
            |fp| fp.frac[0] = 1000,
            "internal error: inconsistent fixed-point plan tables",
        ),
        (
            "a state format missing",
            |fp| {
                fp.state_frac.clear();
            },
            "internal error: inconsistent fixed-point plan tables",
        ),
    ];
    let base = FixedProgram::new(&piano());
    let compile = |fp: &FixedProgram| match FixedJitProgram::compile(fp) {
        Ok(_) => "ok".to_string(),
        Err(e) => e.to_string(),
    };
    for (name, mutate, want) in cases() {
        let mut fp = base.clone();
        mutate(&mut fp.program);
        let got = compile(&fp);
        assert!(got.contains(want), "{name}: got {got:?}, want {want:?}");
    }
    for (name, mutate, want) in fixed_cases {
        let mut fp = base.clone();
        mutate(&mut fp);
        let got = compile(&fp);
        assert!(got.contains(want), "{name}: got {got:?}, want {want:?}");
    }
}
