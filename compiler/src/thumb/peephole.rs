//! Peepholes over one function's allocated machine code in the [`CodeBuffer`], after
//! [`super::emit`] has lowered it (physical registers, spill homes, literal loads): what
//! the lowering of one machine-IR instruction at a time cannot see.
//!
//! Three passes, each over the code as a forward-only graph (the backend's bodies branch
//! only forward, so one walk in program order meets every way into a label before the
//! label; a branch backwards makes the passes leave the function alone):
//!
//! 1. **Compares with 0 that the flags already answer.** `CMP Rn, #0` right after an
//!    instruction that set N and Z from `Rn`'s value (`ADDS`, `LSRS`, `MULS`, … with no
//!    write of `Rn` or the flags in between) is dropped when the branches reading its
//!    flags read only N and Z: `EQ`/`NE`/`MI`/`PL`, and `GE`/`LT` as `PL`/`MI` (after
//!    `CMP #0`, V is 0, so `GE` is N = 0). Its C (1) and V (0) must be dead: no instruction
//!    after the branches, and none at their targets, reads them before they are set again
//!    (a backward liveness of the four flags).
//! 2. **Values a register already holds.** A forward walk knows which registers hold a
//!    constant, a stack slot's word (`[SP, #imm]`) or a state word (`[r7, #imm]`) — through
//!    `MOV` copies, until the register, the slot (a store to it) or the state word (a
//!    store that may overlap it, any store through another base) is written — and keeps at
//!    a label what every way in agrees. A literal or stack or state load of a value the
//!    destination already holds is dropped; of one another register holds, it becomes
//!    `MOV Rt, Rm` (1 cycle where `LDR` costs 2; neither touches the flags). A `MOVS Rd,
//!    #imm` of the value `Rd` already holds is dropped where its N and Z are dead.
//! 3. **Register copies.** With a backward liveness of the registers: `MOV Rd, Rm` whose
//!    copy only the next instruction reads goes, that instruction reading `Rm` (where its
//!    encoding takes `Rm`); `MOV Rd, Rs` right after the instruction that wrote `Rs`, with
//!    `Rs` dead after it, goes, that instruction writing `Rd` (a three-address form).
//!    What the selector's two-address `MOV`s and a diamond's copies into its result
//!    register leave behind.
//!
//! Both keep every register, memory word and live flag as it was at every instruction
//! that remains, so results are bit-identical; the WCET analysis then prices the shorter
//! code from the timing table like any other. What each instruction reads and writes,
//! registers and flags, is [`tactus_isa::effects`]'s one table.

use super::buffer::{CodeBuffer, Item};
use super::ins::cond::{EQ, GE, LT, MI, NE, PL};
use std::collections::HashMap;
use tactus_isa::decode::{AluOp, Instr, MemOp};
use tactus_isa::effects::{cond_reads, effect, ALL, C, N, V, Z};

/// A return (`POP {…, PC}`): the flags are dead after it (AAPCS preserves none).
fn returns(i: &Instr) -> bool {
    matches!(i, Instr::Pop { list } if list & 1 << 15 != 0)
}

/// Whether every branch of `items` goes forward to a label bound once.
fn forward_only(items: &[Item]) -> bool {
    let mut bound = HashMap::new();
    for (k, it) in items.iter().enumerate() {
        if let Item::Bind(l) = it {
            if bound.insert(l.index(), k).is_some() {
                return false;
            }
        }
    }
    items.iter().enumerate().all(|(k, it)| match it {
        Item::Branch(_, l) => bound.get(&l.index()).is_some_and(|&b| b > k),
        _ => true,
    })
}

/// The flags live after each item (read on some way onward before all of them are set
/// again), from a backward walk; a label's liveness is what is live where it is bound.
fn liveness(items: &[Item]) -> Vec<u8> {
    let mut at_label: HashMap<usize, u8> = HashMap::new();
    let mut after = vec![0u8; items.len()];
    let mut live = 0u8;
    for k in (0..items.len()).rev() {
        after[k] = live;
        let target = |l: &super::buffer::Label| at_label.get(&l.index()).copied().unwrap_or(ALL);
        live = match &items[k] {
            Item::Branch(None, l) => target(l),
            Item::Branch(Some(c), l) => live | target(l) | cond_reads(*c),
            Item::Bind(l) => {
                at_label.insert(l.index(), live);
                live
            }
            Item::Instr(i) if returns(i) => 0,
            Item::Instr(i) => match effect(i) {
                Some(e) => live & !e.flags_set | e.flags_read,
                None => ALL,
            },
            Item::Call(_) => ALL,
            _ => live,
        };
    }
    after
}

/// Pass 1: drops each `CMP Rn, #0` whose N and Z the instruction before already set from
/// `Rn` and whose C and V nothing reads; its `GE`/`LT` branches become `PL`/`MI`.
/// Returns the items to drop.
fn compares(items: &mut [Item]) -> Vec<bool> {
    let after = liveness(items);
    let mut dead = vec![false; items.len()];
    // The register whose value N and Z reflect, per way in to each label.
    let mut pending: HashMap<usize, Option<u8>> = HashMap::new();
    let mut nz: Option<u8> = None;
    let mut reachable = true;
    for k in 0..items.len() {
        match &items[k] {
            Item::Bind(l) => {
                let way = pending.remove(&l.index());
                nz = match (reachable, way) {
                    (true, Some(w)) if w == nz => nz,
                    (true, Some(_)) => None,
                    (true, None) => nz,
                    (false, Some(w)) => w,
                    (false, None) => None,
                };
                reachable = true;
            }
            Item::Branch(c, l) => {
                let here = nz;
                pending
                    .entry(l.index())
                    .and_modify(|w| {
                        if *w != here {
                            *w = None
                        }
                    })
                    .or_insert(here);
                if c.is_none() {
                    reachable = false;
                }
            }
            Item::Instr(Instr::CmpImm { rn, imm: 0 }) if nz == Some(*rn) => {
                if let Some(run) = readers(items, &after, k) {
                    for b in run {
                        if let Item::Branch(Some(c), _) = &mut items[b] {
                            *c = match *c {
                                GE => PL,
                                LT => MI,
                                same => same,
                            };
                        }
                    }
                    dead[k] = true;
                }
            }
            Item::Instr(i) if returns(i) => reachable = false,
            Item::Instr(i) => match effect(i) {
                Some(e) if e.flags_set & (N | Z) == N | Z => nz = e.nz,
                Some(e) if nz.is_some_and(|r| e.writes & 1 << r != 0) || e.flags_set != 0 => {
                    nz = None
                }
                Some(_) => {}
                None => nz = None,
            },
            Item::Lit { rt, .. } if nz == Some(*rt) => nz = None,
            Item::Call(_) => nz = None,
            _ => {}
        }
    }
    dead
}

/// The branches reading the flags of the `CMP #0` at `k` when they read only N and Z (or
/// N and V as `GE`/`LT`, whose V a `CMP #0` clears) and no instruction or label after
/// them reads its C or V; `None` otherwise.
fn readers(items: &[Item], after: &[u8], k: usize) -> Option<Vec<usize>> {
    let mut run = Vec::new();
    // Liveness at a label: what is live after the item before its `Bind`.
    let at = |l: &super::buffer::Label| {
        items
            .iter()
            .position(|it| matches!(it, Item::Bind(b) if b == l))
            .map(|b| if b == 0 { ALL } else { after[b - 1] })
    };
    for (q, it) in items.iter().enumerate().skip(k + 1) {
        match it {
            Item::Note(_) | Item::Mark(_) => {}
            Item::Branch(c, l) => {
                if at(l)? & (C | V) != 0 {
                    return None;
                }
                match c {
                    Some(EQ | NE | MI | PL | GE | LT) => run.push(q),
                    Some(_) => return None,
                    None => return Some(run),
                }
            }
            _ => return (after[q - 1] & (C | V) == 0).then_some(run),
        }
    }
    Some(run)
}

/// A value a register is known to hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Fact {
    /// A constant word.
    Const(u32),
    /// The word of the stack frame at `[SP, #off]`.
    Slot(u16),
    /// The state word or byte loaded by `op` from `[r7, #off]` (zero- or sign-extended as
    /// the load extends it).
    State(MemOp, u16),
}

impl Fact {
    /// Whether an access by `op` to `[base, #off]` touches this fact's memory.
    fn overlaps(self, base: u8, op: MemOp, off: u16) -> bool {
        let (b, k, o) = match self {
            Fact::Const(_) => return false,
            Fact::Slot(o) => (13, MemOp::Ldr, o),
            Fact::State(k, o) => (7, k, o),
        };
        b == base && {
            let (lo, hi) = (u32::from(o), u32::from(o) + k.size());
            let (a, z) = (u32::from(off), u32::from(off) + op.size());
            lo < z && a < hi
        }
    }
}

/// What each register (r0–r14) holds.
#[derive(Clone, Debug, PartialEq, Default)]
struct Known {
    regs: [Vec<Fact>; 15],
}

impl Known {
    fn meet(&self, other: &Known) -> Known {
        let mut k = Known::default();
        for r in 0..15 {
            k.regs[r] = self.regs[r]
                .iter()
                .filter(|f| other.regs[r].contains(f))
                .copied()
                .collect();
        }
        k
    }

    /// Register `r` is written with a value of no known fact.
    fn kill(&mut self, r: u8) {
        if let Some(x) = self.regs.get_mut(r as usize) {
            x.clear();
        }
        // The state pointer or the stack pointer moved: no word relative to it is known.
        if r == 7 || r == 13 {
            let base = r;
            for x in &mut self.regs {
                x.retain(|f| !matches!((f, base), (Fact::State(..), 7) | (Fact::Slot(_), 13)));
            }
        }
    }

    /// A store of `op` to `[base, #off]` (`off` `None`: at an offset in a register; a base
    /// other than r7 and SP may write any state word, never the function's own stack
    /// frame).
    fn store(&mut self, base: u8, op: MemOp, off: Option<u16>) {
        for x in &mut self.regs {
            x.retain(|f| match (off, base) {
                (Some(o), 7 | 13) => !f.overlaps(base, op, o),
                (None, 13) => !matches!(f, Fact::State(..) | Fact::Slot(_)),
                _ => !matches!(f, Fact::State(..)),
            });
        }
    }

    fn add(&mut self, r: u8, f: Fact) {
        if let Some(x) = self.regs.get_mut(r as usize) {
            if !x.contains(&f) {
                x.push(f);
            }
        }
    }

    /// A register other than `not` holding `f` (a low one first).
    fn holder(&self, f: Fact, not: u8) -> Option<u8> {
        (0..15u8).find(|&r| r != not && r != 13 && self.regs[r as usize].contains(&f))
    }
}

/// What a load by `op` from `[rn, #imm]` reads, when this pass follows it.
fn load_fact(op: MemOp, rn: u8, imm: u16) -> Option<Fact> {
    match (rn, op) {
        (13, MemOp::Ldr) => Some(Fact::Slot(imm)),
        (7, _) if !op.is_store() => Some(Fact::State(op, imm)),
        _ => None,
    }
}

/// A load of fact `f` into `rt` at `it`: true when `rt` holds `f` already (the load
/// goes), else a `MOV` from a register that holds it, if one does; then `rt` holds `f`.
fn load(known: &mut Known, it: &mut Item, rt: u8, f: Fact) -> bool {
    if known.regs[rt as usize].contains(&f) {
        return true;
    }
    if let Some(rm) = known.holder(f, rt) {
        *it = Item::Instr(Instr::MovHi { rd: rt, rm });
    }
    known.kill(rt);
    known.add(rt, f);
    false
}

/// Pass 2: loads of values a register holds become `MOV`s or go, as do `MOVS` of a value
/// already there whose flags nobody reads. Returns the items to drop.
fn values(items: &mut [Item], pools: &[Vec<u32>]) -> Vec<bool> {
    let after = liveness(items);
    let mut dead = vec![false; items.len()];
    let mut pending: HashMap<usize, Known> = HashMap::new();
    let mut known = Known::default();
    let mut reachable = true;
    for k in 0..items.len() {
        match items[k].clone() {
            Item::Bind(l) => {
                let way = pending.remove(&l.index());
                known = match (reachable, way) {
                    (true, Some(w)) => known.meet(&w),
                    (true, None) => known,
                    (false, Some(w)) => w,
                    (false, None) => Known::default(),
                };
                reachable = true;
            }
            Item::Branch(c, l) => {
                let here = &known;
                pending
                    .entry(l.index())
                    .and_modify(|w| *w = w.meet(here))
                    .or_insert_with(|| here.clone());
                if c.is_none() {
                    reachable = false;
                }
            }
            Item::Lit { rt, pool, index } => {
                let f = Fact::Const(pools[pool][index]);
                dead[k] = load(&mut known, &mut items[k], rt, f);
            }
            Item::Instr(Instr::MovImm { rd, imm }) => {
                let f = Fact::Const(u32::from(imm));
                if known.regs[rd as usize].contains(&f) && after[k] & (N | Z) == 0 {
                    dead[k] = true;
                } else {
                    known.kill(rd);
                    known.add(rd, f);
                }
            }
            Item::Instr(Instr::MemImm { op, rt, rn, imm }) if op.is_store() => {
                known.store(rn, op, Some(imm));
                match (rn, op) {
                    (13, MemOp::Str) => known.add(rt, Fact::Slot(imm)),
                    (7, MemOp::Str) => known.add(rt, Fact::State(MemOp::Ldr, imm)),
                    _ => {}
                }
            }
            Item::Instr(Instr::MemImm { op, rt, rn, imm }) => match load_fact(op, rn, imm) {
                Some(f) => dead[k] = load(&mut known, &mut items[k], rt, f),
                None => known.kill(rt),
            },
            Item::Instr(Instr::MemReg { op, rn, .. }) if op.is_store() => {
                known.store(rn, op, None);
            }
            Item::Instr(Instr::Stm { rn, .. }) => {
                known.store(rn, MemOp::Str, None);
                known.kill(rn);
            }
            // `MOV r8, r8`: the no-op.
            Item::Instr(Instr::MovHi { rd, rm }) if rd == rm && rd != 15 => {}
            Item::Instr(Instr::MovHi { rd, rm }) if rd != 15 && rm != 15 => {
                let copied = known.regs.get(rm as usize).cloned().unwrap_or_default();
                known.kill(rd);
                for f in copied {
                    known.add(rd, f);
                }
            }
            Item::Instr(Instr::Alu {
                op: AluOp::Mvn,
                rdn,
                rm,
            }) => {
                let not = known.regs[rm as usize].iter().find_map(|f| match f {
                    Fact::Const(c) => Some(!c),
                    _ => None,
                });
                known.kill(rdn);
                if let Some(c) = not {
                    known.add(rdn, Fact::Const(c));
                }
            }
            Item::Instr(i) if returns(&i) => {
                known = Known::default();
                reachable = false;
            }
            Item::Instr(i) => match effect(&i) {
                Some(e) => {
                    for r in 0..16u8 {
                        if e.writes & 1 << r != 0 {
                            known.kill(r);
                        }
                    }
                }
                None => known = Known::default(),
            },
            Item::Call(_) => known = Known::default(),
            _ => {}
        }
    }
    dead
}

/// The registers live after each item (read on some way onward before they are written),
/// from a backward walk. A return keeps every register but those it pops live (what the
/// caller may read is not this pass's to decide).
fn live_registers(items: &[Item]) -> Vec<u16> {
    let mut at_label: HashMap<usize, u16> = HashMap::new();
    let mut after = vec![0u16; items.len()];
    let mut live = u16::MAX;
    for k in (0..items.len()).rev() {
        after[k] = live;
        let target =
            |l: &super::buffer::Label| at_label.get(&l.index()).copied().unwrap_or(u16::MAX);
        live = match &items[k] {
            Item::Branch(None, l) => target(l),
            Item::Branch(Some(_), l) => live | target(l),
            Item::Bind(l) => {
                at_label.insert(l.index(), live);
                live
            }
            Item::Instr(Instr::Pop { list }) if list & 1 << 15 != 0 => !(list & 0xff),
            Item::Instr(i) => match effect(i) {
                Some(e) => live & !e.writes | e.reads,
                None => u16::MAX,
            },
            Item::Lit { rt, .. } => live & !(1 << rt),
            Item::Call(_) => u16::MAX,
            _ => live,
        };
    }
    after
}

/// `i` with its register operands renamed by `f` (`read` for each register it reads,
/// `write` for the one it writes), if the result still encodes: `None` for a form this
/// pass leaves alone or a high register where only a low one fits.
fn rename(i: &Instr, read: impl Fn(u8) -> u8, write: impl Fn(u8) -> u8) -> Option<Instr> {
    use Instr::*;
    let lo = |x: u8| (x < 8).then_some(x);
    let mut j = *i;
    match &mut j {
        LslImm { rd, rm, .. }
        | LsrImm { rd, rm, .. }
        | AsrImm { rd, rm, .. }
        | Uxth { rd, rm }
        | Sxth { rd, rm } => {
            *rd = lo(write(*rd))?;
            *rm = lo(read(*rm))?;
        }
        AddReg { rd, rn, rm } | SubReg { rd, rn, rm } => {
            *rd = lo(write(*rd))?;
            *rn = lo(read(*rn))?;
            *rm = lo(read(*rm))?;
        }
        // The 8-bit immediate form is two-address.
        AddImm { rd, rn, imm } | SubImm { rd, rn, imm } => {
            let (d, n) = (lo(write(*rd))?, lo(read(*rn))?);
            if *imm > 7 && d != n {
                return None;
            }
            (*rd, *rn) = (d, n);
        }
        MovImm { rd, .. } => *rd = lo(write(*rd))?,
        CmpImm { rn, .. } => *rn = lo(read(*rn))?,
        // Two-address: renamed only where the register read and written stays one.
        &mut Alu { op, rdn, rm } => {
            let d = match op {
                AluOp::Cmp | AluOp::Cmn | AluOp::Tst => read(rdn),
                AluOp::Rsb | AluOp::Mvn => write(rdn),
                _ if read(rdn) == write(rdn) => read(rdn),
                _ => return None,
            };
            let m = read(rm);
            j = match op {
                AluOp::Cmp if d >= 8 || m >= 8 => CmpHi { rn: d, rm: m },
                _ => Alu {
                    op,
                    rdn: lo(d)?,
                    rm: lo(m)?,
                },
            };
        }
        &mut CmpHi { rn, rm } => {
            let (n, m) = (read(rn), read(rm));
            j = if n < 8 && m < 8 {
                Alu {
                    op: AluOp::Cmp,
                    rdn: n,
                    rm: m,
                }
            } else {
                CmpHi { rn: n, rm: m }
            };
        }
        MovHi { rd, rm } => (*rd, *rm) = (write(*rd), read(*rm)),
        MemImm { op, rt, rn, .. } => {
            *rt = lo(if op.is_store() { read(*rt) } else { write(*rt) })?;
            *rn = match read(*rn) {
                n @ (13 | 0..8) if (n == 13) == (*rn == 13) => n,
                _ => return None,
            };
        }
        MemReg { op, rt, rn, rm } => {
            *rt = lo(if op.is_store() { read(*rt) } else { write(*rt) })?;
            *rn = lo(read(*rn))?;
            *rm = lo(read(*rm))?;
        }
        _ => return None,
    }
    Some(j)
}

/// Pass 3: register copies. `MOV Rd, Rm` whose copy the next instruction alone reads
/// (`Rd` dead after it, not written by it) goes, that instruction reading `Rm` instead;
/// `MOV Rd, Rs` right after the instruction that wrote `Rs`, when `Rs` is dead after the
/// `MOV`, goes, that instruction writing `Rd` instead. Returns the items to drop.
fn copies(items: &mut [Item]) -> Vec<bool> {
    let after = live_registers(items);
    let mut dead = vec![false; items.len()];
    let silent = |it: &Item| matches!(it, Item::Note(_) | Item::Mark(_));
    for k in 0..items.len() {
        let Item::Instr(Instr::MovHi { rd, rm }) = items[k] else {
            continue;
        };
        if rd == rm || rd >= 13 || rm >= 13 && rm != 14 {
            continue;
        }
        // The copy read once, by the next instruction.
        let next = (k + 1..items.len()).find(|&q| !silent(&items[q]));
        if let Some(q) = next {
            if let Item::Instr(i) = &items[q] {
                if let Some(e) = effect(i) {
                    if e.reads & 1 << rd != 0 && e.writes & 1 << rd == 0 && after[q] & 1 << rd == 0
                    {
                        let sub = |x: u8| if x == rd { rm } else { x };
                        if let Some(j) = rename(i, sub, |x| x) {
                            // A copy back into its source is no instruction at all.
                            dead[q] = matches!(j, Instr::MovHi { rd, rm } if rd == rm);
                            items[q] = Item::Instr(j);
                            dead[k] = true;
                            continue;
                        }
                    }
                }
            }
        }
        // The copy of what the instruction before just wrote.
        let prev = (0..k).rev().find(|&p| !dead[p] && !silent(&items[p]));
        let Some(p) = prev else { continue };
        if after[k] & 1 << rm != 0 || rd >= 8 || rm >= 8 {
            continue;
        }
        let renamed = match &items[p] {
            Item::Lit { rt, pool, index } if *rt == rm => Some(Item::Lit {
                rt: rd,
                pool: *pool,
                index: *index,
            }),
            Item::Instr(i) => match effect(i) {
                Some(e) if e.writes == 1 << rm => {
                    let sub = |x: u8| if x == rm { rd } else { x };
                    rename(i, |x| x, sub).map(Item::Instr)
                }
                _ => None,
            },
            _ => None,
        };
        if let Some(it) = renamed {
            items[p] = it;
            dead[k] = true;
        }
    }
    dead
}

/// Runs the three passes over the function whose items start at `start` in `buf` (its prologue
/// on; lowered, not yet assembled).
pub(super) fn run(buf: &mut CodeBuffer, start: usize) {
    let (items, _) = buf.items_from(start);
    if !forward_only(items) {
        return;
    }
    let dead = compares(items);
    buf.drop_from(start, &dead);
    let (items, pools) = buf.items_from(start);
    let pools = pools.to_vec();
    let dead = values(items, &pools);
    buf.drop_from(start, &dead);
    let (items, _) = buf.items_from(start);
    let dead = copies(items);
    buf.drop_from(start, &dead);
}

#[cfg(test)]
mod tests {
    use super::super::buffer::{CodeBuffer, Item, LongBranch};
    use super::super::ins::cond::{EQ, GE, GT, LT, MI, NE, PL};
    use super::super::ins::{alu, asrs, cmp, cmp_imm, ldr, movs, pop_pc, str, subs_imm};
    use super::run;
    use tactus_isa::decode::{AluOp, Instr};

    fn subs(rd: u8) -> Instr {
        subs_imm(rd, rd, 1)
    }
    fn cmp0(rn: u8) -> Instr {
        cmp_imm(rn, 0)
    }
    fn ret() -> Instr {
        pop_pc(0)
    }
    /// `MOV rd, rm` (no flags; `ins::mov` is `MOVS`).
    fn mov(rd: u8, rm: u8) -> Instr {
        Instr::MovHi { rd, rm }
    }

    /// The items after the passes, as text: instructions by their `Debug`, `b<cond>` and
    /// `bind`, literal loads as `lit r<t>`.
    fn after(build: impl FnOnce(&mut CodeBuffer)) -> Vec<String> {
        let mut buf = CodeBuffer::new(LongBranch::Refuse);
        build(&mut buf);
        run(&mut buf, 0);
        let (items, _) = buf.items_from(0);
        items
            .iter()
            .map(|it| match it {
                Item::Instr(i) => format!("{i:?}"),
                Item::Branch(Some(c), _) => format!("b{c}"),
                Item::Branch(None, _) => "b".into(),
                Item::Bind(_) => "bind".into(),
                Item::Lit { rt, .. } => format!("lit r{rt}"),
                other => format!("{other:?}"),
            })
            .collect()
    }

    /// `op rd; cmp rd, #0; b<cond> L; movs r1, #1; L: ret`, then `tail` after the label.
    fn compare(op: Instr, cond: u8, tail: &[Instr]) -> Vec<String> {
        after(|b| {
            let l = b.label();
            b.i(op);
            b.i(cmp0(0));
            b.bc(cond, l);
            b.i(movs(1, 1));
            b.bind(l);
            for &i in tail {
                b.i(i);
            }
            b.i(ret());
        })
    }

    #[test]
    fn a_compare_with_zero_after_its_value_set_the_flags_goes() {
        let got = compare(subs(0), LT, &[]);
        assert_eq!(got[0], format!("{:?}", subs(0)));
        assert_eq!(got[1], format!("b{MI}"), "{got:?}");
        assert_eq!(compare(subs(0), GE, &[])[1], format!("b{PL}"));
        assert_eq!(compare(subs(0), EQ, &[])[1], format!("b{EQ}"));
        // MULS sets N and Z from its result (C and V are kept).
        let muls = alu(AluOp::Mul, 0, 2);
        assert_eq!(compare(muls, NE, &[])[1], format!("b{NE}"));
        // A load or store between them writes neither the register nor the flags.
        let got = after(|b| {
            let l = b.label();
            b.i(subs(0));
            b.i(ldr(3, 7, 8));
            b.i(cmp0(0));
            b.bc(EQ, l);
            b.i(subs(1));
            b.bind(l);
            b.i(ret());
        });
        assert!(!got.contains(&format!("{:?}", cmp0(0))), "{got:?}");
    }

    #[test]
    fn a_compare_whose_c_or_v_is_read_or_whose_register_changed_stays() {
        let kept = |got: Vec<String>| got.contains(&format!("{:?}", cmp0(0)));
        // GT reads Z, N and V: V after SUBS is not CMP #0's 0.
        assert!(kept(compare(subs(0), GT, &[])));
        // ADCS after the join reads CMP's C (1).
        let adcs = alu(AluOp::Adc, 2, 3);
        assert!(kept(compare(subs(0), EQ, &[adcs])));
        // The flags are another register's.
        assert!(kept(after(|b| {
            let l = b.label();
            b.i(subs(1));
            b.i(cmp0(0));
            b.bc(EQ, l);
            b.bind(l);
            b.i(ret());
        })));
        // The register was written after the flags were set.
        assert!(kept(after(|b| {
            let l = b.label();
            b.i(subs(0));
            b.i(ldr(0, 7, 8));
            b.i(cmp0(0));
            b.bc(EQ, l);
            b.bind(l);
            b.i(ret());
        })));
        // A way into a label between them set the flags from something else.
        assert!(kept(after(|b| {
            let (j, l) = (b.label(), b.label());
            b.i(cmp0(1));
            b.bc(EQ, j);
            b.i(subs(0));
            b.bind(j);
            b.i(cmp0(0));
            b.bc(EQ, l);
            b.bind(l);
            b.i(ret());
        })));
    }

    #[test]
    fn loads_of_values_a_register_holds_become_moves_or_go() {
        let got = after(|b| {
            b.ldr_const(1, 123_456);
            b.ldr_const(2, 123_456);
            b.ldr_const(1, 123_456);
            b.i(str(1, 13, 4));
            b.i(ldr(3, 13, 4));
            b.i(ldr(4, 7, 8));
            b.i(ldr(5, 7, 8));
            b.i(ret());
        });
        assert_eq!(
            got,
            [
                "lit r1".to_string(),
                format!("{:?}", mov(2, 1)),
                format!("{:?}", str(1, 13, 4)),
                format!("{:?}", mov(3, 1)),
                format!("{:?}", ldr(4, 7, 8)),
                format!("{:?}", mov(5, 4)),
                format!("{:?}", ret()),
            ]
        );
    }

    #[test]
    fn a_written_register_slot_or_state_word_is_loaded_again() {
        let got = after(|b| {
            let l = b.label();
            b.ldr_const(1, 123_456);
            b.i(str(1, 13, 4));
            b.i(ldr(4, 7, 8));
            // Another base may point at the state word; the slot gets another value.
            b.i(str(2, 6, 0));
            b.i(str(2, 13, 4));
            b.i(ldr(5, 7, 8));
            b.i(ldr(3, 13, 4));
            b.i(subs(1));
            // A way in where r1 holds something else.
            b.i(cmp0(0));
            b.bc(EQ, l);
            b.ldr_const(1, 123_456);
            b.bind(l);
            b.ldr_const(0, 123_456);
            b.i(ret());
        });
        assert_eq!(got[5], format!("{:?}", ldr(5, 7, 8)), "{got:?}");
        assert_eq!(got[6], format!("{:?}", mov(3, 2)), "{got:?}");
        assert_eq!(got[12], "lit r0", "{got:?}");
    }

    #[test]
    fn a_movs_of_the_value_there_goes_where_its_flags_are_dead() {
        let movs = movs(1, 0);
        let adcs = alu(AluOp::Adc, 3, 1);
        let dead = after(|b| {
            b.i(movs);
            b.i(adcs);
            b.i(movs);
            b.i(subs(2));
            b.i(ret());
        });
        assert_eq!(
            dead.iter().filter(|s| **s == format!("{movs:?}")).count(),
            1
        );
        let live = after(|b| {
            let l = b.label();
            b.i(movs);
            b.i(adcs);
            b.i(movs);
            b.bc(EQ, l);
            b.bind(l);
            b.i(ret());
        });
        assert_eq!(
            live.iter().filter(|s| **s == format!("{movs:?}")).count(),
            2
        );
    }
    /// `body`, then `MOVS r0–r6, #0` (every low register but r7 written: dead) and a return.
    fn copy_pass(body: &[Instr]) -> Vec<String> {
        after(|b| {
            for &i in body {
                b.i(i);
            }
            for r in 0..7 {
                b.i(movs(r, 0));
            }
            b.i(ret());
        })
    }

    #[test]
    fn a_copy_read_once_next_is_read_at_its_source() {
        let got = copy_pass(&[mov(6, 1), cmp(0, 6)]);
        assert_eq!(got[0], format!("{:?}", cmp(0, 1)), "{got:?}");
        // A high source: CMP's high-register form.
        let got = copy_pass(&[mov(6, 12), cmp(0, 6)]);
        assert_eq!(got[0], format!("{:?}", Instr::CmpHi { rn: 0, rm: 12 }));
        // Read again later, or a high register where only a low one fits: kept.
        let kept = copy_pass(&[mov(6, 1), cmp(0, 6), str(6, 7, 0)]);
        assert_eq!(kept[0], format!("{:?}", mov(6, 1)));
        let lsls = super::super::ins::lsls(2, 6, 3);
        let kept = copy_pass(&[mov(6, 12), lsls]);
        assert_eq!(kept[0], format!("{:?}", mov(6, 12)));
    }

    #[test]
    fn a_copy_of_what_was_just_written_is_written_there() {
        let asrs = |rd, rm| asrs(rd, rm, 1);
        // (Read twice after: not a copy the next instruction alone reads.)
        let got = copy_pass(&[asrs(0, 0), mov(1, 0), str(1, 7, 0), str(1, 7, 4)]);
        assert_eq!(got[0], format!("{:?}", asrs(1, 0)), "{got:?}");
        assert_eq!(got[1], format!("{:?}", str(1, 7, 0)));
        let got = after(|b| {
            b.ldr_const(0, 123_456);
            b.i(mov(1, 0));
            b.i(str(1, 7, 0));
            b.i(str(1, 7, 4));
            b.i(movs(0, 0));
            b.i(ret());
        });
        assert_eq!(got[0], "lit r1", "{got:?}");
        // The source read again, or an 8-bit immediate's two-address form: kept.
        let kept = copy_pass(&[asrs(0, 0), mov(1, 0), str(0, 7, 0)]);
        assert_eq!(kept[1], format!("{:?}", mov(1, 0)));
        let adds = super::super::ins::adds_imm(0, 0, 16);
        let kept = copy_pass(&[adds, mov(1, 0), str(1, 7, 0), str(1, 7, 4)]);
        assert_eq!(kept[1], format!("{:?}", mov(1, 0)));
    }
}
