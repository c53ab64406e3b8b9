//! Windows on a board with converters (`crate::io`): the cores run ahead of the I/O, and
//! the I/O then replays the window against what they did.
//!
//! **When.** Only while the DMA wins every SRAM bank against both cores (BUS_PRIORITY,
//! [`crate::io::Io::dma_wins`]): its accesses then never wait for a core's, so what it
//! does depends on the cores only through the SRAM words it reads and the registers they
//! write. The I/O raises no interrupt line (its interrupts are not modelled), so a core
//! sees the I/O only through those words.
//!
//! **The cores' run.** At the window's start the I/O is run up to it (as a core's access
//! there would); the cores' run leaves it there, and the replay checkpoints it
//! ([`crate::io::Io::checkpoint`]) before it runs it. Each core then runs alone as in any
//! window, its accesses to the banks the DMA may reach (`L`, [`crate::bus::System::io_banks`]
//! at the start; of them its own) served as if no DMA were there, and logged: the
//! instruction's start cycle, the data phase, the SRAM offset, size, value and, for a
//! store, the word it overwrote ([`IoAccess`]). Native code does and logs single loads and
//! stores there (`jit::abi`'s `io_sram`, called before the access it then does as in any
//! of the core's banks); multiple transfers and exception frames take the general path,
//! whose bus (`board/window.rs`, `Confined`) logs the same, and no code is fetched from
//! `L`. A memoized call ([`crate::memo`]) recorded in such a window keeps its accesses to
//! `L` (cycles from its entry); a hit under the same `L` logs them at the hit's cycles,
//! each store with the word before the memo (the replay needs only the oldest version of a
//! word). A store to the DMA's or the PIOs' registers is logged instead of done (native
//! code's word stores through `jit::abi`'s `io_reg`; a load of them stops the core, as any
//! peripheral access). `tests/io_windows.rs` compares the logs of the two paths, window
//! by window ([`Board::check_io_logs`]).
//!
//! **The replay.** The logged stores are taken back to the words as they were before the
//! window; the two logs are merged in the lock-step order (the instruction that starts
//! first, core 0 on ties: `board/run.rs`) and each entry done as the lock-step bus does it
//! ([`crate::bus::System`]'s `io_sram`, `io_store`): for a bank the DMA may reach now, the
//! I/O run through the access's cycle without settling; a store's bytes written at its
//! place among the DMA's; a register store through the same code as the bus. The window is
//! undone — the replay's SRAM writes (journaled, the DMA's too), the I/O's clone, then the
//! cores as in any window — when the lock-step run would have differed:
//! - the DMA claims the bank in the access's cycle (the core would have waited: *wait*);
//! - a load finds another value than the core loaded (the DMA wrote the word before the
//!   core read it: *stale*);
//! - a register store refused, or making the DMA reach a bank of either core's that was not
//!   logged (*reach*).
//!
//! Otherwise every load returned what the lock-step run returns, every store and register
//! write happened in the same order among the DMA's accesses with the same I/O calls, so
//! registers, memory, cycles, stalls and the I/O come out as the lock-step run's. A DMA read
//! of a word a core stores later in the window sees the old word (the DAC frames the
//! firmware's DMA moves at the tick, before the handler writes the next ones), one after
//! the store the new. The I/O is left where the last logged access left it, as in
//! lock-step. Counts: [`Board::io_windows`].
//!
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
//! time base ([`Rebase`]), compared but for its data words ([`Io::eq_but_data`]) and its
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
//! **Plans.** A hit in the merged order took every logged store back, did the DMA's
//! accesses and the cores' in turn, and did each store again: some 4,000 host instructions
//! a window for what is, window after window, the same sequence. So a hit first works out,
//! once per entry and *shape* of the window's logs — per core each access's address, size
//! and kind and how many of the entry's DMA accesses come before it (those at or before
//! its cycle, [`MemoEntry::at_cycle`]) — where each DMA read takes its word from: the SRAM
//! as the cores' run left it (no core stores the word after the read), the word a core's
//! logged store overwrote (the first store to it after the read: the DAC frames the
//! firmware's DMA moves at the tick, before the handler writes the next ones), or an
//! earlier DMA write of the window; and which core loads read a word a DMA write wrote
//! before them (checked against it). A window of that shape then takes the plan: the DMA's
//! reads and their constraints, the writes' values by their routes, the checks, then the
//! writes in their order — the SRAM the merged replay leaves, since no word is both stored
//! by a core and written by the DMA nor accessed by both cores (a plan is not made for
//! such a shape), and a core access in a cycle the DMA claims its bank leaves the window to
//! the merged replay. A read or check that fails changes nothing: the merged replay then
//! finds what becomes of the window (a miss, stale, or kept). Once the checks pass
//! nothing fails, so the writes are not journaled (the one exception to the replay's
//! journal, which only undoes). The stores are taken back only for the merged replay, and
//! before the I/O's advance to the window's start when that runs anything (a machine held
//! behind: plans are then left out). In the demo on `rp2040_io` 317,111 of the 317,301
//! hits take a plan, nearly always the one the entry's last window took (tried first);
//! 18.43 → 18.05 G. That one is tried access by access against what its shape asks
//! ([`Fit`]: the address, size and kind, and the cycle within the stretch around the
//! recorded one that has the same shape word, worked out when the plan is made), with no
//! lookup in the entry's per-cycle table: 18.02 → 17.94 G. Where no DMA read takes an
//! earlier DMA write's word (the shipped drivers: the DAC frames are read at the tick, the
//! ADC results written later), a plan splits into its reads, then its writes ([`Split`]),
//! done without a match per step or a value kept per read: 17.65 → 17.49 G.
//! `tests/io_windows.rs` (`planned_hits_equal_the_lock_step`,
//! `a_hit_meets_the_dmas_claims_with_or_without_a_plan` and every comparison; their windows
//! take both split and unsplit plans) runs boards with and without plans against the
//! lock-step run.

use super::window::undo_stores;
use super::*;
use crate::bus::{load_le, sram_bank, store_le, ALL_BANKS};
use crate::io::{
    Checkpoint, EndState, Io, IoRecords, LaneOp, LaneRec, LazyEnd, Rebase, RecordCodes, Slot,
};
use crate::lanes::{self, Lane, Route};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// What a window's core access to the I/O is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum IoKind {
    /// A load from a bank the DMA may reach.
    Load,
    /// A store to a bank the DMA may reach.
    Store,
    /// A store to the DMA's or the PIOs' registers, not done yet.
    Reg,
}

/// One logged access (module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct IoAccess {
    /// The cycle at which the instruction (or exception entry) started: the lock-step order.
    pub(crate) start: u64,
    /// The data phase's cycle.
    pub(crate) cycle: u64,
    /// SRAM offset (loads, stores) or the register's address.
    pub(crate) addr: u32,
    /// The value loaded or stored (the bytes of `size`).
    value: u32,
    /// A store's word before it (the word at `addr & !3`).
    pub(crate) old: u32,
    size: u8,
    pub(crate) kind: IoKind,
}

impl IoAccess {
    /// The access of the instruction (or exception entry) that started at cycle `start`,
    /// its data phase at `cycle`: `size` bytes (1, 2 or 4) at SRAM offset or register
    /// address `addr`, `value` loaded or stored, `old` a store's word before it (else 0).
    pub(crate) fn new(
        start: u64,
        cycle: u64,
        kind: IoKind,
        addr: u32,
        size: u32,
        value: u32,
        old: u32,
    ) -> IoAccess {
        IoAccess {
            start,
            cycle,
            addr,
            value,
            old,
            size: size as u8,
            kind,
        }
    }

    /// The access with its cycles counted from `base` (a memo's time base).
    pub(crate) fn since(&self, base: u64) -> IoAccess {
        IoAccess {
            start: self.start.wrapping_sub(base),
            cycle: self.cycle.wrapping_sub(base),
            ..*self
        }
    }
}

/// The log a window's [`super::window`] bus writes for one core.
pub(super) struct IoLog<'a> {
    /// The banks the DMA may reach, `L`.
    pub banks: u8,
    /// The start cycle of the instruction being run.
    pub start: u64,
    pub log: &'a mut Vec<IoAccess>,
}

impl IoLog<'_> {
    /// Logs an access of the instruction being run; returns it.
    pub fn push(
        &mut self,
        cycle: u64,
        kind: IoKind,
        addr: u32,
        size: u32,
        value: u32,
        old: u32,
    ) -> IoAccess {
        let a = IoAccess::new(self.start, cycle, kind, addr, size, value, old);
        self.log.push(a);
        a
    }
}

/// What became of the windows of a board with an I/O ([`Board::io_windows`]); windows
/// undone because a core could not run confined are counted by
/// [`Board::run_ahead_windows`] only.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IoWindows {
    /// Replayed and kept.
    pub kept: u64,
    /// Undone: a core's access to a bank in a cycle the DMA claimed it.
    pub waited: u64,
    /// Undone: a core loaded a word the DMA wrote before the load.
    pub stale: u64,
    /// Undone: a register store refused, or one that let the DMA reach a bank whose
    /// accesses were not logged.
    pub reach: u64,
    /// Of the kept, those whose replay the period memo gave.
    pub memo_hits: u64,
    /// Replays recorded into the period memo.
    pub memo_recorded: u64,
    /// Replays the period memo took from the process's store, recorded by another board
    /// (module documentation).
    pub memo_shared: u64,
    /// Of the memo's hits, those a plan gave (module documentation, "Plans").
    pub memo_planned: u64,
}

impl std::ops::Add for IoWindows {
    type Output = IoWindows;

    /// Both counts together (a keyboard's boards summed).
    fn add(self, o: IoWindows) -> IoWindows {
        IoWindows {
            kept: self.kept + o.kept,
            waited: self.waited + o.waited,
            stale: self.stale + o.stale,
            reach: self.reach + o.reach,
            memo_hits: self.memo_hits + o.memo_hits,
            memo_recorded: self.memo_recorded + o.memo_recorded,
            memo_shared: self.memo_shared + o.memo_shared,
            memo_planned: self.memo_planned + o.memo_planned,
        }
    }
}

/// The period memo (module documentation): the replays recorded, at most
/// [`MEMO_ENTRIES`], the oldest replaced first once it is full.
pub(crate) struct IoMemo {
    /// Whether replays are looked up and recorded.
    pub(crate) on: bool,
    entries: Vec<Arc<MemoEntry>>,
    /// Per entry, the entries a window after its window took, the last taken first (at
    /// most [`FOLLOWERS`]; `usize::MAX` none): each starts where the entry ends but for
    /// data (a link made only where the I/O was compared, or untouched since), so they
    /// are tried first, without comparing the I/O while it is untouched.
    follow: Vec<[usize; FOLLOWERS]>,
    /// The entry the next one replaces once the memo is full.
    next: usize,
    /// The entry the last window's replay was: the next window tries first the one that
    /// followed it last time.
    last: Option<usize>,
    /// The I/O's [`Io::touches`] as that replay left it: while they are the same, the I/O is
    /// that entry's end but for its data, so the entry that followed it (`follow`, set only
    /// where the I/O was compared) starts where it is.
    after: Option<(u64, u64)>,
    /// A hit's inputs: the data words its routes read, then the words the DMA reads.
    inputs: Vec<u32>,
    /// Whether a hit may leave its end behind instead of making it (module documentation,
    /// "The lazy end"); on by default.
    lazy: bool,
    /// Per entry, its plans (module documentation, "Plans"), and whether hits may use them
    /// (on by default).
    plans: Vec<Plans>,
    planned: bool,
    /// A planned hit's values of the DMA's accesses, by op, and the window's shape.
    values: Vec<u32>,
    shape: Vec<u64>,
}

impl IoMemo {
    /// Entry `i` gave (or recorded) the window after the last one's, which left the I/O's
    /// touches at `after`; `linked` when the window's start is known to have been the last
    /// entry's end (compared, or not touched since).
    fn followed_by(&mut self, i: usize, linked: bool, after: Option<(u64, u64)>) {
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
    fn keep(&mut self, e: Arc<MemoEntry>) -> usize {
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
const MEMO_ENTRIES: usize = 64;

/// The most entries kept as following an entry ([`IoMemo::follow`]): a control state's
/// next window can take one of a few (the data decides), each tried before the others.
const FOLLOWERS: usize = 4;

/// The process's store of recorded replays, shared by every board (module documentation):
/// the boards of a keyboard run the same drivers, and an entry's key is the whole state it
/// stands for, so a replay one board recorded serves the others. At most [`SHARED_ENTRIES`],
/// the oldest replaced first.
static SHARED: Mutex<Vec<Arc<MemoEntry>>> = Mutex::new(Vec::new());

/// The most replays the process's store keeps.
const SHARED_ENTRIES: usize = 512;

/// One recorded replay (module documentation, "The period memo"): its key, and what it did
/// as routes from its inputs. Cycles are counted from the I/O's cycle at the window's start.
struct MemoEntry {
    /// The window's end, whether the DMA may read flash ([`System::xip_answers`]), and the
    /// board's own banks (`Config::own_banks`, which a replay's checks read).
    span: u64,
    xip: bool,
    own: u8,
    /// Whether the parts kept records while it was recorded (else `records` is empty, and
    /// it gives no board that keeps them a window: [`Probe::keeps`]).
    with_records: bool,
    /// Each core's register stores: their cycles from the start, addresses and values.
    regs: [Vec<IoAccess>; 2],
    /// The I/O at the window's start at [`Rebase::MEMO`], its records left out and its data
    /// words ([`Io::data_slots`]) 0; its [`Io::quick_key`].
    start: Box<Io>,
    start_key: u64,
    /// What the data words at the start must hold: (slot, mask, bits).
    start_fixed: Vec<(u32, Option<Slot>, u32, u32)>,
    /// The number of data words (the first read's input), and those the routes read (with
    /// where they lie: [`Io::locate`]).
    slots: u32,
    needs: Vec<(u32, Option<Slot>)>,
    /// The DMA's SRAM accesses in their ticks' order.
    ops: Vec<MemoOp>,
    /// The DMA's bank claims: (cycle, bank), sorted; and per cycle a bit set when the DMA
    /// claims some bank then (the common test: most cycles have none).
    claims: Vec<(u64, u8)>,
    claimed: Vec<u64>,
    /// Per cycle from the start through the last claim or access of the DMA's: the number
    /// of its accesses at or before it (low byte) and the banks it claims in it (high
    /// byte), for a window's shape ([`shape_of`]; empty for an entry of more than 255
    /// accesses, which no plan serves).
    at_cycle: Vec<u16>,
    /// The cycle the I/O was run to: a core's access at or after it is not replayed here.
    ran_to: u64,
    /// The I/O at the end at [`Rebase::MEMO`] without its records, and the routes of its
    /// data words but those that end as they started (a hit keeps those): (data slot, where
    /// it lies, route).
    end: Arc<EndState>,
    patches: Vec<(u32, Option<Slot>, Route)>,
    /// Of the data words a hit sets, those whose route is a constant: (data slot, where it
    /// lies, value).
    const_patches: Vec<(u32, Option<Slot>, u32)>,
    /// The parts' records, and the routes of their codes (per ADC its frames', per DAC its
    /// updates').
    records: IoRecords,
    frame_routes: Vec<Vec<Route>>,
    update_routes: Vec<Vec<Route>>,
}

impl MemoEntry {
    /// Gives `set` each data word a hit sets, with its value for `inputs` (the hit's data
    /// words and DMA reads): (data slot, where it lies, value).
    #[inline]
    fn patch(&self, inputs: &[u32], mut set: impl FnMut(u32, Option<Slot>, u32)) {
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
struct MemoOp {
    tick: u64,
    off: u32,
    size: u8,
    kind: MemoOpKind,
}

/// A [`MemoOp`]'s direction.
enum MemoOpKind {
    /// A read: the next input, whose bits under `mask` must be `value` (they decided
    /// something).
    Read { mask: u32, value: u32 },
    /// A write, its value by `route`.
    Write { route: Route },
}

/// The most plans kept per entry ([`Plans`]; all dropped when it is full, so a board keeps
/// at most [`MEMO_ENTRIES`] times this many, each some hundreds of bytes). Which of the
/// DMA's accesses come before each of the cores' could depend on the keys' paths through
/// the handler; on the shipped firmware it does not: in the demo and Maestro_3's first 30 s
/// on `rp2040_io` every entry's windows have one shape (198 plans made in all).
const PLANS: usize = 16;

/// An entry's plans by their shapes' hashes (module documentation, "Plans"), and the
/// one used last (the next window's is that one in all but a few in 10,000).
#[derive(Default)]
struct Plans {
    map: HashMap<u64, Plan, std::hash::BuildHasherDefault<Prehashed>>,
    last: Option<u64>,
}

impl Plans {
    /// The plan of entry `e` for the window whose logs are `logs` (cycles from `base`),
    /// made now if there is none yet (`shape`: a buffer); `None` when a core access falls
    /// in a cycle in which the DMA claims its bank, or the entry has no
    /// [`MemoEntry::at_cycle`].
    fn find(
        &mut self,
        e: &MemoEntry,
        logs: &[Vec<IoAccess>; 2],
        base: u64,
        shape: &mut Vec<u64>,
    ) -> Option<&Plan> {
        if e.at_cycle.is_empty() {
            return None;
        }
        let last = self
            .last
            .filter(|h| self.map.get(h).is_some_and(|p| p.serves(logs, base)));
        let h = match last {
            Some(h) => h,
            None => {
                let h = shape_of(e, logs, base, shape)?;
                if self.map.get(&h).is_none_or(|p| p.shape != *shape) {
                    if self.map.len() >= PLANS {
                        self.map.clear();
                    }
                    self.map.insert(h, Plan::new(e, logs, base, shape));
                }
                self.last = Some(h);
                h
            }
        };
        self.map.get(&h)
    }
}

/// One access's word of a window's shape for entry `e` ([`shape_of`]): its address, size,
/// kind and the number of the entry's DMA accesses at or before its cycle; `None` when it
/// falls in a cycle in which the DMA claims its bank.
#[inline]
fn shape_word(e: &MemoEntry, a: &IoAccess, base: u64) -> Option<u64> {
    let mut pos = 0;
    if a.kind != IoKind::Reg {
        let at = a.cycle.wrapping_sub(base);
        pos = match e.at_cycle.get(at as usize) {
            Some(&x) if (x >> 8) >> sram_bank(a.addr) & 1 != 0 => return None,
            Some(&x) => u64::from(x & 0xff),
            None => e.ops.len() as u64,
        };
    }
    Some(u64::from(a.addr) << 32 | pos << 16 | u64::from(a.size) << 8 | a.kind as u64)
}

/// The shape of a window's logs for entry `e` into `shape` (module documentation,
/// "Plans"): per core each access's [`shape_word`], the cores apart by a `u64::MAX`;
/// returns its hash, or `None` where an access falls in a cycle in which the DMA claims
/// its bank (the window is not the entry's: the general replay finds it so).
fn shape_of(
    e: &MemoEntry,
    logs: &[Vec<IoAccess>; 2],
    base: u64,
    shape: &mut Vec<u64>,
) -> Option<u64> {
    shape.clear();
    for log in logs {
        for a in log {
            shape.push(shape_word(e, a, base)?);
        }
        shape.push(u64::MAX);
    }
    Some((shape.iter()).fold(0xcbf2_9ce4_8422_2325u64, |h, &x| {
        (h ^ x).wrapping_mul(0x0000_0100_0000_01b3)
    }))
}

/// [`MemoEntry::at_cycle`] for the DMA's accesses `ops` (in their ticks' order) and
/// claims `claims` (cycle, bank), both from the start.
fn at_cycle(ops: &[MemoOp], claims: &[(u64, u8)]) -> Vec<u16> {
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

/// A hasher for keys that are hashes already ([`Plans`]).
#[derive(Default)]
struct Prehashed(u64);

impl std::hash::Hasher for Prehashed {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = self.0.rotate_left(8) ^ u64::from(b);
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = x;
    }
}

/// Where a planned hit takes the word a DMA read reads ([`Plan`]).
#[derive(Clone, Copy)]
enum Src {
    /// The SRAM as the cores' run left it (no core stores the word after the read).
    Sram,
    /// The word a core's logged store overwrote (the first store to it after the read),
    /// shifted right by `shift` bits.
    Old { core: u8, at: u32, shift: u8 },
    /// An earlier DMA write's value (op index; the same bytes).
    Dma(u32),
}

/// A hit's replay worked out once for an entry and a shape of the window's logs (module
/// documentation, "Plans").
struct Plan {
    /// The windows it serves ([`shape_of`]).
    shape: Vec<u64>,
    /// Per core, what each logged access must be for the window to have that shape
    /// ([`Plan::serves`]).
    fits: [Vec<Fit>; 2],
    /// False for a shape no plan serves (the general replay does those windows).
    ok: bool,
    /// The DMA's accesses in the entry's order, each with where a read's word comes from
    /// (empty when the plan splits: `split`).
    steps: Vec<PlanStep>,
    /// The core loads of words a DMA write wrote before them: (core, log index, op index,
    /// shift of the load's bytes in the write's value); empty when the plan splits.
    checks: Vec<(u8, u32, u32, u8)>,
    /// The same steps as reads then writes, where no read takes a DMA write's word
    /// ([`Split`]); `None` otherwise.
    split: Option<Split>,
}

/// A [`Plan`]'s steps apart: the DMA's reads in order, then its writes in order. The same
/// hit as the steps in the entry's order when no read takes its word from a DMA write
/// ([`Src::Dma`]): a write's route reads only inputs of reads before it, which the reads
/// give the same numbers, and every write waits for the checks anyway (none is done
/// before all reads and checks pass). The shipped drivers' windows all split (their DMA
/// reads the DAC frames at the tick and writes the ADC results later), and the split hit
/// runs no per-step match and keeps no value per read.
struct Split {
    /// The reads, none from [`Src::Dma`].
    reads: Vec<PlanRead>,
    /// (offset, size, route): as [`PlanStep::Write`].
    writes: Vec<(u32, u8, Route)>,
    /// [`Plan::checks`] with the write's index among `writes` for its op index.
    checks: Vec<(u8, u32, u32, u8)>,
}

impl Split {
    /// The split of `steps` and `checks` ([`Plan`]'s), or `None` where a read takes a DMA
    /// write's word.
    fn of(steps: &[PlanStep], checks: &[(u8, u32, u32, u8)]) -> Option<Split> {
        let mut reads = Vec::new();
        let mut writes = Vec::new();
        // Per step, its index among the writes.
        let mut write_at = vec![u32::MAX; steps.len()];
        for (j, step) in steps.iter().enumerate() {
            match *step {
                PlanStep::Read(PlanRead {
                    src: Src::Dma(_), ..
                }) => return None,
                PlanStep::Read(r) => reads.push(r),
                PlanStep::Write {
                    off,
                    size,
                    ref route,
                } => {
                    write_at[j] = writes.len() as u32;
                    writes.push((off, size, route.clone()));
                }
            }
        }
        let checks = (checks.iter())
            .map(|&(c, k, j, shift)| {
                let w = *write_at.get(j as usize)?;
                (w != u32::MAX).then_some((c, k, w, shift))
            })
            .collect::<Option<Vec<_>>>()?;
        Some(Split {
            reads,
            writes,
            checks,
        })
    }
}

/// What a logged access must be for a window to have a plan's shape: its address, size
/// and kind, and its data phase's cycle from the window's start in `lo..hi`, cycles in
/// which as many of the entry's DMA accesses come at or before it and the DMA does not
/// claim its bank (a stretch of the cycles that give its [`shape_word`]: a window whose
/// access falls elsewhere in them finds the plan by its shape's hash).
struct Fit {
    addr: u32,
    size: u8,
    kind: IoKind,
    lo: u64,
    hi: u64,
}

impl Fit {
    /// The fit of access `a` (cycles from `base`) for entry `e`: the stretch of cycles
    /// around its own with its [`shape_word`] (every cycle for a register store).
    fn of(e: &MemoEntry, a: &IoAccess, base: u64) -> Fit {
        let fit = |lo, hi| Fit {
            addr: a.addr,
            size: a.size,
            kind: a.kind,
            lo,
            hi,
        };
        if a.kind == IoKind::Reg {
            return fit(0, u64::MAX);
        }
        let word = |c: u64| shape_word(e, &IoAccess { cycle: c, ..*a }, 0);
        let at = a.cycle.wrapping_sub(base);
        let mine = word(at);
        if mine.is_none() {
            // Not a shape's access (none is planned): fits no cycle.
            return fit(0, 0);
        }
        let len = e.at_cycle.len() as u64;
        let mut lo = at.min(len);
        while lo > 0 && word(lo - 1) == mine {
            lo -= 1;
        }
        let mut hi = at.saturating_add(1);
        while hi < len && word(hi) == mine {
            hi += 1;
        }
        if hi >= len && word(len) == mine {
            // Past the table every cycle has every DMA access before it and no claim.
            hi = u64::MAX;
        }
        fit(lo, hi)
    }

    /// Whether access `a` (cycles from `base`) fits.
    #[inline]
    fn fits(&self, a: &IoAccess, base: u64) -> bool {
        let at = a.cycle.wrapping_sub(base);
        a.addr == self.addr
            && a.size == self.size
            && a.kind == self.kind
            && at.wrapping_sub(self.lo) < self.hi - self.lo
    }
}

/// One DMA access of a [`Plan`]: a read ([`PlanRead`]), or a write of its route's value
/// (the route cloned from the entry's op).
enum PlanStep {
    Read(PlanRead),
    Write { off: u32, size: u8, route: Route },
}

/// A DMA read of a [`Plan`]: `size` bytes at SRAM offset `off`, whose word comes from
/// `src` and whose bits under `mask` must be `value`.
#[derive(Clone, Copy)]
struct PlanRead {
    off: u32,
    size: u8,
    src: Src,
    mask: u32,
    value: u32,
}

impl PlanRead {
    /// Its word in a hit whose SRAM is `sram` (as the cores' run left it), logs `logs`
    /// and DMA values so far `before` (by op index); `None` when the word is not there or
    /// breaks the constraint (the plan does not serve the window).
    #[inline]
    fn word(&self, sram: &[u8], logs: &[Vec<IoAccess>; 2], before: &[u32]) -> Option<u32> {
        let v = match self.src {
            Src::Sram => load_le(sram, self.off as usize, self.size.into()),
            Src::Old { core, at, shift } => {
                let a = logs[core as usize & 1].get(at as usize)?;
                (a.old >> shift) & size_mask(self.size)
            }
            // An earlier op's (`Plan::new`).
            Src::Dma(i) => before.get(i as usize)? & size_mask(self.size),
        };
        (v & self.mask == self.value).then_some(v)
    }
}

/// The mask of the low `size` bytes.
fn size_mask(size: u8) -> u32 {
    match size {
        1 => 0xff,
        2 => 0xffff,
        _ => u32::MAX,
    }
}

impl Plan {
    /// Whether the window whose logs are `logs` (cycles from `base`) has the plan's shape
    /// ([`shape_of`]), no access of it in a cycle the DMA claims its bank: each access
    /// [`Fit::fits`] (an access elsewhere in the cycles of its shape word is not served
    /// here but by the shape's hash).
    #[inline]
    fn serves(&self, logs: &[Vec<IoAccess>; 2], base: u64) -> bool {
        (logs.iter().zip(&self.fits)).all(|(log, fits)| {
            log.len() == fits.len() && (log.iter().zip(fits)).all(|(a, f)| f.fits(a, base))
        })
    }

    /// The plan of entry `e` for windows shaped as `logs` (cycles from `base`; their shape
    /// `shape`): the general replay's order ([`Board::io_memo_apply`]) worked out once.
    /// Not `ok` (the general replay serves such windows) where a word is accessed by both
    /// cores or both written by the DMA and stored by a core, a DMA read reads a DMA
    /// write's bytes other than exactly, or a read mixes bytes of the DMA's writes and
    /// others.
    fn new(e: &MemoEntry, logs: &[Vec<IoAccess>; 2], base: u64, shape: &[u64]) -> Plan {
        let fits = logs
            .each_ref()
            .map(|log| log.iter().map(|a| Fit::of(e, a, base)).collect());
        let not = |fits| Plan {
            shape: shape.to_vec(),
            fits,
            ok: false,
            steps: Vec::new(),
            checks: Vec::new(),
            split: None,
        };
        // The steps in the merged replay's order.
        let steps: Vec<Step> = Order::new(&e.ops, logs, base).collect();
        // Words by who touches them: bits 0 and 1 the cores, bit 2 a core's store, bit 3
        // a DMA write.
        let mut words: Vec<(u32, u8)> = Vec::new();
        for &step in &steps {
            let (word, bits) = match step {
                Step::Core(k, i) => {
                    let a = &logs[k][i];
                    let store = if a.kind == IoKind::Store { 4 } else { 0 };
                    (a.addr & !3, 1 << k | store)
                }
                Step::Dma(j) => match e.ops.get(j) {
                    Some(op) if matches!(op.kind, MemoOpKind::Write { .. }) => (op.off & !3, 8),
                    _ => continue,
                },
            };
            match words.iter_mut().find(|w| w.0 == word) {
                Some(w) => w.1 |= bits,
                None => words.push((word, bits)),
            }
        }
        if words.iter().any(|&(_, w)| w & 3 == 3 || w & 12 == 12) {
            return not(fits);
        }
        // Each byte a DMA write wrote so far, with the write (op index).
        let mut written: Vec<(u32, u32)> = Vec::new();
        // The DMA write whose bytes `off..off + size` are, or `None` when no DMA write
        // wrote any of them; `Err` when mixed.
        let last_write = |written: &[(u32, u32)], off: u32, size: u8| {
            let by = |b: u32| written.iter().find(|w| w.0 == b).map(|w| w.1);
            let first = by(off);
            match (off + 1..off + u32::from(size)).all(|b| by(b) == first) {
                true => Ok(first),
                false => Err(()),
            }
        };
        // Per op, where a read's word comes from (`None` for a write).
        let mut srcs: Vec<Option<Src>> = vec![None; e.ops.len()];
        let mut checks = Vec::new();
        for (n, &step) in steps.iter().enumerate() {
            match step {
                Step::Core(k, i) => {
                    let a = &logs[k][i];
                    if a.kind != IoKind::Load {
                        continue;
                    }
                    match last_write(&written, a.addr, a.size) {
                        Ok(None) => {}
                        Ok(Some(j)) => {
                            let Some(op) = e.ops.get(j as usize) else {
                                return not(fits);
                            };
                            checks.push((k as u8, i as u32, j, ((a.addr - op.off) * 8) as u8));
                        }
                        Err(()) => return not(fits),
                    }
                }
                Step::Dma(i) => {
                    let Some(op) = e.ops.get(i) else {
                        return not(fits);
                    };
                    let bytes = op.off..op.off + u32::from(op.size);
                    match op.kind {
                        MemoOpKind::Write { .. } => {
                            written.retain(|w| !bytes.contains(&w.0));
                            written.extend(bytes.map(|b| (b, i as u32)));
                        }
                        MemoOpKind::Read { .. } => {
                            srcs[i] = Some(match last_write(&written, op.off, op.size) {
                                Ok(Some(j)) => match e.ops.get(j as usize) {
                                    Some(w) if w.off == op.off && w.size == op.size => Src::Dma(j),
                                    _ => return not(fits),
                                },
                                Err(()) => return not(fits),
                                // The word as a core's run left it at this point: before
                                // the first store to it after the read, else the end's.
                                Ok(None) => (steps.get(n + 1..).into_iter().flatten())
                                    .find_map(|&step| {
                                        let Step::Core(c, k) = step else {
                                            return None;
                                        };
                                        let s = &logs[c][k];
                                        (s.kind == IoKind::Store && s.addr & !3 == op.off & !3)
                                            .then_some(Src::Old {
                                                core: c as u8,
                                                at: k as u32,
                                                shift: ((op.off & 3) * 8) as u8,
                                            })
                                    })
                                    .unwrap_or(Src::Sram),
                            });
                        }
                    }
                }
            }
        }
        let steps = (e.ops.iter().zip(srcs))
            .map(|(op, src)| match (&op.kind, src) {
                (&MemoOpKind::Read { mask, value }, Some(src)) => Some(PlanStep::Read(PlanRead {
                    off: op.off,
                    size: op.size,
                    src,
                    mask,
                    value,
                })),
                (MemoOpKind::Write { route }, _) => Some(PlanStep::Write {
                    off: op.off,
                    size: op.size,
                    route: route.clone(),
                }),
                // A read the merged order never reached (none: every op is a step).
                (MemoOpKind::Read { .. }, None) => None,
            })
            .collect::<Option<Vec<PlanStep>>>();
        let Some(steps) = steps else {
            return not(fits);
        };
        let split = Split::of(&steps, &checks);
        // The steps and checks in order serve only a plan that does not split.
        let (steps, checks) = match split {
            Some(_) => (Vec::new(), Vec::new()),
            None => (steps, checks),
        };
        Plan {
            shape: shape.to_vec(),
            fits,
            ok: true,
            steps,
            checks,
            split,
        }
    }
}

/// The register stores of each core's log of a window, their cycles from `base`: a
/// [`MemoEntry`]'s key. (Per core, not in the lock-step order: with their cycles, the
/// cores' sequences decide that order.)
fn reg_stores(logs: &[Vec<IoAccess>; 2], base: u64) -> [Vec<IoAccess>; 2] {
    logs.each_ref().map(|log| {
        (log.iter())
            .filter(|a| a.kind == IoKind::Reg)
            .map(|a| a.since(base))
            .collect()
    })
}

/// A hash of logs (FNV-1a over their fields).
fn log_hash(logs: &[Vec<IoAccess>; 2]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut mix = |v: u64| h = (h ^ v).wrapping_mul(0x0000_0100_0000_01b3);
    for l in logs {
        for e in l {
            mix(e.start);
            mix(e.cycle);
            mix(u64::from(e.addr) << 32 | u64::from(e.value));
            mix(u64::from(e.old) << 16 | u64::from(e.size) << 8 | e.kind as u64);
        }
        mix(u64::MAX);
    }
    h
}

/// What a window brings to the period memo's lookup: its end (from `base`, the I/O's
/// cycle at its start), whether the DMA may read flash, the board's own banks, its last
/// logged access's cycle, and the live machine's [`Io::quick_key`] once a comparison needs
/// it.
struct Probe {
    span: u64,
    xip: bool,
    own: u8,
    /// Whether the machine's parts keep records (frames, updates): an entry recorded where
    /// they kept none has none to give.
    keeps: bool,
    base: u64,
    last: u64,
    key: std::cell::OnceCell<u64>,
}

impl Probe {
    /// Whether entry `e` stands for the window whose logs are `logs`, its I/O `now`: the
    /// key's parts equal, the machine equal to the entry's start at the memo's time base but
    /// for its data words, which meet the entry's constraints (module documentation).
    ///
    /// With `known`, the machine is known to be equal but for data (the entry that followed
    /// the last one's, the machine untouched since): that comparison is left out.
    fn fits(&self, e: &MemoEntry, now: View, logs: &[Vec<IoAccess>; 2], known: bool) -> bool {
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
enum View<'a> {
    Live(&'a Io),
    Lazy(&'a LazyEnd),
}

impl View<'_> {
    /// The I/O of `sys` (`None` without one).
    fn of(sys: &System) -> Option<View<'_>> {
        match sys.io_lazy.as_deref() {
            Some(l) => Some(View::Lazy(l)),
            None => sys.io.as_deref().map(View::Live),
        }
    }

    /// Data slot `i` ([`Io::data_slots`]' order), which lies at `at` ([`Io::locate`]).
    #[inline]
    fn slot(self, i: u32, at: Option<Slot>) -> u32 {
        match self {
            View::Live(io) => io.slot_at(at),
            View::Lazy(l) => l.data.get(i as usize).copied().unwrap_or(0),
        }
    }
}

/// How a try of the period memo ended.
enum Tried {
    /// No entry fits: the replay is run (and recorded).
    Miss,
    /// An entry gave the replay, or the window is undone for the reason given.
    Done(Result<(), Violation>),
}

/// Why a replay failed (module documentation).
enum Violation {
    Wait,
    Stale,
    Reach,
}

/// What [`Board::io_window_begin`] keeps for the end of the window.
pub(super) struct IoStart {
    banks: u8,
    /// The window's end (the cores run to it).
    end: u64,
}

/// Stores the `size` low bytes of `value` at SRAM offset `off`, journaling the word into
/// [`System::io_journal`].
fn sram_put(sys: &mut System, off: u32, size: u8, value: u32) {
    let word = off & !3;
    let old = sys.sram_peek(word);
    if let Some(j) = sys.io_journal.as_mut() {
        j.push(u64::from(word) << 32 | u64::from(old));
    }
    store_le(&mut sys.sram, off as usize, u32::from(size), value);
}

/// A hit's inputs for entry `e` into `inputs`: the data words its routes read (the others
/// 0), up to the first DMA read's.
#[inline]
fn data_inputs(sys: &System, e: &MemoEntry, inputs: &mut Vec<u32>) {
    inputs.clear();
    inputs.resize(e.slots as usize, 0);
    if let Some(io) = View::of(sys) {
        for &(s, at) in &e.needs {
            inputs[s as usize] = io.slot(s, at);
        }
    }
}

/// Whether each core load that `checks` lists ([`Plan::checks`]: core, log index, index
/// of the DMA write in `values`, shift) loaded what that write's value holds.
fn loads_see_writes(
    checks: &[(u8, u32, u32, u8)],
    logs: &[Vec<IoAccess>; 2],
    values: &[u32],
) -> bool {
    checks.iter().all(|&(c, k, j, shift)| {
        match (logs[c as usize & 1].get(k as usize), values.get(j as usize)) {
            (Some(a), Some(&w)) => (w >> shift) & size_mask(a.size) == a.value,
            _ => false,
        }
    })
}

/// A planned hit by `split` ([`Split`]), the SRAM as the cores' run left it and `inputs`
/// holding the entry's data inputs: the reads checked and taken as inputs, the writes'
/// values into `values`, the core loads checked against them, and the writes done (not
/// journaled: nothing after them fails). False, nothing written, when a read or a check
/// fails.
fn split_hit(
    sys: &mut System,
    split: &Split,
    logs: &[Vec<IoAccess>; 2],
    inputs: &mut Vec<u32>,
    values: &mut Vec<u32>,
) -> bool {
    for r in &split.reads {
        // No read of a split plan takes a DMA write's word: none before it.
        let Some(v) = r.word(&sys.sram, logs, &[]) else {
            return false;
        };
        inputs.push(v);
    }
    values.clear();
    values.extend(split.writes.iter().map(|(_, _, route)| route.eval(inputs)));
    if !loads_see_writes(&split.checks, logs, values) {
        return false;
    }
    for (&(off, size, _), &v) in split.writes.iter().zip(values.iter()) {
        sys.io_dma_write(off, size.into(), v, false);
    }
    true
}

/// A period memo hit's DMA access `op`: a read checks its constraint and becomes the next
/// input, a write stores its route's value (journaled, as [`System::io_dma_write`]).
/// False when a read breaks its constraint (the entry does not stand for the window).
fn dma_op(sys: &mut System, op: &MemoOp, inputs: &mut Vec<u32>) -> bool {
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

impl Board {
    /// The windows of a board with an I/O so far (module documentation).
    pub fn io_windows(&self) -> IoWindows {
        self.io_windows
    }

    /// Turns the period memo of the I/O's replays (module documentation) on or off; on by
    /// default. Results never depend on it: what it gives is the replay's.
    pub fn set_io_memo(&mut self, on: bool) {
        self.io_memo = IoMemo {
            on,
            ..IoMemo::default()
        };
    }

    /// For tests: whether a hit of the period memo may leave its end behind instead of
    /// making it (module documentation, "The lazy end"); on by default. Results never
    /// depend on it.
    #[doc(hidden)]
    pub fn set_io_lazy(&mut self, on: bool) {
        self.system.io_unlazy();
        self.io_memo.lazy = on;
    }

    /// For tests: whether a hit of the period memo may take a plan (module documentation,
    /// "Plans"); on by default. Results never depend on it.
    #[doc(hidden)]
    pub fn set_io_plans(&mut self, on: bool) {
        self.io_memo.planned = on;
    }

    /// For tests: keeps a digest of every window's logs ([`Board::io_log_digest`]), and
    /// with `native` false has the cores' accesses to the DMA's banks and the I/O's
    /// registers take the general path instead of native code (`jit::abi`'s `io_sram`,
    /// `io_reg`), so that a test can compare the logs the two paths write. Results never
    /// depend on it.
    #[doc(hidden)]
    pub fn check_io_logs(&mut self, native: bool) {
        self.io_native = native;
        self.io_digest = Some(0);
    }

    /// The digest [`Board::check_io_logs`] keeps: FNV-1a over every access logged in a
    /// window, each window's logs in order; `None` unless asked for.
    #[doc(hidden)]
    pub fn io_log_digest(&self) -> Option<u64> {
        self.io_digest
    }

    /// At the start of a window from cycle `start`: on a board with an I/O, runs it up to
    /// `start`, keeps a clone and has the cores log their accesses to its DMA's banks;
    /// `None` without an I/O.
    pub(super) fn io_window_begin(&mut self, start: u64, end: u64) -> Option<IoStart> {
        self.system.io.as_ref()?;
        self.system.io_advance_to(start, false);
        let banks = self.system.io_banks;
        // The cores' run does not touch the I/O: their accesses are logged instead.
        self.system.io_banks = 0;
        self.system.allowed_banks = self.system.fast_banks();
        self.io_window = Some(banks);
        for l in &mut self.io_logs {
            l.clear();
        }
        Some(IoStart { banks, end })
    }

    /// At the end of the cores' run of a window (`kept`: both reached its end): replays
    /// the I/O; true when the window is kept. When not, the I/O and the replay's SRAM
    /// writes are undone (the caller undoes the cores).
    pub(super) fn io_window_end(&mut self, start: IoStart, kept: bool) -> bool {
        self.io_window = None;
        self.system.io_banks = start.banks;
        self.system.allowed_banks = self.system.fast_banks();
        if let Some(d) = self.io_digest.as_mut() {
            *d = (*d ^ log_hash(&self.io_logs)).wrapping_mul(0x0000_0100_0000_01b3);
        }
        if !kept {
            return false;
        }
        let mut io = None;
        let r = self.io_replay(start.banks, start.end, &mut io);
        let journal = self.system.io_journal.take().unwrap_or_default();
        let s = &mut self.io_windows;
        let ok = r.is_ok();
        match r {
            Ok(()) => s.kept += 1,
            Err(v) => {
                match v {
                    Violation::Wait => s.waited += 1,
                    Violation::Stale => s.stale += 1,
                    Violation::Reach => s.reach += 1,
                }
                undo_stores(&mut self.system, &journal);
                if let (Some(now), Some(then)) = (self.system.io.as_mut(), io) {
                    now.rewind(then);
                }
                self.system.io_banks = start.banks;
                self.system.allowed_banks = self.system.fast_banks();
            }
        }
        self.io_journal = journal;
        ok
    }

    /// The replay (module documentation), its SRAM writes journaled in
    /// [`System::io_journal`]; `io` becomes the I/O's checkpoint at the window's start
    /// when the I/O is run (not on a hit of the period memo, which changes the I/O only
    /// once it is kept; a recording takes it: the replay is then kept). The I/O is as the
    /// window's start left it: the cores' run does not touch it.
    fn io_replay(
        &mut self,
        banks: u8,
        end: u64,
        io: &mut Option<Checkpoint>,
    ) -> Result<(), Violation> {
        let mut journal = std::mem::take(&mut self.io_journal);
        journal.clear();
        self.system.io_journal = Some(journal);
        let logs = std::mem::take(&mut self.io_logs);
        let own = (self.config.own_banks[0] | self.config.own_banks[1]) & ALL_BANKS;
        let memo = self.io_memo.on && self.system.io.as_ref().is_some_and(|io| !io.stepwise);
        let r = match memo {
            true => self.io_memo_replay(&logs, banks, own, end, io),
            false => {
                self.io_take_back(&logs);
                self.system.io_unlazy();
                *io = self.system.io.as_mut().map(|now| now.checkpoint());
                self.io_merge(&logs, banks, own)
            }
        };
        self.io_logs = logs;
        r
    }

    /// The words the cores' logged stores overwrote put back, newest store first: the
    /// SRAM as it was before the window (journaled), for the replay to do the stores in
    /// their places among the DMA's accesses. (A planned hit does without: module
    /// documentation, "Plans".)
    fn io_take_back(&mut self, logs: &[Vec<IoAccess>; 2]) {
        for log in logs {
            for e in log.iter().rev().filter(|e| e.kind == IoKind::Store) {
                sram_put(&mut self.system, e.addr & !3, 4, e.old);
            }
        }
    }

    /// The replay through the period memo (module documentation): a hit does what the
    /// recorded replay did with its own data; a miss checkpoints the I/O into `io`,
    /// replays with lanes, runs the I/O to the window's `end` and records.
    fn io_memo_replay(
        &mut self,
        logs: &[Vec<IoAccess>; 2],
        banks: u8,
        own: u8,
        end: u64,
        io: &mut Option<Checkpoint>,
    ) -> Result<(), Violation> {
        if self.system.io.is_none() {
            self.io_take_back(logs);
            return self.io_merge(logs, banks, own);
        }
        // A machine held behind (an advance that did not settle) is settled first: the
        // memo's states are settled ones. The stores are taken back before the advance
        // unless it runs nothing (a machine not behind, advanced to its own cycle), and the
        // hit's plans are then left out.
        let (base, back) = match (self.system.io_lazy.as_deref(), self.system.io.as_deref()) {
            (Some(l), _) => (l.cycle(), l.end.io.is_behind()),
            (None, io) => (io.map_or(0, Io::cycle), io.is_none_or(Io::is_behind)),
        };
        if back {
            self.io_take_back(logs);
        }
        self.system.io_advance_to(base, true);
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
    fn io_memo_hit(
        &mut self,
        logs: &[Vec<IoAccess>; 2],
        base: u64,
        end: u64,
        own: u8,
        back: bool,
    ) -> Tried {
        let keeps = (self.system.io.as_deref_mut()).is_some_and(|io| !io.records_full());
        let Some(now) = self.system.io.as_deref() else {
            return Tried::Miss;
        };
        // The live machine's count of changes: a lazy end leaves it as its hit found it.
        let touches = now.touches();
        let probe = Probe {
            span: end.saturating_sub(base),
            xip: self.system.xip_answers,
            own,
            keeps,
            base,
            last: logs.iter().flatten().map(|a| a.cycle).max().unwrap_or(base),
            key: std::cell::OnceCell::new(),
        };
        #[cfg(debug_assertions)]
        for e in &self.io_memo.entries {
            if e.span == probe.span && crate::io::check_this_skip() {
                let r = Rebase {
                    from: base,
                    to: Rebase::MEMO,
                };
                let mut live = now.clone();
                if let Some(l) = self.system.io_lazy.as_deref() {
                    live.become_lazy(l);
                }
                live.check_eq_but_data(&e.start, r);
            }
        }
        let memo = &self.io_memo;
        let first = (memo.last)
            .and_then(|l| memo.follow.get(l).copied())
            .unwrap_or([usize::MAX; FOLLOWERS]);
        let followers = first.iter().copied().filter(|&f| f != usize::MAX);
        let untouched = memo.after.is_some() && memo.after == Some(touches);
        let n = memo.entries.len();
        let mut shared = None;
        let mark = self.system.io_journal.as_ref().map_or(0, Vec::len);
        for i in followers.chain((0..n).filter(|j| !first.contains(j))) {
            let known = untouched && first.contains(&i);
            if !known {
                // Compared with the entry's start: the live machine.
                self.system.io_unlazy();
            }
            let fits = match (View::of(&self.system), self.io_memo.entries.get(i)) {
                (Some(now), Some(e)) => probe.fits(e, now, logs, known),
                _ => false,
            };
            if !fits {
                continue;
            }
            let e = Arc::clone(&self.io_memo.entries[i]);
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
        self.system.io_unlazy();
        if let Some(now) = self.system.io.as_deref() {
            let mine = &self.io_memo.entries;
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
                self.io_windows.memo_shared += 1;
                let i = self.io_memo.keep(e);
                self.io_memo_followed_by(i, untouched);
                return Tried::Done(r);
            }
        }
        Tried::Miss
    }

    /// One try of entry `e` for the window `probe` brings ([`Board::io_memo_apply`]): what
    /// became of the window, or `None` when a word the DMA reads broke its constraints —
    /// then the SRAM writes journaled since `mark` are undone.
    fn io_memo_try(
        &mut self,
        e: &MemoEntry,
        logs: &[Vec<IoAccess>; 2],
        probe: &Probe,
        mark: usize,
    ) -> Option<Result<(), Violation>> {
        match self.io_memo_apply(e, logs, probe) {
            Tried::Done(r) => Some(r),
            Tried::Miss => {
                if let Some(j) = self.system.io_journal.as_mut() {
                    let undo: Vec<u64> = j.drain(mark.min(j.len())..).collect();
                    undo_stores(&mut self.system, &undo);
                }
                None
            }
        }
    }

    /// Entry `i` gave (or recorded) this window ([`IoMemo::followed_by`]), the I/O's
    /// touches now where it left them.
    fn io_memo_followed_by(&mut self, i: usize, linked: bool) {
        let after = self.system.io.as_deref().map(Io::touches);
        self.io_memo.followed_by(i, linked, after);
    }

    /// Entry `i` (`e`) for the window `probe` brings by a plan (module documentation,
    /// "Plans"), the SRAM as the cores' run left it: true when done; false, nothing
    /// changed, when there is no plan for the window's shape or a read or load breaks it
    /// (the general replay then finds what becomes of the window).
    fn io_memo_planned(
        &mut self,
        i: usize,
        e: &MemoEntry,
        logs: &[Vec<IoAccess>; 2],
        probe: &Probe,
    ) -> bool {
        let IoMemo {
            plans,
            inputs,
            values,
            shape,
            planned,
            ..
        } = &mut self.io_memo;
        if !*planned {
            return false;
        }
        let Some(plan) = plans
            .get_mut(i)
            .and_then(|p| p.find(e, logs, probe.base, shape))
        else {
            return false;
        };
        if !plan.ok {
            return false;
        }
        let sys = &mut self.system;
        if sys.io.is_none() {
            return false;
        }
        data_inputs(sys, e, inputs);
        if let Some(split) = &plan.split {
            if !split_hit(sys, split, logs, inputs, values) {
                return false;
            }
            let r = self.io_memo_end(e, probe);
            self.io_windows.memo_planned += 1;
            return matches!(r, Tried::Done(Ok(())));
        }
        values.clear();
        values.resize(plan.steps.len(), 0);
        for j in 0..values.len() {
            let v = match plan.steps[j] {
                PlanStep::Write { ref route, .. } => route.eval(inputs),
                PlanStep::Read(ref r) => {
                    let Some(v) = r.word(&sys.sram, logs, &values[..j]) else {
                        return false;
                    };
                    inputs.push(v);
                    v
                }
            };
            values[j] = v;
        }
        if !loads_see_writes(&plan.checks, logs, values) {
            return false;
        }
        // Not journaled: nothing after them fails (the end of a hit whose machine is there).
        for (step, &v) in plan.steps.iter().zip(values.iter()) {
            if let PlanStep::Write { off, size, .. } = *step {
                sys.io_dma_write(off, size.into(), v, false);
            }
        }
        let r = self.io_memo_end(e, probe);
        self.io_windows.memo_planned += 1;
        matches!(r, Tried::Done(Ok(())))
    }

    /// Does the replay entry `e` recorded, with the window's data (module documentation):
    /// `Miss` when a word the DMA reads breaks its constraints (the caller undoes what it
    /// wrote), else what became of the window.
    fn io_memo_apply(&mut self, e: &MemoEntry, logs: &[Vec<IoAccess>; 2], probe: &Probe) -> Tried {
        let base = probe.base;
        // The inputs: the data words the entry's routes read, then the DMA's reads.
        let inputs = &mut self.io_memo.inputs;
        data_inputs(&self.system, e, inputs);
        for step in Order::new(&e.ops, logs, base) {
            let (k, i) = match step {
                Step::Dma(j) => match e.ops.get(j) {
                    Some(op) if dma_op(&mut self.system, op, inputs) => continue,
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
                sram_put(&mut self.system, a.addr, a.size, a.value);
            } else if load_le(&self.system.sram, a.addr as usize, a.size.into()) != a.value {
                return Tried::Done(Err(Violation::Stale));
            }
        }
        self.io_memo_end(e, probe)
    }

    /// A hit's end, its SRAM accesses done with [`IoMemo::inputs`]: the entry's end, its
    /// data words and the parts' records by their routes. Where the parts keep no records,
    /// left behind (module documentation, "The lazy end").
    fn io_memo_end(&mut self, e: &MemoEntry, probe: &Probe) -> Tried {
        let inputs = std::mem::take(&mut self.io_memo.inputs);
        let r = self.io_memo_end_with(e, &inputs, probe);
        self.io_memo.inputs = inputs;
        r
    }

    /// [`Board::io_memo_end`] with the inputs taken out of the memo.
    fn io_memo_end_with(&mut self, e: &MemoEntry, inputs: &[u32], probe: &Probe) -> Tried {
        let to_memo = Rebase {
            from: probe.base,
            to: Rebase::MEMO,
        };
        let Some(now) = self.system.io.as_mut() else {
            return Tried::Miss;
        };
        if self.io_memo.lazy && !probe.keeps {
            // The last hit's end reused (its box and list), else one made from the machine.
            let mut l = match self.system.io_lazy.take() {
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
            self.system.io_lazy = Some(l);
        } else {
            self.system.io_unlazy();
            let Some(now) = self.system.io.as_mut() else {
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
        self.system.io_refresh();
        self.io_windows.memo_hits += 1;
        Tried::Done(Ok(()))
    }

    /// A miss of the period memo: the replay run with lanes (the I/O stepwise, each data
    /// word's lanes kept: `crate::lanes`) and the I/O run on to the window's `end`, then
    /// recorded when it is kept and stands for others (no timing breach of a part, no read
    /// of ROM or flash, no reset meanwhile). The I/O's checkpoint at `base` goes into `io`.
    fn io_memo_record(
        &mut self,
        logs: &[Vec<IoAccess>; 2],
        banks: u8,
        own: u8,
        base: u64,
        end: u64,
        io: &mut Option<Checkpoint>,
    ) -> Result<(), Violation> {
        let to_memo = Rebase {
            from: base,
            to: Rebase::MEMO,
        };
        self.system.io_unlazy();
        let Some(now) = self.system.io.as_mut() else {
            return self.io_merge(logs, banks, own);
        };
        // Whether the window starts at the last entry's end (untouched since): the entry
        // recorded here then follows it.
        let linked = self.io_memo.after.is_some() && self.io_memo.after == Some(now.touches());
        let with_records = !now.records_full();
        let checkpoint = now.checkpoint();
        let mut start = checkpoint.io.clone();
        *io = Some(checkpoint);
        start.rebase(to_memo);
        start.data_slots(&mut |v, _| *v = 0);
        let counts = now.record_counts();
        let stepwise = std::mem::replace(&mut now.stepwise, true);
        let slots = now.start_lanes();
        // The data words whose lanes start as constants (known by the machine's invariants),
        // with their values.
        let mut start_const = Vec::with_capacity(slots as usize);
        now.data_slots(&mut |v, l| {
            start_const.push(
                l.is_some_and(|l| l.iter().all(|x| x.is_const()))
                    .then_some(*v),
            )
        });
        self.system.io_rec = Some(Box::new(LaneRec::new(slots)));
        let r = self.io_merge(logs, banks, own);
        if r.is_ok() {
            self.system.io_advance_to(end, true);
        }
        let rec = self.system.io_rec.take();
        let Some(now) = self.system.io.as_mut() else {
            return r;
        };
        now.stepwise = stepwise;
        now.forget_idle();
        let kept = now.stop_lanes();
        let (Ok(()), Some(kept), Some(rec)) = (&r, kept, rec) else {
            return r;
        };
        let records = now.records_since(&counts, to_memo);
        let mut fixed = kept.fixed;
        fixed.extend_from_slice(&rec.fixed);
        let (Some(records), false, false) = (records, rec.poisoned, lanes::contradictory(&fixed))
        else {
            return r;
        };
        let constraints = lanes::constraints(&fixed);
        let fixed_of = |input: u32| {
            constraints
                .iter()
                .find(|c| c.0 == input)
                .map_or((0, 0), |c| (c.1, c.2))
        };
        let ops: Vec<MemoOp> = (rec.ops.into_iter())
            .map(|op| match op {
                LaneOp::Read {
                    tick,
                    off,
                    size,
                    input,
                } => {
                    let (mask, value) = fixed_of(input);
                    MemoOp {
                        tick: tick - base,
                        off,
                        size,
                        kind: MemoOpKind::Read { mask, value },
                    }
                }
                LaneOp::Write {
                    tick,
                    off,
                    size,
                    value,
                    lanes,
                } => MemoOp {
                    tick: tick - base,
                    off,
                    size,
                    kind: MemoOpKind::Write {
                        route: Route::of(&lanes, value),
                    },
                },
            })
            .collect();
        // Every data word but those that end as they started (a hit keeps the live ones):
        // its own input, or a constant it held at the start too.
        let patches: Vec<(u32, Route)> = (kept.slots.iter().enumerate())
            .filter(|&(i, (v, w, bits))| {
                let own = (0..*bits as usize).all(|b| w[b] == Lane::input(i as u32, b as u32));
                let kept_const = start_const.get(i) == Some(&Some(*v)) && lanes::is_const(w);
                !(own || kept_const)
            })
            .map(|(i, (v, w, _))| (i as u32, Route::of(w, *v)))
            .collect();
        let (frame_routes, update_routes) = records.routes(&kept.frames, &kept.updates);
        let start_fixed: Vec<(u32, Option<Slot>, u32, u32)> = (constraints.iter())
            .filter(|c| c.0 < slots)
            .map(|&(i, m, v)| (i, now.locate(i as usize), m, v))
            .collect();
        // The data words at the start that the routes read.
        let mut needs: Vec<u32> = (ops.iter())
            .filter_map(|op| match &op.kind {
                MemoOpKind::Write { route } => Some(route),
                MemoOpKind::Read { .. } => None,
            })
            .chain(patches.iter().map(|(_, r)| r))
            .chain(frame_routes.iter().flatten())
            .chain(update_routes.iter().flatten())
            .flat_map(|r| r.inputs())
            .filter(|&i| i < slots)
            .collect();
        needs.sort_unstable();
        needs.dedup();
        let needs = (needs.into_iter())
            .map(|i| (i, now.locate(i as usize)))
            .collect();
        let (const_patches, patches): (Vec<_>, Vec<_>) = (patches.into_iter())
            .map(|(i, r)| (i, now.locate(i as usize), r))
            .partition(|(_, _, r)| r.constant().is_some());
        let const_patches = (const_patches.into_iter())
            .map(|(i, at, r)| (i, at, r.constant().unwrap_or(0)))
            .collect();
        let mut claims: Vec<(u64, u8)> = rec.claims.iter().map(|&(c, b)| (c - base, b)).collect();
        claims.sort_unstable();
        claims.dedup();
        let mut claimed = vec![0u64; claims.last().map_or(0, |c| c.0 as usize / 64 + 1)];
        for &(c, _) in &claims {
            claimed[c as usize / 64] |= 1 << (c % 64);
        }
        let at_cycle = at_cycle(&ops, &claims);
        let mut end_io = now.rebased(to_memo);
        end_io.forget_idle();
        let entry = MemoEntry {
            start_key: start.quick_key(Rebase {
                from: Rebase::MEMO,
                to: Rebase::MEMO,
            }),
            span: end.saturating_sub(base),
            xip: self.system.xip_answers,
            own,
            with_records,
            regs: reg_stores(logs, base),
            start,
            start_fixed,
            slots,
            needs,
            ops,
            claims,
            claimed,
            at_cycle,
            ran_to: now.cycle() - base,
            end: Arc::new(EndState::new(*end_io)),
            patches,
            const_patches,
            records,
            frame_routes,
            update_routes,
        };
        let entry = Arc::new(entry);
        if let Ok(mut shared) = SHARED.lock() {
            if shared.len() >= SHARED_ENTRIES {
                shared.remove(0);
            }
            shared.push(Arc::clone(&entry));
        }
        let at = self.io_memo.keep(entry);
        self.io_memo_followed_by(at, linked);
        self.io_windows.memo_recorded += 1;
        r
    }

    /// Does the logged accesses of `logs` in the lock-step order.
    fn io_merge(&mut self, logs: &[Vec<IoAccess>; 2], banks: u8, own: u8) -> Result<(), Violation> {
        for e in Merged::new(logs) {
            let sys = &mut self.system;
            match e.kind {
                IoKind::Load | IoKind::Store => {
                    let b = sram_bank(e.addr);
                    if sys.io_banks >> b & 1 != 0 && sys.io_claims(b, e.cycle) {
                        return Err(Violation::Wait);
                    }
                    if e.kind == IoKind::Store {
                        sram_put(sys, e.addr, e.size, e.value);
                    } else if load_le(&sys.sram, e.addr as usize, u32::from(e.size)) != e.value {
                        return Err(Violation::Stale);
                    }
                }
                IoKind::Reg => {
                    if sys
                        .io_store(e.cycle, e.addr, u32::from(e.size), e.value)
                        .is_err()
                        || sys.io_banks & !banks & own != 0
                    {
                        return Err(Violation::Reach);
                    }
                }
            }
        }
        Ok(())
    }
}

/// The two cores' logs in the lock-step order: the instruction that starts first, core 0
/// on ties, each core's accesses in their order.
struct Merged<'l> {
    logs: &'l [Vec<IoAccess>; 2],
    at: [usize; 2],
}

impl<'l> Merged<'l> {
    fn new(logs: &'l [Vec<IoAccess>; 2]) -> Self {
        Merged { logs, at: [0, 0] }
    }

    /// The next access's core and index in its log.
    #[inline]
    fn next_index(&mut self) -> Option<(usize, usize)> {
        let k = match (self.logs[0].get(self.at[0]), self.logs[1].get(self.at[1])) {
            (Some(a), Some(b)) if a.start <= b.start => 0,
            (_, Some(_)) => 1,
            (Some(_), None) => 0,
            (None, None) => return None,
        };
        self.at[k] += 1;
        Some((k, self.at[k] - 1))
    }
}

impl<'l> Iterator for Merged<'l> {
    type Item = &'l IoAccess;
    fn next(&mut self) -> Option<&'l IoAccess> {
        let (k, i) = self.next_index()?;
        self.logs[k].get(i)
    }
}

/// One step of a period memo hit ([`Order`]): the entry's DMA access (op index), or a
/// core's logged SRAM access (core, index in its log).
#[derive(Clone, Copy)]
enum Step {
    Dma(usize),
    Core(usize, usize),
}

/// The steps of a hit of an entry whose DMA accesses are `ops` (in their ticks' order) for
/// a window's `logs` (cycles from `base`), in the lock-step order: the cores' accesses
/// merged ([`Merged`], their register stores left out), each after the DMA's accesses at
/// or before its cycle and before the later ones (as the lock-step bus runs the I/O
/// through an access's cycle first), the DMA's last ones after all. The merged replay
/// ([`Board::io_memo_apply`]) does them; a [`Plan`] is worked out from them.
struct Order<'l> {
    ops: &'l [MemoOp],
    logs: &'l [Vec<IoAccess>; 2],
    base: u64,
    merged: Merged<'l>,
    /// The DMA's next access, and the cores' next one if it is known.
    next: usize,
    core: Option<(usize, usize)>,
}

impl<'l> Order<'l> {
    fn new(ops: &'l [MemoOp], logs: &'l [Vec<IoAccess>; 2], base: u64) -> Self {
        Order {
            ops,
            logs,
            base,
            merged: Merged::new(logs),
            next: 0,
            core: None,
        }
    }
}

impl Iterator for Order<'_> {
    type Item = Step;
    fn next(&mut self) -> Option<Step> {
        if self.core.is_none() {
            let logs = self.logs;
            self.core = std::iter::from_fn(|| self.merged.next_index())
                .find(|&(k, i)| logs[k].get(i).is_some_and(|a| a.kind != IoKind::Reg));
        }
        let due = (self.core)
            .and_then(|(k, i)| self.logs[k].get(i))
            .map_or(u64::MAX, |a| a.cycle.wrapping_sub(self.base));
        if self.ops.get(self.next).is_some_and(|op| op.tick <= due) {
            self.next += 1;
            return Some(Step::Dma(self.next - 1));
        }
        self.core.take().map(|(k, i)| Step::Core(k, i))
    }
}
