//! Run-tests of the fixed-point JIT: the fixed interpreter (`tactus_compiler::fixed::interp`,
//! the definition of the bits) and the fixed JIT side by side on the same program and the
//! same sensor words, compared BIT FOR BIT on every sample: every raw force term, the raw
//! total, every raw output, every raw state word, every mode, every saturation count and the
//! event list (kinds, order, raw arguments).
//!
//! Inputs: every instrument in `instruments/` under every built-in stimulus (dip depth = the
//! first sensor's upper bound, SI readings through `FixedInstance::sensor_raw`), and every
//! instrument and `tests/data/*.tactus` under random raw words (`XorShift64`): a random walk
//! inside the raw range, jumps anywhere in it, words far outside it (`i32::MIN`/`MAX`
//! included), missing and extra words. The batched entry point (`run_block`) is checked
//! against the per-sample one on the same inputs.

mod common;
use common::{instruments, load_program, test_programs};
use std::path::Path;
use tactus_compiler::fixed::interp::{FixedInstance, RawOut};
use tactus_compiler::fixed::FixedProgram;
use tactus_jit::{FixedJitInstance, FixedJitProgram};
use tactus_runtime::rng::XorShift64;
use tactus_runtime::stimulus;

fn load(path: &Path) -> FixedProgram {
    FixedProgram::new(&load_program(path))
}

/// What a comparison covered.
#[derive(Debug, Default)]
struct Stats {
    samples: usize,
    /// Raw words compared (forces, total, outputs, states, event arguments).
    words: usize,
    events: usize,
    saturations: u64,
    mismatches: usize,
}

impl Stats {
    fn add(&mut self, o: &Stats) {
        self.samples += o.samples;
        self.words += o.words;
        self.events += o.events;
        self.saturations += o.saturations;
        self.mismatches += o.mismatches;
    }
}

struct Pair<'f, 'j> {
    fp: &'f FixedProgram,
    interp: FixedInstance<'f>,
    jit: FixedJitInstance<'j>,
    stats: Stats,
    what: String,
}

impl Pair<'_, '_> {
    fn compare(&mut self, n: usize, want: &RawOut, got: &RawOut) {
        let p = &self.fp.program;
        let words = want.forces.len()
            + 1
            + want.outputs.len()
            + p.states.len()
            + want.events.iter().map(|(_, a)| a.len()).sum::<usize>();
        self.stats.words += words;
        let same = want == got
            && self.interp.states() == self.jit.states()
            && self.interp.modes() == self.jit.modes()
            && self.interp.saturations() == self.jit.saturations();
        if !same {
            self.stats.mismatches += 1;
            panic!(
                "{}: sample {n}:\n interp {want:?} states {:?} modes {:?} sat {:?}\n jit    {got:?} states {:?} modes {:?} sat {:?}",
                self.what,
                self.interp.states(),
                self.interp.modes(),
                self.interp.saturations(),
                self.jit.states(),
                self.jit.modes(),
                self.jit.saturations(),
            );
        }
        self.stats.samples += 1;
        self.stats.events += got.events.len();
    }

    fn step(&mut self, n: usize, sensors: &[f64]) {
        let want = self.interp.step(sensors).clone();
        let got = self.jit.step(sensors).clone();
        self.compare(n, &want, &got);
    }

    fn step_raw(&mut self, n: usize, sensors: &[i32]) {
        let want = self.interp.step_raw(sensors).clone();
        let got = self.jit.step_raw(sensors).clone();
        self.compare(n, &want, &got);
    }

    fn finish(mut self) -> Stats {
        self.stats.saturations = self.jit.saturations().iter().sum();
        self.stats
    }
}

fn pair<'f, 'j>(fp: &'f FixedProgram, jit: &'j FixedJitProgram, what: String) -> Pair<'f, 'j> {
    Pair {
        fp,
        interp: FixedInstance::new(fp),
        jit: FixedJitInstance::new(jit),
        stats: Stats::default(),
        what,
    }
}

/// Interpreter work per run (value evaluations): large instruments get shorter runs.
const EVALUATIONS_PER_RUN: usize = 30_000_000;

#[test]
fn every_instrument_every_builtin_stimulus_bit_for_bit() {
    let mut total = Stats::default();
    let mut runs = 0;
    for path in instruments() {
        let fp = load(&path);
        let jit =
            FixedJitProgram::compile(&fp).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let dip = fp.program.sensors[0].range.1;
        for &(name, _) in stimulus::builtin_names() {
            let stim =
                stimulus::builtin(name, dip, 44_100.0).unwrap_or_else(|e| panic!("{name}: {e}"));
            let mut pr = pair(&fp, &jit, format!("{} / {name}", fp.program.name));
            let cap = fp.program.samples_within(EVALUATIONS_PER_RUN);
            for (n, &k) in stim.key.iter().take(cap).enumerate() {
                pr.step(n, &[k]);
            }
            total.add(&pr.finish());
            runs += 1;
        }
    }
    println!("stimuli: {runs} runs, {total:?}");
    assert!(
        total.events > 0,
        "no stimulus emitted an event: the event path is untested"
    );
    assert_eq!(total.mismatches, 0, "{total:?}");
}

/// A raw word for a sensor with raw range [lo, hi]: mostly a random walk inside the range
/// (so the mechanics move and fire their handlers), sometimes a jump anywhere in it or far
/// beyond it, or an extreme word.
fn raw_word(rng: &mut XorShift64, prev: i32, (lo, hi): (i32, i32)) -> i32 {
    let span = (i64::from(hi) - i64::from(lo)).max(1);
    let r = |rng: &mut XorShift64, n: i64| (rng.next_u64() % n as u64) as i64;
    let x = match rng.next_u64() % 16 {
        0 => [
            i32::MIN,
            i32::MAX,
            0,
            -1,
            lo,
            hi,
            lo.saturating_sub(1),
            hi.saturating_add(1),
        ][rng.below(8)] as i64,
        1 => rng.next_u64() as u32 as i32 as i64,
        2 | 3 => i64::from(lo) + r(rng, span + 1),
        4 => i64::from(lo) - span + r(rng, 3 * span + 1),
        _ => i64::from(prev) + r(rng, span / 20 + 1) - span / 40,
    };
    x.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

#[test]
fn random_raw_words_in_and_out_of_range_bit_for_bit() {
    let mut total = Stats::default();
    for (k, path) in instruments().into_iter().chain(test_programs()).enumerate() {
        let fp = load(&path);
        let jit =
            FixedJitProgram::compile(&fp).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut rng = XorShift64::new(0x9e37_79b9_7f4a_7c15 ^ (k as u64 + 1));
        let ranges = fp.sensor_raw_range.clone();
        let mut prev: Vec<i32> = ranges.iter().map(|r| r.0).collect();
        let mut pr = pair(&fp, &jit, format!("{} / random raw", fp.program.name));
        for n in 0..50_000.min(fp.program.samples_within(EVALUATIONS_PER_RUN)) {
            for (x, &r) in prev.iter_mut().zip(&ranges) {
                // The walk continues from the saturated word.
                *x = raw_word(&mut rng, (*x).clamp(r.0, r.1), r);
            }
            let mut v = prev.clone();
            match n % 97 {
                0 => v.push(7),
                1 => {
                    v.pop();
                }
                _ => {}
            }
            pr.step_raw(n, &v);
        }
        let s = pr.finish();
        println!("{}: {s:?}", fp.program.name);
        total.add(&s);
    }
    println!("random raw: {total:?}");
    assert!(total.events > 0 && total.saturations > 0, "{total:?}");
    assert_eq!(total.mismatches, 0, "{total:?}");
}

#[test]
fn random_si_readings_bit_for_bit() {
    let mut total = Stats::default();
    for (k, path) in instruments().into_iter().chain(test_programs()).enumerate() {
        let fp = load(&path);
        let jit =
            FixedJitProgram::compile(&fp).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut rng = XorShift64::new(0x1234_5678 + k as u64);
        let mut pr = pair(&fp, &jit, format!("{} / random SI", fp.program.name));
        let specials = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.0, -0.0];
        let mut prev: Vec<f64> = fp.program.sensors.iter().map(|s| s.range.0).collect();
        for n in 0..20_000.min(fp.program.samples_within(EVALUATIONS_PER_RUN)) {
            for (x, s) in prev.iter_mut().zip(&fp.program.sensors) {
                let (lo, hi) = s.range;
                let span = hi - lo;
                *x = match rng.next_u64() % 16 {
                    0 => specials[rng.below(specials.len())],
                    1 | 2 => lo + (rng.unit() * 3.0 - 1.0) * span,
                    _ => {
                        let x0 = if x.is_finite() { *x } else { lo };
                        x0 + (rng.unit() - 0.5) * span * 0.05
                    }
                };
            }
            pr.step(n, &prev);
        }
        total.add(&pr.finish());
    }
    println!("random SI: {total:?}");
    assert_eq!(total.mismatches, 0, "{total:?}");
}

/// `run_block` over a whole stimulus gives the totals, states, modes and saturation counts
/// of sample-by-sample `step_raw`, for several block sizes.
#[test]
fn run_block_matches_step_raw() {
    for path in instruments() {
        let fp = load(&path);
        let jit = FixedJitProgram::compile(&fp).expect("compiles");
        let dip = fp.program.sensors[0].range.1;
        let ns = fp.program.sensors.len();
        for &(name, _) in stimulus::builtin_names() {
            let stim = stimulus::builtin(name, dip, 44_100.0).expect("stimulus");
            let rows: Vec<i32> = stim
                .key
                .iter()
                .take(fp.program.samples_within(EVALUATIONS_PER_RUN))
                .flat_map(|&k| (0..ns).map(move |i| if i == 0 { Some(k) } else { None }))
                .enumerate()
                .map(|(j, x)| FixedInstance::sensor_raw(&fp, j % ns, x))
                .collect();
            let mut one = FixedJitInstance::new(&jit);
            let want: Vec<i32> = rows.chunks(ns).map(|r| one.step_raw(r).total).collect();
            for block in [1, 7, 1000, rows.len()] {
                let mut inst = FixedJitInstance::new(&jit);
                let mut got = vec![0; want.len()];
                let mut done = 0;
                while done < want.len() {
                    let end = (done + block).min(want.len());
                    let n = inst.run_block(&rows[done * ns..end * ns], &mut got[done..end]);
                    assert_eq!(n, end - done);
                    done = end;
                }
                let what = format!("{} / {name} / block {block}", fp.program.name);
                assert_eq!(got, want, "{what}: totals");
                assert_eq!(inst.states(), one.states(), "{what}: states");
                assert_eq!(inst.modes(), one.modes(), "{what}: modes");
                assert_eq!(inst.saturations(), one.saturations(), "{what}: saturations");
            }
        }
    }
}

/// The fixed interpreter defines the bits for any format plan, not only the one the range
/// analysis picks: every program again under 12 plans with each real value's format moved by
/// up to ±12 or ±60 bits (within `FRAC_RANGE`), event formats moved likewise, `MULS`
/// pre-shifts and 32×16 products' cut shifts and units re-drawn, under random raw words.
/// This drives every rounding and saturation path of the JIT — wide alignments, 128-bit intermediates, results rounding to 0, shifts that
/// saturate — against the runtime's definition.
#[test]
fn random_format_plans_bit_for_bit() {
    use tactus_compiler::fixed::{MulKind, FRAC_RANGE};
    use tactus_compiler::ir::Ty;
    let mut total = Stats::default();
    let mut plans = 0;
    for (k, path) in instruments().into_iter().chain(test_programs()).enumerate() {
        let base = load(&path);
        // Every plan is a JIT compile: large programs get two (one of each kind).
        let n_plans = if base.program.values.len() > 2_000 {
            2
        } else {
            12
        };
        for plan in 0..n_plans {
            let mut rng = XorShift64::new(0xf0f0_1234 ^ (k as u64) << 8 ^ plan);
            let mut fp = base.clone();
            // Even plans move formats by up to ±12 bits, odd ones by up to ±60 (anywhere).
            let w = if plan % 2 == 0 { 12 } else { 60 };
            let jiggle = |rng: &mut XorShift64, f: i32| {
                (f + rng.below(2 * w + 1) as i32 - w as i32).clamp(FRAC_RANGE.0, FRAC_RANGE.1)
            };
            for (i, vd) in fp.program.values.iter().enumerate() {
                if matches!(vd.ty, Ty::Real(_)) {
                    fp.frac[i] = jiggle(&mut rng, fp.frac[i]);
                }
                match fp.mul_kind[i] {
                    Some(MulKind::Muls(..)) => {
                        fp.mul_kind[i] =
                            Some(MulKind::Muls(rng.below(20) as u8, rng.below(20) as u8));
                    }
                    // The 32×16 form's cut and unit re-drawn: any words, any `b`, `k`.
                    Some(MulKind::Mul32x16 { cut, .. }) => {
                        fp.mul_kind[i] = Some(MulKind::Mul32x16 {
                            cut,
                            b: rng.below(20) as u8,
                            k: rng.below(17) as u8,
                        });
                    }
                    _ => {}
                }
            }
            for f in fp.event_frac.iter_mut().flatten() {
                *f = jiggle(&mut rng, *f);
            }
            let jit =
                FixedJitProgram::compile(&fp).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let ranges = fp.sensor_raw_range.clone();
            let mut prev: Vec<i32> = ranges.iter().map(|r| r.0).collect();
            let mut pr = pair(&fp, &jit, format!("{} / plan {plan}", fp.program.name));
            for n in 0..5_000.min(fp.program.samples_within(EVALUATIONS_PER_RUN)) {
                for (x, &r) in prev.iter_mut().zip(&ranges) {
                    *x = raw_word(&mut rng, (*x).clamp(r.0, r.1), r);
                }
                pr.step_raw(n, &prev);
            }
            total.add(&pr.finish());
            plans += 1;
        }
    }
    println!("random plans: {plans} plans, {total:?}");
    assert_eq!(total.mismatches, 0, "{total:?}");
}

/// Params as run-time data: the grand piano shared by three hammer masses (the grading of
/// `grand88`: 11 g bass, 7.25 g, 3.5 g treble), each key's param block in the JIT's ctx,
/// bit for bit with the interpreter on every built-in stimulus.
#[test]
fn shared_program_with_each_keys_param_block_bit_for_bit() {
    let path = instruments()
        .into_iter()
        .find(|p| p.ends_with("grand_piano.tactus"))
        .expect("instruments/grand_piano.tactus");
    let text = std::fs::read_to_string(&path).unwrap();
    let irs: Vec<_> = ["11 g", "7.25 g", "3.5 g"]
        .iter()
        .map(|m| {
            let config = tactus_compiler::lower::Config {
                overrides: vec![("M_h".into(), (*m).into())],
                ..Default::default()
            };
            tactus_compiler::compile(&text, &config).unwrap().program
        })
        .collect();
    let shared = tactus_compiler::share::share(&irs).unwrap();
    let fp = FixedProgram::new(&shared.program);
    assert_eq!(fp.param_words.len(), 3);
    let jit = FixedJitProgram::compile(&fp).unwrap();
    let dip = fp.program.sensors[0].range.1;
    let mut total = Stats::default();
    for values in &shared.values() {
        let block = fp.param_block(values).unwrap();
        for &(name, _) in stimulus::builtin_names() {
            let stim = stimulus::builtin(name, dip, 44_100.0).unwrap();
            let mut pr = Pair {
                fp: &fp,
                interp: FixedInstance::with_params(&fp, block.clone()),
                jit: FixedJitInstance::with_params(&jit, &block),
                stats: Stats::default(),
                what: format!("grand_piano {block:?} / {name}"),
            };
            for (n, &k) in stim.key.iter().enumerate() {
                pr.step(n, &[k]);
            }
            total.add(&pr.finish());
        }
    }
    println!("shared grand piano, 3 param blocks: {total:?}");
    assert!(total.events > 0 && total.samples > 10_000);
    assert_eq!(total.mismatches, 0, "{total:?}");
}
