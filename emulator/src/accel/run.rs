//! Scheduling the two cores: the lock-step loop of [`Board::run_until`] and its fast paths.
//!
//! **Speed.** [`Board::run_until`] lets the core whose turn it is run a burst of
//! instructions until it gets ahead of the other core, taking instructions from a
//! direct-mapped decode cache that also holds their timing-table costs and a pre-decoded
//! form (module `fast`); a store into an SRAM page holding cached code, or any host write,
//! invalidates the cache (an epoch), so self-modifying code stays correct. Interrupt lines
//! are recomputed only when a peripheral was accessed or a timer event is due. Once a core
//! is in a state where its next instructions cannot take an exception (running, Thumb,
//! nothing takeable pending, the current interrupt lines already pending on it), the fast
//! path runs it in a tight loop (`Core::execute_op`): common instructions with SRAM and
//! flash accesses complete there; anything else (peripherals, SIO, PPB, faults, sleep,
//! SEV, SVC, exception return, a cache miss) runs through the general path and ends the
//! loop, after which every condition is checked again — except a single load that leaves
//! every such condition as it was (a timer read: no event, the same interrupt-line epoch,
//! timer event and SysTick wrap), after which the loop goes on as the board would. The loop also stops at each core's
//! deadline: the run's limit, the next timer event and its next SysTick wrap. With both
//! cores running, one loop alternates between them in the lock-step order (whichever is
//! behind, core 0 on ties); with one core asleep and nothing able to wake it, the loop runs
//! the other core and moves the sleeper's cycle counter exactly as its sleep steps would.
//! While functions are profiled, the loop also stops after any instruction that lands on a
//! profiled entry or on the return address of the innermost open call, the only places
//! where the per-instruction profiling bookkeeping can do anything; exception handlers
//! profiled with [`Board::profile_handler`] are entered and left only by exception entry
//! and return, in the general path, so they cost the loop no such check.
//! So the order of all shared-state accesses, and every result, is the same as stepping
//! one instruction at a time.
//!
//! [`Config::engine`] selects what runs that fast path for one
//! core: the interpreter above ([`Engine::Interp`]) or the block engine ([`Engine::Block`],
//! the default; module [`crate::accel::block`]: code regions compiled to native code with
//! cranelift, pre-decoded basic blocks where they do not fit; the same results).
//! [`Board::step`] is the same machine one instruction at a time, recording
//! [`Core::last`] for traces.

use super::decode::{cache_key, CACHE_SLOTS};
use super::window::{Window, RETRY};
use super::*;
use crate::accel::block;
use crate::core::Event;
use crate::nvic::IRQ0;
use crate::profile::{NO_WATCH, NO_WATCHES, WATCH_SLOTS};

/// Why a fast-path run ([`run_one`], [`run_both`]) returned.
pub(super) enum Exit {
    /// The core to run reached its deadline.
    Deadline,
    /// The core's next instruction is not in the decode cache.
    Miss,
    /// The core's next instruction (in the cache) needs the general path.
    General,
    /// The core executed an instruction that left it at a watched address (profiling).
    Watch,
    /// The core's next instruction needed the general path and has run there, with this
    /// event ([`general_load`]).
    Ran(Event),
}

/// Turns shorter than this many cycles run on the interpreter's loop even with the block
/// engine ([`Board::fast_run`]); the results are the same either way.
pub(super) const SHORT_TURN: u64 = 32;

/// One step of the fast path for `core`: false (and nothing done) with the reason when
/// it must leave.
///
/// With `WATCH`, an instruction that leaves the PC at an address in `watch` is counted here
/// and ends the run with [`Exit::Watch`].
#[inline(always)]
pub(super) fn fast_step<const WATCH: bool>(
    core: &mut Core,
    sys: &mut System,
    cache: &[Cached; CACHE_SLOTS],
    deadline: u64,
    watch: &[u32; WATCH_SLOTS],
) -> Result<(), Exit> {
    if core.cycle >= deadline {
        return Err(Exit::Deadline);
    }
    let pc = core.r[15];
    let slot = &cache[((pc >> 1) as usize) & (CACHE_SLOTS - 1)];
    if slot.key != cache_key(pc, sys.code_epoch) {
        return Err(Exit::Miss);
    }
    if !core.execute_op(sys, &slot.op, &slot.instr, pc, slot.size, slot.cost) {
        return Err(Exit::General);
    }
    if WATCH && watch.contains(&core.r[15]) {
        core.instructions += 1;
        return Err(Exit::Watch);
    }
    Ok(())
}

/// The fast path on one core until it must leave. A separate function whose arguments
/// cannot alias, so the compiler may keep the core's counters in registers.
#[inline(never)]
pub(super) fn run_one<const WATCH: bool>(
    core: &mut Core,
    sys: &mut System,
    cache: &[Cached; CACHE_SLOTS],
    deadline: u64,
    watch: &[u32; WATCH_SLOTS],
) -> Exit {
    let mut retired = 0;
    loop {
        match fast_step::<WATCH>(core, sys, cache, deadline, watch) {
            Ok(()) => retired += 1,
            Err(Exit::General) if !WATCH => {
                if let Some(event) = general_load(core, sys, cache) {
                    core.instructions += retired;
                    return Exit::Ran(event);
                }
            }
            Err(exit) => {
                core.instructions += retired;
                return exit;
            }
        }
    }
}

/// On [`Exit::General`] in a loop without watched addresses: when the instruction is a
/// single load (a timer read, on the firmware images), runs it on the general path as
/// [`Board::finish_fast`] would; `None` when it left everything the caller's next
/// decision depends on as it was — no event, the interrupt-line epoch, the next timer
/// event and SysTick wrap, the pending exceptions, the core running — so the fast path
/// goes on exactly as [`Board::run_until`] would resume it; else the event, for the caller
/// to return ([`Exit::Ran`]). (A load of a PPB register may signal a SysTick count at 0,
/// pending the exception; a fault is an event; a peripheral read that could change a line
/// bumps the epoch.) Any other instruction runs the same way
/// and returns its event.
#[inline(never)]
pub(super) fn general_load(
    core: &mut Core,
    sys: &mut System,
    cache: &[Cached; CACHE_SLOTS],
) -> Option<Event> {
    let pc = core.r[15];
    let slot = &cache[((pc >> 1) as usize) & (CACHE_SLOTS - 1)];
    let load = tactus_isa::timing::class(&slot.instr) == tactus_isa::timing::Class::Load;
    let before = (
        sys.irq_epoch,
        sys.timer.next_event,
        core.nvic.syst_next,
        core.nvic.pending,
    );
    let event = core.run_priced::<_, false>(sys, pc, slot.instr, slot.size, Some(slot.cost));
    let same = (
        sys.irq_epoch,
        sys.timer.next_event,
        core.nvic.syst_next,
        core.nvic.pending,
    ) == before;
    let quiet = load && same && event == Event::None && core.state == RunState::Running;
    (!quiet).then_some(event)
}

/// The fast path on both cores in lock-step order (the core that is behind, core 0 on
/// ties) until the core whose turn it is must leave; returns that core.
#[inline(never)]
pub(super) fn run_both<const WATCH: bool>(
    cores: &mut [Core; 2],
    sys: &mut System,
    cache: &[Cached; CACHE_SLOTS],
    deadline: [u64; 2],
    watch: &[[u32; WATCH_SLOTS]; 2],
) -> (usize, Exit) {
    let [c0, c1] = cores;
    let mut retired = [0; 2];
    let exit = loop {
        // Two copies of the step, chosen by a branch rather than an index: the choice is
        // then predicted instead of making every instruction wait for the previous one's
        // cycle count (and each core gets its own, better predicted, dispatch).
        if c1.cycle < c0.cycle {
            match fast_step::<WATCH>(c1, sys, cache, deadline[1], &watch[1]) {
                Ok(()) => retired[1] += 1,
                Err(Exit::General) if !WATCH => {
                    if let Some(event) = general_load(c1, sys, cache) {
                        break (1, Exit::Ran(event));
                    }
                }
                Err(exit) => break (1, exit),
            }
        } else {
            match fast_step::<WATCH>(c0, sys, cache, deadline[0], &watch[0]) {
                Ok(()) => retired[0] += 1,
                Err(Exit::General) if !WATCH => {
                    if let Some(event) = general_load(c0, sys, cache) {
                        break (0, Exit::Ran(event));
                    }
                }
                Err(exit) => break (0, exit),
            }
        }
    };
    c0.instructions += retired[0];
    c1.instructions += retired[1];
    exit
}

/// The fast path on core `r` while the other core sleeps soundly ([`Board::sleeps_soundly`]),
/// in lock-step order: on the sleeper's turns, its step — skip to the next cycle at which
/// something could wake it: a timer event, its SysTick, the limit, or the cycle after the
/// running core's — is done here while its cycle is below `wake_check` (the first of
/// those), so nothing else about it can change. `Ok` when the sleeper reached
/// `wake_check`, `Err` when the running core must leave.
#[inline(never)]
pub(super) fn run_beside_sleeper<const SLEEPER_IS_0: bool, const WATCH: bool>(
    run: &mut Core,
    sleep: &mut Core,
    sys: &mut System,
    cache: &[Cached; CACHE_SLOTS],
    deadline: u64,
    wake_check: u64,
    watch: &[u32; WATCH_SLOTS],
) -> Result<(), Exit> {
    loop {
        // The sleeper's turn: it is behind, or level and core 0.
        if sleep.cycle < run.cycle || (SLEEPER_IS_0 && sleep.cycle == run.cycle) {
            let now = sleep.cycle;
            if now >= wake_check {
                return Ok(());
            }
            sleep.cycle = wake_check.min(run.cycle + 1).max(now + 1);
        } else {
            match fast_step::<WATCH>(run, sys, cache, deadline, watch) {
                Ok(()) => run.instructions += 1,
                Err(exit) => return Err(exit),
            }
        }
    }
}

/// [`run_beside_sleeper`] on the block engine (nothing watched): the same interleaving.
/// The running core keeps the turn while its cycle is below the sleeper's (`+ 1` when the
/// sleeper is core 1, which loses ties); each sleeper turn before its wake check only sets
/// its cycle to `min(wake_check, run.cycle + 1)`, which makes the turn the running core's
/// again, so those turns are replayed after each instruction of a block (`after`). The
/// block runs up to the cycle from which the sleeper's turn would find it at its wake
/// check (the later of `wake_check` and the sleeper's cycle, `+ 1` when the sleeper is
/// core 1) and the deadline; the loop then takes the turns exactly as
/// [`run_beside_sleeper`] does.
#[inline(never)]
pub(super) fn blocks_beside_sleeper<const SLEEPER_IS_0: bool>(
    run: &mut Core,
    sleep: &mut Core,
    sys: &mut System,
    blocks: &mut Blocks,
    deadline: u64,
    wake_check: u64,
) -> Result<(), Exit> {
    let loses_ties = !SLEEPER_IS_0 as u64;
    loop {
        if sleep.cycle < run.cycle || (SLEEPER_IS_0 && sleep.cycle == run.cycle) {
            let now = sleep.cycle;
            if now >= wake_check {
                return Ok(());
            }
            sleep.cycle = wake_check.min(run.cycle + 1).max(now + 1);
        } else {
            if run.cycle >= deadline {
                return Err(Exit::Deadline);
            }
            // From this cycle on, the sleeper's turn would find it at (or past) its wake
            // check: the loop must take that turn.
            let limit = deadline.min(wake_check.max(sleep.cycle) + loses_ties);
            let mut turns = block::Sleeper {
                cycle: &mut sleep.cycle,
                wake: wake_check,
                loses_ties: !SLEEPER_IS_0,
            };
            if block::run(run, sys, blocks, limit, &mut turns).is_err() {
                return Err(Exit::Miss);
            }
        }
    }
}

impl Drive<'_> {
    /// Whether the fast path may run the block engine's unconfined code: [`Engine::Block`]
    /// and no I/O attached (that code does not leave the banks the I/O's DMA may reach,
    /// `crate::io`; the interpreter's fast path does).
    #[inline]
    fn blocks_run(&self) -> bool {
        self.cfg.engine == Engine::Block && self.m.system.io.is_none()
    }

    /// Runs until both running cores reach cycle `limit`, or a stop
    /// ([`crate::Board::run_until`]), on the fast paths and engines (module documentation),
    /// with every result of the lock-step machine's [`Machine::step_core`].
    pub(crate) fn run_until(&mut self, limit: u64) -> StopReason {
        if self.cfg.engine == Engine::LockStep {
            if self.prof.is_empty() {
                return self.m.run_lock_step(limit, self.cfg);
            }
            return loop {
                match self.step(limit) {
                    Some(Ok(_)) => {}
                    Some(Err(stop)) => break stop,
                    None => break StopReason::CycleLimit,
                }
            };
        }
        self.a.lines_epoch = u64::MAX; // the host may have touched SIO or the timer
        let run_limit = limit;
        loop {
            let Some(k) = self.m.next_core() else {
                return StopReason::Idle;
            };
            let now = self.m.cores[k].cycle;
            if now >= run_limit {
                return StopReason::CycleLimit;
            }
            // Every engine stops where the watchdog fires (`machine/reset.rs`); a core's
            // write to it ends any fast run (a peripheral access), so this bound is current.
            let fire_at = self.m.system.watchdog.fire_at;
            if now >= fire_at {
                self.m.watchdog_reset();
                self.prof.cores_reset();
                continue;
            }
            let limit = run_limit.min(fire_at);
            // Both cores as independent machines, where their banks allow
            // (`accel/window.rs`); the lock-step loop below otherwise.
            if now >= self.a.window_at && self.windows_allowed() {
                match self.window(limit) {
                    Window::Kept => continue,
                    Window::Idle => self.a.window_at = now.saturating_add(RETRY),
                }
            }
            if self.m.cores[k].state != RunState::Running {
                match self.step(limit) {
                    Some(Ok(_)) => continue,
                    Some(Err(stop)) => return stop,
                    None => return StopReason::CycleLimit,
                }
            }
            // Both cores running the fast path: interleave them there, in lock-step order.
            if self.fast_ready(0) && self.fast_ready(1) {
                let deadline = |c: &Core| {
                    limit
                        .min(self.m.system.timer.next_event)
                        .min(c.nvic.syst_next)
                };
                let deadline = [deadline(&self.m.cores[0]), deadline(&self.m.cores[1])];
                let mut slots = NO_WATCHES;
                if let (true, Some(watch)) = (now < deadline[k], self.prof.watch_sets(&mut slots)) {
                    let (k, ran) = self.fast_run::<true>(k, deadline, watch);
                    if let Some(event) = ran {
                        if !self.prof.is_empty() {
                            self.prof.step(k, &self.m.cores[k]);
                        }
                        if let Some(stop) = self.m.handle_event(k, event, self.cfg) {
                            return stop;
                        }
                    }
                    continue;
                }
            }
            // Core k running the fast path while the other core sleeps and nothing can
            // wake it: the sleeper's steps only move its cycle counter, done in the loop.
            if self.fast_ready(k) && self.m.launch.is_none() && self.m.sleeps_soundly(1 - k) {
                let s = &self.m.cores[1 - k];
                let deadline = limit
                    .min(self.m.system.timer.next_event)
                    .min(self.m.cores[k].nvic.syst_next);
                let wake_check = limit
                    .min(self.m.system.timer.next_event)
                    .min(s.nvic.syst_next);
                if let (true, Some(watch)) = (now < deadline, self.prof.watch_set(k)) {
                    let on_blocks = self.blocks_run();
                    let [c0, c1] = &mut self.m.cores;
                    let (sys, cache) = (&mut self.m.system, &self.a.cache);
                    let blocks = &mut self.a.blocks;
                    let run = match (k == 0, watch[0] == NO_WATCH) {
                        (true, true) if on_blocks => blocks_beside_sleeper::<false>(
                            c0, c1, sys, blocks, deadline, wake_check,
                        ),
                        (false, true) if on_blocks => {
                            blocks_beside_sleeper::<true>(c1, c0, sys, blocks, deadline, wake_check)
                        }
                        (true, true) => run_beside_sleeper::<false, false>(
                            c0, c1, sys, cache, deadline, wake_check, &watch,
                        ),
                        (true, false) => run_beside_sleeper::<false, true>(
                            c0, c1, sys, cache, deadline, wake_check, &watch,
                        ),
                        (false, true) => run_beside_sleeper::<true, false>(
                            c1, c0, sys, cache, deadline, wake_check, &watch,
                        ),
                        (false, false) => run_beside_sleeper::<true, true>(
                            c1, c0, sys, cache, deadline, wake_check, &watch,
                        ),
                    };
                    // Ok: the sleeper reached its wake check; Err: core k must leave.
                    if let Err(exit) = run {
                        if let Some(event) = self.finish_fast(k, exit) {
                            if !self.prof.is_empty() {
                                self.prof.step(k, &self.m.cores[k]);
                            }
                            if let Some(stop) = self.m.handle_event(k, event, self.cfg) {
                                return stop;
                            }
                        }
                    }
                    continue;
                }
            }
            // Core k keeps the turn while it stays behind the other core (core 0 on ties).
            let other = &self.m.cores[1 - k];
            let horizon = if active(other) {
                other.cycle + (k == 0) as u64
            } else {
                u64::MAX
            };
            let event = self.burst(k, horizon.min(limit));
            if let Some(stop) = self.m.handle_event(k, event, self.cfg) {
                return stop;
            }
        }
    }

    /// Runs core `k` while its cycle is below `horizon` and it is running; returns early with
    /// any event other than `None`. The fast path: interrupt lines are recomputed only when a
    /// peripheral was touched or a timer event is due, and instructions come from the
    /// decode cache with their cycle costs.
    ///
    /// The run also ends where the watchdog fires (`machine/reset.rs`): its cycle is part of
    /// the burst's end, taken again whenever a peripheral was written (every write to the
    /// watchdog, the only thing in a burst that moves it, bumps [`System::irq_epoch`]), so
    /// the loop checks one bound per turn.
    pub(super) fn burst(&mut self, k: usize, horizon: u64) -> Event {
        let mut end = horizon.min(self.m.system.watchdog.fire_at);
        loop {
            let core = &mut self.m.cores[k];
            if core.cycle >= end || core.state != RunState::Running {
                return Event::None;
            }
            if self.m.system.irq_epoch != self.a.lines_epoch
                || core.cycle >= self.m.system.timer.next_event
            {
                let now = core.cycle;
                end = horizon.min(self.m.system.watchdog.fire_at);
                if now >= end {
                    return Event::None;
                }
                if self.m.launch.is_some() {
                    self.m.poll_launch();
                    if self.m.launch.is_none() {
                        return Event::None; // core 1 started: re-pick whose turn it is
                    }
                }
                self.a.lines = self.m.system.irq_lines(k, now);
                self.a.lines_epoch = self.m.system.irq_epoch;
            }
            // The fast path when it can run; a single general step otherwise.
            let slots;
            let watch = match self.prof.watch_set(k) {
                _ if self.prof.watch_free => Some(&NO_WATCHES),
                Some(w) => {
                    slots = [w; 2];
                    Some(&slots)
                }
                None => None,
            };
            if let (true, Some(watch)) = (self.fast_ready(k), watch) {
                let deadline = end
                    .min(self.m.system.timer.next_event)
                    .min(self.m.cores[k].nvic.syst_next);
                if self.m.cores[k].cycle < deadline {
                    let (_, ran) = self.fast_run::<false>(k, [deadline; 2], watch);
                    if let Some(event) = ran {
                        if !self.prof.is_empty() {
                            self.prof.step(k, &self.m.cores[k]);
                        }
                        if event != Event::None {
                            return event;
                        }
                    }
                    continue;
                }
            }
            let event = self.m.execute::<false>(k, self.a.lines, &mut self.a.cache);
            if !self.prof.is_empty() {
                self.prof.step(k, &self.m.cores[k]);
            }
            if event != Event::None {
                return event;
            }
        }
    }

    /// True when core `k`'s next instructions may take the fast path ([`Board::fast_run`]):
    /// it is running in Thumb state with no exception it could take, the interrupt lines
    /// are current and already pending on it (so the per-instruction "OR the lines into
    /// pending" of [`Board::step_cached`] would change nothing), and the XIP window reads
    /// the flash (the fast paths read flash bytes directly; without XIP only the general
    /// path's accesses fault as they must, `crate::xip`).
    /// Everything the fast path executes leaves these conditions true; everything that
    /// could change them leaves the fast path.
    #[inline]
    pub(super) fn fast_ready(&self, k: usize) -> bool {
        let c = &self.m.cores[k];
        c.state == RunState::Running
            && c.thumb
            && c.nvic.takeable() == 0
            && ((self.a.lines as u64) << IRQ0) & !c.nvic.active & !c.nvic.pending == 0
            && self.a.lines_epoch == self.m.system.irq_epoch
            && self.m.system.xip_answers
    }

    /// The fast path: runs core `k` (or, with `BOTH`, whichever core is behind, core 0 on
    /// ties: the lock-step order) while the core to run is below its `deadline` (its
    /// horizon, the next timer event and its next SysTick wrap; see [`Board::fast_ready`]
    /// for the other conditions). Instructions come from the decode cache and run through
    /// [`Core::execute_fast`]; the first one that needs the general path (a decode-cache
    /// miss, a peripheral access, anything that could fault or change exception state) is
    /// executed exactly as [`Board::step_cached`] would and ends the run, so the caller
    /// re-checks everything as before. Returns the core that ran last and its event.
    #[inline(always)]
    pub(super) fn fast_run<const BOTH: bool>(
        &mut self,
        k: usize,
        deadline: [u64; 2],
        watch: &[[u32; WATCH_SLOTS]; 2],
    ) -> (usize, Option<Event>) {
        // Slots fill from the first: nothing to watch when it is empty.
        let unwatched = if BOTH {
            watch[0][0] == NO_WATCH && watch[1][0] == NO_WATCH
        } else {
            watch[k][0] == NO_WATCH
        };
        // Both cores running: lock-step turns of one or two instructions, too short for
        // a compiled region to fit in; the interpreter's loop below is the faster there
        // (BENCHMARKS.md, "the block compiler").
        // A short turn (the other core's cycle a few cycles on, as in `burst`) fits no
        // compiled region: the interpreter's loop costs less per call.
        if unwatched
            && !BOTH
            && self.blocks_run()
            && deadline[k] >= self.m.cores[k].cycle.saturating_add(SHORT_TURN)
        {
            let (sys, blocks) = (&mut self.m.system, &mut self.a.blocks);
            let core = &mut self.m.cores[k];
            let exit = match block::run(core, sys, blocks, deadline[k], &mut block::Alone) {
                Ok(()) => Exit::Deadline,
                Err(_) => Exit::Miss,
            };
            return (k, self.finish_fast(k, exit));
        }
        let (cores, sys, cache) = (&mut self.m.cores, &mut self.m.system, &self.a.cache);
        let (k, exit) = match (BOTH, unwatched) {
            (true, true) => run_both::<false>(cores, sys, cache, deadline, watch),
            (true, false) => run_both::<true>(cores, sys, cache, deadline, watch),
            (false, true) => (
                k,
                run_one::<false>(&mut cores[k], sys, cache, deadline[k], &watch[k]),
            ),
            (false, false) => (
                k,
                run_one::<true>(&mut cores[k], sys, cache, deadline[k], &watch[k]),
            ),
        };
        (k, self.finish_fast(k, exit))
    }

    /// Completes a fast-path run of core `k` that left with `exit`: the instruction that
    /// needs the general path runs as [`Board::step_cached`] would run it. Returns the event
    /// of the instruction the run ended with, `None` when it ended before one.
    pub(super) fn finish_fast(&mut self, k: usize, exit: Exit) -> Option<Event> {
        Some(match exit {
            Exit::Deadline => return None,
            Exit::Watch => Event::None,
            Exit::Ran(event) => event,
            Exit::Miss => self.m.execute::<false>(k, self.a.lines, &mut self.a.cache),
            Exit::General => {
                let core = &mut self.m.cores[k];
                let pc = core.r[15];
                let slot = &self.a.cache[((pc >> 1) as usize) & (CACHE_SLOTS - 1)];
                let (instr, size, cost) = (slot.instr, slot.size, slot.cost);
                core.run_priced::<_, false>(&mut self.m.system, pc, instr, size, Some(cost))
            }
        })
    }

    /// One step of the lock-step machine ([`Machine::step_core`]) with the instruction from
    /// the decode cache (decoded from memory on [`Engine::LockStep`]), the profiles told of
    /// it and its event applied: `None` when both running cores are at `limit`;
    /// `Some(Ok(core))` names the core that acted (its [`Core::last`] is the instruction).
    pub(crate) fn step(&mut self, limit: u64) -> Option<Result<usize, StopReason>> {
        let stepped = if self.cfg.engine == Engine::LockStep {
            self.m.step_core(limit, &mut Fetch)
        } else {
            self.m.step_core(limit, &mut self.a.cache)
        };
        let (k, event) = match stepped? {
            Ok(Step::Slept(k)) => return Some(Ok(k)),
            Ok(Step::Reset) => {
                self.prof.cores_reset();
                return Some(Ok(0));
            }
            Ok(Step::Ran(k, event)) => (k, event),
            Err(stop) => return Some(Err(stop)),
        };
        if !self.prof.is_empty() {
            self.prof.step(k, &self.m.cores[k]);
        }
        match self.m.handle_event(k, event, self.cfg) {
            None => Some(Ok(k)),
            Some(stop) => Some(Err(stop)),
        }
    }
}
