//! The bowed strings (`instruments/bowed_string.tactus`, Onofrei, Fontana, Serafin 2023 as
//! summarised in DESIGN.md): a bow stroke at a moderate force and speed settles into periodic
//! stick–slip at the string's fundamental; too little force gives no sustained oscillation;
//! the compile-time stability and uniqueness conditions reject bad params with the numbers.
//!
//! The pen drives all three components of its vector sensor (penetration `pen.z`, bow
//! position `pen.x`, position across the strings `pen.y`) sample by sample. The f64 JIT is used for speed; it computes the
//! reference interpreter's values bit for bit (`compiler/jit/tests`).

mod common;

use common::partial_hz;
use std::path::Path;
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config;
use tactus_jit::{JitInstance, JitProgram};

/// The board's sample rate, Hz (the instrument's default).
const FS: f64 = 44_100.0;
/// The G string's tuning, Hz (G3), written here independently of the instrument.
const G3_HZ: f64 = 196.0;
/// The pen over the G string (0–10 mm across).
const OVER_G_M: f64 = 0.005;

fn source() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("instruments/bowed_string.tactus");
    std::fs::read_to_string(path).unwrap()
}

fn program() -> Program {
    let src = source();
    let lowered = tactus_compiler::compile(&src, &Config::default()).unwrap_or_else(|d| {
        panic!(
            "{}",
            tactus_compiler::diagnostics::emit_to_string("bowed_string", &src, &d)
        )
    });
    assert!(lowered.warnings.is_empty(), "{:?}", lowered.warnings);
    lowered.program
}

/// A raised-cosine step from 0 to 1 between `t0` and `t1`.
fn smooth_step(t: f64, t0: f64, t1: f64) -> f64 {
    let u = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    0.5 - 0.5 * (std::f64::consts::PI * u).cos()
}

/// One bow stroke on the G string: the pen presses to `depth` (m) over [10, 40] ms and lifts
/// over [`lift`, `lift` + 20 ms]; the bow accelerates to `speed` (m/s) over [0, 30] ms from
/// 5 mm and keeps moving. Readings `[pen.z, pen.x, pen.y]`, SI, for `seconds`.
fn stroke(seconds: f64, depth: f64, speed: f64, lift: f64) -> Vec<[f64; 3]> {
    let b = 0.030;
    (0..(seconds * FS) as usize)
        .map(|n| {
            let t = n as f64 / FS;
            let press = depth * (smooth_step(t, 0.010, 0.040) - smooth_step(t, lift, lift + 0.020));
            // ∫ of a raised-cosine blend of length b to `speed`, then constant speed.
            let tau = t.min(b);
            let ramp = speed
                * (tau - b / std::f64::consts::PI * (std::f64::consts::PI * tau / b).sin())
                / 2.0;
            let bow = 0.005 + ramp + speed * (t - b).max(0.0);
            [press, bow.min(0.16), OVER_G_M]
        })
        .collect()
}

fn output_index(p: &Program, name: &str) -> usize {
    p.outputs
        .iter()
        .position(|o| o.name == name)
        .unwrap_or_else(|| panic!("no output {name}"))
}

/// Outputs of every sample; also checks that no state write saturated.
fn run(p: &Program, input: &[[f64; 3]]) -> Vec<Vec<f64>> {
    let jit = JitProgram::compile(p).expect("JIT");
    let mut inst = JitInstance::new(&jit);
    let outs = input.iter().map(|s| inst.step(s).outputs.clone()).collect();
    assert!(
        inst.saturations().iter().all(|&n| n == 0),
        "a state hit its range: {:?}",
        inst.saturations()
    );
    outs
}

fn column(run: &[Vec<f64>], k: usize, from_s: f64, to_s: f64) -> Vec<f64> {
    run[(from_s * FS) as usize..(to_s * FS) as usize]
        .iter()
        .map(|o| o[k])
        .collect()
}

fn rms(x: &[f64]) -> f64 {
    let m = x.iter().sum::<f64>() / x.len() as f64;
    (x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / x.len() as f64).sqrt()
}

/// Normalised autocorrelation of `x` at `lag` samples (1 for a signal that repeats exactly).
fn autocorrelation(x: &[f64], lag: usize) -> f64 {
    let m = x.iter().sum::<f64>() / x.len() as f64;
    let x: Vec<f64> = x.iter().map(|v| v - m).collect();
    let n = x.len() - lag;
    let s: f64 = (0..n).map(|i| x[i] * x[i + lag]).sum();
    let e0: f64 = x[..n].iter().map(|v| v * v).sum();
    let e1: f64 = x[lag..].iter().map(|v| v * v).sum();
    s / (e0 * e1).sqrt()
}

/// Slip onsets per second: |v_rel| rises above 2× the friction peak 1/√(2a) after having been
/// below it (sticking). Hysteresis keeps a noisy transition from counting twice.
fn slips_per_second(vrel: &[f64]) -> f64 {
    let peak = 1.0 / (2.0f64 * 100.0).sqrt();
    let (mut stuck, mut slips) = (false, 0usize);
    for v in vrel {
        if v.abs() < peak {
            stuck = true;
        } else if stuck && v.abs() > 2.0 * peak {
            stuck = false;
            slips += 1;
        }
    }
    slips as f64 * FS / vrel.len() as f64
}

/// A stroke at 22 mN (80 % depth) and 0.1 m/s on the G string: during the stroke the bridge
/// force is periodic (autocorrelation over one period ≥ 0.95) at the string's fundamental —
/// the first mode of the same string ringing freely after the bow is lifted, and the tuning —
/// within 1 %; the relative velocity alternates between sticking (|v_rel| below the friction
/// peak 1/√(2a) = 7 cm/s) and slipping, at least once per period.
#[test]
fn moderate_bowing_settles_into_stick_slip_at_the_fundamental() {
    let p = program();
    let input = stroke(0.95, 0.008, 0.10, 0.70);
    let out = run(&p, &input);
    let bridge = output_index(&p, "audio_g");
    let vrel = output_index(&p, "vrel");
    let bowed = column(&out, bridge, 0.40, 0.70);
    let f_bowed = partial_hz(&bowed, G3_HZ, FS);
    let corr = autocorrelation(&bowed, (FS / f_bowed).round() as usize);
    let free = column(&out, bridge, 0.75, 0.95);
    let f_free = partial_hz(&free, G3_HZ, FS);
    let v = column(&out, vrel, 0.40, 0.70);
    let sticking = v.iter().filter(|x| x.abs() < 0.0707).count() as f64 / v.len() as f64;
    let slips = slips_per_second(&v);
    println!(
        "bowed: {f_bowed:.3} Hz (autocorrelation over one period {corr:.4}), free: {f_free:.3} Hz, \
         tuning {G3_HZ} Hz; bowed/free {:+.3} %, bowed/tuning {:+.3} %; sticking {:.1} % of the \
         time, {slips:.1} slips per second; bridge RMS {:.3e} N",
        100.0 * (f_bowed / f_free - 1.0),
        100.0 * (f_bowed / G3_HZ - 1.0),
        100.0 * sticking,
        rms(&bowed)
    );
    assert!(corr > 0.95, "not periodic: correlation {corr}");
    assert!(
        (f_bowed / f_free - 1.0).abs() < 0.01,
        "{f_bowed} Hz vs {f_free} Hz"
    );
    assert!(
        (f_free / G3_HZ - 1.0).abs() < 0.01,
        "free string at {f_free} Hz"
    );
    // Stick–slip: sticking part of the time, and at least one slip in every period (not
    // steady sliding, not a string dragged along stuck to the bow).
    assert!(sticking > 0.2 && sticking < 0.95, "sticking {sticking}");
    assert!(slips >= 0.99 * f_bowed, "{slips} slips/s at {f_bowed} Hz");
}

/// At 0.28 mN (1 % depth) the same stroke leaves the string nearly still: its bridge force
/// stays below 5 % of the moderate stroke's, and what there is does not build up.
#[test]
fn too_little_force_gives_no_sustained_oscillation() {
    let p = program();
    let bridge = output_index(&p, "audio_g");
    let moderate = run(&p, &stroke(0.6, 0.008, 0.10, 0.70));
    let light = run(&p, &stroke(0.6, 0.0001, 0.10, 0.70));
    let m = rms(&column(&moderate, bridge, 0.40, 0.60));
    let early = rms(&column(&light, bridge, 0.20, 0.40));
    let late = rms(&column(&light, bridge, 0.40, 0.60));
    println!(
        "bridge RMS: moderate {m:.3e} N; light {early:.3e} N (0.2–0.4 s), {late:.3e} N (0.4–0.6 s)"
    );
    assert!(late < 0.05 * m, "light bowing {late} vs moderate {m}");
    assert!(
        late <= early * 1.1,
        "light bowing builds up: {early} → {late}"
    );
}

/// Too fine a grid breaks the FDTD stability bound, and a sticky `a` breaks the uniqueness of
/// the friction solve: both are compile errors that give the two numbers compared.
#[test]
fn stability_and_uniqueness_are_checked_at_compile_time() {
    let src = source();
    let with = |k: &str, v: &str| Config {
        overrides: vec![(k.into(), v.into())],
        ..Config::default()
    };
    for (k, v, what) in [
        ("g.N", "110", "h >= h_min"),
        ("g.a", "15000 s^2/m^2", "uniqueness"),
    ] {
        let diags = tactus_compiler::compile(&src, &with(k, v))
            .err()
            .unwrap_or_else(|| panic!("--param {k}={v} compiled ({what})"));
        let d = diags
            .iter()
            .find(|d| d.code == "E0310")
            .unwrap_or_else(|| panic!("--param {k}={v}: {diags:?}"));
        println!("--param {k}={v}: {}", d.message);
        assert!(
            d.message.chars().filter(|c| c.is_ascii_digit()).count() >= 8,
            "no numbers in {:?}",
            d.message
        );
    }
    // The shipped params pass, and the largest stable grid for G3 is 52 intervals.
    assert!(tactus_compiler::compile(&src, &with("g.N", "102")).is_ok());
    assert!(tactus_compiler::compile(&src, &with("g.N", "103")).is_err());
}
