//! The fixed-point JIT: native code computing, sample by sample, exactly the bits the fixed
//! interpreter (`tactus_compiler::fixed::interp`) computes.
//!
//! [`FixedJitProgram::compile`] verifies the IR of a [`FixedProgram`] (the shared
//! [`crate::verify`]), fixes where every word lives ([`FixedLayout`], built on the f64 JIT's
//! [`Layout`]) and translates the body ([`fixed_codegen`](crate::fixed_codegen)) into one
//! native function that runs a *block* of samples: the loop over samples, the sensor
//! saturation and the differentiator histories are native too, so a block of `n` samples is
//! one call. [`FixedJitInstance::step_raw`] runs a block of one sample and gathers what the
//! interpreter's `step_raw` returns; [`FixedJitInstance::run_block`] runs many and returns
//! only the totals, for throughput.
//!
//! # Calling convention
//!
//! ```text
//! extern "C" fn(ctx: *mut i32, sensors: *const i32, n: u64,
//!               out: *mut i32, sat: *mut u64, totals: *mut i32)
//! ```
//!
//! Runs `n` samples. Every buffer holds 32-bit words (raw fixed-point words, variant indices,
//! 0/1 truth values); offsets are in words:
//! * `ctx` — read and written, carries the instance from sample to sample: states (raw, in
//!   [`FixedProgram::state_frac`]), modes, edge memories (0/1), then one history block of
//!   [`HISTORY_WORDS`] per differentiated sensor: the ring position (0..17), a primed flag,
//!   and the ring of the last 17 raw readings stored *twice* (words `2..19` and `19..36`, the
//!   same ring), so that the reading `k` samples ago is at `2 + pos + 17 − k` without a
//!   modulo. This is exactly `tactus_runtime::differentiator::RawHistory`, unrolled.
//! * `sensors` — `n` rows of one raw word per sensor; the native code saturates each to the
//!   sensor's raw range, as the interpreter does.
//! * `out` — the f64 JIT's `out` slots ([`Layout`]), one word each: forces, total, outputs,
//!   then per `emit` statement a flag (1 = fired in the last sample; cleared at the start of
//!   every sample) and the arguments converted to [`FixedProgram::event_frac`]. After a block
//!   it holds what the *last* sample wrote (untouched slots keep older values, like the
//!   interpreter's `RawOut`).
//! * `sat` — one `u64` saturation counter per state, incremented on each saturated write.
//! * `totals` — `n` words: the total force of each sample.
//!
//! The native code allocates nothing, performs no bounds checks (the layout and the verifier
//! guarantee every access is in bounds) and calls only the host functions behind `/` by a
//! non-constant, `sqrt` and `exp`, which are `tactus_runtime::fixed::{div, sqrt, exp}`.

use crate::layout::FixedLayout;
#[cfg(doc)]
use crate::layout::{Layout, HISTORY_WORDS};
use crate::{finish_module, new_module, Code, JitError};
use cranelift_frontend::FunctionBuilderContext;
use cranelift_jit::JITModule;
use cranelift_module::{Linkage, Module};
use tactus_compiler::fixed::interp::{FixedInstance, RawOut};
use tactus_compiler::fixed::{FixedProgram, FRAC_RANGE};

/// The native function of a compiled fixed-point program (see the module documentation).
pub type BlockFn = unsafe extern "C" fn(
    ctx: *mut i32,
    sensors: *const i32,
    n: u64,
    out: *mut i32,
    sat: *mut u64,
    totals: *mut i32,
);

/// A fixed-point program compiled to native code. Owns the code; instances borrow it.
pub struct FixedJitProgram {
    fp: FixedProgram,
    layout: FixedLayout,
    func: BlockFn,
    _code: Code,
}

impl std::fmt::Debug for FixedJitProgram {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FixedJitProgram")
            .field("name", &self.fp.program.name)
            .field("layout", &self.layout)
            .finish()
    }
}

impl FixedJitProgram {
    /// Compiles `fp` for the host.
    ///
    /// # Errors
    ///
    /// A [`JitError`]: an IR or format-plan invariant that does not hold (a compiler bug),
    /// or a host Cranelift cannot generate code for.
    pub fn compile(fp: &FixedProgram) -> Result<FixedJitProgram, JitError> {
        crate::verify::verify(&fp.program)?;
        check_plan(fp)?;
        let layout = FixedLayout::of(fp);
        let words = layout.slots.out_len.max(layout.ctx_len);
        if words > (i32::MAX / 8) as usize {
            return Err(JitError::TooLarge { slots: words });
        }
        use crate::fixed_codegen as cg;
        let module = new_module(&[
            (cg::DIV_SYMBOL, cg::host_div as *const u8),
            (cg::SQRT_SYMBOL, cg::host_sqrt as *const u8),
            (cg::EXP_SYMBOL, cg::host_exp as *const u8),
        ])?;
        let (func, code) = finish_module(module, |m| define(m, fp, &layout))?;
        Ok(FixedJitProgram {
            fp: fp.clone(),
            layout,
            func,
            _code: code,
        })
    }

    /// The fixed program it was compiled from.
    pub fn program(&self) -> &FixedProgram {
        &self.fp
    }

    /// The memory layout of the native function's buffers.
    pub fn layout(&self) -> &FixedLayout {
        &self.layout
    }
}

/// The per-value tables of the plan have one entry per value, state, sensor and event,
/// raw ranges are ordered, and every format lies in [`FRAC_RANGE`].
fn check_plan(fp: &FixedProgram) -> Result<(), JitError> {
    let p = &fp.program;
    let n = p.values.len();
    let ok = fp.frac.len() == n
        && fp.consts.len() == n
        && fp.recip.len() == n
        && fp.mul_kind.len() == n
        && fp.div_shift.len() == n
        && fp.sensor_frac.len() == p.sensors.len()
        && fp.sensor_raw_range.len() == p.sensors.len()
        && fp.state_frac.len() == p.states.len()
        && fp.state_raw_range.len() == p.states.len()
        && fp.state_init.len() == p.states.len()
        && fp.event_frac.len() == p.events.len()
        && fp.sensor_raw_range.iter().all(|(lo, hi)| lo <= hi)
        && fp.state_raw_range.iter().all(|(lo, hi)| lo <= hi)
        // Every format within FRAC_RANGE bounds the shifts the code generator emits.
        && fp
            .frac
            .iter()
            .chain(&fp.sensor_frac)
            .chain(&fp.state_frac)
            .chain(fp.event_frac.iter().flatten())
            .chain(fp.recip.iter().flatten().map(|(_, f)| f))
            .chain(fp.deriv_gain.iter().map(|(_, f)| f))
            .all(|f| (FRAC_RANGE.0..=FRAC_RANGE.1).contains(f));
    if ok {
        Ok(())
    } else {
        Err(JitError::Internal("fixed-point plan tables"))
    }
}

fn define(
    module: &mut JITModule,
    fp: &FixedProgram,
    layout: &FixedLayout,
) -> Result<BlockFn, JitError> {
    use crate::fixed_codegen as cg;
    let err = |e: &dyn std::fmt::Display| JitError::Codegen(e.to_string());
    let call_conv = module.isa().default_call_conv();
    let pointer = module.target_config().pointer_type();
    let sig = cg::signature(pointer, call_conv);
    let id = module
        .declare_function("tactus_fixed_block", Linkage::Local, &sig)
        .map_err(|e| err(&e))?;
    let mut import = |name: &str, n: usize| {
        module
            .declare_function(name, Linkage::Import, &cg::host_signature(call_conv, n))
            .map_err(|e| err(&e))
    };
    let div_id = import(cg::DIV_SYMBOL, 5)?;
    let sqrt_id = import(cg::SQRT_SYMBOL, 3)?;
    let exp_id = import(cg::EXP_SYMBOL, 3)?;
    let mut ctx = module.make_context();
    ctx.func.signature = sig;
    let mut fctx = FunctionBuilderContext::new();
    let b = cranelift_frontend::FunctionBuilder::new(&mut ctx.func, &mut fctx);
    let host = cg::HostFns {
        div: module.declare_func_in_func(div_id, b.func),
        sqrt: module.declare_func_in_func(sqrt_id, b.func),
        exp: module.declare_func_in_func(exp_id, b.func),
    };
    let b = cg::Translator::new(fp, layout, b, host).finish()?;
    b.finalize(module.target_config());
    let dump = std::env::var_os("TACTUS_JIT_DUMP").is_some();
    ctx.set_disasm(dump);
    module
        .define_function(id, &mut ctx)
        .map_err(|e| JitError::Codegen(format!("{e:?}")))?;
    if dump {
        eprintln!("{}", ctx.func.display());
        if let Some(vcode) = ctx.compiled_code().and_then(|c| c.vcode.as_ref()) {
            eprintln!("{vcode}");
        }
    }
    module.finalize_definitions().map_err(|e| err(&e))?;
    let code = module.get_finalized_function(id);
    // SAFETY: `code` is the function just defined with `fixed_codegen::signature(..)`: six
    // pointer-sized parameters, no result, in the host's default calling convention, which is
    // the C convention on every host Cranelift supports.
    Ok(unsafe { std::mem::transmute::<*const u8, BlockFn>(code) })
}

/// One running instance of a compiled fixed-point program (one key): the fixed
/// interpreter's `FixedInstance` API, native code inside.
#[derive(Clone, Debug)]
pub struct FixedJitInstance<'j> {
    jit: &'j FixedJitProgram,
    ctx: Vec<i32>,
    sensors: Vec<i32>,
    buf: Vec<i32>,
    sat: Vec<u64>,
    modes: Vec<u32>,
    out: RawOut,
}

impl<'j> FixedJitInstance<'j> {
    /// A fresh instance: states at their initial raw words, modes at their initial variants,
    /// edge memories false, histories empty; run-time params at the params' own values
    /// (`FixedProgram::nominal_param_block`).
    pub fn new(jit: &'j FixedJitProgram) -> Self {
        Self::with_params(jit, &jit.fp.nominal_param_block())
    }

    /// A fresh instance of one key of a shared program: `params` is its param block
    /// (`FixedProgram::param_block`; missing words are 0, extra ones ignored).
    pub fn with_params(jit: &'j FixedJitProgram, params: &[i32]) -> Self {
        let (fp, l) = (&jit.fp, &jit.layout);
        let p = &fp.program;
        let mut ctx = vec![0; l.ctx_len];
        for (k, &w) in params.iter().take(fp.param_words.len()).enumerate() {
            ctx[l.params + k] = w;
        }
        for (i, &x) in fp.state_init.iter().enumerate() {
            ctx[l.slots.state(i)] = x;
        }
        for (i, m) in p.modes.iter().enumerate() {
            ctx[l.slots.mode(i)] = m.init as i32;
        }
        FixedJitInstance {
            jit,
            ctx,
            sensors: vec![0; p.sensors.len()],
            buf: vec![0; l.slots.out_len],
            sat: vec![0; l.slots.n_states],
            modes: p.modes.iter().map(|m| m.init).collect(),
            out: RawOut {
                forces: vec![0; p.forces.len()],
                outputs: vec![0; p.outputs.len()],
                ..RawOut::default()
            },
        }
    }

    /// Runs one sample on SI sensor readings, converted by
    /// [`FixedInstance::sensor_raw`] (the conversion every engine uses).
    pub fn step(&mut self, sensors: &[f64]) -> &RawOut {
        let fp = &self.jit.fp;
        for i in 0..self.sensors.len() {
            self.sensors[i] = FixedInstance::sensor_raw(fp, i, sensors.get(i).copied());
        }
        self.run_one()
    }

    /// Runs one sample on raw sensor words; a missing word reads the sensor's raw lower
    /// bound, and every word is saturated to the sensor's raw range.
    pub fn step_raw(&mut self, sensors: &[i32]) -> &RawOut {
        let fp = &self.jit.fp;
        for (i, x) in self.sensors.iter_mut().enumerate() {
            *x = sensors.get(i).copied().unwrap_or(fp.sensor_raw_range[i].0);
        }
        self.run_one()
    }

    fn run_one(&mut self) -> &RawOut {
        let mut total = 0i32;
        // SAFETY: ctx, sensors (one row) and out have the lengths `FixedLayout` gives, the
        // native code accesses only words below them and `n = 1` total; `self.jit` keeps the
        // code alive.
        unsafe {
            (self.jit.func)(
                self.ctx.as_mut_ptr(),
                self.sensors.as_ptr(),
                1,
                self.buf.as_mut_ptr(),
                self.sat.as_mut_ptr(),
                &mut total,
            );
        }
        let l = &self.jit.layout;
        let s = &l.slots;
        self.out.forces.copy_from_slice(&self.buf[..s.n_forces]);
        self.out.total = total;
        self.out
            .outputs
            .copy_from_slice(&self.buf[s.output(0)..s.output(s.n_outputs)]);
        self.out.events.clear();
        for (slot, &n) in s.events.iter().zip(&l.event_args) {
            if self.buf[slot.offset] != 0 {
                let args = self.buf[slot.offset + 1..slot.offset + 1 + n].to_vec();
                self.out.events.push((slot.event, args));
            }
        }
        self.read_modes();
        &self.out
    }

    fn read_modes(&mut self) {
        let s = &self.jit.layout.slots;
        for (m, &x) in self
            .modes
            .iter_mut()
            .zip(&self.ctx[s.mode(0)..s.mode(s.n_modes)])
        {
            // The native code only ever stores a variant index.
            *m = x as u32;
        }
    }

    /// Runs a block of samples in one native call: `sensors` holds one row of raw words per
    /// sample (one word per declared sensor, saturated natively to the sensor's raw range),
    /// `totals` receives each sample's raw total force. Runs
    /// `min(totals.len(), sensors.len() / n_sensors)` samples (`totals.len()` for a program
    /// without sensors) and returns that number. Events are not collected: afterwards
    /// [`Self::last_out`] holds what the last sample wrote to the `out` words.
    pub fn run_block(&mut self, sensors: &[i32], totals: &mut [i32]) -> usize {
        let ns = self.sensors.len();
        let n = match sensors.len().checked_div(ns) {
            Some(rows) => totals.len().min(rows),
            None => totals.len(),
        };
        if n == 0 {
            return 0;
        }
        // SAFETY: as in `run_one`, with `n` rows of `ns` sensor words and `n` totals, both
        // checked above.
        unsafe {
            (self.jit.func)(
                self.ctx.as_mut_ptr(),
                sensors.as_ptr(),
                n as u64,
                self.buf.as_mut_ptr(),
                self.sat.as_mut_ptr(),
                totals.as_mut_ptr(),
            );
        }
        self.read_modes();
        n
    }

    /// The raw `out` words (see the module documentation) as the last sample left them.
    pub fn last_out(&self) -> &[i32] {
        &self.buf
    }
    /// Raw state words, in the program's state order.
    pub fn states(&self) -> &[i32] {
        &self.ctx[..self.jit.layout.slots.n_states]
    }
    /// Mode variant indices.
    pub fn modes(&self) -> &[u32] {
        &self.modes
    }
    /// How many state writes were saturated to the declared range, per state.
    pub fn saturations(&self) -> &[u64] {
        &self.sat
    }
}
