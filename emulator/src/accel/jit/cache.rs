//! The compiled regions: a direct-mapped lookup per board by address and code epoch, the
//! compile threshold, and one store of machine code for the whole process, kept by
//! (flavour, address, instruction halfwords) — so the boards of a keyboard that run the
//! same firmware (or the same code at the same address) compile each region once, on
//! whichever rayon thread meets it first, and a board finds it compiled at first sight.
//!
//! **Why sharing is sound.** A region's native code depends only on its flavour, address
//! and instruction halfwords (the translator reads nothing else: the board's memory,
//! registers and claims reach it through the call's arguments), so code compiled for one
//! board is the code any other would compile. The store is a `Mutex`; the code itself is
//! read-only once finalized and is called from any thread.
//!
//! **Memory.** Machine code lives in cranelift modules (*chunks*); the store compiles into
//! its current chunk and starts a new one after [`MAX_COMPILED`] regions. Each board holds
//! an `Arc` of every chunk its lookup slots point into, so a chunk is freed when the store
//! and the last board that used it have let it go.

use super::abi::NativeFn;
use super::scan::{scan, RegionInstr};
use super::translate::{Flavour, Translator};
use crate::system::System;
use cranelift_codegen::ir::{types, AbiParam, Signature};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, Linkage, Module};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

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

/// A region's flavour, address and instruction halfwords.
type RegionKey = (Flavour, u32, Vec<u16>);

/// One cranelift module's machine code, freed when the last holder drops it.
struct Chunk(Mutex<Option<JITModule>>);

// SAFETY: the module is only touched under its mutex (compiling, freeing); the finalized
// code it owns is immutable and callable from any thread.
unsafe impl Send for Chunk {}
// SAFETY: as above.
unsafe impl Sync for Chunk {}

impl Drop for Chunk {
    fn drop(&mut self) {
        let module = self
            .0
            .get_mut()
            .map(Option::take)
            .unwrap_or_else(|e| e.into_inner().take());
        if let Some(m) = module {
            // SAFETY: every holder of a pointer into the module holds this chunk's `Arc`
            // (the store's map, the boards' lookups), and this is the last one.
            unsafe { m.free_memory() };
        }
    }
}

/// The process's store of compiled regions (see the module documentation).
struct Store {
    /// Regions compiled into `chunk` (`None`: the region cannot be compiled).
    compiled: HashMap<RegionKey, Option<(NativeFn, u64)>>,
    chunk: Arc<Chunk>,
    fctx: FunctionBuilderContext,
    /// Functions defined so far (their symbol names).
    defined: u64,
}

// SAFETY: the function pointers point into `chunk`'s finalized code (see `Chunk`); the
// builder context is plain data.
unsafe impl Send for Store {}

fn store() -> &'static Mutex<Store> {
    static STORE: OnceLock<Mutex<Store>> = OnceLock::new();
    STORE.get_or_init(|| {
        Mutex::new(Store {
            compiled: HashMap::new(),
            chunk: Arc::new(Chunk(Mutex::new(None))),
            fctx: FunctionBuilderContext::new(),
            defined: 0,
        })
    })
}

/// A board's compiled regions of one flavour: a direct-mapped lookup by address for the
/// current code epoch, into code from the process's store.
pub(crate) struct Jit {
    slots: Box<[Slot]>,
    /// The chunks the slots point into (kept alive while they do).
    chunks: Vec<Arc<Chunk>>,
    /// Entries seen this many times uncompiled are compiled (or taken from the store, where
    /// another board may have compiled them already).
    pub(crate) threshold: u32,
    /// Regions this board has taken native code for so far (for tests and reports).
    pub(crate) count: u64,
    /// Which variant of each region this cache holds.
    flavour: Flavour,
    /// Addresses no region runs through (sorted, Thumb bit clear): the memoized spans' entries
    /// ([`crate::accel::memo`]), which a core must reach at a dispatch for its memo to be
    /// tried ([`Jit::set_stops`]).
    stops: Arc<[u32]>,
}

/// Chunks a board's lookup may hold before it forgets them all.
const MAX_CHUNKS: usize = 4;

#[inline(always)]
fn tag(pc: u32, epoch: u32) -> u64 {
    (epoch as u64) << 32 | pc as u64
}

impl Jit {
    /// The variant of each region this cache holds.
    pub(crate) fn flavour(&self) -> Flavour {
        self.flavour
    }

    /// An empty cache compiling regions of `flavour`.
    pub(crate) fn new(flavour: Flavour) -> Jit {
        Jit {
            flavour,
            slots: vec![EMPTY; SLOTS].into_boxed_slice(),
            chunks: Vec::new(),
            // 64 rather than 16: fewer regions compiled that then run little (the demo:
            // 17.10 → 17.04 G host instructions plain, 21.80 → 21.72 G on rp2040_io).
            threshold: 64,
            count: 0,
            stops: Arc::from([]),
        }
    }

    /// Addresses no region runs through from now on (sorted, Thumb bit clear; see
    /// [`super::scan::scan`]): the regions looked up so far are forgotten, since one may
    /// run through a new stop.
    pub(crate) fn set_stops(&mut self, stops: Arc<[u32]>) {
        self.stops = stops;
        self.slots.fill(EMPTY);
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
        let (instrs, halfwords) = scan(sys, pc, &self.stops);
        let mut slot = Slot {
            tag: tag(pc, sys.code_epoch),
            func: None,
            bound: 0,
            hits: 1,
            banks: 0,
        };
        for i in &instrs {
            for h in [i.pc, i.pc.wrapping_add(i.size - 2)] {
                if let Some((_, bank)) = tactus_rp2040::memory::sram_location(h) {
                    slot.banks |= 1 << bank;
                }
            }
        }
        if instrs.is_empty() {
            slot.hits = NEVER;
        } else {
            let fetch = !fresh || self.threshold == 0;
            let key = (self.flavour, pc, halfwords);
            match self.take_from_store(key, &instrs, fetch) {
                Some(Some((f, bound))) => {
                    (slot.func, slot.bound) = (Some(f), bound);
                    self.count += 1;
                }
                Some(None) => slot.hits = NEVER,
                None => {}
            }
        }
        self.slots[index] = slot;
        slot.func.map(|f| Region {
            f,
            bound: slot.bound,
            banks: slot.banks,
        })
    }

    /// The store's code for `key`, compiled now when `compile` (else `None` when it is not
    /// there yet); `Some(None)` when the region cannot be compiled. Keeps the chunk alive.
    fn take_from_store(
        &mut self,
        key: RegionKey,
        instrs: &[RegionInstr],
        compile: bool,
    ) -> Option<Option<(NativeFn, u64)>> {
        // A poisoned store (a panic while compiling) is still consistent: a map entry is
        // inserted only after its code is finalized.
        let mut store = store().lock().unwrap_or_else(|e| e.into_inner());
        let done = match store.compiled.get(&key) {
            Some(&done) => done,
            None if !compile => return None,
            None => {
                if store.compiled.len() >= MAX_COMPILED {
                    store.compiled.clear();
                    store.chunk = Arc::new(Chunk(Mutex::new(None)));
                }
                let done = store.compile(instrs, self.flavour);
                store.compiled.insert(key, done);
                done
            }
        };
        if done.is_some() && !self.chunks.iter().any(|c| Arc::ptr_eq(c, &store.chunk)) {
            if self.chunks.len() >= MAX_CHUNKS {
                // Forget every slot before letting their chunks go.
                self.slots.fill(EMPTY);
                self.chunks.clear();
            }
            self.chunks.push(store.chunk.clone());
        }
        Some(done)
    }
}

impl Store {
    fn compile(&mut self, instrs: &[RegionInstr], flavour: Flavour) -> Option<(NativeFn, u64)> {
        let chunk = self.chunk.clone();
        let mut guard = chunk.0.lock().unwrap_or_else(|e| e.into_inner());
        if guard.is_none() {
            *guard = Some(new_module()?);
        }
        let module = guard.as_mut()?;
        let pointer = module.target_config().pointer_type();
        let mut sig = Signature::new(module.isa().default_call_conv());
        sig.params.push(AbiParam::new(pointer));
        sig.params.push(AbiParam::new(pointer));
        sig.params.push(AbiParam::new(types::I64));
        sig.returns.push(AbiParam::new(types::I32));
        let name = format!("region{}", self.defined);
        self.defined += 1;
        let id = module.declare_function(&name, Linkage::Local, &sig).ok()?;
        let mut ctx = module.make_context();
        ctx.func.signature = sig;
        let b = FunctionBuilder::new(&mut ctx.func, &mut self.fctx);
        let (b, bound) = Translator::run(b, instrs, flavour);
        b.finalize(module.target_config());
        module.define_function(id, &mut ctx).ok()?;
        // `TACTUS_JIT_DUMP=dir`: each region's machine code, for reading with
        // `objdump -D -b binary -m i386:x86-64 dir/region0-Solo.bin`.
        if let Ok(dir) = std::env::var("TACTUS_JIT_DUMP") {
            if let Some(cc) = ctx.compiled_code() {
                let _ = std::fs::write(format!("{dir}/{name}-{flavour:?}.bin"), cc.code_buffer());
            }
        }
        module.finalize_definitions().ok()?;
        let code = module.get_finalized_function(id);
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
