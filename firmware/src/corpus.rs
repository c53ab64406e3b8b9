//! The stimulus corpus the budget checker measures an update over: key motions a player
//! makes (soft to hard presses, repeated notes, trills, half dips, reversals in the let-off
//! zone) and what a real sensor adds (noise, glitches, arbitrary words), as raw sensor words
//! per sample.
//!
//! Every run starts from the initial state and is reproducible: the motions are
//! deterministic and the noise comes from [`XorShift64`] with fixed seeds. Key travel is
//! generated in metres at the front of the key, scaled to sensor 0's declared full range
//! (the dip), sampled at [`SAMPLE_RATE_HZ`] (44.1 kHz) and converted to raw words with
//! [`FixedInstance::sensor_raw`] (the conversion every engine shares); the other sensors
//! sit at their lower bound, except in the random runs, which drive every sensor.
//!
//! [`Size::Full`] is what `tactus budget` measures (every built-in stimulus and every
//! sweep below); [`Size::Quick`] keeps one or two examples of each kind (about a fifth of
//! the samples) for `tactus budget --quick`, the param variants of a layout and the
//! debug-build tests.

use crate::measure::{builtin_runs, random_runs, Run, SAMPLE_RATE_HZ};
use tactus_compiler::fixed::FixedProgram;
use tactus_runtime::rng::XorShift64;

/// How much of the corpus to generate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Size {
    /// Every kind with its sweeps (the default of `tactus budget`).
    Full,
    /// One or two runs of each kind, short holds (tests, `--quick`).
    Quick,
    /// One run of each kind and no built-in stimuli, about a quarter of [`Size::Quick`]:
    /// for the many param variants of one instrument in a layout (graded hammer masses),
    /// whose code differs from the fully measured variant only in constants.
    Brief,
}

/// A key motion: waypoints `(seconds from the previous waypoint, travel as a fraction of the
/// dip)` joined by raised-cosine segments (zero speed at each waypoint, peak speed π/2 times
/// the mean, like the cycloidal built-ins), starting at rest.
fn motion(label: &str, dip_m: f64, points: &[(f64, f64)]) -> (String, Vec<f64>) {
    let mut key = Vec::new();
    let mut x0 = 0.0;
    for &(dt, x1) in points {
        let n = (dt * SAMPLE_RATE_HZ).round().max(1.0) as usize;
        for i in 1..=n {
            let u = i as f64 / n as f64;
            let w = 0.5 - 0.5 * (std::f64::consts::PI * u).cos();
            key.push(dip_m * (x0 + (x1 - x0) * w));
        }
        x0 = x1;
    }
    (label.to_string(), key)
}

/// Full dips from very soft to very hard: descent times (rest to bottom), ms.
const DESCENTS_MS: [f64; 8] = [12.0, 18.0, 25.0, 35.0, 50.0, 80.0, 120.0, 200.0];

/// Presses from rest to the bottom with descent times from 12 ms (a hard blow) to 200 ms
/// (barely audible), each held, released and followed by a rest for the action to settle.
pub fn presses(dip_m: f64, size: Size) -> Vec<(String, Vec<f64>)> {
    let descents: &[f64] = match size {
        Size::Full => &DESCENTS_MS,
        Size::Quick => &[12.0, 80.0],
        Size::Brief => &[12.0],
    };
    let hold = if size == Size::Full { 0.15 } else { 0.05 };
    descents
        .iter()
        .map(|&ms| {
            motion(
                &format!("press-{ms}ms"),
                dip_m,
                &[
                    (0.005, 0.0),
                    (ms / 1e3, 1.0),
                    (hold, 1.0),
                    (0.04, 0.0),
                    (0.15, 0.0),
                ],
            )
        })
        .collect()
}

/// Repeated notes: `n` presses at `rate` notes/s, releasing to `back` of the dip between
/// them (a partial release re-arms the repetition lever without a full return), then a full
/// release.
fn repeated(dip_m: f64, rate: f64, back: f64, n: usize) -> (String, Vec<f64>) {
    let half = 0.5 / rate;
    let mut pts = vec![(0.005, 0.0)];
    for _ in 0..n {
        pts.push((half, 1.0));
        pts.push((half, back));
    }
    pts.push((0.05, 0.0));
    pts.push((0.1, 0.0));
    motion(
        &format!("repeat-{rate}Hz-to-{:.0}%", back * 100.0),
        dip_m,
        &pts,
    )
}

/// Repeated notes (8–16 notes/s, partial releases to 20–60 % of the dip) and trills (one
/// key of a trill: fast shallow alternation near the bottom, 12–20 Hz).
pub fn repetitions(dip_m: f64, size: Size) -> Vec<(String, Vec<f64>)> {
    let cases: &[(f64, f64, usize)] = match size {
        Size::Full => &[
            (8.0, 0.3, 8),
            (12.0, 0.5, 12),
            (16.0, 0.6, 16),
            (10.0, 0.2, 8),
            (14.0, 0.0, 10),
        ],
        Size::Quick => &[(12.0, 0.5, 6)],
        Size::Brief => &[(12.0, 0.5, 4)],
    };
    let mut v: Vec<_> = cases
        .iter()
        .map(|&(r, b, n)| repeated(dip_m, r, b, n))
        .collect();
    let trills: &[(f64, f64)] = match size {
        Size::Full => &[(12.0, 0.7), (16.0, 0.8), (20.0, 0.85)],
        Size::Quick | Size::Brief => &[(16.0, 0.8)],
    };
    for &(rate, low) in trills {
        let (_, key) = repeated(dip_m, rate, low, (rate as usize).max(4));
        v.push((format!("trill-{rate}Hz-{:.0}%", low * 100.0), key));
    }
    v
}

/// Partial dips that stop at 30–97 % of the dip, some with reversals inside the let-off zone
/// (85–95 %: the escapement's hold and return paths) and a slow creep through it.
pub fn half_dips(dip_m: f64, size: Size) -> Vec<(String, Vec<f64>)> {
    let depths: &[f64] = match size {
        Size::Full => &[0.3, 0.5, 0.7, 0.8, 0.85, 0.88, 0.9, 0.92, 0.95, 0.97],
        Size::Quick => &[0.5, 0.9],
        Size::Brief => &[0.9],
    };
    let hold = if size == Size::Full { 0.1 } else { 0.04 };
    let mut v: Vec<_> = depths
        .iter()
        .map(|&d| {
            motion(
                &format!("half-dip-{:.0}%", d * 100.0),
                dip_m,
                &[(0.005, 0.0), (0.03, d), (hold, d), (0.05, 0.0), (0.1, 0.0)],
            )
        })
        .collect();
    v.push(motion(
        "letoff-reversals",
        dip_m,
        &[
            (0.005, 0.0),
            (0.04, 0.9),
            (0.01, 0.86),
            (0.01, 0.93),
            (0.01, 0.88),
            (0.02, 1.0),
            (0.02, 0.87),
            (0.02, 0.95),
            (0.05, 0.0),
            (0.1, 0.0),
        ],
    ));
    if size == Size::Full {
        v.push(motion(
            "letoff-creep",
            dip_m,
            &[
                (0.005, 0.0),
                (0.05, 0.8),
                (0.5, 0.97),
                (0.05, 0.0),
                (0.1, 0.0),
            ],
        ));
    }
    v
}

/// Sensor noise: a medium press with uniform noise of ±`amp` of the dip added to every
/// sample (clamped to the sensor range by the conversion), and noise on a key at rest. The
/// full corpus's top level is the noise the sensor check allows
/// ([`crate::image::fault::SENSOR_NOISE_FRACTION`]): it must trip no key.
pub fn noisy(dip_m: f64, size: Size, seed: u64) -> Vec<(String, Vec<f64>)> {
    let amps: &[f64] = match size {
        Size::Full => &[0.001, 0.005, crate::image::fault::SENSOR_NOISE_FRACTION],
        Size::Quick | Size::Brief => &[0.005],
    };
    let mut rng = XorShift64::new(seed);
    let mut v = Vec::new();
    for &amp in amps {
        for (label, base) in [
            motion(
                "press",
                dip_m,
                &[
                    (0.005, 0.0),
                    (0.04, 1.0),
                    (0.1, 1.0),
                    (0.04, 0.0),
                    (0.1, 0.0),
                ],
            ),
            motion("rest", dip_m, &[(0.1, 0.0)]),
        ] {
            let key = base
                .iter()
                .map(|&x| x + dip_m * amp * (2.0 * rng.unit() - 1.0))
                .collect();
            v.push((format!("noisy-{label}-{:.1}%", amp * 100.0), key));
        }
    }
    v
}

/// Glitches on sensor 0's raw word during a hard press: every `every`-th sample (jittered)
/// is replaced by a corner word (`i32::MIN`, `i32::MAX`, the bounds, one past each, 0), a
/// dropout to the lower bound, or a spike to the upper bound; the other samples are the
/// clean press.
pub fn glitches(fp: &FixedProgram, size: Size, seed: u64) -> Vec<Run> {
    let Some(s0) = fp.program.sensors.first() else {
        return Vec::new();
    };
    let (lo, hi) = fp.sensor_raw_range[0];
    let everies: &[usize] = match size {
        Size::Full => &[7, 50, 400],
        Size::Quick | Size::Brief => &[50],
    };
    let mut rng = XorShift64::new(seed);
    let (_, key) = motion(
        "press",
        s0.range.1,
        &[
            (0.005, 0.0),
            (0.02, 1.0),
            (0.1, 1.0),
            (0.03, 0.4),
            (0.02, 1.0),
            (0.04, 0.0),
            (0.1, 0.0),
        ],
    );
    everies
        .iter()
        .map(|&every| {
            let mut run = crate::measure::key_run(fp, format!("glitch-every-{every}"), &key);
            let mut next = every;
            for (i, rec) in run.records.iter_mut().enumerate() {
                if i == next {
                    rec[0] = rng.corner_word((lo, hi));
                    next += 1 + every / 2 + rng.below(every);
                }
            }
            run
        })
        .collect()
}

/// The built-in stimuli of [`Size::Quick`] (the others are dips at other speeds, which
/// [`presses`] covers, and the 4-second `slow-dip`).
const QUICK_BUILTINS: [&str; 3] = ["ff-dip", "half-dip", "repeated"];

/// The whole corpus for `fp` at `size`: the built-in stimuli ([`builtin_runs`]; in
/// [`Size::Quick`] only `ff-dip`, `half-dip` and `repeated`; none in [`Size::Brief`]), [`presses`], [`repetitions`],
/// [`half_dips`], [`noisy`], [`glitches`] and adversarial random words
/// ([`random_runs`]: 8 × 4000 samples, 2 × 2000 in quick, 1 × 2000 in brief). Deterministic: the same
/// program and size give the same runs. A program without sensors gets the random runs only
/// (which are then empty records).
pub fn corpus(fp: &FixedProgram, size: Size) -> Vec<Run> {
    let mut runs: Vec<Run> = builtin_runs(fp)
        .into_iter()
        .filter(|r| match size {
            Size::Full => true,
            Size::Quick => QUICK_BUILTINS.contains(&r.label.as_str()),
            Size::Brief => false,
        })
        .collect();
    if let Some(s0) = fp.program.sensors.first() {
        let dip = s0.range.1;
        let motions = presses(dip, size)
            .into_iter()
            .chain(repetitions(dip, size))
            .chain(half_dips(dip, size))
            .chain(noisy(dip, size, 0x7ac7_0500));
        runs.extend(motions.map(|(label, key)| crate::measure::key_run(fp, label, &key)));
        runs.extend(glitches(fp, size, 0x6117_c400));
    }
    let (n, len) = match size {
        Size::Full => (8, 4000),
        Size::Quick => (2, 2000),
        Size::Brief => (1, 2000),
    };
    runs.extend(random_runs(fp, 0x5eed_b0d6, n, len));
    runs
}

/// Whether a corpus run of this label feeds the sensor implausible words by design:
/// `glitch-…` ([`glitches`]: corner words, dropouts, spikes) and `random…` (adversarial
/// words, [`random_runs`]). The others are motions a key makes (with a real sensor's
/// noise), which the firmware's sensor check must let through (`tactus corpus trips`).
pub fn by_design(label: &str) -> bool {
    label.starts_with("glitch") || label.starts_with("random")
}

/// Samples in a set of runs.
pub fn samples(runs: &[Run]) -> usize {
    runs.iter().map(|r| r.records.len()).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use tactus_compiler::lower::Config;

    fn piano() -> FixedProgram {
        let src = include_str!("../../instruments/grand_piano.tactus");
        let l = tactus_compiler::compile(src, &Config::default()).unwrap();
        FixedProgram::new(&l.program)
    }

    #[test]
    fn corpus_is_deterministic_and_covers_every_kind() {
        let fp = piano();
        let a = corpus(&fp, Size::Quick);
        let b = corpus(&fp, Size::Quick);
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(&b) {
            assert_eq!((&x.label, &x.records), (&y.label, &y.records));
        }
        for kind in [
            "ff-dip",
            "press-",
            "repeat-",
            "trill-",
            "half-dip-",
            "letoff-",
            "noisy-",
            "glitch-",
            "random",
        ] {
            assert!(
                a.iter().any(|r| r.label.starts_with(kind)),
                "no {kind} run in {:?}",
                a.iter().map(|r| &r.label).collect::<Vec<_>>()
            );
        }
        let full = corpus(&fp, Size::Full);
        assert!(full.len() > 2 * a.len() && samples(&full) > 4 * samples(&a));
        let brief = corpus(&fp, Size::Brief);
        assert!(samples(&brief) < samples(&a));
        println!(
            "brief {} samples, quick {}, full {}",
            samples(&brief),
            samples(&a),
            samples(&full)
        );
    }

    #[test]
    fn motions_stay_in_the_dip_and_reach_their_targets() {
        let (_, key) = motion("m", 0.01, &[(0.01, 1.0), (0.01, 0.5)]);
        assert_eq!(key.len(), 882);
        assert!(key.iter().all(|&x| (0.0..=0.01 + 1e-12).contains(&x)));
        assert!((key[440] - 0.01).abs() < 1e-12);
        assert!((key[881] - 0.005).abs() < 1e-12);
        // Hard presses are faster than soft ones: peak speed of the descent (the first
        // 5 ms + descent time), 200 ms / 12 ms apart.
        let p = presses(0.01, Size::Full);
        let peak = |k: &[f64], ms: f64| {
            let n = ((5.0 + ms) * 44.1) as usize;
            k[..n]
                .windows(2)
                .map(|w| (w[1] - w[0]).abs())
                .fold(0.0, f64::max)
        };
        let (first, last) = (DESCENTS_MS[0], DESCENTS_MS[DESCENTS_MS.len() - 1]);
        assert!(peak(&p[0].1, first) > 15.0 * peak(&p[p.len() - 1].1, last));
    }

    #[test]
    fn glitches_hit_corner_words() {
        let fp = piano();
        let (lo, hi) = fp.sensor_raw_range[0];
        let g = glitches(&fp, Size::Full, 1);
        let words: Vec<i32> = g[0].records.iter().map(|r| r[0]).collect();
        assert!(words.contains(&i32::MIN) || words.contains(&i32::MAX));
        assert!(words.iter().any(|&w| w < lo || w > hi));
    }
}
