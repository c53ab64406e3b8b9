//! The RP2040 board: two cores and the system, run in lock-step, plus the host API (load,
//! run for N cycles, read/write memory, count cycles per function).
//!
//! **Lock-step.** Each core has its own cycle counter; the board always executes the next
//! instruction of the core whose counter is lower (core 0 on a tie), so every shared-state
//! access (SRAM banks, SIO FIFOs, spinlocks, timer) happens in global cycle order and a run
//! is a pure function of the initial state: deterministic, whatever the host. A sleeping core
//! (WFI/WFE) skips ahead to the next cycle at which something could wake it. Core 1 starts
//! parked in the boot ROM's launch protocol (RP2040 datasheet 2.8.2): it echoes the FIFO
//! sequence `0, 0, 1, vector table, stack pointer, entry` and then starts.
//!
//!
//! **Modules, by job.** `host`: the host API (loading an image, memory reads and writes
//! that cost the cores nothing, calling one function); `run`: scheduling the two cores
//! (the lock-step loop, the fast paths, the engines); `window`: running ahead, with its
//! undo journal; `launch`: core 1's boot ROM launch protocol; `profile`: cycles per
//! function and per interrupt handler. The cores reach memory only through
//! [`crate::bus::Bus`].

mod host;
mod io_window;
mod launch;
mod profile;
mod rest;
mod run;
mod window;

pub use host::{CallError, CallResult, EmuError, CALL_STUB};
pub use io_window::IoWindows;
pub(crate) use io_window::{IoAccess, IoKind};
pub use profile::Call;
pub use rest::{Period, RestPoint};

use crate::block::Blocks;
use crate::core::{Core, Fault, RunState};
use crate::elf::Image;
use crate::system::System;
use launch::Launch;
use profile::{Profile, NO_WATCH, WATCH_SLOTS};
use run::{Cached, CACHE_SLOTS};

/// Board configuration.
#[derive(Clone, Debug)]
pub struct Config {
    /// System clock in Hz (RP2040: 133 MHz); drives the microsecond timer.
    pub clock_hz: u64,
    /// Stop [`Board::run_until`] at every SVC with [`StopReason::Svc`] (for host calls such as a
    /// test harness's `write`/`exit`) instead of taking the SVCall exception.
    pub svc_halts: bool,
    /// Stop [`Board::run_until`] with [`StopReason::Fault`] after a core takes a HardFault, instead
    /// of running the firmware's HardFault handler.
    pub stop_on_fault: bool,
    /// Which engine runs the fast path of [`Board::run_until`] / [`Board::run_for`]
    /// (default [`Engine::Block`], the faster: see BENCHMARKS.md, "the block compiler").
    /// Both give the same cycles, registers and memory; [`Board::step`] is always the
    /// general path.
    pub engine: Engine,
    /// Each core's own SRAM banks (bit per bank: 0-3 SRAM0-3, 4 SRAM4, 5 SRAM5). When
    /// they are disjoint and both set, [`Engine::Block`] runs the two cores as independent
    /// machines over whole windows of cycles, each confined to its own banks and private
    /// registers, undoing a window in which either touches anything else (`board/window.rs`;
    /// the firmware images lay each core out in its own banks,
    /// `tactus_firmware::FirmwareImage::own_banks`). Default `[0, 0]`: the two cores in lock-step. Results never
    /// depend on it, only speed.
    pub own_banks: [u8; 2],
}

/// The engine behind [`Board::run_until`]'s fast path.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Engine {
    /// The interpreter: one instruction at a time from the decode cache (module `fast`).
    Interp,
    /// The block engine (module [`crate::block`]): code regions compiled to native code
    /// with cranelift (module `jit`) once warm, pre-decoded basic blocks otherwise, the
    /// same cycles and results as [`Engine::Interp`]. It runs one core at a time; with both
    /// cores running and [`Config::own_banks`] set, the core behind runs ahead in its own
    /// banks ("Running ahead" in [`crate::board`]) and the interpreter's lock-step turns run where
    /// that is not possible, as while functions are profiled with [`Board::profile_addr`].
    #[default]
    Block,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            clock_hz: 133_000_000,
            svc_halts: false,
            stop_on_fault: true,
            engine: Engine::default(),
            own_banks: [0, 0],
        }
    }
}

/// Why [`Board::run_until`] returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// Both cores reached the cycle limit.
    CycleLimit,
    /// A core executed SVC with [`Config::svc_halts`] set (its PC is past the SVC).
    Svc {
        /// The core.
        core: usize,
        /// The SVC immediate.
        imm: u8,
    },
    /// A core faulted (with [`Config::stop_on_fault`]); it has entered its HardFault handler.
    Fault {
        /// The core.
        core: usize,
        /// The fault.
        fault: Fault,
    },
    /// A core locked up (fault while handling HardFault, or failed stacking).
    Lockup {
        /// The core.
        core: usize,
        /// The fault.
        fault: Fault,
    },
    /// No core can run (all parked or locked up).
    Idle,
    /// The emulator refused what a core did: a clock or voltage write that would run clk_sys
    /// faster than the core voltage allows (`crate::clocks`). The store faulted.
    Refused {
        /// The core.
        core: usize,
        /// Why.
        why: crate::clocks::Refusal,
    },
}

/// The emulated RP2040.
pub struct Board {
    /// Configuration.
    pub config: Config,
    /// The two cores.
    pub cores: [Core; 2],
    /// Memories and peripherals.
    pub system: System,
    /// The loaded image's symbols etc. (empty until [`Board::load_elf`]).
    pub image: Image,
    profiles: Vec<Profile>,
    /// Each core's profiling at the start of the current window (`window.rs`), kept to
    /// reuse its vectors.
    marks: [profile::ProfileMark; 2],
    launch: Option<Launch>,
    cache: Box<[Cached; CACHE_SLOTS]>,
    blocks: Blocks,
    /// Windows kept and undone ([`Board::run_ahead_windows`]).
    windows: [u64; 2],
    /// While a window runs on a board with an I/O: the banks its DMA may reach, whose
    /// accesses the cores log (`board/io_window.rs`).
    io_window: Option<u8>,
    /// Per core, the accesses of the current window the I/O's replay needs.
    io_logs: [Vec<io_window::IoAccess>; 2],
    /// The replay's undo journal (SRAM words it overwrote).
    io_journal: Vec<u64>,
    /// What became of the windows on a board with an I/O ([`Board::io_windows`]).
    io_windows: IoWindows,
    /// The period memo of the I/O's replays (`board/io_window.rs`).
    io_memo: io_window::IoMemo,
    /// Whether native code does and logs a window's accesses to the DMA's banks and the
    /// I/O's registers ([`Board::check_io_logs`]).
    io_native: bool,
    /// A digest of the windows' logs so far, when kept ([`Board::check_io_logs`]).
    io_digest: Option<u64>,
    /// No window before either core reaches this cycle (after one that ran nothing).
    window_at: u64,
    /// Each core's active exceptions at its last [`Board::profile_step`] that ran its loop
    /// (`u64::MAX`, which no core has, before any).
    profiled_active: [u64; 2],
    /// No profile watches an address (none, or handler profiles only): the fast path's
    /// watch sets are empty ([`Board::watch_set`]).
    watch_free: bool,
    /// Every profiled entry, sorted, and per core the distinct return addresses of each
    /// profile's innermost open call: the only PCs at which [`Board::profile_step`] can open
    /// or close a call (besides a change of active exceptions). With them, per core, the
    /// fast path's watch set ([`Board::watch_set`]), `None` when it has too many. Rebuilt
    /// when a profile is added or an open call changes.
    profile_entries: Vec<u32>,
    profile_returns: [Vec<u32>; 2],
    /// Per core, a 4096-bit filter of those PCs (bit `(pc >> 1) mod 4096`): a clear bit
    /// rules a PC out in one load.
    profile_filter: [[u64; 64]; 2],
    profile_watch: [Option<[u32; WATCH_SLOTS]>; 2],
    /// Interrupt lines as of `lines_epoch` (a [`System::irq_epoch`] value).
    lines: u32,
    lines_epoch: u64,
    /// The debugger in charge of [`Board::run_until`] and what it watches, if any
    /// ([`crate::debug`]).
    pub(crate) debug: crate::debug::Attachment,
}

impl Board {
    /// A board with zeroed memory and both cores parked (core 1 in the launch protocol).
    pub fn new(config: Config) -> Self {
        let system = System::new(config.clock_hz);
        let mut cores = [Core::new(0), Core::new(1)];
        for c in &mut cores {
            // SysTick's reference: the 1 µs pulse of the watchdog's tick generator.
            c.nvic.clock_hz = config.clock_hz;
        }
        let mut board = Board {
            config,
            cores,
            system,
            image: Image::default(),
            profiles: Vec::new(),
            marks: Default::default(),
            launch: None,
            lines: 0,
            profiled_active: [u64::MAX; 2],
            watch_free: true,
            profile_entries: Vec::new(),
            profile_returns: [Vec::new(), Vec::new()],
            profile_filter: [[0; 64]; 2],
            profile_watch: [Some([NO_WATCH; WATCH_SLOTS]); 2],
            lines_epoch: u64::MAX,
            blocks: Blocks::new(),
            windows: [0; 2],
            io_window: None,
            io_logs: Default::default(),
            io_journal: Vec::new(),
            io_windows: IoWindows::default(),
            io_memo: Default::default(),
            io_native: true,
            io_digest: None,
            window_at: 0,
            debug: Default::default(),
            cache: run::empty_cache(),
        };
        // Core 1 reaches `wait_for_vector` a few cycles after reset, long before core 0
        // can send anything: its first handshake is part of the power-on state.
        board.launch = Some(Launch::default());
        board.launch_handshake();
        board
    }

    /// Attaches the converters' I/O of `config` (`crate::io`: both PIO blocks, the DMA,
    /// IO_BANK0's function select, BUS_PRIORITY and the parts at their pins), out of reset,
    /// its clock at the board's cycle; replaces any attached before.
    pub fn attach_io(&mut self, config: &crate::io::IoConfig) {
        let io = crate::io::Io::new(config, self.config.clock_hz as f64, self.cycle());
        self.system.io = Some(Box::new(io));
        self.system.io_lazy = None;
        self.system.io_banks = 0;
        self.system.allowed_banks = self.system.fast_banks();
    }

    /// The attached I/O (`None` without [`Board::attach_io`]), run up to the board's cycle.
    pub fn io(&mut self) -> Option<&crate::io::Io> {
        self.system.io_unlazy();
        self.system.io.as_deref()
    }

    /// Sets the code channel `channel` (0–7) of ADC `adc` reads from now on
    /// ([`crate::converters::Ads8688::set_code`]); nothing without that ADC. Only data
    /// changes: unlike a change through [`Board::io_mut`], the I/O's period memo still knows
    /// where it is (`board/io_window.rs`), and a machine a hit left behind takes the code
    /// among its data words ("The lazy end").
    pub fn set_adc_code(&mut self, adc: usize, channel: usize, code: u16) {
        // The machine a period memo's hit left behind keeps its data words apart.
        if let (Some(l), Some(io)) = (
            self.system.io_lazy.as_deref_mut(),
            self.system.io.as_deref(),
        ) {
            if let Some(w) = io
                .adc_code_slot(adc, channel)
                .and_then(|at| l.data.get_mut(at))
            {
                *w = u32::from(code);
            }
            return;
        }
        if let Some(io) = self.system.io.as_deref_mut() {
            if let Some(a) = io.adcs.get_mut(adc) {
                a.set_code(channel, code);
                io.data_changed();
            }
        }
    }

    /// The attached I/O, to set what the ADCs read (`Ads8688::set_code`).
    pub fn io_mut(&mut self) -> Option<&mut crate::io::Io> {
        self.system.io_unlazy();
        let io = self.system.io.as_deref_mut()?;
        io.forget_idle();
        Some(io)
    }

    /// Total cycles elapsed: the lower of the running cores' counters.
    pub fn cycle(&self) -> u64 {
        match self.next_core() {
            Some(k) => self.cores[k].cycle,
            None => self.cores[0].cycle.max(self.cores[1].cycle),
        }
    }

    /// The core whose turn it is: the active core with the lower cycle, core 0 on ties.
    fn next_core(&self) -> Option<usize> {
        match (active(&self.cores[0]), active(&self.cores[1])) {
            (true, true) => Some((self.cores[1].cycle < self.cores[0].cycle) as usize),
            (true, false) => Some(0),
            (false, true) => Some(1),
            (false, false) => None,
        }
    }
}

pub(super) fn active(c: &Core) -> bool {
    matches!(c.state, RunState::Running | RunState::Sleeping { .. })
}
