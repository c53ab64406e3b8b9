//! The safety limiter: commanded force → motor current → DAC code, within the motor's limits.
//!
//! Every key's force word passes through it before it reaches the DAC, in the firmware and
//! in every simulation, so no instrument file — however wrong — can overdrive a motor.
//!
//! Physics (MIKEY: voice-coil motor, torque constant ≈ 0.007 N·m/A, rated current 0.5 A,
//! peak 2 A allowed for less than 100 ms; 16-bit DAC driving a transconductance amplifier):
//! the motor acts on the key through a lever arm `r`, so a force `F` at the key front needs
//! the torque `F·r` and the current `I = F·r / k_t`.
//!
//! Limits, in this order, every sample:
//! 1. `|I|` is clamped to the peak current;
//! 2. a **time budget** allows currents above the rated current for at most `t_over`
//!    (100 ms) in a row: each sample above rated spends one sample of budget; each sample
//!    at or below rated earns back `1/recovery` of a sample; with the budget spent the
//!    current is clamped to the rated current until enough is earned back. Hence no stretch
//!    above rated is longer than `t_over`, and over any window of `W` samples at most
//!    `t_over·fs + W/recovery` samples are above rated.
//!
//! Arithmetic is integer (currents in microamperes, the budget in 1/`recovery` samples), so
//! the firmware computes the same words; the force→current gain uses
//! [`crate::fixed::mul`] with its rounding.

use crate::fixed;

/// Actuator and limits of one key's motor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LimiterConfig {
    /// Motor torque constant, N·m/A (MIKEY: ≈ 0.007).
    pub torque_constant_nm_per_a: f64,
    /// Lever arm from the motor's axis to the key front, m.
    pub lever_arm_m: f64,
    /// Peak current, A (MIKEY: 2 A).
    pub peak_a: f64,
    /// Rated (continuous) current, A (MIKEY: 0.5 A).
    pub rated_a: f64,
    /// Longest stretch above the rated current, s (MIKEY: < 100 ms).
    pub over_time_s: f64,
    /// Samples at or below rated needed to earn back one sample above it.
    pub recovery: u32,
    /// Current at DAC full scale (code ±32767), A.
    pub dac_full_scale_a: f64,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
}

impl Default for LimiterConfig {
    /// MIKEY's motor; a 7 mm lever arm (so that the 2 A peak gives 2 N at the key front);
    /// the DAC's full scale at the peak current; recovery 4:1.
    fn default() -> Self {
        LimiterConfig {
            torque_constant_nm_per_a: 0.007,
            lever_arm_m: 0.007,
            peak_a: 2.0,
            rated_a: 0.5,
            over_time_s: 0.1,
            recovery: 4,
            dac_full_scale_a: 2.0,
            sample_rate_hz: crate::DEFAULT_SAMPLE_RATE_HZ,
        }
    }
}

/// The limiter of one key: its integer constants and its state (the time budget).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Limiter {
    gain: (i32, i32),
    peak_ua: i32,
    rated_ua: i32,
    budget_max: i64,
    recovery: i64,
    dac_scale: (i32, i32),
    /// Remaining budget in 1/`recovery` samples.
    budget: i64,
}

/// The integer constants of a [`Limiter`] ([`Limiter::constants`]); [`Limiter::step`] is
/// defined in terms of these alone (and the budget).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LimiterConstants {
    /// Force → current gain: (raw word, fraction bits), µA per N.
    pub gain: (i32, i32),
    /// Peak current, µA.
    pub peak_ua: i32,
    /// Rated current, µA.
    pub rated_ua: i32,
    /// Full time budget, in 1/`recovery` samples.
    pub budget_max: i64,
    /// Budget spent per sample above rated (one sample = `recovery` units).
    pub recovery: i64,
    /// Current → DAC code scale: (raw word, fraction bits), codes per µA.
    pub dac_scale: (i32, i32),
}

/// One sample's result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limited {
    /// Current sent to the motor, µA (after both limits).
    pub current_ua: i32,
    /// The DAC code for it.
    pub dac: i16,
    /// Whether a limit changed the current this sample.
    pub limited: bool,
}

impl Limiter {
    /// Integer constants for `c`. Errors name the field that is not finite and positive.
    pub fn new(c: &LimiterConfig) -> Result<Self, String> {
        for (name, v) in [
            ("torque_constant_nm_per_a", c.torque_constant_nm_per_a),
            ("lever_arm_m", c.lever_arm_m),
            ("peak_a", c.peak_a),
            ("rated_a", c.rated_a),
            ("over_time_s", c.over_time_s),
            ("dac_full_scale_a", c.dac_full_scale_a),
            ("sample_rate_hz", c.sample_rate_hz),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("limiter: `{name}` must be finite and > 0, got {v}"));
            }
        }
        if c.rated_a > c.peak_a || c.peak_a > 2000.0 {
            return Err(format!(
                "limiter: need rated_a ≤ peak_a ≤ 2000 A, got {} and {}",
                c.rated_a, c.peak_a
            ));
        }
        let recovery = c.recovery.max(1) as i64;
        let gain_ua_per_n = c.lever_arm_m / c.torque_constant_nm_per_a * 1e6;
        let fg = fixed::frac_for(gain_ua_per_n);
        let gain = (fixed::from_f64(gain_ua_per_n, fg).0, fg);
        let dac_per_ua = 32767.0 / (c.dac_full_scale_a * 1e6);
        let fd = fixed::frac_for(dac_per_ua);
        let budget_max = (c.over_time_s * c.sample_rate_hz).floor() as i64 * recovery;
        Ok(Limiter {
            gain,
            peak_ua: (c.peak_a * 1e6).round() as i32,
            rated_ua: (c.rated_a * 1e6).round() as i32,
            budget_max,
            recovery,
            dac_scale: (fixed::from_f64(dac_per_ua, fd).0, fd),
            budget: budget_max,
        })
    }

    /// Limits one commanded force (a raw word with `frac` fraction bits, newtons).
    pub fn step(&mut self, force: i32, frac: i32) -> Limited {
        let (asked, _) = fixed::mul(force, frac, self.gain.0, self.gain.1, 0);
        let mut i = asked.clamp(-self.peak_ua, self.peak_ua);
        if i.unsigned_abs() > self.rated_ua as u32 {
            if self.budget >= self.recovery {
                self.budget -= self.recovery;
            } else {
                i = i.clamp(-self.rated_ua, self.rated_ua);
            }
        }
        if i.unsigned_abs() <= self.rated_ua as u32 {
            self.budget = (self.budget + 1).min(self.budget_max);
        }
        let (code, _) = fixed::mul(i, 0, self.dac_scale.0, self.dac_scale.1, 0);
        Limited {
            current_ua: i,
            dac: code.clamp(-32767, 32767) as i16,
            limited: i != asked,
        }
    }

    /// The integer constants of this limiter, for firmware that computes the same words
    /// (the firmware image's Thumb limiter is generated from them).
    pub fn constants(&self) -> LimiterConstants {
        LimiterConstants {
            gain: self.gain,
            peak_ua: self.peak_ua,
            rated_ua: self.rated_ua,
            budget_max: self.budget_max,
            recovery: self.recovery,
            dac_scale: self.dac_scale,
        }
    }

    /// The remaining time budget, in 1/`recovery` samples (full after [`Limiter::new`]).
    pub fn budget(&self) -> i64 {
        self.budget
    }

    /// The rated current, µA.
    pub fn rated_ua(&self) -> i32 {
        self.rated_ua
    }
    /// The peak current, µA.
    pub fn peak_ua(&self) -> i32 {
        self.peak_ua
    }
    /// The longest stretch above rated, in samples.
    pub fn over_samples(&self) -> i64 {
        self.budget_max / self.recovery
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::XorShift64;

    const F: i32 = 24; // force words in Q7.24 (±128 N)

    fn word(newtons: f64) -> i32 {
        fixed::from_f64(newtons, F).0
    }

    /// Drives the limiter and checks the invariants on every sample.
    fn check(lim: &mut Limiter, forces: impl Iterator<Item = i32>) -> (usize, usize) {
        let (mut run, mut longest, mut above) = (0usize, 0usize, 0usize);
        for f in forces {
            let out = lim.step(f, F);
            assert!(
                out.current_ua.unsigned_abs() <= lim.peak_ua() as u32,
                "{out:?}"
            );
            if out.current_ua.unsigned_abs() > lim.rated_ua() as u32 {
                run += 1;
                above += 1;
            } else {
                run = 0;
            }
            longest = longest.max(run);
            assert!(
                longest as i64 <= lim.over_samples(),
                "{longest} samples above rated"
            );
        }
        (longest, above)
    }

    #[test]
    fn stuck_at_full_scale_falls_back_to_rated_after_100_ms() {
        let mut lim = Limiter::new(&LimiterConfig::default()).unwrap();
        let (longest, _) = check(&mut lim, std::iter::repeat_n(i32::MAX, 44_100));
        assert_eq!(longest, 4410, "peak allowed for exactly 100 ms");
        let out = lim.step(i32::MAX, F);
        assert_eq!(out.current_ua, lim.rated_ua());
        assert!(out.limited);
    }

    #[test]
    fn noise_and_glitches_never_exceed_the_limits() {
        let mut lim = Limiter::new(&LimiterConfig::default()).unwrap();
        let mut rng = XorShift64::new(7);
        let forces = (0..200_000).map(|_| match rng.below(4) {
            0 => {
                if rng.below(2) == 0 {
                    i32::MAX
                } else {
                    i32::MIN
                }
            }
            1 => word((rng.unit() - 0.5) * 6.0),
            2 => word(0.3),
            _ => rng.next_u64() as i32,
        });
        let (longest, above) = check(&mut lim, forces);
        assert!(longest > 0 && above < 200_000 / 2, "{longest} {above}");
    }

    #[test]
    fn small_forces_pass_unchanged_and_map_to_dac_codes() {
        let mut lim = Limiter::new(&LimiterConfig::default()).unwrap();
        // 0.5 N at the key: 0.5 · 7 mm / 0.007 N·m/A = 0.5 A → DAC 0.5/2 · 32767.
        let out = lim.step(word(0.5), F);
        assert!((out.current_ua - 500_000).abs() <= 1, "{out:?}");
        assert!((out.dac as i32 - 8192).abs() <= 1, "{out:?}");
        assert!(!out.limited);
        let out = lim.step(word(-1.0), F);
        assert!((out.current_ua + 1_000_000).abs() <= 1 && out.dac < 0);
    }

    #[test]
    fn bad_config_is_an_error_naming_the_field() {
        let c = LimiterConfig {
            lever_arm_m: f64::NAN,
            ..LimiterConfig::default()
        };
        assert!(Limiter::new(&c).unwrap_err().contains("lever_arm_m"));
    }
}
