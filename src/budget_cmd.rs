//! `tactus budget`: does a keyboard fit its boards, and how few boards does it need?
//!
//! The command resolves the input (a layout, or one instrument on `--keys` keys), compiles
//! every distinct program (an instrument with one set of params) printing its diagnostics,
//! and hands them to `tactus_firmware::verdict::keyboard_budget`, which plans the boards
//! (or checks the layout's own) by the static analysis of each board's sample interrupt and
//! returns the report; this module only prints it (text or `--json`) and writes
//! `--write-plan`.
//!
//! Exit codes: 0 fits; 1 does not fit (or measured > static, an analysis bug); 2 bad input.

use crate::check_cmd::{compile_reporting, parse_override};
use crate::source;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use tactus_firmware::verdict::{self, BudgetInput, ProgramInput};
use tactus_runtime::keyboard::{self, Board, KeyAssignment, Layout};
use tactus_runtime::limiter::LimiterConfig;

/// Boards shipped in the binary, by name (the file stem in `boards/`).
pub const BUILTIN_BOARDS: &[(&str, &str)] = &[
    ("rp2040", include_str!("../boards/rp2040.toml")),
    (
        "rp2040_200mhz",
        include_str!("../boards/rp2040_200mhz.toml"),
    ),
    ("rp2040_20mhz", include_str!("../boards/rp2040_20mhz.toml")),
];

/// Arguments of `tactus budget`.
#[derive(Debug, clap::Args)]
#[command(after_long_help = "\
Examples:
  tactus budget instruments/layouts/grand88.toml
  tactus budget instruments/layouts/grand88.toml --board rp2040_200mhz --write-plan out/grand88-boards.toml
  tactus budget grand_piano --keys 12
  tactus budget harpsichord --keys 88 --json > budget.json

A keyboard is a set of boards, each a microcontroller with a few keys (each key with its
own motor driver and converter channels); the sample deadline holds per board, on its
cores. A layout may list its boards ([[board]] keys = [21, 28], contiguous key ranges);
otherwise Tactus plans the fewest: a greedy sweep along the keyboard giving each board as
many keys as still fit, which is optimal because any sub-range of a fitting range fits.

How to read it: `static` is the proven worst case of one key's update (cycles per
key-sample, call included); `glue` the key's share of the sample interrupt (sensor copy,
call set-up, safety limiter, DAC store); `measured` the worst and mean of the update over
the stimulus corpus in the emulator (always ≤ static, else the analysis has a bug). Per
board, per core: the static bound of that core's whole sample interrupt as the firmware
image lays it out (entry, tick, every key's glue and update, window contention, return)
against the cycles of the shortest interval between two sample ticks (each core's SysTick
ticks every ⌊clock/fs⌋ cycles or one more, exactly fs times a second: 3,015 cycles at
133 MHz and 44.1 kHz, whose mean period is 3,015.87), its utilisation and headroom.
`what fits` is the most keys of each instrument one board holds. The costliest param set
of each instrument is measured over the full corpus (presses, repeated notes, trills, half
dips, noise, glitches, random words), its other param sets over a brief one; `--quick`
shrinks the full one (the static figures and the verdict do not change).

Exit codes: 0 fits, 1 does not fit (or measured > static), 2 bad input.")]
pub struct BudgetArgs {
    /// A layout (`instruments/layouts/grand88.toml`: which instrument on which keys, and
    /// optionally on which boards), or one instrument (file or built-in name, e.g.
    /// `grand_piano`) on `--keys` keys.
    pub input: String,
    /// The board kind: a built-in name (`rp2040`, `rp2040_200mhz`, `rp2040_20mhz`) or a
    /// board TOML file (name, clock_hz, cores, sample_rate_hz). Default: the layout's
    /// `board_kind`, else rp2040.
    #[arg(long, value_name = "NAME_OR_FILE")]
    pub board: Option<String>,
    /// For a single instrument: how many keys (identical copies; default 88, a pen 1), from
    /// MIDI 21 (A0) up.
    #[arg(long, value_name = "N")]
    pub keys: Option<u32>,
    /// Override a param of every key: `--param M_h=8 g` (repeatable; after the layout's own).
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_override)]
    pub params: Vec<(String, String)>,
    /// Print the result as one JSON document on stdout instead of the tables.
    #[arg(long)]
    pub json: bool,
    /// Measure over the quick corpus (about a fifth of the samples; the static figures and
    /// the verdict do not change).
    #[arg(long)]
    pub quick: bool,
    /// Write the layout with its boards as planned (`board_kind` and one `[[board]]` per
    /// board) to FILE, for `tactus play --layout` and later runs of `tactus budget`.
    #[arg(long, value_name = "FILE")]
    pub write_plan: Option<PathBuf>,
    /// The emulator's engine for the measurements: `block` (code compiled to native code
    /// with cranelift) or `interp` (the interpreter): the same cycles; compare their speed.
    #[arg(long, value_enum, default_value = "block")]
    pub emu: EmuEngine,
}

/// The emulator's engine (`--emu`): both are exact; the block engine is the faster.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum EmuEngine {
    /// One pre-decoded instruction at a time.
    Interp,
    /// Code regions compiled to native code (the default).
    #[default]
    Block,
}

impl From<EmuEngine> for tactus_emulator::Engine {
    fn from(e: EmuEngine) -> Self {
        match e {
            EmuEngine::Interp => tactus_emulator::Engine::Interp,
            EmuEngine::Block => tactus_emulator::Engine::Block,
        }
    }
}

/// A failure: bad input (exit 2) with its message.
struct Bad(String);

/// Runs `tactus budget`.
pub fn run(args: BudgetArgs) -> ExitCode {
    match budget(&args) {
        Ok(code) => code,
        Err(Bad(e)) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

/// The board named `arg`: a board file, or a built-in board's name, checked by
/// `tactus_firmware::board_file::read_board` (the one validation of boards); errors name the
/// file and the field, or list the built-ins.
pub(crate) fn board_named(arg: &str) -> Result<Board, String> {
    if Path::new(arg).exists() {
        let text = keyboard::read_text(Path::new(arg))?;
        return tactus_firmware::board_file::read_board(&text, arg);
    }
    let stem = arg.trim_end_matches(".toml").replace('-', "_");
    match BUILTIN_BOARDS.iter().find(|(n, _)| *n == stem) {
        Some((n, text)) => tactus_firmware::board_file::read_board(text, &format!("builtin:{n}")),
        None => Err(format!(
            "no board file `{arg}`, and no built-in board of that name (built-ins: {})",
            BUILTIN_BOARDS
                .iter()
                .map(|(n, _)| *n)
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// The input resolved: name, keys, the layout (if one), its explicit boards.
struct Resolved {
    name: String,
    keys: Vec<KeyAssignment>,
    layout: Option<(Layout, PathBuf)>,
    boards: Option<Vec<Vec<u8>>>,
}

fn resolve(args: &KeyboardSpec, single_is_pen: bool) -> Result<Resolved, Bad> {
    if args.input.ends_with(".toml") {
        if args.keys.is_some() {
            return Err(Bad(format!(
                "{}: --keys is for a single instrument; a layout lists its own keys",
                args.input
            )));
        }
        let path = Path::new(args.input);
        let (l, keys) = keyboard::read_layout(path).map_err(Bad)?;
        let boards = keyboard::board_keys(&l, args.input, &keys).map_err(Bad)?;
        return Ok(Resolved {
            name: l.name.clone(),
            keys,
            layout: Some((l, path.to_path_buf())),
            boards,
        });
    }
    // A pen instrument is budgeted as one pen unless told otherwise.
    let n = args.keys.unwrap_or(if single_is_pen { 1 } else { 88 });
    if !(1..=128).contains(&n) {
        return Err(Bad(format!(
            "--keys must be between 1 and 128 (MIDI keys), got {n}"
        )));
    }
    // From A0 up, or from MIDI 0 when that would pass key 127.
    let first = if 21 + n <= 128 { 21 } else { 0 };
    Ok(Resolved {
        name: format!("{} × {n}", args.input),
        keys: (first..first + n)
            .map(|k| KeyAssignment {
                key: k as u8,
                instrument: args.input.to_string(),
                params: vec![],
            })
            .collect(),
        layout: None,
        boards: None,
    })
}

/// A keyboard to compile: a layout file, or an instrument on `keys` keys.
pub(crate) struct KeyboardSpec<'a> {
    /// The layout file (`.toml`) or the instrument.
    pub input: &'a str,
    /// `--board`.
    pub board: Option<&'a str>,
    /// `--keys` (an instrument only).
    pub keys: Option<u32>,
    /// `--param` overrides for every key.
    pub params: &'a [(String, String)],
}

/// A compiled keyboard: its keys resolved, its board, its distinct programs.
pub(crate) struct Keyboard {
    resolved: Resolved,
    /// The board kind as given (a name or a path).
    pub kind: String,
    /// The board.
    pub board: Board,
    /// Distinct programs, in order of first key.
    pub programs: Vec<ProgramInput>,
    /// (MIDI key, program), ascending.
    pub keys: Vec<(u8, usize)>,
}

impl Keyboard {
    /// The layout's (or the instrument's) name.
    pub fn name(&self) -> &str {
        &self.resolved.name
    }

    /// The layout's own boards, if it lists them.
    pub fn boards(&self) -> Option<&[Vec<u8>]> {
        self.resolved.boards.as_deref()
    }
}

/// Resolves and compiles a keyboard, printing each instrument's diagnostics once.
///
/// Errors: a message naming the input (a bad layout or board, an instrument that does not
/// compile).
pub(crate) fn compile_keyboard(args: &KeyboardSpec) -> Result<Keyboard, String> {
    // A layout is resolved first (it may name the board kind).
    let layout_input = args.input.ends_with(".toml");
    let resolved = match layout_input {
        true => Some(resolve(args, false).map_err(|b| b.0)?),
        false => None,
    };
    let layout = resolved.as_ref().and_then(|r| r.layout.as_ref());
    // The board kind: --board, else the layout's, else rp2040 (a layout's board file is
    // relative to the layout).
    let kind = match (&args.board, layout.and_then(|(l, _)| l.board_kind.clone())) {
        (Some(b), _) => b.to_string(),
        (None, Some(k)) => {
            let dir = layout.and_then(|(_, p)| p.parent().map(Path::to_path_buf));
            match dir.map(|d| d.join(&k)).filter(|p| p.exists()) {
                Some(p) => p.display().to_string(),
                None => k,
            }
        }
        (None, None) => "rp2040".to_string(),
    };
    let board = board_named(&kind).map_err(|e| match layout {
        Some((_, p)) if args.board.is_none() => format!("{}: `board_kind`: {e}", p.display()),
        _ => e,
    })?;
    // Every program is compiled for the board's sample rate (its `require`s see it, its
    // dynamics are discretised at it).
    let fs = board.sample_rate_hz;
    // A single instrument is compiled once, here (whether it is a pen decides the default
    // number of keys), and reused for its keys below, so its diagnostics print once.
    let mut precompiled = None;
    if !layout_input {
        let src = source::load(args.input)?;
        let lowered = compile_reporting(&src, args.params, fs);
        precompiled = Some((src, lowered));
    }
    let single_is_pen = matches!(&precompiled, Some((_, Some(l))) if l.program.is_pen());
    let r = match resolved {
        Some(r) => r,
        None => resolve(args, single_is_pen).map_err(|b| b.0)?,
    };

    // Distinct parameter sets, in order of first key: (instrument, params, source, IR).
    type ParamSet = (
        String,
        Vec<(String, String)>,
        source::Source,
        tactus_compiler::ir::Program,
    );
    let mut sets: Vec<ParamSet> = Vec::new();
    let mut keys: Vec<(u8, usize)> = Vec::new();
    for a in &r.keys {
        let mut params = a.params.clone();
        params.extend(args.params.iter().cloned());
        let idx = match sets
            .iter()
            .position(|p: &ParamSet| p.0 == a.instrument && p.1 == params)
        {
            Some(i) => i,
            None => {
                let (src, lowered) = match precompiled.take() {
                    Some(pre) => pre,
                    None => {
                        let src = source::load(&a.instrument)
                            .map_err(|e| format!("{}: key {}: {e}", args.input, a.key))?;
                        let lowered = compile_reporting(&src, &params, fs);
                        (src, lowered)
                    }
                };
                let Some(lowered) = lowered else {
                    return Err(format!(
                        "{}: key {}: `{}` does not compile with params {} for the board's \
                         sample rate, {fs} Hz (`{kind}`; see the diagnostics above)",
                        args.input,
                        a.key,
                        a.instrument,
                        verdict::show_params(params.iter().map(|(n, v)| (n, v)))
                    ));
                };
                sets.push((a.instrument.clone(), params, src, lowered.program));
                sets.len() - 1
            }
        };
        keys.push((a.key, idx));
    }
    keys.sort_unstable();
    // One code per instrument: graded params become run-time data (a param block per set).
    let lowered: Vec<(&str, &tactus_compiler::ir::Program)> =
        sets.iter().map(|s| (s.0.as_str(), &s.3)).collect();
    let compiled = tactus_firmware::image::compile_shared(&lowered)
        .map_err(|(i, e)| format!("{}: {e}", sets[i].2.name))?;
    let programs: Vec<ProgramInput> = sets
        .into_iter()
        .zip(compiled)
        .map(|((instrument, params, src, _), program)| ProgramInput {
            instrument,
            params,
            source: src.text,
            program,
        })
        .collect();

    Ok(Keyboard {
        resolved: r,
        kind,
        board,
        programs,
        keys,
    })
}

fn budget(args: &BudgetArgs) -> Result<ExitCode, Bad> {
    let kb = compile_keyboard(&KeyboardSpec {
        input: &args.input,
        board: args.board.as_deref(),
        keys: args.keys,
        params: &args.params,
    })
    .map_err(Bad)?;
    let (r, kind, board, programs, keys) = (kb.resolved, kb.kind, kb.board, kb.programs, kb.keys);
    let input = BudgetInput {
        name: r.name.clone(),
        input: args.input.clone(),
        board: board.clone(),
        programs,
        keys,
        boards: r.boards.clone(),
        quick: args.quick,
        engine: args.emu.into(),
        limiter: LimiterConfig {
            sample_rate_hz: board.sample_rate_hz,
            ..LimiterConfig::default()
        },
    };
    let bar = ProgressBar::new(1);
    bar.set_style(
        ProgressStyle::with_template("{msg:>16} [{bar:30}] {pos}/{len}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let report = verdict::keyboard_budget(&input, &mut |stage, done, total| {
        bar.set_message(stage.to_string());
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })
    .map_err(|e| Bad(e.0))?;
    bar.finish_and_clear();

    if args.json {
        let json = serde_json::to_string_pretty(&report)
            .map_err(|e| Bad(format!("cannot write the report as JSON: {e}")))?;
        println!("{json}");
    } else {
        print!("{}", report.text());
    }
    if !report.fits {
        // The verdict's one line on stderr too (stdout may be JSON).
        let why = match report.what_fits.iter().find_map(|w| {
            w.fits_no_board.as_ref().map(|why| {
                format!(
                    "{} fits no {} board: {why}",
                    w.instrument, report.board.name
                )
            })
        }) {
            Some(line) => line,
            None => format!(
                "{} of {} boards over budget",
                report.boards.iter().filter(|b| !b.fits()).count(),
                report.board_count
            ),
        };
        eprintln!("error: {}: does not fit: {why}", r.name);
    }
    for p in report.unsound() {
        eprintln!(
            "BUG: {} ({} keys): measured {} cycles at {} sample {} exceed the static worst case {} — the WCET analysis or the emulator's timing is wrong",
            p.instrument,
            p.keys.len(),
            p.measured_max,
            p.measured_max_at.run,
            p.measured_max_at.sample,
            p.static_cycles
        );
    }
    if let Some(out) = &args.write_plan {
        write_plan(&report, &r, &kind, out)?;
        if !args.json {
            println!(
                "plan: {} boards written to {}",
                report.board_count,
                out.display()
            );
        }
    }
    Ok(ExitCode::from(report.exit_code()))
}

/// Writes the planned layout: the input layout (or one range for a single instrument) with
/// `board_kind` and explicit boards. Instrument and board paths are made absolute, so the
/// file works wherever it is written.
fn write_plan(
    report: &verdict::BudgetReport,
    r: &Resolved,
    kind: &str,
    out: &Path,
) -> Result<(), Bad> {
    let absolute = |s: &str, dir: Option<&Path>| -> String {
        let p = dir.map_or_else(|| PathBuf::from(s), |d| d.join(s));
        match p.canonicalize() {
            Ok(abs) if p.exists() => abs.display().to_string(),
            _ => s.to_string(),
        }
    };
    let mut layout = match &r.layout {
        Some((l, path)) => {
            let dir = path.parent();
            let mut l = l.clone();
            for range in &mut l.ranges {
                range.instrument = absolute(&range.instrument, dir);
            }
            l
        }
        None => {
            let (first, last) = (
                r.keys.first().map_or(0, |k| k.key),
                r.keys.last().map_or(0, |k| k.key),
            );
            keyboard::parse_layout(
                &format!(
                    "name = {:?}\n[[range]]\nkeys = [{first}, {last}]\ninstrument = {:?}\n",
                    r.name,
                    absolute(&r.keys[0].instrument, None)
                ),
                "plan",
            )
            .map_err(Bad)?
        }
    };
    layout = report.with_boards(&layout, &absolute(kind, None));
    // The header is one comment line whatever the names hold.
    let header = format!(
        "Planned by `tactus budget` for {}: {} boards of kind {}, each a contiguous key range.",
        r.name, report.board_count, report.board.name
    );
    let text = keyboard::layout_text(&layout, &header)
        .map_err(|e| Bad(format!("{}: {e}; nothing written", out.display())))?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| Bad(format!("{}: cannot create: {e}", dir.display())))?;
    }
    std::fs::write(out, text).map_err(|e| Bad(format!("{}: cannot write: {e}", out.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_boards_parse() {
        for (n, text) in BUILTIN_BOARDS {
            keyboard::parse_board(text, n).unwrap();
        }
        assert!(board_named("no-such-board").is_err());
    }
}
