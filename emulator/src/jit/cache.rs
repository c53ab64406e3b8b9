//! The compiled regions: a direct-mapped lookup by address and code epoch, the compile
//! threshold, the code kept by (address, instruction halfwords) across invalidations, and
//! the cranelift module that owns the machine code.

use super::abi::NativeFn;
use super::scan::{scan, RegionInstr};
use super::translate::{Flavour, Translator};
use crate::bus::System;
use cranelift_codegen::ir::{types, AbiParam, Signature};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, Linkage, Module};
use std::collections::HashMap;

/// Compiled regions kept before all are dropped (and their memory freed).
const MAX_COMPILED: usize = 8192;

/// Slots of the direct-mapped region lookup (by address).
const SLOTS: usize = 1 << 14;

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
    /// SRAM banks its instructions are fetched from (bit per bank).
    banks: u8,
}

/// A compiled region found by [`Jit::lookup`].
#[derive(Clone, Copy)]
pub(crate) struct Region {
    /// The native code.
    pub(crate) f: NativeFn,
    /// Cycles bound from the entry (see `scan::bounds`).
    pub(crate) bound: u64,
    /// SRAM banks its instructions are fetched from (bit per bank; flash and ROM none).
    pub(crate) banks: u8,
}

const EMPTY: Slot = Slot {
    tag: u64::MAX,
    func: None,
    bound: 0,
    hits: 0,
    banks: 0,
};

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
    /// Which variant of each region this cache compiles.
    flavour: Flavour,
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
    /// An empty cache compiling regions of `flavour`.
    pub(crate) fn new(flavour: Flavour) -> Jit {
        Jit {
            flavour,
            slots: vec![EMPTY; SLOTS].into_boxed_slice(),
            compiled: HashMap::new(),
            module: None,
            threshold: 16,
            count: 0,
            fctx: FunctionBuilderContext::new(),
        }
    }

    /// The compiled region at `pc`, compiling it when it has been seen
    /// [`Jit::threshold`] times; `None` while it is cold or when it cannot be compiled.
    #[inline(always)]
    pub(crate) fn lookup(&mut self, sys: &mut System, pc: u32) -> Option<Region> {
        let slot = &mut self.slots[((pc >> 1) as usize) & (SLOTS - 1)];
        if slot.tag == tag(pc, sys.code_epoch) {
            if let Some(f) = slot.func {
                return Some(Region {
                    f,
                    bound: slot.bound,
                    banks: slot.banks,
                });
            }
            if slot.hits == NEVER || slot.hits < self.threshold {
                slot.hits = slot.hits.saturating_add((slot.hits != NEVER) as u32);
                return None;
            }
        }
        self.miss(sys, pc)
    }

    #[inline(never)]
    fn miss(&mut self, sys: &mut System, pc: u32) -> Option<Region> {
        let index = ((pc >> 1) as usize) & (SLOTS - 1);
        let fresh = self.slots[index].tag != tag(pc, sys.code_epoch);
        let (instrs, halfwords) = scan(sys, pc);
        let mut slot = Slot {
            tag: tag(pc, sys.code_epoch),
            func: None,
            bound: 0,
            hits: 1,
            banks: 0,
        };
        for i in &instrs {
            for h in [i.pc, i.pc.wrapping_add(i.size - 2)] {
                if let Some((_, bank)) = crate::bus::sram_location(h) {
                    slot.banks |= 1 << bank;
                }
            }
        }
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
        slot.func.map(|f| Region {
            f,
            bound: slot.bound,
            banks: slot.banks,
        })
    }

    /// Drops every compiled region and frees its memory.
    fn reset(&mut self) {
        self.slots.fill(EMPTY);
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
        let (b, bound) = Translator::run(b, instrs, self.flavour);
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
    // The translator's output is checked by the differential tests; the verifier would
    // cost a tenth of every compile.
    flags.set("enable_verifier", "false").ok()?;
    let isa = cranelift_native::builder()
        .ok()?
        .finish(settings::Flags::new(flags))
        .ok()?;
    Some(JITModule::new(JITBuilder::with_isa(
        isa,
        default_libcall_names(),
    )))
}
