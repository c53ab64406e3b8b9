//! The accuracy contract of a fixed-point plan, in physical terms, checked by simulation
//! against the f64 reference semantics.
//!
//! The error analysis ([`super::report`]) bounds one sample; integrated states (a hammer's
//! angle and speed) accumulate their errors, and a threshold crossed a sample later moves an
//! event. So what an instrument maker cares about is stated as a contract on whole runs and
//! checked by running the f64 interpreter and the fixed interpreter side by side on the same
//! quantised sensor samples: the force at the key within a DAC LSB, the same events on the
//! same key (none lost or added) within half a millisecond, their arguments (a strike's
//! hammer speed) within a percent, and every state within its declared range with no
//! saturation. [`Contract::default`] holds the issue-16 defaults; an instrument's
//! `tolerance` lines ([`Program::contract`]) change them or add clauses on single force
//! terms, outputs and events. A run is recorded once ([`reference`]) and compared with as
//! many plans as the planner's search needs ([`compare`]).

mod retimed;
mod switches;

pub use switches::{Kind as DecisionKind, Site as Decision};

/// Every branch decision of `p`'s update the switch clause compares, in body order, then
/// the modes' variants ([`Decision`]).
pub fn decisions(p: &Program) -> Vec<Decision> {
    switches::sites(p)
}

/// The decisions of `a` and `b` (the lowered and the planned program) that are the same
/// decision of the source, as (index in `a`, index in `b`): named by kind, source span and
/// rank (see [`Decision`]).
pub fn matched_decisions(a: &[Decision], b: &[Decision]) -> Vec<(usize, usize)> {
    switches::matched(a, b)
}

use super::interp::FixedInstance;
use super::{FixedProgram, ParamBlockError};
use crate::interp::Instance;
use crate::ir::{EventId, Program};
use tactus_runtime::fixed as fx;

pub use crate::ir::Contract;

/// What one run showed, clause by clause (the worst over its samples and events).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ContractCheck {
    /// Samples compared.
    pub samples: usize,
    /// One DAC LSB in newtons (what force bounds in newtons are converted with).
    pub dac_lsb_n: f64,
    /// Largest |total force difference| at the samples the per-sample force clause holds
    /// (every sample but those of a switch's window, [`ContractCheck::switches`]), DAC LSB.
    pub max_force_lsb: f64,
    /// Largest |total force difference| at any sample, switch windows included, DAC LSB.
    pub max_force_lsb_all: f64,
    /// Per clause of [`Contract::terms`]: the largest |term difference|, DAC LSB.
    pub term_lsb: Vec<f64>,
    /// Per clause of [`Contract::outputs`]: the largest |output difference|, SI.
    pub output_err: Vec<f64>,
    /// Events in the f64 run.
    pub events_f64: usize,
    /// Events in the fixed run.
    pub events_fixed: usize,
    /// Events of the f64 run with no partner in the fixed run, plus the reverse (an event is
    /// paired with the next unpaired one of the same kind within its time tolerance).
    pub unmatched: usize,
    /// Largest time shift of a paired event, samples.
    pub max_event_shift: usize,
    /// Largest relative difference of a paired event's arguments.
    pub max_arg_rel: f64,
    /// The largest shift of a paired event as a fraction of its kind's time tolerance.
    pub shift_ratio: f64,
    /// The largest relative difference of an argument as a fraction of its tolerance.
    pub arg_ratio: f64,
    /// The force clause read with the contract's time tolerance for events
    /// ([`Contract::event_time_s`], 0.5 ms by default): the largest distance, DAC LSB, from a
    /// sample's total force in either run to the nearest total force of the other run within
    /// that tolerance — (τ, ε)-closeness of hybrid trajectories (H. Abbas, G. Fainekos et
    /// al., "Conformance testing as falsification for cyber-physical systems", ACM TECS
    /// 2014). A contact that closes a sample apart (the piano's hammer landing back on the
    /// key, which emits no event) moves a force step by a sample: the strict clause
    /// ([`ContractCheck::max_force_lsb`]) sees the whole step, this one the step's shift as
    /// the event clause sees an event's. Measured only by a full comparison (`stop` off).
    pub max_force_lsb_within_time: f64,
    /// Samples where the two runs were in different discrete states.
    pub switch_samples: usize,
    /// How many times the runs fell into different discrete states (each the start of a
    /// switch window).
    pub switch_count: usize,
    /// The switches, in order (at most [`MAX_SWITCHES_KEPT`]; the worst is always kept).
    pub switches: Vec<Switch>,
    /// The worst switch's force as a fraction of its bound ([`Switch::force_lsb`] over
    /// [`Switch::bound_lsb`]; 0 without switches).
    pub switch_ratio: f64,
    /// Switches whose discrete states did not agree again within the window: a switch lost
    /// or added.
    pub switches_unresolved: usize,
    /// Switches that started within a window's length of the previous one or in its
    /// after-effect (chatter): the per-sample clause holds at their samples.
    pub switch_chatter: usize,
    /// Disagreements that started again inside an open switch window: the other run's side
    /// of the same switch (one run's hammer lands three samples before the other's, and the
    /// runs agree in between). The window measures them and its after-effect goes on.
    pub switch_rejoined: usize,
    /// Whether the fixed run was read against the reference re-timed to its switches
    /// ([`retimed::compare`]) — because against the recorded reference, its switches read
    /// as time shifts, some clause broke — and held there. Then every figure of this check
    /// is that reading's: the force per sample against the re-timed run at every sample,
    /// and each switch a disagreement with the re-timed run's own decisions.
    ///
    /// The re-timed reference is the f64 semantics stepped beside the fixed run, which
    /// takes the fixed run's branch decisions at the samples where its own differ, for at
    /// most the switch tolerance at a time (longer: a switch lost or added), and only
    /// decisions the f64 semantics itself takes within the switch tolerance of that sample
    /// (else a switch added, not moved): a switch
    /// decided a sample later — within the switch tolerance — and what the f64 semantics
    /// itself does with that timing. Its continuous values are the f64 semantics' own
    /// throughout, so an arithmetic error shows against it as against the recorded run.
    pub retimed: bool,
    /// Samples where the re-timed reference took the fixed run's decisions (0 unless
    /// [`ContractCheck::retimed`]).
    pub retimed_samples: usize,
    /// Where the recorded reading broke and the re-timed one broke too: the re-timed
    /// reading's largest per-sample force difference, DAC LSB (for the violation's message).
    pub retimed_force_lsb: Option<f64>,
    /// Samples where some fixed state lay outside its declared range.
    pub state_out_of_range: usize,
    /// Values that saturated (the range analysis claimed they cannot).
    pub overflowed: usize,
}

/// Most switches a [`ContractCheck`] keeps (a run of random sensor words can switch the
/// piano's contact every few samples); the count is [`ContractCheck::switch_count`].
pub const MAX_SWITCHES_KEPT: usize = 64;

/// One switch window of the contract's switch clause: the two runs fell into different
/// discrete states at `sample` (some branch decision of the update differed — a mode, an
/// `on` handler's edge, a body's or an `if … else`'s condition such as a Heaviside
/// contact), which is how a hybrid system's two simulations differ when one switches a
/// sample after the other (H. Abbas, G. Fainekos et al., "Conformance testing as
/// falsification for cyber-physical systems", ACM TECS 2014: (τ, ε)-closeness, a
/// trajectory within ε of the other's values within τ of each time).
///
/// The clause, with τ the switch window ([`Contract::switch_time_s`], 0.5 ms) and ε the
/// force tolerance plus the f64 force's own largest one-sample change near the switch:
/// * the discrete states agree again within τ ([`Switch::resolved`]);
/// * for τ from `sample` on, the state-driven part of each run's total force (the terms
///   that read a state, mode or edge: the piano's contact, impact pulse and let-off; the
///   other terms read only the sensor, whose words both runs share) lies within ε of the
///   other run's at some sample within τ, and the rest differs by at most ε minus that
///   distance at the same sample ([`Switch::force_lsb`] ≤ [`Switch::bound_lsb`]), instead
///   of the per-sample clause;
/// * after the window, until the per-sample clause holds again for a whole window's length
///   (the switch's after-effect: the runs go on from states a sample apart — the piano's
///   impact pulse, set at the landing a sample later, decays over milliseconds), each
///   sample the per-sample clause breaks is held to the same (τ, ε) distance with ε the
///   force tolerance alone: a time shift within τ and nothing more
///   ([`Switch::after_lsb`]);
/// * a disagreement that starts again before the window closes is the other run's side of
///   the same switch, not a new one ([`ContractCheck::switch_rejoined`]): one run's hammer
///   lands on the rest felt three samples before the other's and bounces, so the runs agree
///   for the two samples between the landings and disagree again at the second. The window
///   measures its samples (each disagreement must still end within τ) and the after-effect
///   goes on: after both landings the runs are a time shift of three samples apart, and the
///   pulse set by the landings decays over hundreds of samples;
/// * elsewhere the per-sample clause holds unchanged — also at a switch that starts within
///   τ of the last window or in its after-effect ([`ContractCheck::switch_chatter`]): a
///   contact chattering under sensor noise or arbitrary sensor words has no one switch time,
///   and a window there would excuse what the per-sample clause must catch (the planner's
///   runs of random sensor words are what refuse a product cut too far).
///
/// ε's second part is the reference's own discretisation uncertainty: the f64 run decides
/// a switch at a sample, so its contact closes anywhere within a sample period before it,
/// and the force right after the switch is uncertain by what the force changes in one
/// sample there — for a contact spring `k·ċ·T` (stiffness × closing speed × sample
/// period), which is what the largest one-sample change of the f64 force's state-driven
/// part within τ of the window measures, counted only where the f64 run itself does not
/// switch (a switch's own step is a time shift, which τ absorbs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Switch {
    /// The sample where the discrete states first differed.
    pub sample: usize,
    /// How many samples they differed before agreeing again (to the end of the run when
    /// they never did).
    pub samples: usize,
    /// Whether they agreed again within the window.
    pub resolved: bool,
    /// The first decision that differed, in words ([`Decision::describe`]).
    pub decision: String,
    /// Over the window: the largest distance from either run's total force to the other
    /// run's nearest total force within the window's length, DAC LSB.
    pub force_lsb: f64,
    /// The clause's bound there: the force tolerance plus [`Switch::slope_lsb`], DAC LSB.
    pub bound_lsb: f64,
    /// The f64 force's largest one-sample change within a window's length of the switch,
    /// where the f64 run does not switch, DAC LSB.
    pub slope_lsb: f64,
    /// Over the window: the largest |total force difference| at one sample, DAC LSB (what
    /// the per-sample clause would have seen).
    pub strict_lsb: f64,
    /// The after-effect: samples from the window's end to the last one the per-sample
    /// clause breaks before it holds for a whole window's length again (0: none).
    pub after_samples: usize,
    /// Over the after-effect's samples the per-sample clause breaks: the largest (τ, ε)
    /// distance as in the window (state-driven part to the other run's within τ, plus the
    /// rest's difference at the sample), DAC LSB; the clause bounds it by the force
    /// tolerance itself.
    pub after_lsb: f64,
}

/// One clause's worst case against its bound, for the precision report: (clause, worst,
/// bound, unit). The margin is `bound − worst`.
pub type Margin = (String, f64, f64, &'static str);

impl ContractCheck {
    /// Each clause of `c` with the worst this run showed (names from `p`).
    pub fn margins(&self, p: &Program, c: &Contract) -> Vec<Margin> {
        let mut m = vec![(
            "total force".to_string(),
            self.max_force_lsb,
            c.force.lsb(self.dac_lsb_n),
            "DAC LSB",
        )];
        for ((f, b), w) in c.terms.iter().zip(&self.term_lsb) {
            m.push((
                format!("force `{}`", p.forces[f.index()].name),
                *w,
                b.lsb(self.dac_lsb_n),
                "DAC LSB",
            ));
        }
        for ((o, b), w) in c.outputs.iter().zip(&self.output_err) {
            m.push((
                format!("output `{}`", p.outputs[o.index()].name),
                *w,
                *b,
                "SI",
            ));
        }
        m.push((
            "force at switches (of its bound)".into(),
            self.switch_ratio,
            1.0,
            "",
        ));
        m.push((
            "switches lost or added".into(),
            self.switches_unresolved as f64,
            0.0,
            "",
        ));
        m.push((
            "events lost or added".into(),
            self.unmatched as f64,
            0.0,
            "",
        ));
        m.push((
            "event time shift (of its tolerance)".into(),
            self.shift_ratio,
            1.0,
            "",
        ));
        m.push((
            "event arguments (of their tolerance)".into(),
            self.arg_ratio,
            1.0,
            "",
        ));
        m.push((
            "samples with a state out of range, saturations".into(),
            (self.state_out_of_range + self.overflowed) as f64,
            0.0,
            "",
        ));
        m
    }

    /// The clauses this run breaks, each as a sentence with the numbers (empty: it holds).
    pub fn violations(&self, c: &Contract, sample_rate_hz: f64) -> Vec<String> {
        let mut v = Vec::new();
        let lsb = self.dac_lsb_n;
        if self.max_force_lsb > c.force.lsb(lsb) {
            v.push(format!(
                "force differs by {:.3} DAC LSB{} (contract {})",
                self.max_force_lsb,
                if self.retimed {
                    " from the f64 run re-timed to the fixed run's switches"
                } else {
                    ""
                },
                c.force
            ));
        }
        if let Some(r) = self.retimed_force_lsb {
            v.push(format!(
                "and against the f64 run re-timed to the fixed run's switches the force differs by {r:.3} DAC LSB (contract {})",
                c.force
            ));
        }
        let window = (c.switch_time_s * sample_rate_hz).ceil();
        for w in self.switches.iter().filter(|w| !w.resolved) {
            v.push(format!(
                "a switch lost or added: the discrete states differ for {} samples from sample {} ({}), more than the switch tolerance {} ms ({window} samples)",
                w.samples,
                w.sample,
                w.decision,
                c.switch_time_s * 1e3
            ));
        }
        if self.switches_unresolved > self.switches.iter().filter(|w| !w.resolved).count() {
            v.push(format!(
                "{} switch(es) lost or added in all",
                self.switches_unresolved
            ));
        }
        if let Some(w) = self
            .switches
            .iter()
            .filter(|w| w.force_lsb > w.bound_lsb)
            .max_by(|a, b| (a.force_lsb / a.bound_lsb).total_cmp(&(b.force_lsb / b.bound_lsb)))
        {
            v.push(format!(
                "at a switch at sample {} ({}; states apart {} samples) the force is {:.3} DAC LSB from the f64 force within {} ms, bound {:.3} (contract {} + the f64 force's own one-sample change there, {:.3})",
                w.sample,
                w.decision,
                w.samples,
                w.force_lsb,
                c.switch_time_s * 1e3,
                w.bound_lsb,
                c.force,
                w.slope_lsb
            ));
        }
        if let Some(w) = self
            .switches
            .iter()
            .filter(|w| w.after_lsb > c.force.lsb(lsb))
            .max_by(|a, b| a.after_lsb.total_cmp(&b.after_lsb))
        {
            v.push(format!(
                "after a switch at sample {} ({}) the force is {:.3} DAC LSB from the f64 force within {} ms over its after-effect of {} samples (contract {})",
                w.sample,
                w.decision,
                w.after_lsb,
                c.switch_time_s * 1e3,
                w.after_samples,
                c.force
            ));
        }
        for ((f, b), w) in c.terms.iter().zip(&self.term_lsb) {
            if *w > b.lsb(lsb) {
                v.push(format!(
                    "force term {} differs by {w:.3} DAC LSB (contract {b})",
                    f.index()
                ));
            }
        }
        for ((o, b), w) in c.outputs.iter().zip(&self.output_err) {
            if *w > *b {
                v.push(format!(
                    "output {} differs by {w:e} (contract {b:e})",
                    o.index()
                ));
            }
        }
        if self.unmatched > 0 {
            v.push(format!(
                "{} event(s) lost or added ({} in f64, {} in fixed point)",
                self.unmatched, self.events_f64, self.events_fixed
            ));
        }
        if self.shift_ratio > 1.0 {
            v.push(format!(
                "an event moved by {} samples ({:.2} of its tolerance; default {:.1} samples)",
                self.max_event_shift,
                self.shift_ratio,
                c.event_time_s * sample_rate_hz
            ));
        }
        if self.arg_ratio > 1.0 {
            v.push(format!(
                "an event argument differs by {:.3} % ({:.2} of its tolerance; default {} %)",
                100.0 * self.max_arg_rel,
                self.arg_ratio,
                100.0 * c.event_arg_rel
            ));
        }
        if self.state_out_of_range > 0 || self.overflowed > 0 {
            v.push(format!(
                "states out of their ranges on {} samples, {} saturating values",
                self.state_out_of_range, self.overflowed
            ));
        }
        v
    }
}

/// One run of the f64 reference on one stimulus, recorded so that several fixed-point plans
/// of the same program can be compared with it ([`compare`]) without re-running it: the
/// planner's search ([`super::FixedProgram::with_config`]) compares dozens of plans.
#[derive(Clone, Debug)]
pub struct ReferenceRun {
    /// The quantised sensor word of each sample (first sensor; both engines read it).
    raw: Vec<i32>,
    /// The f64 total force of each sample, newtons.
    total: Vec<f64>,
    /// Per clause of the contract's `terms`, the f64 term of each sample, newtons.
    terms: Vec<Vec<f64>>,
    /// Per clause of the contract's `outputs`, the f64 output of each sample, SI.
    outputs: Vec<Vec<f64>>,
    /// (sample, event, arguments SI) of each event of the f64 run.
    events: Vec<(usize, usize, Vec<f64>)>,
    /// The run-time params' values (SI, [`Program::runtime_params`] order) this run used;
    /// empty for the params' own values.
    params: Vec<f64>,
    /// The discrete state of each sample: [`switches::words`] words per sample, bit `i` for
    /// decision `i` of [`switches::sites`] of the program.
    sig: Vec<u64>,
    /// Words per sample of `sig`.
    sig_words: usize,
    /// How the f64 run read each word: (lowest, highest raw word, fraction bits) — the
    /// word clamped to the sensor's raw range, in the sensor's format. The re-timed
    /// reference ([`ContractCheck::retimed`]) reads them the same way.
    sensor: (i32, i32, i32),
    /// The state-driven part of the f64 total force of each sample, newtons: the sum of the
    /// terms [`switches::state_driven_terms`] marks (the rest reads only sensors).
    driven: Vec<f64>,
}

impl ReferenceRun {
    /// Samples of the run.
    pub fn len(&self) -> usize {
        self.raw.len()
    }

    /// Whether the run has no sample.
    pub fn is_empty(&self) -> bool {
        self.raw.is_empty()
    }

    /// The f64 reading of sensor word `w` (SI), as the run read it.
    fn reading(&self, w: i32) -> f64 {
        let (lo, hi, frac) = self.sensor;
        fx::to_f64(w.clamp(lo, hi), frac)
    }
}

/// Runs the f64 interpreter of `p` on the key trajectory `keys` (metres, first sensor,
/// quantised to the sensor words of `fp`), with the run-time params at `params` (SI, in
/// [`Program::runtime_params`] order; empty: the params' own values), recording what the
/// clauses of `p.contract` need.
///
/// Errors: [`ParamBlockError`] (naming the param) when `params` is not empty and does not
/// give one value within its planned interval per run-time param of `fp`.
pub fn reference(
    p: &Program,
    fp: &FixedProgram,
    keys: &[f64],
    params: &[f64],
) -> Result<ReferenceRun, ParamBlockError> {
    let raw: Vec<i32> = keys
        .iter()
        .map(|&k| FixedInstance::sensor_raw(fp, 0, Some(k)))
        .collect();
    reference_raw(p, fp, &raw, params)
}

/// The param block a run with run-time params `params` (SI; empty: the params' own values)
/// gives `fp`'s fixed engines.
fn block_of(fp: &FixedProgram, params: &[f64]) -> Result<Vec<i32>, ParamBlockError> {
    if params.is_empty() {
        Ok(fp.nominal_param_block())
    } else {
        fp.param_block(params)
    }
}

/// [`reference`] from raw words of the first sensor, as a sensor delivers them (the budget
/// corpus: glitches, words outside the declared range, arbitrary words). Both engines read
/// each word as the fixed engines do: the f64 interpreter gets the word's value in the
/// sensor's format, clamped to the declared range as every engine clamps a reading.
///
/// Errors: as [`reference`].
pub fn reference_raw(
    p: &Program,
    fp: &FixedProgram,
    raw: &[i32],
    params: &[f64],
) -> Result<ReferenceRun, ParamBlockError> {
    // The fixed engines will need these values as a param block: refused here, before the
    // f64 run, rather than compared against another program's params.
    block_of(fp, params)?;
    Ok(record(p, fp, raw, params))
}

/// The state-driven force terms of `p` that its total sums (a pen's `z` axis, a keyboard's
/// every term), as indices.
fn total_terms(p: &Program) -> Vec<usize> {
    switches::state_driven_terms(p)
        .into_iter()
        .enumerate()
        .filter(|&(i, d)| d && matches!(p.forces[i].axis, None | Some(crate::ir::Axis::Z)))
        .map(|(i, _)| i)
        .collect()
}

/// `p` with its run-time params at `params` (SI, [`Program::runtime_params`] order; empty:
/// `p` itself), the program a reference run of those params interprets.
fn with_params<'p>(p: &'p Program, params: &[f64]) -> std::borrow::Cow<'p, Program> {
    if params.is_empty() {
        return std::borrow::Cow::Borrowed(p);
    }
    let mut q = p.clone();
    let ids: Vec<_> = q.runtime_params().collect();
    for (id, &v) in ids.iter().zip(params) {
        q.params[id.index()].value = v;
    }
    std::borrow::Cow::Owned(q)
}

/// [`reference_raw`] once `params` is known to fit `fp`.
fn record(p: &Program, fp: &FixedProgram, raw: &[i32], params: &[f64]) -> ReferenceRun {
    let prog = with_params(p, params);
    let prog = &*prog;
    let c = &p.contract;
    let mut a = Instance::new(prog);
    let n = raw.len();
    let sites = switches::sites(prog);
    let sig_words = switches::words(sites.len());
    let mut run = ReferenceRun {
        raw: Vec::with_capacity(n),
        total: Vec::with_capacity(n),
        terms: vec![Vec::with_capacity(n); c.terms.len()],
        outputs: vec![Vec::with_capacity(n); c.outputs.len()],
        events: Vec::new(),
        params: params.to_vec(),
        sig: vec![0; n * sig_words],
        sig_words,
        driven: Vec::with_capacity(n),
        sensor: (
            fp.sensor_raw_range[0].0,
            fp.sensor_raw_range[0].1,
            fp.sensor_frac[0],
        ),
    };
    let driven = total_terms(prog);
    for (n, &w) in raw.iter().enumerate() {
        let oa = a.step(&[run.reading(w)]);
        run.raw.push(w);
        run.total.push(oa.total);
        run.driven
            .push(driven.iter().map(|f| oa.forces[*f]).sum::<f64>());
        for (t, (f, _)) in run.terms.iter_mut().zip(&c.terms) {
            t.push(oa.forces[f.index()]);
        }
        for (t, (o, _)) in run.outputs.iter_mut().zip(&c.outputs) {
            t.push(oa.outputs[o.index()]);
        }
        run.events
            .extend(oa.events.iter().map(|e| (n, e.0.index(), e.1.clone())));
        let vals = a.values();
        switches::signature(
            &sites,
            |v| vals[v.index()] != 0.0,
            a.modes(),
            &mut run.sig[n * sig_words..(n + 1) * sig_words],
        );
    }
    run
}

/// Runs the fixed interpreter of `fp` on the samples of a recorded reference run and
/// measures each clause of `c` against it (`c` must have the clauses of `p.contract` the run
/// recorded, scaled or not). With `stop`, the run ends at the first sample whose force,
/// terms, outputs or states break `c` (the planner's search only needs to know that a plan
/// fails); the events are compared over the samples run. The fixed engine runs with the
/// param block of the run's params ([`FixedProgram::param_block`]).
///
/// Errors: [`ParamBlockError`] (naming the param) when the run's params do not fit `fp`'s
/// run-time params (their number, or a value outside its planned interval): `fp` is then
/// not the program the run was recorded for, and no comparison is made.
pub fn compare(
    p: &Program,
    fp: &FixedProgram,
    run: &ReferenceRun,
    dac_lsb_n: f64,
    c: &Contract,
    stop: bool,
) -> Result<ContractCheck, ParamBlockError> {
    let block = block_of(fp, &run.params)?;
    Ok(compare_block(p, fp, run, block, dac_lsb_n, c, stop))
}

/// [`compare`] with the param block given: the fixed run against the recorded reference,
/// switches read as time shifts ([`Switch`]); where that breaks a clause after the runs fell
/// into different discrete states, against the reference re-timed to the fixed run's
/// switches ([`ContractCheck::retimed`], [`retimed::compare`]) — the run holds if either
/// reading holds.
fn compare_block(
    p: &Program,
    fp: &FixedProgram,
    run: &ReferenceRun,
    block: Vec<i32>,
    dac_lsb_n: f64,
    c: &Contract,
    stop: bool,
) -> ContractCheck {
    let first = compare_recorded(p, fp, run, block.clone(), dac_lsb_n, c, stop);
    if first.switch_count == 0 || first.violations(c, p.sample_rate_hz).is_empty() {
        return first;
    }
    let second = retimed::compare(p, fp, run, block, dac_lsb_n, c, stop);
    if second.violations(c, p.sample_rate_hz).is_empty() {
        second
    } else {
        ContractCheck {
            retimed_force_lsb: Some(second.max_force_lsb),
            ..first
        }
    }
}

/// The fixed run of `fp` with param block `block` against the recorded reference `run`,
/// switches read as time shifts (see [`compare`]).
fn compare_recorded(
    p: &Program,
    fp: &FixedProgram,
    run: &ReferenceRun,
    block: Vec<i32>,
    dac_lsb_n: f64,
    c: &Contract,
    stop: bool,
) -> ContractCheck {
    let mut b = FixedInstance::with_params(fp, block);
    let mut out = ContractCheck {
        dac_lsb_n,
        term_lsb: vec![0.0; run.terms.len()],
        output_err: vec![0.0; run.outputs.len()],
        ..ContractCheck::default()
    };
    let force_limit = c.force.lsb(dac_lsb_n);
    let mut ev_b: Vec<(usize, usize, Vec<f64>)> = Vec::new();
    let mut ran = run.raw.len();
    let mut fixed_total: Vec<f64> = Vec::with_capacity(run.raw.len());
    let mut fixed_driven: Vec<f64> = Vec::with_capacity(run.raw.len());
    let driven = total_terms(p);
    // The switch clause: the decisions both programs have, the fixed run's signature, the
    // open disagreement (its first sample) and the end of the last switch window.
    let sites_a = switches::sites(p);
    let sites_b = switches::sites(&fp.program);
    let pairs = switches::matched(&sites_a, &sites_b);
    let mut sig_b = vec![0u64; switches::words(sites_b.len())];
    let window = (c.switch_time_s * p.sample_rate_hz).ceil() as usize;
    let mut open: Option<usize> = None;
    let mut windows: Vec<(usize, usize, Option<usize>, bool)> = Vec::new();
    let mut cover_end = 0;
    // After a window, the samples the per-sample clause breaks until it holds for a whole
    // window's length (the switch's after-effect), per window.
    let mut after: Vec<Vec<usize>> = Vec::new();
    let mut agreeing = window;
    let mut last_window: Option<usize> = None;
    let mut chattered: Vec<bool> = Vec::new();
    // The window whose after-effect runs (the last one a switch opened).
    let mut owner = 0;
    for (n, (&raw, &total)) in run.raw.iter().zip(&run.total).enumerate() {
        let ob = b.step_raw(&[raw]);
        out.samples += 1;
        let ft = fx::to_f64(ob.total, fp.total_frac);
        let diff = (total - ft).abs() / dac_lsb_n;
        out.max_force_lsb_all = out.max_force_lsb_all.max(diff);
        fixed_total.push(ft);
        fixed_driven.push(
            driven
                .iter()
                .map(|&i| fx::to_f64(ob.forces[i], fp.force_frac[i]))
                .sum::<f64>(),
        );
        let mut broken = false;
        for (k, ((f, bound), series)) in c.terms.iter().zip(&run.terms).enumerate() {
            let i = f.index();
            let x = fx::to_f64(ob.forces[i], fp.force_frac[i]);
            let e = (series[n] - x).abs() / dac_lsb_n;
            out.term_lsb[k] = out.term_lsb[k].max(e);
            broken |= e > bound.lsb(dac_lsb_n);
        }
        for (k, ((o, bound), series)) in c.outputs.iter().zip(&run.outputs).enumerate() {
            let i = o.index();
            let x = fx::to_f64(ob.outputs[i], fp.output_frac[i]);
            let e = (series[n] - x).abs();
            out.output_err[k] = out.output_err[k].max(e);
            broken |= e > *bound;
        }
        push_fixed_events(fp, n, &ob.events, &mut ev_b);
        // The discrete states of this sample.
        let vals = b.values();
        switches::signature(&sites_b, |v| vals[v.index()] != 0, b.modes(), &mut sig_b);
        let sa = &run.sig[n * run.sig_words..(n + 1) * run.sig_words];
        let differ = pairs
            .iter()
            .find(|&&(i, j)| switches::bit(sa, i) != switches::bit(&sig_b, j));
        match (differ, open) {
            (Some(&(i, _)), None) => {
                open = Some(windows.len());
                windows.push((n, i, None, false));
                after.push(Vec::new());
                out.switch_count += 1;
                // A disagreement that starts again inside the open window is the other
                // side of that window's switch (one run's hammer lands at n, the other's
                // at n + 3: the runs agree in between, both in the air or both landed and
                // bounced): the window measures its samples and the switch's after-effect
                // goes on. An isolated switch gets its window; one that starts within a
                // window's length after the last window, or in its after-effect, is
                // chatter (a contact bouncing under sensor noise or arbitrary words has no
                // one switch time): the per-sample clause holds there.
                let rejoined = n < cover_end;
                let chatter =
                    !rejoined && (last_window.is_some_and(|e| n < e + window) || agreeing < window);
                chattered.push(chatter || rejoined);
                if rejoined {
                    out.switch_rejoined += 1;
                } else if chatter {
                    agreeing = window;
                    out.switch_chatter += 1;
                } else {
                    cover_end = n + window;
                    agreeing = 0;
                    owner = windows.len() - 1;
                }
                if !rejoined {
                    last_window = Some(n + window);
                }
            }
            (None, Some(w)) => {
                windows[w].2 = Some(n - windows[w].0);
                open = None;
            }
            _ => {}
        }
        if differ.is_some() {
            out.switch_samples += 1;
        }
        if let Some(w) = open {
            // Still apart when the window closes: a switch lost or added.
            if n + 1 - windows[w].0 > window && !windows[w].3 {
                windows[w].3 = true;
                out.switches_unresolved += 1;
                broken = true;
            }
        }
        // The per-sample force clause, outside the switch windows and their after-effects.
        if n >= cover_end {
            if agreeing >= window {
                out.max_force_lsb = out.max_force_lsb.max(diff);
                broken |= diff > force_limit;
            } else if diff > force_limit {
                agreeing = 0;
                after[owner].push(n);
            } else {
                agreeing += 1;
            }
        }
        let outside = states_out_of_range(fp, b.states());
        out.state_out_of_range += outside as usize;
        if stop && (broken || outside) {
            ran = n + 1;
            break;
        }
    }
    // The switch windows' force clause, now that both runs are known around them.
    for (((start, site, len, unresolved), after), chatter) in
        windows.into_iter().zip(after).zip(chattered)
    {
        let mut s = switch_window(
            run,
            (&fixed_total, &fixed_driven),
            start,
            window,
            force_limit * dac_lsb_n,
            dac_lsb_n,
        );
        if chatter {
            // The per-sample clause measured its samples.
            s.force_lsb = 0.0;
        }
        // The after-effect: each sample within the force tolerance of a time shift.
        let near = |x: f64, other: &[f64], n: usize| {
            other[n.saturating_sub(window)..(n + window + 1).min(other.len())]
                .iter()
                .map(|&y| (x - y).abs())
                .fold(f64::INFINITY, f64::min)
        };
        let after_lsb = after
            .iter()
            .map(|&n| {
                let q = ((run.total[n] - run.driven[n]) - (fixed_total[n] - fixed_driven[n])).abs();
                near(fixed_driven[n], &run.driven, n).max(near(run.driven[n], &fixed_driven, n)) + q
            })
            .fold(0.0, f64::max)
            / dac_lsb_n;
        let s = Switch {
            after_samples: after.last().map_or(0, |&l| l + 1 - (start + window)),
            after_lsb,
            ..s
        };
        let ratio = (s.force_lsb / s.bound_lsb).max(s.after_lsb / force_limit);
        let w = Switch {
            samples: len.unwrap_or(ran - start),
            resolved: !unresolved,
            decision: sites_a[site].describe(p),
            ..s
        };
        let worst = ratio > out.switch_ratio;
        out.switch_ratio = out.switch_ratio.max(ratio);
        if out.switches.len() < MAX_SWITCHES_KEPT {
            out.switches.push(w);
        } else if worst || unresolved {
            // Keep the worst (and the lost ones) in place of the last kept.
            *out.switches.last_mut().expect("kept") = w;
        }
    }
    if !stop {
        let window = (c.event_time_s * p.sample_rate_hz).ceil() as usize;
        let a = &run.total[..fixed_total.len()];
        out.max_force_lsb_within_time =
            closeness(a, &fixed_total, window).max(closeness(&fixed_total, a, window)) / dac_lsb_n;
    }
    out.overflowed = b.overflowed().iter().filter(|o| **o).count();
    let ev_a: Vec<&(usize, usize, Vec<f64>)> = run.events.iter().filter(|e| e.0 < ran).collect();
    pair_events(&mut out, &ev_a, &ev_b, c, p.sample_rate_hz);
    out
}

/// Whether a state word of the fixed run (`states`, raw words in `fp.state_frac`) lies
/// outside its state's declared range (SI) — the contract's state clause for one sample.
fn states_out_of_range(fp: &FixedProgram, states: &[i32]) -> bool {
    states.iter().enumerate().any(|(i, &w)| {
        let x = fx::to_f64(w, fp.state_frac[i]);
        let (lo, hi) = fp.program.states[i].range;
        x < lo || x > hi
    })
}

/// The fixed run's events of sample `n` (`events`: each event and its raw argument words)
/// appended to `out` as (sample, event index, arguments in SI units, each word read in its
/// argument's format, `fp.event_frac`).
fn push_fixed_events(
    fp: &FixedProgram,
    n: usize,
    events: &[(EventId, Vec<i32>)],
    out: &mut Vec<(usize, usize, Vec<f64>)>,
) {
    for (e, args) in events {
        let f = &fp.event_frac[e.index()];
        let si = args
            .iter()
            .zip(f)
            .map(|(&x, &f)| fx::to_f64(x, f))
            .collect();
        out.push((n, e.index(), si));
    }
}

/// The event clauses of a comparison: the f64 run's events `ev_a` and the fixed run's
/// `ev_b` as (sample, event, arguments SI), paired in order, per kind, within the kind's
/// time tolerance (a larger shift counts as a lost plus an added event), into `out`'s
/// counts, shifts and argument errors.
fn pair_events(
    out: &mut ContractCheck,
    ev_a: &[&(usize, usize, Vec<f64>)],
    ev_b: &[(usize, usize, Vec<f64>)],
    c: &Contract,
    sample_rate_hz: f64,
) {
    out.events_f64 = ev_a.len();
    out.events_fixed = ev_b.len();
    let mut used = vec![false; ev_b.len()];
    for &(na, ka, args_a) in ev_a {
        let tol = c.time_of(*ka) * sample_rate_hz;
        let window = tol.ceil() as usize;
        let partner = ev_b
            .iter()
            .enumerate()
            .find(|(j, (nb, kb, _))| !used[*j] && kb == ka && na.abs_diff(*nb) <= window);
        match partner {
            Some((j, (nb, _, args_b))) => {
                used[j] = true;
                let shift = na.abs_diff(*nb);
                out.max_event_shift = out.max_event_shift.max(shift);
                out.shift_ratio = out.shift_ratio.max(shift as f64 / tol.max(1e-12));
                for (i, (x, y)) in args_a.iter().zip(args_b).enumerate() {
                    let rel = (x - y).abs() / x.abs().max(1e-12);
                    out.max_arg_rel = out.max_arg_rel.max(rel);
                    out.arg_ratio = out.arg_ratio.max(rel / c.arg_rel_of(*ka, i));
                }
            }
            None => out.unmatched += 1,
        }
    }
    out.unmatched += used.iter().filter(|u| !**u).count();
}

/// The force figures of the switch window of `window` samples from `start` ([`Switch`]),
/// DAC LSB of `lsb` newtons, from the f64 run and the fixed run's (total, state-driven
/// part) per sample (newtons). Each total is split into its state-driven part `S` (the
/// terms a switch moves) and the rest `Q` (terms of sensors only, which both runs compute
/// from the same words at the same sample): at each sample of the window the distance is
/// the (τ, ε) distance of either run's `S` to the other's nearest `S` within `window`
/// samples, plus `|ΔQ|` at that sample. The bound is `tol_n` plus the f64 run's largest
/// one-sample change of `S` within `window` samples of the window where its discrete state
/// does not change. `decision`, `samples` and `resolved` are left to the caller.
fn switch_window(
    run: &ReferenceRun,
    (fixed, fixed_s): (&[f64], &[f64]),
    start: usize,
    window: usize,
    tol_n: f64,
    lsb: f64,
) -> Switch {
    let sa = &run.driven;
    let end = (start + window).min(fixed.len());
    let near = |x: f64, other: &[f64], n: usize| {
        other[n.saturating_sub(window)..(n + window + 1).min(other.len())]
            .iter()
            .map(|&y| (x - y).abs())
            .fold(f64::INFINITY, f64::min)
    };
    let (mut force, mut strict) = (0.0f64, 0.0f64);
    for n in start..end {
        let q = ((run.total[n] - sa[n]) - (fixed[n] - fixed_s[n])).abs();
        let d = near(fixed_s[n], sa, n).max(near(sa[n], fixed_s, n)) + q;
        force = force.max(d);
        strict = strict.max((run.total[n] - fixed[n]).abs());
    }
    let w = run.sig_words;
    let same = |m: usize| run.sig[(m - 1) * w..m * w] == run.sig[m * w..(m + 1) * w];
    let slope = (start.saturating_sub(window).max(1)..(start + 2 * window + 1).min(sa.len()))
        .filter(|&m| same(m))
        .map(|m| (sa[m] - sa[m - 1]).abs())
        .fold(0.0, f64::max);
    Switch {
        sample: start,
        force_lsb: force / lsb,
        bound_lsb: (tol_n + slope) / lsb,
        slope_lsb: slope / lsb,
        strict_lsb: strict / lsb,
        ..Switch::default()
    }
}

/// The largest distance from a sample of `a` to the nearest sample of `b` at most `window`
/// samples away (the one-sided (τ, ε)-closeness of [`ContractCheck::max_force_lsb_within_time`]).
fn closeness(a: &[f64], b: &[f64], window: usize) -> f64 {
    let mut worst: f64 = 0.0;
    for (n, &x) in a.iter().enumerate() {
        let near = &b[n.saturating_sub(window)..(n + window + 1).min(b.len())];
        let d = near
            .iter()
            .map(|&y| (x - y).abs())
            .fold(f64::INFINITY, f64::min);
        if d.is_finite() {
            worst = worst.max(d);
        }
    }
    worst
}

/// Runs the f64 interpreter of `p` and the fixed interpreter of `fp` side by side on the key
/// trajectory `keys` (metres, first sensor; the f64 engine reads the same quantised samples)
/// and measures each clause of `p.contract`. `dac_lsb_n` is one DAC LSB in newtons.
pub fn check(p: &Program, fp: &FixedProgram, keys: &[f64], dac_lsb_n: f64) -> ContractCheck {
    let raw: Vec<i32> = keys
        .iter()
        .map(|&k| FixedInstance::sensor_raw(fp, 0, Some(k)))
        .collect();
    let run = record(p, fp, &raw, &[]);
    compare_block(
        p,
        fp,
        &run,
        fp.nominal_param_block(),
        dac_lsb_n,
        &p.contract,
        false,
    )
}

/// The accuracy contract broken on a built-in stimulus: what `tactus check --report
/// precision` exits 1 for and `tactus build`, `budget` and `play` refuse.
#[derive(Clone, Debug, PartialEq)]
pub struct Broken {
    /// The instrument.
    pub instrument: String,
    /// The first stimulus (of [`check_builtin`]'s order) on which a clause breaks.
    pub stimulus: String,
    /// The clauses it breaks, each a sentence with its numbers
    /// ([`ContractCheck::violations`]).
    pub violations: Vec<String>,
}

impl std::fmt::Display for Broken {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "`{}`: its accuracy contract does not hold in fixed point on the built-in stimulus `{}`: {} \
             (`tactus check --report precision` gives every clause's margin; loosen a `tolerance`, or \
             narrow the ranges the formats are planned for)",
            self.instrument,
            self.stimulus,
            self.violations.join("; ")
        )
    }
}

impl std::error::Error for Broken {}

/// The first of `runs` ([`check_builtin`]'s) that breaks `p`'s contract, as [`Broken`].
///
/// Errors: [`Broken`].
pub fn holds_on(p: &Program, runs: &[(&str, ContractCheck)]) -> Result<(), Broken> {
    for (stim, c) in runs {
        let v = c.violations(&p.contract, p.sample_rate_hz);
        if !v.is_empty() {
            return Err(Broken {
                instrument: p.name.clone(),
                stimulus: stim.to_string(),
                violations: v,
            });
        }
    }
    Ok(())
}

/// Whether `fp` keeps `p`'s accuracy contract on every built-in stimulus
/// ([`check_builtin`], [`holds_on`]); a program of several sensors (a pen) has no built-in
/// stimuli and passes.
///
/// Errors: [`Broken`].
pub fn verdict(p: &Program, fp: &FixedProgram) -> Result<(), Broken> {
    // A deterministic simulation of the program and its plan: memoised per process and on
    // disk with the plans (`plan_cache`), so `tactus budget`, `build` and `play` of a piano
    // pay it once.
    let key = format!(
        "{p:?}\n{:?}\n{:?}\n{:?}",
        fp.mul_kind,
        fp.frac,
        fp.nominal_param_block()
    );
    let broken = super::plan_cache::verdict_once(&key, || {
        holds_on(p, &check_builtin(p, fp))
            .err()
            .map(|b| (b.stimulus, b.violations))
    });
    match broken {
        None => Ok(()),
        Some((stimulus, violations)) => Err(Broken {
            instrument: p.name.clone(),
            stimulus,
            violations,
        }),
    }
}

/// Every built-in stimulus of a keyboard program (one sensor) through both engines,
/// clause by clause against `p.contract`: (stimulus, what it showed). Empty for a program of
/// several sensors (a pen), whose stimuli are not key dips.
pub fn check_builtin(p: &Program, fp: &FixedProgram) -> Vec<(&'static str, ContractCheck)> {
    if p.sensors.len() != 1 {
        return Vec::new();
    }
    let lsb = super::report::analyse(fp).dac_lsb_n();
    tactus_runtime::stimulus::builtin_names()
        .iter()
        .filter_map(|(stim, _)| {
            let s = tactus_runtime::stimulus::builtin(stim, p.sensors[0].range.1, p.sample_rate_hz)
                .ok()?;
            Some((*stim, check(p, fp, &s.key, lsb)))
        })
        .collect()
}
