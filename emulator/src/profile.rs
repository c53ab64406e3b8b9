//! Profiling: every call of a function, or every activation of an exception handler, with
//! its cycles, on both cores ([`Profiler`]).
//!
//! The profiler watches the machine after each instruction ([`Profiler::step`]), whoever
//! runs it: the lock-step machine's steps and the accelerator's runs alike. So that those
//! runs need not stop after every instruction, it says where it could do anything: the
//! addresses at which a call can open or close ([`Profiler::watch_set`]); a run stops
//! there. Undoing a core's steps (a window put back, `crate::accel::window`) undoes its
//! profiling too ([`Profiler::mark`], [`Profiler::restore`]).

use crate::core::Core;
/// One measured call of a profiled function.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Call {
    /// Core that made the call.
    pub core: usize,
    /// Cycle at which the function's first instruction started.
    pub start: u64,
    /// Cycles from the function's first instruction to the first instruction after its
    /// return (the return instruction and any exception taken meanwhile included; the call
    /// instruction excluded).
    pub cycles: u64,
}

#[derive(Clone, Debug)]
pub(crate) struct Profile {
    entry: u32,
    /// Measures only activations entered by exception entry ([`Board::profile_handler`]):
    /// the fast path need not watch the entry, which only the general path reaches then.
    handler_only: bool,
    /// Open calls per core.
    open: [Vec<Open>; 2],
    calls: Vec<Call>,
    /// Times the entry was reached (calls open or completed, both cores).
    entries: [u64; 2],
}

impl Profile {
    /// Whether a call is open on either core.
    pub(crate) fn is_open(&self) -> bool {
        self.open.iter().any(|o| !o.is_empty())
    }

    /// Times each core reached the entry.
    pub(crate) fn entries(&self) -> [u64; 2] {
        self.entries
    }

    /// Counts `more` entries on each core (`rest.rs`: periods skipped).
    pub(crate) fn add_entries(&mut self, more: [u64; 2]) {
        for (e, m) in self.entries.iter_mut().zip(more) {
            *e = e.wrapping_add(m);
        }
    }
}

/// An open call: (return address or exception number, SP at entry, start cycle).
type Open = (Return, u32, u64);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Return {
    To(u32),
    FromException(u32),
}

/// An unused slot of a watch set ([`Board::watch_set`]): odd, so no PC equals it.
pub(crate) const NO_WATCH: u32 = 1;

/// Most addresses the fast path watches for profiling ([`Board::watch_set`]).
pub(crate) const WATCH_SLOTS: usize = 8;

/// Both cores' watch sets when nothing is watched.
pub(crate) static NO_WATCHES: [[u32; WATCH_SLOTS]; 2] = [[NO_WATCH; WATCH_SLOTS]; 2];

/// Every profile of a board and what tells a run where to stop for them (module
/// documentation).
pub(crate) struct Profiler {
    profiles: Vec<Profile>,
    /// Each core's profiling at the start of the current window (`accel/window.rs`),
    /// kept to reuse its vectors.
    pub(crate) marks: [ProfileMark; 2],
    /// Each core's active exceptions at its last [`Profiler::step`] that ran its loop
    /// (`u64::MAX`, which no core has, before any).
    active: [u64; 2],
    /// No profile watches an address (none, or handler profiles only): the fast path's
    /// watch sets are empty ([`Profiler::watch_set`]).
    pub(crate) watch_free: bool,
    /// Every profiled entry, sorted, and per core the distinct return addresses of each
    /// profile's innermost open call: the only PCs at which [`Profiler::step`] can open
    /// or close a call (besides a change of active exceptions). With them, per core, the
    /// fast path's watch set ([`Profiler::watch_set`]), `None` when it has too many. Rebuilt
    /// when a profile is added or an open call changes.
    entries: Vec<u32>,
    returns: [Vec<u32>; 2],
    /// Per core, a 4096-bit filter of those PCs (bit `(pc >> 1) mod 4096`): a clear bit
    /// rules a PC out in one load.
    filter: [[u64; 64]; 2],
    watch: [Option<[u32; WATCH_SLOTS]>; 2],
}

impl Default for Profiler {
    fn default() -> Self {
        Profiler {
            profiles: Vec::new(),
            marks: Default::default(),
            active: [u64::MAX; 2],
            watch_free: true,
            entries: Vec::new(),
            returns: [Vec::new(), Vec::new()],
            filter: [[0; 64]; 2],
            watch: [Some([NO_WATCH; WATCH_SLOTS]); 2],
        }
    }
}

impl Profiler {
    /// A new profile of the code at `addr` (Thumb bit ignored); its handle.
    pub(crate) fn add(&mut self, addr: u32, handler_only: bool) -> usize {
        self.active = [u64::MAX; 2];
        self.watch_free &= handler_only;
        self.profiles.push(Profile {
            entry: addr & !1,
            handler_only,
            open: [Vec::new(), Vec::new()],
            calls: Vec::new(),
            entries: [0; 2],
        });
        self.index();
        self.profiles.len() - 1
    }

    /// The completed calls of profile `handle` (none for an unknown handle).
    pub(crate) fn calls(&self, handle: usize) -> &[Call] {
        self.profiles.get(handle).map_or(&[], |p| &p.calls)
    }

    /// How many times the entry of profile `handle` has been reached (0 for an unknown
    /// handle).
    pub(crate) fn entry_count(&self, handle: usize) -> u64 {
        self.profiles
            .get(handle)
            .map_or(0, |p| p.entries[0] + p.entries[1])
    }

    /// Forgets the completed calls of profile `handle` (an unknown handle is ignored).
    pub(crate) fn clear_calls(&mut self, handle: usize) {
        if let Some(p) = self.profiles.get_mut(handle) {
            p.calls.clear();
        }
    }

    /// Whether there is no profile: nothing to do after a step.
    #[inline(always)]
    pub(crate) fn is_empty(&self) -> bool {
        self.profiles.is_empty()
    }

    /// The profiles, for `accel/rest.rs` (a rest period's entries counted).
    pub(crate) fn profiles_mut(&mut self) -> &mut [Profile] {
        &mut self.profiles
    }

    /// After an instruction (or exception entry or return) of core `k`: opens and closes
    /// the profiled calls it began or ended. The common case, a PC the filter rules out
    /// with the core's active exceptions unchanged, costs its caller a few instructions;
    /// the rest is [`Board::profile_step_slow`].
    #[inline(always)]
    pub(crate) fn step(&mut self, k: usize, core: &Core) {
        let pc = core.r[15];
        if self.active[k] == core.nvic.active
            && self.filter[k][(pc as usize >> 7) & 63] >> ((pc >> 1) & 63) & 1 == 0
        {
            return;
        }
        self.step_slow(k, core);
    }

    #[inline(never)]
    fn step_slow(&mut self, k: usize, core: &Core) {
        let (pc, sp, now) = (core.r[15], core.r[13], core.cycle);
        // The core's active exceptions as at this core's last call, and the PC neither a
        // profiled entry nor the return address of an innermost open call: no activation
        // can open or close (an open one closes when its exception's active bit clears or
        // at its return address; one opens at an entry), so the loop below would do
        // nothing. (`profile_step` has returned already where the filter rules the PC out.)
        if self.active[k] == core.nvic.active
            && self.entries.binary_search(&pc).is_err()
            && !self.returns[k].contains(&pc)
        {
            return;
        }
        self.active[k] = core.nvic.active;
        // Whether an innermost open call changed where it returns to (a handler's return
        // is no address: opening or closing one over another handler changes nothing the
        // index holds).
        let mut changed = false;
        for p in &mut self.profiles {
            while let Some(&(ret, entry_sp, start)) = p.open[k].last() {
                let done = match ret {
                    Return::To(addr) => pc == addr && sp >= entry_sp,
                    Return::FromException(exc) => core.nvic.active & (1 << exc) == 0,
                };
                if !done {
                    break;
                }
                p.open[k].pop();
                changed |= matches!(ret, Return::To(_))
                    || matches!(p.open[k].last(), Some((Return::To(_), ..)));
                p.calls.push(Call {
                    core: k,
                    start,
                    cycles: now - start,
                });
            }
            if pc == p.entry && core.thumb {
                p.entries[k] += 1;
                let lr = core.r[14];
                let ret = if lr >> 28 == 0xf && core.ipsr != 0 {
                    Return::FromException(core.ipsr)
                } else if p.handler_only {
                    continue;
                } else {
                    Return::To(lr & !1)
                };
                changed |= matches!(ret, Return::To(_))
                    || matches!(p.open[k].last(), Some((Return::To(_), ..)));
                p.open[k].push((ret, sp, now));
            }
        }
        if changed {
            self.returns_index(k);
        }
    }

    /// Rebuilds the sorted profiled entries and both cores' return addresses, filters and
    /// watch sets ([`Board::profile_returns_index`]) from the profiles and their open calls.
    fn index(&mut self) {
        let mut entries = std::mem::take(&mut self.entries);
        entries.clear();
        entries.extend(self.profiles.iter().map(|p| p.entry));
        entries.sort_unstable();
        entries.dedup();
        self.entries = entries;
        self.returns_index(0);
        self.returns_index(1);
    }

    /// Rebuilds core `k`'s `profile_returns`, `profile_filter` and `profile_watch` (the
    /// profiled entries are as they were).
    fn returns_index(&mut self, k: usize) {
        let mut returns = std::mem::take(&mut self.returns[k]);
        returns.clear();
        let mut watch = Some([NO_WATCH; WATCH_SLOTS]);
        let mut n = 0;
        for p in &self.profiles {
            let ret = match p.open[k].last() {
                Some(&(Return::To(addr), _, _)) => Some(addr),
                _ => None,
            };
            if let Some(a) = ret {
                // Typically every open call returns to one of a few addresses.
                if !returns.contains(&a) {
                    returns.push(a);
                }
            }
            // Handler profiles watch nothing on the fast path: they open and close at
            // exception entry and return, on the general path.
            for a in [(!p.handler_only).then_some(p.entry), ret]
                .into_iter()
                .flatten()
            {
                if let Some(w) = &mut watch {
                    match w.get_mut(n) {
                        Some(slot) => *slot = a,
                        None => watch = None,
                    }
                    n += 1;
                }
            }
        }
        let mut filter = [0u64; 64];
        for &a in self.entries.iter().chain(&returns) {
            filter[(a as usize >> 7) & 63] |= 1 << ((a >> 1) & 63);
        }
        self.filter[k] = filter;
        self.returns[k] = returns;
        self.watch[k] = watch;
    }

    /// The addresses at which core `k`'s fast path must stop for [`Board::profile_step`]
    /// (unused slots hold 1, which no PC equals), or `None` when there are too many. After
    /// any other instruction of the fast path `profile_step` would do nothing: no call can
    /// start (the PC is no profiled entry) and none can end (the PC is not the return
    /// address of the innermost open call, and a call ending with an exception return
    /// leaves the fast path anyway).
    #[inline(always)]
    pub(crate) fn watch_set(&self, k: usize) -> Option<[u32; WATCH_SLOTS]> {
        // Handler profiles ([`Board::profile_handler`]) watch nothing: they open and close
        // at exception entry and return, on the general path.
        if self.watch_free {
            return Some([NO_WATCH; WATCH_SLOTS]);
        }
        self.watched(k)
    }

    /// Both cores' watch sets ([`Board::watch_set`]): the constant empty sets when nothing
    /// is watched (no copy: the hot loop of [`Board::run_until`] passes them on by
    /// reference), else built in `slots`; `None` when there are too many.
    #[inline(always)]
    pub(crate) fn watch_sets<'a>(
        &self,
        slots: &'a mut [[u32; WATCH_SLOTS]; 2],
    ) -> Option<&'a [[u32; WATCH_SLOTS]; 2]> {
        if self.watch_free {
            return Some(&NO_WATCHES);
        }
        *slots = [self.watched(0)?, self.watched(1)?];
        Some(slots)
    }

    /// [`Board::watch_set`] when some profile watches an address.
    #[inline(always)]
    pub(crate) fn watched(&self, k: usize) -> Option<[u32; WATCH_SLOTS]> {
        self.watch[k]
    }
}

/// Core `k`'s part of every profile at some moment ([`Board::profile_mark`]): what undoing
/// its steps since then restores.
#[derive(Default)]
pub(crate) struct ProfileMark {
    /// Per profile: completed calls then, core `k`'s open calls, core `k`'s entries.
    each: Vec<(usize, Vec<Open>, u64)>,
    active: u64,
}

impl Profiler {
    /// Core `k`'s part of every profile now, into `mark` (its vectors reused: a window
    /// marks both cores every time).
    pub(crate) fn mark(&self, k: usize, mark: &mut ProfileMark) {
        mark.each.truncate(self.profiles.len());
        while mark.each.len() < self.profiles.len() {
            mark.each.push((0, Vec::new(), 0));
        }
        for (m, p) in mark.each.iter_mut().zip(&self.profiles) {
            m.0 = p.calls.len();
            m.1.clear();
            m.1.extend_from_slice(&p.open[k]);
            m.2 = p.entries[k];
        }
        mark.active = self.active[k];
    }

    /// Undoes core `k`'s profiling since `mark`: its calls completed since then are
    /// forgotten (the other core's stay, in their order), its open calls, entries and
    /// active exceptions are as they were.
    pub(crate) fn restore(&mut self, k: usize, mark: &ProfileMark) {
        for (p, (calls, open, entries)) in self.profiles.iter_mut().zip(&mark.each) {
            let later: Vec<Call> = p.calls.drain((*calls).min(p.calls.len())..).collect();
            p.calls.extend(later.into_iter().filter(|c| c.core != k));
            p.open[k].clone_from(open);
            p.entries[k] = *entries;
        }
        self.active[k] = mark.active;
        self.returns_index(k);
    }

    /// Both cores were reset (`machine/reset.rs`): their open calls never return and are
    /// dropped; completed calls and entries stay.
    pub(crate) fn cores_reset(&mut self) {
        for p in &mut self.profiles {
            p.open = Default::default();
        }
        self.active = [u64::MAX; 2];
        self.returns_index(0);
        self.returns_index(1);
    }
}
