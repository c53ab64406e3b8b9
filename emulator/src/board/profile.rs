//! Profiling: every call of a function, or every activation of an exception handler, with
//! its cycles, on both cores.

use super::*;
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
pub(super) struct Profile {
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
    pub(super) fn is_open(&self) -> bool {
        self.open.iter().any(|o| !o.is_empty())
    }

    /// Times each core reached the entry.
    pub(super) fn entries(&self) -> [u64; 2] {
        self.entries
    }

    /// Counts `more` entries on each core (`rest.rs`: periods skipped).
    pub(super) fn add_entries(&mut self, more: [u64; 2]) {
        for (e, m) in self.entries.iter_mut().zip(more) {
            *e = e.wrapping_add(m);
        }
    }
}

/// An open call: (return address or exception number, SP at entry, start cycle).
type Open = (Return, u32, u64);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Return {
    To(u32),
    FromException(u32),
}

/// An unused slot of a watch set ([`Board::watch_set`]): odd, so no PC equals it.
pub(super) const NO_WATCH: u32 = 1;

/// Most addresses the fast path watches for profiling ([`Board::watch_set`]).
pub(super) const WATCH_SLOTS: usize = 8;

/// Both cores' watch sets when nothing is watched.
pub(super) static NO_WATCHES: [[u32; WATCH_SLOTS]; 2] = [[NO_WATCH; WATCH_SLOTS]; 2];

impl Board {
    /// A new profile of the code at `addr` (Thumb bit ignored); its handle.
    pub(super) fn add_profile(&mut self, addr: u32, handler_only: bool) -> usize {
        self.profiled_active = [u64::MAX; 2];
        self.watch_free &= handler_only;
        self.profiles.push(Profile {
            entry: addr & !1,
            handler_only,
            open: [Vec::new(), Vec::new()],
            calls: Vec::new(),
            entries: [0; 2],
        });
        self.profile_index();
        self.profiles.len() - 1
    }

    /// Starts measuring every call of the function at `addr` (Thumb bit ignored) on both
    /// cores; see [`Board::calls`]. Returns a handle.
    pub fn profile_addr(&mut self, addr: u32) -> usize {
        self.add_profile(addr, false)
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
        self.add_profile(addr, true)
    }

    /// Starts measuring the function named `name`.
    pub fn profile(&mut self, name: &str) -> Result<usize, EmuError> {
        let addr = self.symbol(name)?;
        Ok(self.profile_addr(addr))
    }

    /// The completed calls of profiled function `handle`.
    pub fn calls(&self, handle: usize) -> &[Call] {
        self.profiles.get(handle).map_or(&[], |p| &p.calls)
    }

    /// How many times the entry of profiled address `handle` has been reached (0 for an
    /// unknown handle). Unlike [`Board::calls`], which completes a call when control returns
    /// to the link register it was entered with, this counts a block that is not a function
    /// (a code generator's `BL` long branches change LR inside one) at the moment it runs.
    pub fn entries(&self, handle: usize) -> u64 {
        self.profiles
            .get(handle)
            .map_or(0, |p| p.entries[0] + p.entries[1])
    }

    /// Forgets the completed calls of profiled function `handle` (read them with
    /// [`Board::calls`] first); measuring continues. Long runs call this now and then so the
    /// record does not grow without bound. An unknown handle is ignored.
    pub fn clear_calls(&mut self, handle: usize) {
        if let Some(p) = self.profiles.get_mut(handle) {
            p.calls.clear();
        }
    }

    /// After an instruction (or exception entry or return) of core `k`: opens and closes
    /// the profiled calls it began or ended. The common case, a PC the filter rules out
    /// with the core's active exceptions unchanged, costs its caller a few instructions;
    /// the rest is [`Board::profile_step_slow`].
    #[inline(always)]
    pub(super) fn profile_step(&mut self, k: usize) {
        let core = &self.cores[k];
        let pc = core.r[15];
        if self.profiled_active[k] == core.nvic.active
            && self.profile_filter[k][(pc as usize >> 7) & 63] >> ((pc >> 1) & 63) & 1 == 0
        {
            return;
        }
        self.profile_step_slow(k);
    }

    #[inline(never)]
    fn profile_step_slow(&mut self, k: usize) {
        let core = &self.cores[k];
        let (pc, sp, now) = (core.r[15], core.r[13], core.cycle);
        // The core's active exceptions as at this core's last call, and the PC neither a
        // profiled entry nor the return address of an innermost open call: no activation
        // can open or close (an open one closes when its exception's active bit clears or
        // at its return address; one opens at an entry), so the loop below would do
        // nothing. (`profile_step` has returned already where the filter rules the PC out.)
        if self.profiled_active[k] == core.nvic.active
            && self.profile_entries.binary_search(&pc).is_err()
            && !self.profile_returns[k].contains(&pc)
        {
            return;
        }
        self.profiled_active[k] = core.nvic.active;
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
            self.profile_returns_index(k);
        }
    }

    /// Rebuilds the sorted profiled entries and both cores' return addresses, filters and
    /// watch sets ([`Board::profile_returns_index`]) from the profiles and their open calls.
    fn profile_index(&mut self) {
        let mut entries = std::mem::take(&mut self.profile_entries);
        entries.clear();
        entries.extend(self.profiles.iter().map(|p| p.entry));
        entries.sort_unstable();
        entries.dedup();
        self.profile_entries = entries;
        self.profile_returns_index(0);
        self.profile_returns_index(1);
    }

    /// Rebuilds core `k`'s `profile_returns`, `profile_filter` and `profile_watch` (the
    /// profiled entries are as they were).
    fn profile_returns_index(&mut self, k: usize) {
        let mut returns = std::mem::take(&mut self.profile_returns[k]);
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
        for &a in self.profile_entries.iter().chain(&returns) {
            filter[(a as usize >> 7) & 63] |= 1 << ((a >> 1) & 63);
        }
        self.profile_filter[k] = filter;
        self.profile_returns[k] = returns;
        self.profile_watch[k] = watch;
    }

    /// The addresses at which core `k`'s fast path must stop for [`Board::profile_step`]
    /// (unused slots hold 1, which no PC equals), or `None` when there are too many. After
    /// any other instruction of the fast path `profile_step` would do nothing: no call can
    /// start (the PC is no profiled entry) and none can end (the PC is not the return
    /// address of the innermost open call, and a call ending with an exception return
    /// leaves the fast path anyway).
    #[inline(always)]
    pub(super) fn watch_set(&self, k: usize) -> Option<[u32; WATCH_SLOTS]> {
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
    pub(super) fn watch_sets<'a>(
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
    pub(super) fn watched(&self, k: usize) -> Option<[u32; WATCH_SLOTS]> {
        self.profile_watch[k]
    }
}

/// Core `k`'s part of every profile at some moment ([`Board::profile_mark`]): what undoing
/// its steps since then restores.
#[derive(Default)]
pub(super) struct ProfileMark {
    /// Per profile: completed calls then, core `k`'s open calls, core `k`'s entries.
    each: Vec<(usize, Vec<Open>, u64)>,
    active: u64,
}

impl Board {
    /// Core `k`'s part of every profile now, into `mark` (its vectors reused: a window
    /// marks both cores every time).
    pub(super) fn profile_mark(&self, k: usize, mark: &mut ProfileMark) {
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
        mark.active = self.profiled_active[k];
    }

    /// Undoes core `k`'s profiling since `mark`: its calls completed since then are
    /// forgotten (the other core's stay, in their order), its open calls, entries and
    /// active exceptions are as they were.
    pub(super) fn profile_restore(&mut self, k: usize, mark: &ProfileMark) {
        for (p, (calls, open, entries)) in self.profiles.iter_mut().zip(&mark.each) {
            let later: Vec<Call> = p.calls.drain((*calls).min(p.calls.len())..).collect();
            p.calls.extend(later.into_iter().filter(|c| c.core != k));
            p.open[k].clone_from(open);
            p.entries[k] = *entries;
        }
        self.profiled_active[k] = mark.active;
        self.profile_returns_index(k);
    }
}
