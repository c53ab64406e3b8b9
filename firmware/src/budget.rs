//! The timing budget of a keyboard: does every key's update fit in one sample period of the
//! board's cores?
//!
//! Per compiled program (an instrument with one set of param overrides):
//! - [`static_update`]: the static worst case of the Thumb update, from
//!   [`tactus_isa::wcet::analyse`] on the `.text` (loaded at [`LOAD_ADDR`], as the
//!   runner loads it), plus [`BL_CYCLES`] for the caller's `BL` — the same convention as the
//!   runner's measured [`crate::runner::Sample::cycles`] (first instruction to return
//!   inclusive, plus the `BL`), so the two compare directly. The backend's long branches
//!   (`BL` to a label of the same function) are analysed as branches
//!   ([`wcet::Bounds::branch_links`]), and its flow facts (pairs of `if` bodies that never
//!   both run) split the analysis into scenarios ([`wcet::Bounds::unexecuted`]). It also returns the worst path
//!   and the source-level events on it (the Thumb backend's notes: `if` conditions with
//!   their source spans, `emit`s), rendered with [`describe_note`].
//! - [`measure_update`]: the update run in the emulator over a corpus
//!   ([`crate::corpus`]), re-initialised before each run: worst and mean cycles.
//! - [`program_cost`]: both, and whether measured ≤ static holds (if not, the analysis or
//!   the emulator has a bug: [`ProgramCost::sound`]).
//!
//! Whether the keys fit their boards is not decided here but by the static analysis of each
//! board's actual sample interrupt ([`crate::boards`]).

use crate::measure::{CycleStats, Run};
use crate::runner::{RunError, UpdateRunner, BL_CYCLES};
use crate::Interface;
use std::fmt;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::sources::SourceMap;
use tactus_compiler::thumb::{ThumbError, ThumbObject};
use tactus_isa::wcet::{self, Bounds, Image, WcetError};

/// Where the runner loads the Thumb `.text` (start of SRAM); the static analysis uses the
/// same addresses.
pub const LOAD_ADDR: u32 = 0x2000_0000;

/// Why a program's cost could not be found.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BudgetError {
    /// The Thumb backend could not compile the program.
    Compile(ThumbError),
    /// The object has no update (or init) function symbol.
    MissingSymbol(String),
    /// The static analysis failed (an indirect branch, an unbounded loop, …).
    Wcet(WcetError),
    /// The update could not be run in the emulator.
    Run(RunError),
}

impl fmt::Display for BudgetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BudgetError::Compile(e) => write!(f, "cannot compile to Thumb code: {e}"),
            BudgetError::MissingSymbol(s) => write!(f, "the compiled code has no `{s}`"),
            BudgetError::Wcet(e) => write!(f, "static WCET analysis failed: {e}"),
            BudgetError::Run(e) => write!(f, "cannot run the update in the emulator: {e}"),
        }
    }
}

impl std::error::Error for BudgetError {}

/// The static worst case of an update.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StaticCost {
    /// Worst-case cycles per key-sample: the update's first instruction to its return
    /// inclusive, plus [`BL_CYCLES`] for the caller's `BL`.
    pub cycles: u64,
    /// Start offsets (bytes into `.text`) of the blocks on a worst path, in execution order.
    pub path: Vec<u32>,
    /// The backend's notes (source-level events) inside the blocks of that path, in
    /// execution order, each once: `(offset into .text, note)`.
    pub events: Vec<(usize, String)>,
    /// The calls (`BL` to a routine outside the update; the long branches inside it are
    /// not calls) on that path, in execution order: `(offset of the BL, offset of the
    /// callee, the callee's worst case in cycles)`.
    pub calls: Vec<(u32, u32, u64)>,
}

/// [`StaticCost`] of the update function of `obj`.
///
/// Errors: [`BudgetError::MissingSymbol`], [`BudgetError::Wcet`].
pub fn static_update(obj: &ThumbObject) -> Result<StaticCost, BudgetError> {
    let name = obj.update_name();
    let w = function_wcet(obj, &name)?;
    let end_of = |start: u32| {
        w.blocks
            .iter()
            .find(|b| b.start == start)
            .map_or(start, |b| b.end)
    };
    let mut events = Vec::new();
    let mut calls = Vec::new();
    let mut path = Vec::with_capacity(w.path.len());
    for &start in &w.path {
        let (s, e) = (start - LOAD_ADDR, end_of(start) - LOAD_ADDR);
        path.push(s);
        for c in &w.calls {
            if (start..end_of(start)).contains(&c.site) {
                calls.push((c.site - LOAD_ADDR, c.callee - LOAD_ADDR, c.cycles));
            }
        }
        for (off, note) in &obj.code.notes {
            if (s as usize..e as usize).contains(off) && !events.iter().any(|(o, _)| o == off) {
                events.push((*off, note.clone()));
            }
        }
    }
    Ok(StaticCost {
        cycles: w.cycles + BL_CYCLES,
        path,
        events,
        calls,
    })
}

/// The static analysis of one function of `obj` (loaded at [`LOAD_ADDR`]; the backend's
/// code is position independent, so the cycles hold anywhere in SRAM): cycles from its first
/// instruction to its return inclusive (without the caller's `BL`), worst path, blocks and
/// calls. The backend's code is forward-only (no loops), so it needs no loop bounds. Its long
/// branches are `BL`s to labels of the same function: a `BL` whose target lies inside the
/// function is declared a branch, not a call ([`wcet::Bounds::branch_links`]; found one
/// layer at a time: a long branch analysed as a call hides the ones in the code it reaches).
/// The backend's flow facts (`Code::exclusive`) then tighten it ([`MAX_FACT_BLOCKS`]).
///
/// Errors: [`BudgetError::MissingSymbol`], [`BudgetError::Wcet`].
pub fn function_wcet(obj: &ThumbObject, name: &str) -> Result<wcet::Wcet, BudgetError> {
    let (off, size) = obj
        .symbol(name)
        .ok_or_else(|| BudgetError::MissingSymbol(name.to_string()))?;
    let image = Image {
        base: LOAD_ADDR,
        bytes: &obj.code.text,
    };
    let entry = LOAD_ADDR + off as u32;
    let inside = entry..entry + size as u32;
    let mut bounds = Bounds::new();
    // A linear sweep finds the long branches up front: one analysis instead of one per layer
    // (plucked_string's delay line chains over 200 of them, each hiding the next, and as
    // calls their costs double per layer). A sweep can misread a literal pool; the loop
    // below still catches any long branch it missed, and a misread `BL` at a non-instruction
    // address is never consulted.
    for site in long_branch_sites(&obj.code.text, off, size) {
        bounds.branch_links.insert(LOAD_ADDR + site as u32);
    }
    let w = loop {
        let w = wcet::analyse(&image, entry, &bounds).map_err(BudgetError::Wcet)?;
        let before = bounds.branch_links.len();
        for c in &w.calls {
            if inside.contains(&c.callee) {
                bounds.branch_links.insert(c.site);
            }
        }
        if bounds.branch_links.len() == before {
            break w;
        }
    };
    Ok(with_flow_facts(&image, entry, bounds, &obj.code.exclusive)?.unwrap_or(w))
}

/// Offsets (in `text`) of the `BL`s in `text[off..off + size]`, decoded in a linear sweep,
/// whose targets lie inside that range: the backend's long branches within a function.
fn long_branch_sites(text: &[u8], off: usize, size: usize) -> Vec<usize> {
    let end = (off + size).min(text.len());
    let half = |at: usize| -> u16 {
        match text.get(at..at + 2) {
            Some(b) => u16::from_le_bytes([b[0], b[1]]),
            None => 0,
        }
    };
    let mut sites = Vec::new();
    let mut at = off;
    while at + 2 <= end {
        let hw1 = half(at);
        let width = tactus_isa::decode::size_of(hw1) as usize;
        if width == 4 {
            if let tactus_isa::decode::Instr::Bl { offset } =
                tactus_isa::decode::decode(hw1, half(at + 2))
            {
                let target = at as i64 + 4 + i64::from(offset);
                if (off as i64..end as i64).contains(&target) {
                    sites.push(at);
                }
            }
        }
        at += width;
    }
    sites
}

/// Most distinct blocks of the backend's exclusion facts used (2^n subsets are
/// enumerated); facts about further blocks are left out (the bound stays sound, only
/// looser).
pub const MAX_FACT_BLOCKS: usize = 20;

/// The backend's flow facts (`Code::exclusive`: pairs of `if` bodies no call runs both of)
/// applied: for every maximal set of fact blocks that may run together, the analysis with
/// the other fact blocks declared unexecuted ([`wcet::Bounds::unexecuted`]); the worst of
/// these scenarios. Every call runs such a set, so the maximum is a bound; it excludes
/// exactly the paths through two exclusive bodies. `None` without facts.
fn with_flow_facts(
    image: &Image<'_>,
    entry: u32,
    bounds: Bounds,
    exclusive: &[(usize, usize)],
) -> Result<Option<wcet::Wcet>, BudgetError> {
    let mut blocks: Vec<u32> = Vec::new();
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    for &(a, b) in exclusive {
        let (a, b) = (LOAD_ADDR + a as u32, LOAD_ADDR + b as u32);
        let mut index = |x: u32| match blocks.iter().position(|&y| y == x) {
            Some(i) => Some(i),
            None if blocks.len() < MAX_FACT_BLOCKS => {
                blocks.push(x);
                Some(blocks.len() - 1)
            }
            None => None,
        };
        if let (Some(i), Some(j)) = (index(a), index(b)) {
            if i != j {
                pairs.push((i, j));
            }
        }
    }
    if pairs.is_empty() {
        return Ok(None);
    }
    let n = blocks.len();
    let conflict = |set: u32| {
        pairs
            .iter()
            .any(|&(i, j)| set & (1 << i) != 0 && set & (1 << j) != 0)
    };
    let mut best: Option<wcet::Wcet> = None;
    for set in 0..1u32 << n {
        // Only maximal sets of blocks that may run together: adding any other conflicts.
        if conflict(set) || (0..n).any(|k| set & (1 << k) == 0 && !conflict(set | (1 << k))) {
            continue;
        }
        let mut b = bounds.clone();
        b.unexecuted = (0..n)
            .filter(|&k| set & (1 << k) == 0)
            .map(|k| blocks[k])
            .collect();
        let w = wcet::analyse(image, entry, &b).map_err(BudgetError::Wcet)?;
        if best.as_ref().is_none_or(|x| w.cycles > x.cycles) {
            best = Some(w);
        }
    }
    Ok(best)
}

/// Runs the update of `obj` over `runs` in the emulator (re-initialised before each run)
/// and returns the cycles per key-sample (including the `BL`, as [`StaticCost::cycles`]).
///
/// Errors: [`BudgetError::MissingSymbol`], [`BudgetError::Run`] (a fault, a runaway call).
pub fn measure_update(
    obj: &ThumbObject,
    fp: &FixedProgram,
    runs: &[Run],
) -> Result<CycleStats, BudgetError> {
    measure_update_with(obj, fp, runs, tactus_emulator::Engine::default())
}

/// [`measure_update`] on the emulator engine `engine` (the same cycles on every engine).
///
/// Errors: as [`measure_update`].
pub fn measure_update_with(
    obj: &ThumbObject,
    fp: &FixedProgram,
    runs: &[Run],
    engine: tactus_emulator::Engine,
) -> Result<CycleStats, BudgetError> {
    measure_key_update(obj, fp, &fp.nominal_param_block(), runs, engine)
}

/// [`measure_update_with`] for one key of a shared program: `params` is its param block
/// (`FixedProgram::param_block`), written into its state before each `init`.
///
/// Errors: as [`measure_update_with`].
pub fn measure_key_update(
    obj: &ThumbObject,
    fp: &FixedProgram,
    params: &[i32],
    runs: &[Run],
    engine: tactus_emulator::Engine,
) -> Result<CycleStats, BudgetError> {
    let sym = |name: String| {
        obj.symbol(&name)
            .map(|(o, _)| o as u32)
            .ok_or(BudgetError::MissingSymbol(name))
    };
    let init = sym(obj.init_name())?;
    let update = sym(obj.update_name())?;
    let iface = Interface {
        params: params.to_vec(),
        ..Interface::new(fp, &obj.stem, &obj.out)
    };
    let mut runner = UpdateRunner::from_code(&obj.code.text, LOAD_ADDR, init, update, iface)
        .map_err(BudgetError::Run)?;
    runner.board().config.engine = engine;
    let mut stats = CycleStats::default();
    for run in runs {
        runner.init().map_err(BudgetError::Run)?;
        for (n, rec) in run.records.iter().enumerate() {
            let s = runner.step(rec).map_err(BudgetError::Run)?;
            stats.add(s.cycles, &run.label, n);
        }
    }
    Ok(stats)
}

/// A program's static and measured cost.
#[derive(Clone, Debug)]
pub struct ProgramCost {
    /// The static worst case.
    pub static_cost: StaticCost,
    /// The measured cycles over the corpus.
    pub measured: CycleStats,
}

impl ProgramCost {
    /// Whether the measured worst case is within the static one (it must be: otherwise the
    /// analysis or the emulator's timing is wrong).
    pub fn sound(&self) -> bool {
        self.measured.worst <= self.static_cost.cycles
    }

    /// Static over measured worst case (≥ 1 when sound; 1 is a tight bound). `None` with no
    /// measurement.
    pub fn ratio(&self) -> Option<f64> {
        (self.measured.worst > 0)
            .then(|| self.static_cost.cycles as f64 / self.measured.worst as f64)
    }
}

/// Compiles nothing: analyses `obj` statically and measures it over `runs`.
///
/// Errors: as [`static_update`] and [`measure_update`].
pub fn program_cost(
    obj: &ThumbObject,
    fp: &FixedProgram,
    runs: &[Run],
) -> Result<ProgramCost, BudgetError> {
    Ok(ProgramCost {
        static_cost: static_update(obj)?,
        measured: measure_update(obj, fp, runs)?,
    })
}

/// The note name of a MIDI key number: 60 → `C4`, 21 → `A0`, 61 → `C#4` (scientific pitch
/// notation, MIDI 60 = middle C = C4).
pub fn note_name(key: u8) -> String {
    const NAMES: [&str; 12] = [
        "C", "C#", "D", "D#", "E", "F", "F#", "G", "G#", "A", "A#", "B",
    ];
    format!("{}{}", NAMES[key as usize % 12], key as i32 / 12 - 1)
}

/// A backend note rendered for people, given the instrument's source files (the program's
/// [`SourceMap`]: its file and those it imports): an `if condition vN @start..end` becomes
/// the source line of the condition in its own file, prefixed by the enclosing
/// `component`/`instrument` and followed by the head of the comment just above the
/// statement, if any (`grand_piano line 151: on s >= s_string — Hammer–string impact`).
/// Notes without a span (`emit strike`), or whose span is in no file, are returned as they
/// are; `None` for an empty span (`@0..0`: a condition the compiler generated, with no
/// source text of its own).
pub fn describe_note(note: &str, sources: &SourceMap) -> Option<String> {
    let Some((a, b)) = note.rsplit_once('@').and_then(|(_, s)| {
        let (a, b) = s.trim().split_once("..")?;
        Some((a.parse::<usize>().ok()?, b.parse::<usize>().ok()?))
    }) else {
        return Some(note.to_string());
    };
    if b <= a {
        return None;
    }
    let (file, local) = sources.locate(&(a..b));
    let source = sources.get(file).text.as_str();
    let a = a - sources.get(file).base;
    if a > source.len() || local.start != a || !source.is_char_boundary(a) {
        return Some(note.to_string());
    }
    let lines: Vec<&str> = source.lines().collect();
    let line_no = source[..a].matches('\n').count();
    let Some(line) = lines.get(line_no) else {
        return Some(note.to_string());
    };
    let mut text: String = line.split("//").next().unwrap_or("").trim().to_string();
    if text.chars().count() > 72 {
        text = text.chars().take(70).collect::<String>() + "…";
    }
    let owner = lines[..line_no]
        .iter()
        .rev()
        .find_map(|l| {
            let t = l.trim_start();
            ["component ", "instrument "]
                .iter()
                .find_map(|k| t.strip_prefix(k))
                .and_then(|r| r.split_whitespace().next())
        })
        .map(|n| n.trim_end_matches('{').to_string());
    // The head of the comment block directly above the statement.
    let mut i = line_no;
    let mut head = None;
    while i > 0 && lines[i - 1].trim_start().starts_with("//") {
        i -= 1;
        head = Some(lines[i].trim_start().trim_start_matches('/').trim());
    }
    let head = head.map(|h| {
        let cut = h.find([':', '.', ';', '(']).unwrap_or(h.len());
        h[..cut].trim().to_string()
    });
    let mut s = String::new();
    if let Some(o) = owner {
        s.push_str(&o);
        s.push(' ');
    }
    s.push_str(&format!("line {}: {text}", line_no + 1));
    if let Some(h) = head.filter(|h| !h.is_empty()) {
        s.push_str(" — ");
        s.push_str(&h);
    }
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::corpus::{self, Size};
    use tactus_compiler::lower::Config;
    use tactus_compiler::sources::Origin;

    fn compile(src: &str) -> (FixedProgram, ThumbObject) {
        let l = tactus_compiler::compile(src, &Config::default()).unwrap();
        let fp = FixedProgram::new(&l.program);
        let obj = tactus_compiler::thumb::compile(&fp).unwrap();
        (fp, obj)
    }

    const INSTRUMENTS: [(&str, &str); 4] = [
        (
            "grand_piano",
            include_str!("../../instruments/grand_piano.tactus"),
        ),
        (
            "harpsichord",
            include_str!("../../instruments/harpsichord.tactus"),
        ),
        (
            "harpsichord_2x8",
            include_str!("../../instruments/harpsichord_2x8.tactus"),
        ),
        ("hammond", include_str!("../../instruments/hammond.tactus")),
    ];

    /// Soundness: the static worst case bounds every measured call of an instrument over
    /// the whole (full) corpus, and the worst path's events are notes of the code.
    /// Tightness guard: static ≤ 2 × measured (analysing the backend's long branches — `BL`
    /// to a label of the same function — as calls counted the update's tail twice and gave
    /// 2.2× on the piano). Returns static / measured.
    fn static_bounds_measured(name: &str, src: &str) -> f64 {
        let (fp, obj) = compile(src);
        static_bounds_measured_on(name, &fp, &obj)
    }

    /// [`static_bounds_measured`] of a program already compiled.
    fn static_bounds_measured_on(name: &str, fp: &FixedProgram, obj: &ThumbObject) -> f64 {
        let mut runs = corpus::corpus(fp, Size::Full);
        // A contact-point instrument of thousands of values (a bank, a string) runs a brief
        // corpus, each run cut to 4 M value evaluations (a fifth of what a piano key costs
        // to emulate over the full one).
        if fp.program.values.len() > 2_000 {
            runs = corpus::corpus(fp, Size::Brief);
            let cap = fp.program.samples_within(4_000_000);
            for r in &mut runs {
                r.records.truncate(cap);
            }
        }
        let c = program_cost(obj, fp, &runs).unwrap();
        let ratio = c.ratio().unwrap();
        println!(
            "{name}: static {} measured worst {} mean {:.1} static/measured {ratio:.3} over {} samples (worst at {} sample {})",
            c.static_cost.cycles,
            c.measured.worst,
            c.measured.mean(),
            c.measured.calls,
            c.measured.worst_at.0,
            c.measured.worst_at.1
        );
        assert!(
            c.sound(),
            "{name}: measured {} > static {} at {:?}",
            c.measured.worst,
            c.static_cost.cycles,
            c.measured.worst_at
        );
        assert!(ratio <= 2.0, "{name}: static/measured {ratio:.3}");
        assert_eq!(c.measured.calls as usize, corpus::samples(&runs));
        assert!(c.measured.best <= c.measured.worst && c.measured.best > BL_CYCLES);
        assert!(!c.static_cost.path.is_empty());
        for (off, note) in &c.static_cost.events {
            assert!(obj.code.notes.contains(&(*off, note.clone())));
        }
        ratio
    }

    fn shipped(name: &str) -> &'static str {
        INSTRUMENTS.iter().find(|(n, _)| *n == name).unwrap().1
    }

    // One test per instrument (the harness runs them in parallel).

    /// The tightness target: the piano's static bound within 20 % of its measured
    /// worst case over the full corpus.
    #[test]
    fn static_bounds_measured_grand_piano_within_20_percent() {
        let ratio = static_bounds_measured("grand_piano", shipped("grand_piano"));
        assert!(
            ratio <= 1.2,
            "grand_piano: static/measured {ratio:.3} > 1.2"
        );
    }
    #[test]
    fn static_bounds_measured_harpsichord() {
        static_bounds_measured("harpsichord", shipped("harpsichord"));
    }
    #[test]
    fn static_bounds_measured_harpsichord_2x8() {
        static_bounds_measured("harpsichord_2x8", shipped("harpsichord_2x8"));
    }
    #[test]
    fn static_bounds_measured_hammond() {
        static_bounds_measured("hammond", shipped("hammond"));
    }

    /// Every other instrument in `instruments/` (added after these tests were written) is
    /// checked too; one the Thumb backend does not support is reported and skipped (`tactus
    /// budget` reports it as an error).
    #[test]
    fn static_bounds_measured_other_instruments() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments");
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            let Some(stem) = p.file_stem().and_then(|s| s.to_str()) else {
                continue;
            };
            if p.extension().is_none_or(|x| x != "tactus")
                || INSTRUMENTS.iter().any(|(n, _)| *n == stem)
            {
                continue;
            }
            let src = std::fs::read_to_string(&p).unwrap();
            let l = tactus_compiler::compile(&src, &Config::default()).unwrap();
            let fp = FixedProgram::new(&l.program);
            match tactus_compiler::thumb::compile(&fp) {
                Ok(obj) => {
                    static_bounds_measured_on(stem, &fp, &obj);
                }
                Err(e) => println!("{stem}: skipped: {e}"),
            }
        }
    }

    /// The worst path of the piano passes `if` bodies of its source (which ones depends on
    /// the code generator), each rendered as a source line of the piano or of its
    /// escapement component, in execution order (increasing code offsets: the update is
    /// forward-only).
    #[test]
    fn piano_worst_path_names_source_events() {
        let (_, obj) = compile(INSTRUMENTS[0].1);
        let sources = tactus_compiler::imports::link(
            "grand_piano",
            Origin::Text,
            INSTRUMENTS[0].1,
            &mut tactus_compiler::imports::NoFiles,
        )
        .sources;
        let s = static_update(&obj).unwrap();
        let described: Vec<String> = s
            .events
            .iter()
            .filter_map(|(_, n)| describe_note(n, &sources))
            .collect();
        println!("{described:#?}");
        assert!(!described.is_empty());
        for d in &described {
            assert!(
                d.starts_with("emit ")
                    || d.starts_with("grand_piano line ")
                    || d.starts_with("escapement line "),
                "{d}"
            );
        }
        assert!(
            s.events.windows(2).all(|w| w[0].0 < w[1].0),
            "{:?}",
            s.events
        );
    }

    #[test]
    fn notes_render_as_source_lines() {
        let text = "instrument a {\n  // Impact: a comment\n  on x >= y {\n  }\n}\n";
        let src = &SourceMap::new("a.tactus", Origin::Text, text);
        let at = text.find("x >= y").unwrap();
        let d = describe_note(&format!("if condition v3 @{at}..{}", at + 6), src);
        assert_eq!(d.as_deref(), Some("a line 3: on x >= y { — Impact"));
        assert_eq!(describe_note("emit strike", src).unwrap(), "emit strike");
        assert_eq!(
            describe_note("if condition v3 @999..1000", src).unwrap(),
            "if condition v3 @999..1000"
        );
        assert_eq!(describe_note("if condition v9 @0..0", src), None);
    }

    #[test]
    fn note_names() {
        assert_eq!(note_name(21), "A0");
        assert_eq!(note_name(60), "C4");
        assert_eq!(note_name(61), "C#4");
        assert_eq!(note_name(108), "C8");
        assert_eq!(note_name(0), "C-1");
    }
}
