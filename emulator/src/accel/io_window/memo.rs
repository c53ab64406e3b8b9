//! **The period memo.** A firmware's windows are its sample periods (a window ends at the
//! SysTick event), and its I/O does the same thing every period but for its data (the ADC
//! codes it samples, the DAC frames it moves, the results it writes): its *control* comes
//! back to a handful of states at the tick (the ring of results buffers, the PIO clock
//! divider's phase, a period of 3,015 or 3,016 cycles), busy keys or not. So a replay is
//! recorded once per control state with *lanes* ([`crate::lanes`]: the I/O run stepwise,
//! every bit of its data tagged with the input it comes from — a data word of the machine
//! at the start, or an SRAM word the DMA read — through every move the PIOs, the DMA and
//! the parts make), and a later window from the same control state takes the recorded
//! effect with its own data, by the routes. The recording then runs the I/O on to the
//! window's end (lazily run or not, the machine's state is the same).
//!
//! The key, none of it data: the I/O at the window's start, its cycles moved to the memo's
//! time base ([`Rebase`]), compared but for its data words ([`ReplayState::eq_but_data`]) and its
//! parts' records; the window's end; the cores' register stores (cycles from the start,
//! addresses, values); whether the DMA may read flash; the board's own banks; and the
//! *constraints*: the bits of data that decided something in the recording (a `JMP` on
//! X, a part decoding its command or a DAC frame's address) must be what they were — the
//! data words at the start checked first, each SRAM word the DMA reads when it reads it.
//! The cores' SRAM accesses are not in the key: the DMA wins every bank, so what it does
//! does not depend on them. A hit does, in the lock-step order, the DMA's SRAM reads (the
//! inputs) and writes (their values by their routes) and the cores' logged accesses, each
//! access checked against the recorded bank claims (a core's access in a cycle the DMA
//! claims its bank undoes the window: *wait*) and each load against what the lock-step run
//! would load (*stale*); then the I/O becomes the recorded end but for its data words,
//! which keep their values where they end as they started and take their routes'
//! elsewhere, and the parts' records are appended, their codes by their routes. A
//! recording that breached a part's timing, read ROM or flash, or whose constraints
//! contradict each other is not kept.
//!
//! The recordings are shared by every board of the process (the boards of a keyboard run
//! the same drivers: one board's recording serves all, since its key is the whole state it
//! stands for), each board keeping the entries it uses. Counts:
//! [`IoWindows::memo_hits`], [`IoWindows::memo_recorded`], [`IoWindows::memo_shared`];
//! [`Board::set_io_memo`] turns it off.
//!
//! **Links.** Each entry keeps the entries that gave the window after one of its own, the
//! last first: a window is tried against those first, and while the I/O is untouched since
//! the entry's hit ([`Io::touches`]: a change but for data counts, the host's codes through
//! [`Board::set_adc_code`] do not) it is known to start where the entry ends but for data,
//! so their comparison with the machine is left out. A link is made only from a window
//! known so (a window that merely matched an entry after the I/O was touched says nothing
//! of where the last entry ended: linking it made a later untouched window take an entry
//! whose start was not its own, `tests/io_windows.rs`,
//! `data_set_between_hits_is_the_lock_steps`).
//!
//! **The lazy end.** Making the machine the entry's end (its control state moved to the
//! window's cycles, its data words set by their routes) was half of a hit's cost, and until
//! the next window nothing but the period memo looks at the machine. So where the parts
//! keep no records (`tactus play` without an I/O trace), a hit leaves the end behind
//! ([`System::io_lazy`]: the entry's end, the move back to the window's time base, and
//! every data word in a flat list, those the routes give written, those with no place in
//! the end 0) and the live machine stale. The next window's hit reads its data words from
//! the list and leaves its own end; [`Board::set_adc_code`] writes the list. Anything else
//! — an advance past the end, a register access, a rest point, a recording, the host's
//! [`Board::io`] — first makes the live machine the end ([`System::io_unlazy`], which
//! counts as no change: the machine was that since the hit), and what needs only its
//! control state (the registers it accepts, the DMA's priority and reach) reads the end's
//! ([`System::io_control`]). The demo on `rp2040_io`: 19.11 → 18.46 G host instructions;
//! `tests/io_windows.rs` runs boards with and without it against the lock-step run.
//!

use super::*;
use crate::replay::ReplayState;

/// The period memo (module documentation): the replays recorded, at most
/// [`MEMO_ENTRIES`], the oldest replaced first once it is full.
pub(crate) struct IoMemo {
    /// Whether replays are looked up and recorded.
    pub(crate) on: bool,
    pub(super) entries: Vec<Arc<MemoEntry>>,
    /// Per entry, the entries a window after its window took, the last taken first (at
    /// most [`FOLLOWERS`]; `usize::MAX` none): each starts where the entry ends but for
    /// data (a link made only where the I/O was compared, or untouched since), so they
    /// are tried first, without comparing the I/O while it is untouched.
    pub(super) follow: Vec<[usize; FOLLOWERS]>,
    /// The entry the next one replaces once the memo is full.
    pub(super) next: usize,
    /// The entry the last window's replay was: the next window tries first the one that
    /// followed it last time.
    pub(super) last: Option<usize>,
    /// The I/O's [`Io::touches`] as that replay left it: while they are the same, the I/O is
    /// that entry's end but for its data, so the entry that followed it (`follow`, set only
    /// where the I/O was compared) starts where it is.
    pub(super) after: Option<(u64, u64)>,
    /// A hit's inputs: the data words its routes read, then the words the DMA reads.
    pub(super) inputs: Vec<u32>,
    /// Whether a hit may leave its end behind instead of making it (module documentation,
    /// "The lazy end"); on by default.
    pub(super) lazy: bool,
    /// Per entry, its plans (module documentation, "Plans"), and whether hits may use them
    /// (on by default).
    pub(super) plans: Vec<Plans>,
    pub(super) planned: bool,
    /// A planned hit's values of the DMA's accesses, by op, and the window's shape.
    pub(super) values: Vec<u32>,
    pub(super) shape: Vec<u64>,
}

impl IoMemo {
    /// Entry `i` gave (or recorded) the window after the last one's, which left the I/O's
    /// touches at `after`; `linked` when the window's start is known to have been the last
    /// entry's end (compared, or not touched since).
    pub(super) fn followed_by(&mut self, i: usize, linked: bool, after: Option<(u64, u64)>) {
        // A link is the two entries' (the second starts where the first ends): a window
        // not known to follow leaves the links there are.
        if let (true, Some(f)) = (linked, self.last.and_then(|l| self.follow.get_mut(l))) {
            let at = f.iter().position(|&x| x == i).unwrap_or(FOLLOWERS - 1);
            f.copy_within(0..at, 1);
            f[0] = i;
        }
        self.last = Some(i);
        self.after = after;
    }

    /// Keeps `e` (the oldest replaced once the memo is full); returns its index.
    pub(super) fn keep(&mut self, e: Arc<MemoEntry>) -> usize {
        if self.entries.len() < MEMO_ENTRIES {
            self.entries.push(e);
            self.follow.push([usize::MAX; FOLLOWERS]);
            self.plans.push(Plans::default());
            return self.entries.len() - 1;
        }
        let at = self.next;
        self.entries[at] = e;
        self.plans[at] = Plans::default();
        // No link leads to the entry replaced, nor from it.
        for f in self.follow.iter_mut().flatten() {
            if *f == at {
                *f = usize::MAX;
            }
        }
        self.follow[at] = [usize::MAX; FOLLOWERS];
        if self.last == Some(at) {
            self.last = None;
        }
        self.next = (self.next + 1) % MEMO_ENTRIES;
        at
    }
}

impl Default for IoMemo {
    fn default() -> Self {
        IoMemo {
            on: true,
            entries: Vec::new(),
            follow: Vec::new(),
            next: 0,
            last: None,
            after: None,
            inputs: Vec::new(),
            lazy: true,
            plans: Vec::new(),
            planned: true,
            values: Vec::new(),
            shape: Vec::new(),
        }
    }
}

/// The most replays the period memo keeps per board (a board's I/O comes back to a
/// handful of control states at its ticks, whatever its keys do; more entries cover the
/// start-up and the rare constraint that data breaks).
pub(super) const MEMO_ENTRIES: usize = 64;

/// The most entries kept as following an entry ([`IoMemo::follow`]): a control state's
/// next window can take one of a few (the data decides), each tried before the others.
pub(super) const FOLLOWERS: usize = 4;

/// The process's store of recorded replays, shared by every board (module documentation):
/// the boards of a keyboard run the same drivers, and an entry's key is the whole state it
/// stands for, so a replay one board recorded serves the others. At most [`SHARED_ENTRIES`],
/// the oldest replaced first.
pub(super) static SHARED: Mutex<Vec<Arc<MemoEntry>>> = Mutex::new(Vec::new());

/// The most replays the process's store keeps.
pub(super) const SHARED_ENTRIES: usize = 512;

/// One recorded replay (module documentation, "The period memo"): its key, and what it did
/// as routes from its inputs. Cycles are counted from the I/O's cycle at the window's start.
pub(super) struct MemoEntry {
    /// The window's end, whether the DMA may read flash ([`System::xip_answers`]), and the
    /// board's own banks (`Config::own_banks`, which a replay's checks read).
    pub(super) span: u64,
    pub(super) xip: bool,
    pub(super) own: u8,
    /// Whether the parts kept records while it was recorded (else `records` is empty, and
    /// it gives no board that keeps them a window: [`Probe::keeps`]).
    pub(super) with_records: bool,
    /// Each core's register stores: their cycles from the start, addresses and values.
    pub(super) regs: [Vec<IoAccess>; 2],
    /// The I/O at the window's start at [`Rebase::MEMO`], its records left out and its data
    /// words ([`Io::data_slots`]) 0; its [`Io::quick_key`].
    pub(super) start: Box<Io>,
    pub(super) start_key: u64,
    /// What the data words at the start must hold: (slot, mask, bits).
    pub(super) start_fixed: Vec<(u32, Option<Slot>, u32, u32)>,
    /// The number of data words (the first read's input), and those the routes read (with
    /// where they lie: [`Io::locate`]).
    pub(super) slots: u32,
    pub(super) needs: Vec<(u32, Option<Slot>)>,
    /// The DMA's SRAM accesses in their ticks' order.
    pub(super) ops: Vec<MemoOp>,
    /// The DMA's bank claims: (cycle, bank), sorted; and per cycle a bit set when the DMA
    /// claims some bank then (the common test: most cycles have none).
    pub(super) claims: Vec<(u64, u8)>,
    pub(super) claimed: Vec<u64>,
    /// Per cycle from the start through the last claim or access of the DMA's: the number
    /// of its accesses at or before it (low byte) and the banks it claims in it (high
    /// byte), for a window's shape ([`shape_of`]; empty for an entry of more than 255
    /// accesses, which no plan serves).
    pub(super) at_cycle: Vec<u16>,
    /// The cycle the I/O was run to: a core's access at or after it is not replayed here.
    pub(super) ran_to: u64,
    /// The I/O at the end at [`Rebase::MEMO`] without its records, and the routes of its
    /// data words but those that end as they started (a hit keeps those): (data slot, where
    /// it lies, route).
    pub(super) end: Arc<EndState>,
    pub(super) patches: Vec<(u32, Option<Slot>, Route)>,
    /// Of the data words a hit sets, those whose route is a constant: (data slot, where it
    /// lies, value).
    pub(super) const_patches: Vec<(u32, Option<Slot>, u32)>,
    /// The parts' records, and the routes of their codes (per ADC its frames', per DAC its
    /// updates').
    pub(super) records: IoRecords,
    pub(super) frame_routes: Vec<Vec<Route>>,
    pub(super) update_routes: Vec<Vec<Route>>,
}

impl MemoEntry {
    /// Gives `set` each data word a hit sets, with its value for `inputs` (the hit's data
    /// words and DMA reads): (data slot, where it lies, value).
    #[inline]
    pub(super) fn patch(&self, inputs: &[u32], mut set: impl FnMut(u32, Option<Slot>, u32)) {
        for &(i, at, v) in &self.const_patches {
            set(i, at, v);
        }
        for (i, at, r) in &self.patches {
            set(*i, *at, r.eval(inputs));
        }
    }
}

/// One SRAM access of the DMA in a [`MemoEntry`]: at its tick (from the start), `size`
/// bytes at SRAM offset `off`.
pub(super) struct MemoOp {
    pub(super) tick: u64,
    pub(super) off: u32,
    pub(super) size: u8,
    pub(super) kind: MemoOpKind,
}

/// A [`MemoOp`]'s direction.
pub(super) enum MemoOpKind {
    /// A read: the next input, whose bits under `mask` must be `value` (they decided
    /// something).
    Read { mask: u32, value: u32 },
    /// A write, its value by `route`.
    Write { route: Route },
}

/// [`MemoEntry::at_cycle`] for the DMA's accesses `ops` (in their ticks' order) and
/// claims `claims` (cycle, bank), both from the start.
pub(super) fn at_cycle(ops: &[MemoOp], claims: &[(u64, u8)]) -> Vec<u16> {
    let last = (ops.iter().map(|op| op.tick))
        .chain(claims.iter().map(|c| c.0))
        .max()
        .unwrap_or(0);
    if ops.len() > 255 || last >= 1 << 20 {
        return Vec::new();
    }
    let mut t = vec![0u16; last as usize + 1];
    let mut pos = 0;
    for (c, x) in t.iter_mut().enumerate() {
        while ops.get(pos).is_some_and(|op| op.tick <= c as u64) {
            pos += 1;
        }
        *x = pos as u16;
    }
    for &(c, b) in claims {
        if let Some(x) = t.get_mut(c as usize) {
            *x |= 1 << (8 + u32::from(b));
        }
    }
    t
}

/// What a window brings to the period memo's lookup: its end (from `base`, the I/O's
/// cycle at its start), whether the DMA may read flash, the board's own banks, its last
/// logged access's cycle, and the live machine's [`Io::quick_key`] once a comparison needs
/// it.
pub(super) struct Probe {
    pub(super) span: u64,
    pub(super) xip: bool,
    pub(super) own: u8,
    /// Whether the machine's parts keep records (frames, updates): an entry recorded where
    /// they kept none has none to give.
    pub(super) keeps: bool,
    pub(super) base: u64,
    pub(super) last: u64,
    pub(super) key: std::cell::OnceCell<u64>,
}

impl Probe {
    /// Whether entry `e` stands for the window whose logs are `logs`, its I/O `now`: the
    /// key's parts equal, the machine equal to the entry's start at the memo's time base but
    /// for its data words, which meet the entry's constraints (module documentation).
    ///
    /// With `known`, the machine is known to be equal but for data (the entry that followed
    /// the last one's, the machine untouched since): that comparison is left out.
    pub(super) fn fits(
        &self,
        e: &MemoEntry,
        now: View,
        logs: &[Vec<IoAccess>; 2],
        known: bool,
    ) -> bool {
        let base = self.base;
        // The register stores against the entry's, core by core.
        let regs = || {
            logs.iter().zip(&e.regs).all(|(log, theirs)| {
                let mut mine = log.iter().filter(|a| a.kind == IoKind::Reg);
                (theirs.iter()).all(|r| mine.next().is_some_and(|a| a.since(base) == *r))
                    && mine.next().is_none()
            })
        };
        let to_memo = Rebase {
            from: base,
            to: Rebase::MEMO,
        };
        e.span == self.span
            && e.xip == self.xip
            && e.own == self.own
            && (e.with_records || !self.keeps)
            && self.last.wrapping_sub(base) < e.ran_to
            && (known || {
                let View::Live(now) = now else {
                    return false;
                };
                e.start_key == *self.key.get_or_init(|| now.quick_key(to_memo))
            })
            && regs()
            && (known || matches!(now, View::Live(now) if now.eq_but_data(&e.start, to_memo)))
            && (!known || {
                if let View::Live(now) = now {
                    debug_assert!(now.eq_but_data(&e.start, to_memo), "an untouched I/O moved");
                }
                true
            })
            && (e.start_fixed.iter()).all(|&(i, at, m, v)| now.slot(i, at) & m == v)
    }
}

/// The I/O as the period memo sees it: the live machine, or the one a hit left behind
/// (module documentation, "The lazy end"), whose data words it reads.
#[derive(Clone, Copy)]
pub(super) enum View<'a> {
    Live(&'a Io),
    Lazy(&'a LazyEnd),
}

impl View<'_> {
    /// The I/O of `sys` (`None` without one).
    pub(super) fn of(sys: &System) -> Option<View<'_>> {
        match sys.io_lazy.as_deref() {
            Some(l) => Some(View::Lazy(l)),
            None => sys.io.as_deref().map(View::Live),
        }
    }

    /// Data slot `i` ([`Io::data_slots`]' order), which lies at `at` ([`Io::locate`]).
    #[inline]
    pub(super) fn slot(self, i: u32, at: Option<Slot>) -> u32 {
        match self {
            View::Live(io) => io.slot_at(at),
            View::Lazy(l) => l.data.get(i as usize).copied().unwrap_or(0),
        }
    }
}

/// How a try of the period memo ended.
pub(super) enum Tried {
    /// No entry fits: the replay is run (and recorded).
    Miss,
    /// An entry gave the replay, or the window is undone for the reason given.
    Done(Result<(), Violation>),
}

/// A hit's inputs for entry `e` into `inputs`: the data words its routes read (the others
/// 0), up to the first DMA read's.
#[inline]
pub(super) fn data_inputs(sys: &System, e: &MemoEntry, inputs: &mut Vec<u32>) {
    inputs.clear();
    inputs.resize(e.slots as usize, 0);
    if let Some(io) = View::of(sys) {
        for &(s, at) in &e.needs {
            inputs[s as usize] = io.slot(s, at);
        }
    }
}

/// A period memo hit's DMA access `op`: a read checks its constraint and becomes the next
/// input, a write stores its route's value (journaled, as [`System::io_dma_write`]).
/// False when a read breaks its constraint (the entry does not stand for the window).
pub(super) fn dma_op(sys: &mut System, op: &MemoOp, inputs: &mut Vec<u32>) -> bool {
    let size = u32::from(op.size);
    match op.kind {
        MemoOpKind::Read { mask, value } => {
            let v = load_le(&sys.sram, op.off as usize, size);
            if v & mask != value {
                return false;
            }
            inputs.push(v);
        }
        MemoOpKind::Write { ref route } => {
            sys.io_dma_write(op.off, size, route.eval(inputs), true);
        }
    }
    true
}

impl Drive<'_> {
    /// The replay through the period memo (module documentation): a hit does what the
    /// recorded replay did with its own data; a miss checkpoints the I/O into `io`,
    /// replays with lanes, runs the I/O to the window's `end` and records.
    pub(super) fn io_memo_replay(
        &mut self,
        logs: &[Vec<IoAccess>; 2],
        banks: u8,
        own: u8,
        end: u64,
        io: &mut Option<Checkpoint>,
    ) -> Result<(), Violation> {
        if self.m.system.io.is_none() {
            self.io_take_back(logs);
            return self.io_merge(logs, banks, own);
        }
        // A machine held behind (an advance that did not settle) is settled first: the
        // memo's states are settled ones. The stores are taken back before the advance
        // unless it runs nothing (a machine not behind, advanced to its own cycle), and the
        // hit's plans are then left out.
        let (base, back) = match (
            self.m.system.io_lazy.as_deref(),
            self.m.system.io.as_deref(),
        ) {
            (Some(l), _) => (l.cycle(), l.end.io.is_behind()),
            (None, io) => (io.map_or(0, Io::cycle), io.is_none_or(Io::is_behind)),
        };
        if back {
            self.io_take_back(logs);
        }
        self.m.system.io_advance_to(base, true);
        if let Tried::Done(r) = self.io_memo_hit(logs, base, end, own, back) {
            return r;
        }
        if !back {
            self.io_take_back(logs);
        }
        self.io_memo_record(logs, banks, own, base, end, io)
    }

    /// Looks the window up in the period memo, its I/O at `base` (settled) and its end at
    /// `end`: the entries whose key the window's start meets, this board's first (the one
    /// that followed the last first), then the process's store; each tried in turn until
    /// one's replay goes through (a word the DMA reads may break its constraints part-way:
    /// what that try wrote is undone). `back`: the stores are taken back already
    /// ([`Board::io_take_back`]); else the SRAM is as the cores' run left it, which a plan
    /// takes (module documentation, "Plans"), and the stores are taken back before a try
    /// without one. A miss leaves the SRAM as it found it.
    pub(super) fn io_memo_hit(
        &mut self,
        logs: &[Vec<IoAccess>; 2],
        base: u64,
        end: u64,
        own: u8,
        back: bool,
    ) -> Tried {
        let keeps = (self.m.system.io.as_deref_mut()).is_some_and(|io| !io.records_full());
        let Some(now) = self.m.system.io.as_deref() else {
            return Tried::Miss;
        };
        // The live machine's count of changes: a lazy end leaves it as its hit found it.
        let touches = now.touches();
        let probe = Probe {
            span: end.saturating_sub(base),
            xip: self.m.system.xip_answers,
            own,
            keeps,
            base,
            last: logs.iter().flatten().map(|a| a.cycle).max().unwrap_or(base),
            key: std::cell::OnceCell::new(),
        };
        #[cfg(debug_assertions)]
        for e in &self.a.io_memo.entries {
            if e.span == probe.span && crate::io::events::check_this_skip() {
                let r = Rebase {
                    from: base,
                    to: Rebase::MEMO,
                };
                let mut live = now.clone();
                if let Some(l) = self.m.system.io_lazy.as_deref() {
                    live.become_lazy(l);
                }
                live.check_eq_but_data(&e.start, r);
            }
        }
        let memo = &self.a.io_memo;
        let first = (memo.last)
            .and_then(|l| memo.follow.get(l).copied())
            .unwrap_or([usize::MAX; FOLLOWERS]);
        let followers = first.iter().copied().filter(|&f| f != usize::MAX);
        let untouched = memo.after.is_some() && memo.after == Some(touches);
        let n = memo.entries.len();
        let mut shared = None;
        let mark = self.m.system.io_journal.as_ref().map_or(0, Vec::len);
        for i in followers.chain((0..n).filter(|j| !first.contains(j))) {
            let known = untouched && first.contains(&i);
            if !known {
                // Compared with the entry's start: the live machine.
                self.m.system.io_unlazy();
            }
            let fits = match (View::of(&self.m.system), self.a.io_memo.entries.get(i)) {
                (Some(now), Some(e)) => probe.fits(e, now, logs, known),
                _ => false,
            };
            if !fits {
                continue;
            }
            let e = Arc::clone(&self.a.io_memo.entries[i]);
            if !back && self.io_memo_planned(i, &e, logs, &probe) {
                self.io_memo_followed_by(i, untouched);
                return Tried::Done(Ok(()));
            }
            // A miss undoes the try's writes, the taking back among them.
            if !back {
                self.io_take_back(logs);
            }
            if let Some(r) = self.io_memo_try(&e, logs, &probe, mark) {
                self.io_memo_followed_by(i, untouched);
                return Tried::Done(r);
            }
        }
        // Another board's recordings, from the process's store.
        self.m.system.io_unlazy();
        if let Some(now) = self.m.system.io.as_deref() {
            let mine = &self.a.io_memo.entries;
            shared = SHARED.lock().ok().map(|s| {
                (s.iter())
                    .filter(|e| {
                        probe.fits(e, View::Live(now), logs, false)
                            && !mine.iter().any(|m| Arc::ptr_eq(m, e))
                    })
                    .cloned()
                    .collect::<Vec<_>>()
            });
        }
        for e in shared.into_iter().flatten() {
            if !back {
                self.io_take_back(logs);
            }
            if let Some(r) = self.io_memo_try(&e, logs, &probe, mark) {
                self.a.io_windows.memo_shared += 1;
                let i = self.a.io_memo.keep(e);
                self.io_memo_followed_by(i, untouched);
                return Tried::Done(r);
            }
        }
        Tried::Miss
    }

    /// One try of entry `e` for the window `probe` brings ([`Board::io_memo_apply`]): what
    /// became of the window, or `None` when a word the DMA reads broke its constraints —
    /// then the SRAM writes journaled since `mark` are undone.
    pub(super) fn io_memo_try(
        &mut self,
        e: &MemoEntry,
        logs: &[Vec<IoAccess>; 2],
        probe: &Probe,
        mark: usize,
    ) -> Option<Result<(), Violation>> {
        match self.io_memo_apply(e, logs, probe) {
            Tried::Done(r) => Some(r),
            Tried::Miss => {
                if let Some(j) = self.m.system.io_journal.as_mut() {
                    let undo: Vec<u64> = j.drain(mark.min(j.len())..).collect();
                    self.m.system.undo_stores(&undo);
                }
                None
            }
        }
    }

    /// Entry `i` gave (or recorded) this window ([`IoMemo::followed_by`]), the I/O's
    /// touches now where it left them.
    pub(super) fn io_memo_followed_by(&mut self, i: usize, linked: bool) {
        let after = self.m.system.io.as_deref().map(Io::touches);
        self.a.io_memo.followed_by(i, linked, after);
    }

    /// Does the replay entry `e` recorded, with the window's data (module documentation):
    /// `Miss` when a word the DMA reads breaks its constraints (the caller undoes what it
    /// wrote), else what became of the window.
    pub(super) fn io_memo_apply(
        &mut self,
        e: &MemoEntry,
        logs: &[Vec<IoAccess>; 2],
        probe: &Probe,
    ) -> Tried {
        let base = probe.base;
        // The inputs: the data words the entry's routes read, then the DMA's reads.
        let inputs = &mut self.a.io_memo.inputs;
        data_inputs(&self.m.system, e, inputs);
        for step in Order::new(&e.ops, logs, base) {
            let (k, i) = match step {
                Step::Dma(j) => match e.ops.get(j) {
                    Some(op) if dma_op(&mut self.m.system, op, inputs) => continue,
                    _ => return Tried::Miss,
                },
                Step::Core(k, i) => (k, i),
            };
            let a = &logs[k][i];
            let at = a.cycle.wrapping_sub(base);
            let bank = sram_bank(a.addr) as u8;
            let some = (e.claimed.get((at / 64) as usize)).is_some_and(|w| w >> (at % 64) & 1 != 0);
            if some && e.claims.binary_search(&(at, bank)).is_ok() {
                return Tried::Done(Err(Violation::Wait));
            }
            if a.kind == IoKind::Store {
                sram_put(&mut self.m.system, a.addr, a.size, a.value);
            } else if load_le(&self.m.system.sram, a.addr as usize, a.size.into()) != a.value {
                return Tried::Done(Err(Violation::Stale));
            }
        }
        self.io_memo_end(e, probe)
    }

    /// A hit's end, its SRAM accesses done with [`IoMemo::inputs`]: the entry's end, its
    /// data words and the parts' records by their routes. Where the parts keep no records,
    /// left behind (module documentation, "The lazy end").
    pub(super) fn io_memo_end(&mut self, e: &MemoEntry, probe: &Probe) -> Tried {
        let inputs = std::mem::take(&mut self.a.io_memo.inputs);
        let r = self.io_memo_end_with(e, &inputs, probe);
        self.a.io_memo.inputs = inputs;
        r
    }

    /// [`Board::io_memo_end`] with the inputs taken out of the memo.
    pub(super) fn io_memo_end_with(
        &mut self,
        e: &MemoEntry,
        inputs: &[u32],
        probe: &Probe,
    ) -> Tried {
        let to_memo = Rebase {
            from: probe.base,
            to: Rebase::MEMO,
        };
        let Some(now) = self.m.system.io.as_mut() else {
            return Tried::Miss;
        };
        if self.a.io_memo.lazy && !probe.keeps {
            // The last hit's end reused (its box and list), else one made from the machine.
            let mut l = match self.m.system.io_lazy.take() {
                Some(mut l) => {
                    l.end = Arc::clone(&e.end);
                    l.back = to_memo.back();
                    l
                }
                None => {
                    let mut data = Vec::new();
                    now.data_words(&mut data);
                    Box::new(LazyEnd {
                        end: Arc::clone(&e.end),
                        back: to_memo.back(),
                        data,
                    })
                }
            };
            let data = &mut l.data;
            e.patch(inputs, |i, _, v| {
                if let Some(w) = data.get_mut(i as usize) {
                    *w = v;
                }
            });
            l.drop_absent();
            self.m.system.io_lazy = Some(l);
        } else {
            self.m.system.io_unlazy();
            let Some(now) = self.m.system.io.as_mut() else {
                return Tried::Miss;
            };
            let codes = RecordCodes {
                frames: &e.frame_routes,
                updates: &e.update_routes,
                inputs,
            };
            now.become_but_data(&e.end.io, to_memo.back(), &e.records, Some(codes));
            e.patch(inputs, |_, at, v| now.set_slot_at(at, v));
        }
        self.m.system.io_refresh();
        self.a.io_windows.memo_hits += 1;
        Tried::Done(Ok(()))
    }
}
