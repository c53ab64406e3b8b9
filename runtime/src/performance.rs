//! Recorded performances: MIDI files → notes → key trajectories (the "player").
//!
//! **Reading.** A standard MIDI file (format 0 or 1) is read with `midly`; tempo changes are
//! honoured (SMPTE time codes too), a note-on with velocity 0 is a note-off, and the sustain
//! pedal (controller 64, ≥ 64 = down) is kept as a list of changes. Every note-on is paired
//! with the next note-off of the same key and channel; a note still sounding at the end of
//! the file ends there.
//!
//! **Corrupt files.** The file's chunk structure is checked before `midly` sees it
//! ([`parse_midi_reporting`]): a file over [`MAX_MIDI_BYTES`], a header claiming 0 tracks,
//! format 2 (independent sequences, which have no common time line), a division of 0 ticks
//! per quarter note or 0 SMPTE subframes are errors naming the file. A truncated track or a
//! header that claims more tracks than the file holds is read as far as it goes, with a
//! warning giving the bytes missing and the notes left without a note-off. A note held
//! longer than [`MAX_HELD_S`] is cut there, with a warning, so a stray note-off hours later
//! cannot make a player simulate hours.
//!
//! **The key-motion model.** A recorded note-on (a Disklavier records it when the hammer
//! reaches the string) becomes a key press that reaches the key bottom at the note-on time:
//!
//! * descent time from velocity, log-linear between the literature's end points (Tactus
//!   DESIGN.md: the key reaches bottom ≈ 160 ms after the start at *piano*, ≈ 25 ms at
//!   *forte*), which we assign to MIDI velocities 30 and 100:
//!   `T(v) = 160 ms · (25/160)^((v − 30)/70)`, clamped to [20 ms, 200 ms] (a recorded
//!   note-on means the hammer did reach the string, and the shipped piano's hammer no longer
//!   does at a 250 ms descent). MIDI velocity
//!   is close to logarithmic in hammer speed on reproducing pianos (the map the strike
//!   outputs use, `tactus_host::play::strike::midi_velocity`, is the Bösendorfer SE's,
//!   `52 + 25·log2(v)`), so a log-linear map of travel time keeps the order of velocities
//!   (the property the tests rely on); this player does not aim at a hammer speed;
//! * the press follows the cycloidal law of [`crate::stimulus`] (smooth to the second
//!   derivative) from wherever the key is, so a repeated note that comes before the key is
//!   back up re-strikes from a half-released key; such a press covers the remaining travel
//!   in the same fraction of `T(v)`, so the key keeps the speed of its velocity (a soft
//!   re-strike over the full `T(v)` would move the key too slowly to throw the hammer to the
//!   string);
//! * the key is held at the bottom until the note-off, then released over
//!   [`RELEASE_S`] (60 ms) back to rest; when the next press of that key starts before the
//!   release could finish, the key is released faster, to [`REPEAT_RISE`] of the dip
//!   raised, by the time that press would start from rest, and waits there.
//!
//! The sustain pedal does not move keys (it lifts dampers), so it does not enter the key
//! tracks; the WAV rendering of `tactus play` uses it to hold the dampers off
//! ([`crate::voice::damper_time`]).
//!
//! This model prescribes the key's travel (open loop): the instrument's force does not move
//! the key. The closed-loop alternative, a finger force against the instrument's force, is
//! [`crate::player`].

use midly::{MetaMessage, MidiMessage, Smf, Timing, TrackEventKind};
use std::fmt;
use std::path::Path;

/// Key release time, s.
pub const RELEASE_S: f64 = 0.060;

/// Slowest key descent the player uses, s.
pub const MAX_DESCENT_S: f64 = 0.200;

/// A repeated note that comes before the key is back up re-strikes from at least this
/// fraction of the dip raised (the repetition lever lets a grand re-strike from a half-raised
/// key; the jack re-arms below its let-off zone).
pub const REPEAT_RISE: f64 = 0.6;

/// The longest a note may be held, s: a note-off later than this after its note-on is
/// moved here (with a warning). Two minutes is beyond any held chord of the piano
/// repertoire (the sustain pedal, not the key, holds longer sounds).
pub const MAX_HELD_S: f64 = 120.0;

/// The largest MIDI file read, bytes (the MAESTRO performances are well under 1 MB).
pub const MAX_MIDI_BYTES: u64 = 16 << 20;

/// One note of a performance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Note {
    /// MIDI key number (21 = A0 … 108 = C8 on a piano).
    pub key: u8,
    /// Note-on velocity, 1–127.
    pub velocity: u8,
    /// Note-on time, s.
    pub on_s: f64,
    /// Note-off time, s (≥ `on_s`).
    pub off_s: f64,
}

/// A performance: notes sorted by note-on time, and the sustain pedal's changes.
#[derive(Clone, Debug, PartialEq)]
pub struct Performance {
    /// Notes, by note-on time.
    pub notes: Vec<Note>,
    /// Sustain pedal changes: (time s, down).
    pub sustain: Vec<(f64, bool)>,
    /// Time of the last event, s.
    pub duration_s: f64,
}

impl Performance {
    /// The first `seconds` of the performance (`tactus play --seconds`): the notes that
    /// start before it, each still held then released there (the pedal is left as it is:
    /// it only decides when dampers fall in the rendering).
    ///
    /// Errors: `seconds` not a positive number.
    pub fn cut(&mut self, seconds: f64) -> Result<(), String> {
        if !(seconds.is_finite() && seconds > 0.0) {
            return Err(format!(
                "--seconds must be a positive number, got {seconds}"
            ));
        }
        self.notes.retain(|n| n.on_s < seconds);
        for n in &mut self.notes {
            n.off_s = n.off_s.min(seconds);
        }
        self.duration_s = self.duration_s.min(seconds);
        Ok(())
    }
}

/// Why a MIDI file could not be read.
#[derive(Debug)]
pub enum MidiError {
    /// The file could not be read.
    Io(String, std::io::Error),
    /// The bytes are not a valid standard MIDI file.
    Parse(String, String),
    /// The file holds no notes.
    NoNotes(String),
}

impl fmt::Display for MidiError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MidiError::Io(p, e) => write!(f, "{p}: cannot read: {e}"),
            MidiError::Parse(p, e) => write!(f, "{p}: not a standard MIDI file: {e}"),
            MidiError::NoNotes(p) => write!(f, "{p}: the file holds no notes"),
        }
    }
}

impl std::error::Error for MidiError {}

/// Reads a MIDI file from disk; repairs are dropped (see [`read_midi_reporting`]).
pub fn read_midi(path: &Path) -> Result<Performance, MidiError> {
    read_midi_reporting(path).map(|(p, _)| p)
}

/// Reads a MIDI file from disk, with a warning (naming the file) per repair made.
pub fn read_midi_reporting(path: &Path) -> Result<(Performance, Vec<String>), MidiError> {
    let name = path.display().to_string();
    let bytes =
        crate::files::read_bounded(path, MAX_MIDI_BYTES, "a MIDI file").map_err(|e| {
            match e.kind {
                crate::files::ReadErrorKind::Io(io) => MidiError::Io(name.clone(), io),
                _ => MidiError::Parse(
                    name.clone(),
                    format!("more than the {MAX_MIDI_BYTES} bytes a MIDI file may have"),
                ),
            }
        })?;
    parse_midi_reporting(&bytes, &name)
}

/// Parses MIDI bytes; `name` is used in errors; repairs are dropped (see
/// [`parse_midi_reporting`]).
pub fn parse_midi(bytes: &[u8], name: &str) -> Result<Performance, MidiError> {
    parse_midi_reporting(bytes, name).map(|(p, _)| p)
}

/// Checks a standard MIDI file's header and chunks (see the module documentation):
/// the warnings of a repaired read, or the error.
fn check_chunks(bytes: &[u8], name: &str) -> Result<Vec<String>, MidiError> {
    let bad = |m: String| MidiError::Parse(name.to_string(), m);
    let be32 =
        |at: usize| u32::from_be_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    let be16 = |at: usize| u16::from_be_bytes([bytes[at], bytes[at + 1]]);
    if bytes.len() < 14 || &bytes[..4] != b"MThd" {
        // Not a bare SMF (a RIFF RMID wrapper, or not MIDI): midly decides.
        return Ok(Vec::new());
    }
    let header_len = be32(4) as usize;
    if header_len < 6 || header_len > bytes.len() - 8 {
        return Err(bad(format!("the header chunk claims {header_len} bytes")));
    }
    let (format, claimed, division) = (be16(8), be16(10), be16(12));
    match format {
        0 | 1 => {}
        2 => {
            return Err(bad(
                "MIDI format 2 (independent sequences) has no common time line; convert it to format 0 or 1".into(),
            ))
        }
        f => return Err(bad(format!("unknown MIDI format {f}"))),
    }
    if claimed == 0 {
        return Err(bad("the header claims 0 tracks".into()));
    }
    if division & 0x8000 == 0 {
        if division == 0 {
            return Err(bad(
                "the header's division is 0 ticks per quarter note".into()
            ));
        }
    } else {
        let fps = -i32::from((division >> 8) as u8 as i8);
        if ![24, 25, 29, 30].contains(&fps) || division & 0xFF == 0 {
            return Err(bad(format!(
                "the header's SMPTE division ({fps} frames/s, {} subframes) is not valid",
                division & 0xFF
            )));
        }
    }
    let mut warnings = Vec::new();
    let mut at = 8 + header_len;
    let mut tracks = 0usize;
    while at < bytes.len() {
        if bytes.len() - at < 8 {
            warnings.push(format!(
                "{name}: {} stray bytes after the last chunk are ignored",
                bytes.len() - at
            ));
            break;
        }
        let len = be32(at + 4) as usize;
        let is_track = &bytes[at..at + 4] == b"MTrk";
        tracks += usize::from(is_track);
        let present = bytes.len() - at - 8;
        if len > present {
            warnings.push(format!(
                "{name}: track {tracks} is truncated: its header claims {len} bytes, {present} are present; the events in the {} missing bytes are lost",
                len - present
            ));
            break;
        }
        at += 8 + len;
    }
    if tracks != usize::from(claimed) {
        warnings.push(format!(
            "{name}: the header claims {claimed} tracks, the file holds {tracks}"
        ));
    }
    if tracks == 0 {
        return Err(bad("the file holds no track chunk".into()));
    }
    Ok(warnings)
}

/// Parses MIDI bytes; `name` is used in errors and warnings. Returns the performance and a
/// warning per repair: a truncated track or a wrong track count (read as far as the file
/// goes), notes left without a note-off, notes held longer than [`MAX_HELD_S`].
///
/// Errors ([`MidiError::Parse`], naming the file): see the module documentation.
pub fn parse_midi_reporting(
    bytes: &[u8],
    name: &str,
) -> Result<(Performance, Vec<String>), MidiError> {
    let mut warnings = check_chunks(bytes, name)?;
    let smf = Smf::parse(bytes).map_err(|e| MidiError::Parse(name.to_string(), e.to_string()))?;
    // Merge all tracks into (tick, event) in tick order (stable: track order on ties).
    let mut events = Vec::new();
    for track in &smf.tracks {
        let mut tick: u64 = 0;
        for ev in track {
            tick += u64::from(ev.delta.as_int());
            events.push((tick, ev.kind));
        }
    }
    events.sort_by_key(|e| e.0);
    let seconds = TickClock::new(smf.header.timing);
    let mut clock = seconds;
    let mut sounding: Vec<Option<(f64, u8)>> = vec![None; 16 * 128];
    let mut notes = Vec::new();
    let mut sustain = Vec::new();
    let mut last_s = 0.0f64;
    for (tick, kind) in events {
        let t = clock.seconds(tick);
        last_s = last_s.max(t);
        match kind {
            TrackEventKind::Meta(MetaMessage::Tempo(us)) => clock.set_tempo(tick, us.as_int()),
            TrackEventKind::Midi { channel, message } => {
                let ch = channel.as_int() as usize;
                match message {
                    MidiMessage::NoteOn { key, vel } if vel.as_int() > 0 => {
                        let slot = &mut sounding[ch * 128 + key.as_int() as usize];
                        if let Some((on, v)) = slot.take() {
                            notes.push(Note {
                                key: key.as_int(),
                                velocity: v,
                                on_s: on,
                                off_s: t,
                            });
                        }
                        *slot = Some((t, vel.as_int()));
                    }
                    MidiMessage::NoteOn { key, .. } | MidiMessage::NoteOff { key, .. } => {
                        if let Some((on, v)) = sounding[ch * 128 + key.as_int() as usize].take() {
                            notes.push(Note {
                                key: key.as_int(),
                                velocity: v,
                                on_s: on,
                                off_s: t,
                            });
                        }
                    }
                    MidiMessage::Controller { controller, value } if controller.as_int() == 64 => {
                        sustain.push((t, value.as_int() >= 64));
                    }
                    _ => {}
                }
            }
            _ => {}
        }
    }
    let mut open = 0usize;
    for (i, s) in sounding.iter().enumerate() {
        if let Some((on, v)) = s {
            open += 1;
            notes.push(Note {
                key: (i % 128) as u8,
                velocity: *v,
                on_s: *on,
                off_s: last_s,
            });
        }
    }
    if open > 0 {
        warnings.push(format!(
            "{name}: {open} notes have no note-off and end at the last event ({last_s:.3} s)"
        ));
    }
    if notes.is_empty() {
        return Err(MidiError::NoNotes(name.to_string()));
    }
    let mut cut = 0usize;
    for n in &mut notes {
        if n.off_s - n.on_s > MAX_HELD_S {
            n.off_s = n.on_s + MAX_HELD_S;
            cut += 1;
        }
    }
    if cut > 0 {
        warnings.push(format!(
            "{name}: {cut} notes are held longer than {MAX_HELD_S} s and end there"
        ));
    }
    // The piece ends at its last event, but not after its last (bounded) note by more than
    // the longest hold: a stray event far after the music moves no key.
    let last_note = notes.iter().map(|n| n.off_s).fold(0.0, f64::max);
    let duration_s = last_s.min(last_note + MAX_HELD_S);
    notes.sort_by(|a, b| a.on_s.total_cmp(&b.on_s).then(a.key.cmp(&b.key)));
    Ok((
        Performance {
            notes,
            sustain,
            duration_s,
        },
        warnings,
    ))
}

/// Tick → seconds with a piecewise-constant tempo map.
#[derive(Clone, Copy)]
struct TickClock {
    /// Ticks per quarter note, or 0 for SMPTE timing.
    tpq: f64,
    /// Seconds per tick under SMPTE timing.
    smpte_s_per_tick: f64,
    /// The tempo segment in force: its start tick, start seconds, µs per quarter.
    seg_tick: u64,
    seg_s: f64,
    us_per_q: f64,
}

impl TickClock {
    fn new(t: Timing) -> Self {
        match t {
            Timing::Metrical(tpq) => TickClock {
                tpq: f64::from(tpq.as_int().max(1)),
                smpte_s_per_tick: 0.0,
                seg_tick: 0,
                seg_s: 0.0,
                us_per_q: 500_000.0,
            },
            Timing::Timecode(fps, sub) => TickClock {
                tpq: 0.0,
                smpte_s_per_tick: 1.0 / (f64::from(fps.as_f32()) * f64::from(sub.max(1))),
                seg_tick: 0,
                seg_s: 0.0,
                us_per_q: 500_000.0,
            },
        }
    }
    fn seconds(&self, tick: u64) -> f64 {
        if self.tpq == 0.0 {
            return tick as f64 * self.smpte_s_per_tick;
        }
        self.seg_s + (tick - self.seg_tick.min(tick)) as f64 * self.us_per_q * 1e-6 / self.tpq
    }
    fn set_tempo(&mut self, tick: u64, us_per_q: u32) {
        if self.tpq == 0.0 {
            return;
        }
        self.seg_s = self.seconds(tick);
        self.seg_tick = tick;
        self.us_per_q = f64::from(us_per_q.max(1));
    }
}

/// Key descent time for a MIDI velocity, s (see the module documentation).
pub fn descent_time_s(velocity: u8) -> f64 {
    let v = f64::from(velocity.clamp(1, 127));
    (0.160 * (0.025f64 / 0.160).powf((v - 30.0) / 70.0)).clamp(0.020, MAX_DESCENT_S)
}

/// One movement of a key: from `from` (m) at `start_s` to `to` (m) at `end_s`, cycloidal.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Move {
    start_s: f64,
    end_s: f64,
    from: f64,
    to: f64,
}

impl Move {
    fn at(&self, t: f64) -> f64 {
        if t <= self.start_s {
            return self.from;
        }
        if t >= self.end_s {
            return self.to;
        }
        let u = (t - self.start_s) / (self.end_s - self.start_s);
        let s = u - (2.0 * std::f64::consts::PI * u).sin() / (2.0 * std::f64::consts::PI);
        self.from + (self.to - self.from) * s
    }
}

/// The key trajectory of one key for a whole performance.
#[derive(Clone, Debug, PartialEq)]
pub struct KeyTrack {
    /// MIDI key number.
    pub key: u8,
    moves: Vec<Move>,
    /// Note-on times of the notes played on this key, s, with their velocities.
    pub notes: Vec<(f64, u8)>,
    /// Notes the model could not place as recorded ([`Rushed`]): pressed faster than their
    /// velocity's descent (the piece starts too soon after them, or the key was still
    /// moving for the previous note), or reaching the bottom after their note-on.
    pub rushed: Vec<Rushed>,
    /// Notes left out: their press could not start before the performance's end (the key
    /// still busy with earlier notes of a dense repetition).
    pub dropped: usize,
}

/// A note the key-motion model could not play as recorded: what it asked and what the key
/// did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rushed {
    /// Its note-on, s.
    pub on_s: f64,
    /// Its MIDI velocity.
    pub velocity: u8,
    /// The press it asked for (the descent time of its velocity for the travel left), s.
    pub wanted_s: f64,
    /// The press the key made, s.
    pub pressed_s: f64,
    /// How late the key reached the bottom after the note-on, s (0: on time).
    pub late_s: f64,
}

impl KeyTrack {
    /// When the key's last movement ends, s.
    pub fn last_move_end_s(&self) -> f64 {
        self.moves.last().map_or(0.0, |m| m.end_s)
    }

    /// Key travel at time `t` (s), m; 0 before the first press.
    pub fn position(&self, t: f64) -> f64 {
        // The last move that has started by t decides.
        self.travel(self.moves.partition_point(|m| m.start_s <= t), t)
    }

    /// [`KeyTrack::position`] for a caller that asks at times that rarely go back (a play
    /// loop, sample after sample): `cursor` (start it at 0; the caller keeps it between
    /// calls) is the number of moves started by the last time asked, and moves on from
    /// there instead of searching all the moves again. The same value as `position(t)` for
    /// any `t` and any cursor.
    pub fn position_from(&self, t: f64, cursor: &mut usize) -> f64 {
        let m = &self.moves;
        let mut i = (*cursor).min(m.len());
        if i > 0 && m[i - 1].start_s > t {
            // Back in time: search again.
            i = m.partition_point(|m| m.start_s <= t);
        }
        while i < m.len() && m[i].start_s <= t {
            i += 1;
        }
        *cursor = i;
        self.travel(i, t)
    }

    /// Whether the key holds still at time `t` (m, as [`KeyTrack::position_from`], whose
    /// `cursor` it moves the same way): `Some((travel, until))` when its travel is
    /// `travel` at `t` and at every later time before `until` (s; infinite after the last
    /// move): no move under way at `t`, the next starting at `until`. `None` while it
    /// moves.
    pub fn steady_from(&self, t: f64, cursor: &mut usize) -> Option<(f64, f64)> {
        let x = self.position_from(t, cursor);
        let i = *cursor;
        if i > 0 && t < self.moves[i - 1].end_s {
            return None;
        }
        let until = self.moves.get(i).map_or(f64::INFINITY, |m| m.start_s);
        Some((x, until))
    }

    /// Key travel at time `t` when `started` moves have started by then.
    fn travel(&self, started: usize, t: f64) -> f64 {
        match started {
            0 => 0.0,
            i => self.moves[i - 1].at(t),
        }
    }
}

/// The key tracks of every key played in a performance, for a key dip `dip_m` (m).
/// Presses end at the note-on time (the hammer reaches the string then); a note whose press
/// would start before time 0 starts at 0, pressed faster, and one whose press would start
/// while the key still moves for the previous note waits for it; both are recorded in
/// [`KeyTrack::rushed`]. A note whose key is busy beyond both its note-on and the piece's
/// end is left out ([`KeyTrack::dropped`]), so a dense repetition cannot stretch the key's
/// motion beyond the piece.
pub fn key_tracks(perf: &Performance, dip_m: f64) -> Vec<KeyTrack> {
    let mut by_key: std::collections::BTreeMap<u8, Vec<Note>> = Default::default();
    for n in &perf.notes {
        by_key.entry(n.key).or_default().push(*n);
    }
    let mut tracks = Vec::new();
    for (key, notes) in by_key {
        let mut t = KeyTrack {
            key,
            moves: Vec::new(),
            notes: Vec::new(),
            rushed: Vec::new(),
            dropped: 0,
        };
        for (i, n) in notes.iter().enumerate() {
            let descent = descent_time_s(n.velocity);
            // Presses start after the previous movement ends (moves stay in time order). A
            // press from a half-released key covers only the remaining travel, in the same
            // fraction of the descent time (the key keeps the speed of its velocity); the
            // start depends on where the rising key is then, so it is found by iteration.
            let earliest = t.moves.last().map_or(0.0, |m| m.end_s);
            if earliest >= perf.duration_s.max(n.on_s) && !t.moves.is_empty() {
                // The key is busy past the note-on and the piece's end: no press for it.
                t.dropped += 1;
                continue;
            }
            let mut start = (n.on_s - descent).max(earliest);
            let mut remaining = 1.0;
            for _ in 0..3 {
                remaining = (1.0 - t.position(start) / dip_m).clamp(0.0, 1.0);
                start = (n.on_s - descent * remaining).max(earliest);
            }
            let from = t.position(start);
            let bottom = n.on_s.max(start + 1e-3);
            // Pressed faster than asked (more than 1 % or 0.1 ms), or late: reported.
            let (wanted, pressed) = (descent * remaining, bottom - start);
            if pressed < wanted * 0.99 - 1e-4 || bottom > n.on_s + 1e-4 {
                t.rushed.push(Rushed {
                    on_s: n.on_s,
                    velocity: n.velocity,
                    wanted_s: wanted,
                    pressed_s: pressed,
                    late_s: bottom - n.on_s,
                });
            }
            t.moves.push(Move {
                start_s: start,
                end_s: bottom,
                from,
                to: dip_m,
            });
            // When the next press would start if it started from rest: a release that cannot
            // finish by then is a quick partial one, and the key waits, raised by
            // `REPEAT_RISE` of the dip, for that press (the hammer stays up on the
            // repetition lever meanwhile).
            let next_start = notes
                .get(i + 1)
                .map(|m| (m.on_s - descent_time_s(m.velocity)).max(0.0));
            let release_at = n.off_s.max(bottom);
            let release = match next_start {
                // Time for a full release before the next press.
                None => Move {
                    start_s: release_at,
                    end_s: release_at + RELEASE_S,
                    from: dip_m,
                    to: 0.0,
                },
                Some(next) if next >= release_at + RELEASE_S => Move {
                    start_s: release_at,
                    end_s: release_at + RELEASE_S,
                    from: dip_m,
                    to: 0.0,
                },
                // A quick partial release, by when the next press would start from rest.
                Some(next) => {
                    let end = next.max(bottom + 2e-3);
                    let start_r = release_at.min(end - 2e-3).max(bottom);
                    Move {
                        start_s: start_r,
                        end_s: end,
                        from: dip_m,
                        to: dip_m * (1.0 - REPEAT_RISE),
                    }
                }
            };
            t.moves.push(release);
            t.notes.push((n.on_s, n.velocity));
        }
        tracks.push(t);
    }
    tracks
}

/// A built-in demo performance (4.5 s, generated, no recording): a C-major scale up from
/// *pp* to *ff* at five notes per second, four repeated notes at 8 per second, a trill,
/// and a loud chord — the main job's default input when no MIDI file is given. It is short
/// because `tactus play` runs it through the firmware of all 22 boards of the 88-key grand,
/// every key every sample, in the emulator: about 6 s on two cores with the plan cached
/// (BENCHMARKS.md).
pub fn demo() -> Performance {
    let mut notes = Vec::new();
    let mut t = 0.2;
    let scale = [60u8, 62, 64, 65, 67, 69, 71, 72];
    for (i, &k) in scale.iter().enumerate() {
        let v = 20 + (i as u8) * 14;
        notes.push(Note {
            key: k,
            velocity: v,
            on_s: t,
            off_s: t + 0.17,
        });
        t += 0.2;
    }
    t += 0.2;
    for i in 0..4 {
        notes.push(Note {
            key: 67,
            velocity: 70,
            on_s: t + i as f64 * 0.125,
            off_s: t + i as f64 * 0.125 + 0.06,
        });
    }
    t += 0.6;
    for i in 0..8 {
        let k = if i % 2 == 0 { 72 } else { 74 };
        notes.push(Note {
            key: k,
            velocity: 55,
            on_s: t + i as f64 * 0.1,
            off_s: t + i as f64 * 0.1 + 0.08,
        });
    }
    t += 0.9;
    for k in [48u8, 55, 60, 64, 67] {
        notes.push(Note {
            key: k,
            velocity: 110,
            on_s: t,
            off_s: t + 0.8,
        });
    }
    notes.sort_by(|a, b| a.on_s.total_cmp(&b.on_s).then(a.key.cmp(&b.key)));
    Performance {
        notes,
        sustain: vec![],
        duration_s: t + 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn smf(events: &[(u32, [u8; 3])]) -> Vec<u8> {
        // Format 0, one track, 480 ticks per quarter, default tempo (0.5 s per quarter).
        let mut track = Vec::new();
        for (delta, msg) in events {
            let mut d = *delta;
            let mut bytes = vec![(d & 0x7f) as u8];
            d >>= 7;
            while d > 0 {
                bytes.insert(0, 0x80 | (d & 0x7f) as u8);
                d >>= 7;
            }
            track.extend(bytes);
            track.extend(msg);
        }
        track.extend([0, 0xff, 0x2f, 0]);
        let mut f = b"MThd\0\0\0\x06\0\0\0\x01\x01\xe0MTrk".to_vec();
        f.extend((track.len() as u32).to_be_bytes());
        f.extend(track);
        f
    }

    #[test]
    fn notes_pair_and_time_converts() {
        // Note 60 on at 0, off at 480 ticks (0.5 s); note 62 on at 240 with velocity 0 = off.
        let f = smf(&[
            (0, [0x90, 60, 100]),
            (240, [0x90, 62, 40]),
            (240, [0x80, 60, 0]),
            (0, [0x90, 62, 0]),
            (0, [0xb0, 64, 127]),
        ]);
        let p = parse_midi(&f, "t.mid").unwrap();
        assert_eq!(p.notes.len(), 2);
        assert_eq!(
            (
                p.notes[0].key,
                p.notes[0].velocity,
                p.notes[0].on_s,
                p.notes[0].off_s
            ),
            (60, 100, 0.0, 0.5)
        );
        assert_eq!(
            (p.notes[1].key, p.notes[1].on_s, p.notes[1].off_s),
            (62, 0.25, 0.5)
        );
        assert_eq!(p.sustain, vec![(0.5, true)]);
    }

    #[test]
    fn bad_files_are_clear_errors() {
        let e = parse_midi(b"not midi", "x.mid").unwrap_err().to_string();
        assert!(
            e.contains("x.mid") && e.contains("not a standard MIDI file"),
            "{e}"
        );
        let e = parse_midi(&smf(&[(0, [0xb0, 64, 127])]), "empty.mid")
            .unwrap_err()
            .to_string();
        assert!(e.contains("no notes"), "{e}");
        let e = parse_midi(&[], "zero.mid").unwrap_err().to_string();
        assert!(e.contains("zero.mid"), "{e}");
    }

    #[test]
    fn presses_reach_bottom_at_note_on_and_repeat_from_half_release() {
        let perf = Performance {
            notes: vec![
                Note {
                    key: 60,
                    velocity: 100,
                    on_s: 0.3,
                    off_s: 0.35,
                },
                Note {
                    key: 60,
                    velocity: 60,
                    on_s: 0.45,
                    off_s: 0.8,
                },
            ],
            sustain: vec![],
            duration_s: 1.0,
        };
        let t = &key_tracks(&perf, 0.01)[0];
        assert_eq!(t.position(0.0), 0.0);
        assert!((t.position(0.3) - 0.01).abs() < 1e-12);
        assert!((t.position(0.45) - 0.01).abs() < 1e-12);
        // The second press starts before the first release ends: the key never returns to 0.
        let lowest = (3500..4500)
            .map(|i| t.position(i as f64 * 1e-4))
            .fold(f64::INFINITY, f64::min);
        assert!(lowest > 0.0 && lowest < 0.01, "{lowest}");
        assert_eq!(t.position(2.0), 0.0);
        assert!(descent_time_s(100) < descent_time_s(60) && descent_time_s(30) == 0.160);
    }
    /// A performance of `notes` (on, off, s) on key 60 at `velocity`, `duration_s` long.
    fn one_key(velocity: u8, notes: &[(f64, f64)], duration_s: f64) -> Performance {
        Performance {
            notes: notes
                .iter()
                .map(|&(on_s, off_s)| Note {
                    key: 60,
                    velocity,
                    on_s,
                    off_s,
                })
                .collect(),
            sustain: vec![],
            duration_s,
        }
    }

    #[test]
    fn a_restrike_from_a_half_released_key_keeps_the_speed_of_its_velocity() {
        let perf = one_key(25, &[(0.5, 0.52), (0.68, 1.0)], 1.5);
        let dip = 0.01;
        let t = &key_tracks(&perf, dip)[0];
        // The last lowest point between the notes is where the second press starts.
        let (i_low, low) = (5200..6800)
            .map(|i| (i, t.position(i as f64 * 1e-4)))
            .fold((0, f64::INFINITY), |a, b| if b.1 <= a.1 { b } else { a });
        assert!(low > 0.0 && low < dip, "{low}");
        let press_s = 0.68 - i_low as f64 * 1e-4;
        let mean_speed = (dip - low) / press_s;
        let full_speed = dip / descent_time_s(25);
        assert!(
            mean_speed > 0.95 * full_speed && mean_speed < 1.05 * full_speed,
            "re-strike {mean_speed} m/s, full press {full_speed} m/s"
        );
        assert!((t.position(0.68) - dip).abs() < 1e-12);
    }

    #[test]
    fn position_from_a_cursor_equals_position_forward_and_back() {
        let notes = [(0.3, 0.4), (0.5, 0.52), (0.68, 1.0), (1.2, 1.3)];
        let perf = one_key(40, &notes, 1.5);
        let t = &key_tracks(&perf, 0.01)[0];
        let mut cursor = 0;
        // Forward sample by sample, then jumps back and forth (bit-for-bit equal).
        let times = (0..16_000)
            .map(|i| i as f64 * 1e-4)
            .chain([1.0, 0.2, 0.69, 0.0, 1.45, 0.31, 0.31, -1.0, 3.0]);
        for time in times {
            let a = t.position(time);
            let b = t.position_from(time, &mut cursor);
            assert_eq!(a.to_bits(), b.to_bits(), "at {time} s");
        }
    }

    #[test]
    fn a_steady_key_holds_its_travel_until_its_next_move() {
        let notes = [(0.3, 0.4), (0.5, 0.52), (0.68, 1.0), (1.2, 1.3)];
        let perf = one_key(40, &notes, 1.5);
        let t = &key_tracks(&perf, 0.01)[0];
        let (mut cursor, mut steady, mut moving) = (0, 0, 0);
        for i in 0..16_000 {
            let time = i as f64 * 1e-4;
            match t.steady_from(time, &mut cursor) {
                Some((x, until)) => {
                    steady += 1;
                    assert!(until > time, "at {time} s: until {until}");
                    // The same travel, bit for bit, at every time before `until`.
                    let last = if until.is_finite() { until } else { 2.0 };
                    for u in [time, (time + last) / 2.0, last - 1e-9] {
                        assert_eq!(t.position(u).to_bits(), x.to_bits(), "{time} s → {u} s");
                    }
                    assert_eq!(t.position_from(time, &mut cursor).to_bits(), x.to_bits());
                }
                None => {
                    moving += 1;
                    // Moving: a later time nearby has another travel.
                    let (a, b) = (t.position(time), t.position(time + 1e-4));
                    assert!(a != b, "at {time} s: {a} m both");
                }
            }
        }
        assert!(
            steady > 1_000 && moving > 1_000,
            "{steady} steady, {moving} moving"
        );
    }
}
