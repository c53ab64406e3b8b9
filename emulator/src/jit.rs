//! The block compiler: Thumb code regions translated to native code with cranelift.
//!
//! **What a region is.** A region starts at the address the core is about to execute and
//! runs linearly through memory over the instructions this module translates (data
//! processing, multiplies, loads and stores, LDM/STM/PUSH/POP, ADR/SP arithmetic, B, B<cc>,
//! BL, BX, BLX, MOV/ADD to PC), up to [`MAX_REGION`] instructions; it stops before the first
//! instruction it does not translate (SVC, WFI, MSR, CPS, barriers, …) and after an
//! unconditional branch that no earlier branch jumps beyond. Branches whose target is an
//! instruction of the region become native jumps (a forward `if`, a counted loop), so the
//! guest registers stay in host registers across loop iterations; every other target
//! leaves the native code with the core's PC set.
//!
//! **Meaning.** Each instruction's effect is written once more here, as cranelift IR — the
//! flags of `adds`, the conditions of `condition`, the shifts of `alu`, the memory paths of
//! `mem_fast`/`push_fast`/`pop_fast` in `exec.rs`. They are not a second authority:
//! `tests/block_jit.rs` runs every translated form, on random operands and flags, as a
//! one-instruction region against `Core::execute_op` (the interpreter's executor), and
//! `tests/block_engine.rs` runs random programs, the key-update workload and (in
//! `firmware`) the firmware images on both engines with every observable compared. The
//! region's decoding is `decode::decode` and its prices are `timing::cycles`, called when
//! the region is compiled: the timing table stays the one source of cycles.
//!
//! **Cycles.** Each instruction's cost is the timing table's `(not taken, taken)` pair,
//! summed at compile time along straight-line code; the run-time additions are only the
//! data-dependent ones: which way a conditional branch went, and the wait state of an SRAM
//! access that finds its bank claimed by the other core in the same cycle (the arbiter of
//! [`crate::bus`], done inline on the same `bank_claim` table). Flash never waits; any
//! other address (peripherals, SIO, PPB, the boot ROM, an unaligned or unmapped access)
//! leaves the native code *before* the instruction, with every register, flag and counter
//! as at its start, and the board's general path executes it. The caller runs a region
//! only when the core's cycle plus the region's bound — the longest path from its entry to
//! an exit or a loop's back edge, each instruction priced by the table's larger cost plus
//! one wait per data word — is at most the run's deadline, so every instruction the native
//! code starts starts before the deadline, as the interpreter's would; each back edge
//! checks the same against the bound from the loop's head, and leaves at the head when it
//! does not fit.
//!
//! **Self-modifying code.** A region marks the SRAM pages its instructions come from as
//! code pages ([`System::code_pages`]); a native store into such a page completes, and the
//! code leaves right after that instruction so the caller drops every decoded block and
//! region ([`System::invalidate_code`]), as the interpreter's store does. Compiled code is
//! kept by the region's address *and its instruction halfwords*, so after an invalidation
//! (or a host write) an unchanged region is found again without recompiling; changed code
//! is a new key.
//!
//! **Exits.** The function returns why it stopped ([`Exit`]) and writes back the guest
//! registers and flags it changed, the cycle counter, the contention stalls, the number of
//! instructions retired and the end cycle of its last instruction that took two cycles or
//! more (what the board needs to replay a sleeping core's turns, [`crate::block`]).

use crate::bus::{Bus, System, FLASH_BASE, FLASH_SIZE, SRAM_ALIAS_BASE, SRAM_BASE, SRAM_SIZE};
use crate::core::Core;
use crate::decode::{decode, AluOp, Instr, MemOp};
use crate::exec::{branch_target, literal_address};
use crate::timing;
use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{
    types, AbiParam, Block, BlockArg, InstBuilder, MemFlagsData, Signature, Value,
};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext, Variable};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, Linkage, Module};
use std::collections::HashMap;
use std::mem::offset_of;

/// Most instructions in one region.
pub const MAX_REGION: usize = 128;

/// Compiled regions kept before all are dropped (and their memory freed).
const MAX_COMPILED: usize = 8192;

/// Slots of the direct-mapped region lookup (by address).
const SLOTS: usize = 1 << 14;

/// What the native code shares with the board for one call (`#[repr(C)]`: the generated
/// code reads its fields at fixed offsets).
#[repr(C)]
pub(crate) struct Ctx {
    /// [`System::sram`]'s bytes.
    pub sram: *mut u8,
    /// [`System::flash`]'s bytes.
    pub flash: *const u8,
    /// [`System::code_pages`] (one `bool` per 256-byte page).
    pub code_pages: *const u8,
    /// `bank_claim[0][core]` (banks are 16 bytes apart).
    pub claims_self: *mut u64,
    /// `bank_claim[0][other core]`.
    pub claims_other: *const u64,
    /// `contention_stalls[core]`.
    pub stalls: *mut u64,
    /// Out: end cycle of the last instruction that cost two cycles or more (0: none).
    pub q: u64,
    /// Out: instructions retired.
    pub retired: u64,
}

/// Why native code returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub(crate) enum Exit {
    /// At a branch out of the region or the region's end; PC is where to go on.
    Out = 0,
    /// Before an instruction the native code does not complete (PC is its address).
    General = 1,
    /// After a store into a code page (PC is the next instruction): drop decoded code.
    Invalidate = 2,
    /// A loop's back edge did not fit before the deadline (PC is the loop's head).
    Deadline = 3,
}

impl Exit {
    fn from_raw(r: u32) -> Exit {
        match r {
            0 => Exit::Out,
            1 => Exit::General,
            2 => Exit::Invalidate,
            _ => Exit::Deadline,
        }
    }
}

/// A compiled region: `fn(core, ctx, limit) -> Exit`.
pub(crate) type NativeFn = unsafe extern "C" fn(*mut Core, *mut Ctx, u64) -> u32;

/// One instruction of a region.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RegionInstr {
    pub pc: u32,
    pub size: u32,
    pub instr: Instr,
    /// (not taken, taken) cycles from the timing table.
    pub cost: (u32, u32),
}

/// Whether the block compiler translates `instr`.
pub(crate) fn translated(instr: &Instr) -> bool {
    use Instr::*;
    match *instr {
        LslImm { .. } | LsrImm { .. } | AsrImm { .. } | AddReg { .. } | SubReg { .. } => true,
        AddImm { .. } | SubImm { .. } | MovImm { .. } | CmpImm { .. } | Alu { .. } => true,
        CmpHi { .. } | Sxth { .. } | Sxtb { .. } | Uxth { .. } | Uxtb { .. } => true,
        Rev { .. } | Rev16 { .. } | Revsh { .. } | AddHi { .. } | MovHi { .. } => true,
        Bx { .. } | Blx { .. } | LdrLit { .. } | MemReg { .. } | MemImm { .. } => true,
        Adr { .. } | AddSpImm { .. } | AddSp { .. } | SubSp { .. } => true,
        Push { list } | Pop { list } => list != 0,
        Stm { list, .. } | Ldm { list, .. } => list != 0,
        Instr::Hint(crate::decode::Hint::Nop | crate::decode::Hint::Yield) => true,
        BCond { cond, .. } => cond < 14,
        B { .. } | Bl { .. } => true,
        _ => false,
    }
}

/// True when `instr` always transfers control (nothing falls through it).
fn unconditional(instr: &Instr) -> bool {
    use Instr::*;
    match *instr {
        B { .. } | Bl { .. } | Bx { .. } | Blx { .. } => true,
        Pop { list } => list & 0x8000 != 0,
        AddHi { rdn, .. } => rdn == 15,
        MovHi { rd, .. } => rd == 15,
        _ => false,
    }
}

/// The internal target of a B / B<cond> at `pc`.
fn branch_of(i: &RegionInstr) -> Option<u32> {
    match i.instr {
        Instr::B { offset } | Instr::BCond { offset, .. } => Some(branch_target(i.pc, offset)),
        _ => None,
    }
}

/// Data words `instr` moves (each may wait one cycle for the other core).
pub(crate) fn data_words(instr: &Instr) -> u32 {
    use Instr::*;
    match *instr {
        LdrLit { .. } | MemImm { .. } | MemReg { .. } => 1,
        Push { list } | Pop { list } => list.count_ones(),
        Stm { list, .. } | Ldm { list, .. } => list.count_ones(),
        _ => 0,
    }
}

/// Decodes the region at `entry` (see the module documentation), marking the SRAM pages
/// it comes from as code pages. Returns its instructions and halfwords (the cache key).
pub(crate) fn scan(sys: &mut System, entry: u32) -> (Vec<RegionInstr>, Vec<u16>) {
    let mut instrs = Vec::new();
    let mut halfwords = Vec::new();
    let mut a = entry;
    let mut furthest = entry;
    while instrs.len() < MAX_REGION {
        let Ok((hw1, hw2, size)) = sys.fetch_instr(a) else {
            break;
        };
        let instr = decode(hw1, hw2);
        if !translated(&instr) {
            break;
        }
        for h in [a, a.wrapping_add(size - 2)] {
            if let Some((off, _)) = crate::bus::sram_location(h) {
                sys.code_pages[off >> 8] = true;
            }
        }
        halfwords.push(hw1);
        if size == 4 {
            halfwords.push(hw2);
        }
        let cost = (
            timing::cycles(&instr, false, false),
            timing::cycles(&instr, true, false),
        );
        let i = RegionInstr {
            pc: a,
            size,
            instr,
            cost,
        };
        if let Some(t) = branch_of(&i) {
            if t > a && t.wrapping_sub(entry) < 4 * MAX_REGION as u32 {
                furthest = furthest.max(t);
            }
        }
        instrs.push(i);
        let next = a.wrapping_add(size);
        if next < a || (unconditional(&instr) && furthest < next) {
            break;
        }
        a = next;
    }
    (instrs, halfwords)
}

/// Per instruction, an upper bound on the cycles from its start to the region's next exit
/// or back edge (see the module documentation); `targets[i]` is the index a B / B<cond>
/// jumps to when it stays in the region.
fn bounds(instrs: &[RegionInstr], targets: &[Option<usize>]) -> Vec<u64> {
    let mut bound = vec![0u64; instrs.len() + 1];
    for i in (0..instrs.len()).rev() {
        let ins = &instrs[i];
        let own = ins.cost.0.max(ins.cost.1).max(1) as u64 + data_words(&ins.instr) as u64;
        let fall = if unconditional(&ins.instr) {
            0
        } else {
            bound[i + 1]
        };
        let jump = match targets[i] {
            Some(t) if t > i => bound[t],
            _ => 0,
        };
        bound[i] = own + fall.max(jump);
    }
    bound
}

/// One slot of the region lookup.
#[derive(Clone, Copy)]
struct Slot {
    /// Address and code epoch (as the decode cache's tag); `u64::MAX` is empty.
    tag: u64,
    func: Option<NativeFn>,
    /// Cycles bound from the entry (see [`bounds`]).
    bound: u64,
    /// Times seen uncompiled; [`NEVER`] when the entry is not translated.
    hits: u32,
}

const NEVER: u32 = u32::MAX;

/// A region's address and instruction halfwords.
type RegionKey = (u32, Vec<u16>);

/// The compiled regions: a direct-mapped lookup by address for the current code epoch, and
/// the code itself kept by (address, halfwords) across epochs.
pub(crate) struct Jit {
    slots: Box<[Slot]>,
    compiled: HashMap<RegionKey, Option<(NativeFn, u64)>>,
    module: Option<JITModule>,
    /// Entries seen this many times uncompiled are compiled.
    pub(crate) threshold: u32,
    /// Regions compiled so far (for tests and reports).
    pub(crate) count: u64,
    fctx: FunctionBuilderContext,
}

// SAFETY: the module and the function pointers into it are owned by this `Jit` alone;
// `JITModule` is `Send`, and nothing here is shared between threads.
unsafe impl Send for Jit {}

impl Drop for Jit {
    fn drop(&mut self) {
        if let Some(m) = self.module.take() {
            // SAFETY: the slots and the map holding pointers into the module die with it.
            unsafe { m.free_memory() };
        }
    }
}

#[inline(always)]
fn tag(pc: u32, epoch: u32) -> u64 {
    (epoch as u64) << 32 | pc as u64
}

impl Jit {
    pub(crate) fn new() -> Jit {
        Jit {
            slots: vec![
                Slot {
                    tag: u64::MAX,
                    func: None,
                    bound: 0,
                    hits: 0,
                };
                SLOTS
            ]
            .into_boxed_slice(),
            compiled: HashMap::new(),
            module: None,
            threshold: 16,
            count: 0,
            fctx: FunctionBuilderContext::new(),
        }
    }

    /// The compiled region at `pc` and its bound, compiling it when it has been seen
    /// [`Jit::threshold`] times; `None` while it is cold or when it cannot be compiled.
    #[inline(always)]
    pub(crate) fn lookup(&mut self, sys: &mut System, pc: u32) -> Option<(NativeFn, u64)> {
        let slot = &mut self.slots[((pc >> 1) as usize) & (SLOTS - 1)];
        if slot.tag == tag(pc, sys.code_epoch) {
            if let Some(f) = slot.func {
                return Some((f, slot.bound));
            }
            if slot.hits == NEVER || slot.hits < self.threshold {
                slot.hits = slot.hits.saturating_add((slot.hits != NEVER) as u32);
                return None;
            }
        }
        self.miss(sys, pc)
    }

    #[inline(never)]
    fn miss(&mut self, sys: &mut System, pc: u32) -> Option<(NativeFn, u64)> {
        let index = ((pc >> 1) as usize) & (SLOTS - 1);
        let fresh = self.slots[index].tag != tag(pc, sys.code_epoch);
        let (instrs, halfwords) = scan(sys, pc);
        let mut slot = Slot {
            tag: tag(pc, sys.code_epoch),
            func: None,
            bound: 0,
            hits: 1,
        };
        if instrs.is_empty() {
            slot.hits = NEVER;
        } else if let Some(done) = self.compiled.get(&(pc, halfwords.clone())) {
            match *done {
                Some((f, bound)) => (slot.func, slot.bound) = (Some(f), bound),
                None => slot.hits = NEVER,
            }
        } else if !fresh || self.threshold == 0 {
            if self.compiled.len() >= MAX_COMPILED {
                self.reset();
            }
            let done = self.compile(&instrs);
            self.compiled.insert((pc, halfwords), done);
            match done {
                Some((f, bound)) => (slot.func, slot.bound) = (Some(f), bound),
                None => slot.hits = NEVER,
            }
        }
        self.slots[index] = slot;
        slot.func.map(|f| (f, slot.bound))
    }

    /// Drops every compiled region and frees its memory.
    fn reset(&mut self) {
        self.slots.fill(Slot {
            tag: u64::MAX,
            func: None,
            bound: 0,
            hits: 0,
        });
        self.compiled.clear();
        if let Some(m) = self.module.take() {
            // SAFETY: no slot or map entry points into the module any more.
            unsafe { m.free_memory() };
        }
    }

    fn compile(&mut self, instrs: &[RegionInstr]) -> Option<(NativeFn, u64)> {
        if self.module.is_none() {
            self.module = Some(new_module()?);
        }
        let module = self.module.as_mut()?;
        let pointer = module.target_config().pointer_type();
        let mut sig = Signature::new(module.isa().default_call_conv());
        sig.params.push(AbiParam::new(pointer));
        sig.params.push(AbiParam::new(pointer));
        sig.params.push(AbiParam::new(types::I64));
        sig.returns.push(AbiParam::new(types::I32));
        let name = format!("region{}", self.count);
        let id = module.declare_function(&name, Linkage::Local, &sig).ok()?;
        let mut ctx = module.make_context();
        ctx.func.signature = sig;
        let b = FunctionBuilder::new(&mut ctx.func, &mut self.fctx);
        let (b, bound) = Translator::run(b, instrs);
        b.finalize(module.target_config());
        module.define_function(id, &mut ctx).ok()?;
        module.finalize_definitions().ok()?;
        let code = module.get_finalized_function(id);
        self.count += 1;
        // SAFETY: `code` is the function just defined with the signature above (two
        // pointers and a u64 in, a u32 out, the host's C calling convention), which is
        // `NativeFn`.
        Some((
            unsafe { std::mem::transmute::<*const u8, NativeFn>(code) },
            bound,
        ))
    }
}

fn new_module() -> Option<JITModule> {
    let mut flags = settings::builder();
    flags.set("opt_level", "speed").ok()?;
    flags.set("is_pic", "false").ok()?;
    let isa = cranelift_native::builder()
        .ok()?
        .finish(settings::Flags::new(flags))
        .ok()?;
    Some(JITModule::new(JITBuilder::with_isa(
        isa,
        default_libcall_names(),
    )))
}

/// Runs `f` on `core`: the raw call with the context built from `sys`. Returns why it
/// stopped, the instructions retired and the `q` cycle (see [`Ctx::q`]).
#[inline(always)]
pub(crate) fn call(f: NativeFn, core: &mut Core, sys: &mut System, limit: u64) -> (Exit, u64, u64) {
    let id = core.id & 1;
    let claims = sys.bank_claim.as_mut_ptr() as *mut u64;
    let mut ctx = Ctx {
        sram: sys.sram.as_mut_ptr(),
        flash: sys.flash.as_ptr(),
        code_pages: sys.code_pages.as_ptr() as *const u8,
        // SAFETY (both): `bank_claim` is `[[u64; 2]; BANKS]`; `id` and `1 - id` are 0 or 1.
        claims_self: unsafe { claims.add(id) },
        claims_other: unsafe { claims.add(1 - id) },
        stalls: &mut sys.contention_stalls[id],
        q: 0,
        retired: 0,
    };
    // SAFETY: `f` was compiled by `Jit::compile` for this layout of `Core` and `Ctx`; it
    // reads and writes only the core's registers, flags, cycle, PC, the SRAM and flash
    // bytes at offsets it has bounds-checked against `SRAM_SIZE` / `FLASH_SIZE`, the code
    // page flags of those offsets, the claim table's six banks and the stall counter.
    let exit = unsafe { f(core, &mut ctx, limit) };
    (Exit::from_raw(exit), ctx.retired, ctx.q)
}

/// Flag variables, in `Core` field order.
const N: usize = 0;
const Z: usize = 1;
const C: usize = 2;
const V: usize = 3;

struct Translator<'a> {
    b: FunctionBuilder<'a>,
    mf: MemFlagsData,
    core: Value,
    limit: Value,
    sram: Value,
    flash: Value,
    code_pages: Value,
    claims_self: Value,
    claims_other: Value,
    regs: [Variable; 16],
    flags: [Variable; 4],
    cyc: Variable,
    retired: Variable,
    stalls: Variable,
    q: Variable,
    exit_pc: Variable,
    exit_why: Variable,
    /// Cycles and instructions not yet added to `cyc` / `retired` (straight-line code).
    pend_cyc: u64,
    pend_n: u64,
    exit: Block,
    written: u16,
}

impl<'a> Translator<'a> {
    /// Translates `instrs` (a region from [`scan`], not empty) into `b`; returns the
    /// builder and the bound from the entry.
    fn run(mut b: FunctionBuilder<'a>, instrs: &[RegionInstr]) -> (FunctionBuilder<'a>, u64) {
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
        let flash = ptr(&mut b, offset_of!(Ctx, flash));
        let code_pages = ptr(&mut b, offset_of!(Ctx, code_pages));
        let claims_self = ptr(&mut b, offset_of!(Ctx, claims_self));
        let claims_other = ptr(&mut b, offset_of!(Ctx, claims_other));
        let stalls_ptr = ptr(&mut b, offset_of!(Ctx, stalls));
        let regs = std::array::from_fn(|_| b.declare_var(types::I32));
        let flags = std::array::from_fn(|_| b.declare_var(types::I8));
        let cyc = b.declare_var(types::I64);
        let retired = b.declare_var(types::I64);
        let stalls = b.declare_var(types::I64);
        let q = b.declare_var(types::I64);
        let exit_pc = b.declare_var(types::I32);
        let exit_why = b.declare_var(types::I32);
        for (i, &r) in regs.iter().enumerate() {
            let v = b
                .ins()
                .load(types::I32, mf, core, (offset_of!(Core, r) + 4 * i) as i32);
            b.def_var(r, v);
        }
        let flag_at = [
            offset_of!(Core, n),
            offset_of!(Core, z),
            offset_of!(Core, c),
            offset_of!(Core, v),
        ];
        for (f, at) in flags.iter().zip(flag_at) {
            let v = b.ins().load(types::I8, mf, core, at as i32);
            b.def_var(*f, v);
        }
        let v = b
            .ins()
            .load(types::I64, mf, core, offset_of!(Core, cycle) as i32);
        b.def_var(cyc, v);
        let v = b.ins().load(types::I64, mf, stalls_ptr, 0);
        b.def_var(stalls, v);
        let zero = b.ins().iconst(types::I64, 0);
        b.def_var(retired, zero);
        b.def_var(q, zero);
        let zero32 = b.ins().iconst(types::I32, 0);
        b.def_var(exit_pc, zero32);
        b.def_var(exit_why, zero32);
        let exit = b.create_block();
        let mut t = Translator {
            b,
            mf,
            core,
            limit,
            sram,
            flash,
            code_pages,
            claims_self,
            claims_other,
            regs,
            flags,
            cyc,
            retired,
            stalls,
            q,
            exit_pc,
            exit_why,
            pend_cyc: 0,
            pend_n: 0,
            exit,
            written: 0,
        };
        // A block for each instruction a branch of the region jumps to.
        let mut labels: Vec<Option<Block>> = vec![None; instrs.len()];
        for &t_ in targets.iter().flatten() {
            if labels[t_].is_none() {
                labels[t_] = Some(t.b.create_block());
            }
        }
        let mut live = true;
        for (i, ins) in instrs.iter().enumerate() {
            if let Some(l) = labels[i] {
                if live {
                    t.flush();
                    t.b.ins().jump(l, &[]);
                }
                t.b.switch_to_block(l);
                live = true;
            }
            if !live {
                continue;
            }
            live = t.instr(ins, targets[i].map(|j| (j, labels[j], bound[j], j <= i)));
        }
        if live {
            let end = instrs[instrs.len() - 1];
            t.flush();
            let pc = t.c32(end.pc.wrapping_add(end.size));
            t.leave(pc, Exit::Out);
        }
        // The exit: write back and return.
        t.b.switch_to_block(exit);
        for i in 0..16 {
            if t.written & (1 << i) != 0 {
                let v = t.b.use_var(t.regs[i]);
                t.b.ins()
                    .store(mf, v, core, (offset_of!(Core, r) + 4 * i) as i32);
            }
        }
        let pc = t.b.use_var(exit_pc);
        t.b.ins()
            .store(mf, pc, core, (offset_of!(Core, r) + 4 * 15) as i32);
        for (f, at) in flags.iter().zip(flag_at) {
            let v = t.b.use_var(*f);
            t.b.ins().store(mf, v, core, at as i32);
        }
        let v = t.b.use_var(cyc);
        t.b.ins().store(mf, v, core, offset_of!(Core, cycle) as i32);
        let v = t.b.use_var(stalls);
        t.b.ins().store(mf, v, stalls_ptr, 0);
        let v = t.b.use_var(retired);
        t.b.ins().store(mf, v, ctx, offset_of!(Ctx, retired) as i32);
        let v = t.b.use_var(q);
        t.b.ins().store(mf, v, ctx, offset_of!(Ctx, q) as i32);
        let why = t.b.use_var(exit_why);
        t.b.ins().return_(&[why]);
        t.b.seal_all_blocks();
        (t.b, bound[0])
    }

    fn c32(&mut self, x: u32) -> Value {
        self.b.ins().iconst(types::I32, x as i64)
    }

    fn reg(&mut self, r: u8, pc: u32) -> Value {
        if r == 15 {
            return self.c32(pc.wrapping_add(4));
        }
        self.b.use_var(self.regs[(r & 15) as usize])
    }

    fn set(&mut self, r: u8, v: Value) {
        let r = (r & 15) as usize;
        self.written |= 1 << r;
        self.b.def_var(self.regs[r], v);
    }

    fn flag(&mut self, f: usize) -> Value {
        self.b.use_var(self.flags[f])
    }

    fn set_flag(&mut self, f: usize, v: Value) {
        self.b.def_var(self.flags[f], v);
    }

    fn nz(&mut self, r: Value) {
        let n = self.b.ins().icmp_imm_s(IntCC::SignedLessThan, r, 0);
        let z = self.b.ins().icmp_imm_u(IntCC::Equal, r, 0);
        self.set_flag(N, n);
        self.set_flag(Z, z);
    }

    /// `Core::adds`: `x + y + carry` with N, Z, C and V.
    fn adds(&mut self, x: Value, y: Value, carry: Value) -> Value {
        let ins = self.b.ins();
        let xw = ins.uextend(types::I64, x);
        let yw = self.b.ins().uextend(types::I64, y);
        let cw = self.b.ins().uextend(types::I64, carry);
        let s = self.b.ins().iadd(xw, yw);
        let wide = self.b.ins().iadd(s, cw);
        let r = self.b.ins().ireduce(types::I32, wide);
        let hi = self.b.ins().ushr_imm_u(wide, 32);
        let c = self.b.ins().ireduce(types::I8, hi);
        let a = self.b.ins().bxor(x, r);
        let bb = self.b.ins().bxor(y, r);
        let both = self.b.ins().band(a, bb);
        let v = self.b.ins().icmp_imm_s(IntCC::SignedLessThan, both, 0);
        self.set_flag(C, c);
        self.set_flag(V, v);
        self.nz(r);
        r
    }

    /// `Core::adds(x, y, false)` (ADDS, CMN) in 32-bit operations: the carry is the
    /// unsigned wrap, the overflow the sign rule.
    fn add_flags(&mut self, x: Value, y: Value) -> Value {
        let r = self.b.ins().iadd(x, y);
        let c = self.b.ins().icmp(IntCC::UnsignedLessThan, r, x);
        let a = self.b.ins().bxor(x, r);
        let bb = self.b.ins().bxor(y, r);
        let both = self.b.ins().band(a, bb);
        let v = self.b.ins().icmp_imm_s(IntCC::SignedLessThan, both, 0);
        self.set_flag(C, c);
        self.set_flag(V, v);
        self.nz(r);
        r
    }

    /// `Core::adds(x, !y, true)` (SUBS, CMP, NEGS) in 32-bit operations: the carry is
    /// "no borrow" (`x >= y` unsigned), the overflow the sign rule of a subtraction.
    fn sub_flags(&mut self, x: Value, y: Value) -> Value {
        let r = self.b.ins().isub(x, y);
        let c = self.b.ins().icmp(IntCC::UnsignedGreaterThanOrEqual, x, y);
        let a = self.b.ins().bxor(x, y);
        let bb = self.b.ins().bxor(x, r);
        let both = self.b.ins().band(a, bb);
        let v = self.b.ins().icmp_imm_s(IntCC::SignedLessThan, both, 0);
        self.set_flag(C, c);
        self.set_flag(V, v);
        self.nz(r);
        r
    }

    /// `Core::condition`: 1 when `cond` (0-13) holds.
    fn condition(&mut self, cond: u8) -> Value {
        let (n, z, c, v) = (self.flag(N), self.flag(Z), self.flag(C), self.flag(V));
        let r = match cond >> 1 {
            0 => z,
            1 => c,
            2 => n,
            3 => v,
            4 => {
                let nz_ = self.b.ins().bxor_imm_u(z, 1);
                self.b.ins().band(c, nz_)
            }
            5 => self.b.ins().icmp(IntCC::Equal, n, v),
            _ => {
                let ge = self.b.ins().icmp(IntCC::Equal, n, v);
                let nz_ = self.b.ins().bxor_imm_u(z, 1);
                self.b.ins().band(ge, nz_)
            }
        };
        if cond & 1 == 1 {
            self.b.ins().bxor_imm_u(r, 1)
        } else {
            r
        }
    }

    /// Adds the pending straight-line cycles and instructions to their variables.
    fn flush(&mut self) {
        if self.pend_cyc != 0 {
            let c = self.b.use_var(self.cyc);
            let c = self.b.ins().iadd_imm_s(c, self.pend_cyc as i64);
            self.b.def_var(self.cyc, c);
            self.pend_cyc = 0;
        }
        if self.pend_n != 0 {
            let n = self.b.use_var(self.retired);
            let n = self.b.ins().iadd_imm_s(n, self.pend_n as i64);
            self.b.def_var(self.retired, n);
            self.pend_n = 0;
        }
    }

    /// Jumps to the exit with PC `pc` and reason `why` (pending counts flushed first).
    fn leave(&mut self, pc: Value, why: Exit) {
        self.flush();
        self.b.def_var(self.exit_pc, pc);
        let w = self.b.ins().iconst(types::I32, why as i64);
        self.b.def_var(self.exit_why, w);
        self.b.ins().jump(self.exit, &[]);
    }

    /// Leaves before the instruction at `pc` when `cond` holds (nothing of it done).
    fn general_if(&mut self, cond: Value, pc: u32) {
        self.flush();
        let out = self.b.create_block();
        let on = self.b.create_block();
        self.b.ins().brif(cond, out, &[], on, &[]);
        self.b.switch_to_block(out);
        let p = self.c32(pc);
        self.leave(p, Exit::General);
        self.b.switch_to_block(on);
    }

    /// Counts a completed instruction of `cycles` static cycles (plus `wait` dynamic ones),
    /// recording its end as `q` when it took two cycles or more.
    fn retire(&mut self, cycles: u32, wait: Option<Value>) {
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
    fn goto(&mut self, target: u32, internal: Option<(usize, Option<Block>, u64, bool)>) {
        self.flush();
        match internal {
            Some((_, Some(label), bound, back)) => {
                if back {
                    // Every instruction up to the next exit or back edge starts before the
                    // limit when `cycle + bound <= limit`.
                    let c = self.b.use_var(self.cyc);
                    let end = self.b.ins().iadd_imm_s(c, bound as i64);
                    let fits = self
                        .b
                        .ins()
                        .icmp(IntCC::UnsignedLessThanOrEqual, end, self.limit);
                    let stop = self.b.create_block();
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
    fn instr(
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
                let r = if imm == 0 {
                    x
                } else {
                    let bit = self.b.ins().ushr_imm_u(x, 32 - imm as i64);
                    let bit = self.b.ins().band_imm_u(bit, 1);
                    let c = self.b.ins().ireduce(types::I8, bit);
                    self.set_flag(C, c);
                    self.b.ins().ishl_imm_u(x, imm as i64)
                };
                self.set(rd, r);
                self.nz(r);
            }
            LsrImm { rd, rm, imm } => {
                let x = self.reg(rm, pc);
                let bit = self.b.ins().ushr_imm_u(x, imm as i64 - 1);
                let bit = self.b.ins().band_imm_u(bit, 1);
                let c = self.b.ins().ireduce(types::I8, bit);
                self.set_flag(C, c);
                let r = if imm == 32 {
                    self.c32(0)
                } else {
                    self.b.ins().ushr_imm_u(x, imm as i64)
                };
                self.set(rd, r);
                self.nz(r);
            }
            AsrImm { rd, rm, imm } => {
                let x = self.reg(rm, pc);
                let bit = self.b.ins().sshr_imm_u(x, imm as i64 - 1);
                let bit = self.b.ins().band_imm_u(bit, 1);
                let c = self.b.ins().ireduce(types::I8, bit);
                self.set_flag(C, c);
                let r = self.b.ins().sshr_imm_u(x, (imm as i64).min(31));
                self.set(rd, r);
                self.nz(r);
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
                let odd = self.b.ins().band_imm_u(target, 1);
                let even = self.b.ins().icmp_imm_u(IntCC::Equal, odd, 0);
                let bad = if let Bx { .. } = ins.instr {
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
                } else {
                    even
                };
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
                self.retire(base, Some(wait));
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
                self.retire(base, Some(wait));
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

    /// POP (`rn` 13) or LDM: the words, the base write-back (LDM: unless the base is
    /// loaded), the registers, and for POP {…, pc} the branch; false when it branched.
    fn load_multiple(&mut self, ins: &RegionInstr, rn: u8, list: u16) -> bool {
        let count = list.count_ones();
        let start = self.reg(rn, ins.pc);
        let pops_pc = rn == 13 && list & 0x8000 != 0;
        let (loaded, wait, _) = self.multiple(ins, start, count, None, pops_pc);
        if rn == 13 || list & (1 << rn) == 0 {
            let end = self.b.ins().iadd_imm_s(start, 4 * count as i64);
            self.set(rn, end);
        }
        let regs: Vec<u8> = (0..16u8).filter(|r| list & (1 << r) != 0).collect();
        let mut target = None;
        for (&r, &v) in regs.iter().zip(&loaded) {
            if r == 15 {
                target = Some(self.b.ins().band_imm_u(v, !1u32 as i64));
            } else {
                self.set(r, v);
            }
        }
        self.retire(ins.cost.0, Some(wait));
        match target {
            Some(t) => {
                self.leave(t, Exit::Out);
                false
            }
            None => true,
        }
    }

    /// `Core::alu`: the ALU group on `Rdn` and `m`.
    fn alu(&mut self, op: AluOp, rdn: u8, m: Value) {
        let x = self.reg(rdn, 0);
        let r = match op {
            AluOp::And => self.b.ins().band(x, m),
            AluOp::Eor => self.b.ins().bxor(x, m),
            AluOp::Orr => self.b.ins().bor(x, m),
            AluOp::Bic => self.b.ins().band_not(x, m),
            AluOp::Mvn => self.b.ins().bnot(m),
            AluOp::Mul => self.b.ins().imul(m, x),
            AluOp::Tst => {
                let r = self.b.ins().band(x, m);
                self.nz(r);
                return;
            }
            AluOp::Lsl | AluOp::Lsr | AluOp::Asr => {
                // Shift by the bottom byte of Rm, through a 64-bit word (see the
                // module tests): the carry is the last bit shifted out.
                let s = self.b.ins().band_imm_u(m, 0xff);
                let s33 = self.c32(33);
                let s = self.b.ins().umin(s, s33);
                let s64 = self.b.ins().uextend(types::I64, s);
                let (r, c) = match op {
                    AluOp::Lsl => {
                        let w = self.b.ins().uextend(types::I64, x);
                        let w = self.b.ins().ishl(w, s64);
                        let r = self.b.ins().ireduce(types::I32, w);
                        let c = self.b.ins().ushr_imm_u(w, 32);
                        let c = self.b.ins().band_imm_u(c, 1);
                        (r, c)
                    }
                    _ => {
                        let w = if op == AluOp::Lsr {
                            self.b.ins().uextend(types::I64, x)
                        } else {
                            self.b.ins().sextend(types::I64, x)
                        };
                        let w = self.b.ins().ishl_imm_u(w, 1);
                        let u = if op == AluOp::Lsr {
                            self.b.ins().ushr(w, s64)
                        } else {
                            self.b.ins().sshr(w, s64)
                        };
                        let r = self.b.ins().sshr_imm_u(u, 1);
                        let r = self.b.ins().ireduce(types::I32, r);
                        let c = self.b.ins().band_imm_u(u, 1);
                        (r, c)
                    }
                };
                let c = self.b.ins().ireduce(types::I8, c);
                let zero = self.b.ins().icmp_imm_u(IntCC::Equal, s, 0);
                let old = self.flag(C);
                let c = self.b.ins().select(zero, old, c);
                self.set_flag(C, c);
                r
            }
            AluOp::Ror => {
                let s = self.b.ins().band_imm_u(m, 0xff);
                let s31 = self.b.ins().band_imm_u(m, 31);
                let r = self.b.ins().rotr(x, s31);
                let c = self.b.ins().icmp_imm_s(IntCC::SignedLessThan, r, 0);
                let zero = self.b.ins().icmp_imm_u(IntCC::Equal, s, 0);
                let old = self.flag(C);
                let c = self.b.ins().select(zero, old, c);
                self.set_flag(C, c);
                r
            }
            AluOp::Cmp => {
                self.sub_flags(x, m);
                return;
            }
            AluOp::Cmn => {
                self.add_flags(x, m);
                return;
            }
            AluOp::Rsb => {
                let zero = self.c32(0);
                let r = self.sub_flags(zero, m);
                self.set(rdn, r);
                return;
            }
            AluOp::Adc | AluOp::Sbc => {
                let (a, b, carry) = match op {
                    AluOp::Adc => (x, m, self.flag(C)),
                    _ => (x, self.b.ins().bnot(m), self.flag(C)),
                };
                let r = self.adds(a, b, carry);
                self.set(rdn, r);
                return;
            }
        };
        self.set(rdn, r);
        self.nz(r);
    }

    /// The SRAM arbiter for the access to offset `off` at data cycle `at`: the wait (0 or
    /// 1, i64) after claiming the bank (`System::arbitrate_fast`).
    fn arbitrate(&mut self, off: Value, at: Value) -> Value {
        let striped = self
            .b
            .ins()
            .icmp_imm_u(IntCC::UnsignedLessThan, off, 0x4_0000);
        let b0 = self.b.ins().ushr_imm_u(off, 2);
        let b0 = self.b.ins().band_imm_u(b0, 3);
        let b1 = self.b.ins().ushr_imm_u(off, 12);
        let b1 = self.b.ins().band_imm_u(b1, 1);
        let b1 = self.b.ins().iadd_imm_s(b1, 4);
        let bank = self.b.ins().select(striped, b0, b1);
        let bank = self.b.ins().uextend(types::I64, bank);
        let boff = self.b.ins().ishl_imm_u(bank, 4);
        let other_at = self.b.ins().iadd(self.claims_other, boff);
        let other = self.b.ins().load(types::I64, self.mf, other_at, 0);
        let hit = self.b.ins().icmp(IntCC::Equal, other, at);
        let wait = self.b.ins().uextend(types::I64, hit);
        let claim = self.b.ins().iadd(at, wait);
        let self_at = self.b.ins().iadd(self.claims_self, boff);
        self.b.ins().store(self.mf, claim, self_at, 0);
        let s = self.b.use_var(self.stalls);
        let s = self.b.ins().iadd(s, wait);
        self.b.def_var(self.stalls, s);
        wait
    }

    /// A single load or store (`Core::mem_fast`): SRAM (striped, SRAM4/5 or the
    /// non-striped aliases) or a flash load; anything else leaves before it.
    fn mem(&mut self, ins: &RegionInstr, op: MemOp, rt: u8, addr: Value) -> bool {
        let pc = ins.pc;
        let size = op.size();
        self.flush();
        if size > 1 {
            let low = self.b.ins().band_imm_u(addr, size as i64 - 1);
            self.general_if(low, pc);
        }
        let in_sram = self.b.create_block();
        self.b.append_block_param(in_sram, types::I32);
        let join = self.b.create_block();
        self.b.append_block_param(join, types::I32);
        self.b.append_block_param(join, types::I64);
        let alias = self.b.create_block();
        let off = self.b.ins().iadd_imm_s(addr, -(SRAM_BASE as i64));
        let ok = self
            .b
            .ins()
            .icmp_imm_u(IntCC::UnsignedLessThan, off, SRAM_SIZE as i64);
        self.b
            .ins()
            .brif(ok, in_sram, &[BlockArg::Value(off)], alias, &[]);
        // The non-striped alias of SRAM0-3.
        self.b.switch_to_block(alias);
        let al = self.b.ins().iadd_imm_s(addr, -(SRAM_ALIAS_BASE as i64));
        let ok = self
            .b
            .ins()
            .icmp_imm_u(IntCC::UnsignedLessThan, al, 0x4_0000);
        let bank = self.b.ins().ushr_imm_u(al, 16);
        let word = self.b.ins().band_imm_u(al, 0xffff);
        let word = self.b.ins().ushr_imm_u(word, 2);
        let word = self.b.ins().ishl_imm_u(word, 2);
        let phys = self.b.ins().iadd(word, bank);
        let phys = self.b.ins().ishl_imm_u(phys, 2);
        let low = self.b.ins().band_imm_u(al, 3);
        let phys = self.b.ins().bor(phys, low);
        let elsewhere = self.b.create_block();
        self.b
            .ins()
            .brif(ok, in_sram, &[BlockArg::Value(phys)], elsewhere, &[]);
        self.b.switch_to_block(elsewhere);
        if op.is_store() {
            let p = self.c32(pc);
            self.leave(p, Exit::General);
        } else {
            let f = self.b.ins().iadd_imm_s(addr, -(FLASH_BASE as i64));
            let ok = self
                .b
                .ins()
                .icmp_imm_u(IntCC::UnsignedLessThan, f, FLASH_SIZE as i64);
            let in_flash = self.b.create_block();
            let out = self.b.create_block();
            self.b.ins().brif(ok, in_flash, &[], out, &[]);
            self.b.switch_to_block(out);
            let p = self.c32(pc);
            self.leave(p, Exit::General);
            self.b.switch_to_block(in_flash);
            let f64_ = self.b.ins().uextend(types::I64, f);
            let at = self.b.ins().iadd(self.flash, f64_);
            let v = self.load_sized(op, at);
            let zero = self.b.ins().iconst(types::I64, 0);
            self.b
                .ins()
                .jump(join, &[BlockArg::Value(v), BlockArg::Value(zero)]);
        }
        // SRAM: the arbiter, then the data.
        self.b.switch_to_block(in_sram);
        let off = self.b.block_params(in_sram)[0];
        let c = self.b.use_var(self.cyc);
        let at = self.b.ins().iadd_imm_s(c, 1);
        let wait = self.arbitrate(off, at);
        let off64 = self.b.ins().uextend(types::I64, off);
        let p = self.b.ins().iadd(self.sram, off64);
        if op.is_store() {
            let v = self.reg(rt, pc);
            match size {
                1 => self.b.ins().istore8(self.mf, v, p, 0),
                2 => self.b.ins().istore16(self.mf, v, p, 0),
                _ => self.b.ins().store(self.mf, v, p, 0),
            };
            let page = self.b.ins().ushr_imm_u(off64, 8);
            let pp = self.b.ins().iadd(self.code_pages, page);
            let code = self.b.ins().uload8(types::I32, self.mf, pp, 0);
            self.b
                .ins()
                .jump(join, &[BlockArg::Value(code), BlockArg::Value(wait)]);
        } else {
            let v = self.load_sized(op, p);
            self.b
                .ins()
                .jump(join, &[BlockArg::Value(v), BlockArg::Value(wait)]);
        }
        self.b.switch_to_block(join);
        let v = self.b.block_params(join)[0];
        let wait = self.b.block_params(join)[1];
        if !op.is_store() {
            self.set(rt, v);
        }
        self.retire(ins.cost.0, Some(wait));
        if op.is_store() {
            self.invalidate_if(v, ins);
        }
        true
    }

    /// After a store: leaves with [`Exit::Invalidate`] when it hit a code page.
    fn invalidate_if(&mut self, code: Value, ins: &RegionInstr) {
        let out = self.b.create_block();
        let on = self.b.create_block();
        self.flush();
        self.b.ins().brif(code, out, &[], on, &[]);
        self.b.switch_to_block(out);
        let p = self.c32(ins.pc.wrapping_add(ins.size));
        self.leave(p, Exit::Invalidate);
        self.b.switch_to_block(on);
    }

    fn load_sized(&mut self, op: MemOp, p: Value) -> Value {
        let mf = self.mf;
        match op {
            MemOp::Ldrb => self.b.ins().uload8(types::I32, mf, p, 0),
            MemOp::Ldrsb => self.b.ins().sload8(types::I32, mf, p, 0),
            MemOp::Ldrh => self.b.ins().uload16(types::I32, mf, p, 0),
            MemOp::Ldrsh => self.b.ins().sload16(types::I32, mf, p, 0),
            _ => self.b.ins().load(types::I32, mf, p, 0),
        }
    }

    /// `count` consecutive words from `start` (PUSH, POP, STM, LDM: `push_fast`,
    /// `pop_fast` and the `Stm`/`Ldm` arms of `execute_fast`): all in the striped view or
    /// SRAM4/5 and word-aligned, else it leaves before the instruction. Stores `values`,
    /// or loads the words; with `pops_pc`, a PC word that would leave Thumb state or return
    /// from an exception leaves before the instruction. Returns the loaded words, the
    /// wait states and whether a store hit a code page; the caller retires it.
    fn multiple(
        &mut self,
        ins: &RegionInstr,
        start: Value,
        count: u32,
        values: Option<&[Value]>,
        pops_pc: bool,
    ) -> (Vec<Value>, Value, Value) {
        let pc = ins.pc;
        self.flush();
        let off = self.b.ins().iadd_imm_s(start, -(SRAM_BASE as i64));
        let low = self.b.ins().band_imm_u(start, 3);
        let too_far = self.b.ins().icmp_imm_u(
            IntCC::UnsignedGreaterThan,
            off,
            (SRAM_SIZE - 4 * count) as i64,
        );
        let too_far = too_far.into_i32(&mut self.b);
        let bad = self.b.ins().bor(low, too_far);
        self.general_if(bad, pc);
        let off64 = self.b.ins().uextend(types::I64, off);
        let base_p = self.b.ins().iadd(self.sram, off64);
        if pops_pc {
            let t = self
                .b
                .ins()
                .load(types::I32, self.mf, base_p, 4 * (count as i32 - 1));
            let odd = self.b.ins().band_imm_u(t, 1);
            let even = self.b.ins().icmp_imm_u(IntCC::Equal, odd, 0);
            let ipsr = self.b.ins().load(
                types::I32,
                self.mf,
                self.core,
                offset_of!(Core, ipsr) as i32,
            );
            let handler = self.b.ins().icmp_imm_u(IntCC::NotEqual, ipsr, 0);
            let top = self.b.ins().ushr_imm_u(t, 28);
            let exc = self.b.ins().icmp_imm_u(IntCC::Equal, top, 0xf);
            let ret = self.b.ins().band(handler, exc);
            let bad = self.b.ins().bor(even, ret);
            self.general_if(bad, pc);
        }
        let c = self.b.use_var(self.cyc);
        let mut at = self.b.ins().iadd_imm_s(c, 1);
        let mut total = self.b.ins().iconst(types::I64, 0);
        let mut loaded = Vec::new();
        let mut code = self.b.ins().iconst(types::I32, 0);
        for k in 0..count {
            let o = self.b.ins().iadd_imm_s(off, 4 * k as i64);
            let wait = self.arbitrate(o, at);
            total = self.b.ins().iadd(total, wait);
            let step = self.b.ins().iadd_imm_s(wait, 1);
            at = self.b.ins().iadd(at, step);
            match values {
                Some(vs) => {
                    self.b
                        .ins()
                        .store(self.mf, vs[k as usize], base_p, 4 * k as i32);
                    let o64 = self.b.ins().uextend(types::I64, o);
                    let page = self.b.ins().ushr_imm_u(o64, 8);
                    let pp = self.b.ins().iadd(self.code_pages, page);
                    let hit = self.b.ins().uload8(types::I32, self.mf, pp, 0);
                    code = self.b.ins().bor(code, hit);
                }
                None => {
                    let v = self.b.ins().load(types::I32, self.mf, base_p, 4 * k as i32);
                    loaded.push(v);
                }
            }
        }
        (loaded, total, code)
    }
}

/// `icmp` results are `i8`; widen one to `i32` to combine it with a word.
trait IntoI32 {
    fn into_i32(self, b: &mut FunctionBuilder) -> Value;
}

impl IntoI32 for Value {
    fn into_i32(self, b: &mut FunctionBuilder) -> Value {
        b.ins().uextend(types::I32, self)
    }
}
