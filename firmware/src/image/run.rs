//! [`ImageRun`]: a [`FirmwareImage`] running on an emulated RP2040, stepped one sample at a
//! time from the host.
//!
//! The run starts from reset, through each core's start-up and the start alarm, at which
//! both cores start their SysTick ([`run_to_first_tick`]), and stops at the first sample
//! tick; tick *n* then falls on cycle `first + ⌊n·clock/fs⌋`
//! (`tactus_runtime::keyboard::tick_cycle`), on both cores. Per [`ImageRun::step`]: the
//! host writes every key's sensor words into the sensor window (as the sensor DMA would,
//! before the tick), runs the board up to the *next* sample's tick — both cores sleep in `WFI` between their handlers, and the emulator skips sleep in
//! one jump — and reads back each key's out words, and per force word it drives (one for a
//! keyboard key, one per axis for a pen) the limited current and the DAC word, each
//! core's handler cycles (measured by profiling the handler: exception entry + first
//! instruction to the completed return) and the miss counters. If a core has not completed
//! the sample by then (an overloaded image), the run continues until it has; the next
//! handler may then already have started with the previous sensor words.

use super::glue::ctrl;
use super::layout::START_CYCLES;
use super::rest::{lcm, Phase, Rest, SETTLE};
use super::sample::{DriveOut, KeyEvent, SampleOut};
use super::{FirmwareImage, ImageError, STACK_CANARY};
use crate::windows::{DAC_BASE, SENSOR_BASE};
use tactus_emulator::{Board, Config, StopReason};
use tactus_isa::timing::EXCEPTION_ENTRY;
use tactus_rp2040::memory::sram_location;
use tactus_runtime::limiter::{Limiter, LimiterConstants};

mod inject;
pub use inject::{code_word, FaultKind, Injection, ResetRecord, HANG_STUB, NOISE_SEED};

/// One frame at a converter's pins ([`ImageRun::take_io`]): an ADC frame (the channel it
/// sampled at its chip select's fall, the code, the command it carried) or a DAC output
/// change (at the frame's 32nd SCLK falling edge, the channel's new code).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IoRecord {
    /// The core whose converter it is.
    pub core: usize,
    /// `true` for the DAC, `false` for the ADC.
    pub dac: bool,
    /// The board's cycle of the edge.
    pub cycle: u64,
    /// The channel.
    pub channel: u8,
    /// The code (the ADC's sample; the DAC's output, straight binary).
    pub code: u16,
    /// The ADC frame's command (0 for the DAC).
    pub command: u16,
}

/// A firmware image on an emulated board.
pub struct ImageRun {
    board: Board,
    image: FirmwareImage,
    /// Samples completed on every core.
    samples: u64,
    /// Cycle of the first sample tick (tick 0).
    first_tick: u64,
    profiles: Vec<usize>,
    sample: SampleOut,
    stalls: [u64; 2],
    scratch: Vec<u32>,
    /// The sensor words the ADC's codes were last set from ([`ImageRun::set_codes`]); empty
    /// when they must be set again (never set, or set under injected faults).
    codes_of: Vec<i32>,
    /// Where the words the host touches every sample lie in the emulated SRAM
    /// ([`tactus_emulator::bus::System::sram`], byte offsets): read and written there
    /// directly, as [`Board::read_words`] and [`Board::write_words`] would (no cycles, the
    /// decoded code left alone: no instruction lives in them).
    at: HostWords,
    /// The limiter's constants: the current of each DAC code written.
    limiter: LimiterConstants,
    /// The rest replay ([`super::rest`]; off unless [`ImageRun::set_rest_replay`]).
    rest: Rest,
    /// An error of the rest replay met where none could be returned ([`ImageRun::board`]),
    /// returned by the next [`ImageRun::step`] or [`ImageRun::settle`].
    rest_error: Option<ImageError>,
    /// Injected faults and the resets met (`inject.rs`).
    faults: inject::Faults,
}

/// SRAM byte offsets of the words [`ImageRun::step`] reads and writes (see
/// [`ImageRun::at`]).
#[derive(Clone, Debug, Default)]
struct HostWords {
    /// Every key's sensor window words, in flat order (the keys' words in key-list order).
    sensors: Vec<usize>,
    /// Every key's DAC window words, in flat order.
    dacs: Vec<usize>,
    /// Per key, its out words.
    outs: Vec<Vec<usize>>,
    /// Every key's out words, in key order (`outs` flat: the rest replay's recording).
    all_outs: Vec<usize>,
    /// Per core: its sample counter, its miss counter, its stack canary.
    samples: Vec<usize>,
    /// Per drive of each key (key index, drive index, SRAM offset): its limiter's budget
    /// word.
    budgets: Vec<(usize, usize, usize)>,
    /// The rest replay's counter words: `samples`, then `budgets`' words.
    counters: Vec<usize>,
    misses: Vec<usize>,
    canaries: Vec<usize>,
}

impl HostWords {
    fn new(image: &FirmwareImage) -> Result<HostWords, ImageError> {
        let off = |addr: u32| match sram_location(addr) {
            Some((o, _)) if o + 4 <= tactus_rp2040::memory::SRAM_SIZE as usize => Ok(o),
            _ => Err(ImageError::Run(format!("{addr:#010x} is not an SRAM word"))),
        };
        let window = |base: u32, w: &usize| off(base + 4 * *w as u32);
        let outs: Vec<Vec<usize>> = image
            .keys
            .iter()
            .map(|k| {
                (0..k.out_len as u32)
                    .map(|i| off(k.record + k.out_offset + 4 * i))
                    .collect()
            })
            .collect::<Result<_, _>>()?;
        let samples: Vec<usize> = (image.cores.iter())
            .map(|c| off(c.ctrl + ctrl::SAMPLES as u32))
            .collect::<Result<_, _>>()?;
        let mut budgets = Vec::new();
        for (i, k) in image.keys.iter().enumerate() {
            for (j, &(_, b)) in k.drives.iter().enumerate() {
                budgets.push((i, j, off(k.record + b)?));
            }
        }
        let counters = (samples.iter().copied())
            .chain(budgets.iter().map(|b| b.2))
            .collect();
        Ok(HostWords {
            samples,
            budgets,
            counters,
            sensors: image
                .keys
                .iter()
                .flat_map(|k| k.sensor_words.iter())
                .map(|w| window(SENSOR_BASE, w))
                .collect::<Result<_, _>>()?,
            dacs: if image.io.is_some() {
                // The DAC frames the handler writes, one word a channel.
                (image.keys.iter())
                    .flat_map(|k| {
                        let frames = super::io::io_base(k.spec.core) + super::io::DAC_FRAMES;
                        k.dac_channels.iter().map(move |&ch| off(frames + 4 * ch))
                    })
                    .collect::<Result<_, _>>()?
            } else {
                (image.keys.iter())
                    .flat_map(|k| k.dac_words.iter())
                    .map(|w| window(DAC_BASE, w))
                    .collect::<Result<_, _>>()?
            },
            all_outs: outs.iter().flatten().copied().collect(),
            outs,
            misses: image
                .cores
                .iter()
                .map(|c| off(c.ctrl + ctrl::MISSES as u32))
                .collect::<Result<_, _>>()?,
            canaries: image
                .cores
                .iter()
                .map(|c| off(c.stack_bottom))
                .collect::<Result<_, _>>()?,
        })
    }
}

/// The little-endian word at byte `o` of `sram` (`o + 4` within it: [`HostWords`]' offsets
/// are).
#[inline(always)]
fn word(sram: &[u8], o: usize) -> u32 {
    // One bounds check and one load (four byte indexes compile to four of each).
    sram.get(o..o + 4)
        .and_then(|b| b.try_into().ok())
        .map_or(0, u32::from_le_bytes)
}

/// `from` into `to`, reusing `to`'s buffers (every field named: a new one must be
/// copied too).
fn copy_sample(from: &SampleOut, to: &mut SampleOut) {
    let SampleOut {
        force,
        current_ua,
        dac,
        drives,
        events,
        core_cycles,
        handler_runs,
        misses,
        stalls,
    } = from;
    to.force.clone_from(force);
    to.current_ua.clone_from(current_ua);
    to.dac.clone_from(dac);
    to.drives.clone_from(drives);
    to.events.clone_from(events);
    to.core_cycles.clone_from(core_cycles);
    to.handler_runs.clone_from(handler_runs);
    to.misses.clone_from(misses);
    to.stalls.clone_from(stalls);
}

/// Samples after which a board at rest repeats its state ([`super::rest`]): the lcm of the
/// tick schedule's remainder's period (its `den`: `rem/den` in lowest terms, 1 for whole
/// cycles) and the differentiator rings' length; with converters also of the ring of
/// results buffers (3 samples, `super::io`, "A resting board repeats"), and a whole number
/// of each PIO clock divider's periods (a state machine's divider phase is state:
/// 3,230,000 cycles, 1,071 samples, at 133 MHz; 102,000,000 cycles, 22,491 samples, at
/// 200 MHz, whose ADC divider is 3).
fn rest_period(image: &FirmwareImage) -> usize {
    let ring = 2 * tactus_runtime::differentiator::WINDOW as u64 + 1;
    let samples = lcm(u64::from(image.tick().den), ring);
    let Some(plan) = &image.io else {
        return samples as usize;
    };
    let samples = lcm(samples, super::io::RESULTS.len() as u64);
    let cycles =
        tactus_runtime::keyboard::tick_cycle(0, samples, image.clock_hz, image.sample_rate_hz);
    let divs = lcm(
        u64::from(plan.adc_div.max(1)),
        u64::from(plan.dac_div.max(1)),
    );
    // The fewest periods whose cycles are a whole number of `divs`.
    let times = divs / crate::board_file::gcd(cycles, divs).max(1);
    (samples * times.max(1)) as usize
}

/// Host access failure as an image error.
fn emu(e: impl std::fmt::Display) -> ImageError {
    ImageError::Emu(e.to_string())
}

/// How often [`run_to_timer`] follows the timer's restarts before it gives up.
const MAX_TIMER_RESTARTS: usize = 16;
/// How long [`run_to_timer`] waits for the firmware to release the timer, µs of the
/// board's clock (a fresh flash chip's status write alone takes 10 ms).
const MAX_BOOT_US: u64 = 1_000_000;

/// Runs `board` until its timer, once the firmware's reset handler has released it from
/// reset (which restarts its count, `tactus_emulator::timer`), reads `us` µs, and returns
/// that cycle: a boot of any length before the release (boot2, the copy from flash, the
/// core voltage's settling) is followed to the firmware's own time. The run goes in
/// steps of half of `us` until the release (so it stops before the timer reaches `us`
/// after it), then to where the timer would reach `us`, again while that moves.
///
/// Errors: a message when the board stops otherwise ([`Board::describe_stop`]), when the
/// firmware has not released the timer within a second of the board's clock, or when
/// it restarts the timer more than 16 times.
pub fn run_to_timer(board: &mut Board, us: u64) -> Result<u64, String> {
    let step = (us * board.config.clock_hz / 2_000_000).max(1);
    let give_up = board.cycle() + MAX_BOOT_US * (board.config.clock_hz / 1_000_000);
    while board.system.timer.released_at().is_none() {
        if board.cycle() > give_up {
            return Err(format!(
                "the firmware did not release the timer from reset within {} ms of power-on",
                MAX_BOOT_US / 1000
            ));
        }
        let stop = board.run_for(step);
        if stop != StopReason::CycleLimit {
            return Err(format!("the board stopped: {}", board.describe_stop(&stop)));
        }
    }
    for _ in 0..MAX_TIMER_RESTARTS {
        let at = board.system.timer.cycle_at_us(us);
        let stop = board.run_until(at);
        if stop != StopReason::CycleLimit {
            return Err(format!("the board stopped: {}", board.describe_stop(&stop)));
        }
        if board.system.timer.cycle_at_us(us) == at {
            return Ok(at);
        }
    }
    Err(format!(
        "the timer was restarted more than {MAX_TIMER_RESTARTS} times before reading {us} µs"
    ))
}

/// Runs `board` — booted into a [`FirmwareImage`]'s firmware, at or before its start
/// alarm at `alarm_us` µs of its timer — until each of its first `cores` cores has started
/// its SysTick ([`START_CYCLES`] after the alarm), then to the first sample tick; returns
/// that tick's cycle. The tick is the board's own state: the cycle at which each core's
/// SysTick next reaches 0 (the emulated `SYST_CVR`, as a logic analyser would see the
/// first interrupt), which must be the same on every core.
///
/// Errors: a message when the board stops otherwise (a fault), a core's SysTick is not
/// counting the processor clock with its interrupt enabled by then, or the cores' first
/// ticks differ.
pub fn run_to_first_tick(board: &mut Board, alarm_us: u64, cores: usize) -> Result<u64, String> {
    let check = |stop: StopReason, board: &Board| match stop {
        StopReason::CycleLimit => Ok(()),
        other => Err(format!(
            "the board stopped: {}",
            board.describe_stop(&other)
        )),
    };
    let started = run_to_timer(board, alarm_us)? + START_CYCLES;
    let stop = board.run_until(started);
    check(stop, board)?;
    let mut first = None;
    for (k, c) in board.cores.iter().take(cores).enumerate() {
        let n = &c.nvic;
        if n.syst_csr & 7 != 7 || n.syst_next == u64::MAX || n.syst_next <= started {
            return Err(format!(
                "core {k}: SysTick not started by {START_CYCLES} cycles after the start \
                 alarm ({alarm_us} µs): SYST_CSR {:#x}",
                n.syst_csr
            ));
        }
        match first {
            None => first = Some(n.syst_next),
            Some(t) if t != n.syst_next => {
                return Err(format!(
                    "the cores' first sample ticks differ: cycle {t} on core 0, {} on core {k}",
                    n.syst_next
                ))
            }
            Some(_) => {}
        }
    }
    let first = first.ok_or("no core")?;
    let stop = board.run_until(first);
    check(stop, board)?;
    Ok(first)
}

/// How many eighths of a sample period a step may run past the next tick for an
/// overloaded core before the run is declared stuck.
const MAX_EXTRA_EIGHTHS: u32 = 8 * 1000;

impl ImageRun {
    /// A fresh board for `image`: its converters at their pins when it drives some.
    fn fresh_board(image: &FirmwareImage, own_banks: [u8; 2]) -> Board {
        let mut board = Board::new(Config {
            clock_hz: image.clock_hz,
            own_banks,
            ..Config::default()
        });
        if let Some(io) = &image.io {
            board.attach_io(&io.emulator_config());
        }
        board
    }

    pub(crate) fn new(
        image: &FirmwareImage,
        first: Option<&[i32]>,
    ) -> Result<ImageRun, ImageError> {
        let mut board = ImageRun::fresh_board(image, image.own_banks());
        for (addr, bytes) in &image.segments {
            board.write_bytes(*addr, bytes).map_err(emu)?;
        }
        // From reset, as after a RAM UF2 download: the boot ROM enters the image at its
        // lowest address with SP at the top of SRAM (`super::boot`); core 0 sets the clocks
        // up and launches core 1 over the FIFOs, where core 1 waits in the boot ROM.
        board.enter_ram_image(super::boot::ENTRY | 1);
        ImageRun::start(board, image, first)
    }

    /// Writes `flash` (bytes from 0x10000000: the image's [`FirmwareImage::flash_image`], or
    /// a corrupted copy) into the flash of a fresh emulated board and powers it on through
    /// the boot ROM's flash path ([`Board::boot_from_flash`]: boot2's CRC checked, boot2,
    /// the image's copy of itself to SRAM, then its reset handlers as in [`FirmwareImage::run`]),
    /// and runs it up to the first tick.
    ///
    /// Errors: [`ImageError::Emu`] when the boot ROM rejects boot2 or `flash` passes the
    /// flash; those of [`FirmwareImage::run`].
    pub fn from_flash(image: &FirmwareImage, flash: &[u8]) -> Result<ImageRun, ImageError> {
        let mut board = ImageRun::fresh_board(image, [0, 0]);
        board
            .write_bytes(tactus_rp2040::memory::FLASH_BASE, flash)
            .map_err(emu)?;
        board.boot_from_flash().map_err(emu)?;
        ImageRun::start(board, image, None)
    }

    /// Loads `elf` (the image's [`FirmwareImage::elf`] or [`FirmwareImage::flash_elf`], or a
    /// file claiming to be) into a fresh emulated board, which boots it as the boot ROM
    /// would ([`Board::load_elf`]: from flash through boot2, or at the entry point of a RAM
    /// image), and runs it up to the first tick; `image` tells where its keys and counters
    /// are. `first`: the keys' sensor words from power-on, as
    /// [`FirmwareImage::run_from`] takes them (`None`: [`FirmwareImage::run`]'s).
    ///
    /// Errors: [`ImageError::Emu`] for a file the loader rejects; those of
    /// [`FirmwareImage::run_from`].
    pub fn from_elf(
        image: &FirmwareImage,
        elf: &[u8],
        first: Option<&[i32]>,
    ) -> Result<ImageRun, ImageError> {
        let mut board = ImageRun::fresh_board(image, image.own_banks());
        board.load_elf(elf).map_err(emu)?;
        ImageRun::start(board, image, first)
    }

    /// `first`: the keys' sensor words from power-on ([`FirmwareImage::run_from`]).
    fn start(
        mut board: Board,
        image: &FirmwareImage,
        first: Option<&[i32]>,
    ) -> Result<ImageRun, ImageError> {
        let mut profiles = Vec::new();
        for c in &image.cores {
            profiles.push(board.profile_handler(c.isr));
        }
        // Keys at rest compute the same update sample after sample: the emulator replays
        // such calls, and each run of a copy of a core's keys code in the handler, from
        // recordings (exactly; `tactus_emulator::Board::memoize`). Not the copies on a
        // board with converters: there a span's recording interprets every key's update
        // (the emulator takes a call in it from the call's memo only without an I/O), and
        // its sensor words lie in one of three results buffers, three times the states:
        // the `rp2040_io` demo took 19.16 G host instructions with them, 18.13 G without.
        let updates: Vec<u32> = image.keys.iter().map(|k| k.update).collect();
        let spans: Vec<(u32, u32)> = match image.io {
            Some(_) => Vec::new(),
            None => (image.cores.iter())
                .flat_map(|c| c.keys_spans.iter().copied())
                .collect(),
        };
        board.memoize(&updates, &spans);
        let n = image.keys.len();
        let cores = image.cores.len();
        let mut run = ImageRun {
            board,
            image: image.clone(),
            samples: 0,
            first_tick: 0,
            profiles,
            sample: SampleOut {
                force: vec![0; n],
                current_ua: vec![0; n],
                dac: vec![0; n],
                drives: image
                    .keys
                    .iter()
                    .map(|k| {
                        k.drives
                            .iter()
                            .enumerate()
                            .map(|(j, (d, _))| DriveOut {
                                axis: d.axis,
                                slot: k.dac_words[j],
                                ..DriveOut::default()
                            })
                            .collect()
                    })
                    .collect(),
                events: Vec::new(),
                core_cycles: vec![0; cores],
                handler_runs: vec![0; cores],
                misses: vec![0; cores],
                stalls: vec![0; cores],
            },
            stalls: [0; 2],
            scratch: Vec::new(),
            codes_of: Vec::new(),
            at: HostWords::new(image)?,
            limiter: Limiter::new(&image.limiter)
                .map_err(ImageError::Limiter)?
                .constants(),
            rest: Rest::new(rest_period(image)),
            rest_error: None,
            faults: Default::default(),
        };
        if let Some(first) = first {
            // Before the start alarm, whose ADC burst the first handler reads.
            let expected = run.image.sensor_words();
            if first.len() != expected {
                return Err(ImageError::SensorCount {
                    expected,
                    got: first.len(),
                });
            }
            run.set_codes(first);
        }
        let alarm = run.image.start_alarm_us as u64;
        run_to_timer(&mut run.board, alarm).map_err(ImageError::Run)?;
        for (k, c) in run.image.cores.iter().enumerate() {
            let ready = run
                .board
                .read_u32(c.ctrl + ctrl::READY as u32)
                .map_err(emu)?;
            if ready != 1 {
                return Err(ImageError::Run(format!(
                    "core {k} did not finish its start-up before the start alarm ({alarm} µs)"
                )));
            }
        }
        let cores = run.image.cores.len();
        run.first_tick =
            run_to_first_tick(&mut run.board, alarm, cores).map_err(ImageError::Run)?;
        run.stalls = run.board.system.contention_stalls;
        Ok(run)
    }

    /// Cycle of sample tick `n` (sample `n`'s interrupt, from 0), as the cores' SysTicks
    /// tick: `first + ⌊n·clock/fs⌋` (`tactus_runtime::keyboard::tick_cycle`).
    pub fn tick_cycle(&self, n: u64) -> u64 {
        // After a reset, `first_tick` is the firmware's new tick 0, at sample `tick_base`
        // (`inject.rs`).
        tactus_runtime::keyboard::tick_cycle(
            self.first_tick,
            n.saturating_sub(self.faults.tick_base),
            self.image.clock_hz,
            self.image.sample_rate_hz,
        )
    }

    fn check_stop(&self, stop: StopReason) -> Result<(), ImageError> {
        match stop {
            StopReason::CycleLimit => Ok(()),
            other => Err(ImageError::Run(format!(
                "the board stopped: {}",
                self.board.describe_stop(&other)
            ))),
        }
    }

    /// Runs one sample: `sensors` holds the raw sensor words of every key in key-list
    /// order, each key's [`super::Program::sensor_words`] words in its program's sensor
    /// order (one per keyboard key; a pen's `z`, `x`, … as declared), written to the key's
    /// sensor window words before the sample's tick. Returns what the sample produced.
    /// With the rest replay on ([`ImageRun::set_rest_replay`]) a sample of a board at rest
    /// may be given from a recording instead: the same outputs, exactly.
    ///
    /// Errors: [`ImageError::SensorCount`]; [`ImageError::Run`] when the board faults, a
    /// core never completes the sample, a stack canary was overwritten, or the rest
    /// replay's board differs from its recording.
    pub fn step(&mut self, sensors: &[i32]) -> Result<&SampleOut, ImageError> {
        let words = self.image.sensor_words();
        if sensors.len() != words {
            return Err(ImageError::SensorCount {
                expected: words,
                got: sensors.len(),
            });
        }
        if let Some(e) = self.rest_error.take() {
            return Err(e);
        }
        if self.has_faults() {
            return self.step_faulted(sensors);
        }
        self.step_words(sensors)
    }

    /// [`ImageRun::step`] with injected faults (`inject.rs`): the faults applied to the
    /// words and the board, a board rebooting or dead giving zero-force samples.
    fn step_faulted(&mut self, sensors: &[i32]) -> Result<&SampleOut, ImageError> {
        if self.faults.dead.is_some() || self.faults.zero_left > 0 {
            self.faults.zero_left = self.faults.zero_left.saturating_sub(1);
            self.samples += 1;
            self.zero_sample();
            return Ok(&self.sample);
        }
        // A replay's samples are run again with the codes they had: end it before the
        // faults change anything.
        self.leave_rest()?;
        if self.apply_faults(sensors)? {
            self.rest.forget();
        }
        let words = std::mem::take(&mut self.faults.buf);
        let out = self.step_words(&words).map(|_| ());
        self.faults.buf = words;
        out?;
        Ok(&self.sample)
    }

    /// [`ImageRun::step`] of checked words.
    fn step_words(&mut self, sensors: &[i32]) -> Result<&SampleOut, ImageError> {
        if !self.rest.on {
            self.run_sample(sensors)?;
            return Ok(&self.sample);
        }
        let same = self.rest.note(sensors);
        if same && self.rest.can_give() {
            self.samples += 1;
            return Ok(self.rest.give());
        }
        // New words, or as many samples given as the budgets' room allows.
        if same && self.rest.replaying() {
            self.rest.room_ends += 1;
        }
        self.leave_rest()?;
        self.run_sample(sensors)?;
        self.after_sample(same);
        Ok(&self.sample)
    }

    /// Gives up to `most` samples with the sensor words `sensors` from the rest replay's
    /// recording, as as many [`ImageRun::step`]s would, while `take` accepts each (it sees
    /// the sample before it is given; the first it refuses is not given); returns how many
    /// it gave. None when the replay is not giving samples now, `sensors` are not the last
    /// sample's words, or an error is waiting for the next step.
    pub fn give_while(
        &mut self,
        sensors: &[i32],
        most: u64,
        take: impl FnMut(&SampleOut) -> bool,
    ) -> u64 {
        if !self.rest.on || self.rest_error.is_some() || self.rest.last != sensors {
            return 0;
        }
        let most = if self.has_faults() {
            most.min(self.faults_quiet(self.samples))
        } else {
            most
        };
        let given = self.rest.give_while(most, take);
        self.rest.same += given;
        self.samples += given;
        given
    }

    /// Turns the rest replay on or off (off by default; [`super::rest`]). Turning it off
    /// first brings the board to the present (errors as [`ImageRun::settle`]) and forgets
    /// the rest so far.
    pub fn set_rest_replay(&mut self, on: bool) -> Result<(), ImageError> {
        if !on {
            self.settle()?;
            // A recording must not span samples run with the replay off.
            self.rest.forget();
        }
        self.rest.on = on;
        Ok(())
    }

    /// Samples given from recordings by the rest replay, and whole periods skipped.
    pub fn rest_replayed(&self) -> (u64, u64) {
        (self.rest.given, self.rest.skipped)
    }

    /// The longest period the rest replay has replayed (samples: a multiple of the tried
    /// period, [`super::rest::max_periods`]), and how many replays ended because a
    /// limiter's budget would have reached its full budget or run out (tests, reports).
    pub fn rest_periods(&self) -> (usize, u64) {
        (self.rest.longest, self.rest.room_ends)
    }

    /// Why the board refused the rest replay a rest point during the current rest
    /// ([`tactus_emulator::Board::rest_point`]'s error), if it did.
    pub fn rest_refused(&self) -> Option<&str> {
        match &self.rest.phase {
            Phase::Refused(e) => Some(e),
            _ => None,
        }
    }

    /// Brings a board the rest replay has parked to the present (the periods skipped, the
    /// rest run), so that [`ImageRun::board`] shows the state after the last sample;
    /// nothing when it is not parked.
    ///
    /// Errors: [`ImageError::Run`] when the board cannot skip the periods or runs
    /// differently from the recording (or an earlier such error met by
    /// [`ImageRun::board`]).
    pub fn settle(&mut self) -> Result<(), ImageError> {
        if let Some(e) = self.rest_error.take() {
            return Err(e);
        }
        self.leave_rest()
    }

    /// Ends a replay: the board skips the whole periods given and runs the samples of the
    /// last one, each checked against its recording.
    fn leave_rest(&mut self) -> Result<(), ImageError> {
        if !self.rest.replaying() {
            return Ok(());
        }
        let Phase::Replaying {
            period,
            outs,
            words,
            sensors,
            parked_at,
            given,
            ..
        } = std::mem::replace(&mut self.rest.phase, Phase::Watching)
        else {
            return Ok(());
        };
        let fail = |e: String| ImageError::Run(format!("the rest replay: {e}"));
        let len = outs.len() as u64;
        let (k, r) = (given / len, given % len);
        if k > 0 {
            self.board.skip_periods(&period, k).map_err(fail)?;
            self.rest.skipped += k;
        }
        self.stalls = self.board.system.contention_stalls;
        let now = self.samples;
        self.samples = parked_at + k * len;
        for out in outs.iter().take(r as usize) {
            self.run_sample(&sensors)?;
            if self.sample != *out {
                return Err(fail(format!(
                    "sample {} ran differently from its recording",
                    self.samples
                )));
            }
        }
        if self.samples != now {
            return Err(fail(format!(
                "{} samples run where {now} were given",
                self.samples
            )));
        }
        self.rest.keep_buffers(outs, words);
        Ok(())
    }

    /// The rest replay's bookkeeping after a sample the board ran (`same`: with the last
    /// sample's sensor words).
    fn after_sample(&mut self, same: bool) {
        if !same {
            if let Phase::Recording { outs, words, .. } =
                std::mem::replace(&mut self.rest.phase, Phase::Watching)
            {
                self.rest.keep_buffers(outs, words);
            }
            return;
        }
        let phase = std::mem::replace(&mut self.rest.phase, Phase::Watching);
        self.rest.phase = match phase {
            Phase::Watching if self.rest.same >= SETTLE => match self.rest_point() {
                Ok(start) => Phase::Recording {
                    starts: vec![(Box::new(start), 0)],
                    outs: std::mem::take(&mut self.rest.spare),
                    filled: 0,
                    words: std::mem::take(&mut self.rest.spare_words),
                },
                Err(e) => Phase::Refused(e),
            },
            Phase::Recording {
                starts,
                mut outs,
                mut filled,
                mut words,
            } => {
                // The recording's buffers are reused from try to try.
                match outs.get_mut(filled) {
                    Some(o) => copy_sample(&self.sample, o),
                    None => outs.push(self.sample.clone()),
                }
                filled += 1;
                let sram = &self.board.system.sram;
                words.extend(self.at.all_outs.iter().map(|&o| word(sram, o)));
                let last = starts.last().map_or(0, |s| s.1);
                if filled - last < self.rest.period {
                    Phase::Recording {
                        starts,
                        outs,
                        filled,
                        words,
                    }
                } else {
                    match self.rest_point() {
                        Err(e) => {
                            self.rest.keep_buffers(outs, words);
                            Phase::Refused(e)
                        }
                        Ok(end) => self.try_periods(end, starts, outs, filled, words),
                    }
                }
            }
            other => other,
        };
    }

    /// A try's end (`end`, after `filled` samples of `outs` recorded since the first of
    /// `starts`): the replay of the period from the latest start whose state `end` repeats
    /// (the shortest), or the recording on with `end` as a start, the oldest dropped beyond
    /// [`super::rest::max_periods`] periods.
    fn try_periods(
        &mut self,
        end: tactus_emulator::RestPoint,
        mut starts: Vec<(Box<tactus_emulator::RestPoint>, usize)>,
        mut outs: Vec<SampleOut>,
        mut filled: usize,
        mut words: Vec<u32>,
    ) -> Phase {
        let per = self.at.all_outs.len();
        for (start, at) in starts.iter().rev() {
            let Ok(period) = self.board.period(start, &end) else {
                continue;
            };
            let Some(room) = self.replay_room(&period, &outs[*at..filled]) else {
                continue;
            };
            // The period's samples first; the buffers before them kept for the next.
            outs[..filled].rotate_left(*at);
            let tail = outs.split_off(filled - at);
            self.rest.keep_spare(tail);
            self.rest.longest = self.rest.longest.max(outs.len());
            words.drain(..at * per);
            return Phase::Replaying {
                period: Box::new(period),
                outs,
                words,
                sensors: self.rest.last.clone(),
                parked_at: self.samples,
                given: 0,
                room,
            };
        }
        starts.push((Box::new(end), filled));
        if starts.len() > super::rest::max_periods(&self.limiter, self.rest.period) {
            starts.remove(0);
            let cut = starts[0].1;
            outs[..filled].rotate_left(cut);
            filled -= cut;
            words.drain(..cut * per);
            for s in &mut starts {
                s.1 -= cut;
            }
        }
        Phase::Recording {
            starts,
            outs,
            filled,
            words,
        }
    }

    /// How many samples the replay of `period` (whose samples gave `outs`) may give:
    /// while every limiter budget that grew over the period stays below its full budget
    /// (`super::rest`, "Budgets"); `None` when a budget changed otherwise, or grew on a
    /// path that can change with its value.
    fn replay_room(&self, period: &tactus_emulator::Period, outs: &[SampleOut]) -> Option<u64> {
        let cores = self.at.samples.len();
        let increases = &period.counter_increases()[cores..];
        let ends = period.counters_at_end().skip(cores);
        let c = &self.limiter;
        let mut room = u64::MAX;
        let samples = i64::try_from(outs.len()).ok()?;
        for (((key, drive, _), &grew), end) in self.at.budgets.iter().zip(increases).zip(ends) {
            let (grew, end) = (i64::from(grew as i32), i64::from(end as i32));
            let room_here = if grew == 0 {
                continue;
            } else if grew == samples {
                // One unit a sample: every sample earned one (+1 is the most a sample
                // earns), at or below rated or on the spent path; the spent path gives the
                // rated code and its test (`budget − recovery < 0`) depends on the value,
                // so a period that gave that code is not replayed. (A drive a sample does
                // not report counts as one that gave it.)
                let rated = outs.iter().any(|o| {
                    (o.drives.get(*key).and_then(|d| d.get(*drive)))
                        .is_none_or(|d| i32::from(d.dac).abs() == c.rated_code)
                });
                if rated {
                    return None;
                }
                // Earning while below the full budget: the samples that reach it.
                i64::from(c.budget_max) - end
            } else if grew == -samples * i64::from(c.recovery) {
                // `recovery` spent a sample (the most a sample spends): above rated with
                // budget, which holds while a sample starts with at least `recovery`.
                end / i64::from(c.recovery.max(1))
            } else {
                return None;
            };
            room = room.min(u64::try_from(room_here).ok()?);
        }
        Some(room)
    }

    /// The board's rest point now, the cores' sample counters and the limiters' budgets as
    /// its counters.
    fn rest_point(&mut self) -> Result<tactus_emulator::RestPoint, String> {
        self.board.rest_point(&self.at.counters)
    }

    /// One sample on the board (`step` without the rest replay).
    fn run_sample(&mut self, sensors: &[i32]) -> Result<(), ImageError> {
        if self.image.io.is_some() {
            self.set_codes(sensors);
        } else {
            let sram = &mut self.board.system.sram;
            for (&o, &w) in self.at.sensors.iter().zip(sensors) {
                sram[o..o + 4].copy_from_slice(&w.to_le_bytes());
            }
        }
        let want = self.samples + 1;
        let limit = self.tick_cycle(want);
        let stop = self.board.run_until(limit);
        if self.has_faults() && self.after_reset(stop)? {
            self.reset_sample(want);
            return Ok(());
        }
        self.check_stop(stop)?;
        let eighth = (self.image.cycles_per_sample() / 8).max(1);
        let mut extra = 0;
        // The firmware's sample count since its last boot (`inject.rs`).
        let (base, count_base) = (self.faults.tick_base, self.faults.count_base);
        // With faults on a board whose watchdog counts, a core that has not finished the
        // sample by its end is late (`inject.rs`, "Late samples"): the run does not wait
        // for it, so that the board's clock keeps the host's.
        let give_late = self.has_faults() && self.board.system.watchdog.is_enabled();
        loop {
            let sram = &self.board.system.sram;
            let done = self
                .at
                .samples
                .iter()
                .all(|&o| word(sram, o).wrapping_sub(count_base) as u64 >= want - base);
            if done {
                self.faults.late_since = None;
                break;
            }
            if give_late {
                return self.late_sample(want);
            }
            extra += 1;
            if extra > MAX_EXTRA_EIGHTHS {
                return Err(ImageError::Run(format!(
                    "sample {want} not completed {} periods after its tick",
                    MAX_EXTRA_EIGHTHS / 8
                )));
            }
            let stop = self.board.run_for(eighth);
            if self.has_faults() && self.after_reset(stop)? {
                self.reset_sample(want);
                return Ok(());
            }
            self.check_stop(stop)?;
        }
        self.samples = want;
        self.collect()
    }

    /// Sample `want`, in which the board reset (`inject.rs`, `after_reset`): the rest
    /// replay forgotten, the sample one of zero force, with the handlers that completed in
    /// it before the reset.
    fn reset_sample(&mut self, want: u64) {
        self.rest.forget();
        self.samples = want;
        self.zero_sample();
        self.take_handlers();
    }

    /// With converters: each key's sensor words as its ADC channels' codes
    /// (`AdcScale::code`), which the ADC samples from now on: the burst of this step's
    /// period, which the next sample's handler reads (module documentation of
    /// `super::io`: a position reaches the firmware one sample later than a host-written
    /// window word).
    fn set_codes(&mut self, sensors: &[i32]) {
        let Some(plan) = &self.image.io else {
            return;
        };
        // The same words as the codes were set from, without faults (whose codes the words
        // do not tell, `inject.rs`): the ADC reads those codes already. A key at rest gives
        // the same words sample after sample.
        let faults = self.has_faults();
        if !faults && self.codes_of == sensors {
            return;
        }
        let mut flat = 0;
        for k in &self.image.keys {
            let core = k.spec.core;
            for &ch in &k.adc_channels {
                let scale = &plan.cores[core].scales[ch as usize];
                if let Some(&w) = sensors.get(flat) {
                    // A sensor fault's code (`inject.rs`) in place of the word's.
                    let forced = self.faults.codes.get(flat).copied().flatten();
                    let code = forced.unwrap_or(scale.code(w) as u16);
                    self.board.set_adc_code(core, ch as usize, code);
                }
                flat += 1;
            }
        }
        self.codes_of.clear();
        if !faults {
            self.codes_of.extend_from_slice(sensors);
        }
    }

    /// Each core's handler runs completed since the last sample into the sample (their
    /// cycles with the exception entry, and their count), forgotten by the profiles. A run
    /// a reset cut never completes: the emulator drops it (`Board::calls`).
    fn take_handlers(&mut self) {
        let s = &mut self.sample;
        for c in 0..self.image.cores.len() {
            let calls = self.board.calls(self.profiles[c]);
            s.core_cycles[c] = calls
                .iter()
                .map(|x| x.cycles + EXCEPTION_ENTRY as u64)
                .sum();
            s.handler_runs[c] = calls.len() as u32;
            self.board.clear_calls(self.profiles[c]);
        }
    }

    fn collect(&mut self) -> Result<(), ImageError> {
        self.take_handlers();
        let s = &mut self.sample;
        s.events.clear();
        for c in 0..self.image.cores.len() {
            let sram = &self.board.system.sram;
            s.misses[c] = word(sram, self.at.misses[c]);
            if word(sram, self.at.canaries[c]) != STACK_CANARY {
                return Err(ImageError::Run(format!("core {c} overflowed its stack")));
            }
            let now = self.board.system.contention_stalls[c];
            s.stalls[c] = now - self.stalls[c];
            self.stalls[c] = now;
        }
        let sram = &self.board.system.sram;
        // Every key's DAC words, in flat order; with converters the codes of the DAC frames
        // the handler wrote (they go out at the next tick).
        let dac = &mut self.scratch;
        dac.clear();
        if self.image.io.is_some() {
            dac.extend(
                (self.at.dacs.iter()).map(|&o| super::io::word_code(word(sram, o)) as i32 as u32),
            );
        } else {
            dac.extend(self.at.dacs.iter().map(|&o| word(sram, o)));
        }
        let mut at = 0;
        for (i, k) in self.image.keys.iter().enumerate() {
            // Only the words a sample reports: each force word, each event's flag and, when
            // set, its arguments (`out` reads the others on demand).
            let outs = &self.at.outs[i];
            let out = |j: usize| outs.get(j).map_or(0, |&o| word(sram, o) as i32);
            for (j, (d, _)) in k.drives.iter().enumerate() {
                let o = &mut s.drives[i][j];
                o.force = out(d.out_index);
                // A stalled DAC holds its code (`inject.rs`).
                let held = self.faults.frozen.get(at + j).copied().flatten();
                o.dac = held.unwrap_or(dac[at + j] as i32) as i16;
                o.current_ua = self.limiter.current_ua(i32::from(o.dac));
            }
            at += k.drives.len();
            if let Some(first) = s.drives[i].first() {
                s.force[i] = first.force;
                s.current_ua[i] = first.current_ua;
                s.dac[i] = first.dac;
            }
            let p = &self.image.programs[k.spec.program];
            for site in &p.thumb.out.emits {
                if out(site.offset) == 1 {
                    let nargs = p.fixed.program.events[site.event.index()].args.len();
                    s.events.push(KeyEvent {
                        key: i,
                        event: site.event,
                        args: (site.offset + 1..site.offset + 1 + nargs)
                            .map(out)
                            .collect(),
                    });
                }
            }
        }
        Ok(())
    }

    /// The converters' frames since the last call (every core's ADC frames, then its DAC
    /// updates, in cycle order per part), removed from the emulated parts; empty without
    /// converters. Also the parts' data-sheet breaches so far, as text. A board the rest
    /// replay has parked is brought to the present first (the frames of the samples it
    /// gave, as [`ImageRun::settle`]; an error doing so is returned by the next
    /// [`ImageRun::step`]), and the rest so far is forgotten.
    pub fn take_io(&mut self) -> (Vec<IoRecord>, Vec<String>) {
        if self.image.io.is_none() {
            return (Vec::new(), Vec::new());
        }
        // The frames of the samples the rest replay gave are the board's once it is brought
        // to the present; a recording under way must not lose the frames taken here.
        if let Err(e) = self.leave_rest() {
            self.rest_error.get_or_insert(e);
        }
        self.rest.forget();
        let Some(io) = self.board.io_mut() else {
            return (Vec::new(), Vec::new());
        };
        let mut out = Vec::new();
        let mut breaches = Vec::new();
        for (core, adc) in io.adcs.iter_mut().enumerate() {
            out.extend(adc.take_frames().into_iter().map(|f| IoRecord {
                core,
                dac: false,
                cycle: f.cs_fall,
                channel: f.channel,
                code: f.code,
                command: f.command,
            }));
            breaches.extend(adc.violations().iter().map(|v| v.what.clone()));
        }
        for (core, dac) in io.dacs.iter_mut().enumerate() {
            out.extend(dac.take_updates().into_iter().map(|u| IoRecord {
                core,
                dac: true,
                cycle: u.cycle,
                channel: u.channel,
                code: u.code,
                command: 0,
            }));
            breaches.extend(dac.violations().iter().map(|v| v.what.clone()));
        }
        (out, breaches)
    }

    /// Key `key`'s out words after the last sample (the update's `out[]`, `OutLayout`),
    /// read from the emulated SRAM, or from the rest replay's recording of the sample it
    /// gave (empty for an unknown key).
    pub fn out(&self, key: usize) -> Vec<i32> {
        let Some(w) = self.at.outs.get(key) else {
            return Vec::new();
        };
        if let Phase::Replaying {
            outs, words, given, ..
        } = &self.rest.phase
        {
            if *given > 0 {
                let per = self.at.all_outs.len();
                let before: usize = self.at.outs[..key].iter().map(Vec::len).sum();
                let i = ((*given - 1) % outs.len() as u64) as usize;
                let at = i * per + before;
                return (words.get(at..at + w.len()).unwrap_or(&[]).iter())
                    .map(|&x| x as i32)
                    .collect();
            }
        }
        let sram = &self.board.system.sram;
        w.iter().map(|&o| word(sram, o) as i32).collect()
    }

    /// Samples completed.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// The image.
    pub fn image(&self) -> &FirmwareImage {
        &self.image
    }

    /// The emulated board (to inspect memory, cores and counters), brought to the present
    /// first when the rest replay had parked it ([`ImageRun::settle`]; an error doing so is
    /// returned by the next [`ImageRun::step`] or [`ImageRun::settle`]).
    pub fn board(&mut self) -> &mut Board {
        if let Err(e) = self.leave_rest() {
            self.rest_error.get_or_insert(e);
        }
        &mut self.board
    }
}
