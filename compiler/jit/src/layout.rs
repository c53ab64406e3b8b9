//! Where each quantity lives in the three `f64` buffers the native code works on, and (at
//! the end, [`FixedLayout`]) in the word buffers of the fixed-point native code.
//!
//! The layout is computed once from a [`Program`] and shared by the code generator (which
//! bakes the offsets into loads and stores) and the Rust harness (which fills the inputs and
//! reads the outputs), so the two cannot disagree. Everything is a `f64` so that one slot is
//! one 8-byte load or store; saturation counters, the only integers, get their own `u64`
//! buffer. Offsets below are in slots (multiply by 8 for bytes).
//!
//! * **ctx** (read and written, persists across samples): `states`, then `modes` (variant
//!   index as `f64`), then `edges` (0.0/1.0).
//! * **inputs** (read only, filled by the harness each sample): the saturated reading of
//!   every sensor in declaration order, then one slot per `(sensor, order)` pair that some
//!   [`Op::Deriv`] reads, in order of first appearance in the value table.
//! * **out** (written; untouched slots keep last sample's value, like the interpreter's
//!   `SampleOut`): `forces`, then `total`, then `outputs`, then one [`EventSlot`] per
//!   [`Stmt::Emit`] *statement* of the body, numbered in pre-order (the order a walk of the
//!   body meets them, descending into `if` bodies in place). A slot is a flag (1.0 = fired
//!   this sample; the native code clears every flag on entry) followed by the arguments.
//!   Each statement runs at most once per sample and statements run in pre-order, so the
//!   fired slots read in slot order are the events in emission order.
//! * **sat** (`u64`, persists): one saturation counter per state.

use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::ir::{EventId, Op, Program, SensorId, Stmt};
use tactus_runtime::differentiator::WINDOW;

/// One `emit` statement's place in the `out` buffer.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EventSlot {
    /// The event kind the statement emits.
    pub event: EventId,
    /// Slot index of the flag; the arguments follow it.
    pub offset: usize,
    /// Number of arguments the statement passes.
    pub n_args: usize,
}

/// One derivative the harness computes each sample and passes in `inputs`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DerivSlot {
    /// The differentiated sensor.
    pub sensor: SensorId,
    /// 1 for `d()`, 2 for `d2()` (the interpreter reads every order other than 1 as `d2`).
    pub order: u8,
    /// Slot index in `inputs`.
    pub offset: usize,
}

/// The memory layout of one compiled program (see the module documentation).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Number of states (slots `0..n_states` of ctx).
    pub n_states: usize,
    /// Number of modes (slots `n_states..n_states + n_modes` of ctx).
    pub n_modes: usize,
    /// Number of edge memories (the last slots of ctx).
    pub n_edges: usize,
    /// Number of sensors (the first slots of inputs).
    pub n_sensors: usize,
    /// Derivative slots of inputs, after the sensors.
    pub derivs: Vec<DerivSlot>,
    /// Number of force terms (the first slots of out).
    pub n_forces: usize,
    /// Number of outputs (after the total in out).
    pub n_outputs: usize,
    /// Event slots of out, one per `emit` statement, in pre-order.
    pub events: Vec<EventSlot>,
    /// Total length of out.
    pub out_len: usize,
}

impl Layout {
    /// The layout of `program`.
    pub fn of(program: &Program) -> Layout {
        let n_sensors = program.sensors.len();
        let mut derivs: Vec<DerivSlot> = Vec::new();
        for v in &program.values {
            if let Op::Deriv(sensor, order) = v.op {
                let order = if order == 1 { 1 } else { 2 };
                if !derivs
                    .iter()
                    .any(|d| d.sensor == sensor && d.order == order)
                {
                    derivs.push(DerivSlot {
                        sensor,
                        order,
                        offset: n_sensors + derivs.len(),
                    });
                }
            }
        }
        let n_forces = program.forces.len();
        let n_outputs = program.outputs.len();
        let mut events = Vec::new();
        let mut next = n_forces + 1 + n_outputs;
        fn walk(body: &[Stmt], events: &mut Vec<EventSlot>, next: &mut usize) {
            for s in body {
                match s {
                    Stmt::Emit(event, args) => {
                        events.push(EventSlot {
                            event: *event,
                            offset: *next,
                            n_args: args.len(),
                        });
                        *next += 1 + args.len();
                    }
                    Stmt::If(_, inner) => walk(inner, events, next),
                    _ => {}
                }
            }
        }
        walk(&program.body, &mut events, &mut next);
        Layout {
            n_states: program.states.len(),
            n_modes: program.modes.len(),
            n_edges: program.edges.len(),
            n_sensors,
            derivs,
            n_forces,
            n_outputs,
            events,
            out_len: next,
        }
    }

    /// Length of ctx.
    pub fn ctx_len(&self) -> usize {
        self.n_states + self.n_modes + self.n_edges
    }
    /// Slot of state `i` in ctx.
    pub fn state(&self, i: usize) -> usize {
        i
    }
    /// Slot of mode `i` in ctx.
    pub fn mode(&self, i: usize) -> usize {
        self.n_states + i
    }
    /// Slot of edge `i` in ctx.
    pub fn edge(&self, i: usize) -> usize {
        self.n_states + self.n_modes + i
    }
    /// Length of inputs.
    pub fn inputs_len(&self) -> usize {
        self.n_sensors + self.derivs.len()
    }
    /// Slot of the total force in out.
    pub fn total(&self) -> usize {
        self.n_forces
    }
    /// Slot of output `i` in out.
    pub fn output(&self, i: usize) -> usize {
        self.n_forces + 1 + i
    }
}

/// Readings a differentiator history holds (`2N + 1`).
pub const HISTORY_LEN: usize = 2 * WINDOW + 1;
/// Words of one sensor's history block in ctx: position, primed flag, the ring twice.
pub const HISTORY_WORDS: usize = 2 + 2 * HISTORY_LEN;

/// Where each word lives in the buffers of the fixed-point native code ([`crate::fixed`]'s
/// module documentation). The slot numbering of states, modes, edges and of `out` is the f64
/// JIT's [`Layout`]; its `inputs` part is unused (the native code reads raw sensor rows and
/// computes the derivatives itself).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FixedLayout {
    /// States, modes, edges and `out` slots, as in the f64 JIT.
    pub slots: Layout,
    /// Word offset in ctx of each sensor's history block (`None`: not differentiated).
    pub history: Vec<Option<usize>>,
    /// Number of arguments each event slot (in [`Layout::events`] order) receives: the
    /// emitted arguments that have a format in [`FixedProgram::event_frac`].
    pub event_args: Vec<usize>,
    /// Word offset in ctx of the key's param block (one word per run-time param,
    /// `FixedProgram::param_words`; written by the harness, read by the native code).
    pub params: usize,
    /// Length of ctx in words.
    pub ctx_len: usize,
}

impl FixedLayout {
    /// The layout of `fp`.
    pub fn of(fp: &FixedProgram) -> FixedLayout {
        let p = &fp.program;
        let slots = Layout::of(p);
        let mut next = slots.ctx_len();
        let history = p
            .sensors
            .iter()
            .map(|s| {
                s.differentiated.then(|| {
                    next += HISTORY_WORDS;
                    next - HISTORY_WORDS
                })
            })
            .collect();
        let event_args = slots
            .events
            .iter()
            .map(|e| {
                let formats = fp.event_frac.get(e.event.index()).map_or(0, Vec::len);
                e.n_args.min(formats)
            })
            .collect();
        let params = next;
        next += fp.param_words.len();
        FixedLayout {
            slots,
            history,
            event_args,
            params,
            ctx_len: next,
        }
    }
}
