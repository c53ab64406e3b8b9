//! The budget of a keyboard, as `tactus budget` reports it: per program its static and
//! measured cost, per board its cores' static bounds, the verdict, the worst board and key,
//! and what fits. [`keyboard_budget`] computes it; [`BudgetReport`] is serialised as JSON
//! (`--json`) and rendered as text ([`BudgetReport::text`]); the CLI only prints it.
//!
//! Measurement is over the stimulus corpus ([`crate::corpus`]): each instrument's costliest
//! param set over the full (or quick) corpus, its other param sets over the brief one. The
//! verdict does not depend on it: it is the static bound of each board's sample interrupt
//! ([`crate::boards`]); measured > static for a program means the analysis or the emulator's
//! timing is wrong ([`BudgetReport::unsound`]).

use crate::boards::{self, BoardVerdict, PlanKey, ProgramCosts};
use crate::budget::{self, describe_note, note_name, BudgetError, ProgramCost};
use crate::corpus::{self, Size};
use crate::image::{FirmwareImage, Program};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use tactus_runtime::keyboard::BoardSpec;
use tactus_runtime::limiter::LimiterConfig;

/// One distinct program of the keyboard (an instrument with one set of params), as given to
/// [`keyboard_budget`].
#[derive(Clone, Debug)]
pub struct ProgramInput {
    /// The instrument as the layout names it.
    pub instrument: String,
    /// Its param overrides, `(name, value with unit)`.
    pub params: Vec<(String, String)>,
    /// The instrument's source files, its own and those it imports (to render the worst
    /// path as source lines).
    pub sources: tactus_compiler::sources::SourceMap,
    /// The compiled program.
    pub program: Program,
}

/// What [`keyboard_budget`] needs.
#[derive(Clone, Debug)]
pub struct BudgetInput {
    /// The layout's name (or `instrument × N`).
    pub name: String,
    /// What the user gave (a path or an instrument name).
    pub input: String,
    /// The board kind.
    pub board: BoardSpec,
    /// The distinct programs.
    pub programs: Vec<ProgramInput>,
    /// The keys, ascending: (MIDI key, index into `programs`).
    pub keys: Vec<(u8, usize)>,
    /// The keyboard's boards, planned or the layout's own, with their verdicts (made once
    /// for the keyboard: `tactus_host::keyboard::Keyboard::plan`).
    pub plan: boards::KeyboardPlan,
    /// Measure over the quick corpus instead of the full one.
    pub quick: bool,
    /// The emulator's engine for the measurements (the same cycles either way).
    pub engine: tactus_emulator::Engine,
    /// The limiter every force word passes.
    pub limiter: LimiterConfig,
}

/// Why the budget could not be computed (bad input or a program the tools cannot handle).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VerdictError(pub String);

impl std::fmt::Display for VerdictError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for VerdictError {}

/// The board kind, as reported.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BoardKind {
    /// Its name.
    pub name: String,
    /// Core clock, Hz.
    pub clock_hz: f64,
    /// Cores.
    pub cores: u32,
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Cycles per sample per core: the deadline (`BoardSpec::cycles_per_sample`, the shortest tick interval).
    pub cycles_per_sample: u64,
    /// Static cycles of a core's sample interrupt with no key (entry, tick, miss check,
    /// return): core 0's, with the watchdog's feed when the programs run it
    /// ([`crate::image::Program::watchdog`]), the most any core's costs.
    pub isr_cycles: u64,
}

/// Where the measured worst case was.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WorstAt {
    /// The corpus run.
    pub run: String,
    /// The sample in it.
    pub sample: usize,
}

/// A call on a worst path.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PathCall {
    /// Offset of the `BL` in `.text`.
    pub site: u32,
    /// Offset of the callee.
    pub callee: u32,
    /// The callee's worst case, cycles.
    pub cycles: u64,
}

/// One program's cost.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ProgramReport {
    /// The instrument.
    pub instrument: String,
    /// Its param overrides.
    pub params: BTreeMap<String, String>,
    /// Its keys (MIDI numbers; a pen's slot).
    pub keys: Vec<u8>,
    /// A pen program (counted as pens).
    pub pen: bool,
    /// Static worst case of the update, cycles per key-sample (the caller's `BL`
    /// included).
    pub static_cycles: u64,
    /// Static cycles of the key's glue in the sample interrupt (sensor copy, call set-up,
    /// limiter, DAC store), from the image.
    pub glue_cycles: u64,
    /// Measured worst case over the corpus.
    pub measured_max: u64,
    /// Measured mean.
    pub measured_mean: f64,
    /// Static over measured worst case.
    pub static_over_measured: Option<f64>,
    /// Measured ≤ static.
    pub sound: bool,
    /// The corpus size used (`full`, `quick`, `brief`; `token`: the first
    /// [`TOKEN_SAMPLES`] samples of each brief run, for a program one key of which fits no
    /// board).
    pub corpus: String,
    /// Samples measured.
    pub samples: usize,
    /// Where the measured worst case was.
    pub measured_max_at: WorstAt,
    /// The worst path's source-level events.
    pub worst_path: Vec<String>,
    /// The calls on the worst path.
    pub worst_path_calls: Vec<PathCall>,
}

/// The most expensive key.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WorstKey {
    /// MIDI key (a pen: its slot).
    pub key: u8,
    /// Its note name.
    pub note: String,
    /// A pen.
    pub pen: bool,
    /// Its instrument.
    pub instrument: String,
    /// Its program (index into `programs`).
    pub program: usize,
    /// Update + glue, static cycles per sample.
    pub cycles: u64,
}

/// How many keys of one instrument one board holds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct WhatFits {
    /// The instrument (its costliest param set).
    pub instrument: String,
    /// Static cycles of one key (update + glue) as the densest board builds it: without the
    /// quiescent-key guard when `guard_off`.
    pub cycles_per_key: u64,
    /// Whether the densest board leaves out the quiescent-key guard the program asks for
    /// (the plan's choice, [`BoardVerdict::guard_off`]).
    pub guard_off: bool,
    /// Static cycles of one key with the guard (equal to `cycles_per_key` when the board
    /// keeps it or the program has none).
    pub guarded_cycles_per_key: u64,
    /// The most such keys one board holds.
    pub keys_per_board: u64,
    /// Boards for this instrument's keys of the layout at that density (0 when none fits).
    pub boards_for_its_keys: u64,
    /// Why not even one key fits a board of this kind (`keys_per_board` is 0), from
    /// [`boards::fits_no_board`]; `None` when one does.
    pub fits_no_board: Option<String>,
}

/// The budget of a keyboard.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BudgetReport {
    /// The layout's name.
    pub layout: String,
    /// The input as given.
    pub input: String,
    /// The board kind.
    pub board: BoardKind,
    /// Whether the boards were planned (`false`: the layout lists them).
    pub planned: bool,
    /// Per distinct program.
    pub programs: Vec<ProgramReport>,
    /// Per board, in key order.
    pub boards: Vec<BoardVerdict>,
    /// Number of boards.
    pub board_count: usize,
    /// Every board fits.
    pub fits: bool,
    /// Index (in `boards`) of the board with the least headroom.
    pub worst_board: usize,
    /// Its headroom (cycles; negative: over budget).
    pub min_headroom: i64,
    /// The most expensive key.
    pub worst_key: WorstKey,
    /// Per instrument.
    pub what_fits: Vec<WhatFits>,
}

impl BudgetReport {
    /// Programs whose measured worst case exceeds the static one (an analysis bug).
    pub fn unsound(&self) -> Vec<&ProgramReport> {
        self.programs.iter().filter(|p| !p.sound).collect()
    }

    /// The errors to show beside the report (on stderr, as stdout may be JSON): when the
    /// keyboard does not fit, one line saying why (the instrument that fits no board, or
    /// how many boards are over budget), prefixed with `name`; and one line per program
    /// whose measured worst case exceeds the static one (a bug of the WCET analysis or of
    /// the emulator's timing).
    pub fn error_lines(&self, name: &str) -> Vec<String> {
        let mut lines = Vec::new();
        if !self.fits {
            let no_board = self.what_fits.iter().find_map(|w| {
                let why = w.fits_no_board.as_ref()?;
                Some(format!(
                    "{} fits no {} board: {why}",
                    w.instrument, self.board.name
                ))
            });
            let why = no_board.unwrap_or_else(|| {
                format!(
                    "{} of {} boards over budget",
                    self.boards.iter().filter(|b| !b.fits()).count(),
                    self.board_count
                )
            });
            lines.push(format!("error: {name}: does not fit: {why}"));
        }
        for p in self.unsound() {
            lines.push(format!(
                "BUG: {} ({} keys): measured {} cycles at {} sample {} exceed the static worst case {} — the WCET analysis or the emulator's timing is wrong",
                p.instrument,
                p.keys.len(),
                p.measured_max,
                p.measured_max_at.run,
                p.measured_max_at.sample,
                p.static_cycles
            ));
        }
        lines
    }

    /// The exit code `tactus budget` gives: 0 fits (and sound), 1 otherwise.
    pub fn exit_code(&self) -> u8 {
        if self.fits && self.unsound().is_empty() {
            0
        } else {
            1
        }
    }

    /// The layout with explicit boards as planned, for `--write-plan`: `layout` with its
    /// `board_kind` and one `[[board]]` per board.
    pub fn with_boards(
        &self,
        layout: &tactus_runtime::keyboard::Layout,
        board_kind: &str,
    ) -> tactus_runtime::keyboard::Layout {
        let mut l = layout.clone();
        l.board_kind = Some(board_kind.to_string());
        l.boards = self
            .boards
            .iter()
            .filter_map(|b| {
                Some(tactus_runtime::keyboard::BoardKeys {
                    keys: [*b.keys.first()?, *b.keys.last()?],
                })
            })
            .collect();
        l
    }

    /// The one line saying which boards leave the quiescent-key guard out
    /// ([`boards::BoardVerdict::guard_off`]), `None` when every board keeps what its
    /// programs ask for.
    pub fn guard_line(&self) -> Option<String> {
        let off: Vec<usize> = (0..self.boards.len())
            .filter(|&i| self.boards[i].guard_off)
            .collect();
        if off.is_empty() {
            return None;
        }
        // Board numbers (from 1) as ranges: "1–18, 20".
        let mut runs: Vec<(usize, usize)> = Vec::new();
        for &i in &off {
            match runs.last_mut() {
                Some((_, b)) if *b + 1 == i => *b = i,
                _ => runs.push((i, i)),
            }
        }
        let list = runs
            .iter()
            .map(|&(a, b)| match a == b {
                true => format!("{}", a + 1),
                false => format!("{}–{}", a + 1, b + 1),
            })
            .collect::<Vec<_>>()
            .join(", ");
        let (n, all) = (off.len(), self.boards.len());
        Some(format!(
            "quiescent-key guard: left out on board{} {list} ({n} of {all}): its static cost would cost boards (docs/language.md, \"Quiescent keys\")",
            if n == 1 { "" } else { "s" }
        ))
    }

    /// The report as text: per instrument static / measured, per board one row (keys, keys
    /// per core, cycles per core, utilisation, headroom), the board count, the verdict, the
    /// worst board and key with its worst path, what fits.
    pub fn text(&self) -> String {
        let b = &self.board;
        let cps = b.cycles_per_sample;
        let nkeys: usize = self.programs.iter().map(|p| p.keys.len()).sum();
        let all_pens = self.programs.iter().all(|p| p.pen);
        let unit = |n: usize| match (all_pens, n) {
            (true, 1) => "pen",
            (true, _) => "pens",
            (false, 1) => "key",
            (false, _) => "keys",
        };
        let mut s = String::new();
        let _ = writeln!(
            s,
            "budget of {} ({}): {nkeys} {} on {} {} boards: {} core{} × {cps} cycles per sample ({} MHz / {} Hz); a core's interrupt without keys: {} cycles",
            self.layout,
            self.input,
            unit(nkeys),
            if self.planned { "planned" } else { "listed" },
            b.name,
            b.cores,
            if b.cores == 1 { "" } else { "s" },
            b.clock_hz / 1e6,
            b.sample_rate_hz,
            b.isr_cycles
        );
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "{:<18} {:>5} {:>6} {:>8} {:>6} {:>9} {:>8} {:>9} {:>8} {:>9}",
            "instrument",
            "keys",
            "params",
            "static",
            "glue",
            "measured",
            "mean",
            "static /",
            "corpus",
            "samples"
        );
        let _ = writeln!(
            s,
            "{:<18} {:>5} {:>6} {:>8} {:>6} {:>9} {:>8} {:>9} {:>8} {:>9}",
            "", "", "sets", "max", "", "max", "", "measured", "", ""
        );
        for (name, is) in self.by_instrument() {
            let rep = self.representative(&is);
            let p = &self.programs[rep];
            let keys: usize = is.iter().map(|&i| self.programs[i].keys.len()).sum();
            let _ = writeln!(
                s,
                "{:<18} {:>5} {:>6} {:>8} {:>6} {:>9} {:>8.1} {:>9} {:>8} {:>9}",
                name,
                keys,
                is.len(),
                p.static_cycles,
                p.glue_cycles,
                p.measured_max,
                p.measured_mean,
                p.static_over_measured
                    .map_or("–".to_string(), |r| format!("{r:.3}")),
                p.corpus,
                p.samples
            );
            if is.len() > 1 {
                let st = is.iter().map(|&i| self.programs[i].static_cycles);
                let me = is.iter().map(|&i| self.programs[i].measured_max);
                let _ = writeln!(
                    s,
                    "{:<18} other param sets: static {}–{}, measured max {}–{} (brief corpus), all measured ≤ static: {}",
                    "",
                    st.clone().min().unwrap_or(0),
                    st.max().unwrap_or(0),
                    me.clone().min().unwrap_or(0),
                    me.max().unwrap_or(0),
                    if is.iter().all(|&i| self.programs[i].sound) { "yes" } else { "NO" }
                );
            }
        }
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "{:<5} {:<26} {:>9} {:>15} {:>13} {:>11}",
            "board", "keys", "per core", "cycles/sample", "utilisation", "headroom"
        );
        for (i, bv) in self.boards.iter().enumerate() {
            let label = abbreviate(&key_ranges(&bv.keys), 26);
            if let Some(e) = &bv.error {
                let _ = writeln!(s, "{:<5} {:<26} does not fit: {e}", i + 1, label);
                continue;
            }
            let join = |f: &dyn Fn(&boards::CoreVerdict) -> String| {
                bv.cores.iter().map(f).collect::<Vec<_>>().join(" + ")
            };
            let _ = writeln!(
                s,
                "{:<5} {:<26} {:>9} {:>15} {:>13} {:>11}{}",
                i + 1,
                label,
                join(&|c| c.keys.len().to_string()),
                join(&|c| c.cycles.to_string()),
                join(&|c| format!("{:.1}%", 100.0 * c.utilisation)),
                join(&|c| c.headroom.to_string()),
                if bv.fits() { "" } else { "  OVER" }
            );
        }
        if let Some(line) = self.guard_line() {
            let _ = writeln!(s, "{line}");
        }
        if let Some((i, cycles)) = self
            .boards
            .iter()
            .enumerate()
            .filter_map(|(i, bv)| bv.latency_cycles.map(|c| (i, c)))
            .max_by_key(|&(i, c)| (c, std::cmp::Reverse(i)))
        {
            let _ = writeln!(
                s,
                "latency (a key's position sampled by its ADC → the DAC output that answers it): at most {:.2} µs ({cycles} cycles, board {} {})",
                cycles as f64 / b.clock_hz * 1e6,
                i + 1,
                key_ranges(&self.boards[i].keys)
            );
        }
        let _ = writeln!(s);
        let over = self.boards.iter().filter(|b| !b.fits()).count();
        let wb = &self.boards[self.worst_board];
        let wb_name = format!("board {} ({})", self.worst_board + 1, key_ranges(&wb.keys));
        if self.fits {
            let _ = writeln!(
                s,
                "verdict: FITS on {} board{} — the fullest core ({wb_name}) uses {} of {cps} cycles per sample ({} cycles headroom)",
                self.board_count,
                if self.board_count == 1 { "" } else { "s" },
                cps as i64 - self.min_headroom,
                self.min_headroom
            );
        } else if let Some(w) = self.what_fits.iter().find(|w| w.fits_no_board.is_some()) {
            let _ = writeln!(
                s,
                "verdict: DOES NOT FIT — {over} of {} board{} over budget; {} fits no {} board: {}",
                self.board_count,
                if self.board_count == 1 { "" } else { "s" },
                w.instrument,
                b.name,
                w.fits_no_board.as_deref().unwrap_or("")
            );
        } else if wb.error.is_some() {
            let _ = writeln!(
                s,
                "verdict: DOES NOT FIT — {over} of {} board{} over budget; {wb_name}: {}",
                self.board_count,
                if self.board_count == 1 { "" } else { "s" },
                wb.error.as_deref().unwrap_or("")
            );
        } else {
            let need = cps as i64 - self.min_headroom;
            let _ = writeln!(
                s,
                "verdict: DOES NOT FIT — {over} of {} board{} over budget; the fullest core ({wb_name}) needs {need} cycles per sample, {cps} available: over by {} cycles ({:.1} × the budget)",
                self.board_count,
                if self.board_count == 1 { "" } else { "s" },
                -self.min_headroom,
                need as f64 / cps.max(1) as f64
            );
        }
        let wk = &self.worst_key;
        let wp = &self.programs[wk.program];
        let who = if wk.pen {
            format!("pen (slot {})", wk.key)
        } else {
            format!("key: {} ({})", wk.key, wk.note)
        };
        let _ = writeln!(
            s,
            "most expensive {who} {} ({}): {} cycles per sample = update {} + glue {}",
            wp.instrument,
            show_params(&wp.params),
            wk.cycles,
            wp.static_cycles,
            wp.glue_cycles
        );
        let _ = writeln!(
            s,
            "its worst path passes: {}",
            if wp.worst_path.is_empty() {
                "no source-level events".to_string()
            } else {
                collapse_runs(&wp.worst_path).join(" → ")
            }
        );
        if !wp.worst_path_calls.is_empty() {
            let total: u64 = wp
                .worst_path_calls
                .iter()
                .map(|c| c.cycles + crate::runner::BL_CYCLES)
                .sum();
            let _ = writeln!(
                s,
                "calls on it: {} ({total} cycles with their BLs, of the {} static)",
                wp.worst_path_calls
                    .iter()
                    .map(|c| format!(
                        "BL at .text+{:#x} to +{:#x} ({} cycles)",
                        c.site, c.callee, c.cycles
                    ))
                    .collect::<Vec<_>>()
                    .join(", "),
                wp.static_cycles
            );
        }
        let _ = writeln!(s, "what fits on one {} board:", b.name);
        for w in &self.what_fits {
            let pen = self
                .programs
                .iter()
                .any(|p| p.instrument == w.instrument && p.pen);
            let u = if pen { "pen" } else { "key" };
            let count: usize = self
                .programs
                .iter()
                .filter(|p| p.instrument == w.instrument)
                .map(|p| p.keys.len())
                .sum();
            let guard = if w.guard_off {
                format!(
                    ", the quiescent-key guard left out: {} with it",
                    w.guarded_cycles_per_key
                )
            } else {
                String::new()
            };
            if let Some(why) = &w.fits_no_board {
                let _ = writeln!(
                    s,
                    "  {}: no {u} fits one {} board, so its {count} {u}{} of this layout fit none: {why}",
                    w.instrument,
                    b.name,
                    if count == 1 { "" } else { "s" },
                );
                continue;
            }
            let _ = writeln!(
                s,
                "  {}: {} {u}{} ({} cycles per {u} with its glue{guard}); its {count} {u}{} of this layout need{} {} board{}",
                w.instrument,
                w.keys_per_board,
                if w.keys_per_board == 1 { "" } else { "s" },
                w.cycles_per_key,
                if count == 1 { "" } else { "s" },
                if count == 1 { "s" } else { "" },
                w.boards_for_its_keys,
                if w.boards_for_its_keys == 1 { "" } else { "s" }
            );
        }
        s
    }

    /// Per instrument name: (name, indices of its programs), in order of first program.
    fn by_instrument(&self) -> Vec<(String, Vec<usize>)> {
        let mut v: Vec<(String, Vec<usize>)> = Vec::new();
        for (i, p) in self.programs.iter().enumerate() {
            match v.iter_mut().find(|(n, _)| *n == p.instrument) {
                Some((_, is)) => is.push(i),
                None => v.push((p.instrument.clone(), vec![i])),
            }
        }
        v
    }

    /// The costliest of `is` (the lowest index of equals).
    fn representative(&self, is: &[usize]) -> usize {
        *is.iter()
            .max_by_key(|&&i| {
                (
                    self.programs[i].static_cycles + self.programs[i].glue_cycles,
                    std::cmp::Reverse(i),
                )
            })
            .unwrap_or(&is[0])
    }
}

/// Param overrides for people: `name=value, …`, or `defaults` when there are none.
pub fn show_params<'a>(params: impl IntoIterator<Item = (&'a String, &'a String)>) -> String {
    let v: Vec<String> = params
        .into_iter()
        .map(|(n, v)| format!("{n}={v}"))
        .collect();
    if v.is_empty() {
        "defaults".to_string()
    } else {
        v.join(", ")
    }
}

fn corpus_name(s: Size) -> &'static str {
    match s {
        Size::Full => "full",
        Size::Quick => "quick",
        Size::Brief => "brief",
    }
}

/// Keys as ranges: `21–64 (A0–E4), 70 (A#4)`.
pub fn key_ranges(keys: &[u8]) -> String {
    let mut sorted = keys.to_vec();
    sorted.sort_unstable();
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < sorted.len() {
        let mut j = i;
        while j + 1 < sorted.len() && sorted[j + 1] == sorted[j] + 1 {
            j += 1;
        }
        out.push(if i == j {
            format!("{} ({})", sorted[i], note_name(sorted[i]))
        } else {
            format!(
                "{}–{} ({}–{})",
                sorted[i],
                sorted[j],
                note_name(sorted[i]),
                note_name(sorted[j])
            )
        });
        i = j + 1;
    }
    out.join(", ")
}

/// `s` cut at a `, ` boundary to about `max` characters, with `… last item` appended.
pub fn abbreviate(s: &str, max: usize) -> String {
    if s.chars().count() <= max {
        return s.to_string();
    }
    let items: Vec<&str> = s.split(", ").collect();
    let mut out = String::new();
    for it in &items[..items.len() - 1] {
        if out.chars().count() + it.chars().count() > max {
            break;
        }
        out.push_str(it);
        out.push_str(", ");
    }
    out.push_str("… ");
    out.push_str(items[items.len() - 1]);
    out
}

/// `items` with each run of equal neighbours written once, followed by `(× n)` when `n > 1`:
/// a worst path through a 225-element delay line reads "line 85: … (× 225)", not the same
/// label 225 times.
pub fn collapse_runs(items: &[String]) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < items.len() {
        let n = items[i..].iter().take_while(|x| **x == items[i]).count();
        out.push(if n > 1 {
            format!("{} (× {n})", items[i])
        } else {
            items[i].clone()
        });
        i += n;
    }
    out
}

/// Samples of each corpus run measured for a program that fits no board ([`ProgramReport::corpus`]
/// `token`): a few milliseconds of each run, enough to compare measured with static.
pub const TOKEN_SAMPLES: usize = 200;

/// Progress of [`keyboard_budget`]: a stage name, units done, units in all.
pub type Progress<'a> = &'a mut dyn FnMut(&str, usize, usize);

/// Computes the budget of a keyboard: each program's static cost, glue and measurement;
/// the boards (planned, or the layout's checked); the verdict.
///
/// Errors: [`VerdictError`] naming the instrument when a program's cost cannot be found
/// (its code cannot be analysed or run), or a key's program does not exist.
pub fn keyboard_budget(
    input: &BudgetInput,
    progress: Progress<'_>,
) -> Result<BudgetReport, VerdictError> {
    let board = &input.board;
    let bad = |who: &str, e: &dyn std::fmt::Display| VerdictError(format!("{who}: {e}"));
    if input.keys.is_empty() {
        return Err(VerdictError(format!("{}: no keys", input.input)));
    }
    let programs: Vec<Program> = input.programs.iter().map(|p| p.program.clone()).collect();
    let costs =
        ProgramCosts::new(&programs, board, &input.limiter).map_err(|e| bad(&input.input, &e))?;

    // Static cost per program, then measurement: the costliest variant of each instrument
    // over the full (or quick) corpus, its other param sets over the brief one.
    let mut statics = Vec::with_capacity(programs.len());
    for (p, pi) in programs.iter().zip(&input.programs) {
        statics.push(p.static_cost().map_err(|e| bad(&pi.instrument, &e))?);
    }
    // Whether one key of each distinct code fits a board at all (the rule of
    // `boards::fits_no_board`): one that does not is measured over a token corpus only —
    // the verdict does not depend on the measurement, and the bowed string's 100,193 cycles
    // a sample over the quick corpus took 270 CPU-s.
    let unfit = boards::fits_no_board_each(&programs, &costs, board, &input.limiter)
        .map_err(|e| bad(&input.input, &e))?;
    let mut reports = Vec::with_capacity(programs.len());
    for (i, pi) in input.programs.iter().enumerate() {
        progress("measuring", i, programs.len());
        let representative = !input.programs.iter().enumerate().any(|(j, q)| {
            q.instrument == pi.instrument && (statics[j].cycles, i) > (statics[i].cycles, j)
        });
        let token = unfit[i].is_some();
        let size = match (representative && !token, input.quick) {
            (true, false) => Size::Full,
            (true, true) => Size::Quick,
            (false, _) => Size::Brief,
        };
        let fp = &pi.program.fixed;
        let mut runs = corpus::corpus(fp, size);
        if token {
            for r in &mut runs {
                r.records.truncate(TOKEN_SAMPLES);
            }
        }
        let measured = budget::measure_key_update(
            &pi.program.thumb,
            fp,
            &pi.program.params,
            &runs,
            input.engine,
        )
        .map_err(|e: BudgetError| bad(&pi.instrument, &e))?;
        let cost = ProgramCost {
            static_cost: statics[i].clone(),
            measured,
        };
        let glue = costs.key_cycles[i] - statics[i].cycles;
        reports.push(ProgramReport {
            instrument: pi.instrument.clone(),
            params: pi.params.iter().cloned().collect(),
            keys: input
                .keys
                .iter()
                .filter(|k| k.1 == i)
                .map(|k| k.0)
                .collect(),
            pen: fp.program.is_pen(),
            static_cycles: cost.static_cost.cycles,
            glue_cycles: glue,
            measured_max: cost.measured.worst,
            measured_mean: cost.measured.mean(),
            static_over_measured: cost.ratio(),
            sound: cost.sound(),
            corpus: match token {
                true => "token".to_string(),
                false => corpus_name(size).to_string(),
            },
            samples: corpus::samples(&runs),
            measured_max_at: WorstAt {
                run: cost.measured.worst_at.0.clone(),
                sample: cost.measured.worst_at.1,
            },
            worst_path: cost
                .static_cost
                .events
                .iter()
                .filter_map(|(_, n)| describe_note(n, &pi.sources))
                .collect(),
            worst_path_calls: cost
                .static_cost
                .calls
                .iter()
                .map(|&(site, callee, cycles)| PathCall {
                    site,
                    callee,
                    cycles,
                })
                .collect(),
        });
    }

    let keys: Vec<PlanKey> = input
        .keys
        .iter()
        .map(|&(key, program)| PlanKey { key, program })
        .collect();
    let (boards, planned) = (&input.plan.boards, input.plan.planned);
    let worst_board = (0..boards.len())
        .min_by_key(|&i| (boards[i].min_headroom(), i))
        .unwrap_or(0);
    let min_headroom = boards.get(worst_board).map_or(0, |b| b.min_headroom());
    let worst = (0..keys.len())
        .max_by_key(|&i| (costs.key_cycles[keys[i].program], std::cmp::Reverse(i)))
        .unwrap_or(0);
    let wk = keys[worst];
    // Core 0's: with the watchdog's feed when the programs run it.
    let isr_cycles = FirmwareImage::build(&programs, &[], board, &input.limiter)
        .ok()
        .and_then(|i| i.wcet(0))
        .map_or(0, |w| w.bound());

    // What fits: per instrument, its costliest param set's keys on one board.
    let mut what_fits = Vec::new();
    let mut seen: Vec<&str> = Vec::new();
    for (i, pi) in input.programs.iter().enumerate() {
        if seen.contains(&pi.instrument.as_str()) {
            continue;
        }
        seen.push(&pi.instrument);
        let rep = (0..programs.len())
            .filter(|&j| input.programs[j].instrument == pi.instrument)
            .max_by_key(|&j| (costs.key_cycles[j], std::cmp::Reverse(j)))
            .unwrap_or(i);
        progress("what fits", what_fits.len(), input.programs.len());
        let densest = boards::densest_board(&programs, &costs, rep, board, &input.limiter)
            .map_err(|e| bad(&pi.instrument, &e))?;
        let fits_no_board = match densest {
            Some(_) => None,
            None => unfit[rep].clone(),
        };
        let n = densest.as_ref().map_or(0, |b| b.keys.len()) as u64;
        let guard_off = densest.is_some_and(|b| b.guard_off);
        let count = input
            .keys
            .iter()
            .filter(|k| input.programs[k.1].instrument == pi.instrument)
            .count() as u64;
        what_fits.push(WhatFits {
            instrument: pi.instrument.clone(),
            cycles_per_key: match guard_off {
                true => costs.plain_key_cycles[rep],
                false => costs.key_cycles[rep],
            },
            guard_off,
            guarded_cycles_per_key: costs.key_cycles[rep],
            keys_per_board: n,
            boards_for_its_keys: if n == 0 { 0 } else { count.div_ceil(n) },
            fits_no_board,
        });
    }

    Ok(BudgetReport {
        layout: input.name.clone(),
        input: input.input.clone(),
        board: BoardKind {
            name: board.name.clone(),
            clock_hz: board.clock_hz,
            cores: board.cores,
            sample_rate_hz: board.sample_rate_hz,
            cycles_per_sample: board.cycles_per_sample(),
            isr_cycles,
        },
        planned,
        programs: reports,
        board_count: boards.len(),
        fits: boards.iter().all(BoardVerdict::fits),
        worst_board,
        min_headroom,
        worst_key: WorstKey {
            key: wk.key,
            note: note_name(wk.key),
            pen: input.programs[wk.program].program.fixed.program.is_pen(),
            instrument: input.programs[wk.program].instrument.clone(),
            program: wk.program,
            cycles: costs.key_cycles[wk.program],
        },
        what_fits,
        boards: boards.clone(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_ranges_name_notes() {
        assert_eq!(key_ranges(&[23, 21, 22, 60]), "21–23 (A0–B0), 60 (C4)");
        assert_eq!(abbreviate("a, b, c, d, e", 6), "a, b, … e");
        assert_eq!(abbreviate("a, b", 6), "a, b");
    }

    #[test]
    fn runs_of_equal_labels_are_counted() {
        let v: Vec<String> = ["a", "b", "b", "b", "a", "c", "c"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        assert_eq!(collapse_runs(&v), ["a", "b (× 3)", "a", "c (× 2)"]);
        assert!(collapse_runs(&[]).is_empty());
    }
}
