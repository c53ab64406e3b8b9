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
//! saturation. [`Contract::default`] holds the issue-16 defaults; there is no `tolerance`
//! syntax in the language yet, so an instrument cannot change them.

use super::interp::FixedInstance;
use super::FixedProgram;
use crate::interp::Instance;
use crate::ir::Program;
use tactus_runtime::fixed as fx;

/// The clauses of an accuracy contract.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contract {
    /// The total force at the key may differ from f64 by this many LSBs of a 16-bit DAC at
    /// `full_scale` (the report's [`super::report::Precision::dac_lsb_n`]), at every sample.
    pub force_lsb: f64,
    /// An event may happen this much earlier or later than in f64, seconds (0.5 ms: 22
    /// samples at 44.1 kHz).
    pub event_time_s: f64,
    /// An event's arguments may differ from f64 by this fraction of the f64 value (1 %: a
    /// third of a MIDI velocity step at mf).
    pub event_arg_rel: f64,
}

impl Default for Contract {
    fn default() -> Self {
        Contract {
            force_lsb: 1.0,
            event_time_s: 0.5e-3,
            event_arg_rel: 0.01,
        }
    }
}

/// What one run showed, clause by clause (the worst over its samples and events).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ContractCheck {
    /// Samples compared.
    pub samples: usize,
    /// Largest |total force difference|, in DAC LSB.
    pub max_force_lsb: f64,
    /// Events in the f64 run.
    pub events_f64: usize,
    /// Events in the fixed run.
    pub events_fixed: usize,
    /// Events of the f64 run with no partner in the fixed run, plus the reverse (an event is
    /// paired with the next unpaired one of the same kind within the time tolerance).
    pub unmatched: usize,
    /// Largest time shift of a paired event, samples.
    pub max_event_shift: usize,
    /// Largest relative difference of a paired event's arguments.
    pub max_arg_rel: f64,
    /// Samples where some fixed state lay outside its declared range.
    pub state_out_of_range: usize,
    /// Values that saturated (the range analysis claimed they cannot).
    pub overflowed: usize,
}

impl ContractCheck {
    /// The clauses this run breaks, each as a sentence with the numbers (empty: it holds).
    pub fn violations(&self, c: &Contract, sample_rate_hz: f64) -> Vec<String> {
        let mut v = Vec::new();
        if self.max_force_lsb > c.force_lsb {
            v.push(format!(
                "force differs by {:.3} DAC LSB (contract {})",
                self.max_force_lsb, c.force_lsb
            ));
        }
        if self.unmatched > 0 {
            v.push(format!(
                "{} event(s) lost or added ({} in f64, {} in fixed point)",
                self.unmatched, self.events_f64, self.events_fixed
            ));
        }
        let max_shift = c.event_time_s * sample_rate_hz;
        if self.max_event_shift as f64 > max_shift {
            v.push(format!(
                "an event moved by {} samples (contract {:.1})",
                self.max_event_shift, max_shift
            ));
        }
        if self.max_arg_rel > c.event_arg_rel {
            v.push(format!(
                "an event argument differs by {:.3} % (contract {} %)",
                100.0 * self.max_arg_rel,
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

/// Runs the f64 interpreter of `p` and the fixed interpreter of `fp` side by side on the key
/// trajectory `keys` (metres, first sensor; the f64 engine reads the same quantised samples)
/// and measures each clause. `dac_lsb_n` is one DAC LSB in newtons.
pub fn check(p: &Program, fp: &FixedProgram, keys: &[f64], dac_lsb_n: f64) -> ContractCheck {
    let mut a = Instance::new(p);
    let mut b = FixedInstance::new(fp);
    let mut out = ContractCheck::default();
    // (sample, event, args) of each run.
    let mut ev_a: Vec<(usize, usize, Vec<f64>)> = Vec::new();
    let mut ev_b: Vec<(usize, usize, Vec<f64>)> = Vec::new();
    for (n, &k) in keys.iter().enumerate() {
        let raw = FixedInstance::sensor_raw(fp, 0, Some(k));
        let oa = a.step(&[fx::to_f64(raw, fp.sensor_frac[0])]).clone();
        let ob = b.step_raw(&[raw]).to_si(fp);
        out.samples += 1;
        out.max_force_lsb = out
            .max_force_lsb
            .max((oa.total - ob.total).abs() / dac_lsb_n);
        ev_a.extend(oa.events.iter().map(|e| (n, e.0.index(), e.1.clone())));
        ev_b.extend(ob.events.iter().map(|e| (n, e.0.index(), e.1.clone())));
        let outside = b.states().iter().enumerate().any(|(i, &w)| {
            let x = fx::to_f64(w, fp.state_frac[i]);
            let (lo, hi) = p.states[i].range;
            x < lo || x > hi
        });
        out.state_out_of_range += outside as usize;
    }
    out.overflowed = b.overflowed().iter().filter(|o| **o).count();
    out.events_f64 = ev_a.len();
    out.events_fixed = ev_b.len();
    // Pair events in order, per kind, within the time tolerance window of 0.5 ms (the
    // contract's default; a larger shift counts as a lost plus an added event).
    let window = (Contract::default().event_time_s * p.sample_rate_hz).ceil() as usize;
    let mut used = vec![false; ev_b.len()];
    for (na, ka, args_a) in &ev_a {
        let partner = ev_b
            .iter()
            .enumerate()
            .find(|(j, (nb, kb, _))| !used[*j] && kb == ka && na.abs_diff(*nb) <= window);
        match partner {
            Some((j, (nb, _, args_b))) => {
                used[j] = true;
                out.max_event_shift = out.max_event_shift.max(na.abs_diff(*nb));
                for (x, y) in args_a.iter().zip(args_b) {
                    let rel = (x - y).abs() / x.abs().max(1e-12);
                    out.max_arg_rel = out.max_arg_rel.max(rel);
                }
            }
            None => out.unmatched += 1,
        }
    }
    out.unmatched += used.iter().filter(|u| !**u).count();
    out
}
