//! The fault checks' code in the image (docs/firmware.md, "Faults"; `super::super::fault`):
//! a key's sensor check and its trip path, the copy of a key's state words its recovery
//! makes, and the watchdog's enabling, feed and fault-record restore. Kept beside the
//! handler's glue, whose registers and record layout they share (`super`'s module
//! documentation).

use super::{ctrl, ldr_rec, KeyCode};
use tactus_compiler::thumb::buffer::{CodeBuffer, Label};
use tactus_compiler::thumb::ins::{self as asm, cond};
use tactus_isa::decode::{AluOp, Instr};
use tactus_rp2040::watchdog::BOOT_MAGIC;

/// The plausibility check of a key's first sensor word (a key's position, a pen's depth;
/// docs/firmware.md, "Faults"), and the key's trip path.
///
/// **Every sample** the handler copies the word to the record (the update reads the copy)
/// and checks its change since the copy it replaces: `d = new − copy` must lie in
/// `[−2^shift, 2^shift)` (`SUBS`, `ASRS`, `ADDS #1`, `LSRS #1`, `BNE`: `(d >> shift) + 1`
/// is 0 or 1 exactly then), 2^shift being the power of two at or above the largest change
/// a plausible reading makes: the key's physics plus the declared sensor noise on both
/// readings ([`super::super::fault::max_step_raw`]). Its static cost on the path
/// that runs the update: 11 cycles (the load of the word, the copy's load and store, the
/// five instructions) less the sensor pointer's set-up the update no longer needs from the
/// window.
///
/// **A trip** (the branch taken) runs the key's trip path instead of its update: it checks
/// the word's range (`[lo, hi]`, the sensor's declared range) and its change since the
/// last reading ([`SensorCheck::last_offset`]), and
/// - when either fails: the copy set to a *poison* word (half the word space away from the
///   range, so that every later reading fails the every-sample check and comes here), the
///   recovery count to [`SensorCheck::recovery`]; on the first trip of a fault (the count
///   was 0) the core's fault record gets the trip (kind, slot, trips + 1; the sample) and
///   so do the watchdog's scratch registers;
/// - when both hold: one less to count; at 0 the key recovers: the copy is the reading, its
///   state is put back to rest — the rest image its `init` left at boot, copied back
///   (`LDM`/`STM`, 3 cycles a word: cheaper than the update, whose place it takes; the
///   update's differentiators then start again from the reading) — the guard's counter 0;
/// - always: the key's force words are 0, and the handler joins the key's limiters (so its
///   DAC words are 0 from this sample on while tripped, [`super::super::fault`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SensorCheck {
    /// The sensor word's declared range, raw.
    pub lo: i32,
    /// See [`SensorCheck::lo`].
    pub hi: i32,
    /// The accepted change per sample is `[−2^shift, 2^shift)` raw (1 to 30).
    pub shift: u8,
    /// Byte offset in the record of the recovery count (0: the key plays; ≤ 124).
    pub left_offset: u32,
    /// Byte offset in the record of the last reading while tripped (≤ 124).
    pub last_offset: u32,
    /// The key's window slot, for the fault word.
    pub slot: u8,
    /// Plausible samples before a tripped key plays again.
    pub recovery: u32,
    /// Address of the key's rest image: its state as its `init` left it at boot (the reset
    /// handler copies it there), which the recovery copies back.
    pub rest: u32,
    /// Words of the state struct.
    pub state_words: u32,
    /// The key's turn ([`Turns`]): the class of samples whose handler checks it, `None`
    /// when every sample does (a key with the quiescent-key guard, or a core whose tick has
    /// no accumulator).
    pub turn: Option<u8>,
    /// Per drive, byte offsets in the record of the limiter's rated-magnitude threshold
    /// and gain words while the key takes turns: the limiter reads them there (not from
    /// the literal pool), and the trip path sets them to `u32::MAX` and 0 while the key is
    /// tripped, so that its DAC code is 0 in the samples between its checks
    /// ([`super::limiter_inline`]'s earn path: `m ≤ u32::MAX`, `m · 0`). Empty when
    /// `turn` is `None`.
    pub gate: Vec<Gate>,
    /// The state check (docs/firmware.md, "Faults", the flipped-bit row): per mode of the
    /// key's program, its byte's offset in the state struct (`StateLayout::modes` + the
    /// mode's index, ≤ 31) and its variants (1–255). At each of the key's checks, after
    /// its sensor word passed, the handler tests each mode byte below its variants
    /// (`LDRB`, `CMP`, `BCS`: 4 cycles a mode, on the path of the one key a copy checks)
    /// and on a byte out of range takes the key's trip path as a `state-range` trip
    /// ([`super::super::fault::FaultKind::StateRange`]): its force words 0, its limiters
    /// gated, the fault record written, and its recovery (plausible readings, then its
    /// state copied back from the rest image, where every mode is valid) as a sensor
    /// trip's. The one state word a flipped bit leaves out of range that the update keeps
    /// and reads: every other state word the update rewrites (saturated to its range)
    /// before it reads it, or keeps in range whatever its bits. Empty: no state check.
    pub modes: Vec<(u8, u8)>,
}

/// One drive's gate words ([`SensorCheck::gate`]): where they lie in the record and what
/// they hold while the key plays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Gate {
    /// Byte offset of the rated-magnitude threshold word (≤ 124).
    pub rated_offset: u32,
    /// Byte offset of the gain word (≤ 124).
    pub gain_offset: u32,
    /// The threshold while the key plays (`DacScale::last_magnitude_within(rated_code)`).
    pub rated: u32,
    /// The gain while the key plays (`DacScale::gain`).
    pub gain: u32,
}

impl SensorCheck {
    /// The poison word of the copy while the key is tripped: half the word space from the
    /// middle of the range, so `word − poison` is beyond `2^shift` for every word within
    /// `2^31 − 2^shift − (hi − lo)/2` of the range.
    pub fn poison(&self) -> u32 {
        let mid = (i64::from(self.lo) + i64::from(self.hi)) / 2;
        (mid as u32).wrapping_add(1 << 31)
    }

    /// The record's words of the check at power-on (byte offset in the record, value): the
    /// copy and the last reading the poison word, the recovery count 0, the gate's words
    /// those of a key that plays. So the key's first check takes the trip path, which
    /// judges the first reading by its range alone (there is no change yet to judge) and,
    /// when it is in range, takes it as the last reading and runs the key's update on it
    /// ([`trip_path`]'s first reading): whatever the key's position at the start (a key
    /// held down at power-on does not trip), its forces and state are the model's from
    /// its first sample. A reading out of range trips as any later one would, and is
    /// recorded in the fault word.
    pub fn seed(&self) -> Vec<(u32, u32)> {
        let p = self.poison();
        let mut w = vec![(0, p), (self.left_offset, 0), (self.last_offset, p)];
        for g in &self.gate {
            w.push((g.rated_offset, g.rated));
            w.push((g.gain_offset, g.gain));
        }
        w
    }

    /// Whether `word` is plausible after `prev` by the every-sample test.
    pub fn step_ok(&self, prev: i32, word: i32) -> bool {
        let d = word.wrapping_sub(prev) >> self.shift;
        d == 0 || d == -1
    }
}

/// Which samples check which keys on a core (docs/firmware.md, "Faults"): the handler
/// runs one of `classes` copies of its keys' code, chosen by two bits of the tick's
/// accumulator ([`super::ctrl::ACC`], already in a register after the tick's step:
/// `class = (acc >> shift) & (classes − 1)`), and copy `c` checks the keys of class `c`.
/// The accumulator repeats with the tick's period (`den` samples), so the state of a
/// board at rest still repeats with it (`super::super::rest`), and the dispatch reads no
/// counter. A key is thus checked every few samples, not every one: its rate bound is
/// the key's physics over the longest gap between two checks of its class plus the
/// noise ([`super::super::fault::max_step_raw`]), its recovery a count of plausible
/// checks that spans at least the stated time over the shortest gap.
///
/// Why: checking every key every sample costs 11 cycles a key, 44 on a core of four
/// piano keys, where grand88's fullest core on `rp2040_io` has 19 to spare; one check a
/// sample plus its dispatch (two flag branches) costs at most 18.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Turns {
    /// Classes of samples (1: every checked key every sample; 2 or 4).
    pub classes: u32,
    /// The accumulator's bit the class starts at.
    pub shift: u8,
    /// Per class: the longest and the shortest gap, samples, from one sample of the
    /// class to the next.
    pub gaps: Vec<(u32, u32)>,
    /// Per class: its samples in one period of the accumulator.
    pub per_period: Vec<u32>,
    /// The accumulator's period, samples (the tick's `den`; 1 for every sample).
    pub period: u32,
    /// Whether the dispatch reaches copies 2 and 3 through a trampoline in each copy
    /// before them (two cycles more a hop): where the copies are too long for one `B`
    /// (2 KiB) from the first.
    pub hops: bool,
    /// Whether each checked key's trip path follows the key's code in its copy, behind a
    /// `B` over it (2 cycles a checked key), instead of at the copy's or the handler's end:
    /// where a copy is too long for the `B`s between a check and its path (2 KiB).
    pub near_trips: bool,
}

/// The most samples between two checks of a key: 1 ms at 44.1 kHz is 44; a gap of at
/// most 40 leaves the converters' sample of delay and a margin.
pub const MAX_GAP: u32 = 40;

/// The longest accumulator period [`Turns::plan`] simulates (a board whose tick's
/// fraction has a larger denominator checks every key every sample).
const MAX_DEN: u32 = 8192;

impl Turns {
    /// Every checked key every sample.
    pub fn every_sample() -> Turns {
        Turns {
            classes: 1,
            shift: 0,
            gaps: vec![(1, 1)],
            per_period: vec![1],
            period: 1,
            hops: false,
            near_trips: false,
        }
    }

    /// The turns of `keys` checked keys that may take turns under tick `t`: as many
    /// classes as keys up to 4 (a power of two), the shift whose classes come back most
    /// evenly (the smallest longest gap, from the accumulator's sequence over a period as
    /// the handler steps it from its first value `rem`); every sample when there is one
    /// key or none, no accumulator (a whole number of cycles a sample), or no shift keeps
    /// every gap within [`MAX_GAP`].
    pub fn plan(t: &super::Tick, keys: usize) -> Turns {
        if keys <= 1 || t.rem == 0 || t.den > MAX_DEN {
            return Turns::every_sample();
        }
        let classes = (keys.next_power_of_two().min(4)) as u32;
        let n = t.den as usize;
        let mut acc = t.rem;
        let seq: Vec<u32> = (0..n)
            .map(|_| {
                // The handler's step: acc − (den − rem), plus den when negative.
                acc = (acc + t.rem) % t.den;
                acc
            })
            .collect();
        let mut best: Option<Turns> = None;
        for shift in 0..(32 - t.den.leading_zeros()) as u8 {
            let class = |a: u32| (a >> shift) & (classes - 1);
            let mut gaps = Vec::with_capacity(classes as usize);
            let mut per_period = Vec::with_capacity(classes as usize);
            for c in 0..classes {
                let at: Vec<usize> = (0..n).filter(|&i| class(seq[i]) == c).collect();
                if at.is_empty() {
                    gaps.clear();
                    break;
                }
                per_period.push(at.len() as u32);
                // Cyclic gaps over the period.
                let g: Vec<u32> = at
                    .iter()
                    .enumerate()
                    .map(|(j, &i)| {
                        let next = at.get(j + 1).copied().unwrap_or(at[0] + n);
                        (next - i) as u32
                    })
                    .collect();
                gaps.push((
                    g.iter().copied().max().unwrap_or(1),
                    g.iter().copied().min().unwrap_or(1),
                ));
            }
            if gaps.is_empty() {
                continue;
            }
            let worst = gaps.iter().map(|g| g.0).max().unwrap_or(u32::MAX);
            if worst <= MAX_GAP && best.as_ref().is_none_or(|b| worst < b.worst_gap()) {
                best = Some(Turns {
                    classes,
                    shift,
                    gaps,
                    per_period,
                    period: t.den,
                    hops: false,
                    near_trips: false,
                });
            }
        }
        best.unwrap_or_else(Turns::every_sample)
    }

    /// The longest gap of any class, samples.
    pub fn worst_gap(&self) -> u32 {
        self.gaps.iter().map(|g| g.0).max().unwrap_or(1)
    }

    /// Checks of class `class` in `samples` samples, rounded up (a key's recovery in
    /// checks: as many as fall in the stated time, within one accumulator period).
    pub fn checks_in(&self, class: u8, samples: u32) -> u32 {
        let n = u64::from(self.per_period[usize::from(class)]);
        (u64::from(samples) * n).div_ceil(u64::from(self.period.max(1))) as u32
    }

    /// The class of the `i`-th key that takes turns.
    pub fn class_of(&self, i: usize) -> u8 {
        (i as u32 % self.classes) as u8
    }

    /// The class of samples whose handler feeds the watchdog ([`Feed::class`], on core 0
    /// of an image at `fs` Hz): the class with the smallest longest gap, the lowest on a
    /// tie (class 0 runs the dispatch's cheapest path, straight on); `None`, every sample
    /// feeds, with one class, or when that gap is longer than
    /// [`super::super::fault::MAX_FEED_GAP_US`] (a healthy board must stay well within the
    /// watchdog's period between two feeds).
    pub fn feed_class(&self, fs: f64) -> Option<u8> {
        if self.classes <= 1 {
            return None;
        }
        let (class, gap) = (0..self.classes as u8)
            .zip(self.gaps.iter().map(|g| g.0))
            .min_by_key(|&(c, g)| (g, c))?;
        let limit = f64::from(super::super::fault::MAX_FEED_GAP_US) * 1e-6 * fs;
        (f64::from(gap) <= limit).then_some(class)
    }
}

/// The every-sample part of [`SensorCheck`]: `r0` = the new word; branches to `trip` when
/// its change from the record's copy at `copy_off` is beyond the bound. Clobbers r1.
pub(super) fn check_step(a: &mut CodeBuffer, c: &SensorCheck, copy_off: u16, trip: Label) {
    a.i(asm::ldr(1, 4, copy_off));
    a.i(asm::subs(1, 0, 1));
    a.i(asm::asrs(1, 1, c.shift));
    a.i(asm::adds_imm(1, 1, 1));
    a.i(asm::lsrs(1, 1, 1));
    a.bc(cond::NE, trip);
}

/// The state check of [`SensorCheck::modes`]: r0 = the key's state struct; branches to
/// `trip` when a mode byte is not below its variants (`LDRB`, `CMP`, `BCS`). Clobbers r1.
pub(super) fn check_modes(a: &mut CodeBuffer, c: &SensorCheck, trip: Label) {
    for &(off, variants) in &c.modes {
        a.i(Instr::MemImm {
            op: tactus_isa::decode::MemOp::Ldrb,
            rt: 1,
            rn: 0,
            imm: u16::from(off),
        });
        a.i(asm::cmp_imm(1, variants));
        a.bc(cond::CS, trip);
    }
}

/// The trip path of [`SensorCheck`] for key `k` (its record at r4): entered with r0 = the
/// word that tripped; ends with a branch to `join` (the key's limiters) with its force
/// words 0, or, for the key's first reading in range, to `resume` (the check's way on to
/// the update) with r0 the word. Uses the control block's address `ctrl_addr` (r5 may be
/// an update's), the watchdog's scratch pair of core `core`.
///
/// **The first reading** (the last reading still the poison word the record starts with,
/// [`SensorCheck::seed`]) has no change to judge: in range, it becomes the last reading,
/// the recovery count 0, and the key's update runs on it as on any plausible reading (the
/// copy is stored on the way on), so a checked key is the model from its first sample,
/// whatever its position at power-on; out of range, it trips as any later reading would.
/// Its cost over the check's path, 21 cycles once per key, is in the static bound.
#[allow(clippy::too_many_arguments)]
fn trip_path(
    a: &mut CodeBuffer,
    k: &KeyCode,
    c: &SensorCheck,
    ctrl_addr: u32,
    core: usize,
    join: Label,
    resume: Label,
    state: Option<Label>,
) {
    use super::super::fault::{self, FaultKind};
    use tactus_rp2040::watchdog::{reg as wreg, WATCHDOG_BASE};
    let (check, bad, zero, gate) = (a.label(), a.label(), a.label(), a.label());
    let (bad_range, tripped) = (a.label(), a.label());
    let (left, last) = (c.left_offset as u16, c.last_offset as u16);
    // The first reading since the start, in range: on to the update.
    a.i(asm::ldr(2, 4, last));
    a.ldr_const(3, c.poison());
    a.i(asm::cmp(2, 3));
    a.bc(cond::NE, tripped);
    range_test(a, c, tripped);
    a.i(asm::str(0, 4, last));
    a.i(asm::movs(1, 0));
    a.i(asm::str(1, 4, left));
    a.b(resume);
    a.bind(tripped);
    // First trip of a fault: the last reading is the copy (the one before this word).
    a.i(asm::ldr(1, 4, left));
    a.i(asm::cmp_imm(1, 0));
    a.bc(cond::NE, check);
    a.i(asm::ldr(1, 4, 0));
    a.i(asm::str(1, 4, last));
    a.bind(check);
    // The range (kind: range).
    a.i(asm::ldr(2, 4, last));
    a.i(asm::str(0, 4, last));
    range_test(a, c, bad_range);
    // The change since the last reading (kind: rate).
    a.i(asm::movs(3, FaultKind::SensorRate.code()));
    a.i(asm::subs(2, 0, 2));
    a.i(asm::asrs(2, 2, c.shift));
    a.i(asm::adds_imm(2, 2, 1));
    a.i(asm::lsrs(2, 2, 1));
    a.bc(cond::NE, bad);
    // Plausible: one less to count; at 0 the key recovers.
    a.i(asm::ldr(1, 4, left));
    a.i(asm::subs_imm(1, 1, 1));
    a.i(asm::str(1, 4, left));
    a.bc(cond::NE, gate);
    a.i(asm::str(0, 4, 0));
    if let Some(g) = &k.guard {
        a.i(asm::movs(1, 0));
        a.i(asm::str(1, 4, g.calm_offset as u16));
    }
    // The state back to rest: the rest image copied over it.
    ldr_rec(a, 0, k.state_offset);
    a.ldr_const(1, c.rest);
    copy_words(a, 1, 0, c.state_words, CopyMode::Unrolled);
    // Its limiters' constants back (a key taking turns).
    for g in &c.gate {
        a.ldr_const(1, g.rated);
        a.i(asm::str(1, 4, g.rated_offset as u16));
        a.ldr_const(1, g.gain);
        a.i(asm::str(1, 4, g.gain_offset as u16));
    }
    a.b(zero);
    // A mode byte out of range ([`SensorCheck::modes`]; the key plays: its recovery count
    // is 0): the reading, stored as the copy, becomes the last reading; then as an
    // implausible reading, of kind state-range.
    if let Some(entry) = state {
        a.bind(entry);
        a.i(asm::ldr(0, 4, 0));
        a.i(asm::str(0, 4, last));
        a.i(asm::movs(3, FaultKind::StateRange.code()));
        a.b(bad);
    }
    // Implausible: poison the copy, count the recovery again; a new fault is a trip.
    a.bind(bad_range);
    a.i(asm::movs(3, FaultKind::SensorRange.code()));
    a.bind(bad);
    a.ldr_const(1, c.poison());
    a.i(asm::str(1, 4, 0));
    a.i(asm::ldr(1, 4, left));
    a.ldr_const(2, c.recovery);
    a.i(asm::str(2, 4, left));
    a.i(asm::cmp_imm(1, 0));
    a.bc(cond::NE, gate);
    a.ldr_const(2, ctrl_addr);
    a.i(asm::ldr(1, 2, ctrl::FAULT));
    a.i(asm::lsrs(1, 1, 16));
    a.i(asm::adds_imm(1, 1, 1));
    a.i(asm::lsls(1, 1, 16));
    a.i(asm::alu(AluOp::Orr, 1, 3));
    a.mov_const(3, u32::from(c.slot) << 8);
    a.i(asm::alu(AluOp::Orr, 1, 3));
    a.i(asm::str(1, 2, ctrl::FAULT));
    a.i(asm::ldr(3, 2, ctrl::SAMPLES));
    a.i(asm::str(3, 2, ctrl::FAULT_AT));
    let (w, _) = fault::scratch(core);
    a.ldr_const(2, WATCHDOG_BASE + wreg::SCRATCH0 + 4 * w);
    a.i(asm::str(1, 2, 0));
    a.i(asm::str(3, 2, 4));
    // A key taking turns stays at DAC code 0 until its next check: its limiters' earn
    // path (every magnitude at or below `u32::MAX`) times a gain of 0.
    a.bind(gate);
    if !c.gate.is_empty() {
        a.i(asm::movs(0, 0));
        a.i(asm::alu(AluOp::Mvn, 1, 0));
        for g in &c.gate {
            a.i(asm::str(1, 4, g.rated_offset as u16));
            a.i(asm::str(0, 4, g.gain_offset as u16));
        }
    }
    // The key's force words 0: its limiters make DAC code 0 of them.
    a.bind(zero);
    motors_to_zero(a, k.drives.iter().map(|d| ZeroWord::Force(d.force_offset)));
    a.b(join);
}

/// A word [`motors_to_zero`] writes the zero force to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum ZeroWord {
    /// A key's force word, at this byte offset in its record (r4): the key's limiter, which
    /// the caller then runs, makes DAC code 0 of it (its earn path: a magnitude of 0), and
    /// its time budget earns as at any zero force.
    Force(u32),
    /// A converter core's DAC channel: its DAC word (r7's frames, [`super::super::io::write_dac`])
    /// code 0, sent by the next sample's DMA, no limiter run.
    Dac(u32),
}

/// The motors at zero force on a fault, the image's one emitter of it: r0 = 0 stored to
/// each of `words` — a tripped key's force words (the sensor check's trip path, which then
/// joins the key's limiters, so a key taking turns keeps its gate) or a stalled converter
/// core's DAC words (the burst check's stall path, whose keys do not run). Both are DAC
/// code 0 in the sample they run in: the limiter of a zero force is code 0 for every
/// format ([`super::limiter_inline`]). Rare paths only: no cycle of the sample path.
/// Leaves r0 = 0; clobbers r1.
pub(super) fn motors_to_zero(a: &mut CodeBuffer, words: impl IntoIterator<Item = ZeroWord>) {
    a.i(asm::movs(0, 0));
    for w in words {
        match w {
            ZeroWord::Force(off) if off <= 124 => a.i(asm::str(0, 4, off as u16)),
            ZeroWord::Force(off) => {
                a.mov_const(1, off);
                a.i(Instr::MemReg {
                    op: tactus_isa::decode::MemOp::Str,
                    rt: 0,
                    rn: 4,
                    rm: 1,
                });
            }
            ZeroWord::Dac(ch) => super::super::io::write_dac(a, ch),
        }
    }
}

/// The range test of [`SensorCheck`]: `r0` = the word; branches to `bad` when it lies
/// outside `[lo, hi]`, tested unsigned as `word − lo > hi − lo` (`SUBS`, `CMP`, `BHI`).
/// Clobbers r1, r3.
fn range_test(a: &mut CodeBuffer, c: &SensorCheck, bad: Label) {
    a.ldr_const(1, c.lo as u32);
    a.i(asm::subs(1, 0, 1));
    a.ldr_const(3, c.hi.wrapping_sub(c.lo) as u32);
    a.i(asm::cmp(1, 3));
    a.bc(cond::HI, bad);
}

/// A checked key's trip path that the handler has branched to but not yet emitted: the
/// check's `BNE` reaches a `B` behind the key's first limiter, which reaches the path
/// where [`trip_paths`] puts it (after the key, its copy or the handler:
/// [`Turns::near_trips`]).
pub(super) struct PendingTrip {
    /// The key's sensor check.
    pub check: SensorCheck,
    /// The path's own label, the target of the `B` behind the key's first limiter.
    pub far: Label,
    /// The key's limiters, where the path joins the handler with the key's force words 0.
    pub join: Label,
    /// The check's way on to the update, for the key's first reading in range.
    pub resume: Label,
    /// The path's entry for a mode byte out of range ([`SensorCheck::modes`]), the target
    /// of a `B` behind the key's first limiter; `None` without a state check.
    pub state: Option<Label>,
    /// The key's index in the core's keys.
    pub key: usize,
}

/// Emits the pending trip paths `trips` (taking them all), each with its literal pool
/// after it, for the core `core` with control block `ctrl_addr` ([`trip_path`]).
pub(super) fn trip_paths(
    a: &mut CodeBuffer,
    trips: &mut Vec<PendingTrip>,
    keys: &[KeyCode],
    ctrl_addr: u32,
    core: usize,
) {
    for t in trips.drain(..) {
        a.bind(t.far);
        trip_path(
            a,
            &keys[t.key],
            &t.check,
            ctrl_addr,
            core,
            t.join,
            t.resume,
            t.state,
        );
        a.pool();
    }
}

/// How [`copy_words`] copies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum CopyMode {
    /// Two words at a time, unrolled: 3 cycles a word (`LDM`/`STM` of r2-r3), code
    /// growing with the words (the trip path's recovery, where cycles count).
    Unrolled,
    /// A word at a time in a loop counting down in r2: 7 cycles a word, fixed code (the
    /// reset handler's).
    Looped,
}

/// Copies `words` (≥ 1) words from the address in r`from` to that in r`to`, both advanced
/// past them: the image's one copy of a key's state words (the rest image made at reset,
/// put back at a recovery). Clobbers r2, r3.
pub(super) fn copy_words(a: &mut CodeBuffer, from: u8, to: u8, words: u32, how: CopyMode) {
    match how {
        CopyMode::Unrolled => {
            // r2-r3 per pair, r2 for an odd last word.
            let pairs = std::iter::repeat_n(0b1100, (words / 2) as usize);
            for list in pairs.chain((words % 2 == 1).then_some(0b100)) {
                a.i(Instr::Ldm { rn: from, list });
                a.i(Instr::Stm { rn: to, list });
            }
        }
        CopyMode::Looped => {
            let top = a.label();
            a.mov_const(2, words);
            a.bind(top);
            a.i(Instr::Ldm {
                rn: from,
                list: 0b1000,
            });
            a.i(Instr::Stm {
                rn: to,
                list: 0b1000,
            });
            a.i(asm::subs_imm(2, 2, 1));
            a.bc(cond::NE, top);
        }
    }
}

/// The watchdog's feed of an image ([`super::super::fault`], "The watchdog"): core 0's handler
/// loads the watchdog at the end of each sample of its feeding class ([`Feed::class`]) in
/// which the other core kept up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Feed {
    /// The address of core 1's sample count ([`ctrl::SAMPLES`] in its control block); `None`
    /// on a one-core image (then the feed checks nothing).
    pub other_samples: Option<u32>,
    /// The class of samples whose handler feeds ([`Turns::feed_class`] of core 0's turns):
    /// the copy of the keys' code of that class ends with its own tail, which feeds, and the
    /// other copies' tail does not (`super::core_code`). `None`: every sample feeds.
    ///
    /// Why: the feed's load of core 1's count makes the two cores meet in the emulator in
    /// every sample that feeds, which costs its speed machinery most of what the feed costs
    /// (the demo fed every sample: 14.86 G host instructions; in class 0's samples, a
    /// quarter: 13.68 G; BENCHMARKS.md). Feeding in one class keeps the hang's upper bound
    /// (the last feed is still at the latest the hang's own sample's: `super::super::fault`,
    /// "The watchdog") and takes the feed's cycles off the other classes' paths; the
    /// feeding path itself is as long or 2 cycles shorter (no branch to the common tail), so the
    /// handler's static bound, the maximum over the copies, does not rise.
    pub class: Option<u8>,
    /// The boot ROM's watchdog entry core 0's start handler arms with the watchdog
    /// ([`enable_watchdog`]): (entry, Thumb bit set; stack pointer), the RAM image's
    /// re-entry (`super::super::reboot`); `None` arms none (SCRATCH4 the non-reboot magic).
    pub entry: Option<(u32, u32)>,
}

impl Feed {
    /// Cycles the feed adds to core 0's handler beyond what the static analysis prices
    /// (it prices every access as SRAM's): the LOAD store's APB wait states, and one
    /// arbitration wait for the load of core 1's count from core 1's bank (core 1's
    /// handler may access that bank in the same cycle).
    pub fn unpriced_cycles(&self) -> u64 {
        u64::from(tactus_isa::timing::APB_STORE_WAIT) + u64::from(self.other_samples.is_some())
    }

    /// Cycles the feed adds to core 1's handler beyond its static analysis: core 0's load
    /// of core 1's count contends for core 1's bank once a sample, and the bank's
    /// arbitration may make core 1 the one that waits (which core waits depends on the
    /// arbiter's state, so a boot from flash and one from RAM may split the cycle
    /// differently). 0 on a one-core image.
    pub fn other_core_cycles(&self) -> u64 {
        u64::from(self.other_samples.is_some())
    }
}

/// The feed at the end of core 0's handler, r1 = core 0's sample count just stored: LOAD =
/// [`super::super::fault::WATCHDOG_LOAD`] when core 1's count is core 0's or one less (core 1
/// finished this sample, or the one before and is finishing this one now); else a branch
/// to `behind` ([`mark_behind`]). Clobbers r0-r2. 13 cycles on the feeding path with two
/// cores (plus [`Feed::unpriced_cycles`]).
pub(super) fn feed_watchdog(a: &mut CodeBuffer, f: &Feed, behind: Label) {
    use tactus_rp2040::watchdog::{reg as wreg, WATCHDOG_BASE};
    if let Some(other) = f.other_samples {
        a.ldr_const(2, other);
        a.i(asm::ldr(2, 2, 0));
        a.i(asm::subs(2, 1, 2));
        a.i(asm::cmp_imm(2, 1));
        a.bc(cond::HI, behind);
    }
    a.ldr_const(0, WATCHDOG_BASE + wreg::LOAD);
    a.ldr_const(1, super::super::fault::WATCHDOG_LOAD);
    a.i(asm::str(1, 0, 0));
}

/// Where [`feed_watchdog`] goes instead of feeding (core 1 more than a sample behind: hung,
/// or stopped finishing its samples): sets [`super::super::fault::BEHIND`] in core 1's
/// fault word in the watchdog's scratch register (through the SET alias, datasheet 2.1.2:
/// no read), so that after the reset the trip is recorded on core 1's side
/// ([`record_watchdog_trip`]). The caller then returns from the handler as the feeding path
/// does. As long as the feed it replaces (a taken branch, a literal, a `MOVS`, an APB
/// store: 7 cycles against the feed's 7, the same 2 APB wait states), so the handler's
/// bound does not change.
pub(super) fn mark_behind(a: &mut CodeBuffer) {
    use super::super::fault::{self, BEHIND};
    use tactus_rp2040::watchdog::{reg as wreg, WATCHDOG_BASE};
    let w = wreg::SCRATCH0 + 4 * fault::scratch(1).0;
    a.ldr_const(0, WATCHDOG_BASE + tactus_rp2040::ATOMIC_SET + w);
    a.i(asm::movs(1, BEHIND as u8));
    a.i(asm::str(1, 0, 0));
}

/// Core 0's start handler enables the watchdog ([`super::super::fault`], "The watchdog"):
/// with [`Feed::entry`], SCRATCH5-7 for the boot ROM's watchdog entry into it (SCRATCH5 =
/// entry ^ −[`BOOT_MAGIC`], SCRATCH6 = SP, SCRATCH7 = entry: pico-sdk's `watchdog_reboot`)
/// and then SCRATCH4 = the word the entry stub wrote at [`super::super::boot::BOOT_SOURCE`]
/// ([`BOOT_MAGIC`] on a RAM image's boot that can come back, the non-reboot magic from
/// flash: `super::super::reboot`); without it SCRATCH4 =
/// [`super::super::fault::NON_REBOOT_MAGIC`]. Then LOAD, CTRL.ENABLE (through the SET
/// alias: the PAUSE bits kept). Clobbers r0-r2.
pub(super) fn enable_watchdog(a: &mut CodeBuffer, f: &Feed) {
    use tactus_rp2040::watchdog::{reg as wreg, CTRL_ENABLE, WATCHDOG_BASE};
    let scratch = |n: u32| (wreg::SCRATCH0 + 4 * n) as u16;
    a.ldr_const(0, WATCHDOG_BASE);
    if let Some((pc, sp)) = f.entry {
        a.ldr_const(1, pc ^ BOOT_MAGIC.wrapping_neg());
        a.i(asm::str(1, 0, scratch(5)));
        a.ldr_const(1, sp);
        a.i(asm::str(1, 0, scratch(6)));
        a.ldr_const(1, pc);
        a.i(asm::str(1, 0, scratch(7)));
        a.ldr_const(1, super::super::boot::BOOT_SOURCE);
        a.i(asm::ldr(1, 1, 0));
    } else {
        a.ldr_const(1, super::super::fault::NON_REBOOT_MAGIC);
    }
    a.i(asm::str(1, 0, scratch(4)));
    a.ldr_const(1, super::super::fault::WATCHDOG_LOAD);
    a.i(asm::str(1, 0, wreg::LOAD as u16));
    a.ldr_const(2, WATCHDOG_BASE + tactus_rp2040::ATOMIC_SET + wreg::CTRL);
    a.ldr_const(1, CTRL_ENABLE);
    a.i(asm::str(1, 2, 0));
}

/// Core 0's reset handler, first (before core 1's launch, so before core 1 copies its
/// pair): after a reset by its own watchdog's count (REASON.TIMER, SCRATCH4 =
/// [`super::super::fault::NON_REBOOT_MAGIC`]; a reset by CTRL.TRIGGER, REASON.FORCE, is
/// a HardFault's, whose handler recorded it, [`hard_fault_handler`]) one more trip of kind
/// [`super::super::fault::FaultKind::Watchdog`] (key [`super::super::fault::NO_KEY`] until
/// [`restore_fault_record`] names it, time 0) in the scratch pair of the core that stopped: core 1's when its fault word holds
/// [`super::super::fault::BEHIND`] (core 0 saw it more than a sample behind, [`mark_behind`]),
/// else core 0's. Then, on a two-core image, the mark cleared. Clobbers r0-r4.
pub(super) fn record_watchdog_trip(a: &mut CodeBuffer, cores: usize) {
    use super::super::fault::{self, FaultKind, BEHIND, NON_REBOOT_MAGIC};
    use tactus_rp2040::watchdog::{reg as wreg, REASON_TIMER, WATCHDOG_BASE};
    let at = |core: usize| (wreg::SCRATCH0 + 4 * fault::scratch(core).0) as u16;
    let (done, own) = (a.label(), a.label());
    a.ldr_const(2, WATCHDOG_BASE);
    a.i(asm::ldr(3, 2, wreg::REASON as u16));
    // REASON.TIMER alone: a FORCE reset is a HardFault's, recorded by its handler.
    a.i(asm::cmp_imm(3, REASON_TIMER as u8));
    a.bc(cond::NE, done);
    a.i(asm::ldr(3, 2, (wreg::SCRATCH0 + 16) as u16));
    a.ldr_const(4, NON_REBOOT_MAGIC);
    a.i(asm::cmp(3, 4));
    a.bc(cond::NE, done);
    // r4 = the offset of the stopped core's fault word from SCRATCH0.
    a.i(asm::movs(4, at(0) as u8));
    if cores > 1 {
        a.i(asm::ldr(0, 2, at(1)));
        a.i(asm::movs(1, BEHIND as u8));
        a.i(asm::alu(AluOp::Tst, 0, 1));
        a.bc(cond::EQ, own);
        a.i(asm::movs(4, at(1) as u8));
    }
    a.bind(own);
    a.i(asm::adds(4, 4, 2));
    one_more_trip(a, 0, 4, FaultKind::Watchdog);
    a.i(asm::movs(1, 0));
    a.i(asm::str(0, 4, 0));
    a.i(asm::str(1, 4, 4));
    a.bind(done);
    if cores > 1 {
        a.i(asm::ldr(0, 2, at(1)));
        a.i(asm::movs(1, BEHIND as u8));
        a.i(asm::alu(AluOp::Bic, 0, 1));
        a.i(asm::str(0, 2, at(1)));
    }
}

/// Where a core's reset handler finds which key hung (`super::super::fault`, "Which key
/// hung"): its return slot and its table of call sites.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HangLookup {
    /// The core's return slot ([`super::super::fault::return_slot`]).
    pub slot: u32,
    /// The table's address: per call site two words, the `BL`'s return address (its
    /// address + 4, Thumb bit set) and its key's window slot.
    pub table: u32,
    /// The table's entries.
    pub entries: u32,
}

impl HangLookup {
    /// The table's bytes for `calls` (per call site: its `BL`'s address, its key's slot).
    pub fn table_bytes(calls: &[(u32, u8)]) -> Vec<u8> {
        let mut t = Vec::with_capacity(8 * calls.len());
        for &(at, slot) in calls {
            t.extend(((at + 4) | 1).to_le_bytes());
            t.extend(u32::from(slot).to_le_bytes());
        }
        t
    }
}

/// The reset handler's copy of core `core`'s fault record from the watchdog's scratch pair
/// (where [`record_watchdog_trip`] counted a watchdog reset, or [`hard_fault_handler`] a
/// HardFault) into its control block (r5). With `hang`, first a watchdog or HardFault trip
/// on the pair whose key is still [`super::super::fault::NO_KEY`] gets its key: the one whose call site the return slot
/// holds the return address of, else [`super::super::fault::UNKNOWN_KEY`]
/// (`super::super::fault`, "Which key hung"); the pair in the scratch registers too.
/// Clobbers r0-r4, r6, r7.
pub(super) fn restore_fault_record(a: &mut CodeBuffer, core: usize, hang: Option<&HangLookup>) {
    use super::super::fault::{self, FaultKind, NO_KEY, UNKNOWN_KEY};
    use tactus_rp2040::watchdog::{reg as wreg, WATCHDOG_BASE};
    let (w, _) = fault::scratch(core);
    let at = (wreg::SCRATCH0 + 4 * w) as u16;
    a.ldr_const(2, WATCHDOG_BASE);
    a.i(asm::ldr(0, 2, at));
    if let Some(h) = hang {
        let (keep, next, unknown, put) = (a.label(), a.label(), a.label(), a.label());
        // The kind and key halfword: a watchdog or HardFault trip not yet named?
        let name = a.label();
        a.i(asm::lsls(3, 0, 16));
        a.i(asm::lsrs(3, 3, 16));
        a.ldr_const(
            1,
            u32::from(NO_KEY) << 8 | u32::from(FaultKind::Watchdog.code()),
        );
        a.i(asm::cmp(3, 1));
        a.bc(cond::EQ, name);
        a.i(asm::adds_imm(
            1,
            1,
            FaultKind::HardFault.code() - FaultKind::Watchdog.code(),
        ));
        a.i(asm::cmp(3, 1));
        a.bc(cond::NE, keep);
        a.bind(name);
        // r3 = the slot's word; r1..r4 the table; r7 = the key.
        a.ldr_const(3, h.slot);
        a.i(asm::ldr(3, 3, 0));
        a.ldr_const(1, h.table);
        a.ldr_const(4, h.table + 8 * h.entries);
        a.bind(next);
        a.i(asm::cmp(1, 4));
        a.bc(cond::EQ, unknown);
        a.i(Instr::Ldm {
            rn: 1,
            list: 0b1100_0000,
        });
        a.i(asm::cmp(6, 3));
        a.bc(cond::NE, next);
        a.b(put);
        a.bind(unknown);
        a.i(asm::movs(7, UNKNOWN_KEY));
        a.bind(put);
        // The key into the word's key byte, in the scratch register and below.
        a.i(asm::lsls(7, 7, 8));
        a.ldr_const(1, u32::from(NO_KEY) << 8);
        a.i(asm::alu(AluOp::Bic, 0, 1));
        a.i(asm::alu(AluOp::Orr, 0, 7));
        a.i(asm::str(0, 2, at));
        a.bind(keep);
    }
    a.i(asm::ldr(1, 2, at + 4));
    a.i(asm::str(0, 5, ctrl::FAULT));
    a.i(asm::str(1, 5, ctrl::FAULT_AT));
}

/// The reset handler's clear of the return slot after its keys' `init`s (whose frames may
/// reach it; `super::super::fault`, "Which key hung"). Clobbers r0, r1.
pub(super) fn clear_return_slot(a: &mut CodeBuffer, hang: &HangLookup) {
    a.ldr_const(0, hang.slot);
    a.i(asm::movs(1, 0));
    a.i(asm::str(1, 0, 0));
}

/// Core `core`'s HardFault handler (its control block at `ctrl_addr`; docs/firmware.md,
/// "Faults"): a fault exception (an unaligned store of a key whose ring position a flipped
/// bit left no multiple of 4, a bus fault, an undefined instruction) records one more trip
/// of kind [`super::super::fault::FaultKind::HardFault`] on the core's pair — key
/// [`super::super::fault::NO_KEY`] (the reset handler names it from the return slot, as a
/// hung key's: [`restore_fault_record`]), time the core's sample count — in its control
/// block and in its watchdog scratch pair, which keep it through the reset, and then
/// writes CTRL.TRIGGER (datasheet 4.7.6, through the SET alias): the chip resets at once
/// (REASON.FORCE, which [`record_watchdog_trip`] leaves to this record), the DACs cleared,
/// instead of the core hanging in `B .` with its motors at their last codes until the
/// watchdog's count runs out. The loop after the store only waits for the reset. Never on
/// the sample path (an exception, not a branch, enters it): no cycle of the proven bound.
/// Uses r0-r3 only, no stack (the faulting core's registers are of no more use).
pub(super) fn hard_fault_handler(a: &mut CodeBuffer, core: usize, ctrl_addr: u32) {
    use super::super::fault::{self, FaultKind};
    use tactus_rp2040::watchdog::{reg as wreg, CTRL_TRIGGER, WATCHDOG_BASE};
    let (w, _) = fault::scratch(core);
    // r1 = the scratch fault word's trips + 1, this kind, no key yet.
    a.ldr_const(2, WATCHDOG_BASE + wreg::SCRATCH0 + 4 * w);
    one_more_trip(a, 1, 2, FaultKind::HardFault);
    a.ldr_const(0, ctrl_addr);
    a.i(asm::ldr(3, 0, ctrl::SAMPLES));
    a.i(asm::str(1, 0, ctrl::FAULT));
    a.i(asm::str(3, 0, ctrl::FAULT_AT));
    a.i(asm::str(1, 2, 0));
    a.i(asm::str(3, 2, 4));
    a.ldr_const(0, WATCHDOG_BASE + tactus_rp2040::ATOMIC_SET + wreg::CTRL);
    a.ldr_const(1, CTRL_TRIGGER);
    a.i(asm::str(1, 0, 0));
    let wait = a.label();
    a.bind(wait);
    a.b(wait);
    a.pool();
}

/// `rd` = the fault word at `[rn]` with one more trip, of kind `kind` and key
/// [`super::super::fault::NO_KEY`] (the count in the high halfword, `super::super::fault`).
/// Clobbers r3.
fn one_more_trip(a: &mut CodeBuffer, rd: u8, rn: u8, kind: super::super::fault::FaultKind) {
    use super::super::fault::NO_KEY;
    a.i(asm::ldr(rd, rn, 0));
    a.i(asm::lsrs(rd, rd, 16));
    a.i(asm::adds_imm(rd, rd, 1));
    a.i(asm::lsls(rd, rd, 16));
    a.ldr_const(3, u32::from(NO_KEY) << 8 | u32::from(kind.code()));
    a.i(asm::alu(AluOp::Orr, rd, 3));
}
