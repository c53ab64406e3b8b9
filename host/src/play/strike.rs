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

/// Strikes per note: how many notes one strike answers, and how many two or more (a key
/// that re-struck its string under one note: a bounce or a second blow) with the most
/// strikes any note got, from what [`answer`] set. Notes no strike answers are
/// [`silent`]'s.
pub fn per_note(strikes: &[Strike]) -> (usize, usize, usize) {
    let mut count: std::collections::HashMap<(u8, u64), usize> = Default::default();
    for n in strikes.iter().filter_map(|s| s.answers) {
        *count.entry((n.key, n.on_s.to_bits())).or_default() += 1;
    }
    let once = count.values().filter(|&&c| c == 1).count();
    let most = count.values().copied().max().unwrap_or(0);
    (once, count.len() - once, most)
}

/// MIDI velocity for a hammer-head speed at the strike (m/s): the Bösendorfer SE
/// reproducing piano's convention, `v = 52 + 25 · log2(speed / 1 m/s)`, rounded and clamped
/// to 1–127 (W. Goebl's doctoral thesis, 2003, and W. Goebl and R. Bresin, "Measurement and
/// reproduction accuracy of computer-controlled grand pianos", JASA 114(4), 2003, as Tactus
/// DESIGN.md quotes them: a device's convention, not a law). So MIDI 1 is 0.24 m/s, 52 is
/// 1 m/s, 127 is 8 m/s: the span of the hammer speeds grand actions give, from the softest
/// that reaches the string (≈ 0.2 m/s) to a struck *fff* (6.8–7.8 m/s; Goebl, Bresin and
/// Galembo, JASA 118(2), 2005), which the shipped piano's action reaches too (`tactus
/// regulate`'s dynamic sheet). Logarithmic, so each doubling of the speed is 25 steps. Its
/// inverse is [`speed_for_velocity`]; the force player aims at it, the strike outputs (MIDI
/// and CSV) write it.
pub fn midi_velocity(speed_mps: f64) -> u8 {
    let v = 52.0 + 25.0 * speed_mps.log2();
    if v.is_nan() {
        return 1;
    }
    v.round().clamp(1.0, 127.0) as u8
}

/// The hammer speed (m/s) that [`midi_velocity`] maps to MIDI velocity `v` (clamped to
/// 1–127): its inverse, `2^((v − 52)/25)` m/s.
pub fn speed_for_velocity(v: u8) -> f64 {
    2f64.powf((f64::from(v.clamp(1, 127)) - 52.0) / 25.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_note_counts_the_strikes_each_note_got() {
        let note = |key, on_s| Note {
            key,
            velocity: 64,
            on_s,
            off_s: on_s + 0.5,
        };
        let strike = |key, time_s, answers| Strike {
            key,
            time_s,
            speed_mps: 1.0,
            answers,
        };
        let (a, b) = (note(60, 1.0), note(62, 1.0));
        let strikes = [
            strike(60, 1.0, Some(a)),
            strike(60, 1.01, Some(a)),
            strike(60, 1.02, Some(a)),
            strike(62, 1.0, Some(b)),
            strike(64, 3.0, None),
        ];
        assert_eq!(per_note(&strikes), (1, 1, 3));
        assert_eq!(per_note(&[]), (0, 0, 0));
    }

    #[test]
    fn velocity_and_speed_maps_are_inverse() {
        for v in 1..=127u8 {
            assert_eq!(midi_velocity(speed_for_velocity(v)), v);
        }
        // Goebl's Bösendorfer convention: 1 m/s is 52, each doubling 25 more.
        assert_eq!(midi_velocity(1.0), 52);
        assert_eq!(midi_velocity(2.0), 77);
        assert_eq!(midi_velocity(0.5), 27);
        assert_eq!(midi_velocity(8.0), 127);
        assert!((speed_for_velocity(127) - 8.0).abs() < 1e-12);
        assert!((speed_for_velocity(1) - 2f64.powf(-51.0 / 25.0)).abs() < 1e-12);
        assert_eq!(midi_velocity(0.1), 1);
        assert_eq!(midi_velocity(100.0), 127);
        assert_eq!(midi_velocity(0.0), 1);
        assert_eq!(midi_velocity(f64::NAN), 1);
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
