//! The rubbed resonator bank (`instruments/rubbed_bank.tactus`, Onofrei, Fontana, Serafin
//! 2023 as summarised in DESIGN.md): each of the 11 masses rings at its tuning
//! 55 Hz + 27.5 Hz·i after a short rub, the free vibration loses energy at the rate its
//! damping sets, the friction drags the pen back, the fixed-point build follows the f64 build
//! within a measured bound, and the fixed JIT reproduces the fixed interpreter bit for bit.
//!
//! The pen is driven directly through both components of its vector sensor (penetration
//! `pen.z`, rubbing position `pen.x`), sample by sample; `tactus sim`'s key stimuli drive
//! only the first sensor. The friction is the force's x component: the force term
//! `contact.x`, whose axis total is the compiler-generated output `force.x`.

mod common;

use common::smooth_step;
use std::path::Path;
use tactus_compiler::fixed::interp::{FixedInstance, RawOut};
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::interp::Instance;
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config;
use tactus_jit::{FixedJitInstance, FixedJitProgram};
use tactus_runtime::fixed as fx;
use tactus_runtime::rng::XorShift64;
use tactus_runtime::stimulus;

/// The board's sample rate, Hz (the instrument's default).
const FS: f64 = 44_100.0;
/// Number of resonators in the bank (DESIGN.md: 11).
const BANK: usize = 11;
/// Tuning of resonator `i`, Hz: 55 Hz + 27.5 Hz·i (DESIGN.md, the paper's bank). Written here
/// independently of the instrument, so a mistuned file fails.
fn tuning_hz(i: usize) -> f64 {
    55.0 + 27.5 * i as f64
}

/// The stimulus of [`rub_then_release`]: the pen is pressed, rubs, and is lifted while still
/// moving. Press 5 mm deep (1.5 N at the 300 N/m plane) from 40 to 240 ms (20 ms
/// raised-cosine ramps); rubbing at `speed` (mostly 0.1 m/s) from 20 to 300 ms (20 ms
/// raised-cosine blends), from 40 mm. The pen is lifted at:
const LIFTED_S: f64 = 0.26;
/// Everything is still from here on: the masses ring freely.
const FREE_S: f64 = 0.32;
/// Rubbing speed during the contact, m/s.
const RUB_SPEED: f64 = 0.1;
/// Penetration while rubbing, metres.
const PRESS_M: f64 = 0.005;

fn program() -> Program {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("instruments/rubbed_bank.tactus");
    let src = std::fs::read_to_string(&path).unwrap();
    let lowered = tactus_compiler::compile(&src, &Config::default()).unwrap_or_else(|d| {
        panic!(
            "{}",
            tactus_compiler::diagnostics::emit_to_string("rubbed_bank", &src, &d)
        )
    });
    assert!(lowered.warnings.is_empty(), "{:?}", lowered.warnings);
    lowered.program
}

fn fixed_program(p: &Program) -> FixedProgram {
    let fp = FixedProgram::new(p);
    assert!(
        fp.warnings.is_empty(),
        "fixed-point warnings: {:?}",
        fp.warnings
    );
    fp
}

/// Rubbing position at time `t`: the integral of a velocity that blends from 0 to
/// `v` (m/s) over [20, 40] ms, holds, and blends back to 0 over [280, 300] ms. The
/// integral of a raised-cosine blend of length `b` is `v·(τ − b/π·sin(πτ/b))/2`.
fn rub_position(t: f64, v: f64) -> f64 {
    let b = 0.020;
    let ramp = |tau: f64| {
        let tau = tau.clamp(0.0, b);
        v * (tau - b / std::f64::consts::PI * (std::f64::consts::PI * tau / b).sin()) / 2.0
    };
    let up = ramp(t - 0.020);
    let hold = v * (t.clamp(0.040, 0.280) - 0.040);
    let down = if t > 0.280 {
        v * (t.min(0.300) - 0.280) - ramp(t - 0.280)
    } else {
        0.0
    };
    0.040 + up + hold + down
}

/// `[pen.z, pen.x]` readings, SI, for `seconds`: press, rub at `speed` (m/s), lift, then still.
fn rub_then_release(seconds: f64, speed: f64) -> Vec<[f64; 2]> {
    (0..(seconds * FS) as usize)
        .map(|n| {
            let t = n as f64 / FS;
            let press = PRESS_M * (smooth_step(t, 0.040, 0.060) - smooth_step(t, 0.240, LIFTED_S));
            [press, rub_position(t, speed)]
        })
        .collect()
}

fn output_index(p: &Program, name: &str) -> usize {
    p.outputs
        .iter()
        .position(|o| o.name == name)
        .unwrap_or_else(|| panic!("no output {name}"))
}

/// The outputs (SI) of every sample, f64 reference interpreter; also checks that no state
/// write saturated.
fn run_f64(p: &Program, input: &[[f64; 2]]) -> Vec<Vec<f64>> {
    let mut inst = Instance::new(p);
    let outs = input.iter().map(|s| inst.step(s).outputs.clone()).collect();
    assert!(
        inst.saturations().iter().all(|&n| n == 0),
        "a state hit its range: {:?}",
        inst.saturations()
    );
    outs
}

/// One column of a run.
fn column(run: &[Vec<f64>], k: usize) -> Vec<f64> {
    run.iter().map(|o| o[k]).collect()
}

/// Frequency of a free oscillation, Hz: upward zero crossings located by linear
/// interpolation between samples, (crossings − 1) periods over the time from the first to
/// the last.
fn zero_crossing_hz(x: &[f64]) -> f64 {
    let mut times = Vec::new();
    for n in 1..x.len() {
        if x[n - 1] < 0.0 && x[n] >= 0.0 {
            let frac = -x[n - 1] / (x[n] - x[n - 1]);
            times.push((n - 1) as f64 + frac);
        }
    }
    assert!(times.len() >= 10, "only {} crossings", times.len());
    (times.len() - 1) as f64 * FS / (times[times.len() - 1] - times[0])
}

/// (a) After a short rub the pen is lifted; each mass then rings at its own tuning, measured
/// on its velocity output from 0.4 s to 1.4 s (55 to 330 periods), within 0.5 %.
#[test]
fn each_mass_rings_at_its_tuning() {
    let p = program();
    let input = rub_then_release(1.4, RUB_SPEED);
    let run = run_f64(&p, &input);
    let from = (0.4 * FS) as usize;
    let mut report = Vec::new();
    for i in 0..BANK {
        let v = column(&run, output_index(&p, &format!("audio[{i}]")));
        let peak = v[from..].iter().fold(0.0f64, |m, x| m.max(x.abs()));
        // Excited: the rub left a vibration far above the fixed-point LSB (3.7e-9 m/s).
        assert!(
            peak > 1e-4,
            "mass {i} barely moves after the rub: {peak} m/s"
        );
        let f = zero_crossing_hz(&v[from..]);
        let err = (f - tuning_hz(i)) / tuning_hz(i);
        report.push(format!("{i}: {f:.4} Hz ({:+.4} %)", 100.0 * err));
        assert!(
            err.abs() < 0.005,
            "mass {i}: {f} Hz, tuned {} Hz ({:+.3} %)",
            tuning_hz(i),
            100.0 * err
        );
    }
    println!("measured frequencies: {}", report.join(", "));
}

/// Σᵢ vᵢ² averaged over `[t, t + 0.2 s)`: 0.2 s is 11 periods of the lowest mode, so the
/// average of each sin² is within 1.5 % of ½ whatever the phase.
fn mean_square_sum(run: &[Vec<f64>], audio: &[usize], t: f64) -> f64 {
    let (a, b) = ((t * FS) as usize, ((t + 0.2) * FS) as usize);
    run[a..b]
        .iter()
        .map(|o| audio.iter().map(|&k| o[k] * o[k]).sum::<f64>())
        .sum::<f64>()
        / (b - a) as f64
}

/// (b) Without excitation the bank loses energy: Σ vᵢ² 0.5 s after the pen has gone is
/// strictly lower than right after, in every 0.1 s step, and by the factor the damping sets:
/// each velocity decays as exp(−t/τ) (R = 2M/τ, τ = 1 s in the file), so the mean square by
/// exp(−2·0.5/τ) = 0.368; allowed ±5 % (window averaging).
#[test]
fn energy_decays_without_excitation() {
    let p = program();
    let input = rub_then_release(FREE_S + 0.8, RUB_SPEED);
    let run = run_f64(&p, &input);
    let audio: Vec<usize> = (0..BANK)
        .map(|i| output_index(&p, &format!("audio[{i}]")))
        .collect();
    let tau = p
        .params
        .iter()
        .find(|x| x.name == "r[0].tau")
        .expect("param r[0].tau")
        .value;
    let e: Vec<f64> = (0..=5)
        .map(|k| mean_square_sum(&run, &audio, FREE_S + 0.1 * k as f64))
        .collect();
    assert!(e[0] > 1e-6, "the rub did not excite the bank: {e:?}");
    for w in e.windows(2) {
        assert!(w[1] < w[0], "energy did not decrease: {e:?}");
    }
    let ratio = e[5] / e[0];
    let want = (-2.0 * 0.5 / tau).exp();
    println!("mean-square ratio over 0.5 s: {ratio:.4} (exp(-2·0.5 s/τ) = {want:.4})");
    assert!(
        (ratio / want - 1.0).abs() < 0.05,
        "energy ratio {ratio}, damping gives {want}"
    );
}

/// While the pen rubs forwards faster than the masses can follow, friction drags it back:
/// the friction output is negative on average during the contact, never larger than the
/// normal force (|φ| ≤ 1 and the 11 contacts share the normal force), and zero once lifted.
#[test]
fn friction_drags_the_pen_back() {
    let p = program();
    let input = rub_then_release(0.4, RUB_SPEED);
    let mut inst = Instance::new(&p);
    let fr = output_index(&p, "force.x");
    let plane = p.forces.iter().position(|f| f.name == "contact.z").unwrap();
    let (mut sum, mut n) = (0.0, 0);
    for (k, s) in input.iter().enumerate() {
        let out = inst.step(s);
        let (f, normal) = (out.outputs[fr], out.forces[plane]);
        assert!(
            f.abs() <= normal * (1.0 + 1e-12) + 1e-15,
            "sample {k}: friction {f} N above the normal force {normal} N"
        );
        let t = k as f64 / FS;
        if (0.1..0.2).contains(&t) {
            sum += f;
            n += 1;
        }
        if t >= LIFTED_S {
            assert_eq!(f, 0.0, "friction after the lift at {t} s");
        }
    }
    let mean = sum / n as f64;
    let normal = 300.0 * PRESS_M;
    println!("mean friction while rubbing: {mean:.4} N (normal {normal} N)");
    assert!(
        mean < -0.05 * normal,
        "mean friction {mean} N while rubbing forwards"
    );
}

/// Fixed-point RMS floor, m/s: a mass is compared in (c) only when its f64 velocity RMS in
/// the free ringing is above this. The fixed build sees a mass velocity with about 2⁻¹³ m/s
/// resolution where the position integrates it (the plan's pre-shifted `MULS` of `h·v`, from
/// the ±2 m/s range), so a mass ringing at a few 10⁻⁴ m/s sticks instead of ringing; 10⁻³ m/s
/// is 8 of those steps.
const FIXED_RMS_FLOOR: f64 = 1e-3;

/// Runs both interpreters over `input`: (f64 outputs, fixed outputs in SI).
fn both(p: &Program, fp: &FixedProgram, input: &[[f64; 2]]) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let want = run_f64(p, input);
    let mut fixed = FixedInstance::new(fp);
    let got = input
        .iter()
        .map(|s| fixed.step(s).to_si(fp).outputs)
        .collect();
    assert!(fixed.saturations().iter().all(|&n| n == 0));
    assert!(
        fixed.overflowed().iter().all(|&o| !o),
        "a fixed-point value saturated"
    );
    (want, got)
}

fn rms(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// (c) The fixed-point build follows the f64 build. The precision report gives the bank's
/// integrated states no finite bound, so the bounds are measured, on two rubs:
///
/// * a slow rub (0.02 m/s, below the 7.07 cm/s where φ peaks, so friction damps differences
///   instead of amplifying them): the friction output within 1 % of its peak on every
///   sample (measured 0.45 %);
/// * both that rub and the 0.1 m/s stick-slip rub: every mass ringing above
///   `FIXED_RMS_FLOOR` rings in fixed point at the f64 build's frequency within 0.1 %
///   (measured ≤ 0.0075 %, 110 Hz at the slow rub; ≤ 0.002 % at 0.1 m/s) and with its RMS
///   (0.4 s to 1.4 s) within 5 % (measured ≤ 1.1 %); the friction's mean over the contact
///   within 5 % (measured 0.42 % and 0.17 %). At the slow rub only the three lowest masses
///   ring above the floor (the others at 0.3 to 5·10⁻⁴ m/s RMS are not compared).
///
/// Stick-slip is not compared sample by sample: on its negative-slope branch friction
/// amplifies any difference, and the f64 build itself departs by more than 1 % of the
/// friction's peak when the normal force is changed by 10⁻³ (asserted below; measured 8 %;
/// the fixed build departs by 23 %).
#[test]
fn fixed_point_follows_f64() {
    let p = program();
    let fp = fixed_program(&p);
    let fr = output_index(&p, "force.x");
    let from = (0.4 * FS) as usize;
    let contact = ((0.06 * FS) as usize, (0.24 * FS) as usize);
    for speed in [0.02, RUB_SPEED] {
        let input = rub_then_release(1.4, speed);
        let (want, got) = both(&p, &fp, &input);

        let (fw, fg) = (column(&want, fr), column(&got, fr));
        let peak = fw.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let err = fw
            .iter()
            .zip(&fg)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
        let (mw, mg) = (
            mean(&fw[contact.0..contact.1]),
            mean(&fg[contact.0..contact.1]),
        );
        println!(
            "{speed} m/s: friction peak {peak:.4} N, max |fixed − f64| {err:.3e} N ({:.2} %), mean in contact {mw:.4} / {mg:.4} N",
            100.0 * err / peak
        );
        if speed < 0.05 {
            assert!(
                err < 0.01 * peak,
                "friction differs by {err} N, peak {peak} N"
            );
        }
        assert!(
            (mg / mw - 1.0).abs() < 0.05,
            "{speed} m/s: mean friction {mg} N fixed vs {mw} N f64"
        );

        let mut compared = 0;
        for i in 0..BANK {
            let k = output_index(&p, &format!("audio[{i}]"));
            let (a, b) = (&column(&want, k)[from..], &column(&got, k)[from..]);
            let (ra, rb) = (rms(a), rms(b));
            if ra < FIXED_RMS_FLOOR {
                println!("{speed} m/s: audio{i} RMS {ra:.2e} m/s, below the fixed-point floor: not compared");
                continue;
            }
            compared += 1;
            let (fa, fb) = (zero_crossing_hz(a), zero_crossing_hz(b));
            println!(
                "{speed} m/s: audio{i} f64 {fa:.4} Hz, fixed {fb:.4} Hz ({:+.4} %); RMS {ra:.4e} / {rb:.4e} m/s ({:+.2} %)",
                100.0 * (fb / fa - 1.0),
                100.0 * (rb / ra - 1.0)
            );
            assert!((fb / fa - 1.0).abs() < 1e-3, "audio{i}: {fb} Hz vs {fa} Hz");
            assert!((fb / tuning_hz(i) - 1.0).abs() < 0.005, "audio{i}: {fb} Hz");
            assert!((rb / ra - 1.0).abs() < 0.05, "audio{i}: RMS {rb} vs {ra}");
        }
        // The slow rub excites the low masses only; the stick-slip rub all of them.
        assert!(
            compared >= if speed < 0.05 { 3 } else { BANK },
            "{compared}"
        );
    }

    // Why stick-slip is compared by statistics: the f64 build against itself, with the
    // normal force 10⁻³ larger, departs by more than 1 % of the friction's peak.
    let input = rub_then_release(0.4, RUB_SPEED);
    let pushed: Vec<[f64; 2]> = input.iter().map(|s| [s[0] * 1.001, s[1]]).collect();
    let (a, b) = (run_f64(&p, &input), run_f64(&p, &pushed));
    let peak = a.iter().fold(0.0f64, |m, r| m.max(r[fr].abs()));
    let err = a
        .iter()
        .zip(&b)
        .fold(0.0f64, |m, (x, y)| m.max((x[fr] - y[fr]).abs()));
    println!(
        "f64, normal force +0.1 %: friction departs by {:.1} % of its peak",
        100.0 * err / peak
    );
    assert!(err > 0.01 * peak, "stick-slip not sensitive: {err} N");
}

/// Runs the fixed interpreter and the fixed JIT side by side on raw sensor rows and
/// compares every raw force, the total, every output and every state word, every sample.
fn compare_bits(fp: &FixedProgram, jit: &FixedJitProgram, rows: &[Vec<i32>], what: &str) {
    let mut interp = FixedInstance::new(fp);
    let mut native = FixedJitInstance::new(jit);
    for (n, row) in rows.iter().enumerate() {
        let want: RawOut = interp.step_raw(row).clone();
        let got = native.step_raw(row);
        assert_eq!(&want, got, "{what}: sample {n}");
        assert_eq!(
            interp.states(),
            native.states(),
            "{what}: states, sample {n}"
        );
    }
    assert_eq!(interp.saturations(), native.saturations(), "{what}");
}

fn raw_rows(fp: &FixedProgram, input: &[[f64; 2]]) -> Vec<Vec<i32>> {
    input
        .iter()
        .map(|s| {
            (0..2)
                .map(|i| FixedInstance::sensor_raw(fp, i, Some(s[i])))
                .collect()
        })
        .collect()
}

/// Samples per stimulus in (d): 0.3 s.
const BIT_SAMPLES: usize = 13_230;

/// (d) The fixed JIT and the fixed interpreter agree bit for bit (every raw force, total,
/// output and state word, every sample): on the rub stimulus (0.5 s); on the first 0.3 s of
/// each built-in key stimulus pressing the pen (dip = the press sensor's 10 mm range) while
/// it rubs back and forth at up to 0.25 m/s; and on 0.3 s of random raw words (a random walk
/// with jumps, and `i32::MIN`/`MAX`, outside the sensors' ranges).
#[test]
fn fixed_jit_matches_fixed_interpreter_bit_for_bit() {
    let p = program();
    let fp = fixed_program(&p);
    let jit = FixedJitProgram::compile(&fp).expect("fixed JIT");

    compare_bits(
        &fp,
        &jit,
        &raw_rows(&fp, &rub_then_release(0.5, RUB_SPEED)),
        "rub",
    );

    for (name, _) in stimulus::builtin_names() {
        let s = stimulus::builtin(name, 0.010, FS).unwrap();
        // A back-and-forth rub, 4 Hz, ±10 mm: up to 2π·4·0.01 = 0.25 m/s. The first 0.3 s
        // of each stimulus (its press), to keep the test short in debug builds.
        let input: Vec<[f64; 2]> = s
            .key
            .iter()
            .take(BIT_SAMPLES)
            .enumerate()
            .map(|(n, &k)| {
                let t = n as f64 / FS;
                [
                    k,
                    0.080 + 0.010 * (2.0 * std::f64::consts::PI * 4.0 * t).sin(),
                ]
            })
            .collect();
        compare_bits(&fp, &jit, &raw_rows(&fp, &input), name);
    }

    let mut rng = XorShift64::new(0x00B0_5EED);
    let (lo, hi): (Vec<i64>, Vec<i64>) = fp
        .sensor_raw_range
        .iter()
        .map(|&(l, h)| (i64::from(l), i64::from(h)))
        .unzip();
    let mut x: Vec<i64> = lo.iter().zip(&hi).map(|(l, h)| (l + h) / 2).collect();
    let rows: Vec<Vec<i32>> = (0..BIT_SAMPLES)
        .map(|_| {
            (0..2)
                .map(|i| {
                    let span = hi[i] - lo[i];
                    x[i] = match rng.below(100) {
                        0 => lo[i] + rng.below(span as usize + 1) as i64,
                        1 => {
                            return if rng.below(2) == 0 {
                                i32::MIN
                            } else {
                                i32::MAX
                            }
                        }
                        _ => {
                            let step = (span / 4000).max(1);
                            (x[i] + rng.below(2 * step as usize + 1) as i64 - step)
                                .clamp(lo[i], hi[i])
                        }
                    };
                    x[i] as i32
                })
                .collect()
        })
        .collect();
    compare_bits(&fp, &jit, &rows, "random words");

    // The comparison saw the bank move, not just zeros.
    let mut interp = FixedInstance::new(&fp);
    let audio0 = output_index(&p, "audio[0]");
    let moved = raw_rows(&fp, &rub_then_release(0.4, RUB_SPEED))
        .iter()
        .any(|r| {
            let out = interp.step_raw(r);
            fx::to_f64(out.outputs[audio0], fp.output_frac[audio0]).abs() > 1e-4
        });
    assert!(moved, "the rub did not move mass 0 in fixed point");
}

/// The side walls at the track's ends push the pen back along x — lifted or pressed, with
/// the plane's stiffness — and nothing between them: lifted and still at 80 mm the pen feels
/// no force along x; 3 mm into either wall it feels 300 N/m × 3 mm = 0.9 N back towards the
/// track, on the force's x axis (`force.x`).
#[test]
fn side_walls_push_the_pen_back_at_the_track_ends() {
    let p = program();
    let fx = output_index(&p, "force.x");
    // Hold the pen lifted at `x` for 0.1 s (the differentiator settles: no rubbing velocity).
    let held = |x: f64| -> f64 {
        let input = vec![[0.0, x]; 4410];
        run_f64(&p, &input).last().unwrap()[fx]
    };
    let (lo, mid, hi) = (held(0.002), held(0.080), held(0.158));
    println!("force.x lifted at 2 mm {lo:.4} N, 80 mm {mid:.4} N, 158 mm {hi:.4} N");
    assert!((lo - 0.9).abs() < 1e-9, "at 2 mm: {lo} N");
    assert_eq!(mid, 0.0, "at 80 mm: {mid} N");
    assert!((hi + 0.9).abs() < 1e-9, "at 158 mm: {hi} N");
}
