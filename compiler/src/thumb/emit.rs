//! Emission: allocated machine IR to Thumb instructions in the [`CodeBuffer`] — spill
//! homes, the AAPCS prologue and epilogue, constants — and the object's [`Code`] from the
//! assembled buffer (literal pools, branch relaxation, encoding and the GNU assembler
//! listing are the buffer's).

use super::buffer::{self, CodeBuffer};
use super::mir::{Base, Label, Shift, ARG2, M, STATE_V, V};
use super::regalloc::{Allocation, Loc, Remat};
use super::ThumbError;
use std::collections::HashMap;
use tactus_isa::decode::{AluOp, Instr, MemOp};

/// Machine code of an object: bytes, symbols, the listing.
#[derive(Clone, Debug)]
pub struct Code {
    /// The `.text` bytes.
    pub text: Vec<u8>,
    /// Functions: name, offset, size in bytes.
    pub symbols: Vec<(String, usize, usize)>,
    /// Ranges of literal data inside `.text` (offset, length), for `$d` mapping symbols.
    pub data: Vec<(usize, usize)>,
    /// GNU-syntax assembly that `arm-none-eabi-as` assembles to `text`.
    pub listing: String,
    /// Comments (source-level events) at code offsets, for the WCET report.
    pub notes: Vec<(usize, String)>,
    /// Flow facts for the WCET analysis: pairs of `.text` offsets of block starts (bodies of
    /// top-level `if` statements) that no single call of the function executes both of —
    /// the first body's assignments make the second's condition false (see
    /// `crate::fixed::flow::exclusions`).
    pub exclusive: Vec<(usize, usize)>,
}

struct Lower<'a> {
    alloc: &'a Allocation,
    buf: &'a mut CodeBuffer,
    /// The buffer's label for each machine-IR label of this function.
    labels: HashMap<u32, buffer::Label>,
    /// What each scratch register is known to hold (reload cache). The body branches only
    /// forward, so at a label every way in has been lowered: the cache there is what all of
    /// them agree on ([`Lower::pending`] for the branches, the fall-through unless the
    /// instruction before is a `B`).
    holds: [Option<Held>; 2],
    /// Per machine-IR label: what the branches to it lowered so far agree the scratch
    /// registers hold, and the copy of a spill slot they agree on ([`Lower::copy`]).
    pending: HashMap<u32, Ways>,
    /// Whether the instruction being lowered can be reached by falling through (not right
    /// after an unconditional `B`).
    reachable: bool,
    /// The instructions reading each spilled or rematerialised value, ascending: a reload
    /// evicts the scratch register whose value is read again last (Belady's rule).
    reads: HashMap<Held, Vec<usize>>,
    /// A low register other than the scratch registers that holds a spill slot's value
    /// (the register a slot was just stored from), until that register is written: a
    /// read of the slot is then that register (no `LDR` from a stack home, 2 cycles, no
    /// `MOV` from a high one, 1). The instruction that writes it may still read it (its
    /// operands are read first), and a label keeps it when every way in agrees.
    copy: Option<(u8, u16)>,
    /// The register the instruction being lowered writes when that ends [`Lower::copy`]
    /// (cleared once the instruction is lowered).
    copy_ends: Option<u8>,
    /// Scratch registers holding an operand of the instruction being lowered (a second
    /// spilled operand is reloaded into the other one).
    pinned: [bool; 2],
    /// The last instruction reading or writing each virtual register, and the index of
    /// the instruction being lowered: an operand whose register is free after it.
    last: Vec<usize>,
    at: usize,
    /// Where each spill slot lives: a high register (`MOV` to and from it costs 1 cycle
    /// where `LDR`/`STR` cost 2) or a word of the stack frame.
    home: Vec<Home>,
}

/// What a scratch register holds, for the reload cache.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Held {
    /// The value of a spill slot.
    Slot(u16),
    /// A rematerialised constant or state word (a state word until a store may write it).
    Remat(Remat),
}

/// What a way into a label knows: what the scratch registers hold ([`Lower::holds`]) and
/// the copy of a spill slot in another low register ([`Lower::copy`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Ways {
    holds: [Option<Held>; 2],
    copy: Option<(u8, u16)>,
}

/// Where both `a` and `b` agree.
fn meet(a: Ways, b: Ways) -> Ways {
    Ways {
        holds: [0, 1].map(|j| {
            if a.holds[j] == b.holds[j] {
                a.holds[j]
            } else {
                None
            }
        }),
        copy: if a.copy == b.copy { a.copy } else { None },
    }
}

/// The home of a spill slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Home {
    /// A high register (`r8`–`r12`, `LR`).
    Hi(u8),
    /// A word of the stack frame (index from SP).
    Stack(u16),
}

/// Spill slots get the high registers, most referenced first: `r12` (caller-saved, free),
/// `LR` where [`Homes::lr`] allows (the prologue pushes it and the epilogue pops its word
/// into PC, so the body may use it for free unless a long branch, a `BL`, writes it),
/// then those of `r8`–`r11` the convention leaves free ([`Homes::free`], from `r11` down),
/// then the others from `r8` up. Each high register in turn takes every slot it can (most
/// referenced first, each disjoint in its live span from those it holds). A reference to a slot in a
/// high register is a `MOV` (1 cycle) where a stack slot's is an `LDR`/`STR` (2); a
/// callee-saved register costs its save and restore: two `MOV`s and a `PUSH`/`POP` of its
/// own, about 6 cycles, for the first of a pair, two `MOV`s and a register more in the
/// pair's `PUSH`/`POP`, about 4, for the second. So the first is taken only for slots with
/// this many static references in all (the static count over-counts the worst path, which
/// passes only some of them) …
const HI_FIRST_REFS: u32 = 10;
/// … and the second of a pair for this many.
const HI_PAIR_REFS: u32 = 6;
/// A high register the convention leaves free ([`Homes::free`]: not saved, not restored)
/// costs no save and restore, only what its caller pays to re-establish it (the firmware
/// glue: a limiter constant loaded from the literal pool, a cycle or two per key), so it
/// is taken for slots with this many static references in all.
const HI_FREE_REFS: u32 = 3;

/// Which high registers spill slots may live in, and which callee-saved registers need no
/// saving.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Homes {
    /// `LR` is free in the body: no branch of the function may be relaxed to `BL` (the
    /// buffer then refuses one, and the caller lowers again without it).
    pub lr: bool,
    /// Callee-saved registers (bit *n* = r*n*, r4–r11) the calling convention lets the
    /// function leave modified ([`super::Convention::free`]): neither saved nor restored.
    pub free: u16,
}

/// The homes of `alloc`'s spill slots, from their static reference counts in `code`.
fn homes(code: &[M], alloc: &Allocation, cfg: Homes) -> Vec<Home> {
    let n = alloc.slots as usize;
    let mut refs = vec![0u32; n];
    let slot = |v: V| match alloc.loc.get(v.0 as usize).copied().flatten() {
        Some(Loc::Slot(s)) => Some(s as usize),
        _ => None,
    };
    for m in code {
        for v in m.uses().into_iter().chain(m.def()) {
            if let Some(s) = slot(v) {
                refs[s] += 1;
            }
        }
    }
    let mut order: Vec<usize> = (0..n).filter(|&s| refs[s] > 0).collect();
    order.sort_by_key(|&s| (std::cmp::Reverse(refs[s]), s));
    let mut home = vec![Home::Stack(0); n];
    // r12 and LR first (free), then the high registers the convention leaves free, from
    // r11 down (the firmware glue re-establishes the limiter's gain in r11 most cheaply,
    // `hi`), then the callee-saved ones from r8 up.
    let mut closed: Vec<u8> = if cfg.lr { vec![12, 14] } else { vec![12] };
    closed.extend((8..12u8).rev().filter(|&r| cfg.free & 1 << r != 0));
    closed.extend((8..12u8).filter(|&r| cfg.free & 1 << r == 0));
    let closed = &closed[..];
    let mut taken = vec![false; n];
    // Each high register in turn takes the slots it can hold (most referenced first, each
    // disjoint from those it holds already); a callee-saved one only when those slots are
    // referenced at least HI_FIRST_REFS (HI_PAIR_REFS) times in all.
    for &r in closed {
        let mut spans: Vec<(usize, usize)> = Vec::new();
        let mut mine = Vec::new();
        for &s in &order {
            let span = alloc.slot_span[s];
            if !taken[s] && spans.iter().all(|&(a, b)| b < span.0 || span.1 < a) {
                spans.push(span);
                mine.push(s);
            }
        }
        let total: u32 = mine.iter().map(|&s| refs[s]).sum();
        // Callee-saved registers are saved and restored in pairs: the second of a pair
        // costs less than the first.
        let opened = closed
            .iter()
            .filter(|&&h| {
                (8..=11).contains(&h) && cfg.free & 1 << h == 0 && home.contains(&Home::Hi(h))
            })
            .count();
        let need = if cfg.free & 1 << r != 0 {
            HI_FREE_REFS
        } else if opened % 2 == 1 {
            HI_PAIR_REFS
        } else {
            HI_FIRST_REFS
        };
        if mine.is_empty() || (!matches!(r, 12 | 14) && total < need) {
            continue;
        }
        for s in mine {
            taken[s] = true;
            home[s] = Home::Hi(r);
        }
    }
    let mut next_stack = 0u16;
    for s in 0..n {
        if !taken[s] {
            home[s] = Home::Stack(next_stack);
            next_stack += 1;
        }
    }
    home
}

impl Lower<'_> {
    fn loc(&self, v: V) -> Loc {
        if v == STATE_V {
            return Loc::Reg(7);
        }
        self.alloc.loc[v.0 as usize].expect("referenced register has a location")
    }

    fn i(&mut self, i: Instr) {
        self.buf.i(i);
    }

    /// The buffer's label for `l`.
    fn label(&mut self, l: Label) -> buffer::Label {
        let buf = &mut *self.buf;
        *self.labels.entry(l.0).or_insert_with(|| buf.label())
    }

    /// The scratch register a reload should take: the other one if `k` holds an operand of
    /// this instruction, else whichever holds nothing or the value read again last.
    fn victim(&self, k: usize) -> usize {
        if self.pinned[k] {
            return 1 - k;
        }
        if self.pinned[1 - k] {
            return k;
        }
        let next = |j: usize| -> usize {
            match self.holds[j] {
                None => usize::MAX,
                Some(h) => self.reads.get(&h).map_or(usize::MAX, |at| {
                    let p = at.partition_point(|&i| i <= self.at);
                    at.get(p).copied().unwrap_or(usize::MAX)
                }),
            }
        };
        if next(1 - k) > next(k) {
            1 - k
        } else {
            k
        }
    }

    /// A register holding `v` for reading: its own, a scratch register that already holds
    /// its slot's value or its rematerialised word, or scratch `k` (the other one if `k`
    /// holds an operand of this instruction, else the one [`Lower::victim`] picks) after a
    /// reload.
    fn read(&mut self, v: V, k: usize) -> u8 {
        let held = match self.loc(v) {
            Loc::Reg(r) => return r,
            Loc::Remat(how) => Held::Remat(how),
            Loc::Slot(s) => Held::Slot(s),
        };
        if let Some(j) = (0..2).find(|&j| self.holds[j] == Some(held)) {
            self.pinned[j] = true;
            return self.alloc.scratch[j];
        }
        // The low register a stack slot was just stored from still holds its value (the
        // instruction writing it reads its operands first): read it there.
        if let (Held::Slot(s), Some((c, cs))) = (held, self.copy) {
            if cs == s {
                return c;
            }
        }
        let k = self.victim(k);
        self.pinned[k] = true;
        let r = self.alloc.scratch[k];
        match held {
            Held::Remat(how) => self.remat(r, how),
            Held::Slot(s) => self.transfer_home(MemOp::Ldr, r, s),
        }
        self.holds[k] = Some(held);
        r
    }

    /// [`Lower::read`], but never the copy of a spill slot in low register `r` (an
    /// instruction writes `r` before reading `v`).
    fn read_not_in(&mut self, v: V, k: usize, r: u8) -> u8 {
        let copy = self.copy;
        if copy.is_some_and(|(c, _)| c == r) {
            self.copy = None;
        }
        let got = self.read(v, k);
        self.copy = copy;
        got
    }

    /// The high register `v`'s spill slot lives in, when no low register holds its value
    /// now: an instruction with a high-register form (`CMP`, `MOV`) reads it there, without
    /// a `MOV` into a scratch register first.
    fn hi_home(&self, v: V) -> Option<u8> {
        let Loc::Slot(s) = self.loc(v) else {
            return None;
        };
        let cached = self.cached(s);
        match self.home[s as usize] {
            Home::Hi(h) if !cached => Some(h),
            _ => None,
        }
    }

    /// Where `v` lives in a spill slot that no low register holds now: copies it straight
    /// into low register `r` from its home (`MOV` from a high register, `LDR` from the stack)
    /// and returns true — a two-address instruction's `MOV d, a` then needs no reload into a
    /// scratch register first.
    fn reload_into(&mut self, v: V, r: u8) -> bool {
        match self.loc(v) {
            Loc::Slot(s) if !self.cached(s) => {
                self.transfer_home(MemOp::Ldr, r, s);
                true
            }
            // A rematerialised word no scratch register holds: recomputed straight into `r`.
            Loc::Remat(how) if !self.holds.contains(&Some(Held::Remat(how))) => {
                self.remat(r, how);
                true
            }
            _ => false,
        }
    }

    /// Recomputes a rematerialised word into low register `r`.
    fn remat(&mut self, r: u8, how: Remat) {
        match how {
            Remat::Const(imm) => self.movi(r, imm),
            Remat::State(op, off) => self.i(Instr::MemImm {
                op,
                rt: r,
                rn: 7,
                imm: off,
            }),
        }
    }

    /// The register to write `v` into (when spilled: scratch 0, or scratch 1 if scratch 0
    /// is `avoid`), and the store to do after.
    fn write(&mut self, v: V, avoid: Option<u8>) -> (u8, Option<u16>) {
        match self.loc(v) {
            Loc::Reg(r) => (r, None),
            Loc::Remat(_) => unreachable!("a rematerialised register's definition is not emitted"),
            Loc::Slot(s) => {
                let j = usize::from(avoid == Some(self.alloc.scratch[0]));
                self.holds[j] = None;
                (self.alloc.scratch[j], Some(s))
            }
        }
    }

    /// Whether `v` lives in a register of its own that is free after this instruction (its
    /// last reference; no other register is defined here but the instruction's own).
    fn ends_here_in(&self, v: V, r: u8) -> bool {
        v != STATE_V
            && self.loc(v) == Loc::Reg(r)
            && self.at > 0
            && self.last.get(v.0 as usize) == Some(&self.at)
            && !self.alloc.scratch.contains(&r)
    }

    /// Stores the value in low register `r` (not necessarily a scratch register) as spill
    /// slot `s`'s new value.
    fn spill_from(&mut self, r: u8, s: u16) {
        for j in 0..2 {
            if self.holds[j] == Some(Held::Slot(s)) {
                self.holds[j] = None;
            }
        }
        self.store_home(r, s);
        match self.alloc.scratch.iter().position(|&x| x == r) {
            Some(j) => self.holds[j] = Some(Held::Slot(s)),
            // A reload before `r` is written again reads it there instead (no `LDR` from a
            // stack home, no `MOV` from a high one).
            None => self.copy = Some((r, s)),
        }
    }

    /// Forgets what the instruction about to be lowered invalidates: a copy in the low
    /// register it defines, cached state words a store may write.
    fn invalidate(&mut self, m: &M) {
        if let (Some((c, _)), Some(Loc::Reg(r))) = (self.copy, m.def().map(|d| self.loc(d))) {
            if c == r {
                self.copy_ends = Some(c);
            }
        }
        let written = match *m {
            M::Store {
                op,
                base: Base::State,
                off,
                ..
            } => Some((op, off)),
            M::Store {
                base: Base::V(b), ..
            } if b == ARG2 => return,
            M::Store { .. } | M::StoreR { .. } => None,
            _ => return,
        };
        for h in &mut self.holds {
            if let Some(Held::Remat(Remat::State(k, o))) = *h {
                if written.is_none_or(|w| super::mir::accesses_overlap(w, (k, o))) {
                    *h = None;
                }
            }
        }
    }

    fn spill(&mut self, r: u8, slot: Option<u16>) {
        if let Some(s) = slot {
            // The scratch register written now holds the slot's new value; a copy of the
            // slot in the other one is stale.
            let j = usize::from(self.alloc.scratch[1] == r);
            self.holds[j] = Some(Held::Slot(s));
            if self.holds[1 - j] == Some(Held::Slot(s)) {
                self.holds[1 - j] = None;
            }
            self.store_home(r, s);
        }
    }

    /// Stores low register `r` into spill slot `s`'s home.
    fn store_home(&mut self, r: u8, s: u16) {
        if self.copy.is_some_and(|(_, cs)| cs == s) {
            self.copy = None;
        }
        self.transfer_home(MemOp::Str, r, s);
    }

    /// Whether a low register holds spill slot `s`'s value now (a scratch register's
    /// cache, or the copy of the slot just stored).
    fn cached(&self, s: u16) -> bool {
        self.holds.contains(&Some(Held::Slot(s))) || self.copy.is_some_and(|(_, cs)| cs == s)
    }

    /// Moves low register `r` and spill slot `s`'s home: `op` [`MemOp::Ldr`] reads the home
    /// into `r` (`MOV r, hi` or `LDR r, [sp, #…]`), [`MemOp::Str`] writes `r` to it.
    fn transfer_home(&mut self, op: MemOp, r: u8, s: u16) {
        match self.home[s as usize] {
            Home::Hi(h) if op == MemOp::Ldr => self.i(Instr::MovHi { rd: r, rm: h }),
            Home::Hi(h) => self.i(Instr::MovHi { rd: h, rm: r }),
            Home::Stack(w) => self.i(Instr::MemImm {
                op,
                rt: r,
                rn: 13,
                imm: 4 * w,
            }),
        }
    }

    fn movi(&mut self, rd: u8, imm: i32) {
        if (0..=255).contains(&imm) {
            self.i(Instr::MovImm { rd, imm: imm as u8 });
        } else if (0..=255).contains(&!imm) {
            // MVNS keeps C (no shift), so this is as flag-safe as MOVS.
            self.i(Instr::MovImm {
                rd,
                imm: !imm as u8,
            });
            self.i(Instr::Alu {
                op: AluOp::Mvn,
                rdn: rd,
                rm: rd,
            });
        } else {
            self.buf.ldr_const(rd, imm as u32);
        }
    }

    /// Records the reload cache on a branch to `l` (the body branches only forward).
    fn branch_to(&mut self, l: Label) {
        let h = Ways {
            holds: self.holds,
            copy: self.copy,
        };
        self.pending
            .entry(l.0)
            .and_modify(|w| *w = meet(*w, h))
            .or_insert(h);
    }

    fn base(&mut self, b: Base, k: usize) -> u8 {
        match b {
            Base::State => 7,
            Base::V(v) => self.read(v, k),
        }
    }

    /// Lowers `m`; a copy its destination register held ends after it.
    fn one(&mut self, m: &M) {
        self.copy_ends = None;
        self.one_inner(m);
        if let Some(c) = self.copy_ends.take() {
            if self.copy.is_some_and(|(r, _)| r == c) {
                self.copy = None;
            }
        }
    }

    fn one_inner(&mut self, m: &M) {
        self.pinned = [false, false];
        self.invalidate(m);
        if let Some(Loc::Remat(_)) = m.def().map(|d| self.loc(d)) {
            // Recomputed at each read instead.
            return;
        }
        match *m {
            M::Movi { d, imm } => {
                let (r, s) = self.write(d, None);
                self.movi(r, imm);
                self.spill(r, s);
            }
            M::Mov { d, s } if matches!(self.loc(d), Loc::Slot(_)) => {
                // A copy into a spilled register is a store of the source.
                let src = self.read(s, 1);
                let Loc::Slot(slot) = self.loc(d) else {
                    unreachable!()
                };
                self.spill_from(src, slot);
            }
            M::Mov { d, s } => {
                if let Loc::Reg(r) = self.loc(d) {
                    if self.reload_into(s, r) {
                        return;
                    }
                }
                let src = self.read(s, 1);
                let (r, sl) = self.write(d, None);
                if r != src {
                    self.i(Instr::MovHi { rd: r, rm: src });
                }
                self.spill(r, sl);
            }
            M::AddSub { sub, d, a, b } => {
                let (ra, rb) = (self.read(a, 0), self.read(b, 1));
                let (r, s) = self.write(d, None);
                self.i(if sub {
                    Instr::SubReg {
                        rd: r,
                        rn: ra,
                        rm: rb,
                    }
                } else {
                    Instr::AddReg {
                        rd: r,
                        rn: ra,
                        rm: rb,
                    }
                });
                self.spill(r, s);
            }
            M::AddSubI { sub, d, a, imm } => {
                // The 8-bit form is two-address: a spilled `a` goes straight into `d`.
                if let Loc::Reg(r) = self.loc(d) {
                    if imm > 7 && self.reload_into(a, r) {
                        self.i(if sub {
                            Instr::SubImm { rd: r, rn: r, imm }
                        } else {
                            Instr::AddImm { rd: r, rn: r, imm }
                        });
                        return;
                    }
                }
                let ra = self.read(a, 0);
                let (r, s) = self.write(d, None);
                let rn = if imm > 7 && r != ra {
                    self.i(Instr::MovHi { rd: r, rm: ra });
                    r
                } else {
                    ra
                };
                self.i(if sub {
                    Instr::SubImm { rd: r, rn, imm }
                } else {
                    Instr::AddImm { rd: r, rn, imm }
                });
                self.spill(r, s);
            }
            M::Alu2 { op, d, a, m } => {
                // `a` homed in a high register while `d` has a low register of its own: the
                // two-address `MOV d, a` copies it from there (no reload into a scratch
                // register first).
                if let (Loc::Slot(_), Loc::Reg(r)) = (self.loc(a), self.loc(d)) {
                    if a != m {
                        let rm = self.read(m, 1);
                        if r != rm && self.reload_into(a, r) {
                            self.i(Instr::Alu { op, rdn: r, rm });
                            return;
                        }
                    }
                }
                let ra = self.read(a, 0);
                let commutative = super::mir::commutative(op);
                // `MOV d, a` would overwrite a copy of `m` in `d`'s register: `m` is then
                // reloaded instead.
                let rm = match self.loc(d) {
                    _ if m == a => ra,
                    Loc::Reg(r) if !commutative && r != ra => self.read_not_in(m, 1, r),
                    _ => self.read(m, 1),
                };
                // A spilled result computed in the register of an operand that ends here
                // (no `MOV` into a scratch register first), then stored.
                if let Loc::Slot(slot) = self.loc(d) {
                    let in_place = if self.ends_here_in(a, ra) {
                        Some((ra, rm))
                    } else if commutative && self.ends_here_in(m, rm) {
                        Some((rm, ra))
                    } else {
                        None
                    };
                    if let Some((r, other)) = in_place {
                        self.i(Instr::Alu {
                            op,
                            rdn: r,
                            rm: other,
                        });
                        self.spill_from(r, slot);
                        return;
                    }
                }
                // A non-commutative op cannot write `m`'s register first (`MOV d, a`).
                let avoid = (!commutative && rm != ra).then_some(rm);
                let (r, s) = self.write(d, avoid);
                let other = if r == ra {
                    rm
                } else if r == rm && commutative {
                    ra
                } else {
                    debug_assert!(r != rm, "late use shares the definition's register");
                    self.i(Instr::MovHi { rd: r, rm: ra });
                    rm
                };
                self.i(Instr::Alu {
                    op,
                    rdn: r,
                    rm: other,
                });
                self.spill(r, s);
            }
            M::Unary { op, d, m } => {
                let rm = self.read(m, 0);
                let (r, s) = self.write(d, None);
                self.i(Instr::Alu { op, rdn: r, rm });
                self.spill(r, s);
            }
            M::Sh { op, d, m, imm } => {
                let rm = self.read(m, 0);
                let (rd, s) = self.write(d, None);
                self.i(match op {
                    Shift::Lsl => Instr::LslImm { rd, rm, imm },
                    Shift::Lsr => Instr::LsrImm { rd, rm, imm },
                    Shift::Asr => Instr::AsrImm { rd, rm, imm },
                });
                self.spill(rd, s);
            }
            M::Uxth { d, m } => {
                let rm = self.read(m, 0);
                let (rd, s) = self.write(d, None);
                self.i(Instr::Uxth { rd, rm });
                self.spill(rd, s);
            }
            M::Cmp { a, b } => {
                // `CMP Rn, Rm` takes high registers (one of them is enough; ARMv6-M ARM
                // A6.7.17, encoding T2): a slot homed in one is compared in place.
                let (ha, hb) = (self.hi_home(a), self.hi_home(b));
                let (ra, rb) = match (ha, hb) {
                    (Some(h), Some(k)) => (h, k),
                    (Some(h), None) => (h, if b == a { h } else { self.read(b, 1) }),
                    (None, Some(h)) => (self.read(a, 0), h),
                    (None, None) => (self.read(a, 0), self.read(b, 1)),
                };
                self.i(if ra < 8 && rb < 8 {
                    Instr::Alu {
                        op: AluOp::Cmp,
                        rdn: ra,
                        rm: rb,
                    }
                } else {
                    Instr::CmpHi { rn: ra, rm: rb }
                });
            }
            M::CmpI { a, imm } => {
                let ra = self.read(a, 0);
                self.i(Instr::CmpImm { rn: ra, imm });
            }
            M::Load { op, t, base, off } => {
                let rn = self.base(base, 0);
                let (rt, s) = self.write(t, None);
                self.i(Instr::MemImm {
                    op,
                    rt,
                    rn,
                    imm: off,
                });
                self.spill(rt, s);
            }
            M::LoadR { op, t, base, idx } => {
                let rn = self.base(base, 0);
                let rm = self.read(idx, 1);
                let (rt, s) = self.write(t, None);
                self.i(Instr::MemReg { op, rt, rn, rm });
                self.spill(rt, s);
            }
            M::StoreR { op, t, idx } => {
                let rt = self.read(t, 0);
                let rm = self.read(idx, 1);
                self.i(Instr::MemReg { op, rt, rn: 7, rm });
            }
            M::Store { op, t, base, off } => {
                let rt = self.read(t, 0);
                let rn = self.base(base, 1);
                self.i(Instr::MemImm {
                    op,
                    rt,
                    rn,
                    imm: off,
                });
            }
            M::Label(l) => {
                let ways = self.pending.remove(&l.0);
                let here = Ways {
                    holds: self.holds,
                    copy: self.copy,
                };
                let known = match (self.reachable, ways) {
                    (true, Some(w)) => meet(here, w),
                    (true, None) => here,
                    (false, Some(w)) => w,
                    (false, None) => Ways {
                        holds: [None, None],
                        copy: None,
                    },
                };
                self.holds = known.holds;
                self.copy = known.copy;
                self.reachable = true;
                let l = self.label(l);
                self.buf.bind(l);
            }
            M::B(l) => {
                self.branch_to(l);
                self.reachable = false;
                let l = self.label(l);
                self.buf.b(l);
                self.buf.pool_after_branch();
            }
            M::Bc(c, l) => {
                self.branch_to(l);
                let l = self.label(l);
                self.buf.bc(c as u8, l);
            }
            M::Note(ref s) => self.buf.note(s.clone()),
            M::Mark(k) => self.buf.mark(k),
            // `MOV r8, r8`: what GNU as assembles `nop` to for ARMv6-M (1 cycle, no effect).
            M::Nop => self.i(Instr::MovHi { rd: 8, rm: 8 }),
        }
    }
}

/// Lowers an allocated body into `buf` as function `name`, with the prologue and epilogue
/// of its calling convention: save the callee-saved registers used (but those
/// [`Homes::free`] leaves free) and LR, `r7 = r0` (the state pointer), the frame for spill
/// slots, store spilled arguments; at the end, free the frame and `POP {…, PC}`. The
/// buffer must relax long branches with [`buffer::LongBranch::Bl`] (LR is saved). Returns
/// the callee-saved registers the function leaves modified (bit *n* = r*n*; within
/// [`Homes::free`]).
pub(crate) fn lower(
    buf: &mut CodeBuffer,
    name: &str,
    code: &[M],
    alloc: &Allocation,
    cfg: Homes,
) -> u16 {
    let home = homes(code, alloc, cfg);
    let frame = home.iter().filter(|h| matches!(h, Home::Stack(_))).count() as u16;
    // Callee-saved high registers used as spill homes, saved in pairs through r0 and r3
    // (free after `r7 = r0`; r3 is no argument) so the stack stays 8-byte aligned; those
    // the convention leaves free are clobbered, not saved.
    let mut used_high: Vec<u8> = home
        .iter()
        .filter_map(|h| match h {
            Home::Hi(r) if (8..=11).contains(r) => Some(*r),
            _ => None,
        })
        .collect();
    used_high.sort_unstable();
    used_high.dedup();
    let (free_high, high): (Vec<u8>, Vec<u8>) =
        used_high.iter().partition(|&&r| cfg.free & 1 << r != 0);
    let used_low = (alloc.used_mask | 0x80) & 0xf0;
    let clobbered = (used_low as u16 & cfg.free) | free_high.iter().fold(0, |m, &r| m | 1 << r);
    let start = buf.len();
    buf.begin_function(name);
    let mut l = Lower {
        alloc,
        buf,
        labels: HashMap::new(),
        holds: [None, None],
        pending: HashMap::new(),
        reachable: true,
        copy: None,
        copy_ends: None,
        reads: reads(code, alloc),
        pinned: [false, false],
        last: last_refs(code, alloc.loc.len()),
        at: 0,
        home,
    };
    let saved = used_low & !(cfg.free as u8);
    l.i(Instr::Push {
        list: saved as u16 | 1 << 14,
    });
    l.i(Instr::MovHi { rd: 7, rm: 0 });
    for pair in high.chunks(2) {
        l.i(Instr::MovHi { rd: 0, rm: pair[0] });
        let mut list = 1u16;
        if let Some(&h) = pair.get(1) {
            l.i(Instr::MovHi { rd: 3, rm: h });
            list |= 1 << 3;
        }
        l.i(Instr::Push { list });
    }
    if frame > 0 {
        for chunk in chunks(4 * frame) {
            l.i(Instr::SubSp { imm: chunk });
        }
    }
    for (arg, r) in [(super::mir::ARG1, 1u8), (ARG2, 2u8)] {
        match alloc.loc.get(arg.0 as usize).copied().flatten() {
            Some(Loc::Slot(s)) => l.store_home(r, s),
            Some(Loc::Reg(x)) if x != r => unreachable!("arguments are pre-coloured"),
            _ => {}
        }
    }
    for (i, m) in code.iter().enumerate() {
        l.at = i;
        l.one(m);
    }
    if frame > 0 {
        for chunk in chunks(4 * frame) {
            l.i(Instr::AddSp { imm: chunk });
        }
    }
    for pair in high.chunks(2).rev() {
        let mut list = 1u16;
        if pair.len() > 1 {
            list |= 1 << 3;
        }
        l.i(Instr::Pop { list });
        l.i(Instr::MovHi { rd: pair[0], rm: 0 });
        if let Some(&h) = pair.get(1) {
            l.i(Instr::MovHi { rd: h, rm: 3 });
        }
    }
    l.i(Instr::Pop {
        list: saved as u16 | 1 << 15,
    });
    super::peephole::run(l.buf, start);
    l.buf.end_function();
    clobbered
}

/// The instructions reading each spilled or rematerialised value of `code`, ascending.
fn reads(code: &[M], alloc: &Allocation) -> HashMap<Held, Vec<usize>> {
    let mut at: HashMap<Held, Vec<usize>> = HashMap::new();
    for (i, m) in code.iter().enumerate() {
        for v in m.uses() {
            let held = match alloc.loc.get(v.0 as usize).copied().flatten() {
                Some(Loc::Slot(s)) => Held::Slot(s),
                Some(Loc::Remat(r)) => Held::Remat(r),
                _ => continue,
            };
            at.entry(held).or_default().push(i);
        }
    }
    at
}

/// The index of the last instruction reading or writing each of `n` virtual registers.
fn last_refs(code: &[M], n: usize) -> Vec<usize> {
    let mut last = vec![0usize; n];
    for (i, m) in code.iter().enumerate() {
        for v in m.uses().into_iter().chain(m.def()) {
            if let Some(x) = last.get_mut(v.0 as usize) {
                *x = i;
            }
        }
    }
    last
}

/// `SUB SP`/`ADD SP` immediates are at most 508 bytes.
fn chunks(mut bytes: u16) -> Vec<u16> {
    let mut v = Vec::new();
    while bytes > 0 {
        let c = bytes.min(508);
        v.push(c);
        bytes -= c;
    }
    v
}

/// The object's code: `buf` assembled at 0, with `exclusive`'s pairs of [`M::Mark`]s
/// (from every function) as pairs of `.text` offsets.
///
/// Errors: [`ThumbError::Encoding`] for what the buffer refuses (a backend bug).
pub(crate) fn assemble(buf: &CodeBuffer, exclusive: &[(u32, u32)]) -> Result<Code, ThumbError> {
    let a = buf
        .finish(0)
        .map_err(|e| ThumbError::Encoding(e.to_string()))?;
    // A select arm's facts only where the arm has code of its own: its end mark apart from
    // its start (an empty arm's start is the join after it).
    let at = |m: &u32| -> Option<usize> {
        let start = *a.marks.get(m)?;
        match crate::fixed::flow::arm_end(*m) {
            Some(end) if a.marks.get(&end).is_none_or(|&e| e == start) => None,
            _ => Some(start),
        }
    };
    let exclusive = exclusive
        .iter()
        .filter_map(|(x, y)| Some((at(x)?, at(y)?)))
        .collect();
    Ok(Code {
        text: a.text,
        symbols: a.symbols,
        data: a.data,
        listing: a.listing,
        notes: a.notes,
        exclusive,
    })
}
