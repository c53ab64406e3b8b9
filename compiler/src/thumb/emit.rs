//! Emission: allocated machine IR to Thumb instructions, literal pools, branch relaxation,
//! bytes (the emulator's encoder, one function per encoding format) and the GNU assembler
//! listing.

use super::mir::{Base, Label, Shift, M, V};
use super::regalloc::{Allocation, Loc};
use super::select::STATE_V;
use super::ThumbError;
use std::collections::HashMap;
use std::fmt::Write as _;
use tactus_emulator::decode::{AluOp, Instr, MemOp};
use tactus_emulator::encode::{enc_imm8, encode};

/// One item of a function body after allocation.
#[derive(Clone, Debug)]
enum Item {
    /// A fixed instruction.
    I(Instr),
    /// `LDR rt, =value` (literal pool).
    Lit {
        rt: u8,
        value: i32,
    },
    /// A (conditional) branch to a label; relaxed to a long form when out of range.
    Br {
        cond: Option<u8>,
        target: Label,
    },
    Label(Label),
    /// A literal island: `B over` (unless `fallthrough` is false), alignment, the words.
    Island {
        id: usize,
        jump: bool,
    },
    Note(String),
    /// Start of a top-level `if` body (see [`M::Mark`]).
    Mark(u32),
}

/// Lowered code of one function.
pub(crate) struct Function {
    /// Symbol name.
    pub name: String,
    items: Vec<Item>,
    /// Pairs of [`M::Mark`]s whose blocks no single call executes both of.
    pub exclusive: Vec<(u32, u32)>,
}

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
    /// `select::exclusions`).
    pub exclusive: Vec<(usize, usize)>,
}

struct Lower<'a> {
    alloc: &'a Allocation,
    items: Vec<Item>,
    /// The stack slot each scratch register is known to hold (reload cache): valid in
    /// straight-line code, forgotten at every label (a join point).
    holds: [Option<u16>; 2],
    /// Where each spill slot lives: a high register (`MOV` to and from it costs 1 cycle
    /// where `LDR`/`STR` cost 2) or a word of the stack frame.
    home: Vec<Home>,
}

/// The home of a spill slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Home {
    /// A high register (`r8`–`r12`).
    Hi(u8),
    /// A word of the stack frame (index from SP).
    Stack(u16),
}

/// Spill slots get the high registers, most referenced first: `r12` (caller-saved, free),
/// then `r8`–`r11` (callee-saved: each costs two `MOV`s and a share of a `PUSH`/`POP` pair,
/// about 4 cycles, so it is used only for a slot referenced at least this many times).
const HI_MIN_REFS: u32 = 6;

/// The homes of `alloc`'s spill slots, from their static reference counts in `code`.
fn homes(code: &[M], alloc: &Allocation) -> Vec<Home> {
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
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&s| (std::cmp::Reverse(refs[s]), s));
    let mut home = vec![Home::Stack(0); n];
    let mut hi = [12u8, 8, 9, 10, 11].into_iter();
    let mut next_stack = 0u16;
    for s in order {
        let h = match hi.clone().next() {
            Some(12) if refs[s] > 0 => hi.next(),
            Some(r) if refs[s] >= HI_MIN_REFS => {
                let _ = r;
                hi.next()
            }
            _ => None,
        };
        home[s] = match h {
            Some(r) => Home::Hi(r),
            None => {
                next_stack += 1;
                Home::Stack(next_stack - 1)
            }
        };
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
        self.items.push(Item::I(i));
    }

    /// A register holding `v` for reading: its own, or scratch `k` after a reload.
    fn read(&mut self, v: V, k: usize) -> u8 {
        match self.loc(v) {
            Loc::Reg(r) => r,
            Loc::Slot(s) => {
                let r = self.alloc.scratch[k];
                if self.holds[k] != Some(s) {
                    match self.home[s as usize] {
                        Home::Hi(h) => self.i(Instr::MovHi { rd: r, rm: h }),
                        Home::Stack(w) => self.i(Instr::MemImm {
                            op: MemOp::Ldr,
                            rt: r,
                            rn: 13,
                            imm: 4 * w,
                        }),
                    }
                    self.holds[k] = Some(s);
                }
                r
            }
        }
    }

    /// The register to write `v` into (scratch 0 when spilled), and the store to do after.
    fn write(&mut self, v: V) -> (u8, Option<u16>) {
        match self.loc(v) {
            Loc::Reg(r) => (r, None),
            Loc::Slot(s) => {
                self.holds[0] = None;
                (self.alloc.scratch[0], Some(s))
            }
        }
    }

    fn spill(&mut self, r: u8, slot: Option<u16>) {
        if let Some(s) = slot {
            // Scratch 0 now holds the slot's new value; a copy in scratch 1 is stale.
            self.holds = [Some(s), None];
            self.store_home(r, s);
        }
    }

    /// Stores low register `r` into spill slot `s`'s home.
    fn store_home(&mut self, r: u8, s: u16) {
        match self.home[s as usize] {
            Home::Hi(h) => self.i(Instr::MovHi { rd: h, rm: r }),
            Home::Stack(w) => self.i(Instr::MemImm {
                op: MemOp::Str,
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
            self.items.push(Item::Lit { rt: rd, value: imm });
        }
    }

    fn base(&mut self, b: Base, k: usize) -> u8 {
        match b {
            Base::State => 7,
            Base::V(v) => self.read(v, k),
        }
    }

    fn one(&mut self, m: &M) {
        match *m {
            M::Movi { d, imm } => {
                let (r, s) = self.write(d);
                self.movi(r, imm);
                self.spill(r, s);
            }
            M::Mov { d, s } => {
                let src = self.read(s, 1);
                let (r, sl) = self.write(d);
                if r != src {
                    self.i(Instr::MovHi { rd: r, rm: src });
                }
                self.spill(r, sl);
            }
            M::AddSub { sub, d, a, b } => {
                let (ra, rb) = (self.read(a, 0), self.read(b, 1));
                let (r, s) = self.write(d);
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
                let ra = self.read(a, 0);
                let (r, s) = self.write(d);
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
                let ra = self.read(a, 0);
                let rm = if m == a { ra } else { self.read(m, 1) };
                let (r, s) = self.write(d);
                let commutative = matches!(
                    op,
                    AluOp::And | AluOp::Orr | AluOp::Eor | AluOp::Adc | AluOp::Mul
                );
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
                let (r, s) = self.write(d);
                self.i(Instr::Alu { op, rdn: r, rm });
                self.spill(r, s);
            }
            M::Sh { op, d, m, imm } => {
                let rm = self.read(m, 0);
                let (rd, s) = self.write(d);
                self.i(match op {
                    Shift::Lsl => Instr::LslImm { rd, rm, imm },
                    Shift::Lsr => Instr::LsrImm { rd, rm, imm },
                    Shift::Asr => Instr::AsrImm { rd, rm, imm },
                });
                self.spill(rd, s);
            }
            M::Uxth { d, m } => {
                let rm = self.read(m, 0);
                let (rd, s) = self.write(d);
                self.i(Instr::Uxth { rd, rm });
                self.spill(rd, s);
            }
            M::Cmp { a, b } => {
                let (ra, rb) = (self.read(a, 0), self.read(b, 1));
                self.i(Instr::Alu {
                    op: AluOp::Cmp,
                    rdn: ra,
                    rm: rb,
                });
            }
            M::CmpI { a, imm } => {
                let ra = self.read(a, 0);
                self.i(Instr::CmpImm { rn: ra, imm });
            }
            M::Load { op, t, base, off } => {
                let rn = self.base(base, 0);
                let (rt, s) = self.write(t);
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
                let (rt, s) = self.write(t);
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
                self.holds = [None, None];
                self.items.push(Item::Label(l))
            }
            M::B(l) => self.items.push(Item::Br {
                cond: None,
                target: l,
            }),
            M::Bc(c, l) => self.items.push(Item::Br {
                cond: Some(c as u8),
                target: l,
            }),
            M::Note(ref s) => self.items.push(Item::Note(s.clone())),
            M::Mark(k) => self.items.push(Item::Mark(k)),
            // `MOV r8, r8`: what GNU as assembles `nop` to for ARMv6-M (1 cycle, no effect).
            M::Nop => self.i(Instr::MovHi { rd: 8, rm: 8 }),
        }
    }
}

/// Lowers an allocated body to items, with the AAPCS prologue and epilogue: save the
/// callee-saved registers used and LR, `r7 = r0` (the state pointer), the frame for
/// spill slots, store spilled arguments; at the end, free the frame and `POP {…, PC}`.
pub(crate) fn lower(name: &str, code: &[M], alloc: &Allocation) -> Function {
    let home = homes(code, alloc);
    let frame = home.iter().filter(|h| matches!(h, Home::Stack(_))).count() as u16;
    // Callee-saved high registers used as spill homes, saved in pairs through r0 and r3
    // (free after `r7 = r0`; r3 is no argument) so the stack stays 8-byte aligned.
    let mut high: Vec<u8> = home
        .iter()
        .filter_map(|h| match h {
            Home::Hi(r) if (8..=11).contains(r) => Some(*r),
            _ => None,
        })
        .collect();
    high.sort_unstable();
    let mut l = Lower {
        alloc,
        items: Vec::new(),
        holds: [None, None],
        home,
    };
    let saved = (alloc.used_mask | 0x80) & 0xf0;
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
    for (arg, r) in [(super::select::ARG1, 1u8), (super::select::ARG2, 2u8)] {
        match alloc.loc.get(arg.0 as usize).copied().flatten() {
            Some(Loc::Slot(s)) => l.store_home(r, s),
            Some(Loc::Reg(x)) if x != r => unreachable!("arguments are pre-coloured"),
            _ => {}
        }
    }
    for m in code {
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
    Function {
        name: name.to_string(),
        items: l.items,
        exclusive: Vec::new(),
    }
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

/// Distance (bytes) after which pending literals are flushed into an island: the `LDR`
/// literal reach is 1020 bytes; sizes are estimated with every branch long, so relaxation
/// never lengthens a distance past the estimate.
const ISLAND_AFTER: usize = 800;

fn est_size(it: &Item) -> usize {
    match it {
        Item::I(i) => encode(i).map(|e| e.bytes().len()).unwrap_or(2),
        Item::Lit { .. } => 2,
        Item::Br { .. } => 6,
        Item::Label(_) | Item::Note(_) | Item::Mark(_) => 0,
        Item::Island { .. } => 0,
    }
}

/// Assembles functions into one `.text`.
pub(crate) fn assemble(funcs: Vec<Function>) -> Result<Code, ThumbError> {
    // 1. Insert literal islands (per function: after the body, and inside when far).
    let mut islands: Vec<Vec<i32>> = Vec::new();
    let mut fitems: Vec<(String, Vec<Item>)> = Vec::new();
    let excl: Vec<(u32, u32)> = funcs.iter().flat_map(|f| f.exclusive.clone()).collect();
    for f in funcs {
        let mut out = Vec::new();
        let mut pending_since: Option<usize> = None;
        let mut pos = 0usize;
        let mut cur: Vec<i32> = Vec::new();
        for it in f.items {
            if let Item::Lit { value, .. } = it {
                if !cur.contains(&value) {
                    cur.push(value);
                }
                pending_since.get_or_insert(pos);
            }
            pos += est_size(&it);
            out.push(it);
            if let Some(p0) = pending_since {
                if pos - p0 + 4 * cur.len() + 8 > ISLAND_AFTER {
                    out.push(Item::Island {
                        id: islands.len(),
                        jump: true,
                    });
                    islands.push(std::mem::take(&mut cur));
                    pos += 4 * islands.last().map_or(0, |v| v.len()) + 4;
                    pending_since = None;
                }
            }
        }
        if !cur.is_empty() {
            out.push(Item::Island {
                id: islands.len(),
                jump: false,
            });
            islands.push(cur);
        }
        fitems.push((f.name, out));
    }
    // 2. Branch relaxation: short until out of range.
    let mut long: HashMap<(usize, usize), bool> = HashMap::new();
    loop {
        let (addrs, labels, _) = layout(&fitems, &islands, &long);
        let mut changed = false;
        for (fi, (_, items)) in fitems.iter().enumerate() {
            for (ii, it) in items.iter().enumerate() {
                if let Item::Br { cond, target } = it {
                    if long.get(&(fi, ii)).copied().unwrap_or(false) {
                        continue;
                    }
                    let at = addrs[fi][ii];
                    let off = labels[&(fi, target.0)] as i64 - (at as i64 + 4);
                    let ok = match cond {
                        Some(_) => (-256..=254).contains(&off),
                        None => (-2048..=2046).contains(&off),
                    };
                    if !ok {
                        long.insert((fi, ii), true);
                        changed = true;
                    }
                }
            }
        }
        if !changed {
            break;
        }
    }
    // 3. Encode.
    let (addrs, labels, island_at) = layout(&fitems, &islands, &long);
    let mut text = Vec::new();
    let mut listing = String::from(
        "    .syntax unified\n    .cpu cortex-m0plus\n    .thumb\n    .text\n    .p2align 2\n",
    );
    let mut symbols = Vec::new();
    let mut data = Vec::new();
    let mut notes = Vec::new();
    let mut marks: std::collections::HashMap<u32, usize> = std::collections::HashMap::new();
    let enc = |i: &Instr| match *i {
        // `ADDS Rdn, Rdn, #imm` with imm < 8 has two 16-bit encodings; GNU as picks T2
        // (imm8), so the listing assembles to the same bytes only if we do too.
        Instr::AddImm { rd, rn, imm } | Instr::SubImm { rd, rn, imm } if rd == rn && rd < 8 => {
            let op = if matches!(i, Instr::SubImm { .. }) {
                3
            } else {
                2
            };
            Ok(enc_imm8(op, rd as u16, imm as u16).to_le_bytes().to_vec())
        }
        _ => encode(i)
            .map(|e| e.bytes())
            .map_err(|e| ThumbError::Encoding(e.to_string())),
    };
    for (fi, (name, items)) in fitems.iter().enumerate() {
        let start = text.len();
        let _ = write!(
            listing,
            "\n    .global {name}\n    .type {name}, %function\n    .thumb_func\n    .p2align 1\n{name}:\n"
        );
        for (ii, it) in items.iter().enumerate() {
            debug_assert_eq!(text.len(), addrs[fi][ii]);
            match it {
                Item::I(i) => {
                    text.extend(enc(i)?);
                    let _ = writeln!(listing, "    {i}");
                }
                Item::Lit { rt, value } => {
                    let (isl, k) = find_lit(items, ii, &islands, *value);
                    let target = island_at[&isl] + 4 * k;
                    let pc = (text.len() + 4) & !3;
                    let imm = target - pc;
                    let i = Instr::LdrLit {
                        rt: *rt,
                        imm: imm as u16,
                    };
                    text.extend(enc(&i)?);
                    let _ = writeln!(listing, "    ldr r{rt}, .Lpool{isl}_{k}");
                }
                Item::Br { cond, target } => {
                    let dest = labels[&(fi, target.0)];
                    let is_long = long.get(&(fi, ii)).copied().unwrap_or(false);
                    let lname = format!(".L{fi}_{}", target.0);
                    let cname = |c: u8| CONDS[c as usize];
                    if !is_long {
                        let off = dest as i32 - (text.len() as i32 + 4);
                        let i = match cond {
                            Some(c) => Instr::BCond {
                                cond: *c,
                                offset: off,
                            },
                            None => Instr::B { offset: off },
                        };
                        text.extend(enc(&i)?);
                        let _ = writeln!(listing, "    b{} {lname}", cond.map_or("", cname));
                    } else {
                        if let Some(c) = cond {
                            // B<!c> over the long branch.
                            let inv = invert(*c);
                            let i = Instr::BCond {
                                cond: inv,
                                offset: 2, // to the instruction after the 4-byte BL
                            };
                            text.extend(enc(&i)?);
                            let _ = writeln!(listing, "    b{} .+6", cname(inv));
                        }
                        // The long form is always BL (4 bytes), so sizes stay as laid out.
                        let off = dest as i32 - (text.len() as i32 + 4);
                        let i = Instr::Bl { offset: off };
                        text.extend(enc(&i)?);
                        let _ = writeln!(listing, "    bl {lname}");
                    }
                }
                Item::Label(lb) => {
                    let _ = writeln!(listing, ".L{fi}_{}:", lb.0);
                }
                Item::Note(s) => {
                    notes.push((text.len(), s.clone()));
                    let _ = writeln!(listing, "    @ {s}");
                }
                Item::Mark(k) => {
                    marks.insert(*k, text.len());
                }
                Item::Island { id, jump } => {
                    let words = &islands[*id];
                    if *jump {
                        let end = island_at[id] + 4 * words.len();
                        let off = end as i32 - (text.len() as i32 + 4);
                        text.extend(enc(&Instr::B { offset: off })?);
                        let _ = writeln!(listing, "    b .Lisland{id}_end");
                    }
                    if !text.len().is_multiple_of(4) {
                        text.extend(enc(&PAD)?);
                        let _ = writeln!(listing, "    mov r8, r8");
                    }
                    debug_assert_eq!(text.len(), island_at[id]);
                    data.push((text.len(), 4 * words.len()));
                    for (k, w) in words.iter().enumerate() {
                        text.extend(w.to_le_bytes());
                        let _ = writeln!(listing, ".Lpool{id}_{k}:\n    .word {w}");
                    }
                    if *jump {
                        let _ = writeln!(listing, ".Lisland{id}_end:");
                    }
                }
            }
        }
        let _ = writeln!(listing, "    .size {name}, .-{name}");
        symbols.push((name.clone(), start, text.len() - start));
        // Functions start on a word boundary (keeps the next function's pools aligned
        // the same way the assembler's `.p2align` does).
        if !text.len().is_multiple_of(4) {
            text.extend(enc(&PAD)?);
            let _ = writeln!(listing, "    mov r8, r8");
        }
    }
    let exclusive = excl
        .iter()
        .filter_map(|(a, b)| Some((*marks.get(a)?, *marks.get(b)?)))
        .collect();
    Ok(Code {
        text,
        symbols,
        data,
        listing,
        notes,
        exclusive,
    })
}

/// Alignment padding: `MOV r8, r8` (0x46c0), the no-op GNU as pads Thumb code with for
/// ARMv6-M, so that the listing assembles to the same bytes.
const PAD: Instr = Instr::MovHi { rd: 8, rm: 8 };

const CONDS: [&str; 14] = [
    "eq", "ne", "cs", "cc", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le",
];

fn invert(c: u8) -> u8 {
    c ^ 1
}

/// The island and index holding `value` for the literal load at `ii`: the first island
/// after it.
fn find_lit(items: &[Item], ii: usize, islands: &[Vec<i32>], value: i32) -> (usize, usize) {
    for it in &items[ii..] {
        if let Item::Island { id, .. } = it {
            if let Some(k) = islands[*id].iter().position(|&w| w == value) {
                return (*id, k);
            }
        }
    }
    unreachable!("every literal has an island after it")
}

type Layout = (
    Vec<Vec<usize>>,
    HashMap<(usize, u32), usize>,
    HashMap<usize, usize>,
);

/// Addresses of every item, of labels, and of island data, for the given branch forms.
fn layout(
    fitems: &[(String, Vec<Item>)],
    islands: &[Vec<i32>],
    long: &HashMap<(usize, usize), bool>,
) -> Layout {
    let mut addrs = Vec::new();
    let mut labels = HashMap::new();
    let mut island_at = HashMap::new();
    let mut pos = 0usize;
    for (fi, (_, items)) in fitems.iter().enumerate() {
        let mut a = Vec::with_capacity(items.len());
        for (ii, it) in items.iter().enumerate() {
            a.push(pos);
            pos += match it {
                Item::I(i) => encode(i).map(|e| e.bytes().len()).unwrap_or(2),
                Item::Lit { .. } => 2,
                Item::Br { cond, .. } => {
                    if long.get(&(fi, ii)).copied().unwrap_or(false) {
                        if cond.is_some() {
                            6
                        } else {
                            4
                        }
                    } else {
                        2
                    }
                }
                Item::Label(l) => {
                    labels.insert((fi, l.0), pos);
                    0
                }
                Item::Note(_) | Item::Mark(_) => 0,
                Item::Island { id, jump } => {
                    let mut p = pos + if *jump { 2 } else { 0 };
                    if !p.is_multiple_of(4) {
                        p += 2;
                    }
                    island_at.insert(*id, p);
                    p + 4 * islands[*id].len() - pos
                }
            };
        }
        addrs.push(a);
        if !pos.is_multiple_of(4) {
            pos += 2;
        }
    }
    (addrs, labels, island_at)
}
