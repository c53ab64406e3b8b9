//! A keyboard as a set of boards: the planner and the one verdict of "does it fit".
//!
//! A real force-feedback keyboard puts a few keys on each microcontroller board (each key
//! with its motor driver and converter channels), so the sample deadline is proven **per
//! board, on its cores**. The verdict for a board is the static WCET of its actual sample
//! interrupt, per core, as [`FirmwareImage::build`] lays it out ([`IsrWcet::bound`]: the
//! handler with every key's update call, sensor copy, inline limiter and DAC store, plus
//! the window contention) against `BoardSpec::cycles_per_sample` cycles (the shortest tick
//! interval, `tactus_runtime::keyboard::deadline_cycles`). Nothing else prices
//! a key: the board file describes the machine only.
//!
//! **Keys on a board.** A board's keys take window slots from 0 in key order (a pen takes
//! as many consecutive slots as it has sensor or DAC words). They go to the cores by an
//! exact two-way partition ([`crate::schedule::partition`]) of their costs (update WCET + call + glue, each
//! from the image), so no core assignment of the same keys needs fewer cycles on its
//! fullest core; on a board with converters, among the assignments that give no core more
//! keys (slots) than its parts have channels ([`crate::schedule::partition_capped`]), so
//! the argument below holds there too: a sub-range's capped optimum is at most the range's
//! restricted to it.
//!
//! **Planning** ([`plan`]): boards take contiguous key ranges (the wiring runs along the
//! keyboard). A greedy sweep gives each board, from the lowest key up, as many further keys
//! as still fit. It is optimal when "fits" is *hereditary* — every sub-range of a fitting
//! range fits — which holds here: a sub-range's optimal partition is at most the range's
//! (costs are non-negative and additive), its window contention and its code are no
//! larger. Then, by induction, the greedy sweep's *i*-th board ends at or beyond the *i*-th
//! board of any valid plan (if greedy's board *i* starts no later, the other plan's board
//! *i* restricted to greedy's start is a fitting sub-range), so no plan has fewer boards.
//! The fit is decided by building each candidate board's image; a test checks the count
//! against brute force over every contiguous split of small mixed layouts. Heredity also
//! makes the sweep cheap: a board's end is settled by two answers (its range fits, one key
//! more does not), so the sweep searches from the previous board's key count instead of
//! growing each board from one key (`sweep`). And a candidate of the same *shape* as one
//! already built (its keys' code, flags, costs and places: `Shape`; params are data the
//! WCET never reads) takes that one's verdict, its keys renamed, instead of being built
//! and analysed again: grand88's boards are all of one shape. The plan keeps each board's
//! image ([`KeyboardPlan::images`]: a board of a shape already built takes that image with
//! its keys' param blocks, [`FirmwareImage::with_params`]), which `tactus play` boots
//! instead of building them again.

mod sweep;

use sweep::Checked;
pub use sweep::{check_boards, plan};

use crate::image::{FirmwareImage, ImageError, IsrWcet, KeySpec, Program};
use crate::windows::MAX_KEYS;
use serde::Serialize;
use std::sync::Arc;
use tactus_runtime::keyboard::BoardSpec;
use tactus_runtime::limiter::LimiterConfig;

/// One key of a keyboard, as the planner sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlanKey {
    /// MIDI key number (a pen: its layout slot).
    pub key: u8,
    /// Index of its program.
    pub program: usize,
}

/// One core of a board: its keys and its sample interrupt's static cost.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CoreVerdict {
    /// MIDI keys on the core.
    pub keys: Vec<u8>,
    /// The handler's static bound, cycles per sample ([`IsrWcet::bound`]).
    pub cycles: u64,
    /// Of `cycles`: the keys' update calls (`BL` + update WCET each).
    pub updates: u64,
    /// Of `cycles`: the window contention allowance.
    pub contention: u64,
    /// `cycles` over the cycles per sample.
    pub utilisation: f64,
    /// Cycles per sample minus `cycles` (negative: over budget).
    pub headroom: i64,
}

/// One board of a keyboard: its keys, cores and verdict.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BoardVerdict {
    /// MIDI keys on the board, ascending.
    pub keys: Vec<u8>,
    /// Per core.
    pub cores: Vec<CoreVerdict>,
    /// Per core: bytes of code (vector table, program copies, glue) in its SRAM bank.
    pub code_bytes: Vec<u32>,
    /// Why no image could be built (e.g. the code does not fit a bank): the board does not
    /// fit.
    pub error: Option<String>,
    /// Whether the board's image leaves out the quiescent-key guard its programs ask for
    /// ([`Program::quiescent_guard`]): with the guard's static cost the board would miss the
    /// deadline, and [`plan`] found that keeping it would cost boards.
    pub guard_off: bool,
    /// On a board with converters: the worst static latency of its keys, core clock cycles
    /// from a key's position being sampled to the motor command that answers it
    /// ([`FirmwareImage::latency_cycles`]); `None` without converters.
    pub latency_cycles: Option<u64>,
}

impl BoardVerdict {
    /// Every core within its cycles per sample, and an image could be built.
    pub fn fits(&self) -> bool {
        self.error.is_none() && self.cores.iter().all(|c| c.headroom >= 0)
    }

    /// Why the board does not fit, for people (`None` when it fits): its image's error (code
    /// and data beyond a core's SRAM bank, …), or each core whose sample interrupt needs
    /// more than the `cycles_per_sample` between two ticks. The one wording `tactus budget`,
    /// `build` and `play` give.
    pub fn why_not(&self, cycles_per_sample: u64) -> Option<String> {
        if let Some(e) = &self.error {
            return Some(e.clone());
        }
        let over: Vec<String> = self
            .cores
            .iter()
            .enumerate()
            .filter(|(_, c)| c.headroom < 0)
            .map(|(i, c)| {
                format!(
                    "core {i}'s sample interrupt needs {} cycles per sample, {cycles_per_sample} available",
                    c.cycles
                )
            })
            .collect();
        (!over.is_empty()).then(|| over.join("; "))
    }

    /// The smallest headroom of any core (cycles; `i64::MIN` when there is no image).
    pub fn min_headroom(&self) -> i64 {
        if self.error.is_some() {
            return i64::MIN;
        }
        self.cores.iter().map(|c| c.headroom).min().unwrap_or(0)
    }
}

/// Why boards could not be planned or checked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BoardsError {
    /// A key's program index does not exist, or its window words do not fit a board.
    BadKey(String),
    /// A program's static cost could not be found.
    Image(ImageError),
}

impl std::fmt::Display for BoardsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BoardsError::BadKey(e) => f.write_str(e),
            BoardsError::Image(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for BoardsError {}

/// A board's image as [`board_image`] builds it: the core of each of its keys (in key
/// order) and the image.
#[derive(Clone, Debug)]
pub struct BoardImage {
    /// Per key of the board, in key order: its core.
    pub core_of: Vec<usize>,
    /// The image.
    pub image: FirmwareImage,
}

impl BoardImage {
    /// Whether this can be the image of the board holding `keys` running `programs`: as many
    /// keys, each running the same code with the same param block, sensor check and
    /// watchdog (the quiescent-key guard is the planner's to drop, [`board_image`]).
    pub fn holds(&self, programs: &[Program], keys: &[PlanKey]) -> bool {
        let (specs, local) = (self.image.keys(), self.image.programs());
        specs.len() == keys.len()
            && self.core_of.len() == keys.len()
            && specs.iter().zip(keys).all(|(s, k)| {
                match (local.get(s.program), programs.get(k.program)) {
                    (Some(a), Some(b)) => {
                        a.same_code(b)
                            && a.params == b.params
                            && a.sensor_check == b.sensor_check
                            && a.watchdog == b.watchdog
                    }
                    _ => false,
                }
            })
    }
}

impl BoardImage {
    /// Whether every core's sample interrupt fits `board`'s cycles per sample
    /// ([`IsrWcet::bound`]): the image's part of [`BoardVerdict::fits`].
    pub fn fits(&self, board: &BoardSpec) -> bool {
        image_fits(&self.image, board.cycles_per_sample())
    }
}

/// Whether every core of `image` has a static bound of at most `cps` cycles.
fn image_fits(image: &FirmwareImage, cps: u64) -> bool {
    (0..image.cores()).all(|c| image.wcet(c).is_none_or(|w| w.bound() <= cps))
}

impl PartialEq for BoardImage {
    /// The same cores and the same bytes at the same addresses.
    fn eq(&self, other: &BoardImage) -> bool {
        self.core_of == other.core_of && self.image.segments() == other.image.segments()
    }
}

/// What one key of each program costs in a sample interrupt and how many window slots it
/// takes, computed once per program.
#[derive(Clone, Debug)]
pub struct ProgramCosts {
    /// Per program: update WCET + `BL` + the key's glue (static cycles, from the image).
    pub key_cycles: Vec<u64>,
    /// Per program: the same without the quiescent-key guard (equal to `key_cycles` for a
    /// program without it): what a key costs on a board where the guard does not fit
    /// ([`board_image`]).
    pub plain_key_cycles: Vec<u64>,
    /// Per program: window slots a key takes (the larger of its sensor and DAC words).
    pub slots: Vec<usize>,
}

impl ProgramCosts {
    /// Prices each program's key with [`FirmwareImage::key_glue`] and the update's WCET.
    ///
    /// Errors: [`BoardsError::Image`] (a program whose code cannot be analysed or placed).
    pub fn new(
        programs: &[Program],
        board: &BoardSpec,
        limiter: &LimiterConfig,
    ) -> Result<ProgramCosts, BoardsError> {
        let mut key_cycles = Vec::with_capacity(programs.len());
        let mut plain_key_cycles = Vec::with_capacity(programs.len());
        let mut slots = Vec::with_capacity(programs.len());
        // The glue depends on the code and the guard, not on the param block: priced once
        // per distinct code (88 graded piano keys are one).
        let mut glue_of: Vec<(&Program, u64, u64)> = Vec::new();
        for p in programs {
            let update = p.update_wcet().map_err(BoardsError::Image)?;
            let (glue, plain_glue) = match glue_of
                .iter()
                .find(|(q, ..)| q.same_code(p) && q.quiescent_guard == p.quiescent_guard)
            {
                Some(&(_, g, pg)) => (g, pg),
                None => {
                    // A program too large for a bank has no glue figure; its boards report
                    // NoRoom.
                    let price = |p: &Program| {
                        FirmwareImage::key_glue(p, board, limiter)
                            .map(|g| g.cycles)
                            .unwrap_or(0)
                    };
                    let glue = price(p);
                    let plain_glue = match p.quiescent_guard {
                        true => {
                            let mut plain = p.clone();
                            plain.quiescent_guard = false;
                            price(&plain)
                        }
                        false => glue,
                    };
                    glue_of.push((p, glue, plain_glue));
                    (glue, plain_glue)
                }
            };
            key_cycles.push(update + crate::runner::BL_CYCLES + glue);
            plain_key_cycles.push(update + crate::runner::BL_CYCLES + plain_glue);
            let drives = p.drives().map_err(BoardsError::Image)?.len();
            slots.push(p.sensor_words().max(drives));
        }
        Ok(ProgramCosts {
            key_cycles,
            plain_key_cycles,
            slots,
        })
    }
}

/// The image of one board holding `keys` (slots from 0 in key order, cores by
/// [`crate::schedule::partition`]), with the programs it uses only.
///
/// Errors: [`BoardsError::BadKey`] for an unknown program or window slots beyond the
/// board's; the image's own errors are returned inside `Ok(Err(..))` (a board that does
/// not fit, not bad input).
pub fn board_image(
    programs: &[Program],
    costs: &ProgramCosts,
    keys: &[PlanKey],
    board: &BoardSpec,
    limiter: &LimiterConfig,
) -> Result<(Vec<usize>, Result<FirmwareImage, ImageError>), BoardsError> {
    let inputs = PlanInputs::new(programs, costs, board, limiter);
    image_of(inputs, keys)
}

/// The programs `keys` run, in order of first use: the image's programs, by index.
fn used_programs(keys: &[PlanKey]) -> Vec<usize> {
    let mut used: Vec<usize> = Vec::new();
    for k in keys {
        if !used.contains(&k.program) {
            used.push(k.program);
        }
    }
    used
}

/// What a candidate board's image is built from but its keys, the same for every candidate
/// of a plan ([`image_of`], the planner's `checked` and its memo's): the programs, their
/// costs, the board and the limiter, and whether a board may leave the quiescent-key guard
/// out where only that makes it fit.
#[derive(Clone, Copy)]
struct PlanInputs<'a> {
    programs: &'a [Program],
    costs: &'a ProgramCosts,
    board: &'a BoardSpec,
    limiter: &'a LimiterConfig,
    may_drop_guard: bool,
}

impl<'a> PlanInputs<'a> {
    /// The inputs of a plan that may leave a board's quiescent-key guard out where only
    /// that makes it fit (every planner's start; the sweep's second pass turns it off).
    fn new(
        programs: &'a [Program],
        costs: &'a ProgramCosts,
        board: &'a BoardSpec,
        limiter: &'a LimiterConfig,
    ) -> PlanInputs<'a> {
        PlanInputs {
            programs,
            costs,
            board,
            limiter,
            may_drop_guard: true,
        }
    }
}

/// [`board_image`] of `keys` from `inputs`, with the fallback to an unguarded image only
/// when [`PlanInputs::may_drop_guard`].
fn image_of(
    inputs: PlanInputs,
    keys: &[PlanKey],
) -> Result<(Vec<usize>, Result<FirmwareImage, ImageError>), BoardsError> {
    let PlanInputs {
        programs,
        costs,
        board,
        limiter,
        may_drop_guard,
    } = inputs;
    let used = used_programs(keys);
    let mut specs = Vec::with_capacity(keys.len());
    let mut slot = 0;
    let mut cycles = Vec::with_capacity(keys.len());
    for k in keys {
        let width = *costs.slots.get(k.program).ok_or_else(|| {
            BoardsError::BadKey(format!(
                "key {}: program {} does not exist",
                k.key, k.program
            ))
        })?;
        let local = used.iter().position(|&p| p == k.program).unwrap_or(0);
        specs.push(KeySpec {
            slot,
            program: local,
            core: 0,
        });
        cycles.push(costs.key_cycles[k.program]);
        slot += width;
    }
    if slot > MAX_KEYS {
        return Ok((
            vec![0; keys.len()],
            Err(ImageError::Board(format!(
                "{slot} window words, the board has {MAX_KEYS}"
            ))),
        ));
    }
    // With converters a core holds keys of at most its parts' channels (one per sensor
    // word and per force word): the partition keeps within them where it can (else the
    // image says which part has too few).
    let cap = board.converter_parts().map(|(a, d)| {
        a.channels
            .min(d.channels)
            .min(crate::image::io::MAX_CHANNELS)
    });
    let widths: Vec<u32> = keys
        .iter()
        .map(|k| costs.slots.get(k.program).copied().unwrap_or(1) as u32)
        .collect();
    let build = |local: &[Program], cycles: &[u64], specs: &mut [KeySpec]| {
        let cores = board.cores as usize;
        let core = cap
            .and_then(|cap| crate::schedule::partition_capped(cycles, &widths, cores, cap))
            .unwrap_or_else(|| crate::schedule::partition(cycles, cores));
        for (s, &c) in specs.iter_mut().zip(&core) {
            s.core = c;
        }
        (core, FirmwareImage::build(local, specs, board, limiter))
    };
    let local: Vec<Program> = used.iter().map(|&p| programs[p].clone()).collect();
    let (core, image) = build(&local, &cycles, &mut specs);
    // The quiescent-key guard only where it fits: it saves cycles at rest but adds to the
    // worst case, and it must never cost a board. Where the guarded image misses the
    // deadline (or has no room), the board is built without it, its cores partitioned by
    // the unguarded costs.
    let cps = board.cycles_per_sample();
    let fits = |i: &FirmwareImage| image_fits(i, cps);
    let guarded = local.iter().any(|p| p.quiescent_guard);
    if may_drop_guard && guarded && !image.as_ref().is_ok_and(fits) {
        let plain: Vec<Program> = local
            .iter()
            .map(|p| {
                let mut p = p.clone();
                p.quiescent_guard = false;
                p
            })
            .collect();
        let plain_cycles: Vec<u64> = keys
            .iter()
            .map(|k| costs.plain_key_cycles[k.program])
            .collect();
        let (plain_core, plain_image) = build(&plain, &plain_cycles, &mut specs);
        if plain_image.is_ok() {
            return Ok((plain_core, plain_image));
        }
    }
    Ok((core, image))
}

/// Parses a board file's `text` and checks it: the chip
/// ([`crate::board_file::check_board`]: cores, sample rate, a clock PLL_SYS makes, the core
/// voltage, the converter parts and their wiring), then, on a board with `[converters]`,
/// its drivers planned for one key a core ([`check_drivers`]). `name` (the file, or
/// `builtin:NAME`) starts every error. This is the one validation of a board file:
/// `tactus budget`, `build` and `play` read every board through it.
///
/// Errors: a message naming the file and the field.
pub fn read_board(text: &str, name: &str) -> Result<BoardSpec, String> {
    let b = tactus_runtime::keyboard::parse_board(text, name)?;
    let explain = |e: crate::board_file::BoardError| {
        format!(
            "{name}: {e} (a board file describes an RP2040 board the firmware can be built for)"
        )
    };
    let chip = crate::board_file::check_board(&b).map_err(explain)?;
    check_drivers(&b, &chip).map_err(explain)?;
    Ok(b)
}

/// A board with `[converters]`: its drivers planned for one key a core (one ADC and one
/// DAC channel each, [`crate::image::io::IoPlan::plan`], the plan every image of the board
/// starts from), so that a board no key can run on — a clock the SPI clocks cannot be
/// divided from, a sample period shorter than one frame's burst, a conversion the frame
/// would outrun — is refused where it is read, not when a key's firmware is built.
///
/// Errors: [`crate::board_file::BoardError`] on `converters.adc`, `converters.dac` or
/// `converters`.
pub fn check_drivers(
    board: &BoardSpec,
    chip: &crate::board_file::Chip,
) -> Result<(), crate::board_file::BoardError> {
    let Some((adc, _)) = board.converter_parts() else {
        return Ok(());
    };
    let one = tactus_runtime::converters::AdcScale::new(0, 0, adc.bits);
    crate::image::io::IoPlan::plan(
        board,
        chip.clock_hz,
        u64::from(chip.tick.q),
        vec![vec![one]; chip.cores],
        vec![1; chip.cores],
    )
    .map(|_| ())
}

/// The verdict of one board holding `keys`: its image's static bound per core.
///
/// Errors: as [`board_image`].
pub fn check_board(
    programs: &[Program],
    costs: &ProgramCosts,
    keys: &[PlanKey],
    board: &BoardSpec,
    limiter: &LimiterConfig,
) -> Result<BoardVerdict, BoardsError> {
    let (core_of, image) = board_image(programs, costs, keys, board, limiter)?;
    Ok(image_verdict(programs, keys, board, &core_of, &image))
}

/// A keyboard's boards with their verdicts: planned by [`plan`] when its layout lists none,
/// else the layout's own checked ([`check_boards`]). Made once per keyboard
/// (`tactus_host::keyboard::Keyboard::plan`); `tactus build`, `budget` and `play` read it.
#[derive(Clone, Debug, PartialEq)]
pub struct KeyboardPlan {
    /// Per board, in key order: its keys (ascending MIDI numbers), cores and verdict.
    pub boards: Vec<BoardVerdict>,
    /// Whether the boards were planned (`false`: the layout's own).
    pub planned: bool,
    /// Per board: its image, [`board_image`] of its keys, as the planner built it, or took
    /// it from a board of the same shape with its keys' param blocks
    /// ([`FirmwareImage::with_params`]); `None` when it has none (its verdict's error says
    /// why). `tactus play` runs these instead of building them again.
    pub images: Vec<Option<Arc<BoardImage>>>,
}

impl KeyboardPlan {
    /// The plan of the checked boards `boards`.
    fn of(boards: Vec<Checked>, planned: bool) -> KeyboardPlan {
        let (boards, images) = boards.into_iter().map(|c| (c.verdict, c.image)).unzip();
        KeyboardPlan {
            boards,
            planned,
            images,
        }
    }

    /// The MIDI keys of each board, in board order.
    pub fn key_lists(&self) -> Vec<Vec<u8>> {
        self.boards.iter().map(|b| b.keys.clone()).collect()
    }
}

/// The verdict of the board holding `keys` from what [`board_image`] gave for it (the core
/// of each key and the image, or why there is none): each core's static bound against
/// `board`'s cycles per sample. [`check_board`] is this of [`board_image`].
pub fn image_verdict(
    programs: &[Program],
    keys: &[PlanKey],
    board: &BoardSpec,
    core: &[usize],
    image: &Result<FirmwareImage, ImageError>,
) -> BoardVerdict {
    let cps = board.cycles_per_sample();
    let key_list: Vec<u8> = keys.iter().map(|k| k.key).collect();
    let asked = keys
        .iter()
        .any(|k| programs.get(k.program).is_some_and(|p| p.quiescent_guard));
    let image = match image {
        Ok(i) => i,
        Err(e) => {
            return BoardVerdict {
                keys: key_list,
                cores: Vec::new(),
                code_bytes: Vec::new(),
                error: Some(e.to_string()),
                guard_off: false,
                latency_cycles: None,
            }
        }
    };
    let cores = (0..image.cores())
        .map(|c| {
            let w: IsrWcet = image.wcet(c).unwrap_or_default();
            let cycles = w.bound();
            CoreVerdict {
                keys: keys
                    .iter()
                    .zip(core)
                    .filter(|(_, &kc)| kc == c)
                    .map(|(k, _)| k.key)
                    .collect(),
                cycles,
                updates: w.updates,
                contention: w.contention,
                utilisation: cycles as f64 / cps.max(1) as f64,
                headroom: i64::try_from(cps)
                    .unwrap_or(i64::MAX)
                    .saturating_sub(i64::try_from(cycles).unwrap_or(i64::MAX)),
            }
        })
        .collect();
    BoardVerdict {
        keys: key_list,
        cores,
        code_bytes: (0..image.cores()).map(|c| image.code_bytes(c)).collect(),
        error: None,
        guard_off: asked && !image.programs().iter().any(|p| p.quiescent_guard),
        latency_cycles: (0..keys.len())
            .filter_map(|k| image.latency_cycles(k))
            .max(),
    }
}

/// Why no board of kind `board` holds even one key of program `program`, for people; `None`
/// when one key fits (the rule is [`BoardVerdict::fits`] of a one-key board). The reason
/// gives the key's static cost against the deadline when that alone is over, and the
/// image's error (code beyond a bank) when there is one.
///
/// Errors: as [`board_image`].
pub fn fits_no_board(
    programs: &[Program],
    costs: &ProgramCosts,
    program: usize,
    board: &BoardSpec,
    limiter: &LimiterConfig,
) -> Result<Option<String>, BoardsError> {
    let one = [PlanKey { key: 0, program }];
    let v = check_board(programs, costs, &one, board, limiter)?;
    let cps = board.cycles_per_sample();
    let Some(why) = v.why_not(cps) else {
        return Ok(None);
    };
    let cycles = costs.plain_key_cycles.get(program).copied().unwrap_or(0);
    Ok(Some(match (v.error.is_some(), cycles > cps) {
        (true, true) => format!(
            "one key alone takes {cycles} static cycles per sample, {cps} available; and {why}"
        ),
        _ => why,
    }))
}

/// [`fits_no_board`] of every program (`None`: one key of it fits), computed once per
/// distinct code ([`Program::same_code`]: 88 graded piano keys are one check).
///
/// Errors: as [`board_image`].
pub fn fits_no_board_each(
    programs: &[Program],
    costs: &ProgramCosts,
    board: &BoardSpec,
    limiter: &LimiterConfig,
) -> Result<Vec<Option<String>>, BoardsError> {
    let mut out: Vec<Option<Option<String>>> = vec![None; programs.len()];
    for i in 0..programs.len() {
        if out[i].is_none() {
            let why = fits_no_board(programs, costs, i, board, limiter)?;
            for j in i..programs.len() {
                if programs[j].same_code(&programs[i]) {
                    out[j] = Some(why.clone());
                }
            }
        }
    }
    Ok(out.into_iter().map(Option::flatten).collect())
}

/// The densest board of one program's keys: the most keys of program `program` that one
/// board holds (found by building boards of identical keys, at most [`MAX_KEYS`]) and that
/// board's verdict, which says whether it keeps the quiescent-key guard
/// ([`BoardVerdict::guard_off`]); `None` when not even one key fits.
///
/// Errors: as [`board_image`].
pub fn densest_board(
    programs: &[Program],
    costs: &ProgramCosts,
    program: usize,
    board: &BoardSpec,
    limiter: &LimiterConfig,
) -> Result<Option<BoardVerdict>, BoardsError> {
    let check = |n: usize| {
        let keys: Vec<PlanKey> = (0..n)
            .map(|i| PlanKey {
                key: i as u8,
                program,
            })
            .collect();
        check_board(programs, costs, &keys, board, limiter)
    };
    let fits = |n: usize| -> Result<bool, BoardsError> { Ok(check(n)?.fits()) };
    let width = costs.slots.get(program).copied().unwrap_or(1).max(1);
    let (mut lo, mut hi) = (0usize, MAX_KEYS / width);
    if !fits(1)? {
        return Ok(None);
    }
    lo = lo.max(1);
    // Largest n in [lo, hi] that fits (fits is hereditary in n).
    while lo < hi {
        let mid = (lo + hi).div_ceil(2);
        if fits(mid)? {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    check(lo).map(Some)
}

#[cfg(test)]
mod tests {
    use super::sweep::{first_miss, greedy_end, plan_with};
    use super::{
        board_image, check_board, plan, read_board, BoardImage, BoardVerdict, BoardsError, PlanKey,
        ProgramCosts,
    };
    use crate::image::{compile_layout, Program};
    use std::path::Path;
    use tactus_runtime::keyboard::BoardSpec;
    use tactus_runtime::limiter::LimiterConfig;
    use tactus_runtime::rng::XorShift64;

    /// The shipped layout `name`'s programs and keys (ascending).
    fn layout(name: &str) -> (Vec<Program>, Vec<PlanKey>) {
        let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
        let path = root.join(format!("instruments/layouts/{name}.toml"));
        let (_, keys) = tactus_runtime::keyboard::read_layout(&path).unwrap();
        let source = |i: &str| {
            std::fs::read_to_string(root.join(format!("instruments/{i}.tactus")))
                .map_err(|e| format!("{i}: {e}"))
        };
        let (programs, index) = compile_layout(&keys, &source, 44_100.0).unwrap();
        let mut keys: Vec<PlanKey> = (keys.iter().zip(index))
            .map(|(k, program)| PlanKey {
                key: k.key,
                program,
            })
            .collect();
        keys.sort_by_key(|k| k.key);
        (programs, keys)
    }

    /// Plans `keys` with the verdicts taken by shape and with every candidate built: the
    /// same boards, verdicts and errors; each image the first plan kept is the second's, and
    /// each board's verdict that of its board checked alone. Returns the boards and how
    /// many images the first plan kept.
    fn same_plans(programs: &[Program], keys: &[PlanKey], b: &BoardSpec) -> (usize, usize) {
        let lim = LimiterConfig::for_board(b);
        let costs = ProgramCosts::new(programs, b, &lim).unwrap();
        let memo = plan_with(programs, &costs, keys, b, &lim, true, &mut |_, _| {});
        let each = plan_with(programs, &costs, keys, b, &lim, false, &mut |_, _| {});
        let (memo, each) = match (memo, each) {
            (Ok(m), Ok(e)) => (m, e),
            (m, e) => {
                assert_eq!(m.map(|p| p.boards), e.map(|p| p.boards), "{}", b.name);
                return (0, 0);
            }
        };
        assert_eq!(memo.boards, each.boards, "{}", b.name);
        assert_eq!(memo.planned, each.planned);
        assert!(each.images.iter().all(Option::is_some), "{}", b.name);
        let mut kept = 0;
        for (i, (m, e)) in memo.images.iter().zip(&each.images).enumerate() {
            if m.is_some() {
                assert_eq!(m, e, "{} board {i}", b.name);
                kept += 1;
            }
            let bkeys: Vec<PlanKey> = (keys.iter())
                .filter(|k| memo.boards[i].keys.contains(&k.key))
                .copied()
                .collect();
            let alone = check_board(programs, &costs, &bkeys, b, &lim).unwrap();
            assert_eq!(alone, memo.boards[i], "{} board {i}", b.name);
        }
        (memo.boards.len(), kept)
    }

    #[test]
    fn every_planned_board_of_grand88_has_the_image_board_image_builds_for_it() {
        // grand88's boards are of one shape: the plan builds the first board's image and
        // gives the others that image with their keys' param blocks (`with_params`). Each
        // must be byte for byte the image `board_image` builds for the board (the guard
        // left out, as the plan chose: BENCHMARKS.md), cores included, and hold the
        // board's programs (what `tactus play` checks before booting it).
        let (programs, keys) = layout("grand88");
        for name in ["rp2040", "rp2040_io"] {
            let b = board(name);
            let lim = LimiterConfig::for_board(&b);
            let costs = ProgramCosts::new(&programs, &b, &lim).unwrap();
            let plan = plan(&programs, &costs, &keys, &b, &lim, &mut |_, _| {}).unwrap();
            assert_eq!(plan.boards.len(), 11, "{name}");
            assert_eq!(plan.images.len(), 11, "{name}");
            for (i, (v, planned)) in plan.boards.iter().zip(&plan.images).enumerate() {
                let bkeys: Vec<PlanKey> = (keys.iter())
                    .filter(|k| v.keys.contains(&k.key))
                    .copied()
                    .collect();
                let planned = planned.as_deref().expect("an image for every board");
                let (core_of, image) = board_image(&programs, &costs, &bkeys, &b, &lim).unwrap();
                let want = BoardImage {
                    core_of,
                    image: image.unwrap(),
                };
                assert!(
                    planned == &want,
                    "{name} board {}: not board_image's",
                    i + 1
                );
                assert!(planned.holds(&programs, &bkeys), "{name} board {}", i + 1);
                // The boards differ in their param blocks: a board's image is not another's.
                if i > 0 {
                    let first = plan.images[0].as_deref().unwrap();
                    assert!(first != planned, "{name} board {}: board 1's image", i + 1);
                }
            }
        }
    }

    /// The shipped board `name`.
    fn board(name: &str) -> BoardSpec {
        let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../boards"));
        let text = std::fs::read_to_string(root.join(format!("{name}.toml"))).unwrap();
        read_board(&text, name).unwrap()
    }

    #[test]
    fn the_plan_with_verdicts_by_shape_is_the_plan_of_every_candidate_built() {
        // grand88: 88 graded piano keys, one code; 11 boards on rp2040, the first built,
        // the others of its shape, each with its image all the same.
        let (programs, keys) = layout("grand88");
        let (boards, kept) = same_plans(&programs, &keys, &board("rp2040"));
        assert_eq!(boards, 11);
        assert_eq!(kept, 11);
        // Two instruments, on a converter board (the capped partition).
        let (programs, keys) = layout("split_harpsichord_piano");
        let (boards, _) = same_plans(&programs, &keys, &board("rp2040_io"));
        assert!(boards >= 2, "{boards}");
        // Keys of the two instruments interleaved, some sharing a param set: boards with
        // a program used twice or more and classes mixed; and a key whose program does
        // not exist (the sweep's error, as without shapes).
        let mut rng = XorShift64::new(0x5AFE);
        let pick = [0, 1, programs.len() - 1, programs.len() - 2];
        let mixed: Vec<PlanKey> = (0..40)
            .map(|k| PlanKey {
                key: 21 + k as u8,
                program: pick[rng.below(pick.len())],
            })
            .collect();
        let (boards, _) = same_plans(&programs, &mixed, &board("rp2040"));
        assert!(boards >= 2, "{boards}");
        let mut bad = mixed.clone();
        bad[25].program = programs.len();
        assert_eq!(same_plans(&programs, &bad, &board("rp2040")), (0, 0));
    }

    /// A verdict that fits or not, for `len` keys.
    fn verdict(len: usize, fits: bool) -> BoardVerdict {
        BoardVerdict {
            keys: vec![0; len],
            cores: Vec::new(),
            code_bytes: Vec::new(),
            error: (!fits).then(|| "over".to_string()),
            guard_off: false,
            latency_cycles: None,
        }
    }

    #[test]
    fn the_search_for_a_boards_end_gives_the_one_key_at_a_time_answer() {
        // Hereditary fits (a board from `start` fits up to some end), starts and guesses,
        // and errors from some key on: the search's end, verdict and error are the
        // sequential sweep's.
        let keys: Vec<PlanKey> = (0..12).map(|k| PlanKey { key: k, program: 0 }).collect();
        let mut rng = XorShift64::new(0x5EA4C4);
        let mut compared = 0;
        for trial in 0..400 {
            let n = 1 + rng.below(keys.len());
            let keys = &keys[..n];
            let start = rng.below(n);
            // The greedy end: `start - 1` (not even one key fits) up to the last key.
            let last_fit = start as i64 - 1 + rng.below(n - start + 1) as i64;
            let error_at = (trial % 3 == 0).then(|| start + rng.below(n - start));
            let check = |ks: &[PlanKey]| -> Result<BoardVerdict, BoardsError> {
                let end = start + ks.len() - 1;
                // Errors are per key (a program that does not exist): every range that
                // holds the erring key errs.
                if error_at.is_some_and(|e| end >= e) {
                    return Err(BoardsError::BadKey(format!("end {end}")));
                }
                Ok(verdict(ks.len(), end as i64 <= last_fit))
            };
            let want = first_miss(&check, keys, start);
            for guess in [0, 1, 2, 3, 5, 8, 12, 40] {
                let got = greedy_end(&check, keys, start, guess);
                assert_eq!(got, want, "start {start} of {n}, fits to {last_fit}, error at {error_at:?}, guess {guess}");
                compared += 1;
            }
        }
        assert_eq!(compared, 3200);
        // A fit that is not hereditary (ranges to 2 and 5 fit, 3 and 4 do not), which the
        // module documentation's argument excludes: from any guess, a fitting board whose
        // next range does not fit, and no panic or endless search.
        let check = |ks: &[PlanKey]| -> Result<BoardVerdict, BoardsError> {
            Ok(verdict(ks.len(), [0, 1, 2, 5].contains(&(ks.len() - 1))))
        };
        for guess in 1..8 {
            let (end, v) = greedy_end(&check, &keys[..8], 0, guess).unwrap();
            assert!(v.fits() && [2, 5].contains(&end), "guess {guess}: {end}");
            assert_eq!(v.keys.len(), end + 1);
        }
    }

    const IO: &str = "name = \"io\"\nclock_hz = 133e6\ncores = 2\nsample_rate_hz = 44100\n\
                      [converters]\nadc = \"ADS8688\"\ndac = \"DAC8568\"\n\
                      adc_pins = [[2, 3, 4, 5], [10, 11, 12, 13]]\n\
                      dac_pins = [[6, 7, 8], [14, 15, 16]]\n";

    #[test]
    fn converters_are_parts_the_firmware_drives_wired_as_its_drivers_need() {
        assert!(read_board(IO, "io.toml").is_ok());
        let e = read_board(&IO.replace("ADS8688", "ADS1278"), "io.toml").unwrap_err();
        assert!(
            e.contains("io.toml") && e.contains("`converters.adc`"),
            "{e}"
        );
        let e = read_board(&IO.replace("[14, 15, 16]", "[14, 16, 15]"), "io.toml").unwrap_err();
        assert!(
            e.contains("io.toml") && e.contains("`converters.dac_pins`"),
            "{e}"
        );
    }

    #[test]
    fn a_converter_board_whose_sample_period_is_shorter_than_one_frame_is_refused() {
        // 500 kHz at 133 MHz: 266 cycles a sample, less than one ADC frame's burst (332
        // cycles): no key could run, so the board is refused where it is read.
        let fast = IO.replace("sample_rate_hz = 44100", "sample_rate_hz = 500000");
        let e = read_board(&fast, "io.toml").unwrap_err();
        assert!(
            e.contains("io.toml") && e.contains("`converters.adc`") && e.contains("sample period"),
            "{e}"
        );
        // Without converters the same clock and rate are a board.
        let plain = &fast[..fast.find("[converters]").unwrap()];
        assert!(read_board(plain, "io.toml").is_ok());
        // The shipped converter board is read.
        let shipped = include_str!("../../../boards/rp2040_io.toml");
        assert!(read_board(shipped, "rp2040_io.toml").is_ok());
    }
}
