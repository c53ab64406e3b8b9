//! A performance through the firmware of every board of a keyboard: each board's image on
//! its own emulated RP2040, every key of every board every sample (unplayed keys at rest, as
//! on the hardware), the boards in parallel on host threads (they share nothing).
//!
//! A board is a [`BoardEngine`]: the play loop ([`run_keys`], the one every engine runs
//! through) steps it with every key's travel, so a key moved by a [`Motion::Finger`] is
//! pushed against the force word its firmware computed that sample (`SampleOut::force`,
//! before the safety limiter, as the host engines' force). Strikes come from the keys'
//! `out[]` words through the strike rule ([`strike_event`]), their speeds converted from the
//! event's format. Per board and core the run keeps the largest handler, the misses, the
//! static bound and, decimated to at most [`MAX_POINTS`] points, the cycles of the busier
//! core.

use crate::play::engine::{KeyEngine, KeySample};
use crate::play::error::{BoardError, RunError};
use crate::play::run::{Drive, KeysLoop, LoopConfig, TraceWindow};
use crate::play::strike::{strike_event, Strike};
use crate::play::timeline::Timeline;
use std::collections::BTreeMap;
use std::sync::Arc;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_firmware::boards::{self, BoardImage, PlanKey, ProgramCosts};
use tactus_firmware::image::Program;
use tactus_runtime::fixed::to_f64;
use tactus_runtime::keyboard::BoardSpec;
use tactus_runtime::limiter::LimiterConfig;
use tactus_runtime::player::FingerConfig;

pub use crate::play::motion::Motion;
pub use crate::play::run::{TraceRows, Traces};

/// Most points of a board's cycle series ([`BoardRun::cycles`]).
pub const MAX_POINTS: usize = 4000;

/// How [`play_boards`] runs.
#[derive(Clone, Debug)]
pub struct PerformOptions {
    /// Samples to run, from sample 0 (the run's: a lead-in's first).
    pub end: usize,
    /// The run's clock: its sample rate and lead-in ([`Timeline`]).
    pub clock: Timeline,
    /// The finger of the force player.
    pub finger: FingerConfig,
    /// Which keys to trace, and when.
    pub trace: TraceWindow,
    /// The keyboard's boards (MIDI keys per board), as its plan gives them
    /// (`crate::keyboard::Keyboard::plan`: the boards `tactus budget` reports and `tactus
    /// build` builds).
    pub boards: Vec<Vec<u8>>,
    /// Per board of `boards`: the image its plan built (`KeyboardPlan::images`), which the
    /// run takes instead of building it again when the board's keys and programs are the
    /// plan's (`None`, or none given: it builds it, [`boards::board_image`]).
    pub images: Vec<Option<Arc<BoardImage>>>,
    /// The safety limiter.
    pub limiter: LimiterConfig,
    /// The emulator's engine (the same cycles either way).
    pub engine: tactus_emulator::Engine,
    /// Whether the images guard quiescent keys ([`Program::quiescent_guard`]: the same
    /// outputs either way; fewer cycles and a faster emulation with it).
    pub quiescent_guard: bool,
    /// Whether a board at rest replays its repeating period instead of emulating it
    /// ([`BoardEngine::rest_replay`]).
    pub rest_replay: bool,
    /// On boards with converters: a directory to write each board's frames at the pins
    /// into (`board-NN.csv`, [`IO_TRACE_HEADER`]); `None` writes none.
    pub io_trace: Option<std::path::PathBuf>,
    /// Run in consecutive spans of this many samples, each board's budget reported per span
    /// ([`BoardRun::spans`]); `None`: one span, none reported.
    pub span: Option<usize>,
    /// Faults injected (`crate::fault`): the board (from 0) and the fault.
    pub faults: Vec<(usize, tactus_firmware::image::Injection)>,
}

/// The spans of a run of `end` samples cut every `span` samples (`None` or 0: one span):
/// their ends, in order.
pub fn span_ends(end: usize, span: Option<usize>) -> Vec<usize> {
    match span.filter(|&s| s > 0 && s < end) {
        None => vec![end],
        Some(s) => (1..=end.div_ceil(s)).map(|k| (k * s).min(end)).collect(),
    }
}

/// The columns of an I/O trace file (`--io-trace`): one row per ADC frame (its chip
/// select's fall: the sample instant) and per DAC output change (its 32nd SCLK falling
/// edge), the board's cycle and µs, the core, the part, the channel, the code (the ADC's
/// sample, the DAC's output in straight binary: midscale 32768 is 0 A) and the ADC frame's
/// command word.
pub const IO_TRACE_HEADER: &str = "cycle,time_us,core,part,channel,code,command";

/// One board's run.
#[derive(Clone, Debug, Default)]
pub struct BoardRun {
    /// Its keys (MIDI), ascending.
    pub keys: Vec<u8>,
    /// Keys per core.
    pub core_keys: Vec<usize>,
    /// The largest handler per core, cycles (exception entry to return).
    pub max: Vec<u64>,
    /// All handler cycles per core over the run (their mean per sample, over the cycles
    /// of a sample period, is the core's mean utilisation).
    pub total: Vec<u64>,
    /// Deadline misses the firmware counted, per core.
    pub misses: Vec<u32>,
    /// Per core, the samples it had not finished by the next tick: a handler that never
    /// returned (a hung update), cut by the watchdog's reset, in no `max` or `total`
    /// (`tactus_firmware::image::ImageRun::unfinished`; all zero without injected faults).
    pub unfinished: Vec<u64>,
    /// The static bound of each core's handler.
    pub bound: Vec<u64>,
    /// The busier core's cycles, the largest of each `decimation` samples.
    pub cycles: Vec<u64>,
    /// Its keys' strikes.
    pub strikes: Vec<Strike>,
    /// Its traced keys' samples.
    pub traces: Traces,
    /// What the emulator's memoized key updates did (`tactus_emulator::Board::memoize`).
    pub memo: tactus_emulator::MemoStats,
    /// Samples the rest replay gave from recordings of the board at rest, and the whole
    /// periods it skipped ([`BoardEngine::rest_replay`]).
    pub rest_replayed: (u64, u64),
    /// On a board with converters, what its windows' I/O replays did
    /// (`tactus_emulator::Board::io_windows`; all zero on a plain board).
    pub io_windows: tactus_emulator::IoWindows,
    /// On a board with converters, its parts' timing breaches of their data sheets
    /// (`tactus_emulator::converters`: each part keeps its first 65,536), as "core *c*
    /// ADC|DAC, cycle *n*: what"; empty on a plain board.
    pub io_breaches: Vec<String>,
    /// With [`PerformOptions::span`]: the board's budget over each span alone (its largest
    /// and summed handler cycles, misses, rest replay and I/O over the span; no cycle
    /// series, strikes or traces), in order.
    pub spans: Vec<BoardRun>,
    /// The resets the board met (the watchdog's, a brown-out), with injected faults
    /// ([`PerformOptions::faults`]); empty otherwise.
    pub resets: Vec<tactus_firmware::image::ResetRecord>,
    /// Per core, its fault record at the end of the run (the firmware's checks:
    /// `crate::fault::read_records`).
    pub faults: Vec<tactus_firmware::image::fault::FaultWord>,
    /// Per key (as [`BoardRun::keys`]), its window slot in the image (what a fault word
    /// names it by, `tactus_firmware::image::KeySpec::slot`).
    pub slots: Vec<usize>,
}

/// The whole keyboard's run.
#[derive(Clone, Debug)]
pub struct KeyboardRun {
    /// Per board, in key order.
    pub boards: Vec<BoardRun>,
    /// Samples per point of [`BoardRun::cycles`].
    pub decimation: usize,
    /// With [`PerformOptions::span`]: each span's samples, in order (each board's
    /// [`BoardRun::spans`] follow them).
    pub spans: Vec<u64>,
}

/// Plays `motions` on the keyboard whose keys (ascending MIDI numbers) run `programs`
/// (`key_programs[i]` is key `keys[i]`'s program) on the boards `opts.boards`: boots each
/// board's image (the plan's, `opts.images`, else built) and runs it for `opts.end`
/// samples, the boards in parallel (rayon). `progress` is called with key-samples done
/// since its last call.
///
/// Errors: a message naming the board when its image cannot be built or its run fails.
pub fn play_boards(
    programs: &[Program],
    keys: &[u8],
    key_programs: &[usize],
    board: &BoardSpec,
    motions: &BTreeMap<u8, &Motion>,
    opts: &PerformOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<KeyboardRun, RunError> {
    let lim = &opts.limiter;
    // The plan's images are of the programs as given (`opts.images`).
    let same_programs = programs
        .iter()
        .all(|p| p.quiescent_guard == opts.quiescent_guard);
    let guarded: Vec<Program> = programs
        .iter()
        .map(|p| {
            let mut p = p.clone();
            p.quiescent_guard = opts.quiescent_guard;
            p
        })
        .collect();
    let programs = &guarded[..];
    let keys: Vec<PlanKey> = keys
        .iter()
        .zip(key_programs)
        .map(|(&key, &program)| PlanKey { key, program })
        .collect();
    let lists = &opts.boards;
    let board_keys: Vec<Vec<PlanKey>> = (lists.iter())
        .map(|list| {
            keys.iter()
                .filter(|k| list.contains(&k.key))
                .copied()
                .collect()
        })
        .collect();
    // The plan's image of each board, built of the same programs for the same keys.
    let planned: Vec<Option<&BoardImage>> = (board_keys.iter().enumerate())
        .map(|(i, bkeys)| {
            (opts.images.get(i).and_then(Option::as_deref))
                .filter(|b| same_programs && b.holds(programs, bkeys))
        })
        .collect();
    // The programs' costs, for the boards the run builds (none when the plan gave them all).
    let costs = std::sync::OnceLock::new();
    let costs = || -> Result<&ProgramCosts, RunError> {
        if let Some(c) = costs.get() {
            return Ok(c);
        }
        let c = ProgramCosts::new(programs, board, lim)?;
        Ok(costs.get_or_init(|| c))
    };
    // A key that fits no board of this kind stops the run with the budget's reason (a
    // board over its deadline still runs: its misses are what the run shows). A key on a
    // board whose planned image fits fits alone (a sub-range of a fitting range fits:
    // `tactus_firmware::boards`), so only the other keys are asked.
    let asked: Vec<PlanKey> = (keys.iter())
        .filter(|k| {
            !(board_keys.iter().zip(&planned))
                .any(|(bk, p)| p.is_some_and(|p| p.fits(board)) && bk.contains(k))
        })
        .copied()
        .collect();
    if !asked.is_empty() {
        let unfit = boards::fits_no_board_each(programs, costs()?, board, lim)?;
        if let Some((k, why)) =
            (asked.iter()).find_map(|k| unfit.get(k.program)?.as_ref().map(|w| (k.key, w)))
        {
            return Err(RunError::Unfit {
                key: k,
                board: board.name.clone(),
                why: why.clone(),
            });
        }
    }
    // Each board's image: the plan's, else built from the costs (found before the boards
    // start).
    let images: Vec<Image> = (planned.iter())
        .map(|p| match p {
            Some(built) => Ok(Image::Planned(built)),
            None => costs().map(Image::Build),
        })
        .collect::<Result<_, _>>()?;
    if opts.io_trace.is_some() && board.converters.is_none() {
        return Err(RunError::NoConverters {
            board: board.name.clone(),
        });
    }
    let decimation = opts.end.div_ceil(MAX_POINTS).max(1);
    // The boards share nothing: each runs whole on one of as many threads as the machine
    // has cores. A board whose keys play many notes takes several times as long as one at
    // rest, so they start longest first (by notes played), each thread taking the next
    // board when it is free: no thread is left with a long board when the others are done.
    let notes = |list: &Vec<u8>| -> usize {
        list.iter()
            .filter_map(|k| motions.get(k))
            .map(|m| m.notes())
            .sum()
    };
    let mut order: Vec<usize> = (0..lists.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(notes(&lists[i])));
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(Vec::with_capacity(lists.len()));
    let threads = rayon::current_num_threads().clamp(1, lists.len().max(1));
    rayon::scope(|s| {
        for _ in 0..threads {
            s.spawn(|_| loop {
                let n = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(&i) = order.get(n) else {
                    break;
                };
                let r = run_board(
                    programs,
                    images[i],
                    &board_keys[i],
                    board,
                    motions,
                    opts,
                    progress,
                    decimation,
                    i,
                )
                .map(|r| (i, r))
                .map_err(|source| RunError::Board {
                    board: i + 1,
                    keys: tactus_firmware::verdict::key_ranges(&lists[i]),
                    source,
                });
                results.lock().unwrap_or_else(|e| e.into_inner()).push(r);
            });
        }
    });
    let mut results = results.into_inner().unwrap_or_else(|e| e.into_inner());
    // The first board's error, as before (boards in order).
    results.sort_by_key(|r| match r {
        Ok((i, _)) => (*i, 1),
        Err(RunError::Board { board, .. }) => (board - 1, 0),
        Err(_) => (0, 0),
    });
    let mut runs: Vec<(usize, BoardRun)> = results.into_iter().collect::<Result<_, _>>()?;
    runs.sort_by_key(|r| r.0);
    let ends = span_ends(opts.end, opts.span);
    let spans = match opts.span.is_some() {
        true => (ends.iter().scan(0, |from, &to| {
            let len = (to - *from) as u64;
            *from = to;
            Some(len)
        }))
        .collect(),
        false => Vec::new(),
    };
    Ok(KeyboardRun {
        boards: runs.into_iter().map(|r| r.1).collect(),
        decimation,
        spans,
    })
}

/// One board's firmware on its emulated RP2040 as a [`KeyEngine`]: all its keys every
/// sample through the image's sample interrupt. Per core it keeps the largest handler, the
/// sum of the handlers, the misses the firmware counted and the busier core's largest
/// handler of each `decimation` samples.
pub struct BoardEngine<'p> {
    run: tactus_firmware::image::ImageRun,
    /// Per key of the board: its program.
    programs: Vec<&'p Program>,
    /// Per key: the strike event ([`strike_event`]).
    strike: Vec<Option<tactus_compiler::ir::EventId>>,
    /// Per key: the out word of `hammer_pos` and its format.
    hammer: Vec<Option<(usize, i32)>>,
    /// Per key: the real value of one unit of its force word (`to_f64(1, total_frac)`).
    force_scale: Vec<f64>,
    sensors: Vec<i32>,
    /// Per key: the travel (`f64` bits, `None` for none given) `sensors` was converted from.
    last_travel: Vec<Option<Option<u64>>>,
    samples: Vec<KeySample>,
    report: BoardRun,
    decimation: usize,
    steps: usize,
    block_max: u64,
    /// The I/O trace being written (`--io-trace`): the board's number (from 1), the file's
    /// name and its writer.
    io_trace: Option<(usize, String, std::io::BufWriter<std::fs::File>)>,
    clock_hz: f64,
    /// The largest handler per core since the span began ([`BoardEngine::end_span`]).
    span_max: Vec<u64>,
    /// The board's report when the span began.
    span_start: BoardRun,
}

impl<'p> BoardEngine<'p> {
    /// Writes the board's converter frames from now on into `path` (header first),
    /// replacing the file; `board` numbers the board (from 1) in errors.
    ///
    /// Errors: [`BoardError::Trace`] naming the file.
    pub fn trace_io(&mut self, path: &std::path::Path, board: usize) -> Result<(), BoardError> {
        use std::io::Write;
        let name = path.display().to_string();
        let fail = |e: std::io::Error| BoardError::Trace {
            path: name.clone(),
            message: e.to_string(),
        };
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(fail)?;
        }
        let mut w = std::io::BufWriter::new(std::fs::File::create(path).map_err(fail)?);
        writeln!(w, "{IO_TRACE_HEADER}").map_err(fail)?;
        if let Some(io) = self.run.board().io_mut() {
            io.keep_records(true);
        }
        self.io_trace = Some((board, name.clone(), w));
        Ok(())
    }

    /// Writes the frames the last step's run left at the pins (nothing without a trace).
    fn write_io(&mut self) -> Result<(), BoardError> {
        use std::io::Write;
        let Some((_, name, w)) = self.io_trace.as_mut() else {
            return Ok(());
        };
        let (records, _) = self.run.take_io();
        for r in records {
            writeln!(
                w,
                "{},{:.3},{},{},{},{},{}",
                r.cycle,
                r.cycle as f64 / self.clock_hz * 1e6,
                r.core,
                if r.dac { "dac" } else { "adc" },
                r.channel,
                r.code,
                if r.dac {
                    String::new()
                } else {
                    format!("{:#06x}", r.command)
                }
            )
            .map_err(|e| BoardError::Trace {
                path: name.clone(),
                message: e.to_string(),
            })?;
        }
        Ok(())
    }
    /// Builds the image of the board whose keys are `bkeys` (as [`boards::board_image`]
    /// does for `tactus budget`) and boots it on an emulated RP2040 with the emulator's
    /// engine `engine`; its cycle series keeps the largest of each `decimation` samples.
    ///
    /// Errors: a message when the image cannot be built or booted.
    pub fn new(
        programs: &'p [Program],
        costs: &ProgramCosts,
        bkeys: &[PlanKey],
        board: &BoardSpec,
        limiter: &LimiterConfig,
        engine: tactus_emulator::Engine,
        decimation: usize,
    ) -> Result<Self, BoardError> {
        let (core_of, image) = boards::board_image(programs, costs, bkeys, board, limiter)?;
        let built = BoardImage {
            core_of,
            image: image?,
        };
        BoardEngine::boot(programs, bkeys, board, engine, decimation, &built)
    }

    /// Boots `built`, the image [`boards::board_image`] gives the board whose keys are
    /// `bkeys` (the plan's, `tactus_firmware::boards::KeyboardPlan::images`), as
    /// [`BoardEngine::new`] boots the image it builds.
    ///
    /// Errors: a message when the image cannot be booted.
    pub fn boot(
        programs: &'p [Program],
        bkeys: &[PlanKey],
        board: &BoardSpec,
        engine: tactus_emulator::Engine,
        decimation: usize,
        built: &BoardImage,
    ) -> Result<Self, BoardError> {
        let (core_of, image) = (&built.core_of, &built.image);
        let mut run = image.run()?;
        run.board().config.engine = engine;
        // Nothing reads the converters' frames but an I/O trace (`trace_io`), which keeps
        // them again: without one the parts keep none.
        if let Some(io) = run.board().io_mut() {
            io.keep_records(false);
        }
        let n_cores = image.cores();
        let key_programs: Vec<&Program> = bkeys.iter().map(|k| &programs[k.program]).collect();
        let report = BoardRun {
            keys: bkeys.iter().map(|k| k.key).collect(),
            slots: image.keys().iter().map(|k| k.slot).collect(),
            core_keys: (0..n_cores)
                .map(|c| core_of.iter().filter(|&&k| k == c).count())
                .collect(),
            max: vec![0; n_cores],
            total: vec![0; n_cores],
            misses: vec![0; n_cores],
            bound: (0..n_cores)
                .map(|c| image.wcet(c).map_or(0, |w| w.bound()))
                .collect(),
            ..BoardRun::default()
        };
        Ok(BoardEngine {
            run,
            strike: key_programs
                .iter()
                .map(|p| strike_event(&p.fixed.program))
                .collect(),
            hammer: key_programs
                .iter()
                .map(|p| {
                    let fp = &p.fixed;
                    fp.program
                        .outputs
                        .iter()
                        .position(|o| o.name == "hammer_pos")
                        .map(|i| (p.thumb.out.outputs + i, fp.output_frac[i]))
                })
                .collect(),
            force_scale: key_programs
                .iter()
                .map(|p| to_f64(1, p.fixed.total_frac))
                .collect(),
            sensors: vec![0; bkeys.len()],
            last_travel: vec![None; bkeys.len()],
            samples: vec![KeySample::default(); bkeys.len()],
            programs: key_programs,
            report,
            decimation: decimation.max(1),
            steps: 0,
            block_max: 0,
            io_trace: None,
            clock_hz: board.clock_hz,
            span_max: vec![0; n_cores],
            span_start: BoardRun::default(),
        })
    }

    /// The same board with the rest replay on or off
    /// (`tactus_firmware::image::ImageRun::set_rest_replay`: a board whose sensor words stop
    /// changing gives its samples from a recording of the period its state repeats with,
    /// exactly; off by default).
    ///
    /// Errors: [`BoardError`] when turning it off cannot bring the board to the present.
    pub fn rest_replay(mut self, on: bool) -> Result<Self, BoardError> {
        self.run.set_rest_replay(on)?;
        Ok(self)
    }

    /// The same board with the emulator's memoized calls off (`tactus_emulator::Board::memoize`:
    /// the same results, every update emulated; for measuring what they save).
    pub fn without_memos(mut self) -> Self {
        self.run.board().memoize(&[], &[]);
        self
    }

    /// What the board reported so far; its strikes and traces are the play loop's.
    ///
    /// Errors: [`BoardError::Trace`] when the I/O trace's last rows cannot be written.
    pub fn finish(mut self) -> Result<BoardRun, BoardError> {
        self.settle_report()?;
        if !self.steps.is_multiple_of(self.decimation) {
            self.report.cycles.push(self.block_max);
        }
        if let Some((_, name, mut w)) = self.io_trace.take() {
            use std::io::Write;
            w.flush().map_err(|e| BoardError::Trace {
                path: name,
                message: e.to_string(),
            })?;
        }
        Ok(self.report)
    }
}

impl BoardEngine<'_> {
    /// Brings the board to the present ([`tactus_firmware::image::ImageRun::settle`]) and
    /// its report's counts up to date: the memos', the rest replay's, the I/O's windows and
    /// its parts' breaches so far.
    fn settle_report(&mut self) -> Result<(), BoardError> {
        self.run.settle()?;
        self.report.memo = self.run.board().memo_stats();
        self.report.rest_replayed = self.run.rest_replayed();
        self.report.resets = self.run.resets().to_vec();
        self.report.unfinished = self.run.unfinished().to_vec();
        self.report.faults = crate::fault::run_records(&mut self.run)
            .map_err(tactus_firmware::image::ImageError::Run)?;
        self.report.io_windows = self.run.board().io_windows();
        self.report.io_breaches.clear();
        if let Some(io) = self.run.board().io() {
            let adcs = (io.adcs.iter().enumerate()).map(|(k, a)| (k, "ADC", a.violations()));
            let dacs = (io.dacs.iter().enumerate()).map(|(k, d)| (k, "DAC", d.violations()));
            for (core, part, vs) in adcs.chain(dacs) {
                self.report.io_breaches.extend(
                    vs.iter()
                        .map(|v| format!("core {core} {part}, cycle {}: {}", v.cycle, v.what)),
                );
            }
        }
        Ok(())
    }

    /// Ends a span: the board's budget over the samples since the last span ended (or the
    /// run began) — its largest handler per core, the sum of its handlers, its misses, the
    /// rest replay's samples and periods, the I/O's windows and breaches over the span —
    /// and a new span begun.
    ///
    /// Errors: what [`tactus_firmware::image::ImageRun::settle`] returns.
    pub fn end_span(&mut self) -> Result<BoardRun, BoardError> {
        self.settle_report()?;
        let (now, then) = (&self.report, &self.span_start);
        let minus = |a: &[u64], b: &[u64]| -> Vec<u64> {
            (a.iter().enumerate())
                .map(|(c, &x)| x.saturating_sub(b.get(c).copied().unwrap_or(0)))
                .collect()
        };
        let (io, io0) = (now.io_windows, then.io_windows);
        let span = BoardRun {
            keys: now.keys.clone(),
            core_keys: now.core_keys.clone(),
            max: std::mem::replace(&mut self.span_max, vec![0; now.max.len()]),
            total: minus(&now.total, &then.total),
            misses: (now.misses.iter().enumerate())
                .map(|(c, &m)| m.saturating_sub(then.misses.get(c).copied().unwrap_or(0)))
                .collect(),
            unfinished: minus(&now.unfinished, &then.unfinished),
            bound: now.bound.clone(),
            rest_replayed: (
                now.rest_replayed.0.saturating_sub(then.rest_replayed.0),
                now.rest_replayed.1.saturating_sub(then.rest_replayed.1),
            ),
            io_windows: tactus_emulator::IoWindows {
                kept: io.kept.saturating_sub(io0.kept),
                waited: io.waited.saturating_sub(io0.waited),
                stale: io.stale.saturating_sub(io0.stale),
                reach: io.reach.saturating_sub(io0.reach),
                memo_hits: io.memo_hits.saturating_sub(io0.memo_hits),
                memo_recorded: io.memo_recorded.saturating_sub(io0.memo_recorded),
                memo_shared: io.memo_shared.saturating_sub(io0.memo_shared),
                memo_planned: io.memo_planned.saturating_sub(io0.memo_planned),
            },
            io_breaches: now.io_breaches[then.io_breaches.len().min(now.io_breaches.len())..]
                .to_vec(),
            ..BoardRun::default()
        };
        self.span_start = BoardRun {
            total: now.total.clone(),
            misses: now.misses.clone(),
            unfinished: now.unfinished.clone(),
            rest_replayed: now.rest_replayed,
            io_windows: now.io_windows,
            io_breaches: now.io_breaches.clone(),
            ..BoardRun::default()
        };
        Ok(span)
    }
}

impl KeyEngine for BoardEngine<'_> {
    fn step(&mut self, travel_m: &[f64]) -> Result<&[KeySample], RunError> {
        for (k, p) in self.programs.iter().enumerate() {
            // A key at rest reads the same travel sample after sample: the conversion is a
            // pure function of it, kept from the last sample.
            let x = travel_m.get(k).copied();
            let bits = x.map(f64::to_bits);
            if self.last_travel[k] != Some(bits) {
                self.sensors[k] = FixedInstance::sensor_raw(&p.fixed, 0, x);
                self.last_travel[k] = Some(bits);
            }
        }
        let i = self.steps;
        let out = self
            .run
            .step(&self.sensors)
            .map_err(|source| RunError::Sample { sample: i, source })?;
        for (k, &scale) in self.force_scale.iter().enumerate() {
            self.samples[k] = KeySample {
                // `to_f64(force, total_frac)`: the word times 2^-frac, the power taken once.
                force_n: out.force[k] as f64 * scale,
                strike_mps: None,
                current_a: out.current_ua[k] as f64 * 1e-6,
                dac: out.dac[k] as f64,
            };
        }
        for ev in &out.events {
            if Some(ev.event) == self.strike[ev.key] {
                let p = self.programs[ev.key];
                let frac = p.fixed.event_frac[ev.event.index()][0];
                self.samples[ev.key].strike_mps =
                    Some(to_f64(ev.args.first().copied().unwrap_or(0), frac));
            }
        }
        count_sample(
            &mut self.report,
            &mut self.span_max,
            &mut self.block_max,
            &mut self.steps,
            self.decimation,
            out,
        );
        if let Some(board) = self.io_trace.as_ref().map(|t| t.0) {
            self.write_io().map_err(|source| RunError::Board {
                board,
                keys: tactus_firmware::verdict::key_ranges(&self.report.keys),
                source,
            })?;
        }
        Ok(&self.samples)
    }

    fn step_held(&mut self, travel_m: &[f64], most: usize) -> Result<usize, RunError> {
        // The sensor words of the last step (the travels it converted), no trace to write.
        let same = (self.last_travel.iter().enumerate())
            .all(|(k, t)| *t == Some(travel_m.get(k).map(|x| x.to_bits())));
        if !same || self.io_trace.is_some() {
            return Ok(0);
        }
        let BoardEngine {
            run,
            sensors,
            report: r,
            span_max,
            block_max,
            steps,
            decimation,
            ..
        } = self;
        // Each sample as `step` reports it; one with an event (a strike) is left to `step`.
        let given = run.give_while(sensors, most as u64, |out| {
            if !out.events.is_empty() {
                return false;
            }
            count_sample(r, span_max, block_max, steps, *decimation, out);
            true
        });
        Ok(given as usize)
    }

    fn hammer_m(&self, k: usize) -> f64 {
        match self.hammer[k] {
            Some((w, frac)) => self
                .run
                .out(k)
                .get(w)
                .map_or(f64::NAN, |&x| to_f64(x, frac)),
            None => f64::NAN,
        }
    }
}

/// Adds one sample's handler cycles and misses to `r`: per core the largest (of the run
/// and of the span, `span_max`) and the sum, the firmware's miss count, and every
/// `decimation` samples (counted by `steps`) the busier core's largest of them
/// (`block_max`) to the cycle series.
fn count_sample(
    r: &mut BoardRun,
    span_max: &mut [u64],
    block_max: &mut u64,
    steps: &mut usize,
    decimation: usize,
    out: &tactus_firmware::image::SampleOut,
) {
    // `span_max` has a word per core, as `r.max`, `r.total` and `r.misses`.
    let cores = (r.max.iter_mut().zip(&mut r.total))
        .zip(r.misses.iter_mut().zip(span_max.iter_mut()))
        .zip(out.core_cycles.iter().zip(&out.misses));
    for (((max, total), (misses, span)), (&cycles, &m)) in cores {
        *max = (*max).max(cycles);
        *span = (*span).max(cycles);
        *total += cycles;
        *misses = m;
        *block_max = (*block_max).max(cycles);
    }
    *steps += 1;
    if steps.is_multiple_of(decimation) {
        r.cycles.push(*block_max);
        *block_max = 0;
    }
}

/// Where a board's image comes from in [`play_boards`].
#[derive(Clone, Copy)]
enum Image<'a> {
    /// The plan's (`PerformOptions::images`).
    Planned(&'a BoardImage),
    /// Built by [`BoardEngine::new`] from the programs' costs.
    Build(&'a ProgramCosts),
}

/// One board of [`play_boards`]: its image, every key every sample through the play loop.
#[allow(clippy::too_many_arguments)]
fn run_board(
    programs: &[Program],
    image: Image,
    bkeys: &[PlanKey],
    board: &BoardSpec,
    motions: &BTreeMap<u8, &Motion>,
    opts: &PerformOptions,
    progress: &(dyn Fn(u64) + Sync),
    decimation: usize,
    index: usize,
) -> Result<BoardRun, BoardError> {
    let mut engine = match image {
        Image::Planned(built) => {
            BoardEngine::boot(programs, bkeys, board, opts.engine, decimation, built)
        }
        Image::Build(costs) => BoardEngine::new(
            programs,
            costs,
            bkeys,
            board,
            &opts.limiter,
            opts.engine,
            decimation,
        ),
    }?
    // A traced board writes each sample's frames as they come: it runs every sample.
    .rest_replay(opts.rest_replay && opts.io_trace.is_none())?;
    for (_, f) in opts.faults.iter().filter(|f| f.0 == index) {
        engine.run.inject(*f).map_err(|e| {
            tactus_firmware::image::ImageError::Run(format!("board {}: --fault: {e}", index + 1))
        })?;
    }
    if let (Some(dir), Some(_)) = (&opts.io_trace, &board.converters) {
        engine.trace_io(&dir.join(format!("board-{:02}.csv", index + 1)), index + 1)?;
    }
    let drives: Vec<Drive> = bkeys
        .iter()
        .map(|k| Drive {
            key: k.key,
            motion: motions.get(&k.key).copied(),
            dip_m: programs[k.program].fixed.program.sensors[0].range.1,
        })
        .collect();
    let config = LoopConfig {
        clock: opts.clock,
        finger: opts.finger,
        trace: &opts.trace,
        stop_at_strike_after_s: None,
    };
    // Span by span, the board and the loop carrying on from where the last span ended.
    let mut keys = KeysLoop::new(&drives, &config);
    let mut spans = Vec::new();
    let mut from = 0;
    for to in span_ends(opts.end, opts.span) {
        keys.run(&mut engine, from..to, &|n| progress(n))?;
        if opts.span.is_some() {
            spans.push(engine.end_span()?);
        }
        from = to;
    }
    let run = keys.finish();
    let mut report = engine.finish()?;
    report.strikes = run.strikes;
    report.traces = run.traces;
    report.spans = spans;
    Ok(report)
}
