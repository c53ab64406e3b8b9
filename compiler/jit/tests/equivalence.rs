//! Run-tests: the reference interpreter and the JIT side by side on the same program and the
//! same sensor readings, compared on every sample.
//!
//! Every instrument in `instruments/` runs every built-in stimulus (dip depth = the first
//! sensor's upper bound); every instrument and `tests/data/*.tactus` also run random
//! readings (deterministic xorshift) inside and outside the declared ranges, NaN, ±∞ and
//! signed zeros included. Required on every sample: each force term, the total, each
//! output and each state within 1e-12 relative (or both NaN), identical modes, saturation
//! counts and event lists (names and order; arguments within 1e-12). The tests also count
//! the values that are not bit-identical, and require none.

mod common;
use common::{instruments, load_program, test_programs};
use std::path::Path;
use tactus_compiler::interp::{Instance, SampleOut};
use tactus_compiler::ir::Program;
use tactus_jit::{JitInstance, JitProgram};
use tactus_runtime::rng::XorShift64;
use tactus_runtime::stimulus;

fn load(path: &Path) -> Program {
    load_program(path)
}

/// What a comparison found.
#[derive(Debug, Default)]
struct Stats {
    samples: usize,
    /// Events emitted (by both engines).
    events: usize,
    /// Saturated state writes (by both engines).
    saturations: u64,
    values: usize,
    /// Values equal within tolerance but not bit for bit.
    not_bit_identical: usize,
    max_rel: f64,
}

impl Stats {
    fn add(&mut self, o: &Stats) {
        self.samples += o.samples;
        self.events += o.events;
        self.saturations += o.saturations;
        self.values += o.values;
        self.not_bit_identical += o.not_bit_identical;
        self.max_rel = self.max_rel.max(o.max_rel);
    }
}

/// Relative difference under the test's rule: 0 when both are NaN or bit-identical, ∞ when
/// only one is NaN.
fn rel(a: f64, b: f64) -> f64 {
    if a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()) {
        return 0.0;
    }
    if a.is_nan() || b.is_nan() {
        return f64::INFINITY;
    }
    if a == b {
        return 0.0; // +0 and -0, or equal infinities
    }
    (a - b).abs() / a.abs().max(b.abs()).max(1e-300)
}

struct Pair<'p, 'j> {
    program: &'p Program,
    interp: Instance<'p>,
    jit: JitInstance<'j>,
    stats: Stats,
    what: String,
}

impl Pair<'_, '_> {
    fn check(&mut self, what: &str, n: usize, a: f64, b: f64) {
        let r = rel(a, b);
        let bits_equal = a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        self.stats.values += 1;
        if !bits_equal {
            self.stats.not_bit_identical += 1;
        }
        self.stats.max_rel = self.stats.max_rel.max(r);
        assert!(
            r <= 1e-12,
            "{}: sample {n}: {what}: interp {a:e} ({:#x}), jit {b:e} ({:#x})",
            self.what,
            a.to_bits(),
            b.to_bits()
        );
    }

    fn step(&mut self, n: usize, sensors: &[f64]) {
        let want: SampleOut = self.interp.step(sensors).clone();
        let got: SampleOut = self.jit.step(sensors).clone();
        let p = self.program;
        for (i, f) in p.forces.iter().enumerate() {
            self.check(
                &format!("force {}", f.name),
                n,
                want.forces[i],
                got.forces[i],
            );
        }
        self.check("total", n, want.total, got.total);
        for (i, o) in p.outputs.iter().enumerate() {
            self.check(
                &format!("output {}", o.name),
                n,
                want.outputs[i],
                got.outputs[i],
            );
        }
        let (ws, gs) = (self.interp.states().to_vec(), self.jit.states().to_vec());
        for (i, s) in p.states.iter().enumerate() {
            self.check(&format!("state {}", s.name), n, ws[i], gs[i]);
        }
        assert_eq!(
            self.interp.modes(),
            self.jit.modes(),
            "{}: sample {n}: modes",
            self.what
        );
        assert_eq!(
            self.interp.saturations(),
            self.jit.saturations(),
            "{}: sample {n}: saturations",
            self.what
        );
        let names = |o: &SampleOut| {
            o.events
                .iter()
                .map(|(e, a)| (p.events[e.index()].name.clone(), a.len()))
                .collect::<Vec<_>>()
        };
        assert_eq!(
            names(&want),
            names(&got),
            "{}: sample {n}: events",
            self.what
        );
        for ((e, wa), (_, ga)) in want.events.iter().zip(&got.events) {
            for (k, (x, y)) in wa.iter().zip(ga).enumerate() {
                self.check(
                    &format!("event {} arg {k}", p.events[e.index()].name),
                    n,
                    *x,
                    *y,
                );
            }
        }
        self.stats.samples += 1;
        self.stats.events += got.events.len();
    }
}

fn run(
    program: &Program,
    jit: &JitProgram,
    what: String,
    readings: impl Iterator<Item = Vec<f64>>,
) -> Stats {
    let mut pair = Pair {
        program,
        interp: Instance::new(program),
        jit: JitInstance::new(jit),
        stats: Stats::default(),
        what,
    };
    for (n, sensors) in readings.enumerate() {
        pair.step(n, &sensors);
    }
    pair.stats.saturations = pair.jit.saturations().iter().sum();
    pair.stats
}

/// Interpreter work per run (value evaluations): large instruments get shorter runs.
const EVALUATIONS_PER_RUN: usize = 30_000_000;

#[test]
fn every_instrument_every_builtin_stimulus() {
    let mut total = Stats::default();
    for path in instruments() {
        let program = load(&path);
        let jit =
            JitProgram::compile(&program).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let dip = program.sensors[0].range.1;
        for &(name, _) in stimulus::builtin_names() {
            let stim =
                stimulus::builtin(name, dip, 44_100.0).unwrap_or_else(|e| panic!("{name}: {e}"));
            let what = format!("{} / {name}", program.name);
            let cap = program.samples_within(EVALUATIONS_PER_RUN);
            let s = run(
                &program,
                &jit,
                what,
                stim.key.iter().take(cap).map(|&k| vec![k]),
            );
            total.add(&s);
        }
    }
    println!("stimuli: {total:?}");
    assert!(
        total.events > 0,
        "no stimulus emitted an event: the event path is untested"
    );
    assert_eq!(total.not_bit_identical, 0, "{total:?}");
}

/// Random readings from the runtime's deterministic xorshift64*.
struct Rng(XorShift64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0.next_u64()
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A reading for a sensor with range [lo, hi]: mostly a random walk inside the range
    /// (so the mechanics move and fire their handlers), sometimes a jump anywhere in or
    /// beyond it, or a special value.
    fn reading(&mut self, prev: f64, (lo, hi): (f64, f64)) -> f64 {
        let span = hi - lo;
        match self.next() % 16 {
            0 => f64::NAN,
            1 => [
                f64::INFINITY,
                f64::NEG_INFINITY,
                0.0,
                -0.0,
                lo,
                hi,
                -lo,
                -hi,
            ][(self.next() % 8) as usize],
            2 | 3 => lo + (self.unit() * 3.0 - 1.0) * span, // anywhere in [lo - span, hi + span)
            _ => {
                let x = if prev.is_finite() { prev } else { lo };
                x + (self.unit() - 0.5) * span * 0.05
            }
        }
    }
}

#[test]
fn random_readings_in_and_out_of_range() {
    let mut total = Stats::default();
    for (k, path) in instruments().into_iter().chain(test_programs()).enumerate() {
        let program = load(&path);
        let jit =
            JitProgram::compile(&program).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut rng = Rng(XorShift64::new(0x9e37_79b9_7f4a_7c15 ^ (k as u64 + 1)));
        let ranges: Vec<(f64, f64)> = program.sensors.iter().map(|s| s.range).collect();
        let mut prev: Vec<f64> = ranges.iter().map(|r| r.0).collect();
        // One more reading than sensors sometimes, one fewer sometimes: missing readings
        // read the lower bound, extra ones are ignored.
        let readings = (0..50_000.min(program.samples_within(EVALUATIONS_PER_RUN))).map(move |n| {
            for (x, &r) in prev.iter_mut().zip(&ranges) {
                *x = rng.reading(*x, r);
            }
            let mut v = prev.clone();
            match n % 97 {
                0 => v.push(1.0),
                1 => {
                    v.pop();
                }
                _ => {}
            }
            v
        });
        let s = run(
            &program,
            &jit,
            format!("{} / random", program.name),
            readings,
        );
        println!("{}: {s:?}", program.name);
        total.add(&s);
    }
    println!("random: {total:?}");
    assert!(total.events > 0 && total.saturations > 0, "{total:?}");
    assert_eq!(total.not_bit_identical, 0, "{total:?}");
}

#[test]
fn layout_has_one_event_slot_per_emit_statement() {
    for path in instruments().into_iter().chain(test_programs()) {
        let program = load(&path);
        let jit = JitProgram::compile(&program).expect("compiles");
        let l = jit.layout();
        let mut next = l.output(l.n_outputs);
        for slot in &l.events {
            assert_eq!(slot.offset, next, "{}", path.display());
            assert!(slot.event.index() < program.events.len());
            next += 1 + slot.n_args;
        }
        assert_eq!(l.out_len, next);
    }
}
