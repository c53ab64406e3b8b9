//! One code buffer for every piece of Thumb code Tactus emits — the backend's functions
//! ([`super::emit`]) and the firmware image's glue (reset handlers, sample interrupts, the
//! boot stub) — in the way cranelift has one `MachBuffer`: instructions, labels, branches to
//! labels with range checks and relaxation, `BL` calls to labels or to absolute addresses,
//! literal pools (placed explicitly or as islands when a load would fall out of reach),
//! alignment, data words, and a GNU assembler listing of exactly the bytes it encodes.
//!
//! Code is assembled at a known base address ([`CodeBuffer::finish`]): the backend's
//! relocatable `.text` at 0, the image's glue where the image places it. Every size is
//! known before encoding, so layout is a fixed point over the branch forms (short until out
//! of range) and encoding is one pass with [`tactus_isa::encode::encode`] — the ISA's
//! bit layouts stay in the emulator crate.
//!
//! **Relocations.** The backend's code is position independent (PC-relative branches and
//! literal loads only), so its ELF object carries none. A `BL` to an absolute address
//! ([`CodeBuffer::bl_addr`], the glue's calls into a key's update) is the one relocation
//! kind (`R_ARM_THM_CALL`, ARM ELF ABI IHI 0044 §5.6); the buffer resolves it when it is
//! assembled at its base and checks its ±4 MiB range.
//!
//! Ranges (ARMv7-M/ARMv6-M ARM, A6.7): `B<cond>` −256…+254 bytes, `B` −2048…+2046, `BL`
//! ±4 MiB, `LDR Rt, [PC, #imm]` 0…1020 bytes forward of `Align(PC, 4)`. Out-of-range code
//! is relaxed or refused with a [`BufferError`] naming what failed — never encoded wrong.

use std::collections::HashMap;
use std::fmt::{self, Write as _};
use tactus_isa::decode::Instr;
use tactus_isa::encode::{enc_imm8, encode, Encoding};

/// A label: an index into the buffer's label table ([`Assembled::labels`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Label(usize);

impl Label {
    /// Its index into [`Assembled::labels`].
    pub fn index(self) -> usize {
        self.0
    }
}

/// What a conditional or unconditional branch whose label is out of its range becomes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LongBranch {
    /// `BL label` (±4 MiB), behind `B<!cond> .+6` for a conditional branch. `BL` writes LR,
    /// so this is only for code that has saved LR: an AAPCS function body that returns
    /// with `POP {…, PC}`, as the backend's functions do.
    Bl,
    /// A conditional branch out of its ±256 bytes becomes `B<!cond> .+4; B label` (±2 KiB,
    /// one cycle more when it is not taken, ARMv6-M A6.7.10); an unconditional one out of
    /// its ±2 KiB is a [`BufferError::BranchRange`]. LR is not written: for code where LR is
    /// live or is not saved, such as an exception handler's glue.
    Hop,
    /// A [`BufferError::BranchRange`]: code where LR is live, such as an exception
    /// handler (its LR holds the EXC_RETURN value).
    Refuse,
}

/// Why a buffer could not be assembled. Each is a bug of the code's generator or code too
/// large for a short form; the message names the item.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BufferError {
    /// A label referenced but never bound.
    Unbound(usize),
    /// A branch out of range where [`LongBranch::Refuse`] forbids the long form.
    BranchRange {
        /// The branch's address.
        at: u32,
        /// Its label's address.
        target: u32,
    },
    /// A `BL` farther than ±4 MiB.
    CallRange {
        /// The `BL`'s address.
        at: u32,
        /// The callee's address.
        target: u32,
    },
    /// A literal load whose pool entry is behind it or more than 1,020 bytes ahead.
    LiteralRange {
        /// The load's address.
        at: u32,
        /// Its pool entry's address.
        literal: u32,
    },
    /// Literals loaded but no pool placed after them.
    UnplacedPool,
    /// An instruction with a field out of range for its encoding.
    Encoding(String),
    /// An odd base address (Thumb code is halfword aligned).
    OddBase(u32),
}

impl fmt::Display for BufferError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BufferError::Unbound(l) => write!(f, "label {l} is never bound"),
            BufferError::BranchRange { at, target } => write!(
                f,
                "the branch at {at:#x} cannot reach {target:#x} and may not be relaxed to BL (LR is live)"
            ),
            BufferError::CallRange { at, target } => {
                write!(f, "the BL at {at:#x} cannot reach {target:#x} (±4 MiB)")
            }
            BufferError::LiteralRange { at, literal } => write!(
                f,
                "literal at {literal:#x} out of reach of the load at {at:#x} (0–1020 bytes ahead)"
            ),
            BufferError::UnplacedPool => write!(f, "a literal pool was never placed"),
            BufferError::Encoding(e) => write!(f, "cannot encode: {e}"),
            BufferError::OddBase(b) => write!(f, "code base {b:#x} is not halfword aligned"),
        }
    }
}

impl std::error::Error for BufferError {}

/// The target of a `BL`.
#[derive(Clone, Copy, Debug)]
pub(super) enum Callee {
    Label(Label),
    /// An absolute address (the Thumb bit is ignored): resolved as `R_ARM_THM_CALL`.
    Addr(u32),
}

/// One entry of the buffer: an instruction, a label bound here, a branch or call to be
/// laid out, a literal load, a pool, data or a marker.
#[derive(Clone, Debug)]
pub(super) enum Item {
    Instr(Instr),
    Bind(Label),
    /// `B`/`B<cond>` to a label; relaxed per [`LongBranch`].
    Branch(Option<u8>, Label),
    Call(Callee),
    /// `LDR rt, [PC, #imm]` of entry `index` of pool `pool`.
    Lit {
        rt: u8,
        pool: usize,
        index: usize,
    },
    /// Pad to a word boundary with [`PAD`].
    Align4,
    /// A data word.
    Word(u32),
    /// Pool `id`'s literals, word aligned, behind a `B` over them when `jump`.
    Pool {
        id: usize,
        jump: bool,
    },
    /// A comment for the listing, recorded at its offset.
    Note(String),
    /// A named offset ([`Assembled::marks`]).
    Mark(u32),
    /// A function's symbol starts here.
    FuncStart(String),
    /// The open function's symbol ends here; then pad to a word boundary.
    FuncEnd,
}

/// Distance (bytes) after the first pending literal at which the buffer places an island
/// (a `B` over the pool): the `LDR` literal reach is 1020 bytes, sizes are estimated with
/// every branch long, so relaxation never lengthens a distance past the estimate.
const ISLAND_AFTER: usize = 800;

/// Alignment padding: `MOV r8, r8` (0x46c0), the no-op GNU as pads Thumb code with for
/// ARMv6-M, so that the listing assembles to the same bytes.
const PAD: Instr = Instr::MovHi { rd: 8, rm: 8 };

const CONDS: [&str; 14] = [
    "eq", "ne", "cs", "cc", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le",
];

/// Code being emitted. Push instructions, bind labels, load constants; then
/// [`CodeBuffer::finish`] at a base address.
#[derive(Clone, Debug)]
pub struct CodeBuffer {
    items: Vec<Item>,
    labels: usize,
    /// Literal pools; the last is open (collecting), earlier ones are placed.
    pools: Vec<Vec<u32>>,
    /// Estimated size so far (branches long) and where the open pool's first load is.
    est: usize,
    pending_since: Option<usize>,
    long: LongBranch,
}

impl CodeBuffer {
    /// An empty buffer whose out-of-range branches become `long`.
    pub fn new(long: LongBranch) -> Self {
        CodeBuffer {
            items: Vec::new(),
            labels: 0,
            pools: vec![Vec::new()],
            est: 0,
            pending_since: None,
            long,
        }
    }

    fn push(&mut self, it: Item) {
        self.est += est_size(&it, &self.pools);
        self.items.push(it);
        if let Some(p0) = self.pending_since {
            let open = self.pools.last().map_or(0, Vec::len);
            if self.est - p0 + 4 * open + 8 > ISLAND_AFTER {
                self.place_pool(true);
            }
        }
    }

    /// A fresh, unbound label.
    pub fn label(&mut self) -> Label {
        self.labels += 1;
        Label(self.labels - 1)
    }

    /// Binds `l` here (a join point).
    pub fn bind(&mut self, l: Label) {
        self.push(Item::Bind(l));
    }

    /// Any instruction (its own branches are not checked: use [`CodeBuffer::b`] and
    /// [`CodeBuffer::bc`] for branches to labels).
    pub fn i(&mut self, i: Instr) {
        self.push(Item::Instr(i));
    }

    /// `B label`.
    pub fn b(&mut self, l: Label) {
        self.push(Item::Branch(None, l));
    }

    /// `B<cond> label` (`cond` 0–13, ARMv6-M A6.3; see [`super::ins::cond`]).
    pub fn bc(&mut self, cond: u8, l: Label) {
        self.push(Item::Branch(Some(cond), l));
    }

    /// `BL addr` to an absolute address (a relocation resolved at [`CodeBuffer::finish`]).
    pub fn bl_addr(&mut self, addr: u32) {
        self.push(Item::Call(Callee::Addr(addr)));
    }

    /// `BL label`.
    pub fn bl(&mut self, l: Label) {
        self.push(Item::Call(Callee::Label(l)));
    }

    /// `LDR rt, =value`: the value joins the open pool (shared with equal values), placed
    /// by the next [`CodeBuffer::pool`], [`CodeBuffer::pool_inline`] or
    /// [`CodeBuffer::end_function`], or by an island when the load would fall out of reach.
    pub fn ldr_const(&mut self, rt: u8, value: u32) {
        let pool = self.pools.len() - 1;
        let open = &mut self.pools[pool];
        let index = open.iter().position(|&v| v == value).unwrap_or_else(|| {
            open.push(value);
            open.len() - 1
        });
        self.pending_since.get_or_insert(self.est);
        self.push(Item::Lit { rt, pool, index });
    }

    /// `rd = value`: `MOVS` when it fits 8 bits, else a literal load (which, unlike `MOVS`,
    /// leaves the flags alone).
    pub fn mov_const(&mut self, rd: u8, value: u32) {
        if value < 256 {
            self.i(Instr::MovImm {
                rd,
                imm: value as u8,
            });
        } else {
            self.ldr_const(rd, value);
        }
    }

    fn place_pool(&mut self, jump: bool) {
        let id = self.pools.len() - 1;
        if !self.pools[id].is_empty() {
            self.pools.push(Vec::new());
            self.pending_since = None;
            self.push(Item::Pool { id, jump });
        }
    }

    /// Places the open pool here (word aligned). The caller makes sure control never
    /// falls into it (after a return or an unconditional branch).
    pub fn pool(&mut self) {
        self.place_pool(false);
    }

    /// After an unconditional branch: places the open pool here (control never falls into
    /// it) when its first literal lies a quarter of an island's distance back or more, so
    /// that fewer islands need a `B` over them (2 cycles each on the path through them).
    pub fn pool_after_branch(&mut self) {
        if self
            .pending_since
            .is_some_and(|p0| self.est - p0 >= ISLAND_AFTER / 4)
        {
            self.place_pool(false);
        }
    }

    /// Places the open pool here behind a `B` over it.
    pub fn pool_inline(&mut self) {
        self.place_pool(true);
    }

    /// How many items the buffer holds: where the next function's code starts, for a pass
    /// over it ([`CodeBuffer::items_from`]).
    pub(super) fn len(&self) -> usize {
        self.items.len()
    }

    /// The items from `start` on (a pass over one function's code may rewrite them, never
    /// a pool, a label or a mark) and the literal pools their loads index.
    pub(super) fn items_from(&mut self, start: usize) -> (&mut [Item], &[Vec<u32>]) {
        (&mut self.items[start..], &self.pools)
    }

    /// Drops item `start + k` for each `dead[k]` (a function's deleted instructions; the
    /// code only shrinks, so every branch and literal load stays in reach).
    pub(super) fn drop_from(&mut self, start: usize, dead: &[bool]) {
        let mut k = 0;
        self.items.retain(|_| {
            k += 1;
            k <= start || !dead.get(k - 1 - start).copied().unwrap_or(false)
        });
    }

    /// Aligns to 4 bytes (with a no-op).
    pub fn align4(&mut self) {
        self.push(Item::Align4);
    }

    /// A data word (aligned first).
    pub fn word(&mut self, w: u32) {
        self.push(Item::Align4);
        self.push(Item::Word(w));
    }

    /// A comment for the listing, recorded with its offset ([`Assembled::notes`]).
    pub fn note(&mut self, s: impl Into<String>) {
        self.push(Item::Note(s.into()));
    }

    /// Records this offset under `key` ([`Assembled::marks`]).
    pub fn mark(&mut self, key: u32) {
        self.push(Item::Mark(key));
    }

    /// Starts function `name` (a global symbol, `%function`).
    pub fn begin_function(&mut self, name: &str) {
        self.push(Item::FuncStart(name.to_string()));
    }

    /// Ends the open function: its pending literals become a pool after its last
    /// instruction (which must not fall through), and the next code starts on a word
    /// boundary, as the assembler's `.p2align 2` would place it.
    pub fn end_function(&mut self) {
        self.place_pool(false);
        self.push(Item::FuncEnd);
    }

    /// Addresses of every item, every label and every pool for the given branch forms.
    fn layout(&self, base: u32, long: &[bool]) -> Layout {
        let mut at = Vec::with_capacity(self.items.len());
        let mut labels = vec![None; self.labels];
        let mut pools = vec![0u32; self.pools.len()];
        let mut pos = base;
        for (k, it) in self.items.iter().enumerate() {
            at.push(pos);
            pos += match it {
                Item::Instr(i) => size(i),
                Item::Lit { .. } => 2,
                Item::Branch(c, _) => match (long[k], c) {
                    (false, _) => 2,
                    (true, None) => 4,
                    (true, Some(_)) if self.long == LongBranch::Hop => 4,
                    (true, Some(_)) => 6,
                },
                Item::Call(_) => 4,
                Item::Bind(l) => {
                    labels[l.0] = Some(pos);
                    0
                }
                Item::Note(_) | Item::Mark(_) | Item::FuncStart(_) => 0,
                Item::Align4 | Item::FuncEnd => pos.next_multiple_of(4) - pos,
                Item::Word(_) => 4,
                Item::Pool { id, jump } => {
                    let data = (pos + if *jump { 2 } else { 0 }).next_multiple_of(4);
                    pools[*id] = data;
                    data + 4 * self.pools[*id].len() as u32 - pos
                }
            };
        }
        Layout { at, labels, pools }
    }

    /// Assembles the buffer at `base` (even): lays it out, relaxes out-of-range branches
    /// (per [`LongBranch`]), and encodes it with its listing.
    ///
    /// Errors: see [`BufferError`].
    pub fn finish(&self, base: u32) -> Result<Assembled, BufferError> {
        self.assemble(base, true)
    }

    /// [`CodeBuffer::finish`] without the listing ([`Assembled::listing`] empty): the same
    /// bytes, labels, symbols, data, notes and marks, for code nobody reads as text (a
    /// firmware image's glue, assembled once per image the keyboard's plan tries; its
    /// listing was a fifth of the plan's instructions).
    ///
    /// Errors: see [`BufferError`].
    pub fn finish_code(&self, base: u32) -> Result<Assembled, BufferError> {
        self.assemble(base, false)
    }

    /// [`CodeBuffer::finish`], with the listing or not.
    fn assemble(&self, base: u32, listing: bool) -> Result<Assembled, BufferError> {
        if !base.is_multiple_of(2) {
            return Err(BufferError::OddBase(base));
        }
        if self.pools.last().is_some_and(|p| !p.is_empty()) {
            return Err(BufferError::UnplacedPool);
        }
        // Branch relaxation: short until out of range; a long branch never gets short
        // again, so this terminates after at most one round per branch.
        let mut long = vec![false; self.items.len()];
        let lay = loop {
            let lay = self.layout(base, &long);
            let mut changed = false;
            for (k, it) in self.items.iter().enumerate() {
                if let Item::Branch(c, l) = it {
                    if long[k] {
                        continue;
                    }
                    let target = lay.label(*l)?;
                    let off = target as i64 - (lay.at[k] as i64 + 4);
                    let ok = match c {
                        Some(_) => (-256..=254).contains(&off),
                        None => (-2048..=2046).contains(&off),
                    };
                    if !ok {
                        let refused = match self.long {
                            LongBranch::Refuse => true,
                            LongBranch::Hop => c.is_none(),
                            LongBranch::Bl => false,
                        };
                        if refused {
                            return Err(BufferError::BranchRange {
                                at: lay.at[k],
                                target,
                            });
                        }
                        long[k] = true;
                        changed = true;
                    }
                }
            }
            if !changed {
                break lay;
            }
        };
        self.encode(base, &lay, &long, listing)
    }

    fn encode(
        &self,
        base: u32,
        lay: &Layout,
        long: &[bool],
        listing: bool,
    ) -> Result<Assembled, BufferError> {
        let mut out = Assembled {
            text: Vec::new(),
            labels: lay.labels.iter().map(|a| a.unwrap_or(u32::MAX)).collect(),
            symbols: Vec::new(),
            data: Vec::new(),
            listing: String::new(),
            notes: Vec::new(),
            marks: HashMap::new(),
        };
        let mut text = Listing {
            on: listing,
            text: String::new(),
        };
        let _ = text.write_str(
            "    .syntax unified\n    .cpu cortex-m0plus\n    .thumb\n    .text\n    .p2align 2\n",
        );
        let mut func: Option<(String, usize)> = None;
        let text_len = |out: &Assembled| out.text.len();
        for (k, it) in self.items.iter().enumerate() {
            let pc = base + out.text.len() as u32;
            debug_assert_eq!(pc, lay.at[k]);
            let listing = &mut text;
            match it {
                Item::Instr(i) => {
                    put(&mut out.text, enc(i)?);
                    let _ = writeln!(listing, "    {i}");
                }
                Item::Bind(l) => {
                    let _ = writeln!(listing, ".L{}:", l.0);
                }
                Item::Branch(c, l) => {
                    let dest = lay.label(*l)?;
                    let cname = |c: u8| CONDS[c as usize];
                    if !long[k] {
                        let offset = dest as i32 - (pc as i32 + 4);
                        let i = match c {
                            Some(cond) => Instr::BCond {
                                cond: *cond,
                                offset,
                            },
                            None => Instr::B { offset },
                        };
                        put(&mut out.text, enc(&i)?);
                        let _ = writeln!(listing, "    b{} .L{}", c.map_or("", cname), l.0);
                    } else if let (LongBranch::Hop, Some(c)) = (self.long, c) {
                        // B<!c> over a B to the label.
                        let inv = c ^ 1;
                        put(
                            &mut out.text,
                            enc(&Instr::BCond {
                                cond: inv,
                                offset: 0,
                            })?,
                        );
                        let offset = dest as i32 - (pc as i32 + 2 + 4);
                        put(&mut out.text, enc(&Instr::B { offset })?);
                        let _ = writeln!(listing, "    b{} .+4", cname(inv));
                        let _ = writeln!(listing, "    b .L{}", l.0);
                    } else {
                        let mut at = pc;
                        if let Some(c) = c {
                            // B<!c> over the 4-byte BL.
                            let inv = c ^ 1;
                            put(
                                &mut out.text,
                                enc(&Instr::BCond {
                                    cond: inv,
                                    offset: 2,
                                })?,
                            );
                            let _ = writeln!(listing, "    b{} .+6", cname(inv));
                            at += 2;
                        }
                        put(&mut out.text, call(at, dest)?);
                        let _ = writeln!(listing, "    bl .L{}", l.0);
                    }
                }
                Item::Call(c) => {
                    let dest = match *c {
                        Callee::Label(l) => lay.label(l)?,
                        Callee::Addr(a) => a & !1,
                    };
                    put(&mut out.text, call(pc, dest)?);
                    let _ = match *c {
                        Callee::Label(l) => writeln!(listing, "    bl .L{}", l.0),
                        Callee::Addr(_) => writeln!(listing, "    bl {dest:#x}"),
                    };
                }
                Item::Lit { rt, pool, index } => {
                    let literal = lay.pools[*pool] + 4 * *index as u32;
                    let from = (pc + 4) & !3;
                    let imm = literal
                        .checked_sub(from)
                        .filter(|d| *d <= 1020)
                        .ok_or(BufferError::LiteralRange { at: pc, literal })?;
                    put(
                        &mut out.text,
                        enc(&Instr::LdrLit {
                            rt: *rt,
                            imm: imm as u16,
                        })?,
                    );
                    let _ = writeln!(listing, "    ldr r{rt}, .Lpool{pool}_{index}");
                }
                Item::Align4 => pad(&mut out, listing, base)?,
                Item::Word(w) => {
                    out.text.extend(w.to_le_bytes());
                    let _ = writeln!(listing, "    .word {:#x}", w);
                }
                Item::Pool { id, jump } => {
                    let words = &self.pools[*id];
                    if *jump {
                        let end = lay.pools[*id] + 4 * words.len() as u32;
                        put(
                            &mut out.text,
                            enc(&Instr::B {
                                offset: end as i32 - (pc as i32 + 4),
                            })?,
                        );
                        let _ = writeln!(listing, "    b .Lisland{id}_end");
                    }
                    pad(&mut out, listing, base)?;
                    debug_assert_eq!(base + text_len(&out) as u32, lay.pools[*id]);
                    out.data.push((text_len(&out), 4 * words.len()));
                    for (n, w) in words.iter().enumerate() {
                        out.text.extend(w.to_le_bytes());
                        let _ = writeln!(listing, ".Lpool{id}_{n}:\n    .word {}", *w as i32);
                    }
                    if *jump {
                        let _ = writeln!(listing, ".Lisland{id}_end:");
                    }
                }
                Item::Note(s) => {
                    out.notes.push((out.text.len(), s.clone()));
                    let _ = writeln!(listing, "    @ {s}");
                }
                Item::Mark(key) => {
                    out.marks.insert(*key, out.text.len());
                }
                Item::FuncStart(name) => {
                    let _ = write!(
                        listing,
                        "\n    .global {name}\n    .type {name}, %function\n    .thumb_func\n    .p2align 1\n{name}:\n"
                    );
                    func = Some((name.clone(), out.text.len()));
                }
                Item::FuncEnd => {
                    if let Some((name, start)) = func.take() {
                        let _ = writeln!(listing, "    .size {name}, .-{name}");
                        out.symbols.push((name, start, out.text.len() - start));
                    }
                    pad(&mut out, listing, base)?;
                }
            }
        }
        if text.on {
            out.listing = text.text;
        }
        Ok(out)
    }
}

/// The listing [`CodeBuffer::encode`] writes, or nothing ([`CodeBuffer::finish_code`]): off,
/// a write formats nothing.
struct Listing {
    on: bool,
    text: String,
}

impl fmt::Write for Listing {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        if self.on {
            self.text.push_str(s);
        }
        Ok(())
    }

    fn write_fmt(&mut self, args: fmt::Arguments<'_>) -> fmt::Result {
        match self.on {
            true => self.text.write_fmt(args),
            false => Ok(()),
        }
    }
}

/// Encodes `i`. `ADDS Rdn, Rdn, #imm` with imm < 8 has two 16-bit encodings; GNU as picks
/// T2 (imm8), so the listing assembles to the same bytes only if we do too.
fn enc(i: &Instr) -> Result<Encoding, BufferError> {
    match *i {
        Instr::AddImm { rd, rn, imm } | Instr::SubImm { rd, rn, imm } if rd == rn && rd < 8 => {
            let op = if matches!(i, Instr::SubImm { .. }) {
                3
            } else {
                2
            };
            Ok(Encoding::Half(enc_imm8(op, rd as u16, imm as u16)))
        }
        _ => encode(i).map_err(|e| BufferError::Encoding(format!("{i:?}: {e}"))),
    }
}

/// Appends `e`'s little-endian bytes, as they sit in memory, to `text` (no allocation:
/// the glue of every image a keyboard's plan tries is assembled, a million instructions
/// for the demo).
fn put(text: &mut Vec<u8>, e: Encoding) {
    match e {
        Encoding::Half(h) => text.extend(h.to_le_bytes()),
        Encoding::Word(a, b) => {
            text.extend(a.to_le_bytes());
            text.extend(b.to_le_bytes());
        }
    }
}

/// Size in bytes of `i` (2 when it does not encode; [`enc`] reports that).
fn size(i: &Instr) -> u32 {
    match encode(i) {
        Ok(Encoding::Word(..)) => 4,
        _ => 2,
    }
}

/// The `BL` at `at` to `target`, range checked.
fn call(at: u32, target: u32) -> Result<Encoding, BufferError> {
    let offset = target as i64 - (at as i64 + 4);
    if !(-(1 << 22)..(1 << 22)).contains(&offset) {
        return Err(BufferError::CallRange { at, target });
    }
    enc(&Instr::Bl {
        offset: offset as i32,
    })
}

/// Pads `out` to a word boundary (absolute, from `base`).
fn pad(out: &mut Assembled, listing: &mut Listing, base: u32) -> Result<(), BufferError> {
    if !(base as usize + out.text.len()).is_multiple_of(4) {
        put(&mut out.text, enc(&PAD)?);
        let _ = listing.write_str("    mov r8, r8\n");
    }
    Ok(())
}

/// Upper bound of an item's size, for placing islands (branches long, padding 2).
fn est_size(it: &Item, pools: &[Vec<u32>]) -> usize {
    match it {
        Item::Instr(i) => size(i) as usize,
        Item::Lit { .. } => 2,
        Item::Branch(..) => 6,
        Item::Call(_) => 4,
        Item::Align4 | Item::FuncEnd => 2,
        Item::Word(_) => 4,
        Item::Pool { id, .. } => 4 * pools[*id].len() + 4,
        Item::Bind(_) | Item::Note(_) | Item::Mark(_) | Item::FuncStart(_) => 0,
    }
}

struct Layout {
    /// Address of every item.
    at: Vec<u32>,
    labels: Vec<Option<u32>>,
    /// Address of every pool's first word.
    pools: Vec<u32>,
}

impl Layout {
    fn label(&self, l: Label) -> Result<u32, BufferError> {
        self.labels[l.0].ok_or(BufferError::Unbound(l.0))
    }
}

/// An assembled buffer.
#[derive(Clone, Debug, Default)]
pub struct Assembled {
    /// The bytes, starting at the base address.
    pub text: Vec<u8>,
    /// Each label's absolute address (`u32::MAX` for a label never bound nor referenced).
    pub labels: Vec<u32>,
    /// Functions: name, offset from the base, size in bytes.
    pub symbols: Vec<(String, usize, usize)>,
    /// Literal data inside the text (offset, length), for `$d` mapping symbols.
    pub data: Vec<(usize, usize)>,
    /// GNU-syntax assembly that `arm-none-eabi-as` assembles to `text` (at base 0).
    pub listing: String,
    /// Comments at offsets.
    pub notes: Vec<(usize, String)>,
    /// Offsets recorded by [`CodeBuffer::mark`].
    pub marks: HashMap<u32, usize>,
}

#[cfg(test)]
mod tests {
    use super::super::ins::{cond, movs};
    use super::*;
    use tactus_isa::decode::decode;

    fn dec(bytes: &[u8], off: usize) -> Instr {
        let h = |o: usize| u16::from_le_bytes([bytes[o], bytes[o + 1]]);
        decode(h(off), if off + 3 < bytes.len() { h(off + 2) } else { 0 })
    }

    #[test]
    fn branches_literals_and_pools_land_where_they_should() {
        let mut a = CodeBuffer::new(LongBranch::Refuse);
        let top = a.label();
        a.bind(top);
        a.ldr_const(0, 0x1234_5678);
        a.ldr_const(1, 0x1234_5678); // shared entry
        a.bc(cond::NE, top);
        a.bl_addr(0x2000_0100);
        a.pool_inline();
        a.i(movs(2, 7));
        a.b(top);
        let out = a.finish(0x2000_0002).unwrap();
        let bytes = &out.text;
        assert_eq!(out.labels[0], 0x2000_0002);
        // ldr 0x..02, ldr 0x..04, bne 0x..06, bl 0x..08, b over 0x..0c, padding at 0x..0e,
        // the pool's one (shared) literal at 0x..10: absolute alignment, whatever the base.
        assert_eq!(&bytes[0x0c..0x0e], &enc(&PAD).unwrap().bytes()[..]);
        assert_eq!(&bytes[0x0e..0x12], &0x1234_5678u32.to_le_bytes());
        assert_eq!(bytes.len(), 0x16);
        match dec(bytes, 0) {
            Instr::LdrLit { rt: 0, imm } => {
                let lit = ((0x2000_0002u32 + 4) & !3) + imm as u32;
                let off = (lit - 0x2000_0002) as usize;
                assert_eq!(&bytes[off..off + 4], &0x1234_5678u32.to_le_bytes());
            }
            other => panic!("{other:?}"),
        }
        let Instr::LdrLit { imm, .. } = dec(bytes, 0) else {
            unreachable!()
        };
        assert_eq!(
            dec(bytes, 2),
            Instr::LdrLit {
                rt: 1,
                imm: imm - 4
            }
        );
        // bne top: at 0x..06, target 0x..02: offset = 2 - 10 = -8.
        assert_eq!(
            dec(bytes, 4),
            Instr::BCond {
                cond: cond::NE,
                offset: -8
            }
        );
        // bl at 0x..08 to 0x..100: offset 0x100 - 0x0c.
        assert_eq!(
            dec(bytes, 6),
            Instr::Bl {
                offset: 0x100 - 0x0c
            }
        );
        assert_eq!(out.data, vec![(0x0e, 4)]);
    }

    #[test]
    fn unplaced_pools_unbound_labels_and_far_calls_are_errors() {
        let mut a = CodeBuffer::new(LongBranch::Refuse);
        a.ldr_const(0, 5);
        assert_eq!(a.finish(0).unwrap_err(), BufferError::UnplacedPool);
        a.pool_inline();
        assert!(a.finish(0).is_ok());
        let mut a = CodeBuffer::new(LongBranch::Refuse);
        let l = a.label();
        a.b(l);
        assert_eq!(a.finish(0).unwrap_err(), BufferError::Unbound(0));
        let mut a = CodeBuffer::new(LongBranch::Refuse);
        a.bl_addr(0x1000_0000);
        assert!(matches!(
            a.finish(0x2000_0000).unwrap_err(),
            BufferError::CallRange { .. }
        ));
        assert_eq!(
            a.finish(1).unwrap_err(),
            BufferError::OddBase(1),
            "Thumb code is halfword aligned"
        );
    }

    #[test]
    fn far_literals_get_an_island_and_stay_in_reach() {
        let mut a = CodeBuffer::new(LongBranch::Refuse);
        a.ldr_const(0, 5);
        for _ in 0..600 {
            a.i(movs(1, 1));
        }
        a.pool();
        let out = a.finish(0).unwrap();
        // The island (B over, the word) came before 800 bytes; the final pool is empty.
        assert_eq!(out.data.len(), 1);
        let (at, len) = out.data[0];
        assert!(at <= 800 && len == 4, "{at} {len}");
        let Instr::LdrLit { imm, .. } = dec(&out.text, 0) else {
            panic!()
        };
        assert_eq!(4 + imm as usize, at);
        assert_eq!(&out.text[at..at + 4], &5u32.to_le_bytes());
        // Control jumps over the island: `B` (then perhaps the padding) right before it,
        // landing right after its word.
        let b = if dec(&out.text, at - 2) == PAD {
            at - 4
        } else {
            at - 2
        };
        assert_eq!(
            dec(&out.text, b),
            Instr::B {
                offset: (at + 4) as i32 - (b as i32 + 4)
            }
        );
    }

    #[test]
    fn out_of_range_branches_are_relaxed_to_bl_or_refused() {
        let build = |long| {
            let mut a = CodeBuffer::new(long);
            a.begin_function("f");
            let far = a.label();
            a.bc(cond::EQ, far);
            for _ in 0..200 {
                a.i(movs(1, 1));
            }
            a.bind(far);
            a.i(movs(2, 2));
            a.end_function();
            a.finish(0)
        };
        assert!(matches!(
            build(LongBranch::Refuse).unwrap_err(),
            BufferError::BranchRange { at: 0, .. }
        ));
        let out = build(LongBranch::Bl).unwrap();
        // BNE .+6 ; BL far.
        assert_eq!(
            dec(&out.text, 0),
            Instr::BCond {
                cond: cond::NE,
                offset: 2
            }
        );
        let Instr::Bl { offset } = dec(&out.text, 2) else {
            panic!("{:?}", dec(&out.text, 2))
        };
        assert_eq!(6 + offset as usize, out.labels[0] as usize);
        assert_eq!(out.labels[0], 6 + 400);
        assert_eq!(out.symbols, vec![("f".to_string(), 0, 408)]);
        assert!(out.listing.contains("bne .+6\n    bl .L0\n"));
        // Hop: BNE .+4 ; B far (LR untouched).
        let out = build(LongBranch::Hop).unwrap();
        assert_eq!(
            dec(&out.text, 0),
            Instr::BCond {
                cond: cond::NE,
                offset: 0
            }
        );
        let Instr::B { offset } = dec(&out.text, 2) else {
            panic!("{:?}", dec(&out.text, 2))
        };
        assert_eq!(out.labels[0], 4 + 400);
        assert_eq!(6 + offset as usize, out.labels[0] as usize);
        assert!(out.listing.contains("bne .+4\n    b .L0\n"));
    }

    #[test]
    fn a_hop_refuses_an_unconditional_branch_beyond_2_kib() {
        let mut a = CodeBuffer::new(LongBranch::Hop);
        let far = a.label();
        a.b(far);
        for _ in 0..1100 {
            a.i(movs(1, 1));
        }
        a.bind(far);
        a.i(movs(2, 2));
        assert!(matches!(
            a.finish(0).unwrap_err(),
            BufferError::BranchRange { at: 0, .. }
        ));
    }
}
