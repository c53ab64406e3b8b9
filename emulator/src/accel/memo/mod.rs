//! Memoized calls: a call whose every input is as it was at a recorded call is replaced by
//! that call's effect, exactly.
//!
//! **Why.** A keyboard's keys are at rest most of the time, and a key at rest reads the same
//! sensor word and the same state sample after sample: its update computes, cycle for cycle,
//! what it computed the sample before. Emulating it again is the bulk of a performance's
//! work. The board is told which functions to watch ([`crate::Board::memoize`]: the
//! image's key updates); a call is what runs from such an entry (the core's PC at it, LR the
//! return address) until the PC is at the return address with SP as at the entry.
//!
//! **A memo** is one call, recorded on the interpreter as it ran: its *inputs* — the
//! registers and flags it read before writing them (each instruction's reads and writes,
//! [`usage`]), the code epoch, and every SRAM byte it loaded before storing to it — and its
//! *effect*: the registers and flags it wrote, the final value of every SRAM byte it stored
//! to, its cycles and instructions, and each bank's last claim as an offset from the entry
//! cycle. At a watched entry, a memo whose inputs equal the core's registers and memory now
//! is applied instead of running the call: the same code on the same inputs takes the same
//! path, reads the same words and writes the same values in the same cycles, so the effect
//! is the call's. That rests on what a call may touch while it is recorded, enforced there:
//!
//! * only SRAM data (a load or store elsewhere — flash, ROM, SIO, a peripheral, the private
//!   peripheral bus, checked before the instruction from its address — gives the recording
//!   up: those answer by time or have side effects); code fetched from SRAM, flash or ROM
//!   is the code of the epoch, and a store into a page holding decoded code starts a new
//!   epoch ([`System::code_epoch`]), which voids every memo of the old one;
//! * only the instructions [`usage`] knows (no MRS/MSR/CPS, no hint but NOP and YIELD, no
//!   SVC, BKPT, UDF or barrier), and no change of IPSR, PRIMASK, CONTROL, the other stack
//!   pointer, the event register, the Thumb bit or the run state (an exception return, a
//!   sleep);
//! * no wait state (the recording is dropped when the core's contention stalls grew), and
//!   no exception taken: the call runs confined in a window before the core's deadline, and
//!   the recording ends at the deadline.
//!
//! A memo is applied only under the same conditions: no access can wait (the core's cycle
//! at or past the other core's last claim of its banks, [`crate::accel::block`]'s solo
//! condition), every instruction starts before the run's limit (entry cycle + the call's
//! cycles at most the limit), its banks allowed, its stores journaled like native code's
//! (room for every word), and no page it stores to holding decoded code (else the store
//! would have started a new epoch). In a window on a board with an I/O (`accel/io_window/`)
//! the banks its DMA may reach are not allowed, but a memo recorded there under the same
//! banks holds its accesses to them (their cycles from the entry, values) and a hit logs
//! them for the I/O's replay, which checks them as the run's own. Loads from a page that held decoded code when they
//! were recorded are not compared: until the epoch changes no store reaches that page.
//!
//! **Based memos.** Two inputs of a call would make a memo per place rather than per
//! value. A register among r0-r3 that the call reads only as the base of immediate-offset
//! loads (a key update's r1: its sensor words, in whichever of the converter drivers'
//! ring of results buffers this sample's are) is not compared: the words loaded through it
//! are, where it points now ([`Based`]), when each lies in the bank it lay in at the
//! recording (so the cycles and claims are the same) and apart from every word the call's
//! other accesses touched (so none can meet a store of the call). And a register among
//! r4-r7 that the call pushes before reading it and pops back from the same word, touched
//! by nothing else in between and read by nothing after ([`Save`]), is not compared
//! either: a hit leaves it as it is and stores its value where the call pushed it. Where
//! a base's words and I/O accesses lie for a delta depends on nothing but the delta, so a
//! based memo works it out once for each of the last [`MOVED`] deltas ([`Moved`]), not at
//! every call (the converter demo: 18.05 → 18.02 G). A call
//! site's recordings look for either only once a call came with another value in one of
//! r0-r7 that its last recorded call read (where nothing moves, as on a board without
//! converters, looking costs about 2 % of the demo's instructions and finds nothing). Tests:
//! `tests/memo.rs::a_memo_moves_with_its_base_and_keeps_the_saved_registers`, and the
//! random calls (loads through r0-r3, data repeating every 16 bytes, bases moved by 16).
//!
//! **The return address.** A function's call site is the core, the entry and the first
//! argument r0 (a key's state: the keys of an image share their program's update), not
//! the return address: with the sensor check on, each key's update is called from each of
//! the handler's copies of the keys' code (`tactus-firmware`'s `glue/checks.rs`, `Turns`),
//! and sites by return address each saw a quarter of a key's calls. A call that pushes LR
//! while it holds its entry value and pops that word into PC, LR read nowhere else and the
//! word touched by nothing else in between, returns to whatever LR held at the entry: its
//! memo compares of LR only the Thumb bit and the top nibble (an `EXC_RETURN` value would
//! make the `POP` an exception return), and a hit stores LR into the pushed word and sets
//! PC to it (the `POP`'s cycles do not depend on the address). Any other call compares LR
//! and returns where it was recorded returning. The demo with the sensor check:
//! 21.04 → 18.68 G instructions, hits 1.77 → 1.98 M, misses 656 → 445 k, recordings
//! 8,043 → 3,174. Test: `tests/memo.rs::a_memo_returns_to_its_own_caller`.
//!
//! **When to record.** Recording runs the call on the interpreter, several times the
//! native code's cost; a moving key's inputs differ every sample. So per call site (the
//! function, the core and the first argument) each recording doubles the misses to wait
//! before the next one, up to 4,095; a hit makes the next miss record (a key that moved
//! and stopped is memoized at once) but takes only one halving off the wait per 256 hits in
//! a row, so a key that keeps changing between hits (settling slowly on its felts, or
//! cycling through more states than a site keeps) is not interpreted at every miss; new
//! code at the site starts its backoff afresh. A span (a core's whole keys part) whose last
//! run had a call of a watched function miss its memo (a key moving: the span's next run
//! would not repeat this one) is not recorded, its backoff counted as if it were: on the
//! demo that took the span recordings from 941 to 160 (plain board) and from 1,212 to
//! 353 (converters), each an interpretation of every key of a core, for 15 % fewer span
//! hits (`tests/memo.rs::a_span_whose_call_missed_last_run_is_not_recorded`).
//!
//! **Spans of a firmware's keys code.** With the sensor check's turns a core's keys code
//! comes in four copies, one per class of samples (`tactus-firmware`'s `Turns`), and its
//! keys at rest cycle through their differentiator rings' 17 states: a span of the whole
//! keys part, dispatch included, would come round only every 68 samples (more states than
//! a site keeps, each recorded through a backoff). So each copy is a span of its own
//! (from after the dispatch), of 17 states. A span is tried only where a core is
//! dispatched, so no confined region runs through a span's entry (`Jit::set_stops`).
//! Its recording interprets the span, but takes each watched function's call in it from
//! the call's memo where one applies ([`Recording::nest`]: the memo's inputs and effect
//! logged as the call's instructions would be), as `block::run_confined` would: a key's
//! update is most of a span's cycles, and interpreting it made the four copies' 136
//! recordings a board cost more than their hits saved (keyboard bench's steady pass
//! 5.22 G host instructions, 3.89 G with the nesting; 3.99 G with no span hit at all).
//! Without an I/O only (`tactus-firmware` watches no span on a board with converters).
//! Test: `tests/memo.rs::a_span_recording_takes_a_call_from_its_memo`. Tests:
//! `tests/memo.rs` (random calls
//! against the interpreter, one input changed at a time), `firmware/tests/image.rs` and the
//! keyboard comparisons (firmware images on the block engine, memoized, against the
//! interpreter).

use crate::accel::io_window::{IoAccess, IoKind};
use crate::bus::sram_bank;
use crate::core::{Core, RunState};
use crate::exec::literal_address;
use crate::system::System;
use tactus_isa::decode::{self, AluOp, Instr};
// The flag bits of [`Usage`]: N, Z, C, V as `effects` numbers them.
use tactus_isa::effects::{self, C, N, V, Z};
use tactus_rp2040::memory::{sram_location, BANKS};

mod based;
mod record;

use based::{based_of, Based};
pub(crate) use record::usage;
pub(crate) use record::Recording;
use record::{flags_of, holds, peek, poke, special_of, words, Entry, Save, Stores, Word};

/// Memos kept per call site (the least recently used goes first): a key at rest calls
/// its update in up to 17 states in turn (its differentiator ring's positions; on a
/// converter board, three times as many places its sensor words are read from, the ring
/// of results buffers of `tactus-firmware`'s `image/io.rs`, which based memos fold into
/// one). With 48 the converter demo took 80.54 G instructions, with 64 59.21 G (before
/// based memos; the plain demo 15.41 G either way).
const PER_SITE: usize = 64;
/// Most sites of one watched function on one core, each its own first argument (a
/// key's state, [`Site::arg`]); then one more for its calls with any other: r0 may be
/// data, not a key's state, and sites are looked for one by one.
const ARGS: usize = 64;
/// Successors a memo remembers ([`Memo::next`]), tried in turn before a scan of the
/// site's memos.
const NEXTS: usize = 4;
/// No memo, in [`Memo::next`].
const NONE: u8 = u8::MAX;
/// Return addresses a site tells apart ([`Site::lrs`]): with the sensor check on, the
/// handler's four copies of the keys' code (`tactus-firmware`'s `Turns`).
const CLASSES: usize = 4;
// A site's memo indices fit `Memo::next`'s bytes, with `NONE` left over.
const _: () = assert!(PER_SITE < NONE as usize);
/// Most instructions a recorded call may run.
const MAX_INSTRUCTIONS: u64 = 50_000;
/// Most SRAM accesses a recording logs.
const MAX_ACCESSES: usize = 16_384;
/// A call site waits at most `2^MAX_BACKOFF - 1` calls between recordings.
const MAX_BACKOFF: u32 = 12;
/// Hits in a row that take one halving off a site's backoff.
const DECAY: u32 = 256;
/// A site tries all its memos (not only the predicted one) within this many calls of its
/// last hit or recording: a key at rest finds its states, a moving one costs no scan of
/// memos that do not match.
const SCAN_AFTER: u32 = 64;
/// Most watched entries.
pub const MAX_ENTRIES: usize = 64;
/// Registers a call's loads may be based on ([`Based`]): the AAPCS argument registers
/// r0-r3 (a key update's r1 is its sensor words' address).
const BASES: u16 = 0xf;
/// Registers a call may save and restore ([`Save`]): the callee-saved low registers
/// r4-r7 (AAPCS), which a key update pushes at its entry and pops at its return.
const SAVES: std::ops::RangeInclusive<u8> = 4..=7;

/// What the memos did (for tests and reports).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MemoStats {
    /// Calls replaced by a memo.
    pub hits: u64,
    /// Of those, the hits whose memo was not the one predicted (the one applied after the
    /// site's last memo the time before), found by trying the site's others.
    pub unpredicted: u64,
    /// Emulated cycles of those calls.
    pub hit_cycles: u64,
    /// Watched entries reached with no memo matching.
    pub misses: u64,
    /// Calls recorded into a memo.
    pub recorded: u64,
    /// Recordings given up (the call touched something a memo cannot hold, or did not
    /// return before the deadline).
    pub abandoned: u64,
}

/// The registers (bit *n*: r*n*, r0-r14; PC is never an input, its value is the code's)
/// and flags ([`effects::N`], `Z`, `C`, `V`) an instruction may read, and those it writes. A register
/// or flag an instruction writes only sometimes (the carry of a shift by a register) is
/// among its reads too, so that a write counts only where it always happens.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Usage {
    pub reads: u16,
    pub writes: u16,
    pub flag_reads: u8,
    pub flag_writes: u8,
}

/// One recorded call (see the module documentation).
#[derive(Clone, Debug)]
struct Memo {
    epoch: u32,
    /// The registers it reads before writing them: per register all ones when it does,
    /// else 0 ...
    live: [u32; 16],
    /// ... and their values at the entry (0 for the others): compared lane by lane.
    regs_in: [u32; 16],
    live_flags: u8,
    flags_in: u8,
    /// Input bytes, by word.
    reads: Vec<Word>,
    /// Stored bytes, by word, with their final values (but for words stored back as they
    /// were read, which the inputs' match already guarantees).
    writes: Stores,
    /// One past the last byte of any of those words (checked against the SRAM's length
    /// once per use).
    end: usize,
    /// 256-byte pages of the stored bytes, as groups of eight of [`System::code_pages`]:
    /// the first page's index and a mask of the group's bytes (`0xff` per page stored to),
    /// so that a hit reads eight pages' flags at once ([`Memo::stores_to_code`]).
    pages: Vec<(u32, u64)>,
    /// Words a hit may journal: `writes`, `saved` and `lr`'s.
    stores: usize,
    /// Registers and flags set by the call (r15 among them), and their values: per
    /// register, all ones when the call leaves it as it was, else 0 (r_i becomes
    /// `r_i & keep[i] | regs_out[i]`, lane by lane with no branch) ...
    keep: [u32; 16],
    /// ... the values of the registers set (0 for the others) ...
    regs_out: [u32; 16],
    /// ... and the flags.
    out_flags: u8,
    flags_out: u8,
    cycles: u64,
    instructions: u64,
    /// The banks the core claimed and its last claim of each, from the entry cycle (the
    /// first `claimed` of them).
    claims: [(u8, u64); BANKS],
    claimed: u8,
    /// SRAM banks the call fetched from, loaded from or stored to.
    banks: u8,
    /// The recording's [`Recording::io_banks`] and accesses to them (cycles from the
    /// entry, stores' old words unset): a hit in a window on a board with an I/O logs them.
    io_banks: u8,
    io: Vec<IoAccess>,
    /// Its base, when its loads through a register are compared where the register points
    /// now (that register then not compared itself).
    based: Option<Box<Based>>,
    /// Callee-saved registers the call pushed and popped back ([`Save::Restored`]): the
    /// SRAM word (offset) it pushed each to and the register. A hit stores each one's
    /// value there (not compared: the call leaves it as it was).
    saved: Vec<(u32, u8)>,
    /// The SRAM word (offset) the call pushed its return address to and popped it from
    /// into PC, LR not read otherwise (module documentation, "The return address"): a hit
    /// stores LR there and returns to it. `None`: LR is compared as any register, PC set
    /// as recorded.
    lr: Option<u32>,
    /// [`Memos`]' clock at its last use.
    used: u64,
    /// Indices in its site of the memos applied after it, the latest first ([`NONE`]:
    /// none yet): a based memo stands for several states (a key's sensor words in each
    /// results buffer of a converter board), each with its own successor.
    next: [u8; NEXTS],
    /// The memo applied after it last at a call from each of its site's return addresses
    /// ([`Site::lrs`]; [`NONE`]: none yet): the memo predicted first.
    by_class: [u8; CLASSES],
}

impl Memo {
    #[inline]
    fn inputs_match(&mut self, core: &Core, sys: &System) -> bool {
        if self.epoch != sys.code_epoch {
            return false;
        }
        // Lane by lane with no branch (the compiler's vector instructions).
        let mut d = 0;
        for i in 0..16 {
            d |= (core.r[i] & self.live[i]) ^ self.regs_in[i];
        }
        if d != 0 || flags_of(core) & self.live_flags != self.flags_in {
            return false;
        }
        let sram = &sys.sram[..];
        if self.end > sram.len() {
            return false;
        }
        // SAFETY: every word's offset + 4 is at most `self.end`.
        let held = unsafe { holds(sram, &self.reads) };
        held && (self.based.as_deref_mut())
            .is_none_or(|b| b.matches(core.r[b.reg as usize].wrapping_sub(b.at), sram))
    }

    /// Whether the memo stores to a page of [`System::code_pages`] (its pages' flags read
    /// eight at a time).
    #[inline]
    fn stores_to_code(&self, sys: &System) -> bool {
        let flags = &sys.code_pages[..];
        self.pages.iter().any(|&(first, mask)| {
            let first = first as usize;
            // `bool` is one byte, 0 or 1 (its groups lie in the flags: checked here).
            first + 8 > flags.len()
                // SAFETY: `first + 8 <= flags.len()`.
                || unsafe { std::ptr::read_unaligned(flags.as_ptr().add(first) as *const u64) }
                    & mask
                    != 0
        })
    }

    /// Before [`Memo::apply`] at `entry`: its accesses to the DMA's banks into a window's
    /// `log`, at the hit's cycles, each store with the word as it is before the memo (the
    /// replay takes the stored words back to the oldest of those, `accel/io_window/`).
    fn log_io(&mut self, entry: u64, core: &Core, sys: &System, log: &mut Vec<IoAccess>) {
        if self.io.is_empty() {
            return;
        }
        let moved = self.based.as_deref_mut().and_then(|b| {
            let delta = core.r[b.reg as usize].wrapping_sub(b.at);
            (delta != 0).then(|| {
                let i = b.moved(delta);
                &b.moved[i].io[..]
            })
        });
        for (i, a) in self.io.iter().enumerate() {
            let mut a = *a;
            // A load through the base: where the base points now (its bank the same,
            // `Based::matches`).
            if let Some(&(_, off)) = moved.and_then(|m| m.iter().find(|x| x.0 == i as u32)) {
                a.addr = off;
            }
            a.start += entry;
            a.cycle += entry;
            a.old = sys.sram_peek(a.addr & !3);
            log.push(a);
        }
    }

    fn apply(&self, core: &mut Core, sys: &mut System, journal: Option<&mut Vec<u64>>) {
        // A word that already holds its final bytes is left alone (a key at rest rewrites
        // the same state): no store, no journal entry (undoing it would change nothing).
        let sram = &mut sys.sram[..];
        // `inputs_match` has checked `self.end` against the SRAM's length (which never
        // changes): only a memo whose inputs matched is applied.
        assert!(self.end <= sram.len());
        let mut j = journal;
        // The return address, before the registers are set (the call may write LR).
        let lr = core.r[14];
        let mut store = |off: u32, mask: u32, value: u32| {
            // SAFETY: every word's offset + 4 is at most `self.end`.
            let old = unsafe { peek(sram, off) };
            if old & mask != value {
                if let Some(j) = j.as_deref_mut() {
                    j.push(u64::from(off) << 32 | u64::from(old));
                }
                // SAFETY: as above.
                unsafe { poke(sram, off, old & !mask | value) };
            }
        };
        for &(off, value) in &self.writes.full {
            store(off, u32::MAX, value);
        }
        for w in &self.writes.part {
            store(w.off, w.mask, w.value);
        }
        for &(off, r) in &self.saved {
            store(off, u32::MAX, core.r[r as usize & 15]);
        }
        if let Some(off) = self.lr {
            store(off, u32::MAX, lr);
        }
        // Lane by lane with no branch.
        for i in 0..16 {
            core.r[i] = core.r[i] & self.keep[i] | self.regs_out[i];
        }
        if self.lr.is_some() {
            // `POP {..., pc}` of the word holding LR: its bit 0 is the Thumb bit, compared.
            core.r[15] = lr & !1;
        }
        if self.out_flags != 0 {
            let f = (flags_of(core) & !self.out_flags) | self.flags_out;
            (core.n, core.z, core.c, core.v) = (f & N != 0, f & Z != 0, f & C != 0, f & V != 0);
        }
        let entry = core.cycle;
        let k = core.id & 1;
        for &(b, d) in &self.claims[..self.claimed as usize] {
            sys.bank_claim[b as usize][k] = entry + d;
        }
        core.cycle = entry + self.cycles;
        core.instructions += self.instructions;
    }
}

/// A call site: a watched function called on one core with one first argument (a key of
/// the image: the keys share their program's update, each its own state in r0), from any
/// return address (each key's update is called from every copy of the handler's code), or
/// a span on one core. Its memos, newest last, the one applied last, and how many calls to let run
/// before the next recording.
#[derive(Clone, Debug)]
struct Site {
    core: usize,
    pc: u32,
    /// Where its calls end, a span's (a function's calls end at the return address in
    /// LR at their entry; 0 here).
    end: u32,
    /// Whether its entry is a span's (its end fixed), not a function's (the return
    /// address in LR).
    span: bool,
    /// A function's first argument (r0) at its calls (a key's state); `None` for a span,
    /// and for a function's calls with any first argument past the [`ARGS`] first.
    arg: Option<u32>,
    memos: Vec<Memo>,
    /// Index in `memos` of the memo applied last (`usize::MAX`: none).
    last: usize,
    /// Calls to let run before the next recording.
    wait: u32,
    /// Recordings not followed by a hit, less one per [`DECAY`] hits in a row: the
    /// exponent of the wait after the next recording.
    fails: u32,
    /// Hits since the last miss.
    streak: u32,
    /// The code epoch of its backoff: new code starts it afresh.
    epoch: u32,
    /// Calls since the last hit or recording (saturating): past [`SCAN_AFTER`] a miss
    /// tries the predicted memo only.
    quiet: u32,
    /// Whether its calls' base and saved registers move ([`Based`], [`Save`]): set once a
    /// recording starts with another value in one of r0-r7 that the last recorded call
    /// read (`seen`: which, and their values); until then its recordings track neither
    /// (where nothing moves, tracking costs and gains nothing).
    moving: bool,
    seen: Option<(u16, [u32; 8])>,
    /// The return addresses (LR at the entry) of its calls, the last [`CLASSES`] seen.
    /// With the sensor check on, the keys take turns in four copies of the handler's code
    /// (`tactus-firmware`'s `Turns`), and which copy calls tells which of a based memo's
    /// states comes next: the memo predicted is the one applied after the last at the
    /// same return address ([`Memo::by_class`]), else the latest ([`Memo::next`]). On
    /// the converter demo's traced calls the first guess is right for 2.03 M of 2.04 M
    /// hits, against 1.01 M (20.19 → 19.97 G instructions; plain 13.58 → 13.64 G, where
    /// the latest successor was right already and the look-up costs).
    lrs: [u32; CLASSES],
    /// The slot of `lrs` a new return address takes.
    lr_slot: u8,
}

/// The groups of eight pages ([`Memo::pages`]) of `pages` (ascending, repeats allowed),
/// each within the `len` flags of [`System::code_pages`] (`len` at least 8).
fn page_groups(pages: impl Iterator<Item = u32>, len: usize) -> Vec<(u32, u64)> {
    let last = len.saturating_sub(8) as u32;
    let mut groups: Vec<(u32, u64)> = Vec::new();
    for p in pages {
        match groups.last_mut() {
            Some((first, mask)) if p >= *first && p < *first + 8 => {
                *mask |= 0xff << (8 * (p - *first));
            }
            _ => {
                let first = p.min(last);
                groups.push((first, 0xff << (8 * (p - first))));
            }
        }
    }
    groups
}

/// Notes in a memo's successors `next` ([`Memo::next`]) that the memo at index `i` of its
/// site was applied after it: `i` first, the others kept in order behind it (the last
/// dropped when `i` is new).
fn follow(next: &mut [u8; NEXTS], i: usize) {
    const _: () = assert!(NEXTS == 4);
    let i = i as u8;
    let at = next.iter().position(|&n| n == i).unwrap_or(NEXTS - 1);
    // As one word (no call of `memmove` for three bytes): those before `at` move up one,
    // those after it stay.
    let v = u32::from_le_bytes(*next);
    let after = u32::MAX.checked_shl(8 * (at as u32 + 1)).unwrap_or(0);
    *next = (v & after | (v << 8) & !after & !0xff | u32::from(i)).to_le_bytes();
}

impl Site {
    /// The slot of `lr` in [`Site::lrs`], given one (the oldest-given first) when new.
    #[inline]
    fn class(&mut self, lr: u32) -> usize {
        match self.lrs.iter().position(|&l| l == lr) {
            Some(k) => k,
            None => {
                let k = self.lr_slot as usize % CLASSES;
                self.lrs[k] = lr;
                self.lr_slot = self.lr_slot.wrapping_add(1);
                k
            }
        }
    }

    /// The memo to apply when `first`, the one predicted (see [`Site::lrs`]), does not
    /// match: within [`SCAN_AFTER`] calls of the last hit or recording, the successors of
    /// the memo applied last (`next`), then every memo of the site; after that, none.
    #[inline(never)]
    fn other(
        &mut self,
        next: [u8; NEXTS],
        first: usize,
        core: &Core,
        sys: &System,
        stats: &mut MemoStats,
    ) -> Option<usize> {
        if self.quiet >= SCAN_AFTER {
            // A key moving for a while: no memo tried but the first successor.
            return None;
        }
        let tried = next.iter().take_while(|&&n| n != NONE).count();
        let found = (next[..tried].iter().map(|&n| n as usize))
            .filter(|&n| n != first)
            .find(|&n| {
                self.memos
                    .get_mut(n)
                    .is_some_and(|m| m.inputs_match(core, sys))
            });
        if found.is_some() {
            return found;
        }
        // The successors tried are tried again (rarely: a hit usually stops at the first).
        let i =
            (0..self.memos.len()).find(|&i| i != first && self.memos[i].inputs_match(core, sys));
        stats.unpredicted += i.is_some() as u64;
        i
    }
}

/// What [`Memos::call`] found at a watched entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Try {
    /// A memo was applied: the call is done.
    Applied,
    /// No memo applies: record this call ([`Memos::begin`]).
    Record,
    /// Run the call as usual.
    Run,
}

/// [`Memos`]' site hints (`Default` is not derived for arrays of 64).
#[derive(Clone, Debug)]
struct SiteHints([[u32; 64]; 2]);

impl Default for SiteHints {
    fn default() -> Self {
        SiteHints([[u32::MAX; 64]; 2])
    }
}

/// A board's memos (see the module documentation).
#[derive(Clone, Debug, Default)]
pub(crate) struct Memos {
    /// The watched entries (addresses without the Thumb bit), and where their calls end:
    /// `None` at the return address in LR (a function), else the span's end.
    entries: Vec<(u32, Option<u32>)>,
    /// Bit `(entry >> 1) % 64` of every entry: a clear bit rules a PC out at once.
    filter: u64,
    sites: Vec<Site>,
    /// Per core and bits 1-6 of the entry XOR bits 2-7 of r0, the index in `sites` of
    /// the site found there last: tried first by [`Memos::site`] (a hint, checked before
    /// use).
    hints: SiteHints,
    clock: u64,
    /// Per core, whether a watched function's call missed since the core last entered a
    /// span: a span whose last run had a call miss (a key moving) is not recorded
    /// (module documentation, "When to record").
    call_missed: [bool; 2],
    pub(crate) stats: MemoStats,
}

impl Memos {
    /// Watches the functions at `calls` and the spans `spans` (start, end) (the Thumb bit
    /// ignored; at most [`MAX_ENTRIES`] in all, the rest ignored), forgetting every memo.
    pub(crate) fn watch(&mut self, calls: &[u32], spans: &[(u32, u32)]) {
        let mut e: Vec<(u32, Option<u32>)> = calls
            .iter()
            .map(|c| (c & !1, None))
            .chain(
                spans
                    .iter()
                    .filter(|(a, b)| a & !1 != b & !1)
                    .map(|&(a, b)| (a & !1, Some(b & !1))),
            )
            .collect();
        e.sort_unstable();
        e.dedup_by_key(|x| x.0);
        e.truncate(MAX_ENTRIES);
        self.filter = e.iter().fold(0, |f, x| f | 1 << ((x.0 >> 1) & 63));
        self.entries = e;
        self.sites.clear();
        self.call_missed = [false; 2];
    }

    /// The watched spans' entries (sorted, Thumb bit clear): where no confined region may
    /// run through (`Jit::set_stops`). Not the functions' entries, which their calls reach
    /// by a `BL` (the end of a region): stopping at those too cost the `rp2040_io` demo,
    /// where no span is watched, 0.01 G host instructions.
    pub(crate) fn span_entries(&self) -> Vec<u32> {
        (self.entries.iter())
            .filter(|e| e.1.is_some())
            .map(|e| e.0)
            .collect()
    }

    /// Whether `pc` is a watched entry.
    #[inline(always)]
    pub(crate) fn watches(&self, pc: u32) -> bool {
        self.filter >> ((pc >> 1) & 63) & 1 != 0 && self.entries.iter().any(|e| e.0 == pc)
    }

    /// The call site of `core`'s call (its PC at a watched entry).
    #[inline(always)]
    fn site(&mut self, core: &Core) -> usize {
        let (id, pc) = (core.id, core.r[15]);
        // By entry and first argument: the keys of an image share their program's update,
        // each its own state (r0).
        let slot = (((pc >> 1) ^ (core.r[0] >> 2)) & 63) as usize;
        let hint = &mut self.hints.0[id & 1][slot];
        // The hinted site is this call's when it has the core, the entry and (a function's)
        // the first argument: sites are unique by those (a function's calls from every
        // return address share one).
        if let Some(s) = self.sites.get(*hint as usize) {
            if s.pc == pc && s.core == id && (s.span || s.arg == Some(core.r[0])) {
                return *hint as usize;
            }
        }
        let i = self.find_site(core);
        self.hints.0[id & 1][slot] = i as u32;
        i
    }

    /// [`Memos::site`] without the hint: found or made.
    #[inline(never)]
    fn find_site(&mut self, core: &Core) -> usize {
        let (id, pc) = (core.id, core.r[15]);
        let (end, span) = match self.entries.iter().find(|e| e.0 == pc) {
            Some(&(_, Some(end))) => (end, true),
            _ => (0, false),
        };
        let find = |sites: &[Site], arg| {
            sites
                .iter()
                .position(|s| s.pc == pc && s.core == id && s.arg == arg)
        };
        let mut arg = (!span).then_some(core.r[0]);
        if arg.is_some() && find(&self.sites, arg).is_none() {
            // Past [`ARGS`] first arguments, the entry's calls share one site.
            let n = (self.sites.iter())
                .filter(|s| s.pc == pc && s.core == id)
                .count();
            if n >= ARGS {
                arg = None;
            }
        }
        match find(&self.sites, arg) {
            Some(i) => i,
            None => {
                self.sites.push(Site {
                    core: id,
                    pc,
                    end,
                    span,
                    arg,
                    memos: Vec::new(),
                    last: usize::MAX,
                    wait: 0,
                    fails: 0,
                    streak: 0,
                    epoch: u32::MAX,
                    quiet: 0,
                    moving: false,
                    seen: None,
                    lrs: [0; CLASSES],
                    lr_slot: 0,
                });
                self.sites.len() - 1
            }
        }
    }

    /// At a watched entry (`core`'s PC): applies a memo whose inputs match and which fits
    /// (module documentation: `limit`, the run's; `solo`, no access can wait; `allowed`,
    /// the banks; `journal`, when stores are journaled), or says whether to record the
    /// call. The memo recorded after the one applied last is tried first (a key at rest
    /// cycles through a few states, as a ring buffer's index does).
    // The run's state (core, system, limit, solo, allowed banks) and its two sinks (undo
    // journal, I/O log), as `block::run_confined` holds them.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn call<const NEST: bool>(
        &mut self,
        core: &mut Core,
        sys: &mut System,
        limit: u64,
        solo: bool,
        allowed: u8,
        journal: Option<&mut Vec<u64>>,
        io: Option<(&mut Vec<IoAccess>, u8)>,
        nest: Option<&mut Recording>,
    ) -> Try {
        // `NEST` false (the native run's calls): none, known when compiled.
        let mut nest = if NEST { nest } else { None };
        let s = self.site(core);
        if nest.is_some() && self.sites[s].span {
            return Try::Run;
        }
        self.clock += 1;
        let site = &mut self.sites[s];
        // A span's entry starts a run of its keys: whether one of the last run's missed.
        let moved = site.span && std::mem::take(&mut self.call_missed[core.id & 1]);
        if site.epoch != sys.code_epoch {
            // New code at the site: its calls' past says nothing of these.
            (site.epoch, site.fails, site.wait, site.streak) = (sys.code_epoch, 0, 0, 0);
        }
        let class = site.class(core.r[14]);
        let (next, first) = site
            .memos
            .get(site.last)
            .map_or(([NONE; NEXTS], NONE), |m| {
                let by_class = m.by_class[class];
                (
                    m.next,
                    if by_class != NONE {
                        by_class
                    } else {
                        m.next[0]
                    },
                )
            });
        let first = first as usize;
        let found = match (site.memos.get_mut(first)).is_some_and(|m| m.inputs_match(core, sys)) {
            true => Some(first),
            false => site.other(next, first, core, sys, &mut self.stats),
        };
        site.quiet = site.quiet.saturating_add(1);
        if let Some(i) = found {
            let m = &mut site.memos[i];
            let room = journal
                .as_deref()
                .is_none_or(|j| j.capacity() - j.len() >= m.stores);
            // The DMA's banks (`L`) are not allowed in a window on a board with an I/O,
            // but a memo recorded with the same `L` holds its accesses to them for the
            // window's log.
            let io_banks = io.as_ref().map_or(0, |&(_, l)| l);
            let fits = solo
                && core.cycle.saturating_add(m.cycles) <= limit
                && m.banks & !(allowed | io_banks) == 0
                && (m.banks & io_banks == 0 || m.io_banks == io_banks)
                && room
                && !m.stores_to_code(sys)
                && nest.as_deref().is_none_or(|r| r.can_nest(m));
            if !fits {
                return Try::Run;
            }
            if let Some((log, _)) = io {
                m.log_io(core.cycle, core, sys, log);
            }
            if let Some(r) = nest.as_deref_mut() {
                r.nest(m, core);
            }
            m.apply(core, sys, journal);
            m.used = self.clock;
            self.stats.hit_cycles += m.cycles;
            if let Some(l) = site.memos.get_mut(site.last) {
                follow(&mut l.next, i);
                l.by_class[class] = i as u8;
            }
            site.last = i;
            // The next miss records (a key that moved and stopped again is memoized at
            // once), but a hit does not end the backoff: a key whose state keeps changing
            // between hits (settling slowly, or cycling through more states than a site
            // keeps) would otherwise record — interpret a whole call — at every miss after
            // a hit, and wait no longer after each. A site earns back one halving per
            // [`DECAY`] hits in a row.
            site.streak = site.streak.saturating_add(1);
            if site.streak.is_multiple_of(DECAY) {
                site.fails = site.fails.saturating_sub(1);
            }
            site.wait = 0;
            site.quiet = 0;
            self.stats.hits += 1;
            return Try::Applied;
        }
        self.stats.misses += 1;
        site.streak = 0;
        if !site.span {
            self.call_missed[core.id & 1] = true;
        }
        if nest.is_some() {
            // Within a recording: the call is recorded with it, not on its own.
            return Try::Run;
        }
        if site.wait > 0 || !solo {
            site.wait = site.wait.saturating_sub(1);
            return Try::Run;
        }
        site.wait = (1u32 << site.fails.min(MAX_BACKOFF)) - 1;
        site.fails += 1;
        site.quiet = 0;
        if moved {
            // A key of the span missed last run: the backoff as after a recording, none.
            return Try::Run;
        }
        Try::Record
    }

    /// Starts recording the call `core` is about to make (its PC at a watched entry).
    pub(crate) fn begin(&mut self, core: &Core, sys: &System) -> Recording {
        let k = core.id & 1;
        let site = self.site(core);
        let s = &mut self.sites[site];
        if let Some((live, r)) = s.seen {
            s.moving |= (0..8).any(|i| live >> i & 1 != 0 && core.r[i] != r[i]);
        }
        let moving = s.moving;
        let span = s.span;
        Recording {
            site,
            end: if span { s.end } else { core.r[14] & !1 },
            entry: Entry {
                r: core.r,
                flags: flags_of(core),
                cycle: core.cycle,
                instructions: core.instructions,
                stalls: sys.contention_stalls[k],
                claims: sys.bank_claim.map(|c| c[k]),
                epoch: sys.code_epoch,
                special: special_of(core),
            },
            live_regs: 0,
            def_regs: 0,
            live_flags: 0,
            def_flags: 0,
            fetch_banks: 0,
            log: Vec::new(),
            spoiled: false,
            io_banks: 0,
            io: Vec::new(),
            bases: if moving { BASES } else { 0 },
            via: None,
            moving,
            log_via: Vec::new(),
            io_via: Vec::new(),
            saves: [if moving { Save::Entry } else { Save::Lost }; 4],
            saving: 0,
            kept: if moving { 0xf0 } else { 0 },
            restored: 0,
            lost: if moving { 0 } else { 0xf0 },
            slots: (u32::MAX, 0),
            lr: if span { Save::Lost } else { Save::Entry },
            lr_moving: false,
        }
    }

    /// Gives a recording up.
    pub(crate) fn abandon(&mut self, _rec: Recording) {
        self.stats.abandoned += 1;
    }

    /// Ends a recording whose call has returned ([`Recording::returned`]) on `core`: keeps
    /// its memo, unless the call waited for a bank or changed the code epoch.
    pub(crate) fn finish(&mut self, rec: Recording, core: &Core, sys: &System) {
        let k = core.id & 1;
        let e = &rec.entry;
        if rec.spoiled
            || sys.contention_stalls[k] != e.stalls
            || sys.code_epoch != e.epoch
            || !rec.after(core)
        {
            self.stats.abandoned += 1;
            return;
        }
        // The inputs: bytes loaded before any store of the call to them, outside pages of
        // code; the outputs: every byte stored. Each access as one number per SRAM word it
        // touches, sorted by word and then by its place in the log: the word (bits 32-63)
        // and the place (bits 0-31); then each word's accesses in the log's order. (One
        // number per byte cost the keyboard bench's steady pass 3.89 G host instructions
        // against 3.76 G, most of it sorting.)
        let mut keys: Vec<u64> = Vec::with_capacity(rec.log.len() + 8);
        let mut banks = rec.fetch_banks;
        let based = based_of(&rec);
        let base_bit = based.as_ref().map_or(0, |b| 1u16 << b.reg);
        // The loads through the base are its words, not inputs here (their places in the
        // log, ascending).
        let mut through = (rec.log_via.iter())
            .filter(|x| based.is_some() && 1u16 << x.1 == base_bit)
            .map(|x| x.0 as usize)
            .peekable();
        for (n, a) in rec.log.iter().enumerate() {
            banks |= 1 << sram_bank(a.off);
            if through.next_if_eq(&n).is_some() {
                continue;
            }
            let (first, last) = (a.off >> 2, (a.off + u32::from(a.size.max(1)) - 1) >> 2);
            keys.push(u64::from(first) << 32 | n as u64);
            if last != first {
                keys.push(u64::from(last) << 32 | n as u64);
            }
        }
        keys.sort_unstable();
        let (mut inputs, mut stored): (Vec<(u32, u8)>, Vec<u32>) = (Vec::new(), Vec::new());
        for accesses in keys.chunk_by(|a, b| a >> 32 == b >> 32) {
            let word = (accesses[0] >> 32) as u32;
            // Per byte of the word: the value its first load before any store gave (not
            // from a page of code), and whether it was stored.
            let (mut input, mut store) = ([None::<u8>; 4], [false; 4]);
            for &x in accesses {
                let a = &rec.log[x as u32 as usize];
                for i in 0..u32::from(a.size) {
                    let byte = a.off + i;
                    if byte >> 2 != word {
                        continue;
                    }
                    let j = (byte & 3) as usize;
                    if a.store {
                        store[j] = true;
                    } else if !store[j] && !a.code && input[j].is_none() {
                        input[j] = Some((a.value >> (8 * i)) as u8);
                    }
                }
            }
            for j in 0..4 {
                let byte = 4 * word + j as u32;
                if let Some(v) = input[j] {
                    inputs.push((byte, v));
                }
                if store[j] {
                    stored.push(byte);
                }
            }
        }
        let reads = words(inputs.into_iter());
        let writes = words(stored.iter().map(|&b| (b, sys.sram[b as usize])));
        let pages = page_groups(writes.iter().map(|w| w.off >> 8), sys.code_pages.len());
        // A stored word whose bytes are all inputs, stored back with the values they were
        // read with, already holds them whenever the inputs match: applying it would
        // change nothing (a key at rest rewrites its state), so it is left out of the
        // effect. Its page stays in `pages`, its bytes in `end`.
        let end = reads
            .iter()
            .chain(&writes)
            .map(|w| w.off as usize + 4)
            .max()
            .unwrap_or(0);
        let writes: Vec<Word> = writes
            .into_iter()
            .filter(|w| {
                let r = reads.binary_search_by_key(&w.off, |r| r.off);
                !r.is_ok_and(|i| {
                    let r = &reads[i];
                    w.mask & !r.mask == 0 && r.value & w.mask == w.value
                })
            })
            .collect();
        // The saved registers the call left as they were, and the words it pushed them to.
        let saved: Vec<(u32, u8)> = (SAVES)
            .filter_map(|r| match rec.saves[(r - 4) as usize] {
                Save::Restored(at)
                    if rec.live_regs >> r & 1 != 0
                        && core.r[r as usize] == e.r[r as usize]
                        && sys.sram_peek(at) == e.r[r as usize] =>
                {
                    Some((at, r))
                }
                _ => None,
            })
            .collect();
        // The return address, pushed and popped into PC, its word holding it again and
        // not among the I/O's accesses (whose values a hit logs as recorded).
        let lr = match rec.lr {
            Save::Restored(at)
                if rec.live_regs >> 14 & 1 != 0
                    && core.r[15] == e.r[14] & !1
                    && sys.sram_peek(at) == e.r[14]
                    && rec.io.iter().all(|a| a.addr & !3 != at) =>
            {
                Some(at)
            }
            _ => None,
        };
        let saved_bits = saved.iter().fold(0u16, |b, &(_, r)| b | 1 << r);
        // LR is no input then; the call sets it only where it writes it (`def_regs`).
        let lr_bit = u16::from(lr.is_some()) << 14;
        let writes: Vec<Word> = (writes.into_iter())
            .filter(|w| saved.iter().all(|&(at, _)| at != w.off) && lr != Some(w.off))
            .collect();
        // The base and the saved registers are no inputs, and the call leaves them as
        // they were (the base unless it writes it).
        let live_regs = rec.live_regs & !base_bit & !saved_bits & !lr_bit;
        let out_regs = (live_regs | rec.def_regs | 1 << 15) & !saved_bits;
        let out_flags = rec.live_flags | rec.def_flags;
        let (mut claims, mut claimed) = ([(0, 0); BANKS], 0);
        for b in 0..BANKS {
            let now = sys.bank_claim[b][k];
            if now != e.claims[b] {
                claims[claimed] = (b as u8, now - e.cycle);
                claimed += 1;
            }
        }
        let mut live: [u32; 16] =
            std::array::from_fn(|i| 0u32.wrapping_sub(u32::from(live_regs >> i & 1)));
        if lr.is_some() {
            // Of a return address, only what makes the `POP` a plain return to it: the
            // Thumb bit and the top nibble (0xf in handler mode: an exception return).
            live[14] = 0xf000_0001;
        }
        let memo = Memo {
            epoch: e.epoch,
            live,
            regs_in: std::array::from_fn(|i| e.r[i] & live[i]),
            live_flags: rec.live_flags,
            flags_in: e.flags & rec.live_flags,
            end,
            reads,
            pages,
            stores: writes.len() + saved.len() + usize::from(lr.is_some()),
            keep: std::array::from_fn(|i| if out_regs >> i & 1 != 0 { 0 } else { u32::MAX }),
            regs_out: std::array::from_fn(|i| if out_regs >> i & 1 != 0 { core.r[i] } else { 0 }),
            out_flags,
            flags_out: flags_of(core) & out_flags,
            cycles: core.cycle - e.cycle,
            instructions: core.instructions - e.instructions,
            claims,
            claimed: claimed as u8,
            banks,
            io_banks: rec.io_banks,
            io: rec.io,
            writes: Stores::new(&writes),
            based: based.map(Box::new),
            saved,
            lr,
            used: self.clock,
            next: [NONE; NEXTS],
            by_class: [NONE; CLASSES],
        };
        self.stats.recorded += 1;
        let site = &mut self.sites[rec.site];
        site.seen = Some((rec.live_regs & 0xff, std::array::from_fn(|i| e.r[i])));
        // Memos of a past epoch never match again.
        let before = site.memos.len();
        site.memos.retain(|m| m.epoch == sys.code_epoch);
        if site.memos.len() >= PER_SITE {
            if let Some(old) = (0..site.memos.len()).min_by_key(|&i| site.memos[i].used) {
                site.memos.swap_remove(old);
            }
        }
        if site.memos.len() != before {
            // Indices moved: forget the successors.
            site.last = usize::MAX;
            for m in &mut site.memos {
                m.next = [NONE; NEXTS];
                m.by_class = [NONE; CLASSES];
            }
        }
        // The new memo follows the one applied last (a cycle of states comes round in order).
        let at = site.memos.len();
        let class = site.class(e.r[14]);
        if let Some(l) = site.memos.get_mut(site.last) {
            follow(&mut l.next, at);
            l.by_class[class] = at as u8;
        }
        site.last = site.memos.len();
        site.memos.push(memo);
    }
}

#[cfg(test)]
mod tests {
    use super::{follow, NEXTS, NONE};

    #[test]
    fn successors_are_kept_latest_first_without_repeats() {
        let mut next = [NONE; NEXTS];
        follow(&mut next, 5);
        assert_eq!(next, [5, NONE, NONE, NONE]);
        for i in [7, 9, 11] {
            follow(&mut next, i);
        }
        assert_eq!(next, [11, 9, 7, 5]);
        // One already there moves to the front; nothing is lost or repeated.
        follow(&mut next, 7);
        assert_eq!(next, [7, 11, 9, 5]);
        follow(&mut next, 7);
        assert_eq!(next, [7, 11, 9, 5]);
        // A new one pushes the oldest out.
        follow(&mut next, 2);
        assert_eq!(next, [2, 7, 11, 9]);
    }
}
