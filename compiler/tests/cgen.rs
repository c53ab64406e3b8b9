//! The C backend against the fixed interpreter, bit for bit: every instrument, every
//! built-in stimulus, and random raw sensor words (in and far out of range), compiled with
//! the host `cc -std=c99 -O2 -Wall -Wextra -Werror` and run in one process per instrument.
//! Compared on every sample: each force term's raw word, the total, the outputs, the
//! emitted events with their arguments, the states and the modes.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use tactus_compiler::cgen::{self, CSource};
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::lower::Config;
use tactus_runtime::rng::XorShift64;
use tactus_runtime::stimulus;

#[path = "support/shipped.rs"]
mod shipped;

/// The instruments: every `instruments/*.tactus` and `instruments/experimental/*.tactus`
/// (named `experimental/STEM`).
fn instruments() -> Vec<(String, String)> {
    shipped::instrument_sources(true)
}

fn have_cc() -> bool {
    Command::new("cc")
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// Writes the generated files and a driver; compiles them. The driver reads records
/// `[reset, sensor words...]` of native-endian `int32_t` from stdin and writes, per record,
/// `out[]`, then the states, then the modes.
fn build(dir: &Path, fp: &FixedProgram, c: &CSource) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let st = &c.stem;
    std::fs::write(dir.join(format!("{st}.h")), &c.header).unwrap();
    std::fs::write(dir.join(format!("{st}.c")), &c.source).unwrap();
    let p = &fp.program;
    let (ns, nst, nm, len) = (p.sensors.len(), p.states.len(), p.modes.len(), c.layout.len);
    let driver = format!(
        r#"#include <stdio.h>
#include "{st}.h"
int main(void) {{
    static struct tactus_{st}_state s;
    int32_t rec[1 + {ns}];
    int32_t out[{len} + {nst} + {nm} + 1];
    int i;
    tactus_{st}_init(&s);
    while (fread(rec, sizeof rec[0], 1 + {ns}, stdin) == 1 + {ns}) {{
        if (rec[0]) tactus_{st}_init(&s);
        tactus_{st}_update(&s, rec + 1, out);
        for (i = 0; i < {nst}; i++) out[{len} + i] = s.states[i];
        for (i = 0; i < {nm}; i++) out[{len} + {nst} + i] = s.modes[i];
        fwrite(out, sizeof out[0], {len} + {nst} + {nm}, stdout);
    }}
    return 0;
}}
"#
    );
    std::fs::write(dir.join("driver.c"), driver).unwrap();
    let exe = dir.join("run");
    // gcc -O2 takes over a minute on the 1.3 MB of C of a bowed string (20 000 values);
    // such programs are built with -O1 (15 s), the keyboard instruments with -O2.
    let opt = if p.values.len() > 2_000 { "-O1" } else { "-O2" };
    let o = Command::new("cc")
        .args(["-std=c99", opt, "-Wall", "-Wextra", "-Werror", "-o"])
        .arg(&exe)
        .arg(dir.join("driver.c"))
        .arg(dir.join(format!("{st}.c")))
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "cc failed in {}:\n{}",
        dir.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    exe
}

/// Interpreter work per run (value evaluations): large instruments get shorter runs.
const EVALUATIONS_PER_RUN: usize = 30_000_000;

struct Run {
    label: String,
    records: Vec<Vec<i32>>,
}

#[test]
fn c_matches_the_fixed_interpreter_bit_for_bit() {
    if !have_cc() {
        // Every CI image has `cc` (Rust links with it): there, a missing one fails.
        assert!(std::env::var_os("CI").is_none(), "no cc, and CI is set");
        println!("SKIPPED: no cc");
        return;
    }
    let base = std::env::temp_dir().join(format!("tactus-cgen-test-{}", std::process::id()));
    // One thread per instrument: the interpreter side dominates the time.
    let total_samples: usize = std::thread::scope(|scope| {
        let handles: Vec<_> = instruments()
            .into_iter()
            .map(|(name, text)| {
                let base = &base;
                scope.spawn(move || check_instrument(base, &name, &text, true))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .sum()
    });
    println!("{total_samples} samples compared");
    let _ = std::fs::remove_dir_all(&base);
}

/// Every operation with its corners (division by ranges through zero, exp and sqrt, min/max,
/// abs, negation, comparisons, select, two sensors, modes, d() and d2()), none of which the
/// shipped instruments cover in full; the formats here include the clamped (W0101) ones.
/// A copy of the JIT's `specials.tactus` (so that this test does not move with it), except
/// that `exp(q)` is `exp(min(q, 40))`: for q ≳ 90 `tactus_runtime::fixed::exp` shifts its
/// Q60 sum left by more than 65 bits in `rescale` and the `i128` wraps to a negative word
/// (i32::MIN for e^100), where the rule saturates to i32::MAX, which the C code gives; the
/// primitive test `cgen_prims.rs` checks `exp` on every format against the saturating value.
const SPECIALS: &str = r#"// Special values for engine comparisons: NaN, infinities and signed zeros through every
// operation whose IEEE or Rust semantics has a corner (min/max with NaN, sqrt of negatives
// and of -0, exp overflow, division by zero, comparisons with NaN, saturation of NaN).
// Driven by random readings of a and b, including -0.0, the bounds and NaN (→ lower bound).
instrument specials {
    sensor a: m in [-2 m, 2 m]
    sensor b: m in [-0 m, 2 m]

    mode m { low, high } = low
    state z = 0 m in [-1 m, 1 m]
    state u = 0.5 in [0, 1]

    let q = a / b                       // NaN at 0/0, ±inf at x/0
    let r = b / a

    while a > b { z = q * 1 m }         // NaN and ±inf saturate
    on q != q { emit nan_seen(a = a, b = b) }
    on a < -1 m {
        m = high
        emit low_a(q = q, r = r)
    }
    on a > 1 m { m = low }
    while not (a == b) or u > 0.5 {
        u = exp(min(q, 40))
        emit again(u = u, v = min(q, r))
    }

    dynamics {
        z' = d(a) - d2(b) * 1 s
    }

    force f = if m == high { a * 1 N/m } else { -b * 1 N/m }
    output max_qr = max(q, r)
    output min_qr = min(q, r)
    output max_rq = max(r, q)
    output min_rq = min(r, q)
    output max_ab = max(a, -b)
    output min_ab = min(-a, b)
    output max_0 = max(q, 0)
    output sqrt_ab = sqrt(a * b)
    output sqrt_q = sqrt(q)
    output sqrt_nq = sqrt(-q)
    output exp_q = exp(min(q, 40))
    output abs_q = abs(q)
    output neg_q = -q
    output lt = q < r
    output le = q <= r
    output ne = q != r
    output eq = q == r
    output logic = (a > b and not (q >= r)) or (m == low) != (z > 0 m)
    output sel = if q > r or q != q { q } else { r - q }
    output clamp_q = clamp(q, -1, 1)
    output one_over_sqrt = 1 / sqrt(a * b)
    output one_over_max = 1 / max(-b, a * 0)
}
"#;

#[test]
fn c_matches_the_fixed_interpreter_on_special_operations() {
    if !have_cc() {
        // Every CI image has `cc` (Rust links with it): there, a missing one fails.
        assert!(std::env::var_os("CI").is_none(), "no cc, and CI is set");
        println!("SKIPPED: no cc");
        return;
    }
    let base = std::env::temp_dir().join(format!("tactus-cgen-specials-{}", std::process::id()));
    let n = check_instrument(&base, "specials", SPECIALS, false);
    println!("{n} samples compared");
    let _ = std::fs::remove_dir_all(&base);
}

/// Compiles one instrument to C, runs every built-in stimulus (if `stimuli`) and random
/// words through it and through the fixed interpreter, and asserts equal bits; returns the number of samples.
fn check_instrument(base: &Path, name: &str, text: &str, stimuli: bool) -> usize {
    let p = tactus_compiler::compile(text, &Config::default())
        .unwrap()
        .program;
    let fp = FixedProgram::new(&p);
    let c = cgen::emit_c(&fp).unwrap();
    let exe = build(&base.join(name), &fp, &c);
    let ns = p.sensors.len();
    let cap = p.samples_within(EVALUATIONS_PER_RUN);
    // Stimuli: sensor 0 follows the stimulus, the others sit at their lower bound.
    let mut runs = Vec::new();
    for (stim, _) in stimulus::builtin_names().iter().filter(|_| stimuli) {
        let s = stimulus::builtin(stim, p.sensors[0].range.1, 44_100.0).unwrap();
        let records = s
            .key
            .iter()
            .take(cap)
            .map(|&k| {
                (0..ns)
                    .map(|i| FixedInstance::sensor_raw(&fp, i, if i == 0 { Some(k) } else { None }))
                    .collect()
            })
            .collect();
        runs.push(Run {
            label: format!("{name}/{stim}"),
            records,
        });
    }
    let mut rng = XorShift64::new(0x9E37_79B9_7F4A_7C15 ^ name.len() as u64);
    for r in 0..if stimuli { 8 } else { 24 } {
        let mut prev: Vec<i32> = fp.sensor_raw_range.iter().map(|r| r.0).collect();
        let records = (0..4000.min(cap))
            .map(|_| {
                for (i, w) in prev.iter_mut().enumerate() {
                    *w = rng.sensor_word(*w, fp.sensor_raw_range[i]);
                }
                prev.clone()
            })
            .collect();
        runs.push(Run {
            label: format!("{name}/random{r}"),
            records,
        });
    }
    // One input file for all runs; a reset flag starts each run.
    let mut input = Vec::new();
    for run in &runs {
        for (n, rec) in run.records.iter().enumerate() {
            input.extend_from_slice(&i32::from(n == 0).to_ne_bytes());
            for w in rec {
                input.extend_from_slice(&w.to_ne_bytes());
            }
        }
    }
    let input_path = base.join(name).join("input.bin");
    std::fs::write(&input_path, &input).unwrap();
    let o = Command::new(&exe)
        .stdin(std::fs::File::open(&input_path).unwrap())
        .output()
        .unwrap();
    assert!(o.status.success(), "{name}: the C driver failed");
    let words: Vec<i32> = o
        .stdout
        .chunks_exact(4)
        .map(|b| i32::from_ne_bytes(b.try_into().unwrap()))
        .collect();
    let (len, nst, nm) = (c.layout.len, fp.program.states.len(), p.modes.len());
    let per = len + nst + nm;
    let nrec: usize = runs.iter().map(|r| r.records.len()).sum();
    assert_eq!(words.len(), nrec * per, "{name}: output length");
    let mut mismatches = Vec::new();
    let mut events = 0usize;
    let mut rows = words.chunks_exact(per);
    for run in &runs {
        let mut inst = FixedInstance::new(&fp);
        for (n, rec) in run.records.iter().enumerate() {
            let row = rows.next().unwrap();
            let want = inst.step_raw(rec).clone();
            let l = &c.layout;
            let mut got_events = Vec::new();
            let mut stray = false;
            for site in &l.emits {
                let nargs = p.events[site.event.index()].args.len();
                let args = &row[site.offset + 1..site.offset + 1 + nargs];
                match row[site.offset] {
                    1 => got_events.push((site.event, args.to_vec())),
                    0 => stray |= args.iter().any(|&a| a != 0),
                    _ => stray = true,
                }
            }
            events += want.events.len();
            let ok = row[l.forces..l.forces + p.forces.len()] == want.forces[..]
                && row[l.total] == want.total
                && row[l.outputs..l.outputs + p.outputs.len()] == want.outputs[..]
                && got_events == want.events
                && !stray
                && row[len..len + nst] == *inst.states()
                && row[len + nst..]
                    .iter()
                    .map(|&m| m as u32)
                    .eq(inst.modes().iter().copied());
            if !ok {
                mismatches.push(format!(
                        "{} sample {n} sensors {rec:?}:\n  C:      {:?}\n  interp: forces {:?} total {} outputs {:?} events {:?} states {:?} modes {:?}",
                        run.label,
                        row,
                        want.forces,
                        want.total,
                        want.outputs,
                        want.events,
                        inst.states(),
                        inst.modes()
                    ));
            }
        }
    }
    println!(
        "{name:<16} {} runs, {nrec} samples, {events} events, {} mismatches",
        runs.len(),
        mismatches.len()
    );
    assert!(
        mismatches.is_empty(),
        "{name}: {} mismatching samples; first:\n{}",
        mismatches.len(),
        mismatches[..mismatches.len().min(5)].join("\n")
    );
    nrec
}
