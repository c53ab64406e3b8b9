//! Checking a compiled update against the fixed interpreter and measuring its cycles, for
//! any engine that implements the [`crate::layout::Interface`] (a C compiler's build, the
//! Thumb backend): [`compare`] runs sensor records through an [`UpdateRunner`] and through
//! [`FixedInstance`] side by side and returns the mismatches and the cycle statistics.

use crate::runner::{RunError, UpdateRunner};
use std::fmt::Write as _;
use tactus_compiler::abi::OutLayout;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_compiler::fixed::FixedProgram;
use tactus_runtime::rng::XorShift64;
use tactus_runtime::stimulus;

/// Sample rate of the built-in stimuli the measurements use, Hz (the board's).
pub const SAMPLE_RATE_HZ: f64 = 44_100.0;

/// One run from the initial state: raw sensor words per sample.
#[derive(Clone, Debug)]
pub struct Run {
    /// What it is (`"mf-dip"`).
    pub label: String,
    /// Per sample, one raw word per sensor.
    pub records: Vec<Vec<i32>>,
}

/// The raw sensor words for a key stimulus: sensor 0 follows the stimulus (converted with
/// [`FixedInstance::sensor_raw`], the conversion every engine shares), the others sit at
/// their lower bound.
pub fn stimulus_run(fp: &FixedProgram, s: &stimulus::Stimulus) -> Run {
    key_run(fp, s.name.clone(), &s.key)
}

/// The raw words of a key-travel sequence (metres, one per sample) on sensor 0, the other
/// sensors at their lower bound, converted as every engine converts them.
pub fn key_run(fp: &FixedProgram, label: String, key: &[f64]) -> Run {
    let ns = fp.program.sensors.len();
    Run {
        label,
        records: key
            .iter()
            .map(|&k| {
                (0..ns)
                    .map(|i| FixedInstance::sensor_raw(fp, i, (i == 0).then_some(k)))
                    .collect()
            })
            .collect(),
    }
}

/// Every built-in stimulus ([`stimulus::builtin_names`]) at [`SAMPLE_RATE_HZ`], scaled to
/// sensor 0's declared upper bound (the full dip), as runs.
///
/// Panics never; a built-in that cannot be generated (a sensor whose upper bound is not
/// positive) is left out.
pub fn builtin_runs(fp: &FixedProgram) -> Vec<Run> {
    let Some(s0) = fp.program.sensors.first() else {
        return Vec::new();
    };
    stimulus::builtin_names()
        .iter()
        .filter_map(|(name, _)| stimulus::builtin(name, s0.range.1, SAMPLE_RATE_HZ).ok())
        .map(|s| stimulus_run(fp, &s))
        .collect()
}

/// `n` runs of `len` samples of adversarial raw sensor words
/// ([`XorShift64::sensor_word`]: arbitrary words, corners, in-range walks), each sensor
/// starting at its lower bound; reproducible from `seed`.
pub fn random_runs(fp: &FixedProgram, seed: u64, n: usize, len: usize) -> Vec<Run> {
    let mut rng = XorShift64::new(seed);
    (0..n)
        .map(|r| {
            let mut prev: Vec<i32> = fp.sensor_raw_range.iter().map(|r| r.0).collect();
            let records = (0..len)
                .map(|_| {
                    for (w, &range) in prev.iter_mut().zip(&fp.sensor_raw_range) {
                        *w = rng.sensor_word(*w, range);
                    }
                    prev.clone()
                })
                .collect();
            Run {
                label: format!("random{r}"),
                records,
            }
        })
        .collect()
}

/// Cycle statistics over the calls of the update.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CycleStats {
    /// Calls measured.
    pub calls: u64,
    /// Sum of their cycles.
    pub total: u64,
    /// Fewest cycles of one call.
    pub best: u64,
    /// Most cycles of one call.
    pub worst: u64,
    /// Where the worst call happened: (run label, sample index).
    pub worst_at: (String, usize),
}

impl CycleStats {
    /// Mean cycles per call (0 with no calls).
    pub fn mean(&self) -> f64 {
        if self.calls == 0 {
            0.0
        } else {
            self.total as f64 / self.calls as f64
        }
    }

    /// Records one call of `cycles` cycles, made at sample `sample` of the run `label`.
    pub fn add(&mut self, cycles: u64, label: &str, sample: usize) {
        if self.calls == 0 || cycles < self.best {
            self.best = cycles;
        }
        if self.calls == 0 || cycles > self.worst {
            self.worst = cycles;
            self.worst_at = (label.to_string(), sample);
        }
        self.calls += 1;
        self.total += cycles;
    }
}

/// What [`compare`] found.
#[derive(Clone, Debug, Default)]
pub struct Comparison {
    /// Samples compared.
    pub samples: usize,
    /// Events the interpreter emitted over all samples.
    pub events: usize,
    /// Mismatching samples (all of them counted).
    pub mismatches: usize,
    /// The first few mismatches, described (run, sample, both sides).
    pub first_mismatches: Vec<String>,
    /// Cycles of the update calls (per key-sample, including call and return; see
    /// [`crate::runner::Sample::cycles`]).
    pub cycles: CycleStats,
    /// Cycles of the last `init` call, including call and return.
    pub init_cycles: u64,
}

/// How many mismatches [`Comparison::first_mismatches`] describes.
pub const MISMATCHES_KEPT: usize = 5;

/// Runs every run from the initial state through `runner` (re-initialised before each run)
/// and through the fixed interpreter, and compares after `init` the states and modes, and
/// per sample: each force term, the total, the outputs, the emitted events with their
/// arguments (decoded from the emit sites of `out`, which must be 0 or 1 with zero arguments
/// when not fired), the states and the modes. Collects the cycles of every update call.
///
/// `out` is the layout of the update's `out` words (as `cgen` reports it).
///
/// Errors: the runner's [`RunError`] (a fault, a runaway call, an overrun) ends the
/// comparison.
pub fn compare(
    runner: &mut UpdateRunner,
    fp: &FixedProgram,
    out: &OutLayout,
    runs: &[Run],
) -> Result<Comparison, RunError> {
    let mut v = compare_many(std::slice::from_mut(runner), fp, out, runs)?;
    Ok(v.pop().unwrap_or_default())
}

/// [`compare`] for several engines of the same program at once, in lock-step with one pass
/// of the interpreter (which costs as much host time as an emulated engine); one
/// [`Comparison`] per runner, in order.
///
/// The interpreter runs with the first runner's param block ([`crate::layout::Interface::params`]; the
/// runners of one comparison run one key).
///
/// Errors: the first [`RunError`] of any runner ends the comparison.
pub fn compare_many(
    runners: &mut [UpdateRunner],
    fp: &FixedProgram,
    out: &OutLayout,
    runs: &[Run],
) -> Result<Vec<Comparison>, RunError> {
    let p = &fp.program;
    let mut cs = vec![Comparison::default(); runners.len()];
    let mut got_events = Vec::new();
    let params = runners.first().map_or_else(
        || fp.nominal_param_block(),
        |r| r.interface().params.clone(),
    );
    for run in runs {
        let mut inst = FixedInstance::with_params(fp, params.clone());
        for (runner, c) in runners.iter_mut().zip(&mut cs) {
            c.init_cycles = runner.init()?;
            let (states, modes) = runner.read_state()?;
            if states != inst.states()
                || !modes
                    .iter()
                    .map(|&m| m as u32)
                    .eq(inst.modes().iter().copied())
            {
                c.mismatches += 1;
                if c.first_mismatches.len() < MISMATCHES_KEPT {
                    c.first_mismatches.push(format!(
                        "{} after init: states {states:?} modes {modes:?}; interpreter states {:?} modes {:?}",
                        run.label,
                        inst.states(),
                        inst.modes()
                    ));
                }
            }
        }
        for (n, rec) in run.records.iter().enumerate() {
            // The interpreter's result of this sample (stepped once for all runners).
            let want = inst.step_raw(rec).clone();
            for (runner, c) in runners.iter_mut().zip(&mut cs) {
                let got = runner.step(rec)?;
                c.samples += 1;
                c.events += want.events.len();
                c.cycles.add(got.cycles, &run.label, n);
                let row = &got.out;
                got_events.clear();
                let mut stray = false;
                for site in &out.emits {
                    let nargs = p.events[site.event.index()].args.len();
                    let args = &row[site.offset + 1..site.offset + 1 + nargs];
                    match row[site.offset] {
                        1 => got_events.push((site.event, args.to_vec())),
                        0 => stray |= args.iter().any(|&a| a != 0),
                        _ => stray = true,
                    }
                }
                let ok = row[out.forces..out.forces + p.forces.len()] == want.forces[..]
                    && row[out.total] == want.total
                    && row[out.outputs..out.outputs + p.outputs.len()] == want.outputs[..]
                    && got_events == want.events
                    && !stray
                    && got.states[..] == *inst.states()
                    && got
                        .modes
                        .iter()
                        .map(|&m| m as u32)
                        .eq(inst.modes().iter().copied());
                if !ok {
                    c.mismatches += 1;
                    if c.first_mismatches.len() < MISMATCHES_KEPT {
                        let mut s = String::new();
                        let _ = write!(
                            s,
                            "{} sample {n} sensors {rec:?}:\n  emulated: out {:?} states {:?} modes {:?}\n  interp:   forces {:?} total {} outputs {:?} events {:?} states {:?} modes {:?}",
                            run.label,
                            row,
                            got.states,
                            got.modes,
                            want.forces,
                            want.total,
                            want.outputs,
                            want.events,
                            inst.states(),
                            inst.modes()
                        );
                        c.first_mismatches.push(s);
                    }
                }
            }
        }
    }
    Ok(cs)
}
