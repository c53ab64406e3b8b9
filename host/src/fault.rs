//! The `--fault` syntax of `tactus play` and `tactus emu run` ([`FaultSpec`]), and a spec
//! resolved to one board's [`Injection`] ([`FaultSpec::resolve`]).
//!
//! A fault is comma-separated `field=value` pairs, in any order, each field once:
//!
//! ```text
//! kind=open,note=60,at=0.5s,until=0.8s        the key's sensor reads code 0, then recovers
//! kind=stuck,code=1200,board=2,key=3,at=1s    key 3 (from 0) of board 2 (from 1) stuck
//! kind=noise,amplitude=400,note=64,at=200ms,until=300ms
//! kind=jump,delta=8000,note=60,at=1s          the code plus 8,000 from 1 s on
//! kind=adc-silent,board=1,core=0,at=1s        core 0's ADC answers all ones
//! kind=adc-no-dreq,board=1,core=0,at=1s       core 0's ADC raises no DREQ (converter boards)
//! kind=dac-stall,board=1,core=1,at=1s         core 1's DAC takes no more frames
//! kind=hang,note=60,at=1s,until=1.5s          that key's update never returns (a loop)
//! kind=flip,word=2,bit=30,note=60,at=1s       bit 30 of the key's state word 2 flips
//! kind=brownout,board=1,at=1s                 the supply dips: a power-on reset
//! ```
//!
//! Kinds: `open` (code 0), `short` (full scale), `stuck` (`code=` 0–65535), `jump`
//! (`delta=` −65535–65535 codes), `noise` (`amplitude=` 1–65535 codes, each sample),
//! `adc-silent`, `adc-no-dreq`, `dac-stall`, `hang`, `flip` (`word=`, `bit=` 0–31), `brownout`. The
//! target: `note=` a MIDI key (0–127), or `board=` (from 1, along the keyboard) with `key=`
//! (from 0, in the board's key order) or `core=` (0 or 1). `at=` and `until=` are times
//! from the run's start: seconds (`1.5`, `1.5s`) or milliseconds (`200ms`). A flip and a
//! brown-out happen once at `at`; the others last until `until`, or to the end. Sensor
//! faults are defined on the key's 16-bit ADC code (`tactus_firmware::image::FaultKind`).
//!
//! Every error names the field, and no number is taken unchecked.
//!
//! **The fault report.** After a run, each board's fault records — per core the fault word
//! and the fault time (`tactus_firmware::image::fault`), at the address `keys.json` names
//! `cores[c].fault` — are read from the emulated SRAM ([`read_records`]) and told in lines
//! ([`report_lines`]): one per core that tripped (the kind by name, the key, the time, the
//! trips), and a summary line that is there when nothing tripped too (`faults: 0 trips on
//! 11 boards`).

use std::fmt;
use tactus_firmware::image::fault::{FaultKind as TripKind, FaultWord, NO_KEY, UNKNOWN_KEY};
use tactus_firmware::image::{FaultKind, Injection};

/// Where a fault is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Target {
    /// The key playing this MIDI note (its board found from the keyboard's plan).
    Note(u8),
    /// A key of a board: board from 1, key from 0.
    Key {
        /// The board, from 1.
        board: usize,
        /// The key, from 0 in the board's key order.
        key: usize,
    },
    /// A core of a board (the ADC's and DAC's faults).
    Core {
        /// The board, from 1.
        board: usize,
        /// The core.
        core: usize,
    },
    /// A whole board (a brown-out).
    Board(usize),
}

/// One `--fault` (module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct FaultSpec {
    /// What.
    pub kind: FaultKind,
    /// Where.
    pub target: Target,
    /// When it starts, s from the run's start.
    pub at_s: f64,
    /// When it clears, s (`None`: it does not).
    pub until_s: Option<f64>,
    /// The text it was read from.
    pub text: String,
}

/// A `--fault` that does not parse or resolve: the text, the field and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FaultError {
    /// The `--fault` text.
    pub text: String,
    /// The field (`kind`, `note`, …), or empty for the whole.
    pub field: String,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for FaultError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.field.is_empty() {
            write!(f, "--fault `{}`: {}", self.text, self.message)
        } else {
            write!(
                f,
                "--fault `{}`: field `{}`: {}",
                self.text, self.field, self.message
            )
        }
    }
}

impl std::error::Error for FaultError {}

/// The fault kinds' names, as `kind=` takes them.
pub const KINDS: &str =
    "open, short, stuck, jump, noise, adc-silent, adc-no-dreq, dac-stall, hang, flip, brownout";

/// The longest time a fault may name, s (an hour: longer than any run `play` allows).
const MAX_TIME_S: f64 = 3600.0;

fn time(text: &str) -> Result<f64, String> {
    let (num, scale) = if let Some(n) = text.strip_suffix("ms") {
        (n, 1e-3)
    } else if let Some(n) = text.strip_suffix('s') {
        (n, 1.0)
    } else {
        (text, 1.0)
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a time (seconds, `1.5s`, or `200ms`)"))?;
    let s = v * scale;
    if !s.is_finite() || !(0.0..=MAX_TIME_S).contains(&s) {
        return Err(format!("`{text}`: a time from 0 to {MAX_TIME_S} s"));
    }
    Ok(s)
}

fn int(text: &str, lo: i64, hi: i64) -> Result<i64, String> {
    let v: i64 = text
        .trim()
        .parse()
        .map_err(|_| format!("`{text}` is not a whole number"))?;
    if !(lo..=hi).contains(&v) {
        return Err(format!("{v} is outside {lo}–{hi}"));
    }
    Ok(v)
}

impl std::str::FromStr for FaultSpec {
    type Err = FaultError;

    /// Parses a `--fault` (module documentation).
    fn from_str(text: &str) -> Result<FaultSpec, FaultError> {
        let err = |field: &str, message: String| FaultError {
            text: text.to_string(),
            field: field.to_string(),
            message,
        };
        let mut fields: Vec<(&str, &str)> = Vec::new();
        for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let Some((k, v)) = part.split_once('=') else {
                return Err(err(
                    "",
                    format!("`{part}` is not `field=value` (e.g. `kind=open,note=60,at=1s`)"),
                ));
            };
            let k = k.trim();
            if fields.iter().any(|f| f.0 == k) {
                return Err(err(k, "given twice".into()));
            }
            fields.push((k, v.trim()));
        }
        const KNOWN: [&str; 13] = [
            "kind",
            "note",
            "board",
            "key",
            "core",
            "at",
            "until",
            "code",
            "delta",
            "amplitude",
            "word",
            "bit",
            "channel",
        ];
        if let Some((k, _)) = fields.iter().find(|f| !KNOWN.contains(&f.0)) {
            return Err(err(
                k,
                "unknown field (kind, note, board, key, core, at, until, code, delta, \
                 amplitude, word, bit)"
                    .into(),
            ));
        }
        let get = |k: &str| fields.iter().find(|f| f.0 == k).map(|f| f.1);
        let num = |k: &str, lo: i64, hi: i64| -> Result<Option<i64>, FaultError> {
            get(k)
                .map(|v| int(v, lo, hi).map_err(|m| err(k, m)))
                .transpose()
        };
        let need = |k: &str, lo: i64, hi: i64, kind: &str| -> Result<i64, FaultError> {
            num(k, lo, hi)?.ok_or_else(|| err(k, format!("`kind={kind}` needs `{k}=`")))
        };
        let kind_text = get("kind").ok_or_else(|| err("kind", format!("missing ({KINDS})")))?;
        let kind = match kind_text {
            "open" => FaultKind::Open,
            "short" => FaultKind::Short,
            "stuck" => FaultKind::Stuck(need("code", 0, 65535, "stuck")? as u16),
            "jump" => FaultKind::Jump(need("delta", -65535, 65535, "jump")? as i32),
            "noise" => FaultKind::Noise(need("amplitude", 1, 65535, "noise")? as u16),
            "adc-silent" => FaultKind::AdcSilent,
            "adc-no-dreq" => FaultKind::AdcNoDreq,
            "dac-stall" => FaultKind::DacStall,
            "hang" => FaultKind::Hang,
            "flip" => FaultKind::Flip {
                word: need("word", 0, 1 << 20, "flip")? as u32,
                bit: need("bit", 0, 31, "flip")? as u8,
            },
            "brownout" => FaultKind::BrownOut,
            other => return Err(err("kind", format!("`{other}` is not a fault ({KINDS})"))),
        };
        for (k, needs) in [
            ("code", "stuck"),
            ("delta", "jump"),
            ("amplitude", "noise"),
            ("word", "flip"),
            ("bit", "flip"),
        ] {
            if get(k).is_some() && kind_text != needs {
                return Err(err(k, format!("only `kind={needs}` takes it")));
            }
        }
        if get("channel").is_some() {
            return Err(err(
                "channel",
                "name the key (`note=` or `board=,key=`): its ADC channel follows from the \
                 key map"
                    .into(),
            ));
        }
        let note = num("note", 0, 127)?;
        let board = num("board", 1, 1 << 16)?;
        let key = num("key", 0, 1 << 16)?;
        let core = num("core", 0, 1)?;
        let by_core = matches!(
            kind,
            FaultKind::AdcSilent | FaultKind::AdcNoDreq | FaultKind::DacStall
        );
        let by_board = kind == FaultKind::BrownOut;
        let target = match (note, board, key, core) {
            _ if by_board => match (note, board, key, core) {
                (None, Some(b), None, None) => Target::Board(b as usize),
                _ => return Err(err("board", "`kind=brownout` takes `board=` alone".into())),
            },
            _ if by_core => match (note, board, key, core) {
                (None, Some(b), None, Some(c)) => Target::Core {
                    board: b as usize,
                    core: c as usize,
                },
                _ => {
                    return Err(err(
                        "core",
                        format!("`kind={kind_text}` takes `board=` and `core=`"),
                    ))
                }
            },
            (Some(n), None, None, None) => Target::Note(n as u8),
            (None, Some(b), Some(k), None) => Target::Key {
                board: b as usize,
                key: k as usize,
            },
            (Some(_), ..) => {
                return Err(err("note", "`note=` names the key alone".into()));
            }
            _ => {
                return Err(err(
                    "key",
                    format!("`kind={kind_text}` needs `note=` or `board=` with `key=`"),
                ))
            }
        };
        let at_s = time(get("at").ok_or_else(|| err("at", "missing (e.g. `at=1s`)".into()))?)
            .map_err(|m| err("at", m))?;
        let until_s = get("until")
            .map(|u| time(u).map_err(|m| err("until", m)))
            .transpose()?;
        if let Some(u) = until_s {
            if matches!(kind, FaultKind::Flip { .. } | FaultKind::BrownOut) {
                return Err(err("until", format!("`kind={kind_text}` happens once")));
            }
            if u <= at_s {
                return Err(err("until", "must be after `at`".into()));
            }
        }
        Ok(FaultSpec {
            kind,
            target,
            at_s,
            until_s,
            text: text.to_string(),
        })
    }
}

impl FaultSpec {
    /// The board (from 0) and the injection of this fault on a keyboard whose boards play
    /// the MIDI keys `boards` (each board's keys in its key order), at `fs` samples a
    /// second.
    ///
    /// Errors: a note no board plays, a board or key the keyboard does not have.
    ///
    /// The same on the one board `board` (from 1, as its `keys.json` numbers it) that plays
    /// `keys` (in its key order): [`FaultSpec::resolve_on_board`].
    pub fn resolve(&self, boards: &[Vec<u8>], fs: f64) -> Result<(usize, Injection), FaultError> {
        let err = |field: &str, message: String| FaultError {
            text: self.text.clone(),
            field: field.to_string(),
            message,
        };
        let board_of = |b: usize| {
            if b == 0 || b > boards.len() {
                Err(err(
                    "board",
                    format!("board {b} of a keyboard of {} boards", boards.len()),
                ))
            } else {
                Ok(b - 1)
            }
        };
        let (board, key, core) = match self.target {
            Target::Note(n) => {
                let found = boards
                    .iter()
                    .enumerate()
                    .find_map(|(b, keys)| keys.iter().position(|&k| k == n).map(|k| (b, k)));
                let Some((b, k)) = found else {
                    return Err(err("note", format!("no board plays MIDI key {n}")));
                };
                (b, Some(k), None)
            }
            Target::Key { board, key } => {
                let b = board_of(board)?;
                if key >= boards[b].len() {
                    return Err(err(
                        "key",
                        format!("key {key} of board {board}, which has {}", boards[b].len()),
                    ));
                }
                (b, Some(key), None)
            }
            Target::Core { board, core } => (board_of(board)?, None, Some(core)),
            Target::Board(board) => (board_of(board)?, None, None),
        };
        let sample = |s: f64| (s * fs).ceil() as u64;
        Ok((
            board,
            Injection {
                kind: self.kind,
                key,
                core,
                from: sample(self.at_s),
                until: self.until_s.map(sample),
            },
        ))
    }
}

/// One board's fault records after a run: per core, its fault word and fault time decoded
/// (`tactus_firmware::image::fault::FaultWord`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BoardFaults {
    /// The board, from 1 along the keyboard.
    pub board: usize,
    /// Per core, in core order.
    pub cores: Vec<FaultWord>,
    /// The board's keys by window slot (slot, MIDI key): the fault word names the tripped
    /// key by its slot (`tactus_firmware::image::KeySpec::slot`: on a keyboard's board the
    /// keys take slots from 0 in key order, `keys.json`'s order, a pen one per word).
    pub slots: Vec<(usize, u8)>,
    /// The resets the board met (the watchdog's, a brown-out), each at its sample: a reset
    /// board's motors are at zero force from the reset until its firmware runs again, or
    /// from then on when it does not boot again (a RAM image, which `play` runs, after a
    /// brown-out: SRAM lost, the boot ROM in USB boot).
    pub resets: Vec<tactus_firmware::image::ResetRecord>,
}

impl BoardFaults {
    /// Trips on the board since power-on (its cores' counts summed).
    pub fn trips(&self) -> u64 {
        self.cores.iter().map(|c| u64::from(c.trips)).sum()
    }

    /// The MIDI key of a tripped fault word's key field, if it names a key of the board.
    pub fn midi(&self, w: &FaultWord) -> Option<u8> {
        (w.tripped() && w.key != NO_KEY)
            .then(|| self.slots.iter().find(|s| s.0 == usize::from(w.key)))
            .flatten()
            .map(|s| s.1)
    }

    /// The key a fault word names, in words: `key 64 (E4)` (a watchdog trip's: the key whose
    /// update hung; a hard-fault trip's: the key whose update faulted), `every key of the core …` (an `adc-stall`), `the whole board`, `an unknown key` (a watchdog trip whose hung key the
    /// firmware could not name, `tactus_firmware::image::fault`, "Which key hung"), or the
    /// slot when the board has no key there.
    fn key_text(&self, w: &FaultWord) -> String {
        match (w.key, self.midi(w)) {
            (NO_KEY, _) if w.kind == Some(TripKind::AdcStall) => {
                "every key of the core (its ADC's burst did not finish)".to_string()
            }
            (NO_KEY, _) => "the whole board".to_string(),
            (UNKNOWN_KEY, _) => "an unknown key".to_string(),
            (_, Some(k)) => format!("key {k} ({})", tactus_firmware::budget::note_name(k)),
            (s, None) => format!("window slot {s} (no key of the board)"),
        }
    }

    /// The sample a fault word's last trip is reported at. A watchdog trip is recorded by
    /// the reset handler at the boot after the reset, when the core's sample count starts
    /// again from 0 (`tactus_firmware::image::fault`): its time is the sample of the
    /// board's last watchdog reset in [`BoardFaults::resets`] (the firmware's 0 when the
    /// board met none). A HardFault trip resets the board at once through the watchdog's
    /// trigger: its time is the sample of the board's last `watchdog trigger` reset (the
    /// fault word's own time, the firmware's count since its last boot, when it met none).
    /// Every other kind: the fault word's own time.
    pub fn trip_sample(&self, w: &FaultWord) -> u64 {
        let watchdog = (self.resets.iter().rev()).find(|r| r.by_watchdog());
        let trigger = (self.resets.iter().rev()).find(|r| r.by_trigger());
        match (w.kind, watchdog, trigger) {
            (Some(TripKind::Watchdog), Some(r), _) => r.sample,
            (Some(TripKind::HardFault), _, Some(r)) => r.sample,
            _ => u64::from(w.at_sample),
        }
    }
}

impl BoardFaults {
    /// The line of a board that booted again after a reset: why its firmware recorded the
    /// boot (core 0's reset word, `tactus_firmware::image::fault`, "The reset word"). After
    /// a brown-out the word says a power-on or brown-out, which the RP2040 cannot tell
    /// apart; the run, which started before, names it a brown-out, and says that the trips
    /// before it were lost with SRAM. `None` for a board without a reset it booted again
    /// from.
    pub fn boot_line(&self) -> Option<String> {
        let last = self.resets.iter().rev().find(|r| r.reboot.is_ok())?;
        let w = self.cores.first()?;
        let cause = w.reset_cause();
        let after = match (last.by_brown_out(), cause) {
            (true, tactus_firmware::image::fault::ResetCause::PowerOn) => format!(
                ": the brown-out at sample {} (the board ran before it; its trips before it \
                 were lost with SRAM and the scratch registers)",
                last.sample
            ),
            (false, tactus_firmware::image::fault::ResetCause::Watchdog) => {
                format!(": the watchdog's reset at sample {}", last.sample)
            }
            _ => format!(
                " (the run's last reset: {} at sample {})",
                last.why, last.sample
            ),
        };
        Some(format!(
            "board {}: its firmware recorded its last boot from {} (reset word {:#010x}){after}",
            self.board,
            cause.text(),
            w.reset_word
        ))
    }
}

/// Reads the fault record at each of `addrs` (one per core: the fault word, the fault time,
/// the reset word) through `read` (a word of the emulated board's memory), decoded.
///
/// Errors: what `read` returns, naming the core.
pub fn read_records(
    read: &mut dyn FnMut(u32) -> Result<u32, String>,
    addrs: &[u32],
) -> Result<Vec<FaultWord>, String> {
    let records = (addrs.iter().enumerate())
        .map(|(c, &a)| {
            let word = read(a).map_err(|e| format!("core {c}'s fault word: {e}"))?;
            let at = read(a.wrapping_add(4)).map_err(|e| format!("core {c}'s fault time: {e}"))?;
            let boot =
                read(a.wrapping_add(8)).map_err(|e| format!("core {c}'s reset word: {e}"))?;
            Ok([word, at, boot])
        })
        .collect::<Result<Vec<_>, String>>()?;
    Ok(decode(&records))
}

/// A fault word's kind as the report names it: the kind's name, or the code when it is
/// none of the known kinds.
pub fn kind_name(w: &FaultWord) -> String {
    match w.kind {
        Some(k) => k.name().to_string(),
        None => format!("unknown kind {}", w.code),
    }
}

/// The fault report of a run on `boards`, at `fs` samples a second: a line per core that
/// tripped (`board 4 core 1: sensor-range on key 60 (C4) at sample 44100 (1.000 s), 1
/// trip`), then the summary line (`faults: 0 trips on 11 boards`, or the trips and on how
/// many boards). Lines are not indented.
pub fn report_lines(boards: &[BoardFaults], fs: f64) -> Vec<String> {
    let mut lines = Vec::new();
    for b in boards {
        for (c, w) in b.cores.iter().enumerate().filter(|(_, w)| w.tripped()) {
            let key = b.key_text(w);
            let at = b.trip_sample(w);
            lines.push(format!(
                "board {} core {c}: {} on {key} at sample {at} ({:.4} s), {} trip{}",
                b.board,
                kind_name(w),
                at as f64 / fs.max(1.0),
                w.trips,
                if w.trips == 1 { "" } else { "s" }
            ));
        }
    }
    lines.extend(boards.iter().filter_map(BoardFaults::boot_line));
    let trips: u64 = boards.iter().map(BoardFaults::trips).sum();
    let resets: usize = boards.iter().map(|b| b.resets.len()).sum();
    let hit = (boards.iter())
        .filter(|b| b.trips() > 0 || !b.resets.is_empty())
        .count();
    let n = boards.len();
    let plural = |k: u64| if k == 1 { "" } else { "S" };
    lines.push(match (trips, resets) {
        (0, 0) => format!("faults: 0 trips on {n} board{}", if n == 1 { "" } else { "s" }),
        (t, 0) => format!(
            "faults: {t} TRIP{} on {hit} of {n} boards (the firmware's checks set these motors to zero force)",
            plural(t)
        ),
        (t, r) => format!(
            "faults: {t} {}, {r} RESET{} on {hit} of {n} boards (a reset board's motors at zero force{})",
            if t == 0 { "trips".to_string() } else { format!("TRIP{}", plural(t)) },
            plural(r as u64),
            if t == 0 { "" } else { "; the firmware's checks set the tripped keys' motors to zero force" }
        ),
    });
    lines
}

/// The columns of a run's fault file (`OUT/NAME-faults.csv`, [`csv_text`]).
pub const CSV_HEADER: &str = "board,core,kind,code,slot,key,trips,at_sample,at_s,boot";

/// The fault records as CSV ([`CSV_HEADER`]): one row per core of every board, tripped or
/// not (kind `none`, trips 0): the fault word's key field (`slot`) and its MIDI key (empty
/// when it names none); `at_s` at `fs` Hz; `boot` the core's reset word's cause
/// (`tactus_firmware::image::fault::ResetCause::name`: `power-on` on a board that never
/// reset, and after a brown-out).
pub fn csv_text(boards: &[BoardFaults], fs: f64) -> String {
    let mut s = format!("{CSV_HEADER}\n");
    for b in boards {
        for (c, w) in b.cores.iter().enumerate() {
            let key = b.midi(w).map_or(String::new(), |k| k.to_string());
            let at = b.trip_sample(w);
            s.push_str(&format!(
                "{},{c},{},{},{},{key},{},{at},{:.6},{}\n",
                b.board,
                kind_name(w),
                w.code,
                w.key,
                w.trips,
                at as f64 / fs.max(1.0),
                w.reset_cause().name()
            ));
        }
    }
    s
}

/// The names of the trip kinds, for help texts: every [`TripKind`] but `none`.
pub fn trip_kinds() -> String {
    (TripKind::ALL.iter().filter(|k| **k != TripKind::None))
        .map(|k| k.name())
        .collect::<Vec<_>>()
        .join(", ")
}

impl FaultSpec {
    /// The injection of this fault on the one board numbered `board` (from 1 along its
    /// keyboard, `keys.json`'s `board`) whose keys are `keys` (MIDI, in its key order), at
    /// `fs` samples a second: what `tactus emu run --fault` runs on one board's firmware.
    ///
    /// Errors: a `board=` that is not this board, a note it does not play, a key it does
    /// not have.
    pub fn resolve_on_board(
        &self,
        board: usize,
        keys: &[u8],
        fs: f64,
    ) -> Result<Injection, FaultError> {
        let err = |field: &str, message: String| FaultError {
            text: self.text.clone(),
            field: field.to_string(),
            message,
        };
        let named = match self.target {
            Target::Note(n) if !keys.contains(&n) => {
                return Err(err(
                    "note",
                    format!(
                        "board {board} does not play MIDI key {n} (its keys: {})",
                        tactus_firmware::verdict::key_ranges(keys)
                    ),
                ))
            }
            Target::Note(_) => None,
            Target::Key { board: b, .. } | Target::Core { board: b, .. } | Target::Board(b) => {
                Some(b)
            }
        };
        if let Some(b) = named.filter(|&b| b != board) {
            return Err(err(
                "board",
                format!("board {b}: this firmware is board {board} (its keys.json)"),
            ));
        }
        let one = |b: usize| if named.is_some() { 1 } else { b };
        let spec = FaultSpec {
            target: match self.target {
                Target::Key { board: b, key } => Target::Key { board: one(b), key },
                Target::Core { board: b, core } => Target::Core {
                    board: one(b),
                    core,
                },
                Target::Board(b) => Target::Board(one(b)),
                t => t,
            },
            ..self.clone()
        };
        spec.resolve(&[keys.to_vec()], fs).map(|(_, i)| i)
    }
}

/// The fault records of a board's run now: per core of its image, the fault word and time
/// at its control block's record (`tactus_firmware::image::glue::ctrl::fault_record`),
/// read from the emulated SRAM ([`read_records`]). What `play`, `emu run` and `corpus
/// trips` report. A board that a brown-out left without firmware (a RAM image: SRAM lost,
/// the boot ROM in USB boot) has no record: SRAM holds the power-on pattern there, and the
/// scratch registers were cleared with it; its cores report none (the reset's line says
/// why).
///
/// Errors: a record the board cannot read, naming the core.
pub fn run_records(
    run: &mut tactus_firmware::image::ImageRun,
) -> Result<Vec<tactus_firmware::image::fault::FaultWord>, String> {
    let image = run.image();
    if (run.resets().last()).is_some_and(|r| r.by_brown_out() && r.reboot.is_err()) {
        return Ok(decode(&vec![[0, 0, 0]; image.cores()]));
    }
    let addrs: Vec<u32> = (0..image.cores())
        .filter_map(|c| {
            (image.core_addresses(c))
                .map(|a| tactus_firmware::image::glue::ctrl::fault_record(a[3]))
        })
        .collect();
    let board = run.board();
    read_records(
        &mut |a| board.read_u32(a).map_err(|e| e.to_string()),
        &addrs,
    )
}

/// A board's keys by window slot ([`BoardFaults::slots`]): the slot of each key of `image`
/// with its MIDI key (`midi`, in the image's key order).
pub fn image_slots(image: &tactus_firmware::image::FirmwareImage, midi: &[u8]) -> Vec<(usize, u8)> {
    (image.keys().iter().zip(midi))
        .map(|(s, &k)| (s.slot, k))
        .collect()
}

/// A reset a board met, in words, at `fs` samples a second: `watchdog timer reset at t =
/// 1.0000 s (sample 44100, cycle …): booted again, 12 samples at zero force after the
/// reset's own (13 in all)` — the run gives the reset's sample at zero force, then
/// [`tactus_firmware::image::ResetRecord::reboot`] more while the firmware boots —, or that
/// the board held at zero force from then on, since it did not boot again, and why.
pub fn reset_text(reset: &tactus_firmware::image::ResetRecord, fs: f64) -> String {
    let after = match &reset.reboot {
        Ok(n) => format!(
            "booted again, {n} samples at zero force after the reset's own ({} in all)",
            n + 1
        ),
        Err(e) => format!("the board held at zero force from then (it did not boot again: {e})"),
    };
    format!(
        "{} reset at t = {:.4} s (sample {}, cycle {}): {after}",
        reset.why,
        reset.sample as f64 / fs.max(1.0),
        reset.sample,
        reset.cycle
    )
}

/// A hung update (`kind=hang`) injected on a key that stands still when it begins. The
/// firmware's quiescent-key guard skips the update of a key whose sensors and state stand
/// still, and the hang loops at that key's own calls of its update
/// (`tactus_firmware::image::FaultKind::Hang`), so it takes effect when the key's update
/// next runs: at the latest when the key next moves, sooner while its state still settles,
/// or maybe never when it rests until the fault clears or the run ends (docs/faults.md:
/// hang a key that moves). `tactus play` and `tactus emu run` find it by this one rule
/// ([`RestingHang::of`]) and warn of it in these words ([`RestingHang::warning`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RestingHang {
    /// The `--fault` as given.
    pub fault: String,
    /// The key (MIDI).
    pub key: u8,
    /// When the hang begins, s.
    pub at_s: f64,
    /// When the key next moves within the fault's window, s (the clock of `at_s`); `None`:
    /// not before the fault clears or the run ends.
    pub moves_at_s: Option<f64>,
}

impl RestingHang {
    /// The hang `fault` on `key` from `from_s` to `until_s` (s; the run's end when it does
    /// not clear) whose key's sensor next moves at `next_s` (at or after `from_s`; infinite
    /// when it never does), at `fs` samples a second, if the key stands still when the
    /// hang begins: it does not move within a sample of `from_s`. The times keep the
    /// caller's clock.
    pub fn of(
        fault: &str,
        key: u8,
        from_s: f64,
        until_s: f64,
        next_s: f64,
        fs: f64,
    ) -> Option<RestingHang> {
        (next_s > from_s + 1.0 / fs).then(|| RestingHang {
            fault: fault.to_string(),
            key,
            at_s: from_s,
            moves_at_s: (next_s < until_s).then_some(next_s),
        })
    }

    /// The warning: the key stands still, the guard skips its update, and when the hang
    /// takes effect (docs/faults.md).
    pub fn warning(&self) -> String {
        let key = format!(
            "key {} ({})",
            self.key,
            tactus_firmware::budget::note_name(self.key)
        );
        let when = match self.moves_at_s {
            None => "it does not move before the fault ends: the hang may never run (only while the key's state still settles)".to_string(),
            Some(t) => format!(
                "the hang takes effect when its update next runs: at the latest when the key next moves, at {t:.3} s"
            ),
        };
        format!(
            "--fault {}: {key} stands still at {:.3} s, and the quiescent-key guard skips the update of a key whose sensor and state stand still (the hang loops at that key's calls of its update); {when}. Hang a key that moves (docs/faults.md)",
            self.fault, self.at_s
        )
    }
}

/// Decodes each core's raw fault record (the fault word, the fault time, the reset word).
pub fn decode(records: &[[u32; 3]]) -> Vec<FaultWord> {
    records
        .iter()
        .map(|&r| FaultWord::decode_record(r))
        .collect()
}

/// `, N samples unfinished (…)` for a core that had not finished `n` > 0 samples by the
/// next tick (a hung handler: `tactus_firmware::image::ImageRun::unfinished`), else
/// nothing: the same words in `play` and `emu run`.
pub fn unfinished_text(n: u64) -> String {
    match n {
        0 => String::new(),
        n => format!(
            ", {n} sample{} unfinished (a handler that never returned, cut by a reset: not a handler time, in neither max nor mean)",
            if n == 1 { "" } else { "s" }
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> FaultError {
        text.parse::<FaultSpec>().unwrap_err()
    }

    #[test]
    fn each_kind_parses_with_its_target_and_times() {
        let f: FaultSpec = "kind=open,note=60,at=0.5s,until=800ms".parse().unwrap();
        assert_eq!(f.kind, FaultKind::Open);
        assert_eq!(f.target, Target::Note(60));
        assert_eq!((f.at_s, f.until_s), (0.5, Some(0.8)));
        let f: FaultSpec = "at=1,kind=stuck,code=1200,board=2,key=3".parse().unwrap();
        assert_eq!(f.kind, FaultKind::Stuck(1200));
        assert_eq!(f.target, Target::Key { board: 2, key: 3 });
        let f: FaultSpec = "kind=adc-silent,board=1,core=1,at=0".parse().unwrap();
        assert_eq!(f.target, Target::Core { board: 1, core: 1 });
        let f: FaultSpec = "kind=adc-no-dreq,board=2,core=0,at=1s,until=2s"
            .parse()
            .unwrap();
        assert_eq!(f.kind, FaultKind::AdcNoDreq);
        assert_eq!(f.target, Target::Core { board: 2, core: 0 });
        assert_eq!(err("kind=adc-no-dreq,note=60,at=1s").field, "core");
        let f: FaultSpec = "kind=flip,word=2,bit=31,note=21,at=2s".parse().unwrap();
        assert_eq!(f.kind, FaultKind::Flip { word: 2, bit: 31 });
        let f: FaultSpec = "kind=brownout,board=4,at=1s".parse().unwrap();
        assert_eq!(f.target, Target::Board(4));
        let f: FaultSpec = "kind=jump,delta=-500,note=60,at=1s".parse().unwrap();
        assert_eq!(f.kind, FaultKind::Jump(-500));
    }

    #[test]
    fn bad_faults_name_their_field() {
        for (text, field) in [
            ("kind=opne,note=60,at=1s", "kind"),
            ("note=60,at=1s", "kind"),
            ("kind=open,note=128,at=1s", "note"),
            ("kind=open,note=60", "at"),
            ("kind=open,note=60,at=-1s", "at"),
            ("kind=open,note=60,at=NaN", "at"),
            ("kind=open,note=60,at=1e400", "at"),
            ("kind=open,note=60,at=1s,until=0.5s", "until"),
            ("kind=stuck,note=60,at=1s", "code"),
            ("kind=stuck,code=70000,note=60,at=1s", "code"),
            ("kind=noise,amplitude=0,note=60,at=1s", "amplitude"),
            ("kind=flip,word=1,bit=32,note=60,at=1s", "bit"),
            ("kind=flip,word=1,bit=3,note=60,at=1s,until=2s", "until"),
            ("kind=open,code=5,note=60,at=1s", "code"),
            ("kind=open,note=60,note=61,at=1s", "note"),
            ("kind=open,velocity=3,note=60,at=1s", "velocity"),
            ("kind=adc-silent,note=60,at=1s", "core"),
            ("kind=open,board=1,at=1s", "key"),
            ("kind=open,board=0,key=1,at=1s", "board"),
            ("kind=brownout,note=60,at=1s", "board"),
        ] {
            let e = err(text);
            assert_eq!(e.field, field, "{text}: {e}");
            assert!(e.to_string().contains(text), "{e}");
        }
        assert_eq!(err("open").field, "", "not field=value");
    }

    #[test]
    fn fault_records_are_read_and_reported() {
        let mem = [
            (
                0x2000_0014u32,
                FaultWord::encode(TripKind::SensorRange, 3, 2),
            ),
            (0x2000_0018, 44_100),
            (0x2000_001c, 0),
            (0x2000_0114, 0),
            (0x2000_0118, 0),
            (0x2000_011c, 0),
        ];
        let mut read =
            |a: u32| (mem.iter().find(|m| m.0 == a).map(|m| m.1)).ok_or_else(|| format!("{a:#x}"));
        let cores = read_records(&mut read, &[0x2000_0014, 0x2000_0114]).unwrap();
        assert_eq!(cores[0].kind, Some(TripKind::SensorRange));
        assert_eq!(
            (cores[0].key, cores[0].trips, cores[0].at_sample),
            (3, 2, 44_100)
        );
        assert!(!cores[1].tripped());
        assert!(read_records(&mut read, &[0x2000_0200])
            .unwrap_err()
            .contains("core 0"));
        let slots: Vec<(usize, u8)> = (0..8).map(|s| (s, 57 + s as u8)).collect();
        let boards = [
            BoardFaults {
                board: 1,
                cores: vec![cores[1]; 2],
                slots: slots.clone(),
                resets: Vec::new(),
            },
            BoardFaults {
                board: 2,
                cores,
                slots,
                resets: Vec::new(),
            },
        ];
        let lines = report_lines(&boards, 44_100.0);
        assert_eq!(
            lines[0],
            "board 2 core 0: sensor-range on key 60 (C4) at sample 44100 (1.0000 s), 2 trips"
        );
        assert!(
            lines[1].starts_with("faults: 2 TRIPS on 1 of 2 boards"),
            "{}",
            lines[1]
        );
        let csv = csv_text(&boards, 44_100.0);
        assert!(
            csv.contains("\n2,0,sensor-range,1,3,60,2,44100,1.000000,unrecorded\n"),
            "{csv}"
        );
        assert!(
            csv.contains("\n1,1,none,0,0,,0,0,0.000000,unrecorded\n"),
            "{csv}"
        );
        assert_eq!(
            report_lines(&boards[..1], 44_100.0),
            ["faults: 0 trips on 1 board"]
        );
        // A board reset by its watchdog, its RAM image not booting again: counted, and said
        // in words with its time.
        let reset = tactus_firmware::image::ResetRecord {
            sample: 13_230,
            cycle: 40_044_705,
            why: "watchdog timer",
            reboot: Err("the board stopped: Idle".into()),
        };
        let mut reset_board = boards[0].clone();
        reset_board.resets.push(reset.clone());
        assert_eq!(
            report_lines(&[reset_board.clone()], 44_100.0),
            ["faults: 0 trips, 1 RESET on 1 of 1 boards (a reset board's motors at zero force)"]
        );
        assert_eq!(
            reset_text(&reset, 44_100.0),
            "watchdog timer reset at t = 0.3000 s (sample 13230, cycle 40044705): the board \
             held at zero force from then (it did not boot again: the board stopped: Idle)"
        );
        let both = [boards[1].clone(), reset_board];
        assert!(
            report_lines(&both, 44_100.0)[1]
                .starts_with("faults: 2 TRIPS, 1 RESET on 2 of 2 boards"),
            "{:?}",
            report_lines(&both, 44_100.0)
        );
        // A watchdog trip (recorded at the boot after the reset, at the core's sample 0) is
        // reported at the board's last watchdog reset; with none, at the record's own time.
        let hung = FaultWord::decode(FaultWord::encode(TripKind::Watchdog, 2, 2), 0);
        let mut hung_board = BoardFaults {
            board: 3,
            cores: vec![hung, boards[0].cores[0]],
            slots: boards[0].slots.clone(),
            resets: Vec::new(),
        };
        assert_eq!(hung_board.trip_sample(&hung), 0);
        let watchdog_reset = |sample| tactus_firmware::image::ResetRecord {
            sample,
            reboot: Ok(5),
            ..reset.clone()
        };
        hung_board.resets = vec![watchdog_reset(13_230), watchdog_reset(13_236)];
        assert_eq!(
            report_lines(std::slice::from_ref(&hung_board), 44_100.0)[0],
            "board 3 core 0: watchdog on key 59 (B3) at sample 13236 (0.3001 s), 2 trips"
        );
        assert!(
            csv_text(std::slice::from_ref(&hung_board), 44_100.0)
                .contains("\n3,0,watchdog,4,2,59,2,13236,0.300136,unrecorded\n"),
            "{}",
            csv_text(std::slice::from_ref(&hung_board), 44_100.0)
        );
        // The firmware's reset word, on the line of a board that booted again: after a
        // watchdog reset the watchdog (REASON.TIMER, HAD_POR kept from the power-on), after
        // a brown-out a power-on, which the run names a brown-out.
        hung_board.cores[0].reset_word = 0x101;
        assert_eq!(
            hung_board.boot_line().unwrap(),
            "board 3: its firmware recorded its last boot from the watchdog (reset word \
             0x00000101): the watchdog's reset at sample 13236"
        );
        let mut browned = hung_board.clone();
        browned.cores[0] = FaultWord::decode_record([0, 0, 0x100]);
        browned.resets.push(tactus_firmware::image::ResetRecord {
            sample: 20_000,
            why: "brown-out",
            ..watchdog_reset(0)
        });
        assert_eq!(
            report_lines(std::slice::from_ref(&browned), 44_100.0)[0],
            "board 3: its firmware recorded its last boot from a power-on or brown-out (reset \
             word 0x00000100): the brown-out at sample 20000 (the board ran before it; its \
             trips before it were lost with SRAM and the scratch registers)"
        );
        assert!(csv_text(std::slice::from_ref(&browned), 44_100.0).contains(",power-on\n"));
        assert_eq!(boards[0].boot_line(), None, "no reset");
        // A sensor trip keeps its own time beside a watchdog reset.
        let mut sensor_board = boards[1].clone();
        sensor_board.resets = hung_board.resets.clone();
        assert_eq!(sensor_board.trip_sample(&sensor_board.cores[0]), 44_100);
        assert_eq!(
            tactus_firmware::image::glue::ctrl::fault_record(0x2003_f000),
            0x2003_f014
        );
    }

    #[test]
    fn a_fault_resolves_to_its_board_and_samples() {
        let boards = vec![vec![21, 22, 23], vec![24, 25]];
        let f: FaultSpec = "kind=short,note=25,at=0.5s,until=1s".parse().unwrap();
        let (b, i) = f.resolve(&boards, 1000.0).unwrap();
        assert_eq!((b, i.key, i.from, i.until), (1, Some(1), 500, Some(1000)));
        let f: FaultSpec = "kind=short,note=60,at=0.5s".parse().unwrap();
        assert_eq!(f.resolve(&boards, 1000.0).unwrap_err().field, "note");
        let f: FaultSpec = "kind=short,board=3,key=0,at=0.5s".parse().unwrap();
        assert_eq!(f.resolve(&boards, 1000.0).unwrap_err().field, "board");
        let f: FaultSpec = "kind=short,board=2,key=2,at=0.5s".parse().unwrap();
        assert_eq!(f.resolve(&boards, 1000.0).unwrap_err().field, "key");
    }
}
