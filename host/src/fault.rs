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
//! kind=dac-stall,board=1,core=1,at=1s         core 1's DAC takes no more frames
//! kind=hang,note=60,at=1s,until=1.5s          the key's update never returns (`b .`)
//! kind=flip,word=2,bit=30,note=60,at=1s       bit 30 of the key's state word 2 flips
//! kind=brownout,board=1,at=1s                 the supply dips: a power-on reset
//! ```
//!
//! Kinds: `open` (code 0), `short` (full scale), `stuck` (`code=` 0–65535), `jump`
//! (`delta=` −65535–65535 codes), `noise` (`amplitude=` 1–65535 codes, each sample),
//! `adc-silent`, `dac-stall`, `hang`, `flip` (`word=`, `bit=` 0–31), `brownout`. The
//! target: `note=` a MIDI key (0–127), or `board=` (from 1, along the keyboard) with `key=`
//! (from 0, in the board's key order) or `core=` (0 or 1). `at=` and `until=` are times
//! from the run's start: seconds (`1.5`, `1.5s`) or milliseconds (`200ms`). A flip and a
//! brown-out happen once at `at`; the others last until `until`, or to the end. Sensor
//! faults are defined on the key's 16-bit ADC code (`tactus_firmware::image::FaultKind`).
//!
//! Every error names the field, and no number is taken unchecked.

use std::fmt;
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
    "open, short, stuck, jump, noise, adc-silent, dac-stall, hang, flip, brownout";

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
        let by_core = matches!(kind, FaultKind::AdcSilent | FaultKind::DacStall);
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
