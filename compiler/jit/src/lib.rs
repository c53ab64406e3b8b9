//! Two JITs of the Tactus IR with Cranelift, each computing, sample by sample, exactly what
//! its reference interpreter computes:
//!
//! * the **f64 JIT** ([`JitProgram`], [`JitInstance`]) — bit-identical to the f64 reference
//!   interpreter (`tactus_compiler::interp`); documented below;
//! * the **fixed-point JIT** ([`FixedJitProgram`], [`FixedJitInstance`], module [`fixed`])
//!   — bit-identical to the fixed interpreter (`tactus_compiler::fixed::interp`), with the
//!   sample loop and the differentiator histories in native code so that a block of samples
//!   is one call ([`FixedJitInstance::run_block`]).
//!
//! Both share the IR verifier ([`verify`]), the slot numbering of states, modes, edges and
//! outputs ([`layout::Layout`]) and the Cranelift module setup.
//!
//! [`JitProgram::compile`] verifies a [`Program`] ([`verify`]), fixes where every quantity
//! lives ([`layout::Layout`]) and translates the body into one native function
//! ([`codegen`]); [`JitInstance`] is the harness around it with the interpreter's API.
//!
//! # Calling convention (f64)
//!
//! ```text
//! extern "C" fn(ctx: *mut f64, inputs: *const f64, out: *mut f64, sat: *mut u64)
//! ```
//!
//! One call runs one sample. The buffers (slot layout in [`layout`]):
//! * `ctx` — states, modes (variant index as `f64`), edge memories (0.0/1.0); read on
//!   entry, written back on exit, so it carries the instance from sample to sample;
//! * `inputs` — this sample's sensor readings, already saturated to their declared ranges,
//!   then the `d()`/`d2()` values the program reads;
//! * `out` — force terms, total, outputs, then one slot per `emit` statement: a flag
//!   (1.0 = fired) and the arguments;
//! * `sat` — one saturation counter per state, incremented when a write is saturated.
//!
//! The native code does no allocation, no bounds checks (the layout and the verifier
//! guarantee every access is in bounds) and calls nothing but the host function behind
//! `exp` (and, in the fixed-point build, the ones behind `exp` and `sqrt`).
//!
//! # What the harness does
//!
//! Exactly the parts of `interp::Instance::step` that are not the body: saturate each
//! reading to its sensor's range (a missing or NaN reading reads the lower bound), push it
//! into the sensor's [`Differentiator`] when the sensor is differentiated, compute the
//! derivatives the program reads with the same [`Differentiator`] methods, call the native
//! code, and gather the fired event slots, in slot order, into [`SampleOut::events`].
#![deny(missing_docs)]

pub mod codegen;
pub mod fixed;
pub mod fixed_codegen;
pub mod layout;
pub mod verify;

use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::FunctionBuilderContext;
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, Linkage, Module};
pub use fixed::{FixedJitInstance, FixedJitProgram};
use layout::Layout;
use tactus_compiler::interp::SampleOut;
use tactus_compiler::ir::{Program, Value};
use tactus_runtime::differentiator::Differentiator;

/// Why a program could not be compiled.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum JitError {
    /// A value is used where no definition of it is in scope (front-end bug).
    #[error("value {value} is used where it is not defined (IR invariant: its definition precedes every use)")]
    UndefinedValue {
        /// The value.
        value: Value,
    },
    /// A value is defined twice (front-end bug).
    #[error("value {value} is defined twice (IR invariant: exactly one definition)")]
    Redefined {
        /// The value.
        value: Value,
    },
    /// An index into one of the program's tables is out of range (front-end bug).
    #[error("{kind} index {index} is out of range (the program has {len})")]
    BadIndex {
        /// Which table (`"state"`, `"value"`, …).
        kind: &'static str,
        /// The index.
        index: usize,
        /// The table's length.
        len: usize,
    },
    /// A declared range is not `lo <= hi` (or has a NaN bound).
    #[error("{kind} `{name}` has the invalid range [{lo}, {hi}]")]
    BadRange {
        /// `"sensor"` or `"state"`.
        kind: &'static str,
        /// Its name.
        name: String,
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// A buffer would be too large for 32-bit displacements.
    #[error("the program is too large for the JIT ({slots} slots in one buffer)")]
    TooLarge {
        /// Slots in the largest buffer.
        slots: usize,
    },
    /// Cranelift does not support the host, or rejected its settings.
    #[error("host not supported by Cranelift: {0}")]
    Host(String),
    /// Cranelift failed to compile or link the function (a JIT bug).
    #[error("code generation failed: {0}")]
    Codegen(String),
    /// An inconsistency inside the JIT (a JIT bug).
    #[error("internal error: inconsistent {0}")]
    Internal(&'static str),
}

/// The native function of a compiled program (see the crate documentation).
pub type SampleFn =
    unsafe extern "C" fn(ctx: *mut f64, inputs: *const f64, out: *mut f64, sat: *mut u64);

/// A program compiled to native code. Owns the code; instances borrow it.
pub struct JitProgram {
    program: Program,
    layout: Layout,
    func: SampleFn,
    /// Holds the code memory; freed on drop.
    _code: Code,
}

impl std::fmt::Debug for JitProgram {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JitProgram")
            .field("name", &self.program.name)
            .field("layout", &self.layout)
            .finish()
    }
}

/// The executable memory of one compiled program: a finished [`JITModule`], freed on drop.
/// Shared by the f64 and the fixed-point JIT.
pub(crate) struct Code(Option<JITModule>);

// SAFETY: `JITModule` is `Send` but not `Sync` (its symbol table is a `RefCell`). A `Code`
// never touches the module through `&self` — only `drop` (with `&mut self`) uses it — so
// sharing `&Code` shares only the finished code, which any number of threads may run at once
// on their own instances' buffers.
unsafe impl Sync for Code {}

impl Drop for Code {
    fn drop(&mut self) {
        if let Some(module) = self.0.take() {
            // SAFETY: the program owning `self` is being dropped; instances borrow it, so
            // none is alive, and the function pointers into the code die with it.
            unsafe { module.free_memory() };
        }
    }
}

/// A fresh module for the host with the given host symbols (name, address) importable, at
/// `opt_level = speed`. Shared by both JITs so they run under the same settings.
pub(crate) fn new_module(symbols: &[(&'static str, *const u8)]) -> Result<JITModule, JitError> {
    let host = |e: &dyn std::fmt::Display| JitError::Host(e.to_string());
    let mut flags = settings::builder();
    flags.set("opt_level", "speed").map_err(|e| host(&e))?;
    flags
        .set("use_colocated_libcalls", "false")
        .map_err(|e| host(&e))?;
    flags.set("is_pic", "false").map_err(|e| host(&e))?;
    let isa = cranelift_native::builder()
        .map_err(|e| host(&e))?
        .finish(settings::Flags::new(flags))
        .map_err(|e| host(&e))?;
    let mut builder = JITBuilder::with_isa(isa, default_libcall_names());
    for &(name, addr) in symbols {
        builder.symbol(name, addr);
    }
    Ok(JITModule::new(builder))
}

/// Runs `define` on `module`; on success wraps the module in a [`Code`], on failure frees
/// its memory. `define` returns the address of the finished function.
pub(crate) fn finish_module<T>(
    mut module: JITModule,
    define: impl FnOnce(&mut JITModule) -> Result<T, JitError>,
) -> Result<(T, Code), JitError> {
    match define(&mut module) {
        Ok(f) => Ok((f, Code(Some(module)))),
        Err(e) => {
            // SAFETY: no pointer into the module's memory was handed out.
            unsafe { module.free_memory() };
            Err(e)
        }
    }
}

impl JitProgram {
    /// Compiles `program` for the host.
    ///
    /// # Errors
    ///
    /// A [`JitError`]: an IR invariant that does not hold (a front-end bug; the front end's
    /// programs always compile), or a host Cranelift cannot generate code for.
    pub fn compile(program: &Program) -> Result<JitProgram, JitError> {
        verify::verify(program)?;
        let layout = Layout::of(program);
        let slots = layout
            .out_len
            .max(layout.ctx_len())
            .max(layout.inputs_len());
        if slots > (i32::MAX / 8) as usize {
            return Err(JitError::TooLarge { slots });
        }
        let module = new_module(&[(codegen::EXP_SYMBOL, codegen::host_exp as *const u8)])?;
        let (func, code) = finish_module(module, |m| Self::define(m, program, &layout))?;
        Ok(JitProgram {
            program: program.clone(),
            layout,
            func,
            _code: code,
        })
    }

    fn define(
        module: &mut JITModule,
        program: &Program,
        layout: &Layout,
    ) -> Result<SampleFn, JitError> {
        let cg = |e: &dyn std::fmt::Display| JitError::Codegen(e.to_string());
        let call_conv = module.isa().default_call_conv();
        let pointer = module.target_config().pointer_type();
        let sig = codegen::signature(pointer, call_conv);
        let id = module
            .declare_function("tactus_sample", Linkage::Local, &sig)
            .map_err(|e| cg(&e))?;
        let host_sig = codegen::host_signature(call_conv);
        let exp_id = module
            .declare_function(codegen::EXP_SYMBOL, Linkage::Import, &host_sig)
            .map_err(|e| cg(&e))?;
        let mut ctx = module.make_context();
        ctx.func.signature = sig;
        let mut fctx = FunctionBuilderContext::new();
        let b = cranelift_frontend::FunctionBuilder::new(&mut ctx.func, &mut fctx);
        let host = codegen::HostFns {
            exp: module.declare_func_in_func(exp_id, b.func),
        };
        let b = codegen::Translator::new(program, layout, b, host).finish()?;
        b.finalize(module.target_config());
        module
            .define_function(id, &mut ctx)
            .map_err(|e| JitError::Codegen(format!("{e:?}")))?;
        module.finalize_definitions().map_err(|e| cg(&e))?;
        let code = module.get_finalized_function(id);
        // SAFETY: `code` is the function just defined with `signature(..)`: four pointer
        // parameters, no result, in the host's default calling convention, which is the C
        // convention on every host Cranelift supports.
        Ok(unsafe { std::mem::transmute::<*const u8, SampleFn>(code) })
    }

    /// The program it was compiled from.
    pub fn program(&self) -> &Program {
        &self.program
    }

    /// The memory layout of the native function's buffers.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }
}

/// One running instance of a compiled program (one key): the interpreter's
/// `interp::Instance` API, native code inside.
#[derive(Clone, Debug)]
pub struct JitInstance<'j> {
    jit: &'j JitProgram,
    ctx: Vec<f64>,
    inputs: Vec<f64>,
    buf: Vec<f64>,
    sat: Vec<u64>,
    modes: Vec<u32>,
    diffs: Vec<Differentiator>,
    out: SampleOut,
}

impl<'j> JitInstance<'j> {
    /// A fresh instance: states and modes at their initial values, edge memories false.
    pub fn new(jit: &'j JitProgram) -> Self {
        let (p, l) = (&jit.program, &jit.layout);
        let mut ctx = vec![0.0; l.ctx_len()];
        for (i, s) in p.states.iter().enumerate() {
            ctx[l.state(i)] = s.init;
        }
        for (i, m) in p.modes.iter().enumerate() {
            ctx[l.mode(i)] = f64::from(m.init);
        }
        JitInstance {
            jit,
            ctx,
            inputs: vec![0.0; l.inputs_len()],
            buf: vec![0.0; l.out_len],
            sat: vec![0; l.n_states],
            modes: p.modes.iter().map(|m| m.init).collect(),
            diffs: vec![Differentiator::default(); p.sensors.len()],
            out: SampleOut {
                forces: vec![0.0; l.n_forces],
                outputs: vec![0.0; l.n_outputs],
                ..SampleOut::default()
            },
        }
    }

    /// Runs one sample. `sensors` holds one reading per declared sensor, SI; missing
    /// readings are taken as the sensor's lower bound, and every reading is saturated to
    /// the declared range.
    pub fn step(&mut self, sensors: &[f64]) -> &SampleOut {
        let (p, l) = (&self.jit.program, &self.jit.layout);
        for (i, s) in p.sensors.iter().enumerate() {
            let x = sensors.get(i).copied().unwrap_or(s.range.0);
            let x = if x.is_nan() {
                s.range.0
            } else {
                x.clamp(s.range.0, s.range.1)
            };
            self.inputs[i] = x;
            if s.differentiated {
                self.diffs[i].push(x);
            }
        }
        for d in &l.derivs {
            let diff = &self.diffs[d.sensor.index()];
            self.inputs[d.offset] = if d.order == 1 {
                diff.d1(p.sample_rate_hz)
            } else {
                diff.d2(p.sample_rate_hz)
            };
        }
        // SAFETY: the buffers have the lengths `Layout` gives, the native code accesses
        // only slots below them (its offsets come from the same `Layout`), and
        // `self.jit` keeps the code alive.
        unsafe {
            (self.jit.func)(
                self.ctx.as_mut_ptr(),
                self.inputs.as_ptr(),
                self.buf.as_mut_ptr(),
                self.sat.as_mut_ptr(),
            );
        }
        self.out.forces.copy_from_slice(&self.buf[..l.n_forces]);
        self.out.total = self.buf[l.total()];
        self.out
            .outputs
            .copy_from_slice(&self.buf[l.output(0)..l.output(l.n_outputs)]);
        self.out.events.clear();
        for slot in &l.events {
            if self.buf[slot.offset] != 0.0 {
                let args = self.buf[slot.offset + 1..slot.offset + 1 + slot.n_args].to_vec();
                self.out.events.push((slot.event, args));
            }
        }
        for (m, x) in self
            .modes
            .iter_mut()
            .zip(&self.ctx[l.mode(0)..l.mode(l.n_modes)])
        {
            // Exact: the native code only ever stores a variant index.
            *m = *x as u32;
        }
        &self.out
    }

    /// Current state values (SI), in the program's state order.
    pub fn states(&self) -> &[f64] {
        &self.ctx[..self.jit.layout.n_states]
    }
    /// Current mode variant indices.
    pub fn modes(&self) -> &[u32] {
        &self.modes
    }
    /// How many writes each state had saturated to its declared range so far.
    pub fn saturations(&self) -> &[u64] {
        &self.sat
    }
}
