//! Params as run-time data (issue 15, part 3): the graded grand piano of `grand88` is one
//! program with a param block per key. Every engine that runs on the emulated Cortex-M0+
//! (the Thumb backend, the C backend through clang) is bit-exact with the fixed
//! interpreter for the grading's end points and middle; a board of graded keys holds one
//! code copy per core; and the cost against constant params is measured, static and
//! emulated.

use std::path::Path;
use tactus_compiler::cgen;
use tactus_compiler::ir::Program as Ir;
use tactus_compiler::lower::Config;
use tactus_firmware::budget::{self, LOAD_ADDR};
use tactus_firmware::cc::{self, Compiler, Options};
use tactus_firmware::corpus::{self, Size};
use tactus_firmware::image::{compile_layout, FirmwareImage, KeySpec, Program};
use tactus_firmware::measure::{builtin_runs, compare};
use tactus_firmware::{Interface, UpdateRunner};
use tactus_runtime::keyboard::{read_layout, KeyAssignment};
use tactus_runtime::limiter::LimiterConfig;

#[path = "common/layouts.rs"]
mod layouts;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn shipped(name: &str) -> Result<String, String> {
    std::fs::read_to_string(root().join(format!("instruments/{name}.tactus")))
        .map_err(|e| format!("{name}: {e}"))
}

/// grand88's keys and its compiled programs (one per key, all sharing one code).
fn grand88() -> (Vec<KeyAssignment>, Vec<Program>, Vec<usize>) {
    let (_, assigned) = read_layout(&root().join("instruments/layouts/grand88.toml")).unwrap();
    let (programs, index) = compile_layout(&assigned, &shipped, 44_100.0).unwrap();
    (assigned, programs, index)
}

/// The grading's end points and middle: A0 (11 g), E4 and C8 (3.5 g).
const KEYS: [u8; 3] = [21, 64, 108];

#[test]
fn graded_grand88_is_one_program_with_a_param_block_per_key() {
    let (assigned, programs, index) = grand88();
    assert_eq!(programs.len(), 88, "one parameter set per key");
    assert!(programs.iter().all(|p| p.same_code(&programs[0])));
    let fp = &programs[0].fixed;
    let names: Vec<&str> = fp
        .program
        .runtime_params()
        .map(|p| fp.program.params[p.index()].name.as_str())
        .collect();
    println!("run-time params of the graded piano: {names:?}");
    // The knuckle's load (`load = M_h / m_ref`: the jack's and lever's felt and the repetition
    // spring scale with the hammer they carry), the key leads (`G = balance − M_h·grav·ratio`:
    // the key weighed off at every hammer mass), and one product of M_h, I_h, load and G that
    // the key's force needs. The hammer's equation is divided through by M_h, so its terms are
    // the same constants at every hammer mass. Nothing else depends on the hammer mass, and
    // nothing divides by it at run time.
    assert_eq!(names.len(), 3, "{names:?}");
    let p = &fp.program;
    assert!(
        !p.values.iter().any(|vd| matches!(vd.op,
            tactus_compiler::ir::Op::Arith(tactus_compiler::ir::ArithOp::Div, _, y)
                if matches!(p.values[y.index()].op,
                    tactus_compiler::ir::Op::Param(q) if p.params[q.index()].runtime.is_some()))),
        "a division by a run-time param"
    );
    let block = |key: u8| {
        let i = assigned.iter().position(|a| a.key == key).unwrap();
        programs[index[i]].params.clone()
    };
    let (bass, mid, treble) = (block(21), block(64), block(108));
    println!("param blocks: A0 {bass:?}, E4 {mid:?}, C8 {treble:?}");
    // Each word is monotonic in the hammer mass, so from bass to treble.
    assert!(bass[0] > mid[0] && mid[0] > treble[0] || bass[0] < mid[0] && mid[0] < treble[0]);
    assert_ne!(bass, treble);
}

/// The piano lowered with the hammer mass of each of [`KEYS`], shared.
fn shared_piano() -> (Ir, Vec<Vec<f64>>) {
    let text = shipped("grand_piano").unwrap();
    let irs: Vec<Ir> = ["11 g", "7.25 g", "3.5 g"]
        .iter()
        .map(|m| {
            let config = Config {
                overrides: vec![("M_h".into(), (*m).into())],
                ..Config::default()
            };
            tactus_compiler::compile(&text, &config).unwrap().program
        })
        .collect();
    let shared = tactus_compiler::share::share(&irs).unwrap();
    let values = shared.values();
    (shared.program, values)
}

#[test]
fn thumb_code_with_param_blocks_is_bit_exact_with_the_fixed_interpreter() {
    let (ir, values) = shared_piano();
    let fp = tactus_compiler::fixed::FixedProgram::new(&ir);
    let obj = tactus_compiler::thumb::compile(&fp).unwrap();
    let runs = builtin_runs(&fp);
    for (k, v) in values.iter().enumerate() {
        let block = fp.param_block(v).unwrap();
        let iface = Interface {
            params: block.clone(),
            ..Interface::new(&fp, &obj.stem, &obj.out)
        };
        let init = obj.symbol(&obj.init_name()).unwrap().0 as u32;
        let update = obj.symbol(&obj.update_name()).unwrap().0 as u32;
        let mut r =
            UpdateRunner::from_code(&obj.code.text, LOAD_ADDR, init, update, iface).unwrap();
        let c = compare(&mut r, &fp, &obj.out, &runs).unwrap();
        println!(
            "Thumb, M_h set {k} (block {block:?}): {} samples, {} events, {} mismatches",
            c.samples, c.events, c.mismatches
        );
        assert!(c.samples > 1000 && c.events > 0);
        assert_eq!(c.mismatches, 0, "{:#?}", c.first_mismatches);
    }
}

#[test]
fn c_code_with_param_blocks_is_bit_exact_with_the_fixed_interpreter() {
    if let Err(e) = cc::check_tools(Compiler::Clang) {
        let msg = format!("clang build not tested: {e}");
        if std::env::var_os("CI").is_some() {
            panic!("{msg} (CI is set: .ci/run installs the tools)");
        }
        println!("SKIPPED: {msg}");
        return;
    }
    let (ir, values) = shared_piano();
    let fp = tactus_compiler::fixed::FixedProgram::new(&ir);
    let c = cgen::emit_c(&fp).unwrap();
    assert!(c.header.contains("int32_t params[3];"), "{}", c.header);
    let b = cc::build(&c, Compiler::Clang, &Options::default()).unwrap();
    let runs = builtin_runs(&fp);
    for v in &values {
        let iface = Interface {
            params: fp.param_block(v).unwrap(),
            ..Interface::new(&fp, &c.stem, &c.layout)
        };
        let mut r = UpdateRunner::from_elf(&b.elf, iface).unwrap();
        let cmp = compare(&mut r, &fp, &c.layout, &runs).unwrap();
        assert!(cmp.samples > 1000 && cmp.events > 0);
        assert_eq!(cmp.mismatches, 0, "{:#?}", cmp.first_mismatches);
    }
}

/// Different param blocks give different forces: the block is really read.
#[test]
fn the_param_block_changes_the_hammer() {
    let (ir, values) = shared_piano();
    let fp = tactus_compiler::fixed::FixedProgram::new(&ir);
    let run = &builtin_runs(&fp)[0];
    // Per M_h set: the first sample the hammer reaches the string (a strike event) and
    // the hammer-position trace.
    let traces: Vec<(Option<usize>, Vec<i32>)> = values
        .iter()
        .map(|v| {
            let mut inst = tactus_compiler::fixed::interp::FixedInstance::with_params(
                &fp,
                fp.param_block(v).unwrap(),
            );
            let mut strike = None;
            let trace = run
                .records
                .iter()
                .enumerate()
                .map(|(n, r)| {
                    let out = inst.step_raw(r);
                    if strike.is_none() && !out.events.is_empty() {
                        strike = Some(n);
                    }
                    out.outputs[0]
                })
                .collect();
            (strike, trace)
        })
        .collect();
    let strikes: Vec<Option<usize>> = traces.iter().map(|t| t.0).collect();
    println!(
        "{}: first strike sample per M_h set (11, 7.25, 3.5 g): {strikes:?}",
        run.label
    );
    assert_ne!(traces[0].1, traces[1].1);
    assert_ne!(traces[1].1, traces[2].1);
}

/// Static and measured cycles of the piano update with constant params (the default
/// `M_h = 8 g`, folded) and with run-time params (the graded program, for each of
/// [`KEYS`]); the figures of BENCHMARKS.md. The run-time program must be sound (static ≥
/// measured) and, as designed, cost little more than constant params: at most 10 %.
#[test]
fn the_cost_of_run_time_params_against_constant_params() {
    let constant = Program::compile(&shipped("grand_piano").unwrap(), &Config::default()).unwrap();
    let (assigned, programs, index) = grand88();
    let quick = |p: &Program| {
        let runs = corpus::corpus(&p.fixed, Size::Quick);
        budget::measure_key_update(
            &p.thumb,
            &p.fixed,
            &p.params,
            &runs,
            tactus_emulator::Engine::default(),
        )
        .unwrap()
    };
    let c_static = constant.static_cost().unwrap().cycles;
    let c_meas = quick(&constant);
    println!(
        "constant params (M_h = 8 g): static {c_static}, measured max {} mean {:.1} cycles/key-sample",
        c_meas.worst,
        c_meas.mean()
    );
    for key in KEYS {
        let i = assigned.iter().position(|a| a.key == key).unwrap();
        let p = &programs[index[i]];
        let s = p.static_cost().unwrap().cycles;
        let m = quick(p);
        println!(
            "run-time params, key {key}: static {s} ({:+}), measured max {} mean {:.1} ({:+.1})",
            s as i64 - c_static as i64,
            m.worst,
            m.mean(),
            m.mean() - c_meas.mean()
        );
        assert!(s >= m.worst, "key {key}: static {s} < measured {}", m.worst);
        assert!(
            (s as f64) <= 1.10 * c_static as f64,
            "key {key}: {s} cycles against {c_static} with constant params"
        );
    }
    // What the run-time words cost: the products that read one, in both programs (the
    // shared program's value table is the constant one's plus the reciprocals).
    let (cf, sf) = (&constant.fixed, &programs[0].fixed);
    for (i, vd) in sf.program.values.iter().enumerate() {
        if let tactus_compiler::ir::Op::Arith(op, x, y) = vd.op {
            if sf.param_word_of(x).is_some() || sf.param_word_of(y).is_some() {
                println!(
                    "v{i} {op:?}: run-time {:?} (frac {}), constant {:?} (frac {})",
                    sf.mul_kind[i],
                    sf.frac[i],
                    cf.mul_kind.get(i).copied().flatten(),
                    cf.frac.get(i).copied().unwrap_or(0)
                );
            }
        }
    }
    println!(
        "MULS/high/64-bit products: constant {:?}, run-time {:?}",
        cf.mul_forms(),
        sf.mul_forms()
    );
    if let Some(dir) = std::env::var_os("TACTUS_LISTINGS") {
        // Both listings, to see where the cycles go (`diff` them).
        let dir = Path::new(&dir);
        std::fs::write(dir.join("piano-constant.s"), &constant.thumb.code.listing).unwrap();
        std::fs::write(dir.join("piano-runtime.s"), &programs[0].thumb.code.listing).unwrap();
    }
    println!(
        "code: constant {} bytes, shared {} bytes",
        constant.thumb.code.text.len(),
        programs[0].thumb.code.text.len()
    );
}

/// Twenty graded piano keys on one 200 MHz board, ten per core: one piano code per core, and
/// the image fits its banks (twenty copies, one per parameter set, did not).
#[test]
fn twenty_graded_piano_keys_fit_a_board_with_one_code_copy_per_core() {
    let (_, programs, index) = grand88();
    let b = layouts::shipped_board("rp2040_200mhz");
    let keys: Vec<KeySpec> = (0..20)
        .map(|i| KeySpec {
            slot: 21 + i,
            program: index[i],
            core: i % 2,
        })
        .collect();
    let lim = LimiterConfig::for_board(&b);
    let image = FirmwareImage::build(&programs, &keys, &b, &lim).unwrap();
    for core in 0..2 {
        assert_eq!(image.code_copies(core), 1, "core {core}");
        println!(
            "core {core}: {} keys, {} bytes of code",
            image.core_keys(core).len(),
            image.code_bytes(core)
        );
    }
    // The code bytes are one piano's text plus the glue, far below twenty copies.
    assert!(
        (image.code_bytes(0) as usize) < 2 * programs[0].thumb.code.text.len() + 8192,
        "{}",
        image.code_bytes(0)
    );
}
