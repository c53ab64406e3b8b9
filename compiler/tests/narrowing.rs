//! States that only events write are narrowed to the hull of what they are assigned
//! (`fixed::range::state_hulls`): a recorded key position takes the key's range, a state
//! integrated every sample or one that counts up keeps its declared range, and the plan
//! gives a narrowed state its hull's format and reports the declared range.

use tactus_compiler::fixed::range::state_hulls;
use tactus_compiler::fixed::{FixedProgram, PlanConfig};
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config;

fn compile(src: &str) -> Program {
    tactus_compiler::compile(src, &Config::default())
        .unwrap_or_else(|d| panic!("{d:?}"))
        .program
}

const SRC: &str = "instrument t {
    sensor key: m in [0 mm, 10 mm]
    param full_scale = 5 N
    state deepest = 0 mm in [0 mm, 40 mm]
    state half = 1 mm in [0 mm, 40 mm]
    state count = 0 m in [0 m, 100 m]
    state x = 0 m in [-1 m, 1 m]
    on key > 5 mm { deepest = key
                    half = key / 2 + 1 mm
                    count = count + 1 m }
    dynamics { x' = 0.1 m/s }
    force f = 10 N/m * (deepest + half + count + x)
}
";

#[test]
fn event_states_take_the_hull_of_their_assignments() {
    let p = compile(SRC);
    let h = state_hulls(&p);
    let name = |i: usize| p.states[i].name.as_str();
    // Within the hull's margin (`NARROWING_MARGIN` of its magnitude: ≈ 6 nm here).
    let near = |a: f64, b: f64| (a - b).abs() <= 1e-8;
    for (i, &(lo, hi)) in h.iter().enumerate() {
        let declared = p.states[i].range;
        assert!(
            lo >= declared.0 && hi <= declared.1,
            "{}: {lo} {hi}",
            name(i)
        );
        match name(i) {
            // The key's range (its initial 0 inside it).
            "deepest" => assert!(near(lo, 0.0) && near(hi, 0.01), "{lo} {hi}"),
            // key/2 + 1 mm ∈ [1 mm, 6 mm]; the initial 1 mm inside it.
            "half" => assert!(near(lo, 0.001) && near(hi, 0.006), "{lo} {hi}"),
            // Grows every round: its declared range.
            "count" => assert_eq!((lo, hi), declared),
            // Written every sample (integrated): its declared range.
            "x" => assert_eq!((lo, hi), declared),
            other => panic!("unexpected state {other}"),
        }
    }
}

#[test]
fn the_plan_gives_a_narrowed_state_its_hulls_format() {
    let p = compile(SRC);
    let narrowed = FixedProgram::new(&p);
    let declared = FixedProgram::with_config(
        &p,
        &PlanConfig {
            narrow_states: false,
            ..PlanConfig::default()
        },
    );
    let i = p.states.iter().position(|s| s.name == "deepest").unwrap();
    // [0, 10 mm] takes two more fraction bits than [0, 40 mm].
    assert_eq!(narrowed.state_frac[i], declared.state_frac[i] + 2);
    assert_eq!(narrowed.narrowed[i], Some((0.0, 0.04)));
    assert!(declared.narrowed.iter().all(|n| n.is_none()));
    let x = p.states.iter().position(|s| s.name == "x").unwrap();
    assert_eq!(narrowed.narrowed[x], None);
    let report = tactus_compiler::fixed::render::render(
        &narrowed,
        &tactus_compiler::fixed::report::analyse(&narrowed),
    );
    assert!(
        report.contains("narrowed to what its assignments can hold"),
        "{report}"
    );
}

#[test]
fn the_pianos_deepest_travel_takes_the_keys_format() {
    let src = include_str!("../../instruments/grand_piano.tactus");
    let p = compile(src);
    let fp = FixedProgram::new(&p);
    let xmax = fp
        .program
        .states
        .iter()
        .position(|s| s.name == "esc.xmax")
        .unwrap();
    assert_eq!(fp.narrowed[xmax], Some((0.0, 0.02)));
    assert_eq!(fp.state_frac[xmax], fp.sensor_frac[0]);
}
