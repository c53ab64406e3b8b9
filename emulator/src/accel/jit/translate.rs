//! A region's function: the entry (flags and cycle loaded into cranelift variables; the
//! guest registers stay in the core, each read a load and each write a store, a value
//! reused where its load or store dominates), straight-line code with pending cycle and
//! instruction counts, branches inside the region as native jumps (back edges checking
//! the deadline), the exits, and the write-back. The instruction groups are in
//! [`super::alu`] and [`super::memory`].

use super::abi::{Ctx, Exit};
use super::scan::{bounds, branch_of, RegionInstr};
use crate::core::Core;
use crate::exec::{branch_target, literal_address};
use crate::semantics::ShiftImm;
use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, Block, InstBuilder, MemFlagsData, Value};
use cranelift_frontend::{FunctionBuilder, Variable};
use std::collections::HashMap;
use std::mem::offset_of;
use tactus_isa::decode::{Instr, MemOp};
use tactus_rp2040::memory::SRAM_ALIAS_BASE;

/// Flags, in `Core` field order (see [`Flags`] for how they are held).
pub(super) const N: usize = 0;
pub(super) const Z: usize = 1;
pub(super) const C: usize = 2;
pub(super) const V: usize = 3;

/// The guest flags as the translated code holds them, so that an instruction that sets
/// them computes almost nothing and a flag nobody reads before the next setter costs
/// nothing: N and Z as one word whose sign is N and which is zero exactly when Z is set
/// (every Thumb instruction that sets N sets Z from the same result: the word *is* the
/// result), C as a byte, and V as a word whose sign is V (the overflow rule's XOR term,
/// its sign not yet extracted). They become the core's four bytes only where read — a
/// condition — and at the exit. A core whose N and Z are both set (only `MSR APSR` can do
/// that) has no such word: the region leaves at once, before its first instruction.
#[derive(Clone, Copy)]
pub(super) struct Flags {
    /// i32: N = sign, Z = (word == 0).
    pub(super) nz: Variable,
    /// i8: 0 or 1.
    pub(super) c: Variable,
    /// i32: V = sign.
    pub(super) v: Variable,
}

/// How a region's SRAM accesses meet the other core (one compiled variant each).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Flavour {
    /// The other core may have claimed a bank in the cycles this code runs in: each
    /// access arbitrates against its claim (`System::arbitrate_fast`).
    Shared,
    /// Every claim of the other core is older than the core's cycle at the call (it is
    /// parked, asleep or behind and not running meanwhile): no access can wait, so each
    /// only records its own claim (the other core reads it when it runs again).
    Solo,
    /// Running ahead ([`crate::board`], "Running ahead"): arbitrated, every access checked
    /// against the allowed banks (the bank mask, bit per bank, [`System::allowed_banks`] at
    /// every call of this code: a constant of the code), and, when the second field is true
    /// (the code is only called with a journal), every store journaled (see the parent module); when false
    /// (a core catching up, called without a journal), no journal code at all.
    ///
    /// The third field: the code also does and logs a single access to a bank of the
    /// I/O's that the mask does not allow, and logs a word store to its registers (a
    /// window on a board with converters, `accel/io_window/`: [`abi::io_sram`],
    /// [`abi::io_reg`]); without it such an access leaves, as any other outside the mask.
    ///
    /// The fourth field: the code checks the deadline before every instruction and leaves
    /// there ([`Exit::Deadline`]) once the cycle has reached it, as the interpreter stops
    /// at its first instruction boundary at or after the limit; its back edges check only
    /// the journal's room. Called where the region's bound does not fit before the run's
    /// limit (a core run to the other's cycle at a meeting, `accel/window.rs`), instead of
    /// pre-decoded instructions.
    ///
    /// [`abi::io_sram`]: super::abi::io_sram
    /// [`abi::io_reg`]: super::abi::io_reg
    /// [`System::allowed_banks`]: crate::system::System::allowed_banks
    Confined(u8, bool, bool, bool),
    /// [`Flavour::Confined`] for a core whose accesses all come after the other core's last
    /// claims (as [`Flavour::Solo`]): in a window the other core does not touch the banks
    /// this core may, so their claims stay as they were.
    ConfinedSolo(u8, bool, bool, bool),
}

pub(super) struct Translator<'a> {
    pub(super) b: FunctionBuilder<'a>,
    pub(super) mf: MemFlagsData,
    pub(super) core: Value,
    pub(super) limit: Value,
    pub(super) sram: Value,
    pub(super) claims_self: Value,
    /// `None` in [`Flavour::Solo`] code: no access waits.
    pub(super) claims_other: Option<Value>,
    /// The guest registers live in the core ([`Core::r`]): a write is a store there, a
    /// read a load, so no exit carries them. The value last loaded or stored of each,
    /// with the block where: reused where that block dominates (see
    /// [`Translator::known`]).
    pub(super) known: [Option<(Value, Block)>; 16],
    /// The blocks the translation stood in at an instruction's start since the last label:
    /// each dominates the code after it up to the next label (every path from one
    /// instruction's start to the next runs through that instruction's code).
    pub(super) main_line: Vec<Block>,
    /// The registers the region never writes (their loads are pure).
    pub(super) read_only: u16,
    pub(super) flags: Flags,
    pub(super) cyc: Variable,
    /// The call's [`Ctx`]: instructions retired are added to [`Ctx::retired`] in place
    /// (at exits, back edges and jumps to a label), so no register holds their count.
    pub(super) ctx: Value,
    /// The core's contention stalls: only code that arbitrates ([`Flavour::Shared`],
    /// [`Flavour::Confined`]) can add to them, so the others neither load nor store them.
    pub(super) stalls: Option<Variable>,
    pub(super) q: Variable,
    /// Cycles not yet added to `cyc` and instructions not yet added to [`Ctx::retired`]
    /// (straight-line code; the cycles are added before each memory access and branch,
    /// the instructions only where control flow leaves or joins).
    pub(super) pend_cyc: u64,
    pub(super) pend_n: u64,
    /// The exits' blocks, one per reason ([`Exit`] as index) and, from index 4 on, per reason
    /// for paths that may have changed a flag ([`Translator::flags_set`]): each writes back
    /// (the flags only from index 4 on) and returns its reason. A leaving path stores the PC
    /// itself, so the exits take no PC or reason.
    pub(super) exits: [Option<Block>; 8],
    /// Whether a path from the entry to the translation's point may have set a flag: an
    /// instruction that sets one has been translated since the entry, or a loop's head (a
    /// label a later branch jumps back to) has been passed. An exit before that leaves the
    /// core's flags as they were and writes none back (a short region's exit packed all four
    /// again, some 10 host instructions).
    pub(super) flags_set: bool,
    pub(super) written: u16,
    /// Confined code only (see the parent module): the bank mask and the journal.
    pub(super) confined: Option<Confined>,
    /// The region is fetched through the non-striped alias of SRAM0-3 (as the firmware
    /// images place each core's code): its accesses try that view before the striped one.
    pub(super) alias_first: bool,
    /// Every instruction checks the deadline ([`Flavour::Confined`]'s fourth field).
    pub(super) timed: bool,
    /// The last cold exit block made ([`Translator::cold_exit`]): the PC it leaves before,
    /// its reason, the instructions it retires, and the block. The checks of one
    /// instruction (view, alignment, bank, confinement) share it.
    pub(super) cold: Option<(u32, Exit, u64, bool, Block)>,
}

/// A confined function's bank mask and journal (the journal's pointer and capacity are
/// loaded from [`Ctx`] where they are used, [`Translator::ctx_ptr`], rather than held in
/// registers through the region).
#[derive(Clone, Copy)]
pub(super) struct Confined {
    /// Entries used ([`Ctx::journal_len`], written back at the exit).
    pub(super) len: Variable,
    /// Journal entries the region's stores can write between two checks (at the entry and
    /// at each back edge): every store word of the region, as a forward path runs each
    /// instruction at most once.
    pub(super) room: u64,
    /// Whether the entry has checked that the journal has the room ([`Ctx::journal_cap`]
    /// at least `room`, so that `cap - room` does not wrap): each back edge then compares
    /// the length with `cap - room`.
    pub(super) checked: bool,
    /// The bank mask the code is compiled for: the allowed banks (bit per bank), a constant
    /// of the code (`block.rs` keeps a cache per mask: [`Translator::allowed`]).
    pub(super) mask: u8,
    /// The code is called with a journal (else without: no journal code).
    pub(super) journaled: bool,
    /// The code does and logs the I/O's accesses ([`Flavour::Confined`]'s third field).
    pub(super) io: bool,
}

impl<'a> Translator<'a> {
    /// Translates `instrs` (a region from [`scan`], not empty) into `b`; returns the
    /// builder and the bound from the entry.
    pub(super) fn run(
        mut b: FunctionBuilder<'a>,
        instrs: &[RegionInstr],
        flavour: Flavour,
    ) -> (FunctionBuilder<'a>, u64) {
        let (mask, journaled, io, timed) = match flavour {
            Flavour::Confined(m, j, io, t) | Flavour::ConfinedSolo(m, j, io, t) => {
                (Some(m), j, io, t)
            }
            _ => (None, false, false, false),
        };
        let confined = mask.is_some();
        let solo = matches!(flavour, Flavour::Solo | Flavour::ConfinedSolo(..));
        let index: HashMap<u32, usize> =
            instrs.iter().enumerate().map(|(i, x)| (x.pc, i)).collect();
        let targets: Vec<Option<usize>> = instrs
            .iter()
            .map(|i| branch_of(i).and_then(|t| index.get(&t).copied()))
            .collect();
        let bound = bounds(instrs, &targets);
        let entry = b.create_block();
        b.append_block_params_for_function_params(entry);
        b.switch_to_block(entry);
        let params = b.block_params(entry).to_vec();
        let (core, ctx, limit) = (params[0], params[1], params[2]);
        let mf = MemFlagsData::trusted();
        let ptr =
            |b: &mut FunctionBuilder, off: usize| b.ins().load(types::I64, mf, ctx, off as i32);
        let sram = ptr(&mut b, offset_of!(Ctx, sram));
        let claims_self = ptr(&mut b, offset_of!(Ctx, claims_self));
        let claims_other = (!solo).then(|| ptr(&mut b, offset_of!(Ctx, claims_other)));
        let flags = Flags {
            nz: b.declare_var(types::I32),
            c: b.declare_var(types::I8),
            v: b.declare_var(types::I32),
        };
        let cyc = b.declare_var(types::I64);
        let stalls = (!solo).then(|| b.declare_var(types::I64));
        let q = b.declare_var(types::I64);
        // A register the region never writes is stored nowhere in it (no helper the code
        // calls touches the core's registers), so its loads are pure: cranelift merges
        // them and places them where first needed.
        let written = instrs.iter().try_fold(0u16, |w, i| {
            crate::accel::memo::usage(&i.instr).map(|u| w | u.writes)
        });
        let read_only = written.map_or(0, |w| !w & 0x7fff);
        let flag_at = [
            offset_of!(Core, n),
            offset_of!(Core, z),
            offset_of!(Core, c),
            offset_of!(Core, v),
        ];
        let [n, z, c, v] = flag_at.map(|at| b.ins().load(types::I8, mf, core, at as i32));
        {
            // N and Z both set: no word holds them; leave before the first instruction,
            // nothing changed (the context's counts are zero on the call).
            let both = b.ins().band(n, z);
            let bail = b.create_block();
            b.set_cold_block(bail);
            let go = b.create_block();
            b.ins().brif(both, bail, &[], go, &[]);
            b.switch_to_block(bail);
            let why = b.ins().iconst(types::I32, Exit::General as i64);
            b.ins().return_(&[why]);
            b.switch_to_block(go);
        }
        // nz = Z ? 0 : (N ? i32::MIN : 1); V's word = V << 31.
        let n32 = b.ins().uextend(types::I32, n);
        let sign = b.ins().ishl_imm_u(n32, 31);
        let one = b.ins().iconst(types::I32, 1);
        let nonzero = b.ins().bor(sign, one);
        let zero = b.ins().iconst(types::I32, 0);
        let nz = b.ins().select(z, zero, nonzero);
        b.def_var(flags.nz, nz);
        b.def_var(flags.c, c);
        let v32 = b.ins().uextend(types::I32, v);
        let v32 = b.ins().ishl_imm_u(v32, 31);
        b.def_var(flags.v, v32);
        let v = b
            .ins()
            .load(types::I64, mf, core, offset_of!(Core, cycle) as i32);
        b.def_var(cyc, v);
        if let Some(stalls) = stalls {
            let stalls_ptr = ptr(&mut b, offset_of!(Ctx, stalls));
            let v = b.ins().load(types::I64, mf, stalls_ptr, 0);
            b.def_var(stalls, v);
        }
        let zero = b.ins().iconst(types::I64, 0);
        b.def_var(q, zero);
        let confined = confined.then(|| {
            let len = b.declare_var(types::I64);
            let v = ptr(&mut b, offset_of!(Ctx, journal_len));
            b.def_var(len, v);
            let room = instrs
                .iter()
                .filter(|i| {
                    matches!(
                        tactus_isa::timing::class(&i.instr),
                        tactus_isa::timing::Class::Store
                            | tactus_isa::timing::Class::StoreMultiple
                            | tactus_isa::timing::Class::Push
                    )
                })
                .map(|i| super::scan::data_words(&i.instr) as u64)
                .sum();
            Confined {
                len,
                room,
                checked: false,
                mask: mask.unwrap_or(0),
                journaled,
                io,
            }
        });
        let mut t = Translator {
            b,
            mf,
            core,
            limit,
            sram,
            claims_self,
            claims_other,
            known: [None; 16],
            main_line: Vec::new(),
            read_only,
            flags,
            cyc,
            ctx,
            stalls,
            q,
            pend_cyc: 0,
            pend_n: 0,
            exits: [None; 8],
            flags_set: false,
            written: 0,
            confined,
            alias_first: instrs[0].pc.wrapping_sub(SRAM_ALIAS_BASE) < 0x4_0000,
            timed,
            cold: None,
        };
        // A block for each instruction a branch of the region jumps to.
        let mut labels: Vec<Option<Block>> = vec![None; instrs.len()];
        // Loops' heads: reached again from code translated after them.
        let mut loop_head = vec![false; instrs.len()];
        for (i, &t_) in targets.iter().enumerate() {
            let Some(t_) = t_ else { continue };
            if labels[t_].is_none() {
                labels[t_] = Some(t.b.create_block());
            }
            loop_head[t_] |= t_ <= i;
        }
        // Confined: no store checks the journal's capacity; the entry checks room for all.
        if let Some(c) = t.confined.filter(|c| c.journaled) {
            let room = t.journal_room();
            t.general_unless(room, instrs[0].pc);
            t.confined = Some(Confined { checked: true, ..c });
        }
        let mut live = true;
        for (i, ins) in instrs.iter().enumerate() {
            if let Some(l) = labels[i] {
                if live {
                    t.flush();
                    t.flush_retired();
                    t.b.ins().jump(l, &[]);
                }
                // Every way into a label carries nothing pending: an exit before dead code
                // (a `BL`, an unconditional exit) left its count pending for a side exit's
                // sake, which must not reach the code after the label.
                (t.pend_cyc, t.pend_n) = (0, 0);
                // Every other way into a label was translated before it, with the flags as
                // far as `flags_set` says, except a loop's back edge.
                t.flags_set |= loop_head[i];
                t.b.switch_to_block(l);
                t.main_line.clear();
                live = true;
            }
            if !live {
                continue;
            }
            if t.timed {
                t.deadline_check(ins.pc);
            }
            t.mark_main_line();
            live = t.instr(ins, targets[i].map(|j| (j, labels[j], bound[j], j <= i)));
        }
        if live {
            let end = instrs[instrs.len() - 1];
            t.flush();
            let pc = t.c32(end.pc.wrapping_add(end.size));
            t.leave(pc, Exit::Out);
        }
        // The loads `reg` made pure were of registers the translation never wrote.
        debug_assert!(written.is_none_or(|w| t.written & !w & 0x7fff == 0));
        // The exits: write back and return.
        for (k, exit) in t.exits.into_iter().enumerate() {
            let Some(exit) = exit else { continue };
            let why = k % 4;
            t.b.switch_to_block(exit);
            if k >= 4 {
                let values = [N, Z, C, V].map(|f| t.flag(f));
                for (v, at) in values.into_iter().zip(flag_at) {
                    t.b.ins().store(mf, v, core, at as i32);
                }
            }
            let v = t.b.use_var(cyc);
            t.b.ins().store(mf, v, core, offset_of!(Core, cycle) as i32);
            if let Some(stalls) = stalls {
                let v = t.b.use_var(stalls);
                let stalls_ptr = t.ctx_ptr(offset_of!(Ctx, stalls));
                t.b.ins().store(mf, v, stalls_ptr, 0);
            }
            let v = t.b.use_var(q);
            t.b.ins().store(mf, v, ctx, offset_of!(Ctx, q) as i32);
            if let Some(c) = t.confined {
                let v = t.b.use_var(c.len);
                t.b.ins()
                    .store(mf, v, ctx, offset_of!(Ctx, journal_len) as i32);
            }
            let why = t.b.ins().iconst(types::I32, why as i64);
            t.b.ins().return_(&[why]);
        }
        t.b.seal_all_blocks();
        (t.b, bound[0])
    }

    /// A pointer field of the context (`off`: its offset in [`Ctx`]), loaded where it is
    /// used rather than held in a register through the region.
    pub(super) fn ctx_ptr(&mut self, off: usize) -> Value {
        self.b.ins().load(types::I64, self.mf, self.ctx, off as i32)
    }

    /// Confined code: the allowed banks' mask (i32, bit per bank), a constant of the
    /// compiled code rather than a register held through the region.
    pub(super) fn allowed(&mut self, c: Confined) -> Value {
        self.b.ins().iconst(types::I32, i64::from(c.mask))
    }

    pub(super) fn c32(&mut self, x: u32) -> Value {
        self.b.ins().iconst(types::I32, x as i64)
    }

    /// 1 when a `BX` or `POP {…, PC}` to `target` must leave compiled code for the
    /// interpreter: an even target (no Thumb bit: a HardFault on ARMv6-M) or, when
    /// `exc_return` and the core is in a handler, an EXC_RETURN value (`0xFxxxxxxx`).
    pub(super) fn interworking_exit(&mut self, target: Value, exc_return: bool) -> Value {
        let odd = self.b.ins().band_imm_u(target, 1);
        let even = self.b.ins().icmp_imm_u(IntCC::Equal, odd, 0);
        if !exc_return {
            return even;
        }
        let ipsr = self.b.ins().load(
            types::I32,
            self.mf,
            self.core,
            offset_of!(Core, ipsr) as i32,
        );
        let handler = self.b.ins().icmp_imm_u(IntCC::NotEqual, ipsr, 0);
        let top = self.b.ins().ushr_imm_u(target, 28);
        let exc = self.b.ins().icmp_imm_u(IntCC::Equal, top, 0xf);
        let ret = self.b.ins().band(handler, exc);
        self.b.ins().bor(even, ret)
    }

    pub(super) fn reg(&mut self, r: u8, pc: u32) -> Value {
        if r == 15 {
            return self.c32(pc.wrapping_add(4));
        }
        let r = (r & 15) as usize;
        if let Some(v) = self.known(r) {
            return v;
        }
        let flags = match self.read_only >> r & 1 {
            1 => self.mf.with_readonly().with_can_move(),
            _ => self.mf,
        };
        let at = (offset_of!(Core, r) + 4 * r) as i32;
        let v = self.b.ins().load(types::I32, flags, self.core, at);
        self.known[r] = Some((v, self.block()));
        v
    }

    pub(super) fn set(&mut self, r: u8, v: Value) {
        let r = (r & 15) as usize;
        self.written |= 1 << r;
        let at = (offset_of!(Core, r) + 4 * r) as i32;
        self.b.ins().store(self.mf, v, self.core, at);
        self.known[r] = Some((v, self.block()));
    }

    /// Register `r`'s value as last loaded or stored, where the block of that dominates
    /// the current one (the same block, or one of [`Translator::main_line`]).
    fn known(&mut self, r: usize) -> Option<Value> {
        let (v, at) = self.known[r]?;
        (at == self.block() || self.main_line.contains(&at)).then_some(v)
    }

    fn block(&self) -> Block {
        self.b
            .current_block()
            .expect("the translation stands in a block")
    }

    /// Records the current block as the start of an instruction (see
    /// [`Translator::main_line`]).
    pub(super) fn mark_main_line(&mut self) {
        let b = self.block();
        if self.main_line.last() != Some(&b) {
            self.main_line.push(b);
        }
    }

    /// Flag `f` (0 or 1, i8) from its held form ([`Flags`]).
    pub(super) fn flag(&mut self, f: usize) -> Value {
        match f {
            N => {
                let w = self.b.use_var(self.flags.nz);
                self.b.ins().icmp_imm_s(IntCC::SignedLessThan, w, 0)
            }
            Z => {
                let w = self.b.use_var(self.flags.nz);
                self.b.ins().icmp_imm_u(IntCC::Equal, w, 0)
            }
            C => self.b.use_var(self.flags.c),
            _ => {
                let w = self.b.use_var(self.flags.v);
                self.b.ins().icmp_imm_s(IntCC::SignedLessThan, w, 0)
            }
        }
    }

    /// Sets C (an i8, 0 or 1).
    pub(super) fn set_c(&mut self, c: Value) {
        self.flags_set = true;
        self.b.def_var(self.flags.c, c);
    }

    /// Adds the pending straight-line cycles to the cycle variable.
    pub(super) fn flush(&mut self) {
        if self.pend_cyc != 0 {
            let c = self.b.use_var(self.cyc);
            let c = self.b.ins().iadd_imm_s(c, self.pend_cyc as i64);
            self.b.def_var(self.cyc, c);
            self.pend_cyc = 0;
        }
    }

    /// Adds the pending instructions to [`Ctx::retired`] before a jump to a label (every
    /// path into a label carries none pending).
    pub(super) fn flush_retired(&mut self) {
        self.add_retired();
        self.pend_n = 0;
    }

    /// Adds the pending instructions to [`Ctx::retired`] and keeps them pending: for an
    /// exit in a side block, after which the translation goes on along the other branch.
    fn add_retired(&mut self) {
        if self.pend_n != 0 {
            let at = offset_of!(Ctx, retired) as i32;
            let n = self.b.ins().load(types::I64, self.mf, self.ctx, at);
            let n = self.b.ins().iadd_imm_s(n, self.pend_n as i64);
            self.b.ins().store(self.mf, n, self.ctx, at);
        }
    }

    /// Stores PC `pc` and jumps to the exit for `why` (pending counts flushed first).
    pub(super) fn leave(&mut self, pc: Value, why: Exit) {
        self.flush();
        self.add_retired();
        let at = (offset_of!(Core, r) + 4 * 15) as i32;
        self.b.ins().store(self.mf, pc, self.core, at);
        let k = why as usize + 4 * self.flags_set as usize;
        let exit = *self.exits[k].get_or_insert_with(|| self.b.create_block());
        self.b.ins().jump(exit, &[]);
    }

    /// Confined code: whether the journal has room for [`Confined::room`] more entries.
    pub(super) fn journal_room(&mut self) -> Value {
        let c = self.confined.expect("confined code");
        let len = self.b.use_var(c.len);
        let cap = self.ctx_ptr(offset_of!(Ctx, journal_cap));
        if c.checked {
            let cap_room = self.b.ins().iadd_imm_s(cap, -(c.room as i64));
            return self
                .b
                .ins()
                .icmp(IntCC::UnsignedLessThanOrEqual, len, cap_room);
        }
        let need = self.b.ins().iadd_imm_s(len, c.room as i64);
        self.b.ins().icmp(IntCC::UnsignedLessThanOrEqual, need, cap)
    }

    /// Leaves before the instruction at `pc` unless `cond` holds (nothing of it done).
    pub(super) fn general_unless(&mut self, cond: Value, pc: u32) {
        self.leave_unless(cond, pc, Exit::General);
    }

    /// Timed code ([`Translator::timed`]): leaves before the instruction at `pc` with
    /// [`Exit::Deadline`] when the cycle has reached the limit (nothing of it done).
    fn deadline_check(&mut self, pc: u32) {
        self.flush();
        let c = self.b.use_var(self.cyc);
        let early = self.b.ins().icmp(IntCC::UnsignedLessThan, c, self.limit);
        self.leave_unless(early, pc, Exit::Deadline);
    }

    /// Leaves by `exit` before the instruction at `pc` unless `cond` holds, through a cold
    /// block (nothing of the instruction done).
    fn leave_unless(&mut self, cond: Value, pc: u32, exit: Exit) {
        self.flush();
        let (out, new) = self.cold_exit(pc, exit);
        let on = self.b.create_block();
        self.b.ins().brif(cond, on, &[], out, &[]);
        self.fill_cold_exit(out, new, pc, exit);
        self.b.switch_to_block(on);
    }

    /// Leaves before the instruction at `pc` when `cond` holds (nothing of it done).
    pub(super) fn general_if(&mut self, cond: Value, pc: u32) {
        self.flush();
        let (out, new) = self.cold_exit(pc, Exit::General);
        let on = self.b.create_block();
        self.b.ins().brif(cond, out, &[], on, &[]);
        self.fill_cold_exit(out, new, pc, Exit::General);
        self.b.switch_to_block(on);
    }

    /// The cold block that leaves by `exit` before the instruction at `pc` (pending cycles
    /// flushed by the caller), and whether it is new (to be filled by
    /// [`Translator::fill_cold_exit`] once the branch to it is made): the last one made
    /// when that leaves before the same instruction for the same reason with the same
    /// instructions pending, else a new one: one per instruction rather than one per
    /// check of an access halves the exits of a memory access, each a jump with the
    /// variables the exit writes back (flags, cycle, stalls, `q`, journal length; the
    /// guest registers are in the core already). Those are the variables' values on each
    /// path into the block (the SSA builder gives the block a parameter where two paths
    /// differ), so a shared block leaves each path as its own would.
    fn cold_exit(&mut self, pc: u32, exit: Exit) -> (Block, bool) {
        match self.cold {
            Some((p, e, n, f, block))
                if p == pc && e == exit && n == self.pend_n && f == self.flags_set =>
            {
                (block, false)
            }
            _ => {
                let out = self.b.create_block();
                self.b.set_cold_block(out);
                self.cold = Some((pc, exit, self.pend_n, self.flags_set, out));
                (out, true)
            }
        }
    }

    /// Fills a new cold exit block (see [`Translator::cold_exit`]); nothing for a shared one.
    fn fill_cold_exit(&mut self, out: Block, new: bool, pc: u32, exit: Exit) {
        if new {
            self.b.switch_to_block(out);
            let p = self.c32(pc);
            self.leave(p, exit);
        }
    }

    /// Counts a completed instruction of `cycles` static cycles (plus `wait` dynamic ones),
    /// recording its end as `q` when it took two cycles or more.
    pub(super) fn retire(&mut self, cycles: u32, wait: Option<Value>) {
        self.pend_cyc += cycles as u64;
        self.pend_n += 1;
        if let Some(w) = wait {
            self.flush();
            let c = self.b.use_var(self.cyc);
            let c = self.b.ins().iadd(c, w);
            self.b.def_var(self.cyc, c);
        }
        if cycles >= 2 {
            self.flush();
            let c = self.b.use_var(self.cyc);
            self.b.def_var(self.q, c);
        }
    }

    /// A branch to `target` (absolute), taken after the instruction was retired: a native
    /// jump when it stays in the region (a back edge checks the deadline), else an exit.
    pub(super) fn goto(
        &mut self,
        target: u32,
        internal: Option<(usize, Option<Block>, u64, bool)>,
    ) {
        self.flush();
        self.flush_retired();
        match internal {
            Some((_, Some(label), bound, back)) => {
                if back {
                    // Every instruction up to the next exit or back edge starts before the
                    // limit when `cycle + bound <= limit` (timed code checks each one).
                    let c = self.b.use_var(self.cyc);
                    let end = self.b.ins().iadd_imm_s(c, bound as i64);
                    let mut fits = match self.timed {
                        true => self.b.ins().iconst(types::I8, 1),
                        false => self
                            .b
                            .ins()
                            .icmp(IntCC::UnsignedLessThanOrEqual, end, self.limit),
                    };
                    if self.confined.is_some_and(|c| c.journaled) {
                        let room = self.journal_room();
                        fits = self.b.ins().band(fits, room);
                    }
                    let stop = self.b.create_block();
                    self.b.set_cold_block(stop);
                    self.b.ins().brif(fits, label, &[], stop, &[]);
                    self.b.switch_to_block(stop);
                    let p = self.c32(target);
                    self.leave(p, Exit::Deadline);
                } else {
                    self.b.ins().jump(label, &[]);
                }
            }
            _ => {
                let p = self.c32(target);
                self.leave(p, Exit::Out);
            }
        }
    }

    /// Translates one instruction; false when nothing falls through it.
    pub(super) fn instr(
        &mut self,
        ins: &RegionInstr,
        internal: Option<(usize, Option<Block>, u64, bool)>,
    ) -> bool {
        use Instr::*;
        let pc = ins.pc;
        let next = pc.wrapping_add(ins.size);
        let base = ins.cost.0;
        match ins.instr {
            LslImm { rd, rm, imm } => {
                let x = self.reg(rm, pc);
                self.shift_imm(ShiftImm::Lsl, rd, x, imm);
            }
            LsrImm { rd, rm, imm } => {
                let x = self.reg(rm, pc);
                self.shift_imm(ShiftImm::Lsr, rd, x, imm);
            }
            AsrImm { rd, rm, imm } => {
                let x = self.reg(rm, pc);
                self.shift_imm(ShiftImm::Asr, rd, x, imm);
            }
            AddReg { rd, rn, rm } => {
                let (x, y) = (self.reg(rn, pc), self.reg(rm, pc));
                let r = self.add_flags(x, y);
                self.set(rd, r);
            }
            SubReg { rd, rn, rm } => {
                let (x, y) = (self.reg(rn, pc), self.reg(rm, pc));
                let r = self.sub_flags(x, y);
                self.set(rd, r);
            }
            AddImm { rd, rn, imm } => {
                let x = self.reg(rn, pc);
                let y = self.c32(imm as u32);
                let r = self.add_flags(x, y);
                self.set(rd, r);
            }
            SubImm { rd, rn, imm } => {
                let x = self.reg(rn, pc);
                let y = self.c32(imm as u32);
                let r = self.sub_flags(x, y);
                self.set(rd, r);
            }
            MovImm { rd, imm } => {
                let r = self.c32(imm as u32);
                self.set(rd, r);
                self.nz(r);
            }
            CmpImm { rn, imm } => {
                let x = self.reg(rn, pc);
                let y = self.c32(imm as u32);
                self.sub_flags(x, y);
            }
            Alu { op, rdn, rm } => {
                let m = self.reg(rm, pc);
                self.alu(op, rdn, m);
            }
            CmpHi { rn, rm } => {
                let (x, y) = (self.reg(rn, pc), self.reg(rm, pc));
                self.sub_flags(x, y);
            }
            Sxth { rd, rm } | Sxtb { rd, rm } | Uxth { rd, rm } | Uxtb { rd, rm } => {
                let x = self.reg(rm, pc);
                let (ty, signed) = match ins.instr {
                    Sxth { .. } => (types::I16, true),
                    Sxtb { .. } => (types::I8, true),
                    Uxth { .. } => (types::I16, false),
                    _ => (types::I8, false),
                };
                let n = self.b.ins().ireduce(ty, x);
                let r = if signed {
                    self.b.ins().sextend(types::I32, n)
                } else {
                    self.b.ins().uextend(types::I32, n)
                };
                self.set(rd, r);
            }
            Rev { rd, rm } => {
                let x = self.reg(rm, pc);
                let r = self.b.ins().bswap(x);
                self.set(rd, r);
            }
            Rev16 { rd, rm } => {
                let x = self.reg(rm, pc);
                let lo = self.b.ins().band_imm_u(x, 0x00ff_00ff);
                let lo = self.b.ins().ishl_imm_u(lo, 8);
                let hi = self.b.ins().ushr_imm_u(x, 8);
                let hi = self.b.ins().band_imm_u(hi, 0x00ff_00ff);
                let r = self.b.ins().bor(lo, hi);
                self.set(rd, r);
            }
            Revsh { rd, rm } => {
                let x = self.reg(rm, pc);
                let h = self.b.ins().ireduce(types::I16, x);
                let h = self.b.ins().bswap(h);
                let r = self.b.ins().sextend(types::I32, h);
                self.set(rd, r);
            }
            AddHi { rdn, rm } | MovHi { rd: rdn, rm } => {
                let v = self.reg(rm, pc);
                let r = if let AddHi { .. } = ins.instr {
                    let x = self.reg(rdn, pc);
                    self.b.ins().iadd(x, v)
                } else {
                    v
                };
                if rdn == 15 {
                    let t = self.b.ins().band_imm_u(r, !1i64 as u32 as i64);
                    self.retire(base, None);
                    self.flush();
                    self.leave(t, Exit::Out);
                    return false;
                }
                let r = if rdn == 13 {
                    self.b.ins().band_imm_u(r, !3u32 as i64)
                } else {
                    r
                };
                self.set(rdn, r);
            }
            Bx { rm } | Blx { rm } => {
                let target = self.reg(rm, pc);
                let bad = self.interworking_exit(target, matches!(ins.instr, Bx { .. }));
                self.general_if(bad, pc);
                if let Blx { .. } = ins.instr {
                    let lr = self.c32(next | 1);
                    self.set(14, lr);
                }
                let t = self.b.ins().band_imm_u(target, !1u32 as i64);
                self.retire(base, None);
                self.leave(t, Exit::Out);
                return false;
            }
            LdrLit { rt, imm } => {
                let a = self.c32(literal_address(pc, imm));
                return self.mem(ins, MemOp::Ldr, rt, a);
            }
            MemReg { op, rt, rn, rm } => {
                let (x, y) = (self.reg(rn, pc), self.reg(rm, pc));
                let a = self.b.ins().iadd(x, y);
                return self.mem(ins, op, rt, a);
            }
            MemImm { op, rt, rn, imm } => {
                let x = self.reg(rn, pc);
                let a = self.b.ins().iadd_imm_s(x, imm as i64);
                return self.mem(ins, op, rt, a);
            }
            Adr { rd, imm } => {
                let v = self.c32(literal_address(pc, imm));
                self.set(rd, v);
            }
            AddSpImm { rd, imm } => {
                let sp = self.reg(13, pc);
                let v = self.b.ins().iadd_imm_s(sp, imm as i64);
                self.set(rd, v);
            }
            AddSp { imm } => {
                let sp = self.reg(13, pc);
                let v = self.b.ins().iadd_imm_s(sp, imm as i64);
                self.set(13, v);
            }
            SubSp { imm } => {
                let sp = self.reg(13, pc);
                let v = self.b.ins().iadd_imm_s(sp, -(imm as i64));
                self.set(13, v);
            }
            Push { list } => {
                let count = list.count_ones();
                let sp = self.reg(13, pc);
                let start = self.b.ins().iadd_imm_s(sp, -4 * count as i64);
                let regs: Vec<u8> = (0..16u8).filter(|r| list & (1 << r) != 0).collect();
                let values: Vec<Value> = regs.iter().map(|&r| self.reg(r, pc)).collect();
                let (_, wait, code) = self.multiple(ins, start, count, Some(&values), false);
                self.set(13, start);
                self.retire(base, wait);
                self.invalidate_if(code, ins);
                return true;
            }
            Stm { rn, list } => {
                let count = list.count_ones();
                let start = self.reg(rn, pc);
                let regs: Vec<u8> = (0..8u8).filter(|r| list & (1 << r) != 0).collect();
                let values: Vec<Value> = regs.iter().map(|&r| self.reg(r, pc)).collect();
                let (_, wait, code) = self.multiple(ins, start, count, Some(&values), false);
                let end = self.b.ins().iadd_imm_s(start, 4 * count as i64);
                self.set(rn, end);
                self.retire(base, wait);
                self.invalidate_if(code, ins);
                return true;
            }
            Pop { list } => return self.load_multiple(ins, 13, list),
            Ldm { rn, list } => return self.load_multiple(ins, rn, list as u16),
            Hint(_) => {}
            B { offset } => {
                self.retire(base, None);
                self.goto(branch_target(pc, offset), internal);
                return false;
            }
            BCond { cond, offset } => {
                let c = self.condition(cond);
                self.flush();
                let taken = self.b.create_block();
                let on = self.b.create_block();
                self.b.ins().brif(c, taken, &[], on, &[]);
                self.b.switch_to_block(taken);
                let saved = (self.pend_cyc, self.pend_n);
                self.retire(ins.cost.1, None);
                self.goto(branch_target(pc, offset), internal);
                (self.pend_cyc, self.pend_n) = saved;
                self.b.switch_to_block(on);
                self.retire(base, None);
                return true;
            }
            Bl { offset } => {
                let lr = self.c32(next | 1);
                self.set(14, lr);
                self.retire(base, None);
                let t = self.c32(branch_target(pc, offset));
                self.leave(t, Exit::Out);
                return false;
            }
            _ => {
                // Not translated (`translated` keeps these out of regions).
                self.flush();
                let p = self.c32(pc);
                self.leave(p, Exit::General);
                return false;
            }
        }
        self.retire(base, None);
        true
    }
}
