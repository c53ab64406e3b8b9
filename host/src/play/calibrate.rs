//! The force player's calibration of an instrument ([`calibrate`]): single strokes at
//! [`CALIBRATION_LEVELS_N`] through the one play loop ([`run_keys`]) on fresh instances,
//! from rest and as re-strikes, each giving the lead from the push to the strike and the
//! hammer's speed — what [`super::motion`] turns a note's MIDI velocity into a finger
//! force and a start time with ([`FingerCalibration`]). Apart from the motions because it
//! runs the loop that moves keys by them.

use super::engine::KeyEngine;
use super::error::RunError;
use super::motion::{FingerCalibration, Motion, Restrike};
use super::run::{run_keys, Drive, LoopConfig, TraceWindow};
use super::strike::speed_for_velocity;
use tactus_runtime::player::{Calibration, FingerConfig, ForceProfile, Stroke};

/// Peak finger forces of the calibration strokes, N (log-spaced from a push barely above a
/// piano key's down-weight to the hardest *fff* blow, the 50 N peak key force a haptic
/// grand key was sized for: Timmermans et al. 2020, Tactus DESIGN.md), so that the strikes
/// span the hammer speeds of MIDI 1–127 ([`speed_for_velocity`]: 0.24–8 m/s) as far as the
/// action gives them.
pub const CALIBRATION_LEVELS_N: [f64; 17] = [
    0.6, 0.75, 0.9, 1.1, 1.4, 1.8, 2.3, 3.0, 4.0, 5.5, 7.5, 10.0, 14.0, 20.0, 28.0, 38.0, 50.0,
];

/// How long a calibration stroke is simulated, s.
const CALIBRATION_S: f64 = 0.6;

/// How long the finger lets the key rise before a re-strike, s, the shortest first: the
/// finger lifts this long before the re-striking push starts. The calibration keeps each
/// rise down to the shortest that re-strikes at as many levels as the longest
/// ([`FingerCalibration::restrikes`]); a note takes the longest that fits before it.
/// A grand-piano key released at the bottom rises through the let-off zone, above the point
/// where the jack re-arms under the knuckle of the hammer the repetition lever holds up (the
/// escapement's `theta1`, ≈ 7.7 mm): the double escapement's purpose. How fast depends on
/// the hammer: the key rises no faster than the hammer on the lever falls back with it (the
/// key and wippen alone are nearly balanced by the leads, and friction holds them), so
/// 40 ms suffice for some keys and states, not all. The longer rises (100 and 140 ms) serve
/// soft repeated bass notes 0.15–0.3 s apart: after 70 ms their hammer was still high, and
/// a soft push threw it at the string 50–60 ms before its note-on at 0.1–0.4 m/s
/// (Maestro_2's A2 and F2 at 92–102 s: 18 of 44 notes; with them, none).
pub const RESTRIKE_RISES_S: [f64; 5] = [0.040, 0.055, 0.070, 0.100, 0.140];

/// The first stroke of a re-strike calibration is a *mezzo-forte* note (MIDI velocity
/// [`RESTRIKE_FIRST_VELOCITY`]) played from rest, lifted this long after its strike, s: the
/// state a performance's repeated note leaves. Repetitions 170–250 ms apart (the force
/// player's tests) lift the previous finger a calibrated rise ([`FingerCalibration::restrikes`]) before a push
/// that starts a re-strike's lead (≈ 40–60 ms) before the note-on: 70–150 ms after the
/// previous strike.
/// Then a *mf* hammer has fallen back onto the repetition lever or the back-check, not
/// always checked; a stroke held much longer (the calibration's first stroke was held 0.25 s
/// at 3 N) leaves it checked, the lever's spring compressed, and the key rises faster from
/// there than in the performance.
const RESTRIKE_FIRST_HOLD_S: f64 = 0.100;

/// How long the first stroke of a re-strike calibration is held after its strike, s: the
/// short hold of fast repetitions ([`RESTRIKE_FIRST_HOLD_S`]) and a long one, by which a
/// hammer has settled on its repetition lever (a note held 0.4 s, then repeated 0.2 s
/// after its note-off: Maestro_2's soft repeated A2), each a calibration of its own.
pub const RESTRIKE_HOLDS_S: [f64; 2] = [RESTRIKE_FIRST_HOLD_S, 0.400];

/// MIDI velocity of the re-strike calibration's first stroke (*mezzo-forte*).
const RESTRIKE_FIRST_VELOCITY: u8 = 64;

/// Measures strokes at [`CALIBRATION_LEVELS_N`] on fresh instances of one instrument
/// (`fresh()`: one key at rest; its dip `dip_m`): from rest (the push held until the strike
/// or 0.6 s), and re-strikes (a *mf* stroke from rest lifted each of [`RESTRIKE_HOLDS_S`]
/// after its strike, the finger lifted for each of [`RESTRIKE_RISES_S`], then the measured
/// push; every rise down to the shortest that re-strikes as many levels as the longest is
/// kept). Each
/// gives the lead from the start of the push to the strike and the strike's hammer speed.
/// `None` when fewer than two levels strike from rest.
///
/// Errors: the engine's (see [`run_keys`]).
pub fn calibrate<'e>(
    fresh: &dyn Fn() -> Box<dyn KeyEngine + 'e>,
    dip_m: f64,
    finger: FingerConfig,
    fs: f64,
) -> Result<Option<FingerCalibration>, RunError> {
    let measure = |first: Option<Stroke>, start: f64| -> Result<Vec<(f64, f64, f64)>, RunError> {
        let mut levels = Vec::new();
        for &peak in &CALIBRATION_LEVELS_N {
            let push = Stroke {
                start_s: start,
                peak_n: peak,
                push_end_s: 10.0,
                lift_s: 10.0,
            };
            let motion = Motion::Finger(ForceProfile::new(
                finger,
                first.into_iter().chain([push]).collect(),
            ));
            let drive = Drive {
                key: 0,
                motion: Some(&motion),
                dip_m,
            };
            let run = run_keys(
                &mut *fresh(),
                &[drive],
                0..((start + CALIBRATION_S) * fs) as usize,
                &LoopConfig {
                    clock: super::timeline::Timeline::at_zero(fs),
                    finger,
                    trace: &TraceWindow::default(),
                    stop_at_strike_after_s: Some(start),
                },
                &|_| {},
            )?;
            if let Some(s) = run.strikes.iter().find(|s| s.time_s >= start) {
                levels.push((peak, s.time_s - start, s.speed_mps));
            }
        }
        Ok(levels)
    };
    let Some(from_rest) = Calibration::new(measure(None, 0.01)?) else {
        return Ok(None);
    };
    // The first stroke as the force player plays a note: its push until 10 ms after the
    // strike, held, lifted RESTRIKE_FIRST_HOLD_S after the strike.
    let (peak, lead) = from_rest.for_speed(speed_for_velocity(RESTRIKE_FIRST_VELOCITY));
    let strike = 0.01 + lead;
    let mut restrikes = Vec::new();
    for hold_s in RESTRIKE_HOLDS_S {
        let first = Stroke {
            start_s: 0.01,
            peak_n: peak,
            push_end_s: strike + 0.010,
            lift_s: strike + hold_s,
        };
        // Every rise down to the shortest after which as many levels re-strike as after
        // the longest.
        let [shortest @ .., longest] = RESTRIKE_RISES_S;
        let levels = measure(Some(first), first.lift_s + longest)?;
        let most = levels.len();
        let mut family: Vec<Restrike> = Calibration::new(levels)
            .map(|cal| Restrike {
                hold_s,
                rise_s: longest,
                cal,
            })
            .into_iter()
            .collect();
        for &rise_s in shortest.iter().rev() {
            let sooner = measure(Some(first), first.lift_s + rise_s)?;
            if sooner.len() < most {
                break;
            }
            family.extend(Calibration::new(sooner).map(|cal| Restrike {
                hold_s,
                rise_s,
                cal,
            }));
        }
        family.reverse();
        restrikes.extend(family);
    }
    Ok(Some(FingerCalibration {
        from_rest,
        restrikes,
    }))
}
