//! The regulation sheet (`tactus_host::regulate`): measured figures against what the
//! model says they must be, on a toy key whose answers are known, and on every shipped key
//! instrument (figures that do not apply left out with a note).

use std::path::Path;
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config as LowerConfig;
use tactus_host::play::engine::JitEngine;
use tactus_host::regulate::{self, gf_to_n, n_to_gf, Config, Figure, Sheet};

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn compile(source: &str, overrides: &[(&str, &str)]) -> Program {
    let config = LowerConfig {
        overrides: overrides
            .iter()
            .map(|(n, v)| (n.to_string(), v.to_string()))
            .collect(),
        ..LowerConfig::default()
    };
    tactus_compiler::compile(source, &config)
        .unwrap_or_else(|d| panic!("{d:?}"))
        .program
}

fn shipped(name: &str, overrides: &[(&str, &str)]) -> Program {
    let text = std::fs::read_to_string(root().join(format!("instruments/{name}.tactus"))).unwrap();
    compile(&text, overrides)
}

/// The static sheet on the f64 JIT (bit-identical to the f64 interpreter, and faster).
fn sheet(program: &Program) -> Sheet {
    sheet_with(program, &static_only())
}

/// The sheet measured as `config` says, on the f64 JIT.
fn sheet_with(program: &Program, config: &Config) -> Sheet {
    let jit = tactus_jit::JitProgram::compile(program).unwrap();
    regulate::measure(
        program,
        JitEngine(tactus_jit::JitInstance::new(&jit)),
        config,
    )
    .unwrap()
}

/// The static sheet alone (the dynamic sweep has tests of its own).
fn static_only() -> Config {
    Config {
        dynamic: false,
        ..Config::default()
    }
}

fn figure(sheet: &Sheet, f: Figure) -> f64 {
    sheet
        .get(f)
        .unwrap_or_else(|| panic!("{:?} not measured: {:?}", f, sheet.notes))
}

/// A key with only a constant weight `G` (and a little viscosity): a weight above `G` takes
/// it down, one below lets it rise, so down-weight = up-weight = balance weight = G, no
/// friction, and a key held by G stays put.
#[test]
fn a_key_of_constant_weight_regulates_to_that_weight() {
    let p = compile(
        "instrument toy {\n  sensor key: m in [0 mm, 10 mm]\n  param G = 0.5 N\n  force weight = G\n  force viscous = 0.05 N*s/m * d(key)\n}\n",
        &[],
    );
    let s = sheet(&p);
    let g = n_to_gf(0.5);
    for f in [Figure::DownWeight, Figure::UpWeight, Figure::BalanceWeight] {
        let v = figure(&s, f);
        assert!((v - g).abs() <= 0.15, "{f:?} {v} gf, G = {g} gf");
    }
    assert!(figure(&s, Figure::Friction).abs() <= 0.15);
    assert!(figure(&s, Figure::Creep) < 0.01, "{s:?}");
    assert_eq!(figure(&s, Figure::KeyDip), 10.0);
    // Hammer figures do not apply: left out, with a note.
    for f in [Figure::LetOff, Figure::BlowDistance, Figure::Repetition] {
        assert_eq!(s.get(f), None);
    }
    assert!(
        s.notes.iter().any(|n| n.contains("no hammer")),
        "{:?}",
        s.notes
    );
    // Constant force: the loop's two branches agree (up to the viscous 0.25 mN).
    let (gap, _) = s.force_loop.least_gap(0.002, 0.007).unwrap();
    assert!(gap.abs() < gf_to_n(0.1), "{gap}");
    // A finger of 0.8 N against 0.5 N: free fall over 10 mm with 0.3 N on 30 g ≈ 45 ms
    // (plus half the 5 ms rise).
    let t = figure(&s, Figure::KeyBottomPp);
    assert!((44.0..51.0).contains(&t), "{t} ms");
}

/// The heavier weight regulates heavier: the toy with G doubled.
#[test]
fn down_weight_follows_the_weight() {
    let src = "instrument toy {\n  sensor key: m in [0 mm, 10 mm]\n  param G = 0.5 N\n  force weight = G\n}\n";
    let light = sheet(&compile(src, &[]));
    let heavy = sheet(&compile(src, &[("G", "1 N")]));
    let (l, h) = (
        figure(&light, Figure::DownWeight),
        figure(&heavy, Figure::DownWeight),
    );
    assert!((h - 2.0 * l).abs() < 0.3, "{l} {h}");
}

#[test]
fn every_shipped_key_instrument_prints_its_sheet() {
    // The grand piano: every figure applies, the dynamic sheet's too.
    let piano = sheet_with(&shipped("grand_piano", &[]), &Config::default());
    for f in Figure::ALL {
        assert!(piano.get(f).is_some(), "{f:?}: {:?}", piano.notes);
    }
    assert_eq!(figure(&piano, Figure::BlowDistance).round(), 45.0);
    // The harpsichords pluck but have no hammer; the organ key has neither, and sinks
    // unloaded (MIKEY's removed weight ΔG), so it has no up-weight.
    for name in ["harpsichord", "harpsichord_2x8"] {
        let s = sheet(&shipped(name, &[]));
        assert_eq!(figure(&s, Figure::KeyDip), 7.0);
        assert!(s.get(Figure::DownWeight).is_some() && s.get(Figure::StrikeSpeedFf).is_some());
        assert_eq!(s.get(Figure::LetOff), None, "{name}");
    }
    let organ = sheet(&shipped("hammond", &[]));
    assert_eq!(organ.get(Figure::UpWeight), None);
    assert!(
        organ.notes.iter().any(|n| n.starts_with("up-weight")),
        "{:?}",
        organ.notes
    );
    assert_eq!(organ.get(Figure::StrikeSpeedPp), None);
}

/// The interpreter defines the meaning; the JIT reproduces it bit for bit, so the sheet is
/// the same figure for figure.
#[test]
fn the_interpreter_and_the_jit_measure_the_same_sheet() {
    let p = shipped("harpsichord", &[]);
    let interp = regulate::measure(
        &p,
        tactus_compiler::interp::Instance::new(&p),
        &static_only(),
    )
    .unwrap();
    assert_eq!(interp, sheet(&p));
}

#[test]
fn a_pen_instrument_is_refused() {
    let p = shipped("rubbed_bank", &[]);
    let err = regulate::measure(
        &p,
        tactus_compiler::interp::Instance::new(&p),
        &Config::default(),
    )
    .unwrap_err();
    assert!(err.contains("pen instrument"), "{err}");
}

fn concert_grand() -> regulate::spec::Spec {
    regulate::spec::read(&root().join("instruments/specs/concert_grand.toml")).unwrap()
}

fn concert_grand_dynamic() -> regulate::spec::Spec {
    regulate::spec::read(&root().join("instruments/specs/concert_grand_dynamic.toml")).unwrap()
}

fn outside(sheet: &Sheet) -> Vec<String> {
    outside_of(sheet, &concert_grand())
}

fn outside_of(sheet: &Sheet, spec: &regulate::spec::Spec) -> Vec<String> {
    regulate::spec::check(sheet, spec)
        .iter()
        .filter(|v| !v.holds())
        .map(|v| {
            format!(
                "{:?}: {:?} not in {}",
                v.range.figure,
                v.value,
                v.range.text()
            )
        })
        .collect()
}

/// Issue 35: the grand piano (Hayward–Armstrong key friction, weighed off, repetition lever
/// with drop screw) is inside the regulated concert grand's ranges at grand88's bass, middle
/// and treble hammer masses — down- and up-weight, friction, hysteresis, creep, the geometry,
/// the key-bottom times and the repetition.
#[test]
fn the_grand_piano_regulates_inside_the_concert_grand_spec_at_bass_middle_and_treble() {
    for m_h in ["11 g", "8 g", "3.5 g"] {
        let s = sheet(&shipped("grand_piano", &[("M_h", m_h)]));
        assert_eq!(outside(&s), Vec::<String>::new(), "M_h = {m_h}");
        // The friction itself, not the action's other hysteresis: up below down by ≥ 10 gf.
        assert!(figure(&s, Figure::Hysteresis) >= 10.0, "M_h = {m_h}");
        assert!(figure(&s, Figure::Creep) <= 0.05, "M_h = {m_h}");
    }
}

/// The sheet of `p` measured on the fixed JIT of its fixed-point program `fp`.
fn fixed_jit_sheet(p: &Program, fp: &tactus_compiler::fixed::FixedProgram) -> Sheet {
    fixed_jit_sheet_with(p, fp, &static_only())
}

fn fixed_jit_sheet_with(
    p: &Program,
    fp: &tactus_compiler::fixed::FixedProgram,
    config: &Config,
) -> Sheet {
    let jit = tactus_jit::fixed::FixedJitProgram::compile(fp).unwrap();
    regulate::measure(
        p,
        tactus_host::play::engine::FixedJitEngine(
            tactus_jit::fixed::FixedJitInstance::new(&jit),
            fp,
        ),
        config,
    )
    .unwrap()
}

/// The same sheet in the firmware's fixed point: the fixed interpreter and the fixed JIT
/// measure the same figures bit for bit, and they are inside the spec too (the friction
/// holds the key still in fixed point as in f64).
#[test]
fn the_grand_piano_in_fixed_point_regulates_the_same_on_the_interpreter_and_the_jit() {
    let p = shipped("grand_piano", &[]);
    let fp = tactus_compiler::fixed::FixedProgram::new(&p);
    let interp = regulate::measure(
        &p,
        tactus_compiler::fixed::interp::FixedInstance::new(&fp),
        &static_only(),
    )
    .unwrap();
    let by_jit = fixed_jit_sheet(&p, &fp);
    assert_eq!(interp, by_jit);
    assert_eq!(outside(&interp), Vec::<String>::new());
}

/// grand88's bass and treble hammers in the firmware's fixed point (on the fixed JIT, which
/// the test above holds to the interpreter): inside the spec too, the creep of a held key
/// included.
#[test]
fn the_grand_piano_in_fixed_point_regulates_inside_the_spec_at_bass_and_treble() {
    for m_h in ["11 g", "3.5 g"] {
        let p = shipped("grand_piano", &[("M_h", m_h)]);
        let s = fixed_jit_sheet(&p, &tactus_compiler::fixed::FixedProgram::new(&p));
        assert_eq!(outside(&s), Vec::<String>::new(), "M_h = {m_h}");
        assert!(figure(&s, Figure::Creep) <= 0.05, "M_h = {m_h}");
    }
}

/// Issue 70's frictionless sprung key (a 100 N/m return spring, a 4,000 N/m stop from 6 mm
/// to the 8 mm bed, 0.3 N·s/m), its sheet by hand: the weight that holds it at its bed is
/// 100·0.008 + 4000·0.002 = 8.8 N (897.4 gf), not the 158 gf a weight dropped on measured
/// when the key swung into its bed; the most weight under which it returns to rest (≤ 1 % of
/// the dip, 0.08 mm) is 100 N/m·0.08 mm = 8 mN (0.82 gf); its friction is 0; its balance
/// weight, the force at mid-dip (4 mm), 0.4 N (40.8 gf), which holds it there without
/// creep. A sprung key's figures come from the quasi-static loop (5 mm/s), whose viscous
/// term adds b·v = 0.3·0.005 N = 0.15 gf going down and takes it going up.
#[test]
fn a_frictionless_sprung_key_regulates_to_its_spring() {
    let p = compile(
        "instrument sprung {\n  sensor key: m in [0 mm, 8 mm]\n  force spring = 100 N/m * key\n  force stop = if key > 6 mm { 4000 N/m * (key - 6 mm) } else { 0 N }\n  force viscous = 0.3 N*s/m * d(key)\n}\n",
        &[],
    );
    let s = sheet(&p);
    let near = |f: Figure, want: f64, tol: f64| {
        let v = figure(&s, f);
        assert!(
            (v - want).abs() <= tol,
            "{f:?} {v} gf, by hand {want}: {s:#?}"
        );
    };
    near(Figure::DownWeight, n_to_gf(8.8), 0.2);
    near(Figure::UpWeight, n_to_gf(0.008), 0.2);
    near(Figure::Friction, n_to_gf(0.3 * 0.005), 0.05);
    near(Figure::BalanceWeight, n_to_gf(0.4), 0.2);
    assert!(figure(&s, Figure::Creep) < 0.01);
    let how = &s
        .figures
        .iter()
        .find(|m| m.figure == Figure::Friction)
        .unwrap()
        .how;
    assert!(how.contains("sprung"), "{how}");
}

/// The toy key of the known-value tests: a 0.5 N weight, a 20 N/m spring, a 0.1 N
/// Hayward–Armstrong stick point (0.02 mm of presliding), a strike at 8 mm of five times the
/// key's speed, a 10 mm dip.
const TOY: &str = "component stick_friction {\n  param f_c = 0.1 N\n  param z_max = 0.02 mm\n  input x: m\n  state w = 0 mm in [-1 mm, 11 mm]\n  while true { w = clamp(w, x - z_max, x + z_max) }\n  output f = f_c / z_max * (x - w)\n}\ninstrument toy {\n  sensor key: m in [0 mm, 10 mm]\n  use fr = stick_friction(x = key)\n  force weight = 0.5 N\n  force spring = 20 N/m * key\n  force friction = fr.f\n  on key >= 8 mm { emit strike(velocity = 5 * d(key)) }\n}\n";

/// The toy key's dynamic sheet against an independent integration of its pressed touches:
/// finger and key as one rigid body of m = 20 g + 10 g (`PRESSED_FINGER_KG`, the fingertip's
/// key) under the finger's push P(t) = P·(1 − cos(π·t / R))/2 (then P; R = `PUSH_RISE_S`), against the
/// weight, the friction going down and the spring: m·x'' = P(t) − 0.5 N − 0.1 N − 20 N/m·x,
/// the key held at rest until P(t) passes 0.6 N. Integrated here in 1 µs steps (no player,
/// no instrument program, no pulp: the fingertip's 20 kN/m pulp under that rise moves the
/// answer by well under 1 %). Travel time = when x reaches 8 mm, hammer speed = 5·x' there,
/// key bottom = when x reaches 10 mm; each measured figure within 4 % of it (a measurement
/// 20 % off fails), over every pressed push of the sweep (those too weak to reach 8 mm by
/// hand must not strike in the sheet either).
#[test]
fn the_toy_keys_pressed_touches_match_an_independent_integration() {
    let p = compile(TOY, &[]);
    let s = sheet_with(&p, &Config::default());
    let m = tactus_runtime::player::PRESSED_FINGER_KG
        + tactus_runtime::player::Fingertip::default().key_kg;
    let rise = tactus_runtime::player::PUSH_RISE_S;
    // ((time at 8 mm s, hammer speed there m/s), time at 10 mm s)
    let by_hand = |push: f64| -> (Option<(f64, f64)>, Option<f64>) {
        let dt = 1e-6;
        let (mut x, mut v, mut t) = (0.0f64, 0.0f64, 0.0f64);
        let mut at8 = None;
        while t < regulate::dynamic::RUN_S {
            let p_t = if t < rise {
                push * 0.5 * (1.0 - (std::f64::consts::PI * t / rise).cos())
            } else {
                push
            };
            let net = p_t - 0.5 - 0.1 - 20.0 * x;
            if x > 0.0 || v > 0.0 || net > 0.0 {
                v += dt * net / m;
                x += dt * v;
            }
            t += dt;
            if at8.is_none() && x >= 0.008 {
                at8 = Some((t, 5.0 * v));
            }
            if x >= 0.010 {
                return (at8, Some(t));
            }
        }
        (at8, None)
    };
    let mut checked = 0;
    for run in s
        .touches
        .iter()
        .filter(|r| r.touch.kind == tactus_runtime::player::TouchKind::Pressed)
    {
        let label = run.touch.label();
        let (strike, bottom) = by_hand(run.touch.push_n);
        let near = |what: &str, got: f64, want: f64| {
            assert!(
                (got - want).abs() <= 0.04 * want,
                "{label}: {what} {got}, by hand {want}"
            );
        };
        match (run.strike, strike) {
            (Some((travel, speed)), Some((t8, v8))) => {
                near("travel time s", travel, t8);
                near("hammer speed m/s", speed, v8);
                checked += 1;
            }
            (None, None) => {}
            (got, want) => panic!("{label}: strike {got:?}, by hand {want:?}"),
        }
        match (run.bottom_s, bottom) {
            (Some(got), Some(want)) => near("key bottom s", got, want),
            (None, None) => {}
            (got, want) => panic!("{label}: key bottom {got:?}, by hand {want:?}"),
        }
    }
    assert!(checked >= 10, "{checked} pressed touches compared");
}

/// A toy key with a known weight, spring and friction (0.5 N, 20 N/m, a 0.1 N
/// Hayward–Armstrong stick point) and a strike at 8 mm of five times the key's speed. By
/// hand: down-weight to the bed G + f_c + k·10 mm = 0.8 N (81.6 gf); up-weight, back to rest
/// (0.1 mm), G − f_c + k·0.1 mm = 0.402 N (41.0 gf); friction f_c = 0.1 N (10.2 gf) and
/// balance weight G + k·5 mm = 0.6 N (61.2 gf), both from the quasi-static loop (sprung:
/// (down − up)/2 = 20.3 gf would count the spring); the hammer/key speed ratio 5 at every
/// touch. The dynamic sheet's travel times and key bottoms equal a run of the same touch
/// against the same forces computed here in Rust (the player's own model, no instrument
/// program between).
#[test]
fn a_toy_key_of_known_weight_spring_and_friction_regulates_to_them() {
    let p = compile(TOY, &[]);
    let s = sheet_with(&p, &Config::default());
    let near = |f: Figure, want: f64, tol: f64| {
        let v = figure(&s, f);
        assert!((v - want).abs() <= tol, "{f:?} {v}, by hand {want}");
    };
    near(Figure::DownWeight, n_to_gf(0.8), 0.2);
    near(Figure::UpWeight, n_to_gf(0.5 - 0.1 + 20.0 * 0.0001), 0.2);
    near(Figure::Friction, n_to_gf(0.1), 0.1);
    near(Figure::BalanceWeight, n_to_gf(0.6), 0.2);
    // The strike's speed is 5·d(key); the ratio reads the key's peak speed from the player.
    near(Figure::SpeedRatioMin, 5.0, 0.1);
    near(Figure::SpeedRatioMax, 5.0, 0.1);
    // Travel times and key bottoms: the same touches against the same forces, here.
    let force = |x: f64, w: &mut f64| {
        *w = w.clamp(x - 2e-5, x + 2e-5);
        0.5 + 20.0 * x + 0.1 / 2e-5 * (x - *w)
    };
    let fs = p.sample_rate_hz;
    for run in s.touches.iter().filter(|r| r.strike.is_some()) {
        let mut t = tactus_runtime::player::TouchPlay::new(
            run.touch,
            0.010,
            tactus_runtime::player::Fingertip::default(),
            fs,
            regulate::dynamic::CONTACT_S,
            tactus_runtime::player::FingerConfig::default().hold_n,
            regulate::dynamic::RUN_S,
        );
        let contact = (regulate::dynamic::CONTACT_S * fs).round() as usize;
        let mut w = 0.0;
        let mut at8 = None;
        for n in 0..(regulate::dynamic::RUN_S * fs) as usize {
            let x = t.key_m();
            if at8.is_none() && x >= 0.008 {
                at8 = Some((n - contact) as f64 / fs);
            }
            let f = force(x, &mut w);
            if at8.is_some() && t.bottom_s().is_some() {
                break;
            }
            t.step(f);
        }
        let (travel, _) = run.strike.unwrap();
        let label = run.touch.label();
        assert!(
            (travel - at8.unwrap()).abs() <= 1.5 / fs,
            "{label}: travel {travel} s, by the player alone {at8:?}"
        );
        let bottom = t.bottom_s().unwrap() - contact as f64 / fs;
        assert!(
            (run.bottom_s.unwrap() - bottom).abs() <= 1.5 / fs,
            "{label}: bottom {:?}, by the player alone {bottom}",
            run.bottom_s
        );
    }
    assert!(s.touches.iter().filter(|r| r.strike.is_some()).count() >= 20);
}

/// Every figure of `sheet` is inside `dynamic`; what is outside is printed.
fn inside(sheet: &Sheet, dynamic: &regulate::spec::Spec, m_h: &str, numeric: &str) {
    let out = outside_of(sheet, dynamic);
    println!("M_h = {m_h}, {numeric}: outside the dynamic spec: {out:?}");
    assert!(out.is_empty(), "M_h = {m_h}, {numeric}: {out:?}");
}

/// Issue 70: the grand piano's dynamic sheet. At grand88's bass (11 g), middle (8 g) and
/// treble (3.5 g) hammers every figure lies inside the dynamic spec, in f64 and in the
/// firmware's fixed point: the softest strike and the loudest, the hammer/key speed ratio
/// over p–f, travel times against Goebl's fit, struck sooner than pressed (the pressed
/// push's rise time is calibrated to it: `PUSH_RISE_S`), the key bottoming after the string
/// contact at the softest touch and before it at the loudest, and where the two cross. The
/// treble's travel time is the closest (0.82 against 0.8: the light hammer's loud pressed
/// touches lie below the fit's v^−0.57; docs/regulating.md). Each figure outside is printed.
#[test]
fn the_grand_piano_moves_as_measured_grand_actions_move() {
    let dynamic = concert_grand_dynamic();
    for m_h in ["11 g", "8 g", "3.5 g"] {
        let p = shipped("grand_piano", &[("M_h", m_h)]);
        let s = sheet_with(&p, &Config::default());
        for m in s.figures.iter().filter(|m| m.figure.is_dynamic()) {
            println!(
                "M_h = {m_h}: {:<28} {:>8.3} {}",
                m.figure.title(),
                m.value,
                m.figure.unit()
            );
        }
        inside(&s, &dynamic, m_h, "f64");
        for f in [Figure::SpeedRatioMin, Figure::SpeedRatioMax] {
            let r = figure(&s, f);
            assert!((3.5..=6.5).contains(&r), "M_h = {m_h}: {f:?} {r}");
        }
        assert!(figure(&s, Figure::KeyBottomSoft) > 0.0, "M_h = {m_h}");
        assert!(figure(&s, Figure::KeyBottomLoud) < 0.0, "M_h = {m_h}");
    }
    // The firmware's fixed point: the same at the three hammers.
    for m_h in ["11 g", "8 g", "3.5 g"] {
        let p = shipped("grand_piano", &[("M_h", m_h)]);
        let fp = tactus_compiler::fixed::FixedProgram::new(&p);
        let s = fixed_jit_sheet_with(&p, &fp, &Config::default());
        inside(&s, &dynamic, m_h, "fixed point");
    }
}
