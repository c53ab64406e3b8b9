//! The one engine trait of the play loop: a group of keys stepped together, one call per
//! sample with each key's travel. A host engine is one key's instance of any
//! [`tactus_compiler::sim::Engine`] (the f64 interpreter, the f64 JIT, the fixed-point
//! JIT, all seen in SI); the firmware of a board on the emulated RP2040
//! ([`super::emulated::BoardEngine`]) is all the keys of that board, since its sample
//! interrupt runs them together.
//!
//! Strikes are read through [`super::strike::strike_event`], the one strike rule.

use super::error::RunError;
use super::strike::strike_event;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::interp::SampleOut;
use tactus_compiler::ir::{EventId, Program};
use tactus_compiler::sim::Engine;

/// What one sample of one key gives the play loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeySample {
    /// The commanded force at the key, N (positive pushes the key up; the firmware's force
    /// word before the safety limiter).
    pub force_n: f64,
    /// The hammer (or plectrum) speed of a strike emitted this sample, m/s.
    pub strike_mps: Option<f64>,
    /// The motor current the safety limiter allowed, A (`NaN` on a host engine, which has no
    /// limiter).
    pub current_a: f64,
    /// The DAC code written (`NaN` on a host engine).
    pub dac: f64,
}

impl Default for KeySample {
    fn default() -> Self {
        KeySample {
            force_n: 0.0,
            strike_mps: None,
            current_a: f64::NAN,
            dac: f64::NAN,
        }
    }
}

/// A group of keys the play loop steps together, sample by sample.
pub trait KeyEngine {
    /// Runs one sample: `travel_m[k]` is key `k`'s travel (m, 0 = rest); returns one
    /// [`KeySample`] per key.
    ///
    /// Errors: a message when the engine cannot run the sample (an emulated board that
    /// faults).
    fn step(&mut self, travel_m: &[f64]) -> Result<&[KeySample], RunError>;
    /// Runs up to `most` samples in which every key holds the travel `travel_m` of the
    /// last [`KeyEngine::step`], when the engine can give them without running each (an
    /// emulated board replaying a rest) and none of them strikes; returns how many it ran
    /// (0: none, the caller steps them one at a time). What it runs is what as many steps
    /// would have run. The default runs none.
    ///
    /// Errors: as [`KeyEngine::step`].
    fn step_held(&mut self, travel_m: &[f64], most: usize) -> Result<usize, RunError> {
        let _ = (travel_m, most);
        Ok(0)
    }
    /// Key `k`'s hammer-head travel from rest after the last step, m (`NaN` when its
    /// instrument has no `hammer_pos` output). Read only for traced keys.
    fn hammer_m(&self, k: usize) -> f64;
}

/// One key on a host engine: any [`Engine`] seen through the strike rule.
pub struct HostKey<'a> {
    engine: Box<dyn Engine + 'a>,
    strike: Option<EventId>,
    hammer_out: Option<usize>,
    last: SampleOut,
    sample: [KeySample; 1],
}

impl<'a> HostKey<'a> {
    /// One key of `program` (the IR the engine runs: for the fixed-point JIT, the fixed
    /// program's IR) on `engine`.
    pub fn new(program: &Program, engine: Box<dyn Engine + 'a>) -> Self {
        HostKey {
            engine,
            strike: strike_event(program),
            hammer_out: program.outputs.iter().position(|o| o.name == "hammer_pos"),
            last: SampleOut::default(),
            sample: [KeySample::default()],
        }
    }
}

impl KeyEngine for HostKey<'_> {
    fn step(&mut self, travel_m: &[f64]) -> Result<&[KeySample], RunError> {
        self.last = self.engine.step_si(&travel_m[..1]);
        let out = &self.last;
        self.sample[0] = KeySample {
            force_n: out.total,
            strike_mps: out
                .events
                .iter()
                .find(|(e, _)| Some(*e) == self.strike)
                .map(|(_, a)| a.first().copied().unwrap_or(0.0)),
            ..KeySample::default()
        };
        Ok(&self.sample)
    }

    fn hammer_m(&self, _k: usize) -> f64 {
        self.hammer_out
            .and_then(|i| self.last.outputs.get(i).copied())
            .unwrap_or(f64::NAN)
    }
}

/// The f64 JIT seen as a simulation engine.
#[derive(Clone)]
pub struct JitEngine<'j>(pub tactus_jit::JitInstance<'j>);

impl Engine for JitEngine<'_> {
    fn step_si(&mut self, sensors: &[f64]) -> SampleOut {
        self.0.step(sensors).clone()
    }
    fn states_si(&self) -> Vec<f64> {
        self.0.states().to_vec()
    }
    fn modes_now(&self) -> Vec<u32> {
        self.0.modes().to_vec()
    }
    fn state_saturations(&self) -> Vec<u64> {
        self.0.saturations().to_vec()
    }
}

/// The fixed-point JIT seen as a simulation engine (SI through the format plan, as
/// `FixedInstance` is).
#[derive(Clone)]
pub struct FixedJitEngine<'j>(
    pub tactus_jit::fixed::FixedJitInstance<'j>,
    pub &'j FixedProgram,
);

impl Engine for FixedJitEngine<'_> {
    fn step_si(&mut self, sensors: &[f64]) -> SampleOut {
        let fp = self.1;
        self.0.step(sensors).to_si(fp)
    }
    fn states_si(&self) -> Vec<f64> {
        self.1.states_si(self.0.states())
    }
    fn modes_now(&self) -> Vec<u32> {
        self.0.modes().to_vec()
    }
    fn state_saturations(&self) -> Vec<u64> {
        self.1.declared_saturations(self.0.saturations())
    }
}
