//! What runs the machine ([`crate::machine::Machine`]) faster, beside it: every result it
//! gives is the lock-step machine's ([`Machine::step_core`]), only sooner.
//!
//! **Invariant.** The accelerator drives the machine through its narrow interface (the
//! instructions it hands it, [`crate::machine::Decoder`]; core snapshots and undo journals;
//! the I/O's hooks and data slots) and keeps nothing the machine's state does not decide
//! but what it checks before use (the decode cache and the blocks by the code epoch, a memo
//! by its inputs, a period memo entry by the I/O's control state, a rest point by the
//! whole state). Nothing here is state of the chip: a board with a fresh accelerator runs
//! exactly as one with a warm one. It never names the façade ([`crate::board`]).
//!
//! **Modules, by job.** `run`: scheduling the two cores (the lock-step loop with the fast
//! paths: the interpreter's loop, a sleeper's turns in closed form); `decode`: the decode
//! cache;
//! `fast`: pre-decoded instructions; `block` and `jit`: the block engine (pre-decoded
//! basic blocks, code regions compiled to native code with cranelift); `memo`: memoized
//! calls; `window`: the two cores as independent machines over a window, with undo
//! journals; `io_window`: on a board with converters, the I/O's replay of a window (the
//! cores' access log, the replay in lock-step order, the period memo, plans); `rest`: rest
//! points and the jump over whole periods of a repeating board.
//!
//! [`Accel`] is the state; [`Drive`] is the accelerator at work on one machine, with the
//! profiles it must stop for ([`Profiler`]) and the board's configuration.

pub(crate) mod block;
mod decode;
pub(crate) mod fast;
pub(crate) mod io_window;
pub(crate) mod jit;
pub(crate) mod memo;
mod rest;
mod run;
mod window;

pub use io_window::IoWindows;
pub use memo::MemoStats;
pub use rest::{Period, RestPoint};

use crate::config::{Config, Engine};
use crate::core::{Core, RunState};
use crate::machine::{active, Decoder, Fetch, Machine, Step, StopReason};
use crate::profile::Profiler;
use crate::system::System;
use block::Blocks;
use decode::{Cached, CACHE_SLOTS};
use io_window::{IoAccess, IoMemo};

/// The accelerator's state (module documentation): caches, engines, memos and counts.
pub(crate) struct Accel {
    /// The decode cache ([`run`]).
    cache: Box<[Cached; CACHE_SLOTS]>,
    /// The block engine, its compiled regions and memos.
    blocks: Blocks,
    /// Interrupt lines as of `lines_epoch` (a [`System::irq_epoch`] value): the fast
    /// path's copy.
    lines: u32,
    lines_epoch: u64,
    /// Windows kept and undone ([`Drive::run_ahead_windows`]).
    windows: [u64; 2],
    /// No window before either core reaches this cycle (after one that ran nothing).
    window_at: u64,
    /// While a window runs on a board with an I/O: the banks its DMA may reach, whose
    /// accesses the cores log (`io_window`).
    io_window: Option<u8>,
    /// Per core, the accesses of the current window the I/O's replay needs.
    io_logs: [Vec<IoAccess>; 2],
    /// The replay's undo journal (SRAM words it overwrote).
    io_journal: Vec<u64>,
    /// What became of the windows on a board with an I/O.
    io_windows: IoWindows,
    /// The period memo of the I/O's replays (`io_window/memo.rs`).
    io_memo: IoMemo,
    /// Whether native code does and logs a window's accesses to the DMA's banks and the
    /// I/O's registers ([`Drive::check_io_logs`]).
    io_native: bool,
    /// A digest of the windows' logs so far, when kept ([`Drive::check_io_logs`]).
    io_digest: Option<u64>,
    /// The current window's writes to the watchdog (`window`).
    feeds: window::Feeds,
    /// Where core 0 stopped at a load it could not make confined (`window`, "Meetings").
    cut: Option<u64>,
}

impl Default for Accel {
    fn default() -> Self {
        Accel {
            cache: decode::empty_cache(),
            blocks: Blocks::new(),
            lines: 0,
            lines_epoch: u64::MAX,
            windows: [0; 2],
            window_at: 0,
            io_window: None,
            io_logs: Default::default(),
            io_journal: Vec::new(),
            io_windows: IoWindows::default(),
            io_memo: Default::default(),
            io_native: true,
            io_digest: None,
            feeds: window::Feeds::default(),
            cut: None,
        }
    }
}

impl Accel {
    /// Basic blocks the block engine has decoded so far.
    pub(crate) fn blocks_decoded(&self) -> u64 {
        self.blocks.decoded
    }

    /// Memoizes calls to the functions at `calls` and runs of the spans `spans`
    /// ([`crate::Board::memoize`]); forgets every memo.
    pub(crate) fn memoize(&mut self, calls: &[u32], spans: &[(u32, u32)]) {
        self.blocks.memo.watch(calls, spans);
        self.blocks.set_stops(self.blocks.memo.span_entries());
    }

    /// What the memoized calls did so far.
    pub(crate) fn memo_stats(&self) -> MemoStats {
        self.blocks.memo.stats
    }

    /// Code regions the block engine has compiled to native code so far ([`jit`]).
    pub(crate) fn regions_compiled(&self) -> u64 {
        let b = &self.blocks;
        let confined: u64 = b
            .confined
            .iter()
            .chain(&b.confined_solo)
            .map(|j| j.count)
            .sum();
        b.jit.count + b.solo.count + confined
    }

    /// Runs of timed native code stopped at their limit ([`crate::Board::timed_stops`]).
    pub(crate) fn timed_stops(&self) -> u64 {
        self.blocks.timed_stops
    }

    /// Compiles a code region once its entry has been reached `times` times.
    pub(crate) fn set_compile_threshold(&mut self, times: u32) {
        self.blocks.jit.threshold = times;
        self.blocks.solo.threshold = times;
        let b = &mut self.blocks;
        for j in b.confined.iter_mut().chain(b.confined_solo.iter_mut()) {
            j.threshold = times;
        }
    }
}

/// The accelerator at work on a machine (module documentation).
pub(crate) struct Drive<'a> {
    /// The accelerator's state.
    pub(crate) a: &'a mut Accel,
    /// The machine it runs.
    pub(crate) m: &'a mut Machine,
    /// The profiles whose watched addresses its runs stop at, told of every step.
    pub(crate) prof: &'a mut Profiler,
    /// The board's configuration (engine, own banks, what stops a run).
    pub(crate) cfg: &'a Config,
}
