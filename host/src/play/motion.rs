//! What moves the keys: the two players and the stretches of time a key needs simulating.
//!
//! * the position player ([`Motion::Track`]): the key-motion model of
//!   `tactus_runtime::performance` prescribes the key travel; the instrument's force is
//!   computed but does not move the key;
//! * the force player ([`Motion::Finger`]): a finger pushes with a force profile and the key
//!   moves under the finger's and the instrument's forces (`tactus_runtime::player`): the
//!   closed loop. Each instrument is first calibrated with single strokes at
//!   `CALIBRATION_LEVELS_N` ([`super::calibrate`]), so a note of MIDI velocity `v` is played with
//!   the finger force that gives the hammer speed [`speed_for_velocity`]`(v)`, started that
//!   stroke's lead time before the note-on ([`finger_profile`]).
//!
//! On a host engine a key is simulated only around its movements ([`busy_stretches`]): from
//! [`LEAD_IN_S`] before a press to [`TAIL_S`] after it ends, and a key at rest for more than
//! [`IDLE_GAP_S`] between notes is simulated as separate stretches, each from a fresh
//! instance (a key at rest that long is back in its initial state — hammer on the rest felt,
//! jack re-armed, impact pulses decayed — so this changes no strike, and a whole piece costs
//! the time its keys move, not its length times its keys). The firmware runs every key
//! every sample, as the hardware does.

use super::strike::speed_for_velocity;
use tactus_runtime::performance::{self, KeyTrack, Note, Performance};
use tactus_runtime::player::{Calibration, FingerConfig, ForceProfile, Stroke};

/// How a played key moves.
#[derive(Clone, Debug)]
pub enum Motion {
    /// It follows a key-travel track (the position player).
    Track(KeyTrack),
    /// A finger pushes it with a force profile against the instrument (the force player).
    Finger(ForceProfile),
}

impl Motion {
    /// Notes the key plays (a track's notes, a finger's strokes): what makes a board's run
    /// long, since a key at rest costs the emulator little (its calls are memoized).
    pub fn notes(&self) -> usize {
        match self {
            Motion::Track(t) => t.notes.len(),
            Motion::Finger(f) => f.strokes().len(),
        }
    }
}

/// Time a stroke waits for the key to rise after the previous note's finger lifted, s: a
/// note that follows sooner lifts the previous finger earlier.
pub const RISE_GAP_S: f64 = 0.030;

/// Simulated time before a key's first movement, s.
pub const LEAD_IN_S: f64 = 0.05;
/// Simulated time after a key's last movement ends, s (the hammer settles on its rest felt).
pub const TAIL_S: f64 = 0.5;
/// A key at rest for longer than this between two movements, s, is simulated as two
/// stretches, each from a fresh instance.
pub const IDLE_GAP_S: f64 = 1.0;

/// A stroke is played from rest only when its push starts at least this long after the
/// previous stroke's finger lifted, s: the key is back up and the hammer back on its rest
/// felt (a released grand-piano key rises in ≈ 60 ms, its hammer lands ≈ 100 ms after the
/// lift). A sooner stroke is a re-strike ([`FingerCalibration::restrikes`]).
pub const SETTLE_S: f64 = 0.100;

/// The force player's calibration of one instrument: strokes from rest and re-strikes.
#[derive(Clone, Debug, PartialEq)]
pub struct FingerCalibration {
    /// Strokes from rest: (peak N, lead s, hammer speed m/s); the lead from the start of
    /// the push to the strike.
    pub from_rest: Calibration,
    /// Re-strikes, one calibration per hold and rise, by increasing hold, then rise. Each
    /// is the key held down for the hold after a strike, released for the rise and pushed
    /// again from where it rose to, the hammer still on the repetition lever; the holds are
    /// [`super::calibrate::RESTRIKE_HOLDS_S`], the rises
    /// [`super::calibrate::RESTRIKE_RISES_S`] at which at least two levels re-strike, down
    /// to the shortest after which as many levels re-strike as after the longest. Empty when
    /// none re-strikes two levels.
    pub restrikes: Vec<Restrike>,
}

/// One re-strike calibration ([`FingerCalibration::restrikes`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Restrike {
    /// How long the previous note was held after its strike, s.
    pub hold_s: f64,
    /// How long the finger let the key rise before the push, s.
    pub rise_s: f64,
    /// The pushes: (peak N, lead s, hammer speed m/s).
    pub cal: Calibration,
}

impl FingerCalibration {
    /// The shortest calibrated rise, s.
    pub fn shortest_rise_s(&self) -> Option<f64> {
        self.restrikes
            .iter()
            .map(|r| r.rise_s)
            .min_by(f64::total_cmp)
    }

    /// The re-strikes after a previous note held `hold_s` after its strike: those of the
    /// calibrated hold nearest to it (on a log scale: the state of the hammer on its lever
    /// changes with the hold's ratio, not its difference), by increasing rise.
    pub fn restrikes_after(&self, hold_s: f64) -> Vec<&Restrike> {
        let distance = |r: &Restrike| (r.hold_s.ln() - hold_s.max(1e-3).ln()).abs();
        let Some(nearest) = self
            .restrikes
            .iter()
            .min_by(|a, b| distance(a).total_cmp(&distance(b)))
        else {
            return Vec::new();
        };
        self.restrikes
            .iter()
            .filter(|r| r.hold_s == nearest.hold_s)
            .collect()
    }
}

/// The finger's strokes for one key's notes: each aims at the hammer speed of its MIDI
/// velocity ([`speed_for_velocity`]) with the calibrated force, starts the calibrated lead
/// before its note-on, pushes until 10 ms after the note-on, holds until the note-off and
/// lifts then.
///
/// A stroke whose push would start less than [`SETTLE_S`] after the previous finger lifted
/// finds the key not yet back at rest: it is a **re-strike**, played as a re-strike
/// calibration measured it — with its force and lead, the previous finger lifted that
/// calibration's rise before the push (holding the previous note that much longer, or
/// releasing it sooner), and never before the previous push has ended. Of the calibrations
/// ([`FingerCalibration::restrikes`]) it takes those of the hold nearest to the previous
/// note's (a hammer held long has settled on its lever, and a push from there strikes
/// sooner and softer than after a short hold: Maestro_2's soft A2 after notes held 0.4 s
/// struck 60 ms early at 0.2 m/s, played with the short hold's calibration), and of their
/// rises the longest whose push fits before the note-on: a key let rise longer is higher
/// when the push comes, the jack surely re-armed
/// under the knuckle (a bass key released from its bed rises no faster than its hammer
/// falls back onto the repetition lever, and 40 ms left it where the jack re-arms, or just
/// short of it: Maestro_2's repeated A1, 5.5 notes a second, lost 37 of 55 notes). A
/// re-strike whose lead fits at no rise takes the shortest rise and the weakest re-strike
/// whose lead does (louder than asked, on time); when none does, it starts late. Without a
/// re-strike calibration (or for the first note) the stroke keeps the from-rest force and
/// lead, and the previous finger lifts [`RISE_GAP_S`] before it.
pub fn finger_profile(
    notes: &[Note],
    cal: &FingerCalibration,
    finger: FingerConfig,
    end_s: f64,
) -> (ForceProfile, Restrikes) {
    let mut strokes: Vec<Stroke> = Vec::with_capacity(notes.len());
    let mut counts = Restrikes::default();
    for n in notes {
        let speed = speed_for_velocity(n.velocity);
        let (mut peak, lead) = cal.from_rest.for_speed(speed);
        let mut start = (n.on_s - lead).max(0.0);
        // The key still busy with earlier strokes beyond this note-on and the piece's end
        // (a dense repetition, each re-strike waiting for the last): the note is left out.
        let shortest_rise = cal.shortest_rise_s().unwrap_or(0.0);
        if strokes
            .last()
            .is_some_and(|p| p.push_end_s + shortest_rise >= end_s.max(n.on_s))
        {
            counts.dropped += 1;
            continue;
        }
        if strokes.is_empty() && n.on_s - lead < 0.0 {
            // The piece starts sooner than the push needs: the stroke starts at 0, late.
            counts.late += 1;
        }
        if let Some(prev) = strokes.last_mut() {
            // The previous note's hold after its strike (its push ends 10 ms after it).
            let family = cal.restrikes_after(prev.lift_s - prev.push_end_s + 0.010);
            match family.first() {
                Some(shortest) if start < prev.lift_s + SETTLE_S => {
                    // The longest rise whose push for this speed fits before the note-on.
                    let r = family
                        .iter()
                        .rev()
                        .find(|r| n.on_s - r.cal.for_speed(speed).1 >= prev.push_end_s + r.rise_s)
                        .unwrap_or(shortest);
                    let (rise, re) = (r.rise_s, &r.cal);
                    let earliest = prev.push_end_s + rise;
                    let (mut p, mut lead) = re.for_speed(speed);
                    counts.restrikes += 1;
                    if n.on_s - lead < earliest {
                        // No time for so soft a push: the weakest re-strike that reaches
                        // the string by the note-on (a pianist plays a fast repetition
                        // louder rather than late).
                        if let Some(l) = re.levels().iter().find(|l| n.on_s - l.1 >= earliest) {
                            (p, lead) = (l.0, l.1);
                            counts.raised += 1;
                        }
                    }
                    peak = p;
                    if n.on_s - lead < earliest {
                        counts.late += 1;
                    }
                    start = (n.on_s - lead).max(earliest);
                    prev.lift_s = start - rise;
                }
                _ => {
                    prev.lift_s = prev.lift_s.min(start - RISE_GAP_S).max(prev.start_s);
                    prev.push_end_s = prev.push_end_s.min(prev.lift_s);
                }
            }
        }
        let push_end = n.on_s.max(start) + 0.010;
        strokes.push(Stroke {
            start_s: start,
            peak_n: peak,
            push_end_s: push_end,
            lift_s: n.off_s.max(push_end),
        });
    }
    (ForceProfile::new(finger, strokes), counts)
}

/// How the force player played repeated notes ([`finger_profile`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Restrikes {
    /// Notes played as re-strikes (the key not yet back at rest).
    pub restrikes: usize,
    /// … of which the asked softness had no time: played with the weakest re-strike that
    /// fits, louder than asked.
    pub raised: usize,
    /// … of which none fits: started late (with the first note of a piece that starts
    /// sooner than its push needs).
    pub late: usize,
    /// Notes left out: the key still busy with earlier strokes beyond the note-on and the
    /// piece's end.
    pub dropped: usize,
}

impl std::ops::AddAssign for Restrikes {
    fn add_assign(&mut self, o: Restrikes) {
        self.restrikes += o.restrikes;
        self.raised += o.raised;
        self.late += o.late;
        self.dropped += o.dropped;
    }
}

/// One key's motion for its notes `notes` (sorted by note-on), the intervals it moves
/// (start s, end s) and how its repeated notes were played: the position player's track for
/// a key of dip `dip_m` over a piece of `duration_s`, or with a calibration the force
/// player's finger.
pub fn key_motion(
    notes: &[Note],
    dip_m: f64,
    duration_s: f64,
    force: Option<(&FingerCalibration, FingerConfig)>,
) -> (Motion, Vec<(f64, f64)>, Restrikes) {
    match force {
        None => {
            let track = performance::key_tracks(
                &Performance {
                    notes: notes.to_vec(),
                    sustain: vec![],
                    duration_s,
                },
                dip_m,
            )
            .remove(0);
            let mut busy: Vec<(f64, f64)> = notes
                .iter()
                .map(|n| {
                    (
                        n.on_s - performance::MAX_DESCENT_S,
                        n.off_s.max(n.on_s) + performance::RELEASE_S,
                    )
                })
                .collect();
            // A chain of waiting presses may end later than its notes' own intervals.
            let end = track.last_move_end_s();
            busy.push((end - performance::RELEASE_S, end));
            let counts = Restrikes {
                dropped: track.dropped,
                ..Restrikes::default()
            };
            (Motion::Track(track), busy, counts)
        }
        Some((cal, finger)) => {
            let (profile, counts) = finger_profile(notes, cal, finger, duration_s);
            let busy = profile
                .strokes()
                .iter()
                .map(|s| (s.start_s, s.lift_s))
                .collect();
            (Motion::Finger(profile), busy, counts)
        }
    }
}

/// Merges movement intervals (start s, end s) into busy stretches: intervals closer than
/// [`IDLE_GAP_S`] belong to one stretch.
pub fn busy_stretches(mut busy: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    busy.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (a, b) in busy {
        match out.last_mut() {
            Some(last) if a - last.1 < IDLE_GAP_S => last.1 = last.1.max(b),
            _ => out.push((a, b)),
        }
    }
    out
}

/// The samples to simulate for a busy stretch (start s, end s) at `fs` Hz: from
/// [`LEAD_IN_S`] before it to [`TAIL_S`] after it.
pub fn stretch_samples((start_s, end_s): (f64, f64), fs: f64) -> std::ops::Range<usize> {
    let a = ((start_s - LEAD_IN_S).max(0.0) * fs) as usize;
    let b = ((end_s + TAIL_S) * fs) as usize;
    a..b.max(a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn busy_stretches_merge_only_short_rests() {
        let s = busy_stretches(vec![(5.0, 5.2), (0.0, 0.5), (1.2, 1.4), (0.4, 0.6)]);
        // 0.6 → 1.2 is a rest shorter than IDLE_GAP_S: one stretch; 1.4 → 5.0 is longer.
        assert_eq!(s, vec![(0.0, 1.4), (5.0, 5.2)]);
        assert!(busy_stretches(vec![]).is_empty());
    }
}
