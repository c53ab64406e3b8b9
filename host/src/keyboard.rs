//! The one resolution and compilation of a keyboard, for `tactus build`, `tactus budget`
//! and `tactus play`.
//!
//! A keyboard is given as a [`KeyboardSpec`]: a layout file (`*.toml`), a built-in layout
//! (`grand88`), or one instrument (a file or a built-in name) on N keys from A0 up, plus a
//! board kind and `--param` overrides. [`compile`] resolves it to one
//! [`KeyAssignment`] per key (the overrides last), reads the board (the spec's, else the
//! layout's `board_kind`, else [`catalogue::DEFAULT_BOARD`]), and lowers every distinct
//! (instrument, params) once, for the board's sample rate, reporting each source's
//! diagnostics once. [`Keyboard::firmware`] compiles the distinct sets to the firmware's
//! programs (an instrument's graded params become run-time data:
//! [`tactus_firmware::image::compile_shared`]); [`Keyboard::played`] gives `play` the keys
//! a performance plays.

use crate::catalogue::{self, Source};
use crate::play::{self, HostProgram};
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use tactus_compiler::diagnostics::Diagnostic;
use tactus_compiler::ir::Program;
use tactus_firmware::boards::{self, KeyboardPlan};
use tactus_firmware::image::Program as FirmwareProgram;
use tactus_firmware::verdict::{self, ProgramInput};
use tactus_runtime::keyboard::{self as layout_file, BoardSpec, KeyAssignment, Layout};
use tactus_runtime::limiter::LimiterConfig;

/// A path as written into a plan: absolute when it names an existing file (relative to
/// `dir` when given), else as it is (a built-in name).
fn absolute(s: &str, dir: Option<&Path>) -> String {
    let p = dir.map_or_else(|| PathBuf::from(s), |d| d.join(s));
    match p.canonicalize() {
        Ok(abs) if p.exists() => abs.display().to_string(),
        _ => s.to_string(),
    }
}

/// The most keys a single instrument may be given (`--keys`): the MIDI key numbers.
pub const MAX_KEYS: u32 = 128;

/// What a keyboard is made of, as a command's arguments give it.
#[derive(Clone, Copy, Debug)]
pub struct KeyboardSpec<'a> {
    /// A layout file (`.toml`), a built-in layout's name, or an instrument (a file or a
    /// built-in name).
    pub input: &'a str,
    /// Whether `input` is a layout (`Some(true)`: `tactus play --layout`), an instrument
    /// (`Some(false)`: `--instrument`), or to be told by its name (`None`: [`is_layout`]).
    pub as_layout: Option<bool>,
    /// The board kind (a built-in name or a board file); `None`: the layout's
    /// `board_kind`, else [`catalogue::DEFAULT_BOARD`].
    pub board: Option<&'a str>,
    /// For an instrument: how many keys, from MIDI 21 (A0) up (from MIDI 0 when that would
    /// pass key 127); `None`: 88, or 1 for a pen. An error with a layout.
    pub keys: Option<u32>,
    /// Overrides of every key's params, `(name, value with unit)`, applied after the
    /// layout's own.
    pub params: &'a [(String, String)],
}

/// Why a keyboard cannot be made. Every message names the input and, where there is one,
/// the file and the field or the key.
#[derive(Debug, thiserror::Error)]
pub enum KeyboardError {
    /// A bad layout, board, instrument name or count.
    #[error("{0}")]
    Input(String),
    /// An instrument does not compile for one of its keys (its diagnostics went to the
    /// reporter).
    #[error(
        "{input}: key {key}: `{instrument}` does not compile with params {params} for the \
         board's sample rate, {fs} Hz (`{kind}`; see the diagnostics above)"
    )]
    Compile {
        /// The keyboard's input.
        input: String,
        /// The first key (MIDI) of the set.
        key: u8,
        /// The instrument as the layout names it.
        instrument: String,
        /// The set's params, shown.
        params: String,
        /// The board's sample rate, Hz.
        fs: f64,
        /// The board kind.
        kind: String,
    },
    /// The fixed-point or Thumb compilation of a set failed, or its plan breaks its
    /// accuracy contract.
    #[error("{source_name}: {message}")]
    Firmware {
        /// The source of the set.
        source_name: String,
        /// What failed.
        message: String,
    },
    /// A played key's instrument is not one `play` can move.
    #[error("{0}")]
    NotPlayable(String),
}

/// One distinct (instrument, params) of a keyboard, lowered.
#[derive(Clone, Debug)]
pub struct ProgramSet {
    /// The instrument as the layout names it (built-in name or path).
    pub instrument: String,
    /// Its params: the layout's, then the spec's overrides ([`with_overrides`]).
    pub params: Vec<(String, String)>,
    /// Its source.
    pub source: Source,
    /// Its program, lowered for the board's sample rate.
    pub ir: Program,
}

/// A keyboard resolved and lowered: see the module documentation.
#[derive(Clone, Debug)]
pub struct Keyboard {
    /// The layout's name, or `INSTRUMENT × N`.
    pub name: String,
    /// The input as given.
    pub input: String,
    /// The layout and its file (empty for a built-in layout), if the input is a layout.
    pub layout: Option<(Layout, PathBuf)>,
    /// The board kind as resolved (a name or a path).
    pub kind: String,
    /// The board.
    pub board: BoardSpec,
    /// Every key, ascending, with its instrument and params (the spec's overrides last,
    /// replacing the layout's values of the same params: [`with_overrides`]).
    pub keys: Vec<KeyAssignment>,
    /// `sets[key_set[i]]` is `keys[i]`'s program.
    pub key_set: Vec<usize>,
    /// The distinct (instrument, params), in order of first key.
    pub sets: Vec<ProgramSet>,
    /// The layout's own boards (MIDI keys per board), or `None` to plan them.
    pub boards: Option<Vec<Vec<u8>>>,
    /// The spec's overrides of every key's params (already in [`Keyboard::keys`]).
    pub overrides: Vec<(String, String)>,
    /// The firmware's sensor check on or off on every key
    /// (`tactus_firmware::image::Program::sensor_check`, set by [`Keyboard::firmware`] and
    /// so planned and priced with it: `--sensor-check`); `None`: the programs' default.
    pub sensor_check: Option<bool>,
    /// The firmware's watchdog on or off on every board
    /// (`tactus_firmware::image::Program::watchdog`: fed by core 0 when both cores finished
    /// their sample, so a hung core resets the board), set by [`Keyboard::firmware`] and so
    /// planned and priced with it (`--watchdog`); `None`: the programs' default.
    pub watchdog: Option<bool>,
}

/// The one spelling of a firmware option's state ([`Keyboard::sensor_check`],
/// [`Keyboard::watchdog`]) in what `tactus` prints: `on` or `off`, the words
/// `--sensor-check` and `--watchdog` take.
pub fn on_off(on: bool) -> &'static str {
    if on {
        "on"
    } else {
        "off"
    }
}

/// Receives a source's diagnostics: its warnings when it compiles, its errors (and
/// warnings) when it does not. Called once per distinct set at most.
pub type Reporter<'r> = dyn FnMut(&Source, &[Diagnostic]) + 'r;

/// Lowers `src` with `params` for a board sampling at `fs` Hz, handing its diagnostics to
/// `report`; `None` when it does not compile.
pub fn lower(
    src: &Source,
    params: &[(String, String)],
    fs: f64,
    report: &mut Reporter,
) -> Option<tactus_compiler::lower::Lowered> {
    let config = tactus_compiler::lower::Config {
        overrides: params.to_vec(),
        sample_rate_hz: fs,
    };
    match tactus_compiler::compile_linked(&src.linked, &config) {
        Ok(l) => {
            if !l.warnings.is_empty() {
                report(src, &l.warnings);
            }
            Some(l)
        }
        Err(d) => {
            report(src, &d);
            None
        }
    }
}

/// Whether `input` names a layout: a `.toml` path, or a built-in layout's name that is not
/// a file or a built-in instrument.
pub fn is_layout(input: &str) -> bool {
    input.ends_with(".toml")
        || (catalogue::layout(input).is_some()
            && !Path::new(input).exists()
            && !catalogue::INSTRUMENTS.iter().any(|(n, _)| *n == input))
}

/// A layout resolved key by key: (layout, its file, keys, its boards).
type LayoutKeys = (Layout, PathBuf, Vec<KeyAssignment>, Option<Vec<Vec<u8>>>);

fn read_layout(input: &str) -> Result<LayoutKeys, String> {
    let (layout, path, keys, name) = match catalogue::layout(input) {
        Some(text) if !Path::new(input).exists() => {
            let name = format!("builtin:{input}");
            let l = layout_file::parse_layout(text, &name)?;
            let keys = layout_file::assign(&l, &name, Path::new(""))?;
            (l, PathBuf::new(), keys, name)
        }
        _ => {
            let path = Path::new(input);
            let (l, keys) = layout_file::read_layout(path)?;
            (l, path.to_path_buf(), keys, input.to_string())
        }
    };
    let boards = layout_file::board_keys(&layout, &name, &keys)?;
    Ok((layout, path, keys, boards))
}

/// Key `key` (a MIDI number) of the layout `input` (a `.toml` path or a built-in layout's
/// name, as [`is_layout`] reads it): its instrument and its params, grades resolved, as a
/// keyboard compiles that key (`tactus regulate --layout grand88 --key 21`).
///
/// Errors, as messages: a bad layout (its file and field), or a key it does not assign.
pub fn layout_key(input: &str, key: u8) -> Result<KeyAssignment, String> {
    let (_, _, keys, _) = read_layout(input)?;
    let span = match (keys.first(), keys.last()) {
        (Some(a), Some(b)) => format!("keys {}–{}", a.key, b.key),
        _ => "no keys".to_string(),
    };
    keys.into_iter().find(|k| k.key == key).ok_or_else(|| {
        format!("layout `{input}` assigns no instrument to key {key} (it has {span})")
    })
}

/// `params` with `overrides` applied in turn: each replaces every earlier value of its
/// param (the compiler's rule, the last value wins), so that keys whose params differ only
/// in values an override replaces have equal lists and share one program (`--param M_h=9 g`
/// on grand88, whose hammer mass is graded, is one set, not 88).
pub fn with_overrides(
    params: &[(String, String)],
    overrides: &[(String, String)],
) -> Vec<(String, String)> {
    let mut out = params.to_vec();
    for (name, value) in overrides {
        out.retain(|(n, _)| n != name);
        out.push((name.clone(), value.clone()));
    }
    out
}

/// Resolves and lowers the keyboard `spec` describes; see the module documentation.
///
/// Errors: [`KeyboardError::Input`] for a bad layout, board, instrument name or `keys`
/// (naming the file and the field); [`KeyboardError::Compile`] when an instrument does not
/// compile with a key's params (its diagnostics went to `report`).
pub fn compile(spec: &KeyboardSpec, report: &mut Reporter) -> Result<Keyboard, KeyboardError> {
    let bad = KeyboardError::Input;
    // A layout is resolved first (it may name the board kind).
    let layout = match spec.as_layout.unwrap_or_else(|| is_layout(spec.input)) {
        true => {
            if spec.keys.is_some() {
                return Err(bad(format!(
                    "{}: --keys is for a single instrument; a layout lists its own keys",
                    spec.input
                )));
            }
            Some(read_layout(spec.input).map_err(bad)?)
        }
        false => None,
    };
    // The board kind: the spec's, else the layout's, else the default (a layout's board
    // file is relative to the layout).
    let kind = match (
        spec.board,
        layout.as_ref().and_then(|l| l.0.board_kind.clone()),
    ) {
        (Some(b), _) => b.to_string(),
        (None, Some(k)) => {
            let dir = layout
                .as_ref()
                .and_then(|l| l.1.parent().map(Path::to_path_buf));
            match dir.map(|d| d.join(&k)).filter(|p| p.exists()) {
                Some(p) => p.display().to_string(),
                None => k,
            }
        }
        (None, None) => catalogue::DEFAULT_BOARD.to_string(),
    };
    let board = catalogue::board(&kind).map_err(|e| match &layout {
        Some(l) if spec.board.is_none() => bad(format!("{}: `board_kind`: {e}", spec.input)),
        _ => bad(e),
    })?;
    // Every program is compiled for the board's sample rate (its `require`s see it, its
    // dynamics are discretised at it).
    let fs = board.sample_rate_hz;
    // A single instrument's set, lowered before its keys are known.
    let mut first: Option<ProgramSet> = None;
    let failed = |key: u8, instrument: &str, params: &[(String, String)]| KeyboardError::Compile {
        input: spec.input.to_string(),
        key,
        instrument: instrument.to_string(),
        params: verdict::show_params(params.iter().map(|(n, v)| (n, v))),
        fs,
        kind: kind.clone(),
    };
    let (name, keys, layout, boards) = match layout {
        Some((l, path, keys, boards)) => (l.name.clone(), keys, Some((l, path)), boards),
        None => {
            // A single instrument is lowered first: whether it is a pen decides the
            // default number of keys.
            let src = catalogue::load(spec.input).map_err(bad)?;
            let params = with_overrides(&[], spec.params);
            let Some(lowered) = lower(&src, &params, fs, report) else {
                return Err(failed(21, spec.input, &params));
            };
            let pen = lowered.program.is_pen();
            first = Some(ProgramSet {
                instrument: spec.input.to_string(),
                params,
                source: src,
                ir: lowered.program,
            });
            let n = spec.keys.unwrap_or(if pen { 1 } else { 88 });
            if !(1..=MAX_KEYS).contains(&n) {
                return Err(bad(format!(
                    "--keys must be between 1 and {MAX_KEYS} (MIDI keys), got {n}"
                )));
            }
            // From A0 up, or from MIDI 0 when that would pass key 127.
            let first = if 21 + n <= 128 { 21 } else { 0 };
            let keys = (first..first + n)
                .map(|k| KeyAssignment {
                    key: k as u8,
                    instrument: spec.input.to_string(),
                    params: vec![],
                })
                .collect();
            (format!("{} × {n}", spec.input), keys, None, None)
        }
    };
    let mut keys: Vec<KeyAssignment> = keys;
    keys.sort_by_key(|a| a.key);
    for a in &mut keys {
        a.params = with_overrides(&a.params, spec.params);
    }
    let (sets, key_set) = lower_sets(&keys, first, spec.input, &kind, fs, report)?;
    Ok(Keyboard {
        name,
        input: spec.input.to_string(),
        layout,
        kind,
        board,
        keys,
        key_set,
        sets,
        boards,
        overrides: spec.params.to_vec(),
        sensor_check: None,
        watchdog: None,
    })
}

/// The distinct (instrument, params) of `keys` (ascending), each lowered once for `fs` Hz,
/// in order of first key, and per key the index of its set: the one rule of which keys
/// share a program (`group_sets`). `first`, when given, is a set already lowered (a single
/// instrument's). `input` and `kind` name the keyboard and board in errors.
///
/// Errors: [`KeyboardError::Input`] for an instrument that cannot be read,
/// [`KeyboardError::Compile`] for one that does not compile (its diagnostics to `report`).
fn lower_sets(
    keys: &[KeyAssignment],
    mut first: Option<ProgramSet>,
    input: &str,
    kind: &str,
    fs: f64,
    report: &mut Reporter,
) -> Result<(Vec<ProgramSet>, Vec<usize>), KeyboardError> {
    let bad = KeyboardError::Input;
    let failed = |key: u8, instrument: &str, params: &[(String, String)]| KeyboardError::Compile {
        input: input.to_string(),
        key,
        instrument: instrument.to_string(),
        params: verdict::show_params(params.iter().map(|(n, v)| (n, v))),
        fs,
        kind: kind.to_string(),
    };
    // Which keys share a program: the one rule, as the firmware's own tests group them.
    let (firsts, key_set) = layout_file::group_sets(keys, Ok::<_, KeyboardError>)?;
    // Each instrument read, parsed and linked once (in the order of its first set), the sets
    // lowered in parallel, then taken in order: the diagnostics reported and the first
    // failure returned as lowering them one by one would (a graded layout is one
    // instrument and as many sets as keys).
    let mut sources: Vec<(&str, Result<Source, String>)> = Vec::new();
    for a in &firsts {
        let reused = first
            .as_ref()
            .is_some_and(|s| s.instrument == a.instrument && s.params == a.params);
        if !reused && !sources.iter().any(|(n, _)| *n == a.instrument) {
            sources.push((a.instrument.as_str(), catalogue::load(&a.instrument)));
        }
    }
    let source_of = |a: &KeyAssignment| {
        sources
            .iter()
            .find(|(n, _)| *n == a.instrument)
            .map(|(_, r)| r)
    };
    let lowered: Vec<Option<Result<tactus_compiler::lower::Lowered, Vec<Diagnostic>>>> = firsts
        .par_iter()
        .map(|a| match source_of(a)? {
            Ok(src) => Some(tactus_compiler::compile_linked(
                &src.linked,
                &tactus_compiler::lower::Config {
                    overrides: a.params.clone(),
                    sample_rate_hz: fs,
                },
            )),
            Err(_) => None,
        })
        .collect();
    let mut sets = Vec::with_capacity(firsts.len());
    for (a, lowered) in firsts.iter().zip(lowered) {
        if let Some(set) = first.take_if(|s| s.instrument == a.instrument && s.params == a.params) {
            sets.push(set);
            continue;
        }
        let src = match source_of(a) {
            Some(Ok(src)) => src,
            Some(Err(e)) => return Err(bad(format!("{}: key {}: {e}", input, a.key))),
            None => return Err(bad(format!("{}: key {}: not read", input, a.key))),
        };
        match lowered {
            Some(Ok(l)) => {
                if !l.warnings.is_empty() {
                    report(src, &l.warnings);
                }
                sets.push(ProgramSet {
                    instrument: a.instrument.clone(),
                    params: a.params.clone(),
                    source: src.clone(),
                    ir: l.program,
                });
            }
            Some(Err(d)) => {
                report(src, &d);
                return Err(failed(a.key, &a.instrument, &a.params));
            }
            None => return Err(failed(a.key, &a.instrument, &a.params)),
        }
    }
    Ok((sets, key_set))
}

/// The keyboard a built board's firmware belongs to, from the key maps (`keys.json`) of its
/// boards as `tactus build` wrote them (`maps`, each naming its board, kind, keys, their
/// instruments and params): every key with its instrument and params, the boards' key
/// lists as the maps give them (by board number), and every distinct (instrument, params)
/// lowered as [`compile`] lowers them, so that [`Keyboard::firmware`] gives the programs
/// the build compiled (an instrument's sets sharing one code over every board's values).
/// `name` names the keyboard in errors. The sensor check and the watchdog are left to the
/// programs' default (the maps do not say: set [`Keyboard::sensor_check`] and
/// [`Keyboard::watchdog`]).
///
/// Errors: [`KeyboardError::Input`] for no maps, maps of different board kinds or sample
/// rates, a key on two boards, a board kind that is not built in, an instrument that
/// cannot be read; [`KeyboardError::Compile`] for one that does not compile.
pub fn from_key_maps(
    maps: &[tactus_firmware::flash::KeyMap],
    name: &str,
    report: &mut Reporter,
) -> Result<Keyboard, KeyboardError> {
    let bad = KeyboardError::Input;
    let Some(first) = maps.first() else {
        return Err(bad(format!("{name}: no key maps")));
    };
    if let Some(m) = (maps.iter())
        .find(|m| m.board_kind != first.board_kind || m.sample_rate_hz != first.sample_rate_hz)
    {
        return Err(bad(format!(
            "{name}: board {} is a `{}` at {} Hz, board {} a `{}` at {} Hz: not one keyboard",
            first.board,
            first.board_kind,
            first.sample_rate_hz,
            m.board,
            m.board_kind,
            m.sample_rate_hz
        )));
    }
    let board = catalogue::board(&first.board_kind).map_err(|e| {
        bad(format!(
            "{name}: `board_kind` = {:?}: {e} (a key map names its board by name: only a \
             built-in board can be rebuilt from it)",
            first.board_kind
        ))
    })?;
    let mut ordered: Vec<&tactus_firmware::flash::KeyMap> = maps.iter().collect();
    ordered.sort_by_key(|m| m.board);
    let mut keys: Vec<KeyAssignment> = Vec::new();
    for m in &ordered {
        for k in &m.keys {
            if keys.iter().any(|a| a.key == k.midi) {
                return Err(bad(format!(
                    "{name}: key {} is on two boards (board {} and another)",
                    k.midi, m.board
                )));
            }
            keys.push(KeyAssignment {
                key: k.midi,
                instrument: k.instrument.clone(),
                params: (k.params.iter())
                    .map(|p| match p.split_once('=') {
                        Some((a, b)) => (a.to_string(), b.to_string()),
                        None => (p.clone(), String::new()),
                    })
                    .collect(),
            });
        }
    }
    keys.sort_by_key(|a| a.key);
    let fs = board.sample_rate_hz;
    let (sets, key_set) = lower_sets(&keys, None, name, &first.board_kind, fs, report)?;
    Ok(Keyboard {
        name: name.to_string(),
        input: name.to_string(),
        layout: None,
        kind: first.board_kind.clone(),
        board,
        keys,
        key_set,
        sets,
        boards: Some(
            (ordered.iter())
                .map(|m| m.keys.iter().map(|k| k.midi).collect())
                .collect(),
        ),
        overrides: Vec::new(),
        sensor_check: None,
        watchdog: None,
    })
}

impl Keyboard {
    /// The firmware's program of each set, in the order of [`Keyboard::sets`]: the sets of
    /// one instrument share one code, their params a block each
    /// ([`tactus_firmware::image::compile_shared`]).
    ///
    /// Errors: [`KeyboardError::Firmware`] naming the set's source when the fixed-point or
    /// Thumb compilation fails or a plan breaks its instrument's accuracy contract.
    pub fn firmware(&self) -> Result<Vec<FirmwareProgram>, KeyboardError> {
        let lowered: Vec<(&str, &Program)> = self
            .sets
            .iter()
            .map(|s| (s.instrument.as_str(), &s.ir))
            .collect();
        let mut programs = tactus_firmware::image::compile_shared(&lowered).map_err(|(i, e)| {
            KeyboardError::Firmware {
                source_name: self.sets[i].source.name.clone(),
                message: e.to_string(),
            }
        })?;
        if let Some(on) = self.sensor_check {
            programs.iter_mut().for_each(|p| p.sensor_check = on);
        }
        if let Some(on) = self.watchdog {
            programs.iter_mut().for_each(|p| p.watchdog = on);
        }
        Ok(programs)
    }

    /// The safety limiter of every key ([`LimiterConfig::for_board`]: the one configuration
    /// `build`, `budget` and `play` give the firmware).
    pub fn limiter(&self) -> LimiterConfig {
        LimiterConfig::for_board(&self.board)
    }

    /// The keyboard's boards, with their verdicts: the layout's own checked
    /// ([`boards::check_boards`]), or when it lists none planned ([`boards::plan`]: the
    /// fewest boards that fit, contiguous key ranges). `programs` are [`Keyboard::firmware`]'s.
    /// Made once per command: `tactus budget` reports this plan, `tactus build` builds it,
    /// `tactus play` runs it (and `tactus emu run` reads it back from what `build` wrote).
    /// `progress(done, total)` counts keys placed (boards checked for a layout's own).
    ///
    /// Errors: [`KeyboardError::Firmware`] when a program cannot be costed or placed on a
    /// board (its code cannot be analysed, its window words do not fit).
    pub fn plan(
        &self,
        programs: &[FirmwareProgram],
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<KeyboardPlan, KeyboardError> {
        let bad = |e: boards::BoardsError| KeyboardError::Firmware {
            source_name: self.input.clone(),
            message: e.to_string(),
        };
        let (board, limiter) = (&self.board, self.limiter());
        let costs = boards::ProgramCosts::new(programs, board, &limiter).map_err(bad)?;
        let keys: Vec<boards::PlanKey> = (self.key_programs().into_iter())
            .map(|(key, program)| boards::PlanKey { key, program })
            .collect();
        match &self.boards {
            None => boards::plan(programs, &costs, &keys, board, &limiter, progress),
            Some(lists) => {
                boards::check_boards(programs, &costs, &keys, lists, board, &limiter, progress)
            }
        }
        .map_err(bad)
    }

    /// The keyboard as a layout file with `report`'s boards: the layout (or one range for a
    /// single instrument) with `board_kind` and one `[[board]]` per board, the spec's
    /// overrides written into every range (replacing a grade of the same param), so that the
    /// file alone gives the keys `report` budgeted. Instrument and board paths are made
    /// absolute, so the file works wherever it is written. What `tactus budget
    /// --write-plan` writes.
    ///
    /// Errors: [`KeyboardError::Input`] when the layout cannot be written as TOML or does
    /// not read back as itself (a bug, reported rather than written).
    pub fn plan_text(&self, report: &verdict::BudgetReport) -> Result<String, KeyboardError> {
        let bad = KeyboardError::Input;
        let mut layout = match &self.layout {
            Some((l, path)) => {
                let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
                let mut l = l.clone();
                for range in &mut l.ranges {
                    range.instrument = absolute(&range.instrument, dir);
                }
                l
            }
            None => {
                let (first, last) = (
                    self.keys.first().map_or(0, |k| k.key),
                    self.keys.last().map_or(0, |k| k.key),
                );
                let instrument = self
                    .keys
                    .first()
                    .map_or(String::new(), |k| k.instrument.clone());
                layout_file::parse_layout(
                    &format!(
                        "name = {:?}\n[[range]]\nkeys = [{first}, {last}]\ninstrument = {:?}\n",
                        self.name,
                        absolute(&instrument, None)
                    ),
                    "plan",
                )
                .map_err(bad)?
            }
        };
        for range in &mut layout.ranges {
            for (name, value) in &self.overrides {
                range.grade.retain(|g| &g.param != name);
                range.params.insert(name.clone(), value.clone());
            }
        }
        let layout = report.with_boards(&layout, &absolute(&self.kind, None));
        // The header is one comment line whatever the names hold.
        let header = format!(
            "Planned by `tactus budget` for {}: {} boards of kind {}, each a contiguous key range.",
            self.name, report.board_count, report.board.name
        );
        layout_file::layout_text(&layout, &header).map_err(bad)
    }

    /// Each key (MIDI, ascending) with the index of its set.
    pub fn key_programs(&self) -> Vec<(u8, usize)> {
        self.keys
            .iter()
            .map(|a| a.key)
            .zip(self.key_set.iter().copied())
            .collect()
    }

    /// The sets as `tactus budget` takes them, with their firmware `programs`
    /// ([`Keyboard::firmware`]'s, in the order of [`Keyboard::sets`]).
    pub fn program_inputs(&self, programs: &[FirmwareProgram]) -> Vec<ProgramInput> {
        self.sets
            .iter()
            .zip(programs)
            .map(|(s, program)| ProgramInput {
                instrument: s.instrument.clone(),
                params: s.params.clone(),
                sources: s.source.linked.sources.clone(),
                program: program.clone(),
            })
            .collect()
    }

    /// The keyboard as `play` takes it for a performance on `played` keys (MIDI): every key
    /// (the firmware runs them all), the distinct programs of the played keys, the
    /// firmware's programs (`firmware`: [`Keyboard::firmware`]) when the engine runs them
    /// ([`play::PlayConfig::needs_firmware`]), and the boards of the keyboard's `plan`
    /// ([`Keyboard::plan`]) when it runs them on emulated boards.
    ///
    /// Errors: [`KeyboardError::NotPlayable`] naming the key when a played key's instrument
    /// reads other than one key sensor (a pen, several sensors) or emits no strike event
    /// ([`play::strike::strike_event`]).
    pub fn played<'a>(
        &'a self,
        played: &BTreeSet<u8>,
        firmware: Option<&'a [FirmwareProgram]>,
        plan: Option<&'a KeyboardPlan>,
    ) -> Result<play::Keyboard<'a>, KeyboardError> {
        // Set index → index among the played programs.
        let mut host: BTreeMap<usize, usize> = BTreeMap::new();
        let mut programs = Vec::new();
        let mut key_program = BTreeMap::new();
        for (a, &s) in self.keys.iter().zip(&self.key_set) {
            if !played.contains(&a.key) {
                continue;
            }
            let p = match host.get(&s) {
                Some(&p) => p,
                None => {
                    let program = &self.sets[s].ir;
                    if program.is_pen() || program.sensors.len() > 1 {
                        return Err(KeyboardError::NotPlayable(format!(
                            "instrument `{}` (key {}) reads {} sensors{}: `tactus play` moves \
                             one key sensor per key; run a pen with \
                             `tactus sim <instrument> --stimulus <pen gesture>`",
                            program.name,
                            a.key,
                            program.sensors.len(),
                            if program.is_pen() {
                                " and pushes a 3-D force (a pen)"
                            } else {
                                ""
                            }
                        )));
                    }
                    if program.sensors.is_empty() || play::strike::strike_event(program).is_none() {
                        return Err(KeyboardError::NotPlayable(format!(
                            "instrument `{}` (key {}) has no sensor or emits no `strike`/`pluck` \
                             to play",
                            program.name, a.key
                        )));
                    }
                    programs.push(HostProgram {
                        name: self.sets[s].instrument.clone(),
                        program: program.clone(),
                    });
                    host.insert(s, programs.len() - 1);
                    programs.len() - 1
                }
            };
            key_program.insert(a.key, p);
        }
        Ok(play::Keyboard {
            keys: self.keys.clone(),
            programs,
            key_program,
            boards: plan.map(KeyboardPlan::key_lists),
            firmware: firmware.map(|programs| play::Firmware {
                programs,
                key_program: &self.key_set,
                images: plan.map_or(&[], |p| &p.images),
            }),
        })
    }
}
