//! Recording a call (module documentation of [`super`], "A memo"): what each instruction
//! reads and writes ([`usage`]), the call's inputs (registers and flags read before they
//! are written, SRAM bytes loaded before they are stored to) and its effect, kept as it runs
//! on the interpreter ([`Recording`]), with the registers it saves and restores ([`Save`])
//! and the loads through a base register it could move with ([`super::based`]).

use super::*;

/// Where a callee-saved register stands in a recording ([`Recording::saves`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Save {
    /// Not read yet: its entry value is in it.
    Entry,
    /// Pushed, before the call wrote it, to the SRAM word at this offset, which nothing
    /// has loaded or stored since.
    Pushed(u32),
    /// Popped back from that word: it holds its entry value again, and nothing has read
    /// or written it since.
    Restored(u32),
    /// Read or written otherwise: an input as any other register.
    Lost,
}

/// The [`Usage`] of `instr` (DDI0419 A6.7, as `exec.rs` executes it), `None` for an
/// instruction a memoized call may not contain: a layer over [`effects::effect`], the one
/// list of what an instruction reads and writes, that adds the control transfers a call
/// makes (which have no [`effects::Effect`]) and counts a flag an instruction writes only
/// sometimes (the carry of a shift by a register, left alone by a shift of 0) as read too.
pub(crate) fn usage(instr: &Instr) -> Option<Usage> {
    use Instr::*;
    let b = |r: u8| 1u16 << (r & 15);
    // PC is never an input or an output here: its value is the code's.
    let u = |reads: u16, writes: u16, flag_reads: u8, flag_writes: u8| {
        Some(Usage {
            reads: reads & 0x7fff,
            writes: writes & 0x7fff,
            flag_reads,
            flag_writes,
        })
    };
    match *instr {
        B { .. } | Hint(decode::Hint::Nop | decode::Hint::Yield) => u(0, 0, 0, 0),
        // What a memo cannot hold: special registers, traps, other hints, barriers.
        Cps { .. }
        | Bkpt { .. }
        | Hint(_)
        | Svc { .. }
        | Udf { .. }
        | Msr { .. }
        | Mrs { .. }
        | Barrier(_)
        | Undefined { .. } => None,
        BCond { cond, .. } => u(0, 0, effects::cond_reads(cond), 0),
        Bl { .. } => u(0, b(14), 0, 0),
        Bx { rm } => u(b(rm), 0, 0, 0),
        Blx { rm } => u(b(rm), b(14), 0, 0),
        AddHi { rdn: 15, rm } | MovHi { rd: 15, rm } => u(b(rm), 0, 0, 0),
        Pop { list } if list & 1 << 15 != 0 => u(b(13), b(13) | (list & 0xff), 0, 0),
        _ => {
            let e = effects::effect(instr)?;
            let sometimes = match *instr {
                Alu {
                    op: AluOp::Lsl | AluOp::Lsr | AluOp::Asr | AluOp::Ror,
                    ..
                } => C,
                _ => 0,
            };
            u(
                e.reads,
                e.writes,
                e.flags_read | sometimes,
                e.flags_set | sometimes,
            )
        }
    }
}

/// Whether every data address `instr` at `pc` would load or store, on `core`'s registers
/// now, is in SRAM (so none reaches the private peripheral bus, which `Core` answers
/// without the bus that logs the recording).
pub(super) fn data_in_sram(instr: &Instr, core: &Core, pc: u32) -> bool {
    use Instr::*;
    let r = |x: u8| core.r[(x & 15) as usize];
    let (addr, len) = match *instr {
        LdrLit { imm, .. } => (literal_address(pc, imm), 4),
        MemReg { op, rn, rm, .. } => (r(rn).wrapping_add(r(rm)), op.size()),
        MemImm { op, rn, imm, .. } => (r(rn).wrapping_add(imm as u32), op.size()),
        Push { list } => {
            let n = 4 * list.count_ones();
            (r(13).wrapping_sub(n), n)
        }
        Pop { list } => (r(13), 4 * list.count_ones()),
        Stm { rn, list } | Ldm { rn, list } => (r(rn), 4 * list.count_ones()),
        _ => return true,
    };
    let last = addr.wrapping_add(len.max(1) - 1);
    last >= addr && sram_location(addr).is_some() && sram_location(last).is_some()
}

/// One SRAM access of a recording: byte offset into [`System::sram`], size, the value
/// loaded (loads), and whether its page held decoded code (loads: then it is not an input
/// to compare, see the module documentation).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Access {
    pub(super) off: u32,
    pub(super) size: u8,
    pub(super) store: bool,
    pub(super) code: bool,
    pub(super) value: u32,
}

/// Bytes of one SRAM word: its offset in [`System::sram`] (aligned), which bytes (a mask)
/// and their values (the other bits 0).
#[derive(Clone, Copy, Debug)]
pub(super) struct Word {
    pub(super) off: u32,
    pub(super) mask: u32,
    pub(super) value: u32,
}

/// The [`Word`]s of `bytes` (offsets ascending) with their values.
pub(super) fn words(bytes: impl Iterator<Item = (u32, u8)>) -> Vec<Word> {
    let mut v: Vec<Word> = Vec::new();
    for (b, x) in bytes {
        let (off, shift) = (b & !3, 8 * (b & 3));
        match v.last_mut() {
            Some(w) if w.off == off => {}
            _ => v.push(Word {
                off,
                mask: 0,
                value: 0,
            }),
        }
        if let Some(w) = v.last_mut() {
            w.mask |= 0xff << shift;
            w.value |= (x as u32) << shift;
        }
    }
    v
}

/// The word at byte `off` of `sram`.
///
/// # Safety
/// `off + 4 <= sram.len()`.
#[inline(always)]
pub(super) unsafe fn peek(sram: &[u8], off: u32) -> u32 {
    // SAFETY: the caller's bound.
    unsafe { std::ptr::read_unaligned(sram.as_ptr().add(off as usize) as *const u32) }.to_le()
}

/// Stores `value` at byte `off` of `sram`.
///
/// # Safety
/// `off + 4 <= sram.len()`.
#[inline(always)]
pub(super) unsafe fn poke(sram: &mut [u8], off: u32, value: u32) {
    // SAFETY: the caller's bound.
    unsafe {
        std::ptr::write_unaligned(
            sram.as_mut_ptr().add(off as usize) as *mut u32,
            value.to_le(),
        )
    }
}

/// Whether the words of `sram` hold the bytes `ws` give them. Four words at a time with no
/// branch per word (a memo's inputs are compared whole on a hit).
///
/// # Safety
/// Each word's `off + 4 <= sram.len()`.
#[inline(always)]
pub(super) unsafe fn holds(sram: &[u8], ws: &[Word]) -> bool {
    // SAFETY (of each `peek`): the caller's bound.
    let differ = |w: &Word| (unsafe { peek(sram, w.off) } & w.mask) ^ w.value;
    let (quads, rest) = ws.as_chunks::<4>();
    for q in quads {
        if differ(&q[0]) | differ(&q[1]) | differ(&q[2]) | differ(&q[3]) != 0 {
            return false;
        }
    }
    rest.iter().fold(0, |d, w| d | differ(w)) == 0
}

/// A memo's stored words as lists a hit runs down: those of all four bytes (most) as
/// their offsets and values, the others as [`Word`]s.
#[derive(Clone, Debug, Default)]
pub(super) struct Stores {
    pub(super) full: Box<[(u32, u32)]>,
    pub(super) part: Box<[Word]>,
}

impl Stores {
    pub(super) fn new(ws: &[Word]) -> Stores {
        let (full, part): (Vec<Word>, Vec<Word>) = ws.iter().partition(|w| w.mask == u32::MAX);
        Stores {
            full: full.iter().map(|w| (w.off, w.value)).collect(),
            part: part.into(),
        }
    }
}

/// The architectural state a recording starts from.
#[derive(Clone, Debug)]
pub(super) struct Entry {
    pub(super) r: [u32; 16],
    pub(super) flags: u8,
    pub(super) cycle: u64,
    pub(super) instructions: u64,
    pub(super) stalls: u64,
    pub(super) claims: [u64; BANKS],
    pub(super) epoch: u32,
    pub(super) special: (bool, u32, bool, u32, u32, bool),
}

pub(super) fn flags_of(core: &Core) -> u8 {
    [(core.n, N), (core.z, Z), (core.c, C), (core.v, V)]
        .iter()
        .fold(0, |f, &(on, bit)| if on { f | bit } else { f })
}

/// What a call may not change: Thumb bit, IPSR, PRIMASK, CONTROL, the other SP, the event
/// register.
pub(super) fn special_of(core: &Core) -> (bool, u32, bool, u32, u32, bool) {
    (
        core.thumb,
        core.ipsr,
        core.primask,
        core.control,
        core.other_sp,
        core.event,
    )
}

/// A call being recorded (see the module documentation): its entry, the registers and
/// flags it has read before writing them and those it has written, and its SRAM accesses.
pub(crate) struct Recording {
    pub(super) site: usize,
    /// Where the call ends: its return address, or the span's end.
    pub(super) end: u32,
    pub(super) entry: Entry,
    pub(super) live_regs: u16,
    pub(super) def_regs: u16,
    pub(super) live_flags: u8,
    pub(super) def_flags: u8,
    pub(super) fetch_banks: u8,
    pub(super) log: Vec<Access>,
    /// Something a memo cannot hold happened: the recording is given up.
    pub(super) spoiled: bool,
    /// In a window on a board with an I/O: the banks its DMA may reach (`L`), and the
    /// call's accesses to them, as the window's log holds them but for cycles from the
    /// entry (`accel/io_window/`).
    pub(crate) io_banks: u8,
    pub(super) io: Vec<IoAccess>,
    /// Registers that may be the call's base ([`BASES`] at the entry): read, before the
    /// call writes them, only as the base of an immediate-offset load.
    pub(super) bases: u16,
    /// The instruction being run loads through one of `bases`: that register and the
    /// address.
    pub(super) via: Option<(u8, u32)>,
    /// Whether its site's calls move ([`Site::moving`]): only then are candidate bases
    /// and saved registers tracked.
    pub(super) moving: bool,
    /// Of `log`, the loads through a candidate base: index, register, address.
    pub(super) log_via: Vec<(u32, u8, u32)>,
    /// Of `io`, those loaded through a candidate base: index, register, address.
    pub(super) io_via: Vec<(u32, u8, u32)>,
    /// r4-r7 ([`SAVES`]): each one's [`Save`].
    pub(super) saves: [Save; 4],
    /// The registers of [`SAVES`] the instruction being run pushes or pops (its own
    /// accesses to their words are not the others' that lose them).
    pub(super) saving: u16,
    /// Of [`SAVES`], those at their entry value or pushed (`kept`), restored, and lost:
    /// masks of `saves`, so that most instructions need not look at it.
    pub(super) kept: u16,
    pub(super) restored: u16,
    pub(super) lost: u16,
    /// The lowest and highest SRAM word any of them was pushed to (a load or store
    /// outside meets none).
    pub(super) slots: (u32, u32),
    /// The return address in LR ([`Recording::track_return`]): [`Save::Restored`] once
    /// the call has popped it into PC from the word it pushed it to (a function's call;
    /// a span's is [`Save::Lost`] from the start).
    pub(super) lr: Save,
    /// Whether the instruction being run is the `PUSH` or `POP` of LR's word.
    pub(super) lr_moving: bool,
}

impl Recording {
    /// Whether the call has returned (or the span ended): PC at its end, SP as at the
    /// entry.
    pub(crate) fn returned(&self, core: &Core) -> bool {
        core.r[15] == self.end && core.r[13] == self.entry.r[13]
    }

    /// Before `core` executes `instr` (`size` bytes at its PC) in the recorded call: false
    /// (the recording is given up, the instruction not run by it) when a memo cannot hold
    /// it; else notes its register and flag usage and the bank it is fetched from.
    pub(crate) fn admit(&mut self, core: &Core, instr: &Instr, size: u32) -> bool {
        let pc = core.r[15];
        let Some(u) = usage(instr) else {
            return false;
        };
        if !data_in_sram(instr, core, pc)
            || self.log.len() >= MAX_ACCESSES
            || core.instructions - self.entry.instructions >= MAX_INSTRUCTIONS
        {
            return false;
        }
        if self.moving {
            self.track_moving(core, instr, &u);
        }
        if self.lr != Save::Lost {
            self.track_return(core, instr, &u);
        }
        self.live_regs |= u.reads & !self.def_regs;
        self.def_regs |= u.writes;
        self.live_flags |= u.flag_reads & !self.def_flags;
        self.def_flags |= u.flag_writes;
        for a in [pc, pc.wrapping_add(size - 2)] {
            if let Some((off, _)) = sram_location(a) {
                self.fetch_banks |= 1 << sram_bank(off as u32);
            }
        }
        true
    }

    /// Before `core` runs `instr` (of usage `u`) in a recording of a site whose calls move
    /// (module documentation, "Based memos"): the candidate bases and the saved registers.
    pub(super) fn track_moving(&mut self, core: &Core, instr: &Instr, u: &Usage) {
        // A candidate base read otherwise than as an immediate-offset load's base, before
        // the call writes it, is no longer one; such a load through one is marked.
        self.via = None;
        let open = self.bases & !self.def_regs;
        let based = match *instr {
            _ if open == 0 => None,
            Instr::MemImm { op, rn, imm, .. } if !op.is_store() => {
                let bit = 1u16 << (rn & 15);
                (self.bases & bit & !self.def_regs != 0).then(|| {
                    let addr = core.r[(rn & 15) as usize].wrapping_add(u32::from(imm));
                    self.via = Some((rn & 15, addr));
                    bit
                })
            }
            _ => None,
        };
        self.bases &= !(u.reads & open & !based.unwrap_or(0));
        self.track_saves(core, instr, u);
    }

    /// Before `core` runs `instr` (of usage `u`): the [`Save`] of r4-r7 (a `PUSH` of one
    /// still at its entry value saves it; the `POP` of that word back into it restores
    /// it; any other read or write of its entry value, or of it restored, loses it).
    pub(super) fn track_saves(&mut self, core: &Core, instr: &Instr, u: &Usage) {
        self.saving = 0;
        // Only those a PUSH or POP may move, and those whose state a read or write may
        // lose: at their entry value or pushed but not written since, or restored.
        let mut regs = match instr {
            Instr::Push { .. } | Instr::Pop { .. } => !self.lost & 0xf0,
            _ => (u.reads | u.writes) & ((self.kept & !self.def_regs) | self.restored),
        };
        if regs == 0 {
            return;
        }
        let slot = |list: u16, r: u8, first: u32| {
            let k = (list & ((1u16 << r) - 1)).count_ones();
            sram_location(first.wrapping_add(4 * k)).map(|(off, _)| off as u32)
        };
        while regs != 0 {
            let r = regs.trailing_zeros() as u8;
            regs &= regs - 1;
            let bit = 1u16 << r;
            let i = (r - 4) as usize;
            if self.saves[i] == Save::Lost {
                continue;
            }
            let read = u.reads & bit != 0;
            let written = u.writes & bit != 0;
            let now = match (self.saves[i], *instr) {
                (Save::Entry, Instr::Push { list })
                    if list & bit != 0 && self.def_regs & bit == 0 =>
                {
                    self.saving |= bit;
                    let n = (list & 0x40ff).count_ones();
                    let first = core.r[13].wrapping_sub(4 * n);
                    slot(list, r, first).map_or(Save::Lost, Save::Pushed)
                }
                (Save::Entry, _) if read && self.def_regs & bit == 0 => Save::Lost,
                (Save::Pushed(at), Instr::Pop { list }) if list & bit != 0 => {
                    self.saving |= bit;
                    if slot(list, r, core.r[13]) == Some(at) {
                        Save::Restored(at)
                    } else {
                        Save::Lost
                    }
                }
                // Pushed, it may be used as any register (its entry value is in the word)
                // once written; read before, its entry value is an input.
                (Save::Pushed(_), _) if read && self.def_regs & bit == 0 => Save::Lost,
                (Save::Restored(_), _) if read || written => Save::Lost,
                (s, _) => s,
            };
            self.set_save(r, now);
        }
    }

    /// Before `core` runs `instr` (of usage `u`): the [`Save`] of the return address in LR
    /// (module documentation, "The return address"). A `PUSH` of LR still at its entry
    /// value saves it; the `POP` of that word into PC returns to it; any other read of its
    /// entry value, or any instruction after that `POP` (the call did not return), loses
    /// it. Accesses of other instructions to the word lose it too ([`Recording::load`]).
    pub(super) fn track_return(&mut self, core: &Core, instr: &Instr, u: &Usage) {
        const LR: u16 = 1 << 14;
        self.lr_moving = false;
        let unwritten = self.def_regs & LR == 0;
        let low = |list: u16| 4 * (list & 0xff).count_ones();
        self.lr = match (self.lr, *instr) {
            (Save::Entry, Instr::Push { list }) if list & LR != 0 && unwritten => {
                self.lr_moving = true;
                let first = core.r[13].wrapping_sub(low(list) + 4);
                let slot = first.wrapping_add(low(list));
                sram_location(slot).map_or(Save::Lost, |(off, _)| Save::Pushed(off as u32))
            }
            (Save::Pushed(at), Instr::Pop { list }) if list & 0x8000 != 0 => {
                self.lr_moving = true;
                let slot = core.r[13].wrapping_add(low(list));
                match sram_location(slot) {
                    Some((off, _)) if off as u32 == at => Save::Restored(at),
                    _ => Save::Lost,
                }
            }
            (Save::Entry | Save::Pushed(_), _) if u.reads & LR != 0 && unwritten => Save::Lost,
            (Save::Restored(_), _) => Save::Lost,
            (s, _) => s,
        };
    }

    /// A load or store of `size` bytes at SRAM offset `off` loses LR's saved word when it
    /// meets it, unless the instruction is its own `PUSH` or `POP`.
    #[inline]
    fn meet_return(&mut self, off: u32, size: u32) {
        if let Save::Pushed(at) | Save::Restored(at) = self.lr {
            let (lo, hi) = (off & !3, (off + size.max(1) - 1) & !3);
            if (at == lo || at == hi) && !self.lr_moving {
                self.lr = Save::Lost;
            }
        }
    }

    /// Register `r` (of [`SAVES`]) now stands as `s`: its [`Save`], the masks of them, and
    /// the span of the words pushed to.
    pub(super) fn set_save(&mut self, r: u8, s: Save) {
        let bit = 1u16 << r;
        self.saves[(r - 4) as usize] = s;
        match s {
            Save::Entry => {}
            Save::Pushed(at) => self.slots = (self.slots.0.min(at), self.slots.1.max(at)),
            Save::Restored(_) => {
                self.restored |= bit;
                self.kept &= !bit;
            }
            Save::Lost => {
                self.lost |= bit;
                self.kept &= !bit;
                self.restored &= !bit;
            }
        }
    }

    /// A load or store of `size` bytes at SRAM offset `off` loses the saved registers
    /// whose words it meets, unless the instruction is their own `PUSH` or `POP`.
    pub(super) fn meet_saves(&mut self, off: u32, size: u32) {
        let (lo, hi) = (off & !3, (off + size.max(1) - 1) & !3);
        if hi < self.slots.0 || lo > self.slots.1 {
            return;
        }
        for r in SAVES {
            if let Save::Pushed(at) | Save::Restored(at) = self.saves[(r - 4) as usize] {
                if (at == lo || at == hi) && self.saving & 1 << r == 0 {
                    self.set_save(r, Save::Lost);
                }
            }
        }
    }

    /// After the instruction: false when it changed what a call may not.
    pub(crate) fn after(&self, core: &Core) -> bool {
        !self.spoiled && core.state == RunState::Running && special_of(core) == self.entry.special
    }

    /// A load of `size` bytes at SRAM offset `off` gave `value`; `code`: its page holds
    /// decoded code.
    #[inline]
    pub(crate) fn load(&mut self, off: u32, size: u32, value: u32, code: bool) {
        self.meet_return(off, size);
        if self.moving {
            self.meet_saves(off, size);
            if let Some((r, addr)) = self.via {
                self.log_via.push((self.log.len() as u32, r, addr));
            }
        }
        self.log.push(Access {
            off,
            size: size as u8,
            store: false,
            code,
            value,
        });
    }

    /// A store of `size` bytes at SRAM offset `off`.
    #[inline]
    pub(crate) fn store(&mut self, off: u32, size: u32) {
        self.meet_return(off, size);
        if self.moving {
            self.meet_saves(off, size);
        }
        self.log.push(Access {
            off,
            size: size as u8,
            store: true,
            code: false,
            value: 0,
        });
    }

    /// An access of the call to a bank the I/O's DMA may reach, as the window logs it
    /// (kept with the memo: a hit logs it again, at the hit's cycles).
    pub(crate) fn io_access(&mut self, a: IoAccess) {
        let a = a.since(self.entry.cycle);
        if let (Some((r, addr)), IoKind::Load) = (self.via, a.kind) {
            self.io_via.push((self.io.len() as u32, r, addr));
        }
        self.io.push(a);
    }

    /// Whether the memo `m` of a watched function, its inputs matching at the function's
    /// entry in the recorded call, may stand for the function's call in the recording
    /// ([`Recording::nest`]): where the recording tracks no base, saved register or return
    /// address (which a hit would hide from it: a span's recording on a board whose keys do
    /// not move), on a board without an I/O, and with room in the log. A based memo's
    /// words are loaded where its base points now (`core`'s register: they matched there).
    pub(super) fn can_nest(&self, m: &Memo) -> bool {
        !self.moving
            && self.lr == Save::Lost
            && self.io_banks == 0
            && m.io.is_empty()
            && self.log.len()
                + 4 * (m.reads.len() + m.stores + m.based.as_ref().map_or(0, |b| b.words.len()))
                <= MAX_ACCESSES
    }

    /// Takes the memo `m`, about to be applied in place of a call inside the recorded one
    /// ([`Recording::can_nest`]), into the recording as the instructions of that call would
    /// have come: its input registers and flags read, the others it sets written, its
    /// input bytes loaded (with the values they hold now: its inputs match), then the
    /// words it stores (its effect's, the saved registers' and the return address's) stored,
    /// and its banks. What it stored back as it was read is left out of its effect and is
    /// among its inputs: loaded, the byte holds that value after the call too.
    pub(super) fn nest(&mut self, m: &mut Memo, core: &Core) {
        let (mut reads, mut writes) = (0u16, 0u16);
        for i in 0..15 {
            if m.live[i] != 0 {
                reads |= 1 << i;
            }
            if m.keep[i] == 0 {
                writes |= 1 << i;
            }
        }
        for &(_, r) in &m.saved {
            reads |= 1 << (r & 15);
        }
        if let Some(b) = m.based.as_deref() {
            reads |= 1 << (b.reg & 15);
        }
        if m.lr.is_some() {
            reads |= 1 << 14;
        }
        self.live_regs |= reads & !self.def_regs;
        self.def_regs |= writes;
        self.live_flags |= m.live_flags & !self.def_flags;
        self.def_flags |= m.out_flags;
        self.fetch_banks |= m.banks;
        let mut bytes = |w: &Word, store: bool| {
            for i in 0..4 {
                if w.mask >> (8 * i) & 0xff != 0 {
                    self.log.push(Access {
                        off: w.off + i,
                        size: 1,
                        store,
                        code: false,
                        value: if store { 0 } else { w.value >> (8 * i) & 0xff },
                    });
                }
            }
        };
        for w in &m.reads {
            bytes(w, false);
        }
        if let Some(b) = m.based.as_deref_mut() {
            let delta = core.r[b.reg as usize & 15].wrapping_sub(b.at);
            let moved = (delta != 0).then(|| b.moved(delta));
            for (k, w) in b.words.iter().enumerate() {
                let off = match moved {
                    None => Some(w.off),
                    Some(i) => b.moved[i].offs.as_ref().and_then(|o| o.get(k).copied()),
                };
                if let Some(off) = off {
                    bytes(
                        &Word {
                            off,
                            mask: w.mask,
                            value: w.value,
                        },
                        false,
                    );
                }
            }
        }
        for w in &m.writes.part {
            bytes(w, true);
        }
        let stored = (m.writes.full.iter().map(|&(off, _)| off))
            .chain(m.saved.iter().map(|&(off, _)| off))
            .chain(m.lr);
        for off in stored {
            self.log.push(Access {
                off,
                size: 4,
                store: true,
                code: false,
                value: 0,
            });
        }
    }

    /// An access a memo cannot hold (outside SRAM).
    #[inline]
    pub(crate) fn spoil(&mut self) {
        self.spoiled = true;
    }
}
