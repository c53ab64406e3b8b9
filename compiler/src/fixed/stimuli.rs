//! What the planner's search simulates: the built-in key stimuli, full dips at several
//! descent times, noisy dips, runs of adversarial raw sensor words, and for a shared program
//! the param values of a few real keys ([`simulated_keys`]). Reproducible: every random run
//! is seeded.

use super::*;

/// Key descent times (seconds) of the full dips the planner's search simulates besides the
/// built-in stimuli: forte (≈ 25 ms to the key bottom) to piano (≈ 160 ms) and slower
/// (DESIGN.md's grand-action reference numbers).
pub const SIMULATED_DESCENTS_S: [f64; 7] = [0.025, 0.03, 0.04, 0.06, 0.1, 0.16, 0.2];

/// Most keys of a shared program ([`Program::runtime_keys`]) whose param values the
/// planner's search simulates ([`simulated_keys`]).
pub const MAX_SIMULATED_KEYS: usize = 6;

/// The keys (indices into [`Program::runtime_keys`]) at whose param values the planner's
/// search simulates the contract: every key when there are at most [`MAX_SIMULATED_KEYS`];
/// otherwise the first and the last key (a grading's ends: for grand88 the 11 g and 3.5 g
/// hammers, the ends of every run-time param's interval), per run-time param the key whose
/// value lies nearest the middle of its interval (grand88: D♯6, MIDI 87, 5.31 g, for each
/// of its `h/I_h`-scaled params), then evenly spaced keys (`j·(n−1)/(m−1)`) until
/// [`MAX_SIMULATED_KEYS`]. Real keys, not each param's interval taken alone: a param's
/// middle combined with another's is no hammer. In ascending order; empty without recorded
/// keys.
pub fn simulated_keys(p: &Program) -> Vec<usize> {
    let keys = &p.runtime_keys;
    let n = keys.len();
    if n <= MAX_SIMULATED_KEYS {
        return (0..n).collect();
    }
    let mut chosen = vec![0, n - 1];
    let ids: Vec<ParamId> = p.runtime_params().collect();
    for (j, id) in ids.iter().enumerate() {
        let (lo, hi) = p.params[id.index()].runtime.unwrap_or((0.0, 0.0));
        let mid = 0.5 * (lo + hi);
        let nearest = (0..n)
            .filter(|&k| keys[k].len() == ids.len())
            .min_by(|&a, &b| {
                (keys[a][j] - mid)
                    .abs()
                    .total_cmp(&(keys[b][j] - mid).abs())
            });
        if let Some(k) = nearest {
            if !chosen.contains(&k) && chosen.len() < MAX_SIMULATED_KEYS {
                chosen.push(k);
            }
        }
    }
    let m = MAX_SIMULATED_KEYS;
    for j in 1..m - 1 {
        if chosen.len() == m {
            break;
        }
        let k = (j * (n - 1) + (m - 1) / 2) / (m - 1);
        if !chosen.contains(&k) {
            chosen.push(k);
        }
    }
    chosen.sort_unstable();
    chosen
}

/// Runs of adversarial raw sensor words the planner's search simulates besides the key
/// stimuli, and their samples each (the budget corpus's kind of input, reproducibly seeded).
pub const SIMULATED_RANDOM_RUNS: usize = 2;

/// Samples of each of [`SIMULATED_RANDOM_RUNS`].
pub const SIMULATED_RANDOM_SAMPLES: usize = 4000;

/// The raw sensor words of the planner's random run `run` (< [`SIMULATED_RANDOM_RUNS`]) for
/// a sensor of raw range `range`: [`SIMULATED_RANDOM_SAMPLES`] words of
/// `XorShift64::sensor_word`, from the range's lower bound, seeded by `run`.
pub fn simulated_random_words(range: (i32, i32), run: usize) -> Vec<i32> {
    let mut rng = tactus_runtime::rng::XorShift64::new(0x5EED_3216 ^ run as u64);
    let mut w = range.0;
    (0..SIMULATED_RANDOM_SAMPLES)
        .map(|_| {
            w = rng.sensor_word(w, range);
            w
        })
        .collect()
}

/// Uniform sensor noise of the planner's noisy press, as a fraction of the dip (±0.5 %: a
/// noisy key sensor; the budget corpus's quick noise amplitude).
pub const SIMULATED_NOISE_REL: f64 = 0.005;

/// The planner's noisy press: key travel `key` (metres) with uniform noise of
/// ±[`SIMULATED_NOISE_REL`] of `dip_m` added to every sample, from a fixed seed (its own,
/// not the budget corpus's: the corpus checks what the planner did not see).
pub fn simulated_noisy(key: &[f64], dip_m: f64) -> Vec<f64> {
    let mut rng = tactus_runtime::rng::XorShift64::new(0x5EED_0015);
    key.iter()
        .map(|&x| x + dip_m * SIMULATED_NOISE_REL * (2.0 * rng.unit() - 1.0))
        .collect()
}

/// One input of the planner's simulation ([`simulated_inputs`]).
#[derive(Clone, Debug, PartialEq)]
pub enum SimulatedInput {
    /// Key travel, metres per sample (first sensor; both engines read its quantised words).
    Key(Vec<f64>),
    /// Raw words of the first sensor, as a sensor delivers them (arbitrary words included).
    Words(Vec<i32>),
}

impl SimulatedInput {
    /// Samples of the input.
    pub fn len(&self) -> usize {
        match self {
            SimulatedInput::Key(k) => k.len(),
            SimulatedInput::Words(w) => w.len(),
        }
    }

    /// Whether the input has no sample.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The f64 reference run of `p` on this input for the plan `fp`, with the run-time
    /// params at `params` (SI; empty: their own values): [`contract::reference`] or
    /// [`contract::reference_raw`].
    ///
    /// Errors: [`ParamBlockError`] when `params` do not fit `fp`'s run-time params.
    pub fn reference(
        &self,
        p: &Program,
        fp: &FixedProgram,
        params: &[f64],
    ) -> Result<contract::ReferenceRun, ParamBlockError> {
        match self {
            SimulatedInput::Key(k) => contract::reference(p, fp, k, params),
            SimulatedInput::Words(w) => contract::reference_raw(p, fp, w, params),
        }
    }
}

/// Every input the planner's search simulates for a keyboard program `p` (one sensor) whose
/// plan reads raw sensor words in `raw_range`, named: the built-in stimuli, the full dips of
/// [`SIMULATED_DESCENTS_S`], a press under sensor noise ([`simulated_noisy`]) and the runs
/// of random sensor words ([`simulated_random_words`]). The one definition of that set:
/// the search runs exactly these, and a test that shows what the search refused runs them
/// too.
pub fn simulated_inputs(p: &Program, raw_range: (i32, i32)) -> Vec<(String, SimulatedInput)> {
    let Some(sensor) = p.sensors.first() else {
        return Vec::new();
    };
    let (dip, fs) = (sensor.range.1, p.sample_rate_hz);
    let mut out: Vec<(String, SimulatedInput)> = tactus_runtime::stimulus::builtin_names()
        .iter()
        .filter_map(|(name, _)| {
            let s = tactus_runtime::stimulus::builtin(name, dip, fs).ok()?;
            Some((name.to_string(), SimulatedInput::Key(s.key)))
        })
        .collect();
    // Full dips over the range of key descent times (an event's arguments, a strike's
    // hammer speed, are most sensitive to the slow ones, where the hammer barely reaches
    // the string).
    for descent in SIMULATED_DESCENTS_S {
        if let Ok(s) = tactus_runtime::stimulus::dip(descent, 0.1, 0.06, dip, fs) {
            out.push((
                format!("dip {} ms", descent * 1e3),
                SimulatedInput::Key(s.key),
            ));
        }
    }
    // A press under sensor noise (the budget corpus's kind of input): a product cut that
    // holds on clean key travel can break under noise, where the contact switches on the
    // noise and the switch clause reads the runs' disagreements.
    if let Ok(s) = tactus_runtime::stimulus::dip(0.04, 0.1, 0.04, dip, fs) {
        out.push((
            "noisy press".to_string(),
            SimulatedInput::Key(simulated_noisy(&s.key, dip)),
        ));
    }
    // Adversarial raw sensor words as the budget corpus has them (arbitrary words,
    // corners, in-range walks; `XorShift64::sensor_word`): a product cut to 16 bits can be
    // harmless on every key travel and break the force at an extreme word.
    for r in 0..SIMULATED_RANDOM_RUNS {
        out.push((
            format!("random words {r}"),
            SimulatedInput::Words(simulated_random_words(raw_range, r)),
        ));
    }
    out
}
