//! The play loop, once: a group of keys ([`KeyEngine`]) stepped sample by sample, each key
//! moved by its [`Motion`] — a prescribed track (the position player) or a finger pushing
//! against the force the engine computed the sample before (the force player: the closed
//! loop, with the one-sample delay of the real board) — its strikes collected through the
//! strike rule and the traced keys' samples recorded.
//!
//! Every engine runs through [`run_keys`]: a host engine one key at a time over a busy
//! stretch, the firmware of a board all its keys over the whole piece (in consecutive spans
//! when asked: [`KeysLoop`] carries the loop's state from one to the next), the force
//! player's calibration one stroke at a time.

use super::engine::KeyEngine;
use super::error::RunError;
use super::motion::Motion;
use super::strike::Strike;
use super::timeline::Timeline;
use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;
use tactus_runtime::player::{FingerConfig, ForcePlayer};

/// A traced key's samples: (time s, key travel m, instrument force N, hammer m, finger N,
/// motor current A, DAC code); the last two `NaN` on a host engine.
pub type TraceRows = Vec<[f64; 7]>;

/// The traced keys' samples, by key.
pub type Traces = BTreeMap<u8, TraceRows>;

/// Which keys to trace, and when.
#[derive(Clone, Debug, Default)]
pub struct TraceWindow {
    /// The traced keys (MIDI).
    pub keys: BTreeSet<u8>,
    /// Trace from this time on, s.
    pub from_s: f64,
    /// Trace until this time, s.
    pub to_s: f64,
}

/// One key of a group: what moves it.
#[derive(Clone, Copy, Debug)]
pub struct Drive<'m> {
    /// MIDI key.
    pub key: u8,
    /// What moves it; `None`: it rests (travel 0).
    pub motion: Option<&'m Motion>,
    /// Its key dip (the upper bound of its sensor), m: the force player's bottom stop.
    pub dip_m: f64,
}

/// What [`run_keys`] produced.
#[derive(Clone, Debug, Default)]
pub struct KeysRun {
    /// The strikes, in sample order (then key order); none answers a note yet.
    pub strikes: Vec<Strike>,
    /// The traced keys' samples.
    pub traces: Traces,
}

/// How [`run_keys`] runs.
#[derive(Clone, Debug)]
pub struct LoopConfig<'t> {
    /// The run's clock: its sample rate, and its lead-in before the performance's 0 s
    /// (the players' motions are in the run's time, from its first sample; the strikes,
    /// the trace rows and the trace window in the performance's).
    pub clock: Timeline,
    /// The finger of a force player's key.
    pub finger: FingerConfig,
    /// What to trace.
    pub trace: &'t TraceWindow,
    /// Stop after the sample of the first strike at or after this time (the performance's),
    /// s (a calibration stroke needs no more).
    pub stop_at_strike_after_s: Option<f64>,
}

/// Samples the play loop steps one at a time after an engine could not give a held
/// stretch whole ([`KeyEngine::step_held`]) before it asks again.
const HELD_RETRY: usize = 64;

/// Key-samples between two calls of the progress callback.
pub const PROGRESS_SAMPLES: usize = 4096;

/// Runs the keys `drives` (in the engine's key order) over the samples `samples` on
/// `engine` as `config` says ([`KeysLoop`] over one span). `progress` is called with the
/// key-samples done since its last call.
///
/// Errors: those of [`KeysLoop::run`].
pub fn run_keys(
    engine: &mut dyn KeyEngine,
    drives: &[Drive],
    samples: Range<usize>,
    config: &LoopConfig,
    progress: &dyn Fn(u64),
) -> Result<KeysRun, RunError> {
    let mut keys = KeysLoop::new(drives, config);
    keys.run(engine, samples, progress)?;
    Ok(keys.finish())
}

/// The play loop between the spans of a long performance: what it keeps of its keys from
/// one sample to the next (the force players' keys in flight, each track's place, the
/// engine's held stretches) besides the engine's own state, so that a performance run as
/// consecutive spans ([`KeysLoop::run`] called for each) is the performance run whole.
pub struct KeysLoop<'d, 'c> {
    drives: &'d [Drive<'d>],
    config: &'c LoopConfig<'c>,
    players: Vec<Option<ForcePlayer>>,
    traced: Vec<bool>,
    any_traced: bool,
    xs: Vec<f64>,
    /// Per key, the moves of its track started so far (`KeyTrack::position_from`).
    cursors: Vec<usize>,
    /// Whether stretches in which every key holds still may go to the engine whole
    /// ([`KeyEngine::step_held`]): not with a force player (its key moves with the force)
    /// or a traced key (a row a sample).
    held_ok: bool,
    /// After an engine that could not give a held stretch, the sample of the next try.
    next_try: Option<usize>,
    /// Where the last span ended (the next must start there).
    at: Option<usize>,
    stopped: bool,
    out: KeysRun,
}

impl<'d, 'c> KeysLoop<'d, 'c> {
    /// The loop for the keys `drives` (in the engine's key order) as `config` says, before
    /// its first sample.
    pub fn new(drives: &'d [Drive<'d>], config: &'c LoopConfig<'c>) -> Self {
        let (fs, finger, trace) = (config.clock.fs, &config.finger, config.trace);
        let players: Vec<Option<ForcePlayer>> = drives
            .iter()
            .map(|d| {
                matches!(d.motion, Some(Motion::Finger(_)))
                    .then(|| ForcePlayer::new(d.dip_m, finger.mass_kg, fs))
            })
            .collect();
        let traced: Vec<bool> = drives.iter().map(|d| trace.keys.contains(&d.key)).collect();
        let any_traced = traced.contains(&true);
        let held_ok = !any_traced && players.iter().all(Option::is_none);
        KeysLoop {
            drives,
            config,
            players,
            traced,
            any_traced,
            xs: vec![0.0; drives.len()],
            cursors: vec![0; drives.len()],
            held_ok,
            next_try: None,
            at: None,
            stopped: false,
            out: KeysRun::default(),
        }
    }

    /// Runs the samples `samples` on `engine`: the first span from any sample, each next
    /// from where the last ended (the engine, too, carried on from there). `progress` is
    /// called with the key-samples done since its last call.
    ///
    /// Errors: the engine's; a message naming the key, sample and time when an engine
    /// computes a non-finite force or strike speed (an f64 program that divides by zero):
    /// the run stops there rather than play `NaN`; [`RunError::Span`] for a span that does
    /// not start where the last ended.
    pub fn run(
        &mut self,
        engine: &mut dyn KeyEngine,
        samples: Range<usize>,
        progress: &dyn Fn(u64),
    ) -> Result<(), RunError> {
        if let Some(at) = self.at.filter(|&at| at != samples.start) {
            return Err(RunError::Span {
                start: samples.start,
                expected: at,
            });
        }
        self.at = Some(samples.end.max(samples.start));
        if self.stopped {
            return Ok(());
        }
        let config = self.config;
        let (clock, trace) = (config.clock, config.trace);
        let fs = clock.fs;
        let drives = self.drives;
        let n = drives.len();
        let (players, cursors, xs, run) = (
            &mut self.players,
            &mut self.cursors,
            &mut self.xs,
            &mut self.out,
        );
        let (traced, any_traced) = (&self.traced, self.any_traced);
        let mut pending = 0usize;
        let next_try = self.next_try.get_or_insert(samples.start + 1);
        let mut i = samples.start;
        while i < samples.end {
            // The run's time (the motions'), and the performance's (what is reported).
            let time = i as f64 / fs;
            let at = clock.sample_to_performance_s(i as u64);
            if self.held_ok && i >= *next_try {
                let held = held_samples(drives, cursors, xs, i, samples.end, fs);
                let done = match held {
                    0 | 1 => 0,
                    m => engine.step_held(xs, m)?,
                };
                if done == 0 {
                    *next_try = i + HELD_RETRY;
                } else {
                    i += done;
                    pending += done;
                    if pending >= PROGRESS_SAMPLES {
                        progress((pending * n) as u64);
                        pending = 0;
                    }
                    continue;
                }
            }
            // This sample is `i`; the loop goes on from the next.
            i += 1;
            let i = i - 1;
            for (k, d) in drives.iter().enumerate() {
                xs[k] = match (d.motion, &players[k]) {
                    (Some(Motion::Track(t)), _) => t.position_from(time, &mut cursors[k]),
                    (_, Some(p)) => p.x_m,
                    _ => 0.0,
                };
            }
            let out = engine.step(xs)?;
            for (k, d) in drives.iter().enumerate() {
                let s = &out[k];
                if !s.force_n.is_finite() || s.strike_mps.is_some_and(|v| !v.is_finite()) {
                    return Err(RunError::NonFinite {
                        key: d.key,
                        sample: i,
                        time_s: at,
                        force_n: s.force_n,
                        strike_mps: s.strike_mps,
                    });
                }
                if let Some(speed) = s.strike_mps {
                    run.strikes.push(Strike {
                        key: d.key,
                        time_s: at,
                        speed_mps: speed,
                        answers: None,
                    });
                }
                let push = match d.motion {
                    Some(Motion::Finger(f)) => f.force(time),
                    _ => 0.0,
                };
                if let Some(p) = &mut players[k] {
                    p.step(push, s.force_n);
                }
                if traced[k] && at >= trace.from_s && at <= trace.to_s {
                    run.traces.entry(d.key).or_default().push([
                        at,
                        xs[k],
                        s.force_n,
                        f64::NAN,
                        push,
                        s.current_a,
                        s.dac,
                    ]);
                }
            }
            // The hammer once the samples are done with (an emulated board reads it from the
            // key's out words).
            for (k, d) in drives.iter().enumerate().filter(|_| any_traced) {
                if traced[k] && at >= trace.from_s && at <= trace.to_s {
                    if let Some(row) = run.traces.get_mut(&d.key).and_then(|r| r.last_mut()) {
                        row[3] = engine.hammer_m(k);
                    }
                }
            }
            pending += 1;
            if let Some(after) = config.stop_at_strike_after_s {
                if run.strikes.last().is_some_and(|s| s.time_s >= after) {
                    self.stopped = true;
                    break;
                }
            }
            if pending == PROGRESS_SAMPLES {
                progress((PROGRESS_SAMPLES * n) as u64);
                pending = 0;
            }
        }
        progress((pending * n) as u64);
        Ok(())
    }

    /// What the loop produced over all its spans.
    pub fn finish(self) -> KeysRun {
        self.out
    }
}

/// The samples from `i` (before `end`) in which every key of `drives` holds the travel it
/// has at sample `i` (a prescribed track that is not moving, or no motion), that travel
/// written to `xs`; 0 when a key moves at `i` or is moved by a finger. The times are the
/// play loop's (`j / fs`), so a key's travel at each of them is the one
/// [`tactus_runtime::performance::KeyTrack::position_from`] gives.
fn held_samples(
    drives: &[Drive],
    cursors: &mut [usize],
    xs: &mut [f64],
    i: usize,
    end: usize,
    fs: f64,
) -> usize {
    let time = i as f64 / fs;
    let mut until = f64::INFINITY;
    for (k, d) in drives.iter().enumerate() {
        xs[k] = match d.motion {
            Some(Motion::Track(t)) => match t.steady_from(time, &mut cursors[k]) {
                Some((x, u)) => {
                    until = until.min(u);
                    x
                }
                None => return 0,
            },
            Some(Motion::Finger(_)) => return 0,
            None => 0.0,
        };
    }
    // The first sample at or after `until`, found from its estimate.
    let mut j = if until.is_finite() {
        ((until * fs).floor().max(0.0) as usize).clamp(i, end)
    } else {
        end
    };
    while j > i && ((j - 1) as f64 / fs) >= until {
        j -= 1;
    }
    while j < end && (j as f64 / fs) < until {
        j += 1;
    }
    j - i
}
