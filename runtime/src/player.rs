//! The force-driven player: a finger pushes a key with a force profile, the instrument's
//! commanded force pushes back, and the key moves by Newton's law — the closed loop of
//! MIKEY's second validation experiment (key and finger mass, a finger force profile, the
//! commanded instrument force opposing, integrated at the sample rate) instead of a
//! prescribed key trajectory. The structure follows that experiment; the finger's mass and
//! force profiles below are our own choices, not the paper's numbers.
//!
//! **The law.** Key travel `x` (m, at the key front, 0 = rest, `dip` = key bottom) and its
//! speed `v` (m/s) obey
//!
//! ```text
//! m · dv/dt = f_finger(t) − f_instrument(x, history)
//! ```
//!
//! with `m` the mass of the key and the finger together referred to the key front (kg),
//! `f_finger` the finger's push (N, positive down) and `f_instrument` the force the
//! instrument commands (N, positive up: the grand piano's weight term `G` is positive, so a
//! key that nobody pushes rises back). One step per sample, semi-implicit (symplectic) Euler
//! at the sample rate: `v ← v + dt·(f_finger − f_instrument)/m`, then `x ← x + dt·v`.
//! The key stops are inelastic: travel is clamped to `[0, dip]` and the speed into a stop is
//! zeroed (the key bed and the rest rail are felt).
//!
//! The instrument sees only `x` (its sensor) and computes its force from it; the force of
//! sample `n` moves the key to its travel of sample `n + 1`, so the loop has the one-sample
//! delay of the real board (ADC read → force → DAC).
//!
//! **The finger.** A [`Stroke`] is one press: the force rises as a raised cosine over
//! [`FingerConfig::rise_s`] to its peak, stays there for the push (until the expected
//! strike), falls to a holding force [`FingerConfig::hold_n`] that keeps the key down until
//! the note-off, and is removed at the note-off (the finger lifts: force 0). A [`ForceProfile`]
//! is the strokes of one key in time order; a stroke that starts while the key is still
//! rising re-strikes from a half-released key.
//!
//! **Numbers.** MIKEY does not publish the finger's mass; [`FingerConfig::default`] uses
//! 30 g at the key front (a fingertip's effective mass is of the order of 10–20 g and the
//! key's own, beyond what an instrument simulates, about 10 g) — an assumption of ours, to be
//! set per experiment.

/// The finger and key as the player sees them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FingerConfig {
    /// Key and finger mass referred to the key front, kg.
    pub mass_kg: f64,
    /// Rise time of a stroke's force from 0 to its peak (raised cosine), s.
    pub rise_s: f64,
    /// Force that holds the key down between the push and the note-off, N.
    pub hold_n: f64,
}

impl Default for FingerConfig {
    /// 30 g, 5 ms rise, 1.2 N hold (above the grand piano's ≈ 0.5 N down-weight, so a held
    /// key stays down).
    fn default() -> Self {
        FingerConfig {
            mass_kg: 0.030,
            rise_s: 0.005,
            hold_n: 1.2,
        }
    }
}

/// One press of a finger on a key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stroke {
    /// When the finger starts pushing, s.
    pub start_s: f64,
    /// Peak force of the push, N.
    pub peak_n: f64,
    /// When the push ends and the holding force takes over, s (≥ `start_s`).
    pub push_end_s: f64,
    /// When the finger lifts (force 0), s (≥ `push_end_s`).
    pub lift_s: f64,
}

/// The finger force on one key over time: its strokes, in time order.
#[derive(Clone, Debug, PartialEq)]
pub struct ForceProfile {
    config: FingerConfig,
    strokes: Vec<Stroke>,
}

impl ForceProfile {
    /// A profile from strokes (sorted here by start time). A stroke's push and hold are cut
    /// short by the start of the next one.
    pub fn new(config: FingerConfig, mut strokes: Vec<Stroke>) -> Self {
        strokes.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
        ForceProfile { config, strokes }
    }

    /// The strokes, by start time.
    pub fn strokes(&self) -> &[Stroke] {
        &self.strokes
    }

    /// The finger's force at time `t` (s), N (positive pushes the key down).
    pub fn force(&self, t: f64) -> f64 {
        let i = self.strokes.partition_point(|s| s.start_s <= t);
        if i == 0 {
            return 0.0;
        }
        let s = &self.strokes[i - 1];
        let c = &self.config;
        if t >= s.lift_s {
            return 0.0;
        }
        let since = t - s.start_s;
        let push = if since < c.rise_s {
            let u = since / c.rise_s;
            s.peak_n * 0.5 * (1.0 - (std::f64::consts::PI * u).cos())
        } else {
            s.peak_n
        };
        if t < s.push_end_s {
            push
        } else {
            // The push relaxes to the holding force over one rise time.
            let u = ((t - s.push_end_s) / c.rise_s).min(1.0);
            push + (c.hold_n - push) * u
        }
    }
}

/// One key moved by a finger against the instrument's force (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct ForcePlayer {
    /// Key travel, m (0 = rest, `dip_m` = bottom).
    pub x_m: f64,
    /// Key speed, m/s (positive down).
    pub v_mps: f64,
    dip_m: f64,
    mass_kg: f64,
    dt_s: f64,
}

impl ForcePlayer {
    /// A key at rest with dip `dip_m` (m), mass `mass_kg` (kg, key + finger at the key
    /// front), stepped at `sample_rate_hz`.
    pub fn new(dip_m: f64, mass_kg: f64, sample_rate_hz: f64) -> Self {
        ForcePlayer {
            x_m: 0.0,
            v_mps: 0.0,
            dip_m,
            mass_kg,
            dt_s: 1.0 / sample_rate_hz,
        }
    }

    /// One sample: the finger pushes with `finger_n` (N, down), the instrument with
    /// `instrument_n` (N, up). Returns the new key travel, m (semi-implicit Euler, travel
    /// clamped to `[0, dip]`, speed into a stop zeroed).
    pub fn step(&mut self, finger_n: f64, instrument_n: f64) -> f64 {
        let f = finger_n - instrument_n;
        let a = if f.is_finite() { f / self.mass_kg } else { 0.0 };
        self.v_mps += self.dt_s * a;
        self.x_m += self.dt_s * self.v_mps;
        if self.x_m <= 0.0 {
            self.x_m = 0.0;
            self.v_mps = self.v_mps.max(0.0);
        } else if self.x_m >= self.dip_m {
            self.x_m = self.dip_m;
            self.v_mps = self.v_mps.min(0.0);
        }
        self.x_m
    }
}

/// Finger force and lead time for a wanted hammer speed, from measured single strokes.
///
/// Each level is one stroke of peak force `peak_n` on a key at rest, measured on the
/// instrument: `lead_s`, the time from the start of the push to the strike, and `speed_mps`,
/// the strike's hammer speed. [`Calibration::for_speed`] interpolates (log–log) between the
/// levels, so a player can aim at a hammer speed and start early enough to strike on time.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// (peak force N, lead s, hammer speed m/s), by increasing speed.
    levels: Vec<(f64, f64, f64)>,
}

impl Calibration {
    /// A calibration from measured levels (peak N, lead s, speed m/s). Levels that did not
    /// strike are left out by the caller; levels whose speed does not exceed every weaker
    /// level's are dropped, so the table is monotonic. `None` when fewer than two remain.
    pub fn new(mut levels: Vec<(f64, f64, f64)>) -> Option<Self> {
        levels.retain(|l| l.0 > 0.0 && l.1 >= 0.0 && l.2 > 0.0);
        levels.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut kept: Vec<(f64, f64, f64)> = Vec::new();
        for l in levels {
            if kept.last().is_none_or(|k| l.2 > k.2) {
                kept.push(l);
            }
        }
        (kept.len() >= 2).then_some(Calibration { levels: kept })
    }

    /// The levels kept: (peak force N, lead s, hammer speed m/s), by increasing speed.
    pub fn levels(&self) -> &[(f64, f64, f64)] {
        &self.levels
    }

    /// (peak force N, lead s) for a hammer speed (m/s); clamped to the measured range.
    pub fn for_speed(&self, speed_mps: f64) -> (f64, f64) {
        let l = &self.levels;
        let s = speed_mps.clamp(l[0].2, l[l.len() - 1].2);
        let i = l.partition_point(|k| k.2 < s).clamp(1, l.len() - 1);
        let (a, b) = (l[i - 1], l[i]);
        let u = (s.ln() - a.2.ln()) / (b.2.ln() - a.2.ln());
        let peak = (a.0.ln() + u * (b.0.ln() - a.0.ln())).exp();
        let lead = a.1 + u * (b.1 - a.1);
        (peak, lead)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FS: f64 = 44_100.0;

    /// A toy instrument: a 0.5 N weight and a 20 N/m return spring (the key pushes up).
    fn toy(x: f64) -> f64 {
        0.5 + 20.0 * x
    }

    /// Runs a key under `profile` against [`toy`] for `seconds`; returns travel per sample.
    fn run(profile: &ForceProfile, seconds: f64) -> Vec<f64> {
        let mut p = ForcePlayer::new(0.010, 0.030, FS);
        (0..(seconds * FS) as usize)
            .map(|i| {
                let t = i as f64 / FS;
                let x = p.x_m;
                p.step(profile.force(t), toy(x));
                x
            })
            .collect()
    }

    fn stroke(peak: f64) -> ForceProfile {
        ForceProfile::new(
            FingerConfig::default(),
            vec![Stroke {
                start_s: 0.01,
                peak_n: peak,
                push_end_s: 0.2,
                lift_s: 0.3,
            }],
        )
    }

    fn time_to_bottom(x: &[f64]) -> Option<f64> {
        x.iter().position(|&x| x >= 0.010).map(|i| i as f64 / FS)
    }

    #[test]
    fn a_stronger_push_bottoms_sooner_and_the_key_returns_when_released() {
        let weak = run(&stroke(1.0), 0.6);
        let strong = run(&stroke(4.0), 0.6);
        let (tw, ts) = (
            time_to_bottom(&weak).unwrap(),
            time_to_bottom(&strong).unwrap(),
        );
        assert!(ts < tw, "strong {ts} s, weak {tw} s");
        // Free fall under constant net force: t = sqrt(2·dip·m / F_net) gives the order.
        assert!(ts > 0.01 && ts < 0.01 + 0.02, "{ts}");
        // Held down while the hold force exceeds the instrument's force at the bottom …
        let at = |x: &[f64], t: f64| x[(t * FS) as usize];
        assert_eq!(at(&strong, 0.25), 0.010);
        // … and back at rest after the finger lifts at 0.3 s.
        assert_eq!(at(&strong, 0.59), 0.0);
        assert!(at(&strong, 0.31) > 0.0);
        // Never outside the stops.
        assert!(strong.iter().all(|&x| (0.0..=0.010).contains(&x)));
    }

    #[test]
    fn no_push_no_motion_and_a_push_below_the_weight_does_not_move_the_key() {
        assert!(run(&stroke(0.0), 0.1).iter().all(|&x| x == 0.0));
        let mut p = ForceProfile::new(FingerConfig::default(), vec![]);
        assert_eq!(p.force(1.0), 0.0);
        p = stroke(0.4); // below the 0.5 N weight
        p.config = FingerConfig {
            hold_n: 0.4,
            ..FingerConfig::default()
        };
        assert!(run(&p, 0.4).iter().all(|&x| x == 0.0));
    }

    #[test]
    fn a_restrike_starts_from_a_half_released_key() {
        let cfg = FingerConfig::default();
        let p = ForceProfile::new(
            cfg,
            vec![
                Stroke {
                    start_s: 0.0,
                    peak_n: 4.0,
                    push_end_s: 0.05,
                    lift_s: 0.1,
                },
                Stroke {
                    start_s: 0.115,
                    peak_n: 4.0,
                    push_end_s: 0.2,
                    lift_s: 0.3,
                },
            ],
        );
        let x = run(&p, 0.3);
        let lowest = x[(0.1 * FS) as usize..(0.2 * FS) as usize]
            .iter()
            .fold(f64::INFINITY, |a, &b| a.min(b));
        assert!(lowest > 0.0 && lowest < 0.010, "{lowest}");
        assert_eq!(x[(0.18 * FS) as usize], 0.010);
    }

    #[test]
    fn force_profile_shape() {
        let p = stroke(3.0);
        assert_eq!(p.force(0.0), 0.0);
        assert!((p.force(0.01 + 0.0025) - 1.5).abs() < 1e-9);
        assert_eq!(p.force(0.1), 3.0);
        assert!((p.force(0.25) - FingerConfig::default().hold_n).abs() < 1e-12);
        assert_eq!(p.force(0.3), 0.0);
    }

    #[test]
    fn calibration_interpolates_and_drops_non_monotonic_levels() {
        let c = Calibration::new(vec![
            (1.0, 0.10, 0.5),
            (4.0, 0.03, 4.0),
            (2.0, 0.05, 2.0),
            (3.0, 0.04, 1.5), // slower than the 2 N level: dropped
        ])
        .unwrap();
        assert_eq!(c.levels().len(), 3);
        let (f, lead) = c.for_speed(1.0);
        assert!(
            f > 1.0 && f < 2.0 && lead > 0.05 && lead < 0.10,
            "{f} {lead}"
        );
        assert_eq!(c.for_speed(100.0), (4.0, 0.03));
        assert_eq!(c.for_speed(0.0), (1.0, 0.10));
        assert!(Calibration::new(vec![(1.0, 0.1, 0.5)]).is_none());
    }
}
