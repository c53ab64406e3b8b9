//! The regulation sheet of a key instrument: the figures a piano technician measures on a
//! real action (down-weight, up-weight, friction, balance weight, key dip, let-off, drop,
//! aftertouch, blow distance, back-check), plus the dynamics a player feels (time to key
//! bottom and hammer speed for a *pp* and an *ff* finger, the fastest repetition) — measured
//! on the instrument's own semantics (any [`Engine`]: the f64 interpreter that defines the
//! meaning, or the fixed-point interpreter that defines the firmware's bits) with the
//! closed-loop key model of `tactus_runtime::player` (key and finger mass at the key front,
//! the instrument's force pushing back, the one-sample delay of the board).
//!
//! Why the sheet looks the way it does: each figure is what a technician reads off an action
//! with weights, a ruler and a slow finger, so each is measured the same way here and says
//! how ([`Measured::how`]). Weights are in grams-force (1 gf = 9.806 65 mN), the unit of the
//! trade; travels in millimetres. A figure that does not apply to the instrument (a
//! harpsichord has no hammer to let off; an organ key that does not return by itself has no
//! up-weight) is left out with a note saying why ([`Sheet::notes`]), never faked.
//!
//! What the instrument must provide, by convention: its **first sensor** is the key travel at
//! the key front (0 = rest, the sensor's upper bound = the key bed); its **force** pushes the
//! key up; a hammer action publishes the hammer-head travel from rest as the output
//! **`hammer_pos`** (m) and strikes through the one strike rule
//! ([`crate::play::strike::strike_event`]: an event `strike` or `pluck`, first argument the
//! speed). The geometry figures need both; the weights need neither.
//!
//! The technicians' definitions (sources in `instruments/specs/concert_grand.toml`):
//! down-weight is the least weight on the key front that makes the key go down from rest —
//! through the stroke to the let-off zone on a hammer action (the let-off resistance is
//! measured separately: "the weight increases when let-off is reached", N. Hunt, PTG
//! archive 1999), to the key bed otherwise; up-weight the most weight a key held down still
//! lifts back to rest; friction `(down − up)/2`; balance weight `(down + up)/2` (D. Stanwood,
//! "The New Touchweight Metrology", PTG Journal, June 1996 and February 2000).

pub mod dynamic;
mod figure;
pub mod sheet;
pub mod spec;

use crate::play::strike::strike_event;
pub use figure::Figure;
use tactus_compiler::ir::{EventId, Program};
use tactus_compiler::sim::Engine;
use tactus_runtime::player::{FingerConfig, ForcePlayer};

/// Standard gravity, m/s² (grams-force to newtons: 1 gf = 9.806 65 mN, CGPM 1901).
pub const G_N: f64 = 9.806_65;

/// Speed of the quasi-static dip, m/s: the built-in `slow-dip` stimulus's 10 mm in 2 s, at
/// which the key's viscous terms are below 0.2 gf.
pub const QUASI_STATIC_SPEED: f64 = 0.005;

/// How long the quasi-static dip holds the key at the bottom before rising, s (the hammer
/// settles on the repetition lever: the drop is read over the last 100 ms of it).
pub const BOTTOM_HOLD_S: f64 = 0.4;

/// Bins of the force–travel loop per key dip: 0.1 mm on a 10 mm dip.
pub const LOOP_BINS: usize = 100;

/// The let-off zone starts where the quasi-static force going down first exceeds its
/// plateau (the median over 10–50 % of the dip) by this much, gf, beyond half the dip.
pub const LETOFF_RISE_GF: f64 = 10.0;

/// The longest a weight is given to move the key, s: a technician's patience. A key that
/// has not reached its goal by then (or stands still for [`STALL_S`]) did not go.
pub const WEIGHT_TIMEOUT_S: f64 = 4.0;

/// How gently a down-weight is laid on the key, s: its force rises as a raised cosine over
/// this long, longer than the swing of a key on a soft spring (a 30 g key on 20 N/m swings
/// in 0.24 s), so that the key follows the weight instead of swinging past where the weight
/// holds it (Tactus issue 70: a frictionless key on a 100 N/m spring, the weight laid on in
/// 5 ms, swung into its bed under 158 gf where 897 gf hold it there).
pub const WEIGHT_RISE_S: f64 = 0.3;

/// A key whose travel changes by less than [`STALL_M`] over this long has stopped, s.
pub const STALL_S: f64 = 0.15;

/// See [`STALL_S`], m.
pub const STALL_M: f64 = 1e-6;

/// Resolution of the weight searches, gf.
pub const WEIGHT_RESOLUTION_GF: f64 = 0.1;

/// The heaviest weight tried, gf: beyond any key (a harpsichord's pluck is ≈ 60 gf, a
/// piano's let-off ≈ 150 gf here).
pub const MAX_WEIGHT_GF: f64 = 2000.0;

/// How long the creep test watches a key held still, s (issue 35: no creep beyond 0.05 mm
/// in 1 s).
pub const CREEP_S: f64 = 1.0;

/// How a sheet is measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config {
    /// The moving key: key and finger mass at the key front (the force player's; a weight's
    /// own mass is taken as part of it).
    pub finger: FingerConfig,
    /// The *pp* finger's constant push, N. Default 0.8 N: "for a force of about 0.8 N the key
    /// takes about 150 ms to touch the keybed" (A. Askenfelt, ed., *Five Lectures on the
    /// Acoustics of the Piano*, Royal Swedish Academy of Music, 1990).
    pub pp_n: f64,
    /// The *ff* finger's constant push, N. Default 10 N, between a forte key stroke and the
    /// ≈ 50 N peak of the hardest (Tactus DESIGN.md's literature figures).
    pub ff_n: f64,
    /// The repetition finger's push, N (default 3 N, the force player's re-strike stroke).
    pub repetition_n: f64,
    /// Whether to measure the dynamic sheet too (the touch sweep of [`dynamic`]; default
    /// true).
    pub dynamic: bool,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            finger: FingerConfig::default(),
            pp_n: 0.8,
            ff_n: 10.0,
            repetition_n: 3.0,
            dynamic: true,
        }
    }
}

/// One measured figure.
#[derive(Clone, Debug, PartialEq)]
pub struct Measured {
    /// Which figure.
    pub figure: Figure,
    /// Its value, in [`Figure::unit`].
    pub value: f64,
    /// How it was measured: the stimulus or finger and what was read, with its numbers.
    pub how: String,
}

/// The quasi-static force–travel loop: the force at the key while the key is moved down
/// and back up at [`QUASI_STATIC_SPEED`] (position-driven, as `tactus sim --stimulus
/// slow-dip`), raw and in [`LOOP_BINS`] bins of travel.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ForceLoop {
    /// (travel m, force N) going down, one per sample.
    pub down: Vec<(f64, f64)>,
    /// (travel m, force N) going up, one per sample.
    pub up: Vec<(f64, f64)>,
    /// Bin width, m (the dip / [`LOOP_BINS`]).
    pub bin_m: f64,
    /// Mean force going down per bin, N (`None`: no sample in it).
    pub down_bins: Vec<Option<f64>>,
    /// Mean force going up per bin, N.
    pub up_bins: Vec<Option<f64>>,
}

impl ForceLoop {
    /// The least of `down − up` (N) over the bins wholly inside `[from_m, to_m]`, with the
    /// travel (m, the bin's middle) where it is least; `None` without such a bin.
    pub fn least_gap(&self, from_m: f64, to_m: f64) -> Option<(f64, f64)> {
        let mut best: Option<(f64, f64)> = None;
        for (i, (d, u)) in self.down_bins.iter().zip(&self.up_bins).enumerate() {
            let (lo, hi) = (i as f64 * self.bin_m, (i + 1) as f64 * self.bin_m);
            if lo < from_m - 1e-12 || hi > to_m + 1e-12 {
                continue;
            }
            if let (Some(d), Some(u)) = (d, u) {
                let gap = d - u;
                if best.is_none_or(|b| gap < b.0) {
                    best = Some((gap, 0.5 * (lo + hi)));
                }
            }
        }
        best
    }
}

/// The regulation sheet of one instrument.
#[derive(Clone, Debug, PartialEq)]
pub struct Sheet {
    /// The instrument's name.
    pub instrument: String,
    /// The figures measured, in [`Figure::ALL`] order.
    pub figures: Vec<Measured>,
    /// Figures left out and why, one sentence each.
    pub notes: Vec<String>,
    /// The quasi-static force–travel loop.
    pub force_loop: ForceLoop,
    /// The dynamic sweep's touches ([`dynamic::sweep`]), empty when the sheet was measured
    /// without it ([`Config::dynamic`]).
    pub touches: Vec<dynamic::TouchRun>,
}

impl Sheet {
    /// The value of `figure`, if measured.
    pub fn get(&self, figure: Figure) -> Option<f64> {
        self.figures
            .iter()
            .find(|m| m.figure == figure)
            .map(|m| m.value)
    }
}

/// Grams-force to newtons.
pub fn gf_to_n(gf: f64) -> f64 {
    gf * 1e-3 * G_N
}

/// Newtons to grams-force.
pub fn n_to_gf(n: f64) -> f64 {
    n / G_N * 1e3
}

/// One key of the instrument on an engine, seen as the sheet needs it: the force, the
/// hammer's travel and the strikes.
#[derive(Clone)]
struct Key<E> {
    engine: E,
    strike: Option<EventId>,
    hammer: Option<usize>,
    sample: usize,
    fs: f64,
    /// Force of the last sample, N (positive pushes the key up).
    force: f64,
    /// Hammer travel from rest after the last sample, m (`NaN` without `hammer_pos`).
    hammer_m: f64,
    /// Strike speed of the last sample, m/s.
    struck: Option<f64>,
}

impl<E: Engine + Clone> Key<E> {
    fn new(program: &Program, engine: E) -> Self {
        Key {
            engine,
            strike: strike_event(program),
            hammer: program.outputs.iter().position(|o| o.name == "hammer_pos"),
            sample: 0,
            fs: program.sample_rate_hz,
            force: 0.0,
            hammer_m: f64::NAN,
            struck: None,
        }
    }

    /// One sample with the key at travel `x` (m).
    fn at(&mut self, x: f64) -> Result<(), String> {
        let out = self.engine.step_si(&[x]);
        self.force = out.total;
        self.hammer_m = self
            .hammer
            .and_then(|i| out.outputs.get(i).copied())
            .unwrap_or(f64::NAN);
        self.struck = out
            .events
            .iter()
            .find(|(e, _)| Some(*e) == self.strike)
            .map(|(_, a)| a.first().copied().unwrap_or(0.0));
        if !self.force.is_finite() || self.struck.is_some_and(|s| !s.is_finite()) {
            return Err(format!(
                "the instrument computed a non-finite value at sample {} (t = {:.6} s): force {} N",
                self.sample,
                self.sample as f64 / self.fs,
                self.force
            ));
        }
        self.sample += 1;
        Ok(())
    }

    /// One sample of the closed loop: the engine reads the player's travel, then the finger
    /// (`push` N, down) and the instrument's force move the key (the board's one-sample
    /// delay).
    fn finger(&mut self, p: &mut ForcePlayer, push: f64) -> Result<(), String> {
        self.at(p.x_m)?;
        p.step(push, self.force);
        Ok(())
    }
}

/// What the quasi-static dip read, besides the loop.
struct Dip<E> {
    force_loop: ForceLoop,
    /// Highest hammer travel going down (m) and the key travel there (m).
    hammer_peak: Option<(f64, f64)>,
    /// Mean hammer travel over the last 100 ms at the bottom, m.
    hammer_at_bottom: f64,
    /// The key held at the bottom after the hold (for the up-weight).
    at_bottom: Key<E>,
}

/// Builds the force–travel loop's bins.
fn bins(samples: &[(f64, f64)], bin_m: f64) -> Vec<Option<f64>> {
    let mut sum = vec![(0.0, 0usize); LOOP_BINS];
    for &(x, f) in samples {
        let i = ((x / bin_m).floor() as isize).clamp(0, LOOP_BINS as isize - 1) as usize;
        sum[i].0 += f;
        sum[i].1 += 1;
    }
    sum.iter()
        .map(|&(s, n)| (n > 0).then(|| s / n as f64))
        .collect()
}

/// The quasi-static dip: 20 ms at rest, down to the bottom at [`QUASI_STATIC_SPEED`], held
/// [`BOTTOM_HOLD_S`], back up, 50 ms at rest.
fn quasi_static<E: Engine + Clone>(rest: &Key<E>, dip: f64) -> Result<Dip<E>, String> {
    let mut key = rest.clone();
    let fs = key.fs;
    let step = QUASI_STATIC_SPEED / fs;
    let n_move = (dip / step).ceil() as usize;
    let mut lp = ForceLoop {
        bin_m: dip / LOOP_BINS as f64,
        ..ForceLoop::default()
    };
    let mut peak: Option<(f64, f64)> = None;
    for i in 1..=n_move {
        let x = (i as f64 * step).min(dip);
        key.at(x)?;
        lp.down.push((x, key.force));
        if key.hammer_m.is_finite() && peak.is_none_or(|p| key.hammer_m > p.0) {
            peak = Some((key.hammer_m, x));
        }
    }
    let n_hold = (BOTTOM_HOLD_S * fs) as usize;
    let n_tail = (0.1 * fs) as usize;
    let mut tail = 0.0;
    for i in 0..n_hold {
        key.at(dip)?;
        if i >= n_hold - n_tail {
            tail += key.hammer_m;
        }
    }
    let at_bottom = key.clone();
    for i in 1..=n_move {
        let x = (dip - i as f64 * step).max(0.0);
        key.at(x)?;
        lp.up.push((x, key.force));
    }
    lp.down_bins = bins(&lp.down, lp.bin_m);
    lp.up_bins = bins(&lp.up, lp.bin_m);
    Ok(Dip {
        force_loop: lp,
        hammer_peak: peak,
        hammer_at_bottom: tail / n_tail as f64,
        at_bottom,
    })
}

/// Where the let-off zone starts on the way down, m: the first bin beyond half the dip whose
/// force exceeds the plateau (median over 10–50 % of the dip) by [`LETOFF_RISE_GF`].
fn letoff_zone(lp: &ForceLoop) -> Option<f64> {
    above_plateau(lp, LETOFF_RISE_GF)
}

/// The first bin beyond half the dip whose force going down exceeds the plateau (the median
/// over 10–50 % of the dip) by more than `rise_gf`, as a travel, m; `None` when the plateau
/// has no bin or no bin rises so far.
fn above_plateau(lp: &ForceLoop, rise_gf: f64) -> Option<f64> {
    let n = lp.down_bins.len();
    let mut plateau: Vec<f64> = lp.down_bins[n / 10..n / 2]
        .iter()
        .flatten()
        .copied()
        .collect();
    if plateau.is_empty() {
        return None;
    }
    plateau.sort_by(f64::total_cmp);
    let limit = plateau[plateau.len() / 2] + gf_to_n(rise_gf);
    (n / 2..n)
        .find(|&i| lp.down_bins[i].is_some_and(|f| f > limit))
        .map(|i| i as f64 * lp.bin_m)
}

/// What the quasi-static loop says of a key whose force rises along its stroke.
struct Sprung {
    /// Change of the mean of the down and up forces between the ends of the range, gf.
    rise_gf: f64,
    /// The median gap (down − up) over the bins, gf.
    gap_gf: f64,
    /// The median gap over 40–60 % of the dip, gf.
    mid_gap_gf: f64,
    /// The median of the mean of down and up over 40–60 % of the dip, gf.
    mid_mean_gf: f64,
}

/// Whether the key is sprung: the mean of its quasi-static forces going down and up differs
/// between the ends of `[from_m, to_m]` (a few bins each) by more than twice the weights'
/// resolution, [`WEIGHT_RESOLUTION_GF`]: then `(down − up)/2` would count half that change
/// as friction, beyond what the weights resolve (a balanced lever's force is flat: the
/// piano's changes by 0.00 gf). `None` for a balanced key or a loop with too few bins to say.
fn sprung(lp: &ForceLoop, from_m: f64, to_m: f64) -> Option<Sprung> {
    let dip = lp.bin_m * LOOP_BINS as f64;
    let pairs = |lo: f64, hi: f64| -> Vec<(f64, f64)> {
        (0..LOOP_BINS)
            .filter(|&i| {
                let x = (i as f64 + 0.5) * lp.bin_m;
                x >= lo && x <= hi
            })
            .filter_map(|i| Some((lp.down_bins[i]?, lp.up_bins[i]?)))
            .map(|(d, u)| (n_to_gf(0.5 * (d + u)), n_to_gf(d - u)))
            .collect()
    };
    // The median, the two middle values' mean for an even count (the middle of the dip
    // falls between two bins).
    let med = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n.is_multiple_of(2) {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        } else {
            v[n / 2]
        }
    };
    let all = pairs(from_m, to_m);
    let mid = pairs(0.4 * dip, 0.6 * dip);
    if all.len() < 2 || mid.is_empty() {
        return None;
    }
    // The ends of the range, a few bins each: a bump between them (a plectrum, a let-off)
    // is no spring.
    let ends = (all.len() / 4).clamp(1, 5);
    let head: Vec<f64> = all[..ends].iter().map(|p| p.0).collect();
    let tail: Vec<f64> = all[all.len() - ends..].iter().map(|p| p.0).collect();
    let rise = (med(tail) - med(head)).abs();
    let gap = med(all.iter().map(|p| p.1).collect());
    (rise > 2.0 * WEIGHT_RESOLUTION_GF).then(|| Sprung {
        rise_gf: rise,
        gap_gf: gap,
        mid_gap_gf: med(mid.iter().map(|p| p.1).collect()),
        mid_mean_gf: med(mid.iter().map(|p| p.0).collect()),
    })
}

/// Where the force going down starts to rise into the let-off zone, m: the first bin beyond
/// half the dip whose force exceeds the plateau (as [`letoff_zone`] reads it) by more than
/// [`LETOFF_ONSET_GF`]. A down-weight takes the key to there, where the let-off's rising
/// resistance stops it (the key comes to rest at the goal, [`Goal::DownTo`]).
fn letoff_onset(lp: &ForceLoop) -> Option<f64> {
    above_plateau(lp, LETOFF_ONSET_GF)
}

/// The rise over the plateau that marks the onset of the let-off, gf (ten times the weights'
/// resolution).
pub const LETOFF_ONSET_GF: f64 = 1.0;

/// Outcome of a weight on a key.
enum Went {
    /// Reached its goal.
    There,
    /// Stopped, or ran out of time.
    Stuck,
}

/// Where a weight must take a key.
#[derive(Clone, Copy)]
enum Goal {
    /// Down to at least this travel, m, and stay there: a key that swings past the goal and
    /// back under the weight has not gone (the weight does not hold it there), one that
    /// comes to rest at the goal or beyond has.
    DownTo(f64),
    /// Back to this travel or above, m, and stay there: the key must come to rest there (a
    /// key that bounces off its rest stop and sinks again has not returned).
    BackTo(f64),
}

/// Runs `key` under a constant finger force `push_n` (reached over `rise_s`) from the
/// player `p` until `goal` is met, the key stops, or [`WEIGHT_TIMEOUT_S`] passes.
fn under_weight<E: Engine + Clone>(
    mut key: Key<E>,
    mut p: ForcePlayer,
    push_n: f64,
    rise_s: f64,
    goal: Goal,
) -> Result<Went, String> {
    let fs = key.fs;
    let stall = (STALL_S * fs) as usize;
    // The key has stopped when it stays within STALL_M of where it was `stall` samples ago.
    let (mut anchor, mut since) = (p.x_m, 0usize);
    for n in 0..(WEIGHT_TIMEOUT_S * fs) as usize {
        let t = n as f64 / fs;
        let ramp = if t < rise_s {
            0.5 * (1.0 - (std::f64::consts::PI * t / rise_s).cos())
        } else {
            1.0
        };
        key.finger(&mut p, push_n * ramp)?;
        let x = p.x_m;
        // Still while the weight is still being laid on is no stop.
        if (x - anchor).abs() > STALL_M || t < rise_s {
            (anchor, since) = (x, 0);
        } else {
            since += 1;
            if since > stall {
                break;
            }
        }
    }
    Ok(match goal {
        Goal::BackTo(g) if p.x_m <= g => Went::There,
        Goal::DownTo(g) if p.x_m >= g => Went::There,
        _ => Went::Stuck,
    })
}

/// The boundary weight (gf) between weights that fail below and weights that `goes` above,
/// to [`WEIGHT_RESOLUTION_GF`]: bracketed around `estimate` (the quasi-static loop's force
/// there, gf) by steps that double, then bisected. `None` when even weight 0 goes or
/// [`MAX_WEIGHT_GF`] does not.
fn threshold(
    estimate: f64,
    goes: &mut dyn FnMut(f64) -> Result<bool, String>,
) -> Result<Option<f64>, String> {
    let mut step = 4.0;
    let mut lo = (estimate - step).clamp(0.0, MAX_WEIGHT_GF);
    let mut hi = (estimate + step).clamp(0.0, MAX_WEIGHT_GF);
    while !goes(hi)? {
        if hi >= MAX_WEIGHT_GF {
            return Ok(None);
        }
        lo = hi;
        step *= 2.0;
        hi = (hi + step).min(MAX_WEIGHT_GF);
    }
    while goes(lo)? {
        if lo <= 0.0 {
            return Ok(None);
        }
        hi = lo;
        step *= 2.0;
        lo = (lo - step).max(0.0);
    }
    while hi - lo > WEIGHT_RESOLUTION_GF {
        let mid = 0.5 * (lo + hi);
        if goes(mid)? {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Ok(Some(0.5 * (lo + hi)))
}

/// The largest (`max`) or least mean force of `bins` (N) over `[from_m, to_m]`, gf.
fn loop_force(lp: &ForceLoop, bins: &[Option<f64>], from_m: f64, to_m: f64, max: bool) -> f64 {
    let it = bins.iter().enumerate().filter_map(|(i, f)| {
        let x = (i as f64 + 0.5) * lp.bin_m;
        (x >= from_m && x <= to_m).then_some(*f).flatten()
    });
    let f = if max {
        it.fold(f64::NEG_INFINITY, f64::max)
    } else {
        it.fold(f64::INFINITY, f64::min)
    };
    if f.is_finite() {
        n_to_gf(f)
    } else {
        50.0
    }
}

/// A push of constant force `push_n` from rest for `seconds`: (time to the key bed s, first
/// strike (time s, speed m/s), the key held after it for the back-check: hammer travel
/// 250–300 ms after the strike, mean, m).
struct Stroke {
    bottom_s: Option<f64>,
    strike: Option<(f64, f64)>,
    hammer_strike_m: f64,
    hammer_after_m: Option<f64>,
}

fn stroke<E: Engine + Clone>(
    rest: &Key<E>,
    config: &Config,
    dip: f64,
    push_n: f64,
    seconds: f64,
) -> Result<Stroke, String> {
    let mut key = rest.clone();
    let fs = key.fs;
    let mut p = ForcePlayer::new(dip, config.finger.mass_kg, fs);
    let rise = config.finger.rise_s;
    let mut out = Stroke {
        bottom_s: None,
        strike: None,
        hammer_strike_m: f64::NAN,
        hammer_after_m: None,
    };
    let (mut sum, mut count) = (0.0, 0usize);
    for n in 0..(seconds * fs) as usize {
        let t = n as f64 / fs;
        let ramp = if t < rise {
            0.5 * (1.0 - (std::f64::consts::PI * t / rise).cos())
        } else {
            1.0
        };
        key.finger(&mut p, push_n * ramp)?;
        if out.bottom_s.is_none() && p.x_m >= dip {
            out.bottom_s = Some(t);
        }
        if out.strike.is_none() {
            if let Some(v) = key.struck {
                out.strike = Some((t, v));
                out.hammer_strike_m = key.hammer_m;
            }
        } else if let Some((ts, _)) = out.strike {
            if (0.25..0.30).contains(&(t - ts)) && key.hammer_m.is_finite() {
                sum += key.hammer_m;
                count += 1;
            }
        }
    }
    out.hammer_after_m = (count > 0).then(|| sum / count as f64);
    Ok(out)
}

/// Repeated strokes of `push_n` with period `period_s`, five notes: each note's finger
/// pushes from the start of its period until its hammer strikes, then lifts until the next
/// note (the force player's stroke: the push lasts until the strike; a finger lifted at a
/// fixed half period left a heavy bass key short of let-off, coasting, and the hammer's
/// return from the string threw key and hammer back up into the next push: at 9–11 g the
/// notes of a 3 N push failed and struck in alternate bands of periods from 68 to 84 ms).
/// Whether each note strikes (and none more often than the first), and the lowest travel
/// between the first strike and the last push (m).
fn repeats<E: Engine + Clone>(
    rest: &Key<E>,
    config: &Config,
    dip: f64,
    push_n: f64,
    period_s: f64,
) -> Result<(bool, f64), String> {
    const NOTES: usize = 5;
    let mut key = rest.clone();
    let fs = key.fs;
    let mut p = ForcePlayer::new(dip, config.finger.mass_kg, fs);
    let rise = config.finger.rise_s;
    let mut strikes = [0usize; NOTES];
    let mut lowest = f64::INFINITY;
    let mut first_strike = false;
    let total = ((NOTES as f64 + 0.5) * period_s * fs) as usize;
    // The note whose push has ended with its strike.
    let mut done = None;
    for n in 0..total {
        let t = n as f64 / fs;
        let note = ((t / period_s) as usize).min(NOTES);
        let since = t - note as f64 * period_s;
        let push = if note < NOTES && done != Some(note) {
            let ramp = if since < rise {
                0.5 * (1.0 - (std::f64::consts::PI * since / rise).cos())
            } else {
                1.0
            };
            push_n * ramp
        } else {
            0.0
        };
        key.finger(&mut p, push)?;
        if key.struck.is_some() {
            first_strike = true;
            if note < NOTES {
                strikes[note] += 1;
                done = Some(note);
            } else {
                strikes[NOTES - 1] += 1;
            }
        }
        if first_strike && note < NOTES - 1 {
            lowest = lowest.min(p.x_m);
        }
    }
    // Every note strikes, and none more often than the first (an instrument may strike
    // several times a note: two plectra).
    Ok((
        strikes[0] >= 1 && strikes.iter().all(|&s| s >= 1 && s <= strikes[0]),
        lowest,
    ))
}

/// Measures the regulation sheet of `program` on `engine` (a fresh instance at rest of that
/// program: the f64 interpreter for the meaning, the fixed-point interpreter for the
/// firmware's bits).
///
/// Errors: a message when `program` is not a key instrument (no sensor, a pen instrument, a
/// first sensor whose range does not start at 0 or is not a length) or when the engine
/// computes a non-finite force.
pub fn measure<E: Engine + Clone>(
    program: &Program,
    engine: E,
    config: &Config,
) -> Result<Sheet, String> {
    let Some(sensor) = program.sensors.first() else {
        return Err(format!(
            "instrument `{}` has no sensor: regulation needs a key",
            program.name
        ));
    };
    if program.is_pen() {
        return Err(format!(
            "instrument `{}` is a pen instrument (a vector force): regulation measures keys",
            program.name
        ));
    }
    let (lo, dip) = sensor.range;
    if lo != 0.0 || !(dip > 0.0 && dip <= 0.1) {
        return Err(format!(
            "instrument `{}`: regulation reads the first sensor `{}` as the key travel, from 0 at rest to the key bed (at most 100 mm); its range is [{lo}, {dip}]",
            program.name, sensor.name
        ));
    }
    let mut key = Key::new(program, engine);
    for _ in 0..(0.02 * key.fs) as usize {
        key.at(0.0)?;
    }
    let rest = key;
    let hammer_action = rest.hammer.is_some() && rest.strike.is_some();
    let mut figures = Vec::new();
    let mut notes = Vec::new();
    let mm = |m: f64| m * 1e3;
    let speed_mm_s = mm(QUASI_STATIC_SPEED);

    // The quasi-static loop.
    let dipped = quasi_static(&rest, dip)?;
    let lp = &dipped.force_loop;
    let letoff_zone = if hammer_action { letoff_zone(lp) } else { None };
    let goal = letoff_zone.unwrap_or(dip);
    if hammer_action && letoff_zone.is_none() {
        notes.push(format!(
            "no let-off zone found on the quasi-static dip (no rise of {LETOFF_RISE_GF} gf beyond half the dip): the down-weight is measured to the key bed"
        ));
    }

    // Down-weight (to the let-off zone or the key bed) and, on a hammer action, the weight
    // through let-off to the key bed.
    let m = config.finger.mass_kg;
    let fs = rest.fs;
    let rise = config.finger.rise_s;
    let down_to = |goal: f64| {
        let rest = &rest;
        move |w: f64| -> Result<bool, String> {
            let p = ForcePlayer::new(dip, m, fs);
            Ok(matches!(
                under_weight(
                    rest.clone(),
                    p,
                    gf_to_n(w),
                    WEIGHT_RISE_S,
                    Goal::DownTo(goal)
                )?,
                Went::There
            ))
        }
    };
    // The key must come to rest there: at the let-off's onset (the zone's rising force
    // stops it), or at the bed.
    let rest_at = letoff_zone.and_then(|_| letoff_onset(lp)).unwrap_or(goal);
    // A sprung key's weights come from the quasi-static loop: a weight laid on swings it
    // past where the weight holds it (and friction holds it there, at the bed); the loop
    // reads the force that holds it at each travel.
    let spring = sprung(lp, 0.1 * dip, 0.9 * goal);
    let down = match &spring {
        Some(_) => lp
            .down
            .iter()
            .filter(|(x, _)| *x <= rest_at)
            .map(|&(_, f)| n_to_gf(f))
            .fold(None, |m: Option<f64>, f| Some(m.map_or(f, |m| m.max(f))))
            .filter(|&f| f > 0.0),
        None => threshold(
            loop_force(lp, &lp.down_bins, 0.0, goal, true),
            &mut down_to(rest_at),
        )?,
    };
    let goal_text = match letoff_zone {
        Some(z) => format!(
            "to the let-off zone ({:.2} mm; it comes to rest where the let-off's force begins to rise, {:.2} mm)",
            mm(z),
            mm(rest_at)
        ),
        None => format!("to the key bed ({:.2} mm)", mm(dip)),
    };
    match down {
        Some(w) => figures.push(Measured {
            figure: Figure::DownWeight,
            value: w,
            how: match &spring {
                Some(_) => format!(
                    "the largest force of the quasi-static dip ({speed_mm_s} mm/s, position-driven) going down from rest {goal_text}: a sprung key (see friction), which a weight laid on swings past where the weight holds it"
                ),
                None => format!(
                    "least constant weight, laid on over {:.0} ms, that moves the key from rest {goal_text} and holds it there within {WEIGHT_TIMEOUT_S} s (closed loop, {:.0} g key and finger; bisection to {WEIGHT_RESOLUTION_GF} gf)",
                    WEIGHT_RISE_S * 1e3,
                    m * 1e3
                ),
            },
        }),
        None => notes.push(format!(
            "down-weight: the key does not go {goal_text} under {MAX_WEIGHT_GF} gf, or sinks unloaded"
        )),
    }
    if letoff_zone.is_some() {
        if let Some(w) = threshold(
            loop_force(lp, &lp.down_bins, 0.0, dip, true),
            &mut down_to(dip),
        )? {
            figures.push(Measured {
                figure: Figure::LetoffWeight,
                value: w,
                how: format!(
                    "least constant weight that moves the key from rest through let-off to the key bed ({:.2} mm)",
                    mm(dip)
                ),
            });
        }
    }

    // Up-weight: the key held at the bottom after the quasi-static dip, a weight put on, the
    // key let go.
    let home = 0.01 * dip;
    let mut returns = |w: f64| -> Result<bool, String> {
        let mut p = ForcePlayer::new(dip, m, fs);
        p.x_m = dip;
        // `returns` is decreasing in the weight; bisect wants "goes" increasing.
        Ok(!matches!(
            under_weight(
                dipped.at_bottom.clone(),
                p,
                gf_to_n(w),
                0.0,
                Goal::BackTo(home)
            )?,
            Went::There
        ))
    };
    let up = match (down, &spring) {
        (None, _) => None,
        (Some(_), Some(_)) => lp
            .up
            .iter()
            .filter(|(x, _)| *x >= home)
            .map(|&(_, f)| n_to_gf(f))
            .fold(None, |m: Option<f64>, f| Some(m.map_or(f, |m| m.min(f))))
            .filter(|&f| f > 0.0),
        (Some(_), None) => threshold(loop_force(lp, &lp.up_bins, home, dip, false), &mut returns)?,
    };
    match up {
        Some(w) => figures.push(Measured {
            figure: Figure::UpWeight,
            value: w,
            how: match &spring {
                Some(_) => format!(
                    "the least force of the quasi-static dip ({speed_mm_s} mm/s) going up, from the bed to rest (≤ {:.2} mm): a sprung key (see friction)",
                    mm(home)
                ),
                None => format!(
                    "most constant weight under which the key, held at the bottom after a quasi-static dip ({speed_mm_s} mm/s, {BOTTOM_HOLD_S} s at the bottom), comes back to rest (≤ {:.2} mm) and stays there (within {WEIGHT_TIMEOUT_S} s)",
                    mm(home)
                ),
            },
        }),
        None => notes.push(
            "up-weight: the key held at the bottom does not return to rest even unloaded (or has no down-weight)"
                .to_string(),
        ),
    }
    match (down, up, spring) {
        (_, _, Some(spring)) => {
            // A sprung key: its weights are read at different travels, so their difference
            // is mostly the spring's; the loop reads both directions at the same travel.
            let why = format!(
                "the key's quasi-static force (the mean of down and up) changes by {:.1} gf from {:.2} to {:.2} mm (hysteresis {:.1} gf): a sprung key, whose down- and up-weight are read at different travels",
                spring.rise_gf,
                mm(0.1 * dip),
                mm(0.9 * goal),
                spring.gap_gf
            );
            figures.push(Measured {
                figure: Figure::Friction,
                value: 0.5 * spring.mid_gap_gf,
                how: format!(
                    "half the gap between the quasi-static force going down and going up ({speed_mm_s} mm/s) over {:.2}–{:.2} mm, the middle of the dip; {why}, so (down-weight − up-weight)/2 would read the spring",
                    mm(0.4 * dip),
                    mm(0.6 * dip)
                ),
            });
            figures.push(Measured {
                figure: Figure::BalanceWeight,
                value: spring.mid_mean_gf,
                how: format!(
                    "the mean of the quasi-static forces going down and up over {:.2}–{:.2} mm, the middle of the dip ({why})",
                    mm(0.4 * dip),
                    mm(0.6 * dip)
                ),
            });
        }
        (Some(d), Some(u), None) => {
            figures.push(Measured {
                figure: Figure::Friction,
                value: 0.5 * (d - u),
                how: "(down-weight − up-weight) / 2".to_string(),
            });
            figures.push(Measured {
                figure: Figure::BalanceWeight,
                value: 0.5 * (d + u),
                how: "(down-weight + up-weight) / 2".to_string(),
            });
        }
        _ => {}
    }
    figures.sort_by_key(|f| f.figure);

    // The loop's gaps.
    if let Some((gap, at)) = lp.least_gap(0.2 * dip, 0.7 * dip) {
        figures.push(Measured {
            figure: Figure::Hysteresis,
            value: n_to_gf(gap),
            how: format!(
                "least (force going down − force going up) of the quasi-static dip ({speed_mm_s} mm/s, position-driven), per {:.2} mm bin over {:.1}–{:.1} mm; least at {:.2} mm",
                mm(lp.bin_m),
                mm(0.2 * dip),
                mm(0.7 * dip),
                mm(at)
            ),
        });
    }
    // To the let-off zone, or short of the bottom's last 10 % (where the key's reversal,
    // seen through the differentiator's lag, mixes both directions).
    if let Some((gap, at)) = lp.least_gap(0.1 * dip, goal.min(0.9 * dip)) {
        figures.push(Measured {
            figure: Figure::HysteresisToLetoff,
            value: n_to_gf(gap),
            how: format!(
                "as above, from {:.1} mm to {:.2} mm ({}); least at {:.2} mm",
                mm(0.1 * dip),
                mm(goal.min(0.9 * dip)),
                if letoff_zone.is_some() {
                    "the let-off zone"
                } else {
                    "90 % of the dip"
                },
                mm(at)
            ),
        });
    }

    // Creep: the key brought to half its dip at the quasi-static speed, then held by the
    // balance weight alone (a sprung key's is the loop's force at mid-dip, see above).
    let balance = figures
        .iter()
        .find(|f| f.figure == Figure::BalanceWeight)
        .map(|f| f.value);
    if let Some(w) = balance {
        let mut key = rest.clone();
        let half = 0.5 * dip;
        let step = QUASI_STATIC_SPEED / fs;
        let n_move = (half / step).ceil() as usize;
        for i in 1..=n_move {
            key.at((i as f64 * step).min(half))?;
        }
        let mut p = ForcePlayer::new(dip, m, fs);
        p.x_m = half;
        let mut worst = 0.0f64;
        for _ in 0..(CREEP_S * fs) as usize {
            key.finger(&mut p, gf_to_n(w))?;
            worst = worst.max((p.x_m - half).abs());
        }
        figures.push(Measured {
            figure: Figure::Creep,
            value: mm(worst),
            how: format!(
                "largest travel from {:.2} mm of a key brought there at {speed_mm_s} mm/s and then held by the balance weight {w:.1} gf alone, over {CREEP_S} s",
                mm(half)
            ),
        });
    }

    // Geometry.
    figures.push(Measured {
        figure: Figure::KeyDip,
        value: mm(dip),
        how: format!(
            "range of the key sensor `{}`: rest to the key bed (the closed loop's bottom stop)",
            sensor.name
        ),
    });
    let ff = stroke(&rest, config, dip, config.ff_n, 0.6)?;
    let pp = stroke(&rest, config, dip, config.pp_n, 1.0)?;
    if hammer_action {
        let h0 = rest.hammer_m;
        let blow = ff
            .strike
            .map(|_| ff.hammer_strike_m - h0)
            .filter(|b| b.is_finite() && *b > 0.0);
        match blow {
            Some(blow) => figures.push(Measured {
                figure: Figure::BlowDistance,
                value: mm(blow),
                how: format!(
                    "hammer travel (`hammer_pos`) from rest to the string, read at the strike of the ff push ({} N)",
                    config.ff_n
                ),
            }),
            None => notes.push(format!(
                "blow distance, let-off, back-check: the ff push ({} N) did not strike",
                config.ff_n
            )),
        }
        if let (Some(blow), Some((peak, x_lo))) = (blow, dipped.hammer_peak) {
            figures.push(Measured {
                figure: Figure::LetOff,
                value: mm(blow - (peak - h0)),
                how: format!(
                    "blow distance − the highest hammer travel of the quasi-static dip ({speed_mm_s} mm/s), reached at {:.2} mm of key travel",
                    mm(x_lo)
                ),
            });
            figures.push(Measured {
                figure: Figure::Aftertouch,
                value: mm(dip - x_lo),
                how: format!(
                    "key dip − the key travel where the jack escapes on the quasi-static dip ({:.2} mm)",
                    mm(x_lo)
                ),
            });
            figures.push(Measured {
                figure: Figure::Drop,
                value: mm(peak - dipped.hammer_at_bottom),
                how: format!(
                    "highest hammer travel of the quasi-static dip − its travel over the last 100 ms of {BOTTOM_HOLD_S} s at the bottom"
                ),
            });
        }
        if let (Some(blow), Some(after)) = (blow, ff.hammer_after_m) {
            figures.push(Measured {
                figure: Figure::BackCheck,
                value: mm(blow - (after - h0)),
                how: format!(
                    "hammer distance from the string 250–300 ms after the ff strike, the key held down by the ff push ({} N)",
                    config.ff_n
                ),
            });
        }
    } else {
        notes.push(
            "let-off, drop, aftertouch, blow distance, back-check: no hammer (`hammer_pos` output and a `strike`/`pluck` event)"
                .to_string(),
        );
    }

    // Dynamics.
    for (s, push, bottom_fig, speed_fig, name) in [
        (
            &pp,
            config.pp_n,
            Figure::KeyBottomPp,
            Figure::StrikeSpeedPp,
            "pp",
        ),
        (
            &ff,
            config.ff_n,
            Figure::KeyBottomFf,
            Figure::StrikeSpeedFf,
            "ff",
        ),
    ] {
        match s.bottom_s {
            Some(t) => figures.push(Measured {
                figure: bottom_fig,
                value: t * 1e3,
                how: format!(
                    "from the start of a constant {push} N push (the force player's finger: {:.0} g, {:.0} ms rise) on the key at rest to the key bed",
                    m * 1e3,
                    rise * 1e3
                ),
            }),
            None => notes.push(format!(
                "key bottom, {name}: a constant {push} N push does not take the key to the key bed"
            )),
        }
        match s.strike {
            Some((_, v)) => figures.push(Measured {
                figure: speed_fig,
                value: v,
                how: format!("first argument of the strike event of the {name} push ({push} N)"),
            }),
            None if rest.strike.is_some() => notes.push(format!(
                "strike speed, {name}: a constant {push} N push does not strike"
            )),
            None => {}
        }
    }

    // Repetition.
    if rest.strike.is_some() {
        let push = config.repetition_n;
        let ok = |period: f64| repeats(&rest, config, dip, push, period);
        // From slow to fast while every note strikes, then bisection between.
        let mut slow = 0.5;
        let (first, _) = ok(slow)?;
        if first {
            let mut fast = slow;
            loop {
                let next = fast * 0.8;
                if next < 0.02 || !ok(next)?.0 {
                    slow = fast;
                    fast = next;
                    break;
                }
                fast = next;
            }
            while slow - fast > 0.001 {
                let mid = 0.5 * (slow + fast);
                if ok(mid)?.0 {
                    slow = mid;
                } else {
                    fast = mid;
                }
            }
            let (_, lowest) = ok(slow)?;
            let released = if lowest <= home {
                "back to rest between notes".to_string()
            } else {
                format!(
                    "half released: it rose to {:.2} mm at most between notes",
                    mm(lowest)
                )
            };
            figures.push(Measured {
                figure: Figure::Repetition,
                value: 1.0 / slow,
                how: format!(
                    "shortest period ({:.1} ms) at which 5 notes of a {push} N push (each pushed from the start of its period until its strike, then released) all strike; the key {released}",
                    slow * 1e3
                ),
            });
        } else {
            notes.push(format!(
                "repetition: 5 notes of a {push} N push at 2 notes/s do not all strike"
            ));
        }
    }

    // The dynamic sheet.
    let touches = if config.dynamic && rest.strike.is_some() {
        let letoff = if hammer_action {
            dipped.hammer_peak.map(|(_, x)| x)
        } else {
            None
        };
        let runs = dynamic::sweep(&rest, dip, letoff)?;
        let (f, n) = dynamic::figures(&runs, dip, hammer_action);
        figures.extend(f);
        notes.extend(n);
        runs
    } else {
        if config.dynamic {
            notes.push(
                "dynamic sheet: no strike (a `strike` or `pluck` event) to time a touch by"
                    .to_string(),
            );
        }
        Vec::new()
    };

    figures.sort_by_key(|f| f.figure);
    Ok(Sheet {
        instrument: program.name.clone(),
        figures,
        notes,
        force_loop: dipped.force_loop,
        touches,
    })
}
