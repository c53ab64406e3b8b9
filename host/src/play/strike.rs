//! The strike rule, once: which event of an instrument is its hammer strike (or pluck), which
//! input note a strike answers, and the map between hammer speed and MIDI velocity.
//!
//! Every engine's strikes pass through here, so the firmware on the emulated board and the
//! host engines can only differ in the bits they compute, never in how those bits become
//! strikes.

use tactus_compiler::ir::{EventId, Program};
use tactus_runtime::performance::Note;

/// A strike answers the note-on of its key nearest in time when it is at most this far from
/// it, s.
pub const ANSWER_WINDOW_S: f64 = 0.050;

/// The event of `program` that sounds a note: the first event named `strike` (a hammer
/// hits the string) or `pluck` (a plectrum plucks it); its first argument is the speed of
/// the hammer or plectrum, m/s. `None` when the program emits neither.
pub fn strike_event(program: &Program) -> Option<EventId> {
    program
        .events
        .iter()
        .position(|e| e.name == "strike" || e.name == "pluck")
        .map(|i| EventId(i as u32))
}

/// One simulated hammer strike (or pluck).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Strike {
    /// MIDI key.
    pub key: u8,
    /// Time of the sample that emitted it, s.
    pub time_s: f64,
    /// The event's first argument: hammer (or plectrum) speed, m/s.
    pub speed_mps: f64,
    /// The input note it answers ([`answer`]), if any.
    pub answers: Option<Note>,
}

/// Sorts `strikes` by time and sets what each answers: the note-on of its key nearest in
/// time, if within [`ANSWER_WINDOW_S`].
pub fn answer(strikes: &mut [Strike], notes: &[Note]) {
    strikes.sort_by(|a, b| a.time_s.total_cmp(&b.time_s).then(a.key.cmp(&b.key)));
    for s in strikes {
        s.answers = notes
            .iter()
            .filter(|n| n.key == s.key)
            .min_by(|a, b| {
                (a.on_s - s.time_s)
                    .abs()
                    .total_cmp(&(b.on_s - s.time_s).abs())
            })
            .filter(|n| (n.on_s - s.time_s).abs() <= ANSWER_WINDOW_S)
            .copied();
    }
}

/// The notes no strike answers (after [`answer`]): the instrument did not sound them.
pub fn silent(notes: &[Note], strikes: &[Strike]) -> Vec<Note> {
    notes
        .iter()
        .filter(|n| {
            !strikes.iter().any(|s| {
                s.answers
                    .is_some_and(|a| a.key == n.key && a.on_s == n.on_s)
            })
        })
        .copied()
        .collect()
}

/// MIDI velocity for a hammer-head speed at the strike (m/s):
/// `v = 1 + 126 · ln(speed / 0.1 m/s) / ln(60)`, rounded and clamped to 1–127, so
/// 0.1 m/s → 1 and 6 m/s → 127. The end points span grand-piano hammer speeds from the
/// softest audible blow to *fff*; the map is logarithmic because reproducing pianos record
/// velocities close to logarithmic in hammer speed (the same assumption as the key-motion
/// model of `tactus_runtime::performance`, which is what keeps input and output velocities
/// in the same order). Its inverse is [`speed_for_velocity`].
pub fn midi_velocity(speed_mps: f64) -> u8 {
    let v = 1.0 + 126.0 * (speed_mps / 0.1).ln() / (6.0f64 / 0.1).ln();
    v.round().clamp(1.0, 127.0) as u8
}

/// The hammer speed (m/s) that [`midi_velocity`] maps to MIDI velocity `v`: its inverse,
/// `0.1 m/s · 60^((v − 1)/126)`.
pub fn speed_for_velocity(v: u8) -> f64 {
    0.1 * 60f64.powf((f64::from(v.clamp(1, 127)) - 1.0) / 126.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn velocity_and_speed_maps_are_inverse() {
        for v in 1..=127u8 {
            assert_eq!(midi_velocity(speed_for_velocity(v)), v);
        }
        assert_eq!(midi_velocity(0.1), 1);
        assert_eq!(midi_velocity(6.0), 127);
        assert_eq!(midi_velocity(100.0), 127);
        assert_eq!(midi_velocity(0.0), 1);
    }

    #[test]
    fn a_strike_answers_the_nearest_note_on_of_its_key_within_the_window() {
        let note = |key, on_s| Note {
            key,
            velocity: 64,
            on_s,
            off_s: on_s + 0.1,
        };
        let notes = [note(60, 1.0), note(60, 1.08), note(62, 1.0)];
        let strike = |key, time_s| Strike {
            key,
            time_s,
            speed_mps: 1.0,
            answers: None,
        };
        let mut s = [strike(60, 1.05), strike(60, 1.01), strike(64, 1.0)];
        answer(&mut s, &notes);
        // Sorted by time (then key); 1.05 is nearer 1.08 than 1.0; key 64 has no note.
        assert_eq!(s[0].key, 64);
        assert_eq!(s[0].answers, None);
        assert_eq!(s[1].answers.map(|n| n.on_s), Some(1.0));
        assert_eq!(s[2].answers.map(|n| n.on_s), Some(1.08));
        let quiet = silent(&notes, &s);
        assert_eq!(quiet, vec![note(62, 1.0)]);
    }
}
