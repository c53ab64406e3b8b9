//! `tactus budget`: does a keyboard fit the board's cycle budget?
//!
//! For each distinct program of the layout (an instrument with one set of params) the
//! command compiles the Thumb update, takes its static worst case (`wcet::analyse` on the
//! machine code, plus the caller's `BL`: the runner's cycle convention), runs it in the
//! emulator over the stimulus corpus (`tactus_firmware::corpus`) and checks measured ≤
//! static. Each key then costs its program's static worst case plus the board's
//! `io_cycles_per_key`; the keys go to the cores by longest processing time first, and each
//! core's sum plus `isr_overhead_cycles` must stay within `clock_hz / sample_rate_hz`.
//!
//! Exit codes: 0 fits; 1 does not fit (or measured > static, an analysis bug); 2 bad input.

use crate::check_cmd::{compile_reporting, parse_override};
use crate::source;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;
use std::process::ExitCode;
use tactus_compiler::fixed::FixedProgram;
use tactus_firmware::budget::{self, describe_note, note_name, Plan, ProgramCost};
use tactus_firmware::corpus::{self, Size};
use tactus_firmware::image::FirmwareImage;
use tactus_runtime::keyboard::{self, Board, KeyAssignment};
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
  tactus budget grand_piano --keys 12 --board rp2040_200mhz
  tactus budget harpsichord --keys 88 --json > budget.json

How to read it: `static` is the proven worst case of one key's update (cycles per
key-sample, call included); `measured` the worst and mean over the stimulus corpus in the
emulator (always ≤ static, else the analysis has a bug). A key costs static + the board's
io_cycles_per_key; a core's load is its keys plus isr_overhead_cycles, against
clock_hz / sample_rate_hz cycles per sample. `what fits` is the most keys of each
instrument the board could run. The costliest param set of each instrument is measured over
the full corpus (presses, repeated notes, trills, half dips, noise, glitches, random words),
its other param sets (graded params) over a brief one; `--quick` shrinks the full one.

Exit codes: 0 fits, 1 does not fit (or measured > static), 2 bad input.")]
pub struct BudgetArgs {
    /// A layout (`instruments/layouts/grand88.toml`: which instrument on which keys), or one
    /// instrument (file or built-in name, e.g. `grand_piano`) on `--keys` keys.
    pub input: String,
    /// The board: a built-in name (`rp2040`, `rp2040_200mhz`, `rp2040_20mhz`) or a board
    /// TOML file (clock_hz, cores, sample_rate_hz, io_cycles_per_key, isr_overhead_cycles).
    #[arg(long, default_value = "rp2040", value_name = "NAME_OR_FILE")]
    pub board: String,
    /// For a single instrument: how many keys (identical copies; default 88), from MIDI 21
    /// (A0) up.
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
}

/// A failure: bad input (exit 2) with its message.
struct Bad(String);

/// One distinct program: an instrument and its params, with its keys and costs.
struct Program {
    instrument: String,
    params: Vec<(String, String)>,
    source: String,
    keys: Vec<u8>,
    corpus: Size,
    samples: usize,
    cost: ProgramCost,
    /// Firmware glue per key of this program, cycles per sample: the board's
    /// `io_cycles_per_key` for a keyboard key; for a pen (several sensor words, a DAC word
    /// per force axis), its glue measured from the firmware image
    /// ([`FirmwareImage::key_glue`]) plus one contention cycle each way per window word.
    io_cycles: u64,
    /// Why a pen's glue could not be measured (its code does not fit a core's SRAM bank):
    /// its `io_cycles` is then a keyboard key's, a lower bound.
    io_note: Option<String>,
    /// A pen instrument (counted as pens, not keys).
    pen: bool,
}

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

/// The board named `arg`: a board file, or a built-in board's name; errors name the file or
/// list the built-ins.
pub(crate) fn board_named(arg: &str) -> Result<Board, String> {
    load_board(arg).map_err(|b| b.0)
}

fn load_board(arg: &str) -> Result<Board, Bad> {
    if Path::new(arg).exists() {
        return keyboard::read_board(Path::new(arg)).map_err(Bad);
    }
    let stem = arg.trim_end_matches(".toml").replace('-', "_");
    match BUILTIN_BOARDS.iter().find(|(n, _)| *n == stem) {
        Some((n, text)) => keyboard::parse_board(text, &format!("builtin:{n}")).map_err(Bad),
        None => Err(Bad(format!(
            "no board file `{arg}`, and no built-in board of that name (built-ins: {})",
            BUILTIN_BOARDS
                .iter()
                .map(|(n, _)| *n)
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

fn budget(args: &BudgetArgs) -> Result<ExitCode, Bad> {
    let board = load_board(&args.board)?;
    let is_layout = args.input.ends_with(".toml");
    // A single instrument is compiled once, here (it decides the default number of keys),
    // and reused for its keys below, so its diagnostics are printed once.
    let mut precompiled = None;
    let (name, assignments) = if is_layout {
        if args.keys.is_some() {
            return Err(Bad(format!(
                "{}: --keys is for a single instrument; a layout lists its own keys",
                args.input
            )));
        }
        let (l, keys) = keyboard::read_layout(Path::new(&args.input)).map_err(Bad)?;
        (l.name, keys)
    } else {
        precompiled = source::load(&args.input).ok().map(|src| {
            let lowered = compile_reporting(&src, &args.params);
            (src, lowered)
        });
        // A pen instrument is budgeted as one pen unless told otherwise.
        let default_keys = match &precompiled {
            Some((_, Some(l))) if l.program.is_pen() => 1,
            _ => 88,
        };
        let n = args.keys.unwrap_or(default_keys);
        if !(1..=128).contains(&n) {
            return Err(Bad(format!(
                "--keys must be between 1 and 128 (MIDI keys), got {n}"
            )));
        }
        // From A0 up, or from MIDI 0 when that would pass key 127.
        let first = if 21 + n <= 128 { 21 } else { 0 };
        let keys = (first..first + n)
            .map(|k| KeyAssignment {
                key: k as u8,
                instrument: args.input.clone(),
                params: vec![],
            })
            .collect();
        (format!("{} × {n}", args.input), keys)
    };
    if assignments.is_empty() {
        return Err(Bad(format!("{}: the layout has no keys", args.input)));
    }

    // Distinct programs, in order of first key.
    let mut programs: Vec<Program> = Vec::new();
    let mut key_program: Vec<(u8, usize)> = Vec::new();
    let mut compiled = Vec::new();
    for a in &assignments {
        let mut params = a.params.clone();
        params.extend(args.params.iter().cloned());
        let idx = match programs
            .iter()
            .position(|p| p.instrument == a.instrument && p.params == params)
        {
            Some(i) => i,
            None => {
                // Only the single instrument is precompiled, with exactly these params.
                let (src, lowered) = match precompiled.take() {
                    Some(pre) => pre,
                    None => {
                        let src = source::load(&a.instrument)
                            .map_err(|e| Bad(format!("{}: key {}: {e}", args.input, a.key)))?;
                        let lowered = compile_reporting(&src, &params);
                        (src, lowered)
                    }
                };
                let Some(lowered) = lowered else {
                    return Err(Bad(format!(
                        "{}: key {}: `{}` does not compile with params {}",
                        args.input,
                        a.key,
                        a.instrument,
                        show_params(&params)
                    )));
                };
                let fp = FixedProgram::new(&lowered.program);
                let obj = tactus_compiler::thumb::compile(&fp)
                    .map_err(|e| Bad(format!("{}: {e}", src.name)))?;
                let static_cost =
                    budget::static_update(&obj).map_err(|e| Bad(format!("{}: {e}", src.name)))?;
                let (io_cycles, io_note) = if fp.program.is_pen() {
                    let image_program = tactus_firmware::image::Program {
                        fixed: fp.clone(),
                        thumb: obj.clone(),
                    };
                    match FirmwareImage::key_glue(
                        &image_program,
                        &board,
                        &LimiterConfig::default(),
                    ) {
                        Ok(g) => (g.cycles + 2 * g.window_words, None),
                        Err(e) => (
                            u64::from(board.io_cycles_per_key),
                            Some(format!(
                                "{}: a pen's firmware glue not measured ({e}); a keyboard key's {} cycles used, a lower bound",
                                src.name, board.io_cycles_per_key
                            )),
                        ),
                    }
                } else {
                    (u64::from(board.io_cycles_per_key), None)
                };
                let pen = fp.program.is_pen();
                compiled.push((fp, obj));
                programs.push(Program {
                    pen,
                    io_cycles,
                    io_note,
                    instrument: a.instrument.clone(),
                    params,
                    source: src.text,
                    keys: Vec::new(),
                    corpus: Size::Brief,
                    samples: 0,
                    cost: ProgramCost {
                        static_cost,
                        measured: Default::default(),
                    },
                });
                programs.len() - 1
            }
        };
        programs[idx].keys.push(a.key);
        key_program.push((a.key, idx));
    }

    // Measure: the costliest variant of each instrument over the full (or quick) corpus,
    // its other param sets over the brief one.
    for i in 0..programs.len() {
        let representative = !programs.iter().enumerate().any(|(j, q)| {
            q.instrument == programs[i].instrument
                && (q.cost.static_cost.cycles, i) > (programs[i].cost.static_cost.cycles, j)
        });
        let size = match (representative, args.quick) {
            (true, false) => Size::Full,
            (true, true) => Size::Quick,
            (false, _) => Size::Brief,
        };
        let (fp, obj) = &compiled[i];
        let runs = corpus::corpus(fp, size);
        let measured = budget::measure_update(obj, fp, &runs)
            .map_err(|e| Bad(format!("{}: {e}", programs[i].instrument)))?;
        let p = &mut programs[i];
        p.corpus = size;
        p.samples = corpus::samples(&runs);
        p.cost.measured = measured;
    }

    let key_cycles: Vec<u64> = key_program
        .iter()
        .map(|&(_, p)| programs[p].cost.static_cost.cycles + programs[p].io_cycles)
        .collect();
    let plan = budget::plan(&board, &key_cycles);
    // The most expensive key (the lowest of equals).
    let worst = (0..key_cycles.len())
        .max_by_key(|&i| (key_cycles[i], std::cmp::Reverse(i)))
        .unwrap_or(0);
    let unsound: Vec<&Program> = programs.iter().filter(|p| !p.cost.sound()).collect();

    let r = Report {
        name: &name,
        input: &args.input,
        board: &board,
        programs: &programs,
        key_program: &key_program,
        key_cycles: &key_cycles,
        plan: &plan,
        worst,
    };
    if args.json {
        println!("{}", r.json());
    } else {
        print!("{}", r.text());
    }
    for p in &unsound {
        eprintln!(
            "BUG: {} ({}): measured {} cycles at {} sample {} exceed the static worst case {} — the WCET analysis or the emulator's timing is wrong",
            p.instrument,
            show_params(&p.params),
            p.cost.measured.worst,
            p.cost.measured.worst_at.0,
            p.cost.measured.worst_at.1,
            p.cost.static_cost.cycles
        );
    }
    Ok(if plan.fits() && unsound.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn show_params(params: &[(String, String)]) -> String {
    if params.is_empty() {
        "defaults".to_string()
    } else {
        params
            .iter()
            .map(|(n, v)| format!("{n}={v}"))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

fn corpus_name(s: Size) -> &'static str {
    match s {
        Size::Full => "full",
        Size::Quick => "quick",
        Size::Brief => "brief",
    }
}

/// Keys as ranges: `21–64, 70`.
fn key_ranges(keys: &[u8]) -> String {
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
fn abbreviate(s: &str, max: usize) -> String {
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

struct Report<'a> {
    name: &'a str,
    input: &'a str,
    board: &'a Board,
    programs: &'a [Program],
    key_program: &'a [(u8, usize)],
    key_cycles: &'a [u64],
    plan: &'a Plan,
    worst: usize,
}

/// Per instrument name: (name, indices of its programs).
fn by_instrument(programs: &[Program]) -> Vec<(String, Vec<usize>)> {
    let mut v: Vec<(String, Vec<usize>)> = Vec::new();
    for (i, p) in programs.iter().enumerate() {
        match v.iter_mut().find(|(n, _)| *n == p.instrument) {
            Some((_, is)) => is.push(i),
            None => v.push((p.instrument.clone(), vec![i])),
        }
    }
    v
}

impl Report<'_> {
    fn path_events(&self, p: &Program) -> Vec<String> {
        p.cost
            .static_cost
            .events
            .iter()
            .filter_map(|(_, n)| describe_note(n, &p.source))
            .collect()
    }

    /// Per instrument: the most keys of it (at its costliest param set) that fit.
    fn what_fits(&self) -> Vec<(String, u64, u64)> {
        by_instrument(self.programs)
            .into_iter()
            .map(|(name, is)| {
                let c = is
                    .iter()
                    .map(|&i| self.programs[i].cost.static_cost.cycles + self.programs[i].io_cycles)
                    .max()
                    .unwrap_or(0);
                (name, c, budget::max_keys(self.board, c))
            })
            .collect()
    }

    fn text(&self) -> String {
        let b = self.board;
        let cps = self.plan.cycles_per_sample;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "budget of {} ({}): {} {} on {}: {} core{} × {} cycles per sample ({} MHz / {} Hz); per key {} I/O cycles, per core {} interrupt cycles",
            self.name,
            self.input,
            self.key_program.len(),
            match (self.programs.iter().all(|p| p.pen), self.key_program.len()) {
                (true, 1) => "pen",
                (true, _) => "pens",
                (false, _) => "keys",
            },
            b.name,
            b.cores,
            if b.cores == 1 { "" } else { "s" },
            cps,
            b.clock_hz / 1e6,
            b.sample_rate_hz,
            b.io_cycles_per_key,
            b.isr_overhead_cycles
        );
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "{:<18} {:>5} {:>6} {:>8} {:>9} {:>8} {:>9} {:>8} {:>9}",
            "instrument",
            "keys",
            "params",
            "static",
            "measured",
            "mean",
            "static /",
            "corpus",
            "samples"
        );
        let _ = writeln!(
            s,
            "{:<18} {:>5} {:>6} {:>8} {:>9} {:>8} {:>9} {:>8} {:>9}",
            "", "", "sets", "max", "max", "", "measured", "", ""
        );
        for (name, is) in by_instrument(self.programs) {
            // The costliest param set is the fully measured one; show it, and the spread.
            let rep = *is
                .iter()
                .max_by_key(|&&i| {
                    (
                        self.programs[i].cost.static_cost.cycles,
                        std::cmp::Reverse(i),
                    )
                })
                .unwrap_or(&is[0]);
            let p = &self.programs[rep];
            let keys: usize = is.iter().map(|&i| self.programs[i].keys.len()).sum();
            let _ = writeln!(
                s,
                "{:<18} {:>5} {:>6} {:>8} {:>9} {:>8.1} {:>9} {:>8} {:>9}",
                name,
                keys,
                is.len(),
                p.cost.static_cost.cycles,
                p.cost.measured.worst,
                p.cost.measured.mean(),
                p.cost
                    .ratio()
                    .map_or("–".to_string(), |r| format!("{r:.3}")),
                corpus_name(p.corpus),
                p.samples
            );
            if is.len() > 1 {
                let st: Vec<u64> = is
                    .iter()
                    .map(|&i| self.programs[i].cost.static_cost.cycles)
                    .collect();
                let me: Vec<u64> = is
                    .iter()
                    .map(|&i| self.programs[i].cost.measured.worst)
                    .collect();
                let _ = writeln!(
                    s,
                    "{:<18} other param sets: static {}–{}, measured max {}–{} (brief corpus), all measured ≤ static: {}",
                    "",
                    st.iter().min().unwrap_or(&0),
                    st.iter().max().unwrap_or(&0),
                    me.iter().min().unwrap_or(&0),
                    me.iter().max().unwrap_or(&0),
                    if is.iter().all(|&i| self.programs[i].cost.sound()) { "yes" } else { "NO" }
                );
            }
        }
        let _ = writeln!(s);
        let _ = writeln!(
            s,
            "{:<5} {:>5} {:>14} {:>12} {:>10}   keys",
            "core", "keys", "cycles/sample", "utilisation", "headroom"
        );
        for (c, core) in self.plan.cores.iter().enumerate() {
            let keys: Vec<u8> = core.keys.iter().map(|&k| self.key_program[k].0).collect();
            let _ = writeln!(
                s,
                "{:<5} {:>5} {:>14} {:>11.1}% {:>10}   {}",
                c,
                core.keys.len(),
                core.cycles,
                100.0 * core.utilisation,
                core.headroom,
                abbreviate(&key_ranges(&keys), 60)
            );
        }
        let _ = writeln!(s);
        let (key, pi) = self.key_program[self.worst];
        let wp = &self.programs[pi];
        let events = self.path_events(wp);
        if self.plan.fits() {
            let _ = writeln!(
                s,
                "verdict: FITS — the fullest core uses {} of {cps} cycles per sample ({} cycles headroom)",
                cps as i64 - self.plan.min_headroom(),
                self.plan.min_headroom()
            );
        } else {
            let need = cps as i64 - self.plan.min_headroom();
            let _ = writeln!(
                s,
                "verdict: DOES NOT FIT — the fullest core needs {need} cycles per sample, {cps} available: over by {} cycles ({:.1} × the budget)",
                -self.plan.min_headroom(),
                need as f64 / cps as f64
            );
        }
        // A pen has no note name: it is named by its window slot (the key number).
        let who = if wp.pen {
            format!("pen (slot {key})")
        } else {
            format!("key: {key} ({})", note_name(key))
        };
        let _ = writeln!(
            s,
            "most expensive {who} {} ({}): {} cycles per sample = static {} + I/O {}",
            wp.instrument,
            show_params(&wp.params),
            self.key_cycles[self.worst],
            wp.cost.static_cost.cycles,
            wp.io_cycles
        );
        for p in self.programs {
            if let Some(n) = &p.io_note {
                let _ = writeln!(s, "note: {n}");
            }
        }
        let _ = writeln!(
            s,
            "its worst path ({} blocks) passes: {}",
            wp.cost.static_cost.path.len(),
            if events.is_empty() {
                "no source-level events".to_string()
            } else {
                collapse_runs(&events).join(" → ")
            }
        );
        let calls = &wp.cost.static_cost.calls;
        if !calls.is_empty() {
            let total: u64 = calls.iter().map(|c| c.2 + 3).sum();
            let _ = writeln!(
                s,
                "calls on it: {} ({total} cycles with their BLs, of the {} static)",
                calls
                    .iter()
                    .map(|(site, callee, c)| format!(
                        "BL at .text+{site:#x} to +{callee:#x} ({c} cycles)"
                    ))
                    .collect::<Vec<_>>()
                    .join(", "),
                wp.cost.static_cost.cycles
            );
        }
        let _ = writeln!(s, "what fits on {}:", self.board.name);
        let free = cps.saturating_sub(u64::from(self.board.isr_overhead_cycles));
        for (name, c, n) in self.what_fits() {
            let per_key =
                free * u64::from(self.board.cores) / (self.key_program.len() as u64).max(1);
            let ps = || self.programs.iter().filter(|p| p.instrument == name);
            let unit = if ps().any(|p| p.pen) { "pen" } else { "key" };
            // The glue of this instrument's keys (a pen's is measured; a key's is the board's).
            let io = ps()
                .map(|p| p.io_cycles)
                .max()
                .unwrap_or(u64::from(self.board.io_cycles_per_key));
            let count = self.key_program.len();
            let _ = writeln!(
                s,
                "  {name}: {n} {unit}{} ({c} cycles per {unit}; {} per core of {free} after the interrupt; {count} {unit}{} ≤ {per_key} cycles per {unit}{})",
                if n == 1 { "" } else { "s" },
                n / u64::from(self.board.cores.max(1)),
                if count == 1 { " needs" } else { "s need" },
                if per_key <= io {
                    format!(
                        ", less than the {io} cycles of per-{unit} firmware glue alone: no update fits that many {unit}s"
                    )
                } else {
                    format!(", {} for the update after the glue", per_key - io)
                }
            );
        }
        s
    }

    fn json(&self) -> String {
        let b = self.board;
        let programs: Vec<Json> = self
            .programs
            .iter()
            .map(|p| {
                let c = &p.cost;
                Json::obj([
                    ("instrument", Json::Str(p.instrument.clone())),
                    (
                        "params",
                        Json::Obj(
                            p.params
                                .iter()
                                .map(|(n, v)| (n.clone(), Json::Str(v.clone())))
                                .collect(),
                        ),
                    ),
                    (
                        "keys",
                        Json::Arr(p.keys.iter().map(|&k| Json::Num(k as f64)).collect()),
                    ),
                    ("static_cycles", Json::Num(c.static_cost.cycles as f64)),
                    ("measured_max", Json::Num(c.measured.worst as f64)),
                    ("measured_mean", Json::Num(c.measured.mean())),
                    (
                        "static_over_measured",
                        c.ratio().map_or(Json::Null, Json::Num),
                    ),
                    ("sound", Json::Bool(c.sound())),
                    ("corpus", Json::Str(corpus_name(p.corpus).into())),
                    ("samples", Json::Num(p.samples as f64)),
                    (
                        "measured_max_at",
                        Json::obj([
                            ("run", Json::Str(c.measured.worst_at.0.clone())),
                            ("sample", Json::Num(c.measured.worst_at.1 as f64)),
                        ]),
                    ),
                    (
                        "worst_path",
                        Json::Arr(self.path_events(p).into_iter().map(Json::Str).collect()),
                    ),
                ])
            })
            .collect();
        let cores: Vec<Json> = self
            .plan
            .cores
            .iter()
            .map(|c| {
                Json::obj([
                    (
                        "keys",
                        Json::Arr(
                            c.keys
                                .iter()
                                .map(|&k| Json::Num(self.key_program[k].0 as f64))
                                .collect(),
                        ),
                    ),
                    ("cycles", Json::Num(c.cycles as f64)),
                    ("utilisation", Json::Num(c.utilisation)),
                    ("headroom", Json::Num(c.headroom as f64)),
                ])
            })
            .collect();
        let (key, pi) = self.key_program[self.worst];
        let wp = &self.programs[pi];
        Json::obj([
            ("layout", Json::Str(self.name.to_string())),
            ("input", Json::Str(self.input.to_string())),
            (
                "board",
                Json::obj([
                    ("name", Json::Str(b.name.clone())),
                    ("clock_hz", Json::Num(b.clock_hz)),
                    ("cores", Json::Num(b.cores as f64)),
                    ("sample_rate_hz", Json::Num(b.sample_rate_hz)),
                    (
                        "cycles_per_sample",
                        Json::Num(self.plan.cycles_per_sample as f64),
                    ),
                    ("io_cycles_per_key", Json::Num(b.io_cycles_per_key as f64)),
                    (
                        "isr_overhead_cycles",
                        Json::Num(b.isr_overhead_cycles as f64),
                    ),
                ]),
            ),
            ("fits", Json::Bool(self.plan.fits())),
            ("min_headroom", Json::Num(self.plan.min_headroom() as f64)),
            ("programs", Json::Arr(programs)),
            ("cores", Json::Arr(cores)),
            (
                "worst_key",
                Json::obj([
                    ("key", Json::Num(key as f64)),
                    ("note", Json::Str(note_name(key))),
                    ("instrument", Json::Str(wp.instrument.clone())),
                    ("cycles", Json::Num(self.key_cycles[self.worst] as f64)),
                    (
                        "worst_path",
                        Json::Arr(self.path_events(wp).into_iter().map(Json::Str).collect()),
                    ),
                    (
                        "worst_path_calls",
                        Json::Arr(
                            wp.cost
                                .static_cost
                                .calls
                                .iter()
                                .map(|&(site, callee, c)| {
                                    Json::obj([
                                        ("site", Json::Num(site as f64)),
                                        ("callee", Json::Num(callee as f64)),
                                        ("cycles", Json::Num(c as f64)),
                                    ])
                                })
                                .collect(),
                        ),
                    ),
                ]),
            ),
            (
                "what_fits",
                Json::Arr(
                    self.what_fits()
                        .into_iter()
                        .map(|(n, c, k)| {
                            Json::obj([
                                ("instrument", Json::Str(n)),
                                ("cycles_per_key", Json::Num(c as f64)),
                                ("max_keys", Json::Num(k as f64)),
                            ])
                        })
                        .collect(),
                ),
            ),
        ])
        .to_string()
    }
}

/// A minimal JSON value (the document `--json` prints; no dependency for one writer).
enum Json {
    Null,
    Bool(bool),
    Num(f64),
    Str(String),
    Arr(Vec<Json>),
    Obj(BTreeMap<String, Json>),
}

impl Json {
    fn obj<const N: usize>(fields: [(&str, Json); N]) -> Json {
        Json::Obj(
            fields
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect(),
        )
    }
}

fn write_str(out: &mut String, s: &str) {
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
}

impl std::fmt::Display for Json {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut s = String::new();
        self.write(&mut s);
        f.write_str(&s)
    }
}

impl Json {
    fn write(&self, out: &mut String) {
        match self {
            Json::Null => out.push_str("null"),
            Json::Bool(b) => out.push_str(if *b { "true" } else { "false" }),
            // Integers print without a fraction; non-finite numbers are not JSON: null.
            Json::Num(x) if !x.is_finite() => out.push_str("null"),
            Json::Num(x) if x.fract() == 0.0 && x.abs() < 1e15 => {
                let _ = write!(out, "{}", *x as i64);
            }
            Json::Num(x) => {
                let _ = write!(out, "{x}");
            }
            Json::Str(s) => write_str(out, s),
            Json::Arr(v) => {
                out.push('[');
                for (i, x) in v.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    x.write(out);
                }
                out.push(']');
            }
            Json::Obj(m) => {
                out.push('{');
                for (i, (k, v)) in m.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    write_str(out, k);
                    out.push(':');
                    v.write(out);
                }
                out.push('}');
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_escapes_and_numbers() {
        let j = Json::obj([
            ("a", Json::Str("x\"y\\\n\u{1}".into())),
            (
                "n",
                Json::Arr(vec![Json::Num(3.0), Json::Num(0.5), Json::Null]),
            ),
            ("b", Json::Bool(true)),
        ]);
        assert_eq!(
            j.to_string(),
            r#"{"a":"x\"y\\\n\u0001","b":true,"n":[3,0.5,null]}"#
        );
    }

    #[test]
    fn key_ranges_name_notes() {
        assert_eq!(key_ranges(&[23, 21, 22, 60]), "21–23 (A0–B0), 60 (C4)");
        assert_eq!(abbreviate("a, b, c, d, e", 6), "a, b, … e");
        assert_eq!(abbreviate("a, b", 6), "a, b");
    }

    #[test]
    fn builtin_boards_parse() {
        for (n, text) in BUILTIN_BOARDS {
            keyboard::parse_board(text, n).unwrap();
        }
        assert!(load_board("no-such-board").is_err());
    }
}

/// `items` with each run of equal neighbours written once, followed by `(× n)` when `n > 1`:
/// a worst path through a 225-element delay line reads "line 85: … (× 225)", not the same
/// label 225 times.
fn collapse_runs(items: &[String]) -> Vec<String> {
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

#[cfg(test)]
mod collapse_tests {
    use super::collapse_runs;

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
