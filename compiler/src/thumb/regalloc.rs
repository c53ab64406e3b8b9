//! Register allocation: linear scan (Poletto & Sarkar, "Linear scan register allocation",
//! TOPLAS 21(5), 1999) over the forward-only machine IR.
//!
//! Because the body has no backward branches, a virtual register's live range is exactly
//! the interval from its first definition to its last use in program order. The allocator
//! first tries all seven free low registers (`r0`–`r6`; `r7` holds the state pointer); if
//! that needs spills, it retries with five (`r0`–`r4`) and keeps `r5`, `r6` as scratch
//! registers for reloading spilled operands (`LDR` from the stack frame, which leaves the
//! flags alone, so `ADDS`/`ADCS` pairs survive reloads). The victim of a spill is the
//! interval with the fewest references per instruction of its range (the emitter's reload
//! cache then removes repeated reloads in straight-line code); a spilled register lives in
//! its stack slot for its whole interval. A slot is reused by a later spilled interval only
//! when the frame would otherwise outgrow [`MAX_UNSHARED_SLOTS`] (a long body such as eleven
//! inlined `exp`s: `LDR`/`STR` reach 255 words from SP); shorter bodies keep one slot per
//! spilled interval, as before.

use super::mir::*;
use tactus_isa::decode::MemOp;

/// Where a virtual register lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Loc {
    /// A low register.
    Reg(u8),
    /// A stack slot (word index from SP).
    Slot(u16),
    /// Not kept anywhere: each read recomputes it into a scratch register (a spilled
    /// constant or state word — no store at its definition, which is not emitted).
    Remat(Remat),
}

/// How a rematerialised register's value is recomputed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Remat {
    /// `MOVS`/literal load of a constant (C and V kept, as a stack reload keeps them; no
    /// reload sits between a flag-setting instruction and the branch that reads N or Z).
    Const(i32),
    /// A load from the state struct at this byte offset (`LDR`/`LDRB [r7, #off]`), where no
    /// store in the register's live range may write that word.
    State(MemOp, u16),
}

/// The allocation of one function.
pub struct Allocation {
    /// Location of each virtual register (`None`: never referenced).
    pub loc: Vec<Option<Loc>>,
    /// Number of stack slots.
    pub slots: u16,
    /// The instructions each slot's registers are live over, `(first, last)` (the union
    /// when intervals share a slot): slots whose spans are disjoint may share a home.
    pub slot_span: Vec<(usize, usize)>,
    /// Scratch registers for spilled operands (empty when nothing spilled).
    pub scratch: Vec<u8>,
    /// Registers used (bit mask over r0–r7), for the prologue's `PUSH`.
    pub used_mask: u8,
}

#[derive(Clone, Copy, Debug)]
struct Interval {
    v: u32,
    start: usize,
    end: usize,
    /// Reads and writes of the register: each costs a reload or a store when spilled.
    refs: u32,
    /// Operands of the defining instruction whose register this one would like to share
    /// ([`M::tied`]: no `MOV` for a two-address instruction when one of them ends there).
    tied: [Option<V>; 2],
    /// Recomputed at each use instead of spilled, if it must leave the registers.
    remat: Option<Remat>,
    /// A diamond's result ([`holes`]): not live from the `B` that ends its first arm up to
    /// its definition in the second, `(b, def)` — another interval inside may take its
    /// register.
    hole: Option<(usize, usize)>,
    /// The diamond result whose second definition copies this register where it ends
    /// (`MOV d, this`): this one takes `d`'s register inside `d`'s hole, so the copy goes.
    host: Option<u32>,
}

impl Interval {
    /// Spill weight: references per instruction of the live range (Poletto & Sarkar's
    /// "ends last" rule spills long-lived operands read everywhere, such as a sensor word;
    /// the density keeps those in registers and spills the rarely used ones).
    fn weight(&self) -> f64 {
        // A rematerialised register costs nothing at its definition.
        let cost = self.refs - u32::from(self.remat.is_some());
        cost as f64 / (self.end - self.start + 1) as f64
    }
}

/// Allocates the virtual registers of `code` (`nregs` of them).
pub fn allocate(code: &[M], nregs: u32) -> Allocation {
    let mut first = vec![usize::MAX; nregs as usize];
    let mut last = vec![0usize; nregs as usize];
    let mut late_at = vec![usize::MAX; nregs as usize];
    let mut refs = vec![0u32; nregs as usize];
    let mut tied = vec![[None, None]; nregs as usize];
    let mut defs = vec![0u32; nregs as usize];
    let mut def_at = vec![usize::MAX; nregs as usize];
    for (i, m) in code.iter().enumerate() {
        for u in m.uses() {
            if u == STATE_V {
                continue;
            }
            let k = u.0 as usize;
            refs[k] += 1;
            first[k] = first[k].min(i);
            last[k] = last[k].max(i);
        }
        if let Some(d) = m.def() {
            let k = d.0 as usize;
            if first[k] == usize::MAX || first[k] == i {
                tied[k] = m.tied();
            }
            defs[k] += 1;
            def_at[k] = i;
            refs[k] += 1;
            first[k] = first[k].min(i);
            last[k] = last[k].max(i);
        }
        if let Some(u) = m.late_use() {
            // The late use must stay out of the definition's register at `i`.
            if last[u.0 as usize] == i {
                late_at[u.0 as usize] = i;
            }
        }
    }
    // Arguments are live from the entry.
    for a in [ARG1, ARG2] {
        if (a.0 as usize) < first.len() && first[a.0 as usize] != usize::MAX {
            first[a.0 as usize] = 0;
        }
    }
    let mut intervals: Vec<Interval> = (0..nregs as usize)
        .filter(|&k| first[k] != usize::MAX)
        .map(|k| Interval {
            v: k as u32,
            start: first[k],
            // A late use stays live one step longer, past the definition it must not share.
            end: if late_at[k] == last[k] {
                last[k] + 1
            } else {
                last[k]
            },
            refs: refs[k],
            tied: tied[k],
            remat: None,
            hole: None,
            host: None,
        })
        .collect();
    let hole = holes(code, nregs, &first, &def_at, &defs);
    for iv in &mut intervals {
        iv.hole = hole[iv.v as usize];
        // The last use of this register is the copy into a diamond's result at the end of
        // that result's hole, and it starts inside the hole.
        if let Some(M::Mov { d, s }) = code.get(iv.end) {
            if s.0 == iv.v {
                if let Some(Some((b, h))) = hole.get(d.0 as usize) {
                    if *h == iv.end && iv.start > *b {
                        iv.host = Some(d.0);
                    }
                }
            }
        }
    }
    let stores = StateStores::new(code);
    for iv in &mut intervals {
        let k = iv.v as usize;
        if defs[k] != 1 || iv.v == ARG1.0 || iv.v == ARG2.0 {
            continue;
        }
        iv.remat = match code[def_at[k]] {
            M::Movi { imm, .. } => Some(Remat::Const(imm)),
            M::Load {
                op: op @ (MemOp::Ldr | MemOp::Ldrb),
                base: Base::State,
                off,
                ..
            } if !stores.may_write((op, off), iv.start, iv.end) => Some(Remat::State(op, off)),
            _ => None,
        };
    }
    intervals.sort_by_key(|iv| (iv.start, iv.v));
    if let Some(a) = scan(&intervals, nregs, &[0, 1, 2, 3, 4, 5, 6], &[], false) {
        return a;
    }
    let a = scan(&intervals, nregs, &[0, 1, 2, 3, 4], &[5, 6], false)
        .expect("spilling always succeeds");
    if a.slots as usize <= MAX_UNSHARED_SLOTS {
        return a;
    }
    scan(&intervals, nregs, &[0, 1, 2, 3, 4], &[5, 6], true).expect("spilling always succeeds")
}

/// Per register: its hole `(b, def)` where it is a diamond's result (`select`s emitted as
/// branches, 0/1 words from flags): defined exactly twice, the first definition followed by
/// a `B` (the end of the first arm) before the second, no read of it after that `B` up to
/// the second definition, and no branch from the first definition to that `B` into the
/// hole. The second arm is entered only where the register holds nothing yet, so it is
/// dead from the `B` up to its second definition.
fn holes(
    code: &[M],
    nregs: u32,
    first: &[usize],
    last_def: &[usize],
    defs: &[u32],
) -> Vec<Option<(usize, usize)>> {
    let mut out = vec![None; nregs as usize];
    let mut at_label = std::collections::HashMap::new();
    for (i, m) in code.iter().enumerate() {
        if let M::Label(l) = m {
            at_label.insert(l.0, i);
        }
    }
    for k in 0..nregs as usize {
        if defs[k] != 2 {
            continue;
        }
        let (d1, d2) = (first[k], last_def[k]);
        if d1 >= d2 || code[d1].def() != Some(V(k as u32)) {
            continue;
        }
        let Some(b) = (d1 + 1..d2).find(|&i| matches!(code[i], M::B(_))) else {
            continue;
        };
        let read = (b + 1..=d2).any(|i| code[i].uses().contains(&V(k as u32)));
        let into = (d1..=b).any(|i| match code[i] {
            M::B(l) | M::Bc(_, l) => at_label.get(&l.0).is_some_and(|&t| t > b && t <= d2),
            _ => false,
        });
        if !read && !into {
            out[k] = Some((b, d2));
        }
    }
    out
}

/// The stores of a body that may write the state struct, for [`Remat::State`]: stores at
/// a known offset from r7 by word (with their kind and offset: a byte store writes only
/// its byte), and the others (through a computed address: a region
/// base or `STR Rt, [r7, Rm]`) counted by position. Stores through the `out` pointer
/// ([`ARG2`]) write the caller's output array, never the state.
struct StateStores {
    /// The stores to each state word (by `off / 4`): instruction index, kind and byte
    /// offset, by ascending index.
    by_word: std::collections::HashMap<u16, Vec<(usize, MemOp, u16)>>,
    /// `unknown[i]`: stores at an unknown address before instruction `i`.
    unknown: Vec<u32>,
}

impl StateStores {
    fn new(code: &[M]) -> Self {
        let mut by_word: std::collections::HashMap<u16, Vec<(usize, MemOp, u16)>> =
            Default::default();
        let mut unknown = Vec::with_capacity(code.len() + 1);
        let mut n = 0u32;
        for (i, m) in code.iter().enumerate() {
            unknown.push(n);
            match m {
                M::Store {
                    op,
                    base: Base::State,
                    off,
                    ..
                } => by_word.entry(off / 4).or_default().push((i, *op, *off)),
                M::Store {
                    base: Base::V(b), ..
                } if *b == ARG2 => {}
                M::Store { .. } | M::StoreR { .. } => n += 1,
                _ => {}
            }
        }
        unknown.push(n);
        StateStores { by_word, unknown }
    }

    /// Whether a store in instructions `start..=end` may write a byte that access `at`
    /// (kind, byte offset) reads.
    fn may_write(&self, at: (MemOp, u16), start: usize, end: usize) -> bool {
        let end = end.min(self.unknown.len() - 2);
        if self.unknown[end + 1] > self.unknown[start] {
            return true;
        }
        self.by_word.get(&(at.1 / 4)).is_some_and(|stores| {
            let p = stores.partition_point(|&(i, _, _)| i < start);
            stores[p..]
                .iter()
                .take_while(|&&(i, _, _)| i <= end)
                .any(|&(_, op, off)| accesses_overlap((op, off), at))
        })
    }
}

/// Spill slots beyond which intervals that do not overlap share slots.
pub const MAX_UNSHARED_SLOTS: usize = 200;

/// One linear scan with the given registers; `None` when it would spill and no scratch
/// registers were set aside.
/// With `share`, a spilled interval takes a slot whose previous occupant ended before it
/// starts.
fn scan(
    intervals: &[Interval],
    nregs: u32,
    regs: &[u8],
    scratch: &[u8],
    share: bool,
) -> Option<Allocation> {
    let mut loc: Vec<Option<Loc>> = vec![None; nregs as usize];
    // The end of the last interval given each slot, and (for sharing) the slots ordered by
    // that end, earliest first.
    let mut slot_end: Vec<usize> = Vec::new();
    let mut slot_span: Vec<(usize, usize)> = Vec::new();
    let mut by_end: std::collections::BinaryHeap<std::cmp::Reverse<(usize, u16)>> =
        Default::default();
    let mut take_slot = |iv: &Interval| -> u16 {
        let s = match by_end.peek() {
            Some(&std::cmp::Reverse((e, s))) if share && e < iv.start => {
                by_end.pop();
                slot_end[s as usize] = iv.end;
                let span = &mut slot_span[s as usize];
                *span = (span.0.min(iv.start), span.1.max(iv.end));
                s
            }
            _ => {
                slot_end.push(iv.end);
                slot_span.push((iv.start, iv.end));
                (slot_end.len() - 1) as u16
            }
        };
        by_end.push(std::cmp::Reverse((iv.end, s)));
        s
    };
    let mut free: Vec<u8> = regs.iter().rev().copied().collect();
    // Active intervals with their register, sorted by end.
    let mut active: Vec<(Interval, u8)> = Vec::new();
    // Per register: the end of the interval living in its holder's hole, if any.
    let mut tenant_until: [Option<usize>; 8] = [None; 8];
    let mut used_mask = 0u8;
    let pre = |v: u32| -> Option<u8> {
        if v == ARG1.0 {
            Some(1)
        } else if v == ARG2.0 {
            Some(2)
        } else {
            None
        }
    };
    for &iv in intervals {
        // Expire intervals that ended before this one starts (a use at `start` may share
        // its register with this definition).
        active.retain(|(a, r)| {
            if a.end <= iv.start && !(a.end == iv.start && a.start == iv.start) {
                free.push(*r);
                false
            } else {
                true
            }
        });
        // A pre-coloured argument's register, else the register of a tied operand that
        // ended here (coalescing the two-address `MOV` away), else the last one freed.
        let tied_reg = iv.tied.into_iter().flatten().find_map(|t| {
            match loc.get(t.0 as usize).copied().flatten() {
                Some(Loc::Reg(r)) if free.contains(&r) => Some(r),
                _ => None,
            }
        });
        // The register of the diamond result this interval is copied into at the end of
        // its hole, when nothing else lives in that hole: the copy then goes. (Lodging any
        // interval in a hole instead of spilling: plucked_string 2 cycles worse.)
        let host_reg = iv.host.filter(|_| pre(iv.v).is_none()).and_then(|host| {
            active.iter().find_map(|(a, r)| {
                let (b, h) = a.hole?;
                let fits = a.v == host && b < iv.start && iv.end <= h;
                let vacant = tenant_until[*r as usize].is_none_or(|e| e < iv.start);
                (fits && vacant).then_some(*r)
            })
        });
        if let Some(r) = host_reg {
            loc[iv.v as usize] = Some(Loc::Reg(r));
            tenant_until[r as usize] = Some(iv.end);
            continue;
        }
        let want = pre(iv.v).or(tied_reg);
        let reg = match want.and_then(|w| free.iter().position(|&r| r == w)) {
            Some(p) => Some(free.remove(p)),
            None => free.pop(),
        };
        match reg {
            Some(r) => {
                loc[iv.v as usize] = Some(Loc::Reg(r));
                used_mask |= 1 << r;
                active.push((iv, r));
            }
            None => {
                if scratch.is_empty() {
                    return None;
                }
                // Spill the interval with the fewest references per instruction (ties: the
                // one that ends last) — not one whose register an interval in its hole
                // still holds.
                let lodged = |r: u8| tenant_until[r as usize].is_some_and(|e| e >= iv.start);
                let Some((k, _)) = active
                    .iter()
                    .enumerate()
                    .filter(|(_, (_, r))| !lodged(*r))
                    .min_by(|(_, (a, _)), (_, (b, _))| {
                        a.weight().total_cmp(&b.weight()).then(b.end.cmp(&a.end))
                    })
                else {
                    loc[iv.v as usize] = Some(match iv.remat {
                        Some(r) => Loc::Remat(r),
                        None => Loc::Slot(take_slot(&iv)),
                    });
                    continue;
                };
                let victim_first = active[k].0.weight() < iv.weight()
                    || (active[k].0.weight() == iv.weight() && active[k].0.end > iv.end);
                let mut spill = |iv: &Interval| match iv.remat {
                    Some(r) => Loc::Remat(r),
                    None => Loc::Slot(take_slot(iv)),
                };
                if victim_first {
                    let (victim, r) = active.remove(k);
                    loc[victim.v as usize] = Some(spill(&victim));
                    loc[iv.v as usize] = Some(Loc::Reg(r));
                    active.push((iv, r));
                } else {
                    loc[iv.v as usize] = Some(spill(&iv));
                }
            }
        }
    }
    // (More than u16::MAX unshared slots: reported as u16::MAX, which makes `allocate`
    // share them.)
    let slots = slot_end.len().min(u16::MAX as usize) as u16;
    // Scratch registers serve reloads and rematerialisations.
    let spilled = loc
        .iter()
        .any(|l| matches!(l, Some(Loc::Slot(_) | Loc::Remat(_))));
    for &s in scratch {
        if spilled {
            used_mask |= 1 << s;
        }
    }
    Some(Allocation {
        loc,
        slots,
        slot_span,
        scratch: if spilled { scratch.to_vec() } else { vec![] },
        used_mask,
    })
}
