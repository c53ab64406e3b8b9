//! A performance through the firmware of every board of a keyboard: each board's image on
//! its own emulated RP2040, every key of every board every sample (unplayed keys at rest, as
//! on the hardware), the boards in parallel on host threads (they share nothing).
//!
//! A key moved by a [`Motion::Track`] follows it; a key moved by a [`Motion::Finger`] is a
//! [`ForcePlayer`] pushed by the finger against the force word its firmware computed that
//! sample (`SampleOut::force`, before the safety limiter, as the host engines' force): the
//! closed loop, stepped exactly as the host engines' loop. Strikes come from the keys'
//! `out[]` words (the `strike` or `pluck` event), their speeds converted from the event's
//! format. Per board and core the run keeps the largest handler, the misses, the static
//! bound and, decimated to at most [`MAX_POINTS`] points, the cycles of the busier core.

use crate::boards::{self, PlanKey, ProgramCosts};
use crate::image::Program;
use std::collections::{BTreeMap, BTreeSet};
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_runtime::keyboard::Board;
use tactus_runtime::limiter::LimiterConfig;
use tactus_runtime::performance::KeyTrack;
use tactus_runtime::player::{FingerConfig, ForcePlayer, ForceProfile};

/// How a played key moves.
#[derive(Clone, Debug)]
pub enum Motion {
    /// It follows a key-travel track (the position player).
    Track(KeyTrack),
    /// A finger pushes it with a force profile against the instrument (the force player).
    Finger(ForceProfile),
}

/// A traced key's samples: (time s, key travel m, instrument force N, hammer m, finger N,
/// motor current A, DAC code).
pub type TraceRows = Vec<[f64; 7]>;

/// The traced keys' samples, by key.
pub type Traces = BTreeMap<u8, TraceRows>;

/// Most points of a board's cycle series ([`BoardRun::cycles`]).
pub const MAX_POINTS: usize = 4000;

/// A hammer strike (or pluck) a key's firmware emitted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyStrike {
    /// MIDI key.
    pub key: u8,
    /// Time of the sample, s.
    pub time_s: f64,
    /// The event's first argument (the hammer speed), m/s.
    pub speed_mps: f64,
}

/// How [`play_boards`] runs.
#[derive(Clone, Debug)]
pub struct PerformOptions {
    /// Samples to run, from sample 0.
    pub end: usize,
    /// Sample rate, Hz.
    pub fs: f64,
    /// The finger of the force player.
    pub finger: FingerConfig,
    /// Keys to trace.
    pub trace_keys: BTreeSet<u8>,
    /// Trace from this time on, s.
    pub trace_from_s: f64,
    /// Trace until this time, s.
    pub trace_to_s: f64,
    /// The layout's boards (MIDI keys per board), or `None` to plan them as `tactus
    /// budget` does ([`boards::plan`]).
    pub boards: Option<Vec<Vec<u8>>>,
    /// The safety limiter.
    pub limiter: LimiterConfig,
    /// The emulator's engine (the same cycles either way).
    pub engine: tactus_emulator::Engine,
    /// Whether the images guard quiescent keys ([`Program::quiescent_guard`]: the same
    /// outputs either way; fewer cycles and a faster emulation with it).
    pub quiescent_guard: bool,
}

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
    /// The static bound of each core's handler.
    pub bound: Vec<u64>,
    /// The busier core's cycles, the largest of each `decimation` samples.
    pub cycles: Vec<u64>,
    /// Its keys' strikes.
    pub strikes: Vec<KeyStrike>,
    /// Its traced keys' samples.
    pub traces: Traces,
}

/// The whole keyboard's run.
#[derive(Clone, Debug)]
pub struct KeyboardRun {
    /// Per board, in key order.
    pub boards: Vec<BoardRun>,
    /// Samples per point of [`BoardRun::cycles`].
    pub decimation: usize,
}

/// Plays `motions` on the keyboard whose keys (ascending MIDI numbers) run `programs`
/// (`key_programs[i]` is key `keys[i]`'s program): plans or takes the boards, builds each
/// board's image and runs it for `opts.end` samples, the boards in parallel (rayon). `progress` is called with key-samples done since its last call.
///
/// Errors: a message naming the board when its image cannot be built or its run fails.
pub fn play_boards(
    programs: &[Program],
    keys: &[u8],
    key_programs: &[usize],
    board: &Board,
    motions: &BTreeMap<u8, &Motion>,
    opts: &PerformOptions,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<KeyboardRun, String> {
    let lim = &opts.limiter;
    let guarded: Vec<Program> = programs
        .iter()
        .map(|p| {
            let mut p = p.clone();
            p.quiescent_guard = opts.quiescent_guard;
            p
        })
        .collect();
    let programs = &guarded[..];
    let costs = ProgramCosts::new(programs, board, lim).map_err(|e| e.to_string())?;
    let keys: Vec<PlanKey> = keys
        .iter()
        .zip(key_programs)
        .map(|(&key, &program)| PlanKey { key, program })
        .collect();
    let lists: Vec<Vec<u8>> = match &opts.boards {
        Some(l) => l.clone(),
        None => boards::plan(programs, &costs, &keys, board, lim, &mut |_, _| {})
            .map_err(|e| e.to_string())?
            .into_iter()
            .map(|b| b.keys)
            .collect(),
    };
    let decimation = opts.end.div_ceil(MAX_POINTS).max(1);
    // The boards share nothing: one rayon task each, on as many threads as the machine has
    // cores.
    use rayon::prelude::*;
    let results: Vec<Result<(usize, BoardRun), String>> = lists
        .par_iter()
        .enumerate()
        .map(|(i, list)| {
            let bkeys: Vec<PlanKey> = keys
                .iter()
                .filter(|k| list.contains(&k.key))
                .copied()
                .collect();
            run_board(
                programs, &costs, &bkeys, board, motions, opts, progress, decimation,
            )
            .map(|r| (i, r))
            .map_err(|e| {
                format!(
                    "board {} ({}): {e}",
                    i + 1,
                    crate::verdict::key_ranges(list)
                )
            })
        })
        .collect();
    let mut runs: Vec<(usize, BoardRun)> = results.into_iter().collect::<Result<_, _>>()?;
    runs.sort_by_key(|r| r.0);
    Ok(KeyboardRun {
        boards: runs.into_iter().map(|r| r.1).collect(),
        decimation,
    })
}

/// One board of [`play_boards`]: its image, every key every sample.
#[allow(clippy::too_many_arguments)]
fn run_board(
    programs: &[Program],
    costs: &ProgramCosts,
    bkeys: &[PlanKey],
    board: &Board,
    motions: &BTreeMap<u8, &Motion>,
    opts: &PerformOptions,
    progress: &(dyn Fn(u64) + Sync),
    decimation: usize,
) -> Result<BoardRun, String> {
    let (end, fs) = (opts.end, opts.fs);
    let (core_of, image) = boards::board_image(programs, costs, bkeys, board, &opts.limiter)
        .map_err(|e| e.to_string())?;
    let image = image.map_err(|e| e.to_string())?;
    let mut run = image.run().map_err(|e| e.to_string())?;
    run.board().config.engine = opts.engine;
    let n_cores = image.cores();
    let key_programs: Vec<usize> = bkeys.iter().map(|k| k.program).collect();
    let mut report = BoardRun {
        keys: bkeys.iter().map(|k| k.key).collect(),
        core_keys: (0..n_cores)
            .map(|c| core_of.iter().filter(|&&k| k == c).count())
            .collect(),
        max: vec![0; n_cores],
        total: vec![0; n_cores],
        misses: vec![0; n_cores],
        bound: (0..n_cores)
            .map(|c| image.wcet(c).map_or(0, |w| w.bound()))
            .collect(),
        cycles: Vec::with_capacity(end / decimation + 1),
        strikes: Vec::new(),
        traces: Traces::new(),
    };
    let strike_event: Vec<Option<tactus_compiler::ir::EventId>> = programs
        .iter()
        .map(|p| {
            p.fixed
                .program
                .events
                .iter()
                .position(|e| e.name == "strike" || e.name == "pluck")
                .map(|i| tactus_compiler::ir::EventId(i as u32))
        })
        .collect();
    // Per program: the out word of `hammer_pos` and its format.
    let hammer_word: Vec<Option<(usize, i32)>> = programs
        .iter()
        .map(|p| {
            let fp = &p.fixed;
            fp.program
                .outputs
                .iter()
                .position(|o| o.name == "hammer_pos")
                .map(|i| (p.thumb.out.outputs + i, fp.output_frac[i]))
        })
        .collect();
    let motion: Vec<Option<&Motion>> = bkeys.iter().map(|k| motions.get(&k.key).copied()).collect();
    let mut players: Vec<Option<ForcePlayer>> = motion
        .iter()
        .zip(&key_programs)
        .map(|(m, &p)| {
            matches!(m, Some(Motion::Finger(_))).then(|| {
                let dip = programs[p].fixed.program.sensors[0].range.1;
                ForcePlayer::new(dip, opts.finger.mass_kg, fs)
            })
        })
        .collect();
    let traced: Vec<bool> = bkeys
        .iter()
        .map(|k| opts.trace_keys.contains(&k.key))
        .collect();
    let n = bkeys.len();
    let (mut sensors, mut xs) = (vec![0i32; n], vec![0.0; n]);
    let mut block_max = 0u64;
    // Traced rows of this sample waiting for their key's hammer position: (key, row).
    let mut hammers: Vec<(usize, usize)> = Vec::with_capacity(n);
    for i in 0..end {
        let time = i as f64 / fs;
        for k in 0..n {
            let x = match (motion[k], &players[k]) {
                (Some(Motion::Track(t)), _) => t.position(time),
                (_, Some(p)) => p.x_m,
                _ => 0.0,
            };
            xs[k] = x;
            let fp = &programs[key_programs[k]].fixed;
            sensors[k] = FixedInstance::sensor_raw(fp, 0, Some(x));
        }
        let out = run.step(&sensors).map_err(|e| format!("sample {i}: {e}"))?;
        for ev in &out.events {
            let p = key_programs[ev.key];
            if Some(ev.event) == strike_event[p] {
                let frac = programs[p].fixed.event_frac[ev.event.index()][0];
                report.strikes.push(KeyStrike {
                    key: bkeys[ev.key].key,
                    time_s: time,
                    speed_mps: tactus_runtime::fixed::to_f64(
                        ev.args.first().copied().unwrap_or(0),
                        frac,
                    ),
                });
            }
        }
        for c in 0..n_cores {
            report.max[c] = report.max[c].max(out.core_cycles[c]);
            report.total[c] += out.core_cycles[c];
            report.misses[c] = out.misses[c];
            block_max = block_max.max(out.core_cycles[c]);
        }
        if i % decimation == decimation - 1 || i + 1 == end {
            report.cycles.push(block_max);
            block_max = 0;
        }
        for k in 0..n {
            let p = key_programs[k];
            let force_n = tactus_runtime::fixed::to_f64(out.force[k], programs[p].fixed.total_frac);
            let push = match motion[k] {
                Some(Motion::Finger(f)) => f.force(time),
                _ => 0.0,
            };
            if let Some(player) = &mut players[k] {
                player.step(push, force_n);
            }
            if traced[k] && time >= opts.trace_from_s && time <= opts.trace_to_s {
                // The hammer is read from the key's out words once `out` is done with.
                let rows = report.traces.entry(bkeys[k].key).or_default();
                rows.push([
                    time,
                    xs[k],
                    force_n,
                    f64::NAN,
                    push,
                    out.current_ua[k] as f64 * 1e-6,
                    out.dac[k] as f64,
                ]);
                hammers.push((k, rows.len() - 1));
            }
        }
        for (k, row) in hammers.drain(..) {
            if let Some((w, frac)) = hammer_word[key_programs[k]] {
                let rows = report.traces.entry(bkeys[k].key).or_default();
                rows[row][3] = tactus_runtime::fixed::to_f64(run.out(k)[w], frac);
            }
        }
        if i % 4096 == 4095 {
            progress(4096 * n as u64);
        }
    }
    Ok(report)
}
