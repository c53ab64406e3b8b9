//! Every instrument in `instruments/` compiles without warnings, and its IR is a snapshot;
//! a mutation test feeds 10,000+ damaged versions of them to the front end, which must
//! answer with diagnostics, never a panic.

use std::path::PathBuf;
use tactus_compiler::ir::{Axis, AxisTotal, Stmt};
use tactus_compiler::lower::Config;
use tactus_runtime::rng::XorShift64;

#[path = "support/shipped.rs"]
mod shipped;

fn instrument_files() -> Vec<PathBuf> {
    shipped::instrument_files(false)
        .into_iter()
        .map(|(_, p)| p)
        .collect()
}

/// Lines of an instrument's IR kept in its snapshot.
const SNAPSHOT_LINES: usize = 3_000;

#[test]
fn ir_of_every_instrument() {
    let files = instrument_files();
    assert!(files.len() >= 4, "{files:?}");
    for path in files {
        let name = path.file_stem().unwrap().to_str().unwrap().to_string();
        let src = std::fs::read_to_string(&path).unwrap();
        let lowered = tactus_compiler::compile(&src, &Config::default()).unwrap_or_else(|d| {
            panic!(
                "{name}:\n{}",
                tactus_compiler::diagnostics::emit_to_string(&name, &src, &d)
            )
        });
        assert!(
            lowered.warnings.is_empty(),
            "{name}: {:?}",
            lowered.warnings
        );
        // The IR of an FDTD string runs to tens of thousands of lines: its snapshot keeps the
        // declarations and the first part of the body, and counts the rest.
        let text = lowered.program.to_string();
        let lines: Vec<&str> = text.lines().collect();
        let shown = if lines.len() > SNAPSHOT_LINES {
            format!(
                "{}\n… {} more lines ({} values)\n",
                lines[..SNAPSHOT_LINES].join("\n"),
                lines.len() - SNAPSHOT_LINES,
                lowered.program.values.len()
            )
        } else {
            text
        };
        insta::assert_snapshot!(format!("ir_{name}"), shown);
    }
}

const SNIPPETS: &[&str] = &[
    "{",
    "}",
    "(",
    ")",
    "[",
    "]",
    ",",
    "=",
    "==",
    "'",
    ".",
    "^",
    "-",
    "*",
    "/",
    " mm",
    " N*s/m",
    "1e",
    "9999999999999999999999",
    "0",
    " m^-3",
    " if ",
    " else ",
    " on ",
    " while ",
    " emit x()",
    " use ",
    " state ",
    " mode ",
    "//",
    "\n",
    "é",
    "\u{0}",
    " d(",
    " d2(",
    " and ",
    " not ",
    ": bool",
    "1/s",
];

fn mutate(src: &str, rng: &mut XorShift64) -> String {
    let mut s: Vec<char> = src.chars().collect();
    for _ in 0..1 + rng.below(3) {
        if s.is_empty() {
            break;
        }
        let at = rng.below(s.len());
        match rng.below(5) {
            0 => {
                let len = 1 + rng.below(12);
                s.drain(at..(at + len).min(s.len()));
            }
            1 => {
                let snippet = SNIPPETS[rng.below(SNIPPETS.len())];
                s.splice(at..at, snippet.chars());
            }
            2 => {
                let from = rng.below(s.len());
                let len = 1 + rng.below(30);
                let piece: Vec<char> = s[from..(from + len).min(s.len())].to_vec();
                s.splice(at..at, piece);
            }
            3 => {
                let b = rng.below(s.len());
                s.swap(at, b);
            }
            _ => s.truncate(at),
        }
    }
    s.into_iter().collect()
}

#[test]
fn mutated_instruments_never_panic() {
    let sources: Vec<String> = instrument_files()
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect();
    // Instruments of thousands of values (arrays of nodes) cost a hundred times a piano key
    // to compile: they get one turn in 20.
    let large: Vec<bool> = sources
        .iter()
        .map(|s| {
            tactus_compiler::compile(s, &Config::default())
                .is_ok_and(|l| l.program.values.len() > 2_000)
        })
        .collect();
    let mut rng = XorShift64::new(0x007A_C705);
    let (mut ok, mut failed) = (0usize, 0usize);
    for i in 0..10_400 {
        let k = i % sources.len();
        if large[k] && !(i / sources.len()).is_multiple_of(20) {
            continue;
        }
        let m = mutate(&sources[k], &mut rng);
        let linked = tactus_compiler::imports::link(
            "m.tactus",
            tactus_compiler::sources::Origin::Text,
            &m,
            &mut tactus_compiler::imports::NoFiles,
        );
        match tactus_compiler::compile_linked(&linked, &Config::default()) {
            Ok(_) => ok += 1,
            Err(diags) => {
                assert!(diags.iter().any(|d| d.is_error()));
                // Every span lies in one file of the program (the mutant, or a library file
                // an argument of the wrong unit reaches).
                for d in &diags {
                    let span = &d.primary.0;
                    let file = linked.sources.get(linked.sources.file_at(span.start));
                    assert!(
                        span.start <= span.end && span.end <= file.base + file.text.len(),
                        "span out of file: {d:?}"
                    );
                }
                // Rendering must not panic either.
                let _ = tactus_compiler::diagnostics::emit_files_to_string(&linked.sources, &diags);
                failed += 1;
            }
        }
    }
    // Mutations that happen to be harmless are fine, but most must be caught.
    assert!(
        failed > ok,
        "only {failed} of {} mutants rejected",
        ok + failed
    );
}

/// The instruments driven by a 3-DoF pen (a vector sensor and vector forces); every other
/// shipped instrument is a keyboard key with one scalar force.
const PEN_INSTRUMENTS: [&str; 3] = ["bowed_string", "plucked_string", "rubbed_bank"];

/// Pen instruments publish one total per axis (`force.x`, `force.y` as outputs, z as the
/// total); keyboard instruments keep the one scalar total, with no axis anywhere.
#[test]
fn pen_and_keyboard_instruments() {
    for path in instrument_files() {
        let name = path.file_stem().unwrap().to_str().unwrap().to_string();
        let src = std::fs::read_to_string(&path).unwrap();
        let p = tactus_compiler::compile(&src, &Config::default())
            .unwrap()
            .program;
        if PEN_INSTRUMENTS.contains(&name.as_str()) {
            assert!(p.is_pen(), "{name}");
            assert!(p.forces.iter().all(|f| f.axis.is_some()), "{name}");
            let axes: Vec<Axis> = p.force_axes.iter().map(|a| a.0).collect();
            assert_eq!(axes, [Axis::X, Axis::Y, Axis::Z], "{name}");
            for (axis, t) in &p.force_axes {
                match t {
                    AxisTotal::Output(o) => {
                        assert_eq!(p.outputs[o.index()].name, format!("force.{axis}"))
                    }
                    AxisTotal::Total => assert_eq!(*axis, Axis::Z, "{name}"),
                }
            }
            assert_eq!(p.sensors[0].name, "pen.z", "{name}: the depth first");
        } else {
            assert!(!p.is_pen(), "{name}");
            assert!(p.forces.iter().all(|f| f.axis.is_none()), "{name}");
            assert!(p.outputs.iter().all(|o| !o.name.starts_with("force.")));
        }
    }
}

/// A pen with every kind of vector force: a component's (`w.push`), an array of them in a
/// loop (`ring[i]`, one read back as `ring[2].x`; the component's as `w.push.y`), terms on
/// all three axes and an axis
/// total made of several terms. Sensors are written x, z, y.
const PEN: &str = "
component wall {
    input y: m
    param k = 100 N/m
    force push = { y: -k * y }
}
instrument pen_test {
    sensor pen: m in { x: [0 mm, 160 mm], z: [0 mm, 10 mm], y: [-20 mm, 20 mm] }
    param k = 300 N/m
    param b = 2 N*s/m
    force contact = { z: k * pen.z, x: -b * d(pen.x) * pen.z / 10 mm }
    use w = wall(y = pen.y)
    for i in 0..3 {
        force ring[i] = { x: 0.01 N * i, z: -0.1 N }
    }
    force spring = { x: -20 N/m * (pen.x - 80 mm) }
    output third = ring[2].x
    output pushed = w.push.y
}
";

/// The axis totals of [`PEN`] are the sums of their terms in declaration order (the f64
/// interpreter, to the bit), the terms are what the source says (recomputed here from the
/// sensors), and the fixed interpreter follows the f64 one within the precision report's
/// bound of every term, of each axis output and of the total.
#[test]
fn vector_forces_sum_per_axis() {
    use tactus_compiler::fixed::interp::FixedInstance;
    use tactus_compiler::fixed::{report, FixedProgram};
    use tactus_compiler::interp::Instance;
    use tactus_runtime::fixed as fx;

    let p = tactus_compiler::compile(PEN, &Config::default())
        .unwrap_or_else(|d| {
            panic!(
                "{}",
                tactus_compiler::diagnostics::emit_to_string("pen", PEN, &d)
            )
        })
        .program;
    let names: Vec<&str> = p.sensors.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["pen.x", "pen.z", "pen.y"]);
    let terms: Vec<(&str, Option<Axis>)> =
        p.forces.iter().map(|f| (f.name.as_str(), f.axis)).collect();
    assert_eq!(
        terms,
        [
            ("contact.z", Some(Axis::Z)),
            ("contact.x", Some(Axis::X)),
            ("w.push.y", Some(Axis::Y)),
            ("ring[0].x", Some(Axis::X)),
            ("ring[0].z", Some(Axis::Z)),
            ("ring[1].x", Some(Axis::X)),
            ("ring[1].z", Some(Axis::Z)),
            ("ring[2].x", Some(Axis::X)),
            ("ring[2].z", Some(Axis::Z)),
            ("spring.x", Some(Axis::X)),
        ]
    );
    let out = |name: &str| p.outputs.iter().position(|o| o.name == name).unwrap();
    let (ox, oy, third, pushed) = (out("force.x"), out("force.y"), out("third"), out("pushed"));
    let force_value = |o: usize| {
        p.body
            .iter()
            .find_map(|s| match s {
                Stmt::Output(id, v) if id.index() == o => Some(*v),
                _ => None,
            })
            .unwrap()
    };

    let fp = FixedProgram::new(&p);
    assert!(fp.warnings.is_empty(), "{:?}", fp.warnings);
    let pr = report::analyse(&fp);
    assert!(!pr.total_is_local, "no states: the bounds are global");
    let (bound_x, bound_y) = (
        pr.value[force_value(ox).index()],
        pr.value[force_value(oy).index()],
    );
    let mut f64i = Instance::new(&p);
    let mut fixed = FixedInstance::new(&fp);
    let mut rng = XorShift64::new(8);
    let (mut worst_x, mut worst_y, mut worst_z) = (0.0f64, 0.0f64, 0.0f64);
    let mut moved = false;
    for n in 0..3000 {
        let t = n as f64 / p.sample_rate_hz;
        // A smooth stroke with some noise, every axis inside (and sometimes outside) its range.
        let want = [
            0.080 + 0.09 * (7.0 * t).sin() + 1e-4 * rng.unit(),
            0.005 + 0.006 * (11.0 * t).cos(),
            0.025 * (5.0 * t).sin(),
        ];
        let raw: Vec<i32> = (0..3)
            .map(|i| FixedInstance::sensor_raw(&fp, i, Some(want[i])))
            .collect();
        let x: Vec<f64> = (0..3)
            .map(|i| fx::to_f64(raw[i], fp.sensor_frac[i]))
            .collect();
        let a = f64i.step(&x).clone();
        let f = |name: &str| a.forces[p.forces.iter().position(|f| f.name == name).unwrap()];
        // The totals are the sums in declaration order, to the bit.
        let sum_x =
            f("contact.x") + f("ring[0].x") + f("ring[1].x") + f("ring[2].x") + f("spring.x");
        let sum_z = f("contact.z") + f("ring[0].z") + f("ring[1].z") + f("ring[2].z");
        assert_eq!(a.outputs[ox], sum_x, "sample {n}: force.x");
        assert_eq!(a.outputs[oy], f("w.push.y"), "sample {n}: force.y");
        assert_eq!(a.total, sum_z, "sample {n}: the total is z");
        assert_eq!(a.outputs[third], f("ring[2].x"));
        assert_eq!(a.outputs[pushed], f("w.push.y"));
        // The terms are what the source says, of the readings clamped into their ranges.
        let c: Vec<f64> = (0..3)
            .map(|i| x[i].clamp(p.sensors[i].range.0, p.sensors[i].range.1))
            .collect();
        let (px, pz, py) = (c[0], c[1], c[2]);
        assert!((f("contact.z") - 300.0 * pz).abs() < 1e-12);
        assert!((f("w.push.y") + 100.0 * py).abs() < 1e-12);
        assert!((f("spring.x") + 20.0 * (px - 0.080)).abs() < 1e-12);
        assert!((f("ring[2].x") - 0.02).abs() < 1e-15);
        moved |= f("contact.x").abs() > 1e-3;

        let b = fixed.step_raw(&raw).to_si(&fp);
        for (i, (u, v)) in a.forces.iter().zip(&b.forces).enumerate() {
            assert!((u - v).abs() <= pr.force[i], "sample {n}: term {i}");
        }
        worst_x = worst_x.max((a.outputs[ox] - b.outputs[ox]).abs());
        worst_y = worst_y.max((a.outputs[oy] - b.outputs[oy]).abs());
        worst_z = worst_z.max((a.total - b.total).abs());
    }
    println!(
        "fixed − f64: x {worst_x:.2e} N (bound {bound_x:.2e}), y {worst_y:.2e} N (bound {bound_y:.2e}), z {worst_z:.2e} N (bound {:.2e})",
        pr.total
    );
    assert!(
        moved,
        "the pen never moved fast enough for the friction term"
    );
    assert!(worst_x <= bound_x && worst_y <= bound_y && worst_z <= pr.total);
    assert!(
        worst_x > 0.0,
        "the fixed build computed force.x exactly: compared nothing?"
    );
}
