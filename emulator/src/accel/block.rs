//! The block engine: Thumb code compiled to native code by region ([`crate::accel::jit`]), with
//! pre-decoded basic blocks for what is cold or does not fit before a deadline.
//!
//! **Two layers.** A *region* ([`crate::accel::jit`]) is the code from an address on, compiled
//! with cranelift once its entry has been reached [`Jit::threshold`] times: straight-line
//! code, forward branches and loops inside it are native, with the guest registers in host
//! registers; it runs whenever the core's cycle plus the region's static bound fits before
//! the run's deadline. Otherwise, or at an instruction the region leaves to the
//! interpreter, a *block* runs: a run of pre-decoded instructions (`BlockOp`, each the
//! same `Op` the per-instruction fast path executes) from its first address to the first
//! instruction that may write the PC (a branch, BL, BX/BLX, `POP {…, pc}`, ADD/MOV to PC,
//! a trap) or [`MAX_BLOCK`] instructions, decoded once and executed by
//! `Core::execute_op`, the interpreter's executor. Both layers are checked against the
//! interpreter instruction by instruction (`tests/block_jit.rs`) and on whole programs
//! (`tests/block_engine.rs`, the firmware images in `firmware/tests/image.rs`).
//! Measured: see docs/benchmarks-log.md, "the block compiler".
//!
//! **Cycles.** Each instruction's cost comes from the one timing table
//! ([`tactus_isa::timing::cycles`]) when the block is decoded, as `(not taken, taken)`; the block
//! also records, for each of its instructions, an upper bound on the cycles from that
//! instruction's start to the block's end: the timing table's larger cost of each following
//! instruction plus one wait state per data word it moves (an SRAM access waits at most one
//! cycle for the other core, see [`crate::bus`]; flash never waits, and anything slower
//! — APB, SIO — leaves the fast path). When the core's cycle plus that bound is at most the
//! run's deadline, every instruction of the rest of the block starts before the deadline
//! (each costs at least one cycle), so the block runs with no per-instruction check;
//! otherwise it runs with the check, stopping at the first instruction boundary at or after
//! the deadline, exactly where the interpreter stops. The cycle counter itself still
//! advances per instruction by the table's cost plus the wait states the bus reports —
//! that is where the data-dependent parts (taken branches, bank contention) come from.
//!
//! **Exits.** An instruction the fast path does not complete (peripherals, SIO, PPB,
//! anything that could fault, sleep, signal or change exception state) leaves the block
//! *before* it runs, with every register, flag and counter as at that instruction's start;
//! the board then executes it on the general path. A store that hits an SRAM page holding
//! decoded code bumps the code epoch ([`System::code_epoch`]): the block stops after that
//! store and every block is dropped (a host write does the same), so self-modifying code
//! runs what memory holds.
//!
//! **Two cores.** The interpreter runs the cores in lock-step: the core whose next
//! instruction starts earlier goes first (core 0 on a tie), which orders every shared-state
//! access — SRAM data and bank arbitration, SIO, the timer, interrupt lines — in global
//! cycle order. The block engine keeps that order exactly, by running one core at a time
//! only where the other core's turns are known in advance:
//!
//! * the other core is parked or locked up: it takes no turns;
//! * the other core sleeps and nothing can wake it before its *wake check* (the next timer
//!   event, its SysTick, the limit; see [`crate::board`]): its turns only move its cycle
//!   counter, to the running core's cycle + 1, capped at the wake check. The running core
//!   runs up to the cycle at which such a turn would find the sleeper at its wake check,
//!   and the turns are replayed after each pre-decoded instruction ([`Sleeper::after`]), or
//!   in closed form after native code ([`Sleeper::after_native`]), which needs only the
//!   end cycle and that of the last instruction of two cycles or more;
//! * both cores run on disjoint banks: each runs alone over a window, confined
//!   ([`run_confined`]; the argument and the rollback are in [`crate::board`]'s
//!   `window.rs`); where that fails, the board's lock-step loop on the interpreter.
//!
//! **Memoized calls.** In a window, a core at the entry of a watched function
//! ([`crate::Board::memoize`]) whose inputs are those of a recorded call takes that
//! call's effect instead of running it ([`crate::accel::memo`]); a call to record leaves
//! [`run_confined`] ([`Leave::Record`]) for the board's general path, which runs it one
//! instruction at a time while recording it.

use crate::accel::fast::Op;
use crate::accel::jit::{self, Jit};
use crate::accel::memo::{Memos, Try};
use crate::bus::Bus;
use crate::core::Core;
use crate::system::System;
use tactus_isa::decode::{decode, Instr};
use tactus_isa::timing::{self, Class};
use tactus_rp2040::memory::sram_location;

/// Most instructions in one block.
pub const MAX_BLOCK: usize = 64;

/// Decoded instructions kept before every block is dropped and decoding starts again.
const MAX_OPS: usize = 1 << 20;

/// Slots of the direct-mapped block lookup (by instruction address).
const SLOTS: usize = 1 << 14;

/// One instruction of a block: the pre-decoded form the fast path executes, the
/// instruction, its address and size, its `(not taken, taken)` cycles from the timing
/// table, and the bound on the cycles from its start to the block's end.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BlockOp {
    op: Op,
    instr: Instr,
    pc: u32,
    size: u8,
    /// A store (STR*, STM, PUSH): the code epoch is checked after it.
    store: bool,
    cost: (u8, u8),
    /// Upper bound on the cycles from this instruction's start to the end of its block
    /// (see the module documentation).
    worst_from: u32,
}

/// Where a core left its block when it lost the turn: `ops[op..end]` is the rest, valid
/// while the blocks are of generation `generation`.
#[derive(Clone, Copy, Debug, Default)]
struct Cursor {
    op: u32,
    end: u32,
    generation: u64,
    /// It stopped at its run's limit (not before an instruction it leaves to the general
    /// path): [`run_confined`] goes on in the block.
    at_limit: bool,
}

/// Why [`run`] returned early.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Leave {
    /// The core's next instruction needs the general path (nothing of it was done).
    General,
    /// No block can be decoded at the core's PC (a fetch would fault).
    Miss,
    /// The core is at a watched entry ([`crate::accel::memo`]) whose call is to be recorded
    /// (nothing of it was done).
    Record,
}

/// The confined caches [`run_confined`] runs a core's code with, for one bank mask,
/// journaling and I/O code (the first three fields of [`jit::Flavour::Confined`]): their
/// indices in [`Blocks::confined_solo`] (`solo`, `timed_solo`) and [`Blocks::confined`]
/// (`shared`, `timed_shared`); the timed ones are compiled with the flavour's fourth field
/// set (a region checked instruction by instruction against the run's limit).
#[derive(Clone, Copy, Debug)]
struct ConfinedAt {
    mask: u8,
    journaled: bool,
    io: bool,
    solo: usize,
    shared: usize,
    timed_solo: usize,
    timed_shared: usize,
}

/// Blocks [`run_confined`] runs pre-decoded from where the core resumed at the last run's
/// limit, while each ends going forward (no region compiled at each place it resumes at).
const TAIL_BLOCKS: u32 = 8;

/// Undo-journal entries the journal is made with (a window's stores beyond stop its core).
const JOURNAL: usize = 1 << 16;

/// The decoded blocks and their lookup.
pub(crate) struct Blocks {
    /// (tag, index of the block's first op in `ops`, one past its last); the tag is the
    /// block's address and the code epoch, as the board's decode cache keys them.
    slots: Box<[(u64, u32, u32)]>,
    ops: Vec<BlockOp>,
    /// The [`System::code_epoch`] the blocks were decoded in.
    epoch: u32,
    /// Bumped whenever `ops` is cleared: cursors of an older generation are void.
    generation: u64,
    cursor: [Cursor; 2],
    /// Blocks decoded so far (for tests and reports).
    pub(crate) decoded: u64,
    /// The compiled regions ([`crate::accel::jit`]) that arbitrate against the other core.
    pub(crate) jit: Jit,
    /// The same regions compiled for a core whose every access is later than the other
    /// core's last bank claim ([`jit::Flavour::Solo`]).
    pub(crate) solo: Jit,
    /// The same regions compiled confined, for running ahead ([`run_confined`]): one
    /// cache per bank mask met (the masks come from [`crate::Config::own_banks`] and their
    /// complements, so a few).
    pub(crate) confined: Vec<Jit>,
    /// Confined without arbitration ([`jit::Flavour::ConfinedSolo`]), per bank mask.
    pub(crate) confined_solo: Vec<Jit>,
    /// Per core, the last bank mask and journaling [`run_confined`] ran it with, and their
    /// caches' indices in `confined_solo` and `confined` (the lists only grow).
    confined_last: [Option<ConfinedAt>; 2],
    /// Per core, the PC at which timed native code stopped at the last run's limit
    /// ([`run_confined`]): the next run goes on pre-decoded to the end of the block there.
    timed_cut: [Option<u32>; 2],
    /// Runs of timed native code that stopped at their limit (for tests and reports).
    pub(crate) timed_stops: u64,
    /// The undo journals of the two cores in a window (entries as [`crate::accel::jit`] writes
    /// them; [`crate::board`]'s `window.rs`).
    pub(crate) journal: Vec<u64>,
    /// The other core's.
    pub(crate) journal_other: Vec<u64>,
    /// The memoized calls ([`crate::accel::memo`]).
    pub(crate) memo: Memos,
    /// The memoized spans' entries, which no confined region runs through ([`Blocks::set_stops`]).
    stops: std::sync::Arc<[u32]>,
}

#[inline(always)]
fn tag(pc: u32, epoch: u32) -> u64 {
    (epoch as u64) << 32 | pc as u64
}

/// True when `instr` may write the PC (or trap): it ends its block.
fn ends_block(instr: &Instr) -> bool {
    use Instr::*;
    match *instr {
        B { .. } | BCond { .. } | Bl { .. } | Bx { .. } | Blx { .. } => true,
        Svc { .. } | Bkpt { .. } | Udf { .. } | Undefined { .. } => true,
        Pop { list } => list & 0x8000 != 0,
        AddHi { rdn, .. } => rdn == 15,
        MovHi { rd, .. } => rd == 15,
        _ => false,
    }
}

/// The cycle from which core `core`'s accesses to the SRAM banks `banks` (bit per bank) can
/// wait no more while the other core takes no turn: the other core's last claim of any of
/// them (0 when it claimed none).
pub(crate) fn quiet_from(sys: &System, core: usize, banks: u8) -> u64 {
    (0..tactus_rp2040::memory::BANKS)
        .filter(|b| banks >> b & 1 != 0)
        .map(|b| sys.bank_claim[b][(core ^ 1) & 1])
        .filter(|&c| c != u64::MAX)
        .max()
        .unwrap_or(0)
}

impl Blocks {
    /// Makes the confined region caches, where memos are tried ([`run_confined`]), end
    /// their regions before the addresses `stops` (sorted, Thumb bit clear:
    /// [`Jit::set_stops`]), the ones made later too.
    pub(crate) fn set_stops(&mut self, stops: Vec<u32>) {
        self.stops = stops.into();
        for j in self
            .confined
            .iter_mut()
            .chain(self.confined_solo.iter_mut())
        {
            j.set_stops(self.stops.clone());
        }
    }

    pub(crate) fn new() -> Blocks {
        Blocks {
            slots: vec![(u64::MAX, 0, 0); SLOTS].into_boxed_slice(),
            ops: Vec::new(),
            epoch: 0,
            generation: 0,
            cursor: [Cursor::default(); 2],
            decoded: 0,
            jit: Jit::new(jit::Flavour::Shared),
            solo: Jit::new(jit::Flavour::Solo),
            confined: Vec::new(),
            confined_solo: Vec::new(),
            confined_last: [None; 2],
            timed_cut: [None; 2],
            timed_stops: 0,
            journal: Vec::with_capacity(JOURNAL),
            journal_other: Vec::with_capacity(JOURNAL),
            memo: Memos::default(),
            stops: std::sync::Arc::from([]),
        }
    }

    /// The index of the confined cache (`solo`: without arbitration, in
    /// `confined_solo`; else in `confined`) for bank mask `mask`, with or without journal
    /// code, with or without the code that logs the I/O's accesses (`io`), timed or not
    /// ([`jit::Flavour::Confined`]), made on first use with the board's compile threshold.
    fn confined_index(
        &mut self,
        solo: bool,
        mask: u8,
        journaled: bool,
        io: bool,
        timed: bool,
    ) -> usize {
        let threshold = self.jit.threshold;
        let (list, flavour) = if solo {
            (
                &mut self.confined_solo,
                jit::Flavour::ConfinedSolo(mask, journaled, io, timed),
            )
        } else {
            (
                &mut self.confined,
                jit::Flavour::Confined(mask, journaled, io, timed),
            )
        };
        match list.iter().position(|j| j.flavour() == flavour) {
            Some(at) => at,
            None => {
                let mut j = Jit::new(flavour);
                j.threshold = threshold;
                j.set_stops(self.stops.clone());
                list.push(j);
                list.len() - 1
            }
        }
    }

    fn clear(&mut self, epoch: u32) {
        self.ops.clear();
        self.generation += 1;
        self.epoch = epoch;
    }

    /// The rest of core `id`'s block when it stopped at `pc` in it.
    #[inline(always)]
    fn resume(&self, id: usize, pc: u32) -> Option<(usize, usize)> {
        let c = self.cursor[id & 1];
        let (op, end) = (c.op as usize, c.end as usize);
        (c.generation == self.generation && op < end && self.ops.get(op)?.pc == pc)
            .then_some((op, end))
    }

    /// The block starting at `pc` (decoded now if need be): its range in `ops`.
    #[inline(always)]
    fn find(&mut self, sys: &mut System, pc: u32) -> Option<(usize, usize)> {
        if sys.code_epoch != self.epoch {
            self.clear(sys.code_epoch);
        }
        let slot = ((pc >> 1) as usize) & (SLOTS - 1);
        let (t, first, end) = self.slots[slot];
        if t == tag(pc, self.epoch) && (end as usize) <= self.ops.len() {
            return Some((first as usize, end as usize));
        }
        self.decode(sys, pc, slot)
    }

    #[inline(never)]
    fn decode(&mut self, sys: &mut System, pc: u32, slot: usize) -> Option<(usize, usize)> {
        if self.ops.len() + MAX_BLOCK > MAX_OPS {
            self.clear(self.epoch);
            self.slots.fill((u64::MAX, 0, 0));
        }
        let first = self.ops.len();
        let mut a = pc;
        while self.ops.len() - first < MAX_BLOCK {
            let Ok((hw1, hw2, size)) = sys.fetch_instr(a) else {
                break;
            };
            for h in [a, a.wrapping_add(size - 2)] {
                if let Some((off, _)) = sram_location(h) {
                    sys.code_pages[off >> 8] = true;
                }
            }
            let instr = decode(hw1, hw2);
            let cost = (
                timing::cycles(&instr, false, false) as u8,
                timing::cycles(&instr, true, false) as u8,
            );
            self.ops.push(BlockOp {
                op: Op::new(&instr, a),
                instr,
                pc: a,
                size: size as u8,
                store: matches!(
                    timing::class(&instr),
                    Class::Store | Class::StoreMultiple | Class::Push
                ),
                cost,
                worst_from: (cost.0.max(cost.1).max(1) as u32) + jit::data_words(&instr),
            });
            if ends_block(&instr) {
                break;
            }
            a = a.wrapping_add(size);
        }
        let end = self.ops.len();
        if end == first {
            return None;
        }
        // Suffix sums: the bound from each instruction to the block's end.
        for i in (first..end - 1).rev() {
            self.ops[i].worst_from += self.ops[i + 1].worst_from;
        }
        self.slots[slot] = (tag(pc, self.epoch), first as u32, end as u32);
        self.decoded += 1;
        Some((first, end))
    }
}

/// Who else takes turns while a core runs its blocks, and how their turns follow from the
/// running core's cycles.
pub(crate) trait Turns {
    /// `after` must see every instruction's end cycle (else a block whose bound fits
    /// runs with no per-instruction call).
    const EACH: bool;
    /// After an instruction that ended at `cycle`.
    fn after(&mut self, cycle: u64);
    /// After native code that ended at `cycle`, whose last instruction of two cycles or
    /// more ended at `q` (0: none).
    fn after_native(&mut self, cycle: u64, q: u64);
}

/// No one else: the core runs alone, or the caller's limit ends its turn.
pub(crate) struct Alone;

impl Turns for Alone {
    const EACH: bool = false;
    #[inline(always)]
    fn after(&mut self, _: u64) {}
    #[inline(always)]
    fn after_native(&mut self, _: u64, _: u64) {}
}

/// A sleeping core whose turns only move its cycle counter (see [`crate::board`]'s
/// `run_beside_sleeper`): on each of its turns before `wake`, `cycle` becomes
/// `min(wake, running core's cycle + 1)`; its turn comes once the running core's cycle
/// reaches its own (`loses_ties`: the sleeper is core 1, which loses ties, so the turn
/// comes one cycle later).
pub(crate) struct Sleeper<'a> {
    pub(crate) cycle: &'a mut u64,
    pub(crate) wake: u64,
    pub(crate) loses_ties: bool,
}

impl Turns for Sleeper<'_> {
    const EACH: bool = true;

    #[inline(always)]
    fn after(&mut self, r: u64) {
        // (A turn that finds the sleeper at its wake check ends the run: the caller takes
        // it, after the block.)
        let s = &mut *self.cycle;
        if r >= *s + self.loses_ties as u64 && *s < self.wake {
            *s = self.wake.min(r + 1).max(*s + 1);
        }
    }

    /// The same turns taken after each instruction of the native run, in closed form. Let
    /// `s` be the sleeper's cycle before and `r` the running core's after. The sleeper is
    /// core 0 (`!loses_ties`): its first turn comes at the first instruction end at or
    /// after `s`, and each turn leaves it one cycle ahead, so every later instruction end
    /// gives it another: `r + 1` if `r >= s`. The sleeper is core 1: a turn comes at an
    /// end at least one cycle past it and leaves it one cycle ahead, so after a
    /// one-cycle instruction it is level (no turn) and after the next one behind again
    /// (a turn); an instruction of two cycles or more always gives it a turn. So from the
    /// later of the last such instruction's end `q` and the first turn (`s + 1`), the
    /// one-cycle instructions to `r` alternate: `r + 1` after an even number of them,
    /// `r` after an odd one. Both are capped at `wake`, where the turns stop.
    #[inline(always)]
    fn after_native(&mut self, r: u64, q: u64) {
        let s = *self.cycle;
        if s >= self.wake {
            return;
        }
        let next = if self.loses_ties {
            if r < s + 1 {
                s
            } else {
                let p = q.max(s + 1);
                r + (r - p).is_multiple_of(2) as u64
            }
        } else if r < s {
            s
        } else {
            r + 1
        };
        *self.cycle = next.min(self.wake);
    }
}

/// Runs `core` on blocks while its cycle is below `limit` (the caller has checked that
/// the core may take the fast path: [`crate::board`]'s `fast_ready`), with `turns` told of
/// the instructions' end cycles. A region compiled to native code ([`crate::accel::jit`]) runs
/// whenever its bound fits before `limit`; otherwise the block's pre-decoded instructions
/// run, with one deadline check per block when its bound fits and `turns` need not see
/// every instruction. `Ok` when the core reached `limit` (at its first
/// instruction boundary at or after it), else why it left, with the instruction that needs
/// the general path not started. Not inlined: its arguments cannot alias, so the compiler
/// may keep the core's counters in registers across the block.
#[inline(never)]
pub(crate) fn run<T: Turns>(
    core: &mut Core,
    sys: &mut System,
    blocks: &mut Blocks,
    limit: u64,
    turns: &mut T,
) -> Result<(), Leave> {
    let mut retired = 0u64;
    let mut native = true;
    // The other core takes no turn during this run: once the core's cycle reaches the
    // other's last claim of any bank, none of its accesses can wait (solo code).
    let quiet_from = quiet_from(sys, core.id, u8::MAX);
    let result = loop {
        if core.cycle >= limit {
            break Ok(());
        }
        let pc = core.r[15];
        if native {
            let cache = if core.cycle >= quiet_from {
                &mut blocks.solo
            } else {
                &mut blocks.jit
            };
            if let Some(region) = cache.lookup(sys, pc) {
                if core.cycle.saturating_add(region.bound) <= limit {
                    let (exit, n, q) = jit::call(region.f, core, sys, limit);
                    retired += n;
                    turns.after_native(core.cycle, q);
                    match exit {
                        jit::Exit::Invalidate => sys.invalidate_code(),
                        // The next instruction needs the pre-decoded path (or the general).
                        jit::Exit::General => native = false,
                        jit::Exit::Out | jit::Exit::Deadline => {}
                    }
                    continue;
                }
            }
        }
        native = true;
        let found = match blocks.resume(core.id, pc) {
            Some(r) if sys.code_epoch == blocks.epoch => Some(r),
            _ => blocks.find(sys, pc),
        };
        let Some((mut i, end)) = found else {
            break Err(Leave::Miss);
        };
        let epoch = sys.code_epoch;
        let ops = &blocks.ops[..end];
        let mut leave = None;
        if !T::EACH && core.cycle.saturating_add(ops[i].worst_from as u64) <= limit {
            // The whole rest of the block starts before `limit`: no per-instruction check.
            let start = i;
            for o in &ops[start..] {
                if !core.execute_op(sys, &o.op, &o.instr, o.pc, o.size as u32, o.cost) {
                    leave = Some(Leave::General);
                    break;
                }
                i += 1;
                if o.store && sys.code_epoch != epoch {
                    break;
                }
            }
            retired += (i - start) as u64;
        } else {
            while i < end {
                if core.cycle >= limit {
                    break;
                }
                let o = &ops[i];
                if !core.execute_op(sys, &o.op, &o.instr, o.pc, o.size as u32, o.cost) {
                    leave = Some(Leave::General);
                    break;
                }
                retired += 1;
                i += 1;
                turns.after(core.cycle);
                if o.store && sys.code_epoch != epoch {
                    break;
                }
            }
        }
        blocks.cursor[core.id & 1] = Cursor {
            op: i as u32,
            end: end as u32,
            generation: blocks.generation,
            at_limit: false,
        };
        if let Some(l) = leave {
            break Err(l);
        }
    };
    core.instructions += retired;
    result
}

/// Whether the fast path may fetch the instruction at `pc` of `size` bytes now (its SRAM
/// banks allowed, [`System::allows`]; flash and ROM always).
#[inline(always)]
fn fetch_allowed(sys: &System, pc: u32, size: u32) -> bool {
    [pc, pc.wrapping_add(size - 2)]
        .into_iter()
        .all(|a| sram_location(a).is_none_or(|(off, _)| sys.allows(off as u32)))
}

/// Appends to `journal` the old value of each SRAM word the store `instr` (a
/// [`BlockOp::store`]) writes when it runs with `core`'s registers now, as the confined
/// native code journals its stores ([`crate::accel::jit`]): entries `offset << 32 | old
/// word`, the offset word-aligned. False, with nothing appended, when the journal has no
/// room for them ([`JOURNAL`]) or `instr` is a store form the fast path does not run. A
/// store the executor then does not complete leaves entries for words it did not write,
/// which undo to the values they hold: harmless, but the caller takes them back.
fn journal_store(core: &Core, sys: &System, instr: &Instr, journal: &mut Vec<u64>) -> bool {
    let r = &core.r;
    let (addr, words) = match *instr {
        Instr::MemImm { op, rn, imm, .. } if op.is_store() => {
            (r[rn as usize & 15].wrapping_add(u32::from(imm)), 1)
        }
        Instr::MemReg { op, rn, rm, .. } if op.is_store() => {
            (r[rn as usize & 15].wrapping_add(r[rm as usize & 15]), 1)
        }
        Instr::Stm { rn, list } => (r[rn as usize & 15], list.count_ones()),
        Instr::Push { list } => {
            let n = list.count_ones();
            (r[13].wrapping_sub(4 * n), n)
        }
        _ => return false,
    };
    if journal.len() + words as usize > JOURNAL {
        return false;
    }
    for k in 0..words {
        if let Some((off, _)) = sram_location(addr.wrapping_add(4 * k)) {
            let word = off as u32 & !3;
            journal.push(u64::from(word) << 32 | u64::from(sys.sram_peek(word)));
        }
    }
    true
}

/// [`run`] confined to the SRAM banks in [`System::allowed_banks`] (set by the caller), for
/// a window ([`crate::board`]'s `window.rs`): compiled regions come from the
/// confined cache, whose loads and stores leave before an access to another bank, and
/// pre-decoded instructions run through the executor, whose fast path does the same; an
/// instruction fetched from another bank leaves too. With `journal`, every store's old word
/// is appended to `journal` — by the native code, and by [`journal_store`] before a
/// pre-decoded store — (the run ends before a store that finds it full) so that the
/// caller can undo the run; where a region does not fit before `limit` (a meeting's run
/// of core 1 to core 0's cycle, `window.rs`) its timed variant runs, which checks the
/// deadline before each instruction ([`jit::Flavour::Confined`]), or pre-decoded blocks
/// until that is compiled; pre-decoded blocks also run through the rest of a block the
/// core stopped in at the last run's limit (by either), and elsewhere an
/// instruction native code does not run ends the run (`Err(Leave::General)`). With `io`
/// (a window on a board with an I/O: its log, the DMA's banks `L`, and those of `L` the
/// core may access, `accel/io_window/`), memos that touch `L` apply too, logging their
/// accesses there, and native code does and logs its single loads and stores to the third
/// mask's banks and its word stores to the I/O's registers ([`jit::Ctx::io_banks`]). `Ok`
/// when the core reached `limit`.
pub(crate) fn run_confined(
    core: &mut Core,
    sys: &mut System,
    blocks: &mut Blocks,
    limit: u64,
    mut journal: Option<&mut Vec<u64>>,
    mut io: Option<(&mut Vec<crate::accel::io_window::IoAccess>, u8, u8)>,
) -> Result<(), Leave> {
    let allowed = sys.allowed_banks;
    let io_own = io.as_ref().map_or(0, |&(_, _, own)| own & !allowed);
    let mut retired = 0u64;
    let mut native = true;
    // The other core does not touch the allowed banks while this one runs (see
    // [`crate::board`], "Running ahead"), so its claims of them stay as they are: once the
    // core's cycle reaches the last, no access can wait.
    let quiet_from = quiet_from(sys, core.id, allowed | io_own);
    let journaled = journal.is_some();
    // Code that logs the I/O's accesses only where there are some to log: it is larger,
    // and compiling it cost the plain board's demo 3.7 % more instructions.
    let io_code = io_own != 0;
    let at = match blocks.confined_last[core.id & 1] {
        Some(at) if at.mask == allowed && at.journaled == journaled && at.io == io_code => at,
        _ => {
            let mut index =
                |solo, timed| blocks.confined_index(solo, allowed, journaled, io_code, timed);
            let at = ConfinedAt {
                mask: allowed,
                journaled,
                io: io_code,
                solo: index(true, false),
                shared: index(false, false),
                timed_solo: index(true, true),
                timed_shared: index(false, true),
            };
            blocks.confined_last[core.id & 1] = Some(at);
            at
        }
    };
    // The native code's context, for the whole run (`jit::Ctx::confined`); it counts the
    // instructions the native code retires.
    let io_ctx = match sys.io_control() {
        Some(i) if io_own != 0 => Some((io_own, i as *const crate::io::Io)),
        _ => None,
    };
    let mut ctx = jit::Ctx::confined(sys, io_ctx);
    let timed_cut = blocks.timed_cut[core.id & 1].take();
    // Blocks still to run pre-decoded after the one the core resumed in (see `inside`).
    let mut tail = 0u32;
    let mut first = true;
    let result = loop {
        if core.cycle >= limit {
            break Ok(());
        }
        let pc = core.r[15];
        // A region at `pc` that does not fit before `limit`.
        let mut unfit = false;
        // The rest of a block the core stopped in at the last run's limit (core 1 at a
        // meeting's cut, `window.rs`) runs pre-decoded: no region is looked up, and none
        // compiled, at an instruction inside a block (a meeting's cut falls anywhere).
        // So does the rest of the block from where timed native code stopped at that limit,
        // and after it up to [`TAIL_BLOCKS`] blocks more while each ends going forward (a
        // conditional or plain branch ahead, or no branch): the cut falls anywhere in the
        // code, and a region compiled at each place the core went on from (a *tail*, a few
        // instructions inside a compiled region) cost the demo 0.30 G, most of it compiling.
        // Only where the run starts: a block this run leaves before its end stops it (at
        // `limit`) or starts a new code epoch, and timed native code stops it.
        let resumed = std::mem::take(&mut first)
            && ((blocks.cursor[core.id & 1].at_limit
                && blocks.resume(core.id, pc).is_some()
                && sys.code_epoch == blocks.epoch)
                || timed_cut == Some(pc));
        if resumed {
            tail = TAIL_BLOCKS;
        }
        let inside = tail > 0;
        if inside {
            unfit = true;
        } else if blocks.memo.watches(pc) {
            let solo = core.cycle >= quiet_from;
            match blocks.memo.call::<false>(
                core,
                sys,
                limit,
                solo,
                allowed,
                journal.as_deref_mut(),
                io.as_mut().map(|(log, l, _)| (&mut **log, *l)),
                None,
            ) {
                Try::Applied => continue,
                Try::Record => break Err(Leave::Record),
                Try::Run => {}
            }
        }
        if native && !inside {
            let solo = core.cycle >= quiet_from;
            let cache = if solo {
                &mut blocks.confined_solo[at.solo]
            } else {
                &mut blocks.confined[at.shared]
            };
            if let Some(mut region) = cache.lookup(sys, pc) {
                let fits = core.cycle.saturating_add(region.bound) <= limit;
                // A region that does not fit runs timed, once compiled so.
                let timed = match (fits, solo) {
                    (true, _) => None,
                    (false, true) => blocks.confined_solo[at.timed_solo].lookup(sys, pc),
                    (false, false) => blocks.confined[at.timed_shared].lookup(sys, pc),
                };
                if let Some(t) = timed {
                    region = t;
                }
                if (fits || timed.is_some()) && region.banks & !allowed == 0 {
                    let log = io
                        .as_mut()
                        .filter(|_| io_own != 0)
                        .map(|(log, ..)| &mut **log);
                    let (f, journal) = (region.f, journal.as_deref_mut());
                    match jit::call_confined(f, core, sys, limit, &mut ctx, journal, log) {
                        jit::Exit::Invalidate => sys.invalidate_code(),
                        jit::Exit::General => native = false,
                        jit::Exit::Out | jit::Exit::Deadline => {}
                    }
                    if timed.is_some() && core.cycle >= limit {
                        blocks.timed_cut[core.id & 1] = Some(core.r[15]);
                        blocks.timed_stops += 1;
                    }
                    continue;
                }
                unfit = true;
            }
        }
        // With a journal, blocks run only where a region does not fit before `limit`; an
        // instruction native code left to the general path, or code not compiled, goes
        // there (the executor's fast path would mostly refuse it too: trying it first cost
        // the demo 0.26 G more with the watchdog off).
        if !unfit && journal.is_some() {
            break Err(Leave::General);
        }
        native = true;
        let found = match blocks.resume(core.id, pc) {
            Some(r) if sys.code_epoch == blocks.epoch => Some(r),
            _ => blocks.find(sys, pc),
        };
        let Some((mut i, end)) = found else {
            break Err(Leave::Miss);
        };
        let epoch = sys.code_epoch;
        let ops = &blocks.ops[..end];
        let mut leave = None;
        while i < end && core.cycle < limit {
            let o = &ops[i];
            // A store journals the words it will overwrite first (taken back if it leaves).
            let mark = journal.as_ref().map_or(0, |j| j.len());
            if !fetch_allowed(sys, o.pc, o.size as u32)
                || (o.store
                    && journal
                        .as_deref_mut()
                        .is_some_and(|j| !journal_store(core, sys, &o.instr, j)))
                || !core.execute_op(sys, &o.op, &o.instr, o.pc, o.size as u32, o.cost)
            {
                if let Some(j) = journal.as_deref_mut() {
                    j.truncate(mark);
                }
                leave = Some(Leave::General);
                break;
            }
            retired += 1;
            i += 1;
            if o.store && sys.code_epoch != epoch {
                break;
            }
        }
        if inside {
            tail = match ops[i.max(1) - 1].instr {
                _ if i < end => 0,
                Instr::B { offset } | Instr::BCond { offset, .. } if offset >= 0 => tail - 1,
                ref last if !ends_block(last) => tail - 1,
                _ => 0,
            };
        }
        blocks.cursor[core.id & 1] = Cursor {
            op: i as u32,
            end: end as u32,
            generation: blocks.generation,
            at_limit: leave.is_none(),
        };
        if let Some(l) = leave {
            break Err(l);
        }
    };
    core.instructions += retired + ctx.retired;
    result
}
