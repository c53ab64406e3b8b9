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
//! writes in their order — the SRAM the merged replay leaves, since no core stores a word
//! after the DMA wrote it in the window nor do both cores access one (a plan is not made
//! for such a shape: a core's stores to a word before the DMA's writes to it are what the
//! cores' run left there, which the writes then overwrite as in the merged order), and a
//! core access in a cycle the DMA claims its bank leaves the window to the merged replay. A read or check that fails changes nothing: the merged replay then
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
//! done without a match per step or a value kept per read: 17.65 → 17.49 G. The firmware's
//! burst check stores a mark into a results word before the burst that overwrites it
//! (`tactus_firmware`'s `IoPlan::burst_mark`): planned since such a word no longer keeps
//! a window from a plan, 20.19 → 18.29 G (18.10 G without the check).
//! `tests/io_windows.rs` (`planned_hits_equal_the_lock_step`,
//! `a_core_store_the_dma_overwrites_is_planned`,
//! `a_hit_meets_the_dmas_claims_with_or_without_a_plan` and every comparison; their windows
//! take both split and unsplit plans) runs boards with and without plans against the
//! lock-step run.

use super::*;

/// The most plans kept per entry ([`Plans`]; all dropped when it is full, so a board keeps
/// at most [`MEMO_ENTRIES`] times this many, each some hundreds of bytes). Which of the
/// DMA's accesses come before each of the cores' could depend on the keys' paths through
/// the handler; on the shipped firmware it does not: in the demo and Maestro_3's first 30 s
/// on `rp2040_io` every entry's windows have one shape (198 plans made in all).
pub(super) const PLANS: usize = 16;

/// An entry's plans by their shapes' hashes (module documentation, "Plans"), and the
/// one used last (the next window's is that one in all but a few in 10,000).
#[derive(Default)]
pub(super) struct Plans {
    pub(super) map: HashMap<u64, Plan, std::hash::BuildHasherDefault<Prehashed>>,
    pub(super) last: Option<u64>,
}

impl Plans {
    /// The plan of entry `e` for the window whose logs are `logs` (cycles from `base`),
    /// made now if there is none yet (`shape`: a buffer); `None` when a core access falls
    /// in a cycle in which the DMA claims its bank, or the entry has no
    /// [`MemoEntry::at_cycle`].
    pub(super) fn find(
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
pub(super) fn shape_word(e: &MemoEntry, a: &IoAccess, base: u64) -> Option<u64> {
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
pub(super) fn shape_of(
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

/// A hasher for keys that are hashes already ([`Plans`]).
#[derive(Default)]
pub(super) struct Prehashed(pub(super) u64);

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
pub(super) enum Src {
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
pub(super) struct Plan {
    /// The windows it serves ([`shape_of`]).
    pub(super) shape: Vec<u64>,
    /// Per core, what each logged access must be for the window to have that shape
    /// ([`Plan::serves`]).
    pub(super) fits: [Vec<Fit>; 2],
    /// False for a shape no plan serves (the general replay does those windows).
    pub(super) ok: bool,
    /// The DMA's accesses in the entry's order, each with where a read's word comes from
    /// (empty when the plan splits: `split`).
    pub(super) steps: Vec<PlanStep>,
    /// The core loads of words a DMA write wrote before them: (core, log index, op index,
    /// shift of the load's bytes in the write's value); empty when the plan splits.
    pub(super) checks: Vec<(u8, u32, u32, u8)>,
    /// The same steps as reads then writes, where no read takes a DMA write's word
    /// ([`Split`]); `None` otherwise.
    pub(super) split: Option<Split>,
}

/// A [`Plan`]'s steps apart: the DMA's reads in order, then its writes in order. The same
/// hit as the steps in the entry's order when no read takes its word from a DMA write
/// ([`Src::Dma`]): a write's route reads only inputs of reads before it, which the reads
/// give the same numbers, and every write waits for the checks anyway (none is done
/// before all reads and checks pass). The shipped drivers' windows all split (their DMA
/// reads the DAC frames at the tick and writes the ADC results later), and the split hit
/// runs no per-step match and keeps no value per read.
pub(super) struct Split {
    /// The reads, none from [`Src::Dma`].
    pub(super) reads: Vec<PlanRead>,
    /// (offset, size, route): as [`PlanStep::Write`].
    pub(super) writes: Vec<(u32, u8, Route)>,
    /// [`Plan::checks`] with the write's index among `writes` for its op index.
    pub(super) checks: Vec<(u8, u32, u32, u8)>,
}

impl Split {
    /// The split of `steps` and `checks` ([`Plan`]'s), or `None` where a read takes a DMA
    /// write's word.
    pub(super) fn of(steps: &[PlanStep], checks: &[(u8, u32, u32, u8)]) -> Option<Split> {
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
pub(super) struct Fit {
    pub(super) addr: u32,
    pub(super) size: u8,
    pub(super) kind: IoKind,
    pub(super) lo: u64,
    pub(super) hi: u64,
}

impl Fit {
    /// The fit of access `a` (cycles from `base`) for entry `e`: the stretch of cycles
    /// around its own with its [`shape_word`] (every cycle for a register store).
    pub(super) fn of(e: &MemoEntry, a: &IoAccess, base: u64) -> Fit {
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
    pub(super) fn fits(&self, a: &IoAccess, base: u64) -> bool {
        let at = a.cycle.wrapping_sub(base);
        a.addr == self.addr
            && a.size == self.size
            && a.kind == self.kind
            && at.wrapping_sub(self.lo) < self.hi - self.lo
    }
}

/// One DMA access of a [`Plan`]: a read ([`PlanRead`]), or a write of its route's value
/// (the route cloned from the entry's op).
pub(super) enum PlanStep {
    Read(PlanRead),
    Write { off: u32, size: u8, route: Route },
}

/// A DMA read of a [`Plan`]: `size` bytes at SRAM offset `off`, whose word comes from
/// `src` and whose bits under `mask` must be `value`.
#[derive(Clone, Copy)]
pub(super) struct PlanRead {
    pub(super) off: u32,
    pub(super) size: u8,
    pub(super) src: Src,
    pub(super) mask: u32,
    pub(super) value: u32,
}

impl PlanRead {
    /// Its word in a hit whose SRAM is `sram` (as the cores' run left it), logs `logs`
    /// and DMA values so far `before` (by op index); `None` when the word is not there or
    /// breaks the constraint (the plan does not serve the window).
    #[inline]
    pub(super) fn word(
        &self,
        sram: &[u8],
        logs: &[Vec<IoAccess>; 2],
        before: &[u32],
    ) -> Option<u32> {
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
pub(super) fn size_mask(size: u8) -> u32 {
    match size {
        1 => 0xff,
        2 => 0xffff,
        _ => u32::MAX,
    }
}

/// The register stores of each core's log of a window, their cycles from `base`: a
/// [`MemoEntry`]'s key. (Per core, not in the lock-step order: with their cycles, the
/// cores' sequences decide that order.)
pub(super) fn reg_stores(logs: &[Vec<IoAccess>; 2], base: u64) -> [Vec<IoAccess>; 2] {
    logs.each_ref().map(|log| {
        (log.iter())
            .filter(|a| a.kind == IoKind::Reg)
            .map(|a| a.since(base))
            .collect()
    })
}

/// Whether each core load that `checks` lists ([`Plan::checks`]: core, log index, index
/// of the DMA write in `values`, shift) loaded what that write's value holds.
pub(super) fn loads_see_writes(
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
pub(super) fn split_hit(
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

impl Drive<'_> {
    /// Entry `i` (`e`) for the window `probe` brings by a plan (module documentation,
    /// "Plans"), the SRAM as the cores' run left it: true when done; false, nothing
    /// changed, when there is no plan for the window's shape or a read or load breaks it
    /// (the general replay then finds what becomes of the window).
    pub(super) fn io_memo_planned(
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
        } = &mut self.a.io_memo;
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
        let sys = &mut self.m.system;
        if sys.io.is_none() {
            return false;
        }
        data_inputs(sys, e, inputs);
        if let Some(split) = &plan.split {
            if !split_hit(sys, split, logs, inputs, values) {
                return false;
            }
            let r = self.io_memo_end(e, probe);
            self.a.io_windows.memo_planned += 1;
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
        self.a.io_windows.memo_planned += 1;
        matches!(r, Tried::Done(Ok(())))
    }
}

impl Plan {
    /// Whether the window whose logs are `logs` (cycles from `base`) has the plan's shape
    /// ([`shape_of`]), no access of it in a cycle the DMA claims its bank: each access
    /// [`Fit::fits`] (an access elsewhere in the cycles of its shape word is not served
    /// here but by the shape's hash).
    #[inline]
    pub(super) fn serves(&self, logs: &[Vec<IoAccess>; 2], base: u64) -> bool {
        (logs.iter().zip(&self.fits)).all(|(log, fits)| {
            log.len() == fits.len() && (log.iter().zip(fits)).all(|(a, f)| f.fits(a, base))
        })
    }

    /// The plan of entry `e` for windows shaped as `logs` (cycles from `base`; their shape
    /// `shape`): the general replay's order ([`Board::io_memo_apply`]) worked out once.
    /// Not `ok` (the general replay serves such windows) where a word is accessed by both
    /// cores or stored by a core after a DMA write to it, a DMA read reads a DMA
    /// write's bytes other than exactly, or a read mixes bytes of the DMA's writes and
    /// others.
    pub(super) fn new(e: &MemoEntry, logs: &[Vec<IoAccess>; 2], base: u64, shape: &[u64]) -> Plan {
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
        // Words by who touches them: bits 0 and 1 the cores, bit 2 a DMA write, bit 3 a
        // core's store after a DMA write (a store before the DMA's writes to its word is
        // what the cores' run left there, which the writes then overwrite as the merged
        // order does: the burst check's mark, `firmware/src/image/io.rs`).
        let mut words: Vec<(u32, u8)> = Vec::new();
        for &step in &steps {
            let (word, bits) = match step {
                Step::Core(k, i) => (logs[k][i].addr & !3, 1 << k),
                Step::Dma(j) => match e.ops.get(j) {
                    Some(op) if matches!(op.kind, MemoOpKind::Write { .. }) => (op.off & !3, 4),
                    _ => continue,
                },
            };
            let store_after_write = |w: u8| match step {
                Step::Core(k, i) if logs[k][i].kind == IoKind::Store && w & 4 != 0 => 8,
                _ => 0,
            };
            match words.iter_mut().find(|w| w.0 == word) {
                Some(w) => w.1 |= bits | store_after_write(w.1),
                None => words.push((word, bits)),
            }
        }
        if words.iter().any(|&(_, w)| w & 3 == 3 || w & 8 != 0) {
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
