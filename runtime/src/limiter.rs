//! The safety limiter: commanded force → DAC code, within the motor's limits.
//!
//! Every key's force word passes through it before it reaches the DAC, in the firmware and
//! in every simulation, so no instrument file — however wrong — can overdrive a motor.
//!
//! Physics (MIKEY: voice-coil motor, torque constant ≈ 0.007 N·m/A, rated current 0.5 A,
//! peak 2 A allowed for less than 100 ms; 16-bit DAC driving a transconductance amplifier):
//! the motor acts on the key through a lever arm `r`, so a force `F` at the key front needs
//! the torque `F·r` and the current `I = F·r / k_t`; the amplifier turns DAC code `c` into
//! the current `c / 32767 · I_fs` (`I_fs`: the current at full scale).
//!
//! **Everything is defined on the 16-bit DAC code** — the quantity the hardware resolves —
//! so the firmware needs one `MULS` and no 64-bit arithmetic (the firmware image's Thumb
//! limiter, `firmware/src/image/glue.rs`, computes exactly these words):
//!
//! 1. **Scale** ([`DacScale`], per force format), in sign and magnitude:
//!    `x = min(|force| >> a, 32767)`, `c = sign(force) · ((x · g) >> b)` (`g < 2^16`, so
//!    the product fits 32 bits; the shifts truncate the magnitude, so the scale is
//!    symmetric about zero). `a` is the smallest shift whose 16-bit `x` still spans
//!    the peak force, so `x` keeps 15 bits over `±peak`; `g / 2^b` is the gain in DAC codes
//!    per unit of `x`, with `b` as large as `g < 2^16` allows. A force too large for 16 bits
//!    after the shift is *above the peak* whatever its exact value.
//! 2. **Peak**: `|c|` is clamped to the peak code (`peak_a / I_fs · 32767`).
//! 3. **Time budget**: a code above the rated code (`rated_a / I_fs · 32767`) spends
//!    `recovery` units of budget; at or below rated it earns one back (up to the full
//!    budget, `⌊t_over · fs⌋ · recovery`); with the budget spent, `|c|` is clamped to the rated
//!    code (and, being then at rated, earns). Hence no stretch above rated is longer than
//!    `t_over`, and over any window of `W` samples at most `t_over·fs + W/recovery` samples
//!    are above rated.
//!
//! Error of the scale against the exact `F · codes/N`: the shift `a` truncates, dropping less
//! than one `x` unit — under two DAC codes, since the smallest `a` leaves `x` at least half
//! its 16-bit span over ±peak (under one code for formats that need no shift); `g`'s rounding
//! is below `2^-15` relative; the final shift truncates (under one code): under three codes
//! in all (0.18 mN at the key with MIKEY's motor), tested for formats Q23.8 to Q3.28.
//!
//! The DAC code is a [`DacCode`] (the `fixed` crate's `I1F15`: a fraction of full scale in
//! `[-1, 1)`), whose bits are the word the DAC receives.

/// A DAC word: the fraction of the full-scale current, in `[-1, 1)` with 15 fraction bits
/// (`to_bits()` is the 16-bit code; the limiter writes codes within ±32767).
pub type DacCode = ::fixed::types::I1F15;
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

impl LimiterConfig {
    /// The limiter of every key of a keyboard on `board`: MIKEY's motor ([`Default`]) at the
    /// board's sample rate. The one configuration `tactus build`, `budget` and `play` give
    /// the firmware (its budget of samples above rated, `⌊t_over · fs⌋ · recovery`, counts
    /// the board's samples).
    pub fn for_board(board: &crate::keyboard::BoardSpec) -> LimiterConfig {
        LimiterConfig {
            sample_rate_hz: board.sample_rate_hz,
            ..LimiterConfig::default()
        }
    }
}

/// The force → DAC code scale for force words with a given number of fraction bits
/// ([`LimiterConstants::dac_scale`]): `c = (sat16(force >> pre_shift) · gain) >> post_shift`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DacScale {
    /// `a`: arithmetic right shift of the force word (0-31).
    pub pre_shift: u32,
    /// `g`: DAC codes per unit of the shifted force, times `2^post_shift` (1 to 65535).
    pub gain: u32,
    /// `b`: arithmetic right shift of the product (0-31), flooring.
    pub post_shift: u32,
}

impl DacScale {
    /// The unclamped DAC code of a force word, and whether its shifted magnitude had to be
    /// saturated to 15 bits (a force beyond the 16-bit span: above the peak). Sign and
    /// magnitude: `c = sign(F) · ((min(|F| >> a, 32767) · g) >> b)`, so the code is
    /// symmetric about zero (`|F|` of `i32::MIN` is 2^31).
    pub fn code(&self, force: i32) -> (i32, bool) {
        let mag = force.unsigned_abs() >> self.pre_shift;
        let sat = mag > 32767;
        let c = (mag.min(32767) * self.gain) >> self.post_shift;
        let c = c as i32;
        (if force < 0 { -c } else { c }, sat)
    }

    /// The largest shifted magnitude `x` in `[0, 32767]` whose code `(x · g) >> b` is at
    /// most `code` (≥ 0): since the code grows with `x`, `|F| >> a` above it means a code
    /// above `code` or a saturated force. The firmware's limiter compares magnitudes with
    /// these thresholds (of the rated and the peak code) before it multiplies, so it
    /// multiplies only magnitudes it keeps.
    pub fn last_magnitude_within(&self, code: i32) -> u32 {
        let limit = ((i64::from(code.max(0)) + 1) << self.post_shift) - 1;
        (limit / i64::from(self.gain.max(1))).min(32767) as u32
    }
}

/// The limiter of one key: its integer constants and its state (the time budget).
#[derive(Clone, Debug, PartialEq)]
pub struct Limiter {
    consts: LimiterConstants,
    /// The last scale used, by force format (the firmware has one per format).
    scale: Option<(i32, DacScale)>,
    /// Remaining budget in 1/`recovery` samples.
    budget: i32,
}

/// The integer constants of a [`Limiter`] ([`Limiter::constants`]); [`Limiter::step`] is
/// defined in terms of these alone (and the budget).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LimiterConstants {
    /// DAC codes per newton at the key front (`r / k_t · 32767 / I_fs`), exact.
    pub codes_per_newton: f64,
    /// The peak force at the key front, N (`peak_a · k_t / r`).
    pub peak_force_n: f64,
    /// Peak current as a DAC code (`peak_a / I_fs · 32767`, rounded, at most 32767).
    pub peak_code: i32,
    /// Rated current as a DAC code (rounded, at most `peak_code`).
    pub rated_code: i32,
    /// Full time budget, in 1/`recovery` samples.
    pub budget_max: i32,
    /// Budget spent per sample above rated (one sample = `recovery` units).
    pub recovery: i32,
    /// Current at DAC full scale (code 32767), µA.
    pub full_scale_ua: i64,
}

impl LimiterConstants {
    /// The scale for force words with `frac` fraction bits (see the module documentation).
    ///
    /// Errors: the force format cannot span the peak force in 16 bits even unshifted, or
    /// its gain rounds to zero (a message naming the format).
    pub fn dac_scale(&self, frac: i32) -> Result<DacScale, String> {
        // Smallest a with 32767 · 2^(a − frac) ≥ peak force.
        let mut a = 0u32;
        while 32767.0 * 2f64.powi(a as i32 - frac) < self.peak_force_n {
            a += 1;
            if a > 31 {
                return Err(format!(
                    "limiter: force words with {frac} fraction bits cannot span the peak force {} N",
                    self.peak_force_n
                ));
            }
        }
        if 32767.0 * 2f64.powi(-frac) < self.peak_force_n && a == 0 {
            return Err(format!(
                "limiter: force words with {frac} fraction bits cannot span the peak force"
            ));
        }
        let per_x = self.codes_per_newton * 2f64.powi(a as i32 - frac);
        let mut b = 31u32;
        loop {
            let g = (per_x * 2f64.powi(b as i32)).round();
            if g <= 65535.0 {
                if g < 1.0 {
                    return Err(format!(
                        "limiter: force words with {frac} fraction bits: a gain of {per_x:e} codes per step rounds to 0"
                    ));
                }
                return Ok(DacScale {
                    pre_shift: a,
                    gain: g as u32,
                    post_shift: b,
                });
            }
            if b == 0 {
                return Err(format!(
                    "limiter: force words with {frac} fraction bits: gain {per_x:e} codes per step is above 65535"
                ));
            }
            b -= 1;
        }
    }

    /// The motor current of DAC code `code`, µA (rounded toward zero).
    pub fn current_ua(&self, code: i32) -> i32 {
        (i64::from(code) * self.full_scale_ua / 32767) as i32
    }
}

/// One sample's result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limited {
    /// Current sent to the motor, µA ([`LimiterConstants::current_ua`] of the code).
    pub current_ua: i32,
    /// The DAC code (bits of the [`DacCode`]), within ±32767.
    pub dac: i16,
    /// Whether a limit changed the code this sample.
    pub limited: bool,
}

impl Limited {
    /// The DAC word as a fraction of full scale.
    pub fn dac_code(&self) -> DacCode {
        DacCode::from_bits(self.dac)
    }
}

impl Limiter {
    /// Integer constants for `c`. Errors name the field that is not finite and positive, or
    /// say which limits are inconsistent.
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
        if c.rated_a > c.peak_a || c.peak_a > 2000.0 || c.dac_full_scale_a > 2000.0 {
            return Err(format!(
                "limiter: need rated_a ≤ peak_a ≤ 2000 A and dac_full_scale_a ≤ 2000 A, got {}, {} and {}",
                c.rated_a, c.peak_a, c.dac_full_scale_a
            ));
        }
        if c.sample_rate_hz > 1e7 || c.over_time_s > 3600.0 {
            return Err(format!(
                "limiter: need sample_rate_hz ≤ 10 MHz and over_time_s ≤ 3600 s, got {} and {}",
                c.sample_rate_hz, c.over_time_s
            ));
        }
        let recovery = c.recovery.clamp(1, 255) as i32;
        if c.recovery != recovery as u32 {
            return Err(format!(
                "limiter: `recovery` must be 1 to 255, got {}",
                c.recovery
            ));
        }
        let code =
            |amps: f64| ((amps / c.dac_full_scale_a * 32767.0).round() as i64).min(32767) as i32;
        let peak_code = code(c.peak_a);
        let rated_code = code(c.rated_a).min(peak_code);
        if rated_code < 1 {
            return Err(format!(
                "limiter: the rated current {} A is below one DAC code of {} A full scale",
                c.rated_a, c.dac_full_scale_a
            ));
        }
        let samples = (c.over_time_s * c.sample_rate_hz).floor() as i64;
        let budget_max = samples * recovery as i64;
        if samples < 1 || budget_max > i64::from(i32::MAX) {
            return Err(format!(
                "limiter: over_time_s · sample_rate_hz must be 1 to {} samples, got {samples}",
                i32::MAX / recovery
            ));
        }
        let consts = LimiterConstants {
            codes_per_newton: c.lever_arm_m / c.torque_constant_nm_per_a * 32767.0
                / c.dac_full_scale_a,
            peak_force_n: c.peak_a * c.torque_constant_nm_per_a / c.lever_arm_m,
            peak_code,
            rated_code,
            budget_max: budget_max as i32,
            recovery,
            full_scale_ua: (c.dac_full_scale_a * 1e6).round() as i64,
        };
        Ok(Limiter {
            consts,
            scale: None,
            budget: budget_max as i32,
        })
    }

    /// Limits one commanded force (a raw word with `frac` fraction bits, newtons).
    ///
    /// A force format the scale cannot serve ([`LimiterConstants::dac_scale`]'s errors)
    /// gives code 0, marked limited: no current rather than a wrong one.
    pub fn step(&mut self, force: i32, frac: i32) -> Limited {
        let scale = match self.scale {
            Some((f, s)) if f == frac => Ok(s),
            _ => self.consts.dac_scale(frac),
        };
        let Ok(scale) = scale else {
            return Limited {
                current_ua: 0,
                dac: 0,
                limited: true,
            };
        };
        self.scale = Some((frac, scale));
        let c = &self.consts;
        let (asked, saturated) = scale.code(force);
        let mut code = asked;
        let sign = |m: i32| if force < 0 { -m } else { m };
        if saturated || asked.abs() > c.rated_code {
            if self.budget >= c.recovery {
                self.budget -= c.recovery;
                if saturated || asked.abs() > c.peak_code {
                    code = sign(c.peak_code);
                }
            } else {
                code = sign(c.rated_code);
                self.budget += 1;
            }
        } else {
            self.budget = (self.budget + 1).min(c.budget_max);
        }
        Limited {
            current_ua: c.current_ua(code),
            dac: code as i16,
            limited: saturated || code != asked,
        }
    }

    /// The integer constants of this limiter, for firmware that computes the same words
    /// (the firmware image's Thumb limiter is generated from them).
    pub fn constants(&self) -> LimiterConstants {
        self.consts
    }

    /// The remaining time budget, in 1/`recovery` samples (full after [`Limiter::new`]).
    pub fn budget(&self) -> i64 {
        i64::from(self.budget)
    }

    /// The rated current as a DAC code.
    pub fn rated_code(&self) -> i32 {
        self.consts.rated_code
    }
    /// The peak current as a DAC code.
    pub fn peak_code(&self) -> i32 {
        self.consts.peak_code
    }
    /// The rated current, µA (of the rated code).
    pub fn rated_ua(&self) -> i32 {
        self.consts.current_ua(self.consts.rated_code)
    }
    /// The peak current, µA (of the peak code).
    pub fn peak_ua(&self) -> i32 {
        self.consts.current_ua(self.consts.peak_code)
    }
    /// The longest stretch above rated, in samples.
    pub fn over_samples(&self) -> i64 {
        i64::from(self.consts.budget_max / self.consts.recovery)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixed;
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
            let code = i32::from(out.dac).abs();
            assert!(code <= lim.peak_code(), "{out:?}");
            assert!(out.current_ua.abs() <= lim.peak_ua(), "{out:?}");
            if code > lim.rated_code() {
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
        // 0.5 N at the key: 0.5 · 7 mm / 0.007 N·m/A = 0.5 A → DAC 0.5/2 · 32767 = 8191.75.
        let out = lim.step(word(0.5), F);
        assert!((f64::from(out.dac) - 8191.75).abs() <= 2.0, "{out:?}");
        assert!((out.current_ua - 500_000).abs() <= 2 * 62, "{out:?}");
        assert!(!out.limited);
        assert!((out.dac_code().to_num::<f64>() - 0.25).abs() < 1e-4);
        let out = lim.step(word(-1.0), F);
        assert!((out.current_ua + 1_000_000).abs() <= 2 * 62 && out.dac < 0);
    }

    /// The scale is within three DAC codes of the exact `F · codes/N` over the whole ±peak
    /// range, for every force format from coarse to fine, and beyond the peak it saturates.
    /// The exact value is computed independently with the `fixed` crate (the force word
    /// as `I8F24`, and the product in `I32F32`).
    #[test]
    fn the_scale_is_within_three_codes_for_every_format() {
        let lim = Limiter::new(&LimiterConfig::default()).unwrap();
        let c = lim.constants();
        let mut rng = XorShift64::new(11);
        for frac in [8, 12, 16, 20, 24, 26, 28] {
            let s = c.dac_scale(frac).unwrap();
            assert!(s.gain >= 32768 || s.post_shift == 0, "{frac}: {s:?}");
            for _ in 0..20_000 {
                let n = (rng.unit() * 2.0 - 1.0) * c.peak_force_n;
                let w = fixed::from_f64(n, frac).0;
                let exact = f64::from(w) * 2f64.powi(-frac) * c.codes_per_newton;
                let (code, sat) = s.code(w);
                assert!(!sat, "{frac}: {n} N saturated");
                assert!(
                    (f64::from(code) - exact).abs() < 3.0,
                    "{frac}: {n} N → {code}, exact {exact}"
                );
            }
            let (hi, sat) = s.code(i32::MAX);
            assert!(sat && hi >= c.peak_code, "{frac}: {hi}");
            let (lo, sat) = s.code(i32::MIN);
            assert!(sat && lo <= -c.peak_code, "{frac}: {lo}");
        }
        // The `fixed` crate's own Q-format arithmetic agrees on Q7.24 words.
        use ::fixed::types::{I32F32, I8F24};
        let s = c.dac_scale(24).unwrap();
        for _ in 0..20_000 {
            let w = fixed::from_f64((rng.unit() * 2.0 - 1.0) * 1.9, 24).0;
            let f = I8F24::from_bits(w);
            let exact = I32F32::from_num(f) * I32F32::from_num(c.codes_per_newton);
            let got = I32F32::from_num(s.code(w).0);
            assert!((got - exact).abs() < 3, "{w}: {got} against {exact}");
        }
    }

    /// The magnitude thresholds against the scale itself, over every 15-bit magnitude.
    #[test]
    fn magnitude_thresholds_split_the_codes() {
        let lim = Limiter::new(&LimiterConfig::default()).unwrap();
        let c = lim.constants();
        for frac in [8, 16, 24, 28] {
            let s = c.dac_scale(frac).unwrap();
            for code in [1, c.rated_code, c.peak_code, 32767] {
                let m = s.last_magnitude_within(code);
                let at = |x: u32| ((x * s.gain) >> s.post_shift) as i32;
                assert!(at(m) <= code, "{frac}: {code}");
                assert!(m == 32767 || at(m + 1) > code, "{frac}: {code}");
                assert!((0..=32767).all(|x| (at(x) <= code) == (x <= m)));
            }
        }
        let tiny = DacScale {
            pre_shift: 0,
            gain: 65535,
            post_shift: 0,
        };
        assert_eq!(tiny.last_magnitude_within(0), 0);
        assert_eq!(tiny.last_magnitude_within(65535), 1);
    }

    #[test]
    fn recovery_and_budget_are_checked() {
        let c = LimiterConfig {
            recovery: 300,
            ..LimiterConfig::default()
        };
        assert!(Limiter::new(&c).unwrap_err().contains("recovery"));
        let c = LimiterConfig {
            over_time_s: 1e-9,
            ..LimiterConfig::default()
        };
        assert!(Limiter::new(&c).unwrap_err().contains("over_time_s"));
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
