//! The accuracy contract (`tactus_compiler::fixed::contract`) over the budget corpus
//! (`tactus_firmware::corpus`, [`Size::Quick`]: presses from 12 to 200 ms, repeated notes,
//! trills, half dips with reversals in the let-off zone, sensor noise, glitches and random
//! words), for the piano (its default params, and grand88's graded hammer masses as one
//! shared program at the keys the planner simulates), the harpsichords and the organ. Each
//! run is compared with the f64 reference clause by clause — force within its DAC LSB
//! bound, no event lost or added, every event within its time tolerance, arguments within
//! theirs, states within their ranges and no value saturating — and the test fails naming
//! every run and clause broken. The worst of each clause and its margin are printed
//! (`cargo test -p tactus-firmware --test contract_corpus -- --nocapture`).
//!
//! The corpus's glitches and random words put arbitrary words on the sensor: both engines
//! read them clamped to the sensor's declared range, as every engine does
//! ([`contract::reference_raw`]).

use std::path::Path;
use tactus_compiler::fixed::contract::{self, ContractCheck};
use tactus_compiler::fixed::{report, simulated_keys, FixedProgram};
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config;
use tactus_firmware::corpus::{self, Size};
use tactus_runtime::keyboard::read_layout;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn source(name: &str) -> String {
    std::fs::read_to_string(root().join(format!("instruments/{name}.tactus"))).unwrap()
}

fn lower(name: &str, config: &Config) -> Program {
    tactus_compiler::compile(&source(name), config)
        .unwrap_or_else(|d| panic!("{name}: {d:?}"))
        .program
}

/// The worst of each clause over a set of runs.
#[derive(Default)]
struct Worst {
    runs: usize,
    samples: usize,
    events: usize,
    force: (f64, String),
    force_within_time: (f64, String),
    shift: (f64, String),
    arg: (f64, String),
    unmatched: usize,
    out_of_range: usize,
    overflowed: usize,
    /// The strict force difference at any sample, switch windows included (DAC LSB).
    force_all: (f64, String),
    /// Runs the brief's form of the switch clause breaks (no after-effect allowed: the
    /// per-sample clause from the window's end on).
    literal_broken: usize,
    /// Runs the per-sample clause at every sample breaks (no switch clause at all).
    strict_broken: usize,
    switches: usize,
    switch: (f64, String),
    unresolved: usize,
}

impl Worst {
    fn add(&mut self, label: &str, r: &ContractCheck, force_bound: f64) {
        self.runs += 1;
        self.samples += r.samples;
        self.events += r.events_f64;
        let ratio = r.max_force_lsb / force_bound;
        if ratio > self.force.0 {
            self.force = (ratio, label.to_string());
        }
        let ratio = r.max_force_lsb_within_time / force_bound;
        if ratio > self.force_within_time.0 {
            self.force_within_time = (ratio, label.to_string());
        }
        if r.shift_ratio > self.shift.0 {
            self.shift = (r.shift_ratio, label.to_string());
        }
        if r.arg_ratio > self.arg.0 {
            self.arg = (r.arg_ratio, label.to_string());
        }
        self.unmatched += r.unmatched;
        self.out_of_range += r.state_out_of_range;
        self.overflowed += r.overflowed;
        if r.switches
            .iter()
            .any(|w| w.after_samples > 0 || w.force_lsb > w.bound_lsb)
        {
            self.literal_broken += 1;
        }
        if r.max_force_lsb_all > force_bound {
            self.strict_broken += 1;
        }
        if r.max_force_lsb_all > self.force_all.0 {
            self.force_all = (r.max_force_lsb_all, label.to_string());
        }
        self.switches += r.switch_count;
        self.unresolved += r.switches_unresolved;
        if r.switch_ratio > self.switch.0 {
            let worst = r
                .switches
                .iter()
                .max_by(|a, b| (a.force_lsb / a.bound_lsb).total_cmp(&(b.force_lsb / b.bound_lsb)))
                .expect("a switch");
            self.switch = (
                r.switch_ratio,
                format!(
                    "{label} at sample {}: {:.3} of {:.3} LSB (slope {:.3}, one sample {:.1}), apart {} samples, {}",
                    worst.sample,
                    worst.force_lsb,
                    worst.bound_lsb,
                    worst.slope_lsb,
                    worst.strict_lsb,
                    worst.samples,
                    worst.decision
                ),
            );
        }
    }

    fn print(&self, what: &str, force_bound: f64) {
        println!(
            "{what:<26} {} runs, {} samples, {} events: force {:.4} of {force_bound} LSB (margin {:.4}; {}), \
             within the 0.5 ms time tolerance {:.4} ({}), \
             event shift {:.3} of its tolerance ({}), arguments {:.4} of theirs ({}), \
             unmatched events {}, samples with a state out of range {}, saturating values {}",
            self.runs,
            self.samples,
            self.events,
            self.force.0 * force_bound,
            (1.0 - self.force.0) * force_bound,
            self.force.1,
            self.force_within_time.0 * force_bound,
            self.force_within_time.1,
            self.shift.0,
            self.shift.1,
            self.arg.0,
            self.arg.1,
            self.unmatched,
            self.out_of_range,
            self.overflowed
        );
        println!(
            "{:<26} switches {} ({} lost or added); worst switch {:.4} of its bound ({}); one-sample difference anywhere {:.1} LSB ({})",
            "",
            self.switches,
            self.unresolved,
            self.switch.0,
            self.switch.1,
            self.force_all.0,
            self.force_all.1
        );
    }
}

/// Every run of the quick corpus of `fp` through the f64 reference of `p` (run-time params
/// at `params`, SI; empty for the params' own values) and the fixed interpreter: the broken
/// clauses, each as "what/run: clause", and the worst of each clause.
fn check_corpus(
    what: &str,
    p: &Program,
    fp: &FixedProgram,
    params: &[f64],
) -> (Vec<String>, Worst) {
    let lsb = report::analyse(fp).dac_lsb_n();
    let c = &p.contract;
    let bound = c.force.lsb(lsb);
    let mut worst = Worst::default();
    let mut broken = Vec::new();
    for run in corpus::corpus(fp, Size::Quick) {
        let raw: Vec<i32> = run.records.iter().map(|r| r[0]).collect();
        let reference = contract::reference_raw(p, fp, &raw, params)
            .unwrap_or_else(|e| panic!("{what}/{}: {e}", run.label));
        let r = contract::compare(p, fp, &reference, lsb, c, false)
            .unwrap_or_else(|e| panic!("{what}/{}: {e}", run.label));
        assert_eq!(r.samples, raw.len(), "{what}/{}", run.label);
        worst.add(&run.label, &r, bound);
        for v in r.violations(c, p.sample_rate_hz) {
            broken.push(format!("{what}/{}: {v}", run.label));
        }
    }
    assert!(
        worst.runs > 10 && worst.samples > 100_000,
        "{what}: the corpus ran nothing"
    );
    if !p.events.is_empty() {
        assert!(worst.events > 0, "{what}: no event in the whole corpus");
    }
    worst.print(what, bound);
    (broken, worst)
}

/// Every clause on every run of the corpus, for each keyboard instrument with its own
/// params.
#[test]
fn the_contract_holds_over_the_budget_corpus() {
    let mut broken = Vec::new();
    for name in ["grand_piano", "harpsichord", "harpsichord_2x8", "hammond"] {
        let p = lower(name, &Config::default());
        let fp = FixedProgram::new(&p);
        let (b, worst) = check_corpus(name, &p, &fp, &[]);
        assert!(
            worst.force.0 > 0.0,
            "{name}: no force error measured at all"
        );
        broken.extend(b);
    }
    assert!(broken.is_empty(), "contract broken:\n{}", broken.join("\n"));
}

/// grand88's layout: its keys, the shared program of their graded hammer masses (as
/// `compile_layout` shares them) and each key's run-time param values.
fn grand88() -> (
    Vec<tactus_runtime::keyboard::KeyAssignment>,
    tactus_compiler::share::Shared,
    Vec<Vec<f64>>,
) {
    let (_, assigned) = read_layout(&root().join("instruments/layouts/grand88.toml")).unwrap();
    let irs: Vec<Program> = assigned
        .iter()
        .map(|k| {
            assert_eq!(k.instrument, "grand_piano");
            let config = Config {
                overrides: k.params.clone(),
                ..Config::default()
            };
            lower("grand_piano", &config)
        })
        .collect();
    let shared = tactus_compiler::share::share(&irs).unwrap();
    assert!(
        shared.program.runtime_params().count() > 0,
        "the masses must be run-time params"
    );
    let values = shared.values();
    (assigned, shared, values)
}

/// The contract at every one of grand88's 88 keys over the quick corpus, with the shared
/// program's plan (the planner's search simulates six of them): every clause on every run.
/// It costs about 3 CPU-minutes in the test profile (1,320 runs, 26 million samples through
/// both interpreters), over CI's budget, so it is ignored there — CI checks the six keys the
/// planner simulates ([`the_contract_over_the_budget_corpus_for_grand88s_graded_masses`]) —
/// and run by hand: `cargo test -p tactus-firmware --test contract_corpus --
/// --ignored --nocapture the_contract_at_every_grand88_key` (BENCHMARKS.md, "Session 13
/// (switch16)"). It prints how many keys hold, also under the brief's form of the switch
/// clause (no after-effect) and under the per-sample force clause alone.
#[test]
#[ignore = "3 CPU-minutes in the test profile: run by hand (BENCHMARKS.md, Session 13 (switch16))"]
fn the_contract_at_every_grand88_key() {
    let (assigned, shared, values) = grand88();
    let fp = FixedProgram::new(&shared.program);
    let mut broken = Vec::new();
    let (mut holding, mut literal, mut strict) = (0, 0, 0);
    for (k, values) in assigned.iter().zip(&values) {
        let what = format!("grand88 key {} ({:?})", k.key, k.params);
        let (b, worst) = check_corpus(&what, &shared.program, &fp, values);
        holding += usize::from(b.is_empty());
        literal += usize::from(b.is_empty() && worst.literal_broken == 0);
        strict += usize::from(b.is_empty() && worst.strict_broken == 0);
        broken.extend(b);
    }
    println!(
        "{holding} of {} keys hold every clause; {literal} without the after-effect allowance; {strict} with the per-sample force clause at every sample",
        assigned.len()
    );
    assert!(broken.is_empty(), "contract broken:\n{}", broken.join("\n"));
}

/// The clauses the corpus breaks today, as (key, run, clause), which the grand88 test
/// asserts are exactly those broken — a ledger, like the static-WCET ceilings: a fix
/// that removes one, or a plan that breaks another, fails the test until this list is
/// updated. See [`the_contract_over_the_budget_corpus_for_grand88s_graded_masses`].
///
/// With the switch clause (session 13): D2's rest-felt landing under noise and D♯6's
/// hammer–key contact close a sample apart as before, and their windows hold, but the
/// after-effect is not a time shift: at D2 the f64 hammer lands at sample 1135 and, resting
/// on the felt with one sample of gravity, lands again at 1136 with −1.7 mrad/s, which
/// overwrites the landing's 34 mN pulse with 0.46 mN; the fixed hammer lands once, at 1136,
/// and keeps its pulse (19.2 DAC LSB, decaying over 390 samples). D♯6's after-effect is
/// 3.5 LSB over 335 samples. E4's contact is 8.38 LSB from the f64 force within the window
/// against a bound of 6.40 (1 + its own one-sample change 5.40): the contact closes a sample
/// later, so the hammer's speed misses one sample of contact deceleration (12.6 mrad/s,
/// `b_jack·l3·Δw` ≈ 8 LSB), which the f64 force's one-sample change does not bound; 2.09
/// over its after-effect and 1.11 after that.
///
/// Gone in session 14 (contract17): D♯6's 22.2 LSB and C8's 3.92 LSB per sample. Both
/// were one landing on the rest felt seen from both sides (D♯6: the fixed hammer lands at
/// 7892, the f64 one at 7895; C8: at 12240 and 12242), which the chatter rule took for a
/// second switch and ended the first one's after-effect; a disagreement starting again
/// inside an open window is now that switch's other side (`ContractCheck::switch_rejoined`).
const KNOWN_BREAKS: &[(u8, &str, &str)] = &[
    (38, "noisy-rest-0.5%", "after a switch at sample"),
    (64, "half-dip", "at a switch at sample"),
    (64, "half-dip", "after a switch at sample"),
    (64, "half-dip", "force differs by"),
    (87, "half-dip-90%", "after a switch at sample"),
];

/// grand88's graded hammer masses: all 88 keys shared into one program as the layout
/// shares them (`compile_layout`), and the contract checked over the corpus at the param
/// values of the keys the planner's search simulates (`fixed::simulated_keys`: A0 and C8,
/// the grading's ends; E4 and D♯6, the keys nearest the middles of the two run-time
/// params' intervals; D2 and G♯3, evenly spaced).
///
/// Before the contract's switch clause (`contract::Switch`) this was **not met** at three of
/// the six (E4 half dip 2,046 DAC LSB for one sample, D♯6 half-dip-90% 2,535, D2
/// noisy-rest-0.5% 22.7): a switch of the model closing a sample apart in fixed point and
/// f64, decided by nanometres (at E4 the hammer–key contact `c > 0 m` closes after ≈ 150 ms
/// of free flight with 11 nm to spare in f64, the fixed hammer 1.4 µrad behind). The switch
/// clause reads the force there as (τ, ε)-closeness within the switch tolerance, ε the force
/// tolerance plus the f64 force's own one-sample change, and the switch's after-effect as a
/// time shift; what it still does not excuse is listed in [`KNOWN_BREAKS`], and the test
/// asserts that the broken clauses are exactly those.
#[test]
fn the_contract_over_the_budget_corpus_for_grand88s_graded_masses() {
    let (assigned, shared, values) = grand88();
    let chosen = simulated_keys(&shared.program);
    assert!(chosen.len() >= 3, "{chosen:?}");
    let keys: Vec<_> = chosen.iter().map(|&i| (&assigned[i], &values[i])).collect();
    let fp = FixedProgram::new(&shared.program);
    let mut unexpected = Vec::new();
    let mut seen = vec![false; KNOWN_BREAKS.len()];
    for (k, values) in keys {
        let what = format!("grand88 key {} ({:?})", k.key, k.params);
        let (broken, _) = check_corpus(&what, &shared.program, &fp, values);
        for v in broken {
            let known = KNOWN_BREAKS.iter().position(|(key, run, clause)| {
                *key == k.key && v.contains(&format!("/{run}: {clause}"))
            });
            match known {
                Some(i) => {
                    seen[i] = true;
                    println!("  broken (known, not met): {v}");
                }
                None => unexpected.push(v),
            }
        }
    }
    assert!(
        unexpected.is_empty(),
        "contract broken:\n{}",
        unexpected.join("\n")
    );
    let gone: Vec<_> = KNOWN_BREAKS
        .iter()
        .zip(&seen)
        .filter(|(_, s)| !**s)
        .map(|(b, _)| b)
        .collect();
    assert!(
        gone.is_empty(),
        "known breaks no longer broken (remove them from KNOWN_BREAKS): {gone:?}"
    );
}
