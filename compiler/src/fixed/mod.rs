//! Fixed-point compilation: range analysis, Q-format choice, and the fixed-point program
//! that the fixed interpreter, the JIT and the firmware backends run.
//!
//! The fixed program is the IR plus a *format plan*: one binary point (fraction bits) per
//! value, per state and per sensor, the raw words of constants, and the reciprocal that
//! replaces each division by a constant. Each value's format is the finest that holds its
//! whole interval from [`range`] in a signed 32-bit word:
//! `frac = 30 − floor(log2(max |v|))`, so `|raw| < 2^31`. What an operation computes is
//! defined once, in [`tactus_runtime::fixed`]: the exact result rounded half up to the result
//! format and saturated. Because the formats hold the analysed intervals, saturation can fire
//! only where the analysis had to clamp an unbounded value, and those places are warned about.

pub mod chains;
pub mod common;
pub mod contract;
pub mod distribute;
pub mod flow;
pub mod interp;
pub mod plan_cache;
pub mod range;
pub mod recip;
pub mod report;
mod workers;

use crate::diagnostics::Diagnostic;
use crate::ir::*;
use range::{Interval, Ranges};
use tactus_runtime::differentiator::WINDOW;
use tactus_runtime::fixed as fx;

pub use tactus_runtime::fixed::FRAC_RANGE;

/// The finest format holding `iv` in an `i32`: fraction bits ([`tactus_runtime::fixed::frac_for`]).
pub fn frac_for(iv: Interval) -> i32 {
    tactus_runtime::fixed::frac_for(iv.mag())
}

/// A multiplication may drop low operand bits to fit `MULS` when the error this adds is at
/// most this fraction of the product's largest magnitude (2^-22: 6 bits finer than a 16-bit
/// DAC at full scale).
pub const MULS_REL_TOLERANCE: f64 = 1.0 / (1u64 << 22) as f64;

/// A run-time division may shift its divisor right ([`tactus_runtime::fixed::div_shifted`])
/// when the dropped bits cost at most this relative error of the quotient (2^-10). The shift
/// frees quotient digits per division of the RP2040's 32÷32 SIO divider
/// ([`sio_division_steps`]). Chosen by the accuracy contract ([`contract`], checked in
/// `compiler/tests/contract.rs`): on the grand piano's built-in stimuli the worst force error
/// is 0.12 DAC LSB at 2^-16 and 2^-12, 0.19 at 2^-10, 0.76 at 2^-8 and 1.12 (broken) at 2^-6
/// (its two divisions set the impact pulse's decay time and rate).
pub const DIV_REL_TOLERANCE: f64 = 1.0 / 1024.0;

/// Divisors are not shifted below this many significant bits: at 16, two hardware divisions
/// give any quotient of up to 32 bits, so more shifting buys nothing.
pub const DIV_MIN_DIVISOR_BITS: i32 = 16;

/// Number of bits of a raw magnitude bound `m` (`ceil(log2(m + 1))`): 0 for 0.
pub fn bits_of(m: u64) -> i32 {
    64 - m.leading_zeros() as i32
}

/// Hardware divisions a long division by the RP2040's 32÷32 unsigned divider takes for a
/// quotient of `quotient_bits` bits and a divisor of `divisor_bits` bits: digits of
/// `s = 32 − divisor_bits` bits (each step divides the remainder with the next `s` dividend
/// bits appended), `ceil(quotient_bits / s)` steps. `None` for a divisor of 32 bits or more
/// (no digit fits). One definition, used by the Thumb backend and the precision report.
pub fn sio_division_steps(quotient_bits: i32, divisor_bits: i32) -> Option<u32> {
    let s = 32 - divisor_bits;
    if s <= 0 {
        return None;
    }
    Some((quotient_bits.max(1) + s - 1) as u32 / s as u32)
}

/// Estimated Cortex-M0+ cycles of a run-time division of `quotient_bits` quotient bits:
/// `(steps, cycles)` on the SIO divider when that is cheaper than the restoring division
/// (6 cycles a quotient bit, `compiler/src/thumb/select/divide.rs`), else `(0, cycles)` of the
/// restoring division. SIO: about 18 cycles of set-up and sign handling plus 14 per step
/// (the remainder load and shift, the dividend store, the 8-cycle latency that also shifts
/// the digits, the quotient load and merge).
pub fn division_cycles(quotient_bits: i32, divisor_bits: i32) -> (u32, u32) {
    let restoring = 12 + 6 * quotient_bits.max(1) as u32;
    match sio_division_steps(quotient_bits, divisor_bits) {
        Some(n) if 18 + 14 * n < restoring => (n, 18 + 14 * n),
        _ => (0, restoring),
    }
}

/// The divisor pre-shift of a run-time division (see [`DIV_REL_TOLERANCE`]): the largest `b`
/// with `2^b ≤ DIV_REL_TOLERANCE · min |y raw|` that leaves the divisor at least
/// [`DIV_MIN_DIVISOR_BITS`] bits and at least 4 after the shift, and keeps the quotient with
/// the shifted divisor below 2^31 in the result format. 0 when the divisor's range contains
/// 0 (no shift is safe then).
fn plan_div_shift(fy: i32, ry: Interval, fr: i32, rv: Interval, tolerance: f64) -> u8 {
    let scale = 2f64.powi(fy);
    let (lo, hi) = (ry.lo * scale, ry.hi * scale);
    let ymin = if lo > 0.0 {
        lo
    } else if hi < 0.0 {
        -hi
    } else {
        return 0;
    };
    let ymax = ry.mag() * scale;
    if !(ymin.is_finite() && ymax.is_finite()) || ymin < 1.0 {
        return 0;
    }
    let lmax = bits_of(ymax.ceil() as u64);
    let mut b = ((tolerance * ymin).log2().floor() as i32)
        .min(lmax - DIV_MIN_DIVISOR_BITS)
        .clamp(0, 30);
    let q = rv.mag() * 2f64.powi(fr);
    while b > 0
        && (q * (1.0 + 2f64.powi(b + 1) / ymin) + 2.0 >= 2147483648.0 || ymin < 4.0 * 2f64.powi(b))
    {
        b -= 1;
    }
    b as u8
}

/// The largest local error bound, relative to a value's magnitude, by which
/// [`FixedProgram::widen_by_local_errors`] widens its interval (2^-10: 64 times a 32×16
/// product's cut).
pub const WIDEN_MAX_REL: f64 = 1.0 / 1024.0;

/// Precision budget of the `MULS` plan: a force term's or the total's error bound may grow
/// to this many DAC LSB (a quarter: the quantisation stays below what the DAC resolves).
pub const BUDGET_FORCE_LSB: f64 = 0.25;

/// Precision budget of the `MULS` plan: the error bound of a state that is only set (a held
/// force, a recorded position) may grow to this fraction of its range (2^-24).
pub const BUDGET_STATE_REL: f64 = 1.0 / (1u64 << 24) as f64;

/// Precision budget of the `MULS` plan: the one-sample error bound of an integrated
/// (accumulating) state may grow by at most this factor over its bound with exact products.
/// Its errors add up sample after sample, and a floor shift's error is a bias, not noise: a
/// near-threshold motion (a hammer that barely reaches the string) is decided by them.
pub const BUDGET_ACCUMULATING_GROWTH: f64 = 2.0;

/// Precision budget of the `MULS` plan: a value that is compared, emitted or output may
/// carry an error bound of this fraction of its range (2^-20).
pub const BUDGET_VALUE_REL: f64 = 1.0 / (1u64 << 20) as f64;

/// The precision budget of a format plan: how much error the planner may spend on cheaper
/// arithmetic. [`Default`] is the budget every engine and backend uses (the constants above);
/// the accuracy contract ([`contract`]) is what it must keep, checked by simulation against
/// the f64 reference (`compiler/tests/contract.rs`), including that a greedier budget breaks it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanConfig {
    /// [`BUDGET_FORCE_LSB`].
    pub force_lsb: f64,
    /// [`BUDGET_STATE_REL`].
    pub state_rel: f64,
    /// [`BUDGET_ACCUMULATING_GROWTH`].
    pub accumulating_growth: f64,
    /// [`BUDGET_VALUE_REL`].
    pub value_rel: f64,
    /// [`DIV_REL_TOLERANCE`].
    pub div_rel_tolerance: f64,
    /// Whether the planner also tries cheaper product forms than the error analysis proves,
    /// checked by simulating the accuracy contract (`FixedProgram::spend_by_simulation`).
    pub simulate: bool,
    /// Whether divisions by states that only events set become products with their
    /// reciprocals ([`recip`]). Off only to measure what the reciprocals save and to pin
    /// the divisor tolerance on a program that still divides.
    pub reciprocals: bool,
    /// Whether states only events write are narrowed to the hull of what they are assigned
    /// ([`range::state_hulls`]). Off only to measure what the narrowing saves.
    pub narrow_states: bool,
    /// Whether `on` handlers whose edge memory is provably false whenever their condition
    /// holds are run as `while` handlers ([`flow::edges`]: no edge load or store). Off only
    /// to measure what it saves and to check that both programs run alike.
    pub level_edges: bool,
}

impl Default for PlanConfig {
    fn default() -> Self {
        PlanConfig {
            force_lsb: BUDGET_FORCE_LSB,
            state_rel: BUDGET_STATE_REL,
            accumulating_growth: BUDGET_ACCUMULATING_GROWTH,
            value_rel: BUDGET_VALUE_REL,
            div_rel_tolerance: DIV_REL_TOLERANCE,
            simulate: true,
            reciprocals: true,
            narrow_states: true,
            level_edges: true,
        }
    }
}

impl PlanConfig {
    /// A budget with no limit on products (every product that fits `MULS` gets it) and
    /// divisors shifted to [`DIV_MIN_DIVISOR_BITS`] whatever it costs: what a planner
    /// ignoring the contract would do. For tests that show the contract catches it.
    pub fn unlimited() -> Self {
        PlanConfig {
            force_lsb: f64::INFINITY,
            state_rel: f64::INFINITY,
            accumulating_growth: f64::INFINITY,
            value_rel: f64::INFINITY,
            div_rel_tolerance: 1.0,
            simulate: false,
            reciprocals: true,
            narrow_states: true,
            level_edges: true,
        }
    }
}

/// The share of each contract clause the planner's simulation may spend: a cheaper product
/// form is kept only when the built-in stimuli stay within half of every tolerance, so
/// that what the built-in stimuli do not show (other params, other touches) has the other
/// half.
pub const SIMULATION_MARGIN: f64 = 0.5;

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

/// Whether a plan's check `c` of a run is no worse than `base`, the analysis' plan's check
/// of the same run, which breaks `strict` (the half-tolerance contract both were measured
/// against): clause by clause at most the base's figure plus the clause's `strict` bound —
/// the total force read within the events' time tolerance
/// ([`contract::ContractCheck::max_force_lsb_within_time`]: a switch a sample apart is what
/// broke the base), each force term and output as measured, the event shift and argument
/// ratios plus one tolerance — and no more events lost or added, samples out of range or
/// saturations than the base.
pub fn within_base(
    c: &contract::ContractCheck,
    base: &contract::ContractCheck,
    strict: &contract::Contract,
) -> bool {
    let lsb = c.dac_lsb_n;
    let force =
        c.max_force_lsb_within_time <= base.max_force_lsb_within_time + strict.force.lsb(lsb);
    let terms = strict
        .terms
        .iter()
        .zip(c.term_lsb.iter().zip(&base.term_lsb))
        .all(|((_, b), (x, y))| *x <= *y + b.lsb(lsb));
    let outputs = strict
        .outputs
        .iter()
        .zip(c.output_err.iter().zip(&base.output_err))
        .all(|((_, b), (x, y))| *x <= *y + *b);
    force
        && terms
        && outputs
        && c.unmatched <= base.unmatched
        && c.shift_ratio <= base.shift_ratio + 1.0
        && c.arg_ratio <= base.arg_ratio + 1.0
        && c.state_out_of_range <= base.state_out_of_range
        && c.overflowed <= base.overflowed
}

/// Most contract simulations per round of the planner's search
/// ([`FixedProgram::with_config`]).
pub const MAX_SIMULATIONS: usize = 40;

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

/// Most passes of the planner's rounds ([`FixedProgram::with_config`]): a second pass tries
/// again, in the plan the first settled in, the forms refused beside others.
pub const SEARCH_PASSES: usize = 2;

/// Programs with more IR values than this are not simulated by the planner (a rubbed bank
/// or a bowed string: a simulation of the built-in stimuli would take minutes).
pub const MAX_SIMULATED_VALUES: usize = 1500;

/// Work (candidate products × IR values) up to which the precision budget is spent one
/// product at a time, one error analysis each (every shipped keyboard instrument, the bank
/// and the plucked string: at most 3.6 M). Above it, products are tried in groups
/// ([`MAX_GROUP_ANALYSES`]).
pub const SEQUENTIAL_BUDGET_WORK: usize = 4_000_000;

/// Most error analyses spent on a large program's products, tried in groups.
pub const MAX_GROUP_ANALYSES: usize = 64;

/// Values whose error the budget watches: operands of comparisons, event arguments, outputs.
fn watched_values(p: &Program) -> Vec<Value> {
    let mut out: Vec<Value> = p
        .values
        .iter()
        .filter_map(|vd| match vd.op {
            Op::Cmp(_, x, y) => Some([x, y]),
            _ => None,
        })
        .flatten()
        .filter(|v| matches!(p.values[v.index()].ty, Ty::Real(_)))
        .collect();
    fn walk(stmts: &[Stmt], out: &mut Vec<Value>) {
        for s in stmts {
            match s {
                Stmt::Emit(_, args) => out.extend(args.iter().copied()),
                Stmt::Output(_, v) => out.push(*v),
                Stmt::If(_, b) => walk(b, out),
                _ => {}
            }
        }
    }
    walk(&p.body, &mut out);
    out.sort_by_key(|v| v.index());
    out.dedup();
    out
}

/// The operands of one product as the plan sees them: each operand's format and range, and
/// the number of its low bits known to be zero (a constant's trailing zeros), which shift
/// off exactly.
#[derive(Clone, Copy, Debug)]
struct MulOperands {
    x: (i32, Interval),
    free_x: i32,
    y: (i32, Interval),
    free_y: i32,
    /// Whether `y` is a constant (its word known at compile time).
    constant: bool,
    result: Interval,
    /// The result's fraction bits.
    fr: i32,
}

impl MulOperands {
    /// The pre-shifts `(a, b)` that fit the product in 31 bits and their absolute error.
    fn shifts(&self) -> Option<(i32, i32, f64)> {
        let ((fx, rx), (fy, ry)) = (self.x, self.y);
        let (free_x, free_y) = (self.free_x, self.free_y);
        let bits = |f: i32, r: Interval| (r.mag() * 2f64.powi(f)).max(1.0).log2().ceil() as i32;
        let (mut a, mut b) = (0i32, 0i32);
        let (bx, by) = (bits(fx, rx), bits(fy, ry));
        while (bx - a) + (by - b) > 31 && a < 31 && b < 31 {
            if a < free_x {
                a += 1;
            } else if b < free_y {
                b += 1;
            } else if bx - a >= by - b {
                a += 1;
            } else {
                b += 1;
            }
        }
        if (bx - a) + (by - b) > 31 {
            return None;
        }
        let shift_err = |s: i32, f: i32, free: i32| if s <= free { 0.0 } else { 2f64.powi(s - f) };
        let (ex, ey) = (shift_err(a, fx, free_x), shift_err(b, fy, free_y));
        Some((a, b, ry.mag() * ex + rx.mag() * ey + ex * ey))
    }

    /// The high-word form ([`MulKind::High`]): the smallest `k` in 16..=32 for which the
    /// partial-product sum `p` of [`tactus_runtime::fixed::mul_high`] fits a signed 32-bit
    /// word, and its absolute error (`(2 + 2^(32−k))·2^(k − fx − fy)`, SI).
    fn high(&self) -> Option<(u8, f64)> {
        let ((fx, rx), (fy, ry)) = (self.x, self.y);
        let word = |f: i32, r: Interval| (r.mag() * 2f64.powi(f) * (1.0 + 1e-9)).ceil() + 1.0;
        let (bx, by) = (word(fx, rx), word(fy, ry));
        if !(bx.is_finite() && by.is_finite()) || bx > 2147483648.0 || by > 2147483648.0 {
            return None;
        }
        // Bounds of the high halves: |x >> 16| ≤ floor(bx / 2^16) + 1.
        let (hx, hy) = ((bx / 65536.0).floor() + 1.0, (by / 65536.0).floor() + 1.0);
        (16..=32).find_map(|k: i32| {
            let p = (hx * hy + hx + hy) * 2f64.powi(32 - k) + 2.0;
            (p < 2147483647.0)
                .then(|| (k as u8, (2.0 + 2f64.powi(32 - k)) * 2f64.powi(k - fx - fy)))
        })
    }

    /// The 32×16 form ([`MulKind::Mul32x16`]) cutting the pair's second operand (`cut_y`) or
    /// its first: the smallest pre-shift `b` that leaves the cut word a signed 16-bit half
    /// (`|word| < 2^(15+b)`); the unit `2^k` of the partial-product sum `p` of
    /// [`tactus_runtime::fixed::mul_32x16`] that makes `p`'s format the result's (its floor
    /// then is the rounding, one `ASRS` instead of a rounding shift after the sum: an error
    /// of one result LSB where the cut costs 2^15 times more), within 0..=16 and not below
    /// the smallest `k` for which every part of `p` and `p` itself fit a signed 32-bit word;
    /// and the absolute error (SI): the kept operand's magnitude times one LSB of the cut
    /// word (`|x|·2^(b − fy)`, 0 when the dropped bits are known zeros) plus the floor's
    /// `2^(b + k − fx − fy)`. `None` when an operand is unbounded.
    fn half(&self, cut_y: bool) -> Option<(u8, u8, f64)> {
        let ((fk, rk), (fc, rc), free) = if cut_y {
            (self.x, self.y, self.free_y)
        } else {
            (self.y, self.x, self.free_x)
        };
        let word = |f: i32, r: Interval| (r.mag() * 2f64.powi(f) * (1.0 + 1e-9)).ceil() + 1.0;
        let (bk, bc) = (word(fk, rk), word(fc, rc));
        if !(bk.is_finite() && bc.is_finite()) || bk > 2147483648.0 || bc > 2147483648.0 {
            return None;
        }
        let b = (0..=16).find(|&b| bc < 2f64.powi(15 + b))?;
        // Bounds of |ys| (≤ 2^15) and of the kept word's high half |xh|.
        let ys = ((bc / 2f64.powi(b)).floor() + 1.0).min(32768.0);
        let hk = (bk / 65536.0).floor() + 1.0;
        let kmin = (0..=16).find(|&k| {
            let high = hk * ys * 2f64.powi(16 - k);
            let low = (65535.0 * ys / 2f64.powi(k)).ceil();
            high + low + 1.0 < 2147483647.0
        })?;
        let k = (fk + fc - b - self.fr).clamp(kmin, 16);
        let cut = if b > free {
            rk.mag() * 2f64.powi(b - fc)
        } else {
            0.0
        };
        Some((b as u8, k as u8, cut + 2f64.powi(b + k - fk - fc)))
    }

    /// The 32×16 forms of the product in operand order (`swapped`: the plan's pair is
    /// (y, x)), the smaller error first: a product by a constant cuts the constant; two
    /// run-time operands may cut either, and the error analysis decides
    /// ([`FixedProgram::spend_precision_budget`]).
    fn halves(&self, swapped: bool) -> Vec<MulKind> {
        let mut out: Vec<(f64, MulKind)> = [true, false]
            .into_iter()
            .filter(|&cut_y| cut_y || !self.constant)
            .filter_map(|cut_y| {
                let (b, k, err) = self.half(cut_y)?;
                let second = cut_y != swapped;
                let cut = if second { Cut::Second } else { Cut::First };
                Some((err, MulKind::Mul32x16 { cut, b, k }))
            })
            .collect();
        out.sort_by(|a, b| a.0.total_cmp(&b.0));
        out.into_iter().map(|(_, k)| k).collect()
    }

    /// Plans the product: shift free bits first, then the operand with more significant
    /// bits, until the product fits 31 bits. With `tolerance`, accept only when the floor
    /// shifts cost at most [`MULS_REL_TOLERANCE`] of the result's magnitude, else the 64-bit
    /// product; without, always `MULS` where the shifts exist. The precision budget then
    /// tries the cheaper forms ([`MulOperands::high`] among them) on the 64-bit ones.
    /// The shifts are returned in operand order (`swapped`: the plan's pair is (y, x)).
    fn plan(&self, swapped: bool, tolerance: bool) -> MulKind {
        let limit = MULS_REL_TOLERANCE * self.result.mag().max(f64::MIN_POSITIVE);
        if let Some((a, b, err)) = self.shifts() {
            if !tolerance || err <= limit {
                return if swapped {
                    MulKind::Muls(b as u8, a as u8)
                } else {
                    MulKind::Muls(a as u8, b as u8)
                };
            }
        }
        let _ = tolerance;
        MulKind::Wide
    }
}

/// Which operand of a product a [`MulKind::Mul32x16`] cuts to 16 bits, in operand order
/// (`x · y`: `First` is `x`; for a division by a constant, `Second` is the reciprocal).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cut {
    /// The first operand.
    First,
    /// The second operand.
    Second,
}

impl Cut {
    /// The operands `(x, y)` of a product as `(kept, cut)`: how every engine passes them to
    /// [`tactus_runtime::fixed::mul_32x16`] (its `y` is the cut one).
    pub fn kept_cut<T>(self, x: T, y: T) -> (T, T) {
        match self {
            Cut::First => (y, x),
            Cut::Second => (x, y),
        }
    }
}

/// How a multiplication is done on a 32-bit core without a 64-bit product instruction,
/// cheapest first. A 16×16 product is `Muls(0, 0)` (its operands already fit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MulKind {
    /// Operands pre-shifted right by (a, b) bits so the product fits 32 bits: one `MULS`
    /// plus shifts ([`tactus_runtime::fixed::mul_shifted`]).
    Muls(u8, u8),
    /// One operand (`cut`) pre-shifted right by `b` bits to a signed 16-bit half, the other
    /// kept whole as its two halves: two 16×16 `MULS`, the low one floored by `k` bits
    /// ([`tactus_runtime::fixed::mul_32x16`]).
    Mul32x16 {
        /// The operand cut to 16 bits.
        cut: Cut,
        /// Its pre-shift (bits).
        b: u8,
        /// The sum's unit `2^k` (0..=16).
        k: u8,
    },
    /// The high word of the 32×32 product in units of `2^k`: three 16×16 `MULS` partial
    /// products, two floored, the low one dropped, summed in 32 bits
    /// ([`tactus_runtime::fixed::mul_high`]).
    High(u8),
    /// The exact product needs up to 64 bits: four 16×16 `MULS` partial products and adds
    /// (ARMv6-M has no `SMULL`).
    Wide,
}

impl MulKind {
    /// Estimated Cortex-M0+ cycles, operand splitting and the final rounding included (the
    /// Cortex-M0+ TRM's single-cycle ALU and fast multiplier): `Muls` 6 (pre-shifts, a
    /// constant load, `MULS`, the rounding shift); `Mul32x16` 9 (`ASRS`/`UXTH` for the kept
    /// operand's halves, the cut operand's `ASRS` or its constant's 2-cycle `LDR`, 2 `MULS`,
    /// `LSLS`, `ASRS`, `ADDS`; its unit `k` is chosen so that no rounding shift follows —
    /// the piano's listing has exactly these 8 instructions); `High` 14 (halves of each operand, 3
    /// `MULS`, 3 shifts, 2 adds, the rounding); `Wide` 23 (a literal load, halves, 4 `MULS`,
    /// the cross terms into a 64-bit pair with `ADDS`/`ADCS`, a 64-bit rounding shift).
    pub fn cycles(self) -> u32 {
        match self {
            MulKind::Muls(..) => 6,
            MulKind::Mul32x16 { .. } => 9,
            MulKind::High(_) => 14,
            MulKind::Wide => 23,
        }
    }

    /// The same form with the operands exchanged (`y · x` for `x · y`): the pre-shifts and
    /// the cut side follow their operands.
    pub fn swapped(self) -> MulKind {
        match self {
            MulKind::Muls(a, b) => MulKind::Muls(b, a),
            MulKind::Mul32x16 { cut, b, k } => MulKind::Mul32x16 {
                cut: match cut {
                    Cut::First => Cut::Second,
                    Cut::Second => Cut::First,
                },
                b,
                k,
            },
            k => k,
        }
    }

    /// The form's name in the precision report.
    pub fn name(self) -> String {
        match self {
            MulKind::Muls(0, 0) => "MULS 32×32→32 (operands fit)".into(),
            MulKind::Muls(a, b) => format!("pre-shifted MULS (>>{a}, >>{b})"),
            MulKind::Mul32x16 { cut, b, k } => format!(
                "32×16 (2 MULS, {} >>{b}, units of 2^{k})",
                match cut {
                    Cut::First => "x",
                    Cut::Second => "y",
                }
            ),
            MulKind::High(k) => format!("high word of 32×32 (3 MULS, units of 2^{k})"),
            MulKind::Wide => "64-bit product (4 MULS)".into(),
        }
    }
}

/// Products per form ([`MulKind`]) of a plan and their estimated Cortex-M0+ cycles
/// ([`FixedProgram::mul_forms`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MulForms {
    /// `MULS` products (16×16 or pre-shifted).
    pub muls: usize,
    /// 32×16 products.
    pub m32x16: usize,
    /// High words of 32×32.
    pub high: usize,
    /// Full 64-bit products.
    pub wide: usize,
    /// Estimated cycles of all ([`MulKind::cycles`]).
    pub cycles: u32,
}

impl std::fmt::Display for MulForms {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} MULS, {} 32×16, {} high word, {} 64-bit (≈ {} cycles)",
            self.muls, self.m32x16, self.high, self.wide, self.cycles
        )
    }
}

/// A program compiled to fixed point.
#[derive(Clone, Debug)]
pub struct FixedProgram {
    /// The IR (its statement list is what every fixed engine executes).
    pub program: Program,
    /// Interval of every value.
    pub ranges: Ranges,
    /// Fraction bits of every value (truth values and modes: 0).
    pub frac: Vec<i32>,
    /// Raw word of every constant and param value (0 for other values).
    pub consts: Vec<i32>,
    /// For a division by a constant: the raw word and fraction bits of the reciprocal it
    /// multiplies by instead.
    pub recip: Vec<Option<(i32, i32)>>,
    /// How each multiplication (and division by a constant) is done; `None` for other values.
    pub mul_kind: Vec<Option<MulKind>>,
    /// Per product: the cheaper forms the planner considered beside the exact 64-bit one, in
    /// the order tried (its `MULS` plan when the operands can be pre-shifted into 32 bits,
    /// its high word when the partial sum fits); empty for other values.
    pub mul_options: Vec<Vec<MulKind>>,
    /// For a division by a run-time value: the right shift of its divisor's word
    /// ([`tactus_runtime::fixed::div_shifted`]); 0 for an exact division and for other values.
    pub div_shift: Vec<u8>,
    /// Fraction bits of each sensor (from its declared range).
    pub sensor_frac: Vec<i32>,
    /// Raw bounds of each sensor.
    pub sensor_raw_range: Vec<(i32, i32)>,
    /// Fraction bits of each state (from its declared range).
    pub state_frac: Vec<i32>,
    /// Raw bounds each state write saturates to.
    pub state_raw_range: Vec<(i32, i32)>,
    /// Raw initial value of each state.
    pub state_init: Vec<i32>,
    /// `fs/N` and `(fs/N)²` of the differentiators as (raw, fraction bits).
    pub deriv_gain: [(i32, i32); 2],
    /// Format of each force term (that of its value).
    pub force_frac: Vec<i32>,
    /// Format of the total force.
    pub total_frac: i32,
    /// Format of each output.
    pub output_frac: Vec<i32>,
    /// Format of each event argument: the coarsest among the emits of that event; `emit`
    /// converts its arguments to it.
    pub event_frac: Vec<Vec<i32>>,
    /// Saturation inserted where the analysis found no bound.
    pub warnings: Vec<Diagnostic>,
    /// Per param ([`ParamId`]): its word's index in a key's param block when it is a
    /// run-time param ([`ParamDecl::runtime`]), else `None`.
    pub param_slot: Vec<Option<usize>>,
    /// Per word of the param block ([`Program::runtime_params`] order): its fraction bits
    /// (those of every value reading it) and the raw bounds of its declared interval.
    pub param_words: Vec<ParamWord>,
    /// The states whose divisions became products with a hidden reciprocal state
    /// ([`recip`]); the hidden states are the last `reciprocals.len()` of
    /// `program.states`, in this order.
    pub reciprocals: Vec<recip::Reciprocal>,
    /// States used as divisors that keep their divisions, and why ([`recip::Refused`]).
    pub refused_reciprocals: Vec<recip::Refused>,
    /// Per state of `program`: its declared range when the plan narrowed it to the hull of
    /// what the state is assigned ([`range::state_hulls`]; `program.states` holds the hull,
    /// which its word's format, its saturation and every read's interval follow), else
    /// `None`.
    pub narrowed: Vec<Option<(f64, f64)>>,
}

/// The format of one word of a key's param block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParamWord {
    /// The run-time param it holds.
    pub param: ParamId,
    /// Fraction bits.
    pub frac: i32,
    /// Raw bounds: the words of the param's interval ends in this format.
    pub raw_range: (i32, i32),
}

/// Why a param block could not be made.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamBlockError {
    /// The number of values is not the number of run-time params.
    Count {
        /// Values given.
        given: usize,
        /// Run-time params of the program.
        expected: usize,
    },
    /// A value lies outside the interval the program was planned for.
    OutOfRange {
        /// The param's name.
        param: String,
        /// The value given, SI.
        value: f64,
        /// The planned interval, SI.
        range: (f64, f64),
    },
}

impl std::fmt::Display for ParamBlockError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ParamBlockError::Count { given, expected } => write!(
                f,
                "{given} param values given for a program with {expected} run-time params"
            ),
            ParamBlockError::OutOfRange {
                param,
                value,
                range,
            } => write!(
                f,
                "param `{param}` = {value:e} lies outside [{:e}, {:e}], the interval its program was planned for",
                range.0, range.1
            ),
        }
    }
}

impl std::error::Error for ParamBlockError {}

/// Formats of what the body publishes.
struct Published {
    force: Vec<i32>,
    total: i32,
    output: Vec<i32>,
    event: Vec<Vec<i32>>,
}

fn published(p: &Program, frac: &[i32]) -> Published {
    let mut out = Published {
        force: vec![0; p.forces.len()],
        total: 0,
        output: vec![0; p.outputs.len()],
        event: p
            .events
            .iter()
            .map(|e| vec![FRAC_RANGE.1; e.args.len()])
            .collect(),
    };
    fn walk(stmts: &[Stmt], frac: &[i32], out: &mut Published) {
        for s in stmts {
            match s {
                Stmt::Force(f, v) => out.force[f.index()] = frac[v.index()],
                Stmt::Total(v) => out.total = frac[v.index()],
                Stmt::Output(o, v) => out.output[o.index()] = frac[v.index()],
                Stmt::Emit(e, args) => {
                    for (slot, v) in out.event[e.index()].iter_mut().zip(args) {
                        *slot = (*slot).min(frac[v.index()]);
                    }
                }
                Stmt::If(_, body) => walk(body, frac, out),
                _ => {}
            }
        }
    }
    walk(&p.body, frac, &mut out);
    out
}

fn constant(v: f64) -> (i32, i32) {
    let f = frac_for(Interval::point(v));
    (fx::from_f64(v, f).0, f)
}

impl FixedProgram {
    /// Plans formats for `program` with the default budget ([`PlanConfig::default`]). Never
    /// fails: unbounded values get saturation and a warning.
    pub fn new(program: &Program) -> Self {
        Self::with_config(program, &PlanConfig::default())
    }

    /// Plans formats for `program` under the precision budget `config`.
    pub fn with_config(program: &Program, config: &PlanConfig) -> Self {
        let original = program;
        // Divisions by states that only events set: products with their reciprocals
        // (`recip`), recomputed where the states are assigned.
        let recips = if config.reciprocals {
            recip::reciprocals(program)
        } else {
            recip::Reciprocals {
                program: program.clone(),
                recips: Vec::new(),
                refused: Vec::new(),
            }
        };
        // Products of products by constants: one product by the constants' product (`chains`);
        // each common value once (`common`): the same meaning, fewer products to plan and
        // run; constant factors of sums distributed into their terms (`distribute`).
        let mut shared = distribute::fold_constants(&recips.program);
        // States only events set: the hull of what they are assigned, within their declared
        // ranges (`range::state_hulls`); their words take that hull's format.
        let mut narrowed = vec![None; shared.states.len()];
        let hulls = if config.narrow_states {
            range::state_hulls(&shared)
        } else {
            shared.states.iter().map(|s| s.range).collect()
        };
        for ((st, h), n) in shared.states.iter_mut().zip(hulls).zip(&mut narrowed) {
            if h != st.range {
                *n = Some(st.range);
                st.range = h;
            }
        }
        let program = &shared;
        let ranges = range::analyse(program);
        let n = program.values.len();
        let mut frac = vec![0; n];
        let mut consts = vec![0; n];
        let mut recip = vec![None; n];
        let mut mul_kind = vec![None; n];
        let mut div_shift = vec![0u8; n];
        for (i, vd) in program.values.iter().enumerate() {
            frac[i] = match vd.ty {
                Ty::Real(_) => frac_for(ranges.values[i]),
                Ty::Bool | Ty::Mode(_) => 0,
            };
            match vd.op {
                Op::Const(c) => consts[i] = fx::from_f64(c, frac[i]).0,
                Op::Param(p) => {
                    consts[i] = fx::from_f64(program.params[p.index()].value, frac[i]).0
                }
                _ => {}
            }
        }
        let mut param_slot = vec![None; program.params.len()];
        let mut param_words: Vec<ParamWord> = program
            .runtime_params()
            .enumerate()
            .map(|(k, id)| {
                param_slot[id.index()] = Some(k);
                let (lo, hi) = program.params[id.index()].runtime.unwrap_or((0.0, 0.0));
                let f = frac_for(Interval::new(lo, hi));
                ParamWord {
                    param: id,
                    frac: f,
                    raw_range: (fx::from_f64(lo, f).0, fx::from_f64(hi, f).0),
                }
            })
            .collect();
        // A word has the format of the values reading it (their intervals are the param's).
        for (i, vd) in program.values.iter().enumerate() {
            if let Op::Param(p) = vd.op {
                if let Some(k) = param_slot[p.index()] {
                    let w = &mut param_words[k];
                    let (lo, hi) = program.params[p.index()].runtime.unwrap_or((0.0, 0.0));
                    w.frac = frac[i];
                    w.raw_range = (fx::from_f64(lo, frac[i]).0, fx::from_f64(hi, frac[i]).0);
                }
            }
        }
        let is_const = |v: Value| program.const_value(v).is_some();
        let const_value = |v: Value| program.const_value(v).unwrap_or(f64::NAN);
        // Per multiplication: its operands as planned (format, range, free low bits) and
        // whether the plan's pair is swapped against operand order.
        let mut planned: Vec<(usize, MulOperands, bool)> = Vec::new();
        for (i, vd) in program.values.iter().enumerate() {
            let (x, y, c) = match vd.op {
                Op::Arith(ArithOp::Div, _, y) if !is_const(y) => {
                    if matches!(program.values[y.index()].ty, Ty::Real(_)) {
                        div_shift[i] = plan_div_shift(
                            frac[y.index()],
                            ranges.values[y.index()],
                            frac[i],
                            ranges.values[i],
                            config.div_rel_tolerance,
                        );
                    }
                    continue;
                }
                Op::Arith(ArithOp::Div, x, y) if is_const(y) => {
                    let c = const_value(y);
                    if c == 0.0 {
                        continue;
                    }
                    let (raw, f) = constant(1.0 / c);
                    recip[i] = Some((raw, f));
                    (x, None, Some((raw, f)))
                }
                Op::Arith(ArithOp::Mul, x, y) => {
                    if is_const(y) {
                        (x, None, Some((consts[y.index()], frac[y.index()])))
                    } else if is_const(x) {
                        (y, None, Some((consts[x.index()], frac[x.index()])))
                    } else {
                        (x, Some(y), None)
                    }
                }
                _ => continue,
            };
            let fx_of = |v: Value| (frac[v.index()], ranges.values[v.index()]);
            let (ops, swapped) = match (y, c) {
                (_, Some((raw, fc))) => {
                    let free = raw.trailing_zeros().min(31) as i32;
                    let ops = MulOperands {
                        x: fx_of(x),
                        free_x: 0,
                        y: (fc, Interval::point(tactus_runtime::fixed::to_f64(raw, fc))),
                        free_y: free,
                        constant: true,
                        result: ranges.values[i],
                        fr: frac[i],
                    };
                    // The constant operand is the second one of the planned pair; the shifts
                    // are stored in operand order (x, y), which is what every engine applies.
                    let swapped = matches!(vd.op, Op::Arith(ArithOp::Mul, a, _) if is_const(a));
                    (ops, swapped)
                }
                (Some(y), None) => (
                    MulOperands {
                        x: fx_of(x),
                        free_x: 0,
                        y: fx_of(y),
                        free_y: 0,
                        constant: false,
                        result: ranges.values[i],
                        fr: frac[i],
                    },
                    false,
                ),
                (None, None) => continue,
            };
            mul_kind[i] = Some(ops.plan(swapped, true));
            planned.push((i, ops, swapped));
        }
        let mut mul_options = vec![Vec::new(); n];
        for (i, ops, swapped) in &planned {
            let muls = Some(ops.plan(*swapped, false)).filter(|k| matches!(k, MulKind::Muls(..)));
            let halves = ops.halves(*swapped);
            let high = ops.high().map(|(k, _)| MulKind::High(k));
            mul_options[*i] = muls.into_iter().chain(halves).chain(high).collect();
        }
        let sensor_frac: Vec<i32> = program
            .sensors
            .iter()
            .map(|s| frac_for(Interval::new(s.range.0, s.range.1)))
            .collect();
        let sensor_raw_range = program
            .sensors
            .iter()
            .zip(&sensor_frac)
            .map(|(s, &f)| (fx::from_f64(s.range.0, f).0, fx::from_f64(s.range.1, f).0))
            .collect();
        let state_frac: Vec<i32> = program
            .states
            .iter()
            .map(|s| frac_for(Interval::new(s.range.0, s.range.1)))
            .collect();
        let state_raw_range = program
            .states
            .iter()
            .zip(&state_frac)
            .map(|(s, &f)| (fx::from_f64(s.range.0, f).0, fx::from_f64(s.range.1, f).0))
            .collect();
        let state_init = program
            .states
            .iter()
            .zip(&state_frac)
            .map(|(s, &f)| fx::from_f64(s.init, f).0)
            .collect();
        let r = program.sample_rate_hz / WINDOW as f64;
        let deriv_gain = [constant(r), constant(r * r)];
        let warnings = ranges
            .clamped
            .iter()
            .map(|v| {
                let vd = &program.values[v.index()];
                Diagnostic::warning(
                    "W0101",
                    format!(
                        "no bound for this value: fixed-point saturation inserted at ±{} {}",
                        range::UNBOUNDED_CLAMP,
                        match vd.ty {
                            Ty::Real(d) => d.unit_string(),
                            _ => String::new(),
                        }
                    ),
                    vd.span.clone(),
                )
                .hint("bound it: a division by a range containing 0 or an exp of a wide range has no bound; clamp the operand or narrow the ranges it comes from")
            })
            .collect();
        let publ = published(program, &frac);
        let mut fp = FixedProgram {
            force_frac: publ.force,
            total_frac: publ.total,
            output_frac: publ.output,
            event_frac: publ.event,
            program: program.clone(),
            ranges,
            frac,
            consts,
            recip,
            mul_kind,
            mul_options,
            div_shift: vec![0; n],
            sensor_frac,
            sensor_raw_range,
            state_frac,
            state_raw_range,
            state_init,
            deriv_gain,
            warnings,
            param_slot,
            param_words,
            reciprocals: recips.recips,
            refused_reciprocals: recips.refused,
            narrowed,
        };
        // Products are budgeted against the exact divisions: the divisor shifts' error is
        // charged to the divisions' own tolerance, not handed on to the products.
        fp.spend_precision_budget(&planned, config);
        fp.div_shift = div_shift;
        if config.simulate {
            fp.spend_by_simulation(original, &planned, config);
        }
        fp.widen_by_local_errors();
        // Once the plan (and with it every value's error bound) is final: the flow facts
        // the rewrite rests on hold for the words every fixed engine computes.
        if config.level_edges {
            flow::edges::level_edges(&mut fp);
        }
        fp
    }

    /// Widens every real value's interval by its local error bound
    /// ([`report::local_errors`]), once the plan is final: the interval of the exact result
    /// then also holds the word every fixed engine computes — a cut 32×16 product or a
    /// pre-shifted `MULS` lies up to 2^-15 of its magnitude outside the exact one. Backends
    /// that drop a saturation or a state store's clamp where the interval proves it dead
    /// (the Thumb code) rely on this. Formats are not changed: a widened interval beyond its
    /// format's reach only makes those backends keep the saturation. Values whose bound is
    /// not finite or above [`WIDEN_MAX_REL`] of their magnitude keep their interval (as
    /// before the widening): there the bound is the analysis' looseness over long chains
    /// (a bowed string's divisors would all seem to reach 0), not a form's error.
    fn widen_by_local_errors(&mut self) {
        let errors = report::local_errors(self);
        for ((iv, e), vd) in self
            .ranges
            .values
            .iter_mut()
            .zip(errors)
            .zip(&self.program.values)
        {
            let small = e <= WIDEN_MAX_REL * iv.mag();
            if matches!(vd.ty, Ty::Real(_)) && e.is_finite() && e > 0.0 && small {
                *iv = Interval::new(iv.lo - e, iv.hi + e);
            }
        }
    }

    /// The planner's second pass: cheaper product forms than the error analysis could prove,
    /// each kept only when the accuracy contract ([`contract`]) still holds with
    /// [`SIMULATION_MARGIN`] of every clause to spare, simulated against the f64 reference
    /// on every built-in stimulus, full dips of [`SIMULATED_DESCENTS_S`] and
    /// [`SIMULATED_RANDOM_RUNS`] runs of adversarial raw sensor words (where the
    /// analysis proves the force clause for every input, also keeping that proof), with
    /// the params' own values — for a shared program, at the param values of the keys
    /// [`simulated_keys`] picks (physical points: each key's values come from its own fold;
    /// a program with run-time params but no recorded keys also at the far corner of the
    /// intervals). It starts from the analysis' plan. A run on which that plan already breaks
    /// the half-tolerance contract (a contact switch decided by nanometres after a long free
    /// flight: grand88's E4 half dip closes the hammer–key contact with 11 nm to spare in
    /// f64, and every product 64-bit closes it a sample late too) cannot tell plans apart by
    /// holding the contract; there a cheaper plan must be no worse than the analysis' plan
    /// clause by clause, with the force read within the events' time tolerance
    /// ([`contract::ContractCheck::max_force_lsb_within_time`]), plus the search's share of
    /// each clause ([`within_base`]); this holds for every form's round. Four rounds: every
    /// product not yet `MULS` tries its `MULS` plan, every product still high word or 64-bit
    /// its first then its second 32×16 form, every product still 64-bit its high word; the
    /// rounds again while a pass changed the plan (at most [`SEARCH_PASSES`]). Each round tests
    /// groups of products, breadth first (the whole round, then the halves of a failing
    /// group), with at most [`MAX_SIMULATIONS`] simulations a round; a failing simulation
    /// stops at its first broken sample, and the stimulus that failed is tried first next
    /// time. Only keyboard programs (one sensor) of at most [`MAX_SIMULATED_VALUES`] values
    /// are simulated. Results are kept per process and on disk ([`plan_cache`]: the same
    /// program planned again by the same compiler costs nothing), and threads or processes
    /// planning the same program at once wait for one search
    /// ([`plan_cache::searched_once`]).
    fn spend_by_simulation(
        &mut self,
        original: &Program,
        planned: &[(usize, MulOperands, bool)],
        config: &PlanConfig,
    ) {
        if original.sensors.len() != 1 || self.program.values.len() > MAX_SIMULATED_VALUES {
            return;
        }
        let key = format!("{config:?}{original:?}");
        let start = self.mul_kind.clone();
        self.mul_kind = plan_cache::searched_once(&key, &start, || {
            self.search_by_simulation(original, planned);
            self.mul_kind.clone()
        });
    }

    /// The search of [`Self::spend_by_simulation`], uncached.
    fn search_by_simulation(&mut self, original: &Program, planned: &[(usize, MulOperands, bool)]) {
        let strict = original.contract.scaled(SIMULATION_MARGIN);
        let lsb = report::analyse(self).dac_lsb_n();
        // The params' own values; for a shared program the param values of real keys
        // (`simulated_keys`); with run-time params but no keys also the far corner (each
        // param at the end farther from its own value).
        let ids: Vec<ParamId> = original.runtime_params().collect();
        let keys = simulated_keys(original);
        let mut points: Vec<Vec<f64>> = keys
            .iter()
            .map(|&k| original.runtime_keys[k].clone())
            .filter(|v| v.len() == ids.len())
            .collect();
        if points.is_empty() {
            points.push(Vec::new());
            if !ids.is_empty() {
                points.push(
                    ids.iter()
                        .map(|id| {
                            let d = &original.params[id.index()];
                            let (lo, hi) = d.runtime.unwrap_or((d.value, d.value));
                            if (d.value - lo).abs() > (hi - d.value).abs() {
                                lo
                            } else {
                                hi
                            }
                        })
                        .collect(),
                );
            }
        }
        // The inputs ([`simulated_inputs`]) at every point, recorded once (f64), each
        // independent: on every core, in a fixed order.
        let inputs = simulated_inputs(original, self.sensor_raw_range[0]);
        let this = &*self;
        let np = points.len();
        let mut runs: Vec<contract::ReferenceRun> = workers::map(inputs.len() * np, |j| {
            // Every point lies within the intervals the program was planned for.
            inputs[j / np]
                .1
                .reference(original, this, &points[j % np])
                .ok()
        })
        .into_iter()
        .flatten()
        .collect();
        // The shortest runs first: a failing plan is found sooner.
        runs.sort_by_key(|r| r.len());
        // What the analysis' plan shows on each run, where it breaks the half-tolerance
        // contract (`None` where it holds).
        let base: Vec<Option<contract::ContractCheck>> = workers::map(runs.len(), |i| {
            let c = contract::compare(original, this, &runs[i], lsb, &strict, false).ok()?;
            let broken = !c.violations(&strict, original.sample_rate_hz).is_empty();
            broken.then_some(c)
        });
        let mut order: Vec<usize> = (0..runs.len()).collect();
        // Where the analysis proves the force clause for every input (no integrated state
        // feeds the total), the search keeps it proven: simulation only adds to a proof.
        let proven = {
            let pr = report::analyse(self);
            !pr.total_is_local && pr.total <= original.contract.force.lsb(lsb) * lsb
        };
        let mut holds = |fp: &FixedProgram| -> bool {
            if proven {
                let pr = report::analyse(fp);
                if pr.total_is_local || pr.total > original.contract.force.lsb(lsb) * lsb {
                    return false;
                }
            }
            let fails = |&i: &usize| {
                let (r, b) = (&runs[i], &base[i]);
                // A run the analysis' plan breaks is compared whole (the force within the
                // time tolerance needs every sample).
                let check = contract::compare(original, fp, r, lsb, &strict, b.is_none());
                !match (b, check) {
                    (_, Err(_)) => false,
                    (None, Ok(c)) => c.violations(&strict, original.sample_rate_hz).is_empty(),
                    (Some(b), Ok(c)) => within_base(&c, b, &strict),
                }
            };
            // The run that broke the last refused plan first (it often breaks this one too),
            // then the others on every core ([`workers::find`]); a failing run goes first
            // next time.
            let failed = match order.first() {
                Some(i) if fails(i) => Some(0),
                Some(_) => workers::find(&order[1..], fails).map(|pos| pos + 1),
                None => None,
            };
            if let Some(pos) = failed {
                let i = order.remove(pos);
                order.insert(0, i);
                return false;
            }
            true
        };
        {
            // Round 0: every product not yet `MULS` tries its `MULS` form; rounds 1 and 2:
            // every product still high word or 64-bit its first, then its second 32×16 form
            // (the smaller error first; two run-time operands have two); round 3: every
            // product still 64-bit its high word — the forms `mul_options` lists. Then the
            // rounds again while a pass changed something (at most [`SEARCH_PASSES`]): a
            // product refused beside others may pass in the plan they settled in.
            for _ in 0..SEARCH_PASSES {
                let before = self.mul_kind.clone();
                for round in 0..4 {
                    let candidates: Vec<(usize, MulKind)> = planned
                        .iter()
                        .filter_map(|&(i, _, _)| {
                            let now = self.mul_kind[i];
                            let options = &self.mul_options[i];
                            let option = |f: fn(&MulKind) -> bool, nth: usize| {
                                options.iter().copied().filter(f).nth(nth).map(|k| (i, k))
                            };
                            let above_half = matches!(now, Some(MulKind::High(_) | MulKind::Wide));
                            match round {
                                0 if !matches!(now, Some(MulKind::Muls(..))) => {
                                    option(|k| matches!(k, MulKind::Muls(..)), 0)
                                }
                                1 | 2 if above_half => {
                                    option(|k| matches!(k, MulKind::Mul32x16 { .. }), round - 1)
                                }
                                3 if now == Some(MulKind::Wide) => {
                                    option(|k| matches!(k, MulKind::High(_)), 0)
                                }
                                _ => None,
                            }
                        })
                        .collect();
                    let mut queue: std::collections::VecDeque<&[(usize, MulKind)]> =
                        std::collections::VecDeque::from([&candidates[..]]);
                    let mut done = 0;
                    while let Some(group) = queue.pop_front() {
                        if group.is_empty() || done == MAX_SIMULATIONS {
                            continue;
                        }
                        done += 1;
                        let was: Vec<Option<MulKind>> =
                            group.iter().map(|(i, _)| self.mul_kind[*i]).collect();
                        for &(i, k) in group {
                            self.mul_kind[i] = Some(k);
                        }
                        if !holds(self) {
                            for (&(i, _), w) in group.iter().zip(was) {
                                self.mul_kind[i] = w;
                            }
                            if group.len() > 1 {
                                let (a, b) = group.split_at(group.len() / 2);
                                queue.push_back(a);
                                queue.push_back(b);
                            }
                        }
                    }
                }
                if self.mul_kind == before {
                    break;
                }
            }
        }
    }

    /// Turns 64-bit products into `MULS` products while the error bounds of
    /// [`report::analyse`] stay within the precision budget: the total force and every force
    /// term within [`BUDGET_FORCE_LSB`] DAC LSB (or their bound with exact products, if
    /// larger); every state's one-sample bound within [`BUDGET_STATE_REL`] of its range;
    /// every value that is compared, emitted or output within [`BUDGET_VALUE_REL`] of its
    /// range. Products are tried in program order; each one kept spends part of the budget.
    /// Large programs (over [`SEQUENTIAL_BUDGET_WORK`]) try them in groups instead, with at
    /// most [`MAX_GROUP_ANALYSES`] analyses: whole groups kept, the others left exact.
    fn spend_precision_budget(
        &mut self,
        planned: &[(usize, MulOperands, bool)],
        config: &PlanConfig,
    ) {
        let not_muls = |k: Option<MulKind>| !matches!(k, Some(MulKind::Muls(..)));
        if !planned.iter().any(|(i, _, _)| not_muls(self.mul_kind[*i])) {
            return;
        }
        let base = report::analyse(self);
        let watched = watched_values(&self.program);
        let lsb = base.dac_lsb_n();
        // A bound that is not finite proves nothing: such a candidate is never accepted.
        let within_growth = |pr: &report::Precision, growth: f64| -> bool {
            let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
            if !(pr.total.is_finite() && finite(&pr.force) && finite(&pr.write)) {
                return false;
            }
            let force_ok = |now: f64, was: f64| now <= was.max(config.force_lsb * lsb);
            force_ok(pr.total, base.total)
                && pr
                    .force
                    .iter()
                    .zip(&base.force)
                    .all(|(n, w)| force_ok(*n, *w))
                && self.program.states.iter().enumerate().all(|(i, st)| {
                    let mag = st.range.0.abs().max(st.range.1.abs());
                    if base.accumulating[i] || pr.accumulating[i] {
                        growth == f64::INFINITY || pr.write[i] <= growth * base.write[i]
                    } else {
                        pr.state[i].is_finite()
                            && pr.state[i] <= base.state[i].max(config.state_rel * mag)
                    }
                })
                && watched.iter().all(|v| {
                    let mag = self.ranges.values[v.index()].mag();
                    pr.value[v.index()].is_finite()
                        && pr.value[v.index()] <= base.value[v.index()].max(config.value_rel * mag)
                })
        };
        let within = |pr: &report::Precision| within_growth(pr, config.accumulating_growth);
        // A high-word product's floors are a bias, not noise: on an integrated state it adds
        // up sample after sample (three of the piano's hammer-velocity products moved a
        // slow dip's force by 48 DAC LSB with a 2× growth allowed), so it may not grow an
        // integrated state's one-sample bound at all.
        let within_high =
            |pr: &report::Precision| within_growth(pr, config.accumulating_growth.min(1.0 + 1e-9));
        // (product, its MULS plan, its plan within the tolerance to fall back to).
        let candidates: Vec<(usize, MulKind, MulKind)> = planned
            .iter()
            .filter(|(i, _, _)| not_muls(self.mul_kind[*i]))
            .map(|(i, ops, swapped)| {
                let was = self.mul_kind[*i].unwrap_or(MulKind::Wide);
                (*i, ops.plan(*swapped, false), was)
            })
            .filter(|(_, k, _)| matches!(k, MulKind::Muls(..)))
            .collect();
        // The high-word form of each 64-bit product, tried where `MULS` is refused.
        let high: std::collections::HashMap<usize, MulKind> = planned
            .iter()
            .filter_map(|(i, ops, _)| ops.high().map(|(k, _)| (*i, MulKind::High(k))))
            .collect();
        let values = self.program.values.len().max(1);
        if candidates.len().saturating_mul(values) <= SEQUENTIAL_BUDGET_WORK {
            // One analysis per product, in program order.
            for &(i, k, was) in &candidates {
                self.mul_kind[i] = Some(k);
                if !within(&report::analyse(self)) {
                    self.mul_kind[i] = Some(was);
                }
            }
            // Then the 32×16 forms for every product still 64-bit, the smaller error first
            // (its floors and cut are a bias like the high word's: no growth of an
            // integrated state), one analysis each.
            for (i, _, _) in planned {
                if self.mul_kind[*i] != Some(MulKind::Wide) {
                    continue;
                }
                let halves: Vec<MulKind> = self.mul_options[*i]
                    .iter()
                    .copied()
                    .filter(|k| matches!(k, MulKind::Mul32x16 { .. }))
                    .collect();
                for h in halves {
                    self.mul_kind[*i] = Some(h);
                    if within_high(&report::analyse(self)) {
                        break;
                    }
                    self.mul_kind[*i] = Some(MulKind::Wide);
                }
            }
            // Then the high-word form for every product still 64-bit (also those with no
            // `MULS` plan), one analysis each.
            for (i, _, _) in planned {
                if self.mul_kind[*i] != Some(MulKind::Wide) {
                    continue;
                }
                if let Some(&h) = high.get(i) {
                    self.mul_kind[*i] = Some(h);
                    if !within_high(&report::analyse(self)) {
                        self.mul_kind[*i] = Some(MulKind::Wide);
                    }
                }
            }
            return;
        }
        // Large programs: groups of products, breadth first — the whole list, then the
        // halves of each rejected group, level by level in program order, so that large
        // acceptable groups are found before the analyses run out — with at most `tries`
        // analyses. A product
        // not reached stays a 64-bit product (exact, only slower). On a bowed string
        // (19,000 values, 2,946 candidates) one analysis per product took 46 s and kept
        // none of them.
        let tries = (SEQUENTIAL_BUDGET_WORK / values).clamp(1, MAX_GROUP_ANALYSES);
        let mut queue: std::collections::VecDeque<&[(usize, MulKind, MulKind)]> =
            std::collections::VecDeque::from([&candidates[..]]);
        let mut done = 0;
        while let Some(group) = queue.pop_front() {
            if done == tries {
                break;
            }
            done += 1;
            for &(i, k, _) in group {
                self.mul_kind[i] = Some(k);
            }
            if !within(&report::analyse(self)) {
                for &(i, _, was) in group {
                    self.mul_kind[i] = Some(was);
                }
                if group.len() > 1 {
                    let (a, b) = group.split_at(group.len() / 2);
                    queue.push_back(a);
                    queue.push_back(b);
                }
            }
        }
    }

    /// The exact (unquantised) value of a constant or compile-time param value, for
    /// comparisons; `None` for a run-time param and every other value.
    pub fn exact_const(&self, v: Value) -> Option<f64> {
        self.program.const_value(v)
    }

    /// The word of value `v` in a key's param block when `v` reads a run-time param.
    pub fn param_word_of(&self, v: Value) -> Option<usize> {
        match self.program.values[v.index()].op {
            Op::Param(p) => self.param_slot[p.index()],
            _ => None,
        }
    }

    /// A key's param block: the raw word of each run-time param ([`Program::runtime_params`]
    /// order) from its SI value `values`, rounded half up in the word's format
    /// ([`tactus_runtime::fixed::from_f64`], as every constant is). Empty for a program
    /// without run-time params.
    ///
    /// Errors: [`ParamBlockError`] when the count differs or a value lies outside the
    /// interval the program was planned for (its formats would not hold it).
    pub fn param_block(&self, values: &[f64]) -> Result<Vec<i32>, ParamBlockError> {
        if values.len() != self.param_words.len() {
            return Err(ParamBlockError::Count {
                given: values.len(),
                expected: self.param_words.len(),
            });
        }
        values
            .iter()
            .zip(&self.param_words)
            .map(|(&v, w)| {
                let d = &self.program.params[w.param.index()];
                let range = d.runtime.unwrap_or((d.value, d.value));
                if !(range.0..=range.1).contains(&v) {
                    return Err(ParamBlockError::OutOfRange {
                        param: d.name.clone(),
                        value: v,
                        range,
                    });
                }
                Ok(fx::from_f64(v, w.frac).0)
            })
            .collect()
    }

    /// The param block of the params' own values ([`ParamDecl::value`]: the first key's, for
    /// a shared program); empty without run-time params.
    pub fn nominal_param_block(&self) -> Vec<i32> {
        self.param_words
            .iter()
            .map(|w| fx::from_f64(self.program.params[w.param.index()].value, w.frac).0)
            .collect()
    }

    /// Number of declared states: those of the source program, before the hidden reciprocal
    /// states ([`FixedProgram::reciprocals`]).
    pub fn declared_states(&self) -> usize {
        self.program.states.len() - self.reciprocals.len()
    }

    /// The declared states' values (SI) from a fixed engine's state words (all of them,
    /// hidden ones included): each word in its format, except that a state carried by its
    /// reciprocal ([`recip::Reciprocal::carried`]: the fixed program no longer writes it) is
    /// `k / (k/s)` of its hidden word (`k` its [`recip::Reciprocal::scale`]). What traces of
    /// the fixed engines show.
    pub fn states_si(&self, words: &[i32]) -> Vec<f64> {
        let n = self.declared_states().min(words.len());
        let mut out: Vec<f64> = (0..n)
            .map(|i| fx::to_f64(words[i], self.state_frac[i]))
            .collect();
        for r in self.reciprocals.iter().filter(|r| r.carried) {
            let (s, h) = (r.state.index(), r.recip.index());
            if s < n && h < words.len() {
                out[s] = r.scale / fx::to_f64(words[h], self.state_frac[h]);
            }
        }
        out
    }

    /// Saturations per declared state from a fixed engine's counts per state (hidden ones
    /// included): a state carried by its reciprocal counts its reciprocal's (the
    /// reciprocal saturates exactly when the state would: [`recip`]).
    pub fn declared_saturations(&self, counts: &[u64]) -> Vec<u64> {
        let n = self.declared_states().min(counts.len());
        let mut out = counts[..n].to_vec();
        for r in self.reciprocals.iter().filter(|r| r.carried) {
            if let Some(&c) = counts.get(r.recip.index()) {
                if r.state.index() < n {
                    out[r.state.index()] = c;
                }
            }
        }
        out
    }

    /// Number of multiplications of each form and their estimated cycles on a Cortex-M0+
    /// ([`MulKind::cycles`]).
    pub fn mul_forms(&self) -> MulForms {
        let mut f = MulForms::default();
        for k in self.mul_kind.iter().flatten() {
            match k {
                MulKind::Muls(..) => f.muls += 1,
                MulKind::Mul32x16 { .. } => f.m32x16 += 1,
                MulKind::High(_) => f.high += 1,
                MulKind::Wide => f.wide += 1,
            }
            f.cycles += k.cycles();
        }
        f
    }

    /// Number of `MULS` products, of products needing more (32×16, high word or 64-bit),
    /// and the estimated cycles of all ([`FixedProgram::mul_forms`]).
    pub fn mul_cost(&self) -> (usize, usize, u32) {
        let f = self.mul_forms();
        (f.muls, f.m32x16 + f.high + f.wide, f.cycles)
    }
}
