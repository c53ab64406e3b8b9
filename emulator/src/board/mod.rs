//! The emulated RP2040 as the host uses it ([`Board`]): a thin façade over the machine that
//! defines the chip ([`Machine`], which a board dereferences to: its cores, its system,
//! the host's memory access) and the accelerator that runs it faster
//! ([`crate::accel`]), with what the host adds: the loaded image's symbols, profiles of
//! functions and handlers ([`crate::profile`]), and a debugger in charge of its runs
//! ([`crate::debug`]).
//!
//! **Invariant.** Every way a board runs — [`Board::run_until`] on any [`crate::config::Engine`], with
//! windows, memos and the I/O's replays or without, [`Board::step`] one instruction at a
//! time, a debugger's run — gives the lock-step machine's results: the same cycles,
//! registers, memory and I/O. Speed is the only difference (`Config::engine`,
//! `Config::own_banks`, [`Board::memoize`], [`Board::set_io_memo`]).
//!
//! `host.rs`: loading an ELF image and calling one function.

mod host;

pub use host::{CallError, CallResult, CALL_STUB};

use crate::accel::{Accel, Drive, IoWindows, MemoStats, Period, RestPoint};
use crate::config::Config;
use crate::elf::Image;
use crate::machine::{EmuError, Machine, StopReason};
use crate::profile::{Call, Profiler};

/// A debugger in charge of a board's runs ([`Board::attach_debugger`]).
pub trait Debugger: Send {
    /// Runs `board` to cycle `limit` as [`Board::run_until`] would, stopping and serving
    /// the debugger's client as it wants on the way. The board's own `run_until` inside
    /// this call runs plainly (the hook is detached meanwhile).
    fn run_until(&mut self, board: &mut Board, limit: u64) -> StopReason;

    /// Whether the debugger has left (its client detached): the board then drops it.
    fn detached(&self) -> bool;

    /// The host's run is over (the program "exits"): tell the client, and end.
    fn finish(&mut self, board: &mut Board);
}

/// The emulated RP2040 (module documentation).
pub struct Board {
    /// Configuration.
    pub config: Config,
    /// The chip.
    machine: Machine,
    /// What runs it faster.
    accel: Accel,
    /// The loaded image's symbols etc. (empty until [`Board::load_elf`]).
    pub image: Image,
    /// The profiled functions and handlers.
    profiler: Profiler,
    /// The debugger in charge of [`Board::run_until`], if any ([`crate::debug`]).
    debugger: Option<Box<dyn Debugger>>,
    /// What a debugger keeps on the board between its client's packets.
    pub(crate) debug_state: crate::watch::DebugState,
}

impl std::ops::Deref for Board {
    type Target = Machine;

    fn deref(&self) -> &Machine {
        &self.machine
    }
}

impl std::ops::DerefMut for Board {
    fn deref_mut(&mut self) -> &mut Machine {
        &mut self.machine
    }
}

impl Board {
    /// A board with zeroed memory and both cores parked (core 1 in the launch protocol).
    pub fn new(config: Config) -> Self {
        Board {
            machine: Machine::new(config.clock_hz),
            config,
            accel: Accel::default(),
            image: Image::default(),
            profiler: Profiler::default(),
            debugger: None,
            debug_state: Default::default(),
        }
    }

    /// The accelerator at work on the machine.
    fn drive(&mut self) -> Drive<'_> {
        Drive {
            a: &mut self.accel,
            m: &mut self.machine,
            prof: &mut self.profiler,
            cfg: &self.config,
        }
    }

    /// Attaches the converters' I/O of `config` (`crate::io`: both PIO blocks, the DMA,
    /// IO_BANK0's function select, BUS_PRIORITY and the parts at their pins), out of reset,
    /// its clock at the board's cycle; replaces any attached before.
    pub fn attach_io(&mut self, config: &crate::io::IoConfig) {
        let clock_hz = self.config.clock_hz;
        self.machine.attach_io(config, clock_hz);
    }

    /// The host's memory access, as [`Machine`]'s (so that an argument may borrow the board
    /// too, as in `board.read_u32(board.symbol("x")?)`): [`Machine::read_bytes`].
    pub fn read_bytes(&mut self, addr: u32, out: &mut [u8]) -> Result<(), EmuError> {
        self.machine.read_bytes(addr, out)
    }

    /// [`Machine::write_bytes`].
    pub fn write_bytes(&mut self, addr: u32, data: &[u8]) -> Result<(), EmuError> {
        self.machine.write_bytes(addr, data)
    }

    /// [`Machine::write_data`].
    pub fn write_data(&mut self, addr: u32, data: &[u8]) -> Result<(), EmuError> {
        self.machine.write_data(addr, data)
    }

    /// [`Machine::read_words`].
    pub fn read_words(&mut self, addr: u32, out: &mut [u32]) -> Result<(), EmuError> {
        self.machine.read_words(addr, out)
    }

    /// [`Machine::write_words`].
    pub fn write_words(&mut self, addr: u32, words: &[u32]) -> Result<(), EmuError> {
        self.machine.write_words(addr, words)
    }

    /// [`Machine::read_u32`].
    pub fn read_u32(&mut self, addr: u32) -> Result<u32, EmuError> {
        self.machine.read_u32(addr)
    }

    /// [`Machine::write_u32`].
    pub fn write_u32(&mut self, addr: u32, value: u32) -> Result<(), EmuError> {
        self.machine.write_u32(addr, value)
    }

    /// Runs for `cycles` more cycles (from [`Machine::cycle`]) or until a stop.
    pub fn run_for(&mut self, cycles: u64) -> StopReason {
        let limit = self.machine.cycle().saturating_add(cycles);
        self.run_until(limit)
    }

    /// Runs until both running cores reach cycle `limit`, or a stop. Instructions are not
    /// split: each core stops at its first instruction boundary at or after `limit` (a
    /// multi-cycle instruction that starts before the limit completes). The I/O, if any
    /// ([`Board::attach_io`]), has run up to the board's cycle when it returns.
    ///
    /// With a debugger attached ([`Board::attach_debugger`]) the debugger runs the board
    /// there instead, stopping on the way as its client asks, with the same results.
    pub fn run_until(&mut self, limit: u64) -> StopReason {
        let stop = match self.debugger.take() {
            Some(mut d) => {
                let stop = d.run_until(self, limit);
                if !d.detached() {
                    self.debugger = Some(d);
                }
                stop
            }
            None => self.drive().run_until(limit),
        };
        if self.machine.system.io.is_some() {
            let now = self.machine.cycle();
            self.machine.system.io_advance(now);
        }
        stop
    }

    /// Executes one instruction (or exception entry, or a sleep interval) on the core that
    /// is behind, if it is before `limit`: the lock-step machine's step
    /// ([`Machine::step_core`]), the profiles told of it and its event applied. `None` when
    /// both running cores are at `limit`; `Some(Ok(core))` names the core that acted (its
    /// [`crate::core::Core::last`] is the instruction).
    pub fn step(&mut self, limit: u64) -> Option<Result<usize, StopReason>> {
        self.drive().step(limit)
    }

    /// Attaches a debugger: from now on [`Board::run_until`] (and so every host loop built
    /// on it) runs under it, until it detaches.
    pub fn attach_debugger(&mut self, debugger: Box<dyn Debugger>) {
        self.debugger = Some(debugger);
    }

    /// Removes the debugger, if any, and returns it.
    pub fn detach_debugger(&mut self) -> Option<Box<dyn Debugger>> {
        self.debugger.take()
    }

    /// Tells an attached debugger that the host's run is over ([`Debugger::finish`]) and
    /// removes it.
    pub fn finish_debugging(&mut self) {
        if let Some(mut d) = self.debugger.take() {
            d.finish(self);
        }
    }

    /// Starts measuring every call of the function at `addr` (Thumb bit ignored) on both
    /// cores; see [`Board::calls`]. Returns a handle.
    pub fn profile_addr(&mut self, addr: u32) -> usize {
        self.profiler.add(addr, false)
    }

    /// Starts measuring the exception handler at `addr` (Thumb bit ignored) on both cores:
    /// like [`Board::profile_addr`], but only activations entered by exception entry are
    /// measured (from the handler's first instruction to the first instruction after the
    /// exception return that deactivates it, as `profile_addr` measures them); a branch or
    /// call to `addr` is not. Both ends of such an activation are exception entry and
    /// return, which the general path executes, so unlike `profile_addr` this costs the
    /// fast path nothing: use it for interrupt handlers. Returns a handle for
    /// [`Board::calls`].
    pub fn profile_handler(&mut self, addr: u32) -> usize {
        self.profiler.add(addr, true)
    }

    /// [`Machine::io_write`].
    pub fn io_write(&mut self, addr: u32, value: u32) -> bool {
        self.machine.io_write(addr, value)
    }

    /// A brown-out ([`Machine::brown_out`]): the profiles' open calls, which never
    /// return, dropped (as at a watchdog reset).
    pub fn brown_out(&mut self) {
        self.machine.brown_out();
        self.profiler.cores_reset();
    }

    /// Starts measuring the function named `name`.
    pub fn profile(&mut self, name: &str) -> Result<usize, EmuError> {
        let addr = self.symbol(name)?;
        Ok(self.profile_addr(addr))
    }

    /// The completed calls of profiled function `handle`.
    pub fn calls(&self, handle: usize) -> &[Call] {
        self.profiler.calls(handle)
    }

    /// How many times the entry of profiled address `handle` has been reached (0 for an
    /// unknown handle). Unlike [`Board::calls`], which completes a call when control returns
    /// to the link register it was entered with, this counts a block that is not a function
    /// (a code generator's `BL` long branches change LR inside one) at the moment it runs.
    pub fn entries(&self, handle: usize) -> u64 {
        self.profiler.entry_count(handle)
    }

    /// Forgets the completed calls of profiled function `handle` (read them with
    /// [`Board::calls`] first); measuring continues. Long runs call this now and then so the
    /// record does not grow without bound. An unknown handle is ignored.
    pub fn clear_calls(&mut self, handle: usize) {
        self.profiler.clear_calls(handle);
    }

    /// Basic blocks the block engine ([`crate::config::Engine::Block`]) has decoded so far (0 with
    /// [`crate::config::Engine::Interp`]): a block is decoded again after a store into a page holding
    /// decoded code or a host write drops them all.
    pub fn blocks_decoded(&self) -> u64 {
        self.accel.blocks_decoded()
    }

    /// Memoizes calls to the functions at `calls` and runs of the spans `spans` (from each
    /// `start` to its `end`; addresses, the Thumb bit ignored; at most 64 in all) on the
    /// block engine while the cores run in windows ([`Config::own_banks`]): a call (from
    /// the entry to the return address LR held there, SP back as it was) or a span run
    /// (from its start to its end, SP back as it was) whose inputs — the registers and
    /// flags it reads, the SRAM bytes it loads, the code — are those of one recorded before
    /// is replaced by that one's effect (registers, flags, stores, cycles, instructions,
    /// bank claims; module `memo`). Results never depend on it, only speed: a call that
    /// touches anything but registers and SRAM, or whose inputs differ, runs as before.
    /// Empty lists stop it. Forgets every memo.
    pub fn memoize(&mut self, calls: &[u32], spans: &[(u32, u32)]) {
        self.accel.memoize(calls, spans);
    }

    /// What the memoized calls did so far ([`Board::memoize`]).
    pub fn memo_stats(&self) -> MemoStats {
        self.accel.memo_stats()
    }

    /// Code regions the block engine has compiled to native code so far.
    pub fn regions_compiled(&self) -> u64 {
        self.accel.regions_compiled()
    }

    /// Times native code compiled *timed* (checking the deadline before each instruction)
    /// ran a core in a window up to its run's limit, where the region's bound did not fit
    /// before it (a core run to the other's cycle at a meeting, `accel/window.rs`).
    pub fn timed_stops(&self) -> u64 {
        self.accel.timed_stops()
    }

    /// The block engine compiles a code region to native code once its entry has been
    /// reached `times` times (default 64; 0 compiles every region at once — the tests use
    /// it to run everything natively). Results never depend on it, only speed.
    pub fn set_compile_threshold(&mut self, times: u32) {
        self.accel.set_compile_threshold(times);
    }

    /// Windows so far (module documentation): (kept, undone because a core could not
    /// reach the window's end confined).
    pub fn run_ahead_windows(&self) -> (u64, u64) {
        self.accel.run_ahead_windows()
    }

    /// The windows of a board with an I/O so far (module documentation).
    pub fn io_windows(&self) -> IoWindows {
        self.accel.io_windows()
    }

    /// Turns the period memo of the I/O's replays (module documentation) on or off; on by
    /// default. Results never depend on it: what it gives is the replay's.
    pub fn set_io_memo(&mut self, on: bool) {
        self.accel.set_io_memo(on);
    }

    /// For tests: whether a hit of the period memo may leave its end behind instead of
    /// making it (module documentation, "The lazy end"); on by default. Results never
    /// depend on it.
    #[doc(hidden)]
    pub fn set_io_lazy(&mut self, on: bool) {
        self.machine.system.io_unlazy();
        self.accel.set_io_lazy(on);
    }

    /// For tests: whether a hit of the period memo may take a plan (module documentation,
    /// "Plans"); on by default. Results never depend on it.
    #[doc(hidden)]
    pub fn set_io_plans(&mut self, on: bool) {
        self.accel.set_io_plans(on);
    }

    /// For tests: keeps a digest of every window's logs ([`Board::io_log_digest`]), and
    /// with `native` false has the cores' accesses to the DMA's banks and the I/O's
    /// registers take the general path instead of native code (`jit::abi`'s `io_sram`,
    /// `io_reg`), so that a test can compare the logs the two paths write. Results never
    /// depend on it.
    #[doc(hidden)]
    pub fn check_io_logs(&mut self, native: bool) {
        self.accel.check_io_logs(native);
    }

    /// The digest [`Board::check_io_logs`] keeps: FNV-1a over every access logged in a
    /// window, each window's logs in order; `None` unless asked for.
    #[doc(hidden)]
    pub fn io_log_digest(&self) -> Option<u64> {
        self.accel.io_log_digest()
    }

    /// The board's state now as a [`RestPoint`], the SRAM words at `counters` (offsets of
    /// aligned words from [`tactus_rp2040::memory::SRAM_BASE`]) taken as counters (module
    /// documentation).
    ///
    /// Errors (as text): a debugger attached, core 1's launch under way, a timer alarm
    /// armed, a profiled call open, a counter offset outside SRAM or unaligned.
    pub fn rest_point(&mut self, counters: &[usize]) -> Result<RestPoint, String> {
        self.machine.system.io_unlazy();
        if self.debugger.is_some() {
            return Err("a debugger is attached".into());
        }
        self.drive().rest_point(counters)
    }

    /// The period from `start` to `end`, two rest points of this board, `end` its point
    /// now ([`Board::rest_point`]): with converters, their records since `start` are the
    /// period's.
    ///
    /// Errors (as text): the states differ, no time passed, a core read the timer's count
    /// between them, a SysTick counts the 1 µs pulses and the period is not a whole
    /// number of microseconds at the board's clock, a converter's timing was breached or
    /// its records taken ([`crate::io::Io`]'s records drained) between them.
    pub fn period(&mut self, start: &RestPoint, end: &RestPoint) -> Result<Period, String> {
        self.drive().period(start, end)
    }

    /// Moves the board forward by `periods` whole periods of `period` without running them:
    /// what running them would give when the host writes over them what it wrote over the
    /// period (module documentation). The board's state now must equal the state at the
    /// period's end ([`RestPoint::same_state`], checked here: the board is then on the
    /// repeating run).
    ///
    /// Errors (as text): the state differs (or [`Board::rest_point`]'s), or the cycles
    /// overflow. Nothing is changed on an error.
    pub fn skip_periods(&mut self, period: &Period, periods: u64) -> Result<(), String> {
        self.drive().skip_periods(period, periods)
    }
}
